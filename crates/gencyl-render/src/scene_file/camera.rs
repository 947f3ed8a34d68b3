//! The view and its settings: `[camera]` (perspective or orthographic) and `[render]`.

use std::ops::Range;

use glam::DVec3;
use serde::Deserialize;
use toml::Spanned;

use super::values::*;
use crate::optics::{Camera, Projection};
use crate::settings::{Integrator, RenderTable};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawCamera {
    #[serde(rename = "type")]
    pub(super) kind: Option<Spanned<String>>,
    pub(super) position: Option<Spanned<Array<f64, 3>>>,
    pub(super) look_at: Option<Spanned<Array<f64, 3>>>,
    pub(super) up: Option<Spanned<Array<f64, 3>>>,
    pub(super) fov: Option<Spanned<f64>>,
    pub(super) view_height: Option<Spanned<f64>>,
    pub(super) resolution: Option<Spanned<Array<u32, 2>>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawRender {
    pub(super) integrator: Option<Spanned<String>>,
    pub(super) spp: Option<Spanned<u32>>,
    pub(super) max_depth: Option<Spanned<u32>>,
    pub(super) seed: Option<u64>,
}

pub(super) fn build_camera(c: &RawCamera, table: Range<usize>) -> Result<Camera, Problem> {
    let kind = c
        .kind
        .as_ref()
        .map_or("perspective", |k| k.get_ref().as_str());
    let projection = match kind {
        "perspective" => {
            not_for(&c.view_height, "view_height", "a perspective camera")?;
            Projection::Perspective {
                fov: match &c.fov {
                    Some(f) => number(f, "fov", 0.0, 179.0, true)?,
                    None => 40.0,
                },
            }
        }
        "orthographic" => {
            not_for(&c.fov, "fov", "an orthographic camera")?;
            Projection::Orthographic {
                height: number(
                    required(
                        &c.view_height,
                        "view_height",
                        "an orthographic camera",
                        &table,
                    )?,
                    "view_height",
                    0.0,
                    f64::INFINITY,
                    true,
                )?,
            }
        }
        other => {
            return Err((
                c.kind.as_ref().map_or(table.clone(), |k| k.span()),
                format!("unknown camera type `{other}`: expected `perspective` or `orthographic`"),
            ));
        }
    };
    let [width, height] = match &c.resolution {
        Some(r) => {
            let [w, h] = val(r);
            if !(1..=65536).contains(&w) || !(1..=65536).contains(&h) {
                return Err((
                    r.span(),
                    format!("resolution must be 1 to 65536 pixels each way, got {w}x{h}"),
                ));
            }
            [w, h]
        }
        None => [640, 480],
    };
    let camera = Camera {
        position: vec3(
            required(&c.position, "position", "a camera", &table)?,
            "position",
        )?,
        look_at: vec3(
            required(&c.look_at, "look_at", "a camera", &table)?,
            "look_at",
        )?,
        up: match &c.up {
            Some(u) => direction(u, "up")?,
            None => DVec3::Y,
        },
        projection,
        width,
        height,
    };
    camera.validate().map_err(|e| (table, e))?;
    Ok(camera)
}

pub(super) fn build_render(r: &RawRender) -> Result<RenderTable, Problem> {
    let integrator = match &r.integrator {
        Some(i) => Some(
            i.get_ref()
                .parse::<Integrator>()
                .map_err(|e| (i.span(), e))?,
        ),
        None => None,
    };
    let positive = |k: &Option<Spanned<u32>>, name: &str| match k {
        Some(x) if *x.get_ref() == 0 => Err((x.span(), format!("{name} must be at least 1"))),
        Some(x) => Ok(Some(*x.get_ref())),
        None => Ok(None),
    };
    Ok(RenderTable {
        integrator,
        spp: positive(&r.spp, "spp")?,
        max_depth: positive(&r.max_depth, "max_depth")?,
        seed: r.seed,
    })
}
