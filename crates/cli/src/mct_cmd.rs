//! `cetratus mct`: the dashboard on its own, watching every PLC on a broker.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use anyhow::Context;

/// Arguments of `cetratus mct`.
#[derive(clap::Args, Debug)]
pub struct MctArgs {
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
}

/// Runs `cetratus mct` until Ctrl-C.
pub fn run(args: &MctArgs) -> anyhow::Result<()> {
    let http = args.http.parse().with_context(|| {
        format!(
            "--http `{}`: expected an address such as 127.0.0.1:8080",
            args.http
        )
    })?;
    let d = cetratus_dashboard::serve(cetratus_dashboard::DashboardConfig {
        http,
        broker_url: args.broker.clone(),
        user: args.user.clone(),
        password: args.password.clone(),
    })?;
    println!(
        "dashboard on http://{}/ watching {}; Ctrl-C stops",
        d.local_addr(),
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
