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
//! Newton's method inside its bracket. Where `Z'` keeps one sign on the range, both branches are
//! first isolated together through the polynomial `G = H+ H- = P^2 - Z'^2 D` ([`product_cells`]),
//! which has no singular ends and costs one subdivision instead of two. On a tube that cannot
//! fold, where the distance from the ray to the axis is convex, not even that: each branch has
//! exactly one root where `D > 0` and none elsewhere ([`tube_cells`]). Rounding: every
//! coefficient is within `SLACK` times its polynomial's largest coefficient of its exact value
//! (they come from convex combinations of the control points, de Casteljau steps and short
//! sums), and every enclosure is widened by that. A shallow graze can dip below that bound on
//! the prefilter's range (it is relative to the range's `X^2 + Y^2`); where the subdivision
//! finds nothing there, the polynomials are formed again on the narrow parts where `D` nears
//! zero ([`zoom_parts`]), whose bounds also carry what the control points' own absolute
//! rounding makes of them ([`coordinate_error`]: there `X` and `Y` are as small as the graze,
//! but still rounded to units of the coordinates). (On the prefilter's ranges that term, bounded by
//! coefficients, `2 e max|X|` where a point's is `2 e |X(s)|`, rose above the dips of shallow
//! oblique grazes of thin fibers that the relative bound resolves: an independent review found
//! 14 such crossings lost with it, in 45,812 rays.)

use arrayvec::ArrayVec;
use glam::{DVec2, DVec3};

use super::{SideRoot, SideRoots};
use crate::bernstein::Bernstein;
use crate::cylinder::GeneralizedCylinder;
use crate::frame::Frame;
use crate::real::{Interval, Real, V2};
use crate::roots::{bracketed_root, converged_root_from};
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
type B11 = Bernstein<11>;

/// The ray-space polynomials of one `u` range, with their rounding bounds.
struct Polys {
    /// The axis' coordinate along the ray.
    z: Bernstein<4>,
    /// `D = r^2 - X^2 - Y^2` (`D'`: [`Self::disc_s`]).
    disc: B7,
    /// `P = X X' + Y Y'` and `P'`.
    p: B6,
    p_s: B5,
    /// `Z'` (`Z''`: [`Self::z_ss`]).
    z_s: B3,
    /// Rounding bounds of `D`, `P` and `Z'` (their derivatives' are 12, 10 and 4 times these:
    /// `n` times differences of coefficients).
    err_disc: f64,
    err_p: f64,
    err_z: f64,
    /// Whether the radius is constant and `P' > 0` on the range (`slope_lo > 0`): the squared
    /// distance `X^2 + Y^2` from the ray to the axis is then strictly convex, and `D = r^2 -
    /// X^2 - Y^2` is largest where `P` (half its slope) vanishes.
    distance_convex: bool,
    /// A lower bound of `P'` on the range: its least coefficient less ten times `P`'s rounding
    /// bound (as a derivative's differences may take).
    slope_lo: f64,
    /// The radius `r(s) = r0 + (r1 - r0) s` at the range's ends, `[r0, r1]`.
    radius: [f64; 2],
}

/// The size of the coordinates a range's ray-space polynomials are formed from: the largest
/// coordinate `|p_ik|` of the cylinder's axis' control points (a range's control points are
/// blossoms of them) plus that of `o`, the local ray's origin (each length is at most `sqrt 3`
/// times it).
fn coordinate_size(axis: &[DVec3; 4], o: DVec3) -> f64 {
    let largest = |p: DVec3| p.abs().max_element();
    axis.iter().fold(0.0f64, |m, &p| m.max(largest(p))) + largest(o)
}

/// The absolute rounding of the ray-space control points `(p_i - o).e` of a range, for
/// coordinates of size `size` ([`coordinate_size`]): the blossoms `p_i` are off by a few units
/// of the axis' size (three levels of convex combinations), `p_i - o` by a unit more, and the
/// dot product with a unit vector rounded to a unit or two by a few: 16 units of the lengths,
/// `32 eps size` (`16 sqrt 3 < 32`).
fn coordinate_error(size: f64) -> f64 {
    32.0 * f64::EPSILON * size
}

/// A relative margin for a crossing's `z` near `z` on a fiber of radius `r_max`, far above
/// its `f64` rounding: `1e-9 (|z| + r_max)`.
fn relative_margin(z: f64, r_max: f64) -> f64 {
    1e-9 * (z.abs() + r_max)
}

/// Sign changes along a sequence of Bernstein coefficients (none of them zero): by Descartes'
/// rule in the Bernstein basis, at least the number of roots in the cell, of the same parity.
fn sign_changes(c: &[f64]) -> usize {
    c.windows(2)
        .filter(|w| (w[0] > 0.0) != (w[1] > 0.0))
        .count()
}

/// `[lo, hi]` of a polynomial on a cell, widened by its rounding bound.
#[inline]
fn bounds<const K: usize>(b: &Bernstein<K>, err: f64) -> Interval {
    let (lo, hi) = b.range();
    Interval::new(lo - err, hi + err)
}

/// The axis' control points `axis` in the frame of the ray `o + w d`, `[X, Y, Z]`: `Z` along
/// the unit direction, `X` and `Y` across it, from `o`.
#[inline]
fn ray_coords(axis: [DVec3; 4], o: DVec3, d: DVec3) -> [Bernstein<4>; 3] {
    let w = d.normalize();
    let (e1, e2) = basis(w);
    [e1, e2, w].map(|e| Bernstein(axis.map(|p| (p - o).dot(e))))
}

/// `D = r^2 - X^2 - Y^2` for the radius `r` (linear from `r[0]` to `r[1]`), and its rounding
/// bound: `SLACK (|X^2| + |Y^2| + |r^2|)` (each by its largest coefficient) for the products
/// and sums, and `2 e (|X| + |Y| + e)` for `X`'s and `Y`'s own absolute rounding `e`
/// ([`coordinate_error`]); `across` is `|X| + |Y|`.
#[inline]
fn discriminant(
    x: &Bernstein<4>,
    y: &Bernstein<4>,
    r: [f64; 2],
    (e, across): (f64, f64),
) -> (B7, f64) {
    let rr = Bernstein([r[0], r[1]]);
    let r2: B3 = rr.mul(&rr);
    let (xx, yy): (B7, B7) = (x.mul(x), y.mul(y));
    let disc = r2.elevate::<7>().sub(&xx).sub(&yy);
    (
        disc,
        SLACK * (xx.magnitude() + yy.magnitude() + r2.magnitude()) + 2.0 * e * (across + e),
    )
}

/// What the entry proofs ([`no_entry_after`]) read: `Z`, `D` and `D`'s rounding bound.
#[derive(Clone, Copy)]
struct Balls<'a> {
    z: &'a Bernstein<4>,
    disc: &'a B7,
    err_disc: f64,
}

impl Balls<'_> {
    /// How late rounding may put a crossing `z = Z ± sqrt(D)` where `D` is at its rounding
    /// level (a nearly tangent one): `4 sqrt(err_D)`.
    fn tangent_margin(&self) -> f64 {
        4.0 * self.err_disc.sqrt()
    }
}

impl Polys {
    /// The polynomials of the range whose axis' control points are `axis` (local coordinates),
    /// for the local ray `o + w d`; `e` is the control points' absolute rounding where it is
    /// counted ([`coordinate_error`], on [`zoom_parts`]'s parts), else 0.
    ///
    /// Besides their relative rounding (`SLACK`), the ray-space control points carry an
    /// absolute one, `e = coordinate_error(size)`, which narrow ranges make dominant (there
    /// `X` and `Y` are as small as the radius, but still rounded to units of the coordinates):
    /// `D = r^2 - X^2 - Y^2` is off by `2 e (max|X| + max|Y|) + 2 e^2` more, `P = X X' + Y Y'` by
    /// `e (max|X'| + max|Y'|) + 6 e (max|X| + max|Y|) <= 12 e (max|X| + max|Y|)` (`X'`'s
    /// coefficients are three times differences of `X`'s, each off by `2 e`), `Z'` by `6 e`.
    fn new(axis: [DVec3; 4], r: [f64; 2], o: DVec3, d: DVec3, e: f64) -> Self {
        let [x, y, z] = ray_coords(axis, o, d);
        let (xs, ys, z_s): (B3, B3, B3) = (x.derivative(), y.derivative(), z.derivative());
        // (Not needed where `e` is 0: the prefilter's ranges, every query's.)
        let across = if e > 0.0 {
            x.magnitude() + y.magnitude()
        } else {
            0.0
        };
        let (disc, err_disc) = discriminant(&x, &y, r, (e, across));
        let (px, py): (B6, B6) = (x.mul(&xs), y.mul(&ys));
        let p = px.add(&py);
        let scale = |m: f64| SLACK * m;
        let err_p = scale(px.magnitude() + py.magnitude()) + 12.0 * e * across;
        let err_z = scale(z_s.magnitude()) + 6.0 * e;
        let p_s: B5 = p.derivative();
        let slope_lo = bounds(&p_s, 10.0 * err_p).lo;
        let distance_convex = r[0] == r[1] && slope_lo > 0.0;
        Polys {
            z,
            disc,
            p_s,
            p,
            z_s,
            err_disc,
            err_p,
            err_z,
            distance_convex,
            slope_lo,
            radius: r,
        }
    }

    /// Whether `D < 0` at the range's end `j` (0 or 1) beyond its rounding bound (a Bernstein
    /// form's end value is its end coefficient): the ray passes outside the ball about the
    /// axis' end point there.
    fn end_outside(&self, j: usize) -> bool {
        self.disc.0[6 * j] < -self.err_disc
    }

    /// `D'`, formed where it is used (the subdivision and the nearly parallel crossings; most
    /// queries settle without it).
    fn disc_s(&self) -> B6 {
        self.disc.derivative()
    }

    /// `Z''`, formed where it is used (as [`Self::disc_s`]).
    fn z_ss(&self) -> Bernstein<2> {
        self.z_s.derivative()
    }

    /// `Z`, `D` and `D`'s rounding bound, for the entry proofs.
    fn balls(&self) -> Balls<'_> {
        Balls {
            z: &self.z,
            disc: &self.disc,
            err_disc: self.err_disc,
        }
    }

    /// [`Balls::tangent_margin`].
    fn tangent_margin(&self) -> f64 {
        self.balls().tangent_margin()
    }

    /// `H` of branch `sign` at `s`, in `f64` (the same value [`Self::branch`] gives).
    #[inline]
    fn h(&self, s: f64, sign: f64) -> f64 {
        let (minus_p, across) = self.parts(s);
        minus_p + sign * across
    }

    /// `(-P, Z' sqrt(D))` at `s` (`D` clamped at 0): both branches at once, `H± = -P ± Z' sqrt(D)`.
    #[inline]
    fn parts(&self, s: f64) -> (f64, f64) {
        let root = self.disc.eval(s).max(0.0).sqrt();
        (-self.p.eval(s), self.z_s.eval(s) * root)
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
        // Where D <= 0 the clamped branch is -P (its slope -P'), not the sqrt's infinite slope
        // (Newton's method would crawl by ulps there).
        let dh = if root > 0.0 {
            -ps + sign * (zss * root + zs * dsc_s / (2.0 * root))
        } else {
            -ps
        };
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
            disc_s: k.disc_s().restrict(s0, s1),
            p: k.p.restrict(s0, s1),
            p_s: k.p_s.restrict(s0, s1),
            z_s: k.z_s.restrict(s0, s1),
            z_ss: k.z_ss().restrict(s0, s1),
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
/// Returns false where a cell too narrow (or past the budget) to split further may hold a root
/// that its ends' signs do not show, or more than one, or where `out` had no room for a root.
fn branch_roots(k: &Polys, a: f64, b: f64, sign: f64, out: &mut ArrayVec<f64, 16>) -> bool {
    let mut sure = true;
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
        // A derivative's coefficients are `n` times differences of its polynomial's, each off
        // by that one's bound: `D'` (n = 6) by `12 err_D`, `P'` (5) by `10 err_P`, `Z''` (2) by
        // `4 err_Z'`.
        let monotone = disc.lo > 0.0 && {
            let dh = Interval::cst(0.0) - bounds(&c.p_s, 10.0 * k.err_p)
                + (bounds(&c.z_ss, 4.0 * k.err_z) * root
                    + z_s * bounds(&c.disc_s, 12.0 * k.err_disc) / (root + root))
                    * Interval::cst(sign);
            dh.excludes_zero()
        };
        if monotone || narrow {
            sure &= monotone;
            let (fa, fb) = (k.h(c.s0, sign), k.h(c.s1, sign));
            if let Some(r) = bracketed_root(&value, c.s0, c.s1, fa, fb)
                && out.last().is_none_or(|&l| r > l)
            {
                sure &= out.try_push(r).is_ok();
            }
            continue;
        }
        let (l, r) = c.halves();
        stack.push(r);
        stack.push(l);
    }
    sure
}

/// Most cells [`Product::cells`] examines before it leaves the range to [`branch_roots`].
const PRODUCT_BUDGET: usize = 48;

/// `G = H+ H- = P^2 - Z'^2 D` on a range where `Z'` keeps one sign, with its rounding bound: the
/// polynomial whose roots are both branches' ([`Product::cells`]).
struct Product {
    g: B11,
    err: f64,
}

impl Product {
    /// `G` of the range, where the ray is oblique to the axis on all of it (`Z'` keeps one
    /// sign); `None` otherwise.
    fn new(k: &Polys) -> Option<Self> {
        if !bounds(&k.z_s, k.err_z).excludes_zero() {
            return None;
        }
        let pp: B11 = k.p.mul(&k.p);
        let zz: B5 = k.z_s.mul(&k.z_s);
        let zzd: B11 = zz.mul(&k.disc);
        // Rounding: the factors' own bounds carried through the products, and the products'
        // and the cells' de Casteljau steps relative to the terms that cancel.
        let (pm, zm, dm) = (k.p.magnitude(), k.z_s.magnitude(), k.disc.magnitude());
        let err = 4.0
            * (2.0 * pm * k.err_p
                + k.err_p * k.err_p
                + (2.0 * zm * k.err_z + k.err_z * k.err_z) * (dm + k.err_disc)
                + zm * zm * k.err_disc)
            + SLACK * (pp.magnitude() + zzd.magnitude());
        Some(Product {
            g: pp.sub(&zzd),
            err,
        })
    }

    /// The roots of both branches on `[a, b]` isolated, one per [`RootCell`], ascending, into
    /// `found`; `None` where this cannot be certified cheaply (then [`branch_roots`] on each
    /// stretch decides).
    ///
    /// If `Z'` keeps one sign, `G(s) = 0` means `P = ± Z' sqrt(D)` with `D >= 0`: a root of
    /// exactly one branch, the one whose `H` changes sign there (the other, `G / H`, does not
    /// vanish near it); and every branch root is a root of `G`. So the branch roots are isolated
    /// by isolating `G`'s: a cell whose Bernstein coefficients (each of a sign that its rounding
    /// bound cannot flip) show no sign change holds no root, one sign change exactly one
    /// (Descartes' rule of signs in the Bernstein basis), on the branch [`RootCell::of`] names.
    fn cells(&self, k: &Polys, a: f64, b: f64, found: &mut ArrayVec<RootCell, 16>) -> Option<()> {
        let mut stack: ArrayVec<(B11, f64, f64), 32> = ArrayVec::new();
        stack.push((self.g.restrict(a, b), a, b));
        let mut cells = 0;
        while let Some((c, s0, s1)) = stack.pop() {
            cells += 1;
            if cells > PRODUCT_BUDGET {
                return None;
            }
            if c.0.iter().any(|x| x.abs() <= self.err) {
                // A coefficient whose sign rounding may flip: a narrower cell may settle it.
                // A split takes the popped cell's slot and one more.
                if s1 - s0 < 1e-6 || stack.remaining_capacity() < 2 {
                    return None;
                }
            } else {
                let changes = sign_changes(&c.0);
                if changes == 0 {
                    continue;
                }
                if changes == 1 {
                    // Otherwise a narrower cell about the root settles it.
                    if let Some(cell) = RootCell::of(k, s0, s1, c.0[0] < 0.0) {
                        found.try_push(cell).ok()?;
                        continue;
                    }
                }
                if stack.remaining_capacity() < 2 {
                    return None;
                }
            }
            let m = 0.5 * (s0 + s1);
            let (l, r) = c.split(0.5);
            stack.push((r, m, s1));
            stack.push((l, s0, m));
        }
        Some(())
    }
}

/// The root cells of the whole range on a tube that does not fold (a round section whose
/// radius `r(s) = r0 + rho s` is linear on the range, `r |a''| < |a'|^2` everywhere:
/// [`GeneralizedCylinder::may_fold`] false) where `D = r^2 - X^2 - Y^2` is concave, without
/// `G`, into `found`: none where the ray certainly passes outside, two (one for each branch)
/// where it certainly crosses; `None` where neither is certified cheaply (then
/// [`product_cells`] decides).
///
/// Where `D > 0`, along branch `±` the ray's point is `p = (0, 0, Z ± sqrt(D))`, at distance `r`
/// from `a`, and the derivative of `H± = a'.(p - a)` is `a''.(p - a) - |a'|^2 + Z' t'` with
/// `t' = Z' ± D' / (2 sqrt(D))`, `D' = 2 (r rho - P)`. At a root (`P = ± Z' sqrt(D)`) `t' = ±
/// r rho / sqrt(D)`, so `H±' = -K ± Z' r rho / sqrt(D)` with `K = |a'|^2 + a''.(a - p) = P' + Z'^2
/// ∓ Z'' sqrt(D) >= |a'|^2 - r |a''| > 0`, and `K >= kappa = min P' + min Z'^2 - max|Z''| r_max`
/// on the range (`sqrt(D) <= r`). On a tube of constant radius every root has `H±' = -K < 0`;
/// on a tapered one every root where `sqrt(D) > delta / 2`, `delta = 2 max|Z'| r_max |rho| /
/// kappa`. A root with `sqrt(D) <= delta / 2` has `|P| = |Z'| sqrt(D) < max|Z'| delta`: where
/// `D > delta^2` wherever `|P| < max|Z'| delta` there is none, and then `H±` crosses zero only
/// downward, so at most once on `[0, 1]` (the clamped branch is continuous, and where `D <= 0`
/// it is `-P`, zero only at the zero `s*` of `P`, where `D > 0`).
///
/// Here `P' > rho^2` ([`Polys::slope_lo`], certified), so `P` rises and `D'' = 2 (rho^2 - P') <
/// 0`. With `D < 0` at both ends of the range (its end coefficients, certified), `D` is
/// negative everywhere if `D' = 2 (r rho - P)` keeps one sign (from its ends); otherwise
/// Newton's method on `P` gives `m` near `s*`. Constant radius: where `D(m) > 0`, `D(s*) > 0`
/// (`D` is largest at `s*`). Tapered: `D > delta^2` at points `a < m < b` where `P < -max|Z'|
/// delta` and `P > max|Z'| delta` (all certified by rounding bounds), so on `[a, b]`
/// (concavity), which holds `s*` and every point where `|P| < max|Z'| delta`. Then each branch
/// has exactly one root in `[0, 1]`: it is `-P > 0` at 0 and `-P < 0` at 1 (`D < 0` there, and
/// `P(0) < P(a) < 0 < P(b) < P(1)`). They are certified ([`RootCell::certain`]); `m` splits the
/// range where the branch's sign there allows. `Z'` must keep one sign, as
/// [`RootCell::w_range`] takes it.
///
/// With `ends_inside` (the whole axis, [`whole_tube`]), a tube of constant radius may also have
/// `D >= 0` at an end (a ray that passes within `r` of the axis' end point, as near a strand's
/// joints). The argument above still gives each branch at most one root on `[0, 1]` (every root
/// where `D > 0` is a downward crossing, and `D(m) > 0` leaves `-P` no zero where `D <= 0`),
/// so a branch has one where its values at the ends ([`branch_at_end`], certified beyond their
/// rounding there) are positive then negative, and none where both have one sign and the end
/// that shows it is inside a ball (both ends outside give `-P(0) > 0 > -P(1)`). `m` is then the
/// end nearer `P`'s zero where `P` keeps one sign on the range.
///
/// Returns, where it certifies, `D` at the crossings of the straight tube through `m`, `D(m)
/// P' / (P' + Z'^2)` (`D(m)` times the squared sine of the angle between the ray and the
/// axis; `+inf` where the range has no crossing): how deep the crossings lie in `D`, which
/// sets how much `D`'s rounding moves them ([`whole_tube`]).
fn tube_cells(k: &Polys, ends_inside: bool, found: &mut ArrayVec<RootCell, 16>) -> Option<f64> {
    let [r0, r1] = k.radius;
    let (rho, r_max) = (r1 - r0, r0.abs().max(r1.abs()));
    let z_range = bounds(&k.z_s, k.err_z);
    // Both ends outside the balls about the axis (`D < 0`), or, where `ends_inside`, a
    // constant radius (see below).
    let outside = k.end_outside(0) && k.end_outside(1);
    let applies = k.slope_lo > rho * rho
        && z_range.excludes_zero()
        && (outside || (ends_inside && rho == 0.0));
    if !applies {
        return None;
    }
    let (p0, p1) = (k.p.0[0], k.p.0[5]);
    // `D'/2 = r rho - P` at the ends (`r rho` rounded too).
    let err_q = k.err_p + SLACK * (r_max * rho).abs();
    if outside && (p0 - r0 * rho > err_q || p1 - r1 * rho < -err_q) {
        // `D'` keeps one sign (it falls): `D` is monotone, below its negative ends.
        return Some(f64::INFINITY);
    }
    // Newton's method on `P` (rising) from the secant point of its end values, until a step is
    // below 1e-6 (the next is then below about 1e-12): `m` only splits the range and starts the
    // polish, whose start is off by 1e-4 to 1e-5 of the cell anyway (the tube's curvature), and
    // the certificate below holds or fails by what it checks at `m`, wherever `m` lies. Where
    // `P` keeps one sign on the range (an end inside a ball; with both outside it changes
    // sign), `m` is the end nearer its zero.
    let mut m = if p0 >= 0.0 {
        0.0
    } else if p1 <= 0.0 {
        1.0
    } else {
        -p0 / (p1 - p0)
    };
    let mut slope = f64::NAN;
    for _ in 0..4 {
        let (p, ps) = k.p.eval_with_derivative(m);
        slope = ps;
        let next = m - p / ps;
        if !(next > 0.0 && next < 1.0) {
            break;
        }
        let step = (next - m).abs();
        m = next;
        if step < 1e-6 {
            break;
        }
    }
    let dm = k.disc.eval(m);
    if !(dm > k.err_disc) {
        return None;
    }
    if rho != 0.0 {
        // Tapered: `D > delta^2` where `|P| < max|Z'| delta` (see above).
        let z_min = z_range.lo.abs().min(z_range.hi.abs());
        let z_max = z_range.lo.abs().max(z_range.hi.abs());
        let (zss_lo, zss_hi) = k.z_ss().range();
        // `Z''`'s coefficients are differences of `Z'`'s, times 2.
        let zss_max = zss_lo.abs().max(zss_hi.abs()) + 4.0 * k.err_z;
        let kappa = k.slope_lo + z_min * z_min - zss_max * r_max;
        let delta = 2.0 * z_max * r_max * rho.abs() / kappa;
        let band = z_max * delta + k.err_p;
        let h = 2.0 * band / slope;
        let (a, b) = ((m - h).max(0.0), (m + h).min(1.0));
        let floor = delta * delta + k.err_disc;
        let certified = kappa > 0.0
            && k.p.eval(a) < -band
            && k.p.eval(b) > band
            && k.disc.eval(a) > floor
            && k.disc.eval(b) > floor;
        if !certified {
            return None;
        }
    }
    // Where a straight tube's crossings lie from `m` (the ray's closest approach, `P' = |a'|^2
    // sin^2` of the angle between them): `cos sqrt(D / P')` either side. Only a start.
    let zs = k.z_s.eval(m);
    let reach = zs.abs() * (dm / (slope * (slope + zs * zs))).sqrt();
    // At `m`, `-P ± Z' sqrt(D)` ([`Polys::parts`], from the `D` and `Z'` just evaluated); at
    // the ends, [`branch_at_end`].
    let (minus_p, across) = (-k.p.eval(m), zs * dm.sqrt());
    for sign in [-1.0, 1.0] {
        let (fa, fb) = (branch_at_end(k, 0, sign)?, branch_at_end(k, 1, sign)?);
        let fm = minus_p + sign * across;
        if !(fa > 0.0 && fb < 0.0) {
            // No root of this branch on the range: certain where the end whose sign shows it
            // lies inside a ball (`H` crosses zero only downward), not where both lie
            // outside (there `-P(0) > 0 > -P(1)`, so such values are rounding's).
            let inside = |j: usize| !k.end_outside(j);
            if (fa < 0.0 && inside(0) && fb < 0.0) || (fb > 0.0 && inside(1) && fa > 0.0) {
                continue;
            }
            return None;
        }
        let (s0, s1, fa, fb, start) = if fm < 0.0 && m > 0.0 {
            (0.0, m, fa, fm, m - reach)
        } else if fm > 0.0 && m < 1.0 {
            (m, 1.0, fm, fb, m + reach)
        } else {
            (0.0, 1.0, fa, fb, f64::NAN)
        };
        found
            .try_push(RootCell {
                s0,
                s1,
                sign,
                fa,
                fb,
                certain: true,
                start,
            })
            .ok()?;
    }
    Some(dm * slope / (slope + zs * zs))
}

/// Branch `sign`'s value at the end `j` (0 or 1) of the range, where its sign is certain:
/// `-P` where `D < 0` there (an end coefficient; [`tube_cells`] shows its sign), else `-P ±
/// Z' sqrt(D)` where it exceeds its rounding bound (`P`'s and `Z'`'s, and what `D`'s does to
/// the square root: `sqrt(D + e) - sqrt(D - e)`, `e` its bound, at most `sqrt(2 e)`); `None`
/// where it does not. (An independent review found `err_p` and `err_z`, formed without the
/// coordinates' own rounding on the whole axis, exceeded alone on rays nearly along or across
/// the axis; the sum held, by 10 to 75 times, through the square root's term, which is at
/// least `|Z'| err_D / r`: no wrong sign in 770,000 ends inside a ball.)
fn branch_at_end(k: &Polys, j: usize, sign: f64) -> Option<f64> {
    let (dj, pj, zj) = (k.disc.0[6 * j], k.p.0[5 * j], k.z_s.0[2 * j]);
    if k.end_outside(j) {
        return Some(-pj);
    }
    let (high, low) = ((dj + k.err_disc).sqrt(), (dj - k.err_disc).max(0.0).sqrt());
    let value = -pj + sign * zj * dj.max(0.0).sqrt();
    let bound = k.err_p
        + zj.abs() * (high - low)
        + k.err_z * high
        + 4.0 * f64::EPSILON * (pj.abs() + zj.abs() * high);
    (value.abs() > bound).then_some(value)
}

/// The root cells of the whole range into `cells` ([`Product::new`], [`Product::cells`]);
/// `None` where the product method cannot isolate them.
fn product_cells(k: &Polys, cells: &mut ArrayVec<RootCell, 16>) -> Option<()> {
    Product::new(k)?.cells(k, 0.0, 1.0, cells)
}

/// The roots of both branches at once, as `(s, sign)`, polished: [`product_cells`] and
/// [`settle_all`]; `None` where the product method cannot certify them.
#[cfg(test)]
fn product_roots(k: &Polys) -> Option<ArrayVec<(f64, f64), 16>> {
    let (mut cells, mut out) = (ArrayVec::new(), ArrayVec::new());
    product_cells(k, &mut cells)?;
    settle_all(k, &cells, &mut out)?;
    Some(out)
}

/// The roots of the cells ([`settle`]) into `out`, or `None` if the product method cannot
/// certify them.
fn settle_all(k: &Polys, cells: &[RootCell], out: &mut ArrayVec<(f64, f64), 16>) -> Option<()> {
    cells.iter().try_for_each(|cell| settle(k, cell, out))
}

/// A cell `[s0, s1]` where `G` has exactly one (simple) root `r` (certified by
/// [`Product::cells`]), or where branch `sign` has exactly one (certified by [`tube_cells`]; the
/// other branch's root may lie in the cell too), and the branch `H_sign` that vanishes there:
/// `fa` at `s0` and `fb` at `s1`, of opposite signs. Where `certain`, the branch is certified
/// and `D(r) > 0` ([`RootCell::certified_branch`], [`tube_cells`]): the cell certainly holds a
/// crossing of the side surface
/// (the point of the circle of radius `r(s)` in the normal plane at `s` where the ray crosses
/// it), where the ray enters the ball about the axis point on the `-` branch and leaves it on
/// the `+` branch.
#[derive(Clone, Copy, Debug)]
struct RootCell {
    s0: f64,
    s1: f64,
    sign: f64,
    fa: f64,
    fb: f64,
    certain: bool,
    /// Where Newton's method starts (NaN: the bracket's secant point; outside it, its midpoint).
    start: f64,
}

impl RootCell {
    /// Where a search of the cell starts: `start` where it lies inside, else the secant point
    /// of the end values.
    fn start_or_secant(&self) -> f64 {
        if self.start > self.s0 && self.start < self.s1 {
            self.start
        } else {
            self.s0 + (self.s1 - self.s0) * (self.fa / (self.fa - self.fb))
        }
    }

    /// Whether the branch's values at `lo` and `hi` (`h`'s; the cell's end values where they
    /// reach past its ends) have the signs of the cell's ends, so that the cell's one root lies
    /// between them; `None` where `h` gives no value (its sign is not certain).
    fn brackets(&self, (lo, hi): (f64, f64), h: impl Fn(f64) -> Option<f64>) -> Option<bool> {
        let f_lo = if lo <= self.s0 { self.fa } else { h(lo)? };
        let f_hi = if hi >= self.s1 { self.fb } else { h(hi)? };
        Some(f_lo * self.fa > 0.0 && f_hi * self.fb > 0.0)
    }

    /// The root cell of `[s0, s1]`, where `G` has exactly one root; `g_rises` when `G < 0` at
    /// `s0` (its end values' signs are certified). `None` where a narrower cell is needed.
    ///
    /// The branch is the certified one where [`Self::certified_branch`] gives it, else the one
    /// whose end values (in `f64`) change sign: where `G < 0` the branches have opposite signs,
    /// where `G > 0` the same sign (`|P| > |Z'| sqrt(D)`), also where `D < 0` (both read `-P`,
    /// `sqrt(D)` clamped at 0), so the branch of `r` changes sign there and the other does not,
    /// unless `P` vanishes an odd number of times where `D < 0` in the cell, which flips both.
    /// Such a guess may be wrong: its polish then fails to verify and the cell is isolated
    /// again ([`settle`]), and its bounds ([`Self::w_range`]) hold on either branch. The branch's
    /// end values must also differ in sign (the polish's bracket): where rounding hides that,
    /// a narrower cell settles it.
    fn of(k: &Polys, s0: f64, s1: f64, g_rises: bool) -> Option<Self> {
        let ((q0, c0), (q1, c1)) = (k.parts(s0), k.parts(s1));
        let (m0, m1, p0, p1) = (q0 - c0, q1 - c1, q0 + c0, q1 + c1);
        // `-P` at the end where `G > 0`.
        let q_f = if g_rises { q1 } else { q0 };
        let certified = Self::certified_branch(k, s0, s1, -q_f);
        let sign = match (certified, m0 * m1 < 0.0, p0 * p1 < 0.0) {
            (Some(sign), _, _) => sign,
            (None, true, false) => -1.0,
            (None, false, true) => 1.0,
            _ => return None,
        };
        let (fa, fb) = if sign < 0.0 { (m0, m1) } else { (p0, p1) };
        if !(fa * fb < 0.0) {
            return None;
        }
        Some(RootCell {
            s0,
            s1,
            sign,
            fa,
            fb,
            certain: certified.is_some(),
            start: f64::NAN,
        })
    }

    /// The branch of the cell's root `r`, where it can be certified; `p` is `P(f)` in `f64`.
    ///
    /// At `r`, if `P(r) != 0`, `D = P^2 / Z'^2 > 0`, and the branch `H± = -P ± Z' sqrt(D)` that
    /// vanishes is the one with `P = ± Z' sqrt(D)`: `+` where `P(r)` has the sign of `Z'` (which
    /// keeps one sign on the range), `-` where it has the other. Between `r` and the end `f`
    /// where `G > 0`, `G > 0`, so `P` vanishes only where `D < 0` (there `G = -Z'^2 D`). So
    /// `P(r)` has the sign of `P(f)` (certified by its rounding bound) when `P` has no zero
    /// (or an even number) where `D < 0` in the cell, which holds where any of these does:
    /// - `P`'s coefficients on the cell keep one sign beyond their rounding bound;
    /// - `D > 0` on the whole cell ([`positive_disc`]);
    /// - [`Polys::distance_convex`]: `P` has at most one zero, where the squared distance is
    ///   least and `D` largest, so `D >= D(r) > 0` there.
    fn certified_branch(k: &Polys, s0: f64, s1: f64, p: f64) -> Option<f64> {
        if p.abs() <= 2.0 * k.err_p {
            return None;
        }
        let no_flip = k.distance_convex
            || bounds(&k.p.restrict(s0, s1), k.err_p).excludes_zero()
            || positive_disc(k, s0, s1);
        if !no_flip {
            return None;
        }
        Some(if (p > 0.0) == (k.z_s.0[0] > 0.0) {
            1.0
        } else {
            -1.0
        })
    }

    /// The root, polished on its branch and verified; `None` where it is not verified.
    ///
    /// Newton's method in the bracket finds a point `x` where `H_sign` changes sign. If `D(x)`
    /// exceeds its rounding bound, `H_sign` is the unclamped branch about `x`, so `x` is a root
    /// of `G`: it is `r`. Otherwise (a zero of `-P` where `D < 0`, or `r` where the ray grazes
    /// the sphere) `x` is taken only if `D > 0` on the whole cell (then `H_sign` has no other
    /// zero there).
    fn polish(&self, k: &Polys) -> Option<f64> {
        let (s0, s1, sign, fa, fb) = (self.s0, self.s1, self.sign, self.fa, self.fb);
        // Newton's method from the cell's start, or the bracket's secant point.
        let start = if self.start.is_nan() {
            s0 + (s1 - s0) * (fa / (fa - fb))
        } else {
            self.start
        };
        let (r, converged) =
            converged_root_from(&|s: f64| k.branch(s, sign), (s0, s1, fa, fb), start)?;
        (converged && k.disc.eval(r) > k.err_disc || positive_disc(k, s0, s1)).then_some(r)
    }

    /// Lower and upper bounds of the ray parameter `w` of the cell's crossing (whose
    /// `z = Z ± sqrt(D)` along `d / |d|`): `Z` is monotone on the range (`Z'` keeps one sign), so
    /// it lies between its end values on the cell, and `0 <= sqrt(D) <= r_max` (on the branch
    /// named where it is certain, on either otherwise). The margins
    /// cover the rounding of `Z`, and a root that rounding puts on the other branch where both
    /// meet (`D` at its rounding level).
    fn w_range(&self, k: &Polys, r_max: f64, len: f64) -> [f64; 2] {
        let (za, zb) = (k.z.eval(self.s0), k.z.eval(self.s1));
        let (z_lo, z_hi) = (za.min(zb), za.max(zb));
        let (low, high) = match (self.certain, self.sign < 0.0) {
            (false, _) => (z_lo - r_max, z_hi + r_max),
            (true, true) => (z_lo - r_max, z_hi),
            (true, false) => (z_lo, z_hi + r_max),
        };
        let margin = |z: f64| k.tangent_margin() + relative_margin(z, r_max);
        [(low - margin(z_lo)) / len, (high + margin(z_hi)) / len]
    }
}

/// The roots of a cell, as `(s, sign)`, into `out`: its own root where [`RootCell::polish`]
/// verifies it, otherwise those of its halves isolated again; `None` where the product method
/// cannot certify them.
fn settle(k: &Polys, cell: &RootCell, out: &mut ArrayVec<(f64, f64), 16>) -> Option<()> {
    if let Some(r) = cell.polish(k) {
        return out.try_push((r, cell.sign)).ok();
    }
    if cell.s1 - cell.s0 < 1e-6 {
        return None;
    }
    let product = Product::new(k)?;
    let m = 0.5 * (cell.s0 + cell.s1);
    for (a, b) in [(cell.s0, m), (m, cell.s1)] {
        let mut halves = ArrayVec::new();
        product.cells(k, a, b, &mut halves)?;
        settle_all(k, &halves, out)?;
    }
    Some(())
}

/// Whether `D > 0` on all of `[s0, s1]`, by its coefficients there and their rounding bound.
fn positive_disc(k: &Polys, s0: f64, s1: f64) -> bool {
    bounds(&k.disc.restrict(s0, s1), k.err_disc).lo > 0.0
}

/// A range's polynomials kept for [`Deferred`] cells, with the range `[u0, u1]`.
struct DeferredRange {
    k: Polys,
    u: (f64, f64),
    /// Where the range is a whole tube's ([`whole_tube`]), how its crossings are refined in
    /// space ([`refined`]).
    local: Option<Refine>,
}

/// What [`refined`] needs of a whole tube's range: the local ray's origin, and how far along
/// the ray (in `z`) the refinement may move a crossing.
#[derive(Clone, Copy, Debug)]
struct Refine {
    o: DVec3,
    reach: f64,
}

/// What a deferred root cell holds: certainly a crossing of the side surface where the ray
/// enters the ball about the axis point (the `-` branch, `z = Z - sqrt(D)`) or leaves it (`+`),
/// certainly a crossing of unknown direction (a [`super::radial_cells`] cell), or a root whose
/// branch (or its being a crossing rather than a touch) is not certified.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum CellCrossing {
    Entry,
    Exit,
    Either,
    Unsure,
}

/// Root cells of the Round method whose polishing waits until a query reaches them, with a
/// lower bound of each one's `w` ([`RootCell::w_range`]): a nearest-hit query polishes the
/// crossing it takes, not the exit behind it.
pub(crate) struct Deferred {
    ranges: ArrayVec<DeferredRange, DEFERRED_RANGES>,
    cells: ArrayVec<(usize, RootCell, [f64; 2]), MAX_DEFERRED>,
}

/// Most cells a [`Deferred`] keeps.
pub(crate) const MAX_DEFERRED: usize = 16;

/// Ranges whose cells a [`Deferred`] keeps (a ray near a fiber usually has one; others are
/// polished at once).
const DEFERRED_RANGES: usize = 2;

impl Deferred {
    pub(crate) fn new() -> Self {
        Deferred {
            ranges: ArrayVec::new(),
            cells: ArrayVec::new(),
        }
    }

    /// Keeps the range `u` (polynomials `k`) and its root cells, each with its bounds of `w`
    /// ([`RootCell::w_range`]), but a tube's certain exits where the query wants entries only
    /// (`entries_only`): they would be dropped unpolished; `local`: how its crossings are
    /// [`refined`] (a whole tube's range). The caller makes sure there is room.
    fn keep(
        &mut self,
        (k, u, local): (Polys, (f64, f64), Option<Refine>),
        cells: &[RootCell],
        entries_only: bool,
        len: f64,
    ) {
        let range = self.ranges.len();
        let r_max = k.radius[0].abs().max(k.radius[1].abs());
        let wanted = |c: &&RootCell| !(entries_only && c.certain && c.sign > 0.0);
        for cell in cells.iter().filter(wanted) {
            let bounds = cell.w_range(&k, r_max, len);
            self.cells.push((range, *cell, bounds));
        }
        self.ranges.push(DeferredRange { k, u, local });
    }

    /// The deferred cells: index, lower and upper bound of `w`, and what each holds.
    pub(crate) fn bounds(&self) -> impl Iterator<Item = (usize, [f64; 2], CellCrossing)> + '_ {
        (0..self.cells.len()).map(|i| {
            let (w, holds) = self.cell(i);
            (i, w, holds)
        })
    }

    /// Cell `i`'s bounds of `w` and what it holds ([`Self::bounds`]).
    pub(crate) fn cell(&self, i: usize) -> ([f64; 2], CellCrossing) {
        let (_, cell, w) = &self.cells[i];
        let holds = match (cell.certain, cell.sign > 0.0) {
            (false, _) => CellCrossing::Unsure,
            (true, false) => CellCrossing::Entry,
            (true, true) => CellCrossing::Exit,
        };
        (*w, holds)
    }

    /// Polishes cell `i` into `out` (as [`roots`] would have given its roots); where
    /// [`subdivided`] leaves the cell's `u` range to the Radial method, returns that range and
    /// whether `a'.d > 0` there instead.
    pub(crate) fn polish<C: CrossSection, S: SweepRule>(
        &self,
        i: usize,
        cyl: &GeneralizedCylinder<C, S>,
        d: DVec3,
        out: &mut SideRoots,
    ) -> Option<((f64, f64), bool)> {
        let (range, cell, [w_lo, w_hi]) = self.cells[i];
        let r = &self.ranges[range];
        if let Some(refine) = r.local
            && let Some((u, w)) = solved_in_space(cyl, (refine.o, d), &r.k, r.u, &cell)
            && (w_lo..=w_hi).contains(&w)
        {
            push(cyl, d, u, w, out);
            return None;
        }
        let mut roots = ArrayVec::new();
        if settle(&r.k, &cell, &mut roots).is_none() {
            let (u0, u1) = r.u;
            let cell_u = (u0 + (u1 - u0) * cell.s0, u0 + (u1 - u0) * cell.s1);
            return subdivided(cyl, (d, r.local), &r.k, r.u, cell_u, out);
        }
        push_all(cyl, (d, r.local), &r.k, r.u, &roots, out);
        None
    }
}

/// The roots on the part `[ua, ub]` of the `u` range `[u0, u1]` (whose polynomials are `k`) by
/// the subdivision of both branches ([`stretch_roots`]), into `out`; or, where the subdivision
/// met a cell it could not resolve, on a part whose radius varies (by more than `1e-8` of
/// itself and `1e-12` of the coordinates: far above the rounding of the distance from the
/// axis) and that lies within 60 degrees of the ray ([`NEARLY_ALONG`]), nothing, and returns
/// the part and whether `a'.d > 0` there. That is a ray nearly parallel to a nearly straight
/// tapered axis, where the branch functions nearly vanish along the whole part but the Radial
/// method's normal-plane function (`|e(u)|^2 / r(u)^2 - 1`, `e(u)` the ray's point in the
/// normal plane at `u` less `a(u)`) changes by the taper's share, far beyond its rounding and
/// its tangent tolerance (`1e-9` of its scale): its sign changes are the crossings. (Not on a
/// constant radius: a ray lying in the surface makes that function zero to rounding along the
/// whole part, and its isolation would report sign changes everywhere; nor on nearly
/// perpendicular rays, whose shallow grazes that tolerance would merge into one touch.)
fn subdivided<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    (d, local): (DVec3, Option<Refine>),
    k: &Polys,
    (u0, u1): (f64, f64),
    (ua, ub): (f64, f64),
    out: &mut SideRoots,
) -> Option<((f64, f64), bool)> {
    let span = u1 - u0;
    let (sa, sb) = ((ua - u0) / span, (ub - u0) / span);
    let (found, sure) = stretch_roots(k, sa, sb);
    let [r0, r1] = k.radius;
    let change = (r1 - r0).abs() * (sb - sa);
    let tapered = change > 1e-8 * r0.abs().max(r1.abs()) + 1e-12 * k.z.magnitude();
    if !sure
        && tapered
        && let Some(rising) = cyl.obliquity_at_least(d, ua, ub, NEARLY_ALONG)
    {
        return Some(((ua, ub), rising));
    }
    push_all(cyl, (d, local), k, (u0, u1), &found, out);
    None
}

/// How oblique a range must be for [`subdivided`] to leave it to the Radial method: `|a'.d|`
/// at least half of `max|a'| |d|` on it.
const NEARLY_ALONG: f64 = 0.5;

/// The side roots of a round fiber for the local ray `o + w d` on the `u` range `[u0, u1]`:
/// polished into `out`, or where `deferred` has room and [`tube_cells`] or the product method
/// isolates them, left there as cells. With `entries_after = Some(w_min)` (a query that wants
/// only entries beyond `w_min`, on a tube: [`GeneralizedCylinder::intersect_first_entering_with`])
/// a range that [`no_entry_after`] clears is left at once. Returns the range and whether
/// `a'.d > 0` there where [`subdivided`] leaves it to the Radial method (nothing is pushed
/// then).
pub(crate) fn roots<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    o: DVec3,
    d: DVec3,
    (u0, u1): (f64, f64),
    entries_after: Option<f64>,
    out: &mut SideRoots,
    deferred: &mut Deferred,
) -> Option<((f64, f64), bool)> {
    roots_in(cyl, (o, d, 0.0), (u0, u1), entries_after, out, deferred, 0)
}

/// [`roots`] on the range `[u0, u1]`, `depth` zooms ([`zoom_parts`]) below the prefilter's
/// range; `e` the control points' absolute rounding counted in the bounds (0 on the
/// prefilter's ranges).
fn roots_in<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    (o, d, e): (DVec3, DVec3, f64),
    (u0, u1): (f64, f64),
    entries_after: Option<f64>,
    out: &mut SideRoots,
    deferred: &mut Deferred,
    depth: usize,
) -> Option<((f64, f64), bool)> {
    let r = range_radius(cyl, (u0, u1))?;
    let k = Polys::new(cyl.axis.segment(u0, u1).points, r, o, d, e);
    let len = d.length();
    // The subdivision, and where it finds nothing, a closer look at where `D` nears zero.
    let subdivide = |out: &mut SideRoots, deferred: &mut Deferred| {
        let before = out.len();
        let left = subdivided(cyl, (d, None), &k, (u0, u1), (u0, u1), out);
        if left.is_some() || out.len() > before {
            return left;
        }
        if depth >= ZOOM_LEVELS {
            return None;
        }
        // The parts, in `u`, each searched again with its own polynomials and bounds.
        let span = u1 - u0;
        let at = |s: f64| if s == 1.0 { u1 } else { u0 + span * s };
        let ray = (o, d, coordinate_error(coordinate_size(&cyl.axis.points, o)));
        let mut left = None;
        for (a, b) in zoom_parts(&k) {
            let part = (at(a), at(b));
            let l = roots_in(cyl, ray, part, entries_after, out, deferred, depth + 1);
            left = left.or(l);
        }
        left
    };
    if entries_after.is_some_and(|w_min| {
        no_entry_after(k.balls(), w_min * len, r[0].abs().max(r[1].abs()), None)
    }) {
        return None;
    }
    if let Some(crossing) = level_crossing(cyl, o, d, (u0, u1), &k) {
        if let Some((u, w)) = crossing {
            push(cyl, d, u, w, out);
        }
        return None;
    }
    let mut cells = ArrayVec::new();
    if cyl.may_fold() || tube_cells(&k, false, &mut cells).is_none() {
        cells.clear();
        if product_cells(&k, &mut cells).is_none() {
            return subdivide(out, deferred);
        }
    }
    if cells.is_empty() {
        return None;
    }
    let room = deferred.cells.remaining_capacity() >= cells.len();
    if !deferred.ranges.is_full() && room {
        deferred.keep((k, (u0, u1), None), &cells, entries_after.is_some(), len);
        return None;
    }
    let mut found = ArrayVec::new();
    if settle_all(&k, &cells, &mut found).is_none() {
        return subdivide(out, deferred);
    }
    push_all(cyl, (d, None), &k, (u0, u1), &found, out);
    None
}

/// How far [`whole_tube`] lets `D`'s rounding over the whole axis move a crossing before the
/// refinement ([`refined`]), relative to the crossing's depth in the ball about the axis point
/// (`sqrt(D*)`), by its bound `16 eps max|D|`: one Newton step then leaves at most `e /
/// (2 sqrt(D*))` of an error `e` (the distance `|e|^2 - r^2` is quadratic in `w`, with
/// curvature `1 / (2 sqrt(D*))` against its slope), `2.5e-4` of it at the gate's edge, and in
/// practice (the actual rounding is far below the bound) a few units of rounding.
const WHOLE_START: f64 = 1e-3;

/// The least cosine of incidence at which [`whole_tube`] takes a crossing: at grazing
/// incidence the refinement's residual, rounded to the coordinates' size rather than the
/// radius', places it farther than the narrow ranges do (an independent review found a
/// crossing at `cos = 1.2e-5` 18 times farther from the exact one than theirs).
const WHOLE_MIN_COS: f64 = 1e-3;

/// The side roots of a tube (constant radius, no folding) on the whole `u` range `[u0, u1]` at
/// once, without the prefilter's narrower ranges: where [`tube_cells`] certifies them there
/// (one entry and one exit, each the only root of its branch in its cell), their cells are left
/// in `deferred` (empty before) as [`roots`] leaves a range's, marked for refinement, and the
/// answer is `true`; also where it certifies a miss (no cells). Else `false` and nothing is
/// left (the caller searches the prefilter's ranges). With `entries_after = Some(w_min)`, a
/// range that [`no_entry_after`] clears is left at once, as in [`roots`].
///
/// The certificate and the bounds hold whatever the range (their rounding bounds are the
/// range's), but the polished crossing is not as close: on the whole axis `D`'s coefficients
/// are as large as the axis' squared distance from the ray (about the fiber's length squared),
/// not the radius' as on the prefilter's narrow ranges, and forming and evaluating `D` rounds
/// it by about `16 eps max|D|`, which moves `z = Z - sqrt(D)` by that over `sqrt(D*)`, `D*` the
/// crossings' depth in `D` ([`tube_cells`]'s answer): about `1e-13` on the ponytail, where the
/// narrow ranges keep it to a few units of rounding. So each crossing found here takes one
/// Newton step on its conditions in space ([`refined`]), whose rounding is that of the
/// coordinates, as on the narrow ranges; where that start is not within [`WHOLE_START`] of
/// the depth, or the incidence is grazing ([`WHOLE_MIN_COS`]: `D* < cos^2 r^2` for the
/// straight tube's `D*`), the prefilter's ranges take the ray.
pub(crate) fn whole_tube<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    o: DVec3,
    d: DVec3,
    (u0, u1): (f64, f64),
    entries_after: Option<f64>,
    deferred: &mut Deferred,
) -> bool {
    let Some(r) = range_radius(cyl, (u0, u1)) else {
        return false;
    };
    if r[0] != r[1] || cyl.may_fold() || !deferred.ranges.is_empty() {
        return false;
    }
    let k = Polys::new(cyl.axis.segment(u0, u1).points, r, o, d, 0.0);
    let (len, r_max) = (d.length(), r[0].abs());
    if entries_after.is_some_and(|w_min| no_entry_after(k.balls(), w_min * len, r_max, None)) {
        return true;
    }
    let mut cells = ArrayVec::new();
    let Some(depth) = tube_cells(&k, true, &mut cells) else {
        return false;
    };
    let rounding = 16.0 * f64::EPSILON * k.disc.magnitude();
    if !(rounding <= WHOLE_START * depth && depth >= (WHOLE_MIN_COS * r_max).powi(2)) {
        return false;
    }
    // The refinement may move a crossing 8 times as far as `D`'s rounding may have moved it
    // (`rounding / (2 sqrt(D*))`; the depth at the root can fall below the straight tube's, to
    // 0.19 of it at worst in the review's sample): at the gate's edge, under a hundredth of
    // the cells' bounds' margin (`4 sqrt(err_D)`).
    let local = Refine {
        o,
        reach: 8.0 * rounding / (2.0 * depth.sqrt()),
    };
    deferred.keep(
        (k, (u0, u1), Some(local)),
        &cells,
        entries_after.is_some(),
        len,
    );
    true
}

/// The part of the `u` range `[u0, u1]` outside which the local ray `o + w d` passes farther
/// than `r` from the axis (its point in the normal plane at `u`), for a constant `r` at which
/// the fiber's tube does not fold (the caller's): from the tube's crossings on the range,
/// certified by [`tube_cells`] (which counts them all, ends inside the balls about the axis
/// allowed: each branch has at most one root there) and each bracketed, by
/// [`window_bracket`] about the cell's start where that settles it, else within
/// [`SPACE_BRACKET`] of the `s` [`solved_in_space`] finds (the window reaches to the
/// brackets' far ends), and
/// whether each end's normal-plane point lies inside the tube ([`end_inside_tube`]): the
/// inside set's ends are the crossings and the ends inside (a prefilter's range often ends
/// inside, short of the crossing beyond a strand's joint). `Some(None)` where the ray
/// certainly passes outside the tube, `None` where that is not certified (a graze, a ray
/// across the axis somewhere), or the inside set is not one interval.
///
/// The General method's window where `phi` may lie in the section's bounding disc, where the
/// rule scales uniformly ([`GeneralizedCylinder::disc_window`]): the disc function `g` is
/// `q^2 (|e|^2 / s^2 - R^2)` there, zero on this tube.
pub(crate) fn tube_window<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    o: DVec3,
    d: DVec3,
    (u0, u1): (f64, f64),
    r: f64,
) -> Option<Option<(f64, f64)>> {
    // The coordinates' absolute rounding counted: it places the brackets' signs
    // ([`window_bracket`]) on narrow ranges, where it outweighs the relative one.
    let e = coordinate_error(coordinate_size(&cyl.axis.points, o));
    let k = Polys::new(cyl.axis.segment(u0, u1).points, [r, r], o, d, e);
    let mut cells = ArrayVec::new();
    tube_cells(&k, true, &mut cells)?;
    let (inside0, inside1) = (end_inside_tube(&k, 0)?, end_inside_tube(&k, 1)?);
    // Each crossing's bracket in `s`: about the cell's start where that settles it, else
    // about the crossing found in space.
    let mut crossings: ArrayVec<(f64, f64), 2> = ArrayVec::new();
    let rounding = inner_rounding(&k);
    for cell in &cells {
        let bracket = match window_bracket(&k, rounding, cell) {
            Some(b) => b,
            None => {
                let (u, _) = solved_in_space(cyl, (o, d), &k, (u0, u1), cell)?;
                let s = (u - u0) / (u1 - u0);
                (s - SPACE_BRACKET, s + SPACE_BRACKET)
            }
        };
        crossings.try_push(bracket).ok()?;
    }
    // The range's own ends where the window reaches them (`u0 + (u1 - u0)` may round off `u1`).
    let at = |s: f64| match s {
        ..=0.0 => u0,
        1.0.. => u1,
        _ => u0 + (u1 - u0) * s,
    };
    let (first, last) = match (inside0, inside1, crossings.as_slice()) {
        (false, false, []) => return Some(None),
        (false, false, &[a, b]) => (a.0.min(b.0), a.1.max(b.1)),
        (true, false, &[a]) => (0.0, a.1),
        (false, true, &[a]) => (a.0, 1.0),
        _ => return None,
    };
    Some(Some((at(first), at(last))))
}

/// The half-width of [`window_bracket`]'s brackets, as a part of the start's distance from
/// the nearer end of its cell: most cells end at the ray's closest approach to the axis, and
/// their starts, the straight tube's crossings, lie half the tube's chord from it, so the
/// window grows by about this part of itself. (A part of the cell instead let a ray within
/// `1e-13` of perpendicular to a thin fiber, which meets its tube over `1e-18` of the axis,
/// have a window `1e15` times wider than that, where the branch method, whose isolation
/// narrows a cell about such a dip only so many times, missed crossings: the stress tests'
/// radii family.) Measured: on the CT view of an elliptical ply seen side-on every one of
/// its 88,828 crossings was bracketed at `1/32` and at `1/128`; on side-on strands 99.9% at
/// `1/32`, 95% at `1/128`, 30% at `1/1000` (the rest solved in space).
const WINDOW_BRACKET: f64 = 1.0 / 32.0;

/// A bracket `[lo, hi]` (in `s`) of the crossing of [`tube_window`]'s cell, without solving
/// for it: [`WINDOW_BRACKET`] of the start's distance from the nearer end of the cell either
/// side of the start (else of its secant point), where the branch's values at `lo` and `hi`
/// (the cell's end values where they reach
/// past its ends) have the signs of the cell's ends, beyond the polynomials' rounding
/// ([`branch_beyond_rounding`]). The cell holds exactly one root of the branch
/// ([`tube_cells`]), so that root lies in the bracket. A window needs no more: two values of
/// `H` instead of Newton's steps in space and two values. `None` where the signs do not show
/// it (the start is farther off, or the bracket's ends are within the rounding of `H`'s root:
/// on a short range, where `H`'s rounding, relative to the coordinates, is wide in `s`).
fn window_bracket(k: &Polys, rounding: [f64; 3], cell: &RootCell) -> Option<(f64, f64)> {
    let s = cell.start_or_secant();
    let half = WINDOW_BRACKET * (s - cell.s0).min(cell.s1 - s);
    let (lo, hi) = (s - half, s + half);
    let bracketed = cell.brackets((lo, hi), |x| {
        branch_beyond_rounding(k, rounding, x, cell.sign)
    })?;
    bracketed.then_some((lo.max(cell.s0), hi.min(cell.s1)))
}

/// The rounding bounds of `D`, `P` and `Z'` at points inside the range: the polynomials'
/// own ([`Polys`]) grown by their evaluation's (de Casteljau's `n` levels of convex
/// combinations round by at most `n eps` of the largest coefficient, taken twice over).
fn inner_rounding(k: &Polys) -> [f64; 3] {
    let eps = f64::EPSILON;
    [
        k.err_disc + 12.0 * eps * k.disc.magnitude(),
        k.err_p + 10.0 * eps * k.p.magnitude(),
        k.err_z + 4.0 * eps * k.z_s.magnitude(),
    ]
}

/// `H±` of branch `sign` at `s` inside the range, where its sign is certain: its value
/// exceeds the bound of [`branch_at_end`] with the rounding bounds of [`inner_rounding`].
fn branch_beyond_rounding(
    k: &Polys,
    [err_disc, err_p, err_z]: [f64; 3],
    s: f64,
    sign: f64,
) -> Option<f64> {
    let (dsc, p, zs) = (k.disc.eval(s), k.p.eval(s), k.z_s.eval(s));
    let (high, low) = (
        (dsc + err_disc).max(0.0).sqrt(),
        (dsc - err_disc).max(0.0).sqrt(),
    );
    let value = -p + sign * zs * dsc.max(0.0).sqrt();
    let bound = err_p
        + zs.abs() * (high - low)
        + err_z * high
        + 4.0 * f64::EPSILON * (p.abs() + zs.abs() * high);
    (value.abs() > bound).then_some(value)
}

/// Whether the local ray's point in the normal plane at the range's end `j` (0 or 1) lies
/// inside the tube of [`tube_window`], where that is certain: the ray meets the ball of radius
/// `r` about the axis point in the chord between its branch points `p-` and `p+`, and the
/// normal-plane point (where `H = a'.(p - a) = 0`, linear along the ray) lies on that chord
/// exactly where `H-` and `H+` there have opposite signs ([`branch_at_end`], `-P` for both
/// outside the ball). `None` where either sign is not certain.
fn end_inside_tube(k: &Polys, j: usize) -> Option<bool> {
    Some(branch_at_end(k, j, -1.0)? * branch_at_end(k, j, 1.0)? < 0.0)
}

/// The crossing `(u, w)` of the local ray `o + w d` with the tube of radius `r` about the
/// axis, after one Newton step from `(u, w)` on its conditions in space ([`space_step`]).
/// `(u, w)` itself where the step is not finite, moves the point along the ray by more than
/// `refine.reach`, or takes `u` out of `[0, 1]`: the crossing then stays where the whole axis'
/// polynomials put it (still inside its cell's bounds), never somewhere the certificate does
/// not cover.
fn refined<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    (refine, d): (Refine, DVec3),
    r: f64,
    (u, w): (f64, f64),
) -> (f64, f64) {
    let (du, dw, _) = space_step(cyl.axis.jet(u), (refine.o, d), r, w);
    let (u1, w1) = (u - du, w - dw);
    if (dw * d).length() <= refine.reach && (0.0..=1.0).contains(&u1) {
        (u1, w1)
    } else {
        (u, w)
    }
}

/// Newton's step `(du, dw)` (to be taken away from `(u, w)`) on the conditions in space of the
/// local ray `o + w d` crossing the tube of radius `r`, from `[a, a', a'']` at `u`, with the
/// offset `e = o + w d - a(u)` there: `e` lies in the normal plane, `F1 = a'.e = 0`, and on
/// the circle, `F2 = |e|^2 - r^2 = 0`. The Jacobian is `[[a''.e - |a'|^2, a'.d], [-2 F1,
/// 2 e.d]]`.
#[inline]
fn space_step(
    [a, a1, a2]: [DVec3; 3],
    (o, d): (DVec3, DVec3),
    r: f64,
    w: f64,
) -> (f64, f64, DVec3) {
    let e = o + w * d - a;
    let (f1, f2) = (a1.dot(e), e.length_squared() - r * r);
    let (j11, j12, j21, j22) = (
        a2.dot(e) - a1.length_squared(),
        a1.dot(d),
        -2.0 * f1,
        2.0 * e.dot(d),
    );
    let det = j11 * j22 - j12 * j21;
    let (du, dw) = ((f1 * j22 - j12 * f2) / det, (j11 * f2 - j21 * f1) / det);
    (du, dw, e)
}

/// The crossing of a whole tube's root cell ([`whole_tube`], [`tube_window`]) for the local
/// ray `o + w d`, found by Newton's method in space and certified by the cell's branch
/// function: where it is, as `(u, w)`; `None` where Newton's method does not settle or the
/// certificate fails (then the cell is polished on `H`, as others are). The start is the cell's `u` (the straight tube's crossing, [`tube_cells`]) with
/// `w` on the sphere about `a(u)` ([`space_crossing_from`]).
fn solved_in_space<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    (o, d): (DVec3, DVec3),
    k: &Polys,
    (u0, u1): (f64, f64),
    cell: &RootCell,
) -> Option<(f64, f64)> {
    let s = cell.start_or_secant();
    let u = u0 + (u1 - u0) * s;
    space_crossing_from(cyl, (o, d), k, (u0, u1), cell, (u, None))
}

/// Most Newton steps [`space_crossing_from`] takes.
const SPACE_STEPS: usize = 6;

/// Where [`space_crossing_from`] stops: after a step of at most this in `u` that moves the
/// point along the ray by at most this times the radius. Newton's error after it is about `C`
/// times its square, `C` the conditions' second derivatives over their first (about 100 in
/// `u` on the ponytail's tubes: steps of `1e-5`, `1e-8`, `1e-15` from the cells' starts), so
/// at the coordinates' rounding; most crossings settle in three steps.
const SPACE_SETTLED: f64 = 1e-10;

/// How far either side of the crossing's `s` [`space_crossing_from`] looks for the branch
/// function's change of sign: far above its rounding there (`D`'s on the whole axis moves its
/// root by about `1e-13` of the axis' parameter), far below the cells' widths.
const SPACE_BRACKET: f64 = 1e-9;

/// Newton's method in space on a whole tube's crossing conditions (those of [`refined`]: `F1 =
/// a'.e = 0`, `F2 = |e|^2 - r^2 = 0`, `e = o + w d - a(u)`) from `(u, w)` (where `w` is `None`,
/// the ray's crossing of the sphere of radius `r` about `a(u)` on the cell's side: `w0 ±
/// sqrt((r^2 - m^2) / |d|^2)`, `w0` the ray's point nearest `a(u)`, `m` its distance), until a
/// step is below [`SPACE_SETTLED`], then certified as the cell's crossing:
/// - `e.d` has the sign of the cell's branch (`-` for an entry: the ray's point enters the
///   ball about `a(u)`), so the point is `z = Z(s) ± sqrt(D(s))` of that branch at `s`, the
///   `s` of `u` on the range, and `H±(s) = a'.e` vanishes there (to rounding);
/// - `s` lies in the cell, and `H±` changes sign between `s - SPACE_BRACKET` and `s +
///   SPACE_BRACKET` as it does between the cell's ends (where those points reach past the cell,
///   its end values stand for them): the branch's one root in the cell ([`tube_cells`]) lies
///   within `SPACE_BRACKET` of `s`.
///
/// So the point found is that root's crossing, not the other branch's (an entry and an exit
/// nearly in one normal plane have nearly one `s`) nor another point of the ray; and as
/// [`refined`]'s, its rounding is the coordinates', not that of `D` on the whole axis. It takes
/// about as many evaluations of `a`, `a'` and `a''` as the polish on `H` takes of `H` and `H'`,
/// each a third of the work, and two values of `H` for the certificate.
fn space_crossing_from<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    (o, d): (DVec3, DVec3),
    k: &Polys,
    (u0, u1): (f64, f64),
    cell: &RootCell,
    (mut u, start_w): (f64, Option<f64>),
) -> Option<(f64, f64)> {
    let r = k.radius[0];
    let mut w = start_w.unwrap_or(f64::NAN);
    let reach = SPACE_SETTLED * r / d.length();
    let mut settled = false;
    let mut e = DVec3::NAN;
    for _ in 0..SPACE_STEPS {
        let [a, a1, a2] = cyl.axis.jet(u);
        if w.is_nan() {
            let dd = d.length_squared();
            let w0 = (a - o).dot(d) / dd;
            let miss = (o + w0 * d - a).length_squared();
            w = w0 + cell.sign * ((r * r - miss).max(0.0) / dd).sqrt();
        }
        let (du, dw, at) = space_step([a, a1, a2], (o, d), r, w);
        e = at;
        if !(du.is_finite() && dw.is_finite()) {
            return None;
        }
        (u, w) = (u - du, w - dw);
        if du.abs() <= SPACE_SETTLED && dw.abs() <= reach {
            settled = true;
            break;
        }
    }
    // `e` as of the last step's start, a rounding's breadth from the point found (the whole
    // tube's crossings are not grazing: [`WHOLE_MIN_COS`]; for [`tube_window`], which has no
    // such gate, the bracket below alone places the branch's root, all the window needs).
    if !settled || !(e.dot(d) * cell.sign > 0.0) {
        return None;
    }
    let s = (u - u0) / (u1 - u0);
    if !(s >= cell.s0 && s <= cell.s1) {
        return None;
    }
    let bracket = (s - SPACE_BRACKET, s + SPACE_BRACKET);
    let bracketed = cell.brackets(bracket, |x| Some(k.h(x, cell.sign)))?;
    bracketed.then_some((u, w))
}

/// Most times [`roots_in`] forms a range's polynomials again on a narrower part
/// ([`zoom_parts`]).
const ZOOM_LEVELS: usize = 4;

/// The cells (as parts of the range) [`zoom_parts`] looks for `D`'s band with.
const ZOOM_CELL: f64 = 1.0 / 64.0;

/// Where the subdivision found no root on a range (polynomials `k`) but `D` may come within
/// its rounding bound of zero (a shallow graze: the ray dips into the ball about the axis by
/// less than the rounding of `D = r^2 - X^2 - Y^2`, which is relative to the range's `X^2 +
/// Y^2`), the parts of the range (in `s`) where it may, which [`roots_in`] searches again,
/// each with polynomials formed from its own control points: there `X` and `Y` are smaller,
/// and so is `D`'s rounding bound, about quadratically in the part's width (until the
/// coordinates' own rounding, [`coordinate_error`], counted on the parts, dominates it). The
/// parts: the cells of `[0, 1]` (halved down to [`ZOOM_CELL`]) where `D`'s coefficients reach
/// `-err_D`, merged; none unless they are at most two and cover at most a quarter of the range
/// (a ray along the surface has `D` near zero on all of it, which no narrower part resolves
/// better).
fn zoom_parts(k: &Polys) -> ArrayVec<(f64, f64), 2> {
    let floor = -k.err_disc;
    let mut parts: ArrayVec<(f64, f64), 2> = ArrayVec::new();
    let mut stack: ArrayVec<(B7, f64, f64), 16> = ArrayVec::new();
    stack.push((k.disc, 0.0, 1.0));
    while let Some((b, s0, s1)) = stack.pop() {
        if b.range().1 < floor {
            continue;
        }
        if s1 - s0 > ZOOM_CELL {
            let (l, r) = b.split(0.5);
            let m = 0.5 * (s0 + s1);
            stack.push((r, m, s1));
            stack.push((l, s0, m));
            continue;
        }
        match parts.last_mut() {
            Some(last) if last.1 == s0 => last.1 = s1,
            _ => {
                if parts.try_push((s0, s1)).is_err() {
                    return ArrayVec::new();
                }
            }
        }
    }
    if parts.iter().map(|(a, b)| b - a).sum::<f64>() > 0.25 {
        parts.clear();
    }
    parts
}

/// The side crossings of a range where `P = X X' + Y Y'` is so small that every crossing has
/// `D` below its rounding bound (the axis keeps its distance from the ray: a ray parallel, or
/// parallel but for the rounding of the inputs, to a straight axis) and the radius varies:
/// `Some(Some((u, w)))` for the one crossing, `Some(None)` where there is none; `None` where
/// that is not the case, or the answer is not certified (the other methods then decide). On
/// an independent review's 13,205 parallel and nearly parallel rays (tilts 0 and 1e-16 to
/// 1e-5; straight tapered fibers to 1e8 from the origin, tapers from `1 + 1e-9` to `1e6`)
/// against a dense scan of the normal-plane function: no extra or misplaced crossing (radius
/// at the hit within 3e-12 of the truth); 142 missed, against 2,802 without this (nearly
/// parallel rays whose crossings' `D` lies above this band but too low for the branch method
/// to certify: README, Not yet).
///
/// There `H± = -P ± Z' sqrt(D)` vanish (exactly parallel) or nearly vanish wherever `D <= 0`,
/// and the branch functions certify nothing; but `G = P^2 - Z'^2 D = 0` puts every crossing
/// where `0 <= D <= (p / z)^2` (`p` a bound of the true `|P|`, its coefficients' and their
/// rounding's, and `z` the least `|Z'|`), and `D' = 2 r r' - 2 P` keeps the sign of `r'` where
/// `|r r'|` exceeds `p` (four times `p` is asked): `D` is monotone, and every crossing lies at
/// its root `s*`, to within `D`'s own resolution. A crossing is certain where the normal-plane
/// function `f(u) = |x(u) - a(u)|^2 - r(u)^2` (`x(u)` the ray's point in the normal plane at
/// `u`, on a range oblique to the ray) changes sign within the range beyond its rounding: then
/// the range has exactly one crossing, at `s*`. (On a ray exactly parallel to a straight
/// tapered axis the branch method found none.)
fn level_crossing<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    o: DVec3,
    d: DVec3,
    (u0, u1): (f64, f64),
    k: &Polys,
) -> Option<Option<(f64, f64)>> {
    let [r0, r1] = k.radius;
    if r0 == r1 {
        return None;
    }
    let (p_lo, p_hi) = k.p.range();
    let p_bound = 2.0 * k.err_p + p_lo.abs().max(p_hi.abs());
    let (ra, rb) = (r0.abs().min(r1.abs()), r0.abs().max(r1.abs()));
    let (z_lo, z_hi) = k.z_s.range();
    let z_min = if z_lo > 0.0 { z_lo } else { -z_hi } - k.err_z;
    // Every crossing has `D = P^2 / Z'^2 <= band = (p_bound / z_min)^2`, here below `D`'s own
    // rounding level (the branch method cannot certify it); `D' = 2 r r' - 2 P` keeps the sign
    // of `r' = r1 - r0` (per unit of `s`) where `|r r'| > |P|`: four times `P`'s bound.
    let band = (p_bound / z_min).powi(2);
    if !(z_min > 0.0 && band <= 16.0 * k.err_disc && ra * (r1 - r0).abs() > 4.0 * p_bound) {
        return None;
    }
    cyl.obliquity(d, u0, u1)?;
    let (d0, d1) = (k.disc.eval(0.0), k.disc.eval(1.0));
    // The true `D` within `err_disc` of the computed one: certainly above every crossing's,
    // or certainly negative (none has `D < 0`).
    let above = |x: f64| x > band + k.err_disc;
    let below = |x: f64| x < -k.err_disc;
    if above(d0) && above(d1) || below(d0) && below(d1) {
        // `D` monotone: beyond the crossings' band on the whole range, so none.
        return Some(None);
    }
    if !(above(d0) && below(d1) || below(d0) && above(d1)) {
        return None;
    }
    let disc_s = k.disc_s();
    let (s, converged) = converged_root_from(
        &|s: f64| (k.disc.eval(s), disc_s.eval(s)),
        (0.0, 1.0, d0, d1),
        d0 / (d0 - d1),
    )?;
    if !converged {
        return None;
    }
    // `f` about `u* = u0 + (u1 - u0) s`. Its rounding: `e = o + w d - a` is off by a few units
    // of `|o| + |a| + |w d|` and, through `w = (a - o).a' / (d.a')` (relative error a few units
    // of `|a - o| |a'| / |(a - o).a'| + 1 / cos`, `cos = |d.a'| / (|d| |a'|)`), of
    // `(|a - o| + |w d|) / cos`; `f = |e|^2 - r^2` by twice `|e|` times that, and a few units of
    // `|e|^2 + r^2`. The margin is thirty times as much (`1e-13` against `16 eps`).
    let axis = &cyl.axis;
    let span = u1 - u0;
    let u_star = u0 + span * s;
    let w_at = |a: DVec3, a1: DVec3| (a - o).dot(a1) / d.dot(a1);
    let f = |u: f64| -> (f64, f64) {
        let (a, a1) = (axis.point(u), axis.d1(u));
        let along = d.dot(a1);
        let w = w_at(a, a1);
        let e = o + w * d - a;
        let r = (r0 + (r1 - r0) * ((u - u0) / span)).abs();
        let over_cos = d.length() * a1.length() / along.abs();
        let lengths = o.length() + a.length() + ((w * d).length() + (a - o).length()) * over_cos;
        // (`r` itself is off by a few units of `rb`.)
        let margin = 1e-13 * (r + e.length()) * lengths + 1e-15 * (e.length_squared() + r * rb);
        (e.length_squared() - r * r, margin)
    };
    // `|f'| ~ 2 r |r'|` about `u*` (`|e|` stays near the radius there): a step whose change is
    // some hundred margins, kept within the range (where `D` is known to be monotone).
    let (_, margin) = f(u_star);
    let r_star = (r0 + (r1 - r0) * s).abs().max(ra);
    let step = 200.0 * margin / (r_star * ((r1 - r0) / span).abs());
    let (ua, ub) = ((u_star - step).max(u0), (u_star + step).min(u1));
    let ((fa, ea), (fb, eb)) = (f(ua), f(ub));
    if !(fa.abs() > ea && fb.abs() > eb && (fa > 0.0) != (fb > 0.0)) {
        return None;
    }
    // The crossing's `w` where the ray meets the normal plane at `u*` (the range is oblique to
    // the ray: well conditioned), not `Z - sqrt(D)` (`D` is known there only to its rounding,
    // and its square root is off by `sqrt(err_D)`).
    Some(Some((u_star, w_at(axis.point(u_star), axis.d1(u_star)))))
}

/// A round fiber's radius at the ends of the `u` range `[u0, u1]`; `None` unless the rule
/// scales uniformly. (The callers build the range's [`Polys`] in place: returned through a
/// call, the 300-byte value was copied once more, 0.35% of a camera ray's instructions.)
fn range_radius<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    (u0, u1): (f64, f64),
) -> Option<[f64; 2]> {
    let [r0, r1] = cyl.sweep.uniform_scale()?;
    Some([r0 + (r1 - r0) * u0, r0 + (r1 - r0) * u1])
}

/// Whether the local ray `o + w d` certainly enters the tube nowhere beyond `w_min` on the `u`
/// range `[u0, u1]`: [`no_entry_after`] on the whole range at once, without the prefilter's
/// search for the ranges near the ray. For a ray that leaves the fiber's surface (a renderer's
/// spawned ray) the range's only dip lies about the point it leaves, and [`entered_behind`]
/// shows that entry behind it, inward and outward rays alike; `near_u`, the `u` of the point
/// left, is its first candidate witness (the ray's line enters the ball about the axis there
/// behind the origin). The caller makes sure the fiber is a tube (constant radius, no
/// folding).
pub(crate) fn range_enters_nowhere_after<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    o: DVec3,
    d: DVec3,
    (u0, u1): (f64, f64),
    w_min: f64,
    near_u: Option<f64>,
) -> bool {
    let Some(r) = range_radius(cyl, (u0, u1)) else {
        return false;
    };
    // Only `Z` and `D`: the rest of the range's `Polys` would be half the work.
    let [x, y, z] = ray_coords(cyl.axis.segment(u0, u1).points, o, d);
    let (disc, err_disc) = discriminant(&x, &y, r, (0.0, 0.0));
    let k = Balls {
        z: &z,
        disc: &disc,
        err_disc,
    };
    let near = near_u.map(|u| (u - u0) / (u1 - u0));
    no_entry_after(k, w_min * d.length(), r[0].abs().max(r[1].abs()), near)
}

/// Whether no crossing of the `-` branch (`z = Z - sqrt(D)`) lies beyond `z_min` on a tube
/// (constant radius, no folding), where the `-` branch holds every entry (`normal . d =
/// -sqrt(D) |d| / r`): [`entered_behind`] (a ray that leaves a fiber's surface, into it or
/// out of it: its line enters a ball about the axis behind the origin; tried first, as it
/// costs one witness search where the other halves cells) or [`nothing_ahead`]. `r_max`
/// is the radius; `near`, where known, a likely witness for [`entered_behind`].
fn no_entry_after(k: Balls, z_min: f64, r_max: f64, near: Option<f64>) -> bool {
    // `Z`'s rounding and a relative margin; where `D` may be at its rounding level, the margin
    // of [`RootCell::w_range`] for a crossing there.
    let relative = relative_margin(z_min, r_max) + SLACK * k.z.magnitude();
    entered_behind(k, z_min - relative, r_max, near)
        || nothing_ahead(k, z_min - relative - k.tangent_margin())
}

/// Whether `Z <= z_below` wherever `D >= 0` on the range, so that every `-` crossing
/// `Z - sqrt(D)` lies at or behind it: on Bernstein cells of `Z` and `D` (each cell's `Z`
/// coefficients below `z_below`, or its `D` coefficients below zero beyond their rounding
/// bound), halving at most [`CLEAR_BUDGET`] cells.
fn nothing_ahead(k: Balls, z_below: f64) -> bool {
    // All of the range ahead (a ray from afar): only a range without crossings would pass,
    // and the isolation clears those as fast.
    if k.z.range().0 >= z_below {
        return false;
    }
    let mut stack: ArrayVec<(Bernstein<4>, B7), 8> = ArrayVec::new();
    stack.push((*k.z, *k.disc));
    let mut cells = 0;
    while let Some((z, disc)) = stack.pop() {
        if z.range().1 < z_below || disc.range().1 < -k.err_disc {
            continue;
        }
        // An end of the cell ahead where the ray is within reach of a ball: give up early.
        let ahead = |z: f64, disc: f64| z >= z_below && disc > 0.0;
        if ahead(z.0[0], disc.0[0]) || ahead(z.0[3], disc.0[6]) {
            return false;
        }
        cells += 1;
        if cells > CLEAR_BUDGET || stack.len() + 2 > stack.capacity() {
            return false;
        }
        let ((z0, z1), (d0, d1)) = (z.split(0.5), disc.split(0.5));
        stack.push((z1, d1));
        stack.push((z0, d0));
    }
    true
}

/// Whether the range's only entry lies behind `z_below`, for a ray whose line enters the tube
/// behind that point (a ray that leaves its fiber's surface, into the fiber or out of it).
///
/// - `D > 0` on one interval of the range at most: `D`'s coefficients, of signs their rounding
///   bound cannot flip, change sign at most once, or twice starting negative.
/// - On it the critical points of `z_-(s) = Z - sqrt(D)` (where the ray enters the ball about
///   `a(s)`) are the `-` roots (`z_-' = -H- / sqrt(D)` where `r` is constant), and each is a
///   local minimum: where a neighbouring `s` has a smaller `z_-`, the ray's point at the
///   critical value lies inside that ball, inside the solid, though on the circle of radius
///   `r` in the normal plane: on the surface, which for a tube that does not fold (nor pass
///   through itself) is its boundary. So `z_-` has no local maximum there, and at most one
///   `-` root, where it is least.
/// - A witness `s` where `D > 0` and `z_-(s) < z_below` (the ray's line enters the ball about
///   `a(s)` behind `z_below`): then the least `z_-` lies behind `z_below` too. It is sought where the
///   squared distance `E(s) = |a(s) - q|^2` from the ray's point `q` at `z_below` is least
///   (there, if anywhere, `q` lies inside a ball), by Newton's method on
///   `E' / 2 = P + (Z - z) Z'` from the best of five samples (`E = r^2 - D + (Z - z)^2`), and
///   taken with `D` and `Z` widened by their rounding bounds; `near` (in `[0, 1]`), where the
///   caller knows a likely witness, is tried first. (The entry itself may be nearly
///   tangent, `D` at its rounding level there: the polish of the full isolation could then
///   report it up to `sqrt(err_D)` late, past `tmin`, a hit that is not there. The witness
///   shows the exact entry behind `z_below`, which is the answer given.)
fn entered_behind(k: Balls, z_below: f64, r_max: f64, near: Option<f64>) -> bool {
    // Only a point within `r` of the axis along the ray can be inside a ball.
    let (z_lo, z_hi) = k.z.range();
    if z_below <= z_lo - r_max || z_below >= z_hi + r_max {
        return false;
    }
    let c = &k.disc.0;
    if c.iter().any(|x| x.abs() <= k.err_disc) {
        return false;
    }
    let changes = sign_changes(c);
    if !(changes <= 1 || (changes == 2 && c[0] < 0.0)) {
        return false;
    }
    // The ray's line enters the ball about `a(s)` behind `z_below`, by `D` and `Z` widened.
    let witness = |s: f64| {
        let disc = k.disc.eval(s) - 2.0 * k.err_disc;
        disc > 0.0 && k.z.eval(s) - disc.sqrt() < z_below
    };
    if near.is_some_and(|s| (0.0..=1.0).contains(&s) && witness(s)) {
        return true;
    }
    let excess = |s: f64| {
        let z = k.z.eval(s) - z_below;
        z * z - k.disc.eval(s)
    };
    let mut s = [0.0, 0.25, 0.5, 0.75, 1.0]
        .into_iter()
        .map(|s| (excess(s), s))
        .fold((f64::INFINITY, 0.5), |a, b| if b.0 < a.0 { b } else { a })
        .1;
    // `D'` and `Z'`; on a tube `P = X X' + Y Y' = -D' / 2`.
    let (disc_s, z_s): (B6, B3) = (k.disc.derivative(), k.z.derivative());
    for _ in 0..WITNESS_STEPS {
        let (d_s, d_ss) = disc_s.eval_with_derivative(s);
        let (p, p_s) = (-0.5 * d_s, -0.5 * d_ss);
        let (z_s, z_ss) = z_s.eval_with_derivative(s);
        let z = k.z.eval(s) - z_below;
        let slope = p + z * z_s;
        let curve = p_s + z_s * z_s + z * z_ss;
        if !(curve > 0.0) {
            break;
        }
        s = (s - slope / curve).clamp(0.0, 1.0);
    }
    witness(s)
}

/// Newton steps [`entered_behind`] takes toward its witness.
const WITNESS_STEPS: usize = 4;

/// Most cells [`nothing_ahead`] halves before it leaves a range to the full isolation.
const CLEAR_BUDGET: usize = 12;

/// Records the roots `(s, sign)` of the range `[u0, u1]` as side roots; where `local` is given
/// (a whole tube's range, [`whole_tube`]), each [`refined`] in space.
fn push_all<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    (d, local): (DVec3, Option<Refine>),
    k: &Polys,
    (u0, u1): (f64, f64),
    roots: &[(f64, f64)],
    out: &mut SideRoots,
) {
    let len = d.length();
    for &(s, sign) in roots {
        // The crossing of the sphere: z = Z ± sqrt(D) along d / |d| from o.
        let w = (k.z.eval(s) + sign * k.disc.eval(s).max(0.0).sqrt()) / len;
        let u = u0 + (u1 - u0) * s;
        let (u, w) = match local {
            Some(refine) => refined(cyl, (refine, d), k.radius[0], (u, w)),
            None => (u, w),
        };
        push(cyl, d, u, w, out);
    }
}

/// The roots on `[a, b]` of both branches as `(s, sign)`, each branch on each stretch where
/// `D >= 0` (between the roots of `D`) by [`branch_roots`]: the method for any angle, and
/// whether [`branch_roots`] resolved every cell and kept every root (not a certificate: a
/// stretch is taken or skipped by `D`'s value at its middle).
fn stretch_roots(k: &Polys, a: f64, b: f64) -> (ArrayVec<(f64, f64), 16>, bool) {
    let mut ends: ArrayVec<f64, 18> = ArrayVec::new();
    ends.push(a);
    let mut zs = ArrayVec::new();
    k.disc
        .roots(&k.disc_s(), k.err_disc, MIN_WIDTH, BUDGET, &mut zs);
    ends.extend(zs.into_iter().filter(|&z| z > a && z < b));
    ends.push(b);
    let mut found = ArrayVec::new();
    let mut sure = true;
    for w in ends.windows(2) {
        let (a, b) = (w[0], w[1]);
        if !(b > a) || !(k.disc.eval(0.5 * (a + b)) > 0.0) {
            continue;
        }
        for sign in [-1.0, 1.0] {
            let mut ss = ArrayVec::new();
            sure &= branch_roots(k, a, b, sign, &mut ss);
            for s in ss {
                if found.try_push((s, sign)).is_err() {
                    return (found, false);
                }
            }
        }
    }
    (found, sure)
}

/// Records the hit at `(u, w)`, unless it repeats one (both branches meet where `D = 0`).
fn push<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    d: DVec3,
    u: f64,
    w: f64,
    out: &mut SideRoots,
) {
    if !w.is_finite() {
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
    // The section angle is left to the hit, which takes it and the normal from one frame
    // ([`section_angle`]).
    super::push_side_root(out, SideRoot { u, w, v: f64::NAN });
}

/// The section angle of a side hit at `u` whose offset from the axis is `e`, with `f` the
/// frame at `u`: the offset in the frame, through the rule's inverse.
pub(crate) fn section_angle<C: CrossSection, S: SweepRule>(
    cyl: &GeneralizedCylinder<C, S>,
    u: f64,
    e: DVec3,
    f: &Frame,
) -> f64 {
    let phi = cyl
        .sweep
        .inverse(u, V2::new(f.n.dot(e), f.b.dot(e)))
        .value();
    crate::section::angle(DVec2::new(phi.x, phi.y))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::Lcg;

    /// The ray's point `z = Z ± sqrt(D)` of the root `(s, ±1)`.
    fn ray_point(k: &Polys, (s, sign): (f64, f64)) -> f64 {
        k.z.eval(s) + sign * k.disc.eval(s).max(0.0).sqrt()
    }

    /// A cubic axis from `shift` to `shift + (1, 0, 0)`, its control points a third apart
    /// along `x` and bent across by up to `bend`.
    fn bent_axis(rng: &mut Lcg, shift: DVec3, bend: f64) -> crate::curve::CubicBezier {
        crate::curve::CubicBezier::new(std::array::from_fn(|j| {
            shift
                + DVec3::new(
                    j as f64 / 3.0,
                    rng.range(-bend, bend),
                    rng.range(-bend, bend),
                )
        }))
    }

    /// A round fiber of the tests.
    type RoundFiber = GeneralizedCylinder<crate::section::Section, crate::sweep::HairSweep>;

    /// The round fiber about `curve` whose radius runs from `r0` to `r1`, unless it is refused
    /// or may fold.
    fn round_fiber(curve: crate::curve::CubicBezier, [r0, r1]: [f64; 2]) -> Option<RoundFiber> {
        let sweep = crate::sweep::HairSweep {
            major: [r0, r1],
            minor: [r0, r1],
            rotation: [0.0, 0.0],
        };
        let section = crate::section::Section::default();
        GeneralizedCylinder::new(curve, section, sweep, true, None)
            .ok()
            .filter(|c| !c.may_fold())
    }

    /// At `s` on `curve`: the unit tangent `t`, a unit vector across it in a random direction,
    /// and `t` times that.
    fn across_at(
        rng: &mut Lcg,
        curve: &crate::curve::CubicBezier,
        s: f64,
    ) -> (DVec3, DVec3, DVec3) {
        let t = curve.d1(s).normalize();
        let across = t.any_orthonormal_vector();
        let across =
            (across * rng.range(-1.0, 1.0) + t.cross(across) * rng.range(-1.0, 1.0)).normalize();
        (t, across, t.cross(across))
    }

    /// The oracle of the tests below: the branch-by-branch subdivision's roots on the whole
    /// range, ascending, a grazing root (found on both branches at one point of the ray) kept
    /// once. (An entry and an exit at nearly one `s`, as a ray nearly in the normal plane has
    /// them, are two roots: their points `z = Z ± sqrt(D)` differ.)
    fn subdivision_roots(k: &Polys) -> Vec<(f64, f64)> {
        let mut roots = stretch_roots(k, 0.0, 1.0).0.to_vec();
        roots.sort_by(|a, b| a.0.total_cmp(&b.0));
        let z = |root| ray_point(k, root);
        let r_max = k.radius[0].abs().max(k.radius[1].abs());
        roots.dedup_by(|a, b| {
            (a.0 - b.0).abs() < 1e-12
                && (z(*a) - z(*b)).abs() <= k.tangent_margin() + relative_margin(z(*b), r_max)
        });
        roots
    }

    /// Where the product method settles a range, it finds the same roots on the same branches
    /// as the branch-by-branch subdivision: curved round fibers of radii 1e-4 to 1e-1 of their
    /// length, on ranges about a point near the axis (as the prefilter gives them), hit from
    /// random directions (oblique ones mostly, where the product applies).
    #[test]
    fn product_roots_agree_with_stretch_roots() {
        let mut rng = Lcg(17);
        let (mut settled, mut roots) = (0, 0);
        for i in 0..3000 {
            let axis: [DVec3; 4] = std::array::from_fn(|j| {
                DVec3::new(j as f64 / 3.0, rng.range(-0.3, 0.3), rng.range(-0.3, 0.3))
            });
            let r0 = 10f64.powf(rng.range(-4.0, -1.0));
            let r = [r0, r0 * rng.range(0.5, 1.5)];
            // A ray through a point near the axis, from a random direction.
            let s = rng.range(0.0, 1.0);
            let v = 1.0 - s;
            let p = axis[0] * v * v * v
                + axis[1] * 3.0 * s * v * v
                + axis[2] * 3.0 * s * s * v
                + axis[3] * s * s * s;
            let d = DVec3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            );
            let off = DVec3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            ) * (1.5 * r0);
            let o = p + off - d * rng.range(1.0, 3.0);
            // On a range about the point, as the prefilter gives them (tens of radii wide).
            let h = 30.0 * r0;
            let (u0, u1) = ((s - h).max(0.0), (s + h).min(1.0));
            let piece = crate::curve::CubicBezier::new(axis).segment(u0, u1);
            let k = Polys::new(piece.points, r, o, d, 0.0);
            let Some(fast) = product_roots(&k) else {
                continue;
            };
            settled += 1;
            let slow = subdivision_roots(&k);
            assert_eq!(
                fast.len(),
                slow.len(),
                "case {i}: {fast:?} against {slow:?}"
            );
            for (f, s) in fast.iter().zip(&slow) {
                assert!(
                    (f.0 - s.0).abs() < 1e-12 && f.1 == s.1,
                    "case {i}: {f:?} against {s:?}"
                );
            }
            roots += fast.len();
        }
        assert!(
            settled > 2000,
            "the product should settle most oblique cases: {settled}"
        );
        assert!(roots > 1000, "the cases should hit: {roots} roots");
    }

    /// A tapered tube can hold a crossing where `P` keeps one sign on the range (`D` rises
    /// with the radius, then falls with the distance): a straight cone whose radius grows from
    /// 0.01 to 0.03, and a ray nearly along it whose closest approach lies before the range.
    /// [`tube_cells`] must not certify a miss there (nor, as `P`'s sign rules out its split,
    /// cells); a miss is certified only where `D' = 2 (r rho - P)` keeps one sign.
    #[test]
    fn tube_cells_keep_a_tapered_crossing_beyond_the_closest_approach() {
        let axis = [0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0].map(|x| DVec3::new(x, 0.0, 0.0));
        // Squared distance h^2 + (s - s_c)^2 sin^2 with s_c = -0.2: D < 0 at both ends of the
        // range, about 2.8e-5 at s = 0.4, and P > 0 on all of it.
        let d = DVec3::new(1.0, 0.0, 6e-4f64.sqrt());
        let o = DVec3::new(-0.2, 8e-5f64.sqrt(), 0.0) - 0.5 * d;
        for (r, crossings) in [([0.01, 0.03], 2), ([0.01, 0.01], 0)] {
            let k = Polys::new(axis, r, o, d, 0.0);
            assert!(k.disc.0[0] < 0.0 && k.disc.0[6] < 0.0 && k.p.0.iter().all(|&c| c > 0.0));
            let slow = subdivision_roots(&k);
            assert_eq!(slow.len(), crossings, "radii {r:?}: {slow:?}");
            let mut cells = ArrayVec::new();
            if tube_cells(&k, false, &mut cells).is_some() {
                let mut fast = ArrayVec::new();
                settle_all(&k, &cells, &mut fast).expect("certified cells settle");
                assert_eq!(fast.len(), crossings, "radii {r:?}: {cells:?}");
            }
        }
    }

    /// Where [`tube_cells`] certifies a range of a tube that does not fold, its cells' roots are
    /// the branch-by-branch subdivision's, on the same branches: curved fibers of radii 1e-6 to
    /// 1e-1 of their length, constant or tapered (to between a third and three times the
    /// radius), rays through points near the axis, grazing it (1e-9 to 1e-2 of the radius
    /// inside or outside), tilted from its normal plane by 1e-15 to 1 rad, exactly
    /// perpendicular, nearly along it (1e-8 to 1e-1 rad off, at 1e-12 to 1e-2 of the radius from
    /// the surface), or from any direction, at the origin and at 1e4; on ranges about the point,
    /// beside it, or ending within three radii of it (one crossing on the range, the other
    /// beyond an end inside a ball about the axis). Some of the misses are certified too (no
    /// cells); the rest of the ranges are left to the product method.
    #[test]
    fn tube_cells_agree_with_stretch_roots() {
        let mut rng = Lcg(23);
        let (mut hits, mut misses, mut left, mut roots) = (0, 0, 0, 0);
        let (mut tapered_hits, mut along_hits, mut unsettled, mut halves) = (0, 0, 0, 0);
        for i in 0..6000 {
            let shift = if i % 3 == 0 {
                DVec3::splat(1e4)
            } else {
                DVec3::ZERO
            };
            let curve = bent_axis(&mut rng, shift, [0.05, 0.2, 0.4][i % 3]);
            let r0 = 10f64.powf(rng.range(-6.0, -1.0));
            // Half the fibers tapered, to between a third and three times the radius.
            let tapered = (i / 5) % 2 == 1;
            let r1 = if tapered {
                r0 * 10f64.powf(rng.range(-0.5, 0.5))
            } else {
                r0
            };
            let radius = |u: f64| r0 + (r1 - r0) * u;
            let Some(cyl) = round_fiber(curve, [r0, r1]) else {
                continue;
            };
            let s = rng.range(0.0, 1.0);
            let rs = radius(s);
            let (t, across, side) = across_at(&mut rng, &curve, s);
            let (o, d) = match i % 8 {
                // Across the axis, tilted by 10^-15 .. 1 rad, or exactly perpendicular.
                0 | 1 | 4 | 5 => {
                    let tilt = if i % 8 == 0 {
                        0.0
                    } else {
                        10f64.powf(rng.range(-15.0, 0.0))
                    };
                    let d = (across + tilt * t).normalize();
                    let p = curve.point(s) + side * (rs * rng.range(-1.2, 1.2));
                    (p - d * rng.range(0.5, 3.0), d)
                }
                // Grazing: past the axis at the radius times 1 -+ 10^-9 .. 10^-2.
                2 | 6 => {
                    let g = 10f64.powf(rng.range(-9.0, -2.0)) * if i % 8 < 4 { 1.0 } else { -1.0 };
                    let d = (across + rng.range(-0.5, 0.5) * t).normalize();
                    let p = curve.point(s) + d.cross(t).normalize() * rs * (1.0 + g);
                    (p - d * rng.range(0.5, 3.0), d)
                }
                // Nearly along the axis (10^-8 .. 10^-1 rad off it), at the radius times 1 -+
                // 10^-12 .. 10^-2 from it: where a tapered tube's crossings have `D` near 0.
                7 => {
                    let g =
                        10f64.powf(rng.range(-12.0, -2.0)) * if i % 16 < 8 { 1.0 } else { -1.0 };
                    let angle = 10f64.powf(rng.range(-8.0, -1.0));
                    let d = (t + angle * across).normalize();
                    let p = curve.point(s) + side * rs * (1.0 + g);
                    (p - d * (30.0 * rs), d)
                }
                _ => {
                    let d = DVec3::new(
                        rng.range(-1.0, 1.0),
                        rng.range(-1.0, 1.0),
                        rng.range(-1.0, 1.0),
                    )
                    .normalize();
                    let p = curve.point(s) + across * (rs * rng.range(0.0, 1.5));
                    (p - d * rng.range(0.5, 3.0), d)
                }
            };
            // On a range about the point, as the prefilter gives them (tens of radii wide), one
            // beside it (a fifth of the cases: mostly misses), or one that ends within three
            // radii of it (a fifth: the end often inside a ball about the axis, and one
            // crossing beyond it), in the cylinder's own coordinates.
            let h = 30.0 * r0;
            let near = s + rng.range(-3.0, 3.0) * r0 / curve.d1(s).length();
            let (u0, u1) = match i % 5 {
                4 => ((s + 0.5 * h).min(1.0 - h), (s + 2.0 * h).min(1.0)),
                3 if i % 2 == 0 => (near.min(1.0 - h).max(0.0), (s + 2.0 * h).min(1.0)),
                3 => ((s - 2.0 * h).max(0.0), near.max(h).min(1.0)),
                _ => ((s - h).max(0.0), (s + h).min(1.0)),
            };
            let piece = cyl.axis.segment(u0, u1);
            let o = o - cyl.origin;
            let k = Polys::new(piece.points, [radius(u0), radius(u1)], o, d, 0.0);
            let mut cells = ArrayVec::new();
            if tube_cells(&k, true, &mut cells).is_none() {
                left += 1;
                continue;
            }
            let mut fast: Vec<(f64, f64)> = Vec::new();
            // Each cell as the query polishes it ([`Deferred::polish`]).
            for cell in &cells {
                let mut one = ArrayVec::new();
                if settle(&k, cell, &mut one).is_none() {
                    unsettled += 1;
                    one = stretch_roots(&k, cell.s0, cell.s1).0;
                }
                fast.extend(one);
            }
            fast.sort_by(|a, b| a.0.total_cmp(&b.0));
            let slow = subdivision_roots(&k);
            assert_eq!(
                fast.len(),
                slow.len(),
                "case {i}: {fast:?} against {slow:?}"
            );
            // The same crossing: the same branch, and the ray's point `z = Z +- sqrt(D)` within
            // the code's relative margin (a grazing crossing's `s` is ill-conditioned; its `z` is
            // not).
            let z = |root| ray_point(&k, root);
            for (&f, &s) in fast.iter().zip(&slow) {
                let (zf, zs) = (z(f), z(s));
                assert!(
                    f.1 == s.1
                        && (f.0 - s.0).abs() < 1e-9
                        && (zf - zs).abs() <= relative_margin(zs, r0),
                    "case {i}: {f:?} (z {zf}) against {s:?} (z {zs})"
                );
            }
            if fast.is_empty() {
                misses += 1;
            } else if fast.len() == 1 {
                // One crossing on the range, the other beyond an end that lies inside a ball.
                halves += 1;
            } else {
                hits += 1;
                tapered_hits += usize::from(tapered);
                along_hits += usize::from(i % 8 == 7);
            }
            roots += fast.len();
        }
        assert!(
            tapered_hits > 400,
            "certified crossings of tapered tubes: {tapered_hits}"
        );
        assert!(
            along_hits > 30,
            "certified crossings nearly along the axis: {along_hits}"
        );
        assert!(hits > 1000, "certified crossings: {hits}");
        assert!(misses > 500, "certified misses: {misses}");
        assert!(left > 300, "ranges left to the product method: {left}");
        assert!(
            halves > 20,
            "crossings with the other beyond an end: {halves}"
        );
        assert!(
            roots == 2 * hits + halves,
            "two roots a crossing: {roots} {hits} {halves}"
        );
        // Cells whose polish cannot verify a nearly tangent root (`D` at its rounding level, as
        // nearly along the axis) fall back to the subdivision: rarely.
        assert!(
            unsettled * 20 < roots,
            "unsettled cells: {unsettled} of {roots}"
        );
    }

    /// The crossing `(u, w)` of the local ray `o + w d` with the tube of radius `r` about
    /// `curve` near `(u, w)`, in double-double: Newton's method on `F1 = a'.e`, `F2 = |e|^2 -
    /// r^2` (`e = o + w d - a(u)`) with the residuals in double-double and the steps in `f64`
    /// (the residuals set the accuracy), from the crossing given.
    fn crossing_dd(
        curve: &[DVec3; 4],
        (o, d): (DVec3, DVec3),
        r: f64,
        (u, w): (f64, f64),
    ) -> (f64, f64) {
        use crate::test_rng::Dd;
        let neg = |x: Dd| Dd(-x.0, -x.1);
        let (mut u, mut w) = (Dd::of(u), Dd::of(w));
        for _ in 0..4 {
            let v = Dd::of(1.0).add(neg(u));
            let (uu, vv) = (u.mul(u), v.mul(v));
            let three = Dd::of(3.0);
            // Bernstein weights of a, a' (over the hodograph) and a''.
            let wp = [
                vv.mul(v),
                three.mul(vv).mul(u),
                three.mul(v).mul(uu),
                uu.mul(u),
            ];
            let wd = [vv, Dd::of(2.0).mul(v).mul(u), uu];
            let h: [DVec3; 3] = std::array::from_fn(|i| 3.0 * (curve[i + 1] - curve[i]));
            let h2: [DVec3; 2] = std::array::from_fn(|i| h[i + 1] - h[i]);
            let comb = |pts: &[DVec3], ws: &[Dd], k: usize| {
                pts.iter()
                    .zip(ws)
                    .fold(Dd::of(0.0), |acc, (p, &wt)| acc.add(Dd::of(p[k]).mul(wt)))
            };
            let mut e = [Dd::of(0.0); 3];
            let (mut a1, mut a2) = ([0.0; 3], [0.0; 3]);
            let mut a1d = [Dd::of(0.0); 3];
            for k in 0..3 {
                let a = comb(curve, &wp, k);
                e[k] = Dd::of(o[k]).add(w.mul(Dd::of(d[k]))).add(neg(a));
                a1d[k] = comb(&h, &wd, k);
                a1[k] = a1d[k].value();
                a2[k] = 2.0 * comb(&h2, &[v, u], k).value();
            }
            let f1 = (0..3)
                .fold(Dd::of(0.0), |acc, k| acc.add(a1d[k].mul(e[k])))
                .value();
            let f2 = (0..3)
                .fold(Dd::of(-r).mul(Dd::of(r)), |acc, k| acc.add(e[k].mul(e[k])))
                .value();
            let ev = DVec3::new(e[0].value(), e[1].value(), e[2].value());
            let (a1, a2) = (DVec3::from_array(a1), DVec3::from_array(a2));
            let (j11, j12, j21, j22) = (
                a2.dot(ev) - a1.length_squared(),
                a1.dot(d),
                -2.0 * f1,
                2.0 * ev.dot(d),
            );
            let det = j11 * j22 - j12 * j21;
            u = u.add(Dd::of(-(f1 * j22 - j12 * f2) / det));
            w = w.add(Dd::of(-(j11 * f2 - j21 * f1) / det));
        }
        (u.value(), w.value())
    }

    /// Case `i` of the whole-tube tests: a round tube about a bent axis ([`bent_axis`]; radius
    /// `1e-6` to `0.3` of its length, at the origin and `1e4` from it) and a local ray `(o, d)`
    /// across it (tilted from its normal plane down to `1e-12`, or from any direction, every
    /// fourth case), entering between the axis and `0.98` of the radius from it, every fifth
    /// near an end; with the radius. `None` where the fiber is refused or may fold.
    fn whole_tube_case(rng: &mut Lcg, i: usize) -> Option<(RoundFiber, (DVec3, DVec3), f64)> {
        let shift = if i.is_multiple_of(2) {
            DVec3::splat(1e4)
        } else {
            DVec3::ZERO
        };
        let curve = bent_axis(rng, shift, [0.05, 0.2, 0.4][i % 3]);
        let r = 10f64.powf(rng.range(-6.0, -0.5));
        let cyl = round_fiber(curve, [r, r])?;
        // Every fifth ray passes within a hundredth of the axis' length of an end (through
        // the ball about its end point, often: one crossing or none on this fiber).
        let s = match i % 5 {
            2 => rng.range(-0.01, 0.01) + if i.is_multiple_of(2) { 0.0 } else { 1.0 },
            _ => rng.range(0.05, 0.95),
        };
        let (t, across, side) = across_at(rng, &curve, s);
        let d = if i % 4 == 3 {
            rng.unit()
        } else {
            (across + 10f64.powf(rng.range(-12.0, 0.0)) * t).normalize()
        };
        let p = curve.point(s) + side * (r * rng.range(-0.98, 0.98));
        let ray = crate::Ray {
            origin: p - d * rng.range(0.5, 3.0),
            dir: d * rng.range(0.5, 2.0),
        };
        let (o, _) = cyl.local_ray(&ray, &cyl.bounds());
        Some((cyl, (o, ray.dir), r))
    }

    /// [`tube_window`] holds every `u` whose normal-plane point of the ray lies inside the
    /// tube, and little more; where it reports a miss, none does. Brute force against the
    /// definition: `e(u) = o + w(u) d - a(u)`, `w(u) = a'.(a - o) / (a'.d)`, sampled densely
    /// and at the closest approach (golden section about the best sample), and the inside
    /// set's ends by bisection on `|e|^2 - r^2`. The tubes and rays of [`whole_tube_case`]
    /// (radii `1e-6` to `0.3` of the length, axes at the origin and at `1e4`, rays tilted
    /// `1e-12` to 1 from the normal plane, through the ends' balls), every third one moved
    /// to pass at `r (1 -+ 10^-k)` from the axis, `k` up to 9 (grazes, inside and out). Half
    /// on the whole axis, half on a range about the closest approach, as the prefilter's are,
    /// whose ends fall between `1e-2` and `1e2` times the inside set's half-width from it:
    /// often inside that set (one crossing on the range, or none).
    #[test]
    fn tube_windows_hold_the_tubes_inside() {
        use super::super::U_MARGIN;
        let mut rng = Lcg(38);
        let whole = (-U_MARGIN, 1.0 + U_MARGIN);
        let (mut windows, mut misses, mut refused, mut grazes) = (0, 0, 0, 0);
        // Windows that reach an end of their range inside the tube.
        let mut end_inside = 0;
        // Most rays nearly in a normal plane are refused (`a'.d` changes sign on the axis).
        for i in 0..9000 {
            let Some((cyl, (o, d), r)) = whole_tube_case(&mut rng, i) else {
                continue;
            };
            let axis = cyl.axis;
            // The ray's point in the normal plane at `u`, less the axis point.
            let offset = |o: DVec3, u: f64| {
                let (a, a1) = (axis.point(u), axis.d1(u));
                let w = a1.dot(a - o) / a1.dot(d);
                o + w * d - a
            };
            // A graze: the ray moved across so that its closest approach to the axis point
            // it aimed at is `r (1 -+ 10^-k)`.
            let o = if i % 3 == 1 {
                let s = rng.range(0.1, 0.9);
                let e = offset(o, s);
                let k = 10f64.powf(-rng.range(1.0, 9.0));
                let depth = if rng.range(0.0, 1.0) < 0.5 {
                    1.0 - k
                } else {
                    1.0 + k
                };
                grazes += 1;
                o + e.normalize_or_zero() * (r * depth - e.length())
            } else {
                o
            };
            let e_at = |u: f64| offset(o, u);
            // What `|e|`'s rounding may hide: a few units of the coordinates' size.
            let size = axis
                .points
                .iter()
                .fold(o.length(), |m, p| m.max(p.length()));
            let err = 64.0 * f64::EPSILON * (size + r);
            let surely_inside = |u: f64| e_at(u).length() < r - err;
            let n = 4000;
            let samples_on = |(lo, hi): (f64, f64)| -> Vec<f64> {
                (0..=n)
                    .map(|j| (lo + (hi - lo) * j as f64 / n as f64).min(hi))
                    .collect()
            };
            // The closest approach on `[lo, hi]`: the best of the samples, then golden section
            // on its neighbourhood.
            let closest_on = |(lo, hi): (f64, f64), samples: &[f64]| {
                let best = samples
                    .iter()
                    .copied()
                    .min_by(|&x, &y| e_at(x).length().total_cmp(&e_at(y).length()))
                    .unwrap();
                let step = (hi - lo) / n as f64;
                let (mut x0, mut x1) = ((best - step).max(lo), (best + step).min(hi));
                for _ in 0..80 {
                    let (m0, m1) = (x0 + 0.382 * (x1 - x0), x0 + 0.618 * (x1 - x0));
                    if e_at(m0).length() < e_at(m1).length() {
                        x1 = m1;
                    } else {
                        x0 = m0;
                    }
                }
                0.5 * (x0 + x1)
            };
            // The inside set's end from a point inside towards `outside` (or that point, if it
            // is inside too), by bisection.
            let crossing = |mut inside: f64, mut outside: f64| {
                for _ in 0..200 {
                    let m = 0.5 * (inside + outside);
                    if m == inside || m == outside {
                        break;
                    }
                    if e_at(m).length_squared() < r * r {
                        inside = m;
                    } else {
                        outside = m;
                    }
                }
                inside
            };
            let (lo, hi) = if i % 2 == 0 {
                whole
            } else {
                let closest = closest_on(whole, &samples_on(whole));
                let mut width = |end: f64| {
                    let far = if e_at(closest).length_squared() < r * r {
                        crossing(closest, end)
                    } else {
                        end
                    };
                    (far - closest).abs().max(1e-12) * 10f64.powf(rng.range(-2.0, 2.0))
                };
                let (below, above) = (width(whole.0), width(whole.1));
                (
                    (closest - below).max(whole.0),
                    (closest + above).min(whole.1),
                )
            };
            let samples = samples_on((lo, hi));
            let closest = closest_on((lo, hi), &samples);
            let Some(window) = tube_window(&cyl, o, d, (lo, hi), r) else {
                refused += 1;
                continue;
            };
            let Some((a, b)) = window else {
                misses += 1;
                for &u in samples.iter().chain([&closest]) {
                    assert!(
                        !surely_inside(u),
                        "case {i}: a miss, but u = {u} is {} inside the tube of radius {r}",
                        r - e_at(u).length()
                    );
                }
                continue;
            };
            windows += 1;
            if a == lo || b == hi {
                end_inside += 1;
            }
            assert!(lo <= a && a < b && b <= hi, "case {i}: window ({a}, {b})");
            for &u in samples.iter().chain([&closest]) {
                assert!(
                    !surely_inside(u) || (a <= u && u <= b),
                    "case {i}: u = {u}, inside the tube, outside the window ({a}, {b})"
                );
            }
            // The inside set's ends by bisection from the closest approach: in the window, and
            // no farther from its ends than its margin (both up to the ends' rounding).
            if !surely_inside(closest) {
                continue;
            }
            let (ua, ub) = (crossing(closest, lo), crossing(closest, hi));
            // A bracket reaches `WINDOW_BRACKET` of the crossing's distance from the nearer
            // end of its cell (the closest approach, mostly: half the inside set) beyond the
            // crossing, or `SPACE_BRACKET` of the range where the crossing was solved for.
            let slack = 2.0 * WINDOW_BRACKET * (ub - ua) + 2.0 * SPACE_BRACKET * (hi - lo) + 1e-12;
            let moved = |u: f64| {
                // How far `u` may be from the crossing for the bisection's `|e|` to be off by
                // `err`: `err` over `|e|`'s rate there.
                let h = 1e-7;
                let rate = (e_at(u + h).length() - e_at(u - h).length()).abs() / (2.0 * h);
                err / rate
            };
            assert!(
                a <= ua + moved(ua) && b >= ub - moved(ub),
                "case {i}: window ({a}, {b}) does not hold the inside set ({ua}, {ub})"
            );
            assert!(
                a >= ua - slack - moved(ua) && b <= ub + slack + moved(ub),
                "case {i}: window ({a}, {b}) against the inside set ({ua}, {ub})"
            );
        }
        println!(
            "windows {windows} ({end_inside} reaching an end), misses {misses}, \
             refused {refused}, grazes {grazes}"
        );
        assert!(
            windows > 700 && end_inside > 300 && misses > 80 && grazes > 1500,
            "windows {windows} ({end_inside} reaching an end), misses {misses}, \
             refused {refused}, grazes {grazes}"
        );
    }

    /// [`solved_in_space`] settles nearly every whole tube's cell, and where it does its
    /// crossing is the one the polish on `H` and [`refined`] find (within a few units of the
    /// coordinates' rounding over the cosine of incidence, both as close to the exact crossing:
    /// [`whole_tube_crossings_are_as_close_as_the_narrow_ranges`]), on the same tubes and rays.
    #[test]
    fn crossings_solved_in_space_are_the_cells_crossings() {
        use super::super::U_MARGIN;
        let mut rng = Lcg(37);
        let (mut cells, mut solved) = (0, 0);
        for i in 0..3000 {
            let Some((cyl, (o, d), r)) = whole_tube_case(&mut rng, i) else {
                continue;
            };
            let mut whole = Deferred::new();
            let range = (-U_MARGIN, 1.0 + U_MARGIN);
            if !whole_tube(&cyl, o, d, range, None, &mut whole) {
                continue;
            }
            let size = cyl
                .axis
                .points
                .iter()
                .fold(o.abs().max_element(), |m, p| m.max(p.abs().max_element()));
            for &(j, cell, _) in &whole.cells {
                let k = &whole.ranges[j].k;
                let refine = whole.ranges[j].local.expect("a whole tube's range");
                cells += 1;
                let Some((u, w)) = solved_in_space(&cyl, (refine.o, d), k, range, &cell) else {
                    continue;
                };
                solved += 1;
                let mut roots = ArrayVec::new();
                settle(k, &cell, &mut roots).expect("a tube's cell settles");
                let [(s, sign)] = roots.as_slice() else {
                    panic!("case {i}: one root in the cell, not {roots:?}");
                };
                let w_h = (k.z.eval(*s) + sign * k.disc.eval(*s).max(0.0).sqrt()) / d.length();
                let u_h = range.0 + (range.1 - range.0) * s;
                let (u_h, w_h) = refined(&cyl, (refine, d), r, (u_h, w_h));
                let e = o + w * d - cyl.axis.point(u);
                let cos = (e.dot(d) / (r * d.length())).abs();
                let allowance = 64.0 * f64::EPSILON * (size + (w * d).length()) / cos;
                let speed = cyl.axis.d1(u).length();
                assert!(
                    ((w - w_h) * d).length() <= allowance && (u - u_h).abs() * speed <= allowance,
                    "case {i}: r {r:e}, in space ({u}, {w}), on H ({u_h}, {w_h}), allowance \
                     {allowance:e}"
                );
            }
        }
        println!("{solved} of {cells} cells solved in space");
        assert!(
            cells > 600 && solved as f64 >= 0.99 * cells as f64,
            "{solved} of {cells}"
        );
    }

    /// [`space_crossing_from`]'s certificate names the cell's crossing, not another: on a
    /// straight tube and a ray across its axis tilted by `1e-12` (nearly in a normal plane),
    /// whose entry and exit lie `1e-13` apart in `u` (so the branch function's bracket alone
    /// cannot tell them apart), Newton's method started at the exit is refused for the entry's
    /// cell (whose end at the closest approach lies between them) and for a wider cell of the
    /// entry that holds both (by the sign of `e.d`), and started at the entry gives it;
    /// started at the entry for a cell that does not hold it (one beside it, or one whose
    /// branch function's end values have the other signs), it is refused.
    #[test]
    fn a_space_crossing_must_be_its_cells() {
        use super::super::U_MARGIN;
        use crate::Ray;
        let curve = crate::curve::CubicBezier::new(std::array::from_fn(|j| {
            DVec3::new(j as f64 / 3.0, 0.0, 0.0)
        }));
        let r = 0.05;
        let cyl = round_fiber(curve, [r, r]).expect("a straight tube");
        let ray = Ray {
            origin: DVec3::new(0.4, -1.0, 0.01),
            dir: DVec3::new(1e-12, 1.0, 0.0),
        };
        let (o, _) = cyl.local_ray(&ray, &cyl.bounds());
        let d = ray.dir;
        let range = (-U_MARGIN, 1.0 + U_MARGIN);
        let mut whole = Deferred::new();
        assert!(whole_tube(&cyl, o, d, range, None, &mut whole));
        let (j, entry, _) = *whole
            .cells
            .iter()
            .find(|c| c.1.sign < 0.0)
            .expect("an entry cell");
        let k = &whole.ranges[j].k;
        // The crossings (the axis is `x = u` from the first control point, the cylinder's
        // origin): `y = -+ sqrt(r^2 - z^2)` in the normal plane `x = u` of the ray's point.
        let cross = |sign: f64| {
            let w = sign * (r * r - o.z * o.z).sqrt() - o.y;
            (o.x + w * d.x, w)
        };
        let ((u_in, w_in), (u_out, w_out)) = (cross(-1.0), cross(1.0));
        // The entry's cell ends at the closest approach, between the two; a wider one (as
        // valid: `H-` has one root on the axis) holds both.
        let s_of = |u: f64| (u - range.0) / (range.1 - range.0);
        let mut wide = entry;
        wide.s1 = s_of(u_out) + 0.05;
        wide.fb = k.h(wide.s1, -1.0);
        assert!(
            wide.fb < 0.0 && s_of(u_in) > wide.s0,
            "the wider cell holds the entry"
        );
        let solve = |cell: &RootCell, (u, w)| {
            space_crossing_from(&cyl, (o, d), k, range, cell, (u, Some(w)))
        };
        for cell in [entry, wide] {
            let (u, w) = solve(&cell, (u_in, w_in)).expect("the entry, from the entry");
            assert!(
                (w - w_in).abs() < 1e-12 && (u - u_in).abs() < 1e-12,
                "({u}, {w})"
            );
            assert_eq!(solve(&cell, (u_out, w_out)), None, "the exit refused");
        }
        // A cell whose branch function rose through its root (the end values' signs turned)
        // does not hold this crossing, where it falls.
        let mut rising = entry;
        (rising.fa, rising.fb) = (-entry.fa, -entry.fb);
        assert_eq!(
            solve(&rising, (u_in, w_in)),
            None,
            "the bracket's signs checked"
        );
        let mut elsewhere = entry;
        (elsewhere.s0, elsewhere.s1) = (entry.s0, s_of(u_in) - 0.1);
        elsewhere.fb = k.h(elsewhere.s1, -1.0);
        assert_eq!(
            solve(&elsewhere, (u_in, w_in)),
            None,
            "a crossing outside the cell refused"
        );
    }

    /// [`whole_tube`]'s crossings are as close to the exact ones (double-double Newton's method
    /// on their conditions in space, [`crossing_dd`]) as those of the prefilter's narrow ranges
    /// ([`roots`]), and as many: within 4 times their error plus 16 units of the coordinates'
    /// size over the cosine of incidence, in `w` and in `u` (times `|a'|`). Tubes of radius `1e-6` to `0.3`
    /// of their length, at the origin and 1e4 from it; rays across the axis at tilts down to
    /// `1e-12`, or from any direction, entering anywhere between the axis and 0.98 of the
    /// radius from it. Without [`refined`] the thinnest tubes' crossings are off by far more.
    #[test]
    fn whole_tube_crossings_are_as_close_as_the_narrow_ranges() {
        use super::super::U_MARGIN;
        let mut rng = Lcg(36);
        let (mut taken, mut compared, mut one, mut none) = (0, 0, 0, 0);
        let (mut worst, mut thinnest, mut thickest) = (0.0f64, f64::INFINITY, 0.0f64);
        for i in 0..3000 {
            let Some((cyl, (o, d), r)) = whole_tube_case(&mut rng, i) else {
                continue;
            };
            let range = (-U_MARGIN, 1.0 + U_MARGIN);
            let mut whole = Deferred::new();
            if !whole_tube(&cyl, o, d, range, None, &mut whole) {
                continue;
            }
            // Near an end: one crossing on the fiber, or none (the ray crosses the surface
            // beyond the end).
            one += usize::from(whole.cells.len() == 1);
            none += usize::from(whole.cells.is_empty());
            taken += 1;
            (thinnest, thickest) = (thinnest.min(r), thickest.max(r));
            let mut narrow = Deferred::new();
            let mut narrow_out = SideRoots::new();
            for (a, b) in super::super::prefilter::candidate_ranges(&cyl, o, d, |_, _| true) {
                let range = super::super::widen(a, b, range.0, range.1);
                roots(&cyl, o, d, range, None, &mut narrow_out, &mut narrow);
            }
            let polish_all = |def: &Deferred, out: &mut SideRoots| {
                for j in 0..def.cells.len() {
                    assert!(def.polish(j, &cyl, d, out).is_none());
                }
            };
            let mut whole_out = SideRoots::new();
            polish_all(&whole, &mut whole_out);
            polish_all(&narrow, &mut narrow_out);
            assert_eq!(
                whole_out.len(),
                narrow_out.len(),
                "case {i}: the whole axis and the narrow ranges find as many crossings"
            );
            let axis = cyl.axis.points;
            let size = axis
                .iter()
                .fold(o.abs().max_element(), |m, p| m.max(p.abs().max_element()));
            for h in &whole_out {
                let Some(n) = narrow_out
                    .iter()
                    .min_by(|x, y| (x.w - h.w).abs().total_cmp(&(y.w - h.w).abs()))
                else {
                    panic!("case {i}: the narrow ranges found no crossing");
                };
                let (u, w) = crossing_dd(&axis, (o, d), r, (h.u, h.w));
                let e = o + w * d - cyl.axis.point(u);
                let cos = (e.dot(d) / (r * d.length())).abs();
                compared += 1;
                let speed = cyl.axis.d1(u).length();
                let scale = 16.0 * f64::EPSILON * (size + (w * d).length()) / cos;
                let (ew, nw) = (((h.w - w) * d).length(), ((n.w - w) * d).length());
                let (eu, nu) = ((h.u - u).abs() * speed, (n.u - u).abs() * speed);
                worst = worst.max(ew / (4.0 * nw + scale));
                assert!(
                    ew <= 4.0 * nw + scale && eu <= 4.0 * nu + scale,
                    "case {i}: r {r:e}, whole (u, w) ({}, {}) off by ({eu:e}, {ew:e}), narrow ({}, \
                     {}) by ({nu:e}, {nw:e}); exact ({u}, {w}), allowance {scale:e}",
                    h.u,
                    h.w,
                    n.u,
                    n.w
                );
            }
        }
        println!(
            "taken {taken} (one crossing {one}, none {none}), compared {compared}, worst \
             {worst:.3}, radii {thinnest:e} to {thickest:e}"
        );
        assert!(
            taken > 300 && compared > 600 && one > 10 && none > 10,
            "taken {taken}, compared {compared}, one crossing {one}, none {none}"
        );
        assert!(
            thinnest < 1e-5 && thickest > 0.1,
            "radii {thinnest:e} to {thickest:e}"
        );
    }
}
