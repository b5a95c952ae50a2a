//! `[st]` resolved: the POU compiled with the chart's entries (`[st.bodies]`, then
//! `[st.conditions]`, each in document order), wired to the program's signals and, through
//! `[st.steps]`, to its places; errors at the file:line:column of the text at fault.

use std::sync::Arc;

use cetratus_net::Net;
use cetratus_st::parse::parse_library;
use cetratus_st::{compile_entry_texts, Diagnostic};
use toml::Spanned;

use super::resolve::in_document_order;
use crate::body::Body;
use crate::source::{Doc, Origin, StDecl};
use crate::st::{ChartTexts, StProgram};
use crate::value::Signal;
use crate::{Program, ProgramError};

/// The texts of a chart's entries, in the order they are compiled: bodies, then conditions.
fn entry_texts(decl: &StDecl) -> Vec<(&Spanned<String>, &Spanned<String>, bool)> {
    let bodies = in_document_order(&decl.bodies).into_iter();
    let conditions = in_document_order(&decl.conditions).into_iter();
    (bodies.map(|(k, t)| (k, t, true)))
        .chain(conditions.map(|(k, t)| (k, t, false)))
        .collect()
}

/// `[st]` compiled: the POU named, with the chart's entries, wired to the program's inputs,
/// outputs and places. An error in the ST is placed in the file where its text says (exact for
/// a literal string, `'''…'''`, whose characters are the text's).
pub(super) fn structured_text(
    o: &Origin,
    doc: &Doc,
    net: &Net,
    signals: (&[Signal], &[Signal]),
) -> Result<Option<Arc<StProgram>>, ProgramError> {
    let Some(decl) = &doc.st else {
        return Ok(None);
    };
    let decl = decl.get_ref();
    let located = |at: &Spanned<String>, what: &str, d: Diagnostic| {
        o.err(
            o.in_string(at, d.pos as usize),
            format!("in {what}: {}", d.message),
        )
    };
    let in_source = |d| located(&decl.source, "the Structured Text", d);
    let lib = parse_library(decl.source.get_ref()).map_err(in_source)?;
    let texts = entry_texts(decl);
    let named: Vec<(&str, &str, bool)> = (texts.iter())
        .map(|&(key, text, body)| (key.get_ref().as_str(), text.get_ref().as_str(), body))
        .collect();
    let unit = compile_entry_texts(&lib, Some(decl.pou.get_ref()), &named).map_err(|e| match e
        .entry
        .and_then(|k| texts.get(k))
    {
        Some(&(key, text, body)) => located(text, &entry_what(key, body), e.diagnostic),
        None => in_source(e.diagnostic),
    })?;
    if decl.is_chart() && !unit.code.ops.is_empty() {
        return Err(o.err(decl.pou.span().start, format!("`[st] pou`: the body of `{}` does not run in a chart, whose actions are `[st.bodies]`; move its statements into one of them", unit.name)));
    }
    let mut st = StProgram::wire(unit, signals.0, signals.1)
        .map_err(|w| o.err(decl.pou.span().start, format!("`[st] pou`: {}", w.message)))?;
    let steps = in_document_order(&decl.steps);
    let pairs = steps
        .iter()
        .map(|(p, v)| (p.get_ref().as_str(), v.get_ref().as_str()));
    st.wire_steps(net, pairs).map_err(|w| {
        let at = steps.iter().find(|(p, _)| *p.get_ref() == w.name);
        o.err(at.map_or(0, |(p, _)| p.span().start), w.message)
    })?;
    Ok(Some(Arc::new(st)))
}

/// What an entry is, for messages: `the ST body `Act`` or `the ST condition of `T1``.
fn entry_what(key: &Spanned<String>, body: bool) -> String {
    match body {
        true => format!("the ST body `{}`", key.get_ref()),
        false => format!("the ST condition of `{}`", key.get_ref()),
    }
}

/// The bodies of the program's ST: the POU's own, or a chart's `[st.bodies]`, none of them
/// named as a body of `[bodies]` (`guard_bodies`).
pub(super) fn st_bodies(
    o: &Origin,
    decl: &StDecl,
    st: &Arc<StProgram>,
    guard_bodies: &std::collections::BTreeMap<Spanned<String>, Spanned<String>>,
) -> Result<Vec<Body>, ProgramError> {
    if !decl.is_chart() {
        let (pou, source) = (decl.pou.get_ref(), decl.source.get_ref());
        return Ok(vec![Body::structured_text(pou, source, st.clone(), None)]);
    }
    let mut out = Vec::new();
    for (k, (key, text)) in in_document_order(&decl.bodies).into_iter().enumerate() {
        if guard_bodies.keys().any(|b| b.get_ref() == key.get_ref()) {
            return Err(o.err(
                key.span().start,
                format!(
                    "the body `{}` is in both `[bodies]` and `[st.bodies]`; rename one",
                    key.get_ref()
                ),
            ));
        }
        let entry = Some(k as u32);
        out.push(Body::structured_text(
            key.get_ref(),
            text.get_ref(),
            st.clone(),
            entry,
        ));
    }
    Ok(out)
}

/// Per transition of `net`, the entry of its `[st.conditions]`, if it has one; a transition
/// the net lacks, or one with a `[guards]` entry too, is refused.
pub(super) fn st_conditions(
    o: &Origin,
    doc: &Doc,
    net: &Net,
) -> Result<Vec<Option<u32>>, ProgramError> {
    let mut out = vec![None; net.num_transitions()];
    let Some(decl) = &doc.st else {
        return Ok(out);
    };
    let decl = decl.get_ref();
    let first = decl.bodies.len() as u32;
    for (j, (key, _)) in in_document_order(&decl.conditions).into_iter().enumerate() {
        let Some(t) = net.transition_by_id(key.get_ref()) else {
            return Err(o.err(
                key.span().start,
                format!(
                    "`[st.conditions]` names the transition `{}`, which the net does not have",
                    key.get_ref()
                ),
            ));
        };
        if doc.guards.keys().any(|g| g.get_ref() == key.get_ref()) {
            return Err(o.err(
                key.span().start,
                format!(
                    "`{}` has a guard in `[guards]` and a condition in `[st.conditions]`; keep one",
                    key.get_ref()
                ),
            ));
        }
        out[t.index()] = Some(first + j as u32);
    }
    Ok(out)
}

impl Program {
    /// The texts of the program's chart in Structured Text (`[st]` with `[st.bodies]`,
    /// `[st.conditions]` or `[st.steps]`), read again from its text; `None` for any other
    /// program.
    pub fn chart_texts(&self) -> Option<ChartTexts> {
        if !self.st()?.is_chart() {
            return None;
        }
        let doc: Doc = toml::from_str(self.source()).ok()?;
        let decl = doc.st?.into_inner();
        let owned = |table: &std::collections::BTreeMap<Spanned<String>, Spanned<String>>| {
            (in_document_order(table).into_iter())
                .map(|(k, v)| (k.get_ref().clone(), v.get_ref().clone()))
                .collect()
        };
        Some(ChartTexts {
            bodies: owned(&decl.bodies),
            conditions: owned(&decl.conditions),
            steps: owned(&decl.steps),
            pou: decl.pou.into_inner(),
            library: decl.source.into_inner(),
        })
    }
}
