//! The `[material.NAME]` tables (diffuse, Kajiya-Kay, hair, dielectric) and the built-in
//! materials `fiber` and `surface`; names resolved to indices.

use std::collections::BTreeMap;
use std::ops::Range;
use std::sync::Arc;

use glam::DVec3;
use serde::Deserialize;
use toml::Spanned;

use super::values::*;
use gencyl::{GeneralizedCylinder, Section};

use crate::optics::material::exact::{ExactSection, SectionShape};
use crate::optics::material::hair::{HairMaterial, HairParams};
use crate::optics::material::{Material, SceneMaterial};

/// Name of the built-in material of fibers without a `material` key.
pub const FIBER_MATERIAL: &str = "fiber";
/// Name of the built-in material of spheres and planes without a `material` key.
pub const SURFACE_MATERIAL: &str = "surface";

/// The built-in materials: brown hair (Chiang et al., eumelanin 1.3) and grey diffuse.
pub(super) fn builtin_material(name: &str) -> Option<Material> {
    match name {
        FIBER_MATERIAL => Some(Material::Hair(HairMaterial::new(HairParams::from_melanin(
            1.55,
            1.3,
            0.0,
            0.3,
            0.3,
            2f64.to_radians(),
        )))),
        SURFACE_MATERIAL => Some(Material::Diffuse {
            albedo: DVec3::splat(0.5),
        }),
        _ => None,
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawMaterial {
    #[serde(rename = "type")]
    pub(super) kind: Spanned<String>,
    pub(super) albedo: Option<Spanned<Colour>>,
    pub(super) diffuse: Option<Spanned<Colour>>,
    pub(super) specular: Option<Spanned<Colour>>,
    pub(super) exponent: Option<Spanned<f64>>,
    pub(super) eta: Option<Spanned<f64>>,
    pub(super) sigma_a: Option<Spanned<Colour>>,
    pub(super) melanin: Option<Spanned<f64>>,
    pub(super) pheomelanin: Option<Spanned<f64>>,
    pub(super) color: Option<Spanned<Colour>>,
    pub(super) beta_m: Option<Spanned<f64>>,
    pub(super) beta_n: Option<Spanned<f64>>,
    pub(super) alpha: Option<Spanned<f64>>,
    pub(super) section: Option<Spanned<String>>,
    pub(super) xray_mu: Option<Spanned<Numbers>>,
}

pub(super) fn build_material(
    m: &RawMaterial,
    table: Range<usize>,
) -> Result<(Material, Vec<f64>), Problem> {
    let kind = m.kind.get_ref().as_str();
    let roughness = |k: &Option<Spanned<f64>>, name: &str, default: f64| match k {
        Some(x) => number(x, name, 0.0, 1.0, true),
        None => Ok(default),
    };
    // Which keys each type takes, so that a key of another type is an error, not ignored.
    let allowed: &[&str] = match kind {
        "diffuse" => &["albedo"],
        "kajiya_kay" => &["diffuse", "specular", "exponent"],
        "hair" => &[
            "eta",
            "sigma_a",
            "melanin",
            "pheomelanin",
            "color",
            "beta_m",
            "beta_n",
            "alpha",
            "section",
        ],
        "dielectric" => &["eta", "sigma_a"],
        other => {
            return Err((
                m.kind.span(),
                format!(
                    "unknown material type `{other}`: expected `diffuse`, `kajiya_kay`, `hair` or `dielectric`"
                ),
            ));
        }
    };
    only_keys(
        &[
            ("albedo", span_of(&m.albedo)),
            ("diffuse", span_of(&m.diffuse)),
            ("specular", span_of(&m.specular)),
            ("exponent", span_of(&m.exponent)),
            ("eta", span_of(&m.eta)),
            ("sigma_a", span_of(&m.sigma_a)),
            ("melanin", span_of(&m.melanin)),
            ("pheomelanin", span_of(&m.pheomelanin)),
            ("color", span_of(&m.color)),
            ("beta_m", span_of(&m.beta_m)),
            ("beta_n", span_of(&m.beta_n)),
            ("alpha", span_of(&m.alpha)),
            ("section", span_of(&m.section)),
        ],
        allowed,
        &format!("a {kind} material"),
    )?;
    let opt_colour = |k: &Option<Spanned<Colour>>, name: &str, default: DVec3| match k {
        Some(c) => colour(c, name),
        None => Ok(default),
    };
    let material = match kind {
        "diffuse" => Material::Diffuse {
            albedo: opt_colour(&m.albedo, "albedo", DVec3::splat(0.5))?,
        },
        "kajiya_kay" => Material::KajiyaKay {
            diffuse: opt_colour(&m.diffuse, "diffuse", DVec3::new(0.4, 0.2, 0.1))?,
            specular: opt_colour(&m.specular, "specular", DVec3::splat(0.3))?,
            exponent: match &m.exponent {
                Some(x) => number(x, "exponent", 0.0, f64::INFINITY, false)?,
                None => 40.0,
            },
        },
        "hair" => {
            let eta = match &m.eta {
                Some(x) => number(x, "eta", 1.0, f64::INFINITY, true)?,
                None => 1.55,
            };
            let beta_m = roughness(&m.beta_m, "beta_m", 0.3)?;
            let beta_n = roughness(&m.beta_n, "beta_n", 0.3)?;
            let alpha = match &m.alpha {
                Some(x) => number(x, "alpha", -90.0, 90.0, false)?,
                None => 2.0,
            }
            .to_radians();
            let given = [
                m.sigma_a.as_ref().map(|x| x.span()),
                m.color.as_ref().map(|x| x.span()),
                m.melanin
                    .as_ref()
                    .or(m.pheomelanin.as_ref())
                    .map(|x| x.span()),
            ];
            if given.iter().flatten().count() > 1 {
                return Err((
                    table,
                    "a hair material takes one of `sigma_a`, `color` or `melanin`/`pheomelanin`"
                        .into(),
                ));
            }
            let conc = |k: &Option<Spanned<f64>>, name: &str| match k {
                Some(x) => number(x, name, 0.0, f64::INFINITY, false),
                None => Ok(0.0),
            };
            let params = if let Some(s) = &m.sigma_a {
                HairParams {
                    eta,
                    sigma_a: colour(s, "sigma_a")?,
                    beta_m,
                    beta_n,
                    alpha,
                }
            } else if let Some(c) = &m.color {
                let c = colour(c, "color")?;
                if c.max_element() > 1.0 {
                    return Err((
                        m.color.as_ref().unwrap().span(),
                        "color must be in [0, 1]".into(),
                    ));
                }
                HairParams::from_color(eta, c, beta_m, beta_n, alpha)
            } else if m.melanin.is_some() || m.pheomelanin.is_some() {
                HairParams::from_melanin(
                    eta,
                    conc(&m.melanin, "melanin")?,
                    conc(&m.pheomelanin, "pheomelanin")?,
                    beta_m,
                    beta_n,
                    alpha,
                )
            } else {
                HairParams::from_melanin(eta, 1.3, 0.0, beta_m, beta_n, alpha)
            };
            let hair = HairMaterial::new(params);
            match &m.section {
                None => Material::Hair(hair),
                Some(s) => match s.get_ref().as_str() {
                    "circular" => Material::Hair(hair),
                    "exact" => Material::ExactHair { hair, tables: None },
                    other => {
                        return Err((
                            s.span(),
                            format!("section must be \"circular\" or \"exact\", got {other:?}"),
                        ));
                    }
                },
            }
        }
        _ => Material::Dielectric {
            eta: match &m.eta {
                Some(x) => number(x, "eta", 1.0, f64::INFINITY, false)?,
                None => 1.55,
            },
            sigma_a: opt_colour(&m.sigma_a, "sigma_a", DVec3::ZERO)?,
        },
    };
    material.validate().map_err(|e| (table.clone(), e))?;
    let mu = match &m.xray_mu {
        Some(x) => {
            let values = &x.get_ref().0;
            if values.is_empty() || values.len() > super::ct::MAX_BINS {
                return Err((
                    x.span(),
                    format!(
                        "xray_mu must be a number or 1 to {} numbers (one per spectrum bin), got {}",
                        super::ct::MAX_BINS,
                        values.len()
                    ),
                ));
            }
            for &mu in values {
                check_number(mu, "xray_mu", 0.0, f64::MAX, false).map_err(|e| (x.span(), e))?;
            }
            values.clone()
        }
        None => vec![1.0],
    };
    Ok((material, mu))
}

/// Resolves material names: the scene's `[material.NAME]` tables, then the built-ins not
/// redefined.
pub(super) struct Materials {
    pub(super) list: Vec<SceneMaterial>,
}

impl Materials {
    pub(super) fn new(raw: &BTreeMap<String, Spanned<RawMaterial>>) -> Result<Self, Problem> {
        let mut list = Vec::new();
        for (name, m) in raw {
            let (material, xray_mu) = build_material(m.get_ref(), m.span())
                .map_err(|(s, e)| (s, format!("{e} (material `{name}`)")))?;
            list.push(SceneMaterial {
                name: name.clone(),
                material,
                xray_mu,
            });
        }
        for name in [FIBER_MATERIAL, SURFACE_MATERIAL] {
            if !raw.contains_key(name) {
                list.push(SceneMaterial {
                    name: name.to_string(),
                    material: builtin_material(name).expect("a built-in name"),
                    xray_mu: vec![1.0],
                });
            }
        }
        Ok(Materials { list })
    }

    /// The index of the material named by `key`, or of `default`.
    pub(super) fn index(
        &self,
        key: &Option<Spanned<String>>,
        default: &str,
    ) -> Result<u32, Problem> {
        let name = key.as_ref().map_or(default, |k| k.get_ref().as_str());
        self.list
            .iter()
            .position(|m| m.name == name)
            .map(|i| i as u32)
            .ok_or_else(|| {
                let known: Vec<&str> = self.list.iter().map(|m| m.name.as_str()).collect();
                (
                    key.as_ref().map_or(0..0, |k| k.span()),
                    format!("unknown material `{name}` (defined: {})", known.join(", ")),
                )
            })
    }
}

/// Builds the tables of every `section = "exact"` hair material from the sections of the
/// fibers that use it: one section shape per material (an ellipse of any aspect, or one
/// profile), tables over the range of aspects the fibers reach (at their ends: `B / A` is
/// monotone between). `span` locates a material's table for errors.
pub(super) fn build_exact_tables(
    materials: &mut [SceneMaterial],
    cylinders: &[GeneralizedCylinder],
    cylinder_materials: &[u32],
    span: impl Fn(&str) -> Range<usize>,
) -> Result<(), Problem> {
    for (index, m) in materials.iter_mut().enumerate() {
        let Material::ExactHair {
            hair,
            ref mut tables,
        } = m.material
        else {
            continue;
        };
        let mut shape: Option<SectionShape> = None;
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for (c, _) in cylinders
            .iter()
            .zip(cylinder_materials)
            .filter(|(_, k)| **k as usize == index)
        {
            let this = match c.section() {
                Section::Circle(_) => SectionShape::Ellipse,
                Section::Loop(l) => SectionShape::Profile(
                    l.pieces().iter().flat_map(|p| [p[0], p[1], p[2]]).collect(),
                ),
            };
            if shape.as_ref().is_some_and(|s| *s != this) {
                return Err((
                    span(&m.name),
                    format!(
                        "material `{}` has section = \"exact\" and is used by fibers of different section shapes (an ellipse and a profile, or two profiles): give each shape its own material",
                        m.name
                    ),
                ));
            }
            let sweep = c.sweep();
            for end in 0..2 {
                let (a, b) = (sweep.major[end], sweep.minor[end]);
                let aspect = match this {
                    SectionShape::Ellipse => a.min(b) / a.max(b),
                    SectionShape::Profile(_) => b / a,
                };
                lo = lo.min(aspect);
                hi = hi.max(aspect);
            }
            shape = Some(this);
        }
        if let Some(shape) = shape {
            let built = ExactSection::build(shape, lo, hi, &hair.params)
                .map_err(|e| (span(&m.name), format!("{e} (material `{}`)", m.name)))?;
            *tables = Some(Arc::new(built));
        }
    }
    Ok(())
}
