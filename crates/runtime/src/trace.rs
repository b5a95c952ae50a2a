//! Traces of a run: the I/O image whenever it changes, written as CSV, JSON or an SVG timing
//! diagram in the style of the paper's Fig. 7.
//!
//! The diagram draws digital lanes (a level over time), value lanes (PRIMARY, STATUS: a bus with
//! its value written in each segment) and absent spans (a container that holds no program: hatched,
//! no level, so that an empty container is not mistaken for one whose outputs are all off). Time is
//! labelled in seconds and, when the scan period is known, in scan steps. No two texts overlap:
//! marker labels that would collide go on further rows, and a value is written in a bus segment
//! only where it fits. Every element a reader may look for carries `data-` attributes (group,
//! signal, times in µs), so that tests and tools read the drawing without guessing at geometry.

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
    /// The watched program variables, in the order asked for.
    #[serde(serialize_with = "values", skip_serializing_if = "Vec::is_empty")]
    pub watched: Vec<Value>,
}

/// The changes of the I/O image over a run.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Trace {
    /// Input names.
    pub input_names: Vec<String>,
    /// Output names.
    pub output_names: Vec<String>,
    /// Names of the watched program variables (`cetratus run --watch`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub watched_names: Vec<String>,
    /// One row per scan in which an input, output or watched variable changed (and the first
    /// scan).
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
            watched_names: Vec::new(),
            rows: Vec::new(),
            end_us: 0,
        }
    }

    /// The trace also records these program variables, as columns after the outputs.
    pub fn watching(mut self, names: Vec<String>) -> Self {
        self.watched_names = names;
        self
    }

    /// Records the images of a scan if they differ from the last row.
    pub fn observe(&mut self, scan: u64, time_us: u64, inputs: &[Value], outputs: &[Value]) {
        self.observe_watched(scan, time_us, inputs, outputs, &[]);
    }

    /// [`Trace::observe`], with the values of the watched variables.
    pub fn observe_watched(
        &mut self,
        scan: u64,
        time_us: u64,
        inputs: &[Value],
        outputs: &[Value],
        watched: &[Value],
    ) {
        self.end_us = time_us;
        if let Some(last) = self.rows.last() {
            if last.inputs == inputs && last.outputs == outputs && last.watched == watched {
                return;
            }
        }
        self.rows.push(TraceRow {
            scan,
            time_us,
            inputs: inputs.to_vec(),
            outputs: outputs.to_vec(),
            watched: watched.to_vec(),
        });
    }

    /// CSV: `scan,time_ms,<inputs>,<outputs>,<watched>` with booleans as 0/1.
    pub fn to_csv(&self) -> String {
        let mut s = String::from("scan,time_ms");
        let names = self.input_names.iter().chain(&self.output_names);
        for n in names.chain(&self.watched_names) {
            let _ = write!(s, ",{n}");
        }
        s.push('\n');
        for r in &self.rows {
            let _ = write!(s, "{},{:.3}", r.scan, r.time_us as f64 / 1000.0);
            for v in r.inputs.iter().chain(&r.outputs).chain(&r.watched) {
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
                        .map(|r| (r.time_us, LaneValue::Level(truthy(pick(r)[i]))))
                        .collect(),
                })
                .collect::<Vec<_>>()
        };
        d.lanes
            .extend(lanes(&|r| &r.inputs, &self.input_names, "inputs"));
        d.lanes
            .extend(lanes(&|r| &r.outputs, &self.output_names, "outputs"));
        d.lanes
            .extend(lanes(&|r| &r.watched, &self.watched_names, "variables"));
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

/// What a lane shows from a time on.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum LaneValue {
    /// A digital level.
    Level(bool),
    /// A value written in the lane, e.g. PRIMARY's `A` or STATUS's `quarantine`.
    Text(String),
    /// Nothing: the signal's source does not exist (an empty container).
    Absent,
}

/// One signal over time.
#[derive(Clone, Debug)]
pub struct Lane {
    /// The signal's name.
    pub label: String,
    /// The group the lane is drawn under (inputs, outputs A, dispatched, ...).
    pub group: String,
    /// `(time_us, value)` at each sample; a value holds until the next sample.
    pub changes: Vec<(u64, LaneValue)>,
}

/// A timing diagram, drawn as SVG.
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
    /// The scan period, when every scan is one period long: the axis then numbers scan steps too.
    pub scan_period_us: Option<u64>,
}

/// Geometry of the drawing, in SVG user units.
mod geometry {
    /// Where the plot starts; lane labels sit left of it.
    pub const LEFT: f64 = 150.0;
    /// Width of the plot.
    pub const WIDTH: f64 = 1100.0;
    /// Height of one lane.
    pub const LANE: f64 = 22.0;
    /// Height of the title band.
    pub const TITLE: f64 = 30.0;
    /// Height of one row of marker labels.
    pub const MARKER_ROW: f64 = 14.0;
    /// Font size of every text but the title.
    pub const FONT: f64 = 11.0;
    /// Font size of the title.
    pub const TITLE_FONT: f64 = 14.0;
    /// Advance of one character of the monospace font, as a share of its size.
    pub const CHAR: f64 = 0.6;
}

/// The width of `text` in the diagram's monospace font of size `font`.
pub fn text_width(text: &str, font: f64) -> f64 {
    text.chars().count() as f64 * geometry::CHAR * font
}

impl TimingDiagram {
    /// An empty diagram.
    pub fn new(title: &str, end_us: u64) -> Self {
        TimingDiagram {
            title: title.to_string(),
            lanes: Vec::new(),
            end_us,
            markers: Vec::new(),
            scan_period_us: None,
        }
    }

    /// The label of a marker: its text, and its scan step when the period is known.
    fn marker_label(&self, t: u64, label: &str) -> String {
        match self.scan_period_us.filter(|&p| p > 0) {
            Some(p) => format!("{label} (scan {})", t / p),
            None => label.to_string(),
        }
    }

    /// The diagram as a self-contained SVG document.
    pub fn to_svg(&self) -> String {
        use geometry::*;
        let end = self.end_us.max(1) as f64;
        let x = |t: u64| LEFT + (t.min(self.end_us) as f64 / end) * WIDTH;
        // Marker labels: each on the first row where it clears the labels already there.
        let mut rows: Vec<f64> = Vec::new();
        let mut placed = Vec::new();
        for (t, label) in &self.markers {
            let text = self.marker_label(*t, label);
            let left = x(*t) + 3.0;
            let row = match rows.iter().position(|&right| left > right + 6.0) {
                Some(r) => r,
                None => {
                    rows.push(f64::MIN);
                    rows.len() - 1
                }
            };
            rows[row] = left + text_width(&text, FONT);
            placed.push((*t, row, text));
        }
        let top = TITLE + rows.len() as f64 * MARKER_ROW + 6.0;
        let mut groups: Vec<&str> = Vec::new();
        for l in &self.lanes {
            if !groups.contains(&l.group.as_str()) {
                groups.push(&l.group);
            }
        }
        let steps = self.scan_period_us.is_some();
        let height =
            top + (self.lanes.len() + groups.len()) as f64 * LANE + if steps { 50.0 } else { 40.0 };
        let mut s = String::new();
        let _ = writeln!(
            s,
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{:.0}" height="{:.0}" font-family="monospace" font-size="{FONT}">"#,
            LEFT + WIDTH + 20.0,
            height
        );
        let _ = writeln!(
            s,
            "<defs><pattern id=\"absent\" width=\"6\" height=\"6\" patternUnits=\"userSpaceOnUse\" patternTransform=\"rotate(45)\"><line x1=\"0\" y1=\"0\" x2=\"0\" y2=\"6\" stroke=\"#bbb\" stroke-width=\"2\"/></pattern></defs>"
        );
        let _ = writeln!(s, r#"<rect width="100%" height="100%" fill="white"/>"#);
        let _ = writeln!(
            s,
            r#"<text class="title" x="10" y="20" font-size="{TITLE_FONT}" font-weight="bold">{}</text>"#,
            xml_escape(&self.title)
        );
        let mut y = top;
        let mut current_group = "";
        for lane in &self.lanes {
            if lane.group != current_group {
                current_group = &lane.group;
                let _ = writeln!(
                    s,
                    r##"<text class="group" x="10" y="{:.1}" font-weight="bold" fill="#555">{}</text>"##,
                    y + 14.0,
                    xml_escape(current_group)
                );
                y += LANE;
            }
            let _ = writeln!(
                s,
                r#"<text class="lane-label" data-group="{}" x="20" y="{:.1}">{}</text>"#,
                xml_escape(&lane.group),
                y + 14.0,
                xml_escape(&lane.label)
            );
            self.draw_lane(&mut s, lane, y, &x);
            y += LANE;
        }
        for (t, row, text) in &placed {
            let ly = TITLE + (*row as f64 + 1.0) * MARKER_ROW;
            let _ = writeln!(
                s,
                "<line class=\"marker\" x1=\"{0:.1}\" y1=\"{1:.1}\" x2=\"{0:.1}\" y2=\"{2:.1}\" stroke=\"#c33\" stroke-dasharray=\"4 3\"/><text class=\"marker-label\" data-time-us=\"{3}\" x=\"{4:.1}\" y=\"{5:.1}\" fill=\"#c33\">{6}</text>",
                x(*t),
                ly + 3.0,
                y,
                t,
                x(*t) + 3.0,
                ly,
                xml_escape(text)
            );
        }
        // Time axis in seconds, and in scan steps when every scan is one period.
        let _ = writeln!(
            s,
            r#"<line x1="{LEFT}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="black"/>"#,
            LEFT + WIDTH
        );
        let ticks = 10;
        for i in 0..=ticks {
            let t = self.end_us as f64 * f64::from(i) / f64::from(ticks);
            let tx = LEFT + WIDTH * f64::from(i) / f64::from(ticks);
            let _ = writeln!(
                s,
                r#"<text class="tick" x="{tx:.1}" y="{:.1}" text-anchor="middle">{:.1}s</text>"#,
                y + 15.0,
                t / 1e6
            );
            if let Some(p) = self.scan_period_us.filter(|&p| p > 0) {
                let _ = writeln!(
                    s,
                    r##"<text class="tick step" x="{tx:.1}" y="{:.1}" text-anchor="middle" fill="#555">#{}</text>"##,
                    y + 29.0,
                    (t as u64) / p
                );
            }
        }
        if steps {
            let _ = writeln!(
                s,
                r##"<text class="axis-label" x="10" y="{:.1}" fill="#555">time, scan step</text>"##,
                y + 22.0
            );
        }
        s.push_str("</svg>\n");
        s
    }

    /// Draws one lane's samples, span by span, at lane top `y`.
    fn draw_lane(&self, s: &mut String, lane: &Lane, y: f64, x: &dyn Fn(u64) -> f64) {
        use geometry::*;
        let hi = y + 4.0;
        let lo = y + 18.0;
        let group = xml_escape(&lane.group);
        let signal = xml_escape(&lane.label);
        // Spans of equal value: (from, to, value), the last one up to the end of the diagram.
        let mut spans: Vec<(u64, u64, &LaneValue)> = Vec::new();
        for (i, (t, v)) in lane.changes.iter().enumerate() {
            let to = lane.changes.get(i + 1).map_or(self.end_us, |n| n.0).max(*t);
            match spans.last_mut() {
                Some(last) if last.2 == v => last.1 = to,
                _ => spans.push((*t, to, v)),
            }
        }
        let mut pts = String::new();
        let flush = |s: &mut String, pts: &mut String| {
            if !pts.is_empty() {
                let _ = writeln!(
                    s,
                    "<polyline class=\"level\" data-group=\"{group}\" data-signal=\"{signal}\" fill=\"none\" stroke=\"#1f5fbf\" stroke-width=\"1.5\" points=\"{pts}\"/>"
                );
                pts.clear();
            }
        };
        for &(from, to, v) in &spans {
            match v {
                LaneValue::Level(on) => {
                    let ly = if *on { hi } else { lo };
                    if !pts.is_empty() {
                        let _ = write!(pts, " {:.1},{ly:.1}", x(from));
                    }
                    let sep = if pts.is_empty() { "" } else { " " };
                    let _ = write!(pts, "{sep}{:.1},{ly:.1} {:.1},{ly:.1}", x(from), x(to));
                }
                LaneValue::Absent => {
                    flush(s, &mut pts);
                    let _ = writeln!(
                        s,
                        "<rect class=\"absent\" data-group=\"{group}\" data-signal=\"{signal}\" data-from-us=\"{from}\" data-to-us=\"{to}\" x=\"{:.1}\" y=\"{hi:.1}\" width=\"{:.1}\" height=\"{:.1}\" fill=\"url(#absent)\"/>",
                        x(from),
                        (x(to) - x(from)).max(0.5),
                        lo - hi
                    );
                }
                LaneValue::Text(text) => {
                    flush(s, &mut pts);
                    let (a, b) = (x(from), x(to));
                    let _ = writeln!(
                        s,
                        "<rect class=\"value\" data-group=\"{group}\" data-signal=\"{signal}\" data-value=\"{}\" data-from-us=\"{from}\" data-to-us=\"{to}\" x=\"{a:.1}\" y=\"{hi:.1}\" width=\"{:.1}\" height=\"{:.1}\" fill=\"#eef3fb\" stroke=\"#1f5fbf\"/>",
                        xml_escape(text),
                        (b - a).max(0.5),
                        lo - hi
                    );
                    // Written only where it fits, so that no two texts overlap.
                    if text_width(text, FONT) + 4.0 <= b - a {
                        let _ = writeln!(
                            s,
                            r#"<text class="value-label" x="{:.1}" y="{:.1}">{}</text>"#,
                            a + 2.0,
                            lo - 3.0,
                            xml_escape(text)
                        );
                    }
                }
            }
        }
        flush(s, &mut pts);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn diagram_with(lanes: Vec<Lane>, markers: Vec<(u64, String)>) -> String {
        let mut d = TimingDiagram::new("t", 1_000_000);
        d.lanes = lanes;
        d.markers = markers;
        d.scan_period_us = Some(10_000);
        d.to_svg()
    }

    #[test]
    fn markers_too_close_for_their_labels_go_on_separate_rows() {
        let svg = diagram_with(
            Vec::new(),
            vec![
                (0, "load accepted".into()),
                (10_000, "quarantine started".into()),
            ],
        );
        let ys: Vec<&str> = svg
            .lines()
            .filter(|l| l.contains("marker-label"))
            .filter_map(|l| l.split("fill=\"#c33\">").next()?.rsplit("y=\"").next())
            .collect();
        assert_eq!(ys.len(), 2);
        assert_ne!(ys[0], ys[1], "{svg}");
        assert!(svg.contains("(scan 1)"), "markers name their scan step");
    }

    #[test]
    fn an_absent_span_draws_no_level_and_a_value_is_written_only_where_it_fits() {
        let lanes = vec![
            Lane {
                label: "CM1".into(),
                group: "outputs of B".into(),
                changes: vec![(0, LaneValue::Absent), (500_000, LaneValue::Level(true))],
            },
            Lane {
                label: "STATUS".into(),
                group: "update".into(),
                changes: vec![
                    (0, LaneValue::Text("idle".into())),
                    (500_000, LaneValue::Text("quarantine".into())),
                    (500_001, LaneValue::Text("idle".into())),
                ],
            },
        ];
        let svg = diagram_with(lanes, Vec::new());
        assert!(svg.contains(r#"class="absent" data-group="outputs of B" data-signal="CM1" data-from-us="0" data-to-us="500000""#));
        let level = svg
            .lines()
            .find(|l| l.contains("class=\"level\""))
            .expect("a level after the absent span");
        assert!(level.contains("points=\"700.0,"), "{level}");
        // `quarantine` lasts 1 µs: its segment is drawn, its word is not.
        assert!(svg.contains(r#"data-value="quarantine""#));
        assert!(!svg.contains(">quarantine</text>"));
        assert_eq!(svg.matches(">idle</text>").count(), 2);
    }
}
