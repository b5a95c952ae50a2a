//! Loopback ports for the servers a test starts: one nobody listens on, and waiting until one
//! is listened on.

use std::collections::BTreeSet;
use std::net::{IpAddr, SocketAddr, TcpListener, TcpStream};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// A loopback port nobody listens on right now.
///
/// The port is free when this returns, not reserved: the server the test starts next takes it.
pub fn free_port() -> u16 {
    free_addr().port()
}

/// A loopback address, on a port nobody listens on right now, and never handed out before in
/// this process.
///
/// The tests of one binary run side by side, and some stop a server and start it again on its
/// port (a device that goes away and comes back). Without the second condition another test
/// could be given that port in between, or the same port before either server took it, and
/// then talk to the other test's server.
pub fn free_addr() -> SocketAddr {
    static GIVEN: Mutex<BTreeSet<u16>> = Mutex::new(BTreeSet::new());
    let mut given = GIVEN.lock().unwrap_or_else(|e| e.into_inner());
    loop {
        let addr = TcpListener::bind("127.0.0.1:0")
            .and_then(|l| l.local_addr())
            .expect("a free port on 127.0.0.1");
        if given.insert(addr.port()) {
            return addr;
        }
    }
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

/// A connection to `addr` from the local address `source`: another address of the loopback
/// network (127.0.0.2 and up) stands for another host.
///
/// # Panics
///
/// When the source cannot be bound or nothing accepts the connection.
pub fn connect_from(source: IpAddr, addr: SocketAddr) -> TcpStream {
    use socket2::{Domain, Socket, Type};
    let s = Socket::new(Domain::for_address(addr), Type::STREAM, None).expect("a socket");
    s.bind(&SocketAddr::new(source, 0).into())
        .expect("bind the source address");
    s.connect(&addr.into())
        .unwrap_or_else(|e| panic!("{addr} accepts a connection from {source}: {e}"));
    s.into()
}
