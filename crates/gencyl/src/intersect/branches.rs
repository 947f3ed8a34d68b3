//! Unit-circle sections (round and elliptical fibers under any rule): the side roots as the
//! zeros of two branch functions of `u` that stay well conditioned at every angle.
//!
//! The section at `u` (the unit circle under the rule: an ellipse in the normal plane) is the
//! slice `z = 0` of the ellipsoid
//!
//! `E_u = { a(u) + x n + y b + z t : |s^-1((x, y), u)|^2 + (z / lambda(u))^2 = 1 }`
//!
//! (`lambda` = the major radius; any positive length would do). With `e = o - a(u)`,
//! `phi0 = s^-1(n.e, b.e)`, `phid = s^-1(n.d, b.d)`, `z0 = t.e / lambda`, `zd = t.d / lambda`, the
//! ray meets `E_u` where `A w^2 + 2 B w + C = 0`:
//!
//! `A = |phid|^2 + zd^2 > 0`, `B = phi0.phid + z0 zd`, `C = |phi0|^2 + z0^2 - 1`,
//!
//! at `w±(u) = (-B ± sqrt(D)) / A` where `D(u) = B^2 - A C >= 0`. A point of the ray is on the
//! side surface exactly when it lies on the section at some `u`: on `E_u` and in the normal plane
//! there. So the side roots are the zeros of the branch functions
//!
//! `H±(u) = a'(u).(o + w±(u) d - a(u)) = m + q w±`   (`m = a'.e`, `q = a'.d`)
//!
//! on the set where `D >= 0`, and every zero is a hit (`w = w±(u)`, `v` the angle of
//! `phi0 + w phid`). For a round fiber under a uniform scale `r(u)` the ellipsoid is the sphere of
//! radius `r(u)` about `a(u)` and the frame drops out: [`super::round`] solves that case with
//! polynomials in ray space.
//!
//! Why this and not `phi(u) = s^-1(rho(u))` with `w(u) = -m/q` (seed 2.1): where the ray is
//! nearly perpendicular to the axis, `q` is tiny, `w(u)` steep, and the entry and exit both fall
//! within `~|q| / |a'|^2` of one `u` (closer than `f64` resolves, at `1e-15` off perpendicular):
//! no root finder in `u` alone separates them, and `w(u)` at a rounded `u` is off by
//! `ulp(u) |a'|^2 / |q|`. Here the two hits lie on different branches (the entry of a round fiber
//! on `H-`, its exit on `H+`), each a simple zero with slope `H' = det J / (dG2/dw)` (the
//! Jacobian of the normal-plane and surface conditions, bounded away from 0 off tangency), and
//! `w±(u)` varies slowly with `u`: exactly perpendicular rays, planar fibers seen
//! orthographically and poles of `phi` need no special case. Shallow grazing chords stay simple
//! zeros too (the roots sit inside the branch domain, not at its ends where `D = 0`).

use arrayvec::ArrayVec;
use glam::{DVec2, DVec3};

use super::SideRoots;
use crate::cylinder::GeneralizedCylinder;
use crate::frame::Framing;
use crate::real::{Real, V2, V3};
use crate::roots::{Function1D, IsolateOptions, MAX_ROOTS, isolate_roots};
use crate::section::CrossSection;
use crate::sweep::SweepRule;

/// The ray's quadric intersection and normal-plane terms at `u`: `(A, B, D, m, q)` of the module
/// docs, for the ray `o' + w d` with `o'` the ray's point nearest `a(u.value())` (which keeps
/// `B` and the cancellation in `D` small); `w` is then relative to `o'`. The quadric's `A`, `B`
/// and `C` may come multiplied by a positive `k(u)^2`, and so `D` by `k^4` (a projection frame's,
/// formed without unit vectors): the roots `w±`, the signs of `D` and so the branches are the
/// same.
struct Terms<T> {
    a: T,
    b: T,
    disc: T,
    m: T,
    q: T,
}

/// A unit-circle fiber and a local ray.
pub(crate) struct Quadric<'a, C, S> {
    cyl: &'a GeneralizedCylinder<C, S>,
    o: DVec3,
    d: DVec3,
}

impl<'a, C: CrossSection, S: SweepRule> Quadric<'a, C, S> {
    /// The quadric of `cyl` (its frame's ellipsoid) for the local ray `o + w d`.
    pub(crate) fn new(cyl: &'a GeneralizedCylinder<C, S>, o: DVec3, d: DVec3) -> Self {
        Quadric { cyl, o, d }
    }

    /// The shift `s` of the origin to the ray's point nearest `a(u)`: `o' = o + s d`.
    #[inline(always)]
    fn shift(&self, u: f64) -> f64 {
        let s = self.d.dot(self.cyl.axis.point(u) - self.o) / self.d.length_squared();
        if s.is_finite() { s } else { 0.0 }
    }

    #[inline(always)]
    fn terms<T: Real>(&self, u: T, shift: f64) -> Terms<T> {
        let o = self.o + shift * self.d;
        let [ao, d1, d2] = self.cyl.axis_jet_r(u, o);
        let e = V3::new(-ao.x, -ao.y, -ao.z);
        let dd = self.d;
        let m = d1.dot(e);
        let q = d1.dot_cst(dd);
        let rule = &self.cyl.sweep;
        // `z / lambda`, by the constant where `lambda` is one.
        let [l0, l1] = rule.scale_bound();
        let over_lambda = |z: T| {
            if l0 == l1 {
                z.div_cst(l0)
            } else {
                z / (T::cst(l0) + u.scale(l1 - l0))
            }
        };
        // `(x, y, z)` coordinates of `e` and `d` in the frame, all times one positive `k`, and
        // `k^2`: the quadric's coefficients are then `k^2` times the module docs' (its roots
        // `w` the same, `D` times `k^4`).
        let ([e_n, e_b, e_t], [d_n, d_b, d_t], k2) =
            if let Framing::Projected(r) = self.cyl.framing() {
                // Without unit vectors: with `a = a'` (at unit size), `C = a x r` and
                // `N = C x a = |a|^2 r - (a.r) a`, the frame is `t = a/|a|`, `b = C/|C|`,
                // `n = N/(|a| |C|)`; times `k = |a| |C|`, the coordinates are `N.e`, `|a| C.e` and
                // `|C| a.e` (and so for `d`).
                let a = d1.scale(self.cyl.speed_scale());
                let c = a.cross_cst(*r);
                let (aa, cc, ar) = (a.norm2(), c.norm2(), a.dot_cst(*r));
                let (na, nc) = (aa.sqrt(), cc.sqrt());
                let (ae, ad) = (a.dot(e), a.dot_cst(dd));
                let (re, rd) = (e.dot_cst(*r), r.dot(dd));
                (
                    [aa * re - ar * ae, na * c.dot(e), nc * ae],
                    [aa.scale(rd) - ar * ad, na * c.dot_cst(dd), nc * ad],
                    aa * cc,
                )
            } else {
                let [t, n, bn] = self.cyl.frame_from_jet_r(u, d1, d2);
                (
                    [n.dot(e), bn.dot(e), t.dot(e)],
                    [n.dot_cst(dd), bn.dot_cst(dd), t.dot_cst(dd)],
                    T::cst(1.0),
                )
            };
        let phi0 = rule.inverse(u, V2::new(e_n, e_b));
        let phid = rule.inverse(u, V2::new(d_n, d_b));
        let (z0, zd) = (over_lambda(e_t), over_lambda(d_t));
        let a = phid.norm2() + zd.sqr();
        let b = phi0.dot(phid) + z0 * zd;
        let c = phi0.norm2() + z0.sqr() - k2;
        Terms {
            a,
            b,
            disc: b.sqr() - a * c,
            m,
            q,
        }
    }

    /// `w±(u)` relative to `o` (not `o'`), `H±(u)`.
    #[inline(always)]
    fn branch<T: Real>(&self, u: T, sign: f64) -> (T, T) {
        let shift = self.shift(u.value());
        let k = self.terms(u, shift);
        let w = (k.disc.sqrt_pos().scale(sign) - k.b) / k.a;
        (w + T::cst(shift), k.m + k.q * w)
    }

    /// The side roots on `[lo, hi]`, appended to `out` (unsorted).
    pub(crate) fn roots(&self, lo: f64, hi: f64, out: &mut SideRoots) {
        let outside = Outside(self);
        // Zeros narrower than this are not split further: the width of a grazing chord's
        // domain is sqrt(2 r depth) / |a'|, 4e-11 at depth 1e-9 r and r = 1e-6 |a'|.
        let opts = IsolateOptions {
            min_width: 1e-15,
            tangent_tolerance: 0.0,
            max_evaluations: 600,
            u_shaped: false,
        };
        let mut ends: ArrayVec<f64, { MAX_ROOTS + 2 }> = ArrayVec::new();
        ends.push(lo);
        let mut zs = ArrayVec::new();
        let u_shaped = IsolateOptions {
            u_shaped: true,
            ..opts
        };
        isolate_roots(&outside, lo, hi, &u_shaped, &mut zs);
        ends.extend(zs);
        ends.push(hi);
        for w in ends.windows(2) {
            let (a, b) = (w[0], w[1]);
            if !(b > a) || !(outside.eval(0.5 * (a + b)) < 0.0) {
                continue;
            }
            for sign in [-1.0, 1.0] {
                let mut us = ArrayVec::new();
                isolate_roots(&Branch { quad: self, sign }, a, b, &opts, &mut us);
                for u in us {
                    self.push(u, sign, out);
                }
            }
        }
    }

    /// Records the root at `u` on branch `sign`, unless it repeats one on the other branch
    /// (at a branch point, `D = 0`, both branches meet).
    fn push(&self, u: f64, sign: f64, out: &mut SideRoots) {
        let (w, _) = self.branch(u, sign);
        if !w.is_finite() {
            return;
        }
        let scale = self.cyl.sweep.scale_bound()[0].max(self.cyl.sweep.scale_bound()[1]);
        let tol = 1e-12 * scale / self.d.length();
        if out
            .iter()
            .any(|r| (r.u - u).abs() <= 1e-14 && (r.w - w).abs() <= tol)
        {
            return;
        }
        // The section angle of the hit: its in-plane offset through the rule's inverse.
        let e = self.o + w * self.d - self.cyl.axis.point(u);
        let f = self.cyl.frame(u);
        let phi = self
            .cyl
            .sweep
            .inverse(u, V2::new(f.n.dot(e), f.b.dot(e)))
            .value();
        super::push_side_root(
            out,
            super::SideRoot {
                u,
                w,
                v: crate::section::angle(DVec2::new(phi.x, phi.y)),
            },
        );
    }
}

/// `-D(u)`: the ray meets the ellipsoid `E_u` where it is not positive. Across a fiber it is
/// U-shaped (positive where the range begins and ends, beyond the ellipsoids' reach, negative
/// where the ray passes through them), which [`IsolateOptions::u_shaped`] splits from point
/// values without enclosing the whole range first (the CT of an elliptical ply about its fiber
/// axis, whose rays within `1e-3` of perpendicular take this method: 10% fewer instructions in
/// it than with `D` and plain cells).
struct Outside<'q, 'a, C, S>(&'q Quadric<'a, C, S>);

impl<C: CrossSection, S: SweepRule> Function1D for Outside<'_, '_, C, S> {
    #[inline]
    fn eval<T: Real>(&self, u: T) -> T {
        let q = self.0;
        -q.terms(u, q.shift(u.value())).disc
    }
}

/// `H±(u)` for `sign = ±1`.
struct Branch<'q, 'a, C, S> {
    quad: &'q Quadric<'a, C, S>,
    sign: f64,
}

impl<C: CrossSection, S: SweepRule> Function1D for Branch<'_, '_, C, S> {
    #[inline]
    fn eval<T: Real>(&self, u: T) -> T {
        self.quad.branch(u, self.sign).1
    }
}
