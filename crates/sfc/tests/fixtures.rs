//! Every SFC chart of the PLCopen reference fixtures, read and compared with what
//! `plcopen/expected.json` says of it: steps, initial steps, transitions with their source and
//! target steps, divergences and convergences, jumps, action associations and qualifiers, and
//! the reachable markings of the structural net.

use std::collections::BTreeMap;

use cetratus_analysis::coverability::karp_miller;
use cetratus_analysis::reach::ReachOptions;
use cetratus_sfc::{ActionRef, Chart, Qualifier};
use cetratus_testkit::paths::fixture;
use serde_json::Value;

fn read(rel: &str) -> String {
    let path = fixture(rel);
    std::fs::read_to_string(&path).unwrap_or_else(|e| {
        panic!(
            "cannot read {}: {e}; the PLCopen fixtures live beside the workspace in ../shared/fixtures",
            path.display()
        )
    })
}

fn expected() -> Value {
    serde_json::from_str(&read("plcopen/expected.json")).expect("expected.json is JSON")
}

fn names(v: &Value) -> Vec<String> {
    v.as_array()
        .expect("an array")
        .iter()
        .map(|s| s.as_str().expect("a string").to_string())
        .collect()
}

fn count(v: &Value, key: &str) -> usize {
    v[key]
        .as_u64()
        .unwrap_or_else(|| panic!("`{key}` is a count")) as usize
}

/// The chart that `expected` describes: POU and location (`body` or `action NAME`).
fn find<'c>(charts: &'c [Chart], expected: &Value) -> &'c Chart {
    let pou = expected["pou"].as_str().expect("pou");
    let location = expected["where"].as_str().expect("where");
    charts
        .iter()
        .find(|c| c.pou == pou && c.location == location)
        .unwrap_or_else(|| panic!("no chart {pou} ({location}) was read"))
}

fn check_chart(file: &str, chart: &Chart, e: &Value, text: &str) {
    let what = format!("{file}: {} ({})", chart.pou, chart.location);
    let steps: Vec<String> = chart.steps.iter().map(|s| s.name.clone()).collect();
    assert_eq!(steps, names(&e["step_names"]), "{what}: steps");
    let initial: Vec<String> = chart
        .steps
        .iter()
        .filter(|s| s.initial)
        .map(|s| s.name.clone())
        .collect();
    assert_eq!(initial, names(&e["initial_steps"]), "{what}: initial steps");
    assert_eq!(chart.transitions.len(), count(e, "transitions"), "{what}");
    assert_eq!(
        chart.selection_divergences,
        count(e, "selection_divergences"),
        "{what}"
    );
    assert_eq!(
        chart.selection_convergences,
        count(e, "selection_convergences"),
        "{what}"
    );
    assert_eq!(
        chart.simultaneous_divergences,
        count(e, "simultaneous_divergences"),
        "{what}"
    );
    assert_eq!(
        chart.simultaneous_convergences,
        count(e, "simultaneous_convergences"),
        "{what}"
    );
    assert_eq!(chart.jumps.len(), count(e, "jump_steps"), "{what}: jumps");
    let mut targets: Vec<String> = Vec::new();
    for j in &chart.jumps {
        if !targets.contains(j) {
            targets.push(j.clone());
        }
    }
    assert_eq!(targets, names(&e["jump_targets"]), "{what}: jump targets");
    assert_eq!(chart.action_blocks, count(e, "action_blocks"), "{what}");
    assert_eq!(
        chart.associations.len(),
        count(e, "action_associations"),
        "{what}"
    );

    // Every transition, by localId, with its source and target steps.
    for t in e["transition_list"].as_array().expect("transition_list") {
        let id = t["localId"].as_str().expect("localId");
        let ours = chart
            .transitions
            .iter()
            .find(|x| x.local_id == id)
            .unwrap_or_else(|| panic!("{what}: transition {id} missing"));
        let mut from: Vec<String> = ours.from.iter().map(|&s| steps[s].clone()).collect();
        let mut to: Vec<String> = ours.to.iter().map(|&s| steps[s].clone()).collect();
        let (mut want_from, mut want_to) = (names(&t["from"]), names(&t["to"]));
        for v in [&mut from, &mut to, &mut want_from, &mut want_to] {
            v.sort();
        }
        assert_eq!((from, to), (want_from, want_to), "{what}: transition {id}");
        let form = t["condition_form"].as_str().expect("condition_form");
        // Every ST form is read as ST, the function-call form `:= …` of a body included.
        let supported = ours.condition.form() == "ST";
        let ours_st = form == "inline ST" || form == "inVariable" || form == "reference (ST body)";
        assert_eq!(supported, ours_st, "{what}: transition {id} is {form}");
    }

    // Qualifiers, with N for a missing attribute.
    let mut qualifiers: BTreeMap<String, u64> = BTreeMap::new();
    for a in &chart.associations {
        *qualifiers.entry(a.qualifier.to_string()).or_default() += 1;
    }
    let want: BTreeMap<String, u64> = e["qualifiers"]
        .as_object()
        .expect("qualifiers")
        .iter()
        .map(|(k, v)| (k.clone(), v.as_u64().expect("a count")))
        .collect();
    assert_eq!(qualifiers, want, "{what}: qualifiers");
    // Each association on its step, in order.
    for (ours, want) in chart
        .associations
        .iter()
        .zip(e["action_list"].as_array().expect("action_list"))
    {
        assert_eq!(
            chart.steps[ours.step].name,
            want["step"].as_str().expect("step"),
            "{what}"
        );
        let q = want["qualifier"].as_str().expect("qualifier");
        assert!(
            q.starts_with(&ours.qualifier.to_string()),
            "{what}: {q} vs {}",
            ours.qualifier
        );
        let duration = want["duration"].as_str().unwrap_or("");
        assert_eq!(
            ours.duration.as_deref().unwrap_or(""),
            duration,
            "{what}: duration"
        );
        let target = want["target"].as_str().expect("target");
        match &ours.action {
            ActionRef::Reference(name) => {
                assert!(target.contains(name.as_str()), "{what}: {target} vs {name}")
            }
            ActionRef::Inline(_) => assert!(target.starts_with("inline"), "{what}: {target}"),
        }
    }

    // The structural net: its reachable markings, edges and dead markings.
    let net = cetratus_sfc::chart_net(text, file, chart).expect("the structural net builds");
    let reach = &e["reachability"];
    let graph = karp_miller(&net, &ReachOptions::default());
    assert!(graph.unbounded.is_empty(), "{what}: bounded");
    assert_eq!(
        graph.nodes,
        reach["markings"].as_u64().expect("markings"),
        "{what}: markings"
    );
    assert_eq!(
        graph.edges,
        reach["edges"].as_u64().expect("edges"),
        "{what}: edges"
    );
    assert_eq!(
        graph.dead,
        reach["dead_markings"].as_u64().expect("dead"),
        "{what}: dead"
    );
}

#[test]
fn every_fixture_chart_reads_as_expected_json_describes_it() {
    let expected = expected();
    let files = expected["files"].as_object().expect("files");
    assert_eq!(files.len(), 6, "six PLCopen files");
    let mut checked = 0;
    for (file, facts) in files {
        let text = read(&format!("plcopen/{file}"));
        assert!(
            cetratus_sfc::is_plcopen(&text),
            "{file} is recognised as PLCopen"
        );
        let charts = cetratus_sfc::charts(&text, file)
            .unwrap_or_else(|e| panic!("{file} does not read: {e}"));
        let want = facts["sfc_charts"].as_array().expect("sfc_charts");
        assert_eq!(charts.len(), want.len(), "{file}: charts");
        for e in want {
            check_chart(file, find(&charts, e), e, &text);
            checked += 1;
        }
    }
    assert_eq!(checked, 7, "seven charts in all");
}

#[test]
fn a_selection_divergence_gives_the_leftmost_branch_the_highest_priority() {
    let text = read("plcopen/beremiz-first-steps.xml");
    let imported = cetratus_sfc::charts(&text, "beremiz-first-steps.xml").expect("reads");
    let chart = imported
        .iter()
        .find(|c| c.pou == "CounterSFC")
        .expect("CounterSFC");
    let net = cetratus_sfc::chart_net(&text, "f", chart).expect("net");
    let start = net.place_by_id("Start").expect("Start");
    let mut leaving: Vec<_> = net.consumers(start).iter().map(|&(t, _)| t).collect();
    leaving.sort_by_key(|&t| std::cmp::Reverse(net.transition(t).priority));
    let xs: Vec<f64> = leaving
        .iter()
        .map(|&t| {
            let id = &net.transition(t).id;
            chart
                .transitions
                .iter()
                .find(|x| format!("T{}", x.local_id) == *id)
                .expect("transition")
                .x
        })
        .collect();
    assert!(xs.windows(2).all(|w| w[0] < w[1]), "left to right: {xs:?}");
    assert!(net.transition(leaving[0]).priority > net.transition(leaving[1]).priority);
}

#[test]
fn qualifiers_read_from_the_fixtures_are_the_iec_ones() {
    assert_eq!(Qualifier::parse("SD"), Some(Qualifier::SD));
    assert_eq!(Qualifier::parse("X"), None);
}

#[test]
fn the_nested_codesys_chart_imports_with_both_charts_as_expected_json_describes_them() {
    let file = "codesys-nested-sfc.xml";
    let text = read(&format!("plcopen/{file}"));
    let imported = cetratus_sfc::import_str(&text, file, None, "PLC_PRG.pnml")
        .unwrap_or_else(|e| panic!("{file} imports: {e}"));
    let expected = expected();
    let want = expected["files"][file]["sfc_charts"]
        .as_array()
        .expect("sfc_charts");
    assert_eq!(want.len(), 2, "the POU's chart and the chart of sub_sfc1");
    assert_eq!(imported.nested.len(), 1, "one nested chart");
    let (main, nested) = (&want[0], &want[1]);
    assert_eq!(main["where"], "body");
    assert_eq!(nested["where"], "action sub_sfc1");
    // Each chart as imported: counts, transitions, qualifiers and its own reachable markings.
    check_chart(file, &imported.chart, main, &text);
    check_chart(file, &imported.nested[0], nested, &text);

    // Both charts are in the program's net: the nested steps and transitions qualified by the
    // action's name, each with its source and target steps.
    let net = imported.program.net();
    for (chart, prefix) in [(main, ""), (nested, "sub_sfc1__")] {
        for s in names(&chart["step_names"]) {
            let p = net
                .place_by_id(&format!("{prefix}{s}"))
                .unwrap_or_else(|| panic!("step {prefix}{s} is a place"));
            let initial = net.initial_marking().as_slice()[p.index()];
            // A nested chart's initial step waits in its held place until the action is on.
            let want_initial = prefix.is_empty() && names(&chart["initial_steps"]).contains(&s);
            assert_eq!(initial == 1, want_initial, "{prefix}{s}: initial marking");
        }
        for t in chart["transition_list"].as_array().expect("transitions") {
            let id = format!("{prefix}T{}", t["localId"].as_str().expect("localId"));
            let t_idx = net
                .transition_by_id(&id)
                .unwrap_or_else(|| panic!("transition {id}"));
            let ids = |arcs: &[(cetratus_net::PlaceIdx, u32)]| {
                let mut v: Vec<String> =
                    arcs.iter().map(|&(p, _)| net.place(p).id.clone()).collect();
                v.sort();
                v
            };
            let qualified = |v: Vec<String>| {
                let mut v: Vec<String> = v.into_iter().map(|s| format!("{prefix}{s}")).collect();
                v.sort();
                v
            };
            assert_eq!(
                ids(net.pre(t_idx)),
                qualified(names(&t["from"])),
                "{id}: from"
            );
            assert_eq!(ids(net.post(t_idx)), qualified(names(&t["to"])), "{id}: to");
        }
    }
    let held = net
        .place_by_id("sub_sfc1__Init_sub_sfc1__held")
        .expect("the held place of the nested initial step");
    assert_eq!(net.initial_marking().as_slice()[held.index()], 1);
    // Steps: 6 + 1, each nested step with its held place; transitions: 5 + 1, and a hold and a
    // resume per nested step.
    assert_eq!(net.num_places(), 6 + 1 + 1);
    assert_eq!(net.num_transitions(), 5 + 1 + 2);
    // The program's own reachable markings, guards ignored: the nested chart's single step is
    // active or held in every marking of the POU's chart, independently, so the markings are
    // the product, and from each marking the chart's edges, the nested chart's own edges while
    // its step is active, and one hold or resume edge leave.
    let m = |c: &Value| {
        let r = &c["reachability"];
        (
            r["markings"].as_u64().expect("markings"),
            r["edges"].as_u64().expect("edges"),
        )
    };
    let ((main_m, main_e), (nested_m, nested_e)) = (m(main), m(nested));
    assert_eq!(
        count(nested, "steps"),
        1,
        "the product rule below is for one nested step"
    );
    let graph = karp_miller(net, &ReachOptions::default());
    assert!(graph.unbounded.is_empty());
    assert_eq!(graph.nodes, main_m * nested_m * 2, "markings");
    assert_eq!(
        graph.edges,
        main_e * 2 + main_m * nested_e + main_m * 2,
        "edges"
    );
    assert_eq!(graph.dead, 0, "dead markings");
}
