//! The geometry tables: `[[cylinder]]` (interface.md section 2), `[[strand]]`, `[[hair]]`,
//! `[[sphere]]`, `[[plane]]`, and the `transform` they share.

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::Path;

use gencyl::section::ProfileError;
use gencyl::{
    BezierLoop, FiberSpec, GeneralizedCylinder, GeometryError, Section, Strand, StrandControls,
    StrandFraming, Taper, Unresolved,
};
use glam::{DQuat, DVec2, DVec3};
use rayon::prelude::*;
use serde::Deserialize;
use toml::Spanned;

use super::SceneDescription;
use super::materials::{FIBER_MATERIAL, Materials};
use super::values::*;
use crate::accel::{Plane, Sphere};
use crate::formats::hair::parse_hair;
use crate::limits::MAX_LENGTH;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawCylinder {
    pub(super) bezier: Spanned<Array<Array<f64, 3>, 4>>,
    pub(super) major_radius: Spanned<Array<f64, 2>>,
    pub(super) minor_radius: Option<Spanned<Array<f64, 2>>>,
    pub(super) rotation: Option<Spanned<Array<f64, 2>>>,
    pub(super) caps: Option<Caps>,
    pub(super) normal_hint: Option<Spanned<Array<f64, 3>>>,
    pub(super) profile: Option<Spanned<Vec<Array<f64, 2>>>>,
    pub(super) material: Option<Spanned<String>>,
    pub(super) transform: Option<Spanned<RawTransform>>,
}

/// `caps`: `true` or `false` for both ends (interface.md), or `[start, end]` for each (an
/// extension: a strand segment exported by `gencyl export` keeps its caps at root and tip only).
#[derive(Clone, Copy, Debug)]
pub(super) enum Caps {
    Both(bool),
    Each(Array<bool, 2>),
}

impl<'de> Deserialize<'de> for Caps {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = Caps;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                write!(f, "true, false, or [start, end]")
            }
            fn visit_bool<E>(self, b: bool) -> Result<Caps, E> {
                Ok(Caps::Both(b))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(self, seq: A) -> Result<Caps, A::Error> {
                Deserialize::deserialize(serde::de::value::SeqAccessDeserializer::new(seq))
                    .map(Caps::Each)
            }
        }
        d.deserialize_any(V)
    }
}

impl Caps {
    fn ends(caps: Option<Caps>) -> [bool; 2] {
        match caps {
            None => [true, true],
            Some(Caps::Both(c)) => [c, c],
            Some(Caps::Each(a)) => a.0,
        }
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawStrand {
    pub(super) points: Option<Spanned<Vec<Array<f64, 3>>>>,
    pub(super) control_points: Option<Spanned<Vec<Array<f64, 3>>>>,
    pub(super) radius: Spanned<Array<f64, 2>>,
    pub(super) ellipticity: Option<Spanned<f64>>,
    pub(super) twist: Option<Spanned<Array<f64, 2>>>,
    pub(super) frame: Option<Spanned<String>>,
    pub(super) profile: Option<Spanned<Vec<Array<f64, 2>>>>,
    pub(super) material: Option<Spanned<String>>,
    pub(super) transform: Option<Spanned<RawTransform>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawHair {
    pub(super) file: Spanned<String>,
    pub(super) radius: Option<Spanned<f64>>,
    pub(super) ellipticity: Option<Spanned<f64>>,
    pub(super) twist: Option<Spanned<Array<f64, 2>>>,
    pub(super) frame: Option<Spanned<String>>,
    pub(super) profile: Option<Spanned<Vec<Array<f64, 2>>>>,
    pub(super) material: Option<Spanned<String>>,
    pub(super) transform: Option<Spanned<RawTransform>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawSphere {
    pub(super) center: Spanned<Array<f64, 3>>,
    pub(super) radius: Spanned<f64>,
    pub(super) material: Option<Spanned<String>>,
    pub(super) transform: Option<Spanned<RawTransform>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawPlane {
    pub(super) point: Spanned<Array<f64, 3>>,
    pub(super) normal: Spanned<Array<f64, 3>>,
    pub(super) material: Option<Spanned<String>>,
    pub(super) transform: Option<Spanned<RawTransform>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawTransform {
    pub(super) scale: Option<Spanned<f64>>,
    pub(super) rotate: Option<Spanned<Array<f64, 4>>>,
    pub(super) translate: Option<Spanned<Array<f64, 3>>>,
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
pub(super) fn transform(t: &Option<Spanned<RawTransform>>) -> Result<Similarity, Problem> {
    let Some(t) = t else {
        return Ok(Similarity::default());
    };
    let t = t.get_ref();
    let mut out = Similarity::default();
    if let Some(s) = &t.scale {
        out.scale = length(s, "transform scale")?;
    }
    if let Some(r) = &t.rotate {
        let [x, y, z, deg] = val(r);
        let axis = DVec3::new(x, y, z);
        let big = axis.abs().max_element();
        if !(axis.is_finite() && deg.is_finite() && big > 0.0) {
            return Err((
                r.span(),
                format!(
                    "transform rotate must be [axis x, y, z, degrees], finite, with a non-zero axis, got {:?}",
                    val(r)
                ),
            ));
        }
        out.rotation = DQuat::from_axis_angle((axis / big).normalize(), deg.to_radians());
    }
    if let Some(tr) = &t.translate {
        out.translation = vec3(tr, "transform translate")?;
    }
    Ok(out)
}

/// A profile (`profile` key) as a section.
pub(super) fn section(p: &Option<Spanned<Vec<Array<f64, 2>>>>) -> Result<Section, Problem> {
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

/// Which value of a fiber's or strand's input a problem is about: the scene file points at
/// its key, the Python bindings name the argument.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Key {
    /// `bezier` (a fiber's control points).
    Bezier,
    /// `major_radius`.
    MajorRadius,
    /// `minor_radius`.
    MinorRadius,
    /// `rotation`.
    Rotation,
    /// `normal_hint`.
    NormalHint,
    /// A strand's `points` or `control_points`.
    Points,
    /// A strand's `radius`.
    Radius,
    /// A strand's `ellipticity`.
    Ellipticity,
    /// A strand's `twist`.
    Twist,
    /// The values together (no one of them is at fault).
    Whole,
}

/// The values of a `[[cylinder]]` table (interface.md section 2), as [`build_fiber`] checks
/// and builds them.
#[derive(Clone, Debug, Default)]
pub struct FiberInput {
    /// Bezier control points `P0..P3`, before `transform`.
    pub bezier: [[f64; 3]; 4],
    /// `[A0, A1]`.
    pub major_radius: [f64; 2],
    /// `[B0, B1]` (default: the major radii, a round fiber).
    pub minor_radius: Option<[f64; 2]>,
    /// `[theta0, theta1]`, radians (default 0).
    pub rotation: Option<[f64; 2]>,
    /// Whether the caps at `u = 0` and `u = 1` are closed.
    pub caps: [bool; 2],
    /// Frame hint for straight axes, before `transform`.
    pub normal_hint: Option<[f64; 3]>,
    /// The section (default: the unit circle).
    pub section: Section,
    /// The similarity applied to the points, radii and hint.
    pub transform: Similarity,
}

/// Checks a fiber's values (finite control points, positive finite radii, finite rotation,
/// a finite non-zero hint, a sweep that stays invertible) and builds its cylinder; a problem
/// names the [`Key`] at fault.
pub fn build_fiber(c: &FiberInput) -> Result<GeneralizedCylinder, (Key, String)> {
    if let Some(i) = c
        .bezier
        .iter()
        .position(|p| !p.iter().all(|x| x.is_finite()))
    {
        return Err((
            Key::Bezier,
            format!("bezier control point {i} is not finite: {:?}", c.bezier[i]),
        ));
    }
    let radius = |key: Key, name: &str, v: [f64; 2]| -> Result<[f64; 2], (Key, String)> {
        if !v.iter().all(|x| x.is_finite()) {
            return Err((key, format!("{name} must be finite, got {v:?}")));
        }
        if !v.iter().all(|&x| x > 0.0) {
            return Err((
                key,
                format!("{name} must be positive at both ends, got {v:?}"),
            ));
        }
        Ok(v)
    };
    let major = radius(Key::MajorRadius, "major_radius", c.major_radius)?;
    let minor = c
        .minor_radius
        .map_or(Ok(major), |r| radius(Key::MinorRadius, "minor_radius", r))?;
    let rotation = c.rotation.unwrap_or([0.0, 0.0]);
    if !rotation.iter().all(|x| x.is_finite()) {
        return Err((
            Key::Rotation,
            format!("rotation must be finite, got {rotation:?}"),
        ));
    }
    let normal_hint = match c.normal_hint {
        Some(h) => {
            let v = DVec3::from_array(h);
            if !v.is_finite() || v == DVec3::ZERO {
                return Err((
                    Key::NormalHint,
                    format!("normal_hint must be a finite non-zero vector, got {h:?}"),
                ));
            }
            Some(v)
        }
        None => None,
    };
    let xf = c.transform;
    let spec = FiberSpec {
        bezier: c.bezier.map(|p| xf.point(DVec3::from_array(p))),
        major_radius: major.map(|r| r * xf.scale),
        minor_radius: minor.map(|r| r * xf.scale),
        rotation,
        caps: true,
        normal_hint: normal_hint.map(|h| xf.direction(h)),
        section: c.section.clone(),
    };
    let [start, end] = c.caps;
    spec.build().map(|c| c.with_caps(start, end)).map_err(|e| {
        let msg = e.to_string();
        // A sweep's message starts with the key it is about (`HairSweep::validate`).
        let starts = |name: &str| msg.starts_with(name);
        let key = match &e {
            GeometryError::BadNormalHint if normal_hint.is_some() => Key::NormalHint,
            GeometryError::Sweep(_) if starts("minor_radius") => Key::MinorRadius,
            GeometryError::Sweep(_) if starts("rotation") => Key::Rotation,
            GeometryError::Sweep(_) if starts("major_radius") => Key::MajorRadius,
            GeometryError::Sweep(_) => Key::Whole,
            GeometryError::Unresolvable {
                of: Unresolved::Section,
                ..
            } => Key::MajorRadius,
            _ => Key::Bezier,
        };
        (key, msg)
    })
}

/// Checks one `[[cylinder]]` table and builds its cylinder.
pub(super) fn build_cylinder(
    c: &RawCylinder,
    table: Range<usize>,
) -> Result<GeneralizedCylinder, Problem> {
    let input = FiberInput {
        bezier: val(&c.bezier).map(|p| p.0),
        major_radius: val(&c.major_radius),
        minor_radius: c.minor_radius.as_ref().map(val),
        rotation: c.rotation.as_ref().map(val),
        caps: Caps::ends(c.caps),
        normal_hint: c.normal_hint.as_ref().map(val),
        section: section(&c.profile)?,
        transform: transform(&c.transform)?,
    };
    build_fiber(&input).map_err(|(key, msg)| {
        let or_table = |s: Option<Range<usize>>| s.unwrap_or(table.clone());
        let span = match key {
            Key::MinorRadius => or_table(c.minor_radius.as_ref().map(Spanned::span)),
            Key::Rotation => or_table(c.rotation.as_ref().map(Spanned::span)),
            Key::NormalHint => or_table(c.normal_hint.as_ref().map(Spanned::span)),
            Key::MajorRadius => c.major_radius.span(),
            Key::Whole => table.clone(),
            _ => c.bezier.span(),
        };
        (span, msg)
    })
}

/// Ellipticity (minor / major radius) and twist keys shared by strands and hair files.
pub(super) fn strand_shape(
    ellipticity: &Option<Spanned<f64>>,
    twist: &Option<Spanned<Array<f64, 2>>>,
) -> Result<(f64, [f64; 2]), Problem> {
    check_shape(
        ellipticity.as_ref().map(|e| *e.get_ref()),
        twist.as_ref().map(val),
    )
    .map_err(|(key, m)| {
        let span = match key {
            Key::Ellipticity => ellipticity.as_ref().map(Spanned::span),
            _ => twist.as_ref().map(Spanned::span),
        };
        (span.unwrap_or(0..0), m)
    })
}

/// Ellipticity in (0, 1] (default 1) and a finite twist (default 0).
fn check_shape(
    ellipticity: Option<f64>,
    twist: Option<[f64; 2]>,
) -> Result<(f64, [f64; 2]), (Key, String)> {
    let e = match ellipticity {
        Some(e) => {
            check_number(e, "ellipticity", 0.0, 1.0, true).map_err(|m| (Key::Ellipticity, m))?
        }
        None => 1.0,
    };
    let tw = twist.unwrap_or([0.0, 0.0]);
    if !tw.iter().all(|x| x.is_finite()) {
        return Err((Key::Twist, format!("twist must be finite, got {tw:?}")));
    }
    Ok((e, tw))
}

/// The `frame` key of strands and hair files: `"minimal"` (the default; also
/// `"rotation-minimizing"`, `"rotation-minimising"`, `"rmf"`) or `"frenet"`.
pub(super) fn strand_framing(frame: &Option<Spanned<String>>) -> Result<StrandFraming, Problem> {
    let Some(f) = frame else {
        return Ok(StrandFraming::default());
    };
    match f.get_ref().as_str() {
        "minimal" | "rotation-minimizing" | "rotation-minimising" | "rmf" => {
            Ok(StrandFraming::RotationMinimizing)
        }
        "frenet" => Ok(StrandFraming::Frenet),
        other => Err((
            f.span(),
            format!("frame must be \"minimal\" or \"frenet\", got {other:?}"),
        )),
    }
}

/// The values of a `[[strand]]` table, as [`build_strand_from`] checks and builds them.
#[derive(Clone, Debug, Default)]
pub struct StrandInput {
    /// Points the strand passes through (`through`), or its Bezier control points
    /// (`3 n + 1` of them, segments sharing their ends), before `transform`.
    pub points: Vec<[f64; 3]>,
    /// Whether `points` are points on the strand (interpolated by a C1 spline) rather than
    /// control points.
    pub through: bool,
    /// Radius at root and tip.
    pub radius: [f64; 2],
    /// Minor / major radius, in (0, 1] (default 1).
    pub ellipticity: Option<f64>,
    /// Section rotation at root and tip, radians (default 0).
    pub twist: Option<[f64; 2]>,
    /// How the section's frame follows the axis.
    pub framing: StrandFraming,
    /// The section (default: the unit circle).
    pub section: Section,
    /// The similarity applied to the points and radius.
    pub transform: Similarity,
}

/// A strand's segments as cylinders, the B-spline control points they are segments of, and
/// its radii along it.
pub type StrandParts = (Vec<GeneralizedCylinder>, Vec<DVec3>, Taper);

/// Strands' segments as cylinders, and the B-spline control points they are segments of
/// ([`gencyl::Strand::spline_controls`]), by which a scene stores them compactly.
#[derive(Clone, Debug, Default)]
pub struct BuiltStrands {
    /// The segments, strand after strand.
    pub cylinders: Vec<GeneralizedCylinder>,
    /// Each strand's first segment in `cylinders`, its control points and its radii.
    pub controls: StrandControls,
}

impl BuiltStrands {
    /// Appends a strand's segments, its control points and its radii.
    pub fn push(&mut self, cylinders: Vec<GeneralizedCylinder>, controls: &[DVec3], taper: Taper) {
        self.controls.push(self.cylinders.len(), controls, taper);
        self.cylinders.extend(cylinders);
    }

    /// Appends other strands (takes them, without a copy, when there are none yet).
    pub fn append(&mut self, other: BuiltStrands) {
        if self.cylinders.is_empty() && self.controls.is_empty() {
            *self = other;
            return;
        }
        self.controls.append(&other.controls, self.cylinders.len());
        self.cylinders.extend(other.cylinders);
    }
}

/// Checks a strand's values (at least 2 finite points, none repeating the one before, a
/// positive finite radius, the shape) and builds its segments, with the control points they
/// are segments of; a problem names the [`Key`].
pub fn build_strand_from(s: StrandInput) -> Result<StrandParts, (Key, String)> {
    let xf = s.transform;
    let mut points = Vec::with_capacity(s.points.len());
    for (i, p) in s.points.iter().enumerate() {
        let v = DVec3::from_array(*p);
        if !v.is_finite() {
            return Err((Key::Points, format!("point {i} is not finite: {p:?}")));
        }
        if points.last() == Some(&xf.point(v)) {
            return Err((Key::Points, format!("point {i} repeats point {}", i - 1)));
        }
        points.push(xf.point(v));
    }
    if points.len() < 2 {
        return Err((Key::Points, "a strand needs at least 2 points".into()));
    }
    let r = s.radius;
    if !r.iter().all(|x| x.is_finite() && *x > 0.0) {
        return Err((
            Key::Radius,
            format!("radius must be positive and finite at root and tip, got {r:?}"),
        ));
    }
    let (ellipticity, twist) = check_shape(s.ellipticity, s.twist)?;
    let strand = Strand {
        points: if s.through {
            Strand::interpolating_control_points(&points)
        } else {
            points
        },
        radius: r.map(|x| x * xf.scale),
        ellipticity,
        twist,
        section: s.section,
    };
    let cylinders = strand
        .cylinders_with(s.framing)
        .map_err(|(seg, e)| (Key::Points, format!("segment {seg}: {e}")))?;
    Ok((cylinders, strand.spline_controls(), strand.taper()))
}

/// Checks one `[[strand]]` table and builds its segments.
pub(super) fn build_strand(s: &RawStrand, table: Range<usize>) -> Result<StrandParts, Problem> {
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
    let input = StrandInput {
        points: pts.get_ref().iter().map(|p| p.0).collect(),
        through,
        radius: val(&s.radius),
        ellipticity: s.ellipticity.as_ref().map(|e| *e.get_ref()),
        twist: s.twist.as_ref().map(val),
        framing: strand_framing(&s.frame)?,
        section: section(&s.profile)?,
        transform: transform(&s.transform)?,
    };
    build_strand_from(input).map_err(|(key, m)| {
        let span = match key {
            Key::Radius => s.radius.span(),
            Key::Ellipticity => s.ellipticity.as_ref().map_or(table, Spanned::span),
            Key::Twist => s.twist.as_ref().map_or(table, Spanned::span),
            _ => pts.span(),
        };
        (span, m)
    })
}

/// Checks one `[[sphere]]` table and builds its sphere.
pub(super) fn build_sphere(r: &RawSphere) -> Result<Sphere, Problem> {
    let xf = transform(&r.transform)?;
    let sphere = Sphere {
        center: xf.point(vec3(&r.center, "center")?),
        radius: length(&r.radius, "radius")? * xf.scale,
    };
    let far = sphere.center.abs().max_element() + sphere.radius;
    if !(far <= MAX_LENGTH && sphere.radius > 0.0) {
        return Err((
            r.radius.span(),
            format!(
                "with its transform the sphere reaches {} from the origin (radius {}), beyond {MAX_LENGTH:.0e} or too small to resolve",
                gencyl::limits::short(far),
                gencyl::limits::short(sphere.radius)
            ),
        ));
    }
    Ok(sphere)
}

/// Checks one `[[plane]]` table and builds its plane.
pub(super) fn build_plane(r: &RawPlane) -> Result<Plane, Problem> {
    let xf = transform(&r.transform)?;
    let plane = Plane {
        point: xf.point(vec3(&r.point, "point")?),
        normal: xf.direction(direction(&r.normal, "normal")?),
    };
    if !(plane.point.abs().max_element() <= MAX_LENGTH) {
        return Err((
            r.point.span(),
            format!(
                "with its transform the plane's point is beyond {MAX_LENGTH:.0e} from the origin"
            ),
        ));
    }
    Ok(plane)
}

/// Reads one `[[hair]]` file (relative to the scene's folder) and builds its strands.
pub(super) fn build_hair(h: &RawHair, base: &Path) -> Result<BuiltStrands, Problem> {
    let file = h.file.get_ref();
    let radius = match &h.radius {
        Some(r) => Some(length(r, "radius")?),
        None => None,
    };
    let (ellipticity, twist) = strand_shape(&h.ellipticity, &h.twist)?;
    let framing = strand_framing(&h.frame)?;
    let section = section(&h.profile)?;
    let xf = transform(&h.transform)?;
    let shape = StrandShape {
        radius,
        ellipticity,
        twist,
        framing,
        section,
    };
    hair_cylinders(&base.join(file), file, shape, xf).map_err(|e| (h.file.span(), e))
}

/// How a hair file's strands are shaped and framed.
pub(super) struct StrandShape {
    /// The radius at root and tip; `None`: half the file's thickness.
    pub(super) radius: Option<f64>,
    pub(super) ellipticity: f64,
    pub(super) twist: [f64; 2],
    pub(super) framing: StrandFraming,
    /// Every strand's section (a `profile`, or the unit circle).
    pub(super) section: Section,
}

/// The cylinders of a hair file's strands (through the file's points), radius from the
/// file's thickness unless given; the error names the file and the strand.
pub(super) fn hair_cylinders(
    path: &Path,
    file: &str,
    shape: StrandShape,
    xf: Similarity,
) -> Result<BuiltStrands, String> {
    let StrandShape {
        radius,
        ellipticity,
        twist,
        framing,
        section,
    } = shape;
    let bytes = crate::limits::read_file(path, crate::limits::MAX_HAIR_FILE, "hair file")
        .map_err(|e| format!("cannot read {file}: {e}"))?;
    let hair = parse_hair(&bytes, file).map_err(|e| e.to_string())?;
    drop(bytes);
    let segments: u64 = hair.strands.iter().map(|s| s.len() as u64).sum();
    crate::limits::check_memory(
        segments.saturating_mul(crate::limits::PEAK_BYTES_PER_SEGMENT),
        &format!("{file}: its {segments} segments"),
    )?;
    // The cylinders and control points are written in place, each strand's share of the two
    // arrays known from its point count (n points: n - 1 segments, n + 2 control points), so
    // no per-strand list outlives its strand and nothing is copied (a copy's freed blocks stay
    // resident: the peak would hold the model twice).
    let strands = hair.to_strands(radius);
    drop(hair);
    let mut cylinders: Vec<Option<GeneralizedCylinder>> =
        (0..strands.iter().map(|s| s.points.len() - 1).sum())
            .map(|_| None)
            .collect();
    let mut points = vec![DVec3::ZERO; strands.iter().map(|s| s.points.len() + 2).sum()];
    let mut starts = Vec::with_capacity(strands.len());
    let mut jobs = Vec::with_capacity(strands.len());
    let (mut cyl_rest, mut pts_rest) = (&mut cylinders[..], &mut points[..]);
    let (mut first, mut start) = (0, 0);
    for s in strands {
        let n = s.points.len();
        let (cyl, c) = std::mem::take(&mut cyl_rest).split_at_mut(n - 1);
        let (pts, p) = std::mem::take(&mut pts_rest).split_at_mut(n + 2);
        (cyl_rest, pts_rest) = (c, p);
        starts.push((first, start));
        (first, start) = (first + n - 1, start + n + 2);
        jobs.push((s, cyl, pts));
    }
    let built: Vec<Result<Taper, String>> = jobs
        .into_par_iter()
        .enumerate()
        .map(|(i, (mut s, cyl, pts))| {
            for p in &mut s.points {
                *p = xf.point(*p);
            }
            s.points = Strand::interpolating_control_points(&s.points);
            s.radius = s.radius.map(|r| r * xf.scale);
            s.ellipticity = ellipticity;
            s.twist = twist;
            s.section = section.clone();
            let segments = s
                .cylinders_with(framing)
                .map_err(|(seg, e)| format!("{file}: strand {i}, segment {seg}: {e}"))?;
            for (slot, c) in cyl.iter_mut().zip(segments) {
                *slot = Some(c);
            }
            pts.copy_from_slice(&s.spline_controls());
            Ok(s.taper())
        })
        .collect();
    // The first problem in file order.
    let tapers = built.into_iter().collect::<Result<Vec<Taper>, String>>()?;
    Ok(BuiltStrands {
        cylinders: cylinders
            .into_iter()
            .map(|c| c.expect("every strand fills its segments"))
            .collect(),
        controls: StrandControls::from_parts(points, starts, tapers),
    })
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
        let shape = StrandShape {
            radius,
            ellipticity: 1.0,
            twist: [0.0, 0.0],
            framing: StrandFraming::default(),
            section: Section::default(),
        };
        let strands = hair_cylinders(path, &name, shape, Similarity::default())?;
        Ok(Self::from_strands(strands))
    }

    /// [`Self::from_cylinders`] of strands' segments, their control points kept for compact
    /// storage.
    pub fn from_strands(strands: BuiltStrands) -> Self {
        SceneDescription {
            strands: strands.controls,
            ..Self::from_cylinders(strands.cylinders)
        }
    }

    /// A scene of these cylinders in the built-in `fiber` material, with no camera or lights
    /// (the renderer frames and lights it).
    pub fn from_cylinders(cylinders: Vec<GeneralizedCylinder>) -> Self {
        let materials = Materials::new(&BTreeMap::new()).expect("the built-in materials are valid");
        let fiber = materials
            .index(&None, FIBER_MATERIAL)
            .expect("the built-in fiber material exists");
        SceneDescription {
            cylinder_materials: vec![fiber; cylinders.len()],
            cylinders,
            materials: materials.list,
            ..Default::default()
        }
    }
}
