//! Scalars the geometry is written over once and evaluated in several ways.
//!
//! The curve `phi(u)` of the Hsu-Chelberg method, the frame and the sweep rule are written
//! generically over [`Real`], then evaluated with
//! - `f64` for values,
//! - [`Dual`] for exact derivatives (forward-mode automatic differentiation; nest it for higher
//!   derivatives),
//! - [`Interval`] for guaranteed enclosures over a parameter range, which is what lets the root
//!   finders prove that a range holds no root, or exactly one,
//! - [`Taylor`] for guaranteed enclosures that are tight to second order in the range's width
//!   (first-order Taylor models with rounding-safe remainders); `Dual<Taylor>` encloses a
//!   function and its derivative at once, for the root isolator.

use std::ops::{Add, Div, Mul, Neg, Sub};

/// A real scalar: `f64`, a dual number, or an interval.
pub trait Real:
    'static
    + Copy
    + std::fmt::Debug
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// The constant `x`.
    fn cst(x: f64) -> Self;
    /// A representative `f64` value (an interval's midpoint, a dual number's value).
    fn value(self) -> f64;
    /// Square root.
    fn sqrt(self) -> Self;
    /// `sqrt(max(x, 0))`: the square root of a quantity that is non-negative wherever it is
    /// used, but whose enclosure (or rounded value) may reach below 0 near the boundary of
    /// that domain. Enclosures clamp at 0 (`[0, sqrt(hi)]` where they straddle it), so they
    /// hold the root over the part of the range inside the domain.
    fn sqrt_pos(self) -> Self;
    /// Sine.
    fn sin(self) -> Self;
    /// Cosine.
    fn cos(self) -> Self;
    /// `(sin, cos)`, sharing the work where a type can.
    fn sin_cos(self) -> (Self, Self) {
        (self.sin(), self.cos())
    }
    /// `self * self`; intervals give the tight (non-negative) square.
    fn sqr(self) -> Self {
        self * self
    }
    /// `self * k` for a constant `k`.
    fn scale(self, k: f64) -> Self {
        self * Self::cst(k)
    }
    /// `self / k` for a constant `k` (the same value as `self / Self::cst(k)` in `f64`).
    fn div_cst(self, k: f64) -> Self {
        self / Self::cst(k)
    }
    /// Whether values enclose sets (intervals, and dual numbers of them) rather than points:
    /// constants such a computation needs must then be enclosures too (see [`Real::lift`]).
    const ENCLOSURE: bool = false;
    /// A constant known only as an enclosure: `x` itself for [`Real::ENCLOSURE`] types, its
    /// midpoint otherwise.
    fn lift(x: Interval) -> Self {
        Self::cst(x.value())
    }
    /// The cubic `k0 + k1 t + k2 t^2 + k3 t^3` at `t = self - m`, for enclosures `k` of its
    /// coefficients (say a cubic's Taylor coefficients at `m`). Horner's rule by default;
    /// [`Taylor`] builds its model directly when `m` is its centre.
    fn cubic_at(self, m: f64, k: [Interval; 4]) -> Self {
        let t = self - Self::cst(m);
        Self::lift(k[0]) + t * (Self::lift(k[1]) + t * (Self::lift(k[2]) + t * Self::lift(k[3])))
    }
    /// `R(-theta) (x, y) = (c x + s y, c y - s x)` with `(s, c) = (sin, cos)(theta)`,
    /// `theta = self`: the sweep rule's inverse rotation.
    #[inline(always)]
    fn rotate_back(self, x: Self, y: Self) -> (Self, Self) {
        let (s, c) = self.sin_cos();
        (c * x + s * y, c * y - s * x)
    }
    /// [`Dual`]'s product `(a b, a' b + a b')`; [`Taylor`] computes the three products and
    /// their sum in one pass.
    #[inline(always)]
    fn dual_product(a: Dual<Self>, b: Dual<Self>) -> Dual<Self> {
        Dual {
            v: a.v * b.v,
            d: a.d * b.v + a.v * b.d,
        }
    }
    /// `1 / self`.
    fn recip(self) -> Self {
        Self::cst(1.0) / self
    }
    /// Whether `a / b` is `a * b.recip()` to the bit, so that quotients by one divisor may
    /// share its reciprocal (as [`Dual`]'s quotient does).
    const DIV_BY_RECIP: bool = false;
    /// Whether `self` is the exact constant `x` (a point, no slope, no remainder), which
    /// arithmetic may then skip: multiplying by an exact 1 changes nothing, rounding included.
    /// `false` where a type cannot tell.
    fn is_exactly(self, _x: f64) -> bool {
        false
    }
    /// A cubic `p` and its first two derivatives at `self`, from enclosures `d` of
    /// `p(m), p'(m), p''(m), p'''` (a curve's coordinate and its derivatives, say): each by
    /// [`Real::cubic_at`] with the Taylor coefficients at `m`,
    /// `p = [d0, d1, d2/2, d3/6]`, `p' = [d1, d2, d3/2, 0]`, `p'' = [d2, d3, 0, 0]`.
    /// [`Dual`] shares the work: the derivative of each is the value of the next.
    #[inline(always)]
    fn cubic_jet(self, m: f64, d: [Interval; 4]) -> [Self; 3] {
        let zero = Interval::cst(0.0);
        let [d0, d1, d2, d3] = d;
        [
            self.cubic_at(m, [d0, d1, d2.scale(0.5), d3 / Interval::cst(6.0)]),
            self.cubic_at(m, [d1, d2, d3.scale(0.5), zero]),
            self.cubic_at(m, [d2, d3, zero, zero]),
        ]
    }
}

impl Real for f64 {
    #[inline(always)]
    fn cst(x: f64) -> Self {
        x
    }
    #[inline(always)]
    fn value(self) -> f64 {
        self
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline(always)]
    fn sqrt_pos(self) -> Self {
        self.max(0.0).sqrt()
    }
    #[inline(always)]
    fn sin(self) -> Self {
        f64::sin(self)
    }
    #[inline(always)]
    fn cos(self) -> Self {
        f64::cos(self)
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        sin_cos(self)
    }
    #[inline(always)]
    fn is_exactly(self, x: f64) -> bool {
        self == x
    }
    #[inline(always)]
    fn scale(self, k: f64) -> Self {
        self * k
    }
    #[inline(always)]
    fn div_cst(self, k: f64) -> Self {
        self / k
    }
}

/// `(sin x, cos x)` within two units in the last place of the C library's values (of `2^-60`
/// where those are smaller; measured), inline and in fewer instructions than the library's
/// call: the value path's sine and cosine (a sweep's rotation at each Newton step of an
/// elliptical fiber's root, say), the unit circle's points and [`Taylor`] models' (about the
/// centre; [`Interval`]'s keep the library's).
///
/// `x = k pi/2 + r` with `k` an integer nearest to `x 2/pi` and `|r| <= pi/4` (a little
/// more from rounding), `r` by Cody and Waite's three-part `pi/2`: the first two parts hold 31
/// and 32 significant bits, so `k P1` and `k P2` are exact for `|k| < 2^21` (here `|k| <
/// 2^19`), and `r` is within about an ulp of `pi/4` of the truth. On `r` the Taylor series, to
/// `r^17` for the sine and `r^16` for the cosine, leave out less than `1e-19` and `3e-18`
/// (0.02 ulp). Then the quadrant `k mod 4` swaps and signs them. Beyond `|x| = 2^19` (never a
/// sweep's rotation), or for NaN and infinities, the library's. Within [`TRIG_ERR`] of the
/// truth (a review measured it against mpmath: within 2.11 ulp of the true values on 200,000
/// angles and beside multiples of `pi/2`), so [`Taylor`]'s sine and cosine use it too.
/// `Real::sin` and `Real::cos` alone stay the library's: a value taken both ways may differ by
/// an ulp or two.
#[inline]
pub fn sin_cos(x: f64) -> (f64, f64) {
    const P1: f64 = 1.5707963267341256; // pi/2 to 31 significant bits (33 truncated)
    const P2: f64 = 6.077100506303966e-11; // the next 33 bits (32 significant)
    const P3: f64 = 2.0222662487959506e-21; // the rest, rounded
    if !(x.abs() <= 524_288.0) {
        return x.sin_cos();
    }
    // `-0` keeps its sign.
    if x == 0.0 {
        return (x, 1.0);
    }
    // The nearest integer (ties to even) by adding and taking away `1.5 * 2^52`, exact for
    // `|x 2/pi| < 2^51` (the baseline's `round` is a library call).
    const SHIFT: f64 = 6_755_399_441_055_744.0;
    let k = (x * std::f64::consts::FRAC_2_PI + SHIFT) - SHIFT;
    let r = ((x - k * P1) - k * P2) - k * P3;
    let z = r * r;
    // sin r = r + r^3 (-1/3! + z (1/5! - z (1/7! - ...))), cos r = 1 - z/2 + z^2 (1/4! - ...).
    let sp = -1.0 / 6.0
        + z * (1.0 / 120.0
            + z * (-1.0 / 5040.0
                + z * (1.0 / 362_880.0
                    + z * (-1.0 / 39_916_800.0
                        + z * (1.0 / 6_227_020_800.0
                            + z * (-1.0 / 1_307_674_368_000.0
                                + z * (1.0 / 355_687_428_096_000.0)))))));
    let cp = 1.0 / 24.0
        + z * (-1.0 / 720.0
            + z * (1.0 / 40_320.0
                + z * (-1.0 / 3_628_800.0
                    + z * (1.0 / 479_001_600.0
                        + z * (-1.0 / 87_178_291_200.0 + z * (1.0 / 20_922_789_888_000.0))))));
    let sin = r + r * z * sp;
    let cos = (1.0 - 0.5 * z) + z * z * cp;
    match (k as i64) & 3 {
        0 => (sin, cos),
        1 => (cos, -sin),
        2 => (-sin, -cos),
        _ => (-cos, sin),
    }
}

/// A dual number `v + d eps` with `eps^2 = 0`: evaluating `f(Dual::var(x))` gives
/// `f(x)` in `v` and `f'(x)` in `d`. `Dual<Dual<f64>>` carries the second derivative.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dual<T> {
    /// The value.
    pub v: T,
    /// The derivative.
    pub d: T,
}

impl<T: Real> Dual<T> {
    /// The independent variable at `x` (derivative 1).
    pub fn var(x: T) -> Self {
        Dual {
            v: x,
            d: T::cst(1.0),
        }
    }
}

impl<T: Real> Add for Dual<T> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Dual {
            v: self.v + o.v,
            d: self.d + o.d,
        }
    }
}
impl<T: Real> Sub for Dual<T> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Dual {
            v: self.v - o.v,
            d: self.d - o.d,
        }
    }
}
impl<T: Real> Mul for Dual<T> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        T::dual_product(self, o)
    }
}
impl<T: Real> Div for Dual<T> {
    type Output = Self;
    /// `(f/g)' = (f' g - f g') / g^2`
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        if T::DIV_BY_RECIP {
            // The same values, one reciprocal.
            let r = o.v.recip();
            let v = self.v * r;
            return Dual {
                v,
                d: (self.d - v * o.d) * r,
            };
        }
        let v = self.v / o.v;
        Dual {
            v,
            d: (self.d - v * o.d) / o.v,
        }
    }
}
impl<T: Real> Neg for Dual<T> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Dual {
            v: -self.v,
            d: -self.d,
        }
    }
}

impl<T: Real> Real for Dual<T> {
    const ENCLOSURE: bool = T::ENCLOSURE;
    #[inline(always)]
    fn cst(x: f64) -> Self {
        Dual {
            v: T::cst(x),
            d: T::cst(0.0),
        }
    }
    #[inline(always)]
    fn lift(x: Interval) -> Self {
        Dual {
            v: T::lift(x),
            d: T::cst(0.0),
        }
    }
    /// The chain rule: `p(x)' = p'(x) x'`, with `p'` the derivative cubic.
    #[inline(always)]
    fn cubic_at(self, m: f64, k: [Interval; 4]) -> Self {
        let dk = [k[1], k[2].scale(2.0), k[3].scale(3.0), Interval::cst(0.0)];
        Dual {
            v: self.v.cubic_at(m, k),
            d: self.v.cubic_at(m, dk) * self.d,
        }
    }
    /// For enclosures, the derivative by `s' = theta' c`, `c' = -theta' s`:
    /// `(c x + s y)' = theta' (c y - s x) + (c x' + s y')` and
    /// `(c y - s x)' = -theta' (c x + s y) + (c y' - s x')`, the turned values and the turned
    /// derivatives: six products where the dual products took ten (and the sine's and cosine's
    /// derivatives no longer enter twice). The values are the plain rule's to the bit; point
    /// types keep the plain rule.
    #[inline(always)]
    fn rotate_back(self, x: Self, y: Self) -> (Self, Self) {
        if !T::ENCLOSURE {
            let (s, c) = self.sin_cos();
            return (c * x + s * y, c * y - s * x);
        }
        let (s, c) = self.v.sin_cos();
        let (vx, vy) = (c * x.v + s * y.v, c * y.v - s * x.v);
        let (dx, dy) = (c * x.d + s * y.d, c * y.d - s * x.d);
        if self.d.is_exactly(0.0) {
            return (Dual { v: vx, d: dx }, Dual { v: vy, d: dy });
        }
        (
            Dual {
                v: vx,
                d: self.d * vy + dx,
            },
            Dual {
                v: vy,
                d: dy - self.d * vx,
            },
        )
    }
    /// `(p, p', p'')(x)' = (p', p'', p''')(x) x'`: the derivatives' values are the models the
    /// jet holds already (enclosures of the same functions as [`Dual::cubic_at`]'s, from the
    /// coefficients themselves rather than rescaled ones), and `p''' = d3` is constant.
    #[inline(always)]
    fn cubic_jet(self, m: f64, d: [Interval; 4]) -> [Self; 3] {
        let [p0, p1, p2] = self.v.cubic_jet(m, d);
        // The variable itself (`x' = 1`, the isolator's case) needs no product.
        let one = self.d.is_exactly(1.0);
        let chain = |p: T| if one { p } else { p * self.d };
        [
            Dual {
                v: p0,
                d: chain(p1),
            },
            Dual {
                v: p1,
                d: chain(p2),
            },
            Dual {
                v: p2,
                d: chain(T::lift(d[3])),
            },
        ]
    }
    #[inline(always)]
    fn is_exactly(self, x: f64) -> bool {
        self.v.is_exactly(x) && self.d.is_exactly(0.0)
    }
    #[inline(always)]
    fn value(self) -> f64 {
        self.v.value()
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        let s = self.v.sqrt();
        Dual {
            v: s,
            d: self.d / (s + s),
        }
    }
    #[inline(always)]
    fn sqrt_pos(self) -> Self {
        let s = self.v.sqrt_pos();
        Dual {
            v: s,
            d: self.d / (s + s),
        }
    }
    #[inline(always)]
    fn sin(self) -> Self {
        Dual {
            v: self.v.sin(),
            d: self.d * self.v.cos(),
        }
    }
    #[inline(always)]
    fn cos(self) -> Self {
        Dual {
            v: self.v.cos(),
            d: -(self.d * self.v.sin()),
        }
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        let (s, c) = self.v.sin_cos();
        (
            Dual {
                v: s,
                d: self.d * c,
            },
            Dual {
                v: c,
                d: -(self.d * s),
            },
        )
    }
    #[inline(always)]
    fn sqr(self) -> Self {
        Dual {
            v: self.v.sqr(),
            d: (self.v * self.d).scale(2.0),
        }
    }
    #[inline(always)]
    fn scale(self, k: f64) -> Self {
        Dual {
            v: self.v.scale(k),
            d: self.d.scale(k),
        }
    }
    /// `(f / k)' = f' / k` (what [`Div`] gives for a constant divisor, whose derivative is 0).
    #[inline(always)]
    fn div_cst(self, k: f64) -> Self {
        Dual {
            v: self.v.div_cst(k),
            d: self.d.div_cst(k),
        }
    }
}

/// A closed interval `[lo, hi]` with outward rounding: every operation returns an interval
/// that contains the exact result for all arguments in the operands. An operation without a
/// finite enclosure (division by an interval holding 0, `inf - inf`) returns the whole line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interval {
    /// Lower bound.
    pub lo: f64,
    /// Upper bound.
    pub hi: f64,
}

impl Interval {
    /// The whole real line.
    pub const ENTIRE: Interval = Interval {
        lo: f64::NEG_INFINITY,
        hi: f64::INFINITY,
    };

    /// `[lo, hi]`, widened by one ulp each way; NaN bounds give [`Interval::ENTIRE`].
    #[inline(always)]
    pub fn new(lo: f64, hi: f64) -> Self {
        if lo.is_nan() || hi.is_nan() {
            Self::ENTIRE
        } else {
            Interval {
                lo: lo.next_down(),
                hi: hi.next_up(),
            }
        }
    }

    /// The exact interval `[lo, hi]` (no widening).
    #[inline(always)]
    pub fn exact(lo: f64, hi: f64) -> Self {
        Interval { lo, hi }
    }

    /// Whether `x` lies in the interval.
    #[inline(always)]
    pub fn contains(self, x: f64) -> bool {
        self.lo <= x && x <= self.hi
    }

    /// Whether the interval holds only strictly positive, or only strictly negative, numbers.
    #[inline(always)]
    pub fn excludes_zero(self) -> bool {
        self.lo > 0.0 || self.hi < 0.0
    }

    /// `hi - lo`.
    #[inline(always)]
    pub fn width(self) -> f64 {
        self.hi - self.lo
    }
}

/// Outward rounding of one bound: `down(x) <= pred(x)`, the largest `f64` below `x`, so
/// `down(x)` is below every real number that rounds to `x` (and `up(x)`, symmetrically, above).
///
/// Proof: `x - pred(x)`, the spacing of the `f64`s just below `x`, is at most `2^-52 |x|` for
/// normal `x` and `2^-1074` (the smallest subnormal) otherwise. The step
/// `s = fl(|x| 2^-52) + 2^-1074` is at least both: the product is exact unless it is
/// subnormal, where it errs by at most `2^-1075 < 2^-1074`, and a sum of two subnormal
/// multiples of `2^-1074` is exact. So the real `x - s <= pred(x)`, and rounding to nearest is
/// monotone and leaves `pred(x)` fixed: `fl(x - s) <= pred(x)`. A real `z` that rounds to `x`
/// lies strictly above `pred(x)`. At most two ulps below `x`, without the branches of
/// `f64::next_down`. `down(+inf)` and `up(-inf)` are NaN, which callers turn into
/// [`Interval::ENTIRE`].
#[inline(always)]
fn down(x: f64) -> f64 {
    x - (x.abs() * f64::EPSILON + TINY)
}
/// See [`down`].
#[inline(always)]
fn up(x: f64) -> f64 {
    x + (x.abs() * f64::EPSILON + TINY)
}
/// The smallest positive subnormal, `2^-1074`.
const TINY: f64 = f64::from_bits(1);

/// `[down(lo), up(hi)]`, or [`Interval::ENTIRE`] when a bound is NaN or `probe` is (callers
/// pass a sum of the candidate bounds, NaN when one is: `0 * inf` or `inf - inf`).
#[inline(always)]
fn rounded(lo: f64, hi: f64, probe: f64) -> Interval {
    let (lo, hi) = (down(lo), up(hi));
    // lo - hi is NaN exactly when a bound is (lo = hi = -inf cannot happen: up(-inf) is NaN).
    if (probe + (lo - hi)).is_nan() {
        Interval::ENTIRE
    } else {
        Interval { lo, hi }
    }
}

/// `min` and `max` of numbers known not to be NaN: one instruction each, unlike `f64::min`.
#[inline(always)]
fn fmin(a: f64, b: f64) -> f64 {
    if a < b { a } else { b }
}
#[inline(always)]
fn fmax(a: f64, b: f64) -> f64 {
    if a > b { a } else { b }
}
#[inline(always)]
fn min4(a: f64, b: f64, c: f64, d: f64) -> f64 {
    fmin(fmin(a, b), fmin(c, d))
}
#[inline(always)]
fn max4(a: f64, b: f64, c: f64, d: f64) -> f64 {
    fmax(fmax(a, b), fmax(c, d))
}

impl Add for Interval {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        rounded(self.lo + o.lo, self.hi + o.hi, 0.0)
    }
}
impl Sub for Interval {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        rounded(self.lo - o.hi, self.hi - o.lo, 0.0)
    }
}
impl Mul for Interval {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        let (a, b, c, d) = (
            self.lo * o.lo,
            self.lo * o.hi,
            self.hi * o.lo,
            self.hi * o.hi,
        );
        // 0 * inf is NaN (the true product set is unbounded only if a factor is); the sum
        // carries a NaN product into the probe, which min and max would drop.
        rounded(min4(a, b, c, d), max4(a, b, c, d), (a + b) + (c + d))
    }
}
impl Div for Interval {
    type Output = Self;
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        if !o.excludes_zero() {
            return Interval::ENTIRE;
        }
        let (a, b, c, d) = (
            self.lo / o.lo,
            self.lo / o.hi,
            self.hi / o.lo,
            self.hi / o.hi,
        );
        rounded(min4(a, b, c, d), max4(a, b, c, d), (a + b) + (c + d))
    }
}
impl Neg for Interval {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Interval {
            lo: -self.hi,
            hi: -self.lo,
        }
    }
}

impl Real for Interval {
    const ENCLOSURE: bool = true;
    #[inline(always)]
    fn is_exactly(self, x: f64) -> bool {
        self.lo == x && self.hi == x
    }
    #[inline(always)]
    fn cst(x: f64) -> Self {
        Interval { lo: x, hi: x }
    }
    #[inline(always)]
    fn lift(x: Interval) -> Self {
        x
    }
    #[inline(always)]
    fn value(self) -> f64 {
        0.5 * (self.lo + self.hi)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        // Rounding can push a sum of squares a hair below zero; the exact value is not.
        Interval::new(self.lo.max(0.0).sqrt(), self.hi.max(0.0).sqrt())
    }
    #[inline(always)]
    fn sqrt_pos(self) -> Self {
        self.sqrt()
    }
    #[inline(always)]
    fn sin(self) -> Self {
        (self - Interval::cst(std::f64::consts::FRAC_PI_2)).cos()
    }
    #[inline]
    fn cos(self) -> Self {
        use std::f64::consts::{PI, TAU};
        if !(self.width() < PI) {
            return Interval::new(-1.0, 1.0);
        }
        // cos is decreasing on [2k pi, (2k+1) pi] and increasing on [(2k-1) pi, 2k pi].
        let (c0, c1) = (self.lo.cos(), self.hi.cos());
        let mut lo = c0.min(c1);
        let mut hi = c0.max(c1);
        let k_max = (self.hi / TAU).floor(); // a maximum 2k pi in [lo, hi]?
        if k_max * TAU >= self.lo - 1e-15 {
            hi = 1.0;
        }
        let k_min = ((self.hi - PI) / TAU).floor(); // a minimum (2k+1) pi in [lo, hi]?
        if k_min * TAU + PI >= self.lo - 1e-15 {
            lo = -1.0;
        }
        // libm's cos is faithful to about an ulp; widen by a few.
        Interval::new((lo - TRIG_ERR).max(-1.0), (hi + TRIG_ERR).min(1.0))
    }
    #[inline(always)]
    fn sqr(self) -> Self {
        let (a, b) = (self.lo * self.lo, self.hi * self.hi);
        let lo = if self.lo > 0.0 || self.hi < 0.0 {
            fmin(a, b)
        } else {
            0.0
        };
        rounded(lo, fmax(a, b), a + b)
    }
    #[inline(always)]
    fn scale(self, k: f64) -> Self {
        let (a, b) = (self.lo * k, self.hi * k);
        let (lo, hi) = if k >= 0.0 { (a, b) } else { (b, a) };
        rounded(lo, hi, k)
    }
}

/// A first-order Taylor model in one variable: the set of functions
/// `c + s t + r(t)` with `|r(t)| <= rho` for `t in [-1, 1]`.
///
/// Evaluating a function with the variable `u = m + h t` as a `Taylor` ([`Taylor::var`]: `c = m`,
/// `s = h`, the domain's centre and half-width) gives an
/// enclosure of the function over `[m - h, m + h]` that keeps its linear dependence on `t`
/// exactly and bounds only the rest: products of two models (`t^2` terms), the curvature of
/// `sqrt`, `1/x`, `sin` and `cos` between the centre and the ends, and every rounding error.
/// The slope `s` is the function's derivative in `u` times `h` (so a constant has `s = 0`, and
/// every model of one evaluation shares the domain `[-1, 1]` without carrying `h`: fewer
/// operations and smaller models than with `t in [-h, h]`; [`Taylor::slope_per_unit`] gives the
/// derivative in `u`).
/// The remainder shrinks like `h^2`, so the enclosure of a smooth function is its true range to
/// second order, where interval arithmetic overestimates to first order by the dependency
/// problem. In a [`Dual`] it encloses the derivative the same way, which is what the root
/// isolator needs to prove a cell monotone. The bookkeeping is plain `f64` arithmetic, about as
/// costly as an [`Interval`] operation.
///
/// Rounding: `c` and `s` are computed to nearest, and each operation adds a bound on their
/// rounding errors to `rho` (4u times a bound on the magnitude of the rounded terms,
/// u = 2^-53, against at most 3 roundings each; a product bounds them by its factors'
/// magnitudes, which it has, and adds what an underflow in those may hide). `rho` itself is a
/// sum of products of non-negative terms, each computed to nearest from computed non-negative
/// terms, fewer than 40 roundings in all, so it is low by less than a factor `1 - 40u`; each
/// operation multiplies it by `1 + 2^-44` and adds `1e-300` (underflow), which more than covers
/// that. `sqrt` is correctly rounded (IEEE 754); `sin` and `cos` ([`sin_cos`]) are within
/// [`TRIG_ERR`] of the truth.
/// NaN and infinite parts propagate and make the enclosure the whole line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Taylor {
    /// The value at `t = 0`.
    pub c: f64,
    /// The slope in `t` (in `u = m + h t`: the derivative in `u` times `h`).
    pub s: f64,
    /// The remainder bound.
    pub rho: f64,
}

/// Absolute error bound of the C library's `sin` and `cos` (a few ulps of 1; [`Interval`]'s
/// `cos`), and of [`sin_cos`] (the [`Taylor`] models'): there `r` is within `1.2e-16` of
/// `x - k pi/2` (`x - k P1` is exact, by Sterbenz's lemma; the two later subtractions round by
/// at most half an ulp of `pi/4` each, and `k P3` and the three parts' error, `k 2e-37`, add
/// less than `1e-30`), which moves the sine and cosine by as much; the series leave out less
/// than `3e-18`; and their evaluation rounds by less than `1.5e-16` (the last sum half an ulp
/// of a number below 1, `1 - z/2` as much, the higher terms, below `0.1`, a few relative
/// ulps): below `2.7e-16` in all. (Reviews measured at most `2.05e-16` against mpmath, on
/// 5.7 million angles to `2^19`.)
const TRIG_ERR: f64 = 4e-16;
/// Four units in the last place, relative: `2^-51`.
const U4: f64 = 4.0 * 0.5 * f64::EPSILON;

impl Taylor {
    /// The whole real line.
    pub const ENTIRE: Taylor = Taylor {
        c: 0.0,
        s: 0.0,
        rho: f64::INFINITY,
    };

    /// The variable `u` over `[lo, hi]`: `m + h t` with `m` the midpoint and `h` at least
    /// `hi - m` and `m - lo` (`c = m`, `s = h`, exact: the set `[m - h, m + h]` holds
    /// `[lo, hi]`).
    pub fn var(lo: f64, hi: f64) -> Self {
        let m = 0.5 * (lo + hi);
        let h = up((hi - m).max(m - lo));
        Taylor::finish(m, h, 0.0)
    }

    /// The model's slope in `u` for the domain `[m - h, m + h]` of [`Taylor::var`] (`h` its
    /// `s`): `(q, rho')` with `q = s / h` rounded, so that `c + q (u - m) + [-rho', rho']` holds
    /// the model's values at `u`. The line moves by `|s - q h| |t|`, `|t| <= 1`: at most
    /// `2^-53 |s|` where `q` is normal, and up to `2^-1075 h` more where it is subnormal or
    /// zero (an absolute error of half the least subnormal), so `rho' = rho + 2^-52 |s|` plus
    /// `(h + 1) 2^-1074` in the second case, rounded up. (An independent review found the
    /// subnormal case 13 to 4.5e11 times short without that term, for `h` above `1e20`.) Where
    /// `s / h` overflows the slope is infinite and bounds nothing. `h = 0` (a point) gives a
    /// slope of 0 and `rho + |s|`.
    pub fn slope_per_unit(self, h: f64) -> (f64, f64) {
        if h == 0.0 {
            return (0.0, up(self.rho + self.s.abs()));
        }
        let q = self.s / h;
        let lost = if q.abs() < f64::MIN_POSITIVE {
            (h + 1.0) * f64::from_bits(1)
        } else {
            0.0
        };
        (q, up(self.rho + f64::EPSILON * self.s.abs() + lost))
    }

    /// Rounds the remainder up (see the type's docs).
    ///
    /// Non-finite parts are not normalised here: NaN and infinities propagate through the
    /// arithmetic (every comparison with NaN fails, so `sqrt` and `1/x` give up), and
    /// [`Taylor::enclosure`] turns them into the whole line.
    #[inline(always)]
    fn finish(c: f64, s: f64, rho: f64) -> Self {
        const GROW: f64 = 1.0 + 1.0 / (1u64 << 44) as f64;
        Taylor {
            c,
            s,
            rho: rho * GROW + 1e-300,
        }
    }

    /// A bound on `|s t + r|`, the distance of the model's values from `c`, rounded up.
    #[inline(always)]
    fn spread(self) -> f64 {
        (self.s.abs() + self.rho) * (1.0 + 1e-15)
    }

    /// An interval holding every value of the model.
    #[inline(always)]
    pub fn enclosure(self) -> Interval {
        let w = self.spread();
        rounded(self.c - w, self.c + w, self.c + w)
    }

    /// `f(self)` for `f` with value `f0` within `err0` of `f(c)`, slope `f1` within `err1` of
    /// `f'(c)` at `c`, and `|f''| <= f2` between `c` and the model's values: Taylor's theorem,
    /// `f(c + d) = f(c) + f'(c) d + f''(xi) d^2 / 2` with `d = s t + r`, so the remainder is
    /// `f1 r - e0 - e1 d + f''(xi) d^2 / 2` with `|e0| <= err0`, `|e1| <= err1`. (The two
    /// errors are kept apart: for `sqrt` near 0 the slope's is far larger than the value's.)
    ///
    /// `range` encloses `f` over the model's values. Where the model is wide against the
    /// curvature of `f` (`1/x` or `sqrt` near 0) the remainder alone can exceed it; then the
    /// result is that interval as a constant model, so a model is never much wider than interval
    /// arithmetic would be. (Comparing the whole spread instead would also discard the linear
    /// part where it is large but exact, and it is what cancels in, say, `x^2 / x^2`.)
    #[inline(always)]
    fn compose(self, f0: f64, f1: f64, f2: f64, err0: f64, err1: f64, range: Interval) -> Self {
        let s = f1 * self.s;
        let w = self.spread();
        let rho = (f1.abs() + err1) * self.rho
            + 0.5 * f2 * w * w
            + err0
            + err1 * self.s.abs()
            + U4 * (f0.abs() + s.abs());
        if rho > 0.5 * range.width() {
            return Taylor::lift(range);
        }
        Taylor::finish(f0, s, rho)
    }

    /// `1 / self`.
    #[inline(always)]
    fn reciprocal(self) -> Self {
        let lo = down(self.c.abs() - self.spread());
        if !(lo > 0.0) {
            return Self::ENTIRE;
        }
        let r = 1.0 / self.c;
        let hi = up(self.c.abs() + self.spread());
        let mag = Interval {
            lo: down(1.0 / hi),
            hi: up(1.0 / lo),
        };
        let range = if self.c > 0.0 { mag } else { -mag };
        // (1/x)' = -1/x^2, |(1/x)''| = 2/|x|^3 <= 2/lo^3. Where `lo^3` overflows (`|x|` above
        // about `5e102`) that bound would be a zero, where `r^2` underflows the slope loses
        // its digits, and where it overflows (`|x|` below `1e-154`) the model its finite
        // parts: the range alone (an independent review found errors `1e14` times the
        // remainder in the first case).
        let (r2, lo3) = (r * r, lo * lo * lo);
        if !(lo3.is_finite() && (f64::MIN_POSITIVE..=f64::MAX).contains(&r2)) {
            return Taylor::lift(range);
        }
        self.compose(r, -r2, 2.0 / lo3, U4 * r.abs(), U4 * r2, range)
    }
}

impl Add for Taylor {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        let (c, s) = (self.c + o.c, self.s + o.s);
        Taylor::finish(c, s, self.rho + o.rho + U4 * (c.abs() + s.abs()))
    }
}
impl Sub for Taylor {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        let (c, s) = (self.c - o.c, self.s - o.s);
        Taylor::finish(c, s, self.rho + o.rho + U4 * (c.abs() + s.abs()))
    }
}
impl Mul for Taylor {
    type Output = Self;
    /// `(a0 + a1 t + ra)(b0 + b1 t + rb) = a0 b0 + (a0 b1 + a1 b0) t + a1 b1 t^2 + ...`, with
    /// `a1 b1 t^2 in a1 b1 [0, 1]` as its midpoint `shift = a1 b1 / 2` plus a remainder.
    ///
    /// Rounding: the rounded terms `c0 = a0 b0`, `shift`, `c = c0 + shift` and `s1 + s2`
    /// add up to at most `2 |a0| |b0| + |a1 b1| + |a0 b1| + |a1 b0|` (to a factor
    /// `1 + 4u`), which is at most `2 (|a0| + |a1|)(|b0| + |b1|)`: `4u` times that bounds
    /// their errors with two products, where summing the terms took ten operations. Where a
    /// product underflows it may lose up to `2^-1075`, which a huge other factor
    /// would scale past what the `1e-300` of each operation covers: each factor is taken plus
    /// the smallest normal `2^-1022` (absorbed, where a factor is larger than `2^-969`, by the
    /// bound's slack).
    ///
    /// The slopes carry the domain's half-width `h` (`t` in `[-1, 1]`, [`Taylor::var`]), so
    /// `shift` is the product of the scaled slopes: the form an independent review asked for
    /// when the domain was `[-h, h]` (`(a1 b1) h^2` lost the `t^2` term where `h * h`
    /// underflowed, and scaled an underflowed `a1 b1` past the bound where `h` was huge).
    ///
    /// Not inlined, unlike the other operations: the enclosures of the radial function and of
    /// the General method's `phi` each inlined well over a hundred products, and their code
    /// (92 and 67 KB) outgrew the instruction cache. One shared copy (58 and 43 KB left)
    /// executes 2-3% more instructions but made elliptical camera rays 3-4% faster and
    /// three-lobed ones 5% (whole-process timings; outlining sums, `compose` or the functions
    /// built on it as well was slower).
    #[inline(never)]
    fn mul(self, o: Self) -> Self {
        let (c, s, rho) = Taylor::product_terms(self, o, (self.magnitude(), o.magnitude()));
        Taylor::finish(c, s, rho)
    }
}

impl Taylor {
    /// `|c| + |s|`: a bound of the model's line on `[-1, 1]`.
    #[inline(always)]
    fn magnitude(self) -> f64 {
        self.c.abs() + self.s.abs()
    }

    /// The product's centre, slope and remainder before [`Taylor::finish`], from the factors'
    /// [`Taylor::magnitude`]s `(rx, ry)` (see `Mul` for the terms and their rounding), shared
    /// by `Mul` and the dual product (which computes each factor's magnitude once for its
    /// three products).
    #[inline(always)]
    fn product_terms(x: Taylor, y: Taylor, (rx, ry): (f64, f64)) -> (f64, f64, f64) {
        let shift = 0.5 * (x.s * y.s);
        let c = x.c * y.c + shift;
        let s = x.c * y.s + x.s * y.c;
        let rho = shift.abs()
            + rx * y.rho
            + ry * x.rho
            + x.rho * y.rho
            + (2.0 * U4) * ((rx + f64::MIN_POSITIVE) * (ry + f64::MIN_POSITIVE));
        (c, s, rho)
    }
}
impl Div for Taylor {
    type Output = Self;
    /// `self * (1 / o)`.
    #[inline(always)]
    #[allow(clippy::suspicious_arithmetic_impl)]
    fn div(self, o: Self) -> Self {
        self * o.reciprocal()
    }
}
impl Neg for Taylor {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Taylor {
            c: -self.c,
            s: -self.s,
            ..self
        }
    }
}

impl Real for Taylor {
    const ENCLOSURE: bool = true;
    const DIV_BY_RECIP: bool = true;
    /// The three products and the sum of [`Dual`]'s product in one pass, each term as
    /// [`Taylor`]'s product and sum form it (the same centres and slopes to the bit: each
    /// product's terms are `Mul`'s, [`Taylor::product_terms`]; each factor's magnitude
    /// computed once). The derivative's remainder is the two
    /// products' (see `Mul`) without the sum's rounding term or the two intermediate
    /// rounding-ups (`finish`). The products' rounding terms cover the sum's: its centre
    /// `(p0 + shift_p) + (q0 + shift_q)` and slope `(p1 + p2) + (q1 + q2)` round each product
    /// term at most five times (`shift`'s own three, two sums), so by at most `5u` times the
    /// terms' magnitudes, at most `5u (ra_d rb_v + ra_v rb_d)`; the
    /// products' rounding terms are `8u` times that. One `finish` at the end covers the
    /// rounding of the remainder's own terms (far fewer than the `2^-44 / u = 512` roundings
    /// it allows for).
    ///
    /// Not inlined, as the product is not: one call where the three products took three
    /// (the elliptical ponytail's radial function multiplies ten dual pairs a value).
    #[inline(never)]
    fn dual_product(a: Dual<Self>, b: Dual<Self>) -> Dual<Self> {
        let (av, ad, bv, bd) = (
            a.v.magnitude(),
            a.d.magnitude(),
            b.v.magnitude(),
            b.d.magnitude(),
        );
        let (vc, vs, vrho) = Taylor::product_terms(a.v, b.v, (av, bv));
        let (pc, ps, prho) = Taylor::product_terms(a.d, b.v, (ad, bv));
        let (qc, qs, qrho) = Taylor::product_terms(a.v, b.d, (av, bd));
        Dual {
            v: Taylor::finish(vc, vs, vrho),
            // The two `1e-300`s of the intermediate `finish`es kept: an independent review
            // found errors of 2.7e-300 against a single one, at `h = 1e-300`.
            d: Taylor::finish(pc + qc, ps + qs, prho + qrho + 2e-300),
        }
    }
    #[inline(always)]
    fn recip(self) -> Self {
        self.reciprocal()
    }
    #[inline(always)]
    fn is_exactly(self, x: f64) -> bool {
        self.c == x && self.s == 0.0 && self.rho == 0.0
    }
    #[inline(always)]
    fn cst(x: f64) -> Self {
        Taylor {
            c: x,
            s: 0.0,
            rho: 0.0,
        }
    }
    #[inline(always)]
    fn lift(x: Interval) -> Self {
        let c = x.value();
        Taylor::finish(c, 0.0, fmax(x.hi - c, c - x.lo))
    }
    /// At the model's centre (`m = c`, the usual case) directly: `p(c + d) = k0 + k1 d +
    /// p''(xi) d^2 / 2` with `|p''| <= 2|k2| + 6|k3| |d|` and `|d| <= |s| + rho`; elsewhere by
    /// Horner's rule.
    #[inline(always)]
    fn cubic_at(self, m: f64, k: [Interval; 4]) -> Self {
        if self.c != m {
            let t = self - Self::cst(m);
            return Self::lift(k[0])
                + t * (Self::lift(k[1]) + t * (Self::lift(k[2]) + t * Self::lift(k[3])));
        }
        let mag = |x: Interval| fmax(x.lo.abs(), x.hi.abs());
        let (f0, f1) = (k[0].value(), k[1].value());
        let err0 = fmax(k[0].hi - f0, f0 - k[0].lo);
        let err1 = fmax(k[1].hi - f1, f1 - k[1].lo);
        let f2 = 2.0 * mag(k[2]) + 6.0 * mag(k[3]) * self.spread();
        self.compose(f0, f1, f2, err0, err1, Interval::ENTIRE)
    }
    #[inline(always)]
    fn value(self) -> f64 {
        self.c
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        let lo = down(self.c - self.spread());
        if !(lo > 0.0) {
            return Self::ENTIRE;
        }
        let r = self.c.sqrt();
        let range = Interval {
            lo: down(lo.sqrt()),
            hi: up(up(self.c + self.spread()).sqrt()),
        };
        // sqrt' = 1/(2 sqrt), |sqrt''| = 1/(4 x^1.5) <= 1/(4 lo sqrt(lo)); where `lo^1.5`
        // overflows (`x` above about `3e205`) that bound would be a zero: the range alone.
        let f1 = 0.5 / r;
        let lo32 = lo * lo.sqrt();
        if !lo32.is_finite() {
            return Taylor::lift(range);
        }
        self.compose(r, f1, 0.25 / lo32, U4 * r, U4 * f1, range)
    }
    #[inline(always)]
    fn sqrt_pos(self) -> Self {
        if down(self.c - self.spread()) > 0.0 {
            return self.sqrt();
        }
        let hi = up(self.c + self.spread()).max(0.0);
        if !hi.is_finite() {
            return Self::ENTIRE;
        }
        Taylor::lift(Interval {
            lo: 0.0,
            hi: up(hi.sqrt()),
        })
    }
    #[inline(always)]
    fn sin(self) -> Self {
        self.sin_cos().0
    }
    #[inline(always)]
    fn cos(self) -> Self {
        self.sin_cos().1
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        let (s, c) = sin_cos(self.c);
        let unit = Interval { lo: -1.0, hi: 1.0 };
        (
            self.compose(s, c, 1.0, TRIG_ERR, TRIG_ERR, unit),
            self.compose(c, -s, 1.0, TRIG_ERR, TRIG_ERR, unit),
        )
    }
    #[inline(always)]
    fn sqr(self) -> Self {
        let c0 = self.c * self.c;
        let s = 2.0 * self.c * self.s;
        let shift = 0.5 * (self.s * self.s);
        let c = c0 + shift;
        let ra = self.magnitude();
        // The rounded terms' sum `2 c^2 + s^2 + 2 |c s|` is at most `2 ra^2` (as in `mul`).
        let rho = shift + 2.0 * ra * self.rho + self.rho * self.rho + (2.0 * U4) * (ra * ra);
        Taylor::finish(c, s, rho)
    }
    #[inline(always)]
    fn scale(self, k: f64) -> Self {
        let (c, s) = (self.c * k, self.s * k);
        Taylor::finish(c, s, self.rho * k.abs() + U4 * (c.abs() + s.abs()))
    }
    /// `(c + s t + r) / k = c/k + (s/k) t + r/k`: the two quotients' rounding goes into the
    /// remainder, as for [`Real::scale`]. A divisor of 0 or NaN makes the whole line.
    #[inline(always)]
    fn div_cst(self, k: f64) -> Self {
        if !(k != 0.0) {
            return Self::ENTIRE;
        }
        let (c, s) = (self.c / k, self.s / k);
        Taylor::finish(c, s, self.rho / k.abs() + U4 * (c.abs() + s.abs()))
    }
}

/// A 2D vector over any [`Real`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct V2<T> {
    /// First coordinate.
    pub x: T,
    /// Second coordinate.
    pub y: T,
}

/// A 3D vector over any [`Real`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct V3<T> {
    /// First coordinate.
    pub x: T,
    /// Second coordinate.
    pub y: T,
    /// Third coordinate.
    pub z: T,
}

impl<T: Real> V2<T> {
    /// `(x, y)`.
    #[inline(always)]
    pub fn new(x: T, y: T) -> Self {
        V2 { x, y }
    }
    /// Lifts a constant `f64` vector.
    #[inline(always)]
    pub fn cst(p: glam::DVec2) -> Self {
        V2 {
            x: T::cst(p.x),
            y: T::cst(p.y),
        }
    }
    /// The dot product.
    #[inline(always)]
    pub fn dot(self, o: Self) -> T {
        self.x * o.x + self.y * o.y
    }
    /// `|self|^2`.
    #[inline(always)]
    pub fn norm2(self) -> T {
        self.x.sqr() + self.y.sqr()
    }
    /// Representative values.
    #[inline(always)]
    pub fn value(self) -> glam::DVec2 {
        glam::DVec2::new(self.x.value(), self.y.value())
    }
}

impl<T: Real> V3<T> {
    /// `(x, y, z)`.
    #[inline(always)]
    pub fn new(x: T, y: T, z: T) -> Self {
        V3 { x, y, z }
    }
    /// Lifts a constant `f64` vector.
    #[inline(always)]
    pub fn cst(p: glam::DVec3) -> Self {
        V3 {
            x: T::cst(p.x),
            y: T::cst(p.y),
            z: T::cst(p.z),
        }
    }
    /// The dot product.
    #[inline(always)]
    pub fn dot(self, o: Self) -> T {
        self.x * o.x + self.y * o.y + self.z * o.z
    }
    /// The dot product with a constant vector.
    #[inline(always)]
    pub fn dot_cst(self, o: glam::DVec3) -> T {
        self.x.scale(o.x) + self.y.scale(o.y) + self.z.scale(o.z)
    }
    /// The cross product.
    #[inline(always)]
    pub fn cross(self, o: Self) -> Self {
        V3 {
            x: self.y * o.z - self.z * o.y,
            y: self.z * o.x - self.x * o.z,
            z: self.x * o.y - self.y * o.x,
        }
    }
    /// The cross product with a constant vector (by [`Real::scale`]).
    #[inline(always)]
    pub fn cross_cst(self, o: glam::DVec3) -> Self {
        V3 {
            x: self.y.scale(o.z) - self.z.scale(o.y),
            y: self.z.scale(o.x) - self.x.scale(o.z),
            z: self.x.scale(o.y) - self.y.scale(o.x),
        }
    }
    /// `|self|^2`.
    #[inline(always)]
    pub fn norm2(self) -> T {
        self.x.sqr() + self.y.sqr() + self.z.sqr()
    }
    /// `self * k`.
    #[inline(always)]
    pub fn scaled(self, k: T) -> Self {
        V3 {
            x: self.x * k,
            y: self.y * k,
            z: self.z * k,
        }
    }
    /// `self * k` for a constant `k` ([`Real::scale`]: for a [`Dual`] two products a
    /// coordinate, not a dual product's three).
    #[inline(always)]
    pub fn scale(self, k: f64) -> Self {
        V3 {
            x: self.x.scale(k),
            y: self.y.scale(k),
            z: self.z.scale(k),
        }
    }
    /// `self / k`.
    #[inline(always)]
    pub fn divided(self, k: T) -> Self {
        V3 {
            x: self.x / k,
            y: self.y / k,
            z: self.z / k,
        }
    }
    /// Representative values.
    #[inline(always)]
    pub fn value(self) -> glam::DVec3 {
        glam::DVec3::new(self.x.value(), self.y.value(), self.z.value())
    }
}

impl<T: Real> Add for V3<T> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        V3 {
            x: self.x + o.x,
            y: self.y + o.y,
            z: self.z + o.z,
        }
    }
}
impl<T: Real> Sub for V3<T> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        V3 {
            x: self.x - o.x,
            y: self.y - o.y,
            z: self.z - o.z,
        }
    }
}
impl<T: Real> Add for V2<T> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        V2 {
            x: self.x + o.x,
            y: self.y + o.y,
        }
    }
}
impl<T: Real> Sub for V2<T> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        V2 {
            x: self.x - o.x,
            y: self.y - o.y,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The value path's `sin_cos` against the library's: within two units in the last place of
    /// each value, or of `2^-60` where the value is smaller (near a multiple of `pi/2` a double
    /// angle keeps a distance from it far above that, so both are accurate there in absolute
    /// terms), on angles of every magnitude the fast path takes, uniform ones, angles just
    /// beside multiples of `pi/4`, and the fast path's edge; exact at zero; the library's own
    /// bits beyond the edge and for NaN and infinities.
    #[test]
    fn fast_sin_cos_agrees_with_the_library() {
        let mut rng = crate::test_rng::Lcg(4242);
        let mut xs: Vec<f64> = vec![0.0, -0.0, 524_288.0, -524_288.0, 1e-300, 5e-324];
        for _ in 0..200_000 {
            xs.push(rng.range(-7.0, 7.0));
            let mag = 10f64.powf(rng.range(-300.0, 5.7));
            xs.push(if rng.next() < 0.5 { mag } else { -mag });
        }
        for k in -2000..2000 {
            let base = k as f64 * std::f64::consts::FRAC_PI_4;
            let mut x = base;
            for _ in 0..4 {
                xs.extend([x, -x]);
                x = x.next_up();
            }
            x = base;
            for _ in 0..4 {
                x = x.next_down();
                xs.extend([x, -x]);
            }
        }
        let ulp = |v: f64| (v.abs().next_up() - v.abs()).max(f64::EPSILON * 2f64.powi(-8));
        let mut worst = 0.0f64;
        for &x in &xs {
            let (s, c) = sin_cos(x);
            let (s0, c0) = x.sin_cos();
            for (v, v0) in [(s, s0), (c, c0)] {
                let err = (v - v0).abs() / ulp(v0);
                worst = worst.max(err);
                assert!(err <= 2.0, "x = {x:e}: {v:e} against {v0:e}");
            }
        }
        assert!(
            worst > 0.0,
            "a fast path that never differs is the library's own"
        );
        assert_eq!(sin_cos(0.0), (0.0, 1.0));
        assert!(sin_cos(-0.0).0.is_sign_negative());
        for x in [600_000.0, -1e300, f64::INFINITY, f64::NAN] {
            let ((s, c), (s0, c0)) = (sin_cos(x), x.sin_cos());
            assert!(
                s.to_bits() == s0.to_bits() && c.to_bits() == c0.to_bits(),
                "{x}"
            );
        }
    }

    /// Random points of an interval must map into the interval result: the enclosure property.
    #[test]
    fn interval_operations_enclose_pointwise_results() {
        let mut seed = 12345u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) * 8.0 - 4.0
        };
        for _ in 0..2000 {
            let (a0, a1, b0, b1) = (rnd(), rnd(), rnd(), rnd());
            let a = Interval::exact(a0.min(a1), a0.max(a1));
            let b = Interval::exact(b0.min(b1), b0.max(b1));
            for k in 0..=4 {
                let x = a.lo + (a.hi - a.lo) * k as f64 / 4.0;
                let y = b.lo + (b.hi - b.lo) * (4 - k) as f64 / 4.0;
                assert!((a + b).contains(x + y), "add {a:?} {b:?}");
                assert!((a - b).contains(x - y), "sub {a:?} {b:?}");
                assert!((a * b).contains(x * y), "mul {a:?} {b:?}");
                assert!((a / b).contains(x / y) || y == 0.0, "div {a:?} {b:?}");
                assert!(a.sqr().contains(x * x), "sqr {a:?}");
                assert!(a.sin().contains(x.sin()), "sin {a:?} at {x}");
                assert!(a.cos().contains(x.cos()), "cos {a:?} at {x}");
                assert!(a.sqrt().contains(x.max(0.0).sqrt()), "sqrt {a:?}");
            }
        }
    }

    #[test]
    fn interval_cos_finds_interior_extrema() {
        let c = Interval::exact(-0.5, 0.5).cos();
        assert!(
            c.hi >= 1.0 && c.lo <= 0.5f64.cos(),
            "max of cos at 0 missed: {c:?}"
        );
        let c = Interval::exact(3.0, 3.3).cos();
        assert!(c.lo <= -1.0, "min of cos at pi missed: {c:?}");
        let c = Interval::exact(0.2, 0.3).cos();
        assert!(c.hi < 1.0 && c.lo > 0.9, "monotone piece too wide: {c:?}");
    }

    #[test]
    fn dual_numbers_match_known_derivatives() {
        // f(x) = sin(x) * sqrt(x) / (1 + x^2), f' by the quotient and product rules by hand.
        let x = 0.7f64;
        fn f<T: Real>(x: T) -> T {
            x.sin() * x.sqrt() / (T::cst(1.0) + x.sqr())
        }
        let r = f(Dual::var(x));
        let g = x.sin() * x.sqrt();
        let dg = x.cos() * x.sqrt() + x.sin() / (2.0 * x.sqrt());
        let h = 1.0 + x * x;
        let expected = (dg * h - g * 2.0 * x) / (h * h);
        assert!((r.v - g / h).abs() < 1e-15, "value {r:?}");
        assert!(
            (r.d - expected).abs() < 1e-14,
            "derivative {} vs {expected}",
            r.d
        );
        // Second derivative through nesting, against a central difference of the first.
        let d2 = f(Dual {
            v: Dual::var(x),
            d: Dual::cst(1.0),
        })
        .d
        .d;
        let h = 1e-5;
        let fd = (f(Dual::var(x + h)).d - f(Dual::var(x - h)).d) / (2.0 * h);
        assert!((d2 - fd).abs() < 1e-8, "second derivative {d2} vs {fd}");
        // Dividing by a constant is the quotient rule with a zero derivative, to the bit.
        for k in [3.0, -0.37, 1e-300, 7e250] {
            let y = f(Dual::var(x));
            assert_eq!(y.div_cst(k), y / Dual::cst(k), "div_cst({k})");
        }
    }

    /// `down` and `up` step past the neighbouring `f64`s, also for subnormals, zero, powers of
    /// two (where the spacing changes) and the largest finite numbers.
    #[test]
    fn outward_rounding_passes_the_neighbours() {
        let mut xs = vec![
            0.0,
            -0.0,
            TINY,
            -TINY,
            f64::MIN_POSITIVE,
            f64::MIN_POSITIVE * 0.75,
            1.0,
            -1.0,
            2.0,
            0.5,
            f64::MAX,
            -f64::MAX,
            1e-310,
            3.0e-320,
        ];
        let mut seed = 99u64;
        for _ in 0..2000 {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let x = f64::from_bits(seed >> 1);
            if x.is_finite() {
                xs.push(x);
                xs.push(-x);
            }
        }
        for k in -1074..1024 {
            xs.push(2f64.powi(k));
            xs.push(-(2f64.powi(k)));
        }
        for x in xs {
            let (d, u) = (down(x), up(x));
            assert!(d <= x.next_down(), "down({x:e}) = {d:e}");
            assert!(
                u >= x.next_up() || (x == f64::MAX && u == f64::INFINITY),
                "up({x:e}) = {u:e}"
            );
            assert!(
                !(x.next_down() - d > 4.0 * (x - x.next_down()).abs().max(TINY)),
                "down({x:e}) too far"
            );
        }
        assert!(down(f64::INFINITY).is_nan() && up(f64::NEG_INFINITY).is_nan());
        assert_eq!(down(f64::NEG_INFINITY), f64::NEG_INFINITY);
    }

    use crate::test_rng::Lcg;

    /// A random model of a variable's domain of half-width `h` (a slope in `u` times `h`: 0 for
    /// a constant, `h = 0`) and a random member `(t, value)` of its set, `t` in `[-1, 1]`.
    fn random_model(rng: &mut Lcg, h: f64) -> (Taylor, f64, f64) {
        let m = Taylor {
            c: rng.range(-3.0, 3.0),
            s: rng.range(-2.0, 2.0) * h,
            rho: if rng.next() < 0.3 {
                0.0
            } else {
                rng.range(0.0, 0.05)
            },
        };
        let t = rng.range(-1.0, 1.0);
        let r = rng.range(-m.rho, m.rho);
        (m, t, m.c + m.s * t + r)
    }

    /// Whether the model at `t` admits `x` (with a little slack for the rounding of `x` and of
    /// the check itself).
    fn admits(m: Taylor, t: f64, x: f64) -> bool {
        let slack = 1e-14 * (x.abs() + m.c.abs() + m.s.abs());
        (x - (m.c + m.s * t)).abs() <= m.rho + slack
    }

    /// The enclosure property of every `Taylor` operation: apply it to members of the operand
    /// sets (sharing `t`) and the result must be a member of the result's set.
    #[test]
    fn taylor_operations_enclose_their_members() {
        let mut rng = Lcg(2024);
        for _ in 0..20000 {
            let h = if rng.next() < 0.1 {
                0.0
            } else {
                rng.range(0.0, 0.6)
            };
            let (a, t, x) = random_model(&mut rng, h);
            let (b, _, _) = random_model(&mut rng, h);
            // A member of b's set at the same t.
            let y = b.c + b.s * t + rng.range(-b.rho, b.rho);
            let k = rng.range(-3.0, 3.0);
            let checks: [(&str, Taylor, f64); 10] = [
                ("add", a + b, x + y),
                ("sub", a - b, x - y),
                ("mul", a * b, x * y),
                ("sqr", a.sqr(), x * x),
                ("scale", a.scale(k), x * k),
                ("div_cst", a.div_cst(k), x / k),
                ("sin", a.sin(), x.sin()),
                ("cos", a.cos(), x.cos()),
                ("sin_cos.0", a.sin_cos().0, x.sin()),
                ("sin_cos.1", a.sin_cos().1, x.cos()),
            ];
            for (name, m, v) in checks {
                assert!(
                    admits(m, t, v),
                    "{name}: {a:?} {b:?} at t={t}: {v} not in {m:?}"
                );
                assert!(m.enclosure().contains(v), "{name} enclosure");
            }
            let div = a / b;
            assert!(
                admits(div, t, x / y) || div.enclosure() == Interval::ENTIRE,
                "div: {a:?} / {b:?} at {t}"
            );
            let sqrt = a.sqrt();
            assert!(
                x < 0.0 || admits(sqrt, t, x.sqrt()) || sqrt.enclosure() == Interval::ENTIRE,
                "sqrt: {a:?} at {t}"
            );
            // A cubic with interval coefficients, at the model's centre and off it.
            let kc = [0, 1, 2, 3].map(|_| {
                let c = rng.range(-2.0, 2.0);
                Interval::new(c, c + rng.range(0.0, 0.01))
            });
            let kv = kc.map(|k| rng.range(k.lo, k.hi));
            for m in [a.c, a.c + rng.range(-0.1, 0.1)] {
                let z = x - m;
                let v = kv[0] + z * (kv[1] + z * (kv[2] + z * kv[3]));
                assert!(admits(a.cubic_at(m, kc), t, v), "cubic at {m}: {a:?}");
            }
        }
    }

    /// [`Taylor::slope_per_unit`] turns a model of a cell's variable `t` into one of `u`: a
    /// cubic's model over cells `1e-9` to `10` wide, centred anywhere in `[-1e3, 1e3]`, holds
    /// the cubic at points across the cell as `c + s (u - m) + [-rho, rho]` with the slope and
    /// remainder it gives (no slack but the check's own rounding); a point's model (`h = 0`)
    /// keeps its value. It fails where the slope is not divided by `h`.
    #[test]
    fn slopes_per_unit_hold_the_model() {
        use crate::test_rng::Dd;
        let mut rng = Lcg(4242);
        for case in 0..4000 {
            let k: [f64; 4] =
                std::array::from_fn(|_| rng.range(-2.0, 2.0) * 10f64.powf(rng.range(0.0, 6.0)));
            let lo = rng.range(-1e3, 1e3);
            let hi = lo + 10f64.powf(rng.range(-9.0, 1.0));
            let var = Taylor::var(lo, hi);
            let (m, h) = (var.c, var.s);
            // The cubic's exact coefficients about `m`.
            let model = var.cubic_at(m, k.map(|x| Interval::new(x, x)));
            let (s, rho) = model.slope_per_unit(h);
            for i in 0..=16 {
                let u = lo + (hi - lo) * i as f64 / 16.0;
                let z = Dd::of(u).add(Dd::of(-m));
                let exact = Dd::of(k[0])
                    .add(z.mul(Dd::of(k[1]).add(z.mul(Dd::of(k[2]).add(z.mul(Dd::of(k[3])))))));
                let line = Dd::of(model.c).add(Dd::of(s).mul(z));
                let err = exact.add(line.mul(Dd::of(-1.0))).value().abs();
                assert!(
                    err <= rho * (1.0 + 1e-12),
                    "case {case}: {err:e} > {rho:e} at {u} in [{lo}, {hi}]"
                );
            }
        }
        let point = Taylor::cst(2.0).scale(3.0);
        let (slope, rho) = point.slope_per_unit(0.0);
        assert!(slope == 0.0 && rho >= point.rho && rho <= 2.0 * point.rho + 1e-300);
        // Any slope and half-width (subnormal to `1e300`): the line in `u` moves from the
        // model's by `|s - q h|` at most (at `|t| = 1`), which the remainder's growth must
        // hold; without the term for a subnormal quotient it falls 13 to 1e11 times short.
        let mut subnormal = 0;
        for case in 0..200_000 {
            let h = 10f64.powf(rng.range(-300.0, 300.0));
            let s = rng.range(-1.0, 1.0) * 10f64.powf(rng.range(-320.0, 300.0));
            let rho = if case % 2 == 0 {
                0.0
            } else {
                s.abs() * 10f64.powf(rng.range(-20.0, 0.0))
            };
            let m = Taylor { c: 1.0, s, rho };
            let (q, grown) = m.slope_per_unit(h);
            if !q.is_finite() {
                continue;
            }
            if q != 0.0 && q.abs() < f64::MIN_POSITIVE || q == 0.0 && s != 0.0 {
                subnormal += 1;
            }
            let moved = Dd::of(s).add(Dd::of(q).mul(Dd::of(-h))).value().abs();
            let room = Dd::of(grown).add(Dd::of(-rho)).value();
            assert!(
                moved <= room,
                "case {case}: s {s:e}, h {h:e}: the line moves {moved:e}, room {room:e}"
            );
        }
        assert!(subnormal > 1000, "{subnormal} subnormal quotients");
    }

    /// `1/x` and `sqrt` hold their members at any magnitude: models with centres `1e-300` to
    /// `1e300` (positive, and negative for `1/x`), slopes and remainders a fraction of the
    /// centre, at `t` across `[-1, 1]` and the remainder's ends. An independent review found
    /// both off by `1e14` to `1e16` times the remainder above `5e102` (`1/x`) and `3e205`
    /// (`sqrt`), where the curvature bound overflowed to a zero.
    #[test]
    fn taylor_reciprocals_and_roots_hold_at_any_magnitude() {
        let mut rng = Lcg(1077);
        for case in 0..20000 {
            let c = 10f64.powf(rng.range(-300.0, 300.0));
            let s = c * rng.range(-0.9, 0.9) * 10f64.powf(rng.range(-6.0, 0.0));
            let rho = if case % 3 == 0 {
                0.0
            } else {
                (c - s.abs()) * 10f64.powf(rng.range(-12.0, -1.0))
            };
            for sign in [1.0, -1.0] {
                let x = Taylor {
                    c: sign * c,
                    s,
                    rho,
                };
                let (recip, root) = (x.recip(), x.sqrt());
                for i in 0..=8 {
                    let t = i as f64 / 4.0 - 1.0;
                    for r in [-rho, 0.0, rho] {
                        let v = x.c + x.s * t + r;
                        let want = 1.0 / v;
                        let slack = 1e-14 * want.abs();
                        assert!(
                            (want - (recip.c + recip.s * t)).abs() <= recip.rho + slack,
                            "case {case}: 1/{v:e} = {want:e} outside {recip:?} at {t}"
                        );
                        if sign > 0.0 {
                            let want = v.sqrt();
                            let slack = 1e-14 * want;
                            assert!(
                                (want - (root.c + root.s * t)).abs() <= root.rho + slack,
                                "case {case}: sqrt {v:e} = {want:e} outside {root:?} at {t}"
                            );
                        }
                    }
                }
            }
        }
    }

    /// `cubic_jet` encloses a cubic and its first two derivatives over a cell, and in a [`Dual`]
    /// their derivatives too (chained through the variable's own derivative, 1 or not): for
    /// `Dual<Taylor>`, `Dual<Interval>` and `Taylor`, at points sampled across the cell and at
    /// its ends, with the coefficients known only as intervals around the true ones.
    #[test]
    fn cubic_jets_enclose_the_cubic_and_its_derivatives() {
        let mut rng = Lcg(77);
        for case in 0..2000 {
            // p(x) = sum c_i (x - m)^i, exact coefficients; the jet gets p^(j)(m) widened.
            let c: [f64; 4] = std::array::from_fn(|_| rng.range(-2.0, 2.0));
            let (lo, hi) = {
                let a = rng.range(-1.0, 2.0);
                (a, a + 10f64.powf(rng.range(-9.0, 0.0)))
            };
            let m = 0.5 * (lo + hi);
            let p = |x: f64, j: usize| {
                let z = x - m;
                match j {
                    0 => c[0] + z * (c[1] + z * (c[2] + z * c[3])),
                    1 => c[1] + z * (2.0 * c[2] + z * 3.0 * c[3]),
                    2 => 2.0 * c[2] + 6.0 * c[3] * z,
                    _ => 6.0 * c[3],
                }
            };
            let widen = |v: f64| {
                let w = if case % 3 == 0 {
                    0.0
                } else {
                    1e-12 * (1.0 + v.abs())
                };
                Interval::new(v - w, v + w)
            };
            let d = [0, 1, 2, 3].map(|j| widen(p(m, j)));
            // The variable's derivative: 1 (the isolator's) or another constant.
            let dx = if case % 2 == 0 {
                1.0
            } else {
                rng.range(-3.0, 3.0)
            };
            let taylor = Dual {
                v: Taylor::var(lo, hi),
                d: Taylor::cst(dx),
            }
            .cubic_jet(m, d);
            let interval = Dual {
                v: Interval::exact(lo, hi),
                d: Interval::cst(dx),
            }
            .cubic_jet(m, d);
            let plain = Taylor::var(lo, hi).cubic_jet(m, d);
            // `x = m + h t`.
            let h = Taylor::var(lo, hi).s;
            for i in 0..=20 {
                let x = lo + (hi - lo) * i as f64 / 20.0;
                let t = (x - m) / h;
                for j in 0..3 {
                    let (value, slope) = (p(x, j), p(x, j + 1) * dx);
                    let slack = 1e-13 * (1.0 + value.abs() + slope.abs());
                    assert!(admits(taylor[j].v, t, value), "case {case}: Taylor p^({j})");
                    assert!(admits(plain[j], t, value), "case {case}: plain p^({j})");
                    assert!(
                        admits(taylor[j].d, t, slope),
                        "case {case}: Taylor p^({j})' at {x}: {slope} not in {:?}",
                        taylor[j].d
                    );
                    let iv = interval[j];
                    assert!(
                        iv.v.lo - slack <= value && value <= iv.v.hi + slack,
                        "case {case}: interval p^({j})"
                    );
                    assert!(
                        iv.d.lo - slack <= slope && slope <= iv.d.hi + slack,
                        "case {case}: interval p^({j})'"
                    );
                }
            }
        }
        // What the shortcut for an exact 1 may rely on.
        assert!(Taylor::cst(1.0).is_exactly(1.0));
        assert!(
            !Taylor::var(0.0, 1.0).is_exactly(0.5),
            "a variable is no constant"
        );
        assert!(!Taylor::lift(Interval::new(1.0, 1.0 + 1e-15)).is_exactly(1.0));
        assert!(Dual::var(Taylor::var(0.0, 1.0)).d.is_exactly(1.0));
        assert!(
            !Dual::var(2.0).is_exactly(2.0),
            "its derivative is 1, not 0"
        );
        assert!(Dual::<f64>::cst(2.0).is_exactly(2.0));
        assert!(Interval::cst(1.0).is_exactly(1.0) && !Interval::new(1.0, 2.0).is_exactly(1.0));
    }

    /// The shortcuts by constants give what the general operations give: `cross_cst` the cross
    /// product with a constant vector (to the bit in `f64`, and enclosing the members' in
    /// Taylor models), and `Dual<Taylor>`'s quotient, which shares one reciprocal, the two
    /// quotients of the general formula to the bit.
    #[test]
    fn constant_shortcuts_agree_with_the_general_operations() {
        use glam::DVec3;
        let mut rng = Lcg(31);
        for _ in 0..5000 {
            let h = rng.range(0.0, 0.3);
            let k = DVec3::new(
                rng.range(-2.0, 2.0),
                rng.range(-2.0, 2.0),
                rng.range(-2.0, 2.0),
            );
            // Three models sharing `t`, and a member of each there.
            let t = rng.range(-1.0, 1.0);
            let [(a, _, _), (b, _, _), (c, _, _)] = [0, 1, 2].map(|_| random_model(&mut rng, h));
            let member = |m: Taylor, f: f64| m.c + m.s * t + f * m.rho;
            let x = DVec3::new(member(a, 0.37), member(b, -0.8), member(c, 1.0));
            let got = V3::new(a, b, c).cross_cst(k);
            let want = x.cross(k);
            for (m, w) in [(got.x, want.x), (got.y, want.y), (got.z, want.z)] {
                assert!(admits(m, t, w), "cross_cst: {w} not in {m:?}");
            }
            let plain = V3::new(x.x, x.y, x.z);
            assert_eq!(plain.cross_cst(k).value(), plain.cross(V3::cst(k)).value());
            // Quotients.
            let (p, q) = (
                Dual { v: a, d: b },
                Dual {
                    v: c + Taylor::cst(4.0),
                    d: b,
                },
            );
            let quotient = p / q;
            let v = p.v / q.v;
            let d = (p.d - v * q.d) / q.v;
            assert_eq!(
                (quotient.v, quotient.d),
                (v, d),
                "one reciprocal, the same models"
            );
        }
    }

    /// `rotate_back` in `Dual<Taylor>` and `Dual<Interval>` encloses the turned functions and
    /// their derivatives (analytic, at points across the cell), with the values to the bit of
    /// the plain rule's; a constant angle (no derivative) too.
    #[test]
    fn rotate_back_encloses_the_turned_functions_and_their_derivatives() {
        let mut rng = Lcg(5);
        for case in 0..2000 {
            let (th0, k) = (
                rng.range(-4.0, 4.0),
                if case % 4 == 0 {
                    0.0
                } else {
                    rng.range(-7.0, 7.0)
                },
            );
            let a: [f64; 3] = std::array::from_fn(|_| rng.range(-2.0, 2.0));
            let b: [f64; 3] = std::array::from_fn(|_| rng.range(-2.0, 2.0));
            fn quad<T: Real>(c: [f64; 3], u: T) -> T {
                T::cst(c[0]) + u * (T::cst(c[1]) + u.scale(c[2]))
            }
            let lo = rng.range(-1.0, 1.0);
            let hi = lo + 10f64.powf(rng.range(-8.0, -0.5));
            let theta = |u: Dual<Taylor>| {
                if k == 0.0 {
                    Dual::cst(th0)
                } else {
                    Dual::cst(th0) + u.scale(k)
                }
            };
            let u = Dual::var(Taylor::var(lo, hi));
            let (x, y) = (quad(a, u), quad(b, u));
            let (rx, ry) = theta(u).rotate_back(x, y);
            let (s, c) = theta(u).v.sin_cos();
            assert_eq!(
                (rx.v, ry.v),
                (c * x.v + s * y.v, c * y.v - s * x.v),
                "values"
            );
            let ui = Dual::var(Interval::exact(lo, hi));
            let th = Dual::cst(th0) + ui.scale(k);
            let (ix, iy) = th.rotate_back(quad(a, ui), quad(b, ui));
            let Taylor { c: m, s: h, .. } = Taylor::var(lo, hi);
            for i in 0..=16 {
                let w = lo + (hi - lo) * i as f64 / 16.0;
                let p = Dual::var(w);
                let (px, py) = (Dual::cst(th0) + p.scale(k)).rotate_back(quad(a, p), quad(b, p));
                // The truth from the plain rule in f64 (point types keep it), with slack for its
                // rounding.
                for (name, model, iv, want) in [
                    ("x", rx.v, ix.v, px.v),
                    ("y", ry.v, iy.v, py.v),
                    ("x'", rx.d, ix.d, px.d),
                    ("y'", ry.d, iy.d, py.d),
                ] {
                    let slack = 1e-13 * (1.0 + want.abs());
                    let t = (w - m) / h;
                    assert!(
                        (want - (model.c + model.s * t)).abs() <= model.rho + slack,
                        "case {case} {name} at {w}: {want} not in {model:?}"
                    );
                    assert!(
                        iv.lo - slack <= want && want <= iv.hi + slack,
                        "case {case} {name}: interval {iv:?} misses {want}"
                    );
                }
            }
        }
    }

    /// The products' tests' magnitude (`1e-8` to `1e8`) and domain half-width (every third
    /// case a constant's, 0; a model's slope is one in `u` times it) for case `case`.
    fn product_case(rng: &mut Lcg, case: usize) -> (f64, f64) {
        let scale = 10f64.powf(rng.range(-8.0, 8.0));
        let h = if case.is_multiple_of(3) {
            0.0
        } else {
            rng.range(0.0, 0.5)
        };
        (scale, h)
    }

    /// The rounding bounds of `mul` and `sqr` hold with no slack: for models without a
    /// remainder, `(a0 + a1 t)(b0 + b1 t)` in double-double at points across `[-1, 1]` (and
    /// constants, `h = 0`, where the remainder is only rounding) lies within `rho` of the
    /// computed `c + s t`, itself taken in double-double.
    #[test]
    fn taylor_products_bound_their_rounding() {
        use crate::test_rng::Dd;
        let mut rng = Lcg(99);
        let mut tight = 0.0f64;
        for case in 0..20000 {
            let (scale, h) = product_case(&mut rng, case);
            let model = |rng: &mut Lcg| Taylor {
                c: rng.range(-1.0, 1.0) * scale,
                s: rng.range(-1.0, 1.0) * scale * h,
                rho: 0.0,
            };
            let (a, b) = (model(&mut rng), model(&mut rng));
            for (name, m, (x, y)) in [("mul", a * b, (a, b)), ("sqr", a.sqr(), (a, a))] {
                for i in 0..=8 {
                    let t = i as f64 / 4.0 - 1.0;
                    let at = |p: Taylor| Dd::of(p.c).add(Dd::of(p.s).mul(Dd::of(t)));
                    let exact = at(x).mul(at(y));
                    let err = exact.add(Dd::of(-m.c)).add(Dd::of(-m.s).mul(Dd::of(t)));
                    let err = err.value().abs();
                    assert!(
                        err <= m.rho,
                        "{name} case {case}: error {err:e} > rho {:e}",
                        m.rho
                    );
                    if m.rho > 0.0 {
                        tight = tight.max(err / m.rho);
                    }
                }
            }
        }
        // The bound is not vacuous: some error comes within a factor 20 of it.
        assert!(tight > 0.05, "largest error / rho = {tight}");
        // A subnormal slope against a huge centre (a review's case, when the slope was in `u`
        // and `t` in `[-h, h]` with `h = 1e-160`, was `|a1| h` underflowing to 0 in the
        // magnitudes; the scaled slope is that product, here subnormal): the product's slope
        // `a0 b1` is normal and rounded, and the bound holds it.
        let t = 1.0;
        let a = Taylor {
            c: 1.2345678901234567e200,
            s: 0.0,
            rho: 0.0,
        };
        let b = Taylor {
            c: 0.0,
            s: 1.111_111_113e-315,
            rho: 0.0,
        };
        let m = a * b;
        let exact = Dd::of(a.c).mul(Dd::of(b.s)).mul(Dd::of(t));
        let err = exact.add(Dd::of(-m.c)).add(Dd::of(-m.s).mul(Dd::of(t)));
        let err = err.value().abs();
        assert!(err <= m.rho, "underflow: {err:e} > {:e}", m.rho);
    }

    /// The products' bounds hold for slopes from subnormal to `1e23` (a slope in `u` of
    /// `1e-8` to `1e8` times a domain's half-width of `1e-300` to `1e15`; an independent review
    /// found the products losing the `t^2` term or overshooting their bound on such domains
    /// when the slope was kept in `u`): models with centres 0 or not, against double-double
    /// at points across `[-1, 1]`, for `mul`, `sqr` and the dual product's derivative.
    #[test]
    fn taylor_products_hold_on_extreme_domains() {
        use crate::test_rng::Dd;
        let mut rng = Lcg(1154);
        for case in 0..20000 {
            let h = 10f64.powf(rng.range(-300.0, 15.0));
            let model = |rng: &mut Lcg| Taylor {
                c: if rng.next() < 0.5 {
                    0.0
                } else {
                    rng.range(-1.0, 1.0) * 10f64.powf(rng.range(-8.0, 8.0))
                },
                s: rng.range(-1.0, 1.0) * 10f64.powf(rng.range(-8.0, 8.0)) * h,
                rho: 0.0,
            };
            let (a, b) = (model(&mut rng), model(&mut rng));
            let (c, e) = (model(&mut rng), model(&mut rng));
            let pair = Taylor::dual_product(Dual { v: a, d: c }, Dual { v: b, d: e });
            let at = |p: Taylor, t: f64| Dd::of(p.c).add(Dd::of(p.s).mul(Dd::of(t)));
            for i in 0..=8 {
                let t = i as f64 / 4.0 - 1.0;
                let checks = [
                    ("mul", a * b, at(a, t).mul(at(b, t))),
                    ("sqr", a.sqr(), at(a, t).mul(at(a, t))),
                    (
                        "dual",
                        pair.d,
                        at(c, t).mul(at(b, t)).add(at(a, t).mul(at(e, t))),
                    ),
                ];
                for (name, m, exact) in checks {
                    if !(m.c.is_finite() && m.s.is_finite()) {
                        // A slope past the largest float: the whole line.
                        assert_eq!(m.enclosure(), Interval::ENTIRE, "{name} case {case}");
                        continue;
                    }
                    let err = exact.add(Dd::of(-m.c)).add(Dd::of(-m.s).mul(Dd::of(t)));
                    let err = err.value().abs();
                    assert!(
                        err <= m.rho,
                        "{name} case {case}, h = {h:e}: error {err:e} > rho {:e}",
                        m.rho
                    );
                }
            }
        }
    }

    /// [`Taylor`]'s dual product ([`Real::dual_product`]) is the separate products' and sum's
    /// to the bit in every centre and slope, its value part in everything, and its derivative's
    /// remainder no larger; that remainder bounds the rounding with no slack (models without a
    /// remainder against double-double at points across `[-1, 1]`, constants among them, scales
    /// `1e-8` to `1e8`), and members of the factors' sets give members of the product's.
    #[test]
    fn taylor_dual_products_are_the_products_and_their_sum() {
        use crate::test_rng::Dd;
        let mut rng = Lcg(2026);
        let mut tight = 0.0f64;
        for case in 0..20000 {
            let (scale, h) = product_case(&mut rng, case);
            let exact_case = case % 2 == 0;
            let model = |rng: &mut Lcg| {
                // A constant now and then, as the radial function's factors have them.
                let constant = h == 0.0 || rng.next() < 0.15;
                let (m, _, _) = random_model(rng, if constant { 0.0 } else { h });
                Taylor {
                    c: m.c * scale,
                    s: m.s * scale,
                    rho: if exact_case { 0.0 } else { m.rho * scale },
                }
            };
            let a = Dual {
                v: model(&mut rng),
                d: model(&mut rng),
            };
            let b = Dual {
                v: model(&mut rng),
                d: model(&mut rng),
            };
            let fused = Taylor::dual_product(a, b);
            for i in 0..=8 {
                let t = i as f64 / 4.0 - 1.0;
                if exact_case {
                    let at = |p: Taylor| Dd::of(p.c).add(Dd::of(p.s).mul(Dd::of(t)));
                    let exact = at(a.d).mul(at(b.v)).add(at(a.v).mul(at(b.d)));
                    let err = exact
                        .add(Dd::of(-fused.d.c))
                        .add(Dd::of(-fused.d.s).mul(Dd::of(t)));
                    let err = err.value().abs();
                    assert!(
                        err <= fused.d.rho,
                        "case {case}: error {err:e} > {:e}",
                        fused.d.rho
                    );
                    if fused.d.rho > 0.0 {
                        tight = tight.max(err / fused.d.rho);
                    }
                } else {
                    let member =
                        |p: Taylor, rng: &mut Lcg| p.c + p.s * t + rng.range(-p.rho, p.rho);
                    let (av, ad) = (member(a.v, &mut rng), member(a.d, &mut rng));
                    let (bv, bd) = (member(b.v, &mut rng), member(b.d, &mut rng));
                    assert!(
                        admits(fused.d, t, ad * bv + av * bd),
                        "case {case}: a member at t = {t} outside {:?}",
                        fused.d
                    );
                }
            }
            let (v, d) = (a.v * b.v, a.d * b.v + a.v * b.d);
            assert_eq!(fused.v, v, "case {case}: the value part");
            assert_eq!(
                (fused.d.c.to_bits(), fused.d.s.to_bits()),
                (d.c.to_bits(), d.s.to_bits()),
                "case {case}: the derivative's centre and slope"
            );
            assert!(
                fused.d.rho <= d.rho,
                "case {case}: {:e} > {:e}",
                fused.d.rho,
                d.rho
            );
        }
        assert!(tight > 0.05, "largest error / rho = {tight}");
    }

    /// The point of Taylor models: they enclose a smooth function's range, and its derivative's,
    /// to second order in the width (halving the interval quarters the excess), where interval
    /// arithmetic is off to first order (halving only halves it).
    #[test]
    fn taylor_enclosures_are_tight() {
        fn f<T: Real>(x: T) -> T {
            x.sin() * x.sqrt() / (T::cst(1.0) + x.sqr())
        }
        // Excess widths over the sampled ranges: [Taylor value, Taylor slope, interval value,
        // interval slope].
        let excess = |lo: f64, hi: f64| {
            let samples: Vec<(f64, f64)> = (0..=200)
                .map(|i| {
                    let r = f(Dual::var(lo + (hi - lo) * i as f64 / 200.0));
                    (r.v, r.d)
                })
                .collect();
            let range = |k: fn(&(f64, f64)) -> f64| {
                let v = samples.iter().map(k);
                let (a, b) = (
                    v.clone().fold(f64::INFINITY, f64::min),
                    v.fold(f64::NEG_INFINITY, f64::max),
                );
                Interval::exact(a, b)
            };
            let (rv, rd) = (range(|s| s.0), range(|s| s.1));
            let tm = f(Dual::var(Taylor::var(lo, hi)));
            let iv = f(Dual::var(Interval::exact(lo, hi)));
            [
                (tm.v.enclosure(), rv),
                (tm.d.enclosure(), rd),
                (iv.v, rv),
                (iv.d, rd),
            ]
            .map(|(e, r)| {
                assert!(e.lo <= r.lo && r.hi <= e.hi, "{e:?} must hold {r:?}");
                e.width() - r.width()
            })
        };
        let w = [0.04, 0.02, 0.01].map(|w| excess(0.3, 0.3 + w));
        for k in 0..2 {
            assert!(
                w[0][k] > 3.0 * w[1][k] && w[1][k] > 3.0 * w[2][k],
                "Taylor {k}: {w:?}"
            );
            assert!(
                w[0][k + 2] < 2.5 * w[1][k + 2] && w[2][k + 2] > 20.0 * w[2][k],
                "interval {k}: {w:?}"
            );
        }
    }

    /// `sqrt` and `1/x` of small arguments keep their linear part: the rounding error of the
    /// slope (`1 / (2 sqrt(c))`, large) is charged to the slope only. When it was charged to the
    /// value too, `sqrt` of `|C|^2 ~ 1e-13` (a' x a'' near an inflection of the axis) came out
    /// as a constant with a remainder of 0.3% of its value, and the unit binormal `C / |C|`
    /// with a remainder of 1e-3 however narrow the interval.
    #[test]
    fn taylor_sqrt_of_small_values_stays_first_order() {
        let (lo, hi) = (1e-7, 1e-7 + 1e-10);
        let x = Taylor::var(lo, hi);
        for (name, model, f) in [
            ("sqrt", x.sqr().sqrt(), (|x: f64| x) as fn(f64) -> f64),
            ("x / sqrt(x^2)", x / x.sqr().sqrt(), |_| 1.0),
        ] {
            let e = model.enclosure();
            for k in 0..=8 {
                let u = lo + (hi - lo) * k as f64 / 8.0;
                assert!(e.contains(f(u)), "{name}: {e:?} must hold {}", f(u));
            }
            // Second order: the excess is about (width / x)^2 = 1e-6 of the value.
            let exact = f(hi) - f(lo);
            assert!(
                e.width() <= exact + 1e-5 * f(lo).abs(),
                "{name}: {e:?}, width {} against {exact}",
                e.width()
            );
        }
    }
}
