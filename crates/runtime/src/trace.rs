//! Traces of a run: the I/O image whenever it changes, written as CSV, JSON or an SVG timing
//! diagram in the style of the paper's Fig. 7.

use std::fmt::Write as _;

use cetratus_net::xml_escape;
use cetratus_program::Value;
use serde::Serialize;

/// One row: the images at a scan in which something changed.
#[derive(Clone, Debug, Serialize)]
pub struct TraceRow {
    /// Scan index, from 0.
    pub scan: u64,
    /// Program time at the scan's start, in microseconds.
    pub time_us: u64,
    /// Inputs, in declared order.
    #[serde(serialize_with = "values")]
    pub inputs: Vec<Value>,
    /// Outputs, in declared order.
    #[serde(serialize_with = "values")]
    pub outputs: Vec<Value>,
}

/// The changes of the I/O image over a run.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Trace {
    /// Input names.
    pub input_names: Vec<String>,
    /// Output names.
    pub output_names: Vec<String>,
    /// One row per scan in which an input or output changed (and the first scan).
    pub rows: Vec<TraceRow>,
    /// Program time of the last scan recorded or seen.
    pub end_us: u64,
}

impl Trace {
    /// An empty trace for these signals.
    pub fn new(input_names: Vec<String>, output_names: Vec<String>) -> Self {
        Trace {
            input_names,
            output_names,
            rows: Vec::new(),
            end_us: 0,
        }
    }

    /// Records the images of a scan if they differ from the last row.
    pub fn observe(&mut self, scan: u64, time_us: u64, inputs: &[Value], outputs: &[Value]) {
        self.end_us = time_us;
        if let Some(last) = self.rows.last() {
            if last.inputs == inputs && last.outputs == outputs {
                return;
            }
        }
        self.rows.push(TraceRow {
            scan,
            time_us,
            inputs: inputs.to_vec(),
            outputs: outputs.to_vec(),
        });
    }

    /// CSV: `scan,time_ms,<inputs>,<outputs>` with booleans as 0/1.
    pub fn to_csv(&self) -> String {
        let mut s = String::from("scan,time_ms");
        for n in self.input_names.iter().chain(&self.output_names) {
            let _ = write!(s, ",{n}");
        }
        s.push('\n');
        for r in &self.rows {
            let _ = write!(s, "{},{:.3}", r.scan, r.time_us as f64 / 1000.0);
            for v in r.inputs.iter().chain(&r.outputs) {
                let _ = write!(s, ",{}", value_text(*v));
            }
            s.push('\n');
        }
        s
    }

    /// The trace as a timing diagram: one lane per input, then per output.
    pub fn diagram(&self, title: &str) -> TimingDiagram {
        let mut d = TimingDiagram::new(title, self.end_us);
        let lanes = |pick: &dyn Fn(&TraceRow) -> &Vec<Value>, names: &[String], group: &str| {
            names
                .iter()
                .enumerate()
                .map(|(i, n)| Lane {
                    label: n.clone(),
                    group: group.to_string(),
                    changes: self
                        .rows
                        .iter()
                        .map(|r| (r.time_us, truthy(pick(r)[i])))
                        .collect(),
                })
                .collect::<Vec<_>>()
        };
        d.lanes
            .extend(lanes(&|r| &r.inputs, &self.input_names, "inputs"));
        d.lanes
            .extend(lanes(&|r| &r.outputs, &self.output_names, "outputs"));
        d
    }
}

/// Serializes an image as plain JSON scalars: booleans, integers and reals.
pub fn values<S: serde::Serializer>(vs: &[Value], s: S) -> Result<S::Ok, S::Error> {
    use serde::ser::SerializeSeq;
    let mut seq = s.serialize_seq(Some(vs.len()))?;
    for v in vs {
        match *v {
            Value::Bool(b) => seq.serialize_element(&b)?,
            Value::Int(i) => seq.serialize_element(&i)?,
            Value::Real(x) => seq.serialize_element(&x)?,
        }
    }
    seq.end()
}

fn value_text(v: Value) -> String {
    match v {
        Value::Bool(b) => u8::from(b).to_string(),
        Value::Int(i) => i.to_string(),
        Value::Real(x) => x.to_string(),
    }
}

fn truthy(v: Value) -> bool {
    match v {
        Value::Bool(b) => b,
        Value::Int(i) => i != 0,
        Value::Real(x) => x != 0.0,
    }
}

/// One digital signal over time.
#[derive(Clone, Debug)]
pub struct Lane {
    /// The signal's name.
    pub label: String,
    /// The group the lane is drawn under (inputs, outputs A, dispatched, ...).
    pub group: String,
    /// `(time_us, level)` at each sample; levels hold until the next sample.
    pub changes: Vec<(u64, bool)>,
}

/// A timing diagram of digital signals, drawn as SVG.
#[derive(Clone, Debug)]
pub struct TimingDiagram {
    /// The heading.
    pub title: String,
    /// Lanes, top to bottom.
    pub lanes: Vec<Lane>,
    /// Where time ends, in microseconds.
    pub end_us: u64,
    /// Vertical markers: `(time_us, label)`, e.g. an update being loaded.
    pub markers: Vec<(u64, String)>,
}

impl TimingDiagram {
    /// An empty diagram.
    pub fn new(title: &str, end_us: u64) -> Self {
        TimingDiagram {
            title: title.to_string(),
            lanes: Vec::new(),
            end_us,
            markers: Vec::new(),
        }
    }

    /// The diagram as a self-contained SVG document.
    pub fn to_svg(&self) -> String {
        const LEFT: f64 = 150.0;
        const WIDTH: f64 = 1100.0;
        const LANE: f64 = 22.0;
        const TOP: f64 = 40.0;
        let end = self.end_us.max(1) as f64;
        let x = |t: u64| LEFT + (t as f64 / end) * WIDTH;
        let mut groups: Vec<&str> = Vec::new();
        for l in &self.lanes {
            if !groups.contains(&l.group.as_str()) {
                groups.push(&l.group);
            }
        }
        let height = TOP + (self.lanes.len() + groups.len()) as f64 * LANE + 40.0;
        let mut s = String::new();
        let _ = writeln!(
            s,
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{:.0}" height="{:.0}" font-family="monospace" font-size="11">"#,
            LEFT + WIDTH + 20.0,
            height
        );
        let _ = writeln!(s, r#"<rect width="100%" height="100%" fill="white"/>"#);
        let _ = writeln!(
            s,
            r#"<text x="10" y="20" font-size="14" font-weight="bold">{}</text>"#,
            xml_escape(&self.title)
        );
        let mut y = TOP;
        let mut current_group = "";
        for lane in &self.lanes {
            if lane.group != current_group {
                current_group = &lane.group;
                let _ = writeln!(
                    s,
                    r##"<text x="10" y="{:.1}" font-weight="bold" fill="#555">{}</text>"##,
                    y + 14.0,
                    xml_escape(current_group)
                );
                y += LANE;
            }
            let _ = writeln!(
                s,
                r#"<text x="20" y="{:.1}">{}</text>"#,
                y + 14.0,
                xml_escape(&lane.label)
            );
            let hi = y + 4.0;
            let lo = y + 18.0;
            let mut pts = String::new();
            let mut level = false;
            let _ = write!(pts, "{:.1},{:.1}", x(0), lo);
            for &(t, v) in &lane.changes {
                if v != level {
                    let _ = write!(pts, " {:.1},{:.1}", x(t), if level { hi } else { lo });
                    let _ = write!(pts, " {:.1},{:.1}", x(t), if v { hi } else { lo });
                    level = v;
                }
            }
            let _ = write!(
                pts,
                " {:.1},{:.1}",
                x(self.end_us),
                if level { hi } else { lo }
            );
            let _ = writeln!(
                s,
                "<polyline data-signal=\"{}\" fill=\"none\" stroke=\"#1f5fbf\" stroke-width=\"1.5\" points=\"{}\"/>",
                xml_escape(&lane.label),
                pts
            );
            y += LANE;
        }
        for (t, label) in &self.markers {
            let _ = writeln!(
                s,
                "<line x1=\"{0:.1}\" y1=\"{1:.1}\" x2=\"{0:.1}\" y2=\"{2:.1}\" stroke=\"#c33\" stroke-dasharray=\"4 3\"/><text x=\"{3:.1}\" y=\"{4:.1}\" fill=\"#c33\">{5}</text>",
                x(*t),
                TOP - 8.0,
                y,
                x(*t) + 3.0,
                TOP - 10.0,
                xml_escape(label)
            );
        }
        // Time axis in seconds.
        let _ = writeln!(
            s,
            r#"<line x1="{LEFT}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="black"/>"#,
            LEFT + WIDTH
        );
        let ticks = 10;
        for i in 0..=ticks {
            let t = self.end_us as f64 * i as f64 / ticks as f64;
            let _ = writeln!(
                s,
                r#"<text x="{:.1}" y="{:.1}" text-anchor="middle">{:.1}s</text>"#,
                LEFT + WIDTH * i as f64 / ticks as f64,
                y + 15.0,
                t / 1e6
            );
        }
        s.push_str("</svg>\n");
        s
    }
}
