//! Pictures of a net: Graphviz DOT text and a self-contained SVG drawing with its marking.
//!
//! The SVG is meant to be updated live by the dashboard: each place is a `<g id="place-<id>"
//! data-tokens="N">` whose `.tokens` group holds the token dots (or the count above five), and each
//! transition is a `<g id="trans-<id>">`. Nodes are drawn where the file put them when every node
//! has a distinct position; otherwise [`layout`] computes a layered drawing, so no external layout
//! tool is needed.

use std::borrow::Cow;
use std::collections::{HashSet, VecDeque};
use std::fmt::Write as _;

use crate::{
    xml_escape, Arc, ArcKind, Net, NodeRef, Place, PlaceIdx, Position, Tokens, TransIdx, Transition,
};

/// Radius of a place, in drawing units.
const PLACE_R: f64 = 18.0;
/// Half the width of a transition bar.
const TRANS_HW: f64 = 8.0;
/// Half the height of a transition bar.
const TRANS_HH: f64 = 20.0;
/// Distance between layers of the computed layout.
const LAYER_DX: f64 = 110.0;
/// Distance between nodes within a layer of the computed layout.
const ROW_DY: f64 = 90.0;
/// Empty space around the drawing.
const MARGIN: f64 = 50.0;

/// Where every node of a net is drawn, indexed like the net's places and transitions.
#[derive(Clone, Debug, PartialEq)]
pub struct Layout {
    /// Centre of each place, in declaration order.
    pub places: Vec<Position>,
    /// Centre of each transition, in declaration order.
    pub transitions: Vec<Position>,
}

impl Layout {
    fn at(&self, node: NodeRef) -> Position {
        match node {
            NodeRef::Place(p) => self.places[p.index()],
            NodeRef::Transition(t) => self.transitions[t.index()],
        }
    }
}

/// The positions from the file when every node has a distinct one, else a computed layered layout.
pub fn layout(net: &Net) -> Layout {
    let from_file: Option<Vec<Position>> = net
        .places()
        .iter()
        .map(|p| p.position)
        .chain(net.transitions().iter().map(|t| t.position))
        .collect();
    if let Some(all) = from_file {
        // Some tools write the same position for every node; drawing that would hide the net.
        let distinct: HashSet<(i64, i64)> = all
            .iter()
            .map(|p| (p.x.round() as i64, p.y.round() as i64))
            .collect();
        if !all.is_empty() && distinct.len() == all.len() {
            let (places, transitions) = all.split_at(net.num_places());
            return Layout {
                places: places.to_vec(),
                transitions: transitions.to_vec(),
            };
        }
    }
    layered(net)
}

/// Layers by breadth-first distance from the initially marked places, so the drawing reads left to
/// right in the direction tokens flow; places and transitions fall in alternating columns.
fn layered(net: &Net) -> Layout {
    let np = net.num_places();
    let nt = net.num_transitions();
    let mut place_layer: Vec<Option<usize>> = vec![None; np];
    let mut trans_layer: Vec<Option<usize>> = vec![None; nt];
    let mut queue: VecDeque<NodeRef> = VecDeque::new();
    for (i, p) in net.places().iter().enumerate() {
        if p.initial > 0 {
            place_layer[i] = Some(0);
            queue.push_back(NodeRef::Place(PlaceIdx(i as u32)));
        }
    }
    loop {
        while let Some(node) = queue.pop_front() {
            match node {
                NodeRef::Place(p) => {
                    let layer = place_layer[p.index()].unwrap_or(0) + 1;
                    let next = net.consumers(p).iter().chain(net.inhibited(p));
                    for &(t, _) in next {
                        if trans_layer[t.index()].is_none() {
                            trans_layer[t.index()] = Some(layer);
                            queue.push_back(NodeRef::Transition(t));
                        }
                    }
                }
                NodeRef::Transition(t) => {
                    let layer = trans_layer[t.index()].unwrap_or(1) + 1;
                    for &(p, _) in net.post(t) {
                        if place_layer[p.index()].is_none() {
                            place_layer[p.index()] = Some(layer);
                            queue.push_back(NodeRef::Place(p));
                        }
                    }
                }
            }
        }
        // A part of the net no token reaches starts its own walk at its first declared node.
        if let Some(i) = place_layer.iter().position(Option::is_none) {
            place_layer[i] = Some(0);
            queue.push_back(NodeRef::Place(PlaceIdx(i as u32)));
        } else if let Some(i) = trans_layer.iter().position(Option::is_none) {
            trans_layer[i] = Some(1);
            queue.push_back(NodeRef::Transition(TransIdx(i as u32)));
        } else {
            break;
        }
    }

    let layers = place_layer
        .iter()
        .chain(&trans_layer)
        .map(|l| l.unwrap_or(0) + 1)
        .max()
        .unwrap_or(0);
    let mut columns: Vec<Vec<NodeRef>> = vec![Vec::new(); layers];
    for (i, l) in place_layer.iter().enumerate() {
        columns[l.unwrap_or(0)].push(NodeRef::Place(PlaceIdx(i as u32)));
    }
    for (i, l) in trans_layer.iter().enumerate() {
        columns[l.unwrap_or(0)].push(NodeRef::Transition(TransIdx(i as u32)));
    }
    // One barycentre sweep: a node moves towards its neighbours in the column before, which
    // removes most crossings at the cost of one sort per column.
    let mut place_row = vec![0usize; np];
    let mut trans_row = vec![0usize; nt];
    for (layer, column) in columns.iter_mut().enumerate() {
        if layer > 0 {
            let before = layer - 1;
            let mut keyed: Vec<(f64, NodeRef)> = column
                .iter()
                .enumerate()
                .map(|(row, &node)| {
                    let rows: Vec<usize> = neighbours(net, node)
                        .filter(|&m| layer_of(&place_layer, &trans_layer, m) == before)
                        .map(|m| match m {
                            NodeRef::Place(p) => place_row[p.index()],
                            NodeRef::Transition(t) => trans_row[t.index()],
                        })
                        .collect();
                    let key = if rows.is_empty() {
                        row as f64
                    } else {
                        rows.iter().sum::<usize>() as f64 / rows.len() as f64
                    };
                    (key, node)
                })
                .collect();
            keyed.sort_by(|a, b| a.0.total_cmp(&b.0));
            *column = keyed.into_iter().map(|(_, n)| n).collect();
        }
        for (row, node) in column.iter().enumerate() {
            match node {
                NodeRef::Place(p) => place_row[p.index()] = row,
                NodeRef::Transition(t) => trans_row[t.index()] = row,
            }
        }
    }
    let tallest = columns.iter().map(Vec::len).max().unwrap_or(0);
    let at = |layer: usize, row: usize| {
        // Centre short columns against the tallest one.
        let offset = (tallest - columns[layer].len()) as f64 * ROW_DY / 2.0;
        Position {
            x: MARGIN + layer as f64 * LAYER_DX,
            y: MARGIN + offset + row as f64 * ROW_DY,
        }
    };
    let places = (0..np)
        .map(|i| at(place_layer[i].unwrap_or(0), place_row[i]))
        .collect();
    let transitions = (0..nt)
        .map(|i| at(trans_layer[i].unwrap_or(0), trans_row[i]))
        .collect();
    Layout {
        places,
        transitions,
    }
}

fn layer_of(place_layer: &[Option<usize>], trans_layer: &[Option<usize>], node: NodeRef) -> usize {
    match node {
        NodeRef::Place(p) => place_layer[p.index()].unwrap_or(0),
        NodeRef::Transition(t) => trans_layer[t.index()].unwrap_or(0),
    }
}

/// The nodes joined to `node` by an arc in either direction.
fn neighbours(net: &Net, node: NodeRef) -> Box<dyn Iterator<Item = NodeRef> + '_> {
    match node {
        NodeRef::Place(p) => Box::new(
            net.consumers(p)
                .iter()
                .chain(net.producers(p))
                .chain(net.inhibited(p))
                .map(|&(t, _)| NodeRef::Transition(t)),
        ),
        NodeRef::Transition(t) => Box::new(
            net.pre(t)
                .iter()
                .chain(net.post(t))
                .chain(net.inhibitors(t))
                .map(|&(p, _)| NodeRef::Place(p)),
        ),
    }
}

/// The tokens of place `i`: from `marking` when it has an entry for it, else the initial marking.
fn tokens_of(net: &Net, marking: Option<&[Tokens]>, i: usize) -> Tokens {
    marking
        .and_then(|m| m.get(i).copied())
        .unwrap_or_else(|| net.places()[i].initial)
}

/// Graphviz DOT text: places as circles holding their token count, transitions as boxes, weights
/// above 1 as labels, inhibitor arcs with `arrowhead=odot`. Without a marking, M0 is shown.
pub fn to_dot(net: &Net, marking: Option<&[Tokens]>) -> String {
    let mut w = String::new();
    write_dot(net, marking, &mut w).expect("writing to a String cannot fail");
    w
}

fn write_dot(net: &Net, marking: Option<&[Tokens]>, w: &mut String) -> std::fmt::Result {
    writeln!(w, "digraph \"{}\" {{", dot(net.name().unwrap_or(net.id())))?;
    writeln!(w, "  rankdir=LR;")?;
    writeln!(w, "  node [fontname=\"Helvetica\", fontsize=10];")?;
    writeln!(w, "  edge [fontname=\"Helvetica\", fontsize=9];")?;
    for (i, p) in net.places().iter().enumerate() {
        let tokens = tokens_of(net, marking, i);
        let inside = if tokens == 0 {
            String::new()
        } else {
            tokens.to_string()
        };
        let cap = p
            .capacity
            .map(|c| format!(" (cap {c})"))
            .unwrap_or_default();
        writeln!(
            w,
            "  \"p:{}\" [shape=circle, width=0.5, fixedsize=true, label=\"{}\", xlabel=\"{}{}\"];",
            dot(&p.id),
            inside,
            dot(p.label()),
            dot(&cap)
        )?;
    }
    for t in net.transitions() {
        let prio = if t.priority != 0 {
            format!(" [{}]", t.priority)
        } else {
            String::new()
        };
        writeln!(
            w,
            "  \"t:{}\" [shape=box, height=0.4, label=\"{}{}\"];",
            dot(&t.id),
            dot(t.label()),
            dot(&prio)
        )?;
    }
    for a in net.arcs() {
        let mut attrs: Vec<String> = Vec::new();
        if a.weight > 1 {
            attrs.push(format!("label=\"{}\"", a.weight));
        }
        if a.kind == ArcKind::Inhibitor {
            attrs.push("arrowhead=odot".to_string());
        }
        let attrs = if attrs.is_empty() {
            String::new()
        } else {
            format!(" [{}]", attrs.join(", "))
        };
        writeln!(
            w,
            "  \"{}\" -> \"{}\"{attrs};",
            dot_node(net, a.source),
            dot_node(net, a.target)
        )?;
    }
    writeln!(w, "}}")
}

fn dot_node(net: &Net, node: NodeRef) -> String {
    match node {
        NodeRef::Place(p) => format!("p:{}", dot(&net.place(p).id)),
        NodeRef::Transition(t) => format!("t:{}", dot(&net.transition(t).id)),
    }
}

/// Escapes a DOT double-quoted string.
fn dot(s: &str) -> Cow<'_, str> {
    if !s.contains(['"', '\\', '\n', '\r']) {
        return Cow::Borrowed(s);
    }
    let mut out = String::with_capacity(s.len() + 4);
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\r' => {}
            c => out.push(c),
        }
    }
    Cow::Owned(out)
}

/// A self-contained SVG drawing of the net with its marking (M0 when `marking` is `None`).
pub fn to_svg(net: &Net, marking: Option<&[Tokens]>) -> String {
    let mut w = String::new();
    write_svg(net, marking, &layout(net), &mut w).expect("writing to a String cannot fail");
    w
}

fn write_svg(
    net: &Net,
    marking: Option<&[Tokens]>,
    lay: &Layout,
    w: &mut String,
) -> std::fmt::Result {
    write_svg_head(net, lay, w)?;
    writeln!(w, "  <g class=\"arcs\">")?;
    for a in net.arcs() {
        write_arc(a, lay, w)?;
    }
    writeln!(w, "  </g>")?;
    writeln!(w, "  <g class=\"places\">")?;
    for (i, p) in net.places().iter().enumerate() {
        write_place(p, lay.places[i], tokens_of(net, marking, i), w)?;
    }
    writeln!(w, "  </g>")?;
    writeln!(w, "  <g class=\"transitions\">")?;
    for (i, t) in net.transitions().iter().enumerate() {
        write_transition(t, lay.transitions[i], w)?;
    }
    writeln!(w, "  </g>")?;
    writeln!(w, "</svg>")
}

/// The smallest box holding every node centre and every bend point: the drawing's extent
/// before the margin, as `(x0, y0, x1, y1)`.
fn extent(net: &Net, lay: &Layout) -> (f64, f64, f64, f64) {
    let all = lay.places.iter().chain(&lay.transitions);
    let (mut x0, mut y0, mut x1, mut y1) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for (i, p) in all.enumerate() {
        if i == 0 {
            (x0, y0, x1, y1) = (p.x, p.y, p.x, p.y);
        }
        x0 = x0.min(p.x);
        y0 = y0.min(p.y);
        x1 = x1.max(p.x);
        y1 = y1.max(p.y);
    }
    for a in net.arcs() {
        for p in &a.path {
            x0 = x0.min(p.x);
            y0 = y0.min(p.y);
            x1 = x1.max(p.x);
            y1 = y1.max(p.y);
        }
    }
    (x0, y0, x1, y1)
}

/// The `<svg>` element's opening, title, arrow markers and style: everything before the nodes.
fn write_svg_head(net: &Net, lay: &Layout, w: &mut String) -> std::fmt::Result {
    let (x0, y0, x1, y1) = extent(net, lay);
    let (vx, vy) = (x0 - MARGIN, y0 - MARGIN);
    let (vw, vh) = (x1 - x0 + 2.0 * MARGIN, y1 - y0 + 2.0 * MARGIN);
    writeln!(
        w,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" class=\"cetratus-net\" data-net=\"{}\" viewBox=\"{} {} {} {}\" width=\"{}\" height=\"{}\">",
        xml_escape(net.id()),
        n(vx),
        n(vy),
        n(vw),
        n(vh),
        n(vw),
        n(vh)
    )?;
    if let Some(name) = net.name() {
        writeln!(w, "  <title>{}</title>", xml_escape(name))?;
    }
    writeln!(w, "  <defs>")?;
    writeln!(w, "    <marker id=\"cetratus-arrow\" viewBox=\"0 0 10 10\" refX=\"10\" refY=\"5\" markerWidth=\"8\" markerHeight=\"8\" orient=\"auto\"><path d=\"M0,0 L10,5 L0,10 z\" fill=\"#222\"/></marker>")?;
    writeln!(w, "    <marker id=\"cetratus-inhibitor\" viewBox=\"0 0 10 10\" refX=\"9\" refY=\"5\" markerWidth=\"8\" markerHeight=\"8\" orient=\"auto\"><circle cx=\"5\" cy=\"5\" r=\"4\" fill=\"#fff\" stroke=\"#222\" stroke-width=\"1.5\"/></marker>")?;
    writeln!(w, "  </defs>")?;
    writeln!(w, "  <style>.cetratus-net text{{font-family:Helvetica,Arial,sans-serif;font-size:11px;text-anchor:middle}} .arc{{fill:none;stroke:#222;stroke-width:1.3}} .place circle.node{{fill:#fff;stroke:#222;stroke-width:1.5}} .transition rect{{fill:#222}} .tokens circle{{fill:#222}} .weight{{fill:#036}} .label,.weight{{paint-order:stroke;stroke:#fff;stroke-width:3px;stroke-linejoin:round}}</style>")
}

/// An arc as a path from border to border through its bend points, its weight above 1 at the
/// middle segment.
fn write_arc(a: &Arc, lay: &Layout, w: &mut String) -> std::fmt::Result {
    let from = lay.at(a.source);
    let to = lay.at(a.target);
    let mut points = Vec::with_capacity(a.path.len() + 2);
    let first_aim = a.path.first().copied().unwrap_or(to);
    let last_aim = a.path.last().copied().unwrap_or(from);
    points.push(clip(a.source, from, first_aim));
    points.extend(a.path.iter().copied());
    points.push(clip(a.target, to, last_aim));
    let d: Vec<String> = points
        .iter()
        .enumerate()
        .map(|(i, p)| format!("{}{},{}", if i == 0 { "M" } else { "L" }, n(p.x), n(p.y)))
        .collect();
    let (class, marker) = match a.kind {
        ArcKind::Normal => ("arc", "cetratus-arrow"),
        ArcKind::Inhibitor => ("arc inhibitor", "cetratus-inhibitor"),
    };
    writeln!(
        w,
        "    <path id=\"arc-{}\" class=\"{class}\" d=\"{}\" marker-end=\"url(#{marker})\"/>",
        xml_escape(&a.id),
        d.join(" ")
    )?;
    if a.weight > 1 {
        let mid = points.len() / 2;
        let (p, q) = (points[mid - 1], points[mid]);
        writeln!(
            w,
            "    <text class=\"weight\" x=\"{}\" y=\"{}\">{}</text>",
            n((p.x + q.x) / 2.0),
            n((p.y + q.y) / 2.0 - 4.0),
            a.weight
        )?;
    }
    Ok(())
}

/// A place centred on `c` with its `tokens`, in the `<g>` the dashboard finds by id to update.
fn write_place(p: &Place, c: Position, tokens: Tokens, w: &mut String) -> std::fmt::Result {
    writeln!(
        w,
        "    <g id=\"place-{}\" class=\"place\" data-tokens=\"{tokens}\">",
        xml_escape(&p.id)
    )?;
    write_title(w, &p.id, p.name.as_deref())?;
    writeln!(
        w,
        "      <circle class=\"node\" cx=\"{}\" cy=\"{}\" r=\"{PLACE_R}\"/>",
        n(c.x),
        n(c.y)
    )?;
    write!(w, "      <g class=\"tokens\">")?;
    write_tokens(w, c, tokens)?;
    writeln!(w, "</g>")?;
    write_label(w, c.x, c.y + PLACE_R + 13.0, p.label())?;
    writeln!(w, "    </g>")
}

/// A transition as a bar centred on `c`, in the `<g>` the dashboard finds by id.
fn write_transition(t: &Transition, c: Position, w: &mut String) -> std::fmt::Result {
    writeln!(
        w,
        "    <g id=\"trans-{}\" class=\"transition\">",
        xml_escape(&t.id)
    )?;
    write_title(w, &t.id, t.name.as_deref())?;
    writeln!(
        w,
        "      <rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\"/>",
        n(c.x - TRANS_HW),
        n(c.y - TRANS_HH),
        n(2.0 * TRANS_HW),
        n(2.0 * TRANS_HH)
    )?;
    write_label(w, c.x, c.y + TRANS_HH + 13.0, t.label())?;
    writeln!(w, "    </g>")
}

/// A node's tooltip: its name and id, so that a named node can still be found by id.
fn write_title(w: &mut String, id: &str, name: Option<&str>) -> std::fmt::Result {
    let title = match name {
        Some(name) if name != id => format!("{name} ({id})"),
        _ => id.to_string(),
    };
    writeln!(w, "      <title>{}</title>", xml_escape(&title))
}

/// A node's label at `(x, y)`, below the node.
fn write_label(w: &mut String, x: f64, y: f64, label: &str) -> std::fmt::Result {
    writeln!(
        w,
        "      <text class=\"label\" x=\"{}\" y=\"{}\">{}</text>",
        n(x),
        n(y),
        xml_escape(label)
    )
}

/// Up to five tokens as dots in the usual dice patterns, more as a number.
fn write_tokens(w: &mut String, c: Position, tokens: Tokens) -> std::fmt::Result {
    const D: f64 = 6.5;
    let dots: &[(f64, f64)] = match tokens {
        0 => &[],
        1 => &[(0.0, 0.0)],
        2 => &[(-D, 0.0), (D, 0.0)],
        3 => &[(0.0, -D), (-D, D * 0.8), (D, D * 0.8)],
        4 => &[(-D, -D), (D, -D), (-D, D), (D, D)],
        5 => &[(-D, -D), (D, -D), (0.0, 0.0), (-D, D), (D, D)],
        _ => {
            return write!(
                w,
                "<text class=\"count\" x=\"{}\" y=\"{}\">{tokens}</text>",
                n(c.x),
                n(c.y + 4.0)
            )
        }
    };
    for (dx, dy) in dots {
        write!(
            w,
            "<circle cx=\"{}\" cy=\"{}\" r=\"3.5\"/>",
            n(c.x + dx),
            n(c.y + dy)
        )?;
    }
    Ok(())
}

/// The point where a line from the centre of `node` towards `aim` leaves the node's shape.
fn clip(node: NodeRef, centre: Position, aim: Position) -> Position {
    let (dx, dy) = (aim.x - centre.x, aim.y - centre.y);
    let len = (dx * dx + dy * dy).sqrt();
    if len < 1e-9 {
        return centre;
    }
    let scale = match node {
        NodeRef::Place(_) => PLACE_R / len,
        NodeRef::Transition(_) => {
            let sx = if dx.abs() > 1e-9 {
                TRANS_HW / dx.abs()
            } else {
                f64::INFINITY
            };
            let sy = if dy.abs() > 1e-9 {
                TRANS_HH / dy.abs()
            } else {
                f64::INFINITY
            };
            sx.min(sy)
        }
    };
    // A bend point inside the node would make the clip point overshoot; stay at the aim then.
    let scale = scale.min(1.0);
    Position {
        x: centre.x + dx * scale,
        y: centre.y + dy * scale,
    }
}

/// A coordinate with at most two decimals, to keep the SVG small.
fn n(v: f64) -> String {
    let r = (v * 100.0).round() / 100.0;
    if r == 0.0 {
        "0".to_string()
    } else {
        format!("{r}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{NetBuilder, Place, Transition};

    fn small() -> Net {
        let mut b = NetBuilder::new("n");
        b.add_place(Place::new("a", 2)).unwrap();
        b.add_place(Place::new("b", 0)).unwrap();
        b.add_transition(Transition::new("t")).unwrap();
        b.add_arc("x", "a", "t", 2, ArcKind::Normal).unwrap();
        b.add_arc("y", "t", "b", 1, ArcKind::Normal).unwrap();
        b.add_arc("z", "b", "t", 3, ArcKind::Inhibitor).unwrap();
        b.build().unwrap()
    }

    #[test]
    fn layered_layout_alternates_places_and_transitions_from_the_marked_places() {
        let lay = layout(&small());
        assert_eq!(lay.places[0].x, MARGIN);
        assert_eq!(lay.transitions[0].x, MARGIN + LAYER_DX);
        assert_eq!(lay.places[1].x, MARGIN + 2.0 * LAYER_DX);
    }

    #[test]
    fn clipping_stops_at_the_rim_of_a_place() {
        let p = clip(
            NodeRef::Place(PlaceIdx(0)),
            Position { x: 0.0, y: 0.0 },
            Position { x: 100.0, y: 0.0 },
        );
        assert_eq!(p, Position { x: PLACE_R, y: 0.0 });
    }
}
