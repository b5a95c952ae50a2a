//! DOT and SVG pictures of nets, checked structurally.

use cetratus_net::export::{layout, to_dot, to_svg};
use cetratus_net::pnml;
use cetratus_testkit::nets;

#[test]
fn dot_shows_places_as_circles_with_tokens_and_weights_as_labels() {
    let net = nets::fixture("crafted/nested-pages.pnml");
    let dot = to_dot(&net, None);
    assert!(dot.starts_with("digraph \"Producer and consumer on nested pages\" {"));
    assert!(dot.contains("\"p:free\" [shape=circle, width=0.5, fixedsize=true, label=\"3\", xlabel=\"free slots\"];"), "{dot}");
    assert!(dot.contains("\"t:take\" [shape=box"), "{dot}");
    assert!(
        dot.contains("\"p:buffer\" -> \"t:take\" [label=\"2\"];"),
        "{dot}"
    );
    assert_eq!(dot.matches(" -> ").count(), 12);
    assert!(dot.trim_end().ends_with('}'));
}

#[test]
fn dot_marks_inhibitor_arcs_with_an_odot_head() {
    let dot = to_dot(&nets::fixture("pipe5/inhibitorArc.xml"), None);
    assert!(
        dot.contains("\"p:P0\" -> \"t:T0\" [arrowhead=odot];"),
        "{dot}"
    );
}

#[test]
fn dot_shows_the_given_marking_instead_of_the_initial_one() {
    let net = nets::fixture("pipe5/simpleNet.xml");
    let dot = to_dot(&net, Some(&[0, 7]));
    assert!(
        dot.contains("\"p:P1\" [shape=circle, width=0.5, fixedsize=true, label=\"7\""),
        "{dot}"
    );
    assert!(
        dot.contains("\"p:P0\" [shape=circle, width=0.5, fixedsize=true, label=\"\""),
        "{dot}"
    );
}

#[test]
fn dot_escapes_quotes_in_names() {
    let net = pnml::read_str(
        "<pnml><net id='n'><place id='p\"q'><name><value>a \"b\" \\ c</value></name></place></net></pnml>",
        "q.xml",
    )
    .expect("reads");
    let dot = to_dot(&net, None);
    assert!(dot.contains("\"p:p\\\"q\""), "{dot}");
    assert!(dot.contains("xlabel=\"a \\\"b\\\" \\\\ c\""), "{dot}");
}

#[test]
fn svg_of_every_fixture_is_well_formed_and_names_every_node() {
    for rel in [
        "pipe/ClassicGSPN.xml",
        "pipe/DiningPhilosophers.xml",
        "pipe5/inhibitorArc.xml",
        "mcc/Philosophers-PT-000005.pnml",
        "mcc/TokenRing-PT-005.pnml",
        "mcc/FMS-PT-00002.pnml",
        "crafted/nested-pages.pnml",
    ] {
        let net = nets::fixture(rel);
        let svg = to_svg(&net, None);
        let doc = roxmltree::Document::parse(&svg).unwrap_or_else(|e| panic!("{rel}: {e}\n{svg}"));
        for (i, p) in net.places().iter().enumerate() {
            let id = format!("place-{}", p.id);
            let g = doc
                .descendants()
                .find(|n| n.attribute("id") == Some(id.as_str()))
                .unwrap_or_else(|| panic!("{rel}: no {id}"));
            let tokens = net.initial_marking().0[i].to_string();
            assert_eq!(
                g.attribute("data-tokens"),
                Some(tokens.as_str()),
                "{rel} {id}"
            );
        }
        for t in net.transitions() {
            let id = format!("trans-{}", t.id);
            assert!(
                doc.descendants()
                    .any(|n| n.attribute("id") == Some(id.as_str())),
                "{rel}: no {id}"
            );
        }
        let arcs = doc
            .descendants()
            .filter(|n| {
                n.has_tag_name("path") && n.attribute("class").is_some_and(|c| c.starts_with("arc"))
            })
            .count();
        assert_eq!(arcs, net.arcs().len(), "{rel}");
    }
}

#[test]
fn svg_draws_tokens_as_dots_or_a_count_and_inhibitors_with_a_circle() {
    let net = nets::fixture("pipe5/inhibitorArc.xml");
    let svg = to_svg(&net, Some(&[9]));
    assert!(svg.contains("data-tokens=\"9\""));
    assert!(svg.contains("<text class=\"count\""), "{svg}");
    assert!(
        svg.contains("marker-end=\"url(#cetratus-inhibitor)\""),
        "{svg}"
    );
    let svg = to_svg(&net, Some(&[3]));
    let tokens = svg
        .split("<g class=\"tokens\">")
        .nth(1)
        .and_then(|s| s.split("</g>").next())
        .unwrap_or("");
    assert_eq!(tokens.matches("<circle").count(), 3, "{svg}");
}

#[test]
fn svg_labels_weights_above_one() {
    let svg = to_svg(&nets::fixture("crafted/nested-pages.pnml"), None);
    assert_eq!(svg.matches("<text class=\"weight\"").count(), 2, "{svg}");
}

#[test]
fn file_positions_are_used_when_every_node_has_a_distinct_one() {
    let net = nets::fixture("pipe/ClassicGSPN.xml");
    let lay = layout(&net);
    for (p, at) in net.places().iter().zip(&lay.places) {
        assert_eq!(Some(*at), p.position);
    }
}

#[test]
fn a_layout_is_computed_when_the_file_stacks_every_node_on_one_spot() {
    // The contest's Philosophers file puts every node at (100, 100).
    let net = nets::fixture("mcc/Philosophers-PT-000005.pnml");
    let lay = layout(&net);
    let mut spots: Vec<(i64, i64)> = lay
        .places
        .iter()
        .chain(&lay.transitions)
        .map(|p| (p.x as i64, p.y as i64))
        .collect();
    spots.sort_unstable();
    spots.dedup();
    assert_eq!(spots.len(), net.num_places() + net.num_transitions());
}

#[test]
fn a_net_without_positions_gets_a_layout_too() {
    let net = nets::fixture("crafted/nested-pages.pnml");
    let lay = layout(&net);
    assert_eq!(lay.places.len(), 6);
    assert_eq!(lay.transitions.len(), 4);
    // Marked places start the first column; transitions never share a column with places.
    let free = net.place_by_id("free").unwrap().index();
    let min_x = lay.places.iter().map(|p| p.x).fold(f64::INFINITY, f64::min);
    assert_eq!(lay.places[free].x, min_x);
    for t in &lay.transitions {
        assert!(lay.places.iter().all(|p| p.x != t.x));
    }
}
