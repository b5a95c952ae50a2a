//! IEC 61131-3 names for a program's signals and for what the export declares beside them.
//!
//! The rule (docs/export.md, *Names*): a name keeps its spelling when it is a valid IEC
//! identifier that no keyword, standard type, standard function or function block, or other
//! name of the same scope already takes (IEC names are case-insensitive). Otherwise every
//! character outside `A–Z a–z 0–9 _` becomes `_`, runs of `_` become one, a trailing `_` goes, a
//! leading digit gets `N_` before it, and then `_2`, `_3`, … is appended until the name is free.
//! Every change is kept, to be listed in the I/O map and the file's header.

use std::collections::HashSet;

/// Words no name of an export may take: IEC 61131-3 keywords and elementary types, the
/// standard functions and function blocks, and the keywords of the dialects' vendors.
const RESERVED: &[&str] = &[
    "ACTION",
    "AND",
    "AND_THEN",
    "ANY",
    "ARRAY",
    "AT",
    "BOOL",
    "BY",
    "BYTE",
    "CASE",
    "CONFIGURATION",
    "CONSTANT",
    "CONTINUE",
    "DATA_BLOCK",
    "DATE",
    "DATE_AND_TIME",
    "DINT",
    "DO",
    "DT",
    "DWORD",
    "ELSE",
    "ELSIF",
    "EN",
    "END_ACTION",
    "END_CASE",
    "END_CONFIGURATION",
    "END_DATA_BLOCK",
    "END_FOR",
    "END_FUNCTION",
    "END_FUNCTION_BLOCK",
    "END_IF",
    "END_METHOD",
    "END_PROGRAM",
    "END_REPEAT",
    "END_RESOURCE",
    "END_STEP",
    "END_STRUCT",
    "END_TRANSITION",
    "END_TYPE",
    "END_VAR",
    "END_WHILE",
    "ENO",
    "EXIT",
    "EXTENDS",
    "FALSE",
    "FOR",
    "FROM",
    "FUNCTION",
    "FUNCTION_BLOCK",
    "F_EDGE",
    "GOTO",
    "IF",
    "IMPLEMENTS",
    "INITIAL_STEP",
    "INT",
    "INTERFACE",
    "INTERVAL",
    "JMP",
    "LINT",
    "LREAL",
    "LWORD",
    "METHOD",
    "MOD",
    "NON_RETAIN",
    "NOT",
    "OF",
    "ON",
    "OR",
    "OR_ELSE",
    "ORGANIZATION_BLOCK",
    "POINTER",
    "PRIORITY",
    "PROGRAM",
    "PROPERTY",
    "READ_ONLY",
    "READ_WRITE",
    "REAL",
    "REF",
    "REF_TO",
    "REGION",
    "REPEAT",
    "RESOURCE",
    "RETAIN",
    "RETURN",
    "R_EDGE",
    "SINGLE",
    "SINT",
    "STEP",
    "STRING",
    "STRUCT",
    "SUPER",
    "TASK",
    "THEN",
    "THIS",
    "TIME",
    "TIME_OF_DAY",
    "TO",
    "TOD",
    "TRANSITION",
    "TRUE",
    "TYPE",
    "UDINT",
    "UINT",
    "ULINT",
    "UNTIL",
    "USINT",
    "VAR",
    "VAR_ACCESS",
    "VAR_CONFIG",
    "VAR_EXTERNAL",
    "VAR_GLOBAL",
    "VAR_INPUT",
    "VAR_IN_OUT",
    "VAR_OUTPUT",
    "VAR_STAT",
    "VAR_TEMP",
    "WCHAR",
    "WHILE",
    "WITH",
    "WORD",
    "WSTRING",
    "XOR", // standard function blocks
    "CTD",
    "CTU",
    "CTUD",
    "F_TRIG",
    "RS",
    "RTC",
    "R_TRIG",
    "SEMA",
    "SR",
    "TOF",
    "TON",
    "TP",
    // standard functions
    "ABS",
    "ACOS",
    "ADD",
    "ASIN",
    "ATAN",
    "CONCAT",
    "COS",
    "DELETE",
    "DIV",
    "EQ",
    "EXP",
    "EXPT",
    "FIND",
    "GE",
    "GT",
    "INSERT",
    "LE",
    "LEFT",
    "LEN",
    "LIMIT",
    "LN",
    "LOG",
    "LT",
    "MAX",
    "MID",
    "MIN",
    "MOVE",
    "MUL",
    "MUX",
    "NE",
    "REPLACE",
    "RIGHT",
    "ROL",
    "ROR",
    "SEL",
    "SHL",
    "SHR",
    "SIN",
    "SQRT",
    "SUB",
    "TAN",
    "TRUNC",
];

/// A name the export had to change.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Rename {
    /// What was named: `input`, `output`, `variable`.
    pub kind: &'static str,
    /// The program's name.
    pub from: String,
    /// The name in the export.
    pub to: String,
}

/// The names taken in one scope, case-insensitively, and the renames made in it.
#[derive(Clone, Debug, Default)]
pub(crate) struct Names {
    taken: HashSet<String>,
    renames: Vec<Rename>,
}

impl Names {
    /// A scope in which the reserved words and `fixed` (the export's own global names) are
    /// taken.
    pub(crate) fn new(fixed: &[&str]) -> Self {
        let taken = RESERVED
            .iter()
            .chain(fixed)
            .map(|w| w.to_string())
            .collect();
        Names {
            taken,
            renames: Vec::new(),
        }
    }

    /// A free name as close to `wanted` as the rule allows; the program's own names (`kind`
    /// given) have their change recorded.
    pub(crate) fn claim(&mut self, kind: Option<&'static str>, wanted: &str) -> String {
        let base = legal(wanted);
        let mut name = base.clone();
        let mut n = 2;
        while self.taken.contains(&name.to_ascii_uppercase()) {
            name = format!("{base}_{n}");
            n += 1;
        }
        self.taken.insert(name.to_ascii_uppercase());
        if let (Some(kind), true) = (kind, name != wanted) {
            self.renames.push(Rename {
                kind,
                from: wanted.to_string(),
                to: name.clone(),
            });
        }
        name
    }

    /// The renames made so far, in the order made.
    pub(crate) fn renames(&self) -> &[Rename] {
        &self.renames
    }
}

/// `wanted` as a valid IEC identifier: `[A-Za-z_][A-Za-z0-9_]*`, no `__`, no trailing `_`.
pub(crate) fn legal(wanted: &str) -> String {
    let mut out = String::with_capacity(wanted.len() + 2);
    for c in wanted.chars() {
        let c = if c.is_ascii_alphanumeric() { c } else { '_' };
        if c == '_' && out.ends_with('_') {
            continue;
        }
        out.push(c);
    }
    while out.ends_with('_') {
        out.pop();
    }
    if out.starts_with(|c: char| c.is_ascii_digit()) {
        out.insert_str(0, "N_");
    }
    if out.is_empty() || out == "_" {
        out = "X".to_string();
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn invalid_and_reserved_names_are_renamed_by_the_rule_and_listed() {
        let mut n = Names::new(&["NET_M0"]);
        assert_eq!(n.claim(Some("input"), "PE"), "PE");
        assert_eq!(n.claim(Some("input"), "pe"), "pe_2");
        assert_eq!(n.claim(Some("output"), "TON"), "TON_2");
        assert_eq!(n.claim(Some("output"), "end_if"), "end_if_2");
        assert_eq!(n.claim(Some("variable"), "a__b_"), "a_b");
        assert_eq!(n.claim(Some("variable"), "net_m0"), "net_m0_2");
        assert_eq!(n.claim(None, "9lives"), "N_9lives");
        let from: Vec<&str> = n.renames().iter().map(|r| r.from.as_str()).collect();
        assert_eq!(from, ["pe", "TON", "end_if", "a__b_", "net_m0"]);
    }
}
