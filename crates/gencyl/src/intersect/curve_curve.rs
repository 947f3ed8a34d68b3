//! The general path (seed 2.3): intersect the plane curve `phi(u)` with the section `cs(v)` by
//! recursive subdivision into pieces with bounding boxes, until both pieces of a pair are
//! linear; then the chords' crossing, polished by Newton's method.
//!
//! The section's pieces are the seed's: split at its polynomial pieces' exact tangent and
//! inflection points, each is monotone and convex, so it lies in the box of its end points and
//! in the triangle of its chord and end tangents.
//!
//! `phi` is not split at features. Its tangent and inflection points are roots of functions
//! that no sampling can be sure to find: near an inflection of a nearly planar axis the Frenet
//! frame turns half round within `1e-6` of `u`, and `phi` with it, through several tangent
//! directions between two samples; a piece that is not monotone is not inside its end points'
//! box, and pairs holding roots were pruned. Instead each piece of `phi` carries a first-order
//! Taylor model of `phi` over its `u` range ([`Taylor`]): `phi(m + h t) = c + s t + r` with
//! `|t| <= 1`, `|r| <= rho` per coordinate, rounding included. Its enclosure is a box that holds the piece
//! whatever its shape, and `rho` bounds the piece's distance from a line, which is what the
//! linearity test needs. Both tighten as the pieces shrink (`rho` like the square of the
//! width), so the subdivision ends as before.
//!
//! The frame, and with it `phi`, may jump where [`frenet_shift`](crate::frame) switches (at an
//! inflection of a planar axis it turns by a half turn there: for a section that is not
//! point-symmetric the swept surface itself is discontinuous, see [`frenet_switches`](crate::frame::frenet_switches)); `phi`
//! is split there so that no model spans a jump.

use arrayvec::ArrayVec;
use glam::{DVec2, DVec3};

use crate::cylinder::GeneralizedCylinder;
use crate::real::{Dual, Real, Taylor, V2};
use crate::section::CrossSection;
use crate::sweep::SweepRule;

/// A piece is linear when the tangent-intersection point is within this distance of the chord
/// in the `(parameter, coordinate)` planes (seed 2.3 with errata 3) and, times the section's
/// bounding radius, the piece is within it of a line in the plane of the curves. The first
/// keeps the parameterisation close to uniform, so the chord intersection's parameters start
/// Newton's method near the root. The second is needed because the first is not scale
/// invariant: where `phi` moves fast in `u` (`|phi'|` near `1e6` close to a nearly planar
/// axis' inflection) every short piece passes it however much it bends.
const LINEARITY_EPS: f64 = 1e-3;
/// Subdivision depth cap: beyond it two pieces are treated as linear (a tangential contact).
/// Each level halves one piece of the pair (the seed halves both): 48 levels of both.
const MAX_DEPTH: u32 = 96;
/// Work bound of one call of [`roots`]: piece pairs visited. The test suite's fibers and rays
/// need at most about 8,000; past the bound every pair left is settled by its chords
/// (at most two per level of the recursion), and the search is counted as exhausted
/// ([`crate::budget`]).
const MAX_PAIRS: u32 = 1 << 16;

/// `phi(u)` alone (without `w`): `q phi / q`.
#[inline(always)]
fn phi_only<C: CrossSection, S: SweepRule, T: Real>(
    cyl: &GeneralizedCylinder<C, S>,
    o: DVec3,
    d: DVec3,
    u: T,
) -> V2<T> {
    let (qphi, q) = cyl.scaled_phi_r(o, d, u);
    V2::new(qphi.x / q, qphi.y / q)
}

/// A piece of a plane curve over `[s0, s1]`: end points, end derivatives, a box holding it and
/// a bound on its distance from its chord.
#[derive(Clone, Copy, Debug)]
struct Piece {
    s0: f64,
    s1: f64,
    p0: DVec2,
    p1: DVec2,
    d0: DVec2,
    d1: DVec2,
    /// Corners of a box holding the piece.
    lo: DVec2,
    hi: DVec2,
    /// A proven bound on the piece's distance from its chord; infinite for a monotone, convex
    /// piece, whose end tangents bound it ([`flatness`]).
    flat: f64,
    /// Set on the halves of a `phi` piece whose bound did not shrink when it was split: it is
    /// at the floor set by rounding, and the piece counts as linear ([`Intersector::split_phi`]).
    floor: bool,
}

trait PlaneCurve {
    /// Point and derivative at `s`.
    fn eval(&self, s: f64) -> (DVec2, DVec2);

    /// A box holding the curve over `[s0, s1]` and a bound on its distance from the chord
    /// `p0 p1` (infinite: [`flatness`] applies), given the end points. By default the end
    /// points' box, for pieces that are monotone in both coordinates.
    fn bounds(&self, _s0: f64, _s1: f64, p0: DVec2, p1: DVec2) -> (DVec2, DVec2, f64) {
        (p0.min(p1), p0.max(p1), f64::INFINITY)
    }

    fn piece(&self, s0: f64, s1: f64) -> Piece {
        let ((p0, d0), (p1, d1)) = (self.eval(s0), self.eval(s1));
        let (lo, hi, flat) = self.bounds(s0, s1, p0, p1);
        Piece {
            s0,
            s1,
            p0,
            p1,
            d0,
            d1,
            lo,
            hi,
            flat,
            floor: false,
        }
    }

    fn split(&self, p: &Piece) -> (Piece, Piece) {
        let m = 0.5 * (p.s0 + p.s1);
        let (pm, dm) = self.eval(m);
        let (lo0, hi0, flat0) = self.bounds(p.s0, m, p.p0, pm);
        let (lo1, hi1, flat1) = self.bounds(m, p.s1, pm, p.p1);
        (
            Piece {
                s1: m,
                p1: pm,
                d1: dm,
                lo: lo0,
                hi: hi0,
                flat: flat0,
                ..*p
            },
            Piece {
                s0: m,
                p0: pm,
                d0: dm,
                lo: lo1,
                hi: hi1,
                flat: flat1,
                ..*p
            },
        )
    }
}

struct PhiCurve<'a, C, S> {
    cyl: &'a GeneralizedCylinder<C, S>,
    o: DVec3,
    d: DVec3,
}

#[cfg(test)]
impl<C: CrossSection, S: SweepRule> PhiCurve<'_, C, S> {
    /// A bound on the rounding error of `phi(u)` in `f64`: the remainder of its Taylor model
    /// over the single point `u`.
    fn noise(&self, u: f64) -> f64 {
        let m = phi_only(self.cyl, self.o, self.d, Taylor::var(u, u));
        m.x.rho.hypot(m.y.rho)
    }
}

impl<C: CrossSection, S: SweepRule> PlaneCurve for PhiCurve<'_, C, S> {
    fn eval(&self, u: f64) -> (DVec2, DVec2) {
        let p = phi_only(self.cyl, self.o, self.d, Dual::var(u));
        (DVec2::new(p.x.v, p.y.v), DVec2::new(p.x.d, p.y.d))
    }

    /// From the Taylor model `c + s t + r`, `|t| <= 1`, `|r| <= rho` of `phi` over `[u0, u1]`:
    /// its enclosure, and twice `|rho|`: the piece is within `|rho|` of the line `c + s t`, and
    /// so is the chord's every point (its ends are points of the piece), so the piece is within
    /// `2 |rho|` of the chord. The box is cut down to the end points' box grown by `2 |rho|`
    /// along the line, which holds the piece too and is tighter where the model is wide.
    fn bounds(&self, u0: f64, u1: f64, p0: DVec2, p1: DVec2) -> (DVec2, DVec2, f64) {
        let m = phi_only(self.cyl, self.o, self.d, Taylor::var(u0, u1));
        let (ex, ey) = (m.x.enclosure(), m.y.enclosure());
        let flat = 2.0 * m.x.rho.hypot(m.y.rho);
        if !flat.is_finite() {
            // No model (phi is finite on the range, so only for a piece far too wide).
            return (DVec2::NEG_INFINITY, DVec2::INFINITY, f64::MAX);
        }
        (
            DVec2::new(ex.lo, ey.lo).max(p0.min(p1) - flat),
            DVec2::new(ex.hi, ey.hi).min(p0.max(p1) + flat),
            flat,
        )
    }
}

struct SectionCurve<'a, C>(&'a C);

impl<C: CrossSection> PlaneCurve for SectionCurve<'_, C> {
    fn eval(&self, v: f64) -> (DVec2, DVec2) {
        (self.0.point(v), self.0.derivative(v))
    }
}

/// Distance of the end tangents' intersection from the chord, for one coordinate seen as a
/// graph `x(s)` (seed 2.3, errata 3): the tangents meet at
/// `s* = (x0 - x1 + s1 x1' - s0 x0') / (x1' - x0')`, `x* = x0 + x0' (s* - s0)`, and the chord is
/// `(s1 - s0) x - (x1 - x0) s + (x1 - x0) s0 - x0 (s1 - s0) = 0`.
fn coordinate_deviation(s0: f64, s1: f64, x0: f64, x1: f64, dx0: f64, dx1: f64) -> f64 {
    let (ds, dx) = (s1 - s0, x1 - x0);
    let slope = dx / ds;
    let tol = 1e-12 * (1.0 + slope.abs());
    if (dx0 - slope).abs() <= tol && (dx1 - slope).abs() <= tol {
        return 0.0; // both tangents along the chord: the graph is a line
    }
    // When the tangents are (nearly) parallel, or meet outside the piece, the tangent point is
    // ill-conditioned; the vertical offset of the end tangents from the chord over the piece
    // still bounds the deviation: max |x_i' - slope| |ds| / sqrt(1 + slope^2).
    let fallback =
        (dx0 - slope).abs().max((dx1 - slope).abs()) * ds.abs() / (1.0 + slope * slope).sqrt();
    if dx1 == dx0 {
        return fallback;
    }
    let s_star = (x0 - x1 + s1 * dx1 - s0 * dx0) / (dx1 - dx0);
    if !(s_star >= s0 - 1e-12 * ds.abs() && s_star <= s1 + 1e-12 * ds.abs()) {
        return fallback;
    }
    let x_star = x0 + dx0 * (s_star - s0);
    (ds * x_star - dx * s_star + dx * s0 - x0 * ds).abs() / (ds * ds + dx * dx).sqrt()
}

/// A bound on the distance of a piece from its chord, in the plane of the curve: the proven
/// one it carries, or for a monotone, convex piece (a section piece), which turns by at most a
/// right angle and lies in the triangle of its chord and end tangents, the apex' height
/// `L tan(a0) tan(a1) / (tan(a0) + tan(a1))` above the chord of length `L`, with `a0`, `a1`
/// the tangents' angles to the chord.
fn flatness(p: &Piece) -> f64 {
    if p.flat.is_finite() {
        return p.flat;
    }
    let c = p.p1 - p.p0;
    let l = c.length();
    if l == 0.0 {
        return 0.0;
    }
    let (c0, c1) = (c.perp_dot(p.d0), c.perp_dot(p.d1));
    let tan = |cross: f64, d: DVec2| {
        let along = c.dot(d);
        if along > 0.0 {
            cross.abs() / along
        } else {
            f64::INFINITY
        }
    };
    let (t0, t1) = (tan(c0, p.d0), tan(c1, p.d1));
    let h = if t0 == 0.0 || t1 == 0.0 {
        0.0
    } else if c0.signum() != c1.signum() {
        // Tangents on opposite sides of the chord: the triangle.
        l * t0.min(t1) * (t0.max(t1) / (t0 + t1))
    } else {
        // Both on one side, which only rounding can give a convex piece (a straight one): the
        // larger tangent offset.
        l * t0.max(t1)
    };
    if h.is_nan() { l } else { h.min(l) }
}

/// Seed 2.3's linearity test (errata 3) in both coordinates, and the piece within
/// `LINEARITY_EPS * scale` of its chord in the plane.
fn is_linear(p: &Piece, scale: f64) -> bool {
    if p.floor {
        return true;
    }
    let dx = coordinate_deviation(p.s0, p.s1, p.p0.x, p.p1.x, p.d0.x, p.d1.x);
    let dy = coordinate_deviation(p.s0, p.s1, p.p0.y, p.p1.y, p.d0.y, p.d1.y);
    (dx * dx + dy * dy).sqrt() < LINEARITY_EPS && flatness(p) < LINEARITY_EPS * scale
}

/// Whether halving the piece gives two shorter pieces (it spans more than two floats).
fn splittable(p: &Piece) -> bool {
    let m = 0.5 * (p.s0 + p.s1);
    p.s0 < m && m < p.s1
}

/// The larger side of a piece's box.
fn size(p: &Piece) -> f64 {
    let e = p.hi - p.lo;
    e.x.max(e.y)
}

/// Padding of the box and band tests (section units): keeps touching contacts, and covers the
/// rounding of the end points.
const PAD: f64 = 1e-9;

/// Whether `p`'s box lies wholly on one side of the band around `q`'s chord line that holds `q`
/// (its half-width is `q`'s distance bound [`flatness`]): then the pieces do not meet. This is
/// the fat-line test of Bezier clipping; it prunes a pair whose boxes overlap only because one
/// piece runs diagonally through its box.
fn separated(p: &Piece, q: &Piece) -> bool {
    let c = q.p1 - q.p0;
    let l = c.length();
    let h = flatness(q);
    if !(l > 0.0) || !(h < l) {
        return false;
    }
    let normal = c.perp() / l;
    let dist = |x: f64, y: f64| (DVec2::new(x, y) - q.p0).dot(normal);
    let ds = [
        dist(p.lo.x, p.lo.y),
        dist(p.hi.x, p.lo.y),
        dist(p.lo.x, p.hi.y),
        dist(p.hi.x, p.hi.y),
    ];
    let band = h + PAD;
    ds.iter().all(|&x| x > band) || ds.iter().all(|&x| x < -band)
}

fn boxes_overlap(a: &Piece, b: &Piece) -> bool {
    let pad = PAD;
    let (amin, amax) = (a.lo - pad, a.hi + pad);
    amin.x <= b.hi.x && b.lo.x <= amax.x && amin.y <= b.hi.y && b.lo.y <= amax.y
}

struct Intersector<'a, C, S> {
    phi: PhiCurve<'a, C, S>,
    cs: SectionCurve<'a, C>,
    /// Newton results outside this `u` range are rejected.
    range: (f64, f64),
    found: &'a mut Found,
    /// The section's bounding radius: the scale of both curves.
    scale: f64,
    /// The stretch of `u` and the monotone piece of the section being intersected.
    stretch: (f64, f64),
    piece: (f64, f64),
    /// Piece pairs visited so far, and the work bound ([`MAX_PAIRS`]).
    pairs: u32,
    max_pairs: u32,
    /// Whether a pair that may hold a root met a full `found` (roots possibly lost).
    overflow: bool,
}

/// A piece of `phi` and, once computed, its halves: the subdivision of `phi` (a Taylor model
/// per piece, the costly part) is built once and shared by every piece of the section it meets.
struct PhiNode {
    piece: Piece,
    halves: Option<Box<[PhiNode; 2]>>,
}

impl PhiNode {
    fn new(piece: Piece) -> Self {
        PhiNode {
            piece,
            halves: None,
        }
    }
}

impl<C: CrossSection, S: SweepRule> Intersector<'_, C, S> {
    /// INTERSECT(curve1, curve2) of seed 2.3, for a piece of `phi` and one of the section.
    fn intersect(&mut self, node: &mut PhiNode, b: Piece, depth: u32) {
        let a = node.piece;
        if !boxes_overlap(&a, &b) || separated(&a, &b) || separated(&b, &a) {
            return;
        }
        if self.found.is_full() {
            self.overflow = true;
            return;
        }
        self.pairs += 1;
        if self.pairs == self.max_pairs {
            crate::budget::note_exhausted();
        }
        let la = is_linear(&a, self.scale) || !splittable(&a);
        let lb = is_linear(&b, self.scale) || !splittable(&b);
        // Both bend: split the larger only, so a wide box (`phi` near a singular frame) is
        // not paired with ever more pieces of the section.
        let split_a = !la && (lb || size(&a) >= size(&b));
        if (la && lb) || depth >= MAX_DEPTH || self.pairs >= self.max_pairs {
            self.chord_intersect(&a, &b);
        } else if split_a {
            let [a1, a2] = &mut **self.halves(node);
            self.intersect(a1, b, depth + 1);
            self.intersect(a2, b, depth + 1);
        } else {
            let (b1, b2) = self.cs.split(&b);
            self.intersect(node, b1, depth + 1);
            self.intersect(node, b2, depth + 1);
        }
    }

    /// The halves of a node, computed on first use ([`Self::split_phi`]).
    fn halves<'n>(&self, node: &'n mut PhiNode) -> &'n mut Box<[PhiNode; 2]> {
        node.halves.get_or_insert_with(|| {
            let (a1, a2) = self.split_phi(&node.piece);
            Box::new([PhiNode::new(a1), PhiNode::new(a2)])
        })
    }

    /// Halves a piece of `phi`. The bound of a smooth piece shrinks about fourfold per halving
    /// (it is second order in the width). Near an inflection of the axis, though, the Frenet
    /// frame and `phi` carry rounding noise (the binormal is the direction of a short
    /// `a' x a''`), and the models' bounds stop shrinking at its level, possibly above the
    /// linearity tolerance; halving further would only multiply the pieces. When neither half
    /// improves on its parent, both are marked as at that floor, and count as linear.
    fn split_phi(&self, a: &Piece) -> (Piece, Piece) {
        let (mut a1, mut a2) = self.phi.split(a);
        if a.flat <= 1e-3 * self.scale && a1.flat > 0.7 * a.flat && a2.flat > 0.7 * a.flat {
            a1.floor = true;
            a2.floor = true;
        }
        (a1, a2)
    }

    /// LINE-INTERSECT: the chords' crossing gives `(u, v)` by linear interpolation, then Newton's
    /// method on `G(u, v) = phi(u) - cs(v)`, `J = [phi'(u), -cs'(v)]`, polishes it.
    ///
    /// The pieces lie within `ha`, `hb` ([`flatness`]) of their chords, so where they cross,
    /// the chords' lines cross within `(ha + hb) / sin(angle)` along either chord: a crossing
    /// of the lines that far outside a chord may still be this pair's root (near the end it
    /// shares with a neighbour, whose chord can miss it on the other side).
    #[inline(never)] // its frame (the 2D isolator's box stack) stays off the recursion's
    fn chord_intersect(&mut self, a: &Piece, b: &Piece) {
        let (ea, eb) = (a.p1 - a.p0, b.p1 - b.p0);
        let den = ea.perp_dot(eb);
        let (alpha, beta) = if den != 0.0 {
            let r = b.p0 - a.p0;
            (r.perp_dot(eb) / den, r.perp_dot(ea) / den)
        } else {
            (0.5, 0.5) // parallel chords of a tangential contact: start from the middles
        };
        // (ha + hb) / sin(angle) / |ea| = (ha + hb) |eb| / |den|.
        let offset = (flatness(a) + flatness(b)) / den.abs();
        let (slack_a, slack_b) = (1e-6 + offset * eb.length(), 1e-6 + offset * ea.length());
        if !(alpha >= -slack_a
            && alpha <= 1.0 + slack_a
            && beta >= -slack_b
            && beta <= 1.0 + slack_b)
        {
            return;
        }
        // The pair's roots by interval Newton on the prism system ([`super::prism`]) over the
        // pieces' ranges grown by the chords' slack: it separates the two roots of a
        // near-tangency, which Newton's method on `phi(u) = cs(v)` from one start merges.
        // (A root beyond the pieces' ends lies in a neighbouring pair, which finds it: the
        // ranges grow only by a tenth, so the box holds about one tangency's worth of E.)
        let grow = |s0: f64, s1: f64, (lo, hi): (f64, f64)| {
            let w = (s1 - s0) * 0.1;
            ((s0 - w).max(lo), (s1 + w).min(hi))
        };
        let (u0, u1) = grow(a.s0, a.s1, self.stretch);
        let (v0, v1) = grow(b.s0, b.s1, self.piece);
        let mut roots = ArrayVec::<(f64, f64), 16>::new();
        let phi = &self.phi;
        super::prism::box_roots(phi.cyl, phi.o, phi.d, [u0, v0], [u1, v1], &mut roots);
        for (u, v) in roots {
            let v = v.rem_euclid(std::f64::consts::TAU);
            if u >= self.range.0
                && u <= self.range.1
                && !is_known(self.found, u, v)
                && self.found.try_push((u, v)).is_err()
            {
                self.overflow = true;
            }
        }
    }
}

/// Roots `(u, v)` of `phi(u) = cs(v)` for `u` in `range`, where `phi` must be finite, by the
/// general method; Newton results anywhere in `valid` are kept (a root at the edge of `range`
/// may converge just outside it). Appends to `found`; returns whether every root found had
/// room there (false: some may be lost, for the caller to split its range or count).
pub(crate) fn roots<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    o: DVec3,
    d: DVec3,
    range: (f64, f64),
    valid: (f64, f64),
    found: &mut Found,
    search: impl Fn(f64) -> bool,
) -> bool {
    roots_within(cyl, o, d, range, valid, found, MAX_PAIRS, search)
}

/// [`roots`] with a work bound of `max_pairs` piece pairs, on the monotone pieces of the
/// section for whose middle `v` `search` holds.
#[allow(clippy::too_many_arguments)]
fn roots_within<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    o: DVec3,
    d: DVec3,
    range: (f64, f64),
    valid: (f64, f64),
    found: &mut Found,
    max_pairs: u32,
    search: impl Fn(f64) -> bool,
) -> bool {
    let (lo, hi) = range;
    let scale = cyl.section.bounding_radius();
    // Stretches of u on which the frame is smooth.
    let stretches = cyl.smooth_stretches(lo, hi);

    let mut it = Intersector {
        phi: PhiCurve { cyl, o, d },
        cs: SectionCurve(&cyl.section),
        range: valid,
        found,
        scale,
        stretch: (lo, hi),
        piece: (0.0, 0.0),
        pairs: 0,
        max_pairs,
        overflow: false,
    };
    let vb = cyl.section.monotone_breaks();
    for (u0, u1) in stretches {
        if !(u0 < u1) {
            continue;
        }
        it.stretch = (u0, u1);
        let a = it.phi.piece(u0, u1);
        if !(a.p0.is_finite() && a.p1.is_finite()) {
            continue;
        }
        let mut root = PhiNode::new(a);
        for vw in vb.windows(2) {
            if !search(0.5 * (vw[0] + vw[1])) {
                continue;
            }
            it.piece = (vw[0], vw[1]);
            let b = it.cs.piece(vw[0], vw[1]);
            it.intersect(&mut root, b, 0);
        }
    }
    !it.overflow
}

/// Roots found by the general method: `(u, v)`.
pub(crate) type Found = ArrayVec<(f64, f64), 64>;

/// Whether `(u, v)` is (to rounding) a root already found: neighbouring leaf pairs converge
/// to the same root.
pub(crate) fn is_known(found: &[(f64, f64)], u: f64, v: f64) -> bool {
    found.iter().any(|&(ku, kv)| {
        let dv = (kv - v).abs();
        (ku - u).abs() <= 1e-12 * (1.0 + u.abs()) && dv.min(std::f64::consts::TAU - dv) <= 1e-9
    })
}

/// Keeps one of each root found more than once (from neighbouring ranges), sorted by `u`: in
/// place, the first `kept` entries those kept so far (no second array, whose move would copy
/// all of its capacity).
pub(crate) fn dedupe(found: &mut Found) {
    found.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut kept = 0;
    for i in 0..found.len() {
        let (u, v) = found[i];
        if !is_known(&found[..kept], u, v) {
            found[kept] = (u, v);
            kept += 1;
        }
    }
    found.truncate(kept);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cylinder::FiberSpec;
    use crate::section::{BezierLoop, Section};

    /// Distance of `x` from the segment `a b`.
    fn segment_distance(x: DVec2, a: DVec2, b: DVec2) -> f64 {
        let e = b - a;
        let t = ((x - a).dot(e) / e.length_squared()).clamp(0.0, 1.0);
        if t.is_nan() {
            return (x - a).length();
        }
        (x - (a + t * e)).length()
    }

    /// `examples/xray.toml`'s trilobal fiber, the axis bent out of its plane by `dx`.
    fn xray_fiber(dx: f64) -> GeneralizedCylinder {
        let profile: Vec<DVec2> = [
            [1.0, 0.0],
            [1.0, 0.35],
            [0.55, 0.55],
            [-0.5, 0.87],
            [-0.45, 0.45],
            [-0.5, 0.0],
            [-0.5, -0.87],
            [0.1, -0.75],
            [0.55, -0.55],
        ]
        .map(DVec2::from_array)
        .to_vec();
        FiberSpec {
            bezier: [
                DVec3::new(-0.3, -1.1, 0.5),
                DVec3::new(-0.1 + dx, -0.4, 0.6),
                DVec3::new(0.1, 0.4, 0.4),
                DVec3::new(0.3, 1.1, 0.5),
            ],
            major_radius: [0.13, 0.13],
            minor_radius: [0.13, 0.13],
            rotation: [0.0, 2.0],
            caps: true,
            normal_hint: None,
            section: Section::Loop(BezierLoop::new(&profile).unwrap()),
        }
        .build()
        .unwrap()
    }

    /// With a tiny work bound the search still ends, is counted as exhausted, and every root
    /// it reports is one the full search finds (the bound's fallback, interval Newton on the
    /// boxes of the pieces left, certifies its roots like any leaf; here it finds them all).
    #[test]
    fn the_work_bound_ends_the_search_with_true_roots() {
        let cyl = xray_fiber(0.05);
        let before = crate::budget::exhausted_here();
        let (mut complete, mut bounded_roots) = (0, 0);
        for k in 0..40 {
            let o = DVec3::new(-1.0, -0.9 + 0.045 * k as f64, 0.45 + 0.002 * k as f64) - cyl.origin;
            let d = DVec3::new(1.0, 0.013, 0.021);
            let mut full = Found::new();
            roots(&cyl, o, d, (0.0, 1.0), (0.0, 1.0), &mut full, |_| true);
            let mut bounded = Found::new();
            roots_within(&cyl, o, d, (0.0, 1.0), (0.0, 1.0), &mut bounded, 4, |_| {
                true
            });
            complete += full.len();
            bounded_roots += bounded.len();
            for &(u, v) in &bounded {
                assert!(
                    full.iter()
                        .any(|&(fu, fv)| (fu - u).abs() < 1e-9 && (fv - v).abs() < 1e-9),
                    "ray {k}: bounded root ({u}, {v}) not among {full:?}"
                );
            }
        }
        assert!(complete > 20, "the rays cross the fiber: {complete} roots");
        assert!(bounded_roots > 0, "the chords' fallback still finds roots");
        assert!(
            crate::budget::exhausted_here() > before,
            "exhaustion is counted"
        );
    }

    /// The bounds of `phi` pieces hold the curve: sampled points lie in the box and within the
    /// bound of the chord, on pieces of widths `1e-2` down to `1e-10` around `u = 1/2` of the
    /// xray fiber (planar, where the frame flips, and bent by `1e-6`, where it turns half round
    /// within about `1e-6`) and of a twisted elliptical fiber; and the bound shrinks about
    /// fourfold per halving where `phi` is smooth.
    #[test]
    fn phi_piece_bounds_hold_the_curve() {
        let ellipse = FiberSpec {
            bezier: [
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(0.35, 0.45, 0.1),
                DVec3::new(0.75, 0.05, 0.55),
                DVec3::new(1.05, 0.45, 0.35),
            ],
            major_radius: [0.03, 0.03],
            minor_radius: [0.015, 0.015],
            rotation: [0.0, std::f64::consts::TAU],
            caps: true,
            normal_hint: None,
            section: Section::default(),
        }
        .build()
        .unwrap();
        let d = DVec3::new(0.0, 0.0, -1.0);
        let mut checked = 0;
        for (name, cyl, o) in [
            ("planar", xray_fiber(0.0), DVec3::new(-0.105, 0.023, 0.0)),
            ("bent", xray_fiber(1e-6), DVec3::new(-0.105, 0.023, 0.0)),
            ("ellipse", ellipse, DVec3::new(0.52, 0.26, 0.0)),
        ] {
            let o = o - cyl.origin;
            let phi = PhiCurve { cyl: &cyl, o, d };
            for (k, w) in [1e-2, 1e-4, 1e-6, 1e-8, 1e-10].into_iter().enumerate() {
                for j in 0..7 {
                    let u0 = 0.5 - w * (0.13 + 0.31 * j as f64 + 0.05 * k as f64);
                    // Pieces are never taken across a switch of the frame (the intersector
                    // splits there), where the piece's enclosure would hold one side only.
                    if cyl.switches_in(u0, u0 + w).next().is_some() {
                        continue;
                    }
                    let p = phi.piece(u0, u0 + w);
                    if !p.flat.is_finite() || p.flat >= 1.0 {
                        continue;
                    }
                    for i in 0..=64 {
                        let x = phi.eval(u0 + w * i as f64 / 64.0).0;
                        let slack = 1e-12 + phi.noise(u0 + w * i as f64 / 64.0);
                        assert!(
                            x.cmpge(p.lo - slack).all() && x.cmple(p.hi + slack).all(),
                            "{name} [{u0}, {}]: {x:?} outside {:?}-{:?}",
                            u0 + w,
                            p.lo,
                            p.hi
                        );
                        let dist = segment_distance(x, p.p0, p.p1);
                        assert!(
                            dist <= p.flat + slack,
                            "{name} [{u0}, {}]: {x:?} at {dist} from the chord, bound {}",
                            u0 + w,
                            p.flat
                        );
                    }
                    checked += 1;
                }
            }
            if name == "ellipse" {
                let (a, b) = (phi.piece(0.4, 0.41), phi.piece(0.4, 0.405));
                assert!(b.flat < 0.3 * a.flat, "{} vs {}", b.flat, a.flat);
            }
        }
        assert!(checked > 50, "{checked} pieces checked");
    }

    /// The end tangents' triangle bounds monotone, convex section pieces: sampled points are
    /// within `flatness` of the chord, on the pieces of `monotone_breaks` and their halves and
    /// quarters (what the fat-line test `separated` relies on).
    #[test]
    fn section_piece_flatness_holds() {
        let sections = [
            Section::Loop(BezierLoop::circle_approximation()),
            xray_fiber(0.0).section.clone(),
            Section::default(),
        ];
        for section in &sections {
            let cs = SectionCurve(section);
            let vb = section.monotone_breaks();
            for w in vb.windows(2) {
                for parts in [1, 2, 4] {
                    for k in 0..parts {
                        let s = |f: f64| w[0] + (w[1] - w[0]) * (k as f64 + f) / parts as f64;
                        let p = cs.piece(s(0.0), s(1.0));
                        let h = flatness(&p);
                        for i in 0..=64 {
                            let x = cs.eval(s(i as f64 / 64.0)).0;
                            let dist = segment_distance(x, p.p0, p.p1);
                            assert!(dist <= h + 1e-14, "{section:?} {w:?}: {dist} > {h}");
                            assert!(x.cmpge(p.lo - 1e-14).all() && x.cmple(p.hi + 1e-14).all());
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn corrected_linearity_distance() {
        // x(s) = s^2 on [0, 1]: tangents x = 0 and x = 2s - 1 meet at (1/2, 0); the chord x = s
        // is at distance |1/2 - 0| / sqrt 2 from it. The seed's minus sign would divide by 0.
        let d = coordinate_deviation(0.0, 1.0, 0.0, 1.0, 0.0, 2.0);
        assert!((d - 0.5 / 2f64.sqrt()).abs() < 1e-15, "deviation {d}");
        // A straight graph is linear.
        assert_eq!(
            coordinate_deviation(0.0, 2.0, 1.0, 5.0, 2.0, 2.0),
            0.0,
            "line"
        );
        // Parallel tangents off the chord (errata 3's guarded case): the offset bound
        // max |x_i' - slope| |ds| / sqrt(1 + slope^2) = 1 / sqrt 2.
        let d = coordinate_deviation(0.0, 1.0, 0.0, 1.0, 0.0, 0.0);
        assert!((d - 0.5f64.sqrt()).abs() < 1e-15, "parallel: {d}");
    }
}
