//! The polynomial fast path for circular fibers.
//!
//! For a circular section of radius `r(u) = r0 + (r1 - r0) u` the surface is the set of points at
//! distance `r(u)` from `a(u)` in the normal plane at `u`, whatever the frame. With `e = o - a(u)`,
//! `q = a'.d`, `m = a'.e` and `w = -m/q`, the offset `p = e + w d` satisfies
//! `q p = q e - m d`, so `|p|^2 = r^2` becomes
//! `F(u) = |q e - m d|^2 - r^2 q^2 = 0`: `q e - m d` has degree 5 in `u`, so `F` has degree 10.
//! At a pole (`q = 0`), `F = m^2 |d|^2 >= 0` vanishes only where the ray lies in the normal
//! plane, which the caller handles; so the roots of `F` with `q != 0` are exactly the hits.

use glam::DVec3;
use polycool::PolyDyn;

use super::{Radial, SideRoots};
use crate::cylinder::GeneralizedCylinder;
use crate::roots::{Function1D, bracketed_root};
use crate::section::CrossSection;
use crate::sweep::SweepRule;

/// `a * b` for power-basis coefficient slices, into `out` (which must be long enough).
fn mul_into(a: &[f64], b: &[f64], out: &mut [f64]) {
    out.iter_mut().for_each(|c| *c = 0.0);
    for (i, &x) in a.iter().enumerate() {
        for (j, &y) in b.iter().enumerate() {
            out[i + j] += x * y;
        }
    }
}

/// The coefficients of `F(u)` (see the module docs), lowest degree first.
pub(crate) fn hit_polynomial<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    o: DVec3,
    d: DVec3,
    r: [f64; 2],
) -> [f64; 11] {
    let p = cyl.axis.points;
    // a(u) = c0 + c1 u + c2 u^2 + c3 u^3.
    let c = [p[0], 3.0 * (p[1] - p[0]), 3.0 * (p[2] - 2.0 * p[1] + p[0]), p[3] - 3.0 * p[2] + 3.0 * p[1] - p[0]];
    let e = [o - c[0], -c[1], -c[2], -c[3]];
    let da = [c[1], 2.0 * c[2], 3.0 * c[3]];
    let q = da.map(|x| x.dot(d));
    // m = a'.e, degree 5.
    let mut m = [0.0; 6];
    for k in 0..3 {
        let ek = e.map(|v| v[k]);
        let dk = da.map(|v| v[k]);
        let mut prod = [0.0; 6];
        mul_into(&dk, &ek, &mut prod);
        m.iter_mut().zip(prod).for_each(|(a, b)| *a += b);
    }
    // F = sum_k (q e_k - m d_k)^2 - r^2 q^2.
    let mut f = [0.0; 11];
    for k in 0..3 {
        let mut v = [0.0; 6];
        mul_into(&q, &e.map(|x| x[k]), &mut v);
        v.iter_mut().zip(m).for_each(|(a, mk)| *a -= mk * d[k]);
        let mut sq = [0.0; 11];
        mul_into(&v, &v, &mut sq);
        f.iter_mut().zip(sq).for_each(|(a, b)| *a += b);
    }
    let rq = {
        let rl = [r[0], r[1] - r[0]];
        let mut x = [0.0; 4];
        mul_into(&rl, &q, &mut x);
        x
    };
    let mut rq2 = [0.0; 7];
    mul_into(&rq, &rq, &mut rq2);
    f.iter_mut().zip(rq2).for_each(|(a, b)| *a -= b);
    f
}

/// Side roots of a circular fiber on `[lo, hi]` from the roots of `F`, each polished by
/// bracketed Newton iteration on the rational `|p|^2 / r^2 - 1`.
pub(crate) fn roots<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    o: DVec3,
    d: DVec3,
    lo: f64,
    hi: f64,
    out: &mut SideRoots,
) {
    let Some(r) = cyl.sweep.uniform_scale() else { return };
    let coeffs = hit_polynomial(cyl, o, d, r);
    let poly = PolyDyn::new(coeffs);
    let (mut found, mut scratch) = (Vec::with_capacity(10), Vec::with_capacity(10));
    poly.roots_between_with_buffer(lo, hi, 1e-13, &mut found, &mut scratch);
    let radial = Radial { cyl, o, d };
    let value = |u: f64| {
        let r = radial.eval(crate::real::Dual::var(u));
        (r.v, r.d)
    };
    let qscale = cyl.axis.hodograph().iter().fold(0.0f64, |m, h| m.max(h.length())) * d.length();
    for u in found {
        // A root at a pole is the in-plane case, handled by the caller.
        if cyl.axis.d1(u).dot(d).abs() <= 1e-13 * qscale {
            continue;
        }
        let h = 1e-9 * (1.0 + u.abs());
        let (a, b) = (u - h, u + h);
        let u = bracketed_root(&value, a, b, value(a).0, value(b).0).unwrap_or(u);
        cyl.push_circle_root(o, d, u, out);
    }
}
