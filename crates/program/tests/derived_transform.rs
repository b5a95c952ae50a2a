//! The generated transformation and projection of the paper's updates, with their bases derived
//! from the P-invariants of both nets (`transform/derive.rs`): U.1's equal the ones its package
//! writes by hand (`H` + 2 and − 2), and U.2's, whose kept places keep their initial marking,
//! are the id maps they were.

use std::collections::BTreeMap;
use std::path::PathBuf;

use cetratus_program::{Program, Projection, StateTransform};

fn example(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples/vernadat")
        .join(name)
}

fn program(name: &str) -> Program {
    Program::load(&example(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// The `[transform]` table of U.1's package, written by hand: the identity and `H` + 2.
fn u1_by_hand(old: &Program, new: &Program) -> StateTransform {
    let text = std::fs::read_to_string(example("u1.package.toml")).expect("u1.package.toml");
    let doc: toml::Table = toml::from_str(&text).expect("a manifest");
    let t = &doc["transform"];
    let strings = |k: &str| -> Vec<String> {
        t[k].as_array()
            .expect("ids")
            .iter()
            .map(|v| v.as_str().expect("an id").to_string())
            .collect()
    };
    let ints = |v: &toml::Value| -> Vec<i64> {
        v.as_array()
            .expect("numbers")
            .iter()
            .map(|x| x.as_integer().expect("an integer"))
            .collect()
    };
    let matrix: Vec<Vec<i64>> = t["matrix"]
        .as_array()
        .expect("rows")
        .iter()
        .map(ints)
        .collect();
    StateTransform::dense(
        old.net(),
        new.net(),
        &strings("rows"),
        &strings("cols"),
        &matrix,
        &ints(&t["base"]),
    )
    .expect("U.1's hand-written transform")
}

#[test]
fn u1s_generated_transform_and_projection_equal_the_hand_written_ones() {
    let (old, new) = (program("vernadat.toml"), program("u1.toml"));
    let st = StateTransform::generated(&old, &new, &BTreeMap::new()).expect("derived");
    assert_eq!(st.to_dense(), u1_by_hand(&old, &new).to_dense());
    let pi = Projection::generated(old.net(), new.net()).expect("derived");
    let by_hand = Projection::sparse(
        old.net(),
        new.net(),
        &old.net()
            .places()
            .iter()
            .map(|p| (p.id.clone(), p.id.clone(), 1))
            .collect::<Vec<_>>(),
        &BTreeMap::from([("H".to_string(), -2)]),
    )
    .expect("U.1's hand-written projection");
    assert_eq!(pi.to_dense(), by_hand.to_dense());
    // Through both, a running marking comes back as it was: the buffer invariant is 9 after
    // the transform and 7 again after the projection.
    let m: Vec<u32> = old.net().initial_marking().as_slice().to_vec();
    let mut there = vec![0; new.net().num_places()];
    st.apply(&m, &new, &mut there).expect("transform");
    new.check_invariants(&there).expect("U.1's invariants hold");
    let mut back = vec![0; m.len()];
    pi.apply(&there, &old, &mut back).expect("projection");
    assert_eq!(back, m);
}

#[test]
fn u2s_generated_transform_keeps_u1s_places_and_starts_its_lubrication_afresh() {
    let (old, new) = (program("u1.toml"), program("u2.toml"));
    let st = StateTransform::generated(&old, &new, &BTreeMap::new()).expect("U.2 generates");
    let dense = st.to_dense();
    for (r, id) in dense.row_ids.iter().enumerate() {
        let initial = new.net().places()[r].initial;
        match dense.col_ids.iter().position(|c| c == id) {
            Some(c) => {
                assert_eq!(dense.base[r], 0, "{id} keeps its tokens");
                assert_eq!(dense.matrix[r][c], 1, "{id} reads its old place");
            }
            None => assert_eq!(dense.base[r], i64::from(initial), "{id} starts afresh"),
        }
    }
    Projection::generated(old.net(), new.net()).expect("U.2's projection generates");
}
