//! Part 2 of the export: the net as data. Pre, Post and the inhibitor arcs are stored sparse,
//! by transition (compressed rows: where each transition's arcs start, then each arc's place
//! and weight), with M0, the capacities, the visiting order and the priorities beside them.

use std::fmt::Write as _;

use cetratus_net::{Net, PlaceIdx, Policy, SingleRule, Tokens, TransIdx};

/// The size of the net's data in the export, beside the dense layout of the semi-compiled
/// paper (Pre and Post as full matrices, and M0), both counted in 4-byte DINTs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DataSize {
    /// Bytes of the sparse tables the export writes.
    pub sparse_bytes: usize,
    /// Bytes of Pre, Post and M0 as dense DINT matrices.
    pub dense_bytes: usize,
}

/// A sparse table by transition.
struct Rows {
    start: Vec<usize>,
    place: Vec<u32>,
    weight: Vec<Tokens>,
}

fn rows(net: &Net, row: impl Fn(TransIdx) -> Vec<(PlaceIdx, Tokens)>) -> Rows {
    let mut r = Rows {
        start: Vec::with_capacity(net.num_transitions() + 1),
        place: Vec::new(),
        weight: Vec::new(),
    };
    for t in 0..net.num_transitions() {
        r.start.push(r.place.len() + 1);
        for (p, w) in row(TransIdx(t as u32)) {
            r.place.push(p.0 + 1);
            r.weight.push(w);
        }
    }
    r.start.push(r.place.len() + 1);
    r
}

/// The net's tables, ready to be written.
pub(crate) struct NetData {
    places: usize,
    transitions: usize,
    policy: u8,
    m0: Vec<Tokens>,
    capacity: Vec<Tokens>,
    pre: Rows,
    post: Rows,
    inhibitors: Rows,
    order: Vec<u32>,
    priority: Vec<i32>,
    /// Per place, where its dependents start in `dependents` (1-based, one past the last).
    dependent_start: Vec<usize>,
    /// The transitions whose enabling can change when a place's count changes.
    dependents: Vec<u32>,
}

impl NetData {
    pub(crate) fn new(net: &Net, policy: Policy) -> Self {
        let n = net.num_transitions();
        let (dependent_start, dependents) = dependent_rows(net);
        NetData {
            places: net.num_places(),
            transitions: n,
            policy: match policy {
                Policy::Step => 0,
                Policy::Single(SingleRule::Last) => 1,
                Policy::Single(SingleRule::First) => 2,
                Policy::Single(SingleRule::Priority) => 3,
            },
            m0: net.places().iter().map(|p| p.initial).collect(),
            capacity: net
                .places()
                .iter()
                .map(|p| p.capacity.unwrap_or(0))
                .collect(),
            pre: rows(net, |t| net.pre(t).to_vec()),
            post: rows(net, |t| net.post(t).to_vec()),
            inhibitors: rows(net, |t| net.inhibitors(t).to_vec()),
            order: (0..n as u32).map(|r| net.by_rank(r).0 + 1).collect(),
            priority: net.transitions().iter().map(|t| t.priority).collect(),
            dependent_start,
            dependents,
        }
    }

    /// The export's sparse bytes beside the dense layout.
    pub(crate) fn size(&self) -> DataSize {
        let (p, t) = (self.places, self.transitions);
        let arcs = |r: &Rows| r.start.len() + 2 * r.place.len();
        let dependents = self.dependent_start.len() + self.dependents.len().max(1);
        let dints = 3
            + 2 * p
            + arcs(&self.pre)
            + arcs(&self.post)
            + arcs(&self.inhibitors)
            + 2 * t
            + dependents;
        DataSize {
            sparse_bytes: 4 * dints,
            dense_bytes: 4 * (2 * p * t + p),
        }
    }

    /// The array types the kernel and the interpretation declare their data with: name,
    /// length, element type, what it holds.
    pub(crate) fn types(&self) -> Vec<ArrayType> {
        let (p, t) = (self.places.max(1), self.transitions.max(1));
        let len = |r: &Rows| r.place.len().max(1);
        let deltas = (self.pre.place.len() + self.post.place.len()).max(1);
        [
            ("CETRATUS_PLACES", p, "DINT", "one count per place"),
            ("CETRATUS_PLACE_FLAGS", p, "BOOL", "one flag per place"),
            (
                "CETRATUS_TRANSITIONS",
                t,
                "DINT",
                "one number per transition",
            ),
            (
                "CETRATUS_TRANSITION_FLAGS",
                t,
                "BOOL",
                "one flag per transition",
            ),
            (
                "CETRATUS_ROWS",
                t + 1,
                "DINT",
                "where each transition's arcs start",
            ),
            ("CETRATUS_PRE_ARCS", len(&self.pre), "DINT", "the Pre arcs"),
            (
                "CETRATUS_POST_ARCS",
                len(&self.post),
                "DINT",
                "the Post arcs",
            ),
            (
                "CETRATUS_INHIBITOR_ARCS",
                len(&self.inhibitors),
                "DINT",
                "the inhibitor arcs",
            ),
            (
                "CETRATUS_PLACE_ROWS",
                p + 1,
                "DINT",
                "where each place's dependents start",
            ),
            (
                "CETRATUS_DEPENDENTS",
                self.dependents.len().max(1),
                "DINT",
                "the transitions a place's count can enable or disable",
            ),
            (
                "CETRATUS_DELTAS",
                deltas,
                "DINT",
                "the nonzero entries of C",
            ),
        ]
        .into_iter()
        .map(|(name, len, element, about)| ArrayType {
            name,
            len,
            element,
            about,
        })
        .collect()
    }

    /// The net's constants: name, array type (`None` for a DINT), value text.
    pub(crate) fn constants(&self) -> Vec<Constant> {
        let mut v = vec![
            Constant::scalar("NET_PLACES", self.places.to_string()),
            Constant::scalar("NET_TRANSITIONS", self.transitions.to_string()),
            Constant {
                note: "0 step, 1 single-last, 2 single-first, 3 single-priority",
                ..Constant::scalar("NET_POLICY", self.policy.to_string())
            },
        ];
        let mut put = |name: &str, ty: &'static str, values: Vec<i64>| {
            v.push(Constant {
                ty: Some(ty),
                ..Constant::scalar(name, list(&values))
            });
        };
        let wide = |v: &[u32]| v.iter().map(|&x| i64::from(x)).collect::<Vec<_>>();
        put("NET_M0", "CETRATUS_PLACES", wide(&self.m0));
        put("NET_CAPACITY", "CETRATUS_PLACES", wide(&self.capacity));
        for (name, ty, r) in [
            ("PRE", "CETRATUS_PRE_ARCS", &self.pre),
            ("POST", "CETRATUS_POST_ARCS", &self.post),
            ("INHIBITOR", "CETRATUS_INHIBITOR_ARCS", &self.inhibitors),
        ] {
            let start = r.start.iter().map(|&x| x as i64).collect();
            put(&format!("NET_{name}_START"), "CETRATUS_ROWS", start);
            put(&format!("NET_{name}_PLACE"), ty, padded(wide(&r.place)));
            put(&format!("NET_{name}_WEIGHT"), ty, padded(wide(&r.weight)));
        }
        put(
            "NET_ORDER",
            "CETRATUS_TRANSITIONS",
            padded(wide(&self.order)),
        );
        let priority = self.priority.iter().map(|&x| i64::from(x)).collect();
        put("NET_PRIORITY", "CETRATUS_TRANSITIONS", padded(priority));
        let start = self.dependent_start.iter().map(|&x| x as i64).collect();
        put("NET_DEPENDENT_START", "CETRATUS_PLACE_ROWS", start);
        put(
            "NET_DEPENDENT",
            "CETRATUS_DEPENDENTS",
            padded(wide(&self.dependents)),
        );
        v
    }
}

/// An array type of the export.
pub(crate) struct ArrayType {
    pub(crate) name: &'static str,
    pub(crate) len: usize,
    pub(crate) element: &'static str,
    pub(crate) about: &'static str,
}

impl ArrayType {
    /// `ARRAY[1..n] OF T`.
    pub(crate) fn spelled(&self) -> String {
        format!("ARRAY[1..{}] OF {}", self.len, self.element)
    }
}

/// One of the net's constants.
pub(crate) struct Constant {
    pub(crate) name: String,
    /// Its array type, or `None` for a DINT.
    pub(crate) ty: Option<&'static str>,
    /// Its value: a number or `[a, b, …]`.
    pub(crate) value: String,
    /// A comment for the reader, or empty.
    pub(crate) note: &'static str,
}

impl Constant {
    fn scalar(name: &str, value: String) -> Self {
        Constant {
            name: name.to_string(),
            ty: None,
            value,
            note: "",
        }
    }
}

/// Per place, the transitions whose enabling its count can change (consumers, inhibited
/// transitions, producers of a bounded place), as compressed rows: where each place's start
/// (1-based, with one past the last) and the transitions, 1-based.
fn dependent_rows(net: &Net) -> (Vec<usize>, Vec<u32>) {
    let (mut start, mut all) = (Vec::with_capacity(net.num_places() + 1), Vec::new());
    for p in 0..net.num_places() {
        start.push(all.len() + 1);
        all.extend(net.dependents(PlaceIdx(p as u32)).iter().map(|t| t.0 + 1));
    }
    start.push(all.len() + 1);
    (start, all)
}

/// An empty table still has one element: IEC arrays are never empty.
fn padded(mut v: Vec<i64>) -> Vec<i64> {
    if v.is_empty() {
        v.push(0);
    }
    v
}

/// `[a, b, c]`, wrapped every sixteen values.
fn list(values: &[i64]) -> String {
    let mut s = String::from("[");
    for (i, v) in values.iter().enumerate() {
        if i > 0 {
            s.push_str(if i % 16 == 0 { ",\n      " } else { ", " });
        }
        let _ = write!(s, "{v}");
    }
    s.push(']');
    s
}

/// The fixed global names of the export, taken before any of the program's names.
pub(crate) const GLOBALS: &[&str] = &[
    "CETRATUS_PLACES",
    "CETRATUS_PLACE_FLAGS",
    "CETRATUS_TRANSITIONS",
    "CETRATUS_TRANSITION_FLAGS",
    "CETRATUS_ROWS",
    "CETRATUS_PRE_ARCS",
    "CETRATUS_POST_ARCS",
    "CETRATUS_INHIBITOR_ARCS",
    "CETRATUS_DELTAS",
    "CETRATUS_PLACE_ROWS",
    "CETRATUS_DEPENDENTS",
    "CETRATUS_KERNEL",
    "NET_PLACES",
    "NET_TRANSITIONS",
    "NET_POLICY",
    "NET_M0",
    "NET_CAPACITY",
    "NET_PRE_START",
    "NET_PRE_PLACE",
    "NET_PRE_WEIGHT",
    "NET_POST_START",
    "NET_POST_PLACE",
    "NET_POST_WEIGHT",
    "NET_INHIBITOR_START",
    "NET_INHIBITOR_PLACE",
    "NET_INHIBITOR_WEIGHT",
    "NET_ORDER",
    "NET_PRIORITY",
    "NET_DEPENDENT_START",
    "NET_DEPENDENT",
];
