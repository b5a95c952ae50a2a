//! The node's side of the MQTT control plane: what the scan thread meets of MQTT.
//!
//! Three threads, joined by bounded queues; the scan thread never blocks:
//! * the **scan thread** runs the cycle at absolute deadlines, takes ready commands with
//!   `try_recv`, and hands snapshots and events on with `try_send`;
//! * the **preparer** turns MQTT commands into runtime commands: it verifies and builds update
//!   packages and compiles `substitute --when` conditions, away from the scan thread;
//! * the **publisher** turns snapshots into `state`, `exec_info`, `io` and `net` messages.

use std::collections::VecDeque;
use std::sync::atomic::AtomicBool;
use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TrySendError};
use std::sync::Arc;

use cetratus_mct::{accepted, refused, IncomingCommand, MctLink, Outgoing, Request};
use cetratus_program::{Program, TrustStore, Value};
use cetratus_proto::{EventMsg, IoMsg, IoNames, StateMsg};
use cetratus_runtime::monitor::CycleRecord;
use cetratus_runtime::{
    Command, Event, ExecInfo, LoopTiming, Plc, Slot, Status, SubstituteMode, SubstituteRequest,
    UpdateContext,
};
use serde_json::json;

use crate::wire;

enum ToScan {
    Command(Box<Command>, IncomingCommand),
    ExecInfo(IncomingCommand),
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
    samples: Vec<CycleRecord>,
    programs: Option<[Option<ProgramAndMarking>; 2]>,
    time_us: u64,
}

/// The scan thread's side of MQTT: call [`ControlLink::take_commands`] before each cycle and
/// [`ControlLink::after_cycle`] after it. Neither blocks.
pub struct ControlLink {
    to_scan_rx: Receiver<ToScan>,
    ctx_tx: SyncSender<UpdateContext>,
    snap_tx: Option<SyncSender<Snapshot>>,
    outgoing: SyncSender<Outgoing>,
    pending: VecDeque<Outgoing>,
    names_in: Arc<Vec<String>>,
    names_out: Arc<Vec<String>>,
    last_key: (Slot, Status, String, String),
    last_sampled: u64,
    first: bool,
    publish_every: u64,
    done: Arc<AtomicBool>,
    threads: Vec<std::thread::JoinHandle<()>>,
}

impl ControlLink {
    /// Starts the preparer and the publisher for `plc` on `link`.
    pub fn start(
        plc: &Plc,
        link: MctLink,
        trust: TrustStore,
        allow_unsigned: bool,
        publish_every: u64,
    ) -> ControlLink {
        let MctLink { commands, outgoing } = link;
        let (to_scan_tx, to_scan_rx) = sync_channel::<ToScan>(32);
        let (ctx_tx, ctx_rx) = sync_channel::<UpdateContext>(4);
        let (snap_tx, snap_rx) = sync_channel::<Snapshot>(2);
        let _ = ctx_tx.try_send(plc.update_context());
        let prep_out = outgoing.clone();
        let done = Arc::new(AtomicBool::new(false));
        let prep_done = done.clone();
        let preparer = std::thread::Builder::new()
            .name("cetratus-prepare".into())
            .spawn(move || {
                prepare_loop(
                    commands,
                    ctx_rx,
                    to_scan_tx,
                    prep_out,
                    trust,
                    allow_unsigned,
                    prep_done,
                )
            })
            .expect("spawn the preparer");
        let pub_out = outgoing.clone();
        let publisher = std::thread::Builder::new()
            .name("cetratus-publish".into())
            .spawn(move || publish_loop(snap_rx, pub_out))
            .expect("spawn the publisher");
        ControlLink {
            to_scan_rx,
            ctx_tx,
            snap_tx: Some(snap_tx),
            outgoing,
            pending: VecDeque::with_capacity(256),
            names_in: Arc::new(plc.io_inputs().to_vec()),
            names_out: Arc::new(plc.io_outputs().to_vec()),
            last_key: (Slot::A, Status::Idle, String::new(), String::new()),
            last_sampled: 0,
            first: true,
            publish_every: publish_every.max(1),
            done,
            threads: vec![preparer, publisher],
        }
    }

    /// Gives the PLC the commands that are ready. Returns who sent the last one, for the audit
    /// log (`mqtt` or `mqtt:<key id>`), when there was one.
    pub fn take_commands(&mut self, plc: &mut Plc) -> Option<String> {
        let mut who = None;
        while let Ok(msg) = self.to_scan_rx.try_recv() {
            match msg {
                ToScan::Command(cmd, from) => {
                    let outcome = match plc.command(*cmd) {
                        Ok(()) => accepted(),
                        Err(e) => Err(refused(e.to_string())),
                    };
                    who = Some(
                        from.key_id
                            .as_ref()
                            .map_or("mqtt".to_string(), |k| format!("mqtt:{k}")),
                    );
                    self.pending.push_back(Outgoing::Reply(from.reply, outcome));
                }
                ToScan::ExecInfo(from) => {
                    let info = serde_json::to_value(wire::exec_info_msg(plc)).ok();
                    self.pending
                        .push_back(Outgoing::Reply(from.reply, Ok(info)));
                }
            }
        }
        who
    }

    /// Queues events (those of a command taken between cycles) for publication.
    pub fn queue_events(&mut self, events: &[Event]) {
        for e in events {
            self.pending.push_back(Outgoing::Event(wire::event(e)));
        }
    }

    /// Publishes the cycle's events, and a snapshot when one is due or something changed.
    pub fn after_cycle(&mut self, plc: &Plc, events: &[Event], timing: &LoopTiming, now: u64) {
        self.queue_events(events);
        let hash = |s: Slot| {
            plc.container(s)
                .map_or(String::new(), |c| c.program().hash_hex().to_string())
        };
        let key = (plc.primary(), plc.status(), hash(Slot::A), hash(Slot::B));
        let changed = key != self.last_key;
        if changed {
            if key.0 != self.last_key.0 || key.2 != self.last_key.2 || key.3 != self.last_key.3 {
                let _ = self.ctx_tx.try_send(plc.update_context());
            }
            self.last_key = key;
        }
        if self.first || changed || plc.cycles() % self.publish_every == 0 {
            let since = self.last_sampled;
            let samples: Vec<CycleRecord> = plc
                .monitor()
                .recent
                .iter()
                .filter(|r| r.cycle >= since)
                .copied()
                .collect();
            self.last_sampled = plc.cycles();
            let snap = Snapshot {
                state: wire::state(plc, timing),
                exec_info: plc.exec_info(),
                names_in: self.names_in.clone(),
                names_out: self.names_out.clone(),
                inputs: plc.inputs().to_vec(),
                outputs: [Slot::A, Slot::B].map(|s| plc.outputs_of(s).map(<[Value]>::to_vec)),
                dispatched: plc.dispatched().to_vec(),
                samples,
                programs: (self.first || changed).then(|| {
                    [Slot::A, Slot::B].map(|s| {
                        plc.container(s)
                            .map(|c| (c.program().clone(), c.marking().to_vec()))
                    })
                }),
                time_us: now,
            };
            self.first = false;
            if let Some(tx) = &self.snap_tx {
                // When the publisher is behind this snapshot is dropped; the next one carries on.
                let _ = tx.try_send(snap);
            }
        }
        while let Some(m) = self.pending.pop_front() {
            if let Err(back) = try_out(&self.outgoing, m) {
                self.pending.push_front(back);
                break;
            }
        }
    }

    /// Stops the preparer and the publisher.
    pub fn stop(mut self) {
        self.snap_tx = None;
        self.done.store(true, std::sync::atomic::Ordering::Release);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

#[allow(clippy::result_large_err)]
fn try_out(tx: &SyncSender<Outgoing>, m: Outgoing) -> Result<(), Outgoing> {
    tx.try_send(m).map_err(|e| match e {
        TrySendError::Full(m) | TrySendError::Disconnected(m) => m,
    })
}

fn prepare_loop(
    commands: Receiver<IncomingCommand>,
    ctx_rx: Receiver<UpdateContext>,
    to_scan: SyncSender<ToScan>,
    out: SyncSender<Outgoing>,
    trust: TrustStore,
    allow_unsigned: bool,
    done: Arc<AtomicBool>,
) {
    let mut ctx: Option<UpdateContext> = None;
    loop {
        let cmd = match commands.recv_timeout(std::time::Duration::from_millis(200)) {
            Ok(c) => c,
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
                if done.load(std::sync::atomic::Ordering::Acquire) {
                    return;
                }
                while let Ok(c) = ctx_rx.try_recv() {
                    ctx = Some(c);
                }
                continue;
            }
            Err(_) => return,
        };
        while let Ok(c) = ctx_rx.try_recv() {
            ctx = Some(c);
        }
        let Some(c) = ctx.as_ref() else {
            let _ = out.send(Outgoing::Reply(
                cmd.reply,
                Err(refused("the PLC is starting; try again")),
            ));
            continue;
        };
        let prepared: Result<ToScan, String> = match &cmd.request {
            Request::Load { package } => c
                .prepare_package(package, &trust, allow_unsigned, false)
                .map_err(|e| e.to_string())
                .map(|p| ToScan::Command(Box::new(Command::Load(Box::new(p))), cmd.clone())),
            Request::Substitute(a) => substitute(c, a)
                .map(|s| ToScan::Command(Box::new(Command::Substitute(s)), cmd.clone())),
            Request::Remove => Ok(ToScan::Command(Box::new(Command::Remove), cmd.clone())),
            Request::Abort => Ok(ToScan::Command(Box::new(Command::Abort), cmd.clone())),
            Request::Reset => Ok(ToScan::Command(Box::new(Command::Reset), cmd.clone())),
            Request::ExecInfo => Ok(ToScan::ExecInfo(cmd.clone())),
        };
        match prepared {
            Ok(m) => {
                if to_scan.send(m).is_err() {
                    return;
                }
            }
            Err(reason) => {
                let _ = out.send(Outgoing::Event(EventMsg {
                    cycle: None,
                    time_us: None,
                    kind: "refused".into(),
                    message: reason.clone(),
                    detail: json!({"verb": cmd.request.verb(), "key_id": cmd.key_id}),
                }));
                let _ = out.send(Outgoing::Reply(cmd.reply, Err(refused(reason))));
            }
        }
    }
}

fn substitute(
    c: &UpdateContext,
    a: &cetratus_proto::SubstituteArgs,
) -> Result<SubstituteRequest, String> {
    let mode = match a.mode {
        None | Some(cetratus_proto::SubstituteMode::Retransform) => SubstituteMode::Retransform,
        Some(cetratus_proto::SubstituteMode::Keep) => SubstituteMode::Keep,
    };
    c.substitute_request(
        mode,
        a.when.as_deref(),
        a.within_ms.map(|ms| ms * 1000),
        a.force,
    )
    .map_err(|e| e.to_string())
}

fn publish_loop(rx: Receiver<Snapshot>, out: SyncSender<Outgoing>) {
    while let Ok(s) = rx.recv() {
        if out.send(Outgoing::State(Box::new(s.state))).is_err() {
            return;
        }
        let info =
            cetratus_proto::ExecInfoMsg(s.exec_info.map(|e| e.as_ref().map(wire::exec_info)));
        let _ = out.send(Outgoing::ExecInfo(Box::new(info)));
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
            samples: s.samples.iter().map(wire::sample).collect(),
            time_ms: s.time_us / 1000,
            unix_ms: None,
        };
        let _ = out.send(Outgoing::Io(io));
        if let Some(programs) = s.programs {
            let _ = out.send(Outgoing::Net(wire::net(&programs)));
        }
    }
}
