//! Structural checks of an IEC 61131-3 chart imported as a net (docs/sfc.md), which IEC editors do
//! not make: a step that can be active twice (an unsafe chart: a step activated again through
//! parallel branches before it was left), a step that is never active, and a parallel branch
//! that never joins the other branches of its fork.
//!
//! The first two come from the behaviour already explored by [`crate::check`] (each place's
//! bound); when that run was partial, unreachable steps fall back to the structural test (a step
//! the net cannot mark whatever the guards), and the unsafe test says it could not tell. The
//! third is structural. Every walk is a loop with a visited set.

use std::collections::VecDeque;
use std::fmt;

use cetratus_net::{Net, PlaceIdx, TransIdx};
use serde::Serialize;

use crate::report::{Bound, Report};

/// What the chart checks found; each list is empty for a well-formed chart.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct SfcFindings {
    /// Steps that can hold two activations at once: the chart is not safe there.
    pub unsafe_steps: Vec<String>,
    /// Steps that no reachable state activates.
    pub unreachable_steps: Vec<String>,
    /// Parallel branches that never join: (fork transition, first step of the branch).
    pub unjoined_branches: Vec<(String, String)>,
    /// The exploration was partial: `unsafe_steps` may be incomplete and `unreachable_steps`
    /// holds only the steps the structure cannot reach.
    pub partial: bool,
}

impl SfcFindings {
    /// One warning per finding, naming the steps and what to do.
    pub fn warnings(&self) -> Vec<String> {
        let mut w = Vec::new();
        if !self.unsafe_steps.is_empty() {
            w.push(format!("unsafe SFC: step {} can be active twice at once, activated again through parallel branches before it was left; join the branches before the step, or give each branch its own step", self.unsafe_steps.join(", ")));
        }
        if !self.unreachable_steps.is_empty() {
            w.push(format!(
                "unreachable steps: {} never become active; connect them, or remove them",
                self.unreachable_steps.join(", ")
            ));
        }
        for (t, p) in &self.unjoined_branches {
            w.push(format!("the parallel branch starting at step {p} (after {t}) never joins the other branches of its divergence; end it with a simultaneous convergence"));
        }
        w
    }

    /// True when nothing was found.
    pub fn is_clean(&self) -> bool {
        self.unsafe_steps.is_empty()
            && self.unreachable_steps.is_empty()
            && self.unjoined_branches.is_empty()
    }
}

/// The chart checks of `net`, whose behaviour `report` describes ([`crate::check`] of the same
/// net).
pub fn check_chart(net: &Net, report: &Report) -> SfcFindings {
    let bound = |i: usize| report.max_tokens.0.get(i).map(|(_, b)| b);
    let explored = !report.partial && report.graph != "none";
    let mut out = SfcFindings {
        partial: !explored,
        ..SfcFindings::default()
    };
    let markable = markable(net);
    for (i, p) in net.places().iter().enumerate() {
        match bound(i) {
            Some(Bound::Tokens(n)) if *n > 1 => out.unsafe_steps.push(p.id.clone()),
            Some(Bound::Omega) => out.unsafe_steps.push(p.id.clone()),
            _ => {}
        }
        let never = if explored {
            matches!(bound(i), Some(Bound::Tokens(0)))
        } else {
            !markable[i]
        };
        if never {
            out.unreachable_steps.push(p.id.clone());
        }
    }
    out.unjoined_branches = unjoined_branches(net);
    out
}

/// Places the net lets be marked, guards ignored (a fixpoint over transitions).
fn markable(net: &Net) -> Vec<bool> {
    let mut m: Vec<bool> = net.places().iter().map(|p| p.initial > 0).collect();
    let mut changed = true;
    while changed {
        changed = false;
        for t in 0..net.num_transitions() {
            let t = TransIdx(t as u32);
            if net.pre(t).iter().all(|&(p, _)| m[p.index()]) {
                for &(p, _) in net.post(t) {
                    if !std::mem::replace(&mut m[p.index()], true) {
                        changed = true;
                    }
                }
            }
        }
    }
    m
}

/// The joins (transitions with two or more preceding steps) that a branch starting at `start`
/// reaches and cannot pass alone: walking forward through plain transitions, and through a join
/// only when the branch itself reaches all its preceding steps (a nested fork and join inside it).
fn open_joins(net: &Net, start: PlaceIdx) -> Vec<bool> {
    let mut seen = vec![false; net.num_places()];
    let mut reached = vec![false; net.num_transitions()];
    let mut passed = vec![false; net.num_transitions()];
    let mut todo = VecDeque::from([start]);
    seen[start.index()] = true;
    loop {
        while let Some(p) = todo.pop_front() {
            for &(t, _) in net.consumers(p) {
                if net.pre(t).len() >= 2 {
                    reached[t.index()] = true;
                    continue;
                }
                for &(q, _) in net.post(t) {
                    if !std::mem::replace(&mut seen[q.index()], true) {
                        todo.push_back(q);
                    }
                }
            }
        }
        let mut progressed = false;
        for t in 0..net.num_transitions() {
            let tt = TransIdx(t as u32);
            if reached[t] && !passed[t] && net.pre(tt).iter().all(|&(p, _)| seen[p.index()]) {
                passed[t] = true;
                progressed = true;
                for &(q, _) in net.post(tt) {
                    if !std::mem::replace(&mut seen[q.index()], true) {
                        todo.push_back(q);
                    }
                }
            }
        }
        if !progressed {
            break;
        }
    }
    reached
        .iter()
        .zip(&passed)
        .map(|(&r, &p)| r && !p)
        .collect()
}

/// For each fork (a transition with two or more following steps), the branches that reach no
/// join that another branch of the fork reaches too.
fn unjoined_branches(net: &Net) -> Vec<(String, String)> {
    let mut out = Vec::new();
    for t in 0..net.num_transitions() {
        let t = TransIdx(t as u32);
        let branches: Vec<PlaceIdx> = net.post(t).iter().map(|&(p, _)| p).collect();
        if branches.len() < 2 {
            continue;
        }
        let joins: Vec<Vec<bool>> = branches.iter().map(|&b| open_joins(net, b)).collect();
        for (i, &b) in branches.iter().enumerate() {
            let meets = (0..net.num_transitions())
                .any(|j| joins[i][j] && joins.iter().enumerate().any(|(k, o)| k != i && o[j]));
            if !meets {
                out.push((net.transition(t).id.clone(), net.place(b).id.clone()));
            }
        }
    }
    out
}

impl fmt::Display for SfcFindings {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "\nsfc chart")?;
        let list = |v: &[String]| {
            if v.is_empty() {
                "none".to_string()
            } else {
                v.join(", ")
            }
        };
        writeln!(
            f,
            "  unsafe steps (active twice through parallel branches): {}{}",
            list(&self.unsafe_steps),
            if self.partial {
                " (exploration partial: not known)"
            } else {
                ""
            }
        )?;
        writeln!(f, "  unreachable steps: {}", list(&self.unreachable_steps))?;
        let branches: Vec<String> = self
            .unjoined_branches
            .iter()
            .map(|(t, p)| format!("{p} (from {t})"))
            .collect();
        writeln!(
            f,
            "  parallel branches that never join: {}",
            list(&branches)
        )
    }
}
