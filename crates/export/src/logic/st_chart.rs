//! A chart in Structured Text (`[st.bodies]`, `[st.conditions]`, `[st.steps]`; docs/sfc.md,
//! *Charts in Structured Text*). Its POU, a FUNCTION_BLOCK without a body, is given one that
//! runs the part of the chart the interpretation asks for, on the POU's state, as the runtime
//! runs the chart's entries. `CETRATUS_ENTRY` selects the part: 0 nothing (the call passes the
//! inputs and the step flags only), entry `k` (a body, or a condition whose value the call
//! leaves in `CETRATUS_COND`) is `k + 1`, and past the entries each variable an action drives
//! with its Q (`CETRATUS_Q`). The step flags come in as `CETRATUS_X<i>` and `CETRATUS_T<i>`, and
//! go into each step's `X` and `T` before the part runs, as the runtime writes them before each
//! pass.

use cetratus_program::st::{ChartTexts, StProgram};
use cetratus_st::assigned_name;

use super::st_body::{from_pou, into_pou, StBody};
use super::*;

/// The input that selects the part a call runs.
const ENTRY: &str = "CETRATUS_ENTRY";
/// The input that carries an action's Q to the variable it drives.
const Q: &str = "CETRATUS_Q";
/// The output that holds a condition's value after its call.
const COND: &str = "CETRATUS_COND";

/// How the interpretation calls the parts of a chart's Structured Text.
pub(crate) struct ChartCalls {
    /// Per step, in `[st.steps]` order: its place's id and its index in the kernel's arrays.
    steps: Vec<(String, usize)>,
    /// Per variable an action drives (a `Target::St`): its slot and the part that sets it.
    targets: Vec<(u32, usize)>,
}

/// The calls of the chart of `program`, whose ST is `st` and texts `texts`; the chart's POU
/// in the rewritten library `text` gets the body that runs the parts.
pub(crate) fn prepare(
    program: &Program,
    st: &StProgram,
    texts: &ChartTexts,
    text: &mut String,
) -> Result<ChartCalls, ExportError> {
    let unit = st.unit();
    let own = |n: &str| n.to_ascii_uppercase().starts_with("CETRATUS_");
    if let Some(v) = unit.vars.iter().find(|v| own(&v.name)) {
        return Err(ExportError::Unsupported {
            what: format!(
                "the chart's POU `{}` declares `{}`, and the export names its own variables of that POU CETRATUS_…",
                unit.name, v.name
            ),
            hint: "rename the variable in the chart's source and import it again",
        });
    }
    let net = program.net();
    let steps = (texts.steps.iter())
        .filter_map(|(place, _)| Some((place.clone(), net.place_by_id(place)?.index() + 1)))
        .collect();
    let entries = texts.bodies.len() + texts.conditions.len();
    let driven = (program.action_targets().iter()).filter_map(|t| match *t {
        Target::St(at) => Some(at),
        _ => None,
    });
    let targets = (driven.enumerate())
        .map(|(j, at)| (at, entries + 1 + j))
        .collect();
    let calls = ChartCalls { steps, targets };
    let body = calls.body(st, texts)?;
    inject(text, &unit.name, &body)?;
    Ok(calls)
}

impl ChartCalls {
    /// The declarations and the body given to the chart's POU.
    fn body(&self, st: &StProgram, texts: &ChartTexts) -> Result<String, ExportError> {
        let mut s = format!("VAR_INPUT\n  {ENTRY} : INT;\n  {Q} : BOOL;\n");
        for i in 1..=self.steps.len() {
            let _ = writeln!(s, "  CETRATUS_X{i} : BOOL;\n  CETRATUS_T{i} : TIME;");
        }
        let _ = writeln!(s, "END_VAR\nVAR_OUTPUT\n  {COND} : BOOL;\nEND_VAR");
        // A condition written as statements assigns its value to its transition's id.
        let assigned: Vec<&(String, String)> = (texts.conditions.iter())
            .filter(|(_, text)| cetratus_st::parse::parse_expression(text).is_err())
            .collect();
        if !assigned.is_empty() {
            s.push_str("VAR\n");
            let mut declared = std::collections::HashSet::new();
            for (id, _) in &assigned {
                let name = assigned_name(id);
                if declared.insert(name.to_ascii_uppercase()) {
                    let _ = writeln!(s, "  {name} : BOOL;");
                }
            }
            s.push_str("END_VAR\n");
        }
        s.push_str("(* The step flags, as the interpretation passes them. *)\n");
        for (i, (_, var)) in texts.steps.iter().enumerate() {
            let _ = writeln!(
                s,
                "{var}.X := CETRATUS_X{};\n{var}.T := CETRATUS_T{};",
                i + 1,
                i + 1
            );
        }
        let mut parts = String::new();
        for (k, (name, text)) in texts.bodies.iter().enumerate() {
            let statements = terminated(name, text)?;
            let _ = writeln!(
                parts,
                "  {}:  (* the body {} *)\n{statements}",
                k + 1,
                comment(name)
            );
        }
        let first = texts.bodies.len();
        for (j, (id, text)) in texts.conditions.iter().enumerate() {
            let (label, what) = (first + j + 1, comment(id));
            let result = assigned_name(id);
            let _ = match assigned.iter().any(|(a, _)| a == id) {
                true => writeln!(
                    parts,
                    "  {label}:  (* the condition of {what}, as statements *)\n  {result} := FALSE;\n{}\n  {COND} := {result};",
                    terminated(id, text)?
                ),
                false => writeln!(
                    parts,
                    "  {label}:  (* the condition of {what} *)\n  {COND} := (\n{text}\n  );"
                ),
            };
        }
        for &(at, label) in &self.targets {
            let var = st.slot_name(at).unwrap_or_default();
            let _ = writeln!(
                parts,
                "  {label}:  (* driven by its actions' Q *)\n  {var} := {Q};"
            );
        }
        if !parts.is_empty() {
            let _ = write!(s, "CASE {ENTRY} OF\n{parts}END_CASE;\n");
        }
        Ok(s)
    }
}

/// The statements `text` of the part `name` with the `;` that the vendors' form leaves out.
fn terminated(name: &str, text: &str) -> Result<String, ExportError> {
    cetratus_st::parse::terminated(text).map_err(|d| ExportError::Unsupported {
        what: format!("the ST of `{name}` does not lex again: {}", d.message),
        hint: "this is a fault of the exporter; report it with the program",
    })
}

/// `body` put into the FUNCTION_BLOCK `pou` of `text`, before its `END_FUNCTION_BLOCK`.
fn inject(text: &mut String, pou: &str, body: &str) -> Result<(), ExportError> {
    let head = |l: &str| {
        let t = l.trim();
        let name = t
            .get(..15)
            .filter(|k| k.eq_ignore_ascii_case("FUNCTION_BLOCK "));
        name.is_some()
            && t[15..]
                .split_whitespace()
                .next()
                .is_some_and(|n| n.eq_ignore_ascii_case(pou))
    };
    let lines: Vec<&str> = text.lines().collect();
    let end = (lines.iter().position(|l| head(l))).and_then(|h| {
        let after = lines[h..].iter().position(|l| {
            l.trim()
                .to_ascii_uppercase()
                .starts_with("END_FUNCTION_BLOCK")
        })?;
        Some(h + after)
    });
    let Some(end) = end else {
        return Err(ExportError::Unsupported {
            what: format!("the chart's POU `{pou}` does not begin and end on lines of its own"),
            hint: "write `FUNCTION_BLOCK` and `END_FUNCTION_BLOCK` on lines of their own and import it again",
        });
    };
    let mut out = String::with_capacity(text.len() + body.len());
    for l in &lines[..end] {
        out.push_str(l);
        out.push('\n');
    }
    out.push_str(body);
    for l in &lines[end..] {
        out.push_str(l);
        out.push('\n');
    }
    *text = out;
    Ok(())
}

impl Logic<'_> {
    /// The chart's ST and its calls, when the program is a chart in Structured Text.
    fn chart(&self) -> Option<(&StBody, &ChartCalls)> {
        let b = self.st_body.as_ref()?;
        Some((b, b.chart.as_ref()?))
    }

    /// The POU's inputs, from the interpretation's signals.
    pub(super) fn st_inputs(&self, st: &StBody) -> Vec<String> {
        (st.wires.iter().filter(|w| w.3))
            .map(|(var, e, sig, _)| format!("{var} := {}", into_pou(*e, &self.signal(sig))))
            .collect()
    }

    /// The POU's outputs copied into the interpretation's signals, indented by `pad`.
    pub(super) fn st_outputs(&self, s: &mut String, st: &StBody, pad: &str) {
        for (var, e, sig, _) in st.wires.iter().filter(|w| !w.3) {
            let from = format!("{}.{var}", st.instance);
            let _ = writeln!(s, "{pad}{} := {};", self.signal(sig), from_pou(*e, &from));
        }
    }

    /// Each step's flags as the call's arguments: marked, and its time (while marked) or its
    /// last dwell (once left).
    fn step_flags(&self, calls: &ChartCalls) -> Vec<String> {
        let m = &self.locals.marking;
        let mut args = Vec::new();
        for (i, (place, at)) in calls.steps.iter().enumerate() {
            let (t, d) = (&self.sym.timers[place], &self.sym.dwells[place]);
            args.push(format!("CETRATUS_X{} := {m}[{at}] > 0", i + 1));
            args.push(format!(
                "CETRATUS_T{} := SEL({m}[{at}] > 0, {d}, {t}.ET)",
                i + 1
            ));
        }
        args
    }

    /// Before the conditions: the inputs and the step flags passed in, as the runtime prepares
    /// the POU's state once a scan before its conditions.
    pub(super) fn chart_prepare(&self, s: &mut String) {
        let Some((st, calls)) = self.chart() else {
            return;
        };
        let mut args = vec![format!("{ENTRY} := 0")];
        args.extend(self.st_inputs(st));
        args.extend(self.step_flags(calls));
        let _ = writeln!(
            s,
            "(* The chart's Structured Text: this scan's inputs and step flags. *)\n{}({});",
            st.instance,
            args.join(", ")
        );
    }

    /// The condition entry `k` of candidate transition `n` into the kernel's `COND[n]`.
    pub(super) fn chart_condition(&self, s: &mut String, n: usize, k: u32, what: &str) {
        let Some((st, _)) = self.chart() else {
            return;
        };
        let (i, c) = (&st.instance, &self.locals.cond);
        let _ = writeln!(
            s,
            "IF {}[{n}] THEN  (* {what} *)\n  {i}({ENTRY} := {});\n  {c}[{n}] := {i}.{COND};\nEND_IF;",
            self.locals.candidate,
            k + 1
        );
    }

    /// Before the actions: this scan's inputs passed in once, as the action control copies
    /// them before its bodies (a VAR_INPUT that one body assigns, the next one sees).
    pub(super) fn chart_inputs(&self, s: &mut String) {
        if let Some((st, _)) = self.chart() {
            let mut args = vec![format!("{ENTRY} := 0")];
            args.extend(self.st_inputs(st));
            let _ = writeln!(s, "{}({});", st.instance, args.join(", "));
        }
    }

    /// The body entry `k`, with the step flags after the marking update.
    pub(super) fn chart_body(&self, s: &mut String, k: u32) {
        if let Some((st, calls)) = self.chart() {
            let mut args = vec![format!("{ENTRY} := {}", k + 1)];
            args.extend(self.step_flags(calls));
            let _ = writeln!(s, "  {}({});", st.instance, args.join(", "));
        }
    }

    /// The POU's variable at `slot` set to `q`, an action's Q.
    pub(super) fn chart_target(&self, s: &mut String, slot: u32, q: &str) {
        let Some((st, calls)) = self.chart() else {
            return;
        };
        if let Some(&(_, label)) = calls.targets.iter().find(|t| t.0 == slot) {
            let _ = writeln!(s, "  {}({ENTRY} := {label}, {Q} := {q});", st.instance);
        }
    }

    /// After the actions: the POU's outputs, which it holds, copied out.
    pub(super) fn chart_outputs(&self, s: &mut String) {
        if let Some((st, _)) = self.chart() {
            self.st_outputs(s, st, "");
        }
    }
}
