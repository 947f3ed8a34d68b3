//! Many cylinders stored compactly: a strand's segments share their joints' control points.
//!
//! A [`GeneralizedCylinder`] is 224 bytes. Of a hair segment's, 96 are its axis (relative to its
//! first control point, which is stored again as the origin), 48 its sweep (radii and rotation
//! at both ends) and 32 its framing. A strand's consecutive segments share the control point
//! at their joint, and most strands keep one radius: [`PackedCylinders`] stores a segment's
//! first three world control points, its framing's reference and its rotation in a 120-byte
//! record; its fourth point is the next record's first (the joint), or, at a strand's tip, kept
//! aside; radii are stored at the ends of the segments, once where consecutive segments share
//! them (a strand's joint, or every segment of a strand of one radius). A cylinder's data is then
//! one contiguous span (its record and the next one's first point), whose address is known
//! without reading anything, so a BVH walk can ask for it early.
//!
//! Nothing is approximated: [`PackedCylinders::get`] rebuilds the very cylinder that was packed
//! (equal in every bit; the local axis is recomputed as `p_i - p_0` from the world points, the
//! same subtraction that built it). A cylinder packs when its section is the unit circle, its
//! frame is Frenet's or a projection frame, it has no frame switches, and its world points
//! come back exactly (`(o + l_i) - o == l_i` for its local points `l_i` and origin `o`, which
//! holds for nearly every axis); any other cylinder is kept whole.

use std::borrow::Cow;

#[cfg(test)]
use glam::DVec2;
use glam::DVec3;

use crate::curve::CubicBezier;
use crate::cylinder::GeneralizedCylinder;
use crate::frame::Framing;
use crate::section::{CrossSection, Section, UnitCircle};
use crate::sweep::{HairSweep, SweepRule};

/// A packed cylinder (module docs), or a whole one's place in `whole`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
struct Packed {
    /// The first three control points `p0, p1, p2`, world coordinates.
    points: [DVec3; 3],
    /// The projection frame's reference ([`Framing::Projected`]); zero for Frenet's frame.
    reference: DVec3,
    /// The sweep's rotation at `u = 0` and `u = 1`.
    rotation: [f64; 2],
    /// Index of its radii at `u = 0` in `radii`, with [`Packed::TAPERED`] set when those at
    /// `u = 1` are the next entry (else they are the same); for a whole cylinder, its index in
    /// `whole`.
    radii: u32,
    /// The low bits: [`Packed::CAP_START`], [`Packed::CAP_END`], [`Packed::MAY_FOLD`],
    /// [`Packed::PROJECTED`], [`Packed::WHOLE`], [`Packed::JOINED`]; above
    /// [`Packed::END_SHIFT`], where `p3` is in `ends` when not joined.
    flags: u32,
}

impl Packed {
    const CAP_START: u32 = 1;
    const CAP_END: u32 = 2;
    const MAY_FOLD: u32 = 4;
    const PROJECTED: u32 = 8;
    /// Kept whole in `whole` (did not pack).
    const WHOLE: u32 = 16;
    /// `p3` is the next record's `p0`.
    const JOINED: u32 = 32;
    const END_SHIFT: u32 = 6;
    /// In `radii`: the radii at `u = 1` are the entry after those at `u = 0`.
    const TAPERED: u32 = 1 << 31;
}

/// A cylinder's own record in a [`PackedCylinders`], as [`PackedCylinders::new_mapped`] makes
/// it (opaque).
#[derive(Clone, Copy, Debug)]
pub struct Record(Packed);

/// The sweep's radii at one end of a segment, `A` and `B` (see [`HairSweep`]).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Radii {
    major: f64,
    minor: f64,
}

/// Cylinders, numbered in the order given, stored compactly (module docs).
#[derive(Clone, Debug, Default)]
pub struct PackedCylinders {
    /// One a cylinder, in order (a joined record's `p3` is the next record's `p0`).
    records: Vec<Packed>,
    /// The fourth control points of the packed cylinders that are not joined to the next.
    ends: Vec<DVec3>,
    /// Radii at the segments' ends; a segment's end and the next one's start share an entry
    /// when they are equal, and so do the ends of a segment of constant radii.
    radii: Vec<Radii>,
    /// The cylinders that did not pack.
    whole: Vec<GeneralizedCylinder>,
}

impl PackedCylinders {
    /// The most cylinders a store holds, 2^26 (a record names its end point in the 26 bits
    /// its flags leave).
    pub const MAX: usize = 1 << (32 - Packed::END_SHIFT);

    /// Packs `cylinders` (module docs), keeping their order.
    ///
    /// # Panics
    ///
    /// With more than [`Self::MAX`] cylinders.
    pub fn new(cylinders: impl IntoIterator<Item = GeneralizedCylinder>) -> Self {
        let cylinders: Vec<GeneralizedCylinder> = cylinders.into_iter().collect();
        Self::new_mapped(cylinders, |cylinders, record| {
            cylinders.iter().map(record).collect()
        })
    }

    /// [`Self::new`], with each cylinder's own record made by `map(cylinders, record)`, which
    /// must return `cylinders.iter().map(record)` collected, in order (a caller can map in
    /// parallel; the records then take their first touch of fresh memory in parallel too).
    /// The rest, joining a strand's records and sharing their radii, runs in order.
    ///
    /// # Panics
    ///
    /// With more than [`Self::MAX`] cylinders, or if `map` returns other than one record a
    /// cylinder.
    pub fn new_mapped(
        cylinders: Vec<GeneralizedCylinder>,
        map: impl FnOnce(
            &[GeneralizedCylinder],
            &(dyn Fn(&GeneralizedCylinder) -> Record + Sync),
        ) -> Vec<Record>,
    ) -> Self {
        assert!(cylinders.len() <= Self::MAX, "too many cylinders");
        let records = map(&cylinders, &|c| Record(Self::pack(c)));
        assert_eq!(records.len(), cylinders.len(), "one record a cylinder");
        let mut out = PackedCylinders {
            // The records' own memory, written in place below.
            records: records.into_iter().map(|r| r.0).collect(),
            ..Default::default()
        };
        for (i, c) in cylinders.into_iter().enumerate() {
            out.settle(i, c);
        }
        out.ends.shrink_to_fit();
        out.radii.shrink_to_fit();
        out.whole.shrink_to_fit();
        out
    }

    /// Completes record `i` (made by [`Self::pack`], all before it settled): a cylinder that
    /// did not pack is kept whole; a packed one is joined to the record before it where it
    /// starts at that one's end, and takes its radii's place.
    fn settle(&mut self, i: usize, c: GeneralizedCylinder) {
        if self.records[i].flags & Packed::WHOLE != 0 {
            self.records[i].radii = self.whole.len() as u32;
            self.whole.push(c);
            return;
        }
        // Joined to the record before when that is packed, its end is the last one kept
        // aside, and `c`'s origin serves as its `p3` (rebuilds its local point: the end kept
        // is `o + l`, which may differ from the strand's joint in the last bit).
        if let Some(last) = i.checked_sub(1).map(|j| &mut self.records[j])
            && last.flags & (Packed::WHOLE | Packed::JOINED) == 0
            && (last.flags >> Packed::END_SHIFT) as usize + 1 == self.ends.len()
            && self.ends.last().is_some_and(|&end| {
                let o = last.points[0];
                bits(c.origin - o) == bits(end - o)
            })
        {
            last.flags = (last.flags & ((1 << Packed::END_SHIFT) - 1)) | Packed::JOINED;
            self.ends.pop();
        }
        let record = &mut self.records[i];
        record.flags |= (self.ends.len() as u32) << Packed::END_SHIFT;
        self.ends.push(c.origin + c.axis.points[3]);
        let [start, end] = [0, 1].map(|k| Radii {
            major: c.sweep.major[k],
            minor: c.sweep.minor[k],
        });
        if self.radii.last().map(|r| r.bits()) != Some(start.bits()) {
            self.radii.push(start);
        }
        record.radii = self.radii.len() as u32 - 1;
        if end.bits() != start.bits() {
            self.radii.push(end);
            record.radii |= Packed::TAPERED;
        }
        debug_assert!(self.unpack(i) == c, "a packed cylinder rebuilds as itself");
    }

    /// The record of `c` (without `radii` and the end's place) if it packs (module docs), else
    /// a placeholder marked [`Packed::WHOLE`].
    fn pack(c: &GeneralizedCylinder) -> Packed {
        Self::packed(c).unwrap_or(Packed {
            points: [DVec3::ZERO; 3],
            reference: DVec3::ZERO,
            rotation: [0.0; 2],
            radii: 0,
            flags: Packed::WHOLE,
        })
    }

    /// The record of `c` (without `radii` and the end's place), if it packs.
    fn packed(c: &GeneralizedCylinder) -> Option<Packed> {
        if !matches!(c.section, Section::Circle(_)) || c.has_switches() {
            return None;
        }
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
        let l = &c.axis.points;
        Some(Packed {
            points: [o, o + l[1], o + l[2]],
            reference,
            rotation: c.sweep.rotation,
            radii: 0,
            flags: flag | caps | (u32::from(c.may_fold()) * Packed::MAY_FOLD),
        })
    }

    /// The world control points of packed record `i`.
    #[inline]
    fn world_points(&self, i: usize) -> [DVec3; 4] {
        let r = &self.records[i];
        let p3 = if r.flags & Packed::JOINED != 0 {
            self.records[i + 1].points[0]
        } else {
            self.ends[(r.flags >> Packed::END_SHIFT) as usize]
        };
        [r.points[0], r.points[1], r.points[2], p3]
    }

    /// The sweep of packed record `r`: its radii and rotation.
    #[inline]
    fn sweep(&self, r: &Packed) -> HairSweep {
        let start = (r.radii & !Packed::TAPERED) as usize;
        let [a, b] = [
            self.radii[start],
            self.radii[start + usize::from(r.radii & Packed::TAPERED != 0)],
        ];
        HairSweep {
            major: [a.major, b.major],
            minor: [a.minor, b.minor],
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
            Section::Circle(UnitCircle),
            self.sweep(r),
            [
                r.flags & Packed::CAP_START != 0,
                r.flags & Packed::CAP_END != 0,
            ],
            r.flags & Packed::MAY_FOLD != 0,
        )
    }

    /// Cylinder `i`'s axis control points in world coordinates and
    /// [`GeneralizedCylinder::reach_ends`], without rebuilding the cylinder: what a cheap cull
    /// needs. The points are those stored (a whole cylinder's [`GeneralizedCylinder::axis`],
    /// origin plus local points); they may differ from the rebuilt cylinder's `axis()` in the
    /// last bit.
    ///
    /// # Panics
    ///
    /// If `i >= self.len()`.
    #[inline]
    pub fn axis_and_reach(&self, i: usize) -> ([DVec3; 4], [f64; 2]) {
        let r = &self.records[i];
        if r.flags & Packed::WHOLE != 0 {
            let c = &self.whole[r.radii as usize];
            return (c.axis().points, c.reach_ends());
        }
        // `reach_ends` of the rebuilt cylinder.
        let bound = UnitCircle.bounding_radius();
        let reach = self.sweep(r).scale_bound().map(|l| l * bound);
        (self.world_points(i), reach)
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
    /// store: its record and the next record's first point (its fourth control point when
    /// joined), for a caller that wants to start loading them early (a cache hint; past the
    /// end, the address lies outside the store and must not be read).
    #[inline]
    pub fn storage(&self, i: usize) -> (*const u8, usize) {
        let r = self.records.as_ptr().wrapping_add(i);
        (r.cast::<u8>(), size_of::<Packed>() + size_of::<DVec3>())
    }

    /// Bytes held: the records, ends and radii, and the whole cylinders with their own heap
    /// data (a section's profile not included: profiles are shared).
    pub fn memory_bytes(&self) -> usize {
        self.records.capacity() * size_of::<Packed>()
            + self.ends.capacity() * size_of::<DVec3>()
            + self.radii.capacity() * size_of::<Radii>()
            + self.whole.capacity() * size_of::<GeneralizedCylinder>()
            + self.whole.iter().map(|c| c.heap_bytes()).sum::<usize>()
    }

    /// The cylinders kept whole (did not pack), in order.
    pub fn whole(&self) -> &[GeneralizedCylinder] {
        &self.whole
    }
}

impl Radii {
    /// The radii's bits.
    fn bits(&self) -> [u64; 2] {
        [self.major, self.minor].map(f64::to_bits)
    }
}

/// The bits of a point's coordinates (equal bits: the same point, `-0` and `0` told apart).
fn bits(p: DVec3) -> [u64; 3] {
    p.to_array().map(f64::to_bits)
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
        let mut strands = 0;
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
                    all.extend(s.cylinders_with(framing).unwrap());
                    strands += 1;
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
        // The records made in another order (as a parallel map makes them): the same store.
        let mapped = PackedCylinders::new_mapped(all.clone(), |cylinders, record| {
            let mut records: Vec<Record> = cylinders.iter().rev().map(record).collect();
            records.reverse();
            records
        });
        assert!(mapped.records == packed.records && mapped.ends == packed.ends);
        assert!(mapped.radii == packed.radii && mapped.whole == packed.whole);
        // What packs: all strand segments but those whose points do not come back; three kinds
        // a block stay whole.
        let whole = packed.whole().len();
        assert!(whole >= 12, "{whole} whole");
        assert!(
            whole <= 12 + strands * 8 / 4,
            "most strand segments pack: {whole} whole"
        );
        assert!(
            packed.memory_bytes() * 10 < bytes_whole(&all) * 8,
            "packed {} bytes against {}",
            packed.memory_bytes(),
            bytes_whole(&all)
        );
    }

    /// A strand's segments share their joints and radii: three points a segment and its tip, one
    /// set of radii for a round strand of constant radius, 120 bytes of record a segment.
    #[test]
    fn a_strand_stores_three_points_a_segment() {
        let mut rng = Lcg(3);
        let s = strand(
            &mut rng,
            DVec3::new(0.5, 0.25, -0.75),
            17,
            [0.01, 0.01],
            1.0,
        );
        let cylinders = s.cylinders().unwrap();

        let packed = PackedCylinders::new(cylinders.clone());
        assert!(packed.whole().is_empty(), "every segment packs");
        assert_eq!(packed.ends.len(), 1, "joints shared: one end kept aside");
        assert_eq!(packed.radii.len(), 1, "one radius");
        assert_eq!(size_of::<Packed>(), 120);
        for (i, c) in cylinders.iter().enumerate() {
            assert!(*packed.get(i) == *c, "segment {i}");
        }
        // Two strands one after the other share nothing across their gap.
        let t = strand(&mut rng, DVec3::new(5.0, 0.0, 0.0), 5, [0.02, 0.01], 1.0);
        let both: Vec<_> = cylinders
            .iter()
            .cloned()
            .chain(t.cylinders().unwrap())
            .collect();
        let packed = PackedCylinders::new(both.clone());
        assert_eq!(packed.ends.len(), 2, "each strand's tip kept aside");
        assert_eq!(
            packed.radii.len(),
            1 + 5,
            "a tapered strand of 4 segments: radii at its 3 joints and 2 ends"
        );
        for (i, c) in both.iter().enumerate() {
            assert!(*packed.get(i) == *c, "segment {i}");
        }
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
