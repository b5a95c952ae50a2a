//! What a connection makes the embedded broker hold in its own buffers must not make the PLC's
//! memory depend on what others send: neither many clients that each send all but the end of a
//! packet of the largest size and then stall (the packets they have begun, in the connections'
//! read buffers), nor many clients that each send one such packet whole and then stay connected
//! (read buffers that would keep the size of their largest packet).
//!
//! `cetratus run` on its embedded broker; the attackers are MQTT 3.1.1 clients on bare sockets
//! (`common::raw_mqtt`), connected at once, well within `MAX_CLIENTS`. The PLC's resident memory
//! must grow by no more than the bound that holds (`PARTIALS_BYTES` and a floor a connection for
//! the begun packets; `CONNECTION_BUFFER_BYTES` a connection for the buffers once the packets
//! are read) and a margin; the broker must say when it disconnects a client for the total; and
//! the PLC must go on cycling and answering an operator's command. The two tests run one at a
//! time: each measures the memory of its own PLC.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::sync::Mutex;
use std::time::Duration;

use cetratus_mct::{
    BROKER_MAX_PACKET, CONNECTION_BUFFER_BYTES, MAX_CLIENTS, PARTIALS_BYTES, PARTIAL_FLOOR_BYTES,
};

mod common;

use common::raw_mqtt::{connect as raw_connect, mqtt_str, packet};
use common::{
    assert_cycles_on, client, first_answer, primary_cycles, rss_kb, RssSampler, RunningPlc,
};

const PLC: &str = "cell1";
/// Attackers connected at once: most of what the broker admits ([`MAX_CLIENTS`]), leaving room
/// for the PLC's own client, its dashboard and the operator.
const ATTACKERS: usize = 160;
const _: () = assert!(ATTACKERS + 3 < MAX_CLIENTS, "the attackers are admitted");
/// Room for what else the attack costs the PLC besides the bound: the attackers' sessions and
/// sockets, the allocator's slack, a packet being read by each of the broker's two threads when
/// it checks the total, and the PLC's own work meanwhile.
const MARGIN_KB: u64 = 48 * 1024;

/// One test at a time: each measures its own PLC's memory while it attacks it.
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

/// A PUBLISH at QoS 0 to a topic no one reads, of the largest size the broker takes.
fn largest_publish() -> Vec<u8> {
    let mut body = mqtt_str("plant/unread");
    body.resize(BROKER_MAX_PACKET as usize - 16, 0xA5);
    packet(0x30, &body)
}

/// An UNSUBSCRIBE of topics no one subscribed, of nearly the largest size the broker takes: read
/// and answered (UNSUBACK) like any packet, and never charged to what others may publish.
fn largest_unsubscribe() -> Vec<u8> {
    let mut body = vec![0, 7];
    let filter = "x".repeat(60_000);
    while body.len() + filter.len() + 2 < BROKER_MAX_PACKET as usize - 16 {
        body.extend_from_slice(&mqtt_str(&filter));
    }
    packet(0xA2, &body)
}

/// Starts the PLC, runs `attack` against its broker's port, checks that the PLC cycles on and
/// answers an operator while the attackers are still connected, and returns the growth of its
/// resident memory in kB (the peak during the attack) and its log.
fn attacked(attack: impl FnOnce(u16) -> Vec<TcpStream>) -> (u64, Vec<String>) {
    let (plc, log) = RunningPlc::start_logged(PLC, &[]);
    let pid = plc.process.id();
    let (ops, replies) = client(plc.mqtt, "ops", PLC);
    let before = primary_cycles(&first_answer(&ops, &replies, PLC, Duration::from_secs(30)));

    let rss_before = rss_kb(pid).expect("the PLC's memory");
    let sampler = RssSampler::start(pid);
    let held = attack(plc.mqtt);
    // Whatever the broker still holds for the attackers, it holds now.
    std::thread::sleep(Duration::from_secs(2));
    let peak = sampler.peak_kb();
    let settled = rss_kb(pid).expect("the PLC's memory");

    assert_cycles_on(&ops, &replies, PLC, b"under-attack", before);
    let growth = peak.saturating_sub(rss_before);
    eprintln!(
        "{} attackers' sockets kept; PLC RSS before {rss_before} kB, peak {peak} kB, \
         settled {settled} kB, growth {growth} kB",
        held.len()
    );
    drop(held);
    let logged: Vec<String> = log.try_iter().collect();
    drop(plc);
    (growth, logged)
}

#[test]
fn clients_that_stall_in_the_middle_of_large_packets_hold_no_more_than_the_brokers_total() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let publish = largest_publish();
    // All but the last 4 KiB: the broker can decode nothing and holds what it has read.
    let begun = &publish[..publish.len() - 4096];
    let (growth, logged) = attacked(|port| {
        let attackers: Vec<_> = (0..ATTACKERS)
            .map(|k| raw_connect(("127.0.0.1", port), &format!("stall-{k}")))
            .collect();
        let held = std::thread::scope(|scope| {
            let sending: Vec<_> = attackers
                .into_iter()
                .map(|mut s| {
                    scope.spawn(move || {
                        // A write that fails: the broker has disconnected this attacker.
                        s.write_all(begun).ok().map(|()| s)
                    })
                })
                .collect();
            sending
                .into_iter()
                .filter_map(|t| t.join().expect("an attacker's thread"))
                .collect::<Vec<_>>()
        });
        eprintln!(
            "{ATTACKERS} attackers each sent {} of a {}-byte PUBLISH; {} of them were not cut off \
             while sending",
            begun.len(),
            publish.len(),
            held.len()
        );
        held
    });
    let floors = (ATTACKERS * PARTIAL_FLOOR_BYTES) as u64 / 1024;
    let bound = PARTIALS_BYTES as u64 / 1024 + floors + MARGIN_KB;
    eprintln!(
        "bound {bound} kB: the total {} kB + floors {floors} kB + margin {MARGIN_KB} kB",
        PARTIALS_BYTES / 1024
    );
    assert!(
        growth < bound,
        "the PLC's memory grew by {growth} kB while {ATTACKERS} clients stalled in the middle of \
         large packets: more than all begun packets may hold together and a margin"
    );
    assert!(
        logged
            .iter()
            .any(|l| l.contains("packets begun and not yet received")),
        "the broker says it disconnected clients for its total; the log:\n{}",
        logged.join("\n")
    );
}

#[test]
fn one_large_packet_does_not_cost_its_size_for_the_life_of_the_connection() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let unsubscribe = largest_unsubscribe();
    let (growth, _) = attacked(|port| {
        // One at a time, each waiting for its answer: the packets never add up while they are
        // read, so only what a connection keeps afterwards can.
        (0..ATTACKERS)
            .map(|k| {
                let mut s = raw_connect(("127.0.0.1", port), &format!("large-once-{k}"));
                s.write_all(&unsubscribe).expect("UNSUBSCRIBE");
                let mut unsuback = [0u8; 4];
                s.read_exact(&mut unsuback).expect("UNSUBACK");
                assert_eq!(
                    unsuback,
                    [0xB0, 2, 0, 7],
                    "the broker answers the attacker {k}"
                );
                // Then only tiny packets: a ping.
                s.write_all(&[0xC0, 0]).expect("PINGREQ");
                let mut pingresp = [0u8; 2];
                s.read_exact(&mut pingresp).expect("PINGRESP");
                s
            })
            .collect()
    });
    let buffers = (ATTACKERS * 2 * CONNECTION_BUFFER_BYTES) as u64 / 1024;
    let bound = buffers + MARGIN_KB;
    eprintln!(
        "bound {bound} kB: two small buffers a connection {buffers} kB + margin {MARGIN_KB} kB"
    );
    assert!(
        growth < bound,
        "the PLC's memory grew by {growth} kB while {ATTACKERS} clients, each after one large \
         packet, sent only tiny ones: connections keep the size of their largest packet"
    );
}
