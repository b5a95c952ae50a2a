//! The scan thread of a node as `cetratus run` has it (embedded broker, MQTT link) touches the
//! heap only when it builds a snapshot for the publisher: the cycles between publications, the
//! ones that decide the scan latency when nothing else happens, allocate nothing. (An allocation
//! may grow the heap, and the kernel's memory map is shared with the broker's threads.)

use cetratus_runtime::LoopTiming;
use cetratus_testkit::CountingAlloc;

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc::new();

#[test]
fn the_cycles_between_publications_allocate_nothing() {
    const PERIOD_US: u64 = 1_000;
    let addr = std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free port");
    let mut node =
        cetratus_bench::harness::vernadat_node("alloc", addr, PERIOD_US).expect("the node");
    let timing = LoopTiming::default();
    let mut now = 0;
    let mut step = |n: u64| {
        (0..n)
            .map(|_| {
                let a = ALLOC.during(|| {
                    node.node_mut().step(now, &timing).expect("the node runs");
                });
                now += PERIOD_US;
                a
            })
            .collect::<Vec<u64>>()
    };
    // Warm-up: everything built on first use, the first snapshots.
    step(2_000);
    let counts = step(4_000);
    // Five publications a second at 1 ms: one cycle in 200 builds a snapshot.
    let allocating = counts.iter().filter(|&&a| a > 0).count();
    let published = counts.len() / 200;
    assert!(
        allocating <= published + 1,
        "{allocating} of {} cycles allocated (snapshots due: {published}): {:?}",
        counts.len(),
        counts
            .iter()
            .enumerate()
            .filter(|(_, &a)| a > 0)
            .take(20)
            .collect::<Vec<_>>()
    );
    assert!(allocating > 0, "no snapshot was built");
    node.finish().expect("the node stops");
}
