//! The standard function blocks in machine code: each call translated in line, without a
//! branch, into what [`crate::stdfb::StdFb::step`] does on the instance's slots. The members are
//! slots at fixed indices (the instance's base and the member's place in it), so a call reads
//! and writes them as any other instruction does, and what the next instructions read of them
//! stays in registers.

use cranelift_codegen::ir::condcodes::IntCC;
use cranelift_codegen::ir::{types, InstBuilder, Value};

use super::Lower;
use crate::code::Slot;
use crate::stdfb::StdFb;
use crate::types::Elem;

impl Lower<'_, '_> {
    /// A call of `fb` on the instance whose first slot is `base`.
    pub(super) fn std_fb(&mut self, fb: StdFb, base: Slot) {
        let m = |i: u32| base + i;
        match fb {
            StdFb::Sr | StdFb::Rs => {
                let (s, r, q) = (self.truth(m(0)), self.truth(m(1)), self.truth(m(2)));
                let q = match fb {
                    // Q1 := S1 OR (NOT R AND Q1)
                    StdFb::Sr => {
                        let hold = self.and_not(q, r);
                        self.b.ins().bor(s, hold)
                    }
                    // Q1 := NOT R1 AND (S OR Q1)
                    _ => {
                        let set = self.b.ins().bor(s, q);
                        self.and_not(set, r)
                    }
                };
                self.set_flag(m(2), q);
            }
            StdFb::RTrig | StdFb::FTrig => {
                let (clk, mem) = (self.get(m(0)), self.truth(m(2)));
                let level = match fb {
                    StdFb::RTrig => self.b.ins().icmp_imm_s(IntCC::NotEqual, clk, 0),
                    _ => self.b.ins().icmp_imm_s(IntCC::Equal, clk, 0),
                };
                let q = self.and_not(level, mem);
                self.set_flag(m(1), q);
                match fb {
                    StdFb::RTrig => self.set(m(2), clk),
                    _ => self.set_flag(m(2), level),
                }
            }
            StdFb::Ctu(e) | StdFb::Ctd(e) => self.counter(fb, e, base),
            StdFb::Ctud(e) => self.up_down(e, base),
            StdFb::Tp | StdFb::Ton | StdFb::Tof => self.timer(fb, base),
        }
    }

    /// CTU (count up to PV, reset by R) or CTD (count down to 0, loaded with PV by LD).
    fn counter(&mut self, fb: StdFb, e: Elem, base: Slot) {
        let m = |i: u32| base + i;
        let edge = self.rising(m(0), m(5));
        let (clear, pv, cv) = (self.truth(m(1)), self.get(m(2)), self.get(m(4)));
        let (cv, q) = match fb {
            StdFb::Ctu(_) => {
                let below = self.less(e, cv, pv);
                let step = self.b.ins().band(edge, below);
                let up = self.b.ins().iadd_imm_s(cv, 1);
                let up = self.wrap(e, up);
                let counted = self.b.ins().select(step, up, cv);
                let zero = self.b.ins().iconst(types::I64, 0);
                let cv = self.b.ins().select(clear, zero, counted);
                let below = self.less(e, cv, pv);
                (cv, self.not(below))
            }
            _ => {
                let above = self.positive(e, cv);
                let step = self.b.ins().band(edge, above);
                let down = self.b.ins().iadd_imm_s(cv, -1);
                let down = self.wrap(e, down);
                let counted = self.b.ins().select(step, down, cv);
                let cv = self.b.ins().select(clear, pv, counted);
                let above = self.positive(e, cv);
                (cv, self.not(above))
            }
        };
        self.set(m(4), cv);
        self.set_flag(m(3), q);
    }

    /// CTUD: up on CU, down on CD, neither when both rise; R clears, LD loads PV.
    fn up_down(&mut self, e: Elem, base: Slot) {
        let m = |i: u32| base + i;
        let down = self.rising(m(1), m(9));
        let up = self.rising(m(0), m(8));
        let (r, ld, pv, cv) = (
            self.truth(m(2)),
            self.truth(m(3)),
            self.get(m(4)),
            self.get(m(7)),
        );
        let both = self.b.ins().band(up, down);
        let below = self.less(e, cv, pv);
        let count_up = self.b.ins().band(up, below);
        let count_up = self.and_not(count_up, both);
        let above = self.positive(e, cv);
        let count_down = self.b.ins().band(down, above);
        let count_down = self.and_not(count_down, both);
        let count_down = self.and_not(count_down, count_up);
        let plus = self.b.ins().iadd_imm_s(cv, 1);
        let plus = self.wrap(e, plus);
        let minus = self.b.ins().iadd_imm_s(cv, -1);
        let minus = self.wrap(e, minus);
        let counted = self.b.ins().select(count_up, plus, cv);
        let counted = self.b.ins().select(count_down, minus, counted);
        let loaded = self.b.ins().select(ld, pv, counted);
        let zero = self.b.ins().iconst(types::I64, 0);
        let cv = self.b.ins().select(r, zero, loaded);
        self.set(m(7), cv);
        let below = self.less(e, cv, pv);
        let qu = self.not(below);
        self.set_flag(m(5), qu);
        let above = self.positive(e, cv);
        let qd = self.not(above);
        self.set_flag(m(6), qd);
    }

    /// TP, TON or TOF: the states and times of `crate::stdfb`'s `tp`, `ton` and `tof`, each
    /// branch there a condition here that picks what the slot becomes.
    fn timer(&mut self, fb: StdFb, base: Slot) {
        let m = |i: u32| base + i;
        let (input, pt, q, et) = (
            self.truth(m(0)),
            self.get(m(1)),
            self.get(m(2)),
            self.get(m(3)),
        );
        let (state, prev, start) = (self.get(m(4)), self.truth(m(5)), self.get(m(6)));
        let now = self.now;
        let idle = self.b.ins().icmp_imm_s(IntCC::Equal, state, 0);
        // The edge that starts the timer: IN rises (TP, TON) or falls (TOF) while idle.
        let starts = match fb {
            StdFb::Tof => self.and_not(prev, input),
            _ => self.and_not(input, prev),
        };
        let starts = self.b.ins().band(starts, idle);
        // TON stops when IN falls, TOF when it rises again; TP runs to its end whatever IN does.
        let stops = match fb {
            StdFb::Tp => self.b.ins().iconst(types::I8, 0),
            StdFb::Ton => self.not(input),
            _ => input,
        };
        let stops = self.and_not(stops, starts);
        let running = self.b.ins().icmp_imm_s(IntCC::Equal, state, 1);
        let running = self.and_not(running, starts);
        let running = self.and_not(running, stops);
        let end = self.b.ins().iadd(start, pt);
        let elapsed = self.b.ins().icmp(IntCC::SignedLessThanOrEqual, end, now);
        let ends = self.b.ins().band(running, elapsed);
        let runs_on = self.and_not(running, elapsed);
        let (one, two) = (
            self.b.ins().iconst(types::I64, 1),
            self.b.ins().iconst(types::I64, 2),
        );
        let zero = self.b.ins().iconst(types::I64, 0);
        let state = self.b.ins().select(starts, one, state);
        let state = self.b.ins().select(stops, zero, state);
        let state = self.b.ins().select(ends, two, state);
        let start = self.b.ins().select(starts, now, start);
        let since = self.b.ins().isub(now, start);
        let et = self.b.ins().select(stops, zero, et);
        let et = self.b.ins().select(ends, pt, et);
        let et = self.b.ins().select(runs_on, since, et);
        let (state, et) = match fb {
            // A pulse that has ended rests until IN is low again.
            StdFb::Tp => {
                let done = self.b.ins().icmp_imm_s(IntCC::Equal, state, 2);
                let rests = self.and_not(done, input);
                (
                    self.b.ins().select(rests, zero, state),
                    self.b.ins().select(rests, zero, et),
                )
            }
            _ => (state, et),
        };
        let q = match fb {
            StdFb::Tp => {
                let q = self.b.ins().select(starts, one, q);
                self.b.ins().select(ends, zero, q)
            }
            StdFb::Ton => {
                let q = self.b.ins().select(starts, zero, q);
                let q = self.b.ins().select(stops, zero, q);
                self.b.ins().select(ends, one, q)
            }
            _ => {
                let delaying = self.b.ins().icmp_imm_s(IntCC::Equal, state, 1);
                let on = self.b.ins().bor(input, delaying);
                self.b.ins().uextend(types::I64, on)
            }
        };
        self.set(m(2), q);
        self.set(m(3), et);
        self.set(m(4), state);
        let raw = self.get(m(0));
        self.set(m(5), raw);
        self.set(m(6), start);
    }

    /// Whether slot `clk` rose since the memory slot `mem`, which takes `clk`'s value.
    fn rising(&mut self, clk: Slot, mem: Slot) -> Value {
        let (c, was) = (self.get(clk), self.truth(mem));
        let high = self.b.ins().icmp_imm_s(IntCC::NotEqual, c, 0);
        self.set(mem, c);
        self.and_not(high, was)
    }

    /// Slot `s` as a condition: not zero.
    fn truth(&mut self, s: Slot) -> Value {
        let v = self.get(s);
        self.b.ins().icmp_imm_s(IntCC::NotEqual, v, 0)
    }

    /// `a AND NOT b` of two conditions.
    fn and_not(&mut self, a: Value, b: Value) -> Value {
        let not_b = self.not(b);
        self.b.ins().band(a, not_b)
    }

    /// `NOT c` of a condition.
    fn not(&mut self, c: Value) -> Value {
        self.b.ins().bxor_imm_u(c, 1)
    }

    /// Condition `c` into slot `s` as a BOOL.
    fn set_flag(&mut self, s: Slot, c: Value) {
        let v = self.b.ins().uextend(types::I64, c);
        self.set(s, v);
    }

    /// `a < b` in the counter type `e`.
    fn less(&mut self, e: Elem, a: Value, b: Value) -> Value {
        let cc = match e.is_signed() {
            true => IntCC::SignedLessThan,
            false => IntCC::UnsignedLessThan,
        };
        self.b.ins().icmp(cc, a, b)
    }

    /// `a > 0` in the counter type `e`.
    fn positive(&mut self, e: Elem, a: Value) -> Value {
        let cc = match e.is_signed() {
            true => IntCC::SignedGreaterThan,
            false => IntCC::NotEqual,
        };
        self.b.ins().icmp_imm_s(cc, a, 0)
    }
}
