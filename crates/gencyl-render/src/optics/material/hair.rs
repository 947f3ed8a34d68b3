//! The hair BSDF of Chiang, Bitterli, Tappan and Burley 2016 ("A Practical and Controllable
//! Hair and Fur Model for Production Path Tracing"), with the longitudinal lobe of d'Eon et al.
//! 2011, following the conventions of pbrt-v4's `HairBxDF`, in `f64` with RGB as [`DVec3`].
//!
//! **Frame.** `x` is the fiber tangent, `(y, z)` span the normal plane, right-handed
//! (`x × y = z`). For a unit direction `w`: `sin θ = w.x`, `φ = atan2(w.z, w.y)`.
//!
//! **Model.** With `φ = φ_i − φ_o` and `h ∈ [−1, 1]` the azimuthal offset of the hit,
//! `eval(wo, wi) = Σ_{p=0..2} M_p(θ_i; θ_o^p) A_p N_p(φ) + M_3(θ_i; θ_o) A_3 / 2π`, the
//! radiance integrand `L_o = ∫ eval L_i dω_i` (pbrt's `f · |cos|`; no further cosine).
//! - `M(θ_i; θ_o, v) = exp(−sin θ_i sin θ_o / v) I0(cos θ_i cos θ_o / v) / (2 v sinh(1/v))`, the
//!   azimuthal marginal of a von Mises–Fisher lobe, so `∫ M cos θ_i dθ_i = 1`. Evaluated as
//!   `exp(log I0(a) − b − 1/v − ln v − ln(1 − e^{−2/v}))`, exact for every `v`.
//! - Cuticle tilt `α` (as pbrt-v4, on `θ_o`): `θ_o^0 = θ_o − 2α`, `θ_o^1 = θ_o + α`,
//!   `θ_o^2 = θ_o + 4α`, `|cos θ_o^p|` kept; so the `θ_i` peaks move by `+2α, −α, −4α`.
//! - `N_p(φ) = ℓ(φ − Φ_p; s) / tanh(π / 2s)`, the logistic
//!   `ℓ(x; s) = e^{−|x|/s} / (s (1 + e^{−|x|/s})²)` trimmed to `[−π, π]` (wrapped), with
//!   `Φ_p = 2p γ_t − 2γ_o + pπ`, `γ_o = asin h`, `sin γ_t = h / η'`,
//!   `η' = sqrt(η² − sin² θ_o) / cos θ_o` (Bravais).
//! - `A_0 = F`, `A_1 = (1 − F)² T`, `A_2 = A_1 F T`, `A_3 = A_2 F T / (1 − F T)`, with `F` the
//!   unpolarised dielectric Fresnel term at `cos θ_o cos γ_o` and
//!   `T = exp(−σ_a · 2 cos γ_t / cos θ_t)`, `sin θ_t = sin θ_o / η`: `σ_a` is per unit fiber
//!   *radius* (pbrt-v4). With `σ_a = 0`, `Σ A_p = 1` and the BSDF conserves energy exactly.
//! - Roughness: `v_0 = (0.726 β_m + 0.812 β_m² + 3.7 β_m^20)²`, `v_1 = v_0/4`,
//!   `v_2 = v_3 = 4 v_0`; `s = sqrt(π/8) (0.265 β_n + 1.194 β_n² + 5.372 β_n^22)`.
//!
//! **Sampling.** A lobe `p` is picked with probability `mean(A_p) / Σ mean(A_q)`; `θ_i` is
//! the longitudinal angle of an exact vMF sample about `θ = −θ_o^p`
//! (`cos ψ = 1 + v ln(ξ + (1 − ξ) e^{−2/v})`); `φ` is `Φ_p` plus an exact trimmed-logistic
//! sample (uniform for `p = 3`). The density is the full mixture `Σ_p P(p) M_p N_p`.
//!
//! **Use.** At a hit with tangent `t`, outward normal `n` and `wo` in world space:
//! `h = azimuthal_offset(t, n, wo)`; local frame `x = t`, `y = normalize(n − (n·t) t)`,
//! `z = x × y` (any right-handed frame with this `x` gives the same values), and
//! `w_local = (w·x, w·y, w·z)`. With `α > 0` the R peak moves toward `+x` (`θ_i + θ_o = 2α`);
//! Marschner et al. 2003 observe R shifted toward the root, so orient `t` from tip to root
//! for that sense (the sign of `t` changes nothing else).

use std::f64::consts::{PI, TAU};

use glam::DVec3;

use super::bessel::log_i0;

/// The last lobe index: R, TT, TRT explicit, `p = 3` the residual with isotropic azimuth.
pub const P_MAX: usize = 3;
/// Absorption of eumelanin per unit concentration (pbrt-v4).
const EUMELANIN_SIGMA_A: DVec3 = DVec3::new(0.419, 0.697, 1.37);
/// Absorption of pheomelanin per unit concentration (pbrt-v4).
const PHEOMELANIN_SIGMA_A: DVec3 = DVec3::new(0.187, 0.4, 1.05);

/// User parameters of the hair material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HairParams {
    /// Index of refraction of the fiber (1.55 typical); `>= 1`.
    pub eta: f64,
    /// Absorption coefficient per unit fiber radius (pbrt-v4 convention), RGB, `>= 0`.
    pub sigma_a: DVec3,
    /// Longitudinal roughness in `(0, 1]`.
    pub beta_m: f64,
    /// Azimuthal roughness in `(0, 1]`.
    pub beta_n: f64,
    /// Cuticle tilt in radians (pbrt's default is 2 degrees, `0.0349`).
    pub alpha: f64,
}

impl HairParams {
    /// Absorption from melanin concentrations (pbrt-v4's `SigmaAFromConcentration`):
    /// `σ_a = c_eu (0.419, 0.697, 1.37) + c_pheo (0.187, 0.4, 1.05)`.
    pub fn from_melanin(
        eta: f64,
        eumelanin: f64,
        pheomelanin: f64,
        beta_m: f64,
        beta_n: f64,
        alpha: f64,
    ) -> Self {
        let sigma_a = eumelanin * EUMELANIN_SIGMA_A + pheomelanin * PHEOMELANIN_SIGMA_A;
        HairParams {
            eta,
            sigma_a,
            beta_m,
            beta_n,
            alpha,
        }
    }

    /// Absorption that gives roughly the multiple-scattering colour `color` (each channel
    /// clamped to `[1e-4, 1]`) in a hair assembly (pbrt-v4's `SigmaAFromReflectance`):
    /// `σ_a = (ln c / (5.969 − 0.215 β_n + 2.532 β_n² − 10.73 β_n³ + 5.574 β_n⁴ + 0.245 β_n⁵))²`.
    pub fn from_color(eta: f64, color: DVec3, beta_m: f64, beta_n: f64, alpha: f64) -> Self {
        let b = beta_n;
        let d = 5.969 - 0.215 * b + 2.532 * b.powi(2) - 10.73 * b.powi(3)
            + 5.574 * b.powi(4)
            + 0.245 * b.powi(5);
        let sigma = |c: f64| (c.clamp(1e-4, 1.0).ln() / d).powi(2);
        let c = color;
        let sigma_a = DVec3::new(sigma(c.x), sigma(c.y), sigma(c.z));
        HairParams {
            sigma_a,
            ..Self::from_melanin(eta, 0.0, 0.0, beta_m, beta_n, alpha)
        }
    }

    /// Checks the parameters: all finite, `eta >= 1`, `beta_m, beta_n` in `(0, 1]`,
    /// `sigma_a >= 0`, `|alpha| <= pi/4` (radians). The message names the parameter.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.eta >= 1.0 && self.eta.is_finite()) {
            return Err(format!(
                "hair eta = {} must be a finite index of refraction >= 1",
                self.eta
            ));
        }
        for (name, b) in [("beta_m", self.beta_m), ("beta_n", self.beta_n)] {
            if !(b > 0.0 && b <= 1.0) {
                return Err(format!("hair {name} = {b} must be in (0, 1]"));
            }
        }
        let s = self.sigma_a;
        if !(s.is_finite() && s.min_element() >= 0.0) {
            return Err(format!("hair sigma_a = {s} must be finite and >= 0"));
        }
        if !(self.alpha.abs() <= PI / 4.0) {
            return Err(format!(
                "hair alpha = {} must be a cuticle tilt in radians with |alpha| <= pi/4",
                self.alpha
            ));
        }
        Ok(())
    }
}

/// A hair material ready to shade: its parameters and what depends on them alone (the
/// longitudinal lobes, the azimuthal logistic), made once per material rather than at every
/// hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HairMaterial {
    /// The parameters.
    pub params: HairParams,
    lobes: Longitudinal,
    azimuth: Logistic,
}

impl HairMaterial {
    /// The material of `params`.
    pub fn new(params: HairParams) -> Self {
        HairMaterial {
            params,
            lobes: Longitudinal::new(params.beta_m, params.alpha),
            azimuth: Logistic::new(logistic_scale(params.beta_n)),
        }
    }

    /// Its longitudinal lobes.
    pub fn lobes(&self) -> &Longitudinal {
        &self.lobes
    }
}

/// The BSDF at one hit: the material plus the azimuthal offset `h` in `[-1, 1]`.
#[derive(Clone, Copy, Debug)]
pub struct HairBsdf {
    h: f64,
    gamma_o: f64,
    eta: f64,
    sigma_a: DVec3,
    lobes: Longitudinal,
    azimuth: Logistic,
    /// The terms of one outgoing direction, made once ([`HairBsdf::for_outgoing`]): a
    /// renderer asks for the same `wo` for its light sample and its BSDF sample.
    kept: Option<(DVec3, Outgoing)>,
}

/// Chiang et al.'s longitudinal lobes `M_p(θ_i; θ_o^p)`, shared by every hair model here.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Longitudinal {
    /// Longitudinal variance per lobe.
    v: [f64; P_MAX + 1],
    /// `ln(1 / (2 v sinh(1/v)))` per lobe.
    m_norm: [f64; P_MAX + 1],
    /// `e^{−2/v}` per lobe (sampling).
    e_2v: [f64; P_MAX + 1],
    /// `(sin, cos)` of the rotation of `θ_o` per lobe (cuticle tilt).
    tilt: [(f64, f64); P_MAX + 1],
}

impl Longitudinal {
    /// The lobes of roughness `beta_m` and cuticle tilt `alpha`:
    /// `v_0 = (0.726 β_m + 0.812 β_m² + 3.7 β_m^20)²`, `v_1 = v_0/4`, `v_2 = v_3 = 4 v_0`;
    /// `θ_o` turned by `−2α, α, 4α, 0`.
    pub fn new(beta_m: f64, alpha: f64) -> Self {
        let bm = beta_m;
        let v0 = (0.726 * bm + 0.812 * bm * bm + 3.7 * bm.powi(20)).powi(2);
        let v = [v0, 0.25 * v0, 4.0 * v0, 4.0 * v0];
        Longitudinal {
            v,
            m_norm: v.map(longitudinal_norm),
            e_2v: v.map(|v| (-2.0 / v).exp()),
            tilt: [-2.0 * alpha, alpha, 4.0 * alpha, 0.0].map(f64::sin_cos),
        }
    }

    /// `(sin θ_o^p, |cos θ_o^p|)` per lobe for `(sin θ_o, cos θ_o)`.
    pub fn turned(&self, sin_o: f64, cos_o: f64) -> [(f64, f64); P_MAX + 1] {
        self.tilt
            .map(|(sd, cd)| (sin_o * cd + cos_o * sd, (cos_o * cd - sin_o * sd).abs()))
    }

    /// `M_p(θ_i; θ_o^p)` for `(sin θ_i, cos θ_i)` and `turned = (sin θ_o^p, |cos θ_o^p|)`.
    pub fn eval(&self, p: usize, sin_i: f64, cos_i: f64, turned: (f64, f64)) -> f64 {
        let (sp, cp) = turned;
        longitudinal(cos_i, cp, sin_i, sp, self.v[p], self.m_norm[p])
    }

    /// `(sin θ_i, cos θ_i)` of an exact vMF sample about the direction at `θ = −θ_o^p`:
    /// `1 − cos ψ = −v ln(ξ + (1 − ξ) e^{−2/v})`, `ξ = 1 − u[0]`, and the cone's azimuth
    /// `2π u[1]`.
    pub fn sample(&self, p: usize, turned: (f64, f64), u: [f64; 2]) -> (f64, f64) {
        let v = self.v[p];
        let xi = 1.0 - u[0]; // (0, 1]
        let one_minus_cos = (-v * (xi + (1.0 - xi) * self.e_2v[p]).ln()).clamp(0.0, 2.0);
        let cos_psi = 1.0 - one_minus_cos;
        let sin_psi = safe_sqrt(one_minus_cos * (2.0 - one_minus_cos));
        let (sp, cp) = turned;
        let sin_i = (-cos_psi * sp + sin_psi * (TAU * u[1]).cos() * cp).clamp(-1.0, 1.0);
        (sin_i, safe_sqrt(1.0 - sin_i * sin_i))
    }
}

/// One importance sample of a [`HairBsdf`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HairSample {
    /// The sampled incident direction (local frame, unit).
    pub wi: DVec3,
    /// `eval(wo, wi) / pdf`.
    pub weight: DVec3,
    /// Solid-angle density of `wi`, equal to `pdf(wo, wi)`.
    pub pdf: f64,
}

/// Everything that depends on `wo` only.
#[derive(Clone, Copy, Debug)]
struct Outgoing {
    phi_o: f64,
    gamma_t: f64,
    ap: [DVec3; P_MAX + 1],
    /// Lobe selection probabilities; all zero when nothing scatters.
    lobe_pdf: [f64; P_MAX + 1],
    /// `(sin θ_o^p, |cos θ_o^p|)` per lobe.
    rot: [(f64, f64); P_MAX + 1],
}

impl HairBsdf {
    /// The BSDF of `material` at azimuthal offset `h` (clamped to `[-1, 1]`; NaN reads as 0).
    pub fn new(material: &HairMaterial, h: f64) -> Self {
        let h = if h.is_nan() { 0.0 } else { h.clamp(-1.0, 1.0) };
        HairBsdf {
            h,
            gamma_o: h.asin(),
            eta: material.params.eta,
            sigma_a: material.params.sigma_a,
            lobes: material.lobes,
            azimuth: material.azimuth,
            kept: None,
        }
    }

    /// The same BSDF with the terms of `wo` made now and kept: the same values for every
    /// `wo`, found faster for this one.
    pub fn for_outgoing(self, wo: DVec3) -> Self {
        HairBsdf {
            kept: Some((wo, self.outgoing(wo))),
            ..self
        }
    }

    /// The terms of `wo`: the kept ones if they are of `wo` to the bit (`-0.0` is not `0.0`
    /// here: `atan2` tells them apart).
    fn terms(&self, wo: DVec3) -> Outgoing {
        let bits = |v: DVec3| v.to_array().map(f64::to_bits);
        match self.kept {
            Some((w, o)) if bits(w) == bits(wo) => o,
            _ => self.outgoing(wo),
        }
    }

    /// `f(wo, wi) |cos θ_i|` (pbrt's frame): the integrand weight for radiance,
    /// `L_o = ∫ eval(wo, wi) L_i dω_i`, i.e. `Σ_p M_p A_p N_p`.
    pub fn eval(&self, wo: DVec3, wi: DVec3) -> DVec3 {
        self.eval_and_pdf(wo, wi).0
    }

    /// Solid-angle density of [`HairBsdf::sample`] choosing `wi`.
    pub fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        self.eval_and_pdf(wo, wi).1
    }

    /// [`HairBsdf::eval`] and [`HairBsdf::pdf`] at once (one pass over the lobes).
    pub fn eval_and_pdf(&self, wo: DVec3, wi: DVec3) -> (DVec3, f64) {
        self.eval_pdf(&self.terms(wo), wi)
    }

    /// Importance-samples `wi` given `wo` and 3 uniform numbers in `[0, 1)`: `u[0]` picks the
    /// lobe and then its azimuth, `u[1], u[2]` the longitudinal angle. `None` when nothing
    /// scatters (e.g. `eta = 1` with opaque fibers).
    pub fn sample(&self, wo: DVec3, u: [f64; 3]) -> Option<HairSample> {
        let o = self.terms(wo);
        let (p, uc) = pick_rescaled(o.lobe_pdf.into_iter(), u[0])?;

        let (sin_i, cos_i) = self.lobes.sample(p, o.rot[p], [u[1], u[2]]);

        // φ_i: the lobe's azimuthal centre plus a trimmed logistic (uniform for p = 3).
        let dphi = if p < P_MAX {
            self.phi_center(p, o.gamma_t) + self.azimuth.sample(uc)
        } else {
            TAU * uc
        };
        let phi_i = o.phi_o + dphi;
        let wi = DVec3::new(sin_i, cos_i * phi_i.cos(), cos_i * phi_i.sin());
        let (f, pdf) = self.eval_pdf(&o, wi);
        let weight = f / pdf;
        (pdf > 0.0 && pdf.is_finite() && weight.is_finite()).then_some(HairSample {
            wi,
            weight,
            pdf,
        })
    }

    /// `Φ_p = 2p γ_t − 2 γ_o + p π`.
    fn phi_center(&self, p: usize, gamma_t: f64) -> f64 {
        let p = p as f64;
        2.0 * p * gamma_t - 2.0 * self.gamma_o + p * PI
    }

    fn outgoing(&self, wo: DVec3) -> Outgoing {
        let sin_o = wo.x.clamp(-1.0, 1.0);
        let cos_o = safe_sqrt(1.0 - sin_o * sin_o);
        let phi_o = wo.z.atan2(wo.y);
        let eta = self.eta;
        // Refraction: longitudinal (sin θ_t = sin θ_o / η) and azimuthal (sin γ_t = h / η').
        let sin_t = sin_o / eta;
        let cos_t = safe_sqrt(1.0 - sin_t * sin_t);
        let d = safe_sqrt(eta * eta - sin_o * sin_o); // η' cos θ_o
        let sin_gt = if d > 0.0 {
            (self.h * cos_o / d).clamp(-1.0, 1.0)
        } else {
            self.h
        };
        let cos_gt = safe_sqrt(1.0 - sin_gt * sin_gt);
        // One pass through the fiber: length 2 cos γ_t / cos θ_t in units of the radius
        // (infinite only when η = 1 and wo runs along the fiber).
        let len = 2.0 * cos_gt / cos_t.max(f64::MIN_POSITIVE);
        let t = self
            .sigma_a
            .to_array()
            .map(|sa| if sa > 0.0 { (-sa * len).exp() } else { 1.0 });
        let t = DVec3::from_array(t);
        let f = fresnel_dielectric(cos_o * self.gamma_o.cos(), eta);
        let a1 = (1.0 - f) * (1.0 - f) * t;
        let a2 = a1 * t * f;
        let ft = (f * t).to_array();
        let a3 = DVec3::from_array([0, 1, 2].map(|c| {
            if ft[c] < 1.0 {
                a2[c] * ft[c] / (1.0 - ft[c])
            } else {
                0.0
            }
        }));
        let ap = [DVec3::splat(f), a1, a2, a3];
        let mean = ap.map(|a| a.element_sum() / 3.0);
        let total: f64 = mean.iter().sum();
        let lobe_pdf = if total > 0.0 && total.is_finite() {
            mean.map(|m| m / total)
        } else {
            [0.0; P_MAX + 1]
        };
        let rot = self.lobes.turned(sin_o, cos_o);
        Outgoing {
            phi_o,
            gamma_t: sin_gt.asin(),
            ap,
            lobe_pdf,
            rot,
        }
    }

    /// Per lobe `p`, the azimuthal term `A_p N_p(phi)` at `wi` (without the longitudinal
    /// `M_p`): what a measurement of the fiber's azimuthal scattering compares with.
    pub fn azimuthal_terms(&self, wo: DVec3, wi: DVec3) -> [DVec3; P_MAX + 1] {
        let o = self.terms(wo);
        let phi = wi.z.atan2(wi.y) - o.phi_o;
        std::array::from_fn(|p| {
            let n = if p < P_MAX {
                self.azimuth.density(phi - self.phi_center(p, o.gamma_t))
            } else {
                1.0 / TAU
            };
            n * o.ap[p]
        })
    }

    /// `(eval, pdf)` for `wi` given the `wo` terms.
    fn eval_pdf(&self, o: &Outgoing, wi: DVec3) -> (DVec3, f64) {
        let sin_i = wi.x.clamp(-1.0, 1.0);
        let cos_i = safe_sqrt(1.0 - sin_i * sin_i);
        let phi = wi.z.atan2(wi.y) - o.phi_o;
        let (mut f, mut pdf) = (DVec3::ZERO, 0.0);
        for p in 0..=P_MAX {
            let m = self.lobes.eval(p, sin_i, cos_i, o.rot[p]);
            let n = if p < P_MAX {
                self.azimuth.density(phi - self.phi_center(p, o.gamma_t))
            } else {
                1.0 / TAU
            };
            f += (m * n) * o.ap[p];
            pdf += m * n * o.lobe_pdf[p];
        }
        (f, pdf)
    }
}

/// The azimuthal offset of a hit from the exact geometry:
/// `h = x · (n⊥ × wo⊥) / (|n⊥| |wo⊥|)`, the sine of the azimuthal angle `γ_o = φ_o − φ_n`
/// from the surface normal to the outgoing direction, both projected onto the normal plane
/// (`x` = fiber tangent). All in any one frame (world space is fine). Returns 0 when either
/// projection is ~0. The local frame given to [`HairBsdf`] must use the same `x` and be
/// right-handed, so that the R lobe peaks at the mirror image of `wo` about the normal.
pub fn azimuthal_offset(tangent: DVec3, normal: DVec3, wo: DVec3) -> f64 {
    let x = tangent.normalize_or_zero();
    let n = normal - normal.dot(x) * x;
    let w = wo - wo.dot(x) * x;
    let (ln, lw) = (n.length(), w.length());
    if x == DVec3::ZERO || !(ln > 1e-9 * normal.length()) || !(lw > 1e-9 * wo.length()) {
        return 0.0;
    }
    (x.dot(n.cross(w)) / (ln * lw)).clamp(-1.0, 1.0)
}

/// Picks an index from `weights` (not normalised) with `x` in `[0, Σ w)`: the first whose
/// running sum exceeds `x`, else (rounding) the last with weight; and what is left of `x`
/// rescaled to `[0, 1)` for the next choice. `None` when no weight is positive.
pub fn pick_rescaled(weights: impl Iterator<Item = f64>, x: f64) -> Option<(usize, f64)> {
    let (mut acc, mut last) = (0.0, None);
    for (i, w) in weights.enumerate() {
        if w > 0.0 {
            last = Some((i, acc, w));
            if x < acc + w {
                break;
            }
        }
        acc += w;
    }
    last.map(|(i, lo, w)| (i, ((x - lo) / w).clamp(0.0, 1.0 - f64::EPSILON)))
}

/// Chiang et al.'s logistic scale for azimuthal roughness `β_n`:
/// `s = sqrt(π/8) (0.265 β_n + 1.194 β_n² + 5.372 β_n^22)`.
pub fn logistic_scale(beta_n: f64) -> f64 {
    let bn = beta_n;
    (PI / 8.0).sqrt() * (0.265 * bn + 1.194 * bn * bn + 5.372 * bn.powi(22))
}

fn safe_sqrt(x: f64) -> f64 {
    x.max(0.0).sqrt()
}

/// Unpolarised Fresnel reflectance from outside at `cos_i ∈ [0, 1]` into index `eta >= 1`.
fn fresnel_dielectric(cos_i: f64, eta: f64) -> f64 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    let cos_t = safe_sqrt(1.0 - sin2_t);
    let (dp, ds) = (eta * cos_i + cos_t, cos_i + eta * cos_t);
    if !(dp > 0.0 && ds > 0.0) {
        return 1.0; // grazing with eta = 1: the limit of eta > 1
    }
    let r_par = (eta * cos_i - cos_t) / dp;
    let r_perp = (cos_i - eta * cos_t) / ds;
    0.5 * (r_par * r_par + r_perp * r_perp)
}

/// `ln(1 / (2 v sinh(1/v))) = −1/v − ln v − ln(1 − e^{−2/v})`, exact for every `v > 0`.
fn longitudinal_norm(v: f64) -> f64 {
    -1.0 / v - v.ln() - (-(-2.0 / v).exp_m1()).ln()
}

/// `M(θ_i; θ_o, v) = exp(ln I0(a) − b + norm)`, `a = cos θ_i cos θ_o / v`,
/// `b = sin θ_i sin θ_o / v`, `norm = longitudinal_norm(v)`.
fn longitudinal(cos_i: f64, cos_o: f64, sin_i: f64, sin_o: f64, v: f64, norm: f64) -> f64 {
    (log_i0(cos_i * cos_o / v) - sin_i * sin_o / v + norm).exp()
}

/// The logistic of scale `s` trimmed to `[−π, π]`, at `x` wrapped into that range.
pub fn trimmed_logistic(x: f64, s: f64) -> f64 {
    Logistic::new(s).density(x)
}

/// The logistic `ℓ(x; s)` trimmed to `[−π, π]` and normalised there: the azimuthal lobe
/// `N_p`. Its normalisation `tanh(π / 2s)` and the sampling bound `CDF(−π)` are made once.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Logistic {
    /// The scale `s`.
    s: f64,
    /// `tanh(π / 2s) = CDF(π) − CDF(−π)`.
    mass: f64,
    /// `CDF(−π) = 1 / (1 + e^{π/s})`, with `CDF(x) = 1 / (1 + e^{−x/s})`.
    below: f64,
}

impl Logistic {
    /// The trimmed logistic of scale `s > 0`.
    pub fn new(s: f64) -> Self {
        Logistic {
            s,
            mass: (PI / (2.0 * s)).tanh(),
            below: 1.0 / (1.0 + (PI / s).exp()),
        }
    }

    /// The density at `x` wrapped into `[−π, π]`:
    /// `e^{−|x|/s} / (s (1 + e^{−|x|/s})²) / tanh(π / 2s)`.
    pub fn density(&self, x: f64) -> f64 {
        let s = self.s;
        let x = x - TAU * (x / TAU).round();
        let e = (-x.abs() / s).exp();
        e / (s * (1.0 + e) * (1.0 + e)) / self.mass
    }

    /// Inverse CDF: `x = s ln(u' / (1 − u'))`, `u'` spanning `[CDF(−π), CDF(π)]` for `u` in
    /// `[0, 1]`.
    fn sample(&self, u: f64) -> f64 {
        let lo = self.below;
        let u = lo + u * (1.0 - 2.0 * lo);
        (self.s * (u / (1.0 - u)).ln()).clamp(-PI, PI)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{SampleRng, uniform_sphere};

    const TILT: f64 = 2.0 * PI / 180.0;

    fn params(beta_m: f64, beta_n: f64, alpha: f64, sigma_a: DVec3) -> HairParams {
        HairParams {
            eta: 1.55,
            sigma_a,
            beta_m,
            beta_n,
            alpha,
        }
    }

    fn u3(rng: &mut SampleRng) -> [f64; 3] {
        [rng.uniform(), rng.uniform(), rng.uniform()]
    }

    /// Mean and standard error of the mean.
    fn mean_se(xs: &[f64]) -> (f64, f64) {
        let n = xs.len() as f64;
        let mean = xs.iter().sum::<f64>() / n;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
        (mean, (var / n).sqrt())
    }

    /// The direction with `sin θ = x` and azimuth `phi`.
    fn dir(x: f64, phi: f64) -> DVec3 {
        let c = safe_sqrt(1.0 - x * x);
        DVec3::new(x, c * phi.cos(), c * phi.sin())
    }

    /// Midpoint rule for `∫ g dω` over the cell `[x0, x1] × [p0, p1]` in `(x = sin θ, φ)`,
    /// where `dω = dx dφ`, on an `n × m` grid.
    fn cell_integral(
        x: [f64; 2],
        p: [f64; 2],
        n: usize,
        m: usize,
        g: impl Fn(DVec3) -> DVec3,
    ) -> DVec3 {
        let (dx, dp) = ((x[1] - x[0]) / n as f64, (p[1] - p[0]) / m as f64);
        let mut sum = DVec3::ZERO;
        for i in 0..n * m {
            sum += g(dir(
                x[0] + ((i / m) as f64 + 0.5) * dx,
                p[0] + ((i % m) as f64 + 0.5) * dp,
            ));
        }
        sum * dx * dp
    }

    /// The point of the grid `lo + (hi − lo) j / n` where `f` is largest.
    fn argmax(lo: f64, hi: f64, n: usize, f: impl Fn(f64) -> f64) -> f64 {
        let grid = (0..n).map(|j| lo + (hi - lo) * j as f64 / n as f64);
        grid.max_by(|a, b| f(*a).total_cmp(&f(*b))).unwrap()
    }

    #[test]
    fn white_furnace_uniform_sphere() {
        // σ_a = 0: ∫ eval dω_i = Σ A_p = 1 for every wo, h and tilt. Uniform-sphere MC with h
        // random per sample (as pbrt's test); tolerance 4 standard errors of this very
        // estimate (+1e-3), and se < 0.015 so that the check has teeth (a 6% error fails).
        let mut rng = SampleRng::from_seed(11);
        let configs = [
            (0.2, 0.3, 0.0),
            (0.3, 0.8, TILT),
            (0.7, 0.25, TILT),
            (1.0, 1.0, -TILT),
        ];
        for (bm, bn, alpha) in configs.into_iter().chain([(0.5, 0.5, 0.1)]) {
            let prm = params(bm, bn, alpha, DVec3::ZERO);
            let wo = uniform_sphere(rng.uniform2());
            let xs: Vec<f64> = (0..500_000)
                .map(|_| {
                    let bsdf = HairBsdf::new(&HairMaterial::new(prm), 2.0 * rng.uniform() - 1.0);
                    bsdf.eval(wo, uniform_sphere(rng.uniform2())).x * 4.0 * PI
                })
                .collect();
            let (mean, se) = mean_se(&xs);
            eprintln!("furnace uniform beta ({bm}, {bn}) alpha {alpha:.3}: {mean:.4} ± {se:.4}");
            assert!(se < 0.015, "estimate too noisy to test: se {se}");
            assert!(
                (mean - 1.0).abs() < 4.0 * se + 1e-3,
                "furnace {mean} ± {se} for {prm:?}"
            );
        }
    }

    #[test]
    fn white_furnace_importance_sampled() {
        // σ_a = 0: the lobe probabilities equal A_p, so every weight is exactly 1 (1e-9 for
        // rounding), even at the roughness extremes where uniform MC is hopeless.
        let mut rng = SampleRng::from_seed(12);
        for (bm, bn) in [
            (0.01, 0.01),
            (0.1, 0.1),
            (0.3, 0.7),
            (1.0, 1.0),
            (0.05, 0.9),
        ] {
            let prm = params(bm, bn, TILT, DVec3::ZERO);
            for _ in 0..20_000 {
                let bsdf = HairBsdf::new(&HairMaterial::new(prm), 2.0 * rng.uniform() - 1.0);
                let s = bsdf
                    .sample(uniform_sphere(rng.uniform2()), u3(&mut rng))
                    .unwrap();
                assert!((s.weight - 1.0).abs().max_element() < 1e-9, "{}", s.weight);
            }
        }
        // Absorbing: the sampled albedo (mean weight) matches the uniform-sphere estimate of
        // ∫ eval within 4 combined standard errors, per channel.
        let bsdf = HairBsdf::new(
            &HairMaterial::new(params(0.35, 0.5, TILT, DVec3::new(0.2, 0.6, 1.5))),
            0.3,
        );
        let wo = uniform_sphere(rng.uniform2());
        let n = 200_000;
        let (mut is, mut un) = (vec![[0.0; 3]; n], vec![[0.0; 3]; n]);
        for k in 0..n {
            is[k] = bsdf.sample(wo, u3(&mut rng)).unwrap().weight.to_array();
            un[k] = (bsdf.eval(wo, uniform_sphere(rng.uniform2())) * 4.0 * PI).to_array();
        }
        for c in 0..3 {
            let (a, sa) = mean_se(&is.iter().map(|w| w[c]).collect::<Vec<_>>());
            let (b, sb) = mean_se(&un.iter().map(|w| w[c]).collect::<Vec<_>>());
            eprintln!("albedo channel {c}: sampled {a:.4} ± {sa:.4}, uniform {b:.4} ± {sb:.4}");
            assert!(
                (a - b).abs() < 4.0 * (sa * sa + sb * sb).sqrt(),
                "channel {c}"
            );
        }
    }

    #[test]
    fn reciprocal_for_equal_longitudinal_angles_without_tilt() {
        // The model is not pointwise reciprocal (pbrt-v4's reciprocity test is disabled):
        // A_p and γ_t depend on θ_o only, and the tilt rotates θ_o only. What holds exactly
        // with α = 0 and |sin θ_i| = |sin θ_o|: the reversed path has the offset −h (mirror
        // and chord geometry flip the sign of n × w), and eval(wo, wi; h) = eval(wi, wo; −h).
        // As cos θ_i = cos θ_o here, f = eval / cos θ_i is then symmetric too.
        let mut rng = SampleRng::from_seed(13);
        for _ in 0..5000 {
            let sig = DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 3.0;
            let prm = params(
                0.05 + 0.95 * rng.uniform(),
                0.05 + 0.95 * rng.uniform(),
                0.0,
                sig,
            );
            let h = 2.0 * rng.uniform() - 1.0;
            let wo = uniform_sphere(rng.uniform2());
            let sign = if rng.uniform() < 0.5 { 1.0 } else { -1.0 };
            let wi = dir(sign * wo.x, TAU * rng.uniform());
            let a = HairBsdf::new(&HairMaterial::new(prm), h).eval(wo, wi);
            let b = HairBsdf::new(&HairMaterial::new(prm), -h).eval(wi, wo);
            let rel = (a - b).abs().max_element() / a.max_element().max(1e-300);
            assert!(
                rel < 1e-9,
                "{a} vs {b} (rel {rel:e}), h {h}, wo {wo}, wi {wi}"
            );
        }
    }

    /// The BSDF with one direction's terms kept gives every value to the bit as without,
    /// for that direction, for it with a zero's sign flipped, and for others.
    #[test]
    fn kept_outgoing_terms_change_no_value() {
        let mut rng = SampleRng::from_seed(23);
        for _ in 0..2_000 {
            let sig = DVec3::new(rng.uniform(), rng.uniform(), 3.0 * rng.uniform());
            let prm = params(rng.range(0.1, 1.0), rng.range(0.1, 1.0), TILT, sig);
            let plain = HairBsdf::new(&HairMaterial::new(prm), 2.0 * rng.uniform() - 1.0);
            let mut kept_wo = uniform_sphere(rng.uniform2());
            // A signed zero where `atan2` tells the signs apart (`y < 0`), queried with both.
            let flipped = if kept_wo.y < 0.0 {
                kept_wo.z = 0.0;
                DVec3::new(kept_wo.x, kept_wo.y, -0.0)
            } else {
                kept_wo
            };
            let kept = plain.for_outgoing(kept_wo);
            for wo in [kept_wo, flipped, uniform_sphere(rng.uniform2())] {
                let (wi, u) = (uniform_sphere(rng.uniform2()), u3(&mut rng));
                assert_eq!(kept.eval_and_pdf(wo, wi), plain.eval_and_pdf(wo, wi));
                assert_eq!(kept.azimuthal_terms(wo, wi), plain.azimuthal_terms(wo, wi));
                let (a, b) = (kept.sample(wo, u), plain.sample(wo, u));
                assert_eq!(
                    a.map(|s| (s.wi, s.weight, s.pdf)),
                    b.map(|s| (s.wi, s.weight, s.pdf))
                );
            }
        }
    }

    #[test]
    fn sampling_matches_pdf_and_eval() {
        let mut rng = SampleRng::from_seed(14);
        let sig = DVec3::new(0.3, 0.8, 2.0);
        // (a) The sample's pdf and weight agree with pdf() and eval() at its wi.
        for _ in 0..20_000 {
            let bsdf = HairBsdf::new(
                &HairMaterial::new(params(0.3, 0.4, TILT, sig)),
                2.0 * rng.uniform() - 1.0,
            );
            let wo = uniform_sphere(rng.uniform2());
            let s = bsdf.sample(wo, u3(&mut rng)).unwrap();
            let pdf = bsdf.pdf(wo, s.wi);
            assert!((s.pdf - pdf).abs() <= 1e-6 * pdf, "{} vs {pdf}", s.pdf);
            let w = bsdf.eval(wo, s.wi) / pdf;
            assert!((s.weight - w).abs().max_element() <= 1e-9 * w.max_element());
        }
        for (bm, bn, h, wo) in [
            (0.3, 0.4, -0.6, dir(0.4, 1.0)),
            (0.6, 0.8, 0.9, dir(-0.8, -2.0)),
        ] {
            let bsdf = HairBsdf::new(&HairMaterial::new(params(bm, bn, TILT, sig)), h);
            // (b) pdf integrates to 1: uniform-sphere MC, 4 standard errors.
            let xs: Vec<f64> = (0..300_000)
                .map(|_| bsdf.pdf(wo, uniform_sphere(rng.uniform2())) * 4.0 * PI)
                .collect();
            let (mean, se) = mean_se(&xs);
            eprintln!("pdf integral (MC): {mean:.4} ± {se:.4}");
            assert!(
                se < 0.01 && (mean - 1.0).abs() < 4.0 * se + 1e-3,
                "{mean} ± {se}"
            );
            // (c) Chi-square of sampled directions.
            chi_square(&bsdf, wo, &mut rng);
        }
    }

    /// Bins 200k samples in 20 × 40 equal-area cells of `(sin θ, φ)` and compares the counts
    /// with the pdf integrated over each cell (6 × 6 midpoint rule: relative error ~1e-3, far
    /// below the ~3% Poisson noise of the fullest cells). Cells expecting < 5 are pooled.
    fn chi_square(bsdf: &HairBsdf, wo: DVec3, rng: &mut SampleRng) {
        const NX: usize = 20;
        const NP: usize = 40;
        let n = 200_000;
        let mut counts = vec![0.0; NX * NP];
        for _ in 0..n {
            let wi = bsdf.sample(wo, u3(rng)).unwrap().wi;
            let ix = (((wi.x + 1.0) / 2.0 * NX as f64) as usize).min(NX - 1);
            let ip = (((wi.z.atan2(wi.y) + PI) / TAU * NP as f64) as usize).min(NP - 1);
            counts[ix * NP + ip] += 1.0;
        }
        let (dx, dp) = (2.0 / NX as f64, TAU / NP as f64);
        let (mut chi2, mut dof, mut pool, mut total) = (0.0, -1.0, (0.0, 0.0), 0.0);
        for (k, &o) in counts.iter().enumerate() {
            let (x0, p0) = (-1.0 + (k / NP) as f64 * dx, -PI + (k % NP) as f64 * dp);
            let prob = cell_integral([x0, x0 + dx], [p0, p0 + dp], 6, 6, |wi| {
                DVec3::splat(bsdf.pdf(wo, wi))
            });
            let e = prob.x * n as f64;
            total += prob.x;
            if e < 5.0 {
                pool = (pool.0 + e, pool.1 + o);
            } else {
                (chi2, dof) = (chi2 + (o - e) * (o - e) / e, dof + 1.0);
            }
        }
        if pool.0 > 0.0 {
            (chi2, dof) = (chi2 + (pool.1 - pool.0).powi(2) / pool.0, dof + 1.0);
        }
        assert!(
            (total - 1.0).abs() < 2e-3,
            "pdf integral (quadrature) {total}"
        );
        // Wilson–Hilferty: z ~ N(0, 1) under the null; z < 4.5 is p > ~3e-6.
        let k = 2.0 / (9.0 * dof);
        let z = ((chi2 / dof).cbrt() - (1.0 - k)) / k.sqrt();
        eprintln!("chi-square {chi2:.1} on {dof} dof (z = {z:.2}), pdf integral {total:.5}");
        assert!(z < 4.5, "chi-square {chi2} on {dof} dof, z = {z}");
    }

    #[test]
    fn absorbing_fiber_reflects_fresnel() {
        // With huge σ_a (T < e^-90) only R is left: ∫ eval dω = A_0 = F(cos θ_o cos γ_o),
        // checked by quadrature against Fresnel in its sin/tan form (independent of the
        // code's); this also checks that M_0 N_0 stays normalised under tilt. Tolerance 1e-4:
        // the 300 × 600 midpoint rule's error for these lobe widths is ~1e-6.
        let prm = params(0.25, 0.3, TILT, DVec3::splat(60.0));
        for (x, phi, h) in [(0.3, 0.5, 0.4), (-0.6, 2.0, -0.9), (0.05, -1.0, 0.7)] {
            let (wo, bsdf) = (dir(x, phi), HairBsdf::new(&HairMaterial::new(prm), h));
            let albedo = cell_integral([-1.0, 1.0], [-PI, PI], 300, 600, |wi| bsdf.eval(wo, wi));
            let ti = (safe_sqrt(1.0 - x * x) * safe_sqrt(1.0 - h * h)).acos();
            let tt = (ti.sin() / 1.55).asin();
            let (s, t) = (
                (ti - tt).sin() / (ti + tt).sin(),
                (ti - tt).tan() / (ti + tt).tan(),
            );
            let f = 0.5 * (s * s + t * t);
            eprintln!("R-only albedo {} vs Fresnel {f:.6}", albedo.x);
            assert!((albedo - f).abs().max_element() < 1e-4, "{albedo} vs {f}");
        }
    }

    #[test]
    fn offset_ties_r_lobe_to_mirror_of_normal() {
        // A smooth, opaque fiber (β = 0.1, only R left). wo at φ_o = π/2; for normals at
        // several azimuths φ_n, h comes from the exact geometry through azimuthal_offset. The
        // R peak must be the mirror of wo about n, wi = 2 (wo·n) n − wo: φ = 2φ_n − φ_o, and
        // θ_i = −θ_o (+ 2α with tilt). The wrong sign of h would put it 4|γ_o| >= 0.4 rad off.
        let wo = dir(0.3, PI / 2.0);
        let mut rng = SampleRng::from_seed(15);
        for alpha in [0.0, 0.05] {
            let prm = params(0.1, 0.1, alpha, DVec3::splat(1e3));
            for dn in [-1.2, -0.5, -0.1, 0.3, 0.9, 1.4] {
                let n = DVec3::new(0.0, (PI / 2.0 + dn).cos(), (PI / 2.0 + dn).sin());
                let h = azimuthal_offset(DVec3::X, n, wo);
                assert!((h - (-dn).sin()).abs() < 1e-12, "h {h} for γ_o {}", -dn);
                let bsdf = HairBsdf::new(&HairMaterial::new(prm), h);
                let mirror = 2.0 * wo.dot(n) * n - wo;
                let phi_r = mirror.z.atan2(mirror.y);
                let lum = |w: DVec3| bsdf.eval(wo, w).element_sum();
                // Argmax over φ on the peak's latitude: eval's φ dependence is N_0 alone, so
                // the tolerance is 2 grid steps (2π/7200 ≈ 0.0009 rad).
                let theta_peak = -(0.3f64.asin()) + 2.0 * alpha;
                let best = argmax(-PI, PI, 7200, |phi| lum(dir(theta_peak.sin(), phi)));
                let d = best - phi_r;
                assert!(
                    (d - TAU * (d / TAU).round()).abs() < 2e-3,
                    "φ peak {best} vs {phi_r}"
                );
                // Argmax over θ at φ_r (grid 0.0005 rad): M_0's 1/sqrt(cos θ_i) factor moves
                // its peak by ~v tan θ / 2 < 1e-3, so tolerance 3e-3 (2α = 0.1 rad).
                let best_t = argmax(-1.5, 1.5, 6000, |t| lum(dir(t.sin(), phi_r)));
                assert!(
                    (best_t - theta_peak).abs() < 3e-3,
                    "θ peak {best_t} vs {theta_peak}"
                );
                // Sampling agrees: the mean sampled direction points at the mirror (lobe
                // widths ~0.08 rad; the mean of 2000 is within ~0.01 of the mode).
                if alpha == 0.0 {
                    let mean: DVec3 = (0..2000)
                        .map(|_| bsdf.sample(wo, u3(&mut rng)).unwrap().wi)
                        .sum();
                    let ang = mean.normalize().angle_between(mirror);
                    assert!(
                        ang < 0.03,
                        "sampled mean {mean} is {ang} rad from the mirror"
                    );
                }
            }
        }
        assert_eq!(azimuthal_offset(DVec3::X, DVec3::X, wo), 0.0);
        assert_eq!(azimuthal_offset(DVec3::X, DVec3::Y, DVec3::X), 0.0);
    }

    #[test]
    fn lobe_centres_match_a_traced_ray() {
        // Trace the reversed path in the normal plane through a unit circle: leave the hit
        // point (normal n, h from azimuthal_offset) against wo, refract with Bravais' η',
        // reflect p − 1 times inside, refract out. The exit direction is wi's azimuth and
        // must equal φ_o + Φ_p for R, TT and TRT (1e-9, rounding only).
        use glam::DVec2;
        let refract = |d: DVec2, n: DVec2, r: f64| {
            let c = -d.dot(n);
            r * d + (r * c - (1.0 - r * r * (1.0 - c * c)).sqrt()) * n
        };
        let mut rng = SampleRng::from_seed(18);
        for _ in 0..300 {
            let (x, phi_o, gamma_o) = (
                1.8 * rng.uniform() - 0.9,
                TAU * rng.uniform(),
                3.1 * rng.uniform() - 1.55,
            );
            let wo = dir(x, phi_o);
            let phi_n = phi_o - gamma_o;
            let n3 = DVec3::new(0.0, phi_n.cos(), phi_n.sin());
            let prm = params(0.3, 0.3, TILT, DVec3::ZERO);
            let bsdf = HairBsdf::new(&HairMaterial::new(prm), azimuthal_offset(DVec3::X, n3, wo));
            let gamma_t = bsdf.outgoing(wo).gamma_t;
            let eta_p = (1.55f64 * 1.55 - x * x).sqrt() / (1.0 - x * x).sqrt();
            for p in 0..3 {
                let mut at = DVec2::new(n3.y, n3.z);
                let mut d = -DVec2::new(wo.y, wo.z).normalize();
                let exit = if p == 0 {
                    d - 2.0 * d.dot(at) * at
                } else {
                    d = refract(d, at, 1.0 / eta_p);
                    for _ in 1..p {
                        at += -2.0 * at.dot(d) * d;
                        d -= 2.0 * d.dot(at) * at;
                    }
                    at += -2.0 * at.dot(d) * d;
                    refract(d, -at, eta_p)
                };
                let diff = exit.y.atan2(exit.x) - phi_o - bsdf.phi_center(p, gamma_t);
                let diff = diff - TAU * (diff / TAU).round();
                assert!(
                    diff.abs() < 1e-9,
                    "p {p}: off by {diff} (γ_o {gamma_o}, x {x})"
                );
            }
        }
    }

    #[test]
    fn longitudinal_lobes_are_normalised() {
        // ∫ M cos θ_i dθ_i = 1 for every v from β_m = 0.01 (v_1 = 1.3e-5) to β_m = 1
        // (v_2 = 110) and tilted θ_o: midpoint rule with 400k steps (step 8e-6 rad, several
        // per lobe width sqrt(v) >= 0.0036). Tolerance 1e-6: the rule's endpoint error
        // h²/24 |f'(±π/2)| reaches 2e-7 when the narrowest lobe sits on the pole.
        for v in [1.3e-5, 1e-3, 0.1, 1.0, 110.0] {
            for t_o in [0.0, 0.7, -1.4, PI / 2.0 - 1e-4] {
                let n = 400_000;
                let sum: f64 = (0..n)
                    .map(|k| {
                        let t = -PI / 2.0 + PI * (k as f64 + 0.5) / n as f64;
                        let (s, c) = t.sin_cos();
                        longitudinal(c, t_o.cos(), s, t_o.sin(), v, longitudinal_norm(v)) * c
                    })
                    .sum();
                let total = sum * PI / n as f64;
                assert!(
                    (total - 1.0).abs() < 1e-6,
                    "∫ M = {total} for v {v}, θ_o {t_o}"
                );
            }
        }
    }

    #[test]
    fn extremes_stay_finite() {
        // Grazing wo and wi, h = ±1, roughness 0.01 and 1, η = 1 and 1.0001, clear to opaque
        // fibers: eval, pdf and sample are finite and >= 0. sample may decline only when
        // nothing scatters (η = 1 with absorption and no Fresnel reflection) or at u exactly
        // 0 or 1 − ε, where the trimmed logistic's density underflows at ±π.
        let mut rng = SampleRng::from_seed(16);
        let xs = [1.0, -1.0, 1.0 - 1e-12, -1.0 + 1e-12, 1e-300, 0.3];
        let sigmas = [DVec3::ZERO, DVec3::new(0.2, 0.5, 1.0), DVec3::splat(1e4)];
        let betas = [(0.01, 0.01), (1.0, 1.0), (0.01, 1.0), (1.0, 0.01)];
        let edge = 1.0 - f64::EPSILON;
        for k in 0..3 * 4 * 3 * 2 * 5 {
            let (beta_m, beta_n) = betas[k / 3 % 4];
            let prm = HairParams {
                eta: [1.0, 1.0001, 1.55][k % 3],
                sigma_a: sigmas[k / 12 % 3],
                beta_m,
                beta_n,
                alpha: [0.0, TILT][k / 36 % 2],
            };
            let h = [-1.0, -0.999_999, 0.0, 0.5, 1.0][k / 72];
            let bsdf = HairBsdf::new(&HairMaterial::new(prm), h);
            for x in xs {
                let wo = dir(x, TAU * rng.uniform());
                let wis = (0..10).map(|_| uniform_sphere(rng.uniform2()));
                for wi in wis.chain(xs.map(|x| dir(x, 0.7))) {
                    let (f, pdf) = (bsdf.eval(wo, wi), bsdf.pdf(wo, wi));
                    assert!(f.is_finite() && f.min_element() >= 0.0, "{f} {prm:?} h {h}");
                    assert!(pdf.is_finite() && pdf >= 0.0, "{pdf} {prm:?} h {h}");
                }
                for u in [
                    u3(&mut rng),
                    u3(&mut rng),
                    [0.0; 3],
                    [edge; 3],
                    [0.5, 0.0, edge],
                ] {
                    let Some(s) = bsdf.sample(wo, u) else {
                        let nothing = bsdf.outgoing(wo).lobe_pdf == [0.0; 4];
                        let allowed = nothing || u[0] == 0.0 || u[0] == edge;
                        assert!(allowed, "no sample for {prm:?}, h {h}, wo {wo}, u {u:?}");
                        continue;
                    };
                    assert!(
                        s.weight.is_finite() && s.weight.min_element() >= 0.0,
                        "{}",
                        s.weight
                    );
                    assert!(s.pdf > 0.0 && s.pdf.is_finite() && (s.wi.length() - 1.0).abs() < 1e-9);
                }
            }
        }
    }

    #[test]
    fn melanin_and_color() {
        let p = HairParams::from_melanin(1.55, 0.0, 0.0, 0.3, 0.3, TILT);
        assert_eq!(p.sigma_a, DVec3::ZERO);
        let p = HairParams::from_melanin(1.55, 1.3, 0.5, 0.3, 0.3, TILT);
        let want = DVec3::new(
            1.3 * 0.419 + 0.5 * 0.187,
            1.3 * 0.697 + 0.2,
            1.3 * 1.37 + 0.525,
        );
        assert!(
            (p.sigma_a - want).abs().max_element() < 1e-12,
            "{}",
            p.sigma_a
        );
        assert!(p.validate().is_ok());
        // Colour: white gives no absorption; a brighter channel absorbs less; the resulting
        // single-fiber albedo (importance-sampled over random h and wo; se ~0.001) is ordered
        // like the requested colour.
        let white = HairParams::from_color(1.55, DVec3::ONE, 0.3, 0.5, TILT);
        assert_eq!(white.sigma_a, DVec3::ZERO);
        let c = DVec3::new(0.8, 0.5, 0.2);
        let p = HairParams::from_color(1.55, c, 0.3, 0.5, TILT);
        let s = p.sigma_a;
        assert!(s.x > 0.0 && s.x < s.y && s.y < s.z, "{s}");
        let darker = HairParams::from_color(1.55, c * 0.5, 0.3, 0.5, TILT).sigma_a;
        assert!(darker.cmpgt(s).all(), "{darker} vs {s}");
        let mut rng = SampleRng::from_seed(17);
        let mut albedo = DVec3::ZERO;
        for _ in 0..20_000 {
            let bsdf = HairBsdf::new(&HairMaterial::new(p), 2.0 * rng.uniform() - 1.0);
            albedo += bsdf
                .sample(uniform_sphere(rng.uniform2()), u3(&mut rng))
                .unwrap()
                .weight
                / 2e4;
        }
        eprintln!("from_color {c}: sigma_a {s}, single-fiber albedo {albedo}");
        assert!(albedo.x > albedo.y + 0.01 && albedo.y > albedo.z + 0.01 && albedo.x < 1.0);
    }

    #[test]
    fn validate_names_the_parameter() {
        let ok = params(0.3, 0.3, TILT, DVec3::new(0.1, 0.2, 0.3));
        assert_eq!(ok.validate(), Ok(()));
        assert_eq!(HairParams { eta: 1.0, ..ok }.validate(), Ok(()));
        let bad = [
            (HairParams { eta: 0.9, ..ok }, "eta = 0.9"),
            (
                HairParams {
                    eta: f64::NAN,
                    ..ok
                },
                "eta = NaN",
            ),
            (HairParams { beta_m: 0.0, ..ok }, "beta_m = 0"),
            (HairParams { beta_n: 1.5, ..ok }, "beta_n = 1.5"),
            (
                HairParams {
                    sigma_a: DVec3::new(0.1, -1.0, 0.0),
                    ..ok
                },
                "sigma_a",
            ),
            (
                HairParams {
                    sigma_a: DVec3::splat(f64::INFINITY),
                    ..ok
                },
                "sigma_a",
            ),
            (HairParams { alpha: 2.0, ..ok }, "alpha = 2"),
        ];
        for (p, needle) in bad {
            let e = p.validate().expect_err(needle);
            assert!(e.contains(needle), "{e:?} lacks {needle:?}");
        }
    }
}
