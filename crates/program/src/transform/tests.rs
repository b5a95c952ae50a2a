//! Unit tests of `transform`.

use super::*;
use cetratus_net::{NetBuilder, Place};

fn net(places: &[(&str, Tokens)]) -> Net {
    let mut b = NetBuilder::new("n");
    for &(id, m) in places {
        b.add_place(Place::new(id, m))
            .unwrap_or_else(|e| panic!("{e}"));
    }
    b.build().unwrap_or_else(|e| panic!("{e}"))
}

fn program(places: &[(&str, Tokens)], invariants: &[&str]) -> Program {
    let mut src = String::from("[program]\nname = \"t\"\nversion = \"1\"\n");
    for i in invariants {
        src.push_str(&format!("[[invariant]]\nexpr = \"{i}\"\n"));
    }
    Program::from_sources(&src, "t.toml", net(places)).unwrap_or_else(|e| panic!("{e}"))
}

fn s(v: &[&str]) -> Vec<String> {
    v.iter().map(|x| x.to_string()).collect()
}

#[test]
fn generated_keeps_kept_places_and_starts_new_ones_at_their_initial_marking() {
    let old = program(&[("A", 1), ("B", 0)], &[]);
    let new = program(&[("B", 0), ("C", 2), ("A", 1)], &[]);
    let st =
        StateTransform::generated(&old, &new, &BTreeMap::new()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!((st.rows(), st.cols()), (3, 2));
    let mut out = [0; 3];
    st.apply(&[5, 7], &new, &mut out)
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(out, [7, 2, 5]);
}

#[test]
fn a_removed_place_with_tokens_and_no_destination_is_refused_by_name() {
    let old = program(&[("A", 1), ("X", 0)], &[]);
    let new = program(&[("A", 1)], &[]);
    let st =
        StateTransform::generated(&old, &new, &BTreeMap::new()).unwrap_or_else(|e| panic!("{e}"));
    let mut out = [9];
    let err = st.apply(&[1, 2], &new, &mut out).unwrap_err();
    assert!(err.to_string().contains("`X`"), "{err}");
    assert_eq!(out, [9], "nothing written");
    st.apply(&[1, 0], &new, &mut out)
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(out, [1]);
}

#[test]
fn a_removed_place_sends_its_tokens_where_the_package_says() {
    let old = program(&[("A", 1), ("X", 0)], &[]);
    let new = program(&[("A", 1)], &[]);
    let removed = BTreeMap::from([("X".to_string(), "A".to_string())]);
    let st = StateTransform::generated(&old, &new, &removed).unwrap_or_else(|e| panic!("{e}"));
    let mut out = [0];
    st.apply(&[1, 2], &new, &mut out)
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(out, [3]);
}

#[test]
fn removed_must_name_a_place_that_is_really_removed() {
    let old = program(&[("A", 1), ("X", 0)], &[]);
    let new = program(&[("A", 1)], &[]);
    let kept = BTreeMap::from([("A".to_string(), "A".to_string())]);
    assert!(matches!(
        StateTransform::generated(&old, &new, &kept),
        Err(TransformError::RemovedIsKept { .. })
    ));
    let nowhere = BTreeMap::from([("X".to_string(), "Z".to_string())]);
    assert!(matches!(
        StateTransform::generated(&old, &new, &nowhere),
        Err(TransformError::RemovedTargetUnknown { .. })
    ));
    let unknown = BTreeMap::from([("Q".to_string(), "A".to_string())]);
    assert!(matches!(
        StateTransform::generated(&old, &new, &unknown),
        Err(TransformError::RemovedUnknown { .. })
    ));
}

#[test]
fn sparse_refuses_unknown_places_and_duplicates() {
    let old = net(&[("A", 0)]);
    let new = net(&[("A", 0), ("B", 0)]);
    let e = |t: &str, f: &str| (t.to_string(), f.to_string(), 1);
    let none = BTreeMap::new();
    let err = StateTransform::sparse(&old, &new, &[e("Z", "A")], &none).unwrap_err();
    assert!(err.to_string().contains("`Z`") && err.to_string().contains("new net"));
    let err = StateTransform::sparse(&old, &new, &[e("A", "B")], &none).unwrap_err();
    assert!(err.to_string().contains("`B`") && err.to_string().contains("running"));
    let err = StateTransform::sparse(&old, &new, &[e("A", "A"), e("A", "A")], &none);
    assert!(matches!(err, Err(TransformError::DuplicateEntry { .. })));
    let bad_base = BTreeMap::from([("Q".to_string(), 1)]);
    assert!(StateTransform::sparse(&old, &new, &[], &bad_base).is_err());
}

#[test]
fn timers_of_kept_places_carry_over_and_new_marked_places_start_now() {
    let old = program(&[("A", 1), ("B", 0)], &[]);
    let new = program(&[("A", 1), ("N", 1), ("B", 0)], &[]);
    let st =
        StateTransform::generated(&old, &new, &BTreeMap::new()).unwrap_or_else(|e| panic!("{e}"));
    let mut m = [0; 3];
    st.apply(&[1, 0], &new, &mut m)
        .unwrap_or_else(|e| panic!("{e}"));
    let mut since = [Some(7); 3];
    st.apply_timers(&[Some(100), None], &m, 500, &mut since);
    assert_eq!(since, [Some(100), Some(500), None]);
}

#[test]
fn the_dense_form_prints_aligned_with_place_ids() {
    let old = net(&[("A", 0), ("LONG", 0)]);
    let new = net(&[("A", 0)]);
    let st = StateTransform::dense(
        &old,
        &new,
        &s(&["A"]),
        &s(&["A", "LONG"]),
        &[vec![1, -12]],
        &[3],
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let text = st.to_dense().to_string();
    assert_eq!(text, "  A LONG | base\nA 1  -12 |    3\n");
}

#[test]
fn drift_counts_every_token_of_difference() {
    let old = net(&[("A", 0), ("B", 0)]);
    let new = net(&[("B", 0), ("C", 0)]);
    let pi = Projection::generated(&old, &new).expect("projection");
    assert_eq!((pi.rows(), pi.cols()), (2, 2));
    // A reads nothing (0 vs 2), B reads B (1 vs 4).
    assert_eq!(pi.drift(&[1, 9], &[2, 4]), 5);
    assert_eq!(pi.drift(&[4, 9], &[0, 4]), 0);
}

#[test]
fn a_projection_gives_the_old_program_a_marking_and_its_timers_back_by_place_id() {
    let old = program(&[("A", 1), ("B", 0)], &["A + B = 1"]);
    let new = program(&[("B", 0), ("C", 0), ("A", 1)], &["A + B + C = 1"]);
    let proj = Projection::sparse(
        old.net(),
        new.net(),
        &[
            ("A".into(), "A".into(), 1),
            ("B".into(), "B".into(), 1),
            ("B".into(), "C".into(), 1),
        ],
        &BTreeMap::new(),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let mut out = [9; 2];
    proj.apply(&[0, 1, 0], &old, &mut out)
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(out, [0, 1], "C is projected onto B");
    let mut since = [None; 2];
    proj.apply_timers(&[None, Some(40), None], &out, 100, &mut since);
    assert_eq!(
        since,
        [None, Some(100)],
        "B was empty in the new net: its timer starts now"
    );
    proj.apply(&[1, 0, 0], &old, &mut out)
        .unwrap_or_else(|e| panic!("{e}"));
    proj.apply_timers(&[Some(40), None, None], &out, 100, &mut since);
    assert_eq!(since, [None, Some(40)], "B keeps the timer of B");
}

#[test]
fn a_projection_that_breaks_an_invariant_of_the_old_program_is_refused_and_writes_nothing() {
    let old = program(&[("A", 1), ("B", 0)], &["A + B = 1"]);
    let new = program(&[("A", 1), ("B", 0), ("C", 0)], &[]);
    let proj = Projection::generated(old.net(), new.net()).expect("projection");
    let mut out = [7; 2];
    let e = proj
        .apply(&[1, 1, 0], &old, &mut out)
        .expect_err("A + B = 2 breaks the old invariant");
    assert!(e.to_string().contains("A + B"), "{e}");
    assert_eq!(out, [7, 7]);
}

/// A program whose net has `places` and the transitions `(id, from, to)`, each moving one token.
fn cyclic(places: &[(&str, Tokens)], moves: &[(&str, &str, &str)]) -> Program {
    let mut b = NetBuilder::new("n");
    for &(id, m) in places {
        b.add_place(Place::new(id, m))
            .unwrap_or_else(|e| panic!("{e}"));
    }
    for &(t, from, to) in moves {
        b.add_transition(cetratus_net::Transition::new(t))
            .unwrap_or_else(|e| panic!("{e}"));
        let kind = cetratus_net::ArcKind::Normal;
        b.add_arc(&format!("{t}i"), from, t, 1, kind)
            .unwrap_or_else(|e| panic!("{e}"));
        b.add_arc(&format!("{t}o"), t, to, 1, kind)
            .unwrap_or_else(|e| panic!("{e}"));
    }
    let net = b.build().unwrap_or_else(|e| panic!("{e}"));
    let src = "[program]\nname = \"t\"\nversion = \"1\"\n";
    Program::from_sources(src, "t.toml", net).unwrap_or_else(|e| panic!("{e}"))
}

const RING: &[(&str, &str, &str)] = &[("t1", "A", "B"), ("t2", "B", "A")];

#[test]
fn a_changed_initial_marking_goes_into_the_base_so_that_the_ring_keeps_its_new_count() {
    // The ring's invariant A + B goes from 1 to 3: only A changed its initial marking, so A
    // takes the two tokens, and the projection gives them back.
    let old = cyclic(&[("A", 1), ("B", 0)], RING);
    let new = cyclic(&[("A", 3), ("B", 0)], RING);
    let st =
        StateTransform::generated(&old, &new, &BTreeMap::new()).unwrap_or_else(|e| panic!("{e}"));
    let mut out = [0; 2];
    st.apply(&[0, 1], &new, &mut out)
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(out, [2, 1]);
    let pi = Projection::generated(old.net(), new.net()).unwrap_or_else(|e| panic!("{e}"));
    let mut back = [9; 2];
    pi.apply(&out, &old, &mut back)
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(back, [0, 1]);
}

#[test]
fn two_changed_places_in_one_invariant_are_ambiguous_and_refused_with_what_to_write() {
    let old = cyclic(&[("A", 1), ("B", 0)], RING);
    let new = cyclic(&[("A", 2), ("B", 1)], RING);
    let e = StateTransform::generated(&old, &new, &BTreeMap::new())
        .err()
        .unwrap_or_else(|| panic!("ambiguous"));
    let text = e.to_string();
    assert!(matches!(e, TransformError::InvariantAmbiguous(_)), "{text}");
    for part in [
        "`A + B`",
        "holds 3",
        "carried over 1",
        "A, B",
        "base = { A = 2 }",
    ] {
        assert!(text.contains(part), "{part}: {text}");
    }
}

#[test]
fn a_token_the_new_net_drops_from_an_old_invariant_makes_the_projection_impossible() {
    // X is removed and its token sent to A, and the new ring starts empty: the transform makes
    // A take X's token and gives up the one the new net does not hold (A starts from X's tokens,
    // not from its initial marking). Back through the projection, the old net's invariant
    // A + B + X needs its token, and nothing whose initial marking changed can give it.
    let old = cyclic(
        &[("A", 0), ("B", 0), ("X", 1)],
        &[("t1", "A", "X"), ("t2", "X", "B"), ("t3", "B", "A")],
    );
    let new = cyclic(&[("A", 0), ("B", 0)], RING);
    let removed = BTreeMap::from([("X".to_string(), "A".to_string())]);
    let st = StateTransform::generated(&old, &new, &removed).unwrap_or_else(|e| panic!("{e}"));
    let mut out = [9; 2];
    st.apply(&[0, 0, 1], &new, &mut out)
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(out, [0, 0], "the new ring holds no token");
    let e = Projection::generated(old.net(), new.net())
        .err()
        .unwrap_or_else(|| panic!("impossible"));
    let text = e.to_string();
    assert!(
        matches!(e, TransformError::InvariantImpossible(_)),
        "{text}"
    );
    for part in [
        "`A + B + X`",
        "holds 1",
        "carried over 0",
        "fix the initial marking",
    ] {
        assert!(text.contains(part), "{part}: {text}");
    }
}
