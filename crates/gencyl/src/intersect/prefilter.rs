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
    let p = cyl.axis.points;
    // a(u) = c0 + c1 u + c2 u^2 + c3 u^3.
    let c = [
        p[0],
        3.0 * (p[1] - p[0]),
        3.0 * (p[2] - 2.0 * p[1] + p[0]),
        p[3] - 3.0 * p[2] + 3.0 * p[1] - p[0],
    ];
    let across = |x: DVec3| x - d * (x.dot(d) / d.length_squared());
    let e = [
        across(o - c[0]),
        -across(c[1]),
        -across(c[2]),
        -across(c[3]),
    ];
    let mut f = [0.0; DEGREE + 1];
    let mut size = 0.0f64;
    for i in 0..4 {
        for j in 0..4 {
            let t = e[i].dot(e[j]);
            f[i + j] += t;
            size = size.max(e[i].length() * e[j].length());
        }
    }
    let dr = r[1] - r[0];
    f[0] -= r[0] * r[0];
    f[1] -= 2.0 * r[0] * dr;
    f[2] -= dr * dr;
    (f, size.max(r[0] * r[0]).max(r[1] * r[1]))
}

/// The `u` ranges in `[0, 1]` (before the caller's margin) where `Q(u) <= 0` may hold, sorted
/// and disjoint. Empty when the ray cannot meet the side surface.
pub(crate) fn candidate_ranges<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    o: DVec3,
    d: DVec3,
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
    let mut stack: ArrayVec<(Bernstein, f64, f64), 32> = ArrayVec::new();
    stack.push((b, 0.0, 1.0));
    while let Some((b, lo, hi)) = stack.pop() {
        let min = b.iter().fold(f64::INFINITY, |m, &x| m.min(x));
        if min > eps {
            continue;
        }
        let max = b.iter().fold(f64::NEG_INFINITY, |m, &x| m.max(x));
        if max <= 0.0 || hi - lo <= RESOLUTION || stack.len() + 2 > stack.capacity() {
            let full = out.is_full();
            match out.last_mut() {
                Some(last) if last.1 >= lo || full => last.1 = last.1.max(hi),
                _ => out.push((lo, hi)),
            }
            continue;
        }
        let (l, r) = split(&b);
        let m = 0.5 * (lo + hi);
        stack.push((r, m, hi));
        stack.push((l, lo, m));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

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
