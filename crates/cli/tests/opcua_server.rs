//! The PLC's OPC UA server, against asyncua (FreeOpcUa's Python stack, installed by scripts/test)
//! as its client: it browses the nodes, reads and subscribes to them, writes the inputs when the
//! I/O configuration says OPC UA provides them, and every malformed write gets a Bad status while
//! the PLC runs on. A configuration that would serve beyond loopback without security is refused.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use cetratus_testkit::opcua::run as peer;
use cetratus_testkit::paths::example;
use cetratus_testkit::ports::{free_port, wait_for_port};
use cetratus_testkit::process::{
    demo_files, json_of, run_vernadat, stop_with_sigterm as stop, ChildGuard,
};
use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

fn write_io(dir: &Path, body: &str) -> PathBuf {
    let io = dir.join("io.toml");
    std::fs::write(&io, body).expect("write io.toml");
    io
}

/// The Vernadat program in real time as PLC `cell`, with `io` and `extra` arguments.
fn start(dir: &Path, io: &Path, port: u16, extra: &[&str]) -> ChildGuard {
    let plc = ChildGuard::spawn(
        run_vernadat(BIN, io, dir)
            .arg("--no-mqtt")
            .args(extra)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped()),
    );
    wait_for_port(port, "the PLC's OPC UA server", Duration::from_secs(60));
    plc
}

#[test]
fn a_scada_client_browses_reads_and_subscribes_and_cannot_write_a_read_only_node() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let url = format!("opc.tcp://127.0.0.1:{port}");
    let io = write_io(
        dir.path(),
        // Eight connections: the three sessions below come from one address, which may hold
        // half of them.
        &format!("[opcua]\nlisten = \"{url}\"\nmax_sessions = 2\nmax_connections = 8\n"),
    );
    let plc = start(dir.path(), &io, port, &["--twin", "vernadat"]);
    let nodes = peer(&["browse", &url]);
    assert_eq!(nodes[0], "cell", "{nodes:?}");
    for want in [
        "cell.PRIMARY",
        "cell.STATUS",
        "cell.Inputs.PE",
        "cell.Inputs.PS",
        "cell.Outputs.CM1",
        "cell.Marking.H",
        "cell.Marking.P24",
        "cell.ExecInfo.Cycles",
        "cell.ExecInfo.ProgramHash",
    ] {
        assert!(nodes.iter().any(|n| n == want), "{want} in {nodes:?}");
    }
    // 13 places, 8 inputs and 8 outputs, PRIMARY, STATUS, 7 figures, 4 folders and the PLC.
    assert_eq!(nodes.len(), 1 + 4 + 2 + 8 + 8 + 13 + 7, "{nodes:?}");
    let read = peer(&[
        "read",
        &url,
        "cell.PRIMARY",
        "cell.STATUS",
        "cell.ExecInfo.Program",
    ]);
    assert_eq!(
        read,
        [
            "cell.PRIMARY=A",
            "cell.STATUS=idle",
            "cell.ExecInfo.Program=vernadat-cell"
        ]
    );
    // Subscriptions are sampled at the cycle: the cycle counter is told of again and again.
    let sub = peer(&["subscribe", &url, "cell.ExecInfo.Cycles", "1.5"]);
    let distinct: u64 = sub[0].parse().unwrap();
    assert!(distinct >= 3, "{sub:?}");
    // Nothing here is writable: outputs, the marking, STATUS, and the inputs the twin provides.
    for (node, ty, value) in [
        ("cell.Outputs.CM1", "bool", "1"),
        ("cell.Marking.H", "int32", "5"),
        ("cell.STATUS", "string", "fault"),
        ("cell.Inputs.PE", "bool", "1"),
    ] {
        let got = peer(&["write", &url, node, ty, value]);
        assert_eq!(got, ["BadUserAccessDenied"], "{node}");
    }
    let got = peer(&["write", &url, "cell.Outputs.NOPE", "bool", "1"]);
    assert_eq!(got, ["BadNodeIdUnknown"]);
    // Sessions beyond max_sessions are refused.
    let sessions = peer(&["sessions", &url, "3"]);
    assert_eq!(sessions, ["2", "BadTooManySessions"]);
    // A flood of connections: those beyond the limit are closed at once, and the server answers.
    let closed: u64 = peer(&["flood", &url, "20"])[0].parse().unwrap();
    assert!(closed >= 16, "{closed} of 20 closed");
    let read = peer(&["read", &url, "cell.STATUS", "cell.Marking.NOPE"]);
    assert_eq!(
        read,
        ["cell.STATUS=idle", "cell.Marking.NOPE=BadNodeIdUnknown"]
    );
    let s = stop(plc);
    assert!(
        s["opcua_server"]["refused_connections"].as_u64().unwrap() >= 16,
        "{s}"
    );
    assert!(s["opcua_server"]["published"].as_u64().unwrap() > 10, "{s}");
    assert_eq!(s["opcua_server"]["writes"], 0, "{s}");
    assert!(s["parts_finished"].as_u64().is_some(), "{s}");
}

#[test]
fn inputs_from_opcua_reach_the_program_and_malformed_writes_get_a_bad_status() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let url = format!("opc.tcp://127.0.0.1:{port}");
    let io = write_io(
        dir.path(),
        &format!("start_timeout = \"1s\"\n\n[opcua]\nlisten = \"{url}\"\ninputs = true\n"),
    );
    let plc = start(dir.path(), &io, port, &[]);
    let got = peer(&[
        "run",
        &url,
        // Wrong types, a range, a node that is not there, a read-only node.
        "w:cell.Inputs.PE:double:1.5",
        "w:cell.Inputs.PE:int64:1",
        "w:cell.Inputs.PE:string:true",
        "w:cell.Inputs.NOPE:bool:1",
        "w:cell.Outputs.CM1:bool:1",
        "w:cell.ExecInfo.Cycles:int64:0",
        // The program gets what a client writes, from the next cycle on.
        "w:cell.Inputs.PE:bool:1",
        "wait:cell.Inputs.PE:1",
        "w:cell.Inputs.PE:bool:0",
        "wait:cell.Inputs.PE:0",
        "r:cell.STATUS",
    ]);
    assert_eq!(
        got,
        [
            "BadTypeMismatch",
            "BadTypeMismatch",
            "BadTypeMismatch",
            "BadNodeIdUnknown",
            "BadUserAccessDenied",
            "BadUserAccessDenied",
            "ok",
            "ok",
            "ok",
            "ok",
            "idle"
        ]
    );
    let s = stop(plc);
    assert_eq!(s["opcua_server"]["writes"], 2, "{s}");
    assert!(
        s["opcua_server"]["refused_writes"].as_u64().unwrap() >= 1,
        "{s}"
    );
}

#[test]
fn a_server_beyond_loopback_without_security_is_refused_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let io = write_io(
        dir.path(),
        "[opcua]\nlisten = \"opc.tcp://0.0.0.0:14899\"\n",
    );
    let out = Command::new(BIN)
        .arg("run")
        .arg(example("vernadat/vernadat.toml"))
        .args(["--twin", "vernadat", "--no-mqtt", "--cold", "--for", "1s"])
        .arg("--io")
        .arg(&io)
        .arg("--config")
        .arg(dir.path().join("config"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(err.contains("io.toml:2:"), "{err}");
    assert!(err.contains("policy None is only for loopback"), "{err}");
}

/// The one real-time OPC UA run of this suite: a minute of the cell with the twin host as the
/// OPC UA client of the PLC (the paper's setup), U.1 and then U.2 loaded and substituted on the
/// way, compared with the in-process twin under the same script.
#[test]
fn a_minute_with_the_twin_as_the_plcs_opcua_client_finishes_as_many_parts_as_in_process() {
    let demo = demo_files(BIN);
    let d = demo.path();
    let port = free_port();
    let io = d.join("io-opcua.toml");
    let text = std::fs::read_to_string(example("vernadat/io-opcua.toml")).unwrap();
    std::fs::write(&io, text.replace("14840", &port.to_string())).unwrap();
    let url = format!("opc.tcp://127.0.0.1:{port}");
    let pkg = |name: &str| d.join(name).display().to_string();
    let script = [
        "--trust".to_string(),
        pkg("trusted"),
        "--at".into(),
        format!("10s load {}", pkg("u1.cpkg")),
        "--at".into(),
        "20s substitute".into(),
        "--at".into(),
        "25s accept".into(),
        "--at".into(),
        format!("30s load {}", pkg("u2.cpkg")),
        "--at".into(),
        "40s substitute".into(),
        "--at".into(),
        "45s accept".into(),
    ];
    // The twin retries until the PLC serves; the PLC waits for the twin's first sensors.
    let twin = ChildGuard::spawn(
        Command::new(BIN)
            .args(["twin", "serve", "vernadat", "--for", "60s", "--json"])
            .args(["--opcua", &url])
            .stdout(Stdio::piped())
            .stderr(Stdio::null()),
    );
    // The PLC outlives the twin, so that the twin never sees its outputs go safe mid-move.
    let plc = ChildGuard::spawn(
        Command::new(BIN)
            .arg("run")
            .arg(d.join("vernadat.toml"))
            .arg("--io")
            .arg(&io)
            .args([
                "--no-mqtt",
                "--cold",
                "--json",
                "--plc",
                "cell",
                "--for",
                "62s",
            ])
            .args(&script)
            .arg("--state-dir")
            .arg(d.join("state"))
            .arg("--config")
            .arg(d.join("config"))
            .stdout(Stdio::piped())
            .stderr(Stdio::null()),
    );
    let served = json_of(twin);
    let run = json_of(plc);
    let in_process = Command::new(BIN)
        .arg("run")
        .arg(d.join("vernadat.toml"))
        .args(["--twin", "vernadat", "--virtual", "--for", "60s", "--json"])
        .arg("--config")
        .arg(d.join("config"))
        .args(&script)
        .output()
        .unwrap();
    let in_process: Value = serde_json::from_slice(&in_process.stdout).unwrap();
    let (two, one) = (
        served["parts_finished"].as_i64().unwrap(),
        in_process["parts_finished"].as_i64().unwrap(),
    );
    assert!(
        one > 0 && (two - one).abs() <= 1,
        "two processes {two}, in process {one}: {served}"
    );
    assert_eq!(served["twin_faults"], 0, "{served}");
    assert_eq!(served["plc"], "cell", "{served}");
    let substituted = run["events"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e["kind"] == "substituted")
        .count();
    assert_eq!(substituted, 2, "{run}");
    assert_eq!(run["opcua_server"]["model_changes"], 2, "{run}");
    assert!(run["faults"].as_array().unwrap().is_empty(), "{run}");
}

#[test]
fn after_a_substitution_the_marking_nodes_follow_the_new_program_with_a_model_change_event() {
    let demo = demo_files(BIN);
    let d = demo.path();
    let (port, mqtt) = (free_port(), free_port());
    let url = format!("opc.tcp://127.0.0.1:{port}");
    let io = write_io(d, &format!("[opcua]\nlisten = \"{url}\"\n"));
    let pkg = |name: &str| d.join(name).display().to_string();
    let mqtt = format!("127.0.0.1:{mqtt}");
    let plc = ChildGuard::spawn(
        run_vernadat(BIN, &io, d)
            .args(["--twin", "vernadat", "--trust", &pkg("trusted")])
            .args(["--mqtt", &mqtt, "--no-dashboard"])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped()),
    );
    wait_for_port(port, "the PLC's OPC UA server", Duration::from_secs(60));
    let before = peer(&["browse", &url]);
    assert!(
        !before.iter().any(|n| n == "cell.Marking.P30"),
        "{before:?}"
    );
    let hash_before = peer(&["read", &url, "cell.ExecInfo.ProgramHash"]);
    // Subscribed to the Server's events before the first substitution, until after the second
    // model change (GeneralModelChangeEventType, i=2133); the updates go over MQTT once the
    // subscription is confirmed.
    let mut events = ChildGuard::spawn(
        cetratus_testkit::opcua::command()
            .args(["events", &url, "120", "--until", "i=2133:2"])
            .stdout(Stdio::piped()),
    );
    let mut lines = std::io::BufRead::lines(std::io::BufReader::new(
        events.0.stdout.take().expect("the peer's output"),
    ));
    let first = lines.next().and_then(Result::ok);
    assert_eq!(first.as_deref(), Some("subscribed"));
    for verb in [
        vec!["load", &pkg("u1.cpkg")],
        vec!["substitute"],
        vec!["accept"],
        vec!["load", &pkg("u2.cpkg")],
        vec!["substitute"],
    ] {
        let out = Command::new(BIN)
            .args(&verb)
            .args(["--plc", "cell", "--mqtt", &mqtt, "--timeout", "60s"])
            .output()
            .expect("the client runs");
        assert!(out.status.success(), "{verb:?}: {out:?}");
    }
    let events: Vec<String> = lines.map_while(Result::ok).collect();
    let changes = events.iter().filter(|e| *e == "i=2133").count();
    assert!(changes >= 2, "{events:?}");
    let after = peer(&["browse", &url]);
    for want in ["cell.Marking.P30", "cell.Marking.P31", "cell.Marking.H"] {
        assert!(after.iter().any(|n| n == want), "{want} in {after:?}");
    }
    let hash_after = peer(&["read", &url, "cell.ExecInfo.ProgramHash"]);
    assert_ne!(hash_before, hash_after);
    let s = stop(plc);
    assert!(
        s["opcua_server"]["model_changes"].as_u64().unwrap() >= 2,
        "{s}"
    );
}

#[test]
fn an_encrypted_login_needs_a_trusted_certificate_and_the_right_password() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let port = free_port();
    let url = format!("opc.tcp://127.0.0.1:{port}");
    let mut hash = Command::new(BIN)
        .arg("hash-password")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    std::io::Write::write_all(hash.stdin.as_mut().unwrap(), b"panel-secret\n").unwrap();
    let hash = hash.wait_with_output().unwrap();
    let hash = String::from_utf8_lossy(&hash.stdout).trim().to_string();
    assert!(hash.starts_with("$argon2id$"), "{hash}");
    let io = write_io(
        d,
        &format!("[opcua]\nlisten = \"{url}\"\nsecurity = \"sign-and-encrypt\"\npki = \"pki\"\n\n[[opcua.user]]\nname = \"hmi\"\npassword_hash = \"{hash}\"\n"),
    );
    let plc = start(d, &io, port, &["--twin", "vernadat"]);
    assert_eq!(peer(&["keys", &d.display().to_string()]), ["ok"]);
    let (cert, key) = (d.join("client.der"), d.join("client.pem"));
    let login = |policy: &str, password: &str| {
        peer(&[
            "secure",
            &url,
            policy,
            &cert.display().to_string(),
            &key.display().to_string(),
            "--user",
            "hmi",
            "--password",
            password,
        ])
        .join(" ")
    };
    // Unknown to the server: refused, and kept for an administrator to look at.
    let first = login("Basic256Sha256", "panel-secret");
    assert!(first.starts_with("refused"), "{first}");
    let rejected_dir = d.join("pki/rejected");
    let end = Instant::now() + Duration::from_secs(10);
    let rejected = loop {
        let found: Vec<_> = std::fs::read_dir(&rejected_dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        if !found.is_empty() || Instant::now() > end {
            break found;
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    assert_eq!(rejected.len(), 1, "{first}: {rejected:?}");
    let name = rejected[0].file_name().unwrap().to_owned();
    std::fs::rename(&rejected[0], d.join("pki/trusted").join(name)).unwrap();
    // Trusted now: each policy logs in with the right password, never with a wrong one.
    for policy in [
        "Basic256Sha256",
        "Aes128_Sha256_RsaOaep",
        "Aes256_Sha256_RsaPss",
    ] {
        assert_eq!(login(policy, "panel-secret"), "idle", "{policy}");
    }
    let wrong = login("Aes256_Sha256_RsaPss", "panel-secreT");
    assert!(wrong.starts_with("refused"), "{wrong}");
    stop(plc);
}
