//! What the broker says of each PLC, as the rollout last heard it: its retained `state`, its
//! latest `exec_info`, the reply and the event that ended the rollout's last command to it.
//! Everything here arrived from outside: a payload that is not what the protocol says is
//! dropped, and the view holds at most [`MAX_PLCS`] PLCs, one message of each kind per PLC.

use std::collections::BTreeMap;
use std::time::Instant;

use cetratus_proto::{
    ending, Ending, EventMsg, ExecInfoMsg, Leaf, Reply, Slot, StateMsg, StatePayload, Verb,
};

/// Most PLCs the view keeps; the ones beyond are not seen (a plant broker's topics may come
/// from anyone).
pub const MAX_PLCS: usize = 4096;

/// The rollout's last command to a PLC, and how it ended so far.
#[derive(Clone, Debug)]
pub struct Pending {
    /// Its verb.
    pub verb: Verb,
    /// When it was sent.
    pub at: Instant,
    /// The correlation data it was sent with: only a reply that carries it back is its reply.
    pub correlation: Vec<u8>,
    /// The PLC's reply, once it came.
    pub reply: Option<Reply>,
    /// The event that ended it, once it came.
    pub ended: Option<(Ending, EventMsg)>,
}

/// One PLC as last heard.
#[derive(Clone, Debug)]
pub struct Seen {
    /// Its last `state` while online; kept when it goes offline.
    pub state: Option<StateMsg>,
    /// Whether its last `state` said online.
    pub online: bool,
    /// When anything was last heard from it.
    pub heard: Instant,
    /// Its latest `exec_info`, when the view keeps them for it.
    pub info: Option<ExecInfoMsg>,
    /// Its last event that ends an update or alarms, for the reasons a report gives.
    pub last_event: Option<EventMsg>,
    /// The rollout's last command to it.
    pub pending: Option<Pending>,
}

impl Seen {
    /// The program in `slot`'s hash, when it holds one.
    pub fn hash(&self, slot: Slot) -> Option<&str> {
        let s = self.state.as_ref()?;
        s.programs.get(slot).map(|p| p.hash.as_str())
    }

    /// PRIMARY's program hash.
    pub fn primary_hash(&self) -> Option<&str> {
        self.hash(self.state.as_ref()?.primary)
    }

    /// The secondary container's program hash.
    pub fn secondary_hash(&self) -> Option<&str> {
        self.hash(self.state.as_ref()?.primary.other())
    }
}

/// Every PLC the rollout has heard of.
#[derive(Debug, Default)]
pub struct View {
    plcs: BTreeMap<String, Seen>,
    /// The PLCs whose `exec_info` is kept: the rollout's own.
    watched: std::collections::BTreeSet<String>,
    /// The suffix of the rollout's reply topics (`reply/<this>`).
    reply_leaf: String,
}

impl View {
    /// An empty view; replies arrive on `cetratus/<plc>/<reply_leaf>`.
    pub fn new(reply_leaf: &str) -> View {
        View {
            reply_leaf: reply_leaf.to_string(),
            ..View::default()
        }
    }

    /// Keeps the `exec_info` of these PLCs (and only theirs) from now on.
    pub fn watch(&mut self, ids: impl IntoIterator<Item = String>) {
        self.watched = ids.into_iter().collect();
    }

    /// One PLC, if heard of.
    pub fn get(&self, id: &str) -> Option<&Seen> {
        self.plcs.get(id)
    }

    /// Every PLC heard of, by id.
    pub fn all(&self) -> impl Iterator<Item = (&String, &Seen)> {
        self.plcs.iter()
    }

    /// Notes that `verb` was sent to `plc` now, with `correlation` as its correlation data.
    pub fn sent(&mut self, plc: &str, verb: Verb, correlation: Vec<u8>, now: Instant) {
        if let Some(s) = self.plcs.get_mut(plc) {
            s.pending = Some(Pending {
                verb,
                at: now,
                correlation,
                reply: None,
                ended: None,
            });
        }
    }

    /// Takes in one message from `cetratus/<plc>/<leaf>`, with the MQTT correlation data it
    /// carried; what is not the protocol's is dropped, and so is a reply whose correlation data
    /// is not the pending command's (anyone who may publish there could send it).
    pub fn take(
        &mut self,
        plc: &str,
        leaf: &str,
        payload: &[u8],
        correlation: Option<&[u8]>,
        now: Instant,
    ) {
        if !self.plcs.contains_key(plc) && (self.plcs.len() >= MAX_PLCS || leaf != "state") {
            return;
        }
        if leaf == Leaf::State.as_str() {
            let Ok(state) = serde_json::from_slice::<StatePayload>(payload) else {
                return;
            };
            let seen = self.plcs.entry(plc.to_string()).or_insert_with(|| Seen {
                state: None,
                online: false,
                heard: now,
                info: None,
                last_event: None,
                pending: None,
            });
            seen.heard = now;
            match state {
                StatePayload::Online(s) => {
                    seen.online = true;
                    seen.state = Some(s);
                }
                StatePayload::Offline => seen.online = false,
            }
            return;
        }
        let watched = self.watched.contains(plc);
        let reply = leaf == self.reply_leaf;
        let Some(seen) = self.plcs.get_mut(plc) else {
            return;
        };
        if leaf == Leaf::ExecInfo.as_str() && watched {
            if let Ok(info) = serde_json::from_slice::<ExecInfoMsg>(payload) {
                seen.heard = now;
                seen.info = Some(info);
            }
        } else if leaf == Leaf::Events.as_str() {
            if let Ok(event) = serde_json::from_slice::<EventMsg>(payload) {
                seen.heard = now;
                take_event(seen, event);
            }
        } else if reply {
            let pending = (seen.pending.as_mut())
                .filter(|p| correlation == Some(p.correlation.as_slice()) && p.reply.is_none());
            if let (Ok(r), Some(p)) = (serde_json::from_slice::<Reply>(payload), pending) {
                p.reply = Some(r);
            }
        }
    }
}

/// Keeps an event that ends the pending command, or that says why an update ended.
fn take_event(seen: &mut Seen, event: EventMsg) {
    use cetratus_proto::EventKind as K;
    let Some(kind) = event.kind.known() else {
        return;
    };
    if let Some(p) = &mut seen.pending {
        if p.ended.is_none() {
            if let Some(e) = ending(p.verb, &event.kind) {
                p.ended = Some((e, event.clone()));
            }
        }
    }
    if matches!(
        kind,
        K::Refused
            | K::Removed
            | K::Aborted
            | K::CandidateFault
            | K::PrimaryFault
            | K::UpdateDiscarded
            | K::TransformRefused
            | K::StateTransTimeout
            | K::SubstituteTimeout
            | K::Reverted
            | K::StallAlarm
            | K::Verdict
            | K::Accepted
    ) {
        seen.last_event = Some(event);
    }
}
