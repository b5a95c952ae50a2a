//! The base of a generated transformation or projection, derived from the P-invariants of both
//! nets (docs/live-update.md, *Generated transformations*).
//!
//! A map generated from place ids keeps every token where it is. When an update changes the
//! initial marking of a place it keeps (U.1 gives the buffer two more free slots: `H` starts at
//! 6, not 4), an invariant of the new net holds a different constant (`H + B + P14 = 9`, not 7),
//! and the running state, carried over token for token, would not meet it. The derivation puts
//! the difference into the base:
//!
//! * every minimal P-semiflow `y` of the row net (the new net for a transformation, the old net
//!   for a projection) whose image `v = yᵀ·L` through the map is a P-semiflow of the column net
//!   is an invariant the map carries: `y·(L·M) = v·M = v·M0` for every marking the column net
//!   reaches, so after the map `y·M'` is `v·M0_col + y·base`, where `y·M0_row` is needed;
//! * the unknowns are corrections to the base on the row places whose initial marking differs
//!   from that of the column place of the same id, and on those that receive the tokens of a
//!   removed place (`removed = { X = "A" }`: A starts from X's tokens, not from its initial
//!   marking); each carried invariant gives one linear equation on them;
//! * a unique integer solution is the derived base; several solutions are ambiguous, none is
//!   impossible, and both are refused with the invariant named and what to write.
//!
//! When no kept place changed its initial marking, no place receives another's tokens and no
//! marked place is left without tokens to read, the map is the identity where it matters and
//! nothing is derived (no semiflows are computed).

use std::fmt::Write;

use cetratus_analysis::invariants::p_semiflows_within;
use cetratus_analysis::Semiflow;
use cetratus_net::Net;

use super::{Derivation, Role, TransformError};

/// The limits of the Farkas tableau for a derivation. Past them, nothing is derived and the
/// base stays as generated from ids (the analysis gate still reports a broken invariant).
const MAX_ROWS: usize = 20_000;
const MAX_BYTES: usize = 64 << 20;

/// One carried invariant: its weights on the row net, what the map carries over, and what the
/// row net's initial marking says it holds.
struct Requirement {
    y: Semiflow,
    carried: i128,
    needed: i128,
}

/// Adds to `base` the corrections that make every invariant carried by the map `rows` (row
/// place → its (column place, coefficient) entries) hold after it.
pub(super) fn correct_base(
    role: Role,
    rows: &[Vec<(u32, i64)>],
    base: &mut [i64],
    row_net: &Net,
    col_net: &Net,
) -> Result<(), TransformError> {
    let mut unknowns = changed_places(row_net, col_net);
    // A place that receives another place's tokens (`removed`) starts from them, not from its
    // initial marking: its base is an unknown too.
    for (r, entries) in rows.iter().enumerate() {
        let receives = entries
            .iter()
            .any(|&(c, _)| col_net.places()[c as usize].id != row_net.places()[r].id);
        if receives && !unknowns.contains(&r) {
            unknowns.push(r);
        }
    }
    // A marked place the map gives nothing to (a place the other net lacks) can leave an
    // invariant short even when nothing is unknown: checked too.
    let dropped = rows.iter().enumerate().any(|(r, entries)| {
        let p = &row_net.places()[r];
        entries.is_empty() && p.initial > 0 && col_net.place_by_id(&p.id).is_none()
    });
    if unknowns.is_empty() && !dropped {
        return Ok(());
    }
    let Ok(flows) = p_semiflows_within(row_net, MAX_ROWS, MAX_BYTES, &|| false) else {
        return Ok(());
    };
    let reqs: Vec<Requirement> = flows
        .into_iter()
        .filter_map(|y| requirement(y, rows, base, row_net, col_net))
        .filter(|q| q.needed != q.carried || touches(&q.y, &unknowns))
        .collect();
    if reqs.iter().all(|q| q.needed == q.carried) {
        return Ok(());
    }
    let fix = solve(role, &reqs, &unknowns, (row_net, col_net))?;
    for (&p, d) in unknowns.iter().zip(fix) {
        base[p] = i64::try_from(i128::from(base[p]) + d).map_err(|_| TransformError::Overflow {
            place: row_net.places()[p].id.clone(),
            value: i128::from(base[p]) + d,
        })?;
    }
    Ok(())
}

/// Row places whose initial marking differs from that of the column place of the same id.
fn changed_places(row_net: &Net, col_net: &Net) -> Vec<usize> {
    row_net
        .places()
        .iter()
        .enumerate()
        .filter(|(_, p)| {
            col_net
                .place_by_id(&p.id)
                .is_some_and(|q| col_net.place(q).initial != p.initial)
        })
        .map(|(r, _)| r)
        .collect()
}

fn touches(y: &Semiflow, places: &[usize]) -> bool {
    y.0.iter().any(|(p, _)| places.contains(p))
}

/// The requirement of the row invariant `y`, when the map carries it from an invariant of the
/// column net.
fn requirement(
    y: Semiflow,
    rows: &[Vec<(u32, i64)>],
    base: &[i64],
    row_net: &Net,
    col_net: &Net,
) -> Option<Requirement> {
    let mut v = vec![0i128; col_net.num_places()];
    for &(r, w) in &y.0 {
        for &(c, k) in &rows[r] {
            v[c as usize] += i128::from(w) * i128::from(k);
        }
    }
    let is_semiflow = (0..col_net.num_transitions() as u32).all(|t| {
        col_net
            .delta(cetratus_net::TransIdx(t))
            .iter()
            .map(|&(p, d)| v[p.index()] * i128::from(d))
            .sum::<i128>()
            == 0
    });
    if !is_semiflow {
        return None;
    }
    let carried = col_net
        .places()
        .iter()
        .zip(&v)
        .map(|(p, &w)| w * i128::from(p.initial))
        .sum::<i128>()
        + y.0
            .iter()
            .map(|&(r, w)| i128::from(w) * i128::from(base[r]))
            .sum::<i128>();
    let needed =
        y.0.iter()
            .map(|&(r, w)| i128::from(w) * i128::from(row_net.places()[r].initial))
            .sum();
    Some(Requirement { y, carried, needed })
}

/// The invariant as its weighted places, e.g. `H + B + P14`.
fn expression(y: &Semiflow, net: &Net) -> String {
    let mut s = String::new();
    for (k, &(p, w)) in y.0.iter().enumerate() {
        let sep = if k == 0 { "" } else { " + " };
        let id = &net.places()[p].id;
        let _ = if w == 1 {
            write!(s, "{sep}{id}")
        } else {
            write!(s, "{sep}{w}·{id}")
        };
    }
    s
}

/// Solves the requirements for the corrections on `unknowns` by Gaussian elimination on
/// integers (each row kept divided by its gcd): one equation per requirement,
/// `Σ y[p]·δ[p] = needed − carried`.
fn solve(
    role: Role,
    reqs: &[Requirement],
    unknowns: &[usize],
    (net, other): (&Net, &Net),
) -> Result<Vec<i128>, TransformError> {
    let n = unknowns.len();
    let mut m: Vec<(Vec<i128>, i128, usize)> = reqs
        .iter()
        .enumerate()
        .map(|(i, q)| {
            let mut row = vec![0i128; n];
            for &(p, w) in &q.y.0 {
                if let Some(k) = unknowns.iter().position(|&u| u == p) {
                    row[k] = i128::from(w);
                }
            }
            (row, q.needed - q.carried, i)
        })
        .collect();
    let pivots = eliminate(&mut m, n);
    let about = |q: &Requirement| Derivation {
        what: role.what,
        net: role.row_net,
        invariant: expression(&q.y, net),
        carried: q.carried,
        needed: q.needed,
        places: String::new(),
        example: String::new(),
        change: q.needed - q.carried,
        why: String::new(),
    };
    let refuse = |i: usize, why: String| {
        TransformError::InvariantImpossible(Box::new(Derivation {
            why,
            ..about(&reqs[i])
        }))
    };
    if let Some((_, _, i)) = m
        .iter()
        .find(|(row, d, _)| *d != 0 && row.iter().all(|&a| a == 0))
    {
        return Err(refuse(*i, short_of(&reqs[*i], net, (other, role.col_net))));
    }
    if let Some(free) =
        (0..n).find(|c| !pivots.contains(c) && m.iter().any(|(row, _, _)| row[*c] != 0))
    {
        let (_, _, i) = m
            .iter()
            .find(|(row, _, _)| row[free] != 0)
            .expect("found above");
        let q = &reqs[*i];
        let places: Vec<&str> = unknowns
            .iter()
            .filter(|&&p| q.y.0.iter().any(|&(r, _)| r == p))
            .map(|&p| net.places()[p].id.as_str())
            .collect();
        return Err(TransformError::InvariantAmbiguous(Box::new(Derivation {
            places: places.join(", "),
            example: places.first().copied().unwrap_or("?").to_string(),
            ..about(q)
        })));
    }
    let mut fix = vec![0i128; n];
    for (row, d, i) in &m {
        let Some(c) = row.iter().position(|&a| a != 0) else {
            continue;
        };
        if d % row[c] != 0 {
            let id = &net.places()[unknowns[c]].id;
            return Err(refuse(
                *i,
                format!("`{id}` would need a fraction of a token"),
            ));
        }
        fix[c] = d / row[c];
    }
    Ok(fix)
}

/// Why nothing makes up `q`'s difference, in words: a marked place of it that the other net
/// lacks (its tokens are given nothing to come from), with the base that gives them back.
fn short_of(q: &Requirement, net: &Net, (other, other_name): (&Net, &str)) -> String {
    let lacking = q.y.0.iter().find(|&&(p, _)| {
        let place = &net.places()[p];
        place.initial > 0 && other.place_by_id(&place.id).is_none()
    });
    match lacking {
        Some(&(p, _)) => {
            let place = &net.places()[p];
            format!(
                "its place `{}` is not in the {} net, so nothing gives it its tokens: write the base yourself, e.g. kind = \"sparse\", identity_on_kept = true, base = {{ {} = {} }} (its initial marking)",
                place.id, other_name, place.id, place.initial
            )
        }
        None => "no place whose initial marking changed can make up the difference without breaking another invariant".into(),
    }
}

/// Brings `m` (rows of coefficients, right side, requirement) to reduced row echelon form over
/// the integers; returns the pivot columns.
fn eliminate(m: &mut [(Vec<i128>, i128, usize)], n: usize) -> Vec<usize> {
    let mut pivots = Vec::new();
    let mut top = 0;
    for c in 0..n {
        let Some(p) = (top..m.len()).find(|&r| m[r].0[c] != 0) else {
            continue;
        };
        m.swap(top, p);
        let (pivot_row, pivot_d) = (m[top].0.clone(), m[top].1);
        let a = pivot_row[c];
        for (r, (row, d, _)) in m.iter_mut().enumerate() {
            let b = row[c];
            if r == top || b == 0 {
                continue;
            }
            for (x, &px) in row.iter_mut().zip(&pivot_row) {
                *x = *x * a - px * b;
            }
            *d = *d * a - pivot_d * b;
            let g = row.iter().fold(d.abs(), |g, &x| gcd(g, x));
            if g > 1 {
                row.iter_mut().for_each(|x| *x /= g);
                *d /= g;
            }
        }
        pivots.push(c);
        top += 1;
    }
    pivots
}

fn gcd(a: i128, b: i128) -> i128 {
    let (mut a, mut b) = (a.abs(), b.abs());
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}
