//! Machine code for compiled Structured Text (docs/st.md, *Machine code*): each piece of code of a
//! unit (its body, each chart entry) is translated once, at load, by Cranelift into a native
//! function that does what [`crate::vm::run`] does on the same state, instruction for
//! instruction. The register machine stays the reference: what the translation does not compile
//! itself (strings, conversions that round, the functions of `math.h`) it hands to
//! [`crate::vm::exec`] through one call, and a unit that cannot be translated (a target
//! Cranelift does not know, code past [`MAX_OPS`]) runs on the interpreter.
//!
//! The one `unsafe` of the crate is here, and it is the fourth exception of the workspace's
//! `unsafe_code` rule (ARCHITECTURE.md): calling the generated function, the call back from it,
//! and freeing its memory. What makes it sound:
//! * the generated code reads and writes the slots only at indices below the length it is given:
//!   the fixed indices of the code are checked against the state once before the call
//!   ([`Machine::run`] falls back to the interpreter when the state is shorter), and an index
//!   computed at run time (`LoadInd`, `StoreInd`) is compared with the length before it is used,
//!   and handed to the interpreter, whose slice index panics as it always has, when it is past it;
//! * the text is touched only by the interpreter, through the slice of the state;
//! * the loops charge the work budget as the interpreter's do, so the code ends;
//! * the memory of the code is freed only when the [`Machine`] is dropped, and a call borrows it.

mod lower;

use std::any::Any;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::Mutex;

use cranelift_codegen::ir::{types, AbiParam, Signature};
use cranelift_codegen::settings::{self, Configurable};
use cranelift_jit::{JITBuilder, JITModule};
use cranelift_module::{default_libcall_names, Linkage, Module};

use crate::code::{Code, FaultKind, Piece};
use crate::vm::{Fault, State};
use crate::work::Work;

/// The longest code that is translated, under a second of translation (some 7 µs an
/// instruction); longer code runs on the interpreter, whose speed does not depend on the code's
/// length while the translation's time grows with it, and a package cannot make a load spend
/// more than that on it.
pub const MAX_OPS: usize = 100_000;

/// What the generated code and its call back share, laid out for the generated code: it reads
/// the first six fields at fixed offsets ([`lower`]).
#[repr(C)]
pub(crate) struct Frame<'a> {
    /// The first slot.
    slots: *mut u64,
    /// The number of slots.
    len: u64,
    /// Work charged so far.
    used: u64,
    /// Work allowed.
    budget: u64,
    /// [`call_back`].
    back: extern "C" fn(*mut Frame<'_>, u64) -> u64,
    /// The scan's time.
    now: i64,
    /// The text, for the interpreter's instructions.
    text: *mut u8,
    /// Its length.
    text_len: usize,
    /// The code, for the instructions handed back.
    code: &'a Code,
    /// The fault an instruction handed back had.
    fault: Option<FaultKind>,
    /// The panic of an instruction handed back, carried across the generated code.
    panic: Option<Box<dyn Any + Send>>,
}

/// Offsets of [`Frame`]'s fields that the generated code reads.
pub(crate) mod offset {
    /// `slots`.
    pub const SLOTS: i32 = 0;
    /// `len`.
    pub const LEN: i32 = 8;
    /// `used`.
    pub const USED: i32 = 16;
    /// `budget`.
    pub const BUDGET: i32 = 24;
    /// `back`.
    pub const BACK: i32 = 32;
    /// `now`.
    pub const NOW: i32 = 40;
}

// The generated code reads the frame at these offsets: the layout must be what it reads.
const _: () = {
    use std::mem::offset_of;
    assert!(offset_of!(Frame<'static>, slots) == offset::SLOTS as usize);
    assert!(offset_of!(Frame<'static>, len) == offset::LEN as usize);
    assert!(offset_of!(Frame<'static>, used) == offset::USED as usize);
    assert!(offset_of!(Frame<'static>, budget) == offset::BUDGET as usize);
    assert!(offset_of!(Frame<'static>, back) == offset::BACK as usize);
    assert!(offset_of!(Frame<'static>, now) == offset::NOW as usize);
};

type Entry = extern "C" fn(*mut Frame<'_>) -> u64;

/// The machine code of a unit: one function per piece of code, in the order they were given.
pub struct Machine {
    /// The functions; `None` for a piece that runs on the interpreter.
    functions: Vec<Option<Compiled>>,
    /// The memory the functions are in, freed on drop.
    module: Mutex<Option<JITModule>>,
}

#[derive(Clone, Copy)]
struct Compiled {
    entry: Entry,
    /// One past the largest fixed slot index of the code.
    needs: usize,
}

impl std::fmt::Debug for Machine {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let native = self.functions.iter().filter(|c| c.is_some()).count();
        write!(
            f,
            "Machine({native} of {} in machine code)",
            self.functions.len()
        )
    }
}

impl Machine {
    /// Translates `pieces`; `None` when this machine has no code generator (the caller then
    /// interprets). A piece that is too long, or that the generator refuses, is interpreted.
    #[allow(unsafe_code)]
    pub fn compile(pieces: &[&Code]) -> Option<Machine> {
        let mut flags = settings::builder();
        flags.set("opt_level", "speed").ok()?;
        // Cranelift's verifier checks the IR in debug builds (the tests), not at every load of
        // a release build, where it took half the translation's time.
        let verify = if cfg!(debug_assertions) {
            "true"
        } else {
            "false"
        };
        flags.set("enable_verifier", verify).ok()?;
        flags.set("use_colocated_libcalls", "false").ok()?;
        flags.set("is_pic", "false").ok()?;
        let isa = cranelift_native::builder()
            .ok()?
            .finish(settings::Flags::new(flags))
            .ok()?;
        let mut module = JITModule::new(JITBuilder::with_isa(isa, default_libcall_names()));
        let ids: Vec<_> = pieces
            .iter()
            .enumerate()
            .map(|(k, code)| define(&mut module, k, code))
            .collect();
        module.finalize_definitions().ok()?;
        let functions = ids
            .into_iter()
            .map(|d| {
                d.map(|(id, needs)| {
                    let ptr = module.get_finalized_function(id);
                    // SAFETY: `ptr` is the function just defined with the signature of
                    // `Entry` (`define`), whose memory lives as long as `self.module`.
                    let entry = unsafe { std::mem::transmute::<*const u8, Entry>(ptr) };
                    Compiled { entry, needs }
                })
            })
            .collect();
        Some(Machine {
            functions,
            module: Mutex::new(Some(module)),
        })
    }

    /// Whether piece `k` runs in machine code.
    pub fn is_native(&self, k: usize) -> bool {
        matches!(self.functions.get(k), Some(Some(_)))
    }

    /// Runs `piece` as [`crate::vm::run`] runs it; `None` when that piece is interpreted or
    /// `state` is too short for it (the caller then interprets).
    #[inline]
    pub fn run(
        &self,
        piece: Piece<'_>,
        state: &mut State,
        now: i64,
        work: &mut Work,
    ) -> Option<Result<(), Fault>> {
        let Piece { index, code, cost } = piece;
        let compiled = (*self.functions.get(index)?)?;
        if state.slots.len() < compiled.needs {
            return None;
        }
        if !work.charge(cost) {
            return Some(Err(fault(code, 0, FaultKind::Budget)));
        }
        let mut frame = Frame {
            slots: state.slots.as_mut_ptr(),
            len: state.slots.len() as u64,
            used: work.used(),
            budget: work.budget(),
            back: call_back,
            now,
            text: state.text.as_mut_ptr(),
            text_len: state.text.len(),
            code,
            fault: None,
            panic: None,
        };
        let status = (compiled.entry)(&mut frame);
        work.set_used(frame.used);
        if let Some(payload) = frame.panic.take() {
            std::panic::resume_unwind(payload);
        }
        Some(match status {
            0 => Ok(()),
            _ => Err(stopped(code, status, frame.fault, state)),
        })
    }
}

/// The fault of a run that stopped with `status` (the faulting instruction's index plus one).
#[cold]
fn stopped(code: &Code, status: u64, checked: Option<FaultKind>, state: &State) -> Fault {
    let pc = (status - 1) as usize;
    // An instruction the generated code checks itself (a loop out of budget, a division by
    // zero, an index out of bounds) left the state unwritten.
    let kind = checked.unwrap_or_else(|| match code.ops.get(pc) {
        Some(&op) => crate::vm::fault_of(op, &state.slots),
        None => FaultKind::Budget,
    });
    fault(code, pc, kind)
}

impl Drop for Machine {
    #[allow(unsafe_code)]
    fn drop(&mut self) {
        let module = match self.module.get_mut() {
            Ok(m) => m.take(),
            Err(poisoned) => poisoned.into_inner().take(),
        };
        if let Some(module) = module {
            // SAFETY: the functions are called only through `&self` (`run`), so none runs now,
            // and `self.functions` goes with `self`.
            unsafe { module.free_memory() };
        }
    }
}

/// Defines piece `k` in `module`: its id and the slots it needs, or `None` when it is
/// interpreted.
fn define(
    module: &mut JITModule,
    k: usize,
    code: &Code,
) -> Option<(cranelift_module::FuncId, usize)> {
    if code.ops.len() > MAX_OPS {
        return None;
    }
    let ptr = module.target_config().pointer_type();
    let mut sig = Signature::new(module.isa().default_call_conv());
    sig.params.push(AbiParam::new(ptr));
    sig.returns.push(AbiParam::new(types::I64));
    let id = module
        .declare_function(&format!("piece{k}"), Linkage::Local, &sig)
        .ok()?;
    let mut ctx = module.make_context();
    ctx.func.signature = sig;
    let needs = lower::lower(code, &mut ctx.func, module.isa())?;
    module.define_function(id, &mut ctx).ok()?;
    module.clear_context(&mut ctx);
    Some((id, needs))
}

/// The fault of instruction `pc` of `code`, at its place in the source.
fn fault(code: &Code, pc: usize, kind: FaultKind) -> Fault {
    Fault {
        kind,
        pos: code.pos.get(pc).copied().unwrap_or(0),
    }
}

/// Runs instruction `pc` on the interpreter, for the generated code: 0 when it went through,
/// else 1 and the frame holds its fault, or its panic, which [`Machine::run`] resumes past the
/// generated code (a panic cannot unwind through it).
#[allow(unsafe_code)]
extern "C" fn call_back(frame: *mut Frame<'_>, pc: u64) -> u64 {
    // SAFETY: the generated code passes on the frame that `Machine::run` gave it, which lives
    // for the call, and does not touch the state while this runs; the slots and the text are
    // the state's, of the lengths recorded beside them.
    let frame = unsafe { &mut *frame };
    let s = unsafe { std::slice::from_raw_parts_mut(frame.slots, frame.len as usize) };
    let t = unsafe { std::slice::from_raw_parts_mut(frame.text, frame.text_len) };
    let (code, now) = (frame.code, frame.now);
    let Some(&op) = code.ops.get(pc as usize) else {
        return 1;
    };
    // Only instructions that do not jump come here, so the work is never charged.
    let mut work = Work::unlimited();
    let ran = catch_unwind(AssertUnwindSafe(|| {
        crate::vm::exec(&op, code, s, t, now, &mut work)
    }));
    match ran {
        Ok(crate::vm::Flow::Next | crate::vm::Flow::Goto(_)) => 0,
        Ok(crate::vm::Flow::Fault) => {
            frame.fault = Some(crate::vm::fault_of(op, s));
            1
        }
        Err(payload) => {
            frame.panic = Some(payload);
            1
        }
    }
}
