//! Cells of [`Radial`]'s isolation left for later: a nearest-hit query isolates the cell
//! nearest along the ray first and stops before the others.
//!
//! A ray through an elliptical fiber splits its `u` range into three cells
//! ([`first_cells`]): the entry's, the middle (where `g` stays negative) and the exit's; the
//! cut beyond the root nearer along the ray (between the middle and the other side) waits
//! until a query reaches those cells (one cell until then, and one value of `g` fewer for a
//! query that stops at the nearer crossing: the elliptical ponytail's camera rays took 1.8%
//! fewer instructions). Each
//! is placed along the ray by an enclosure of `w(u) = a'.(a - o) / (a'.d)` over it (from the
//! Bernstein forms of its numerator and denominator on the cell,
//! [`GeneralizedCylinder::plane_w_bounds`]; on these ranges the ray is [`super::OBLIQUE`], so
//! `a'.d` keeps its sign), and isolated and polished only when a query
//! reaches its lower bound. A query that takes the nearest hit then pays for one cell's
//! enclosures and one Newton solve, not three cells and two. A cell with more roots than one
//! isolation keeps (a fiber twisted by many turns, seen along its axis) is split in two when
//! reached, and the halves wait in turn; a query that takes every hit isolates its cells at
//! once unless one isolation cannot keep them all.
//!
//! The General method's ranges on a Bezier-loop section wait here too, as two halves each
//! ([`RadialCells::add_profile`]): a half is searched, every piece of the section on it
//! ([`GeneralizedCylinder::general_window_roots`]), when a query reaches its lower bound of `w`,
//! so a nearest-hit query usually searches only the half that holds the entry. A half whose
//! searches find more roots than they keep is split in two in turn.

use arrayvec::ArrayVec;
use glam::DVec3;

use super::curve_curve::Found;
use super::round::CellCrossing;
use super::{Radial, SideRoots};
use crate::cylinder::GeneralizedCylinder;
use crate::roots::{
    Cell, FirstCells, FirstRoot, Function1D, Hints, IsolateOptions, PendingCut, first_cells,
    isolate_in_cells,
};
use crate::section::CrossSection;
use crate::sweep::SweepRule;

/// Most cells a [`RadialCells`] keeps at once (a ray near a fiber usually brings three; a cell
/// with more roots than one isolation keeps is split in two, into its own slot and a free
/// one).
pub(crate) const MAX_RADIAL_CELLS: usize = 12;

/// A cell of [`Radial`] (`R = 1`) not yet isolated: its ends and values there, the [`Hints`] of
/// the samples that placed it (estimates of roots that start Newton's method), and bounds of
/// `w` over it ([`GeneralizedCylinder::plane_w_bounds`], about the ray's point in the normal
/// plane at the middle of the range, or of the parent cell for the halves of a split one),
/// padded by `1e-9 max|a'| / |d|` and `1e-12 |w|`. The bounds enclose `w` for the ray through
/// the rounded shifted origin; what the pad covers is far smaller: that origin's rounding off the
/// ray (at most `1e3` times its ulp over `|d|`, at the least obliqueness the Radial method
/// isolates, `|a'.d| >= 1e-3 max|a'| |d|`), and a root's refinement in `w`
/// ([`GeneralizedCylinder::refined_w`]: `|w'|` times a few ulps of `u`, about
/// `1e-12 max|a'| / |d|`). An independent review of the earlier Taylor bounds found every
/// root at least 100 pads inside its cell's bounds (20,000 fibers, radii to 30 times the
/// length); one of these bounds found no `w` outside them by more than 8 ulps, unpadded, in
/// 200,000 spans against double-double values (straight to nearly cusped axes 1e-6 to 10
/// long at up to 1e6 from the origin, rays to 1e-15 off perpendicular), once a span reaching
/// below `u = 0` was restricted from its start ([`crate::bernstein::Bernstein::restrict`]).
#[derive(Clone, Copy, Debug)]
struct Deferred {
    work: Work,
    w: [f64; 2],
}

/// What a deferred cell holds.
#[derive(Clone, Copy, Debug)]
enum Work {
    /// A cell of [`Radial`] (`R = 1`), with the [`Hints`] of the samples that placed it, and
    /// the cut that splits it where that waits (the cells beyond the nearer root).
    Radial {
        cell: Cell,
        hints: Hints,
        cut: Option<PendingCut>,
    },
    /// Half of a range of the General method's where `phi` lies in the section's bounding
    /// disc of radius `disc` ([`GeneralizedCylinder::general_window_roots`]): every piece of the
    /// section is searched on it when it is reached, roots `u` kept in `valid`.
    Profile {
        range: (f64, f64),
        disc: f64,
        valid: (f64, f64),
    },
}

/// [`Radial`]'s cells waiting for a query to reach them (see the module docs).
pub(crate) struct RadialCells {
    cells: ArrayVec<Deferred, MAX_RADIAL_CELLS>,
    /// Whether cells wait for the walk (a query that may stop early), or are isolated at once
    /// (every hit wanted: the bounds would save nothing), deferred only where one isolation
    /// cannot keep all their roots.
    lazy: bool,
    /// Slots of cells isolated without a split: no pending crossing refers to them any more,
    /// and a split's second half may take one.
    free: ArrayVec<usize, MAX_RADIAL_CELLS>,
}

impl RadialCells {
    pub(crate) fn new(lazy: bool) -> Self {
        RadialCells {
            cells: ArrayVec::new(),
            lazy,
            free: ArrayVec::new(),
        }
    }

    /// Defers the cells of the oblique range `[a, b]` (`rising`: `a'.d > 0` there,
    /// [`GeneralizedCylinder::obliquity`]) and returns their indices, or isolates them into
    /// `out` at once where the cells are not lazy (and one isolation keeps all their roots) or
    /// there is no room for them.
    pub(crate) fn add<C: CrossSection, S: SweepRule>(
        &mut self,
        cyl: &GeneralizedCylinder<C, S>,
        (o, d): (DVec3, DVec3),
        (a, b): (f64, f64),
        rising: bool,
        out: &mut SideRoots,
    ) -> ArrayVec<usize, 3> {
        let (f, opts) = unit_radial(cyl, (o, d));
        // Room for the most cells `first_cells` gives.
        let room = self.cells.remaining_capacity() >= 3;
        // A lazy query wants the root nearer along the ray first: the lower end's where `w`
        // rises with `u` (`rising`: `a'.d > 0` on the oblique range; near the axis the ray's
        // point in the normal plane moves by `|a'|^2 / a'.d`). Guessing wrong costs the cut.
        let first = match (self.lazy && room, rising) {
            (false, _) => FirstRoot::Both,
            (true, true) => FirstRoot::Low,
            (true, false) => FirstRoot::High,
        };
        let FirstCells {
            cells,
            hints,
            pending,
        } = first_cells(&f, a, b, &opts, first);
        if !self.lazy || !room {
            let mut us = ArrayVec::new();
            let found = isolate_in_cells(&f, &cells, hints, &opts, &mut us);
            if !found.overflow || !room {
                if found.overflow && found.complete {
                    crate::budget::note_exhausted();
                }
                push_roots(cyl, (o, d), &us, out);
                return ArrayVec::new();
            }
        }
        let first = self.cells.len();
        self.cells
            .extend(place(cyl, (o, d), (a, b), &cells, hints, pending));
        (first..self.cells.len()).collect()
    }

    /// The deferred cells: index, lower and upper bound of `w`, and what each holds.
    pub(crate) fn bounds(&self) -> impl Iterator<Item = (usize, [f64; 2], CellCrossing)> + '_ {
        (0..self.cells.len()).map(|i| {
            let (w, holds) = self.cell(i);
            (i, w, holds)
        })
    }

    /// Defers `spans` of one of the General method's ranges (adjacent and ascending; `phi`
    /// lies in the disc of radius `disc` there, or the spans are searched as if it did: `phi`
    /// is finite on an oblique range), each placed by bounds of `w` over it, and returns true;
    /// false (nothing deferred) where they and `spare` more cells do not fit. A range's two
    /// halves ([`profile_halves`]) keep one spare cell, for the rest of the range when the
    /// windows of the disc are more than the cells hold (deferred whole, and split when its
    /// searches overflow). A query for the nearest hit then usually searches the half that
    /// holds the entry and stops; a query for every hit reaches both, and their roots join the
    /// walk's list in order (as many as it holds, where one range's list of side roots could
    /// overflow and drop the nearest).
    pub(crate) fn add_profile<C: CrossSection, S: SweepRule>(
        &mut self,
        cyl: &GeneralizedCylinder<C, S>,
        (o, d): (DVec3, DVec3),
        spans: &[(f64, f64)],
        (disc, valid): (f64, (f64, f64)),
        spare: usize,
    ) -> bool {
        if self.cells.remaining_capacity() < spans.len() + spare {
            return false;
        }
        self.cells
            .extend(profile_cells(cyl, (o, d), spans, disc, valid));
        true
    }

    /// Cell `i`'s bounds of `w`, and what it holds: for a Radial cell, a crossing whose
    /// direction is not known where `g` has opposite signs at its ends (an odd number of roots:
    /// at least one, where the ray passes from inside the section to outside or back), else
    /// possibly nothing.
    pub(crate) fn cell(&self, i: usize) -> ([f64; 2], CellCrossing) {
        let c = &self.cells[i];
        let holds = match c.work {
            Work::Radial { cell, .. } => {
                let (fa, fb) = (cell.2, cell.3);
                let changes = (fa < 0.0 && fb > 0.0) || (fa > 0.0 && fb < 0.0);
                if changes {
                    CellCrossing::Either
                } else {
                    CellCrossing::Unsure
                }
            }
            Work::Profile { .. } => CellCrossing::Unsure,
        };
        (c.w, holds)
    }

    /// Isolates cell `i` into `out` (as an eager isolation would have given its roots; a
    /// General method's half range: searches it), and returns no cells; or, where it holds more
    /// roots than one isolation keeps ([`crate::roots::MAX_ROOTS`]; a half range: more than
    /// its searches keep; a fiber twisted by many turns, seen along its axis), defers its two
    /// halves instead (a cell whose cut waited: the two cells of the cut, as an eager
    /// isolation defers them) and returns them, for the walk to reach the nearer first.
    /// Where there is no room for them the roots kept (the lowest `u`'s) go to `out` and the
    /// search is counted as one that reached its bound.
    pub(crate) fn isolate<C: CrossSection, S: SweepRule>(
        &mut self,
        i: usize,
        cyl: &GeneralizedCylinder<C, S>,
        (o, d): (DVec3, DVec3),
        out: &mut SideRoots,
    ) -> ArrayVec<usize, 3> {
        let (cell, hints, cut) = match self.cells[i].work {
            Work::Radial { cell, hints, cut } => (cell, hints, cut),
            Work::Profile { range, disc, valid } => {
                let mut found = Found::new();
                let all = cyl.general_window_roots((o, d), range, disc, valid, &mut found);
                let (a, b) = range;
                let halves = profile_halves(a, b);
                if !all && halves.len() == 2 && self.has_room() {
                    // More roots than the searches keep: the halves wait instead.
                    let placed = profile_cells(cyl, (o, d), &halves, disc, valid);
                    return self.replace(i, [placed[0], placed[1]]);
                }
                if !all {
                    crate::budget::note_exhausted();
                }
                cyl.push_general_roots(o, d, &mut found, out);
                let _ = self.free.try_push(i);
                return ArrayVec::new();
            }
        };
        let (f, opts) = unit_radial(cyl, (o, d));
        let mut us = ArrayVec::new();
        // The cells beyond the nearer root are cut now, and isolated together.
        let (cells, hints) = match cut {
            Some(cut) => cut.make(&f, cell, hints),
            None => (ArrayVec::from_iter([cell]), hints),
        };
        let found = isolate_in_cells(&f, &cells, hints, &opts, &mut us);
        let (a, b, fa, fb) = cell;
        let mid = 0.5 * (a + b);
        if found.overflow {
            if cells.len() == 2 && self.has_room() {
                // The cut's two cells wait apart, as an eager isolation that overflows defers
                // its cells.
                let placed = place(cyl, (o, d), (a, b), &cells, hints, None);
                return self.replace(i, [placed[0], placed[1]]);
            }
            if self.has_room() && a < mid && mid < b {
                let fm = f.eval(mid);
                let halves = [(a, mid, fa, fm), (mid, b, fm, fb)];
                let placed = place(cyl, (o, d), (a, b), &halves, hints.for_part(), None);
                return self.replace(i, [placed[0], placed[1]]);
            }
            if found.complete {
                crate::budget::note_exhausted();
            }
        }
        push_roots(cyl, (o, d), &us, out);
        let _ = self.free.try_push(i);
        ArrayVec::new()
    }

    /// Whether a cell being isolated may give way to two.
    fn has_room(&self) -> bool {
        !self.cells.is_full() || !self.free.is_empty()
    }

    /// Cell `i`, reached, replaced by `halves`: the first takes its place (the walk has let go
    /// of it), the second a finished cell's, or a new one. Returns their indices.
    fn replace(&mut self, i: usize, halves: [Deferred; 2]) -> ArrayVec<usize, 3> {
        self.cells[i] = halves[0];
        let j = match self.free.pop() {
            Some(j) => {
                self.cells[j] = halves[1];
                j
            }
            None => {
                self.cells.push(halves[1]);
                self.cells.len() - 1
            }
        };
        ArrayVec::from_iter([i, j])
    }
}

/// The halves of the General method's range `[a, b]` that [`RadialCells::add_profile`]
/// defers, and that a query for every hit searches in turn (the same searches, so the roots
/// are the same to the bit): `[a, m]` and `[m, b]` at the midpoint, or `[a, b]` where that has
/// no float inside.
pub(crate) fn profile_halves(a: f64, b: f64) -> ArrayVec<(f64, f64), 2> {
    let m = 0.5 * (a + b);
    if a < m && m < b {
        ArrayVec::from([(a, m), (m, b)])
    } else {
        ArrayVec::from_iter([(a, b)])
    }
}

/// The General method's `halves` (adjacent, ascending) to defer, each placed by bounds of `w`
/// ([`w_bounds`], about the middle of their union). Roots of the subdivision's pieces may converge just
/// outside a half: its bounds are taken over the half grown by a hundredth of the union at
/// each end (within the union; a half of a half split again is grown within its parent).
fn profile_cells<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    (o, d): (DVec3, DVec3),
    halves: &[(f64, f64)],
    disc: f64,
    valid: (f64, f64),
) -> ArrayVec<Deferred, 2> {
    let (a, b) = (halves[0].0, halves[halves.len() - 1].1);
    let grow = 0.01 * (b - a);
    let spans: ArrayVec<(f64, f64), 2> = halves
        .iter()
        .map(|&(x, y)| ((x - grow).max(a), (y + grow).min(b)))
        .collect();
    halves
        .iter()
        .zip(w_bounds(cyl, (o, d), (a, b), &spans))
        .map(|(&range, w)| Deferred {
            work: Work::Profile { range, disc, valid },
            w,
        })
        .collect()
}

/// [`Radial`] for the unit circle (`R = 1`) and its isolation settings.
fn unit_radial<'a, C: CrossSection, S: SweepRule>(
    cyl: &'a GeneralizedCylinder<C, S>,
    (o, d): (DVec3, DVec3),
) -> (Radial<'a, C, S>, IsolateOptions) {
    let f = Radial {
        cyl,
        o,
        d,
        radius: 1.0,
    };
    (f, cyl.radial_options(d, 1.0))
}

/// `cells` (within `[a, b]`) to defer, each with bounds of `w` ([`w_bounds`]), and the cut
/// that waits in one of them.
fn place<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    (o, d): (DVec3, DVec3),
    (a, b): (f64, f64),
    cells: &[Cell],
    hints: Hints,
    pending: Option<(usize, PendingCut)>,
) -> ArrayVec<Deferred, 3> {
    let spans: ArrayVec<(f64, f64), 3> = cells.iter().map(|c| (c.0, c.1)).collect();
    cells
        .iter()
        .zip(w_bounds(cyl, (o, d), (a, b), &spans))
        .enumerate()
        .map(|(i, (&cell, w))| Deferred {
            work: Work::Radial {
                cell,
                hints,
                cut: pending.filter(|p| p.0 == i).map(|p| p.1),
            },
            w,
        })
        .collect()
}

/// Bounds of `w` over each of `spans` (within `[a, b]`), each from the Bernstein forms of its
/// numerator and denominator on the span ([`GeneralizedCylinder::plane_w_bounds`], about the
/// ray's point in the normal plane at the middle of `[a, b]`), padded (see [`Deferred`]).
fn w_bounds<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    (o, d): (DVec3, DVec3),
    (a, b): (f64, f64),
    spans: &[(f64, f64)],
) -> ArrayVec<[f64; 2], 3> {
    let (shift, bounds) = cyl.plane_w_bounds(o, d, 0.5 * (a + b), spans);
    // max|a'| / |d|.
    let speed = cyl.q_scale(d) / d.length_squared();
    bounds
        .into_iter()
        .map(|e| {
            let (lo, hi) = (shift + e.lo, shift + e.hi);
            let pad = 1e-9 * speed + 1e-12 * lo.abs().max(hi.abs());
            if lo.is_nan() || hi.is_nan() {
                [f64::NEG_INFINITY, f64::INFINITY]
            } else {
                [lo - pad, hi + pad]
            }
        })
        .collect()
}

/// The hits of the roots `us` of [`Radial`] (`R = 1`), polished into `out`.
fn push_roots<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    (o, d): (DVec3, DVec3),
    us: &[f64],
    out: &mut SideRoots,
) {
    for &u in us {
        cyl.push_circle_root(o, d, u, out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Ray;
    use crate::cylinder::FiberSpec;
    use crate::intersect::{U_MARGIN, prefilter, widen};
    use crate::test_rng::Lcg as Rng;

    /// A nearest-hit query, whose cells wait and whose cut beyond the nearer root waits, finds
    /// the first hit of every hit's query to the bit, where cells hold more crossings than one
    /// isolation keeps: an elliptical fiber (ellipticity 0.3) twisted by 60 and 200 rad along
    /// a nearly straight axis, rays from inside it nearly along it (the review's case: a
    /// waiting cut's two cells that overflow together wait apart, as the eager isolation's do;
    /// split at their midpoint instead, the last bits of some hits differed).
    #[test]
    fn overflowing_cells_keep_the_first_hit_of_every_hit() {
        let mut rng = Rng(29);
        let (mut compared, mut many) = (0, 0);
        for twist in [60.0, 200.0] {
            let k = 0.001 * 2.0 / 3.0;
            let spec = FiberSpec {
                major_radius: [0.05, 0.05],
                minor_radius: [0.015, 0.015],
                rotation: [0.0, twist],
                ..FiberSpec::round(
                    [
                        DVec3::ZERO,
                        DVec3::new(k, 0.0, 1.0 / 3.0),
                        DVec3::new(k, 0.0, 2.0 / 3.0),
                        DVec3::Z,
                    ],
                    0.05,
                )
            };
            let cyl = spec.build().unwrap();
            let mut all = Vec::new();
            for _ in 0..1000 {
                let o = DVec3::new(
                    rng.range(-0.01, 0.01),
                    rng.range(-0.01, 0.01),
                    rng.range(0.05, 0.95),
                );
                let along = if rng.range(0.0, 1.0) < 0.5 { 1.0 } else { -1.0 };
                let d = DVec3::new(rng.range(-0.03, 0.03), rng.range(-0.03, 0.03), along);
                let ray = Ray::new(o, d);
                all.clear();
                cyl.intersect_all(&ray, 0.0, f64::INFINITY, &mut all);
                let first = cyl.intersect(&ray, 0.0, f64::INFINITY);
                assert_eq!(first, all.first().copied(), "twist {twist}, ray {ray:?}");
                compared += 1;
                many += usize::from(all.len() > crate::roots::MAX_ROOTS);
            }
        }
        assert!(
            many > 150,
            "{many} of {compared} rays cross the fiber's side that often"
        );
    }

    /// Every deferred cell's bounds of `w` hold `w(u) = a'.(a - o)/(a'.d)` at points across
    /// the cell (plain `f64` evaluations, apart from the Bernstein forms that bound it) and the
    /// `w` of each root isolated in it; a cell said to hold a crossing holds an odd number of
    /// roots; and the cells' roots, isolated one by one, are the eager isolation's to the bit.
    /// Elliptical fibers, twisted and tapering, on curved axes (Frenet and projected frames),
    /// major radii from 1e-6 to 1e-1 of the length, every fifth at 1e4 from the origin; rays
    /// at angles to the axis from 1e-3 off perpendicular (the Radial method's limit) to along
    /// it, log-uniform, passing the axis at grazing depths down to 1e-9 of the radius, some
    /// starting on the surface.
    #[test]
    fn cells_bound_w_and_hold_the_eager_roots() {
        let mut rng = Rng(83);
        let (mut cells_checked, mut roots_checked, mut crossings) = (0, 0, 0);
        let mut cuts_waiting = [0; 2];
        for case in 0..3000 {
            let offset = if case % 5 == 0 {
                DVec3::splat(1e4)
            } else {
                DVec3::ZERO
            };
            let bezier: [DVec3; 4] = std::array::from_fn(|j| {
                offset + DVec3::new(j as f64 / 3.0, rng.range(-0.3, 0.3), rng.range(-0.3, 0.3))
            });
            let r = 10f64.powf(rng.range(-6.0, -1.0));
            let k = rng.range(0.2, 0.9);
            let taper = rng.range(0.5, 2.0);
            let spec = FiberSpec {
                bezier,
                major_radius: [r, r * taper],
                minor_radius: [k * r, k * r * taper],
                rotation: [rng.range(-3.0, 3.0), rng.range(-3.0, 3.0)],
                caps: true,
                normal_hint: (case % 2 == 0).then(|| rng.unit()),
                section: Default::default(),
            };
            let Ok(cyl) = spec.build() else { continue };
            let axis = crate::curve::CubicBezier::new(bezier);
            let u = rng.range(0.02, 0.98);
            let t = axis.d1(u).normalize();
            let across = (rng.unit() - t * rng.unit().dot(t)).normalize();
            // cos of the angle to the axis: 1e-3 to 1, log-uniform.
            let c = 10f64.powf(rng.range(-3.0, 0.0));
            let side = rng.unit().cross(t).normalize();
            let d = (c * t + (1.0 - c * c).sqrt() * side).normalize();
            let d = if case % 3 == 0 { -d } else { d };
            // Passing the axis at 1 - 1e-9 .. 0 of the major or the minor radius.
            let depth = 1.0 - 10f64.powf(rng.range(-9.0, 0.0));
            let reach = if case % 2 == 0 { r } else { k * r };
            let target = axis.point(u) + depth * reach * across;
            let o = if case % 4 == 0 {
                cyl.surface_point(u, rng.range(0.0, std::f64::consts::TAU))
            } else {
                target - 2.0 * r * d / c.max(1e-2)
            };
            // The local ray, as `each_hit` makes it.
            let o = o - cyl.origin;
            let (lo, hi) = (-U_MARGIN, 1.0 + U_MARGIN);
            for (a, b) in prefilter::candidate_ranges(&cyl, o, d, |_, _| true) {
                let (a, b) = widen(a, b, lo, hi);
                let Some(rising) = cyl.obliquity(d, a, b) else {
                    continue;
                };
                // The cut beyond the root taken first waits, on whichever side that is.
                let mut cells = RadialCells::new(true);
                let mut eager = SideRoots::new();
                let rising = if case % 2 == 0 { rising } else { !rising };
                cells.add(&cyl, (o, d), (a, b), rising, &mut eager);
                assert!(eager.is_empty(), "case {case}: room for the cells");
                let mut lazy = Vec::new();
                for i in 0..cells.cells.len() {
                    let ([w0, w1], holds) = cells.cell(i);
                    let Work::Radial { cell, cut, .. } = cells.cells[i].work else {
                        panic!("case {case}: a Radial cell");
                    };
                    cuts_waiting[usize::from(rising)] += usize::from(cut.is_some());
                    let (ca, cb, _, _) = cell;
                    for j in 0..=32 {
                        let x = ca + (cb - ca) * j as f64 / 32.0;
                        let w = cyl.plane_w_r(o, d, x);
                        assert!(
                            w0 <= w && w <= w1,
                            "case {case}: w({x}) = {w} outside [{w0}, {w1}]"
                        );
                    }
                    let mut out = SideRoots::new();
                    let halves = cells.isolate(i, &cyl, (o, d), &mut out);
                    assert!(halves.is_empty(), "case {case}: no cell overflows here");
                    for root in &out {
                        assert!(
                            w0 <= root.w && root.w <= w1,
                            "case {case}: root at w = {} outside [{w0}, {w1}]",
                            root.w
                        );
                    }
                    if holds == CellCrossing::Either {
                        assert!(out.len() % 2 == 1, "case {case}: {} roots", out.len());
                        crossings += 1;
                    }
                    roots_checked += out.len();
                    lazy.extend(out.iter().map(|r| r.u));
                    cells_checked += 1;
                }
                let mut want = SideRoots::new();
                for u in cyl.radial_roots_between(o, d, 1.0, a, b) {
                    cyl.push_circle_root(o, d, u, &mut want);
                }
                let want: Vec<f64> = want.iter().map(|r| r.u).collect();
                assert_eq!(lazy, want, "case {case}: cell by cell against at once");
            }
        }
        assert!(
            cells_checked > 2500 && roots_checked > 3500 && crossings > 600,
            "{cells_checked} cells, {roots_checked} roots, {crossings} certain crossings"
        );
        assert!(
            cuts_waiting.iter().all(|&n| n > 300),
            "cuts waiting below and above: {cuts_waiting:?}"
        );
    }
}
