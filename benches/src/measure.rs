//! The figures of `cetratus bench`: the same workloads as the criterion benches, timed with a
//! simple median-of-batches loop so that a quick run finishes in seconds.

use std::hint::black_box;
use std::sync::Arc;
use std::time::{Duration, Instant};

use cetratus_net::{Engine, Policy};
use serde::Serialize;

use crate::{dense::DenseNet, workloads};

/// Median time of one call of `f`, in nanoseconds, over batches that each last about `batch`.
pub fn median_ns(mut f: impl FnMut(), batch: Duration, batches: usize) -> f64 {
    // Calibrate the batch size so that timer overhead is negligible.
    let mut iters = 1u64;
    loop {
        let t0 = Instant::now();
        for _ in 0..iters {
            f();
        }
        if t0.elapsed() >= batch / 4 || iters >= 1 << 30 {
            break;
        }
        iters *= 2;
    }
    let iters = iters * 4;
    let mut samples: Vec<f64> = (0..batches)
        .map(|_| {
            let t0 = Instant::now();
            for _ in 0..iters {
                f();
            }
            t0.elapsed().as_nanos() as f64 / iters as f64
        })
        .collect();
    samples.sort_by(|a, b| a.total_cmp(b));
    samples[samples.len() / 2]
}

/// Engine figures of the engine issue.
#[derive(Debug, Serialize)]
pub struct EngineFigures {
    /// Median ns of one step scan of the bare Vernadat net.
    pub vernadat_scan_ns: f64,
    /// Median ns per step scan of the ring nets, by transition count.
    pub ring_scan_ns: Vec<(usize, f64)>,
    /// Cost per scan at 10⁶ transitions over the cost at 10³.
    pub scale_ratio_1m_vs_1k: f64,
    /// Median ns per scan of the dense baseline, by transition count.
    pub dense_scan_ns: Vec<(usize, f64)>,
    /// Dense baseline over the engine at 10³ transitions.
    pub dense_speedup_1k: f64,
    /// Dense baseline over the engine at 10⁴ transitions.
    pub dense_speedup_10k: f64,
}

/// Median ns of one step scan of `net` with every guard true.
pub fn engine_scan_ns(net: cetratus_net::Net, batch: Duration, batches: usize) -> f64 {
    let mut e = Engine::new(Arc::new(net));
    median_ns(
        || {
            let fired = e
                .scan(Policy::Step, |_| Ok::<bool, ()>(true))
                .expect("bare nets cannot fail")
                .len();
            black_box(fired);
        },
        batch,
        batches,
    )
}

/// Median ns of one dense-baseline scan of `net`.
pub fn dense_scan_ns(net: &cetratus_net::Net, batch: Duration, batches: usize) -> f64 {
    let mut d = DenseNet::new(net);
    median_ns(
        || {
            black_box(d.scan());
        },
        batch,
        batches,
    )
}

/// Measures every engine figure; `quick` keeps the whole run well under a minute.
pub fn engine_figures(quick: bool) -> EngineFigures {
    let (batch, batches) = if quick {
        (Duration::from_millis(20), 7)
    } else {
        (Duration::from_millis(100), 15)
    };
    let vernadat_scan_ns = engine_scan_ns(workloads::vernadat(), batch, batches);
    let ring_scan_ns: Vec<(usize, f64)> = [1_000, 10_000, 100_000, 1_000_000]
        .into_iter()
        .map(|n| (n, engine_scan_ns(workloads::rings(n), batch, batches)))
        .collect();
    let dense_scan_ns: Vec<(usize, f64)> = [1_000, 10_000]
        .into_iter()
        .map(|n| (n, dense_scan_ns(&workloads::rings(n), batch, 5)))
        .collect();
    let at = |v: &[(usize, f64)], n: usize| v.iter().find(|x| x.0 == n).map_or(f64::NAN, |x| x.1);
    EngineFigures {
        vernadat_scan_ns,
        scale_ratio_1m_vs_1k: at(&ring_scan_ns, 1_000_000) / at(&ring_scan_ns, 1_000),
        dense_speedup_1k: at(&dense_scan_ns, 1_000) / at(&ring_scan_ns, 1_000),
        dense_speedup_10k: at(&dense_scan_ns, 10_000) / at(&ring_scan_ns, 10_000),
        ring_scan_ns,
        dense_scan_ns,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dense_baseline_and_engine_reach_the_same_markings() {
        let net = workloads::rings(1_000);
        let mut d = DenseNet::new(&net);
        let mut e = Engine::new(Arc::new(net));
        for _ in 0..250 {
            let a = d.scan();
            let b = e
                .scan(Policy::Step, |_| Ok::<bool, ()>(true))
                .unwrap()
                .len();
            assert_eq!(a, b);
            assert_eq!(a, 10);
            let m: Vec<i32> = e.marking().iter().map(|&x| x as i32).collect();
            assert_eq!(d.m, m);
        }
    }

    #[test]
    fn vernadat_bare_net_keeps_its_invariants() {
        let net = workloads::vernadat();
        let id = |s: &str| net.place_by_id(s).unwrap().index();
        let mut e = Engine::new(Arc::new(net.clone()));
        for _ in 0..100 {
            e.scan(Policy::Step, |_| Ok::<bool, ()>(true)).unwrap();
            let m = e.marking();
            assert_eq!(
                m[id("R")] + m[id("P11")] + m[id("P14")] + m[id("P22")] + m[id("P24")],
                1
            );
            assert_eq!(m[id("H")] + m[id("B")] + m[id("P14")], 7);
        }
    }
}
