//! The scene ready for ray queries: cylinders and a BVH over pieces of their axes.

use std::borrow::Cow;

use gencyl::{GeneralizedCylinder, Hit, Method, PackedCylinders, Ray, Section, StrandControls};
use rayon::prelude::*;

use crate::accel::COUNTING;
use crate::accel::bvh::{Bvh, RegionList};
use crate::accel::cull::{Piece, RaySpace, level_for, pieces_bounds_under};
use crate::accel::prefetch::prefetch_bytes;

/// A hit on a scene: the cylinder's hit and the cylinder's number.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneHit {
    /// The hit on the cylinder.
    pub hit: Hit,
    /// The cylinder's number (its index in file order).
    pub object: u32,
}

/// Cylinders with a BVH over them, ready for ray queries.
///
/// Each cylinder enters the BVH as one or more [`Piece`]s of its axis (long, thin fibers as
/// several, so their boxes stay tight); a ray reaching a piece's box is culled by the cheap
/// [`RaySpace`] test against that piece before the exact solver runs, once per cylinder and
/// ray. Queries take a caller-owned [`Scratch`] so that none allocates once its buffers have
/// grown. The cylinders are stored packed ([`PackedCylinders`]: a strand's segments share their
/// joints' control points) and rebuilt for each test.
#[derive(Clone, Debug)]
pub struct Scene {
    cylinders: PackedCylinders,
    bvh: Bvh,
}

/// Buffers a query reuses: one per thread. It also counts what the queries made with it did
/// ([`Scratch::counts`], where counting is built in).
#[derive(Clone, Debug, Default)]
pub struct Scratch {
    hits: Vec<Hit>,
    /// Cylinders already given to the exact solver in this query.
    tested: Vec<u32>,
    counts: QueryCounts,
}

impl Scratch {
    /// What the queries made with this scratch did so far.
    pub fn counts(&self) -> QueryCounts {
        self.counts
    }

    /// [`Self::counts`], starting the count again from zero.
    pub fn take_counts(&mut self) -> QueryCounts {
        std::mem::take(&mut self.counts)
    }
}

/// What a scene's queries did, step by step (as pbrt's statistics count them): how much of
/// the BVH the rays walked, how many cylinders the cull cleared and how many went to the exact
/// test. Counted per thread in its [`Scratch`] as the queries run, where counting is built in
/// ([`COUNTING`]; all zero otherwise); sums of several threads' by `+=`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct QueryCounts {
    /// Nearest-hit queries (a renderer's camera and bounce rays) and how many found a hit.
    pub nearest: u64,
    /// See [`Self::nearest`].
    pub nearest_hits: u64,
    /// Any-hit queries (shadow rays) and how many found one (a blocker).
    pub any: u64,
    /// See [`Self::any`].
    pub any_hits: u64,
    /// All-hits queries.
    pub all: u64,
    /// BVH nodes whose children's boxes a ray was tested against.
    pub nodes: u64,
    /// Cylinder pieces in the leaves the rays reached.
    pub pieces: u64,
    /// Culls: pieces of cylinders not yet tested in the query (other than the one the ray
    /// leaves), and of those, how many the cull cleared.
    pub culls: u64,
    /// See [`Self::culls`].
    pub cleared: u64,
    /// Exact tests on the cylinders the cull let through (`culls - cleared`).
    pub exact: u64,
    /// The cylinder a spawned ray leaves, reached by the walk: given to the exact test (or
    /// its cheaper clearing test) without the cull; an any-hit query tests it last, only if
    /// nothing else blocks the ray.
    pub exact_leaving: u64,
}

/// `n += 1` where counting is built in ([`COUNTING`]); nothing otherwise.
#[inline(always)]
fn tally(n: &mut u64) {
    if COUNTING {
        *n += 1;
    }
}

impl QueryCounts {
    /// Queries of every kind.
    pub fn queries(&self) -> u64 {
        self.nearest + self.any + self.all
    }
}

impl std::ops::AddAssign for QueryCounts {
    fn add_assign(&mut self, o: QueryCounts) {
        self.nearest += o.nearest;
        self.nearest_hits += o.nearest_hits;
        self.any += o.any;
        self.any_hits += o.any_hits;
        self.all += o.all;
        self.nodes += o.nodes;
        self.pieces += o.pieces;
        self.culls += o.culls;
        self.cleared += o.cleared;
        self.exact += o.exact;
        self.exact_leaving += o.exact_leaving;
    }
}

/// BVH keys: cylinder number in the high bits, the piece's heap index (< 16) in the low 4.
const PIECE_BITS: u32 = 4;
const _: () = assert!(
    2 << crate::accel::cull::MAX_PIECE_LEVEL <= 1 << PIECE_BITS,
    "piece index fits its bits"
);
const _: () = assert!(
    PackedCylinders::MAX <= 1 << (32 - PIECE_BITS),
    "cylinder numbers fit their bits"
);

impl Scene {
    /// The most cylinders a scene holds, 2^26 (the packed store's limit; the BVH names a
    /// cylinder's pieces in 32 bits, which would allow 2^28).
    pub const MAX_CYLINDERS: usize = PackedCylinders::MAX;

    /// Builds the BVH over `cylinders` (in parallel on the current rayon pool).
    ///
    /// # Panics
    ///
    /// With more than [`Scene::MAX_CYLINDERS`] cylinders.
    pub fn new(cylinders: Vec<GeneralizedCylinder>) -> Self {
        Self::with_strands(cylinders, StrandControls::default())
    }

    /// [`Scene::new`], with the strands among the cylinders named by their control points,
    /// which then store their segments compactly ([`PackedCylinders::new_mapped`]).
    ///
    /// # Panics
    ///
    /// With more than [`Scene::MAX_CYLINDERS`] cylinders.
    pub fn with_strands(cylinders: Vec<GeneralizedCylinder>, strands: StrandControls) -> Self {
        assert!(
            cylinders.len() <= Self::MAX_CYLINDERS,
            "at most 2^26 cylinders"
        );
        // Packed before the BVH is built, so the build's memory adds to the packed cylinders,
        // not to the whole ones; each cylinder's pieces are chosen in the same pass.
        let mut levels = Vec::new();
        let cylinders = PackedCylinders::new_mapped(cylinders, &strands, |cylinders, record| {
            let records;
            (records, levels) = cylinders
                .par_iter()
                .enumerate()
                .map(|(i, c)| (record(i, c), level_for(c)))
                .unzip();
            records
        });
        // The packed store keeps what it needs of the strands' points.
        drop(strands);
        let bvh = Bvh::build_grouped(
            cylinders.len(),
            |i| 1 << levels[i],
            |i, out| {
                pieces_bounds_under(&cylinders.get(i), Piece::WHOLE, levels[i], &mut |p, b| {
                    out.push((b, (i as u32) << PIECE_BITS | p.0))
                });
            },
        );
        Scene { cylinders, bvh }
    }

    /// How many cylinders.
    pub fn len(&self) -> usize {
        self.cylinders.len()
    }

    /// Whether the scene has no cylinder.
    pub fn is_empty(&self) -> bool {
        self.cylinders.is_empty()
    }

    /// Cylinder `object` (rebuilt from its packed form, or borrowed).
    ///
    /// # Panics
    ///
    /// If `object >= self.len()`.
    pub fn cylinder(&self, object: u32) -> Cow<'_, GeneralizedCylinder> {
        self.cylinders.get(object as usize)
    }

    /// The cylinders in object order.
    pub fn cylinders(&self) -> impl ExactSizeIterator<Item = Cow<'_, GeneralizedCylinder>> + '_ {
        self.cylinders.iter()
    }

    /// The BVH (over pieces of cylinders).
    pub fn bvh(&self) -> &Bvh {
        &self.bvh
    }

    /// Bytes held by the cylinders (packed, and the whole ones with their heap data; a profile
    /// shared by many cylinders once) and the BVH.
    pub fn memory_bytes(&self) -> usize {
        let mut profiles = std::collections::HashSet::new();
        let sections = self
            .cylinders
            .whole()
            .iter()
            .map(|c| match c.section() {
                Section::Loop(l) if profiles.insert(l.storage_id()) => l.storage_bytes(),
                _ => 0,
            })
            .sum::<usize>();
        self.cylinders.memory_bytes() + sections + self.bvh.memory_bytes()
    }

    /// Walks the BVH and hands each cylinder that may be hit within `(tmin, tmax)` to
    /// `exact(object, cylinder, tmax)` (at most once per query), which returns the new `tmax`
    /// as [`Bvh::traverse`]'s closure does: nearer boxes first where `NEAREST_FIRST` (a
    /// nearest-hit query, whose `tmax` shrinks with each hit), in the tree's order otherwise
    /// ([`Bvh::traverse_prefetching_in`]: all hits, any hit). With `list`, the walk is over the
    /// listed leaves of a region the ray lies in ([`Bvh::traverse_listed`]).
    ///
    /// `leaving`: the cylinder the ray leaves, its origin on that cylinder's surface (a ray a
    /// renderer spawns from a hit). The cull cannot clear a piece the origin lies within reach
    /// of, and for a piece about the origin it would halve the axis, often to its last level,
    /// before saying so: that cylinder goes to the exact test without it. The answer is the same for
    /// any cylinder named (the cull only ever clears cylinders the exact test would find no
    /// hit on); naming the right one only makes it faster.
    fn candidates<const NEAREST_FIRST: bool>(
        &self,
        ray: &Ray,
        (tmin, tmax): (f64, f64),
        leaving: Option<u32>,
        list: Option<&RegionList>,
        (tested, counts): (&mut Vec<u32>, &mut QueryCounts),
        mut exact: impl FnMut(u32, &GeneralizedCylinder, f64) -> f64,
    ) {
        tested.clear();
        // Counted here, added to `counts` once the walk is done.
        let (mut pieces, mut culls, mut cleared, mut tests, mut exact_leaving) = (0, 0, 0, 0, 0);
        // Made when the first leaf is reached (most rays miss the model).
        let mut space: Option<RaySpace> = None;
        // Every cylinder of a leaf (of several pieces, each of another cylinder, mostly).
        let cylinder = |keys: &[u32]| {
            let mut last = u32::MAX;
            for &key in keys {
                let i = key >> PIECE_BITS;
                if i == last {
                    continue;
                }
                last = i;
                for (p, len) in self.cylinders.storage(i as usize) {
                    if len > 0 {
                        prefetch_bytes(p, len);
                    }
                }
            }
        };
        let visit = |key: u32, tmax: f64| {
            tally(&mut pieces);
            let i = key >> PIECE_BITS;
            if tested.contains(&i) {
                return tmax;
            }
            if leaving != Some(i) {
                tally(&mut culls);
                // The cull reads the stored axis; the cylinder is rebuilt only past it.
                let space = space.get_or_insert_with(|| RaySpace::new(ray));
                let piece = Piece(key & ((1 << PIECE_BITS) - 1));
                let may_hit =
                    self.cylinders
                        .with_axis_controls(i as usize, |axis, spline, reach| {
                            space.may_hit_axis_controls(axis, spline, reach, piece, tmin, tmax)
                        });
                if !may_hit {
                    tally(&mut cleared);
                    return tmax;
                }
            } else {
                tally(&mut exact_leaving);
            }
            tested.push(i);
            tally(&mut tests);
            exact(i, &self.cylinders.get(i as usize), tmax)
        };
        let range = (tmin, tmax);
        let nodes = match list {
            Some(list) => self.bvh.traverse_listed(ray, range, list, visit),
            None => self
                .bvh
                .traverse_prefetching_in::<NEAREST_FIRST>(ray, range, cylinder, visit),
        };
        if COUNTING {
            counts.nodes += nodes as u64;
            counts.pieces += pieces;
            counts.culls += culls;
            counts.cleared += cleared;
            counts.exact += tests - exact_leaving;
            counts.exact_leaving += exact_leaving;
        }
    }

    /// The nearest hit with `tmin < t < tmax`. Of hits at the same `t` the one of the lowest
    /// object number wins, so the answer does not depend on the BVH's layout.
    pub fn nearest_hit(
        &self,
        ray: &Ray,
        tmin: f64,
        tmax: f64,
        scratch: &mut Scratch,
    ) -> Option<SceneHit> {
        self.nearest_hit_where(ray, (tmin, tmax), None, scratch, |_| true)
    }

    /// The nearest hit with `tmin < t < tmax`, where on the cylinders for which `exits_stop`
    /// is false only entries count (`normal . d <= 0`,
    /// [`GeneralizedCylinder::intersect_first_entering_with`]): a renderer skips the exits of
    /// fibers it shades as far-field scatterers this way. `leaving`: the cylinder whose
    /// surface the ray leaves and the point's `u`, if any (the same answer, found faster:
    /// where only entries count on it, that fiber is mostly cleared at once,
    /// [`GeneralizedCylinder::enters_nowhere_after`]).
    pub fn nearest_hit_where(
        &self,
        ray: &Ray,
        range: (f64, f64),
        leaving: Option<Leaving>,
        scratch: &mut Scratch,
        exits_stop: impl Fn(u32) -> bool,
    ) -> Option<SceneHit> {
        self.nearest(ray, range, leaving, None, scratch, exits_stop)
    }

    /// [`Self::nearest_hit_where`] for a ray within a region whose leaves `list` holds
    /// ([`Bvh::list_region`]; a camera ray within its pixel's frustum): the same hit, found
    /// over the list instead of the tree ([`Bvh::traverse_listed`]).
    pub fn nearest_hit_listed(
        &self,
        ray: &Ray,
        range: (f64, f64),
        list: &RegionList,
        scratch: &mut Scratch,
        exits_stop: impl Fn(u32) -> bool,
    ) -> Option<SceneHit> {
        self.nearest(ray, range, None, Some(list), scratch, exits_stop)
    }

    /// [`Self::nearest_hit_where`] over the tree, or over `list` where given.
    fn nearest(
        &self,
        ray: &Ray,
        (tmin, tmax): (f64, f64),
        leaving: Option<Leaving>,
        list: Option<&RegionList>,
        scratch: &mut Scratch,
        exits_stop: impl Fn(u32) -> bool,
    ) -> Option<SceneHit> {
        let mut best: Option<SceneHit> = None;
        let range = (tmin, tmax);
        let left = leaving.map(|l| l.object);
        tally(&mut scratch.counts.nearest);
        let parts = (&mut scratch.tested, &mut scratch.counts);
        self.candidates::<true>(ray, range, left, list, parts, |i, c, _| {
            // The fiber the ray leaves, where only entries count: mostly shown to have none
            // ahead at a small part of the search's cost.
            if leaving.is_some_and(|l| l.object == i && !exits_stop(i) && l.clears(c, ray, tmin)) {
                return best.map_or(tmax, |b| b.hit.t);
            }
            // Exclusive upper bound for the cylinder: up to and including the best t, for ties.
            let limit = best.map_or(tmax, |b| b.hit.t.next_up());
            if let Some(hit) = first_hit(c, ray, tmin, limit, exits_stop(i))
                && best.is_none_or(|b| hit.t < b.hit.t || (hit.t == b.hit.t && i < b.object))
            {
                best = Some(SceneHit { hit, object: i });
            }
            best.map_or(tmax, |b| b.hit.t)
        });
        if best.is_some() {
            tally(&mut scratch.counts.nearest_hits);
        }
        best
    }

    /// Appends every hit with `tmin < t < tmax` to `out`, sorted by `t` (then object number).
    pub fn all_hits(
        &self,
        ray: &Ray,
        tmin: f64,
        tmax: f64,
        out: &mut Vec<SceneHit>,
        scratch: &mut Scratch,
    ) {
        let start = out.len();
        let hits = &mut scratch.hits;
        tally(&mut scratch.counts.all);
        self.candidates::<false>(
            ray,
            (tmin, tmax),
            None,
            None,
            (&mut scratch.tested, &mut scratch.counts),
            |i, c, tmax| {
                hits.clear();
                c.intersect_all(ray, tmin, tmax, hits);
                out.extend(hits.iter().map(|&hit| SceneHit { hit, object: i }));
                tmax
            },
        );
        sort_hits(&mut out[start..]);
    }

    /// Whether anything is hit with `tmin < t < tmax` (stops at the first hit found).
    pub fn any_hit(&self, ray: &Ray, tmin: f64, tmax: f64, scratch: &mut Scratch) -> bool {
        self.any_hit_where(ray, (tmin, tmax), None, scratch, |_| true)
    }

    /// Whether any hit lies within `tmin < t < tmax`, where on the cylinders for which
    /// `exits_stop` is false only entries count, and `leaving` names the cylinder the ray
    /// leaves (as [`Self::nearest_hit_where`]).
    ///
    /// The cylinder left is tested last, only if the walk reaches it and nothing else blocks
    /// the ray: a shadow ray from a fiber is mostly blocked by others (two in three on the
    /// path-traced ponytail), and its own fiber's test, which mostly shows that the ray does
    /// not enter it again, is then never made; where it is made, and only entries count on
    /// it, it is mostly cleared at once ([`GeneralizedCylinder::enters_nowhere_after`]).
    pub fn any_hit_where(
        &self,
        ray: &Ray,
        (tmin, tmax): (f64, f64),
        leaving: Option<Leaving>,
        scratch: &mut Scratch,
        exits_stop: impl Fn(u32) -> bool,
    ) -> bool {
        let left = leaving.map(|l| l.object);
        let mut found = false;
        let mut reached_left = false;
        let range = (tmin, tmax);
        tally(&mut scratch.counts.any);
        let parts = (&mut scratch.tested, &mut scratch.counts);
        self.candidates::<false>(ray, range, left, None, parts, |i, c, tmax| {
            if left == Some(i) {
                reached_left = true;
                return tmax;
            }
            // Once found, stays found (with `tmin = -inf` the walk goes on after a hit).
            found |= c.any_hit(ray, tmin, tmax, !exits_stop(i));
            if found { f64::NEG_INFINITY } else { tmax }
        });
        if let Some(l) = leaving.filter(|_| reached_left && !found) {
            let c = self.cylinder(l.object);
            let entering = !exits_stop(l.object);
            found = !(entering && l.clears(&c, ray, tmin)) && c.any_hit(ray, tmin, tmax, entering);
        }
        if found {
            tally(&mut scratch.counts.any_hits);
        }
        found
    }
}

/// The fiber a spawned ray leaves ([`Scene::nearest_hit_where`], [`Scene::any_hit_where`]): its
/// object number and the `u` of the point it leaves (any value is safe; the right one makes
/// the query faster).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Leaving {
    /// The cylinder's object number.
    pub object: u32,
    /// The axis parameter of the point left.
    pub u: f64,
}

impl Leaving {
    /// Whether the ray certainly enters `c`, the fiber it leaves, nowhere beyond `tmin`
    /// ([`GeneralizedCylinder::enters_nowhere_after`], from the point left).
    fn clears(&self, c: &GeneralizedCylinder, ray: &Ray, tmin: f64) -> bool {
        c.enters_nowhere_after(ray, tmin, Some(self.u))
    }
}

/// The cylinder's nearest hit with `tmin < t < tmax`, among its entries only unless
/// `exits_stop`.
#[inline]
fn first_hit(
    c: &GeneralizedCylinder,
    ray: &Ray,
    tmin: f64,
    tmax: f64,
    exits_stop: bool,
) -> Option<Hit> {
    if exits_stop {
        c.intersect_first_with(ray, tmin, tmax, Method::Auto, |_| true)
    } else {
        c.intersect_first_entering_with(ray, tmin, tmax, Method::Auto, |_| true)
    }
}

/// Sorts hits by `t`, then object number; a stable sort, so one cylinder's hits at equal `t`
/// stay in the cylinder's order.
pub fn sort_hits(hits: &mut [SceneHit]) {
    hits.sort_by(|a, b| a.hit.t.total_cmp(&b.hit.t).then(a.object.cmp(&b.object)));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::SampleRng as Rng;
    use crate::scenes::synth::hair_model;
    use gencyl::{Strand, StrandFraming};
    use glam::DVec3;

    /// The cylinders of `hair_model(strands, segments, seed)`'s strands, each made by `strand`
    /// (its number, its interpolating control points) with its framing, and their controls.
    fn strands(
        (count, segments, seed): (usize, usize, u64),
        strand: impl Fn(usize, Vec<DVec3>) -> (Strand, StrandFraming),
    ) -> (Vec<GeneralizedCylinder>, StrandControls) {
        let (points, _) = hair_model(count, segments, seed);
        let mut cylinders = vec![];
        let mut controls = StrandControls::default();
        for (k, p) in points.iter().enumerate() {
            let (s, framing) = strand(k, Strand::interpolating_control_points(p));
            controls.push(cylinders.len(), &s.spline_controls(), s.taper());
            cylinders.extend(s.cylinders_with(framing).unwrap());
        }
        (cylinders, controls)
    }

    /// A ray spawned from a hit, with the cylinder it leaves named, gets the same answers as
    /// without (nearest hit and any hit, with exits counting or, as for far-field fibers, not):
    /// rays from points on the surface (or just off it, as a renderer offsets them) into the
    /// fiber and out of it, nearly along it (1e-12 to 1e-1 rad off the tangent) and tangent
    /// to it, and across it down to 1e-15 rad off the normal plane. Enough of them have their
    /// nearest hit on the cylinder they leave (its far side), so that a query skipping that
    /// cylinder's exact test, not just its cull, or deferring it (as the any-hit query does)
    /// and never making it, would fail.
    #[test]
    fn rays_leaving_a_named_cylinder_get_the_same_answers() {
        let (cylinders, controls) = strands((40, 8, 3), |k, points| {
            let strand = Strand {
                points,
                radius: [0.004, 0.002 + 0.002 * (k % 2) as f64],
                ellipticity: 1.0,
                twist: [0.0, 0.0],
                section: Default::default(),
            };
            (strand, StrandFraming::RotationMinimizing)
        });
        let scene = Scene::with_strands(cylinders.clone(), controls);
        let mut rng = Rng::from_seed(5);
        let (mut a, mut b) = (Scratch::default(), Scratch::default());
        let (mut own, mut other, mut blocked) = (0, 0, 0);
        for i in 0..4000 {
            let object = rng.range(0.0, cylinders.len() as f64) as u32;
            let c = &cylinders[object as usize];
            let (u, v) = (rng.range(0.02, 0.98), rng.range(0.0, std::f64::consts::TAU));
            let f = c.frame(u);
            let across = (f.n * v.cos() + f.b * v.sin()).normalize();
            let side = f.t.cross(across);
            let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
            let d = match i / 2 % 4 {
                // Into the fiber or out of it, in any direction on that side.
                0 => {
                    let d = rng.unit_vector();
                    if d.dot(across) * sign < 0.0 { -d } else { d }
                }
                // Nearly along the fiber, tilted in or out.
                1 => f.t + across * sign * 10f64.powf(rng.range(-12.0, -1.0)),
                // Tangent to the section.
                2 => side,
                // Across the fiber, off the normal plane by 1e-15 .. 1e-1 rad or not at all.
                _ => {
                    let off = if i % 16 < 2 {
                        0.0
                    } else {
                        10f64.powf(rng.range(-15.0, -1.0))
                    };
                    across * sign + f.t * off
                }
            };
            // On the surface, or off it by up to 1e-9 of the radius either way.
            let offset = rng.range(-1e-9, 1e-9) * 0.004 * (i % 3) as f64;
            let ray = Ray::new(c.surface_point(u, v) + across * offset, d.normalize());
            let range = (1e-9, f64::INFINITY);
            // The point left named, or a wrong one (any is safe).
            let named_u = if i % 5 == 0 { rng.range(0.0, 1.0) } else { u };
            let left = Leaving { object, u: named_u };
            for far_field in [false, true] {
                let exits_stop = |_: u32| !far_field;
                let named = scene.nearest_hit_where(&ray, range, Some(left), &mut a, exits_stop);
                let plain = scene.nearest_hit_where(&ray, range, None, &mut b, exits_stop);
                assert_eq!(
                    named, plain,
                    "{ray:?} leaving {object}, far field {far_field}"
                );
                let named = scene.any_hit_where(&ray, range, Some(left), &mut a, exits_stop);
                let plain = scene.any_hit_where(&ray, range, None, &mut b, exits_stop);
                assert_eq!(
                    named, plain,
                    "{ray:?} leaving {object}, far field {far_field}"
                );
                blocked += usize::from(plain);
                // The whole line (`tmin = -inf`, which the box test once let into empty slots).
                let line = (f64::NEG_INFINITY, f64::INFINITY);
                let any = scene.any_hit_where(&ray, line, Some(left), &mut a, exits_stop);
                let nearest = scene.nearest_hit_where(&ray, line, None, &mut b, exits_stop);
                assert_eq!(
                    any,
                    nearest.is_some(),
                    "{ray:?} leaving {object}, the whole line"
                );
            }
            match scene.nearest_hit(&ray, range.0, range.1, &mut b) {
                Some(h) if h.object == object => own += 1,
                Some(_) => other += 1,
                None => {}
            }
        }
        assert!(own > 1000, "{own} nearest hits on the cylinder left");
        assert!(other > 50, "{other} nearest hits on other cylinders");
        assert!(blocked > 2000, "{blocked} blocked of 8000 queries");
    }

    /// A scratch's counts add up: the queries of each kind and their hits are the answers'
    /// (counted here from what the queries returned), every cull either clears its cylinder or
    /// sends it to the exact test, a leaf's pieces are at least the culls and the tests without
    /// one, the fiber a spawned ray leaves goes to its test without a cull, and a ray that
    /// misses the scene's box walks no node and reaches no piece. Counts of several scratches
    /// add as their parts.
    #[test]
    fn query_counts_add_up() {
        let (cylinders, controls) = strands((60, 8, 4), |_, points| {
            let strand = Strand {
                points,
                radius: [0.004, 0.003],
                ellipticity: 1.0,
                twist: [0.0, 0.0],
                section: Default::default(),
            };
            (strand, StrandFraming::RotationMinimizing)
        });
        let scene = Scene::with_strands(cylinders.clone(), controls);
        let bounds = scene.bvh().bounds();
        let mut rng = Rng::from_seed(12);
        let (mut scratch, mut other) = (Scratch::default(), Scratch::default());
        let mut want = QueryCounts::default();
        let mut all = Vec::new();
        for i in 0..3000 {
            // Toward a point near a fiber's axis (most hit), from anywhere about it.
            let c = &cylinders[rng.next_u64() as usize % cylinders.len()];
            let target = c.axis().point(rng.uniform()) + rng.unit_vector() * 0.006;
            let origin = target + rng.unit_vector() * 0.5;
            let ray = Ray::new(origin, target - origin);
            let s = if i % 3 == 0 { &mut other } else { &mut scratch };
            match i % 4 {
                0 | 1 => {
                    want.nearest += 1;
                    let hit = scene.nearest_hit(&ray, 0.0, f64::INFINITY, s);
                    want.nearest_hits += u64::from(hit.is_some());
                    // A spawned ray from that hit, leaving its fiber.
                    if let Some(h) = hit {
                        let leaving = Leaving {
                            object: h.object,
                            u: h.hit.u,
                        };
                        let spawned = Ray::new(ray.at(h.hit.t), rng.unit_vector());
                        let before = s.counts().exact_leaving;
                        want.nearest += 1;
                        let again = scene.nearest_hit_where(
                            &spawned,
                            (1e-9, f64::INFINITY),
                            Some(leaving),
                            s,
                            |_| true,
                        );
                        want.nearest_hits += u64::from(again.is_some());
                        assert!(s.counts().exact_leaving <= before + 1, "its fiber once");
                    }
                }
                2 => {
                    want.any += 1;
                    want.any_hits += u64::from(scene.any_hit(&ray, 0.0, f64::INFINITY, s));
                }
                _ => {
                    want.all += 1;
                    all.clear();
                    scene.all_hits(&ray, 0.0, f64::INFINITY, &mut all, s);
                }
            }
        }
        let mut got = scratch.counts();
        got += other.counts();
        let kinds = |c: &QueryCounts| (c.nearest, c.nearest_hits, c.any, c.any_hits, c.all);
        assert_eq!(kinds(&got), kinds(&want), "queries and hits");
        assert!(want.nearest_hits > 500 && want.any_hits > 100, "{want:?}");
        assert_eq!(
            got.exact,
            got.culls - got.cleared,
            "a cull clears or sends to the test"
        );
        assert!(got.pieces >= got.culls + got.exact_leaving, "{got:?}");
        assert!(
            got.cleared > 0 && got.exact > 0 && got.exact_leaving > 0,
            "{got:?}"
        );
        assert!(
            got.nodes >= got.queries(),
            "every ray here enters the scene's box: {got:?}"
        );
        // A ray that misses the scene's box.
        let before = scratch.take_counts();
        assert_eq!(scratch.counts(), QueryCounts::default(), "taken");
        let away = Ray::new(bounds.max + DVec3::ONE, DVec3::ONE);
        assert!(
            scene
                .nearest_hit(&away, 0.0, f64::INFINITY, &mut scratch)
                .is_none()
        );
        let c = scratch.counts();
        assert_eq!(
            (c.nearest, c.nodes, c.pieces, c.culls),
            (1, 0, 0, 0),
            "{c:?}"
        );
        assert!(before.queries() > 0);
    }

    /// Strands named by their control points store their segments by them: the same hits to
    /// the bit as the same cylinders stored without them, for rays across the fibers (down to
    /// 1e-15 rad off perpendicular, and exactly so), grazing them (1e-9 of the radius deep),
    /// from points on their surface and at random; and at least 36 bytes a segment less.
    #[test]
    fn strands_by_their_control_points_give_the_same_hits() {
        let (cylinders, controls) = strands((60, 10, 5), |k, points| {
            let strand = Strand {
                points,
                radius: [0.004, 0.0015],
                ellipticity: [1.0, 0.7][k % 2],
                twist: [0.0, 2.0 * (k % 3) as f64],
                section: Default::default(),
            };
            let framing = [StrandFraming::RotationMinimizing, StrandFraming::Frenet][k % 5 / 4];
            (strand, framing)
        });
        let plain = Scene::new(cylinders.clone());
        let named = Scene::with_strands(cylinders.clone(), controls);
        let saved = plain.memory_bytes() - named.memory_bytes();
        assert!(saved >= 36 * cylinders.len(), "{saved} bytes saved");

        let mut rng = Rng::from_seed(11);
        let mut rays = vec![];
        for i in 0..3000 {
            let c = &cylinders[rng.range(0.0, cylinders.len() as f64) as usize];
            let (u, v) = (rng.uniform(), rng.range(0.0, std::f64::consts::TAU));
            let f = c.frame(u);
            let p = c.surface_point(u, v);
            let across = (f.n * v.cos() + f.b * v.sin()).normalize();
            let ray = match i % 4 {
                // Across the fiber, off perpendicular by 10^-15 .. 10^-1 rad, or exactly.
                0 => {
                    let off = if i % 8 == 0 {
                        0.0
                    } else {
                        10f64.powf(rng.range(-15.0, -1.0))
                    };
                    let d = -across * off.cos() + f.t * off.sin();
                    Ray::new(p - d * rng.range(0.01, 2.0), d)
                }
                // Grazing: tangent to the section, 1e-9 .. 1e-2 of the radius inside.
                1 => {
                    let side = f.t.cross(across).normalize();
                    let depth = 10f64.powf(rng.range(-9.0, -2.0)) * 0.004;
                    Ray::new(p - across * depth - side * 0.5, side)
                }
                // From a point on the surface, any direction.
                2 => Ray::new(p, rng.unit_vector()),
                _ => Ray::new(
                    DVec3::new(rng.range(-3.0, 3.0), rng.range(-3.0, 3.0), 4.0),
                    (rng.unit_vector() - DVec3::new(0.0, 0.0, 1.5)).normalize(),
                ),
            };
            rays.push(ray);
        }
        let (mut a, mut b) = (Scratch::default(), Scratch::default());
        let (mut hits_a, mut hits_b) = (vec![], vec![]);
        let mut hit = 0;
        for ray in &rays {
            let nearest = plain.nearest_hit(ray, 0.0, f64::INFINITY, &mut a);
            assert_eq!(nearest, named.nearest_hit(ray, 0.0, f64::INFINITY, &mut b));
            hits_a.clear();
            hits_b.clear();
            plain.all_hits(ray, 0.0, f64::INFINITY, &mut hits_a, &mut a);
            named.all_hits(ray, 0.0, f64::INFINITY, &mut hits_b, &mut b);
            assert_eq!(hits_a, hits_b, "{ray:?}");
            hit += usize::from(nearest.is_some());
        }
        assert!(hit > 1500, "{hit} of 3000 rays hit");
    }
}
