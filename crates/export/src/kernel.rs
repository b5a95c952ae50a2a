//! Part 1 of the export: the kernel, the semi-compiled Petri-net algorithm as one
//! FUNCTION_BLOCK that reads the net from the constants of part 2 and knows nothing else of it.
//!
//! Its phases are those of docs/export.md: startup (M := M0 and the incidence C = Post − Pre,
//! on the first scan only), enabling (recomputed only after a firing changed the marking), the
//! decision under the program's policy (firable = enabled ∧ condition), and the marking update,
//! which reports the places entered and left for the actions. The text is the same for every
//! program; only the sizes of its array types (part 2) differ. Its loops are WHILE loops: the
//! dialects disagree on FOR (MATIEC runs `FOR i := 3 TO 3` no time and evaluates the bounds
//! again in every iteration), and a WHILE means the same everywhere.

/// The kernel's declarations and body, in IEC 61131-3 Structured Text. The enabling test
/// stands twice in the body, once against the marking being built in the step (`AVAIL` for the
/// inputs, `NEXT` for the inhibitors and capacities) and once against `M`; it is written once, in
/// [`enabling_test`].
pub(crate) fn text() -> String {
    [
        HEAD,
        &enabling_test("AVAIL", "NEXT", 6),
        STEP_REST,
        &enabling_test("M", "M", 6),
        TAIL,
    ]
    .concat()
}

/// The test that sets `OK := FALSE` when transition `T` is not enabled: an input place of
/// `inputs` holds less than its arc's weight, an inhibitor place of `after` holds its arc's weight
/// or more, or the firing would fill a place of `after` over its capacity.
fn enabling_test(inputs: &str, after: &str, indent: usize) -> String {
    let pre = arc_test(
        "PRE",
        &format!("{inputs}[NET_PRE_PLACE[I]] < NET_PRE_WEIGHT[I]"),
    );
    let inhibitors = arc_test(
        "INHIBITOR",
        &format!("{after}[NET_INHIBITOR_PLACE[I]] >= NET_INHIBITOR_WEIGHT[I]"),
    );
    let capacities = format!(
        "I := C_START[T];
WHILE I < C_START[T + 1] DO
  P := C_PLACE[I];
  IF NET_CAPACITY[P] > 0 AND C_DELTA[I] > 0 THEN
    IF {after}[P] + C_DELTA[I] > NET_CAPACITY[P] THEN
      OK := FALSE;
    END_IF;
  END_IF;
  I := I + 1;
END_WHILE;
"
    );
    [pre, inhibitors, capacities]
        .concat()
        .lines()
        .map(|l| format!("{:indent$}{l}\n", ""))
        .collect()
}

/// The loop over transition `T`'s arcs of the table `NET_<arcs>_*` that sets `OK := FALSE` when
/// an arc `I` `fails`.
fn arc_test(arcs: &str, fails: &str) -> String {
    format!(
        "I := NET_{arcs}_START[T];
WHILE I < NET_{arcs}_START[T + 1] DO
  IF {fails} THEN
    OK := FALSE;
  END_IF;
  I := I + 1;
END_WHILE;
"
    )
}

/// The kernel up to the enabling test of the step.
const HEAD: &str = r#"FUNCTION_BLOCK CETRATUS_KERNEL
(* The semi-compiled Petri-net algorithm. It reads the net from the constants NET_* and keeps
   nothing of it in its code: called once with STARTUP on the first scan, then once a scan after
   the caller has written the condition of each CANDIDATE into COND. *)
VAR_INPUT
  STARTUP : BOOL;                       (* TRUE: M := M0, derive the incidence, and return *)
  COND : CETRATUS_TRANSITION_FLAGS;     (* each candidate's condition in this scan *)
END_VAR
VAR_OUTPUT
  M : CETRATUS_PLACES;                  (* the marking *)
  CANDIDATE : CETRATUS_TRANSITION_FLAGS;(* enabled at M, or may join a step though not *)
  ENTERED : CETRATUS_PLACE_FLAGS;       (* count went from 0 to more in this scan *)
  EXITED : CETRATUS_PLACE_FLAGS;        (* count went to 0 in this scan *)
END_VAR
VAR_EXTERNAL CONSTANT
  NET_PLACES : DINT;
  NET_TRANSITIONS : DINT;
  NET_POLICY : DINT;
  NET_M0 : CETRATUS_PLACES;
  NET_CAPACITY : CETRATUS_PLACES;
  NET_PRE_START : CETRATUS_ROWS;
  NET_PRE_PLACE : CETRATUS_PRE_ARCS;
  NET_PRE_WEIGHT : CETRATUS_PRE_ARCS;
  NET_POST_START : CETRATUS_ROWS;
  NET_POST_PLACE : CETRATUS_POST_ARCS;
  NET_POST_WEIGHT : CETRATUS_POST_ARCS;
  NET_INHIBITOR_START : CETRATUS_ROWS;
  NET_INHIBITOR_PLACE : CETRATUS_INHIBITOR_ARCS;
  NET_INHIBITOR_WEIGHT : CETRATUS_INHIBITOR_ARCS;
  NET_ORDER : CETRATUS_TRANSITIONS;
  NET_PRIORITY : CETRATUS_TRANSITIONS;
  NET_DEPENDENT_START : CETRATUS_PLACE_ROWS;
  NET_DEPENDENT : CETRATUS_DEPENDENTS;
END_VAR
VAR
  C_START : CETRATUS_ROWS;              (* the incidence C = Post - Pre, by transition *)
  C_PLACE : CETRATUS_DELTAS;
  C_DELTA : CETRATUS_DELTAS;
  ENABLED : CETRATUS_TRANSITION_FLAGS;  (* enabled at M *)
  STALE : CETRATUS_TRANSITION_FLAGS;    (* its enabling is to be computed again *)
  LATE : CETRATUS_TRANSITION_FLAGS;     (* may join a step though not enabled at M *)
  AVAIL : CETRATUS_PLACES;              (* M minus what the step consumes *)
  NEXT : CETRATUS_PLACES;               (* M plus the step's C columns *)
  DIRTY : BOOL;
  STARTED : BOOL;
  OK : BOOL;
  P : DINT;
  T : DINT;
  R : DINT;
  I : DINT;
  J : DINT;
  K : DINT;
  CHOSEN : DINT;
END_VAR
IF STARTUP THEN
  (* Startup: M := M0, and C from Pre and Post, sparse. *)
  P := 1;
  WHILE P <= NET_PLACES DO
    M[P] := NET_M0[P];
    P := P + 1;
  END_WHILE;
  K := 1;
  T := 1;
  WHILE T <= NET_TRANSITIONS DO
    C_START[T] := K;
    STALE[T] := TRUE;
    LATE[T] := NET_INHIBITOR_START[T + 1] > NET_INHIBITOR_START[T];
    I := NET_PRE_START[T];
    WHILE I < NET_PRE_START[T + 1] DO
      C_PLACE[K] := NET_PRE_PLACE[I];
      C_DELTA[K] := -NET_PRE_WEIGHT[I];
      K := K + 1;
      I := I + 1;
    END_WHILE;
    I := NET_POST_START[T];
    WHILE I < NET_POST_START[T + 1] DO
      P := NET_POST_PLACE[I];
      R := 0;
      J := C_START[T];
      WHILE J < K DO
        IF C_PLACE[J] = P THEN
          R := J;
        END_IF;
        J := J + 1;
      END_WHILE;
      IF R = 0 THEN
        R := K;
        C_PLACE[K] := P;
        C_DELTA[K] := 0;
        K := K + 1;
      END_IF;
      C_DELTA[R] := C_DELTA[R] + NET_POST_WEIGHT[I];
      IF NET_CAPACITY[P] > 0 AND C_DELTA[R] > 0 THEN
        LATE[T] := TRUE;
      END_IF;
      I := I + 1;
    END_WHILE;
    T := T + 1;
  END_WHILE;
  C_START[NET_TRANSITIONS + 1] := K;
  DIRTY := TRUE;
  STARTED := FALSE;
ELSE
  P := 1;
  WHILE P <= NET_PLACES DO
    AVAIL[P] := M[P];
    NEXT[P] := M[P];
    P := P + 1;
  END_WHILE;
  CHOSEN := 0;
  IF NET_POLICY <> 0 THEN
    (* Single: one firing among the firable, the last (1), the first (2) or the highest
       priority, ties to the first declared (3). *)
    T := 1;
    WHILE T <= NET_TRANSITIONS DO
      IF ENABLED[T] AND COND[T] THEN
        IF NET_POLICY = 1 OR CHOSEN = 0 THEN
          CHOSEN := T;
        ELSIF NET_POLICY = 3 THEN
          IF NET_PRIORITY[T] > NET_PRIORITY[CHOSEN] THEN
            CHOSEN := T;
          END_IF;
        END_IF;
      END_IF;
      T := T + 1;
    END_WHILE;
  END_IF;
  (* The firings, visited by priority, then declaration order: under a single firing the one
     chosen; in a step, each transition whose condition holds, Pre <= M - Pre(chosen), whose
     inhibitors hold and whose outputs fit in M + C(chosen). *)
  R := 1;
  WHILE R <= NET_TRANSITIONS DO
    T := NET_ORDER[R];
    OK := FALSE;
    IF NET_POLICY <> 0 THEN
      OK := T = CHOSEN;
    ELSIF COND[T] AND (ENABLED[T] OR LATE[T]) THEN
      OK := TRUE;
"#;

/// From the step's enabling test to the enabling test at `M`.
const STEP_REST: &str = r#"      IF OK THEN
        I := NET_PRE_START[T];
        WHILE I < NET_PRE_START[T + 1] DO
          AVAIL[NET_PRE_PLACE[I]] := AVAIL[NET_PRE_PLACE[I]] - NET_PRE_WEIGHT[I];
          I := I + 1;
        END_WHILE;
      END_IF;
    END_IF;
    IF OK THEN
      I := C_START[T];
      WHILE I < C_START[T + 1] DO
        NEXT[C_PLACE[I]] := NEXT[C_PLACE[I]] + C_DELTA[I];
        I := I + 1;
      END_WHILE;
    END_IF;
    R := R + 1;
  END_WHILE;
  (* The marking update; the first scan enters every place marked after it. *)
  P := 1;
  WHILE P <= NET_PLACES DO
    IF STARTED THEN
      ENTERED[P] := M[P] = 0 AND NEXT[P] > 0;
    ELSE
      ENTERED[P] := NEXT[P] > 0;
    END_IF;
    EXITED[P] := M[P] > 0 AND NEXT[P] = 0;
    IF NEXT[P] <> M[P] THEN
      (* Only the transitions this place's count can enable or disable are tested again. *)
      DIRTY := TRUE;
      M[P] := NEXT[P];
      I := NET_DEPENDENT_START[P];
      WHILE I < NET_DEPENDENT_START[P + 1] DO
        STALE[NET_DEPENDENT[I]] := TRUE;
        I := I + 1;
      END_WHILE;
    END_IF;
    P := P + 1;
  END_WHILE;
  STARTED := TRUE;
END_IF;
IF DIRTY THEN
  (* Enabling at M, of the stale transitions: Pre <= M, every inhibitor arc M < w, M + C
     within the capacities. *)
  T := 1;
  WHILE T <= NET_TRANSITIONS DO
    IF STALE[T] THEN
      OK := TRUE;
"#;

/// From the enabling test at `M` to the end.
const TAIL: &str = r#"      ENABLED[T] := OK;
      CANDIDATE[T] := OK OR (NET_POLICY = 0 AND LATE[T]);
      STALE[T] := FALSE;
    END_IF;
    T := T + 1;
  END_WHILE;
  DIRTY := FALSE;
END_IF;
END_FUNCTION_BLOCK
"#;
