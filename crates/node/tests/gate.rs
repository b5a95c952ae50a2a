//! The analysis gate at load on the real packages of the examples: U.1 passes, U.2 warns of the
//! machine invariants it changes, a U.1 without T24 reaches a deadlock and loses T23 and T24, and
//! the policy turns a finding into a refusal.

use std::path::Path;
use std::sync::Arc;

use cetratus_node::gate::{self, GatePolicy, Severity};
use cetratus_program::{build_package, Program, TrustStore};
use cetratus_runtime::{
    ManualStopwatch, Plc, PreparedUpdate, UpdateContext, VerdictKind, VerdictResult,
};

const EXAMPLES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/vernadat");

/// A copy of the Vernadat example, where a test may change files before building a package.
fn workshop() -> tempfile::TempDir {
    let dir = tempfile::tempdir().expect("a temporary directory");
    for entry in std::fs::read_dir(EXAMPLES).expect("the example") {
        let path = entry.expect("an entry").path();
        if path.extension().is_some_and(|e| e == "toml" || e == "pnml") {
            let name = path.file_name().expect("a name");
            std::fs::copy(&path, dir.path().join(name)).expect("copy");
        }
    }
    dir
}

/// The context of a PLC at cold start running `base`, and `manifest` prepared against it.
fn prepared(dir: &Path, base: &str, manifest: &str) -> (UpdateContext, PreparedUpdate) {
    let program = Arc::new(Program::load(&dir.join(base)).expect("the program"));
    let plc = Plc::new(program, 0, Box::new(ManualStopwatch::default()));
    let ctx = plc.update_context();
    let (bytes, _) =
        build_package(&dir.join(manifest), None, 1_700_000_000).expect("the package builds");
    let up = ctx
        .prepare_package(
            &bytes,
            &TrustStore::empty(),
            cetratus_program::Unsigned::Allowed,
            cetratus_program::OtherBase::Refused,
        )
        .expect("the package fits the running program");
    (ctx, up)
}

/// U.1 without T24: machine 2's part is never unloaded, so the robot and the cell stop.
fn without_t24(dir: &Path) {
    let net = std::fs::read_to_string(dir.join("u1.pnml")).expect("u1.pnml");
    let start = net.find("<transition id=\"T24\">").expect("T24");
    let end = start + net[start..].find("</transition>").expect("its end") + "</transition>".len();
    let mut cut = format!("{}{}", &net[..start], &net[end..]);
    for arc in [
        "<arc id=\"P23-T24\" source=\"P23\" target=\"T24\"/>",
        "<arc id=\"R-T24\" source=\"R\" target=\"T24\"/>",
        "<arc id=\"T24-P24\" source=\"T24\" target=\"P24\"/>",
    ] {
        assert!(cut.contains(arc), "{arc}");
        cut = cut.replace(arc, "");
    }
    std::fs::write(dir.join("u1.pnml"), cut).expect("write");
}

#[test]
fn u1_passes_the_gate_with_both_graphs_explored() {
    let dir = workshop();
    let (ctx, up) = prepared(dir.path(), "vernadat.toml", "u1.package.toml");
    let out = gate::run(&ctx, &up, &GatePolicy::default());
    assert_eq!(out.verdict.result, VerdictResult::Pass, "{:?}", out.verdict);
    assert!(out.refusal.is_none());
    assert!(out.verdict.figures["states_candidate"] > 100.0);
    assert!(out.verdict.figures["states_primary"] > 100.0);
}

#[test]
fn u2_warns_that_it_changes_the_running_programs_machine_invariants() {
    let dir = workshop();
    let (ctx, up) = prepared(dir.path(), "u1.toml", "u2.package.toml");
    let out = gate::run(&ctx, &up, &GatePolicy::default());
    assert_eq!(out.verdict.result, VerdictResult::Warn, "{:?}", out.verdict);
    let text = out.verdict.reasons.join("\n");
    assert!(
        text.contains("`P10 + P11 + P12 + P13 + P14 = 1` is changed by T12 in the new net"),
        "{text}"
    );
    assert!(!text.contains("deadlock"), "{text}");
    assert!(!text.contains("lost transitions"), "{text}");
    assert!(out.refusal.is_none(), "warnings by default");
}

#[test]
fn a_candidate_that_cannot_unload_machine_2_deadlocks_with_a_witness_and_loses_t23_and_t24() {
    let dir = workshop();
    without_t24(dir.path());
    let (ctx, up) = prepared(dir.path(), "vernadat.toml", "u1.package.toml");
    let out = gate::run(&ctx, &up, &GatePolicy::default());
    assert_eq!(out.verdict.result, VerdictResult::Warn, "{:?}", out.verdict);
    let text = out.verdict.reasons.join("\n");
    assert!(text.contains("deadlock: the candidate reaches"), "{text}");
    assert!(
        text.contains("a shortest firing sequence to one: T"),
        "{text}"
    );
    assert!(
        text.contains("lost transitions: T24, T23 can fire"),
        "{text}"
    );
    assert!(out.refusal.is_none());

    let strict = GatePolicy {
        deadlock: Severity::Refuse,
        ..GatePolicy::default()
    };
    let out = gate::run(&ctx, &up, &strict);
    assert_eq!(out.verdict.result, VerdictResult::Fail);
    let refusal = out.refusal.expect("refused by policy");
    assert!(
        refusal.contains("deadlock") && !refusal.contains("lost transitions"),
        "{refusal}"
    );
    assert!(refusal.contains("[updates]"), "{refusal}");
}

#[test]
fn a_budget_of_a_few_states_says_the_findings_are_partial() {
    let dir = workshop();
    let (ctx, up) = prepared(dir.path(), "vernadat.toml", "u1.package.toml");
    let tight = GatePolicy {
        max_states: 10,
        ..GatePolicy::default()
    };
    let out = gate::run(&ctx, &up, &tight);
    let text = out.verdict.reasons.join("\n");
    assert!(text.contains("stopped early"), "{text}");
    assert!(out.verdict.figures["states_candidate"] <= 11.0);
}

/// A scripted load is gated from the marking its install transforms: the primary's at the cycle
/// boundary the load is due at, not an earlier one. The deadlock witness of a U.1 without T24 is a
/// shortest firing sequence from where the candidate starts, so it differs from one moment of the
/// cell to another; the node's verdict is the gate's from the marking of the install's boundary.
#[test]
fn a_scripted_load_is_gated_from_the_marking_of_the_boundary_it_is_installed_at() {
    use cetratus_io::TwinDriver;
    use cetratus_node::script::Script;
    use cetratus_node::{Node, NodeOptions};
    use cetratus_runtime::{EventKind, LoopTiming, Slot};
    use cetratus_twin::TwinKind;

    const PERIOD: u64 = 10_000;
    const DUE: u64 = 7_000_000;
    let dir = workshop();
    without_t24(dir.path());
    let (bytes, _) =
        build_package(&dir.path().join("u1.package.toml"), None, 1_700_000_000).expect("builds");
    let pkg = dir.path().join("u1.cpkg");
    std::fs::write(&pkg, &bytes).expect("write");
    let program = Arc::new(Program::load(&dir.path().join("vernadat.toml")).expect("program"));
    let io = TwinDriver::new(
        TwinKind::Vernadat.build(1),
        program.inputs(),
        program.outputs(),
    )
    .expect("the signals match");
    let mut plc = Plc::new(program, 0, Box::new(ManualStopwatch::default()));
    plc.use_virtual_time(PERIOD);
    let at_start = plc.update_context();
    let opts = NodeOptions {
        base_us: 0,
        load: cetratus_node::load::LoadPolicy {
            trust: TrustStore::empty(),
            unsigned: cetratus_program::Unsigned::Allowed,
            gate: Default::default(),
        },
        record_trace: false,
        watch: Vec::new(),
        progress_every: None,
    };
    let script = Script::parse(&[format!("{}us load {}", DUE, pkg.display())]).expect("script");
    let mut node = Node::new(plc, io, opts).with_script(script);
    let idle = LoopTiming::default();
    let mut now = 0;
    while now < DUE {
        node.step(now, &idle).expect("a cycle");
        now += PERIOD;
    }
    // The context of the boundary the load is due at, as a test sees it from outside.
    let at_due = node.plc().update_context();
    let events = node.step(now, &idle).expect("the install's cycle");
    let started = events
        .iter()
        .find(|e| e.kind == EventKind::QuarantineStarted)
        .unwrap_or_else(|| panic!("{events:#?}"));
    assert_eq!(started.cycle, at_due.cycle, "installed at that boundary");
    let info = node.plc().exec_info();
    let verdict = info[Slot::B.index()]
        .as_ref()
        .and_then(|c| c.verdicts.iter().find(|v| v.kind == VerdictKind::Analysis))
        .expect("the candidate's analysis verdict")
        .clone();
    assert_eq!(verdict.figures["from_cycle"], at_due.cycle as f64);

    let gate_at = |ctx: &UpdateContext| {
        let up = ctx
            .prepare_package(
                &bytes,
                &TrustStore::empty(),
                cetratus_program::Unsigned::Allowed,
                cetratus_program::OtherBase::Refused,
            )
            .expect("prepares");
        gate::run(ctx, &up, &GatePolicy::default()).verdict.reasons
    };
    let witness = |reasons: &[String]| {
        reasons
            .iter()
            .find(|r| r.starts_with("deadlock:"))
            .cloned()
            .unwrap_or_else(|| panic!("a deadlock finding: {reasons:?}"))
    };
    assert_eq!(
        witness(&verdict.reasons),
        witness(&gate_at(&at_due)),
        "the node's gate explored from the install's marking"
    );
    assert_ne!(
        witness(&gate_at(&at_due)),
        witness(&gate_at(&at_start)),
        "the cell has moved on since it started: another marking, another shortest witness"
    );
}
