//! Any section, for rays nearly perpendicular to the axis: the ray's crossings of the section
//! extruded along the tangent, in the normal-plane condition, as a system in `(u, v)`.
//!
//! At each `u` the ray, projected along the tangent `t(u)` into the normal plane and mapped by
//! the rule's inverse, is the line `phi0(u) + w phid(u)` in section coordinates (with
//! `e = o - a(u)`: `phi0 = s^-1(n.e, b.e)`, `phid = s^-1(n.d, b.d)`): the ray meets the prism
//! `{section at u} + R t(u)` where that line crosses the section curve, at `cs(v)` with
//! `w = (cs(v) - phi0).phid / |phid|^2`. Such a crossing is a hit when it lies in the normal plane,
//! `m + q w = 0` (`m = a'.e`, `q = a'.d`). So the side roots on the section piece holding `v` are
//! the roots of
//!
//! `E1(u, v) = (cs(v) - phi0(u)) x phid(u)`,
//! `E2(u, v) = m(u) |phid(u)|^2 + q(u) (cs(v) - phi0(u)).phid(u)`,
//!
//! isolated by interval Newton on boxes ([`isolate_roots_2d`]). Unlike `phi(u) = cs(v)` with
//! `w = -m/q` (seed 2.1, [`super::curve_curve`]), whose `v` column `-q cs'(v)` vanishes with `q`,
//! the Jacobian stays regular as `q -> 0`: `E2` pins `u` (through `m`), `E1` pins `v` (through
//! the line), and exactly perpendicular rays need no special case. Away from perpendicular the
//! subdivision of [`super::curve_curve`] is faster and is used instead.

use arrayvec::ArrayVec;
use glam::{DVec2, DVec3};

use super::{SideRoot, SideRoots};
use crate::cylinder::GeneralizedCylinder;
use crate::real::{Dual, Interval, Real, Taylor, V2, V3};
use crate::roots::{Enclosure2, Function2D, Isolate2D, isolate_roots_2d};
use crate::section::CrossSection;
use crate::sweep::SweepRule;

/// `(E1, E2)` for the local ray `o + w d`.
struct Prism<'a, C, S> {
    cyl: &'a GeneralizedCylinder<C, S>,
    o: DVec3,
    d: DVec3,
}

/// `E` split for enclosures over a box: with `cm` the section point at the box's middle `v`,
/// `E1 = (cs(v) - cm) x A + G1(u)` and `E2 = G2(u) + Q.(cs(v) - cm)`, where `A = phid`,
/// `Q = q phid`, and `G = E(u, v_mid)` is enclosed as one function of `u` (one Taylor model),
/// which keeps the cancellation between `cm x phid` and `phi0 x phid` inside it; only the
/// small `cs(v) - cm` multiplies separately enclosed terms.
struct UPart<T> {
    a: V2<T>,
    q: V2<T>,
    g: [T; 2],
}

impl<C: CrossSection, S: SweepRule> Prism<'_, C, S> {
    /// `phi0(u)`, `phid(u)`, `m(u)`, `q(u)` and the shift of `o` they are taken from. `E` does not change when `o` moves along the ray
    /// (`phi0` moves along `phid` and `m` by `q` times the shift), so `o` is first moved to the
    /// ray's point nearest `a(u.value())`: `e` is then small near a hit, and so is the
    /// cancellation in `cs - phi0` (to the fiber's radius, not the range's length).
    #[inline(always)]
    fn line<T: Real>(&self, u: T) -> (V2<T>, V2<T>, T, T, f64) {
        let s = self.d.dot(self.cyl.axis.point(u.value()) - self.o) / self.d.length_squared();
        let s = if s.is_finite() { s } else { 0.0 };
        let o = self.o + s * self.d;
        let [ao, d1, d2] = self.cyl.axis_jet_r(u, o);
        let e = V3::new(-ao.x, -ao.y, -ao.z);
        let [_, n, b] = self.cyl.frame_from_jet_r(u, d1, d2);
        let rule = &self.cyl.sweep;
        let phi0 = rule.inverse(u, V2::new(n.dot(e), b.dot(e)));
        let phid = rule.inverse(u, V2::new(n.dot_cst(self.d), b.dot_cst(self.d)));
        (phi0, phid, d1.dot(e), d1.dot_cst(self.d), s)
    }

    #[inline(always)]
    fn u_part<T: Real>(&self, u: T, cm: DVec2) -> UPart<T> {
        let (p0, pd, m, q, _) = self.line(u);
        let rel = V2::new(T::cst(cm.x) - p0.x, T::cst(cm.y) - p0.y);
        UPart {
            a: pd,
            q: V2::new(q * pd.x, q * pd.y),
            g: [
                rel.x * pd.y - rel.y * pd.x,
                m * pd.norm2() + q * rel.dot(pd),
            ],
        }
    }
}

/// `E` from its split at `cm` and the section point's offset `dc = cs(v) - cm`.
#[inline(always)]
fn combine<T: Real>(p: &UPart<T>, dc: V2<T>) -> [T; 2] {
    [dc.x * p.a.y - dc.y * p.a.x + p.g[0], p.g[1] + p.q.dot(dc)]
}

impl<C: CrossSection, S: SweepRule> Function2D for Prism<'_, C, S> {
    fn jet(&self, x: [f64; 2]) -> ([f64; 2], [[f64; 2]; 2]) {
        // Split at the point's own section point: dc = 0, and d/dv comes from cs'(v) alone.
        let c = self.cyl.section.point_r(Dual::var(x[1]));
        let (cv, cd) = (DVec2::new(c.x.v, c.y.v), V2::new(c.x.d, c.y.d));
        let p = self.u_part(Dual::var(x[0]), cv);
        let f = [p.g[0].v, p.g[1].v];
        let du = [p.g[0].d, p.g[1].d];
        let (a, q) = (V2::new(p.a.x.v, p.a.y.v), V2::new(p.q.x.v, p.q.y.v));
        let dv = [cd.x * a.y - cd.y * a.x, q.dot(cd)];
        (f, [[du[0], dv[0]], [du[1], dv[1]]])
    }

    fn enclose(&self, lo: [f64; 2], hi: [f64; 2]) -> Enclosure2 {
        let mid = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])];
        let cm = self.cyl.section.point(mid[1]);
        let p = self.u_part(Dual::var(Taylor::var(lo[0], hi[0])), cm);
        let iv = |t: Taylor| t.enclosure();
        let value = UPart {
            a: V2::new(iv(p.a.x.v), iv(p.a.y.v)),
            q: V2::new(iv(p.q.x.v), iv(p.q.y.v)),
            g: [iv(p.g[0].v), iv(p.g[1].v)],
        };
        let slope = UPart {
            a: V2::new(iv(p.a.x.d), iv(p.a.y.d)),
            q: V2::new(iv(p.q.x.d), iv(p.q.y.d)),
            g: [iv(p.g[0].d), iv(p.g[1].d)],
        };
        let c = self
            .cyl
            .section
            .point_r(Dual::var(Interval::exact(lo[1], hi[1])));
        let dc = V2::new(c.x.v - Interval::cst(cm.x), c.y.v - Interval::cst(cm.y));
        let cd = V2::new(c.x.d, c.y.d);
        let du = combine(&slope, dc);
        let dv = [cd.x * value.a.y - cd.y * value.a.x, value.q.dot(cd)];
        // At the centre: the u part as a point enclosure, the section point's offset from cm
        // as an interval (cm is the rounded point; the exact one differs by rounding).
        let pc = self.u_part(Interval::cst(mid[0]), cm);
        let cc = self.cyl.section.point_r(Interval::cst(mid[1]));
        let dcc = V2::new(cc.x - Interval::cst(cm.x), cc.y - Interval::cst(cm.y));
        // Near an inflection the frame's enclosure blows up over ranges of u that reach it:
        // those are split in u (splitting v would only double them).
        let bounded = [
            value.a.x, value.a.y, value.q.x, value.q.y, value.g[0], value.g[1],
        ]
        .iter()
        .chain(&[
            slope.a.x, slope.a.y, slope.q.x, slope.q.y, slope.g[0], slope.g[1],
        ])
        .all(|x| x.lo.is_finite() && x.hi.is_finite());
        Enclosure2 {
            f: combine(&value, dc),
            j: [[du[0], dv[0]], [du[1], dv[1]]],
            f_center: combine(&pc, dcc),
            split: (!bounded).then_some(0),
        }
    }
}

/// In `u`, `1e-13` moves the point by `1e-13` of the axis' length; in `v`, `1e-12` of the
/// section's size: the enclosures of `E` are at their rounding floor about there.
const OPTS: Isolate2D = Isolate2D {
    min_width: [1e-13, 1e-12 * std::f64::consts::TAU],
    max_boxes: 2000,
};

/// The side roots on the `u` range `[u0, u1]`, appended to `out`.
pub(crate) fn roots<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    o: DVec3,
    d: DVec3,
    (u0, u1): (f64, f64),
    out: &mut SideRoots,
) {
    // Work from the ray's point nearest the range's middle: small offsets, small cancellation.
    let shift = d.dot(cyl.axis.point(0.5 * (u0 + u1)) - o) / d.length_squared();
    let shift = if shift.is_finite() { shift } else { 0.0 };
    let f = Prism {
        cyl,
        o: o + shift * d,
        d,
    };
    let breaks = cyl.section.monotone_breaks();
    let opts = OPTS;
    let stretches = cyl.smooth_stretches(u0, u1);
    for (a, b) in stretches {
        for vw in breaks.windows(2) {
            let mut found = ArrayVec::new();
            isolate_roots_2d(&f, [a, vw[0]], [b, vw[1]], &opts, &mut found);
            for [u, v] in found {
                let (phi0, phid, _, _, s) = f.line(u);
                let (phi0, phid) = (phi0.value(), phid.value());
                let w = (cyl.section.point(v) - phi0).dot(phid) / phid.length_squared();
                push(u, w + s + shift, v.rem_euclid(std::f64::consts::TAU), out);
            }
        }
    }
}

/// The roots `(u, v)` in the box `[lo, hi]` (which must lie in one smooth stretch of the frame
/// and one smooth piece of the section), for pairs of pieces found by [`super::curve_curve`].
pub(crate) fn box_roots<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    o: DVec3,
    d: DVec3,
    lo: [f64; 2],
    hi: [f64; 2],
    out: &mut ArrayVec<(f64, f64), 16>,
) {
    let f = Prism { cyl, o, d };
    let mut found = ArrayVec::new();
    isolate_roots_2d(&f, lo, hi, &OPTS, &mut found);
    out.extend(found.into_iter().map(|[u, v]| (u, v)));
}

/// Records a root unless it repeats one (a root on a break between two pieces is found in
/// both).
fn push(u: f64, w: f64, v: f64, out: &mut SideRoots) {
    if !w.is_finite() {
        return;
    }
    let dup = out.iter().any(|r| {
        let dv = (r.v - v).abs();
        (r.u - u).abs() <= 1e-12 && dv.min(std::f64::consts::TAU - dv) <= 1e-9
    });
    if !dup {
        super::push_side_root(out, SideRoot { u, w, v });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cylinder::FiberSpec;

    /// The box enclosures of `E` and its Jacobian hold the values sampled in the box, and the
    /// enclosure at the centre holds the value there: on a tapered round fiber near a grazing
    /// pair of roots, and on random boxes around random rays of curved elliptical fibers.
    #[test]
    fn enclosures_hold_sampled_values() {
        let tapered = FiberSpec {
            bezier: [
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(0.2, 0.5, -0.2),
                DVec3::new(0.8, 0.6, 0.3),
                DVec3::new(0.9, 0.1, 0.6),
            ],
            major_radius: [0.06, 0.02],
            minor_radius: [0.06, 0.02],
            rotation: [0.0, 0.0],
            caps: true,
            normal_hint: None,
            section: crate::section::Section::default(),
        }
        .build()
        .unwrap();
        let o = DVec3::new(
            0.18017821106558374,
            0.20827309502998492,
            -0.07480194825773012,
        ) - tapered.origin;
        let d = DVec3::new(
            -0.18561877488980658,
            0.6193357598647236,
            -0.7628688530548309,
        );
        let mut boxes = vec![(
            &tapered,
            o,
            d,
            [0.18591266318090854, 1.4689735583090249],
            [0.18591277625202646, 1.4689807488439681],
        )];
        for (cyl, o, d, lo, hi) in boxes.drain(..) {
            let f = Prism { cyl, o, d };
            let enc = f.enclose(lo, hi);
            let within = |e: Interval, x: f64, what: &str| {
                let slack = 1e-12 * (1.0 + x.abs());
                assert!(
                    e.lo - slack <= x && x <= e.hi + slack,
                    "{what}: {x} outside {e:?}"
                );
            };
            let mid = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])];
            let (fc, _) = f.jet(mid);
            within(enc.f_center[0], fc[0], "E1 at the centre");
            within(enc.f_center[1], fc[1], "E2 at the centre");
            for i in 0..=8 {
                for j in 0..=8 {
                    let x = [
                        lo[0] + (hi[0] - lo[0]) * i as f64 / 8.0,
                        lo[1] + (hi[1] - lo[1]) * j as f64 / 8.0,
                    ];
                    let (g, jac) = f.jet(x);
                    within(enc.f[0], g[0], "E1");
                    within(enc.f[1], g[1], "E2");
                    for (r, c) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                        within(enc.j[r][c], jac[r][c], &format!("J[{r}][{c}] at {x:?}"));
                    }
                }
            }
        }
    }
}
