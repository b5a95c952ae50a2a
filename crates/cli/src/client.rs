//! The CLI's client commands: `load`, `substitute`, `remove`, `abort`, `reset`, `status`, `watch`
//! and `exec-info`, spoken over MQTT 5 request/reply to a PLC.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{bail, Context};
use base64::Engine as _;
use cetratus_mct::client::{Message, OperatorKey, Outcome, Session, SessionConfig};
use cetratus_proto::{
    Command, EventMsg, ExecInfoMsg, Leaf, PlcId, ProgramInfo, Reply, Slot, StatePayload,
    SubstituteMode,
};
use serde_json::{json, Value};

use crate::mqtt_args::MqttArgs;

/// Options every client command takes.
#[derive(clap::Args, Debug, Clone)]
pub struct ClientOpts {
    /// Which PLC and which broker.
    #[command(flatten)]
    pub mqtt: MqttArgs,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// How long to wait for the PLC.
    #[arg(long, default_value = "10s")]
    pub timeout: String,
    /// Sign commands with this operator key (`cetratus package keygen` makes one); needed when
    /// the PLC has operator keys configured.
    #[arg(long)]
    pub key: Option<PathBuf>,
}

/// `cetratus load PKG`.
#[derive(clap::Args, Debug)]
pub struct LoadArgs {
    /// The update package file.
    pub package: PathBuf,
    #[command(flatten)]
    opts: ClientOpts,
}

/// `cetratus substitute`.
#[derive(clap::Args, Debug)]
pub struct SubstituteArgs {
    /// retransform (default) or keep.
    #[arg(long)]
    mode: Option<String>,
    /// Wait until this condition over the primary holds, e.g. `P10 == 1 && P20 == 1`.
    #[arg(long)]
    when: Option<String>,
    /// Give up waiting after this long, e.g. `30s` (at most `24h`).
    #[arg(long)]
    within: Option<String>,
    /// Keep the candidate's marking even with drift.
    #[arg(long)]
    force: bool,
    #[command(flatten)]
    opts: ClientOpts,
}

/// Commands with no argument: `remove`, `abort`, `reset`, `status`, `watch`, `exec-info`.
#[derive(clap::Args, Debug)]
pub struct PlainArgs {
    #[command(flatten)]
    opts: ClientOpts,
}

/// The operator key at `path`, which signs commands; `None` without a path.
pub fn operator_key(path: Option<&std::path::Path>) -> anyhow::Result<Option<OperatorKey>> {
    let Some(p) = path else {
        return Ok(None);
    };
    let k = cetratus_program::KeyPair::load(p)
        .with_context(|| format!("operator key {}", p.display()))?;
    Ok(Some(OperatorKey {
        id: k.key_id(),
        key: k.signing_key().clone(),
    }))
}

/// Opens a session with the PLC the options name.
fn open(opts: &ClientOpts) -> anyhow::Result<Session> {
    let key = operator_key(opts.key.as_deref())?;
    Ok(Session::open(SessionConfig {
        url: opts.mqtt.client_url()?,
        credentials: opts.mqtt.to.credentials(),
        plc: PlcId::new(opts.mqtt.plc_id())?,
        timeout: Duration::from_micros(crate::parse_duration_us(&opts.timeout)?),
        key,
    })?)
}

fn print_reply(reply: &Reply, json: bool) -> anyhow::Result<()> {
    let verb = &reply.verb;
    if json {
        println!("{}", serde_json::to_string_pretty(reply)?);
    }
    match &reply.error {
        None if reply.ok => {
            if !json {
                println!("{verb}: accepted");
            }
            Ok(())
        }
        Some(e) => bail!("{verb} refused: {} ({})", e.message, e.code),
        None => bail!("{verb} refused: no reason given (error)"),
    }
}

/// A command the PLC accepted whose outcome did not come within `--timeout`; the binary exits
/// with [`StillPending::EXIT_CODE`] (docs/operations.md).
#[derive(Debug)]
pub struct StillPending(String);

impl StillPending {
    /// The exit code of a command still pending.
    pub const EXIT_CODE: u8 = 3;
}

impl std::fmt::Display for StillPending {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for StillPending {}

/// Sends `command`, waits for its outcome event and prints it: success when it took effect, an
/// error when it was refused or failed, [`StillPending`] when `--timeout` ran out first.
fn send_and_follow(s: &mut Session, command: &Command, json: bool) -> anyhow::Result<()> {
    let verb = command.verb();
    let outcome = s.command(command)?;
    let (name, reply, event) = match &outcome {
        Outcome::Refused(r) => ("refused", r, None),
        Outcome::Done { reply, event } => ("done", reply, Some(event)),
        Outcome::Failed { reply, event } => ("failed", reply, Some(event)),
        Outcome::Pending { reply } => ("pending", reply, None),
        Outcome::Replied(r) => ("done", r, None),
    };
    if json {
        let out = json!({ "verb": verb.as_str(), "outcome": name, "reply": reply, "event": event });
        println!("{}", serde_json::to_string_pretty(&out)?);
    }
    match outcome {
        Outcome::Refused(r) => match r.error {
            Some(e) => bail!("{verb} refused: {} ({})", e.message, e.code),
            None => bail!("{verb} refused: no reason given (error)"),
        },
        Outcome::Done { event, .. } => {
            if !json {
                println!("{verb}: {}: {}", event.kind, event.message);
            }
            Ok(())
        }
        Outcome::Failed { event, .. } => bail!("{verb} failed: {}: {}", event.kind, event.message),
        Outcome::Pending { .. } => Err(StillPending(format!(
            "{verb} accepted, and still pending after {:?}: no outcome yet; follow it with \
             `cetratus watch`, or cancel the update with `cetratus abort`",
            s.timeout()
        ))
        .into()),
        Outcome::Replied(_) => Ok(()),
    }
}

/// `cetratus load PKG`: sends the package and follows the update until quarantine or refusal.
pub fn load(args: &LoadArgs) -> anyhow::Result<()> {
    let bytes = std::fs::read(&args.package)
        .with_context(|| format!("cannot read {}", args.package.display()))?;
    let quiet = args.opts.json;
    if !quiet {
        eprintln!("read {} ({} bytes)", args.package.display(), bytes.len());
    }
    let mut s = open(&args.opts)?;
    if !quiet {
        eprintln!(
            "sending to {} and waiting for the install at the next cycle boundary …",
            s.topics().prefix().trim_end_matches('/')
        );
    }
    let package_b64 = base64::engine::general_purpose::STANDARD.encode(&bytes);
    let command = Command::Load(cetratus_proto::LoadArgs { package_b64 });
    send_and_follow(&mut s, &command, quiet)
}

/// `cetratus substitute`: waits until the substitution happens, is refused or gives up.
pub fn substitute(args: &SubstituteArgs) -> anyhow::Result<()> {
    let within_ms = match &args.within {
        Some(w) => {
            let us = crate::parse_duration_us(w)
                .map_err(|e| anyhow::anyhow!("--within {w}: {e}; the longest wait is 24 h"))?;
            let ms = us / 1000;
            if ms > cetratus_proto::MAX_WITHIN_MS {
                bail!("--within {w} is longer than the longest wait, 24 h; give a shorter one");
            }
            Some(ms)
        }
        None => None,
    };
    let mode = match &args.mode {
        Some(m) => Some(m.parse::<SubstituteMode>()?),
        None => None,
    };
    let mut s = open(&args.opts)?;
    let command = Command::Substitute(cetratus_proto::SubstituteArgs {
        force: args.force,
        mode,
        when: args.when.clone(),
        within_ms,
    });
    send_and_follow(&mut s, &command, args.opts.json)
}

/// `remove`, `abort` and `reset`: each waits for its event (`removed`, `aborted`, `reset`).
pub fn plain(command: Command, args: &PlainArgs) -> anyhow::Result<()> {
    let mut s = open(&args.opts)?;
    send_and_follow(&mut s, &command, args.opts.json)
}

/// `cetratus status`: the retained state.
pub fn status(args: &PlainArgs) -> anyhow::Result<()> {
    let mut s = open(&args.opts)?;
    s.subscribe(Leaf::State)?;
    let Some(Message { payload: v, .. }) = s.next_message(Some(s.timeout()))? else {
        bail!(
            "no state from {} within {:?}; check --plc",
            s.topics().prefix().trim_end_matches('/'),
            s.timeout()
        );
    };
    if args.opts.json {
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    print_state(v);
    Ok(())
}

/// Prints a `state` payload; one this client cannot read (a PLC of another version) is printed
/// as it came, with why.
fn print_state(v: Value) {
    let state = match serde_json::from_value::<StatePayload>(v.clone()) {
        Ok(StatePayload::Online(state)) => state,
        Ok(StatePayload::Offline) => {
            println!("offline");
            return;
        }
        Err(e) => {
            println!("state (not read: {e}): {v}");
            return;
        }
    };
    let prog = |p: Option<&ProgramInfo>| match p {
        None => "(empty)".to_string(),
        Some(p) => format!("{} {} ({})", p.name, p.version, short_hash(&p.hash)),
    };
    println!("PRIMARY {}   STATUS {}", state.primary, state.status);
    println!("  A  {}", prog(state.programs.get(Slot::A)));
    println!("  B  {}", prog(state.programs.get(Slot::B)));
    let c = &state.cycle;
    println!(
        "  cycles {}  scan p99 {} ns  overruns {}",
        c.cycles, c.scan.p99_ns, c.overruns
    );
    if let Some(f) = &state.persist_fault {
        let saved = f.saved_cycle.map_or("none".into(), |c| c.to_string());
        println!(
            "  PERSISTENCE FAULT since cycle {}: {} (last saved: cycle {saved})",
            f.since_cycle, f.error
        );
    }
}

/// The first twelve digits of a program hash.
fn short_hash(hash: &str) -> &str {
    hash.get(..12).unwrap_or(hash)
}

/// `cetratus watch`: state changes and events as they happen.
pub fn watch(args: &PlainArgs) -> anyhow::Result<()> {
    let mut s = open(&args.opts)?;
    s.subscribe(Leaf::State)?;
    s.subscribe(Leaf::Events)?;
    while let Some(Message { leaf, payload: v }) = s.next_message(None)? {
        if args.opts.json {
            println!("{}", json!({ "topic": leaf, "payload": v }));
        } else if leaf == Leaf::Events.as_str() {
            match serde_json::from_value::<EventMsg>(v.clone()) {
                Ok(e) => println!(
                    "{:>10.3} s  {:<20} {}",
                    e.time_us.unwrap_or(0) as f64 / 1e6,
                    e.kind.to_string(),
                    e.message
                ),
                Err(e) => println!("event (not read: {e}): {v}"),
            }
        } else {
            print_state(v);
        }
    }
    Ok(())
}

/// `cetratus exec-info`: program_exec_info of both containers.
pub fn exec_info(args: &PlainArgs) -> anyhow::Result<()> {
    let mut s = open(&args.opts)?;
    let reply = s.request(&Command::ExecInfo)?;
    if args.opts.json || !reply.ok {
        return print_reply(&reply, true);
    }
    let result = reply.result.unwrap_or(Value::Null);
    let info: ExecInfoMsg = match serde_json::from_value(result.clone()) {
        Ok(info) => info,
        Err(e) => {
            println!("exec_info (not read: {e}): {result}");
            return Ok(());
        }
    };
    for c in info.0.iter().flatten() {
        println!(
            "{} ({}): {} {}  cycles {}  scan mean {} ns p99 {} ns  drift {}  deadlock {}",
            c.container,
            c.role,
            c.program.name,
            c.program.version,
            c.cycles,
            c.scan.mean_ns,
            c.scan.p99_ns,
            c.drift,
            c.deadlock
        );
        if !c.divergence.is_empty() {
            println!("   divergence {}", json!(c.divergence));
        }
        if let Some(cause) = &c.first_cause {
            println!("   cause      {cause}");
        }
    }
    Ok(())
}
