//! The actions in Structured Text: the IEC 61131-3 action control of docs/program-format.md
//! (*Actions*, *Action bodies*), step by step as the runtime computes it after the marking
//! update: the flags cleared, the edges of the places entered and left, the stored timers (SD,
//! SL) and resets, the non-stored and timed qualifiers of the marked places, then each driven
//! target in order, a body running while its Q is on and once more when it falls.

use super::*;

impl Logic<'_> {
    pub(super) fn actions(&self, s: &mut String) -> Result<(), ExportError> {
        if self.program.actions().is_empty() && self.program.outputs().is_empty() {
            return Ok(());
        }
        s.push_str("(* Actions. *)\n");
        for slot in &self.slots {
            for f in [&slot.on, &slot.pulse, &slot.reset].into_iter().flatten() {
                let _ = writeln!(s, "{f} := FALSE;");
            }
        }
        self.edges(s);
        self.stored_timers(s);
        self.marked(s);
        self.drive(s)
    }

    fn place(&self, p: cetratus_net::PlaceIdx) -> (usize, String) {
        let id = &self.program.net().place(p).id;
        (p.index() + 1, comment(id))
    }

    /// Entering and leaving: S latches, R resets, P1 and P0 pulse, SD starts its delay if it
    /// is not running, SL restarts its time.
    fn edges(&self, s: &mut String) {
        let l = &self.locals;
        let slots = self.program.action_slots();
        for (k, a) in self.program.actions().iter().enumerate() {
            let slot = &self.slots[slots[k] as usize];
            let (i, id) = self.place(a.place);
            let (edge, set) = match (a.qualifier, &self.stored[k]) {
                (Qualifier::S, _) => (&l.entered, slot.latch.clone()),
                (Qualifier::R, _) => (&l.entered, slot.reset.clone()),
                (Qualifier::P1, _) => (&l.entered, slot.pulse.clone()),
                (Qualifier::P0, _) => (&l.left, slot.pulse.clone()),
                (Qualifier::SD(_), Some((run, _))) => (&l.entered, Some(run.clone())),
                (Qualifier::SL(d), Some((run, timer))) => {
                    let _ = writeln!(
                        s,
                        "IF {}[{i}] THEN  (* SL on {id}: entering again restarts its time *)\n  {timer}(IN := FALSE, PT := {});\n  {run} := TRUE;\nEND_IF;",
                        l.entered,
                        time_literal(d)
                    );
                    continue;
                }
                _ => continue,
            };
            if let Some(f) = set {
                let _ = writeln!(
                    s,
                    "IF {edge}[{i}] THEN  (* {} on {id} *)\n  {f} := TRUE;\nEND_IF;",
                    a.qualifier
                );
            }
        }
    }

    /// A reset clears its target's latch and stops its SD and SL timers; SD is on once its
    /// delay has passed, SL while its time runs, whether or not the place is still marked.
    fn stored_timers(&self, s: &mut String) {
        for slot in &self.slots {
            if let (Some(r), Some(latch)) = (&slot.reset, &slot.latch) {
                let _ = writeln!(s, "IF {r} THEN\n  {latch} := FALSE;\nEND_IF;");
            }
        }
        let slots = self.program.action_slots();
        for (k, a) in self.program.actions().iter().enumerate() {
            let Some((run, timer)) = &self.stored[k] else {
                continue;
            };
            let slot = &self.slots[slots[k] as usize];
            let on = slot.on.as_deref().expect("SD and SL drive the on flag");
            if let Some(r) = &slot.reset {
                let _ = writeln!(s, "IF {r} THEN\n  {run} := FALSE;\nEND_IF;");
            }
            let d = time_literal(a.qualifier.duration_us().unwrap_or(0));
            let _ = writeln!(s, "{timer}(IN := {run}, PT := {d});");
            match a.qualifier {
                Qualifier::SD(_) => {
                    let _ = writeln!(s, "IF {run} AND {timer}.Q THEN\n  {on} := TRUE;\nEND_IF;");
                }
                _ => {
                    let _ = writeln!(
                        s,
                        "IF {run} THEN\n  IF {timer}.Q THEN\n    {run} := FALSE;\n  ELSE\n    {on} := TRUE;\n  END_IF;\nEND_IF;"
                    );
                }
            }
        }
    }

    /// The qualifiers of marked places: N on, L before its time, D after it, DS latches after
    /// it unless reset in this scan.
    fn marked(&self, s: &mut String) {
        let m = &self.locals.marking;
        let slots = self.program.action_slots();
        for (k, a) in self.program.actions().iter().enumerate() {
            let slot = &self.slots[slots[k] as usize];
            let (i, id) = self.place(a.place);
            let timer = || &self.sym.timers[&self.program.net().place(a.place).id];
            let (cond, flag) = match a.qualifier {
                Qualifier::N => (String::new(), &slot.on),
                Qualifier::L(d) => (
                    format!(" AND {}.ET < {}", timer(), time_literal(d)),
                    &slot.on,
                ),
                Qualifier::D(d) => (
                    format!(" AND {}.ET >= {}", timer(), time_literal(d)),
                    &slot.on,
                ),
                Qualifier::DS(d) => {
                    let not_reset = slot
                        .reset
                        .as_ref()
                        .map(|r| format!(" AND NOT {r}"))
                        .unwrap_or_default();
                    (
                        format!(" AND {}.ET >= {}{not_reset}", timer(), time_literal(d)),
                        &slot.latch,
                    )
                }
                _ => continue,
            };
            if let Some(f) = flag {
                let _ = writeln!(
                    s,
                    "IF {m}[{i}] > 0{cond} THEN  (* {} on {id} *)\n  {f} := TRUE;\nEND_IF;",
                    a.qualifier
                );
            }
        }
    }

    /// Outputs no body assigns start each scan at zero; each target then takes its Q, and each
    /// body runs while its Q is on and once more in the scan it falls (pulses excepted).
    fn drive(&self, s: &mut String) -> Result<(), ExportError> {
        let p = self.program;
        let held: BTreeSet<u32> = p
            .bodies()
            .iter()
            .flat_map(|b| b.outputs().iter().copied())
            .collect();
        for (i, o) in p.outputs().iter().enumerate() {
            if !held.contains(&(i as u32)) {
                let _ = writeln!(s, "{} := {};", self.signal(&o.name), zero(o.ty));
            }
        }
        self.chart_inputs(s);
        for (slot, target) in self.slots.iter().zip(p.action_targets()) {
            match *target {
                Target::Output(i) => {
                    let _ = writeln!(
                        s,
                        "{} := {};",
                        self.signal(&p.outputs()[i as usize].name),
                        slot.q()
                    );
                }
                Target::Variable(i) => {
                    let _ = writeln!(
                        s,
                        "{} := {};",
                        self.signal(&p.variables()[i as usize].name),
                        slot.q()
                    );
                }
                Target::Body(b) => {
                    let body = &p.bodies()[b as usize];
                    // A body whose actions are all pulses has no final run, and no last Q.
                    let run = match &slot.was {
                        Some(was) => format!("{} OR {was}", slot.q()),
                        None => slot.q(),
                    };
                    let _ = writeln!(s, "IF {run} THEN  (* body {} *)", comment(body.name()));
                    match (&self.st_body, body.st(), body.st_entry()) {
                        (Some(_), Some(_), Some(k)) => self.chart_body(s, k),
                        (Some(st), Some(_), None) => self.st_call(s, st),
                        _ => self.body(s, body)?,
                    }
                    s.push_str("END_IF;\n");
                    if let Some(was) = &slot.was {
                        let _ = writeln!(s, "{was} := {};", slot.stored());
                    }
                }
                Target::St(at) => {
                    // Written while Q is on and once more as it falls, as the runtime does.
                    let was = slot.was.as_deref().unwrap_or("FALSE");
                    let _ = writeln!(s, "IF {} OR {was} THEN", slot.q());
                    self.chart_target(s, at, &slot.q());
                    s.push_str("END_IF;\n");
                    if let Some(was) = &slot.was {
                        let _ = writeln!(s, "{was} := {};", slot.q());
                    }
                }
            }
        }
        self.chart_outputs(s);
        Ok(())
    }

    /// A Structured Text body: its inputs copied in, one pass, its outputs copied out.
    fn st_call(&self, s: &mut String, st: &super::st_body::StBody) {
        let args = self.st_inputs(st);
        let _ = writeln!(s, "  {}({});", st.instance, args.join(", "));
        self.st_outputs(s, st, "  ");
    }

    /// A guard-language body as ST statements, indented under its `IF`.
    fn body(&self, s: &mut String, body: &cetratus_program::Body) -> Result<(), ExportError> {
        let mut depth = 1usize;
        for st_ in statements(body)? {
            let pad = |d: usize| "  ".repeat(d);
            match st_ {
                Statement::Assign { name, expr, line } => {
                    let _ = writeln!(
                        s,
                        "{}{} := {};  (* line {line} *)",
                        pad(depth),
                        self.signal(&name),
                        st(&expr, &self.sym)
                    );
                }
                Statement::If(c) => {
                    let _ = writeln!(s, "{}IF {} THEN", pad(depth), st(&c, &self.sym));
                    depth += 1;
                }
                Statement::Elif(c) => {
                    let _ = writeln!(s, "{}ELSIF {} THEN", pad(depth - 1), st(&c, &self.sym));
                }
                Statement::Else => {
                    let _ = writeln!(s, "{}ELSE", pad(depth - 1));
                }
                Statement::End => {
                    depth -= 1;
                    let _ = writeln!(s, "{}END_IF;", pad(depth));
                }
            }
        }
        Ok(())
    }
}
