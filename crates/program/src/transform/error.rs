//! Why a transform or projection could not be resolved, or refused to apply.

use cetratus_net::Tokens;

use crate::InvariantViolation;

/// Why a transform or projection could not be resolved, or refused to apply.
#[derive(Debug, thiserror::Error)]
pub enum TransformError {
    /// The matrix has the wrong number of rows or columns for a net.
    #[error("the {what} has {found} {axis}, but the {net} net has {expected} places; {axis} follow its places in declaration order")]
    Dimensions {
        /// "state transform" or "projection".
        what: &'static str,
        /// "rows" or "columns".
        axis: &'static str,
        /// Which net the axis follows.
        net: &'static str,
        /// Places of that net.
        expected: usize,
        /// What the matrix has.
        found: usize,
    },
    /// A row of a dense matrix has the wrong length.
    #[error("row {row} (`{id}`) of the {what} has {found} entries; it needs one per place of the {net} net ({expected})")]
    RowLength {
        /// "state transform" or "projection".
        what: &'static str,
        /// The row, from 1.
        row: usize,
        /// The row's place id.
        id: String,
        /// Which net the columns follow.
        net: &'static str,
        /// Places of that net.
        expected: usize,
        /// What the row has.
        found: usize,
    },
    /// The base vector has the wrong length.
    #[error("the base of the {what} has {found} entries; it needs one per row ({expected})")]
    BaseLength {
        /// "state transform" or "projection".
        what: &'static str,
        /// Rows.
        expected: usize,
        /// What the base has.
        found: usize,
    },
    /// A row or column id of a dense matrix differs from the net's place at that position.
    #[error("{axis} {index} of the {what} is `{found}`, but place {index} of the {net} net is `{expected}`; list the {net} net's place ids in declaration order")]
    PlaceId {
        /// "state transform" or "projection".
        what: &'static str,
        /// "row" or "column".
        axis: &'static str,
        /// The position, from 1.
        index: usize,
        /// Which net.
        net: &'static str,
        /// The net's place id there.
        expected: String,
        /// The id the matrix gives.
        found: String,
    },
    /// A sparse entry or base key names a place the net does not have.
    #[error("the {what} names `{id}` as {role}, which is not a place of the {net} net")]
    UnknownPlace {
        /// "state transform" or "projection".
        what: &'static str,
        /// The id.
        id: String,
        /// Where it was used ("a target (`to`)", "a source (`from`)", "a base key").
        role: &'static str,
        /// Which net.
        net: &'static str,
    },
    /// A sparse matrix gives the same (to, from) pair twice.
    #[error("the {what} gives `{to}` <- `{from}` twice; give each pair once")]
    DuplicateEntry {
        /// "state transform" or "projection".
        what: &'static str,
        /// Row place.
        to: String,
        /// Column place.
        from: String,
    },
    /// A chart's step that the new version removes, that the old version can reach, and that
    /// `removed` does not map.
    #[error("step `{id}` is removed by the new version, and the running chart can reach it (its net lets it be marked, guards ignored); map it to a step of the new version with `[transform.removed] {id} = \"…\"`")]
    RemovedReachable {
        /// The step.
        id: String,
    },
    /// `removed` names a place the new net still has.
    #[error("`{id}` is listed in `removed`, but the new net still has a place `{id}`, which keeps its tokens; remove it from `removed`")]
    RemovedIsKept {
        /// The place.
        id: String,
    },
    /// `removed` names a place the old net does not have.
    #[error("`{id}` is listed in `removed`, but the running program's net has no such place")]
    RemovedUnknown {
        /// The place.
        id: String,
    },
    /// `removed` sends tokens to a place the new net does not have.
    #[error(
        "removed place `{from}` sends its tokens to `{to}`, which is not a place of the new net"
    )]
    RemovedTargetUnknown {
        /// The removed place.
        from: String,
        /// The missing destination.
        to: String,
    },
    /// A marking or output buffer has a length other than the one the transform was resolved for.
    #[error("the {what} was resolved for {expected} places, but the {which} has {found}; resolve it against this program")]
    MarkingLength {
        /// "state transform" or "projection".
        what: &'static str,
        /// "old marking", "new program" or "output marking".
        which: &'static str,
        /// Places the transform expects.
        expected: usize,
        /// What was given.
        found: usize,
    },
    /// A row evaluates to a negative token count.
    #[error("place `{place}` would get {value} tokens, a negative count; check the coefficients and base of its row")]
    Negative {
        /// The new place.
        place: String,
        /// The value computed.
        value: i128,
    },
    /// A row evaluates to more tokens than a count can hold.
    #[error("place `{place}` would get {value} tokens, more than a token count can hold ({max})", max = Tokens::MAX)]
    Overflow {
        /// The new place.
        place: String,
        /// The value computed.
        value: i128,
    },
    /// A row evaluates above the place's capacity in the new net.
    #[error("place `{place}` would get {value} tokens, above its capacity {capacity} in the new net; wait for a marking that fits, or fix the transform")]
    AboveCapacity {
        /// The new place.
        place: String,
        /// The value computed.
        value: u64,
        /// Its capacity.
        capacity: Tokens,
    },
    /// A place the update removes holds tokens and the package says nowhere for them to go.
    #[error("place `{place}` is removed by the update and holds {tokens} token(s) that would be lost; apply the update when it is empty, or send its tokens to a new place (generated: `removed = {{ {place} = \"…\" }}`; dense or sparse: a nonzero coefficient in its column)")]
    RemovedNotEmpty {
        /// The old place.
        place: String,
        /// Its tokens.
        tokens: Tokens,
    },
    /// The initial markings changed an invariant's constant, and more than one base on the
    /// places whose initial marking changed makes up for it.
    #[error("the generated {what} cannot tell where the difference of the {net} net's invariant `{invariant}` goes: its initial marking holds {needed}, the state carried over {carried}, and {places} all changed their initial marking; write the {what} with its base, e.g. kind = \"sparse\", identity_on_kept = true, base = {{ {example} = {change} }}",
        what = .0.what, net = .0.net, invariant = .0.invariant, needed = .0.needed,
        carried = .0.carried, places = .0.places, example = .0.example, change = .0.change)]
    InvariantAmbiguous(Box<Derivation>),
    /// The initial markings changed an invariant's constant, and no base on the places whose
    /// initial marking changed makes up for it.
    #[error("the generated {what} cannot keep the {net} net's invariant `{invariant}`: its initial marking holds {needed}, the state carried over {carried}, and {why}; fix the initial marking, or write the {what} with its matrix and base",
        what = .0.what, net = .0.net, invariant = .0.invariant, needed = .0.needed,
        carried = .0.carried, why = .0.why)]
    InvariantImpossible(Box<Derivation>),
    /// The transformed marking breaks an invariant the new program declares.
    #[error("the transformed marking breaks the new program's {violation}; fix the transform's matrix or base so that it holds")]
    Invariant {
        /// Which invariant and by how much.
        violation: InvariantViolation,
    },
}

/// An invariant a generated base could not be derived for (`derive.rs`): which, and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Derivation {
    /// "state transform" or "projection".
    pub what: &'static str,
    /// The net the invariant is of.
    pub net: &'static str,
    /// The invariant, as its weighted places.
    pub invariant: String,
    /// What the map carries over from the running state.
    pub carried: i128,
    /// What the net's initial marking says it holds.
    pub needed: i128,
    /// Ambiguous: the places whose initial marking changed, in the invariant.
    pub places: String,
    /// Ambiguous: one of them, for the example to write.
    pub example: String,
    /// The difference to make up.
    pub change: i128,
    /// Impossible: why no base does.
    pub why: String,
}
