//! The independent geometry and the brute-force ray oracle shared by `tests/oracle.rs` and
//! `tests/stress.rs` (both include this file as `mod common`). Nothing here is taken from the
//! library's intersection code: the geometry is implemented again from `interface.md` section 1
//! (with `errata.md`); `tests/oracle.rs`'s module documentation describes the oracle, its
//! march, bisection, classification and the comparison with the library's hits.

#![allow(
    dead_code,
    clippy::too_many_arguments,
    clippy::type_complexity,
    clippy::needless_range_loop
)]

use std::collections::{BTreeMap, BTreeSet};
use std::f64::consts::{PI, TAU};
use std::time::Instant;

use gencyl::{FiberSpec, Framing, GeneralizedCylinder, Hit, Method, Part, Ray, Section};
use glam::{DVec2, DVec3};

// ---------------------------------------------------------------------------------------------
// Tolerances (world distances are multiplied by the fiber's size).

/// Largest allowed `|t_lib - t_oracle| |d|` / size at a well-conditioned crossing. The oracle
/// locates crossings to 1e-13 size; a library that solves to near machine precision is at
/// ~1e-12 / |cos(incidence)| <= 1e-9 outside the grazing band, so 1e-7 (the brief's bound)
/// leaves two orders of magnitude and still catches any wrong root.
pub const T_TOL: f64 = 1e-7;
/// Largest allowed `|Gamma_oracle(u, v) - (o + t d)|` / size for a library hit: both sides are
/// evaluated in f64 from O(size) quantities (~1e-15 size); 1e-9 allows the library a converged
/// but not fully polished (u, v), and catches any wrong u or v (an error of 1e-8 in v moves the
/// point by ~1e-8 of a radius, i.e. above this on the fibers here).
pub const POINT_TOL: f64 = 1e-9;
/// Largest allowed |n_lib - n_fd|. The finite-difference normal (steps 1e-5, central) is good to
/// ~1e-9 (truncation h^2 ~ 1e-10 times derivative ratios, rounding 1e-16 / 1e-5 divided by a
/// radius ~0.03); 1e-6 is the brief's bound.
pub const NORMAL_TOL: f64 = 1e-6;
/// Grazing band: hits with |n . d_unit| below this are reported but not asserted on (the
/// crossing pair may be closer than the march step, and t is ill-conditioned as 1/|n.d|).
pub const GRAZE_COS: f64 = 1e-3;
/// The oracle bisects crossings down to this fraction of the fiber's size.
pub const BISECT_TOL: f64 = 1e-13;
/// A crossing lies on the side surface when its section point is within this (in section
/// units) of the section boundary, and on a cap when it is within `CAP_PLANE_TOL * size` of the
/// cap plane and inside the section up to `SIDE_TOL`. The crossing itself is within
/// ~1e-13 size (1e-11 section units for radii >= 0.01 size) of the true boundary, so both
/// leave ~1000x margin; a point satisfying both is on the rim (ambiguous part, banded).
pub const SIDE_TOL: f64 = 1e-8;
pub const CAP_PLANE_TOL: f64 = 1e-10;
/// Number of subintervals of [0, 1] with their own bounding boxes in the inside test.
pub const K_SUB: usize = 16;

/// The tolerances of one oracle, in world units where not said otherwise. [`Oracle::new`] sets
/// them from the constants above (`T_TOL`, `POINT_TOL` and `BISECT_TOL` times the fiber's size,
/// `NORMAL_TOL`); a test may tighten or widen them for its fibers (`tests/stress.rs` does, for
/// radii down to 1e-6 of the size and for fibers far from the origin).
#[derive(Clone, Copy, Debug)]
pub struct Tol {
    /// Largest `|t_lib - t_oracle| |d|` at a well-conditioned crossing.
    pub t: f64,
    /// Largest `|Gamma_oracle(u, v) - (o + t d)|` (and distance from the cap plane) of a hit.
    pub point: f64,
    /// Largest `|n_lib - n_fd|`.
    pub normal: f64,
    /// Crossings are bisected down to this length along the ray.
    pub bisect: f64,
}

// ---------------------------------------------------------------------------------------------
// A small deterministic generator (SplitMix64): failures are reproducible from the printed ray.

pub struct Rng(pub u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed.wrapping_mul(0x2545F4914F6CDD1D) ^ 0x9E3779B97F4A7C15)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E3779B97F4A7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
        z ^ (z >> 31)
    }
    pub fn f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.f64()
    }
    pub fn ball(&mut self) -> DVec3 {
        loop {
            let v = DVec3::new(
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
            );
            if v.length_squared() <= 1.0 {
                return v;
            }
        }
    }
    pub fn unit(&mut self) -> DVec3 {
        loop {
            let v = self.ball();
            let l = v.length_squared();
            if l > 1e-4 {
                return v / l.sqrt();
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Bernstein cubics.

pub fn bez(p: &[DVec3; 4], u: f64) -> DVec3 {
    let s = 1.0 - u;
    s * s * s * p[0] + 3.0 * u * s * s * p[1] + 3.0 * u * u * s * p[2] + u * u * u * p[3]
}
pub fn bez_d1(p: &[DVec3; 4], u: f64) -> DVec3 {
    let s = 1.0 - u;
    3.0 * (s * s * (p[1] - p[0]) + 2.0 * u * s * (p[2] - p[1]) + u * u * (p[3] - p[2]))
}
pub fn bez_d2(p: &[DVec3; 4], u: f64) -> DVec3 {
    6.0 * ((1.0 - u) * (p[2] - 2.0 * p[1] + p[0]) + u * (p[3] - 2.0 * p[2] + p[1]))
}
pub fn bez_d3(p: &[DVec3; 4]) -> DVec3 {
    6.0 * (p[3] - 3.0 * p[2] + 3.0 * p[1] - p[0])
}
pub fn bez2(p: &[DVec2; 4], s: f64) -> DVec2 {
    let r = 1.0 - s;
    r * r * r * p[0] + 3.0 * s * r * r * p[1] + 3.0 * s * s * r * p[2] + s * s * s * p[3]
}
pub fn bez2_d1(p: &[DVec2; 4], s: f64) -> DVec2 {
    let r = 1.0 - s;
    3.0 * (r * r * (p[1] - p[0]) + 2.0 * s * r * (p[2] - p[1]) + s * s * (p[3] - p[2]))
}
pub fn bez2_d2(p: &[DVec2; 4], s: f64) -> DVec2 {
    6.0 * ((1.0 - s) * (p[2] - 2.0 * p[1] + p[0]) + s * (p[3] - 2.0 * p[2] + p[1]))
}
pub fn cross2(a: DVec2, b: DVec2) -> f64 {
    a.x * b.y - a.y * b.x
}

/// Value and derivative of the polynomial `sum c[i] u^i` (Horner).
pub fn poly_eval(c: &[f64; 6], u: f64) -> (f64, f64) {
    let mut f = c[5];
    let mut df = 0.0;
    for i in (0..5).rev() {
        df = df * u + f;
        f = f * u + c[i];
    }
    (f, df)
}

/// The root of the polynomial in `[lo, hi]` where it changes sign (Newton safeguarded by
/// bisection, "rtsafe"), to full precision.
pub fn poly_root(c: &[f64; 6], lo: f64, hi: f64, flo: f64, fhi: f64) -> f64 {
    if flo == 0.0 {
        return lo;
    }
    if fhi == 0.0 {
        return hi;
    }
    let (mut xl, mut xh) = if flo < 0.0 { (lo, hi) } else { (hi, lo) };
    let mut x = 0.5 * (lo + hi);
    let mut dxold = (hi - lo).abs();
    let mut dx = dxold;
    let (mut f, mut df) = poly_eval(c, x);
    for _ in 0..200 {
        if f == 0.0 {
            return x;
        }
        if ((x - xh) * df - f) * ((x - xl) * df - f) > 0.0 || (2.0 * f).abs() > (dxold * df).abs() {
            dxold = dx;
            dx = 0.5 * (xh - xl);
            x = xl + dx;
            if xl == x {
                return x;
            }
        } else {
            dxold = dx;
            dx = f / df;
            let tmp = x;
            x -= dx;
            if tmp == x {
                return x;
            }
        }
        if dx.abs() < 1e-17 {
            return x;
        }
        (f, df) = poly_eval(c, x);
        if f < 0.0 {
            xl = x;
        } else {
            xh = x;
        }
    }
    x
}

// ---------------------------------------------------------------------------------------------
// Cross sections.

/// A y-monotone stretch `[s0, s1]` of a loop piece, for the crossing-number test.
pub struct Mono {
    pub piece: usize,
    pub s0: f64,
    pub s1: f64,
    pub y0: f64,
    pub y1: f64,
    pub xmin: f64,
    pub xmax: f64,
}

pub struct OLoop {
    pub pieces: Vec<[DVec2; 4]>,
    pub monos: Vec<Mono>,
    /// +1 counter-clockwise, -1 clockwise (sign of the area).
    pub orient: f64,
    /// max |control point|: the loop lies in the disc of this radius.
    pub radius: f64,
}

pub enum OSection {
    Circle,
    Loop(OLoop),
}

impl OLoop {
    pub fn new(points: &[DVec2]) -> OLoop {
        assert!(!points.is_empty() && points.len().is_multiple_of(3));
        let k = points.len() / 3;
        let pieces: Vec<[DVec2; 4]> = (0..k)
            .map(|i| {
                [
                    points[3 * i],
                    points[3 * i + 1],
                    points[3 * i + 2],
                    points[(3 * i + 3) % points.len()],
                ]
            })
            .collect();
        let mut monos = Vec::new();
        for (i, p) in pieces.iter().enumerate() {
            // y'(s)/3 = d0 (1-s)^2 + 2 d1 s (1-s) + d2 s^2 = a s^2 + b s + c.
            let (d0, d1, d2) = (p[1].y - p[0].y, p[2].y - p[1].y, p[3].y - p[2].y);
            let (a, b, c) = (d0 - 2.0 * d1 + d2, 2.0 * (d1 - d0), d0);
            let mut splits = vec![0.0];
            let mut roots = Vec::new();
            if a.abs() < 1e-300 {
                if b != 0.0 {
                    roots.push(-c / b);
                }
            } else {
                let disc = b * b - 4.0 * a * c;
                if disc >= 0.0 {
                    let q = -0.5 * (b + b.signum() * disc.sqrt());
                    roots.push(q / a);
                    if q != 0.0 {
                        roots.push(c / q);
                    }
                }
            }
            roots.retain(|&r| r > 0.0 && r < 1.0);
            roots.sort_by(f64::total_cmp);
            splits.extend(roots);
            splits.push(1.0);
            let xmin = p.iter().map(|q| q.x).fold(f64::INFINITY, f64::min);
            let xmax = p.iter().map(|q| q.x).fold(f64::NEG_INFINITY, f64::max);
            for w in splits.windows(2) {
                monos.push(Mono {
                    piece: i,
                    s0: w[0],
                    s1: w[1],
                    y0: bez2(p, w[0]).y,
                    y1: bez2(p, w[1]).y,
                    xmin,
                    xmax,
                });
            }
        }
        // Signed area by a fine trapezoid rule (only its sign is used).
        let n = 400;
        let mut area = 0.0;
        for p in &pieces {
            for j in 0..n {
                let (a, b) = (
                    bez2(p, j as f64 / n as f64),
                    bez2(p, (j + 1) as f64 / n as f64),
                );
                area += 0.5 * cross2(a, b);
            }
        }
        let radius = points.iter().map(|p| p.length()).fold(0.0, f64::max);
        OLoop {
            pieces,
            monos,
            orient: area.signum(),
            radius,
        }
    }

    /// Even-odd rule with the horizontal ray `p + (s, 0)`, `s > 0`, counted over y-monotone
    /// stretches with the half-open rule `(y0 > py) != (y1 > py)` (stretch ends are shared
    /// exactly, so a ray through a joint is counted once).
    pub fn contains(&self, p: DVec2) -> bool {
        let mut inside = false;
        for m in &self.monos {
            if (m.y0 > p.y) == (m.y1 > p.y) || p.x > m.xmax {
                continue;
            }
            if p.x < m.xmin {
                inside = !inside;
                continue;
            }
            let piece = &self.pieces[m.piece];
            let rising = m.y1 > m.y0;
            let (mut lo, mut hi) = (m.s0, m.s1);
            loop {
                let mid = 0.5 * (lo + hi);
                if mid <= lo || mid >= hi {
                    break;
                }
                if (bez2(piece, mid).y > p.y) == rising {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            if bez2(piece, 0.5 * (lo + hi)).x > p.x {
                inside = !inside;
            }
        }
        inside
    }

    /// The loop parameter `v` of the point nearest to `q`, and the distance.
    pub fn nearest(&self, q: DVec2) -> (f64, f64) {
        let k = self.pieces.len();
        let mut cands: Vec<(f64, usize, f64)> = Vec::new();
        for (i, p) in self.pieces.iter().enumerate() {
            for j in 0..=48 {
                let s = j as f64 / 48.0;
                cands.push(((bez2(p, s) - q).length(), i, s));
            }
        }
        cands.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut best = (f64::INFINITY, 0usize, 0.0);
        for &(_, i, s0) in cands.iter().take(6) {
            let p = &self.pieces[i];
            let mut s = s0;
            for _ in 0..40 {
                let e = bez2(p, s) - q;
                let d1 = bez2_d1(p, s);
                let g = e.dot(d1);
                let dg = d1.length_squared() + e.dot(bez2_d2(p, s));
                if dg <= 0.0 {
                    break;
                }
                let sn = (s - g / dg).clamp(0.0, 1.0);
                if sn == s {
                    break;
                }
                s = sn;
            }
            let d = (bez2(p, s) - q).length();
            if d < best.0 {
                best = (d, i, s);
            }
        }
        let v = (TAU * (best.1 as f64 + best.2) / k as f64).rem_euclid(TAU);
        (v, best.0)
    }
}

impl OSection {
    pub fn contains(&self, q: DVec2) -> bool {
        match self {
            OSection::Circle => q.length_squared() <= 1.0,
            OSection::Loop(l) => l.contains(q),
        }
    }
    pub fn radius(&self) -> f64 {
        match self {
            OSection::Circle => 1.0,
            OSection::Loop(l) => l.radius,
        }
    }
    pub fn orient(&self) -> f64 {
        match self {
            OSection::Circle => 1.0,
            OSection::Loop(l) => l.orient,
        }
    }
    /// The piece holding `v` (always 0 for the circle).
    pub fn piece_of(&self, v: f64) -> usize {
        match self {
            OSection::Circle => 0,
            OSection::Loop(l) => {
                let k = l.pieces.len();
                ((v.rem_euclid(TAU) * k as f64 / TAU).floor() as usize).min(k - 1)
            }
        }
    }
    /// `cs(v)`, evaluating the polynomial of `piece` (extended beyond its interval if `v` is
    /// outside it: used by finite differences so that they never straddle a joint).
    pub fn point_on(&self, v: f64, piece: usize) -> DVec2 {
        match self {
            OSection::Circle => DVec2::new(v.cos(), v.sin()),
            OSection::Loop(l) => {
                let k = l.pieces.len() as f64;
                let vv = if piece == 0 && v > PI { v - TAU } else { v };
                bez2(&l.pieces[piece], vv * k / TAU - piece as f64)
            }
        }
    }
    /// `(v, signed distance)` of the section point nearest to `q` (negative inside), in
    /// section units.
    pub fn boundary(&self, q: DVec2) -> (f64, f64) {
        match self {
            OSection::Circle => (q.y.atan2(q.x).rem_euclid(TAU), q.length() - 1.0),
            OSection::Loop(l) => {
                let (v, d) = l.nearest(q);
                (v, if l.contains(q) { -d } else { d })
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The oracle fiber.

pub struct Oracle {
    /// World position of P0; everything else is relative to it.
    pub origin: DVec3,
    pub p: [DVec3; 4],
    /// Fixed `(t, n, b)` of a straight segment.
    pub straight: Option<[DVec3; 3]>,
    pub major: [f64; 2],
    pub minor: [f64; 2],
    pub rot: [f64; 2],
    pub caps: bool,
    pub sec: OSection,
    /// `a'(u) = dc[0] + dc[1] u + dc[2] u^2` (power form, for the plane equation only).
    pub dc: [DVec3; 3],
    /// `a'(u) . a(u)` in power form.
    pub g: [f64; 6],
    /// Per subinterval `[k/K, (k+1)/K]`: a box holding every point within `rmax` of `a(u)`.
    pub boxes: Vec<(DVec3, DVec3)>,
    /// Plane-equation samples per subinterval (from a root-separation bound).
    pub m: usize,
    /// Diagonal of the solid's bounding box.
    pub size: f64,
    pub bbox: (DVec3, DVec3),
    /// March step (world units).
    pub h: f64,
    /// max curvature * rmax (must stay below 1/2: errata 5).
    pub beta: f64,
    /// Smallest of the radii A0, A1, B0, B1 (world units).
    pub thin: f64,
    /// Parameters where the Frenet frame jumps (see [`frenet_jumps`]).
    pub seams: Vec<f64>,
    /// The tolerances of the checks (see [`Tol`]).
    pub tol: Tol,
    /// The reference direction of a projection frame ([`Oracle::new_projected`]), if the fiber
    /// has one instead of the Frenet or straight-segment frame.
    pub projected: Option<DVec3>,
}

/// Parameters in (0, 1) where the Frenet binormal `a' x a'' / |a' x a''|` jumps: inflections of
/// a planar axis, where `a' x a''` vanishes and changes direction. The frame turns by half a
/// turn there, and with a section that is not point-symmetric the swept surface has a seam:
/// the solid's boundary includes the part of that normal plane covered by one limiting
/// section but not the other (interface.md 1: "the frame is the limit from either side").
/// Found on a grid and bisected; a jump is told from a fast continuous turn by the binormals
/// just either side being opposite rather than equal.
pub fn frenet_jumps(p: &[DVec3; 4]) -> Vec<f64> {
    let c = |u: f64| bez_d1(p, u).cross(bez_d2(p, u));
    // A grid offset by an irrational fraction of a cell: a jump does not fall on a grid point,
    // where `a' x a''` would be rounding noise of no definite direction.
    let n = 4000;
    let grid = |k: i32| ((k as f64 + 0.381_966_011_250_105_1) / n as f64).clamp(0.0, 1.0);
    let mut out = Vec::new();
    for k in -1..n {
        let (u0, u1) = (grid(k), grid(k + 1));
        let c0 = c(u0);
        if !(c0.dot(c(u1)) < 0.0) {
            continue;
        }
        let (mut a, mut b) = (u0, u1);
        loop {
            let m = 0.5 * (a + b);
            if m <= a || m >= b {
                break;
            }
            if c(m).dot(c0) > 0.0 {
                a = m;
            } else {
                b = m;
            }
        }
        // Compared 1e-10 either side (there a' x a'' is well above rounding noise at a simple
        // inflection, while a continuous turn would need to happen within 1e-10).
        let m = 0.5 * (a + b);
        if c(m - 1e-10).normalize().dot(c(m + 1e-10).normalize()) < -0.5 {
            out.push(m);
        }
    }
    out
}

pub fn lerp(a: [f64; 2], u: f64) -> f64 {
    a[0] + (a[1] - a[0]) * u
}

impl Oracle {
    pub fn new(spec: &FiberSpec, loop_points: Option<&[DVec2]>) -> Oracle {
        let origin = spec.bezier[0];
        let p = spec.bezier.map(|q| q - origin);
        let sec = match (&spec.section, loop_points) {
            (Section::Circle(_), None) => OSection::Circle,
            (Section::Loop(_), Some(pts)) => OSection::Loop(OLoop::new(pts)),
            _ => panic!("section and oracle loop points disagree"),
        };
        // Straight-segment rule (interface.md 1).
        let chord = p[3] - p[0];
        let len = chord.length();
        let dist = |q: DVec3| (q - p[0]).cross(chord).length() / len;
        let straight = if dist(p[1]) <= 1e-9 * len && dist(p[2]) <= 1e-9 * len {
            let t = chord / len;
            let hint = spec.normal_hint.unwrap_or_else(|| {
                let mut k = 0;
                for j in 1..3 {
                    if t[j].abs() < t[k].abs() {
                        k = j;
                    }
                }
                DVec3::AXES[k]
            });
            let n = (hint - hint.dot(t) * t).normalize();
            Some([t, n, t.cross(n)])
        } else {
            None
        };
        // Power form: a = c0 + c1 u + c2 u^2 + c3 u^3.
        let c = [
            p[0],
            3.0 * (p[1] - p[0]),
            3.0 * (p[2] - 2.0 * p[1] + p[0]),
            p[3] - 3.0 * p[2] + 3.0 * p[1] - p[0],
        ];
        let dc = [c[1], 2.0 * c[2], 3.0 * c[3]];
        let mut g = [0.0; 6];
        for (i, d) in dc.iter().enumerate() {
            for (j, cj) in c.iter().enumerate() {
                g[i + j] += d.dot(*cj);
            }
        }
        let rmax = spec
            .major_radius
            .iter()
            .chain(spec.minor_radius.iter())
            .fold(0.0f64, |m, &r| m.max(r))
            * sec.radius();
        let mut o = Oracle {
            origin,
            p,
            straight,
            major: spec.major_radius,
            minor: spec.minor_radius,
            rot: spec.rotation,
            caps: spec.caps,
            sec,
            dc,
            g,
            boxes: Vec::new(),
            m: 0,
            size: 0.0,
            bbox: (DVec3::ZERO, DVec3::ZERO),
            h: 0.0,
            beta: 0.0,
            thin: 0.0,
            seams: Vec::new(),
            tol: Tol {
                t: 0.0,
                point: 0.0,
                normal: NORMAL_TOL,
                bisect: 0.0,
            },
            projected: None,
        };
        // Sub-boxes: the Bezier restricted to [u0, u1] has control points a(u0),
        // a(u0) + (u1-u0)/3 a'(u0), a(u1) - (u1-u0)/3 a'(u1), a(u1); the arc lies in their hull.
        let pad = DVec3::splat(rmax * (1.0 + 1e-9) + 1e-12 * len);
        let mut diag_max = 0.0f64;
        for k in 0..K_SUB {
            let (u0, u1) = (k as f64 / K_SUB as f64, (k + 1) as f64 / K_SUB as f64);
            let q = [
                bez(&p, u0),
                bez(&p, u0) + (u1 - u0) / 3.0 * bez_d1(&p, u0),
                bez(&p, u1) - (u1 - u0) / 3.0 * bez_d1(&p, u1),
                bez(&p, u1),
            ];
            let lo = q.iter().fold(DVec3::INFINITY, |m, &x| m.min(x)) - pad;
            let hi = q.iter().fold(DVec3::NEG_INFINITY, |m, &x| m.max(x)) + pad;
            diag_max = diag_max.max((hi - lo).length());
            o.boxes.push((lo, hi));
        }
        let lo = p.iter().fold(DVec3::INFINITY, |m, &x| m.min(x)) - pad;
        let hi = p.iter().fold(DVec3::NEG_INFINITY, |m, &x| m.max(x)) + pad;
        o.bbox = (lo, hi);
        o.size = (hi - lo).length();
        o.tol.t = T_TOL * o.size;
        o.tol.point = POINT_TOL * o.size;
        o.tol.bisect = BISECT_TOL * o.size;
        // Curvature bound and root separation of the plane equation f(u) = a'.(x - a).
        // At a root where x lies in the section disc, f' = a''.(x-a) - |a'|^2
        // = |a'|^2 (kappa n.(x-a) - 1) <= -(1 - beta) |a'|^2. With |f''| <= M on the
        // subinterval (f'' = a'''.(x-a) - 3 a'.a'', |x - a| <= box diagonal), any other root is
        // at least (1 - beta) min|a'|^2 / M away, so sampling at half that spacing brackets
        // every relevant root alone.
        let (mut smin, mut smax, mut kmax) = (f64::INFINITY, 0.0f64, 0.0f64);
        for i in 0..=4000 {
            let u = i as f64 / 4000.0;
            let (d1, d2) = (bez_d1(&p, u), bez_d2(&p, u));
            smin = smin.min(d1.length());
            smax = smax.max(d1.length());
            kmax = kmax.max(d1.cross(d2).length() / d1.length().powi(3));
        }
        if o.straight.is_some() {
            kmax = 0.0;
        }
        o.beta = kmax * rmax;
        let a2max = bez_d2(&p, 0.0).length().max(bez_d2(&p, 1.0).length());
        let mbound = bez_d3(&p).length() * diag_max + 3.0 * smax * a2max;
        let sep = (1.0 - o.beta) * (0.9 * smin).powi(2) / mbound;
        o.m = ((2.0 / (K_SUB as f64 * sep)).ceil() as usize).max(2);
        let thin = spec
            .major_radius
            .iter()
            .chain(spec.minor_radius.iter())
            .fold(f64::INFINITY, |m, &r| m.min(r));
        o.thin = thin;
        o.h = 0.01 * thin;
        if o.straight.is_none() {
            o.seams = frenet_jumps(&o.p);
        }
        o
    }

    pub fn axis(&self, u: f64) -> DVec3 {
        bez(&self.p, u)
    }

    /// The same fiber with the projection frame of the reference `r` (the framing strands use):
    /// `t = a'/|a'|`, `n` the part of `r` normal to `t`, `n = (r - (r.t) t)/|r - (r.t) t|`, and
    /// `b = t x n`, on straight and curved axes alike; smooth (no seams) as long as `r` is
    /// never parallel to `t`.
    pub fn new_projected(spec: &FiberSpec, loop_points: Option<&[DVec2]>, r: DVec3) -> Oracle {
        let mut o = Oracle::new(spec, loop_points);
        o.straight = None;
        o.seams = Vec::new();
        o.projected = Some(r);
        o
    }

    /// `(t, n, b)` at `u`.
    pub fn frame(&self, u: f64) -> [DVec3; 3] {
        if let Some(r) = self.projected {
            let t = bez_d1(&self.p, u).normalize();
            let n = (r - r.dot(t) * t).normalize();
            return [t, n, t.cross(n)];
        }
        if let Some(f) = self.straight {
            return f;
        }
        let t = bez_d1(&self.p, u).normalize();
        let b = t.cross(bez_d2(&self.p, u)).normalize();
        [t, b.cross(t), b]
    }

    pub fn sweep(&self, u: f64, cs: DVec2) -> DVec2 {
        let (s, c) = lerp(self.rot, u).sin_cos();
        let q = DVec2::new(lerp(self.major, u) * cs.x, lerp(self.minor, u) * cs.y);
        DVec2::new(c * q.x - s * q.y, s * q.x + c * q.y)
    }

    pub fn sweep_inv(&self, u: f64, rho: DVec2) -> DVec2 {
        let (s, c) = lerp(self.rot, u).sin_cos();
        let r = DVec2::new(c * rho.x + s * rho.y, -s * rho.x + c * rho.y);
        DVec2::new(r.x / lerp(self.major, u), r.y / lerp(self.minor, u))
    }

    /// `Gamma(u, v)` relative to `origin`, the section evaluated on `piece`'s polynomial.
    pub fn gamma_on(&self, u: f64, v: f64, piece: usize) -> DVec3 {
        let [_, n, b] = self.frame(u);
        let c = self.sweep(u, self.sec.point_on(v, piece));
        self.axis(u) + c.x * n + c.y * b
    }

    /// `Gamma(u, v) - a(u)`: the section point's offset from the axis, on `piece`'s polynomial.
    pub fn offset_on(&self, u: f64, v: f64, piece: usize) -> DVec3 {
        let [_, n, b] = self.frame(u);
        let c = self.sweep(u, self.sec.point_on(v, piece));
        c.x * n + c.y * b
    }

    pub fn gamma(&self, u: f64, v: f64) -> DVec3 {
        self.gamma_on(u, v.rem_euclid(TAU), self.sec.piece_of(v))
    }

    /// Outward unit normal `orient * (dGamma/dv x dGamma/du)` by central differences.
    /// `dGamma/dv` is differenced on the offset from the axis (`a(u)` does not depend on `v`):
    /// differencing `Gamma` itself would lose `ulp(|Gamma|) / (h r)` to rounding, 1e-5 rad at a
    /// radius of 1e-6 of the coordinates.
    pub fn normal_fd(&self, u: f64, v: f64) -> DVec3 {
        let v = v.rem_euclid(TAU);
        let piece = self.sec.piece_of(v);
        let h = 1e-5;
        let gu = (self.gamma_on(u + h, v, piece) - self.gamma_on(u - h, v, piece)) / (2.0 * h);
        let gv = (self.offset_on(u, v + h, piece) - self.offset_on(u, v - h, piece)) / (2.0 * h);
        (self.sec.orient() * gv.cross(gu)).normalize()
    }

    /// The section point of `x` in the plane at `u`, and `t . (x - a(u))`.
    pub fn section_point(&self, u: f64, x: DVec3) -> (DVec2, f64) {
        let e = x - self.axis(u);
        let [t, n, b] = self.frame(u);
        (self.sweep_inv(u, DVec2::new(n.dot(e), b.dot(e))), t.dot(e))
    }

    /// Every relevant root of `a'(u).(x - a(u)) = 0` in [0, 1] (those within `rmax` of the
    /// axis are all found; others may be), calling `visit(u)`; stops when it returns true.
    pub fn plane_roots(&self, x: DVec3, mut visit: impl FnMut(f64) -> bool) -> bool {
        let mut coef = [0.0; 6];
        for i in 0..6 {
            coef[i] = -self.g[i];
        }
        for i in 0..3 {
            coef[i] += self.dc[i].dot(x);
        }
        let n = K_SUB * self.m;
        for (k, (lo, hi)) in self.boxes.iter().enumerate() {
            if x.cmplt(*lo).any() || x.cmpgt(*hi).any() {
                continue;
            }
            // The derivative, for pairs of roots within one cell (a folded solid's normal
            // planes are born in pairs at their envelope): where it changes sign in a cell
            // whose ends agree, the extremum between may still cross zero.
            let dcoef = [
                coef[1],
                2.0 * coef[2],
                3.0 * coef[3],
                4.0 * coef[4],
                5.0 * coef[5],
                0.0,
            ];
            let mut u0 = (k * self.m) as f64 / n as f64;
            let (mut f0, mut d0) = poly_eval(&coef, u0);
            for j in 1..=self.m {
                let u1 = (k * self.m + j) as f64 / n as f64;
                let (f1, d1) = poly_eval(&coef, u1);
                if (f0 <= 0.0 && f1 >= 0.0) || (f0 >= 0.0 && f1 <= 0.0) {
                    let u = poly_root(&coef, u0, u1, f0, f1);
                    if visit(u) {
                        return true;
                    }
                } else if (d0 < 0.0) != (d1 < 0.0) {
                    let uc = poly_root(&dcoef, u0, u1, d0, d1);
                    let fc = poly_eval(&coef, uc).0;
                    if (fc < 0.0) != (f0 < 0.0) {
                        for (a, b, fa, fb) in [(u0, uc, f0, fc), (uc, u1, fc, f1)] {
                            if visit(poly_root(&coef, a, b, fa, fb)) {
                                return true;
                            }
                        }
                    }
                }
                (u0, f0, d0) = (u1, f1, d1);
            }
        }
        false
    }

    /// A double root `u` of the plane equation `a'(u).(x - a(u)) = 0` whose section holds `x`:
    /// `x` lies on the envelope of the normal planes there (within `1e-9` of the size in the
    /// equation's value per unit speed), in the section. The critical points come from the
    /// derivative's sign changes on a fine grid.
    pub fn envelope_at(&self, x: DVec3) -> Option<f64> {
        let f = |u: f64| bez_d1(&self.p, u).dot(x - bez(&self.p, u));
        let df = |u: f64| {
            bez_d2(&self.p, u).dot(x - bez(&self.p, u)) - bez_d1(&self.p, u).length_squared()
        };
        let n = 4000;
        let mut u0 = 0.0;
        let mut d0 = df(u0);
        for k in 1..=n {
            let u1 = k as f64 / n as f64;
            let d1 = df(u1);
            if (d0 < 0.0) != (d1 < 0.0) {
                let (mut a, mut b, mut da) = (u0, u1, d0);
                for _ in 0..100 {
                    let m = 0.5 * (a + b);
                    if m <= a || m >= b {
                        break;
                    }
                    if (df(m) < 0.0) == (da < 0.0) {
                        (a, da) = (m, df(m));
                    } else {
                        b = m;
                    }
                }
                let uc = 0.5 * (a + b);
                let speed = bez_d1(&self.p, uc).length();
                if f(uc).abs() <= 1e-9 * speed * self.size
                    && self.sec.contains(self.section_point(uc, x).0)
                {
                    return Some(uc);
                }
            }
            (u0, d0) = (u1, d1);
        }
        None
    }

    /// Point membership in the solid (`x` relative to `origin`).
    pub fn inside(&self, x: DVec3) -> bool {
        self.plane_roots(x, |u| self.sec.contains(self.section_point(u, x).0))
    }

    /// The same by brute force: 20000 uniform samples of the plane equation from Bernstein
    /// form, bisection of every sign change (a second method, for self-checks).
    pub fn inside_brute(&self, x: DVec3) -> bool {
        let f = |u: f64| bez_d1(&self.p, u).dot(x - bez(&self.p, u));
        let n = 20000;
        let mut u0 = 0.0;
        let mut f0 = f(0.0);
        for j in 1..=n {
            let u1 = j as f64 / n as f64;
            let f1 = f(u1);
            if (f0 <= 0.0) != (f1 <= 0.0) || f0 == 0.0 {
                let (mut a, mut b, fa) = (u0, u1, f0);
                for _ in 0..80 {
                    let m = 0.5 * (a + b);
                    if (f(m) <= 0.0) == (fa <= 0.0) {
                        a = m;
                    } else {
                        b = m;
                    }
                }
                if self.sec.contains(self.section_point(0.5 * (a + b), x).0) {
                    return true;
                }
            }
            (u0, f0) = (u1, f1);
        }
        false
    }

    pub fn world(&self, x: DVec3) -> DVec3 {
        x + self.origin
    }

    pub fn local(&self, x: DVec3) -> DVec3 {
        x - self.origin
    }

    pub fn rmax_at(&self, u: f64) -> f64 {
        lerp(self.major, u).max(lerp(self.minor, u)) * self.sec.radius()
    }
}

// ---------------------------------------------------------------------------------------------
// The ray oracle.

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum OPart {
    Side,
    StartCap,
    EndCap,
    /// On the rim: side and cap both within tolerance.
    Rim,
    /// On the seam at a jump of the frame ([`frenet_jumps`]): a boundary the library does not
    /// report (it is neither side surface nor cap), counted and banded.
    Seam,
}

#[derive(Clone, Debug)]
pub struct Crossing {
    pub t: f64,
    pub part: OPart,
    pub u: f64,
    pub v: f64,
    pub normal: DVec3,
    /// Whether the ray enters the solid here (printed in failure messages).
    #[allow(dead_code)]
    pub entering: bool,
    /// Why this crossing is not asserted on, if it is not.
    pub band: Option<&'static str>,
}

pub struct RayCtx {
    pub o: DVec3, // local origin
    pub d: DVec3,
    pub dl: f64,
    pub tmin: f64,
    pub tmax: f64,
}

impl RayCtx {
    pub fn at(&self, t: f64) -> DVec3 {
        self.o + t * self.d
    }
}

/// The `t` range of the ray inside the box `(lo, hi)`, clipped to `(t0, t1)`.
pub fn slab(
    r: &RayCtx,
    (mut t0, mut t1): (f64, f64),
    (blo, bhi): (DVec3, DVec3),
) -> Option<(f64, f64)> {
    for k in 0..3 {
        let (lo, hi) = (blo[k], bhi[k]);
        if r.d[k] == 0.0 {
            if r.o[k] < lo || r.o[k] > hi {
                return None;
            }
        } else {
            let (a, b) = ((lo - r.o[k]) / r.d[k], (hi - r.o[k]) / r.d[k]);
            t0 = t0.max(a.min(b));
            t1 = t1.min(a.max(b));
        }
    }
    (t0 < t1).then_some((t0, t1))
}

impl Oracle {
    pub fn ray_ctx(&self, ray: &Ray, tmin: f64, tmax: f64) -> RayCtx {
        RayCtx {
            o: self.local(ray.origin),
            d: ray.dir,
            dl: ray.dir.length(),
            tmin,
            tmax,
        }
    }

    /// The `t` range of the ray inside the solid's bounding box, clipped to (tmin, tmax).
    pub fn clip(&self, r: &RayCtx) -> Option<(f64, f64)> {
        slab(r, (r.tmin, r.tmax), self.bbox)
    }

    /// The `t` ranges of the ray inside the sub-boxes of the inside test (outside them every
    /// point is outside the solid), clipped to `(lo, hi)`, merged where they overlap.
    pub fn box_spans(&self, r: &RayCtx, lo: f64, hi: f64) -> Vec<(f64, f64)> {
        let mut spans: Vec<(f64, f64)> = self
            .boxes
            .iter()
            .filter_map(|&b| slab(r, (lo, hi), b))
            .collect();
        spans.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut out: Vec<(f64, f64)> = Vec::new();
        for (a, b) in spans {
            match out.last_mut() {
                Some(last) if a <= last.1 => last.1 = last.1.max(b),
                _ => out.push((a, b)),
            }
        }
        out
    }

    /// Bisects the inside/outside change in `[ta, tb]` (`sa` the state at `ta`).
    pub fn refine(&self, r: &RayCtx, mut ta: f64, mut tb: f64, sa: bool) -> f64 {
        while (tb - ta) * r.dl > self.tol.bisect {
            let tm = 0.5 * (ta + tb);
            if tm <= ta || tm >= tb {
                break;
            }
            if self.inside(r.at(tm)) == sa {
                ta = tm;
            } else {
                tb = tm;
            }
        }
        0.5 * (ta + tb)
    }

    /// Classifies the crossing at `t` geometrically.
    pub fn classify(&self, r: &RayCtx, t: f64, entering: bool) -> Crossing {
        let x = r.at(t);
        // Side: the section disc whose boundary passes closest to x.
        let mut side: Option<(f64, f64, f64)> = None; // (|delta|, u, v)
        self.plane_roots(x, |u| {
            let (q, _) = self.section_point(u, x);
            let (v, delta) = self.sec.boundary(q);
            if side.is_none_or(|s| delta.abs() < s.0) {
                side = Some((delta.abs(), u, v));
            }
            false
        });
        let side_ok = side.is_some_and(|s| s.0 <= SIDE_TOL);
        let cap = |u: f64| {
            let (q, pd) = self.section_point(u, x);
            let (v, delta) = self.sec.boundary(q);
            (
                pd.abs() <= CAP_PLANE_TOL * self.size && delta <= SIDE_TOL,
                v,
            )
        };
        let (c0, v0) = cap(0.0);
        let (c1, v1) = cap(1.0);
        // In the normal plane at a jump of the frame (where neither side nor cap holds it).
        let seam_at = if side_ok || c0 || c1 {
            None
        } else {
            let mut on_seam = None;
            self.plane_roots(x, |u| {
                on_seam = self.seams.iter().copied().find(|s| (u - s).abs() <= 1e-9);
                on_seam.is_some()
            });
            // Or on the envelope of the normal planes, where a folded solid's planes through a
            // point are born in pairs (a double root of the plane equation) inside the section.
            on_seam.or_else(|| self.envelope_at(x))
        };
        let (part, u, v, mut normal) = match (side_ok, c0, c1) {
            (true, false, false) => {
                let (_, u, v) = side.unwrap();
                (OPart::Side, u, v, self.normal_fd(u, v))
            }
            (false, true, false) => (OPart::StartCap, 0.0, v0, -self.frame(0.0)[0]),
            (false, false, true) => (OPart::EndCap, 1.0, v1, self.frame(1.0)[0]),
            (true, _, _) => {
                let (_, u, v) = side.unwrap();
                (OPart::Rim, u, v, self.normal_fd(u, v))
            }
            // In the normal plane at a jump of the frame: the seam, with normal +-t there,
            // pointing out (against d where the ray enters).
            _ if seam_at.is_some() => {
                let s = seam_at.unwrap_or(f64::NAN);
                let ts = bez_d1(&self.p, s).normalize();
                let along = if ts.dot(r.d) > 0.0 { ts } else { -ts };
                return Crossing {
                    t,
                    part: OPart::Seam,
                    u: s,
                    v: f64::NAN,
                    normal: if entering { -along } else { along },
                    entering,
                    band: None,
                };
            }
            // Neither side nor cap within tolerance: an oracle failure, reported by the caller.
            _ => {
                return Crossing {
                    t,
                    part: OPart::Rim,
                    u: f64::NAN,
                    v: f64::NAN,
                    normal: DVec3::NAN,
                    entering,
                    band: Some("ORACLE-UNCLASSIFIED"),
                };
            }
        };
        let cosi = normal.dot(r.d) / r.dl;
        let mut band = None;
        if part == OPart::Rim {
            band = Some("rim");
        } else if cosi.abs() < GRAZE_COS {
            band = Some("grazing");
        } else if (cosi < 0.0) != entering && self.beta >= 1.0 {
            // A folded solid's boundary can lie on a sheet of the swept surface that is turned
            // inside out beyond a fold edge: its outward normal is the opposite one.
            normal = -normal;
        } else if (cosi < 0.0) != entering {
            // The oracle's own normal disagrees with its inside test: an oracle bug, reported.
            band = Some("ORACLE-INCONSISTENT");
        }
        Crossing {
            t,
            part,
            u,
            v,
            normal,
            entering,
            band,
        }
    }

    /// All crossings of the solid's boundary with `t` in (tmin, tmax), and the cap crossings
    /// dropped because the fiber has no caps.
    pub fn crossings_in(&self, r: &RayCtx, t0: f64, t1: f64, steps: usize) -> Vec<Crossing> {
        let mut out = Vec::new();
        let mut ta = t0;
        let mut sa = self.inside(r.at(ta));
        for i in 1..=steps {
            let tb = if i == steps {
                t1
            } else {
                t0 + (t1 - t0) * i as f64 / steps as f64
            };
            let sb = self.inside(r.at(tb));
            if sb != sa {
                let t = self.refine(r, ta, tb, sa);
                out.push(self.classify(r, t, sb));
            }
            (ta, sa) = (tb, sb);
        }
        out
    }

    pub fn crossings(&self, r: &RayCtx) -> (Vec<Crossing>, Vec<Crossing>) {
        let Some((t0, t1)) = self.clip(r) else {
            return (Vec::new(), Vec::new());
        };
        let steps = (((t1 - t0) * r.dl / self.h).ceil() as usize).max(1);
        let all = self.crossings_in(r, t0, t1, steps);
        self.finish_crossings(r, all)
    }

    /// The crossings of [`Self::crossings`] with `t` in `(lo, hi)`, the march restricted to the
    /// sub-boxes (the same march step, so the same crossings, at a fraction of the cost for a
    /// thin or curved fiber); `None` if that takes more than `max_steps` steps.
    pub fn crossings_boxed(
        &self,
        r: &RayCtx,
        lo: f64,
        hi: f64,
        max_steps: usize,
    ) -> Option<(Vec<Crossing>, Vec<Crossing>)> {
        let spans = self.box_spans(r, lo.max(r.tmin), hi.min(r.tmax));
        let steps: Vec<usize> = spans
            .iter()
            .map(|&(a, b)| (((b - a) * r.dl / self.h).ceil() as usize).max(1))
            .collect();
        if steps.iter().sum::<usize>() > max_steps {
            return None;
        }
        let mut all = Vec::new();
        for (&(a, b), &n) in spans.iter().zip(&steps) {
            all.extend(self.crossings_in(r, a, b, n));
        }
        Some(self.finish_crossings(r, all))
    }

    /// Bands crossing pairs and crossings at tmin / tmax, and splits off the cap crossings of a
    /// fiber without caps.
    pub fn finish_crossings(
        &self,
        r: &RayCtx,
        all: Vec<Crossing>,
    ) -> (Vec<Crossing>, Vec<Crossing>) {
        let mut all = self.mark_pairs(r, all);
        for c in &mut all {
            if c.band.is_none()
                && ((c.t - r.tmin) * r.dl < 1e-9 * self.size
                    || (r.tmax - c.t) * r.dl < 1e-9 * self.size)
            {
                c.band = Some("at tmin/tmax");
            }
        }
        if self.caps {
            (all, Vec::new())
        } else {
            all.into_iter()
                .partition(|c| matches!(c.part, OPart::Side | OPart::Rim | OPart::Seam))
        }
    }

    /// Crossings closer than two march steps to a neighbour may hide a pair the march skipped.
    pub fn mark_pairs(&self, r: &RayCtx, mut c: Vec<Crossing>) -> Vec<Crossing> {
        let lim = 2.0 * self.h / r.dl;
        for i in 0..c.len() {
            let close = (i > 0 && c[i].t - c[i - 1].t < lim)
                || (i + 1 < c.len() && c[i + 1].t - c[i].t < lim);
            if close && c[i].band.is_none() {
                c[i].band = Some("close pair");
            }
        }
        c
    }

    /// A fine march (1/256 of a step) around `t`, to resolve crossing pairs the coarse march
    /// cannot see.
    pub fn fine_crossings(&self, r: &RayCtx, t: f64) -> Vec<Crossing> {
        let w = 2.0 * self.h / r.dl;
        let (t0, t1) = ((t - w).max(r.tmin), (t + w).min(r.tmax));
        if t0 >= t1 {
            return Vec::new();
        }
        self.crossings_in(r, t0, t1, 1024)
    }

    /// Second method for a crossing: Newton on `Gamma(u, v) = o + t d` in `(u, v, t)` from the
    /// crossing, with a finite-difference Jacobian. Returns the converged `(u, v, t, residual)`.
    pub fn newton(&self, r: &RayCtx, c: &Crossing) -> (f64, f64, f64, f64) {
        let (mut u, mut v, mut t) = (c.u, c.v, c.t);
        let h = 1e-7;
        let mut res = f64::INFINITY;
        for _ in 0..30 {
            let f = self.gamma(u, v) - r.at(t);
            res = f.length();
            let gu = (self.gamma(u + h, v) - self.gamma(u - h, v)) / (2.0 * h);
            let gv = (self.gamma(u, v + h) - self.gamma(u, v - h)) / (2.0 * h);
            let cols = [gu, gv, -r.d];
            let det = cols[0].dot(cols[1].cross(cols[2]));
            if det == 0.0 {
                break;
            }
            let du = f.dot(cols[1].cross(cols[2])) / det;
            let dv = cols[0].dot(f.cross(cols[2])) / det;
            let dt = cols[0].dot(cols[1].cross(f)) / det;
            u -= du;
            v -= dv;
            t -= dt;
        }
        (u, v.rem_euclid(TAU), t, res)
    }
}

// ---------------------------------------------------------------------------------------------
// Comparison with the library.

#[derive(Default)]
pub struct Stats {
    pub rays: usize,
    pub crossings: usize,
    pub hits: usize,
    pub matched: usize,
    pub misses: usize,
    pub false_hits: usize,
    /// Hits matched to a crossing (within a quarter step) but more than T_TOL off: counted in
    /// both `misses` and `false_hits`, as no hit lies within T_TOL of the crossing.
    pub inaccurate: usize,
    pub band: usize,
    /// Oracle crossings on a seam (in `band` too).
    pub seam: usize,
    pub fine_resolved: usize,
    pub part_mismatch: usize,
    pub first_mismatch: usize,
    pub max_t_err: f64,
    pub max_normal_err: f64,
    pub max_point_err: f64,
    /// The same in units of the smallest radius.
    pub max_point_err_thin: f64,
    pub max_cap_normal_err: f64,
    pub outward_checked: usize,
    pub failures: usize,
    pub messages: Vec<String>,
    /// Failures by kind.
    pub kinds: BTreeMap<&'static str, usize>,
    /// `(ray number, t bits)` of the hits flagged by [`Stats::flag_hit`].
    pub bad_hits: BTreeSet<(usize, u64)>,
}

impl Stats {
    /// A failure of the given kind (counted per kind in `kinds`).
    pub fn fail_as(&mut self, kind: &'static str, msg: String) {
        *self.kinds.entry(kind).or_default() += 1;
        self.fail(msg);
    }

    /// Marks the hit at `t` of the current ray (number `rays`) as not a true crossing (off the
    /// surface, or with no crossing of the oracle's): `bad_hits` counts each hit once.
    pub fn flag_hit(&mut self, t: f64) {
        self.bad_hits.insert((self.rays, t.to_bits()));
    }

    pub fn fail(&mut self, msg: String) {
        self.failures += 1;
        if (self.messages.len() as f64) < scale_from_env("ORACLE_MAX_MESSAGES").max(12.0) {
            self.messages.push(msg);
        }
    }
}

pub struct Case {
    pub name: &'static str,
    pub spec: FiberSpec,
    pub loop_points: Option<Vec<DVec2>>,
}

pub fn part_of(p: Part) -> OPart {
    match p {
        Part::Side => OPart::Side,
        Part::StartCap => OPart::StartCap,
        Part::EndCap => OPart::EndCap,
        Part::Seam => OPart::Seam,
    }
}

/// Checks one library hit on its own (point 4 of the brief).
pub fn check_hit(o: &Oracle, r: &RayCtx, h: &Hit, st: &mut Stats, ctx: &dyn Fn() -> String) {
    if ![h.t, h.u, h.v].iter().all(|x| x.is_finite())
        || !h.point.is_finite()
        || !h.normal.is_finite()
    {
        st.flag_hit(h.t);
        st.fail_as("NaN", format!("non-finite hit\n{}\nhit {h:?}", ctx()));
        return;
    }
    let x = r.at(h.t);
    let xw = o.world(x);
    let scale = o.size.max(o.origin.length()).max(xw.length());
    if (h.point - xw).length() > 1e-12 * scale.max(h.t.abs() * r.dl) {
        st.fail_as(
            "hit.point",
            format!(
                "hit.point {:?} != o + t d = {:?}\n{}\nhit {h:?}",
                h.point,
                xw,
                ctx()
            ),
        );
    }
    if !(h.t > r.tmin && h.t < r.tmax) {
        st.fail_as(
            if !(h.t > r.tmin) {
                "behind origin"
            } else {
                "beyond tmax"
            },
            format!("hit t {} outside (tmin, tmax)\n{}\nhit {h:?}", h.t, ctx()),
        );
    }
    if !(0.0..TAU).contains(&h.v) || !(0.0..=1.0).contains(&h.u) {
        st.fail_as(
            "u, v range",
            format!(
                "hit (u, v) = ({}, {}) out of range\n{}\nhit {h:?}",
                h.u,
                h.v,
                ctx()
            ),
        );
    }
    // Unit normal: computed as n / |n| in f64, so within a few ulps.
    if (h.normal.length() - 1.0).abs() > 1e-12 {
        st.fail_as(
            "normal not unit",
            format!(
                "normal not unit: |n| = {}\n{}\nhit {h:?}",
                h.normal.length(),
                ctx()
            ),
        );
    }
    // Displacement for the outward test: far above the hit's position error (1e-9 size) and far
    // below the profile's radii of curvature (>= 0.1 of the smallest radius here). For radii
    // below ~1e-4 size a position error within tolerance can exceed 1e-5 radii: then 4 times
    // the error.
    let eps = 1e-5 * o.thin;
    match h.part {
        Part::Side => {
            let g = o.gamma(h.u, h.v);
            let err = (g - x).length() / o.size;
            st.max_point_err = st.max_point_err.max(err);
            st.max_point_err_thin = st.max_point_err_thin.max(err * o.size / o.thin);
            let eps = eps.max(4.0 * err * o.size);
            if err * o.size > o.tol.point {
                st.flag_hit(h.t);
                st.fail_as("off surface", format!(
                    "side hit: |Gamma(u, v) - (o + t d)| = {:.3e} size (Gamma = {:?}, o + t d = {:?})\n{}\nhit {h:?}",
                    err,
                    o.world(g),
                    xw,
                    ctx()
                ));
            }
            let mut nf = o.normal_fd(h.u, h.v);
            // On a sheet turned inside out beyond a fold edge the outward normal is the other one.
            if o.beta >= 1.0 && o.inside(x + 4.0 * eps * nf) && !o.inside(x - 4.0 * eps * nf) {
                nf = -nf;
            }
            let nerr = (nf - h.normal).length();
            st.max_normal_err = st.max_normal_err.max(nerr);
            if nerr > o.tol.normal {
                st.fail_as("normal error", format!(
                    "side hit: normal {:?} != finite-difference normal {:?} (|diff| {:.3e})\n{}\nhit {h:?}",
                    h.normal,
                    nf,
                    nerr,
                    ctx()
                ));
            }
            // Near the ends x - eps n may leave the solid through the cap plane: skip there; and
            // off the surface (failed above) the test would say nothing about the normal.
            if h.u > 1e-4 && h.u < 1.0 - 1e-4 && err * o.size <= o.tol.point {
                st.outward_checked += 1;
                let (a, b) = (o.inside(x - eps * h.normal), o.inside(x + eps * h.normal));
                if !a || b {
                    st.fail_as("normal not outward", format!(
                        "side hit: normal not outward: inside(x - eps n) = {a}, inside(x + eps n) = {b} (eps {eps:.1e})\n{}\nhit {h:?}",
                        ctx()
                    ));
                }
            }
        }
        Part::Seam => {
            // In the normal plane at one of the oracle's seams, or at a double root of the
            // plane equation (the envelope of the normal planes through a folded solid; the
            // double root's u is conditioned like a square root), with normal +-t there.
            let at = o
                .seams
                .iter()
                .copied()
                .find(|&s| (h.u - s).abs() <= 1e-9)
                .or_else(|| o.envelope_at(x).filter(|uc| (uc - h.u).abs() <= 1e-5));
            let Some(s) = at else {
                st.flag_hit(h.t);
                st.fail_as(
                    "seam off a jump",
                    format!("seam hit at u = {} with no jump of the frame there (jumps {:?}) and off the normal planes' envelope\n{}\nhit {h:?}", h.u, o.seams, ctx()),
                );
                return;
            };
            let ts = bez_d1(&o.p, s).normalize();
            let pd = ts.dot(x - o.axis(s));
            st.max_point_err = st.max_point_err.max(pd.abs() / o.size);
            if pd.abs() > o.tol.point {
                st.flag_hit(h.t);
                st.fail_as(
                    "off seam",
                    format!("seam hit {:.3e} size off the normal plane at the jump u = {s}\n{}\nhit {h:?}", pd.abs() / o.size, ctx()),
                );
            }
            let nerr = (h.normal - ts).length().min((h.normal + ts).length());
            if nerr > 1e-9 {
                st.fail_as(
                    "seam normal",
                    format!(
                        "seam hit: normal {:?} is not +-t = {ts:?}\n{}\nhit {h:?}",
                        h.normal,
                        ctx()
                    ),
                );
            }
            let eps = eps.max(4.0 * pd.abs());
            let (a, b) = (o.inside(x - eps * h.normal), o.inside(x + eps * h.normal));
            st.outward_checked += 1;
            if !a || b {
                st.fail_as(
                    "seam normal not outward",
                    format!("seam hit: normal not outward: inside(x - eps n) = {a}, inside(x + eps n) = {b}\n{}\nhit {h:?}", ctx()),
                );
            }
        }
        Part::StartCap | Part::EndCap => {
            let uc = if h.part == Part::StartCap { 0.0 } else { 1.0 };
            let t = o.frame(uc)[0];
            let nexp = if uc == 0.0 { -t } else { t };
            let (q, pd) = o.section_point(uc, x);
            let (_, delta) = o.sec.boundary(q);
            st.max_point_err = st.max_point_err.max(pd.abs() / o.size);
            let off_cap = h.u != uc || pd.abs() > o.tol.point || delta > o.tol.point / o.thin;
            let eps = eps.max(4.0 * pd.abs());
            if off_cap {
                st.flag_hit(h.t);
                st.fail_as("off cap", format!(
                    "cap hit: u = {} (expected {uc}), distance from cap plane {:.3e} size, section boundary distance {:.3e}\n{}\nhit {h:?}",
                    h.u,
                    pd.abs() / o.size,
                    delta,
                    ctx()
                ));
            }
            if !o.caps {
                st.flag_hit(h.t);
                st.fail_as(
                    "cap without caps",
                    format!("cap hit on a fiber without caps\n{}\nhit {h:?}", ctx()),
                );
            }
            // The cap normal is +-t, exact up to rounding of one normalisation.
            let nerr = (h.normal - nexp).length();
            st.max_cap_normal_err = st.max_cap_normal_err.max(nerr);
            if nerr > 1e-12 {
                st.fail_as(
                    "cap normal",
                    format!(
                        "cap hit: normal {:?}, expected {:?}\n{}\nhit {h:?}",
                        h.normal,
                        nexp,
                        ctx()
                    ),
                );
            }
            if delta < -1e-4 && !off_cap {
                st.outward_checked += 1;
                let (a, b) = (o.inside(x - eps * h.normal), o.inside(x + eps * h.normal));
                if !a || b {
                    st.fail_as("cap normal not outward", format!(
                        "cap hit: normal not outward: inside(x - eps n) = {a}, inside(x + eps n) = {b}\n{}\nhit {h:?}",
                        ctx()
                    ));
                }
            }
        }
    }
}

/// Compares the library's hits of one ray with the oracle's crossings.
/// `oracle` is `o.crossings()` of this ray (computed once and shared by the methods).
pub fn compare_ray(
    o: &Oracle,
    case: &Case,
    ray: &Ray,
    tmin: f64,
    tmax: f64,
    hits: &[Hit],
    method: Method,
    oracle: &(Vec<Crossing>, Vec<Crossing>),
    st: &mut Stats,
) {
    let r = o.ray_ctx(ray, tmin, tmax);
    let ctx = || {
        format!(
            "fiber {}: {:?}\nray {:?} tmin {:?} tmax {:?} method {:?}",
            case.name, case.spec, ray, tmin, tmax, method
        )
    };
    st.rays += 1;
    st.hits += hits.len();
    if hits.windows(2).any(|w| !(w[0].t <= w[1].t)) {
        st.fail_as(
            "unsorted",
            format!(
                "hits not sorted by t: {:?}\n{}",
                hits.iter().map(|h| h.t).collect::<Vec<_>>(),
                ctx()
            ),
        );
    }
    for h in hits {
        check_hit(o, &r, h, st, &ctx);
    }
    let (mut cross, dropped) = (oracle.0.clone(), &oracle.1);
    st.crossings += cross.len();
    st.seam += cross.iter().filter(|c| c.part == OPart::Seam).count();
    for c in &cross {
        if matches!(c.band, Some("ORACLE-INCONSISTENT" | "ORACLE-UNCLASSIFIED")) {
            st.fail_as(
                "oracle inconsistency",
                format!(
                    "ORACLE self-inconsistency (normal vs inside test) at crossing {c:?}\n{}",
                    ctx()
                ),
            );
        }
    }
    let match_tol = 0.25 * o.h / r.dl;
    let mut used = vec![false; hits.len()];
    let mut matched: Vec<Option<usize>> = vec![None; cross.len()];
    for (ci, c) in cross.iter().enumerate() {
        let best = (0..hits.len())
            .filter(|&i| !used[i] && (hits[i].t - c.t).abs() <= match_tol)
            .min_by(|&a, &b| (hits[a].t - c.t).abs().total_cmp(&(hits[b].t - c.t).abs()));
        if let Some(i) = best {
            used[i] = true;
            matched[ci] = Some(i);
        }
    }
    // Unmatched library hits: look closer before calling them false.
    for (i, h) in hits.iter().enumerate() {
        if used[i] {
            continue;
        }
        let fine = o.fine_crossings(&r, h.t);
        let known = |c: &Crossing| {
            cross
                .iter()
                .any(|k| (k.t - c.t).abs() * r.dl <= 1e-9 * o.size)
        };
        if let Some(c) = fine
            .into_iter()
            .filter(|c| (c.t - h.t).abs() <= match_tol && !known(c))
            .min_by(|a, b| (a.t - h.t).abs().total_cmp(&(b.t - h.t).abs()))
            && (o.caps || matches!(c.part, OPart::Side | OPart::Rim))
        {
            st.fine_resolved += 1;
            used[i] = true;
            let mut c = c;
            if c.band.is_none() {
                c.band = Some("fine-resolved pair");
            }
            cross.push(c);
            matched.push(Some(i));
            continue;
        }
        // A clip of a corner shorter than the fine march's step (a ray through the rim, inside
        // for 1e-7 of the size): the membership test confirms a boundary within half the
        // distance to the nearest other library hit, where it differs on the two sides of this
        // one (so a spurious hit beside a real one, or a real crossing reported twice, is not
        // confirmed by its neighbour's boundary; by index, so that an exact duplicate is at
        // distance 0 and confirms nothing), both probes within `tmin..tmax`.
        let nearest = hits
            .iter()
            .enumerate()
            .filter(|&(j, _)| j != i)
            .map(|(_, n)| (n.t - h.t).abs())
            .fold(f64::INFINITY, f64::min);
        let delta = 0.5 * nearest;
        let clip = delta > 0.0
            && delta <= match_tol
            && h.t - delta >= tmin
            && h.t + delta <= tmax
            && o.inside(r.at(h.t - delta)) != o.inside(r.at(h.t + delta));
        if clip {
            st.fine_resolved += 1;
            used[i] = true;
            continue;
        }
        let cosi = h.normal.dot(r.d) / r.dl;
        let near_dropped_rim = dropped
            .iter()
            .any(|c| (c.t - h.t).abs() <= match_tol && c.part == OPart::Rim);
        let near_tlimit =
            (h.t - tmin) * r.dl < 1e-9 * o.size || (tmax - h.t) * r.dl < 1e-9 * o.size;
        if cosi.abs() < GRAZE_COS || near_dropped_rim || near_tlimit {
            st.band += 1;
        } else {
            st.false_hits += 1;
            let inside_before = o.inside(r.at(h.t - 1e-6 * o.size / r.dl));
            let inside_after = o.inside(r.at(h.t + 1e-6 * o.size / r.dl));
            st.flag_hit(h.t);
            st.fail_as("no crossing", format!(
                "FALSE HIT: library hit with no oracle crossing within {:.1e} in t (oracle crossings {:?}; inside just before/after: {inside_before}/{inside_after}; cos(incidence) {cosi:.3e})\n{}\nhit {h:?}",
                match_tol,
                cross.iter().map(|c| (c.t, c.part)).collect::<Vec<_>>(),
                ctx()
            ));
        }
    }
    for (c, m) in cross.iter().zip(&matched) {
        match m {
            None => {
                if c.band.is_some() {
                    st.band += 1;
                } else {
                    st.misses += 1;
                    // Second method: Newton on Gamma(u, v) = o + t d from the crossing, and the
                    // library's own surface point there.
                    let (nu, nv, nt, res) = o.newton(&r, c);
                    let lib_res = if c.part == OPart::Side {
                        (cyl_point(case, nu, nv) - ray.at(nt)).length()
                    } else {
                        f64::NAN
                    };
                    st.fail_as("miss", format!(
                        "MISS: oracle crossing {c:?} has no library hit (library t: {:?}); Newton on Gamma = o + t d from it: u {nu} v {nv} t {nt} \
                         residual {res:.2e}; |library surface_point(u, v) - ray.at(t)| = {lib_res:.2e}\n{}",
                        hits.iter().map(|h| (h.t, h.part)).collect::<Vec<_>>(),
                        ctx()
                    ));
                }
            }
            Some(i) => {
                st.matched += 1;
                let h = &hits[*i];
                if c.band.is_some() {
                    st.band += 1;
                    continue;
                }
                let terr = (h.t - c.t).abs() * r.dl / o.size;
                st.max_t_err = st.max_t_err.max(terr);
                if terr * o.size > o.tol.t {
                    st.inaccurate += 1;
                    st.misses += 1;
                    st.false_hits += 1;
                    st.flag_hit(h.t);
                    st.fail_as(
                        "t error",
                        format!(
                            "t error {terr:.3e} size: library {h:?}, oracle {c:?}\n{}",
                            ctx()
                        ),
                    );
                }
                if c.part != OPart::Rim && part_of(h.part) != c.part {
                    st.part_mismatch += 1;
                    st.fail_as(
                        "part mismatch",
                        format!(
                            "part mismatch: library {:?}, oracle {:?} ({c:?})\n{}\nhit {h:?}",
                            h.part,
                            c.part,
                            ctx()
                        ),
                    );
                }
            }
        }
    }
}

/// The library's own `surface_point` (used only in failure messages, as corroboration).
pub fn cyl_point(case: &Case, u: f64, v: f64) -> DVec3 {
    case.spec
        .build()
        .map(|c| c.surface_point(u, v))
        .unwrap_or(DVec3::NAN)
}

pub fn random_ray(o: &Oracle, rng: &mut Rng) -> (Ray, f64, f64) {
    let u = rng.range(-0.12, 1.12);
    let uc = u.clamp(0.0, 1.0);
    let [t, n, b] = o.frame(uc);
    let target = o.world(o.axis(u)) + rng.ball() * (1.4 * o.rmax_at(uc));
    let kind = rng.f64();
    let dirn = if kind < 0.6 {
        rng.unit()
    } else if kind < 0.8 {
        // Roughly along the axis: long paths inside, cap hits.
        let s = if rng.f64() < 0.5 { -1.0 } else { 1.0 };
        (s * t + 0.35 * rng.unit()).normalize()
    } else {
        // Roughly across, in the normal plane.
        let a = rng.range(0.0, TAU);
        (a.cos() * n + a.sin() * b + 0.15 * rng.unit()).normalize()
    };
    let scale = rng.range(-1.5, 1.5).exp();
    let d = dirn * scale;
    let k = rng.f64();
    if k < 0.15 {
        // From the target itself: often inside the solid.
        (Ray::new(target, d), 0.0, f64::INFINITY)
    } else {
        let back = rng.range(0.3, 2.0) * o.size;
        let origin = target - back * dirn;
        if k < 0.3 {
            let tt = back / scale;
            (
                Ray::new(origin, d),
                rng.range(0.0, tt),
                tt + rng.range(0.0, 0.3 * o.size / scale),
            )
        } else {
            (Ray::new(origin, d), 0.0, f64::INFINITY)
        }
    }
}

/// Multiplier for the ray counts, from the environment (default 1): `ORACLE_RAYS_SCALE` for the
/// fast paths, `ORACLE_GENERAL_SCALE` for runs that go through the (slow) general path.
pub fn scale_from_env(var: &str) -> f64 {
    std::env::var(var)
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1.0)
}

/// The ray counts of `runs` scaled by `ORACLE_GENERAL_SCALE` (the general method, and every
/// method on a Bezier-loop section) or `ORACLE_RAYS_SCALE` (the rest), at least 1 each.
fn scaled_runs(case: &Case, runs: &[(Method, usize)]) -> Vec<(Method, usize)> {
    let is_loop = case.loop_points.is_some();
    runs.iter()
        .map(|&(m, n)| {
            let slow = m == Method::General || is_loop;
            let f = scale_from_env(if slow {
                "ORACLE_GENERAL_SCALE"
            } else {
                "ORACLE_RAYS_SCALE"
            });
            (m, ((n as f64 * f).round() as usize).max(1))
        })
        .collect()
}

/// As many random rays (from `seed`) as the largest run needs: one sequence for every method.
fn case_rays(o: &Oracle, seed: u64, runs: &[(Method, usize)]) -> Vec<(Ray, f64, f64)> {
    let mut rng = Rng::new(seed);
    (0..runs.iter().map(|r| r.1).max().unwrap_or(0))
        .map(|_| random_ray(o, &mut rng))
        .collect()
}

/// Runs `n` rays per method, the same ray sequence (from `seed`) for every method.
pub fn run_case(case: &Case, seed: u64, runs: &[(Method, usize)]) {
    let runs = scaled_runs(case, runs);
    let o = Oracle::new(&case.spec, case.loop_points.as_deref());
    let rays = case_rays(&o, seed, &runs);
    run_rays(case, &o, &rays, &runs);
}

/// [`run_case`] for a fiber with a projection frame of reference `r`: the oracle is
/// [`Oracle::new_projected`], the library's cylinder `case.spec.build_framed(Projected(r))`.
pub fn run_case_projected(case: &Case, r: DVec3, seed: u64, runs: &[(Method, usize)]) {
    let runs = scaled_runs(case, runs);
    let o = Oracle::new_projected(&case.spec, case.loop_points.as_deref(), r);
    let cyl = case
        .spec
        .build_framed(Framing::Projected(r))
        .unwrap_or_else(|e| panic!("fiber {} does not build: {e}", case.name));
    let rays = case_rays(&o, seed, &runs);
    run_rays_on(case, &o, &cyl, &rays, &runs);
}

/// Runs the first `n` of `rays` per method and returns the most seam crossings the oracle saw
/// in one run.
pub fn run_rays(
    case: &Case,
    o: &Oracle,
    rays: &[(Ray, f64, f64)],
    runs: &[(Method, usize)],
) -> usize {
    let cyl: GeneralizedCylinder = case
        .spec
        .build()
        .unwrap_or_else(|e| panic!("fiber {} does not build: {e}", case.name));
    run_rays_on(case, o, &cyl, rays, runs)
}

/// [`run_rays`] on a given library cylinder (one built with another framing than
/// `case.spec.build()`'s).
pub fn run_rays_on(
    case: &Case,
    o: &Oracle,
    cyl: &GeneralizedCylinder,
    rays: &[(Ray, f64, f64)],
    runs: &[(Method, usize)],
) -> usize {
    // Fibers that fold (errata 5) only in the cases named for it: elsewhere a tight bend would
    // be a mistake in the fixture. (The inside test holds either way: it finds every normal
    // plane through a point within the reach of the axis.)
    assert!(
        o.beta < 0.5 || case.name.starts_with("fold-"),
        "fiber {}: max curvature * radius = {} >= 1/2 (errata 5): not a valid test fiber",
        case.name,
        o.beta
    );
    let runs: Vec<(Method, usize)> = runs.iter().map(|&(m, n)| (m, n.min(rays.len()))).collect();
    let rays = &rays[..runs.iter().map(|r| r.1).max().unwrap_or(0)];
    let t0 = Instant::now();
    let oracle: Vec<_> = rays
        .iter()
        .map(|(ray, tmin, tmax)| o.crossings(&o.ray_ctx(ray, *tmin, *tmax)))
        .collect();
    eprintln!(
        "[oracle] {:<16} oracle for {} rays: {:.2}s",
        case.name,
        rays.len(),
        t0.elapsed().as_secs_f64()
    );
    let mut all_fail = Vec::new();
    let mut seams = 0;
    for &(method, n) in &runs {
        let start = Instant::now();
        let mut st = Stats::default();
        let mut out = Vec::new();
        for (&(ray, tmin, tmax), oc) in rays[..n].iter().zip(&oracle) {
            out.clear();
            cyl.intersect_all_with(&ray, tmin, tmax, method, &mut out);
            if method == Method::Auto {
                let mut plain = Vec::new();
                cyl.intersect_all(&ray, tmin, tmax, &mut plain);
                let first = cyl.intersect(&ray, tmin, tmax);
                if plain != out {
                    st.fail_as("intersect_all != Auto", format!("intersect_all {plain:?} != intersect_all_with(Auto) {out:?}\nfiber {}: {:?}\nray {ray:?} tmin {tmin:?} tmax {tmax:?}", case.name, case.spec));
                }
                if first.map(|h| (h.t, h.part)) != out.first().map(|h| (h.t, h.part)) {
                    st.first_mismatch += 1;
                    st.fail_as("intersect != first", format!(
                        "intersect {first:?} != first of intersect_all {:?}\nfiber {}: {:?}\nray {ray:?} tmin {tmin:?} tmax {tmax:?}",
                        out.first(),
                        case.name,
                        case.spec
                    ));
                }
            }
            compare_ray(o, case, &ray, tmin, tmax, &out, method, oc, &mut st);
        }
        seams = seams.max(st.seam);
        eprintln!(
            "[oracle] {:<16} {:<10} rays {:>5}  oracle crossings {:>5}  library hits {:>5}  matched {:>5}  misses {}  false hits {} ({} inaccurate)  grazing band {} (seam {})  \
             fine-resolved {}  part mismatches {}  intersect!=first {}  max t err {:.1e}  max normal err {:.1e}  max cap normal err {:.1e}  \
             max point err {:.1e}  outward checks {}  (m {}, beta {:.2})  {:.2}s",
            case.name,
            format!("{method:?}"),
            st.rays,
            st.crossings,
            st.hits,
            st.matched,
            st.misses,
            st.false_hits,
            st.inaccurate,
            st.band,
            st.seam,
            st.fine_resolved,
            st.part_mismatch,
            st.first_mismatch,
            st.max_t_err,
            st.max_normal_err,
            st.max_cap_normal_err,
            st.max_point_err,
            st.outward_checked,
            o.m,
            o.beta,
            start.elapsed().as_secs_f64()
        );
        if st.failures > 0 {
            all_fail.push(format!(
                "{} / {method:?}: {} failures ({} misses, {} false hits); first ones:\n\n{}",
                case.name,
                st.failures,
                st.misses,
                st.false_hits,
                st.messages.join("\n\n")
            ));
        }
    }
    assert!(all_fail.is_empty(), "{}", all_fail.join("\n\n=====\n\n"));
    seams
}

// ---------------------------------------------------------------------------------------------
// Test fibers and profiles used by both test files.

pub fn v3(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}

pub fn fiber(
    bezier: [DVec3; 4],
    major: [f64; 2],
    minor: [f64; 2],
    rotation: [f64; 2],
    caps: bool,
) -> FiberSpec {
    FiberSpec {
        bezier,
        major_radius: major,
        minor_radius: minor,
        rotation,
        caps,
        normal_hint: None,
        section: Section::default(),
    }
}

pub const CURVE_3D: [[f64; 3]; 4] = [
    [0.0, 0.0, 0.0],
    [0.35, 0.45, 0.1],
    [0.75, 0.05, 0.55],
    [1.05, 0.45, 0.35],
];

pub fn curve_3d() -> [DVec3; 4] {
    CURVE_3D.map(|p| v3(p[0], p[1], p[2]))
}

/// A flat ribbon (a textile tape): a 2:1 rectangle with corners rounded to 0.3, its straight
/// sides with uneven inner control points (their equations are lines).
pub fn ribbon_points() -> Vec<DVec2> {
    let v = DVec2::new;
    let k = 0.3 * 4.0 / 3.0 * (2f64.sqrt() - 1.0);
    let mut pts = Vec::new();
    for q in 0..4 {
        let rot = |p: DVec2| match q {
            0 => p,
            1 => v(-p.y, p.x),
            2 => -p,
            _ => v(p.y, -p.x),
        };
        let (a, b) = if q % 2 == 0 { (1.0, 0.5) } else { (0.5, 1.0) };
        let (s0, s1) = (v(a, -b + 0.3), v(a, b - 0.3));
        pts.extend([s0, s0.lerp(s1, 0.3), s0.lerp(s1, 0.8)].map(rot));
        pts.extend([s1, s1 + v(0.0, k), v(a - 0.3 + k, b)].map(rot));
    }
    pts
}

/// An oval of four parabolic arcs (quadratics degree-raised to cubics; their equations are
/// conics) through `(+-1, 0)` and `(0, +-0.6)`, their middle control points at the corners of
/// the box, so the tangent is continuous at the anchors.
pub fn parabolic_points() -> Vec<DVec2> {
    let v = DVec2::new;
    let quad = |a: DVec2, q: DVec2, b: DVec2| [a, (a + 2.0 * q) / 3.0, (2.0 * q + b) / 3.0];
    let (x, y) = (1.0, 0.6);
    let anchors = [v(x, 0.0), v(0.0, y), v(-x, 0.0), v(0.0, -y)];
    let corners = [v(x, y), v(-x, y), v(-x, -y), v(x, -y)];
    (0..4)
        .flat_map(|i| quad(anchors[i], corners[i], anchors[(i + 1) % 4]))
        .collect()
}

/// Three lobes (tips at radius 1, valleys at 0.5), C1 at the anchors, counter-clockwise.
pub fn trilobal_points() -> Vec<DVec2> {
    let mut anchors = Vec::new();
    for j in 0..6 {
        let phi = PI / 2.0 + j as f64 * PI / 3.0;
        let (r, l) = if j % 2 == 0 { (1.0, 0.42) } else { (0.5, 0.22) };
        let dir = DVec2::new(phi.cos(), phi.sin());
        anchors.push((r * dir, DVec2::new(-dir.y, dir.x), l));
    }
    let mut pts = Vec::new();
    for j in 0..6 {
        let (p, t, l) = anchors[j];
        let (p1, t1, l1) = anchors[(j + 1) % 6];
        pts.extend([p, p + l * t, p1 - l1 * t1]);
    }
    pts
}
