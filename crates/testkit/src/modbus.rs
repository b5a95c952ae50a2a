//! The pymodbus peer of the field I/O tests (`scripts/modbus_peer.py`): a remote I/O device, and a
//! client that reads what a Modbus server holds.

use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::Duration;

use crate::paths::workspace_root;
use crate::ports::wait_for_port;
use crate::process::ChildGuard;

/// The peer's script.
pub fn peer() -> PathBuf {
    workspace_root().join("scripts/modbus_peer.py")
}

/// A pymodbus remote I/O device on `port`, set up by `args` (e.g. `["--di", "1"]`), once it
/// listens.
pub fn device(port: u16, args: &[&str]) -> ChildGuard {
    let d = ChildGuard::spawn(
        Command::new("python3")
            .arg(peer())
            .args(["device", &port.to_string()])
            .args(args)
            .stdout(Stdio::null())
            .stderr(Stdio::null()),
    );
    wait_for_port(port, "the pymodbus device", Duration::from_secs(30));
    d
}

/// What the peer prints for `args` (a client command), trimmed; empty when it cannot say.
pub fn client(args: &[&str]) -> String {
    let out = Command::new("python3")
        .arg(peer())
        .args(args)
        .output()
        .expect("run the pymodbus client");
    String::from_utf8_lossy(&out.stdout).trim().to_string()
}

/// What a pymodbus client reads from `table` (`coils`, `di`, `ir`, `hr`) of the server on
/// `port`: the values joined by commas, or empty when it cannot read them.
pub fn read(port: u16, table: &str, address: u16, count: u16) -> String {
    client(&[
        "read",
        &port.to_string(),
        table,
        &address.to_string(),
        &count.to_string(),
    ])
}
