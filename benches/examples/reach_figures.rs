//! Prints `reachability_figures` (what `cetratus bench` reports for the analysis) as a table,
//! without building the CLI: `cargo run --release -p cetratus-bench --example reach_figures`
//! (`-- --quick` for N = 3; `-- --reductions` for the stubborn-set counts alone, N = 5 and 6).
use cetratus_bench::analysis::Reduction;

fn print_reduction(r: &Reduction) {
    println!(
        "{}({}): full {} states ({:.3} s), stubborn sets {} states ({:.3} s), deadlock: {}",
        r.family,
        r.n,
        r.full_states,
        r.full_seconds,
        r.reduced_states,
        r.reduced_seconds,
        r.deadlock
    );
}

fn main() {
    let quick = std::env::args().any(|a| a == "--quick");
    if std::env::args().any(|a| a == "--reductions") {
        for n in [5, 6] {
            for family in ["Kanban", "FMS"] {
                print_reduction(&cetratus_bench::analysis::reduction(family, n));
            }
        }
        return;
    }
    let f = cetratus_bench::analysis::reachability_figures(quick);
    for n in &f.nets {
        println!(
            "{}({}): {} states, {} edges, {} bits/state | 1 thread: {:.3} s = {:.2} M states/s, {:.1} B/state | {} threads: {:.3} s = {:.2} M states/s, {:.1} B/state | invariants {:.2} ms {:?}",
            n.family,
            n.n,
            n.states,
            n.edges,
            n.bits_per_state,
            n.seconds,
            n.reachability_states_per_s / 1e6,
            n.bytes_per_state,
            n.threads_multi,
            n.seconds_multi,
            n.reachability_states_per_s_multi / 1e6,
            n.bytes_per_state_multi,
            n.invariants_ms,
            n.invariants
        );
    }
    for b in &f.baselines {
        println!(
            "{}({}): Python {:.2} s, Rust {:.3} s ({} thread(s)): speedup {:.1}x (one thread: {:.1}x)",
            b.family,
            b.n,
            b.python_seconds,
            b.rust_seconds,
            b.rust_threads,
            b.speedup,
            b.speedup_one_thread
        );
    }
    if let Some(note) = &f.baseline_note {
        println!("note: {note}");
    }
    f.reductions.iter().for_each(print_reduction);
}
