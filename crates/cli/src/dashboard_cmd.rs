//! `cetratus dashboard`: the dashboard on its own, watching every PLC on a broker.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use anyhow::Context;

/// Arguments of `cetratus dashboard`.
#[derive(clap::Args, Debug)]
pub struct DashboardArgs {
    /// Where the dashboard listens.
    #[arg(long, default_value = "127.0.0.1:8080")]
    http: String,
    /// The broker the PLCs publish on.
    #[arg(long, default_value = "mqtt://127.0.0.1:1883")]
    broker: String,
    /// Broker user name.
    #[arg(long)]
    user: Option<String>,
    /// Broker password (or set CETRATUS_MQTT_PASSWORD).
    #[arg(long, env = "CETRATUS_MQTT_PASSWORD", hide_env_values = true)]
    password: Option<String>,
    /// Sign the commands of the page with this operator key, for PLCs with operator keys.
    #[arg(long)]
    key: Option<std::path::PathBuf>,
    /// The local configuration directory, for its `[dashboard]` accounts.
    #[arg(long)]
    config: Option<std::path::PathBuf>,
    /// A directory of rollout plans (`*.toml`) that logged-in operators may start from the
    /// fleet page (docs/fleet.md).
    #[arg(long)]
    plans: Option<std::path::PathBuf>,
    /// The state directory of the page's rollouts.
    #[arg(long, default_value = "cetratus-rollout")]
    rollout_state: std::path::PathBuf,
}

/// Runs `cetratus dashboard` until Ctrl-C.
pub fn run(args: &DashboardArgs) -> anyhow::Result<()> {
    let http = args.http.parse().with_context(|| {
        format!(
            "--http `{}`: expected an address such as 127.0.0.1:8080",
            args.http
        )
    })?;
    let local = cetratus_node::config::LocalConfig::load(args.config.as_deref())?;
    let d = cetratus_dashboard::serve(cetratus_dashboard::DashboardConfig {
        http,
        broker_url: args.broker.clone(),
        user: args.user.clone(),
        password: args.password.clone(),
        signer: match &args.key {
            Some(path) => Some(signer(path)?),
            None => None,
        },
        access: crate::mqtt_args::access_config(&local),
        tls: crate::mqtt_args::dashboard_tls(&local),
        rollouts: rollouts(args)?,
    })?;
    println!(
        "dashboard on {} watching {}; Ctrl-C stops",
        d.login_url()?,
        args.broker
    );
    let stop = Arc::new(AtomicBool::new(false));
    let s = stop.clone();
    ctrlc::set_handler(move || s.store(true, Ordering::Relaxed))
        .context("cannot install the Ctrl-C handler")?;
    while !stop.load(Ordering::Relaxed) {
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    d.stop();
    Ok(())
}

/// The page's rollouts, when `--plans` is given: on the dashboard's broker, signed with its key.
fn rollouts(args: &DashboardArgs) -> anyhow::Result<Option<cetratus_dashboard::RolloutConfig>> {
    let Some(plans) = &args.plans else {
        return Ok(None);
    };
    anyhow::ensure!(
        plans.is_dir(),
        "--plans {}: not a directory; give the directory of the rollout plans (*.toml)",
        plans.display()
    );
    Ok(Some(cetratus_dashboard::RolloutConfig {
        plans: plans.clone(),
        state_dir: args.rollout_state.clone(),
        link: cetratus_fleet::LinkConfig {
            url: args.broker.clone(),
            credentials: (args.user.clone())
                .map(|u| (u, args.password.clone().unwrap_or_default())),
            key: crate::client::operator_key(args.key.as_deref())?,
            timeout: std::time::Duration::from_secs(10),
            account: None,
        },
    }))
}

/// `cetratus hash-password`: the first line of stdin (without its line end), hashed for
/// `[[dashboard.accounts]] password_hash`.
pub fn hash_password() -> anyhow::Result<()> {
    use std::io::IsTerminal as _;
    if std::io::stdin().is_terminal() {
        eprintln!("password (shown as typed; pipe it in to keep it off the screen):");
    }
    let mut line = String::new();
    std::io::stdin()
        .read_line(&mut line)
        .context("cannot read the password from stdin")?;
    let password = line.trim_end_matches(['\n', '\r']);
    anyhow::ensure!(
        !password.is_empty(),
        "no password on stdin: write it on the first line, e.g. `cetratus hash-password < file`"
    );
    let hash = cetratus_dashboard::hash_password(password)
        .map_err(|e| anyhow::anyhow!("cannot hash the password: {e}"))?;
    println!("{hash}");
    Ok(())
}

/// A signer for the dashboard's commands: a version-2 envelope (the PLC, the verb, the payload's
/// hash, the correlation data, the time and a nonce) with the operator key at `path`.
fn signer(path: &std::path::Path) -> anyhow::Result<cetratus_dashboard::CommandSigner> {
    let key = cetratus_program::KeyPair::load(path)
        .with_context(|| format!("operator key {}", path.display()))?;
    let key_id = key.key_id();
    let counter = std::sync::atomic::AtomicU64::new(0);
    Ok(cetratus_dashboard::CommandSigner(Arc::new(
        move |r: &cetratus_dashboard::SignRequest<'_>| {
            let n = counter.fetch_add(1, Ordering::Relaxed);
            let nonce = format!(
                "mct-{}-{}-{n}",
                std::process::id(),
                cetratus_mct::unix_now()
            );
            let signed = cetratus_mct::Signed {
                plc: r.plc,
                verb: r.verb,
                correlation: r.correlation,
                timestamp: cetratus_mct::unix_now(),
                nonce: &nonce,
                account: Some(r.account),
            };
            let env = cetratus_mct::sign(&signed, r.payload, &key_id, key.signing_key());
            serde_json::to_value(env).unwrap_or(serde_json::Value::Null)
        },
    )))
}
