//! Profiling aid: prepares the U.2 package against a PLC running U.1, many times.
fn main() {
    let pk = cetratus_bench::update::packages();
    let u1 = std::sync::Arc::new(
        cetratus_program::Program::load(
            &cetratus_bench::program::examples_dir().join("vernadat/u1.toml"),
        )
        .expect("U.1"),
    );
    let ctx = cetratus_runtime::Plc::new(u1, 0, cetratus_node::clock::MonotonicStopwatch::boxed())
        .update_context();
    let n: u32 = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(200);
    let t = std::time::Instant::now();
    for _ in 0..n {
        std::hint::black_box(
            ctx.prepare_package(
                &pk.u2,
                &pk.trust,
                cetratus_program::Unsigned::Refused,
                cetratus_program::OtherBase::Refused,
            )
            .expect("prepares"),
        );
    }
    println!("prepare_package {:?}", t.elapsed() / n);
}
