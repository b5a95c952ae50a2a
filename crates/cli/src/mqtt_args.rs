//! The MQTT flags shared by `run`, `demo`, `mct` and the client commands.

use std::net::SocketAddr;

use anyhow::Context;
use cetratus_mct::{BrokerChoice, MqttConfig};

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
    pub fn config(&self, local: &crate::config::LocalConfig) -> anyhow::Result<MqttConfig> {
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
