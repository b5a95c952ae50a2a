//! Paths the tests share: the workspace, its examples, the reference nets, and where tests leave
//! artifacts; and a fixture edited where the import refuses a form of it.

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

/// Beremiz's SVGHMI traffic light (`plcopen/beremiz-svghmi-traffic-light.xml`), a chart whose
/// named transition `STOP` is an FBD network and whose action `BLINK_ORANGE_LIGHT` is an LD
/// network, with the two conditions that it draws as networks in the chart itself (a form the
/// import refuses) written inline in ST: `NOT SWITCH_BUTTON`, which its LD contact means, and
/// `PEDESTRIAN_BUTTON OR WARN_CARS` in place of its latch and 2 s timer.
pub fn traffic_light_inline() -> String {
    let xml = std::fs::read_to_string(fixture("plcopen/beremiz-svghmi-traffic-light.xml"))
        .expect("the traffic light fixture");
    let xml = inline_condition(&xml, "refLocalId=\"48\"", "NOT SWITCH_BUTTON");
    inline_condition(&xml, "refLocalId=\"35\"", "PEDESTRIAN_BUTTON OR WARN_CARS")
}

/// `xml` with the `<condition>` that holds `needle` replaced by an inline ST condition `st`.
fn inline_condition(xml: &str, needle: &str, st: &str) -> String {
    let at = xml.find(needle).expect("the condition's connection");
    let open = xml[..at].rfind("<condition>").expect("its <condition>");
    let close = at + xml[at..].find("</condition>").expect("its end") + "</condition>".len();
    let inline = format!(
        "<condition><inline name=\"\"><ST><xhtml:p><![CDATA[{st}]]></xhtml:p></ST></inline></condition>"
    );
    format!("{}{inline}{}", &xml[..open], &xml[close..])
}
