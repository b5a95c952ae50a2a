//! Profiling aid: explores Kanban or FMS once (run it under perf or callgrind).
//!
//! `cargo run --release -p cetratus-bench --example reach_profile -- kanban 5 [threads]`
fn main() {
    let mut args = std::env::args().skip(1);
    let fam = args.next().unwrap_or_else(|| "kanban".into());
    let n: u32 = args.next().and_then(|a| a.parse().ok()).unwrap_or(5);
    let threads: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(1);
    let name = if fam.eq_ignore_ascii_case("fms") {
        "FMS"
    } else {
        "Kanban"
    };
    let net = cetratus_bench::analysis::family(name, n);
    let t = std::time::Instant::now();
    let r = cetratus_bench::analysis::explore_with(&net, threads);
    let s = t.elapsed().as_secs_f64();
    println!(
        "{name}({n}) threads={threads}: {} states {} edges in {s:.3} s = {:.2} M states/s, {:.1} B/state",
        r.states,
        r.edges,
        r.states as f64 / s / 1e6,
        r.peak_bytes as f64 / r.states as f64
    );
}
