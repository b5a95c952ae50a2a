//! Criterion benches of the analysis: reachability on Kanban and FMS, and the Farkas invariants.

use cetratus_analysis::invariants::{p_semiflows, t_semiflows, DEFAULT_MAX_ROWS};
use cetratus_bench::analysis::{explore_once, explore_with, family};
use criterion::{criterion_group, criterion_main, Criterion, Throughput};

fn reachability(c: &mut Criterion) {
    let mut g = c.benchmark_group("reachability_states_per_s");
    g.sample_size(10);
    for (fam, n) in [("Kanban", 3), ("FMS", 3), ("Kanban", 5), ("FMS", 5)] {
        let net = family(fam, n);
        let states = explore_once(&net).states;
        g.throughput(Throughput::Elements(states));
        g.bench_function(format!("{fam}-{n}"), |b| b.iter(|| explore_once(&net)));
        // The parallel explorer on every available thread (the same states and edges).
        let threads = std::thread::available_parallelism().map_or(1, usize::from);
        if threads > 1 {
            g.bench_function(format!("{fam}-{n}-threads{threads}"), |b| {
                b.iter(|| explore_with(&net, threads))
            });
        }
    }
    g.finish();
}

fn invariants(c: &mut Criterion) {
    let mut g = c.benchmark_group("invariants");
    for fam in ["Kanban", "FMS"] {
        let net = family(fam, 5);
        g.bench_function(format!("{fam}-5"), |b| {
            b.iter(|| {
                (
                    p_semiflows(&net, DEFAULT_MAX_ROWS),
                    t_semiflows(&net, DEFAULT_MAX_ROWS),
                )
            })
        });
    }
    g.finish();
}

criterion_group!(benches, reachability, invariants);
criterion_main!(benches);
