//! Root finding: closed-form quadratics and a guaranteed root isolator for smooth functions.

use arrayvec::ArrayVec;

use crate::real::{Dual, Interval, Real};

/// Real roots of `a x^2 + b x + c`, ascending, by the cancellation-free formula
/// `q = -(b + sign(b) sqrt(b^2 - 4ac)) / 2`, roots `q/a` and `c/q`. Degrades to the linear case
/// when `a = 0`; a double root is returned once.
pub fn quadratic_roots(a: f64, b: f64, c: f64) -> ArrayVec<f64, 2> {
    let mut out = ArrayVec::new();
    if a == 0.0 {
        if b != 0.0 {
            out.push(-c / b);
        }
        return out;
    }
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 {
        return out;
    }
    let q = -0.5 * (b + b.signum() * disc.sqrt());
    if q == 0.0 {
        // b = 0 and c = 0: double root at 0.
        out.push(0.0);
        return out;
    }
    let (r0, r1) = (q / a, c / q);
    let (lo, hi) = if r0 <= r1 { (r0, r1) } else { (r1, r0) };
    out.push(lo);
    if hi != lo {
        out.push(hi);
    }
    out
}

/// Most roots [`isolate_roots`] reports on one interval.
pub const MAX_ROOTS: usize = 16;

/// A smooth real function of one variable that can also be enclosed over an interval.
///
/// `eval` is written once over [`Real`]; [`isolate_roots`] calls it with `Dual<f64>` for values
/// and slopes and with second-order duals of [`Interval`]s for enclosures of the function and
/// its first two derivatives.
pub trait Function1D {
    /// `f(u)` over any scalar.
    fn eval<T: Real>(&self, u: T) -> T;
}

/// Settings of [`isolate_roots`].
#[derive(Clone, Copy, Debug)]
pub struct IsolateOptions {
    /// Subintervals narrower than this are no longer split: they are resolved by a sign test,
    /// or accepted as a tangential (double) root when `|f|` at their midpoint is at most
    /// `tangent_tolerance`.
    pub min_width: f64,
    /// See `min_width`.
    pub tangent_tolerance: f64,
    /// Safety cap on enclosure evaluations per call.
    pub max_evaluations: usize,
}

impl Default for IsolateOptions {
    fn default() -> Self {
        IsolateOptions {
            min_width: 1e-10,
            tangent_tolerance: 1e-9,
            max_evaluations: 4000,
        }
    }
}

/// Finds every root of `f` in `[lo, hi]`, ascending, by interval subdivision:
/// a subinterval whose enclosure of `f` excludes 0 holds no root and is dropped; one whose
/// enclosure of `f'` excludes 0 is monotone and holds a root exactly when `f` changes sign
/// between its ends, found by safeguarded Newton iteration to full precision; others are split
/// in half. The enclosures are rigorous, so no simple root is missed; what the method cannot
/// decide is only a tangential root narrower than `min_width` (see [`IsolateOptions`]).
///
/// Returns whether the evaluation budget sufficed.
pub fn isolate_roots<F: Function1D>(
    f: &F,
    lo: f64,
    hi: f64,
    opts: &IsolateOptions,
    out: &mut ArrayVec<f64, MAX_ROOTS>,
) -> bool {
    let value = |u: f64| {
        let r = f.eval(Dual::var(u));
        (r.v, r.d)
    };
    let mut stack: ArrayVec<(f64, f64), 128> = ArrayVec::new();
    stack.push((lo, hi));
    let mut evaluations = 0;
    let mut complete = true;
    while let Some((a, b)) = stack.pop() {
        evaluations += 1;
        let (fa, fb) = (value(a).0, value(b).0);
        if evaluations > opts.max_evaluations {
            // Out of budget: fall back to sign changes at the ends for what is left.
            complete = false;
            if let Some(r) = bracketed_root(&value, a, b, fa, fb) {
                push_root(out, r);
            }
            continue;
        }
        let (enclosure, slope) = enclose(f, a, b);
        if enclosure.excludes_zero() {
            continue;
        }
        if slope.excludes_zero() {
            if let Some(r) = bracketed_root(&value, a, b, fa, fb) {
                push_root(out, r);
            }
            continue;
        }
        let m = 0.5 * (a + b);
        if b - a <= opts.min_width || m <= a || m >= b || stack.len() + 2 > stack.capacity() {
            if let Some(r) = bracketed_root(&value, a, b, fa, fb) {
                push_root(out, r);
            } else if value(m).0.abs() <= opts.tangent_tolerance
                && !out.last().is_some_and(|&l| m - l <= 2.0 * opts.min_width)
            {
                push_root(out, m);
            }
            continue;
        }
        // Right half first so the left half is processed first: roots come out ascending.
        stack.push((m, b));
        stack.push((a, m));
    }
    // Roots from the budget fallback can come out of order.
    out.sort_by(f64::total_cmp);
    complete
}

/// Enclosures of `f` and `f'` over `[a, b]`: the natural interval extensions intersected with
/// the second-order centred forms (Taylor's theorem about the midpoint `m`, `h = (b - a)/2`)
/// `f(x) in f(m) + f'(m) [-h, h] + f''([a, b]) [0, h^2] / 2` and
/// `f'(x) in f'(m) + f''([a, b]) [-h, h]`, which shrink quadratically with the width where the
/// natural extensions shrink only linearly.
fn enclose<F: Function1D>(f: &F, a: f64, b: f64) -> (Interval, Interval) {
    let second = |x: Interval| {
        f.eval(Dual {
            v: Dual::var(x),
            d: Dual::cst(1.0),
        })
    };
    let whole = second(Interval::exact(a, b));
    let (nat_v, nat_d, dd) = (whole.v.v, whole.v.d, whole.d.d);
    let m = 0.5 * (a + b);
    let h = 0.5 * (b - a);
    let mid = second(Interval::cst(m));
    let (fm, dm) = (mid.v.v, mid.v.d);
    let span = Interval::new(-h, h);
    let value = fm + dm * span + dd * Interval::new(0.0, 0.5 * h * h);
    let slope = dm + dd * span;
    (meet(nat_v, value), meet(nat_d, slope))
}

/// The intersection of two enclosures of the same quantity (either one if they are disjoint,
/// which only rounding of an unbounded enclosure can cause).
fn meet(x: Interval, y: Interval) -> Interval {
    let (lo, hi) = (x.lo.max(y.lo), x.hi.min(y.hi));
    if lo <= hi { Interval::exact(lo, hi) } else { x }
}

fn push_root(out: &mut ArrayVec<f64, MAX_ROOTS>, r: f64) {
    // A root on a shared end point of two subintervals is found twice.
    if out
        .last()
        .is_some_and(|&l| (r - l).abs() <= 1e-14 * (1.0 + r.abs()))
        || out.is_full()
    {
        return;
    }
    out.push(r);
}

/// The root of a continuous `f` in `[a, b]` when `f(a)` and `f(b)` differ in sign (or one is 0),
/// by Newton steps kept inside the shrinking bracket, bisecting when a step leaves it or
/// converges slowly. Stops at the resolution of `f64`.
pub fn bracketed_root(
    value: &impl Fn(f64) -> (f64, f64),
    a: f64,
    b: f64,
    fa: f64,
    fb: f64,
) -> Option<f64> {
    if fa == 0.0 {
        return Some(a);
    }
    if fb == 0.0 {
        return Some(b);
    }
    if !(fa.signum() != fb.signum()) {
        return None;
    }
    let (mut a, mut b) = (a, b);
    let rising = fb > 0.0;
    let mut x = 0.5 * (a + b);
    let mut last_width = b - a;
    for _ in 0..200 {
        let (fx, dfx) = value(x);
        if fx == 0.0 || !fx.is_finite() {
            return fx.is_finite().then_some(x);
        }
        if (fx > 0.0) == rising {
            b = x;
        } else {
            a = x;
        }
        let newton = x - fx / dfx;
        let width = b - a;
        // Newton's step when it stays in the bracket and either the bracket shrinks fast or the
        // step is small; otherwise bisect.
        let inside = newton > a && newton < b;
        x = if inside && (width < 0.7 * last_width || (newton - x).abs() < 0.25 * width) {
            newton
        } else {
            0.5 * (a + b)
        };
        last_width = width;
        if b - a <= 2.0 * f64::EPSILON * a.abs().max(b.abs()).max(1e-300) || x <= a || x >= b {
            // Pick the end with the smaller residual.
            let (fa, fb) = (value(a).0.abs(), value(b).0.abs());
            return Some(if fa <= fb { a } else { b });
        }
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quadratic_roots_are_accurate_without_cancellation() {
        // x^2 - 1e8 x + 1: roots ~1e8 and ~1e-8; the naive formula loses the small one.
        let r = quadratic_roots(1.0, -1e8, 1.0);
        assert_eq!(r.len(), 2, "two roots");
        assert!((r[0] - 1e-8).abs() < 1e-22, "small root {}", r[0]);
        assert!((r[1] - 1e8).abs() < 1e-6, "large root {}", r[1]);
        assert_eq!(quadratic_roots(1.0, 0.0, 1.0).len(), 0, "complex roots");
        assert_eq!(quadratic_roots(0.0, 2.0, -1.0).as_slice(), &[0.5], "linear");
        assert_eq!(
            quadratic_roots(1.0, -2.0, 1.0).as_slice(),
            &[1.0],
            "double root once"
        );
    }

    struct Wiggle;
    impl Function1D for Wiggle {
        /// sin(40 u) - 0.3 + 0.2 u: 13 roots in [0, 1] (checked by dense sign sampling below).
        fn eval<T: Real>(&self, u: T) -> T {
            u.scale(40.0).sin() - T::cst(0.3) + u.scale(0.2)
        }
    }

    #[test]
    fn isolate_finds_every_sign_change_of_a_wiggly_function() {
        let mut out = ArrayVec::new();
        assert!(
            isolate_roots(&Wiggle, 0.0, 1.0, &IsolateOptions::default(), &mut out),
            "budget"
        );
        let f = |u: f64| (40.0 * u).sin() - 0.3 + 0.2 * u;
        let n = 200_000;
        let changes = (0..n)
            .filter(|&i| f(i as f64 / n as f64).signum() != f((i + 1) as f64 / n as f64).signum())
            .count();
        assert_eq!(out.len(), changes, "roots {out:?}");
        for w in out.windows(2) {
            assert!(w[0] < w[1], "ascending");
        }
        for &r in &out {
            assert!(f(r).abs() < 1e-14, "residual {} at {r}", f(r));
        }
    }

    struct Tangent;
    impl Function1D for Tangent {
        /// (u - 0.3)^2: a double root that no sign test sees.
        fn eval<T: Real>(&self, u: T) -> T {
            (u - T::cst(0.3)).sqr()
        }
    }

    #[test]
    fn isolate_reports_a_tangential_root_once() {
        let mut out = ArrayVec::new();
        isolate_roots(&Tangent, 0.0, 1.0, &IsolateOptions::default(), &mut out);
        assert_eq!(out.len(), 1, "double root {out:?}");
        assert!((out[0] - 0.3).abs() < 1e-9, "at 0.3: {}", out[0]);
    }
}
