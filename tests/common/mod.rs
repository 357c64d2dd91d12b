//! Shared by the integration tests that check the rule "no allocation in a step": a global
//! allocator that counts every allocation, per thread and in the whole process.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;

static PROCESS: AtomicUsize = AtomicUsize::new(0);
thread_local! {
    static THREAD: Cell<usize> = const { Cell::new(0) };
}

// The one unsafe code of the crate's tests: a global allocator must implement an unsafe trait.
#[allow(unsafe_code)]
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        PROCESS.fetch_add(1, Ordering::Relaxed);
        THREAD.with(|a| a.set(a.get() + 1));
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Allocations made so far by the calling thread (not disturbed by tests running in parallel).
#[allow(dead_code)] // each test binary uses one of the two counters
pub fn thread_allocations() -> usize {
    THREAD.with(Cell::get)
}

/// Allocations made so far by every thread of the process (worker threads included; only
/// meaningful while no other test of the binary runs).
#[allow(dead_code)]
pub fn process_allocations() -> usize {
    PROCESS.load(Ordering::Relaxed)
}
