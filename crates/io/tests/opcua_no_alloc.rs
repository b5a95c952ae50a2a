//! The OPC UA server's side of the scan never touches the heap: publishing what each cycle left
//! and taking the inputs that clients wrote (ARCHITECTURE: "a scan never allocates"). The
//! server's own thread allocates as it likes; the counter counts the scan thread only.

mod common;

use cetratus_io::config::IoConfig;
use cetratus_io::opcua::{OpcUaServer, Start};
use cetratus_io::TwinDriver;
use cetratus_program::Value;
use cetratus_runtime::{Plc, Provider};
use cetratus_testkit::CountingAlloc;
use cetratus_twin::VernadatCell;
use common::{load, VERNADAT};

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc::new();

#[test]
fn publishing_each_cycle_and_taking_written_inputs_never_allocates_on_the_scan_thread() {
    let program = load(VERNADAT);
    let config = IoConfig::parse(
        "io.toml",
        "[opcua]\nlisten = \"opc.tcp://127.0.0.1:0\"\ninputs = true\n",
    )
    .unwrap();
    let mut server = OpcUaServer::start(
        config.opcua.as_ref().unwrap(),
        Start {
            plc: "cell",
            program: &program,
            inputs: program.inputs(),
            outputs: program.outputs(),
            passwords: None,
        },
    )
    .unwrap();
    let mut publisher = server.publisher();
    let mut twin = TwinDriver::new(
        VernadatCell::with_defaults(1),
        program.inputs(),
        program.outputs(),
    )
    .unwrap();
    let mut plc = Plc::new(program.clone(), 0, cetratus_testkit::stopwatch());
    let period = 10_000;
    let mut inputs = vec![Value::Bool(false); program.inputs().len()];
    let mut now = 0;
    let mut one = |plc: &mut Plc, now: u64| {
        plc.cycle(now, &mut twin);
        publisher.show(plc);
    };
    for _ in 0..500 {
        one(&mut plc, now);
        now += period;
    }
    let counted = ALLOC.during(|| {
        for _ in 0..5_000 {
            one(&mut plc, now);
            server.read_inputs(now, &mut inputs);
            now += period;
        }
    });
    assert_eq!(counted, 0);
    assert!(plc.cycles() >= 5_500);
    assert!(server.counters().published > 0, "{:?}", server.counters());
    server.stop();
}
