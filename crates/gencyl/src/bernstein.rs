//! Polynomials in Bernstein form on `[0, 1]`: `p(s) = sum_k b_k C(n, k) s^k (1 - s)^(n - k)`.
//!
//! The coefficients bound the polynomial on `[0, 1]` (convex hull property); de Casteljau's
//! algorithm evaluates it and splits it into the coefficients on subintervals, which bound it
//! there ever more tightly (quadratically in the width), and does so stably: every step is a
//! convex combination, so a value's rounding error stays within a few units of the largest
//! coefficient. Products and derivatives stay in the form. `K` is the number of coefficients,
//! the degree plus one.

use arrayvec::ArrayVec;

use crate::roots::bracketed_root;

/// A polynomial of degree `K - 1` in Bernstein form on `[0, 1]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bernstein<const K: usize>(pub [f64; K]);

/// `C(n, k)` for `n < 16` (`0` for `k > n`), exact in `f64`, from Pascal's rule at compile time.
const BINOMIAL: [[f64; 16]; 16] = {
    let mut c = [[0.0f64; 16]; 16];
    let mut n = 0;
    while n < 16 {
        c[n][0] = 1.0;
        let mut k = 1;
        while k <= n {
            c[n][k] = c[n - 1][k - 1] + c[n - 1][k];
            k += 1;
        }
        n += 1;
    }
    c
};

/// `C(n, k)` for `n < 16`.
#[inline]
fn binomial(n: usize, k: usize) -> f64 {
    BINOMIAL[n][k]
}

impl<const K: usize> Bernstein<K> {
    /// The degree.
    pub const DEGREE: usize = K - 1;

    /// `p(s)` by de Casteljau's algorithm.
    #[inline]
    pub fn eval(&self, s: f64) -> f64 {
        let mut w = self.0;
        for k in 1..K {
            for i in 0..K - k {
                w[i] += s * (w[i + 1] - w[i]);
            }
        }
        w[0]
    }

    /// `(p(s), p'(s))` by one run of de Casteljau's algorithm: the value as [`Self::eval`]
    /// gives it, and `p'(s) = n (w_1 - w_0)` from the two points of the last-but-one level.
    #[inline]
    pub fn eval_with_derivative(&self, s: f64) -> (f64, f64) {
        if K < 2 {
            return (self.0[0], 0.0);
        }
        let mut w = self.0;
        for k in 1..K - 1 {
            for i in 0..K - k {
                w[i] += s * (w[i + 1] - w[i]);
            }
        }
        let slope = w[1] - w[0];
        (w[0] + s * slope, (K - 1) as f64 * slope)
    }

    /// The coefficients on `[0, s]` and on `[s, 1]` (each reparametrised to `[0, 1]`).
    #[inline]
    pub fn split(&self, s: f64) -> (Self, Self) {
        let mut w = self.0;
        let (mut left, mut right) = ([0.0; K], [0.0; K]);
        for k in 0..K {
            left[k] = w[0];
            right[K - 1 - k] = w[K - 1 - k];
            for i in 0..K - 1 - k {
                w[i] += s * (w[i + 1] - w[i]);
            }
        }
        (Bernstein(left), Bernstein(right))
    }

    /// The coefficients on `[s0, s1]` (reparametrised to `[0, 1]`). Below 0 (a span reaching
    /// just past the start) the split at `s0` comes first, so that the second split's point
    /// stays in `[0, 1]`: splitting at `s1` first would make the second an extrapolation by
    /// `s0 / s1`, far outside `[0, 1]` where `0 < s1 << -s0`, and no interval at all where
    /// `s1 = 0`.
    #[inline]
    pub fn restrict(&self, s0: f64, s1: f64) -> Self {
        if s0 == 0.0 && s1 == 1.0 {
            return *self;
        }
        if s0 < 0.0 {
            return self.split(s0).1.split((s1 - s0) / (1.0 - s0)).0;
        }
        let right = if s1 == 1.0 { *self } else { self.split(s1).0 };
        if s0 == 0.0 || s1 == 0.0 {
            return right;
        }
        right.split(s0 / s1).1
    }

    /// The smallest and largest coefficient: bounds of `p` on `[0, 1]`.
    #[inline]
    pub fn range(&self) -> (f64, f64) {
        self.0
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &c| {
                (lo.min(c), hi.max(c))
            })
    }

    /// The largest coefficient magnitude: the scale of rounding errors in `p`.
    #[inline]
    pub fn magnitude(&self) -> f64 {
        self.0.iter().fold(0.0f64, |m, c| m.max(c.abs()))
    }

    /// `p'` (in `s`) as a polynomial with `J = K - 1` coefficients: `n (b_{k+1} - b_k)`.
    #[inline]
    pub fn derivative<const J: usize>(&self) -> Bernstein<J> {
        debug_assert_eq!(J + 1, K, "the derivative has one coefficient fewer");
        let n = (K - 1) as f64;
        Bernstein(std::array::from_fn(|k| n * (self.0[k + 1] - self.0[k])))
    }

    /// `p q` with `M = K + L - 1` coefficients:
    /// `c_k = sum_{i + j = k} C(m, i) C(n, j) / C(m + n, k) a_i b_j`. Each weight is one
    /// constant (the compiler folds the quotient of the table's entries, correctly rounded), so
    /// no coefficient is divided at run time.
    #[inline]
    pub fn mul<const L: usize, const M: usize>(&self, o: &Bernstein<L>) -> Bernstein<M> {
        debug_assert_eq!(M, K + L - 1, "degrees add");
        let (m, n) = (K - 1, L - 1);
        let mut c = [0.0; M];
        for (i, &a) in self.0.iter().enumerate() {
            for (j, &b) in o.0.iter().enumerate() {
                c[i + j] += binomial(m, i) * binomial(n, j) / binomial(m + n, i + j) * a * b;
            }
        }
        Bernstein(c)
    }

    /// The same polynomial with `M >= K` coefficients (degree elevation).
    #[inline]
    pub fn elevate<const M: usize>(&self) -> Bernstein<M> {
        debug_assert!(M >= K, "elevation raises the degree");
        // p * 1, with 1 = sum of the M - K + 1 Bernstein basis functions of degree M - K.
        let one = [1.0; 16];
        let mut c = [0.0; M];
        let (m, n) = (K - 1, M - K);
        for (i, &a) in self.0.iter().enumerate() {
            for (j, &b) in one.iter().take(n + 1).enumerate() {
                c[i + j] += binomial(m, i) * binomial(n, j) / binomial(m + n, i + j) * a * b;
            }
        }
        Bernstein(c)
    }

    /// The roots of `p` in `[0, 1]`, ascending, appended to `out`, for coefficients known to
    /// within `err`: a subinterval whose coefficients keep one sign (beyond `err`) holds none,
    /// one whose coefficients change sign once exactly one (Descartes' rule of signs for the
    /// Bernstein basis), found by bracketed Newton steps on `p` and `dp` (its derivative);
    /// others are halved, down to `min_width`, where a sign change between the ends gives one
    /// root (a double root whose value stays within `err` gives none). At most `budget`
    /// subintervals.
    pub fn roots<const J: usize>(
        &self,
        dp: &Bernstein<J>,
        err: f64,
        min_width: f64,
        budget: usize,
        out: &mut ArrayVec<f64, 16>,
    ) {
        let f = |s: f64| (self.eval(s), dp.eval(s));
        let mut stack: ArrayVec<(Self, f64, f64), 64> = ArrayVec::new();
        stack.push((*self, 0.0, 1.0));
        let mut cells = 0;
        while let Some((b, s0, s1)) = stack.pop() {
            cells += 1;
            let (lo, hi) = b.range();
            if lo - err > 0.0 || hi + err < 0.0 {
                continue;
            }
            let clear = b.0.iter().all(|c| c.abs() > err);
            let changes =
                b.0.windows(2)
                    .filter(|w| (w[0] > 0.0) != (w[1] > 0.0))
                    .count();
            let narrow =
                s1 - s0 <= min_width || cells > budget || stack.len() + 2 > stack.capacity();
            if (clear && changes == 1) || narrow {
                let (fa, fb) = (f(s0).0, f(s1).0);
                if let Some(r) = bracketed_root(&f, s0, s1, fa, fb)
                    && !out.is_full()
                    && out.last().is_none_or(|&l| r > l)
                {
                    out.push(r);
                }
                continue;
            }
            if clear && changes == 0 {
                continue;
            }
            let m = 0.5 * (s0 + s1);
            let (l, r) = b.split(0.5);
            stack.push((r, m, s1));
            stack.push((l, s0, m));
        }
    }

    /// `p + q`.
    #[inline]
    pub fn add(&self, o: &Self) -> Self {
        Bernstein(std::array::from_fn(|k| self.0[k] + o.0[k]))
    }

    /// `p - q`.
    #[inline]
    pub fn sub(&self, o: &Self) -> Self {
        Bernstein(std::array::from_fn(|k| self.0[k] - o.0[k]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::Lcg;

    /// The power form `sum a_j s^j`, by Horner's rule: an independent evaluation.
    fn power(a: &[f64], s: f64) -> f64 {
        a.iter().rev().fold(0.0, |acc, &c| acc * s + c)
    }

    /// Bernstein coefficients from power coefficients, `b_i = sum_{j <= i} C(i, j) / C(n, j) a_j`.
    fn from_power<const K: usize>(a: &[f64; K]) -> Bernstein<K> {
        let n = K - 1;
        Bernstein(std::array::from_fn(|i| {
            (0..=i)
                .map(|j| binomial(i, j) / binomial(n, j) * a[j])
                .sum()
        }))
    }

    #[test]
    fn value_and_derivative_match_the_power_form() {
        let mut rng = Lcg(5);
        for _ in 0..50 {
            let a: [f64; 7] = std::array::from_fn(|_| rng.range(-2.0, 2.0));
            let da: Vec<f64> = (1..7).map(|j| j as f64 * a[j]).collect();
            let p = from_power(&a);
            for s in [0.0, 0.25, rng.range(0.0, 1.0), 1.0] {
                let (v, d) = p.eval_with_derivative(s);
                assert_eq!(v, p.eval(s), "the value is eval's, bit for bit");
                assert!((v - power(&a, s)).abs() < 1e-13, "value at {s}");
                assert!((d - power(&da, s)).abs() < 1e-12, "derivative at {s}: {d}");
            }
        }
        assert_eq!(
            Bernstein([3.0]).eval_with_derivative(0.5),
            (3.0, 0.0),
            "constant"
        );
    }

    /// Restrictions to spans reaching below 0 (by `1e-11`, a search margin, or by 0.3) and
    /// ending at 0, just above it, inside or past 1 bound and evaluate the polynomial there:
    /// splitting at the end first would extrapolate the second split by `s0 / s1` (or, ending
    /// at 0, keep only the value at 0).
    #[test]
    fn restrictions_below_zero_match_the_power_form() {
        let mut rng = Lcg(11);
        for _ in 0..200 {
            let a: [f64; 6] = std::array::from_fn(|_| rng.range(-2.0, 2.0));
            let p = from_power(&a);
            for s0 in [-1e-11, -1e-6, -0.3] {
                for s1 in [0.0, 1e-18, 1e-13, 1e-3, 0.5, 1.0, 1.0 + 1e-11] {
                    let part = p.restrict(s0, s1);
                    let (lo, hi) = part.range();
                    for i in 0..=16 {
                        let s = i as f64 / 16.0;
                        let want = power(&a, s0 + (s1 - s0) * s);
                        assert!(
                            (part.eval(s) - want).abs() < 1e-12,
                            "[{s0}, {s1}] at {s}: {} against {want}",
                            part.eval(s)
                        );
                        assert!(
                            lo - 1e-12 <= want && want <= hi + 1e-12,
                            "bounds on [{s0}, {s1}]"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn operations_match_the_power_form() {
        let mut rng = Lcg(3);
        for _ in 0..50 {
            let a: [f64; 4] = std::array::from_fn(|_| rng.range(-2.0, 2.0));
            let b: [f64; 3] = std::array::from_fn(|_| rng.range(-2.0, 2.0));
            let (pa, pb) = (from_power(&a), from_power(&b));
            let prod: Bernstein<6> = pa.mul(&pb);
            let da: Bernstein<3> = pa.derivative();
            let up: Bernstein<7> = pa.elevate();
            let (s0, s1) = (rng.range(0.0, 0.5), rng.range(0.5, 1.0));
            let part = pa.restrict(s0, s1);
            for i in 0..=20 {
                let s = i as f64 / 20.0;
                let want = power(&a, s);
                assert!((pa.eval(s) - want).abs() < 1e-12, "eval at {s}");
                assert!((up.eval(s) - want).abs() < 1e-12, "elevated at {s}");
                let wp = want * power(&b, s);
                assert!((prod.eval(s) - wp).abs() < 1e-12, "product at {s}");
                let wd = a[1] + 2.0 * a[2] * s + 3.0 * a[3] * s * s;
                assert!((da.eval(s) - wd).abs() < 1e-12, "derivative at {s}");
                let x = s0 + (s1 - s0) * s;
                assert!(
                    (part.eval(s) - power(&a, x)).abs() < 1e-12,
                    "restricted at {s}"
                );
                let (lo, hi) = part.range();
                assert!(
                    lo - 1e-12 <= power(&a, x) && power(&a, x) <= hi + 1e-12,
                    "bounds"
                );
            }
        }
    }
}
