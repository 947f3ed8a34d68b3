//! A bounding volume hierarchy over axis-aligned boxes.
//!
//! Built as pbrt builds it (a binary tree by the binned surface area heuristic, [`BINS`] bins
//! on each axis), for large inputs over Morton-code clusters as HLBVH builds it (`build.rs`),
//! then collapsed into an 8-wide tree as Embree stores it: each [`Node`] holds
//! the boxes of up to [`WIDTH`] children, which one ray tests together (eight SIMD lanes), and
//! the children it enters are visited nearest first. Queried as parry queries it: one
//! traversal core, [`Bvh::traverse`], takes a closure that tests a primitive and returns the
//! best `t` so far, which serves nearest-hit (shrink `tmax`), all-hits (keep it) and any-hit
//! (return `-inf` to stop) queries alike.
//!
//! Boxes are stored in `f32` relative to the root's centre, rounded outward, so each holds its
//! primitives' `f64` boxes. The ray-box test runs in `f32` lanes (`Slabs32`), rounded so
//! that it misses no box the exact test meets, or for rays outside its range (`tmin < 0`,
//! extreme directions or origins) in `f64` lanes (`Slabs`).

use arrayvec::ArrayVec;
use gencyl::{Aabb, Ray};
use glam::DVec3;
use wide::{CmpGe, CmpLe, CmpLt, f32x8, f64x4};

use super::prefetch::prefetch;

/// Number of SAH bins per axis.
pub const BINS: usize = 16;
/// Most primitives in a leaf.
pub const MAX_LEAF: usize = 8;
/// Children of a wide node. Eight, not four: a ray's walk down the ponytail's tree loads a
/// third fewer nodes one after another (each waits on its parent's; 4.5 against 6.5 a camera
/// ray, 11.3 against 17 an incoherent one), and a node's eight boxes are two SIMD groups of
/// four tested without a dependency between them.
const WIDTH: usize = 8;
/// A bound on the binary tree's depth (48 SAH levels + 32 halving levels + 1); the wide
/// tree is no deeper.
const MAX_DEPTH: usize = 96;
/// The relative slack of [`Bvh::list_region`]'s test: sixteen units of `f32`'s rounding.
pub const REGION_SLACK: f64 = 16.0 * f32::EPSILON as f64 / 2.0;
/// The slack of [`Bvh::list_region`] for the anchor's own rounding, relative to its size.
pub const ANCHOR_SLACK: f64 = 1e-12;
/// Traversal stack size: each wide level leaves at most `WIDTH - 1` siblings on it (it pushes
/// up to `WIDTH` and pops one), so at depth `d` it holds at most `(WIDTH - 1) d + 1`.
const STACK: usize = (WIDTH - 1) * MAX_DEPTH + 1;

mod build;

/// A child slot of a [`Node`]: an interior node, a leaf (a run of primitives) or nothing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C)]
struct Child {
    /// Interior: the child node's index. Leaf of one primitive: its key itself (most leaves:
    /// the walk then reads no index array). Longer leaf: index of its first key in
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

/// One node of the wide tree: the children's boxes by axis and lane (`min[k][i]` is the
/// lower bound of child `i` on axis `k`; an empty slot has the box `+inf..+inf`, which no ray
/// meets: see [`Slabs32`]), and the children. 256 bytes, aligned to 64 so that a node spans
/// four cache lines, not five.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
struct Node {
    /// `planes[0]`: the lower bounds, `planes[1]` the upper ones.
    planes: [[[f32; WIDTH]; 3]; 2],
    child: [Child; WIDTH],
}

impl Node {
    /// The children's lower bounds by axis and lane.
    #[inline]
    fn min(&self) -> &[[f32; WIDTH]; 3] {
        &self.planes[0]
    }

    /// The children's upper bounds by axis and lane.
    #[inline]
    fn max(&self) -> &[[f32; WIDTH]; 3] {
        &self.planes[1]
    }
}

/// A BVH over primitives given by their boxes, named by `u32` keys (by default their indices).
#[derive(Clone, Debug)]
pub struct Bvh {
    /// The wide nodes, the root first (none for an empty BVH).
    nodes: Vec<Node>,
    /// The root's slot: interior node 0, or a single leaf.
    root: Option<Child>,
    /// The root's box.
    bounds: Aabb,
    /// The point node boxes are stored relative to (the root box's centre), so that their `f32`
    /// bounds keep their precision far from the world's origin.
    center: DVec3,
    /// At least the largest `|coordinate|` of any node box on each axis, relative to `center`
    /// (the `f32` box test takes only rays whose entries into such boxes cannot overflow).
    extent: [f64; 3],
    /// The keys of the leaves of two or more primitives, leaf by leaf.
    indices: Vec<u32>,
    /// Primitive count.
    primitives: usize,
    depth: usize,
}

/// Statistics of a built BVH.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BvhStats {
    /// Primitives.
    pub primitives: usize,
    /// Wide nodes.
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
            center: DVec3::ZERO,
            extent: [0.0; 3],
            indices: Vec::new(),
            primitives: 0,
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

    /// Bytes of nodes and indices: the nodes written (the build reserves a bound and never
    /// touches the rest, so it is not resident) and the indices' allocation.
    pub fn memory_bytes(&self) -> usize {
        self.nodes.len() * size_of::<Node>() + self.indices.capacity() * size_of::<u32>()
    }

    /// Node count, depth, memory.
    pub fn stats(&self) -> BvhStats {
        let slots = self.nodes.iter().flat_map(|n| n.child);
        BvhStats {
            primitives: self.primitives,
            nodes: self.nodes.len(),
            leaves: slots.filter(|c| c.count > 0 && c.count != u32::MAX).count()
                + usize::from(self.root.is_some_and(|c| c.count > 0)),
            depth: self.depth,
            bytes: self.memory_bytes(),
        }
    }

    /// The keys of the leaf in slot `c` (a leaf's slot, `c.count > 0`).
    #[inline]
    fn leaf_keys<'a>(&'a self, c: &'a Child) -> &'a [u32] {
        if c.count == 1 {
            std::slice::from_ref(&c.offset)
        } else {
            let s = c.offset as usize;
            &self.indices[s..s + c.count as usize]
        }
    }

    /// The leaves whose boxes may meet the convex region of the points `p` with
    /// `n.(p - anchor) >= c` for every plane `(n, c)` (`n` unit; the first eight, a larger
    /// region, where more are given), into `out`, node by node,
    /// each node's entry with the least of `axis.(p - anchor)` over its listed boxes (`axis` a
    /// unit vector; rounded down by `1e-9` of the sizes involved), sorted by it: what rays
    /// within the region walk instead of the tree ([`Self::traverse_listed`]). A tree of one
    /// leaf is listed whole, an empty one not at all, and a region that meets leaves in more
    /// than `limit` nodes is marked whole too once that many are found (its rays walk the
    /// tree: a long list costs a ray that misses more than the walk).
    ///
    /// A leaf is left out only if its box (or a box above it) lies beyond some plane by more
    /// than [`REGION_SLACK`] times `|p - anchor|_1 + |c| + |anchor - center|_1` at its farthest
    /// corner `p` along `n`, plus [`ANCHOR_SLACK`] `|anchor|_1` (for regions whose planes are
    /// placed in `f64` about a far anchor, as an orthographic camera's rays start). (A box can
    /// meet every plane's half-space and yet miss the region; such boxes are listed.)
    ///
    /// Each node's eight boxes are tested at once in `f32` relative to [`Bvh`]'s `center`:
    /// the farthest corner along `n` gives `sum_k max(n_k lo_k, n_k hi_k)` with `lo`, `hi`
    /// relative to the anchor. Its rounding (the stored bounds are exact; the anchor's shift
    /// and `n` rounded to `f32`, and three products and sums, each within `2^-24`) stays
    /// below 8 units of `2^-24` of the same sizes, and the slack is 16: no box the exact
    /// test keeps is left out. A box with an infinite bound (or one beyond `f32`'s range
    /// relative to the anchor) makes the slack infinite and is listed.
    pub fn list_region(
        &self,
        anchor: DVec3,
        planes: &[(DVec3, f64)],
        axis: DVec3,
        limit: usize,
        out: &mut RegionList,
    ) {
        out.entries.clear();
        (out.anchor, out.axis, out.whole) = (anchor, axis, false);
        match self.root {
            None => return,
            Some(root) if root.count > 0 => {
                out.whole = true;
                return;
            }
            Some(_) => {}
        }
        let a = anchor - self.center;
        let size = anchor.abs().element_sum();
        self.region_walk(anchor, planes, |index, n, mut leaves| {
            let mut near = f64::INFINITY;
            while leaves != 0 {
                let slot = leaves.trailing_zeros() as usize;
                leaves &= leaves - 1;
                let (mut least, mut scale) = (0.0, size);
                for k in 0..3 {
                    let lo = f64::from(n.min()[k][slot]) - a[k];
                    let hi = f64::from(n.max()[k][slot]) - a[k];
                    least += (axis[k] * lo).min(axis[k] * hi);
                    scale += lo.abs().max(hi.abs());
                }
                near = near.min(least - 1e-9 * scale);
            }
            out.entries.push((index, near));
            out.entries.len() > limit
        });
        if out.entries.len() > limit {
            out.entries.clear();
            out.whole = true;
        }
        out.entries.sort_by(|x, y| x.1.total_cmp(&y.1));
    }

    /// The walk of [`Self::list_region`]: `leaves(index, &node, mask)` for every node with
    /// leaf slots whose boxes may meet the region (their mask), until it returns `true`.
    fn region_walk(
        &self,
        anchor: DVec3,
        planes: &[(DVec3, f64)],
        mut leaves: impl FnMut(u32, &Node, i32) -> bool,
    ) {
        let Some(root) = self.root else {
            return;
        };
        let a = anchor - self.center;
        let shift =
            REGION_SLACK * a.abs().element_sum() + ANCHOR_SLACK * anchor.abs().element_sum();
        let a = a.to_array().map(|x| f32x8::splat(x as f32));
        let planes: ArrayVec<([f32x8; 3], f32x8), 8> = planes
            .iter()
            .take(8)
            .map(|&(n, c)| {
                let floor = c - REGION_SLACK * c.abs() - shift;
                (
                    n.to_array().map(|x| f32x8::splat(x as f32)),
                    f32x8::splat((floor as f32).next_down()),
                )
            })
            .collect();
        let slack = f32x8::splat(REGION_SLACK as f32);
        let mut stack: ArrayVec<u32, STACK> = ArrayVec::new();
        stack.push(root.offset);
        while let Some(i) = stack.pop() {
            let n = &self.nodes[i as usize];
            let lo: [f32x8; 3] = std::array::from_fn(|k| f32x8::from(n.min()[k]) - a[k]);
            let hi: [f32x8; 3] = std::array::from_fn(|k| f32x8::from(n.max()[k]) - a[k]);
            let size = |k: usize| lo[k].abs().max(hi[k].abs());
            let scale = slack * (size(0) + size(1) + size(2));
            let mut beyond: i32 = 0;
            for (nk, floor) in &planes {
                let far = |k: usize| (nk[k] * lo[k]).max(nk[k] * hi[k]);
                beyond |= (far(0) + far(1) + far(2))
                    .cmp_lt(*floor - scale)
                    .move_mask();
            }
            let mut meets = !beyond & ((1 << WIDTH) - 1);
            let mut leaf_slots = 0;
            while meets != 0 {
                let slot = meets.trailing_zeros() as usize;
                meets &= meets - 1;
                let child = n.child[slot];
                if child.count == Child::EMPTY.count {
                    continue;
                }
                if child.count > 0 {
                    leaf_slots |= 1 << slot;
                } else {
                    stack.push(child.offset);
                }
            }
            if leaf_slots != 0 && leaves(i, n, leaf_slots) {
                return;
            }
        }
    }

    /// Visits, nearer boxes first, every primitive whose leaf box the ray meets within
    /// `[tmin, tmax]`: `visit(primitive, tmax)` tests the primitive and returns the new `tmax`
    /// (the best hit's `t` for a nearest-hit query, the same `tmax` to see everything, `-inf`
    /// to stop). Boxes are tested against the closed range, so a primitive whose hit ties with
    /// the best so far is still visited. A ray with a non-finite origin or direction meets
    /// nothing.
    pub fn traverse(&self, ray: &Ray, tmin: f64, tmax: f64, visit: impl FnMut(u32, f64) -> f64) {
        self.traverse_prefetching(ray, tmin, tmax, |_: &[u32]| {}, visit);
    }

    /// [`Self::traverse`], calling `prefetch_leaf(keys)` with the primitives of every leaf
    /// the ray enters as soon as the walk has tested the leaf's box (with its siblings'), so
    /// the caller can start loading their data (which the visits would otherwise wait for).
    /// The walk does the same for the inner nodes it enters. (Naming every child before the
    /// test, entered or not, overlapped more misses with 4-wide nodes, but with eight
    /// children their up to 32 cache lines a node made incoherent rays 7-19% slower than the
    /// 4-wide tree's, two runs.)
    pub fn traverse_prefetching(
        &self,
        ray: &Ray,
        tmin: f64,
        tmax: f64,
        prefetch_leaf: impl Fn(&[u32]),
        visit: impl FnMut(u32, f64) -> f64,
    ) {
        self.traverse_prefetching_in::<true>(ray, (tmin, tmax), prefetch_leaf, visit);
    }

    /// [`Self::traverse_prefetching`], nearer children first where `NEAREST_FIRST`, else
    /// without ordering the children a ray enters (each node's in slot order): the same
    /// primitives for a query that never lowers `tmax` but to stop (all hits, any hit),
    /// without the sorting. On the path-traced ponytail the shadow rays take about 4% fewer
    /// instructions so: the nearer-first order finds a blocker sooner, but not by enough to
    /// pay for the sorting. Returns the number of nodes whose children's boxes the ray was
    /// tested against where counting is built in ([`super::COUNTING`]), else 0.
    #[inline]
    pub fn traverse_prefetching_in<const NEAREST_FIRST: bool>(
        &self,
        ray: &Ray,
        range: (f64, f64),
        prefetch_leaf: impl Fn(&[u32]),
        visit: impl FnMut(u32, f64) -> f64,
    ) -> usize {
        let Some(root) = self.root else {
            return 0;
        };
        let walk = TreeWalk::<_, _, NEAREST_FIRST> {
            root,
            prefetch_leaf,
            visit,
        };
        self.with_box_test(ray, range, walk)
    }

    /// [`Self::traverse`] for a ray within a region listed by [`Self::list_region`], over
    /// the listed leaves instead of the tree: every leaf whose box the ray meets within
    /// `[tmin, tmax]` is among the listed ones, visited entry by entry (nearest first along
    /// the list's axis) until the entries begin beyond `tmax`, each entry's leaves those the
    /// ray's box test meets (the walk's test, on the listed node). Where `visit` never lowers
    /// `tmax` it sees every primitive whose box the ray meets, as the walk does (whose
    /// rounded test may add a few boxes outside the region, which the ray does not meet), in
    /// another order; a nearest-hit query finds the same hit. For a ray outside the region the
    /// answer is not the walk's.
    pub fn traverse_listed(
        &self,
        ray: &Ray,
        range: (f64, f64),
        list: &RegionList,
        visit: impl FnMut(u32, f64) -> f64,
    ) -> usize {
        if list.whole {
            return self.traverse_prefetching_in::<true>(ray, range, |_: &[u32]| {}, visit);
        }
        let d = ray.dir.length();
        let walk = ListWalk {
            list,
            shift: list.axis.dot(ray.origin - list.anchor),
            speed: d * (1.0 + 1e-12),
            visit,
        };
        self.with_box_test(ray, range, walk)
    }

    /// Runs `walk` with the ray's box test (the `f32` test of its octant, the `f32` test
    /// of a ray with a flat axis, or the `f64` one): 0 for a ray that meets nothing (no
    /// tree, a NaN or empty range, a non-finite ray, a miss of the root's box).
    #[inline]
    fn with_box_test(&self, ray: &Ray, (tmin, tmax): (f64, f64), walk: impl Walk) -> usize {
        // Also refuses NaN bounds.
        if self.root.is_none() {
            return 0;
        }
        if tmin.is_nan() || tmax.is_nan() || tmin > tmax {
            return 0;
        }
        // `0 x` is a zero for a finite `x` and NaN for an infinite or NaN one: the sum is zero
        // exactly where the origin and the direction are finite (one vector test, not six).
        let finite = ray.origin * 0.0 + ray.dir * 0.0 == DVec3::ZERO;
        if !finite || ray.dir == DVec3::ZERO {
            return 0;
        }
        let slab = Slabs::new(ray, self.center, tmin);
        if !slab.meets(&self.bounds, ray, tmax) {
            return 0;
        }
        let range = (tmin, tmax);
        if let Some(fast) = Slabs32::<false>::new(&slab, tmin, &self.extent) {
            // The test of the ray's octant, whose near planes are known when compiled.
            match fast.octant() {
                0 => walk.run(self, &Octant::<0>(&fast), range),
                1 => walk.run(self, &Octant::<1>(&fast), range),
                2 => walk.run(self, &Octant::<2>(&fast), range),
                3 => walk.run(self, &Octant::<3>(&fast), range),
                4 => walk.run(self, &Octant::<4>(&fast), range),
                5 => walk.run(self, &Octant::<5>(&fast), range),
                6 => walk.run(self, &Octant::<6>(&fast), range),
                _ => walk.run(self, &Octant::<7>(&fast), range),
            }
        } else if let Some(fast) = Slabs32::<true>::new(&slab, tmin, &self.extent) {
            walk.run(self, &fast, range)
        } else {
            walk.run(self, &slab, range)
        }
    }

    /// The traversal proper, with the box test `slab`; the children a ray enters nearest first
    /// where `NEAREST_FIRST`, else in slot order. Returns the number of nodes tested (where
    /// counting is built in).
    #[inline]
    fn walk<B: BoxTest, const NEAREST_FIRST: bool>(
        &self,
        root: Child,
        slab: &B,
        tmin: f64,
        mut tmax: f64,
        prefetch_leaf: impl Fn(&[u32]),
        mut visit: impl FnMut(u32, f64) -> f64,
    ) -> usize {
        let mut nodes = 0;
        // Slots still to visit, with the ray's entry into their box (never later than the true
        // entry), in the box test's precision.
        let mut stack: ArrayVec<(Child, B::T), STACK> = ArrayVec::new();
        // `tmax` in the box test's precision (never below it).
        let mut limit = slab.limit(tmax);
        let mut cur = root;
        loop {
            if cur.count > 0 {
                for &p in self.leaf_keys(&cur) {
                    tmax = visit(p, tmax);
                    if tmax.is_nan() || tmax < tmin {
                        return nodes;
                    }
                }
                limit = slab.limit(tmax);
            } else {
                let n = &self.nodes[cur.offset as usize];
                if super::COUNTING {
                    nodes += 1;
                }
                let (entry, hit) = slab.entries(n, limit);
                // What the entered children need, asked for now, instead of one miss after
                // another down the tree.
                let mut h = hit;
                while h != 0 {
                    let c = &n.child[h.trailing_zeros() as usize];
                    h &= h - 1;
                    if c.count == 0 {
                        prefetch(&self.nodes[c.offset as usize]);
                    } else {
                        prefetch_leaf(self.leaf_keys(c));
                    }
                }
                if hit != 0 {
                    if hit & (hit - 1) == 0 {
                        // One child entered (the common case low in the tree): no sorting.
                        cur = n.child[hit.trailing_zeros() as usize];
                        continue;
                    }
                    // The entered children go on the stack, sorted (where `NEAREST_FIRST`) so
                    // that the nearest is on top (ties in slot order: pushed from the last slot,
                    // then a stable sort), and the walk goes on with the top one.
                    let base = stack.len();
                    let mut h = hit;
                    while h != 0 {
                        let i = (31 - h.leading_zeros()) as usize;
                        h &= !(1 << i);
                        stack.push((n.child[i], entry[i]));
                    }
                    if NEAREST_FIRST {
                        let entered = &mut stack[base..];
                        for a in 1..entered.len() {
                            let x = entered[a];
                            let mut j = a;
                            while j > 0 && entered[j - 1].1 < x.1 {
                                entered[j] = entered[j - 1];
                                j -= 1;
                            }
                            entered[j] = x;
                        }
                    }
                    cur = stack.pop().expect("two or more were pushed").0;
                    continue;
                }
            }
            // The next pushed slot the ray still enters before tmax.
            loop {
                let Some((c, t)) = stack.pop() else {
                    return nodes;
                };
                if t <= limit {
                    cur = c;
                    break;
                }
            }
        }
    }
}

/// The leaves of a [`Bvh`] that may meet a region ([`Bvh::list_region`]): nodes with such
/// leaf slots, each with a lower bound of `axis.(p - anchor)` over those leaves' boxes, in
/// increasing order. Reused from region to region.
#[derive(Clone, Debug, Default)]
pub struct RegionList {
    /// Node index and the lower bound.
    entries: Vec<(u32, f64)>,
    anchor: DVec3,
    axis: DVec3,
    /// Rays walk the tree: it is one leaf (no node to list), or the region meets too many.
    whole: bool,
}

impl RegionList {
    /// Whether no leaf may meet the region.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty() && !self.whole
    }

    /// The nodes listed (0 where rays walk the tree whole, or nothing is listed).
    pub fn nodes(&self) -> usize {
        self.entries.len()
    }
}

/// A walk to run with the ray's box test ([`Bvh::with_box_test`]), whichever it is.
trait Walk {
    /// The walk over `range` with the box test `slab`; returns the nodes tested where counting
    /// is built in.
    fn run<B: BoxTest>(self, bvh: &Bvh, slab: &B, range: (f64, f64)) -> usize;
}

/// [`Bvh::walk`] from `root`.
struct TreeWalk<P, V, const NEAREST_FIRST: bool> {
    root: Child,
    prefetch_leaf: P,
    visit: V,
}

impl<P: Fn(&[u32]), V: FnMut(u32, f64) -> f64, const NEAREST_FIRST: bool> Walk
    for TreeWalk<P, V, NEAREST_FIRST>
{
    #[inline]
    fn run<B: BoxTest>(self, bvh: &Bvh, slab: &B, (tmin, tmax): (f64, f64)) -> usize {
        bvh.walk::<B, NEAREST_FIRST>(self.root, slab, tmin, tmax, self.prefetch_leaf, self.visit)
    }
}

/// [`Bvh::traverse_listed`]'s walk over a [`RegionList`]. A point `p = o + t d` of the ray
/// has `axis.(p - anchor) = axis.(o - anchor) + t axis.d <= shift + t |d|`, so an entry
/// whose bound exceeds `shift + tmax |d|` (with `speed` = `|d|` rounded up) holds no box the
/// ray enters before `tmax`, nor does any later one.
struct ListWalk<'a, V> {
    list: &'a RegionList,
    shift: f64,
    speed: f64,
    visit: V,
}

impl<V: FnMut(u32, f64) -> f64> Walk for ListWalk<'_, V> {
    fn run<B: BoxTest>(mut self, bvh: &Bvh, slab: &B, (tmin, mut tmax): (f64, f64)) -> usize {
        let mut nodes = 0;
        let mut limit = slab.limit(tmax);
        for &(index, near) in &self.list.entries {
            let reach = self.shift + tmax * self.speed;
            if near - 1e-9 * (near.abs() + self.shift.abs()) > reach {
                break;
            }
            let n = &bvh.nodes[index as usize];
            if super::COUNTING {
                nodes += 1;
            }
            let (entry, hit) = slab.entries(n, limit);
            let mut h = hit;
            while h != 0 {
                let slot = h.trailing_zeros() as usize;
                h &= h - 1;
                let c = &n.child[slot];
                if c.count == 0 || !(entry[slot] <= limit) {
                    continue;
                }
                for &p in bvh.leaf_keys(c) {
                    tmax = (self.visit)(p, tmax);
                    if tmax.is_nan() || tmax < tmin {
                        return nodes;
                    }
                }
                limit = slab.limit(tmax);
            }
        }
        nodes
    }
}

/// A ray-box test of a node's children: where the ray enters each box within
/// `[tmin, tmax]` (never later than it truly does), and a bit mask of the boxes it meets
/// there (never missing one it truly meets).
trait BoxTest {
    /// The precision of entries and of the range's end.
    type T: Copy + PartialOrd;
    /// `tmax` in that precision, never below it.
    fn limit(&self, tmax: f64) -> Self::T;
    /// Entries into the boxes and the mask of those met before `limit`.
    fn entries(&self, n: &Node, limit: Self::T) -> ([Self::T; WIDTH], i32);
}

/// A ray prepared for slab tests against a [`Node`]'s `f32` boxes, in `f64`: the
/// general test, for any ray.
///
/// Node boxes are stored relative to the BVH's centre `c`, so the ray's origin is taken as
/// `o - c`. On a slab `lo..hi` the ray is inside for `t` between `(lo - o) / d` and
/// `(hi - o) / d`. No NaN arises: the origin is finite, a zero direction component takes the
/// flat case (`0 * inf` would be NaN), and `(+-inf - o) * inv` (an empty slot's bound) is
/// infinite. The range runs from `-f64::MAX` at least to `f64::MAX` at most, so that an empty
/// slot (`+inf..+inf`) is never entered, whichever way the ray runs (its slab is `+inf..+inf`
/// in `t` where `d > 0` and `-inf..-inf` where `d < 0`; `tmin = -inf` once let the latter in):
/// a box whose entry overflows to `+inf`, or whose exit to `-inf`, could hold no hit at a
/// finite `t`.
struct Slabs {
    /// `o - c` and `1 / d`, as arrays (indexing a `DVec3` by axis costs a branch per access).
    origin: [f64; 3],
    inv: [f64; 3],
    neg: [bool; 3],
    /// Direction components that are zero: the ray stays in that slab or misses it entirely.
    flat: [bool; 3],
    tmin: f64,
}

/// Lanes `4 h .. 4 h + 4` of `x`, widened to `f64`.
#[inline]
fn lanes(x: &[f32; WIDTH], h: usize) -> f64x4 {
    f64x4::from(std::array::from_fn(|i| f64::from(x[4 * h + i])))
}

impl Slabs {
    fn new(ray: &Ray, center: DVec3, tmin: f64) -> Self {
        let d = ray.dir;
        Slabs {
            origin: (ray.origin - center).to_array(),
            inv: d.recip().to_array(),
            neg: [d.x < 0.0, d.y < 0.0, d.z < 0.0],
            flat: [d.x == 0.0, d.y == 0.0, d.z == 0.0],
            tmin: tmin.max(-f64::MAX),
        }
    }

    /// Whether the ray meets the box `b` (in world coordinates) within `[tmin, tmax]`.
    fn meets(&self, b: &Aabb, ray: &Ray, tmax: f64) -> bool {
        let (origin, min, max) = (ray.origin.to_array(), b.min.to_array(), b.max.to_array());
        // Each axis narrows `[t0, t1]` to the ray's span in the box's slab. The box and the
        // origin are finite; a NaN (zero times an inverse that overflowed, from a subnormal
        // direction) fails its comparison and narrows nothing.
        let narrow = |(t0, t1): (f64, f64), k: usize| {
            let (o, lo, hi) = (origin[k], min[k], max[k]);
            let (near, far) = if self.neg[k] { (hi, lo) } else { (lo, hi) };
            let (a, b) = ((near - o) * self.inv[k], (far - o) * self.inv[k]);
            (if a > t0 { a } else { t0 }, if b < t1 { b } else { t1 })
        };
        let mut t = (self.tmin, tmax);
        if self.flat == [false; 3] {
            // Nearly every ray: three axes without a branch.
            t = narrow(narrow(narrow(t, 0), 1), 2);
        } else {
            for k in 0..3 {
                if !self.flat[k] {
                    t = narrow(t, k);
                } else if origin[k] < min[k] || origin[k] > max[k] {
                    // A flat axis: the ray stays in its slab or misses the box.
                    return false;
                }
            }
        }
        t.0 <= t.1
    }
}

impl BoxTest for Slabs {
    type T = f64;

    #[inline]
    fn limit(&self, tmax: f64) -> f64 {
        tmax
    }

    #[inline]
    fn entries(&self, n: &Node, tmax: f64) -> ([f64; WIDTH], i32) {
        let mut entry = [0.0; WIDTH];
        let mut hit = 0;
        // Two groups of four lanes.
        for h in 0..WIDTH / 4 {
            let mut t0 = f64x4::splat(self.tmin);
            let mut t1 = f64x4::splat(tmax.min(f64::MAX));
            let mut inside = f64x4::splat(0.0).cmp_le(f64x4::splat(0.0));
            for k in 0..3 {
                let (lo, hi) = (lanes(&n.min()[k], h), lanes(&n.max()[k], h));
                let o = f64x4::splat(self.origin[k]);
                if self.flat[k] {
                    inside = inside & lo.cmp_le(o) & hi.cmp_ge(o);
                    continue;
                }
                let (near, far) = if self.neg[k] { (hi, lo) } else { (lo, hi) };
                let inv = f64x4::splat(self.inv[k]);
                t0 = t0.fast_max((near - o) * inv);
                t1 = t1.fast_min((far - o) * inv);
            }
            hit |= (t0.cmp_le(t1) & inside).move_mask() << (4 * h);
            entry[4 * h..4 * h + 4].copy_from_slice(&t0.to_array());
        }
        (entry, hit)
    }
}

/// The same test in `f32` lanes, rounded so that it never misses a box the exact test meets:
/// the fast path, for rays with `tmin >= 0` whose origin and inverse direction are well inside
/// `f32`'s range. `FLAT`: whether the ray has a zero direction component (then that axis is a
/// containment test, and the others take a branch each to skip it); rays without one, nearly
/// all, run the test without a branch.
///
/// With `x = lo - o` and the ray's `1 / d`, each computed `fl(fl(x') inv')` is within
/// `(1 + 2^-24)^2` of `x' inv'`; the near plane takes the origin rounded toward the box
/// (`o' >= o` when `d > 0`, so `x' <= x`) and `|inv'| <= |1/d| (1 - EPS)`, the far plane the
/// opposite, so the near value is never above the true one where it is positive, the far
/// value never below it where it is positive, and signs survive rounding: with `tmin >= 0`
/// only positive values can decide. `TINY` covers underflow.
///
/// Which of a box's planes is near depends only on the ray (the sign of `d`), so each axis'
/// near and far planes are chosen, and given the origin and inverse of their role, once per
/// ray; a node's test is `a = (near - o_near) inv_near`, `b = (far - o_far) inv_far`, entry
/// `max_k a`, exit `min_k b`: `a` is the near value or below it and `b` the far value or above
/// it, so no box the exact test meets is missed. (The choice is made when compiled for rays
/// without a flat axis, [`Octant`], at run time by an index for the others.) An empty slot is
/// `+inf..+inf`: `a = b = +inf` (entry `+inf`) or `-inf` (exit `-inf`), never met, since the
/// range ends at `f32::MAX` at most and the test takes only rays for which every real box's
/// `a` and `b` are finite: `(extent + |o|) |1/d| <= F32_REACH` on each axis.
struct Slabs32<const FLAT: bool> {
    /// Per axis, which of a node's plane sets ([`Node::planes`]) the ray meets first: `1`
    /// (the upper planes) where `d < 0`, else `0`; the other set is the far one.
    near: [usize; 3],
    /// The origin and inverse direction for each axis' near and far plane: the lower plane's
    /// origin is the origin rounded up, the upper plane's rounded down. On a flat axis the near
    /// planes are the lower ones (the box holds the ray's line where `lo <= o_near` and
    /// `hi >= o_far`).
    o_near: [f32x8; 3],
    o_far: [f32x8; 3],
    inv_near: [f32x8; 3],
    inv_far: [f32x8; 3],
    flat: [bool; 3],
    tmin: f32x8,
}

/// The relative margin of the `f32` test's inverse directions (the rounding needs `2^-22`).
const EPS: f64 = 1.0 / (1u64 << 20) as f64;
/// An absolute margin for values that underflow.
const TINY: f32 = f32::MIN_POSITIVE;
/// The largest origin coordinate or inverse direction (and the smallest inverse) the `f32`
/// test takes.
const F32_SAFE: f64 = 1e30;
/// The largest distance along an axis over `|d|` on that axis (a box's `|x - o| / |d_k|`)
/// the `f32` test takes: its values, grown by their roundings, stay below `f32::MAX`.
const F32_REACH: f64 = 1e38;

impl<const FLAT: bool> Slabs32<FLAT> {
    /// The `f32` test of the ray `s` against boxes within `extent` of the centre, if its range
    /// and numbers suit it and it has a flat axis exactly when `FLAT`.
    fn new(s: &Slabs, tmin: f64, extent: &[f64; 3]) -> Option<Self> {
        if !(tmin >= 0.0) || s.flat.contains(&true) != FLAT {
            return None;
        }
        let suits = |k: usize| {
            let (o, inv) = (s.origin[k].abs(), s.inv[k].abs());
            o <= F32_SAFE
                && (s.flat[k]
                    || (1.0 / F32_SAFE..=F32_SAFE).contains(&inv)
                        && (extent[k] + o) * inv <= F32_REACH)
        };
        if !(0..3).all(suits) {
            return None;
        }
        let mut near = [0usize; 3];
        let mut o_near = [0.0f32; 3];
        let mut o_far = [0.0f32; 3];
        let mut inv_near = [0.0f32; 3];
        let mut inv_far = [0.0f32; 3];
        for k in 0..3 {
            // `o - c` was rounded to the nearest f64: `at_or_above` and `at_or_below` widen by
            // far more than its ulp.
            let (o, inv) = (s.origin[k], s.inv[k]);
            let (o_up, o_down) = (at_or_above(o), at_or_below(o));
            // Within 2^-24 of the scaled values, so |near| <= |1/d| (1 - EPS) and
            // |far| >= |1/d| (1 + EPS); both normal f32 (|inv| is within F32_SAFE).
            let near_inv = (inv * (1.0 - 2.0 * EPS)) as f32;
            let far_inv = (inv * (1.0 + 2.0 * EPS)) as f32;
            // The lower plane takes the origin rounded up and the upper one rounded down,
            // whichever is near (`x' <= x` at the near plane where d > 0, `x' >= x` at the far
            // one where d < 0, and the other way round at the upper plane); the near plane is
            // the lower one where d > 0, the upper one where d < 0.
            (near[k], o_near[k], o_far[k]) = if s.neg[k] {
                (1, o_down, o_up)
            } else {
                (0, o_up, o_down)
            };
            (inv_near[k], inv_far[k]) = (near_inv, far_inv);
        }
        Some(Slabs32 {
            near,
            o_near: o_near.map(f32x8::splat),
            o_far: o_far.map(f32x8::splat),
            inv_near: inv_near.map(f32x8::splat),
            inv_far: inv_far.map(f32x8::splat),
            flat: s.flat,
            tmin: f32x8::splat(if tmin <= F32_SAFE {
                at_or_below(tmin)
            } else {
                f32::MAX
            }),
        })
    }
}

impl Slabs32<false> {
    /// The ray's octant: bit `k` set where `d_k < 0` (its near planes on axis `k` are the
    /// upper ones).
    fn octant(&self) -> usize {
        self.near[0] | self.near[1] << 1 | self.near[2] << 2
    }
}

/// [`Slabs32`]'s test for a ray without a flat axis in the octant `OCT` ([`Slabs32::octant`]):
/// each axis' near and far planes are known when compiled, so a node's test loads them
/// directly. (Choosing them at run time costs every node more: by `min` and `max` of the two
/// planes' values, two operations more for each axis and group of four; by an index, the
/// address arithmetic, redone in each node.)
struct Octant<'a, const OCT: usize>(&'a Slabs32<false>);

impl<const OCT: usize> BoxTest for Octant<'_, OCT> {
    type T = f32;

    #[inline]
    fn limit(&self, tmax: f64) -> f32 {
        self.0.limit(tmax)
    }

    #[inline]
    fn entries(&self, n: &Node, limit: f32) -> ([f32; WIDTH], i32) {
        self.0
            .entries_with(n, limit, [OCT & 1, (OCT >> 1) & 1, (OCT >> 2) & 1])
    }
}

/// An `f32` at or above `x` (`|x| <= F32_SAFE`), without branches: `x` grown by `2^-22` of
/// itself, rounded to nearest (within `2^-24` relative where the result is a normal `f32`),
/// then raised by `TINY` (which covers the subnormal range and `0`).
#[inline]
fn at_or_above(x: f64) -> f32 {
    ((x + x.abs() * MARGIN) as f32) + TINY
}

/// An `f32` at or below `x` (`|x| <= F32_SAFE`): [`at_or_above`] mirrored.
#[inline]
fn at_or_below(x: f64) -> f32 {
    ((x - x.abs() * MARGIN) as f32) - TINY
}

/// The relative growth of [`at_or_above`] and [`at_or_below`] before rounding to `f32`.
const MARGIN: f64 = 1.0 / (1u64 << 22) as f64;

impl<const FLAT: bool> BoxTest for Slabs32<FLAT> {
    type T = f32;

    /// At most `f32::MAX` (so that an empty slot is never entered: every real box's values
    /// are finite and below it).
    #[inline]
    fn limit(&self, tmax: f64) -> f32 {
        if tmax <= F32_SAFE {
            at_or_above(tmax)
        } else {
            f32::MAX
        }
    }

    #[inline]
    fn entries(&self, n: &Node, limit: f32) -> ([f32; WIDTH], i32) {
        self.entries_with(n, limit, self.near)
    }
}

impl<const FLAT: bool> Slabs32<FLAT> {
    /// [`BoxTest::entries`] with each axis' near plane set `near[k]` (`self.near`, or the
    /// same values known when compiled: [`Octant`]).
    #[inline(always)]
    fn entries_with(&self, n: &Node, limit: f32, near: [usize; 3]) -> ([f32; WIDTH], i32) {
        let mut t0 = self.tmin;
        let mut t1 = f32x8::splat(limit);
        let mut inside = f32x8::splat(0.0).cmp_le(f32x8::splat(0.0));
        for k in 0..3 {
            let near = near[k] & 1;
            let (a, b) = (
                f32x8::from(n.planes[near][k]),
                f32x8::from(n.planes[near ^ 1][k]),
            );
            if FLAT && self.flat[k] {
                inside = inside & a.cmp_le(self.o_near[k]) & b.cmp_ge(self.o_far[k]);
                continue;
            }
            t0 = t0.fast_max((a - self.o_near[k]) * self.inv_near[k]);
            t1 = t1.fast_min((b - self.o_far[k]) * self.inv_far[k]);
        }
        let t0 = t0 - f32x8::splat(TINY);
        let met = t0.cmp_le(t1 + f32x8::splat(TINY));
        let hit = if FLAT { met & inside } else { met }.move_mask();
        (t0.to_array(), hit)
    }
}

#[cfg(test)]
mod tests {
    use super::build::{CLUSTER_MIN, collapse_both_ways, down, up};
    use super::*;
    use crate::accel::{Scene, SceneHit, Scratch, sort_hits};
    use crate::sampling::SampleRng as Rng;
    use crate::scenes::synth::{FiberParams, random_fibers, random_rays};
    use gencyl::{GeneralizedCylinder, Hit, Strand};

    #[test]
    fn node_is_256_bytes() {
        assert_eq!(size_of::<Node>(), 256, "node layout");
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

    /// The build's branch-free outward roundings are the nearest `f32` stepped by
    /// `f32::next_down` / `next_up` where it lies on the wrong side, to the bit: at zeros,
    /// `f64` values below `f32`'s subnormals, around `f32::MIN_POSITIVE` and `f32::MAX`,
    /// exact `f32`s and their `f64` neighbours, beyond `f32`'s range, infinities and NaN.
    #[test]
    fn build_roundings_are_the_nearest_stepped_outward() {
        let want_down = |x: f64| {
            let f = x as f32;
            if f as f64 > x { f.next_down() } else { f }
        };
        let want_up = |x: f64| {
            let f = x as f32;
            if (f as f64) < x { f.next_up() } else { f }
        };
        let mut rng = Rng::from_seed(72);
        let mut xs = vec![
            0.0,
            1e-320,
            1e-46,
            f32::MIN_POSITIVE as f64,
            f32::MAX as f64,
            f32::MAX as f64 * (1.0 + 1e-9),
            1e39,
            f64::MAX,
            f64::INFINITY,
        ];
        for e in -50..=40 {
            let m = rng.range(1.0, 10.0) * 10f64.powi(e);
            let f = m as f32 as f64;
            xs.extend([m, f, f.next_up(), f.next_down()]);
        }
        for _ in 0..20_000 {
            xs.push(rng.uniform() * 10f64.powf(rng.range(-330.0, 40.0)));
        }
        for x in xs.iter().flat_map(|&x| [x, -x]) {
            assert_eq!(down(x).to_bits(), want_down(x).to_bits(), "down({x:e})");
            assert_eq!(up(x).to_bits(), want_up(x).to_bits(), "up({x:e})");
        }
        assert!(down(f64::NAN).is_nan() && up(f64::NAN).is_nan(), "NaN");
    }

    /// The ray setup's branch-free roundings hold the value on every scale the `f32` test
    /// takes: zero, `f64` values below `f32`'s subnormals, around `f32::MIN_POSITIVE`, values
    /// that are exact `f32`s and their `f64` neighbours, up to `F32_SAFE`.
    #[test]
    fn branch_free_rounding_holds_the_value() {
        let mut rng = Rng::from_seed(71);
        let mut xs = vec![0.0, -0.0, F32_SAFE, -F32_SAFE, 1e-320, -1e-320];
        for e in -60..=30 {
            let m = rng.range(1.0, 10.0) * 10f64.powi(e);
            let f = m as f32 as f64;
            for x in [
                m,
                f,
                f.next_up(),
                f.next_down(),
                f32::MIN_POSITIVE as f64 * m,
            ] {
                if x.abs() <= F32_SAFE {
                    xs.extend([x, -x]);
                }
            }
        }
        for _ in 0..20_000 {
            let x = (rng.uniform() - 0.5) * 10f64.powf(rng.range(-330.0, 30.0));
            xs.push(x);
        }
        for x in xs {
            let (hi, lo) = (at_or_above(x), at_or_below(x));
            assert!(hi as f64 >= x && lo as f64 <= x, "{x}: {lo} {hi}");
            // Tight: within a few f32 ulps (or TINY) of the value.
            assert!(
                (hi as f64 - x) <= 1e-6 * x.abs() + 2.0 * TINY as f64
                    && (x - lo as f64) <= 1e-6 * x.abs() + 2.0 * TINY as f64,
                "{x}: {lo} {hi}"
            );
        }
    }

    /// Every ray through a point of a box (inside it, on a face, at a corner) visits that
    /// box's primitive, with the `f32` test (`tmin >= 0`) and the `f64` one (negative `tmin`,
    /// or directions too small or too large for `f32`, or entries beyond its range), for
    /// boxes of every size (points and flat ones too) far from the origin and near it, with
    /// bounded and open-ended rays.
    #[test]
    fn rays_through_a_box_always_visit_it() {
        let mut rng = Rng::from_seed(21);
        for (scene, &(offset, size)) in [
            (0.0, 1.0),
            (1e4, 1e-6),
            (-3e7, 1e-3),
            (1e-3, 1e-9),
            // Entries beyond f32's range from rays of tiny directions (F32_REACH).
            (0.0, 1e8),
        ]
        .iter()
        .enumerate()
        {
            let boxes: Vec<Aabb> = (0..500)
                .map(|_| {
                    let c =
                        DVec3::splat(offset) + rng.in_box(DVec3::ZERO, DVec3::splat(50.0 * size));
                    let mut h = DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * size;
                    // Flat boxes and points too (the test takes a box's planes in either order).
                    match rng.next_u64() % 8 {
                        0 => h.y = 0.0,
                        1 => h = DVec3::ZERO,
                        _ => {}
                    }
                    Aabb {
                        min: c - h,
                        max: c + h,
                    }
                })
                .collect();
            for bvh in [Bvh::build(&boxes), Bvh::build_clustered_from(&boxes, 16)] {
                check_structure(&bvh, &boxes);
                let mut missed = 0;
                for i in 0..4000 {
                    let target = i % boxes.len();
                    let b = boxes[target];
                    // A box built from f32-rounded bounds holds b; aim at b's own points.
                    let pick = |rng: &mut Rng, k: usize| match rng.next_u64() % 3 {
                        0 => b.min[k],
                        1 => b.max[k],
                        _ => rng.range(b.min[k], b.max[k]),
                    };
                    let p = DVec3::new(pick(&mut rng, 0), pick(&mut rng, 1), pick(&mut rng, 2));
                    let mut d = rng.unit_vector();
                    match i % 7 {
                        0 => d = [DVec3::X, DVec3::NEG_Y, DVec3::Z][i % 3],
                        1 => d.x = 0.0,
                        _ => {}
                    }
                    let scale = [1.0, 1e-35, 1e35, 1e-3, 1e-29, 1e29][i % 6];
                    let d = d * scale;
                    let back = rng.range(0.0, 100.0 * size) / scale;
                    let ray = Ray::new(p - back * d, d);
                    let tmin = if i % 5 == 0 { -1.0 / scale } else { 0.0 };
                    let mut seen = false;
                    // Open-ended rays too: no empty slot may be entered then.
                    let tmax = if (i / 7) % 3 == 0 {
                        f64::INFINITY
                    } else {
                        back * (1.0 + 1e-12) + 1e-300
                    };
                    bvh.traverse(&ray, tmin, tmax, |key, t| {
                        seen |= key as usize == target;
                        t
                    });
                    missed += usize::from(!seen);
                }
                assert_eq!(
                    missed, 0,
                    "scene {scene}: rays through a box that missed it"
                );
            }
        }
    }

    /// The root box's test ([`Slabs::meets`]) decides as the slab test's definition, written
    /// out axis by axis: a flat axis (`d_k = 0`, either sign of zero) holds the ray when its
    /// origin lies in the slab, any other narrows `[tmin, tmax]` to `[(near - o_k) / d_k,
    /// (far - o_k) / d_k]` (by the inverse direction, as the walk's `f64` test). On rays aimed
    /// at a box's faces, edges and corners and rays that pass them closely, with directions
    /// along axes, in a plane, with zeros of both signs, subnormal or huge components (whose
    /// inverses overflow), boxes that are points or flat, and ranges that start or end at the
    /// box.
    #[test]
    fn the_root_test_is_the_slab_test() {
        let definition = |b: &Aabb, ray: &Ray, (tmin, tmax): (f64, f64)| {
            let (mut t0, mut t1) = (tmin, tmax);
            for k in 0..3 {
                let (o, d, lo, hi) = (ray.origin[k], ray.dir[k], b.min[k], b.max[k]);
                if d == 0.0 {
                    if o < lo || o > hi {
                        return false;
                    }
                    continue;
                }
                let inv = 1.0 / d;
                let (a, c) = ((lo - o) * inv, (hi - o) * inv);
                let (near, far) = if d < 0.0 { (c, a) } else { (a, c) };
                // NaN (0 times an infinite inverse) narrows nothing.
                if near > t0 {
                    t0 = near;
                }
                if far < t1 {
                    t1 = far;
                }
            }
            t0 <= t1
        };
        let mut rng = Rng::from_seed(39);
        let (mut met, mut missed) = (0, 0);
        for i in 0..200_000 {
            let size = 10f64.powi((rng.next_u64() % 9) as i32 - 4);
            let c = DVec3::splat([0.0, 1e4, -3e7][i % 3]) + rng.in_box(DVec3::ZERO, DVec3::ONE);
            let mut h = DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * size;
            match rng.next_u64() % 6 {
                0 => h = DVec3::ZERO,
                1 => h.z = 0.0,
                _ => {}
            }
            let b = Aabb {
                min: c - h,
                max: c + h,
            };
            // A point of the box (a corner, an edge, a face or inside), or one just beside it.
            let pick = |rng: &mut Rng, k: usize| match rng.next_u64() % 4 {
                0 => b.min[k],
                1 => b.max[k],
                2 => rng.range(b.min[k], b.max[k]),
                _ => b.max[k] + size * 10f64.powi(-((rng.next_u64() % 15) as i32)),
            };
            let p = DVec3::new(pick(&mut rng, 0), pick(&mut rng, 1), pick(&mut rng, 2));
            let mut d = rng.unit_vector();
            match rng.next_u64() % 8 {
                0 => d = [DVec3::X, DVec3::NEG_Y, DVec3::Z][i % 3],
                1 => d.x = 0.0,
                2 => d.y = -0.0,
                3 => d.z = 1e-310,
                4 => d.x = -1e-300,
                _ => {}
            }
            let d = d * [1.0, 1e-30, 1e30][i % 3];
            let back = rng.range(0.0, 10.0 * size);
            let ray = Ray::new(p - back * d, d);
            let tmin = [0.0, back, -1.0, back * (1.0 + 1e-15)][(i / 3) % 4];
            let tmax = [f64::INFINITY, back, 2.0 * back + 1.0, back * (1.0 - 1e-15)][(i / 12) % 4];
            if tmin > tmax {
                continue;
            }
            let slab = Slabs::new(&ray, DVec3::ZERO, tmin);
            let want = definition(&b, &ray, (tmin.max(-f64::MAX), tmax));
            assert_eq!(
                slab.meets(&b, &ray, tmax),
                want,
                "case {i}: {ray:?} {b:?} {tmin} {tmax}"
            );
            if want {
                met += 1;
            } else {
                missed += 1;
            }
        }
        assert!(
            met > 20_000 && missed > 20_000,
            "both answers: {met} {missed}"
        );
    }

    /// A ray with an infinite or NaN coordinate in its origin or direction, or a zero
    /// direction, meets nothing (the walk is not entered), even aimed at a box it would meet.
    #[test]
    fn rays_with_non_finite_parts_meet_nothing() {
        let boxes = scattered_boxes(&mut Rng::from_seed(3), 200, 0.5);
        let bvh = Bvh::build(&boxes);
        let target = 0.5 * (boxes[0].min + boxes[0].max);
        let origin = DVec3::new(-5.0, -5.0, -5.0);
        let cast = |ray: Ray| {
            let mut visits = 0;
            bvh.traverse(&ray, 0.0, f64::INFINITY, |_, t| {
                visits += 1;
                t
            });
            visits
        };
        assert!(
            cast(Ray::new(origin, target - origin)) > 0,
            "the finite ray meets its box"
        );
        let mut visits = 0;
        for bad in [f64::INFINITY, f64::NEG_INFINITY, f64::NAN] {
            for k in 0..3 {
                let mut o = origin;
                o[k] = bad;
                visits += cast(Ray::new(o, target - origin));
                let mut d = target - origin;
                d[k] = bad;
                visits += cast(Ray::new(origin, d));
            }
        }
        visits += cast(Ray::new(origin, DVec3::ZERO));
        visits += cast(Ray::new(origin, DVec3::new(0.0, -0.0, 0.0)));
        assert_eq!(visits, 0, "rays with a non-finite part or no direction");
    }

    /// `n` boxes with centres uniform in `[0, 10]^3` and half-sizes uniform in `[0, half]` on
    /// each axis.
    fn scattered_boxes(rng: &mut Rng, n: usize, half: f64) -> Vec<Aabb> {
        (0..n)
            .map(|_| {
                let c = rng.in_box(DVec3::ZERO, DVec3::splat(10.0));
                let h = DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * half;
                Aabb {
                    min: c - h,
                    max: c + h,
                }
            })
            .collect()
    }

    /// A ray from anywhere about the boxes (in `[-5, 15]^3`) toward the centre of one of them.
    fn ray_toward_a_box(rng: &mut Rng, boxes: &[Aabb]) -> Ray {
        let o = rng.in_box(DVec3::splat(-5.0), DVec3::splat(15.0));
        let b = boxes[rng.next_u64() as usize % boxes.len()];
        Ray::new(o, 0.5 * (b.min + b.max) - o)
    }

    /// `list_region` never leaves out a region that holds a point of a primitive's box: pixel
    /// frustums of random cameras (perspective, fields of view from 1e-4 to 170 degrees, and
    /// orthographic) about boxes of sizes 1e-3 to 1e4 at the origin and 1e4 away, checked
    /// against every box's corners and centre; a pixel whose corner ray runs exactly through
    /// a box's point (the image centre looks at it) always meets it; a half-space beyond every
    /// box meets nothing.
    #[test]
    fn regions_keep_every_box_they_meet() {
        use crate::optics::{Camera, Projection};
        let mut rng = Rng::from_seed(41);
        // Whether the region's list holds any leaf.
        let listed = |bvh: &Bvh, eye: DVec3, planes: &[(DVec3, f64)]| {
            let mut list = RegionList::default();
            bvh.list_region(eye, planes, DVec3::X, usize::MAX, &mut list);
            !list.is_empty()
        };
        let inside = |eye: DVec3, planes: &[(DVec3, f64)], p: DVec3| {
            planes.iter().all(|&(n, c)| n.dot(p - eye) >= c)
        };
        let (mut met, mut missed) = (0, 0);
        for case in 0..120 {
            let scale = [1e-3, 1.0, 1e4][case % 3];
            let shift = DVec3::splat(if case % 2 == 0 { 0.0 } else { 1e4 });
            let boxes: Vec<Aabb> = scattered_boxes(&mut rng, 600, 0.3)
                .iter()
                .map(|b| Aabb {
                    min: b.min * scale + shift,
                    max: b.max * scale + shift,
                })
                .collect();
            let bvh = Bvh::build(&boxes);
            let points: Vec<DVec3> = boxes
                .iter()
                .flat_map(|b| {
                    (0..8)
                        .map(|i| {
                            DVec3::select(
                                glam::BVec3::new(i & 1 != 0, i & 2 != 0, i & 4 != 0),
                                b.max,
                                b.min,
                            )
                        })
                        .chain([0.5 * (b.min + b.max)])
                        .collect::<Vec<_>>()
                })
                .collect();
            for _ in 0..40 {
                let target = points[rng.next_u64() as usize % points.len()];
                let eye = rng.in_box(DVec3::splat(-5.0), DVec3::splat(15.0)) * scale + shift;
                let fov = 1e-4 * 1.7e6f64.powf(rng.uniform());
                let size = |rng: &mut Rng| 2 * (1 + rng.next_u64() % 500) as u32;
                let (width, height) = (size(&mut rng), size(&mut rng));
                let projection = if rng.uniform() < 0.3 {
                    Projection::Orthographic {
                        height: scale * 1e-3 * 1e4f64.powf(rng.uniform()),
                    }
                } else {
                    Projection::Perspective { fov }
                };
                let cam = Camera {
                    position: eye,
                    look_at: target,
                    up: rng.unit_vector(),
                    projection,
                    width,
                    height,
                };
                if cam.validate().is_err() {
                    continue;
                }
                let rays = cam.rays();
                // The pixel whose top left corner is the image centre: its corner ray runs
                // through the target (orthographic: the target lies ahead of the eye).
                let (cx, cy) = ((width / 2) as f64, (height / 2) as f64);
                let f = rays.frustum([cx, cy], [cx + 1.0, cy + 1.0]);
                assert!(
                    listed(&bvh, f.eye(), f.planes()),
                    "the pixel at the centre misses its target: {cam:?}"
                );
                // Any pixel: never refused while it holds a box's point.
                let (x, y) = (
                    rng.next_u64() % width as u64,
                    rng.next_u64() % height as u64,
                );
                let (x, y) = (x as f64, y as f64);
                let f = rays.frustum([x, y], [x + 1.0, y + 1.0]);
                let answer = listed(&bvh, f.eye(), f.planes());
                let holds = points.iter().any(|&p| inside(f.eye(), f.planes(), p));
                assert!(
                    answer || !holds,
                    "refused a region holding a point: {cam:?} {x} {y}"
                );
                met += usize::from(answer);
                missed += usize::from(!answer);
                // A half-space beyond every box, by a thousandth of the scene and the boxes'
                // rounding to f32 where the build takes them: nothing.
                let n = rng.unit_vector();
                let far = points
                    .iter()
                    .map(|p| n.dot(*p - eye))
                    .fold(f64::MIN, f64::max);
                let away = [(n, far + 1e-3 * scale + 1e-6 * (shift.x + 20.0 * scale))];
                assert!(!listed(&bvh, eye, &away), "beyond every box: {n}");
            }
        }
        assert!(met > 500 && missed > 500, "{met} met, {missed} missed");
        assert!(!listed(&Bvh::build(&[]), DVec3::ZERO, &[]));
    }

    /// A ray within its pixel's frustum finds over the frustum's list what it finds walking
    /// the tree: with boxes as primitives (a visit is the exact entry into the box, `f64`
    /// slabs), the nearest box and its entry (ties to the lower key), and the same set of
    /// boxes where nothing lowers `tmax`; rays through the pixel's corners, edges and inside,
    /// perspective and orthographic cameras, one-leaf trees too, and lists cut short at three
    /// nodes (then walked as the tree).
    #[test]
    fn listed_walks_find_what_tree_walks_find() {
        use crate::optics::{Camera, Projection};
        let mut rng = Rng::from_seed(43);
        let (mut hits, mut listed) = (0, 0);
        for case in 0..60 {
            let n = if case % 10 == 0 { 1 } else { 2000 };
            let boxes = scattered_boxes(&mut rng, n, 0.3);
            let bvh = Bvh::build(&boxes);
            // The exact entry of the ray into box `p`, if it meets it within `[0, inf)`.
            let entry = |ray: &Ray, p: u32| {
                let b = &boxes[p as usize];
                let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
                for k in 0..3 {
                    let (o, d) = (ray.origin[k], ray.dir[k]);
                    let (a, z) = ((b.min[k] - o) / d, (b.max[k] - o) / d);
                    t0 = t0.max(a.min(z));
                    t1 = t1.min(a.max(z));
                }
                (t0 <= t1).then_some(t0)
            };
            let target = 0.5 * (boxes[0].min + boxes[0].max);
            let cam = Camera {
                position: rng.in_box(DVec3::splat(-5.0), DVec3::splat(15.0)),
                look_at: target,
                up: rng.unit_vector(),
                projection: if case % 3 == 0 {
                    Projection::Orthographic { height: 4.0 }
                } else {
                    Projection::Perspective { fov: 40.0 }
                },
                width: 16,
                height: 12,
            };
            if cam.validate().is_err() {
                continue;
            }
            let rays = cam.rays();
            let mut list = RegionList::default();
            for (x, y) in [(8.0, 6.0), (0.0, 0.0), (15.0, 11.0), (3.0, 9.0), (8.0, 5.0)] {
                let f = rays.frustum([x, y], [x + 1.0, y + 1.0]);
                let limit = [usize::MAX, 3][(x as usize) % 2];
                bvh.list_region(f.eye(), f.planes(), f.axis(), limit, &mut list);
                listed += list.entries.len();
                for (dx, dy) in [(0.0, 0.0), (1.0, 1.0), (0.5, 0.0), (1.0, 0.3), (0.7, 0.2)] {
                    let ray = rays.ray(x + dx, y + dy);
                    let nearest = |listed: bool| {
                        let mut best: Option<(f64, u32)> = None;
                        let visit = |p: u32, tmax: f64| {
                            if let Some(t) = entry(&ray, p).filter(|&t| t <= tmax)
                                && best.is_none_or(|b| (t, p) < b)
                            {
                                best = Some((t, p));
                            }
                            best.map_or(tmax, |b| b.0)
                        };
                        if listed {
                            bvh.traverse_listed(&ray, (0.0, f64::INFINITY), &list, visit);
                        } else {
                            bvh.traverse(&ray, 0.0, f64::INFINITY, visit);
                        }
                        best
                    };
                    let want = nearest(false);
                    assert_eq!(
                        nearest(true),
                        want,
                        "case {case} pixel ({x}, {y}) + ({dx}, {dy})"
                    );
                    hits += usize::from(want.is_some());
                    // Everything met, nothing cut short: the same boxes.
                    let met = |listed: bool| {
                        let mut all = vec![];
                        let visit = |p: u32, tmax: f64| {
                            if entry(&ray, p).is_some() {
                                all.push(p);
                            }
                            tmax
                        };
                        if listed {
                            bvh.traverse_listed(&ray, (0.0, f64::INFINITY), &list, visit);
                        } else {
                            bvh.traverse(&ray, 0.0, f64::INFINITY, visit);
                        }
                        all.sort_unstable();
                        all.dedup();
                        all
                    };
                    assert_eq!(met(true), met(false), "case {case} pixel ({x}, {y})");
                }
            }
        }
        assert!(hits > 500 && listed > 1000, "{hits} hits, {listed} listed");
    }

    /// The primitives `traverse` visits on `ray` over `[0, inf)`, in order, nothing cut short.
    fn visited(bvh: &Bvh, ray: &Ray) -> Vec<u32> {
        let mut out = vec![];
        bvh.traverse(ray, 0.0, f64::INFINITY, |p, t| {
            out.push(p);
            t
        });
        out
    }

    /// `traverse_prefetching_in::<false>` visits the primitives `traverse` visits, each once,
    /// where nothing cuts the range short (over `[0, inf)` and over windows of the ray, one
    /// starting behind the origin, which the `f64` box test walks), in
    /// another order on some rays (it does not sort), names each leaf before visiting it, and
    /// stops where `visit` returns `-inf`.
    #[test]
    fn unordered_traversal_visits_the_same_primitives() {
        let mut rng = Rng::from_seed(9);
        let boxes = scattered_boxes(&mut rng, 3000, 0.2);
        let bvh = Bvh::build(&boxes);
        let (mut reordered, mut visits) = (0, 0);
        let all = |bvh: &Bvh, ray: &Ray, (tmin, tmax): (f64, f64), unordered: bool| {
            let named = std::cell::RefCell::new(Vec::new());
            let mut seen = vec![];
            let name = |keys: &[u32]| named.borrow_mut().extend_from_slice(keys);
            let visit = |p: u32, t: f64| {
                assert!(named.borrow().contains(&p), "{p} visited before named");
                seen.push(p);
                t
            };
            if unordered {
                bvh.traverse_prefetching_in::<false>(ray, (tmin, tmax), name, visit);
            } else {
                bvh.traverse_prefetching(ray, tmin, tmax, name, visit);
            }
            seen
        };
        for _ in 0..3000 {
            let ray = ray_toward_a_box(&mut rng, &boxes);
            let t = rng.range(0.0, 2.0);
            // The last window starts behind the origin: the `f64` box test's walk.
            let windows = [
                (0.0, f64::INFINITY),
                (t, t + rng.range(0.0, 1.0)),
                (-t - 1.0, t),
            ];
            for range in windows {
                let plain = all(&bvh, &ray, range, false);
                let seen = all(&bvh, &ray, range, true);
                reordered += usize::from(seen != plain);
                let (mut a, mut b) = (seen.clone(), plain.clone());
                a.sort_unstable();
                b.sort_unstable();
                assert_eq!(a, b, "the same primitives");
                a.dedup();
                assert_eq!(a.len(), seen.len(), "each once");
                visits += seen.len();
                let mut count = 0;
                bvh.traverse_prefetching_in::<false>(
                    &ray,
                    range,
                    |_| {},
                    |_, _| {
                        count += 1;
                        f64::NEG_INFINITY
                    },
                );
                assert_eq!(count, usize::from(!plain.is_empty()), "stops at once");
            }
        }
        assert!(visits > 3000, "the rays should visit leaves: {visits}");
        assert!(
            reordered > 100,
            "rays visited in another order: {reordered}"
        );
    }

    /// `traverse_prefetching` visits what `traverse` visits, in the same order, and before a
    /// leaf's primitives are visited it has named all of that leaf's primitives to `prefetch_leaf`
    /// (every leaf under an inner root is some node's child), naming only primitives the BVH
    /// holds, and only leaves the ray enters: with nothing cut short (`visit` keeps `tmax`),
    /// the leaves named are those visited, each once.
    #[test]
    fn prefetching_names_each_leaf_before_its_visit() {
        let mut rng = Rng::from_seed(5);
        let boxes = scattered_boxes(&mut rng, 3000, 0.2);
        let bvh = Bvh::build(&boxes);
        assert!(bvh.root.is_some_and(|r| r.count == 0), "an inner root");
        // Each primitive's leaf, by its first primitive.
        let mut leaf_of = vec![u32::MAX; boxes.len()];
        for c in bvh.nodes.iter().flat_map(|n| n.child) {
            if c.count > 0 && c.count != u32::MAX {
                let keys = bvh.leaf_keys(&c);
                for &p in keys {
                    leaf_of[p as usize] = keys[0];
                }
            }
        }
        let (mut visits, mut named) = (0, 0);
        let multi = std::cell::Cell::new(0);
        for _ in 0..3000 {
            let ray = ray_toward_a_box(&mut rng, &boxes);
            let plain = visited(&bvh, &ray);
            let hinted = std::cell::RefCell::new(Vec::new());
            let mut seen = vec![];
            bvh.traverse_prefetching(
                &ray,
                0.0,
                f64::INFINITY,
                |keys: &[u32]| {
                    // A whole leaf, named by its primitives.
                    let first = leaf_of[keys[0] as usize];
                    assert!(
                        keys.iter().all(|&p| leaf_of[p as usize] == first),
                        "{keys:?}"
                    );
                    let size = leaf_of.iter().filter(|&&l| l == first).count();
                    assert_eq!(keys.len(), size, "all of the leaf's primitives: {keys:?}");
                    multi.set(multi.get() + usize::from(keys.len() > 1));
                    hinted.borrow_mut().push(keys[0])
                },
                |p, t| {
                    assert!(
                        hinted.borrow().contains(&leaf_of[p as usize]),
                        "{p} visited before its leaf was named"
                    );
                    seen.push(p);
                    t
                },
            );
            assert_eq!(seen, plain, "the same visits");
            let hinted = hinted.into_inner();
            assert!(
                hinted
                    .iter()
                    .all(|&p| (p as usize) < boxes.len() && leaf_of[p as usize] == p),
                "only whole leaves are named: {hinted:?}"
            );
            let mut named_leaves = hinted.clone();
            named_leaves.sort_unstable();
            let mut visited_leaves: Vec<u32> = seen.iter().map(|&p| leaf_of[p as usize]).collect();
            visited_leaves.sort_unstable();
            visited_leaves.dedup();
            assert_eq!(
                named_leaves, visited_leaves,
                "the leaves named are those visited"
            );
            visits += seen.len();
            named += hinted.len();
        }
        assert!(visits > 3000, "the rays should visit leaves: {visits}");
        assert!(multi.get() > 20, "leaves of several: {}", multi.get());
        assert!(named > 1000, "leaves named: {named}");
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
        // Directly and through clusters (which cannot separate identical centres).
        let builds: [fn(&[Aabb]) -> Bvh; 2] = [Bvh::build, |b| Bvh::build_clustered_from(b, 16)];
        for build in builds {
            // Many identical boxes: no split separates them; leaves stay small, depth bounded.
            let b = Aabb {
                min: DVec3::ZERO,
                max: DVec3::ONE,
            };
            let boxes = vec![b; 10_000];
            let bvh = build(&boxes);
            check_structure(&bvh, &boxes);
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
            let bvh = build(&boxes);
            check_structure(&bvh, &boxes);
            assert!(bvh.stats().depth < STACK, "{:?}", bvh.stats());
            // Infinite boxes.
            let inf = Aabb {
                min: DVec3::splat(-1e300),
                max: DVec3::splat(1e300),
            };
            let bvh = build(&[inf, b, inf]);
            let mut seen = vec![];
            bvh.traverse(
                &Ray::new(DVec3::splat(5.0), DVec3::X),
                0.0,
                f64::INFINITY,
                |p, t| {
                    seen.push(p);
                    t
                },
            );
            // The unit box may share their leaf (a leaf's primitives are visited together).
            assert!(
                seen.contains(&0) && seen.contains(&2),
                "both infinite boxes met: {seen:?}"
            );
        }
    }

    /// Walks the tree: every primitive sits in exactly one leaf, every slot's box holds the
    /// boxes below it (the nodes' children, a leaf's primitives as the build rounds them), no
    /// interior node is reached twice, and the binary depth bound covers the walk.
    fn check_structure(bvh: &Bvh, boxes: &[Aabb]) {
        let mut seen = vec![0u32; boxes.len()];
        let mut visited = vec![false; bvh.nodes.len()];
        let c = bvh.center;
        // (slot, its box relative to the centre, wide depth)
        let mut todo = vec![(
            bvh.root.expect("not empty"),
            None::<([f32; 3], [f32; 3])>,
            1,
        )];
        while let Some((slot, bx, depth)) = todo.pop() {
            assert!(depth <= bvh.depth, "wide depth {depth} past {}", bvh.depth);
            if slot.count > 0 {
                for &p in bvh.leaf_keys(&slot) {
                    seen[p as usize] += 1;
                    if let Some((lo, hi)) = bx {
                        let b = &boxes[p as usize];
                        for k in 0..3 {
                            let (pmin, pmax) = (down(b.min[k]) as f64, up(b.max[k]) as f64);
                            assert!(
                                lo[k] as f64 <= pmin - c[k] && hi[k] as f64 >= pmax - c[k],
                                "primitive {p} outside its leaf's box on axis {k}"
                            );
                        }
                    }
                }
                continue;
            }
            assert!(
                !visited[slot.offset as usize],
                "node {} reached twice",
                slot.offset
            );
            visited[slot.offset as usize] = true;
            let n = &bvh.nodes[slot.offset as usize];
            for (i, &child) in n.child.iter().enumerate() {
                if child.count == u32::MAX {
                    continue;
                }
                let lo: [f32; 3] = std::array::from_fn(|k| n.min()[k][i]);
                let hi: [f32; 3] = std::array::from_fn(|k| n.max()[k][i]);
                if let Some((plo, phi)) = bx {
                    for k in 0..3 {
                        assert!(
                            plo[k] <= lo[k] && phi[k] >= hi[k],
                            "child box outside its parent's on axis {k}"
                        );
                    }
                }
                todo.push((child, Some((lo, hi)), depth + 1));
            }
        }
        assert!(
            seen.iter().all(|&k| k == 1),
            "a primitive is not in exactly one leaf"
        );
        assert!(visited.iter().all(|&v| v), "an unreachable node");
        // The key array is the runs of the leaves of two or more, each once, in order: the
        // root's, then the nodes' slots', node by node.
        let mut next = 0;
        let root = bvh.root.expect("not empty");
        for c in std::iter::once(&root).chain(bvh.nodes.iter().flat_map(|n| &n.child)) {
            if c.count > 1 && c.count != u32::MAX {
                assert_eq!(c.offset as usize, next, "a leaf's run out of order");
                next += c.count as usize;
            }
        }
        assert_eq!(next, bvh.indices.len(), "keys outside the leaves' runs");
    }

    /// The boxes of random fibers' control points, grown by their radii.
    fn fiber_boxes(params: &FiberParams, seed: u64) -> Vec<Aabb> {
        random_fibers(params, seed)
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
            .collect()
    }

    /// The collapse into wide nodes (a dynamic program over the binary tree) costs the SAH no
    /// more than the rule it replaced (opening the largest child first) on the same binary
    /// tree, by the wide nodes' total area, and uses fewer nodes where that rule left slots
    /// empty: fibers and a grid of boxes, direct builds.
    #[test]
    fn collapse_beats_opening_the_largest_child() {
        let mut grid = vec![];
        for i in 0..20 {
            for j in 0..20 {
                for k in 0..7 {
                    let p = DVec3::new(i as f64, j as f64, k as f64 * 1.5);
                    grid.push(Aabb {
                        min: p,
                        max: p + DVec3::new(0.5, 0.7, 0.3),
                    });
                }
            }
        }
        let fibers = fiber_boxes(
            &FiberParams {
                count: 20_000,
                ..FiberParams::default()
            },
            4,
        );
        for (name, boxes) in [("grid", grid), ("fibers", fibers)] {
            let [(nodes, area), (greedy_nodes, greedy_area)] = collapse_both_ways(&boxes);
            // The dynamic program's areas are of `f32` boxes rounded outward from the binary
            // ones: a relative 1e-6 for that.
            assert!(
                area <= greedy_area * (1.0 + 1e-6),
                "{name}: area {area} against {greedy_area}"
            );
            assert!(
                nodes * 100 < greedy_nodes * 95,
                "{name}: {nodes} nodes against {greedy_nodes}"
            );
            let bvh = Bvh::build(&boxes);
            check_structure(&bvh, &boxes);
            assert_eq!(
                bvh.nodes.len(),
                nodes,
                "{name}: the same tree as `Bvh::build`'s"
            );
        }
    }

    /// Clustered builds (nested, from 16 primitives on) of fibers' boxes: the same structure
    /// invariants, every ray visits every box it meets (brute force, in `f64`), and the tree
    /// costs no more than the direct build's by more than a little (SAH of the wide nodes).
    #[test]
    fn clustered_build_is_sound() {
        let params = FiberParams {
            count: 3000,
            ..FiberParams::default()
        };
        let boxes = fiber_boxes(&params, 4);
        let direct = Bvh::build(&boxes);
        for min in [16, 200, 1000] {
            let bvh = Bvh::build_clustered_from(&boxes, min);
            check_structure(&bvh, &boxes);
            let rays = random_rays(500, 9, &params);
            let mut visits = [0usize; 2];
            for ray in &rays {
                let mut seen = vec![false; boxes.len()];
                bvh.traverse(ray, 0.0, f64::INFINITY, |p, t| {
                    seen[p as usize] = true;
                    visits[0] += 1;
                    t
                });
                direct.traverse(ray, 0.0, f64::INFINITY, |_, t| {
                    visits[1] += 1;
                    t
                });
                for (i, b) in boxes.iter().enumerate() {
                    if b.ray_range(ray).is_some_and(|(t0, t1)| t1 >= t0.max(0.0)) {
                        assert!(
                            seen[i],
                            "cluster_min {min}: ray {ray:?} met box {i} unvisited"
                        );
                    }
                }
            }
            // Visits are leaves whose box the ray meets: a poor tree visits many more.
            assert!(
                visits[0] as f64 <= 1.25 * visits[1] as f64,
                "cluster_min {min}: {} visits against the direct build's {}",
                visits[0],
                visits[1]
            );
        }
    }

    /// A clustered build of hundreds of clusters (several batches of them, each copied into
    /// the node array in parallel), among them clusters of one primitive (no nodes of their
    /// own): a dense cloud in one corner of the centres' box and a few boxes scattered over
    /// the rest, each alone in its grid cell.
    #[test]
    fn clustered_build_of_many_batches_is_sound() {
        let mut rng = Rng::from_seed(17);
        let mut boxes: Vec<Aabb> = (0..150_000)
            .map(|_| {
                let c = rng.in_box(DVec3::ZERO, DVec3::splat(0.5));
                let r = DVec3::splat(rng.range(1e-4, 1e-2));
                Aabb {
                    min: c - r,
                    max: c + r,
                }
            })
            .collect();
        for k in 0..12 {
            let c = DVec3::new(0.55 + 0.04 * k as f64, 0.95 - 0.07 * k as f64, 1.0);
            boxes.push(Aabb {
                min: c - 1e-3,
                max: c + 1e-3,
            });
        }
        let bvh = Bvh::build_clustered_from(&boxes, CLUSTER_MIN);
        check_structure(&bvh, &boxes);
        assert_eq!(bvh.stats().primitives, boxes.len());
    }

    /// The hits of every cylinder, brute force.
    fn brute_all(cylinders: &[GeneralizedCylinder], ray: &Ray, tmin: f64) -> Vec<SceneHit> {
        let mut out = vec![];
        let mut scratch: Vec<Hit> = vec![];
        for (i, c) in cylinders.iter().enumerate() {
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

    /// A walk returns the number of nodes it tested: where nothing lowers `tmax`, every node
    /// whose slot box the ray enters from the root (counted by a plain recursion with the same
    /// box test), in either order; none for a ray that misses the root box, or for a tree
    /// that is a single leaf.
    #[test]
    fn walks_count_the_nodes_they_test() {
        fn reference<B: BoxTest>(bvh: &Bvh, c: Child, slab: &B, limit: B::T) -> usize {
            if c.count > 0 {
                return 0;
            }
            let n = &bvh.nodes[c.offset as usize];
            let (_, hit) = slab.entries(n, limit);
            1 + (0..WIDTH)
                .filter(|&i| hit >> i & 1 == 1)
                .map(|i| reference(bvh, n.child[i], slab, limit))
                .sum::<usize>()
        }
        let mut rng = Rng::from_seed(29);
        let boxes = scattered_boxes(&mut rng, 3000, 0.3);
        let bvh = Bvh::build(&boxes);
        let (mut entered, mut several) = (0, 0);
        for _ in 0..400 {
            let ray = ray_toward_a_box(&mut rng, &boxes);
            let slab = Slabs::new(&ray, bvh.center, 0.0);
            let fast = Slabs32::<false>::new(&slab, 0.0, &bvh.extent).expect("an f32 ray");
            let want = reference(&bvh, bvh.root.unwrap(), &fast, fast.limit(f64::INFINITY));
            let range = (0.0, f64::INFINITY);
            let ordered = bvh.traverse_prefetching_in::<true>(&ray, range, |_| {}, |_, t| t);
            let unordered = bvh.traverse_prefetching_in::<false>(&ray, range, |_| {}, |_, t| t);
            assert_eq!((ordered, unordered), (want, want), "ray {ray:?}");
            entered += usize::from(want > 0);
            several += usize::from(want > 3);
        }
        assert!(entered == 400 && several > 100, "{entered} {several}");
        // Rays that miss the root box, and a one-leaf tree.
        let away = Ray::new(DVec3::splat(-5.0), DVec3::new(-1.0, 0.2, 0.1));
        assert_eq!(
            bvh.traverse_prefetching_in::<true>(&away, (0.0, 1e9), |_| {}, |_, t| t),
            0
        );
        let single = Bvh::build(&boxes[..1]);
        let (o, c) = (DVec3::splat(-5.0), 0.5 * (boxes[0].min + boxes[0].max));
        let mut seen = 0;
        let nodes = single.traverse_prefetching_in::<true>(
            &Ray::new(o, c - o),
            (0.0, f64::INFINITY),
            |_| {},
            |_, t| {
                seen += 1;
                t
            },
        );
        assert_eq!((nodes, seen), (0, 1), "a one-leaf tree tests no node");
    }

    /// The walk visits leaves in the order of a recursive reference walk: at each node, the
    /// children whose boxes the ray enters, nearest entry first, equal entries in slot order.
    /// Boxes repeated (ties), random boxes, and rays from inside and outside the model.
    #[test]
    fn visits_nearest_first_with_ties_in_slot_order() {
        fn reference<B: BoxTest>(bvh: &Bvh, c: Child, slab: &B, limit: B::T, out: &mut Vec<u32>) {
            if c.count > 0 {
                out.extend_from_slice(bvh.leaf_keys(&c));
                return;
            }
            let n = &bvh.nodes[c.offset as usize];
            let (entry, hit) = slab.entries(n, limit);
            let mut entered: Vec<usize> = (0..WIDTH).filter(|&i| hit >> i & 1 == 1).collect();
            // A stable sort: equal entries stay in slot order.
            entered.sort_by(|&a, &b| entry[a].partial_cmp(&entry[b]).unwrap());
            for i in entered {
                reference(bvh, n.child[i], slab, limit, out);
            }
        }
        let mut rng = Rng::from_seed(17);
        for repeats in [1usize, 4, 40] {
            let shapes = scattered_boxes(&mut rng, 4000 / repeats, 0.4);
            let boxes: Vec<Aabb> = (0..shapes.len() * repeats)
                .map(|i| shapes[i % shapes.len()])
                .collect();
            let bvh = Bvh::build(&boxes);
            let mut orders = 0;
            for _ in 0..500 {
                let ray = ray_toward_a_box(&mut rng, &boxes);
                let walked = visited(&bvh, &ray);
                let slab = Slabs::new(&ray, bvh.center, 0.0);
                let fast = Slabs32::<false>::new(&slab, 0.0, &bvh.extent).expect("an f32 ray");
                let mut want = vec![];
                reference(
                    &bvh,
                    bvh.root.unwrap(),
                    &fast,
                    fast.limit(f64::INFINITY),
                    &mut want,
                );
                assert_eq!(walked, want, "{repeats} repeats, ray {ray:?}");
                orders += usize::from(walked.len() > 1);
            }
            assert!(orders > 100, "rays that visit several leaves: {orders}");
        }
    }

    #[test]
    fn same_hits_as_brute_force() {
        let params = FiberParams {
            count: 300,
            elliptical_fraction: 0.05,
            ..FiberParams::default()
        };
        let mut cyls: Vec<_> = random_fibers(&params, 11)
            .iter()
            .map(|s| s.build().unwrap())
            .collect();
        // And strands, whose segments the scene stores packed (joined at their joints).
        let mut rng = Rng::from_seed(9);
        for _ in 0..40 {
            let mut p = rng.in_box(DVec3::ZERO, DVec3::ONE);
            let step = rng.unit_vector() * 0.1;
            let points = (0..8)
                .map(|_| {
                    p += step + rng.unit_vector() * 0.03;
                    p
                })
                .collect();
            let strand = Strand {
                points,
                radius: [0.01, rng.range(0.002, 0.01)],
                ellipticity: if rng.uniform() < 0.3 { 0.6 } else { 1.0 },
                twist: [0.0, rng.range(0.0, 3.0)],
                section: Default::default(),
            };
            cyls.extend(strand.cylinders().unwrap());
        }
        let scene = Scene::new(cyls.clone());
        for (i, c) in cyls.iter().enumerate() {
            assert!(*scene.cylinder(i as u32) == *c, "cylinder {i} as given");
        }
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
            let brute = brute_all(&cyls, ray, tmin);
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

    /// A build from groups (of 0 to 40 items, filled together) equals the build over the same
    /// boxes and keys in one list, node for node, directly and through clusters.
    #[test]
    fn grouped_build_equals_the_flat_one() {
        let mut rng = Rng::from_seed(3);
        let counts: Vec<usize> = (0..6000)
            .map(|i| {
                if i % 10 == 0 {
                    0
                } else {
                    (rng.next_u64() % 41) as usize
                }
            })
            .collect();
        let mut boxes = vec![];
        let mut first = vec![];
        for &n in &counts {
            let start = rng.in_box(DVec3::ZERO, DVec3::splat(10.0));
            let step = rng.unit_vector() * 0.05;
            first.push(boxes.len());
            boxes.extend((0..n).map(|k| {
                let (a, b) = (start + step * k as f64, start + step * (k + 1) as f64);
                Aabb {
                    min: a.min(b) - 0.02,
                    max: a.max(b) + 0.02,
                }
            }));
        }
        assert!(boxes.len() > CLUSTER_MIN, "through clusters");
        let keys: Vec<u32> = (0..boxes.len() as u32)
            .map(|k| k.wrapping_mul(2654435761))
            .collect();
        let grouped = Bvh::build_grouped(
            counts.len(),
            |g| counts[g],
            |g, out| out.extend((first[g]..first[g] + counts[g]).map(|k| (boxes[k], keys[k]))),
        );
        let flat = Bvh::build_keyed(&boxes, &keys);
        assert_eq!(grouped.nodes, flat.nodes, "nodes differ");
        assert_eq!(grouped.indices, flat.indices, "indices differ");
        assert_eq!(grouped.root, flat.root, "roots differ");
    }

    #[test]
    fn the_tree_does_not_depend_on_the_order_given() {
        // Fibers, and boxes on a grid whose centres tie on every axis (the build's sorts and
        // selections then order by key); enough for the clustered build, and small clusters
        // too.
        let params = FiberParams {
            count: 30_000,
            ..FiberParams::default()
        };
        let mut boxes = fiber_boxes(&params, 2);
        for i in 0..4_000 {
            let c = DVec3::new((i % 20) as f64, (i / 20 % 20) as f64, (i / 400) as f64) * 0.05;
            let h = DVec3::splat(0.01 + 0.002 * (i % 3) as f64);
            boxes.push(Aabb {
                min: c - h,
                max: c + h,
            });
        }
        // Duplicates: equal boxes under other keys.
        boxes.extend_from_within(..500);
        assert!(boxes.len() >= CLUSTER_MIN);
        let keys: Vec<u32> = (0..boxes.len() as u32).map(|i| i * 7 + 3).collect();
        let mut order: Vec<usize> = (0..boxes.len()).collect();
        let mut rng = Rng::from_seed(56);
        for i in (1..order.len()).rev() {
            order.swap(i, (rng.next_u64() % (i as u64 + 1)) as usize);
        }
        let shuffled = |v: &[u32]| order.iter().map(|&i| v[i]).collect::<Vec<u32>>();
        let shuffled_boxes: Vec<Aabb> = order.iter().map(|&i| boxes[i]).collect();
        let given = Bvh::build_keyed(&boxes, &keys);
        let other = Bvh::build_keyed(&shuffled_boxes, &shuffled(&keys));
        assert_eq!(given.root, other.root);
        assert!(given.nodes == other.nodes, "nodes depend on the order");
        assert_eq!(given.indices, other.indices, "leaves depend on the order");
        // Small clusters, and clusters within clusters.
        let given = Bvh::build_clustered_keyed(&boxes, &keys, 500);
        let other = Bvh::build_clustered_keyed(&shuffled_boxes, &shuffled(&keys), 500);
        assert!(
            given.nodes == other.nodes,
            "clustered nodes depend on the order"
        );
        assert_eq!(
            given.indices, other.indices,
            "clustered leaves depend on the order"
        );
    }

    #[test]
    fn parallel_build_is_deterministic() {
        let params = FiberParams {
            count: 20_000,
            ..FiberParams::default()
        };
        let boxes = fiber_boxes(&params, 1);
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| (Bvh::build(&boxes), Bvh::build_clustered_from(&boxes, 64)));
        let two = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap()
            .install(|| (Bvh::build(&boxes), Bvh::build_clustered_from(&boxes, 64)));
        for (one, two) in [(&one.0, &two.0), (&one.1, &two.1)] {
            assert_eq!(one.nodes, two.nodes, "nodes differ between 1 and 2 threads");
            assert_eq!(
                one.indices, two.indices,
                "indices differ between 1 and 2 threads"
            );
        }
    }
}
