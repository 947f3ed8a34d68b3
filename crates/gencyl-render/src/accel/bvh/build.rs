//! Building a [`Bvh`]: binned surface area heuristic as pbrt builds it ([`BINS`] bins, the
//! widest axis or all three for the largest nodes, the exact SAH over sorted primitives in
//! small nodes, halving splits past a depth bound), children built in parallel, the binary
//! tree then collapsed depth-first into 4-wide [`Node4`]s.

use arrayvec::ArrayVec;
use gencyl::Aabb;
use glam::DVec3;
use rayon::prelude::*;

use super::{BINS, Bvh, Child, MAX_DEPTH, MAX_LEAF, Node4};

/// Cost of visiting an interior node, relative to testing one primitive. A cylinder test that
/// gets past its own box check costs far more than a box test, hence the small value.
const TRAVERSAL_COST: f64 = 0.125;
/// Below this depth the SAH chooses splits; deeper, splits halve the primitive count, so the
/// depth (and the traversal stack) stays bounded whatever the input.
const MAX_SAH_DEPTH: usize = 48;
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

/// `x` rounded down to an `f32`.
pub(super) fn down(x: f64) -> f32 {
    let f = x as f32;
    if f as f64 > x { f.next_down() } else { f }
}

/// `x` rounded up to an `f32`.
pub(super) fn up(x: f64) -> f32 {
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
fn interior(bounds: Bounds, a: Built, b: Built) -> Built {
    Built {
        nodes: 1 + a.nodes + b.nodes,
        depth: 1 + a.depth.max(b.depth),
        node: BuildNode::Interior {
            bounds,
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
        n / 2
    };
    let mid = if ext.max_element() <= 0.0 {
        // All centroids coincide: no split separates them; cut the list in half.
        if n <= MAX_LEAF {
            return leaf(bounds, start, n);
        }
        n / 2
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
        if m == 0 || m == n { halve(prims) } else { m }
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
    interior(bounds, a, b)
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
    interior(bounds, a, b)
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

impl BuildNode {
    fn bounds(&self) -> &Bounds {
        match self {
            BuildNode::Leaf { bounds, .. } | BuildNode::Interior { bounds, .. } => bounds,
        }
    }
}

/// `x - c` rounded down to an `f32` (the `f64` difference is within an ulp of the exact one).
fn relative_down(x: f32, c: f64) -> f32 {
    let d = x as f64 - c;
    if d.is_finite() {
        down(d - d.abs() * f64::EPSILON)
    } else {
        d as f32
    }
}

/// `x - c` rounded up to an `f32`.
fn relative_up(x: f32, c: f64) -> f32 {
    let d = x as f64 - c;
    if d.is_finite() {
        up(d + d.abs() * f64::EPSILON)
    } else {
        d as f32
    }
}

/// Collapses the binary subtree `node` into 4-wide nodes appended to `out` (depth first, a
/// parent before its children) and returns its slot. A wide node starts from its binary
/// node's two children and opens the interior child of the largest surface area until it
/// has four (Wald et al. 2008), so the boxes tested together are the large ones a ray most
/// likely enters.
fn collapse(node: BuildNode, center: DVec3, out: &mut Vec<Node4>) -> Child {
    let children = match node {
        BuildNode::Leaf { start, count, .. } => {
            return Child {
                offset: start as u32,
                count: count as u32,
            };
        }
        BuildNode::Interior { children, .. } => children,
    };
    let mut kids: ArrayVec<BuildNode, 4> = ArrayVec::from_iter(*children as [BuildNode; 2]);
    while kids.len() < 4 {
        let widest = kids
            .iter()
            .enumerate()
            .filter(|(_, k)| matches!(k, BuildNode::Interior { .. }))
            .max_by(|a, b| {
                a.1.bounds()
                    .half_area()
                    .total_cmp(&b.1.bounds().half_area())
            })
            .map(|(i, _)| i);
        let Some(i) = widest else {
            break;
        };
        let BuildNode::Interior { children, .. } = kids.remove(i) else {
            unreachable!("chose an interior node")
        };
        let [a, b] = *children;
        kids.insert(i, b);
        kids.insert(i, a);
    }
    let me = out.len();
    out.push(Node4 {
        min: [[f32::INFINITY; 4]; 3],
        max: [[f32::NEG_INFINITY; 4]; 3],
        child: [Child::EMPTY; 4],
    });
    for (i, kid) in kids.into_iter().enumerate() {
        let b = *kid.bounds();
        for k in 0..3 {
            out[me].min[k][i] = relative_down(b.min[k], center[k]);
            out[me].max[k][i] = relative_up(b.max[k], center[k]);
        }
        out[me].child[i] = collapse(kid, center, out);
    }
    Child {
        offset: me as u32,
        count: 0,
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
        Self::build_from(boxes.par_iter().zip(keys).map(|(b, &key)| (*b, key)))
    }

    /// Builds the BVH over `(box, key)` pairs as they come from a parallel iterator (the
    /// boxes are not kept: the build holds one 40-byte record a primitive).
    pub fn build_from(items: impl ParallelIterator<Item = (Aabb, u32)>) -> Bvh {
        let mut prims: Vec<Prim> = items.map(|(b, key)| Prim::new(&b, key)).collect();
        if prims.is_empty() {
            return Bvh::default();
        }
        let built = build(&mut prims, 0, 1);
        assert!(
            built.depth < MAX_DEPTH,
            "BVH depth {} exceeds the traversal stack",
            built.depth
        );
        let b = *built.node.bounds();
        // A binary tree of n nodes has (n - 1) / 2 interior ones; collapsing keeps about a
        // third of them.
        let mut nodes = Vec::with_capacity(built.nodes / 6 + 1);
        let center = DVec3::from_array(std::array::from_fn(|k| {
            0.5 * (fin(b.min[k]) + fin(b.max[k]))
        }));
        let root = collapse(built.node, center, &mut nodes);
        nodes.shrink_to_fit();
        Bvh {
            nodes,
            root: Some(root),
            bounds: Aabb {
                min: DVec3::from_array(b.min.map(f64::from)),
                max: DVec3::from_array(b.max.map(f64::from)),
            },
            center,
            indices: prims.iter().map(|p| p.index).collect(),
            depth: built.depth,
        }
    }
}
