//! `cetratus bench export`: the semi-compiled paper's comparison made on one machine. For the
//! Vernadat cell and the Festo station, the export of `cetratus export --to st` compiled by
//! MATIEC and `cc -O2` (the kernel playing the net from its tables, the interpretation around
//! it) against Cetratus's interpreted scan of the same program; the bytes of the net's data in
//! the export against the paper's dense layout; and how long the export takes.
//!
//! Both sides hold every bool input TRUE (and every number at zero), so that the cell keeps
//! cycling, run the same scans from the same start with the scan's time advancing by the
//! program's period, and must end with the same outputs, or the figure is refused.

use std::hint::black_box;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use cetratus_matiec::{Case, IecType, Matiec};
use cetratus_program::{Program, Type, Value};
use cetratus_runtime::Container;
use serde::Serialize;

use crate::harness::BenchError;
use crate::st::{canonical, time_batch, time_scans};

/// The figures of one program.
#[derive(Debug, Serialize)]
pub struct ExportFigure {
    /// The program.
    pub name: String,
    /// Places and transitions of its net.
    pub places: usize,
    /// Transitions of its net.
    pub transitions: usize,
    /// Median ms of one export (`cetratus_export::to_st`).
    pub export_ms: f64,
    /// Bytes of the net's data in the export (sparse).
    pub sparse_bytes: usize,
    /// Bytes of Pre, Post and M0 as the paper's dense DINT matrices.
    pub dense_bytes: usize,
    /// Scans per run.
    pub scans: u64,
    /// Median ns of one interpreted scan on Cetratus.
    pub cetratus_ns: f64,
    /// Median ns of one scan of the export compiled by MATIEC and `cc -O2`.
    pub compiled_ns: Option<f64>,
}

/// The export of a program imported from an SFC chart back as that chart.
#[derive(Debug, Serialize)]
pub struct ChartFigure {
    /// The chart's POU.
    pub name: String,
    /// Its steps.
    pub steps: usize,
    /// Its transitions.
    pub transitions: usize,
    /// Median ms of `cetratus_export::to_plcopen`, which imports the chart it writes to check it.
    pub export_ms: f64,
    /// Median ms of importing the chart alone (`cetratus_sfc::import_str`): the baseline.
    pub import_ms: f64,
}

/// What `cetratus bench export` measured.
#[derive(Debug, Serialize)]
pub struct ExportFigures {
    /// Per program.
    pub programs: Vec<ExportFigure>,
    /// The Vernadat SFC cell written back as its chart.
    pub chart: ChartFigure,
    /// Why the compiled side was not measured, when it was not.
    pub matiec_skipped: Option<String>,
}

/// The programs measured, from the embedded examples.
fn programs() -> Result<Vec<Program>, BenchError> {
    let dir = crate::embedded::examples_dir();
    ["vernadat/vernadat.toml", "festo/festo.toml"]
        .iter()
        .map(|p| Program::load(&dir.join(p)).map_err(|e| BenchError::from(e.to_string())))
        .collect()
}

/// Measures each program; the compiled side when `matiec` is an install dir.
pub fn figures(matiec: Option<&Path>, quick: bool) -> Result<ExportFigures, BenchError> {
    let scans: u64 = if quick { 2_000 } else { 50_000 };
    let compiler = match matiec.map(|dir| Matiec::at(dir.to_path_buf())) {
        None => Err("no MATIEC install dir was given (`--matiec DIR`)".to_string()),
        Some(Err(e)) => Err(e.to_string()),
        Some(Ok(m)) => Ok(m),
    };
    let mut out = Vec::new();
    for program in programs()? {
        let export = cetratus_export::to_st(&program, cetratus_export::Dialect::Iec)
            .map_err(|e| e.to_string())?;
        let batch = Duration::from_millis(if quick { 50 } else { 300 });
        let export_ns = crate::measure::median_ns(
            || {
                black_box(cetratus_export::to_st(&program, cetratus_export::Dialect::Iec).is_ok());
            },
            batch,
            5,
        );
        let (cetratus_ns, ours) = interpreted(&program, &export, scans);
        let compiled_ns = match &compiler {
            Ok(m) => Some(compiled(m, &program, &export, scans, &ours)?),
            Err(_) => None,
        };
        out.push(ExportFigure {
            name: program.name().to_string(),
            places: program.net().num_places(),
            transitions: program.net().num_transitions(),
            export_ms: export_ns / 1e6,
            sparse_bytes: export.data.sparse_bytes,
            dense_bytes: export.data.dense_bytes,
            scans,
            cetratus_ns,
            compiled_ns,
        });
    }
    Ok(ExportFigures {
        programs: out,
        chart: chart(quick)?,
        matiec_skipped: compiler.err(),
    })
}

/// The Vernadat SFC cell's chart export, beside its import.
fn chart(quick: bool) -> Result<ChartFigure, BenchError> {
    let text = crate::embedded::VERNADAT_SFC;
    let import = || cetratus_sfc::import_str(text, "vernadat-sfc.xml", None, "Cell.pnml");
    let imported = import().map_err(|e| e.to_string())?;
    let program = &imported.program;
    let export = cetratus_export::to_plcopen(program).map_err(|e| e.to_string())?;
    if !export.chart {
        return Err(format!("the cell was not written as a chart: {:?}", export.notes).into());
    }
    let batch = Duration::from_millis(if quick { 50 } else { 300 });
    let export_ns = crate::measure::median_ns(
        || {
            black_box(cetratus_export::to_plcopen(program).is_ok());
        },
        batch,
        5,
    );
    let import_ns = crate::measure::median_ns(
        || {
            black_box(import().is_ok());
        },
        batch,
        5,
    );
    Ok(ChartFigure {
        name: program.name().to_string(),
        steps: program.net().num_places(),
        transitions: program.net().num_transitions(),
        export_ms: export_ns / 1e6,
        import_ms: import_ns / 1e6,
    })
}

/// The held value of an input: a bool TRUE, a number zero.
fn held(ty: Type) -> Value {
    match ty {
        Type::Bool => Value::Bool(true),
        other => other.zero(),
    }
}

/// The located variable's type of an I/O row.
fn iec_type(row: &cetratus_export::IoRow) -> IecType {
    [
        IecType::Bool,
        IecType::Int,
        IecType::Dint,
        IecType::Lint,
        IecType::Real,
        IecType::Lreal,
    ]
    .into_iter()
    .find(|t| t.name() == row.iec_type)
    .unwrap_or(IecType::Lint)
}

/// Median ns of one interpreted scan, and the outputs after the last scan in MATIEC's text.
fn interpreted(
    program: &Program,
    export: &cetratus_export::StExport,
    scans: u64,
) -> (f64, Vec<String>) {
    let program = Arc::new(program.clone());
    let inputs: Vec<Value> = program.inputs().iter().map(|s| held(s.ty)).collect();
    let period = program.scan_period().as_micros() as u64;
    let fresh = Container::new(program.clone(), 0);
    let (ns, last) = time_scans(&fresh, &inputs, period, scans);
    let outs = (export.io.iter().filter(|r| r.direction == "output"))
        .zip(last.outputs())
        .map(|(r, &v)| canonical(iec_type(r), v))
        .collect();
    (ns, outs)
}

/// Median ns of one scan of the compiled export, after checking it ends with `ours`.
fn compiled(
    m: &Matiec,
    program: &Program,
    export: &cetratus_export::StExport,
    scans: u64,
    ours: &[String],
) -> Result<f64, BenchError> {
    let rows = |dir: &'static str| {
        (export.io.iter().filter(move |r| r.direction == dir))
            .map(|r| (r.address.clone(), iec_type(r)))
    };
    let held_text: Vec<String> = (program.inputs().iter().zip(rows("input")))
        .map(|(s, (_, t))| canonical(t, held(s.ty)))
        .collect();
    let cases = [Case {
        program: export.program.clone(),
        inputs: rows("input").collect(),
        outputs: rows("output").collect(),
        scans: vec![held_text],
    }];
    let m = m.clone().with_globals(export.globals.clone());
    let batch = m.compile(&export.pous, &cases, program.scan_period())?;
    time_batch(&batch, &cases, scans, ours, program.name())
}
