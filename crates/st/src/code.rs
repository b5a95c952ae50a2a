//! The instructions of the register machine that runs compiled Structured Text.
//!
//! Every operand is an absolute index into the state: a slot (`u32`) or a byte offset into the
//! text. A value that is computed lives in a slot too (a temporary, past the variables), so an
//! instruction reads its operands where they are and writes its result where it goes, without a
//! stack. Calls of functions and function blocks are expanded where they are called, so there is
//! no call stack either; what is left is straight code, forward jumps, and the backward jumps of
//! loops ([`Op::Loop`]), each of which charges the loop body's cost to the work budget.

use crate::ast::Rel;
use crate::stdfb::StdFb;
use crate::types::Elem;

/// A slot index.
pub type Slot = u32;
/// A byte offset into the text buffer, where a string starts.
pub type TextAt = u32;

/// Arithmetic and bitwise binary operations.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Arith {
    /// `+`.
    Add,
    /// `-`.
    Sub,
    /// `*`.
    Mul,
    /// `/`: faults on an integer division by zero.
    Div,
    /// `MOD`.
    Mod,
    /// `**`, EXPT.
    Pow,
    /// `AND` on BOOL and bit strings.
    And,
    /// `OR`.
    Or,
    /// `XOR`.
    Xor,
    /// MAX.
    Max,
    /// MIN.
    Min,
}

/// One-argument numeric functions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MathFn {
    /// ABS.
    Abs,
    /// SQRT.
    Sqrt,
    /// LN.
    Ln,
    /// LOG (base 10).
    Log,
    /// EXP.
    Exp,
    /// SIN.
    Sin,
    /// COS.
    Cos,
    /// TAN.
    Tan,
    /// ASIN.
    Asin,
    /// ACOS.
    Acos,
    /// ATAN.
    Atan,
}

/// Shifts and rotations of bit strings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShiftFn {
    /// SHL.
    Shl,
    /// SHR.
    Shr,
    /// ROL.
    Rol,
    /// ROR.
    Ror,
}

/// String functions whose operands do not fit in one instruction; they are kept in
/// [`Code::string_args`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StrFn {
    /// CONCAT(a, b).
    Concat,
    /// LEFT(s, n).
    Left,
    /// RIGHT(s, n).
    Right,
    /// MID(s, n, p).
    Mid,
    /// INSERT(a, b, p).
    Insert,
    /// DELETE(s, n, p).
    Delete,
    /// REPLACE(a, b, n, p).
    Replace,
}

/// The operands of a string function: the result's text offset and capacity, two strings, and
/// two integer slots (`n`, `p`; unused ones are 0).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StrArgs {
    /// Where the result goes.
    pub dst: TextAt,
    /// The result's capacity.
    pub cap: u16,
    /// The first string.
    pub a: TextAt,
    /// The second string (INSERT, REPLACE, CONCAT).
    pub b: TextAt,
    /// The length argument `L`, a slot holding an ANY_INT.
    pub n: Slot,
    /// The position argument `P`, a slot.
    pub p: Slot,
    /// The type of `n` and `p`.
    pub int: Elem,
}

/// What went wrong at run time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FaultKind {
    /// An integer division or MOD by zero.
    DivisionByZero,
    /// An array index outside the declared bounds.
    IndexOutOfRange {
        /// The index.
        index: i64,
        /// The lower bound.
        lo: i32,
        /// The upper bound.
        hi: i32,
    },
    /// The scan's work budget was reached (a loop that runs too long).
    Budget,
}

/// One instruction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Op {
    /// `dst := bits`.
    Const { dst: Slot, bits: u64 },
    /// `dst := src`.
    Move { dst: Slot, src: Slot },
    /// `len` slots from `src` to `dst` (a structure, array or instance).
    Copy { dst: Slot, src: Slot, len: u32 },
    /// `len` bytes of text from `src` to `dst`.
    CopyText { dst: TextAt, src: TextAt, len: u32 },
    /// `dst := a op b` in type `e`.
    Arith {
        op: Arith,
        e: Elem,
        dst: Slot,
        a: Slot,
        b: Slot,
    },
    /// `dst := a rel b` in type `e`.
    Cmp {
        op: Rel,
        e: Elem,
        dst: Slot,
        a: Slot,
        b: Slot,
    },
    /// `dst := -a`.
    Neg { e: Elem, dst: Slot, a: Slot },
    /// `dst := NOT a` (BOOL or bit string).
    Not { e: Elem, dst: Slot, a: Slot },
    /// `dst := <from>_TO_<to>(a)`.
    Conv {
        from: Elem,
        to: Elem,
        dst: Slot,
        a: Slot,
    },
    /// `dst := TRUNC(a)`: a REAL or LREAL to the integer type `to`, toward zero.
    Trunc {
        from: Elem,
        to: Elem,
        dst: Slot,
        a: Slot,
    },
    /// `dst := f(a)`.
    Math {
        f: MathFn,
        e: Elem,
        dst: Slot,
        a: Slot,
    },
    /// `dst := f(a, n)`; `n` a slot of integer type `ne`.
    Shift {
        f: ShiftFn,
        e: Elem,
        dst: Slot,
        a: Slot,
        n: Slot,
    },
    /// `dst := if c then a else b`.
    Select {
        dst: Slot,
        c: Slot,
        a: Slot,
        b: Slot,
    },
    /// Go to `to`.
    Jump { to: u32 },
    /// Go to `to` if slot `c` is true.
    JumpIf { c: Slot, to: u32 },
    /// Go to `to` if slot `c` is false.
    JumpUnless { c: Slot, to: u32 },
    /// The backward jump that closes a loop: charges `cost` units of work, then goes to `to`.
    Loop { to: u32, cost: u32 },
    /// `acc := acc * len + (idx - lo)`, after checking `lo <= idx < lo + len`: one dimension of
    /// an array index, `idx` of integer type `e`.
    Index {
        e: Elem,
        acc: Slot,
        idx: Slot,
        lo: i32,
        len: u32,
    },
    /// `dst := base + (idx - lo)`, after checking `lo <= idx < lo + len`: the slot of an element
    /// of a one-dimensional array of an elementary type at the fixed slot `base`, in one
    /// instruction (an `Index` and its `Addr`s otherwise).
    Index1 {
        e: Elem,
        dst: Slot,
        idx: Slot,
        lo: i32,
        len: u32,
        base: u32,
    },
    /// `dst := base + lin * stride`: an element's slot or text offset from its linear index.
    Addr {
        dst: Slot,
        lin: Slot,
        stride: u32,
        base: u32,
    },
    /// `dst := slots[slots[addr] + off]`.
    LoadInd { dst: Slot, addr: Slot, off: u32 },
    /// `slots[slots[addr] + off] := src`.
    StoreInd { addr: Slot, off: u32, src: Slot },
    /// `len` slots from `slots[addr] + off` to `dst`.
    CopyFromInd {
        dst: Slot,
        addr: Slot,
        off: u32,
        len: u32,
    },
    /// `len` slots from `src` to `slots[addr] + off`.
    CopyToInd {
        addr: Slot,
        off: u32,
        src: Slot,
        len: u32,
    },
    /// `len` bytes of text from `slots[addr] + off` to `dst`.
    TextFromInd {
        dst: TextAt,
        addr: Slot,
        off: u32,
        len: u32,
    },
    /// `len` bytes of text from `src` to `slots[addr] + off`.
    TextToInd {
        addr: Slot,
        off: u32,
        src: TextAt,
        len: u32,
    },
    /// The string literal `lit` of [`Code::literals`] into `dst`, cut to `cap`.
    StrLit { dst: TextAt, cap: u16, lit: u32 },
    /// The string at `src` into `dst`, cut to `cap`.
    StrMove { dst: TextAt, cap: u16, src: TextAt },
    /// `dst := LEN(s)` as type `e`.
    StrLen { e: Elem, dst: Slot, s: TextAt },
    /// `dst := FIND(a, b)` as type `e`.
    StrFind {
        e: Elem,
        dst: Slot,
        a: TextAt,
        b: TextAt,
    },
    /// `dst := a rel b`, byte-wise.
    StrCmp {
        op: Rel,
        dst: Slot,
        a: TextAt,
        b: TextAt,
    },
    /// `dst := STRING_TO_<e>(s)`, read as MATIEC's library reads it.
    FromStr { e: Elem, dst: Slot, s: TextAt },
    /// `dst := <e>_TO_STRING(a)`, cut to `cap`.
    ToStr {
        e: Elem,
        dst: TextAt,
        cap: u16,
        a: Slot,
    },
    /// `dst := a * f` (or `a / f` when `div`): a TIME scaled by the LREAL in slot `f`.
    TimeScale {
        div: bool,
        dst: Slot,
        a: Slot,
        f: Slot,
    },
    /// A string function; its operands are [`Code::string_args`]`[args]`.
    Str { f: StrFn, args: u32 },
    /// Runs a standard function block whose instance starts at slot `base`.
    StdFb { fb: StdFb, base: Slot },
}

impl Op {
    /// The slot of the one result, for the instructions that write one slot and do not read it:
    /// what the compiler may redirect, and what the machine code knows such an instruction
    /// writes.
    pub(crate) fn result_mut(&mut self) -> Option<&mut Slot> {
        match self {
            Op::Const { dst, .. }
            | Op::Move { dst, .. }
            | Op::Arith { dst, .. }
            | Op::Cmp { dst, .. }
            | Op::Neg { dst, .. }
            | Op::Not { dst, .. }
            | Op::Conv { dst, .. }
            | Op::Trunc { dst, .. }
            | Op::Math { dst, .. }
            | Op::Shift { dst, .. }
            | Op::Select { dst, .. }
            | Op::Index1 { dst, .. }
            | Op::Addr { dst, .. }
            | Op::LoadInd { dst, .. }
            | Op::StrLen { dst, .. }
            | Op::FromStr { dst, .. }
            | Op::StrFind { dst, .. }
            | Op::StrCmp { dst, .. }
            | Op::TimeScale { dst, .. } => Some(dst),
            _ => None,
        }
    }

    /// What this instruction costs in units of work: one, and one more per 16 slots or bytes
    /// it moves, so a copy of a large array or string is not as cheap as an addition.
    pub fn cost(&self, code: &Code) -> u64 {
        let moved = match *self {
            Op::Copy { len, .. }
            | Op::CopyText { len, .. }
            | Op::CopyFromInd { len, .. }
            | Op::CopyToInd { len, .. }
            | Op::TextFromInd { len, .. }
            | Op::TextToInd { len, .. } => u64::from(len),
            Op::StrLit { cap, .. } | Op::StrMove { cap, .. } | Op::ToStr { cap, .. } => {
                u64::from(cap)
            }
            Op::StrLen { .. } => 0,
            Op::FromStr { .. } => u64::from(crate::types::MAX_STRING),
            Op::StrFind { .. } | Op::StrCmp { .. } => u64::from(crate::types::MAX_STRING),
            Op::Str { args, .. } => u64::from(code.string_args[args as usize].cap) * 2,
            Op::StdFb { .. } => 16,
            _ => 0,
        };
        1 + moved / 16
    }
}

/// Compiled code: the instructions, and the tables they refer to.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Code {
    /// The instructions.
    pub ops: Vec<Op>,
    /// For each instruction, the byte offset in the source it was compiled from.
    pub pos: Vec<u32>,
    /// String literals.
    pub literals: Vec<Vec<u8>>,
    /// Operands of [`Op::Str`].
    pub string_args: Vec<StrArgs>,
    /// The temporaries, sorted: slots that hold an operation's result for the instructions
    /// after it in the same run of this code, written before they are read, never read by other
    /// code or after the run. A condition's result is not among them.
    pub temps: Vec<Slot>,
}

/// One piece of a unit's code, as it is run: its place among the unit's pieces (0 the body,
/// `k + 1` the entry `k`), which is also its function in the machine code, the code, and what
/// its straight-line code costs a run.
#[derive(Clone, Copy, Debug)]
pub struct Piece<'a> {
    /// Its place among the unit's pieces.
    pub index: usize,
    /// Its code.
    pub code: &'a Code,
    /// What running its straight-line code once costs, in units of work.
    pub cost: u64,
}

impl Code {
    /// Whether slot `s` is one of [`Code::temps`].
    pub fn is_temp(&self, s: Slot) -> bool {
        self.temps.binary_search(&s).is_ok()
    }
}
