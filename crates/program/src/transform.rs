//! State transformations `M_new = ST·M_old + ST_base` and projections `Π·M_cand + Π_base`
//! (docs/design.md §1, §4).
//!
//! Both are linear maps between the place spaces of two nets, resolved once against those nets
//! (ids checked, stored sparse) so that applying one at a cycle boundary is a few multiply-adds
//! and never allocates. Rows and columns follow each net's declaration order.

use std::collections::BTreeMap;
use std::fmt;

use cetratus_net::{Net, PlaceIdx, Tokens};

use crate::{InvariantViolation, Program};

mod chart;
mod derive;
mod error;

pub use chart::markable_places;
use chart::networks_without_kept_places;
pub use error::{Derivation, TransformError};

const ST: &str = "state transform";
const PROJ: &str = "projection";
const NEW: &str = "new";
const OLD: &str = "running (old)";

/// A sparse linear map `y = A·x + b` between two place spaces, with the ids of both.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Linear {
    /// `entries[row_start[r]..row_start[r + 1]]` are row r's (column, coefficient), no zeros.
    row_start: Vec<usize>,
    entries: Vec<(u32, i64)>,
    base: Vec<i64>,
    row_ids: Vec<String>,
    col_ids: Vec<String>,
}

/// Which map and which nets, for messages.
#[derive(Clone, Copy)]
pub(crate) struct Role {
    what: &'static str,
    row_net: &'static str,
    col_net: &'static str,
}

fn ids(net: &Net) -> Vec<String> {
    net.places().iter().map(|p| p.id.clone()).collect()
}

impl Linear {
    fn from_rows(rows: Vec<Vec<(u32, i64)>>, base: Vec<i64>, row_net: &Net, col_net: &Net) -> Self {
        let mut row_start = Vec::with_capacity(rows.len() + 1);
        let mut entries = Vec::new();
        row_start.push(0);
        for mut r in rows {
            r.retain(|&(_, c)| c != 0);
            r.sort_unstable_by_key(|&(c, _)| c);
            entries.extend(r);
            row_start.push(entries.len());
        }
        Linear {
            row_start,
            entries,
            base,
            row_ids: ids(row_net),
            col_ids: ids(col_net),
        }
    }

    pub(crate) fn dense(
        role: Role,
        row_net: &Net,
        col_net: &Net,
        row_ids: &[String],
        col_ids: &[String],
        matrix: &[Vec<i64>],
        base: &[i64],
    ) -> Result<Self, TransformError> {
        let (nr, nc) = (row_net.num_places(), col_net.num_places());
        let dims = |axis, net, expected, found| TransformError::Dimensions {
            what: role.what,
            axis,
            net,
            expected,
            found,
        };
        if row_ids.len() != nr {
            return Err(dims("row ids", role.row_net, nr, row_ids.len()));
        }
        if col_ids.len() != nc {
            return Err(dims("column ids", role.col_net, nc, col_ids.len()));
        }
        check_ids(role.what, "row", role.row_net, row_net, row_ids)?;
        check_ids(role.what, "column", role.col_net, col_net, col_ids)?;
        if matrix.len() != nr {
            return Err(dims("rows", role.row_net, nr, matrix.len()));
        }
        if base.len() != nr {
            return Err(TransformError::BaseLength {
                what: role.what,
                expected: nr,
                found: base.len(),
            });
        }
        let mut rows = Vec::with_capacity(nr);
        for (r, row) in matrix.iter().enumerate() {
            if row.len() != nc {
                return Err(TransformError::RowLength {
                    what: role.what,
                    row: r + 1,
                    id: row_ids[r].clone(),
                    net: role.col_net,
                    expected: nc,
                    found: row.len(),
                });
            }
            rows.push(
                row.iter()
                    .enumerate()
                    .map(|(c, &k)| (c as u32, k))
                    .collect::<Vec<_>>(),
            );
        }
        Ok(Self::from_rows(rows, base.to_vec(), row_net, col_net))
    }

    pub(crate) fn sparse(
        role: Role,
        row_net: &Net,
        col_net: &Net,
        entries: &[(String, String, i64)],
        base: &BTreeMap<String, i64>,
    ) -> Result<Self, TransformError> {
        let unknown = |id: &str, role_name, net| TransformError::UnknownPlace {
            what: role.what,
            id: id.to_string(),
            role: role_name,
            net,
        };
        let mut rows: Vec<Vec<(u32, i64)>> = vec![Vec::new(); row_net.num_places()];
        for (to, from, coef) in entries {
            let r = row_net
                .place_by_id(to)
                .ok_or_else(|| unknown(to, "a target (`to`)", role.row_net))?;
            let c = col_net
                .place_by_id(from)
                .ok_or_else(|| unknown(from, "a source (`from`)", role.col_net))?;
            let row = &mut rows[r.index()];
            if row.iter().any(|&(k, _)| k == c.0) {
                return Err(TransformError::DuplicateEntry {
                    what: role.what,
                    to: to.clone(),
                    from: from.clone(),
                });
            }
            row.push((c.0, *coef));
        }
        let mut b = vec![0i64; row_net.num_places()];
        for (id, v) in base {
            let r = row_net
                .place_by_id(id)
                .ok_or_else(|| unknown(id, "a base key", role.row_net))?;
            b[r.index()] = *v;
        }
        Ok(Self::from_rows(rows, b, row_net, col_net))
    }

    fn rows(&self) -> usize {
        self.base.len()
    }

    fn cols(&self) -> usize {
        self.col_ids.len()
    }

    fn row(&self, r: usize) -> &[(u32, i64)] {
        &self.entries[self.row_start[r]..self.row_start[r + 1]]
    }

    /// Row r at x, exactly: `i64 · u32` terms fit an i128 with room for any realistic row.
    #[inline]
    fn eval(&self, r: usize, x: &[Tokens]) -> i128 {
        self.row(r)
            .iter()
            .fold(i128::from(self.base[r]), |acc, &(c, k)| {
                let v = x.get(c as usize).copied().unwrap_or(0);
                acc.saturating_add(i128::from(k) * i128::from(v))
            })
    }

    /// True when some row reads column c.
    fn reads(&self, c: u32) -> bool {
        self.entries.iter().any(|&(k, _)| k == c)
    }

    /// `y = A·x + b` into `out`, only when every check passes against the program of the rows'
    /// net: no negative count, no overflow, no count above a capacity, no dropped place with
    /// tokens, and every invariant of `new`. Never allocates on success.
    fn apply_checked(
        &self,
        what: &'static str,
        must_be_empty: &[PlaceIdx],
        old_marking: &[Tokens],
        new: &Program,
        out: &mut [Tokens],
    ) -> Result<(), TransformError> {
        let len = |which, expected, found| TransformError::MarkingLength {
            what,
            which,
            expected,
            found,
        };
        if old_marking.len() != self.cols() {
            return Err(len("old marking", self.cols(), old_marking.len()));
        }
        let net = new.net();
        if net.num_places() != self.rows() {
            return Err(len("new program", self.rows(), net.num_places()));
        }
        if out.len() != self.rows() {
            return Err(len("output marking", self.rows(), out.len()));
        }
        for &p in must_be_empty {
            let tokens = old_marking[p.index()];
            if tokens > 0 {
                return Err(TransformError::RemovedNotEmpty {
                    place: self.col_ids[p.index()].clone(),
                    tokens,
                });
            }
        }
        for r in 0..self.rows() {
            let v = self.row_tokens(r, old_marking)?;
            if let Some(cap) = net.capacity(PlaceIdx(r as u32)) {
                if v > cap {
                    return Err(TransformError::AboveCapacity {
                        place: self.row_ids[r].clone(),
                        value: u64::from(v),
                        capacity: cap,
                    });
                }
            }
        }
        // The invariants are checked on rows computed again, not on `out`, so that a refusal
        // leaves the caller's buffer as it was.
        for (index, inv) in new.invariants().iter().enumerate() {
            let mut actual = 0i128;
            for &(p, w) in inv.terms() {
                let v = self.row_tokens(p.index(), old_marking)?;
                actual = actual.saturating_add(i128::from(w) * i128::from(v));
            }
            if actual != i128::from(inv.constant()) {
                return Err(TransformError::Invariant {
                    violation: InvariantViolation {
                        index,
                        expr: inv.expr().into(),
                        actual,
                        expected: inv.constant(),
                    },
                });
            }
        }
        for (r, o) in out.iter_mut().enumerate() {
            *o = self.row_tokens(r, old_marking)?;
        }
        Ok(())
    }

    /// Row r as a token count, or why it is not one.
    #[inline]
    fn row_tokens(&self, r: usize, old: &[Tokens]) -> Result<Tokens, TransformError> {
        let v = self.eval(r, old);
        if v < 0 {
            return Err(TransformError::Negative {
                place: self.row_ids[r].clone(),
                value: v,
            });
        }
        Tokens::try_from(v).map_err(|_| TransformError::Overflow {
            place: self.row_ids[r].clone(),
            value: v,
        })
    }

    fn to_dense(&self) -> DenseMatrix {
        let mut matrix = vec![vec![0i64; self.cols()]; self.rows()];
        for (r, row) in matrix.iter_mut().enumerate() {
            for &(c, k) in self.row(r) {
                row[c as usize] = k;
            }
        }
        DenseMatrix {
            row_ids: self.row_ids.clone(),
            col_ids: self.col_ids.clone(),
            matrix,
            base: self.base.clone(),
        }
    }
}

fn check_ids(
    what: &'static str,
    axis: &'static str,
    net_name: &'static str,
    net: &Net,
    given: &[String],
) -> Result<(), TransformError> {
    for (i, (p, g)) in net.places().iter().zip(given).enumerate() {
        if p.id != *g {
            return Err(TransformError::PlaceId {
                what,
                axis,
                index: i + 1,
                net: net_name,
                expected: p.id.clone(),
                found: g.clone(),
            });
        }
    }
    Ok(())
}

/// The constructors from explicit matrices, the sizes and the dense form that a transformation
/// and a projection share (the doc lines differ: which net is a row), written once.
macro_rules! explicit_constructors_and_sizes {
    ($dense:literal, $sparse:literal, $rows:literal, $cols:literal, $to_dense:literal) => {
        #[doc = $dense]
        pub fn dense(
            old: &Net,
            new: &Net,
            row_ids: &[String],
            col_ids: &[String],
            matrix: &[Vec<i64>],
            base: &[i64],
        ) -> Result<Self, TransformError> {
            <Self as Between>::build(old, new, |role, rows, cols| {
                Linear::dense(role, rows, cols, row_ids, col_ids, matrix, base)
            })
        }

        #[doc = $sparse]
        pub fn sparse(
            old: &Net,
            new: &Net,
            entries: &[(String, String, i64)],
            base: &BTreeMap<String, i64>,
        ) -> Result<Self, TransformError> {
            <Self as Between>::build(old, new, |role, rows, cols| {
                Linear::sparse(role, rows, cols, entries, base)
            })
        }

        #[doc = $rows]
        pub fn rows(&self) -> usize {
            self.map.rows()
        }

        #[doc = $cols]
        pub fn cols(&self) -> usize {
            self.map.cols()
        }

        #[doc = $to_dense]
        pub fn to_dense(&self) -> DenseMatrix {
            self.map.to_dense()
        }
    };
}

/// A linear map between the running (old) and the new net's place spaces: [`StateTransform`]
/// and [`Projection`] resolve their matrices alike and differ in which net gives the rows.
pub(crate) trait Between: Sized {
    /// The map's name and the nets of its rows and columns, for messages.
    const ROLE: Role;
    /// The nets whose places are the rows and the columns.
    fn axes<'n>(old: &'n Net, new: &'n Net) -> (&'n Net, &'n Net);
    /// Wraps a resolved matrix with what the map keeps of the two nets (timers, places to check).
    fn from_map(map: Linear, old: &Net, new: &Net) -> Self;

    /// The map that `linear` resolves on this kind's row and column nets.
    fn build(
        old: &Net,
        new: &Net,
        linear: impl FnOnce(Role, &Net, &Net) -> Result<Linear, TransformError>,
    ) -> Result<Self, TransformError> {
        let (rows, cols) = Self::axes(old, new);
        Ok(Self::from_map(linear(Self::ROLE, rows, cols)?, old, new))
    }
}

/// A state transformation `M_new = ST·M_old + ST_base`, resolved against an old and a new net.
#[derive(Clone, Debug, PartialEq)]
pub struct StateTransform {
    map: Linear,
    /// Per new place, the old place whose timer it inherits (the old place with the same id).
    timer_from: Vec<Option<PlaceIdx>>,
    /// Old places that no row reads and the new net does not have: their tokens would vanish.
    must_be_empty: Vec<PlaceIdx>,
}

impl StateTransform {
    /// The transformation generated from place ids: a place kept by id keeps its tokens and
    /// timer, a new place starts at its initial marking, and a removed place either sends its
    /// tokens to the new place `removed` names for it or must be empty when the update applies.
    /// Where the initial markings of kept places differ, the base is derived from the
    /// invariants of the new net so that they hold after the transform (`derive.rs`), or the
    /// transform is refused with the invariant named.
    pub fn generated(
        old: &Program,
        new: &Program,
        removed: &BTreeMap<String, String>,
    ) -> Result<Self, TransformError> {
        let (on, nn) = (old.net().as_ref(), new.net().as_ref());
        let mut rows: Vec<Vec<(u32, i64)>> = vec![Vec::new(); nn.num_places()];
        let mut base = vec![0i64; nn.num_places()];
        // A chart's added step starts inactive, its initial step too, unless its whole network
        // is new: a running chart goes on from its active steps, and one active step per
        // network is what keeps a chart safe.
        let network_is_new = if new.is_sfc() {
            networks_without_kept_places(nn, on)
        } else {
            vec![true; nn.num_places()]
        };
        for (r, p) in nn.places().iter().enumerate() {
            match on.place_by_id(&p.id) {
                Some(q) => rows[r].push((q.0, 1)),
                None if network_is_new[r] => base[r] = i64::from(p.initial),
                None => {}
            }
        }
        for (from, to) in removed {
            let Some(q) = on.place_by_id(from) else {
                return Err(TransformError::RemovedUnknown { id: from.clone() });
            };
            if nn.place_by_id(from).is_some() {
                return Err(TransformError::RemovedIsKept { id: from.clone() });
            }
            let Some(r) = nn.place_by_id(to) else {
                return Err(TransformError::RemovedTargetUnknown {
                    from: from.clone(),
                    to: to.clone(),
                });
            };
            rows[r.index()].push((q.0, 1));
        }
        derive::correct_base(Self::ROLE, &rows, &mut base, nn, on)?;
        Ok(Self::from_map(
            Linear::from_rows(rows, base, nn, on),
            on,
            nn,
        ))
    }

    explicit_constructors_and_sizes! {
        "An explicit transformation from a dense `|P_new| × |P_old|` matrix whose row ids are the new net's place ids in order and whose column ids are the old net's.",
        "An explicit transformation from `(new place, old place, coefficient)` entries and a base keyed by new place (missing entries are 0).",
        "Places of the new net.",
        "Places of the old net.",
        "The matrix and base in dense form, with the place ids of rows (new) and columns (old)."
    }

    /// Old places whose tokens this transform drops, so they must be empty when it applies.
    pub fn must_be_empty(&self) -> &[PlaceIdx] {
        &self.must_be_empty
    }

    /// `M_new = ST·M_old + ST_base`, written into `out` only when every check passes: no
    /// negative count, no overflow, no count above a capacity of the new net, no removed place
    /// with tokens and nowhere to send them, and every invariant of `new` holds. Never allocates
    /// on success, so it can run at a cycle boundary on the scan thread.
    pub fn apply(
        &self,
        old_marking: &[Tokens],
        new: &Program,
        out: &mut [Tokens],
    ) -> Result<(), TransformError> {
        self.map
            .apply_checked(ST, &self.must_be_empty, old_marking, new, out)
    }

    /// The timers (start of marking, µs) of the new marking: a kept place that was marked keeps
    /// its timer, any other marked place starts at `now_us`, an empty place has none.
    pub fn apply_timers(
        &self,
        old_since: &[Option<u64>],
        new_marking: &[Tokens],
        now_us: u64,
        out: &mut [Option<u64>],
    ) {
        carry_timers(&self.timer_from, old_since, new_marking, now_us, out);
    }
}

impl Between for StateTransform {
    const ROLE: Role = Role {
        what: ST,
        row_net: NEW,
        col_net: OLD,
    };

    fn axes<'n>(old: &'n Net, new: &'n Net) -> (&'n Net, &'n Net) {
        (new, old)
    }

    fn from_map(map: Linear, old: &Net, new: &Net) -> Self {
        let timer_from = timer_sources(new, old);
        let must_be_empty = old
            .places()
            .iter()
            .enumerate()
            .filter(|(c, p)| new.place_by_id(&p.id).is_none() && !map.reads(*c as u32))
            .map(|(c, _)| PlaceIdx(c as u32))
            .collect();
        StateTransform {
            map,
            timer_from,
            must_be_empty,
        }
    }
}

/// Timers of a target marking: a marked place with a source place (`from`) that has a timer
/// keeps it, any other marked place starts at `now_us`, an empty place has none.
fn carry_timers(
    from: &[Option<PlaceIdx>],
    source_since: &[Option<u64>],
    target: &[Tokens],
    now_us: u64,
    out: &mut [Option<u64>],
) {
    for (r, o) in out.iter_mut().enumerate() {
        let marked = target.get(r).is_some_and(|&m| m > 0);
        *o = if marked {
            from.get(r)
                .copied()
                .flatten()
                .and_then(|q| source_since.get(q.index()).copied().flatten())
                .or(Some(now_us))
        } else {
            None
        };
    }
}

/// A projection `Π·M_cand + Π_base` of a candidate (new) marking into the old net's place space,
/// against which the primary's marking is compared to measure drift.
#[derive(Clone, Debug, PartialEq)]
pub struct Projection {
    map: Linear,
    /// Per old place, the new place of the same id, whose timer it takes back at a revert.
    timer_from: Vec<Option<PlaceIdx>>,
}

impl Projection {
    /// The projection generated from place ids: each old place kept by id reads its new place;
    /// places only in the new net are dropped, places only in the old net read 0. Where the
    /// initial markings of kept places differ, the base is derived from the invariants of the
    /// old net so that they hold after the projection (`derive.rs`), or the projection is
    /// refused with the invariant named.
    pub fn generated(old: &Net, new: &Net) -> Result<Projection, TransformError> {
        let rows: Vec<Vec<(u32, i64)>> = old
            .places()
            .iter()
            .map(|p| match new.place_by_id(&p.id) {
                Some(q) => vec![(q.0, 1)],
                None => Vec::new(),
            })
            .collect();
        let mut base = vec![0; old.num_places()];
        derive::correct_base(Self::ROLE, &rows, &mut base, old, new)?;
        Ok(Self::from_map(
            Linear::from_rows(rows, base, old, new),
            old,
            new,
        ))
    }

    explicit_constructors_and_sizes! {
        "An explicit projection from a dense `|P_old| × |P_new|` matrix whose row ids are the old net's place ids in order and whose column ids are the new net's.",
        "An explicit projection from `(old place, new place, coefficient)` entries and a base keyed by old place (missing entries are 0).",
        "Places of the old net.",
        "Places of the new net.",
        "The matrix and base in dense form, with the place ids of rows (old) and columns (new)."
    }

    /// `M_old = Π·M_new + Π_base`, the marking a revert gives the old program back, written into
    /// `out` only when it is a marking of `old`: no negative count, no overflow, no count above
    /// a capacity, and every invariant `old` declares holds. Never allocates on success, so it
    /// can run at a cycle boundary on the scan thread.
    pub fn apply(
        &self,
        new_marking: &[Tokens],
        old: &Program,
        out: &mut [Tokens],
    ) -> Result<(), TransformError> {
        self.map.apply_checked(PROJ, &[], new_marking, old, out)
    }

    /// The timers (start of marking, µs) of a projected marking: an old place kept by id that
    /// is marked takes the timer of its new place, any other marked place starts at `now_us`.
    pub fn apply_timers(
        &self,
        new_since: &[Option<u64>],
        old_marking: &[Tokens],
        now_us: u64,
        out: &mut [Option<u64>],
    ) {
        carry_timers(&self.timer_from, new_since, old_marking, now_us, out);
    }

    /// Drift `‖Π·M_cand + Π_base − M_primary‖₁`, saturating at `u64::MAX`; a primary place
    /// beyond the slice counts as empty. Never allocates.
    pub fn drift(&self, candidate: &[Tokens], primary: &[Tokens]) -> u64 {
        let mut sum: u128 = 0;
        for r in 0..self.rows() {
            let p = i128::from(primary.get(r).copied().unwrap_or(0));
            let d = self.map.eval(r, candidate).saturating_sub(p);
            sum = sum.saturating_add(d.unsigned_abs());
        }
        u64::try_from(sum).unwrap_or(u64::MAX)
    }
}

impl Between for Projection {
    const ROLE: Role = Role {
        what: PROJ,
        row_net: OLD,
        col_net: NEW,
    };

    fn axes<'n>(old: &'n Net, new: &'n Net) -> (&'n Net, &'n Net) {
        (old, new)
    }

    fn from_map(map: Linear, old: &Net, new: &Net) -> Self {
        let timer_from = timer_sources(old, new);
        Projection { map, timer_from }
    }
}

/// Per place of `to`, the place of `from` with the same id, whose timer it carries.
fn timer_sources(to: &Net, from: &Net) -> Vec<Option<PlaceIdx>> {
    to.places()
        .iter()
        .map(|p| from.place_by_id(&p.id))
        .collect()
}

/// A matrix and base in dense form with the place ids of its rows and columns, for reports.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct DenseMatrix {
    /// Row place ids, in declaration order.
    pub row_ids: Vec<String>,
    /// Column place ids, in declaration order.
    pub col_ids: Vec<String>,
    /// `matrix[row][col]`.
    pub matrix: Vec<Vec<i64>>,
    /// One entry per row.
    pub base: Vec<i64>,
}

impl fmt::Display for DenseMatrix {
    /// An aligned table: a header of column ids, then per row its id, its coefficients, `|` and
    /// its base. Zeros print as `.` so that the structure stands out in a large matrix.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let cell = |k: i64| {
            if k == 0 {
                ".".to_string()
            } else {
                k.to_string()
            }
        };
        let id_w = self.row_ids.iter().map(String::len).max().unwrap_or(0);
        let widths: Vec<usize> = self
            .col_ids
            .iter()
            .enumerate()
            .map(|(c, id)| {
                self.matrix
                    .iter()
                    .filter_map(|row| row.get(c))
                    .map(|&k| cell(k).len())
                    .chain([id.len()])
                    .max()
                    .unwrap_or(1)
            })
            .collect();
        let base_w = self
            .base
            .iter()
            .map(|&k| k.to_string().len())
            .chain(["base".len()])
            .max()
            .unwrap_or(4);
        write!(f, "{:id_w$}", "")?;
        for (id, w) in self.col_ids.iter().zip(&widths) {
            write!(f, " {id:>w$}")?;
        }
        writeln!(f, " | {:>base_w$}", "base")?;
        for (r, id) in self.row_ids.iter().enumerate() {
            write!(f, "{id:<id_w$}")?;
            for (c, w) in widths.iter().enumerate() {
                let k = self.matrix.get(r).and_then(|row| row.get(c)).copied();
                write!(f, " {:>w$}", cell(k.unwrap_or(0)))?;
            }
            writeln!(f, " | {:>base_w$}", self.base.get(r).copied().unwrap_or(0))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
