//! An error a client causes is logged as one line, without a backtrace, even when the operator
//! runs the PLC with `RUST_BACKTRACE=1` (for panics): a symbolized backtrace a connection took
//! the PLC's resident memory from 90 to 376 MiB, where it stayed.
//!
//! Against the real binary: twenty clients send the embedded broker a CONNECT and then a packet
//! of a reserved type, with the broker's sessions logged at `debug`, where rmqtt writes the
//! error of each (`pkt: Err(Unsupported packet type`). Before the fix each came with a
//! `Stack backtrace:` that took the PLC a second to symbolize.

use std::io::Write;
use std::time::{Duration, Instant};

use cetratus_testkit::raw_mqtt::connect;

mod common;

use common::RunningPlc;

#[test]
fn a_client_that_sends_garbage_gets_a_log_line_and_no_backtrace() {
    // The child inherits these; this file holds one test, so nothing else sees them.
    std::env::set_var("RUST_BACKTRACE", "1");
    std::env::set_var("RUST_LOG", "warn,rmqtt::session=debug");
    let (plc, log) = RunningPlc::start_logged("errors1", &[]);
    for k in 0..20 {
        let mut s = connect(("127.0.0.1", plc.mqtt), &format!("garbage{k}"));
        // Packet type 0 is reserved: the broker must drop the connection.
        let _ = s.write_all(&[0x00, 0x02, 0xde, 0xad]);
        let _ = s.flush();
    }
    let (mut lines, end) = (Vec::new(), Instant::now() + Duration::from_secs(5));
    while let Some(left) = end.checked_duration_since(Instant::now()) {
        match log.recv_timeout(left) {
            Ok(l) => lines.push(l),
            Err(_) => break,
        }
    }
    let errors = lines
        .iter()
        .filter(|l| l.contains("Unsupported packet type"))
        .count();
    assert!(
        errors >= 1,
        "the broker logged no error for the garbage:\n{}",
        lines.join("\n")
    );
    let traced: Vec<&String> = lines
        .iter()
        .filter(|l| l.to_lowercase().contains("backtrace"))
        .collect();
    assert!(
        traced.is_empty(),
        "{} backtrace lines in the log, e.g. {:?}",
        traced.len(),
        traced.first()
    );
}
