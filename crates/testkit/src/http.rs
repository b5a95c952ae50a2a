//! A plain HTTP/1.0 client over a TCP socket, for tests that talk to the dashboard the way a
//! script or an attacker would, and the dashboard's one-time login links.

use std::io::{Read, Write};
use std::net::SocketAddr;

/// A response: status, head (status line and headers) and body.
#[derive(Debug)]
pub struct Response {
    /// The status code; 0 when the response could not be read.
    pub status: u16,
    /// The status line and the headers.
    pub head: String,
    /// The body.
    pub body: String,
}

impl Response {
    /// The body as JSON, or `null`.
    pub fn json(&self) -> serde_json::Value {
        serde_json::from_str(&self.body).unwrap_or(serde_json::Value::Null)
    }

    /// The value of the first header named `name` (any case).
    pub fn header(&self, name: &str) -> Option<&str> {
        self.head.lines().find_map(|l| {
            let (k, v) = l.split_once(':')?;
            k.trim().eq_ignore_ascii_case(name).then(|| v.trim())
        })
    }
}

/// Sends one request; `headers` are written as they are (`Host` included: give it).
pub fn request(
    addr: SocketAddr,
    method: &str,
    path: &str,
    headers: &[&str],
    body: &[u8],
) -> Response {
    let s = std::net::TcpStream::connect(addr).expect("the dashboard accepts a connection");
    exchange(s, method, path, headers, body)
}

/// Sends one request on the connection `s` and reads the response: [`request`] on a
/// connection made otherwise, such as from another local address
/// ([`crate::ports::connect_from`]).
pub fn exchange(
    mut s: std::net::TcpStream,
    method: &str,
    path: &str,
    headers: &[&str],
    body: &[u8],
) -> Response {
    let mut head = format!(
        "{method} {path} HTTP/1.0\r\nContent-Length: {}\r\n",
        body.len()
    );
    for h in headers {
        head.push_str(h);
        head.push_str("\r\n");
    }
    head.push_str("\r\n");
    s.write_all(head.as_bytes()).expect("the request is sent");
    s.write_all(body).expect("the body is sent");
    let mut raw = Vec::new();
    let _ = s.read_to_end(&mut raw);
    let text = String::from_utf8_lossy(&raw).into_owned();
    let (head, body) = text.split_once("\r\n\r\n").unwrap_or((&text, ""));
    Response {
        status: head
            .split_whitespace()
            .nth(1)
            .and_then(|c| c.parse().ok())
            .unwrap_or(0),
        head: head.to_string(),
        body: body.to_string(),
    }
}

/// Opens a one-time login link (`http://ADDR/login?token=…`, as the dashboard prints it) and
/// returns the session's `Cookie` header line.
pub fn login(link: &str) -> String {
    let rest = link
        .strip_prefix("http://")
        .unwrap_or_else(|| panic!("a login link starts with http://: {link}"));
    let (authority, path) = rest.split_once('/').expect("a path in the login link");
    let addr: SocketAddr = authority.parse().expect("an address in the login link");
    let r = request(
        addr,
        "GET",
        &format!("/{path}"),
        &[&format!("Host: {authority}")],
        b"",
    );
    assert_eq!(r.status, 303, "the login link logs in: {}", r.head);
    let cookie = r
        .header("set-cookie")
        .and_then(|c| c.split(';').next())
        .expect("a session cookie");
    format!("Cookie: {cookie}")
}

/// The one-time login link in a line that `cetratus run`, `demo` or `mct` printed, if any.
pub fn login_link_in(line: &str) -> Option<String> {
    let start = line.find("http://")?;
    let link = line[start..].split_whitespace().next()?;
    link.contains("/login?token=").then(|| link.to_string())
}
