//! The text of parts 3 and 4.

use super::*;

impl Logic<'_> {
    /// Part 3: the FUNCTION_BLOCK `fb` that runs the interpretation once a scan.
    pub(crate) fn pou(&self, fb: &str) -> Result<String, ExportError> {
        let p = self.program;
        let mut s = format!(
            "FUNCTION_BLOCK {fb}\n(* The interpretation of {}: the conditions of its transitions, its place\n   timers and its actions, around the kernel. *)\n",
            comment(p.name())
        );
        self.declarations(&mut s);
        let l = &self.locals;
        let call = |startup: &str| format!("{}(STARTUP := {startup});\n", l.kernel);
        let _ = write!(s, "IF {} THEN\n  {}", l.first, call("TRUE"));
        for (x, prev) in sorted(&self.sym.previous) {
            let _ = writeln!(s, "  {prev} := {};", self.signal(x));
        }
        let _ = writeln!(s, "  {} := FALSE;\nEND_IF;", l.first);
        self.place_timers(&mut s, true);
        self.conditions(&mut s);
        s.push_str("(* The decision under the policy, and the marking update. *)\n");
        s.push_str(&call("FALSE"));
        self.place_timers(&mut s, false);
        self.actions(&mut s)?;
        if !self.sym.previous.is_empty() {
            s.push_str("(* This scan's inputs, for the edges of the next. *)\n");
            for (x, prev) in sorted(&self.sym.previous) {
                let _ = writeln!(s, "{prev} := {};", self.signal(x));
            }
        }
        s.push_str("END_FUNCTION_BLOCK\n");
        Ok(s)
    }

    fn declarations(&self, s: &mut String) {
        let p = self.program;
        for (block, list, init) in [
            ("VAR_INPUT", p.inputs(), false),
            ("VAR_OUTPUT", p.outputs(), false),
        ] {
            if !list.is_empty() {
                let _ = writeln!(s, "{block}");
                for sig in list {
                    declare(s, &self.signal(&sig.name), sig, init);
                }
                s.push_str("END_VAR\n");
            }
        }
        for retain in [false, true] {
            let vars: Vec<&Signal> = (p.variables().iter())
                .filter(|v| v.retain == retain)
                .collect();
            if !vars.is_empty() {
                s.push_str(if retain { "VAR RETAIN\n" } else { "VAR\n" });
                for v in vars {
                    declare(s, &self.signal(&v.name), v, true);
                }
                s.push_str("END_VAR\n");
            }
        }
        s.push_str("VAR\n");
        let l = &self.locals;
        let _ = writeln!(s, "  {} : CETRATUS_KERNEL;", l.kernel);
        if let Some(b) = &self.st_body {
            let _ = writeln!(
                s,
                "  {} : {};  (* the program's Structured Text *)",
                b.instance, b.pou
            );
        }
        let _ = writeln!(s, "  {} : BOOL := TRUE;", l.first);
        for (p, t) in sorted(&self.sym.timers) {
            let _ = writeln!(
                s,
                "  {t} : TON;  (* how long {} has been marked *)",
                comment(p)
            );
        }
        for (p, d) in sorted(&self.sym.dwells) {
            let _ = writeln!(
                s,
                "  {d} : TIME;  (* how long {} was marked the last time *)",
                comment(p)
            );
        }
        for (_, prev) in sorted(&self.sym.previous) {
            let _ = writeln!(s, "  {prev} : BOOL;");
        }
        for slot in &self.slots {
            for f in [&slot.on, &slot.latch, &slot.pulse, &slot.reset, &slot.was]
                .into_iter()
                .flatten()
            {
                let _ = writeln!(s, "  {f} : BOOL;");
            }
        }
        for (run, timer) in self.stored.iter().flatten() {
            let _ = writeln!(s, "  {run} : BOOL;\n  {timer} : TON;");
        }
        s.push_str("END_VAR\n");
    }

    /// The place timers: before the conditions, so that they read each place's time at the
    /// scan's start; after the update, so that a place entered in this scan counts from now.
    fn place_timers(&self, s: &mut String, before: bool) {
        if self.sym.timers.is_empty() {
            return;
        }
        s.push_str(if before {
            "(* Place timers, as the conditions read them. *)\n"
        } else {
            "(* A place entered in this scan counts its time from now. *)\n"
        });
        for (p, t) in sorted(&self.sym.timers) {
            let i = self.sym.places[p];
            let m = &self.locals.marking;
            let _ = writeln!(s, "{t}(IN := {m}[{i}] > 0, PT := {TIMER_RANGE});");
            if let (true, Some(d)) = (before, self.sym.dwells.get(p)) {
                let _ = writeln!(s, "IF {m}[{i}] > 0 THEN\n  {d} := {t}.ET;\nEND_IF;");
            }
        }
    }

    fn conditions(&self, s: &mut String) {
        let p = self.program;
        let net = p.net();
        self.chart_prepare(s);
        s.push_str("(* The condition of each candidate transition (enabled, or able to join the step);\n   one without a guard is always TRUE. *)\n");
        let guard_lines = section_key_lines(p.source(), "[guards]");
        for (j, tr) in net.transitions().iter().enumerate() {
            let t = cetratus_net::TransIdx(j as u32);
            let (c, n) = (&self.locals.cond, j + 1);
            if let (None, Some(k)) = (p.guard(t), p.st_condition(t)) {
                self.chart_condition(s, n, k, &comment(&tr.id));
                continue;
            }
            match p.guard(t) {
                Some(g) => {
                    let line = guard_lines.get(&tr.id);
                    let at = line.map(|n| format!(", line {n}")).unwrap_or_default();
                    let _ = writeln!(
                        s,
                        "IF {}[{n}] THEN  (* {}{at}: {} *)\n  {c}[{n}] := {};\nEND_IF;",
                        self.locals.candidate,
                        comment(&tr.id),
                        comment(g.source()),
                        st(g.expr(), &self.sym),
                    );
                }
                None => {
                    let _ = writeln!(s, "{c}[{n}] := TRUE;  (* {} *)", comment(&tr.id));
                }
            }
        }
    }
}

/// A map's entries in the order of their keys, so that the text never depends on hashing.
pub(super) fn sorted(map: &HashMap<String, String>) -> Vec<(&String, &String)> {
    let mut v: Vec<_> = map.iter().collect();
    v.sort();
    v
}

/// Part 4: the PROGRAM that wires the signals to their addresses and runs the interpretation.
/// Where the dialect locates no variable (OMRON), the signals are global variables, each with
/// its address in a comment, which the engineer assigns to the controller's I/O.
pub(crate) fn program_pou(
    name: &str,
    fb: &str,
    rows: &[IoRow],
    program: &Program,
    d: crate::Dialect,
) -> String {
    let mut names = Names::new(&[name, fb]);
    for r in rows {
        names.claim(None, &r.name);
    }
    let logic = names.claim(None, "LOGIC");
    let mut s = String::new();
    if !d.located() && !rows.is_empty() {
        s.push_str("VAR_GLOBAL\n");
        for r in rows {
            let (n, t) = (&r.name, r.iec_type);
            let _ = writeln!(s, "  {n} : {t};  (* {} {} *)", r.direction, r.address);
        }
        s.push_str("END_VAR\n\n");
    }
    let _ = write!(
        s,
        "PROGRAM {name}\n(* The signals of {} at their addresses (the I/O map), and the interpretation,\n   run once a scan. *)\n",
        comment(program.name())
    );
    if !rows.is_empty() {
        s.push_str(if d.located() {
            "VAR\n"
        } else {
            "VAR_EXTERNAL\n"
        });
        for r in rows {
            let at = match d.located() {
                true => format!(" AT {}", r.address),
                false => String::new(),
            };
            let _ = writeln!(s, "  {}{at} : {};", r.name, r.iec_type);
        }
        s.push_str("END_VAR\n");
    }
    let _ = writeln!(s, "VAR\n  {logic} : {fb};\nEND_VAR");
    let args: Vec<String> = (rows.iter().filter(|r| r.direction == "input"))
        .map(|r| format!("{} := {}", r.name, widen(r.iec_type, &r.name)))
        .collect();
    let _ = writeln!(s, "{logic}({});", args.join(", "));
    for r in rows.iter().filter(|r| r.direction == "output") {
        let from = format!("{logic}.{}", r.name);
        let _ = writeln!(s, "{} := {};", r.name, narrow(r.iec_type, &from));
    }
    s.push_str("END_PROGRAM\n");
    s
}

fn widen(iec: &str, x: &str) -> String {
    match iec {
        "INT" | "DINT" => format!("{iec}_TO_LINT({x})"),
        "REAL" => format!("REAL_TO_LREAL({x})"),
        _ => x.to_string(),
    }
}

fn narrow(iec: &str, x: &str) -> String {
    match iec {
        "INT" | "DINT" => format!("LINT_TO_{iec}({x})"),
        "REAL" => format!("LREAL_TO_REAL({x})"),
        _ => x.to_string(),
    }
}

/// The CONFIGURATION: the net's constants (part 2's values) and one TASK at the scan period.
pub(crate) fn configuration(globals: &str, program: &str, period_us: u64) -> String {
    format!(
        "CONFIGURATION CETRATUS_CONFIG\n{globals}  RESOURCE CETRATUS_RESOURCE ON PLC\n    TASK CETRATUS_TASK(INTERVAL := {}, PRIORITY := 1);\n    PROGRAM CETRATUS_MAIN WITH CETRATUS_TASK : {program};\n  END_RESOURCE\nEND_CONFIGURATION\n",
        time_literal(period_us)
    )
}
