//! Paths the tests share: the workspace, its examples, the reference nets, and where tests leave
//! artifacts; and a fixture edited into a form the import refuses.

use std::path::{Path, PathBuf};

/// The root of the workspace.
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The file `rel` of the workspace's `examples/` directory, e.g. `vernadat/u1.toml`.
pub fn example(rel: &str) -> PathBuf {
    workspace_root().join("examples").join(rel)
}

/// The reference net `rel` of the fixtures shared with the other Petri net tools, e.g.
/// `pipe/ClassicGSPN.xml`; they live beside the workspace, in `../shared/fixtures`.
pub fn fixture(rel: &str) -> PathBuf {
    workspace_root().join("../shared/fixtures").join(rel)
}

/// `test-artifacts/` in the target directory, created if needed: screenshots and measured
/// figures that a person looks at after the run.
pub fn artifacts_dir() -> PathBuf {
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace_root().join("target"));
    let dir = target.join("test-artifacts");
    std::fs::create_dir_all(&dir)
        .unwrap_or_else(|e| panic!("cannot create {}: {e}", dir.display()));
    dir
}

/// Beremiz's SVGHMI traffic light (`plcopen/beremiz-svghmi-traffic-light.xml`) with the
/// condition of its transition 26, a negated contact drawn in the chart, written instead as an
/// inline Instruction List condition (`LDN SWITCH_BUTTON`): a form IEC 61131-3's 3rd edition
/// deprecates and the import refuses by name.
pub fn traffic_light_il() -> String {
    let xml = std::fs::read_to_string(fixture("plcopen/beremiz-svghmi-traffic-light.xml"))
        .expect("the traffic light fixture");
    let needle = "refLocalId=\"48\"";
    let at = xml.find(needle).expect("the condition's connection");
    let open = xml[..at].rfind("<condition>").expect("its <condition>");
    let close = at + xml[at..].find("</condition>").expect("its end") + "</condition>".len();
    let inline = "<condition><inline name=\"\"><IL><xhtml:p><![CDATA[LDN SWITCH_BUTTON]]></xhtml:p></IL></inline></condition>";
    format!("{}{inline}{}", &xml[..open], &xml[close..])
}

/// CODESYS's nested chart (`codesys-nested-sfc.xml`) with an R_TRIG drawn between the condition
/// of its nested transition and the box that feeds it, which reads `(i MOD 3) = 0`: a condition
/// that needs statements (the edge's call, then its `Q`), in a nested chart, where it holds only
/// while the chart's action is on.
pub fn codesys_nested_edge() -> String {
    let xml = std::fs::read_to_string(fixture("plcopen/codesys-nested-sfc.xml"))
        .expect("the nested chart fixture");
    let from = xml
        .find("<action name=\"sub_sfc1\">")
        .expect("the nested chart");
    let to = xml
        .find("<action name=\"shared_st1\"")
        .expect("the next action");
    let block = "<block localId=\"900\" typeName=\"R_TRIG\" instanceName=\"EDGE9\"><inputVariables><variable formalParameter=\"CLK\"><connectionPointIn><connection refLocalId=\"4\" /></connectionPointIn></variable></inputVariables><inOutVariables /><outputVariables><variable formalParameter=\"Q\"><connectionPointOut /></variable></outputVariables></block><inVariable localId=\"4\">";
    let nested = xml[from..to]
        .replace(
            "<connection refLocalId=\"4\" />",
            "<connection refLocalId=\"900\" formalParameter=\"Q\" />",
        )
        .replace("<inVariable localId=\"4\">", block)
        .replace(
            "<expression>FALSE</expression>",
            "<expression>(i MOD 3) = 0</expression>",
        );
    format!("{}{nested}{}", &xml[..from], &xml[to..])
}
