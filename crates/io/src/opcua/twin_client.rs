//! `cetratus twin serve vernadat|festo --opcua opc.tcp://ADDR`: a digital twin as the OPC UA
//! client of a PLC's server, the paper's virtual commissioning (the twin host is the client of
//! the PLC). It writes the twin's sensors to `<plc>.Inputs.<signal>` and reads its actuators from
//! `<plc>.Outputs.<signal>`, stepping the twin in real time, about every millisecond.
//!
//! It retries until the server is up. The twin's clock starts with its first complete write of
//! the sensors, which is also what the PLC's first scan waits for; from then on `--for D` is D of
//! plant time under control, as with the Modbus twin.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use cetratus_twin::{Plant, Twin};
use opcua::client::{ClientBuilder, IdentityToken, Session};
use opcua::crypto::SecurityPolicy;
use opcua::types::{
    AttributeId, BrowseDescription, BrowseDirection, BrowseResultMask, DataValue,
    MessageSecurityMode, NodeClassMask, NodeId, ObjectId, ReadValueId, ReferenceTypeId, StatusCode,
    TimestampsToReturn, UserTokenPolicy, Variant, WriteValue,
};

use super::config::Policy;
use super::NAMESPACE;
use crate::IoError;

/// How the client reaches the PLC's server (docs/io.md, *The twin as an OPC UA client*).
#[derive(Clone, Debug, Default)]
pub struct ClientSecurity {
    /// Sign & Encrypt with this policy; policy None (a server on loopback) when `None`.
    pub policy: Option<Policy>,
    /// The client's PKI directory: its certificate and key (`own/`, `private/`, made on first
    /// use) and the servers it trusts (`trusted/`).
    pub pki: Option<PathBuf>,
    /// The user and password to log in as; anonymous without.
    pub user: Option<(String, String)>,
}

fn policy_of(p: Policy) -> SecurityPolicy {
    match p {
        Policy::Basic256Sha256 => SecurityPolicy::Basic256Sha256,
        Policy::Aes128Sha256RsaOaep => SecurityPolicy::Aes128Sha256RsaOaep,
        Policy::Aes256Sha256RsaPss => SecurityPolicy::Aes256Sha256RsaPss,
    }
}

/// Makes the client's PKI directory and certificate when missing, and installs the certificates
/// an administrator copied into its `trusted/`; returns the client's certificate (DER) path and
/// the name under which a server's trust list must hold it.
pub fn prepare_pki(pki: &std::path::Path) -> Result<(PathBuf, String), IoError> {
    super::pki::install_trusted(pki).map_err(client_error)?;
    // Building the client makes the key pair on first use.
    ClientBuilder::new()
        .application_name("Cetratus twin")
        .application_uri("urn:cetratus:twin")
        .product_uri("urn:cetratus")
        .pki_dir(pki)
        .create_sample_keypair(true)
        .client()
        .map_err(|e| client_error(e.join(", ")))?;
    let cert = pki.join("own/cert.der");
    let der = std::fs::read(&cert).map_err(|e| client_error(format!("{}: {e}", cert.display())))?;
    let name = super::pki::trusted_name(&der).map_err(client_error)?;
    Ok((cert, name))
}

/// How often the client writes every sensor again when none changed: the keep-alive that tells
/// the PLC its inputs' source is alive (docs/io.md, *Quality*).
pub const KEEPALIVE: Duration = Duration::from_millis(100);

/// What the client did.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct ClientCounters {
    /// Read requests answered.
    pub reads: u64,
    /// Write requests answered.
    pub writes: u64,
    /// Requests that failed (a lost connection, a timeout), or values with a bad status.
    pub errors: u64,
    /// Attempts to reach the server before it answered.
    pub connect_attempts: u64,
}

/// What a twin served over OPC UA did.
#[derive(Debug, Clone, serde::Serialize)]
pub struct OpcUaServeReport {
    /// The twin's name.
    pub twin: String,
    /// The PLC it was the plant of.
    pub plc: String,
    /// Seconds of twin time.
    pub seconds: f64,
    /// Parts finished (good parts for the Festo station).
    pub parts_finished: u64,
    /// Physical faults seen.
    pub twin_faults: u64,
    /// Their descriptions.
    pub faults: Vec<String>,
    /// The twin's counters.
    pub counters: serde_json::Value,
    /// What the OPC UA client did.
    pub opcua: ClientCounters,
}

pub(crate) fn client_error(e: impl std::fmt::Display) -> IoError {
    IoError::Thread(format!("OPC UA client: {e}"))
}

/// The PLC a twin is the plant of, and how its client reaches the PLC's server.
#[derive(Clone, Copy, Debug)]
pub struct PlcTarget<'a> {
    /// The server's endpoint, `opc.tcp://ADDR`.
    pub url: &'a str,
    /// The PLC's name; the one object of the `urn:cetratus` namespace when `None`.
    pub plc: Option<&'a str>,
    /// How the client reaches the server.
    pub security: &'a ClientSecurity,
}

/// Connects to `target` (retrying until the server answers or `stop`), finds the PLC, and
/// drives `twin` until `until_us` of twin time or `stop`. `on_connect` is told the PLC's name
/// once the session is up.
pub fn serve(
    twin: Twin,
    target: PlcTarget<'_>,
    until_us: u64,
    stop: &AtomicBool,
    on_connect: impl FnOnce(&str),
) -> Result<OpcUaServeReport, IoError> {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .map_err(|e| IoError::Thread(e.to_string()))?;
    rt.block_on(run(twin, target, until_us, stop, on_connect))
}

pub(crate) async fn connect(
    url: &str,
    stop: &AtomicBool,
    counters: &mut ClientCounters,
    security: &ClientSecurity,
) -> Result<Option<Arc<Session>>, IoError> {
    let secure = security.policy.is_some();
    let pki = match (&security.pki, secure) {
        (Some(p), true) => p.clone(),
        (None, true) => {
            return Err(client_error(
                "Sign & Encrypt needs the client's PKI directory",
            ))
        }
        // Policy None uses no certificate; the store still wants a directory.
        (_, false) => std::env::temp_dir().join("cetratus-opcua-twin"),
    };
    let mut client = ClientBuilder::new()
        .application_name("Cetratus twin")
        .application_uri("urn:cetratus:twin")
        .product_uri("urn:cetratus")
        .pki_dir(pki)
        .create_sample_keypair(secure)
        // Encrypted, the server's certificate must be in the client's trust list.
        .trust_server_certs(!secure)
        .session_retry_limit(-1)
        .session_retry_initial(Duration::from_millis(100))
        .session_retry_max(Duration::from_secs(2))
        .request_timeout(Duration::from_secs(2))
        .client()
        .map_err(|e| client_error(e.join(", ")))?;
    let (policy, mode) = match security.policy {
        Some(p) => (policy_of(p), MessageSecurityMode::SignAndEncrypt),
        None => (SecurityPolicy::None, MessageSecurityMode::None),
    };
    loop {
        if stop.load(Ordering::Relaxed) {
            return Ok(None);
        }
        counters.connect_attempts += 1;
        if let (true, Some(pki)) = (secure, &security.pki) {
            // A certificate an administrator copied into `trusted/` meanwhile counts from the
            // next attempt.
            if let Err(e) = super::pki::install_trusted(pki) {
                if counters.connect_attempts.is_power_of_two() {
                    eprintln!("OPC UA: {e}");
                }
            }
        }
        let endpoint = (url, policy.to_uri(), mode, UserTokenPolicy::anonymous());
        let identity = match &security.user {
            Some((u, p)) => IdentityToken::new_user_name(u.clone(), p.clone()),
            None => IdentityToken::Anonymous,
        };
        match client
            .connect_to_matching_endpoint(endpoint, identity)
            .await
        {
            Ok((session, event_loop)) => {
                event_loop.spawn();
                if tokio::time::timeout(Duration::from_secs(5), session.wait_for_connection())
                    .await
                    .unwrap_or(false)
                {
                    return Ok(Some(session));
                }
                let _ = session.disconnect().await;
            }
            Err(e) => {
                // Told on the 1st, 2nd, 4th… failure: an untrusted certificate or a wrong
                // password is worth knowing, a server that is not up yet is expected.
                if counters.connect_attempts.is_power_of_two() && counters.connect_attempts > 1 {
                    eprintln!(
                        "OPC UA: {url}: attempt {} failed: {e}",
                        counters.connect_attempts
                    );
                }
                tokio::time::sleep(Duration::from_millis(200)).await
            }
        }
    }
}

/// The PLC's name: the one object under Objects in the Cetratus namespace.
pub(crate) async fn find_plc(session: &Session) -> Result<(u16, String), IoError> {
    let ns = session
        .read(
            &[ReadValueId::new_value(NodeId::from(
                opcua::types::VariableId::Server_NamespaceArray,
            ))],
            TimestampsToReturn::Neither,
            0.0,
        )
        .await
        .map_err(client_error)?
        .into_iter()
        .next()
        .and_then(|dv| dv.value)
        .and_then(|v| match v {
            Variant::Array(a) => a
                .values
                .iter()
                .position(|x| matches!(x, Variant::String(s) if s.as_ref() == NAMESPACE)),
            _ => None,
        })
        .ok_or_else(|| {
            client_error(format!(
                "the server has no {NAMESPACE} namespace: is it a Cetratus PLC?"
            ))
        })?;
    let ns = u16::try_from(ns).map_err(client_error)?;
    let browse = BrowseDescription {
        node_id: ObjectId::ObjectsFolder.into(),
        browse_direction: BrowseDirection::Forward,
        reference_type_id: ReferenceTypeId::Organizes.into(),
        include_subtypes: true,
        node_class_mask: NodeClassMask::OBJECT.bits(),
        result_mask: BrowseResultMask::All as u32,
    };
    let results = session
        .browse(&[browse], 100, None)
        .await
        .map_err(client_error)?;
    let plc = results
        .into_iter()
        .flat_map(|r| r.references.unwrap_or_default())
        .find(|r| r.node_id.node_id.namespace == ns)
        .and_then(|r| match r.node_id.node_id.identifier {
            opcua::types::Identifier::String(s) => Some(s.as_ref().to_string()),
            _ => None,
        })
        .ok_or_else(|| client_error("the server shows no PLC under Objects"))?;
    Ok((ns, plc))
}

pub(crate) fn bool_of(dv: &DataValue) -> Option<bool> {
    if dv.status.is_some_and(|s| !s.is_good()) {
        return None;
    }
    match dv.value {
        Some(Variant::Boolean(b)) => Some(b),
        _ => None,
    }
}

/// The client's side of the PLC: the session, the twin's signals as the PLC's nodes, what the
/// PLC last took of each sensor, and what the client did.
struct Link {
    session: Arc<Session>,
    sensors: Vec<NodeId>,
    actuators: Vec<ReadValueId>,
    /// Each sensor's value as the PLC last took it; `None` to write it again.
    written: Vec<Option<bool>>,
    last_write: Instant,
    counters: ClientCounters,
}

/// What came of writing the sensors.
enum Written {
    /// None had changed.
    Nothing,
    /// The PLC took every one.
    Taken,
    /// The PLC refused the write at `index` (the first it refused) with `code`.
    Refused { index: usize, code: StatusCode },
    /// The request failed; every sensor is written again.
    Failed,
}

impl Link {
    /// The link to the twin's signals under `<plc>` in namespace `ns`, none written yet.
    fn new(
        session: Arc<Session>,
        counters: ClientCounters,
        ns: u16,
        plc: &str,
        twin: &Twin,
    ) -> Link {
        let sensors: Vec<NodeId> = twin
            .input_names()
            .iter()
            .map(|n| NodeId::new(ns, format!("{plc}.Inputs.{n}")))
            .collect();
        let actuators = twin
            .output_names()
            .iter()
            .map(|n| ReadValueId::new_value(NodeId::new(ns, format!("{plc}.Outputs.{n}"))))
            .collect();
        Link {
            session,
            written: vec![None; sensors.len()],
            sensors,
            actuators,
            last_write: Instant::now(),
            counters,
        }
    }

    /// Reads the actuators into `outputs`; one the PLC cannot give keeps its last value.
    async fn read_actuators(&mut self, outputs: &mut [bool]) {
        match self
            .session
            .read(&self.actuators, TimestampsToReturn::Neither, 0.0)
            .await
        {
            Ok(values) => {
                self.counters.reads += 1;
                for (o, dv) in outputs.iter_mut().zip(&values) {
                    match bool_of(dv) {
                        Some(b) => *o = b,
                        None => self.counters.errors += 1,
                    }
                }
            }
            Err(_) => {
                self.counters.errors += 1;
                // After a lost connection, every sensor is written again.
                self.written.fill(None);
            }
        }
    }

    /// Writes the sensors whose value the PLC has not taken yet, and all of them once per
    /// [`KEEPALIVE`].
    async fn write_sensors(&mut self, inputs: &[bool]) -> Written {
        if self.last_write.elapsed() >= KEEPALIVE {
            self.written.fill(None);
        }
        let changed: Vec<WriteValue> = self
            .sensors
            .iter()
            .zip(inputs)
            .zip(&self.written)
            .filter(|((_, v), w)| **w != Some(**v))
            .map(|((id, v), _)| WriteValue {
                node_id: id.clone(),
                attribute_id: AttributeId::Value as u32,
                index_range: Default::default(),
                value: DataValue::value_only(*v),
            })
            .collect();
        if changed.is_empty() {
            return Written::Nothing;
        }
        match self.session.write(&changed).await {
            Ok(codes) if codes.iter().all(|c| c.is_good()) => {
                self.counters.writes += 1;
                self.last_write = Instant::now();
                for (w, v) in self.written.iter_mut().zip(inputs) {
                    *w = Some(*v);
                }
                Written::Taken
            }
            Ok(codes) => {
                self.counters.writes += 1;
                self.counters.errors += codes.iter().filter(|c| !c.is_good()).count() as u64;
                let bad = codes.iter().position(|c| !c.is_good()).unwrap_or(0);
                Written::Refused {
                    index: bad,
                    code: codes[bad],
                }
            }
            Err(_) => {
                self.counters.errors += 1;
                self.written.fill(None);
                Written::Failed
            }
        }
    }
}

/// [`serve`] on the client's runtime.
async fn run(
    mut twin: Twin,
    target: PlcTarget<'_>,
    until_us: u64,
    stop: &AtomicBool,
    on_connect: impl FnOnce(&str),
) -> Result<OpcUaServeReport, IoError> {
    let mut counters = ClientCounters::default();
    let Some(session) = connect(target.url, stop, &mut counters, target.security).await? else {
        return Err(client_error("stopped before the server answered"));
    };
    let (ns, found) = find_plc(&session).await?;
    let plc = target.plc.map_or(found, str::to_string);
    on_connect(&plc);
    let mut link = Link::new(session, counters, ns, &plc, &twin);
    let mut inputs = vec![false; link.sensors.len()];
    let mut outputs = vec![false; link.actuators.len()];
    twin.inputs(&mut inputs);
    let mut start: Option<Instant> = None;
    let mut now_us = 0;
    while now_us < until_us && !stop.load(Ordering::Relaxed) {
        let tick = Instant::now();
        if let Some(s) = start {
            link.read_actuators(&mut outputs).await;
            now_us = s.elapsed().as_micros() as u64;
            twin.step(now_us, &outputs);
            twin.inputs(&mut inputs);
        }
        match link.write_sensors(&inputs).await {
            Written::Taken => {
                // The plant's clock starts with its controller's first complete input image.
                start.get_or_insert_with(Instant::now);
            }
            Written::Refused { index, code } if start.is_none() => {
                return Err(client_error(format!(
                    "the PLC refuses the sensor {} ({code}): does its I/O configuration say that inputs come from OPC UA (inputs = true)?",
                    link.sensors[index]
                )));
            }
            Written::Refused { .. } | Written::Nothing | Written::Failed => {}
        }
        let spent = tick.elapsed();
        if spent < Duration::from_millis(1) {
            tokio::time::sleep(Duration::from_millis(1) - spent).await;
        }
    }
    let _ = link.session.disconnect().await;
    Ok(report(&twin, plc, now_us, link.counters))
}

/// What the twin, served `now_us` of its time as the plant of `plc`, and the client did.
fn report(twin: &Twin, plc: String, now_us: u64, opcua: ClientCounters) -> OpcUaServeReport {
    let c = twin.counters();
    OpcUaServeReport {
        twin: twin.name().to_string(),
        plc,
        seconds: now_us as f64 / 1e6,
        parts_finished: c
            .get("parts_finished")
            .or_else(|| c.get("parts_good"))
            .unwrap_or(0),
        twin_faults: twin.faults().len() as u64 + twin.faults_dropped(),
        faults: twin.faults().iter().map(|f| f.to_string()).collect(),
        counters: serde_json::to_value(c).unwrap_or_default(),
        opcua,
    }
}
