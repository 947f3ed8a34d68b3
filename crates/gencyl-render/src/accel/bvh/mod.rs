//! A bounding volume hierarchy over axis-aligned boxes.
//!
//! Built as pbrt builds it (a binary tree by the binned surface area heuristic, [`BINS`] bins
//! on each axis), then collapsed into a 4-wide tree as Embree stores it: each [`Node4`] holds
//! the boxes of up to four children, which one ray tests together (four lanes of `f64`), and
//! the children it enters are visited nearest first. Queried as parry queries it: one
//! traversal core, [`Bvh::traverse`], takes a closure that tests a primitive and returns the
//! best `t` so far, which serves nearest-hit (shrink `tmax`), all-hits (keep it) and any-hit
//! (return `-inf` to stop) queries alike.
//!
//! Boxes are stored in `f32`, rounded outward, so each holds its primitives' `f64` boxes; the
//! ray-box test runs in `f64`, so it misses nothing the exact `f64` test of the same boxes
//! would meet.

use gencyl::{Aabb, Ray};
use glam::DVec3;
use wide::{CmpGe, CmpLe, f64x4};

/// Number of SAH bins per axis.
pub const BINS: usize = 16;
/// Most primitives in a leaf.
pub const MAX_LEAF: usize = 8;
/// A bound on the binary tree's depth (48 SAH levels + 32 halving levels + 1); the 4-wide
/// tree is no deeper.
const MAX_DEPTH: usize = 96;
/// Traversal stack size: each wide level pushes at most three siblings.
const STACK: usize = 3 * MAX_DEPTH + 1;

mod build;

/// A child slot of a [`Node4`]: an interior node, a leaf (a run of primitives) or nothing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C)]
struct Child {
    /// Interior: the child node's index. Leaf: index of the first primitive in
    /// `Bvh::indices`.
    offset: u32,
    /// Leaf: number of primitives (1 to [`MAX_LEAF`]). Interior: 0. Empty slot: `u32::MAX`.
    count: u32,
}

impl Child {
    const EMPTY: Child = Child {
        offset: 0,
        count: u32::MAX,
    };
}

/// One node of the 4-wide tree: the children's boxes by axis and lane (`min[k][i]` is the
/// lower bound of child `i` on axis `k`; an empty slot has the empty box `+inf..-inf`), and
/// the children. 128 bytes.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
struct Node4 {
    min: [[f32; 4]; 3],
    max: [[f32; 4]; 3],
    child: [Child; 4],
}

/// A BVH over primitives given by their boxes, named by `u32` keys (by default their indices).
#[derive(Clone, Debug)]
pub struct Bvh {
    /// The 4-wide nodes, the root first (none for an empty BVH).
    nodes: Vec<Node4>,
    /// The root's slot: interior node 0, or a single leaf.
    root: Option<Child>,
    /// The root's box.
    bounds: Aabb,
    indices: Vec<u32>,
    depth: usize,
}

/// Statistics of a built BVH.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BvhStats {
    /// Primitives.
    pub primitives: usize,
    /// 4-wide nodes.
    pub nodes: usize,
    /// Leaves.
    pub leaves: usize,
    /// Longest root-to-leaf path of the binary tree the wide one was collapsed from (the root
    /// alone is depth 1).
    pub depth: usize,
    /// Bytes of nodes and primitive indices.
    pub bytes: usize,
}

impl BvhStats {
    /// BVH bytes per primitive.
    pub fn bytes_per_primitive(&self) -> f64 {
        self.bytes as f64 / self.primitives.max(1) as f64
    }
}

impl Default for Bvh {
    /// The empty BVH.
    fn default() -> Self {
        Bvh {
            nodes: Vec::new(),
            root: None,
            bounds: Aabb::EMPTY,
            indices: Vec::new(),
            depth: 0,
        }
    }
}

impl Bvh {
    /// Whether the BVH holds no primitive.
    pub fn is_empty(&self) -> bool {
        self.root.is_none()
    }

    /// The root's box (empty for an empty BVH).
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// Bytes of nodes and indices (allocated capacity).
    pub fn memory_bytes(&self) -> usize {
        self.nodes.capacity() * size_of::<Node4>() + self.indices.capacity() * size_of::<u32>()
    }

    /// Node count, depth, memory.
    pub fn stats(&self) -> BvhStats {
        let slots = self.nodes.iter().flat_map(|n| n.child);
        BvhStats {
            primitives: self.indices.len(),
            nodes: self.nodes.len(),
            leaves: slots.filter(|c| c.count > 0 && c.count != u32::MAX).count()
                + usize::from(self.root.is_some_and(|c| c.count > 0)),
            depth: self.depth,
            bytes: self.memory_bytes(),
        }
    }

    /// Visits, nearer boxes first, every primitive whose leaf box the ray meets within
    /// `[tmin, tmax]`: `visit(primitive, tmax)` tests the primitive and returns the new `tmax`
    /// (the best hit's `t` for a nearest-hit query, the same `tmax` to see everything, `-inf`
    /// to stop). Boxes are tested against the closed range, so a primitive whose hit ties with
    /// the best so far is still visited. A ray with a non-finite origin or direction meets
    /// nothing.
    pub fn traverse(
        &self,
        ray: &Ray,
        tmin: f64,
        mut tmax: f64,
        mut visit: impl FnMut(u32, f64) -> f64,
    ) {
        // Also refuses NaN bounds.
        let Some(root) = self.root else {
            return;
        };
        if tmin.is_nan() || tmax.is_nan() || tmin > tmax || !ray.origin.is_finite() {
            return;
        }
        if !ray.dir.is_finite() || ray.dir == DVec3::ZERO {
            return;
        }
        let slab = Slabs::new(ray, tmin);
        if !slab.meets(&self.bounds, tmax) {
            return;
        }
        // Slots still to visit, with the ray's entry into their box.
        let mut stack = [(Child::EMPTY, 0.0f64); STACK];
        let mut sp = 0;
        let mut cur = root;
        loop {
            if cur.count > 0 {
                let s = cur.offset as usize;
                for &p in &self.indices[s..s + cur.count as usize] {
                    tmax = visit(p, tmax);
                    if tmax.is_nan() || tmax < tmin {
                        return;
                    }
                }
            } else {
                let n = &self.nodes[cur.offset as usize];
                let (entry, hit) = slab.entries(n, tmax);
                // The entered children, nearest first; the rest wait on the stack.
                let mut near = [(Child::EMPTY, f64::INFINITY); 4];
                let mut k = 0;
                for (i, (&child, &t)) in n.child.iter().zip(&entry).enumerate() {
                    if hit & (1 << i) != 0 {
                        let mut j = k;
                        while j > 0 && near[j - 1].1 > t {
                            near[j] = near[j - 1];
                            j -= 1;
                        }
                        near[j] = (child, t);
                        k += 1;
                    }
                }
                if k > 0 {
                    for &item in near[1..k].iter().rev() {
                        stack[sp] = item;
                        sp += 1;
                    }
                    cur = near[0].0;
                    continue;
                }
            }
            // The next pushed slot the ray still enters before tmax.
            loop {
                if sp == 0 {
                    return;
                }
                sp -= 1;
                let (c, t) = stack[sp];
                if t <= tmax {
                    cur = c;
                    break;
                }
            }
        }
    }
}

/// A ray prepared for slab tests against a [`Node4`]'s four `f32` boxes, in `f64`.
struct Slabs {
    origin: [f64x4; 3],
    inv: [f64x4; 3],
    origin_scalar: DVec3,
    inv_scalar: DVec3,
    neg: [bool; 3],
    /// Direction components that are zero: the ray stays in that slab or misses it entirely
    /// (`0 * inf` would be NaN in the slab test).
    flat: [bool; 3],
    tmin: f64,
}

/// `[f32; 4]` widened to `f64` lanes.
#[inline]
fn lanes(x: &[f32; 4]) -> f64x4 {
    f64x4::from(x.map(f64::from))
}

impl Slabs {
    fn new(ray: &Ray, tmin: f64) -> Self {
        let d = ray.dir;
        let inv = d.recip();
        Slabs {
            origin: ray.origin.to_array().map(f64x4::splat),
            inv: inv.to_array().map(f64x4::splat),
            origin_scalar: ray.origin,
            inv_scalar: inv,
            neg: [d.x < 0.0, d.y < 0.0, d.z < 0.0],
            flat: [d.x == 0.0, d.y == 0.0, d.z == 0.0],
            tmin,
        }
    }

    /// Where the ray enters each child box within `[tmin, tmax]`, and a bit mask of the
    /// children it meets there.
    ///
    /// On a slab `lo..hi` the ray is inside for `t` between `(lo - o) / d` and `(hi - o) / d`.
    /// No NaN arises: the origin is finite, a zero direction component takes the flat case, and
    /// `(+-inf - o) * inv` (an empty slot's bound) is infinite.
    #[inline]
    fn entries(&self, n: &Node4, tmax: f64) -> ([f64; 4], i32) {
        let mut t0 = f64x4::splat(self.tmin);
        let mut t1 = f64x4::splat(tmax);
        let mut inside = f64x4::splat(0.0).cmp_le(f64x4::splat(0.0));
        for k in 0..3 {
            let (lo, hi) = (lanes(&n.min[k]), lanes(&n.max[k]));
            if self.flat[k] {
                inside = inside & lo.cmp_le(self.origin[k]) & hi.cmp_ge(self.origin[k]);
                continue;
            }
            let (near, far) = if self.neg[k] { (hi, lo) } else { (lo, hi) };
            t0 = t0.fast_max((near - self.origin[k]) * self.inv[k]);
            t1 = t1.fast_min((far - self.origin[k]) * self.inv[k]);
        }
        let hit = (t0.cmp_le(t1) & inside).move_mask();
        (t0.to_array(), hit)
    }

    /// Whether the ray meets the box `b` within `[tmin, tmax]` (the same test, one box).
    fn meets(&self, b: &Aabb, tmax: f64) -> bool {
        let (mut t0, mut t1) = (self.tmin, tmax);
        for k in 0..3 {
            let (o, lo, hi) = (self.origin_scalar[k], b.min[k], b.max[k]);
            if self.flat[k] {
                if o < lo || o > hi {
                    return false;
                }
                continue;
            }
            let (near, far) = if self.neg[k] { (hi, lo) } else { (lo, hi) };
            t0 = t0.max((near - o) * self.inv_scalar[k]);
            t1 = t1.min((far - o) * self.inv_scalar[k]);
        }
        t0 <= t1
    }
}

#[cfg(test)]
mod tests {
    use super::build::{down, up};
    use super::*;
    use crate::accel::{Scene, SceneHit, Scratch, sort_hits};
    use crate::sampling::SampleRng as Rng;
    use crate::scenes::synth::{FiberParams, random_fibers, random_rays};
    use gencyl::Hit;

    #[test]
    fn node_is_128_bytes() {
        assert_eq!(size_of::<Node4>(), 128, "node layout");
    }

    #[test]
    fn outward_rounding_holds_the_value() {
        let mut rng = Rng::from_seed(7);
        for _ in 0..10_000 {
            let x = (rng.uniform() - 0.5) * 10f64.powi((rng.uniform() * 40.0) as i32 - 20);
            assert!((down(x) as f64) <= x && (up(x) as f64) >= x, "{x}");
        }
        assert_eq!(up(1e300), f32::INFINITY, "beyond f32");
        assert_eq!(down(-1e300), f32::NEG_INFINITY, "beyond f32");
    }

    #[test]
    fn empty_and_single() {
        let bvh = Bvh::build(&[]);
        let ray = Ray::new(DVec3::ZERO, DVec3::X);
        bvh.traverse(&ray, 0.0, f64::INFINITY, |_, _| {
            panic!("visited a primitive of an empty BVH")
        });
        let bvh = Bvh::build(&[Aabb {
            min: DVec3::splat(1.0),
            max: DVec3::splat(2.0),
        }]);
        let mut seen = vec![];
        bvh.traverse(
            &Ray::new(DVec3::ZERO, DVec3::ONE),
            0.0,
            f64::INFINITY,
            |p, t| {
                seen.push(p);
                t
            },
        );
        assert_eq!(seen, [0], "the single box is on the ray");
        // A zero direction component with the origin on the box face.
        let mut seen = vec![];
        bvh.traverse(
            &Ray::new(DVec3::new(0.0, 1.0, 1.5), DVec3::X),
            0.0,
            f64::INFINITY,
            |p, t| {
                seen.push(p);
                t
            },
        );
        assert_eq!(seen, [0], "ray along the face");
    }

    #[test]
    fn identical_boxes_and_degenerate_layouts() {
        // Many identical boxes: no split separates them; leaves stay small, depth bounded.
        let b = Aabb {
            min: DVec3::ZERO,
            max: DVec3::ONE,
        };
        let bvh = Bvh::build(&vec![b; 10_000]);
        let s = bvh.stats();
        assert!(s.depth < STACK, "{s:?}");
        let mut n = 0;
        bvh.traverse(
            &Ray::new(DVec3::splat(-1.0), DVec3::ONE),
            0.0,
            f64::INFINITY,
            |_, t| {
                n += 1;
                t
            },
        );
        assert_eq!(n, 10_000, "all visited");
        // Exponentially spaced boxes: SAH would go deep; the depth cap keeps it bounded.
        let boxes: Vec<Aabb> = (0..2000)
            .map(|i| {
                let x = 2f64.powi(-(i % 1000)) * if i < 1000 { 1.0 } else { -1.0 };
                Aabb {
                    min: DVec3::splat(x),
                    max: DVec3::splat(x),
                }
            })
            .collect();
        let bvh = Bvh::build(&boxes);
        assert!(bvh.stats().depth < STACK, "{:?}", bvh.stats());
        // Infinite boxes.
        let inf = Aabb {
            min: DVec3::splat(-1e300),
            max: DVec3::splat(1e300),
        };
        let bvh = Bvh::build(&[inf, b, inf]);
        let mut n = 0;
        bvh.traverse(
            &Ray::new(DVec3::splat(5.0), DVec3::X),
            0.0,
            f64::INFINITY,
            |_, t| {
                n += 1;
                t
            },
        );
        assert_eq!(n, 2, "both infinite boxes met");
    }

    /// The hits of every cylinder, brute force.
    fn brute_all(scene: &Scene, ray: &Ray, tmin: f64) -> Vec<SceneHit> {
        let mut out = vec![];
        let mut scratch: Vec<Hit> = vec![];
        for (i, c) in scene.cylinders().iter().enumerate() {
            scratch.clear();
            c.intersect_all(ray, tmin, f64::INFINITY, &mut scratch);
            out.extend(scratch.iter().map(|&hit| SceneHit {
                hit,
                object: i as u32,
            }));
        }
        sort_hits(&mut out);
        out
    }

    #[test]
    fn same_hits_as_brute_force() {
        let params = FiberParams {
            count: 300,
            elliptical_fraction: 0.05,
            ..FiberParams::default()
        };
        let cyls: Vec<_> = random_fibers(&params, 11)
            .iter()
            .map(|s| s.build().unwrap())
            .collect();
        let scene = Scene::new(cyls);
        let rays = random_rays(1500, 12, &params);
        let mut rng = Rng::from_seed(5);
        let (mut scratch, mut all) = (Scratch::default(), vec![]);
        let mut hits = 0;
        for (r, ray) in rays.iter().enumerate() {
            let tmin = if r % 3 == 0 { rng.uniform() * 2.0 } else { 0.0 };
            // Also rays from inside the fibers' cube, and axis-parallel rays (zero direction
            // components, for the slab test's special case).
            let inside = rng.in_box(DVec3::ZERO, DVec3::ONE);
            let axis = [DVec3::X, DVec3::NEG_Y, DVec3::Z][r % 3];
            let ray = &match r % 4 {
                1 => Ray::new(inside, rng.unit_vector()),
                2 => Ray::new(inside, axis * rng.range(0.1, 10.0)),
                _ => *ray,
            };
            let brute = brute_all(&scene, ray, tmin);
            all.clear();
            scene.all_hits(ray, tmin, f64::INFINITY, &mut all, &mut scratch);
            assert_eq!(all, brute, "all hits of ray {r} {ray:?} tmin {tmin}");
            // The nearest hit: the least (t, object) of the first hits per cylinder.
            let nearest = scene.nearest_hit(ray, tmin, f64::INFINITY, &mut scratch);
            assert_eq!(
                nearest,
                brute.first().copied(),
                "nearest hit of ray {r} {ray:?} tmin {tmin}"
            );
            assert_eq!(
                scene.any_hit(ray, tmin, f64::INFINITY, &mut scratch),
                !brute.is_empty(),
                "any hit of ray {r}"
            );
            hits += brute.len();
        }
        assert!(hits > 500, "the test should see many hits, saw {hits}");
    }

    #[test]
    fn parallel_build_is_deterministic() {
        let params = FiberParams {
            count: 20_000,
            ..FiberParams::default()
        };
        let boxes: Vec<Aabb> = random_fibers(&params, 1)
            .iter()
            .map(|s| {
                let r = s.major_radius[0];
                s.bezier.iter().fold(Aabb::EMPTY, |b, &p| {
                    b.union(Aabb {
                        min: p - r,
                        max: p + r,
                    })
                })
            })
            .collect();
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| Bvh::build(&boxes));
        let two = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap()
            .install(|| Bvh::build(&boxes));
        assert_eq!(one.nodes, two.nodes, "nodes differ between 1 and 2 threads");
        assert_eq!(
            one.indices, two.indices,
            "indices differ between 1 and 2 threads"
        );
    }
}
