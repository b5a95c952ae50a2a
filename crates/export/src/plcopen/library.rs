//! A program's own Structured Text (an `[st]` body, as the export rewrote it: its PROGRAM a
//! FUNCTION_BLOCK, its located variables inputs and outputs) in a TC6 project: each `TYPE` a
//! `dataType`, each POU a `pou` with its interface in XML and its statements as an ST body.
//!
//! The declarations are read with the ST parser (`cetratus_st`), not by lines, since anyone
//! wrote them: types become TC6 type elements, and an initial value, an enumeration's value or
//! a bound keeps its text from the source, which every TC6 reader pastes back as ST. A body is
//! the source text between the POU's last `END_VAR` and its end, comments included.

use std::fmt::Write as _;

use cetratus_net::xml_escape;
use cetratus_st::ast::{self, Library, PouKind, Section, TypeDeclKind, TypeRef};

use crate::ExportError;

/// The library's data types and POUs as TC6 XML, in that order.
pub(crate) struct Written {
    pub(crate) data_types: String,
    /// Each POU's name and `<pou>` element, in the library's order.
    pub(crate) pous: Vec<(String, String)>,
    /// The `globalVars` of the library's CONFIGURATION, for the project's configuration.
    pub(crate) globals: String,
}

fn refuse(what: String) -> ExportError {
    ExportError::Unsupported {
        what,
        hint: "export the program --to st, which carries its ST as written",
    }
}

/// The TC6 XML of the library `text` and of the `VAR_GLOBAL` blocks `globals` of its
/// CONFIGURATION.
pub(crate) fn write(text: &str, globals: &str) -> Result<Written, ExportError> {
    let whole = match globals.is_empty() {
        true => text.to_string(),
        false => format!("{text}\nCONFIGURATION CETRATUS_GLOBALS\n{globals}END_CONFIGURATION\n"),
    };
    let lib: Library = cetratus_st::parse::parse_library(&whole).map_err(|d| {
        refuse(format!(
            "the program's ST does not parse again: {}",
            d.message
        ))
    })?;
    let src = Source(&whole);
    let mut data_types = String::new();
    for t in &lib.types {
        src.data_type(&mut data_types, t)?;
    }
    let mut pous = Vec::with_capacity(lib.pous.len());
    for (i, p) in lib.pous.iter().enumerate() {
        let end = lib.pous.get(i + 1).map_or(text.len(), |n| n.pos as usize);
        let mut xml = String::new();
        src.pou(&mut xml, p, end)?;
        pous.push((p.name.text.clone(), xml));
    }
    let mut global_xml = String::new();
    for block in lib.configs.iter().flat_map(|c| &c.globals) {
        let attrs = match (block.constant, block.retain) {
            (true, _) => " constant=\"true\"",
            (false, true) => " retain=\"true\"",
            (false, false) => "",
        };
        let _ = writeln!(global_xml, "        <globalVars{attrs}>");
        for d in &block.decls {
            src.variables(&mut global_xml, d, "          ")?;
        }
        global_xml.push_str("        </globalVars>\n");
    }
    Ok(Written {
        data_types,
        pous,
        globals: global_xml,
    })
}

/// The library's text, from which values and bodies are taken as written.
struct Source<'t>(&'t str);

impl Source<'_> {
    fn data_type(&self, x: &mut String, t: &ast::TypeDecl) -> Result<(), ExportError> {
        let _ = writeln!(
            x,
            "      <dataType name=\"{}\">\n        <baseType>",
            xml_escape(&t.name.text)
        );
        let mut init = None;
        match &t.kind {
            TypeDeclKind::Struct(members) => {
                x.push_str("          <struct>\n");
                for m in members {
                    self.variables(x, m, "            ")?;
                }
                x.push_str("          </struct>\n");
            }
            TypeDeclKind::Enum { values, init: i } => {
                x.push_str("          <enum>\n            <values>\n");
                for (name, value) in values {
                    let value = match value {
                        Some(v) => format!(" value=\"{}\"", xml_escape(&self.constant(v)?)),
                        None => String::new(),
                    };
                    let _ = writeln!(
                        x,
                        "              <value name=\"{}\"{value}/>",
                        xml_escape(&name.text)
                    );
                }
                x.push_str("            </values>\n          </enum>\n");
                init = i.as_ref().map(|i| i.text.clone());
            }
            TypeDeclKind::Alias { ty, range, init: i } => {
                let ty_xml = self.type_xml(ty)?;
                match range {
                    Some((lo, hi)) => {
                        let _ = writeln!(
                            x,
                            "          <subrangeSigned><range lower=\"{}\" upper=\"{}\"/><baseType>{ty_xml}</baseType></subrangeSigned>",
                            xml_escape(&self.constant(lo)?),
                            xml_escape(&self.constant(hi)?)
                        );
                    }
                    None => {
                        let _ = writeln!(x, "          {ty_xml}");
                    }
                }
                if i.is_some() {
                    init = self.initial(ty.pos());
                }
            }
        }
        x.push_str("        </baseType>\n");
        if let Some(v) = init {
            let _ = writeln!(
                x,
                "        <initialValue><simpleValue value=\"{}\"/></initialValue>",
                xml_escape(&v)
            );
        }
        x.push_str("      </dataType>\n");
        Ok(())
    }

    fn pou(&self, x: &mut String, p: &ast::Pou, end: usize) -> Result<(), ExportError> {
        let kind = match &p.kind {
            PouKind::Program => "program",
            PouKind::FunctionBlock => "functionBlock",
            PouKind::Function(_) => "function",
        };
        let _ = writeln!(
            x,
            "      <pou name=\"{}\" pouType=\"{kind}\">\n        <interface>",
            xml_escape(&p.name.text)
        );
        if let PouKind::Function(ret) = &p.kind {
            let _ = writeln!(
                x,
                "          <returnType>{}</returnType>",
                self.type_xml(ret)?
            );
        }
        for block in &p.vars {
            let element = match block.section {
                Section::Var => "localVars",
                Section::Input => "inputVars",
                Section::Output => "outputVars",
                Section::InOut => "inOutVars",
                Section::Temp => "tempVars",
                Section::External => "externalVars",
                Section::Global => "globalVars",
            };
            let mut attrs = String::new();
            for (on, attr) in [(block.constant, "constant"), (block.retain, "retain")] {
                if on {
                    let _ = write!(attrs, " {attr}=\"true\"");
                }
            }
            let _ = writeln!(x, "          <{element}{attrs}>");
            for d in &block.decls {
                self.variables(x, d, "            ")?;
            }
            let _ = writeln!(x, "          </{element}>");
        }
        let body = self.body(p, end)?;
        let _ = writeln!(
            x,
            "        </interface>\n        <body>\n          <ST>\n            <xhtml:p>{}</xhtml:p>\n          </ST>\n        </body>\n      </pou>",
            super::cdata(&body)
        );
        Ok(())
    }

    /// The `<variable>`s of one declaration (`a, b AT %IX0.0 : T := v;`).
    fn variables(&self, x: &mut String, d: &ast::VarDecl, pad: &str) -> Result<(), ExportError> {
        let ty = self.type_xml(&d.ty)?;
        let init = match d.init {
            Some(_) => self.initial(d.ty.pos()),
            None => None,
        };
        for name in &d.names {
            let address = (d.at.as_ref())
                .map(|a| format!(" address=\"{}\"", xml_escape(&a.text)))
                .unwrap_or_default();
            let _ = writeln!(
                x,
                "{pad}<variable name=\"{}\"{address}>\n{pad}  <type>{ty}</type>",
                xml_escape(&name.text)
            );
            if let Some(v) = &init {
                let _ = writeln!(
                    x,
                    "{pad}  <initialValue><simpleValue value=\"{}\"/></initialValue>",
                    xml_escape(v)
                );
            }
            let _ = writeln!(x, "{pad}</variable>");
        }
        Ok(())
    }

    /// A type as TC6 writes it: an elementary type as its element, a declared one (or a
    /// function block) as `derived`, `string` with its length, `array` with its dimensions.
    fn type_xml(&self, t: &TypeRef) -> Result<String, ExportError> {
        Ok(match t {
            TypeRef::Named(id) => {
                let up = id.key();
                let up = match up.as_str() {
                    "TIME_OF_DAY" => "TOD".to_string(),
                    "DATE_AND_TIME" => "DT".to_string(),
                    _ => up,
                };
                match super::elementary(&up) {
                    true => format!("<{up}/>"),
                    false => format!("<derived name=\"{}\"/>", xml_escape(&id.text)),
                }
            }
            TypeRef::String { len: None, .. } => "<string/>".into(),
            TypeRef::String { len: Some(n), .. } => {
                format!("<string length=\"{}\"/>", xml_escape(&self.constant(n)?))
            }
            TypeRef::Array { dims, elem, .. } => {
                let mut s = String::from("<array>");
                for (lo, hi) in dims {
                    let _ = write!(
                        s,
                        "<dimension lower=\"{}\" upper=\"{}\"/>",
                        xml_escape(&self.constant(lo)?),
                        xml_escape(&self.constant(hi)?)
                    );
                }
                let _ = write!(s, "<baseType>{}</baseType></array>", self.type_xml(elem)?);
                s
            }
        })
    }

    /// A constant as written: a literal, a name, or either negated.
    fn constant(&self, e: &ast::Expr) -> Result<String, ExportError> {
        use ast::ExprKind as K;
        match &e.kind {
            K::Lit(_) | K::Name(_) => Ok(self.token_at(e.pos as usize)),
            K::Unary(ast::UnOp::Neg, inner) => Ok(format!("-{}", self.constant(inner)?)),
            _ => Err(refuse(format!(
                "the bound or value at `{}` is an expression; PLCopen XML holds a literal there",
                self.token_at(e.pos as usize)
            ))),
        }
    }

    /// The literal or name that starts at `at`, as written (`16#FF`, `INT#-5`, `2.5E-3`,
    /// `T#1.5s`, `TOD#12:30:00`, `'text'`, `Color#Red`).
    fn token_at(&self, at: usize) -> String {
        let rest = &self.0[at.min(self.0.len())..];
        if let Some(q) = rest.chars().next().filter(|c| *c == '\'' || *c == '"') {
            let end = rest[1..].find(q).map_or(rest.len(), |i| i + 2);
            return rest[..end].to_string();
        }
        let b = rest.as_bytes();
        let digit_at = |i: usize| b.get(i).is_some_and(u8::is_ascii_digit);
        let number = digit_at(0);
        let mut end = 0;
        while end < b.len() {
            let (c, typed) = (b[end], rest[..end].contains('#'));
            let signed = end > 0 && matches!(b[end - 1], b'#' | b'e' | b'E') && (typed || number);
            let ok = c.is_ascii_alphanumeric()
                || c == b'_'
                || c == b'#'
                || (c == b'.' && digit_at(end + 1))
                || (matches!(c, b'+' | b'-') && signed)
                || (matches!(c, b'-' | b':') && typed && digit_at(end + 1));
            if !ok {
                break;
            }
            end += 1;
        }
        rest[..end].to_string()
    }

    /// The initial value's text of the declaration whose type starts at `ty`: what follows its
    /// `:=`, up to the `;` that ends it, outside brackets, parentheses, strings and comments.
    fn initial(&self, ty: u32) -> Option<String> {
        let text = &self.0[ty as usize..];
        let assign = scan(text, true, |rest| rest.starts_with(":="))?;
        let value = &text[assign + 2..];
        let end = scan(value, true, |rest| rest.starts_with(';')).unwrap_or(value.len());
        Some(value[..end].trim().to_string())
    }

    /// The POU's statements as written: after its last `END_VAR` (or its heading line), up to
    /// its `END_…` keyword before `end`.
    fn body(&self, p: &ast::Pou, end: usize) -> Result<String, ExportError> {
        let closing = match p.kind {
            PouKind::Program => "END_PROGRAM",
            PouKind::FunctionBlock => "END_FUNCTION_BLOCK",
            PouKind::Function(_) => "END_FUNCTION",
        };
        let region = &self.0[p.pos as usize..end];
        let upper = region.to_ascii_uppercase();
        let stop = upper.rfind(closing).ok_or_else(|| {
            refuse(format!(
                "the POU `{}` has no {closing} where the parser ended it",
                p.name.text
            ))
        })?;
        let start = match p.vars.last() {
            Some(b) => {
                let from = b.pos as usize - p.pos as usize;
                scan(&upper[from..stop], false, |rest| {
                    rest.starts_with("END_VAR")
                })
                .map(|i| from + i + 7)
            }
            None => region.find('\n'),
        }
        .unwrap_or(0)
        .min(stop);
        Ok(region[start..stop].trim_matches('\n').to_string() + "\n")
    }
}

/// The offset of the first place in `text`, outside brackets, parentheses, strings and
/// comments, where `at` holds; `None` when there is none, or, in one declaration (`decl`),
/// when a `;` at depth 0 ends it first (unless that is what is sought).
fn scan(text: &str, decl: bool, at: impl Fn(&str) -> bool) -> Option<usize> {
    let b = text.as_bytes();
    let (mut depth, mut i) = (0i32, 0usize);
    while i < b.len() {
        let rest = &text[i..];
        if depth == 0 && at(rest) {
            return Some(i);
        }
        match b[i] {
            b'(' if rest.starts_with("(*") => {
                i += rest.find("*)").map_or(rest.len(), |e| e + 2);
                continue;
            }
            b'/' if rest.starts_with("//") => {
                i += rest.find('\n').unwrap_or(rest.len());
                continue;
            }
            q @ (b'\'' | b'"') => {
                i += 1 + rest[1..].find(q as char).map_or(rest.len() - 1, |e| e + 1);
                continue;
            }
            b'(' | b'[' => depth += 1,
            b')' | b']' => depth -= 1,
            b';' if depth == 0 && decl => return None,
            _ => {}
        }
        i += 1;
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A library with what a controls engineer writes: every kind of type, a FUNCTION, an FB
    /// with initial values that hold `;`, `:=`, brackets and comments, and a PROGRAM.
    const LIBRARY: &str = "TYPE
  Mode : (Idle, Run := 5, Stop) := Run;
  Level : INT (0..100) := 50;
  Pair : STRUCT
    a : INT := -3;
    b : ARRAY [1..3] OF REAL := [1.5, 2(0.0)];
  END_STRUCT;
END_TYPE

FUNCTION Twice : DINT
VAR_INPUT x : DINT; END_VAR
Twice := x * 2;
END_FUNCTION

FUNCTION_BLOCK Counter
VAR_INPUT
  up : BOOL;
END_VAR
VAR_OUTPUT
  n : DINT := 16#10;
END_VAR
VAR
  p : Pair := (a := 1, b := [3.0, 4.0, 5.0]);
  label : STRING[20] := 'a;b:=c';  (* END_VAR in a comment *)
  table : ARRAY [-1..1] OF TIME := [T#1.5s, 2(T#0s)];
END_VAR
(* counts *)
IF up THEN n := Twice(n); END_IF;
END_FUNCTION_BLOCK

PROGRAM Main
VAR c : Counter; m : Mode; END_VAR
c(up := TRUE);
END_PROGRAM
";

    #[test]
    fn every_declaration_keeps_its_type_and_its_value_as_written() {
        let w = write(LIBRARY, "").expect("it writes");
        let d = &w.data_types;
        assert!(d.contains("<value name=\"Run\" value=\"5\"/>"), "{d}");
        assert!(d.contains("<simpleValue value=\"Run\"/>"), "{d}");
        assert!(
            d.contains("<subrangeSigned><range lower=\"0\" upper=\"100\"/><baseType><INT/>"),
            "{d}"
        );
        assert!(d.contains("<simpleValue value=\"-3\"/>"), "{d}");
        assert!(d.contains("<array><dimension lower=\"1\" upper=\"3\"/><baseType><REAL/>"));
        assert!(d.contains("<simpleValue value=\"[1.5, 2(0.0)]\"/>"), "{d}");
        let p: String = w.pous.iter().map(|(_, xml)| xml.as_str()).collect();
        assert!(
            p.contains("<pou name=\"Twice\" pouType=\"function\">"),
            "{p}"
        );
        assert!(p.contains("<returnType><DINT/></returnType>"), "{p}");
        assert!(p.contains("<simpleValue value=\"16#10\"/>"), "{p}");
        assert!(p.contains("<simpleValue value=\"(a := 1, b := [3.0, 4.0, 5.0])\"/>"));
        assert!(p.contains("<string length=\"20\"/>"), "{p}");
        assert!(
            p.contains("<simpleValue value=\"&apos;a;b:=c&apos;\"/>"),
            "{p}"
        );
        assert!(p.contains("<dimension lower=\"-1\" upper=\"1\"/>"), "{p}");
        assert!(
            p.contains("<simpleValue value=\"[T#1.5s, 2(T#0s)]\"/>"),
            "{p}"
        );
        assert!(p.contains("<derived name=\"Counter\"/>"), "{p}");
        assert!(
            p.contains("<![CDATA[(* counts *)\nIF up THEN n := Twice(n); END_IF;\n]]>"),
            "{p}"
        );
        assert!(p.contains("<![CDATA[c(up := TRUE);\n]]>"), "{p}");
    }

    #[test]
    fn a_bound_that_is_an_expression_is_refused_by_what_it_reads() {
        let text =
            "FUNCTION_BLOCK F\nVAR a : ARRAY [1..N + 1] OF INT; END_VAR\nEND_FUNCTION_BLOCK\n";
        let e = write(text, "").err().expect("refused").to_string();
        assert!(e.contains("is an expression"), "{e}");
    }
}
