//! Export of a Cetratus program to the PLCs plants already own (docs/export.md): the
//! semi-compiled Petri-net algorithm in IEC 61131-3 Structured Text.
//!
//! [`to_st`] writes one file in four parts: the kernel ([`kernel`]: a FUNCTION_BLOCK that does
//! not depend on the net), the net as data ([`data`]: sparse Pre, Post and inhibitor tables,
//! M0, capacities, visiting order and priorities, as constants), the interpretation compiled to
//! ST ([`logic`]: guards, place timers, the IEC action control, action bodies), and a PROGRAM
//! that wires the signals to located addresses ([`io`]) with a CONFIGURATION whose TASK runs at
//! the program's scan period. The same program always gives the same bytes.

use std::fmt;

use cetratus_program::Program;

mod data;
mod expr;
mod io;
mod kernel;
mod logic;
mod names;

pub use data::DataSize;
pub use io::IoRow;
pub use names::Rename;

/// The ST dialect of an export.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Dialect {
    /// IEC 61131-3 as MATIEC (OpenPLC, Beremiz) compiles it.
    #[default]
    Iec,
}

impl Dialect {
    /// Every dialect, by name.
    pub const ALL: &'static [(&'static str, Dialect)] = &[("iec", Dialect::Iec)];

    /// The dialect's name.
    pub fn name(self) -> &'static str {
        match self {
            Dialect::Iec => "iec",
        }
    }
}

impl std::str::FromStr for Dialect {
    type Err = ExportError;
    fn from_str(s: &str) -> Result<Self, ExportError> {
        Dialect::ALL
            .iter()
            .find(|(n, _)| *n == s)
            .map(|&(_, d)| d)
            .ok_or_else(|| ExportError::Dialect(s.to_string()))
    }
}

/// Why a program cannot be exported.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum ExportError {
    /// The dialect asked for is none the exporter writes.
    #[error("unknown dialect `{0}`; the dialects are: {names}", names = Dialect::ALL.iter().map(|(n, _)| *n).collect::<Vec<_>>().join(", "))]
    Dialect(String),
    /// A part of the program the export cannot write.
    #[error("cannot export: {what}; {hint}")]
    Unsupported {
        /// What it is.
        what: String,
        /// What to do.
        hint: &'static str,
    },
    /// A signal's address that is no located address of its type.
    #[error("cannot export: {signal}'s address `{address}`: {why}")]
    Address {
        /// The signal.
        signal: String,
        /// Its address.
        address: String,
        /// What is wrong.
        why: String,
    },
}

/// An exported program.
#[derive(Clone, Debug)]
pub struct StExport {
    /// The file's name: the program's name (made a valid file name) and `.st`.
    pub file_name: String,
    /// The whole file.
    pub text: String,
    /// Everything but the CONFIGURATION: the types, the kernel, the interpretation and the
    /// PROGRAM (for a harness that configures the program itself).
    pub pous: String,
    /// The net's constants, as a `VAR_GLOBAL CONSTANT` block of the CONFIGURATION.
    pub globals: String,
    /// The name of the PROGRAM.
    pub program: String,
    /// The I/O map.
    pub io: Vec<IoRow>,
    /// The I/O map as CSV (`<program>.io.csv`).
    pub io_csv: String,
    /// The program's names the export had to change.
    pub renames: Vec<Rename>,
    /// The net's data, sparse, beside the dense layout.
    pub data: DataSize,
}

/// Writes `program` as IEC 61131-3 Structured Text in `dialect`.
pub fn to_st(program: &Program, dialect: Dialect) -> Result<StExport, ExportError> {
    let Dialect::Iec = dialect;
    let net = program.net();
    let data = data::NetData::new(net, program.policy());
    let mut global = names::Names::new(data::GLOBALS);
    for fixed in [
        "CETRATUS_CONFIG",
        "CETRATUS_RESOURCE",
        "CETRATUS_TASK",
        "CETRATUS_MAIN",
    ] {
        global.claim(None, fixed);
    }
    let name = global.claim(None, program.name());
    let fb = global.claim(None, &format!("{name}_LOGIC"));
    let logic = logic::Logic::new(program, global)?;
    let io = io::map(program.inputs(), program.outputs(), |s| logic.signal(s))?;
    let size = data.size();
    let mut globals = format!(
        "  VAR_GLOBAL CONSTANT\n    (* The net as data: {} bytes sparse; Pre, Post and M0 dense would take {}. *)\n",
        size.sparse_bytes, size.dense_bytes
    );
    for c in data.constants() {
        globals.push_str("    ");
        globals.push_str(&c);
        globals.push('\n');
    }
    globals.push_str("  END_VAR\n");
    let mut pous = header(program, &logic, &io, size);
    pous.push_str(
        "\n(* Part 2: the net's array types; its values are the CONFIGURATION's constants. *)\n",
    );
    pous.push_str(&data.types());
    pous.push_str("\n(* Part 1: the kernel. *)\n");
    pous.push_str(kernel::KERNEL);
    pous.push_str("\n(* Part 3: the interpretation. *)\n");
    pous.push_str(&logic.pou(&fb)?);
    pous.push_str("\n(* Part 4: the program at its addresses, and its task. *)\n");
    pous.push_str(&logic::program_pou(&name, &fb, &io, program));
    let text = format!(
        "{pous}\n{}",
        logic::configuration(&globals, &name, program.scan_period().as_micros() as u64)
    );
    Ok(StExport {
        file_name: format!("{}.st", file_stem(program.name())),
        text,
        pous,
        globals,
        program: name,
        io_csv: io::csv(&io),
        io,
        renames: logic.names().renames().to_vec(),
        data: size,
    })
}

/// The file's opening comment: what it is, from which program, and the renames.
fn header(program: &Program, logic: &logic::Logic, io: &[IoRow], size: DataSize) -> String {
    let mut s = format!(
        "(* {} {}, exported by Cetratus as IEC 61131-3 Structured Text.\n   Program hash {}.\n   Policy {}, scan period {} us; {} places, {} transitions.\n   The net's data: {} bytes sparse ({} dense).\n",
        comment(program.name()),
        comment(program.version()),
        program.hash_hex(),
        policy_name(program.policy()),
        program.scan_period().as_micros(),
        program.net().num_places(),
        program.net().num_transitions(),
        size.sparse_bytes,
        size.dense_bytes,
    );
    let assigned: Vec<String> = (io.iter().filter(|r| r.assigned))
        .map(|r| format!("{} at {}", r.signal, r.address))
        .collect();
    if !assigned.is_empty() {
        s.push_str(&format!(
            "   Addresses assigned: {}.\n",
            comment(&assigned.join(", "))
        ));
    }
    for r in logic.names().renames() {
        s.push_str(&format!(
            "   Renamed: {} `{}` is {}.\n",
            r.kind,
            comment(&r.from),
            r.to
        ));
    }
    s.push_str("*)\n");
    s
}

fn policy_name(p: cetratus_net::Policy) -> String {
    match p {
        cetratus_net::Policy::Step => "step".into(),
        cetratus_net::Policy::Single(r) => format!("single-{}", format!("{r:?}").to_lowercase()),
    }
}

/// Text safe inside an ST comment: no `*)` closes it early, no `(*` opens another.
pub(crate) fn comment(text: &str) -> String {
    text.replace("*)", "* )")
        .replace("(*", "( *")
        .replace(['\n', '\r'], " ")
}

/// A program's name as a file name: letters, digits, `-`, `_` and `.` kept, others `_`.
fn file_stem(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || "-_.".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect();
    if s.is_empty() || s.starts_with('.') {
        format!("program{s}")
    } else {
        s
    }
}

impl fmt::Display for Dialect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}
