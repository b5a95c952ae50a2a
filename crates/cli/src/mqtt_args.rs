//! The MQTT flags shared by `run`, `demo`, `dashboard` and the client commands, and the dashboard
//! as a node's companion.

use std::net::SocketAddr;

use anyhow::Context;
use cetratus_node::config::LocalConfig;
use cetratus_node::services::{BrokerAccess, Companion, CompanionStart, MqttSpec};

/// Where MQTT goes and who this PLC is.
#[derive(clap::Args, Debug, Clone)]
pub struct MqttArgs {
    /// The PLC id: topics live under `cetratus/<id>/`. Defaults to the host name.
    #[arg(long = "plc")]
    pub plc: Option<String>,
    /// The broker.
    #[command(flatten)]
    pub to: BrokerArgs,
}

/// Which broker, and who logs in to it.
#[derive(clap::Args, Debug, Clone)]
pub struct BrokerArgs {
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

impl BrokerArgs {
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

    /// `--user` and its password (empty when none is given), when a user is given.
    pub fn credentials(&self) -> Option<(String, String)> {
        (self.user.clone()).map(|u| (u, self.password.clone().unwrap_or_default()))
    }
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

    /// How a node reaches MQTT: the flags, the dashboard at `dashboard` (`--http`) when it is
    /// served, and whether the broker's URL and the dashboard's link are announced.
    pub fn spec(
        &self,
        local: &LocalConfig,
        dashboard: Option<&str>,
        announce: bool,
    ) -> anyhow::Result<MqttSpec> {
        let companion = match dashboard {
            Some(http) => Some(dashboard_companion(http, local)?),
            None => None,
        };
        Ok(MqttSpec {
            embedded: self.to.mqtt.clone(),
            broker: self.to.broker.clone(),
            login: self.to.user.clone().map(|u| (u, self.to.password.clone())),
            companion,
            announce,
        })
    }

    /// The broker URL clients (the dashboard, the CLI client) connect to.
    pub fn client_url(&self) -> anyhow::Result<String> {
        self.to.client_url()
    }
}

/// The dashboard as a node's companion.
struct Dashboard(cetratus_dashboard::DashboardHandle);

impl Companion for Dashboard {
    fn link(&self) -> Option<String> {
        self.0.login_url().ok()
    }

    fn stop(self: Box<Self>) {
        self.0.stop();
    }
}

/// Starts the dashboard on `http` once the node's broker is up, logging in as the node says.
fn dashboard_companion(http: &str, local: &LocalConfig) -> anyhow::Result<CompanionStart> {
    let http: SocketAddr = http
        .parse()
        .with_context(|| format!("--http `{http}`: expected an address such as 127.0.0.1:8080"))?;
    let (access, tls) = (access_config(local), dashboard_tls(local));
    Ok(Box::new(move |broker: &BrokerAccess| {
        let handle = cetratus_dashboard::serve(cetratus_dashboard::DashboardConfig {
            http,
            broker_url: broker.companion_url.clone(),
            user: broker.user.clone(),
            password: broker.password.clone(),
            signer: None,
            access,
            tls,
            rollouts: None,
        })?;
        let companion: Box<dyn Companion> = Box::new(Dashboard(handle));
        Ok(companion)
    }))
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
