//! The MQTT flags shared by `run`, `demo`, `mct` and the client commands.

use std::net::SocketAddr;

use anyhow::Context;
use cetratus_mct::{BrokerChoice, MctLink, MqttConfig};
use cetratus_node::config::LocalConfig;
use cetratus_node::link::ControlLink;

/// Where MQTT goes and who this PLC is.
#[derive(clap::Args, Debug, Clone)]
pub struct MqttArgs {
    /// The PLC id: topics live under `cetratus/<id>/`. Defaults to the host name.
    #[arg(long = "plc")]
    pub plc: Option<String>,
    /// Address of the embedded broker (the default, on 127.0.0.1:1883).
    #[arg(long)]
    pub mqtt: Option<String>,
    /// Use a plant broker instead of the embedded one: mqtt://host:port or mqtts://host:port.
    #[arg(long)]
    pub broker: Option<String>,
    /// User name for the plant broker.
    #[arg(long)]
    pub user: Option<String>,
    /// Password for the plant broker (or set CETRATUS_MQTT_PASSWORD).
    #[arg(long, env = "CETRATUS_MQTT_PASSWORD", hide_env_values = true)]
    pub password: Option<String>,
}

impl MqttArgs {
    /// The PLC id, defaulting to the host name.
    pub fn plc_id(&self) -> String {
        self.plc.clone().unwrap_or_else(|| {
            hostname::get()
                .ok()
                .and_then(|h| h.into_string().ok())
                .filter(|h| !h.is_empty())
                .unwrap_or_else(|| "cetratus".to_string())
        })
    }

    /// The MQTT configuration of a PLC node: broker accounts, plant-broker credentials and
    /// operator keys come from the local configuration; the command line overrides credentials.
    pub fn config(&self, local: &LocalConfig) -> anyhow::Result<MqttConfig> {
        let mut c = MqttConfig::new(&self.plc_id());
        let credentials = self
            .user
            .clone()
            .map(|u| (u, self.password.clone().unwrap_or_default()))
            .or_else(|| local.credentials.clone());
        c.broker = BrokerChoice::from_cli(
            self.mqtt.as_deref(),
            self.broker.as_deref(),
            local.users.clone(),
            local.mqtt_tls.clone(),
            credentials,
        )?;
        c.operator_keys = local.operators.clone();
        Ok(c)
    }

    /// The broker URL clients (the dashboard, the CLI client) connect to.
    pub fn client_url(&self) -> anyhow::Result<String> {
        if let Some(url) = &self.broker {
            return Ok(url.clone());
        }
        let addr: SocketAddr = self
            .mqtt
            .as_deref()
            .unwrap_or(cetratus_mct::DEFAULT_MQTT_ADDR)
            .parse()
            .context("--mqtt takes an address such as 127.0.0.1:1883")?;
        Ok(format!("mqtt://{addr}"))
    }
}

/// The MQTT client of a PLC node, and the dashboard beside it.
pub struct Services {
    mqtt: cetratus_mct::MqttHandle,
    dashboard: Option<cetratus_dashboard::DashboardHandle>,
    broker_url: String,
}

impl Services {
    /// Stops both.
    pub fn stop(self) {
        // The dashboard first: it is a client of the embedded broker, and would report losing it.
        if let Some(d) = self.dashboard {
            d.stop();
        }
        self.mqtt.shutdown();
    }

    /// The URL clients reach the broker at.
    pub fn broker_url(&self) -> &str {
        &self.broker_url
    }

    /// A new one-time login link to the dashboard, when it runs.
    pub fn dashboard_login_url(&self) -> anyhow::Result<Option<String>> {
        Ok(match &self.dashboard {
            Some(d) => Some(d.login_url()?),
            None => None,
        })
    }
}

/// What a node serves beside its MQTT client.
pub struct Wanted<'a> {
    /// The dashboard's address (`--http`), when it is served.
    pub dashboard: Option<&'a str>,
    /// Whether the broker's URL and the dashboard's login link are printed on stderr.
    pub announce: bool,
}

/// Starts MQTT (the embedded broker or a plant broker's client) and the dashboard when asked.
/// Called before the state directory is opened, so that a taken port stops a start before it
/// leaves any trace.
pub fn start_services(
    mqtt: &MqttArgs,
    local: &LocalConfig,
    wanted: Wanted<'_>,
) -> anyhow::Result<(MctLink, Services)> {
    let mut config = mqtt.config(local)?;
    config.publish_period = std::time::Duration::from_millis(200);
    let plc_id = config.plc_id.clone();
    let (link, handle) = cetratus_mct::start(config)?;
    // The embedded broker's own address: with `--mqtt 127.0.0.1:0` it picked its port itself.
    let broker_url = match handle.broker_addr() {
        Some(addr) if local.mqtt_tls.is_some() => format!("mqtts://{addr}"),
        Some(addr) => format!("mqtt://{addr}"),
        None => mqtt.client_url()?,
    };
    // The dashboard beside an embedded broker logs in with the login the broker drew for it, on
    // its loopback port; beside a plant broker, with the PLC's own credentials.
    let (dashboard_url, user, password) =
        match (handle.broker_local_addr(), handle.dashboard_login()) {
            (Some(addr), Some(login)) => (
                format!("mqtt://{addr}"),
                Some(login.user),
                Some(login.password),
            ),
            _ => {
                let creds = mqtt
                    .user
                    .clone()
                    .map(|u| (u, mqtt.password.clone()))
                    .or_else(|| local.credentials.clone().map(|(u, p)| (u, Some(p))));
                (
                    broker_url.clone(),
                    creds.as_ref().map(|c| c.0.clone()),
                    creds.and_then(|c| c.1),
                )
            }
        };
    let dashboard = if let Some(http) = wanted.dashboard {
        let http: SocketAddr = http.parse().with_context(|| {
            format!("--http `{http}`: expected an address such as 127.0.0.1:8080")
        })?;
        Some(cetratus_dashboard::serve(
            cetratus_dashboard::DashboardConfig {
                http,
                broker_url: dashboard_url,
                user,
                password,
                signer: None,
                access: access_config(local),
                tls: dashboard_tls(local),
            },
        )?)
    } else {
        None
    };
    if wanted.announce {
        match &dashboard {
            Some(d) => eprintln!(
                "MQTT {broker_url} (topics cetratus/{plc_id}/…), dashboard {}",
                d.login_url()?
            ),
            None => eprintln!("MQTT {broker_url} (topics cetratus/{plc_id}/…)"),
        }
    }
    Ok((
        link,
        Services {
            mqtt: handle,
            dashboard,
            broker_url,
        },
    ))
}

/// The dashboard's TLS certificate and key, from the `[dashboard]` section.
pub fn dashboard_tls(local: &LocalConfig) -> Option<cetratus_dashboard::DashboardTls> {
    local
        .dashboard_tls
        .clone()
        .map(|(cert, key)| cetratus_dashboard::DashboardTls { cert, key })
}

/// Who may log in to the dashboard, from the `[dashboard]` section of the local configuration.
pub fn access_config(local: &LocalConfig) -> cetratus_dashboard::AccessConfig {
    cetratus_dashboard::AccessConfig {
        accounts: local
            .dashboard_accounts
            .iter()
            .map(|(name, hash)| cetratus_dashboard::Account {
                name: name.clone(),
                password_hash: hash.clone(),
            })
            .collect(),
        hosts: local.dashboard_hosts.clone(),
    }
}

/// The node's side of MQTT for `plc`. Snapshots go out about five times a second of wall time,
/// whatever the speed.
pub fn control_link(
    link: MctLink,
    plc: &cetratus_runtime::Plc,
    load: cetratus_node::load::LoadPolicy,
    speed: f64,
    period_us: u64,
) -> ControlLink {
    let speed = if speed.is_finite() && speed > 0.0 {
        speed
    } else {
        1.0
    };
    let publish_every = ((200_000.0 * speed) / period_us.max(1) as f64)
        .round()
        .max(1.0) as u64;
    ControlLink::start(plc, link, load, publish_every)
}
