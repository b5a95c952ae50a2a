//! Load errors say file:line:column and what was expected.

use cetratus_program::Program;
use cetratus_testkit::nets;

const HEAD: &str = r#"[program]
name = "t"
version = "1"
[[input]]
name = "PE"
type = "bool"
[[input]]
name = "count"
type = "int"
[[output]]
name = "CM1"
type = "bool"
"#;

/// Loads HEAD + `rest` and returns the error message (empty when it loads).
fn error(rest: &str) -> String {
    match Program::from_sources(&format!("{HEAD}{rest}"), "prog.toml", nets::vernadat()) {
        Ok(_) => String::new(),
        Err(e) => e.to_string(),
    }
}

fn assert_at(msg: &str, line: u32, column: u32, needle: &str) {
    let prefix = format!("prog.toml:{line}:{column}: ");
    assert!(msg.starts_with(&prefix), "expected {prefix}…, got: {msg}");
    assert!(msg.contains(needle), "expected `{needle}` in: {msg}");
}

#[test]
fn an_unknown_signal_in_a_guard_points_at_the_name_inside_the_string() {
    let msg = error("[guards]\nT10 = \"PE && FOO\"\n");
    assert_at(&msg, 14, 14, "unknown name `FOO`");
    assert!(
        msg.contains("expected an input, a variable or a place"),
        "{msg}"
    );
}

#[test]
fn comparing_a_bool_with_an_int_is_a_type_error_at_the_operator() {
    let msg = error("[guards]\nT10 = \"PE == 3\"\n");
    assert_at(&msg, 14, 11, "cannot compare bool with int");
}

#[test]
fn mixing_int_and_real_suggests_a_conversion() {
    let msg = error("[guards]\nT10 = \"count + 1.5 > 2.0\"\n");
    assert_at(&msg, 14, 14, "real(");
}

#[test]
fn a_guard_that_is_not_a_condition_is_refused() {
    let msg = error("[guards]\nT10 = \"count + 1\"\n");
    assert_at(&msg, 14, 8, "must be a condition (bool)");
}

#[test]
fn a_guard_on_an_unknown_transition_points_at_the_key() {
    let msg = error("[guards]\nT10 = \"PE\"\nT99 = \"PE\"\n");
    assert_at(&msg, 15, 1, "unknown transition `T99`");
}

#[test]
fn bad_guard_syntax_points_at_the_offending_token() {
    let msg = error("[guards]\nT10 = \"PE && (count > 2\"\n");
    assert_at(&msg, 14, 24, "expected `)`");
    let msg = error("[guards]\nT10 = \"PE & PE\"\n");
    assert_at(&msg, 14, 11, "use `&&`");
    let msg = error("[guards]\nT10 = \"count = 2\"\n");
    assert_at(&msg, 14, 14, "use `==`");
}

#[test]
fn a_guard_too_deep_for_the_evaluator_is_refused_at_load() {
    // Right-nested sums need one stack slot per level.
    let mut g = String::from("count");
    for _ in 0..40 {
        g = format!("1 + ({g})");
    }
    let msg = error(&format!("[guards]\nT10 = \"{g} > 0\"\n"));
    assert!(msg.starts_with("prog.toml:14:"), "{msg}");
    assert!(
        msg.contains("nested too deeply") || msg.contains("stack"),
        "{msg}"
    );
}

#[test]
fn an_action_on_an_unknown_place_or_target_is_refused() {
    let msg = error("[[action]]\nplace = \"P99\"\nqualifier = \"N\"\ntarget = \"CM1\"\n");
    assert_at(&msg, 14, 9, "unknown place `P99`");
    let msg = error("[[action]]\nplace = \"P11\"\nqualifier = \"N\"\ntarget = \"PE\"\n");
    assert_at(&msg, 16, 10, "is an input");
    let msg = error("[[action]]\nplace = \"P11\"\nqualifier = \"L\"\ntarget = \"CM1\"\n");
    assert_at(&msg, 15, 13, "needs a duration");
}

#[test]
fn an_unknown_place_in_an_invariant_is_refused() {
    let msg = error("[[invariant]]\nexpr = \"R + P11 + X14 = 1\"\n");
    assert_at(&msg, 14, 19, "unknown place `X14`");
}

#[test]
fn an_invariant_that_does_not_hold_at_m0_is_refused() {
    let msg = error("[[invariant]]\nexpr = \"H + B + 2*P14 = 8\"\n");
    assert_at(&msg, 14, 8, "does not hold at the initial marking");
}

#[test]
fn a_wrong_type_in_the_file_is_reported_by_toml_with_a_position() {
    let msg = error("[[variable]]\nname = \"v\"\ntype = \"int\"\ninitial = true\n");
    assert_at(&msg, 16, 11, "must be a int");
    let msg = error("[[variable]]\nname = \"v\"\ntype = \"integer\"\n");
    assert_at(&msg, 15, 8, "expected bool, int or real");
    let msg = error("[[output]]\nname = \"X\"\ntype = \"bool\"\ncolour = 1\n");
    assert_at(&msg, 16, 1, "unknown field `colour`");
}

#[test]
fn a_signal_named_like_a_place_is_refused() {
    let msg = error("[[input]]\nname = \"P11\"\ntype = \"bool\"\n");
    assert_at(&msg, 14, 8, "same name as a place");
}

#[test]
fn an_unknown_policy_lists_the_choices() {
    let src = "[program]\nname = \"t\"\nversion = \"1\"\npolicy = \"random\"\n";
    let msg = Program::from_sources(src, "prog.toml", nets::vernadat())
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
    assert_at(&msg, 4, 10, "single-last");
}

#[test]
fn a_program_file_that_is_not_utf8_is_refused_while_its_latin1_net_loads() {
    let dir = tempfile::tempdir().expect("temp dir");
    // The net in ISO-8859-1, as PIPE writes it: its name holds an é as the byte 0xE9.
    let pnml = std::fs::read_to_string(cetratus_testkit::paths::example("vernadat/vernadat.pnml"))
        .expect("read the example net")
        .replacen("encoding=\"UTF-8\"", "encoding=\"ISO-8859-1\"", 1)
        .replacen("Vernadat cell", "Vernadat cell \u{e9}", 1);
    let latin1: Vec<u8> = pnml.chars().map(|c| c as u32 as u8).collect();
    std::fs::write(dir.path().join("net.pnml"), latin1).expect("write the net");
    let toml = "[program]\nname = \"t\"\nversion = \"1\"\nnet = \"net.pnml\"\n";
    std::fs::write(dir.path().join("prog.toml"), toml).expect("write the program");
    let p = Program::load(&dir.path().join("prog.toml")).expect("a Latin-1 net loads");
    assert_eq!(p.net().name(), Some("Vernadat cell \u{e9}"));

    let mut bytes = toml.as_bytes().to_vec();
    bytes.extend_from_slice(b"description = \"caf\xE9\"\n");
    std::fs::write(dir.path().join("prog.toml"), bytes).expect("write the program");
    let msg = Program::load(&dir.path().join("prog.toml"))
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
    assert!(
        msg.contains("prog.toml:5:19: the file is not UTF-8"),
        "{msg}"
    );
    assert!(msg.contains("byte offset 70"), "{msg}");
}

#[test]
fn watchdogs_resolve_their_places_and_refuse_unknown_places_zero_times_and_doubles() {
    let ok = format!(
        "{HEAD}[[watchdog]]\nplace = \"P11\"\nmax = \"10s\"\n[[watchdog]]\nplace = \"P21\"\nmax = \"500ms\"\n[stall]\nno_firing = \"30s\"\n"
    );
    let p = Program::from_sources(&ok, "prog.toml", nets::vernadat()).expect("loads");
    let net = p.net();
    let got: Vec<(String, u64)> = p
        .watchdogs()
        .iter()
        .map(|w| (net.place(w.place).id.clone(), w.max_us))
        .collect();
    assert_eq!(
        got,
        [
            ("P11".to_string(), 10_000_000),
            ("P21".to_string(), 500_000)
        ]
    );
    assert_eq!(p.no_firing_us(), Some(30_000_000));

    let msg = error("[[watchdog]]\nplace = \"P99\"\nmax = \"10s\"\n");
    assert_at(&msg, 14, 9, "`P99` is not a place");
    let msg = error("[[watchdog]]\nplace = \"P11\"\nmax = \"0s\"\n");
    assert_at(&msg, 15, 7, "longer than 0");
    let msg = error(
        "[[watchdog]]\nplace = \"P11\"\nmax = \"1s\"\n[[watchdog]]\nplace = \"P11\"\nmax = \"2s\"\n",
    );
    assert_at(&msg, 17, 9, "has a [[watchdog]] already");
    let msg = error("[stall]\nno_firing = \"30s\"\n");
    assert_at(&msg, 14, 13, "there are none");
}
