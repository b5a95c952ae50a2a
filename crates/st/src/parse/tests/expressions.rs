//! Expressions, literals and the lexer.

#![allow(unused_imports)]
use super::*;

// ---- Expressions ----

#[test]
fn the_precedence_table_of_iec_61131_3_is_followed() {
    let cases = [
        ("a OR b XOR c", "(a OR (b XOR c))"),
        ("a XOR b AND c", "(a XOR (b AND c))"),
        ("a AND b = c", "(a AND (b = c))"),
        ("a & b <> c", "(a AND (b <> c))"),
        ("a = b < c", "(a = (b < c))"),
        ("a <> b >= c", "(a <> (b >= c))"),
        ("a < b + c", "(a < (b + c))"),
        ("a <= b - c", "(a <= (b - c))"),
        ("a + b * c", "(a + (b * c))"),
        ("a - b / c", "(a - (b / c))"),
        ("a + b MOD c", "(a + (b MOD c))"),
        ("a * b ** c", "(a * (b ** c))"),
        ("a ** b * c", "((a ** b) * c)"),
        ("-a * b", "((-a) * b)"),
        ("NOT a AND b", "((NOT a) AND b)"),
        ("NOT a = b", "((NOT a) = b)"),
        ("(a OR b) AND c", "((a OR b) AND c)"),
        ("F(a + b) * 2", "(F((a + b)) * 2)"),
        ("a > b OR c < d AND e", "((a > b) OR ((c < d) AND e))"),
    ];
    for (text, tree) in cases {
        assert_eq!(show(&expr(text)), tree, "{text}");
    }
}

#[test]
fn binary_operators_are_left_associative_power_included() {
    let cases = [
        ("a - b - c", "((a - b) - c)"),
        ("a / b * c", "((a / b) * c)"),
        ("a OR b OR c", "((a OR b) OR c)"),
        ("a < b < c", "((a < b) < c)"),
        ("2 ** 3 ** 2", "((2 ** 3) ** 2)"),
    ];
    for (text, tree) in cases {
        assert_eq!(show(&expr(text)), tree, "{text}");
    }
}

#[test]
fn a_unary_operator_before_an_operand_of_power_is_refused_as_ambiguous() {
    for text in ["-a ** 2", "NOT a ** b", "a ** -b ** c", "+a ** 2"] {
        let d = expr_err(text);
        assert!(
            d.message
                .starts_with("a unary operator before an operand of '**' is ambiguous"),
            "{text}: {}",
            d.message
        );
    }
    assert_eq!(expr_err("x + -a ** 2").pos, 4);
}

#[test]
fn power_with_a_parenthesised_or_a_last_negative_operand_is_accepted() {
    assert_eq!(show(&expr("(-a) ** 2")), "((-a) ** 2)");
    assert_eq!(show(&expr("-(a ** 2)")), "(-(a ** 2))");
    assert_eq!(show(&expr("a ** -b")), "(a ** (-b))");
}

#[test]
fn repeated_unary_operators_and_unary_plus_are_accepted() {
    assert_eq!(show(&expr("NOT NOT a")), "(NOT (NOT a))");
    assert_eq!(show(&expr("- -a")), "(-(-a))");
    assert_eq!(show(&expr("+a - +b")), "(a - b)");
    assert_eq!(show(&expr("a - -1")), "(a - (-1))");
}

#[test]
fn member_index_and_call_chains_are_read() {
    assert_eq!(show(&expr("a.b[1][2].c")), "a.b[1][2].c");
    assert_eq!(show(&expr("F(G(x), y[i])")), "F(G(x), y[i])");
    assert_eq!(
        show(&expr("LIMIT(MN := 0, IN := x, MX := 10)")),
        "LIMIT(MN := 0, IN := x, MX := 10)"
    );
}

#[test]
fn the_expression_position_of_a_binary_operation_is_its_operator() {
    let e = expr("a + b");
    assert_eq!(e.pos, 2);
    let ExprKind::Binary(BinOp::Add, l, r) = &e.kind else {
        panic!("not an addition")
    };
    assert_eq!((l.pos, r.pos), (0, 4));
}

#[test]
fn an_expression_alone_must_be_whole() {
    assert_eq!(
        expr_err("a b").message,
        "expected an operator or the end of the text, found 'b'"
    );
    assert!(expr_err("").message.starts_with("the expression is empty"));
    assert_eq!(
        expr_err("(a + b").message,
        "expected ')' to close the parenthesis, found the end of the text"
    );
    assert_eq!(
        expr_err("a +").message,
        "expected an expression, found the end of the text"
    );
}

// ---- Literals ----

#[test]
fn integers_with_underscores_and_bases_are_read() {
    for (text, value) in [
        ("1_000", 1000),
        ("2#1010_1010", 0xaa),
        ("8#17", 15),
        ("16#FF", 255),
        ("16#ff", 255),
        ("0", 0),
    ] {
        assert!(
            matches!(lit(text), Literal::Int { value: v, ty: None } if v == value),
            "{text}"
        );
    }
    for text in ["1__0", "1_", "16#", "2#102", "10#5", "12ab"] {
        assert!(parse_expression(text).is_err(), "{text}");
    }
}

#[test]
fn typed_literals_are_read() {
    let cases = [
        ("INT#-5", "INT#-5"),
        ("WORD#16#8001", "WORD#32769"),
        ("DINT#100", "DINT#100"),
        ("UINT#5", "UINT#5"),
        ("BOOL#1", "TRUE"),
        ("BOOL#0", "FALSE"),
        ("BOOL#TRUE", "TRUE"),
        ("bool#false", "FALSE"),
        ("REAL#1.5", "REAL#1.5"),
        ("REAL#5", "REAL#5.0"),
        ("LREAL#-2.0E3", "LREAL#-2000.0"),
        ("Color#Red", "Color#Red"),
        ("STRING#'a$Nb'", "'a\nb'"),
    ];
    for (text, shown) in cases {
        assert_eq!(show(&expr(text)), shown, "{text}");
    }
    for text in ["BOOL#2", "INT#TRUE", "INT#-16#FF", "INT# 5", "INT#'a'"] {
        assert!(parse_expression(text).is_err(), "{text}");
    }
}

#[test]
fn reals_need_a_point_and_a_fraction() {
    assert!(matches!(lit("1.5"), Literal::Real { value, .. } if value == 1.5));
    assert!(matches!(lit("1.0E-3"), Literal::Real { value, .. } if value == 1.0E-3));
    assert!(matches!(lit("2.5e2"), Literal::Real { value, .. } if value == 250.0));
    assert!(matches!(lit("1_000.5"), Literal::Real { value, .. } if value == 1000.5));
    let d = expr_err("2e5");
    assert_eq!(
        d.message,
        "a REAL literal needs a '.' and a fraction: write 2.0E…"
    );
    assert!(parse_expression("1.").is_err());
    assert!(parse_expression("1.0E999").is_err());
}

#[test]
fn durations_are_read_in_nanoseconds() {
    const MS: i64 = 1_000_000;
    let cases = [
        ("T#1s500ms", 1500 * MS),
        ("TIME#20ms", 20 * MS),
        ("t#-5s", -5000 * MS),
        ("T#1.5s", 1500 * MS),
        ("T#1h2m3s4ms", (3600 + 120 + 3) * 1000 * MS + 4 * MS),
        ("T#100us", 100_000),
        ("T#7ns", 7),
        ("T#1d_2h", 26 * 3600 * 1000 * MS),
        ("T#90m", 90 * 60 * 1000 * MS),
        ("T#1H30M", 90 * 60 * 1000 * MS),
        ("LT#1.25ms", 1_250_000),
        ("LTIME#+2s", 2000 * MS),
        ("T#0.000000001s", 1),
    ];
    for (text, ns) in cases {
        assert!(matches!(lit(text), Literal::Time(v) if v == ns), "{text}");
    }
}

#[test]
fn malformed_durations_are_refused() {
    let cases = [
        ("T#1m1h", "must go from the largest to the smallest"),
        ("T#1s1s", "must go from the largest to the smallest"),
        ("T#1h70m", "must be less than 60"),
        ("T#1.5h30m", "only the last unit"),
        ("T#5x", "is not a unit of duration"),
        ("T#5", "is not a unit of duration"),
        ("T#0.0000000001s", "finer than a nanosecond"),
        ("T#", "expected a duration after 'T#'"),
        ("T#300000d", "too long"),
    ];
    for (text, part) in cases {
        let d = expr_err(text);
        assert!(d.message.contains(part), "{text}: {}", d.message);
    }
}

#[test]
fn strings_with_escapes_are_read() {
    let Literal::String(bytes) = lit("'a$$b$'c$L$N$P$R$T$0A$41\"'") else {
        panic!("not a string")
    };
    assert_eq!(bytes, b"a$b'c\n\n\x0c\r\t\nA\"");
    assert!(matches!(lit("''"), Literal::String(b) if b.is_empty()));
    assert!(matches!(lit("'Grüße'"), Literal::String(b) if b == "Grüße".as_bytes()));
    assert!(expr_err("'a$Qb'").message.contains("is not an escape"));
    assert!(expr_err("'abc")
        .message
        .starts_with("the string that starts here is never closed"));
    assert!(expr_err("'ab\ncd'")
        .message
        .contains("not closed on its line"));
}

#[test]
fn true_and_false_in_any_case_are_bools() {
    assert!(matches!(lit("TRUE"), Literal::Bool(true)));
    assert!(matches!(lit("false"), Literal::Bool(false)));
    assert!(matches!(lit("True"), Literal::Bool(true)));
}

// ---- Lexical ----

#[test]
fn comments_of_three_kinds_and_pragmas_are_skipped() {
    let s = stmts(
        "(* a comment *) x := 1; // to the end of the line\n/* another\n one */ {attribute 'hide'} y := (* inside *) 2;(**)",
    );
    assert_eq!(s.len(), 2);
}

#[test]
fn comments_do_not_nest() {
    let d = stmts_err("(* outer (* inner *) still outer? *) x := 1;");
    assert_eq!(
        d.message,
        "expected ':=' (an assignment) or '(' (a call) after 'still', found 'outer'"
    );
}

#[test]
fn an_unclosed_comment_or_pragma_is_reported_where_it_starts() {
    let d = stmts_err("x := 1; (* forever");
    assert_eq!(d.pos, 8);
    assert_eq!(
        d.message,
        "the comment that starts here is never closed: add '*)'"
    );
    let d = stmts_err("x := 1; {pragma");
    assert_eq!(
        d.message,
        "the pragma that starts here is never closed: add '}'"
    );
}

#[test]
fn keywords_and_names_are_case_insensitive() {
    let l = lib("program p var X : int; end_var if x > 0 Then x := 0; End_If; END_program");
    assert_eq!(l.pous[0].body.len(), 1);
}

#[test]
fn names_with_double_or_trailing_underscores_are_refused_as_matiec_refuses_them() {
    for text in ["a__b := 1;", "a_ := 1;", "__a := 1;", "_ := 1;"] {
        let d = stmts_err(text);
        assert!(d.message.contains("is not a name"), "{text}: {}", d.message);
    }
    assert_eq!(stmts("_a1 := 1; b_2_c := 2;").len(), 2);
}

#[test]
fn a_byte_order_mark_and_crlf_line_ends_are_accepted() {
    assert_eq!(stmts("\u{feff}x := 1;\r\ny := 2;\r\n").len(), 2);
}

#[test]
fn an_unexpected_character_is_named() {
    let d = stmts_err("x := 1 ! 2;");
    assert_eq!(d.message, "unexpected character '!'");
    assert_eq!(d.pos, 7);
}
