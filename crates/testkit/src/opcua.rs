//! The asyncua peer of the OPC UA tests (`scripts/opcua_peer.py`, FreeOpcUa's Python stack): a
//! client that browses, reads, writes, subscribes, logs in and floods a PLC's OPC UA server.

use std::process::{Command, Stdio};

use crate::paths::workspace_root;

/// The peer, ready for its arguments (to spawn it, or to read its output yourself).
pub fn command() -> Command {
    let mut c = Command::new("python3");
    c.arg(workspace_root().join("scripts/opcua_peer.py"));
    c
}

/// Runs the peer with `args` and returns the lines it printed; fails the test when it fails.
pub fn run(args: &[&str]) -> Vec<String> {
    let out = command()
        .args(args)
        .output()
        .expect("run the asyncua client");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{args:?}: {text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    text.lines().map(str::to_string).collect()
}

/// The argon2 hash of `password` that `cetratus hash-password` (the binary `bin`) prints, for a
/// configuration's `password_hash`.
pub fn hash_password(bin: &str, password: &str) -> String {
    let mut h = Command::new(bin)
        .arg("hash-password")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .expect("run cetratus hash-password");
    std::io::Write::write_all(
        h.stdin.as_mut().expect("its stdin"),
        format!("{password}\n").as_bytes(),
    )
    .expect("write the password");
    let out = h.wait_with_output().expect("its hash");
    String::from_utf8_lossy(&out.stdout).trim().to_string()
}
