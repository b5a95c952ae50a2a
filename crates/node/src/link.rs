//! The node's side of the MQTT control plane: what the scan thread meets of MQTT.
//!
//! Three threads, joined by bounded queues; the scan thread never blocks:
//! * the **scan thread** runs the cycle at absolute deadlines, takes ready commands with
//!   `try_recv`, and hands snapshots and events on with `try_send`;
//! * the **preparer** turns MQTT commands into runtime commands: it verifies and builds update
//!   packages and compiles `substitute --when` conditions, away from the scan thread;
//! * the **publisher** turns snapshots into `state`, `exec_info`, `io` and `net` messages, and
//!   answers `exec_info` requests from the latest snapshot: the scan thread never sees them.
//!
//! Every queue is bounded by what it may hold, not only by its number of entries: the commands
//! by their bytes (in `cetratus-mct`), the `exec_info` requests by [`EXEC_INFO_QUEUE`], the
//! messages the scan thread keeps for a busy MQTT client by [`PENDING_BYTES`]. A full queue
//! answers `busy` or drops the message, and counts it ([`LinkCounters`]).

use std::collections::VecDeque;
use std::sync::atomic::AtomicBool;
use std::sync::mpsc::{channel, sync_channel, Receiver, Sender, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};

use cetratus_mct::budget::{worth_logging, Budget, Permit};
use cetratus_mct::{
    accepted, refused, IncomingCommand, MctLink, Outgoing, ReplyHandle, Request, StatsReader,
};
use cetratus_program::{Program, Value};
use cetratus_proto::{
    within_error, ControlCounters, ErrorBody, ErrorCode, EventMsg, ExecInfoMsg, IoMsg, IoNames,
    StateMsg,
};
use cetratus_runtime::{
    Command, Event, ExecInfo, LoopTiming, Plc, PreparedUpdate, Slot, Status, SubstituteRequest,
    UpdateContext,
};
use serde_json::json;

use crate::load::LoadPolicy;
use crate::wire;
use cetratus_io::field::DeviceStatus;

/// `exec_info` requests that may wait for the publisher; past them a request is answered
/// `busy`.
pub const EXEC_INFO_QUEUE: usize = 64;

/// Bytes of events and replies the scan thread keeps while the MQTT client is behind. Past half
/// of it the scan thread takes no new command (the queues before it fill up and answer `busy`);
/// past all of it an event is dropped, and counted.
pub const PENDING_BYTES: usize = 1 << 20;

/// A command, prepared, for the scan thread.
struct Ready {
    command: Box<Command>,
    from: IncomingCommand,
    // What the reply says besides `accepted` (a load's verdicts), built off the scan thread.
    extra: Option<serde_json::Value>,
}

/// What the publisher is given: snapshots from the scan thread, `exec_info` requests from the
/// preparer. Each holds a permit of its queue's budget until the publisher is done with it.
enum ToPublisher {
    Snapshot(Box<Snapshot>, Permit),
    ExecInfo(ReplyHandle, Permit),
}

/// What the MQTT side of a node turned away or dropped.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkCounters {
    /// Events and replies dropped because the MQTT client was behind ([`PENDING_BYTES`]).
    pub dropped: u64,
    /// Snapshots not published because the publisher was behind (the next one carries on).
    pub snapshots_skipped: u64,
}

/// A program with the marking to draw it with.
type ProgramAndMarking = (Arc<Program>, Vec<u32>);

struct Snapshot {
    state: StateMsg,
    exec_info: [Option<ExecInfo>; 2],
    names_in: Arc<Vec<String>>,
    names_out: Arc<Vec<String>>,
    inputs: Vec<Value>,
    outputs: [Option<Vec<Value>>; 2],
    dispatched: Vec<Value>,
    samples: Vec<cetratus_proto::Sample>,
    programs: Option<[Option<ProgramAndMarking>; 2]>,
    time_us: u64,
}

/// The scan thread's side of MQTT: call [`ControlLink::take_commands`] before each cycle and
/// [`ControlLink::after_cycle`] after it. Neither blocks.
pub struct ControlLink {
    to_scan_rx: Receiver<Ready>,
    ctx_tx: SyncSender<(UpdateContext, bool)>,
    // Set by the preparer when a load needs the primary's marking of now (the analysis gate).
    ctx_wanted: Arc<AtomicBool>,
    snap_tx: Option<Sender<ToPublisher>>,
    snapshots: Budget,
    outgoing: SyncSender<Outgoing>,
    pending: VecDeque<(Outgoing, usize)>,
    pending_bytes: usize,
    counters: LinkCounters,
    net_due: bool,
    names_in: Arc<Vec<String>>,
    names_out: Arc<Vec<String>>,
    last_key: (Slot, Status, Option<[u8; 32]>, Option<[u8; 32]>),
    last_sampled: u64,
    first: bool,
    publish_every: u64,
    done: Arc<AtomicBool>,
    threads: Vec<std::thread::JoinHandle<()>>,
    mqtt_stats: StatsReader,
    quality: QualitySource,
    // The operator key that signed the last accepted load (auto substitution checks it).
    load_key: Option<String>,
    persist_fault: Option<cetratus_proto::PersistFault>,
}

/// Reads the input quality of every source of inputs (field devices, OPC UA clients), from the
/// publisher's thread, never the scan's.
pub type InputQualityReader = Arc<dyn Fn() -> Vec<DeviceStatus> + Send + Sync>;

/// What the local configuration says of the PLC that every `state` carries: its labels and its
/// update policy (docs/fleet.md).
#[derive(Clone, Debug, Default)]
pub struct OwnFacts {
    /// `[labels]`.
    pub labels: cetratus_proto::Labels,
    /// What `[updates]` enforces of every update.
    pub updates: cetratus_proto::UpdatePolicy,
}

/// Where the publisher reads the input quality, once the node has field I/O or OPC UA inputs.
type QualitySource = Arc<Mutex<Option<InputQualityReader>>>;

impl ControlLink {
    /// Starts the preparer and the publisher for `plc` on `link`; loads pass `policy`.
    /// Every `state` carries `own`.
    pub fn start(
        plc: &Plc,
        link: MctLink,
        policy: LoadPolicy,
        publish_every: u64,
        own: OwnFacts,
    ) -> ControlLink {
        let MctLink {
            commands,
            outgoing,
            stats,
        } = link;
        let (to_scan_tx, to_scan_rx) = sync_channel::<Ready>(32);
        let (ctx_tx, ctx_rx) = sync_channel::<(UpdateContext, bool)>(4);
        let ctx_wanted = Arc::new(AtomicBool::new(false));
        // Unbounded as a channel, bounded by the permits its messages carry.
        let (snap_tx, snap_rx) = channel::<ToPublisher>();
        let _ = ctx_tx.try_send((plc.update_context(), false));
        let prep = Preparer {
            ctx_rx,
            ctx_wanted: ctx_wanted.clone(),
            to_scan: to_scan_tx,
            to_publisher: snap_tx.clone(),
            exec_info: Budget::new(EXEC_INFO_QUEUE),
            out: outgoing.clone(),
            policy,
        };
        let done = Arc::new(AtomicBool::new(false));
        let prep_done = done.clone();
        let preparer = std::thread::Builder::new()
            .name("cetratus-prepare".into())
            .spawn(move || prep.run(commands, prep_done))
            .expect("spawn the preparer");
        let pub_out = outgoing.clone();
        let quality: QualitySource = Arc::new(Mutex::new(None));
        let pub_quality = quality.clone();
        let publisher = std::thread::Builder::new()
            .name("cetratus-publish".into())
            .spawn(move || publish_loop(snap_rx, pub_out, pub_quality, own))
            .expect("spawn the publisher");
        ControlLink {
            to_scan_rx,
            ctx_tx,
            ctx_wanted,
            snap_tx: Some(snap_tx),
            snapshots: Budget::new(2),
            outgoing,
            pending: VecDeque::with_capacity(256),
            pending_bytes: 0,
            counters: LinkCounters::default(),
            net_due: true,
            names_in: Arc::new(plc.io_inputs().to_vec()),
            names_out: Arc::new(plc.io_outputs().to_vec()),
            last_key: (Slot::A, Status::Idle, None, None),
            last_sampled: 0,
            first: true,
            publish_every: publish_every.max(1),
            done,
            threads: vec![preparer, publisher],
            mqtt_stats: stats,
            quality,
            load_key: None,
            persist_fault: None,
        }
    }

    /// Shows the input quality of the field devices and OPC UA clients in `exec_info`, read by
    /// the publisher from `reader` (never by the scan thread).
    pub fn set_input_quality(&mut self, reader: InputQualityReader) {
        *self.quality.lock().unwrap_or_else(|p| p.into_inner()) = Some(reader);
    }

    /// Gives the PLC the commands that are ready. Returns who sent the last one, for the audit
    /// log (`mqtt`, `mqtt:<key id>`, or `mqtt:<key id>/<account>` when the signed envelope names
    /// the operator's account), when there was one. While the replies and events of
    /// earlier commands still wait for the MQTT client, no new command is taken.
    pub fn take_commands(&mut self, plc: &mut Plc) -> Option<String> {
        let mut who = None;
        while self.pending_bytes < PENDING_BYTES / 2 {
            let Ok(Ready {
                command,
                from,
                extra,
            }) = self.to_scan_rx.try_recv()
            else {
                break;
            };
            let is_load = matches!(*command, Command::Load(_));
            let outcome = match (plc.command(*command), extra) {
                (Ok(()), None) => accepted(),
                (Ok(()), Some(extra)) => Ok(Some(extra)),
                (Err(e), _) => Err(refused(e.to_string())),
            };
            if is_load && outcome.is_ok() {
                self.load_key = from.key_id.clone();
            }
            who = Some(match (&from.key_id, &from.account) {
                (Some(k), Some(a)) => format!("mqtt:{k}/{a}"),
                (Some(k), None) => format!("mqtt:{k}"),
                (None, _) => "mqtt".to_string(),
            });
            self.queue(Outgoing::Reply(from.reply, outcome));
        }
        who
    }

    /// The operator key that signed the last load the PLC accepted (`None` without operator
    /// keys, or for a load from elsewhere).
    pub fn load_key(&self) -> Option<&str> {
        self.load_key.as_deref()
    }

    /// Keeps a message for the MQTT client, or drops it (counted) when [`PENDING_BYTES`] are
    /// kept already.
    fn queue(&mut self, m: Outgoing) {
        let size = m.approx_bytes();
        if self.pending_bytes + size > PENDING_BYTES {
            self.counters.dropped += 1;
            if worth_logging(self.counters.dropped) {
                tracing::warn!(
                    dropped = self.counters.dropped,
                    kept = self.pending_bytes,
                    "the MQTT client is behind: an event or reply of the PLC was dropped"
                );
            }
            return;
        }
        self.pending_bytes += size;
        self.pending.push_back((m, size));
    }

    /// Whether the state directory can be written, for `state`: published at once when it
    /// changes.
    pub fn set_persist_fault(&mut self, fault: Option<cetratus_proto::PersistFault>) {
        self.persist_fault = fault;
        self.first = true;
    }

    /// Queues events (those of a command taken between cycles) for publication.
    pub fn queue_events(&mut self, events: &[Event]) {
        for e in events {
            self.queue(Outgoing::Event(wire::event(e)));
        }
    }

    /// What was dropped or skipped so far.
    pub fn counters(&self) -> LinkCounters {
        self.counters
    }

    /// What the whole control plane turned away or dropped so far, for `state`.
    fn control_counters(&self) -> ControlCounters {
        let mqtt = self.mqtt_stats.read();
        ControlCounters {
            commands_busy: mqtt.commands_busy,
            commands_dropped: mqtt.commands_dropped,
            messages_lost: mqtt.messages_lost,
            events_dropped: self.counters.dropped,
            snapshots_skipped: self.counters.snapshots_skipped,
        }
    }

    /// Publishes the cycle's events, and a snapshot when one is due or something changed.
    pub fn after_cycle(&mut self, plc: &Plc, events: &[Event], timing: &LoopTiming, now: u64) {
        self.queue_events(events);
        // A load waits for the marking of this boundary: its analysis gate starts from it.
        if self
            .ctx_wanted
            .swap(false, std::sync::atomic::Ordering::AcqRel)
        {
            let _ = self.ctx_tx.try_send((plc.update_context(), true));
        }
        let hash = |s: Slot| plc.container(s).map(|c| c.program().hash());
        let key = (plc.primary(), plc.status(), hash(Slot::A), hash(Slot::B));
        let changed = key != self.last_key;
        if changed {
            if key.0 != self.last_key.0 || key.2 != self.last_key.2 || key.3 != self.last_key.3 {
                let _ = self.ctx_tx.try_send((plc.update_context(), false));
            }
            self.last_key = key;
            self.net_due = true;
        }
        let due = self.first || changed || plc.cycles().is_multiple_of(self.publish_every);
        // Taken before the snapshot is built: when the publisher is behind, the scan thread
        // does not copy what would be dropped.
        let permit = if due {
            let p = self.snapshots.try_take(1);
            if p.is_none() {
                self.counters.snapshots_skipped += 1;
            }
            p
        } else {
            None
        };
        if let (Some(permit), Some(tx)) = (permit, &self.snap_tx) {
            // The preparer's context follows the primary's marking at the publication rate: the
            // analysis gate starts from it.
            let _ = self.ctx_tx.try_send((plc.update_context(), false));
            let since = self.last_sampled;
            let samples: Vec<cetratus_proto::Sample> = plc
                .monitor()
                .recent
                .iter()
                .filter(|r| r.cycle >= since)
                .map(|r| wire::sample(&r))
                .collect();
            self.last_sampled = plc.cycles();
            // A live update may have added signals to the I/O map.
            if self.names_in.len() != plc.io_inputs().len() {
                self.names_in = Arc::new(plc.io_inputs().to_vec());
            }
            if self.names_out.len() != plc.io_outputs().len() {
                self.names_out = Arc::new(plc.io_outputs().to_vec());
            }
            let mut state = wire::state(plc, timing);
            state.control = self.control_counters();
            state.persist_fault = self.persist_fault.clone();
            let snap = Snapshot {
                state,
                exec_info: plc.exec_info(),
                names_in: self.names_in.clone(),
                names_out: self.names_out.clone(),
                inputs: plc.inputs().to_vec(),
                outputs: [Slot::A, Slot::B].map(|s| plc.outputs_of(s).map(<[Value]>::to_vec)),
                dispatched: plc.dispatched().to_vec(),
                samples,
                programs: self.net_due.then(|| {
                    [Slot::A, Slot::B].map(|s| {
                        plc.container(s)
                            .map(|c| (c.program().clone(), c.marking().to_vec()))
                    })
                }),
                time_us: now,
            };
            self.first = false;
            if tx
                .send(ToPublisher::Snapshot(Box::new(snap), permit))
                .is_ok()
            {
                self.net_due = false;
            }
        }
        while let Some((m, size)) = self.pending.pop_front() {
            if let Err(back) = try_out(&self.outgoing, m) {
                self.pending.push_front((back, size));
                break;
            }
            self.pending_bytes -= size;
        }
    }

    /// Stops the preparer and the publisher, within [`cetratus_mct::STOP_WITHIN`] each whatever
    /// is queued: the commands prepared and not yet taken are dropped, since the scan thread
    /// takes no more.
    pub fn stop(self) {
        let ControlLink {
            to_scan_rx,
            snap_tx,
            done,
            threads,
            ..
        } = self;
        done.store(true, std::sync::atomic::Ordering::Release);
        drop(snap_tx);
        // The preparer may be blocked handing a command to the scan thread: without a receiver,
        // its send fails and it ends.
        drop(to_scan_rx);
        for (t, what) in threads.into_iter().zip(["the preparer", "the publisher"]) {
            cetratus_mct::join_within(t, cetratus_mct::STOP_WITHIN, what);
        }
    }
}

#[allow(clippy::result_large_err)]
fn try_out(tx: &SyncSender<Outgoing>, m: Outgoing) -> Result<(), Outgoing> {
    tx.try_send(m).map_err(|e| match e {
        TrySendError::Full(m) | TrySendError::Disconnected(m) => m,
    })
}

/// The preparer thread: MQTT commands in, prepared commands out to the scan thread,
/// `exec_info` requests out to the publisher.
struct Preparer {
    ctx_rx: Receiver<(UpdateContext, bool)>,
    ctx_wanted: Arc<AtomicBool>,
    to_scan: SyncSender<Ready>,
    to_publisher: Sender<ToPublisher>,
    exec_info: Budget,
    out: SyncSender<Outgoing>,
    policy: LoadPolicy,
}

impl Preparer {
    fn run(self, commands: cetratus_mct::CommandQueue, done: Arc<AtomicBool>) {
        let mut ctx: Option<UpdateContext> = None;
        loop {
            let cmd = match commands.recv_timeout(std::time::Duration::from_millis(200)) {
                Ok(c) => c,
                Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
                    if done.load(std::sync::atomic::Ordering::Acquire) {
                        return;
                    }
                    while let Ok((c, _)) = self.ctx_rx.try_recv() {
                        ctx = Some(c);
                    }
                    continue;
                }
                Err(_) => return,
            };
            while let Ok((c, _)) = self.ctx_rx.try_recv() {
                ctx = Some(c);
            }
            if cmd.request == Request::ExecInfo {
                self.exec_info(cmd.reply);
                continue;
            }
            let Some(c) = ctx.as_ref() else {
                let _ = self.out.send(Outgoing::Reply(
                    cmd.reply,
                    Err(refused("the PLC is starting; try again")),
                ));
                continue;
            };
            let (mut extra, mut newer) = (None, None);
            let prepared = cmd.request.as_ref().try_map(
                |package| {
                    let (p, e, n) = self.load(c, package).map_err(|e| e.to_string())?;
                    (extra, newer) = (Some(e), n);
                    Ok(p)
                },
                |a| substitute(c, a),
            );
            if newer.is_some() {
                ctx = newer;
            }
            match prepared {
                Ok(command) => {
                    // Blocks while the scan thread is behind, so the command queue before this
                    // thread fills up and answers `busy`.
                    let ready = Ready {
                        command: Box::new(command),
                        from: cmd,
                        extra,
                    };
                    if self.to_scan.send(ready).is_err() {
                        return;
                    }
                }
                Err(reason) => {
                    let _ = self.out.send(Outgoing::Event(EventMsg {
                        cycle: None,
                        time_us: None,
                        kind: cetratus_runtime::EventKind::Refused.into(),
                        message: reason.clone(),
                        detail: json!({"verb": cmd.request.verb(), "key_id": cmd.key_id}),
                    }));
                    let _ = self
                        .out
                        .send(Outgoing::Reply(cmd.reply, Err(refused(reason))));
                }
            }
        }
    }

    /// Verifies, resolves and builds a package, then gates it from the primary's marking of the
    /// next cycle boundary: the command for the scan thread and what the reply adds. Only a
    /// package that verified asks the scan thread for that marking, so refused loads cost the
    /// scan thread nothing. When the primary changed meanwhile, the package is resolved again,
    /// against the new one.
    fn load(
        &self,
        before: &UpdateContext,
        package: &[u8],
    ) -> Result<
        (
            Box<PreparedUpdate>,
            serde_json::Value,
            Option<UpdateContext>,
        ),
        crate::load::LoadRefusal,
    > {
        let mut p = self.policy.build(before, package)?;
        let newer = self.fresh_context();
        let c = newer.as_ref().unwrap_or(before);
        if c.primary.hash() != before.primary.hash() {
            p = self.policy.build(c, package)?;
        }
        let p = self.policy.gate(c, p)?;
        let accepted = cetratus_proto::Accepted {
            accepted: true,
            verdicts: p.verdicts().last().map(wire::verdict).into_iter().collect(),
        };
        let extra = serde_json::to_value(accepted).unwrap_or_default();
        Ok((Box::new(p), extra, newer))
    }

    /// Asks the scan thread for the primary's marking of its next cycle boundary and waits for
    /// it (a second at most: a scan thread that does not answer leaves the last context), so that
    /// the analysis gate starts from the marking of now rather than of the last publication.
    fn fresh_context(&self) -> Option<UpdateContext> {
        self.ctx_wanted
            .store(true, std::sync::atomic::Ordering::Release);
        let end = std::time::Instant::now() + std::time::Duration::from_secs(1);
        let mut newest = None;
        while let Some(left) = end.checked_duration_since(std::time::Instant::now()) {
            match self.ctx_rx.recv_timeout(left) {
                Ok((c, fresh)) => {
                    newest = Some(c);
                    if fresh {
                        break;
                    }
                }
                Err(_) => break,
            }
        }
        newest
    }

    /// Hands an `exec_info` request to the publisher, or answers `busy` when
    /// [`EXEC_INFO_QUEUE`] requests wait already.
    fn exec_info(&self, reply: ReplyHandle) {
        match self.exec_info.try_take(1) {
            Some(permit) => {
                let _ = self.to_publisher.send(ToPublisher::ExecInfo(reply, permit));
            }
            None => {
                let n = self.exec_info.refused();
                if worth_logging(n) {
                    tracing::warn!(busy = n, "exec_info requests come faster than answered");
                }
                let busy = ErrorBody {
                    code: ErrorCode::Busy,
                    message: format!(
                        "{EXEC_INFO_QUEUE} exec_info requests wait already; retry in a moment"
                    ),
                };
                let _ = self.out.send(Outgoing::Reply(reply, Err(busy)));
            }
        }
    }
}

fn substitute(
    c: &UpdateContext,
    a: &cetratus_proto::SubstituteArgs,
) -> Result<SubstituteRequest, String> {
    let mode = a.mode.unwrap_or_default();
    // The protocol refuses a longer wait already; checked again here, where the multiplication
    // is, so that no path can make it overflow.
    if let Some(e) = a.within_ms.and_then(within_error) {
        return Err(e);
    }
    c.substitute_request(
        mode,
        a.when.as_deref(),
        a.within_ms.map(|ms| ms.saturating_mul(1000)),
        a.force,
    )
    .map_err(|e| e.to_string())
}

fn publish_loop(
    rx: Receiver<ToPublisher>,
    out: SyncSender<Outgoing>,
    quality: QualitySource,
    own: OwnFacts,
) {
    // The figures of the latest snapshot, shared by every `exec_info` answer until the next.
    let mut latest: Option<Arc<ExecInfoMsg>> = None;
    // Requests that came before the first snapshot, bounded by their permits.
    let mut early: Vec<(ReplyHandle, Permit)> = Vec::new();
    while let Ok(msg) = rx.recv() {
        let (s, _permit) = match msg {
            ToPublisher::ExecInfo(reply, permit) => {
                match &latest {
                    Some(info) => {
                        if out
                            .send(Outgoing::ExecInfoReply(reply, info.clone()))
                            .is_err()
                        {
                            return;
                        }
                    }
                    None => early.push((reply, permit)),
                }
                continue;
            }
            ToPublisher::Snapshot(s, permit) => (s, permit),
        };
        // The labels and the policy are the publisher's to add: the scan thread never copies
        // them.
        let mut state = s.state;
        state.labels.clone_from(&own.labels);
        state.updates = Some(own.updates);
        if out.send(Outgoing::State(Box::new(state))).is_err() {
            return;
        }
        let devices = quality
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .as_ref()
            .map(|r| wire::input_quality(&r()))
            .unwrap_or_default();
        let info = Arc::new(ExecInfoMsg(s.exec_info.map(|e| {
            e.as_ref().map(|e| {
                let mut w = wire::exec_info(e);
                w.input_quality.clone_from(&devices);
                w
            })
        })));
        let _ = out.send(Outgoing::ExecInfo(Box::new((*info).clone())));
        for (reply, _permit) in early.drain(..) {
            let _ = out.send(Outgoing::ExecInfoReply(reply, info.clone()));
        }
        latest = Some(info);
        let io = IoMsg {
            dispatched: wire::signals(&s.names_out, &s.dispatched),
            inputs: wire::signals(&s.names_in, &s.inputs),
            names: IoNames {
                inputs: s.names_in.to_vec(),
                outputs: s.names_out.to_vec(),
            },
            outputs_a: s.outputs[0]
                .as_ref()
                .map(|o| wire::signals(&s.names_out, o)),
            outputs_b: s.outputs[1]
                .as_ref()
                .map(|o| wire::signals(&s.names_out, o)),
            samples: s.samples,
            time_ms: s.time_us / 1000,
            unix_ms: None,
        };
        let _ = out.send(Outgoing::Io(io));
        if let Some(programs) = s.programs {
            let _ = out.send(Outgoing::Net(wire::net(&programs)));
        }
    }
}
