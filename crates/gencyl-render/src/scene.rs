//! Scene files (TOML) and the scene they describe, ready for ray queries.
//!
//! # Format
//!
//! A scene file is TOML. Each `[[cylinder]]` table is one generalized cylinder
//! (interface.md section 2); cylinders are numbered 0, 1, 2, ... in file order, which is the
//! `object` number of their hits.
//!
//! | key | value | default |
//! |---|---|---|
//! | `bezier` | four control points `[[x, y, z], ...]` of the cubic Bezier axis | required |
//! | `major_radius` | `[A0, A1]`, both positive | required |
//! | `minor_radius` | `[B0, B1]`, both positive | `major_radius` (circular) |
//! | `rotation` | `[theta0, theta1]`, radians, turning from `n` toward `b` | `[0, 0]` |
//! | `caps` | whether the ends are closed by planar caps | `true` |
//! | `normal_hint` | `[x, y, z]`: the frame's `n` for a straight axis | the least aligned world axis |
//! | `profile` | `3k` points `[[x, y], ...]`: a closed cubic Bezier loop (anchor, control, control per piece) in the section plane | the unit circle |
//!
//! Numbers may be written as integers. Every other key, and every other top-level table, is an
//! error for now (the renderer will add its own tables). A file with no cylinder is a valid,
//! empty scene.
//!
//! ```
//! use gencyl_render::scene::SceneDescription;
//!
//! let src = r#"
//! [[cylinder]]
//! bezier = [[0.0, 0.0, 0.0], [0.0, 0.3, 0.0], [0.2, 0.6, 0.0], [0.2, 1.0, 0.1]]
//! major_radius = [0.05, 0.03]    # [A0, A1]
//! minor_radius = [0.03, 0.02]    # [B0, B1]
//! rotation = [0.0, 3.14159]
//! caps = true
//! normal_hint = [0.0, 1.0, 0.0]
//!
//! [[cylinder]]  # a straight fiber with a rounded-square profile
//! bezier = [[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]]
//! major_radius = [0.1, 0.1]
//! profile = [[1, -1], [1.2, 0], [1, 1], [1, 1], [0, 1.2], [-1, 1],
//!            [-1, 1], [-1.2, 0], [-1, -1], [-1, -1], [0, -1.2], [1, -1]]
//! "#;
//! let scene = SceneDescription::parse(src, "hair.toml").unwrap();
//! assert_eq!(scene.cylinders.len(), 2);
//!
//! let err = SceneDescription::parse("[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.0, 0.03]\n", "s.toml")
//!     .unwrap_err();
//! assert_eq!(err.to_string(), "s.toml:3:16: major_radius must be positive at both ends, got [0.0, 0.03] (cylinder 0)");
//! ```

use std::ops::Range;
use std::path::Path;

use gencyl::section::ProfileError;
use gencyl::{BezierLoop, FiberSpec, GeneralizedCylinder, GeometryError, Hit, Ray, Section};
use glam::{DVec2, DVec3};
use rayon::prelude::*;
use serde::Deserialize;
use toml::Spanned;

use crate::bvh::Bvh;
use crate::cull::{Piece, RaySpace, level_for, piece_bounds};
use crate::error::Diagnostic;

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
    /// cylinder.
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

/// The contents of a scene file, validated, with every cylinder built.
#[derive(Clone, Debug)]
pub struct SceneDescription {
    /// The cylinders in file order: index = `object` number.
    pub cylinders: Vec<GeneralizedCylinder>,
}

// The file's shape, as serde reads it. `Spanned` keeps each value's place for the validation
// errors that come after parsing.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScene {
    #[serde(default)]
    cylinder: Vec<Spanned<RawCylinder>>,
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

/// The value of a spanned array.
fn val<T: Copy, const N: usize>(s: &Spanned<Array<T, N>>) -> [T; N] {
    s.get_ref().0
}

/// A validation failure: where (bytes of the source) and what.
type Problem = (Range<usize>, String);

impl SceneDescription {
    /// Reads and parses the scene file at `path`.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, SceneError> {
        let path = path.as_ref();
        let name = path.display().to_string();
        let bytes = std::fs::read(path).map_err(|error| SceneError::Read {
            path: name.clone(),
            error,
        })?;
        Self::parse_bytes(&bytes, &name)
    }

    /// Parses scene file bytes; `name` is the file's name for messages. Bytes that are not
    /// UTF-8 are reported at the first bad byte.
    pub fn parse_bytes(bytes: &[u8], name: &str) -> Result<Self, SceneError> {
        match std::str::from_utf8(bytes) {
            Ok(src) => Self::parse(src, name),
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

    /// Parses scene source text; `name` is the file's name for messages.
    pub fn parse(src: &str, name: &str) -> Result<Self, SceneError> {
        let raw: RawScene = toml::from_str(src).map_err(|e| {
            let span = e.span().unwrap_or(0..0);
            invalid(name, src, span, e.message().trim().to_string())
        })?;
        // Building a cylinder (its frame, its cusp check) is the costly part: do it in
        // parallel, then report the first problem in file order.
        let built: Vec<Result<GeneralizedCylinder, Problem>> = raw
            .cylinder
            .par_iter()
            .map(|c| build_cylinder(c.get_ref(), c.span()))
            .collect();
        let mut cylinders = Vec::with_capacity(built.len());
        for (i, b) in built.into_iter().enumerate() {
            match b {
                Ok(c) => cylinders.push(c),
                Err((span, msg)) => {
                    return Err(invalid(name, src, span, format!("{msg} (cylinder {i})")));
                }
            }
        }
        Ok(SceneDescription { cylinders })
    }
}

fn invalid(name: &str, src: &str, span: Range<usize>, message: String) -> SceneError {
    SceneError::Invalid(Box::new(Diagnostic::new(name, src, span, message)))
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
    let section = match &c.profile {
        Some(p) => {
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
            Section::Loop(lp)
        }
        None => Section::default(),
    };
    let spec = FiberSpec {
        bezier: bezier.map(DVec3::from_array),
        major_radius: major,
        minor_radius: minor,
        rotation,
        caps: c.caps.unwrap_or(true),
        normal_hint,
        section,
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

/// A hit on a scene: the cylinder's hit and the cylinder's number.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneHit {
    /// The hit on the cylinder.
    pub hit: Hit,
    /// The cylinder's number (its index in file order).
    pub object: u32,
}

/// Cylinders with a BVH over them, ready for ray queries.
///
/// Each cylinder enters the BVH as one or more [`Piece`]s of its axis (long, thin fibers as
/// several, so their boxes stay tight); a ray reaching a piece's box is culled by the cheap
/// [`RaySpace`] test against that piece before the exact solver runs, once per cylinder and
/// ray. Queries take a caller-owned [`Scratch`] so that none allocates once its buffers have
/// grown.
#[derive(Clone, Debug)]
pub struct Scene {
    cylinders: Vec<GeneralizedCylinder>,
    bvh: Bvh,
}

/// Buffers a query reuses: one per thread.
#[derive(Clone, Debug, Default)]
pub struct Scratch {
    hits: Vec<Hit>,
    /// Cylinders already given to the exact solver in this query.
    tested: Vec<u32>,
}

/// BVH keys: cylinder number in the high bits, the piece's heap index (< 16) in the low 4.
const PIECE_BITS: u32 = 4;
const _: () = assert!(
    2 << crate::cull::MAX_LEVEL <= 1 << PIECE_BITS,
    "piece index fits its bits"
);

impl Scene {
    /// The most cylinders a scene holds (the BVH names a cylinder's pieces in 32 bits).
    pub const MAX_CYLINDERS: usize = 1 << (32 - PIECE_BITS);

    /// Builds the BVH over `cylinders` (in parallel on the current rayon pool).
    ///
    /// # Panics
    ///
    /// With more than [`Scene::MAX_CYLINDERS`] cylinders.
    pub fn new(cylinders: Vec<GeneralizedCylinder>) -> Self {
        assert!(
            cylinders.len() <= Self::MAX_CYLINDERS,
            "at most 2^28 cylinders"
        );
        let (boxes, keys): (Vec<_>, Vec<_>) = cylinders
            .par_iter()
            .enumerate()
            .flat_map_iter(|(i, c)| {
                Piece::level_pieces(level_for(c))
                    .map(move |p| (piece_bounds(c, p), (i as u32) << PIECE_BITS | p.0))
            })
            .unzip();
        let bvh = Bvh::build_keyed(&boxes, &keys);
        Scene { cylinders, bvh }
    }

    /// The cylinders, indexed by object number.
    pub fn cylinders(&self) -> &[GeneralizedCylinder] {
        &self.cylinders
    }

    /// The BVH (over pieces of cylinders).
    pub fn bvh(&self) -> &Bvh {
        &self.bvh
    }

    /// Bytes held by the cylinders (their structs and heap data) and the BVH.
    pub fn memory_bytes(&self) -> usize {
        let cyl = self.cylinders.capacity() * std::mem::size_of::<GeneralizedCylinder>()
            + self
                .cylinders
                .iter()
                .map(|c| match c.section() {
                    Section::Loop(l) => std::mem::size_of_val(l.pieces()),
                    Section::Circle(_) => 0,
                })
                .sum::<usize>();
        cyl + self.bvh.memory_bytes()
    }

    /// Walks the BVH and hands each cylinder that may be hit within `(tmin, tmax)` to
    /// `exact(object, cylinder, tmax)` (at most once per query), which returns the new `tmax`
    /// as [`Bvh::traverse`]'s closure does.
    fn candidates(
        &self,
        ray: &Ray,
        tmin: f64,
        tmax: f64,
        tested: &mut Vec<u32>,
        mut exact: impl FnMut(u32, &GeneralizedCylinder, f64) -> f64,
    ) {
        tested.clear();
        let space = RaySpace::new(ray);
        self.bvh.traverse(ray, tmin, tmax, |key, tmax| {
            let i = key >> PIECE_BITS;
            if tested.contains(&i) {
                return tmax;
            }
            let c = &self.cylinders[i as usize];
            if !space.may_hit_piece(c, Piece(key & ((1 << PIECE_BITS) - 1)), tmin, tmax) {
                return tmax;
            }
            tested.push(i);
            exact(i, c, tmax)
        });
    }

    /// The nearest hit with `tmin < t < tmax`. Of hits at the same `t` the one of the lowest
    /// object number wins, so the answer does not depend on the BVH's layout.
    pub fn nearest_hit(
        &self,
        ray: &Ray,
        tmin: f64,
        tmax: f64,
        scratch: &mut Scratch,
    ) -> Option<SceneHit> {
        let mut best: Option<SceneHit> = None;
        let hits = &mut scratch.hits;
        self.candidates(ray, tmin, tmax, &mut scratch.tested, |i, c, _| {
            // Exclusive upper bound for the cylinder: up to and including the best t, for ties.
            let limit = best.map_or(tmax, |b| b.hit.t.next_up());
            hits.clear();
            c.intersect_all(ray, tmin, limit, hits);
            if let Some(&h) = hits.first()
                && best.is_none_or(|b| h.t < b.hit.t || (h.t == b.hit.t && i < b.object))
            {
                best = Some(SceneHit { hit: h, object: i });
            }
            best.map_or(tmax, |b| b.hit.t)
        });
        best
    }

    /// Appends every hit with `tmin < t < tmax` to `out`, sorted by `t` (then object number).
    pub fn all_hits(
        &self,
        ray: &Ray,
        tmin: f64,
        tmax: f64,
        out: &mut Vec<SceneHit>,
        scratch: &mut Scratch,
    ) {
        let start = out.len();
        let hits = &mut scratch.hits;
        self.candidates(ray, tmin, tmax, &mut scratch.tested, |i, c, tmax| {
            hits.clear();
            c.intersect_all(ray, tmin, tmax, hits);
            out.extend(hits.iter().map(|&hit| SceneHit { hit, object: i }));
            tmax
        });
        sort_hits(&mut out[start..]);
    }

    /// Whether anything is hit with `tmin < t < tmax` (stops at the first hit found).
    pub fn any_hit(&self, ray: &Ray, tmin: f64, tmax: f64, scratch: &mut Scratch) -> bool {
        let mut found = false;
        let hits = &mut scratch.hits;
        self.candidates(ray, tmin, tmax, &mut scratch.tested, |_, c, tmax| {
            hits.clear();
            c.intersect_all(ray, tmin, tmax, hits);
            found = !hits.is_empty();
            if found { f64::NEG_INFINITY } else { tmax }
        });
        found
    }
}

/// Sorts hits by `t`, then object number; a stable sort, so one cylinder's hits at equal `t`
/// stay in the cylinder's order.
pub fn sort_hits(hits: &mut [SceneHit]) {
    hits.sort_by(|a, b| a.hit.t.total_cmp(&b.hit.t).then(a.object.cmp(&b.object)));
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
            ("camera = 1\n", "s.toml:1:1: unknown field `camera`"),
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
        for (src, want) in cases {
            let got = err(src);
            assert!(
                got.starts_with(want),
                "for {src:?}\n got: {got}\nwant: {want}..."
            );
        }
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
}
