//! The dialects of an export, and what differs between them (docs/export.md, *Dialects*).
//!
//! The text is written once, in IEC 61131-3; a dialect changes only what its compiler needs
//! changed: where the net's constants live, whether array types are named, whether POUs see
//! globals through VAR_EXTERNAL, how signals reach their addresses, how a task is declared, and
//! whether `&&` and `||` keep their short circuit. Siemens TIA's SCL differs most and is
//! rewritten from the IEC text by [`crate::tia`].

use std::fmt::Write as _;

use crate::data::{ArrayType, Constant, DataSize};
use crate::ExportError;

/// The ST dialect of an export.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Dialect {
    /// IEC 61131-3 as MATIEC (OpenPLC, Beremiz) compiles it.
    #[default]
    Iec,
    /// CODESYS V3 and Beckhoff TwinCAT 3.
    Codesys,
    /// Siemens TIA Portal SCL (S7-1500).
    Tia,
    /// OMRON Sysmac Studio ST (NJ/NX).
    Omron,
}

impl Dialect {
    /// Every dialect, by name.
    pub const ALL: &'static [(&'static str, Dialect)] = &[
        ("iec", Dialect::Iec),
        ("codesys", Dialect::Codesys),
        ("tia", Dialect::Tia),
        ("omron", Dialect::Omron),
    ];

    /// The dialect's name.
    pub fn name(self) -> &'static str {
        Dialect::ALL
            .iter()
            .find(|(_, d)| *d == self)
            .map_or("iec", |(n, _)| n)
    }

    /// The file's extension: `.scl` for TIA, `.st` otherwise.
    pub fn extension(self) -> &'static str {
        match self {
            Dialect::Tia => "scl",
            _ => "st",
        }
    }

    /// IEC declares globals only in a CONFIGURATION, and a POU sees them through VAR_EXTERNAL;
    /// the vendors have global variable lists that every POU sees.
    pub(crate) fn externals(self) -> bool {
        self == Dialect::Iec
    }

    /// The words for `&&` and `||`: CODESYS has the short-circuit `AND_THEN` and `OR_ELSE`,
    /// which keep the guard language's meaning (`n <> 0 AND_THEN 10 / n > 1`).
    pub(crate) fn and_or(self) -> (&'static str, &'static str) {
        match self {
            Dialect::Codesys => ("AND_THEN", "OR_ELSE"),
            _ => ("AND", "OR"),
        }
    }

    /// Whether signals are declared `AT` their address in the PROGRAM (IEC, CODESYS); OMRON
    /// maps global variables to its I/O ports in Sysmac Studio, TIA uses PLC tags.
    pub(crate) fn located(self) -> bool {
        matches!(self, Dialect::Iec | Dialect::Codesys)
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

impl std::fmt::Display for Dialect {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The array types: one TYPE block (IEC), one per type (the vendors' editors keep one data type
/// per object), or none (TIA, whose data types are structures only: arrays are spelled out).
pub(crate) fn types(d: Dialect, types: &[ArrayType]) -> String {
    let mut s = String::new();
    match d {
        Dialect::Iec => {
            s.push_str("TYPE\n");
            for t in types {
                let _ = writeln!(s, "  {} : {};  (* {} *)", t.name, t.spelled(), t.about);
            }
            s.push_str("END_TYPE\n");
        }
        Dialect::Codesys | Dialect::Omron => {
            for t in types {
                let _ = writeln!(
                    s,
                    "TYPE {} : {}; END_TYPE  (* {} *)",
                    t.name,
                    t.spelled(),
                    t.about
                );
            }
        }
        Dialect::Tia => {}
    }
    s
}

/// The net's constants as a `VAR_GLOBAL CONSTANT` block, indented by `pad`; the vendors' get
/// their array types spelled out (CODESYS and its parsers read an array initialiser only
/// after an array type).
pub(crate) fn globals(
    d: Dialect,
    constants: &[Constant],
    types: &[ArrayType],
    size: DataSize,
    pad: &str,
) -> String {
    let mut s = format!(
        "{pad}VAR_GLOBAL CONSTANT\n{pad}  (* The net as data: {} bytes sparse; Pre, Post and M0 dense would take {}. *)\n",
        size.sparse_bytes, size.dense_bytes
    );
    for c in constants {
        let ty = match c.ty {
            None => "DINT".to_string(),
            Some(name) if d == Dialect::Iec => name.to_string(),
            Some(name) => spelled(types, name),
        };
        let note = if c.note.is_empty() {
            String::new()
        } else {
            format!("  (* {} *)", c.note)
        };
        let _ = writeln!(s, "{pad}  {} : {ty} := {};{note}", c.name, c.value);
    }
    let _ = writeln!(s, "{pad}END_VAR");
    s
}

/// A named array type spelled out.
pub(crate) fn spelled(types: &[ArrayType], name: &str) -> String {
    types
        .iter()
        .find(|t| t.name == name)
        .map_or_else(|| name.to_string(), ArrayType::spelled)
}

/// The kernel in the dialect: without its VAR_EXTERNAL block where POUs see globals anyway.
pub(crate) fn kernel(d: Dialect) -> String {
    let text = crate::kernel::text();
    if d.externals() {
        return text;
    }
    let start = text
        .find("VAR_EXTERNAL CONSTANT\n")
        .expect("the kernel reads constants");
    let end = start + text[start..].find("END_VAR\n").expect("a closed block") + "END_VAR\n".len();
    format!("{}{}", &text[..start], &text[end..])
}
