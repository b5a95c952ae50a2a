//! Declared place invariants: `Σ wᵢ·M(pᵢ) = c`, checked at load against M0 and on demand.

use std::fmt;
use std::sync::Arc;

use cetratus_net::{Net, PlaceIdx, Tokens, TransIdx};

use crate::guard::SyntaxError;

/// A linear place invariant the program declares, `Σ weight·M(place) = constant`.
#[derive(Clone, Debug, PartialEq)]
pub struct Invariant {
    expr: Arc<str>,
    terms: Vec<(PlaceIdx, i64)>,
    constant: i64,
}

impl Invariant {
    /// The invariant as written.
    pub fn expr(&self) -> &str {
        &self.expr
    }
    /// The weighted places, in the order written (a place written twice appears twice).
    pub fn terms(&self) -> &[(PlaceIdx, i64)] {
        &self.terms
    }
    /// The right-hand side.
    pub fn constant(&self) -> i64 {
        self.constant
    }

    /// The same invariant resolved against another net (an update's), by place id; `None` when
    /// that net lacks one of its places.
    pub fn on_net(&self, net: &Net) -> Option<Invariant> {
        Invariant::parse(&self.expr, net).ok()
    }

    /// The left-hand side at a marking; places beyond the marking's length count as empty.
    pub fn weighted_sum(&self, marking: &[Tokens]) -> i128 {
        self.terms
            .iter()
            .map(|&(p, w)| i128::from(w) * i128::from(marking.get(p.index()).copied().unwrap_or(0)))
            .sum()
    }

    /// The first transition whose firing changes the weighted sum, with the change: `None` when
    /// the invariant is a P-invariant of the net (`y·C = 0`), so every reachable marking keeps it.
    pub fn first_breaking_transition(&self, net: &Net) -> Option<(TransIdx, i64)> {
        (0..net.num_transitions() as u32)
            .map(TransIdx)
            .find_map(|t| {
                let change: i64 = net
                    .delta(t)
                    .iter()
                    .map(|&(p, d)| {
                        let w: i64 = self
                            .terms
                            .iter()
                            .filter(|(q, _)| *q == p)
                            .map(|(_, w)| w)
                            .sum();
                        w.saturating_mul(d)
                    })
                    .fold(0i64, i64::saturating_add);
                (change != 0).then_some((t, change))
            })
    }

    /// Parses `[k*]P (+|-) [k*]Q … = c` against the net's places.
    pub(crate) fn parse(src: &str, net: &Net) -> Result<Invariant, SyntaxError> {
        let toks = crate::guard::lex_for_invariant(src)?;
        let mut i = 0;
        let mut terms = Vec::new();
        let mut sign = 1i64;
        let expected_term = "expected a place or a weight such as `2*P14`";
        loop {
            let (tok, off) = &toks[i];
            let (weight, place_tok) = match tok {
                InvTok::Int(k) => {
                    i += 1;
                    if !matches!(toks[i].0, InvTok::Star) {
                        return Err(SyntaxError::new(
                            toks[i].1,
                            "expected `*` after a weight, e.g. `2*P14`",
                        ));
                    }
                    i += 1;
                    (*k, i)
                }
                InvTok::Name(_) => (1, i),
                _ => return Err(SyntaxError::new(*off, expected_term)),
            };
            let (InvTok::Name(name), off) = &toks[place_tok] else {
                return Err(SyntaxError::new(
                    toks[place_tok].1,
                    "expected a place after `*`",
                ));
            };
            let p = net.place_by_id(name).ok_or_else(|| {
                SyntaxError::new(
                    *off,
                    format!("unknown place `{name}` in invariant; expected a place id of the net"),
                )
            })?;
            let w = weight
                .checked_mul(sign)
                .ok_or_else(|| SyntaxError::new(*off, "weight too large"))?;
            terms.push((p, w));
            i = place_tok + 1;
            match &toks[i].0 {
                InvTok::Plus => sign = 1,
                InvTok::Minus => sign = -1,
                InvTok::Eq => break,
                _ => return Err(SyntaxError::new(toks[i].1, "expected `+`, `-` or `=`")),
            }
            i += 1;
        }
        i += 1;
        let neg = matches!(toks[i].0, InvTok::Minus);
        if neg {
            i += 1;
        }
        let InvTok::Int(c) = toks[i].0 else {
            return Err(SyntaxError::new(
                toks[i].1,
                "expected an integer after `=`, e.g. `= 1`",
            ));
        };
        i += 1;
        if !matches!(toks[i].0, InvTok::End) {
            return Err(SyntaxError::new(
                toks[i].1,
                "expected the end of the invariant after the constant",
            ));
        }
        Ok(Invariant {
            expr: Arc::from(src.trim()),
            terms,
            constant: if neg { -c } else { c },
        })
    }
}

/// Tokens of the invariant syntax, a small subset of the guard tokens.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum InvTok {
    Name(String),
    Int(i64),
    Plus,
    Minus,
    Star,
    Eq,
    End,
}

/// A marking on which a declared invariant does not hold.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct InvariantViolation {
    /// Which invariant, in declaration order.
    pub index: usize,
    /// The invariant as written (shared, so reporting a violation does not allocate).
    pub expr: Arc<str>,
    /// The left-hand side at the marking.
    pub actual: i128,
    /// The declared constant.
    pub expected: i64,
}

impl fmt::Display for InvariantViolation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "invariant #{} `{}` does not hold: the left side is {}, expected {}",
            self.index + 1,
            self.expr,
            self.actual,
            self.expected
        )
    }
}

impl std::error::Error for InvariantViolation {}

/// Checks invariants in order and reports the first that fails.
pub(crate) fn check(
    invariants: &[Invariant],
    marking: &[Tokens],
) -> Result<(), InvariantViolation> {
    for (index, inv) in invariants.iter().enumerate() {
        let actual = inv.weighted_sum(marking);
        if actual != i128::from(inv.constant) {
            return Err(InvariantViolation {
                index,
                expr: Arc::clone(&inv.expr),
                actual,
                expected: inv.constant,
            });
        }
    }
    Ok(())
}
