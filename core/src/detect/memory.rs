//! How the process asks the system for memory: a choice for the whole process, so each program
//! that runs the detector (the `tagsmith` binary, the Python module) makes it once at start.
//!
//! The networks allocate and free buffers of megabytes for every layer of every pass. glibc serves
//! blocks that large with fresh `mmap`s and hands them back with `munmap` on free; each return
//! makes the kernel interrupt every core to flush its address translations, and each new block is
//! zeroed page by page on first touch. Profiled on a 1280×960 detection, that was a fifth of the
//! time (`native_write_msr`, `smp_call_function_many_cond`, page faults), and stage 1 ran
//! 1.3–1.6× faster once the blocks stayed in the heap (docs/BENCHMARKS-HISTORY.md, "Earlier the same day: the first shipped stage 1").

/// Keeps blocks up to 256 MB in the heap and lets it hold up to 512 MB of freed memory before
/// returning any to the system: the freed buffers of one layer serve the next. The price is a
/// resident size that stays at the peak of the largest pass instead of shrinking between passes.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
pub fn keep_large_buffers() {
    // SAFETY: mallopt only changes glibc's allocation thresholds, under the main arena's lock.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 256 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 512 << 20);
    }
}

/// Other systems' allocators keep large blocks already (or are not ours to tune).
#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
pub fn keep_large_buffers() {}
