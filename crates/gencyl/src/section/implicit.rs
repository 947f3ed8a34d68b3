//! Implicit equations of a Bezier loop's pieces, for the General method's one-dimensional
//! search ([`crate::intersect`]'s `profile` module): a point `p` of the section plane lies on the
//! algebraic curve of piece `B(s) = sum_k C(3, k) (1 - s)^(3 - k) s^k P_k` exactly when
//! `F(p) = 0`, with (Sederberg, Anderson and Goldman 1984: the Bezout resultant in `s` of the two
//! coordinate equations `B(s) = p`)
//!
//! `F(p) = det [[l32, l31, l30], [l31, l30 + l21, l20], [l30, l20, l10]]`,
//! `l_ij(p) = C(3, i) C(3, j) det [[p, 1], [P_i, 1], [P_j, 1]]`,
//!
//! a polynomial of degree 3 in `p`. A piece that is a degree-raised quadratic (control points
//! `P_1 = (P_0 + 2 Q) / 3`, `P_2 = (2 Q + P_3) / 3`) makes that determinant vanish; its curve is
//! the conic `det [[l21, l20], [l20, l10]]` with `l_ij = C(2, i) C(2, j) det [[p, 1], [Q_i, 1],
//! [Q_j, 1]]` over `Q = (P_0, Q, P_3)`. A straight piece has the line through its ends.
//!
//! The curve holds more than the piece (the Bezier for `s` outside `[0, 1]`, and for a cubic
//! possibly an isolated point): a zero of `F` is a point of the piece only when it inverts to an
//! `s` in `[0, 1]` ([`PieceImplicit::parameter_of`]). Each piece is checked when the loop is
//! built: `F` vanishes on it, its gradient stays away from zero on it (the zeros of `F` along a
//! ray that crosses the piece are simple), and no other part of the curve comes near it (the
//! inversion is unambiguous). A piece that fails is searched by the curve-curve subdivision.

use glam::DVec2;
use polycool::Cubic;

use super::bezier_loop::power;
use crate::real::{Interval, Real};

/// A polynomial of degree at most 3 in `(x, y)`: the coefficients of `1, x, y, x^2, x y, y^2,
/// x^3, x^2 y, x y^2, y^3`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Poly([f64; 10]);

/// The index of `x^i y^j` in [`Poly`].
const fn index(i: usize, j: usize) -> usize {
    let n = i + j;
    n * (n + 1) / 2 + j
}

/// The exponents `(i, j)` of each index of [`Poly`].
const EXPONENTS: [(usize, usize); 10] = [
    (0, 0),
    (1, 0),
    (0, 1),
    (2, 0),
    (1, 1),
    (0, 2),
    (3, 0),
    (2, 1),
    (1, 2),
    (0, 3),
];

impl Poly {
    /// `a x + b y + c`.
    fn linear(a: f64, b: f64, c: f64) -> Self {
        let mut p = Poly::default();
        p.0[index(1, 0)] = a;
        p.0[index(0, 1)] = b;
        p.0[index(0, 0)] = c;
        p
    }

    /// The product (of total degree at most 3).
    fn mul(self, o: Self) -> Self {
        let mut r = Poly::default();
        for (k, &(i, j)) in EXPONENTS.iter().enumerate() {
            if self.0[k] == 0.0 {
                continue;
            }
            for (l, &(m, n)) in EXPONENTS.iter().enumerate() {
                if o.0[l] != 0.0 {
                    debug_assert!(i + j + m + n <= 3, "degree above 3");
                    r.0[index(i + m, j + n)] += self.0[k] * o.0[l];
                }
            }
        }
        r
    }

    fn add(self, o: Self) -> Self {
        Poly(std::array::from_fn(|k| self.0[k] + o.0[k]))
    }

    fn sub(self, o: Self) -> Self {
        Poly(std::array::from_fn(|k| self.0[k] - o.0[k]))
    }

    fn max_abs(&self) -> f64 {
        self.0.iter().fold(0.0f64, |m, c| m.max(c.abs()))
    }

    fn eval(&self, p: DVec2) -> f64 {
        EXPONENTS
            .iter()
            .zip(self.0)
            .map(|(&(i, j), c)| c * p.x.powi(i as i32) * p.y.powi(j as i32))
            .sum()
    }

    fn gradient(&self, p: DVec2) -> DVec2 {
        let mut g = DVec2::ZERO;
        for (&(i, j), c) in EXPONENTS.iter().zip(self.0) {
            if i > 0 {
                g.x += c * i as f64 * p.x.powi(i as i32 - 1) * p.y.powi(j as i32);
            }
            if j > 0 {
                g.y += c * j as f64 * p.x.powi(i as i32) * p.y.powi(j as i32 - 1);
            }
        }
        g
    }
}

/// `det [[p, 1], [a, 1], [b, 1]]` as a polynomial in `p` times `k`, and the same with the
/// coefficients' magnitudes (for the rounding bound).
fn line_through(a: DVec2, b: DVec2, k: f64) -> (Poly, Poly) {
    let (ya, xa) = (a.y - b.y, b.x - a.x);
    let c = a.x * b.y - b.x * a.y;
    let mag = (a.x * b.y).abs() + (b.x * a.y).abs();
    (
        Poly::linear(k * ya, k * xa, k * c),
        Poly::linear(k * ya.abs(), k * xa.abs(), k * mag),
    )
}

/// `det` of a 3x3 matrix of polynomials (each product of degree at most 3), and its value
/// with every product's magnitudes added.
fn det3(m: [[(Poly, Poly); 3]; 3]) -> (Poly, Poly) {
    let mut det = Poly::default();
    let mut mag = Poly::default();
    for (perm, sign) in [
        ([0, 1, 2], 1.0),
        ([1, 2, 0], 1.0),
        ([2, 0, 1], 1.0),
        ([0, 2, 1], -1.0),
        ([2, 1, 0], -1.0),
        ([1, 0, 2], -1.0),
    ] {
        let (a, b, c) = (m[0][perm[0]], m[1][perm[1]], m[2][perm[2]]);
        let term = a.0.mul(b.0).mul(c.0);
        det = if sign > 0.0 {
            det.add(term)
        } else {
            det.sub(term)
        };
        mag = mag.add(a.1.mul(b.1).mul(c.1));
    }
    (det, mag)
}

/// The implicit equation of one piece of a Bezier loop, in coordinates local to the piece:
/// `xi = (p - centre) / scale`, with the piece's control points within `[-1, 1]^2`.
#[derive(Clone, Debug, PartialEq)]
pub struct PieceImplicit {
    centre: DVec2,
    inv_scale: f64,
    /// `F` in local coordinates, scaled to a largest coefficient of 1.
    f: Poly,
    /// A bound on `|F_computed(xi) - F_exact(xi)|` per unit of `max(1, |xi|)^3` (the rounding
    /// of the coefficients and of the local control points).
    rounding: f64,
    /// The piece's control points in local coordinates.
    local: [DVec2; 4],
}

/// Unit roundoff.
const U: f64 = f64::EPSILON / 2.0;

impl PieceImplicit {
    /// The implicit equation of the piece with control points `p`, or `None` when it is not
    /// fit for the one-dimensional search (see the module docs).
    pub fn new(p: &[DVec2; 4]) -> Option<Self> {
        let centre = (p[0] + p[1] + p[2] + p[3]) * 0.25;
        let scale = p
            .iter()
            .fold(0.0f64, |m, q| m.max((*q - centre).abs().max_element()));
        if !(scale > 0.0 && scale.is_finite()) {
            return None;
        }
        let inv_scale = 1.0 / scale;
        let local = p.map(|q| (q - centre) * inv_scale);
        let candidates = [
            cubic_implicit(&local).map(|c| (c, true)),
            conic_implicit(&local).map(|c| (c, false)),
            line_implicit(&local).map(|c| (c, false)),
        ];
        candidates
            .into_iter()
            .flatten()
            .find_map(|((f, mag), cubic)| {
                let norm = f.max_abs();
                if !(norm > 0.0 && norm.is_finite()) {
                    return None;
                }
                let f = Poly(f.0.map(|c| c / norm));
                // 40 roundings at most in any coefficient's chain (products of three linear forms,
                // six terms), the normalisation, and the local control points (off by 2u of their
                // size each: F moves by at most its gradient's bound, 9 sum |f|, times that).
                let sum_f: f64 = f.0.iter().map(|c| c.abs()).sum();
                let rounding = 64.0 * U * mag.0.iter().sum::<f64>() / norm + 9.0 * sum_f * 4.0 * U;
                let piece = PieceImplicit {
                    centre,
                    inv_scale,
                    f,
                    rounding,
                    local,
                };
                piece.fits(cubic).then_some(piece)
            })
    }

    /// Whether `F` vanishes on the piece (to `1e-10`), its gradient is at least `1e-3` there
    /// (sampled), and, for a cubic equation, the curve for `s` outside `[-0.05, 1.05]` stays
    /// `0.02` away from the piece (its double point, and samples on `[-8, 9]`, beyond which a
    /// cubic's points run far off): then every zero of `F` near the piece inverts to one
    /// parameter. (A conic's curve is the parabola of a quadratic Bezier, which does not come
    /// back; a line's zero set is the line, on which the piece is the points that project
    /// inside it.)
    fn fits(&self, cubic: bool) -> bool {
        const N: usize = 64;
        let on_piece: Vec<DVec2> = (0..=N)
            .map(|k| bezier(&self.local, k as f64 / N as f64))
            .collect();
        let vanishes = on_piece.iter().all(|&q| self.f.eval(q).abs() <= 1e-10);
        let regular = on_piece
            .iter()
            .all(|&q| self.f.gradient(q).length() >= 1e-3);
        if !(vanishes && regular) {
            return false;
        }
        if !cubic {
            return true;
        }
        let near = |q: DVec2, d: f64| on_piece.iter().any(|&r| (q - r).length() < d);
        // A cubic's curve comes back near itself only about its double point.
        if node(&self.local).is_some_and(|n| near(n, 0.05)) {
            return false;
        }
        let far = (0..=340)
            .map(|k| -8.0 + k as f64 * 0.05)
            .filter(|s| !(-0.05..=1.05).contains(s));
        !far.map(|s| bezier(&self.local, s)).any(|q| near(q, 0.02))
    }

    /// `(Q / k)^3 F(xi)` at `xi = ((X, Y) / Q - centre) / scale`: the homogeneous form, finite
    /// where `Q = 0`, for a constant `k > 0` that keeps the arguments near 1 (`k` at least
    /// `|Q|` and `|Q xi|`, as [`Self::local_bound`] gives, makes `N^2 = (Q^2 + |Q xi|^2) / k^2`
    /// at most 2), plus `rounding (N^2 + N^4) / 2 [-1, 1] >= rounding N^3 [-1, 1]` (the mean
    /// of `N^2` and `N^4` is at least their geometric mean): an enclosure then holds the exact
    /// equation's value. (A floor such as `(1 + N^2)^2` would keep the enclosures about a
    /// shallow graze from excluding zero where `N` is small, and the search would report a touch
    /// between the graze's two crossings.)
    #[inline(always)]
    pub fn homogeneous<T: Real>(&self, x: T, y: T, q: T, k: f64) -> T {
        let inv = 1.0 / k;
        let q = q.scale(inv);
        let xl = (x.scale(inv) - q.scale(self.centre.x)).scale(self.inv_scale);
        let yl = (y.scale(inv) - q.scale(self.centre.y)).scale(self.inv_scale);
        let c = &self.f.0;
        let f = |i: usize, j: usize| c[index(i, j)];
        // Horner's rule in x, then y, with the powers of Q.
        let q2 = q * q;
        let cubic_x = xl.scale(f(3, 0)) + yl.scale(f(2, 1)) + q.scale(f(2, 0));
        let rest_x = yl * (yl.scale(f(1, 2)) + q.scale(f(1, 1))) + q2.scale(f(1, 0));
        let in_y = yl * (yl * (yl.scale(f(0, 3)) + q.scale(f(0, 2))) + q2.scale(f(0, 1)));
        let value = xl * (xl * cubic_x + rest_x) + in_y + (q2 * q).scale(f(0, 0));
        if !T::ENCLOSURE {
            return value;
        }
        let n2 = xl.sqr() + yl.sqr() + q2;
        let spread = T::lift(Interval::new(-self.rounding, self.rounding));
        value + spread * (n2 + n2.sqr()).scale(0.5)
    }

    /// A bound on the size of `xi` for points in the disc of radius `r` about the origin.
    pub fn local_bound(&self, r: f64) -> f64 {
        (r + self.centre.abs().max_element()) * self.inv_scale * (1.0 + 4.0 * U)
    }

    /// A length `r` of the section plane in local units.
    pub fn local_length(&self, r: f64) -> f64 {
        r * self.inv_scale
    }

    /// The parameter `s` in `[0, 1]` of the piece's point nearest `p` (section coordinates),
    /// and that point's distance from `p` in local units ([`Self::local_length`]), or `None`
    /// when it is farther than `1e-3` (the caller decides what is near enough: on a thin fiber
    /// `phi`'s own error, in units of a small piece, can exceed `1e-7`): the roots of
    /// `x(s) = xi_x` and `y(s) = xi_y` (cubics), each refined ([`Self::project`]), the nearest
    /// kept (a piece that turns sharply passes near a point twice). A parameter within `1e-12` outside `[0, 1]` (the rounding of a
    /// point at a shared anchor) is clamped; one farther out is a point of the curve beyond the
    /// piece.
    pub fn parameter_of(&self, p: DVec2) -> Option<(f64, f64)> {
        let xi = (p - self.centre) * self.inv_scale;
        let [c0, c1, c2, c3] = power(&self.local);
        let roots = |k: usize| {
            let (c0, c1, c2, c3) = (c0[k] - xi[k], c1[k], c2[k], c3[k]);
            Cubic::new([c0, c1, c2, c3]).roots_between(-0.05, 1.05, 1e-15)
        };
        // A point of the curve solves both coordinates' cubics; at least one has a simple root
        // there (B' != 0). Each root of either, refined, is a candidate: the nearest is kept.
        let mut best: Option<(f64, f64)> = None;
        for s in roots(0).into_iter().chain(roots(1)) {
            let s = self.project(xi, s);
            if !(-1e-12..=1.0 + 1e-12).contains(&s) {
                continue;
            }
            let s = s.clamp(0.0, 1.0);
            let distance = (bezier(&self.local, s) - xi).length();
            if best.is_none_or(|(_, d)| distance < d) {
                best = Some((s, distance));
            }
        }
        best.filter(|&(_, d)| d <= 1e-3)
    }

    /// Gauss-Newton steps `s -= (B(s) - xi).B'(s) / |B'(s)|^2` from `s`, kept within
    /// `[-0.5, 1.5]`: quadratically convergent for a point on the curve (zero residual), and
    /// defined wherever `B' != 0` (Newton's own derivative, `|B'|^2 + (B - xi).B''`, is not
    /// positive away from a sharply turning piece).
    fn project(&self, xi: DVec2, mut s: f64) -> f64 {
        for _ in 0..16 {
            let (b, d1, _) = bezier_jet(&self.local, s);
            let r = b - xi;
            let dg = d1.length_squared();
            if !(dg > 0.0) {
                break;
            }
            let step = r.dot(d1) / dg;
            s = (s - step).clamp(-0.5, 1.5);
            if step.abs() <= 1e-16 {
                break;
            }
        }
        s
    }
}

/// The cubic's implicit equation (module docs) and its magnitudes, or `None` for a
/// degree-raised quadratic or a line (where it vanishes).
fn cubic_implicit(p: &[DVec2; 4]) -> Option<(Poly, Poly)> {
    let c = [1.0, 3.0, 3.0, 1.0];
    let l = |i: usize, j: usize| line_through(p[i], p[j], c[i] * c[j]);
    let (l30, l21) = (l(3, 0), l(2, 1));
    let middle = (l30.0.add(l21.0), l30.1.add(l21.1));
    let (f, mag) = det3([
        [l(3, 2), l(3, 1), l(3, 0)],
        [l(3, 1), middle, l(2, 0)],
        [l(3, 0), l(2, 0), l(1, 0)],
    ]);
    // Vanishing up to rounding: a degenerate cubic.
    (f.max_abs() > 1e-6 * mag.max_abs()).then_some((f, mag))
}

/// The conic of a degree-raised quadratic (module docs), when the piece is one to rounding.
fn conic_implicit(p: &[DVec2; 4]) -> Option<(Poly, Poly)> {
    // The middle control point from each inner one: Q = (3 P1 - P0) / 2 = (3 P2 - P3) / 2.
    let (qa, qb) = ((3.0 * p[1] - p[0]) * 0.5, (3.0 * p[2] - p[3]) * 0.5);
    if (qa - qb).length() > 1e-12 {
        return None;
    }
    let q = [p[0], (qa + qb) * 0.5, p[3]];
    let c = [1.0, 2.0, 1.0];
    let l = |i: usize, j: usize| line_through(q[i], q[j], c[i] * c[j]);
    let (l21, l20, l10) = (l(2, 1), l(2, 0), l(1, 0));
    let f = l21.0.mul(l10.0).sub(l20.0.mul(l20.0));
    let mag = l21.1.mul(l10.1).add(l20.1.mul(l20.1));
    (f.max_abs() > 1e-6 * mag.max_abs()).then_some((f, mag))
}

/// The line through a straight piece's ends, when all four points lie on it to rounding.
fn line_implicit(p: &[DVec2; 4]) -> Option<(Poly, Poly)> {
    let chord = p[3] - p[0];
    let len = chord.length();
    if !(len > 0.0) {
        return None;
    }
    let n = chord.perp() / len;
    if !p.iter().all(|&q| (q - p[0]).dot(n).abs() <= 1e-12) {
        return None;
    }
    let f = Poly::linear(n.x, n.y, -n.dot(p[0]));
    let mag = Poly::linear(
        n.x.abs(),
        n.y.abs(),
        n.x.abs() * p[0].x.abs() + n.y.abs() * p[0].y.abs(),
    );
    Some((f, mag))
}

/// The double point of a cubic Bezier's curve where two real parameters meet (a loop's
/// crossing, or a cusp), if any: `B(s1) = B(s2)` with `B = c0 + c1 s + c2 s^2 + c3 s^3` gives
/// `c3 (sigma^2 - pi) + c2 sigma + c1 = 0` for `sigma = s1 + s2`, `pi = s1 s2`; its cross
/// product with `c3` gives `sigma = -(c3 x c1) / (c3 x c2)`, its projection on `c3` gives `pi`,
/// and `s1, s2` are real when `sigma^2 >= 4 pi`.
fn node(p: &[DVec2; 4]) -> Option<DVec2> {
    let [_, c1, c2, c3] = power(p);
    let den = c3.perp_dot(c2);
    if !(den.abs() > 1e-12 * c3.length() * c2.length()) {
        return None;
    }
    let sigma = -c3.perp_dot(c1) / den;
    let pi = sigma * sigma + (c2 * sigma + c1).dot(c3) / c3.length_squared();
    let disc = sigma * sigma - 4.0 * pi;
    (disc >= 0.0 && disc.is_finite()).then(|| bezier(p, 0.5 * (sigma - disc.sqrt())))
}

fn bezier(p: &[DVec2; 4], s: f64) -> DVec2 {
    bezier_jet(p, s).0
}

/// `B(s)`, `B'(s)`, `B''(s)` by the power basis.
fn bezier_jet(p: &[DVec2; 4], s: f64) -> (DVec2, DVec2, DVec2) {
    let [c0, c1, c2, c3] = power(p);
    (
        c0 + s * (c1 + s * (c2 + s * c3)),
        c1 + s * (2.0 * c2 + s * 3.0 * c3),
        2.0 * c2 + s * 6.0 * c3,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::{Dd, Lcg};

    /// Random pieces of a section (whose profile spans about the unit disc): generic cubics in
    /// `[-1, 1]^2`, degree-raised quadratics, straight pieces with uneven control points, each
    /// scaled by `1e-3..1` and moved up to 2 away.
    fn pieces(rng: &mut Lcg, n: usize) -> Vec<(&'static str, [DVec2; 4])> {
        let mut out = Vec::new();
        let pt = |rng: &mut Lcg| DVec2::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
        for k in 0..n {
            let scale = 10f64.powf(rng.range(-3.0, 0.0));
            let shift = DVec2::new(rng.range(-2.0, 2.0), rng.range(-2.0, 2.0));
            let (kind, p) = match k % 3 {
                0 => ("cubic", [pt(rng), pt(rng), pt(rng), pt(rng)]),
                1 => {
                    let (a, q, b) = (pt(rng), pt(rng), pt(rng));
                    (
                        "quadratic",
                        [a, (a + 2.0 * q) / 3.0, (2.0 * q + b) / 3.0, b],
                    )
                }
                _ => {
                    let (a, b) = (pt(rng), pt(rng));
                    let (s1, s2) = (rng.range(0.0, 0.6), rng.range(0.4, 1.0));
                    ("line", [a, a.lerp(b, s1), a.lerp(b, s2), b])
                }
            };
            out.push((kind, p.map(|q| q * scale + shift)));
        }
        out
    }

    fn unit_normal(p: &[DVec2; 4], s: f64) -> DVec2 {
        bezier_jet(p, s).1.perp().normalize()
    }

    /// `F` vanishes on the piece and changes sign across it with slope `|grad F|`: at 33
    /// parameters, `|F(B(s))| <= 1e-11 |grad F|`, and `F(B(s) -+ 1e-6 n)` (local units) differ in
    /// sign with magnitudes within 1% of `1e-6 |grad F|`. Nearly all quadratic and straight
    /// pieces are fit (their conic or line), and most random cubics (those without a loop near
    /// them).
    #[test]
    fn the_equation_vanishes_on_the_piece_and_changes_sign_across_it() {
        let mut rng = Lcg(11);
        let mut fit = [0usize; 3];
        let mut seen = [0usize; 3];
        for (kind, p) in pieces(&mut rng, 3000) {
            let i = ["cubic", "quadratic", "line"]
                .iter()
                .position(|&k| k == kind)
                .unwrap();
            seen[i] += 1;
            let Some(imp) = PieceImplicit::new(&p) else {
                continue;
            };
            fit[i] += 1;
            for k in 0..=32 {
                let s = k as f64 / 32.0;
                let x = bezier(&imp.local, s);
                let g = imp.f.gradient(x).length();
                assert!(imp.f.eval(x).abs() <= 1e-11 * g, "{kind} {p:?} at {s}");
                let n = unit_normal(&imp.local, s);
                let (a, b) = (imp.f.eval(x + 1e-6 * n), imp.f.eval(x - 1e-6 * n));
                assert!(a * b < 0.0, "{kind} {p:?} at {s}: {a} {b}");
                for v in [a, b] {
                    assert!(
                        (v.abs() / (1e-6 * g) - 1.0).abs() < 0.01,
                        "{kind} {p:?} at {s}"
                    );
                }
            }
        }
        eprintln!("fit: {fit:?} of {seen:?} (cubic, quadratic, line)");
        assert!(
            fit[0] * 10 >= seen[0] * 6,
            "cubics fit: {fit:?} of {seen:?}"
        );
        assert!(
            fit[1] * 10 >= seen[1] * 9,
            "quadratics fit: {fit:?} of {seen:?}"
        );
        assert!(
            fit[2] * 100 >= seen[2] * 99,
            "lines fit: {fit:?} of {seen:?}"
        );
    }

    /// The enclosure of [`PieceImplicit::homogeneous`] holds the exact equation's value: `F`
    /// evaluated as the determinant of the `l_ij` at the point in double-double arithmetic from
    /// the exactly scaled control points (independent of the coefficients), at 200 points
    /// about each piece and with `Q` of `1e-3` to `1e3`.
    #[test]
    fn enclosures_hold_the_exact_value() {
        let mut rng = Lcg(12);
        let mut checked = 0;
        for (_, p) in pieces(&mut rng, 600) {
            let Some(imp) = PieceImplicit::new(&p) else {
                continue;
            };
            let dd_local = p.map(|q| {
                let d = q - imp.centre;
                [
                    Dd::of(d.x).mul(Dd::of(imp.inv_scale)),
                    Dd::of(d.y).mul(Dd::of(imp.inv_scale)),
                ]
            });
            let exact = |x: f64, y: f64| {
                let neg = |a: Dd| Dd(-a.0, -a.1);
                let sub = |a: Dd, b: Dd| a.add(neg(b));
                let c = [1.0, 3.0, 3.0, 1.0];
                // det [[p, 1], [a, 1], [b, 1]] = (ax - x)(by - y) - (bx - x)(ay - y).
                let l = |i: usize, j: usize| {
                    let (a, b) = (dd_local[i], dd_local[j]);
                    let (ax, ay) = (sub(a[0], Dd::of(x)), sub(a[1], Dd::of(y)));
                    let (bx, by) = (sub(b[0], Dd::of(x)), sub(b[1], Dd::of(y)));
                    sub(ax.mul(by), bx.mul(ay)).mul(Dd::of(c[i] * c[j]))
                };
                let m = [
                    [l(3, 2), l(3, 1), l(3, 0)],
                    [l(3, 1), l(3, 0).add(l(2, 1)), l(2, 0)],
                    [l(3, 0), l(2, 0), l(1, 0)],
                ];
                let t = |a: usize, b: usize, c: usize| m[0][a].mul(m[1][b]).mul(m[2][c]);
                t(0, 1, 2)
                    .add(t(1, 2, 0))
                    .add(t(2, 0, 1))
                    .add(neg(t(0, 2, 1)))
                    .add(neg(t(2, 1, 0)))
                    .add(neg(t(1, 0, 2)))
            };
            // Only cubic equations are the determinant (the others have their own forms).
            let norm = {
                let (f, _) = match cubic_implicit(&imp.local) {
                    Some(c) => c,
                    None => continue,
                };
                if PieceImplicit::new(&p).map(|i| i.f) != Some(Poly(f.0.map(|c| c / f.max_abs()))) {
                    continue;
                }
                f.max_abs()
            };
            for _ in 0..200 {
                let xi = DVec2::new(rng.range(-2.0, 2.0), rng.range(-2.0, 2.0));
                let q = 10f64.powf(rng.range(-3.0, 3.0));
                let k = q * 3.0;
                // (X, Y) = Q (centre + xi / inv_scale): the point xi in local units.
                let world = imp.centre + xi / imp.inv_scale;
                let (x, y) = (world.x * q, world.y * q);
                let got = imp.homogeneous(Interval::cst(x), Interval::cst(y), Interval::cst(q), k);
                // The point the enclosure is of: ((X / Q) - centre) inv_scale, rounded as the
                // code rounds it, is within an ulp of xi; the oracle takes the code's.
                let xl = (x / k - q / k * imp.centre.x) * imp.inv_scale;
                let yl = (y / k - q / k * imp.centre.y) * imp.inv_scale;
                let qk = q / k;
                if qk == 0.0 {
                    continue;
                }
                let want = exact(xl / qk, yl / qk).value() / norm * qk.powi(3);
                assert!(
                    got.lo <= want && want <= got.hi,
                    "{p:?} at {xi} q {q}: [{}, {}] misses {want}",
                    got.lo,
                    got.hi
                );
                checked += 1;
            }
        }
        assert!(checked > 10_000, "{checked}");
    }

    /// Points of the piece invert to their parameter; points of the curve beyond the piece's
    /// ends do not, and points `1e-5` (local units) off it are reported that far.
    #[test]
    fn parameters_invert_on_the_piece_only() {
        let mut rng = Lcg(13);
        for (kind, p) in pieces(&mut rng, 1500) {
            let Some(imp) = PieceImplicit::new(&p) else {
                continue;
            };
            let world = |s: f64| imp.centre + bezier(&imp.local, s) / imp.inv_scale;
            for k in 0..=40 {
                let s = k as f64 / 40.0;
                let Some((got, dist)) = imp.parameter_of(world(s)) else {
                    panic!("{kind} {p:?}: {s} not on the piece")
                };
                // The point is rounded to the section's coordinates: a few ulps of them.
                let ulps =
                    8.0 * f64::EPSILON * (world(s).abs().max_element() + 1.0) * imp.inv_scale;
                assert!(
                    (got - s).abs() <= 1e-9 && dist <= ulps,
                    "{kind} {p:?}: {s} -> {got}"
                );
                let n = unit_normal(&imp.local, s);
                let off = imp.centre + (bezier(&imp.local, s) + 1e-5 * n) / imp.inv_scale;
                let found = imp.parameter_of(off);
                assert!(
                    found.is_none_or(|(_, d)| d > 0.9e-5),
                    "{kind} {p:?}: off at {s}"
                );
            }
            // Beyond the ends: on the curve (a line's: along it, outward).
            for s in [-0.3, -0.05, -1e-6, 1.0 + 1e-6, 1.05, 1.3] {
                let x = if kind == "line" {
                    let (a, b) = (bezier(&imp.local, 0.0), bezier(&imp.local, 1.0));
                    let out = if s < 0.0 {
                        a + (a - b) * -s
                    } else {
                        b + (b - a) * (s - 1.0)
                    };
                    imp.centre + out / imp.inv_scale
                } else {
                    world(s)
                };
                assert!(imp.parameter_of(x).is_none(), "{kind} {p:?}: beyond at {s}");
            }
        }
    }

    /// A piece whose curve crosses itself on the piece (a loop), or comes back to it, or has no
    /// extent, is unfit; one whose loop lies far beyond it is fit.
    #[test]
    fn pieces_near_their_double_point_are_unfit() {
        let v = |x: f64, y: f64| DVec2::new(x, y);
        // A loop: the curve crosses itself at s = 0.2 and 0.8.
        let looped = [v(0.0, 0.0), v(2.0, 1.5), v(-1.0, 1.5), v(1.0, 0.0)];
        assert!(node(&looped).is_some());
        assert!(PieceImplicit::new(&looped).is_none());
        assert!(PieceImplicit::new(&[v(1.0, 2.0); 4]).is_none());
        // The circle's quarter: its double point (-4, -4) in local units is far off.
        let k = 4.0 / 3.0 * (2f64.sqrt() - 1.0);
        let quarter = [v(1.0, 0.0), v(1.0, k), v(k, 1.0), v(0.0, 1.0)];
        assert!(PieceImplicit::new(&quarter).is_some());
    }
}
