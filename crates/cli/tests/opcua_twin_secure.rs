//! `cetratus twin serve --opcua` with Sign & Encrypt and a user, against the real `cetratus run`
//! serving beyond loopback (on every address) with `security = "sign-and-encrypt"`: each side
//! trusts the other's certificate because an administrator copied it into its `trusted/`, and
//! the twin finishes parts as the PLC's plant (docs/io.md, *The twin as an OPC UA client*).

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use cetratus_testkit::opcua::hash_password;
use cetratus_testkit::ports::{free_port, wait_for_port};
use cetratus_testkit::process::{run_vernadat, stop_with_sigterm as stop, ChildGuard};
use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

#[test]
fn the_twin_logs_in_over_sign_and_encrypt_and_finishes_parts() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let port = free_port();
    let io = d.join("io.toml");
    std::fs::write(
        &io,
        format!("start_timeout = \"120s\"\n\n[opcua]\nlisten = \"opc.tcp://0.0.0.0:{port}\"\ninputs = true\nsecurity = \"sign-and-encrypt\"\npki = \"pki\"\n\n[[opcua.user]]\nname = \"twin\"\npassword_hash = \"{}\"\n", hash_password(BIN, "twin-secret")),
    )
    .unwrap();
    std::fs::write(d.join("password"), "twin-secret\n").unwrap();
    let twin_pki = d.join("twin-pki");
    let twin_cmd = |url: &str, for_: &str| {
        let mut c = Command::new(BIN);
        c.args(["twin", "serve", "vernadat", "--for", for_, "--json"])
            .args(["--opcua", url])
            .args(["--security", "sign-and-encrypt", "--user", "twin"])
            .arg("--pki")
            .arg(&twin_pki)
            .arg("--password-file")
            .arg(d.join("password"))
            .stdout(Stdio::piped())
            .stderr(Stdio::null());
        c
    };
    // The twin's certificate is made on first use (here against a port no one serves).
    {
        let _first = ChildGuard::spawn(&mut twin_cmd("opc.tcp://127.0.0.1:9", "1s"));
        let end = Instant::now() + Duration::from_secs(60);
        while !twin_pki.join("own/cert.der").exists() {
            assert!(Instant::now() < end, "the twin made no certificate");
            std::thread::sleep(Duration::from_millis(50));
        }
        std::thread::sleep(Duration::from_millis(500));
    }
    // The PLC trusts the twin: its certificate copied into the PLC's trusted/ under any name.
    std::fs::create_dir_all(d.join("pki/trusted")).unwrap();
    std::fs::copy(
        twin_pki.join("own/cert.der"),
        d.join("pki/trusted/twin.der"),
    )
    .unwrap();
    let plc = ChildGuard::spawn(
        run_vernadat(BIN, &io, d)
            .arg("--no-mqtt")
            .stdout(Stdio::piped())
            .stderr(Stdio::null()),
    );
    wait_for_port(port, "the PLC's OPC UA server", Duration::from_secs(120));
    // The twin trusts the PLC: its certificate copied into the twin's trusted/ under any name.
    std::fs::copy(d.join("pki/own/cert.der"), twin_pki.join("trusted/plc.der")).unwrap();
    let twin = ChildGuard::spawn(&mut twin_cmd(&format!("opc.tcp://127.0.0.1:{port}"), "20s"));
    let mut text = String::new();
    let mut twin = twin;
    std::io::Read::read_to_string(twin.0.stdout.as_mut().unwrap(), &mut text).unwrap();
    assert!(twin.0.wait().unwrap().success(), "{text}");
    let served: Value = serde_json::from_str(&text).unwrap_or_else(|e| panic!("{e}: {text}"));
    assert!(served["parts_finished"].as_u64().unwrap() >= 1, "{served}");
    assert_eq!(served["twin_faults"], 0, "{served}");
    assert_eq!(served["plc"], "cell", "{served}");
    let s = stop(plc);
    assert!(s["opcua_server"]["logins"].as_u64().unwrap() >= 1, "{s}");
    assert!(s["opcua_server"]["writes"].as_u64().unwrap() > 10, "{s}");
    // Trusted from the start: never refused.
    assert_eq!(
        std::fs::read_dir(d.join("pki/rejected")).unwrap().count(),
        0
    );
}

#[test]
fn a_password_never_travels_in_clear_nor_on_the_command_line() {
    let run = |args: &[&str], env: Option<&str>| {
        let mut c = Command::new(BIN);
        c.args([
            "twin",
            "serve",
            "vernadat",
            "--opcua",
            "opc.tcp://127.0.0.1:9",
        ])
        .args(args)
        .env_remove("CETRATUS_OPCUA_PASSWORD");
        if let Some(p) = env {
            c.env("CETRATUS_OPCUA_PASSWORD", p);
        }
        let out = c.output().unwrap();
        assert!(!out.status.success());
        String::from_utf8_lossy(&out.stderr).to_string()
    };
    let e = run(&["--user", "twin"], Some("x"));
    assert!(e.contains("need --security sign-and-encrypt"), "{e}");
    let e = run(
        &["--security", "sign-and-encrypt", "--user", "twin"],
        Some("x"),
    );
    assert!(e.contains("needs --pki DIR"), "{e}");
    let dir = tempfile::tempdir().unwrap();
    let pki = dir.path().join("p").display().to_string();
    let e = run(
        &[
            "--security",
            "sign-and-encrypt",
            "--pki",
            &pki,
            "--user",
            "twin",
        ],
        None,
    );
    assert!(e.contains("set CETRATUS_OPCUA_PASSWORD"), "{e}");
    let e = run(
        &[
            "--security",
            "sign-and-encrypt",
            "--pki",
            &pki,
            "--policy",
            "Basic128Rsa15",
        ],
        None,
    );
    assert!(e.contains("--policy Basic128Rsa15"), "{e}");
    let e = run(&["--password", "x"], None);
    assert!(e.contains("--password"), "{e}");
}
