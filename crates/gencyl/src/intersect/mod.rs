//! Ray intersection: the Hsu-Chelberg pipeline and its fast paths.
//!
//! For each `u` the ray meets the normal plane at `w(u) = -a'(u).(o - a(u)) / q(u)` with
//! `q(u) = a'(u).d`, a quadratic. The side surface is hit where `phi(u) = s^-1(rho(u), u)` lies on
//! the section `cs(v)`:
//!
//! 1. Where `q` vanishes on all of `[0, 1]` (the axis lies in a plane perpendicular to the ray),
//!    the ray lies in the normal plane at each root of `N(u) = a'(u).(a(u) - o)` and nowhere
//!    else meets one: intersect the ray with the contour there, in 2D ([`Self::in_plane_roots`]).
//! 2. Otherwise, at a root of `q` (a pole of `rho`) where `N` vanishes too, the ray lies in that
//!    normal plane: intersect with the contour there as well.
//! 3. Solve `phi(u) on cs` by one of the [`Method`]s. They work with `q phi` rather than `phi`
//!    (see [`Radial`]), which is finite through the poles, so no splitting at poles is needed.
//! 4. Caps: the ray against the planes at `u = 0` and `u = 1`, inside the section.

mod curve_curve;
mod polynomial;
mod prefilter;

use arrayvec::ArrayVec;
use glam::{DVec2, DVec3};

use crate::cylinder::{GeneralizedCylinder, Hit, Part, Ray, v2};
use crate::real::{Real, V2};
use crate::roots::{Function1D, IsolateOptions, MAX_ROOTS, isolate_roots, quadratic_roots};
use crate::section::CrossSection;
use crate::sweep::SweepRule;

/// How the side surface's roots are found.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Method {
    /// The fastest method that applies: [`Method::Polynomial`] for a circular section under a
    /// uniform-scale rule, [`Method::Radial`] for the unit circle, [`Method::General`] otherwise.
    #[default]
    Auto,
    /// Circular fibers: with `e = o - a(u)` and `m = a'.e`, the hit condition
    /// `|o + w d - a|^2 = r(u)^2` times `q^2` is the degree-10 polynomial
    /// `F(u) = |q e - m d|^2 - r(u)^2 q^2`; the frame drops out.
    Polynomial,
    /// The unit circle: `|phi(u)|^2 - 1 = 0`, a 1D root problem solved by interval subdivision.
    Radial,
    /// Seed 2.3: split `phi` and `cs` into monotone, inflection-free pieces, subdivide pairs with
    /// overlapping end-point boxes until both are linear, intersect the chords, polish by
    /// Newton's method on `phi(u) = cs(v)`. Works for any section.
    General,
}

/// Roots are searched on `[-U_MARGIN, 1 + U_MARGIN]` and clamped to `[0, 1]`, so a ray through
/// the joint of two strand segments is not lost between them to rounding.
pub(crate) const U_MARGIN: f64 = 1e-11;

/// A prefilter range `[a, b]` of `[0, 1]` grown to the search margin at the ends of `[lo, hi]`.
fn widen(a: f64, b: f64, lo: f64, hi: f64) -> (f64, f64) {
    (if a <= 0.0 { lo } else { a }, if b >= 1.0 { hi } else { b })
}

/// A side-surface root: axis parameter, local ray parameter, section parameter.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SideRoot {
    pub u: f64,
    pub w: f64,
    pub v: f64,
}

pub(crate) type SideRoots = ArrayVec<SideRoot, 64>;

/// `N(u) = a'(u).(a(u) - o)`: zero where the ray's origin projects onto the normal plane at `u`.
struct PlaneFoot<'a, C, S> {
    cyl: &'a GeneralizedCylinder<C, S>,
    o: DVec3,
}

impl<C: CrossSection, S: SweepRule> Function1D for PlaneFoot<'_, C, S> {
    fn eval<T: Real>(&self, u: T) -> T {
        let e = self.cyl.axis.point_r(u) - crate::real::V3::cst(self.o);
        self.cyl.axis.d1_r(u).dot(e)
    }
}

/// `g(u) = q^2 (|phi(u)|^2 - R^2) = |q phi|^2 - R^2 q^2`: negative exactly where the ray's
/// point in the normal plane at `u` maps inside the disc of radius `R` in section coordinates.
/// With `R = 1` its roots are the hits on the unit-circle section. Unlike `|phi|^2 - R^2` it has
/// no poles where `q = a'.d` vanishes (there `g = |s^-1(m d)|^2 >= 0`, zero only when the ray lies
/// in that normal plane), so one root search covers `[0, 1]` and interval enclosures stay tight.
pub(crate) struct Radial<'a, C, S> {
    pub cyl: &'a GeneralizedCylinder<C, S>,
    pub o: DVec3,
    pub d: DVec3,
    pub radius: f64,
}

impl<C: CrossSection, S: SweepRule> Function1D for Radial<'_, C, S> {
    #[inline]
    fn eval<T: Real>(&self, u: T) -> T {
        if let Some(k) = self.cyl.sweep.uniform_scale() {
            // |q phi| = |V| / r(u): no frame needed (the polynomial of `Method::Polynomial`).
            let (v, q) = self.cyl.scaled_offset_r(self.o, self.d, u);
            let r = (T::cst(k[0]) + u.scale(k[1] - k[0])).scale(self.radius);
            v.norm2() - (r * q).sqr()
        } else {
            let (qphi, q) = self.cyl.scaled_phi_r(self.o, self.d, u);
            qphi.norm2() - q.sqr().scale(self.radius * self.radius)
        }
    }
}

impl<C: CrossSection, S: SweepRule> GeneralizedCylinder<C, S> {
    /// Largest `|a'(u).d|` bound: the scale of `q`, for relative tolerances.
    pub(crate) fn q_scale(&self, d: DVec3) -> f64 {
        self.axis
            .hodograph()
            .iter()
            .fold(0.0f64, |m, h| m.max(h.length()))
            * d.length()
    }

    /// Root-isolation settings for [`Radial`]: `g = q^2 (|phi|^2 - R^2)`, so a tangential root is
    /// accepted where `|g| <= 1e-9 q_scale^2 R^2` (the ray passes within about `5e-10` of the
    /// section size of the surface).
    fn radial_options(&self, d: DVec3, radius: f64) -> IsolateOptions {
        let qs = self.q_scale(d) * radius;
        IsolateOptions {
            tangent_tolerance: 1e-9 * qs * qs,
            ..Default::default()
        }
    }

    /// The sorted roots of [`Radial`] with the given radius on `[lo, hi]`.
    pub(crate) fn radial_roots_between(
        &self,
        o: DVec3,
        d: DVec3,
        radius: f64,
        lo: f64,
        hi: f64,
    ) -> ArrayVec<f64, MAX_ROOTS> {
        let mut us = ArrayVec::new();
        isolate_roots(
            &Radial {
                cyl: self,
                o,
                d,
                radius,
            },
            lo,
            hi,
            &self.radial_options(d, radius),
            &mut us,
        );
        us
    }
}

impl<C: CrossSection, S: SweepRule> GeneralizedCylinder<C, S> {
    /// The nearest hit with `tmin < t < tmax`, if any.
    pub fn intersect(&self, ray: &Ray, tmin: f64, tmax: f64) -> Option<Hit> {
        // A per-thread buffer: no allocation per ray once it has grown.
        thread_local! {
            static HITS: std::cell::RefCell<Vec<Hit>> = const { std::cell::RefCell::new(Vec::new()) };
        }
        HITS.with_borrow_mut(|hits| {
            hits.clear();
            self.intersect_all(ray, tmin, tmax, hits);
            hits.first().copied()
        })
    }

    /// Appends every hit with `tmin < t < tmax` to `out`, sorted by `t`.
    pub fn intersect_all(&self, ray: &Ray, tmin: f64, tmax: f64, out: &mut Vec<Hit>) {
        self.intersect_all_with(ray, tmin, tmax, Method::Auto, out);
    }

    /// [`Self::intersect_all`] with a chosen method for the side surface; a method that does not
    /// apply to this cylinder (say `Polynomial` for an ellipse) is replaced by `General`.
    pub fn intersect_all_with(
        &self,
        ray: &Ray,
        tmin: f64,
        tmax: f64,
        method: Method,
        out: &mut Vec<Hit>,
    ) {
        let d = ray.dir;
        let start = out.len();
        if !(d.length_squared() > 0.0) || !d.is_finite() || !ray.origin.is_finite() {
            return;
        }
        let Some((b0, b1)) = self.bounds().ray_range(ray) else {
            return;
        };
        if b1 <= tmin || b0 >= tmax {
            return;
        }
        // Work near the fiber: o is the ray's point closest to the box centre, t = t0 + w.
        let o_local = ray.origin - self.origin;
        let t0 = (self.bounds().center() - self.origin - o_local).dot(d) / d.length_squared();
        let o = o_local + t0 * d;

        let mut roots = SideRoots::new();
        self.side_roots(o, d, self.resolve(method), &mut roots);
        for r in &roots {
            let t = t0 + r.w;
            if t > tmin && t < tmax && t.is_finite() {
                let u = r.u.clamp(0.0, 1.0);
                // v in [0, 2 pi): rem_euclid of a tiny negative angle can round up to 2 pi.
                let v = if r.v >= std::f64::consts::TAU || r.v < 0.0 {
                    r.v.rem_euclid(std::f64::consts::TAU) % std::f64::consts::TAU
                } else {
                    r.v
                };
                out.push(Hit {
                    t,
                    u,
                    v,
                    point: ray.at(t),
                    normal: self.normal(u, v),
                    part: Part::Side,
                });
            }
        }
        for (part, closed) in [(Part::StartCap, self.caps[0]), (Part::EndCap, self.caps[1])] {
            if let Some((w, v)) = closed.then(|| self.cap_root(o, d, part)).flatten() {
                let t = t0 + w;
                if t > tmin && t < tmax {
                    let u = if part == Part::StartCap { 0.0 } else { 1.0 };
                    out.push(Hit {
                        t,
                        u,
                        v,
                        point: ray.at(t),
                        normal: self.cap_normal(part),
                        part,
                    });
                }
            }
        }
        out[start..].sort_by(|a, b| a.t.total_cmp(&b.t));
    }

    fn resolve(&self, method: Method) -> Method {
        let circle = self.section.is_unit_circle();
        let uniform = self.sweep.uniform_scale().is_some();
        match method {
            Method::Auto if circle && uniform => Method::Polynomial,
            Method::Auto if circle => Method::Radial,
            Method::Polynomial if circle && uniform => Method::Polynomial,
            Method::Radial if circle => Method::Radial,
            _ => Method::General,
        }
    }

    /// Every side root for the local ray `o + w d` (steps 1-3 of the module docs).
    pub(crate) fn side_roots(&self, o: DVec3, d: DVec3, method: Method, out: &mut SideRoots) {
        let hod = self.axis.hodograph();
        let qb = hod.map(|h| h.dot(d));
        let scale = hod.iter().fold(0.0f64, |m, h| m.max(h.length())) * d.length();
        let (lo, hi) = (-U_MARGIN, 1.0 + U_MARGIN);
        // Step 1: q(u) is a Bernstein quadratic; if all its coefficients vanish, so does q.
        if qb.iter().all(|x| x.abs() <= 1e-13 * scale) {
            let mut feet = ArrayVec::new();
            let size = self.bounds().max - self.bounds().min;
            let opts = IsolateOptions {
                tangent_tolerance: 1e-24 * scale * size.length_squared(),
                ..Default::default()
            };
            isolate_roots(&PlaneFoot { cyl: self, o }, lo, hi, &opts, &mut feet);
            for u in feet {
                self.in_plane_roots(o, d, u, out);
            }
            return;
        }
        // Step 2: the poles, q(u) = qb0 (1-u)^2 + 2 qb1 u (1-u) + qb2 u^2.
        let poles: ArrayVec<f64, 2> =
            quadratic_roots(qb[0] - 2.0 * qb[1] + qb[2], 2.0 * (qb[1] - qb[0]), qb[0])
                .into_iter()
                .filter(|&u| u > lo && u < hi)
                .collect();
        let size = (self.bounds().max - self.bounds().min).length();
        for &up in &poles {
            let n = PlaneFoot { cyl: self, o }.eval(up);
            if n.abs() <= 1e-12 * self.axis.d1(up).length() * size {
                self.in_plane_roots(o, d, up, out);
            }
        }
        // Step 3.
        match method {
            Method::Polynomial => polynomial::roots(self, o, d, lo, hi, out),
            Method::Radial => {
                for (a, b) in prefilter::candidate_ranges(self, o, d) {
                    let (a, b) = widen(a, b, lo, hi);
                    for u in self.radial_roots_between(o, d, 1.0, a, b) {
                        self.push_circle_root(o, d, u, out);
                    }
                }
            }
            _ => {
                // Only where phi lies in the section's bounding disc can it meet the section:
                // between sign changes of g with R = the bounding radius, where g < 0. There phi
                // is bounded (no poles), which keeps the subdivision short. A 1% larger disc keeps
                // the hits well inside the ranges.
                let r = self.section.bounding_radius() * 1.01;
                let g = Radial {
                    cyl: self,
                    o,
                    d,
                    radius: r,
                };
                let mut found = ArrayVec::new();
                for (a, b) in prefilter::candidate_ranges(self, o, d) {
                    let (a, b) = widen(a, b, lo, hi);
                    let mut ends: ArrayVec<f64, { MAX_ROOTS + 2 }> = ArrayVec::new();
                    ends.push(a);
                    ends.extend(self.radial_roots_between(o, d, r, a, b));
                    ends.push(b);
                    for w in ends.windows(2) {
                        let (a, b) = (w[0], w[1]);
                        if b > a && g.eval(0.5 * (a + b)) < 0.0 {
                            curve_curve::roots(self, o, d, (a, b), (lo, hi), &mut found);
                        }
                    }
                }
                curve_curve::dedupe(&mut found);
                for (u, v) in found {
                    let w = self.plane_w_r(o, d, u);
                    if w.is_finite() && !out.is_full() {
                        out.push(SideRoot { u, w, v });
                    }
                }
            }
        }
    }

    /// Records the root at `u` of a unit-circle section, with `v` the angle of `phi(u)`.
    pub(crate) fn push_circle_root(&self, o: DVec3, d: DVec3, u: f64, out: &mut SideRoots) {
        let (phi, w) = self.phi_r(o, d, u);
        if w.is_finite() && !out.is_full() {
            out.push(SideRoot {
                u,
                w,
                v: crate::section::angle(v2(phi)),
            });
        }
    }

    /// The ray lies in the normal plane at `u`: it is the line `phi0 + w phid` in section
    /// coordinates (the rule is linear in the section point); intersect it with the section.
    pub(crate) fn in_plane_roots(&self, o: DVec3, d: DVec3, u: f64, out: &mut SideRoots) {
        let f = self.frame(u);
        let e = o - self.axis.point(u);
        let rho0 = V2::new(f.n.dot(e), f.b.dot(e));
        let rhod = V2::new(f.n.dot(d), f.b.dot(d));
        let phi0 = v2(self.sweep.inverse(u, rho0));
        let phid = v2(self.sweep.inverse(u, rhod));
        if phid == DVec2::ZERO {
            return;
        }
        for (w, v) in self.section.intersect_line(phi0, phid) {
            if !out.is_full() {
                out.push(SideRoot { u, w, v });
            }
        }
    }

    /// The cap at `u = 0` or `1`: the plane `t.(x - a) = 0` meets the ray at
    /// `w = t.(a - o) / t.d`; it is a hit when `s^-1(rho)` lies inside the section.
    fn cap_root(&self, o: DVec3, d: DVec3, part: Part) -> Option<(f64, f64)> {
        let u = if part == Part::StartCap { 0.0 } else { 1.0 };
        let f = self.frame(u);
        let a = self.axis.point(u);
        let denom = f.t.dot(d);
        if denom == 0.0 {
            return None;
        }
        let w = f.t.dot(a - o) / denom;
        let e = o + w * d - a;
        let phi = v2(self.sweep.inverse(u, V2::new(f.n.dot(e), f.b.dot(e))));
        self.section
            .contains(phi)
            .then(|| (w, crate::section::angle(phi)))
    }
}
