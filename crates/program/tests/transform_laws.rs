//! Laws of the generated state transform and projection over random pairs of nets that share
//! some place ids: dimensions follow the nets, kept places keep their tokens (when their initial
//! marking is the same in both nets; otherwise the invariants decide, `transform/derive.rs`), new
//! places start at their initial marking, and a candidate equal to the transformed primary has
//! no drift.

use std::collections::BTreeMap;

use cetratus_net::{Net, NetBuilder, Place, Tokens};
use cetratus_program::{Program, Projection, StateTransform};
use proptest::prelude::*;

/// A net over the chosen ids of a pool `Q0..Q9`, in the given order, with the given M0.
fn net(places: &[(usize, Tokens)]) -> Net {
    let mut b = NetBuilder::new("n");
    for &(i, m) in places {
        b.add_place(Place::new(format!("Q{i}"), m))
            .unwrap_or_else(|e| panic!("{e}"));
    }
    b.build().unwrap_or_else(|e| panic!("{e}"))
}

fn program(places: &[(usize, Tokens)]) -> Program {
    Program::from_sources(
        "[program]\nname = \"p\"\nversion = \"1\"\n",
        "p.toml",
        net(places),
    )
    .unwrap_or_else(|e| panic!("{e}"))
}

/// Distinct pool ids in random order, each with a token count.
fn places() -> impl Strategy<Value = Vec<(usize, Tokens)>> {
    proptest::sample::subsequence((0..10).collect::<Vec<usize>>(), 1..=10)
        .prop_shuffle()
        .prop_flat_map(|ids| {
            let n = ids.len();
            (Just(ids), proptest::collection::vec(0u32..5, n))
        })
        .prop_map(|(ids, m)| ids.into_iter().zip(m).collect())
}

proptest! {
    #[test]
    fn generated_transform_has_a_row_per_new_place_and_keeps_kept_places(
        old in places(),
        new in places(),
        marking in proptest::collection::vec(0u32..1000, 10),
    ) {
        // A kept place starts with the same tokens in both nets.
        let new: Vec<(usize, Tokens)> = new
            .iter()
            .map(|&(id, m)| (id, old.iter().find(|&&(j, _)| j == id).map_or(m, |&(_, o)| o)))
            .collect();
        let (op, np) = (program(&old), program(&new));
        let st = StateTransform::generated(&op, &np, &BTreeMap::new())
            .unwrap_or_else(|e| panic!("{e}"));
        prop_assert_eq!(st.rows(), new.len());
        prop_assert_eq!(st.cols(), old.len());
        let dense = st.to_dense();
        prop_assert_eq!(dense.matrix.len(), new.len());
        prop_assert!(dense.matrix.iter().all(|r| r.len() == old.len()));

        // Removed places are empty, as the generated transform requires.
        let kept = |id: usize| new.iter().any(|&(j, _)| j == id);
        let m_old: Vec<Tokens> = old
            .iter()
            .map(|&(id, _)| if kept(id) { marking[id] } else { 0 })
            .collect();
        let mut m_new = vec![0; new.len()];
        st.apply(&m_old, &np, &mut m_new).unwrap_or_else(|e| panic!("{e}"));
        for (r, &(id, initial)) in new.iter().enumerate() {
            let expected = match old.iter().position(|&(j, _)| j == id) {
                Some(c) => m_old[c],
                None => initial,
            };
            prop_assert_eq!(m_new[r], expected);
        }

        // A marked place only the old net has is an invariant of it (no transition moves its
        // tokens): the generated projection cannot give them back, and is refused.
        let dropped = old.iter().any(|&(id, m)| m > 0 && !kept(id));
        let pi = Projection::generated(op.net(), np.net());
        if dropped {
            prop_assert!(pi.is_err());
            return Ok(());
        }
        // Seen through the generated projection, the transformed marking is the primary's.
        let pi = pi.expect("projection");
        prop_assert_eq!((pi.rows(), pi.cols()), (old.len(), new.len()));
        prop_assert_eq!(pi.drift(&m_new, &m_old), 0);
    }

    #[test]
    fn a_removed_place_with_tokens_is_refused_and_nothing_is_written(
        old in places(),
        new in places(),
        tokens in 1u32..5,
    ) {
        let (op, np) = (program(&old), program(&new));
        let st = StateTransform::generated(&op, &np, &BTreeMap::new())
            .unwrap_or_else(|e| panic!("{e}"));
        let removed = old.iter().position(|&(id, _)| !new.iter().any(|&(j, _)| j == id));
        prop_assume!(removed.is_some());
        let mut m_old = vec![0; old.len()];
        m_old[removed.unwrap_or_default()] = tokens;
        let mut out = vec![u32::MAX; new.len()];
        prop_assert!(st.apply(&m_old, &np, &mut out).is_err());
        prop_assert!(out.iter().all(|&t| t == u32::MAX));
    }
}
