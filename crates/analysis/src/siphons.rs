//! Minimal siphons and traps, by a bounded branching search, and Commoner's warning.
//!
//! A siphon S satisfies `•S ⊆ S•`: once empty it stays empty. A trap Q satisfies `Q• ⊆ •Q`: once
//! marked it stays marked. Their number is exponential in general, so the search counts the nodes
//! it visits and the sets it finds, and says when it stopped early. Inhibitor arcs are ignored
//! (the definitions are about Pre and Post).

use cetratus_net::{Net, PlaceIdx, TransIdx};

/// The outcome of an enumeration: the sets found (place indices, increasing) and whether the search
/// stopped at its limit before it was complete.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MinimalSets {
    /// The minimal sets found, each sorted.
    pub sets: Vec<Vec<usize>>,
    /// True when the limit stopped the search: there may be more minimal sets.
    pub truncated: bool,
}

/// Limits of the enumeration.
#[derive(Clone, Copy, Debug)]
pub struct SetLimits {
    /// Search nodes visited before giving up.
    pub max_nodes: usize,
    /// Minimal sets reported before giving up.
    pub max_sets: usize,
}

impl Default for SetLimits {
    fn default() -> Self {
        SetLimits {
            max_nodes: 200_000,
            max_sets: 1_000,
        }
    }
}

/// `ins[t]`/`outs[t]` as place lists: for siphons the inputs and outputs of each transition, for
/// traps the same swapped (a trap of N is a siphon of the reversed net).
fn enumerate(
    np: usize,
    ins: &[Vec<usize>],
    outs: &[Vec<usize>],
    lim: SetLimits,
    stop: &dyn Fn() -> bool,
) -> MinimalSets {
    // Transitions that produce into each place: the ones whose condition can break when p joins S.
    let mut feeders: Vec<Vec<usize>> = vec![Vec::new(); np];
    for (t, o) in outs.iter().enumerate() {
        for &p in o {
            feeders[p].push(t);
        }
    }
    let mut found: Vec<Vec<usize>> = Vec::new();
    let mut nodes = 0usize;
    let mut truncated = false;
    // Each stack entry is (members, excluded); the search for root r excludes places below r, so
    // every minimal set is found from its smallest place.
    'roots: for root in 0..np {
        let mut stack: Vec<(Vec<bool>, Vec<bool>)> = Vec::new();
        let mut s = vec![false; np];
        s[root] = true;
        let mut ex = vec![false; np];
        ex[..root].iter_mut().for_each(|e| *e = true);
        stack.push((s, ex));
        while let Some((s, ex)) = stack.pop() {
            nodes += 1;
            if nodes > lim.max_nodes
                || found.len() >= lim.max_sets
                || (nodes & 0x3FF == 0 && stop())
            {
                truncated = true;
                break 'roots;
            }
            let violated = (0..np)
                .filter(|&p| s[p])
                .flat_map(|p| feeders[p].iter().copied())
                .find(|&t| !ins[t].iter().any(|&q| s[q]));
            match violated {
                None => {
                    let set: Vec<usize> = (0..np).filter(|&p| s[p]).collect();
                    // A set containing one already found is not minimal.
                    if !found
                        .iter()
                        .any(|f| f.iter().all(|p| set.binary_search(p).is_ok()))
                    {
                        found.retain(|f| !set.iter().all(|p| f.binary_search(p).is_ok()));
                        found.push(set);
                    }
                }
                Some(t) => {
                    let mut ex2 = ex.clone();
                    for &q in &ins[t] {
                        if ex2[q] {
                            continue;
                        }
                        let mut s2 = s.clone();
                        s2[q] = true;
                        stack.push((s2, ex2.clone()));
                        ex2[q] = true;
                    }
                }
            }
        }
    }
    found.sort();
    MinimalSets {
        sets: found,
        truncated,
    }
}

fn io(net: &Net) -> (Vec<Vec<usize>>, Vec<Vec<usize>>) {
    let nt = net.num_transitions();
    let ins = (0..nt as u32)
        .map(|t| {
            net.pre(TransIdx(t))
                .iter()
                .map(|&(p, _)| p.index())
                .collect()
        })
        .collect();
    let outs = (0..nt as u32)
        .map(|t| {
            net.post(TransIdx(t))
                .iter()
                .map(|&(p, _)| p.index())
                .collect()
        })
        .collect();
    (ins, outs)
}

/// The minimal (nonempty) siphons of `net`.
pub fn minimal_siphons(net: &Net, lim: SetLimits) -> MinimalSets {
    minimal_siphons_until(net, lim, &|| false)
}

/// [`minimal_siphons`], truncated as soon as `stop` returns true (time is up, Ctrl-C).
pub fn minimal_siphons_until(net: &Net, lim: SetLimits, stop: &dyn Fn() -> bool) -> MinimalSets {
    let (ins, outs) = io(net);
    enumerate(net.num_places(), &ins, &outs, lim, stop)
}

/// The minimal (nonempty) traps of `net`.
pub fn minimal_traps(net: &Net, lim: SetLimits) -> MinimalSets {
    minimal_traps_until(net, lim, &|| false)
}

/// [`minimal_traps`], truncated as soon as `stop` returns true.
pub fn minimal_traps_until(net: &Net, lim: SetLimits, stop: &dyn Fn() -> bool) -> MinimalSets {
    let (ins, outs) = io(net);
    enumerate(net.num_places(), &outs, &ins, lim, stop)
}

/// The largest trap inside `set` (possibly empty), by removing places that leak tokens out of it.
pub fn maximal_trap_in(net: &Net, set: &[usize]) -> Vec<usize> {
    let mut q: Vec<bool> = vec![false; net.num_places()];
    for &p in set {
        q[p] = true;
    }
    loop {
        let leaking = (0..q.len()).filter(|&p| q[p]).find(|&p| {
            net.consumers(PlaceIdx(p as u32))
                .iter()
                .any(|&(t, _)| !net.post(t).iter().any(|&(r, _)| q[r.index()]))
        });
        match leaking {
            Some(p) => q[p] = false,
            None => break,
        }
    }
    (0..q.len()).filter(|&p| q[p]).collect()
}

/// True when the siphon holds a trap marked at M0 (Commoner's condition for that siphon).
pub fn holds_marked_trap(net: &Net, siphon: &[usize]) -> bool {
    maximal_trap_in(net, siphon)
        .iter()
        .any(|&p| net.places()[p].initial > 0)
}
