//! Profiling aid: runs the Vernadat PLC in quarantine (U.1 loaded) on replayed inputs.
use cetratus_bench::update::{packages, Replay};
use cetratus_runtime::{Command, Plc};

fn main() {
    let quarantine = std::env::args().nth(1).as_deref() != Some("single");
    let pk = packages();
    let program = cetratus_bench::program::vernadat_program();
    let images = cetratus_bench::program::recorded_inputs(&program, 100_000);
    let mut replay = Replay::new(images);
    let mut plc = Plc::new(
        program,
        0,
        cetratus_node::clock::MonotonicStopwatch::boxed(),
    );
    if quarantine {
        let p = plc
            .update_context()
            .prepare_package(
                &pk.u1,
                &pk.trust,
                cetratus_program::Unsigned::Refused,
                cetratus_program::OtherBase::Refused,
            )
            .expect("prepares");
        plc.command(Command::Load(Box::new(p))).expect("accepted");
    }
    let t = std::time::Instant::now();
    let n = 2_000_000u64;
    for k in 0..n {
        plc.cycle(k * 10_000, &mut replay);
    }
    println!("{} ns per cycle", t.elapsed().as_nanos() as u64 / n);
}
