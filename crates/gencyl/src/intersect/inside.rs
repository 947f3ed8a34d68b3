//! A cheap certificate that a ray enters a round fiber, for any-hit queries (a renderer's
//! shadow rays, most of which the first fiber they reach blocks): a point of the ray outside
//! the solid, a later one inside it, and the stretch between them clear of the open ends'
//! discs.
//!
//! A round fiber's solid is the union of the discs `D(u) = {a(u) + e : e.a'(u) = 0,
//! |e| <= k(u)}`, `u` in `[0, 1]`, for the unit circle scaled by `k(u) = k0 + (k1 - k0) u`
//! ([`GeneralizedCylinder::contains`]). Then:
//!
//! - **Outside.** Every point of the solid lies within `k_max` of the axis, the axis within
//!   the control points' hull, and the hull within `dev = max_i dist(p_i, [p0, p3])` of the
//!   chord (the distance to a segment is convex: its largest value on the hull is at a
//!   corner). A point `x0` with `dist(x0, [p0, p3]) > dev + k_max` is outside; where a curve
//!   bows by more than its radius, the same holds of its de Casteljau halves, a few times over.
//! - **Inside.** A point `x` where `g(u) = (x - a(u)).a'(u)` changes sign on `[ua, ub]`, with
//!   `|x - a(u)| < k(u)` on all of it, lies in the disc at a sign change `u*` (there `x - a(u*)`
//!   is normal to `a'(u*)`). With `c` the range's middle and `|a'| <= H = 3 max_i |p_{i+1} -
//!   p_i|` (the hodograph's hull), `|x - a(u)| <= |x - a(c)| + H (ub - ua) / 2`; `k` is
//!   linear, least at an end of the range.
//! - **Between.** The ray from `x0` (at `tmin`) to `x` (at `t`, `tmin < t < tmax`) goes from
//!   outside the solid to inside it, so it crosses the solid's boundary going in: at the last
//!   boundary point before `x`, in `(tmin, t]`, it enters (`normal.d <= 0`). The boundary the
//!   intersector reports is the side and the closed caps; an open end's disc is not part of
//!   it (a strand's segments meet there), so the stretch `[x0, x]` must not meet it: it
//!   crosses the end's plane (if at all) farther than `k` from the axis' end point.
//!
//! So where the certificate holds, the exact search ([`GeneralizedCylinder::any_hit`]) finds
//! an entry too, and the answer is the same. `x` is sought where the ray passes nearest the
//! axis: Newton's method on `F(t, u) = |o + t d - a(u)|^2 / 2` from the nearest approach of the
//! ray's line and the chord's. Every test allows for rounding by [`MARGIN`] of the
//! coordinates' size, thousands of units of `f64` rounding.

use glam::DVec3;

use crate::curve::CubicBezier;
use crate::cylinder::{GeneralizedCylinder, Ray};
use crate::section::CrossSection;
use crate::sweep::SweepRule;

/// The margin of every test, relative to the size of the coordinates involved (module docs).
const MARGIN: f64 = 1e-12;
/// The most Newton steps toward the ray's nearest approach to the axis (a short hair segment
/// mostly needs one: the chord's approach is already close).
const STEPS: usize = 4;
/// The most halvings of the axis in the outside test ([`beyond`]): a hair segment mostly needs
/// none; a curve bowed far more than its radius, near the point tested, a few.
const OUTSIDE_DEPTH: u32 = 6;
/// Half the width of the range `[ua, ub]` about that approach, in units of `k_min / H`: the
/// range's own width costs the bound on `|x - a(u)|` at most a hundredth of the radius.
const HALF_WIDTH: f64 = 0.02;

/// A `t` in `(tmin, tmax)` where the ray is certainly inside the solid of `cyl`, a round
/// fiber, having entered it after `tmin` where the intersector reports an entry (module
/// docs). `None` means only that the certificate does not apply or does not hold, as for a
/// fiber with another section or rule, or one whose surface may fold.
pub(crate) fn certain_entry<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    ray: &Ray,
    tmin: f64,
    tmax: f64,
) -> Option<f64> {
    if !cyl.section.is_unit_circle() || cyl.may_fold() {
        return None;
    }
    let [k0, k1] = cyl.sweep.uniform_scale()?;
    let d = ray.dir;
    let o = ray.origin - cyl.origin;
    let dd = d.length_squared();
    let usable = k0 > 0.0
        && k1 > 0.0
        && dd > 0.0
        && tmin < tmax
        && tmin.is_finite()
        && d.is_finite()
        && o.is_finite();
    if !usable {
        return None;
    }
    let p = cyl.axis.points;
    let axis = Power(cyl.axis.power_coefficients());
    let size = p.iter().fold(0.0f64, |m, x| m.max(x.abs().max_element()));
    // Outside at `tmin`: the cheapest test first (a ray leaving a neighbouring fiber's surface
    // fails it, and a ray passing far from this one is mostly culled before it gets here).
    let x0 = o + tmin * d;
    let err0 = 4.0 * MARGIN * (size + o.abs().max_element() + x0.abs().max_element());
    let (k_min, k_max) = (k0.min(k1), k0.max(k1));
    if !beyond(x0, &cyl.axis, k_max * (1.0 + MARGIN) + err0, OUTSIDE_DEPTH) {
        return None;
    }
    // The ray's nearest approach to the axis, from the nearest approach of the two lines.
    let chord = p[3] - p[0];
    let w0 = o - p[0];
    let (b, cc) = (d.dot(chord), chord.length_squared());
    let den = dd * cc - b * b;
    let mut u = if den > 1e-12 * dd * cc {
        ((dd * chord.dot(w0) - b * d.dot(w0)) / den).clamp(0.0, 1.0)
    } else {
        0.5
    };
    let speed = 3.0
        * (p[1] - p[0])
            .length()
            .max((p[2] - p[1]).length())
            .max((p[3] - p[2]).length());
    let half = HALF_WIDTH * k_min / speed;
    let mut t = (axis.point(u) - o).dot(d) / dd;
    for _ in 0..STEPS {
        let (a, a1, a2) = axis.jet(u);
        let r = o + t * d - a;
        // The gradient of F and its Hessian, [[d.d, -d.a'], [-d.a', a'.a' - r.a'']].
        let (gt, gu) = (d.dot(r), -a1.dot(r));
        let (htu, huu) = (-d.dot(a1), a1.length_squared() - r.dot(a2));
        let det = dd * huu - htu * htu;
        if !(det > 0.0 && huu > 0.0) {
            break;
        }
        let du = (dd * gu - htu * gt) / det;
        t -= (huu * gt - htu * gu) / det;
        u = (u - du).clamp(0.0, 1.0);
        // Newton's error after a step is of the order of the step squared: well inside the
        // range about `u` the certificate takes once the step is inside it.
        if du.abs() < half {
            break;
        }
    }
    if !(t > tmin && t < tmax) {
        return None;
    }
    let x = o + t * d;
    // Lengths (points of the ray, of the axis) are off by at most `err`, `g` by `err H`.
    let err = 4.0
        * MARGIN
        * (size + o.abs().max_element() + (t * d).abs().max_element() + x.abs().max_element());
    let (ua, ub) = ((u - half).max(0.0), (u + half).min(1.0));
    let g = |u: f64| {
        let (a, a1, _) = axis.jet(u);
        (x - a).dot(a1)
    };
    let (ga, gb) = (g(ua), g(ub));
    let err_g = err * speed;
    if !(ga > err_g && gb < -err_g || ga < -err_g && gb > err_g) {
        return None;
    }
    let k = |u: f64| k0 + (k1 - k0) * u;
    let c = 0.5 * (ua + ub);
    let far = (x - axis.point(c)).length() + 0.5 * speed * (ub - ua) + err;
    if !(far < k(ua).min(k(ub)) * (1.0 - MARGIN)) {
        return None;
    }
    // Clear of the open ends' discs.
    for (end, closed) in cyl.caps.into_iter().enumerate() {
        if closed {
            continue;
        }
        let (centre, normal) = if end == 0 {
            (p[0], 3.0 * (p[1] - p[0]))
        } else {
            (p[3], 3.0 * (p[3] - p[2]))
        };
        let err_s = 2.0 * err * normal.length();
        let (sa, sb) = ((x0 - centre).dot(normal), (x - centre).dot(normal));
        if sa > err_s && sb > err_s || sa < -err_s && sb < -err_s {
            continue;
        }
        if !(sa > err_s && sb < -err_s || sa < -err_s && sb > err_s) {
            return None;
        }
        // The plane's crossing, `lambda = sa / (sa - sb)` in (0, 1), off by at most
        // `2 err_s / (|sa| + |sb| - 2 err_s)` (each of `sa`, `sb` by `err_s`) and its rounding.
        let total = sa.abs() + sb.abs();
        let lambda = sa / (sa - sb);
        let off_lambda = 2.0 * err_s / (total - 2.0 * err_s) + 4.0 * f64::EPSILON;
        let y = x0 + (x - x0) * lambda;
        let off_y = off_lambda * (x - x0).length() + err;
        let k_end = if end == 0 { k0 } else { k1 };
        if !((y - centre).length() > k_end * (1.0 + MARGIN) + off_y + err) {
            return None;
        }
    }
    Some(t)
}

/// A cubic Bezier curve in power form ([`CubicBezier::power_coefficients`]), evaluated by
/// Horner's rule: on `[0, 1]` its rounding is a few units of `f64` times `|c_i| <= 8 max|p_i|`,
/// far inside [`MARGIN`].
struct Power([DVec3; 4]);

impl Power {
    /// `a(u)`.
    fn point(&self, u: f64) -> DVec3 {
        let c = &self.0;
        ((c[3] * u + c[2]) * u + c[1]) * u + c[0]
    }

    /// `a(u)`, `a'(u)` and `a''(u)`.
    fn jet(&self, u: f64) -> (DVec3, DVec3, DVec3) {
        let c = &self.0;
        (
            self.point(u),
            (3.0 * u * c[3] + 2.0 * c[2]) * u + c[1],
            6.0 * u * c[3] + 2.0 * c[2],
        )
    }
}

/// Whether every point of `curve` lies farther than `reach` from `x`: where the chord stays
/// farther than `reach` plus the inner points' distance from it (module docs), or, `depth`
/// times over, each half does ([`CubicBezier::segment`]: the halves hug the curve, their
/// points' distance from their chords falling fourfold a halving).
fn beyond(x: DVec3, curve: &CubicBezier, reach: f64, depth: u32) -> bool {
    let p = curve.points;
    let dev = segment_distance(p[1], p[0], p[3]).max(segment_distance(p[2], p[0], p[3]));
    if segment_distance(x, p[0], p[3]) > dev + reach {
        return true;
    }
    if depth == 0 {
        return false;
    }
    [(0.0, 0.5), (0.5, 1.0)]
        .into_iter()
        .all(|(u0, u1)| beyond(x, &curve.segment(u0, u1), reach, depth - 1))
}

/// The distance from `x` to the segment `[a, b]`.
fn segment_distance(x: DVec3, a: DVec3, b: DVec3) -> f64 {
    let ab = b - a;
    let len2 = ab.length_squared();
    let s = if len2 > 0.0 {
        ((x - a).dot(ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (x - (a + s * ab)).length()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cylinder::{FiberSpec, Hit};
    use crate::test_rng::Lcg as Rng;

    /// How a test ray is aimed.
    #[derive(Clone, Copy, PartialEq, Eq, Debug)]
    enum Aim {
        /// Exactly perpendicular to the axis where it is aimed.
        Perpendicular,
        /// 1e-15 to 1e-2 rad off perpendicular.
        NearlyPerpendicular,
        /// Within 0.3 rad of the axis' direction.
        NearlyAlong,
        Random,
        /// Exactly along the axis from beyond an end, within the end's radius: it enters the
        /// solid through the end's disc, which bounds it only where the cap is closed.
        ThroughEnd,
        /// From the fiber's own surface (as a renderer spawns rays), outward.
        FromSurface,
    }

    const AIMS: [Aim; 6] = [
        Aim::Perpendicular,
        Aim::NearlyPerpendicular,
        Aim::NearlyAlong,
        Aim::Random,
        Aim::ThroughEnd,
        Aim::FromSurface,
    ];

    /// Case `case` (its shape, ray and window drawn from `rng`): a round fiber of length about
    /// 1 and radius 1e-6 to 1e-1 (every fifth 1e4 from the origin), straight, gently curved
    /// like hair or bent into a U (every eleventh; its thicker ones may fold, and are never
    /// certified), of constant radius or tapering up to threefold, each end capped or open; and
    /// a ray aimed at a point of the axis or its continuation beyond the ends (`u` in
    /// -0.15..1.15), passing it at a distance from the core to just inside the radius (1e-9 of
    /// it) and just outside it, in the ways of [`Aim`], from 1e-3 to 10 lengths back, with a
    /// direction of length 1e-3 to 1e3, over windows `(tmin, tmax)` from `0` or a random point
    /// to infinity or around the aimed point. Returns the fiber, its
    /// radius at the aimed point, the ray, the window, the aim, the distance of the aimed point
    /// from the axis over the radius, and the aimed point's `t`.
    #[allow(clippy::type_complexity)]
    fn case_of(
        rng: &mut Rng,
        case: usize,
    ) -> (GeneralizedCylinder, f64, Ray, (f64, f64), Aim, f64, f64) {
        let offset = if case.is_multiple_of(5) {
            DVec3::splat(1e4)
        } else {
            DVec3::ZERO
        };
        let pick = |rng: &mut Rng, n: usize| (rng.next() * n as f64) as usize;
        let bend = [0.0, 0.05, 0.3][pick(rng, 3)];
        let mut bezier: [DVec3; 4] = std::array::from_fn(|j| {
            DVec3::new(
                j as f64 / 3.0,
                rng.range(-bend, bend),
                rng.range(-bend, bend),
            )
        });
        if case % 11 == 7 {
            // A U.
            bezier = [
                DVec3::ZERO,
                DVec3::new(0.6, 0.0, 0.0),
                DVec3::new(0.6, 0.4, 0.0),
                DVec3::new(0.0, 0.4, 0.0),
            ];
        }
        let bezier = bezier.map(|p| p + offset);
        let r = 10f64.powf(rng.range(-6.0, -1.0));
        let taper = [1.0, 1.0, rng.range(0.3, 3.0)][pick(rng, 3)];
        let mut spec = FiberSpec::round(bezier, r);
        spec.major_radius = [r, r * taper];
        spec.minor_radius = spec.major_radius;
        let caps = [(true, true), (false, false), (true, false), (false, true)][pick(rng, 4)];
        let cyl = spec.build().unwrap().with_caps(caps.0, caps.1);
        let axis = crate::curve::CubicBezier::new(bezier);
        let aim = AIMS[pick(rng, AIMS.len())];
        let k = |u: f64| r + (r * taper - r) * u.clamp(0.0, 1.0);
        let u = rng.range(-0.15, 1.15);
        let end = u.clamp(0.0, 1.0);
        let tangent = axis.d1(end).normalize();
        let centre = axis.point(end) + (u - end) * axis.d1(end);
        // The distance from the axis over the radius: the core, just inside, just outside.
        let depth = 10f64.powf(rng.range(-9.0, 0.0));
        let across = match rng.range(0.0, 3.0) as usize {
            0 => rng.range(0.0, 0.95),
            1 => 1.0 - depth,
            _ => 1.0 + depth,
        };
        let normal = {
            let n = rng.unit();
            (n - n.dot(tangent) * tangent).normalize()
        };
        let aimed = centre + across * k(u) * normal;
        let speed = 10f64.powf(rng.range(-3.0, 3.0));
        let d = match aim {
            Aim::Perpendicular | Aim::FromSurface => normal.cross(tangent),
            Aim::NearlyPerpendicular => {
                let off = 10f64.powf(rng.range(-15.0, -2.0));
                (normal.cross(tangent) + off * tangent).normalize()
            }
            Aim::NearlyAlong => (tangent + 0.3 * rng.unit()).normalize(),
            Aim::Random => rng.unit(),
            Aim::ThroughEnd => {
                if u < 0.5 {
                    tangent
                } else {
                    -tangent
                }
            }
        };
        let d = if rng.next() < 0.5 && aim != Aim::ThroughEnd {
            -d
        } else {
            d
        };
        let back = 10f64.powf(rng.range(-3.0, 1.0));
        let (origin, t_aim) = match aim {
            Aim::FromSurface => {
                let v = rng.range(0.0, std::f64::consts::TAU);
                let p = cyl.surface_point(u.clamp(0.0, 1.0), v);
                let outward = (p - axis.point(u.clamp(0.0, 1.0))).normalize();
                let d = if d.dot(outward) < 0.0 { -d } else { d };
                return (
                    cyl,
                    k(u),
                    Ray::new(
                        p + 1e-9 * (1.0 + p.abs().max_element()) * outward,
                        d * speed,
                    ),
                    (0.0, f64::INFINITY),
                    aim,
                    1.0,
                    0.0,
                );
            }
            Aim::ThroughEnd => {
                // From beyond the end, at the aimed distance from the axis' line.
                let (e, t) = if u < 0.5 {
                    (0.0, tangent)
                } else {
                    (1.0, -tangent)
                };
                let start = axis.point(e) - back * t + across * k(e) * normal;
                (start, back / speed)
            }
            _ => (aimed - back * d, back / speed),
        };
        let ray = Ray::new(origin, d * speed);
        let tmin = if rng.next() < 0.7 {
            0.0
        } else {
            t_aim * rng.range(0.0, 1.2)
        };
        let tmax = if rng.next() < 0.7 {
            f64::INFINITY
        } else {
            t_aim * rng.range(0.5, 2.0)
        };
        (cyl, k(u), ray, (tmin, tmax.max(tmin)), aim, across, t_aim)
    }

    /// Wherever the certificate answers, it is right by two independent measures: the solid's
    /// own definition ([`GeneralizedCylinder::contains`]: outside at `tmin`, inside at the
    /// `t` it names, in the window) and the full search's hit list (an entry, `normal.d <= 0`,
    /// in `(tmin, t]`), on every case of [`case_of`]: perpendicular rays and rays 1e-15 off,
    /// grazing depths to 1e-9 of the radius, radii 1e-6 to 1e-1 of the length, coordinates at
    /// 1e4, rays from the surface. Rays along the axis through an open end (the solid's
    /// boundary there is no hit) are never certified. And it is worth having: it answers for
    /// nine in ten rays from outside that pass through the core of a fiber that cannot fold.
    #[test]
    fn certified_entries_are_entries() {
        let mut rng = Rng(91);
        let (mut certified, mut core, mut core_certified, mut open_ends) = (0, 0, 0, 0);
        let mut by_aim = std::collections::HashMap::new();
        for case in 0..40_000 {
            let (cyl, k, ray, (tmin, tmax), aim, across, t_aim) = case_of(&mut rng, case);
            let found = certain_entry(&cyl, &ray, tmin, tmax);
            let mut all: Vec<Hit> = Vec::new();
            cyl.intersect_all(&ray, tmin, tmax, &mut all);
            let d = ray.dir;
            let end_open = |e: usize| !cyl.caps()[e];
            if aim == Aim::ThroughEnd && across < 1.0 {
                let e = usize::from(ray.dir.dot(cyl.axis().d1(0.5)) < 0.0);
                // Entering through the open end and nowhere else in the window: a certificate
                // here would be wrong (the general checks below catch it).
                if end_open(e) && !all.iter().any(|h| h.normal.dot(ray.dir) <= 0.0) {
                    open_ends += 1;
                }
            }
            if let Some(t) = found {
                certified += 1;
                *by_aim.entry(format!("{aim:?}")).or_insert(0) += 1;
                assert!(
                    t > tmin && t < tmax,
                    "case {case}: {t} outside ({tmin}, {tmax})"
                );
                assert!(
                    !cyl.contains(ray.at(tmin)),
                    "case {case}: inside at tmin {tmin}"
                );
                assert!(cyl.contains(ray.at(t)), "case {case}: not inside at {t}");
                assert!(
                    all.iter().any(|h| h.t <= t && h.normal.dot(d) <= 0.0),
                    "case {case}: no entry in ({tmin}, {t}]: {all:?}"
                );
            }
            let tube_core = across <= 0.9
                && !cyl.may_fold()
                && tmin == 0.0
                && tmax == f64::INFINITY
                && matches!(aim, Aim::Perpendicular | Aim::NearlyPerpendicular)
                && (0.1..0.9).contains(&cyl_u_of(&cyl, ray.at(t_aim)))
                && !cyl.contains(ray.origin)
                && (ray.origin - ray.at(t_aim)).length() > 3.0 * k;
            if tube_core {
                core += 1;
                core_certified += usize::from(found.is_some());
            }
        }
        assert!(open_ends > 300, "rays through an open end: {open_ends}");
        assert!(
            core > 1000 && core_certified * 10 >= core * 9,
            "core rays certified: {core_certified} of {core}"
        );
        assert!(certified > 8000, "certified: {certified} ({by_aim:?})");
        for aim in [
            "Perpendicular",
            "NearlyPerpendicular",
            "NearlyAlong",
            "Random",
        ] {
            assert!(
                by_aim.get(aim).is_some_and(|&n| n > 300),
                "{aim}: {by_aim:?}"
            );
        }
    }

    /// The axis parameter of the point of the axis nearest `x` (by sampling: for the test's
    /// choice of rays only).
    fn cyl_u_of(cyl: &GeneralizedCylinder, x: DVec3) -> f64 {
        let axis = cyl.axis();
        (0..=1000)
            .map(|i| i as f64 / 1000.0)
            .min_by(|a, b| {
                (axis.point(*a) - x)
                    .length()
                    .total_cmp(&(axis.point(*b) - x).length())
            })
            .unwrap()
    }
}
