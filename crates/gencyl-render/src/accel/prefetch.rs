//! Loading memory ahead of its use: the BVH walk asks for the nodes and cylinders it may read
//! next while it tests the current node, so their cache misses overlap instead of queueing one
//! after the other (the walk's loads are a dependent chain: a node names its children).

/// Starts loading every cache line of `x` (64 bytes each) into all cache levels and returns at
/// once: a hint to the CPU that reads nothing the program can see and cannot fault. No-op off
/// x86-64. A type aligned to a line (a BVH node) starts one, so its lines are the bytes 0, 64,
/// ... of it (a 256-byte node four, not the five of an unaligned run).
#[inline(always)]
pub fn prefetch<T>(x: &T) {
    let p = (x as *const T).cast::<u8>();
    if align_of::<T>() >= 64 {
        for offset in (0..size_of::<T>()).step_by(64) {
            prefetch_line(p.wrapping_add(offset));
        }
    } else {
        prefetch_bytes(p, size_of::<T>());
    }
}

/// [`prefetch`] of the `len` bytes at `p` (meant for live data; the hint is harmless for any
/// address: it cannot fault and reads nothing the program sees).
#[inline(always)]
pub fn prefetch_bytes(p: *const u8, len: usize) {
    // The lines of bytes 0, 64, 128, ... and of the last byte (`p` need not start a line).
    let last = len.saturating_sub(1);
    let mut offset = 0;
    while offset <= last + 63 {
        prefetch_line(p.wrapping_add(offset.min(last)));
        offset += 64;
    }
}

/// Starts loading the cache line that holds `p`.
#[inline(always)]
fn prefetch_line(p: *const u8) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        // SAFETY: `_mm_prefetch` dereferences nothing (a prefetch of any address is harmless,
        // even one past the caller's data); SSE, which it needs, is part of the x86-64
        // baseline.
        #[allow(unsafe_code)]
        unsafe {
            _mm_prefetch::<_MM_HINT_T0>(p.cast::<i8>());
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}
