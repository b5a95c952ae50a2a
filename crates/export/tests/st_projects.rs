//! `--to plcopen` of a program whose action body is Structured Text: its own types and POUs go
//! into the project with their interfaces in XML, and `import plcopen` of the project reads
//! them back as they were written (the behaviour, replayed scan for scan, is checked through
//! the binary in `crates/cli/tests/export_replay.rs`).

use cetratus_export::to_plcopen;
use cetratus_sfc::ImportedPou;

const LIBRARY: &str = "TYPE
  Mode : (Idle, Run := 5, Stop) := Run;
  Pair : STRUCT
    a : INT := -3;
    b : ARRAY [1..3] OF REAL := [1.5, 2(0.0)];
  END_STRUCT;
END_TYPE

FUNCTION Twice : DINT
VAR_INPUT x : DINT; END_VAR
Twice := x * 2;
END_FUNCTION

FUNCTION_BLOCK Counter
VAR_INPUT up : BOOL; END_VAR
VAR_OUTPUT n : DINT := 16#10; END_VAR
VAR
  p : Pair := (a := 1, b := [3.0, 4.0, 5.0]);
  label : STRING[20] := 'a;b:=c';  (* END_VAR in a comment *)
END_VAR
IF up THEN n := Twice(n); END_IF;
END_FUNCTION_BLOCK

PROGRAM Main
VAR_INPUT go AT %IX0.0 : BOOL; END_VAR
VAR_OUTPUT count AT %QW0 : INT; END_VAR
VAR c : Counter; m : Mode; END_VAR
c(up := go);
count := DINT_TO_INT(c.n);
END_PROGRAM

CONFIGURATION Config
  RESOURCE R ON PLC
    TASK T (INTERVAL := T#10ms, PRIORITY := 1);
    PROGRAM Inst WITH T : Main;
  END_RESOURCE
END_CONFIGURATION
";

#[test]
fn a_programs_own_types_and_pous_come_back_from_the_project_as_written() {
    let program = cetratus_sfc::structured::import_st(LIBRARY, "lib.st", Some("Main"))
        .expect("the library imports")
        .program;
    let export = to_plcopen(&program).expect("it exports");
    let back = match cetratus_sfc::import_pou(&export.text, "Main.xml", Some(&export.program)) {
        Ok(ImportedPou::Text(t)) => t,
        Ok(ImportedPou::Chart(_)) => panic!("imported as a chart"),
        Err(e) => panic!("the project does not import: {e}"),
    };
    let st = &back.source;
    for declared in [
        "Mode : (Idle, Run := 5, Stop) := Run;",
        "a : INT := -3;",
        "b : ARRAY [1..3] OF REAL := [1.5, 2(0.0)];",
        "FUNCTION Twice : DINT",
        "n : DINT := 16#10;",
        "p : Pair := (a := 1, b := [3.0, 4.0, 5.0]);",
        "label : STRING[20] := 'a;b:=c';",
        "IF up THEN n := Twice(n); END_IF;",
    ] {
        assert!(st.contains(declared), "`{declared}` is not in:\n{st}");
    }
}
