//! The light tables: `[[light]]` (directional, point, sphere) and `[environment]`.

use std::ops::Range;

use glam::DVec3;
use serde::Deserialize;
use toml::Spanned;

use super::values::*;
use crate::accel::Sphere;
use crate::optics::{Environment, Light};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawLight {
    #[serde(rename = "type")]
    pub(super) kind: Spanned<String>,
    pub(super) direction: Option<Spanned<Array<f64, 3>>>,
    pub(super) irradiance: Option<Spanned<Colour>>,
    pub(super) position: Option<Spanned<Array<f64, 3>>>,
    pub(super) intensity: Option<Spanned<Colour>>,
    pub(super) center: Option<Spanned<Array<f64, 3>>>,
    pub(super) radius: Option<Spanned<f64>>,
    pub(super) radiance: Option<Spanned<Colour>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawEnvironment {
    pub(super) color: Option<Spanned<Colour>>,
    pub(super) top: Option<Spanned<Colour>>,
    pub(super) bottom: Option<Spanned<Colour>>,
    pub(super) up: Option<Spanned<Array<f64, 3>>>,
}

pub(super) fn build_light(l: &RawLight, table: Range<usize>) -> Result<Light, Problem> {
    let kind = l.kind.get_ref().as_str();
    let allowed: &[&str] = match kind {
        "directional" => &["direction", "irradiance"],
        "point" => &["position", "intensity"],
        "sphere" => &["center", "radius", "radiance"],
        other => {
            return Err((
                l.kind.span(),
                format!(
                    "unknown light type `{other}`: expected `directional`, `point` or `sphere` (the environment is its own [environment] table)"
                ),
            ));
        }
    };
    let what = format!("a {kind} light");
    only_keys(
        &[
            ("direction", span_of(&l.direction)),
            ("irradiance", span_of(&l.irradiance)),
            ("position", span_of(&l.position)),
            ("intensity", span_of(&l.intensity)),
            ("center", span_of(&l.center)),
            ("radius", span_of(&l.radius)),
            ("radiance", span_of(&l.radiance)),
        ],
        allowed,
        &what,
    )?;
    Ok(match kind {
        "directional" => Light::Directional {
            direction: direction(
                required(&l.direction, "direction", &what, &table)?,
                "direction",
            )?,
            irradiance: radiance(
                required(&l.irradiance, "irradiance", &what, &table)?,
                "irradiance",
            )?,
        },
        "point" => Light::Point {
            position: vec3(
                required(&l.position, "position", &what, &table)?,
                "position",
            )?,
            intensity: radiance(
                required(&l.intensity, "intensity", &what, &table)?,
                "intensity",
            )?,
        },
        _ => Light::Sphere {
            sphere: Sphere {
                center: vec3(required(&l.center, "center", &what, &table)?, "center")?,
                radius: length(required(&l.radius, "radius", &what, &table)?, "radius")?,
            },
            radiance: radiance(
                required(&l.radiance, "radiance", &what, &table)?,
                "radiance",
            )?,
        },
    })
}

pub(super) fn build_environment(
    e: &RawEnvironment,
    table: Range<usize>,
) -> Result<Environment, Problem> {
    match (&e.color, &e.top, &e.bottom) {
        (Some(c), None, None) => {
            not_for(&e.up, "up", "a constant environment")?;
            Ok(Environment::Constant(radiance(c, "color")?))
        }
        (None, Some(t), Some(b)) => Ok(Environment::Gradient {
            up: match &e.up {
                Some(u) => direction(u, "up")?,
                None => DVec3::Y,
            },
            top: radiance(t, "top")?,
            bottom: radiance(b, "bottom")?,
        }),
        _ => Err((
            table,
            "an environment has either `color` (constant) or `top` and `bottom` (gradient)".into(),
        )),
    }
}
