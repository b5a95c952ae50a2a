//! The dashboard over TLS, against the real server: beyond loopback it does not start without
//! TLS; with TLS it speaks nothing else, and its session cookie is `Secure`; connections that
//! never send a ClientHello neither lock out a browser that came before nor hold their slots.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::Arc;

use cetratus_dashboard::{serve, AccessConfig, DashboardConfig, DashboardError, DashboardTls};

fn config(http: SocketAddr, tls: Option<DashboardTls>) -> DashboardConfig {
    DashboardConfig {
        http,
        // Nothing listens there; the page is served all the same.
        broker_url: "mqtt://127.0.0.1:9".into(),
        user: None,
        password: None,
        signer: None,
        access: AccessConfig::default(),
        tls,
        rollouts: None,
    }
}

/// Sends `request` over TLS to `addr`, trusting only `cert_pem`, and returns the response.
fn over_tls(addr: SocketAddr, cert_pem: &str, request: &str) -> String {
    use rustls::pki_types::pem::PemObject as _;
    let mut roots = rustls::RootCertStore::empty();
    for c in rustls::pki_types::CertificateDer::pem_slice_iter(cert_pem.as_bytes()) {
        roots.add(c.expect("a certificate")).expect("a root");
    }
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let client = rustls::ClientConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .expect("versions")
        .with_root_certificates(roots)
        .with_no_client_auth();
    let name = "localhost".try_into().expect("a server name");
    let conn = rustls::ClientConnection::new(Arc::new(client), name).expect("a connection");
    let mut tls = rustls::StreamOwned::new(conn, TcpStream::connect(addr).expect("connects"));
    tls.write_all(request.as_bytes()).expect("writes");
    let mut out = String::new();
    let _ = tls.read_to_string(&mut out);
    out
}

#[test]
fn beyond_loopback_the_dashboard_refuses_to_start_without_tls() {
    let err = serve(config("0.0.0.0:0".parse().expect("addr"), None)).expect_err("exposed");
    assert!(matches!(err, DashboardError::Exposed { .. }), "{err:?}");
    let msg = err.to_string();
    assert!(
        msg.contains("0.0.0.0:0") && msg.contains("tls_cert") && msg.contains("[dashboard]"),
        "{msg}"
    );
}

#[test]
fn with_tls_the_page_speaks_only_tls_and_its_session_cookie_is_secure() {
    let dir = tempfile::tempdir().expect("tempdir");
    let cert = rcgen::generate_simple_self_signed(vec!["localhost".into()]).expect("cert");
    let cert_pem = cert.cert.pem();
    std::fs::write(dir.path().join("cert.pem"), &cert_pem).expect("write");
    std::fs::write(dir.path().join("key.pem"), cert.key_pair.serialize_pem()).expect("write");
    let tls = DashboardTls {
        cert: dir.path().join("cert.pem"),
        key: dir.path().join("key.pem"),
    };
    let h = serve(config("127.0.0.1:0".parse().expect("addr"), Some(tls))).expect("starts");
    let addr = h.local_addr();
    let link = h.login_url().expect("a link");
    assert!(
        link.starts_with(&format!("https://{addr}/login?token=")),
        "{link}"
    );

    // Plain HTTP on the port gets no page.
    let mut plain = TcpStream::connect(addr).expect("connects");
    plain
        .write_all(b"GET / HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n")
        .expect("writes");
    let mut got = Vec::new();
    let _ = plain.read_to_end(&mut got);
    assert!(
        !String::from_utf8_lossy(&got).contains("HTTP/1.1 200"),
        "plain HTTP was served"
    );

    // Over TLS the link logs in, with a cookie the browser sends only over TLS.
    let path = &link[link.find("/login").expect("a path")..];
    let r = over_tls(
        addr,
        &cert_pem,
        &format!(
            "GET {path} HTTP/1.1\r\nHost: localhost:{}\r\nConnection: close\r\n\r\n",
            addr.port()
        ),
    );
    assert!(r.starts_with("HTTP/1.1 303"), "{r}");
    let cookie = r
        .lines()
        .find(|l| l.to_ascii_lowercase().starts_with("set-cookie:"))
        .unwrap_or_default()
        .to_string();
    assert!(
        cookie.contains("HttpOnly")
            && cookie.contains("SameSite=Strict")
            && cookie.contains("; Secure"),
        "{cookie}"
    );
    h.stop();
}

/// `n` TCP connections to `addr` from the source address `from`, that send nothing.
fn silent_connections(addr: SocketAddr, from: &str, n: usize) -> Vec<std::net::TcpStream> {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("a runtime");
    rt.block_on(async {
        let mut out = Vec::new();
        for _ in 0..n {
            let s = tokio::net::TcpSocket::new_v4().expect("a socket");
            s.bind(format!("{from}:0").parse().expect("an address"))
                .expect("bind the source");
            let c = s.connect(addr).await.expect("connects");
            out.push(c.into_std().expect("a std stream"));
        }
        out
    })
}

/// The dashboard over TLS on loopback, with a fresh self-signed certificate for `localhost`.
fn tls_dashboard(dir: &std::path::Path) -> (cetratus_dashboard::DashboardHandle, String) {
    let cert = rcgen::generate_simple_self_signed(vec!["localhost".into()]).expect("cert");
    std::fs::write(dir.join("cert.pem"), cert.cert.pem()).expect("write");
    std::fs::write(dir.join("key.pem"), cert.key_pair.serialize_pem()).expect("write");
    let tls = DashboardTls {
        cert: dir.join("cert.pem"),
        key: dir.join("key.pem"),
    };
    let h = serve(config("127.0.0.1:0".parse().expect("addr"), Some(tls))).expect("starts");
    (h, cert.cert.pem())
}

#[test]
fn seventy_silent_connections_neither_lock_out_a_known_browser_nor_keep_their_slots() {
    use cetratus_dashboard::tls::{HANDSHAKES, HELLO_TIMEOUT};
    use std::time::{Duration, Instant};

    let dir = tempfile::tempdir().expect("tempdir");
    let (h, cert_pem) = tls_dashboard(dir.path());
    let addr = h.local_addr();
    let get = "GET /login HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n";
    // A browser on 127.0.0.1 completes a handshake: its address is known from now on.
    assert!(over_tls(addr, &cert_pem, get).starts_with("HTTP/1.1"));

    // Another host opens more connections than there are handshake slots and sends nothing.
    let mut silent = silent_connections(addr, "127.0.0.2", HANDSHAKES + 6);
    let t0 = Instant::now();
    let page = over_tls(addr, &cert_pem, get);
    let waited = t0.elapsed();
    assert!(page.starts_with("HTTP/1.1"), "{page}");
    assert!(
        waited < Duration::from_secs(2),
        "the known browser waited {waited:?} behind the silent connections"
    );

    // Every silent connection is closed: at once past its address's share, at the hello
    // timeout otherwise.
    std::thread::sleep(HELLO_TIMEOUT + Duration::from_secs(1));
    for s in &mut silent {
        s.set_read_timeout(Some(Duration::from_secs(1)))
            .expect("a timeout");
        let mut buf = [0u8; 16];
        let closed = match s.read(&mut buf) {
            Ok(n) => n == 0,
            Err(e) => !matches!(
                e.kind(),
                std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
            ),
        };
        assert!(closed, "a silent connection is still open");
    }
    h.stop();
}
