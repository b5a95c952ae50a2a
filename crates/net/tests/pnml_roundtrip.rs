//! parse ∘ print = id: any net Cetratus can build survives PNML writing and reading, order included.

use cetratus_net::{
    pnml, xml_escape, ArcKind, Net, NetBuilder, Place, Position, ToolSpecific, Transition,
};
use proptest::prelude::*;

/// Text with the characters XML must escape, and spaces and newlines inside.
fn label() -> impl Strategy<Value = String> {
    "[a-zA-Z0-9_<>&\"' \n\t\r-]{0,10}"
}

fn position() -> impl Strategy<Value = Option<Position>> {
    prop::option::of((-1.0e6..1.0e6f64, -1.0e6..1.0e6f64).prop_map(|(x, y)| Position { x, y }))
}

fn toolspecific() -> impl Strategy<Value = Vec<ToolSpecific>> {
    prop::collection::vec(("[a-z]{1,8}", "[0-9.]{1,4}", label()), 0..3).prop_map(|v| {
        v.into_iter()
            .map(|(tool, version, data)| ToolSpecific {
                xml: format!(
                    "<toolspecific tool=\"{tool}\" version=\"{version}\">\n  <data v=\"{}\">{}</data>\n</toolspecific>",
                    xml_escape(&data),
                    xml_escape(&data)
                ),
                tool,
                version,
            })
            .collect()
    })
}

#[derive(Debug, Clone)]
struct Spec {
    name: Option<String>,
    toolspecific: Vec<ToolSpecific>,
    places: Vec<Place>,
    transitions: Vec<Transition>,
    /// (place, transition, direction: 0 in, 1 out, 2 inhibitor, weight, bend points)
    arcs: Vec<(usize, usize, u8, u32, Vec<Position>)>,
}

fn spec() -> impl Strategy<Value = Spec> {
    let place = (
        prop::option::of(label()),
        prop_oneof![0u32..6, Just(u32::MAX), any::<u32>()],
        prop::option::of(0u32..4),
        position(),
        toolspecific(),
        label(),
    );
    let transition = (
        prop::option::of(label()),
        any::<i32>(),
        position(),
        toolspecific(),
        label(),
    );
    let point = (-1.0e4..1.0e4f64, -1.0e4..1.0e4f64).prop_map(|(x, y)| Position { x, y });
    let arc = (
        any::<usize>(),
        any::<usize>(),
        0u8..3,
        1u32..12,
        prop::collection::vec(point, 0..3),
    );
    (
        prop::option::of(label()),
        toolspecific(),
        prop::collection::vec(place, 1..8),
        prop::collection::vec(transition, 1..8),
        prop::collection::vec(arc, 0..20),
    )
        .prop_map(|(name, toolspecific, places, transitions, arcs)| Spec {
            name,
            toolspecific,
            // The index before the first `-` keeps ids unique whatever the random suffix is.
            places: places
                .into_iter()
                .enumerate()
                .map(
                    |(i, (name, initial, extra, position, toolspecific, suffix))| Place {
                        id: format!("p{i}-{suffix}"),
                        name,
                        initial,
                        // A capacity is at least the initial marking, or the builder refuses the place.
                        capacity: extra.map(|e| initial.saturating_add(e)),
                        position,
                        toolspecific,
                    },
                )
                .collect(),
            transitions: transitions
                .into_iter()
                .enumerate()
                .map(
                    |(i, (name, priority, position, toolspecific, suffix))| Transition {
                        id: format!("t{i}-{suffix}"),
                        name,
                        priority,
                        position,
                        toolspecific,
                    },
                )
                .collect(),
            arcs,
        })
}

fn build(spec: &Spec) -> Net {
    let mut b = NetBuilder::new("net <&> 'id'");
    if let Some(name) = &spec.name {
        b.name(name.clone());
    }
    for ts in &spec.toolspecific {
        b.toolspecific(ts.clone());
    }
    for p in &spec.places {
        b.add_place(p.clone()).expect("generated places are valid");
    }
    for t in &spec.transitions {
        b.add_transition(t.clone())
            .expect("generated transitions are valid");
    }
    for (i, (p, t, dir, weight, path)) in spec.arcs.iter().enumerate() {
        let p = &spec.places[p % spec.places.len()].id;
        let t = &spec.transitions[t % spec.transitions.len()].id;
        let id = format!("a{i} <\"&\">");
        let idx = match dir {
            0 => b.add_arc(&id, p, t, *weight, ArcKind::Normal),
            1 => b.add_arc(&id, t, p, *weight, ArcKind::Normal),
            _ => b.add_arc(&id, p, t, *weight, ArcKind::Inhibitor),
        }
        .expect("generated arcs are valid");
        b.set_arc_path(idx, path.clone());
    }
    b.build().expect("generated nets are valid")
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn pnml_round_trip_is_the_identity(spec in spec()) {
        let net = build(&spec);
        let text = pnml::write_string(&net);
        let again = pnml::read_str(&text, "prop.pnml");
        prop_assert!(again.is_ok(), "{:?}\n{}", again.err(), text);
        let again = again.unwrap();
        prop_assert_eq!(&again, &net);
        prop_assert_eq!(pnml::write_string(&again), text);
    }
}
