//! The I/O configuration of a PLC node (docs/io.md): the field devices, the IEC address ranges
//! each serves, how their words are ordered and scaled, what happens when one falls silent, and
//! the Modbus server that HMIs and SCADA read.
//!
//! It belongs to the node, like a hardware configuration, not to a program: a file given with
//! `cetratus run --io IO.toml`, or the `[io]` section of the local configuration. Everything in
//! it is checked when it is read, with the file, line and column of what is wrong.

use std::collections::BTreeMap;
use std::ops::Range;

use serde::Deserialize;
use toml::Spanned;

use crate::address::{Area, IecAddress, Table};
use crate::IoError;

/// How a device is reached.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Transport {
    /// Modbus TCP, at `host:port`.
    ModbusTcp(String),
}

/// Which register of a 32-bit value comes first.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum WordOrder {
    /// The high word in the lower register (Modbus's own byte order carried to words).
    #[default]
    HighFirst,
    /// The low word in the lower register (many PLCs and meters).
    LowFirst,
}

/// What the program gets from a device that has missed `stale_after` cycles.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum StalePolicy {
    /// The last values read, flagged stale.
    #[default]
    Hold,
    /// The inputs' declared safe values.
    Safe,
    /// The safe values, and the field I/O goes to its safe state: every output gets its safe
    /// value until the run is restarted.
    Fault,
}

/// A contiguous run of IEC addresses that a device serves, and where they are on it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ServedRange {
    /// The first address.
    pub first: IecAddress,
    /// Addresses in the range.
    pub count: u32,
    /// The device's table.
    pub table: Table,
    /// The device's bit or register number of the first address.
    pub offset: u32,
}

impl ServedRange {
    /// Bits or registers the range takes on the device.
    pub fn len(&self) -> u32 {
        self.count * self.first.width()
    }

    /// Always false: a range serves at least one address.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// The device number of `a`, when the range serves it.
    pub fn locate(&self, a: IecAddress) -> Option<u32> {
        (a.area == self.first.area
            && a.size == self.first.size
            && a.index >= self.first.index
            && a.index < self.first.index + self.count)
            .then(|| self.offset + (a.index - self.first.index) * a.width())
    }
}

/// A field device.
#[derive(Clone, Debug, PartialEq)]
pub struct Device {
    /// Its name, for messages, quality and the dashboard.
    pub name: String,
    /// How it is reached.
    pub transport: Transport,
    /// Modbus unit id.
    pub unit: u8,
    /// How long one request may take before it counts as missed (µs).
    pub timeout_us: u64,
    /// Order of the two registers of a 32-bit value.
    pub word_order: WordOrder,
    /// Outputs are written on change, and at least every this many cycles (the device's
    /// communication watchdog).
    pub rewrite_every: u32,
    /// What a silent device's inputs become.
    pub stale: StalePolicy,
    /// Cycles without a complete read after which the policy applies.
    pub stale_after: u32,
    /// First and longest wait between two connection attempts (µs).
    pub reconnect_us: (u64, u64),
    /// What it serves.
    pub ranges: Vec<ServedRange>,
    /// Where it is declared (`file:line:column`).
    pub at: String,
}

/// Linear scaling of a register: `raw[0]` reads as `value[0]`, `raw[1]` as `value[1]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scale {
    /// Two raw register values.
    pub raw: [f64; 2],
    /// The engineering values they stand for.
    pub value: [f64; 2],
}

impl Scale {
    /// Raw to engineering units.
    pub fn to_value(&self, raw: f64) -> f64 {
        self.value[0]
            + (raw - self.raw[0]) * (self.value[1] - self.value[0]) / (self.raw[1] - self.raw[0])
    }

    /// Engineering units to raw.
    pub fn to_raw(&self, value: f64) -> f64 {
        self.raw[0]
            + (value - self.value[0]) * (self.raw[1] - self.raw[0])
                / (self.value[1] - self.value[0])
    }
}

/// Per-address options.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct ChannelOptions {
    /// Linear scaling of a word or double word.
    pub scale: Option<Scale>,
    /// An input that the Modbus server lets an HMI write (a pushbutton on a panel).
    pub hmi_writable: bool,
}

/// The Modbus server of the process image.
#[derive(Clone, Debug, PartialEq)]
pub struct ServerConfig {
    /// Where it listens (`host:port`); loopback unless the configuration says otherwise.
    pub listen: String,
    /// Connections served at once; more are refused.
    pub max_connections: usize,
    /// A connection that sends nothing for this long is closed (µs).
    pub idle_timeout_us: u64,
    /// Addresses of clients that may write; everyone else only reads.
    pub write_from: Vec<std::net::IpAddr>,
}

/// A checked I/O configuration.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct IoConfig {
    /// The file it was read from, for messages.
    pub file: String,
    /// Field devices, in declaration order.
    pub devices: Vec<Device>,
    /// Options by address.
    pub channels: BTreeMap<IecAddress, ChannelOptions>,
    /// The Modbus server, when configured.
    pub server: Option<ServerConfig>,
    /// The OPC UA server, when configured.
    pub opcua: Option<crate::opcua::config::OpcUaConfig>,
    /// How long the first scan waits for every device's first complete read (µs); after that
    /// it runs on the safe values of the inputs still missing.
    pub start_timeout_us: u64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileSrc {
    start_timeout: Option<Spanned<String>>,
    #[serde(default)]
    device: Vec<DeviceSrc>,
    #[serde(default)]
    channel: Vec<ChannelSrc>,
    server: Option<Spanned<ServerSrc>>,
    opcua: Option<Spanned<crate::opcua::config::OpcUaSrc>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct DeviceSrc {
    name: Spanned<String>,
    transport: Spanned<String>,
    address: Spanned<String>,
    unit: Option<Spanned<i64>>,
    timeout: Option<Spanned<String>>,
    word_order: Option<Spanned<String>>,
    rewrite_every: Option<Spanned<i64>>,
    stale: Option<Spanned<String>>,
    stale_after: Option<Spanned<i64>>,
    reconnect_min: Option<Spanned<String>>,
    reconnect_max: Option<Spanned<String>>,
    serves: Vec<Spanned<RangeSrc>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RangeSrc {
    from: Spanned<String>,
    to: Option<Spanned<String>>,
    offset: Option<Spanned<i64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ChannelSrc {
    address: Spanned<String>,
    scale: Option<Spanned<ScaleSrc>>,
    #[serde(default)]
    hmi_writable: bool,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ScaleSrc {
    raw: [f64; 2],
    value: [f64; 2],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ServerSrc {
    modbus: Spanned<String>,
    max_connections: Option<Spanned<i64>>,
    idle_timeout: Option<Spanned<String>>,
    #[serde(default)]
    write_from: Vec<Spanned<String>>,
}

/// The local configuration file, of which only `[io]` is read here.
#[derive(Deserialize)]
struct LocalSrc {
    io: Option<FileSrc>,
}

/// Where in a text a byte offset is, as `file:line:column`.
pub(crate) fn position(file: &str, text: &str, at: usize) -> String {
    let before = &text[..at.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    format!("{file}:{line}:{column}")
}

/// A configuration text being read, to place what is wrong in it.
pub(crate) struct Reader<'a> {
    /// The file, as messages name it.
    pub(crate) file: &'a str,
    /// Its text.
    pub(crate) text: &'a str,
}

impl Reader<'_> {
    /// The error `message` at the start of `span`.
    pub(crate) fn err(&self, span: Range<usize>, message: impl Into<String>) -> IoError {
        IoError::Config {
            at: self.at(span),
            message: message.into(),
        }
    }

    /// Where `span` starts, as `file:line:column`.
    pub(crate) fn at(&self, span: Range<usize>) -> String {
        position(self.file, self.text, span.start)
    }

    /// A stale policy, [`StalePolicy::Hold`] when none is written.
    pub(crate) fn stale(&self, s: &Option<Spanned<String>>) -> Result<StalePolicy, IoError> {
        match s {
            None => Ok(StalePolicy::default()),
            Some(s) => match s.get_ref().as_str() {
                "hold" => Ok(StalePolicy::Hold),
                "safe" => Ok(StalePolicy::Safe),
                "fault" => Ok(StalePolicy::Fault),
                other => Err(self.err(
                    s.span(),
                    format!(
                        "unknown stale policy `{other}`; expected \"hold\", \"safe\" or \"fault\""
                    ),
                )),
            },
        }
    }

    /// A duration longer than 0, in µs; `default_us` when none is written.
    pub(crate) fn duration(
        &self,
        d: &Option<Spanned<String>>,
        default_us: u64,
        what: &str,
    ) -> Result<u64, IoError> {
        match d {
            None => Ok(default_us),
            Some(s) => {
                let us = cetratus_program::duration::parse_us(
                    s.get_ref(),
                    cetratus_program::duration::Bare::Refused,
                )
                .map_err(|e| self.err(s.span(), format!("`{what}`: {e}")))?;
                if us == 0 {
                    return Err(self.err(s.span(), format!("`{what}` must be longer than 0")));
                }
                Ok(us)
            }
        }
    }

    /// A whole number from 1 to `max`; `default` when none is written.
    pub(crate) fn count(
        &self,
        n: &Option<Spanned<i64>>,
        default: u32,
        what: &str,
        max: u32,
    ) -> Result<u32, IoError> {
        match n {
            None => Ok(default),
            Some(v) => u32::try_from(*v.get_ref())
                .ok()
                .filter(|&k| (1..=max).contains(&k))
                .ok_or_else(|| {
                    self.err(
                        v.span(),
                        format!("`{what}` must be a whole number from 1 to {max}"),
                    )
                }),
        }
    }

    /// An IEC address.
    fn address(&self, s: &Spanned<String>) -> Result<IecAddress, IoError> {
        s.get_ref()
            .parse()
            .map_err(|m: crate::address::AddressError| self.err(s.span(), m.to_string()))
    }
}

impl IoConfig {
    /// Reads an I/O configuration file (`--io IO.toml`).
    pub fn load(path: &std::path::Path) -> Result<IoConfig, IoError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| IoError::Read {
            path: file.clone(),
            source,
        })?;
        IoConfig::parse(&file, &text)
    }

    /// Reads an I/O configuration from its text; `file` names it in messages.
    pub fn parse(file: &str, text: &str) -> Result<IoConfig, IoError> {
        let src: FileSrc = toml::from_str(text).map_err(|e| toml_error(file, text, &e))?;
        IoConfig::build(&Reader { file, text }, src)
    }

    /// The `[io]` section of a local configuration file's text, if it has one with a device or
    /// a server in it.
    pub fn from_local(file: &str, text: &str) -> Result<Option<IoConfig>, IoError> {
        let src: LocalSrc = toml::from_str(text).map_err(|e| toml_error(file, text, &e))?;
        match src.io {
            None => Ok(None),
            Some(io) => {
                let c = IoConfig::build(&Reader { file, text }, io)?;
                Ok((!c.devices.is_empty() || c.server.is_some() || c.opcua.is_some()).then_some(c))
            }
        }
    }

    fn build(r: &Reader<'_>, src: FileSrc) -> Result<IoConfig, IoError> {
        let mut devices: Vec<Device> = Vec::new();
        for d in &src.device {
            let device = device(r, d, &devices)?;
            devices.push(device);
        }
        check_overlaps(r, &src, &devices)?;
        let mut channels = BTreeMap::new();
        for c in &src.channel {
            let (a, options) = channel(r, c)?;
            if channels.insert(a, options).is_some() {
                return Err(r.err(
                    c.address.span(),
                    format!("{a} has two [[channel]] entries; merge them"),
                ));
            }
        }
        let server = src.server.as_ref().map(|s| server(r, s)).transpose()?;
        Ok(IoConfig {
            file: r.file.to_string(),
            devices,
            channels,
            server,
            opcua: src
                .opcua
                .as_ref()
                .map(|o| crate::opcua::config::OpcUaConfig::build(r, o))
                .transpose()?,
            start_timeout_us: r.duration(&src.start_timeout, 2_000_000, "start_timeout")?,
        })
    }
}

/// A `[[device]]`, checked against the devices declared before it (`earlier`) for its name.
fn device(r: &Reader<'_>, d: &DeviceSrc, earlier: &[Device]) -> Result<Device, IoError> {
    let name = d.name.get_ref().trim();
    if name.is_empty() || name.len() > 64 {
        return Err(r.err(d.name.span(), "a device needs a name of 1 to 64 characters"));
    }
    if earlier.iter().any(|o| o.name == name) {
        return Err(r.err(
            d.name.span(),
            format!("device `{name}` is declared twice; give each device its own name"),
        ));
    }
    let transport = transport(r, d)?;
    let unit = match &d.unit {
        None => 1,
        Some(u) => u8::try_from(*u.get_ref())
            .map_err(|_| r.err(u.span(), "`unit` must be a Modbus unit id from 0 to 255"))?,
    };
    let word_order = word_order(r, &d.word_order)?;
    let stale = r.stale(&d.stale)?;
    let reconnect_us = reconnect(r, d)?;
    if d.serves.is_empty() {
        return Err(r.err(d.name.span(), format!("device `{name}` serves no address; add e.g. serves = [{{ from = \"%IX0.0\", to = \"%IX0.7\" }}]")));
    }
    let ranges = d
        .serves
        .iter()
        .map(|s| served_range(r, s))
        .collect::<Result<_, _>>()?;
    Ok(Device {
        name: name.to_string(),
        transport,
        unit,
        timeout_us: r.duration(&d.timeout, 100_000, "timeout")?,
        word_order,
        rewrite_every: r.count(&d.rewrite_every, 100, "rewrite_every", 1_000_000)?,
        stale,
        stale_after: r.count(&d.stale_after, 3, "stale_after", 1_000_000)?,
        reconnect_us,
        ranges,
        at: r.at(d.name.span()),
    })
}

/// How a device is reached; the one transport this version knows needs a `host:port`.
fn transport(r: &Reader<'_>, d: &DeviceSrc) -> Result<Transport, IoError> {
    match d.transport.get_ref().as_str() {
        "modbus-tcp" => {
            let a = d.address.get_ref();
            match a.rsplit_once(':') {
                Some((host, port))
                    if !host.is_empty() && port.parse::<u16>().is_ok_and(|p| p > 0) =>
                {
                    Ok(Transport::ModbusTcp(a.clone()))
                }
                _ => Err(r.err(
                    d.address.span(),
                    format!("`{a}` is not host:port; write e.g. \"192.168.0.10:502\""),
                )),
            }
        }
        other => Err(r.err(
            d.transport.span(),
            format!("unknown transport `{other}`; this version knows \"modbus-tcp\""),
        )),
    }
}

/// A device's `word_order`, high word first when it has none.
fn word_order(r: &Reader<'_>, w: &Option<Spanned<String>>) -> Result<WordOrder, IoError> {
    match w {
        None => Ok(WordOrder::default()),
        Some(w) => match w.get_ref().as_str() {
            "high_first" => Ok(WordOrder::HighFirst),
            "low_first" => Ok(WordOrder::LowFirst),
            other => Err(r.err(
                w.span(),
                format!("unknown word order `{other}`; expected \"high_first\" or \"low_first\""),
            )),
        },
    }
}

/// A device's first and longest wait between connection attempts (µs), the first no longer
/// than the second.
fn reconnect(r: &Reader<'_>, d: &DeviceSrc) -> Result<(u64, u64), IoError> {
    let min = r.duration(&d.reconnect_min, 100_000, "reconnect_min")?;
    let max = r.duration(&d.reconnect_max, 5_000_000, "reconnect_max")?;
    if max < min {
        let span = d
            .reconnect_max
            .as_ref()
            .or(d.reconnect_min.as_ref())
            .map_or(d.name.span(), |s| s.span());
        return Err(r.err(span, "`reconnect_max` is shorter than `reconnect_min`"));
    }
    Ok((min, max))
}

/// A `[[channel]]`: the address it is about and its options.
fn channel(r: &Reader<'_>, c: &ChannelSrc) -> Result<(IecAddress, ChannelOptions), IoError> {
    let a = r.address(&c.address)?;
    let scale = c.scale.as_ref().map(|s| scale(r, s, a)).transpose()?;
    if c.hmi_writable && a.area == Area::Output {
        return Err(r.err(c.address.span(), format!("{a} is an output; only inputs can be marked hmi_writable (the program drives outputs)")));
    }
    let options = ChannelOptions {
        scale,
        hmi_writable: c.hmi_writable,
    };
    Ok((a, options))
}

/// The scale of the word or double word at `a`; two equal points would divide by zero.
fn scale(r: &Reader<'_>, s: &Spanned<ScaleSrc>, a: IecAddress) -> Result<Scale, IoError> {
    let ScaleSrc { raw, value } = s.get_ref();
    let finite = raw.iter().chain(value).all(|x| x.is_finite());
    if !finite || raw[0] == raw[1] || value[0] == value[1] {
        return Err(r.err(s.span(), "a scale needs two different finite raw values and two different finite values, e.g. { raw = [0, 27648], value = [0.0, 100.0] }"));
    }
    if a.size == crate::address::Size::Bit {
        return Err(r.err(
            s.span(),
            format!("{a} is a bit; only words and double words are scaled"),
        ));
    }
    Ok(Scale {
        raw: *raw,
        value: *value,
    })
}

/// The `[server]` section: the Modbus server of the process image.
fn server(r: &Reader<'_>, s: &Spanned<ServerSrc>) -> Result<ServerConfig, IoError> {
    let s = s.get_ref();
    let listen = s.modbus.get_ref();
    if listen.parse::<std::net::SocketAddr>().is_err() {
        return Err(r.err(
            s.modbus.span(),
            format!("`{listen}` is not an IP address and port; write e.g. \"127.0.0.1:15021\""),
        ));
    }
    let mut write_from = Vec::new();
    for w in &s.write_from {
        write_from.push(
            w.get_ref()
                .parse()
                .map_err(|_| r.err(w.span(), format!("`{}` is not an IP address", w.get_ref())))?,
        );
    }
    Ok(ServerConfig {
        listen: listen.clone(),
        max_connections: r.count(&s.max_connections, 8, "max_connections", 256)? as usize,
        idle_timeout_us: r.duration(
            &s.idle_timeout,
            crate::bank::DEFAULT_IDLE_TIMEOUT.as_micros() as u64,
            "idle_timeout",
        )?,
        write_from,
    })
}

fn served_range(r: &Reader<'_>, s: &Spanned<RangeSrc>) -> Result<ServedRange, IoError> {
    let src = s.get_ref();
    let first = r.address(&src.from)?;
    let last = match &src.to {
        None => first,
        Some(t) => r.address(t)?,
    };
    if first.area == Area::Memory {
        return Err(r.err(
            src.from.span(),
            format!("{first} is memory, the PLC's own; a device serves %I and %Q addresses"),
        ));
    }
    if (last.area, last.size) != (first.area, first.size) || last.index < first.index {
        return Err(r.err(
            s.span(),
            format!("`to` = {last} must be of the same kind as `from` = {first} and not before it"),
        ));
    }
    let count = last.index - first.index + 1;
    let (table, default_first) = first.default_location();
    let offset = match &src.offset {
        None => default_first,
        Some(o) => u32::try_from(*o.get_ref()).map_err(|_| {
            r.err(
                o.span(),
                "`offset` must be a bit or register number from 0 to 65535",
            )
        })?,
    };
    let range = ServedRange {
        first,
        count,
        table,
        offset,
    };
    if u64::from(offset) + u64::from(range.len()) > 65_536 || count > 2000 {
        return Err(r.err(s.span(), format!("{first}..{last} at {} {offset} runs past the device's table (65536 entries) or is longer than 2000 addresses; shorten it or lower `offset`", table.name())));
    }
    Ok(range)
}

/// Two ranges that claim the same IEC address, or the same device's bits or registers, are a
/// configuration error: which one the program would see would depend on timing.
fn check_overlaps(r: &Reader<'_>, src: &FileSrc, devices: &[Device]) -> Result<(), IoError> {
    let mut all = Vec::new();
    for (d, (dev, dsrc)) in devices.iter().zip(&src.device).enumerate() {
        for (range, rsrc) in dev.ranges.iter().zip(&dsrc.serves) {
            all.push((d, range, rsrc.span()));
        }
    }
    for (i, (d1, a, _)) in all.iter().enumerate() {
        for (d2, b, span) in &all[i + 1..] {
            let (ta, fa) = a.first.default_location();
            let (tb, fb) = b.first.default_location();
            let plc_side =
                ta == tb && a.first.area == b.first.area && fa < fb + b.len() && fb < fa + a.len();
            let device_side = d1 == d2
                && a.table == b.table
                && a.offset < b.offset + b.len()
                && b.offset < a.offset + a.len();
            if plc_side || device_side {
                let what = if plc_side {
                    "the same IEC addresses"
                } else {
                    "the same registers of the device"
                };
                return Err(r.err(
                    span.clone(),
                    format!(
                        "overlapping maps: {} (device `{}`) and {} (device `{}`) take {what}; each address and register may be mapped once",
                        a.first, devices[*d1].name, b.first, devices[*d2].name
                    ),
                ));
            }
        }
    }
    Ok(())
}

fn toml_error(file: &str, text: &str, e: &toml::de::Error) -> IoError {
    IoError::Config {
        at: position(file, text, e.span().map_or(0, |s| s.start)),
        message: e.message().trim().to_string(),
    }
}

#[cfg(test)]
mod tests;
