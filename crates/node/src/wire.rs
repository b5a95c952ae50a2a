//! From the runtime's types to the wire's (`cetratus-proto`): the runtime knows nothing of the
//! protocol, and the protocol nothing of the runtime; the node translates their structures. The
//! names both use (containers, STATUS, roles, verdicts, quality) are `cetratus-vocab`'s, the same
//! type on both sides.

use std::sync::Arc;

use cetratus_net::export::to_svg;
use cetratus_program::{Program, Value};
use cetratus_proto as proto;
use cetratus_runtime::monitor::CycleRecord;
use cetratus_runtime::{Container, Event, ExecInfo, LoopTiming, Plc, Slot, Summary, Verdict};

/// Timing statistics on the wire.
pub fn timing(s: Summary) -> proto::TimingSummary {
    proto::TimingSummary {
        count: s.count,
        last_ns: s.last_ns,
        max_ns: s.max_ns,
        mean_ns: s.mean_ns,
        min_ns: s.min_ns,
        p50_ns: s.p50_ns,
        p99_ns: s.p99_ns,
    }
}

/// A signal value on the wire.
pub fn signal(v: Value) -> proto::SignalValue {
    match v {
        Value::Bool(b) => proto::SignalValue::Bool(b),
        Value::Int(i) => proto::SignalValue::Int(i),
        Value::Real(x) => proto::SignalValue::Real(x),
    }
}

/// Values by name, in the order of `names`.
pub fn signals(names: &[String], values: &[Value]) -> proto::Signals {
    names
        .iter()
        .zip(values)
        .map(|(n, v)| (n.clone(), signal(*v)))
        .collect()
}

/// A container's program identity.
pub fn program_info(c: &Container) -> proto::ProgramInfo {
    let p = c.program();
    proto::ProgramInfo {
        name: p.name().to_string(),
        version: p.version().to_string(),
        hash: p.hash_hex().to_string(),
    }
}

/// A verdict on the wire.
pub fn verdict(v: &Verdict) -> proto::Verdict {
    proto::Verdict {
        figures: v.figures.clone(),
        kind: v.kind,
        reasons: v.reasons.clone(),
        result: v.result,
    }
}

/// One container's `program_exec_info` on the wire.
pub fn exec_info(e: &ExecInfo) -> proto::ExecInfo {
    proto::ExecInfo {
        container: e.container,
        cycles: e.cycles,
        deadlock: e.deadlock,
        stall: e.stall,
        divergence: e.divergence.clone(),
        drift: e.drift,
        firings: e.firings.clone(),
        first_cause: e.first_cause.clone(),
        input_quality: Vec::new(),
        last_cause: e.last_cause.clone(),
        marking: e.marking.clone(),
        max_drift: e.max_drift,
        outputs: e
            .outputs
            .iter()
            .map(|(k, v)| (k.clone(), signal(*v)))
            .collect(),
        program: proto::ProgramInfo {
            name: e.program.name.clone(),
            version: e.program.version.clone(),
            hash: e.program.hash.clone(),
        },
        role: e.role,
        scan: timing(e.scan),
        verdicts: e.verdicts.iter().map(verdict).collect(),
        coverage: e.coverage.map(|c| proto::Coverage {
            cycles: c.cycles,
            outputs_covered: c.outputs_covered as u64,
            outputs_expected: c.outputs_expected as u64,
            unexplained: c.unexplained,
            signature_kinds: c.signature_kinds as u64,
        }),
        changes: e.changes.as_ref().map(|c| proto::DeclaredChanges {
            outputs: c.outputs.clone(),
            throughput_share: c.throughput_share,
        }),
    }
}

/// The quality of each field device's inputs on the wire.
pub fn input_quality(devices: &[cetratus_io::field::DeviceStatus]) -> Vec<proto::InputQuality> {
    devices
        .iter()
        .map(|d| proto::InputQuality {
            device: d.name.clone(),
            link: d.link,
            missed_cycles: d.missed_cycles,
            quality: d.quality,
        })
        .collect()
}

/// Both containers' `program_exec_info`.
pub fn exec_info_msg(plc: &Plc) -> proto::ExecInfoMsg {
    proto::ExecInfoMsg(plc.exec_info().map(|e| e.as_ref().map(exec_info)))
}

/// An event of the PLC on the wire.
pub fn event(e: &Event) -> proto::EventMsg {
    proto::EventMsg {
        cycle: Some(e.cycle),
        time_us: Some(e.time_us),
        kind: e.kind.into(),
        message: e.message.clone(),
        detail: serde_json::to_value(e.detail).unwrap_or(serde_json::Value::Null),
    }
}

/// The retained `state` of a PLC, with the real-time loop's figures.
pub fn state(plc: &Plc, loop_timing: &LoopTiming) -> proto::StateMsg {
    let info = |s: Slot| plc.container(s).map(program_info);
    proto::StateMsg {
        online: true,
        primary: plc.primary(),
        status: plc.status(),
        programs: proto::Programs {
            a: info(Slot::A),
            b: info(Slot::B),
        },
        cycle: proto::CycleFigures {
            cycle: timing(loop_timing.cycle.summary()),
            cycles: plc.cycles(),
            latency: timing(loop_timing.latency.summary()),
            overruns: loop_timing.overruns,
            scan: timing(plc.monitor().stats[plc.primary().index()].scan.summary()),
            time_ms: plc.now_us() / 1000,
            update: plc
                .update_meta()
                .map(|m| format!("{} {}", m.name, m.version)),
        },
        // The control link fills these in; a node without one drops nothing.
        control: proto::ControlCounters::default(),
        persist_fault: None,
        labels: proto::Labels::new(),
        updates: None,
    }
}

/// One cycle of the timing diagram.
pub fn sample(r: &CycleRecord) -> proto::Sample {
    let mask = proto::SignalMask::from_u64_words;
    proto::Sample {
        time_ms: r.time_us / 1000,
        primary: r.primary,
        status: r.status,
        inputs: mask(r.inputs),
        outputs_a: r.outputs_a.map(mask),
        outputs_b: r.outputs_b.map(mask),
        dispatched: mask(r.dispatched),
    }
}

/// The nets of A and B drawn with their markings.
pub fn net(programs: &[Option<(Arc<Program>, Vec<u32>)>; 2]) -> proto::NetMsg {
    let svg = |p: &Option<(Arc<Program>, Vec<u32>)>| {
        p.as_ref().map(|(prog, m)| to_svg(prog.net(), Some(m)))
    };
    proto::NetMsg {
        a: svg(&programs[0]),
        b: svg(&programs[1]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use cetratus_runtime::{Dispatcher, ManualStopwatch, Provider};

    struct Still;
    impl Provider for Still {
        fn read_inputs(&mut self, _: u64, _: &mut [Value]) {}
    }
    impl Dispatcher for Still {
        fn write_outputs(&mut self, _: u64, _: &[Value]) {}
    }

    fn vernadat() -> Plc {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../examples/vernadat/vernadat.toml");
        let program = Arc::new(Program::load(&path).expect("the example loads"));
        let mut plc = Plc::new(program, 0, Box::new(ManualStopwatch::new()));
        for k in 0..5 {
            plc.cycle(k * 10_000, &mut Still);
        }
        plc
    }

    /// The runtime's own serialisations (used by `demo --json` and the audit log) and the wire's
    /// agree field for field.
    #[test]
    fn the_wire_structs_write_what_the_runtime_writes() {
        let mut plc = vernadat();
        let ours = serde_json::to_value(plc.exec_info()).unwrap();
        let wire = serde_json::to_value(exec_info_msg(&plc)).unwrap();
        assert_eq!(ours, wire);
        for e in plc.drain_events() {
            assert_eq!(
                serde_json::to_value(&e).unwrap(),
                serde_json::to_value(event(&e)).unwrap()
            );
        }
    }

    #[test]
    fn a_state_message_reads_back_under_the_strict_wire_schema() {
        let plc = vernadat();
        let bytes = serde_json::to_vec(&state(&plc, &LoopTiming::default())).unwrap();
        let back: proto::StateMsg = proto::decode("state", &bytes).unwrap();
        assert_eq!(back.status, proto::Status::Idle);
        assert_eq!(back.cycle.cycles, 5);
    }
}
