//! The counting allocator counts what the current thread allocates, and nothing else.

use std::hint::black_box;

use cetratus_testkit::CountingAlloc;

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc::new();

#[test]
fn an_allocation_and_a_reallocation_count_one_each() {
    let n = ALLOC.during(|| {
        let mut v: Vec<u64> = black_box(Vec::with_capacity(4));
        v.extend_from_slice(&[1, 2, 3, 4, 5]);
        black_box(v);
    });
    assert_eq!(n, 2);
}

#[test]
fn arithmetic_on_the_stack_counts_nothing() {
    let mut sum = 0u64;
    let n = ALLOC.during(|| {
        for i in 0..1_000u64 {
            sum = black_box(sum.wrapping_add(i * i));
        }
    });
    assert_eq!(n, 0);
    assert_eq!(sum, 332_833_500);
}

#[test]
fn another_thread_s_allocations_are_not_counted() {
    let spawn = || {
        std::thread::scope(|s| {
            s.spawn(|| black_box(0u8));
        });
    };
    // The first spawn of a process builds what later ones reuse.
    spawn();
    let n = ALLOC.during(|| {
        std::thread::scope(|s| {
            s.spawn(|| black_box(vec![0u8; 1024]));
        });
    });
    // Spawning a thread allocates on this one (its handle and stack bookkeeping), but the
    // kilobyte the other thread asked for is not among them.
    let spawn_only = ALLOC.during(spawn);
    assert_eq!(n, spawn_only);
}
