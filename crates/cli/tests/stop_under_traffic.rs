//! A stop always stops (docs/operations.md, *Stopping*): SIGTERM while commands pour in ends the
//! process, with the offline state published, however many commands wait for a scan thread that
//! takes no more. Tried against the real binary.

mod common;

use std::process::Command;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use common::{client, first_answer, wait_for, watch, RunningPlc};
use rumqttc::v5::mqttbytes::QoS;

#[test]
fn sigterm_during_a_flood_of_commands_stops_the_plc_and_says_it_is_offline() {
    let mut plc = RunningPlc::start("stop1", &[]);
    let (ops, replies) = client(plc.mqtt, "ops-stop1", "stop1");
    first_answer(&ops, &replies, "stop1", Duration::from_secs(30));
    let (_watcher, states) = watch(plc.mqtt, "cetratus/stop1/state");
    wait_for("the retained state", Duration::from_secs(10), || {
        !states.lock().expect("seen").is_empty()
    });

    // `abort`, which the preparer hands to the scan thread as it is, as fast as the broker takes
    // it: the hand-over queue is full whenever the scan thread stops.
    let (stop, sent) = (
        Arc::new(AtomicBool::new(false)),
        Arc::new(AtomicU64::new(0)),
    );
    let flood = {
        let (stop, sent) = (stop.clone(), sent.clone());
        std::thread::spawn(move || {
            while !stop.load(Ordering::Relaxed) {
                let ok = ops
                    .try_publish(
                        "cetratus/stop1/cmd/abort",
                        QoS::AtMostOnce,
                        false,
                        b"{}".to_vec(),
                    )
                    .is_ok();
                if ok {
                    sent.fetch_add(1, Ordering::Relaxed);
                } else {
                    std::thread::sleep(Duration::from_micros(200));
                }
            }
        })
    };
    wait_for("a flood of commands", Duration::from_secs(20), || {
        sent.load(Ordering::Relaxed) > 3000
    });
    let kill = Command::new("kill")
        .args(["-TERM", &plc.process.id().to_string()])
        .status()
        .expect("kill");
    assert!(kill.success());
    // Generous: it bounds a failure, not the time a stop takes.
    let end = Instant::now() + Duration::from_secs(30);
    let status = loop {
        if let Some(s) = plc.process.0.try_wait().expect("wait") {
            break s;
        }
        assert!(Instant::now() < end, "the PLC did not stop on SIGTERM");
        std::thread::sleep(Duration::from_millis(50));
    };
    stop.store(true, Ordering::Relaxed);
    let _ = flood.join();
    assert!(status.success(), "the PLC stopped with {status}");
    let offline = states
        .lock()
        .expect("seen")
        .iter()
        .any(|p| String::from_utf8_lossy(p).contains("\"online\":false"));
    assert!(offline, "the PLC said it was offline before it went");
}
