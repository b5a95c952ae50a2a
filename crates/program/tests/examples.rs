//! The Vernadat examples load, keep their declared invariants, and hash stably.

use std::path::{Path, PathBuf};

use cetratus_net::{Engine, Policy, TransIdx};
use cetratus_program::{Program, Type, Value};
use cetratus_testkit::{paths, programs};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

fn ids(p: &Program) -> (Vec<String>, Vec<String>) {
    let net = p.net();
    (
        net.places().iter().map(|p| p.id.clone()).collect(),
        net.transitions().iter().map(|t| t.id.clone()).collect(),
    )
}

#[test]
fn the_vernadat_program_loads_with_places_and_transitions_in_design_order() {
    let p = programs::example("vernadat/vernadat.toml");
    let (places, transitions) = ids(&p);
    assert_eq!(
        places,
        ["H", "B", "R", "P10", "P11", "P12", "P13", "P14", "P20", "P21", "P22", "P23", "P24"]
    );
    assert_eq!(
        transitions,
        ["T10", "T11", "T12", "T13", "T20", "T14", "T21", "T22", "T24", "T23"]
    );
    assert_eq!(
        p.net().initial_marking().as_slice(),
        &[4, 3, 1, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0]
    );
    assert_eq!(p.name(), "vernadat-cell");
    assert_eq!(p.version(), "1.0.0");
    assert_eq!(p.policy(), Policy::Step);
    assert_eq!(p.scan_period(), std::time::Duration::from_millis(10));
    assert_eq!(p.inputs().len(), 8);
    assert_eq!(p.outputs().len(), 8);
    assert!(p
        .outputs()
        .iter()
        .all(|o| o.safe == Some(Value::Bool(false)) && o.ty == Type::Bool));
    assert_eq!(p.actions().len(), 6);
    assert_eq!(p.invariants().len(), 4);
}

#[test]
fn guardless_transitions_are_t14_and_t24() {
    let p = programs::example("vernadat/vernadat.toml");
    let net = p.net();
    let without: Vec<&str> = (0..net.num_transitions() as u32)
        .map(TransIdx)
        .filter(|&t| !p.has_guard(t))
        .map(|t| net.transition(t).id.as_str())
        .collect();
    assert_eq!(without, ["T14", "T24"]);
}

#[test]
fn every_example_keeps_its_invariants_at_m0_and_they_are_p_invariants() {
    for f in ["vernadat.toml", "u1.toml", "u2.toml"] {
        let p = programs::example(&format!("vernadat/{f}"));
        let m0 = p.net().initial_marking();
        assert_eq!(p.check_invariants(m0.as_slice()), Ok(()), "{f}");
        for inv in p.invariants() {
            assert_eq!(
                inv.first_breaking_transition(p.net()),
                None,
                "{f}: {}",
                inv.expr()
            );
        }
    }
}

#[test]
fn u1_is_the_same_net_with_two_more_free_slots() {
    let a = programs::example("vernadat/vernadat.toml");
    let b = programs::example("vernadat/u1.toml");
    assert_eq!(ids(&a), ids(&b));
    assert_eq!(b.net().initial_marking().as_slice()[0], 6);
    assert_eq!(b.invariants()[1].constant(), 9);
    assert_ne!(a.hash(), b.hash());
}

#[test]
fn u2_appends_the_lubrication_places_and_transitions() {
    let p = programs::example("vernadat/u2.toml");
    let (places, transitions) = ids(&p);
    assert_eq!(&places[13..], ["P30", "P31"]);
    assert_eq!(&transitions[10..], ["T30", "T31"]);
    let t30 = p
        .net()
        .transition_by_id("T30")
        .map(|t| p.guard(t).map(|g| g.source().to_string()));
    assert_eq!(t30, Some(Some("P30.t >= 3s".to_string())));
    assert!(p.output_index("LM1").is_some());
}

#[test]
fn the_hash_is_stable_across_loads() {
    let a = programs::example("vernadat/vernadat.toml");
    let b = programs::example("vernadat/vernadat.toml");
    assert_eq!(a.hash(), b.hash());
    assert_eq!(a.hash_hex().len(), 64);
}

#[test]
fn a_pnml_file_carrying_the_program_loads_like_the_toml() {
    let toml =
        std::fs::read_to_string(paths::example("vernadat/vernadat.toml")).unwrap_or_default();
    let pnml =
        std::fs::read_to_string(paths::example("vernadat/vernadat.pnml")).unwrap_or_default();
    let body: String = toml
        .lines()
        .filter(|l| !l.starts_with("net ="))
        .map(|l| format!("{l}\n"))
        .collect();
    let embedded = pnml.replacen(
        "    <page id=\"page0\">",
        &format!("    <toolspecific tool=\"cetratus\" version=\"1\"><![CDATA[\n{body}]]></toolspecific>\n    <page id=\"page0\">"),
        1,
    );
    let dir = std::env::temp_dir().join(format!("cetratus-program-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap_or_default();
    let path = dir.join("embedded.pnml");
    std::fs::write(&path, &embedded).unwrap_or_default();
    let p = programs::load(&path);
    let q = programs::example("vernadat/vernadat.toml");
    assert_eq!(ids(&p), ids(&q));
    assert_eq!(p.invariants().len(), 4);
    assert_eq!(p.net().num_places(), 13);

    // An error inside the embedded TOML points into the PNML file.
    let bad = embedded.replace("T12 = \"FPM1\"", "T12 = \"FPM9\"");
    let line = bad
        .lines()
        .position(|l| l.contains("FPM9"))
        .map(|i| i + 1)
        .unwrap_or(0);
    let err = Program::from_pnml_text(&bad, "embedded.pnml")
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
    assert!(
        err.starts_with(&format!("embedded.pnml:{line}:8:")),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_pnml_file_without_a_program_is_refused_with_a_hint() {
    let err = Program::load(&paths::example("vernadat/vernadat.pnml"))
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
    assert!(err.contains("toolspecific tool=\"cetratus\""), "{err}");
}

#[test]
fn the_broken_program_loads_but_its_buffer_invariant_breaks_when_t13_fires() {
    let p = programs::load(&data("vernadat-broken.toml"));
    let buffer = &p.invariants()[1];
    let t13 = p.net().transition_by_id("T13");
    assert_eq!(
        buffer.first_breaking_transition(p.net()),
        t13.map(|t| (t, 1))
    );

    let mut engine = Engine::new(p.net().clone());
    for id in ["T10", "T11", "T12", "T13"] {
        let t = p.net().transition_by_id(id).unwrap_or(TransIdx(u32::MAX));
        assert_eq!(engine.fire(t), Ok(true), "{id}");
    }
    let v = p.check_invariants(engine.marking()).err();
    assert_eq!(v.as_ref().map(|v| v.index), Some(1));
    assert_eq!(v.as_ref().map(|v| (v.actual, v.expected)), Some((8, 7)));
    assert!(v
        .map(|v| v.to_string())
        .unwrap_or_default()
        .contains("H + B + P14 = 7"));
}

#[test]
fn the_cell_runs_with_its_guards_and_keeps_its_invariants_at_every_scan() {
    let p = programs::example("vernadat/u2.toml");
    let mut engine = Engine::new(p.net().clone());
    let inputs = vec![Value::Bool(true); p.inputs().len()];
    let mut since: Vec<Option<u64>> = engine
        .marking()
        .iter()
        .map(|&m| (m > 0).then_some(0))
        .collect();
    let mut fired = 0;
    for scan in 1..=200u64 {
        let now = scan * 100_000;
        let ctx_marking = engine.marking().to_vec();
        let ctx = cetratus_program::EvalCtx {
            inputs: &inputs,
            prev_inputs: &inputs,
            vars: &[],
            marking: &ctx_marking,
            place_since_us: &since,
            place_dwell_us: &[],
            now_us: now,
        };
        let n = match engine.scan(p.policy(), |t| p.eval_guard(t, &ctx)) {
            Ok(f) => f.len(),
            Err(e) => panic!("{e}"),
        };
        fired += n;
        for (s, &m) in since.iter_mut().zip(engine.marking()) {
            if m == 0 {
                *s = None;
            } else if s.is_none() {
                *s = Some(now);
            }
        }
        assert_eq!(p.check_invariants(engine.marking()), Ok(()), "scan {scan}");
    }
    assert!(fired > 50, "the cell should keep cycling, fired {fired}");
}
