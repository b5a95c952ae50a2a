//! PNML reading and writing seen from outside: the shared fixtures, round trips, and bad input.

use std::collections::{HashMap, VecDeque};
use std::path::Path;

use cetratus_net::{pnml, ArcKind, Net, NetError, NodeRef, Tokens, TransIdx};
use cetratus_testkit::{nets, paths};

/// Every fixture with its places, transitions, arcs, and the README's reachable states and edges.
const ALL: &[(&str, usize, usize, usize, usize, usize)] = &[
    ("pipe/ClassicGSPN.xml", 3, 3, 6, 6, 9),
    ("pipe/DiningPhilosophers.xml", 15, 10, 40, 11, 30),
    ("pipe/ProducerConsumer.xml", 8, 6, 16, 36, 66),
    ("pipe/ReadersWriters.xml", 5, 4, 12, 5, 8),
    ("pipe5/simpleNet.xml", 2, 1, 2, 3, 2),
    ("pipe5/petriNet.xml", 2, 1, 2, 2, 1),
    ("pipe5/inhibitorArc.xml", 1, 1, 1, 1, 1),
    ("mcc/Philosophers-PT-000005.pnml", 25, 25, 80, 243, 945),
    ("mcc/TokenRing-PT-005.pnml", 36, 156, 624, 166, 365),
    ("mcc/FMS-PT-00002.pnml", 22, 20, 50, 3444, 16311),
    ("crafted/nested-pages.pnml", 6, 4, 12, 12, 18),
];

fn marking_of(net: &Net, id: &str) -> Tokens {
    let p = net
        .place_by_id(id)
        .unwrap_or_else(|| panic!("no place {id}"));
    net.place(p).initial
}

/// Reachable states and edges of the plain interleaving semantics, as the fixtures README counts them.
fn state_space(net: &Net) -> (usize, usize) {
    let m0 = net.initial_marking().0;
    let mut seen: HashMap<Vec<Tokens>, ()> = HashMap::new();
    seen.insert(m0.clone(), ());
    let mut queue = VecDeque::from([m0]);
    let mut edges = 0;
    while let Some(m) = queue.pop_front() {
        for t in 0..net.num_transitions() {
            let t = TransIdx(t as u32);
            if !net.is_enabled(t, &m) {
                continue;
            }
            edges += 1;
            let mut next = m.clone();
            for &(p, d) in net.delta(t) {
                next[p.index()] = (i64::from(next[p.index()]) + d) as Tokens;
            }
            if seen.insert(next.clone(), ()).is_none() {
                queue.push_back(next);
            }
        }
    }
    (seen.len(), edges)
}

fn arc<'n>(net: &'n Net, id: &str) -> &'n cetratus_net::Arc {
    net.arcs()
        .iter()
        .find(|a| a.id == id)
        .unwrap_or_else(|| panic!("no arc {id}"))
}

fn syntax(err: NetError) -> (cetratus_net::SourcePos, String) {
    match err {
        NetError::Syntax { pos, message } => (pos, message),
        other => panic!("expected a syntax error, got {other:?}"),
    }
}

#[test]
fn every_fixture_reads_with_the_expected_size() {
    for &(rel, places, transitions, arcs, _, _) in ALL {
        let net = nets::fixture(rel);
        assert_eq!(net.num_places(), places, "{rel} places");
        assert_eq!(net.num_transitions(), transitions, "{rel} transitions");
        assert_eq!(net.arcs().len(), arcs, "{rel} arcs");
    }
}

#[test]
fn every_fixture_has_the_state_space_the_readme_gives() {
    for &(rel, _, _, _, states, edges) in ALL {
        assert_eq!(state_space(&nets::fixture(rel)), (states, edges), "{rel}");
    }
}

#[test]
fn every_fixture_survives_a_write_read_round_trip() {
    for &(rel, ..) in ALL {
        let net = nets::fixture(rel);
        let text = pnml::write_string(&net);
        let again = pnml::read_str(&text, "round-trip.pnml")
            .unwrap_or_else(|e| panic!("{rel}: written PNML does not read back: {e}\n{text}"));
        assert_eq!(again, net, "{rel}");
        assert_eq!(
            pnml::write_string(&again),
            text,
            "{rel}: writing is not stable"
        );
    }
}

#[test]
fn writing_to_a_file_and_reading_it_back_gives_the_same_net() {
    let net = nets::fixture("crafted/nested-pages.pnml");
    let path = std::env::temp_dir().join(format!("cetratus-net-{}.pnml", std::process::id()));
    pnml::write_file(&net, &path).expect("temp file is writable");
    let again = pnml::read_file(&path);
    let _ = std::fs::remove_file(&path);
    assert_eq!(again.expect("written file reads back"), net);
}

#[test]
fn nested_pages_flatten_in_document_order() {
    let net = nets::fixture("crafted/nested-pages.pnml");
    let places: Vec<&str> = net.places().iter().map(|p| p.id.as_str()).collect();
    assert_eq!(
        places,
        ["buffer", "free", "ready_p", "busy_p", "ready_c", "busy_c"]
    );
    let transitions: Vec<&str> = net.transitions().iter().map(|t| t.id.as_str()).collect();
    assert_eq!(transitions, ["produce", "deliver", "take", "consume"]);
    let arcs: Vec<&str> = net.arcs().iter().map(|a| a.id.as_str()).collect();
    assert_eq!(
        arcs,
        ["a1", "a2", "a3", "a4", "a5", "a6", "b1", "b2", "b3", "b4", "b5", "b6"]
    );
    assert_eq!(net.name(), Some("Producer and consumer on nested pages"));
    assert_eq!(net.initial_marking().0, vec![0, 3, 1, 0, 1, 0]);
    assert_eq!(
        net.place(net.place_by_id("free").unwrap()).name.as_deref(),
        Some("free slots")
    );
}

#[test]
fn reference_nodes_resolve_through_chains_to_the_real_node() {
    let net = nets::fixture("crafted/nested-pages.pnml");
    let buffer = NodeRef::Place(net.place_by_id("buffer").unwrap());
    let take = NodeRef::Transition(net.transition_by_id("take").unwrap());
    // buf_ref_c -> buf_ref_p -> buffer, and take_ref -> take.
    let b2 = arc(&net, "b2");
    assert_eq!((b2.source, b2.target, b2.weight), (buffer, take, 2));
    let a6 = arc(&net, "a6");
    assert_eq!(a6.target, buffer);
    let free = NodeRef::Place(net.place_by_id("free").unwrap());
    assert_eq!(arc(&net, "b6").target, free);
    assert_eq!(arc(&net, "b6").weight, 2);
}

#[test]
fn pipe_inhibitor_arc_with_empty_inscription_has_weight_one() {
    let net = nets::fixture("pipe5/inhibitorArc.xml");
    let a = &net.arcs()[0];
    assert_eq!(a.kind, ArcKind::Inhibitor);
    assert_eq!(a.weight, 1);
    assert_eq!(net.inhibitors(TransIdx(0)).len(), 1);
    // PIPE's capacity 0 means unbounded.
    assert_eq!(net.places()[0].capacity, None);
    assert_eq!(net.transitions()[0].priority, 1);
}

#[test]
fn pipe5_default_token_class_counts_are_read_as_plain_counts() {
    let net = nets::fixture("pipe5/petriNet.xml");
    assert_eq!(net.initial_marking().0, vec![1, 0]);
    assert!(net
        .arcs()
        .iter()
        .all(|a| a.weight == 1 && a.kind == ArcKind::Normal));
    assert_eq!(net.places()[0].capacity, None);
    let p0 = net.places()[0].position.expect("P0 is placed");
    assert_eq!((p0.x, p0.y), (225.0, 240.0));
}

#[test]
fn pipe_markings_and_arc_bend_points_are_kept() {
    let net = nets::fixture("pipe/ProducerConsumer.xml");
    assert_eq!(marking_of(&net, "P0"), 1);
    assert_eq!(marking_of(&net, "P7"), 3);
    let simple = nets::fixture("pipe5/simpleNet.xml");
    assert_eq!(simple.initial_marking().0, vec![2, 0]);
    // Two arcpath points are the two ends, so there is no bend.
    assert!(simple.arcs().iter().all(|a| a.path.is_empty()));
    let dining = nets::fixture("pipe/DiningPhilosophers.xml");
    assert!(dining.arcs().iter().any(|a| !a.path.is_empty()));
}

#[test]
fn iso_markings_positions_and_arc_paths_are_kept() {
    let net = nets::fixture("mcc/Philosophers-PT-000005.pnml");
    assert_eq!(marking_of(&net, "Think_1"), 1);
    assert_eq!(marking_of(&net, "Fork_5"), 1);
    assert_eq!(marking_of(&net, "Eat_1"), 0);
    assert_eq!(net.initial_marking().total(), 10);
    let fms = nets::fixture("mcc/FMS-PT-00002.pnml");
    assert_eq!(fms.name(), Some("FMS-PT-00002"));
    let bent = arc(&fms, "cId1090461383811578710155");
    assert_eq!(bent.path.len(), 2);
    assert_eq!((bent.path[1].x, bent.path[1].y), (689.0, 438.0));
}

#[test]
fn net_level_toolspecific_is_kept_verbatim() {
    let net = nets::fixture("mcc/Philosophers-PT-000005.pnml");
    let ts = net.toolspecific();
    assert_eq!(ts.len(), 1);
    assert_eq!(
        (ts[0].tool.as_str(), ts[0].version.as_str()),
        ("nupn", "1.1")
    );
    assert!(ts[0].xml.starts_with("<toolspecific tool=\"nupn\""));
    assert!(ts[0].xml.ends_with("</toolspecific>"));
    assert!(ts[0]
        .xml
        .contains("<places>Fork_1 Catch1_2 Catch2_1 Eat_1 Eat_2</places>"));
}

#[test]
fn latin1_bytes_are_decoded_rather_than_rejected() {
    let text = "<?xml version=\"1.0\" encoding=\"ISO-8859-1\"?><pnml><net id=\"n\">\
        <place id=\"P0\"><name><value>caf\u{e9}</value></name><initialMarking><value>Default,2</value></initialMarking></place>\
        </net></pnml>";
    let bytes: Vec<u8> = text.chars().map(|c| c as u8).collect();
    let net = pnml::read_bytes(&bytes, "latin1.xml").expect("latin-1 reads");
    assert_eq!(net.places()[0].name.as_deref(), Some("caf\u{e9}"));
    assert_eq!(net.places()[0].initial, 2);
}

#[test]
fn capacities_priorities_and_inhibitors_survive_in_cetratus_toolspecific() {
    let text = r#"<pnml><net id="n">
      <place id="p"><initialMarking><value>Default,1</value></initialMarking><capacity><value>4</value></capacity></place>
      <transition id="t"><priority><value>-3</value></priority></transition>
      <arc id="a" source="p" target="t"><inscription><value>Default,2</value></inscription><type value="inhibitor"/></arc>
    </net></pnml>"#;
    let net = pnml::read_str(text, "caps.xml").expect("reads");
    assert_eq!(net.places()[0].capacity, Some(4));
    assert_eq!(net.transitions()[0].priority, -3);
    assert_eq!(
        (net.arcs()[0].kind, net.arcs()[0].weight),
        (ArcKind::Inhibitor, 2)
    );
    let written = pnml::write_string(&net);
    assert!(written.contains(
        r#"<toolspecific tool="cetratus" version="1"><capacity>4</capacity></toolspecific>"#
    ));
    assert!(written.contains("<arcType>inhibitor</arcType>"));
    let again = pnml::read_str(&written, "again.pnml").expect("reads back");
    assert_eq!(again, net);
    assert!(again.places()[0].toolspecific.is_empty());
}

#[test]
fn dialects_are_told_apart_by_namespace() {
    let iso = std::fs::read_to_string(paths::fixture("mcc/FMS-PT-00002.pnml")).unwrap();
    let pipe = std::fs::read_to_string(paths::fixture("pipe5/simpleNet.xml")).unwrap();
    assert_eq!(pnml::detect_dialect(&iso), Some(pnml::Dialect::Iso));
    assert_eq!(pnml::detect_dialect(&pipe), Some(pnml::Dialect::Pipe));
    assert_eq!(pnml::detect_dialect("<pnml"), None);
}

// ---- malformed input: every error names file:line:column and the problem ----

fn error_of(text: &str) -> (String, cetratus_net::SourcePos, String) {
    let err = pnml::read_str(text, "bad.pnml").expect_err("input is malformed");
    let shown = err.to_string();
    let (pos, message) = syntax(err);
    (shown, pos, message)
}

const ISO_HEAD: &str = "<pnml xmlns=\"http://www.pnml.org/version-2009/grammar/pnml\">\n<net id=\"n\" type=\"http://www.pnml.org/version-2009/grammar/ptnet\">\n<page id=\"pg\">\n";
const ISO_TAIL: &str = "</page>\n</net>\n</pnml>\n";

fn iso(body: &str) -> String {
    format!("{ISO_HEAD}{body}{ISO_TAIL}")
}

#[test]
fn bad_xml_is_reported_with_its_position() {
    let (shown, pos, message) = error_of("<pnml>\n  <net id=\"n\">\n  </nett>\n</pnml>");
    assert_eq!((pos.line, pos.column), (3, 3));
    assert!(shown.starts_with("bad.pnml:3:3: "), "{shown}");
    assert!(message.contains("not well-formed XML"), "{message}");
}

#[test]
fn an_arc_between_two_places_is_reported_at_the_arc() {
    let (shown, pos, message) = error_of(&iso(
        "<place id=\"p\"/>\n<place id=\"q\"/>\n<arc id=\"a\" source=\"p\" target=\"q\"/>\n",
    ));
    assert_eq!((pos.line, pos.column), (6, 1));
    assert!(shown.starts_with("bad.pnml:6:1: "), "{shown}");
    assert!(message.contains("two places"), "{message}");
}

#[test]
fn an_unknown_node_id_is_reported_at_the_arc() {
    let (shown, pos, message) = error_of(&iso(
        "<place id=\"p\"/>\n<transition id=\"t\"/>\n  <arc id=\"a\" source=\"p\" target=\"ghost\"/>\n",
    ));
    assert_eq!((pos.line, pos.column), (6, 3));
    assert!(shown.contains("bad.pnml:6:3"), "{shown}");
    assert!(message.contains("unknown node `ghost`"), "{message}");
}

#[test]
fn a_negative_count_is_reported_at_its_label() {
    let (shown, pos, message) = error_of(&iso(
        "<place id=\"p\">\n<initialMarking><text>-2</text></initialMarking></place>\n",
    ));
    assert_eq!((pos.line, pos.column), (5, 17));
    assert!(shown.starts_with("bad.pnml:5:17: "), "{shown}");
    assert!(
        message.contains("initial marking `-2` is negative"),
        "{message}"
    );
}

#[test]
fn a_non_numeric_weight_is_reported_with_what_to_write() {
    let (_, pos, message) = error_of(&iso(
        "<place id=\"p\"/>\n<transition id=\"t\"/>\n<arc id=\"a\" source=\"p\" target=\"t\"><inscription><text>two</text></inscription></arc>\n",
    ));
    assert_eq!(pos.line, 6);
    assert!(
        message.contains("arc weight `two` is not a number"),
        "{message}"
    );
    assert!(message.contains("whole number"), "{message}");
}

#[test]
fn a_zero_weight_is_reported_at_the_arc() {
    let (_, pos, message) = error_of(&iso(
        "<place id=\"p\"/>\n<transition id=\"t\"/>\n<arc id=\"a\" source=\"p\" target=\"t\"><inscription><text>0</text></inscription></arc>\n",
    ));
    assert_eq!((pos.line, pos.column), (6, 1));
    assert!(message.contains("weight 0"), "{message}");
}

#[test]
fn a_duplicate_id_names_both_declarations() {
    let (shown, pos, message) = error_of(&iso("<place id=\"p\"/>\n<transition id=\"p\"/>\n"));
    assert_eq!((pos.line, pos.column), (5, 1));
    assert!(shown.starts_with("bad.pnml:5:1: "), "{shown}");
    assert!(message.contains("duplicate id `p`"), "{message}");
    assert!(
        message.contains("first declared at bad.pnml:4:1"),
        "{message}"
    );
}

#[test]
fn a_file_without_a_net_says_so() {
    let (shown, pos, message) = error_of("<?xml version=\"1.0\"?>\n<pnml>\n</pnml>\n");
    assert_eq!((pos.line, pos.column), (2, 1));
    assert!(shown.starts_with("bad.pnml:2:1: "), "{shown}");
    assert!(message.contains("missing <net>"), "{message}");
}

#[test]
fn a_reference_cycle_is_reported() {
    let (_, pos, message) = error_of(&iso(
        "<referencePlace id=\"r1\" ref=\"r2\"/>\n<referencePlace id=\"r2\" ref=\"r1\"/>\n",
    ));
    assert_eq!(pos.line, 4);
    assert!(
        message.contains("reference cycle `r1` -> `r2` -> `r1`"),
        "{message}"
    );
}

#[test]
fn a_reference_to_a_missing_node_is_reported() {
    let (_, pos, message) = error_of(&iso("<referencePlace id=\"r\" ref=\"nowhere\"/>\n"));
    assert_eq!((pos.line, pos.column), (4, 1));
    assert!(
        message.contains("`nowhere`, which is not declared"),
        "{message}"
    );
}

#[test]
fn a_reference_place_to_a_transition_is_reported() {
    let (_, _, message) = error_of(&iso(
        "<transition id=\"t\"/>\n<referencePlace id=\"r\" ref=\"t\"/>\n",
    ));
    assert!(message.contains("must refer to a place"), "{message}");
}

#[test]
fn references_may_point_forward_in_the_document() {
    let net = pnml::read_str(
        &iso(
            "<arc id=\"a\" source=\"r\" target=\"t\"/>\n<referencePlace id=\"r\" ref=\"r0\"/>\n<referencePlace id=\"r0\" ref=\"p\"/>\n<transition id=\"t\"/>\n<place id=\"p\"/>\n",
        ),
        "fwd.pnml",
    )
    .expect("forward references resolve");
    assert_eq!(
        net.arcs()[0].source,
        NodeRef::Place(net.place_by_id("p").unwrap())
    );
}

#[test]
fn an_unsupported_pipe_arc_type_is_reported() {
    let (_, _, message) = error_of(
        "<pnml><net id=\"n\"><place id=\"p\"/><transition id=\"t\"/>\
         <arc id=\"a\" source=\"p\" target=\"t\"><type value=\"reset\"/></arc></net></pnml>",
    );
    assert!(
        message.contains("arc type `reset` is not supported"),
        "{message}"
    );
}

#[test]
fn an_initial_marking_over_capacity_is_reported_at_the_place() {
    let (shown, pos, _) = error_of(
        "<pnml><net id=\"n\">\n<place id=\"p\"><initialMarking><value>3</value></initialMarking><capacity><value>2</value></capacity></place></net></pnml>",
    );
    assert_eq!((pos.line, pos.column), (2, 1));
    assert!(shown.contains("capacity is 2"), "{shown}");
}

#[test]
fn a_missing_file_is_an_io_error_naming_the_path() {
    let err = pnml::read_file(Path::new("no/such/file.pnml")).expect_err("missing");
    assert!(matches!(err, NetError::Io { .. }));
    assert!(err.to_string().contains("no/such/file.pnml"));
}

#[test]
fn garbage_never_panics() {
    let samples = [
        "",
        "<",
        "<pnml/>",
        "<foo/>",
        "<pnml><net/></pnml>",
        "<pnml><net id='n'><place/></net></pnml>",
        "<pnml><net id='n'><arc id='a'/></net></pnml>",
        "<pnml><net id='n'><place id='p'><graphics><position x='a' y='1'/></graphics></place></net></pnml>",
        "<pnml><net id='n'><place id='p'><graphics><position/></graphics></place></net></pnml>",
        "<pnml><net id='n'><transition id='t'><priority><value>x</value></priority></transition></net></pnml>",
        "<pnml><net id='n'><place id='p'><initialMarking><value>Default</value></initialMarking></place></net></pnml>",
        "<pnml><net id='n'><place id='p'><initialMarking><value>99999999999</value></initialMarking></place></net></pnml>",
        "<pnml><net id='a'/><net id='b'/></pnml>",
        "<pnml><net id='n'><referenceTransition id='r' ref='r'/></net></pnml>",
    ];
    for s in samples {
        match pnml::read_str(s, "g.pnml") {
            Err(NetError::Syntax { pos, message }) => {
                assert!(pos.line >= 1 && pos.column >= 1, "{s}");
                assert!(!message.is_empty());
            }
            Err(other) => panic!("{s}: unexpected {other:?}"),
            Ok(net) => assert!(s.contains("<net"), "{s} read as {net:?}"),
        }
    }
}
