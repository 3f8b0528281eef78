//! The memory bound of a `phalanx` run: the binary's allocator counts the bytes it holds,
//! and an allocation that would take it past the bound ends the run with a message and exit
//! code [`EXIT_MEMORY`] instead of a kill by the system's out-of-memory killer.
//!
//! The bound is `--memory-limit SIZE` (or `PHALANX_MEMORY_LIMIT`), `none` for no bound; by
//! default 90 % of the memory the system reports available when the run starts
//! (`MemAvailable` of `/proc/meminfo`; no bound where it cannot be read). Outputs are written
//! atomically, so a run ended this way leaves no half-written file (docs/errors.md).

use std::alloc::{GlobalAlloc, Layout, System};
use std::io::Write as _;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Tells glibc's malloc to keep what the program frees: by default it hands blocks over
/// 32 MiB (and the top of its heap) back to the kernel on free, so the tensors of every
/// training update (tens of MB each) were mapped and faulted in afresh at every update, and a
/// fine-tuning on 128² maps spent two thirds of its time in the kernel (docs/learning.md,
/// *The allocator*). The same arithmetic, the same bytes out; only where memory comes from.
pub(crate) fn keep_freed() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets two of malloc's parameters; called first in `main`, before
    // any other thread exists.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, libc::c_int::MAX);
        libc::mallopt(libc::M_TRIM_THRESHOLD, libc::c_int::MAX);
    }
}

/// The run would have used more memory than its bound.
pub(crate) const EXIT_MEMORY: i32 = 5;

/// Bytes held by the program's allocations.
static HELD: AtomicUsize = AtomicUsize::new(0);
/// The most bytes held at once so far.
static PEAK: AtomicUsize = AtomicUsize::new(0);
/// The bound (`usize::MAX`: none).
static LIMIT: AtomicUsize = AtomicUsize::new(usize::MAX);

/// Bytes the program's allocations hold now.
pub(crate) fn held() -> usize {
    HELD.load(Ordering::Relaxed)
}

/// The most bytes held at once since the start.
pub(crate) fn peak() -> usize {
    PEAK.load(Ordering::Relaxed)
}

/// [`System`], counting, with the bound.
pub(crate) struct Bounded;

impl Bounded {
    /// Counts `size` more bytes, or ends the run if they pass the bound.
    fn take(size: usize) {
        let held = HELD.fetch_add(size, Ordering::Relaxed).saturating_add(size);
        let limit = LIMIT.load(Ordering::Relaxed);
        if held > limit {
            HELD.fetch_sub(size, Ordering::Relaxed);
            over(size, held - size, limit);
        }
        PEAK.fetch_max(held, Ordering::Relaxed);
    }

    /// `ptr`, uncounting `size` if the system refused the allocation (null).
    fn held(ptr: *mut u8, size: usize) -> *mut u8 {
        if ptr.is_null() {
            HELD.fetch_sub(size, Ordering::Relaxed);
        }
        ptr
    }
}

// SAFETY: every call is passed on to `System` unchanged; the counters are atomics.
unsafe impl GlobalAlloc for Bounded {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        Self::take(layout.size());
        // SAFETY: the caller's contract, passed on.
        Self::held(unsafe { System.alloc(layout) }, layout.size())
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        Self::take(layout.size());
        // SAFETY: the caller's contract, passed on.
        Self::held(unsafe { System.alloc_zeroed(layout) }, layout.size())
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        HELD.fetch_sub(layout.size(), Ordering::Relaxed);
        // SAFETY: the caller's contract, passed on.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if new_size > layout.size() {
            Self::take(new_size - layout.size());
            // SAFETY: the caller's contract, passed on.
            Self::held(unsafe { System.realloc(ptr, layout, new_size) }, new_size - layout.size())
        } else {
            HELD.fetch_sub(layout.size() - new_size, Ordering::Relaxed);
            // SAFETY: the caller's contract, passed on.
            unsafe { System.realloc(ptr, layout, new_size) }
        }
    }
}

/// A message in a buffer on the stack: the allocator cannot allocate to report.
struct StackText {
    buf: [u8; 512],
    len: usize,
}

impl std::fmt::Write for StackText {
    fn write_str(&mut self, s: &str) -> std::fmt::Result {
        let n = s.len().min(self.buf.len() - self.len);
        self.buf[self.len..self.len + n].copy_from_slice(&s.as_bytes()[..n]);
        self.len += n;
        Ok(())
    }
}

/// Reports the bound and ends the run (no destructor runs; outputs are atomic).
fn over(size: usize, held: usize, limit: usize) -> ! {
    let mut text = StackText { buf: [0; 512], len: 0 };
    let _ = std::fmt::Write::write_fmt(
        &mut text,
        format_args!(
            "error: the run needs more memory than its bound of {} MiB (an allocation of {} MiB \
             on top of {} MiB held); raise it with --memory-limit SIZE or PHALANX_MEMORY_LIMIT \
             (e.g. 16G, or none), or give a smaller instance\n",
            limit >> 20,
            size >> 20,
            held >> 20
        ),
    );
    let _ = std::io::stderr().write_all(&text.buf[..text.len]);
    std::process::exit(EXIT_MEMORY)
}

/// Parses a size: bytes, or a number with `K`, `M`, `G` or `T` (binary units); `none`.
pub(crate) fn parse_size(text: &str) -> Result<Option<u64>, String> {
    let text = text.trim();
    if text.eq_ignore_ascii_case("none") {
        return Ok(None);
    }
    let (number, unit) = match text.char_indices().find(|(_, c)| c.is_ascii_alphabetic()) {
        Some((i, _)) => text.split_at(i),
        None => (text, ""),
    };
    let shift = match unit.to_ascii_uppercase().trim_end_matches(['B', 'I']) {
        "" => 0,
        "K" => 10,
        "M" => 20,
        "G" => 30,
        "T" => 40,
        _ => return Err(format!("{text:?}: not a size (e.g. 512M, 16G or none)")),
    };
    let value: f64 = number
        .trim()
        .parse()
        .map_err(|_| format!("{text:?}: not a size (e.g. 512M, 16G or none)"))?;
    if !(value.is_finite() && value > 0.0) {
        return Err(format!("{text:?}: a memory bound must be positive (or none)"));
    }
    let bytes = value * (1u64 << shift) as f64;
    if bytes < MIN_LIMIT as f64 {
        return Err(format!("{text:?}: below the least a run needs, {} MiB", MIN_LIMIT >> 20));
    }
    Ok(Some(bytes.min(u64::MAX as f64) as u64))
}

/// The smallest memory bound accepted: less and no run could start.
const MIN_LIMIT: u64 = 4 << 20;

/// The default bound: 90 % of `MemAvailable`, `None` where `/proc/meminfo` says nothing.
fn default_limit() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024 / 10 * 9)
}

/// Sets the bound: `flag` (from `--memory-limit`), else `PHALANX_MEMORY_LIMIT`, else the
/// default. Returns the bound set, `None` for none.
///
/// # Errors
/// A value that is not a size, naming where it came from.
pub(crate) fn set_limit(flag: Option<&str>) -> Result<Option<u64>, String> {
    let limit = match (flag, std::env::var("PHALANX_MEMORY_LIMIT")) {
        (Some(text), _) => parse_size(text).map_err(|err| format!("--memory-limit {err}"))?,
        (None, Ok(text)) => {
            parse_size(&text).map_err(|err| format!("PHALANX_MEMORY_LIMIT {err}"))?
        }
        (None, Err(_)) => default_limit(),
    };
    let bytes = limit.map_or(usize::MAX, |it| usize::try_from(it).unwrap_or(usize::MAX));
    LIMIT.store(bytes, Ordering::Relaxed);
    Ok(limit)
}
