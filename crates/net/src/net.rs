//! The net as data: places, transitions, arcs, and the sparse tables derived from them.

use rustc_hash::FxHashMap as HashMap;

use crate::{Csr, NetError, Tokens};

/// The index of a place: its position in declaration order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct PlaceIdx(pub u32);

/// The index of a transition: its position in declaration order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct TransIdx(pub u32);

impl PlaceIdx {
    /// As a `usize` for indexing.
    #[inline]
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

impl TransIdx {
    /// As a `usize` for indexing.
    #[inline]
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

/// A position on the drawing, in the file's units (PNML uses pixels).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Position {
    /// Horizontal, growing to the right.
    pub x: f64,
    /// Vertical, growing downwards.
    pub y: f64,
}

/// An element a tool stored for itself (`<toolspecific>`), kept verbatim so it survives a round trip.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ToolSpecific {
    /// The `tool` attribute.
    pub tool: String,
    /// The `version` attribute.
    pub version: String,
    /// The whole element as XML text.
    pub xml: String,
}

/// A place.
#[derive(Clone, Debug, PartialEq)]
pub struct Place {
    /// Unique id.
    pub id: String,
    /// Display name, if the file gave one.
    pub name: Option<String>,
    /// Tokens in the initial marking.
    pub initial: Tokens,
    /// Most tokens the place may hold; `None` is unbounded.
    pub capacity: Option<Tokens>,
    /// Where it is drawn.
    pub position: Option<Position>,
    /// Tool-specific data attached to the place.
    pub toolspecific: Vec<ToolSpecific>,
}

impl Place {
    /// A place with an id and an initial marking and nothing else.
    pub fn new(id: impl Into<String>, initial: Tokens) -> Self {
        Place {
            id: id.into(),
            name: None,
            initial,
            capacity: None,
            position: None,
            toolspecific: Vec::new(),
        }
    }

    /// The name if there is one, else the id.
    pub fn label(&self) -> &str {
        self.name.as_deref().unwrap_or(&self.id)
    }
}

/// A transition.
#[derive(Clone, Debug, PartialEq)]
pub struct Transition {
    /// Unique id.
    pub id: String,
    /// Display name, if the file gave one.
    pub name: Option<String>,
    /// Higher fires first under the step and priority rules; default 0.
    pub priority: i32,
    /// Where it is drawn.
    pub position: Option<Position>,
    /// Tool-specific data attached to the transition.
    pub toolspecific: Vec<ToolSpecific>,
}

impl Transition {
    /// A transition with an id and nothing else.
    pub fn new(id: impl Into<String>) -> Self {
        Transition {
            id: id.into(),
            name: None,
            priority: 0,
            position: None,
            toolspecific: Vec::new(),
        }
    }

    /// The name if there is one, else the id.
    pub fn label(&self) -> &str {
        self.name.as_deref().unwrap_or(&self.id)
    }
}

/// One end of an arc.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum NodeRef {
    /// A place.
    Place(PlaceIdx),
    /// A transition.
    Transition(TransIdx),
}

/// What an arc does.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ArcKind {
    /// Consumes (place → transition) or produces (transition → place) `weight` tokens.
    Normal,
    /// Place → transition only: the transition is enabled only while the place holds fewer than
    /// `weight` tokens.
    Inhibitor,
}

/// An arc as declared.
#[derive(Clone, Debug, PartialEq)]
pub struct Arc {
    /// Unique id.
    pub id: String,
    /// Where it starts.
    pub source: NodeRef,
    /// Where it ends.
    pub target: NodeRef,
    /// Tokens moved, or the inhibitor threshold. At least 1.
    pub weight: Tokens,
    /// Normal or inhibitor.
    pub kind: ArcKind,
    /// Bend points between the two ends, as drawn.
    pub path: Vec<Position>,
}

/// A well-formed place/transition net with inhibitor arcs, capacities and priorities.
///
/// Built through [`NetBuilder`]; read-only afterwards. Besides the declared elements it holds the
/// sparse tables the engine and the analyses need: Pre, Post and inhibitor entries per transition,
/// the same per place, the nonzero column of `C = Post − Pre` per transition, and the transitions
/// whose enabling depends on each place.
#[derive(Clone, Debug, PartialEq)]
pub struct Net {
    id: String,
    name: Option<String>,
    places: Vec<Place>,
    transitions: Vec<Transition>,
    arcs: Vec<Arc>,
    toolspecific: Vec<ToolSpecific>,
    pre: Csr<(PlaceIdx, Tokens)>,
    post: Csr<(PlaceIdx, Tokens)>,
    inhibitors: Csr<(PlaceIdx, Tokens)>,
    delta: Csr<(PlaceIdx, i64)>,
    place_consumers: Csr<(TransIdx, Tokens)>,
    place_producers: Csr<(TransIdx, Tokens)>,
    place_inhibited: Csr<(TransIdx, Tokens)>,
    dependents: Csr<TransIdx>,
    rank: Vec<u32>,
    by_rank: Vec<TransIdx>,
    // Visiting order is declaration order when every priority is equal: rank(t) = t, no lookup.
    rank_is_identity: bool,
    // Capacities as a dense vector (Tokens::MAX = unbounded), so the hot path avoids `Place`.
    caps: Vec<Tokens>,
    any_capacity: bool,
    any_inhibitor: bool,
    place_index: HashMap<String, PlaceIdx>,
    trans_index: HashMap<String, TransIdx>,
}

/// The accessors of the sparse tables, each one row of a table by the index the table is kept
/// by: written once, so that every one stays `#[inline]` on the engine's hot path.
macro_rules! rows {
    ($($(#[$doc:meta])* $name:ident($i:ident: $idx:ty) -> [$item:ty] = $table:ident;)*) => {
        $(
            $(#[$doc])*
            #[inline]
            pub fn $name(&self, $i: $idx) -> &[$item] {
                self.$table.row($i.index())
            }
        )*
    };
}

impl Net {
    /// The net's id.
    pub fn id(&self) -> &str {
        &self.id
    }
    /// The net's display name, if any.
    pub fn name(&self) -> Option<&str> {
        self.name.as_deref()
    }
    /// Places in declaration order.
    pub fn places(&self) -> &[Place] {
        &self.places
    }
    /// Transitions in declaration order.
    pub fn transitions(&self) -> &[Transition] {
        &self.transitions
    }
    /// Arcs in declaration order.
    pub fn arcs(&self) -> &[Arc] {
        &self.arcs
    }
    /// Net-level tool-specific elements.
    pub fn toolspecific(&self) -> &[ToolSpecific] {
        &self.toolspecific
    }
    /// Number of places.
    pub fn num_places(&self) -> usize {
        self.places.len()
    }
    /// Number of transitions.
    pub fn num_transitions(&self) -> usize {
        self.transitions.len()
    }
    /// A place by index.
    pub fn place(&self, p: PlaceIdx) -> &Place {
        &self.places[p.index()]
    }
    /// A transition by index.
    pub fn transition(&self, t: TransIdx) -> &Transition {
        &self.transitions[t.index()]
    }
    /// Looks up a place by id.
    pub fn place_by_id(&self, id: &str) -> Option<PlaceIdx> {
        self.place_index.get(id).copied()
    }
    /// Looks up a transition by id.
    pub fn transition_by_id(&self, id: &str) -> Option<TransIdx> {
        self.trans_index.get(id).copied()
    }
    /// The initial marking M0.
    pub fn initial_marking(&self) -> crate::Marking {
        crate::Marking(self.places.iter().map(|p| p.initial).collect())
    }
    rows! {
        /// `Pre[·,t]`: the places t consumes from, with weights, sorted by place.
        pre(t: TransIdx) -> [(PlaceIdx, Tokens)] = pre;
        /// `Post[·,t]`: the places t produces into, with weights, sorted by place.
        post(t: TransIdx) -> [(PlaceIdx, Tokens)] = post;
        /// The inhibitor arcs of t: t needs `M[p] < w` for each `(p, w)`.
        inhibitors(t: TransIdx) -> [(PlaceIdx, Tokens)] = inhibitors;
        /// `C[·,t] = Post[·,t] − Pre[·,t]`, nonzero entries only, sorted by place.
        delta(t: TransIdx) -> [(PlaceIdx, i64)] = delta;
        /// `p•`: the transitions consuming from p, with weights.
        consumers(p: PlaceIdx) -> [(TransIdx, Tokens)] = place_consumers;
        /// `•p`: the transitions producing into p, with weights.
        producers(p: PlaceIdx) -> [(TransIdx, Tokens)] = place_producers;
        /// The transitions p inhibits, with thresholds.
        inhibited(p: PlaceIdx) -> [(TransIdx, Tokens)] = place_inhibited;
        /// The transitions whose enabling can change when M[p] changes.
        dependents(p: PlaceIdx) -> [TransIdx] = dependents;
    }
    /// The visiting rank of t: 0 is visited first (highest priority, then earliest declared).
    #[inline]
    pub fn rank(&self, t: TransIdx) -> u32 {
        if self.rank_is_identity {
            t.0
        } else {
            self.rank[t.index()]
        }
    }
    /// The transition with visiting rank `r`.
    #[inline]
    pub fn by_rank(&self, r: u32) -> TransIdx {
        if self.rank_is_identity {
            TransIdx(r)
        } else {
            self.by_rank[r as usize]
        }
    }
    /// Capacity of p, `None` for unbounded.
    #[inline]
    pub fn capacity(&self, p: PlaceIdx) -> Option<Tokens> {
        self.places[p.index()].capacity
    }
    /// True when some place has a capacity.
    #[inline]
    pub fn has_capacities(&self) -> bool {
        self.any_capacity
    }
    /// True when the net has an inhibitor arc.
    #[inline]
    pub fn has_inhibitors(&self) -> bool {
        self.any_inhibitor
    }

    /// Enabled(t, M) as docs/design.md §3 defines it: `M ≥ Pre[·,t]`, every inhibitor arc `M[p] < w`, and
    /// `M + C[·,t]` within every capacity.
    pub fn is_enabled(&self, t: TransIdx, m: &[Tokens]) -> bool {
        self.pre(t).iter().all(|&(p, w)| m[p.index()] >= w)
            && (!self.any_inhibitor || self.inhibitors(t).iter().all(|&(p, w)| m[p.index()] < w))
            && self.fits_capacity(t, m)
    }

    /// True when `M + C[·,t]` respects every capacity.
    #[inline]
    pub(crate) fn fits_capacity(&self, t: TransIdx, m: &[Tokens]) -> bool {
        !self.any_capacity
            || self.delta(t).iter().all(|&(p, d)| {
                d <= 0 || i64::from(m[p.index()]) + d <= i64::from(self.caps[p.index()])
            })
    }

    /// A copy of this net with a different initial marking (same length).
    pub fn with_initial_marking(&self, m: &crate::Marking) -> Result<Net, NetError> {
        if m.len() != self.num_places() {
            return Err(NetError::MarkingLength {
                expected: self.num_places(),
                got: m.len(),
            });
        }
        let mut n = self.clone();
        for (p, &t) in n.places.iter_mut().zip(m.as_slice()) {
            p.initial = t;
        }
        Ok(n)
    }
}

/// Builds a [`Net`], checking ids and arcs as they come.
#[derive(Debug, Default)]
pub struct NetBuilder {
    id: String,
    name: Option<String>,
    places: Vec<Place>,
    transitions: Vec<Transition>,
    arcs: Vec<Arc>,
    toolspecific: Vec<ToolSpecific>,
    ids: HashMap<String, NodeRef>,
    arc_ids: HashMap<String, usize>,
}

impl NetBuilder {
    /// A builder for a net with this id.
    pub fn new(id: impl Into<String>) -> Self {
        NetBuilder {
            id: id.into(),
            ..Default::default()
        }
    }

    /// Sets the net's display name.
    pub fn name(&mut self, name: impl Into<String>) -> &mut Self {
        self.name = Some(name.into());
        self
    }

    /// Adds net-level tool-specific data.
    pub fn toolspecific(&mut self, ts: ToolSpecific) -> &mut Self {
        self.toolspecific.push(ts);
        self
    }

    /// Adds a place after the ones already declared.
    pub fn add_place(&mut self, place: Place) -> Result<PlaceIdx, NetError> {
        if let Some(cap) = place.capacity {
            if place.initial > cap {
                return Err(NetError::InitialOverCapacity {
                    place: place.id.clone(),
                    tokens: place.initial,
                    capacity: cap,
                });
            }
        }
        let idx = PlaceIdx(self.places.len() as u32);
        self.claim(&place.id, NodeRef::Place(idx))?;
        self.places.push(place);
        Ok(idx)
    }

    /// Adds a transition after the ones already declared.
    pub fn add_transition(&mut self, transition: Transition) -> Result<TransIdx, NetError> {
        let idx = TransIdx(self.transitions.len() as u32);
        self.claim(&transition.id, NodeRef::Transition(idx))?;
        self.transitions.push(transition);
        Ok(idx)
    }

    fn claim(&mut self, id: &str, node: NodeRef) -> Result<(), NetError> {
        if self.ids.contains_key(id) || self.arc_ids.contains_key(id) {
            return Err(NetError::DuplicateId { id: id.to_string() });
        }
        self.ids.insert(id.to_string(), node);
        Ok(())
    }

    /// Resolves a node id declared so far.
    pub fn node(&self, id: &str) -> Option<NodeRef> {
        self.ids.get(id).copied()
    }

    /// Mutable access to a place declared so far (for readers that learn attributes late).
    pub fn place_mut(&mut self, p: PlaceIdx) -> &mut Place {
        &mut self.places[p.index()]
    }

    /// Adds an arc between two declared nodes; returns its index in declaration order.
    pub fn add_arc(
        &mut self,
        id: &str,
        source: &str,
        target: &str,
        weight: Tokens,
        kind: ArcKind,
    ) -> Result<usize, NetError> {
        let s = self.node(source).ok_or_else(|| NetError::UnknownNode {
            arc: id.to_string(),
            node: source.to_string(),
        })?;
        let t = self.node(target).ok_or_else(|| NetError::UnknownNode {
            arc: id.to_string(),
            node: target.to_string(),
        })?;
        self.add_arc_resolved(id, s, t, weight, kind)
    }

    /// Adds an arc between two resolved nodes; returns its index in declaration order.
    pub fn add_arc_resolved(
        &mut self,
        id: &str,
        source: NodeRef,
        target: NodeRef,
        weight: Tokens,
        kind: ArcKind,
    ) -> Result<usize, NetError> {
        match (source, target) {
            (NodeRef::Place(_), NodeRef::Place(_)) => {
                return Err(NetError::BadArcEnds {
                    arc: id.to_string(),
                    what: "two places",
                })
            }
            (NodeRef::Transition(_), NodeRef::Transition(_)) => {
                return Err(NetError::BadArcEnds {
                    arc: id.to_string(),
                    what: "two transitions",
                })
            }
            (NodeRef::Transition(_), NodeRef::Place(_)) if kind == ArcKind::Inhibitor => {
                return Err(NetError::InhibitorFromTransition {
                    arc: id.to_string(),
                })
            }
            _ => {}
        }
        if weight == 0 {
            return Err(NetError::ZeroWeight {
                arc: id.to_string(),
            });
        }
        if self.ids.contains_key(id) || self.arc_ids.contains_key(id) {
            return Err(NetError::DuplicateId { id: id.to_string() });
        }
        let idx = self.arcs.len();
        self.arc_ids.insert(id.to_string(), idx);
        self.arcs.push(Arc {
            id: id.to_string(),
            source,
            target,
            weight,
            kind,
            path: Vec::new(),
        });
        Ok(idx)
    }

    /// Sets the bend points of an arc added before.
    pub fn set_arc_path(&mut self, arc: usize, path: Vec<Position>) {
        self.arcs[arc].path = path;
    }

    /// Pre, Post and the inhibitor thresholds as (transition, (place, weight)) pairs, sorted
    /// by transition then place: parallel arcs add up, parallel inhibitor arcs keep the
    /// strictest threshold.
    fn arc_pairs(&self) -> Result<[Pairs<Tokens>; 3], NetError> {
        let mut pre: HashMap<(u32, u32), u64> = HashMap::default();
        let mut post: HashMap<(u32, u32), u64> = HashMap::default();
        let mut inh: HashMap<(u32, u32), Tokens> = HashMap::default();
        for a in &self.arcs {
            match (a.source, a.target, a.kind) {
                (NodeRef::Place(p), NodeRef::Transition(t), ArcKind::Normal) => {
                    *pre.entry((t.0, p.0)).or_default() += u64::from(a.weight)
                }
                (NodeRef::Place(p), NodeRef::Transition(t), ArcKind::Inhibitor) => {
                    let e = inh.entry((t.0, p.0)).or_insert(a.weight);
                    *e = (*e).min(a.weight);
                }
                (NodeRef::Transition(t), NodeRef::Place(p), _) => {
                    *post.entry((t.0, p.0)).or_default() += u64::from(a.weight)
                }
                _ => unreachable!("arc ends were checked when the arc was added"),
            }
        }
        let sorted = |sums: HashMap<(u32, u32), u64>| -> Result<Pairs<Tokens>, NetError> {
            let mut pairs = Vec::with_capacity(sums.len());
            for ((t, p), w) in sums {
                let w = Tokens::try_from(w).map_err(|_| NetError::ZeroWeight {
                    arc: format!("(parallel arcs of transition {t}, weight overflow)"),
                })?;
                pairs.push((t, (PlaceIdx(p), w)));
            }
            pairs.sort_unstable_by_key(|&(t, (p, _))| (t, p));
            Ok(pairs)
        };
        let inh = inh.into_iter().map(|(k, w)| (k, u64::from(w))).collect();
        Ok([sorted(pre)?, sorted(post)?, sorted(inh)?])
    }

    /// Finishes the net and derives its sparse tables.
    pub fn build(self) -> Result<Net, NetError> {
        let np = self.places.len();
        let nt = self.transitions.len();
        let [pre_pairs, post_pairs, inh_pairs] = self.arc_pairs()?;
        let delta_pairs = delta_pairs(&pre_pairs, &post_pairs);

        let flip = |pairs: &[(u32, (PlaceIdx, Tokens))]| {
            let mut v: Vec<(u32, (TransIdx, Tokens))> = pairs
                .iter()
                .map(|&(t, (p, w))| (p.0, (TransIdx(t), w)))
                .collect();
            v.sort_unstable_by_key(|&(p, (t, _))| (p, t));
            v
        };
        let consumers = flip(&pre_pairs);
        let producers = flip(&post_pairs);
        let inhibited = flip(&inh_pairs);

        // M[p] matters to t when p is in Pre, in an inhibitor, or when t changes a bounded p.
        let mut dep: Vec<(u32, TransIdx)> = Vec::new();
        dep.extend(consumers.iter().map(|&(p, (t, _))| (p, t)));
        dep.extend(inhibited.iter().map(|&(p, (t, _))| (p, t)));
        for &(t, (p, d)) in &delta_pairs {
            if d > 0 && self.places[p.index()].capacity.is_some() {
                dep.push((p.0, TransIdx(t)));
            }
        }
        dep.sort_unstable_by_key(|&(p, t)| (p, t));
        dep.dedup();

        let mut by_rank: Vec<TransIdx> = (0..nt as u32).map(TransIdx).collect();
        by_rank.sort_by_key(|t| (std::cmp::Reverse(self.transitions[t.index()].priority), t.0));
        let mut rank = vec![0u32; nt];
        for (r, t) in by_rank.iter().enumerate() {
            rank[t.index()] = r as u32;
        }

        // The id map already owns every node id; moving its strings saves copying each one.
        let mut place_index: HashMap<String, PlaceIdx> =
            HashMap::with_capacity_and_hasher(np, Default::default());
        let mut trans_index: HashMap<String, TransIdx> =
            HashMap::with_capacity_and_hasher(nt, Default::default());
        for (id, node) in self.ids {
            match node {
                NodeRef::Place(p) => {
                    place_index.insert(id, p);
                }
                NodeRef::Transition(t) => {
                    trans_index.insert(id, t);
                }
            }
        }

        let caps: Vec<Tokens> = self
            .places
            .iter()
            .map(|p| p.capacity.unwrap_or(Tokens::MAX))
            .collect();
        let any_capacity = self.places.iter().any(|p| p.capacity.is_some());
        Ok(Net {
            id: self.id,
            name: self.name,
            pre: Csr::from_pairs(nt, &pre_pairs),
            post: Csr::from_pairs(nt, &post_pairs),
            inhibitors: Csr::from_pairs(nt, &inh_pairs),
            delta: Csr::from_pairs(nt, &delta_pairs),
            place_consumers: Csr::from_pairs(np, &consumers),
            place_producers: Csr::from_pairs(np, &producers),
            place_inhibited: Csr::from_pairs(np, &inhibited),
            dependents: Csr::from_pairs(np, &dep),
            places: self.places,
            transitions: self.transitions,
            arcs: self.arcs,
            toolspecific: self.toolspecific,
            rank_is_identity: by_rank.iter().enumerate().all(|(r, t)| t.index() == r),
            rank,
            by_rank,
            caps,
            any_capacity,
            any_inhibitor: !inh_pairs.is_empty(),
            place_index,
            trans_index,
        })
    }
}

/// (transition, (place, weight)) pairs, sorted by transition then place.
type Pairs<T> = Vec<(u32, (PlaceIdx, T))>;

/// The nonzero entries of `C = Post - Pre`, sorted as the pairs.
fn delta_pairs(pre: &Pairs<Tokens>, post: &Pairs<Tokens>) -> Pairs<i64> {
    let mut delta: HashMap<(u32, u32), i64> = HashMap::default();
    for &(t, (p, w)) in pre {
        *delta.entry((t, p.0)).or_default() -= i64::from(w);
    }
    for &(t, (p, w)) in post {
        *delta.entry((t, p.0)).or_default() += i64::from(w);
    }
    let mut pairs: Pairs<i64> = delta
        .into_iter()
        .filter(|&(_, d)| d != 0)
        .map(|((t, p), d)| (t, (PlaceIdx(p), d)))
        .collect();
    pairs.sort_unstable_by_key(|&(t, (p, _))| (t, p));
    pairs
}
