//! Hostile and broken PLCopen files: each is a clear error with a position, never a panic, and
//! the work stays bounded (a property test over mutated fixtures).

use cetratus_sfc::SfcError;
use cetratus_testkit::paths::fixture;
use proptest::prelude::*;

fn read(rel: &str) -> String {
    let path = fixture(rel);
    std::fs::read_to_string(&path).unwrap_or_else(|e| {
        panic!(
            "cannot read {}: {e}; the fixtures live in ../shared/fixtures",
            path.display()
        )
    })
}

fn evolution_1() -> String {
    read("plcopen/twincat-sfc-evolution-1.xml")
}

fn import(text: &str) -> Result<cetratus_sfc::Imported, SfcError> {
    cetratus_sfc::import_str(text, "chart.xml", None, "chart.pnml")
}

/// A minimal PLCopen file around an SFC body.
fn project(sfc: &str, vars: &str) -> String {
    format!(
        r#"<?xml version="1.0"?>
<project xmlns="http://www.plcopen.org/xml/tc6_0201"><types><pous>
<pou name="P" pouType="program"><interface><localVars>{vars}</localVars></interface>
<body><SFC>{sfc}</SFC></body></pou></pous></types></project>"#
    )
}

fn bool_var(name: &str) -> String {
    format!(r#"<variable name="{name}"><type><BOOL/></type></variable>"#)
}

const TWO_STEPS: &str = r#"<step localId="1" name="A" initialStep="true"/>
<transition localId="2"><connectionPointIn><connection refLocalId="1"/></connectionPointIn>
<condition><inline name=""><ST><p>go</p></ST></inline></condition></transition>
<step localId="3" name="B"><connectionPointIn><connection refLocalId="2"/></connectionPointIn></step>
<transition localId="4"><connectionPointIn><connection refLocalId="3"/></connectionPointIn>
<condition><inline name=""><ST><p>NOT go</p></ST></inline></condition></transition>
<jumpStep localId="5" targetName="A"><connectionPointIn><connection refLocalId="4"/></connectionPointIn></jumpStep>"#;

#[test]
fn a_hand_written_minimal_chart_imports() {
    let imported = import(&project(TWO_STEPS, &bool_var("go"))).expect("imports");
    assert_eq!(imported.net.num_transitions(), 2);
    let condition = format!("\"T4\" = {q}\nNOT go{q}", q = "'".repeat(3));
    assert!(imported.toml.contains(&condition), "{}", imported.toml);
}

#[test]
fn malformed_xml_is_an_error_with_its_position() {
    let text = evolution_1().replacen("</transition>", "</transitio>", 1);
    let err = import(&text).expect_err("malformed");
    assert!(matches!(err, SfcError::Malformed { .. }), "{err}");
    assert!(err.to_string().contains("chart.xml:"), "{err}");
}

#[test]
fn two_initial_steps_in_one_network_are_refused_naming_both() {
    let text = evolution_1().replace(
        r#"<step localId="3" name="Step1">"#,
        r#"<step localId="3" name="Step1" initialStep="true">"#,
    );
    let err = import(&text).expect_err("two initial steps");
    let msg = err.to_string();
    assert!(msg.contains("`Start`") && msg.contains("`Step1`"), "{msg}");
    assert!(msg.starts_with("chart.xml:115:"), "{msg}");
}

#[test]
fn a_transition_with_no_target_is_refused() {
    let text = evolution_1();
    let start = text.find("<jumpStep").expect("a jump");
    let end = text.find("</jumpStep>").expect("its end") + "</jumpStep>".len();
    let cut = format!("{}{}", &text[..start], &text[end..]);
    let err = import(&cut).expect_err("no target");
    assert!(err.to_string().contains("has no target"), "{err}");
}

#[test]
fn a_jump_to_an_unknown_step_is_refused() {
    let text = evolution_1().replace(r#"targetName="Start""#, r#"targetName="Nowhere""#);
    let err = import(&text).expect_err("unknown jump");
    assert!(err.to_string().contains("`Nowhere`"), "{err}");
}

#[test]
fn an_unknown_variable_in_a_condition_is_refused_with_its_line_and_column() {
    let err = import(&project(TWO_STEPS, "")).expect_err("undeclared");
    let msg = err.to_string();
    assert!(msg.contains("unknown variable `go`"), "{msg}");
    assert!(msg.starts_with("chart.xml:6:35:"), "{msg}");
}

#[test]
fn a_macro_step_is_refused_by_name() {
    let sfc = TWO_STEPS
        .replace(
            r#"<step localId="3" name="B">"#,
            r#"<macroStep localId="3" name="B">"#,
        )
        .replace("</step>", "</macroStep>");
    let err = import(&project(&sfc, &bool_var("go"))).expect_err("macro step");
    assert!(
        err.to_string().contains("a macro step is not supported"),
        "{err}"
    );
}

#[test]
fn deep_st_nesting_in_a_condition_is_refused() {
    let sfc = TWO_STEPS.replace(
        "<p>go</p>",
        &format!("<p>{}go{}</p>", "(".repeat(500), ")".repeat(500)),
    );
    let err = import(&project(&sfc, &bool_var("go"))).expect_err("deep");
    assert!(err.to_string().contains("nested too deeply"), "{err}");
}

#[test]
fn an_entity_bomb_is_refused_as_too_large() {
    let entity = "x".repeat(10_000);
    let uses = "&e;".repeat(200);
    let text = format!(
        r#"<!DOCTYPE project [<!ENTITY e "{entity}">]><project xmlns="http://www.plcopen.org/xml/tc6_0201"><types>{uses}</types></project>"#
    );
    let err = import(&text).expect_err("bomb");
    assert!(matches!(err, SfcError::TooLarge { .. }), "{err}");
}

#[test]
fn deeply_nested_xml_is_a_clear_error_not_a_crash() {
    let depth = 200_000;
    let text = format!(
        r#"<project xmlns="http://www.plcopen.org/xml/tc6_0201">{}{}</project>"#,
        "<a>".repeat(depth),
        "</a>".repeat(depth)
    );
    let err = import(&text).expect_err("no POU");
    assert!(err.to_string().contains("no POU with an SFC body"), "{err}");
}

#[test]
fn a_file_over_the_size_limit_is_refused_before_parsing() {
    let text = format!(
        r#"<project xmlns="http://www.plcopen.org/xml/tc6_0201"><!--{}--></project>"#,
        " ".repeat(cetratus_sfc::MAX_FILE_BYTES)
    );
    let err = import(&text).expect_err("too large");
    assert!(matches!(err, SfcError::TooLarge { .. }), "{err}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// Mutations of a real chart (bytes overwritten, ranges deleted or duplicated) import or
    /// fail with an error; none panics.
    #[test]
    fn mutated_fixture_charts_never_panic(
        file in 0usize..3,
        edits in proptest::collection::vec((any::<u32>(), any::<u32>(), 0u8..3, any::<u8>()), 1..6),
    ) {
        let name = ["twincat-sfc-evolution-6.xml", "beremiz-first-steps.xml", "codesys-nested-sfc.xml"][file];
        let mut bytes = read(&format!("plcopen/{name}")).into_bytes();
        for (a, b, op, byte) in edits {
            let len = bytes.len().max(1);
            let i = a as usize % len;
            let j = (i + (b as usize % 64)).min(bytes.len());
            match op {
                0 => if let Some(x) = bytes.get_mut(i) { *x = byte },
                1 => { bytes.drain(i..j); }
                _ => { let piece = bytes[i..j].to_vec(); bytes.splice(i..i, piece); }
            }
        }
        let text = String::from_utf8_lossy(&bytes);
        let _ = cetratus_sfc::charts(&text, name);
        let _ = cetratus_sfc::import_str(&text, name, None, "n.pnml");
    }
}

/// `TWO_STEPS` with an N action on step A whose inline ST body is `body`.
fn with_body(body: &str) -> String {
    TWO_STEPS.replace(
        r#"<step localId="3" name="B">"#,
        &format!(
            r#"<actionBlock localId="9"><connectionPointIn><connection refLocalId="1"/></connectionPointIn><action localId="0" qualifier="N"><inline><ST><p><![CDATA[{body}]]></p></ST></inline></action></actionBlock>
<step localId="3" name="B">"#
        ),
    )
}

#[test]
fn an_unknown_variable_in_an_action_body_is_refused_with_the_pou_and_its_line_and_column() {
    let vars = bool_var("go");
    let err =
        import(&project(&with_body("go := TRUE;\nmissing := 1;"), &vars)).expect_err("unknown");
    let msg = err.to_string();
    assert!(msg.contains("in POU `P`"), "{msg}");
    assert!(msg.contains("unknown variable `missing`"), "{msg}");
    assert!(msg.starts_with("chart.xml:8:1:"), "{msg}");
}

#[test]
fn deep_if_nesting_in_an_action_body_is_refused_not_a_crash() {
    for depth in [65usize, 5_000] {
        let body = "IF go THEN ".repeat(depth) + "go := FALSE;" + &" END_IF;".repeat(depth);
        let err = import(&project(&with_body(&body), &bool_var("go"))).expect_err("deep");
        let msg = err.to_string();
        assert!(msg.contains("nested too deeply"), "{msg}");
    }
}

#[test]
fn loops_cases_and_block_calls_in_bodies_import_and_errors_stay_located() {
    let vars = format!(
        "{}<variable name=\"i\"><type><INT/></type></variable><variable name=\"f\"><type><derived name=\"F_TRIG\"/></type></variable>",
        bool_var("go")
    );
    for body in [
        "FOR i := 1 TO 3 DO go := TRUE; END_FOR;",
        "WHILE go DO go := FALSE; END_WHILE;",
        "CASE i OF 1: go := TRUE; END_CASE;",
        "i := i MOD 2;",
        "f(CLK := go); go := f.Q;",
    ] {
        let imported =
            import(&project(&with_body(body), &vars)).unwrap_or_else(|e| panic!("{body}: {e}"));
        assert!(imported.toml.contains("[st.bodies]"), "{body}");
    }
    let err = import(&project(&with_body("go := F_TRIG(go);"), &vars))
        .expect_err("an FB called as a function");
    assert!(matches!(err, SfcError::St { .. }), "{err}");
    assert!(err.to_string().starts_with("chart.xml:7:"), "{err}");
}

/// The project's name goes into the program's opening comment and description: one named
/// across lines, or with quotes and backslashes, stays a comment and a string.
#[test]
fn a_project_name_with_newlines_and_quotes_stays_in_its_comment() {
    let text = evolution_1();
    let at = text
        .find("<contentHeader name=\"")
        .expect("a contentHeader")
        + 21;
    let end = at + text[at..].find('"').unwrap();
    let hostile = format!(
        "{}x&#10;[program]&#10;name = &quot;evil\\&quot;{}",
        &text[..at],
        &text[end..]
    );
    let imported = import(&hostile).expect("imports");
    assert_eq!(imported.program.name(), "Main");
    let first = imported.toml.lines().next().unwrap();
    assert!(
        first.starts_with(
            "# Imported from the PLCopen TC6 XML project x [program] name = \"evil\\\""
        ),
        "{first}"
    );
}
