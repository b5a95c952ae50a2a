//! Recorded inputs played back (`cetratus run --replay TRACE.csv`): the inputs of each scan come
//! from a CSV in the format `--trace` writes, for regression tests against recorded plant data.
//!
//! * The header is `scan,time_ms,<signals…>`. The program's inputs are read by name, and every
//!   one of them must have a column; other columns (outputs, signals of other programs) are
//!   ignored.
//! * Rows are keyed by `scan` (from 0, increasing). A value holds until the next row that has
//!   one for its column: `--trace` writes a row only when something changed, and an empty cell
//!   holds the value too. Before the first row that sets an input, it is its type's zero.
//! * Values: a `bool` is `0`/`1` or `true`/`false`; an `int` a decimal integer; a `real` a
//!   decimal number as Rust and C print them (`1.5`, `-2e-3`, `inf`, `NaN`). A cell may be quoted
//!   as CSV quotes (`"…"`, a quote inside written twice), which a STRING value would need.
//!
//! The whole file is read and checked when the run starts, away from the scan thread, so a bad
//! file is refused before the first scan with its line and column; the scan only copies values.
//! The file is at most [`MAX_BYTES`] bytes.

use std::path::Path;

use cetratus_program::{Signal, Type, Value};
use cetratus_runtime::{Dispatcher, Provider};

use crate::plant::PlantDriver;

/// The largest replay file read.
pub const MAX_BYTES: u64 = 64 * 1024 * 1024;

/// Why a replay file was refused: where, and what to do.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// The file could not be read.
    #[error("cannot read the replay file {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// The file's content is wrong at a line.
    #[error("{path}:{line}: {message}")]
    Content {
        /// The file.
        path: String,
        /// The line, from 1.
        line: usize,
        /// What is wrong and what to do.
        message: String,
    },
}

/// A recorded input sequence, played back one row per scan.
#[derive(Debug)]
pub struct Replay {
    /// `(scan, value per program input: set, or held)`, in scan order.
    rows: Vec<(u64, Vec<Option<Value>>)>,
    next_row: usize,
    scan: u64,
    current: Vec<Value>,
}

impl Replay {
    /// Reads and checks `path` against the program's inputs.
    pub fn open(path: &Path, inputs: &[Signal]) -> Result<Replay, ReplayError> {
        let label = path.display().to_string();
        let io = |source| ReplayError::Io {
            path: label.clone(),
            source,
        };
        let len = std::fs::metadata(path).map_err(io)?.len();
        if len > MAX_BYTES {
            return Err(ReplayError::Content {
                path: label,
                line: 1,
                message: format!("the file has {len} bytes, more than the {MAX_BYTES} a replay reads; split the recording"),
            });
        }
        let text = std::fs::read_to_string(path).map_err(io)?;
        Replay::parse(&text, &label, inputs)
    }

    /// Reads CSV text (`label` names it in messages) against the program's inputs.
    pub fn parse(text: &str, label: &str, inputs: &[Signal]) -> Result<Replay, ReplayError> {
        let err = |line: usize, message: String| ReplayError::Content {
            path: label.to_string(),
            line,
            message,
        };
        let mut lines = text
            .lines()
            .enumerate()
            .filter(|(_, l)| !l.trim().is_empty());
        let Some((_, header)) = lines.next() else {
            return Err(err(
                1,
                "the file is empty; it needs a header `scan,time_ms,<signals…>`".into(),
            ));
        };
        let names = cells(header).map_err(|m| err(1, m))?;
        if names.first().map(String::as_str) != Some("scan") {
            return Err(err(1, "the first column must be `scan` (the header is `scan,time_ms,<signals…>`, as --trace writes it)".into()));
        }
        let mut columns = Vec::with_capacity(inputs.len());
        for s in inputs {
            match names.iter().position(|n| *n == s.name) {
                Some(c) => columns.push(c),
                None => {
                    return Err(err(
                        1,
                        format!(
                        "no column for the input `{}`; the replay gives every input of the program",
                        s.name
                    ),
                    ))
                }
            }
        }
        let mut rows: Vec<(u64, Vec<Option<Value>>)> = Vec::new();
        for (i, line) in lines {
            let n = i + 1;
            let cells = cells(line).map_err(|m| err(n, m))?;
            let scan: u64 = cells
                .first()
                .and_then(|c| c.trim().parse().ok())
                .ok_or_else(|| {
                    err(
                        n,
                        format!(
                            "`{}` is not a scan number",
                            cells.first().map_or("", String::as_str)
                        ),
                    )
                })?;
            if rows.last().is_some_and(|(last, _)| *last >= scan) {
                return Err(err(n, format!("scan {scan} does not come after the row before it; rows are in increasing scan order")));
            }
            let mut values = Vec::with_capacity(inputs.len());
            for (s, &c) in inputs.iter().zip(&columns) {
                let cell = cells.get(c).map_or("", |c| c.trim());
                values.push(if cell.is_empty() {
                    None
                } else {
                    Some(
                        value(s.ty, cell)
                            .map_err(|m| err(n, format!("column `{}`: {m}", s.name)))?,
                    )
                });
            }
            rows.push((scan, values));
        }
        Ok(Replay {
            rows,
            next_row: 0,
            scan: 0,
            current: inputs.iter().map(|s| s.ty.zero()).collect(),
        })
    }

    /// The number of rows read.
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// Whether the file had no row.
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }
}

/// A cell's value as a signal of type `ty`.
fn value(ty: Type, cell: &str) -> Result<Value, String> {
    match ty {
        Type::Bool => match cell {
            "0" | "false" | "FALSE" => Ok(Value::Bool(false)),
            "1" | "true" | "TRUE" => Ok(Value::Bool(true)),
            other => Err(format!("`{other}` is not a bool; write 0 or 1")),
        },
        Type::Int => cell
            .parse()
            .map(Value::Int)
            .map_err(|_| format!("`{cell}` is not an integer")),
        Type::Real => cell
            .parse()
            .map(Value::Real)
            .map_err(|_| format!("`{cell}` is not a number")),
    }
}

/// The cells of one CSV line: separated by commas, a quoted cell's quotes removed and `""` read
/// as one quote.
fn cells(line: &str) -> Result<Vec<String>, String> {
    let mut out = Vec::new();
    let mut cell = String::new();
    let mut chars = line.chars().peekable();
    let mut quoted = false;
    while let Some(c) = chars.next() {
        match (quoted, c) {
            (false, ',') => out.push(std::mem::take(&mut cell)),
            (false, '"') if cell.trim().is_empty() => {
                cell.clear();
                quoted = true;
            }
            (true, '"') if chars.peek() == Some(&'"') => {
                chars.next();
                cell.push('"');
            }
            (true, '"') => quoted = false,
            (_, c) => cell.push(c),
        }
    }
    if quoted {
        return Err("a quoted cell is not closed".into());
    }
    out.push(cell);
    Ok(out)
}

impl Provider for Replay {
    fn read_inputs(&mut self, _now_us: u64, inputs: &mut [Value]) {
        while let Some((scan, values)) = self.rows.get(self.next_row) {
            if *scan > self.scan {
                break;
            }
            for (c, v) in self.current.iter_mut().zip(values) {
                if let Some(v) = v {
                    *c = *v;
                }
            }
            self.next_row += 1;
        }
        for (i, c) in inputs.iter_mut().zip(&self.current) {
            *i = *c;
        }
        self.scan += 1;
    }
}

impl Dispatcher for Replay {
    fn write_outputs(&mut self, _now_us: u64, _outputs: &[Value]) {}
}

impl PlantDriver for Replay {}

#[cfg(test)]
mod tests {
    use super::*;

    fn signal(name: &str, ty: Type) -> Signal {
        Signal {
            name: name.into(),
            ty,
            address: None,
            description: String::new(),
            safe: None,
            initial: ty.zero(),
            retain: false,
        }
    }

    #[test]
    fn a_value_holds_until_the_next_row_that_sets_it() {
        let inputs = [signal("a", Type::Bool), signal("n", Type::Int)];
        let csv = "scan,time_ms,a,n,out\n0,0.000,0,5,1\n3,30.000,1,,0\n";
        let mut r = Replay::parse(csv, "t.csv", &inputs).expect("parses");
        let mut got = vec![Value::Bool(false), Value::Int(0)];
        let mut seen = Vec::new();
        for _ in 0..5 {
            r.read_inputs(0, &mut got);
            seen.push(got.clone());
        }
        assert_eq!(seen[2], vec![Value::Bool(false), Value::Int(5)]);
        assert_eq!(seen[3], vec![Value::Bool(true), Value::Int(5)]);
    }

    #[test]
    fn a_bad_cell_is_refused_with_its_line_and_column() {
        let inputs = [signal("a", Type::Bool)];
        let e = Replay::parse("scan,time_ms,a\n0,0,maybe\n", "t.csv", &inputs)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("t.csv:2") && e.contains("`a`") && e.contains("maybe"),
            "{e}"
        );
        let e = Replay::parse("scan,time_ms,b\n", "t.csv", &inputs)
            .unwrap_err()
            .to_string();
        assert!(e.contains("no column for the input `a`"), "{e}");
        let e = Replay::parse("scan,time_ms,a\n2,0,1\n1,0,0\n", "t.csv", &inputs)
            .unwrap_err()
            .to_string();
        assert!(e.contains("increasing"), "{e}");
    }

    #[test]
    fn quoted_cells_read_as_csv_quotes_them() {
        assert_eq!(
            cells(r#"1,"a,b","say ""hi""""#).expect("cells"),
            vec!["1", "a,b", "say \"hi\""]
        );
    }
}
