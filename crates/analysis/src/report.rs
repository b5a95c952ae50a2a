//! The report of `cetratus check`: serialisable, with a text rendering for people.

use std::fmt;

use serde::ser::{SerializeMap, Serializer};
use serde::Serialize;

use cetratus_net::{Net, TransIdx};

use crate::budget::PartialReason;
use crate::classify::classify;
use crate::{Classification, Incidence};

/// A list of `(id, value)` pairs serialised as a JSON object in declaration order.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Named<V>(pub Vec<(String, V)>);

impl<V: Serialize> Serialize for Named<V> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut m = s.serialize_map(Some(self.0.len()))?;
        for (k, v) in &self.0 {
            m.serialize_entry(k, v)?;
        }
        m.end()
    }
}

/// The bound of a place: a number, ω (unbounded), or unknown.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bound {
    /// At most this many tokens in every reachable marking (or seen so far, in a partial run).
    Tokens(u64),
    /// Unbounded: serialised as `"ω"`.
    Omega,
    /// Not known: serialised as `null`.
    Unknown,
}

impl Serialize for Bound {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Bound::Tokens(n) => s.serialize_u64(*n),
            Bound::Omega => s.serialize_str("ω"),
            Bound::Unknown => s.serialize_none(),
        }
    }
}

impl fmt::Display for Bound {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Bound::Tokens(n) => write!(f, "{n}"),
            Bound::Omega => f.write_str("ω"),
            Bound::Unknown => f.write_str("?"),
        }
    }
}

/// Wall-clock time spent in each part of the analysis, in milliseconds.
#[derive(Clone, Debug, PartialEq, Default, Serialize)]
pub struct Timings {
    /// Classification, incidence and structural bounds.
    pub structure_ms: f64,
    /// P- and T-semiflows.
    pub invariants_ms: f64,
    /// Siphons and traps.
    pub siphons_ms: f64,
    /// State-space exploration, SCCs included.
    pub behaviour_ms: f64,
}

/// Everything `cetratus check` finds about a net. Ids are the file's place and transition ids.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Report {
    /// The net's id.
    pub net: String,
    /// Number of places.
    pub places: usize,
    /// Number of transitions.
    pub transitions: usize,
    /// Number of declared arcs (inhibitor arcs included).
    pub arcs: usize,
    /// `"reachability"`, `"coverability"` (Karp–Miller, the net is or may be unbounded) or
    /// `"none"` (behaviour not explored).
    pub graph: &'static str,
    /// Nodes of that graph.
    pub states: u64,
    /// Edges: one per enabled transition at each expanded state.
    pub edges: u64,
    /// Dead states (no transition enabled), each counted once.
    pub deadlocks: u64,
    /// A shortest firing sequence from M0 to a dead state, as transition ids.
    pub deadlock_witness: Option<Vec<String>>,
    /// Every place bounded; `null` when a partial run could not tell.
    pub bounded: Option<bool>,
    /// Every place holds at most one token.
    pub safe: Option<bool>,
    /// Places found unbounded (ω in the coverability graph).
    pub unbounded_places: Vec<String>,
    /// Bound of each place (`"ω"` unbounded, `null` unknown).
    pub max_tokens: Named<Bound>,
    /// Every transition occurs in every terminal SCC (bounded nets only).
    pub live: Option<bool>,
    /// Transitions that are not live.
    pub non_live_transitions: Vec<String>,
    /// Transitions enabled in no reachable state.
    pub dead_transitions: Vec<String>,
    /// M0 is a home state: the initial state's SCC is the unique terminal SCC.
    pub reversible: Option<bool>,
    /// Minimal P-semiflows (`y·C = 0`), `null` when they could not be computed (see `notes`).
    pub p_invariants: Option<Vec<Named<i64>>>,
    /// The constant `y·M0` of each P-invariant, in the same order.
    pub p_invariant_constants: Option<Vec<i128>>,
    /// Minimal T-semiflows (`C·x = 0`).
    pub t_invariants: Option<Vec<Named<i64>>>,
    /// Some `y > 0` has `y·C = 0` (every place is in a P-semiflow).
    pub conservative: Option<bool>,
    /// Some `y > 0` has `y·C ≤ 0`: bounded for every initial marking.
    pub structurally_bounded: Option<bool>,
    /// Net classes.
    pub classification: Classification,
    /// Minimal siphons, as place ids.
    pub siphons: Vec<Vec<String>>,
    /// The siphon enumeration stopped at its limit.
    pub siphons_truncated: bool,
    /// The minimal siphons that hold no trap marked at M0 (Commoner's condition fails for them).
    pub siphons_without_marked_trap: Vec<Vec<String>>,
    /// Minimal traps, as place ids.
    pub traps: Vec<Vec<String>>,
    /// The trap enumeration stopped at its limit.
    pub traps_truncated: bool,
    /// Findings an engineer should look at (Commoner, deadlocks, unboundedness).
    pub warnings: Vec<String>,
    /// How the results were obtained, and what could not be computed.
    pub notes: Vec<String>,
    /// The run stopped early: counts are lower bounds and verdicts may be missing.
    pub partial: bool,
    /// Why it stopped early: `max_states`, `max_memory`, `timeout`, `cancelled` or
    /// `not_explored`; the notes say more.
    pub partial_reason: Option<PartialReason>,
    /// Bits per packed state (reachability graph only).
    pub bits_per_state: Option<usize>,
    /// Peak bytes of the state store divided by the number of states (the store allocates in
    /// chunks of 65,536 states, so small nets show large values).
    pub bytes_per_state: Option<f64>,
    /// Peak bytes of the state store.
    pub store_bytes: Option<usize>,
    /// Property mode (`--property`, `--reach`, `--always`): the property checked, e.g.
    /// `deadlock` or `reach P1 >= 2`; `null` in a full check.
    pub property: Option<String>,
    /// Whether the property holds; `null` when the run could not decide it.
    pub holds: Option<bool>,
    /// The firing sequence that shows the answer: to a marking satisfying `reach`, to a dead
    /// marking, or to a counterexample of `always`, `bounded`, `safe`, `live`, `reversible`.
    pub witness: Option<Vec<String>>,
    /// The witness is a shortest such sequence (breadth-first search without reduction).
    pub witness_shortest: Option<bool>,
    /// The state-space reduction used in property mode: `stubborn` or `none`.
    pub reduction: Option<&'static str>,
    /// The incidence matrices, for nets of at most 10,000 entries.
    pub incidence: Option<Incidence>,
    /// Time per phase.
    pub timings: Timings,
    /// The chart checks of an SFC program (`crate::sfc::check_chart`); absent for other nets.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sfc: Option<crate::sfc::SfcFindings>,
}

impl Report {
    /// The report of `net` before any analysis has run: its size and classes, every verdict
    /// unknown and every list empty, for the analyses to fill in.
    pub(crate) fn empty(net: &Net) -> Report {
        Report {
            net: net.id().to_string(),
            places: net.num_places(),
            transitions: net.num_transitions(),
            arcs: net.arcs().len(),
            graph: "none",
            states: 0,
            edges: 0,
            deadlocks: 0,
            deadlock_witness: None,
            bounded: None,
            safe: None,
            unbounded_places: Vec::new(),
            max_tokens: Named(Vec::new()),
            live: None,
            non_live_transitions: Vec::new(),
            dead_transitions: Vec::new(),
            reversible: None,
            p_invariants: None,
            p_invariant_constants: None,
            t_invariants: None,
            conservative: None,
            structurally_bounded: None,
            classification: classify(net),
            siphons: Vec::new(),
            siphons_truncated: false,
            siphons_without_marked_trap: Vec::new(),
            traps: Vec::new(),
            traps_truncated: false,
            warnings: Vec::new(),
            notes: Vec::new(),
            partial: false,
            partial_reason: None,
            bits_per_state: None,
            bytes_per_state: None,
            store_bytes: None,
            property: None,
            holds: None,
            witness: None,
            witness_shortest: None,
            reduction: None,
            incidence: None,
            timings: Timings::default(),
            sfc: None,
        }
    }

    /// Marks the report partial for `reason`, with the note that says what to raise.
    pub(crate) fn stopped_early(&mut self, reason: PartialReason, note: String) {
        self.partial = true;
        self.partial_reason = Some(reason);
        self.notes.push(note);
    }
}

/// The file's ids of the transitions `ts` (a firing sequence or a set), for the report.
pub(crate) fn transition_ids(net: &Net, ts: &[TransIdx]) -> Vec<String> {
    ts.iter()
        .map(|t| net.transitions()[t.index()].id.clone())
        .collect()
}

/// The file's id of place `p`, for the report.
pub(crate) fn place_id(net: &Net, p: usize) -> String {
    net.places()[p].id.clone()
}

fn yes_no(b: Option<bool>) -> &'static str {
    match b {
        Some(true) => "yes",
        Some(false) => "no",
        None => "unknown",
    }
}

fn weights(v: &Named<i64>) -> String {
    v.0.iter()
        .map(|(id, w)| {
            if *w == 1 {
                id.clone()
            } else {
                format!("{w}·{id}")
            }
        })
        .collect::<Vec<_>>()
        .join(" + ")
}

/// A firing sequence for people: the empty one stays visible.
fn sequence(w: &[String]) -> String {
    if w.is_empty() {
        "(the initial marking)".into()
    } else {
        w.join(" ")
    }
}

/// The names of the classes the net belongs to.
fn classes(c: &Classification) -> Vec<&'static str> {
    [
        (c.ordinary, "ordinary"),
        (c.pure, "pure"),
        (c.state_machine, "state machine"),
        (c.marked_graph, "marked graph"),
        (c.free_choice, "free choice"),
        (c.extended_free_choice, "extended free choice"),
        (c.inhibitor_arcs, "inhibitor arcs"),
        (c.capacities, "capacities"),
    ]
    .iter()
    .filter(|(b, _)| *b)
    .map(|(_, n)| *n)
    .collect()
}

/// One line of minimal siphons or traps: how many, whether the enumeration was cut, the sets.
fn write_sets(
    f: &mut fmt::Formatter<'_>,
    what: &str,
    sets: &[Vec<String>],
    truncated: bool,
) -> fmt::Result {
    let listed = sets
        .iter()
        .map(|s| format!("{{{}}}", s.join(", ")))
        .collect::<Vec<_>>()
        .join(" ");
    writeln!(
        f,
        "  minimal {what}: {}{} {listed}",
        sets.len(),
        if truncated { " (truncated)" } else { "" },
    )
}

impl Report {
    /// The structure section: classes, invariants, siphons and traps.
    fn fmt_structure(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let classes = classes(&self.classification);
        writeln!(f, "\nstructure")?;
        writeln!(
            f,
            "  classes: {}",
            if classes.is_empty() {
                "none".into()
            } else {
                classes.join(", ")
            }
        )?;
        writeln!(f, "  conservative: {}", yes_no(self.conservative))?;
        writeln!(
            f,
            "  structurally bounded: {}",
            yes_no(self.structurally_bounded)
        )?;
        match (&self.p_invariants, &self.p_invariant_constants) {
            (Some(ps), Some(ks)) => {
                writeln!(f, "  P-invariants: {}", ps.len())?;
                for (p, k) in ps.iter().zip(ks) {
                    writeln!(f, "    {} = {k}", weights(p))?;
                }
            }
            _ => writeln!(f, "  P-invariants: not computed (see notes)")?,
        }
        match &self.t_invariants {
            Some(ts) => {
                writeln!(f, "  T-invariants: {}", ts.len())?;
                for t in ts {
                    writeln!(f, "    {}", weights(t))?;
                }
            }
            None => writeln!(f, "  T-invariants: not computed (see notes)")?,
        }
        write_sets(f, "siphons", &self.siphons, self.siphons_truncated)?;
        write_sets(f, "traps", &self.traps, self.traps_truncated)
    }

    /// The property section, in property mode only.
    fn fmt_property(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let Some(p) = &self.property else {
            return Ok(());
        };
        writeln!(f, "\nproperty {p}: {}", yes_no(self.holds))?;
        if let Some(w) = &self.witness {
            writeln!(
                f,
                "  witness{}: {}",
                if self.witness_shortest == Some(true) {
                    " (shortest)"
                } else {
                    ""
                },
                sequence(w)
            )?;
        }
        if let Some(r) = self.reduction {
            writeln!(f, "  reduction: {r}")?;
        }
        Ok(())
    }

    /// The behaviour section: the graph's figures and the verdicts drawn from it.
    fn fmt_behaviour(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "\nbehaviour ({} graph)", self.graph)?;
        writeln!(f, "  states: {}", self.states)?;
        writeln!(f, "  edges: {}", self.edges)?;
        writeln!(f, "  deadlocks: {}", self.deadlocks)?;
        if let Some(w) = &self.deadlock_witness {
            writeln!(f, "  shortest path to a deadlock: {}", sequence(w))?;
        }
        writeln!(f, "  bounded: {}", yes_no(self.bounded))?;
        if !self.unbounded_places.is_empty() {
            writeln!(
                f,
                "  unbounded places: {}",
                self.unbounded_places.join(", ")
            )?;
        }
        writeln!(f, "  safe: {}", yes_no(self.safe))?;
        let bounds: Vec<String> = self
            .max_tokens
            .0
            .iter()
            .map(|(p, b)| format!("{p}={b}"))
            .collect();
        writeln!(f, "  place bounds: {}", bounds.join(" "))?;
        writeln!(f, "  live: {}", yes_no(self.live))?;
        if !self.non_live_transitions.is_empty() {
            writeln!(f, "  not live: {}", self.non_live_transitions.join(", "))?;
        }
        if !self.dead_transitions.is_empty() {
            writeln!(f, "  never enabled: {}", self.dead_transitions.join(", "))?;
        }
        writeln!(f, "  reversible: {}", yes_no(self.reversible))?;
        if let (Some(b), Some(bytes)) = (self.bits_per_state, self.store_bytes) {
            writeln!(
                f,
                "  state encoding: {b} bits per state; state store peak {:.1} MiB",
                bytes as f64 / (1024.0 * 1024.0)
            )?;
        }
        Ok(())
    }
}

impl fmt::Display for Report {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "net {}: {} places, {} transitions, {} arcs",
            self.net, self.places, self.transitions, self.arcs
        )?;
        if self.partial {
            writeln!(
                f,
                "PARTIAL RESULT ({}): see the notes",
                self.partial_reason
                    .map_or("stopped early".into(), |r| r.to_string())
            )?;
        }
        self.fmt_structure(f)?;
        self.fmt_property(f)?;
        self.fmt_behaviour(f)?;
        if let Some(s) = &self.sfc {
            write!(f, "{s}")?;
        }
        for w in &self.warnings {
            writeln!(f, "\nwarning: {w}")?;
        }
        for n in &self.notes {
            writeln!(f, "note: {n}")?;
        }
        let t = &self.timings;
        writeln!(
            f,
            "\ntime: structure {:.1} ms, invariants {:.1} ms, siphons/traps {:.1} ms, behaviour {:.1} ms",
            t.structure_ms, t.invariants_ms, t.siphons_ms, t.behaviour_ms
        )
    }
}
