//! A bounding volume hierarchy over axis-aligned boxes.
//!
//! Built as pbrt builds it (binned surface area heuristic, [`BINS`] bins on each axis,
//! flattened depth-first into 32-byte nodes, the first child right after its parent); queried
//! as parry queries it: one traversal core, [`Bvh::traverse`], takes a closure that tests a
//! primitive and returns the best `t` so far, which serves nearest-hit (shrink `tmax`),
//! all-hits (keep it) and any-hit (return `-inf` to stop) queries alike.
//!
//! Boxes are stored in `f32`, rounded outward, so each holds its primitives' `f64` boxes; the
//! ray-box test runs in `f64`.

use gencyl::{Aabb, Ray};
use glam::DVec3;

/// Number of SAH bins per axis.
pub const BINS: usize = 16;
/// Most primitives in a leaf.
pub const MAX_LEAF: usize = 8;
/// Traversal stack size: a bound on the depth (48 SAH levels + 32 halving levels + 1).
const STACK: usize = 96;

mod build;

/// One flattened node: 32 bytes.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
struct Node {
    min: [f32; 3],
    max: [f32; 3],
    /// Leaf: index of the first primitive in `Bvh::indices`. Interior: index of the second
    /// child (the first is the next node).
    offset: u32,
    /// Leaf: number of primitives (at least 1). Interior: 0.
    count: u16,
    /// Interior: the split axis, for front-to-back order.
    axis: u8,
    _pad: u8,
}

/// A BVH over primitives given by their boxes, named by `u32` keys (by default their indices).
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    nodes: Vec<Node>,
    indices: Vec<u32>,
    depth: usize,
}

/// Statistics of a built BVH.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BvhStats {
    /// Primitives.
    pub primitives: usize,
    /// All nodes.
    pub nodes: usize,
    /// Leaves.
    pub leaves: usize,
    /// Longest root-to-leaf path (the root alone is depth 1).
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

impl Bvh {
    /// Whether the BVH holds no primitive.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// The root's box (empty for an empty BVH).
    pub fn bounds(&self) -> Aabb {
        self.nodes.first().map_or(Aabb::EMPTY, |n| Aabb {
            min: DVec3::from_array(n.min.map(f64::from)),
            max: DVec3::from_array(n.max.map(f64::from)),
        })
    }

    /// Bytes of nodes and indices (allocated capacity).
    pub fn memory_bytes(&self) -> usize {
        self.nodes.capacity() * size_of::<Node>() + self.indices.capacity() * size_of::<u32>()
    }

    /// Node count, depth, memory.
    pub fn stats(&self) -> BvhStats {
        BvhStats {
            primitives: self.indices.len(),
            nodes: self.nodes.len(),
            leaves: self.nodes.iter().filter(|n| n.count > 0).count(),
            depth: self.depth,
            bytes: self.memory_bytes(),
        }
    }

    /// Visits, nearer boxes first, every primitive whose leaf box the ray meets within
    /// `[tmin, tmax]`: `visit(primitive, tmax)` tests the primitive and returns the new `tmax`
    /// (the best hit's `t` for a nearest-hit query, the same `tmax` to see everything, `-inf`
    /// to stop). Boxes are tested against the closed range, so a primitive whose hit ties with
    /// the best so far is still visited.
    pub fn traverse(
        &self,
        ray: &Ray,
        tmin: f64,
        mut tmax: f64,
        mut visit: impl FnMut(u32, f64) -> f64,
    ) {
        // Also refuses NaN bounds.
        if self.nodes.is_empty() || tmin.is_nan() || tmax.is_nan() || tmin > tmax {
            return;
        }
        let slab = Slabs::new(ray, tmin);
        let Some(_) = slab.entry(&self.nodes[0], tmax) else {
            return;
        };
        // Nodes still to visit, with the ray's entry into their box.
        let mut stack = [(0u32, 0.0f64); STACK];
        let mut sp = 0;
        let mut i = 0usize;
        loop {
            let n = &self.nodes[i];
            if n.count > 0 {
                let s = n.offset as usize;
                for &p in &self.indices[s..s + n.count as usize] {
                    tmax = visit(p, tmax);
                    if tmax.is_nan() || tmax < tmin {
                        return;
                    }
                }
            } else {
                let (a, b) = (i + 1, n.offset as usize);
                match (
                    slab.entry(&self.nodes[a], tmax),
                    slab.entry(&self.nodes[b], tmax),
                ) {
                    (Some(ta), Some(tb)) => {
                        let (near, far, tf) = if !slab.neg[n.axis as usize] {
                            (a, b, tb)
                        } else {
                            (b, a, ta)
                        };
                        stack[sp] = (far as u32, tf);
                        sp += 1;
                        i = near;
                        continue;
                    }
                    (Some(_), None) => {
                        i = a;
                        continue;
                    }
                    (None, Some(_)) => {
                        i = b;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            // The next pushed node the ray still enters before tmax.
            loop {
                if sp == 0 {
                    return;
                }
                sp -= 1;
                let (j, t) = stack[sp];
                if t <= tmax {
                    i = j as usize;
                    break;
                }
            }
        }
    }
}

/// A ray prepared for slab tests against `f32` boxes, in `f64`.
struct Slabs {
    origin: DVec3,
    inv: DVec3,
    neg: [bool; 3],
    /// Direction components that are zero: the ray stays in that slab or misses it entirely
    /// (`0 * inf` would be NaN in the slab test).
    flat: [bool; 3],
    any_flat: bool,
    tmin: f64,
}

impl Slabs {
    fn new(ray: &Ray, tmin: f64) -> Self {
        let d = ray.dir;
        let flat = [d.x == 0.0, d.y == 0.0, d.z == 0.0];
        Slabs {
            origin: ray.origin,
            inv: d.recip(),
            neg: [d.x < 0.0, d.y < 0.0, d.z < 0.0],
            flat,
            any_flat: flat.iter().any(|&f| f),
            tmin,
        }
    }

    /// Where the ray enters the node's box within `[tmin, tmax]`, if it does.
    #[inline]
    fn entry(&self, n: &Node, tmax: f64) -> Option<f64> {
        let mut t0 = self.tmin;
        let mut t1 = tmax;
        for k in 0..3 {
            let (lo, hi) = (n.min[k] as f64, n.max[k] as f64);
            if self.any_flat && self.flat[k] {
                if self.origin[k] < lo || self.origin[k] > hi {
                    return None;
                }
                continue;
            }
            let (a, b) = (
                (lo - self.origin[k]) * self.inv[k],
                (hi - self.origin[k]) * self.inv[k],
            );
            let (a, b) = if self.neg[k] { (b, a) } else { (a, b) };
            // max/min ignore a NaN operand (inf - inf on an infinite box): no clipping.
            t0 = t0.max(a);
            t1 = t1.min(b);
        }
        (t0 <= t1).then_some(t0)
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
    fn node_is_32_bytes() {
        assert_eq!(size_of::<Node>(), 32, "node layout");
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
