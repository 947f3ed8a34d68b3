//! The moving frame along the axis: Frenet where the axis bends, a fixed frame where the whole
//! segment is straight (interface.md section 1), and the projection frame of a fixed reference
//! direction, which strands use to follow the fiber without spinning ([`Framing::Projected`]).

use arrayvec::ArrayVec;
use glam::DVec3;

use crate::bernstein::Bernstein;
use crate::curve::{CubicBezier, vector_scale};
use crate::real::{Dual, Real, V3};
use crate::roots::{Function1D, IsolateOptions, isolate_roots};

/// A segment whose control points stray from the chord by at most this fraction of the chord
/// length is straight and gets a fixed frame.
///
/// Why this value: the Frenet binormal is `a' x a''`, and `a''` carries a rounding error of about
/// `1e-16` of the control points' magnitude (they are stored relative to `P0`, so of the chord
/// length `L`). A deviation `delta L` gives `|a''| ~ delta L`, so the binormal's direction is off
/// by about `1e-16 / delta`: at `delta = 1e-9` that is `1e-7` radians, which moves an elliptical
/// section's surface by `1e-7 (A - B)`. Below the threshold the curvature is not resolvable in
/// double precision relative to the segment and the frame would be noise.
pub const STRAIGHT_TOLERANCE: f64 = 1e-9;

/// An orthonormal, right-handed frame (`n x b = t`) at one point of the axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// Unit tangent `t = a'/|a'|`.
    pub t: DVec3,
    /// Unit normal `n = b x t`.
    pub n: DVec3,
    /// Unit binormal `b = (t x a'')/|t x a''|`.
    pub b: DVec3,
}

/// How a segment's frame is defined.
#[derive(Clone, Debug, PartialEq)]
pub enum Framing {
    /// The Frenet frame of the curve.
    Frenet,
    /// A constant frame (a straight segment, whose Frenet frame is undefined). Boxed: straight
    /// segments are rare in hair, and inline the frame would make every cylinder 48 bytes
    /// larger.
    Fixed(Box<Frame>),
    /// The projection frame of the reference direction `r`: `n` is `r` made normal to the
    /// tangent, `n = (r - (r.t) t) / |r - (r.t) t|`, and `b = t x n`. Equivalently
    /// `b = (a' x r) / |a' x r|`, `n = b x t`: Frenet's formula with `a''` replaced by the
    /// constant `r`, a smooth frame wherever `r` is not parallel to `t` (see
    /// [`Framing::projection_sine`]; [`GeneralizedCylinder::with_framing`] requires
    /// `min |r x t| >=` [`PROJECTION_MIN_SINE`] over the segment, so it has no singular point).
    /// It turns about `t` only as fast as the tangent's motion forces it to keep `n` near `r`;
    /// [`Strand`](crate::Strand)s add a linear twist per segment (in the sweep's rotation) so
    /// that it matches a rotation-minimising frame at both ends of every segment.
    ///
    /// [`GeneralizedCylinder::with_framing`]: crate::GeneralizedCylinder::with_framing
    Projected(DVec3),
}

/// The smallest `min_u |r x t(u)|` (for a unit reference `r`) that a projection frame may have:
/// below it the frame turns by up to `1 / PROJECTION_MIN_SINE` times faster than the tangent
/// near the closest approach, and it is singular where `r` is parallel to `t`.
pub const PROJECTION_MIN_SINE: f64 = 1e-3;

/// The sine a strand's projection reference should keep from every tangent of its segment to be
/// taken without looking further (see [`Framing::projected_for_axis`]): at `1/2` the reference
/// stays at least 30 degrees off every tangent.
pub(crate) const PROJECTION_GOOD_SINE: f64 = 0.5;

/// How many times [`Framing::projection_sine`] may halve a piece of `[0, 1]` (pieces down to
/// `2^-16`).
const PROJECTION_DEPTH: u32 = 16;

impl Framing {
    /// The framing interface.md prescribes: `Fixed` when the segment is straight to within
    /// [`STRAIGHT_TOLERANCE`], with `n` the unit vector orthogonal to `t` closest to `hint`
    /// (default: the world axis `e_k` with the smallest `|t_k|`, lowest `k` on ties).
    ///
    /// Returns `None` when the hint is (nearly) parallel to the tangent.
    pub fn for_axis(axis: &CubicBezier, hint: Option<DVec3>) -> Option<Framing> {
        if axis.relative_deviation_from_chord() > STRAIGHT_TOLERANCE {
            return Some(Framing::Frenet);
        }
        let t = (axis.points[3] - axis.points[0]).normalize();
        let hint = hint.unwrap_or_else(|| {
            let a = t.abs();
            if a.x <= a.y && a.x <= a.z {
                DVec3::X
            } else if a.y <= a.z {
                DVec3::Y
            } else {
                DVec3::Z
            }
        });
        let h = hint.normalize_or_zero();
        let perp = h - h.dot(t) * t;
        // |perp| = sin(angle between hint and t); below 1e-6 the choice of n is ill-conditioned.
        if perp.length() < 1e-6 {
            return None;
        }
        let n = perp.normalize();
        Some(Framing::Fixed(Box::new(Frame {
            t,
            n,
            b: t.cross(n),
        })))
    }

    /// A lower bound of `min_u |r x t(u)| / |r|` over `u in [0, 1]`, the sine of the smallest
    /// angle between the reference `r` and the tangents (0 when `r` is zero or not finite).
    ///
    /// `|r x a'(u)|^2 - s^2 |a'(u)|^2` is a quartic in `u`: `w = r x a'` is the quadratic Bezier
    /// with control points `r x h_i` (`h_i` those of the hodograph `a'`), and
    /// `|w|^2 = sum_xyz w_x^2`, `|a'|^2` likewise, products in Bernstein form. Where every
    /// Bernstein coefficient of that quartic is non-negative so is the quartic (convex hull
    /// property), so on a piece of `[0, 1]` `s^2 = min_k P_k / Q_k` (`P`, `Q` the coefficients of
    /// `|w|^2` and `|a'|^2` there; 0 if a `P_k` is negative or a `Q_k` is not positive) holds
    /// `|r x t|^2 >= s^2` on the piece. A piece is halved (de Casteljau) while that bound is
    /// below `0.81` of the smallest of `|w|^2 / |a'|^2` at its ends and middle, at most
    /// `PROJECTION_DEPTH` (16) times: the bound tightens quadratically with the width, and ends
    /// within 10 % (in `s`) of the true minimum, or below it where that is tiny. Exact up to
    /// rounding (relative `1e-15`, far below any threshold it is compared with).
    pub fn projection_sine(axis: &CubicBezier, reference: DVec3) -> f64 {
        Self::projection_sine_bound(axis, reference, None)
    }

    /// Whether [`Framing::projection_sine`]'s bound proves `min_u |r x t(u)| / |r| >= s`: the
    /// same bound, with the subdivision cut short where a piece is proven (its bound reaches
    /// `s`) or cannot be (its value at an end or the middle is below `s`).
    pub fn projection_sine_at_least(axis: &CubicBezier, reference: DVec3, s: f64) -> bool {
        Self::projection_sine_bound(axis, reference, Some(s * s)) >= s
    }

    /// See [`Framing::projection_sine`]; `target` (a squared sine) ends the subdivision early.
    fn projection_sine_bound(axis: &CubicBezier, reference: DVec3, target: Option<f64>) -> f64 {
        let r = reference.normalize_or_zero();
        if r == DVec3::ZERO || !r.is_finite() {
            return 0.0;
        }
        let k1 = axis.speed_scale();
        let h = axis.hodograph().map(|h| h * k1);
        let w = h.map(|h| r.cross(h));
        let square = |v: [DVec3; 3]| -> Bernstein<5> {
            (0..3).fold(Bernstein([0.0; 5]), |acc, k| {
                let c = Bernstein([v[0][k], v[1][k], v[2][k]]);
                acc.add(&c.mul(&c))
            })
        };
        fn bound(p: &Bernstein<5>, q: &Bernstein<5>, depth: u32, target: Option<f64>) -> f64 {
            let b =
                p.0.iter()
                    .zip(q.0.iter())
                    .fold(f64::INFINITY, |m, (pk, qk)| {
                        m.min(if *pk >= 0.0 && *qk > 0.0 {
                            pk / qk
                        } else {
                            0.0
                        })
                    });
            // The coefficients at the ends are the values there.
            let sampled = (p.0[0] / q.0[0])
                .min(p.0[4] / q.0[4])
                .min(p.eval(0.5) / q.eval(0.5));
            let settled = match target {
                Some(t) => b >= t || !(sampled >= t),
                None => !(b < 0.81 * sampled),
            };
            if settled || depth == PROJECTION_DEPTH {
                return b;
            }
            let ((p0, p1), (q0, q1)) = (p.split(0.5), q.split(0.5));
            let left = bound(&p0, &q0, depth + 1, target);
            if target.is_some_and(|t| !(left >= t)) {
                return left;
            }
            left.min(bound(&p1, &q1, depth + 1, target))
        }
        bound(&square(w), &square(h), 0, target)
            .clamp(0.0, 1.0)
            .sqrt()
    }

    /// A projection framing ([`Framing::Projected`]) for `axis` whose reference keeps away from
    /// every tangent: the first of `preferred` whose [`Framing::projection_sine`] is at least
    /// `1/2` (a strand passes the rotation-minimising normals at the segment's middle and ends,
    /// which make the projection frame close to that frame), otherwise the best of `preferred`,
    /// the normals of the planes through pairs of the hodograph's control points (a nearly
    /// planar segment's tangents all lie close to that plane) and the 13 directions of the
    /// cube's faces, edges and corners. `None` if even the best stays within
    /// [`PROJECTION_MIN_SINE`] of some tangent.
    pub fn projected_for_axis(axis: &CubicBezier, preferred: &[DVec3]) -> Option<Framing> {
        let sine = |r: DVec3| Framing::projection_sine(axis, r);
        if let Some(&r) = preferred
            .iter()
            .find(|&&r| Framing::projection_sine_at_least(axis, r, PROJECTION_GOOD_SINE))
        {
            return Some(Framing::Projected(r.normalize()));
        }
        let [h0, h1, h2] = axis.hodograph();
        let mut candidates: Vec<DVec3> = preferred.to_vec();
        candidates.extend([h0.cross(h1), h1.cross(h2), h0.cross(h2)]);
        for x in -1..=1 {
            for y in -1..=1 {
                for z in 0..=1 {
                    // One of each antipodal pair: z > 0, or z = 0 and (y > 0, or y = 0, x > 0).
                    if z == 1 || y == 1 || (y == 0 && x == 1) {
                        candidates.push(DVec3::new(x as f64, y as f64, z as f64));
                    }
                }
            }
        }
        let (best, s) = candidates
            .into_iter()
            .map(|r| (r, sine(r)))
            .fold((DVec3::ZERO, 0.0), |b, c| if c.1 > b.1 { c } else { b });
        (s >= PROJECTION_MIN_SINE).then(|| Framing::Projected(best.normalize()))
    }
}

/// Below this `|a' x a''| / (|a'| max |a''|)` the Frenet normal at a point is rounding noise.
pub(crate) const FRENET_DEGENERATE: f64 = 1e-9;

/// How far from `u` the Frenet frame standing for `u` is taken: 0, or `1e-7` away where
/// `a' x a''` is negligible against `|a'| max|a''|` (`a''` is linear, so its largest length is
/// at an end). That happens at inflections and at the root and tip of a strand, whose
/// reflected end points make `a'' = 0` there exactly in theory and rounding noise in practice:
/// the noise would turn the end cap against the side surface. Within such a stretch the frame
/// is taken toward where `|a' x a''|` grows (`d|a' x a''|^2/du = 2 (a' x a'').(a' x a''')`), so
/// each side of an inflection takes its own limit and the frame switches exactly at the
/// inflection, where `|a' x a''|` is least (and at a strand's end, inward). With `a'` and `a''`
/// scaled to unit size ([`CubicBezier::derivative_scales`]) at any scale of the curve.
///
/// The test `|a' x a''| > FRENET_DEGENERATE |a'| max|a''|` is first made on the unscaled
/// squares, which decide it wherever they neither underflow nor overflow (the usual case, and
/// the cheap one); otherwise on the scaled vectors.
pub(crate) fn frenet_shift(axis: &CubicBezier, u: f64) -> f64 {
    frenet_shift_with(axis, u, axis.d1(u), axis.d2(u))
}

/// [`frenet_shift`] from `a'(u)` and `a''(u)` ([`CubicBezier::d1`], [`CubicBezier::d2`]).
fn frenet_shift_with(axis: &CubicBezier, u: f64, d1: DVec3, d2: DVec3) -> f64 {
    let [h0, h1] = axis.second_hodograph();
    let (s1, m2) = (
        d1.length_squared(),
        h0.length_squared().max(h1.length_squared()),
    );
    let bound = FRENET_DEGENERATE * FRENET_DEGENERATE * s1 * m2;
    // With |a'|^2, max|a''|^2 and the bound in range no product over- or underflows beyond
    // what the comparison can see.
    let representable = |x: f64| x > 1e-250 && x < 1e250;
    let degenerate = if representable(s1) && representable(m2) && representable(bound) {
        !(d1.cross(d2).length_squared() > bound)
    } else {
        let [k1, k2] = axis.derivative_scales();
        let d1 = d1 * k1;
        let c = d1.cross(d2 * k2);
        let scale = d1.length() * (h0 * k2).length().max((h1 * k2).length());
        !(c.length() > FRENET_DEGENERATE * scale)
    };
    if !degenerate {
        return 0.0;
    }
    let [k1, k2] = axis.derivative_scales();
    let (d1, c) = (d1 * k1, (d1 * k1).cross(d2 * k2));
    let grows = c.dot(d1.cross(axis.third_derivative() * k2)) >= 0.0;
    let s = if grows { 1e-7 } else { -1e-7 };
    if u + s > 1.0 {
        -1e-7
    } else if u + s < 0.0 {
        1e-7
    } else {
        s
    }
}

/// `|a' x a''|^2 - (FRENET_DEGENERATE |a'| max|a''|)^2`: negative exactly where
/// [`frenet_shift`] takes the frame away from `u`.
struct Degenerate<'a> {
    axis: &'a CubicBezier,
    /// `(FRENET_DEGENERATE max|a''|)^2`.
    tol2: f64,
}

impl Function1D for Degenerate<'_> {
    fn eval<T: Real>(&self, u: T) -> T {
        let d1 = self.axis.d1_r(u);
        d1.cross(self.axis.d2_r(u)).norm2() - d1.norm2().scale(self.tol2)
    }
}

/// Most cells [`clearly_curved`] examines.
const CURVED_CELLS: usize = 15;

/// Whether [`Degenerate`] is certainly positive on `[lo, hi]` (so [`frenet_shift`] is 0 there
/// and the frame has no switch): most curved axes, decided without root isolation.
///
/// With the hodographs scaled to unit size ([`CubicBezier::derivative_scales`], `k1 a'` and
/// `k2 a''`), `k1^2 k2^2` times the function is the polynomial
/// `|a' x a''|^2 - (FRENET_DEGENERATE max|a''|)^2 |a'|^2` of degree 6 (`a'` is a Bernstein
/// quadratic, `a''` linear, their cross product cubic), whose Bernstein coefficients on a cell
/// bound it there. A cell whose coefficients all exceed their rounding bound (`1e-12` of the
/// terms' magnitudes, far above the few hundred ulps of the products) is clear; others are
/// halved, up to [`CURVED_CELLS`] cells. `false` leaves the question to the isolation.
fn clearly_curved(axis: &CubicBezier, lo: f64, hi: f64) -> bool {
    let [k1, k2] = axis.derivative_scales();
    let h = axis.hodograph().map(|x| x * k1);
    let g = axis.second_hodograph().map(|x| x * k2);
    let d1 = |k: usize| Bernstein::<3>(h.map(|x| x[k]));
    let d2 = |k: usize| Bernstein::<2>(g.map(|x| x[k]));
    let cross = |i: usize, j: usize| -> Bernstein<4> {
        let (a, b): (Bernstein<4>, Bernstein<4>) = (d1(i).mul(&d2(j)), d1(j).mul(&d2(i)));
        a.sub(&b)
    };
    let square = |b: &Bernstein<4>| -> Bernstein<7> { b.mul(b) };
    let c = [cross(1, 2), cross(2, 0), cross(0, 1)];
    let c2 = square(&c[0]).add(&square(&c[1])).add(&square(&c[2]));
    let speed2: Bernstein<5> =
        (0..3).fold(Bernstein([0.0; 5]), |acc, k| acc.add(&d1(k).mul(&d1(k))));
    let tol2 = (FRENET_DEGENERATE * g[0].length().max(g[1].length())).powi(2);
    let floor = Bernstein(speed2.elevate::<7>().0.map(|x| x * tol2));
    let f = c2.sub(&floor);
    let err = 1e-12 * (c2.magnitude() + floor.magnitude());
    let mut stack: ArrayVec<Bernstein<7>, 8> = ArrayVec::new();
    stack.push(f.restrict(lo, hi));
    let mut cells = 0;
    while let Some(b) = stack.pop() {
        cells += 1;
        if b.range().0 > err {
            continue;
        }
        if cells + stack.len() + 2 > CURVED_CELLS || stack.is_full() {
            return false;
        }
        let (l, r) = b.split(0.5);
        stack.push(r);
        stack.push(l);
    }
    true
}

/// Every parameter in `(lo, hi)` where [`frenet_shift`] changes value, ascending: the ends of
/// the stretches around inflections (and strand ends) where `a' x a''` is negligible, and inside
/// a stretch the point where the shift changes side (the inflection). The Frenet frame of
/// [`frame_r`] may jump there (by a half turn at an inflection of a planar axis), and nowhere
/// else: between two of them it is smooth, and an enclosure over a subinterval, which decides
/// the shift at its midpoint, holds the frame at every point of it.
///
/// The stretches are found rigorously (roots of a polynomial by [`isolate_roots`]) and each end
/// is then bisected on `frenet_shift` itself, so it is where the `f64` evaluation switches, to
/// the last bit. (A stretch that only touches the tolerance, a double root, may be missed; the
/// frame then moves by at most `1e-7` in `u` there, continuously up to the tolerance.)
///
/// A strand's end segments have `a'' = 0` at the strand's root or tip (their reflected end
/// point), so a stretch of about `1e-9` there that [`clearly_curved`] cannot clear on the whole
/// range: where it clears all but a short stretch ([`END_STRETCHES`]) at one end or both, only
/// those ends are isolated (the same switches: none lies where the certificate holds, and each
/// is found by bisecting the shift near it), which saves the isolation's descent through the
/// rest.
pub(crate) fn frenet_switches(axis: &CubicBezier, lo: f64, hi: f64) -> ArrayVec<f64, 8> {
    if clearly_curved(axis, lo, hi) {
        return ArrayVec::new();
    }
    for end in END_STRETCHES {
        let (a, b) = (lo + end, hi - end);
        if !(a < b) {
            break;
        }
        if clearly_curved(axis, a, hi) {
            return isolated_switches(axis, lo, a);
        }
        if clearly_curved(axis, lo, b) {
            return isolated_switches(axis, b, hi);
        }
        if clearly_curved(axis, a, b) {
            let mut out = isolated_switches(axis, lo, a);
            for u in isolated_switches(axis, b, hi) {
                if out.try_push(u).is_err() {
                    break;
                }
            }
            return out;
        }
    }
    isolated_switches(axis, lo, hi)
}

/// How much of the range at an end [`frenet_switches`] tries to isolate alone, shortest first (a
/// strand end's degenerate stretch is about `1e-9` long, and the rest of the range clears the
/// certificate's margin from about `1e-5` on for most axes; the isolation's cost grows with the
/// logarithm of the length).
const END_STRETCHES: [f64; 2] = [1.0 / 65536.0, 1.0 / 256.0];

/// [`frenet_switches`] by root isolation, without [`clearly_curved`]'s shortcut.
///
/// [`Degenerate`] is homogeneous (of degree 4) in the axis' size, so it is isolated on the axis
/// scaled to about unit size by a power of two: the same roots, and no square that underflows
/// or overflows (an axis `1e-80` across squared its derivatives' cross product to 0 everywhere).
/// The switches themselves are bisected on [`frenet_shift`] of the axis as given.
fn isolated_switches(axis: &CubicBezier, lo: f64, hi: f64) -> ArrayVec<f64, 8> {
    let mut out = ArrayVec::new();
    let unit = unit_scaled(axis);
    let m = unit.d2(0.0).length().max(unit.d2(1.0).length());
    let f = Degenerate {
        axis: &unit,
        tol2: (FRENET_DEGENERATE * m).powi(2),
    };
    let opts = IsolateOptions {
        min_width: 1e-15,
        tangent_tolerance: 0.0,
        max_evaluations: 400,
        u_shaped: false,
    };
    let mut roots = ArrayVec::new();
    isolate_roots(&f, lo, hi, &opts, &mut roots);
    let shift = |u: f64| frenet_shift(axis, u);
    let mut candidates: ArrayVec<f64, 33> = roots.iter().copied().collect();
    // Inside a stretch (between two of its ends, or an end and lo or hi) the side the frame is
    // taken from flips once, at the inflection: a candidate where the shifts at the stretch's
    // ends differ, bisected on the shift.
    let mut ends: ArrayVec<f64, 18> = ArrayVec::new();
    ends.push(lo);
    ends.extend(roots.iter().copied());
    ends.push(hi);
    for w in ends.windows(2) {
        let (mut a, mut b) = (w[0], w[1]);
        let (sa, sb) = (shift(a.next_up()), shift(b.next_down()));
        if sa == 0.0 || sb == 0.0 || sa == sb || !(a < b) {
            continue;
        }
        loop {
            let mid = 0.5 * (a + b);
            if mid <= a || mid >= b {
                break;
            }
            if shift(mid) == sa {
                a = mid;
            } else {
                b = mid;
            }
        }
        if !candidates.is_full() {
            candidates.push(b);
        }
    }
    candidates.sort_by(f64::total_cmp);
    for r in candidates {
        // Bracket the switch near r: the closest points either side with different shifts.
        let mut step = 4.0 * f64::EPSILON * r.abs().max(1e-300);
        let (mut a, mut b) = (r, r);
        while shift(a) == shift(b) && step < 1e-6 {
            a = (r - step).max(lo);
            b = (r + step).min(hi);
            step *= 4.0;
        }
        if shift(a) == shift(b) {
            continue;
        }
        let sa = shift(a);
        loop {
            let mid = 0.5 * (a + b);
            if mid <= a || mid >= b {
                break;
            }
            if shift(mid) == sa {
                a = mid;
            } else {
                b = mid;
            }
        }
        // The switch lies between the adjacent floats a and b; b is the first with the new shift.
        if b > lo && b < hi && !out.is_full() && out.last().is_none_or(|&l| l < b) {
            out.push(b);
        }
    }
    out
}

/// `axis` scaled by the power of two nearest `1 / max |coordinate|` (exactly, as a power of two
/// scales), or as it is if its coordinates are all 0 or not finite.
fn unit_scaled(axis: &CubicBezier) -> CubicBezier {
    let extent = axis
        .points
        .iter()
        .fold(0.0f64, |m, p| m.max(p.abs().max_element()));
    if !(extent > 0.0 && extent.is_finite()) {
        return *axis;
    }
    // In two factors, each a normal power of two, for extents near the ends of the range.
    let e = -(extent.log2().round() as i32);
    let (e1, e2) = (e / 2, e - e / 2);
    let (s1, s2) = (2f64.powi(e1), 2f64.powi(e2));
    CubicBezier::new(axis.points.map(|p| p * s1 * s2))
}

/// The projection frame ([`Framing::Projected`]) from `a'` (any positive multiple of it) and the
/// reference `r`: `t = a'/|a'|`, `b = (a' x r)/|a' x r|`, `n = b x t`.
///
/// `n` is the component of `r` normal to `t`, normalised: `(a' x r) x a' = |a'|^2 r - (a'.r) a'`.
#[inline(always)]
pub(crate) fn projected_frame<T: Real>(d1: V3<T>, r: DVec3) -> [V3<T>; 3] {
    let c = d1.cross_cst(r);
    let t = d1.divided(d1.norm2().sqrt());
    let b = c.divided(c.norm2().sqrt());
    [t, b.cross(t), b]
}

/// The frame `(t, n, b)` at `u` over any [`Real`].
///
/// Frenet: `t = a'/|a'|`, `b = (a' x a'')/|a' x a''|`, `n = b x t`. Where `a' x a''` vanishes
/// at an isolated point (an inflection), the frame on each side is that side's limit, the one
/// at the inflection itself the limit from the right ([`frenet_shift`]); for point-symmetric
/// sections both limits give the same surface, for others the solid has a seam there.
/// Projected: `t = a'/|a'|`, `b = (a' x r)/|a' x r|`, `n = b x t` at `u` (`a'` scaled to unit
/// size, so no product underflows).
#[inline]
pub fn frame_r<T: Real>(axis: &CubicBezier, framing: &Framing, u: T) -> [V3<T>; 3] {
    match framing {
        Framing::Fixed(f) => [V3::cst(f.t), V3::cst(f.n), V3::cst(f.b)],
        Framing::Projected(r) => {
            let k1 = axis.speed_scale();
            projected_frame(axis.d1_r(u).scale(k1), *r)
        }
        Framing::Frenet => {
            let u = u + T::cst(frenet_shift(axis, u.value()));
            let [k1, k2] = axis.derivative_scales();
            frenet_frame(axis.d1_r(u).scale(k1), axis.d2_r(u).scale(k2))
        }
    }
}

/// The tangent `t = a'/|a'|` of [`frame_r`]'s frame at `u`, to the bit, without its `n` and `b`
/// (what a renderer's hair shading needs): Frenet's taken at the same shifted `u` beside an
/// inflection, a fixed frame's own `t`.
pub fn tangent_at(axis: &CubicBezier, framing: &Framing, u: f64) -> DVec3 {
    let unit = |d1: V3<f64>| d1.divided(d1.norm2().sqrt()).value();
    match framing {
        Framing::Fixed(f) => f.t,
        Framing::Projected(_) => unit(axis.d1_r(u).scale(axis.speed_scale())),
        Framing::Frenet => {
            let u = u + frenet_shift(axis, u);
            let [k1, _] = axis.derivative_scales();
            unit(axis.d1_r(u).scale(k1))
        }
    }
}

/// The Frenet frame from `a'` and `a''` (any positive multiples of them): `t = a'/|a'|`,
/// `b = (a' x a'')/|a' x a''|`, `n = b x t`.
#[inline(always)]
fn frenet_frame<T: Real>(d1: V3<T>, d2: V3<T>) -> [V3<T>; 3] {
    let bt = d1.cross(d2);
    let t = d1.divided(d1.norm2().sqrt());
    let b = bt.divided(bt.norm2().sqrt());
    [t, b.cross(t), b]
}

/// [`frame_r`] in `f64` at `u`, given `a'(u)` and `a''(u)` as [`CubicBezier::d1`] and
/// [`CubicBezier::d2`] evaluate them: the same frame to the bit, without evaluating them again
/// (where the Frenet frame is taken from beside `u`, [`frenet_shift`], it is [`frame_r`]'s).
/// They are brought to unit size by their own scales ([`vector_scale`]), not the hodographs'
/// ([`CubicBezier::derivative_scales`]): powers of two either way, so the same bits wherever
/// neither under- or overflows.
pub(crate) fn frame_with(
    axis: &CubicBezier,
    framing: &Framing,
    u: f64,
    d1: DVec3,
    d2: DVec3,
) -> Frame {
    let [t, n, b] = match framing {
        Framing::Fixed(f) => return **f,
        Framing::Projected(r) => projected_frame(V3::cst(d1 * vector_scale(d1)), *r),
        Framing::Frenet => {
            let shift = frenet_shift_with(axis, u, d1, d2);
            if shift == 0.0 {
                frenet_frame(
                    V3::cst(d1 * vector_scale(d1)),
                    V3::cst(d2 * vector_scale(d2)),
                )
            } else {
                frame_r(axis, framing, u)
            }
        }
    };
    Frame {
        t: t.value(),
        n: n.value(),
        b: b.value(),
    }
}

/// The frame at `u` with its rates of change, for normals and tests.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameAt {
    /// The frame.
    pub frame: Frame,
    /// The speed `|a'(u)|`.
    pub speed: f64,
    /// The curvature `kappa = |a' x a''| / |a'|^3` (0 for a fixed frame).
    pub curvature: f64,
    /// The torsion `tau = (a' x a'') . a''' / |a' x a''|^2` (0 for a fixed frame).
    pub torsion: f64,
    /// `(t'(u), n'(u), b'(u))` where they do not follow from the Frenet-Serret formulas (a
    /// projected frame: by forward-mode differentiation of [`frame_r`]); `None` for Frenet and
    /// fixed frames. [`FrameAt::derivatives`] returns them.
    pub rates: Option<[DVec3; 3]>,
}

impl FrameAt {
    /// Evaluates the frame, curvature and torsion at `u`.
    pub fn new(axis: &CubicBezier, framing: &Framing, u: f64) -> Self {
        let [t, n, b] = frame_r(axis, framing, u);
        let frame = Frame {
            t: t.value(),
            n: n.value(),
            b: b.value(),
        };
        let speed = axis.d1(u).length();
        match framing {
            Framing::Fixed(_) => FrameAt {
                frame,
                speed,
                curvature: 0.0,
                torsion: 0.0,
                rates: None,
            },
            Framing::Projected(_) => {
                // The curve's own curvature and torsion at u (the frame is not Frenet's, but
                // they describe the axis all the same), scaled as below.
                let [k1, k2] = axis.derivative_scales();
                let d1 = axis.d1(u) * k1;
                let c = d1.cross(axis.d2(u) * k2);
                let c2 = c.length_squared();
                let torsion = if c2 > 0.0 {
                    k1 * k2 * c.dot(axis.third_derivative()) / c2
                } else {
                    0.0
                };
                // n'(u), b'(u) exactly: the frame's formula evaluated on dual numbers.
                let [dt, dn, db] = frame_r(axis, framing, Dual::var(u));
                FrameAt {
                    frame,
                    speed,
                    curvature: c2.sqrt() * k1 * k1 / (k2 * d1.length().powi(3)),
                    torsion,
                    rates: Some([
                        DVec3::new(dt.x.d, dt.y.d, dt.z.d),
                        DVec3::new(dn.x.d, dn.y.d, dn.z.d),
                        DVec3::new(db.x.d, db.y.d, db.z.d),
                    ]),
                }
            }
            Framing::Frenet => {
                // Curvature and torsion where the frame was taken (see `frenet_shift`).
                // With a' and a'' scaled by k1 and k2 (see `derivative_scales`) so no product
                // underflows: kappa = |a' x a''| / |a'|^3 = |c| k1^2 / (k2 |a'_s|^3) and
                // tau = (a' x a'').a''' / |a' x a''|^2 = k1 k2 (c.a''') / |c|^2, c = a'_s x a''_s.
                let us = u + frenet_shift(axis, u);
                let [k1, k2] = axis.derivative_scales();
                let d1 = axis.d1(us) * k1;
                let c = d1.cross(axis.d2(us) * k2);
                let c2 = c.length_squared();
                let torsion = if c2 > 0.0 {
                    k1 * k2 * c.dot(axis.third_derivative()) / c2
                } else {
                    0.0
                };
                FrameAt {
                    frame,
                    speed,
                    curvature: c2.sqrt() * k1 * k1 / (k2 * d1.length().powi(3)),
                    torsion,
                    rates: None,
                }
            }
        }
    }

    /// The frame at `u` and `(t'(u), n'(u), b'(u))` ([`FrameAt::derivatives`]), what a
    /// normal needs: for a projected frame from one evaluation of [`frame_r`] on dual numbers
    /// (its values are the `f64` frame's to the bit), without the curvature and torsion that
    /// [`FrameAt::new`] also computes.
    pub fn frame_and_rates(axis: &CubicBezier, framing: &Framing, u: f64) -> (Frame, [DVec3; 3]) {
        if let Framing::Projected(_) = framing {
            let [t, n, b] = frame_r(axis, framing, Dual::var(u));
            let value = |x: V3<Dual<f64>>| DVec3::new(x.x.v, x.y.v, x.z.v);
            let frame = Frame {
                t: value(t),
                n: value(n),
                b: value(b),
            };
            let rate = |x: V3<Dual<f64>>| DVec3::new(x.x.d, x.y.d, x.z.d);
            return (frame, [rate(t), rate(n), rate(b)]);
        }
        let at = FrameAt::new(axis, framing, u);
        (at.frame, at.derivatives())
    }

    /// `(t'(u), n'(u), b'(u))` by the Frenet-Serret formulas with respect to `u`
    /// (seed 2.4, corrected by errata 2: the arc-length formulas times the speed `|a'(u)|`):
    /// `t' = |a'| kappa n`, `n' = |a'| (-kappa t + tau b)`, `b' = -|a'| tau n`; for a projected
    /// frame [`FrameAt::rates`].
    ///
    /// (For the projection frame, `b = C/|C|` with `C = a' x r`, so
    /// `b' = (C' - (C'.b) b)/|C|` with `C' = a'' x r`, and `n = b x t` gives
    /// `n' = b' x t + b x t'`; `t' = |a'| kappa n_F` with Frenet's normal `n_F`. The dual numbers
    /// evaluate exactly these.)
    pub fn derivatives(&self) -> [DVec3; 3] {
        if let Some(r) = self.rates {
            return r;
        }
        let (s, k, tau) = (self.speed, self.curvature, self.torsion);
        let Frame { t, n, b } = self.frame;
        [s * k * n, s * (-k * t + tau * b), -s * tau * n]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn helix_like() -> CubicBezier {
        CubicBezier::new([
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.2, 0.3),
            DVec3::new(1.3, 1.1, 0.9),
            DVec3::new(0.4, 1.6, 1.8),
        ])
    }

    #[test]
    fn frenet_frame_is_orthonormal_and_right_handed() {
        let c = helix_like();
        for i in 0..=20 {
            let f = FrameAt::new(&c, &Framing::Frenet, i as f64 / 20.0).frame;
            for (name, v) in [("t", f.t), ("n", f.n), ("b", f.b)] {
                assert!((v.length() - 1.0).abs() < 1e-14, "{name} not unit at {i}");
            }
            assert!(
                f.t.dot(f.n).abs() < 1e-14 && f.t.dot(f.b).abs() < 1e-14,
                "orthogonality"
            );
            assert!((f.n.cross(f.b) - f.t).length() < 1e-14, "n x b = t");
            // n points toward the centre of curvature: a'' has a non-negative n component.
            assert!(c.d2(i as f64 / 20.0).dot(f.n) >= 0.0, "n toward the bend");
        }
    }

    /// Checks `FrameAt::derivatives` at `u` against central differences of the frame (step
    /// 1e-6, to 1e-7 of the rate or of 1), and returns them.
    fn assert_rates_match_differences(
        c: &CubicBezier,
        framing: &Framing,
        u: f64,
        name: &str,
    ) -> [DVec3; 3] {
        let h = 1e-6;
        let (p, m) = (
            FrameAt::new(c, framing, u + h).frame,
            FrameAt::new(c, framing, u - h).frame,
        );
        let fd = [
            (p.t - m.t) / (2.0 * h),
            (p.n - m.n) / (2.0 * h),
            (p.b - m.b) / (2.0 * h),
        ];
        let an = FrameAt::new(c, framing, u).derivatives();
        for k in 0..3 {
            let scale = an[k].length().max(1.0);
            assert!(
                (fd[k] - an[k]).length() < 1e-7 * scale,
                "{name} u={u} component {k}: fd {:?} exact {:?}",
                fd[k],
                an[k]
            );
        }
        an
    }

    /// Errata 2: the frame derivatives with the speed factor equal finite differences of the
    /// frame; without the factor they would be off by `|a'(u)|` (here between about 1 and 3).
    #[test]
    fn frame_derivatives_match_finite_differences() {
        let c = helix_like();
        for i in 1..20 {
            let u = i as f64 / 20.0;
            let at = FrameAt::new(&c, &Framing::Frenet, u);
            assert_rates_match_differences(&c, &Framing::Frenet, u, "Frenet");
            assert!(
                (at.speed - 1.0).abs() > 0.05,
                "test needs |a'| != 1 to test errata 2"
            );
        }
    }

    #[test]
    fn curvature_and_torsion_of_the_twisted_cubic() {
        // a(u) = (u, u^2, u^3) in Bernstein form; textbook values
        // kappa = 2 sqrt(9u^4 + 9u^2 + 1) / (1 + 4u^2 + 9u^4)^(3/2), tau = 3 / (9u^4 + 9u^2 + 1).
        let c = CubicBezier::new([
            DVec3::ZERO,
            DVec3::new(1.0 / 3.0, 0.0, 0.0),
            DVec3::new(2.0 / 3.0, 1.0 / 3.0, 0.0),
            DVec3::new(1.0, 1.0, 1.0),
        ]);
        for i in 0..=10 {
            let u = i as f64 / 10.0;
            let f = FrameAt::new(&c, &Framing::Frenet, u);
            let g = 9.0 * u.powi(4) + 9.0 * u * u + 1.0;
            let kappa = 2.0 * g.sqrt() / (1.0 + 4.0 * u * u + 9.0 * u.powi(4)).powf(1.5);
            assert!(
                (f.curvature - kappa).abs() < 1e-13,
                "kappa at {u}: {} vs {kappa}",
                f.curvature
            );
            assert!(
                (f.torsion - 3.0 / g).abs() < 1e-13,
                "tau at {u}: {} vs {}",
                f.torsion,
                3.0 / g
            );
        }
        // A planar curve has no torsion.
        let p = CubicBezier::new([
            DVec3::ZERO,
            DVec3::X,
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(3.0, 2.0, 0.0),
        ]);
        assert_eq!(
            FrameAt::new(&p, &Framing::Frenet, 0.4).torsion,
            0.0,
            "planar torsion"
        );
    }

    #[test]
    fn straight_segments_get_the_hinted_or_default_frame() {
        let s = CubicBezier::new([
            DVec3::ZERO,
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(3.0, 0.0, 0.0),
        ]);
        let Some(Framing::Fixed(f)) = Framing::for_axis(&s, None) else {
            panic!("straight axis must get a fixed frame");
        };
        // t = e_x; smallest |t_k| ties between y and z: lowest k wins, so n = e_y, b = e_z.
        assert_eq!(
            (f.t, f.n, f.b),
            (DVec3::X, DVec3::Y, DVec3::Z),
            "default frame"
        );
        let Some(Framing::Fixed(f)) = Framing::for_axis(&s, Some(DVec3::new(0.0, 1.0, 1.0))) else {
            panic!("hinted frame");
        };
        let r = 0.5f64.sqrt();
        assert!(
            (f.n - DVec3::new(0.0, r, r)).length() < 1e-15,
            "n closest to hint"
        );
        assert_eq!(
            Framing::for_axis(&s, Some(DVec3::X)),
            None,
            "hint parallel to t"
        );
        // Nearly straight within tolerance is straight; just above it is Frenet.
        let mut near = s;
        near.points[1].y = 0.5e-9 * 3.0;
        assert!(
            matches!(Framing::for_axis(&near, None), Some(Framing::Fixed(_))),
            "within tol"
        );
        near.points[1].y = 2e-9 * 3.0;
        assert_eq!(
            Framing::for_axis(&near, None),
            Some(Framing::Frenet),
            "above tol"
        );
        // Just above the tolerance the Frenet frame is still well defined: b is e_z to 1e-6.
        let f = FrameAt::new(&near, &Framing::Frenet, 0.3).frame;
        assert!(
            (f.b.abs() - DVec3::Z).length() < 1e-6,
            "nearly straight frame {f:?}"
        );
    }

    #[test]
    fn inflection_point_takes_the_limit() {
        let c = s_curve();
        let at = FrameAt::new(&c, &Framing::Frenet, 0.5).frame;
        let right = FrameAt::new(&c, &Framing::Frenet, 0.5 + 1e-4).frame;
        assert!(
            at.b.is_finite() && at.n.is_finite(),
            "frame finite at the inflection"
        );
        assert!(
            (at.b - right.b).length() < 1e-9,
            "limit from the right: {at:?} vs {right:?}"
        );
    }

    /// The switches of `frenet_shift`: none on a curve whose `a' x a''` never vanishes; on a
    /// planar S-curve (`examples/xray.toml`'s axis, inflection at 1/2) the two ends of the
    /// stretch around the inflection, each the first float with the new shift, and at the
    /// first of them the binormal turns by half a turn; at a strand root (`a''(0) = 0`) the
    /// end of the stretch at `u = 0`; and none outside the range asked for.
    #[test]
    fn frenet_switches_find_where_the_frame_may_jump() {
        assert!(frenet_switches(&helix_like(), 0.0, 1.0).is_empty(), "helix");
        let s_curve = CubicBezier::new([
            DVec3::new(-0.3, -1.1, 0.5),
            DVec3::new(-0.1, -0.4, 0.6),
            DVec3::new(0.1, 0.4, 0.4),
            DVec3::new(0.3, 1.1, 0.5),
        ]);
        // The degenerate stretch's two ends, where the frame is taken from 1e-7 away (and moves
        // by as much), and the inflection between them, where each side takes its own limit and
        // the binormal flips.
        let sw = frenet_switches(&s_curve, -1e-11, 1.0 + 1e-11);
        assert_eq!(sw.len(), 3, "{sw:?}");
        for &u in &sw {
            assert!((u - 0.5).abs() < 1e-8, "{sw:?}");
            assert_ne!(
                frenet_shift(&s_curve, u.next_down()),
                frenet_shift(&s_curve, u),
                "a switch at {u}"
            );
        }
        let b = |u: f64| FrameAt::new(&s_curve, &Framing::Frenet, u).frame.b;
        for (k, &u) in sw.iter().enumerate() {
            let turn = b(u.next_down()).dot(b(u));
            if k == 1 {
                assert!(turn < -0.999, "half a turn at the inflection {u}: {turn}");
            } else {
                assert!(turn > 0.999, "no turn at the stretch's end {u}: {turn}");
            }
        }
        // The inflection of this planar S (a' x a'' = 0 there) by bisection, independently.
        let c = |u: f64| s_curve.d1(u).cross(s_curve.d2(u)).z;
        let (mut a, mut bb) = (0.4, 0.6);
        for _ in 0..80 {
            let m = 0.5 * (a + bb);
            if (c(m) > 0.0) == (c(a) > 0.0) {
                a = m;
            } else {
                bb = m;
            }
        }
        assert!(
            (sw[1] - a).abs() < 1e-15,
            "the switch {} is the inflection {a}",
            sw[1]
        );
        assert!(frenet_switches(&s_curve, 0.0, 0.49).is_empty(), "outside");
        let p1 = DVec3::new(0.02, 0.05, 0.01);
        let root = CubicBezier::new([DVec3::ZERO, p1, 2.0 * p1, DVec3::new(0.1, 0.13, -0.03)]);
        let sw = frenet_switches(&root, -1e-11, 1.0 + 1e-11);
        assert_eq!(sw.len(), 1, "{sw:?}");
        assert!(sw[0] > 0.0 && sw[0] < 1e-6, "{sw:?}");
    }

    /// Control points at `x = 0, 1, 2, 3` with `y` and `z` uniform in `[-1, 1]`: a random
    /// curved axis.
    fn random_points(rng: &mut crate::test_rng::Lcg) -> [DVec3; 4] {
        std::array::from_fn(|j| DVec3::new(j as f64, rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)))
    }

    /// An S in the xy plane, its inflection anywhere inside, bent out of the plane by 1e-12 to
    /// 1e-1.
    fn bent_s(rng: &mut crate::test_rng::Lcg) -> [DVec3; 4] {
        let (a, b) = (rng.range(0.2, 2.0), rng.range(0.2, 2.0));
        [
            DVec3::ZERO,
            DVec3::new(1.0, a, 0.0),
            DVec3::new(2.0, -b, 10f64.powf(rng.range(-12.0, -1.0))),
            DVec3::new(3.0, 0.0, 0.0),
        ]
    }

    /// [`clearly_curved`]'s certificate holds only where the frame has no switch: wherever it
    /// passes, [`Degenerate`] is positive at 4001 samples (in `f64`, of the unscaled axis) and
    /// the isolation finds no switch; it passes for most curved axes, and leaves to the
    /// isolation the S-curves bent out of plane too little to clear the tolerance. Axes: random ones, near-planar S-curves with their
    /// inflection anywhere (bent out of plane by 1e-12 to 1e-1), strand ends with `a'' = 0`,
    /// nearly straight ones (bends of 1e-12 to 1e-3), at scales 1e-120 to 1e120.
    #[test]
    fn clearly_curved_axes_have_no_switch() {
        let mut rng = crate::test_rng::Lcg(83);
        let (lo, hi) = (-1e-11, 1.0 + 1e-11);
        let (mut passed, mut random, mut s_left) = (0, 0, 0);
        for case in 0..3000 {
            let scale = 10f64.powf(rng.range(-120.0, 120.0));
            let mut p = random_points(&mut rng);
            let kind = case % 4;
            match kind {
                1 => p = bent_s(&mut rng),
                // A strand end: a'' = 0 at u = 0.
                2 => p[2] = 2.0 * p[1] - p[0],
                // Nearly straight.
                3 => {
                    let bend = 10f64.powf(rng.range(-12.0, -3.0));
                    p = std::array::from_fn(|j| {
                        DVec3::new(
                            j as f64,
                            bend * rng.range(-1.0, 1.0),
                            bend * rng.range(-1.0, 1.0),
                        )
                    });
                }
                _ => {}
            }
            let axis = CubicBezier::new(p.map(|x| x * scale));
            if !clearly_curved(&axis, lo, hi) {
                s_left += usize::from(kind == 1);
                continue;
            }
            passed += 1;
            random += usize::from(kind == 0);
            let unscaled = CubicBezier::new(p);
            let f = Degenerate {
                axis: &unscaled,
                tol2: (FRENET_DEGENERATE
                    * unscaled.d2(0.0).length().max(unscaled.d2(1.0).length()))
                .powi(2),
            };
            for i in 0..=4000 {
                let u = lo + (hi - lo) * i as f64 / 4000.0;
                assert!(f.eval(u) > 0.0, "case {case}: degenerate at {u}: {p:?}");
            }
            assert!(
                isolated_switches(&axis, lo, hi).is_empty(),
                "case {case}: switches {:?} of {p:?}",
                isolated_switches(&axis, lo, hi)
            );
        }
        assert!(
            random > 600,
            "most random axes should pass: {random} of 750"
        );
        assert!(passed > 900, "curved axes should pass: {passed}");
        assert!(
            s_left > 200,
            "S-curves bent 1e-12 to 1e-1 should not all pass: {s_left}"
        );
    }

    /// Isolating only a strand's end, where the rest of the axis is certified clear, finds the
    /// switches of the whole range, to the bit; each is where the shift changes, and the shift
    /// is constant between them at samples spaced log-uniformly from 1e-2 down to 1e-15 from
    /// either end (the middle is clear by the certificate). Axes with `a'' = 0` at the root or
    /// at the tip (a cubic with both is straight), curved at random or S-shaped with an
    /// inflection inside, at scales 1e-120 to 1e120 (before the isolation scaled the axis, its
    /// squares underflowed at 1e-80 and it found switches everywhere or nowhere).
    #[test]
    fn strand_ends_alone_give_the_switches() {
        let mut rng = crate::test_rng::Lcg(29);
        let (lo, hi) = (-1e-11, 1.0 + 1e-11);
        let (mut shortcut, mut with_switches) = (0, 0);
        for case in 0..2000 {
            let scale = 10f64.powf(rng.range(-120.0, 120.0));
            let mut p = random_points(&mut rng);
            if case % 5 == 4 {
                p = bent_s(&mut rng);
            }
            if case % 2 == 0 {
                p[2] = 2.0 * p[1] - p[0];
            } else {
                p[1] = 2.0 * p[2] - p[3];
            }
            let axis = CubicBezier::new(p.map(|x| x * scale));
            let e = END_STRETCHES[0];
            if clearly_curved(&axis, lo, hi)
                || !(clearly_curved(&axis, lo + e, hi) || clearly_curved(&axis, lo, hi - e))
            {
                continue;
            }
            shortcut += 1;
            let found = frenet_switches(&axis, lo, hi);
            assert_eq!(
                found,
                isolated_switches(&axis, lo, hi),
                "case {case}: the ends alone against the whole range, {p:?} x {scale:e}"
            );
            with_switches += usize::from(!found.is_empty());
            let shift = |u: f64| frenet_shift(&axis, u);
            for &u in &found {
                assert_ne!(
                    shift(u.next_down()),
                    shift(u),
                    "case {case}: no switch at {u}"
                );
            }
            let mut samples: Vec<f64> = (0..=650)
                .map(|i| 10f64.powf(-2.0 - 13.0 * i as f64 / 650.0))
                .flat_map(|x| [lo + x, hi - x])
                .collect();
            samples.sort_by(f64::total_cmp);
            for w in samples.windows(2) {
                assert!(
                    shift(w[0]) == shift(w[1]) || found.iter().any(|&u| w[0] < u && u <= w[1]),
                    "case {case}: the shift changes between {} and {}, switches {found:?}",
                    w[0],
                    w[1]
                );
            }
        }
        assert!(shortcut > 1500, "the shortcut should be taken: {shortcut}");
        assert!(
            with_switches > 1500,
            "strand ends have switches: {with_switches}"
        );
    }

    /// A planar S curve with an exact inflection at `u = 1/2` (`a'' = 0` there by symmetry).
    fn s_curve() -> CubicBezier {
        CubicBezier::new([
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(2.0, -1.0, 0.0),
            DVec3::new(3.0, 0.0, 0.0),
        ])
    }

    /// The S curve bent slightly out of its plane: the Frenet frame turns by nearly half a turn
    /// within a short stretch around the near-inflection at `u = 1/2`.
    fn near_inflection() -> CubicBezier {
        let mut p = s_curve().points;
        p[2].z = 0.02;
        CubicBezier::new(p)
    }

    /// The frame from given `a'` and `a''` ([`frame_with`], the hit finish's) and the tangent
    /// alone ([`tangent_at`], the renderer's) are [`frame_r`]'s to the bit, for every framing:
    /// on a helix, on a near-inflection, on an exact inflection (where the Frenet frame is
    /// taken from beside `u`), at 1e4 and at 1e-6 of the size, and at 1e-150, 1e150, 1e-170 and
    /// 1e170 (where unscaled products, and at the last two unscaled squared lengths of `a'`,
    /// would under- and overflow).
    #[test]
    fn frame_from_given_derivatives_is_the_same_frame() {
        let inflection = s_curve();
        let fixed = Framing::Fixed(Box::new(Frame {
            t: DVec3::X,
            n: DVec3::Y,
            b: DVec3::Z,
        }));
        let mut shifted = 0;
        for (c, scale, offset) in [
            (helix_like(), 1.0, 0.0),
            (near_inflection(), 1.0, 0.0),
            (inflection, 1.0, 0.0),
            (helix_like(), 1e-6, 1e4),
            (inflection, 1e-6, 1e4),
            (helix_like(), 1e-150, 0.0),
            (near_inflection(), 1e150, 0.0),
            (helix_like(), 1e-170, 0.0),
            (near_inflection(), 1e170, 0.0),
        ] {
            let c = CubicBezier::new(c.points.map(|p| p * scale + DVec3::splat(offset)));
            for framing in [Framing::Frenet, Framing::Projected(DVec3::Z), fixed.clone()] {
                // 2001 samples, and a few within 1e-11 of the inflections' u = 1/2.
                let near = (-5..=5).map(|j| 0.5 + j as f64 * 2e-12);
                for u in (0..=2000).map(|i| i as f64 / 2000.0).chain(near) {
                    shifted +=
                        usize::from(framing == Framing::Frenet && frenet_shift(&c, u) != 0.0);
                    let [t, n, b] = frame_r(&c, &framing, u).map(|v| v.value());
                    let f = frame_with(&c, &framing, u, c.d1(u), c.d2(u));
                    let alone = tangent_at(&c, &framing, u);
                    for (x, y) in [(t, f.t), (n, f.n), (b, f.b), (t, alone)] {
                        assert_eq!(
                            x.to_array().map(f64::to_bits),
                            y.to_array().map(f64::to_bits)
                        );
                    }
                }
            }
        }
        assert!(shifted >= 5, "frames taken beside an inflection: {shifted}");
    }

    /// The projection frame is orthonormal and right-handed, and `n` is the reference made
    /// normal to `t` (checked against `r - (r.t) t` normalised, the other form of the formula),
    /// at every sample of three axes, with references chosen to keep away from their tangents.
    #[test]
    fn projected_frame_is_orthonormal_and_follows_the_reference() {
        let straight = CubicBezier::new([0.0, 1.0, 2.0, 3.0].map(|x| DVec3::new(x, 0.1 * x, 0.0)));
        for (name, c, r) in [
            ("helix", helix_like(), DVec3::new(0.3, -0.8, 0.5)),
            ("S", near_inflection(), DVec3::Z),
            ("straight", straight, DVec3::new(0.2, 0.4, -1.0)),
        ] {
            let framing = Framing::Projected(r);
            assert!(
                Framing::projection_sine(&c, r) > 0.1,
                "{name}: test reference too close to a tangent"
            );
            for i in 0..=40 {
                let u = i as f64 / 40.0;
                let f = FrameAt::new(&c, &framing, u).frame;
                for (k, v) in [("t", f.t), ("n", f.n), ("b", f.b)] {
                    assert!(
                        (v.length() - 1.0).abs() < 1e-14,
                        "{name}: {k} not unit at {u}"
                    );
                }
                assert!(f.t.dot(f.n).abs() < 1e-14, "{name}: t.n at {u}");
                assert!(
                    (f.n.cross(f.b) - f.t).length() < 1e-14,
                    "{name}: n x b = t at {u}"
                );
                assert!(
                    (f.t - c.d1(u).normalize()).length() < 1e-14,
                    "{name}: t at {u}"
                );
                let rn = r.normalize();
                let want = (rn - rn.dot(f.t) * f.t).normalize();
                assert!(
                    (f.n - want).length() < 1e-14,
                    "{name}: n at {u}: {:?} vs {want:?}",
                    f.n
                );
            }
        }
    }

    /// [`FrameAt::frame_and_rates`] is [`FrameAt::new`]'s frame and derivatives to the bit,
    /// under every framing (a projected frame's by its own evaluation), at the ends, near an
    /// inflection and across the segment.
    #[test]
    fn frame_and_rates_are_frame_at_to_the_bit() {
        let fixed = Framing::Fixed(Box::new(Frame {
            t: DVec3::X,
            n: DVec3::Y,
            b: DVec3::Z,
        }));
        for (name, c) in [("helix", helix_like()), ("S", near_inflection())] {
            for framing in [
                Framing::Projected(DVec3::new(0.3, -0.8, 0.5)),
                Framing::Projected(DVec3::Z),
                Framing::Frenet,
                fixed.clone(),
            ] {
                for i in 0..=64 {
                    let u = i as f64 / 64.0;
                    let at = FrameAt::new(&c, &framing, u);
                    let (frame, rates) = FrameAt::frame_and_rates(&c, &framing, u);
                    assert_eq!(frame, at.frame, "{name}, {framing:?}: the frame at {u}");
                    assert_eq!(rates, at.derivatives(), "{name}, {framing:?}: rates at {u}");
                }
            }
        }
    }

    /// `n'(u)`, `b'(u)` (and `t'`) of the projection frame, from dual numbers, equal central
    /// differences of the frame (step 1e-6: truncation ~1e-12 times the third derivative,
    /// rounding ~1e-16 / 1e-6; 1e-7 relative leaves a wide margin), also where the axis is
    /// nearly inflected and its speed is far from 1; and they are not the Frenet-Serret ones.
    #[test]
    fn projected_frame_derivatives_match_finite_differences() {
        for (name, c, r) in [
            ("helix", helix_like(), DVec3::new(0.3, -0.8, 0.5)),
            ("S", near_inflection(), DVec3::Z),
        ] {
            let framing = Framing::Projected(r);
            let mut differs = 0.0f64;
            for i in 1..40 {
                let u = i as f64 / 40.0;
                let at = FrameAt::new(&c, &framing, u);
                let an = assert_rates_match_differences(&c, &framing, u, name);
                // The Frenet-Serret formula with this frame would be wrong: n' has a part
                // along b that is the projection frame's own turn, not the torsion's.
                let frenet_like = FrameAt { rates: None, ..at }.derivatives();
                differs = differs.max((frenet_like[1] - an[1]).length());
            }
            assert!(
                differs > 1e-2,
                "{name}: the projected rates are their own ({differs})"
            );
        }
    }

    /// The certified sine is a lower bound of the sampled `min |r x t|` (20001 samples) and
    /// tight to 10 % where that is not small; it is (close to) 0 for a reference along a
    /// tangent, and 0 for a zero or non-finite reference.
    #[test]
    fn projection_sine_bounds_the_smallest_angle_to_the_tangents() {
        let mut rng = crate::test_rng::Lcg(17);
        let mut tight = 0;
        for _ in 0..200 {
            let c = CubicBezier::new([
                DVec3::ZERO,
                rng.unit(),
                rng.unit() + DVec3::X,
                rng.unit() + 2.0 * DVec3::X,
            ]);
            if c.min_speed() < 1e-3 {
                continue;
            }
            let r = rng.unit();
            let bound = Framing::projection_sine(&c, r);
            let sampled = (0..=20000)
                .map(|i| r.cross(c.d1(i as f64 / 20000.0).normalize()).length())
                .fold(f64::INFINITY, f64::min);
            assert!(
                bound <= sampled + 1e-12,
                "bound {bound} above the sampled {sampled} for {c:?}, r {r}"
            );
            if sampled > 0.2 {
                assert!(
                    bound >= 0.9 * sampled,
                    "bound {bound} loose against {sampled} for {c:?}, r {r}"
                );
                tight += 1;
            }
            let along = c.d1(0.37).normalize();
            assert!(
                Framing::projection_sine(&c, along) < 1e-6,
                "along a tangent"
            );
        }
        assert!(tight > 50, "enough well-separated cases ({tight})");
        assert_eq!(
            Framing::projection_sine(&helix_like(), DVec3::ZERO),
            0.0,
            "zero reference"
        );
        assert_eq!(
            Framing::projection_sine(&helix_like(), DVec3::NAN),
            0.0,
            "NaN reference"
        );
    }

    /// A preferred reference far enough from the tangents is taken as it is; one along a tangent
    /// is replaced by one at least 30 degrees off every tangent (here: a planar S-curve, whose
    /// tangents sweep through about 110 degrees, gets its plane's normal or as good).
    #[test]
    fn projected_for_axis_keeps_the_reference_off_the_tangents() {
        let c = near_inflection();
        let good = DVec3::new(0.1, 0.2, 1.0);
        assert_eq!(
            Framing::projected_for_axis(&c, &[good]),
            Some(Framing::Projected(good.normalize())),
            "a good preferred reference"
        );
        let bad = c.d1(0.5).normalize();
        let Some(Framing::Projected(r)) = Framing::projected_for_axis(&c, &[bad]) else {
            panic!("a reference must be found");
        };
        let s = Framing::projection_sine(&c, r);
        assert!(s >= 0.5, "replacement {r} keeps sin {s}");
    }
}
