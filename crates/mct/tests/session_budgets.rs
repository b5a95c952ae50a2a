//! The byte budgets that the patched rmqtt (`vendor/rmqtt`) keeps for the embedded broker's
//! sessions, on rmqtt's own types: a session's deliver queue with its in-flight window
//! (`SESSION_QUEUE_BYTES`), and the total of all sessions with the reserve of the process's own
//! clients (`SESSIONS_BYTES`, `INTERNAL_SESSIONS_BYTES`). The attacks against the real binary
//! are in `crates/cli/tests/slow_subscriber.rs` and `hoarding_subscribers.rs`.

use std::sync::Arc;

use rmqtt::inflight::{MomentStatus, OutInflight, OutInflightMessage};
use rmqtt::net::SessionsBudget;
use rmqtt::queue::{Limiter, Policy, Queue};
use rmqtt::types::{ByteBudget, From, Id, Publish, QoS, Reason};

/// A message of `n` payload bytes on the topic `t`, at `qos`, with packet id `id`.
fn message(n: usize, qos: QoS, id: u16) -> Publish {
    rmqtt::codec::types::Publish {
        dup: false,
        retain: false,
        qos,
        topic: "t".into(),
        packet_id: std::num::NonZeroU16::new(id),
        payload: vec![0u8; n].into(),
        properties: None,
    }
    .into()
}

fn from() -> From {
    From::from_custom(Id::new(0, 0, None, None, "camera".into(), None))
}

fn queue(cap: usize, budget: &ByteBudget) -> Arc<Queue<(From, Publish)>> {
    Arc::new(Queue::new(cap).with_budget(budget.clone(), |(_, p)| ByteBudget::cost(p)))
}

#[test]
fn a_deliver_queue_refuses_what_passes_its_bytes_whatever_the_policy_and_gives_back_what_leaves() {
    let image = message(1000, QoS::AtLeastOnce, 0);
    let cost = ByteBudget::cost(&image);
    let budget = ByteBudget::new(3 * cost, None, None);
    let limiter = Limiter::new(
        std::num::NonZeroU32::new(1000).unwrap(),
        std::time::Duration::from_secs(1),
    );
    let q = queue(64, &budget);
    let (tx, _rx) = limiter.channel(q.clone());
    // QoS 1: rmqtt's policy would drop the earliest message to make room; bytes refuse the new one.
    let tx = tx.policy(|_: &(From, Publish)| Policy::Early);
    futures::executor::block_on(async {
        for k in 0..3 {
            assert!(tx.send((from(), image.clone())).await.is_ok(), "{k}");
        }
        let refused = tx.send((from(), image.clone())).await;
        assert!(
            refused.is_err(),
            "a fourth message passes the queue's bytes"
        );
        assert!(matches!(tx.take_refusal(), Reason::MessageQueueFull));
        assert_eq!(q.len(), 3, "no earlier message was dropped for it");
        assert_eq!(budget.held(), 3 * cost, "a refused message is not booked");
        // Taken out to be written: still booked until written (or in flight).
        assert!(q.pop_for_delivery().is_some());
        assert_eq!(budget.held(), 3 * cost);
        tx.delivered();
        assert_eq!(budget.held(), 2 * cost, "written: given back");
        assert!(tx.pop().is_some());
        assert_eq!(budget.held(), cost, "dropped from the queue: given back");
        assert!(tx.send((from(), image.clone())).await.is_ok());
    });
}

#[test]
fn the_in_flight_window_shares_the_deliver_queue_bytes_until_acknowledged() {
    let image = message(1000, QoS::AtLeastOnce, 7);
    let cost = ByteBudget::cost(&image);
    let budget = ByteBudget::new(2 * cost, None, None);
    let q = queue(64, &budget);
    let mut window = OutInflight::new(16, 0, 0).with_budget(budget.clone());
    assert!(q.push((from(), image.clone())).is_ok());
    assert!(q.push((from(), message(1000, QoS::AtLeastOnce, 8))).is_ok());
    let (f, p) = q.pop_for_delivery().expect("the first message");
    // Written, then kept in the window until acknowledged: booked once, not twice.
    window.push_back(OutInflightMessage::new(MomentStatus::UnAck, f, p));
    if let Some(b) = q.budget() {
        b.delivered();
    }
    assert_eq!(budget.held(), 2 * cost, "one in flight, one queued");
    assert!(
        q.push((from(), image.clone())).is_err(),
        "what is in flight counts against the queue's bytes"
    );
    assert!(window.remove(&7).is_some(), "acknowledged");
    assert_eq!(budget.held(), cost, "acknowledged: given back");
    assert!(q.push((from(), image)).is_ok());
}

#[test]
fn all_sessions_share_a_total_the_reserve_is_apart_and_a_session_gone_gives_back_what_it_held() {
    let image = message(1000, QoS::AtMostOnce, 0);
    let cost = ByteBudget::cost(&image);
    let total = Arc::new(SessionsBudget::new(3 * cost, vec!["$plc".into()], 2 * cost));
    let a = ByteBudget::new(2 * cost, Some(total.clone()), Some("mallory"));
    let b = ByteBudget::new(2 * cost, Some(total.clone()), None);
    let plc = ByteBudget::new(2 * cost, Some(total.clone()), Some("$plc"));
    for budget in [&a, &a, &b] {
        assert!(budget.charge(cost, Reason::MessageQueueFull).is_ok());
    }
    assert!(
        matches!(
            b.charge(cost, Reason::MessageQueueFull),
            Err(Reason::SessionsBudgetFull)
        ),
        "b is within its own budget, but all sessions together are full"
    );
    assert_eq!(
        b.held(),
        cost,
        "a message refused by the total is not booked by the session"
    );
    for k in 0..2 {
        assert!(
            plc.charge(cost, Reason::MessageQueueFull).is_ok(),
            "the PLC's own client is charged to its reserve: {k}"
        );
    }
    assert!(matches!(
        plc.charge(cost, Reason::SessionInboxFull),
        Err(Reason::SessionInboxFull)
    ));
    assert_eq!(
        total.shared.load(std::sync::atomic::Ordering::Acquire),
        3 * cost
    );
    drop(a);
    assert_eq!(
        total.shared.load(std::sync::atomic::Ordering::Acquire),
        cost,
        "a session gone gives back what it still held"
    );
    assert!(b.charge(cost, Reason::MessageQueueFull).is_ok());
}

#[test]
fn a_session_within_its_floor_is_never_refused_by_the_total() {
    let reply = message(100, QoS::AtMostOnce, 0);
    let cost = ByteBudget::cost(&reply);
    let total = Arc::new(SessionsBudget::new(4 * cost, vec![], 0).with_floor(cost));
    let hoarder = ByteBudget::new(4 * cost, Some(total.clone()), Some("mallory"));
    for _ in 0..4 {
        assert!(hoarder.charge(cost, Reason::SessionInboxFull).is_ok());
    }
    let operator = ByteBudget::new(4 * cost, Some(total.clone()), Some("ops"));
    assert!(
        operator.charge(cost, Reason::SessionInboxFull).is_ok(),
        "an operator's session that holds nothing takes a reply, though the others hold the total"
    );
    assert!(
        matches!(
            operator.charge(cost, Reason::SessionInboxFull),
            Err(Reason::SessionsBudgetFull)
        ),
        "past its floor, the total decides"
    );
    assert_eq!(
        total.shared.load(std::sync::atomic::Ordering::Acquire),
        5 * cost,
        "the floor is booked in the total, which it passes by at most a floor a session"
    );
}
