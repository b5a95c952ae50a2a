//! TLS for the page (rustls): an [`axum::serve::Listener`] that accepts TCP connections and hands
//! axum only those whose handshake finished. Handshakes run in tasks of their own, each in a slot
//! of [`HANDSHAKES`] ([`cetratus_slots`]): one address holds at most half of them, and the last
//! quarter is kept for addresses that completed a handshake before; a connection that gets no
//! slot is closed at once. A client must send its first byte within [`HELLO_TIMEOUT`] and finish
//! within [`HANDSHAKE_TIMEOUT`], so a host that opens connections and says nothing holds up
//! neither other clients nor the accept loop (docs/security.md).

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use cetratus_slots::Slots;
use rustls::pki_types::pem::PemObject as _;
use rustls::pki_types::{CertificateDer, PrivateKeyDer};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::mpsc;
use tokio_rustls::server::TlsStream;
use tokio_rustls::TlsAcceptor;

/// Handshakes under way at once; past it, or past an address's share, a new connection is
/// closed at once.
pub const HANDSHAKES: usize = 64;

/// How long a client may take to send the first byte of its handshake (the ClientHello, which
/// a browser sends at once).
pub const HELLO_TIMEOUT: Duration = Duration::from_secs(2);

/// How long a client may take to finish its TLS handshake.
pub const HANDSHAKE_TIMEOUT: Duration = Duration::from_secs(10);

/// The certificate chain and private key (PEM files) the dashboard serves the page with.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DashboardTls {
    /// The certificate chain, PEM.
    pub cert: PathBuf,
    /// The private key, PEM.
    pub key: PathBuf,
}

impl DashboardTls {
    /// Reads the files into a rustls acceptor; `Err` says which file and what is wrong.
    pub(crate) fn acceptor(&self) -> Result<TlsAcceptor, String> {
        let at = |p: &Path, e: &dyn std::fmt::Display| format!("{}: {e}", p.display());
        let certs = CertificateDer::pem_file_iter(&self.cert)
            .and_then(|i| i.collect::<Result<Vec<_>, _>>())
            .map_err(|e| at(&self.cert, &e))?;
        if certs.is_empty() {
            return Err(at(&self.cert, &"no certificate in the file"));
        }
        let key = PrivateKeyDer::from_pem_file(&self.key).map_err(|e| at(&self.key, &e))?;
        let provider = Arc::new(rustls::crypto::ring::default_provider());
        let config = rustls::ServerConfig::builder_with_provider(provider)
            .with_safe_default_protocol_versions()
            .map_err(|e| e.to_string())?
            .with_no_client_auth()
            .with_single_cert(certs, key)
            .map_err(|e| format!("the certificate and the key do not go together: {e}"))?;
        Ok(TlsAcceptor::from(Arc::new(config)))
    }
}

/// Connections whose TLS handshake finished, for axum.
pub(crate) struct TlsListener {
    ready: mpsc::Receiver<(TlsStream<TcpStream>, SocketAddr)>,
    addr: SocketAddr,
}

impl TlsListener {
    /// Accepts on `tcp` and shakes hands with `acceptor`, from a task of its own.
    pub(crate) fn start(tcp: TcpListener, acceptor: TlsAcceptor) -> std::io::Result<Self> {
        let addr = tcp.local_addr()?;
        let (tx, ready) = mpsc::channel(HANDSHAKES);
        let slots = Slots::shared(HANDSHAKES);
        tokio::spawn(async move {
            loop {
                let (stream, from) = match tcp.accept().await {
                    Ok(s) => s,
                    Err(e) => {
                        tracing::debug!(error = %e, "the dashboard could not accept a connection");
                        tokio::time::sleep(Duration::from_millis(50)).await;
                        continue;
                    }
                };
                if tx.is_closed() {
                    return;
                }
                let slot = match Slots::take(&slots, from.ip()) {
                    Ok(slot) => slot,
                    Err(why) => {
                        tracing::debug!(%from, ?why, "a TLS handshake with the dashboard got no slot");
                        continue;
                    }
                };
                let (acceptor, tx) = (acceptor.clone(), tx.clone());
                tokio::spawn(async move {
                    if let Some(tls) = handshake(&acceptor, stream, from).await {
                        slot.served();
                        drop(slot);
                        let _ = tx.send((tls, from)).await;
                    }
                });
            }
        });
        Ok(TlsListener { ready, addr })
    }
}

/// The handshake with the client at `from`: its first byte within [`HELLO_TIMEOUT`], all of it
/// within [`HANDSHAKE_TIMEOUT`]; `None` when it failed or was too slow.
async fn handshake(
    acceptor: &TlsAcceptor,
    stream: TcpStream,
    from: SocketAddr,
) -> Option<TlsStream<TcpStream>> {
    let mut first = [0u8; 1];
    match tokio::time::timeout(HELLO_TIMEOUT, stream.peek(&mut first)).await {
        Ok(Ok(n)) if n > 0 => {}
        Ok(_) => return None,
        Err(_) => {
            tracing::debug!(%from, "a client of the dashboard sent no handshake");
            return None;
        }
    }
    match tokio::time::timeout(HANDSHAKE_TIMEOUT, acceptor.accept(stream)).await {
        Ok(Ok(tls)) => Some(tls),
        Ok(Err(e)) => {
            tracing::debug!(%from, error = %e, "a TLS handshake with the dashboard failed");
            None
        }
        Err(_) => {
            tracing::debug!(%from, "a TLS handshake with the dashboard timed out");
            None
        }
    }
}

impl axum::serve::Listener for TlsListener {
    type Io = TlsStream<TcpStream>;
    type Addr = SocketAddr;

    async fn accept(&mut self) -> (Self::Io, Self::Addr) {
        match self.ready.recv().await {
            Some(c) => c,
            // The accepting task ended (the runtime is stopping): never resolve.
            None => std::future::pending().await,
        }
    }

    fn local_addr(&self) -> std::io::Result<Self::Addr> {
        Ok(self.addr)
    }
}
