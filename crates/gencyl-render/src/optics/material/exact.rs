//! Hair whose azimuthal scattering comes from its exact section: `type = "hair"` with
//! `section = "exact"`.
//!
//! **Model.** `eval(wo, wi) = Σ_{p=0..3} M_p(θ_i; θ_o^p) S_p(φ; θ_o, ρ, a) / Δφ`, where `M_p` are
//! Chiang et al.'s longitudinal lobes with the cuticle tilt ([`Longitudinal`]) and `S_p` the
//! fraction of the power arriving from `wo` that leaves by path order `p` (R, TT, TRT, the
//! rest) into the azimuth bin of `φ = φ_i − φ_o` (width `Δφ`), measured by tracing the smooth
//! dielectric fiber's exact section ([`Goniometer::measure_azimuthal`]). It depends on the
//! longitudinal angle `θ_o` (through Bravais' index and the path lengths), on `ρ`, the angle
//! from `wo`'s projection onto the normal plane to the section's major axis (counterclockwise
//! about the tangent), and on the section's aspect `a` (minor / major). Light is taken to come
//! from `wo`: for the far-field scattering of a fiber (averaged over where on its width a ray
//! meets it) `f(wo, wi) = S(wo → wi)`, as reciprocity `w(i) S(i → o) = w(o) S(o → i)` (`w`
//! the projected width) turns the power scattered from `wi` seen over `w(wo)` into exactly
//! that. Without absorption `Σ_p Σ_φ S_p = 1` for every `wo` (up to the trace's cutoffs), so
//! the white furnace holds as for Chiang's model.
//!
//! **Roughness.** `β_m` as Chiang's. `β_n` blurs each `S_p` by Chiang's trimmed logistic of
//! scale `s(β_n)` (a circular convolution, the kernel averaged over bin pairs), as a rough
//! surface spreads the smooth fiber's azimuths.
//!
//! **Tables.** `S_p` is tabulated at `θ_o` = 0, 10, ..., 80 degrees (beyond 80 the last row),
//! at `ρ` every 10 degrees (an ellipse: over `[0, 90]`, the rest by its symmetries
//! `S(φ; ρ + π) = S(φ; ρ)`, `S(φ; −ρ) = S(−φ; ρ)`; a profile: all the way round; a circle: one
//! node), at the aspects of the fibers that use the material (one table per aspect node, no
//! more than 0.05 apart), in 120 bins of 3 degrees, with 4096 stratified rays per row. Lookup
//! interpolates linearly in `θ_o`, `ρ` and `a` (up to 8 rows). Sampling picks a lobe by its
//! interpolated power, a row by its weight times power, a bin by the row's CDF and a uniform
//! azimuth in the bin, then `θ_i` as Chiang's; the density is the whole mixture's.
//! Tables are built when the scene is loaded and kept for the process, by their parameters.

use std::collections::HashMap;
use std::f64::consts::{FRAC_PI_2, PI, TAU};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::Instant;

use glam::{DVec2, DVec3};

use super::hair::{
    HairMaterial, HairParams, HairSample, Longitudinal, P_MAX, logistic_scale, pick_rescaled,
    trimmed_logistic,
};
use crate::transport::scatter::{FiberSection, Goniometer};

/// Orders tabulated: R, TT, TRT and the rest.
const ORDERS: usize = P_MAX + 1;
/// Azimuth bins over `(−π, π]`.
pub const BINS: usize = 120;
/// Longitudinal nodes, degrees apart, from 0.
const THETA_STEP: f64 = 10.0;
/// Longitudinal nodes.
const THETAS: usize = 9;
/// Rotation nodes, degrees apart.
const ROTATION_STEP: f64 = 10.0;
/// Rays per table row.
pub const RAYS: usize = 4096;
/// Largest aspect step between table nodes.
pub const ASPECT_STEP: f64 = 0.05;

/// The section a table describes, before its aspect is applied.
#[derive(Clone, Debug, PartialEq)]
pub enum SectionShape {
    /// The ellipse (the circle at aspect 1).
    Ellipse,
    /// A Bezier loop's points (the scene's `profile`), stretched by `(1, aspect)`.
    Profile(Vec<DVec2>),
}

/// Azimuthal scattering of one section at one aspect, tabulated over `(θ_o, ρ)`.
#[derive(Clone, Debug, PartialEq)]
pub struct AzimuthalTable {
    /// An ellipse (rotation nodes over `[0, π/2]`, mirrored), else a full turn.
    symmetric: bool,
    /// Rotation nodes.
    rotations: usize,
    /// `S` per row (`(theta * rotations + rho) * ORDERS + p`) and bin.
    values: Vec<DVec3>,
    /// `Σ_φ S` per row and order.
    totals: Vec<DVec3>,
    /// The running sum of the channel mean of `S` over the bins (`BINS + 1` per row and order).
    cdf: Vec<f64>,
    /// Lost to the trace's cutoffs, the largest over rows (channel mean).
    pub lost: f64,
    /// Seconds it took to build.
    pub seconds: f64,
}

/// One row of a lookup: table, row, weight, mirrored.
#[derive(Clone, Copy, Debug)]
struct Corner<'a> {
    table: &'a AzimuthalTable,
    row: usize,
    weight: f64,
    mirror: bool,
}

impl Corner<'_> {
    /// The row's weighted power in order `p` (channel mean).
    fn power(&self, p: usize) -> f64 {
        self.weight * self.table.totals[self.row * ORDERS + p].element_sum() / 3.0
    }
}

impl AzimuthalTable {
    /// Traces the section `shape` at `aspect` for `params` (its `eta`, `sigma_a` per unit of
    /// the section's bounding radius, and `beta_n`).
    pub fn build(shape: &SectionShape, aspect: f64, params: &HairParams) -> Result<Self, String> {
        let start = Instant::now();
        let (section, symmetric) = match shape {
            SectionShape::Ellipse => (FiberSection::Ellipse { aspect }, true),
            SectionShape::Profile(points) => (
                FiberSection::Profile(
                    points
                        .iter()
                        .map(|p| DVec2::new(p.x, p.y * aspect))
                        .collect(),
                ),
                false,
            ),
        };
        let rotations = match (symmetric, aspect == 1.0) {
            (true, true) => 1,
            (true, false) => (90.0 / ROTATION_STEP) as usize + 1,
            (false, _) => (360.0 / ROTATION_STEP) as usize,
        };
        let kernel = blur_kernel(logistic_scale(params.beta_n));
        let mut values = Vec::with_capacity(THETAS * rotations * ORDERS * BINS);
        let mut totals = Vec::with_capacity(THETAS * rotations * ORDERS);
        let mut lost = 0.0f64;
        for i in 0..THETAS {
            let theta = (i as f64 * THETA_STEP).to_radians();
            for j in 0..rotations {
                let g = Goniometer {
                    section: section.clone(),
                    rotation: (j as f64 * ROTATION_STEP).to_radians(),
                    eta: params.eta,
                    sigma_a: 0.0,
                    tilt: 0.0,
                    theta_i: 0.0,
                    phi_i: 0.0,
                    rays: RAYS,
                    max_order: P_MAX,
                    bins: BINS,
                    seed: 0x5eed,
                };
                let m = g.measure_azimuthal(theta, params.sigma_a)?;
                lost = lost.max(m.lost.element_sum() / 3.0);
                for row in &m.values {
                    let blurred = circular_blur(row, &kernel);
                    totals.push(blurred.iter().copied().sum());
                    values.extend(blurred);
                }
            }
        }
        let cdf = values
            .chunks(BINS)
            .flat_map(|row| {
                let mut acc = 0.0;
                std::iter::once(0.0).chain(row.iter().map(move |v| {
                    acc += v.element_sum() / 3.0;
                    acc
                }))
            })
            .collect();
        Ok(AzimuthalTable {
            symmetric,
            rotations,
            values,
            totals,
            cdf,
            lost,
            seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// The rows around `(theta, rho)` with their bilinear weights (`rho` in the table's sense,
    /// any angle; `|theta|` beyond the last node reads the last row).
    fn corners(&self, theta: f64, rho: f64) -> [(usize, f64, bool); 4] {
        let x = (theta.abs().to_degrees() / THETA_STEP).min((THETAS - 1) as f64);
        let i0 = (x.floor() as usize).min(THETAS - 2);
        let fi = x - i0 as f64;
        // Rotation node and mirror.
        let (r0, r1, fr, mirror) = if self.rotations == 1 {
            (0, 0, 0.0, false)
        } else if self.symmetric {
            let mut r = rho.rem_euclid(PI);
            let mirror = r > FRAC_PI_2;
            if mirror {
                r = PI - r;
            }
            let y = (r.to_degrees() / ROTATION_STEP).min((self.rotations - 1) as f64);
            let j0 = (y.floor() as usize).min(self.rotations - 2);
            (j0, j0 + 1, y - j0 as f64, mirror)
        } else {
            let y = rho.rem_euclid(TAU).to_degrees() / ROTATION_STEP;
            let j0 = (y.floor() as usize).min(self.rotations - 1);
            (j0, (j0 + 1) % self.rotations, y - j0 as f64, false)
        };
        let row = |i: usize, j: usize| i * self.rotations + j;
        [
            (row(i0, r0), (1.0 - fi) * (1.0 - fr), mirror),
            (row(i0, r1), (1.0 - fi) * fr, mirror),
            (row(i0 + 1, r0), fi * (1.0 - fr), mirror),
            (row(i0 + 1, r1), fi * fr, mirror),
        ]
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.values.len() * 24 + self.totals.len() * 24 + self.cdf.len() * 8
    }
}

/// The circular blur by the trimmed logistic of scale `s`, averaged over pairs of bins: the
/// weight of a bin offset `k` is `∫ tri(x / Δ − k) ℓ(x; s) dx` (`tri` the hat of half-width 1),
/// by Simpson's rule on 64 panels per bin, normalised to sum to 1.
fn blur_kernel(s: f64) -> Vec<f64> {
    let d = TAU / BINS as f64;
    let n = 64;
    let mut w: Vec<f64> = (0..BINS)
        .map(|k| {
            // Offsets k and k - BINS are the same on the circle: take the one in (-π, π].
            let k = if k > BINS / 2 {
                k as f64 - BINS as f64
            } else {
                k as f64
            };
            let f = |x: f64| (1.0 - (x / d - k).abs()).max(0.0) * trimmed_logistic(x, s);
            let (a, h) = ((k - 1.0) * d, 2.0 * d / (2 * n) as f64);
            let mut sum = f(a) + f(a + 2.0 * d);
            for m in 1..2 * n {
                sum += if m % 2 == 1 { 4.0 } else { 2.0 } * f(a + m as f64 * h);
            }
            sum * h / 3.0
        })
        .collect();
    let total: f64 = w.iter().sum();
    for x in &mut w {
        *x /= total;
    }
    w
}

/// `out[k] = Σ_j row[j] kernel[(k − j) mod BINS]`.
fn circular_blur(row: &[DVec3], kernel: &[f64]) -> Vec<DVec3> {
    let n = row.len();
    (0..n)
        .map(|k| {
            (0..n)
                .filter(|&j| row[j] != DVec3::ZERO)
                .map(|j| row[j] * kernel[(k + n - j) % n])
                .sum()
        })
        .collect()
}

/// The tables of one hair material over the aspects its fibers have.
#[derive(Clone, Debug, PartialEq)]
pub struct ExactSection {
    /// The section.
    pub shape: SectionShape,
    /// `(aspect, table)`, by increasing aspect.
    pub nodes: Vec<(f64, Arc<AzimuthalTable>)>,
}

type Cache = Mutex<HashMap<String, Arc<AzimuthalTable>>>;

/// Tables built so far in this process, by their parameters.
fn cache() -> &'static Cache {
    static CACHE: OnceLock<Cache> = OnceLock::new();
    CACHE.get_or_init(|| Mutex::new(HashMap::new()))
}

impl ExactSection {
    /// The tables for aspects in `[lo, hi]`: nodes at most [`ASPECT_STEP`] apart (one node when
    /// `hi - lo < 1e-9`), each built or taken from the process's cache.
    pub fn build(
        shape: SectionShape,
        lo: f64,
        hi: f64,
        params: &HairParams,
    ) -> Result<Self, String> {
        if !(params.eta > 1.0 && params.eta <= 10.0) {
            return Err(format!(
                "section = \"exact\" needs an eta in (1, 10], got {}",
                params.eta
            ));
        }
        let count = if hi - lo < 1e-9 {
            1
        } else {
            ((hi - lo) / ASPECT_STEP).ceil() as usize + 1
        };
        let mut nodes = Vec::with_capacity(count);
        for k in 0..count {
            let a = if count == 1 {
                lo
            } else {
                lo + (hi - lo) * k as f64 / (count - 1) as f64
            };
            let key = format!(
                "{shape:?} {a:?} {:?} {:?} {:?} {RAYS} {BINS}",
                params.eta, params.sigma_a, params.beta_n
            );
            let cached = cache().lock().expect("the table cache").get(&key).cloned();
            let table = match cached {
                Some(t) => t,
                None => {
                    let t = Arc::new(AzimuthalTable::build(&shape, a, params)?);
                    cache()
                        .lock()
                        .expect("the table cache")
                        .insert(key, t.clone());
                    t
                }
            };
            nodes.push((a, table));
        }
        Ok(ExactSection { shape, nodes })
    }

    /// Up to 8 rows around `(aspect, theta, rho)` with their weights.
    fn corners(&self, aspect: f64, theta: f64, rho: f64) -> [Corner<'_>; 8] {
        let n = self.nodes.len();
        let (k0, fa) = if n == 1 {
            (0, 0.0)
        } else {
            let (lo, hi) = (self.nodes[0].0, self.nodes[n - 1].0);
            let x = ((aspect - lo) / (hi - lo) * (n - 1) as f64).clamp(0.0, (n - 1) as f64);
            let k0 = (x.floor() as usize).min(n - 2);
            (k0, x - k0 as f64)
        };
        let k1 = (k0 + 1).min(n - 1);
        let (t0, t1) = (&*self.nodes[k0].1, &*self.nodes[k1].1);
        let (c0, c1) = (t0.corners(theta, rho), t1.corners(theta, rho));
        std::array::from_fn(|m| {
            let (table, (row, w, mirror), wa) = if m < 4 {
                (t0, c0[m], 1.0 - fa)
            } else {
                (t1, c1[m - 4], fa)
            };
            Corner {
                table,
                row,
                weight: w * wa,
                mirror,
            }
        })
    }

    /// Bytes held by the tables.
    pub fn bytes(&self) -> usize {
        self.nodes.iter().map(|(_, t)| t.bytes()).sum()
    }
}

/// The exact-section hair BSDF at one hit, in the local frame of [`super::hair`] (`x` the
/// tangent from tip to root).
#[derive(Clone, Copy, Debug)]
pub struct ExactHairBsdf<'a> {
    lobes: Longitudinal,
    section: &'a ExactSection,
    aspect: f64,
    /// Azimuth of the section's major axis in the local frame, `atan2(z, y)`.
    phi_major: f64,
}

/// Everything that depends on `wo` only.
struct Outgoing<'a> {
    phi_o: f64,
    turned: [(f64, f64); ORDERS],
    corners: [Corner<'a>; 8],
    /// `Σ_c w_c mean(T_cp)` per lobe.
    lobe: [f64; ORDERS],
    total: f64,
}

impl<'a> ExactHairBsdf<'a> {
    /// The BSDF of `material` (its longitudinal lobes; the tables hold the rest) for a section
    /// of `aspect` whose major axis is `major` (local frame, any length across the tangent).
    pub fn new(
        material: &HairMaterial,
        section: &'a ExactSection,
        aspect: f64,
        major: DVec3,
    ) -> Self {
        ExactHairBsdf {
            lobes: *material.lobes(),
            section,
            aspect,
            phi_major: major.z.atan2(major.y),
        }
    }

    /// Angles about the tangent `t = -x` are the local ones negated: `ρ = φ_o − φ_major` and
    /// `φ = φ_o − φ_i` in the tables' sense.
    fn outgoing(&self, wo: DVec3) -> Outgoing<'a> {
        let sin_o = wo.x.clamp(-1.0, 1.0);
        let cos_o = (1.0 - sin_o * sin_o).max(0.0).sqrt();
        let phi_o = wo.z.atan2(wo.y);
        let corners = self
            .section
            .corners(self.aspect, sin_o.asin(), phi_o - self.phi_major);
        let lobe = std::array::from_fn(|p| corners.iter().map(|c| c.power(p)).sum());
        Outgoing {
            phi_o,
            turned: self.lobes.turned(sin_o, cos_o),
            corners,
            lobe,
            total: lobe.iter().sum(),
        }
    }

    /// The bin of table azimuth `phi` in a row, mirrored or not.
    fn bin(phi: f64, mirror: bool) -> usize {
        let phi = if mirror { -phi } else { phi };
        let x = (phi + PI).rem_euclid(TAU) / TAU * BINS as f64;
        (x as usize).min(BINS - 1)
    }

    /// `(eval, pdf)` at `wi`.
    fn eval_pdf(&self, o: &Outgoing, wi: DVec3) -> (DVec3, f64) {
        if !(o.total > 0.0) {
            return (DVec3::ZERO, 0.0);
        }
        let sin_i = wi.x.clamp(-1.0, 1.0);
        let cos_i = (1.0 - sin_i * sin_i).max(0.0).sqrt();
        let terms = Self::terms(o, wi);
        let (mut f, mut pdf) = (DVec3::ZERO, 0.0);
        for (p, s) in terms.into_iter().enumerate() {
            let m = self.lobes.eval(p, sin_i, cos_i, o.turned[p]);
            f += m * s;
            pdf += m * s.element_sum() / 3.0 / o.total;
        }
        (f, pdf)
    }

    /// `S_p(φ) / Δφ` per order at `wi`: the corners' rows, weighted, at the bin of `φ`.
    fn terms(o: &Outgoing, wi: DVec3) -> [DVec3; ORDERS] {
        let phi = o.phi_o - wi.z.atan2(wi.y);
        let bins = [Self::bin(phi, false), Self::bin(phi, true)];
        let mut s = [DVec3::ZERO; ORDERS];
        for c in o.corners.iter().filter(|c| c.weight > 0.0) {
            let row = &c.table.values[c.row * ORDERS * BINS..][..ORDERS * BINS];
            let k = bins[usize::from(c.mirror)];
            for (p, sp) in s.iter_mut().enumerate() {
                *sp += c.weight * row[p * BINS + k];
            }
        }
        s.map(|v| v * (BINS as f64 / TAU))
    }

    /// Per order `p`, the azimuthal term `S_p(φ) / Δφ` at `wi` (without `M_p`), as
    /// [`super::hair::HairBsdf::azimuthal_terms`].
    pub fn azimuthal_terms(&self, wo: DVec3, wi: DVec3) -> [DVec3; ORDERS] {
        Self::terms(&self.outgoing(wo), wi)
    }

    /// `f(wo, wi) |cos θ_i|`.
    pub fn eval(&self, wo: DVec3, wi: DVec3) -> DVec3 {
        self.eval_and_pdf(wo, wi).0
    }

    /// Solid-angle density of [`ExactHairBsdf::sample`] choosing `wi`.
    pub fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        self.eval_and_pdf(wo, wi).1
    }

    /// [`ExactHairBsdf::eval`] and [`ExactHairBsdf::pdf`] at once.
    pub fn eval_and_pdf(&self, wo: DVec3, wi: DVec3) -> (DVec3, f64) {
        self.eval_pdf(&self.outgoing(wo), wi)
    }

    /// Importance-samples `wi` from 3 uniform numbers: `u[0]` picks the lobe, the row, the bin
    /// and the azimuth in it; `u[1], u[2]` the longitudinal angle.
    pub fn sample(&self, wo: DVec3, u: [f64; 3]) -> Option<HairSample> {
        let o = self.outgoing(wo);
        if !(o.total > 0.0) {
            return None;
        }
        // Each choice rescales what is left of u[0] to [0, 1).
        let (p, u0) = pick_rescaled(o.lobe.iter().copied(), u[0] * o.total)?;
        let (ci, u0) = pick_rescaled(o.corners.iter().map(|c| c.power(p)), u0 * o.lobe[p])?;
        let c = o.corners[ci];
        let cdf = &c.table.cdf[(c.row * ORDERS + p) * (BINS + 1)..][..BINS + 1];
        let target = u0 * cdf[BINS];
        let k = cdf[1..].partition_point(|&x| x <= target).min(BINS - 1);
        let within = if cdf[k + 1] > cdf[k] {
            ((target - cdf[k]) / (cdf[k + 1] - cdf[k])).clamp(0.0, 1.0)
        } else {
            0.5
        };
        let phi = -PI + (k as f64 + within) * TAU / BINS as f64;
        let phi = if c.mirror { -phi } else { phi };
        let (sin_i, cos_i) = self.lobes.sample(p, o.turned[p], [u[1], u[2]]);
        let phi_i = o.phi_o - phi;
        let wi = DVec3::new(sin_i, cos_i * phi_i.cos(), cos_i * phi_i.sin());
        let (f, pdf) = self.eval_pdf(&o, wi);
        let weight = f / pdf;
        (pdf > 0.0 && pdf.is_finite() && weight.is_finite()).then_some(HairSample {
            wi,
            weight,
            pdf,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optics::material::hair::HairBsdf;
    use crate::sampling::{SampleRng, uniform_sphere};

    fn params(sigma_a: DVec3, alpha: f64) -> HairParams {
        HairParams {
            eta: 1.55,
            sigma_a,
            beta_m: 0.3,
            beta_n: 0.3,
            alpha,
        }
    }

    fn section(aspect: f64, p: &HairParams) -> ExactSection {
        ExactSection::build(SectionShape::Ellipse, aspect, aspect, p).unwrap()
    }

    /// The direction with `sin θ = x` and azimuth `phi` (local frame).
    fn dir(x: f64, phi: f64) -> DVec3 {
        let c = (1.0 - x * x).sqrt();
        DVec3::new(x, c * phi.cos(), c * phi.sin())
    }

    fn mean_se(xs: &[f64]) -> (f64, f64) {
        let n = xs.len() as f64;
        let mean = xs.iter().sum::<f64>() / n;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
        (mean, (var / n).sqrt())
    }

    /// Without absorption `∫ eval dω_i = 1 - lost` for every `wo` and section orientation, by
    /// uniform-sphere Monte Carlo (independent of how the tables are laid out).
    #[test]
    fn white_furnace() {
        let p = params(DVec3::ZERO, 2f64.to_radians());
        let s = section(0.75, &p);
        let lost = s.nodes[0].1.lost;
        eprintln!(
            "table: {:.2} s, {} bytes, lost {lost:e}",
            s.nodes[0].1.seconds,
            s.bytes()
        );
        let mut rng = SampleRng::from_seed(21);
        for _ in 0..4 {
            let wo = uniform_sphere(rng.uniform2());
            let major = DVec3::new(0.0, rng.uniform() - 0.5, rng.uniform() - 0.5);
            let b = ExactHairBsdf::new(&HairMaterial::new(p), &s, 0.75, major);
            let xs: Vec<f64> = (0..400_000)
                .map(|_| b.eval(wo, uniform_sphere(rng.uniform2())).x * 4.0 * PI)
                .collect();
            let (mean, se) = mean_se(&xs);
            eprintln!("furnace wo {wo}: {mean:.4} ± {se:.4}");
            assert!(se < 0.01, "too noisy to test: {se}");
            assert!(
                (mean - 1.0).abs() < 4.0 * se + lost,
                "furnace {mean} ± {se} at wo {wo}"
            );
        }
    }

    /// Samples carry `eval / pdf` and `pdf()` at their direction, and land in azimuth sectors
    /// as often as the density integrates to there (midpoint quadrature of `pdf`).
    #[test]
    fn sampling_matches_pdf_and_eval() {
        let p = params(DVec3::new(0.2, 0.5, 1.0), 2f64.to_radians());
        let s = section(0.75, &p);
        let mut rng = SampleRng::from_seed(22);
        for _ in 0..3 {
            let wo = uniform_sphere(rng.uniform2());
            let major = DVec3::new(0.0, rng.uniform() - 0.5, rng.uniform() - 0.5);
            let b = ExactHairBsdf::new(&HairMaterial::new(p), &s, 0.75, major);
            let sectors = 12;
            let mut count = vec![0usize; sectors];
            let n = 200_000;
            for _ in 0..n {
                let u = [rng.uniform(), rng.uniform(), rng.uniform()];
                let x = b.sample(wo, u).expect("light scatters");
                let pdf = b.pdf(wo, x.wi);
                assert!((x.pdf - pdf).abs() <= 1e-9 * pdf, "{} vs {pdf}", x.pdf);
                let w = b.eval(wo, x.wi) / pdf;
                assert!((x.weight - w).abs().max_element() <= 1e-9 * w.max_element());
                let phi = x.wi.z.atan2(x.wi.y).rem_euclid(TAU);
                count[((phi / TAU * sectors as f64) as usize).min(sectors - 1)] += 1;
            }
            // ∫ pdf over each sector: dω = d(sin θ) dφ, 400 x 120 midpoints per sector.
            for (k, &c) in count.iter().enumerate() {
                let (nx, nf) = (400, 120);
                let mut integral = 0.0;
                for i in 0..nx {
                    let x = -1.0 + (i as f64 + 0.5) * 2.0 / nx as f64;
                    for j in 0..nf {
                        let phi = (k as f64 + (j as f64 + 0.5) / nf as f64) * TAU / sectors as f64;
                        integral += b.pdf(wo, dir(x, phi));
                    }
                }
                integral *= (2.0 / nx as f64) * (TAU / sectors as f64 / nf as f64);
                let freq = c as f64 / n as f64;
                let se = (integral * (1.0 - integral) / n as f64).sqrt();
                assert!(
                    (freq - integral).abs() < 5.0 * se + 2e-3 * integral,
                    "sector {k}: sampled {freq}, density {integral} (se {se})"
                );
            }
        }
    }

    /// A circle: the table's azimuthal terms are Chiang's averaged over the offset `h` (whose
    /// attenuations are exact for a smooth circle, and whose logistic is the same blur), per
    /// order R, TT, TRT: the same power, and the same shape up to the 3-degree bins.
    #[test]
    fn a_circle_scatters_as_chiangs_model_averaged_over_h() {
        let p = params(DVec3::new(0.2, 0.5, 1.0), 0.0);
        let s = section(1.0, &p);
        let exact = ExactHairBsdf::new(&HairMaterial::new(p), &s, 1.0, DVec3::Y);
        for deg in [0.0f64, 30.0, 60.0] {
            let x = deg.to_radians().sin();
            let wo = dir(x, 0.3);
            let nh = 400;
            let mut power = [[DVec3::ZERO; 2]; 3];
            let mut l1 = [0.0f64; 3];
            let mut peak = [0.0f64; 3];
            for k in 0..BINS {
                let phi = -PI + (k as f64 + 0.5) * TAU / BINS as f64;
                let wi = dir(-x, 0.3 + phi);
                let ours = exact.azimuthal_terms(wo, wi);
                // Chiang's, averaged over h and over the bin (5 azimuths).
                let mut theirs = [DVec3::ZERO; 4];
                for j in 0..5 {
                    let f = phi + (j as f64 - 2.0) / 5.0 * TAU / BINS as f64;
                    for i in 0..nh {
                        // ∫ g dh / 2 = ∫ g(sin γ) cos γ dγ / 2 over (−π/2, π/2): smooth at the
                        // edges, where the midpoint rule in h is off by 2e-3 of the R power.
                        let gamma = -FRAC_PI_2 + (i as f64 + 0.5) * PI / nh as f64;
                        let weight = 0.5 * gamma.cos() * PI / nh as f64 / 5.0;
                        let t = HairBsdf::new(&HairMaterial::new(p), gamma.sin())
                            .azimuthal_terms(wo, dir(-x, 0.3 + f));
                        for q in 0..4 {
                            theirs[q] += t[q] * weight;
                        }
                    }
                }
                for q in 0..3 {
                    power[q][0] += ours[q] * TAU / BINS as f64;
                    power[q][1] += theirs[q] * TAU / BINS as f64;
                    l1[q] += (ours[q].x - theirs[q].x).abs() * TAU / BINS as f64;
                    peak[q] = peak[q].max(theirs[q].x);
                }
            }
            for q in 0..3 {
                let [a, b] = power[q];
                eprintln!(
                    "theta {deg} order {q}: power {a} vs {b}, L1 {:.4}",
                    l1[q] / b.x
                );
                assert!(
                    (a - b).abs().max_element() < 2e-3 * b.max_element() + 1e-5,
                    "theta {deg}, order {q}: power {a} vs Chiang's {b}"
                );
                assert!(
                    l1[q] < 0.03 * b.x,
                    "theta {deg}, order {q}: L1 {}",
                    l1[q] / b.x
                );
            }
        }
    }

    /// Reciprocity of the far-field model: `w(o) f(wo, wi) = w(i) f(wi, wo)`, `w` the
    /// section's width seen from the direction's azimuth (`sqrt(cos²β + a² sin²β)`, `β` from
    /// the major axis across the direction). The smooth fiber is reciprocal point by point;
    /// the tables hold it to their noise: a circle (at equal `|θ|`, `β_n = 0.3`) point by
    /// point to 1.2e-3 (the jittered trace's mirror asymmetry), an ellipse of aspect 0.75
    /// with little azimuthal roughness (`β_n = 0.02`) over 30 x 30 degree blocks of the two
    /// azimuths to 7 % (unblurred 3-degree bins, incident azimuth interpolated over 10
    /// degrees). The roughness blur acts on the outgoing azimuth only, which for an ellipse
    /// is not reciprocal: at `β_n = 0.3` blocks at the TT lobe's edges differ by up to 44 %.
    #[test]
    fn the_far_field_model_is_reciprocal_with_the_projected_width() {
        let x = 20f64.to_radians().sin();
        for (aspect, beta_n) in [(1.0, 0.3), (0.75, 0.02)] {
            let p = HairParams {
                beta_n,
                ..params(DVec3::new(0.1, 0.4, 0.9), 0.0)
            };
            let s = section(aspect, &p);
            let bsdf = ExactHairBsdf::new(&HairMaterial::new(p), &s, aspect, DVec3::Y); // major axis at azimuth 0
            let width = |phi: f64| {
                let beta = phi + FRAC_PI_2;
                (beta.cos().powi(2) + aspect * aspect * beta.sin().powi(2)).sqrt()
            };
            // Pairs of azimuths `A`, `B` whose difference is on no bin edge (3 k degrees):
            // `w(A) f(A, B)` forward, `w(B) f(B, A)` reversed.
            let sigma = |a: f64, b: f64, reverse: bool| {
                let (a, b) = (a.to_radians(), b.to_radians());
                if reverse {
                    width(b) * bsdf.eval(dir(x, b), dir(-x, a))
                } else {
                    width(a) * bsdf.eval(dir(x, a), dir(-x, b))
                }
            };
            let mut worst = 0.0f64;
            if aspect == 1.0 {
                for o in 0..36 {
                    for i in 0..36 {
                        let (a, b) = (10.0 * o as f64, 10.0 * i as f64 + 1.5);
                        let (l, r) = (sigma(a, b, false), sigma(a, b, true));
                        worst = worst.max((l - r).abs().max_element() / l.max_element());
                    }
                }
                assert!(worst < 5e-3, "circle: {worst}");
            } else {
                // Means over 30 x 30 degree blocks, 15 x 15 azimuths 2 degrees apart in each.
                let block = |a: usize, c: usize, reverse: bool| -> f64 {
                    let mut sum = 0.0;
                    for o in 0..15 {
                        for i in 0..15 {
                            let (pa, pb) = (
                                30.0 * a as f64 + 2.0 * o as f64 + 0.5,
                                30.0 * c as f64 + 2.0 * i as f64 + 1.0,
                            );
                            sum += sigma(pa, pb, reverse).x;
                        }
                    }
                    sum / 225.0
                };
                let mut compared = 0;
                for a in 0..12 {
                    for c in 0..12 {
                        let (l, r) = (block(a, c, false), block(a, c, true));
                        if l.max(r) > 0.02 {
                            compared += 1;
                            worst = worst.max((l - r).abs() / l.max(r));
                        }
                    }
                }
                assert!(compared > 60, "{compared} blocks carry power");
                assert!(worst < 0.1, "ellipse: blocks differ by up to {worst}");
            }
            eprintln!("aspect {aspect}: reciprocity worst {worst:.2e}");
        }
    }
}
