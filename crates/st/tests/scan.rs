//! Programs compiled and run scan by scan, their outputs checked by hand.

use cetratus_st::types::Ty;
use cetratus_st::{compile, parse, Source, State, Unit, Work};

const MS: i64 = 1_000_000;

fn build(text: &str) -> Unit {
    let src = Source {
        origin: "test.st",
        text,
    };
    let lib = parse::parse_library(text).unwrap_or_else(|d| panic!("{}", src.error(d)));
    compile(&lib, None).unwrap_or_else(|d| panic!("{}", src.error(d)))
}

fn slot(unit: &Unit, state: &State, name: &str) -> u64 {
    let v = unit
        .var(name)
        .unwrap_or_else(|| panic!("no variable {name}"));
    assert!(matches!(v.ty, Ty::Elem(_) | Ty::Enum(_)));
    state.slots[v.at.slots as usize]
}

fn set(unit: &Unit, state: &mut State, name: &str, bits: u64) {
    let v = unit
        .var(name)
        .unwrap_or_else(|| panic!("no variable {name}"));
    state.slots[v.at.slots as usize] = bits;
}

fn scan(unit: &Unit, state: &mut State, k: i64) {
    unit.run(state, k * 10 * MS, &mut Work::unlimited())
        .unwrap_or_else(|f| panic!("fault {f:?}"));
}

#[test]
fn an_int_counter_wraps_at_the_type_s_width() {
    let u = build(
        "PROGRAM P VAR_OUTPUT y : INT := 32766; z : DINT; END_VAR
         y := y + 1; z := INT_TO_DINT(y) * 2; END_PROGRAM",
    );
    let mut s = u.new_state();
    scan(&u, &mut s, 0);
    assert_eq!(slot(&u, &s, "y") as i64, 32767);
    scan(&u, &mut s, 1);
    assert_eq!(slot(&u, &s, "y") as i64, -32768);
    assert_eq!(slot(&u, &s, "z") as i64, -65536);
}

#[test]
fn a_ton_called_in_a_body_sets_q_after_its_preset() {
    let u = build(
        "PROGRAM P VAR_INPUT x : BOOL; END_VAR VAR_OUTPUT q : BOOL; END_VAR
         VAR t : TON; END_VAR
         t(IN := x, PT := T#30ms);
         IF t.Q THEN q := TRUE; ELSE q := FALSE; END_IF
         END_PROGRAM",
    );
    let mut s = u.new_state();
    set(&u, &mut s, "x", 1);
    let q: Vec<u64> = (0..5)
        .map(|k| {
            scan(&u, &mut s, k);
            slot(&u, &s, "q")
        })
        .collect();
    assert_eq!(q, [0, 0, 0, 1, 1]);
}

#[test]
fn loops_arrays_case_and_functions_compute_what_they_say() {
    let u = build(
        "FUNCTION Sq : DINT VAR_INPUT v : DINT; END_VAR Sq := v * v; END_FUNCTION
         FUNCTION_BLOCK Acc VAR_INPUT d : DINT; END_VAR VAR_OUTPUT total : DINT; END_VAR
           total := total + d; END_FUNCTION_BLOCK
         PROGRAM P VAR_OUTPUT y : DINT; w : DINT; c : INT; END_VAR
         VAR a : ARRAY[1..5] OF DINT := [1, 2, 3(7)]; i : INT; acc : Acc; END_VAR
         y := 0;
         FOR i := 1 TO 5 DO y := y + Sq(a[i]); END_FOR;
         acc(d := 2);
         w := acc.total;
         CASE i OF 1..5: c := 1; 6: c := 2; ELSE c := 3; END_CASE;
         WHILE c < 10 DO c := c + 4; IF c > 8 THEN EXIT; END_IF; END_WHILE;
         END_PROGRAM",
    );
    let mut s = u.new_state();
    scan(&u, &mut s, 0);
    assert_eq!(slot(&u, &s, "y") as i64, 1 + 4 + 49 * 3);
    assert_eq!(slot(&u, &s, "c") as i64, 10);
    scan(&u, &mut s, 1);
    assert_eq!(slot(&u, &s, "w") as i64, 4);
}

#[test]
fn a_loop_that_never_ends_is_stopped_by_the_work_budget() {
    let u =
        build("PROGRAM P VAR x : DINT; END_VAR WHILE TRUE DO x := x + 1; END_WHILE END_PROGRAM");
    let mut s = u.new_state();
    let err = u.run(&mut s, 0, &mut Work::within(10_000)).unwrap_err();
    assert_eq!(err.kind, cetratus_st::code::FaultKind::Budget);
}

#[test]
fn two_timers_make_a_blinker() {
    let u = build(
        "PROGRAM Blink
VAR_INPUT run : BOOL; END_VAR
VAR_OUTPUT lamp : BOOL; count : INT; END_VAR
VAR t_on : TON; t_off : TON; END_VAR
t_on(IN := run AND NOT t_off.Q, PT := T#50ms);
t_off(IN := t_on.Q, PT := T#50ms);
lamp := run AND NOT t_on.Q;
END_PROGRAM",
    );
    let mut s = u.new_state();
    set(&u, &mut s, "run", 1);
    let lamp: Vec<u64> = (0..24)
        .map(|k| {
            scan(&u, &mut s, k);
            slot(&u, &s, "lamp")
        })
        .collect();
    // t_off sees t_on.Q a scan late, and t_on restarts the scan after t_off resets it.
    assert_eq!(
        lamp,
        [1, 1, 1, 1, 1, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0, 0, 1]
    );
}

#[test]
fn small_integers_are_computed_in_32_bits_and_cut_where_stored() {
    let u = build(
        "PROGRAM P VAR_OUTPUT a : INT; b : BOOL; c : INT; d : UINT; END_VAR
         VAR x : INT := 100; m : INT := 32767; u0 : UINT; u2 : UINT := 2; END_VAR
         a := (x * 1000) / 1000;
         b := m + 1 > m;
         c := m + 1;
         d := (u0 - u2) / 2;
         END_PROGRAM",
    );
    let mut s = u.new_state();
    scan(&u, &mut s, 0);
    assert_eq!(slot(&u, &s, "a") as i64, 100);
    assert_eq!(slot(&u, &s, "b"), 1);
    assert_eq!(slot(&u, &s, "c") as i64, -32768);
    assert_eq!(slot(&u, &s, "d"), 65535);
}

/// An index outside an array's bounds faults, naming the index and the bounds, in the
/// one-instruction path of a one-dimensional array of an elementary type and in the general
/// one (two dimensions, structures); a negative lower bound counts as declared.
#[test]
fn an_index_outside_the_bounds_faults_naming_it_in_every_addressing_path() {
    use cetratus_st::code::FaultKind;
    let u = build(
        "TYPE Pt : STRUCT x : INT; s : STRING[4]; END_STRUCT; END_TYPE
         PROGRAM P
         VAR i : INT; j : INT; k : INT; v : INT;
             a : ARRAY[-2..2] OF INT; m : ARRAY[0..1, 0..2] OF INT; p : ARRAY[0..1] OF Pt;
         END_VAR
         CASE k OF
           0: a[i] := 7; v := a[i];
           1: m[i, j] := 7; v := m[i, j];
           2: p[i].x := 7; v := p[i].x;
         END_CASE;
         END_PROGRAM",
    );
    let run = |k: u64, i: i64, j: i64| {
        let mut s = u.new_state();
        set(&u, &mut s, "k", k);
        set(&u, &mut s, "i", i as u64);
        set(&u, &mut s, "j", j as u64);
        u.run(&mut s, 0, &mut Work::unlimited())
            .map(|()| slot(&u, &s, "v"))
            .map_err(|f| f.kind)
    };
    assert_eq!(run(0, -2, 0), Ok(7));
    assert_eq!(run(0, 2, 0), Ok(7));
    let out = |index, lo, hi| Err(FaultKind::IndexOutOfRange { index, lo, hi });
    assert_eq!(run(0, 3, 0), out(3, -2, 2));
    assert_eq!(run(0, -3, 0), out(-3, -2, 2));
    assert_eq!(run(1, 1, 2), Ok(7));
    assert_eq!(run(1, 1, 3), out(3, 0, 2));
    assert_eq!(run(2, 1, 0), Ok(7));
    assert_eq!(run(2, 2, 0), out(2, 0, 1));
}

/// The error `text` is refused with, as file:line:column: message.
fn refusal(text: &str) -> String {
    let src = Source {
        origin: "test.st",
        text,
    };
    let lib = parse::parse_library(text).unwrap_or_else(|d| panic!("{}", src.error(d)));
    match compile(&lib, None) {
        Ok(_) => panic!("compiled"),
        Err(d) => src.error(d).to_string(),
    }
}

const GLOBALS: &str = "
CONFIGURATION C
  VAR_GLOBAL total : DINT := 100; END_VAR
  VAR_GLOBAL CONSTANT step_size : DINT := 5; END_VAR
  RESOURCE R ON PLC
    TASK T(INTERVAL := T#10ms, PRIORITY := 1);
    PROGRAM main WITH T : P;
  END_RESOURCE
END_CONFIGURATION";

#[test]
fn var_external_reaches_the_configuration_s_globals_from_programs_functions_and_blocks() {
    let u = build(&format!(
        "FUNCTION Next : DINT VAR_INPUT v : DINT; END_VAR
           VAR_EXTERNAL CONSTANT step_size : DINT; END_VAR
           Next := v + step_size; END_FUNCTION
         FUNCTION_BLOCK Bump VAR_EXTERNAL total : DINT; END_VAR
           total := Next(total); END_FUNCTION_BLOCK
         PROGRAM P VAR_EXTERNAL total : DINT; END_VAR
           VAR b1 : Bump; b2 : Bump; END_VAR VAR_OUTPUT seen : DINT; END_VAR
           b1(); b2(); seen := total; END_PROGRAM
         {GLOBALS}"
    ));
    let mut s = u.new_state();
    scan(&u, &mut s, 0);
    // Both instances bump the one global: it is shared, not copied into each.
    assert_eq!(slot(&u, &s, "seen") as i64, 110);
    scan(&u, &mut s, 1);
    assert_eq!(slot(&u, &s, "total") as i64, 120);
    // The globals are variables of the unit, as the Monitor and persistence see them.
    let g = u.var("step_size").expect("the global");
    assert_eq!(g.section, cetratus_st::ast::Section::Global);
    assert!(g.constant);
}

#[test]
fn a_var_external_that_does_not_match_a_global_is_refused_at_its_place() {
    let missing = refusal(&format!(
        "PROGRAM P VAR_EXTERNAL nothing : DINT; END_VAR nothing := 1; END_PROGRAM {GLOBALS}"
    ));
    assert!(missing.contains("test.st:1:"), "{missing}");
    assert!(missing.contains("names no VAR_GLOBAL"), "{missing}");
    let retyped = refusal(&format!(
        "PROGRAM P VAR_EXTERNAL total : INT; END_VAR total := 1; END_PROGRAM {GLOBALS}"
    ));
    assert!(
        retyped.contains("declared INT but the global is DINT"),
        "{retyped}"
    );
    let constant = refusal(&format!(
        "PROGRAM P VAR_EXTERNAL step_size : DINT; END_VAR step_size := 1; END_PROGRAM {GLOBALS}"
    ));
    assert!(
        constant.to_ascii_lowercase().contains("constant"),
        "{constant}"
    );
    let shadow = refusal(&format!(
        "PROGRAM P VAR total : DINT; END_VAR total := 1; END_PROGRAM {GLOBALS}"
    ));
    assert!(shadow.contains("has the name of a VAR_GLOBAL"), "{shadow}");
}

#[test]
fn operators_called_as_functions_and_bool_literals_0_and_1_read_as_iec_writes_them() {
    let u = build(
        "PROGRAM P VAR_OUTPUT a : BOOL; o : BOOL; x : BOOL; m : INT; b : BOOL; END_VAR
         a := AND(TRUE, TRUE, FALSE); o := OR(FALSE, FALSE, TRUE); x := XOR(TRUE, FALSE);
         m := MOD(INT#7, 3); b := 1; END_PROGRAM",
    );
    let mut s = u.new_state();
    scan(&u, &mut s, 0);
    let got: Vec<u64> = ["a", "o", "x", "m", "b"]
        .iter()
        .map(|n| slot(&u, &s, n))
        .collect();
    assert_eq!(got, [0, 1, 1, 1, 1]);
}
