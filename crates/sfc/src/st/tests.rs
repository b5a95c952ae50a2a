use super::*;

/// The names of a small POU: inputs `a`, `b` (BOOL), `n`, `m` (INT), `r` (REAL); steps `S0`, `S1`.
struct Pou;

impl Names for Pou {
    fn resolve(&self, name: &str) -> Option<Resolved> {
        let vars = [
            ("a", Ty::Bool),
            ("b", Ty::Bool),
            ("n", Ty::Int),
            ("m", Ty::Int),
            ("r", Ty::Real),
        ];
        if let Some((v, ty)) = vars.iter().find(|(v, _)| v.eq_ignore_ascii_case(name)) {
            return Some(Resolved::Var(v.to_string(), *ty));
        }
        ["S0", "S1"]
            .iter()
            .find(|s| s.eq_ignore_ascii_case(name))
            .map(|s| Resolved::Step(s.to_string()))
    }
}

fn guard(text: &str) -> String {
    condition(text, &Pou)
        .unwrap_or_else(|e| panic!("{text}: {e:?}"))
        .to_string()
}

#[test]
fn conditions_translate_into_the_guard_language() {
    assert_eq!(guard("NOT a"), "!a");
    assert_eq!(guard("a AND b OR NOT a & b"), "a && b || !a && b");
    assert_eq!(guard("a XOR b"), "a != b");
    assert_eq!(guard("n + m * 2 >= 3 - n"), "n + m * 2 >= 3 - n");
    assert_eq!(guard("(n + m) * 2 = 4"), "(n + m) * 2 == 4");
    assert_eq!(guard("n <> m;"), "n != m");
    assert_eq!(guard("TRUE"), "true");
    assert_eq!(guard("r > 1.5"), "r > 1.5");
}

#[test]
fn step_flags_and_times_read_in_either_case() {
    // Step.T is the place's dwell: kept after the step is left, until it is activated again.
    assert_eq!(guard("S0.t > T#6s"), "S0.dwell > 6s");
    assert_eq!(guard("s0.T >= TIME#1m30s"), "S0.dwell >= 90s");
    assert_eq!(guard("S1.X AND s1.x"), "S1 > 0 && S1 > 0");
    assert_eq!(guard("S1.T < T#1.5s"), "S1.dwell < 1500ms");
    assert_eq!(guard("A"), "a");
}

#[test]
fn time_literals_add_their_units_and_refuse_what_is_not_a_duration() {
    assert_eq!(duration("T#1h2m3s4ms5us"), Ok(3_723_004_005));
    assert_eq!(duration(" t#2s "), Ok(2_000_000));
    assert!(duration("10s").is_err_and(|e| e.construct.is_some()));
    assert!(duration("T#").is_err());
    assert!(duration("T#5ns").is_err());
    assert!(duration("T#999999999999999999d").is_err());
}

#[test]
fn statements_parse_with_if_elsif_else() {
    let body = body(
        "(* a comment *) n := n + 1; IF a THEN b := TRUE; ELSIF n > 2 THEN b := 0; ELSE m := 1; END_IF; // end",
        &Pou,
    )
    .expect("parses");
    assert_eq!(body.len(), 2);
    let Stmt::If {
        arms, otherwise, ..
    } = &body[1]
    else {
        panic!("an IF")
    };
    assert_eq!((arms.len(), otherwise.len()), (2, 1));
}

/// CODESYS writes an action body that ends in `END_IF` without its `;`; inside a body the `;`
/// is still required.
#[test]
fn a_body_may_end_in_end_if_without_its_semicolon_as_codesys_writes_it() {
    let body = body("n := 1;\nIF a THEN\n  b := TRUE;\nEND_IF\n", &Pou).expect("parses");
    assert_eq!(body.len(), 2);
    let nested = "IF a THEN IF b THEN n := 1; END_IF END_IF";
    let e = super::body(nested, &Pou).expect_err("an inner END_IF needs its `;`");
    assert!(e.message.contains("after END_IF"), "{}", e.message);
    let e = super::body("IF a THEN n := 1; END_IF m := 2;", &Pou).expect_err("mid-body");
    assert!(e.message.contains("after END_IF"), "{}", e.message);
}

#[test]
fn constructs_outside_the_subset_are_named_with_their_offset() {
    for (text, construct, offset) in [
        ("AND(a, b)", "the call `AND(…)`", 0),
        ("n MOD 2 = 0", "MOD", 2),
        ("a AND n.Q", "the member access", 6),
        ("16#FF = n", "based literal", 0),
        ("n ** 2 = 4", "`**`", 2),
        ("NOT n = 0", "NOT on INT", 0),
    ] {
        let e = condition(text, &Pou).expect_err(text);
        assert!(
            e.construct
                .as_deref()
                .is_some_and(|c| c.contains(construct)),
            "{text}: {e:?}"
        );
        assert_eq!(e.offset, offset, "{text}");
    }
    let e = body("FOR n := 1 TO 3 DO END_FOR;", &Pou).expect_err("FOR");
    assert_eq!(e.construct.as_deref(), Some("FOR"));
}

#[test]
fn mistakes_are_errors_with_their_offset() {
    for (text, offset, words) in [
        ("a AND", 5, "end of the text"),
        ("a AND zz", 6, "unknown name `zz`"),
        ("n + r > 0", 2, "same type"),
        ("n", 0, "must be BOOL"),
        ("(a", 2, "`)`"),
        ("S0.Y", 3, "`.X`"),
    ] {
        let e = condition(text, &Pou).expect_err(text);
        assert_eq!(e.offset, offset, "{text}: {e:?}");
        assert!(e.message.contains(words), "{text}: {}", e.message);
    }
    let e = body("b := n;", &Pou).expect_err("types");
    assert!(e.message.contains("BOOL"), "{}", e.message);
}

#[test]
fn deep_nesting_and_long_texts_are_refused_without_exhausting_the_stack() {
    let deep = format!("{}a{}", "(".repeat(100_000), ")".repeat(100_000));
    let e = condition(&deep, &Pou).expect_err("too deep");
    assert!(
        e.message.contains("tokens") || e.message.contains("nested"),
        "{}",
        e.message
    );
    let nots = format!("{}a", "NOT ".repeat(40));
    assert!(condition(&nots, &Pou)
        .expect_err("too deep")
        .message
        .contains("nested"));
    let ifs = format!("{}{}", "IF a THEN ".repeat(40), "END_IF; ".repeat(40));
    assert!(body(&ifs, &Pou)
        .expect_err("too deep")
        .message
        .contains("nested"));
    let flat = vec!["a"; 200].join(" AND ");
    assert!(condition(&flat, &Pou)
        .expect_err("too deep")
        .message
        .contains("deep"));
    let long = vec!["a"; 2000].join(" OR ");
    assert!(condition(&long, &Pou)
        .expect_err("too long")
        .message
        .contains("tokens"));
}

proptest::proptest! {
    #[test]
    fn any_text_is_a_result_never_a_panic(text in "[ a-zA-Z0-9_#.:;=<>()+*/&-]{0,120}") {
        let _ = condition(&text, &Pou);
        let _ = body(&text, &Pou);
    }
}
