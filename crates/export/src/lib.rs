//! Export of a Cetratus program to the PLCs plants already own (docs/export.md): the
//! semi-compiled Petri-net algorithm in IEC 61131-3 Structured Text.
//!
//! [`to_st`] writes one file in four parts: the kernel ([`kernel`]: a FUNCTION_BLOCK that does
//! not depend on the net), the net as data ([`data`]: sparse Pre, Post and inhibitor tables,
//! M0, capacities, visiting order and priorities, as constants), the interpretation compiled to
//! ST ([`logic`]: guards, place timers, the IEC action control, action bodies), and a PROGRAM
//! that wires the signals to located addresses ([`io`]) with a CONFIGURATION whose TASK runs at
//! the program's scan period. The same program always gives the same bytes.

use std::fmt::Write as _;

use cetratus_program::Program;

mod chart;
mod data;
mod dialect;
mod expr;
mod io;
mod kernel;
mod logic;
mod names;
mod plcopen;
mod tia;

pub use data::DataSize;
pub use dialect::Dialect;
pub use io::IoRow;
pub use names::Rename;
pub use plcopen::to_plcopen;

/// Why a program cannot be exported.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum ExportError {
    /// The dialect asked for is none the exporter writes.
    #[error("unknown dialect `{0}`; the dialects are: {names}", names = Dialect::ALL.iter().map(|(n, _)| *n).collect::<Vec<_>>().join(", "))]
    Dialect(String),
    /// A part of the program the export cannot write.
    #[error("{what}; {hint}")]
    Unsupported {
        /// What it is.
        what: String,
        /// What to do.
        hint: &'static str,
    },
    /// A signal's address that is no located address of its type.
    #[error("{signal}'s address `{address}`: {why}")]
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
    /// The file's name: the program's name (made a valid file name) and `.st` (`.scl` for
    /// TIA).
    pub file_name: String,
    /// The whole file.
    pub text: String,
    /// Everything but the CONFIGURATION: the types, the kernel, the interpretation and the
    /// PROGRAM (for a harness that configures the program itself).
    pub pous: String,
    /// The net's constants, as a `VAR_GLOBAL CONSTANT` block of the CONFIGURATION, then the
    /// `VAR_GLOBAL` blocks of the program's own ST CONFIGURATION.
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
    /// Whether the export is the program's SFC chart (`--to plcopen` of a chart), rather than
    /// the kernel and the net's data.
    pub chart: bool,
    /// What the export could not do as asked, and what it did instead.
    pub notes: Vec<String>,
}

/// Writes `program` as IEC 61131-3 Structured Text in `dialect`.
pub fn to_st(program: &Program, dialect: Dialect) -> Result<StExport, ExportError> {
    Ok(st_parts(program, dialect)?.0)
}

/// The program's own Structured Text as the export writes it: its `[st]` body's library,
/// rewritten (part of [`StExport::pous`]), and its CONFIGURATION's `VAR_GLOBAL` blocks.
type OwnSt = Option<(String, String)>;

/// [`to_st`], and the program's own Structured Text.
fn st_parts(program: &Program, dialect: Dialect) -> Result<(StExport, OwnSt), ExportError> {
    let d = dialect;
    let data = data::NetData::new(program.net(), program.policy());
    let mut global = names::Names::new(data::GLOBALS);
    for fixed in [
        "CETRATUS_CONFIG",
        "CETRATUS_RESOURCE",
        "CETRATUS_TASK",
        "CETRATUS_MAIN",
    ] {
        global.claim(None, fixed);
    }
    for pou in logic::library_names(program) {
        global.claim(None, &pou);
    }
    let name = global.claim(None, program.name());
    let fb = global.claim(None, &format!("{name}_LOGIC"));
    let logic = logic::Logic::new(program, global, d)?;
    let io = io::map(program.inputs(), program.outputs(), |s| logic.signal(s))?;
    let (size, types, constants) = (data.size(), data.types(), data.constants());
    let period_us = program.scan_period().as_micros() as u64;
    let mut pous = header(program, &logic, &io, size, d);
    pous.push_str("\n(* Part 2: the net as data. *)\n");
    pous.push_str(&dialect::types(d, &types));
    if !d.externals() {
        pous.push_str(&dialect::globals(d, &constants, &types, size, ""));
        pous.push_str(logic.st_globals());
    }
    pous.push_str("\n(* Part 1: the kernel. *)\n");
    pous.push_str(&dialect::kernel(d));
    if let Some(library) = logic.st_library() {
        pous.push_str(match program.st().is_some_and(|s| s.is_chart()) {
            true => "\n(* Part 3: the program's Structured Text, its chart's POU given a body that runs each part. *)\n",
            false => "\n(* Part 3: the program's Structured Text, its PROGRAM made a FUNCTION_BLOCK. *)\n",
        });
        pous.push_str(library);
    }
    pous.push_str("\n(* Part 3: the interpretation. *)\n");
    pous.push_str(&logic.pou(&fb)?);
    pous.push_str("\n(* Part 4: the program at its addresses, and its task. *)\n");
    pous.push_str(&logic::program_pou(&name, &fb, &io, program, d));
    let mut globals = dialect::globals(d, &constants, &types, size, "  ");
    for line in logic.st_globals().lines() {
        let _ = writeln!(globals, "  {line}");
    }
    let tail = match d {
        Dialect::Iec => logic::configuration(&globals, &name, period_us),
        Dialect::Tia => String::new(),
        _ => format!(
            "(* The task: run PROGRAM {name} every {} in a cyclic task of that interval. *)\n",
            expr::time_literal(period_us)
        ),
    };
    let mut text = format!("{pous}\n{tail}");
    if d == Dialect::Tia {
        text = tia::rewrite(&text, &types)?;
    }
    let library = (logic.st_library()).map(|l| (l.to_string(), logic.st_globals().to_string()));
    let export = StExport {
        file_name: format!("{}.{}", program.file_stem(), d.extension()),
        text,
        pous,
        globals,
        program: name,
        io_csv: io::csv(&io),
        io,
        renames: logic.names().renames().to_vec(),
        data: size,
        chart: false,
        notes: Vec::new(),
    };
    Ok((export, library))
}

/// The file's opening comment: what it is, from which program, and the renames.
fn header(
    program: &Program,
    logic: &logic::Logic,
    io: &[IoRow],
    size: DataSize,
    d: Dialect,
) -> String {
    let mut s = format!(
        "(* {} {}, exported by Cetratus as IEC 61131-3 Structured Text, dialect {d}.\n   Program hash {}.\n   Policy {}, scan period {} us; {} places, {} transitions.\n   The net's data: {} bytes sparse ({} dense).\n",
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
