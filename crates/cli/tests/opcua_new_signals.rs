//! After a live update adds signals to the I/O map (on channels a real pymodbus device serves),
//! the PLC's OPC UA server shows them: the `Inputs` and `Outputs` folders gain their nodes, with
//! a `GeneralModelChangeEventType` event on the Server object for each folder, as the `Marking`
//! folder does after a substitution. asyncua (FreeOpcUa's Python stack) browses and subscribes.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use cetratus_testkit::modbus;
use cetratus_testkit::opcua::command as peer;
use cetratus_testkit::ports::{free_port, wait_for_port};
use cetratus_testkit::process::ChildGuard;

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

/// `name.toml` and `name.pnml`: for each `(i, input, output)`, output `y{i}` follows `x{i}`.
fn program(dir: &Path, name: &str, signals: &[(usize, &str, &str)]) -> PathBuf {
    let mut pnml = String::from(
        "<?xml version=\"1.0\"?>\n<pnml xmlns=\"http://www.pnml.org/version-2009/grammar/pnml\">\n<net id=\"n\" type=\"http://www.pnml.org/version-2009/grammar/ptnet\"><page id=\"g\">\n",
    );
    let mut toml = format!("[program]\nname = \"follow\"\nversion = \"1.0.0\"\nnet = \"{name}.pnml\"\npolicy = \"step\"\nscan_period = \"10ms\"\n");
    let (mut outs, mut guards, mut actions) = (String::new(), String::new(), String::new());
    for &(i, input, output) in signals {
        pnml.push_str(&format!(
            "<place id=\"p{i}\"><initialMarking><text>1</text></initialMarking></place><place id=\"q{i}\"/>\n<transition id=\"on{i}\"/><transition id=\"off{i}\"/>\n<arc id=\"a{i}\" source=\"p{i}\" target=\"on{i}\"/><arc id=\"b{i}\" source=\"on{i}\" target=\"q{i}\"/><arc id=\"c{i}\" source=\"q{i}\" target=\"off{i}\"/><arc id=\"d{i}\" source=\"off{i}\" target=\"p{i}\"/>\n"
        ));
        toml.push_str(&format!(
            "[[input]]\nname = \"x{i}\"\ntype = \"bool\"\naddress = \"{input}\"\n"
        ));
        outs.push_str(&format!(
            "[[output]]\nname = \"y{i}\"\ntype = \"bool\"\naddress = \"{output}\"\n"
        ));
        guards.push_str(&format!("on{i} = \"x{i}\"\noff{i} = \"!x{i}\"\n"));
        actions.push_str(&format!(
            "[[action]]\nplace = \"q{i}\"\nqualifier = \"N\"\ntarget = \"y{i}\"\n"
        ));
    }
    pnml.push_str("</page></net></pnml>\n");
    toml.push_str(&outs);
    toml.push_str("[guards]\n");
    toml.push_str(&guards);
    toml.push_str(&actions);
    std::fs::write(dir.join(format!("{name}.pnml")), pnml).unwrap();
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, toml).unwrap();
    path
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn ok(out: Output) -> String {
    let t = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "{t}");
    t
}

fn browse(url: &str) -> Vec<String> {
    ok(peer().args(["browse", url]).output().unwrap())
        .lines()
        .map(str::to_string)
        .collect()
}

#[test]
fn signals_a_live_update_adds_to_the_io_map_appear_as_nodes_with_a_model_change_event() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let base = program(d, "base", &[(0, "%IX0.0", "%QX0.0")]);
    program(
        d,
        "grown",
        &[(0, "%IX0.0", "%QX0.0"), (5, "%IX0.5", "%QX0.5")],
    );
    let key = d.join("k.key");
    ok(Command::new(BIN)
        .args(["package", "keygen", "--out", s(&key)])
        .output()
        .unwrap());
    std::fs::create_dir_all(d.join("trusted")).unwrap();
    std::fs::copy(d.join("k.key.pub"), d.join("trusted/k.pub")).unwrap();
    let manifest = d.join("grown.package.toml");
    std::fs::write(&manifest, "[package]\nname = \"grown\"\nversion = \"1.1.0\"\nauthor = \"tests\"\nprogram = \"grown.toml\"\nbase = \"base.toml\"\n").unwrap();
    let pkg = d.join("grown.cpkg");
    ok(Command::new(BIN)
        .args([
            "package",
            "build",
            s(&manifest),
            "--key",
            s(&key),
            "-o",
            s(&pkg),
        ])
        .output()
        .unwrap());

    let (device, mqtt, port) = (free_port(), free_port(), free_port());
    let url = format!("opc.tcp://127.0.0.1:{port}");
    let _device = modbus::device(device, &["--di", "1,0,0,0,0,1"]);
    let io = d.join("io.toml");
    std::fs::write(
        &io,
        format!("[[device]]\nname = \"rack\"\ntransport = \"modbus-tcp\"\naddress = \"127.0.0.1:{device}\"\ntimeout = \"500ms\"\nserves = [{{ from = \"%IX0.0\", to = \"%IX0.7\" }}, {{ from = \"%QX0.0\", to = \"%QX0.7\" }}]\n\n[opcua]\nlisten = \"{url}\"\n"),
    )
    .unwrap();
    let _plc = ChildGuard::spawn(
        Command::new(BIN)
            .arg("run")
            .arg(&base)
            .arg("--io")
            .arg(&io)
            .args([
                "--for",
                "10min",
                "--cold",
                "--plc",
                "grow1",
                "--no-dashboard",
            ])
            .args(["--mqtt", &format!("127.0.0.1:{mqtt}")])
            .arg("--trust")
            .arg(d.join("trusted"))
            .arg("--state-dir")
            .arg(d.join("state"))
            .arg("--config")
            .arg(d.join("config"))
            .stdout(Stdio::null())
            .stderr(Stdio::null()),
    );
    wait_for_port(mqtt, "the embedded broker", Duration::from_secs(60));
    wait_for_port(port, "the PLC's OPC UA server", Duration::from_secs(60));
    let before = browse(&url);
    assert!(before.iter().any(|n| n == "grow1.Inputs.x0"), "{before:?}");
    assert!(!before.iter().any(|n| n == "grow1.Inputs.x5"), "{before:?}");

    // Subscribed to the Server's events before the load.
    let mut events = ChildGuard::spawn(
        peer()
            .args(["events", &url, "8", "--source"])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped()),
    );
    let mut out = BufReader::new(events.0.stdout.take().unwrap());
    let mut first = String::new();
    out.read_line(&mut first).unwrap();
    assert_eq!(first.trim(), "subscribed");

    let broker = format!("127.0.0.1:{mqtt}");
    ok(Command::new(BIN)
        .args(["load", s(&pkg), "--plc", "grow1", "--mqtt", &broker])
        .output()
        .unwrap());
    // The new nodes appear at the install, and follow the process image.
    let end = Instant::now() + Duration::from_secs(30);
    let after = loop {
        let after = browse(&url);
        if after.iter().any(|n| n == "grow1.Outputs.y5") || Instant::now() > end {
            break after;
        }
        std::thread::sleep(Duration::from_millis(200));
    };
    for want in ["grow1.Inputs.x5", "grow1.Outputs.y5", "grow1.Inputs.x0"] {
        assert!(after.iter().any(|n| n == want), "{want} in {after:?}");
    }
    // x5 is on at the device: the node shows what the scan read.
    let read = ok(peer()
        .args(["wait", &url, "grow1.Inputs.x5", "1", "20"])
        .output()
        .unwrap());
    assert_eq!(read.trim(), "ok");
    assert!(events.0.wait().unwrap().success());
    let mut lines = String::new();
    std::io::Read::read_to_string(&mut out, &mut lines).unwrap();
    for source in ["grow1.Inputs", "grow1.Outputs"] {
        assert!(
            lines.lines().any(|l| l == format!("i=2133 {source}")),
            "a model change on {source}: {lines}"
        );
    }
}
