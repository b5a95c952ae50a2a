//! The execution order of a network's elements (see the parent module).

use std::collections::HashMap;

use super::element::{Element, Kind};
use super::Refused;

/// The elements' indices in execution order (see the module's documentation).
pub(super) fn execution_order(elements: &[Element]) -> Result<Vec<usize>, Refused> {
    let by_id: HashMap<u64, usize> = elements
        .iter()
        .enumerate()
        .map(|(i, e)| (e.id, i))
        .collect();
    let connectors: HashMap<&str, usize> = elements
        .iter()
        .enumerate()
        .filter_map(|(i, e)| match &e.kind {
            Kind::Connector { name } => Some((name.as_str(), i)),
            _ => None,
        })
        .collect();
    let mut deps: Vec<Vec<usize>> = Vec::with_capacity(elements.len());
    for e in elements {
        let mut d = Vec::new();
        for from in e.inputs.iter().flat_map(|p| &p.from) {
            let i = by_id.get(&from.id).ok_or_else(|| {
                (
                    e.at,
                    format!("a connection to element {}", from.id),
                    "the network names an element it does not have; export it again".to_string(),
                )
            })?;
            d.push(*i);
        }
        if let Kind::Continuation { name } = &e.kind {
            let i = connectors.get(name.as_str()).ok_or_else(|| {
                (
                    e.at,
                    format!("the continuation `{name}`"),
                    "it has no connector of that name".to_string(),
                )
            })?;
            d.push(*i);
        }
        deps.push(d);
    }
    let mut roots: Vec<usize> = (0..elements.len()).collect();
    roots.sort_by_key(|&i| {
        let e = &elements[i];
        (e.order == 0, e.order, e.position)
    });
    // A loop that the walk enters at an element holding the scan before's value is cut where it
    // closes, as the walk goes. One entered elsewhere is cut at such an element and the walk
    // starts again: a network has few of those, and a bound on the work keeps a hostile one
    // cheap.
    let restarts = (MAX_WALK_WORK / elements.len().max(1)).max(MIN_RESTARTS);
    let mut cut = std::collections::HashSet::new();
    for _ in 0..=restarts {
        match walk(elements, &deps, &roots, &cut)? {
            Walk::Order(order) => return Ok(order),
            Walk::Cut(reader, held) => {
                cut.insert((reader, held));
            }
        }
    }
    Err((
        elements.first().map_or(0, |e| e.at),
        format!("a network of {} elements with more than {restarts} feedback loops that pass through functions first", elements.len()),
        "split it into several networks or POUs".into(),
    ))
}

/// How many element visits the walks of one network may make in all, restarts included.
pub(super) const MAX_WALK_WORK: usize = 5_000_000;

/// How many times the walk may start again on any network, however large.
pub(super) const MIN_RESTARTS: usize = 64;

/// What a walk of [`execution_order`] found.
pub(super) enum Walk {
    /// Every element after what it reads.
    Order(Vec<usize>),
    /// A loop, to cut where `reader` reads `held`, which holds the scan before's value.
    Cut(usize, usize),
}

/// The depth-first walk of [`execution_order`]: each element after what it reads (less the cut
/// reads), from the roots in their order; a loop found is returned to be cut, or refused when no
/// element on it holds the scan before's value.
pub(super) fn walk(
    elements: &[Element],
    deps: &[Vec<usize>],
    roots: &[usize],
    cut: &std::collections::HashSet<(usize, usize)>,
) -> Result<Walk, Refused> {
    #[derive(Clone, Copy, PartialEq)]
    enum Mark {
        New,
        Open,
        Done,
    }
    let mut mark = vec![Mark::New; elements.len()];
    let mut order = Vec::with_capacity(elements.len());
    let mut stack: Vec<(usize, usize)> = Vec::new();
    for &root in roots {
        if mark[root] != Mark::New {
            continue;
        }
        mark[root] = Mark::Open;
        stack.push((root, 0));
        while let Some(top) = stack.last_mut() {
            let (i, next) = *top;
            let Some(&d) = deps[i].get(next) else {
                stack.pop();
                mark[i] = Mark::Done;
                order.push(i);
                continue;
            };
            top.1 += 1;
            if cut.contains(&(i, d)) {
                continue;
            }
            match mark[d] {
                Mark::New => {
                    mark[d] = Mark::Open;
                    stack.push((d, 0));
                }
                // The reader reads the value the element held at the scan before.
                Mark::Open if holds_last_value(&elements[d]) => {}
                Mark::Open => return loop_cut(elements, &stack, d),
                Mark::Done => {}
            }
        }
    }
    Ok(Walk::Order(order))
}

/// Where to cut the loop that the walk's `stack` closes at `d`: the read of an element on it
/// that holds the scan before's value.
pub(super) fn loop_cut(
    elements: &[Element],
    stack: &[(usize, usize)],
    d: usize,
) -> Result<Walk, Refused> {
    let from = stack.iter().rposition(|&(i, _)| i == d).unwrap_or(0);
    let on_loop: Vec<usize> = stack[from..].iter().map(|&(i, _)| i).collect();
    for (k, &held) in on_loop.iter().enumerate() {
        if holds_last_value(&elements[held]) {
            // Each element on the stack reads the one above it; the last reads `d`.
            let reader = if k == 0 {
                on_loop[on_loop.len() - 1]
            } else {
                on_loop[k - 1]
            };
            return Ok(Walk::Cut(reader, held));
        }
    }
    Err((
        elements[d].at,
        format!("a loop in the network through element {}", elements[d].id),
        "a feedback loop must pass through a function block instance or an in-out variable, which holds the value of the scan before".into(),
    ))
}

/// Whether a loop may pass through an element: its output keeps the scan before's value.
pub(super) fn holds_last_value(e: &Element) -> bool {
    matches!(
        e.kind,
        Kind::InOut { .. }
            | Kind::Block {
                instance: Some(_),
                ..
            }
    )
}
