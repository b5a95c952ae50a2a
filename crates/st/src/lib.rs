//! IEC 61131-3 Structured Text for Cetratus (docs/st.md): a file parsed ([`parse`]), its names
//! and types checked and its PROGRAM compiled ([`compile`]) to the code of a register machine
//! ([`code`]) that runs one scan on a program's state ([`vm`]) without allocating, within a
//! work budget ([`Work`]). The standard function blocks ([`stdfb`]) run natively.
//!
//! The crate depends on nothing of Cetratus: the program crate builds on it, so that the
//! runtime runs ST programs without the importers.

pub mod ast;
pub mod code;
pub mod compile;
pub mod error;
mod format;
#[cfg(feature = "jit")]
pub mod jit;
mod lex;
pub mod parse;
pub mod stdfb;
pub mod types;
pub mod vm;
mod work;

pub use compile::{
    assigned_name, compile, compile_entry_texts, compile_with_entries, Entry, EntryError,
    EntryText, Unit, Var,
};
pub use error::{Diagnostic, Source, StError};
pub use vm::{Fault, State};
pub use work::Work;
