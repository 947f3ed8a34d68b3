//! The polynomial fast path for circular fibers.
//!
//! For a circular section of radius `r(u) = r0 + (r1 - r0) u` the surface is the set of points at
//! distance `r(u)` from `a(u)` in the normal plane at `u`, whatever the frame. With `e = o - a(u)`,
//! `q = a'.d`, `m = a'.e` and `w = -m/q`, the offset `p = e + w d` satisfies
//! `q p = q e - m d`, so `|p|^2 = r^2` becomes
//! `F(u) = |q e - m d|^2 - r^2 q^2 = 0`: `q e - m d` has degree 5 in `u`, so `F` has degree 10.
//! At a pole (`q = 0`), `F = m^2 |d|^2 >= 0` vanishes only where the ray lies in the normal
//! plane, which the caller handles; so the roots of `F` with `q != 0` are exactly the hits.

use arrayvec::ArrayVec;
use glam::DVec3;
use polycool::PolyDyn;

use super::{Radial, SideRoots};
use crate::cylinder::GeneralizedCylinder;
use crate::real::Dual;
use crate::roots::Function1D;
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
    let c = [
        p[0],
        3.0 * (p[1] - p[0]),
        3.0 * (p[2] - 2.0 * p[1] + p[0]),
        p[3] - 3.0 * p[2] + 3.0 * p[1] - p[0],
    ];
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

/// Side roots of a circular fiber on `[lo, hi]`: the roots of `F` (Yuksel's method on the
/// expanded coefficients), each polished by Newton's method on `F` evaluated in product form
/// ([`Radial`], which is far better conditioned than the expanded coefficients where two roots
/// nearly coincide: a ray almost in one normal plane). If a polish fails or two roots merge, the
/// segment falls back to interval isolation.
pub(crate) fn roots<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    o: DVec3,
    d: DVec3,
    lo: f64,
    hi: f64,
    out: &mut SideRoots,
) {
    let Some(r) = cyl.sweep.uniform_scale() else {
        return;
    };
    let coeffs = hit_polynomial(cyl, o, d, r);
    let poly = PolyDyn::new(coeffs);
    // polycool's dynamic-degree solver wants Vec buffers: per-thread ones, reused.
    thread_local! {
        static BUFFERS: std::cell::RefCell<(Vec<f64>, Vec<f64>)> = const { std::cell::RefCell::new((Vec::new(), Vec::new())) };
    }
    let found: ArrayVec<f64, 16> = BUFFERS.with_borrow_mut(|(found, scratch)| {
        poly.roots_between_with_buffer(lo, hi, 1e-13, found, scratch);
        found.iter().copied().take(16).collect()
    });
    let radial = Radial {
        cyl,
        o,
        d,
        radius: 1.0,
    };
    let value = |u: f64| {
        let r = radial.eval(Dual::var(u));
        (r.v, r.d)
    };
    let qscale = cyl.q_scale(d);
    let mut polished: ArrayVec<f64, 16> = ArrayVec::new();
    for u in found {
        // A root at a pole is the in-plane case, handled by the caller.
        if cyl.axis.d1(u).dot(d).abs() <= 1e-13 * qscale {
            continue;
        }
        match newton(&value, u) {
            Some(x) if (x - u).abs() <= 1e-4 && x >= lo && x <= hi && !polished.is_full() => {
                polished.push(x)
            }
            _ => return fallback(cyl, o, d, lo, hi, out),
        }
    }
    if polished.windows(2).any(|w| (w[1] - w[0]).abs() <= 1e-14) {
        return fallback(cyl, o, d, lo, hi, out);
    }
    for u in polished {
        cyl.push_circle_root(o, d, u, out);
    }
}

fn fallback<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    o: DVec3,
    d: DVec3,
    lo: f64,
    hi: f64,
    out: &mut SideRoots,
) {
    for u in cyl.radial_roots_between(o, d, 1.0, lo, hi) {
        cyl.push_circle_root(o, d, u, out);
    }
}

/// Newton's method from `x`; `None` unless the step falls below the resolution of `f64`.
fn newton(value: &impl Fn(f64) -> (f64, f64), mut x: f64) -> Option<f64> {
    for _ in 0..40 {
        let (f, df) = value(x);
        if f == 0.0 {
            return Some(x);
        }
        let step = f / df;
        if !step.is_finite() {
            return None;
        }
        x -= step;
        if step.abs() <= 4.0 * f64::EPSILON * x.abs().max(1e-300) {
            return Some(x);
        }
    }
    None
}
