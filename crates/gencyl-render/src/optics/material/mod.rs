//! Materials: how light scatters where a ray meets a surface.
//!
//! A [`Material`] is what a scene names; at a hit it becomes a [`Bsdf`] in the hit's frame.
//! Every `eval` returns the integrand weight `f(wo, wi) |cos theta_i|` (the cosine taken
//! against whatever the model integrates over: the surface normal, or for fibers the
//! fiber's normal plane), so `L_o = ∫ eval(wo, wi) L_i dω_i`; `sample` returns
//! `eval / pdf`. Directions point away from the surface (`wo` toward the viewer).

mod bessel;
pub mod exact;
pub mod hair;

use std::f64::consts::PI;
use std::sync::Arc;

use glam::DVec3;

use crate::sampling::{basis, cosine_hemisphere, uniform_sphere};
use exact::{ExactHairBsdf, ExactSection};
use hair::{HairBsdf, HairMaterial, azimuthal_offset};

/// A scattering model with its parameters.
#[derive(Clone, Debug, PartialEq)]
pub enum Material {
    /// Lambertian reflection on the exact surface normal (both sides).
    Diffuse {
        /// Reflectance.
        albedo: DVec3,
    },
    /// Kajiya and Kay 1989: a diffuse term `k_d sin(t, wi) / pi^2` (albedo `k_d` under uniform
    /// light) and a highlight `k_s max(0, sin(t,wi) sin(t,wo) - (t.wi)(t.wo))^p` around the
    /// fiber tangent `t`. Not energy conserving; offered because artists know it.
    KajiyaKay {
        /// Diffuse colour.
        diffuse: DVec3,
        /// Highlight colour.
        specular: DVec3,
        /// Highlight exponent.
        exponent: f64,
    },
    /// The hair BSDF of Chiang et al. 2016 ([`hair`]).
    Hair(HairMaterial),
    /// Hair whose azimuthal scattering is traced on its exact section ([`exact`]):
    /// `section = "exact"`.
    ExactHair {
        /// `eta`, `sigma_a` (per unit of the section's bounding radius), `beta_m`, `beta_n`,
        /// `alpha` as for [`Material::Hair`].
        hair: HairMaterial,
        /// The tables, built when the scene is loaded over the sections of the fibers that use
        /// the material (`None` when none does: then it shades as [`Material::Hair`]).
        tables: Option<Arc<ExactSection>>,
    },
    /// A smooth dielectric solid with interior absorption: Fresnel reflection and refraction
    /// at every boundary (side and caps), radiance falling as `exp(-sigma_a s)` along a path
    /// of length `s` inside.
    Dielectric {
        /// Index of refraction (outside is 1).
        eta: f64,
        /// Absorption coefficient per unit length, per channel.
        sigma_a: DVec3,
    },
}

impl Material {
    /// Whether its BSDF reads the fiber's section ([`ShadingPoint::section`]): only the
    /// exact-section hair model with its tables does ([`Bsdf::new`]); the rest need the
    /// tangent and the normal alone.
    pub fn uses_section(&self) -> bool {
        matches!(
            self,
            Material::ExactHair {
                tables: Some(_),
                ..
            }
        )
    }

    /// Checks the parameters; the message names the parameter and its value.
    pub fn validate(&self) -> Result<(), String> {
        let colour = |name: &str, c: DVec3, max: f64| {
            if c.is_finite() && c.min_element() >= 0.0 && c.max_element() <= max {
                Ok(())
            } else {
                Err(format!(
                    "{name} must be finite and in [0, {max}], got {:?}",
                    c.to_array()
                ))
            }
        };
        match *self {
            Material::Diffuse { albedo } => colour("albedo", albedo, 1.0),
            Material::KajiyaKay {
                diffuse,
                specular,
                exponent,
            } => {
                colour("diffuse", diffuse, 1.0)?;
                colour("specular", specular, f64::MAX)?;
                if exponent.is_finite() && exponent >= 0.0 {
                    Ok(())
                } else {
                    Err(format!(
                        "exponent must be finite and non-negative, got {exponent}"
                    ))
                }
            }
            Material::Hair(h) => h.params.validate(),
            Material::ExactHair { hair, .. } => {
                let params = hair.params;
                params.validate()?;
                if params.eta > 1.0 && params.eta <= 10.0 {
                    Ok(())
                } else {
                    Err(format!(
                        "section = \"exact\" needs eta in (1, 10], got {}",
                        params.eta
                    ))
                }
            }
            Material::Dielectric { eta, sigma_a } => {
                if !(eta.is_finite() && eta >= 1.0) {
                    return Err(format!("eta must be finite and at least 1, got {eta}"));
                }
                colour("sigma_a", sigma_a, f64::MAX)
            }
        }
    }
}

/// A material as a scene names it, with its X-ray attenuation.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneMaterial {
    /// The name objects refer to.
    pub name: String,
    /// The scattering model.
    pub material: Material,
    /// X-ray linear attenuation coefficient `mu` per unit length: one value (every energy),
    /// or one per bin of the `[ct]` spectrum.
    pub xray_mu: Vec<f64>,
}

/// Where a ray met a surface, as shading needs it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadingPoint {
    /// Outward unit normal of the solid (for a plane: its normal).
    pub normal: DVec3,
    /// Unit fiber tangent `t(u)`, for fibers.
    pub tangent: Option<DVec3>,
    /// The fiber's section at the hit, for fibers.
    pub section: Option<SectionAt>,
}

/// A fiber's section where a ray met it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SectionAt {
    /// Unit direction of the section's major axis (across the tangent).
    pub major: DVec3,
    /// Minor / major radius (for a profile: its stretch across over along the major axis).
    pub aspect: f64,
}

/// A sampled scattering direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    /// Unit direction the light comes from (the continuing path's direction).
    pub wi: DVec3,
    /// `eval(wo, wi) / pdf`; for delta lobes, the lobe's weight.
    pub weight: DVec3,
    /// Solid-angle density; `inf` for delta lobes.
    pub pdf: f64,
}

/// A material at a hit, in world space.
// Made per hit on the stack and dropped with it: the hair variant's kept terms (a few hundred
// bytes) cost less there than a box would.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug)]
pub enum Bsdf<'a> {
    /// Lambert about `n`, turned to the viewer's side.
    Diffuse {
        /// Albedo.
        albedo: DVec3,
        /// Unit normal on the viewer's side.
        n: DVec3,
    },
    /// Kajiya-Kay around the tangent `t`.
    KajiyaKay {
        /// Diffuse colour.
        diffuse: DVec3,
        /// Highlight colour.
        specular: DVec3,
        /// Highlight exponent.
        exponent: f64,
        /// Unit tangent.
        t: DVec3,
    },
    /// A hair model in the local frame `(x, y, z)`: `x` the tangent from tip to root, `z` the
    /// normal's component in the normal plane, `y = z x x`.
    Hair {
        /// Chiang et al. with its `h`, or the exact-section model with its section.
        model: HairModel<'a>,
        /// Local frame.
        frame: [DVec3; 3],
    },
    /// Smooth dielectric boundary with outward normal `n`.
    Dielectric {
        /// Index of refraction inside.
        eta: f64,
        /// Outward unit normal.
        n: DVec3,
    },
}

/// Unpolarized Fresnel reflectance of a smooth dielectric boundary, for light arriving at
/// `cos_i` (> 0 on the side the relative index `eta = eta_t / eta_i` is seen from):
/// `F = (r_s^2 + r_p^2) / 2`, `r_s = (cos_i - eta cos_t) / (cos_i + eta cos_t)`,
/// `r_p = (eta cos_i - cos_t) / (eta cos_i + cos_t)`, `sin_t = sin_i / eta`; 1 past the
/// critical angle.
pub fn fresnel_dielectric(cos_i: f64, eta: f64) -> f64 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    0.5 * (rs * rs + rp * rp)
}

/// The refraction of `wo` (pointing away from the surface, on the side of `n`) through a
/// boundary of relative index `eta = eta_t / eta_i`: `wi = -wo / eta + (cos_i / eta - cos_t) n`.
/// `None` past the critical angle.
pub fn refract(wo: DVec3, n: DVec3, eta: f64) -> Option<DVec3> {
    let cos_i = wo.dot(n);
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((-wo / eta + (cos_i / eta - cos_t) * n).normalize())
}

/// The hair models, in their local frame.
#[allow(clippy::large_enum_variant)] // as `Bsdf`
#[derive(Clone, Copy, Debug)]
pub enum HairModel<'a> {
    /// Chiang et al. 2016 ([`hair`]).
    Chiang(HairBsdf),
    /// Azimuthal scattering traced on the exact section ([`exact`]).
    Exact(ExactHairBsdf<'a>),
}

impl HairModel<'_> {
    fn eval(&self, wo: DVec3, wi: DVec3) -> DVec3 {
        match self {
            HairModel::Chiang(b) => b.eval(wo, wi),
            HairModel::Exact(b) => b.eval(wo, wi),
        }
    }

    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        match self {
            HairModel::Chiang(b) => b.pdf(wo, wi),
            HairModel::Exact(b) => b.pdf(wo, wi),
        }
    }

    fn eval_and_pdf(&self, wo: DVec3, wi: DVec3) -> (DVec3, f64) {
        match self {
            HairModel::Chiang(b) => b.eval_and_pdf(wo, wi),
            HairModel::Exact(b) => b.eval_and_pdf(wo, wi),
        }
    }

    fn sample(&self, wo: DVec3, u: [f64; 3]) -> Option<hair::HairSample> {
        match self {
            HairModel::Chiang(b) => b.sample(wo, u),
            HairModel::Exact(b) => b.sample(wo, u),
        }
    }
}

/// The local frame of the hair models at a hit: `x = -t` (from tip to root: with a positive
/// cuticle tilt the R highlight then shifts toward the root, as Marschner et al. 2003
/// measured), `z` the normal's part across the fiber, `y = z x x`.
fn hair_frame(t: DVec3, normal: DVec3) -> [DVec3; 3] {
    let x = -t;
    let across = normal - normal.dot(x) * x;
    let z = if across.length_squared() > 1e-24 {
        across.normalize()
    } else {
        basis(x).0
    };
    [x, z.cross(x), z]
}

impl<'a> Bsdf<'a> {
    /// The material's BSDF at a hit seen from `wo`.
    pub fn new(material: &'a Material, at: &ShadingPoint, wo: DVec3) -> Bsdf<'a> {
        let facing = if at.normal.dot(wo) < 0.0 {
            -at.normal
        } else {
            at.normal
        };
        match *material {
            Material::Diffuse { albedo } => Bsdf::Diffuse { albedo, n: facing },
            Material::KajiyaKay {
                diffuse,
                specular,
                exponent,
            } => match at.tangent {
                Some(t) => Bsdf::KajiyaKay {
                    diffuse,
                    specular,
                    exponent,
                    t,
                },
                None => Bsdf::Diffuse {
                    albedo: diffuse,
                    n: facing,
                },
            },
            Material::Hair(ref hair) | Material::ExactHair { ref hair, .. } => match at.tangent {
                Some(t) => {
                    let frame = hair_frame(t, at.normal);
                    let model = match (material, at.section) {
                        (
                            Material::ExactHair {
                                tables: Some(tables),
                                ..
                            },
                            Some(s),
                        ) => HairModel::Exact(ExactHairBsdf::new(
                            hair,
                            tables,
                            s.aspect,
                            Self::to_local(&frame, s.major),
                        )),
                        _ => HairModel::Chiang(
                            HairBsdf::new(hair, azimuthal_offset(frame[0], at.normal, wo))
                                .for_outgoing(Self::to_local(&frame, wo)),
                        ),
                    };
                    Bsdf::Hair { model, frame }
                }
                // Hair on a non-fiber surface has no tangent: shade it as its colour.
                None => Bsdf::Diffuse {
                    albedo: DVec3::splat(0.5),
                    n: facing,
                },
            },
            Material::Dielectric { eta, .. } => Bsdf::Dielectric { eta, n: at.normal },
        }
    }

    /// Whether the BSDF is a delta distribution (no light sampling at it).
    pub fn is_delta(&self) -> bool {
        matches!(self, Bsdf::Dielectric { .. })
    }

    /// Whether [`Self::eval_pdf`] costs enough (the hair models: four longitudinal lobes with
    /// their Bessel terms, three azimuthal ones, an `atan2`: 1,300 instructions, an eighth of
    /// a shadow ray through the ponytail, two thirds of which are blocked) that a renderer
    /// should test the light's visibility first.
    pub fn eval_is_costly(&self) -> bool {
        matches!(self, Bsdf::Hair { .. })
    }

    fn to_local(frame: &[DVec3; 3], w: DVec3) -> DVec3 {
        DVec3::new(w.dot(frame[0]), w.dot(frame[1]), w.dot(frame[2]))
    }

    /// `f(wo, wi) |cos theta_i|` (zero for delta BSDFs).
    pub fn eval(&self, wo: DVec3, wi: DVec3) -> DVec3 {
        match *self {
            Bsdf::Diffuse { albedo, n } => albedo * (n.dot(wi).max(0.0) / PI),
            Bsdf::KajiyaKay {
                diffuse,
                specular,
                exponent,
                t,
            } => {
                let (ti, to) = (t.dot(wi), t.dot(wo));
                let (si, so) = (
                    (1.0 - ti * ti).max(0.0).sqrt(),
                    (1.0 - to * to).max(0.0).sqrt(),
                );
                diffuse * (si / (PI * PI)) + specular * (si * so - ti * to).max(0.0).powf(exponent)
            }
            Bsdf::Hair { ref model, frame } => {
                model.eval(Self::to_local(&frame, wo), Self::to_local(&frame, wi))
            }
            Bsdf::Dielectric { .. } => DVec3::ZERO,
        }
    }

    /// The density of [`Bsdf::sample`] choosing `wi` (zero for delta BSDFs).
    pub fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        match *self {
            Bsdf::Diffuse { n, .. } => n.dot(wi).max(0.0) / PI,
            Bsdf::KajiyaKay { .. } => 1.0 / (4.0 * PI),
            Bsdf::Hair { ref model, frame } => {
                model.pdf(Self::to_local(&frame, wo), Self::to_local(&frame, wi))
            }
            Bsdf::Dielectric { .. } => 0.0,
        }
    }

    /// [`Bsdf::eval`] and [`Bsdf::pdf`] at once (the hair model shares its work between them).
    pub fn eval_pdf(&self, wo: DVec3, wi: DVec3) -> (DVec3, f64) {
        match *self {
            Bsdf::Hair { ref model, frame } => {
                model.eval_and_pdf(Self::to_local(&frame, wo), Self::to_local(&frame, wi))
            }
            _ => (self.eval(wo, wi), self.pdf(wo, wi)),
        }
    }

    /// Samples an incoming direction for `wo` from three uniform numbers.
    pub fn sample(&self, wo: DVec3, u: [f64; 3]) -> Option<BsdfSample> {
        match *self {
            Bsdf::Diffuse { albedo, n } => {
                let (x, y) = basis(n);
                let l = cosine_hemisphere([u[0], u[1]]);
                let wi = x * l.x + y * l.y + n * l.z;
                let pdf = l.z / PI;
                (pdf > 0.0).then_some(BsdfSample {
                    wi,
                    weight: albedo,
                    pdf,
                })
            }
            Bsdf::KajiyaKay { .. } => {
                let wi = uniform_sphere([u[0], u[1]]);
                let pdf = 1.0 / (4.0 * PI);
                Some(BsdfSample {
                    wi,
                    weight: self.eval(wo, wi) / pdf,
                    pdf,
                })
            }
            Bsdf::Hair { ref model, frame } => {
                let s = model.sample(Self::to_local(&frame, wo), u)?;
                let wi = frame[0] * s.wi.x + frame[1] * s.wi.y + frame[2] * s.wi.z;
                Some(BsdfSample {
                    wi,
                    weight: s.weight,
                    pdf: s.pdf,
                })
            }
            Bsdf::Dielectric { eta, n } => {
                // Seen from outside (wo on the normal's side) the relative index is eta.
                let (n, eta_rel) = if wo.dot(n) >= 0.0 {
                    (n, eta)
                } else {
                    (-n, 1.0 / eta)
                };
                let f = fresnel_dielectric(wo.dot(n), eta_rel);
                let reflect = 2.0 * wo.dot(n) * n - wo;
                if u[0] < f {
                    return Some(BsdfSample {
                        wi: reflect,
                        weight: DVec3::ONE,
                        pdf: f64::INFINITY,
                    });
                }
                // Radiance crossing into a denser medium is compressed by eta_rel^2.
                refract(wo, n, eta_rel).map(|wi| BsdfSample {
                    wi,
                    weight: DVec3::splat(1.0 / (eta_rel * eta_rel)),
                    pdf: f64::INFINITY,
                })
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::SampleRng;

    #[test]
    fn fresnel_known_values() {
        // Normal incidence: ((eta - 1)/(eta + 1))^2 = 0.04 for eta = 1.5.
        assert!(
            (fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-12,
            "normal"
        );
        assert_eq!(fresnel_dielectric(0.0, 1.5), 1.0, "grazing");
        // From inside glass past the critical angle asin(1/1.5) = 41.8 degrees.
        assert_eq!(
            fresnel_dielectric(0.5, 1.0 / 1.5),
            1.0,
            "total internal reflection"
        );
        assert_eq!(fresnel_dielectric(0.7, 1.0), 0.0, "index matched");
        // Brewster's angle tan(theta) = eta: r_p = 0, F = r_s^2 / 2.
        let theta = 1.5f64.atan();
        let f = fresnel_dielectric(theta.cos(), 1.5);
        let ct = (1.0 - (theta.sin() / 1.5).powi(2)).sqrt();
        let rs = (theta.cos() - 1.5 * ct) / (theta.cos() + 1.5 * ct);
        assert!((f - 0.5 * rs * rs).abs() < 1e-12, "Brewster {f}");
    }

    #[test]
    fn refraction_obeys_snell() {
        let mut rng = SampleRng::from_seed(5);
        for _ in 0..1000 {
            let n = uniform_sphere(rng.uniform2());
            let mut wo = uniform_sphere(rng.uniform2());
            if wo.dot(n) < 0.0 {
                wo = -wo;
            }
            let eta = 1.0 + rng.uniform();
            let wi = refract(wo, n, eta).expect("entering never reflects totally");
            let (si, st) = (wo.cross(n).length(), wi.cross(n).length());
            assert!((si - eta * st).abs() < 1e-9, "Snell: {si} vs {eta} * {st}");
            assert!(wi.dot(n) < 0.0, "crosses the boundary");
            assert!(
                wo.cross(n).dot(wi.cross(n)) <= 1e-12,
                "in the plane of incidence, opposite side"
            );
        }
    }

    #[test]
    fn diffuse_and_kajiya_kay_sampling_agree_with_eval() {
        let mut rng = SampleRng::from_seed(9);
        let at = ShadingPoint {
            normal: DVec3::new(0.3, 0.9, 0.1).normalize(),
            tangent: Some(DVec3::new(1.0, -0.3, 0.0).normalize()),
            section: None,
        };
        let wo = DVec3::new(0.2, 0.5, 0.8).normalize();
        for m in [
            Material::Diffuse {
                albedo: DVec3::splat(0.8),
            },
            Material::KajiyaKay {
                diffuse: DVec3::splat(0.6),
                specular: DVec3::splat(0.2),
                exponent: 20.0,
            },
        ] {
            let b = Bsdf::new(&m, &at, wo);
            let n = 100_000;
            let mut mean = DVec3::ZERO;
            for _ in 0..n {
                let s = b
                    .sample(wo, [rng.uniform(), rng.uniform(), rng.uniform()])
                    .unwrap();
                let want = b.eval(wo, s.wi) / b.pdf(wo, s.wi);
                assert!(
                    (s.weight - want).length() < 1e-9 * want.length().max(1.0),
                    "{m:?}"
                );
                mean += s.weight;
            }
            mean /= n as f64;
            // Diffuse albedo 0.8 exactly; KK's diffuse part alone has albedo 0.6.
            match m {
                Material::Diffuse { .. } => {
                    assert!((mean.x - 0.8).abs() < 0.01, "diffuse albedo {mean}")
                }
                _ => assert!(mean.x > 0.59, "KK albedo {mean} at least k_d"),
            }
        }
    }

    #[test]
    fn dielectric_sampling_splits_by_fresnel() {
        let b = Bsdf::Dielectric {
            eta: 1.5,
            n: DVec3::Z,
        };
        let wo = DVec3::new(0.6, 0.0, 0.8);
        let f = fresnel_dielectric(0.8, 1.5);
        let r = b.sample(wo, [f * 0.99, 0.0, 0.0]).unwrap();
        assert!(
            (r.wi - DVec3::new(-0.6, 0.0, 0.8)).length() < 1e-12,
            "mirror"
        );
        let t = b.sample(wo, [f * 1.01, 0.0, 0.0]).unwrap();
        assert!(t.wi.z < 0.0, "refracted inward");
        assert!((t.weight.x - 1.0 / 2.25).abs() < 1e-12, "radiance scaling");
        // From inside at a steep angle: total internal reflection whatever u is.
        let inside = DVec3::new(0.9, 0.0, -(1.0f64 - 0.81).sqrt());
        let s = b.sample(inside, [0.999, 0.0, 0.0]).unwrap();
        assert!(s.wi.z < 0.0, "reflected back inside");
    }
}
