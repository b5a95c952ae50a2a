//! Siemens TIA Portal SCL, rewritten from the dialect-neutral text (docs/export.md,
//! *Dialects*): SCL has no PROGRAM, no CONFIGURATION, no array type names and no VAR_EXTERNAL;
//! it quotes the names of blocks and global tags and marks a block's own variables with `#`.
//!
//! * the net's constants become the data block `"CETRATUS_NET"`, read as `"CETRATUS_NET".NAME`;
//! * each FUNCTION_BLOCK gets its attributes and `BEGIN`; the PROGRAM becomes a
//!   FUNCTION_BLOCK whose signals are the PLC tags of the I/O map (`"PE"`), with its instance
//!   data block and the `"Main"` organization block (OB1) that calls it;
//! * array type names are spelled out, `TON` is `TON_TIME`, block types are quoted, and every
//!   name a block declares is written `#NAME` in its statements.
//!
//! The rewrite reads the text line by line and each line token by token, outside comments.

use std::collections::HashSet;
use std::fmt::Write as _;

use crate::data::ArrayType;
use crate::dialect::spelled;
use crate::ExportError;

/// The data block of the net's constants.
const NET_DB: &str = "CETRATUS_NET";

/// Where the rewrite is.
#[derive(PartialEq)]
enum Part {
    /// Between blocks.
    Outside,
    /// A top-level VAR_GLOBAL block: `constant` for the net's data.
    Globals { constant: bool },
    /// The declarations of a block.
    Declarations,
    /// Inside a VAR block of a block; `dropped` for one SCL does not have.
    Block { dropped: bool },
    /// The statements of a block.
    Body,
}

/// The state of the rewrite.
struct Rewrite<'t> {
    types: &'t [ArrayType],
    out: String,
    part: Part,
    /// The net's constants, as `NAME : TYPE := value;` lines.
    constants: Vec<String>,
    /// Global names: the net's constants and the signals' tags.
    constant_names: HashSet<String>,
    tags: HashSet<String>,
    /// Names the current block declares.
    locals: HashSet<String>,
    /// Block names (quoted wherever they appear as types).
    blocks: HashSet<String>,
    /// The PROGRAM's name, which becomes a FUNCTION_BLOCK called from OB1.
    program: Option<String>,
    /// Inside a comment that spans lines.
    comment: std::cell::Cell<bool>,
}

/// `text` (the export in the neutral form) as TIA SCL.
pub(crate) fn rewrite(text: &str, types: &[ArrayType]) -> Result<String, ExportError> {
    let mut r = Rewrite {
        types,
        out: String::with_capacity(text.len() + text.len() / 4),
        part: Part::Outside,
        constants: Vec::new(),
        constant_names: HashSet::new(),
        tags: HashSet::new(),
        locals: HashSet::new(),
        blocks: text
            .lines()
            .filter_map(|l| {
                let l = l
                    .strip_prefix("FUNCTION_BLOCK ")
                    .or_else(|| l.strip_prefix("PROGRAM "))?;
                Some(l.trim().to_string())
            })
            .collect(),
        program: None,
        comment: std::cell::Cell::new(false),
    };
    for line in text.lines() {
        r.line(line);
    }
    let program = r.program.clone().ok_or_else(|| ExportError::Unsupported {
        what: "the text has no PROGRAM to call from OB1".into(),
        hint: "this is a fault of the exporter; report it with the program",
    })?;
    Ok(r.finish(&program))
}

impl Rewrite<'_> {
    fn line(&mut self, line: &str) {
        let t = line.trim();
        match &self.part {
            Part::Outside => self.outside(line, t),
            Part::Globals { constant } => {
                let constant = *constant;
                if let Some(open) = self.constants.last_mut().filter(|c| !c.contains(';')) {
                    // A value written over several lines.
                    open.push(' ');
                    open.push_str(t);
                } else if t == "END_VAR" {
                    self.part = Part::Outside;
                } else if let Some((name, rest)) = declared(t) {
                    if constant {
                        self.constant_names.insert(name.to_string());
                        self.constants.push(format!("{name} :{}", self.spell(rest)));
                    } else {
                        self.tags.insert(name.to_string());
                    }
                }
            }
            Part::Declarations => self.declarations(line, t),
            Part::Block { dropped } => {
                let dropped = *dropped;
                if t == "END_VAR" {
                    self.part = Part::Declarations;
                    if !dropped {
                        self.out.push_str(line);
                        self.out.push('\n');
                    }
                } else if let Some((name, _)) = declared(t) {
                    if dropped {
                        // A VAR_EXTERNAL: the global's own name, a constant or a tag.
                    } else if t.contains(" AT %") {
                        self.tags.insert(name.to_string());
                    } else {
                        self.locals.insert(name.to_string());
                        let decl = self.spell(line);
                        self.out.push_str(&decl);
                        self.out.push('\n');
                    }
                } else if !dropped {
                    self.out.push_str(line);
                    self.out.push('\n');
                }
            }
            Part::Body => self.body(line, t),
        }
    }

    fn outside(&mut self, line: &str, t: &str) {
        if t == "VAR_GLOBAL CONSTANT" || t == "VAR_GLOBAL" {
            self.part = Part::Globals {
                constant: t.ends_with("CONSTANT"),
            };
            return;
        }
        let header = (t.strip_prefix("FUNCTION_BLOCK ").map(|n| (n, false)))
            .or_else(|| t.strip_prefix("PROGRAM ").map(|n| (n, true)));
        if let Some((name, program)) = header {
            if program {
                self.program = Some(name.to_string());
            }
            self.locals.clear();
            let _ = write!(
                self.out,
                "FUNCTION_BLOCK \"{name}\"\n{{ S7_Optimized_Access := 'TRUE' }}\nVERSION : 0.1\n"
            );
            self.part = Part::Declarations;
            return;
        }
        self.out.push_str(line);
        self.out.push('\n');
    }

    fn declarations(&mut self, line: &str, t: &str) {
        if t.starts_with("VAR") {
            let dropped = t.starts_with("VAR_EXTERNAL");
            if !dropped {
                self.out.push_str(line);
                self.out.push('\n');
            }
            self.part = Part::Block { dropped };
        } else if self.comment.get() || t.starts_with("(*") || t.is_empty() {
            let mut comment = self.comment.get();
            map_words(line, &mut comment, |_, _| None);
            self.comment.set(comment);
            self.out.push_str(line);
            self.out.push('\n');
        } else {
            self.out.push_str("BEGIN\n");
            self.part = Part::Body;
            self.body(line, t);
        }
    }

    fn body(&mut self, line: &str, t: &str) {
        if t == "END_FUNCTION_BLOCK" || t == "END_PROGRAM" {
            self.out.push_str("END_FUNCTION_BLOCK\n");
            self.part = Part::Outside;
            return;
        }
        let s = self.names(line);
        self.out.push_str(&s);
        self.out.push('\n');
    }

    /// A declaration with its array types spelled out, TON as TON_TIME and block types quoted.
    fn spell(&self, decl: &str) -> String {
        let mut comment = self.comment.get();
        let s = map_words(decl, &mut comment, |w, _| {
            if w.starts_with("CETRATUS_") && !self.blocks.contains(w) {
                Some(spelled(self.types, w))
            } else if w == "TON" {
                Some("TON_TIME".to_string())
            } else if self.blocks.contains(w) {
                Some(format!("\"{w}\""))
            } else {
                None
            }
        });
        self.comment.set(comment);
        s
    }

    /// A statement with its block's names `#`-marked, tags quoted and constants in their DB.
    fn names(&self, line: &str) -> String {
        let mut comment = self.comment.get();
        let s = map_words(line, &mut comment, |w, after_dot| {
            if after_dot {
                None
            } else if self.locals.contains(w) {
                Some(format!("#{w}"))
            } else if self.tags.contains(w) {
                Some(format!("\"{w}\""))
            } else if self.constant_names.contains(w) {
                Some(format!("\"{NET_DB}\".{w}"))
            } else {
                None
            }
        });
        self.comment.set(comment);
        s
    }

    /// The data blocks and OB1 after the blocks.
    fn finish(mut self, program: &str) -> String {
        let _ = write!(
            self.out,
            "\n(* The net's constants. *)\nDATA_BLOCK \"{NET_DB}\"\n{{ S7_Optimized_Access := 'TRUE' }}\nVERSION : 0.1\nNON_RETAIN\n   STRUCT\n"
        );
        for c in &self.constants {
            let _ = writeln!(self.out, "      {c}");
        }
        let _ = write!(
            self.out,
            "   END_STRUCT;\nBEGIN\nEND_DATA_BLOCK\n\n(* The program's instance, called every cycle of OB1 (or of a cyclic interrupt OB at the scan period). *)\nDATA_BLOCK \"{program}_DB\" \"{program}\"\nBEGIN\nEND_DATA_BLOCK\n\nORGANIZATION_BLOCK \"Main\"\n{{ S7_Optimized_Access := 'TRUE' }}\nVERSION : 0.1\nBEGIN\n  \"{program}_DB\"();\nEND_ORGANIZATION_BLOCK\n"
        );
        self.out
    }
}

/// `NAME : TYPE …` of a declaration line: the name and what follows the colon.
fn declared(t: &str) -> Option<(&str, &str)> {
    let (name, rest) = t.split_once(':')?;
    let name = name.split_whitespace().next()?;
    (name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') && !rest.starts_with('='))
        .then_some((name, rest))
}

/// `line` with each identifier outside comments and typed literals replaced where `f` says;
/// `f` is told whether the word follows a `.` (a member, never a block's own name). `comment`
/// carries a comment that spans lines from one line to the next.
fn map_words(line: &str, comment: &mut bool, f: impl Fn(&str, bool) -> Option<String>) -> String {
    let mut out = String::with_capacity(line.len() + 16);
    let b = line.as_bytes();
    let word_byte = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
    let mut i = 0;
    while i < b.len() {
        if *comment || line[i..].starts_with("(*") {
            let from = if *comment { i } else { i + 2 };
            let end = line[from..].find("*)").map(|e| from + e + 2);
            *comment = end.is_none();
            let end = end.unwrap_or(b.len());
            out.push_str(&line[i..end]);
            i = end;
        } else if b[i].is_ascii_alphabetic() || b[i] == b'_' {
            let start = i;
            while i < b.len() && word_byte(b[i]) {
                i += 1;
            }
            let word = &line[start..i];
            if b.get(i) == Some(&b'#') {
                // A typed literal (`T#3s`, `LINT#0`): copied whole.
                i += 1;
                while i < b.len() && (word_byte(b[i]) || b[i] == b'.') {
                    i += 1;
                }
                out.push_str(&line[start..i]);
                continue;
            }
            let after_dot = start > 0 && b[start - 1] == b'.';
            // `(NAME :=` or `, NAME :=`: a formal parameter, named as its block declares it.
            let before = line[..start].trim_end().chars().last();
            let formal =
                matches!(before, Some('(' | ',')) && line[i..].trim_start().starts_with(":=");
            match formal {
                true => out.push_str(word),
                false => out.push_str(&f(word, after_dot).unwrap_or_else(|| word.to_string())),
            }
        } else {
            let c = line[i..].chars().next().expect("inside the line");
            out.push(c);
            i += c.len_utf8();
        }
    }
    out
}
