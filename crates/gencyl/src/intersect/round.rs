//! Round fibers (a circle of radius `r(u)` at every `u`): the branch functions of
//! [`super::branches`] for the sphere of radius `r(u)` about `a(u)`, as polynomials in ray space.
//!
//! In coordinates with the ray's origin at 0, `x`, `y` across it and `z` along `d/|d|`, the axis
//! over a `u` range is a cubic Bezier `(X, Y, Z)(s)` (its control points are the range's, by
//! blossoming, so they lie near the fiber and rounding is relative to its size, not to the
//! distance from the world origin). The ray passes within `r` of `a` where
//!
//! `D(s) = r^2 - X^2 - Y^2 >= 0` (degree 6),
//!
//! it crosses that sphere at `z = Z ± sqrt(D)`, and such a crossing is in the normal plane at `s`
//! (so on the fiber) where `a'.(p - a) = -(X X' + Y Y') + Z' (z - Z)` vanishes:
//!
//! `H±(s) = -P(s) ± Z'(s) sqrt(D(s))`, `P = X X' + Y Y'` (degree 5), `Z'` (degree 2).
//!
//! All are polynomials (or a polynomial's square root) whose Bernstein coefficients on a cell
//! bound them there, so the roots are isolated rigorously with `f64` arithmetic alone: the cells
//! where `D` changes sign by the number of sign changes of its coefficients, then each branch on
//! each stretch where `D >= 0` by enclosures of `H` and `H'` (a cell whose `H` keeps one sign holds
//! no root, one whose `H'` keeps one sign holds at most one), and each isolated root polished by
//! Newton's method inside its bracket. Rounding: every coefficient is within `SLACK` times its
//! polynomial's largest coefficient of its exact value (they come from convex combinations of
//! the control points, de Casteljau steps and short sums), and every enclosure is widened by
//! that.

use arrayvec::ArrayVec;
use glam::{DVec2, DVec3};

use super::{SideRoot, SideRoots};
use crate::bernstein::Bernstein;
use crate::cylinder::GeneralizedCylinder;
use crate::real::{Interval, Real, V2};
use crate::roots::bracketed_root;
use crate::section::CrossSection;
use crate::sweep::SweepRule;

/// Relative rounding bound of the polynomials' coefficients and their restrictions to cells
/// (a few hundred units in the last place of the largest coefficient: each is a sum of at most
/// 16 products, then up to 60 de Casteljau levels of convex combinations).
const SLACK: f64 = 1e-13;
/// Cells narrower than this (in `s`) are not split: their roots are taken from sign changes.
const MIN_WIDTH: f64 = 1e-15;
/// Most cells examined per polynomial and stretch.
const BUDGET: usize = 400;

type B3 = Bernstein<3>;
type B5 = Bernstein<5>;
type B6 = Bernstein<6>;
type B7 = Bernstein<7>;

/// The ray-space polynomials of one `u` range, with their rounding bounds.
struct Polys {
    /// The axis' coordinate along the ray.
    z: Bernstein<4>,
    /// `D = r^2 - X^2 - Y^2` and `D'`.
    disc: B7,
    disc_s: B6,
    /// `P = X X' + Y Y'` and `P'`.
    p: B6,
    p_s: B5,
    /// `Z'` and `Z''`.
    z_s: B3,
    z_ss: Bernstein<2>,
    /// Rounding bounds of `D` (and `D'`), `P` (and `P'`), `Z'`.
    err_disc: f64,
    err_p: f64,
    err_z: f64,
}

/// `[lo, hi]` of a polynomial on a cell, widened by its rounding bound.
#[inline]
fn bounds<const K: usize>(b: &Bernstein<K>, err: f64) -> Interval {
    let (lo, hi) = b.range();
    Interval::new(lo - err, hi + err)
}

impl Polys {
    fn new(axis: [DVec3; 4], r: [f64; 2], o: DVec3, d: DVec3) -> Self {
        let w = d.normalize();
        let (e1, e2) = basis(w);
        let coords = |f: &dyn Fn(DVec3) -> f64| Bernstein(axis.map(|p| f(p - o)));
        let x = coords(&|p| p.dot(e1));
        let y = coords(&|p| p.dot(e2));
        let z = coords(&|p| p.dot(w));
        let (xs, ys, z_s): (B3, B3, B3) = (x.derivative(), y.derivative(), z.derivative());
        let rr = Bernstein([r[0], r[1]]);
        let r2: B3 = rr.mul(&rr);
        let (xx, yy): (B7, B7) = (x.mul(&x), y.mul(&y));
        let disc = r2.elevate::<7>().sub(&xx).sub(&yy);
        let (px, py): (B6, B6) = (x.mul(&xs), y.mul(&ys));
        let p = px.add(&py);
        let scale = |m: f64| SLACK * m;
        let err_disc = scale(xx.magnitude() + yy.magnitude() + r2.magnitude());
        let err_p = scale(px.magnitude() + py.magnitude());
        let err_z = scale(z_s.magnitude());
        Polys {
            z,
            disc_s: disc.derivative(),
            disc,
            p_s: p.derivative(),
            p,
            z_ss: z_s.derivative(),
            z_s,
            err_disc,
            err_p,
            err_z,
        }
    }

    /// `H` of branch `sign` at `s`, in `f64` (the same value [`Self::branch`] gives).
    #[inline]
    fn h(&self, s: f64, sign: f64) -> f64 {
        let root = self.disc.eval(s).max(0.0).sqrt();
        -self.p.eval(s) + sign * self.z_s.eval(s) * root
    }

    /// `(H, H')` of branch `sign` at `s`, in `f64`.
    #[inline]
    fn branch(&self, s: f64, sign: f64) -> (f64, f64) {
        // One de Casteljau run gives each polynomial and its derivative.
        let (dsc, dsc_s) = self.disc.eval_with_derivative(s);
        let root = dsc.max(0.0).sqrt();
        let (zs, zss) = self.z_s.eval_with_derivative(s);
        let (p, ps) = self.p.eval_with_derivative(s);
        let h = -p + sign * zs * root;
        let dh = -ps + sign * (zss * root + zs * dsc_s / (2.0 * root));
        (h, dh)
    }
}

/// An orthonormal pair across the unit vector `w` (Duff et al. 2017, branch-free).
fn basis(w: DVec3) -> (DVec3, DVec3) {
    let sign = 1f64.copysign(w.z);
    let a = -1.0 / (sign + w.z);
    let b = w.x * w.y * a;
    (
        DVec3::new(1.0 + sign * w.x * w.x * a, sign * b, -sign * w.x),
        DVec3::new(b, sign + w.y * w.y * a, -w.y),
    )
}

/// The polynomials of one cell of a stretch, restricted from the stretch's.
struct Cell {
    s0: f64,
    s1: f64,
    disc: B7,
    disc_s: B6,
    p: B6,
    p_s: B5,
    z_s: B3,
    z_ss: Bernstein<2>,
}

impl Cell {
    fn of(k: &Polys, s0: f64, s1: f64) -> Self {
        Cell {
            s0,
            s1,
            disc: k.disc.restrict(s0, s1),
            disc_s: k.disc_s.restrict(s0, s1),
            p: k.p.restrict(s0, s1),
            p_s: k.p_s.restrict(s0, s1),
            z_s: k.z_s.restrict(s0, s1),
            z_ss: k.z_ss.restrict(s0, s1),
        }
    }

    fn halves(&self) -> (Cell, Cell) {
        let m = 0.5 * (self.s0 + self.s1);
        let (d0, d1) = self.disc.split(0.5);
        let (ds0, ds1) = self.disc_s.split(0.5);
        let (p0, p1) = self.p.split(0.5);
        let (ps0, ps1) = self.p_s.split(0.5);
        let (z0, z1) = self.z_s.split(0.5);
        let (zz0, zz1) = self.z_ss.split(0.5);
        (
            Cell {
                s0: self.s0,
                s1: m,
                disc: d0,
                disc_s: ds0,
                p: p0,
                p_s: ps0,
                z_s: z0,
                z_ss: zz0,
            },
            Cell {
                s0: m,
                s1: self.s1,
                disc: d1,
                disc_s: ds1,
                p: p1,
                p_s: ps1,
                z_s: z1,
                z_ss: zz1,
            },
        )
    }
}

/// Isolates the roots of branch `sign` on the stretch `[a, b]` (where `D >= 0`), ascending.
fn branch_roots(k: &Polys, a: f64, b: f64, sign: f64, out: &mut ArrayVec<f64, 16>) {
    let value = |s: f64| k.branch(s, sign);
    let mut stack: ArrayVec<Cell, 64> = ArrayVec::new();
    stack.push(Cell::of(k, a, b));
    let mut cells = 0;
    while let Some(c) = stack.pop() {
        cells += 1;
        if cells == BUDGET + 1 {
            crate::budget::note_exhausted();
        }
        let disc = bounds(&c.disc, k.err_disc);
        let root = disc.sqrt_pos();
        let z_s = bounds(&c.z_s, k.err_z);
        let h = Interval::cst(0.0) - bounds(&c.p, k.err_p) + z_s * root * Interval::cst(sign);
        if h.excludes_zero() {
            continue;
        }
        let narrow =
            c.s1 - c.s0 <= MIN_WIDTH || cells > BUDGET || stack.len() + 2 > stack.capacity();
        // H' = -P' ± (Z'' sqrt(D) + Z' D' / (2 sqrt(D))), bounded only where D > 0 on the cell.
        let monotone = disc.lo > 0.0 && {
            let dh = Interval::cst(0.0) - bounds(&c.p_s, k.err_p)
                + (bounds(&c.z_ss, k.err_z) * root
                    + z_s * bounds(&c.disc_s, k.err_disc) / (root + root))
                    * Interval::cst(sign);
            dh.excludes_zero()
        };
        if monotone || narrow {
            let (fa, fb) = (k.h(c.s0, sign), k.h(c.s1, sign));
            if let Some(r) = bracketed_root(&value, c.s0, c.s1, fa, fb)
                && !out.is_full()
                && out.last().is_none_or(|&l| r > l)
            {
                out.push(r);
            }
            continue;
        }
        let (l, r) = c.halves();
        stack.push(r);
        stack.push(l);
    }
}

/// The side roots of a round fiber for the local ray `o + w d` on the `u` range `[u0, u1]`.
pub(crate) fn roots<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    o: DVec3,
    d: DVec3,
    (u0, u1): (f64, f64),
    out: &mut SideRoots,
) {
    let Some([r0, r1]) = cyl.sweep.uniform_scale() else {
        return;
    };
    let piece = cyl.axis.segment(u0, u1);
    let r = [r0 + (r1 - r0) * u0, r0 + (r1 - r0) * u1];
    let k = Polys::new(piece.points, r, o, d);
    let mut ends: ArrayVec<f64, 18> = ArrayVec::new();
    ends.push(0.0);
    let mut zs = ArrayVec::new();
    k.disc
        .roots(&k.disc_s, k.err_disc, MIN_WIDTH, BUDGET, &mut zs);
    ends.extend(zs);
    ends.push(1.0);
    let len = d.length();
    for w in ends.windows(2) {
        let (a, b) = (w[0], w[1]);
        if !(b > a) || !(k.disc.eval(0.5 * (a + b)) > 0.0) {
            continue;
        }
        for sign in [-1.0, 1.0] {
            let mut ss = ArrayVec::new();
            branch_roots(&k, a, b, sign, &mut ss);
            for s in ss {
                // The crossing of the sphere: z = Z ± sqrt(D) along d / |d| from o.
                let w = (k.z.eval(s) + sign * k.disc.eval(s).max(0.0).sqrt()) / len;
                let u = u0 + (u1 - u0) * s;
                push(cyl, o, d, u, w, out);
            }
        }
    }
}

/// Records the hit at `(u, w)`, unless it repeats one (both branches meet where `D = 0`).
fn push<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    o: DVec3,
    d: DVec3,
    u: f64,
    w: f64,
    out: &mut SideRoots,
) {
    if !w.is_finite() || out.is_full() {
        return;
    }
    let r = cyl.sweep.scale_bound()[0].max(cyl.sweep.scale_bound()[1]);
    let tol = 1e-12 * r / d.length();
    if out
        .iter()
        .any(|h| (h.u - u).abs() <= 1e-13 && (h.w - w).abs() <= tol)
    {
        return;
    }
    // The section angle: the offset from the axis in the frame, through the rule's rotation.
    let e = o + w * d - cyl.axis.point(u);
    let f = cyl.frame(u);
    let phi = cyl
        .sweep
        .inverse(u, V2::new(f.n.dot(e), f.b.dot(e)))
        .value();
    out.push(SideRoot {
        u,
        w,
        v: crate::section::angle(DVec2::new(phi.x, phi.y)),
    });
}
