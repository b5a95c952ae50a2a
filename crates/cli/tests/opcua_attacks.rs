//! Attacks on the PLC's OPC UA server with a real client (asyncua, FreeOpcUa's Python stack)
//! against the real `cetratus run`: a flood of wrong-password logins is limited before the
//! password check and the right password still logs in afterwards; a flood of malformed writes
//! and of connections leaves the PLC scanning and answering; connections that say hello and
//! nothing more, from other hosts, keep neither every slot nor a known client out
//! (docs/security.md, *OPC UA*).

use std::io::{Read, Write};
use std::net::{IpAddr, Ipv4Addr, SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use cetratus_testkit::opcua::{hash_password, run as peer};
use cetratus_testkit::paths::workspace_root;
use cetratus_testkit::ports::{connect_from, free_port, wait_for_port};
use cetratus_testkit::process::{run_vernadat, stop_with_sigterm as stop, ChildGuard};

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

fn start(dir: &Path, io_body: &str, port: u16, extra: &[&str]) -> ChildGuard {
    let io = dir.join("io.toml");
    std::fs::write(&io, io_body).unwrap();
    let plc = ChildGuard::spawn(
        run_vernadat(BIN, &io, dir)
            .arg("--no-mqtt")
            .args(extra)
            .stdout(Stdio::piped())
            .stderr(std::fs::File::create(dir.join("plc.err")).unwrap()),
    );
    wait_for_port(port, "the PLC's OPC UA server", Duration::from_secs(60));
    plc
}

/// Makes a client certificate in `d` and has the server at `url` (pki at `d/pki`) trust it, as
/// an administrator does: a first connection puts it in `rejected/`, moved to `trusted/`.
fn trusted_client(d: &Path, url: &str) -> (PathBuf, PathBuf) {
    assert_eq!(peer(&["keys", &d.display().to_string()]), ["ok"]);
    let (cert, key) = (d.join("client.der"), d.join("client.pem"));
    let first = peer(&[
        "secure",
        url,
        "Basic256Sha256",
        &cert.display().to_string(),
        &key.display().to_string(),
    ])
    .join(" ");
    assert!(first.starts_with("refused"), "{first}");
    let end = Instant::now() + Duration::from_secs(10);
    loop {
        let found: Vec<_> = std::fs::read_dir(d.join("pki/rejected"))
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        if let Some(f) = found.first() {
            std::fs::rename(f, d.join("pki/trusted").join(f.file_name().unwrap())).unwrap();
            break;
        }
        assert!(Instant::now() < end, "no rejected certificate");
        std::thread::sleep(Duration::from_millis(50));
    }
    (cert, key)
}

fn cycles(url: &str) -> u64 {
    let r = peer(&["read", url, "cell.ExecInfo.Cycles"]);
    r[0].strip_prefix("cell.ExecInfo.Cycles=")
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("{r:?}"))
}

#[test]
fn a_flood_of_wrong_passwords_is_limited_before_the_check_and_the_right_one_still_logs_in() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let port = free_port();
    let url = format!("opc.tcp://127.0.0.1:{port}");
    let h = hash_password(BIN, "panel-secret");
    let plc = start(
        d,
        &format!("[opcua]\nlisten = \"{url}\"\nsecurity = \"sign-and-encrypt\"\npki = \"pki\"\npolicies = [\"Basic256Sha256\"]\nmax_connections = 16\n\n[[opcua.user]]\nname = \"hmi\"\npassword_hash = \"{h}\"\n"),
        port,
        &["--twin", "vernadat"],
    );
    let (cert, key) = trusted_client(d, &url);
    let (cert, key) = (cert.display().to_string(), key.display().to_string());
    let before = cycles_secure(&url, &cert, &key);
    // 48 guesses, 8 at a time.
    let got = peer(&[
        "guess",
        &url,
        "Basic256Sha256",
        &cert,
        &key,
        "hmi",
        "guess",
        "48",
    ])
    .join(" ");
    let count = |name: &str| -> u64 {
        got.split(' ')
            .find_map(|kv| kv.strip_prefix(&format!("{name}=")))
            .map_or(0, |v| v.parse().unwrap())
    };
    assert_eq!(count("ok"), 0, "{got}");
    // Refused whether checked or not (the counters below tell them apart).
    assert!(count("BadUserAccessDenied") > 0, "{got}");
    // The limit refills: the right password logs in, and the PLC kept scanning all along.
    std::thread::sleep(Duration::from_secs(3));
    let ok = peer(&[
        "secure",
        &url,
        "Basic256Sha256",
        &cert,
        &key,
        "--user",
        "hmi",
        "--password",
        "panel-secret",
    ]);
    assert_eq!(ok, ["idle"]);
    let after = cycles_secure(&url, &cert, &key);
    assert!(after > before, "cycles {before} then {after}");
    let s = stop(plc);
    let o = &s["opcua_server"];
    assert!(o["refused_logins"].as_u64().unwrap() > 0, "{s}");
    assert!(o["failed_logins"].as_u64().unwrap() > 0, "{s}");
    assert!(o["logins"].as_u64().unwrap() >= 3, "{s}");
    // Logged on the 1st, 2nd, 4th… refusal only, with the running count.
    let log = std::fs::read_to_string(d.join("plc.err")).unwrap();
    let lines = log
        .lines()
        .filter(|l| l.contains("OPC UA login refused: too many attempts"))
        .count() as u64;
    let refused = o["refused_logins"].as_u64().unwrap();
    assert!(
        lines >= 1 && lines <= 1 + refused.ilog2() as u64,
        "{lines} lines for {refused}: {log}"
    );
    assert!(log.contains("refused=1"), "{log}");
}

/// The cycle counter, read over an encrypted session as `hmi`.
fn cycles_secure(url: &str, cert: &str, key: &str) -> u64 {
    // The rate limit may refuse a login right after a flood: try again for a while.
    let end = Instant::now() + Duration::from_secs(30);
    loop {
        let r = peer(&[
            "secure",
            url,
            "Basic256Sha256",
            cert,
            key,
            "--user",
            "hmi",
            "--password",
            "panel-secret",
            "--read",
            "cell.ExecInfo.Cycles",
        ]);
        if let Some(n) = r.first().and_then(|v| v.parse().ok()) {
            return n;
        }
        assert!(Instant::now() < end, "{r:?}");
        std::thread::sleep(Duration::from_millis(500));
    }
}

#[test]
fn floods_of_malformed_writes_and_of_connections_leave_the_plc_scanning_and_answering() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let url = format!("opc.tcp://127.0.0.1:{port}");
    let mut plc = start(
        dir.path(),
        &format!("start_timeout = \"1s\"\n\n[opcua]\nlisten = \"{url}\"\ninputs = true\nmax_connections = 8\n"),
        port,
        &[],
    );
    let before = cycles(&url);
    let got = peer(&["junk", &url, "600"]);
    // Every malformed write has its Bad status; none was taken.
    assert_eq!(got.last().map(String::as_str), Some("idle"), "{got:?}");
    let total: u64 = got[..got.len() - 1]
        .iter()
        .map(|l| {
            assert!(l.starts_with("Bad"), "{got:?}");
            l.split('=').nth(1).unwrap().parse::<u64>().unwrap()
        })
        .sum();
    assert_eq!(total, 600, "{got:?}");
    assert!(
        got.iter().any(|l| l.starts_with("BadTypeMismatch=")),
        "{got:?}"
    );
    assert!(
        got.iter().any(|l| l.starts_with("BadNodeIdUnknown=")),
        "{got:?}"
    );
    // Connections beyond the limit, or beyond one address's rate, are closed at once.
    let closed: u64 = peer(&["flood", &url, "60"])[0].parse().unwrap();
    assert!(closed >= 50, "{closed} of 60 closed");
    assert!(plc.0.try_wait().unwrap().is_none(), "the PLC is running");
    // The rate of one address refills: the PLC answers, and it kept scanning.
    let end = Instant::now() + Duration::from_secs(30);
    let after = loop {
        let r = Command::new("python3")
            .arg(workspace_root().join("scripts/opcua_peer.py"))
            .args(["read", &url, "cell.ExecInfo.Cycles"])
            .output()
            .unwrap();
        let t = String::from_utf8_lossy(&r.stdout).to_string();
        if let Some(n) = t
            .trim()
            .strip_prefix("cell.ExecInfo.Cycles=")
            .and_then(|v| v.parse::<u64>().ok())
        {
            break n;
        }
        assert!(Instant::now() < end, "{t}");
        std::thread::sleep(Duration::from_millis(500));
    };
    assert!(after > before, "cycles {before} then {after}");
    let s = stop(plc);
    let o = &s["opcua_server"];
    assert_eq!(o["writes"], 0, "{s}");
    assert!(o["refused_writes"].as_u64().unwrap() >= 300, "{s}");
    assert!(o["refused_connections"].as_u64().unwrap() >= 50, "{s}");
}

/// Says hello (OPC UA's HEL) to the server at `addr` from the local address `source`, as a
/// client that then says nothing more: the connection while it holds a slot (the server
/// acknowledged), `None` when the front listener closed it at once.
fn hello_from(source: Ipv4Addr, addr: SocketAddr, url: &str) -> Option<TcpStream> {
    let mut s = connect_from(IpAddr::V4(source), addr);
    // Protocol version, receive and send buffer sizes, no message size or chunk count limit.
    let mut body: Vec<u8> = [0u32, 65_536, 65_536, 0, 0]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    body.extend((url.len() as i32).to_le_bytes());
    body.extend(url.bytes());
    let mut message = b"HELF".to_vec();
    message.extend(((8 + body.len()) as u32).to_le_bytes());
    message.extend(body);
    s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    // A refused connection may be gone before the hello is written: its answer tells.
    let _ = s.write_all(&message);
    let mut head = [0u8; 8];
    match s.read_exact(&mut head) {
        Ok(()) if &head[..3] == b"ACK" => Some(s),
        _ => None,
    }
}

#[test]
fn hellos_from_other_hosts_hold_half_the_connections_at_most_and_a_known_client_still_reads() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let url = format!("opc.tcp://127.0.0.1:{port}");
    let addr = SocketAddr::from(([127, 0, 0, 1], port));
    // Eight connections: one address holds four at most, and the last two are kept.
    let plc = start(
        dir.path(),
        &format!("start_timeout = \"1s\"\n\n[opcua]\nlisten = \"{url}\"\ninputs = true\nmax_connections = 8\n"),
        port,
        &[],
    );
    // The HMI reads once: its address opened a secure channel, and is known from then on.
    let before = cycles(&url);
    std::thread::sleep(Duration::from_secs(1));
    let held = |source: Ipv4Addr, n: usize| -> Vec<TcpStream> {
        (0..n)
            .filter_map(|_| hello_from(source, addr, &url))
            .collect()
    };
    let first = held(Ipv4Addr::new(127, 0, 0, 2), 8);
    assert_eq!(first.len(), 4, "one address holds half the connections");
    let second = held(Ipv4Addr::new(127, 0, 0, 3), 8);
    assert_eq!(second.len(), 2, "a new address does not get the reserve");
    assert!(
        hello_from(Ipv4Addr::new(127, 0, 0, 4), addr, &url).is_none(),
        "only the reserve is left, for addresses known before"
    );
    // Six silent connections are held, and the HMI still reads, through the reserve.
    let after = cycles(&url);
    assert!(after > before, "cycles {before} then {after}");
    drop((first, second));
    let s = stop(plc);
    let refused = s["opcua_server"]["refused_connections"].as_u64().unwrap();
    // Four from the first address, six from the second, one from the third.
    assert!(refused >= 11, "{refused} refused: {s}");
}
