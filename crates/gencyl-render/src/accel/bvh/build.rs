//! Building a [`Bvh`]: binned surface area heuristic as pbrt builds it ([`BINS`] bins, the
//! widest axis or all three for the largest nodes, the exact SAH over sorted primitives in
//! small nodes, halving splits past a depth bound), each binary tree then collapsed
//! depth-first into wide [`Node`]s ([`WIDTH`] children). The tree depends on the primitives'
//! boxes and keys only, not on the order they come in: equal centres are ordered by key
//! wherever the build sorts or selects.
//!
//! Large inputs are first grouped into clusters, as HLBVH does (Pantaleoni and Luebke 2010;
//! Garanzha, Pantaleoni and McAllister 2011): each primitive's centroid gets a Morton code on
//! a `2^b` grid over the centroids' box ([`cluster_bits`]), the primitives are sorted by it,
//! and each run of equal codes is a cluster. The top of the tree is built by the binned SAH
//! over the clusters' boxes (a cluster weighs its primitive count), and each cluster's subtree
//! over its own primitives, all clusters in parallel. A full pass over every primitive per
//! tree level is what made the plain build slow on millions of primitives; here only the
//! sort and two passes see them all, and each cluster's levels run within cache.

use arrayvec::ArrayVec;
use bytemuck::Zeroable;
use gencyl::Aabb;
use glam::DVec3;
use rayon::prelude::*;
use wide::f32x4;

use super::{BINS, Bvh, Child, MAX_DEPTH, MAX_LEAF, Node, WIDTH};

/// Cost of visiting an interior node, relative to testing one primitive. It decides only
/// whether a node of at most [`MAX_LEAF`] primitives becomes a leaf (cost `n`) or is split
/// (`TRAVERSAL_COST + (n_l A_l + n_r A_r) / A`), so it trades memory for rays: 0.125 made
/// nearly every leaf one piece; at 0.75 a leaf keeps pieces (of neighbouring cylinders) whose
/// boxes a split would hardly separate, for 9% less memory on the generated 1.6M model (273 ->
/// 248 bytes a segment) and 0.5-0.8% more instructions a ray; 1 took a fifth off its memory
/// but cost its rays 10-15% (each piece of a leaf is another cylinder's cache miss; README,
/// Performance).
const TRAVERSAL_COST: f64 = 0.75;
/// Below this depth the SAH chooses splits; deeper, splits halve the primitive count, so the
/// depth (and the traversal stack) stays bounded whatever the input.
const MAX_SAH_DEPTH: usize = 48;
/// Nodes with at most this many primitives are split with the exact SAH (sorting them).
const SMALL: usize = 12;
/// Nodes with at least this many primitives try all three axes; smaller ones the widest (as
/// pbrt does): binning one axis is a third of the work, and on 1.6M hair segments it costs
/// no measurable ray speed.
const ALL_AXES: usize = 1 << 18;
/// Nodes with at least this many primitives bin them in parallel.
const PARALLEL_BIN: usize = 1 << 16;

/// `x` rounded down to an `f32`: the nearest `f32`, stepped down one place where it lies
/// above `x`, as `f32::next_down` does, without a branch (whether the nearest lies above is as
/// good as random, and the build rounds six bounds a primitive and forty-eight a wide node).
/// The step is one unit of the bits toward zero for a positive value, away from it for a
/// negative one; `+0.0` never lies above `x` (a negative `x` rounds to `-0.0`, which steps to
/// the least negative subnormal), and `+inf` steps to `f32::MAX`.
#[inline]
pub(super) fn down(x: f64) -> f32 {
    let f = x as f32;
    let bits = f.to_bits();
    // -1 for a positive sign bit, +1 for a negative one.
    let step = (bits >> 31 << 1).wrapping_sub(1);
    let above = u32::from(f as f64 > x).wrapping_neg();
    f32::from_bits(bits.wrapping_add(step & above))
}

/// `x` rounded up to an `f32` ([`down`] mirrored: `-0.0` never lies below `x`, `-inf` steps to
/// `-f32::MAX`).
#[inline]
pub(super) fn up(x: f64) -> f32 {
    let f = x as f32;
    let bits = f.to_bits();
    // +1 for a positive sign bit, -1 for a negative one.
    let step = 1u32.wrapping_sub(bits >> 31 << 1);
    let below = u32::from((f as f64) < x).wrapping_neg();
    f32::from_bits(bits.wrapping_add(step & below))
}

/// A primitive during the build: its box (rounded outward), its key, and a code: its
/// cluster's Morton code ([`cluster_bits`]; 0 until the clusters are formed), then, while its
/// cluster's tree is built, its bin on the axis last binned ([`bin_axis`]). 32 bytes (the box's
/// centre is computed where it is needed, [`Prim::mid`]: the sort, the passes over every
/// primitive and the array's first touch move a quarter less than with it stored); all zeros is
/// a valid placeholder, so a large array of them is fresh memory that the threads filling it
/// touch first ([`bytemuck::allocation::try_zeroed_vec`]).
#[derive(Clone, Copy, Debug, Zeroable)]
#[repr(C)]
struct Prim {
    min: [f32; 3],
    max: [f32; 3],
    index: u32,
    code: u32,
}

/// A finite stand-in for a bound: infinities clamped to `±f32::MAX`.
#[inline]
fn finite(x: f32) -> f32 {
    x.clamp(-f32::MAX, f32::MAX)
}

/// [`finite`] in `f64`, for the build's arithmetic (centroids, areas).
#[inline]
fn fin(x: f32) -> f64 {
    finite(x) as f64
}

/// The midpoint of two bounds' finite stand-ins, `lo / 2 + hi / 2` in `f32` (the halves are
/// exact but for subnormals, so this is the midpoint rounded once; no overflow).
#[inline]
fn midpoint(lo: f32, hi: f32) -> f32 {
    0.5 * finite(lo) + 0.5 * finite(hi)
}

impl Prim {
    fn new(b: &Aabb, index: u32) -> Self {
        Prim {
            min: b.min.to_array().map(down),
            max: b.max.to_array().map(up),
            index,
            code: 0,
        }
    }

    /// The box's centre on axis `k` ([`midpoint`]; it only steers the splits, so `f32` is
    /// plenty).
    #[inline]
    fn mid(&self, k: usize) -> f32 {
        midpoint(self.min[k], self.max[k])
    }

    /// [`Self::mid`] in `f64`, for the build's arithmetic.
    #[inline]
    fn centroid(&self, k: usize) -> f64 {
        self.mid(k) as f64
    }

    /// A sort key: the centre on axis `k` (in `f32`'s total order, as `f32::total_cmp`), then
    /// the primitive's key.
    #[inline]
    fn order(&self, k: usize) -> u64 {
        let bits = self.mid(k).to_bits();
        // Negative values count down: flip them all; positive ones go above them.
        let ordered = bits ^ (((bits as i32) >> 31) as u32 | 1 << 31);
        u64::from(ordered) << 32 | u64::from(self.index)
    }

    /// The box's corners and centre as lanes `x, y, z` and a fourth that nothing reads
    /// (the next field, so that each corner is one load; the upper corner's, the key's bits,
    /// is cleared to zero: as a number it would mostly be subnormal, and the centre's sum of
    /// a subnormal took a microcode assist each, which doubled the build's time).
    #[inline]
    fn lanes(&self) -> [f32x4; 3] {
        let [a, b, c] = self.min;
        let [d, e, f] = self.max;
        let lo = f32x4::new([a, b, c, d]);
        // All ones in lanes x, y, z; zero in the fourth.
        const XYZ: f32x4 = f32x4::new([
            f32::from_bits(u32::MAX),
            f32::from_bits(u32::MAX),
            f32::from_bits(u32::MAX),
            0.0,
        ]);
        let hi = f32x4::new([d, e, f, f32::from_bits(self.index)]) & XYZ;
        let (least, most) = (f32x4::splat(-f32::MAX), f32x4::splat(f32::MAX));
        let half = f32x4::splat(0.5);
        // `finite` in lanes.
        let finite = |x: f32x4| x.fast_max(least).fast_min(most);
        [lo, hi, half * finite(lo) + half * finite(hi)]
    }
}

/// A box during the build (in `f32`, as stored), in lanes `x, y, z` (a fourth lane is
/// carried along and never read): one `minps` and one `maxps` grow it.
#[derive(Clone, Copy, Debug)]
struct Bounds {
    min: f32x4,
    max: f32x4,
}

impl Bounds {
    const EMPTY: Bounds = Bounds {
        min: f32x4::new([f32::INFINITY; 4]),
        max: f32x4::new([f32::NEG_INFINITY; 4]),
    };

    /// The box from its corners' lanes.
    #[inline]
    fn of(min: f32x4, max: f32x4) -> Bounds {
        Bounds { min, max }
    }

    #[inline]
    fn grow(&mut self, p: &Prim) {
        let [lo, hi, _] = p.lanes();
        *self = self.union(&Bounds::of(lo, hi));
    }

    /// The smallest box holding both (bounds are never NaN, so the lanes' `minps` and `maxps`
    /// need no NaN handling).
    #[inline]
    fn union(self, o: &Bounds) -> Bounds {
        Bounds {
            min: self.min.fast_min(o.min),
            max: self.max.fast_max(o.max),
        }
    }

    /// The lower corner, `x, y, z`.
    #[inline]
    fn lo(&self) -> [f32; 3] {
        let [x, y, z, _] = self.min.to_array();
        [x, y, z]
    }

    /// The upper corner, `x, y, z`.
    #[inline]
    fn hi(&self) -> [f32; 3] {
        let [x, y, z, _] = self.max.to_array();
        [x, y, z]
    }

    /// The centre, in `f64` (of the finite stand-ins for infinite bounds).
    fn center(&self) -> [f64; 3] {
        let (lo, hi) = (self.lo(), self.hi());
        std::array::from_fn(|k| 0.5 * (fin(lo[k]) + fin(hi[k])))
    }

    /// Half the surface area (0 for an empty box).
    fn half_area(&self) -> f64 {
        let (lo, hi) = (self.lo(), self.hi());
        if lo[0] > hi[0] {
            return 0.0;
        }
        let e: [f64; 3] = std::array::from_fn(|k| fin(hi[k]) - fin(lo[k]));
        e[0] * e[1] + e[1] * e[2] + e[2] * e[0]
    }
}

/// A node's primitives summed up: the box of their boxes and the box of their centres.
#[derive(Clone, Copy, Debug)]
struct Measure {
    bounds: Bounds,
    centers: Bounds,
}

impl Measure {
    const EMPTY: Measure = Measure {
        bounds: Bounds::EMPTY,
        centers: Bounds::EMPTY,
    };

    #[inline]
    fn add(&mut self, p: &Prim) {
        let [lo, hi, mid] = p.lanes();
        self.bounds = self.bounds.union(&Bounds::of(lo, hi));
        self.centers = self.centers.union(&Bounds::of(mid, mid));
    }

    fn union(self, o: &Measure) -> Measure {
        Measure {
            bounds: self.bounds.union(&o.bounds),
            centers: self.centers.union(&o.centers),
        }
    }

    /// The centres' box in `f64`.
    fn center_range(&self) -> (DVec3, DVec3) {
        (
            DVec3::from_array(self.centers.lo().map(f64::from)),
            DVec3::from_array(self.centers.hi().map(f64::from)),
        )
    }
}

/// One pass over `prims` (in parallel for many).
fn measure(prims: &[Prim]) -> Measure {
    let fold = |c: &[Prim]| {
        c.iter().fold(Measure::EMPTY, |mut m, p| {
            m.add(p);
            m
        })
    };
    if prims.len() >= PARALLEL_BIN {
        prims
            .par_chunks(PARALLEL_BIN / 4)
            .map(fold)
            .reduce(|| Measure::EMPTY, |a, b| a.union(&b))
    } else {
        fold(prims)
    }
}

/// The bins of a node on one axis: per bin the primitives' count and [`Measure`] (so a
/// split's two sides are measured without another pass).
type Bins = [(u32, Measure); BINS];

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

/// Bins `prims` on axis `k`, and notes each one's bin in its `code` (which the partition
/// that follows reads; the Morton codes are no longer needed once the build runs).
fn bin_axis(prims: &mut [Prim], range: &Range3, k: usize) -> Bins {
    let mut b = [(0, Measure::EMPTY); BINS];
    for p in prims {
        let i = range.bin(p, k);
        p.code = i as u32;
        b[i].0 += 1;
        b[i].1.add(p);
    }
    b
}

/// The bins of two parts of a node's primitives, together.
fn merge(mut a: Bins, b: Bins) -> Bins {
    for (x, y) in a.iter_mut().zip(&b) {
        x.0 += y.0;
        x.1 = x.1.union(&y.1);
    }
    a
}

/// The SAH's best split of binned primitives (the count and box of each bin, in order): the
/// bin `i` after which `n_left area_left + n_right area_right` is least, and that cost; `None`
/// if every split leaves a side empty.
fn best_split(bins: &[(usize, Bounds); BINS]) -> Option<(f64, usize)> {
    // right[i]: the count and half area of bins i..
    let mut right = [(0usize, 0.0f64); BINS];
    let (mut cnt, mut bx) = (0, Bounds::EMPTY);
    for i in (1..BINS).rev() {
        cnt += bins[i].0;
        bx = bx.union(&bins[i].1);
        right[i] = (cnt, bx.half_area());
    }
    let mut best = None;
    let (mut cnt, mut bx) = (0, Bounds::EMPTY);
    for i in 0..BINS - 1 {
        cnt += bins[i].0;
        bx = bx.union(&bins[i].1);
        let (rc, ra) = right[i + 1];
        if cnt == 0 || rc == 0 {
            continue;
        }
        let cost = cnt as f64 * bx.half_area() + rc as f64 * ra;
        if best.is_none_or(|(c, _)| cost < c) {
            best = Some((cost, i));
        }
    }
    best
}

/// A node of a binary build tree, in an arena (a `Vec`, reused from tree to tree), collapsed
/// into [`Node`]s afterwards.
#[derive(Clone, Copy, Debug)]
struct BinNode {
    bounds: Bounds,
    kind: Kind,
}

#[derive(Clone, Copy, Debug)]
enum Kind {
    /// A leaf, and the slot it becomes in its parent [`Node`].
    Leaf(Child),
    /// An interior node over the arena's nodes `a` and `b`.
    Interior(u32, u32),
}

/// A built subtree: its root in the arena and its depth.
#[derive(Clone, Copy, Debug)]
struct Built {
    node: u32,
    depth: usize,
}

fn push(arena: &mut Vec<BinNode>, bounds: Bounds, kind: Kind) -> u32 {
    arena.push(BinNode { bounds, kind });
    (arena.len() - 1) as u32
}

/// A leaf over the primitives `start..start + count` of the final order.
fn leaf(arena: &mut Vec<BinNode>, bounds: Bounds, start: usize, count: usize) -> Built {
    let slot = Child {
        offset: start as u32,
        count: count as u32,
    };
    Built {
        node: push(arena, bounds, Kind::Leaf(slot)),
        depth: 1,
    }
}

/// An interior node over two built subtrees.
fn interior(arena: &mut Vec<BinNode>, bounds: Bounds, a: Built, b: Built) -> Built {
    Built {
        node: push(arena, bounds, Kind::Interior(a.node, b.node)),
        depth: 1 + a.depth.max(b.depth),
    }
}

/// Builds the subtree over `prims`, which sit at `start..` in the final index order, into
/// `arena`; `depth` is the subtree root's depth in the whole tree (the root is 1).
fn build(
    prims: &mut [Prim],
    start: usize,
    depth: usize,
    node: Measure,
    arena: &mut Vec<BinNode>,
) -> Built {
    let n = prims.len();
    if n <= SMALL {
        return build_small(prims, start, depth, arena);
    }
    let bounds = node.bounds;
    let cb = node.center_range();
    let range = Range3::new(&cb);
    let ext = cb.1 - cb.0;
    let widest = ext.max_position();
    // Halves along the widest centroid extent; the halves are measured by a pass each.
    let halve = |prims: &mut [Prim]| {
        prims.select_nth_unstable_by(n / 2, |a, b| a.order(widest).cmp(&b.order(widest)));
        let (l, r) = prims.split_at(n / 2);
        (n / 2, measure(l), measure(r))
    };
    let (mid, left, right) = if ext.max_element() <= 0.0 {
        // All centroids coincide: no split separates them; cut the list (in key order) in half.
        prims.sort_unstable_by_key(|p| p.index);
        if n <= MAX_LEAF {
            return leaf(arena, bounds, start, n);
        }
        let (l, r) = prims.split_at(n / 2);
        (n / 2, measure(l), measure(r))
    } else if depth >= MAX_SAH_DEPTH {
        // Halve, to bound the depth.
        halve(prims)
    } else {
        // Large nodes try every axis; smaller ones only the widest, as pbrt does. The axis
        // binned last leaves its bins in the primitives' codes.
        let every = [0, 1, 2];
        let axes: &[usize] = if n >= ALL_AXES {
            &every
        } else {
            std::slice::from_ref(&widest)
        };
        let area = bounds.half_area();
        // SAH: cost of a split after bin i on axis k is
        // TRAVERSAL_COST + (n_left area_left + n_right area_right) / area.
        let mut best = (f64::INFINITY, 0usize, 0usize, [(0, Measure::EMPTY); BINS]);
        for &k in axes.iter().filter(|&&k| ext[k] > 0.0) {
            let bins = if n >= PARALLEL_BIN {
                prims
                    .par_chunks_mut(PARALLEL_BIN / 4)
                    .map(|c| bin_axis(c, &range, k))
                    .reduce_with(merge)
                    .expect("non-empty")
            } else {
                bin_axis(prims, &range, k)
            };
            let boxes = std::array::from_fn(|i| (bins[i].0 as usize, bins[i].1.bounds));
            if let Some((cost, i)) = best_split(&boxes)
                && cost < best.0
            {
                best = (cost, k, i, bins);
            }
        }
        let last = axes.iter().rev().find(|&&k| ext[k] > 0.0).copied();
        let (cost, k, split, bins) = best;
        let cost = TRAVERSAL_COST
            + if area > 0.0 && area.is_finite() {
                cost / area
            } else {
                n as f64
            };
        if n <= MAX_LEAF && n as f64 <= cost {
            return leaf(arena, bounds, start, n);
        }
        let m = if !cost.is_finite() {
            0
        } else if last == Some(k) {
            partition(prims, |p| p.code as usize <= split)
        } else {
            partition(prims, |p| range.bin(p, k) <= split)
        };
        if m == 0 || m == n {
            halve(prims)
        } else {
            let side = |bins: &[(u32, Measure)]| {
                bins.iter().fold(Measure::EMPTY, |acc, (_, m)| acc.union(m))
            };
            (m, side(&bins[..=split]), side(&bins[split + 1..]))
        }
    };
    let (l, r) = prims.split_at_mut(mid);
    let a = build(l, start, depth + 1, left, arena);
    let b = build(r, start + mid, depth + 1, right, arena);
    interior(arena, bounds, a, b)
}

fn build_small(prims: &mut [Prim], start: usize, depth: usize, arena: &mut Vec<BinNode>) -> Built {
    let n = prims.len();
    let node = measure(prims);
    let bounds = node.bounds;
    if n == 1 {
        return leaf(arena, bounds, start, n);
    }
    let cb = node.center_range();
    let ext = cb.1 - cb.0;
    let k = ext.max_position();
    // By key among equal centres, so that the tree does not depend on the order given.
    sort_small(prims, k);
    if ext.max_element() <= 0.0 && n <= MAX_LEAF {
        return leaf(arena, bounds, start, n);
    }
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
            return leaf(arena, bounds, start, n);
        }
        best.1
    };
    let (left, right) = prims.split_at_mut(mid);
    let a = build_small(left, start, depth + 1, arena);
    let b = build_small(right, start + mid, depth + 1, arena);
    interior(arena, bounds, a, b)
}

/// Sorts at most [`SMALL`] primitives by [`Prim::order`] on axis `k`: the keys are computed
/// once and sorted with their positions (16 bytes each), and the records moved once, where
/// sorting the 32-byte records computed two keys a comparison and moved records at each step.
fn sort_small(prims: &mut [Prim], k: usize) {
    let n = prims.len();
    debug_assert!(n <= SMALL);
    let mut keys = [(0u64, 0usize); SMALL];
    for (slot, (i, p)) in keys.iter_mut().zip(prims.iter().enumerate()) {
        *slot = (p.order(k), i);
    }
    let keys = &mut keys[..n];
    keys.sort_unstable_by_key(|&(key, _)| key);
    if keys.iter().enumerate().all(|(i, &(_, at))| at == i) {
        return;
    }
    let mut copy = [Prim::zeroed(); SMALL];
    copy[..n].copy_from_slice(prims);
    for (p, &(_, at)) in prims.iter_mut().zip(keys.iter()) {
        *p = copy[at];
    }
}

/// Moves the items that satisfy `pred` before the others and returns their count: scans from
/// both ends and swaps only the pairs out of place (Hoare), a quarter of the items on random
/// input where moving every match forward swapped half of them, each a record (then 44 bytes) through
/// the stack. The order within each side is unspecified: the trees do not depend on it where
/// the keys are distinct, as the scenes' are (a node's bins are sums and unions, and leaves
/// come from [`build_small`], which sorts by centre and key; with repeated keys and equal
/// centres the tree depends on their input order, as it did before).
fn partition<T>(v: &mut [T], pred: impl Fn(&T) -> bool) -> usize {
    let (mut lo, mut hi) = (0, v.len());
    loop {
        while lo < hi && pred(&v[lo]) {
            lo += 1;
        }
        while lo < hi && !pred(&v[hi - 1]) {
            hi -= 1;
        }
        if lo >= hi {
            return lo;
        }
        v.swap(lo, hi - 1);
        lo += 1;
        hi -= 1;
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
/// Collapses the binary subtree `node` of `arena` into wide nodes appended to `out` (depth
/// first, a parent before its children) and returns its slot.
///
/// Which binary interior nodes become wide nodes is chosen to minimise the sum of their box
/// areas, the SAH's traversal cost of the wide tree (its leaves, and so their cost, are the
/// binary tree's whatever the choice), by dynamic programming over the binary tree as Ylitie,
/// Karras and Laine (2017) do for 8-wide trees: with `S(n, k)` the least cost of holding the
/// subtree `n` in at most `k` slots of a wide node,
/// `S(leaf, k) = 0`, `W(n) = A(n) + min_j S(a, j) + S(b, WIDTH - j)` (`n` a wide node, one
/// slot),
/// `S(n, 1) = W(n)` and `S(n, k) = min(W(n), min_j S(a, j) + S(b, k - j))` (`n` dissolved
/// into its children's slots). It fills the nodes' slots wherever the tree allows (a wide node
/// whose children fit in its parent's free slots costs its area for nothing), where opening
/// the largest child first (Wald et al. 2008) left a third of the ponytail's slots empty.
/// Ties go to fewer nodes (of sums as rounded: see [`best_slot_split`]).
///
/// `plan` is a buffer, reused from call to call.
fn collapse(
    arena: &[BinNode],
    node: u32,
    center: DVec3,
    plan: &mut CollapsePlan,
    out: &mut Vec<Node>,
) -> Child {
    if let Kind::Leaf(slot) = arena[node as usize].kind {
        return slot;
    }
    plan.make(arena, node);
    out.reserve(plan.wide_nodes(node));
    plan.emit(arena, node, center, out)
}

/// A cost of [`collapse`]'s dynamic program: the wide nodes' total area, then their count.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Cost(f64, u32);

impl Cost {
    /// Whether `self` is less: by area, then by count (areas are finite).
    #[inline]
    fn less(self, o: Cost) -> bool {
        self.0 < o.0 || (self.0 == o.0 && self.1 < o.1)
    }
}

impl std::ops::Add for Cost {
    type Output = Cost;
    fn add(self, o: Cost) -> Cost {
        Cost(self.0 + o.0, self.1 + o.1)
    }
}

/// [`collapse`]'s choices for every binary interior node of a subtree, indexed by arena
/// position less `first` (children come before their parents in the arena), and the dynamic
/// program's working arrays.
#[derive(Default)]
struct CollapsePlan {
    /// `spread[n][k - 1]`: how the subtree `n` fills at most `k` slots of its parent: `0` as
    /// one wide node, `j` its first child in at most `j` slots and its second in `k - j`.
    /// `spread[n][WIDTH - 1]` is never `0` (a wide node costs its area more than its children
    /// in its `WIDTH` slots), and is how the wide node `n` fills its own slots.
    spread: Vec<[u8; WIDTH]>,
    /// The subtree's lowest arena position.
    first: usize,
    /// `cost[n][k - 1] = S(n, k)`; zero for leaves.
    cost: Vec<[Cost; WIDTH]>,
    /// Leaves under each node, counted up to `WIDTH + 1` ("more than fit in one node").
    leaves: Vec<u8>,
}

/// For a binary node whose children `a` and `b` hold `la` and `lb` leaves (counted up to
/// `WIDTH + 1`) and cost `S(a, j) = ca[j - 1]`, `S(b, j) = cb[j - 1]`: the least
/// `S(a, j) + S(b, k - j)` over `j` and the first `j` that gives it.
///
/// Only `j <= la` is tried: a subtree of `L <= WIDTH` leaves costs nothing in `L` or more
/// slots (all its leaves fit), and `S` never grows with more slots, so a `j > la` costs
/// `S(b, k - j) >= S(b, k - la)`, no less than `j = la` before it. Where `k >= la + lb` the
/// answer is `j = la` at no cost. (That `S` never grows holds in exact arithmetic. Rounded
/// sums of areas `2^46` or more times apart can hide an area difference and let the node
/// count decide, so that `S` grows by a node, and the plan then differs from trying every
/// `j`: a valid tree with one more node. The review built such a tree by hand; 2 million
/// random ones had none.)
#[inline]
fn best_slot_split(
    ca: &[Cost; WIDTH],
    cb: &[Cost; WIDTH],
    la: usize,
    lb: usize,
    k: usize,
) -> (Cost, u8) {
    if k >= la + lb {
        return (Cost(0.0, 0), la as u8);
    }
    (2..k.min(la + 1)).fold((ca[0] + cb[k - 2], 1), |m, j| {
        let c = ca[j - 1] + cb[k - j - 1];
        if c.less(m.0) { (c, j as u8) } else { m }
    })
}

impl CollapsePlan {
    /// Plans the collapse of the subtree `root`.
    fn make(&mut self, arena: &[BinNode], root: u32) {
        // The subtree's nodes lie between its leftmost leaf (pushed first) and its root
        // (pushed last).
        let mut first = root;
        while let Kind::Interior(a, _) = arena[first as usize].kind {
            first = a;
        }
        let first = first as usize;
        let len = root as usize + 1 - first;
        self.first = first;
        let CollapsePlan {
            spread,
            cost,
            leaves,
            ..
        } = self;
        leaves.clear();
        leaves.resize(len, 1);
        spread.clear();
        spread.resize(len, [0; WIDTH]);
        cost.clear();
        cost.resize(len, [Cost(0.0, 0); WIDTH]);
        for (me, node) in arena[first..=root as usize].iter().enumerate() {
            let Kind::Interior(a, b) = node.kind else {
                continue;
            };
            let (a, b) = (a as usize - first, b as usize - first);
            let (la, lb) = (usize::from(leaves[a]), usize::from(leaves[b]));
            let (ca, cb) = (&cost[a], &cost[b]);
            let (split, j) = best_slot_split(ca, cb, la, lb, WIDTH);
            let wide = Cost(node.bounds.half_area(), 1) + split;
            // From `k = la + lb` on (all the leaves fit) the cost is nothing, with `j = la`;
            // in `WIDTH` slots it is the split itself (`wide` is that and its area more).
            let mut costs = [Cost(0.0, 0); WIDTH];
            let mut spreads = [la as u8; WIDTH];
            (costs[0], spreads[0]) = (wide, 0);
            (costs[WIDTH - 1], spreads[WIDTH - 1]) = (split, j);
            for k in 2..(la + lb).min(WIDTH) {
                let (c, j) = best_slot_split(ca, cb, la, lb, k);
                (costs[k - 1], spreads[k - 1]) = if wide.less(c) { (wide, 0) } else { (c, j) };
            }
            (cost[me], spread[me]) = (costs, spreads);
            leaves[me] = (la + lb).min(WIDTH + 1) as u8;
        }
    }

    /// The number of wide nodes the plan makes of the subtree `root` (an interior node).
    fn wide_nodes(&self, root: u32) -> usize {
        self.cost[root as usize - self.first][0].1 as usize
    }

    /// The slots the subtree `n` takes in at most `k` slots of its parent, appended to `out`:
    /// leaves, and the interior nodes that become wide nodes.
    fn slots(&self, arena: &[BinNode], n: u32, k: usize, out: &mut ArrayVec<u32, WIDTH>) {
        let Kind::Interior(a, b) = arena[n as usize].kind else {
            out.push(n);
            return;
        };
        match self.spread[n as usize - self.first][k - 1] as usize {
            0 => out.push(n),
            j => {
                self.slots(arena, a, j, out);
                self.slots(arena, b, k - j, out);
            }
        }
    }

    /// Writes the wide node of the binary interior node `n` and those below it, depth first.
    fn emit(&self, arena: &[BinNode], n: u32, center: DVec3, out: &mut Vec<Node>) -> Child {
        let Kind::Interior(a, b) = arena[n as usize].kind else {
            unreachable!("a wide node is an interior node");
        };
        let j = self.spread[n as usize - self.first][WIDTH - 1] as usize;
        let mut kids: ArrayVec<u32, WIDTH> = ArrayVec::new();
        self.slots(arena, a, j, &mut kids);
        self.slots(arena, b, WIDTH - j, &mut kids);
        let me = out.len();
        out.push(Node {
            planes: [[[f32::INFINITY; WIDTH]; 3]; 2],
            child: [Child::EMPTY; WIDTH],
        });
        for (i, &kid) in kids.iter().enumerate() {
            let b = arena[kid as usize].bounds;
            let (lo, hi) = (b.lo(), b.hi());
            for k in 0..3 {
                out[me].planes[0][k][i] = relative_down(lo[k], center[k]);
                out[me].planes[1][k][i] = relative_up(hi[k], center[k]);
            }
            out[me].child[i] = match arena[kid as usize].kind {
                Kind::Leaf(slot) => slot,
                Kind::Interior(..) => self.emit(arena, kid, center, out),
            };
        }
        Child {
            offset: me as u32,
            count: 0,
        }
    }
}

/// For the tests: the binary tree of the direct build over `boxes` (primitive `i` with the
/// key `i`): its arena and its root.
#[cfg(test)]
fn binary_tree(boxes: &[Aabb]) -> (Vec<BinNode>, u32) {
    let mut prims: Vec<Prim> = boxes
        .iter()
        .zip(0..)
        .map(|(b, i)| Prim::new(b, i))
        .collect();
    let mut arena = Vec::new();
    let all = measure(&prims);
    let root = build(&mut prims, 0, 1, all, &mut arena).node;
    (arena, root)
}

/// For a test of [`collapse`]: the binary tree of the direct build over `boxes` collapsed by
/// the dynamic program and by the rule it replaced (open the interior child of the largest
/// area until there are [`WIDTH`], Wald et al. 2008), each as (wide nodes, their total area).
#[cfg(test)]
pub(super) fn collapse_both_ways(boxes: &[Aabb]) -> [(usize, f64); 2] {
    fn greedy(arena: &[BinNode], node: u32, nodes: &mut Vec<u32>) {
        let Kind::Interior(a, b) = arena[node as usize].kind else {
            return;
        };
        nodes.push(node);
        let mut kids: ArrayVec<u32, WIDTH> = ArrayVec::from_iter([a, b]);
        while kids.len() < WIDTH {
            let widest = kids
                .iter()
                .enumerate()
                .filter_map(|(i, &k)| match arena[k as usize].kind {
                    Kind::Interior(a, b) => Some((i, a, b, arena[k as usize].bounds.half_area())),
                    Kind::Leaf(_) => None,
                })
                .max_by(|x, y| x.3.total_cmp(&y.3));
            let Some((i, a, b, _)) = widest else {
                break;
            };
            kids[i] = a;
            kids.insert(i + 1, b);
        }
        for kid in kids {
            greedy(arena, kid, nodes);
        }
    }
    let (arena, root) = binary_tree(boxes);
    let mut out = Vec::new();
    collapse(
        &arena,
        root,
        DVec3::ZERO,
        &mut CollapsePlan::default(),
        &mut out,
    );
    let area = |n: &Node| {
        let b = (0..WIDTH)
            .filter(|&i| n.child[i].count != u32::MAX)
            .fold(Bounds::EMPTY, |b, i| {
                let lane = |c: &[[f32; WIDTH]; 3]| f32x4::new([c[0][i], c[1][i], c[2][i], 0.0]);
                b.union(&Bounds::of(lane(n.min()), lane(n.max())))
            });
        b.half_area()
    };
    let mut wide = Vec::new();
    greedy(&arena, root, &mut wide);
    [
        (out.len(), out.iter().map(area).sum()),
        (
            wide.len(),
            wide.iter()
                .map(|&n| arena[n as usize].bounds.half_area())
                .sum(),
        ),
    ]
}

/// Inputs with at least this many primitives are built through clusters (the module's
/// docs); smaller ones directly.
pub(super) const CLUSTER_MIN: usize = 1 << 15;
/// About this many primitives per cluster where the primitives fill their box evenly (hair,
/// which fills a shell, gives clusters a few times larger).
const CLUSTER_SIZE: usize = 256;
/// Below this depth the top tree (over clusters) splits by the SAH, past it where half the
/// primitives lie on each side, so that top and cluster trees together stay within
/// [`MAX_DEPTH`]: SAH levels end at this depth in a top tree and at [`MAX_SAH_DEPTH`] in any
/// tree, and every level past them halves the primitives (or leaves one cluster), at most 32.
const TOP_SAH_DEPTH: usize = 24;
/// Marks a top-tree slot that stands for a cluster until the clusters' nodes are placed.
const CLUSTER_SLOT: u32 = u32::MAX - 1;
/// Clusters built between two appends to the final node array.
const CLUSTER_BATCH: usize = 64;

/// Grid bits per axis for `n` primitives: `8^b` cells, about `n / CLUSTER_SIZE`, at most 10
/// (a 30-bit Morton code).
fn cluster_bits(n: usize) -> u32 {
    (0..10)
        .find(|&b| (CLUSTER_SIZE << (3 * (b + 1))) > n)
        .unwrap_or(10)
}

/// Bits `0..10` of `x` spread to bits `0, 3, 6, ...` (Morton interleaving).
fn spread(x: u32) -> u32 {
    let mut x = x & 0x3ff;
    x = (x | x << 16) & 0x0300_00ff;
    x = (x | x << 8) & 0x0300_f00f;
    x = (x | x << 4) & 0x030c_30c3;
    (x | x << 2) & 0x0924_9249
}

/// A cluster: a run of primitives with one Morton code, and the box of their boxes.
#[derive(Clone, Copy, Debug)]
struct Cluster {
    id: u32,
    count: usize,
    bounds: Bounds,
    center: [f64; 3],
}

/// Builds the top tree over `clusters` into `arena` by the binned SAH on their boxes'
/// centres (a cluster weighs its primitive count), down to one cluster a leaf (its slot marked
/// [`CLUSTER_SLOT`], `offset` its id); records each cluster's depth in `depths`. Past
/// [`TOP_SAH_DEPTH`], or where no SAH split separates them, the clusters are split where half
/// the primitives lie on each side, so these levels halve the primitives (or leave a single
/// cluster).
fn build_top(
    clusters: &mut [Cluster],
    depth: usize,
    depths: &mut [u32],
    arena: &mut Vec<BinNode>,
) -> Built {
    let bounds = clusters
        .iter()
        .fold(Bounds::EMPTY, |b, c| b.union(&c.bounds));
    if let [c] = clusters {
        depths[c.id as usize] = depth as u32;
        let slot = Child {
            offset: c.id,
            count: CLUSTER_SLOT,
        };
        return Built {
            node: push(arena, bounds, Kind::Leaf(slot)),
            depth: 1,
        };
    }
    let n = clusters.len();
    let (lo, hi) = clusters
        .iter()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), c| {
            let p = DVec3::from_array(c.center);
            (lo.min(p), hi.max(p))
        });
    let range = Range3::new(&(lo, hi));
    let ext = hi - lo;
    let bin = |c: &Cluster, k: usize| {
        (((c.center[k] - range.lo[k]) * range.scale[k]) as usize).min(BINS - 1)
    };
    let mut best = (f64::INFINITY, 0usize, 0usize);
    if depth < TOP_SAH_DEPTH {
        for k in (0..3).filter(|&k| ext[k] > 0.0) {
            let mut bins = [(0usize, Bounds::EMPTY); BINS];
            for c in clusters.iter() {
                let b = &mut bins[bin(c, k)];
                b.0 += c.count;
                b.1 = b.1.union(&c.bounds);
            }
            if let Some((cost, i)) = best_split(&bins)
                && cost < best.0
            {
                best = (cost, k, i);
            }
        }
    }
    let mut mid = if best.0.is_finite() {
        partition(clusters, |c| bin(c, best.1) <= best.2)
    } else {
        0
    };
    if mid == 0 || mid == n {
        // Along the widest extent of the centres, where the running count reaches half.
        let k = ext.max_position();
        clusters.sort_unstable_by(|a, b| a.center[k].total_cmp(&b.center[k]).then(a.id.cmp(&b.id)));
        let half = clusters.iter().map(|c| c.count).sum::<usize>() / 2;
        let mut seen = 0;
        mid = clusters
            .iter()
            .position(|c| {
                seen += c.count;
                seen >= half
            })
            .map_or(n / 2, |i| i + 1)
            .clamp(1, n - 1);
    }
    let (left, right) = clusters.split_at_mut(mid);
    let a = build_top(left, depth + 1, depths, arena);
    let b = build_top(right, depth + 1, depths, arena);
    interior(arena, bounds, a, b)
}

/// What one thread reuses from tree to tree: the binary arena and the collapse's plan.
#[derive(Default)]
struct Scratch {
    arena: Vec<BinNode>,
    plan: CollapsePlan,
}

/// Wide nodes over `prims`, numbered from 0 (the root, if interior), the root's slot, and
/// the binary depth of the whole tree below the root's depth `depth`.
type Subtree = (Vec<Node>, Child, usize);

/// The subtree over `prims` (at `start..` in the final order, its root at depth `depth`),
/// built directly.
fn build_direct(
    prims: &mut [Prim],
    start: usize,
    depth: usize,
    center: DVec3,
    scratch: &mut Scratch,
) -> Subtree {
    scratch.arena.clear();
    let built = build(prims, start, depth, measure(prims), &mut scratch.arena);
    // Sized by the plan: one allocation, no copy.
    let mut nodes = Vec::new();
    let root = collapse(
        &scratch.arena,
        built.node,
        center,
        &mut scratch.plan,
        &mut nodes,
    );
    (nodes, root, depth - 1 + built.depth)
}

/// The subtree over `prims` (at `start..` in the final order, its root at depth `depth`),
/// through clusters (the module's docs) while there are at least `min` primitives
/// and the centres are not all in one cell; the primitives end in their final order.
fn build_clustered(
    prims: &mut [Prim],
    start: usize,
    depth: usize,
    center: DVec3,
    min: usize,
) -> Subtree {
    let n = prims.len();
    if n < min {
        return build_direct(prims, start, depth, center, &mut Scratch::default());
    }
    let centers = measure(prims).center_range();
    let bits = cluster_bits(n);
    let (lo, ext) = (centers.0, centers.1 - centers.0);
    // Cells per unit length on each axis (none where the centres do not spread), multiplied
    // rather than divided by in the pass over every primitive.
    let cells = (1u32 << bits) as f64;
    let scale = ext
        .to_array()
        .map(|e| if e > 0.0 { cells / e } else { 0.0 });
    let cell =
        |p: &Prim, k: usize| (((p.centroid(k) - lo[k]) * scale[k]) as u32).min((1 << bits) - 1);
    prims.par_iter_mut().for_each(|p| {
        p.code = spread(cell(p, 0)) << 2 | spread(cell(p, 1)) << 1 | spread(cell(p, 2));
    });
    // By code alone: a cluster's tree does not depend on the order of its primitives (its
    // splits and leaves are fixed by their boxes and keys).
    prims.par_sort_unstable_by_key(|p| p.code);
    let mut starts = vec![0];
    starts.extend((1..n).filter(|&i| prims[i].code != prims[i - 1].code));
    starts.push(n);
    if starts.len() == 2 {
        // One cell holds every centre: no grid separates them.
        return build_direct(prims, start, depth, center, &mut Scratch::default());
    }
    let mut clusters: Vec<Cluster> = starts
        .par_windows(2)
        .enumerate()
        .map(|(id, w)| {
            let bounds = prims[w[0]..w[1]].iter().fold(Bounds::EMPTY, |mut b, p| {
                b.grow(p);
                b
            });
            Cluster {
                id: id as u32,
                count: w[1] - w[0],
                bounds,
                center: bounds.center(),
            }
        })
        .collect();
    let mut depths = vec![0u32; clusters.len()];
    let mut top_arena = Vec::new();
    let top = build_top(&mut clusters, depth, &mut depths, &mut top_arena);
    drop(clusters);
    // Each cluster's own tree, numbered from 0; large clusters through clusters again.
    let mut slices = Vec::with_capacity(depths.len());
    let mut rest = prims;
    for (w, &depth) in starts.windows(2).zip(&depths) {
        let (s, r) = rest.split_at_mut(w[1] - w[0]);
        slices.push((start + w[0], s, depth as usize));
        rest = r;
    }
    // The top's nodes first (the root is node 0), then each cluster's after them, a batch
    // of clusters at a time, so that the clusters' own buffers are reused from batch to batch
    // and only the final array is fresh memory. It never needs more than `n - 1` nodes (one
    // per binary interior node at most); what is reserved and not written is never touched.
    let mut nodes = Vec::with_capacity(n);
    let root = collapse(
        &top_arena,
        top.node,
        center,
        &mut CollapsePlan::default(),
        &mut nodes,
    );
    let tops = nodes.len();
    let mut roots = Vec::with_capacity(depths.len());
    let mut deepest = depth;
    for batch in slices.chunks_mut(CLUSTER_BATCH) {
        let subtrees: Vec<Subtree> = batch
            .par_iter_mut()
            .map_init(Scratch::default, |scratch, (start, s, depth)| {
                if s.len() >= min {
                    build_clustered(s, *start, *depth, center, min)
                } else {
                    build_direct(s, *start, *depth, center, scratch)
                }
            })
            .collect();
        // Each subtree's place in the final array; its nodes are copied there in parallel
        // (with their inner slots moved by that base), so that the copy and the first touches
        // of the array's fresh memory are shared between the threads.
        let first = nodes.len();
        // Where each subtree starts, counted from `first`.
        let mut starts = Vec::with_capacity(subtrees.len());
        let mut count = 0;
        for (sub, root, d) in &subtrees {
            let base = (first + count) as u32;
            starts.push(count);
            count += sub.len();
            deepest = deepest.max(*d);
            roots.push(if root.count == 0 {
                Child {
                    offset: root.offset + base,
                    count: 0,
                }
            } else {
                *root
            });
        }
        nodes.par_extend((0..count).into_par_iter().map(|i| {
            let s = starts.partition_point(|&b| b <= i) - 1;
            let b = starts[s];
            let mut node = subtrees[s].0[i - b];
            for c in &mut node.child {
                if c.count == 0 {
                    c.offset += (first + b) as u32;
                }
            }
            node
        }));
    }
    let slot = |c: Child| {
        if c.count == CLUSTER_SLOT {
            roots[c.offset as usize]
        } else {
            c
        }
    };
    for node in &mut nodes[..tops] {
        node.child = node.child.map(slot);
    }
    (nodes, slot(root), deepest)
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
    /// boxes are not kept: the build holds one 32-byte record a primitive).
    pub fn build_from(items: impl ParallelIterator<Item = (Aabb, u32)>) -> Bvh {
        Self::build_prims(
            items.map(|(b, key)| Prim::new(&b, key)).collect(),
            CLUSTER_MIN,
        )
    }

    /// Builds the BVH over primitives that come in groups (the pieces of each cylinder, say):
    /// group `g` has `count(g)` primitives, which `items(g, out)` pushes to `out` (empty),
    /// each a box and a key, so that a group's items can share their work. The records are
    /// written in place into one array of the exact size, in parallel, in the groups' order.
    ///
    /// # Panics
    ///
    /// If there are `2^32` or more primitives, or `items` pushes other than `count` of them.
    pub fn build_grouped(
        groups: usize,
        count: impl Fn(usize) -> usize + Sync,
        items: impl Fn(usize, &mut Vec<(Aabb, u32)>) + Sync,
    ) -> Bvh {
        /// Groups filled by one task.
        const CHUNK: usize = 1024;
        let counts: Vec<usize> = (0..groups).into_par_iter().map(&count).collect();
        let mut first = Vec::with_capacity(groups + 1);
        first.push(0usize);
        for &c in &counts {
            first.push(first.last().copied().unwrap_or(0) + c);
        }
        drop(counts);
        let total = first[groups];
        assert!(total < u32::MAX as usize, "at most 2^32 - 1 primitives");
        // Zeroed by the allocator (fresh pages), not written here: the fill below is the first
        // touch, shared between the threads (writing 5.7M placeholders on one thread took
        // 0.125 s of the 1.6M model's 1.7 s). Out of memory, it ends the process as `vec!` does,
        // naming the size.
        let mut prims: Vec<Prim> =
            bytemuck::allocation::try_zeroed_vec(total).unwrap_or_else(|()| {
                // Below 2^32 records of 32 bytes: within `isize::MAX`.
                let layout = std::alloc::Layout::array::<Prim>(total).expect("a valid layout");
                std::alloc::handle_alloc_error(layout)
            });
        // The records of groups `CHUNK j..CHUNK (j + 1)`, split off in order.
        let mut tasks = Vec::with_capacity(groups.div_ceil(CHUNK));
        let mut rest = &mut prims[..];
        for g0 in (0..groups).step_by(CHUNK) {
            let g1 = (g0 + CHUNK).min(groups);
            let (chunk, r) = rest.split_at_mut(first[g1] - first[g0]);
            tasks.push((g0..g1, chunk));
            rest = r;
        }
        tasks
            .into_par_iter()
            .for_each_init(Vec::new, |out, (range, prims)| {
                let at = first[range.start];
                for g in range {
                    out.clear();
                    items(g, out);
                    let slots = &mut prims[first[g] - at..first[g + 1] - at];
                    assert_eq!(out.len(), slots.len(), "group {g}: not `count` items");
                    for (p, (b, key)) in slots.iter_mut().zip(out.iter()) {
                        *p = Prim::new(b, *key);
                    }
                }
            });
        drop(first);
        Self::build_prims(prims, CLUSTER_MIN)
    }

    /// [`Bvh::build`], through clusters (and clusters within clusters) from `cluster_min`
    /// primitives on: tests reach the clustered build with small inputs this way.
    #[cfg(test)]
    pub(super) fn build_clustered_from(boxes: &[Aabb], cluster_min: usize) -> Bvh {
        let keys: Vec<u32> = (0..boxes.len() as u32).collect();
        Self::build_clustered_keyed(boxes, &keys, cluster_min)
    }

    /// [`Bvh::build_clustered_from`] with keys.
    #[cfg(test)]
    pub(super) fn build_clustered_keyed(boxes: &[Aabb], keys: &[u32], cluster_min: usize) -> Bvh {
        let prims = boxes
            .iter()
            .zip(keys)
            .map(|(b, &key)| Prim::new(b, key))
            .collect();
        Self::build_prims(prims, cluster_min)
    }

    /// Builds the BVH over `prims`, through clusters if there are at least `cluster_min`.
    fn build_prims(mut prims: Vec<Prim>, cluster_min: usize) -> Bvh {
        if prims.is_empty() {
            return Bvh::default();
        }
        let b = prims
            .par_chunks(PARALLEL_BIN / 4)
            .map(|chunk| {
                chunk.iter().fold(Bounds::EMPTY, |mut b, p| {
                    b.grow(p);
                    b
                })
            })
            .reduce(|| Bounds::EMPTY, |a, b| a.union(&b));
        let center = DVec3::from_array(b.center());
        // The stored boxes lie within the root box rounded outward relative to the centre
        // (within 2^-23 of its size, or the smallest normal f32): 1e-6 covers both.
        let extent = std::array::from_fn(|k| {
            let (lo, hi) = (f64::from(b.lo()[k]), f64::from(b.hi()[k]));
            (hi - center[k]).max(center[k] - lo) * (1.0 + 1e-6) + 1e-30
        });
        let (mut nodes, mut root, depth) = build_clustered(&mut prims, 0, 1, center, cluster_min);
        assert!(
            depth < MAX_DEPTH,
            "BVH depth {depth} exceeds the traversal stack"
        );
        let indices = inline_singletons(&mut nodes, &mut root, &prims);
        // No shrink_to_fit: the reserve past the written nodes was never touched (it is not
        // resident), and shrinking an over-aligned Vec reallocates and copies the whole array
        // (the allocator's in-place realloc keeps only 16-byte alignment), which would raise
        // the build's peak by the size of the tree.
        Bvh {
            nodes,
            root: Some(root),
            bounds: Aabb {
                min: DVec3::from_array(b.lo().map(f64::from)),
                max: DVec3::from_array(b.hi().map(f64::from)),
            },
            center,
            extent,
            indices,
            primitives: prims.len(),
            depth,
        }
    }
}

/// Rewrites the leaf slots of `nodes` and `root` (which name runs of `prims`) as [`Child`]
/// documents: a leaf of one primitive holds its key, a longer one the start of its run in the
/// returned key array, which holds only such runs (the root's first, then the nodes' in order).
///
/// In parallel over chunks of nodes: a first pass counts each chunk's run lengths, so that
/// each chunk writes its own part of the array.
fn inline_singletons(nodes: &mut [Node], root: &mut Child, prims: &[Prim]) -> Vec<u32> {
    /// Nodes a task rewrites.
    const CHUNK: usize = 1 << 12;
    /// The keys a slot puts in the array: those of a leaf of two or more.
    fn run(c: &Child) -> usize {
        if c.count > 1 && c.count != u32::MAX {
            c.count as usize
        } else {
            0
        }
    }
    // Rewrites `c`; a run's keys go to `out` from `*at`, which is `base + *at` in the array.
    let rewrite = |c: &mut Child, out: &mut [u32], at: &mut usize, base: usize| {
        if c.count == 1 {
            c.offset = prims[c.offset as usize].index;
        } else if run(c) > 0 {
            let (s, k) = (c.offset as usize, c.count as usize);
            for (key, p) in out[*at..*at + k].iter_mut().zip(&prims[s..s + k]) {
                *key = p.index;
            }
            c.offset = (base + *at) as u32;
            *at += k;
        }
    };
    let runs: Vec<usize> = nodes
        .par_chunks(CHUNK)
        .map(|chunk| chunk.iter().flat_map(|n| &n.child).map(run).sum())
        .collect();
    let mut indices = vec![0u32; run(root) + runs.iter().sum::<usize>()];
    let (head, mut rest) = indices.split_at_mut(run(root));
    rewrite(root, head, &mut 0, 0);
    let mut parts = Vec::with_capacity(runs.len());
    let mut base = head.len();
    for k in runs {
        let (part, r) = rest.split_at_mut(k);
        parts.push((part, base));
        (rest, base) = (r, base + k);
    }
    nodes
        .par_chunks_mut(CHUNK)
        .zip(parts)
        .for_each(|(chunk, (out, base))| {
            let mut at = 0;
            for c in chunk.iter_mut().flat_map(|n| &mut n.child) {
                rewrite(c, out, &mut at, base);
            }
        });
    indices
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small generator for the tests (splitmix64).
    fn next(state: &mut u64) -> u64 {
        *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = *state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// The collapse's dynamic program, which tries only the splits that can win, chooses what
    /// the plain recurrence (every `j` for every `k`, the first of equal costs) chooses, on
    /// binary trees of 2 to 3,000 leaves: random boxes, and boxes from a few shapes repeated
    /// (equal areas, so ties) in leaves of one to [`MAX_LEAF`]. (Not on every tree: areas
    /// `2^46` times apart can round so that they differ, see [`best_slot_split`].)
    #[test]
    fn collapse_plan_is_the_full_recurrence() {
        let mut state = 11;
        let mut unit = || (next(&mut state) >> 11) as f64 / (1u64 << 53) as f64;
        for n in [2usize, 3, 5, 9, 17, 40, 300, 3000] {
            for shapes in [0usize, 2, 5] {
                let kinds: Vec<(DVec3, DVec3)> = (0..shapes.max(1))
                    .map(|_| {
                        let p = DVec3::new(unit(), unit(), unit()) * 4.0;
                        (p, p + DVec3::new(unit(), unit(), unit()))
                    })
                    .collect();
                let boxes: Vec<Aabb> = (0..n)
                    .map(|_| {
                        let (min, max) = if shapes == 0 {
                            let p = DVec3::new(unit(), unit(), unit()) * 10.0;
                            (p, p + DVec3::new(unit(), unit(), unit()) * 0.5)
                        } else {
                            kinds[(unit() * shapes as f64) as usize % shapes]
                        };
                        Aabb { min, max }
                    })
                    .collect();
                let (arena, root) = binary_tree(&boxes);
                if !matches!(arena[root as usize].kind, Kind::Interior(..)) {
                    continue;
                }
                let mut plan = CollapsePlan::default();
                plan.make(&arena, root);
                // The recurrence as the doc of `collapse` states it.
                let len = root as usize + 1 - plan.first;
                let mut cost = vec![[Cost(0.0, 0); WIDTH]; len];
                let mut spread = vec![[0u8; WIDTH]; len];
                let mut own = vec![0u8; len];
                for (me, node) in arena[plan.first..=root as usize].iter().enumerate() {
                    let Kind::Interior(a, b) = node.kind else {
                        continue;
                    };
                    let (ca, cb) = (cost[a as usize - plan.first], cost[b as usize - plan.first]);
                    let best = |k: usize| {
                        let mut m = (ca[0] + cb[k - 2], 1u8);
                        for j in 2..k {
                            let c = ca[j - 1] + cb[k - j - 1];
                            if c.less(m.0) {
                                m = (c, j as u8);
                            }
                        }
                        m
                    };
                    own[me] = best(WIDTH).1;
                    let wide = Cost(node.bounds.half_area(), 1) + best(WIDTH).0;
                    cost[me][0] = wide;
                    for k in 2..=WIDTH {
                        let (c, j) = best(k);
                        (cost[me][k - 1], spread[me][k - 1]) =
                            if wide.less(c) { (wide, 0) } else { (c, j) };
                    }
                }
                let plan_own: Vec<u8> = plan.spread.iter().map(|s| s[WIDTH - 1]).collect();
                assert_eq!(
                    plan_own, own,
                    "{n} leaves, {shapes} shapes: the nodes' own splits"
                );
                assert_eq!(
                    plan.spread, spread,
                    "{n} leaves, {shapes} shapes: the spreads"
                );
            }
        }
    }

    /// The partition keeps every item, puts exactly the matches first, and returns their
    /// count: empty, all, none, one, and random mixes.
    #[test]
    fn partition_puts_the_matches_first() {
        let mut state = 1;
        for len in [0usize, 1, 2, 3, 7, 64, 1000] {
            for density in [0, 1, 3, 5, 8] {
                let mut v: Vec<u64> = (0..len).map(|_| next(&mut state) % 100).collect();
                let pred = |x: &u64| x % 8 < density;
                let mut want: Vec<u64> = v.clone();
                want.sort_unstable();
                let m = partition(&mut v, pred);
                assert_eq!(m, want.iter().filter(|x| pred(x)).count(), "count");
                assert!(v[..m].iter().all(pred) && !v[m..].iter().any(pred), "sides");
                v.sort_unstable();
                assert_eq!(v, want, "the same items");
            }
        }
    }

    /// `sort_small` orders records as sorting them by [`Prim::order`] does, with ties in the
    /// centre broken by key, on every axis and every length up to [`SMALL`].
    #[test]
    fn sort_small_orders_by_centre_then_key() {
        let mut state = 2;
        for n in 0..=SMALL {
            for k in 0..3 {
                let prims: Vec<Prim> = (0..n)
                    .map(|i| {
                        // Few distinct centres, so ties occur; negative ones too.
                        let c = (next(&mut state) % 5) as f64 - 2.0;
                        let b = Aabb {
                            min: DVec3::splat(c - 1.0),
                            max: DVec3::splat(c + 1.0),
                        };
                        Prim::new(&b, (next(&mut state) % 1000) as u32 * 16 + i as u32)
                    })
                    .collect();
                let mut got = prims.clone();
                sort_small(&mut got, k);
                let mut want = prims;
                want.sort_by_key(|p| p.order(k));
                let keys = |v: &[Prim]| v.iter().map(|p| p.index).collect::<Vec<_>>();
                assert_eq!(keys(&got), keys(&want), "n = {n}, axis {k}");
            }
        }
    }

    /// A record's centre is its bounds' midpoint rounded once (as the `f64` sum of the two
    /// `f32`s, halved and rounded, gives it; bounds from 1e-30 to 1e30, where no half is
    /// subnormal), finite for infinite bounds, the same in the lanes as on each axis, and the
    /// lanes' corners are the box's, whatever the key's bits.
    #[test]
    fn centres_are_the_midpoints_rounded_once() {
        let mut state = 3;
        let mut unit = || (next(&mut state) >> 11) as f64 / (1u64 << 53) as f64;
        for case in 0..20_000 {
            let scale = 10f64.powf(-30.0 + 60.0 * unit());
            let lo = DVec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5) * scale;
            let b = Aabb {
                min: lo,
                max: lo + DVec3::new(unit(), unit(), unit()) * scale * unit(),
            };
            let key = [0, 1, 1 << 22, u32::MAX - 1, (unit() * 4e9) as u32][case % 5];
            let p = Prim::new(&b, key);
            let [lo, hi, mid] = p.lanes().map(|l| l.to_array());
            for k in 0..3 {
                let want = (0.5 * (fin(p.min[k]) + fin(p.max[k]))) as f32;
                assert_eq!(p.mid(k).to_bits(), want.to_bits(), "case {case}, axis {k}");
                assert_eq!(mid[k].to_bits(), want.to_bits(), "lanes, case {case}");
                assert_eq!((lo[k], hi[k]), (p.min[k], p.max[k]));
            }
        }
        let huge = Aabb {
            min: DVec3::splat(-1e300),
            max: DVec3::new(1e300, -1e300, 1e39),
        };
        let p = Prim::new(&huge, 7);
        let mid = p.lanes()[2].to_array();
        for (k, want) in [0.0, -f32::MAX, 0.0].into_iter().enumerate() {
            assert_eq!(p.mid(k), want, "axis {k}");
            assert_eq!(mid[k], want, "lanes, axis {k}");
        }
    }
}
