//! The runaways of `cetratus check`, against the real binary: each stops within its budget and
//! says which budget stopped it. No wall-clock assertion: the timeout test gives a tiny timeout
//! to a run that would take hours, and checks what the report says.

use std::path::Path;
use std::process::Command;

use cetratus_net::{ArcKind, Net, NetBuilder, Place, Transition};
use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

/// A place holding 2³¹ tokens that one transition moves, one by one, to another place: 2³¹ + 1
/// states.
fn huge_place() -> Net {
    let mut b = NetBuilder::new("huge_place");
    b.add_place(Place::new("full", 1 << 31)).expect("place");
    b.add_place(Place::new("empty", 0)).expect("place");
    b.add_transition(Transition::new("move"))
        .expect("transition");
    b.add_arc("a1", "full", "move", 1, ArcKind::Normal)
        .expect("arc");
    b.add_arc("a2", "move", "empty", 1, ArcKind::Normal)
        .expect("arc");
    b.build().expect("net")
}

/// A counter that an inhibitor arc of weight 10⁹ stops: 10⁹ states, and no structural bound, so
/// the Karp–Miller graph explores every one of them.
fn inhibited_counter() -> Net {
    let mut b = NetBuilder::new("counter");
    b.add_place(Place::new("count", 0)).expect("place");
    b.add_transition(Transition::new("tick"))
        .expect("transition");
    b.add_arc("a1", "tick", "count", 1, ArcKind::Normal)
        .expect("arc");
    b.add_arc("a2", "count", "tick", 1_000_000_000, ArcKind::Inhibitor)
        .expect("arc");
    b.build().expect("net")
}

/// A ring of `n` places and `n` transitions with one token.
fn ring(n: usize) -> Net {
    let mut b = NetBuilder::new("ring");
    for i in 0..n {
        b.add_place(Place::new(format!("p{i}"), u32::from(i == 0)))
            .expect("place");
    }
    for i in 0..n {
        b.add_transition(Transition::new(format!("t{i}")))
            .expect("transition");
        b.add_arc(
            &format!("i{i}"),
            &format!("p{i}"),
            &format!("t{i}"),
            1,
            ArcKind::Normal,
        )
        .expect("arc");
        let next = format!("p{}", (i + 1) % n);
        b.add_arc(
            &format!("o{i}"),
            &format!("t{i}"),
            &next,
            1,
            ArcKind::Normal,
        )
        .expect("arc");
    }
    b.build().expect("net")
}

fn check(net: &Net, dir: &Path, args: &[&str]) -> Value {
    let file = dir.join(format!("{}.pnml", net.id()));
    cetratus_net::pnml::write_file(net, &file).expect("PNML written");
    let out = Command::new(BIN)
        .arg("check")
        .arg(&file)
        .arg("--json")
        .args(args)
        .output()
        .expect("cetratus runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("a JSON report")
}

fn dir() -> tempfile::TempDir {
    tempfile::tempdir().expect("a temporary directory")
}

#[test]
fn a_place_of_two_to_the_31_tokens_stops_at_max_states() {
    let d = dir();
    let r = check(&huge_place(), d.path(), &["--max-states", "100000"]);
    assert_eq!(r["partial"], true, "{r}");
    assert_eq!(r["partial_reason"], "max_states", "{r}");
    assert_eq!(r["states"], 100_000, "{r}");
    assert_eq!(r["live"], Value::Null, "{r}");
}

#[test]
fn a_place_of_two_to_the_31_tokens_stops_at_max_memory() {
    let d = dir();
    let r = check(
        &huge_place(),
        d.path(),
        &["--max-memory", "16MiB", "--threads", "1"],
    );
    assert_eq!(r["partial"], true, "{r}");
    assert_eq!(r["partial_reason"], "max_memory", "{r}");
    assert!(
        r["store_bytes"].as_u64().unwrap_or(u64::MAX) <= 16 << 20,
        "{r}"
    );
    assert!(r["states"].as_u64().unwrap_or(0) > 100_000, "{r}");
}

#[test]
fn a_place_of_two_to_the_31_tokens_stops_at_max_memory_on_two_threads() {
    let d = dir();
    let r = check(
        &huge_place(),
        d.path(),
        &["--max-memory", "64MiB", "--threads", "2"],
    );
    assert_eq!(r["partial_reason"], "max_memory", "{r}");
    assert!(
        r["store_bytes"].as_u64().unwrap_or(u64::MAX) <= 64 << 20,
        "{r}"
    );
}

#[test]
fn an_inhibited_counter_of_a_billion_states_stops_at_the_timeout() {
    let d = dir();
    let r = check(&inhibited_counter(), d.path(), &["--timeout", "1ms"]);
    assert_eq!(r["partial"], true, "{r}");
    assert_eq!(r["partial_reason"], "timeout", "{r}");
    assert_eq!(r["graph"], "coverability", "{r}");
}

#[test]
fn an_inhibited_counter_of_a_billion_states_stops_at_max_memory() {
    let d = dir();
    let r = check(&inhibited_counter(), d.path(), &["--max-memory", "8MiB"]);
    assert_eq!(r["partial_reason"], "max_memory", "{r}");
}

#[test]
fn a_ring_of_two_thousand_places_is_checked_in_memory_linear_in_its_size() {
    // Dense Farkas tableaux held places² numbers (64 MB here, 3.4 GB at 20,000 places), over the
    // budget; sparse rows hold a few numbers each.
    let d = dir();
    let r = check(&ring(2_000), d.path(), &["--max-memory", "8MiB"]);
    let invariants = r["p_invariants"].as_array().expect("P-invariants computed");
    assert_eq!(invariants.len(), 1, "{r}");
    assert_eq!(r["t_invariants"].as_array().map(Vec::len), Some(1), "{r}");
}

#[test]
fn the_budgets_refuse_sizes_and_durations_they_cannot_read() {
    let d = dir();
    let net = ring(3);
    let file = d.path().join("ring.pnml");
    cetratus_net::pnml::write_file(&net, &file).expect("PNML written");
    for args in [["--max-memory", "lots"], ["--timeout", "soon"]] {
        let out = Command::new(BIN)
            .arg("check")
            .arg(&file)
            .args(args)
            .output()
            .expect("cetratus runs");
        assert!(!out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(args[1]), "{err}");
    }
}
