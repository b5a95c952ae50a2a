//! The Structured Text generator seen from outside: the same seed gives the same bytes, the
//! programs have the promised shape, and the subset the module doc promises is covered, every
//! feature in many of 2,000 programs. That MATIEC compiles and runs all of them, with the same
//! outputs as Cetratus, is `cetratus-st`'s differential test.

use std::fmt::Write as _;

use cetratus_testkit::matiec::{Case, IecType};
use cetratus_testkit::stgen::{generate, Batch};

const PROGRAMS: usize = 2000;
/// Programs per generated batch.
const PER_BATCH: usize = 250;
const SEED: u64 = 0x5EED_2024;

/// Batch `k` of the 2,000 programs.
fn batch(k: usize, scans: usize) -> Batch {
    generate(SEED + k as u64, PER_BATCH, scans)
}

/// The text of each program of a batch, with its types, functions and FBs.
fn programs(source: &str) -> Vec<&str> {
    source
        .split("(* ---- P")
        .filter(|p| !p.trim().is_empty())
        .collect()
}

#[test]
fn the_same_seed_gives_the_same_bytes_and_another_seed_others() {
    let a = generate(7, 40, 20);
    let b = generate(7, 40, 20);
    assert_eq!(a.source, b.source);
    assert_eq!(a.cases, b.cases);
    let c = generate(8, 40, 20);
    assert_ne!(a.source, c.source);
}

#[test]
fn a_program_does_not_depend_on_the_size_of_its_batch() {
    let small = generate(3, 5, 10);
    let large = generate(3, 12, 10);
    assert!(large.source.starts_with(&small.source));
    assert_eq!(small.cases[..], large.cases[..5]);
}

#[test]
fn every_program_has_the_promised_interface_and_size() {
    let b = generate(11, 400, 30);
    let texts = programs(&b.source);
    assert_eq!(texts.len(), 400);
    let mut lines: Vec<usize> = Vec::new();
    for (case, text) in b.cases.iter().zip(&texts) {
        let (p, ins, outs) = (&case.program, case.inputs.len(), case.outputs.len());
        assert!((2..=6).contains(&ins), "{p}: {ins} inputs");
        assert!((2..=6).contains(&outs), "{p}: {outs} outputs");
        assert_eq!(case.scans.len(), 30);
        assert!(case.scans.iter().all(|s| s.len() == ins));
        // Every output is assigned at the top level of the body, so in every scan.
        for (out, _) in &case.outputs {
            assert!(
                text.contains(&format!("\n  {out} := ")),
                "{p}: {out} unassigned"
            );
        }
        // Some state lives from scan to scan: variables besides the interface.
        assert!(
            text.contains(&format!("PROGRAM {p}\n")) && text.contains("\n  VAR\n"),
            "{p}"
        );
        lines.push(text.lines().count());
    }
    lines.sort_unstable();
    let (min, median, max) = (lines[0], lines[lines.len() / 2], lines[lines.len() - 1]);
    println!(
        "lines per program (with its functions and FBs): min {min}, median {median}, max {max}"
    );
    assert!(
        (20..=80).contains(&median),
        "median program of {median} lines"
    );
}

fn ident(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '_'
}

/// Whether `w` occurs in `text` as a whole word (`INT` in `: INT;` and `INT#5`, not in `DINT`).
fn word(text: &str, w: &str) -> bool {
    text.match_indices(w).any(|(i, _)| {
        let before = text[..i].chars().next_back().is_none_or(|c| !ident(c));
        let after = text[i + w.len()..].chars().next().is_none_or(|c| !ident(c));
        before && after
    })
}

/// A statement `x := x <op> …` (state that creeps to its limits and wraps).
fn self_update(text: &str) -> bool {
    text.lines().any(|l| {
        l.trim().split_once(" := ").is_some_and(|(lhs, rhs)| {
            [" + ", " - ", " * "]
                .iter()
                .any(|op| rhs.starts_with(&format!("{lhs}{op}")))
        })
    })
}

/// An array element indexed by a loop counter, `a[i3]` or `m[i3, i4]`.
fn indexed_by_counter(text: &str) -> bool {
    text.match_indices("[i").any(|(i, _)| {
        let rest = &text[i + 2..];
        let digits = rest.chars().take_while(char::is_ascii_digit).count();
        digits > 0 && matches!(rest[digits..].chars().next(), Some(']' | ','))
    })
}

/// A call of a user function with positional arguments, `P3_F1(x, 2)`.
fn informal_call(text: &str) -> bool {
    text.match_indices("_F").any(|(i, _)| {
        let rest = &text[i + 2..];
        let digits = rest.chars().take_while(char::is_ascii_digit).count();
        digits > 0
            && rest[digits..].starts_with('(')
            && !rest[digits + 1..]
                .split([',', ')'])
                .next()
                .unwrap_or("")
                .contains(":=")
            && text[..i].ends_with(|c: char| c.is_ascii_digit())
    })
}

/// A REAL literal with an exponent, `1.5E2`.
fn exponent(text: &str) -> bool {
    text.match_indices(['E', 'e']).any(|(i, _)| {
        let before = text[..i].chars().next_back();
        let after = text[i + 1..].chars().next();
        before.is_some_and(|c| c.is_ascii_digit())
            && after.is_some_and(|c| c.is_ascii_digit() || c == '-')
            && text[..i]
                .rsplit(|c: char| !(c.is_ascii_digit() || c == '.'))
                .next()
                .is_some_and(|n| n.contains('.'))
    })
}

const TYPES: [&str; 17] = [
    "BOOL", "SINT", "INT", "DINT", "LINT", "USINT", "UINT", "UDINT", "ULINT", "BYTE", "WORD",
    "DWORD", "LWORD", "REAL", "LREAL", "TIME", "STRING",
];

/// Whether a program's text shows a feature.
type Shows = Box<dyn Fn(&str) -> bool>;

/// The features the module doc promises, each with how it shows in a program's text.
fn features() -> Vec<(&'static str, Shows)> {
    let has = |s: &'static str| -> Shows { Box::new(move |t| t.contains(s)) };
    let mut f: Vec<(&'static str, Shows)> = vec![
        ("operator +", has(" + ")),
        ("operator -", has(" - ")),
        ("operator *", has(" * ")),
        ("operator /", has(" / ")),
        ("operator MOD", has(" MOD ")),
        ("operator **", has(" ** ")),
        (
            "unary -",
            Box::new(|t| t.contains(" -(") || t.contains("(-(") || t.contains(":= -")),
        ),
        ("AND", has(" AND ")),
        ("&", has(" & ")),
        ("OR", has(" OR ")),
        ("XOR", has(" XOR ")),
        ("NOT", has("NOT ")),
        (
            "= <>",
            Box::new(|t| t.contains(" = ") && t.contains(" <> ")),
        ),
        (
            "< > <= >=",
            Box::new(|t| [" < ", " > ", " <= ", " >= "].iter().all(|o| t.contains(o))),
        ),
        (
            "bit-string AND/OR/XOR",
            Box::new(|t| {
                t.contains("16#")
                    && (t.contains(" OR 16#") || t.contains(" AND 16#") || t.contains(" XOR 16#"))
            }),
        ),
        ("literal INT#-5", has("INT#-")),
        ("literal 16#", has("16#")),
        ("literal 2#", has("2#")),
        ("literal 8#", has("8#")),
        ("literal WORD#16#…", has("WORD#16#")),
        ("literal DINT#", has("DINT#")),
        ("literal REAL#", has("REAL#")),
        ("literal 1.5E2", Box::new(exponent)),
        ("literal T#…", has("T#")),
        ("literal TIME#", has("TIME#")),
        (
            "literal 1_000",
            Box::new(|t| {
                t.match_indices('_').any(|(i, _)| {
                    t[..i].ends_with(|c: char| c.is_ascii_digit())
                        && t[i + 1..].starts_with(|c: char| c.is_ascii_digit())
                })
            }),
        ),
        (
            "string escape $…",
            Box::new(|t| {
                ["$N", "$T", "$R", "$P", "$$", "$'"]
                    .iter()
                    .any(|e| t.contains(e))
            }),
        ),
        ("x := x + … (wrap-around)", Box::new(self_update)),
        ("IF", has("IF ")),
        ("ELSIF", has("ELSIF ")),
        ("ELSE", has("ELSE\n")),
        (
            "CASE on an integer",
            Box::new(|t| t.contains("CASE ") && t.contains("..")),
        ),
        ("CASE on an enumeration", has("CASE mode")),
        (
            "CASE … ELSE",
            Box::new(|t| t.contains("CASE ") && t.contains("END_CASE") && t.contains("ELSE\n")),
        ),
        ("FOR", has("FOR ")),
        ("FOR … BY -n", has(" BY -")),
        ("WHILE", has("WHILE ")),
        ("REPEAT", has("REPEAT")),
        ("EXIT", has("EXIT;")),
        ("RETURN", has("RETURN;")),
        ("TRUNC", has("TRUNC(")),
        ("EXPT", has("EXPT(")),
        ("FUNCTION", has("\nFUNCTION ")),
        ("FUNCTION_BLOCK", has("\nFUNCTION_BLOCK ")),
        ("VAR_IN_OUT", has("VAR_IN_OUT")),
        ("function call, positional", Box::new(informal_call)),
        ("function call, formal", has("(a1 := ")),
        ("FB call binding an output =>", has(" => ")),
        (
            "FB output read (.Q, .CV, .ET)",
            Box::new(|t| [".Q", ".CV", ".ET"].iter().any(|m| t.contains(m))),
        ),
        ("ARRAY", has("ARRAY[")),
        (
            "ARRAY not from 0",
            Box::new(|t| {
                t.contains("ARRAY[1..") || t.contains("ARRAY[-") || t.contains("ARRAY[5..")
            }),
        ),
        (
            "ARRAY[a..b, c..d]",
            Box::new(|t| {
                t.match_indices("ARRAY[")
                    .any(|(i, _)| t[i..].split(']').next().unwrap_or("").contains(','))
            }),
        ),
        (
            "ARRAY of a structure",
            Box::new(|t| t.contains("] OF P") && t.contains("_S1;")),
        ),
        (
            "array indexed by a loop counter",
            Box::new(indexed_by_counter),
        ),
        ("array initialiser", has(" := [")),
        ("STRUCT", has("STRUCT")),
        ("enumeration type", Box::new(|t| t.contains("_E1 : ("))),
        (
            "typed enumeration value E#V",
            Box::new(|t| t.contains("_E1#") || t.contains("_E2#")),
        ),
    ];
    for s in [
        "ABS", "SQRT", "MIN", "MAX", "LIMIT", "SEL", "MUX", "SHL", "SHR", "ROL", "ROR", "LEN",
        "LEFT", "RIGHT", "MID", "CONCAT", "INSERT", "DELETE", "REPLACE", "FIND",
    ] {
        f.push((s, Box::new(move |t: &str| t.contains(&format!("{s}(")))));
    }
    for fb in [
        "TON", "TOF", "TP", "CTU", "CTD", "CTUD", "R_TRIG", "F_TRIG", "SR", "RS",
    ] {
        f.push((
            fb,
            Box::new(move |t: &str| t.contains(&format!(" : {fb};"))),
        ));
    }
    for ty in TYPES {
        f.push((ty, Box::new(move |t: &str| word(t, ty))));
    }
    f
}

/// The conversions the module doc promises: between the numeric and bit-string types and BOOL
/// both ways, integers and BOOL to STRING, and back to integers of at most 32 bits.
fn conversions() -> Vec<String> {
    let numeric = &TYPES[..15];
    let mut names = Vec::new();
    for a in numeric {
        for b in numeric {
            if a != b {
                names.push(format!("{a}_TO_{b}("));
            }
        }
    }
    for a in &TYPES[..9] {
        names.push(format!("{a}_TO_STRING("));
    }
    names
}

#[test]
fn every_feature_appears_in_many_of_two_thousand_programs() {
    let batches: Vec<Batch> = (0..PROGRAMS / PER_BATCH).map(|k| batch(k, 50)).collect();
    let texts: Vec<&str> = batches.iter().flat_map(|b| programs(&b.source)).collect();
    let cases: Vec<&Case> = batches.iter().flat_map(|b| &b.cases).collect();
    assert_eq!(texts.len(), PROGRAMS);
    let mut report = String::new();
    let mut rare = Vec::new();
    for (name, shows) in features() {
        let n = texts.iter().filter(|t| shows(t)).count();
        let _ = writeln!(report, "{n:5}  {name}");
        if n < PROGRAMS / 50 {
            rare.push(format!("{name}: {n}"));
        }
    }
    for ty in [IecType::String, IecType::Real, IecType::Time, IecType::Bool] {
        let n = cases
            .iter()
            .filter(|c| c.inputs.iter().any(|(_, t)| *t == ty))
            .count();
        let _ = writeln!(report, "{n:5}  a {ty} input");
        if n < PROGRAMS / 50 {
            rare.push(format!("a {ty} input: {n}"));
        }
    }
    let conv: Vec<(usize, String)> = conversions()
        .into_iter()
        .map(|c| (texts.iter().filter(|t| t.contains(&c)).count(), c))
        .collect();
    let least = conv.iter().min().expect("conversions");
    let _ = writeln!(
        report,
        "{:5}  of the {} conversions appear; the rarest, {}, in {} programs",
        conv.iter().filter(|(n, _)| *n > 0).count(),
        conv.len(),
        least.1.trim_end_matches('('),
        least.0
    );
    rare.extend(conv.iter().filter(|(n, _)| *n == 0).map(|(_, c)| c.clone()));
    println!("programs (of {PROGRAMS}) with each feature:\n{report}");
    assert!(rare.is_empty(), "rare or missing features: {rare:?}");
}
