//! The statements of a network, element by element in execution order.

use std::collections::HashMap;

use super::element::{Edge, Element, From, Kind};
use super::{Lowered, Names, Refused};
use crate::pou::Pou;

/// A value computed by an element, as the elements that read it see it.
#[derive(Clone)]
pub(super) struct Value {
    /// The expression (an atom, or parenthesized).
    pub(super) expr: String,
    /// Its type, when the network can tell.
    pub(super) ty: Option<String>,
    /// How deeply its expression nests.
    pub(super) depth: usize,
    /// The statement slot where it could be kept in a temporary, and whether it is already.
    pub(super) slot: Option<usize>,
}

/// How deeply an expression may nest before it is kept in a temporary.
pub(super) const MAX_DEPTH: usize = 8;

/// Writes the elements of one network, in order.
pub(super) struct Writer<'n> {
    /// The POU, whose interface the network reads.
    pub(super) pou: &'n Pou<'n, 'n>,
    pub(super) names: &'n Names,
    pub(super) by_id: HashMap<u64, &'n Element>,
    /// How many inputs read each output.
    pub(super) readers: HashMap<From, usize>,
    /// The outputs that inputs read, by their element's id.
    outputs: HashMap<u64, Vec<From>>,
    pub(super) values: HashMap<From, Value>,
    pub(super) connectors: HashMap<String, Value>,
    /// Statements; `None` is a place kept for a temporary that no reader asked for.
    pub(super) stmts: Vec<(usize, Option<String>)>,
    pub(super) temps: Vec<(String, String)>,
    pub(super) instances: Vec<(String, String)>,
}

impl<'n> Writer<'n> {
    pub(super) fn new(pou: &'n Pou<'n, 'n>, names: &'n Names, elements: &'n [Element]) -> Self {
        let (mut readers, mut outputs) = (HashMap::new(), HashMap::<u64, Vec<From>>::new());
        for from in elements
            .iter()
            .flat_map(|e| e.inputs.iter().flat_map(|p| &p.from))
        {
            let count = readers.entry(from.clone()).or_insert(0);
            if *count == 0 {
                outputs.entry(from.id).or_default().push(from.clone());
            }
            *count += 1;
        }
        Writer {
            pou,
            names,
            by_id: elements.iter().map(|e| (e.id, e)).collect(),
            readers,
            outputs,
            values: HashMap::new(),
            connectors: HashMap::new(),
            stmts: Vec::new(),
            temps: Vec::new(),
            instances: Vec::new(),
        }
    }

    pub(super) fn finish(self) -> Lowered {
        Lowered {
            stmts: self
                .stmts
                .into_iter()
                .filter_map(|(at, s)| Some((at, s?)))
                .collect(),
            temps: self.temps,
            instances: self.instances,
            notes: Vec::new(),
        }
    }

    /// The outputs of the element `id` that an input reads.
    fn read_of(&self, id: u64) -> Vec<From> {
        self.outputs.get(&id).cloned().unwrap_or_default()
    }

    fn push(&mut self, at: usize, stmt: String) {
        self.stmts.push((at, Some(stmt)));
    }

    /// Writes one element.
    pub(super) fn element(&mut self, e: &Element) -> Result<(), Refused> {
        let out = |formal: &str| From {
            id: e.id,
            formal: formal.to_string(),
        };
        match &e.kind {
            Kind::LeftRail => {
                let on = Value {
                    expr: "TRUE".into(),
                    ty: Some("BOOL".into()),
                    depth: 0,
                    slot: None,
                };
                for f in self.read_of(e.id) {
                    self.values.insert(f, on.clone());
                }
            }
            Kind::Contact { var, negated, edge } => {
                let power = self.input(e, 0)?;
                let term = match edge.trigger() {
                    Some(fb) => format!("{}.Q", self.trigger(e, "", fb, var)),
                    None if *negated => format!("NOT {var}"),
                    None => var.clone(),
                };
                let expr = if power.expr == "TRUE" {
                    term
                } else {
                    format!("{} AND {term}", power.expr)
                };
                self.keep(e, out(""), expr, Some("BOOL".into()), power.depth + 1);
            }
            Kind::Coil {
                var,
                negated,
                storage,
                edge,
            } => {
                let power = self.input(e, 0)?;
                self.coil(e, var, &power, *negated, *storage, *edge);
                self.values.insert(out(""), power);
            }
            Kind::In { expr, negated } => {
                let ty = self.type_of_expression(expr);
                let expr = if *negated {
                    format!("NOT ({expr})")
                } else {
                    expr.clone()
                };
                self.keep(e, out(""), expr, ty, 1);
            }
            Kind::Out { expr, negated }
            | Kind::InOut {
                expr,
                negated_in: negated,
                ..
            } => {
                let value = self.input(e, 0)?;
                let v = if *negated {
                    format!("NOT {}", value.expr)
                } else {
                    value.expr
                };
                self.push(e.at, format!("{expr} := {v};"));
                if let Kind::InOut { negated_out, .. } = &e.kind {
                    let read = if *negated_out {
                        format!("NOT ({expr})")
                    } else {
                        expr.clone()
                    };
                    let ty = self.type_of_expression(expr);
                    self.values.insert(
                        out(""),
                        Value {
                            expr: read,
                            ty,
                            depth: 1,
                            slot: None,
                        },
                    );
                }
            }
            Kind::Block {
                ty,
                instance,
                outputs,
            } => self.block(e, ty, instance.as_deref(), outputs)?,
            Kind::Connector { name } => {
                let value = self.input(e, 0)?;
                self.connectors.insert(name.to_ascii_uppercase(), value);
            }
            Kind::Continuation { name } => {
                let value = self
                    .connectors
                    .get(&name.to_ascii_uppercase())
                    .cloned()
                    .ok_or_else(|| {
                        (
                            e.at,
                            format!("the continuation `{name}`"),
                            "its connector is not written before it".to_string(),
                        )
                    })?;
                self.values.insert(out(""), value);
            }
            Kind::Return => {
                let power = self.input(e, 0)?;
                self.push(e.at, format!("IF {} THEN RETURN; END_IF;", power.expr));
            }
            Kind::Drawing => {}
        }
        Ok(())
    }

    /// An LD coil: the variable follows the power, or its negation, its rising or falling edge,
    /// or is set or reset by it.
    fn coil(
        &mut self,
        e: &Element,
        var: &str,
        power: &Value,
        negated: bool,
        storage: Option<bool>,
        edge: Edge,
    ) {
        let p = &power.expr;
        let stmt = match (storage, edge.trigger()) {
            (Some(set), _) => {
                let v = if set { "TRUE" } else { "FALSE" };
                format!("IF {p} THEN {var} := {v}; END_IF;")
            }
            (None, Some(fb)) => {
                let t = self.trigger(e, "", fb, p);
                format!("{var} := {t}.Q;")
            }
            (None, None) if negated => format!("{var} := NOT {p};"),
            (None, None) => format!("{var} := {p};"),
        };
        self.push(e.at, stmt);
    }

    /// Calls an edge detector of element `e` (input `formal`) on `clk`; its instance name.
    fn trigger(&mut self, e: &Element, formal: &str, fb: &'static str, clk: &str) -> String {
        let name = if formal.is_empty() {
            format!("_t{}", e.id)
        } else {
            format!("_t{}_{formal}", e.id)
        };
        self.instances.push((name.clone(), fb.to_string()));
        self.push(e.at, format!("{name}(CLK := {clk});"));
        name
    }

    /// The value of the `index`th input of `e`: its connections ORed, negated or
    /// edge-sensed as drawn.
    fn input(&mut self, e: &Element, index: usize) -> Result<Value, Refused> {
        let pin = &e.inputs[index];
        let mut parts = Vec::new();
        for from in &pin.from {
            parts.push(self.read(e, from)?);
        }
        let mut value = match parts.len() {
            0 => {
                return Err((
                    e.at,
                    format!("element {} with an input connected to nothing", e.id),
                    "connect it, or delete the element".into(),
                ))
            }
            1 => parts.remove(0),
            _ => Value {
                expr: format!(
                    "({})",
                    parts
                        .iter()
                        .map(|p| p.expr.as_str())
                        .collect::<Vec<_>>()
                        .join(" OR ")
                ),
                ty: Some("BOOL".into()),
                depth: parts.iter().map(|p| p.depth).max().unwrap_or(0) + 1,
                slot: None,
            },
        };
        if let Some(fb) = pin.edge.trigger() {
            let t = self.trigger(e, &pin.formal, fb, &value.expr);
            value = Value {
                expr: format!("{t}.Q"),
                ty: Some("BOOL".into()),
                depth: 1,
                slot: None,
            };
        }
        if pin.negated {
            value = Value {
                expr: format!("(NOT {})", value.expr),
                depth: value.depth + 1,
                ..value
            };
        }
        Ok(value)
    }

    /// What reader `e` reads from `from`: the value written, kept in a temporary if others read it
    /// too or a statement came between; or, across a loop, the output as the scan before left it.
    fn read(&mut self, e: &Element, from: &From) -> Result<Value, Refused> {
        let Some(value) = self.values.get(from).cloned() else {
            return self.last_value(e, from);
        };
        let Some(slot) = value.slot else {
            return Ok(value);
        };
        let shared = self.readers.get(from).copied().unwrap_or(0) > 1;
        let moved = slot + 1 != self.stmts.len();
        if !shared && !moved && value.depth <= MAX_DEPTH {
            return Ok(value);
        }
        let Some(ty) = value.ty.clone() else {
            if shared {
                return Err((e.at, format!("the output of element {} read by several elements", from.id), "the importer cannot tell its type; wire it to a variable and read the variable".into()));
            }
            return Ok(value);
        };
        let name = format!(
            "_v{}{}",
            from.id,
            if from.formal.is_empty() {
                String::new()
            } else {
                format!("_{}", from.formal)
            }
        );
        self.temps.push((name.clone(), ty.clone()));
        self.stmts[slot].1 = Some(format!("{name} := {};", value.expr));
        let kept = Value {
            expr: name,
            ty: Some(ty),
            depth: 0,
            slot: None,
        };
        self.values.insert(from.clone(), kept.clone());
        Ok(kept)
    }

    /// An output read before its element runs (a loop): an instance's output or an in-out
    /// variable, as the scan before left it.
    fn last_value(&self, e: &Element, from: &From) -> Result<Value, Refused> {
        let source = self.by_id.get(&from.id).ok_or_else(|| {
            (
                e.at,
                format!("a connection to element {}", from.id),
                "export the network again".to_string(),
            )
        })?;
        let expr = match &source.kind {
            Kind::Block {
                instance: Some(i), ..
            } => format!("{i}.{}", from.formal),
            Kind::InOut { expr, .. } => expr.clone(),
            _ => {
                return Err((
                    e.at,
                    format!("element {} read before it runs", from.id),
                    "draw the network without the loop".into(),
                ))
            }
        };
        let ty = self.type_of_expression(&expr);
        Ok(Value {
            expr,
            ty,
            depth: 0,
            slot: None,
        })
    }

    /// Records the value of an output, with a place kept for a temporary before what follows.
    fn keep(&mut self, e: &Element, out: From, expr: String, ty: Option<String>, depth: usize) {
        let atom = is_atom(&expr);
        let expr = if atom { expr } else { format!("({expr})") };
        let slot = if atom {
            None
        } else {
            self.stmts.push((e.at, None));
            Some(self.stmts.len() - 1)
        };
        self.values.insert(
            out,
            Value {
                expr,
                ty,
                depth,
                slot,
            },
        );
    }

    /// A function block call, or a function's value.
    fn block(
        &mut self,
        e: &Element,
        ty: &str,
        instance: Option<&str>,
        outputs: &[(String, bool)],
    ) -> Result<(), Refused> {
        let mut en = None;
        let mut args = Vec::new();
        for (index, pin) in e.inputs.iter().enumerate() {
            if pin.from.is_empty() {
                continue;
            }
            let value = self.input(e, index)?;
            if pin.formal.eq_ignore_ascii_case("EN") {
                en = Some(value);
            } else {
                args.push((pin.formal.clone(), value));
            }
        }
        let en = match en {
            Some(v) if v.expr != "TRUE" => {
                let name = format!("_en{}", e.id);
                self.temps.push((name.clone(), "BOOL".into()));
                self.push(e.at, format!("{name} := {};", v.expr));
                Some(name)
            }
            _ => None,
        };
        let guarded = |s: String| match &en {
            Some(en) => format!("IF {en} THEN {s} END_IF;"),
            None => s,
        };
        let eno = Value {
            expr: en.clone().unwrap_or_else(|| "TRUE".into()),
            ty: Some("BOOL".into()),
            depth: 0,
            slot: None,
        };
        let out = |formal: &str| From {
            id: e.id,
            formal: formal.to_string(),
        };
        if let Some(instance) = instance {
            let call = args
                .iter()
                .map(|(f, v)| format!("{f} := {}", v.expr))
                .collect::<Vec<_>>()
                .join(", ");
            self.push(e.at, guarded(format!("{instance}({call});")));
            for (formal, negated) in outputs {
                if formal.eq_ignore_ascii_case("ENO") {
                    self.values.insert(out(formal), eno.clone());
                    continue;
                }
                let o = format!("{instance}.{formal}");
                let ty = self.output_type(ty, formal);
                let expr = if *negated { format!("(NOT {o})") } else { o };
                self.values.insert(
                    out(formal),
                    Value {
                        expr,
                        ty,
                        depth: 1,
                        slot: None,
                    },
                );
            }
            return Ok(());
        }
        let result_ty = self.result_type(ty, &args);
        let expr = function_expr(
            ty,
            &args,
            self.names.functions.contains_key(&ty.to_ascii_uppercase()),
        );
        let depth = args.iter().map(|(_, v)| v.depth).max().unwrap_or(0) + 1;
        for (formal, negated) in outputs {
            if formal.eq_ignore_ascii_case("ENO") {
                self.values.insert(out(formal), eno.clone());
                continue;
            }
            let expr = if *negated {
                format!("NOT ({expr})")
            } else {
                expr.clone()
            };
            match &en {
                Some(_) => {
                    let t = result_ty.clone().ok_or_else(|| {
                        (
                            e.at,
                            format!("the {ty} block with EN"),
                            "the importer cannot tell its type; wire its output to a variable"
                                .to_string(),
                        )
                    })?;
                    let name = format!("_v{}_{formal}", e.id);
                    self.temps.push((name.clone(), t.clone()));
                    self.push(e.at, guarded(format!("{name} := {expr};")));
                    self.values.insert(
                        out(formal),
                        Value {
                            expr: name,
                            ty: Some(t),
                            depth: 0,
                            slot: None,
                        },
                    );
                }
                None => self.keep(e, out(formal), expr, result_ty.clone(), depth),
            }
        }
        Ok(())
    }

    /// The type of output `formal` of a function block type, when known.
    fn output_type(&self, fb: &str, formal: &str) -> Option<String> {
        let outs = self.names.fb_outputs.get(&fb.to_ascii_uppercase())?;
        outs.iter()
            .find(|(o, _)| o.eq_ignore_ascii_case(formal))
            .map(|(_, t)| t.clone())
    }

    /// The type of what the function `f` returns, for the arguments given, when known.
    fn result_type(&self, f: &str, args: &[(String, Value)]) -> Option<String> {
        let upper = f.to_ascii_uppercase();
        if let Some(ret) = self.names.functions.get(&upper) {
            return Some(ret.clone());
        }
        if let Some((_, to)) = upper.split_once("_TO_") {
            return Some(to.to_string());
        }
        let known = |skip: usize| args.iter().skip(skip).find_map(|(_, v)| v.ty.clone());
        match upper.as_str() {
            "GT" | "GE" | "EQ" | "LE" | "LT" | "NE" => Some("BOOL".into()),
            "LEN" | "FIND" => Some("INT".into()),
            "TRUNC" => Some("DINT".into()),
            "LEFT" | "RIGHT" | "MID" | "CONCAT" | "INSERT" | "DELETE" | "REPLACE" => {
                Some("STRING".into())
            }
            "SEL" | "MUX" | "LIMIT" => known(1),
            _ => known(0),
        }
    }

    /// The type of a variable's expression in this POU, when it is a name the POU or the
    /// configuration declares, a member of an instance, or a typed literal.
    fn type_of_expression(&self, expr: &str) -> Option<String> {
        let e = expr.trim();
        let upper = e.to_ascii_uppercase();
        if upper == "TRUE" || upper == "FALSE" {
            return Some("BOOL".into());
        }
        if let Some((prefix, _)) = upper.split_once('#') {
            return match prefix {
                "T" | "TIME" => Some("TIME".into()),
                p if p.chars().all(|c| c.is_ascii_alphabetic()) => Some(p.to_string()),
                _ => None,
            };
        }
        let declared = |name: &str| {
            let key = name.to_ascii_uppercase();
            (self.pou.variable(name).map(|v| v.ty.clone()))
                .or_else(|| self.names.globals.get(&key).cloned())
        };
        match e.split_once('.') {
            Some((instance, member)) => self.output_type(&declared(instance)?, member),
            None if is_name(e) => declared(e).filter(|t| t != "array" && t != "struct"),
            None => None,
        }
    }
}

/// The expression of a function block of type `f` on `args`: the ST operator where there is
/// one, else a call (formal for the file's own functions, informal for the standard ones).
pub(super) fn function_expr(f: &str, args: &[(String, Value)], own: bool) -> String {
    let values: Vec<&str> = args.iter().map(|(_, v)| v.expr.as_str()).collect();
    let infix = match f.to_ascii_uppercase().as_str() {
        "ADD" => Some("+"),
        "SUB" => Some("-"),
        "MUL" => Some("*"),
        "DIV" => Some("/"),
        "MOD" => Some("MOD"),
        "EXPT" => Some("**"),
        "AND" => Some("AND"),
        "OR" => Some("OR"),
        "XOR" => Some("XOR"),
        "GT" => Some(">"),
        "GE" => Some(">="),
        "EQ" => Some("="),
        "LE" => Some("<="),
        "LT" => Some("<"),
        "NE" => Some("<>"),
        _ => None,
    };
    let compare = matches!(infix, Some(">" | ">=" | "=" | "<=" | "<" | "<>"));
    match (f.to_ascii_uppercase().as_str(), infix) {
        ("NOT", _) if values.len() == 1 => format!("NOT {}", values[0]),
        ("MOVE", _) if values.len() == 1 => values[0].to_string(),
        (_, Some(op)) if compare && values.len() > 2 => {
            // An extensible comparison holds when each pair in turn does.
            let pairs: Vec<String> = values
                .windows(2)
                .map(|w| format!("({} {op} {})", w[0], w[1]))
                .collect();
            pairs.join(" AND ")
        }
        (_, Some(op)) if values.len() >= 2 => values.join(&format!(" {op} ")),
        _ if own => {
            let formal: Vec<String> = args
                .iter()
                .map(|(f, v)| format!("{f} := {}", v.expr))
                .collect();
            format!("{f}({})", formal.join(", "))
        }
        _ => format!("{f}({})", values.join(", ")),
    }
}

/// Whether an expression needs no parentheses where it is used: a name, a member, a literal.
pub(super) fn is_atom(expr: &str) -> bool {
    !expr.is_empty()
        && expr
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '.' | '#' | '%'))
}

/// Whether a text is a plain IEC identifier.
pub(super) fn is_name(text: &str) -> bool {
    text.chars()
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && text.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
}
