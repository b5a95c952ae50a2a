//! The server's thread: the address space under `<plc>`, the publication of each cycle into it,
//! and the nodes that follow a substitution (a model-change event with them).

use std::net::SocketAddr;
use std::sync::atomic::Ordering;
use std::sync::mpsc::SyncSender;
use std::sync::Arc;
use std::time::Duration;

use cetratus_program::{Program, Type, Value};
use cetratus_runtime::{Slot, Status};
use opcua::nodes::{BaseEventType, Event};
use opcua::server::address_space::{AddressSpace, VariableBuilder};
use opcua::server::diagnostics::NamespaceMetadata;
use opcua::server::node_manager::memory::{simple_node_manager, SimpleNodeManager};
use opcua::server::{ServerBuilder, SubscriptionCache};
use opcua::types::{
    ByteString, DataTypeId, DataValue, DateTime, NodeId, NumericRange, ObjectId, ObjectTypeId,
    StatusCode, Variant,
};
use tokio::net::TcpListener;

use super::config::OpcUaConfig;
use super::{lock, PasswordCheck, Shared, SignalNode, NAMESPACE};
use crate::IoError;

/// What the address space shows of the run.
pub(crate) struct Layout {
    pub plc: String,
    pub inputs: Vec<SignalNode>,
    pub outputs: Vec<SignalNode>,
    pub writable_inputs: bool,
}

/// The figures under `<plc>.ExecInfo`.
const FIGURES: [(&str, DataTypeId); 7] = [
    ("Cycles", DataTypeId::UInt64),
    ("ScanTimeUs", DataTypeId::Double),
    ("Firings", DataTypeId::UInt64),
    ("Drift", DataTypeId::UInt64),
    ("DriftValid", DataTypeId::Boolean),
    ("Program", DataTypeId::String),
    ("ProgramHash", DataTypeId::String),
];

fn data_type(t: Type) -> DataTypeId {
    match t {
        Type::Bool => DataTypeId::Boolean,
        Type::Int => DataTypeId::Int64,
        Type::Real => DataTypeId::Double,
    }
}

fn variant(v: Value) -> Variant {
    match v {
        Value::Bool(b) => Variant::Boolean(b),
        Value::Int(i) => Variant::Int64(i),
        Value::Real(x) => Variant::Double(x),
    }
}

/// The value a client wrote to an input of type `ty`, when it is one: a bool for a bool, an
/// integer that fits for an int, a float or double for a real.
pub(crate) fn written_value(ty: Type, v: &Variant) -> Option<Value> {
    Some(match (ty, v) {
        (Type::Bool, Variant::Boolean(b)) => Value::Bool(*b),
        (Type::Int, Variant::SByte(i)) => Value::Int(i64::from(*i)),
        (Type::Int, Variant::Byte(i)) => Value::Int(i64::from(*i)),
        (Type::Int, Variant::Int16(i)) => Value::Int(i64::from(*i)),
        (Type::Int, Variant::UInt16(i)) => Value::Int(i64::from(*i)),
        (Type::Int, Variant::Int32(i)) => Value::Int(i64::from(*i)),
        (Type::Int, Variant::UInt32(i)) => Value::Int(i64::from(*i)),
        (Type::Int, Variant::Int64(i)) => Value::Int(*i),
        (Type::Int, Variant::UInt64(i)) => Value::Int(i64::try_from(*i).ok()?),
        (Type::Real, Variant::Float(x)) if x.is_finite() => Value::Real(f64::from(*x)),
        (Type::Real, Variant::Double(x)) if x.is_finite() => Value::Real(*x),
        _ => return None,
    })
}

/// Serves until `stop`; tells `ready` where it listens, or why it cannot.
pub(crate) async fn serve(
    config: OpcUaConfig,
    layout: Layout,
    shared: Arc<Shared>,
    passwords: Option<PasswordCheck>,
    ready: SyncSender<Result<SocketAddr, IoError>>,
    mut stop: tokio::sync::oneshot::Receiver<()>,
) {
    let fail = |e: IoError| {
        let _ = ready.send(Err(e));
    };
    let listen_error = |e: std::io::Error| IoError::Listen {
        addr: config.url.clone(),
        reason: e.to_string(),
    };
    let builder = ServerBuilder::new()
        .application_name(format!("Cetratus PLC {}", layout.plc))
        .application_uri(format!("urn:cetratus:{}", layout.plc))
        .product_uri("urn:cetratus")
        .host(config.listen.ip().to_string())
        .port(config.listen.port())
        .discovery_urls(vec![format!("opc.tcp://{}/", config.listen)])
        .max_sessions(config.max_sessions)
        .hello_timeout(5)
        .with_node_manager(simple_node_manager(
            NamespaceMetadata {
                namespace_uri: NAMESPACE.into(),
                ..Default::default()
            },
            "cetratus",
        ));
    let builder = match super::security::configure(builder, &config, passwords, shared.clone()) {
        Ok(b) => b,
        Err(e) => return fail(IoError::OpcUa(e)),
    };
    let (server, handle) = match builder.build() {
        Ok(x) => x,
        Err(e) => return fail(IoError::OpcUa(e)),
    };
    // Bound once the server is built (which may first make its certificate, for seconds): a
    // client that finds the port open finds a server behind it.
    let public = match TcpListener::bind(config.listen).await {
        Ok(l) => l,
        Err(e) => return fail(listen_error(e)),
    };
    let (addr, inner) = match (public.local_addr(), TcpListener::bind("127.0.0.1:0").await) {
        (Ok(a), Ok(i)) => (a, i),
        (Err(e), _) | (_, Err(e)) => return fail(listen_error(e)),
    };
    let inner_addr = match inner.local_addr() {
        Ok(a) => a,
        Err(e) => return fail(listen_error(e)),
    };
    let (Some(manager), Some(ns)) = (
        handle.node_managers().get_of_type::<SimpleNodeManager>(),
        handle.get_namespace_index(NAMESPACE),
    ) else {
        return fail(IoError::OpcUa(
            "the cetratus node manager did not start".into(),
        ));
    };
    let mut space = Space::build(
        ns,
        layout,
        manager,
        handle.subscriptions().clone(),
        shared.clone(),
    );
    let run = tokio::spawn(server.run_with(inner));
    let relay = tokio::spawn(super::front::relay(
        public,
        inner_addr,
        config.max_connections,
        shared.clone(),
    ));
    // The server advertises the port it accepts on; its clients must come through the front.
    while handle.info().port.load(Ordering::Relaxed) != inner_addr.port() && !run.is_finished() {
        tokio::time::sleep(Duration::from_millis(1)).await;
    }
    handle.info().port.store(addr.port(), Ordering::Relaxed);
    let _ = ready.send(Ok(addr));
    loop {
        tokio::select! {
            _ = shared.wake.notified() => space.publish(),
            _ = &mut stop => break,
        }
    }
    relay.abort();
    handle.cancel();
    let _ = tokio::time::timeout(Duration::from_secs(2), run).await;
}

/// The last values set on the nodes, to set only what changed.
#[derive(Default)]
struct Shown {
    inputs: Vec<Option<Value>>,
    outputs: Vec<Option<Value>>,
    marking: Vec<Option<u32>>,
    primary: Option<Slot>,
    status: Option<Status>,
    figures: [Option<Variant>; FIGURES.len()],
}

struct Space {
    plc: String,
    ns: u16,
    manager: Arc<SimpleNodeManager>,
    subscriptions: Arc<SubscriptionCache>,
    shared: Arc<Shared>,
    inputs: Vec<NodeId>,
    outputs: Vec<NodeId>,
    places: Vec<NodeId>,
    figures: Vec<NodeId>,
    primary: NodeId,
    status: NodeId,
    marking_folder: NodeId,
    inputs_folder: NodeId,
    outputs_folder: NodeId,
    program: Option<Arc<Program>>,
    seen: u64,
    shown: Shown,
    /// The working copy of the image.
    copy: Copy,
    changes: u64,
}

#[derive(Default)]
struct Copy {
    inputs: Vec<Value>,
    outputs: Vec<Value>,
    marking: Vec<u32>,
}

impl Space {
    fn id(&self, path: &str) -> NodeId {
        NodeId::new(self.ns, format!("{}.{path}", self.plc))
    }

    fn build(
        ns: u16,
        layout: Layout,
        manager: Arc<SimpleNodeManager>,
        subscriptions: Arc<SubscriptionCache>,
        shared: Arc<Shared>,
    ) -> Space {
        let plc = layout.plc.clone();
        let mut s = Space {
            primary: NodeId::new(ns, format!("{plc}.PRIMARY")),
            status: NodeId::new(ns, format!("{plc}.STATUS")),
            marking_folder: NodeId::new(ns, format!("{plc}.Marking")),
            inputs_folder: NodeId::new(ns, format!("{plc}.Inputs")),
            outputs_folder: NodeId::new(ns, format!("{plc}.Outputs")),
            plc,
            ns,
            manager,
            subscriptions,
            shared,
            inputs: Vec::new(),
            outputs: Vec::new(),
            places: Vec::new(),
            figures: Vec::new(),
            program: None,
            seen: 0,
            shown: Shown::default(),
            copy: Copy::default(),
            changes: 0,
        };
        let program = lock(&s.shared.image).program.clone();
        s.add_nodes(&layout, &program);
        s.shown.inputs = vec![None; s.inputs.len()];
        s.shown.outputs = vec![None; s.outputs.len()];
        s.program = Some(program);
        if layout.writable_inputs {
            for (i, (id, sig)) in s.inputs.iter().zip(&layout.inputs).enumerate() {
                let write = take_write(s.shared.clone(), i, sig.ty);
                s.manager.inner().add_write_callback(id.clone(), write);
            }
        }
        s
    }

    /// Adds the nodes under `<plc>`, each holding its zero until the first publication.
    fn add_nodes(&mut self, layout: &Layout, program: &Program) {
        let root = NodeId::new(self.ns, self.plc.clone());
        let folders = ["Inputs", "Outputs", "Marking", "ExecInfo"].map(|f| self.id(f));
        let a = self.manager.address_space().clone();
        let mut a = a.write();
        a.add_folder(
            &root,
            self.plc.as_str(),
            self.plc.as_str(),
            &NodeId::objects_folder_id(),
        );
        for (f, name) in folders
            .iter()
            .zip(["Inputs", "Outputs", "Marking", "ExecInfo"])
        {
            a.add_folder(f, name, name, &root);
        }
        for (id, name, zero) in [
            (&self.primary, "PRIMARY", "A"),
            (&self.status, "STATUS", "idle"),
        ] {
            let zero = Variant::from(zero);
            variable(&mut a, id, name, DataTypeId::String, zero, &root, false);
        }
        for sig in &layout.inputs {
            let id = self.id(&format!("Inputs.{}", sig.name));
            signal_variable(&mut a, &id, sig, &folders[0], layout.writable_inputs);
            self.inputs.push(id);
        }
        for sig in &layout.outputs {
            let id = self.id(&format!("Outputs.{}", sig.name));
            signal_variable(&mut a, &id, sig, &folders[1], false);
            self.outputs.push(id);
        }
        for (name, ty) in FIGURES {
            let id = self.id(&format!("ExecInfo.{name}"));
            let zero = match ty {
                DataTypeId::UInt64 => Variant::UInt64(0),
                DataTypeId::Double => Variant::Double(0.0),
                DataTypeId::Boolean => Variant::Boolean(false),
                _ => Variant::from(""),
            };
            variable(&mut a, &id, name, ty, zero, &folders[3], false);
            self.figures.push(id);
        }
        self.add_places(&mut a, program);
    }

    fn add_places(&mut self, a: &mut AddressSpace, program: &Program) {
        self.places.clear();
        for p in program.net().places() {
            let id = self.id(&format!("Marking.{}", p.id));
            variable(
                a,
                &id,
                &p.id,
                DataTypeId::UInt32,
                Variant::UInt32(0),
                &self.marking_folder,
                false,
            );
            self.places.push(id);
        }
        self.shown.marking = vec![None; self.places.len()];
    }

    /// Replaces the Marking nodes by the places of `program`, and tells subscribers of the
    /// Server object's events.
    fn follow(&mut self, program: &Arc<Program>) {
        {
            let a = self.manager.address_space().clone();
            let mut a = a.write();
            for id in &self.places {
                a.delete(id, true);
            }
            self.add_places(&mut a, program);
        }
        let message = format!(
            "the nodes of {} follow program {} ({} places)",
            self.plc,
            program.name(),
            self.places.len()
        );
        self.model_changed(self.marking_folder.clone(), message);
    }

    /// Counts a model change and reports it on the Server object, with `source` the folder
    /// whose nodes changed.
    fn model_changed(&mut self, source: NodeId, message: String) {
        self.changes += 1;
        self.shared
            .counters
            .model_changes
            .fetch_add(1, Ordering::Relaxed);
        let event = BaseEventType::new(
            ObjectTypeId::GeneralModelChangeEventType,
            ByteString::from(format!("cetratus:{}:model:{}", self.plc, self.changes).into_bytes()),
            message,
            DateTime::now(),
        )
        .set_source_node(source)
        .set_source_name(self.plc.as_str().into());
        let server: NodeId = ObjectId::Server.into();
        self.subscriptions
            .notify_events([(&event as &dyn Event, &server)].into_iter());
    }

    /// Adds the nodes of the signals a live update appended to the I/O map (read-only: they come
    /// from the field), with a model-change event per folder that gained nodes.
    fn grow(&mut self) {
        let grown = std::mem::take(&mut *lock(&self.shared.grown));
        if grown.is_empty() {
            return;
        }
        let (mut inputs, mut outputs) = (Vec::new(), Vec::new());
        {
            let a = self.manager.address_space().clone();
            let mut a = a.write();
            for (sig, input) in &grown {
                let (folder, path) = if *input {
                    (&self.inputs_folder, "Inputs")
                } else {
                    (&self.outputs_folder, "Outputs")
                };
                let id = self.id(&format!("{path}.{}", sig.name));
                if a.find(&id).is_some() {
                    continue;
                }
                signal_variable(&mut a, &id, sig, folder, false);
                if *input {
                    self.inputs.push(id);
                    self.shown.inputs.push(None);
                    inputs.push(sig.name.as_str());
                } else {
                    self.outputs.push(id);
                    self.shown.outputs.push(None);
                    outputs.push(sig.name.as_str());
                }
            }
        }
        for (folder, names, what) in [
            (self.inputs_folder.clone(), inputs, "inputs"),
            (self.outputs_folder.clone(), outputs, "outputs"),
        ] {
            if !names.is_empty() {
                let message = format!(
                    "the I/O map of {} grew: new {what} {}",
                    self.plc,
                    names.join(", ")
                );
                self.model_changed(folder, message);
            }
        }
    }

    /// Sets the nodes that changed since the last publication.
    fn publish(&mut self) {
        self.grow();
        let (generation, program, primary, status, figures) = {
            let im = lock(&self.shared.image);
            if im.generation == self.seen {
                return;
            }
            self.copy.inputs.clone_from(&im.inputs);
            self.copy.outputs.clone_from(&im.outputs);
            self.copy.marking.clone_from(&im.marking);
            let figures = [
                Variant::UInt64(im.cycles),
                Variant::Double(im.scan_ns as f64 / 1e3),
                Variant::UInt64(im.firings),
                Variant::UInt64(im.drift.unwrap_or(0)),
                Variant::Boolean(im.drift.is_some()),
                Variant::from(im.program.name()),
                Variant::from(im.program.hash_hex()),
            ];
            (
                im.generation,
                im.program.clone(),
                im.primary,
                im.status,
                figures,
            )
        };
        self.seen = generation;
        let same = self
            .program
            .as_ref()
            .is_some_and(|p| p.hash() == program.hash());
        if !same {
            self.follow(&program);
        }
        self.program = Some(program);
        let now = DateTime::now();
        let mut set: Vec<(NodeId, DataValue)> = Vec::new();
        for (i, v) in self.copy.inputs.iter().enumerate() {
            if let (Some(id), Some(last)) = (self.inputs.get(i), self.shown.inputs.get_mut(i)) {
                if *last != Some(*v) {
                    *last = Some(*v);
                    set.push((id.clone(), DataValue::new_at(variant(*v), now)));
                }
            }
        }
        for (i, v) in self.copy.outputs.iter().enumerate() {
            if let (Some(id), Some(last)) = (self.outputs.get(i), self.shown.outputs.get_mut(i)) {
                if *last != Some(*v) {
                    *last = Some(*v);
                    set.push((id.clone(), DataValue::new_at(variant(*v), now)));
                }
            }
        }
        for (i, &m) in self.copy.marking.iter().enumerate() {
            if let (Some(id), Some(last)) = (self.places.get(i), self.shown.marking.get_mut(i)) {
                if *last != Some(m) {
                    *last = Some(m);
                    set.push((id.clone(), DataValue::new_at(Variant::UInt32(m), now)));
                }
            }
        }
        if self.shown.primary != Some(primary) {
            self.shown.primary = Some(primary);
            set.push((
                self.primary.clone(),
                DataValue::new_at(Variant::from(primary.as_str()), now),
            ));
        }
        if self.shown.status != Some(status) {
            self.shown.status = Some(status);
            set.push((
                self.status.clone(),
                DataValue::new_at(Variant::from(status.as_str()), now),
            ));
        }
        for ((id, last), v) in self
            .figures
            .iter()
            .zip(&mut self.shown.figures)
            .zip(figures)
        {
            if last.as_ref() != Some(&v) {
                *last = Some(v.clone());
                set.push((id.clone(), DataValue::new_at(v, now)));
            }
        }
        if !set.is_empty() {
            let _ = self.manager.set_values(
                &self.subscriptions,
                set.iter().map(|(id, dv)| (id, None, dv.clone())),
            );
        }
        self.shared
            .counters
            .published
            .fetch_add(1, Ordering::Relaxed);
    }
}

/// The write callback of input `i`: a client's value of the input's type `ty` goes to the
/// written image, anything else is refused and counted.
fn take_write(
    shared: Arc<Shared>,
    i: usize,
    ty: Type,
) -> impl Fn(DataValue, &NumericRange) -> StatusCode + Send + Sync + 'static {
    move |dv: DataValue, range: &NumericRange| {
        let refuse = |code| {
            shared
                .counters
                .refused_writes
                .fetch_add(1, Ordering::Relaxed);
            code
        };
        if range.has_range() {
            return refuse(StatusCode::BadIndexRangeInvalid);
        }
        let Some(v) = dv.value.as_ref().and_then(|v| written_value(ty, v)) else {
            return refuse(StatusCode::BadTypeMismatch);
        };
        let mut g = lock(&shared.written);
        let w = &mut *g;
        if let (Some(slot), Some(seen)) = (w.values.get_mut(i), w.seen.get_mut(i)) {
            *slot = v;
            *seen = true;
        }
        shared.counters.writes.fetch_add(1, Ordering::Relaxed);
        StatusCode::Good
    }
}

/// The variable of signal `sig` under `parent`, holding its type's zero until the first cycle.
fn signal_variable(
    a: &mut AddressSpace,
    id: &NodeId,
    sig: &SignalNode,
    parent: &NodeId,
    writable: bool,
) {
    let zero = variant(sig.ty.zero());
    variable(a, id, &sig.name, data_type(sig.ty), zero, parent, writable);
}

fn variable(
    a: &mut AddressSpace,
    id: &NodeId,
    name: &str,
    ty: DataTypeId,
    value: Variant,
    parent: &NodeId,
    writable: bool,
) {
    let mut b = VariableBuilder::new(id, name, name)
        .data_type(ty)
        .value(value)
        .organized_by(parent);
    if writable {
        b = b.writable();
    }
    b.insert(a);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_written_value_is_taken_only_with_the_inputs_type() {
        assert_eq!(
            written_value(Type::Bool, &Variant::Boolean(true)),
            Some(Value::Bool(true))
        );
        assert_eq!(written_value(Type::Bool, &Variant::Int64(1)), None);
        assert_eq!(written_value(Type::Bool, &Variant::Empty), None);
        assert_eq!(
            written_value(Type::Int, &Variant::Int16(-3)),
            Some(Value::Int(-3))
        );
        assert_eq!(written_value(Type::Int, &Variant::UInt64(u64::MAX)), None);
        assert_eq!(written_value(Type::Int, &Variant::Double(1.0)), None);
        assert_eq!(
            written_value(Type::Real, &Variant::Float(0.5)),
            Some(Value::Real(0.5))
        );
        assert_eq!(written_value(Type::Real, &Variant::Double(f64::NAN)), None);
        assert_eq!(written_value(Type::Real, &Variant::from("1.0")), None);
    }
}
