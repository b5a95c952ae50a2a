//! A global allocator that counts, for the tests that prove a scan never allocates.
//!
//! Implementing `GlobalAlloc` is an `unsafe impl` by definition, and the workspace denies unsafe
//! code. This module is the one exception (ARCHITECTURE.md, Invariants): the allocator forwards
//! every call to the system allocator unchanged and only counts, so the test suites declare it
//! with `#[global_allocator]` and stay free of unsafe code themselves.
#![allow(unsafe_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicBool, Ordering};

thread_local! {
    // Per thread, so that tests running beside the measuring one are not counted. Const-initialised
    // and without a destructor, so touching it never allocates.
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

/// Set by the first allocation that goes through a `CountingAlloc`: a counter that reads zero
/// because its allocator was never declared global would prove nothing.
static INSTALLED: AtomicBool = AtomicBool::new(false);

/// The system allocator, counting allocations and reallocations per thread. Declare it with
/// `#[global_allocator] static ALLOC: CountingAlloc = CountingAlloc::new();`.
#[derive(Debug, Default)]
pub struct CountingAlloc {
    _private: (),
}

impl CountingAlloc {
    /// An allocator to declare as the `#[global_allocator]`.
    pub const fn new() -> Self {
        CountingAlloc { _private: () }
    }

    /// How many allocations and reallocations the current thread has made so far.
    ///
    /// # Panics
    ///
    /// When no `CountingAlloc` is the global allocator, since every count would then be zero.
    pub fn allocations(&self) -> u64 {
        assert!(
            INSTALLED.load(Ordering::Relaxed),
            "CountingAlloc counts nothing unless it is declared with #[global_allocator]"
        );
        ALLOCATIONS.with(Cell::get)
    }

    /// How many allocations and reallocations `f` makes on the current thread.
    pub fn during(&self, f: impl FnOnce()) -> u64 {
        let before = self.allocations();
        f();
        self.allocations() - before
    }
}

fn count() {
    ALLOCATIONS.with(|c| c.set(c.get() + 1));
    if !INSTALLED.load(Ordering::Relaxed) {
        INSTALLED.store(true, Ordering::Relaxed);
    }
}

// SAFETY: every method forwards to `System` with the caller's arguments unchanged, so `System`'s
// guarantees are this allocator's; counting touches only a const-initialised thread-local and an
// atomic, neither of which allocates.
unsafe impl GlobalAlloc for CountingAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}
