//! Loopback ports for the servers a test starts: one nobody listens on, and waiting until one
//! is listened on.

use std::net::{SocketAddr, TcpListener, TcpStream};
use std::time::{Duration, Instant};

/// A loopback port nobody listens on right now.
///
/// The port is free when this returns, not reserved: the server the test starts next takes it.
pub fn free_port() -> u16 {
    free_addr().port()
}

/// A loopback address, on a port nobody listens on right now.
pub fn free_addr() -> SocketAddr {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free port on 127.0.0.1")
}

/// Whether something accepts connections on 127.0.0.1:`port` before `within` has passed.
fn port_opens(port: u16, within: Duration) -> bool {
    let end = Instant::now() + within;
    loop {
        if TcpStream::connect(("127.0.0.1", port)).is_ok() {
            return true;
        }
        if Instant::now() >= end {
            return false;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Waits until `what` accepts connections on 127.0.0.1:`port`.
///
/// # Panics
///
/// When nothing listens there after `within`.
pub fn wait_for_port(port: u16, what: &str, within: Duration) {
    assert!(
        port_opens(port, within),
        "{what} did not listen on 127.0.0.1:{port} within {within:?}"
    );
}
