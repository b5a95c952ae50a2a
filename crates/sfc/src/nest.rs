//! Actions whose body is a second chart (nested charts): read once, one level deep, and merged
//! into the POU's chart with qualified names (docs/sfc.md, *Nested charts*).
//!
//! A nested chart's step `S` of action `A` becomes the place `A__S` and its transition `T` the
//! transition `A__T` (a dot is not an identifier character of the guard language, so the
//! separator is `__`; the place's display name is `A.S`). The chart evolves only while the
//! action's `Q` is on: `Q` drives a generated BOOL variable named after the action, every
//! nested transition's guard is `A && (condition)`, and each nested step gets a *held* place,
//! `A__S__held`, with two transitions: `A__S__hold` (guard `!A`) moves an active step's token
//! there when the action goes off, and `A__S__resume` (guard `A`) moves it back when the action
//! is on again. The chart thus stops where it was and resumes there; its initial step starts
//! held, so the nested chart starts at its initial step in the scan after its first activation.
//! A chart nested in a nested chart is refused: nesting is one level, whatever the file says.

use std::collections::{HashMap, HashSet};
use std::ops::Range;

use crate::chart::{self, ActionRef, Chart};
use crate::pou::{self, Body, Pou};
use crate::source::Source;
use crate::SfcError;

/// The separator between an action's name and the name of one of its chart's elements.
pub(crate) const SEP: &str = "__";

/// A nested chart merged into the POU's chart.
#[derive(Clone, Debug)]
pub(crate) struct Nest {
    /// The action's name, as declared: also the BOOL variable that its `Q` drives.
    pub action: String,
    /// Its steps in the merged chart.
    pub steps: Range<usize>,
    /// Its transitions in the merged chart.
    pub transitions: Range<usize>,
}

impl Nest {
    /// The nest that holds step `s` of the merged chart. The nests are in the order merged, so
    /// their ranges ascend, and are searched by halving.
    pub(crate) fn of_step(nests: &[Nest], s: usize) -> Option<&Nest> {
        let i = nests.partition_point(|n| n.steps.end <= s);
        nests.get(i).filter(|n| n.steps.contains(&s))
    }

    /// The nest that holds transition `t` of the merged chart (searched as in [`Nest::of_step`]).
    pub(crate) fn of_transition(nests: &[Nest], t: usize) -> Option<&Nest> {
        let i = nests.partition_point(|n| n.transitions.end <= t);
        nests.get(i).filter(|n| n.transitions.contains(&t))
    }
}

/// Whether `name` is a named action of `pou` with an SFC body; its name as declared.
pub(crate) fn sfc_action<'p>(pou: &'p Pou, name: &str) -> Option<&'p str> {
    (pou.action(name))
        .filter(|a| matches!(&a.body, Body::Other { language, .. } if language == "SFC"))
        .map(|a| a.name.as_str())
}

/// The POU's chart `main` with the charts of the SFC-bodied actions that it associates merged
/// in, and where each sits; the nested charts as drawn.
pub(crate) fn merge(
    source: &Source,
    pou: &Pou,
    main: &Chart,
) -> Result<(Chart, Vec<Nest>, Vec<Chart>), SfcError> {
    let mut merged = main.clone();
    let mut nests: Vec<Nest> = Vec::new();
    let mut drawn: Vec<Chart> = Vec::new();
    let mut charts = HashMap::new();
    for (location, node) in pou::sfc_bodies(pou) {
        charts.entry(location).or_insert(node);
    }
    let mut merged_actions = HashSet::new();
    for a in &main.associations {
        let ActionRef::Reference(name) = &a.action else {
            continue;
        };
        let Some(action) = sfc_action(pou, name) else {
            continue;
        };
        if !merged_actions.insert(action) {
            continue;
        }
        let location = format!("action {action}");
        let Some(&node) = charts.get(&location) else {
            continue;
        };
        let nested = chart::read(source, pou, &location, node)?;
        // One level: a nested chart that associates an SFC-bodied action is refused.
        for inner in &nested.associations {
            if let ActionRef::Reference(n) = &inner.action {
                if let Some(deeper) = sfc_action(pou, n) {
                    return Err(SfcError::Unsupported {
                        pos: source.pos(inner.at),
                        pou: pou.name.clone(),
                        construct: format!(
                            "the action `{deeper}` with a SFC body inside the nested chart of action `{action}`"
                        ),
                        message: "charts are nested one level deep at most; write the inner chart's steps into the chart of the action that uses it".into(),
                    });
                }
            }
        }
        let step_base = merged.steps.len();
        let trans_base = merged.transitions.len();
        for s in &nested.steps {
            let mut s = s.clone();
            s.name = format!("{action}{SEP}{}", s.name);
            merged.push_step(s);
        }
        for t in &nested.transitions {
            let mut t = t.clone();
            let base = match &t.name {
                Some(n) if !n.trim().is_empty() => n.trim().to_string(),
                _ => format!("T{}", t.local_id),
            };
            t.name = Some(format!("{action}{SEP}{base}"));
            for s in t.from.iter_mut().chain(t.to.iter_mut()) {
                *s += step_base;
            }
            merged.transitions.push(t);
        }
        for inner in &nested.associations {
            let mut inner = inner.clone();
            inner.step += step_base;
            merged.associations.push(inner);
        }
        merged.action_blocks += nested.action_blocks;
        merged
            .jumps
            .extend(nested.jumps.iter().map(|j| format!("{action}{SEP}{j}")));
        merged.selection_divergences += nested.selection_divergences;
        merged.selection_convergences += nested.selection_convergences;
        merged.simultaneous_divergences += nested.simultaneous_divergences;
        merged.simultaneous_convergences += nested.simultaneous_convergences;
        for (name, count) in &nested.ignored_vendor_data {
            match merged
                .ignored_vendor_data
                .iter_mut()
                .find(|(n, _)| n == name)
            {
                Some((_, c)) => *c += count,
                None => merged.ignored_vendor_data.push((name.clone(), *count)),
            }
        }
        nests.push(Nest {
            action: action.to_string(),
            steps: step_base..merged.steps.len(),
            transitions: trans_base..merged.transitions.len(),
        });
        drawn.push(nested);
    }
    Ok((merged, nests, drawn))
}
