//! The paper's Fig. 7 as `cetratus demo --scripted --svg` draws it, read back as SVG: PRIMARY and
//! STATUS are lanes, no two texts overlap, an empty container is drawn as absent (not as outputs
//! that are off), and the axis and the markers number scan steps as well as times.

use std::process::Command;

use roxmltree::{Document, Node};

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

/// Plays the scripted demo and returns its SVG.
fn fig7() -> String {
    let dir = tempfile::tempdir().expect("temp dir");
    let svg = dir.path().join("fig7.svg");
    let out = Command::new(BIN)
        .args(["demo", "--scripted", "--json", "--dir"])
        .arg(dir.path().join("demo"))
        .arg("--svg")
        .arg(&svg)
        .output()
        .expect("run cetratus demo");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::read_to_string(&svg).expect("the demo wrote its SVG")
}

fn attr<'a>(n: &Node<'a, '_>, name: &str) -> &'a str {
    n.attribute(name)
        .unwrap_or_else(|| panic!("<{}> has no {name}", n.tag_name().name()))
}

fn num(n: &Node<'_, '_>, name: &str) -> f64 {
    attr(n, name)
        .parse()
        .unwrap_or_else(|_| panic!("{name} of <{}> is not a number", n.tag_name().name()))
}

fn with_class<'a, 'i>(doc: &'a Document<'i>, tag: &str, class: &str) -> Vec<Node<'a, 'i>> {
    doc.descendants()
        .filter(|n| n.has_tag_name(tag))
        .filter(|n| {
            n.attribute("class")
                .is_some_and(|c| c.split(' ').any(|c| c == class))
        })
        .collect()
}

/// The box a text occupies: monospace, so each character advances 0.6 of the font size; the
/// glyphs reach 0.8 of the size above the baseline and 0.2 below.
#[derive(Debug)]
struct TextBox {
    text: String,
    x0: f64,
    x1: f64,
    y0: f64,
    y1: f64,
}

fn text_box(n: &Node<'_, '_>, root_font: f64) -> TextBox {
    let size = n
        .attribute("font-size")
        .and_then(|s| s.parse().ok())
        .unwrap_or(root_font);
    let text = n.text().unwrap_or("").to_string();
    let width = text.chars().count() as f64 * 0.6 * size;
    let x = num(n, "x");
    let x0 = match n.attribute("text-anchor") {
        Some("middle") => x - width / 2.0,
        Some("end") => x - width,
        _ => x,
    };
    let y = num(n, "y");
    TextBox {
        text,
        x0,
        x1: x0 + width,
        y0: y - 0.8 * size,
        y1: y + 0.2 * size,
    }
}

#[test]
fn the_scripted_demo_draws_fig_7_with_lanes_apart_labels_absent_containers_and_scan_steps() {
    let svg = fig7();
    let doc = Document::parse(&svg).expect("the demo's SVG is well-formed XML");
    let root_font: f64 = doc
        .root_element()
        .attribute("font-size")
        .and_then(|s| s.parse().ok())
        .unwrap_or(11.0);

    // PRIMARY and STATUS are lanes of their own, above the signals.
    let groups: Vec<&str> = with_class(&doc, "text", "group")
        .iter()
        .filter_map(|n| n.text())
        .collect();
    assert_eq!(
        groups,
        [
            "update",
            "inputs",
            "outputs of A",
            "outputs of B",
            "dispatched"
        ]
    );
    let labels: Vec<(&str, &str)> = with_class(&doc, "text", "lane-label")
        .iter()
        .map(|n| (attr(n, "data-group"), n.text().unwrap_or("")))
        .collect();
    assert_eq!(labels[..2], [("update", "PRIMARY"), ("update", "STATUS")]);
    let values = |signal: &str| -> Vec<String> {
        let mut v: Vec<String> = Vec::new();
        for n in with_class(&doc, "rect", "value") {
            let value = attr(&n, "data-value");
            if attr(&n, "data-signal") == signal && v.last().map(String::as_str) != Some(value) {
                v.push(value.to_string());
            }
        }
        v
    };
    assert_eq!(values("PRIMARY"), ["A", "B", "A"], "U.1 into B, U.2 into A");
    // Setup lasts from the command to the next cycle boundary, inside one step: not a lane value.
    assert_eq!(
        values("STATUS"),
        ["idle", "quarantine", "idle", "quarantine", "idle"]
    );

    // No two texts overlap: lane and group labels, values, marker labels, ticks.
    let boxes: Vec<TextBox> = doc
        .descendants()
        .filter(|n| n.has_tag_name("text"))
        .map(|n| text_box(&n, root_font))
        .collect();
    assert!(boxes.len() > 40, "only {} texts", boxes.len());
    for (i, a) in boxes.iter().enumerate() {
        for b in &boxes[i + 1..] {
            let apart = a.x1 <= b.x0 || b.x1 <= a.x0 || a.y1 <= b.y0 || b.y1 <= a.y0;
            assert!(
                apart,
                "the texts {:?} and {:?} overlap: {a:?}, {b:?}",
                a.text, b.text
            );
        }
    }

    // B is empty until U.1 goes in, A between U.1's substitution and U.2's load: absent spans,
    // on every output lane of the empty container, and no level drawn there.
    let markers: Vec<(u64, String)> = with_class(&doc, "text", "marker-label")
        .iter()
        .map(|n| {
            let t = attr(n, "data-time-us").parse().expect("a time in µs");
            (t, n.text().unwrap_or("").to_string())
        })
        .collect();
    let time_of = |label: &str, nth: usize| {
        markers
            .iter()
            .filter(|(_, l)| l.starts_with(label))
            .nth(nth)
            .unwrap_or_else(|| panic!("marker {label} #{nth} in {markers:?}"))
            .0
    };
    let absent = |group: &str| -> Vec<(u64, u64)> {
        let mut spans: Vec<(u64, u64)> = with_class(&doc, "rect", "absent")
            .iter()
            .filter(|n| attr(n, "data-group") == group)
            .map(|n| {
                let t = |a| attr(n, a).parse::<u64>().expect("a time in µs");
                (t("data-from-us"), t("data-to-us"))
            })
            .collect();
        spans.sort_unstable();
        spans.dedup();
        spans
    };
    let lanes_in = |group: &str| labels.iter().filter(|(g, _)| *g == group).count();
    let outputs = lanes_in("outputs of B");
    assert_eq!(outputs, 8);
    let b_absent = absent("outputs of B");
    assert_eq!(b_absent[0].0, 0, "B is empty at the start: {b_absent:?}");
    assert!(b_absent[0].1 <= time_of("quarantine started", 0));
    let a_absent = absent("outputs of A");
    assert_eq!(a_absent.len(), 1, "{a_absent:?}");
    let (from, to) = a_absent[0];
    assert!(from >= time_of("substituted", 0) && from <= time_of("load accepted", 1));
    assert!(to <= time_of("quarantine started", 1) + 10_000);
    assert_eq!(
        with_class(&doc, "rect", "absent")
            .iter()
            .filter(|n| attr(n, "data-group") == "outputs of A" && num(n, "width") > 10.0)
            .count(),
        outputs,
        "every output of the empty A is drawn absent"
    );
    // A level is drawn in B's lanes only once it holds a program.
    let x_quarantine = with_class(&doc, "line", "marker")[1]
        .attribute("x1")
        .and_then(|x| x.parse::<f64>().ok())
        .expect("the quarantine marker's x");
    for n in with_class(&doc, "polyline", "level") {
        if attr(&n, "data-group") == "outputs of B" {
            let first_x: f64 = attr(&n, "points")
                .split([' ', ','])
                .next()
                .and_then(|x| x.parse().ok())
                .expect("a point");
            assert!(first_x >= x_quarantine - 1.0, "B drawn before it existed");
        }
    }

    // Scan steps are numbered beside the times: on the axis and on the markers.
    let steps: Vec<u64> = with_class(&doc, "text", "step")
        .iter()
        .map(|n| {
            n.text()
                .and_then(|t| t.strip_prefix('#'))
                .and_then(|t| t.parse().ok())
                .expect("a step number")
        })
        .collect();
    assert_eq!(steps.len(), 11);
    assert!(steps.windows(2).all(|w| w[0] < w[1]), "{steps:?}");
    assert!(
        markers.iter().all(|(_, l)| l.contains("(scan ")),
        "{markers:?}"
    );
}
