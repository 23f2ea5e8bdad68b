//! Memory that input decides: how much a batch's worlds take, measured rather than guessed, and
//! the check that a request fits before anything is allocated for it.
//!
//! The crate's global allocator is the system's, wrapped to count the bytes each thread has
//! allocated and not yet freed ([`thread_bytes`]): one thread-local addition per allocation
//! (a step allocates nothing, so stepping pays nothing). [`measure`] runs a closure and returns
//! what it left allocated on the calling thread: a batch builds its first world measured and
//! multiplies. A request beyond [`MAX_BATCH_BYTES`] is a `ConfigError` naming the key and the
//! memory it would need; within it, [`reserve`] asks the system for that much at once (and
//! gives it back), so that a process whose memory is limited (`ulimit -v`, a container) gets
//! an [`Error::Memory`] (Python's `MemoryError`) instead of an abort halfway through building.
//!
//! Threading: the counters are per thread; memory freed by another thread than the one that
//! allocated it is counted there, which only blurs [`thread_bytes`] across threads, never
//! [`measure`] of a closure that frees what it allocates on its own thread.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use crate::error::{Error, Result};

/// Largest estimated memory of one batch (bytes): 16 GiB, about 540,000 Nav worlds or 16 worlds
/// of 1,000-robot swarms; more worlds are a `ConfigError` naming `num_envs`.
pub const MAX_BATCH_BYTES: u64 = 16 << 30;

/// The system allocator, counting each thread's bytes.
pub struct CountingAllocator;

thread_local! {
    static THREAD_BYTES: Cell<i64> = const { Cell::new(0) };
}

fn count(delta: i64) {
    // `try_with`: nothing is counted while the thread's locals are being torn down.
    let _ = THREAD_BYTES.try_with(|bytes| bytes.set(bytes.get().wrapping_add(delta)));
}

// SAFETY: every call is forwarded unchanged to `System`; counting touches only a thread-local
// integer with no destructor, so it neither allocates nor unwinds.
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let ptr = System.alloc(layout);
        if !ptr.is_null() {
            count(layout.size() as i64);
        }
        ptr
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let ptr = System.alloc_zeroed(layout);
        if !ptr.is_null() {
            count(layout.size() as i64);
        }
        ptr
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout);
        count(-(layout.size() as i64));
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let new = System.realloc(ptr, layout, new_size);
        if !new.is_null() {
            count(new_size as i64 - layout.size() as i64);
        }
        new
    }
}

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

/// Bytes the calling thread has allocated and not freed since it started.
pub fn thread_bytes() -> i64 {
    THREAD_BYTES.try_with(Cell::get).unwrap_or(0)
}

/// Runs `f` and returns its result with the bytes it left allocated on this thread (0 if it
/// freed more than it allocated).
pub fn measure<T>(f: impl FnOnce() -> T) -> (T, u64) {
    let before = thread_bytes();
    let out = f();
    (out, (thread_bytes() - before).max(0) as u64)
}

/// `bytes` as a person reads them: `31.0 KiB`, `4.2 GiB`.
pub fn human(bytes: u64) -> String {
    let units = ["bytes", "KiB", "MiB", "GiB", "TiB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < units.len() {
        value /= 1024.0;
        unit += 1;
    }
    match unit {
        0 => format!("{bytes} bytes"),
        _ => format!("{value:.1} {}", units[unit]),
    }
}

/// Asks the system for `bytes` at once and gives them back: an [`Error::Memory`] saying `what`
/// needs them when it refuses (an address-space limit, a container's), so that building does
/// not abort halfway. Pages are not touched, so this costs no physical memory.
pub fn reserve(bytes: u64, what: &str) -> Result<()> {
    let refused = || {
        Error::Memory(format!(
            "{what} needs about {} and the system cannot provide it",
            human(bytes)
        ))
    };
    let size = usize::try_from(bytes).map_err(|_| refused())?;
    let mut probe: Vec<u8> = Vec::new();
    probe.try_reserve_exact(size).map_err(|_| refused())?;
    drop(probe);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn measure_counts_what_a_closure_keeps_on_this_thread() {
        let (kept, bytes) = measure(|| vec![0u8; 100_000]);
        assert!((100_000..110_000).contains(&bytes), "{bytes}");
        drop(kept);
        let ((), freed) = measure(|| drop(vec![0u8; 1_000]));
        assert_eq!(freed, 0);
    }

    #[test]
    fn reserving_more_than_the_address_space_is_a_memory_error() {
        let e = reserve(u64::MAX / 2, "this").unwrap_err();
        assert!(matches!(e, Error::Memory(_)), "{e}");
        assert!(e.to_string().starts_with("this needs about"), "{e}");
        reserve(1 << 20, "a mebibyte").expect("1 MiB");
        assert_eq!(human(31 * 1024), "31.0 KiB");
        assert_eq!(human(100), "100 bytes");
    }
}
