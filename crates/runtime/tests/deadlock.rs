//! A primary that is deadlocked (no transition enabled) while its inputs change raises one alarm.

use std::sync::Arc;

use cetratus_net::{ArcKind, NetBuilder, Place, Transition};
use cetratus_program::{Program, Value};
use cetratus_runtime::{Dispatcher, EventKind, ManualStopwatch, Plc, Provider};

/// An input that toggles every cycle.
struct Toggle(bool);

impl Provider for Toggle {
    fn read_inputs(&mut self, _now_us: u64, inputs: &mut [Value]) {
        self.0 = !self.0;
        inputs[0] = Value::Bool(self.0);
    }
}

impl Dispatcher for Toggle {
    fn write_outputs(&mut self, _now_us: u64, _outputs: &[Value]) {}
}

#[test]
fn a_deadlocked_primary_whose_inputs_change_raises_one_alarm() {
    // One token, one transition that takes it for good.
    let mut b = NetBuilder::new("sink");
    b.add_place(Place::new("p", 1)).expect("place");
    b.add_transition(Transition::new("t")).expect("transition");
    b.add_arc("a", "p", "t", 1, ArcKind::Normal).expect("arc");
    let net = b.build().expect("net");
    let toml = "[program]\nname = \"sink\"\nversion = \"1\"\nnet = \"sink.pnml\"\n\n[[input]]\nname = \"go\"\ntype = \"bool\"\n\n[guards]\nt = \"go\"\n";
    let program = Arc::new(Program::from_sources(toml, "sink.toml", net).expect("program"));
    let mut plc = Plc::new(program, 0, Box::new(ManualStopwatch::new()));
    let mut io = Toggle(false);
    for k in 0..50u64 {
        plc.cycle(k * 10_000, &mut io);
    }
    let alarms = plc
        .drain_events()
        .into_iter()
        .filter(|e| e.kind == EventKind::DeadlockAlarm)
        .count();
    assert_eq!(alarms, 1, "one alarm for one deadlock episode");
    assert!(plc.monitor().stats[0].deadlocked);
}
