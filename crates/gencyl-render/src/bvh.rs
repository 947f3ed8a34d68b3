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
/// Cost of visiting an interior node, relative to testing one primitive. A cylinder test that
/// gets past its own box check costs far more than a box test, hence the small value.
const TRAVERSAL_COST: f64 = 0.125;
/// Below this depth the SAH chooses splits; deeper, splits halve the primitive count, so the
/// depth (and the traversal stack) stays bounded whatever the input.
const MAX_SAH_DEPTH: usize = 48;
/// Traversal stack size: a bound on the depth (48 SAH levels + 32 halving levels + 1).
const STACK: usize = 96;
/// Nodes with at least this many primitives build their children in parallel.
const PARALLEL_SPLIT: usize = 4096;
/// Nodes with at most this many primitives are split with the exact SAH (sorting them).
const SMALL: usize = 32;
/// Nodes with at least this many primitives try all three axes; smaller ones the widest (as
/// pbrt does): binning one axis is a third of the work, and on 1.6M hair segments it costs
/// no measurable ray speed.
const ALL_AXES: usize = 1 << 18;
/// Nodes with at least this many primitives bin them in parallel.
const PARALLEL_BIN: usize = 1 << 16;

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

/// `x` rounded down to an `f32`.
fn down(x: f64) -> f32 {
    let f = x as f32;
    if f as f64 > x { f.next_down() } else { f }
}

/// `x` rounded up to an `f32`.
fn up(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) < x { f.next_up() } else { f }
}

/// A primitive during the build: its box (rounded outward), its box's centre and its key.
/// 40 bytes.
#[derive(Clone, Copy, Debug)]
struct Prim {
    min: [f32; 3],
    max: [f32; 3],
    center: [f32; 3],
    index: u32,
}

/// A finite stand-in for a bound, for the build's arithmetic (centroids, areas).
#[inline]
fn fin(x: f32) -> f64 {
    x.clamp(-f32::MAX, f32::MAX) as f64
}

impl Prim {
    fn new(b: &Aabb, index: u32) -> Self {
        let (min, max) = (b.min.to_array().map(down), b.max.to_array().map(up));
        let center = std::array::from_fn(|k| (0.5 * (fin(min[k]) + fin(max[k]))) as f32);
        Prim {
            min,
            max,
            center,
            index,
        }
    }

    /// The box's centre on axis `k` (only steers the splits, so `f32` is plenty).
    #[inline]
    fn centroid(&self, k: usize) -> f64 {
        self.center[k] as f64
    }
}

/// A box during the build (in `f32`, as stored).
#[derive(Clone, Copy, Debug)]
struct Bounds {
    min: [f32; 3],
    max: [f32; 3],
}

impl Bounds {
    const EMPTY: Bounds = Bounds {
        min: [f32::INFINITY; 3],
        max: [f32::NEG_INFINITY; 3],
    };

    #[inline]
    fn grow(&mut self, p: &Prim) {
        for k in 0..3 {
            self.min[k] = self.min[k].min(p.min[k]);
            self.max[k] = self.max[k].max(p.max[k]);
        }
    }

    #[inline]
    fn union(mut self, o: &Bounds) -> Bounds {
        for k in 0..3 {
            self.min[k] = self.min[k].min(o.min[k]);
            self.max[k] = self.max[k].max(o.max[k]);
        }
        self
    }

    /// Half the surface area (0 for an empty box).
    fn half_area(&self) -> f64 {
        if self.min[0] > self.max[0] {
            return 0.0;
        }
        let e: [f64; 3] = std::array::from_fn(|k| fin(self.max[k]) - fin(self.min[k]));
        e[0] * e[1] + e[1] * e[2] + e[2] * e[0]
    }
}

/// Everything one pass over a node's primitives learns: the node's box, the centroids' box,
/// and for each axis the bins' counts and boxes (given the centroid range).
#[derive(Clone, Debug)]
struct Binning {
    bounds: Bounds,
    bins: [[(u32, Bounds); BINS]; 3],
}

/// The centroid range `[lo, lo + ext]` of a node on each axis, for binning.
#[derive(Clone, Copy, Debug)]
struct Range3 {
    lo: [f64; 3],
    scale: [f64; 3],
}

impl Range3 {
    fn new(c: &(DVec3, DVec3)) -> Self {
        let ext = c.1 - c.0;
        Range3 {
            lo: c.0.to_array(),
            scale: std::array::from_fn(|k| {
                if ext[k] > 0.0 {
                    BINS as f64 / ext[k]
                } else {
                    0.0
                }
            }),
        }
    }

    #[inline]
    fn bin(&self, p: &Prim, k: usize) -> usize {
        (((p.centroid(k) - self.lo[k]) * self.scale[k]) as usize).min(BINS - 1)
    }
}

/// Bins `prims` on every axis, or (`axis = Some(k)`) on axis `k` only.
fn bin_prims(prims: &[Prim], range: &Range3, axis: Option<usize>) -> Binning {
    let mut b = Binning {
        bounds: Bounds::EMPTY,
        bins: [[(0, Bounds::EMPTY); BINS]; 3],
    };
    let axes = match axis {
        Some(k) => k..k + 1,
        None => 0..3,
    };
    for p in prims {
        b.bounds.grow(p);
        for k in axes.clone() {
            let bin = &mut b.bins[k][range.bin(p, k)];
            bin.0 += 1;
            bin.1.grow(p);
        }
    }
    b
}

fn merge(mut a: Binning, b: Binning) -> Binning {
    a.bounds = a.bounds.union(&b.bounds);
    for k in 0..3 {
        for i in 0..BINS {
            a.bins[k][i].0 += b.bins[k][i].0;
            a.bins[k][i].1 = a.bins[k][i].1.union(&b.bins[k][i].1);
        }
    }
    a
}

fn centroid_bounds(prims: &[Prim]) -> (DVec3, DVec3) {
    let f = |acc: (DVec3, DVec3), p: &Prim| {
        let c = DVec3::new(p.centroid(0), p.centroid(1), p.centroid(2));
        (acc.0.min(c), acc.1.max(c))
    };
    let empty = (DVec3::INFINITY, DVec3::NEG_INFINITY);
    if prims.len() >= PARALLEL_BIN {
        use rayon::prelude::*;
        prims
            .par_chunks(PARALLEL_BIN / 4)
            .map(|c| c.iter().fold(empty, f))
            .reduce(|| empty, |a, b| (a.0.min(b.0), a.1.max(b.1)))
    } else {
        prims.iter().fold(empty, f)
    }
}

/// A node of the build tree, flattened afterwards.
enum BuildNode {
    Leaf {
        bounds: Bounds,
        start: usize,
        count: usize,
    },
    Interior {
        bounds: Bounds,
        axis: usize,
        children: Box<[BuildNode; 2]>,
    },
}

/// A built subtree and its node count and depth.
struct Built {
    node: BuildNode,
    nodes: usize,
    depth: usize,
}

fn leaf(bounds: Bounds, start: usize, count: usize) -> Built {
    Built {
        node: BuildNode::Leaf {
            bounds,
            start,
            count,
        },
        nodes: 1,
        depth: 1,
    }
}

/// An interior node over two built subtrees.
fn interior(bounds: Bounds, axis: usize, a: Built, b: Built) -> Built {
    Built {
        nodes: 1 + a.nodes + b.nodes,
        depth: 1 + a.depth.max(b.depth),
        node: BuildNode::Interior {
            bounds,
            axis,
            children: Box::new([a.node, b.node]),
        },
    }
}

/// Builds the subtree over `prims`, which sit at `start..` in the final index order.
fn build(prims: &mut [Prim], start: usize, depth: usize) -> Built {
    let n = prims.len();
    if n <= SMALL {
        return build_small(prims, start, depth);
    }
    let cb = centroid_bounds(prims);
    let range = Range3::new(&cb);
    let ext = cb.1 - cb.0;
    let widest = ext.max_position();
    // Large nodes try every axis; smaller ones only the widest, as pbrt does.
    let axes = if n >= ALL_AXES { None } else { Some(widest) };
    let binning = if n >= PARALLEL_BIN {
        use rayon::prelude::*;
        prims
            .par_chunks(PARALLEL_BIN / 4)
            .map(|c| bin_prims(c, &range, axes))
            .reduce_with(merge)
            .expect("non-empty")
    } else {
        bin_prims(prims, &range, axes)
    };
    let bounds = binning.bounds;
    let halve = |prims: &mut [Prim]| {
        prims.select_nth_unstable_by(n / 2, |a, b| {
            a.centroid(widest).total_cmp(&b.centroid(widest))
        });
        (n / 2, widest)
    };
    let (mid, axis) = if ext.max_element() <= 0.0 {
        // All centroids coincide: no split separates them; cut the list in half.
        if n <= MAX_LEAF {
            return leaf(bounds, start, n);
        }
        (n / 2, 0)
    } else if depth >= MAX_SAH_DEPTH {
        // Halve along the widest centroid extent, to bound the depth.
        halve(prims)
    } else {
        // SAH: cost of a split after bin i on axis k is
        // TRAVERSAL_COST + (n_left area_left + n_right area_right) / area.
        let area = bounds.half_area();
        let mut best = (f64::INFINITY, 0usize, 0usize);
        for k in 0..3 {
            if ext[k] <= 0.0 || axes.is_some_and(|a| a != k) {
                continue;
            }
            let bins = &binning.bins[k];
            let mut right = [(0u32, 0.0f64); BINS];
            let (mut cnt, mut bx) = (0u32, Bounds::EMPTY);
            for i in (1..BINS).rev() {
                cnt += bins[i].0;
                bx = bx.union(&bins[i].1);
                right[i] = (cnt, bx.half_area());
            }
            let (mut cnt, mut bx) = (0u32, Bounds::EMPTY);
            for i in 0..BINS - 1 {
                cnt += bins[i].0;
                bx = bx.union(&bins[i].1);
                let (rc, ra) = right[i + 1];
                if cnt == 0 || rc == 0 {
                    continue;
                }
                let cost = cnt as f64 * bx.half_area() + rc as f64 * ra;
                if cost < best.0 {
                    best = (cost, k, i);
                }
            }
        }
        let (cost, k, split) = best;
        let cost = TRAVERSAL_COST
            + if area > 0.0 && area.is_finite() {
                cost / area
            } else {
                n as f64
            };
        if n <= MAX_LEAF && n as f64 <= cost {
            return leaf(bounds, start, n);
        }
        let m = if cost.is_finite() {
            partition(prims, |p| range.bin(p, k) <= split)
        } else {
            0
        };
        if m == 0 || m == n {
            halve(prims)
        } else {
            (m, k)
        }
    };
    let (left, right) = prims.split_at_mut(mid);
    let (a, b) = if n >= PARALLEL_SPLIT {
        rayon::join(
            || build(left, start, depth + 1),
            || build(right, start + mid, depth + 1),
        )
    } else {
        (
            build(left, start, depth + 1),
            build(right, start + mid, depth + 1),
        )
    };
    interior(bounds, axis, a, b)
}

/// Builds a small subtree with the exact SAH: primitives sorted by centroid along the widest
/// axis, every split between them priced.
fn build_small(prims: &mut [Prim], start: usize, depth: usize) -> Built {
    let n = prims.len();
    let bounds = prims.iter().fold(Bounds::EMPTY, |mut b, p| {
        b.grow(p);
        b
    });
    if n == 1 {
        return leaf(bounds, start, n);
    }
    let cb = centroid_bounds(prims);
    let ext = cb.1 - cb.0;
    let k = ext.max_position();
    if ext.max_element() <= 0.0 && n <= MAX_LEAF {
        return leaf(bounds, start, n);
    }
    prims.sort_unstable_by(|a, b| a.centroid(k).total_cmp(&b.centroid(k)));
    let mid = if ext.max_element() <= 0.0 || depth >= MAX_SAH_DEPTH {
        n / 2
    } else {
        // right[i]: the half area of prims[i..].
        let mut right = [0.0f64; SMALL + 1];
        let mut bx = Bounds::EMPTY;
        for i in (1..n).rev() {
            bx.grow(&prims[i]);
            right[i] = bx.half_area();
        }
        let mut bx = Bounds::EMPTY;
        let mut best = (f64::INFINITY, n / 2);
        for i in 1..n {
            bx.grow(&prims[i - 1]);
            let cost = i as f64 * bx.half_area() + (n - i) as f64 * right[i];
            if cost < best.0 {
                best = (cost, i);
            }
        }
        let area = bounds.half_area();
        let cost = TRAVERSAL_COST
            + if area > 0.0 && area.is_finite() {
                best.0 / area
            } else {
                n as f64
            };
        if n <= MAX_LEAF && n as f64 <= cost {
            return leaf(bounds, start, n);
        }
        best.1
    };
    let (left, right) = prims.split_at_mut(mid);
    let (a, b) = (
        build_small(left, start, depth + 1),
        build_small(right, start + mid, depth + 1),
    );
    interior(bounds, k, a, b)
}

/// Moves the elements satisfying `pred` to the front; returns how many there are.
fn partition<T>(v: &mut [T], pred: impl Fn(&T) -> bool) -> usize {
    let mut m = 0;
    for i in 0..v.len() {
        if pred(&v[i]) {
            v.swap(i, m);
            m += 1;
        }
    }
    m
}

fn flatten(node: BuildNode, out: &mut Vec<Node>) {
    match node {
        BuildNode::Leaf {
            bounds,
            start,
            count,
        } => out.push(Node {
            min: bounds.min,
            max: bounds.max,
            offset: start as u32,
            count: count as u16,
            axis: 0,
            _pad: 0,
        }),
        BuildNode::Interior {
            bounds,
            axis,
            children,
        } => {
            let me = out.len();
            out.push(Node {
                min: bounds.min,
                max: bounds.max,
                offset: 0,
                count: 0,
                axis: axis as u8,
                _pad: 0,
            });
            let [a, b] = *children;
            flatten(a, out);
            out[me].offset = out.len() as u32;
            flatten(b, out);
        }
    }
}

impl Bvh {
    /// Builds the BVH over primitives `0..boxes.len()` with these boxes, in parallel on the
    /// current rayon pool for large inputs. Boxes must not contain NaN.
    ///
    /// # Panics
    ///
    /// If there are `2^32` or more primitives.
    pub fn build(boxes: &[Aabb]) -> Bvh {
        assert!(
            boxes.len() < u32::MAX as usize,
            "at most 2^32 - 1 primitives"
        );
        let keys: Vec<u32> = (0..boxes.len() as u32).collect();
        Self::build_keyed(boxes, &keys)
    }

    /// Builds the BVH over primitives with these boxes, named by these keys (which
    /// [`Bvh::traverse`] hands to its closure).
    ///
    /// # Panics
    ///
    /// If `boxes` and `keys` differ in length.
    pub fn build_keyed(boxes: &[Aabb], keys: &[u32]) -> Bvh {
        assert_eq!(boxes.len(), keys.len(), "one key per box");
        if boxes.is_empty() {
            return Bvh::default();
        }
        use rayon::prelude::*;
        let mut prims: Vec<Prim> = boxes
            .par_iter()
            .zip(keys)
            .map(|(b, &index)| Prim::new(b, index))
            .collect();
        let built = build(&mut prims, 0, 1);
        assert!(
            built.depth < STACK,
            "BVH depth {} exceeds the traversal stack",
            built.depth
        );
        let mut nodes = Vec::with_capacity(built.nodes);
        flatten(built.node, &mut nodes);
        Bvh {
            nodes,
            indices: prims.iter().map(|p| p.index).collect(),
            depth: built.depth,
        }
    }

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
    use super::*;
    use crate::sampling::SampleRng as Rng;
    use crate::scene::{Scene, SceneHit, Scratch, sort_hits};
    use crate::synth::{FiberParams, random_fibers, random_rays};
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
