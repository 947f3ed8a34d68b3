//! A frame-free prefilter: the `u` ranges where the ray passes within reach of the axis, so the
//! exact (and costlier) methods only search there.
//!
//! The section lies in the disc of radius `r_out` and the rule stretches by at most
//! `L(u) = L0 + (L1 - L0) u`, so every point of the solid's slice at `u` lies within
//! `R(u) = L(u) r_out` of `a(u)`. A ray that meets the slice therefore passes within `R(u)` of
//! `a(u)`: with `P x = x - d (x.d)/|d|^2` the projection across the ray,
//! `Q(u) = |P (o - a(u))|^2 - R(u)^2 <= 0`. `P (o - a(u))` is a cubic whose coefficients are the
//! projected power-basis coefficients of the axis, so `Q` is a polynomial of degree 6,
//! independent of the frame and of the ray's angle to the axis (no division by `a'.d`). In
//! Bernstein form on `[0, 1]` its coefficients bound it (convex hull property), and de Casteljau
//! subdivision tightens the bounds quadratically; ranges whose coefficients are all positive
//! are dropped.

use arrayvec::ArrayVec;
use glam::DVec3;

use crate::cylinder::GeneralizedCylinder;
use crate::section::CrossSection;
use crate::sweep::SweepRule;

const DEGREE: usize = 6;
type Bernstein = [f64; DEGREE + 1];

/// Ranges kept are at most this wide before merging (a coarse cover is enough: the exact
/// methods resolve the rest).
const RESOLUTION: f64 = 1.0 / 256.0;

/// Most separate ranges reported; beyond it the last range is stretched to cover the rest.
pub(crate) const MAX_RANGES: usize = 16;

/// `C(i, j) / C(DEGREE, j)`, the weights of [`to_bernstein`].
const WEIGHTS: [[f64; DEGREE + 1]; DEGREE + 1] = {
    let mut binom = [[0.0f64; DEGREE + 1]; DEGREE + 1];
    let mut n = 0;
    while n <= DEGREE {
        binom[n][0] = 1.0;
        let mut k = 1;
        while k <= n {
            binom[n][k] = binom[n - 1][k - 1] + if k < n { binom[n - 1][k] } else { 0.0 };
            k += 1;
        }
        n += 1;
    }
    let mut w = [[0.0f64; DEGREE + 1]; DEGREE + 1];
    let mut i = 0;
    while i <= DEGREE {
        let mut j = 0;
        while j <= i {
            w[i][j] = binom[i][j] / binom[DEGREE][j];
            j += 1;
        }
        i += 1;
    }
    w
};

/// Power-basis coefficients to Bernstein coefficients on `[0, 1]`:
/// `b_i = sum_{j <= i} C(i, j) / C(n, j) a_j`.
fn to_bernstein(a: &[f64; DEGREE + 1]) -> Bernstein {
    let mut b = [0.0; DEGREE + 1];
    for (i, bi) in b.iter_mut().enumerate() {
        *bi = (0..=i).map(|j| WEIGHTS[i][j] * a[j]).sum();
    }
    b
}

/// De Casteljau at `1/2`: the Bernstein coefficients of the two halves.
fn split(b: &Bernstein) -> (Bernstein, Bernstein) {
    let mut work = *b;
    let (mut left, mut right) = ([0.0; DEGREE + 1], [0.0; DEGREE + 1]);
    for k in 0..=DEGREE {
        left[k] = work[0];
        right[DEGREE - k] = work[DEGREE - k];
        for i in 0..DEGREE - k {
            work[i] = 0.5 * (work[i] + work[i + 1]);
        }
    }
    (left, right)
}

/// The power-basis coefficients of `Q(u) = |P (o - a(u))|^2 - R(u)^2` (module docs) for the
/// reach `R(u) = r[0] + (r[1] - r[0]) u`, lowest degree first, and the magnitude of the terms
/// that cancel in them (for the rounding bound).
fn reach_polynomial<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    o: DVec3,
    d: DVec3,
    r: [f64; 2],
) -> ([f64; DEGREE + 1], f64) {
    // a(u) = c0 + c1 u + c2 u^2 + c3 u^3.
    let c = cyl.axis.power_coefficients();
    let across = |x: DVec3| x - d * (x.dot(d) / d.length_squared());
    let e = [
        across(o - c[0]),
        -across(c[1]),
        -across(c[2]),
        -across(c[3]),
    ];
    let mut f = [0.0; DEGREE + 1];
    for i in 0..4 {
        for j in 0..4 {
            f[i + j] += e[i].dot(e[j]);
        }
    }
    // The largest product of two terms' lengths (one square root: it is monotone and
    // correctly rounded, so this is the largest of the lengths to the bit).
    let longest = e
        .iter()
        .fold(0.0f64, |m, x| m.max(x.length_squared()))
        .sqrt();
    let size = longest * longest;
    let dr = r[1] - r[0];
    f[0] -= r[0] * r[0];
    f[1] -= 2.0 * r[0] * dr;
    f[2] -= dr * dr;
    (f, size.max(r[0] * r[0]).max(r[1] * r[1]))
}

/// The `u` ranges in `[0, 1]` (before the caller's margin) where `Q(u) <= 0` may hold, sorted
/// and disjoint. Empty when the ray cannot meet the side surface.
///
/// Most rays that reach the exact test pass near the axis once, where `Q` dips below zero on
/// one short range about the closest approach. That range is cut out first from an estimate
/// ([`core_range`]) and kept whole, without testing, and only the rest of `[0, 1]` is searched
/// by subdivision: every `u` with `Q(u) <= 0` lies in a range either way, and the estimate
/// saves the many halvings that find the dip's ends. The caller decides where it takes the
/// estimate (`take_core(a, c)`; otherwise the whole of `[0, 1]` is subdivided): the Round
/// method always (its product isolation costs little more on the wider range); the Radial and
/// General methods where the ray is oblique across the estimate, since they start from samples
/// of a range (`roots::first_cells`), not an enclosure of all of it, and the subdivision's
/// tighter cover cost them more than it saved (the elliptical ponytail's fiber tests 2.5%
/// fewer instructions with the estimate, the three-lobed one's 1.3%). Where the ray is
/// perpendicular to the axis somewhere in the estimate, the wider range would send more of
/// their search to the fallbacks for such ranges (the General method's prism search has a
/// budget, and a review found crossings lost to it), so the tight cover stays there.
pub(crate) fn candidate_ranges<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    o: DVec3,
    d: DVec3,
    take_core: impl Fn(f64, f64) -> bool,
) -> ArrayVec<(f64, f64), MAX_RANGES> {
    let [l0, l1] = cyl.sweep.scale_bound();
    let r_out = cyl.section.bounding_radius();
    // 1e-6 relative head room keeps hits that rounding would put just outside.
    let grow = r_out * (1.0 + 1e-6);
    let (power, size) = reach_polynomial(cyl, o, d, [l0 * grow, l1 * grow]);
    let b = to_bernstein(&power);
    // Rounding in forming the coefficients: relative to the terms that cancel in them.
    let eps = 1e-12 * size;
    let mut out: ArrayVec<(f64, f64), MAX_RANGES> = ArrayVec::new();
    match core_range(&power).filter(|&(a, c)| take_core(a, c)) {
        Some((a, c)) => {
            if a > 0.0 {
                cover(&restrict(&b, 0.0, a), (0.0, a), eps, &mut out);
            }
            add(&mut out, (a, c));
            if c < 1.0 {
                cover(&restrict(&b, c, 1.0), (c, 1.0), eps, &mut out);
            }
        }
        None => cover(&b, (0.0, 1.0), eps, &mut out),
    }
    out
}

/// The coefficients on `[lo, hi]` of `[0, 1]` (reparametrised to `[0, 1]`).
fn restrict(b: &Bernstein, lo: f64, hi: f64) -> Bernstein {
    crate::bernstein::Bernstein(*b).restrict(lo, hi).0
}

/// Appends the range to the sorted list, merged with the last one where they touch; past
/// [`MAX_RANGES`] the last range is stretched over it.
fn add(out: &mut ArrayVec<(f64, f64), MAX_RANGES>, (lo, hi): (f64, f64)) {
    let full = out.is_full();
    match out.last_mut() {
        Some(last) if last.1 >= lo || full => last.1 = last.1.max(hi),
        _ => out.push((lo, hi)),
    }
}

/// Appends to `out` the ranges of `[lo, hi]` where `Q` (Bernstein coefficients `b` on that
/// range) may be at most `eps`, by de Casteljau halving down to [`RESOLUTION`]: a cell whose
/// coefficients all exceed `eps` is dropped.
fn cover(
    b: &Bernstein,
    (lo, hi): (f64, f64),
    eps: f64,
    out: &mut ArrayVec<(f64, f64), MAX_RANGES>,
) {
    let mut stack: ArrayVec<(Bernstein, f64, f64), 32> = ArrayVec::new();
    stack.push((*b, lo, hi));
    while let Some((b, lo, hi)) = stack.pop() {
        let min = b.iter().fold(f64::INFINITY, |m, &x| m.min(x));
        if min > eps {
            continue;
        }
        let max = b.iter().fold(f64::NEG_INFINITY, |m, &x| m.max(x));
        if max <= 0.0 || hi - lo <= RESOLUTION || stack.len() + 2 > stack.capacity() {
            add(out, (lo, hi));
            continue;
        }
        let (l, r) = split(&b);
        let m = 0.5 * (lo + hi);
        stack.push((r, m, hi));
        stack.push((l, lo, m));
    }
}

/// An estimate of the range about the ray's closest approach to the axis where `Q <= 0`, or
/// `None` where there is no such dip to cut out cheaply (the ray stays outside the reach, the
/// dip is not a single well-curved one, or it spans much of the axis).
///
/// Newton's method on `Q'` (power coefficients `f`) from the middle, `u <- u - Q'(u) / Q''(u)`,
/// finds the minimum `u*` (on a nearly straight axis `Q` is nearly quadratic, and the first
/// step lands near it), stopping once a step is below `RESOLUTION / 64`; the dip
/// `Q(u*) + Q''(u*) (u - u*)^2 / 2 <= 0` is taken 1.5 times as wide, plus a margin. Only speed
/// depends on the estimate: the caller keeps this range and searches the rest rigorously.
fn core_range(f: &[f64; DEGREE + 1]) -> Option<(f64, f64)> {
    // The derivatives' coefficients, made once for the iterations.
    let f1: [f64; DEGREE] = std::array::from_fn(|k| (k + 1) as f64 * f[k + 1]);
    let f2: [f64; DEGREE - 1] = std::array::from_fn(|k| ((k + 2) * (k + 1)) as f64 * f[k + 2]);
    let horner = |c: &[f64], u: f64| c.iter().rev().fold(0.0, |acc, &c| acc * u + c);
    let q = |u: f64| horner(f, u);
    let q1 = |u: f64| horner(&f1, u);
    let q2 = |u: f64| horner(&f2, u);
    let mut u = 0.5;
    for _ in 0..6 {
        let (g, h) = (q1(u), q2(u));
        if !(h > 0.0) {
            return None;
        }
        let next = (u - g / h).clamp(0.0, 1.0);
        let step = (next - u).abs();
        u = next;
        if step < RESOLUTION / 64.0 {
            break;
        }
    }
    let (value, curve) = (q(u), q2(u));
    if !(value < 0.0 && curve > 0.0) {
        return None;
    }
    let half = 1.5 * (-2.0 * value / curve).sqrt() + RESOLUTION;
    if !(half < 0.25) {
        return None;
    }
    Some(((u - half).max(0.0), (u + half).min(1.0)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::curve::CubicBezier;
    use crate::section::Section;
    use crate::sweep::HairSweep;
    use crate::test_rng::Lcg;

    /// Every `u` where the ray passes within the fiber's radius of the axis (measured on a grid
    /// of 4001 points from the geometry: the distance from `a(u)` to the ray's line, not `Q`'s
    /// coefficients) lies in a returned range. Curved, S-shaped and straight round fibers of
    /// radii 1e-4 to 1e-1 of their length; rays through points within 1.2 radii of the axis,
    /// tilted from the normal plane by log-uniform angles down to 1e-12 and exactly 0, or from
    /// any direction. The cut about the closest approach is taken in most cases, so both it and
    /// the subdivision of the rest are checked.
    #[test]
    fn ranges_cover_every_point_within_reach() {
        let mut rng = Lcg(29);
        let (mut cut, mut inside) = (0, 0);
        for case in 0..3000 {
            let bend = [0.0, 0.2, 0.6][case % 3];
            let axis: [DVec3; 4] = std::array::from_fn(|j| {
                let side = if case % 2 == 0 {
                    1.0
                } else {
                    [1.0, -1.0, 1.0, -1.0][j]
                };
                DVec3::new(
                    j as f64 / 3.0,
                    bend * side * rng.range(0.0, 1.0) * (j % 3 != 0) as u8 as f64,
                    bend * rng.range(-0.5, 0.5) * (j % 3 != 0) as u8 as f64,
                )
            });
            let curve = CubicBezier::new(axis);
            let r = 10f64.powf(rng.range(-4.0, -1.0));
            let Ok(cyl) = GeneralizedCylinder::new(
                curve,
                Section::default(),
                HairSweep::circular(r),
                true,
                None,
            ) else {
                continue;
            };
            let s = rng.next();
            let t = curve.d1(s).normalize();
            let n = t.any_orthonormal_vector();
            let n = n * rng.range(-1.0, 1.0) + t.cross(n) * rng.range(-1.0, 1.0);
            let p = curve.point(s) + n.normalize_or_zero() * r * rng.range(0.0, 1.2);
            let d = if case % 5 == 4 {
                rng.unit()
            } else {
                let across = t.cross(rng.unit()).normalize();
                let tilt = if case % 7 == 0 {
                    0.0
                } else {
                    10f64.powf(rng.range(-12.0, 0.0))
                };
                (across + tilt * t).normalize()
            };
            let o = p - d * rng.range(0.5, 3.0);
            let ranges = candidate_ranges(&cyl, o, d, |_, _| true);
            let (power, _) = reach_polynomial(&cyl, o, d, [r, r]);
            cut += usize::from(core_range(&power).is_some());
            for i in 0..=4000 {
                let u = i as f64 / 4000.0;
                let e = o - curve.point(u);
                let dist = (e - d * e.dot(d)).length();
                if dist < r * (1.0 - 1e-9) {
                    inside += 1;
                    assert!(
                        ranges.iter().any(|&(a, b)| a <= u && u <= b),
                        "case {case}: u = {u} at distance {dist} (radius {r}) outside {ranges:?}"
                    );
                }
            }
        }
        assert!(cut > 1500, "the cut should be taken in most cases: {cut}");
        assert!(
            inside > 30_000,
            "the rays should pass near the axes: {inside}"
        );
    }

    #[test]
    fn bernstein_form_evaluates_like_the_power_form() {
        let a: [f64; DEGREE + 1] = [1.0, -2.0, 0.5, 3.0, -1.0, 0.25, 2.0];
        let b = to_bernstein(&a);
        let (l, r) = split(&b);
        let bern = |b: &Bernstein, t: f64| {
            // de Casteljau evaluation
            let mut w = *b;
            for k in 1..=DEGREE {
                for i in 0..=DEGREE - k {
                    w[i] = (1.0 - t) * w[i] + t * w[i + 1];
                }
            }
            w[0]
        };
        for i in 0..=20 {
            let t = i as f64 / 20.0;
            let p: f64 = a.iter().rev().fold(0.0, |acc, &c| acc * t + c);
            assert!((bern(&b, t) - p).abs() < 1e-12, "at {t}");
            assert!(
                (bern(&l, t) - bern(&b, 0.5 * t)).abs() < 1e-12,
                "left half at {t}"
            );
            assert!(
                (bern(&r, t) - bern(&b, 0.5 + 0.5 * t)).abs() < 1e-12,
                "right half at {t}"
            );
        }
    }
}
