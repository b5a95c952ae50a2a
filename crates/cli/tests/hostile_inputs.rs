//! Files and messages built to crash, steer or exhaust a PLC, against the real binary: each must
//! end in an ordinary error that says what is too big or wrong, where, and the limit, and a
//! running PLC must answer with an error and go on scanning.
//!
//! * a guard of 20,000 terms (the guard compiler recursed once per term and overflowed the
//!   stack) in `check`, `sim`, `run` and `package inspect`, and as the condition of a
//!   `substitute` command sent over MQTT to a running PLC;
//! * a PNML file whose one 100 KB internal entity is used 20,000 times (2 GB once expanded, which
//!   the reader tried to allocate);
//! * PNML files of one element with a million attributes, or a million namespace prefixes in
//!   scope (the reader searched both lists linearly, 10¹² steps: hours of CPU);
//! * program, package manifest and configuration TOML files that are not UTF-8 (a program was
//!   read as Latin-1 before, silently).

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use base64::engine::general_purpose::STANDARD as B64;
use base64::Engine as _;
use cetratus_net::pnml::MAX_ENTITY_EXPANSION;
use cetratus_program::guard::MAX_TOKENS;
use cetratus_testkit::mqtt;
use cetratus_testkit::paths::example;
use cetratus_testkit::ports::{free_port, wait_for_port};
use cetratus_testkit::process::{output_within, ChildGuard};
use serde_json::{json, Value};

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

/// `PE && PE && …`, 20,000 terms: about 120 KB of text.
fn huge_guard() -> String {
    vec!["PE"; 20_000].join(" && ")
}

fn cetratus(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .output()
        .expect("cetratus runs")
}

fn path(p: &Path) -> &str {
    p.to_str().expect("a UTF-8 temporary path")
}

/// Asserts that `out` is an ordinary failure (exit status 1, not a signal such as SIGABRT or
/// SIGSEGV) whose message holds every one of `needles`; returns the message.
fn refused(what: &str, out: &Output, needles: &[&str]) -> String {
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(
        out.status.code(),
        Some(1),
        "{what}: expected exit status 1, got {:?}; stderr: {}",
        out.status,
        tail(&err)
    );
    for needle in needles {
        assert!(
            err.contains(needle),
            "{what}: expected `{needle}` in: {}",
            tail(&err)
        );
    }
    err
}

/// The end of a message that may quote a whole hostile input.
fn tail(s: &str) -> &str {
    let mut start = s.len().saturating_sub(2000);
    while !s.is_char_boundary(start) {
        start -= 1;
    }
    &s[start..]
}

/// The Vernadat example in a directory of its own, the guard of T10 replaced by `guard`.
fn vernadat_with_guard(dir: &Path, guard: &str) -> PathBuf {
    std::fs::copy(example("vernadat/vernadat.pnml"), dir.join("vernadat.pnml")).expect("copy");
    let toml = std::fs::read_to_string(example("vernadat/vernadat.toml")).expect("read");
    assert!(
        toml.contains("T10 = \"PE\""),
        "the example's guard of T10 moved"
    );
    let program = dir.join("vernadat.toml");
    std::fs::write(
        &program,
        toml.replace("T10 = \"PE\"", &format!("T10 = \"{guard}\"")),
    )
    .expect("write");
    program
}

#[test]
fn a_guard_of_twenty_thousand_terms_is_a_clear_error_in_check_sim_run_and_package_inspect() {
    let dir = tempfile::tempdir().expect("temp dir");
    let program = vernadat_with_guard(dir.path(), &huge_guard());
    let limit = MAX_TOKENS.to_string();
    let needles = ["vernadat.toml:", "T10", "too long", limit.as_str()];
    let p = path(&program);
    for args in [
        vec!["check", p],
        vec!["sim", p],
        vec!["run", p, "--twin", "vernadat", "--virtual", "--for", "1s"],
    ] {
        refused(&args.join(" "), &cetratus(&args), &needles);
    }

    // A package whose program carries the guard: built from U.1, then its program replaced (the
    // package is unsigned, so the change needs no key).
    let cpkg = dir.path().join("u1.cpkg");
    let out = cetratus(&[
        "package",
        "build",
        path(&example("vernadat/u1.package.toml")),
        "--unsigned",
        "-o",
        path(&cpkg),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut envelope: Value =
        serde_json::from_slice(&std::fs::read(&cpkg).expect("read the package")).expect("JSON");
    let payload_b64 = envelope["payload"].as_str().expect("a payload").to_string();
    let mut payload: Value =
        serde_json::from_slice(&B64.decode(payload_b64).expect("base64")).expect("JSON");
    let toml = payload["program_toml"]
        .as_str()
        .expect("a program")
        .to_string();
    assert!(toml.contains("T10 = \"PE\""), "U.1's guard of T10 moved");
    payload["program_toml"] =
        Value::String(toml.replace("T10 = \"PE\"", &format!("T10 = \"{}\"", huge_guard())));
    envelope["payload"] = Value::String(B64.encode(payload.to_string()));
    std::fs::write(&cpkg, envelope.to_string()).expect("write the package");
    refused(
        "package inspect",
        &cetratus(&["package", "inspect", path(&cpkg)]),
        &["package:program.toml:", "T10", "too long", &limit],
    );
}

#[test]
fn a_substitute_condition_of_twenty_thousand_terms_gets_an_error_reply_and_the_plc_goes_on() {
    let work = tempfile::tempdir().expect("temp dir");
    let (state, config) = (work.path().join("state"), work.path().join("config"));
    std::fs::create_dir_all(&config).expect("an empty configuration");
    let log = std::fs::File::create(work.path().join("plc.log")).expect("a log file");
    let port = free_port();
    let _plc = ChildGuard::spawn(
        Command::new(BIN)
            .arg("run")
            .arg(example("vernadat/vernadat.toml"))
            .args(["--twin", "vernadat", "--no-dashboard", "--plc", "cell1"])
            .args(["--mqtt", &format!("127.0.0.1:{port}")])
            .args(["--state-dir", path(&state), "--config", path(&config)])
            .stdout(Stdio::null())
            .stderr(log),
    );
    wait_for_port(port, "the PLC's embedded broker", Duration::from_secs(20));
    let plc_log = || std::fs::read_to_string(work.path().join("plc.log")).unwrap_or_default();
    let cycles = || -> u64 {
        let end = Instant::now() + Duration::from_secs(20);
        while Instant::now() < end {
            if let Some(v) = mqtt::sub_one(port, "cetratus/cell1/exec_info", 2, false) {
                if let Some(c) = v[0]["cycles"].as_u64() {
                    return c;
                }
            }
        }
        panic!("no exec_info from the PLC; its log: {}", tail(&plc_log()));
    };
    let before = cycles();

    let reply = std::panic::catch_unwind(|| {
        mqtt::request_v311(
            port,
            "cetratus/cell1/cmd/substitute",
            json!({ "when": huge_guard() }),
            "cetratus/cell1/reply/t",
        )
    })
    .unwrap_or_else(|_| {
        panic!(
            "no reply to the substitute; the PLC's log: {}",
            tail(&plc_log())
        )
    });
    assert_eq!(reply["ok"], false, "{reply}");
    let message = reply["error"]["message"].as_str().unwrap_or_default();
    assert!(
        message.contains("too long") && message.contains(&MAX_TOKENS.to_string()),
        "{message}"
    );
    assert!(
        message.len() < 2000,
        "the reply quotes the whole condition: {} bytes",
        message.len()
    );

    // Still scanning, still answering.
    assert!(cycles() > before, "the PLC stopped scanning");
    let info = mqtt::request_v311(
        port,
        "cetratus/cell1/cmd/exec_info",
        json!({}),
        "cetratus/cell1/reply/t2",
    );
    assert_eq!(info["ok"], true, "{info}");
}

/// An ISO PNML net of one place whose name (`in_text`) or tool-specific attribute uses a 100 KB
/// internal entity 20,000 times.
fn entity_bomb(in_text: bool) -> String {
    let refs = "&big;".repeat(20_000);
    let place = if in_text {
        format!("<place id=\"p\"><name><text>{refs}</text></name></place>")
    } else {
        format!("<place id=\"p\"><toolspecific tool=\"{refs}\" version=\"1\"/></place>")
    };
    format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
         <!DOCTYPE pnml [\n<!ENTITY big \"{}\">\n]>\n\
         <pnml xmlns=\"http://www.pnml.org/version-2009/grammar/pnml\">\n\
         <net id=\"n\" type=\"http://www.pnml.org/version-2009/grammar/ptnet\"><page id=\"pg\">\n\
         {place}\n</page></net></pnml>\n",
        "x".repeat(100_000)
    )
}

#[test]
fn a_pnml_entity_that_expands_to_gigabytes_is_refused_naming_the_limit() {
    let dir = tempfile::tempdir().expect("temp dir");
    let limit = MAX_ENTITY_EXPANSION.to_string();
    for (name, in_text) in [("text.pnml", true), ("attribute.pnml", false)] {
        let file = dir.path().join(name);
        std::fs::write(&file, entity_bomb(in_text)).expect("write");
        let out_file = dir.path().join("out.pnml");
        for args in [
            vec!["check", path(&file)],
            vec![
                "convert",
                path(&file),
                "--to",
                "pnml",
                "-o",
                path(&out_file),
            ],
        ] {
            let what = format!("{} on {name}", args[0]);
            let err = refused(&what, &cetratus(&args), &[name, "entit", &limit]);
            assert!(
                err.len() < 2000,
                "{what}: the message quotes the input: {}",
                tail(&err)
            );
        }
    }
}

/// A PNML root whose `attributes` (a million of them) precede one net of one place.
fn pnml_with_root_attributes(attributes: &str, children: &str) -> String {
    format!(
        "<pnml xmlns=\"http://www.pnml.org/version-2009/grammar/pnml\"{attributes}>{children}\n\
         <net id=\"n\" type=\"http://www.pnml.org/version-2009/grammar/ptnet\"><page id=\"pg\">\
         <place id=\"p\"/></page></net></pnml>\n"
    )
}

#[test]
fn pnml_files_with_a_million_attributes_or_prefixes_are_read_in_linear_time() {
    let dir = tempfile::tempdir().expect("temp dir");
    const N: usize = 1_000_000;
    let attributes: String = (0..N).map(|i| format!(" a{i}=\"v\"")).collect();
    let prefixes: String = (0..N).map(|i| format!(" xmlns:p{i}=\"u\"")).collect();
    let children = "<x/>".repeat(N);
    let cases = [
        (
            "attributes.pnml",
            pnml_with_root_attributes(&attributes, ""),
        ),
        (
            "prefixes.pnml",
            pnml_with_root_attributes(&prefixes, &children),
        ),
        (
            "duplicate.pnml",
            pnml_with_root_attributes(&format!("{attributes} a7=\"again\""), ""),
        ),
    ];
    for (name, text) in cases {
        let file = dir.path().join(name);
        std::fs::write(&file, text).expect("write");
        let out = output_within(
            Command::new(BIN).args(["check", path(&file)]),
            Duration::from_secs(120),
        );
        if name == "duplicate.pnml" {
            refused(name, &out, &[name, "`a7` appears twice"]);
        } else {
            let stdout = String::from_utf8_lossy(&out.stdout);
            assert!(
                out.status.success(),
                "{name}: {:?}\n{}",
                out.status,
                tail(&String::from_utf8_lossy(&out.stderr))
            );
            assert!(stdout.contains("1 place"), "{name}: {stdout}");
        }
    }
}

/// `text` with its first `é` written as the single Latin-1 byte 0xE9, and that byte's offset.
fn latin1(text: &str) -> (Vec<u8>, usize) {
    let at = text.find('é').expect("an é to encode");
    let mut bytes = text.as_bytes()[..at].to_vec();
    bytes.push(0xE9);
    bytes.extend_from_slice(&text.as_bytes()[at + 'é'.len_utf8()..]);
    (bytes, at)
}

#[test]
fn toml_files_that_are_not_utf8_are_refused_naming_the_file_and_the_byte() {
    let dir = tempfile::tempdir().expect("temp dir");
    for f in ["vernadat.pnml", "u1.pnml", "u1.toml"] {
        std::fs::copy(example(&format!("vernadat/{f}")), dir.path().join(f)).expect("copy");
    }
    // The program: `check`, `sim` and `run` read it.
    let toml = std::fs::read_to_string(example("vernadat/vernadat.toml")).expect("read");
    let line = "description = \"Two machines sharing a 7-slot buffer, served by one robot\"";
    assert!(toml.contains(line), "the example's description moved");
    let (bytes, at) = latin1(&toml.replace(line, "description = \"Café cell\""));
    let program = dir.path().join("vernadat.toml");
    std::fs::write(&program, bytes).expect("write");
    let offset = format!("byte offset {at}");
    let needles = ["vernadat.toml:", "not UTF-8", offset.as_str()];
    for args in [
        vec!["check", path(&program)],
        vec!["sim", path(&program)],
        vec![
            "run",
            path(&program),
            "--twin",
            "vernadat",
            "--virtual",
            "--for",
            "1s",
        ],
    ] {
        refused(&args.join(" "), &cetratus(&args), &needles);
    }

    // A package manifest.
    let manifest = std::fs::read_to_string(example("vernadat/u1.package.toml")).expect("read");
    let (bytes, at) = latin1(&manifest.replacen("Cetratus examples", "Cetratus café", 1));
    let manifest = dir.path().join("u1.package.toml");
    std::fs::write(&manifest, bytes).expect("write");
    let out = cetratus(&[
        "package",
        "build",
        path(&manifest),
        "--unsigned",
        "-o",
        path(&dir.path().join("u1.cpkg")),
    ]);
    refused(
        "package build",
        &out,
        &[
            "u1.package.toml:",
            "not UTF-8",
            &format!("byte offset {at}"),
        ],
    );

    // The local configuration.
    let config = dir.path().join("config");
    std::fs::create_dir_all(&config).expect("mkdir");
    let (bytes, at) = latin1("# Café\n");
    std::fs::write(config.join("config.toml"), bytes).expect("write");
    let out = cetratus(&[
        "run",
        path(&example("vernadat/vernadat.toml")),
        "--twin",
        "vernadat",
        "--virtual",
        "--for",
        "1s",
        "--config",
        path(&config),
    ]);
    refused(
        "run --config",
        &out,
        &["config.toml:", "not UTF-8", &format!("byte offset {at}")],
    );
}
