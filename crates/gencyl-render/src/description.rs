//! Scene files (TOML): what a scene holds, validated, with every cylinder built.
//!
//! # Format
//!
//! A scene file is TOML. Geometry:
//!
//! - `[[cylinder]]`: one generalized cylinder (interface.md section 2, unchanged);
//! - `[[strand]]`: a fiber through `points` (or on B-spline `control_points`), made of
//!   C2-continuous cubic Bezier segments, capped at root and tip only;
//! - `[[hair]]`: a hair model file (Cem Yuksel's `.hair`), every strand as above;
//! - `[[sphere]]` and `[[plane]]`: a scalp, a floor.
//!
//! Cylinders are numbered in file order, `[[cylinder]]` tables first, then the segments of each
//! `[[strand]]`, then those of each `[[hair]]` file: that number is the `object` of a hit.
//! Appearance: `[camera]`, `[[light]]`, `[environment]`, `[material.NAME]` and `[render]`.
//! The README lists every key; a short scene:
//!
//! ```
//! use gencyl_render::scene::SceneDescription;
//!
//! let src = r#"
//! [camera]
//! position = [0, 1, 4]
//! look_at = [0, 0.5, 0]
//! fov = 35
//!
//! [material.brown]
//! type = "hair"
//! melanin = 1.3
//!
//! [[strand]]
//! points = [[0, 0, 0], [0.1, 0.5, 0], [0, 1, 0.1]]
//! radius = [0.02, 0.01]
//! ellipticity = 0.7
//! twist = [0, 6.28]
//! material = "brown"
//!
//! [[cylinder]]
//! bezier = [[0.0, 0.0, 0.0], [0.0, 0.3, 0.0], [0.2, 0.6, 0.0], [0.2, 1.0, 0.1]]
//! major_radius = [0.05, 0.03]    # [A0, A1]
//! minor_radius = [0.03, 0.02]    # [B0, B1]
//! rotation = [0.0, 3.14159]
//!
//! [[light]]
//! type = "sphere"
//! center = [2, 4, 3]
//! radius = 0.5
//! radiance = 20
//! "#;
//! let scene = SceneDescription::parse(src, "hair.toml").unwrap();
//! assert_eq!(scene.cylinders.len(), 3, "one cylinder, then two strand segments");
//!
//! let err = SceneDescription::parse("[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.0, 0.03]\n", "s.toml")
//!     .unwrap_err();
//! assert_eq!(err.to_string(), "s.toml:3:16: major_radius must be positive at both ends, got [0.0, 0.03] (cylinder 0)");
//! ```

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::{Path, PathBuf};

use gencyl::section::ProfileError;
use gencyl::{BezierLoop, FiberSpec, GeneralizedCylinder, GeometryError, Section, Strand};
use glam::{DQuat, DVec2, DVec3};
use rayon::prelude::*;
use serde::Deserialize;
use toml::Spanned;

use crate::camera::{Camera, Projection};
use crate::error::Diagnostic;
use crate::hair::parse_hair;
use crate::integrator::Integrator;
use crate::light::{Environment, Light};
use crate::material::hair::HairParams;
use crate::material::{Material, SceneMaterial};
use crate::shapes::{Plane, Sphere};

/// Why a scene file could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read.
    #[error("{path}: cannot read: {error}")]
    Read {
        /// The file's name as given.
        path: String,
        /// Why.
        error: std::io::Error,
    },
    /// The file is not a valid scene: a syntax error, a wrong key or value, a degenerate
    /// cylinder, a hair file that cannot be read.
    #[error("{0}")]
    Invalid(Box<Diagnostic>),
}

impl SceneError {
    /// The diagnostic, for an error located in the file.
    pub fn diagnostic(&self) -> Option<&Diagnostic> {
        match self {
            SceneError::Invalid(d) => Some(d),
            SceneError::Read { .. } => None,
        }
    }
}

/// Render settings a scene may give (`[render]`); the command line overrides them.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RenderTable {
    /// `integrator`.
    pub integrator: Option<Integrator>,
    /// `spp`: samples per pixel.
    pub spp: Option<u32>,
    /// `max_depth`: most scattering events on a path.
    pub max_depth: Option<u32>,
    /// `seed` of the per-pixel sample streams.
    pub seed: Option<u64>,
}

/// The contents of a scene file, validated, with every cylinder built.
#[derive(Clone, Debug, Default)]
pub struct SceneDescription {
    /// The cylinders in order: index = `object` number.
    pub cylinders: Vec<GeneralizedCylinder>,
    /// Each cylinder's material, an index into `materials`.
    pub cylinder_materials: Vec<u32>,
    /// Spheres with their material index.
    pub spheres: Vec<(Sphere, u32)>,
    /// Planes with their material index.
    pub planes: Vec<(Plane, u32)>,
    /// Materials: the scene's, then the built-in `fiber` and `surface` unless redefined.
    pub materials: Vec<SceneMaterial>,
    /// Light sources.
    pub lights: Vec<Light>,
    /// The environment, if the scene has one.
    pub environment: Option<Environment>,
    /// The camera, if the scene has one (otherwise the renderer frames the scene).
    pub camera: Option<Camera>,
    /// `[render]` settings.
    pub render: RenderTable,
}

/// Name of the built-in material of fibers without a `material` key.
pub const FIBER_MATERIAL: &str = "fiber";
/// Name of the built-in material of spheres and planes without a `material` key.
pub const SURFACE_MATERIAL: &str = "surface";

/// The built-in materials: brown hair (Chiang et al., eumelanin 1.3) and grey diffuse.
fn builtin_material(name: &str) -> Option<Material> {
    match name {
        FIBER_MATERIAL => Some(Material::Hair(HairParams::from_melanin(
            1.55,
            1.3,
            0.0,
            0.3,
            0.3,
            2f64.to_radians(),
        ))),
        SURFACE_MATERIAL => Some(Material::Diffuse {
            albedo: DVec3::splat(0.5),
        }),
        _ => None,
    }
}

// The file's shape, as serde reads it. `Spanned` keeps each value's place for the validation
// errors that come after parsing.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScene {
    #[serde(default)]
    cylinder: Vec<Spanned<RawCylinder>>,
    #[serde(default)]
    strand: Vec<Spanned<RawStrand>>,
    #[serde(default)]
    hair: Vec<Spanned<RawHair>>,
    #[serde(default)]
    sphere: Vec<Spanned<RawSphere>>,
    #[serde(default)]
    plane: Vec<Spanned<RawPlane>>,
    #[serde(default)]
    light: Vec<Spanned<RawLight>>,
    environment: Option<Spanned<RawEnvironment>>,
    #[serde(default)]
    material: BTreeMap<String, Spanned<RawMaterial>>,
    camera: Option<Spanned<RawCamera>>,
    render: Option<Spanned<RawRender>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCylinder {
    bezier: Spanned<Array<Array<f64, 3>, 4>>,
    major_radius: Spanned<Array<f64, 2>>,
    minor_radius: Option<Spanned<Array<f64, 2>>>,
    rotation: Option<Spanned<Array<f64, 2>>>,
    caps: Option<bool>,
    normal_hint: Option<Spanned<Array<f64, 3>>>,
    profile: Option<Spanned<Vec<Array<f64, 2>>>>,
    material: Option<Spanned<String>>,
    transform: Option<Spanned<RawTransform>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawStrand {
    points: Option<Spanned<Vec<Array<f64, 3>>>>,
    control_points: Option<Spanned<Vec<Array<f64, 3>>>>,
    radius: Spanned<Array<f64, 2>>,
    ellipticity: Option<Spanned<f64>>,
    twist: Option<Spanned<Array<f64, 2>>>,
    profile: Option<Spanned<Vec<Array<f64, 2>>>>,
    material: Option<Spanned<String>>,
    transform: Option<Spanned<RawTransform>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawHair {
    file: Spanned<String>,
    radius: Option<Spanned<f64>>,
    ellipticity: Option<Spanned<f64>>,
    twist: Option<Spanned<Array<f64, 2>>>,
    material: Option<Spanned<String>>,
    transform: Option<Spanned<RawTransform>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSphere {
    center: Spanned<Array<f64, 3>>,
    radius: Spanned<f64>,
    material: Option<Spanned<String>>,
    transform: Option<Spanned<RawTransform>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPlane {
    point: Spanned<Array<f64, 3>>,
    normal: Spanned<Array<f64, 3>>,
    material: Option<Spanned<String>>,
    transform: Option<Spanned<RawTransform>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTransform {
    scale: Option<Spanned<f64>>,
    rotate: Option<Spanned<Array<f64, 4>>>,
    translate: Option<Spanned<Array<f64, 3>>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLight {
    #[serde(rename = "type")]
    kind: Spanned<String>,
    direction: Option<Spanned<Array<f64, 3>>>,
    irradiance: Option<Spanned<Colour>>,
    position: Option<Spanned<Array<f64, 3>>>,
    intensity: Option<Spanned<Colour>>,
    center: Option<Spanned<Array<f64, 3>>>,
    radius: Option<Spanned<f64>>,
    radiance: Option<Spanned<Colour>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawEnvironment {
    color: Option<Spanned<Colour>>,
    top: Option<Spanned<Colour>>,
    bottom: Option<Spanned<Colour>>,
    up: Option<Spanned<Array<f64, 3>>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMaterial {
    #[serde(rename = "type")]
    kind: Spanned<String>,
    albedo: Option<Spanned<Colour>>,
    diffuse: Option<Spanned<Colour>>,
    specular: Option<Spanned<Colour>>,
    exponent: Option<Spanned<f64>>,
    eta: Option<Spanned<f64>>,
    sigma_a: Option<Spanned<Colour>>,
    melanin: Option<Spanned<f64>>,
    pheomelanin: Option<Spanned<f64>>,
    color: Option<Spanned<Colour>>,
    beta_m: Option<Spanned<f64>>,
    beta_n: Option<Spanned<f64>>,
    alpha: Option<Spanned<f64>>,
    xray_mu: Option<Spanned<f64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCamera {
    #[serde(rename = "type")]
    kind: Option<Spanned<String>>,
    position: Spanned<Array<f64, 3>>,
    look_at: Spanned<Array<f64, 3>>,
    up: Option<Spanned<Array<f64, 3>>>,
    fov: Option<Spanned<f64>>,
    view_height: Option<Spanned<f64>>,
    resolution: Option<Spanned<Array<u32, 2>>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRender {
    integrator: Option<Spanned<String>>,
    spp: Option<Spanned<u32>>,
    max_depth: Option<Spanned<u32>>,
    seed: Option<u64>,
}

/// A TOML array of exactly `N` values. (serde's `[T; N]` lets the toml deserializer drop
/// extra elements silently.)
#[derive(Clone, Copy, Debug, PartialEq)]
struct Array<T, const N: usize>([T; N]);

impl<'de, T: Deserialize<'de>, const N: usize> Deserialize<'de> for Array<T, N> {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V<T, const N: usize>(std::marker::PhantomData<T>);
        impl<'de, T: Deserialize<'de>, const N: usize> serde::de::Visitor<'de> for V<T, N> {
            type Value = Array<T, N>;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                write!(f, "an array of {N} elements")
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut seq: A,
            ) -> Result<Self::Value, A::Error> {
                let mut v = Vec::with_capacity(N);
                while let Some(x) = seq.next_element()? {
                    v.push(x);
                }
                let n = v.len();
                v.try_into()
                    .map(Array)
                    .map_err(|_| serde::de::Error::invalid_length(n, &self))
            }
        }
        d.deserialize_seq(V(std::marker::PhantomData))
    }
}

/// An RGB colour: `[r, g, b]`, or one number for grey.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Colour(DVec3);

impl<'de> Deserialize<'de> for Colour {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = Colour;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                write!(f, "a number or an array [r, g, b]")
            }
            fn visit_f64<E>(self, x: f64) -> Result<Colour, E> {
                Ok(Colour(DVec3::splat(x)))
            }
            fn visit_i64<E>(self, x: i64) -> Result<Colour, E> {
                Ok(Colour(DVec3::splat(x as f64)))
            }
            fn visit_u64<E>(self, x: u64) -> Result<Colour, E> {
                Ok(Colour(DVec3::splat(x as f64)))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(self, seq: A) -> Result<Colour, A::Error> {
                let a: Array<f64, 3> =
                    Deserialize::deserialize(serde::de::value::SeqAccessDeserializer::new(seq))?;
                Ok(Colour(DVec3::from_array(a.0)))
            }
        }
        d.deserialize_any(V)
    }
}

/// The value of a spanned array.
fn val<T: Copy, const N: usize>(s: &Spanned<Array<T, N>>) -> [T; N] {
    s.get_ref().0
}

/// A validation failure: where (bytes of the source) and what.
type Problem = (Range<usize>, String);

/// A finite 3-vector.
fn vec3(s: &Spanned<Array<f64, 3>>, what: &str) -> Result<DVec3, Problem> {
    let v = DVec3::from_array(val(s));
    if v.is_finite() {
        Ok(v)
    } else {
        Err((s.span(), format!("{what} must be finite, got {:?}", val(s))))
    }
}

/// A finite non-zero 3-vector, normalized.
fn direction(s: &Spanned<Array<f64, 3>>, what: &str) -> Result<DVec3, Problem> {
    let v = vec3(s, what)?;
    if v.length_squared() > 0.0 {
        Ok(v.normalize())
    } else {
        Err((s.span(), format!("{what} must not be zero")))
    }
}

/// A finite number in `[lo, hi]` (`open`: excluding `lo`).
fn number(s: &Spanned<f64>, what: &str, lo: f64, hi: f64, open: bool) -> Result<f64, Problem> {
    let x = *s.get_ref();
    let ok = x.is_finite() && x <= hi && if open { x > lo } else { x >= lo };
    if ok {
        return Ok(x);
    }
    let range = match (open, hi.is_finite()) {
        (true, false) if lo == 0.0 => "positive and finite".to_string(),
        (false, false) if lo == 0.0 => "non-negative and finite".to_string(),
        (true, _) => format!("in ({lo}, {hi}]"),
        (false, _) => format!("in [{lo}, {hi}]"),
    };
    Err((s.span(), format!("{what} must be {range}, got {x}")))
}

/// A finite non-negative colour.
fn colour(s: &Spanned<Colour>, what: &str) -> Result<DVec3, Problem> {
    let c = s.get_ref().0;
    if c.is_finite() && c.min_element() >= 0.0 {
        Ok(c)
    } else {
        Err((
            s.span(),
            format!(
                "{what} must be finite and non-negative, got {:?}",
                c.to_array()
            ),
        ))
    }
}

/// `key` must be absent for `kind` (a light or material type).
fn not_for<T>(key: &Option<Spanned<T>>, name: &str, kind: &str) -> Result<(), Problem> {
    match key {
        Some(k) => Err((k.span(), format!("`{name}` does not apply to {kind}"))),
        None => Ok(()),
    }
}

/// A required key.
fn required<'a, T>(
    key: &'a Option<Spanned<T>>,
    name: &str,
    kind: &str,
    table: &Range<usize>,
) -> Result<&'a Spanned<T>, Problem> {
    key.as_ref()
        .ok_or_else(|| (table.clone(), format!("{kind} needs `{name}`")))
}

/// A similarity transform `p -> R (s p) + t`: uniform scale, then rotation, then translation.
/// (A fiber under a non-uniform scale would no longer be a swept scaled section, so the format
/// has none.)
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Similarity {
    /// Uniform scale, positive.
    pub scale: f64,
    /// Rotation.
    pub rotation: DQuat,
    /// Translation.
    pub translation: DVec3,
}

impl Default for Similarity {
    fn default() -> Self {
        Similarity {
            scale: 1.0,
            rotation: DQuat::IDENTITY,
            translation: DVec3::ZERO,
        }
    }
}

impl Similarity {
    /// The image of a point.
    pub fn point(&self, p: DVec3) -> DVec3 {
        self.rotation * (self.scale * p) + self.translation
    }

    /// The image of a direction (not scaled).
    pub fn direction(&self, v: DVec3) -> DVec3 {
        self.rotation * v
    }
}

/// `transform = { scale = s, rotate = [ax, ay, az, degrees], translate = [x, y, z] }`.
fn transform(t: &Option<Spanned<RawTransform>>) -> Result<Similarity, Problem> {
    let Some(t) = t else {
        return Ok(Similarity::default());
    };
    let t = t.get_ref();
    let mut out = Similarity::default();
    if let Some(s) = &t.scale {
        out.scale = number(s, "transform scale", 0.0, f64::INFINITY, true)?;
    }
    if let Some(r) = &t.rotate {
        let [x, y, z, deg] = val(r);
        let axis = DVec3::new(x, y, z);
        if !(axis.is_finite() && deg.is_finite() && axis.length_squared() > 0.0) {
            return Err((
                r.span(),
                format!(
                    "transform rotate must be [axis x, y, z, degrees], finite, with a non-zero axis, got {:?}",
                    val(r)
                ),
            ));
        }
        out.rotation = DQuat::from_axis_angle(axis.normalize(), deg.to_radians());
    }
    if let Some(tr) = &t.translate {
        out.translation = vec3(tr, "transform translate")?;
    }
    Ok(out)
}

/// A profile (`profile` key) as a section.
fn section(p: &Option<Spanned<Vec<Array<f64, 2>>>>) -> Result<Section, Problem> {
    let Some(p) = p else {
        return Ok(Section::default());
    };
    let pts: Vec<DVec2> = p.get_ref().iter().map(|q| DVec2::from_array(q.0)).collect();
    let lp = BezierLoop::new(&pts).map_err(|e| {
        let why = match e {
            ProfileError::NotFinite(i) => {
                format!("profile point {i} is not finite: {:?}", p.get_ref()[i].0)
            }
            e => format!("bad profile: {e}"),
        };
        (p.span(), why)
    })?;
    Ok(Section::Loop(lp))
}

/// Checks one `[[cylinder]]` table and builds its cylinder.
fn build_cylinder(c: &RawCylinder, table: Range<usize>) -> Result<GeneralizedCylinder, Problem> {
    let bezier = val(&c.bezier).map(|p| p.0);
    if let Some(i) = bezier.iter().position(|p| !p.iter().all(|x| x.is_finite())) {
        return Err((
            c.bezier.span(),
            format!("bezier control point {i} is not finite: {:?}", bezier[i]),
        ));
    }
    let radius = |name: &str, r: &Spanned<Array<f64, 2>>| -> Result<[f64; 2], Problem> {
        let v = val(r);
        if !v.iter().all(|x| x.is_finite()) {
            return Err((r.span(), format!("{name} must be finite, got {v:?}")));
        }
        if !v.iter().all(|&x| x > 0.0) {
            return Err((
                r.span(),
                format!("{name} must be positive at both ends, got {v:?}"),
            ));
        }
        Ok(v)
    };
    let major = radius("major_radius", &c.major_radius)?;
    let minor = c
        .minor_radius
        .as_ref()
        .map_or(Ok(major), |r| radius("minor_radius", r))?;
    let rotation = match &c.rotation {
        Some(r) if !val(r).iter().all(|x| x.is_finite()) => {
            return Err((
                r.span(),
                format!("rotation must be finite, got {:?}", val(r)),
            ));
        }
        Some(r) => val(r),
        None => [0.0, 0.0],
    };
    let normal_hint = match &c.normal_hint {
        Some(h) => {
            let v = DVec3::from_array(val(h));
            if !v.is_finite() || v == DVec3::ZERO {
                return Err((
                    h.span(),
                    format!(
                        "normal_hint must be a finite non-zero vector, got {:?}",
                        val(h)
                    ),
                ));
            }
            Some(v)
        }
        None => None,
    };
    let xf = transform(&c.transform)?;
    let spec = FiberSpec {
        bezier: bezier.map(|p| xf.point(DVec3::from_array(p))),
        major_radius: major.map(|r| r * xf.scale),
        minor_radius: minor.map(|r| r * xf.scale),
        rotation,
        caps: c.caps.unwrap_or(true),
        normal_hint: normal_hint.map(|h| xf.direction(h)),
        section: section(&c.profile)?,
    };
    spec.build().map_err(|e| {
        let span = match (&e, &c.normal_hint) {
            (GeometryError::BadNormalHint, Some(h)) => h.span(),
            (GeometryError::Sweep(_), _) => table,
            _ => c.bezier.span(),
        };
        (span, e.to_string())
    })
}

/// Ellipticity (minor / major radius) and twist keys shared by strands and hair files.
fn strand_shape(
    ellipticity: &Option<Spanned<f64>>,
    twist: &Option<Spanned<Array<f64, 2>>>,
) -> Result<(f64, [f64; 2]), Problem> {
    let e = match ellipticity {
        Some(e) => number(e, "ellipticity", 0.0, 1.0, true)?,
        None => 1.0,
    };
    let tw = match twist {
        Some(t) if !val(t).iter().all(|x| x.is_finite()) => {
            return Err((t.span(), format!("twist must be finite, got {:?}", val(t))));
        }
        Some(t) => val(t),
        None => [0.0, 0.0],
    };
    Ok((e, tw))
}

/// Checks one `[[strand]]` table and builds its segments.
fn build_strand(s: &RawStrand, table: Range<usize>) -> Result<Vec<GeneralizedCylinder>, Problem> {
    let (pts, through) = match (&s.points, &s.control_points) {
        (Some(p), None) => (p, true),
        (None, Some(c)) => (c, false),
        (Some(_), Some(c)) => {
            return Err((
                c.span(),
                "give either `points` or `control_points`, not both".into(),
            ));
        }
        (None, None) => {
            return Err((table, "a strand needs `points` or `control_points`".into()));
        }
    };
    let xf = transform(&s.transform)?;
    let mut points = Vec::with_capacity(pts.get_ref().len());
    for (i, p) in pts.get_ref().iter().enumerate() {
        let v = DVec3::from_array(p.0);
        if !v.is_finite() {
            return Err((pts.span(), format!("point {i} is not finite: {:?}", p.0)));
        }
        if points.last() == Some(&xf.point(v)) {
            return Err((pts.span(), format!("point {i} repeats point {}", i - 1)));
        }
        points.push(xf.point(v));
    }
    if points.len() < 2 {
        return Err((pts.span(), "a strand needs at least 2 points".into()));
    }
    let r = val(&s.radius);
    if !r.iter().all(|x| x.is_finite() && *x > 0.0) {
        return Err((
            s.radius.span(),
            format!("radius must be positive and finite at root and tip, got {r:?}"),
        ));
    }
    let (ellipticity, twist) = strand_shape(&s.ellipticity, &s.twist)?;
    let strand = Strand {
        points: if through {
            Strand::interpolating_control_points(&points)
        } else {
            points
        },
        radius: r.map(|x| x * xf.scale),
        ellipticity,
        twist,
        section: section(&s.profile)?,
    };
    strand
        .cylinders()
        .map_err(|(seg, e)| (pts.span(), format!("segment {seg}: {e}")))
}

/// Reads one `[[hair]]` file (relative to the scene's folder) and builds its strands.
fn build_hair(h: &RawHair, base: &Path) -> Result<Vec<GeneralizedCylinder>, Problem> {
    let file = h.file.get_ref();
    let radius = match &h.radius {
        Some(r) => Some(number(r, "radius", 0.0, f64::INFINITY, true)?),
        None => None,
    };
    let (ellipticity, twist) = strand_shape(&h.ellipticity, &h.twist)?;
    let xf = transform(&h.transform)?;
    hair_cylinders(&base.join(file), file, radius, ellipticity, twist, xf)
        .map_err(|e| (h.file.span(), e))
}

/// The cylinders of a hair file's strands (through the file's points), radius from the
/// file's thickness unless given; the error names the file and the strand.
fn hair_cylinders(
    path: &Path,
    file: &str,
    radius: Option<f64>,
    ellipticity: f64,
    twist: [f64; 2],
    xf: Similarity,
) -> Result<Vec<GeneralizedCylinder>, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("cannot read {file}: {e}"))?;
    let hair = parse_hair(&bytes, file).map_err(|e| e.to_string())?;
    let built: Vec<_> = hair
        .to_strands(radius)
        .into_par_iter()
        .enumerate()
        .map(|(i, mut s)| {
            for p in &mut s.points {
                *p = xf.point(*p);
            }
            s.points = Strand::interpolating_control_points(&s.points);
            s.radius = s.radius.map(|r| r * xf.scale);
            s.ellipticity = ellipticity;
            s.twist = twist;
            s.cylinders()
                .map_err(|(seg, e)| format!("{file}: strand {i}, segment {seg}: {e}"))
        })
        .collect();
    let mut out = Vec::new();
    for b in built {
        out.extend(b?);
    }
    Ok(out)
}

impl SceneDescription {
    /// A scene of one hair file's strands in the built-in `fiber` material, with no camera
    /// or lights (the renderer frames and lights it). `radius` overrides the file's thickness.
    pub fn from_hair_file(path: &Path, radius: Option<f64>) -> Result<Self, String> {
        let name = path.display().to_string();
        if let Some(r) = radius
            && !(r.is_finite() && r > 0.0)
        {
            return Err(format!("the radius must be positive and finite, got {r}"));
        }
        let cylinders =
            hair_cylinders(path, &name, radius, 1.0, [0.0, 0.0], Similarity::default())?;
        let materials = Materials::new(&BTreeMap::new()).map_err(|(_, e)| e)?;
        let fiber = materials.index(&None, FIBER_MATERIAL).map_err(|(_, e)| e)?;
        Ok(SceneDescription {
            cylinder_materials: vec![fiber; cylinders.len()],
            cylinders,
            materials: materials.list,
            ..Default::default()
        })
    }
}

fn build_light(l: &RawLight, table: Range<usize>) -> Result<Light, Problem> {
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
            irradiance: colour(
                required(&l.irradiance, "irradiance", &what, &table)?,
                "irradiance",
            )?,
        },
        "point" => Light::Point {
            position: vec3(
                required(&l.position, "position", &what, &table)?,
                "position",
            )?,
            intensity: colour(
                required(&l.intensity, "intensity", &what, &table)?,
                "intensity",
            )?,
        },
        _ => Light::Sphere {
            sphere: Sphere {
                center: vec3(required(&l.center, "center", &what, &table)?, "center")?,
                radius: number(
                    required(&l.radius, "radius", &what, &table)?,
                    "radius",
                    0.0,
                    f64::INFINITY,
                    true,
                )?,
            },
            radiance: colour(
                required(&l.radiance, "radiance", &what, &table)?,
                "radiance",
            )?,
        },
    })
}

/// Where a key's value is, if it is there.
fn span_of<T>(k: &Option<Spanned<T>>) -> Option<Range<usize>> {
    k.as_ref().map(Spanned::span)
}

/// Every key present must be one `kind` takes: `keys` pairs names with where their values are.
fn only_keys(
    keys: &[(&str, Option<Range<usize>>)],
    allowed: &[&str],
    kind: &str,
) -> Result<(), Problem> {
    for (name, span) in keys {
        if let Some(span) = span
            && !allowed.contains(name)
        {
            return Err((span.clone(), format!("`{name}` does not apply to {kind}")));
        }
    }
    Ok(())
}

fn build_environment(e: &RawEnvironment, table: Range<usize>) -> Result<Environment, Problem> {
    match (&e.color, &e.top, &e.bottom) {
        (Some(c), None, None) => {
            not_for(&e.up, "up", "a constant environment")?;
            Ok(Environment::Constant(colour(c, "color")?))
        }
        (None, Some(t), Some(b)) => Ok(Environment::Gradient {
            up: match &e.up {
                Some(u) => direction(u, "up")?,
                None => DVec3::Y,
            },
            top: colour(t, "top")?,
            bottom: colour(b, "bottom")?,
        }),
        _ => Err((
            table,
            "an environment has either `color` (constant) or `top` and `bottom` (gradient)".into(),
        )),
    }
}

fn build_material(m: &RawMaterial, table: Range<usize>) -> Result<(Material, f64), Problem> {
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
            Material::Hair(params)
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
        Some(x) => number(x, "xray_mu", 0.0, f64::INFINITY, false)?,
        None => 1.0,
    };
    Ok((material, mu))
}

fn build_camera(c: &RawCamera, table: Range<usize>) -> Result<Camera, Problem> {
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
        position: vec3(&c.position, "position")?,
        look_at: vec3(&c.look_at, "look_at")?,
        up: match &c.up {
            Some(u) => vec3(u, "up")?,
            None => DVec3::Y,
        },
        projection,
        width,
        height,
    };
    camera.validate().map_err(|e| (table, e))?;
    Ok(camera)
}

fn build_render(r: &RawRender) -> Result<RenderTable, Problem> {
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

impl SceneDescription {
    /// Reads and parses the scene file at `path`; hair files are found relative to its folder.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, SceneError> {
        let path = path.as_ref();
        let name = path.display().to_string();
        let bytes = std::fs::read(path).map_err(|error| SceneError::Read {
            path: name.clone(),
            error,
        })?;
        let base = path.parent().map_or_else(PathBuf::new, Path::to_path_buf);
        Self::parse_bytes_in(&bytes, &name, &base)
    }

    /// Parses scene file bytes; `name` is the file's name for messages. Bytes that are not
    /// UTF-8 are reported at the first bad byte. Hair files are found relative to the current
    /// folder.
    pub fn parse_bytes(bytes: &[u8], name: &str) -> Result<Self, SceneError> {
        Self::parse_bytes_in(bytes, name, Path::new(""))
    }

    fn parse_bytes_in(bytes: &[u8], name: &str, base: &Path) -> Result<Self, SceneError> {
        match std::str::from_utf8(bytes) {
            Ok(src) => Self::parse_in(src, name, base),
            Err(e) => {
                let good = &bytes[..e.valid_up_to()];
                // Safe: valid_up_to marks the end of the valid prefix.
                let src = std::str::from_utf8(good).unwrap_or_default();
                let at = src.len();
                Err(invalid(
                    name,
                    src,
                    at..at,
                    "the file is not valid UTF-8 text".to_string(),
                ))
            }
        }
    }

    /// Parses scene source text; `name` is the file's name for messages. Hair files are found
    /// relative to the current folder.
    pub fn parse(src: &str, name: &str) -> Result<Self, SceneError> {
        Self::parse_in(src, name, Path::new(""))
    }

    /// Parses scene source text whose hair files are relative to `base`.
    pub fn parse_in(src: &str, name: &str, base: &Path) -> Result<Self, SceneError> {
        let raw: RawScene = toml::from_str(src).map_err(|e| {
            let span = e.span().unwrap_or(0..0);
            invalid(name, src, span, e.message().trim().to_string())
        })?;
        build(&raw, base).map_err(|(span, msg)| invalid(name, src, span, msg))
    }
}

fn invalid(name: &str, src: &str, span: Range<usize>, message: String) -> SceneError {
    SceneError::Invalid(Box::new(Diagnostic::new(name, src, span, message)))
}

/// Resolves material names: the scene's `[material.NAME]` tables, then the built-ins not
/// redefined.
struct Materials {
    list: Vec<SceneMaterial>,
}

impl Materials {
    fn new(raw: &BTreeMap<String, Spanned<RawMaterial>>) -> Result<Self, Problem> {
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
                    xray_mu: 1.0,
                });
            }
        }
        Ok(Materials { list })
    }

    /// The index of the material named by `key`, or of `default`.
    fn index(&self, key: &Option<Spanned<String>>, default: &str) -> Result<u32, Problem> {
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

/// Validates everything and builds the cylinders (in parallel; the first problem in file
/// order is reported).
fn build(raw: &RawScene, base: &Path) -> Result<SceneDescription, Problem> {
    let materials = Materials::new(&raw.material)?;
    let mut out = SceneDescription::default();

    let built: Vec<Result<GeneralizedCylinder, Problem>> = raw
        .cylinder
        .par_iter()
        .map(|c| build_cylinder(c.get_ref(), c.span()))
        .collect();
    for (i, (b, c)) in built.into_iter().zip(&raw.cylinder).enumerate() {
        let cyl = b.map_err(|(span, msg)| (span, format!("{msg} (cylinder {i})")))?;
        out.cylinders.push(cyl);
        out.cylinder_materials
            .push(materials.index(&c.get_ref().material, FIBER_MATERIAL)?);
    }
    let built: Vec<Result<Vec<GeneralizedCylinder>, Problem>> = raw
        .strand
        .par_iter()
        .map(|s| build_strand(s.get_ref(), s.span()))
        .collect();
    for (i, (b, s)) in built.into_iter().zip(&raw.strand).enumerate() {
        let cyls = b.map_err(|(span, msg)| (span, format!("{msg} (strand {i})")))?;
        let m = materials.index(&s.get_ref().material, FIBER_MATERIAL)?;
        out.cylinder_materials
            .extend(std::iter::repeat_n(m, cyls.len()));
        out.cylinders.extend(cyls);
    }
    for h in &raw.hair {
        let cyls = build_hair(h.get_ref(), base)?;
        let m = materials.index(&h.get_ref().material, FIBER_MATERIAL)?;
        out.cylinder_materials
            .extend(std::iter::repeat_n(m, cyls.len()));
        out.cylinders.extend(cyls);
    }
    if out.cylinders.len() > crate::scene::Scene::MAX_CYLINDERS {
        return Err((
            0..0,
            format!(
                "{} cylinders: more than the {} a scene holds",
                out.cylinders.len(),
                crate::scene::Scene::MAX_CYLINDERS
            ),
        ));
    }
    for s in &raw.sphere {
        let r = s.get_ref();
        let xf = transform(&r.transform)?;
        let sphere = Sphere {
            center: xf.point(vec3(&r.center, "center")?),
            radius: number(&r.radius, "radius", 0.0, f64::INFINITY, true)? * xf.scale,
        };
        out.spheres
            .push((sphere, materials.index(&r.material, SURFACE_MATERIAL)?));
    }
    for p in &raw.plane {
        let r = p.get_ref();
        let xf = transform(&r.transform)?;
        let plane = Plane {
            point: xf.point(vec3(&r.point, "point")?),
            normal: xf.direction(direction(&r.normal, "normal")?),
        };
        out.planes
            .push((plane, materials.index(&r.material, SURFACE_MATERIAL)?));
    }
    for l in &raw.light {
        out.lights.push(build_light(l.get_ref(), l.span())?);
    }
    if let Some(e) = &raw.environment {
        out.environment = Some(build_environment(e.get_ref(), e.span())?);
    }
    if let Some(c) = &raw.camera {
        out.camera = Some(build_camera(c.get_ref(), c.span())?);
    }
    if let Some(r) = &raw.render {
        out.render = build_render(r.get_ref())?;
    }
    out.materials = materials.list;
    Ok(out)
}
#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str =
        "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\n";

    fn err(src: &str) -> String {
        match SceneDescription::parse(src, "s.toml") {
            Ok(s) => panic!("accepted {src:?}: {} cylinders", s.cylinders.len()),
            Err(e) => e.to_string(),
        }
    }

    /// Each scene text fails with a message that starts as given.
    fn expect_errors<S: AsRef<str>>(cases: &[(S, &str)]) {
        for (src, want) in cases {
            let got = err(src.as_ref());
            assert!(
                got.starts_with(want),
                "for {:?}\n got: {got}\nwant: {want}...",
                src.as_ref()
            );
        }
    }

    #[test]
    fn parses_defaults() {
        let s = SceneDescription::parse(GOOD, "s.toml").unwrap();
        assert_eq!(s.cylinders.len(), 1, "one cylinder");
        let c = &s.cylinders[0];
        assert_eq!(c.caps(), [true, true], "caps default to true");
        assert_eq!(c.sweep().minor, [0.1, 0.1], "minor defaults to major");
        assert_eq!(c.sweep().rotation, [0.0, 0.0], "rotation defaults to 0");
        assert!(
            matches!(c.section(), Section::Circle(_)),
            "section defaults to the circle"
        );
    }

    #[test]
    fn empty_scene_is_valid() {
        for src in ["", "# nothing\n", "cylinder = []\n"] {
            let s = SceneDescription::parse(src, "s.toml").unwrap();
            assert!(s.cylinders.is_empty(), "{src:?}");
        }
    }

    #[test]
    fn rejects_shapes_and_values_with_locations() {
        let cases: &[(&str, &str)] = &[
            (
                "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\ncolour = 1\n",
                "s.toml:4:1: unknown field `colour`",
            ),
            ("colour = 1\n", "s.toml:1:1: unknown field `colour`"),
            (
                "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1, 0.2]\n",
                "s.toml:3:16:",
            ),
            (
                "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0],[4,0,0]]\nmajor_radius = [0.1, 0.1]\n",
                "s.toml:2:",
            ),
            (
                "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0]]\nmajor_radius = [0.1, 0.1]\n",
                "s.toml:2:",
            ),
            (
                "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = \"thick\"\n",
                "s.toml:3:16:",
            ),
            (
                "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [nan, 0.1]\n",
                "s.toml:3:16: major_radius must be finite, got [NaN, 0.1] (cylinder 0)",
            ),
            (
                "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\nminor_radius = [0.1, -0.1]\n",
                "s.toml:4:16: minor_radius must be positive at both ends",
            ),
            (
                "[[cylinder]]\nbezier = [[0,0,0],[1,0,inf],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\n",
                "s.toml:2:10: bezier control point 1 is not finite",
            ),
            (
                "[[cylinder]]\nbezier = [[1,1,1],[1,1,1],[1,1,1],[1,1,1]]\nmajor_radius = [0.1, 0.1]\n",
                "s.toml:2:10: the axis has zero length",
            ),
            (
                "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[0,0,0],[1,0,0]]\nmajor_radius = [0.1, 0.1]\n",
                "s.toml:2:10: the axis has a cusp",
            ),
            (
                "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\nnormal_hint = [2, 0, 0]\n",
                "s.toml:4:15: normal_hint is parallel",
            ),
            (
                "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\nnormal_hint = [0, 0, 0]\n",
                "s.toml:4:15: normal_hint must be a finite non-zero vector",
            ),
            (
                "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\nprofile = [[1, 0], [0, 1]]\n",
                "s.toml:4:11: bad profile: a profile needs 3k points",
            ),
            (
                "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\nprofile = [[1, 0], [2, 0], [3, 0]]\n",
                "s.toml:4:11: bad profile: the profile encloses no area",
            ),
            (
                "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\nrotation = [0, inf]\n",
                "s.toml:4:12: rotation must be finite",
            ),
            (
                "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\ncaps = 1\n",
                "s.toml:4:8:",
            ),
            (
                "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\n",
                "s.toml:1:1: missing field `major_radius`",
            ),
            ("[[cylinder]\n", "s.toml:1:"),
            ("[cylinder]\nbezier = 1\n", "s.toml:"),
        ];
        expect_errors(cases);
    }

    #[test]
    fn second_cylinder_is_named() {
        let src = format!(
            "{GOOD}{GOOD}\n[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.0]\n"
        );
        assert!(err(&src).ends_with("(cylinder 2)"), "{}", err(&src));
        assert!(err(&src).starts_with("s.toml:10:16:"), "{}", err(&src));
    }

    #[test]
    fn garbage_bytes_are_an_error() {
        let e = SceneDescription::parse_bytes(b"[[cylinder]]\n\xff\xfe", "s.toml").unwrap_err();
        assert_eq!(
            e.to_string(),
            "s.toml:2:1: the file is not valid UTF-8 text",
            "{e}"
        );
        let e = SceneDescription::parse_bytes(b"\x00\x01\x02", "s.toml").unwrap_err();
        assert!(e.to_string().starts_with("s.toml:1:"), "{e}");
    }

    const FULL: &str = r#"
[render]
integrator = "xray"
spp = 3
max_depth = 5
seed = 9

[camera]
type = "orthographic"
position = [0, 0, 5]
look_at = [0, 0, 0]
view_height = 2
resolution = [64, 32]

[[light]]
type = "directional"
direction = [0, -2, 0]
irradiance = [1, 0.5, 0.25]

[[light]]
type = "point"
position = [1, 2, 3]
intensity = 4

[environment]
top = 1
bottom = [0, 0, 0.1]

[material.glass]
type = "dielectric"
eta = 1.5
sigma_a = [0.1, 0.2, 0.3]
xray_mu = 2.5

[material.kk]
type = "kajiya_kay"
exponent = 12

[[cylinder]]
bezier = [[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]]
major_radius = [0.1, 0.1]
material = "glass"
transform = { scale = 2, rotate = [0, 0, 1, 90], translate = [1, 0, 0] }

[[strand]]
control_points = [[0, 0, 0], [0, 1, 0], [0.5, 2, 0], [0, 3, 0.5]]
radius = [0.05, 0.02]
material = "kk"

[[sphere]]
center = [0, -1, 0]
radius = 0.5
transform = { translate = [0, 0, 1] }

[[plane]]
point = [0, -2, 0]
normal = [0, 3, 0]
"#;

    #[test]
    fn every_table_parses_and_transforms_apply() {
        let d = SceneDescription::parse(FULL, "s.toml").unwrap();
        assert_eq!(
            d.render,
            RenderTable {
                integrator: Some(Integrator::Xray),
                spp: Some(3),
                max_depth: Some(5),
                seed: Some(9)
            },
            "render table"
        );
        let cam = d.camera.unwrap();
        assert_eq!(
            cam.projection,
            Projection::Orthographic { height: 2.0 },
            "camera"
        );
        assert_eq!((cam.width, cam.height), (64, 32), "resolution");
        assert_eq!(d.lights.len(), 2, "lights");
        assert_eq!(
            d.lights[0],
            Light::Directional {
                direction: -DVec3::Y,
                irradiance: DVec3::new(1.0, 0.5, 0.25)
            },
            "directional light, direction normalized"
        );
        assert!(
            matches!(d.environment, Some(Environment::Gradient { .. })),
            "sky"
        );
        // Cylinder 0: scaled by 2, turned 90 degrees about z, moved by +x: the axis from
        // (1, 0, 0) to (1, 6, 0), radius 0.2.
        let c = &d.cylinders[0];
        assert!(
            (c.axis().point(1.0) - DVec3::new(1.0, 6.0, 0.0)).length() < 1e-12,
            "moved"
        );
        assert_eq!(c.sweep().major, [0.2, 0.2], "scaled radius");
        assert_eq!(d.cylinders.len(), 1 + 3, "the strand's 3 segments follow");
        let name = |i: u32| d.materials[i as usize].name.as_str();
        assert_eq!(name(d.cylinder_materials[0]), "glass", "cylinder material");
        assert_eq!(name(d.cylinder_materials[3]), "kk", "strand material");
        let glass = &d.materials[d.cylinder_materials[0] as usize];
        assert_eq!(glass.xray_mu, 2.5, "xray_mu");
        assert_eq!(
            d.spheres[0].0.center,
            DVec3::new(0.0, -1.0, 1.0),
            "sphere moved"
        );
        assert_eq!(
            name(d.spheres[0].1),
            SURFACE_MATERIAL,
            "default surface material"
        );
        assert_eq!(d.planes[0].0.normal, DVec3::Y, "plane normal normalized");
        // The strand's control points are B-spline control points: it starts at the first.
        assert!(
            d.cylinders[1].axis().point(0.0).length() < 1e-15,
            "strand root"
        );
    }

    #[test]
    fn strand_points_are_interpolated() {
        let src = "[[strand]]\npoints = [[0, 0, 0], [0, 1, 0], [0.5, 2, 0], [0, 3, 0.5]]\nradius = [0.05, 0.02]\n";
        let d = SceneDescription::parse(src, "s.toml").unwrap();
        let want = [[0.0, 1.0, 0.0], [0.5, 2.0, 0.0], [0.0, 3.0, 0.5]];
        for (c, w) in d.cylinders.iter().zip(want) {
            let end = c.axis().point(1.0);
            assert!(
                (end - DVec3::from_array(w)).length() < 1e-12,
                "passes through {w:?}: {end}"
            );
        }
        assert_eq!(d.cylinders[0].caps(), [true, false], "root cap only");
        assert_eq!(d.cylinders[2].caps(), [false, true], "tip cap only");
        let major = d.cylinders[1].sweep().major;
        assert!(
            (major[0] - 0.04).abs() < 1e-15 && (major[1] - 0.03).abs() < 1e-15,
            "radius tapers linearly root to tip: {major:?}"
        );
    }

    #[test]
    fn appearance_errors_are_located() {
        let strand = "[[strand]]\npoints = [[0, 0, 0], [0, 1, 0]]\nradius = [0.05, 0.02]\n";
        let cases: &[(String, &str)] = &[
            (
                "[[light]]\ntype = \"laser\"\n".into(),
                "s.toml:2:8: unknown light type `laser`",
            ),
            (
                "[[light]]\ntype = \"point\"\nposition = [0, 0, 0]\nintensity = 1\nradius = 2\n"
                    .into(),
                "s.toml:5:10: `radius` does not apply to a point light",
            ),
            (
                "[[light]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradiance = 1\n".into(),
                "s.toml:1:1: a sphere light needs `radius`",
            ),
            (
                "[[light]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = -1\nradiance = 1\n"
                    .into(),
                "s.toml:4:10: radius must be positive and finite, got -1",
            ),
            (
                "[[light]]\ntype = \"point\"\nposition = [0, 0, 0]\nintensity = [1, -1, 1]\n"
                    .into(),
                "s.toml:4:13: intensity must be finite and non-negative",
            ),
            (
                "[environment]\ncolor = 1\ntop = 1\n".into(),
                "s.toml:1:1: an environment has either",
            ),
            (
                "[material.m]\ntype = \"diffuse\"\neta = 1.5\n".into(),
                "s.toml:3:7: `eta` does not apply to a diffuse material",
            ),
            (
                "[material.m]\ntype = \"diffuse\"\nalbedo = 2\n".into(),
                "s.toml:1:1: albedo must be finite and in [0, 1]",
            ),
            (
                "[material.m]\ntype = \"hair\"\nbeta_m = 0\n".into(),
                "s.toml:3:10: beta_m must be in (0, 1], got 0",
            ),
            (
                "[material.m]\ntype = \"hair\"\nmelanin = 1\ncolor = 0.5\n".into(),
                "s.toml:1:1: a hair material takes one of",
            ),
            (
                "[material.m]\ntype = \"velvet\"\n".into(),
                "s.toml:2:8: unknown material type `velvet`",
            ),
            (
                format!("{strand}material = \"nope\"\n"),
                "s.toml:4:12: unknown material `nope` (defined: fiber, surface)",
            ),
            (
                "[camera]\nposition = [0, 0, 0]\nlook_at = [0, 0, 1]\nfov = 200\n".into(),
                "s.toml:4:7: fov must be in (0, 179], got 200",
            ),
            (
                "[camera]\nposition = [0, 0, 0]\nlook_at = [0, 1, 0]\n".into(),
                "s.toml:1:1: camera up is parallel to the view direction",
            ),
            (
                "[camera]\ntype = \"orthographic\"\nposition = [0, 0, 0]\nlook_at = [0, 0, 1]\n"
                    .into(),
                "s.toml:1:1: an orthographic camera needs `view_height`",
            ),
            (
                "[camera]\nposition = [0, 0, 0]\nlook_at = [0, 0, 1]\nresolution = [0, 10]\n"
                    .into(),
                "s.toml:4:14: resolution must be 1 to 65536",
            ),
            (
                "[render]\nintegrator = \"magic\"\n".into(),
                "s.toml:2:14: unknown integrator `magic`",
            ),
            (
                "[render]\nspp = 0\n".into(),
                "s.toml:2:7: spp must be at least 1",
            ),
            (
                "[[strand]]\nradius = [0.05, 0.02]\n".into(),
                "s.toml:1:1: a strand needs `points` or `control_points`",
            ),
            (
                "[[strand]]\npoints = [[0, 0, 0], [0, 0, 0]]\nradius = [0.05, 0.02]\n".into(),
                "s.toml:2:10: point 1 repeats point 0 (strand 0)",
            ),
            (
                "[[strand]]\npoints = [[0, 0, 0]]\nradius = [0.05, 0.02]\n".into(),
                "s.toml:2:10: a strand needs at least 2 points",
            ),
            (
                "[[strand]]\npoints = [[0, 0, 0], [0, 1, nan]]\nradius = [0.05, 0.02]\n".into(),
                "s.toml:2:10: point 1 is not finite",
            ),
            (
                "[[strand]]\npoints = [[0, 0, 0], [0, 1, 0]]\nradius = [0.05, 0]\n".into(),
                "s.toml:3:10: radius must be positive and finite",
            ),
            (
                format!("{strand}ellipticity = 1.5\n"),
                "s.toml:4:15: ellipticity must be in (0, 1], got 1.5",
            ),
            (
                format!("{strand}transform = {{ scale = 0 }}\n"),
                "s.toml:4:23: transform scale must be positive and finite, got 0",
            ),
            (
                format!("{strand}transform = {{ rotate = [0, 0, 0, 30] }}\n"),
                "s.toml:4:24: transform rotate must be [axis x, y, z, degrees]",
            ),
            (
                "[[hair]]\nfile = \"no/such/file.hair\"\n".into(),
                "s.toml:2:8: cannot read no/such/file.hair:",
            ),
            (
                "[[sphere]]\ncenter = [0, 0, 0]\nradius = 0\n".into(),
                "s.toml:3:10: radius must be positive and finite, got 0",
            ),
            (
                "[[plane]]\npoint = [0, 0, 0]\nnormal = [0, 0, 0]\n".into(),
                "s.toml:3:10: normal must not be zero",
            ),
        ];
        expect_errors(cases);
    }

    #[test]
    fn hair_files_in_scenes_are_read_relative_to_the_scene() {
        let dir = std::env::temp_dir().join(format!("gencyl-hair-scene-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("models")).unwrap();
        let strands = vec![
            vec![
                DVec3::ZERO,
                DVec3::new(0.0, 1.0, 0.0),
                DVec3::new(0.3, 2.0, 0.0),
            ],
            vec![DVec3::X, DVec3::new(1.0, 1.0, 0.2)],
        ];
        let bytes = crate::hair::write_hair(&strands, None, "two strands");
        std::fs::write(dir.join("models/two.hair"), &bytes).unwrap();
        std::fs::write(dir.join("models/cut.hair"), &bytes[..bytes.len() - 3]).unwrap();
        let scene = dir.join("scene.toml");
        std::fs::write(
            &scene,
            "[[hair]]\nfile = \"models/two.hair\"\nradius = 0.01\nellipticity = 0.5\n",
        )
        .unwrap();
        let d = SceneDescription::load(&scene).unwrap();
        assert_eq!(d.cylinders.len(), 3, "2 + 1 segments");
        assert_eq!(
            d.cylinders[0].sweep().minor,
            [0.005, 0.005],
            "ellipticity applied"
        );
        let end = d.cylinders[1].axis().point(1.0);
        assert!(
            (end - DVec3::new(0.3, 2.0, 0.0)).length() < 1e-6,
            "through the file's points"
        );
        std::fs::write(&scene, "\n[[hair]]\nfile = \"models/cut.hair\"\n").unwrap();
        let e = SceneDescription::load(&scene).unwrap_err().to_string();
        assert!(
            e.contains("scene.toml:3:8: models/cut.hair: ") && e.contains("truncated"),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
