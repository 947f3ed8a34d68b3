//! The scene file format (TOML): parsing, checking every value, locating every error, and
//! building what the file describes into a [`SceneDescription`].
//!
//! One file per table family: `geometry` (`[[cylinder]]`, `[[strand]]`, `[[hair]]`,
//! `[[sphere]]`, `[[plane]]`, transforms), `lights` (`[[light]]`, `[environment]`),
//! `materials` (`[material.NAME]`), `camera` (`[camera]` and `[render]`); `values` holds the
//! checks they share, and this file the document as a whole. A new table goes in the file of
//! its family: its serde mirror (`Raw...`, with `Spanned` values), its checks, its builder.
//!
//! Imports: the geometry crate, [`crate::accel`] (shapes, the scene's size limit),
//! [`crate::formats`] (`.hair` files, diagnostics), [`crate::optics`] (the lights, materials
//! and camera it builds) and [`crate::settings`]; never light transport, which reads what
//! this module builds.
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
//! use gencyl_render::scene_file::SceneDescription;
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

use gencyl::{GeneralizedCylinder, StrandControls};
use rayon::prelude::*;
use serde::Deserialize;
use toml::Spanned;

mod camera;
pub mod ct;
pub mod export;
mod geometry;
mod lights;
mod materials;
mod values;

pub use geometry::{
    BuiltStrands, FiberInput, Key, Similarity, StrandInput, StrandParts, build_fiber,
    build_strand_from,
};
pub use materials::{FIBER_MATERIAL, SURFACE_MATERIAL};

use crate::accel::{Plane, Scene, Sphere};
use crate::formats::Diagnostic;
use crate::optics::material::SceneMaterial;
use crate::optics::scanner::CtSetup;
use crate::optics::{Camera, Environment, Light};
use crate::settings::RenderTable;
use camera::{RawCamera, RawRender, build_camera, build_render};
use ct::{RawCt, build_ct};
use geometry::*;
use lights::{RawEnvironment, RawLight, build_environment, build_light};
use materials::{Materials, RawMaterial, build_exact_tables};
use values::Problem;

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
    /// A `.hair` model (loaded by [`SceneDescription::load_any`]) that cannot be read or used,
    /// or a setting that does not apply to the file: the message names the file.
    #[error("{0}")]
    Model(String),
}

impl SceneError {
    /// The diagnostic, for an error located in the file.
    pub fn diagnostic(&self) -> Option<&Diagnostic> {
        match self {
            SceneError::Invalid(d) => Some(d),
            SceneError::Read { .. } | SceneError::Model(_) => None,
        }
    }
}

/// The contents of a scene file, validated, with every cylinder built.
#[derive(Clone, Debug, Default)]
pub struct SceneDescription {
    /// The cylinders in order: index = `object` number.
    pub cylinders: Vec<GeneralizedCylinder>,
    /// The strands among the cylinders, with their B-spline control points, by which a
    /// [`Scene`] stores their segments compactly (a span that does not give back its
    /// cylinders exactly is not used).
    pub strands: StrandControls,
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
    /// The `[ct]` scan, if the scene has one.
    pub ct: Option<CtSetup>,
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
    ct: Option<Spanned<RawCt>>,
}

impl SceneDescription {
    /// Reads and parses the scene file at `path`; hair files are found relative to its folder.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, SceneError> {
        let path = path.as_ref();
        let name = path.display().to_string();
        let bytes = crate::limits::read_file(path, crate::limits::MAX_SCENE_FILE, "scene file")
            .map_err(|error| SceneError::Read {
                path: name.clone(),
                error,
            })?;
        let base = path.parent().map_or_else(PathBuf::new, Path::to_path_buf);
        Self::parse_bytes_in(&bytes, &name, &base)
    }

    /// Loads a scene file, or a hair model in Cem Yuksel's `.hair` format (told by the
    /// extension, in any case) as [`SceneDescription::from_hair_file`] does. `radius` (the
    /// fiber radius) applies to hair models only: a scene file sets its radii itself.
    pub fn load_any(path: impl AsRef<Path>, radius: Option<f64>) -> Result<Self, SceneError> {
        let path = path.as_ref();
        let is_hair = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("hair"));
        if is_hair {
            Self::from_hair_file(path, radius).map_err(SceneError::Model)
        } else if radius.is_some() {
            Err(SceneError::Model(format!(
                "{}: the radius applies to .hair models; a scene file sets radii itself",
                path.display()
            )))
        } else {
            Self::load(path)
        }
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
        if src.len() >= SPLIT_MIN
            && let Some(scene) = parse_split(src, base)
        {
            return Ok(scene);
        }
        Self::parse_whole(src, name, base)
    }

    /// [`Self::parse_in`], the whole text at once.
    fn parse_whole(src: &str, name: &str, base: &Path) -> Result<Self, SceneError> {
        let raw: RawScene = toml::from_str(src).map_err(|e| {
            let span = e.span().unwrap_or(0..0);
            invalid(name, src, span, e.message().trim().to_string())
        })?;
        build(&raw, base).map_err(|(span, msg)| invalid(name, src, span, msg))
    }
}

/// Texts from this size on are parsed in pieces where they can be ([`parse_split`]).
const SPLIT_MIN: usize = 1 << 20;
/// The least size of a piece of [`parse_split`] (the last may be smaller).
const SPLIT_PIECE: usize = 1 << 18;

/// A piece of [`parse_split`]: `[[cylinder]]` tables and nothing else.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CylinderTables {
    #[serde(default)]
    cylinder: Vec<Spanned<RawCylinder>>,
}

/// A long text of `[[cylinder]]` tables (what `gencyl export` writes, or a CT model of many
/// fibers), parsed in pieces of about [`SPLIT_PIECE`] bytes in parallel, so that only one
/// piece's parse tree per thread is alive at once (the whole text's tree takes about twenty
/// times the text's size) and the pieces share the cores.
///
/// The text is cut where a line starts with the header `[[cylinder]]`. The part before the
/// first cut is parsed as a scene, each piece as `[[cylinder]]` tables only. A cut inside a
/// multi-line string or array leaves that piece unterminated, so every piece parses alone
/// exactly as it does within the whole. `None` (the caller then parses the whole text) where
/// that does not settle it: no cut, cylinder tables before the first cut (the whole text
/// might be invalid TOML by joining them with the later ones, as a static array extended by
/// headers), any piece that does not parse, and any error in building the scene (its message
/// needs spans in the whole text).
fn parse_split(src: &str, base: &Path) -> Option<SceneDescription> {
    const HEADER: &str = "[[cylinder]]";
    // Where lines start with the header: the text's start, or after a line feed.
    let at_start = src.starts_with(HEADER).then_some(0);
    let after_newline = src.match_indices("\n[[cylinder]]").map(|(at, _)| at + 1);
    let mut cuts = Vec::new();
    for start in at_start.into_iter().chain(after_newline) {
        // The header alone on its line (TOML allows whitespace or a comment after it).
        let next = src[start + HEADER.len()..].chars().next();
        if !next.is_none_or(|c| matches!(c, ' ' | '\t' | '\r' | '\n' | '#')) {
            continue;
        }
        if cuts.last().is_none_or(|&last| start - last >= SPLIT_PIECE) {
            cuts.push(start);
        }
    }
    let first = *cuts.first()?;
    let mut raw: RawScene = toml::from_str(&src[..first]).ok()?;
    if !raw.cylinder.is_empty() {
        return None;
    }
    cuts.push(src.len());
    let pieces: Vec<Option<CylinderTables>> = cuts
        .par_windows(2)
        .map(|w| toml::from_str(&src[w[0]..w[1]]).ok())
        .collect();
    for piece in pieces {
        raw.cylinder.extend(piece?.cylinder);
    }
    build(&raw, base).ok()
}

fn invalid(name: &str, src: &str, span: Range<usize>, message: String) -> SceneError {
    SceneError::Invalid(Box::new(Diagnostic::new(name, src, span, message)))
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
    let built: Vec<Result<StrandParts, Problem>> = raw
        .strand
        .par_iter()
        .map(|s| build_strand(s.get_ref(), s.span()))
        .collect();
    let mut strands = BuiltStrands {
        cylinders: std::mem::take(&mut out.cylinders),
        controls: StrandControls::default(),
    };
    for (i, (b, s)) in built.into_iter().zip(&raw.strand).enumerate() {
        let (cyls, controls, taper) =
            b.map_err(|(span, msg)| (span, format!("{msg} (strand {i})")))?;
        let m = materials.index(&s.get_ref().material, FIBER_MATERIAL)?;
        out.cylinder_materials
            .extend(std::iter::repeat_n(m, cyls.len()));
        strands.push(cyls, &controls, taper);
    }
    for h in &raw.hair {
        let hair = build_hair(h.get_ref(), base)?;
        let m = materials.index(&h.get_ref().material, FIBER_MATERIAL)?;
        out.cylinder_materials
            .extend(std::iter::repeat_n(m, hair.cylinders.len()));
        strands.append(hair);
    }
    (out.cylinders, out.strands) = (strands.cylinders, strands.controls);
    if out.cylinders.len() > Scene::MAX_CYLINDERS {
        return Err((
            0..0,
            format!(
                "{} cylinders: more than the {} a scene holds",
                out.cylinders.len(),
                Scene::MAX_CYLINDERS
            ),
        ));
    }
    for s in &raw.sphere {
        let r = s.get_ref();
        out.spheres.push((
            build_sphere(r)?,
            materials.index(&r.material, SURFACE_MATERIAL)?,
        ));
    }
    for p in &raw.plane {
        let r = p.get_ref();
        out.planes.push((
            build_plane(r)?,
            materials.index(&r.material, SURFACE_MATERIAL)?,
        ));
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
    if let Some(c) = &raw.ct {
        out.ct = Some(build_ct(c.get_ref(), c.span(), &materials)?);
    }
    let bins = out
        .ct
        .as_ref()
        .and_then(|c| c.spectrum.as_ref())
        .map_or(1, |s| s.weights.len());
    for (name, m) in &raw.material {
        if let Some(mu) = &m.get_ref().xray_mu {
            let n = mu.get_ref().0.len();
            if n != 1 && n != bins {
                let why = if bins == 1 {
                    "the scene has no [ct] spectrum: give one number".to_string()
                } else {
                    format!("the [ct] spectrum has {bins} bins: give one number or {bins}")
                };
                return Err((
                    mu.span(),
                    format!("xray_mu has {n} values but {why} (material `{name}`)"),
                ));
            }
        }
    }
    out.materials = materials.list;
    build_exact_tables(
        &mut out.materials,
        &out.cylinders,
        &out.cylinder_materials,
        |name| raw.material.get(name).map_or(0..0, |m| m.span()),
    )?;
    Ok(out)
}

#[cfg(test)]
mod tests;
