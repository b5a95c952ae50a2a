//! `docs/asyncapi.yaml` against the types: the channels are the topics `Topics` builds, every
//! closed set of names it lists is the vocabulary's, and every field of a payload the running
//! PLC published (the golden files) is declared in its message. The document is written by
//! hand for people; this test fails as soon as it and the protocol disagree.

use std::collections::BTreeSet;
use std::path::Path;

use cetratus_proto::{
    ErrorCode, EventKind, Leaf, LinkState, Quality, Role, Slot, Status, SubstituteMode, Verb,
    VerdictKind, VerdictResult,
};
use serde_json::Value;

fn asyncapi() -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/asyncapi.yaml");
    std::fs::read_to_string(path).expect("docs/asyncapi.yaml")
}

fn golden(name: &str) -> Value {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/golden")
        .join(name);
    serde_json::from_str(&std::fs::read_to_string(path).expect("golden file")).expect("JSON")
}

fn indent(line: &str) -> usize {
    line.len() - line.trim_start().len()
}

/// The lines of the block that `header` (a line of its own, e.g. `    State:`) opens, after the
/// line `after`: up to the next line indented as much as the header or less.
fn block<'a>(doc: &'a str, after: &str, header: &str) -> Vec<&'a str> {
    let mut lines = doc.lines().skip_while(|l| *l != after);
    let mut lines = lines.by_ref().skip_while(|l| *l != header);
    let Some(first) = lines.next() else {
        panic!("asyncapi.yaml has no `{}` after `{after}`", header.trim());
    };
    let depth = indent(first);
    lines
        .take_while(|l| l.trim().is_empty() || indent(l) > depth)
        .collect()
}

/// Whether the block declares a property `key`.
fn declares(block: &[&str], key: &str) -> bool {
    let prefix = format!("{key}:");
    block.iter().any(|l| l.trim_start().starts_with(&prefix))
}

fn names<T: Copy>(all: &[T], name: impl Fn(T) -> &'static str) -> Vec<String> {
    all.iter().map(|&t| name(t).to_string()).collect()
}

#[test]
fn the_channels_are_the_published_topics_and_one_per_verb() {
    let doc = asyncapi();
    let found: BTreeSet<String> = doc
        .lines()
        .filter_map(|l| l.strip_prefix("  cetratus/{plcId}/"))
        .filter_map(|l| l.strip_suffix(':'))
        .map(str::to_string)
        .collect();
    let expected: BTreeSet<String> = Leaf::PUBLISHED
        .iter()
        .copied()
        .chain(Verb::ALL.iter().map(|&v| Leaf::Cmd(v)))
        .map(|l| l.as_str().to_string())
        .collect();
    assert_eq!(found, expected);
}

#[test]
fn every_list_of_names_is_the_vocabularys() {
    let doc = asyncapi();
    let lines: Vec<&str> = doc.lines().collect();
    // The key of each `enum: [...]`, and its names.
    let mut found: Vec<(String, Vec<String>)> = Vec::new();
    for (i, l) in lines.iter().enumerate() {
        let Some(at) = l.find("enum: [") else {
            continue;
        };
        let list = &l[at + "enum: [".len()..];
        let list = &list[..list.find(']').expect("a closed list")];
        let values = list.split(',').map(|v| v.trim().to_string()).collect();
        let own = l.trim_start().split(':').next().unwrap_or("");
        // In a block entry the key is the nearest line above that is indented less.
        let key = if own == "enum" {
            let parent = lines[..i].iter().rev().find(|p| indent(p) < indent(l));
            parent.map_or("", |p| p.trim().trim_end_matches(':'))
        } else {
            own
        };
        found.push((key.to_string(), values));
    }
    let sets: Vec<(&str, Vec<String>)> = vec![
        ("primary", names(Slot::ALL, Slot::as_str)),
        ("container", names(Slot::ALL, Slot::as_str)),
        ("status", names(Status::ALL, Status::as_str)),
        ("role", names(Role::ALL, Role::as_str)),
        ("mode", names(SubstituteMode::ALL, SubstituteMode::as_str)),
        ("code", names(ErrorCode::ALL, ErrorCode::as_str)),
        ("link", names(LinkState::ALL, LinkState::as_str)),
        ("quality", names(Quality::ALL, Quality::as_str)),
        ("kind", names(VerdictKind::ALL, VerdictKind::as_str)),
        ("kind", names(EventKind::ALL, EventKind::as_str)),
        ("result", names(VerdictResult::ALL, VerdictResult::as_str)),
    ];
    for (key, values) in &found {
        let mut want: Vec<&Vec<String>> = sets
            .iter()
            .filter(|(k, _)| k == key)
            .map(|(_, v)| v)
            .collect();
        assert!(
            !want.is_empty(),
            "asyncapi.yaml lists names for `{key}`, which is no set of the vocabulary"
        );
        want.retain(|v| *v == values);
        assert!(
            !want.is_empty(),
            "asyncapi.yaml's `{key}` lists {values:?}; the protocol has {:?}",
            sets.iter()
                .filter(|(k, _)| k == key)
                .map(|(_, v)| v)
                .collect::<Vec<_>>()
        );
    }
    for (key, set) in &sets {
        assert!(
            found.iter().any(|(k, v)| k == key && v == set),
            "asyncapi.yaml does not list the names of `{key}`: {set:?}"
        );
    }
}

#[test]
fn every_field_the_plc_publishes_is_declared_in_its_message() {
    let doc = asyncapi();
    let objects = |v: &Value| -> Vec<String> {
        v.as_object()
            .map(|o| o.keys().cloned().collect())
            .unwrap_or_default()
    };
    let state = golden("state.json");
    let exec_info = golden("exec_info_field_io.json");
    let checks: Vec<(&str, &str, Vec<String>)> = vec![
        ("  messages:", "    State:", objects(&state)),
        ("  messages:", "    State:", objects(&state["cycle"])),
        ("  messages:", "    Io:", objects(&golden("io.json"))),
        (
            "  messages:",
            "    Event:",
            objects(&golden("events_substituted.json")),
        ),
        (
            "  messages:",
            "    Reply:",
            objects(&golden("reply_refused.json")),
        ),
        ("  schemas:", "    ExecInfo:", objects(&exec_info[0])),
        (
            "  schemas:",
            "    Summary:",
            objects(&state["cycle"]["scan"]),
        ),
    ];
    for (after, header, keys) in checks {
        let b = block(&doc, after, header);
        assert!(!keys.is_empty(), "{header}: the golden file has fields");
        for key in keys {
            assert!(
                declares(&b, &key),
                "asyncapi.yaml's {} does not declare `{key}`, which the PLC publishes",
                header.trim()
            );
        }
    }
}

#[test]
fn the_results_of_accepted_commands_are_declared() {
    use cetratus_proto::{Accepted, Verdict};
    let doc = asyncapi();
    let reply = block(&doc, "  messages:", "    Reply:");
    assert!(
        reply
            .iter()
            .any(|l| l.contains("#/components/schemas/Accepted"))
            && reply
                .iter()
                .any(|l| l.contains("#/components/schemas/ExecInfo")),
        "asyncapi.yaml's Reply result names neither Accepted nor ExecInfo: {reply:#?}"
    );
    // A load's result, with the analysis gate's verdict, as the PLC writes it.
    let accepted = Accepted {
        accepted: true,
        verdicts: vec![Verdict {
            figures: [("states".to_string(), 12.0)].into(),
            kind: VerdictKind::Analysis,
            reasons: vec!["no deadlock".into()],
            result: VerdictResult::Pass,
        }],
    };
    let v = serde_json::to_value(&accepted).expect("JSON");
    let schema = block(&doc, "  schemas:", "    Accepted:");
    for key in v.as_object().expect("an object").keys() {
        assert!(
            declares(&schema, key),
            "asyncapi.yaml's Accepted does not declare `{key}`"
        );
    }
    let verdict = block(&doc, "  schemas:", "    Verdict:");
    for key in v["verdicts"][0].as_object().expect("an object").keys() {
        assert!(
            declares(&verdict, key),
            "asyncapi.yaml's Verdict does not declare `{key}`"
        );
    }
}
