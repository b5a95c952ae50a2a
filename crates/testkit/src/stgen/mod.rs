//! Random, well-typed, deterministic IEC 61131-3 Structured Text programs for differential tests
//! against MATIEC ([`crate::matiec`]).
//!
//! [`generate`] writes one ST source that holds `count` PROGRAMs `P0`, `P1`, … (each after its
//! own TYPEs, FUNCTIONs and FUNCTION_BLOCKs, all named `P<k>_…`, and a comment
//! `(* ---- P<k> ---- *)`) and, per program, a [`Case`] with a random input sequence. The same
//! arguments give the same bytes: the only randomness is the splitmix64 generator below, seeded
//! from the seed and the program's index, so program `k` does not depend on the size of its
//! batch either.
//!
//! Programs are correct by construction, not filtered afterwards. Each expression is generated
//! for a *budget*, the values its context accepts, and carries what is known of its value: an
//! integer interval, a float interval, a string's length range, whether a TIME is normalised,
//! whether a BYTE or WORD has C bits above its width. Each variable has a *domain* that every
//! assignment to it keeps (`LIMIT`, `MOD` or a division bring a value back into it), which is
//! what lets state live across scans without ever leaving the defined part of the language.
//!
//! # The subset generated
//!
//! What an implementation must support to run every generated program:
//!
//! * POUs: `TYPE … END_TYPE` with enumerations `P0_E1 : (P0_E1_A, P0_E1_B);` and structures
//!   `P0_S1 : STRUCT f1 : INT; f2 : P0_E1; END_STRUCT;`; `FUNCTION P0_F1 : <elementary type>`
//!   with `VAR_INPUT` and `VAR`, assigning its name and reading it back; `FUNCTION_BLOCK P0_B1`
//!   with `VAR_INPUT`, `VAR_OUTPUT`, `VAR_IN_OUT` and `VAR` (which may hold a standard FB);
//!   `PROGRAM P0` with `VAR_INPUT`, `VAR_OUTPUT` and `VAR`. One to three declarations a line;
//!   initial values `:= <literal>`, array initialisers `[1, 2, 3]` and `[4(0)]`, structure
//!   initialisers `(f1 := 1, f3 := REAL#2.5)`.
//! * Types: the elementary types but the dates: BOOL, SINT, INT, DINT, LINT, USINT, UINT,
//!   UDINT, ULINT, BYTE, WORD, DWORD, LWORD, REAL, LREAL, TIME, STRING (plain, no length);
//!   `ARRAY[a..b] OF t` and `ARRAY[a..b, c..d] OF t` (bounds from -2 to 10) of elementary,
//!   enumeration and structure types; instances of TON, TOF, TP, CTU, CTD, CTUD, R_TRIG,
//!   F_TRIG, SR, RS and of the user FBs.
//! * Statements: `:=`; `IF … THEN … ELSIF … ELSE … END_IF`; `CASE e OF 1, 3..7: … ELSE …
//!   END_CASE` on integers (negative labels too) and on enumerations; `FOR i := a TO b BY c DO
//!   … END_FOR` (`c` negative too, `b` possibly `LIMIT(…)` of inputs); `WHILE`; `REPEAT …
//!   UNTIL … END_REPEAT`; `EXIT`; `RETURN` in functions; FB calls with formal arguments only,
//!   some inputs left out (they keep their value), `VAR_IN_OUT` arguments and `=>` bindings:
//!   `t1(IN := in1, PT := T#30ms, Q => st2);`.
//! * Expressions with the precedence of IEC 61131-3 (parentheses only where needed, and now and
//!   then where not): `OR`, `XOR`, `AND` and `&`, `=` `<>`, `<` `>` `<=` `>=`, `+` `-`, `*` `/`
//!   `MOD`, `**`, unary `-` and `NOT` (of a primary expression: `NOT (a)`, `-(x)`), on TIME
//!   `+`, `-`, `* 1`, `* 2` and `/ 2`, on STRING and TIME the comparisons too; variables,
//!   elements `a[i]`, `m[i, j]`, fields `r.f`, `a[i].f`, FB outputs `t1.Q`, `c1.CV`, `u1.y1`;
//!   calls of user functions with positional (`P0_F1(x, 3)`) or formal (`P0_F1(a1 := x)`)
//!   arguments.
//! * Literals: `123`, `-5`, `1_000`, `16#FF`, `16#FFFF_0000`, `2#1010`, `8#17`, `INT#-5`,
//!   `DINT#100`, `INT#16#7F`, `WORD#16#8001`, `UDINT#4000000000`, `TRUE`, `REAL#1.5`,
//!   `REAL#-2.5E2`, `LREAL#0.125`, `2.5`, `1.25e-1`, `1_024.5`, `T#1s500ms`, `T#1s_500ms`,
//!   `TIME#20ms`, `t#1m`, `T#1.5s`, `TIME#1h`, `'text'` with `$$ $' $N $T $R $P $hh`,
//!   enumeration values `P0_E1_B` and `P0_E1#P0_E1_B`.
//! * Standard functions: ABS, SQRT, EXPT, MIN and MAX (2 or 3 inputs), LIMIT, SEL, MUX (2 to 4
//!   inputs), SHL, SHR, ROL, ROR, TRUNC, LEN, LEFT, RIGHT, MID, CONCAT (2 or 3 inputs), INSERT,
//!   DELETE, REPLACE, FIND; the conversions `<A>_TO_<B>` between any two of BOOL, SINT…ULINT,
//!   BYTE…LWORD, REAL and LREAL; `<integer or BOOL>_TO_STRING`; `STRING_TO_<type>` but TIME.
//!
//! # What is never generated, and why
//!
//! Only what both IEC 61131-3 and C define (MATIEC translates to C), and what MATIEC gets right:
//!
//! 1. Integer arithmetic never leaves its type inside an expression. The whole right-hand side
//!    of an assignment may wrap around, in two's complement (`st1 := st1 + 1` with an INT at
//!    32767 gives -32768, and state starts near the limits on purpose): MATIEC computes SINT,
//!    INT, USINT and UINT in C `int` (so `(x + 1) / 2` would not wrap in C as in IEC, while the
//!    store does wrap), UDINT and ULINT in C unsigned arithmetic, and DINT and LINT wrap because
//!    [`crate::matiec`] compiles with `-fwrapv`. MATIEC folds expressions of literals and
//!    refuses them when they overflow ("Data type mismatch"), so a wrapping one reads a variable.
//!    An operation on untyped literals is computed in C `int` whatever the context's type (in a
//!    UDINT expression, MATIEC's `2_147_483_647 * 16#2` is -2), so its value stays within 32
//!    bits; with a typed literal (`UDINT#2_147_483_647 * 2`) it is computed in the type.
//! 2. Integer `/` and `MOD` divide by a literal other than 0 and -1, or by a guarded
//!    `(ABS(e MOD m) + 1)`; the most negative value is never negated nor given to ABS.
//! 3. Narrowing integer conversions (`DINT_TO_SINT(300)`) wrap modulo 2^n (gcc's choice, as
//!    for rule 1). REAL→integer and REAL→bit-string conversions only see values that round into
//!    the target (MATIEC rounds half to even) and no negative value for unsigned targets (MATIEC
//!    gives 0); TRUNC only as the whole right-hand side of an assignment, which types it
//!    (MATIEC types `TRUNC(r) > 5` as `TRUNC__ULINT__REAL`), and of a typed argument (of
//!    untyped literals only, `TRUNC(79.92 ** 2.0)`, MATIEC takes the REAL TRUNC).
//! 4. `SHL`/`SHR` shift by 0 … width-1, `ROL`/`ROR` by 1 … width-1 (MATIEC's `ROL` of a DWORD
//!    by 0 is a C shift by 32).
//! 5. `NOT` of a BYTE or WORD is C `~` on an `int`, whose bits above the width are set: such a
//!    value is only stored, passed to a function or masked by `AND` with a clean one, never
//!    compared. `NOT`'s operand is typed (MATIEC cannot type `NOT 16#F0F`), and neither `NOT`
//!    nor `-` applies to another unary operation (`NOT NOT x` is not IEC; MATIEC refuses it).
//! 6. Array indices are literals, loop counters whose range lies in the bounds, `LIMIT(lo, e,
//!    hi)` or `lo + ABS(e MOD n)`: never out of bounds.
//! 7. REAL and LREAL values are finite: divisors are literals with |d| ≥ 0.5 or `(ABS(e) +
//!    REAL#1.0)`, SQRT and EXPT see bases ≥ 0 and exponents 0.5 … 3, and every value stays in
//!    known bounds (±1e6 REAL, ±1e9 LREAL). REAL literals are always typed (`REAL#1.5`): MATIEC
//!    prints `1.5` as a C `double`, which makes gcc compute the whole REAL expression in double.
//!    For the same reason REAL `**` (MATIEC: `__expt(double, double)`) is only the whole
//!    right-hand side of an assignment; elsewhere `EXPT` (a function returning REAL). Decimal
//!    literals are ones for which decimal→f64→f32 is decimal→f32. No REAL_TO_STRING (C's
//!    `%.10g`), no trigonometry or logarithms (libm-dependent).
//! 8. TIME: no conversion from or to TIME (MATIEC's `INT_TO_TIME(5)` is 5 *seconds*, its
//!    `TIME_TO_INT` whole seconds); only literals MATIEC's long double arithmetic makes exact
//!    (`T#1ms` is 999 999 ns in MATIEC, as are 2, 4, 8, 16, 32, 63-65, 126, 128, 130, 252, 256,
//!    260, 265, 504, 507, 512, 517, 520, 525, 530 and 533 ms, `T#0.3s`, and most `T#<s>s<ms>ms`).
//!    The result of `+`, `-`, `* 2` or `/ 2` may be unnormalised in MATIEC (`T#600ms +
//!    T#400ms` is {0 s, 1e9 ns}, which compares less than `T#1s`): such a value is stored,
//!    selected or output as it is, and before a comparison, MIN, MAX, LIMIT or `* 2` it is
//!    normalised by `* 1` (MATIEC's `__time_mul` normalises). Every TIME stays within a day
//!    (comparisons: ten days), so that doubling state cannot overflow MATIEC's `tv_sec`.
//! 9. STRING: every value, intermediate ones too, has at most 80 characters (MATIEC's capacity
//!    is 126, ours 80). LEFT, RIGHT, MID, DELETE, INSERT and REPLACE take positions and lengths
//!    inside the string (known from its minimum length, e.g. of `CONCAT(s, 'abc')`); REPLACE's
//!    IN2 is never longer than L (MATIEC copies only L characters of it); FIND searches one
//!    character (MATIEC's search skips candidates after a partial match: `FIND('aab', 'ab')` is
//!    0). Literals have no `$L` (MATIEC prints a raw newline into C), no `$N` or `$hh` before a
//!    hex digit (MATIEC writes `\x0A` and C reads the digit into the escape), no `?` (C
//!    trigraphs), no `$00`, no `{` (MATIEC's lexer, looking for the first `;` of a body, takes it
//!    for a pragma and scans for the `}`: quadratic time, and a failure past 16 KB). No
//!    `<bit string>_TO_STRING` (MATIEC writes `16#ff`, which IEC does not fix), no
//!    `STRING_TO_<type>` but as rule 13 says.
//! 10. Loops terminate and mean the same to both. A FOR's bounds and step are literals or read
//!     inputs only (MATIEC evaluates them in every iteration) and have the counter's type; its
//!     counter is never assigned and never read after the loop (its last value is
//!     implementation-dependent); it runs zero times or at least twice: MATIEC tests
//!     `i + step <= end` before the first iteration, so `FOR i := 1 TO 1` runs zero times there.
//!     WHILE and REPEAT count with a counter of their own that ends them after at most 8 trips.
//! 11. Generic functions whose result type comes from the context (LEN, FIND, TRUNC, MIN of
//!     literals…) appear only where the context types them: in comparisons, indices, MUX
//!     selectors and shift counts at least one operand is typed (a variable, a typed literal).
//! 12. No enumeration value in a structure or array initialiser (MATIEC stops with an internal
//!     error in `enum_declaration_check.cc`); CASE labels never overlap; statement lists are
//!     never empty.
//! 13. `STRING_TO_<type>` of integers, bit strings and BOOL reads any string (MATIEC reads within
//!     the length, skips what is not a digit and wraps past 19 digits, as `cetratus-st` does);
//!     where the value must stay in a budget, the text is a literal the generator wrote (decimal
//!     digits after spaces or a `+`, or `2#`, `8#` and `16#` literals of at most 16, 24 and 64
//!     bits) or what `<integer>_TO_STRING` printed, and otherwise the result goes through
//!     `LIMIT`. To REAL and LREAL only literals, without underscores: MATIEC's `atof` reads past
//!     a string's length into the bytes a variable held before. Never to TIME (MATIEC reads
//!     whole seconds only).
//!
//! What MATIEC does in its own way, which the implementation under test must do too: CTU
//! counts only while `CV < PV` and CTD only while `CV > 0`; F_TRIG's Q is TRUE in the first scan
//! if CLK is FALSE (M starts FALSE); MIN, MAX and LIMIT compare with `<` and `>` (`MAX(-0.0,
//! 0.0)` is the first) and ABS of a REAL is `x < 0 ? -x : x` (`ABS(-0.0)` is -0.0); EXPT and
//! `**` compute C `pow` in double and round; REAL→integer rounds half to even; integer `/`
//! truncates and `MOD` has the dividend's sign; string comparison is bytewise.
//!
//! # Inputs
//!
//! Integers and bit strings take values at their limits (`INT` -32768, 32767, …), small values
//! and random ones, held for a few scans, or count up through their maximum; REALs are multiples
//! of 1/4 and 1/10 up to ±1000 given as exact bit patterns; TIMEs multiples of 10 ms; STRINGs
//! printable ASCII of at most 20 characters; BOOLs square waves, random, or rarely flipping, so
//! that timers, counters and edge detectors fire.

use crate::matiec::{Case, IecType};

/// One ST source holding several programs, and the case that runs each of them.
pub struct Batch {
    /// The programs `P0`, `P1`, … with their types, functions and function blocks; no
    /// CONFIGURATION (the harness adds its own).
    pub source: String,
    /// One case per program, in order: its interface and its input sequence.
    pub cases: Vec<Case>,
}

/// `count` random programs, each with `scans` scans of random inputs; the same arguments give
/// byte-identical batches.
pub fn generate(seed: u64, count: usize, scans: usize) -> Batch {
    let mut source = String::new();
    let mut cases = Vec::with_capacity(count);
    for index in 0..count {
        let mut rng = Rng::new(seed, index as u64);
        let program = ProgramGen::new(&mut rng, index).generate();
        source.push_str(&program.text);
        let scans = inputs::sequence(&mut rng, &program.inputs, scans);
        cases.push(Case {
            program: format!("P{index}"),
            inputs: program
                .inputs
                .iter()
                .map(|(n, t)| (n.clone(), *t))
                .collect(),
            outputs: program.outputs,
            scans,
        });
    }
    Batch { source, cases }
}

// ------------------------------------------------------------------------------------------
// Randomness

/// splitmix64: small, fast, and good enough to pick grammar productions.
struct Rng(u64);

impl Rng {
    fn new(seed: u64, stream: u64) -> Rng {
        let mut rng = Rng(seed ^ stream.wrapping_mul(0xD1B5_4A32_D192_ED03));
        rng.next();
        rng
    }

    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `0..n` (`n > 0`).
    fn below(&mut self, n: u64) -> u64 {
        ((u128::from(self.next()) * u128::from(n)) >> 64) as u64
    }

    /// Uniform in `lo..=hi`; the span may be as wide as ULINT.
    fn int(&mut self, lo: i128, hi: i128) -> i128 {
        let span = (hi - lo) as u128 + 1;
        if span > u128::from(u64::MAX) {
            lo + i128::from(self.next())
        } else {
            lo + i128::from(self.below(span as u64))
        }
    }

    fn range(&mut self, lo: usize, hi: usize) -> usize {
        self.int(lo as i128, hi as i128) as usize
    }

    /// True with probability `percent`/100.
    fn pct(&mut self, percent: u64) -> bool {
        self.below(100) < percent
    }

    fn pick<'a, T>(&mut self, xs: &'a [T]) -> &'a T {
        &xs[self.below(xs.len() as u64) as usize]
    }

    fn weighted<T: Copy>(&mut self, xs: &[(u32, T)]) -> T {
        let total: u32 = xs.iter().map(|x| x.0).sum();
        let mut r = self.below(u64::from(total)) as u32;
        for &(w, x) in xs {
            if r < w {
                return x;
            }
            r -= w;
        }
        xs[xs.len() - 1].1
    }
}

// ------------------------------------------------------------------------------------------
// Types and what is known about values

type Ty = IecType;

const ALL_TYPES: [Ty; 17] = [
    Ty::Bool,
    Ty::Sint,
    Ty::Int,
    Ty::Dint,
    Ty::Lint,
    Ty::Usint,
    Ty::Uint,
    Ty::Udint,
    Ty::Ulint,
    Ty::Byte,
    Ty::Word,
    Ty::Dword,
    Ty::Lword,
    Ty::Real,
    Ty::Lreal,
    Ty::Time,
    Ty::String,
];
/// The integer types: [`ALL_TYPES`] from SINT to ULINT.
const INT_TYPES: &[Ty] = ALL_TYPES.split_at(9).0.split_at(1).1;
/// The bit strings: [`ALL_TYPES`] from BYTE to LWORD.
const BIT_TYPES: &[Ty] = ALL_TYPES.split_at(13).0.split_at(9).1;
/// The sources of the numeric conversions `<A>_TO_<B>`: [`ALL_TYPES`] up to LREAL.
const CONV_TYPES: &[Ty] = ALL_TYPES.split_at(15).0;

/// What the generator needs to know of an elementary type.
trait TyInfo: Copy {
    fn is_int(self) -> bool;
    fn is_bits(self) -> bool;
    fn is_real(self) -> bool;
    fn signed(self) -> bool;
    fn width(self) -> u32;
    /// The values of an integer or bit-string type.
    fn full(self) -> Iv;
    /// Computed in C `int` by MATIEC (8 and 16 bits): exact inside, wraps when stored.
    fn narrow(self) -> bool;
    /// May wrap as the whole right-hand side of an assignment (rule 1 of the module doc).
    fn wraps(self) -> bool;
}

impl TyInfo for Ty {
    fn is_int(self) -> bool {
        INT_TYPES.contains(&self)
    }
    fn is_bits(self) -> bool {
        BIT_TYPES.contains(&self)
    }
    fn is_real(self) -> bool {
        matches!(self, Ty::Real | Ty::Lreal)
    }
    fn signed(self) -> bool {
        matches!(self, Ty::Sint | Ty::Int | Ty::Dint | Ty::Lint)
    }
    fn width(self) -> u32 {
        match self {
            Ty::Bool => 1,
            Ty::Sint | Ty::Usint | Ty::Byte => 8,
            Ty::Int | Ty::Uint | Ty::Word => 16,
            Ty::Dint | Ty::Udint | Ty::Dword | Ty::Real => 32,
            _ => 64,
        }
    }
    fn full(self) -> Iv {
        let w = self.width();
        if self.signed() {
            Iv::new(-(1i128 << (w - 1)), (1i128 << (w - 1)) - 1)
        } else {
            Iv::new(0, (1i128 << w) - 1)
        }
    }
    fn narrow(self) -> bool {
        (self.is_int() || self.is_bits()) && self.width() <= 16
    }
    fn wraps(self) -> bool {
        self.is_int()
    }
}

/// An interval of integers, `lo..=hi`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Iv {
    lo: i128,
    hi: i128,
}

impl Iv {
    fn new(lo: i128, hi: i128) -> Iv {
        debug_assert!(lo <= hi, "empty interval {lo}..{hi}");
        Iv { lo, hi }
    }
    fn point(v: i128) -> Iv {
        Iv::new(v, v)
    }
    fn within(self, o: Iv) -> bool {
        o.lo <= self.lo && self.hi <= o.hi
    }
    fn meet(self, o: Iv) -> Iv {
        Iv::new(self.lo.max(o.lo), self.hi.min(o.hi))
    }
    fn join(self, o: Iv) -> Iv {
        Iv::new(self.lo.min(o.lo), self.hi.max(o.hi))
    }
    /// The largest magnitude.
    fn mag(self) -> i128 {
        self.lo.abs().max(self.hi.abs())
    }
    /// Half of a budget that holds 0: two values of it add up to a value of the budget.
    fn half(self) -> Iv {
        Iv::new(self.lo / 2, self.hi / 2)
    }
}

/// An interval of reals, padded so that it holds the value whatever the rounding.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Rv {
    lo: f64,
    hi: f64,
}

impl Rv {
    fn new(lo: f64, hi: f64) -> Rv {
        Rv { lo, hi }
    }
    /// The interval widened by the relative error of one more rounding (f32 rounds by 6e-8).
    fn padded(lo: f64, hi: f64) -> Rv {
        Rv::new(lo - lo.abs() * 1e-6, hi + hi.abs() * 1e-6)
    }
    fn within(self, o: Rv) -> bool {
        o.lo <= self.lo && self.hi <= o.hi
    }
    fn join(self, o: Rv) -> Rv {
        Rv::new(self.lo.min(o.lo), self.hi.max(o.hi))
    }
    fn mag(self) -> f64 {
        self.lo.abs().max(self.hi.abs())
    }
    fn scaled(self, k: f64) -> Rv {
        Rv::new(self.lo * k, self.hi * k)
    }
}

/// What is known of a value; as a variable's domain, what every assignment to it keeps.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Val {
    Bool,
    Int(Iv),
    /// A BYTE…LWORD; `dirty` when the C value may carry bits above the type's width (rule 5).
    Bits {
        dirty: bool,
    },
    Real(Rv),
    /// A TIME of `range` nanoseconds; `clean` when MATIEC holds it normalised (rule 8), so
    /// that it may be compared.
    Time {
        clean: bool,
        range: Iv,
    },
    Str {
        min: u32,
        max: u32,
    },
    Enum(usize),
}

impl Val {
    fn iv(self) -> Iv {
        match self {
            Val::Int(iv) => iv,
            other => unreachable!("not an integer: {other:?}"),
        }
    }
    fn rv(self) -> Rv {
        match self {
            Val::Real(rv) => rv,
            other => unreachable!("not a real: {other:?}"),
        }
    }
    fn strlen(self) -> (u32, u32) {
        match self {
            Val::Str { min, max } => (min, max),
            other => unreachable!("not a string: {other:?}"),
        }
    }
    fn dirty(self) -> bool {
        matches!(self, Val::Bits { dirty: true })
    }
    /// Whether a value known as `self` may be stored into a variable of domain `dom`.
    fn fits(self, dom: Val) -> bool {
        match (self, dom) {
            (Val::Int(a), Val::Int(b)) => a.within(b),
            (Val::Real(a), Val::Real(b)) => a.within(b),
            (
                Val::Time { clean, range },
                Val::Time {
                    clean: need,
                    range: dom,
                },
            ) => (clean || !need) && range.within(dom),
            (Val::Str { max, .. }, Val::Str { max: cap, .. }) => max <= cap,
            (Val::Bits { .. }, Val::Bits { .. }) | (Val::Bool, Val::Bool) => true,
            (Val::Enum(a), Val::Enum(b)) => a == b,
            _ => false,
        }
    }
    /// The values of either (for SEL, MUX, MIN, MAX).
    fn join(self, o: Val) -> Val {
        match (self, o) {
            (Val::Int(a), Val::Int(b)) => Val::Int(a.join(b)),
            (Val::Real(a), Val::Real(b)) => Val::Real(a.join(b)),
            (Val::Bits { dirty: a }, Val::Bits { dirty: b }) => Val::Bits { dirty: a || b },
            (Val::Time { clean: a, range: r }, Val::Time { clean: b, range: s }) => Val::Time {
                clean: a && b,
                range: r.join(s),
            },
            (Val::Str { min: a, max: b }, Val::Str { min: c, max: d }) => Val::Str {
                min: a.min(c),
                max: b.max(d),
            },
            (a, _) => a,
        }
    }
}

// Precedence levels of ST operators (IEC 61131-3, table 52), loosest first.
const P_OR: u8 = 1;
const P_XOR: u8 = 2;
const P_AND: u8 = 3;
const P_EQ: u8 = 4;
const P_CMP: u8 = 5;
const P_ADD: u8 = 6;
const P_MUL: u8 = 7;
const P_UNARY: u8 = 8;
const P_ATOM: u8 = 10;

/// A generated expression: its text, how tightly it binds, and what is known of its value.
#[derive(Clone, Debug)]
struct Expr {
    text: String,
    prec: u8,
    val: Val,
    /// MATIEC can tell its type without the context (it has a variable, typed literal, …).
    typed: bool,
    /// Made of literals only: MATIEC folds it, and refuses it if it overflows.
    konst: bool,
}

impl Expr {
    /// The value of a TIME literal.
    fn val_time_lo(&self) -> i128 {
        match self.val {
            Val::Time { range, .. } => range.lo,
            other => unreachable!("not a TIME: {other:?}"),
        }
    }

    fn atom(text: String, val: Val, typed: bool) -> Expr {
        Expr {
            text,
            prec: P_ATOM,
            val,
            typed,
            konst: false,
        }
    }
    fn lit(text: String, val: Val, typed: bool) -> Expr {
        let prec = if text.starts_with('-') {
            P_UNARY
        } else {
            P_ATOM
        };
        Expr {
            text,
            prec,
            val,
            typed,
            konst: true,
        }
    }
    /// The text as an operand of an operator of precedence `min`.
    fn at(&self, min: u8) -> String {
        if self.prec >= min {
            self.text.clone()
        } else {
            format!("({})", self.text)
        }
    }
}

// ------------------------------------------------------------------------------------------
// The program being generated

/// Bounds on REAL/LREAL values where the context does not say more (comparisons, arguments).
const REAL_FREE: f64 = 1e6;
const LREAL_FREE: f64 = 1e9;
/// Domains of REAL/LREAL variables and of the inputs (the inputs are "nice" values).
const REAL_VAR: f64 = 1e4;
const LREAL_VAR: f64 = 1e6;
const REAL_INPUT: f64 = 1e3;
const LREAL_INPUT: f64 = 1e5;
/// STRING inputs are at most this long; no string value is ever longer than `STR_CAP`.
const STR_INPUT: u32 = 20;
const STR_CAP: u32 = 80;
/// TIME bounds, in ns: variables (and timer presets) within a day either way, inputs 0 … 10 s,
/// comparisons of values within ten days (far from where MATIEC's `tv_sec` would overflow).
const TIME_VAR: i128 = 86_400_000_000_000;
const TIME_INPUT: i128 = 10_000_000_000;
const TIME_FREE: Iv = Iv {
    lo: -10 * TIME_VAR,
    hi: 10 * TIME_VAR,
};

fn free_real(ty: Ty) -> Rv {
    let b = if ty == Ty::Real {
        REAL_FREE
    } else {
        LREAL_FREE
    };
    Rv::new(-b, b)
}

/// The type of a scalar: elementary or one of the program's enumerations.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Sty {
    E(Ty),
    Enum(usize),
}

/// The standard function blocks.
#[derive(Clone, Copy, Debug, PartialEq)]
enum StdFb {
    Ton,
    Tof,
    Tp,
    Ctu,
    Ctd,
    Ctud,
    RTrig,
    FTrig,
    Sr,
    Rs,
}

const STD_FBS: [StdFb; 10] = [
    StdFb::Ton,
    StdFb::Tof,
    StdFb::Tp,
    StdFb::Ctu,
    StdFb::Ctd,
    StdFb::Ctud,
    StdFb::RTrig,
    StdFb::FTrig,
    StdFb::Sr,
    StdFb::Rs,
];

impl StdFb {
    fn name(self) -> &'static str {
        match self {
            StdFb::Ton => "TON",
            StdFb::Tof => "TOF",
            StdFb::Tp => "TP",
            StdFb::Ctu => "CTU",
            StdFb::Ctd => "CTD",
            StdFb::Ctud => "CTUD",
            StdFb::RTrig => "R_TRIG",
            StdFb::FTrig => "F_TRIG",
            StdFb::Sr => "SR",
            StdFb::Rs => "RS",
        }
    }
    fn stem(self) -> &'static str {
        match self {
            StdFb::Ton | StdFb::Tof | StdFb::Tp => "tmr",
            StdFb::Ctu | StdFb::Ctd | StdFb::Ctud => "ctr",
            StdFb::RTrig | StdFb::FTrig => "trg",
            StdFb::Sr | StdFb::Rs => "ff",
        }
    }
    /// The outputs, with their types; CV's domain depends on the instance (see [`Fb::Std`]).
    fn outputs(self) -> &'static [(&'static str, Ty)] {
        match self {
            StdFb::Ton | StdFb::Tof | StdFb::Tp => &[("Q", Ty::Bool), ("ET", Ty::Time)],
            StdFb::Ctu | StdFb::Ctd => &[("Q", Ty::Bool), ("CV", Ty::Int)],
            StdFb::Ctud => &[("QU", Ty::Bool), ("QD", Ty::Bool), ("CV", Ty::Int)],
            StdFb::RTrig | StdFb::FTrig => &[("Q", Ty::Bool)],
            StdFb::Sr | StdFb::Rs => &[("Q1", Ty::Bool)],
        }
    }
}

/// A function block instance: standard (with the budget its PV argument keeps) or user-defined.
#[derive(Clone, Copy, Debug)]
enum Fb {
    Std(StdFb, Iv),
    User(usize),
}

/// A parameter of a user function or FB, or a field of a structure.
#[derive(Clone, Debug)]
struct Param {
    name: String,
    sty: Sty,
    dom: Val,
}

#[derive(Clone, Debug)]
struct FnDecl {
    name: String,
    ret: Ty,
    dom: Val,
    params: Vec<Param>,
}

#[derive(Clone, Debug)]
struct FbDecl {
    name: String,
    inputs: Vec<Param>,
    outputs: Vec<Param>,
    inouts: Vec<Param>,
}

#[derive(Clone, Debug)]
struct EnumDecl {
    name: String,
    values: Vec<String>,
}

#[derive(Clone, Debug)]
struct StructDecl {
    name: String,
    fields: Vec<Param>,
}

/// What a variable holds.
#[derive(Clone, Debug)]
enum Kind {
    Scalar(Sty, Val),
    /// Dimensions `lo..=hi`, and the element: a scalar or a structure.
    Array(Vec<(i128, i128)>, Elem),
    Struct(usize),
    Fb(Fb),
}

#[derive(Clone, Copy, Debug)]
enum Elem {
    Scalar(Sty, Val),
    Struct(usize),
}

/// Where a variable is declared, which says who may write it.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Section {
    Input,
    Output,
    InOut,
    Var,
    /// A function's result, written as the function's name and declared by its FUNCTION line.
    Result,
}

#[derive(Clone, Debug)]
struct Var {
    name: String,
    kind: Kind,
    section: Section,
    init: Option<String>,
    /// For a user FB instance: the variables passed to its VAR_IN_OUTs.
    binds: Vec<String>,
}

/// A loop counter while its loop runs: readable, with the range the loop gives it.
#[derive(Clone, Debug)]
struct Live {
    name: String,
    ty: Ty,
    range: Iv,
}

/// Something readable (and maybe writable) of a scalar type.
#[derive(Clone, Copy, Debug)]
enum Place {
    Var(usize),
    /// An array element, or a field of it when the elements are structures.
    Elem(usize, Option<usize>),
    Field(usize, usize),
    FbOut(usize, usize),
    Live(usize),
}

/// The POU whose body is being generated.
#[derive(Default)]
struct Pou {
    vars: Vec<Var>,
    live: Vec<Live>,
    /// Loop counters to declare in the POU's VAR section.
    counters: Vec<(String, Ty)>,
    /// How many loops enclose the statement being generated (EXIT is allowed inside one).
    loops: u32,
    /// Only inputs and loop counters may be read (FOR bounds: MATIEC evaluates them each time).
    stable: bool,
    /// The user functions this POU may call (those declared before it).
    callable: usize,
}

/// A generated program: its text and its interface.
struct Program {
    text: String,
    inputs: Vec<(String, Ty)>,
    outputs: Vec<(String, Ty)>,
}

/// Generates one program: its types, functions, function blocks and the PROGRAM itself.
struct ProgramGen<'r> {
    rng: &'r mut Rng,
    prefix: String,
    enums: Vec<EnumDecl>,
    structs: Vec<StructDecl>,
    funcs: Vec<FnDecl>,
    fbs: Vec<FbDecl>,
    /// The text of the TYPE block, functions and FBs, in declaration order.
    decls: String,
    pou: Pou,
    names: usize,
    /// How deep in index expressions we are: an index inside an index is a literal or counter.
    in_index: u32,
    /// How many declarations go on a line, by line number (chosen once: `var_blocks` reads it).
    groups: Vec<usize>,
}

/// What a bit-string expression must be: `clean`, with no bits above its width in C (rule 5),
/// and `typed`, a typed literal where a literal stands at its root.
#[derive(Clone, Copy)]
struct Bits {
    clean: bool,
    typed: bool,
}

impl Bits {
    /// Neither clean nor typed.
    const PLAIN: Bits = Bits {
        clean: false,
        typed: false,
    };

    /// The same, clean or not.
    fn with_clean(self, clean: bool) -> Bits {
        Bits { clean, ..self }
    }

    /// The same, typed or not.
    fn with_typed(self, typed: bool) -> Bits {
        Bits { typed, ..self }
    }
}

/// Where an expression stands: the whole right-hand side of an assignment, or inside another
/// expression (rule 7).
#[derive(Clone, Copy, PartialEq, Eq)]
enum Depth {
    Statement,
    Nested,
}

mod calls;
mod declarations;
mod from_string;
mod inputs;
mod ints;
mod literals;
mod places;
mod program;
mod reals;
mod statements;

#[allow(unused_imports)]
use self::{
    calls::*, declarations::*, ints::*, literals::*, places::*, program::*, reals::*, statements::*,
};
