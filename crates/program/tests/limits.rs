//! Guards and conditions too long or too deep are refused with an error that says what is too big,
//! where, and the limit; nothing that reads one recurses deeper than the limits allow, so no text
//! can overflow the stack of the thread that compiles it (the PLC's preparer thread compiles the
//! conditions of `substitute` commands that come over MQTT).

use cetratus_program::guard::{parse, MAX_DEPTH, MAX_NESTING, MAX_TOKENS};
use cetratus_program::Program;
use cetratus_testkit::{nets, programs};

/// `n` copies of `term` joined by `op`: a flat chain, which the parser builds as a tree as deep
/// as it is long.
fn chain(term: &str, op: &str, n: usize) -> String {
    vec![term; n].join(op)
}

fn vernadat() -> Program {
    programs::example("vernadat/vernadat.toml")
}

#[test]
fn a_condition_of_twenty_thousand_terms_is_an_error_not_a_stack_overflow() {
    let p = vernadat();
    for text in [
        chain("PE", " && ", 20_000),
        chain("PE", " || ", 20_000),
        format!("{} > 0", chain("1", " + ", 20_000)),
        format!("{} == 0", chain("P10", " * ", 20_000)),
    ] {
        let msg = match p.compile_condition(&text) {
            Ok(_) => panic!("a condition of 20,000 terms compiled"),
            Err(e) => e.to_string(),
        };
        assert!(
            msg.contains("too long") && msg.contains(&MAX_TOKENS.to_string()),
            "{msg}"
        );
    }
}

#[test]
fn a_guard_of_twenty_thousand_terms_in_a_program_file_is_refused_at_its_position() {
    let src = format!(
        "[program]\nname = \"t\"\nversion = \"1\"\n[[input]]\nname = \"PE\"\ntype = \"bool\"\n\
         [guards]\nT10 = \"{}\"\n",
        chain("PE", " && ", 20_000)
    );
    let msg = match Program::from_sources(&src, "prog.toml", nets::vernadat()) {
        Ok(_) => panic!("a guard of 20,000 terms loaded"),
        Err(e) => e.to_string(),
    };
    // The first token past the limit, inside the string on line 8.
    assert!(msg.starts_with("prog.toml:8:"), "{msg}");
    assert!(
        msg.contains("T10") && msg.contains("too long") && msg.contains(&MAX_TOKENS.to_string()),
        "{msg}"
    );
}

#[test]
fn a_chain_one_term_deeper_than_the_limit_is_refused_and_one_at_the_limit_compiles() {
    let p = vernadat();
    assert!(p.compile_condition(&chain("PE", " && ", MAX_DEPTH)).is_ok());
    let msg = match p.compile_condition(&chain("PE", " && ", MAX_DEPTH + 1)) {
        Ok(_) => panic!("a chain deeper than MAX_DEPTH compiled"),
        Err(e) => e.to_string(),
    };
    assert!(
        msg.contains("too deep") && msg.contains(&MAX_DEPTH.to_string()),
        "{msg}"
    );
    // The depth counts every operator, whichever side it nests on.
    let right = format!("PE || ({})", chain("PE", " && ", MAX_DEPTH));
    assert!(parse(&right).is_err());
}

#[test]
fn deep_parentheses_negations_and_calls_stop_at_the_nesting_limit() {
    let n = MAX_NESTING + 1;
    for text in [
        format!("{}PE{}", "(".repeat(n), ")".repeat(n)),
        format!("{}PE", "!".repeat(n)),
        format!(
            "{}1.0{} > 0",
            "int(real(".repeat(n / 2 + 1),
            "))".repeat(n / 2 + 1)
        ),
    ] {
        let msg = match parse(&text) {
            Ok(_) => panic!("nesting of {n} parsed"),
            Err(e) => e.to_string(),
        };
        assert!(msg.contains(&MAX_NESTING.to_string()), "{msg}");
    }
    // Far deeper, the size limit comes first.
    let n = 20_000;
    let msg = match parse(&format!("{}PE{}", "(".repeat(n), ")".repeat(n))) {
        Ok(_) => panic!("nesting of {n} parsed"),
        Err(e) => e.to_string(),
    };
    assert!(msg.contains("too long"), "{msg}");
}

/// A balanced tree of `&&` with 2^`levels` leaves, fully parenthesised.
fn balanced(levels: u32) -> String {
    if levels == 0 {
        "PE".to_string()
    } else {
        let half = balanced(levels - 1);
        format!("({half} && {half})")
    }
}

/// Rust gives a spawned thread 2 MiB of stack; the node's preparer thread has that much.
const THREAD_STACK: usize = 2 << 20;

#[test]
fn the_largest_guards_compile_print_clone_and_drop_on_a_thread_of_default_stack() {
    let p = vernadat();
    // At the depth limit, built on each side, and at the size limit.
    let left = chain("PE", " && ", MAX_DEPTH);
    let mixed = format!("{} > 0", chain("1 + P10 * 2", " - ", MAX_DEPTH / 2 - 1));
    let nested = format!(
        "{}PE{}",
        "(PE && ".repeat(MAX_NESTING - 1),
        ")".repeat(MAX_NESTING - 1)
    );
    // 2^8 leaves: 1021 tokens.
    let wide = balanced(8);
    let worker = std::thread::Builder::new()
        .stack_size(THREAD_STACK)
        .spawn(move || {
            for text in [left, mixed, nested, wide] {
                let g = match p.compile_condition(&text) {
                    Ok(g) => g,
                    Err(e) => panic!("{e}"),
                };
                let printed = g.expr().to_string();
                let again = match parse(&printed) {
                    Ok(e) => e,
                    Err(e) => panic!("{e}: {printed}"),
                };
                assert_eq!(&again, g.expr());
                assert!(g.expr().nesting() <= MAX_DEPTH);
                let copy = g.clone();
                drop(g);
                drop(copy);
            }
        })
        .expect("a thread");
    assert!(worker.join().is_ok(), "the worker thread failed");
}
