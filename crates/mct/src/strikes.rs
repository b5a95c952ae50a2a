//! A client that goes on sending past the embedded broker's limits is disconnected, and the
//! backlog in its socket goes with it.
//!
//! The broker reads one client's packets one at a time, and pauses before each refusal
//! ([`crate::ingress::REFUSAL_PAUSE`]), so a flooding client fills its own socket and the kernel
//! holds it back. But what it already sent is still read after it stops: after a 10 s flood the
//! broker went on taking its commands for about three minutes, and they took the command budget
//! that operators' commands needed. So a client refused [`STRIKES`] times within
//! [`STRIKE_WINDOW`] is disconnected (MQTT 5: *quota exceeded*, 0x97, with the reason). At one
//! refusal per pause that takes at least a second of refusals without a break; a client that waits
//! for each reply never gets near it.
//!
//! The clients counted are kept in a table of at most [`MAX_TRACKED`] fixed-size entries, keyed
//! by a hash of the client id: a client that cannot be counted (the table full of clients
//! refused in the last window) is refused as before, and only not disconnected.

use std::collections::hash_map::RandomState;
use std::collections::HashMap;
use std::hash::BuildHasher;
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Refusals within [`STRIKE_WINDOW`] after which a client is disconnected.
pub const STRIKES: u32 = 100;

/// The window in which refusals are counted, from a client's first refusal.
pub const STRIKE_WINDOW: Duration = Duration::from_secs(10);

/// Clients counted at once: four times the broker's session limit.
pub(crate) const MAX_TRACKED: usize = 1024;

/// Refusals per client, in the current window of each.
pub(crate) struct Strikes {
    table: Mutex<HashMap<u64, (Instant, u32)>>,
    keys: RandomState,
}

impl Default for Strikes {
    fn default() -> Self {
        Strikes {
            table: Mutex::new(HashMap::with_capacity(64)),
            keys: RandomState::new(),
        }
    }
}

impl Strikes {
    /// Counts a refusal of `client` at `now`; true when it is the one after which the client is
    /// to be disconnected (its count starts again).
    pub(crate) fn refuse(&self, client: &str, now: Instant) -> bool {
        let key = self.keys.hash_one(client);
        let mut table = self.table.lock().unwrap_or_else(|e| e.into_inner());
        if table.len() >= MAX_TRACKED && !table.contains_key(&key) {
            table.retain(|_, (since, _)| now.saturating_duration_since(*since) < STRIKE_WINDOW);
            if table.len() >= MAX_TRACKED {
                return false;
            }
        }
        let entry = table.entry(key).or_insert((now, 0));
        if now.saturating_duration_since(entry.0) >= STRIKE_WINDOW {
            *entry = (now, 0);
        }
        entry.1 += 1;
        if entry.1 >= STRIKES {
            table.remove(&key);
            return true;
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_client_refused_without_a_break_is_struck_out_and_one_refused_now_and_then_is_not() {
        let s = Strikes::default();
        let t0 = Instant::now();
        let out: Vec<bool> = (0..STRIKES).map(|_| s.refuse("flood", t0)).collect();
        assert_eq!(out.iter().filter(|&&b| b).count(), 1);
        assert!(out[STRIKES as usize - 1]);
        // Ninety-nine refusals a window never add up.
        for w in 0..5u32 {
            let at = t0 + STRIKE_WINDOW * (w + 1);
            for _ in 0..STRIKES - 1 {
                assert!(!s.refuse("now and then", at));
            }
        }
    }

    #[test]
    fn the_table_holds_at_most_its_bound_and_frees_old_windows() {
        let s = Strikes::default();
        let t0 = Instant::now();
        for k in 0..MAX_TRACKED {
            s.refuse(&format!("c{k}"), t0);
        }
        for _ in 0..STRIKES {
            assert!(!s.refuse("one more", t0), "not counted while full");
        }
        let later = t0 + STRIKE_WINDOW;
        s.refuse("one more", later);
        assert_eq!(s.table.lock().expect("table").len(), 1, "old windows freed");
    }
}
