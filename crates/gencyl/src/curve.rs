//! The axis: a cubic Bezier space curve.

use glam::DVec3;

use crate::real::{Interval, Real, V3};

/// A cubic Bezier curve in Bernstein form,
/// `a(u) = (1-u)^3 P0 + 3u(1-u)^2 P1 + 3u^2(1-u) P2 + u^3 P3`, `u in [0, 1]`.
///
/// Derivatives come from the hodographs: `a'(u)` is the quadratic Bezier with control points
/// `3(P1-P0), 3(P2-P1), 3(P3-P2)`, `a''(u)` the line `6(P2-2P1+P0)` to `6(P3-2P2+P1)`, and
/// `a'''` the constant `6(P3-3P2+3P1-P0)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CubicBezier {
    /// The control points `P0..P3`.
    pub points: [DVec3; 4],
}

impl CubicBezier {
    /// The curve with control points `P0..P3`.
    pub fn new(points: [DVec3; 4]) -> Self {
        CubicBezier { points }
    }

    /// The same curve with every control point moved by `-origin`.
    pub fn translated(&self, origin: DVec3) -> Self {
        CubicBezier {
            points: self.points.map(|p| p - origin),
        }
    }

    /// The control points of `a'` (a quadratic Bezier).
    pub fn hodograph(&self) -> [DVec3; 3] {
        let p = &self.points;
        [
            3.0 * (p[1] - p[0]),
            3.0 * (p[2] - p[1]),
            3.0 * (p[3] - p[2]),
        ]
    }

    /// The control points of `a''` (a line).
    pub fn second_hodograph(&self) -> [DVec3; 2] {
        let p = &self.points;
        [
            6.0 * (p[2] - 2.0 * p[1] + p[0]),
            6.0 * (p[3] - 2.0 * p[2] + p[1]),
        ]
    }

    /// Powers of two near `[1 / max |a'|, 1 / max |a''|]` over the hodographs' control points
    /// (within a factor 2 but at the ends of the range; 1 for a vanishing one; [`unit_scale`]):
    /// the frame does not change when `a'` and `a''` are scaled by positive constants, and
    /// scaled to about unit size their products neither underflow nor overflow (a fiber
    /// `1e-150` across squares its derivatives to `1e-300` and their cross product's square to
    /// `1e-600`). Being powers of two they change no bits elsewhere.
    pub fn derivative_scales(&self) -> [f64; 2] {
        [self.speed_scale(), self.second_scale()]
    }

    /// The first of [`Self::derivative_scales`], about `1 / max |a'|`, alone (a cylinder keeps
    /// it: [`crate::GeneralizedCylinder`]'s projection frame scales `a'` by it at every
    /// evaluation).
    #[inline]
    pub fn speed_scale(&self) -> f64 {
        unit_scale(largest_coordinate(&self.hodograph()))
    }

    /// The second of [`Self::derivative_scales`], about `1 / max |a''|`, alone.
    #[inline]
    pub fn second_scale(&self) -> f64 {
        unit_scale(largest_coordinate(&self.second_hodograph()))
    }

    /// The power-basis coefficients `[c0, c1, c2, c3]` of `a(u) = c0 + c1 u + c2 u^2 + c3 u^3`:
    /// `c0 = P0`, `c1 = 3 (P1 - P0)`, `c2 = 3 (P2 - 2 P1 + P0)`, `c3 = P3 - 3 P2 + 3 P1 - P0`.
    pub fn power_coefficients(&self) -> [DVec3; 4] {
        let p = &self.points;
        [
            p[0],
            3.0 * (p[1] - p[0]),
            3.0 * (p[2] - 2.0 * p[1] + p[0]),
            p[3] - 3.0 * p[2] + 3.0 * p[1] - p[0],
        ]
    }

    /// The constant `a'''`.
    pub fn third_derivative(&self) -> DVec3 {
        let p = &self.points;
        6.0 * (p[3] - 3.0 * p[2] + 3.0 * p[1] - p[0])
    }

    /// The blossom `B(u1, u2, u3)` (de Casteljau with a different parameter at each level):
    /// symmetric, affine in each argument, `B(u, u, u) = a(u)`.
    pub fn blossom(&self, u1: f64, u2: f64, u3: f64) -> DVec3 {
        let p = &self.points;
        let lerp = |a: DVec3, b: DVec3, t: f64| a + t * (b - a);
        let q = [
            lerp(p[0], p[1], u1),
            lerp(p[1], p[2], u1),
            lerp(p[2], p[3], u1),
        ];
        let r = [lerp(q[0], q[1], u2), lerp(q[1], q[2], u2)];
        lerp(r[0], r[1], u3)
    }

    /// The same curve on `[u0, u1]` reparametrised to `[0, 1]` (any `u0 != u1`, also outside
    /// `[0, 1]`): control points `B(u0, u0, u0)`, `B(u0, u0, u1)`, `B(u0, u1, u1)`,
    /// `B(u1, u1, u1)`.
    pub fn segment(&self, u0: f64, u1: f64) -> CubicBezier {
        CubicBezier::new([
            self.blossom(u0, u0, u0),
            self.blossom(u0, u0, u1),
            self.blossom(u0, u1, u1),
            self.blossom(u1, u1, u1),
        ])
    }

    /// `a(u)`.
    pub fn point(&self, u: f64) -> DVec3 {
        self.point_r(u).value()
    }

    /// `a'(u)`.
    pub fn d1(&self, u: f64) -> DVec3 {
        self.d1_r(u).value()
    }

    /// `a''(u)`.
    pub fn d2(&self, u: f64) -> DVec3 {
        self.d2_r(u).value()
    }

    /// `[a(u), a'(u), a''(u)]` from one run of de Casteljau's algorithm: the last level's
    /// point, three times the difference of the level before, and six times the second
    /// difference of the first level.
    #[inline]
    pub fn jet(&self, u: f64) -> [DVec3; 3] {
        let [p0, p1, p2, p3] = self.points;
        let (q0, q1, q2) = (p0 + u * (p1 - p0), p1 + u * (p2 - p1), p2 + u * (p3 - p2));
        let (s0, s1) = (q0 + u * (q1 - q0), q1 + u * (q2 - q1));
        [
            s0 + u * (s1 - s0),
            3.0 * (s1 - s0),
            6.0 * ((q2 - q1) - (q1 - q0)),
        ]
    }

    /// `a(u)` over any [`Real`].
    #[inline]
    pub fn point_r<T: Real>(&self, u: T) -> V3<T> {
        let s = T::cst(1.0) - u;
        let (s2, u2) = (s * s, u * u);
        let w = [s2 * s, (s2 * u).scale(3.0), (s * u2).scale(3.0), u2 * u];
        combine(&self.points, &w)
    }

    /// `a'(u)` over any [`Real`].
    #[inline]
    pub fn d1_r<T: Real>(&self, u: T) -> V3<T> {
        let s = T::cst(1.0) - u;
        let w = [s * s, (s * u).scale(2.0), u * u];
        combine(&self.hodograph(), &w)
    }

    /// `a''(u)` over any [`Real`].
    #[inline]
    pub fn d2_r<T: Real>(&self, u: T) -> V3<T> {
        let w = [T::cst(1.0) - u, u];
        combine(&self.second_hodograph(), &w)
    }

    /// `a(m)`, `a'(m)` and `a''(m)` enclosed, from one `f64` evaluation each with an a-priori
    /// rounding bound, for `m` within [`JET_MARGIN`] of `[0, 1]` (`None` elsewhere). The
    /// hodographs' control points are taken as exact, as everywhere.
    ///
    /// With `s = 1 - m` (one rounding) each computed Bernstein weight `w_i` (a product of at most
    /// three rounded factors and a small integer) is within `5u |w_i|` of its value (`u = 2^-53`),
    /// and `sum P_i w_i` adds at most `4u sum |P_i w_i|` (a rounded product and at most three
    /// rounded sums); `sum |w_i| = (|s| + |m|)^n <= 1 + 1e-9` for `m` in range. So each coordinate
    /// lies within `9u max|P_i| (1 + 1e-9)` of the exact value: the enclosure takes `16u max|P_i|`,
    /// plus `1e-300 (1 + max|P_i|)` for products that underflow. Its bounds `v -+ e` are rounded
    /// to nearest, off by at most `u (|v| + e) < 1.01u max|P_i|` (as `|v| <= (1 + 1e-9)
    /// max|P_i|`), which the `7u` to spare covers, so they need no widening. What
    /// [`Self::point_r`] and its kin give in [`Interval`] arithmetic, at a fifth of the cost.
    /// Control points (or hodograph points) beyond `1e300`, whose sums could overflow, also give
    /// `None`; a NaN gives the whole line.
    pub fn jet_enclosure(&self, m: f64) -> Option<[V3<Interval>; 3]> {
        if !(-JET_MARGIN..=1.0 + JET_MARGIN).contains(&m) {
            return None;
        }
        fn enclose<const N: usize>(pts: &[DVec3; N], w: &[f64; N]) -> Option<V3<Interval>> {
            let size = pts.iter().fold(DVec3::ZERO, |acc, p| acc.max(p.abs()));
            if !(size.max_element() <= 1e300) {
                return None;
            }
            let v = combine(pts, w);
            let e = |k: f64| 16.0 * f64::EPSILON * 0.5 * k + 1e-300 * (1.0 + k);
            let wrap = |v: f64, k: f64| {
                let (lo, hi) = (v - e(k), v + e(k));
                if (hi - lo).is_nan() {
                    Interval::ENTIRE
                } else {
                    Interval::exact(lo, hi)
                }
            };
            Some(V3::new(
                wrap(v.x, size.x),
                wrap(v.y, size.y),
                wrap(v.z, size.z),
            ))
        }
        let s = 1.0 - m;
        let (s2, m2) = (s * s, m * m);
        let point = [s2 * s, 3.0 * (s2 * m), 3.0 * (s * m2), m2 * m];
        let d1 = [s2, 2.0 * (s * m), m2];
        let d2 = [s, m];
        Some([
            enclose(&self.points, &point)?,
            enclose(&self.hodograph(), &d1)?,
            enclose(&self.second_hodograph(), &d2)?,
        ])
    }

    /// The largest distance of `P1` and `P2` from the line through `P0` and `P3`, divided by
    /// `|P3 - P0|` (infinite when `P0 = P3`). The curve lies in the control polygon's hull, so
    /// this bounds how far the curve strays from a straight line, relative to its length.
    pub fn relative_deviation_from_chord(&self) -> f64 {
        let p = &self.points;
        let chord = p[3] - p[0];
        let len = chord.length();
        if len == 0.0 {
            return f64::INFINITY;
        }
        let dir = chord / len;
        let off = |q: DVec3| {
            let r = q - p[0];
            (r - r.dot(dir) * dir).length()
        };
        off(p[1]).max(off(p[2])) / len
    }

    /// A lower bound of `|a'(u)|` over `[0, 1]`, cheap: `min_i H_i.e` for the hodograph's
    /// control points `H_i` and `e` the unit chord. `a'(u)` is a convex combination of the
    /// `H_i` (Bernstein weights), so `a'(u).e >= min_i H_i.e`, and `|a'(u)| >= a'(u).e`. Near
    /// the true minimum for a nearly straight curve (hair); zero or negative, bounding nothing,
    /// where the curve turns back on its chord (or has none).
    pub fn speed_floor(&self) -> f64 {
        let chord = self.points[3] - self.points[0];
        let Some(e) = chord.try_normalize() else {
            return 0.0;
        };
        self.hodograph()
            .iter()
            .map(|h| h.dot(e))
            .fold(f64::INFINITY, f64::min)
    }

    /// Smallest `|a'(u)|` over `[0, 1]`: `|a'|` at the ends and at the zeros in `(0, 1)` of
    /// the cubic `a'.a''` (the critical points of the quartic `|a'|^2`).
    pub fn min_speed(&self) -> f64 {
        // a'(u) = A + B u + C u^2 (power form of the hodograph), so |a'|^2 is a quartic whose
        // critical points are the roots of a'.a'' = A.B + (2 A.C + B.B) u + 3 B.C u^2 + 2 C.C u^3.
        let [h0, h1, h2] = self.hodograph();
        let (a, b, c) = (h0, 2.0 * (h1 - h0), h0 - 2.0 * h1 + h2);
        let slope = polycool::Cubic::new([
            a.dot(b),
            2.0 * a.dot(c) + b.dot(b),
            3.0 * b.dot(c),
            2.0 * c.dot(c),
        ]);
        let speed2 = |u: f64| (a + u * (b + u * c)).length_squared();
        slope
            .roots_between(0.0, 1.0, 1e-15)
            .into_iter()
            .chain([0.0, 1.0])
            .map(speed2)
            .fold(f64::INFINITY, f64::min)
            .sqrt()
    }
}

#[inline]
fn combine<T: Real, const N: usize>(pts: &[DVec3; N], w: &[T; N]) -> V3<T> {
    let mut acc = V3::new(T::cst(0.0), T::cst(0.0), T::cst(0.0));
    for (p, &wi) in pts.iter().zip(w) {
        acc = acc + V3::new(wi.scale(p.x), wi.scale(p.y), wi.scale(p.z));
    }
    acc
}

/// How far outside `[0, 1]` [`CubicBezier::jet_enclosure`] evaluates (the intersector searches
/// `1e-11` beyond each end).
pub const JET_MARGIN: f64 = 1e-10;

/// The largest `|coordinate|` of the points (finite ones: the axis is checked at construction).
/// By comparisons, not `f64::max`, whose NaN handling costs several instructions each: the
/// projection frame's `g` scales `a'` by this at every evaluation (2.9% of an elliptical test).
#[inline]
fn largest_coordinate(pts: &[DVec3]) -> f64 {
    let larger = |a: f64, b: f64| if a > b { a } else { b };
    pts.iter().fold(0.0f64, |m, p| {
        let a = p.abs();
        larger(m, larger(larger(a.x, a.y), a.z))
    })
}

/// A power of two near `1 / max|v_i|` ([`unit_scale`] of `v`'s largest coordinate): `v` scaled
/// by it has its largest coordinate in `[1, 2)`. A point's own scale where the frame needs
/// `a'(u)` and `a''(u)` at unit size: the same bits as [`CubicBezier::derivative_scales`]
/// give (both exact) wherever neither scaling under- or overflows, without the hodographs.
pub(crate) fn vector_scale(v: DVec3) -> f64 {
    unit_scale(v.abs().max_element())
}

/// For a positive finite size `m`, the power of two `2^-e` with `m 2^-e` in `[1, 2)` (in
/// `[2, 4)` above `2^1023`, where `2^-1023` would not be normal); else 1 (a vanishing or unbounded
/// derivative keeps its scale). From the bits of `m`: `2^-e` has the biased exponent
/// `2046 - b` for `m`'s `b` (0 for a subnormal `m`, which gets `2^1023` and stays below 2). A
/// power of two is exact to multiply by: what is computed from the scaled numbers is the
/// unscaled result scaled, to the bit, unless a product would have underflowed or overflowed
/// without it.
fn unit_scale(m: f64) -> f64 {
    if m > 0.0 && m.is_finite() {
        let biased = (m.to_bits() >> 52) as i64;
        f64::from_bits(((2046 - biased).max(1) as u64) << 52)
    } else {
        1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::real::Dual;
    use crate::test_rng::Dd;

    /// [`CubicBezier::segment`] traces the curve: its point at `s` is `a(u0 + s (u1 - u0))`
    /// (against a double-double evaluation of the Bernstein form) to rounding, for ranges
    /// inside `[0, 1]`, reaching beyond it, reversed, and `1e-11` beyond both ends (the whole
    /// axis' range), at the origin and at 1e4.
    #[test]
    fn segments_trace_the_curve() {
        let mut rng = crate::test_rng::Lcg(11);
        for i in 0..2000 {
            let shift = DVec3::splat(if i % 2 == 0 { 0.0 } else { 1e4 });
            let c = CubicBezier::new(std::array::from_fn(|_| shift + rng.unit() * rng.next()));
            let (u0, u1) = match i % 4 {
                0 => (-1e-11, 1.0 + 1e-11),
                1 => (rng.range(0.0, 1.0), rng.range(0.0, 1.0)),
                _ => (rng.range(-0.5, 1.5), rng.range(-0.5, 1.5)),
            };
            let seg = c.segment(u0, u1);
            let size = c
                .points
                .iter()
                .fold(0.0f64, |m, p| m.max(p.abs().max_element()));
            let span = (u1 - u0).abs().max(1.0);
            for s in [0.0, 0.25, 0.5, 0.9, 1.0] {
                // a(u) = sum of the Bernstein weights times the points, in double-double.
                let u = Dd::of(u0).add(Dd::of(u1).add(Dd::of(-u0)).mul(Dd::of(s)));
                let v = Dd::of(1.0).add(Dd::of(-u.0)).add(Dd::of(-u.1));
                let (uu, vv) = (u.mul(u), v.mul(v));
                let w = [
                    vv.mul(v),
                    Dd::of(3.0).mul(u).mul(vv),
                    Dd::of(3.0).mul(uu).mul(v),
                    uu.mul(u),
                ];
                let got = seg.point(s);
                for k in 0..3 {
                    let exact = (0..4).fold(Dd::of(0.0), |acc, j| {
                        acc.add(w[j].mul(Dd::of(c.points[j][k])))
                    });
                    let err = Dd::of(got[k]).add(Dd::of(-exact.0)).add(Dd::of(-exact.1));
                    let err = err.value().abs();
                    assert!(
                        err <= 64.0 * f64::EPSILON * size * span.powi(3),
                        "segment [{u0}, {u1}] at {s}: off by {err:e}"
                    );
                }
            }
        }
    }

    /// [`CubicBezier::jet`] (de Casteljau) agrees with the Bernstein weights' `a`, `a'` and
    /// `a''` ([`CubicBezier::point`], `d1`, `d2`) to rounding, at the origin and at 1e4, for
    /// `u` in `[0, 1]` and just outside it.
    #[test]
    fn the_jet_is_the_point_and_its_derivatives() {
        let mut rng = crate::test_rng::Lcg(7);
        for i in 0..2000 {
            let shift = if i % 2 == 0 {
                DVec3::ZERO
            } else {
                DVec3::splat(1e4)
            };
            let c = CubicBezier::new(std::array::from_fn(|_| shift + rng.unit() * rng.next()));
            let u = rng.range(-0.01, 1.01);
            let [a, a1, a2] = c.jet(u);
            let size = c
                .points
                .iter()
                .fold(0.0f64, |m, p| m.max(p.abs().max_element()));
            for (x, y, n) in [(a, c.point(u), 1.0), (a1, c.d1(u), 3.0), (a2, c.d2(u), 6.0)] {
                let err = (x - y).abs().max_element();
                assert!(
                    err <= 16.0 * n * f64::EPSILON * size,
                    "case {i}, u {u}: {x} against {y}"
                );
            }
        }
    }

    /// The derivative scales are normal powers of two that bring a size to `[1, 2)` (`[2, 4)`
    /// above `2^1023`, below 2 from a subnormal one); 1 for zero, infinite or NaN sizes.
    #[test]
    fn unit_scales_are_powers_of_two_to_unit_size() {
        let mut sizes = vec![
            f64::MIN_POSITIVE / 3.0,
            5e-324,
            1.0,
            2.0,
            1.5,
            f64::MAX,
            0.75,
        ];
        sizes.extend((0..2000).map(|i| 10f64.powf(-323.0 + 631.0 * i as f64 / 1999.0)));
        sizes.extend((0..64).map(|k| 2f64.powi(k * 32 - 1074)));
        for m in sizes {
            let k = unit_scale(m);
            assert_eq!(
                k.to_bits() << 12,
                0,
                "{k} for {m} is not a normal power of two"
            );
            assert!(k.is_normal(), "{k} for {m}");
            let unit = m * k;
            let range = if m >= 2f64.powi(1023) {
                2.0..4.0
            } else if m < f64::MIN_POSITIVE {
                // Subnormal: 2^1023, the largest normal power of two.
                0.0..2.0
            } else {
                1.0..2.0
            };
            assert!(range.contains(&unit), "{m} scaled by {k} is {unit}");
        }
        for m in [0.0, f64::INFINITY, f64::NAN, -1.0] {
            assert_eq!(unit_scale(m), 1.0, "{m}");
        }
    }

    fn sample() -> CubicBezier {
        CubicBezier::new([
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(0.3, 1.0, -0.2),
            DVec3::new(1.2, 0.8, 0.5),
            DVec3::new(1.5, -0.4, 0.9),
        ])
    }

    /// Power form `a0 + a1 u + a2 u^2 + a3 u^3` (the seed's form), from the Bernstein points.
    fn power_form(c: &CubicBezier, u: f64) -> DVec3 {
        let p = c.points;
        let a1 = 3.0 * (p[1] - p[0]);
        let a2 = 3.0 * (p[2] - 2.0 * p[1] + p[0]);
        let a3 = p[3] - 3.0 * p[2] + 3.0 * p[1] - p[0];
        p[0] + u * (a1 + u * (a2 + u * a3))
    }

    /// `sum P_i C(n, i) s^(n-i) m^i` in double-double, with `s = 1 - m` exact.
    fn bernstein_dd<const N: usize>(pts: &[DVec3; N], m: f64) -> [f64; 3] {
        let (s, m) = (Dd::of(1.0).add(Dd::of(-m)), Dd::of(m));
        let n = N - 1;
        let binom = |i: usize| (0..i).fold(1.0, |c, j| c * (n - j) as f64 / (j + 1) as f64);
        std::array::from_fn(|k| {
            let mut acc = Dd::of(0.0);
            for (i, p) in pts.iter().enumerate() {
                let mut w = Dd::of(binom(i));
                for _ in 0..n - i {
                    w = w.mul(s);
                }
                for _ in 0..i {
                    w = w.mul(m);
                }
                acc = acc.add(w.mul(Dd::of(p[k])));
            }
            acc.value()
        })
    }

    /// The `f64` jet's enclosures hold the point and derivatives (against a double-double
    /// evaluation, good to about 1e-30), for control points from 1e-6 to 1e4 in size and far
    /// from the origin, and `m` across `[0, 1]`, at its ends, just outside it and tiny; they are
    /// no wider than 34 ulps of the largest control point; outside their range they decline.
    #[test]
    fn jet_enclosures_hold_the_exact_values() {
        let mut rng = crate::test_rng::Lcg(7);
        let mut checked = 0;
        for case in 0..3000 {
            let scale = 10f64.powf(rng.range(-6.0, 4.0));
            let offset = if case % 3 == 0 { 1e4 } else { 0.0 };
            let c = CubicBezier::new(std::array::from_fn(|_| {
                DVec3::splat(offset) + rng.unit() * scale * rng.range(0.1, 1.0)
            }));
            let m = match case % 6 {
                0 => 0.0,
                1 => 1.0,
                2 => rng.range(-JET_MARGIN, 0.0),
                3 => 1.0 + rng.range(0.0, JET_MARGIN),
                4 => 10f64.powf(rng.range(-300.0, -1.0)),
                _ => rng.next(),
            };
            let [a, d1, d2] = c.jet_enclosure(m).expect("in range");
            let exact = [
                bernstein_dd(&c.points, m),
                bernstein_dd(&c.hodograph(), m),
                bernstein_dd(&c.second_hodograph(), m),
            ];
            let sizes = [
                largest_coordinate(&c.points),
                largest_coordinate(&c.hodograph()),
                largest_coordinate(&c.second_hodograph()),
            ];
            for (j, (got, want)) in [a, d1, d2].iter().zip(exact).enumerate() {
                for (k, x) in [got.x, got.y, got.z].into_iter().enumerate() {
                    assert!(
                        x.contains(want[k]),
                        "case {case}, m = {m:e}, derivative {j}, axis {k}: {} not in {x:?}",
                        want[k]
                    );
                    assert!(
                        x.width() <= 34.0 * f64::EPSILON * sizes[j] + 1e-290,
                        "case {case}: derivative {j} too wide: {x:?}"
                    );
                    checked += 1;
                }
            }
        }
        assert_eq!(checked, 27000);
        let c = sample();
        let huge = CubicBezier::new(c.points.map(|p| p * 1e301));
        assert!(huge.jet_enclosure(0.5).is_none(), "sums could overflow");
        assert!(c.jet_enclosure(-2.0 * JET_MARGIN).is_none());
        assert!(c.jet_enclosure(1.0 + 2.0 * JET_MARGIN).is_none());
        assert!(c.jet_enclosure(f64::NAN).is_none());
        // A NaN coordinate gives the whole line there, never a NaN bound.
        let mut nan = c;
        nan.points[1].y = f64::NAN;
        let [a, d1, _] = nan.jet_enclosure(0.5).expect("finite sizes");
        assert_eq!((a.y, d1.y), (Interval::ENTIRE, Interval::ENTIRE));
        assert!(
            a.x.width().is_finite(),
            "the other coordinates are untouched"
        );
    }

    #[test]
    fn bernstein_matches_power_form_and_endpoints() {
        let c = sample();
        assert_eq!(c.point(0.0), c.points[0], "a(0) must be P0");
        assert!(
            (c.point(1.0) - c.points[3]).length() < 1e-15,
            "a(1) must be P3"
        );
        for i in 0..=10 {
            let u = i as f64 / 10.0;
            let e = (c.point(u) - power_form(&c, u)).length();
            assert!(e < 1e-14, "u={u}: Bernstein and power forms differ by {e}");
        }
    }

    /// Derivatives against central finite differences (step 1e-5: truncation ~1e-10,
    /// rounding ~1e-11) and against automatic differentiation of the position.
    #[test]
    fn derivatives_match_finite_differences_and_dual_numbers() {
        let c = sample();
        let h = 1e-5;
        for i in 0..=10 {
            let u = 0.05 + 0.09 * i as f64;
            let fd1 = (c.point(u + h) - c.point(u - h)) / (2.0 * h);
            let fd2 = (c.d1(u + h) - c.d1(u - h)) / (2.0 * h);
            let fd3 = (c.d2(u + h) - c.d2(u - h)) / (2.0 * h);
            assert!((fd1 - c.d1(u)).length() < 1e-8, "a' at {u}");
            assert!((fd2 - c.d2(u)).length() < 1e-8, "a'' at {u}");
            assert!((fd3 - c.third_derivative()).length() < 1e-8, "a''' at {u}");
            let ad = c.point_r(Dual::var(u));
            let ad = DVec3::new(ad.x.d, ad.y.d, ad.z.d);
            assert!((ad - c.d1(u)).length() < 1e-13, "AD a' at {u}");
        }
    }

    #[test]
    fn deviation_and_min_speed() {
        let straight = CubicBezier::new([
            DVec3::ZERO,
            DVec3::new(0.5, 0.0, 0.0),
            DVec3::new(2.5, 0.0, 0.0),
            DVec3::new(3.0, 0.0, 0.0),
        ]);
        assert_eq!(
            straight.relative_deviation_from_chord(),
            0.0,
            "collinear points"
        );
        assert!(
            sample().relative_deviation_from_chord() > 0.1,
            "curved sample"
        );
        // a'(u) = 3[(1-u)^2 (P1-P0) + 2u(1-u)(P2-P1) + u^2 (P3-P2)], here with a zero at u=1/2.
        let cusp = CubicBezier::new([
            DVec3::ZERO,
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
        ]);
        assert!(cusp.min_speed() < 1e-6, "cusp speed {}", cusp.min_speed());
        assert!(sample().min_speed() > 0.1, "regular curve");
        // Against dense sampling on curves with interior minima: never above the sampled
        // minimum, and within its sampling error (|a'|^2 is smooth: error ~ (1/20000)^2).
        let mut x = 0.3f64;
        let mut next = || {
            x = (x * 3.7 + 0.11).fract();
            x * 2.0 - 1.0
        };
        for _ in 0..50 {
            let c = CubicBezier::new([0; 4].map(|_| DVec3::new(next(), next(), next())));
            let sampled = (0..=20_000)
                .map(|i| c.d1(i as f64 / 20_000.0).length())
                .fold(f64::INFINITY, f64::min);
            let m = c.min_speed();
            assert!(
                m <= sampled + 1e-12 && m >= sampled - 1e-6 * (1.0 + sampled),
                "min speed {m} vs sampled {sampled} for {c:?}"
            );
            assert!(
                c.speed_floor() <= sampled * (1.0 + 1e-12),
                "floor for {c:?}"
            );
        }
    }

    /// The cheap floor never exceeds the sampled least speed, and on gently bent curves (hair
    /// segments) it is within a few percent of it, so it decides the cusp test there.
    #[test]
    fn speed_floor_bounds_the_least_speed_from_below() {
        let mut rng = crate::test_rng::Lcg(7);
        let mut next = || rng.range(-1.0, 1.0);
        let mut tight = 0;
        for i in 0..400 {
            // From straight to strongly bent, at scales 1e-6 to 1e4.
            let bend = [0.0, 0.01, 0.1, 1.0, 3.0][i % 5];
            let scale = 10f64.powi((i % 11) as i32 - 6);
            let dir = DVec3::new(next(), next(), next()).normalize_or(DVec3::X);
            let points = [0.0, 1.0, 2.0, 3.0]
                .map(|k| (dir * k + DVec3::new(next(), next(), next()) * bend) * scale);
            let c = CubicBezier::new(points);
            let sampled = (0..=20_000)
                .map(|j| c.d1(j as f64 / 20_000.0).length())
                .fold(f64::INFINITY, f64::min);
            let floor = c.speed_floor();
            assert!(
                floor <= sampled * (1.0 + 1e-12),
                "{floor} > {sampled} for {c:?}"
            );
            if bend <= 0.01 {
                assert!(
                    floor >= 0.9 * sampled,
                    "{floor} far below {sampled} for {c:?}"
                );
                tight += 1;
            }
        }
        assert_eq!(tight, 160);
    }
}
