//! A node's MQTT side: the embedded broker or a plant broker's client, and a companion started
//! beside it once the broker is up (the dashboard, which this crate does not know: its caller
//! hands over how to start it, [`CompanionStart`]).

use cetratus_mct::{BrokerChoice, MctLink, MqttConfig};
use cetratus_runtime::Plc;

use crate::config::LocalConfig;
use crate::link::ControlLink;
use crate::load::LoadPolicy;
use crate::spec::{Notice, Say, SpecError};

/// How often the node's snapshots go out, in wall time, whatever the speed.
const PUBLISH_PERIOD_US: u64 = 200_000;

/// How a node reaches MQTT.
#[derive(Default)]
pub struct MqttSpec {
    /// The embedded broker's address (`--mqtt`); the default is 127.0.0.1:1883.
    pub embedded: Option<String>,
    /// A plant broker instead (`--broker`): `mqtt://host:port` or `mqtts://host:port`.
    pub broker: Option<String>,
    /// The plant broker's user and password, over the local configuration's credentials.
    pub login: Option<(String, Option<String>)>,
    /// Started once the broker is up: the dashboard.
    pub companion: Option<CompanionStart>,
    /// Whether the broker's URL (and the companion's link) are said as [`Notice::Note`].
    pub announce: bool,
}

/// Where and as whom a companion reaches the node's broker.
#[derive(Clone, Debug)]
pub struct BrokerAccess {
    /// The broker's URL, as clients outside the node reach it.
    pub url: String,
    /// The URL the companion connects to: the embedded broker's loopback port, or `url`.
    pub companion_url: String,
    /// The companion's user: the login the embedded broker drew for it, or the PLC's own.
    pub user: Option<String>,
    /// Its password.
    pub password: Option<String>,
}

/// A service that runs beside a node's MQTT client.
pub trait Companion: Send {
    /// Where a person opens it (a one-time login link), if anywhere.
    fn link(&self) -> Option<String>;
    /// Stops it; called before the MQTT client stops, so that it does not report losing it.
    fn stop(self: Box<Self>);
}

/// Starts a companion, given the broker's access.
pub type CompanionStart = Box<
    dyn FnOnce(
        &BrokerAccess,
    ) -> Result<Box<dyn Companion>, Box<dyn std::error::Error + Send + Sync>>,
>;

/// The node's MQTT client and its companion.
pub struct Services {
    mqtt: cetratus_mct::MqttHandle,
    companion: Option<Box<dyn Companion>>,
    broker_url: String,
}

impl Services {
    /// The URL clients reach the broker at.
    pub fn broker_url(&self) -> &str {
        &self.broker_url
    }

    /// Where a person opens the companion, if it runs and has a link.
    pub fn companion_link(&self) -> Option<String> {
        self.companion.as_ref().and_then(|c| c.link())
    }

    /// The MQTT client, to wait for its connection.
    pub fn mqtt(&self) -> &cetratus_mct::MqttHandle {
        &self.mqtt
    }

    /// Stops the companion, then MQTT.
    pub fn stop(self) {
        if let Some(c) = self.companion {
            c.stop();
        }
        self.mqtt.shutdown();
    }
}

/// The MQTT configuration of a node: broker accounts, plant-broker credentials and operator keys
/// come from the local configuration; the spec's login overrides the credentials.
fn config(spec: &MqttSpec, plc_id: &str, local: &LocalConfig) -> Result<MqttConfig, SpecError> {
    let mut c = MqttConfig::new(plc_id);
    let credentials = spec
        .login
        .clone()
        .map(|(u, p)| (u, p.unwrap_or_default()))
        .or_else(|| local.credentials.clone());
    c.broker = BrokerChoice::from_cli(
        spec.embedded.as_deref(),
        spec.broker.as_deref(),
        local.users.clone(),
        local.mqtt_tls.clone(),
        credentials,
    )?;
    c.operator_keys = local.operators.clone();
    c.publish_period = std::time::Duration::from_micros(PUBLISH_PERIOD_US);
    Ok(c)
}

/// Starts MQTT and the companion.
pub(crate) fn start(
    mut spec: MqttSpec,
    plc_id: &str,
    local: &LocalConfig,
    say: Say<'_>,
) -> Result<(MctLink, Services), SpecError> {
    let (link, handle) = cetratus_mct::start(config(&spec, plc_id, local)?)?;
    let access = access(&spec, &handle, local)?;
    let companion = match spec.companion.take() {
        Some(start) => Some(start(&access).map_err(SpecError::Companion)?),
        None => None,
    };
    if spec.announce {
        let topics = format!("MQTT {} (topics cetratus/{plc_id}/…)", access.url);
        say(Notice::Note(
            match companion.as_ref().and_then(|c| c.link()) {
                Some(link) => format!("{topics}, dashboard {link}"),
                None => topics,
            },
        ));
    }
    Ok((
        link,
        Services {
            mqtt: handle,
            companion,
            broker_url: access.url,
        },
    ))
}

/// Where the broker is, and how a companion logs in: beside an embedded broker with the login
/// the broker drew for it, on its loopback port; beside a plant broker with the PLC's own
/// credentials.
fn access(
    spec: &MqttSpec,
    handle: &cetratus_mct::MqttHandle,
    local: &LocalConfig,
) -> Result<BrokerAccess, SpecError> {
    // The embedded broker's own address: with `--mqtt 127.0.0.1:0` it picked its port itself.
    let url = match handle.broker_addr() {
        Some(addr) if local.mqtt_tls.is_some() => format!("mqtts://{addr}"),
        Some(addr) => format!("mqtt://{addr}"),
        None => handle.url().to_string(),
    };
    if let (Some(addr), Some(login)) = (handle.broker_local_addr(), handle.dashboard_login()) {
        return Ok(BrokerAccess {
            url,
            companion_url: format!("mqtt://{addr}"),
            user: Some(login.user),
            password: Some(login.password),
        });
    }
    let creds = spec
        .login
        .clone()
        .or_else(|| local.credentials.clone().map(|(u, p)| (u, Some(p))));
    Ok(BrokerAccess {
        companion_url: url.clone(),
        url,
        user: creds.as_ref().map(|c| c.0.clone()),
        password: creds.and_then(|c| c.1),
    })
}

/// The node's side of MQTT for `plc`: snapshots go out about five times a second of wall time,
/// whatever the speed.
pub(crate) fn control_link(
    link: MctLink,
    plc: &Plc,
    load: LoadPolicy,
    (speed, period_us): (f64, u64),
    own: crate::link::OwnFacts,
) -> ControlLink {
    let publish_every = ((PUBLISH_PERIOD_US as f64 * speed) / period_us.max(1) as f64)
        .round()
        .max(1.0) as u64;
    ControlLink::start(plc, link, load, publish_every, own)
}
