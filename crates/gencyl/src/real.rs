//! Scalars the geometry is written over once and evaluated in several ways.
//!
//! The curve `phi(u)` of the Hsu-Chelberg method, the frame and the sweep rule are written
//! generically over [`Real`], then evaluated with
//! - `f64` for values,
//! - [`Dual`] for exact derivatives (forward-mode automatic differentiation; nest it for higher
//!   derivatives),
//! - [`Interval`] for guaranteed enclosures over a parameter range, which is what lets the root
//!   finders prove that a range holds no root, or exactly one.

use std::ops::{Add, Div, Mul, Neg, Sub};

/// A real scalar: `f64`, a dual number, or an interval.
pub trait Real:
    Copy
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
    /// Sine.
    fn sin(self) -> Self;
    /// Cosine.
    fn cos(self) -> Self;
    /// `self * self`; intervals give the tight (non-negative) square.
    fn sqr(self) -> Self {
        self * self
    }
    /// `self * k` for a constant `k`.
    fn scale(self, k: f64) -> Self {
        self * Self::cst(k)
    }
}

impl Real for f64 {
    #[inline]
    fn cst(x: f64) -> Self {
        x
    }
    #[inline]
    fn value(self) -> f64 {
        self
    }
    #[inline]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline]
    fn sin(self) -> Self {
        f64::sin(self)
    }
    #[inline]
    fn cos(self) -> Self {
        f64::cos(self)
    }
    #[inline]
    fn scale(self, k: f64) -> Self {
        self * k
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
    #[inline]
    fn add(self, o: Self) -> Self {
        Dual {
            v: self.v + o.v,
            d: self.d + o.d,
        }
    }
}
impl<T: Real> Sub for Dual<T> {
    type Output = Self;
    #[inline]
    fn sub(self, o: Self) -> Self {
        Dual {
            v: self.v - o.v,
            d: self.d - o.d,
        }
    }
}
impl<T: Real> Mul for Dual<T> {
    type Output = Self;
    #[inline]
    fn mul(self, o: Self) -> Self {
        Dual {
            v: self.v * o.v,
            d: self.d * o.v + self.v * o.d,
        }
    }
}
impl<T: Real> Div for Dual<T> {
    type Output = Self;
    /// `(f/g)' = (f' g - f g') / g^2`
    #[inline]
    fn div(self, o: Self) -> Self {
        let v = self.v / o.v;
        Dual {
            v,
            d: (self.d - v * o.d) / o.v,
        }
    }
}
impl<T: Real> Neg for Dual<T> {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        Dual {
            v: -self.v,
            d: -self.d,
        }
    }
}

impl<T: Real> Real for Dual<T> {
    #[inline]
    fn cst(x: f64) -> Self {
        Dual {
            v: T::cst(x),
            d: T::cst(0.0),
        }
    }
    #[inline]
    fn value(self) -> f64 {
        self.v.value()
    }
    #[inline]
    fn sqrt(self) -> Self {
        let s = self.v.sqrt();
        Dual {
            v: s,
            d: self.d / (s + s),
        }
    }
    #[inline]
    fn sin(self) -> Self {
        Dual {
            v: self.v.sin(),
            d: self.d * self.v.cos(),
        }
    }
    #[inline]
    fn cos(self) -> Self {
        Dual {
            v: self.v.cos(),
            d: -(self.d * self.v.sin()),
        }
    }
    #[inline]
    fn sqr(self) -> Self {
        Dual {
            v: self.v.sqr(),
            d: (self.v * self.d).scale(2.0),
        }
    }
    #[inline]
    fn scale(self, k: f64) -> Self {
        Dual {
            v: self.v.scale(k),
            d: self.d.scale(k),
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
    #[inline]
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
    #[inline]
    pub fn exact(lo: f64, hi: f64) -> Self {
        Interval { lo, hi }
    }

    /// Whether `x` lies in the interval.
    #[inline]
    pub fn contains(self, x: f64) -> bool {
        self.lo <= x && x <= self.hi
    }

    /// Whether the interval holds only strictly positive, or only strictly negative, numbers.
    #[inline]
    pub fn excludes_zero(self) -> bool {
        self.lo > 0.0 || self.hi < 0.0
    }

    /// `hi - lo`.
    #[inline]
    pub fn width(self) -> f64 {
        self.hi - self.lo
    }
}

#[inline]
fn min4(a: f64, b: f64, c: f64, d: f64) -> f64 {
    a.min(b).min(c.min(d))
}
#[inline]
fn max4(a: f64, b: f64, c: f64, d: f64) -> f64 {
    a.max(b).max(c.max(d))
}

impl Add for Interval {
    type Output = Self;
    #[inline]
    fn add(self, o: Self) -> Self {
        Interval::new(self.lo + o.lo, self.hi + o.hi)
    }
}
impl Sub for Interval {
    type Output = Self;
    #[inline]
    fn sub(self, o: Self) -> Self {
        Interval::new(self.lo - o.hi, self.hi - o.lo)
    }
}
impl Mul for Interval {
    type Output = Self;
    #[inline]
    fn mul(self, o: Self) -> Self {
        let (a, b, c, d) = (
            self.lo * o.lo,
            self.lo * o.hi,
            self.hi * o.lo,
            self.hi * o.hi,
        );
        // 0 * inf is NaN; the true product set is unbounded only if a factor is.
        if a.is_nan() || b.is_nan() || c.is_nan() || d.is_nan() {
            return Interval::ENTIRE;
        }
        Interval::new(min4(a, b, c, d), max4(a, b, c, d))
    }
}
impl Div for Interval {
    type Output = Self;
    #[inline]
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
        if a.is_nan() || b.is_nan() || c.is_nan() || d.is_nan() {
            return Interval::ENTIRE;
        }
        Interval::new(min4(a, b, c, d), max4(a, b, c, d))
    }
}
impl Neg for Interval {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        Interval {
            lo: -self.hi,
            hi: -self.lo,
        }
    }
}

impl Real for Interval {
    #[inline]
    fn cst(x: f64) -> Self {
        Interval { lo: x, hi: x }
    }
    #[inline]
    fn value(self) -> f64 {
        0.5 * (self.lo + self.hi)
    }
    #[inline]
    fn sqrt(self) -> Self {
        // Rounding can push a sum of squares a hair below zero; the exact value is not.
        Interval::new(self.lo.max(0.0).sqrt(), self.hi.max(0.0).sqrt())
    }
    #[inline]
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
        Interval::new((lo - 4e-16).max(-1.0), (hi + 4e-16).min(1.0))
    }
    #[inline]
    fn sqr(self) -> Self {
        let (a, b) = (self.lo * self.lo, self.hi * self.hi);
        if self.lo > 0.0 || self.hi < 0.0 {
            Interval::new(a.min(b), a.max(b))
        } else {
            Interval::new(0.0, a.max(b))
        }
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
    #[inline]
    pub fn new(x: T, y: T) -> Self {
        V2 { x, y }
    }
    /// Lifts a constant `f64` vector.
    #[inline]
    pub fn cst(p: glam::DVec2) -> Self {
        V2 {
            x: T::cst(p.x),
            y: T::cst(p.y),
        }
    }
    /// The dot product.
    #[inline]
    pub fn dot(self, o: Self) -> T {
        self.x * o.x + self.y * o.y
    }
    /// `|self|^2`.
    #[inline]
    pub fn norm2(self) -> T {
        self.x.sqr() + self.y.sqr()
    }
    /// Representative values.
    #[inline]
    pub fn value(self) -> glam::DVec2 {
        glam::DVec2::new(self.x.value(), self.y.value())
    }
}

impl<T: Real> V3<T> {
    /// `(x, y, z)`.
    #[inline]
    pub fn new(x: T, y: T, z: T) -> Self {
        V3 { x, y, z }
    }
    /// Lifts a constant `f64` vector.
    #[inline]
    pub fn cst(p: glam::DVec3) -> Self {
        V3 {
            x: T::cst(p.x),
            y: T::cst(p.y),
            z: T::cst(p.z),
        }
    }
    /// The dot product.
    #[inline]
    pub fn dot(self, o: Self) -> T {
        self.x * o.x + self.y * o.y + self.z * o.z
    }
    /// The dot product with a constant vector.
    #[inline]
    pub fn dot_cst(self, o: glam::DVec3) -> T {
        self.x.scale(o.x) + self.y.scale(o.y) + self.z.scale(o.z)
    }
    /// The cross product.
    #[inline]
    pub fn cross(self, o: Self) -> Self {
        V3 {
            x: self.y * o.z - self.z * o.y,
            y: self.z * o.x - self.x * o.z,
            z: self.x * o.y - self.y * o.x,
        }
    }
    /// `|self|^2`.
    #[inline]
    pub fn norm2(self) -> T {
        self.x.sqr() + self.y.sqr() + self.z.sqr()
    }
    /// `self * k`.
    #[inline]
    pub fn scaled(self, k: T) -> Self {
        V3 {
            x: self.x * k,
            y: self.y * k,
            z: self.z * k,
        }
    }
    /// `self / k`.
    #[inline]
    pub fn divided(self, k: T) -> Self {
        V3 {
            x: self.x / k,
            y: self.y / k,
            z: self.z / k,
        }
    }
    /// Representative values.
    #[inline]
    pub fn value(self) -> glam::DVec3 {
        glam::DVec3::new(self.x.value(), self.y.value(), self.z.value())
    }
}

impl<T: Real> Add for V3<T> {
    type Output = Self;
    #[inline]
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
    #[inline]
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
    #[inline]
    fn add(self, o: Self) -> Self {
        V2 {
            x: self.x + o.x,
            y: self.y + o.y,
        }
    }
}
impl<T: Real> Sub for V2<T> {
    type Output = Self;
    #[inline]
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
    }
}
