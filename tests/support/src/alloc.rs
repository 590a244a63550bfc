//! A global allocator that counts heap allocations, for the tests that a control cycle allocates
//! nothing and for `v2t-bench game` (allocations per decision). It forwards every call to the
//! system allocator unchanged. A binary opts in with
//!
//! ```
//! #[global_allocator]
//! static GLOBAL: v2t_test_support::alloc::Counting = v2t_test_support::alloc::Counting;
//!
//! let (v, n) = v2t_test_support::alloc::count(|| Vec::<u8>::with_capacity(64));
//! assert_eq!((v.capacity(), n), (64, 1));
//! ```
//!
//! and then reads [`on_this_thread`] (tests run on many threads at once: only this thread's
//! allocations are its own), [`total`], or wraps the code it measures in [`count`].

#![allow(unsafe_code)] // a global allocator cannot be written without it

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicU64, Ordering};

thread_local! {
    static THREAD: Cell<u64> = const { Cell::new(0) };
}
static TOTAL: AtomicU64 = AtomicU64::new(0);

/// The counting allocator (allocations and reallocations count; frees do not).
#[derive(Debug, Clone, Copy, Default)]
pub struct Counting;

fn counted() {
    TOTAL.fetch_add(1, Ordering::Relaxed);
    // A thread being torn down has no counter left: its allocation is counted in the total only.
    let _ = THREAD.try_with(|c| c.set(c.get() + 1));
}

// SAFETY: forwards every call to the system allocator unchanged; it only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        counted();
        // SAFETY: the same contract as the caller's.
        unsafe { System.alloc(l) }
    }

    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        // SAFETY: the same contract as the caller's.
        unsafe { System.dealloc(p, l) }
    }

    unsafe fn realloc(&self, p: *mut u8, l: Layout, n: usize) -> *mut u8 {
        counted();
        // SAFETY: the same contract as the caller's.
        unsafe { System.realloc(p, l, n) }
    }
}

/// Allocations so far by every thread of the process (0 when [`Counting`] is not the global
/// allocator).
pub fn total() -> u64 {
    TOTAL.load(Ordering::Relaxed)
}

/// Allocations so far by this thread.
pub fn on_this_thread() -> u64 {
    THREAD.with(Cell::get)
}

/// Runs `f` and returns its result with the allocations this thread made meanwhile.
pub fn count<R>(f: impl FnOnce() -> R) -> (R, u64) {
    let before = on_this_thread();
    let r = f();
    (r, on_this_thread() - before)
}
