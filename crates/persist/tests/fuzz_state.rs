//! Structured fuzzing of the state directory's reader on stable Rust: whatever `state.json` and
//! `audit.jsonl` hold, `cetratus state` (`StateStore::inspect`) reports on them and a start from
//! the directory (`cetratus_persist::start`, the warm start of `cetratus run`) starts or refuses
//! with an error, and never panics; a PLC that warm starts from a hostile marking scans. The inputs
//! are arbitrary bytes, and state files of the right shape whose snapshot holds markings, timers,
//! variables and latches of any length and value, for a stored program or an unknown one.

use std::path::Path;
use std::sync::{Arc, OnceLock};

use cetratus_persist::{StateStore, STATE_FORMAT};
use cetratus_program::{Program, Value};
use cetratus_runtime::{Dispatcher, ManualStopwatch, Provider};
use cetratus_testkit::programs;
use proptest::collection::vec;
use proptest::prelude::*;
use serde_json::{json, Value as Json};

fn vernadat() -> &'static Arc<Program> {
    static P: OnceLock<Arc<Program>> = OnceLock::new();
    P.get_or_init(|| Arc::new(programs::example("vernadat/vernadat.toml")))
}

/// A state directory that holds the Vernadat program, made once per test.
fn state_dir() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("a temporary directory: {e}"));
    let mut store =
        StateStore::open(dir.path()).unwrap_or_else(|e| panic!("a new state directory: {e}"));
    store
        .save_program(vernadat())
        .unwrap_or_else(|e| panic!("the program is saved: {e}"));
    dir
}

/// Every input true, every output ignored: the program's transitions are enabled by its inputs.
struct Io;

impl Provider for Io {
    fn read_inputs(&mut self, _now_us: u64, inputs: &mut [Value]) {
        for v in inputs {
            if let Value::Bool(b) = v {
                *b = true;
            }
        }
    }
}

impl Dispatcher for Io {
    fn write_outputs(&mut self, _now_us: u64, _outputs: &[Value]) {}
}

/// Reads the directory every way the CLI and a PLC do; any of it may fail, none of it may panic.
fn read_every_way(dir: &Path) {
    if let Ok(store) = StateStore::open_read_only(dir) {
        let _ = store.load_state();
        let _ = store.inspect(8);
    }
    let Ok(store) = StateStore::open(dir) else {
        return;
    };
    let started = cetratus_persist::start(
        &store,
        vernadat().clone(),
        false,
        Box::new(ManualStopwatch::new()),
    );
    if let Ok(mut plc) = started {
        let now = plc.now_us();
        for k in 1..=3u64 {
            plc.cycle(now.saturating_add(k * 10_000), &mut Io);
        }
        let _ = plc.exec_info();
    }
}

/// A token count: valid, at its maximum, or not a `u32` at all.
fn count(valid: bool) -> impl Strategy<Value = Json> {
    let any_count = prop_oneof![
        Just(json!(u64::MAX)),
        Just(json!(-1)),
        Just(json!(1.5)),
        (0..3u32).prop_map(|n| json!(n)),
    ];
    if valid {
        prop_oneof![9 => (0..3u32).prop_map(|n| json!(n)), 1 => Just(json!(u32::MAX))].boxed()
    } else {
        any_count.boxed()
    }
}

fn scalar() -> impl Strategy<Value = Json> {
    prop_oneof![
        Just(Json::Null),
        any::<bool>().prop_map(Json::Bool),
        any::<i64>().prop_map(|i| json!(i)),
        any::<f64>().prop_map(|f| json!(f)),
        Just(json!(u64::MAX)),
        "\\PC{0,8}".prop_map(Json::String),
        Just(json!([1])),
    ]
}

fn container() -> impl Strategy<Value = Json> {
    let places = vernadat().net().num_places();
    let hash = vernadat().hash_hex().to_string();
    (
        prop_oneof![
            6 => Just(hash),
            1 => Just("0".repeat(64)),
            1 => Just("../../etc/passwd".to_string()),
            1 => "\\PC{0,70}",
        ],
        prop_oneof![
            // Valid counts (a count that is not one refuses the whole file, and the warm start
            // is the interesting part), the program's initial marking, or anything.
            2 => vec(count(true), places),
            4 => Just(
                vernadat()
                    .net()
                    .initial_marking()
                    .as_slice()
                    .iter()
                    .map(|&m| json!(m))
                    .collect()
            ),
            1 => vec(count(false), 0..20),
        ],
        vec(
            prop_oneof![Just(Json::Null), any::<u64>().prop_map(|t| json!(t))],
            0..20,
        ),
        vec(scalar(), 0..4),
        vec(any::<bool>(), 0..4),
    )
        .prop_map(|(hash, marking, since, variables, latches)| {
            json!({
                "program_hash": hash,
                "marking": marking,
                "place_since_us": since,
                "variables": variables,
                "latches": latches,
            })
        })
}

fn state_file() -> impl Strategy<Value = Json> {
    let slot = prop_oneof![
        6 => Just(json!("A")),
        6 => Just(json!("B")),
        1 => Just(Json::Null),
        1 => Just(json!("C")),
    ];
    let status =
        prop::sample::select(&["idle", "setup", "quarantine", "probation", "fault", "lost"][..])
            .prop_map(|s| json!(s));
    (
        any::<u64>(),
        any::<u64>(),
        slot,
        prop::option::of(status),
        prop::option::weighted(0.8, container()),
        prop::option::weighted(0.8, container()),
        prop::option::of("\\PC{0,12}"),
        prop_oneof![8 => Just(STATE_FORMAT.to_string()), 1 => "\\PC{0,20}"],
    )
        .prop_map(|(cycle, time_us, primary, status, a, b, update, format)| {
            json!({
                "format": format,
                "seq": cycle % 1000,
                "written_utc": "2025-01-01T00:00:00.000Z",
                "snapshot": {
                    "cycle": cycle,
                    "time_us": time_us,
                    "primary": primary,
                    "status": status,
                    "containers": [a, b],
                    "update": update,
                },
            })
        })
}

/// Whole lines of an audit log, some of them records, some torn or foreign.
fn audit_log() -> impl Strategy<Value = Vec<u8>> {
    let line = prop_oneof![
        Just(
            "{\"utc\":\"2025-01-01T00:00:00.000Z\",\"cycle\":1,\"time_us\":0,\"who\":\"local\",\"what\":\"cold_start\",\"message\":\"m\",\"detail\":null}\n"
                .as_bytes()
                .to_vec()
        ),
        vec(any::<u8>(), 0..40),
        Just(b"\n".to_vec()),
    ];
    vec(line, 0..6).prop_map(|lines| lines.concat())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn arbitrary_bytes_as_state_json_are_read_or_refused(bytes in vec(any::<u8>(), 0..300)) {
        let dir = state_dir();
        std::fs::write(dir.path().join("state.json"), &bytes)?;
        read_every_way(dir.path());
    }

    #[test]
    fn state_files_of_any_content_are_read_or_refused(state in state_file()) {
        let dir = state_dir();
        std::fs::write(dir.path().join("state.json"), state.to_string())?;
        read_every_way(dir.path());
    }

    #[test]
    fn arbitrary_audit_logs_are_read_or_repaired(log in audit_log(), state in state_file()) {
        let dir = state_dir();
        std::fs::write(dir.path().join("state.json"), state.to_string())?;
        std::fs::write(dir.path().join("audit.jsonl"), log)?;
        read_every_way(dir.path());
    }
}
