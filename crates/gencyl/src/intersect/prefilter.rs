//! A frame-free prefilter: the `u` ranges where the ray passes within the section's circumscribed
//! tube, so the exact (and costlier) methods only search there.
//!
//! The section lies in the disc of radius `r_out` and the rule stretches by at most
//! `L(u) = L0 + (L1 - L0) u`, so a side hit at `u` needs the ray's in-plane offset `rho` to have
//! `|rho| <= R(u) = L(u) r_out`, i.e. `P(u) = |V|^2 - R(u)^2 q^2 <= 0` with `V = q rho` (see
//! [`super::polynomial`]): a degree-10 polynomial, independent of the frame. In Bernstein form
//! on `[0, 1]` its coefficients bound it (convex hull property), and de Casteljau subdivision
//! tightens the bounds quadratically; ranges whose coefficients are all positive are dropped.

use arrayvec::ArrayVec;
use glam::DVec3;

use super::polynomial::hit_polynomial;
use crate::cylinder::GeneralizedCylinder;
use crate::section::CrossSection;
use crate::sweep::SweepRule;

const DEGREE: usize = 10;
type Bernstein = [f64; DEGREE + 1];

/// Ranges kept are at most this wide before merging (a coarse cover is enough: the exact
/// methods resolve the rest).
const RESOLUTION: f64 = 1.0 / 256.0;

/// Most separate ranges reported; beyond it the last range is stretched to cover the rest.
pub(crate) const MAX_RANGES: usize = 16;

/// Power-basis coefficients to Bernstein coefficients on `[0, 1]`:
/// `b_i = sum_{j <= i} C(i, j) / C(n, j) a_j`.
fn to_bernstein(a: &[f64; DEGREE + 1]) -> Bernstein {
    let mut binom = [[0.0f64; DEGREE + 1]; DEGREE + 1];
    for n in 0..=DEGREE {
        binom[n][0] = 1.0;
        for k in 1..=n {
            binom[n][k] = binom[n - 1][k - 1] + if k < n { binom[n - 1][k] } else { 0.0 };
        }
    }
    let mut b = [0.0; DEGREE + 1];
    for (i, bi) in b.iter_mut().enumerate() {
        *bi = (0..=i).map(|j| binom[i][j] / binom[DEGREE][j] * a[j]).sum();
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

/// The `u` ranges in `[0, 1]` (before the caller's margin) where `P(u) <= 0` may hold, sorted
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
    let b = to_bernstein(&hit_polynomial(cyl, o, d, [l0 * grow, l1 * grow]));
    // Rounding in forming the coefficients: relative to their magnitude.
    let eps = 1e-12 * b.iter().fold(0.0f64, |m, x| m.max(x.abs()));
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
        let a: [f64; 11] = [1.0, -2.0, 0.5, 3.0, -1.0, 0.25, 2.0, -0.5, 0.1, -3.0, 1.5];
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
