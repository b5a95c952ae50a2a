//! Minimal semiflows by the Farkas algorithm, with checked arithmetic and support pruning.
//!
//! The P-semiflows are the minimal-support vectors `y ≥ 0, y ≠ 0` with `y·C = 0`; the T-semiflows
//! the `x ≥ 0, x ≠ 0` with `C·x = 0`. Every intermediate value is computed in `i128` and checked
//! back into `i64`: when a weight does not fit, the result is [`AnalysisError::Overflow`], never a
//! wrong invariant.

use cetratus_net::Net;

use crate::AnalysisError;

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

/// One row of the tableau `[A | I]`, both parts sparse (sorted `(index, value)`, no zeros), so
/// that a net of many places holds a few numbers per row rather than places + transitions.
struct Row {
    lhs: Vec<(u32, i64)>,
    rhs: Vec<(u32, i64)>,
}

impl Row {
    fn at(&self, j: u32) -> i64 {
        self.lhs
            .binary_search_by_key(&j, |e| e.0)
            .map_or(0, |k| self.lhs[k].1)
    }
    fn bytes(&self) -> usize {
        (self.lhs.capacity() + self.rhs.capacity()) * 16 + std::mem::size_of::<Row>()
    }
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

/// `small ⊆ big`, both sorted by index.
fn is_subset(small: &[(u32, i64)], big: &[(u32, i64)]) -> bool {
    if small.len() > big.len() {
        return false;
    }
    let mut k = 0;
    for &(i, _) in small {
        match big[k..].binary_search_by_key(&i, |e| e.0) {
            Ok(x) => k += x + 1,
            Err(_) => return false,
        }
    }
    true
}

fn same_support(a: &[(u32, i64)], b: &[(u32, i64)]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.0 == y.0)
}

/// `a·x + b·y` over two sparse vectors, checked; the gcd of the result folded into `g`.
fn combine(
    a: i128,
    x: &[(u32, i64)],
    b: i128,
    y: &[(u32, i64)],
    g: &mut i128,
) -> Option<Vec<(u32, i128)>> {
    let mut out = Vec::with_capacity(x.len() + y.len());
    let (mut i, mut k) = (0, 0);
    while i < x.len() || k < y.len() {
        let (idx, u, v) = match (x.get(i), y.get(k)) {
            (Some(&(xi, xv)), Some(&(yi, _))) if xi < yi => {
                i += 1;
                (xi, xv, 0)
            }
            (Some(&(xi, _)), Some(&(yi, yv))) if yi < xi => {
                k += 1;
                (yi, 0, yv)
            }
            (Some(&(xi, xv)), Some(&(_, yv))) => {
                i += 1;
                k += 1;
                (xi, xv, yv)
            }
            (Some(&(xi, xv)), None) => {
                i += 1;
                (xi, xv, 0)
            }
            (None, Some(&(yi, yv))) => {
                k += 1;
                (yi, 0, yv)
            }
            (None, None) => break,
        };
        let r = a
            .checked_mul(i128::from(u))?
            .checked_add(b.checked_mul(i128::from(v))?)?;
        if r != 0 {
            *g = gcd(*g, r);
            out.push((idx, r));
        }
    }
    Some(out)
}

/// All minimal-support `x ≥ 0, x ≠ 0` with `x·A = 0`, for `A` given by dense rows (each of
/// length `m`). See [`farkas_sparse`].
pub fn farkas(
    a: &[Vec<i64>],
    m: usize,
    max_rows: usize,
    what: &'static str,
) -> Result<Vec<Semiflow>, AnalysisError> {
    let sparse: Vec<Vec<(u32, i64)>> = a
        .iter()
        .map(|r| {
            r.iter()
                .enumerate()
                .filter(|e| *e.1 != 0)
                .map(|(j, &v)| (j as u32, v))
                .collect()
        })
        .collect();
    farkas_sparse(&sparse, m, max_rows, usize::MAX, what, &|| false)
}

/// All minimal-support `x ≥ 0, x ≠ 0` with `x·A = 0`, for `A` given by sparse rows (sorted
/// `(column, value)` pairs, columns below `m`).
///
/// `what` names the computation in errors. More than `max_rows` rows, or a tableau holding more
/// than `max_bytes`, abandons the computation with [`AnalysisError::Limit`]; `stop` returning
/// true (time is up, Ctrl-C) abandons it with [`AnalysisError::Interrupted`].
pub fn farkas_sparse(
    a: &[Vec<(u32, i64)>],
    m: usize,
    max_rows: usize,
    max_bytes: usize,
    what: &'static str,
    stop: &dyn Fn() -> bool,
) -> Result<Vec<Semiflow>, AnalysisError> {
    let interrupted = || AnalysisError::Interrupted { what };
    let mut pairs = 0u32;
    let mut rows: Vec<Row> = a
        .iter()
        .enumerate()
        .map(|(i, r)| Row {
            lhs: r.clone(),
            rhs: vec![(i as u32, 1)],
        })
        .collect();
    let mut bytes: usize = rows.iter().map(Row::bytes).sum();
    let overflow = || AnalysisError::Overflow { what };
    for j in 0..m as u32 {
        if stop() {
            return Err(interrupted());
        }
        let (mut pos, mut neg, mut zero) = (Vec::new(), Vec::new(), Vec::new());
        for r in rows.drain(..) {
            match r.at(j).signum() {
                1 => pos.push(r),
                -1 => neg.push(r),
                _ => zero.push(r),
            }
        }
        let kept = zero.len();
        let mut next = zero;
        for p in &pos {
            for q in &neg {
                pairs = pairs.wrapping_add(1);
                if pairs & 0xFFF == 0 && stop() {
                    return Err(interrupted());
                }
                let (a, b) = (i128::from(-q.at(j)), i128::from(p.at(j)));
                let mut g = 0i128;
                let rhs = combine(a, &p.rhs, b, &q.rhs, &mut g).ok_or_else(overflow)?;
                // A combination whose support contains a surviving row's support cannot be minimal.
                let support: Vec<(u32, i64)> = rhs.iter().map(|&(i, _)| (i, 0)).collect();
                if next[..kept].iter().any(|z| {
                    z.rhs.len() < support.len()
                        && z.rhs[0].0 >= support[0].0
                        && is_subset(&z.rhs, &support)
                }) {
                    continue;
                }
                let lhs = combine(a, &p.lhs, b, &q.lhs, &mut g).ok_or_else(overflow)?;
                let g = g.max(1);
                let shrink = |v: Vec<(u32, i128)>| -> Result<Vec<(u32, i64)>, AnalysisError> {
                    v.into_iter()
                        .map(|(i, x)| Ok((i, i64::try_from(x / g).map_err(|_| overflow())?)))
                        .collect()
                };
                let row = Row {
                    lhs: shrink(lhs)?,
                    rhs: shrink(rhs)?,
                };
                bytes += row.bytes();
                next.push(row);
                if next.len() > max_rows {
                    return Err(AnalysisError::Limit {
                        what,
                        limit: max_rows,
                    });
                }
                if bytes > max_bytes {
                    return Err(AnalysisError::Limit {
                        what,
                        limit: max_bytes,
                    });
                }
            }
        }
        // Among the new combinations, drop those whose support strictly contains another's and
        // duplicates of equal support (minimal-support semiflows are unique up to a factor).
        let mut fresh: Vec<Row> = next.split_off(kept);
        fresh.sort_by_key(|r| r.rhs.len());
        let mut accepted: Vec<Row> = Vec::with_capacity(fresh.len());
        for r in fresh {
            let dominated = accepted.iter().any(|s| {
                is_subset(&s.rhs, &r.rhs) && (!same_support(&s.rhs, &r.rhs) || s.rhs == r.rhs)
            });
            if !dominated {
                accepted.push(r);
            }
        }
        next.extend(accepted);
        rows = next;
        bytes = rows.iter().map(Row::bytes).sum();
    }
    let mut out: Vec<Semiflow> = rows
        .into_iter()
        .map(|r| Semiflow(r.rhs.iter().map(|&(i, w)| (i as usize, w)).collect()))
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

/// The columns of C as sparse rows: row `p` holds `(t, C[p][t])`.
fn c_rows(net: &Net) -> Vec<Vec<(u32, i64)>> {
    let mut rows = vec![Vec::new(); net.num_places()];
    for t in 0..net.num_transitions() {
        for &(p, d) in net.delta(cetratus_net::TransIdx(t as u32)) {
            rows[p.index()].push((t as u32, d));
        }
    }
    rows
}

/// Cᵀ as sparse rows: row `t` holds `(p, C[p][t])`.
fn c_columns(net: &Net) -> Vec<Vec<(u32, i64)>> {
    (0..net.num_transitions())
        .map(|t| {
            let mut r: Vec<(u32, i64)> = net
                .delta(cetratus_net::TransIdx(t as u32))
                .iter()
                .map(|&(p, d)| (p.index() as u32, d))
                .collect();
            r.sort_unstable();
            r
        })
        .collect()
}

/// The minimal P-semiflows of `net` (`y·C = 0`), indices are places.
pub fn p_semiflows(net: &Net, max_rows: usize) -> Result<Vec<Semiflow>, AnalysisError> {
    p_semiflows_within(net, max_rows, usize::MAX, &|| false)
}

/// [`p_semiflows`] with a limit on the bytes of the tableau, abandoned when `stop` says so.
pub fn p_semiflows_within(
    net: &Net,
    max_rows: usize,
    max_bytes: usize,
    stop: &dyn Fn() -> bool,
) -> Result<Vec<Semiflow>, AnalysisError> {
    let rows = c_rows(net);
    farkas_sparse(
        &rows,
        net.num_transitions(),
        max_rows,
        max_bytes,
        "P-semiflows",
        stop,
    )
}

/// The minimal T-semiflows of `net` (`C·x = 0`), indices are transitions.
pub fn t_semiflows(net: &Net, max_rows: usize) -> Result<Vec<Semiflow>, AnalysisError> {
    t_semiflows_within(net, max_rows, usize::MAX, &|| false)
}

/// [`t_semiflows`] with a limit on the bytes of the tableau.
pub fn t_semiflows_within(
    net: &Net,
    max_rows: usize,
    max_bytes: usize,
    stop: &dyn Fn() -> bool,
) -> Result<Vec<Semiflow>, AnalysisError> {
    let rows = c_columns(net);
    farkas_sparse(
        &rows,
        net.num_places(),
        max_rows,
        max_bytes,
        "T-semiflows",
        stop,
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
    structural_bounds_within(net, max_rows, usize::MAX, &|| false)
}

/// [`structural_bounds`] with a limit on the bytes of the tableau.
pub fn structural_bounds_within(
    net: &Net,
    max_rows: usize,
    max_bytes: usize,
    stop: &dyn Fn() -> bool,
) -> Result<Vec<Option<u64>>, AnalysisError> {
    let np = net.num_places();
    let nt = net.num_transitions();
    let mut a = c_rows(net);
    a.extend((0..nt).map(|t| vec![(t as u32, 1)]));
    let gens = farkas_sparse(&a, nt, max_rows, max_bytes, "structural bounds", stop)?;
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
