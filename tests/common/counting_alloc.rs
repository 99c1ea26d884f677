//! A global allocator that counts one thread's allocations, for the tests that prove a hot
//! path allocates nothing (tests/live_alloc.rs, tests/record_alloc.rs). Included by path in
//! those files only, since it installs the process's global allocator:
//! `#[path = "common/counting_alloc.rs"] mod counting_alloc;`.
//!
//! The flag, the count and the first [`KEEP`] backtraces are thread-locals, so that tests
//! running side by side each count their own thread; each counted allocation's backtrace is
//! kept, so that a failure says where it came from.

use std::alloc::{GlobalAlloc, Layout, System};
use std::backtrace::Backtrace;
use std::cell::{Cell, RefCell};

struct Counting;

thread_local! {
    /// Set on the thread whose allocations count, while they do.
    pub static COUNTING: Cell<bool> = const { Cell::new(false) };
    /// Inside the counter itself (its backtrace allocates): not counted again.
    static INSIDE: Cell<bool> = const { Cell::new(false) };
    /// This thread's counted allocations, and the first [`KEEP`] backtraces.
    pub static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
    pub static WHERE: RefCell<Vec<Backtrace>> = const { RefCell::new(Vec::new()) };
}
/// Backtraces kept per thread.
pub const KEEP: usize = 2000;

fn count() {
    let counting = COUNTING.try_with(Cell::get).unwrap_or(false);
    if !counting || INSIDE.try_with(Cell::get).unwrap_or(true) {
        return;
    }
    INSIDE.with(|i| i.set(true));
    ALLOCATIONS.with(|a| a.set(a.get() + 1));
    WHERE.with(|w| {
        let mut w = w.borrow_mut();
        if w.len() < KEEP {
            w.push(Backtrace::force_capture());
        }
    });
    INSIDE.with(|i| i.set(false));
}

// SAFETY: every call is passed to the system allocator unchanged; counting touches only
// thread-locals, and the backtraces it keeps allocate with the counter's own flag set.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        System.alloc(layout)
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count();
        System.alloc_zeroed(layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        System.realloc(ptr, layout, new_size)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;
