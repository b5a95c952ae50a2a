//! Engine benches: the Vernadat scan, the scale rings, and the dense baseline of the paper.

use std::hint::black_box;
use std::sync::Arc;

use cetratus_bench::{dense::DenseNet, workloads};
use cetratus_net::{Engine, Policy};
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};

fn vernadat(c: &mut Criterion) {
    let mut e = Engine::new(Arc::new(workloads::vernadat()));
    c.bench_function("vernadat_bare_step_scan", |b| {
        b.iter(|| {
            black_box(
                e.scan(Policy::Step, |_| Ok::<bool, ()>(true))
                    .unwrap()
                    .len(),
            )
        })
    });
}

fn rings(c: &mut Criterion) {
    let mut g = c.benchmark_group("ring_step_scan");
    for n in [1_000usize, 10_000, 100_000, 1_000_000] {
        let mut e = Engine::new(Arc::new(workloads::rings(n)));
        g.bench_with_input(BenchmarkId::from_parameter(n), &n, |b, _| {
            b.iter(|| {
                black_box(
                    e.scan(Policy::Step, |_| Ok::<bool, ()>(true))
                        .unwrap()
                        .len(),
                )
            })
        });
    }
    g.finish();
}

fn dense(c: &mut Criterion) {
    let mut g = c.benchmark_group("ring_dense_baseline_scan");
    g.sample_size(10);
    for n in [1_000usize, 10_000] {
        let mut d = DenseNet::new(&workloads::rings(n));
        g.bench_with_input(BenchmarkId::from_parameter(n), &n, |b, _| {
            b.iter(|| black_box(d.scan()))
        });
    }
    g.finish();
}

criterion_group!(benches, vernadat, rings, dense);
criterion_main!(benches);
