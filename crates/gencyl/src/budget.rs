//! The work bounds of the root searches, and a count of the searches that reached theirs.
//!
//! Every search of the intersector is bounded in depth and in work: the 1D isolator in
//! evaluations ([`crate::roots::IsolateOptions::max_evaluations`]), the 2D one in boxes, the
//! round-fiber branches in cells, the general method's curve-curve subdivision in piece pairs.
//! Each has a defined outcome when its bound is reached: what is left of the search is settled
//! by sign changes at the ends of its cells (the 1D searches), by the chords of its pieces
//! (curve-curve), or dropped (2D boxes). The hits of such a search can be incomplete, so each
//! one is counted here, process-wide, for a program to report ("N searches reached their work
//! bound"). A count above zero means geometry at the edge of what f64 resolves, or more
//! crossings in one range than the searches keep: the 1D isolator keeps
//! [`crate::roots::MAX_ROOTS`] roots, which the Radial method extends by splitting its cells
//! and the General method by splitting its half ranges (to 12 cells at once; a fiber twisted
//! by many turns in one segment, seen along its axis, which the scene format allows, can cross
//! a ray more often: tested to 162 crossings, 40 turns, on lenses of ratio 0.3 to 0.8).
//! Geometry within the usual twists does not reach them in the test suite.

use std::cell::Cell;
use std::sync::atomic::{AtomicU64, Ordering};

static EXHAUSTED: AtomicU64 = AtomicU64::new(0);

thread_local! {
    /// The same count for the searches run on this thread (tests run side by side in one
    /// process: each asks about its own searches).
    static EXHAUSTED_HERE: Cell<u64> = const { Cell::new(0) };
}

/// How many root searches reached their work bound since the process started.
pub fn exhausted_searches() -> u64 {
    EXHAUSTED.load(Ordering::Relaxed)
}

/// Counts one search that reached its work bound.
pub(crate) fn note_exhausted() {
    EXHAUSTED.fetch_add(1, Ordering::Relaxed);
    EXHAUSTED_HERE.with(|n| n.set(n.get() + 1));
}

/// How many root searches run on this thread reached their work bound.
#[cfg(test)]
pub(crate) fn exhausted_here() -> u64 {
    EXHAUSTED_HERE.with(Cell::get)
}
