//! Place/transition nets for Cetratus: the net as data, its marking, and the token game.
//!
//! This crate has no I/O besides parsing and printing text, no clock and no threads. A [`Net`] that
//! exists is well-formed: every arc joins a place and a transition, every id is unique, and the
//! sparse Pre/Post/inhibitor tables agree with the declared arcs.
//!
//! Order is declaration order everywhere (docs/design.md §3): `PlaceIdx(i)` is the i-th place declared after
//! nested pages are flattened, and a [`Marking`] is indexed by it.

mod csr;
mod engine;
mod error;
pub mod export;
mod marking;
mod net;
pub mod pnml;
pub mod xml;

pub use csr::Csr;
pub use engine::{Engine, FireError, Policy, SingleRule};
pub use error::{NetError, SourcePos};
pub use marking::Marking;
pub use net::{
    Arc, ArcKind, Net, NetBuilder, NodeRef, Place, PlaceIdx, Position, ToolSpecific, TransIdx,
    Transition,
};

/// Escapes `&`, `<`, `>`, `"` and `'` (quick-xml's `escape`), for XML text or a quoted attribute
/// value; borrows when there is nothing to escape. The one XML escaper of the workspace.
pub fn xml_escape(s: &str) -> std::borrow::Cow<'_, str> {
    quick_xml::escape::escape(s)
}

/// A token count. Arithmetic on it is always checked: overflow is an error, never a wrap-around.
pub type Tokens = u32;
