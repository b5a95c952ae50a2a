//! `cetratus bench` carries its workloads: it runs from a directory that is not the source tree,
//! as a deployed binary does.

use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

/// Runs `cmd`, which must succeed (else its error output is shown), and reads its JSON report.
fn report(cmd: &mut Command) -> serde_json::Value {
    let out = cmd.output().expect("run cetratus");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("one JSON object")
}

#[test]
fn bench_jitter_runs_from_a_directory_outside_the_source_tree() {
    let dir = tempfile::tempdir().expect("temp dir");
    let v = report(
        Command::new(BIN)
            .current_dir(dir.path())
            // The embedded workloads are written under the temporary directory: here, so that the
            // test sees that they came from the binary and not from a source tree.
            .env("TMPDIR", dir.path())
            .args([
                "bench", "jitter", "--period", "10ms", "--for", "300ms", "--json",
            ]),
    );
    assert!(v["cycles"].as_u64().is_some_and(|n| n > 0), "{v}");
    let written = std::fs::read_dir(dir.path())
        .expect("list")
        .filter_map(Result::ok)
        .any(|e| e.path().join("examples/vernadat/vernadat.toml").is_file());
    assert!(written, "the program came from the binary's embedded copy");
}

#[test]
fn bench_jitter_reports_the_machines_own_latency_from_cyclictest_or_why_not() {
    let v = report(Command::new(BIN).args([
        "bench", "jitter", "--period", "10ms", "--for", "1s", "--json",
    ]));
    let m = &v["machine"];
    // scripts/test installs rt-tests, so cyclictest is there; without --rt it needs no priority.
    assert!(
        m["cycles"].as_u64().is_some_and(|n| n > 0),
        "cyclictest measured: {m}"
    );
    assert!(m["command"].as_str().unwrap().contains("--laptop"), "{m}");
    assert!(m["p99_us"].as_u64() >= m["p50_us"].as_u64(), "{m}");
    // Without it on the PATH the report says so instead of failing.
    let v = report(Command::new(BIN).env("PATH", "/nonexistent").args([
        "bench", "jitter", "--period", "10ms", "--for", "300ms", "--json",
    ]));
    assert!(
        v["machine"]["cyclictest"]
            .as_str()
            .is_some_and(|s| s.contains("missing") && s.contains("rt-tests")),
        "{v}"
    );
}

#[test]
fn bench_io_measures_round_trips_against_pymodbus_and_its_own_server_from_anywhere() {
    let dir = tempfile::tempdir().expect("temp dir");
    let v = report(
        Command::new(BIN)
            .current_dir(dir.path())
            .env("TMPDIR", dir.path())
            .args([
                "bench", "io", "--period", "10ms", "--for", "500ms", "--json",
            ]),
    );
    let peers: Vec<&str> = v["round_trips"]
        .as_array()
        .expect("round trips")
        .iter()
        .map(|r| {
            assert!(r["cycles"].as_u64().is_some_and(|n| n > 0), "{r}");
            assert_eq!(r["failed"], 0, "{r}");
            r["peer"].as_str().unwrap()
        })
        .collect();
    assert_eq!(peers, ["pymodbus", "cetratus"]);
    for phase in ["latency_io_off", "latency_io_on"] {
        assert!(v[phase]["cycles"].as_u64().is_some_and(|n| n > 0), "{v}");
    }
    // The phase with I/O exchanged with the device; the phases alternate in slices.
    assert!(v["device"]["reads"].as_u64().is_some_and(|n| n > 0), "{v}");
    assert!(v["slice_us"].as_u64().is_some_and(|n| n > 0), "{v}");
    assert_eq!(v["rt"], "not requested", "{v}");
}

/// `bench flood` interleaves: every kind gets its slices, each after an unloaded one, and every
/// kind is sent and measured in every round.
#[test]
fn bench_flood_measures_every_kind_in_slices_between_unloaded_ones() {
    let v = report(Command::new(BIN).args([
        "bench", "flood", "--for", "200ms", "--slice", "100ms", "--period", "10ms", "--json",
    ]));
    assert_eq!(v["method"], "interleaved", "{v}");
    assert_eq!(v["slice_s"], 0.1, "{v}");
    let kinds = [
        "garbage",
        "refused_loads",
        "exec_info",
        "large_payloads",
        "event_spam",
        "dashboard_logins",
        "deep_topics",
        "wills",
        "id_takeover",
        "idle_sockets",
    ];
    // Two rounds of ten kinds, each flood slice after an unloaded one.
    assert_eq!(v["unloaded_slices"], 20, "{v}");
    assert!(v["unloaded_cycles"].as_u64().is_some_and(|n| n > 0), "{v}");
    let limit = v["limit_ns"].as_f64().expect("the limit");
    let p99 = v["unloaded_latency_p99_ns"]
        .as_f64()
        .expect("the unloaded p99");
    // serde_json reads a float to within an ulp, not always to the value written.
    assert!((limit - (1.2 * p99 + 20_000.0)).abs() < 1e-6, "{v}");
    for kind in kinds {
        let k = &v[kind];
        assert_eq!(k["slices"], 2, "{kind}: {k}");
        assert!(k["cycles"].as_u64().is_some_and(|n| n > 0), "{kind}: {k}");
        assert!(k["sent"].as_u64().is_some_and(|n| n > 0), "{kind}: {k}");
        assert!(k["latency_p99_ns"].as_u64().is_some(), "{kind}: {k}");
        assert!(
            k["unloaded_before_latency_p99_ns"].as_u64().is_some(),
            "{kind}: {k}"
        );
    }
    // The replies are counted for the kind that caused them.
    let garbage = &v["garbage"]["replies"];
    assert!(
        garbage["malformed"].as_u64().is_some_and(|n| n > 0),
        "{garbage}"
    );
    assert!(
        v["dashboard_logins"]["replies"]
            .as_object()
            .is_some_and(|r| r.keys().all(|c| c.starts_with("http_"))),
        "{v}"
    );
    // Each attack of a connection of its own is refused as the broker refuses it.
    for (kind, code) in [
        ("deep_topics", "suback_128_closed"),
        ("wills", "connack_5"),
        ("id_takeover", "connack_5"),
        ("idle_sockets", "idle_open"),
    ] {
        let replies = &v[kind]["replies"];
        let only = replies
            .as_object()
            .is_some_and(|r| r.keys().all(|c| c == code));
        assert!(
            only && replies[code].as_u64().is_some_and(|n| n > 0),
            "{kind}: {replies}"
        );
    }
    assert!(v["machine"].is_object(), "{v}");
}

/// `bench flood --kinds` floods only the kinds it names, and names the kinds when one is wrong.
#[test]
fn bench_flood_runs_only_the_kinds_asked_for() {
    let v = report(Command::new(BIN).args([
        "bench",
        "flood",
        "--for",
        "200ms",
        "--slice",
        "100ms",
        "--period",
        "10ms",
        "--kinds",
        "exec_info",
        "--json",
    ]));
    // Two rounds of one kind.
    assert_eq!(v["unloaded_slices"], 2, "{v}");
    assert_eq!(v["exec_info"]["slices"], 2, "{v}");
    assert!(
        v["exec_info"]["sent"].as_u64().is_some_and(|n| n > 0),
        "{v}"
    );
    for other in [
        "garbage",
        "refused_loads",
        "large_payloads",
        "event_spam",
        "dashboard_logins",
        "deep_topics",
        "wills",
        "id_takeover",
        "idle_sockets",
    ] {
        assert!(v.get(other).is_none(), "{other} was not asked for: {v}");
    }

    let out = Command::new(BIN)
        .args([
            "bench",
            "flood",
            "--for",
            "200ms",
            "--kinds",
            "exec_info,frobnicate",
        ])
        .output()
        .expect("run cetratus");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("unknown flood kind `frobnicate`")
            && err.contains("exec_info, large_payloads"),
        "{err}"
    );
}
