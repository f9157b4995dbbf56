//! A global allocator for tests that weigh the heap. A test binary installs it with
//!
//! ```ignore
//! #[global_allocator]
//! static HEAP: timbre_testkit::heap::Counting = timbre_testkit::heap::Counting;
//! ```
//!
//! and then asks what a piece of code allocates on its own thread ([`counted`]: tests
//! of one binary run on several threads at once), how many bytes are live
//! ([`live_bytes`]) or how many were ever allocated ([`allocated_bytes`]).

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicI64, AtomicU64, Ordering};

/// The system's allocator, counting as it goes.
pub struct Counting;

thread_local! {
    /// This thread's allocations and frees while [`counted`] runs, else None.
    static COUNTS: Cell<Option<(usize, usize)>> = const { Cell::new(None) };
}
static LIVE: AtomicI64 = AtomicI64::new(0);
static ALLOCATED: AtomicU64 = AtomicU64::new(0);

// SAFETY: every call is passed on to the system's allocator unchanged; the counting
// touches only atomics and a thread-local cell, which never allocate.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        LIVE.fetch_add(layout.size() as i64, Ordering::Relaxed);
        ALLOCATED.fetch_add(layout.size() as u64, Ordering::Relaxed);
        COUNTS.with(|c| c.set(c.get().map(|(a, f)| (a + 1, f))));
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size() as i64, Ordering::Relaxed);
        COUNTS.with(|c| c.set(c.get().map(|(a, f)| (a, f + 1))));
        unsafe { System.dealloc(ptr, layout) }
    }
}

/// What `f` returns, and the allocations and frees this thread made while it ran
/// (other threads' are not counted). Needs [`Counting`] installed.
pub fn counted<R>(f: impl FnOnce() -> R) -> (R, usize, usize) {
    COUNTS.with(|c| c.set(Some((0, 0))));
    let result = f();
    let (allocations, frees) = COUNTS.with(|c| c.replace(None)).unwrap_or((0, 0));
    (result, allocations, frees)
}

/// Bytes allocated and not yet freed, by every thread.
pub fn live_bytes() -> i64 {
    LIVE.load(Ordering::Relaxed)
}

/// Bytes ever allocated, by every thread.
pub fn allocated_bytes() -> u64 {
    ALLOCATED.load(Ordering::Relaxed)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[global_allocator]
    static HEAP: Counting = Counting;

    #[test]
    fn a_thread_s_allocations_are_counted_and_no_other_s() {
        let (v, allocations, frees) = counted(|| vec![0u8; 100]);
        assert_eq!((allocations, frees), (1, 0));
        let ((), allocations, frees) = counted(|| drop(v));
        assert_eq!((allocations, frees), (0, 1));
        // Another thread allocates and frees while this one counts: not counted here.
        let (go, done) = (std::sync::Barrier::new(2), std::sync::Barrier::new(2));
        std::thread::scope(|s| {
            s.spawn(|| {
                go.wait();
                drop(std::hint::black_box(vec![1u8; 10]));
                done.wait();
            });
            let ((), allocations, frees) = counted(|| {
                go.wait();
                done.wait();
            });
            assert_eq!((allocations, frees), (0, 0), "another thread's vector");
        });
        let before = live_bytes();
        let kept = vec![0u64; 1000];
        assert!(live_bytes() >= before + 8000);
        assert!(allocated_bytes() >= 8000);
        drop(kept);
    }
}
