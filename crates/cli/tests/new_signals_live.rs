//! A live update that uses signals the running program does not: when their addresses are on
//! channels a field device serves, they join the I/O map at the install, and after the
//! substitution the new output reaches a real pymodbus device, following a new input read from
//! it. An output no program drives holds the safe value of the last program that declared it:
//! a new one until its candidate is PRIMARY, and those the new primary drops after the
//! substitution, and on a stop. The PLC's Modbus server shows the new signals from the install on. A candidate
//! whose new signal no device serves is refused at load, naming it.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use cetratus_testkit::modbus;
use cetratus_testkit::ports::{free_port, wait_for_port};
use cetratus_testkit::process::{stop_with_sigterm, ChildGuard};

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

/// Writes `name.toml` and `name.pnml`: for each `(i, input address, output address, safe)`,
/// output `y{i}` follows input `x{i}` one cycle later, with `safe = true` when `safe`. `extra` is
/// appended to the TOML.
fn program(
    dir: &Path,
    name: &str,
    version: &str,
    signals: &[(usize, &str, &str, bool)],
    extra: &str,
) -> PathBuf {
    let mut pnml = String::from(
        "<?xml version=\"1.0\"?>\n<pnml xmlns=\"http://www.pnml.org/version-2009/grammar/pnml\">\n<net id=\"n\" type=\"http://www.pnml.org/version-2009/grammar/ptnet\"><page id=\"g\">\n",
    );
    let mut toml = format!(
        "[program]\nname = \"follow\"\nversion = \"{version}\"\nnet = \"{name}.pnml\"\npolicy = \"step\"\nscan_period = \"10ms\"\n"
    );
    let (mut outs, mut guards, mut actions) = (String::new(), String::new(), String::new());
    for &(i, input, output, safe) in signals {
        pnml.push_str(&format!(
            "<place id=\"p{i}\"><initialMarking><text>1</text></initialMarking></place><place id=\"q{i}\"/>\n<transition id=\"on{i}\"/><transition id=\"off{i}\"/>\n<arc id=\"a{i}\" source=\"p{i}\" target=\"on{i}\"/><arc id=\"b{i}\" source=\"on{i}\" target=\"q{i}\"/><arc id=\"c{i}\" source=\"q{i}\" target=\"off{i}\"/><arc id=\"d{i}\" source=\"off{i}\" target=\"p{i}\"/>\n"
        ));
        toml.push_str(&format!(
            "[[input]]\nname = \"x{i}\"\ntype = \"bool\"\naddress = \"{input}\"\n"
        ));
        outs.push_str(&format!(
            "[[output]]\nname = \"y{i}\"\ntype = \"bool\"\naddress = \"{output}\"\n{}",
            if safe { "safe = true\n" } else { "" }
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
    toml.push_str(extra);
    std::fs::write(dir.join(format!("{name}.pnml")), pnml).expect("write the net");
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, toml).expect("write the program");
    path
}

fn s(p: &Path) -> &str {
    p.to_str().expect("a UTF-8 path")
}

fn cetratus(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .output()
        .expect("cetratus runs")
}

fn text(out: &Output) -> String {
    format!(
        "exit {:?}\nstdout: {}\nstderr: {}",
        out.status.code(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// A signed package of `name.toml` over `base.toml`, with `more` appended to its manifest.
fn package(dir: &Path, key: &Path, name: &str, more: &str) -> PathBuf {
    let manifest = dir.join(format!("{name}.package.toml"));
    std::fs::write(
        &manifest,
        format!("[package]\nname = \"{name}\"\nversion = \"1.1.0\"\nauthor = \"tests\"\nprogram = \"{name}.toml\"\nbase = \"base.toml\"\n{more}"),
    )
    .expect("write the manifest");
    let pkg = dir.join(format!("{name}.cpkg"));
    let out = cetratus(&[
        "package",
        "build",
        s(&manifest),
        "--key",
        s(key),
        "-o",
        s(&pkg),
    ]);
    assert!(out.status.success(), "{}", text(&out));
    pkg
}

/// What a pymodbus client reads from the device's coils.
fn coils(port: u16) -> String {
    modbus::read(port, "coils", 0, 8)
}

fn wait_coils(port: u16, want: &str) -> String {
    wait_for(port, "coils", 0, 8, want)
}

/// What a pymodbus client reads from `count` entries of `table` at `address`, once it is `want`
/// or after 30 s.
fn wait_for(port: u16, table: &str, address: u16, count: u16, want: &str) -> String {
    let end = Instant::now() + Duration::from_secs(30);
    let mut seen = String::new();
    while Instant::now() < end {
        seen = modbus::read(port, table, address, count);
        if seen == want {
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    seen
}

#[test]
fn an_update_adds_signals_on_configured_channels_and_undriven_outputs_hold_their_safe_values() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    // y1 (safe true) follows x1, which is off; w2 (safe 1234) is 7 while x0 is on.
    let base = program(
        d,
        "base",
        "1.0.0",
        &[(0, "%IX0.0", "%QX0.0", false), (1, "%IX0.1", "%QX0.1", true)],
        "[[output]]\nname = \"w2\"\ntype = \"int\"\naddress = \"%QW2\"\nsafe = 1234\n[bodies]\nSet = \"w2 := 7\"\n[[action]]\nplace = \"q0\"\nqualifier = \"N\"\nbody = \"Set\"\n",
    );
    // Drops y1 and w2; adds x5 and y5 (safe true), which follows x5, off; y0 is safe on now.
    program(
        d,
        "grown",
        "1.1.0",
        &[(0, "%IX0.0", "%QX0.0", true), (5, "%IX0.5", "%QX0.5", true)],
        "",
    );
    // x9 at %IX2.0, which no device serves.
    program(
        d,
        "unserved",
        "1.1.0",
        &[
            (0, "%IX0.0", "%QX0.0", false),
            (9, "%IX2.0", "%QX0.6", false),
        ],
        "",
    );
    let key = d.join("k.key");
    let out = cetratus(&["package", "keygen", "--out", s(&key)]);
    assert!(out.status.success(), "{}", text(&out));
    std::fs::create_dir_all(d.join("trusted")).expect("mkdir");
    std::fs::copy(d.join("k.key.pub"), d.join("trusted/k.pub")).expect("copy the key");
    // The tokens of x1's loop, which the update removes, go to x5's (whose own initial token
    // the derivation gives up, so that the loop holds one). A revert gives x1's loop its token
    // back at p1: the generated projection would leave it empty and is refused, so the package
    // writes it.
    let grown = package(
        d,
        &key,
        "grown",
        "[transform]\nkind = \"generated\"\nremoved = { p1 = \"p5\", q1 = \"p5\" }\n[projection]\nkind = \"sparse\"\nidentity_on_kept = true\nbase = { p1 = 1 }\n",
    );
    let unserved = package(
        d,
        &key,
        "unserved",
        "[projection]\nkind = \"sparse\"\nidentity_on_kept = true\nbase = { p1 = 1 }\n",
    );

    // The device has x0 on, x1 and x5 off.
    let (device, mqtt, server) = (free_port(), free_port(), free_port());
    let _device = modbus::device(device, &["--di", "1,0,0,0,0,0"]);
    let io = d.join("io.toml");
    std::fs::write(
        &io,
        format!("[[device]]\nname = \"rack\"\ntransport = \"modbus-tcp\"\naddress = \"127.0.0.1:{device}\"\ntimeout = \"500ms\"\nserves = [{{ from = \"%IX0.0\", to = \"%IX0.7\" }}, {{ from = \"%QX0.0\", to = \"%QX0.7\" }}, {{ from = \"%QW0\", to = \"%QW3\" }}]\n[server]\nmodbus = \"127.0.0.1:{server}\"\n"),
    )
    .expect("write io.toml");
    let plc = ChildGuard::spawn(
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
                "--json",
            ])
            .args(["--mqtt", &format!("127.0.0.1:{mqtt}")])
            .arg("--trust")
            .arg(d.join("trusted"))
            .arg("--state-dir")
            .arg(d.join("state"))
            .arg("--config")
            .arg(d.join("config"))
            .stdout(Stdio::piped())
            .stderr(Stdio::piped()),
    );
    wait_for_port(mqtt, "the embedded broker", Duration::from_secs(60));
    let broker = format!("127.0.0.1:{mqtt}");
    let client = |args: &[&str]| {
        Command::new(BIN)
            .args(args)
            .args(["--plc", "grow1", "--mqtt", &broker])
            .output()
            .expect("the client runs")
    };
    // y0 on, y1 off (driven), coil 5 has no program yet; w2 is 7.
    assert_eq!(wait_coils(device, "1,0,0,0,0,0,0,0"), "1,0,0,0,0,0,0,0");
    assert_eq!(wait_for(device, "hr", 0, 4, "0,0,7,0"), "0,0,7,0");
    // The PLC's Modbus server shows the signals of the running program: x5 and y5 are not there.
    assert_eq!(wait_for(server, "coils", 0, 2, "1,0"), "1,0");
    let before = modbus::read(server, "coils", 5, 1);
    assert!(before.starts_with("exception"), "coil 5 before: {before}");
    let before = modbus::read(server, "di", 5, 1);
    assert!(
        before.starts_with("exception"),
        "discrete input 5 before: {before}"
    );

    // A new signal no device serves: refused at load, naming it and its address.
    let out = client(&["load", s(&unserved)]);
    assert_ne!(out.status.code(), Some(0), "{}", text(&out));
    let t = text(&out);
    assert!(
        t.contains("x9") && t.contains("%IX2.0") && t.contains("no device"),
        "{t}"
    );

    // New signals on configured channels: loaded and in quarantine. The candidate's y5 is not
    // driven yet: it holds the candidate's safe value; the primary still drives y1 and w2.
    let out = client(&["load", s(&grown)]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    assert_eq!(
        wait_coils(device, "1,0,0,0,0,1,0,0"),
        "1,0,0,0,0,1,0,0",
        "a new output holds its candidate's safe value until the candidate is PRIMARY"
    );
    assert_eq!(modbus::read(device, "hr", 0, 4), "0,0,7,0");
    // From the install on, the server shows them: y5 as dispatched, x5 as read.
    assert_eq!(
        wait_for(server, "coils", 0, 6, "1,0,0,0,0,1"),
        "1,0,0,0,0,1"
    );
    assert_eq!(wait_for(server, "di", 0, 6, "1,0,0,0,0,0"), "1,0,0,0,0,0");

    // Substituted: y5 follows x5 (off); y1 and w2, which no program drives any more, hold the
    // safe values of the program that declared them last.
    let out = client(&["substitute"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    assert_eq!(
        wait_coils(device, "1,1,0,0,0,0,0,0"),
        "1,1,0,0,0,0,0,0",
        "y5 follows x5 and the dropped y1 holds its safe value true"
    );
    assert_eq!(
        wait_for(device, "hr", 0, 4, "0,0,1234,0"),
        "0,0,1234,0",
        "the dropped w2 holds its safe value 1234"
    );
    assert_eq!(
        wait_for(server, "coils", 0, 6, "1,1,0,0,0,0"),
        "1,1,0,0,0,0"
    );
    assert_eq!(modbus::read(server, "hr", 0, 3), "0,0,1234");
    // The status registers are where they were: PRIMARY is B.
    assert_eq!(wait_for(server, "ir", 8192, 1, "1"), "1");
    // A new input is read-only to clients.
    let w = modbus::client(&["write", &server.to_string(), "coils", "8197", "1"]);
    assert!(w.starts_with("exception"), "a write to x5's mirror: {w}");
    let out = Command::new(BIN)
        .args(["exec-info", "--broker", &format!("mqtt://{broker}")])
        .args(["--plc", "grow1", "--json"])
        .output()
        .expect("exec-info");
    let t = String::from_utf8_lossy(&out.stdout);
    assert!(t.contains("\"rack\"") && t.contains("\"good\""), "{t}");

    // On a stop every output goes to the safe value of the program that declared it last: y0
    // to the new primary's (on), y1 and w2 to the old one's, y5 to the new one's.
    stop_with_sigterm(plc);
    assert_eq!(coils(device), "1,1,0,0,0,1,0,0");
    assert_eq!(modbus::read(device, "hr", 0, 4), "0,0,1234,0");
}
