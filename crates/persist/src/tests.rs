//! Unit tests of the state directory and the writer.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use cetratus_program::Program;
use std::fs::OpenOptions;
use std::io::Write;

use cetratus_runtime::{Dispatcher, Plc, PlcSnapshot, Provider};

use super::*;

fn example(name: &str) -> Arc<Program> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples/vernadat")
        .join(name);
    Arc::new(Program::load(&path).expect("the example loads"))
}

fn tmp() -> PathBuf {
    static N: AtomicU64 = AtomicU64::new(0);
    let d = std::env::temp_dir().join(format!(
        "cetratus-persist-{}-{}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    let _ = std::fs::remove_dir_all(&d);
    d
}

#[test]
fn rfc3339_matches_known_dates() {
    assert_eq!(rfc3339_utc(UNIX_EPOCH), "1970-01-01T00:00:00.000Z");
    let t = UNIX_EPOCH + Duration::from_millis(951_782_400_123);
    assert_eq!(rfc3339_utc(t), "2000-02-29T00:00:00.123Z");
}

#[test]
fn program_round_trips_by_hash() {
    let d = tmp();
    let mut store = StateStore::open(&d).expect("open");
    for name in ["vernadat.toml", "u1.toml", "u2.toml"] {
        let p = example(name);
        store.save_program(&p).expect("save");
        let back = store.load_program(p.hash_hex()).expect("load");
        assert_eq!(back.hash_hex(), p.hash_hex());
    }
    assert_eq!(store.program_hashes().len(), 3);
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn altered_program_is_refused() {
    let d = tmp();
    let mut store = StateStore::open(&d).expect("open");
    let p = example("vernadat.toml");
    store.save_program(&p).expect("save");
    let h = p.hash_hex();
    let path = d.join(PROGRAMS_DIR).join(format!("{h}.toml"));
    let text = std::fs::read_to_string(&path).expect("read");
    std::fs::write(&path, format!("{text}\n# edited\n")).expect("write");
    assert!(matches!(
        store.load_program(h),
        Err(PersistError::ProgramMismatch { .. })
    ));
    assert!(matches!(
        store.load_program("../x"),
        Err(PersistError::BadHash { .. })
    ));
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn commit_is_atomic_and_a_torn_temporary_file_is_ignored() {
    let d = tmp();
    let p = example("vernadat.toml");
    let plc = Plc::new(
        p.clone(),
        0,
        Box::new(cetratus_runtime::ManualStopwatch::new()),
    );
    let mut snap = PlcSnapshot::default();
    plc.snapshot_into(&mut snap);
    {
        let mut store = StateStore::open(&d).expect("open");
        assert!(matches!(
            store.commit(&snap, &PersistFigures::default()),
            Err(PersistError::ProgramMissing { .. })
        ));
        store.save_program(&p).expect("save");
        assert_eq!(
            store
                .commit(&snap, &PersistFigures::default())
                .expect("commit"),
            1
        );
    }
    // A crash in the middle of the next commit leaves a torn temporary file.
    std::fs::write(d.join("state.json.tmp"), b"{\"format\":\"cetratus-st").expect("write");
    let store = StateStore::open(&d).expect("reopen");
    assert!(!d.join("state.json.tmp").exists());
    let back = store.load_state().expect("load").expect("a state");
    assert_eq!(back.seq, 1);
    assert_eq!(back.snapshot, snap);
    let ins = store.inspect(10);
    assert!(ins.consistent, "{:?}", ins.problems);
    assert!(ins.invariants_hold);
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn the_lock_keeps_a_second_writer_out() {
    let d = tmp();
    let _a = StateStore::open(&d).expect("open");
    assert!(matches!(
        StateStore::open(&d),
        Err(PersistError::Locked { .. })
    ));
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn audit_reader_tolerates_a_torn_last_line_and_the_writer_cuts_it() {
    let d = tmp();
    let rec = |what: &str| AuditRecord {
        utc: rfc3339_utc(SystemTime::now()),
        cycle: 1,
        time_us: 10,
        who: "cli".into(),
        what: what.into(),
        message: "m".into(),
        detail: serde_json::Value::Null,
    };
    {
        let mut store = StateStore::open(&d).expect("open");
        store.append_audit(&rec("load_accepted")).expect("append");
        store
            .append_audit(&rec("quarantine_started"))
            .expect("append");
    }
    let mut f = OpenOptions::new()
        .append(true)
        .open(d.join(AUDIT_FILE))
        .expect("open");
    f.write_all(b"{\"utc\":\"2026-").expect("write");
    drop(f);
    let ro = StateStore::open_read_only(&d).expect("open");
    let log = ro.read_audit().expect("read");
    assert_eq!(log.records.len(), 2);
    assert_eq!(log.torn_tail.as_deref(), Some("{\"utc\":\"2026-"));
    let mut store = StateStore::open(&d).expect("reopen");
    store.append_audit(&rec("substituted")).expect("append");
    let log = store.read_audit().expect("read");
    assert!(log.torn_tail.is_none());
    assert!(log.bad_lines.is_empty());
    let whats: Vec<&str> = log.records.iter().map(|r| r.what.as_str()).collect();
    assert_eq!(
        whats,
        [
            "load_accepted",
            "quarantine_started",
            "audit_repaired",
            "substituted"
        ]
    );
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn persister_commits_and_a_warm_start_resumes() {
    struct Still;
    impl Provider for Still {
        fn read_inputs(&mut self, _now_us: u64, _inputs: &mut [cetratus_program::Value]) {}
    }
    impl Dispatcher for Still {
        fn write_outputs(&mut self, _now_us: u64, _outputs: &[cetratus_program::Value]) {}
    }
    let d = tmp();
    let p = example("vernadat.toml");
    let mut plc = Plc::new(
        p.clone(),
        0,
        Box::new(cetratus_runtime::ManualStopwatch::new()),
    );
    let store = StateStore::open(&d).expect("open");
    let config = PersistConfig::for_period_us(10_000);
    let mut per = Persister::start(store, config).expect("start");
    for e in plc.drain_events() {
        per.audit(&e, "local");
    }
    for k in 0..50u64 {
        plc.cycle(k * 10_000, &mut Still);
        per.offer(&plc);
    }
    let stats = per.stop(&plc);
    assert!(stats.commits >= 1, "{stats:?}");
    assert_eq!(stats.errors, 0, "{stats:?}");
    let store = StateStore::open(&d).expect("reopen");
    let snap = store.load_snapshot().expect("load").expect("a snapshot");
    assert_eq!(snap.cycle, 50);
    let mut warm = start(
        &store,
        p.clone(),
        false,
        Box::new(cetratus_runtime::ManualStopwatch::new()),
    )
    .expect("warm start");
    assert_eq!(warm.cycles(), 50);
    assert_eq!(
        warm.drain_events()[0].kind,
        cetratus_runtime::EventKind::WarmStart
    );
    let cold = start(
        &store,
        p,
        true,
        Box::new(cetratus_runtime::ManualStopwatch::new()),
    )
    .expect("cold start");
    assert_eq!(cold.cycles(), 0);
    let log = store.read_audit().expect("audit");
    assert_eq!(log.records[0].what, "cold_start");
    let _ = std::fs::remove_dir_all(&d);
}
