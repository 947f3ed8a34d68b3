//! A cheap ray-space test that rejects most cylinders a ray misses before the exact solver.
//!
//! Cylinders enter the BVH as [`Piece`]s of their axis, each with a tight box
//! ([`piece_bounds`]); a ray that reaches a piece's box is then tested against the piece here.
//!
//! Project along the ray onto the plane perpendicular to it, with the ray's origin at `0`:
//! the ray is the point `0`, and the distance from a point `x` to the ray's line is
//! `|proj(x)|`. The solid lies within `R` ([`reach_on`]) of its axis
//! curve (side and caps alike), and the curve within the convex hull of its control points,
//! so a hit `x` near `a(u)` gives `|proj(a(u))| <= |x - a(u)| <= R`: the projected hull comes
//! within `R` of `0`. If it does not, the ray misses. Likewise along the ray: a hit's depth
//! `z = t |d|` lies within `R` of the hull's depths, which must meet `(tmin, tmax)`. The whole
//! curve's hull is checked first, across the ray before its depths are projected (most pieces
//! that reach the test pass beside the ray), by the hull's box in the frame of its chord
//! before the finer tests; if that does not settle it, the halves' hulls (de Casteljau at
//! `u = 1/2`), which hug the curve closer, recursively a few times.

use std::ops::{Add, Mul};

use gencyl::{Aabb, GeneralizedCylinder, Ray, spline_bezier_near};
use glam::{DVec2, DVec3};

/// How many times the hull test halves the curve at most (pieces reach [`MAX_PIECE_LEVEL`]).
pub const MAX_LEVEL: u32 = 3;

/// How many times [`level_for`] halves a cylinder into BVH pieces at most (a quarter of the
/// axis). Eighths, as the hull test goes, cost the generated 1.6M-segment model a third of its
/// BVH build time and a tenth of its memory (fibers falling diagonally from a scalp are cut as
/// deep as allowed) without measurably faster rays there or on the ponytail.
pub const MAX_PIECE_LEVEL: u32 = 2;
const _: () = assert!(
    MAX_PIECE_LEVEL <= MAX_LEVEL,
    "pieces within the hull test's levels"
);

/// A piece of a cylinder's axis, `u in [j / 2^l, (j + 1) / 2^l]`, named by its heap index
/// `2^l + j` (`1` is the whole axis, `2` and `3` its halves, ...), `l <= MAX_LEVEL`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Piece(pub u32);

impl Piece {
    /// The whole axis.
    pub const WHOLE: Piece = Piece(1);

    /// How many halvings deep: `l`.
    pub fn level(self) -> u32 {
        31 - self.0.leading_zeros()
    }

    /// The piece's `u` range.
    pub fn range(self) -> (f64, f64) {
        let l = self.level();
        let j = self.0 - (1 << l);
        let w = 1.0 / (1u32 << l) as f64;
        (j as f64 * w, (j + 1) as f64 * w)
    }

    /// The pieces of level `l`, in order.
    pub fn level_pieces(l: u32) -> impl Iterator<Item = Piece> {
        ((1u32 << l)..(2u32 << l)).map(Piece)
    }

    /// The control points of the piece of the cubic Bezier curve with control points `q`:
    /// halving (de Casteljau at `1/2`, exact up to rounding) down the piece's path.
    pub fn sub_bezier<T: Copy + Add<Output = T> + Mul<f64, Output = T>>(
        self,
        mut q: [T; 4],
    ) -> [T; 4] {
        for bit in (0..self.level()).rev() {
            let [a, b] = halves(&q);
            q = if self.0 >> bit & 1 == 0 { a } else { b };
        }
        q
    }
}

/// The two halves of a cubic Bezier curve (de Casteljau at `u = 1/2`).
#[inline]
fn halves<T: Copy + Add<Output = T> + Mul<f64, Output = T>>(q: &[T; 4]) -> [[T; 4]; 2] {
    let m01 = (q[0] + q[1]) * 0.5;
    let m12 = (q[1] + q[2]) * 0.5;
    let m23 = (q[2] + q[3]) * 0.5;
    let a = (m01 + m12) * 0.5;
    let b = (m12 + m23) * 0.5;
    let mid = (a + b) * 0.5;
    [[q[0], m01, a, mid], [mid, b, m23, q[3]]]
}

/// `R` over a piece of the axis (the whole axis: [`Piece::WHOLE`]): the solid's part over the
/// piece lies within this distance of the axis curve there, the rule's largest stretch on the
/// piece times the section's `bounding_radius` (the surface point is `a(u)` plus an offset of
/// at most that length in the normal plane; caps are sections too). The rule's stretch is
/// bounded by a linear function of `u` ([`gencyl::SweepRule::scale_bound`]), so its larger end value
/// on the piece bounds it there.
pub fn reach_on(c: &GeneralizedCylinder, piece: Piece) -> f64 {
    piece_reach(c.reach_ends(), piece)
}

/// [`reach_on`] from the cylinder's [`GeneralizedCylinder::reach_ends`] `[R0, R1]`: the larger
/// of `R0 + (R1 - R0) u` at the piece's ends.
#[inline]
fn piece_reach([r0, r1]: [f64; 2], piece: Piece) -> f64 {
    let (u0, u1) = piece.range();
    max(r0 + (r1 - r0) * u0, r0 + (r1 - r0) * u1)
}

/// The larger of `a` and `b`, neither NaN: a single comparison, where [`f64::max`] also sorts
/// out NaNs (the same value otherwise, but for which of `0` and `-0`).
#[inline]
fn max(a: f64, b: f64) -> f64 {
    if a > b { a } else { b }
}

/// The smaller of `a` and `b`, neither NaN (as [`max`]).
#[inline]
fn min(a: f64, b: f64) -> f64 {
    if a < b { a } else { b }
}

/// How finely to cut a cylinder into BVH pieces, as a level `l` (`2^l` pieces), at most
/// [`MAX_PIECE_LEVEL`]: halve while halving shrinks the pieces' boxes, by their total half
/// surface area (what the SAH charges a ray for), to at most [`SPLIT_GAIN`] of what it was. A
/// fiber along a coordinate axis keeps one box (its halves' boxes add up to the same area); a
/// diagonal or curved one is cut until its boxes hug it. The boxes judged are those of the
/// pieces' control points grown by their reach ([`hull_areas`]), cheaper than the exact ones.
pub fn level_for(c: &GeneralizedCylinder) -> u32 {
    let areas = hull_areas(c);
    let mut level = 0;
    while level < MAX_PIECE_LEVEL && areas[level as usize + 1] <= SPLIT_GAIN * areas[level as usize]
    {
        level += 1;
    }
    level
}

/// [`level_for`] halves while the pieces' total box area falls to at most this fraction.
pub const SPLIT_GAIN: f64 = 0.75;

/// For each level `l` up to [`MAX_PIECE_LEVEL`], the total half surface area of the boxes of
/// the level's pieces' control points, each grown by the piece's reach.
pub fn hull_areas(c: &GeneralizedCylinder) -> [f64; MAX_PIECE_LEVEL as usize + 1] {
    fn down(
        reach: [f64; 2],
        piece: Piece,
        q: [DVec3; 4],
        areas: &mut [f64; MAX_PIECE_LEVEL as usize + 1],
    ) {
        let lo = q.iter().fold(DVec3::INFINITY, |m, p| m.min(*p));
        let hi = q.iter().fold(DVec3::NEG_INFINITY, |m, p| m.max(*p));
        let e = hi - lo + DVec3::splat(2.0 * piece_reach(reach, piece));
        areas[piece.level() as usize] += e.x * e.y + e.y * e.z + e.z * e.x;
        if piece.level() < MAX_PIECE_LEVEL {
            let [a, b] = halves(&q);
            down(reach, Piece(2 * piece.0), a, areas);
            down(reach, Piece(2 * piece.0 + 1), b, areas);
        }
    }
    let mut areas = [0.0; MAX_PIECE_LEVEL as usize + 1];
    down(c.reach_ends(), Piece::WHOLE, c.axis().points, &mut areas);
    areas
}

/// A tight box of a piece of a cylinder: the piece of the axis curve's exact box (from the
/// roots of `a'`), grown by [`reach_on`]. Never looser than the cylinder's own
/// [`GeneralizedCylinder::bounds`], which grows the control points' box.
pub fn piece_bounds(c: &GeneralizedCylinder, piece: Piece) -> Aabb {
    PieceBounds::of(c).bezier(piece, piece.sub_bezier(c.axis().points))
}

/// [`piece_bounds`] of every piece of level `level` under `piece`
/// (`2^(level - piece.level())` of them, in order), handed to `each`: the halvings down to them
/// are shared, and each piece's control points are the same as [`Piece::sub_bezier`]'s, and so
/// is its box.
pub fn pieces_bounds_under(
    c: &GeneralizedCylinder,
    piece: Piece,
    level: u32,
    each: &mut impl FnMut(Piece, Aabb),
) {
    fn down(
        bounds: &PieceBounds,
        piece: Piece,
        q: [DVec3; 4],
        level: u32,
        each: &mut impl FnMut(Piece, Aabb),
    ) {
        if piece.level() >= level {
            each(piece, bounds.bezier(piece, q));
            return;
        }
        let [a, b] = halves(&q);
        down(bounds, Piece(2 * piece.0), a, level, each);
        down(bounds, Piece(2 * piece.0 + 1), b, level, each);
    }
    let axis = c.axis().points;
    down(
        &PieceBounds::of(c),
        piece,
        piece.sub_bezier(axis),
        level,
        each,
    );
}

/// What bounding a cylinder's pieces takes from the cylinder, computed once for all of them.
struct PieceBounds {
    /// [`GeneralizedCylinder::reach_ends`].
    reach: [f64; 2],
    /// [`GeneralizedCylinder::bounds`].
    own: Aabb,
}

impl PieceBounds {
    fn of(c: &GeneralizedCylinder) -> Self {
        PieceBounds {
            reach: c.reach_ends(),
            own: c.bounds(),
        }
    }

    /// The box of `piece`, whose axis control points are `p`: the end points' box, widened on
    /// each axis `k` to the curve's values where `a'(u)_k` vanishes inside `(0, 1)`.
    /// `a'(u)_k` is the Bernstein quadratic `3 (h0 (1-u)^2 + 2 h1 u (1-u) + h2 u^2)`,
    /// `h_i = p_{i+1} - p_i`; where the three `h_i` have one strict sign it has none there (the
    /// hull property: it lies between the least and the greatest), and the coordinate is
    /// monotone (most axes of most hair pieces; a rounded difference keeps the true one's
    /// sign).
    fn bezier(&self, piece: Piece, p: [DVec3; 4]) -> Aabb {
        let mut lo = p[0].min(p[3]);
        let mut hi = p[0].max(p[3]);
        let h = [p[1] - p[0], p[2] - p[1], p[3] - p[2]];
        for k in 0..3 {
            let (h0, h1, h2) = (h[0][k], h[1][k], h[2][k]);
            if (h0 > 0.0 && h1 > 0.0 && h2 > 0.0) || (h0 < 0.0 && h1 < 0.0 && h2 < 0.0) {
                continue;
            }
            let a = h0 - 2.0 * h1 + h2;
            let b = 2.0 * (h1 - h0);
            let mut roots = [f64::NAN; 2];
            if a.abs() <= 1e-12 * (h0.abs() + h1.abs() + h2.abs()) {
                if b != 0.0 {
                    roots[0] = -h0 / b;
                }
            } else {
                let disc = b * b - 4.0 * a * h0;
                if disc >= 0.0 {
                    let q = -0.5 * (b + b.signum() * disc.sqrt());
                    roots = [q / a, if q != 0.0 { h0 / q } else { f64::NAN }];
                }
            }
            for u in roots {
                if u > 0.0 && u < 1.0 {
                    let v = 1.0 - u;
                    let x = v * v * v * p[0][k]
                        + 3.0 * u * v * (v * p[1][k] + u * p[2][k])
                        + u * u * u * p[3][k];
                    lo[k] = lo[k].min(x);
                    hi[k] = hi[k].max(x);
                }
            }
        }
        // Pad for rounding in the halving and the evaluation (relative to the coordinates).
        let pad = piece_reach(self.reach, piece)
            + 1e-12 * (hi - lo).max_element()
            + 64.0 * f64::EPSILON * lo.abs().max(hi.abs()).max_element();
        Aabb {
            min: (lo - DVec3::splat(pad)).max(self.own.min),
            max: (hi + DVec3::splat(pad)).min(self.own.max),
        }
    }
}

/// A ray's frame for projecting: its origin, the unit direction and two unit vectors
/// perpendicular to it.
#[derive(Clone, Copy, Debug)]
pub struct RaySpace {
    origin: DVec3,
    /// `|o|` in its largest coordinate: a part of [`Self::may_hit_axis_piece`]'s rounding
    /// margin, the same for every piece.
    origin_far: f64,
    e0: DVec3,
    e1: DVec3,
    e2: DVec3,
    /// `|d|`: the distance along the ray per unit of `t`.
    len: f64,
}

impl RaySpace {
    /// The frame of `ray` (whose direction must be finite and non-zero).
    pub fn new(ray: &Ray) -> Self {
        let len = ray.dir.length();
        let e0 = ray.dir.normalize_or(DVec3::Z);
        let (e1, e2) = e0.any_orthonormal_pair();
        RaySpace {
            origin: ray.origin,
            origin_far: ray.origin.abs().max_element(),
            e0,
            e1,
            e2,
            len,
        }
    }

    /// Whether the ray may hit the cylinder with `tmin < t < tmax`: `false` means it surely
    /// does not.
    pub fn may_hit(&self, c: &GeneralizedCylinder, tmin: f64, tmax: f64) -> bool {
        self.may_hit_piece(c, Piece::WHOLE, tmin, tmax)
    }

    /// Whether the ray may hit the part of the cylinder within [`reach_on`] of the axis piece
    /// with `tmin < t < tmax`: `false` means it surely does not.
    pub fn may_hit_piece(
        &self,
        c: &GeneralizedCylinder,
        piece: Piece,
        tmin: f64,
        tmax: f64,
    ) -> bool {
        self.may_hit_axis_piece(&c.axis().points, c.reach_ends(), piece, tmin, tmax)
    }

    /// [`Self::may_hit_piece`] from the cylinder's axis in world coordinates
    /// ([`GeneralizedCylinder::axis`]) and its [`GeneralizedCylinder::reach_ends`], as
    /// [`gencyl::PackedCylinders::axis_and_reach`] gives them without rebuilding the cylinder.
    #[inline]
    pub fn may_hit_axis_piece(
        &self,
        p: &[DVec3; 4],
        reach_ends: [f64; 2],
        piece: Piece,
        tmin: f64,
        tmax: f64,
    ) -> bool {
        self.may_hit_axis_controls(p, false, reach_ends, piece, tmin, tmax)
    }

    /// [`Self::may_hit_axis_piece`] from [`gencyl::PackedCylinders::with_axis_controls`]:
    /// the axis's Bezier points `p`, or where `spline`, a strand's B-spline control points,
    /// whose segment's Bezier points are [`gencyl::spline_bezier_near`] of them.
    ///
    /// The points are projected first and converted after (the conversion's weights are
    /// non-negative of sum `1`, so it commutes with the projection, an affine map, in exact
    /// arithmetic), in the plane across the ray and along it only where that does not settle
    /// it. The margins hold for either order: the control points `w` lie within `size` (their
    /// largest coordinate of `w - o`) of the origin, and so do the Bezier points, their convex
    /// combinations; each projected coordinate (three products and sums of a coordinate
    /// within `size` with a unit vector's) is within `4 eps sqrt(3) size` of the exact
    /// projection of the rounded difference, itself within `eps |w - o|`, and the conversion
    /// (non-negative weights of sum `1`) adds `4 eps` of the largest projected control: in all
    /// a few dozen `eps size`, far inside the `1e-9 size` of the margin. The Bezier points of
    /// the rebuilt cylinder are within a few `eps` of the coordinates (of `|w|` at most, `w`
    /// being within `|o| + size` of `0`) of the exact conversion of `w`: inside the `8 eps
    /// far` of the margin, with `far = |o| + size`.
    #[inline]
    pub fn may_hit_axis_controls(
        &self,
        p: &[DVec3; 4],
        spline: bool,
        reach_ends: [f64; 2],
        piece: Piece,
        tmin: f64,
        tmax: f64,
    ) -> bool {
        let rel = p.map(|x| x - self.origin);
        // Rounding of the projection is about eps |p - o| per coordinate: widen by far more.
        // The points themselves may be off the axis by a few units in their last place (world
        // points of a packed cylinder): widen by 8 eps |p| for that, with `|p| <= |o| + |p - o|`
        // (in the largest coordinate).
        let size = (rel[0].abs().max(rel[1].abs()))
            .max(rel[2].abs().max(rel[3].abs()))
            .max_element();
        let far = self.origin_far + size;
        let reach =
            piece_reach(reach_ends, piece) * (1.0 + 1e-9) + 1e-9 * size + 8.0 * f64::EPSILON * far;
        // Across the ray first: most pieces that get here pass beside it, and need no depths.
        let across = rel.map(|x| DVec2::new(x.dot(self.e1), x.dot(self.e2)));
        let across = piece.sub_bezier(if spline {
            spline_bezier_near(across)
        } else {
            across
        });
        let first = within(&across, reach);
        if first == Reach::Beyond {
            return false;
        }
        let depth = rel.map(|x| x.dot(self.e0));
        let depth = piece.sub_bezier(if spline {
            spline_bezier_near(depth)
        } else {
            depth
        });
        let q = std::array::from_fn(|i| across[i].extend(depth[i]));
        // A hit x within R of a(u) has z(x) within R of z(a(u)), and t = z(x) / |d|.
        let (zmin, zmax) = (tmin * self.len, tmax * self.len);
        let zmin = zmin - reach - 1e-9 * zmin.abs();
        let zmax = zmax + reach + 1e-9 * zmax.abs();
        piece_may_hit(
            &q,
            reach,
            zmin,
            zmax,
            MAX_LEVEL.saturating_sub(piece.level()),
            Some(first),
        )
    }
}

/// Whether the ray (the origin of the projection, between depths `zmin` and `zmax`) comes
/// within `reach` of the hull of the projected Bezier points `q`, or of one of its halves'
/// hulls, recursively `depth` times (`across`: [`within`] of `q` where the caller has it).
/// Where the curve itself comes within reach and all of the hull lies between the depths, no
/// half can be cleared: the halving stops there.
fn piece_may_hit(
    q: &[DVec3; 4],
    reach: f64,
    zmin: f64,
    zmax: f64,
    depth: u32,
    across: Option<Reach>,
) -> bool {
    let (lo, hi) = q
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p.z), hi.max(p.z))
        });
    if lo > zmax || hi < zmin {
        return false;
    }
    match across.unwrap_or_else(|| within(&q.map(|p| p.truncate()), reach)) {
        Reach::Beyond => return false,
        Reach::Curve if lo >= zmin && hi <= zmax => return true,
        _ => {}
    }
    if depth == 0 {
        return true;
    }
    let [a, b] = halves(q);
    piece_may_hit(&a, reach, zmin, zmax, depth - 1, None)
        || piece_may_hit(&b, reach, zmin, zmax, depth - 1, None)
}

/// How near the origin a Bezier curve's convex hull comes ([`within`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Reach {
    /// The hull stays beyond reach.
    Beyond,
    /// The hull comes within reach (the curve may not).
    Hull,
    /// The curve itself comes within reach.
    Curve,
}

/// How near the origin the convex hull of `q`, and the curve, come: [`Reach`].
#[inline(always)]
fn within(q: &[DVec2; 4], reach: f64) -> Reach {
    let r2 = reach * reach;
    // Quick accept: an end (a point of the curve) within reach.
    if q[0].length_squared() <= r2 || q[3].length_squared() <= r2 {
        return Reach::Curve;
    }
    // The hull in the chord's frame (a fat line, and its ends): with `e = q3 - q0`, a point's
    // offsets from `q0` across the chord, `(x - q0) x e`, and along it, `(x - q0).e`, are
    // linear, so over the hull they lie between their least and largest values at the four
    // points (`0` at `q0`; `0` and `|e|^2` at `q3`). Where the origin's offsets, `-q0 x e` and
    // `-q0.e`, lie more than `reach |e|` outside either range, the hull stays beyond reach
    // (offsets over `|e|` are distances, or less). Their rounding is a few units of `|q| |e|`,
    // far inside `reach`'s margin of `1e-9` of the coordinates.
    let e = q[3] - q[0];
    let len2 = e.length_squared();
    if len2 > 0.0 {
        let band = reach * len2.sqrt();
        let (d1, d2) = (q[1] - q[0], q[2] - q[0]);
        let (c0, c1, c2) = (e.perp_dot(q[0]), d1.perp_dot(e), d2.perp_dot(e));
        let (a0, a1, a2) = (-q[0].dot(e), d1.dot(e), d2.dot(e));
        // (The points are finite: no NaNs.)
        if c0 > max(max(c1, c2), 0.0) + band
            || c0 < min(min(c1, c2), 0.0) - band
            || a0 > max(max(a1, a2), len2) + band
            || a0 < min(min(a1, a2), 0.0) - band
        {
            return Reach::Beyond;
        }
    }
    // Every hull point lies within `dev` of the chord `q0 q3` (the distance to a segment is
    // convex, so its largest value on the hull is at a corner: 0 at the chord's ends, at most
    // `dev` at the inner points). So the hull stays beyond reach when the chord does by more
    // than `dev`. Conversely the curve runs from `q0` to `q3`, so it crosses the line across
    // the chord through the chord's point nearest the origin, at a point within `dev` of the
    // chord, within `dev` of that point: the curve comes within reach when the chord comes
    // within `reach - dev`.
    let dev2 =
        segment_distance2_from(q[1], q[0], q[3]).max(segment_distance2_from(q[2], q[0], q[3]));
    let chord2 = segment_distance2(q[0], q[3]);
    let (chord, dev) = (chord2.sqrt(), dev2.sqrt());
    if chord2 > r2 && chord - dev > reach {
        return Reach::Beyond;
    }
    if chord + dev <= reach {
        return Reach::Curve;
    }
    // The hull is the union of the four triangles of the points; outside it, the nearest
    // hull point lies on one of the six segments between the points.
    const TRIS: [[usize; 3]; 4] = [[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]];
    let inner = q[1].length_squared() <= r2 || q[2].length_squared() <= r2;
    const SEGS: [[usize; 2]; 6] = [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]];
    if inner
        || TRIS.iter().any(|t| in_triangle(q[t[0]], q[t[1]], q[t[2]]))
        || SEGS
            .iter()
            .any(|s| segment_distance2(q[s[0]], q[s[1]]) <= r2)
    {
        Reach::Hull
    } else {
        Reach::Beyond
    }
}

/// Whether the origin lies in the closed triangle `a b c` (of either orientation).
#[inline]
fn in_triangle(a: DVec2, b: DVec2, c: DVec2) -> bool {
    let (s1, s2, s3) = (a.perp_dot(b), b.perp_dot(c), c.perp_dot(a));
    (s1 >= 0.0 && s2 >= 0.0 && s3 >= 0.0) || (s1 <= 0.0 && s2 <= 0.0 && s3 <= 0.0)
}

/// The squared distance from `p` to the segment `a b`.
#[inline]
fn segment_distance2_from(p: DVec2, a: DVec2, b: DVec2) -> f64 {
    segment_distance2(a - p, b - p)
}

/// The squared distance from the origin to the segment `a b`.
#[inline]
fn segment_distance2(a: DVec2, b: DVec2) -> f64 {
    let ab = b - a;
    let len2 = ab.length_squared();
    let s = if len2 > 0.0 {
        (-a.dot(ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (a + s * ab).length_squared()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::SampleRng as Rng;
    use crate::scenes::synth::{FiberParams, random_fibers};

    #[test]
    fn never_rejects_a_ray_through_the_surface() {
        // Planted answers: rays through surface points from random directions.
        let specs = random_fibers(
            &FiberParams {
                count: 40,
                elliptical_fraction: 0.4,
                profile_fraction: 0.3,
                ..Default::default()
            },
            4,
        );
        let mut rng = Rng::from_seed(8);
        let mut rejected_misses = 0;
        for spec in &specs {
            let c = spec.build().unwrap();
            for _ in 0..200 {
                let p = c.surface_point(rng.uniform(), rng.range(0.0, std::f64::consts::TAU));
                let d = rng.unit_vector() * rng.range(0.1, 10.0);
                let ray = Ray::new(p - rng.range(-3.0, 3.0) * d, d);
                assert!(
                    RaySpace::new(&ray).may_hit(&c, f64::NEG_INFINITY, f64::INFINITY),
                    "rejected {ray:?} through {p} of {spec:?}"
                );
                // The parallel ray offset far to the side misses.
                let side = d.any_orthonormal_vector() * 0.5;
                if !RaySpace::new(&Ray::new(ray.origin + side, d)).may_hit(
                    &c,
                    f64::NEG_INFINITY,
                    f64::INFINITY,
                ) {
                    rejected_misses += 1;
                }
            }
        }
        assert!(
            rejected_misses > 2000,
            "the cull should reject most far misses: {rejected_misses} of 8000"
        );
    }

    /// Straight fibers of 100 radii: one along an axis keeps one box (halving it saves no
    /// area), a diagonal one is cut to the deepest level (each halving nearly halves the
    /// area), and a stub of two radii keeps one box (the radius fills it).
    #[test]
    fn fibers_are_cut_where_cutting_tightens_their_boxes() {
        let line = |d: DVec3| [0.0, 1.0, 2.0, 3.0].map(|s| d * s);
        let level = |d: DVec3| {
            let c = gencyl::FiberSpec::round(line(d), 0.01).build().unwrap();
            level_for(&c)
        };
        assert_eq!(level(DVec3::X / 3.0), 0, "along x");
        assert_eq!(level(DVec3::Z / 3.0), 0, "along z");
        assert_eq!(level(DVec3::ONE / 3.0), MAX_PIECE_LEVEL, "diagonal");
        assert_eq!(
            level(DVec3::new(1.0, 1.0, 0.0) / 3.0),
            MAX_PIECE_LEVEL,
            "diagonal in a plane"
        );
        assert_eq!(level(DVec3::ONE * 0.02 / 3.0), 0, "stub");
        // The areas judged, against the pieces' own (exact) boxes: a diagonal line's control
        // points lie on it, so its pieces' boxes are theirs; each halving cut the area to
        // SPLIT_GAIN of the level before.
        let c = gencyl::FiberSpec::round(line(DVec3::ONE / 3.0), 0.01)
            .build()
            .unwrap();
        let areas = hull_areas(&c);
        for l in 0..=MAX_PIECE_LEVEL {
            let mut exact = 0.0;
            pieces_bounds_under(&c, Piece::WHOLE, l, &mut |_, b| {
                let e = b.max - b.min;
                exact += e.x * e.y + e.y * e.z + e.z * e.x;
            });
            let a = areas[l as usize];
            assert!(
                (a - exact).abs() <= 1e-9 * exact,
                "level {l}: {a} vs {exact}"
            );
            if l > 0 {
                assert!(a <= SPLIT_GAIN * areas[l as usize - 1], "level {l}");
            }
        }
    }

    #[test]
    fn pieces_cover_the_axis() {
        assert_eq!(Piece(1).range(), (0.0, 1.0), "whole");
        assert_eq!(Piece(3).range(), (0.5, 1.0), "second half");
        assert_eq!(Piece(13).range(), (0.625, 0.75), "level 3, j = 5");
        let q = [
            DVec3::ZERO,
            DVec3::new(1.0, 2.0, 0.0),
            DVec3::new(2.0, -1.0, 1.0),
            DVec3::new(3.0, 0.0, 0.0),
        ];
        let c = gencyl::CubicBezier::new(q);
        for l in 0..=MAX_LEVEL {
            for piece in Piece::level_pieces(l) {
                let (u0, u1) = piece.range();
                let sub = gencyl::CubicBezier::new(piece.sub_bezier(q));
                for i in 0..=4 {
                    let s = i as f64 / 4.0;
                    let d = (sub.point(s) - c.point(u0 + s * (u1 - u0))).length();
                    assert!(d < 1e-14, "piece {piece:?} at {s}: {d}");
                }
            }
        }
    }

    #[test]
    fn piece_bounds_hold_the_surface() {
        let fibers = random_fibers(
            &FiberParams {
                count: 50,
                elliptical_fraction: 0.4,
                profile_fraction: 0.3,
                ..FiberParams::default()
            },
            3,
        );
        for spec in fibers {
            let c = spec.build().unwrap();
            for l in 0..=MAX_LEVEL {
                for piece in Piece::level_pieces(l) {
                    let b = piece_bounds(&c, piece);
                    let own = c.bounds();
                    assert!(
                        b.min.cmpge(own.min).all() && b.max.cmple(own.max).all(),
                        "not within own box: {spec:?}"
                    );
                    let (u0, u1) = piece.range();
                    for i in 0..=10 {
                        for j in 0..16 {
                            let u = u0 + (u1 - u0) * i as f64 / 10.0;
                            let p = c.surface_point(u, j as f64 * std::f64::consts::TAU / 16.0);
                            assert!(b.contains(p), "{p} outside {b:?} for {piece:?} of {spec:?}");
                        }
                    }
                }
            }
        }
    }

    /// The shared halvings give each piece the box it has alone, to the bit.
    #[test]
    fn pieces_under_a_piece_have_their_own_boxes() {
        for spec in random_fibers(&FiberParams::default(), 8).iter().take(30) {
            let c = spec.build().unwrap();
            for l in 0..=MAX_LEVEL {
                for top in (0..=l).flat_map(Piece::level_pieces) {
                    let mut seen = vec![];
                    pieces_bounds_under(&c, top, l, &mut |p, b| seen.push((p, b)));
                    let want: Vec<(Piece, Aabb)> = Piece::level_pieces(l)
                        .filter(|p| p.0 >> (l - top.level()) == top.0)
                        .map(|p| (p, piece_bounds(&c, p)))
                        .collect();
                    assert_eq!(seen, want, "pieces of level {l} under {top:?}");
                }
            }
        }
    }

    #[test]
    fn pieces_never_reject_a_ray_through_their_surface() {
        let specs = random_fibers(
            &FiberParams {
                count: 20,
                elliptical_fraction: 0.4,
                profile_fraction: 0.3,
                ..Default::default()
            },
            6,
        );
        let mut rng = Rng::from_seed(9);
        for spec in &specs {
            let c = spec.build().unwrap();
            for l in 0..=MAX_LEVEL {
                for piece in Piece::level_pieces(l) {
                    let (u0, u1) = piece.range();
                    for _ in 0..20 {
                        let p = c.surface_point(
                            rng.range(u0, u1),
                            rng.range(0.0, std::f64::consts::TAU),
                        );
                        let d = rng.unit_vector() * rng.range(0.1, 10.0);
                        let t = rng.range(-3.0, 3.0);
                        let ray = Ray::new(p - t * d, d);
                        let space = RaySpace::new(&ray);
                        assert!(
                            space.may_hit_piece(&c, piece, t - 1e-9, t + 1e-9),
                            "rejected {ray:?} at t = {t} through {p} of {piece:?} of {spec:?}"
                        );
                    }
                }
            }
        }
    }

    /// A strand's segment handed over as its B-spline control points (converted after the
    /// projection) never makes the cull reject a ray through the segment's surface, near the
    /// origin or far from it, radii `1e-6` to `1e-1` of the length, every other ray tangent to
    /// the surface there (a graze at depth 0).
    #[test]
    fn spline_controls_never_reject_a_ray_through_the_surface() {
        let mut rng = Rng::from_seed(29);
        let mut built = 0;
        for i in 0..300 {
            let at = DVec3::splat([0.0, 1e4, -3.3e5][i % 3]);
            // Hair-like: controls along a direction, bent a little.
            let (dir, len) = (rng.unit_vector(), rng.range(0.1, 2.0));
            let w: [DVec3; 4] = std::array::from_fn(|k| {
                at + dir * (k as f64 * len) + rng.unit_vector() * (0.2 * len)
            });
            let r = len * 10f64.powf(rng.range(-6.0, -1.0));
            let Ok(c) = gencyl::FiberSpec::round(gencyl::spline_segment(w).points, r).build()
            else {
                continue;
            };
            built += 1;
            for l in 0..=MAX_LEVEL {
                for piece in Piece::level_pieces(l) {
                    let (u0, u1) = piece.range();
                    let (u, v) = (rng.range(u0, u1), rng.range(0.0, std::f64::consts::TAU));
                    let p = c.surface_point(u, v);
                    let d = rng.unit_vector() * rng.range(0.1, 10.0);
                    let tangent = d.cross(c.normal(u, v));
                    let d = if rng.uniform() < 0.5 || tangent.length() < 1e-3 * d.length() {
                        d
                    } else {
                        tangent
                    };
                    let t = rng.range(-3.0, 3.0);
                    let ray = Ray::new(p - t * d, d);
                    assert!(
                        RaySpace::new(&ray).may_hit_axis_controls(
                            &w,
                            true,
                            c.reach_ends(),
                            piece,
                            t - 1e-9,
                            t + 1e-9
                        ),
                        "rejected {ray:?} at t = {t} through {p} of {piece:?} of {w:?}"
                    );
                }
            }
        }
        assert!(built > 200, "{built} segments built");
    }

    /// [`within`] says the curve comes within reach only where it does, and the hull stays
    /// beyond reach only where the curve does: against the curve's least distance from the
    /// origin (the best of 400 samples, refined by golden-section search about it), for
    /// projected cubics, straight, bent and looped, whose chord passes the origin at `m`, with
    /// reaches from 1e-9 to 10 times `m`, and within 1e-12 to 1e-1 of it either way.
    #[test]
    fn reach_of_a_curve_is_classified_by_its_points() {
        let mut rng = Rng::from_seed(19);
        let mut seen = [0; 3];
        for case in 0..20_000 {
            let bend = [0.0, 0.05, 0.5, 2.0][case % 4];
            let dir = DVec2::from_angle(rng.range(0.0, std::f64::consts::TAU));
            let across = dir.perp();
            let miss = rng.range(-3.0, 3.0);
            let q: [DVec2; 4] = std::array::from_fn(|j| {
                let along = (j as f64 / 3.0 - rng.range(0.2, 0.8)) * 2.0;
                let off = if j == 0 || j == 3 {
                    0.0
                } else {
                    bend * rng.range(-1.0, 1.0)
                };
                dir * along + across * (miss + off)
            });
            let reach = if case % 3 == 0 {
                miss.abs() * (1.0 + rng.range(-1.0, 1.0) * 10f64.powf(rng.range(-12.0, -1.0)))
            } else {
                miss.abs() * 10f64.powf(rng.range(-9.0, 1.0))
            };
            let dist = |u: f64| {
                let v = 1.0 - u;
                (q[0] * (v * v * v)
                    + q[1] * (3.0 * v * v * u)
                    + q[2] * (3.0 * v * u * u)
                    + q[3] * (u * u * u))
                    .length()
            };
            let best = (0..=400)
                .map(|i| i as f64 / 400.0)
                .min_by(|&a, &b| dist(a).total_cmp(&dist(b)))
                .unwrap();
            let (mut a, mut b) = ((best - 1.0 / 400.0).max(0.0), (best + 1.0 / 400.0).min(1.0));
            let g = 0.5 * (5f64.sqrt() - 1.0);
            for _ in 0..80 {
                let (c, d) = (b - g * (b - a), a + g * (b - a));
                if dist(c) < dist(d) { b = d } else { a = c }
            }
            let nearest = dist(0.5 * (a + b)).min(dist(best));
            let class = within(&q, reach);
            seen[class as usize] += 1;
            match class {
                Reach::Curve => assert!(
                    nearest <= reach * (1.0 + 1e-9),
                    "case {case}: said the curve comes within {reach}, it comes to {nearest}"
                ),
                Reach::Beyond => assert!(
                    nearest > reach * (1.0 - 1e-9),
                    "case {case}: said beyond {reach}, the curve comes to {nearest}"
                ),
                Reach::Hull => {}
            }
        }
        assert!(
            seen.iter().all(|&n| n > 1000),
            "{seen:?} beyond, hull, curve"
        );
    }

    /// Axis points a few units in their last place off (as a packed cylinder's world points
    /// may be) never make the cull reject a ray that passes inside the fiber: short fibers at
    /// 1e4 and 1e6 from the origin, radii from 1e-6 to 1e-2 of their length, rays grazing
    /// 1e-9 of the radius deep from points on the surface.
    #[test]
    fn points_off_in_their_last_place_never_reject_a_hit() {
        let mut rng = Rng::from_seed(23);
        for i in 0..4000 {
            let at = DVec3::splat([1e4, -1e6, 3.3e5, 1.0][i % 4]);
            let length = 10f64.powf(rng.range(-4.0, 0.0));
            let dir = rng.unit_vector();
            let bend = rng.unit_vector() * 0.2 * length;
            let axis = [0.0, 1.0, 2.0, 3.0]
                .map(|k| at + (dir * k + bend * (k * (3.0 - k))) * length / 3.0);
            let r = length * 10f64.powf(rng.range(-6.0, -2.0));
            let Ok(c) = gencyl::FiberSpec::round(axis, r).build() else {
                continue;
            };
            // A ray from a point of the surface, tangent to the section there, moved 1e-9 of
            // the radius inside: it passes within the radius of the axis.
            let u = rng.range(0.05, 0.95);
            let p = c.surface_point(u, rng.range(0.0, std::f64::consts::TAU));
            let centre = c.axis().point(u);
            let out = (p - centre).normalize();
            let along = c.frame(u).t.cross(out).normalize();
            let ray = Ray::new(p - out * (1e-9 * r), along);
            // Each coordinate moved by up to 3 units in its last place.
            let off = c.axis().points.map(|q| {
                DVec3::from_array(q.to_array().map(|x| {
                    let mut y = x;
                    for _ in 0..rng.range(0.0, 4.0) as usize {
                        y = if rng.uniform() < 0.5 {
                            y.next_up()
                        } else {
                            y.next_down()
                        };
                    }
                    y
                }))
            });
            assert!(
                RaySpace::new(&ray).may_hit_axis_piece(
                    &off,
                    c.reach_ends(),
                    Piece::WHOLE,
                    -1.0,
                    f64::INFINITY
                ),
                "rejected {ray:?} of {c:?}"
            );
        }
    }
}
