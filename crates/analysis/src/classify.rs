//! Net classes: ordinary, pure, state machine, marked graph, free choice, extended free choice.

use cetratus_net::{Net, PlaceIdx, TransIdx};
use serde::Serialize;

/// Which classical subclasses the net belongs to. Inhibitor arcs are reported but do not change
/// the classes, which are defined on Pre and Post alone.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Classification {
    /// Every arc weight is 1.
    pub ordinary: bool,
    /// No place is both an input and an output of the same transition (no self-loop).
    pub pure: bool,
    /// Ordinary, and every transition has exactly one input and one output place.
    pub state_machine: bool,
    /// Ordinary, and every place has exactly one input and one output transition.
    pub marked_graph: bool,
    /// Ordinary, and for every arc p → t: `p• = {t}` or `•t = {p}`.
    pub free_choice: bool,
    /// Ordinary, and two places sharing an output transition have the same output transitions.
    pub extended_free_choice: bool,
    /// The net has inhibitor arcs (the classes above ignore them).
    pub inhibitor_arcs: bool,
    /// Some place has a finite capacity.
    pub capacities: bool,
}

/// Classifies `net`.
pub fn classify(net: &Net) -> Classification {
    let np = net.num_places();
    let nt = net.num_transitions();
    let ts = || (0..nt as u32).map(TransIdx);
    let ps = || (0..np as u32).map(PlaceIdx);
    let ordinary = ts().all(|t| {
        net.pre(t).iter().all(|&(_, w)| w == 1) && net.post(t).iter().all(|&(_, w)| w == 1)
    });
    let pure = ts().all(|t| {
        net.pre(t)
            .iter()
            .all(|&(p, _)| !net.post(t).iter().any(|&(q, _)| q == p))
    });
    let state_machine = ordinary && ts().all(|t| net.pre(t).len() == 1 && net.post(t).len() == 1);
    let marked_graph =
        ordinary && ps().all(|p| net.consumers(p).len() == 1 && net.producers(p).len() == 1);
    let free_choice = ordinary
        && ps().all(|p| {
            let out = net.consumers(p);
            out.len() <= 1 || out.iter().all(|&(t, _)| net.pre(t).len() == 1)
        });
    let same_outputs = |a: PlaceIdx, b: PlaceIdx| {
        let x: Vec<TransIdx> = net.consumers(a).iter().map(|&(t, _)| t).collect();
        let y: Vec<TransIdx> = net.consumers(b).iter().map(|&(t, _)| t).collect();
        x == y
    };
    // Two places share an output transition exactly when both are inputs of some t.
    let extended_free_choice = ordinary
        && ts().all(|t| {
            let pre = net.pre(t);
            pre.iter().all(|&(p, _)| same_outputs(p, pre[0].0))
        });
    Classification {
        ordinary,
        pure,
        state_machine,
        marked_graph,
        free_choice,
        extended_free_choice,
        inhibitor_arcs: ts().any(|t| !net.inhibitors(t).is_empty()),
        capacities: net.places().iter().any(|p| p.capacity.is_some()),
    }
}
