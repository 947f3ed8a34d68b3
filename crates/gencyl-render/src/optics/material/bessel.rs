//! `ln I0(x)`, the logarithm of the modified Bessel function of the first kind and order
//! zero, for the hair BSDF's longitudinal lobes (`M_p` takes it four times an evaluation).
//!
//! [`log_i0`] reads piecewise Chebyshev fits, made once from [`log_i0_series`] (the slow
//! reference: tens of terms and a logarithm a call) when first asked for:
//! - `x < 12`: 24 cells of width 1/2 in `x`, fitting `ln I0(x) − x` (between `−2.2` and `0`);
//! - `x >= 12`: 4 cells in `u = 12 / x ∈ (0, 1]`, fitting the asymptotic remainder
//!   `ln I0(x) − x + ln(2πx) / 2` (between `0` and `0.011`), smooth in `u` down to `u = 0`.
//!
//! [`TERMS`] coefficients a cell hold the fit within about `2e-16` of each function: the
//! Chebyshev coefficients of `ln I0` decay geometrically (its only singularities are the
//! zeros of `J0` on the imaginary axis, `±2.405 i`, ...); an offline high-precision check put
//! the sum of the dropped coefficients at most `2e-16` with 12 terms on every cell.

use std::sync::LazyLock;

/// Chebyshev coefficients a cell.
const TERMS: usize = 12;
/// Where the cells in `x` end and those in `u = SPLIT / x` begin.
const SPLIT: f64 = 12.0;
/// Cells in `x` over `[0, SPLIT)` (width 1/2: `x * 2` picks the cell exactly).
const X_CELLS: usize = 24;
/// Cells in `u` over `(0, 1]`.
const U_CELLS: usize = 4;
/// `ln(2π)`.
const LN_TAU: f64 = 1.837_877_066_409_345_3;

/// The fitted coefficients, cells in `x` first.
struct Fits {
    cells: [[f64; TERMS]; X_CELLS + U_CELLS],
}

static FITS: LazyLock<Fits> = LazyLock::new(Fits::make);

impl Fits {
    fn make() -> Self {
        let mut cells = [[0.0; TERMS]; X_CELLS + U_CELLS];
        let x_width = SPLIT / X_CELLS as f64;
        for (i, cell) in cells[..X_CELLS].iter_mut().enumerate() {
            let a = i as f64 * x_width;
            *cell = chebyshev_fit(a, a + x_width, |x| log_i0_series(x) - x);
        }
        let u_width = 1.0 / U_CELLS as f64;
        for (i, cell) in cells[X_CELLS..].iter_mut().enumerate() {
            let a = i as f64 * u_width;
            *cell = chebyshev_fit(a, a + u_width, |u| {
                let x = SPLIT / u;
                if x > ASYMPTOTIC_FROM {
                    asymptotic_remainder(x)
                } else {
                    log_i0_power_series(x) - x + 0.5 * (LN_TAU + x.ln())
                }
            });
        }
        Fits { cells }
    }
}

/// The first `TERMS` Chebyshev coefficients of `f` on `[a, b]`, so that
/// `f(x) ≈ Σ_j c_j T_j(t)` with `t = 2 (x − a) / (b − a) − 1`.
///
/// The chord `ℓ(t) = (f(a) + f(b))/2 + t (f(b) − f(a))/2` is taken out first (it is `T_0` and
/// `T_1`), and the rest `r = f − ℓ` is interpolated at `n = NODES` Chebyshev points
/// `t_k = cos(π (k + 1/2) / n)`: `c_j = (2/n) Σ_k r(t_k) cos(π j (k + 1/2) / n)`, `c_0`
/// halved; the interpolant's higher terms are dropped (twice as many points as terms keep
/// them from folding back). The sums round in proportion to `|r|`, not `|f|`: a tenth to a
/// hundredth of it on these cells.
fn chebyshev_fit(a: f64, b: f64, f: impl Fn(f64) -> f64) -> [f64; TERMS] {
    const NODES: usize = 2 * TERMS;
    let n = NODES as f64;
    let (fa, fb) = (f(a), f(b));
    let (mean, half_rise) = (0.5 * (fa + fb), 0.5 * (fb - fa));
    let angle = |k: usize| std::f64::consts::PI * (k as f64 + 0.5) / n;
    let rest: [f64; NODES] = std::array::from_fn(|k| {
        let t = angle(k).cos();
        f(a + 0.5 * (b - a) * (t + 1.0)) - (mean + half_rise * t)
    });
    let mut c: [f64; TERMS] = std::array::from_fn(|j| {
        let sum: f64 = (0..NODES)
            .map(|k| rest[k] * (j as f64 * angle(k)).cos())
            .sum();
        if j == 0 { sum / n } else { 2.0 * sum / n }
    });
    c[0] += mean;
    c[1] += half_rise;
    c
}

/// `Σ_j c_j T_j(t)` by Clenshaw's recurrence: `b_j = c_j + 2t b_{j+1} − b_{j+2}`, then
/// `c_0 + t b_1 − b_2`.
#[inline]
fn clenshaw(c: &[f64; TERMS], t: f64) -> f64 {
    let (mut b1, mut b2) = (0.0, 0.0);
    for &cj in c[1..].iter().rev() {
        (b1, b2) = (cj + 2.0 * t * b1 - b2, b1);
    }
    c[0] + t * b1 - b2
}

/// `ln I0(x)` (even in `x`; `+inf` at `±inf`, NaN for NaN), within a few units in the last
/// place of `max(1, |x|)` of [`log_i0_series`].
#[inline]
pub fn log_i0(x: f64) -> f64 {
    let x = x.abs();
    if !(x < f64::INFINITY) {
        return x;
    }
    let fits = &*FITS;
    if x < SPLIT {
        // The cell `i` and the point `t ∈ [−1, 1]` in it, exactly (`x * 2` and a subtraction
        // of its integer part).
        let s = x * (X_CELLS as f64 / SPLIT);
        let i = (s as usize).min(X_CELLS - 1);
        x + clenshaw(&fits.cells[i], 2.0 * (s - i as f64) - 1.0)
    } else {
        let s = SPLIT / x * U_CELLS as f64;
        let i = (s as usize).min(U_CELLS - 1);
        x - 0.5 * (LN_TAU + x.ln()) + clenshaw(&fits.cells[X_CELLS + i], 2.0 * (s - i as f64) - 1.0)
    }
}

/// `ln I0(x)` for `x >= 0` the slow way (relative ~1e-15): the power series up to 20
/// ([`log_i0_power_series`]), the asymptotic expansion beyond
/// (`x − ln(2πx)/2 +` [`asymptotic_remainder`]). What the fits are made from.
pub fn log_i0_series(x: f64) -> f64 {
    if x <= ASYMPTOTIC_FROM {
        log_i0_power_series(x)
    } else {
        x - 0.5 * (LN_TAU + x.ln()) + asymptotic_remainder(x)
    }
}

/// Where the asymptotic expansion's smallest term (about `e^{−2x}`) drops below `1e-17`.
const ASYMPTOTIC_FROM: f64 = 20.0;

/// `ln Σ_k (x²/4)^k / (k!)²` as `ln_1p` of the terms after the first (relative accuracy
/// near `x = 0` too), summed until a term falls below `1e-17` of the sum.
fn log_i0_power_series(x: f64) -> f64 {
    let q = 0.25 * x * x;
    let (mut rest, mut term) = (0.0, 1.0);
    for k in 1..120 {
        term *= q / (k * k) as f64;
        rest += term;
        if term < 1e-17 * (1.0 + rest) {
            break;
        }
    }
    rest.ln_1p()
}

/// `ln I0(x) − x + ln(2πx)/2 = ln Σ_k c_k`, `c_0 = 1`, `c_k = c_{k−1} (2k−1)² / (8 k x)`, for
/// `x > 20` (the sum stopped below `1e-17`), found without subtracting large numbers.
fn asymptotic_remainder(x: f64) -> f64 {
    let (mut sum, mut c) = (1.0, 1.0);
    for k in 1..30 {
        let k = k as f64;
        c *= (2.0 * k - 1.0).powi(2) / (8.0 * k * x);
        sum += c;
        if c < 1e-17 {
            break;
        }
    }
    sum.ln()
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use super::*;
    use crate::sampling::SampleRng;

    /// `ln I0(x) = x + ln((1/π) ∫_0^π e^{x (cos t − 1)} dt)`, the integral by the trapezoid
    /// rule on `n` steps (spectrally accurate for this periodic integrand).
    fn log_i0_by_quadrature(x: f64, n: usize) -> f64 {
        let g = |t: f64| (x * (t.cos() - 1.0)).exp();
        let sum: f64 = (1..n).map(|k| g(PI * k as f64 / n as f64)).sum::<f64>();
        x + ((sum + 0.5 * (g(0.0) + g(PI))) / n as f64).ln()
    }

    #[test]
    fn the_series_matches_the_integral() {
        // The reference against an independent oracle, across the series/asymptotic switch at
        // 20: 1e-12 covers both sides' rounding (the quadrature sums 40,000 terms).
        for x in [
            0.0, 1e-6, 0.5, 1.0, 5.0, 11.99, 12.0, 12.01, 19.99, 20.01, 30.0, 100.0, 1e3, 7.5e4,
        ] {
            let want = log_i0_by_quadrature(x, 40_000);
            let got = log_i0_series(x);
            assert!((got - want).abs() < 1e-12, "ln I0({x}) = {got} vs {want}");
        }
    }

    #[test]
    fn fits_match_the_series_everywhere() {
        // Log-uniform from 1e-12 to 1e7, every cell's edges and their neighbours, and
        // uniform in each cell: within 3 units in the last place of max(1, x) (the series'
        // own rounding is about one: its logarithm's, then the subtraction of x).
        let mut rng = SampleRng::new(0, 0, 0, 11);
        let mut xs: Vec<f64> = (0..200_000)
            .map(|_| 10f64.powf(-12.0 + 19.0 * rng.uniform()))
            .collect();
        let edges = (0..=X_CELLS)
            .map(|i| i as f64 * SPLIT / X_CELLS as f64)
            .chain((1..=U_CELLS).map(|i| SPLIT * U_CELLS as f64 / i as f64));
        for e in edges {
            xs.extend([e, e.next_down(), e.next_up()]);
            xs.extend((0..200).map(|_| e + 0.5 * rng.uniform()));
        }
        xs.extend([0.0, f64::MIN_POSITIVE, 1e300, f64::MAX]);
        for x in xs {
            let (got, want) = (log_i0(x), log_i0_series(x));
            let ulps = (got - want).abs() / (f64::EPSILON * x.max(1.0));
            assert!(ulps <= 3.0, "ln I0({x}) = {got}, series {want}: {ulps} ulp");
            assert_eq!(log_i0(-x), got, "even at {x}");
        }
    }

    #[test]
    fn fits_match_the_integral_where_lobes_reach() {
        // Against the independent oracle directly, log-uniform over the arguments the lobes
        // meet (cos θ_i cos θ_o / v with v from 1.3e-5 to 110: 0 to 7.7e4).
        let mut rng = SampleRng::new(0, 0, 0, 12);
        for _ in 0..300 {
            let x = 10f64.powf(-8.0 + 12.9 * rng.uniform());
            let want = log_i0_by_quadrature(x, 40_000);
            assert!(
                (log_i0(x) - want).abs() < 1e-12 * x.max(1.0),
                "ln I0({x}) = {} vs {want}",
                log_i0(x)
            );
        }
    }

    #[test]
    fn extremes() {
        assert_eq!(log_i0(f64::INFINITY), f64::INFINITY);
        assert_eq!(log_i0(f64::NEG_INFINITY), f64::INFINITY);
        assert!(log_i0(f64::NAN).is_nan());
        assert_eq!(log_i0(f64::MAX), log_i0_series(f64::MAX));
        assert!(log_i0(f64::MAX).is_finite());
        // ln I0(x) = x²/4 − x⁴/64 + ...: near 0 the fit is absolute (a lobe's relative
        // error), within 2 units in the last place of 1.
        for x in [0.0, 1e-300, 1e-100, 1e-10, 1e-5] {
            let want = 0.25 * x * x;
            assert!(
                (log_i0(x) - want).abs() <= 2.0 * f64::EPSILON,
                "{x}: {}",
                log_i0(x)
            );
        }
    }
}
