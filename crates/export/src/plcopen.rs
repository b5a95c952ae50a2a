//! `--to plcopen`: the export as a PLCopen TC6 XML project (docs/export.md, *PLCopen XML*),
//! for Beremiz, the OpenPLC Editor and CODESYS: the array types as `dataTypes`, each POU of the
//! IEC text with its interface in XML and its statements as an ST body, and the configuration
//! with the net's constants as `globalVars` and one task at the scan period.
//!
//! The POUs are read back from the IEC text the exporter wrote itself, whose declarations have
//! one shape (`NAME [AT ADDR] : TYPE [:= VALUE];`, a comment after), so a line is enough to
//! know a variable; a program's own Structured Text, written by anyone, is read with the ST
//! parser instead (module `library`).

use std::fmt::Write as _;

use cetratus_net::xml_escape;
use cetratus_program::Program;

use crate::data::{ArrayType, Constant};
use crate::io::IoRow;

pub(crate) mod library;
use crate::{Dialect, ExportError, StExport};

/// The TC6 namespace the project is written in (version 2.01).
const TC6: &str = "http://www.plcopen.org/xml/tc6_0201";

/// The opening of every exported project, through its `contentHeader`: the project `name` at
/// `version`. Its `creationDateTime` is the epoch, so the same program gives the same bytes.
pub(crate) fn opening(name: &str, version: &str) -> String {
    format!(
        "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n<project xmlns=\"{TC6}\" xmlns:xhtml=\"http://www.w3.org/1999/xhtml\">\n  \
         <fileHeader companyName=\"Cetratus\" productName=\"cetratus export\" productVersion=\"{}\" creationDateTime=\"1970-01-01T00:00:00\"/>\n  \
         <contentHeader name=\"{}\" version=\"{}\">\n    <coordinateInfo>\n      <fbd><scaling x=\"1\" y=\"1\"/></fbd>\n      <ld><scaling x=\"1\" y=\"1\"/></ld>\n      <sfc><scaling x=\"1\" y=\"1\"/></sfc>\n    </coordinateInfo>\n  </contentHeader>\n",
        env!("CARGO_PKG_VERSION"),
        xml_escape(name),
        xml_escape(version),
    )
}

/// The opening of the configuration: one resource with one task at `program`'s scan period
/// that runs the POU `type_name`.
pub(crate) fn task(program: &Program, type_name: &str) -> String {
    let period = crate::expr::time_literal(program.scan_period().as_micros() as u64);
    format!(
        "      <configuration name=\"CETRATUS_CONFIG\">\n        <resource name=\"CETRATUS_RESOURCE\">\n          \
         <task name=\"CETRATUS_TASK\" interval=\"{period}\" priority=\"1\">\n            <pouInstance name=\"CETRATUS_MAIN\" typeName=\"{}\"/>\n          </task>\n        </resource>\n",
        xml_escape(type_name)
    )
}

/// `text` as a CDATA section, a `]]>` in it split across two.
pub(crate) fn cdata(text: &str) -> String {
    format!("<![CDATA[{}]]>", text.replace("]]>", "]]]]><![CDATA[>"))
}

/// Whether `ty` (upper case) is an elementary type, which TC6 writes as an element of its name.
pub(crate) fn elementary(ty: &str) -> bool {
    const ELEMENTARY: &[&str] = &[
        "BOOL", "SINT", "INT", "DINT", "LINT", "USINT", "UINT", "UDINT", "ULINT", "REAL", "LREAL",
        "TIME", "DATE", "DT", "TOD", "BYTE", "WORD", "DWORD", "LWORD", "WSTRING",
    ];
    ELEMENTARY.contains(&ty)
}

/// The export of `program` as a PLCopen TC6 XML project: a program imported from an SFC chart
/// as that chart (module `chart`), any other, or a chart the SFC POU cannot carry (said in the
/// export's notes), as the POUs of the IEC text.
pub fn to_plcopen(program: &Program) -> Result<StExport, ExportError> {
    let file_name = format!("{}.xml", program.file_stem());
    let mut notes = Vec::new();
    if program.is_sfc() {
        match crate::chart::project(program, &file_name) {
            Ok((text, io)) => return Ok(chart_export(program, file_name, text, io)),
            Err(why) => notes.push(format!(
                "the program was imported from an SFC chart, and is written as Structured Text POUs rather than as a chart: {why}"
            )),
        }
    }
    let (st, library) = crate::st_parts(program, Dialect::Iec)?;
    let own = (library.as_ref())
        .map(|(l, g)| library::write(l, g))
        .transpose()?;
    let data = crate::data::NetData::new(program.net(), program.policy());
    let mut x = String::with_capacity(st.text.len() * 3);
    x.push_str(&opening(program.name(), program.version()));
    x.push_str("  <types>\n    <dataTypes>\n");
    for t in data.types() {
        data_type(&mut x, &t);
    }
    if let Some(own) = &own {
        x.push_str(&own.data_types);
    }
    x.push_str("    </dataTypes>\n    <pous>\n");
    for (_, pou) in own.iter().flat_map(|o| &o.pous) {
        x.push_str(pou);
    }
    let exporters = match &library {
        Some((l, _)) => st.pous.replacen(l.as_str(), "", 1),
        None => st.pous.clone(),
    };
    for pou in pous(&exporters) {
        pou_xml(&mut x, &pou)?;
    }
    x.push_str("    </pous>\n  </types>\n  <instances>\n    <configurations>\n");
    let own_globals = own.as_ref().map_or("", |o| o.globals.as_str());
    configuration(&mut x, &st.program, program, &data.constants(), own_globals);
    x.push_str("    </configurations>\n  </instances>\n</project>\n");
    Ok(StExport {
        file_name,
        text: x,
        notes,
        ..st
    })
}

/// The export of a chart: the project, and the I/O map of the addresses the chart declares.
fn chart_export(program: &Program, file_name: String, text: String, io: Vec<IoRow>) -> StExport {
    StExport {
        file_name,
        text,
        pous: String::new(),
        globals: String::new(),
        program: program.name().to_string(),
        io_csv: crate::io::csv(&io),
        io,
        renames: Vec::new(),
        data: crate::data::NetData::new(program.net(), program.policy()).size(),
        chart: true,
        notes: Vec::new(),
    }
}

fn data_type(x: &mut String, t: &ArrayType) {
    let _ = writeln!(
        x,
        "      <dataType name=\"{}\">\n        <baseType><array><dimension lower=\"1\" upper=\"{}\"/><baseType>{}</baseType></array></baseType>\n      </dataType>",
        t.name,
        t.len,
        type_xml(t.element)
    );
}

/// An IEC type as TC6 writes it: elementary types as elements of their name, others derived.
fn type_xml(ty: &str) -> String {
    if elementary(ty) {
        format!("<{ty}/>")
    } else {
        format!("<derived name=\"{}\"/>", xml_escape(ty))
    }
}

/// A POU of the IEC text: its kind, name, variable blocks and statements.
struct Pou {
    kind: &'static str,
    name: String,
    blocks: Vec<(String, Vec<Decl>)>,
    body: String,
}

/// One declaration line.
struct Decl {
    name: String,
    address: Option<String>,
    ty: String,
    init: Option<String>,
}

/// The POUs of the text, in order.
fn pous(text: &str) -> Vec<Pou> {
    let mut out = Vec::new();
    let mut current: Option<Pou> = None;
    let (mut declaring, mut comment, mut block) = (false, false, None::<String>);
    for line in text.lines() {
        let t = line.trim();
        let head = (t
            .strip_prefix("FUNCTION_BLOCK ")
            .map(|n| ("functionBlock", n)))
        .or_else(|| t.strip_prefix("PROGRAM ").map(|n| ("program", n)));
        if let (None, Some((kind, name))) = (&current, head) {
            current = Some(Pou {
                kind,
                name: name.to_string(),
                blocks: Vec::new(),
                body: String::new(),
            });
            declaring = true;
            continue;
        }
        let Some(pou) = current.as_mut() else {
            continue;
        };
        if t == "END_FUNCTION_BLOCK" || t == "END_PROGRAM" {
            out.extend(current.take());
            continue;
        }
        if !declaring {
            pou.body.push_str(line);
            pou.body.push('\n');
        } else if comment || (t.starts_with("(*") && block.is_none()) {
            comment = !t.ends_with("*)") || (comment && !t.contains("*)"));
        } else if t == "END_VAR" {
            block = None;
        } else if t.starts_with("VAR") {
            block = Some(t.to_string());
            pou.blocks.push((t.to_string(), Vec::new()));
        } else if block.is_some() {
            if let (Some(d), Some((_, decls))) = (decl(t), pou.blocks.last_mut()) {
                decls.push(d);
            }
        } else {
            declaring = false;
            pou.body.push_str(line);
            pou.body.push('\n');
        }
    }
    out
}

/// `NAME [AT ADDR] : TYPE [:= VALUE];  (* … *)`.
fn decl(t: &str) -> Option<Decl> {
    let t = t.split("(*").next()?.trim().trim_end_matches(';');
    let (left, right) = t.split_once(" : ")?;
    let (name, address) = match left.split_once(" AT ") {
        Some((n, a)) => (n.trim(), Some(a.trim().to_string())),
        None => (left.trim(), None),
    };
    let (ty, init) = match right.split_once(":=") {
        Some((ty, v)) => (ty.trim(), Some(v.trim().to_string())),
        None => (right.trim(), None),
    };
    Some(Decl {
        name: name.to_string(),
        address,
        ty: ty.to_string(),
        init,
    })
}

fn pou_xml(x: &mut String, pou: &Pou) -> Result<(), ExportError> {
    let _ = write!(
        x,
        "      <pou name=\"{}\" pouType=\"{}\">\n        <interface>\n",
        pou.name, pou.kind
    );
    for (header, decls) in &pou.blocks {
        let (element, attrs) = match header.as_str() {
            "VAR_INPUT" => ("inputVars", ""),
            "VAR_OUTPUT" => ("outputVars", ""),
            "VAR_IN_OUT" => ("inOutVars", ""),
            "VAR" => ("localVars", ""),
            "VAR RETAIN" => ("localVars", " retain=\"true\""),
            "VAR_EXTERNAL" => ("externalVars", ""),
            "VAR_EXTERNAL CONSTANT" => ("externalVars", " constant=\"true\""),
            other => {
                return Err(ExportError::Unsupported {
                    what: format!("a `{other}` block in PLCopen XML"),
                    hint: "this is a fault of the exporter; report it with the program",
                })
            }
        };
        let _ = writeln!(x, "          <{element}{attrs}>");
        for d in decls {
            variable(x, d, "            ");
        }
        let _ = writeln!(x, "          </{element}>");
    }
    let _ = write!(
        x,
        "        </interface>\n        <body>\n          <ST>\n            <xhtml:p>{}</xhtml:p>\n          </ST>\n        </body>\n      </pou>\n",
        cdata(&pou.body)
    );
    Ok(())
}

fn variable(x: &mut String, d: &Decl, pad: &str) {
    let address = d
        .address
        .as_ref()
        .map(|a| format!(" address=\"{a}\""))
        .unwrap_or_default();
    let _ = writeln!(x, "{pad}<variable name=\"{}\"{address}>", d.name);
    let _ = writeln!(x, "{pad}  <type>{}</type>", type_xml(&d.ty));
    if let Some(v) = &d.init {
        let _ = writeln!(x, "{pad}  <initialValue>{}</initialValue>", value_xml(v));
    }
    let _ = writeln!(x, "{pad}</variable>");
}

/// A value: `[a, b, …]` as an `arrayValue`, anything else as a `simpleValue`.
fn value_xml(v: &str) -> String {
    match v.strip_prefix('[').and_then(|v| v.strip_suffix(']')) {
        Some(list) => {
            let items: String = (list.split(',').map(str::trim))
                .map(|i| format!("<value><simpleValue value=\"{}\"/></value>", xml_escape(i)))
                .collect();
            format!("<arrayValue>{items}</arrayValue>")
        }
        None => format!("<simpleValue value=\"{}\"/>", xml_escape(v)),
    }
}

/// The configuration: one resource with one task at the scan period running the PROGRAM, and the
/// net's constants as its global variables, then the program's own (`own`, as TC6 XML).
fn configuration(x: &mut String, name: &str, program: &Program, constants: &[Constant], own: &str) {
    x.push_str(&task(program, name));
    x.push_str("        <globalVars constant=\"true\">\n");
    for c in constants {
        let d = Decl {
            name: c.name.clone(),
            address: None,
            ty: c.ty.unwrap_or("DINT").to_string(),
            init: Some(c.value.split_whitespace().collect::<Vec<_>>().join(" ")),
        };
        variable(x, &d, "          ");
    }
    x.push_str("        </globalVars>\n");
    x.push_str(own);
    x.push_str("      </configuration>\n");
}
