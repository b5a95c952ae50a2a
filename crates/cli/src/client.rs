//! The CLI client of the MCT: `load`, `substitute`, `remove`, `abort`, `reset`, `status`, `watch`
//! and `exec-info`, spoken over MQTT 5 request/reply to a PLC.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use base64::Engine as _;
use rumqttc::v5::mqttbytes::v5::{Packet, PublishProperties};
use rumqttc::v5::mqttbytes::QoS;
use rumqttc::v5::{Client, Connection, Event};
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
    /// Give up waiting after this long, e.g. `30s`.
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

struct Session {
    client: Client,
    conn: Connection,
    prefix: String,
    deadline: Duration,
    key: Option<cetratus_program::KeyPair>,
}

impl Session {
    fn open(opts: &ClientOpts) -> anyhow::Result<Self> {
        let url = opts.mqtt.client_url()?;
        let id = format!(
            "cetratus-cli-{}-{}",
            std::process::id(),
            Instant::now().elapsed().as_nanos()
        );
        let mut o = cetratus_mct::client_options(&url, &id)?;
        if let Some(u) = &opts.mqtt.user {
            o.set_credentials(u.clone(), opts.mqtt.password.clone().unwrap_or_default());
        }
        o.set_keep_alive(Duration::from_secs(10));
        o.set_max_packet_size(Some(8 << 20));
        let (client, conn) = Client::new(o, 64);
        let deadline = Duration::from_micros(crate::parse_duration_us(&opts.timeout)?);
        let key = match &opts.key {
            Some(p) => Some(
                cetratus_program::KeyPair::load(p)
                    .with_context(|| format!("operator key {}", p.display()))?,
            ),
            None => None,
        };
        let mut s = Session {
            client,
            conn,
            prefix: format!("cetratus/{}/", opts.mqtt.plc_id()),
            deadline,
            key,
        };
        s.wait_for(|e| matches!(e, Packet::ConnAck(_)))
            .with_context(|| format!("cannot reach the broker at {url}; is the PLC running? (--broker URL or --mqtt ADDR)"))?;
        Ok(s)
    }

    fn subscribe(&mut self, leaf: &str) -> anyhow::Result<()> {
        let topic = format!("{}{leaf}", self.prefix);
        self.client.subscribe(topic, QoS::AtLeastOnce)?;
        self.wait_for(|p| matches!(p, Packet::SubAck(_)))
    }

    fn wait_for(&mut self, mut f: impl FnMut(&Packet) -> bool) -> anyhow::Result<()> {
        let end = Instant::now() + self.deadline;
        loop {
            let left = end.saturating_duration_since(Instant::now());
            if left.is_zero() {
                bail!("timed out after {:?}", self.deadline);
            }
            match self.conn.recv_timeout(left) {
                Ok(Ok(Event::Incoming(p))) if f(&p) => return Ok(()),
                Ok(Ok(_)) => {}
                Ok(Err(e)) => bail!("MQTT connection: {e}"),
                Err(_) => bail!("timed out after {:?}", self.deadline),
            }
        }
    }

    /// The next message on a subscribed topic: (leaf, JSON payload).
    fn next_message(&mut self, wait: Option<Duration>) -> anyhow::Result<Option<(String, Value)>> {
        let end = wait.map(|w| Instant::now() + w);
        loop {
            let r = match end {
                Some(end) => {
                    let left = end.saturating_duration_since(Instant::now());
                    if left.is_zero() {
                        return Ok(None);
                    }
                    match self.conn.recv_timeout(left) {
                        Ok(r) => r,
                        Err(_) => return Ok(None),
                    }
                }
                None => match self.conn.recv() {
                    Ok(r) => r,
                    Err(_) => return Ok(None),
                },
            };
            match r {
                Ok(Event::Incoming(Packet::Publish(p))) => {
                    let topic = String::from_utf8_lossy(&p.topic).to_string();
                    let leaf = topic
                        .strip_prefix(&self.prefix)
                        .unwrap_or(&topic)
                        .to_string();
                    let v = serde_json::from_slice(&p.payload).unwrap_or(Value::Null);
                    return Ok(Some((leaf, v)));
                }
                Ok(_) => {}
                Err(e) => bail!("MQTT connection: {e}"),
            }
        }
    }

    /// Sends `cmd/<verb>` with a response topic and correlation data; returns the reply.
    fn request(&mut self, verb: &str, payload: Value) -> anyhow::Result<Value> {
        let reply_leaf = format!("reply/cli-{}", std::process::id());
        self.subscribe(&reply_leaf)?;
        let corr = format!("{verb}-{}", std::process::id());
        let props = PublishProperties {
            response_topic: Some(format!("{}{reply_leaf}", self.prefix)),
            correlation_data: Some(corr.clone().into_bytes().into()),
            content_type: Some("application/json".into()),
            ..Default::default()
        };
        let body = match &self.key {
            // A signed envelope: ed25519 over the verb, the payload's hash, the time and a nonce.
            Some(k) => {
                let inner = serde_json::to_vec(&payload)?;
                let nonce = format!(
                    "{}-{}",
                    std::process::id(),
                    Instant::now().elapsed().as_nanos() ^ u128::from(cetratus_mct::unix_now())
                );
                let env = cetratus_mct::sign(
                    verb,
                    &inner,
                    cetratus_mct::unix_now(),
                    &nonce,
                    &k.key_id(),
                    k.signing_key(),
                );
                serde_json::to_vec(&json!({ "envelope": env }))?
            }
            None => serde_json::to_vec(&payload)?,
        };
        self.client.publish_with_properties(
            format!("{}cmd/{verb}", self.prefix),
            QoS::AtLeastOnce,
            false,
            body,
            props,
        )?;
        let end = Instant::now() + self.deadline;
        while Instant::now() < end {
            if let Some((leaf, v)) = self.next_message(Some(end - Instant::now()))? {
                if leaf == reply_leaf {
                    return Ok(v);
                }
            }
        }
        bail!(
            "no reply from the PLC within {:?}; check --plc and that it is running",
            self.deadline
        )
    }
}

fn print_reply(verb: &str, reply: &Value, json: bool) -> anyhow::Result<()> {
    if json {
        println!("{}", serde_json::to_string_pretty(reply)?);
    }
    if reply["ok"] == Value::Bool(true) {
        if !json {
            println!("{verb}: accepted");
        }
        Ok(())
    } else {
        bail!(
            "{verb} refused: {} ({})",
            reply["error"]["message"]
                .as_str()
                .unwrap_or("no reason given"),
            reply["error"]["code"].as_str().unwrap_or("error")
        )
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
    let mut s = Session::open(&args.opts)?;
    s.subscribe("events")?;
    if !quiet {
        eprintln!("sending to {} …", s.prefix.trim_end_matches('/'));
    }
    let payload =
        json!({ "package_b64": base64::engine::general_purpose::STANDARD.encode(&bytes) });
    let reply = s.request("load", payload)?;
    print_reply("load", &reply, quiet)?;
    if !quiet {
        eprintln!("verified and accepted; waiting for the install at the next cycle boundary …");
    }
    let end = Instant::now() + s.deadline;
    while Instant::now() < end {
        if let Some((leaf, e)) = s.next_message(Some(end - Instant::now()))? {
            if leaf != "events" {
                continue;
            }
            let kind = e["kind"].as_str().unwrap_or("");
            let msg = e["message"].as_str().unwrap_or("");
            match kind {
                "quarantine_started" => {
                    if !quiet {
                        println!("{msg}");
                    }
                    return Ok(());
                }
                "state_trans_timeout" | "transform_refused" | "refused" => bail!("{msg}"),
                _ => {}
            }
        }
    }
    bail!(
        "the PLC accepted the package but did not report its install within {:?}",
        s.deadline
    )
}

/// `cetratus substitute`.
pub fn substitute(args: &SubstituteArgs) -> anyhow::Result<()> {
    let within_ms = match &args.within {
        Some(w) => Some(crate::parse_duration_us(w)? / 1000),
        None => None,
    };
    let mut s = Session::open(&args.opts)?;
    let payload = json!({ "mode": args.mode, "when": args.when, "within_ms": within_ms, "force": args.force });
    let reply = s.request("substitute", payload)?;
    print_reply("substitute", &reply, args.opts.json)
}

/// `remove`, `abort` and `reset`.
pub fn plain(verb: &str, args: &PlainArgs) -> anyhow::Result<()> {
    let mut s = Session::open(&args.opts)?;
    let reply = s.request(verb, json!({}))?;
    print_reply(verb, &reply, args.opts.json)
}

/// `cetratus status`: the retained state.
pub fn status(args: &PlainArgs) -> anyhow::Result<()> {
    let mut s = Session::open(&args.opts)?;
    s.subscribe("state")?;
    let Some((_, v)) = s.next_message(Some(s.deadline))? else {
        bail!(
            "no state from {} within {:?}; check --plc",
            s.prefix.trim_end_matches('/'),
            s.deadline
        );
    };
    if args.opts.json {
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    print_state(&v);
    Ok(())
}

fn print_state(v: &Value) {
    if v["online"] == Value::Bool(false) {
        println!("offline");
        return;
    }
    let prog = |p: &Value| {
        if p.is_null() {
            "(empty)".to_string()
        } else {
            format!(
                "{} {} ({})",
                p["name"].as_str().unwrap_or("?"),
                p["version"].as_str().unwrap_or("?"),
                &p["hash"].as_str().unwrap_or("")[..12.min(p["hash"].as_str().unwrap_or("").len())]
            )
        }
    };
    println!(
        "PRIMARY {}   STATUS {}",
        v["primary"].as_str().unwrap_or("?"),
        v["status"].as_str().unwrap_or("?")
    );
    println!("  A  {}", prog(&v["programs"]["A"]));
    println!("  B  {}", prog(&v["programs"]["B"]));
    println!(
        "  cycles {}  scan p99 {} ns  overruns {}",
        v["cycle"]["cycles"], v["cycle"]["scan"]["p99_ns"], v["cycle"]["overruns"]
    );
}

/// `cetratus watch`: state changes and events as they happen.
pub fn watch(args: &PlainArgs) -> anyhow::Result<()> {
    let mut s = Session::open(&args.opts)?;
    s.subscribe("state")?;
    s.subscribe("events")?;
    while let Some((leaf, v)) = s.next_message(None)? {
        if args.opts.json {
            println!("{}", json!({ "topic": leaf, "payload": v }));
        } else if leaf == "events" {
            println!(
                "{:>10.3} s  {:<20} {}",
                v["time_us"].as_f64().unwrap_or(0.0) / 1e6,
                v["kind"].as_str().unwrap_or(""),
                v["message"].as_str().unwrap_or("")
            );
        } else {
            print_state(&v);
        }
    }
    Ok(())
}

/// `cetratus exec-info`: program_exec_info of both containers.
pub fn exec_info(args: &PlainArgs) -> anyhow::Result<()> {
    let mut s = Session::open(&args.opts)?;
    let reply = s.request("exec_info", json!({}))?;
    if args.opts.json || reply["ok"] != Value::Bool(true) {
        return print_reply("exec_info", &reply, true);
    }
    for c in reply["result"]
        .as_array()
        .into_iter()
        .flatten()
        .filter(|c| !c.is_null())
    {
        println!(
            "{} ({}): {} {}  cycles {}  scan mean {} ns p99 {} ns  drift {}  deadlock {}",
            c["container"].as_str().unwrap_or("?"),
            c["role"].as_str().unwrap_or("?"),
            c["program"]["name"].as_str().unwrap_or("?"),
            c["program"]["version"].as_str().unwrap_or("?"),
            c["cycles"],
            c["scan"]["mean_ns"],
            c["scan"]["p99_ns"],
            c["drift"],
            c["deadlock"]
        );
        if let Some(d) = c["divergence"].as_object().filter(|d| !d.is_empty()) {
            println!("   divergence {}", Value::Object(d.clone()));
        }
        if let Some(cause) = c["first_cause"].as_str() {
            println!("   cause      {cause}");
        }
    }
    Ok(())
}
