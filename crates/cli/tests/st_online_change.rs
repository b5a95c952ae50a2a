//! The press cell of `examples/st-cell` changed online by the real binary: version 1 imported
//! from its ST, version 2 built into a signed package from the example manifest, loaded,
//! quarantined and substituted by `--at` in a replayed run. The RETAIN count goes on across the
//! switch, the press time changes from 0.8 s to 1.2 s, and nothing restarts.

use std::path::{Path, PathBuf};
use std::process::Command;

use cetratus_testkit::process::signed_package;

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

fn example(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples/st-cell")
        .join(name)
}

fn path(p: &Path) -> &str {
    p.to_str().expect("a UTF-8 path")
}

fn ok(args: &[&str]) -> String {
    let out = Command::new(BIN)
        .args(args)
        .output()
        .expect("cetratus runs");
    assert!(
        out.status.success(),
        "cetratus {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// `press` at each row of the trace (`scan,time_ms,...`), which has a row where anything changed.
fn press_edges(csv: &str) -> Vec<(u64, bool)> {
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().expect("a header").split(',').collect();
    let col = header.iter().position(|c| *c == "press").expect("press");
    lines
        .filter_map(|l| {
            let cells: Vec<&str> = l.split(',').collect();
            let on = match *cells.get(col)? {
                "1" | "true" => true,
                "0" | "false" => false,
                _ => return None,
            };
            Some((cells[0].parse().ok()?, on))
        })
        .collect()
}

#[test]
fn version_2_of_the_press_cell_goes_live_with_its_count_kept_and_its_new_press_time() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let d = dir.path();
    ok(&["import", "st", path(&example("cell.st")), "-o", path(d)]);
    let config = d.join("config");
    let package = signed_package(
        BIN,
        &example("cell-v2.package.toml"),
        "v2",
        d,
        &config.join("trusted"),
    );
    // A part arrives every 2 s, the light curtain clear: part_in is high for 100 ms.
    let mut replay = String::from("scan,time_ms,part_in,guard_ok\n0,0.000,0,1\n");
    for k in 0..10u64 {
        let (on, off) = (200 * k + 50, 200 * k + 60);
        replay.push_str(&format!(
            "{on},{}.000,1,1\n{off},{}.000,0,1\n",
            on * 10,
            off * 10
        ));
    }
    let replay_file = d.join("in.csv");
    std::fs::write(&replay_file, replay).expect("write the replay");
    let trace = d.join("trace.csv");
    let load = format!("5s load {}", path(&package));
    ok(&[
        "run",
        path(&d.join("Cell.toml")),
        "--replay",
        path(&replay_file),
        "--virtual",
        "--for",
        "20s",
        "--config",
        path(&config),
        "--at",
        &load,
        "--at",
        "8s substitute",
        "--trace",
        path(&trace),
        "--no-mqtt",
    ]);
    let csv = std::fs::read_to_string(&trace).expect("the trace");
    let mut edges = press_edges(&csv);
    edges.dedup_by_key(|e| e.1);
    // Each press lasts from its on edge to its off edge; before the switch at 8 s, 0.8 s.
    let presses: Vec<(u64, u64)> = edges
        .windows(2)
        .filter(|w| w[0].1 && !w[1].1)
        .map(|w| (w[0].0, w[1].0 - w[0].0))
        .collect();
    assert_eq!(presses.len(), 10, "{presses:?}\n{csv}");
    for &(at, scans) in &presses {
        let expected = if at < 800 { 80 } else { 120 };
        assert!(
            scans.abs_diff(expected) <= 1,
            "the press at scan {at} lasted {scans} scans: {presses:?}"
        );
    }
    // The count of pressed parts went on across the switch: 10 parts, none counted twice.
    let last = csv.lines().last().expect("a row");
    let header: Vec<&str> = csv.lines().next().expect("a header").split(',').collect();
    let col = header
        .iter()
        .position(|c| *c == "pressed")
        .expect("pressed");
    let pressed_rows: Vec<&str> = csv
        .lines()
        .skip(1)
        .filter_map(|l| l.split(',').nth(col).filter(|c| !c.is_empty()))
        .collect();
    assert_eq!(pressed_rows.last(), Some(&"10"), "{last}\n{csv}");
}
