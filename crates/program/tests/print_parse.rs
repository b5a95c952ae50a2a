//! The guard printer and parser are inverses: parse(print(e)) == e for every tree.

use cetratus_program::guard::{parse, BinOp, Expr, ExprKind, Func, UnOp};
use proptest::prelude::*;

fn name() -> impl Strategy<Value = String> {
    "[A-Za-z_][A-Za-z0-9_]{0,5}".prop_filter("keywords are not names", |s| {
        !matches!(s.as_str(), "true" | "false")
    })
}

fn leaf() -> impl Strategy<Value = ExprKind> {
    prop_oneof![
        any::<bool>().prop_map(ExprKind::Bool),
        (0..=i64::MAX).prop_map(ExprKind::Int),
        (0.0..1e300f64).prop_map(ExprKind::Real),
        prop_oneof![Just(1e-7), Just(0.5), Just(2.0), Just(1e16)].prop_map(ExprKind::Real),
        (0..=i64::MAX as u64).prop_map(ExprKind::Duration),
        prop_oneof![
            Just(0u64),
            Just(1_500_000),
            Just(3_600_000_000),
            Just(120_000_000)
        ]
        .prop_map(ExprKind::Duration),
        name().prop_map(ExprKind::Name),
        name().prop_map(ExprKind::Timer),
        name().prop_map(ExprKind::Dwell),
        name().prop_map(ExprKind::Rise),
        name().prop_map(ExprKind::Fall),
    ]
}

fn binop() -> impl Strategy<Value = BinOp> {
    prop_oneof![
        Just(BinOp::Or),
        Just(BinOp::And),
        Just(BinOp::Eq),
        Just(BinOp::Ne),
        Just(BinOp::Lt),
        Just(BinOp::Le),
        Just(BinOp::Gt),
        Just(BinOp::Ge),
        Just(BinOp::Add),
        Just(BinOp::Sub),
        Just(BinOp::Mul),
        Just(BinOp::Div),
    ]
}

fn expr() -> impl Strategy<Value = Expr> {
    leaf()
        .prop_map(Expr::new)
        .prop_recursive(6, 48, 2, |inner| {
            prop_oneof![
                (prop_oneof![Just(UnOp::Not), Just(UnOp::Neg)], inner.clone())
                    .prop_map(|(op, e)| Expr::new(ExprKind::Unary(op, Box::new(e)))),
                (
                    prop_oneof![Just(Func::Real), Just(Func::Int)],
                    inner.clone()
                )
                    .prop_map(|(f, e)| Expr::new(ExprKind::Call(f, Box::new(e)))),
                (binop(), inner.clone(), inner).prop_map(|(op, l, r)| Expr::new(ExprKind::Binary(
                    op,
                    Box::new(l),
                    Box::new(r)
                ))),
            ]
        })
}

proptest! {
    #[test]
    fn parsing_a_printed_guard_gives_back_the_same_tree(e in expr()) {
        let text = e.to_string();
        let back = parse(&text);
        prop_assert_eq!(back.as_ref().ok(), Some(&e), "printed as `{}`, parsed as {:?}", text, back);
    }
}

#[test]
fn printing_uses_the_fewest_parentheses() {
    let cases = [
        ("(a + b) * c", "(a + b) * c"),
        ("a + (b * c)", "a + b * c"),
        ("a - (b - c)", "a - (b - c)"),
        ("(a - b) - c", "a - b - c"),
        ("!(a && b) || c", "!(a && b) || c"),
        ("t(P30) >= 3000ms", "P30.t >= 3s"),
        ("(a == b) == c", "(a == b) == c"),
        ("- -x", "--x"),
    ];
    for (src, printed) in cases {
        let e = parse(src).map(|e| e.to_string());
        assert_eq!(e.as_deref(), Ok(printed), "{src}");
    }
}

#[test]
fn comparisons_do_not_chain() {
    let e = parse("a < b < c").err().map(|e| (e.offset, e.message));
    assert!(
        matches!(e, Some((6, ref m)) if m.contains("do not chain")),
        "{e:?}"
    );
}
