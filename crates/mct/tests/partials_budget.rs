//! The embedded broker's total of packets begun and not yet received (`PARTIALS_BYTES`): clients
//! that announce large packets and stall fill it, and then a client that sends a large packet is
//! disconnected, while the process's own clients, once logged in, are not counted and still get
//! their large messages through.

mod common;

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::Duration;

use cetratus_mct::{EmbeddedBroker, BROKER_MAX_PACKET, PARTIALS_BYTES};
use cetratus_testkit::raw_mqtt::{connect as raw_client, fixed_header as header, mqtt_str};
use common::*;
use rumqttc::v5::mqttbytes::QoS;

/// Whether the broker closed `s` within `within` (reads until end of stream or an error).
fn closed_within(s: &mut TcpStream, within: Duration) -> bool {
    s.set_read_timeout(Some(within)).expect("a read timeout");
    let mut buf = [0u8; 256];
    loop {
        match s.read(&mut buf) {
            Ok(0) => return true,
            Ok(_) => {}
            Err(e)
                if e.kind() == std::io::ErrorKind::WouldBlock
                    || e.kind() == std::io::ErrorKind::TimedOut =>
            {
                return false
            }
            Err(_) => return true,
        }
    }
}

#[test]
fn clients_that_stall_in_large_packets_fill_the_total_but_never_for_the_processs_own_clients() {
    let broker = EmbeddedBroker::start(free_addr(), "cell1").expect("broker");
    let addr = broker.addr();
    // The process's own clients log in before the attack.
    let plc_login = broker.plc_login().clone();
    let plc = v5(
        broker.local_addr(),
        Some((&plc_login.user, &plc_login.password)),
    );
    let dash_login = broker.dashboard_login().clone();
    let dashboard = v5(
        broker.local_addr(),
        Some((&dash_login.user, &dash_login.password)),
    );
    dashboard.subscribe("cetratus/cell1/#");

    // Attackers announce packets of decreasing sizes and stall after a few bytes, each size until
    // the total refuses one: the room left is then less than the smallest of them.
    let mut held = Vec::new();
    let mut refused = 0;
    for announced in [BROKER_MAX_PACKET as usize - 16, 1 << 20, 256 << 10] {
        for _ in 0..(PARTIALS_BYTES / announced + 2) {
            let mut s = raw_client(addr, &unique("stall"));
            let mut begun = header(0x30, announced);
            begun.extend_from_slice(&mqtt_str("plant/unread"));
            begun.extend_from_slice(&[0xA5; 1024]);
            s.write_all(&begun).expect("the beginning of a PUBLISH");
            if closed_within(&mut s, Duration::from_secs(1)) {
                refused += 1;
                break;
            }
            held.push(s);
        }
    }
    assert!(
        refused >= 1,
        "the total refused none of {} clients that announced large packets",
        held.len()
    );

    // Another client's packet of 1 MiB does not fit: it is disconnected.
    let mut other = raw_client(addr, &unique("other"));
    let mut publish = header(0x30, 2 + 12 + (1 << 20));
    publish.extend_from_slice(&mqtt_str("plant/unread"));
    publish.extend_from_slice(&vec![0x5A; 1 << 20]);
    let _ = other.write_all(&publish);
    assert!(
        closed_within(&mut other, Duration::from_secs(10)),
        "a client that sends 1 MiB while the total is full is disconnected"
    );

    // The PLC's own client is not counted: its message of 1 MiB reaches the dashboard.
    let image = vec![0x42u8; 1 << 20];
    plc.client
        .publish(
            "cetratus/cell1/state",
            QoS::AtLeastOnce,
            false,
            image.clone(),
        )
        .expect("publish");
    let got = dashboard
        .next_on("cetratus/cell1/state", Duration::from_secs(10))
        .expect("the PLC's message of 1 MiB reaches the dashboard while the total is full");
    assert_eq!(got.payload, image);
    drop(held);
}
