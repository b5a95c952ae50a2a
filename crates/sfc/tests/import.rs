//! Importing the fixture charts as programs: what imports, what is refused, and how each
//! refusal names the construct, its POU and its line:column.

use cetratus_sfc::SfcError;
use cetratus_testkit::paths::fixture;

fn read(rel: &str) -> String {
    let path = fixture(rel);
    std::fs::read_to_string(&path).unwrap_or_else(|e| {
        panic!(
            "cannot read {}: {e}; the fixtures live in ../shared/fixtures",
            path.display()
        )
    })
}

fn import(file: &str, pou: Option<&str>) -> Result<cetratus_sfc::Imported, SfcError> {
    cetratus_sfc::import_str(&read(&format!("plcopen/{file}")), file, pou, "chart.pnml")
}

#[test]
fn the_twincat_charts_import_as_programs_with_their_conditions_in_structured_text() {
    let one = import("twincat-sfc-evolution-1.xml", None).expect("imports");
    let p = &one.program;
    assert_eq!(p.name(), "Main");
    assert_eq!(p.net().num_places(), 2);
    assert_eq!(p.net().initial_marking().as_slice(), &[1, 0]);
    let q = "'".repeat(3);
    let condition = format!("\"T2\" = {q}\nCondition_1{q}");
    assert!(one.toml.contains(&condition), "{}", one.toml);
    let six = import("twincat-sfc-evolution-6.xml", Some("main")).expect("imports");
    // The action ACT writes `changed`; the variable is declared `Changed`: one name, IEC case.
    assert!(six.toml.contains("changed := TRUE;"), "{}", six.toml);
    assert!(six
        .program
        .st()
        .is_some_and(|s| s.bool_var("CHANGED").is_some()));
    assert!(six.toml.contains("body = \"ACT\""), "{}", six.toml);
    assert!(six
        .notes
        .iter()
        .any(|n| n.contains("project-level addData")));
}

#[test]
fn importing_the_same_file_twice_gives_the_same_program_hash() {
    let a = import("twincat-sfc-evolution-6.xml", None).expect("imports");
    let b = import("twincat-sfc-evolution-6.xml", None).expect("imports");
    assert_eq!(a.program.hash(), b.program.hash());
    assert_eq!(a.toml, b.toml);
    let other = import("twincat-sfc-evolution-1.xml", None).expect("imports");
    assert_ne!(a.program.hash(), other.program.hash());
}

#[test]
fn refusals_name_the_construct_the_pou_and_the_line_and_column() {
    // Beremiz's traffic light with a condition in IL (`cetratus_testkit::paths`).
    let cases = [(
        cetratus_testkit::paths::traffic_light_il(),
        "light.xml:",
        "an inline IL condition",
    )];
    for (xml, at, construct) in cases {
        let err = cetratus_sfc::import_str(&xml, "light.xml", None, "chart.pnml").expect_err(at);
        let text = err.to_string();
        assert!(matches!(err, SfcError::Unsupported { .. }), "{text}");
        assert!(text.starts_with(at), "{text}");
        assert!(text.contains(construct), "{text}");
        assert!(text.contains("in POU `"), "{text}");
    }
}

/// The iec-checker chart's transition `TR1` is a named transition whose ST body has the
/// function-call form `:= AND(IN1, IN2, IN3);`: the ST compiler takes its expression. The chart
/// is then refused for its D action's duration `10s`, which is no IEC time literal; written as
/// `T#10s` (and its task's interval `10ms` as `T#10ms`), the chart imports.
#[test]
fn a_transition_body_in_the_function_call_form_is_read_as_its_expression() {
    let err = import("iec-checker-example.xml", Some("SFCTest")).expect_err("10s");
    let text = err.to_string();
    assert!(
        text.starts_with("iec-checker-example.xml:802:29:"),
        "{text}"
    );
    assert!(text.contains("T#10s"), "{text}");
    let fixed = read("plcopen/iec-checker-example.xml")
        .replace(r#"duration="10s""#, r#"duration="T#10s""#)
        .replace(r#"interval="10ms""#, r#"interval="T#10ms""#);
    let imported =
        cetratus_sfc::import_str(&fixed, "iec-checker-example.xml", Some("SFCTest"), "c.pnml")
            .unwrap_or_else(|e| panic!("{e}"));
    assert!(
        imported.toml.contains("AND(IN1, IN2, IN3)"),
        "{}",
        imported.toml
    );
    assert!(!imported.toml.contains(":= AND"), "{}", imported.toml);
}

#[test]
fn a_file_with_several_sfc_pous_needs_a_name_and_an_unknown_name_lists_them() {
    let text = read("plcopen/beremiz-first-steps.xml");
    let err =
        cetratus_sfc::import_str(&text, "f.xml", Some("Nope"), "n.pnml").expect_err("no such POU");
    assert!(err.to_string().contains("CounterSFC"), "{err}");
}

#[test]
fn a_pnml_file_is_not_taken_for_plcopen() {
    let pnml = read("mcc/TokenRing-PT-005.pnml");
    assert!(!cetratus_sfc::is_plcopen(&pnml));
    let err = cetratus_sfc::import_str(&pnml, "t.pnml", None, "n.pnml").expect_err("not PLCopen");
    assert!(err.to_string().contains("not PLCopen TC6 XML"), "{err}");
}

/// Beremiz's `CounterSFC` counts in every scan of its step `Count` and runs its bodies once more
/// as the step is left (IEC 61131-3's final run of a non-BOOL action), then `ResetCounter`
/// loads the configuration's constant 17.
#[test]
fn beremiz_counter_bodies_count_in_every_scan_of_their_step_with_the_iec_final_run() {
    use cetratus_program::Value;
    let imported = import("beremiz-first-steps.xml", Some("CounterSFC")).expect("imports");
    assert!(
        imported.toml.contains("Cnt := Cnt + 1"),
        "{}",
        imported.toml
    );
    let mut c = cetratus_runtime::Container::new(std::sync::Arc::new(imported.program), 0);
    let mut outs = Vec::new();
    for (k, reset) in [false, false, false, false, true, true, true, false]
        .iter()
        .enumerate()
    {
        c.scan(10_000 * (k as u64 + 1), &[Value::Bool(*reset)])
            .unwrap_or_else(|e| panic!("scan {k}: {e}"));
        outs.push(c.outputs()[0]);
    }
    let counted: Vec<Value> = [1, 2, 3, 4, 5, 17, 17, 17].map(Value::Int).into();
    assert_eq!(
        outs, counted,
        "counts 1 to 4, the final run 5, then the constant"
    );
}

#[test]
fn a_steps_entry_active_and_exit_actions_in_vendor_data_become_p1_n_and_p0_bodies() {
    let attr = |guid: &str, v: &str| format!(r#"<attribute guid="{guid}">{v}</attribute>"#);
    let step_data = format!(
        r#"<addData><data name="http://www.3s-software.com/plcopenxml/sfc/element" handleUnknown="implementation"><attributes xmlns="">{}{}{}{}</attributes></data></addData>"#,
        attr("38391c6d-6d4a-42f8-8ee7-9f45e5adafa8", "Work"),
        attr("a6b08bd8-b696-47e3-9cbf-7408b61c9ff8", "OnEntry"),
        attr("700a583f-b4d4-43e4-8c14-629c7cd3bec8", "{WhileActive}"),
        attr("a2621e18-7de3-4ea6-ae6d-89e9e0b7befd", "OnExit"),
    )
    .replace("{WhileActive}", "WhileActive");
    let action = |name: &str, st: &str| {
        format!(r#"<action name="{name}"><body><ST><p>{st}</p></ST></body></action>"#)
    };
    let text = format!(
        r#"<?xml version="1.0"?>
<project xmlns="http://www.plcopen.org/xml/tc6_0201"><types><pous>
<pou name="P" pouType="program"><interface><localVars>
<variable name="n"><type><INT/></type></variable>
<variable name="go"><type><BOOL/></type></variable>
</localVars></interface>
<actions>{}{}{}</actions>
<body><SFC>
<step localId="1" name="Idle" initialStep="true"/>
<transition localId="2"><connectionPointIn><connection refLocalId="1"/></connectionPointIn>
<condition><inline name=""><ST><p>go</p></ST></inline></condition></transition>
<step localId="3" name="Work"><connectionPointIn><connection refLocalId="2"/></connectionPointIn>{step_data}</step>
<transition localId="4"><connectionPointIn><connection refLocalId="3"/></connectionPointIn>
<condition><inline name=""><ST><p>NOT go</p></ST></inline></condition></transition>
<jumpStep localId="5" targetName="Idle"><connectionPointIn><connection refLocalId="4"/></connectionPointIn></jumpStep>
</SFC></body></pou></pous></types></project>"#,
        action("OnEntry", "n := 100;"),
        action("WhileActive", "n := n + 1;"),
        action("OnExit", "n := -n;"),
    );
    let imported = cetratus_sfc::import_str(&text, "steps.xml", None, "P.pnml").expect("imports");
    let toml = &imported.toml;
    for (q, body) in [("P1", "OnEntry"), ("N", "WhileActive"), ("P0", "OnExit")] {
        let block = format!("place = \"Work\"\nqualifier = \"{q}\"\nbody = \"{body}\"");
        assert!(toml.contains(&block), "{block} in\n{toml}");
    }
    assert!(toml.contains("n := n + 1"), "{toml}");
}

/// A POU `P` whose chart starts the action `Sub` at step `Run` (S) and stops it at `Off` (R);
/// `Sub`'s body is the chart `sub`, and the action `Inner` has the chart `inner`.
fn nested_pou(sub: &str, inner: &str) -> String {
    format!(
        r#"<?xml version="1.0"?>
<project xmlns="http://www.plcopen.org/xml/tc6_0201"><types><pous>
<pou name="P" pouType="program"><interface><localVars>
<variable name="go"><type><BOOL/></type></variable>
</localVars></interface>
<actions>
<action name="Sub"><body><SFC>{sub}</SFC></body></action>
<action name="Inner"><body><SFC>{inner}</SFC></body></action>
</actions>
<body><SFC>
<step localId="1" name="Run" initialStep="true"/>
<actionBlock localId="2"><connectionPointIn><connection refLocalId="1"/></connectionPointIn><action localId="0" qualifier="S"><reference name="Sub"/></action></actionBlock>
<transition localId="3"><connectionPointIn><connection refLocalId="1"/></connectionPointIn>
<condition><inline name=""><ST><p>go</p></ST></inline></condition></transition>
<step localId="4" name="Off"><connectionPointIn><connection refLocalId="3"/></connectionPointIn></step>
<actionBlock localId="5"><connectionPointIn><connection refLocalId="4"/></connectionPointIn><action localId="0" qualifier="R"><reference name="Sub"/></action></actionBlock>
<transition localId="6"><connectionPointIn><connection refLocalId="4"/></connectionPointIn>
<condition><inline name=""><ST><p>NOT go</p></ST></inline></condition></transition>
<jumpStep localId="7" targetName="Run"><connectionPointIn><connection refLocalId="6"/></connectionPointIn></jumpStep>
</SFC></body></pou></pous></types></project>"#
    )
}

/// A one-step chart whose step `name` runs the action `action` (N) and jumps back to itself.
fn loop_chart(name: &str, action: &str) -> String {
    format!(
        r#"<step localId="1" name="{name}" initialStep="true"/>
<actionBlock localId="2"><connectionPointIn><connection refLocalId="1"/></connectionPointIn><action localId="0" qualifier="N"><reference name="{action}"/></action></actionBlock>
<transition localId="3"><connectionPointIn><connection refLocalId="1"/></connectionPointIn>
<condition><inline name=""><ST><p>{name}.T &gt; T#1s</p></ST></inline></condition></transition>
<jumpStep localId="4" targetName="{name}"><connectionPointIn><connection refLocalId="3"/></connectionPointIn></jumpStep>"#
    )
}

#[test]
fn a_nested_chart_reads_its_own_steps_and_evolves_only_while_its_action_is_on() {
    // `Sub`'s chart associates the variable `go`, and reads its own step's time.
    let text = nested_pou(&loop_chart("A", "go"), &loop_chart("B", "go"));
    let imported = cetratus_sfc::import_str(&text, "n.xml", None, "P.pnml").expect("imports");
    let toml = &imported.toml;
    let q = "'".repeat(3);
    for condition in [
        format!("\"Sub__T3\" = {q}\nSub AND (A.T > T#1s){q}"),
        format!("\"Sub__A__hold\" = {q}\nNOT Sub{q}"),
        format!("\"Sub__A__resume\" = {q}\nSub{q}"),
    ] {
        assert!(toml.contains(&condition), "{condition} in {toml}");
    }
    assert!(
        toml.contains("place = \"Run\"\nqualifier = \"S\"\ntarget = \"Sub\""),
        "{toml}"
    );
    assert!(
        toml.contains("place = \"Sub__A\"\nqualifier = \"N\"\ntarget = \"go\""),
        "{toml}"
    );
    // `Inner` is associated by no step of P's chart: noted, not imported.
    assert!(
        imported
            .notes
            .iter()
            .any(|n| n.contains("`Inner`") && n.contains("not imported")),
        "{:?}",
        imported.notes
    );
    let place = imported
        .program
        .net()
        .place_by_id("Sub__A")
        .expect("the nested step");
    assert_eq!(
        imported.program.net().place(place).name.as_deref(),
        Some("Sub.A")
    );
}

#[test]
fn a_chart_nested_in_a_nested_chart_is_refused_by_name() {
    // `Sub`'s step starts `Inner`, whose body is a chart too: two levels.
    let text = nested_pou(&loop_chart("A", "Inner"), &loop_chart("B", "go"));
    let err = cetratus_sfc::import_str(&text, "n.xml", None, "P.pnml").expect_err("two levels");
    let msg = err.to_string();
    assert!(matches!(err, SfcError::Unsupported { .. }), "{msg}");
    assert!(msg.starts_with("n.xml:"), "{msg}");
    assert!(
        msg.contains("`Inner` with a SFC body inside the nested chart of action `Sub`"),
        "{msg}"
    );
    assert!(msg.contains("one level deep"), "{msg}");
    // A chart that starts itself is the same refusal, not a loop.
    let text = nested_pou(&loop_chart("A", "Sub"), &loop_chart("B", "go"));
    let msg = cetratus_sfc::import_str(&text, "n.xml", None, "P.pnml")
        .expect_err("itself")
        .to_string();
    assert!(
        msg.contains("`Sub` with a SFC body inside the nested chart of action `Sub`"),
        "{msg}"
    );
}

/// A transition drawn back into the step it leaves by a plain connection (not a jump): the
/// step is its source and its target (the walks that find the two once shared their marks,
/// and the target was not found).
#[test]
fn a_transition_connected_back_to_its_own_step_has_it_as_source_and_target() {
    let text = r#"<?xml version="1.0"?>
<project xmlns="http://www.plcopen.org/xml/tc6_0201"><types><pous>
<pou name="P" pouType="program"><interface><localVars>
<variable name="go"><type><BOOL/></type></variable>
</localVars></interface>
<body><SFC>
<step localId="1" name="A" initialStep="true"><connectionPointIn><connection refLocalId="2"/></connectionPointIn></step>
<transition localId="2"><connectionPointIn><connection refLocalId="1"/></connectionPointIn>
<condition><inline name=""><ST><p>go</p></ST></inline></condition></transition>
</SFC></body></pou></pous></types></project>"#;
    let imported = cetratus_sfc::import_str(text, "loop.xml", None, "P.pnml").expect("imports");
    let net = imported.program.net();
    let ends: Vec<_> = net.arcs().iter().map(|a| a.id.as_str()).collect();
    assert_eq!(ends, ["T2_from_A", "T2_to_A"]);
}
