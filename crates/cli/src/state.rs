//! `cetratus state`: what a state directory holds and what a warm start from it would do.
//!
//! Reads only: it takes no lock and repairs nothing, so it is safe next to a running PLC.

use std::path::PathBuf;

use anyhow::bail;
use cetratus_persist::{Inspection, StateStore};

/// Arguments of `cetratus state`.
#[derive(clap::Args, Debug)]
pub struct StateArgs {
    /// The state directory (`cetratus run --state-dir`).
    dir: PathBuf,
    /// Print one JSON object.
    #[arg(long)]
    json: bool,
    /// How many of the last audit records to show.
    #[arg(long, default_value_t = 10)]
    tail: usize,
}

/// Runs `cetratus state`: exits with an error when the directory is not consistent.
pub fn run(args: &StateArgs) -> anyhow::Result<()> {
    let store = StateStore::open_read_only(&args.dir)?;
    let ins = store.inspect(args.tail);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&ins)?);
    } else {
        print(&ins);
    }
    if !ins.consistent {
        bail!(
            "{}: {} problem(s); a warm start may refuse it (start with --cold to replace the state)",
            ins.dir,
            ins.problems.len()
        );
    }
    Ok(())
}

fn print(ins: &Inspection) {
    println!("state directory {}", ins.dir);
    match &ins.state {
        Some(s) => {
            let snap = &s.snapshot;
            println!(
                "  committed       seq {} at {} (cycle {}, program time {:.3} s)",
                s.seq,
                s.written_utc,
                snap.cycle,
                snap.time_us as f64 / 1e6
            );
            println!(
                "  PRIMARY         {}",
                snap.primary.map_or("(none)", |p| p.as_str())
            );
            println!(
                "  STATUS          {}{}",
                snap.status.map_or("(none)", |st| st.as_str()),
                snap.update
                    .as_ref()
                    .map_or(String::new(), |u| format!(" ({u})"))
            );
            println!(
                "  persistence     a snapshot every {} cycles, longest commit {} µs",
                s.persist.every_cycles, s.persist.max_commit_us
            );
        }
        None => println!("  committed       nothing"),
    }
    for c in &ins.containers {
        println!(
            "  container {}     {} {} ({})",
            c.slot,
            c.role,
            c.program,
            &c.program_hash[..c.program_hash.len().min(12)]
        );
        let marked: Vec<String> = c
            .marking
            .iter()
            .filter(|(_, m)| *m > 0)
            .map(|(p, m)| {
                if *m == 1 {
                    p.clone()
                } else {
                    format!("{p}×{m}")
                }
            })
            .collect();
        println!("    marking       {}", marked.join(" "));
        if let Some(v) = &c.violation {
            println!("    invariant     BROKEN: {v}");
        }
    }
    if ins.state.is_some() {
        println!(
            "  invariants      {}",
            if ins.invariants_hold {
                "hold"
            } else {
                "BROKEN"
            }
        );
    }
    println!("  warm start      {}", ins.warm_start);
    println!("  programs");
    for p in &ins.programs {
        match &p.problem {
            None => println!("    {}  {} {}", &p.hash[..12], p.name, p.version),
            Some(e) => println!("    {}  does not load: {e}", &p.hash[..12]),
        }
    }
    println!(
        "  audit log       {} records; the last {}:",
        ins.audit_records,
        ins.audit.records.len()
    );
    for r in &ins.audit.records {
        println!("    {}  {:<8} {:<20} {}", r.utc, r.who, r.what, r.message);
    }
    if let Some(t) = &ins.audit.torn_tail {
        println!(
            "    (a torn last record of {} bytes, cut off when a PLC next opens the directory)",
            t.len()
        );
    }
    if ins.problems.is_empty() {
        println!("  consistent      yes");
    } else {
        println!("  consistent      NO");
        for p in &ins.problems {
            println!("    {p}");
        }
    }
}
