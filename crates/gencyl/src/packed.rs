//! Many cylinders stored compactly: a strand's segments share their control points.
//!
//! A [`GeneralizedCylinder`] is 224 bytes. Of a hair segment's, 96 are its axis (relative to its
//! first control point, which is stored again as the origin), 48 its sweep (radii and rotation
//! at both ends) and 32 its framing. [`PackedCylinders`] keeps, for every cylinder, a 56-byte
//! record (its framing's reference, its rotation, where its radii and points are) and one
//! world point, and the rest of its axis in one of two ways:
//!
//! - **A strand's segment** (named in [`StrandControls`]): its axis is the uniform B-spline
//!   segment ([`spline_segment`]) over four consecutive control points `E_j .. E_{j+3}` of its
//!   strand, and the point kept is `E_j`; so the next three cylinders' points are the rest
//!   (the last three segments of a strand take the points beyond its last from a short tail,
//!   three points a strand). 80 bytes a segment.
//! - **Any other cylinder that packs**: the point kept is its first control point `p0`, and
//!   `p1, p2` are kept by cylinder in an array over the range of such cylinders, with `p3`
//!   aside unless it is the next cylinder's `p0` (a chain of segments sharing joints). 128
//!   bytes (152 at a chain's end).
//!
//! Radii are stored at the ends of the segments, once where consecutive segments share them
//! (a strand's joint, or every segment of a strand of one radius); a tapered strand's segments
//! named with their strand's [`Taper`] take theirs from it (32 bytes a strand) where it gives
//! them back to the bit. A cylinder's record and its
//! points (but a strand's tail and an unjoined `p3`) lie at addresses known without reading
//! anything, so a BVH walk can ask for them early.
//!
//! Nothing is approximated: [`PackedCylinders::get`] rebuilds the very cylinder that was packed
//! (equal in every bit; the local axis is recomputed as `p_i - p_0` from the world points, the
//! same subtraction that built it, and a strand's segment is taken as one only where its
//! spline segment gives back exactly its origin and local points). A cylinder packs when its
//! section is the unit circle or a Bezier loop (each loop kept once, its index in the record),
//! its frame is Frenet's or a projection frame, it has no frame switches, and its world points
//! come back exactly (`(o + l_i) - o == l_i` for its local
//! points `l_i` and origin `o`, which holds for nearly every axis); any other cylinder is kept
//! whole.

use std::borrow::Cow;
use std::ops::{Add, Mul};
use std::sync::atomic::{AtomicBool, Ordering};

#[cfg(test)]
use glam::DVec2;
use glam::DVec3;

use crate::curve::CubicBezier;
use crate::cylinder::GeneralizedCylinder;
use crate::frame::Framing;
use crate::section::{BezierLoop, CrossSection, Section, UnitCircle};
use crate::strand::{Taper, spline_segment};
use crate::sweep::{HairSweep, SweepRule};

/// A packed cylinder's record (module docs), or a whole one's place in `whole`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
struct Packed {
    /// The projection frame's reference ([`Framing::Projected`]); zero for Frenet's frame.
    reference: DVec3,
    /// The sweep's rotation at `u = 0` and `u = 1`.
    rotation: [f64; 2],
    /// Index of its radii at `u = 0` in `radii`, with [`Packed::TAPERED`] set when those at
    /// `u = 1` are the next entry (else they are the same); with [`Packed::STRAND_TAPER`], its
    /// strand's index in `tapers`; for a whole cylinder, its index in `whole`.
    radii: u32,
    /// The low bits: [`Packed::CAP_START`], [`Packed::CAP_END`], [`Packed::MAY_FOLD`],
    /// [`Packed::PROJECTED`], [`Packed::WHOLE`], [`Packed::JOINED`], [`Packed::SPLINE`],
    /// [`Packed::STRAND_TAPER`]; the three from [`Packed::AVAIL_SHIFT`], for a strand's
    /// segment, how many of its four control points are in `points` (1 to 4).
    flags: u32,
    /// Where the rest of the axis is in `extra`: `p3` unless joined, or a strand's segment's
    /// tail (the control points past its strand's last in `points`).
    extra: u32,
    /// The cylinder's `speed_exponent` ([`GeneralizedCylinder::speed_scale`]'s biased
    /// exponent): in what was the record's padding.
    speed_exponent: u16,
}

impl Packed {
    const CAP_START: u32 = 1;
    const CAP_END: u32 = 2;
    const MAY_FOLD: u32 = 4;
    const PROJECTED: u32 = 8;
    /// Kept whole in `whole` (did not pack).
    const WHOLE: u32 = 16;
    /// `p3` is the next cylinder's point (its `p0`).
    const JOINED: u32 = 32;
    /// A strand's segment: its axis is the spline segment of its four control points.
    const SPLINE: u32 = 64;
    const AVAIL_SHIFT: u32 = 7;
    /// Their mask, shifted down.
    const AVAIL_MASK: u32 = 7;
    /// Its radii are its strand's [`Taper`]'s, at its place in the strand (`radii` names the
    /// strand in `tapers`).
    const STRAND_TAPER: u32 = 1 << 10;
    /// Its section is a Bezier loop, the one at the index in the high bits
    /// ([`Packed::LOOP_SHIFT`]) of `loops`.
    const LOOP: u32 = 1 << 11;
    /// While the store is made: a strand's segment whose axis is the spline segment of its
    /// control points ([`gives_back`]).
    const GIVES_BACK: u32 = 1 << 12;
    /// While the store is made: a strand's segment whose radii are its strand's taper's.
    const TAKES_TAPER: u32 = 1 << 13;
    const LOOP_SHIFT: u32 = 16;
    /// In `radii`: the radii at `u = 1` are the entry after those at `u = 0`.
    const TAPERED: u32 = 1 << 31;
}

/// A cylinder's own record in a [`PackedCylinders`], as [`PackedCylinders::new_mapped`] makes
/// it (opaque).
#[derive(Clone, Copy, Debug)]
pub struct Record(Packed);

/// Strands among a list of cylinders, named by their B-spline control points with the
/// reflected ends (as [`crate::Strand::spline_controls`] makes them): a strand whose first
/// segment is cylinder `first` has its segment `j` at cylinder `first + j`, the spline segment
/// ([`spline_segment`]) of its control points `j .. j + 4`, with the radii its [`Taper`] (as
/// [`crate::Strand::taper`] gives it) has there. All the strands' points are kept in one array
/// (a list of many small ones would pin the memory freed around them).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StrandControls {
    points: Vec<DVec3>,
    /// Each strand's first cylinder and its first point in `points` (it ends where the next
    /// strand's begin).
    starts: Vec<(usize, usize)>,
    /// Each strand's radii.
    tapers: Vec<Taper>,
}

impl StrandControls {
    /// Room for `strands` strands of `points` control points in all.
    pub fn with_capacity(strands: usize, points: usize) -> Self {
        StrandControls {
            points: Vec::with_capacity(points),
            starts: Vec::with_capacity(strands),
            tapers: Vec::with_capacity(strands),
        }
    }

    /// Strands whose control points were written in place: each strand's first cylinder and
    /// its first point in `points`, in order (a strand's points end where the next one's
    /// begin), and each one's radii.
    ///
    /// # Panics
    ///
    /// If a strand's first point is before the one before it or past `points`, or `tapers`
    /// and `starts` differ in length.
    pub fn from_parts(points: Vec<DVec3>, starts: Vec<(usize, usize)>, tapers: Vec<Taper>) -> Self {
        assert_eq!(starts.len(), tapers.len(), "one taper a strand");
        let mut last = 0;
        for &(_, start) in &starts {
            assert!(
                start >= last && start <= points.len(),
                "strands' points in order"
            );
            last = start;
        }
        StrandControls {
            points,
            starts,
            tapers,
        }
    }

    /// Adds a strand whose first segment is cylinder `first`, with its control points and
    /// radii.
    pub fn push(&mut self, first: usize, controls: &[DVec3], taper: Taper) {
        self.starts.push((first, self.points.len()));
        self.points.extend_from_slice(controls);
        self.tapers.push(taper);
    }

    /// Adds `other`'s strands, their cylinders numbered from `offset`.
    pub fn append(&mut self, other: &StrandControls, offset: usize) {
        for (first, controls, taper) in other.iter() {
            self.push(first + offset, controls, taper);
        }
    }

    /// How many strands.
    pub fn len(&self) -> usize {
        self.starts.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.starts.is_empty()
    }

    /// Each strand's first cylinder, control points and radii, in the order added.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = (usize, &[DVec3], Taper)> + '_ {
        (0..self.starts.len()).map(|s| {
            let (first, start) = self.starts[s];
            let end = self.starts.get(s + 1).map_or(self.points.len(), |n| n.1);
            (first, &self.points[start..end], self.tapers[s])
        })
    }
}

/// A tapered strand's radii ([`Taper`]) and where its segments are: `segments` records from
/// `first`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct StrandTaper {
    taper: Taper,
    first: u32,
    segments: u32,
}

/// The sweep's radii at one end of a segment, `A` and `B` (see [`HairSweep`]).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Radii {
    major: f64,
    minor: f64,
}

/// Cylinders, numbered in the order given, stored compactly (module docs).
#[derive(Clone, Debug, Default)]
pub struct PackedCylinders {
    /// One a cylinder, in order.
    records: Vec<Packed>,
    /// One a cylinder: a strand's segment's first control point, another packed cylinder's
    /// `p0` (zero for a whole one), and one past the end (so that a record's run of four is
    /// always in bounds to ask for).
    points: Vec<DVec3>,
    /// The other packed cylinders' `p1, p2`, by cylinder from `inner_start` (over the range
    /// that holds them all; empty when there are none).
    inner: Vec<[DVec3; 2]>,
    inner_start: usize,
    /// The other packed cylinders' `p3` where not joined, and the strands' tails.
    extra: Vec<DVec3>,
    /// Radii at the segments' ends; a segment's end and the next one's start share an entry
    /// when they are equal, and so do the ends of a segment of constant radii.
    radii: Vec<Radii>,
    /// The radii of tapered strands whose segments take theirs from them.
    tapers: Vec<StrandTaper>,
    /// The cylinders that did not pack.
    whole: Vec<GeneralizedCylinder>,
    /// The Bezier loops of the packed cylinders' sections, each once (shared, not copied).
    loops: Vec<BezierLoop>,
}

impl PackedCylinders {
    /// The most cylinders a store holds, 2^26 (its indices into `extra`, three points a
    /// cylinder at most, fit 32 bits).
    pub const MAX: usize = 1 << 26;

    /// Packs `cylinders` (module docs), keeping their order.
    ///
    /// # Panics
    ///
    /// With more than [`Self::MAX`] cylinders.
    pub fn new(cylinders: impl IntoIterator<Item = GeneralizedCylinder>) -> Self {
        let cylinders: Vec<GeneralizedCylinder> = cylinders.into_iter().collect();
        Self::new_mapped(cylinders, &StrandControls::default(), in_order)
    }

    /// [`Self::new`], with the strands among the cylinders named (their segments are stored
    /// by their control points where these give them back exactly; `strands` in order of
    /// `first`, not overlapping: a span out of order, or reaching past the cylinders, is not
    /// taken), and each cylinder's own record made by `map(cylinders, record)`, which must
    /// return `cylinders.iter().enumerate().map(|(i, c)| record(i, c))` collected, in order
    /// (a caller can map in parallel: the records, and the checks of the strands' segments
    /// against their control points, then run in parallel, and the records take their first
    /// touch of fresh memory in parallel too). The rest runs in order.
    ///
    /// # Panics
    ///
    /// With more than [`Self::MAX`] cylinders, if `map` returns other than one record a
    /// cylinder, or if it asks for `record(i, c)` with `c` other than `&cylinders[i]` (a
    /// segment would be checked against another's control points).
    pub fn new_mapped(
        cylinders: Vec<GeneralizedCylinder>,
        strands: &StrandControls,
        map: impl FnOnce(
            &[GeneralizedCylinder],
            &(dyn Fn(usize, &GeneralizedCylinder) -> Record + Sync),
        ) -> Vec<Record>,
    ) -> Self {
        assert!(cylinders.len() <= Self::MAX, "too many cylinders");
        // The strands that may be taken: in order and within the cylinders.
        let mut last_end = 0;
        let spans: Vec<(usize, &[DVec3], Taper)> = strands
            .iter()
            .filter(|&(first, controls, _)| {
                let k = controls.len().saturating_sub(3);
                let fits = k > 0 && first >= last_end && first + k <= cylinders.len();
                if fits {
                    last_end = first + k;
                }
                fits
            })
            .collect();
        // Each cylinder's strand in `spans` (`u32::MAX` for none).
        let mut strand_of = vec![u32::MAX; if spans.is_empty() { 0 } else { cylinders.len() }];
        for (s, &(first, controls, _)) in spans.iter().enumerate() {
            strand_of[first..first + controls.len() - 3].fill(s as u32);
        }
        // Whether any cylinder has a Bezier loop for a section (most scenes have none, and
        // then need no pass to index them).
        let any_loop = AtomicBool::new(false);
        // Each record, with a strand's packed segment checked against its control points (it
        // must give back its axis exactly as its spline segment) and, on a tapered strand,
        // its radii against its taper's (to the bit).
        let records = map(&cylinders, &|i, c| {
            assert!(
                std::ptr::eq(c, &cylinders[i]),
                "record({i}, c) with c = &cylinders[{i}]"
            );
            // Read first: only the first loop writes (no line shared between threads' writes).
            if matches!(c.section, Section::Loop(_)) && !any_loop.load(Ordering::Relaxed) {
                any_loop.store(true, Ordering::Relaxed);
            }
            let mut r = Self::pack(c);
            if let Some(&(first, controls, taper)) =
                strand_of.get(i).and_then(|&s| spans.get(s as usize))
                && r.flags & Packed::WHOLE == 0
            {
                let (j, k) = (i - first, controls.len() - 3);
                let w = &controls[j..j + 4];
                if gives_back(c, [w[0], w[1], w[2], w[3]]) {
                    r.flags |= Packed::GIVES_BACK;
                }
                let (major, minor) = taper.radii(j, k);
                if bits_of(&major) == bits_of(&c.sweep.major)
                    && bits_of(&minor) == bits_of(&c.sweep.minor)
                {
                    r.flags |= Packed::TAKES_TAPER;
                }
            }
            Record(r)
        });
        drop(strand_of);
        assert_eq!(records.len(), cylinders.len(), "one record a cylinder");
        let mut out = PackedCylinders {
            // The records' own memory, written in place below.
            records: records.into_iter().map(|r| r.0).collect(),
            points: Vec::with_capacity(cylinders.len() + 1),
            ..Default::default()
        };
        if any_loop.into_inner() {
            out.index_loops(&cylinders);
        }
        // A strand's segments go by their control points where every one of them that packs
        // gives back its axis exactly as its spline segment (a segment's points are the next
        // ones' too, so all or none; one kept whole keeps its point in `points` all the same).
        // A tapered one's take their radii from its taper where every packed one's are the
        // taper's to the bit. The checks' flags are cleared as they are read.
        let mut taken = Vec::new();
        for (first, controls, taper) in spans {
            let k = controls.len() - 3;
            let records = &mut out.records[first..first + k];
            let packed = |r: &Packed| r.flags & Packed::WHOLE == 0;
            let splines = records
                .iter()
                .all(|r| !packed(r) || r.flags & Packed::GIVES_BACK != 0);
            let tapered = taper.radius[0].to_bits() != taper.radius[1].to_bits()
                && records.iter().any(packed)
                && records
                    .iter()
                    .all(|r| !packed(r) || r.flags & Packed::TAKES_TAPER != 0);
            for r in records.iter_mut() {
                r.flags &= !(Packed::GIVES_BACK | Packed::TAKES_TAPER);
            }
            if splines {
                taken.push((first, controls, tapered.then_some(taper)));
            }
        }
        for &(first, controls, taper) in &taken {
            let k = controls.len() - 3;
            let index = taper.map(|taper| {
                out.tapers.push(StrandTaper {
                    taper,
                    first: first as u32,
                    segments: k as u32,
                });
                (out.tapers.len() - 1) as u32
            });
            for r in &mut out.records[first..first + k] {
                if r.flags & Packed::WHOLE == 0 {
                    r.flags |= Packed::SPLINE;
                    if let Some(index) = index {
                        r.flags |= Packed::STRAND_TAPER;
                        r.radii = index;
                    }
                }
            }
        }
        // The range of the other packed cylinders, for their `p1, p2`.
        let other = |r: &Packed| r.flags & (Packed::WHOLE | Packed::SPLINE) == 0;
        if let (Some(lo), Some(hi)) = (
            out.records.iter().position(other),
            out.records.iter().rposition(other),
        ) {
            out.inner_start = lo;
            out.inner = vec![[DVec3::ZERO; 2]; hi + 1 - lo];
        }
        let mut spans = taken.into_iter();
        let mut span = spans.next();
        // The current strand's tail in `extra`, once a segment needs it.
        let mut tail = None;
        // By reference: a strand's segment reads little of its cylinder, and only those kept
        // whole are copied.
        for (i, c) in cylinders.iter().enumerate() {
            while span.is_some_and(|(first, controls, _)| i >= first + controls.len() - 3) {
                (span, tail) = (spans.next(), None);
            }
            match span {
                Some((first, controls, _)) if i >= first => {
                    out.settle_spline(i, c, first, controls, &mut tail)
                }
                _ => out.settle(i, c),
            }
        }
        drop(cylinders);
        // One past the end: a record's run of four points is always an address in bounds.
        out.points.push(DVec3::ZERO);
        out.extra.shrink_to_fit();
        out.radii.shrink_to_fit();
        out.tapers.shrink_to_fit();
        out.whole.shrink_to_fit();
        out
    }

    /// Gives each packed record with a Bezier loop its loop's index (the loops kept once each, by
    /// identity); past `2^16` loops the rest are kept whole.
    fn index_loops(&mut self, cylinders: &[GeneralizedCylinder]) {
        let mut index: std::collections::HashMap<usize, u32> = std::collections::HashMap::new();
        for (r, c) in self.records.iter_mut().zip(cylinders) {
            let Section::Loop(l) = &c.section else {
                continue;
            };
            if r.flags & Packed::WHOLE != 0 {
                continue;
            }
            let next = self.loops.len() as u32;
            let k = *index.entry(l.storage_id()).or_insert(next);
            if k == next {
                if next >= 1 << 16 {
                    *r = Self::pack_whole();
                    continue;
                }
                self.loops.push(l.clone());
            }
            r.flags |= k << Packed::LOOP_SHIFT;
        }
    }

    /// Completes record `i`, segment `j = i - first` of the strand `controls` whose segments go by
    /// their control points: its own is kept in `points` (also if it is kept whole), and the
    /// strand's tail (its points past the last segment's first) in `extra` once a packed
    /// segment reaches it.
    fn settle_spline(
        &mut self,
        i: usize,
        c: &GeneralizedCylinder,
        first: usize,
        controls: &[DVec3],
        tail: &mut Option<u32>,
    ) {
        let (j, k) = (i - first, controls.len() - 3);
        self.points.push(controls[j]);
        if self.records[i].flags & Packed::WHOLE != 0 {
            self.records[i].radii = self.whole.len() as u32;
            self.whole.push(c.clone());
            return;
        }
        let avail = (k - j).min(4);
        let extra = &mut self.extra;
        let record = &mut self.records[i];
        record.flags |= (avail as u32) << Packed::AVAIL_SHIFT;
        if avail < 4 {
            record.extra = *tail.get_or_insert_with(|| {
                extra.extend_from_slice(&controls[k..]);
                (extra.len() - 3) as u32
            });
        }
        // Its axis was checked against its control points before (`gives_back`); the rest of
        // its points are the next records' and not yet kept; so were its radii against its
        // strand's taper where it takes them from there.
        if record.flags & Packed::STRAND_TAPER == 0 {
            self.share_radii(i, c);
        }
    }

    /// Completes record `i` (made by [`Self::pack`], all before it settled), not a strand's
    /// segment: a cylinder that did not pack is kept whole; a packed one keeps `p0` in
    /// `points` and the rest in `extra`, and is joined to the record before where that one ends
    /// at its start (the end it kept aside is dropped).
    fn settle(&mut self, i: usize, c: &GeneralizedCylinder) {
        if self.records[i].flags & Packed::WHOLE != 0 {
            self.records[i].radii = self.whole.len() as u32;
            self.whole.push(c.clone());
            self.points.push(DVec3::ZERO);
            return;
        }
        // Joined to the record before when that is a packed one of this kind with its end
        // kept aside last, and `c`'s origin serves as its `p3` (rebuilds its local point: the
        // end kept is `o + l`, which may differ from the strand's joint in the last bit).
        if let Some(last) = i.checked_sub(1).map(|j| &mut self.records[j])
            && last.flags & (Packed::WHOLE | Packed::JOINED | Packed::SPLINE) == 0
            && last.extra as usize + 1 == self.extra.len()
            && self.extra.last().is_some_and(|&end| {
                let o = self.points[i - 1];
                bits(c.origin - o) == bits(end - o)
            })
        {
            last.flags |= Packed::JOINED;
            self.extra.pop();
        }
        let (o, l) = (c.origin, &c.axis.points);
        self.inner[i - self.inner_start] = [o + l[1], o + l[2]];
        self.records[i].extra = self.extra.len() as u32;
        self.extra.push(o + l[3]);
        self.points.push(o);
        self.share_radii(i, c);
        debug_assert!(self.unpack(i) == *c, "a packed cylinder rebuilds as itself");
    }

    /// Gives record `i` its radii: those at its start shared with the entry before where they
    /// are equal, those at its end with its start.
    fn share_radii(&mut self, i: usize, c: &GeneralizedCylinder) {
        let [start, end] = [0, 1].map(|k| Radii {
            major: c.sweep.major[k],
            minor: c.sweep.minor[k],
        });
        if self.radii.last().map(|r| r.bits()) != Some(start.bits()) {
            self.radii.push(start);
        }
        let record = &mut self.records[i];
        record.radii = self.radii.len() as u32 - 1;
        if end.bits() != start.bits() {
            self.radii.push(end);
            record.radii |= Packed::TAPERED;
        }
    }

    /// The record of `c` (without its radii and points) if it packs (module docs), else a
    /// placeholder marked [`Packed::WHOLE`].
    fn pack(c: &GeneralizedCylinder) -> Packed {
        Self::packed(c).unwrap_or_else(Self::pack_whole)
    }

    /// The placeholder record of a cylinder kept whole.
    fn pack_whole() -> Packed {
        Packed {
            reference: DVec3::ZERO,
            rotation: [0.0; 2],
            radii: 0,
            flags: Packed::WHOLE,
            extra: 0,
            speed_exponent: 0,
        }
    }

    /// The record of `c` (without its radii and points), if it packs.
    fn packed(c: &GeneralizedCylinder) -> Option<Packed> {
        if c.has_switches() {
            return None;
        }
        let section = match c.section {
            Section::Circle(_) => 0,
            Section::Loop(_) => Packed::LOOP,
        };
        let (flag, reference) = match c.framing {
            Framing::Frenet => (0, DVec3::ZERO),
            Framing::Projected(r) => (Packed::PROJECTED, r),
            Framing::Fixed(_) => return None,
        };
        let o = c.origin;
        let comes_back = bits(c.axis.points[0]) == bits(DVec3::ZERO)
            && c.axis.points[1..]
                .iter()
                .all(|&l| bits((o + l) - o) == bits(l));
        if !comes_back {
            return None;
        }
        let caps =
            u32::from(c.caps[0]) * Packed::CAP_START + u32::from(c.caps[1]) * Packed::CAP_END;
        Some(Packed {
            reference,
            rotation: c.sweep.rotation,
            radii: 0,
            flags: flag | section | caps | (u32::from(c.may_fold()) * Packed::MAY_FOLD),
            extra: 0,
            speed_exponent: c.speed_exponent,
        })
    }

    /// The world control points of packed record `i`.
    #[inline]
    fn world_points(&self, i: usize) -> [DVec3; 4] {
        self.points_of(i, |w| spline_segment(w).points)
    }

    /// The world control points of packed record `i`, a strand's segment's made from its
    /// control points by `spline`.
    #[inline]
    fn points_of(&self, i: usize, spline: impl Fn([DVec3; 4]) -> [DVec3; 4]) -> [DVec3; 4] {
        let r = &self.records[i];
        let e = r.extra as usize;
        if r.flags & Packed::SPLINE != 0 {
            // E_{j+m}: in `points` while the strand lasts (nearly always all four), then in its
            // tail.
            let avail = (r.flags >> Packed::AVAIL_SHIFT & Packed::AVAIL_MASK) as usize;
            let w = if avail == 4 {
                let w = &self.points[i..i + 4];
                [w[0], w[1], w[2], w[3]]
            } else {
                std::array::from_fn(|m| {
                    if m < avail {
                        self.points[i + m]
                    } else {
                        self.extra[e + m - avail]
                    }
                })
            };
            return spline(w);
        }
        let p3 = if r.flags & Packed::JOINED != 0 {
            self.points[i + 1]
        } else {
            self.extra[e]
        };
        let [p1, p2] = self.inner[i - self.inner_start];
        [self.points[i], p1, p2, p3]
    }

    /// The sweep of packed record `i`, `r`: its radii and rotation.
    #[inline]
    fn sweep(&self, i: usize, r: &Packed) -> HairSweep {
        let (major, minor) = if r.flags & Packed::STRAND_TAPER != 0 {
            let t = &self.tapers[r.radii as usize];
            t.taper.radii(i - t.first as usize, t.segments as usize)
        } else {
            let start = (r.radii & !Packed::TAPERED) as usize;
            let [a, b] = [
                self.radii[start],
                self.radii[start + usize::from(r.radii & Packed::TAPERED != 0)],
            ];
            ([a.major, b.major], [a.minor, b.minor])
        };
        HairSweep {
            major,
            minor,
            rotation: r.rotation,
        }
    }

    /// The packed cylinder `i` rebuilt.
    #[inline]
    fn unpack(&self, i: usize) -> GeneralizedCylinder {
        let r = &self.records[i];
        let p = self.world_points(i);
        let origin = p[0];
        GeneralizedCylinder::from_packed(
            CubicBezier::new(p.map(|x| x - origin)),
            origin,
            if r.flags & Packed::PROJECTED != 0 {
                Framing::Projected(r.reference)
            } else {
                Framing::Frenet
            },
            self.section(r),
            self.sweep(i, r),
            [
                r.flags & Packed::CAP_START != 0,
                r.flags & Packed::CAP_END != 0,
            ],
            r.flags & Packed::MAY_FOLD != 0,
            r.speed_exponent,
        )
    }

    /// A packed record's section: its Bezier loop (shared) or the unit circle.
    #[inline]
    fn section(&self, r: &Packed) -> Section {
        if r.flags & Packed::LOOP != 0 {
            Section::Loop(self.loops[(r.flags >> Packed::LOOP_SHIFT) as usize].clone())
        } else {
            Section::Circle(UnitCircle)
        }
    }

    /// Cylinder `i`'s axis control points in world coordinates and
    /// [`GeneralizedCylinder::reach_ends`], without rebuilding the cylinder: what a cheap cull
    /// needs. The points are those stored (a whole cylinder's [`GeneralizedCylinder::axis`],
    /// origin plus local points) or a strand's segment's from [`spline_points_near`]; they may
    /// differ from the rebuilt cylinder's `axis()` by a few units in the last place (at most
    /// `2 eps` of the coordinate).
    ///
    /// # Panics
    ///
    /// If `i >= self.len()`.
    #[inline]
    pub fn axis_and_reach(&self, i: usize) -> ([DVec3; 4], [f64; 2]) {
        self.with_axis_controls(i, |&points, spline, reach| {
            let points = if spline {
                spline_points_near(points)
            } else {
                points
            };
            (points, reach)
        })
    }

    /// `f` of [`Self::axis_and_reach`] before a strand's segment's points are made: the four
    /// stored points in world coordinates, lent where they lie in the store (nearly always: a
    /// strand's segment's four controls while the strand lasts), not copied; whether they are
    /// a strand's B-spline control points (then the axis's Bezier points are
    /// [`spline_points_near`] of them, which [`spline_bezier_near`] makes of any linear image of
    /// them); and [`GeneralizedCylinder::reach_ends`]. For a cull that maps the points linearly
    /// first (a projection) and converts fewer coordinates.
    ///
    /// # Panics
    ///
    /// If `i >= self.len()`.
    #[inline]
    pub fn with_axis_controls<R>(
        &self,
        i: usize,
        f: impl FnOnce(&[DVec3; 4], bool, [f64; 2]) -> R,
    ) -> R {
        let r = &self.records[i];
        if r.flags & Packed::WHOLE != 0 {
            let c = &self.whole[r.radii as usize];
            return f(&c.axis().points, false, c.reach_ends());
        }
        // `reach_ends` of the rebuilt cylinder.
        let bound = if r.flags & Packed::LOOP != 0 {
            self.loops[(r.flags >> Packed::LOOP_SHIFT) as usize].bounding_radius()
        } else {
            UnitCircle.bounding_radius()
        };
        let reach = self.sweep(i, r).scale_bound().map(|l| l * bound);
        let spline = r.flags & Packed::SPLINE != 0;
        if spline && (r.flags >> Packed::AVAIL_SHIFT & Packed::AVAIL_MASK) == 4 {
            // As `points_of` reads them.
            let w: &[DVec3; 4] = self.points[i..i + 4].try_into().expect("four points");
            return f(w, true, reach);
        }
        f(&self.points_of(i, |w| w), spline, reach)
    }

    /// How many cylinders.
    pub fn len(&self) -> usize {
        self.records.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.records.is_empty()
    }

    /// Cylinder `i`, as it was given to [`Self::new`]: rebuilt (a few dozen instructions) if
    /// it was packed, borrowed if it was kept whole.
    ///
    /// # Panics
    ///
    /// If `i >= self.len()`.
    #[inline]
    pub fn get(&self, i: usize) -> Cow<'_, GeneralizedCylinder> {
        let r = &self.records[i];
        if r.flags & Packed::WHOLE != 0 {
            Cow::Borrowed(&self.whole[r.radii as usize])
        } else {
            Cow::Owned(self.unpack(i))
        }
    }

    /// The cylinders in order ([`Self::get`] of each).
    pub fn iter(&self) -> impl ExactSizeIterator<Item = Cow<'_, GeneralizedCylinder>> + '_ {
        (0..self.len()).map(|i| self.get(i))
    }

    /// Where cylinder `i`'s packed data lies, as (address, bytes), found without reading the
    /// store: its record, its run of four points (a strand's segment's control points;
    /// another's `p0` and the next one's, its `p3` when joined), and another's `p1, p2` (no
    /// bytes where the store has no such cylinders), for a caller that wants to start loading
    /// them early (a cache hint; past the end, the addresses lie outside the store and must
    /// not be read). A strand's tail and an unjoined `p3` are not included.
    #[inline]
    pub fn storage(&self, i: usize) -> [(*const u8, usize); 3] {
        let r = self.records.as_ptr().wrapping_add(i);
        let p = self.points.as_ptr().wrapping_add(i);
        let q = self
            .inner
            .as_ptr()
            .wrapping_add(i.wrapping_sub(self.inner_start));
        let inner = if self.inner.is_empty() {
            0
        } else {
            size_of::<[DVec3; 2]>()
        };
        [
            (r.cast::<u8>(), size_of::<Packed>()),
            (p.cast::<u8>(), 4 * size_of::<DVec3>()),
            (q.cast::<u8>(), inner),
        ]
    }

    /// Bytes held: the records, points and radii, the loops' handles, and the whole cylinders
    /// with their own heap data (a section's profile not included: profiles are shared).
    pub fn memory_bytes(&self) -> usize {
        self.records.capacity() * size_of::<Packed>()
            + (self.points.capacity() + self.extra.capacity()) * size_of::<DVec3>()
            + self.inner.capacity() * size_of::<[DVec3; 2]>()
            + self.radii.capacity() * size_of::<Radii>()
            + self.tapers.capacity() * size_of::<StrandTaper>()
            + self.whole.capacity() * size_of::<GeneralizedCylinder>()
            + self.whole.iter().map(|c| c.heap_bytes()).sum::<usize>()
            + self.loops.capacity() * size_of::<BezierLoop>()
    }

    /// The cylinders kept whole (did not pack), in order.
    pub fn whole(&self) -> &[GeneralizedCylinder] {
        &self.whole
    }
}

impl Radii {
    /// The radii's bits.
    fn bits(&self) -> [u64; 2] {
        bits_of(&[self.major, self.minor])
    }
}

/// [`spline_segment`]'s points with its divisions by 6 and 3 taken as products with the
/// rounded reciprocals, for a cull that widens its reach by far more than the difference, at
/// a fraction of the divisions' cost: the numerators are the same, `fl(N fl(1/k))` is within
/// `eps` of `N / k` (relative) and `fl(N / k)` within `eps / 2`, so each coordinate is within
/// `1.5 eps` of [`spline_segment`]'s.
#[inline]
fn spline_points_near(w: [DVec3; 4]) -> [DVec3; 4] {
    spline_bezier_near(w)
}

/// [`spline_points_near`] of any linear image of the control points (`T`: points in the
/// plane, numbers, ...): the Bezier points of the B-spline segment of controls `[a, b, c, d]`,
/// `(a + 4 b + c) / 6`, `(2 b + c) / 3`, `(b + 2 c) / 3`, `(b + 4 c + d) / 6`, with the
/// divisions taken as products with the rounded reciprocals. Each is a convex combination
/// of the controls (non-negative weights of sum `1`), so it commutes with any affine map (a
/// projection, a shift) in exact arithmetic, and in floating point lies within a few `eps`
/// of the largest control's magnitude of the exact value.
#[inline]
pub fn spline_bezier_near<T: Copy + Add<Output = T> + Mul<f64, Output = T>>(
    [a, b, c, d]: [T; 4],
) -> [T; 4] {
    const SIXTH: f64 = 1.0 / 6.0;
    const THIRD: f64 = 1.0 / 3.0;
    [
        (a + b * 4.0 + c) * SIXTH,
        (b * 2.0 + c) * THIRD,
        (b + c * 2.0) * THIRD,
        (b + c * 4.0 + d) * SIXTH,
    ]
}

/// [`PackedCylinders::new_mapped`]'s map in order on one thread ([`PackedCylinders::new`]'s).
fn in_order(
    cylinders: &[GeneralizedCylinder],
    record: &(dyn Fn(usize, &GeneralizedCylinder) -> Record + Sync),
) -> Vec<Record> {
    (0..cylinders.len())
        .map(|i| record(i, &cylinders[i]))
        .collect()
}

/// Whether the spline segment of the control points `w` is `c`'s axis to the bit: its first
/// point `c`'s origin, and the others less it `c`'s local points.
fn gives_back(c: &GeneralizedCylinder, w: [DVec3; 4]) -> bool {
    let p = spline_segment(w).points;
    bits(p[0]) == bits(c.origin) && (0..4).all(|m| bits(p[m] - p[0]) == bits(c.axis.points[m]))
}

/// The bits of a point's coordinates (equal bits: the same point, `-0` and `0` told apart).
fn bits(p: DVec3) -> [u64; 3] {
    p.to_array().map(f64::to_bits)
}

/// The bits of two numbers (`-0.0` and `0.0` differ, as do NaNs).
fn bits_of(x: &[f64; 2]) -> [u64; 2] {
    x.map(f64::to_bits)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::section::BezierLoop;
    use crate::strand::{Strand, StrandFraming};
    use crate::test_rng::Lcg;

    /// A wavy strand of `n` points from `start`, radius `radius`.
    fn strand(rng: &mut Lcg, start: DVec3, n: usize, radius: [f64; 2], ellipticity: f64) -> Strand {
        let mut p = start;
        let mut points = vec![p];
        for _ in 1..n {
            p += DVec3::new(rng.range(-0.3, 0.3), 1.0, rng.range(-0.3, 0.3)) * 0.5;
            points.push(p);
        }
        Strand {
            points,
            radius,
            ellipticity,
            twist: [rng.range(-1.0, 1.0), rng.range(-3.0, 3.0)],
            section: Section::default(),
        }
    }

    /// A strand's first cylinder and control points, as a test holds them.
    #[derive(Clone)]
    struct StrandSpan {
        first: usize,
        controls: Vec<DVec3>,
        taper: Taper,
    }

    impl StrandSpan {
        fn of(first: usize, s: &Strand) -> Self {
            StrandSpan {
                first,
                controls: s.spline_controls(),
                taper: s.taper(),
            }
        }
    }

    /// [`in_order`]'s records made last to first (as a parallel map may make them).
    fn reversed(
        cylinders: &[GeneralizedCylinder],
        record: &(dyn Fn(usize, &GeneralizedCylinder) -> Record + Sync),
    ) -> Vec<Record> {
        let mut records: Vec<Record> = (0..cylinders.len())
            .rev()
            .map(|i| record(i, &cylinders[i]))
            .collect();
        records.reverse();
        records
    }

    fn controls_of(spans: &[StrandSpan]) -> StrandControls {
        let mut out = StrandControls::default();
        for s in spans {
            out.push(s.first, &s.controls, s.taper);
        }
        out
    }

    fn bytes_whole(cylinders: &[GeneralizedCylinder]) -> usize {
        size_of_val(cylinders) + cylinders.iter().map(|c| c.heap_bytes()).sum::<usize>()
    }

    /// Every cylinder comes back equal in every field, in order, whatever packed: strands of
    /// both framings (round, tapered, elliptical and twisted), near the origin and at 1e4 and
    /// 1e6 (where `(o + l) - o` may round off `l`), mixed with cylinders that cannot pack (a
    /// Bezier-loop profile, a straight axis' fixed frame, Frenet switches at an inflection).
    #[test]
    fn every_cylinder_comes_back_exactly() {
        let mut rng = Lcg(17);
        let profile: Vec<DVec2> = (0..12)
            .map(|i| {
                let a = i as f64 / 12.0 * std::f64::consts::TAU;
                DVec2::new(a.cos(), 0.6 * a.sin())
            })
            .collect();
        let mut all = vec![];
        let mut strands = vec![];
        for (k, offset) in [0.0, 1e4, 1e6, -3.3e4].into_iter().enumerate() {
            for framing in [StrandFraming::RotationMinimizing, StrandFraming::Frenet] {
                for (radius, ell) in [
                    ([0.01, 0.01], 1.0),
                    ([0.02, 0.005], 1.0),
                    ([0.01, 0.01], 0.5),
                ] {
                    let start =
                        DVec3::splat(offset) + DVec3::new(rng.range(-1.0, 1.0), 0.0, k as f64);
                    let s = strand(&mut rng, start, 9, radius, ell);
                    strands.push(StrandSpan::of(all.len(), &s));
                    all.extend(s.cylinders_with(framing).unwrap());
                }
            }
            let line =
                CubicBezier::new([0.0, 1.0, 2.0, 3.0].map(|x| DVec3::new(x + offset, 0.0, 1.0)));
            let fixed = GeneralizedCylinder::new(
                line,
                Section::default(),
                HairSweep::circular(0.1),
                true,
                None,
            )
            .unwrap();
            assert!(matches!(fixed.framing(), Framing::Fixed(_)));
            all.push(fixed);
            let s_curve = CubicBezier::new(
                [[0.0, 0.0], [1.0, 1.0], [2.0, -1.0], [3.0, 0.0]]
                    .map(|[x, y]| DVec3::new(x + offset, y, 2.0)),
            );
            let switching = GeneralizedCylinder::with_framing(
                s_curve,
                Section::default(),
                HairSweep::circular(0.05),
                true,
                Framing::Frenet,
            )
            .unwrap();
            assert!(
                switching.has_switches(),
                "an inflection switches Frenet's frame"
            );
            all.push(switching);
            let mut looped = all[all.len() - 3].clone();
            looped.section = Section::Loop(BezierLoop::new(&profile).unwrap());
            all.push(looped);
        }
        // The flag the store keeps for a fiber that may fold (none of these curves does).
        let folding = all
            .iter()
            .position(|c| c.framing == Framing::Frenet)
            .unwrap();
        all[folding].may_fold = true;
        let packed = PackedCylinders::new(all.clone());
        assert_eq!(packed.len(), all.len());
        assert!(packed.records.iter().all(|r| r.flags & Packed::SPLINE == 0));
        check_every_cylinder(&packed, &all);
        // The records made in another order (as a parallel map makes them): the same store.
        let mapped = PackedCylinders::new_mapped(all.clone(), &StrandControls::default(), reversed);
        assert!(mapped.records == packed.records && mapped.points == packed.points);
        assert!(mapped.extra == packed.extra && mapped.radii == packed.radii);
        assert!(mapped.inner == packed.inner && mapped.inner_start == packed.inner_start);
        assert!(mapped.whole == packed.whole);
        // Profiled cylinders pack (those whose points come back), each block's loop kept once.
        let looped = all
            .iter()
            .filter(|c| matches!(c.section, Section::Loop(_)))
            .count();
        let packed_loops = packed
            .records
            .iter()
            .filter(|r| r.flags & Packed::LOOP != 0)
            .count();
        assert!(packed_loops > 0, "{packed_loops} of {looped} profiled pack");
        assert_eq!(packed.loops.len(), packed_loops, "one loop a block");
        // What packs: all strand segments but those whose points do not come back; two kinds
        // a block stay whole.
        let whole = packed.whole().len();
        assert!(whole >= 12, "{whole} whole");
        assert!(
            whole <= 12 + strands.len() * 8 / 4,
            "most strand segments pack: {whole} whole"
        );
        assert!(
            packed.memory_bytes() * 10 < bytes_whole(&all) * 8,
            "packed {} bytes against {}",
            packed.memory_bytes(),
            bytes_whole(&all)
        );
        // With the strands named, their packed segments go by their control points (those
        // kept whole at a Frenet switch stay whole), and every cylinder still comes back; so
        // it does where a span's control points lie (one moved by an ulp, one span naming
        // cylinders that are not its segments): those go as before.
        let mut spans = strands.clone();
        let liar = spans.len() / 2;
        spans[liar].controls[2].x = spans[liar].controls[2].x.next_up();
        spans[3].first += 1;
        spans[3].controls.pop();
        let splined = PackedCylinders::new_mapped(all.clone(), &controls_of(&spans), in_order);
        check_every_cylinder(&splined, &all);
        // The records and the segments' checks made in another order: the same store.
        let mapped = PackedCylinders::new_mapped(all.clone(), &controls_of(&spans), reversed);
        assert!(mapped.records == splined.records && mapped.points == splined.points);
        assert!(mapped.extra == splined.extra && mapped.tapers == splined.tapers);
        assert!(mapped.radii == splined.radii && mapped.whole == splined.whole);
        assert!(mapped.inner == splined.inner && mapped.inner_start == splined.inner_start);
        let is_spline = |i: usize| splined.records[i].flags & Packed::SPLINE != 0;
        let is_whole = |i: usize| splined.records[i].flags & Packed::WHOLE != 0;
        let packed_segments = |s: &StrandSpan| (0..8).filter(|j| !is_whole(s.first + j)).count();
        let segments: usize = strands.iter().map(packed_segments).sum();
        let by_controls = (0..all.len()).filter(|&i| is_spline(i)).count();
        assert!(
            !(0..8).any(|j| is_spline(spans[liar].first + j)),
            "the liar"
        );
        assert!(
            !(0..8).any(|j| is_spline(strands[3].first + j)),
            "the shifted span"
        );
        let lied = packed_segments(&strands[liar]) + packed_segments(&strands[3]);
        assert_eq!(
            by_controls,
            segments - lied,
            "all the packed segments of honest spans by their control points"
        );
        // Less memory, though not the 36 bytes a segment of a scene of strands alone: here
        // the other packed cylinders (whose `p1, p2` are kept by cylinder over their range)
        // lie between the strands.
        assert!(splined.memory_bytes() < packed.memory_bytes());
    }

    /// Each cylinder of `packed` comes back equal in every field, in order, and the cull's
    /// view of it (its reach exactly, its world points to rounding).
    fn check_every_cylinder(packed: &PackedCylinders, all: &[GeneralizedCylinder]) {
        assert_eq!(packed.len(), all.len());
        for (i, c) in all.iter().enumerate() {
            assert!(*packed.get(i) == *c, "cylinder {i} comes back as it was");
            // What the cull reads: the reach itself, the world points to rounding.
            let (points, reach) = packed.axis_and_reach(i);
            assert_eq!(reach, c.reach_ends(), "cylinder {i}: reach");
            for (p, q) in points.iter().zip(c.axis().points) {
                let tol = 4.0 * f64::EPSILON * q.abs().max_element();
                assert!(
                    (*p - q).abs().max_element() <= tol,
                    "cylinder {i}: {p} against {q}"
                );
            }
        }
        assert!(
            packed
                .iter()
                .map(|c| c.into_owned())
                .eq(all.iter().cloned())
        );
    }

    /// A map that hands `record` another cylinder than the index names is refused (its
    /// segment would be checked against another segment's control points).
    #[test]
    #[should_panic(expected = "record(0, c) with c = &cylinders[0]")]
    fn a_map_must_pair_each_index_with_its_cylinder() {
        let s = strand(&mut Lcg(5), DVec3::ZERO, 6, [0.01, 0.01], 1.0);
        let cylinders = s.cylinders().unwrap();
        let spans = [StrandSpan::of(0, &s)];
        PackedCylinders::new_mapped(cylinders, &controls_of(&spans), |cylinders, record| {
            let n = cylinders.len();
            (0..n).map(|i| record(i, &cylinders[(i + 1) % n])).collect()
        });
    }

    /// A strand named by its control points stores one point a segment and three at its tip;
    /// unnamed, its segments share their joints: three points a segment and its tip. Radii:
    /// one set for a round strand of constant radius; a tapered one's at its joints and ends,
    /// or its taper alone where it is named.
    #[test]
    fn a_strand_stores_one_point_a_segment() {
        let mut rng = Lcg(3);
        let s = strand(
            &mut rng,
            DVec3::new(0.5, 0.25, -0.75),
            17,
            [0.01, 0.01],
            1.0,
        );
        let cylinders = s.cylinders().unwrap();
        assert_eq!(size_of::<Packed>(), 56);
        let span = StrandSpan::of(0, &s);
        for spans in [vec![], vec![span.clone()]] {
            let packed =
                PackedCylinders::new_mapped(cylinders.clone(), &controls_of(&spans), in_order);
            assert!(packed.whole().is_empty(), "every segment packs");
            assert_eq!(
                packed.points.len(),
                16 + 1,
                "one point a segment, and one past"
            );
            let (aside, inner) = if spans.is_empty() { (1, 16) } else { (3, 0) };
            assert_eq!(packed.extra.len(), aside, "points kept aside");
            assert_eq!(packed.inner.len(), inner, "inner points by cylinder");
            assert_eq!(packed.radii.len(), 1, "one radius");
            for (i, c) in cylinders.iter().enumerate() {
                assert!(*packed.get(i) == *c, "segment {i}");
            }
        }
        // Two strands one after the other share nothing across their gap; the second, of 4
        // segments, takes all from its tail but its first.
        let t = strand(&mut rng, DVec3::new(5.0, 0.0, 0.0), 5, [0.02, 0.01], 1.0);
        let both: Vec<_> = cylinders
            .iter()
            .cloned()
            .chain(t.cylinders().unwrap())
            .collect();
        let spans = [span, StrandSpan::of(16, &t)];
        let unnamed = PackedCylinders::new(both.clone());
        assert_eq!(
            unnamed.radii.len(),
            1 + 5,
            "a tapered strand of 4 segments: radii at its 3 joints and 2 ends"
        );
        assert!(unnamed.tapers.is_empty());
        let packed = PackedCylinders::new_mapped(both.clone(), &controls_of(&spans), in_order);
        assert_eq!(packed.extra.len(), 6, "each strand's tail");
        assert_eq!(packed.radii.len(), 1, "the round strand's radius");
        assert_eq!(packed.tapers.len(), 1, "the tapered strand's taper");
        for (i, c) in both.iter().enumerate() {
            assert!(*packed.get(i) == *c, "segment {i}");
        }
        let avail = |i: usize| packed.records[i].flags >> Packed::AVAIL_SHIFT & Packed::AVAIL_MASK;
        assert_eq!((16..20).map(avail).collect::<Vec<_>>(), [4, 3, 2, 1]);
    }

    /// A tapered strand named with its taper takes its radii from it and comes back to the
    /// bit: radii 1e-6 to 1e-1 of a segment's length, ellipticities 0.2 to 1, 1 to 300
    /// segments, near the origin and at 1e4. A taper that lies (its root radius an ulp off, its
    /// ellipticity a thousandth), or a strand one of whose segments was given other radii,
    /// keeps its radii at its joints instead, and comes back all the same.
    #[test]
    fn tapered_strands_take_their_radii_from_their_taper() {
        let mut rng = Lcg(23);
        let (mut all, mut spans) = (vec![], vec![]);
        // Records expected to go by their taper, and such strands.
        let (mut by_taper, mut honest) = (0, 0);
        for case in 0..60 {
            let n = [2, 3, 5, 17, 301][case % 5];
            let r0 = 10f64.powf(rng.range(-6.0, -1.0));
            let r1 = r0 * rng.range(0.05, 3.0);
            let ell = if case % 2 == 0 {
                1.0
            } else {
                rng.range(0.2, 1.0)
            };
            let start = DVec3::splat([0.0, 1e4, -3e3][case % 3]);
            let s = strand(&mut rng, start, n, [r0, r1], ell);
            let framing = if case % 4 == 3 {
                StrandFraming::Frenet
            } else {
                StrandFraming::RotationMinimizing
            };
            let Ok(mut cylinders) = s.cylinders_with(framing) else {
                continue;
            };
            let mut span = StrandSpan::of(all.len(), &s);
            let lie = match case % 10 {
                7 => {
                    span.taper.radius[0] = r0.next_up();
                    true
                }
                8 => {
                    span.taper.ellipticity = ell * 0.999;
                    true
                }
                9 => {
                    let j = cylinders.len() / 2;
                    cylinders[j].sweep.major[1] *= 1.01;
                    true
                }
                _ => false,
            };
            let packed = PackedCylinders::new(cylinders.clone());
            let segments = (0..cylinders.len())
                .filter(|&i| packed.records[i].flags & Packed::WHOLE == 0)
                .count();
            if !lie && segments > 0 {
                by_taper += segments;
                honest += 1;
            }
            all.extend(cylinders);
            spans.push(span);
        }
        let packed = PackedCylinders::new_mapped(all.clone(), &controls_of(&spans), in_order);
        check_every_cylinder(&packed, &all);
        let tapered = |r: &Packed| r.flags & Packed::STRAND_TAPER != 0;
        assert_eq!(
            packed.records.iter().filter(|r| tapered(r)).count(),
            by_taper
        );
        assert_eq!(packed.tapers.len(), honest);
        assert!(honest >= 30, "{honest} strands by their taper");
        // The liars' radii are at their joints (two entries for a strand of one segment).
        assert!(
            packed.radii.len() > 2 * (spans.len() - honest),
            "{}",
            packed.radii.len()
        );
    }

    /// Axes from 1e-3 to 1e5 from the origin come back equal, packed exactly when their points
    /// come back (`(o + l) - o == l`; in random trials they always have, but nothing in IEEE
    /// arithmetic promises it, so it is checked) and they have no frame switches.
    #[test]
    fn axes_at_every_magnitude_come_back() {
        let mut rng = Lcg(99);
        let mut tried = 0;
        for _ in 0..400 {
            let o = DVec3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            ) * 10f64.powf(rng.range(-3.0, 5.0));
            let dir = rng.unit();
            let bend = rng.unit() * 0.2;
            let axis = CubicBezier::new(
                [0.0, 1.0, 2.0, 3.0].map(|k| o + dir * k + bend * (k * (3.0 - k))),
            );
            let Ok(c) = GeneralizedCylinder::new(
                axis,
                Section::default(),
                HairSweep::circular(0.01),
                true,
                None,
            ) else {
                continue;
            };
            let back = c.axis.points[1..]
                .iter()
                .all(|&l| bits((c.origin + l) - c.origin) == bits(l));
            let packed = PackedCylinders::new([c.clone()]);
            assert!(*packed.get(0) == c);
            assert_eq!(packed.whole().len() == 1, !back || c.has_switches());
            tried += 1;
        }
        assert!(tried > 300, "{tried} cylinders built");
    }
}
