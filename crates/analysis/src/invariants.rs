//! Minimal semiflows by the Farkas algorithm, with checked arithmetic and support pruning.
//!
//! The P-semiflows are the minimal-support vectors `y ≥ 0, y ≠ 0` with `y·C = 0`; the T-semiflows
//! the `x ≥ 0, x ≠ 0` with `C·x = 0`. Every intermediate value is computed in `i128` and checked
//! back into `i64`: when a weight does not fit, the result is [`AnalysisError::Overflow`], never a
//! wrong invariant.

use cetratus_net::Net;

use crate::{AnalysisError, Incidence};

/// A semiflow as sparse `(index, weight)` pairs, weights > 0, indices increasing. The index is a
/// place index for P-semiflows and a transition index for T-semiflows.
#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Semiflow(pub Vec<(usize, i64)>);

impl Semiflow {
    /// The weights as a dense vector of length `n`.
    pub fn dense(&self, n: usize) -> Vec<i64> {
        let mut v = vec![0; n];
        for &(i, w) in &self.0 {
            v[i] = w;
        }
        v
    }

    /// `Σ weight·values[index]`, checked.
    pub fn dot(&self, values: &[u32]) -> Option<i128> {
        self.0.iter().try_fold(0i128, |acc, &(i, w)| {
            acc.checked_add(i128::from(w).checked_mul(i128::from(*values.get(i)?))?)
        })
    }
}

/// The default cap on the number of rows the Farkas tableau may hold.
pub const DEFAULT_MAX_ROWS: usize = 50_000;

struct Row {
    lhs: Vec<i64>,
    rhs: Vec<i64>,
    support: Vec<u64>,
}

fn gcd(mut a: i128, mut b: i128) -> i128 {
    a = a.abs();
    b = b.abs();
    while b != 0 {
        let r = a % b;
        a = b;
        b = r;
    }
    a
}

fn is_subset(a: &[u64], b: &[u64]) -> bool {
    a.iter().zip(b).all(|(x, y)| x & !y == 0)
}

fn popcount(a: &[u64]) -> u32 {
    a.iter().map(|w| w.count_ones()).sum()
}

/// All minimal-support `x ≥ 0, x ≠ 0` with `x·A = 0`, for `A` given by rows (each of length `m`).
///
/// `what` names the computation in errors. Rows beyond `max_rows` abandon the computation with
/// [`AnalysisError::Limit`].
pub fn farkas(
    a: &[Vec<i64>],
    m: usize,
    max_rows: usize,
    what: &'static str,
) -> Result<Vec<Semiflow>, AnalysisError> {
    let n = a.len();
    let words = n.div_ceil(64).max(1);
    let mut rows: Vec<Row> = a
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let mut rhs = vec![0; n];
            rhs[i] = 1;
            let mut support = vec![0u64; words];
            support[i / 64] |= 1 << (i % 64);
            Row {
                lhs: r.clone(),
                rhs,
                support,
            }
        })
        .collect();
    let overflow = || AnalysisError::Overflow { what };
    for j in 0..m {
        let (mut pos, mut neg, mut zero) = (Vec::new(), Vec::new(), Vec::new());
        for r in rows.drain(..) {
            match r.lhs[j].signum() {
                1 => pos.push(r),
                -1 => neg.push(r),
                _ => zero.push(r),
            }
        }
        let kept = zero.len();
        let mut next = zero;
        for p in &pos {
            for q in &neg {
                let support: Vec<u64> = p
                    .support
                    .iter()
                    .zip(&q.support)
                    .map(|(x, y)| x | y)
                    .collect();
                // A combination whose support contains a surviving row's support cannot be minimal.
                if next[..kept]
                    .iter()
                    .any(|z| is_subset(&z.support, &support) && z.support != support)
                {
                    continue;
                }
                let a = i128::from(-q.lhs[j]);
                let b = i128::from(p.lhs[j]);
                let combine = |x: i64, y: i64| -> Option<i128> {
                    a.checked_mul(i128::from(x))?
                        .checked_add(b.checked_mul(i128::from(y))?)
                };
                let mut lhs = Vec::with_capacity(m);
                let mut rhs = Vec::with_capacity(n);
                let mut g = 0i128;
                for (&x, &y) in p.lhs.iter().zip(&q.lhs) {
                    let v = combine(x, y).ok_or_else(overflow)?;
                    g = gcd(g, v);
                    lhs.push(v);
                }
                for (&x, &y) in p.rhs.iter().zip(&q.rhs) {
                    let v = combine(x, y).ok_or_else(overflow)?;
                    g = gcd(g, v);
                    rhs.push(v);
                }
                let g = g.max(1);
                let shrink = |v: Vec<i128>| -> Result<Vec<i64>, AnalysisError> {
                    v.into_iter()
                        .map(|x| i64::try_from(x / g).map_err(|_| overflow()))
                        .collect()
                };
                next.push(Row {
                    lhs: shrink(lhs)?,
                    rhs: shrink(rhs)?,
                    support,
                });
                if next.len() > max_rows {
                    return Err(AnalysisError::Limit {
                        what,
                        limit: max_rows,
                    });
                }
            }
        }
        // Among the new combinations, drop those whose support strictly contains another's and
        // duplicates of equal support (minimal-support semiflows are unique up to a factor).
        let mut fresh: Vec<Row> = next.split_off(kept);
        fresh.sort_by_key(|r| popcount(&r.support));
        let mut accepted: Vec<Row> = Vec::with_capacity(fresh.len());
        for r in fresh {
            let dominated = accepted.iter().any(|s| {
                is_subset(&s.support, &r.support) && (s.support != r.support || s.rhs == r.rhs)
            });
            if !dominated {
                accepted.push(r);
            }
        }
        next.extend(accepted);
        rows = next;
    }
    let mut out: Vec<Semiflow> = rows
        .into_iter()
        .map(|r| {
            Semiflow(
                r.rhs
                    .iter()
                    .enumerate()
                    .filter(|&(_, &w)| w != 0)
                    .map(|(i, &w)| (i, w))
                    .collect(),
            )
        })
        .collect();
    // Equal supports at the end are proportional, hence equal after the gcd division.
    out.sort();
    out.dedup();
    let supp = |s: &Semiflow| s.0.iter().map(|&(i, _)| i).collect::<Vec<_>>();
    let supports: Vec<Vec<usize>> = out.iter().map(supp).collect();
    let minimal: Vec<Semiflow> = out
        .iter()
        .zip(&supports)
        .filter(|(_, a)| {
            !supports
                .iter()
                .any(|b| b.len() < a.len() && b.iter().all(|i| a.binary_search(i).is_ok()))
        })
        .map(|(s, _)| s.clone())
        .collect();
    Ok(minimal)
}

/// The minimal P-semiflows of `net` (`y·C = 0`), indices are places.
pub fn p_semiflows(net: &Net, max_rows: usize) -> Result<Vec<Semiflow>, AnalysisError> {
    let inc = Incidence::of(net);
    farkas(&inc.c, net.num_transitions(), max_rows, "P-semiflows")
}

/// The minimal T-semiflows of `net` (`C·x = 0`), indices are transitions.
pub fn t_semiflows(net: &Net, max_rows: usize) -> Result<Vec<Semiflow>, AnalysisError> {
    let inc = Incidence::of(net);
    farkas(
        &inc.c_transposed(),
        net.num_places(),
        max_rows,
        "T-semiflows",
    )
}

/// Structural bounds: for each place, `Some(b)` when every reachable marking has `M[p] ≤ b`
/// whatever the initial marking's reachable set is, derived from some `y ≥ 0` with `y·C ≤ 0`.
///
/// The cone `{(y, z) ≥ 0 : y·C + z = 0}` is computed exactly by the Farkas algorithm on `[C; I]`
/// (one slack per transition). Every place in the support of some generator's `y` part is
/// structurally bounded by `⌊y·M0 / y[p]⌋` (for a generator with `y[p] > 0`), and the net is
/// structurally bounded exactly when every place is. Capacities are not used here.
pub fn structural_bounds(net: &Net, max_rows: usize) -> Result<Vec<Option<u64>>, AnalysisError> {
    let np = net.num_places();
    let nt = net.num_transitions();
    let inc = Incidence::of(net);
    let mut a = inc.c.clone();
    for t in 0..nt {
        let mut slack = vec![0; nt];
        slack[t] = 1;
        a.push(slack);
    }
    let gens = farkas(&a, nt, max_rows, "structural bounds")?;
    let m0 = net.initial_marking();
    let mut bounds: Vec<Option<u64>> = vec![None; np];
    for g in &gens {
        let y: Vec<(usize, i64)> = g.0.iter().copied().filter(|&(i, _)| i < np).collect();
        if y.is_empty() {
            continue;
        }
        let total = Semiflow(y.clone())
            .dot(m0.as_slice())
            .ok_or(AnalysisError::Overflow {
                what: "structural bounds",
            })?;
        for &(p, w) in &y {
            let b = u64::try_from(total / i128::from(w)).unwrap_or(u64::MAX);
            bounds[p] = Some(bounds[p].map_or(b, |old| old.min(b)));
        }
    }
    Ok(bounds)
}
