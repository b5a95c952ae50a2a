//! Structured fuzzing of the TOML program loader on stable Rust: `Program::from_sources` (the
//! loader of a package's program, which a PLC runs on what comes in an update) returns a program
//! or an error for any text, and never panics. Besides arbitrary text, the inputs are program
//! files assembled from the schema's own sections and keys, with values at the edges: names that
//! clash with places, unknown types, out-of-range literals, bad durations and qualifiers, guards
//! and invariants from token soup.

use std::sync::OnceLock;

use cetratus_net::Net;
use cetratus_program::Program;
use cetratus_testkit::{nets, paths};
use proptest::collection::vec;
use proptest::prelude::*;

fn vernadat_net() -> &'static Net {
    static N: OnceLock<Net> = OnceLock::new();
    N.get_or_init(nets::vernadat)
}

fn load(text: &str) -> Result<Program, String> {
    Program::from_sources(text, "fuzz.toml", vernadat_net().clone()).map_err(|e| e.to_string())
}

/// A TOML basic string holding `s`.
fn quoted(s: &str) -> String {
    let mut out = String::from("\"");
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if c.is_control() => out.push_str(&format!("\\u{:04X}", u32::from(c))),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

const NAMES: &[&str] = &[
    "PE", "FCM1", "CM1", "s0", "H", "P10", "T10", "", " ", "a-b", "é", "true",
];
const TYPES: &[&str] = &["bool", "int", "real", "integer", "", "BOOL"];
/// TOML values, written as TOML.
const LITERALS: &[&str] = &[
    "true",
    "false",
    "0",
    "1",
    "-1",
    "9223372036854775807",
    "-9223372036854775808",
    "1.5",
    "-0.0",
    "nan",
    "inf",
    "-inf",
    "1e308",
    "\"x\"",
    "[]",
    "{}",
    "1979-05-27T07:32:00Z",
];
const DURATIONS: &[&str] = &[
    "10ms",
    "0s",
    "1s",
    "-1s",
    "0.5us",
    "1e3s",
    "99999999999999999999h",
    "18446744073709551615us",
    "9223372036854775807us",
    "2562047788015216h",
    "x",
    "",
];
const QUALIFIERS: &[&str] = &[
    "N", "S", "R", "L", "D", "P", "P0", "P1", "SD", "DS", "SL", "X", "",
];
const POLICIES: &[&str] = &[
    "step",
    "single",
    "single-first",
    "single-last",
    "random",
    "",
];
const PLACES: &[&str] = &["H", "B", "P10", "P11", "P14", "P99", "T10", ""];
const TRANSITIONS: &[&str] = &["T10", "T11", "T20", "T99", "P10", ""];
const GUARD_TOKENS: &[&str] = &[
    "s0",
    "s1",
    "s2",
    "s3",
    "PE",
    "FCM1",
    "n",
    "x",
    "P10",
    "H",
    "CM1",
    "nope",
    "P10.t",
    "rise(PE)",
    "fall(x)",
    "1",
    "0",
    "9223372036854775807",
    "1.5",
    "3s",
    "&&",
    "||",
    "!",
    "==",
    "<",
    ">=",
    "+",
    "-",
    "*",
    "/",
    "(",
    ")",
    "=",
    "real(",
    "int(",
];
const INVARIANT_TOKENS: &[&str] = &[
    "H",
    "B",
    "P14",
    "P99",
    "2*",
    "0*",
    "9223372036854775807*",
    "-",
    "+",
    "=",
    "7",
    "-7",
    "9223372036854775807",
    "x",
];

fn pick(from: &'static [&'static str]) -> impl Strategy<Value = &'static str> {
    prop::sample::select(from)
}

fn words(from: &'static [&'static str], max: usize) -> impl Strategy<Value = String> {
    vec(pick(from), 0..max).prop_map(|w| w.join(" "))
}

/// Mostly a usable value, now and then any of `edge`: a load stops at its first error, so the
/// sections after an error would rarely be reached otherwise.
fn usually(
    good: &'static str,
    edge: &'static [&'static str],
) -> impl Strategy<Value = &'static str> {
    prop_oneof![6 => Just(good), 1 => pick(edge)]
}

fn program_section() -> impl Strategy<Value = String> {
    (
        usually("t", NAMES),
        usually("1", NAMES),
        prop::option::of(usually("step", POLICIES)),
        prop::option::of(usually("10ms", DURATIONS)),
    )
        .prop_map(|(name, version, policy, period)| {
            let mut s = format!(
                "[program]\nname = {}\nversion = {}\n",
                quoted(name),
                quoted(version)
            );
            if let Some(p) = policy {
                s.push_str(&format!("policy = {}\n", quoted(p)));
            }
            if let Some(d) = period {
                s.push_str(&format!("scan_period = {}\n", quoted(d)));
            }
            s
        })
}

/// The `i`-th signal: usually of a fresh name, a known type and the fields its kind takes.
fn signal(i: usize) -> impl Strategy<Value = String> {
    (
        pick(&["input", "output", "variable"]),
        prop::option::weighted(0.1, pick(NAMES)),
        usually("", TYPES),
        prop::option::of(pick(LITERALS)),
        any::<bool>(),
        prop::option::of(any::<bool>()),
    )
        .prop_map(
            move |(kind, edge_name, edge_type, edge_value, set, retain)| {
                let name = edge_name.map_or_else(|| format!("s{i}"), str::to_string);
                let (ty, good) = match (edge_type, i % 3) {
                    ("", 0) => ("bool", "true"),
                    ("", 1) => ("int", "1"),
                    ("", _) => ("real", "1.5"),
                    (t, _) => (t, "0"),
                };
                let mut s = format!(
                    "[[{kind}]]\nname = {}\ntype = {}\n",
                    quoted(&name),
                    quoted(ty)
                );
                let value = edge_value.unwrap_or(good);
                if set {
                    let field = match kind {
                        "output" => "safe",
                        "variable" => "initial",
                        _ => "address",
                    };
                    let value = if field == "address" {
                        quoted("%IX0.0")
                    } else {
                        value.to_string()
                    };
                    s.push_str(&format!("{field} = {value}\n"));
                }
                if let (Some(r), "variable") = (retain, kind) {
                    s.push_str(&format!("retain = {r}\n"));
                }
                s
            },
        )
}

fn signals() -> impl Strategy<Value = String> {
    (0..6usize)
        .prop_flat_map(|n| (0..n).map(signal).collect::<Vec<_>>())
        .prop_map(|v| v.concat())
}

fn action() -> impl Strategy<Value = String> {
    (
        usually("P11", PLACES),
        usually("N", QUALIFIERS),
        pick(&["s0", "s1", "s2", "s3", "s4", "CM1", "PE", "nope", ""]),
        prop::option::of(usually("1s", DURATIONS)),
    )
        .prop_map(|(place, q, target, duration)| {
            let mut s = format!(
                "[[action]]\nplace = {}\nqualifier = {}\ntarget = {}\n",
                quoted(place),
                quoted(q),
                quoted(target)
            );
            if let Some(d) = duration {
                s.push_str(&format!("duration = {}\n", quoted(d)));
            }
            s
        })
}

fn structured_program() -> impl Strategy<Value = String> {
    (
        program_section(),
        signals(),
        // Half the programs have no guards, so that their actions and invariants are reached.
        prop_oneof![
            Just(Vec::new()),
            vec((usually("T10", TRANSITIONS), words(GUARD_TOKENS, 8)), 1..4),
        ],
        vec(action(), 0..4),
        vec(words(INVARIANT_TOKENS, 8), 0..3),
    )
        .prop_map(|(program, signals, guards, actions, invariants)| {
            let mut s = program;
            s.push_str(&signals);
            s.push_str(&actions.concat());
            for inv in invariants {
                s.push_str(&format!("[[invariant]]\nexpr = {}\n", quoted(&inv)));
            }
            s.push_str(&guards_section(guards));
            s
        })
}

/// `[guards]`, one guard per transition (a key written twice is a TOML error, which stops the
/// load before anything of interest).
fn guards_section(guards: Vec<(&str, String)>) -> String {
    let guards: std::collections::BTreeMap<&str, String> = guards.into_iter().collect();
    if guards.is_empty() {
        return String::new();
    }
    let mut s = String::from("[guards]\n");
    for (t, g) in guards {
        s.push_str(&format!("{} = {}\n", quoted(t), quoted(&g)));
    }
    s
}

fn example_program() -> &'static str {
    static T: OnceLock<String> = OnceLock::new();
    T.get_or_init(|| {
        let path = paths::example("vernadat/vernadat.toml");
        std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn arbitrary_text_loads_or_is_refused(text in "\\PC{0,300}") {
        let _ = load(&text);
    }

    #[test]
    fn programs_of_the_schema_load_or_are_refused(text in structured_program()) {
        let _ = load(&text);
    }

    #[test]
    fn the_example_program_edited_loads_or_is_refused(
        edits in vec((any::<prop::sample::Index>(), prop::option::weighted(0.85, value())), 0..6),
        extra in (signals(), vec(action(), 0..3)),
    ) {
        let mut lines: Vec<String> = example_program().lines().map(str::to_string).collect();
        for (i, value) in edits {
            let i = i.index(lines.len());
            match value {
                // A line dropped.
                None => {
                    lines.remove(i);
                }
                // A value replaced.
                Some(v) => {
                    if let Some((key, _)) = lines[i].split_once(" = ") {
                        lines[i] = format!("{key} = {v}");
                    }
                }
            }
        }
        // Signals and actions after the example's own sections, each a table of its own.
        let text = format!("{}\n{}{}", lines.join("\n"), extra.0, extra.1.concat());
        let _ = load(&text);
    }
}

/// A value for any key of the example: a TOML literal, or a string of names, durations or
/// guard tokens.
fn value() -> impl Strategy<Value = String> {
    prop_oneof![
        pick(LITERALS).prop_map(str::to_string),
        pick(NAMES).prop_map(quoted),
        pick(DURATIONS).prop_map(quoted),
        pick(QUALIFIERS).prop_map(quoted),
        words(GUARD_TOKENS, 8).prop_map(|w| quoted(&w)),
        words(INVARIANT_TOKENS, 8).prop_map(|w| quoted(&w)),
    ]
}
