//! Constructs refused by name, error positions, bounds, and corrupted programs.

#![allow(unused_imports)]
use super::*;

// ---- Refused by name ----

#[test]
fn an_instruction_list_body_is_refused_by_name() {
    let il = "PROGRAM P\nVAR a, b : BOOL; END_VAR\n  LD a\n  ANDN b\n  ST c\nEND_PROGRAM";
    let d = lib_err(il);
    assert!(d
        .message
        .starts_with("Instruction List (IL) is not supported"));
    assert_eq!(
        Source {
            origin: "t",
            text: il
        }
        .locate(d.pos),
        (3, 3)
    );
    let d = stmts_err("start: LD %IX0.0\nST q");
    assert!(d
        .message
        .starts_with("Instruction List (IL) is not supported"));
    let d = stmts_err("x := 1;\nRET\n");
    assert!(d
        .message
        .starts_with("Instruction List (IL) is not supported"));
    // A variable that shares a mnemonic's name is still a variable.
    assert_eq!(stmts("LD := 1; ST := LD; S(1);").len(), 3);
}

#[test]
fn sfc_in_text_form_is_refused_by_name() {
    for body in [
        "INITIAL_STEP s0: END_STEP",
        "STEP s1: a(N); END_STEP",
        "TRANSITION FROM s0 TO s1 := x; END_TRANSITION",
        "ACTION a: x := 1; END_ACTION",
    ] {
        let d = stmts_err(body);
        assert!(
            d.message
                .starts_with("Sequential Function Chart (SFC) in text form"),
            "{body}: {}",
            d.message
        );
    }
    // As names, the words are free.
    assert_eq!(stmts("step := step + 1; action := transition;").len(), 2);
}

#[test]
fn pointers_and_references_are_refused_by_name() {
    let cases = [
        "PROGRAM P VAR p : REF_TO INT; END_VAR END_PROGRAM",
        "PROGRAM P VAR p : POINTER TO INT; END_VAR END_PROGRAM",
        "PROGRAM P p^ := 1; END_PROGRAM",
        "PROGRAM P p := ADR(x); END_PROGRAM",
        "PROGRAM P p := REF(x); END_PROGRAM",
    ];
    for text in cases {
        let d = lib_err(text);
        assert!(
            d.message.starts_with("pointers and references"),
            "{text}: {}",
            d.message
        );
    }
}

#[test]
fn methods_and_interfaces_are_refused_by_name() {
    let cases = [
        "FUNCTION_BLOCK F METHOD M : INT END_METHOD END_FUNCTION_BLOCK",
        "FUNCTION_BLOCK F EXTENDS G END_FUNCTION_BLOCK",
        "FUNCTION_BLOCK F IMPLEMENTS I END_FUNCTION_BLOCK",
        "INTERFACE I END_INTERFACE",
        "FUNCTION_BLOCK F x := 1; PROPERTY P : INT END_PROPERTY END_FUNCTION_BLOCK",
        "CLASS C END_CLASS",
        "TYPE S EXTENDS T : STRUCT END_STRUCT END_TYPE",
    ];
    for text in cases {
        let d = lib_err(text);
        assert!(
            d.message.starts_with("object-oriented extensions"),
            "{text}: {}",
            d.message
        );
    }
}

#[test]
fn wstring_and_the_date_types_are_refused_by_name() {
    for text in [
        "PROGRAM P VAR s : WSTRING; END_VAR END_PROGRAM",
        "PROGRAM P s := \"wide\"; END_PROGRAM",
        "PROGRAM P s := WSTRING#'x'; END_PROGRAM",
    ] {
        assert!(lib_err(text).message.starts_with("WSTRING"), "{text}");
    }
    for ty in ["DATE", "TOD", "TIME_OF_DAY", "DT", "DATE_AND_TIME", "ldt"] {
        let text = format!("PROGRAM P VAR d : {ty}; END_VAR END_PROGRAM");
        assert!(
            lib_err(&text).message.starts_with("DATE, TIME_OF_DAY"),
            "{ty}"
        );
    }
    for literal in [
        "D#2024-01-01",
        "DATE#2024-01-01",
        "TOD#12:00:00",
        "DT#2024-01-01-12:00",
        "TIME_OF_DAY#1:2:3",
    ] {
        let d = expr_err(literal);
        assert!(
            d.message.starts_with("DATE, TIME_OF_DAY"),
            "{literal}: {}",
            d.message
        );
        assert_eq!(d.pos, 0);
    }
}

#[test]
fn a_variable_named_dt_or_date_is_a_variable() {
    let l = lib(
        "PROGRAM P VAR dt : TIME; date : INT; END_VAR dt := dt + T#1ms; date := 1; END_PROGRAM",
    );
    assert_eq!(l.pous[0].body.len(), 2);
}

#[test]
fn jumps_labels_and_continue_are_refused_by_name() {
    assert!(stmts_err("JMP done;")
        .message
        .starts_with("JMP and labels are not supported"));
    assert!(stmts_err("x := 1; done: x := 2;")
        .message
        .starts_with("JMP and labels are not supported"));
    assert!(stmts_err("WHILE a DO CONTINUE; END_WHILE")
        .message
        .starts_with("CONTINUE is not supported"));
}

#[test]
fn other_refusals_name_the_construct() {
    let cases = [
        (
            "PROGRAM P VAR_ACCESS a : x : INT; END_VAR END_PROGRAM",
            "VAR_ACCESS and VAR_CONFIG",
        ),
        (
            "FUNCTION_BLOCK F VAR_INPUT x : BOOL R_EDGE; END_VAR END_FUNCTION_BLOCK",
            "R_EDGE and F_EDGE",
        ),
        (
            "PROGRAM P VAR a : ARRAY [*] OF INT; END_VAR END_PROGRAM",
            "ARRAY [*]",
        ),
        (
            "PROGRAM P x := %IX0.0; END_PROGRAM",
            "a direct address cannot be used",
        ),
        ("PROGRAM P x := y.3; END_PROGRAM", "bit access (x.3)"),
        (
            "PROGRAM P VAR AT %IX0.0 : BOOL; END_VAR END_PROGRAM",
            "a located variable needs a name",
        ),
        (
            "PROGRAM P VAR x AT %I* : BOOL; END_VAR END_PROGRAM",
            "an address left open",
        ),
        (
            "PROGRAM P x ?= y; END_PROGRAM",
            "the assignment attempt '?='",
        ),
        (
            "CONFIGURATION C PROGRAM I : P (a := b); END_CONFIGURATION",
            "connecting a program instance's variables",
        ),
    ];
    for (text, part) in cases {
        let d = lib_err(text);
        assert!(d.message.contains(part), "{text}: {}", d.message);
    }
}

// ---- Errors ----

#[test]
fn an_error_in_the_middle_of_a_file_is_located_at_its_line_and_column() {
    let text = "PROGRAM Main\nVAR\n  x : INT;\nEND_VAR\nx := 1;\nIF x > 0 THEN\n  x := x +* 2;\nEND_IF;\nEND_PROGRAM\n";
    let d = lib_err(text);
    assert_eq!(d.message, "expected an expression, found '*'");
    let e = Source {
        origin: "main.st",
        text,
    }
    .error(d);
    assert_eq!((e.line, e.column), (7, 11));
    assert_eq!(
        e.to_string(),
        "main.st:7:11: expected an expression, found '*'"
    );
}

#[test]
fn a_column_counts_characters_not_bytes() {
    let text = "x := 'äöü'; y := ;";
    let d = stmts_err(text);
    assert_eq!(Source { origin: "t", text }.locate(d.pos), (1, 18));
}

#[test]
fn errors_come_in_the_order_of_the_text() {
    // A syntax error before a lexical one is the one reported.
    let d = stmts_err("x := ;\ny := 'unclosed");
    assert_eq!(d.message, "expected an expression, found ';'");
    let d = stmts_err("x := 1;\ny := 'unclosed");
    assert!(d
        .message
        .starts_with("the string that starts here is never closed"));
    assert_eq!(d.pos, 13);
}

#[test]
fn a_long_token_is_shortened_in_a_message() {
    let long = "a".repeat(100);
    let d = stmts_err(&format!("x := 1 {long} := 2;"));
    assert_eq!(
        d.message,
        format!(
            "expected ';' after the assignment, found '{}…'",
            "a".repeat(32)
        )
    );
}

// ---- Bounds ----

fn nested_ifs(n: usize) -> String {
    "IF a THEN ".repeat(n) + "x := 1;" + &" END_IF;".repeat(n)
}

#[test]
fn nesting_at_the_limit_is_accepted_and_past_it_refused_naming_the_limit() {
    stmts(&nested_ifs(MAX_NESTING));
    let d = stmts_err(&nested_ifs(MAX_NESTING + 1));
    assert!(
        d.message
            .contains(&format!("more than {MAX_NESTING} levels")),
        "{}",
        d.message
    );
    let parens = |n: usize| "(".repeat(n) + "a" + &")".repeat(n);
    expr(&parens(MAX_NESTING));
    assert!(expr_err(&parens(MAX_NESTING + 1))
        .message
        .starts_with("nested too deeply"));
    assert!(expr_err(&"NOT ".repeat(MAX_NESTING + 1))
        .message
        .starts_with("nested too deeply"));
    let arrays = "ARRAY [1..2] OF ".repeat(MAX_NESTING + 1);
    let d = lib_err(&format!("TYPE A : {arrays} INT; END_TYPE"));
    assert!(d.message.starts_with("nested too deeply"));
    let inits = "[".repeat(MAX_NESTING + 1) + &"]".repeat(MAX_NESTING + 1);
    let d = lib_err(&format!(
        "PROGRAM P VAR a : INT := {inits}; END_VAR END_PROGRAM"
    ));
    assert!(d.message.starts_with("nested too deeply"));
}

#[test]
fn a_flat_chain_deeper_than_max_depth_is_refused() {
    let chain = |n: usize| vec!["a"; n].join(" + ");
    expr(&chain(MAX_DEPTH));
    let d = expr_err(&chain(MAX_DEPTH + 2));
    assert!(d.message.starts_with(&format!(
        "the expression is too deep: more than {MAX_DEPTH} levels"
    )));
    let members = "a".to_string() + &".b".repeat(MAX_DEPTH + 1);
    assert!(expr_err(&members)
        .message
        .starts_with("the expression is too deep"));
    // Depth is carried through parentheses, so they cannot hide it.
    let grouped = format!("({}) + ({})", chain(200), chain(200));
    expr(&grouped);
    let deep = format!("({}) * 2 + 1", chain(MAX_DEPTH));
    assert!(expr_err(&deep)
        .message
        .starts_with("the expression is too deep"));
}

#[test]
fn pathological_inputs_neither_overflow_the_stack_nor_panic() {
    let n = 200_000;
    let inputs = [
        "(".repeat(n),
        "NOT ".repeat(n),
        "-".repeat(n),
        "IF a THEN ".repeat(n),
        "REPEAT ".repeat(n),
        "x := ".to_string() + &vec!["a"; n].join(" + ") + ";",
        "x := ".to_string() + &vec!["a"; n].join(" ** ") + ";",
        "x := a".to_string() + &".b".repeat(n) + ";",
        "x := a".to_string() + &"[1]".repeat(n) + ";",
        "F(".repeat(n),
        "x := [".to_string() + &"[".repeat(n),
        ";".repeat(n),
        "(*".repeat(n),
    ];
    for input in &inputs {
        let _ = parse_statements(input);
        let _ = parse_expression(input);
        let _ = parse_library(&format!("PROGRAM P {input} END_PROGRAM"));
        let _ = parse_library(&format!("TYPE T : {input}"));
        let _ = parse_library(&format!("PROGRAM P VAR a : INT := {input}"));
    }
}

#[test]
fn a_text_over_the_token_limit_is_refused_before_it_is_parsed() {
    let text = ";".repeat(MAX_TOKENS + 1);
    let d = parse_statements(&text).expect_err("too many tokens");
    assert_eq!(d.pos as usize, MAX_TOKENS);
    assert!(
        d.message
            .contains(&format!("more than {MAX_TOKENS} tokens")),
        "{}",
        d.message
    );
    // At the cap, the text is lexed and parsed (here, to a syntax error at its first token).
    let d = parse_expression(&text[1..]).expect_err("not an expression");
    assert_eq!(d.message, "expected an expression, found ';'");
}

#[test]
fn a_text_over_the_size_limit_is_refused() {
    let text = " ".repeat(MAX_TEXT + 1);
    let d = parse_library(&text).expect_err("too large");
    assert!(
        d.message.contains("more than the limit of"),
        "{}",
        d.message
    );
}

/// A generated file of about `lines` lines: TYPEs, function blocks and programs.
fn large_file(lines: usize) -> String {
    let mut text = String::new();
    let mut i = 0;
    while text.lines().count() < lines {
        text.push_str(
            &SAMPLE
                .replace("Clamp", &format!("Clamp{i}"))
                .replace("Blink", &format!("Blink{i}"))
                .replace("Main", &format!("Main{i}"))
                .replace("Plant", &format!("Plant{i}")),
        );
        i += 1;
    }
    text
}

#[test]
fn a_5000_line_file_is_parsed() {
    let text = large_file(5000);
    let lines = text.lines().count();
    let start = std::time::Instant::now();
    let l = lib(&text);
    let elapsed = start.elapsed();
    // A figure to read with --nocapture (in release: cargo test --release); no assertion on it.
    eprintln!("parsed {lines} lines, {} bytes, in {elapsed:?}", text.len());
    assert_eq!(l.pous.len() % 3, 0);
    assert!(l.pous.len() >= 3 * 5000 / SAMPLE.lines().count());
}

// ---- Corrupted programs ----

fn all_entry_points(text: &str) {
    let _ = parse_library(text);
    let _ = parse_statements(text);
    let _ = parse_expression(text);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn a_truncated_program_never_panics(cut in 0..SAMPLE.len()) {
        all_entry_points(&String::from_utf8_lossy(&SAMPLE.as_bytes()[..cut]));
    }

    #[test]
    fn a_program_with_flipped_bytes_never_panics(
        flips in proptest::collection::vec((0..SAMPLE.len(), any::<u8>()), 1..8)
    ) {
        let mut bytes = SAMPLE.as_bytes().to_vec();
        for (at, byte) in flips {
            bytes[at] = byte;
        }
        all_entry_points(&String::from_utf8_lossy(&bytes));
    }

    #[test]
    fn a_program_with_tokens_cut_out_never_panics(from in 0..SAMPLE.len(), len in 0usize..40) {
        let mut bytes = SAMPLE.as_bytes().to_vec();
        let to = (from + len).min(bytes.len());
        bytes.drain(from..to);
        all_entry_points(&String::from_utf8_lossy(&bytes));
    }

    #[test]
    fn arbitrary_text_of_st_characters_never_panics(
        text in "[A-Za-z0-9_#.:;=<>()\\[\\]*+/&$'%, \n{}-]{0,200}"
    ) {
        all_entry_points(&text);
    }
}
