//! A chart in Structured Text in the chart form: its `[st.conditions]` and `[st.bodies]` as
//! written, with its POU's declarations read from `[st] source` without what the importer added
//! there (the step flags' type, and the chart's own variables: the step flags and the nested
//! charts' `Q`).
//!
//! The importer writes a nested chart's condition `c` as `A AND (c)`, its box negated as
//! `NOT (c)`, and a network that needs statements as those statements; the chart form writes
//! the condition the file had, and refuses what it cannot write back as it was read (a negated
//! box in a nested chart, statements in a nested chart), which the in-process import then
//! catches in any case.

use std::collections::HashMap;
use std::fmt::Write as _;

use cetratus_net::xml_escape;
use cetratus_program::st::ChartTexts;

/// A chart in Structured Text, as the chart form writes it.
pub(crate) struct StChart {
    /// Each transition's condition, by its id.
    conditions: HashMap<String, String>,
    /// Each body's statements, by its name.
    bodies: HashMap<String, String>,
    /// The library's data types, as TC6 `dataType`s.
    pub(crate) data_types: String,
    /// The library's other POUs, as TC6 `pou`s.
    pub(crate) pous: String,
    /// The chart POU's `<pou …>` start tag.
    pub(crate) start: String,
    /// The chart POU's `<interface>`.
    pub(crate) interface: String,
    /// The library's configurations, as TC6 `configuration`s.
    pub(crate) configurations: String,
}

impl StChart {
    /// The chart of `texts`, or why the chart form cannot carry its library.
    pub(crate) fn new(texts: ChartTexts) -> Result<StChart, String> {
        let own = own_library(&texts.library, &texts.pou)?;
        let (own, configs) = match own.find("\nCONFIGURATION ") {
            Some(at) => own.split_at(at + 1),
            None => (own.as_str(), ""),
        };
        let written = crate::plcopen::library::write(own, "").map_err(|e| e.to_string())?;
        let (mut pous, mut chart) = (String::new(), None);
        for (name, xml) in written.pous {
            match name.eq_ignore_ascii_case(&texts.pou) {
                true => chart = Some(xml),
                false => pous.push_str(&xml),
            }
        }
        let chart = chart.ok_or_else(|| format!("its library has no POU `{}`", texts.pou))?;
        let part = |from: &str, to: &str| {
            let start = chart.find(from)?;
            let end = start + chart[start..].find(to)? + to.len();
            Some(format!("{}\n", chart[start..end].trim()))
        };
        let (Some(start), Some(interface)) =
            (part("<pou ", ">"), part("<interface>", "</interface>"))
        else {
            return Err(format!(
                "the POU `{}` is not written as expected",
                texts.pou
            ));
        };
        Ok(StChart {
            conditions: texts.conditions.into_iter().collect(),
            bodies: texts.bodies.into_iter().collect(),
            data_types: written.data_types,
            pous,
            start: format!("      {start}"),
            interface: format!("        {interface}"),
            configurations: configurations(configs)?,
        })
    }

    /// The condition of transition `id` as its chart writes it: `TRUE` where it has none, and
    /// in the nested chart of `action`, without the `action AND (…)` the importer added.
    pub(crate) fn condition(&self, id: &str, action: Option<&str>) -> Result<String, String> {
        let Some(text) = self.conditions.get(id) else {
            return Ok("TRUE".into());
        };
        let Some(action) = action else {
            return Ok(text.clone());
        };
        if text == action {
            return Ok("TRUE".into());
        }
        (text.strip_prefix(&format!("{action} AND ("))).and_then(|t| t.strip_suffix(')'))
            .map(str::to_string)
            .ok_or_else(|| format!("the condition of `{id}` is not `{action} AND (…)` as a nested chart's plain condition is"))
    }

    /// The statements of the body `name`.
    pub(crate) fn body(&self, name: &str) -> Result<&str, String> {
        (self.bodies.get(name).map(String::as_str))
            .ok_or_else(|| format!("no body `{name}` in `[st.bodies]`"))
    }
}

/// The library `text` of a chart's POU `pou` without what the importer added: the step flags'
/// type before it, and the chart's own variables, the last `VAR` block of the POU.
fn own_library(text: &str, pou: &str) -> Result<String, String> {
    let not_written =
        || format!("its `[st] source` is not the library the importer writes for the POU `{pou}`");
    let rest = (text.trim_start().strip_prefix(cetratus_sfc::STEP_TYPE))
        .and_then(|t| t.strip_prefix('\n'))
        .ok_or_else(not_written)?;
    let whole = format!("\n{rest}");
    let open = [
        format!("\nPROGRAM {pou}\n"),
        format!("\nFUNCTION_BLOCK {pou}\n"),
    ]
    .iter()
    .find_map(|o| whole.find(o.as_str()))
    .ok_or_else(not_written)?;
    let close = (["\nEND_PROGRAM\n", "\nEND_FUNCTION_BLOCK\n"].iter())
        .filter_map(|c| whole[open..].find(c))
        .min()
        .map(|at| open + at + 1)
        .ok_or_else(not_written)?;
    let step_type = cetratus_sfc::STEP_TYPE
        .split_whitespace()
        .nth(1)
        .unwrap_or_default();
    let block = (whole[open..close].rfind("\nVAR\n"))
        .map(|at| open + at + 1)
        .filter(|&at| whole[at..close].contains(&format!(": {step_type};")))
        .ok_or_else(not_written)?;
    Ok(format!("{}{}", &whole[1..block], &whole[close..]))
}

/// The `globalVars` of the `VAR_GLOBAL` blocks `blocks`, as TC6 writes them.
fn globals(blocks: &str) -> Result<String, String> {
    let written = crate::plcopen::library::write("", blocks).map_err(|e| e.to_string())?;
    Ok(written.globals)
}

/// The configurations of a chart's library, which the importer writes line by line from the
/// file's (`CONFIGURATION`, its `VAR_GLOBAL` blocks, each `RESOURCE … ON PLC` with its blocks,
/// the `TASK`s that run the chart and their `PROGRAM` instances), as TC6 `configuration`s:
/// each holds its resources, then its global variables, as the schema orders them.
fn configurations(text: &str) -> Result<String, String> {
    let (mut x, mut config_globals, mut resource) = (String::new(), String::new(), String::new());
    let mut block: Option<String> = None;
    let odd = |line: &str| {
        format!("its library's configuration has a line the importer does not write: `{line}`")
    };
    for line in text.lines() {
        let t = line.trim();
        if let Some(b) = block.as_mut() {
            b.push_str(line);
            b.push('\n');
            if t == "END_VAR" {
                let xml = globals(b)?;
                match resource.is_empty() {
                    true => config_globals.push_str(&xml),
                    false => resource.push_str(&xml),
                }
                block = None;
            }
        } else if t.starts_with("VAR_GLOBAL") {
            block = Some(format!("{line}\n"));
        } else if let Some(name) = t.strip_prefix("CONFIGURATION ") {
            let _ = writeln!(x, "      <configuration name=\"{}\">", xml_escape(name));
        } else if let Some(name) = t
            .strip_prefix("RESOURCE ")
            .and_then(|r| r.strip_suffix(" ON PLC"))
        {
            resource = format!("        <resource name=\"{}\">\n", xml_escape(name));
        } else if let Some(task) = t.strip_prefix("TASK ") {
            resource.push_str(&task_xml(task).ok_or_else(|| odd(t))?);
        } else if let Some(instance) = t.strip_prefix("PROGRAM ") {
            let (name, ty) = (instance.strip_suffix(';'))
                .and_then(|i| i.split_once(" WITH "))
                .and_then(|(name, rest)| Some((name, rest.split_once(" : ")?.1)))
                .ok_or_else(|| odd(t))?;
            let close = "          </task>\n";
            let open_task = resource.rfind(close).ok_or_else(|| odd(t))?;
            let pou = format!(
                "            <pouInstance name=\"{}\" typeName=\"{}\"/>\n",
                xml_escape(name),
                xml_escape(ty)
            );
            resource.insert_str(open_task, &pou);
        } else if t == "END_RESOURCE" {
            x.push_str(&resource);
            x.push_str("        </resource>\n");
            resource.clear();
        } else if t == "END_CONFIGURATION" {
            x.push_str(&config_globals);
            x.push_str("      </configuration>\n");
            config_globals.clear();
        } else if !t.is_empty() {
            return Err(odd(t));
        }
    }
    Ok(x)
}

/// A `TASK name(INTERVAL := …, PRIORITY := …);` line's task (after `TASK `), as TC6 writes it,
/// its program instances to come.
fn task_xml(task: &str) -> Option<String> {
    let (name, params) = task.strip_suffix(");")?.split_once('(')?;
    let mut attrs = String::new();
    for p in params.split(", ") {
        let (key, value) = p.split_once(" := ")?;
        let key = match key {
            "INTERVAL" => "interval",
            "PRIORITY" => "priority",
            _ => return None,
        };
        let _ = write!(attrs, " {key}=\"{}\"", xml_escape(value));
    }
    Some(format!(
        "          <task name=\"{}\"{attrs}>\n          </task>\n",
        xml_escape(name)
    ))
}
