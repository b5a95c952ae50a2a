//! The front listener of the OPC UA server: it holds the public port, closes connections beyond
//! the limit, or beyond their address's rate, at once, and relays the others to the server's own
//! listener on a loopback port.
//! async-opcua limits sessions but not connections; a client that opens sockets without ever
//! creating a session would otherwise hold them until its hello timeout, and one that sends a
//! HEL and then nothing, for ever: a connection whose client sends no byte for
//! [`IDLE_TIMEOUT`] is closed.

use std::net::SocketAddr;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

use tokio::net::{TcpListener, TcpStream};

use super::Shared;
use cetratus_slots::Idle;

/// A connection whose client sends no byte for this long is closed. An OPC UA client with a
/// session publishes, reads or renews far more often; one that only said hello does not.
pub const IDLE_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(60);

/// Relays every accepted connection, up to `max` at once, to `inner`; runs until dropped.
pub(crate) async fn relay(public: TcpListener, inner: SocketAddr, max: usize, shared: Arc<Shared>) {
    let open = Arc::new(AtomicUsize::new(0));
    let mut rates = super::limit::PerAddress::new();
    loop {
        let Ok((client, from)) = public.accept().await else {
            // Out of descriptors, say: wait a little rather than spin.
            tokio::time::sleep(std::time::Duration::from_millis(10)).await;
            continue;
        };
        if open.load(Ordering::SeqCst) >= max || !rates.admit(from.ip(), std::time::Instant::now())
        {
            shared
                .counters
                .refused_connections
                .fetch_add(1, Ordering::Relaxed);
            drop(client);
            continue;
        }
        open.fetch_add(1, Ordering::SeqCst);
        let open = open.clone();
        tokio::spawn(async move {
            if let Ok(mut server) = TcpStream::connect(inner).await {
                let _ = client.set_nodelay(true);
                let _ = server.set_nodelay(true);
                let mut client = Idle::new(client, IDLE_TIMEOUT);
                let _ = tokio::io::copy_bidirectional(&mut client, &mut server).await;
            }
            open.fetch_sub(1, Ordering::SeqCst);
        });
    }
}
