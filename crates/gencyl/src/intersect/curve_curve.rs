//! The general path (seed 2.3): intersect the plane curve `phi(u)` with the section `cs(v)` by
//! recursive subdivision of monotone, inflection-free pieces.

use arrayvec::ArrayVec;
use glam::{DVec2, DVec3};

use crate::cylinder::GeneralizedCylinder;
use crate::real::{Dual, Real};
use crate::roots::{Function1D, bracketed_root};
use crate::section::CrossSection;
use crate::sweep::SweepRule;

/// A piece is linear when the tangent-intersection point is within this distance of the chord
/// (in the `(parameter, coordinate)` planes, seed 2.3 with errata 3). The chord intersection then
/// starts Newton's method within about this distance of the root, well inside its basin.
const LINEARITY_EPS: f64 = 1e-6;
/// Grid cells per range in which `phi` is searched for tangent and inflection points.
const FEATURE_SAMPLES: usize = 64;
/// Subdivision depth cap: beyond it two pieces are treated as linear (a tangential contact).
const MAX_DEPTH: u32 = 48;

/// One coordinate, or a combination, of `phi` and its derivatives, as a function of `u`.
#[derive(Clone, Copy)]
enum PhiFeature {
    /// `phi_x'(u)`: zero at vertical tangents.
    DxDu,
    /// `phi_y'(u)`: zero at horizontal tangents.
    DyDu,
    /// `phi_x' phi_y'' - phi_y' phi_x''`: zero at inflections.
    Curvature,
}

struct PhiFn<'a, C, S> {
    cyl: &'a GeneralizedCylinder<C, S>,
    o: DVec3,
    d: DVec3,
    feature: PhiFeature,
}

impl<C: CrossSection, S: SweepRule> Function1D for PhiFn<'_, C, S> {
    fn eval<T: Real>(&self, u: T) -> T {
        match self.feature {
            PhiFeature::DxDu => self.cyl.phi_r(self.o, self.d, Dual::var(u)).0.x.d,
            PhiFeature::DyDu => self.cyl.phi_r(self.o, self.d, Dual::var(u)).0.y.d,
            PhiFeature::Curvature => {
                // u as a doubly dual variable: .v.d and .d.v hold the first derivative,
                // .d.d the second.
                let uu = Dual {
                    v: Dual::var(u),
                    d: Dual::cst(1.0),
                };
                let p = self.cyl.phi_r(self.o, self.d, uu).0;
                let (dx, dy) = (p.x.v.d, p.y.v.d);
                let (ddx, ddy) = (p.x.d.d, p.y.d.d);
                dx * ddy - dy * ddx
            }
        }
    }
}

/// A piece of a plane curve over `[s0, s1]`: end points and end derivatives.
#[derive(Clone, Copy, Debug)]
struct Piece {
    s0: f64,
    s1: f64,
    p0: DVec2,
    p1: DVec2,
    d0: DVec2,
    d1: DVec2,
}

trait PlaneCurve {
    /// Point and derivative at `s`.
    fn eval(&self, s: f64) -> (DVec2, DVec2);

    fn piece(&self, s0: f64, s1: f64) -> Piece {
        let ((p0, d0), (p1, d1)) = (self.eval(s0), self.eval(s1));
        Piece {
            s0,
            s1,
            p0,
            p1,
            d0,
            d1,
        }
    }

    fn split(&self, p: &Piece) -> (Piece, Piece) {
        let m = 0.5 * (p.s0 + p.s1);
        let (pm, dm) = self.eval(m);
        (
            Piece {
                s1: m,
                p1: pm,
                d1: dm,
                ..*p
            },
            Piece {
                s0: m,
                p0: pm,
                d0: dm,
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

impl<C: CrossSection, S: SweepRule> PlaneCurve for PhiCurve<'_, C, S> {
    fn eval(&self, u: f64) -> (DVec2, DVec2) {
        let p = self.cyl.phi_r(self.o, self.d, Dual::var(u)).0;
        (DVec2::new(p.x.v, p.y.v), DVec2::new(p.x.d, p.y.d))
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

fn is_linear(p: &Piece) -> bool {
    let dx = coordinate_deviation(p.s0, p.s1, p.p0.x, p.p1.x, p.d0.x, p.d1.x);
    let dy = coordinate_deviation(p.s0, p.s1, p.p0.y, p.p1.y, p.d0.y, p.d1.y);
    (dx * dx + dy * dy).sqrt() < LINEARITY_EPS
}

fn boxes_overlap(a: &Piece, b: &Piece) -> bool {
    // End-point boxes bound monotone pieces; the pad keeps touching contacts.
    let pad = 1e-9;
    let (amin, amax) = (a.p0.min(a.p1) - pad, a.p0.max(a.p1) + pad);
    let (bmin, bmax) = (b.p0.min(b.p1), b.p0.max(b.p1));
    amin.x <= bmax.x && bmin.x <= amax.x && amin.y <= bmax.y && bmin.y <= amax.y
}

struct Intersector<'a, C, S> {
    phi: PhiCurve<'a, C, S>,
    cs: SectionCurve<'a, C>,
    /// Newton results outside this `u` range are rejected.
    range: (f64, f64),
    found: &'a mut Found,
}

impl<C: CrossSection, S: SweepRule> Intersector<'_, C, S> {
    /// INTERSECT(curve1, curve2) of seed 2.3.
    fn intersect(&mut self, a: Piece, b: Piece, depth: u32) {
        if !boxes_overlap(&a, &b) || self.found.is_full() {
            return;
        }
        let (la, lb) = (is_linear(&a), is_linear(&b));
        if (la && lb) || depth >= MAX_DEPTH {
            self.chord_intersect(&a, &b);
        } else if la {
            let (b1, b2) = self.cs.split(&b);
            self.intersect(a, b1, depth + 1);
            self.intersect(a, b2, depth + 1);
        } else if lb {
            let (a1, a2) = self.phi.split(&a);
            self.intersect(a1, b, depth + 1);
            self.intersect(a2, b, depth + 1);
        } else {
            let (a1, a2) = self.phi.split(&a);
            let (b1, b2) = self.cs.split(&b);
            self.intersect(a1, b1, depth + 1);
            self.intersect(a2, b1, depth + 1);
            self.intersect(a1, b2, depth + 1);
            self.intersect(a2, b2, depth + 1);
        }
    }

    /// LINE-INTERSECT: the chords' crossing gives `(u, v)` by linear interpolation, then Newton's
    /// method on `G(u, v) = phi(u) - cs(v)`, `J = [phi'(u), -cs'(v)]`, polishes it.
    fn chord_intersect(&mut self, a: &Piece, b: &Piece) {
        let (ea, eb) = (a.p1 - a.p0, b.p1 - b.p0);
        let den = ea.perp_dot(eb);
        let (alpha, beta) = if den != 0.0 {
            let r = b.p0 - a.p0;
            (r.perp_dot(eb) / den, r.perp_dot(ea) / den)
        } else {
            (0.5, 0.5) // parallel chords of a tangential contact: start from the middles
        };
        let slack = 1e-6;
        if !(alpha >= -slack && alpha <= 1.0 + slack && beta >= -slack && beta <= 1.0 + slack) {
            return;
        }
        let mut u = a.s0 + alpha.clamp(0.0, 1.0) * (a.s1 - a.s0);
        let mut v = b.s0 + beta.clamp(0.0, 1.0) * (b.s1 - b.s0);
        let mut residual = f64::INFINITY;
        for _ in 0..50 {
            let ((p, dp), (c, dc)) = (self.phi.eval(u), self.cs.eval(v));
            let g = p - c;
            residual = g.length();
            let det = dp.perp_dot(-dc);
            if det == 0.0 || !det.is_finite() {
                break;
            }
            // [dp -dc] (du, dv) = g
            let du = g.perp_dot(-dc) / det;
            let dv = dp.perp_dot(g) / det;
            u -= du;
            v -= dv;
            if du.abs() <= 1e-16 * (1.0 + u.abs()) && dv.abs() <= 1e-16 * (1.0 + v.abs()) {
                residual = (self.phi.eval(u).0 - self.cs.eval(v).0).length();
                break;
            }
        }
        let v = v.rem_euclid(std::f64::consts::TAU);
        if residual <= 1e-9
            && u >= self.range.0
            && u <= self.range.1
            && !self.found.is_full()
            && !is_known(self.found, u, v)
        {
            self.found.push((u, v));
        }
    }
}

/// Roots `(u, v)` of `phi(u) = cs(v)` for `u` in `range`, where `phi` must be finite, by the
/// general method; Newton results anywhere in `valid` are kept (a root at the edge of `range`
/// may converge just outside it). Appends to `found`.
pub(crate) fn roots<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    o: DVec3,
    d: DVec3,
    range: (f64, f64),
    valid: (f64, f64),
    found: &mut Found,
) {
    let (lo, hi) = range;
    // Split phi at vertical and horizontal tangents and at inflections: sign changes of the
    // features on a grid of FEATURE_SAMPLES cells, refined by bracketed Newton iteration. (A
    // feature root pair inside one cell, a piece bending back within 1/64 of the range, is not
    // split; the box test then sees its end points' box, which the subdivision narrows.)
    let mut breaks: Vec<f64> = vec![lo, hi];
    for feature in [PhiFeature::DxDu, PhiFeature::DyDu, PhiFeature::Curvature] {
        let f = PhiFn { cyl, o, d, feature };
        let value = |u: f64| {
            let r = f.eval(Dual::var(u));
            (r.v, r.d)
        };
        let mut prev = (lo, value(lo).0);
        for k in 1..=FEATURE_SAMPLES {
            let u = lo + (hi - lo) * k as f64 / FEATURE_SAMPLES as f64;
            let fu = value(u).0;
            // A feature that vanishes identically (phi is a straight line) gives no split points.
            if prev.1 == 0.0 && fu == 0.0 {
                prev = (u, fu);
                continue;
            }
            if let Some(r) = bracketed_root(&value, prev.0, u, prev.1, fu)
                && r > lo
                && r < hi
            {
                breaks.push(r);
            }
            prev = (u, fu);
        }
    }
    breaks.sort_by(f64::total_cmp);
    breaks.dedup();

    let mut it = Intersector {
        phi: PhiCurve { cyl, o, d },
        cs: SectionCurve(&cyl.section),
        range: valid,
        found,
    };
    let vb = cyl.section.monotone_breaks();
    for uw in breaks.windows(2) {
        let a = it.phi.piece(uw[0], uw[1]);
        if !(a.p0.is_finite() && a.p1.is_finite()) {
            continue;
        }
        for vw in vb.windows(2) {
            let b = it.cs.piece(vw[0], vw[1]);
            it.intersect(a, b, 0);
        }
    }
}

/// Roots found by the general method: `(u, v)`.
pub(crate) type Found = ArrayVec<(f64, f64), 64>;

/// Whether `(u, v)` is (to rounding) a root already found: neighbouring leaf pairs converge
/// to the same root.
fn is_known(found: &Found, u: f64, v: f64) -> bool {
    found.iter().any(|&(ku, kv)| {
        let dv = (kv - v).abs();
        (ku - u).abs() <= 1e-12 * (1.0 + u.abs()) && dv.min(std::f64::consts::TAU - dv) <= 1e-9
    })
}

/// Keeps one of each root found more than once (from neighbouring ranges), sorted by `u`.
pub(crate) fn dedupe(found: &mut Found) {
    found.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut kept = Found::new();
    for &(u, v) in found.iter() {
        if !is_known(&kept, u, v) {
            kept.push((u, v));
        }
    }
    *found = kept;
}

#[cfg(test)]
mod tests {
    use super::*;

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
