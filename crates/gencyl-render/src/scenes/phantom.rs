//! X-ray CT phantoms with exact ground truth: a twisted yarn ([`generate_yarn`]) or a
//! unidirectional composite ply ([`generate_ply`]) as a scene file of `[[strand]]` tables, with
//! the truth ([`GroundTruth`]: fiber volumes, directions, volume fraction) computed from the
//! cylinders the parsed scene holds, and a voxel label volume of the same geometry
//! ([`label_volume`], [`write_labels_tiff`]).
//!
//! **Packing.** Fibers are placed in the cross section at the start of the fiber (`z = 0` for a
//! yarn, `x = 0` for a ply): random positions, then Gauss-Seidel relaxation over a cell grid
//! that pushes every pair closer than allowed apart along the line of centres and keeps each
//! fiber inside the envelope. A fiber's solid lies within its major radius `a` of its
//! centreline (the section is an ellipse of semi-axes `a >= b` in the normal plane), so two
//! fibers are disjoint when their centrelines stay `a_i + a_j` apart; the packing keeps
//! `(a_i + a_j) (1 + GAP)`, and the gap covers the distance of the Bezier axes from the
//! analytic centrelines ([`AXIS_TOLERANCE`], measured on the parsed scene). With elliptical
//! sections the discs of the major radius are what is packed, so the reachable volume
//! fraction scales with the aspect ratio.
//!
//! **Yarn.** Fiber `i` starts at `p_i = r_i (cos theta_i, sin theta_i)` and follows the helix
//! `(Rot(k z) p_i, z)`, `k = 2 pi / pitch = tan(alpha) / R_y` (`alpha` the helix angle at the
//! yarn surface, `R_y` the yarn radius), so its helix angle is `atan(k r_i)`. Its volume is
//! `pi a_i b_i l_i` (Pappus, `l_i = L / cos(alpha_i)` its length), and
//! `R_y^2 = sum_i a_i b_i l_i / (packing L)`, solved together with the positions (the lengths
//! depend on `r_i / R_y`). Two coaxial helices of one pitch are `d(s)` apart at an axial offset
//! `s`, `d^2 = r_i^2 + r_j^2 - 2 r_i r_j cos(dtheta + k s) + s^2`, convex in `s` for
//! `r_i r_j k^2 < 1` (helix angles up to 45 degrees), minimised exactly (Newton in a bracket).
//!
//! **Migration** (coherent): in the frame turning with the twist, the whole cross section is
//! displaced by `m(p, z) = A R_y (1 - |p|^2 / R_y^2) (cos(w z + phi), sin(w z + phi))`,
//! `w = 2 pi / migration_period`, `A = migration`: the core circles by `A R_y` while the surface
//! stays, so each fiber's distance from the axis oscillates (by up to `A R_y`) with the period,
//! and neighbours move together (their offsets differ by at most `2 A` times their distance).
//! The packing then keeps the sufficient condition `(|p_j - p_i| - M_ij) / sqrt(1 + V^2) >=
//! (a_i + a_j)(1 + GAP)`, with `M_ij = A |r_i^2 - r_j^2| / R_y` the largest change of their
//! distance in the section and `V` the larger tangent of the tilt of either fiber (a point
//! moving at horizontal speed `V` along one centreline cannot come closer than `d / sqrt(1 +
//! V^2)` to a point of the other), and the result is verified by dense sampling (below).
//!
//! **Ply.** Straight fibers along `x` in `0..length`, `|y| <= width / 2`, `|z| <= thickness / 2`
//! (exact criterion: the distance of the lines). Waviness is a plane wave of misalignment:
//! `(y, z) = p_i + u sin(kappa x + g . p_i + psi)`, `|u| = waviness * mean radius` in one
//! direction for the ply, `kappa = 2 pi / waviness_period`, the phase turning by `g` across the
//! section (`|g| = kappa / 10`, a random direction: by a whole turn over ten wavelengths), so
//! neighbours wave almost together; the packing
//! keeps the condition above with `M_ij = |u| |2 sin(g . (p_j - p_i) / 2)|`, `V = |u| kappa`.
//!
//! **Verification** (every phantom, on the geometry as parsed): `eps_i`, the largest distance
//! of fiber `i`'s Bezier axis from its analytic centreline (16 samples per segment, times
//! 1.25), must stay below `AXIS_TOLERANCE a_i`; every pair that could come within `1.5 T_ij`,
//! `T_ij = a_i + a_j + eps_i + eps_j`, must keep its centrelines `T_ij` apart: exactly (helices,
//! straight fibers), or for migrating and wavy fibers by sampling `g(t) = dist(c_i(t), c_j)`
//! over one period of the pair's geometry at a step `h` with `min g >= min(samples) - G h^2 / 8`,
//! `G = |c_i''| + |c_i'|^2 / (T / 2)` (the bound on `g''`; `h <= T / (2 |c_i'|)` keeps
//! `g >= T / 2` between samples that are `>= T`).
//!
//! **Ground truth** ([`ground_truth`]): per fiber the volume `sum over its cylinders of
//! integral_0^1 (A_0 det S(u) |a'(u)| - t'(u) . M(u)) du` (`A_0` the unit section's area,
//! `S(u) = R(theta) diag(A(u), B(u))` the sweep, `M` the swept section's first moment, zero for
//! the ellipse: then Pappus' `pi A(u) B(u) |a'(u)|`), by adaptive 20-node Gauss-Legendre to
//! about `1e-13`; its length, chord direction and angle to the envelope's axis, the
//! length-weighted mean angle of its tangent to the axis, its radii.

use std::f64::consts::{PI, TAU};
use std::fmt::Write as _;
use std::path::Path;
use std::sync::OnceLock;

use gencyl::{CubicBezier, GeneralizedCylinder, Section, Strand, SweepRule};
use glam::{DVec2, DVec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::sampling::SampleRng as Rng;
use crate::scene_file::SceneDescription;

/// Relative clearance the packing keeps: centrelines at least `(a_i + a_j)(1 + GAP)` apart.
pub const GAP: f64 = 1e-3;
/// Largest distance of a fiber's Bezier axis from its analytic centreline, relative to its
/// major radius: a quarter of [`GAP`], so two fibers' deviations take at most half of it.
pub const AXIS_TOLERANCE: f64 = GAP / 4.0;
/// Most fibers a phantom holds.
pub const MAX_FIBERS: usize = 1_000_000;
/// Most voxels [`label_volume`] fills: `2^28`, 1 GiB of `u32` labels (a 512^3 volume is half
/// of it).
pub const MAX_LABEL_VOXELS: usize = 1 << 28;
/// Bezier segments per fiber at most (explicit or automatic).
pub const MAX_SEGMENTS: usize = 4096;

/// Sample points per unit of the strand parameter are spaced by `w(t) = t - BETA sin(2 pi t) /
/// (2 pi)`: `1 - BETA` times the mean spacing at the ends, where the strand's natural end
/// condition (no curvature) departs from the centreline, `1 + BETA` in the middle.
const BETA: f64 = 0.8;
/// Axis samples per segment when the deviation from the centreline is measured.
const DEVIATION_SAMPLES: usize = 16;
/// Factor on the sampled deviation (the deviation is smooth, with few extrema per segment).
const DEVIATION_SAFETY: f64 = 1.25;

/// A twisted yarn: `fibers` fibers along `z` from 0 to `length`, centred on the `z` axis.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct YarnSpec {
    /// Number of fibers (at least 1).
    pub fibers: usize,
    /// Length along `z`.
    pub length: f64,
    /// Helix angle at the yarn surface, degrees (0 = untwisted, sign = handedness; at most 45).
    pub twist_deg: f64,
    /// Target fiber volume fraction of the yarn's envelope cylinder `pi R_y^2 length`.
    pub packing: f64,
    /// Mean major radius of a fiber.
    pub radius: f64,
    /// Relative standard deviation of the major radius (normal, cut at 2.5 sigma; at most 0.3).
    pub radius_sd: f64,
    /// Mean minor / major radius (1 = round).
    pub aspect: f64,
    /// Relative standard deviation of the aspect (cut at 2.5 sigma, kept in `[0.05, 1]`).
    pub aspect_sd: f64,
    /// Total turn of the section about the fiber's own axis over its length, radians (a random
    /// sign per fiber; the start angle is random).
    pub section_twist: f64,
    /// Radial migration amplitude, a fraction of the yarn radius (0 = none, at most 0.25): the
    /// core's displacement; see the module's documentation.
    pub migration: f64,
    /// Period of the migration along `z`, length units.
    pub migration_period: f64,
    /// Bezier segments per fiber (0 = the fewest that keep the axis within
    /// [`AXIS_TOLERANCE`] of the centreline).
    pub segments: usize,
    /// Random seed: the same spec gives the same phantom.
    pub seed: u64,
    /// The material's name (letters, digits, `_`, `-`).
    pub material: String,
}

impl Default for YarnSpec {
    /// 100 round fibers of radius 0.01 at packing 0.5, 20 degrees of twist, length 1.
    fn default() -> Self {
        YarnSpec {
            fibers: 100,
            length: 1.0,
            twist_deg: 20.0,
            packing: 0.5,
            radius: 0.01,
            radius_sd: 0.1,
            aspect: 1.0,
            aspect_sd: 0.0,
            section_twist: 0.0,
            migration: 0.0,
            migration_period: 1.0,
            segments: 0,
            seed: 1,
            material: "fiber".into(),
        }
    }
}

/// A unidirectional composite ply: fibers along `x` from 0 to `length` in the cross section
/// `|y| <= width / 2`, `|z| <= thickness / 2`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PlySpec {
    /// Number of fibers, or 0 to take as many as `packing` needs (one of the two is 0).
    pub fibers: usize,
    /// Length along `x`.
    pub length: f64,
    /// Width along `y`.
    pub width: f64,
    /// Thickness along `z`.
    pub thickness: f64,
    /// Target fiber volume fraction of the box, or 0 to derive it from `fibers`. When it is
    /// given, the radii are scaled by one common factor (within one fiber's share) so the
    /// fraction is met exactly.
    pub packing: f64,
    /// Mean major radius.
    pub radius: f64,
    /// Relative standard deviation of the major radius (at most 0.3).
    pub radius_sd: f64,
    /// Mean minor / major radius.
    pub aspect: f64,
    /// Relative standard deviation of the aspect.
    pub aspect_sd: f64,
    /// Waviness amplitude as a fraction of the mean radius (0 = straight fibers).
    pub waviness: f64,
    /// Wavelength of the waviness along `x`.
    pub waviness_period: f64,
    /// Bezier segments per fiber (0 = automatic: 1 for straight fibers).
    pub segments: usize,
    /// Random seed.
    pub seed: u64,
    /// The material's name.
    pub material: String,
}

impl Default for PlySpec {
    /// A 1 x 0.4 x 0.1 ply of round fibers of radius 0.005 at packing 0.55, straight.
    fn default() -> Self {
        PlySpec {
            fibers: 0,
            length: 1.0,
            width: 0.4,
            thickness: 0.1,
            packing: 0.55,
            radius: 0.005,
            radius_sd: 0.1,
            aspect: 1.0,
            aspect_sd: 0.0,
            waviness: 0.0,
            waviness_period: 0.5,
            segments: 0,
            seed: 1,
            material: "fiber".into(),
        }
    }
}

/// A generated phantom: the scene and its truth.
#[derive(Clone, Debug)]
pub struct Phantom {
    /// A complete scene file: the material (diffuse, `xray_mu = 1`), an orthographic camera
    /// across the fibers, `[render]` with the `xray` integrator, and one `[[strand]]` per fiber.
    pub scene_toml: String,
    /// The ground truth of the parsed scene.
    pub truth: GroundTruth,
}

impl Phantom {
    /// The fiber (0-based) of each cylinder of the parsed scene, for [`label_volume`].
    pub fn fiber_of_cylinder(&self) -> Vec<u32> {
        self.truth.fiber_of_cylinder()
    }
}

/// The volume the fibers are packed into.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Envelope {
    /// A yarn's cylinder: radius `radius` about the `z` axis, `z` from 0 to `length`.
    Cylinder {
        /// The yarn radius `R_y`.
        radius: f64,
        /// Its length.
        length: f64,
    },
    /// A ply's box: `x` from 0 to `length`, `|y| <= width / 2`, `|z| <= thickness / 2`.
    Box {
        /// Along `x`.
        length: f64,
        /// Along `y`.
        width: f64,
        /// Along `z`.
        thickness: f64,
    },
}

impl Envelope {
    /// `pi R^2 L` or `L W T`.
    pub fn volume(&self) -> f64 {
        match *self {
            Envelope::Cylinder { radius, length } => PI * radius * radius * length,
            Envelope::Box {
                length,
                width,
                thickness,
            } => length * width * thickness,
        }
    }

    /// The axis the fibers run along (`z` for a yarn, `x` for a ply), through the origin.
    pub fn axis(&self) -> DVec3 {
        match self {
            Envelope::Cylinder { .. } => DVec3::Z,
            Envelope::Box { .. } => DVec3::X,
        }
    }
}

/// What is known of one fiber.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FiberTruth {
    /// Its label in [`label_volume`]: the fiber's index plus 1.
    pub label: u32,
    /// Its first cylinder in the scene.
    pub first_cylinder: usize,
    /// How many cylinders (Bezier segments) it has.
    pub cylinders: usize,
    /// Its volume.
    pub volume: f64,
    /// The length of its axis.
    pub length: f64,
    /// The unit chord of its axis, start to end.
    pub direction: [f64; 3],
    /// The chord's angle to the envelope's axis, degrees (0 to 90).
    pub angle_deg: f64,
    /// The length-weighted mean angle of the axis' tangent to the envelope's axis, degrees (a
    /// helix: its helix angle).
    pub mean_local_angle_deg: f64,
    /// Length-weighted mean distance of the axis from the envelope's axis line.
    pub mean_axis_distance: f64,
    /// Length-weighted mean major radius.
    pub major_radius: f64,
    /// Length-weighted mean minor radius.
    pub minor_radius: f64,
    /// The largest distance of the Bezier axis from the analytic centreline (generated
    /// phantoms).
    pub axis_deviation: Option<f64>,
}

/// How non-overlap was verified (generated phantoms).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PackingCheck {
    /// `exact` (helices, straight fibers) or `sampled` (migrating or wavy fibers).
    pub method: String,
    /// Pairs of fibers checked.
    pub pairs: usize,
    /// Of them, pairs certified by the closed-form lower bound alone (at least 1.5 `T_ij`).
    pub pairs_by_bound: usize,
    /// Pairs checked by dense sampling.
    pub pairs_sampled: usize,
    /// Centreline samples taken.
    pub samples: u64,
    /// The least of `(d_ij - T_ij) / (a_i + a_j)` over the checked pairs (`d_ij` the proven
    /// lower bound of the centrelines' distance): non-negative.
    pub min_clearance: f64,
    /// The largest `eps_i / a_i`.
    pub max_axis_deviation: f64,
}

/// The ground truth of a phantom, computed from the parsed scene's cylinders.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GroundTruth {
    /// Number of fibers.
    pub fiber_count: usize,
    /// Per fiber, in scene order.
    pub fibers: Vec<FiberTruth>,
    /// The sum of the fibers' volumes.
    pub total_fiber_volume: f64,
    /// The envelope.
    pub envelope: Envelope,
    /// Its volume.
    pub envelope_volume: f64,
    /// `total_fiber_volume / envelope_volume`.
    pub fiber_volume_fraction: f64,
    /// The fraction asked for (generated phantoms).
    pub target_fiber_volume_fraction: Option<f64>,
    /// A box holding every cylinder, `[min, max]`.
    pub bounds: [[f64; 3]; 2],
    /// The yarn's helix pitch `2 pi R_y / tan(alpha)` (none when untwisted or for a ply).
    pub pitch: Option<f64>,
    /// Bezier segments per fiber (generated phantoms).
    pub segments_per_fiber: Option<usize>,
    /// How non-overlap was verified (generated phantoms).
    pub packing_check: Option<PackingCheck>,
    /// The generator's input (generated phantoms).
    pub spec: Option<serde_json::Value>,
}

impl GroundTruth {
    /// The fiber (0-based) of each cylinder.
    pub fn fiber_of_cylinder(&self) -> Vec<u32> {
        let n = self
            .fibers
            .iter()
            .map(|f| f.first_cylinder + f.cylinders)
            .max()
            .unwrap_or(0);
        let mut out = vec![0; n];
        for f in &self.fibers {
            out[f.first_cylinder..f.first_cylinder + f.cylinders].fill(f.label - 1);
        }
        out
    }

    /// The truth as pretty-printed JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
    }

    /// A grid of cubic voxels of side `voxel` covering [`Self::bounds`].
    pub fn grid(&self, voxel: f64) -> Result<VoxelGrid, String> {
        VoxelGrid::covering(self.bounds[0], self.bounds[1], voxel)
    }
}

// ---------------------------------------------------------------------------------------------
// Input checks and random fiber shapes.

fn check(ok: bool, what: &str, msg: impl FnOnce() -> String) -> Result<(), String> {
    if ok {
        Ok(())
    } else {
        Err(format!("{what}: {}", msg()))
    }
}

fn positive(what: &str, name: &str, x: f64) -> Result<(), String> {
    check(x > 0.0 && x.is_finite(), what, || {
        format!("{name} must be positive and finite, got {x}")
    })
}

fn in_range(what: &str, name: &str, x: f64, lo: f64, hi: f64) -> Result<(), String> {
    check(x >= lo && x <= hi, what, || {
        format!("{name} must be in [{lo}, {hi}], got {x}")
    })
}

fn check_material(what: &str, name: &str) -> Result<(), String> {
    check(
        !name.is_empty()
            && name.len() <= 64
            && name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-'),
        what,
        || format!("material must be 1 to 64 letters, digits, `_` or `-`, got {name:?}"),
    )
}

/// Standard normal, cut at 2.5 sigma (Box-Muller).
fn normal(rng: &mut Rng) -> f64 {
    loop {
        let (u1, u2) = (rng.uniform(), rng.uniform());
        if u1 > 0.0 {
            let z = (-2.0 * u1.ln()).sqrt() * (TAU * u2).cos();
            if z.abs() <= 2.5 {
                return z;
            }
        }
    }
}

/// One fiber's section: major radius `a`, minor `b`, section rotation at start and end.
#[derive(Clone, Copy, Debug)]
struct Shape {
    a: f64,
    b: f64,
    twist: [f64; 2],
}

struct ShapeParams {
    radius: f64,
    radius_sd: f64,
    aspect: f64,
    aspect_sd: f64,
    section_twist: f64,
}

impl ShapeParams {
    /// Checks the shape settings a yarn and a ply share (`w` names which).
    fn validate(&self, w: &str) -> Result<(), String> {
        positive(w, "radius", self.radius)?;
        in_range(w, "radius_sd", self.radius_sd, 0.0, 0.3)?;
        check(self.aspect > 0.0 && self.aspect <= 1.0, w, || {
            format!("aspect must be in (0, 1], got {}", self.aspect)
        })?;
        in_range(w, "aspect_sd", self.aspect_sd, 0.0, 0.3)?;
        in_range(w, "section_twist", self.section_twist, -1e5, 1e5)
    }
}

/// Checks the segment count and material name a yarn and a ply share.
fn check_segments_and_material(w: &str, segments: usize, material: &str) -> Result<(), String> {
    check(segments <= MAX_SEGMENTS, w, || {
        format!("segments must be at most {MAX_SEGMENTS}, got {segments}")
    })?;
    check_material(w, material)
}

fn draw_shape(p: &ShapeParams, rng: &mut Rng) -> Shape {
    let a = p.radius * (1.0 + p.radius_sd * normal(rng));
    let e = (p.aspect * (1.0 + p.aspect_sd * normal(rng))).clamp(0.05, 1.0);
    let t0 = rng.range(0.0, TAU);
    let sign = if rng.uniform() < 0.5 { -1.0 } else { 1.0 };
    Shape {
        a,
        b: a * e,
        twist: [t0, t0 + sign * p.section_twist],
    }
}

// ---------------------------------------------------------------------------------------------
// Analytic centrelines.

/// `v` turned by `angle`.
fn rot(v: DVec2, angle: f64) -> DVec2 {
    let (s, c) = angle.sin_cos();
    DVec2::new(c * v.x - s * v.y, s * v.x + c * v.y)
}

/// `v` turned by a quarter turn.
fn perp(v: DVec2) -> DVec2 {
    DVec2::new(-v.y, v.x)
}

/// A fiber's centreline as a function of the axis coordinate `t` (`z` for a yarn, `x` for a
/// ply), defined for every `t` (the fiber is its part over `[0, length]`).
#[derive(Clone, Copy, Debug)]
enum Centreline {
    /// `(Rot(k t)(p + c e(w t + phase)), t)`, `e(x) = (cos x, sin x)`.
    Yarn {
        p: DVec2,
        k: f64,
        c: f64,
        w: f64,
        phase: f64,
    },
    /// `(t, p + u sin(kappa t + psi))`.
    Ply {
        p: DVec2,
        u: DVec2,
        kappa: f64,
        psi: f64,
    },
}

impl Centreline {
    fn point(&self, t: f64) -> DVec3 {
        match *self {
            Centreline::Yarn { p, k, c, w, phase } => {
                let (s, co) = (w * t + phase).sin_cos();
                let h = rot(p + c * DVec2::new(co, s), k * t);
                DVec3::new(h.x, h.y, t)
            }
            Centreline::Ply { p, u, kappa, psi } => {
                let q = p + u * (kappa * t + psi).sin();
                DVec3::new(t, q.x, q.y)
            }
        }
    }

    /// `(c'(t), c''(t))`.
    fn derivatives(&self, t: f64) -> (DVec3, DVec3) {
        match *self {
            Centreline::Yarn { p, k, c, w, phase } => {
                let (s, co) = (w * t + phase).sin_cos();
                let e = DVec2::new(co, s);
                let q = p + c * e;
                let q1 = c * w * perp(e);
                let q2 = -c * w * w * e;
                let h1 = rot(k * perp(q) + q1, k * t);
                let h2 = rot(-k * k * q + 2.0 * k * perp(q1) + q2, k * t);
                (DVec3::new(h1.x, h1.y, 1.0), DVec3::new(h2.x, h2.y, 0.0))
            }
            Centreline::Ply { u, kappa, psi, .. } => {
                let (s, co) = (kappa * t + psi).sin_cos();
                let d1 = u * kappa * co;
                let d2 = -u * kappa * kappa * s;
                (DVec3::new(1.0, d1.x, d1.y), DVec3::new(0.0, d2.x, d2.y))
            }
        }
    }

    /// A bound on the centreline's speed across the axis, `|c'| <= sqrt(1 + V^2)`.
    fn tilt_bound(&self) -> f64 {
        match *self {
            Centreline::Yarn { p, k, c, w, .. } => k.abs() * (p.length() + c) + c * w.abs(),
            Centreline::Ply { u, kappa, .. } => u.length() * kappa,
        }
    }

    /// A bound on `|c''|`.
    fn accel_bound(&self) -> f64 {
        match *self {
            Centreline::Yarn { p, k, c, w, .. } => {
                k * k * (p.length() + c) + 2.0 * k.abs() * c * w.abs() + c * w * w
            }
            Centreline::Ply { u, kappa, .. } => u.length() * kappa * kappa,
        }
    }

    fn axis_coord(&self, x: DVec3) -> f64 {
        match self {
            Centreline::Yarn { .. } => x.z,
            Centreline::Ply { .. } => x.x,
        }
    }

    /// The period in `t` of a pair's relative geometry (both fibers share it), if it varies.
    fn pair_period(&self) -> Option<f64> {
        match *self {
            Centreline::Yarn { c, w, .. } if c != 0.0 && w != 0.0 => Some(TAU / w.abs()),
            Centreline::Ply { u, kappa, .. } if u != DVec2::ZERO => Some(TAU / kappa),
            _ => None,
        }
    }

    /// The distance from `x` to the centreline, searched over `t0 + s`, `|s| <= |c(t0) - x|`,
    /// where `|c(t) - x|^2` is convex (the caller's condition): safeguarded Newton on its
    /// derivative.
    fn distance_from(&self, x: DVec3, t0: f64) -> f64 {
        let s0 = (self.point(t0) - x).length();
        let (mut lo, mut hi, mut s) = (-s0, s0, 0.0);
        for _ in 0..64 {
            let (d1, d2) = self.derivatives(t0 + s);
            let e = self.point(t0 + s) - x;
            let g = e.dot(d1);
            let dg = d1.length_squared() + e.dot(d2);
            if g > 0.0 {
                hi = s;
            } else {
                lo = s;
            }
            let mut next = s - g / dg;
            if !(next > lo && next < hi) {
                next = 0.5 * (lo + hi);
            }
            let done = (next - s).abs() <= 1e-15 * (1.0 + t0.abs() + s0);
            s = next;
            if done || g == 0.0 {
                break;
            }
        }
        (self.point(t0 + s) - x).length()
    }

    /// The curve's samples for a strand of `n` segments over `[0, len]`: `t_j = len w(j / n)`.
    fn samples(&self, len: f64, n: usize) -> Vec<DVec3> {
        (0..=n)
            .map(|j| {
                let u = j as f64 / n as f64;
                let t = if j == n {
                    len
                } else {
                    len * (u - BETA * (TAU * u).sin() / TAU)
                };
                self.point(t)
            })
            .collect()
    }

    /// Whether it is a straight line.
    fn is_straight(&self) -> bool {
        match *self {
            Centreline::Yarn { p, k, c, .. } => (k == 0.0 || p == DVec2::ZERO) && c == 0.0,
            Centreline::Ply { u, .. } => u == DVec2::ZERO,
        }
    }
}

/// The Bezier segments a strand through `points` gets (as the scene file builds them).
fn strand_segments(points: &[DVec3]) -> Vec<CubicBezier> {
    Strand {
        points: Strand::interpolating_control_points(points),
        radius: [1.0, 1.0],
        ellipticity: 1.0,
        twist: [0.0, 0.0],
        section: Section::default(),
    }
    .bezier_segments()
}

/// The largest distance of the segments from the centreline (sampled, times the safety
/// factor).
fn axis_deviation(path: &Centreline, segs: &[CubicBezier]) -> f64 {
    let mut worst = 0.0f64;
    for seg in segs {
        for m in 0..=DEVIATION_SAMPLES {
            let x = seg.point(m as f64 / DEVIATION_SAMPLES as f64);
            worst = worst.max(path.distance_from(x, path.axis_coord(x)));
        }
    }
    worst * DEVIATION_SAFETY
}

/// Arc length of the centreline over `[0, len]`.
fn arc_length(path: &Centreline, len: f64) -> f64 {
    let period = match *path {
        Centreline::Yarn { w, c, .. } if c != 0.0 && w != 0.0 => TAU / w.abs(),
        Centreline::Ply { u, kappa, .. } if u != DVec2::ZERO => TAU / kappa,
        _ => return len * path.derivatives(0.0).0.length(),
    };
    let panels = ((len / (0.25 * period)).ceil() as usize).clamp(1, 1 << 20);
    let h = len / panels as f64;
    (0..panels)
        .map(|i| {
            gauss(i as f64 * h, (i + 1) as f64 * h, |t| {
                [path.derivatives(t).0.length()]
            })[0]
        })
        .sum()
}

// ---------------------------------------------------------------------------------------------
// Packing in the cross section.

/// The least distance between the coaxial helices `(Rot(k t) r1 e(0), t)` and
/// `(Rot(k t) r2 e(dth), t)`: `min_s f(s)`, `f = (r1 - r2)^2 + 4 r1 r2 sin^2((dth + k s)/2) +
/// s^2`, convex for `r1 r2 k^2 < 1`; safeguarded Newton on `f'/2 = s + r1 r2 k sin(dth + k s)`
/// in `[-sqrt f(0), sqrt f(0)]` (where the minimum lies, as `f >= s^2`).
fn helix_distance(r1: f64, r2: f64, dth: f64, k: f64) -> f64 {
    let dth = dth - TAU * (dth / TAU).round();
    let f = |s: f64| {
        let h = (0.5 * (dth + k * s)).sin();
        (r1 - r2) * (r1 - r2) + 4.0 * r1 * r2 * h * h + s * s
    };
    let big = f(0.0).sqrt();
    let (mut lo, mut hi, mut s) = (-big, big, 0.0);
    for _ in 0..100 {
        let x = dth + k * s;
        let g = s + r1 * r2 * k * x.sin();
        let dg = 1.0 + r1 * r2 * k * k * x.cos();
        if g > 0.0 {
            hi = s;
        } else {
            lo = s;
        }
        let mut next = s - g / dg;
        if !(next > lo && next < hi) {
            next = 0.5 * (lo + hi);
        }
        let done = (next - s).abs() <= 1e-16 * big || g == 0.0;
        s = next;
        if done {
            break;
        }
    }
    f(s).sqrt()
}

/// How fibers are placed: the envelope and the pair criterion.
#[derive(Clone, Debug)]
enum Layout {
    /// A yarn of radius `r`, twist wavenumber `k`, migration amplitude `mig` (fraction of `r`)
    /// with angular frequency `w`.
    Yarn { r: f64, k: f64, mig: f64, w: f64 },
    /// A ply of half width `hw`, half thickness `ht`, waviness `u` (common), wavenumber
    /// `kappa`, phase gradient `g`.
    Ply {
        hw: f64,
        ht: f64,
        u: DVec2,
        kappa: f64,
        g: DVec2,
    },
}

struct Packer<'a> {
    a: &'a [f64],
    layout: Layout,
    /// Whether fibers are kept inside the envelope.
    confined: bool,
}

impl Packer<'_> {
    /// The migration offset of a fiber starting at `p`: `A R (1 - |p|^2 / R^2)`.
    fn migration(&self, p: DVec2) -> f64 {
        match self.layout {
            Layout::Yarn { r, mig, .. } => mig * r * (1.0 - p.length_squared() / (r * r)).max(0.0),
            Layout::Ply { .. } => 0.0,
        }
    }

    /// `V`: a bound on the tangent of the tilt of a fiber starting at `p`.
    fn tilt(&self, p: DVec2) -> f64 {
        match self.layout {
            Layout::Yarn { k, w, .. } => {
                let c = self.migration(p);
                k.abs() * (p.length() + c) + c * w.abs()
            }
            Layout::Ply { u, kappa, .. } => u.length() * kappa,
        }
    }

    /// Whether the criterion is exact (helices without migration, straight fibers).
    fn exact(&self) -> bool {
        match self.layout {
            Layout::Yarn { mig, .. } => mig == 0.0,
            Layout::Ply { u, .. } => u == DVec2::ZERO,
        }
    }

    /// `M_ij`: the largest change of the pair's distance in the section.
    fn strain(&self, pi: DVec2, pj: DVec2) -> f64 {
        match self.layout {
            Layout::Yarn { .. } => (self.migration(pi) - self.migration(pj)).abs(),
            Layout::Ply { u, g, .. } => u.length() * (2.0 * (0.5 * g.dot(pj - pi)).sin()).abs(),
        }
    }

    /// A lower bound of the distance of the two centrelines (exact when [`Self::exact`]).
    fn distance(&self, pi: DVec2, pj: DVec2) -> f64 {
        let d = (pj - pi).length();
        match self.layout {
            Layout::Yarn { k, mig: 0.0, .. } => {
                let (ri, rj) = (pi.length(), pj.length());
                if ri * rj * k * k < 0.9 {
                    helix_distance(ri, rj, pj.to_angle() - pi.to_angle(), k)
                } else {
                    d / (1.0 + k * k * ri.min(rj).powi(2)).sqrt()
                }
            }
            _ => {
                let v = self.tilt(pi).min(self.tilt(pj));
                ((d - self.strain(pi, pj)) / (1.0 + v * v).sqrt()).max(0.0)
            }
        }
    }

    /// How much farther apart (in the section) the pair must move to keep `need` between
    /// centrelines; 0 if it does.
    fn push(&self, pi: DVec2, pj: DVec2, need: f64) -> f64 {
        let d = (pj - pi).length();
        match self.layout {
            Layout::Yarn { k, mig: 0.0, .. } => {
                let (ri, rj) = (pi.length(), pj.length());
                let s2 = 1.0 + k * k * ri.min(rj).powi(2);
                if d * d >= need * need * s2 {
                    return 0.0;
                }
                if ri * rj * k * k >= 0.9 {
                    return need * s2.sqrt() - d;
                }
                let m = helix_distance(ri, rj, pj.to_angle() - pi.to_angle(), k);
                if m >= need {
                    0.0
                } else if m > 1e-3 * need {
                    (need - m) * d / m
                } else {
                    need * s2.sqrt() - d
                }
            }
            Layout::Ply { u, .. } if u == DVec2::ZERO => (need - d).max(0.0),
            _ => {
                let v = self.tilt(pi).min(self.tilt(pj));
                (need * (1.0 + v * v).sqrt() + self.strain(pi, pj) - d).max(0.0)
            }
        }
    }

    /// The farthest apart (in the section) two fibers can be and still violate `factor` times
    /// the packing distance.
    fn range(&self, factor: f64) -> f64 {
        let amax = self.a.iter().fold(0.0f64, |m, &a| m.max(a));
        let need = 2.0 * amax * (1.0 + GAP) * factor;
        match self.layout {
            Layout::Yarn { r, k, mig, w } => {
                let reach = if self.confined { r } else { 4.0 * r };
                let v = k.abs() * reach + mig * r * w.abs();
                need * (1.0 + v * v).sqrt() / (1.0 - 2.0 * mig)
            }
            Layout::Ply { u, kappa, g, .. } => {
                let v = u.length() * kappa;
                need * (1.0 + v * v).sqrt() / (1.0 - u.length() * g.length())
            }
        }
    }

    /// `p` moved into fiber `i`'s allowed region.
    fn confine(&self, i: usize, p: DVec2) -> DVec2 {
        if !self.confined {
            return p;
        }
        let a = self.a[i];
        match self.layout {
            Layout::Yarn { r, mig, .. } => {
                let m = yarn_reach(a / r, mig) * r;
                let l = p.length();
                if l > m { p * (m / l) } else { p }
            }
            Layout::Ply { hw, ht, u, .. } => {
                let (my, mz) = (hw - a - u.x.abs(), ht - a - u.y.abs());
                DVec2::new(p.x.clamp(-my, my), p.y.clamp(-mz, mz))
            }
        }
    }
}

/// The largest `rho = |p| / R` with `rho + A (1 - rho^2) + a / R <= 1`: a fiber of relative
/// radius `a_rel` starting there stays in the yarn while it migrates (`A < 1/2`).
fn yarn_reach(a_rel: f64, mig: f64) -> f64 {
    if mig == 0.0 {
        return (1.0 - a_rel).max(0.0);
    }
    let c = 1.0 - mig - a_rel;
    let disc = (1.0 - 4.0 * mig * c).max(0.0);
    ((1.0 - disc.sqrt()) / (2.0 * mig)).max(0.0)
}

/// Points sorted into square cells.
struct CellGrid {
    min: DVec2,
    inv: f64,
    nx: usize,
    ny: usize,
    start: Vec<u32>,
    items: Vec<u32>,
}

impl CellGrid {
    fn new(pos: &[DVec2], cell: f64) -> Self {
        let (mut lo, mut hi) = (DVec2::INFINITY, DVec2::NEG_INFINITY);
        for p in pos {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        let ext = (hi - lo).max(DVec2::ZERO);
        let mut cell = cell.max(1e-300);
        let cap = 4 * pos.len() + 64;
        while ((ext.x / cell) as usize + 1).saturating_mul((ext.y / cell) as usize + 1) > cap {
            cell *= 1.5;
        }
        let (nx, ny) = ((ext.x / cell) as usize + 1, (ext.y / cell) as usize + 1);
        let mut g = CellGrid {
            min: lo,
            inv: 1.0 / cell,
            nx,
            ny,
            start: vec![0; nx * ny + 1],
            items: vec![0; pos.len()],
        };
        for p in pos {
            let (x, y) = g.cell(*p);
            g.start[y * nx + x + 1] += 1;
        }
        for c in 0..nx * ny {
            g.start[c + 1] += g.start[c];
        }
        let mut fill = g.start.clone();
        for (i, p) in pos.iter().enumerate() {
            let (x, y) = g.cell(*p);
            let c = y * nx + x;
            g.items[fill[c] as usize] = i as u32;
            fill[c] += 1;
        }
        g
    }

    fn cell(&self, p: DVec2) -> (usize, usize) {
        let q = (p - self.min) * self.inv;
        (
            (q.x.max(0.0) as usize).min(self.nx - 1),
            (q.y.max(0.0) as usize).min(self.ny - 1),
        )
    }

    /// Every point in the 3 x 3 cells around `p`'s cell.
    fn near(&self, p: DVec2, mut f: impl FnMut(usize)) {
        let (x, y) = self.cell(p);
        for cy in y.saturating_sub(1)..=(y + 1).min(self.ny - 1) {
            let row = cy * self.nx;
            let (c0, c1) = (row + x.saturating_sub(1), row + (x + 1).min(self.nx - 1));
            for &i in &self.items[self.start[c0] as usize..self.start[c1 + 1] as usize] {
                f(i as usize);
            }
        }
    }
}

/// How a relaxation ended.
struct Relaxed {
    ok: bool,
    passes: usize,
    left: usize,
}

/// Extra distance, relative, a relaxation pushes a pair apart beyond the least it needs, so that
/// a pair once cleared is not caught again by its neighbours' small moves.
const RELAX_EXTRA: f64 = 2e-4;

/// Gauss-Seidel relaxation: each pass visits every pair in neighbouring cells once and moves a
/// pair that is too close apart (to [`RELAX_EXTRA`] beyond what it needs), half the way each,
/// then back into the envelope. Ends when a pass moves nothing (every pair clear), after
/// `max_passes`, or when the summed shortfall has not fallen by 2% in 400 passes.
fn relax(pos: &mut [DVec2], packer: &Packer, max_passes: usize) -> Relaxed {
    let n = pos.len();
    let need: Vec<f64> = packer.a.iter().map(|a| a * (1.0 + GAP)).collect();
    let range = packer.range(1.0 + RELAX_EXTRA);
    let (mut best, mut since) = (f64::INFINITY, 0);
    let mut moves = 0;
    let mut cands = Vec::new();
    for pass in 1..=max_passes {
        let grid = CellGrid::new(pos, range);
        moves = 0;
        let mut short = 0.0;
        for i in 0..n {
            cands.clear();
            grid.near(pos[i], |j| {
                if j > i {
                    cands.push(j)
                }
            });
            for &j in &cands {
                let want = need[i] + need[j];
                let v = packer.push(pos[i], pos[j], want);
                if v <= 0.0 {
                    continue;
                }
                short += v / want;
                let v = packer
                    .push(pos[i], pos[j], want * (1.0 + RELAX_EXTRA))
                    .max(v);
                let d = pos[j] - pos[i];
                let dir = d.try_normalize().unwrap_or_else(|| {
                    let h = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ j as u64;
                    DVec2::from_angle((h % 6283) as f64 * 1e-3)
                });
                let step = 0.5 * v * dir;
                pos[i] = packer.confine(i, pos[i] - step);
                pos[j] = packer.confine(j, pos[j] + step);
                moves += 1;
            }
        }
        if moves == 0 {
            return Relaxed {
                ok: true,
                passes: pass,
                left: 0,
            };
        }
        if short < 0.98 * best {
            (best, since) = (short, 0);
        } else {
            since += 1;
            if since >= 400 {
                return Relaxed {
                    ok: false,
                    passes: pass,
                    left: moves,
                };
            }
        }
    }
    Relaxed {
        ok: false,
        passes: max_passes,
        left: moves,
    }
}

/// The message for a packing the relaxation cannot reach, with the largest packing
/// `target f^2` (`f = 0.98^k`) at which the fibers, shrunk by `f` where they are, do relax
/// without overlap (starting where discs of the major radii would cover 85% of the section).
fn unreachable(
    what: &str,
    out: &Relaxed,
    pos: &[DVec2],
    packer: &Packer,
    shapes: &[Shape],
    target: f64,
    by_count: bool,
) -> String {
    let n = pos.len();
    let discs = target * shapes.iter().map(|s| s.a * s.a).sum::<f64>()
        / shapes.iter().map(|s| s.a * s.b).sum::<f64>();
    let mut reached = None;
    for k in 1..=200 {
        let f = 0.98f64.powi(k);
        if f * f * target < 0.01 {
            break;
        }
        if f * f * discs > 0.85 {
            continue;
        }
        let a: Vec<f64> = packer.a.iter().map(|a| a * f).collect();
        let shrunk = Packer {
            a: &a,
            layout: packer.layout.clone(),
            confined: true,
        };
        let mut p: Vec<DVec2> = pos
            .iter()
            .enumerate()
            .map(|(i, p)| shrunk.confine(i, *p))
            .collect();
        if relax(&mut p, &shrunk, max_passes(n)).ok {
            reached = Some(f * f * target);
            break;
        }
    }
    let head = format!(
        "{what}: packing {target:.4} is not reachable with these {n} fibers ({} pairs still too \
         close after {} relaxation passes)",
        out.left, out.passes
    );
    match reached {
        Some(r) if by_count => format!(
            "{head}; the relaxation reaches packing {r:.3} with fibers this size: try at most {} \
             fibers",
            (n as f64 * r / target).floor()
        ),
        Some(r) => format!(
            "{head}; the relaxation reaches packing {r:.3} with these fibers: try a packing of \
             {:.2} or lower",
            (r * 100.0).floor() / 100.0
        ),
        None => format!("{head}; try a much lower packing"),
    }
}

/// Passes a relaxation may take.
fn max_passes(n: usize) -> usize {
    4000 + 4 * (n as f64).sqrt() as usize
}

// ---------------------------------------------------------------------------------------------
// Segments, verification, scene text.

/// Candidate segment counts.
const SEGMENT_STEPS: [usize; 22] = [
    1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 768, 1024, 2048, 4096,
];

/// The deviations of every fiber's axis at `n` segments, relative to its radius.
fn deviations(paths: &[Centreline], a: &[f64], len: f64, n: usize) -> Vec<f64> {
    paths
        .par_iter()
        .zip(a.par_iter())
        .map(|(p, a)| axis_deviation(p, &strand_segments(&p.samples(len, n))) / a)
        .collect()
}

/// The segment count: `requested`, checked, or the fewest of [`SEGMENT_STEPS`] that keep every
/// fiber's axis within [`AXIS_TOLERANCE`] (searched on the 16 most bent fibers and 16 others,
/// then checked on all).
fn choose_segments(
    what: &str,
    paths: &[Centreline],
    a: &[f64],
    len: f64,
    requested: usize,
) -> Result<usize, String> {
    let worst = |n: usize| {
        deviations(paths, a, len, n)
            .into_iter()
            .fold(0.0f64, f64::max)
    };
    if paths.iter().all(Centreline::is_straight) {
        return Ok(requested.max(1));
    }
    let mut order: Vec<usize> = (0..paths.len()).collect();
    order.sort_by(|&i, &j| {
        (paths[j].accel_bound() + paths[j].tilt_bound())
            .total_cmp(&(paths[i].accel_bound() + paths[i].tilt_bound()))
    });
    let step = (paths.len() / 16).max(1);
    let mut probe: Vec<usize> = order.iter().take(16).copied().collect();
    probe.extend((0..paths.len()).step_by(step).take(16));
    let probe_paths: Vec<Centreline> = probe.iter().map(|&i| paths[i]).collect();
    let probe_a: Vec<f64> = probe.iter().map(|&i| a[i]).collect();
    let fewest = || -> Option<usize> {
        let start = SEGMENT_STEPS.iter().position(|&n| n >= 2).unwrap_or(0);
        let mut it = SEGMENT_STEPS[start..].iter().copied().filter(|&n| {
            deviations(&probe_paths, &probe_a, len, n)
                .into_iter()
                .fold(0.0f64, f64::max)
                <= 0.8 * AXIS_TOLERANCE
        });
        let mut n = it.next()?;
        while worst(n) > AXIS_TOLERANCE {
            n = it.next()?;
        }
        Some(n)
    };
    if requested > 0 {
        let w = worst(requested);
        if w <= AXIS_TOLERANCE {
            return Ok(requested);
        }
        let hint = fewest().map_or_else(
            || format!("more than {MAX_SEGMENTS}"),
            |n| format!("at least {n}"),
        );
        return Err(format!(
            "{what}: with {requested} segments a fiber's axis strays {w:.2e} of its radius from \
             the centreline (at most {AXIS_TOLERANCE:.1e}); use {hint} segments (or 0 for automatic)"
        ));
    }
    fewest().ok_or_else(|| {
        format!(
            "{what}: even {MAX_SEGMENTS} segments per fiber do not keep the axis within \
             {AXIS_TOLERANCE:.1e} of the radius of the centreline; make the fibers thicker or \
             the curves gentler"
        )
    })
}

/// A lower bound of `min_t dist(c_i(t), c_j)` over one period of the pair's geometry, by
/// samples at step `h` (see the module's documentation), or the first sample below `need`.
/// `Err` when the bound's conditions do not hold.
fn sampled_distance(
    pi: &Centreline,
    pj: &Centreline,
    span: f64,
    need: f64,
    margin: f64,
) -> Result<(f64, u64), String> {
    let (vi, vj) = (pi.tilt_bound(), pj.tilt_bound());
    let (ai, aj) = (pi.accel_bound(), pj.accel_bound());
    let speed2 = 1.0 + vi * vi;
    let g_bound = ai + speed2 / (0.5 * need);
    let h = (need / (2.0 * speed2.sqrt())).min((8.0 * margin / g_bound).sqrt());
    let m = (span / h).ceil().max(1.0);
    if !(m <= 4e6) {
        return Err(format!(
            "the pair needs {m:.0} samples (more than 4e6) to be verified"
        ));
    }
    let m = m as usize;
    let h = span / m as f64;
    let reach = 1.0 + (1.0 + vj * vj).sqrt();
    let (mut lower, mut prev) = (f64::INFINITY, f64::NAN);
    for k in 0..=m {
        let t = k as f64 * h;
        let x = pi.point(t);
        let s0 = (pj.point(t) - x).length();
        if !(reach * s0 * aj < 1.0) {
            return Err(format!(
                "the centrelines bend too much for the distance search (|c''| {aj:.3e} at distance {s0:.3e})"
            ));
        }
        let g = pj.distance_from(x, t);
        if g < need {
            return Ok((g, k as u64 + 1));
        }
        if k > 0 {
            lower = lower.min(prev.min(g) - g_bound * h * h / 8.0);
        } else {
            lower = g;
        }
        prev = g;
    }
    Ok((lower, m as u64 + 1))
}

/// Checks every pair of fibers that could come close (see the module's documentation).
fn verify(
    what: &str,
    packer: &Packer,
    pos: &[DVec2],
    paths: &[Centreline],
    eps: &[f64],
    len: f64,
) -> Result<PackingCheck, String> {
    let a = packer.a;
    let emax = eps.iter().fold(0.0f64, |m, &e| m.max(e));
    let grid = CellGrid::new(pos, packer.range(1.5) + 2.0 * emax);
    let mut pairs = Vec::new();
    for (i, &p) in pos.iter().enumerate() {
        grid.near(p, |j| {
            if j > i {
                pairs.push((i, j))
            }
        });
    }
    let exact = packer.exact();
    let results: Vec<Result<(f64, u8, u64), String>> = pairs
        .par_iter()
        .map(|&(i, j)| {
            let need = a[i] + a[j] + eps[i] + eps[j];
            let bound = packer.distance(pos[i], pos[j]);
            if exact || bound >= 1.5 * need {
                return Ok((bound - need, u8::from(!exact), 0));
            }
            let span = paths[i].pair_period().map_or(len, |p| p.min(len));
            let margin =
                (0.5 * ((a[i] + a[j]) * (1.0 + GAP) - need)).max(0.05 * GAP * (a[i] + a[j]));
            let (d, samples) = sampled_distance(&paths[i], &paths[j], span, need, margin)
                .map_err(|e| format!("{what}: fibers {i} and {j}: {e}"))?;
            Ok((d - need, 2, samples))
        })
        .collect();
    let mut check = PackingCheck {
        method: if exact { "exact" } else { "sampled" }.into(),
        pairs: pairs.len(),
        pairs_by_bound: 0,
        pairs_sampled: 0,
        samples: 0,
        min_clearance: f64::INFINITY,
        max_axis_deviation: eps.iter().zip(a).fold(0.0f64, |m, (e, a)| m.max(e / a)),
    };
    for (r, &(i, j)) in results.into_iter().zip(&pairs) {
        let (clear, kind, samples) = r?;
        let rel = clear / (a[i] + a[j]);
        if !(rel >= 0.0) {
            return Err(format!(
                "{what}: fibers {i} and {j} come within {:.3e} of touching (centrelines closer \
                 than their radii and axis deviations allow): the packing failed",
                -clear
            ));
        }
        check.min_clearance = check.min_clearance.min(rel);
        match kind {
            1 => check.pairs_by_bound += 1,
            2 => check.pairs_sampled += 1,
            _ => {}
        }
        check.samples += samples;
    }
    Ok(check)
}

/// A number as TOML (shortest round trip).
fn num(x: f64) -> String {
    format!("{x:?}")
}

fn vec3(v: DVec3) -> String {
    format!("[{}, {}, {}]", num(v.x), num(v.y), num(v.z))
}

/// The scene's head: comments, camera, render settings, material.
fn scene_head(
    comment: &str,
    position: DVec3,
    look_at: DVec3,
    up: DVec3,
    view: [f64; 2],
    material: &str,
) -> String {
    let scale = 512.0 / view[0].max(view[1]);
    let res = view.map(|v| ((v * scale).ceil() as u32).clamp(8, 4096));
    let mut s = String::new();
    for line in comment.lines() {
        let _ = writeln!(s, "# {line}");
    }
    let _ = write!(
        s,
        "\n[camera]\ntype = \"orthographic\"\nposition = {}\nlook_at = {}\nup = {}\n\
         view_height = {}\nresolution = [{}, {}]\n\n[render]\nintegrator = \"xray\"\nspp = 1\n\n\
         [material.{material}]\ntype = \"diffuse\"\nxray_mu = 1.0\n",
        vec3(position),
        vec3(look_at),
        vec3(up),
        num(view[1]),
        res[0],
        res[1]
    );
    s
}

/// Most detector pixels each way in a phantom's `[ct]` table.
const CT_MAX_PIXELS: f64 = 1024.0;

/// A parallel-beam `[ct]` scan about `axis` through `center`: 180 views over 180 degrees, a
/// detector spanning `extent = [across, along]` (along the axis), pixels of `pixel` (about a
/// third of the mean minor radius: a fiber six pixels across) grown so that neither side
/// passes [`CT_MAX_PIXELS`].
fn ct_table(axis: DVec3, center: DVec3, extent: [f64; 2], pixel: f64) -> String {
    let pixel = pixel.max(extent[0].max(extent[1]) / CT_MAX_PIXELS);
    let [columns, rows] = extent.map(|e| ((e / pixel).ceil() as u32).max(1));
    format!(
        "\n# A CT scan of the phantom (gencyl ct): parallel beam about its axis.\n[ct]\n\
         beam = \"parallel\"\ndetector = [{columns}, {rows}]\npixel = [{0}, {0}]\nviews = 180\n\
         arc = 180\naxis = {1}\ncenter = {2}\nsamples = 4\nquantity = \"absorbance\"\n",
        num(pixel),
        vec3(axis),
        vec3(center)
    )
}

fn push_strand(s: &mut String, points: &[DVec3], shape: &Shape, material: &str) {
    s.push_str("\n[[strand]]\npoints = [");
    for (i, p) in points.iter().enumerate() {
        if i > 0 {
            s.push_str(", ");
        }
        s.push_str(&vec3(*p));
    }
    let _ = writeln!(
        s,
        "]\nradius = [{0}, {0}]\nellipticity = {1}\ntwist = [{2}, {3}]\nmaterial = \"{material}\"",
        num(shape.a),
        num(shape.b / shape.a),
        num(shape.twist[0]),
        num(shape.twist[1])
    );
}

/// Parses the scene, checks the axes against the centrelines and the pairs, and computes the
/// truth.
#[allow(clippy::too_many_arguments)]
fn finish(
    what: &str,
    scene_toml: String,
    shapes: &[Shape],
    paths: &[Centreline],
    packer: &Packer,
    pos: &[DVec2],
    segments: usize,
    envelope: Envelope,
    len: f64,
    target: f64,
    pitch: Option<f64>,
    spec: serde_json::Value,
) -> Result<Phantom, String> {
    if scene_toml.len() as u64 > crate::limits::MAX_SCENE_FILE {
        return Err(format!(
            "{what}: the scene would take {} bytes, more than the {} a scene file may have; \
             use fewer fibers or segments",
            scene_toml.len(),
            crate::limits::MAX_SCENE_FILE
        ));
    }
    let scene = SceneDescription::parse(&scene_toml, "phantom.toml")
        .map_err(|e| format!("{what}: the generated scene does not load: {e}"))?;
    let n = shapes.len();
    if scene.cylinders.len() != n * segments {
        return Err(format!(
            "{what}: the scene has {} cylinders, expected {n} fibers x {segments} segments",
            scene.cylinders.len()
        ));
    }
    let eps: Vec<f64> = scene
        .cylinders
        .par_chunks(segments)
        .zip(paths.par_iter())
        .map(|(cyls, path)| {
            let axes: Vec<CubicBezier> = cyls.iter().map(|c| c.axis()).collect();
            axis_deviation(path, &axes)
        })
        .collect();
    for (i, (e, s)) in eps.iter().zip(shapes).enumerate() {
        if !(*e <= AXIS_TOLERANCE * s.a) {
            return Err(format!(
                "{what}: fiber {i}'s axis strays {:.2e} of its radius from its centreline (at \
                 most {AXIS_TOLERANCE:.1e}); give more segments",
                e / s.a
            ));
        }
    }
    let check = verify(what, packer, pos, paths, &eps, len)?;
    let fiber_of: Vec<u32> = (0..n as u32)
        .flat_map(|i| std::iter::repeat_n(i, segments))
        .collect();
    let mut truth = ground_truth(&scene.cylinders, &fiber_of, envelope)?;
    for (f, e) in truth.fibers.iter_mut().zip(&eps) {
        f.axis_deviation = Some(*e);
    }
    truth.target_fiber_volume_fraction = Some(target);
    truth.pitch = pitch;
    truth.segments_per_fiber = Some(segments);
    truth.packing_check = Some(check);
    truth.spec = Some(spec);
    Ok(Phantom { scene_toml, truth })
}

// ---------------------------------------------------------------------------------------------
// The yarn.

impl YarnSpec {
    /// The fibers' shape settings.
    fn shape(&self) -> ShapeParams {
        ShapeParams {
            radius: self.radius,
            radius_sd: self.radius_sd,
            aspect: self.aspect,
            aspect_sd: self.aspect_sd,
            section_twist: self.section_twist,
        }
    }

    fn validate(&self) -> Result<(), String> {
        let w = "yarn";
        check((1..=MAX_FIBERS).contains(&self.fibers), w, || {
            format!("fibers must be 1 to {MAX_FIBERS}, got {}", self.fibers)
        })?;
        positive(w, "length", self.length)?;
        in_range(w, "twist_deg", self.twist_deg, -45.0, 45.0)?;
        check(self.packing > 0.0 && self.packing < 1.0, w, || {
            format!("packing must be in (0, 1), got {}", self.packing)
        })?;
        self.shape().validate(w)?;
        in_range(w, "migration", self.migration, 0.0, 0.25)?;
        if self.migration > 0.0 {
            positive(w, "migration_period", self.migration_period)?;
        }
        check_segments_and_material(w, self.segments, &self.material)
    }
}

/// Builds a yarn phantom (see the module's documentation): fibers packed without overlap into
/// the yarn radius the packing gives, as helices (with coherent migration if asked), written
/// as a scene and verified on the parsed geometry. Errors name the problem: bad input, a
/// packing the relaxation cannot reach (with the packing it reached), too few segments.
pub fn generate_yarn(spec: &YarnSpec) -> Result<Phantom, String> {
    spec.validate()?;
    let what = "yarn";
    let n = spec.fibers;
    let len = spec.length;
    let mut rng = Rng::from_seed(spec.seed);
    let params = spec.shape();
    let shapes: Vec<Shape> = (0..n).map(|_| draw_shape(&params, &mut rng)).collect();
    let a: Vec<f64> = shapes.iter().map(|s| s.a).collect();
    let tan = spec.twist_deg.to_radians().tan();
    let mig = spec.migration;
    let w = if mig > 0.0 {
        TAU / spec.migration_period
    } else {
        0.0
    };
    let phase = rng.range(0.0, TAU);
    // Start: uniform in the unit disc (relative to the yarn radius).
    let mut rel: Vec<DVec2> = (0..n)
        .map(|_| rng.uniform().sqrt() * DVec2::from_angle(rng.range(0.0, TAU)))
        .collect();
    let path_of = |p: DVec2, r: f64| {
        let k = tan / r;
        let c = mig * r * (1.0 - p.length_squared() / (r * r)).max(0.0);
        Centreline::Yarn { p, k, c, w, phase }
    };
    // R^2 = sum a b l / (packing L), the lengths for the positions `rel` scaled by R.
    let radius_for = |rel: &[DVec2], mut r: f64| {
        for _ in 0..50 {
            let sum: f64 = rel
                .par_iter()
                .zip(shapes.par_iter())
                .map(|(q, s)| s.a * s.b * arc_length(&path_of(*q * r, r), len))
                .sum();
            let next = (sum / (spec.packing * len)).sqrt();
            let done = (next / r - 1.0).abs() < 1e-14;
            r = next;
            if done {
                break;
            }
        }
        r
    };
    let area: f64 = shapes.iter().map(|s| s.a * s.b).sum();
    let mut r = radius_for(&rel, (area / spec.packing).sqrt());
    let mut pos: Vec<DVec2> = rel.iter().map(|q| *q * r).collect();
    let packer_for = |r: f64, confined: bool| Packer {
        a: &a,
        layout: Layout::Yarn {
            r,
            k: tan / r,
            mig,
            w,
        },
        confined,
    };
    for round in 0.. {
        let packer = packer_for(r, true);
        for (i, p) in pos.iter_mut().enumerate() {
            *p = packer.confine(i, *p);
        }
        let out = relax(&mut pos, &packer, max_passes(n));
        if !out.ok {
            return Err(unreachable(
                what,
                &out,
                &pos,
                &packer,
                &shapes,
                spec.packing,
                false,
            ));
        }
        rel = pos.iter().map(|p| *p / r).collect();
        let next = radius_for(&rel, r);
        if (next / r - 1.0).abs() < 1e-12 || round >= 40 {
            break;
        }
        pos.iter_mut().for_each(|p| *p *= next / r);
        r = next;
    }
    let packer = packer_for(r, true);
    let paths: Vec<Centreline> = pos.iter().map(|p| path_of(*p, r)).collect();
    let segments = choose_segments(what, &paths, &a, len, spec.segments)?;
    let approx = n as f64 * (segments as f64 + 1.0) * 66.0;
    if approx > crate::limits::MAX_SCENE_FILE as f64 {
        return Err(format!(
            "{what}: {n} fibers x {segments} segments would make a scene of about {approx:.2e} \
             bytes, more than the {} a scene file may have",
            crate::limits::MAX_SCENE_FILE
        ));
    }
    let pitch = (tan != 0.0).then(|| TAU * r / tan.abs());
    let amax = a.iter().fold(0.0f64, |m, &x| m.max(x));
    let (width, height) = (2.0 * r * 1.1, len * 1.05 + 4.0 * amax);
    let mut toml = scene_head(
        &format!(
            "gencyl phantom: a yarn of {n} fibers, radius {}, length {len}, twist {} degrees, \
             packing {}, migration {}, seed {}\nsegments per fiber: {segments}; fiber i is \
             strand i, cylinders i*{segments} .. (i+1)*{segments}",
            num(r),
            spec.twist_deg,
            spec.packing,
            spec.migration,
            spec.seed
        ),
        DVec3::new(4.0 * r + len, 0.0, 0.5 * len),
        DVec3::new(0.0, 0.0, 0.5 * len),
        DVec3::Z,
        [width, height],
        &spec.material,
    );
    toml.push_str(&ct_table(
        DVec3::Z,
        DVec3::new(0.0, 0.0, 0.5 * len),
        [2.0 * (r + amax) * 1.05, len + 4.0 * amax],
        spec.radius * spec.aspect / 3.0,
    ));
    for (path, shape) in paths.iter().zip(&shapes) {
        push_strand(
            &mut toml,
            &path.samples(len, segments),
            shape,
            &spec.material,
        );
    }
    finish(
        what,
        toml,
        &shapes,
        &paths,
        &packer,
        &pos,
        segments,
        Envelope::Cylinder {
            radius: r,
            length: len,
        },
        len,
        spec.packing,
        pitch,
        serde_json::to_value(spec).unwrap_or_default(),
    )
}

// ---------------------------------------------------------------------------------------------
// The ply.

impl PlySpec {
    /// The fibers' shape settings (no section twist: a ply's fibers are straight or gently
    /// wavy).
    fn shape(&self) -> ShapeParams {
        ShapeParams {
            radius: self.radius,
            radius_sd: self.radius_sd,
            aspect: self.aspect,
            aspect_sd: self.aspect_sd,
            section_twist: 0.0,
        }
    }

    fn validate(&self) -> Result<(), String> {
        let w = "ply";
        check(self.fibers <= MAX_FIBERS, w, || {
            format!("fibers must be at most {MAX_FIBERS}, got {}", self.fibers)
        })?;
        positive(w, "length", self.length)?;
        positive(w, "width", self.width)?;
        positive(w, "thickness", self.thickness)?;
        check(self.packing >= 0.0 && self.packing < 1.0, w, || {
            format!("packing must be in [0, 1), got {}", self.packing)
        })?;
        check((self.fibers == 0) != (self.packing == 0.0), w, || {
            "give either fibers or packing, and 0 for the other".into()
        })?;
        self.shape().validate(w)?;
        in_range(w, "waviness", self.waviness, 0.0, 1e3)?;
        if self.waviness > 0.0 {
            positive(w, "waviness_period", self.waviness_period)?;
            let slope = self.waviness * self.radius * TAU / self.waviness_period;
            check(slope <= 0.5, w, || {
                format!(
                    "the waviness tilts fibers by up to {:.1} degrees (slope {slope:.3}); at most \
                     a slope of 0.5 is supported: lower the amplitude or lengthen the period",
                    slope.atan().to_degrees()
                )
            })?;
        }
        check_segments_and_material(w, self.segments, &self.material)
    }
}

/// Builds a ply phantom (see the module's documentation): straight or gently wavy fibers along
/// `x`, packed without overlap into the box, written as a scene and verified on the parsed
/// geometry.
pub fn generate_ply(spec: &PlySpec) -> Result<Phantom, String> {
    spec.validate()?;
    let what = "ply";
    let len = spec.length;
    let (hw, ht) = (0.5 * spec.width, 0.5 * spec.thickness);
    let mut rng = Rng::from_seed(spec.seed);
    let params = spec.shape();
    let amp = spec.waviness * spec.radius;
    let kappa = if amp > 0.0 {
        TAU / spec.waviness_period
    } else {
        0.0
    };
    let u = amp * DVec2::from_angle(rng.range(0.0, TAU));
    let g = 0.1 * kappa * DVec2::from_angle(rng.range(0.0, TAU));
    let psi = rng.range(0.0, TAU);
    // Every fiber has the same length factor: its waviness is the same wave.
    let probe = Centreline::Ply {
        p: DVec2::ZERO,
        u,
        kappa,
        psi,
    };
    let stretch = arc_length(&probe, len) / len;
    let box_area = spec.width * spec.thickness;
    let mut shapes: Vec<Shape> = Vec::new();
    let target = if spec.fibers > 0 {
        shapes = (0..spec.fibers)
            .map(|_| draw_shape(&params, &mut rng))
            .collect();
        PI * shapes.iter().map(|s| s.a * s.b).sum::<f64>() * stretch / box_area
    } else {
        let want = spec.packing * box_area / (PI * stretch);
        let mut sum = 0.0;
        while sum < want {
            if shapes.len() >= MAX_FIBERS {
                return Err(format!(
                    "{what}: packing {} needs more than {MAX_FIBERS} fibers",
                    spec.packing
                ));
            }
            let s = draw_shape(&params, &mut rng);
            sum += s.a * s.b;
            shapes.push(s);
        }
        let f = (want / sum).sqrt();
        for s in &mut shapes {
            s.a *= f;
            s.b *= f;
        }
        spec.packing
    };
    let n = shapes.len();
    let a: Vec<f64> = shapes.iter().map(|s| s.a).collect();
    let amax = a.iter().fold(0.0f64, |m, &x| m.max(x));
    if !(amax + u.x.abs() < hw && amax + u.y.abs() < ht) {
        return Err(format!(
            "{what}: a fiber of radius {amax:.3e} (with waviness {amp:.3e}) does not fit in the \
             {} x {} cross section",
            spec.width, spec.thickness
        ));
    }
    let mut pos: Vec<DVec2> = (0..n)
        .map(|_| DVec2::new(rng.range(-hw, hw), rng.range(-ht, ht)))
        .collect();
    let packer_for = |confined| Packer {
        a: &a,
        layout: Layout::Ply {
            hw,
            ht,
            u,
            kappa,
            g,
        },
        confined,
    };
    let packer = packer_for(true);
    for (i, p) in pos.iter_mut().enumerate() {
        *p = packer.confine(i, *p);
    }
    let out = relax(&mut pos, &packer, max_passes(n));
    if !out.ok {
        let by_count = spec.fibers > 0;
        return Err(unreachable(
            what, &out, &pos, &packer, &shapes, target, by_count,
        ));
    }
    let paths: Vec<Centreline> = pos
        .iter()
        .map(|p| Centreline::Ply {
            p: *p,
            u,
            kappa,
            psi: psi + g.dot(*p),
        })
        .collect();
    let segments = choose_segments(what, &paths, &a, len, spec.segments)?;
    let approx = n as f64 * (segments as f64 + 1.0) * 66.0;
    if approx > crate::limits::MAX_SCENE_FILE as f64 {
        return Err(format!(
            "{what}: {n} fibers x {segments} segments would make a scene of about {approx:.2e} \
             bytes, more than the {} a scene file may have",
            crate::limits::MAX_SCENE_FILE
        ));
    }
    let mut toml = scene_head(
        &format!(
            "gencyl phantom: a ply of {n} fibers, {len} x {} x {}, packing {target:.6}, waviness \
             {}, seed {}\nsegments per fiber: {segments}; fiber i is strand i, cylinders \
             i*{segments} .. (i+1)*{segments}",
            spec.width, spec.thickness, spec.waviness, spec.seed
        ),
        DVec3::new(0.5 * len, 0.0, ht + len + spec.width),
        DVec3::new(0.5 * len, 0.0, 0.0),
        DVec3::Y,
        [len * 1.05 + 4.0 * amax, spec.width * 1.1],
        &spec.material,
    );
    toml.push_str(&ct_table(
        DVec3::X,
        DVec3::new(0.5 * len, 0.0, 0.0),
        [
            spec.width.hypot(spec.thickness) * 1.05 + 2.0 * amax,
            len + 4.0 * amax,
        ],
        spec.radius * spec.aspect / 3.0,
    ));
    for (path, shape) in paths.iter().zip(&shapes) {
        push_strand(
            &mut toml,
            &path.samples(len, segments),
            shape,
            &spec.material,
        );
    }
    finish(
        what,
        toml,
        &shapes,
        &paths,
        &packer,
        &pos,
        segments,
        Envelope::Box {
            length: len,
            width: spec.width,
            thickness: spec.thickness,
        },
        len,
        target,
        None,
        serde_json::to_value(spec).unwrap_or_default(),
    )
}

// ---------------------------------------------------------------------------------------------
// Ground truth.

/// The 20 Gauss-Legendre nodes and weights on `[-1, 1]` (Newton on the three-term recurrence).
fn gauss_nodes() -> &'static [(f64, f64)] {
    static NODES: OnceLock<Vec<(f64, f64)>> = OnceLock::new();
    NODES.get_or_init(|| {
        let n = 20;
        let legendre = |x: f64| {
            let (mut p0, mut p1) = (1.0, x);
            for k in 2..=n {
                let k = k as f64;
                let p2 = ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k;
                (p0, p1) = (p1, p2);
            }
            (p1, n as f64 * (x * p1 - p0) / (x * x - 1.0))
        };
        (0..n)
            .map(|i| {
                let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
                for _ in 0..100 {
                    let (p, dp) = legendre(x);
                    let dx = p / dp;
                    x -= dx;
                    if dx.abs() < 1e-17 {
                        break;
                    }
                }
                let (_, dp) = legendre(x);
                (x, 2.0 / ((1.0 - x * x) * dp * dp))
            })
            .collect()
    })
}

/// 20-node Gauss-Legendre of `f` over `[a, b]`.
fn gauss<const K: usize>(a: f64, b: f64, f: impl Fn(f64) -> [f64; K]) -> [f64; K] {
    let (m, h) = (0.5 * (a + b), 0.5 * (b - a));
    let mut out = [0.0; K];
    for &(x, w) in gauss_nodes() {
        let v = f(m + h * x);
        for k in 0..K {
            out[k] += w * h * v[k];
        }
    }
    out
}

/// Adaptive Gauss-Legendre: halves until the halves' sum agrees with the whole to `1e-14` in
/// components 0 and 1 (relative), at most 12 levels deep.
fn integrate<const K: usize>(
    f: &impl Fn(f64) -> [f64; K],
    a: f64,
    b: f64,
    whole: [f64; K],
    depth: u32,
) -> [f64; K] {
    let m = 0.5 * (a + b);
    let (l, r) = (gauss(a, m, f), gauss(m, b, f));
    let mut sum = [0.0; K];
    for k in 0..K {
        sum[k] = l[k] + r[k];
    }
    let close = (0..K.min(2)).all(|k| (sum[k] - whole[k]).abs() <= 1e-14 * sum[k].abs());
    if close || depth >= 12 {
        return sum;
    }
    let (l, r) = (
        integrate(f, a, m, l, depth + 1),
        integrate(f, m, b, r, depth + 1),
    );
    let mut out = [0.0; K];
    for k in 0..K {
        out[k] = l[k] + r[k];
    }
    out
}

/// The unit section's area and first moment (Green's theorem, exact for the cubic pieces).
fn section_moments(section: &Section) -> (f64, DVec2) {
    match section {
        Section::Circle(_) => (PI, DVec2::ZERO),
        Section::Loop(l) => {
            let (mut area, mut mx, mut my) = (0.0, 0.0, 0.0);
            for piece in l.pieces() {
                let c = CubicBezier::new(piece.map(|p| DVec3::new(p.x, p.y, 0.0)));
                let [da, dx, dy] = gauss(0.0, 1.0, |t| {
                    let (p, d) = (c.point(t), c.d1(t));
                    [
                        0.5 * (p.x * d.y - p.y * d.x),
                        0.5 * p.x * p.x * d.y,
                        -0.5 * p.y * p.y * d.x,
                    ]
                });
                area += da;
                mx += dx;
                my += dy;
            }
            let s = area.signum();
            (area * s, DVec2::new(mx, my) * s)
        }
    }
}

/// Integrals over one cylinder: volume, length, and (times the length element) the angle to the
/// axis, the distance from the axis line, the point, the major and minor radii.
fn cylinder_integrals(c: &GeneralizedCylinder, axis: DVec3) -> [f64; 9] {
    let (area0, m0) = section_moments(c.section());
    let bez = c.axis();
    let sweep = c.sweep();
    let f = |u: f64| {
        let d1 = bez.d1(u);
        let speed = d1.length();
        let t = d1 / speed;
        let (ma, mi) = (sweep.major_at(u), sweep.minor_at(u));
        let mut vol = area0 * ma * mi * speed;
        if m0 != DVec2::ZERO {
            let fr = c.frame(u);
            let sm = sweep.apply(u, gencyl::real::V2::cst(m0)).value();
            let moment = ma * mi * (sm.x * fr.n + sm.y * fr.b);
            let d2 = bez.d2(u);
            let dt = (d2 - d2.dot(t) * t) / speed;
            vol -= dt.dot(moment);
        }
        let p = bez.point(u);
        let off = p - p.dot(axis) * axis;
        let angle = t.cross(axis).length().atan2(t.dot(axis).abs());
        [
            vol,
            speed,
            angle * speed,
            off.length() * speed,
            p.x * speed,
            p.y * speed,
            p.z * speed,
            ma * speed,
            mi * speed,
        ]
    };
    integrate(&f, 0.0, 1.0, gauss(0.0, 1.0, f), 0)
}

/// The ground truth of fibers made of `cylinders`, cylinder `c` belonging to fiber
/// `fiber_of_cylinder[c]` (0-based; every fiber from 0 to the largest must have a cylinder),
/// in `envelope`. A fiber's chord runs from its first cylinder's start to its last cylinder's
/// end (in cylinder order).
pub fn ground_truth(
    cylinders: &[GeneralizedCylinder],
    fiber_of_cylinder: &[u32],
    envelope: Envelope,
) -> Result<GroundTruth, String> {
    if cylinders.len() != fiber_of_cylinder.len() {
        return Err(format!(
            "ground truth: {} cylinders but {} fiber numbers",
            cylinders.len(),
            fiber_of_cylinder.len()
        ));
    }
    let nf = fiber_of_cylinder
        .iter()
        .map(|&f| f as usize + 1)
        .max()
        .unwrap_or(0);
    let axis = envelope.axis();
    let ints: Vec<[f64; 9]> = cylinders
        .par_iter()
        .map(|c| cylinder_integrals(c, axis))
        .collect();
    let mut acc = vec![[0.0f64; 9]; nf];
    let mut first = vec![usize::MAX; nf];
    let mut last = vec![0usize; nf];
    let mut count = vec![0usize; nf];
    let mut bounds = gencyl::Aabb::EMPTY;
    for (ci, (&f, v)) in fiber_of_cylinder.iter().zip(&ints).enumerate() {
        let f = f as usize;
        for k in 0..9 {
            acc[f][k] += v[k];
        }
        first[f] = first[f].min(ci);
        last[f] = ci;
        count[f] += 1;
        bounds = bounds.union(cylinders[ci].bounds());
    }
    if let Some(f) = count.iter().position(|&c| c == 0) {
        return Err(format!("ground truth: fiber {f} has no cylinder"));
    }
    let fibers: Vec<FiberTruth> = (0..nf)
        .map(|f| {
            let v = acc[f];
            let start = cylinders[first[f]].axis().points[0];
            let end = cylinders[last[f]].axis().points[3];
            let dir = (end - start).normalize_or_zero();
            let len = v[1];
            FiberTruth {
                label: f as u32 + 1,
                first_cylinder: first[f],
                cylinders: count[f],
                volume: v[0],
                length: len,
                direction: dir.to_array(),
                angle_deg: dir
                    .cross(axis)
                    .length()
                    .atan2(dir.dot(axis).abs())
                    .to_degrees(),
                mean_local_angle_deg: (v[2] / len).to_degrees(),
                mean_axis_distance: v[3] / len,
                major_radius: v[7] / len,
                minor_radius: v[8] / len,
                axis_deviation: None,
            }
        })
        .collect();
    let total: f64 = fibers.iter().map(|f| f.volume).sum();
    let env = envelope.volume();
    Ok(GroundTruth {
        fiber_count: nf,
        fibers,
        total_fiber_volume: total,
        envelope_volume: env,
        fiber_volume_fraction: total / env,
        envelope,
        target_fiber_volume_fraction: None,
        bounds: if nf > 0 {
            [bounds.min.to_array(), bounds.max.to_array()]
        } else {
            [[0.0; 3]; 2]
        },
        pitch: None,
        segments_per_fiber: None,
        packing_check: None,
        spec: None,
    })
}

// ---------------------------------------------------------------------------------------------
// Label volumes.

/// A grid of cubic voxels: voxel `(i, j, k)` is the cube of side `voxel` with its lowest corner
/// at `origin + voxel (i, j, k)`; `i` runs fastest in memory, then `j`, then `k`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct VoxelGrid {
    /// The grid's lowest corner.
    pub origin: [f64; 3],
    /// The voxel's side.
    pub voxel: f64,
    /// Voxels along `x`, `y`, `z`.
    pub size: [usize; 3],
}

impl VoxelGrid {
    /// The grid of voxels of side `voxel` covering the box `[min, max]` (rounded out).
    pub fn covering(min: [f64; 3], max: [f64; 3], voxel: f64) -> Result<Self, String> {
        let size = [0, 1, 2].map(|k| ((max[k] - min[k]) / voxel).ceil().max(1.0));
        if !(voxel > 0.0 && voxel.is_finite() && size.iter().all(|s| *s <= 1e9)) {
            return Err(format!(
                "voxel grid: voxel {voxel} over [{min:?}, {max:?}] is not a usable grid"
            ));
        }
        let grid = VoxelGrid {
            origin: min,
            voxel,
            size: size.map(|s| s as usize),
        };
        grid.voxels()?;
        Ok(grid)
    }

    /// The number of voxels, checked: positive sizes, at most [`MAX_LABEL_VOXELS`], a finite
    /// origin and a positive finite voxel.
    pub fn voxels(&self) -> Result<usize, String> {
        if !(self.voxel > 0.0
            && self.voxel.is_finite()
            && self.origin.iter().all(|o| o.is_finite()))
        {
            return Err(format!(
                "voxel grid: the voxel must be positive and finite and the origin finite, got \
                 voxel {} at {:?}",
                self.voxel, self.origin
            ));
        }
        let [nx, ny, nz] = self.size;
        let n = nx
            .checked_mul(ny)
            .and_then(|v| v.checked_mul(nz))
            .filter(|&v| v > 0 && v <= MAX_LABEL_VOXELS)
            .ok_or_else(|| {
                format!(
                    "voxel grid: {nx} x {ny} x {nz} voxels; 1 to {MAX_LABEL_VOXELS} are allowed \
                     ({} MiB of 32-bit labels)",
                    (MAX_LABEL_VOXELS * 4) >> 20
                )
            })?;
        Ok(n)
    }

    /// The centre of voxel `(i, j, k)`.
    pub fn center(&self, i: usize, j: usize, k: usize) -> DVec3 {
        DVec3::from_array(self.origin)
            + self.voxel * DVec3::new(i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5)
    }
}

/// A piece of a cylinder's axis for the label volume: its box, and the capsule around its chord
/// that holds the solid near it.
struct Piece {
    cyl: u32,
    lo: DVec3,
    hi: DVec3,
    a: DVec3,
    ab: DVec3,
    reach2: f64,
}

/// The pieces of one cylinder: its axis cut into `m` parts (about one section radius long, at
/// most 32); each part's solid lies within `r + dev` of its chord, `r` the largest section
/// radius and `dev` the farther inner control point's distance from the chord (the part lies in
/// its control points' hull).
fn pieces(ci: usize, c: &GeneralizedCylinder) -> Vec<Piece> {
    let r = c.reach();
    let bez = c.axis();
    let p = bez.points;
    let poly = (p[1] - p[0]).length() + (p[2] - p[1]).length() + (p[3] - p[2]).length();
    let m = ((poly / r).ceil() as usize).clamp(1, 32);
    (0..m)
        .map(|k| {
            let s = bez
                .segment(k as f64 / m as f64, (k + 1) as f64 / m as f64)
                .points;
            let (a, b) = (s[0], s[3]);
            let ab = b - a;
            let dist = |q: DVec3| {
                let t = if ab.length_squared() > 0.0 {
                    ((q - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                (q - a - t * ab).length()
            };
            let dev = dist(s[1]).max(dist(s[2]));
            let reach = (r + dev) * (1.0 + 1e-9) + 1e-12 * a.abs().max_element();
            let (lo, hi) = s
                .iter()
                .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), q| {
                    (lo.min(*q), hi.max(*q))
                });
            Piece {
                cyl: ci as u32,
                lo: lo - DVec3::splat(reach),
                hi: hi + DVec3::splat(reach),
                a,
                ab,
                reach2: reach * reach,
            }
        })
        .collect()
}

/// The label of each voxel of `grid` (x fastest, then y, then z): 0 outside every cylinder,
/// `fiber_of_cylinder[c] + 1` at a voxel centre inside cylinder `c`
/// ([`GeneralizedCylinder::contains`]; where fibers overlap, the lowest cylinder index wins).
/// Each cylinder is cut into pieces binned into the z slices they reach; each slice (in
/// parallel) tests the voxels of its pieces' boxes that lie in the piece's capsule. Grids of
/// more than [`MAX_LABEL_VOXELS`] voxels are refused.
pub fn label_volume(
    cylinders: &[GeneralizedCylinder],
    fiber_of_cylinder: &[u32],
    grid: VoxelGrid,
) -> Result<Vec<u32>, String> {
    let total = grid.voxels()?;
    if cylinders.len() != fiber_of_cylinder.len() {
        return Err(format!(
            "label volume: {} cylinders but {} fiber numbers",
            cylinders.len(),
            fiber_of_cylinder.len()
        ));
    }
    if let Some(f) = fiber_of_cylinder.iter().find(|&&f| f == u32::MAX) {
        return Err(format!("label volume: fiber number {f} has no label"));
    }
    let [nx, ny, nz] = grid.size;
    let o = DVec3::from_array(grid.origin);
    let v = grid.voxel;
    let all: Vec<Piece> = cylinders
        .par_iter()
        .enumerate()
        .flat_map_iter(|(i, c)| pieces(i, c))
        .collect();
    // Voxel index range (inclusive) whose centres lie in [lo, hi] along one axis.
    let span = |lo: f64, hi: f64, o: f64, n: usize| -> Option<(usize, usize)> {
        let i0 = ((lo - o) / v - 0.5).ceil().max(0.0);
        let i1 = ((hi - o) / v - 0.5).floor().min(n as f64 - 1.0);
        (i0 <= i1).then_some((i0 as usize, i1 as usize))
    };
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); nz];
    for (pi, p) in all.iter().enumerate() {
        if let Some((k0, k1)) = span(p.lo.z, p.hi.z, o.z, nz) {
            for bin in &mut bins[k0..=k1] {
                bin.push(pi as u32);
            }
        }
    }
    let mut labels = vec![0u32; total];
    labels
        .par_chunks_mut(nx * ny)
        .zip(bins.par_iter())
        .enumerate()
        .for_each(|(k, (slice, bin))| {
            let z = o.z + (k as f64 + 0.5) * v;
            let mut tested = vec![0u32; nx * ny];
            for &pi in bin {
                let p = &all[pi as usize];
                let (Some((i0, i1)), Some((j0, j1))) =
                    (span(p.lo.x, p.hi.x, o.x, nx), span(p.lo.y, p.hi.y, o.y, ny))
                else {
                    continue;
                };
                let stamp = p.cyl + 1;
                let cyl = &cylinders[p.cyl as usize];
                let ab2 = p.ab.length_squared();
                for j in j0..=j1 {
                    let y = o.y + (j as f64 + 0.5) * v;
                    for i in i0..=i1 {
                        let idx = j * nx + i;
                        if slice[idx] != 0 || tested[idx] == stamp {
                            continue;
                        }
                        let q = DVec3::new(o.x + (i as f64 + 0.5) * v, y, z);
                        let t = if ab2 > 0.0 {
                            ((q - p.a).dot(p.ab) / ab2).clamp(0.0, 1.0)
                        } else {
                            0.0
                        };
                        if (q - p.a - t * p.ab).length_squared() > p.reach2 {
                            continue;
                        }
                        tested[idx] = stamp;
                        if cyl.contains(q) {
                            slice[idx] = fiber_of_cylinder[p.cyl as usize] + 1;
                        }
                    }
                }
            }
        });
    Ok(labels)
}

/// Writes `labels` (as [`label_volume`] lays them out) as a multi-page TIFF: one 32-bit unsigned
/// grayscale page per z slice, Deflate-compressed ([`crate::formats::tiff`]), complete or not
/// at all ([`crate::formats::write_atomic`]).
pub fn write_labels_tiff(path: &Path, labels: &[u32], grid: VoxelGrid) -> Result<(), String> {
    let total = grid.voxels()?;
    let show = path.display();
    if labels.len() != total {
        return Err(format!(
            "{show}: {} labels for a grid of {total} voxels",
            labels.len()
        ));
    }
    let [nx, ny, nz] = grid.size;
    let (w, h) = (
        u32::try_from(nx).map_err(|_| format!("{show}: {nx} voxels across is too wide"))?,
        u32::try_from(ny).map_err(|_| format!("{show}: {ny} voxels across is too tall"))?,
    );
    let slice = nx * ny;
    crate::formats::write_atomic(
        path,
        |out| {
            crate::formats::tiff::write_pages::<u32, _>(out, (w, h), nz, true, |k, page| {
                page.copy_from_slice(&labels[k * slice..(k + 1) * slice]);
                Ok(())
            })
            .map_err(|e| format!("{show}: {e}"))
        },
        |e| format!("{show}: cannot write: {e}"),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use gencyl::{BezierLoop, FiberSpec};

    fn yarn() -> YarnSpec {
        YarnSpec {
            fibers: 40,
            length: 0.3,
            twist_deg: 25.0,
            packing: 0.45,
            radius: 0.01,
            radius_sd: 0.1,
            aspect: 0.8,
            aspect_sd: 0.1,
            section_twist: 3.0,
            migration: 0.0,
            migration_period: 1.0,
            segments: 0,
            seed: 7,
            material: "fiber".into(),
        }
    }

    fn parse(p: &Phantom) -> SceneDescription {
        SceneDescription::parse(&p.scene_toml, "phantom.toml").unwrap()
    }

    /// Monte Carlo volume of `c` with `contains`: (estimate, standard error).
    fn monte_carlo(c: &GeneralizedCylinder, samples: usize, seed: u64) -> (f64, f64) {
        let b = c.bounds();
        let chunks = 64;
        let hits: usize = (0..chunks)
            .into_par_iter()
            .map(|k| {
                let mut rng = Rng::from_seed(seed ^ (k as u64 * 0x9E37_79B9));
                (0..samples / chunks)
                    .filter(|_| c.contains(rng.in_box(b.min, b.max)))
                    .count()
            })
            .sum();
        let n = (samples / chunks * chunks) as f64;
        let vbox = (b.max - b.min).x * (b.max - b.min).y * (b.max - b.min).z;
        let p = hits as f64 / n;
        (vbox * p, vbox * (p * (1.0 - p) / n).sqrt())
    }

    /// A straight elliptical cylinder (unevenly spaced control points, twisted section) has
    /// volume `pi a b L` to 1e-12, and a strand through two points too.
    #[test]
    fn phantom_straight_elliptical_volume_is_exact() {
        let dir = DVec3::new(1.0, 2.0, -3.0);
        let mut spec = FiberSpec::round(
            [0.0, 0.1, 0.7, 2.0].map(|s| DVec3::new(0.3, -0.2, 5.0) + s * dir),
            0.05,
        );
        spec.minor_radius = [0.02, 0.02];
        spec.rotation = [0.3, 4.0];
        let c = spec.build().unwrap();
        let t = ground_truth(
            std::slice::from_ref(&c),
            &[0],
            Envelope::Box {
                length: 1.0,
                width: 1.0,
                thickness: 1.0,
            },
        )
        .unwrap();
        let exact = PI * 0.05 * 0.02 * 2.0 * dir.length();
        let rel = (t.total_fiber_volume / exact - 1.0).abs();
        eprintln!("[phantom] straight elliptical cylinder: relative volume error {rel:.1e}");
        assert!(rel < 1e-12, "{} vs {exact}", t.total_fiber_volume);
        assert!((t.fibers[0].length / (2.0 * dir.length()) - 1.0).abs() < 1e-12);
    }

    /// The Pappus volume of bent fibers agrees with a Monte Carlo count of `contains` within 4
    /// standard errors: a tapering twisted elliptical Bezier, and an off-centre square profile
    /// on it (where the section's first moment and the axis' curvature enter).
    #[test]
    fn phantom_bent_fiber_volume_matches_monte_carlo() {
        let bez = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(0.35, 0.45, 0.1),
            DVec3::new(0.75, 0.05, 0.55),
            DVec3::new(1.05, 0.45, 0.35),
        ];
        let mut spec = FiberSpec::round(bez, 0.08);
        spec.major_radius = [0.08, 0.05];
        spec.minor_radius = [0.03, 0.025];
        spec.rotation = [0.4, 2.9];
        let ellipse = spec.build().unwrap();
        let (x0, x1, y0, y1) = (-0.2, 1.0, -0.7, 0.7);
        let corners = [
            DVec2::new(x0, y0),
            DVec2::new(x1, y0),
            DVec2::new(x1, y1),
            DVec2::new(x0, y1),
        ];
        let mut pts = Vec::new();
        for i in 0..4 {
            let (p, q) = (corners[i], corners[(i + 1) % 4]);
            pts.extend([p, p + (q - p) / 3.0, p + 2.0 * (q - p) / 3.0]);
        }
        spec.section = Section::Loop(BezierLoop::new(&pts).unwrap());
        spec.rotation = [0.0, 0.0];
        let square = spec.build().unwrap();
        let (area, m) = section_moments(square.section());
        assert!((area - 1.2 * 1.4).abs() < 1e-14 && (m.x - 0.4 * 1.4 * 1.2).abs() < 1e-14);
        for (name, c) in [("ellipse", ellipse), ("off-centre square", square)] {
            assert!(!c.may_fold());
            let t = ground_truth(
                std::slice::from_ref(&c),
                &[0],
                Envelope::Box {
                    length: 1.0,
                    width: 1.0,
                    thickness: 1.0,
                },
            )
            .unwrap();
            let v = t.total_fiber_volume;
            let n = std::env::var("PHANTOM_MC")
                .ok()
                .and_then(|v| v.parse().ok())
                .unwrap_or(400_000);
            let (mc, se) = monte_carlo(&c, n, 11);
            eprintln!(
                "[phantom] {name}: Pappus {v:.6e}, Monte Carlo {mc:.6e} +- {se:.1e} ({:.2} sigma)",
                (mc - v) / se
            );
            assert!((mc - v).abs() < 4.0 * se, "{name}: {v} vs {mc} +- {se}");
        }
    }

    /// Surface points of every cylinder, tested with `contains` against every cylinder of
    /// another fiber whose box holds them: none may be inside. Returns (tests, near tests:
    /// points within 1.25 major radii of the other cylinder's axis).
    fn assert_disjoint(cyls: &[GeneralizedCylinder], fiber_of: &[u32]) -> (usize, usize) {
        let found: Vec<(usize, usize)> = (0..cyls.len())
            .into_par_iter()
            .map(|ci| {
                let c = &cyls[ci];
                let bc = c.bounds();
                let (mut tests, mut near) = (0, 0);
                for (di, d) in cyls.iter().enumerate() {
                    let bd = d.bounds();
                    if fiber_of[di] == fiber_of[ci]
                        || !(bc.min.cmple(bd.max).all() && bd.min.cmple(bc.max).all())
                    {
                        continue;
                    }
                    let ad = d.sweep().major[0];
                    for iu in 0..=8 {
                        let u = iu as f64 / 8.0;
                        for iv in 0..24 {
                            let q = c.surface_point(u, iv as f64 * TAU / 24.0);
                            if !bd.contains(q) {
                                continue;
                            }
                            tests += 1;
                            let axis = d.axis();
                            let close = (0..=32)
                                .map(|k| (axis.point(k as f64 / 32.0) - q).length())
                                .fold(f64::INFINITY, f64::min);
                            if close < 1.25 * ad {
                                near += 1;
                            }
                            assert!(
                                !d.contains(q),
                                "cylinder {ci} (fiber {}) at ({u}, {iv}) is inside cylinder {di} (fiber {})",
                                fiber_of[ci],
                                fiber_of[di]
                            );
                        }
                    }
                }
                // The samples are on c's surface: a point 1% further in is inside c.
                let axis = c.axis();
                for iv in 0..8 {
                    let u = 0.5;
                    let q = c.surface_point(u, iv as f64 * TAU / 8.0);
                    let inner = axis.point(u) + 0.99 * (q - axis.point(u));
                    assert!(c.contains(inner), "cylinder {ci}: inner point outside");
                }
                (tests, near)
            })
            .collect();
        found
            .into_iter()
            .fold((0, 0), |(a, b), (c, d)| (a + c, b + d))
    }

    /// A twisted yarn of elliptical, twisting fibers: no surface point of a fiber is inside
    /// another (many points are within a quarter radius of touching), the volume fraction is
    /// the target within 1%, the truth survives JSON, and the exact check found every pair
    /// clear.
    #[test]
    fn phantom_yarn_fibers_are_disjoint_at_the_packing() {
        let spec = yarn();
        let p = generate_yarn(&spec).unwrap();
        let t = &p.truth;
        let scene = parse(&p);
        let (tests, near) = assert_disjoint(&scene.cylinders, &p.fiber_of_cylinder());
        let check = t.packing_check.as_ref().unwrap();
        eprintln!(
            "[phantom] yarn: {} fibers x {} segments, fraction {:.6} (target {}), {tests} \
             contains tests ({near} near contact), check {check:?}",
            t.fiber_count,
            t.segments_per_fiber.unwrap(),
            t.fiber_volume_fraction,
            spec.packing
        );
        assert!(near > 1000, "the samples come near other fibers: {near}");
        assert_eq!(t.fiber_count, spec.fibers);
        assert!((t.fiber_volume_fraction / spec.packing - 1.0).abs() < 0.01);
        assert_eq!(check.method, "exact");
        assert!(check.min_clearance >= 0.0 && check.max_axis_deviation <= AXIS_TOLERANCE);
        // serde_json reads floats to within an ulp or so (without its `float_roundtrip`).
        let back: GroundTruth = serde_json::from_str(&t.to_json()).unwrap();
        assert_eq!(back.fiber_count, t.fiber_count);
        assert!((back.fiber_volume_fraction / t.fiber_volume_fraction - 1.0).abs() < 1e-15);
        for (b, f) in back.fibers.iter().zip(&t.fibers) {
            assert_eq!(
                (b.label, b.first_cylinder, b.cylinders),
                (f.label, f.first_cylinder, f.cylinders)
            );
            assert!((b.volume / f.volume - 1.0).abs() < 1e-15);
        }
        let sum: f64 = t.fibers.iter().map(|f| f.volume).sum();
        assert!((sum / t.total_fiber_volume - 1.0).abs() < 1e-14);
        assert_inside(&scene.cylinders, &t.envelope);
    }

    /// Every sampled side point lies in the envelope across its axis (up to the axis deviation
    /// the gap allows).
    fn assert_inside(cyls: &[GeneralizedCylinder], env: &Envelope) {
        let amax = cyls.iter().fold(0.0f64, |m, c| m.max(c.sweep().major[0]));
        let slack = 2.0 * AXIS_TOLERANCE * amax;
        for c in cyls {
            for iu in 0..=8 {
                for iv in 0..32 {
                    let q = c.surface_point(iu as f64 / 8.0, iv as f64 * TAU / 32.0);
                    let ok = match *env {
                        Envelope::Cylinder { radius, .. } => {
                            q.truncate().length() <= radius + slack
                        }
                        Envelope::Box {
                            width, thickness, ..
                        } => {
                            q.y.abs() <= 0.5 * width + slack && q.z.abs() <= 0.5 * thickness + slack
                        }
                    };
                    assert!(ok, "{q} outside {env:?}");
                }
            }
        }
    }

    fn yarn_radius(t: &GroundTruth) -> f64 {
        match t.envelope {
            Envelope::Cylinder { radius, .. } => radius,
            Envelope::Box { .. } => f64::NAN,
        }
    }

    /// The fibers' helix angles, measured on the parsed Bezier axes, are `atan(tan(alpha) r /
    /// R_y)`: at the yarn surface, the twist asked for.
    #[test]
    fn phantom_yarn_helix_angle_matches_twist() {
        let spec = YarnSpec {
            fibers: 30,
            twist_deg: 30.0,
            aspect: 1.0,
            aspect_sd: 0.0,
            seed: 3,
            ..yarn()
        };
        let t = generate_yarn(&spec).unwrap().truth;
        let r = yarn_radius(&t);
        let tan = 30f64.to_radians().tan();
        let mut worst = 0.0f64;
        let mut outer = (0.0, 0.0);
        for f in &t.fibers {
            let expect = (tan * f.mean_axis_distance / r).atan().to_degrees();
            worst = worst.max((f.mean_local_angle_deg - expect).abs());
            if f.mean_axis_distance > outer.0 {
                let surface = (f.mean_local_angle_deg.to_radians().tan() * r
                    / f.mean_axis_distance)
                    .atan()
                    .to_degrees();
                outer = (f.mean_axis_distance, surface);
            }
            // The chord of a helix over whole turns runs along the yarn; over part of one, less.
            assert!(f.angle_deg < f.mean_local_angle_deg + 1e-9);
        }
        eprintln!(
            "[phantom] helix angles: worst {worst:.2e} degrees off; outermost fiber at {:.4} R: \
             {:.5} degrees at the surface; pitch {:.4}",
            outer.0 / r,
            outer.1,
            t.pitch.unwrap()
        );
        assert!(worst < 0.01, "{worst}");
        assert!((outer.1 - 30.0).abs() < 0.01, "{outer:?}");
        assert!((t.pitch.unwrap() - TAU * r / tan).abs() < 1e-12 * r);
    }

    /// The volume fraction of the truth matches a label count at 1/8 of the radius, within 4
    /// times the discretisation error estimated for the counting (each fiber's slice error
    /// `h^2 sqrt(P / (12 h))`, `P` its perimeter, taken as fully correlated along the fiber).
    #[test]
    fn phantom_label_count_matches_volume_fraction() {
        let spec = YarnSpec {
            fibers: 12,
            length: 0.06,
            packing: 0.4,
            twist_deg: 20.0,
            seed: 5,
            ..yarn()
        };
        let p = generate_yarn(&spec).unwrap();
        let t = &p.truth;
        let h = spec.radius / 8.0;
        let grid = t.grid(h).unwrap();
        let scene = parse(&p);
        let labels = label_volume(&scene.cylinders, &p.fiber_of_cylinder(), grid).unwrap();
        let count = labels.iter().filter(|&&l| l != 0).count();
        let mut per_fiber = vec![0usize; t.fiber_count];
        for &l in labels.iter().filter(|&&l| l != 0) {
            per_fiber[l as usize - 1] += 1;
        }
        let counted = count as f64 * h * h * h;
        let var: f64 = t
            .fibers
            .iter()
            .map(|f| {
                let (a, b) = (f.major_radius, f.minor_radius);
                let perimeter = PI * (3.0 * (a + b) - ((3.0 * a + b) * (a + 3.0 * b)).sqrt());
                (f.length * h * h * (perimeter / (12.0 * h)).sqrt()).powi(2)
            })
            .sum();
        let sigma = var.sqrt();
        let err = counted - t.total_fiber_volume;
        eprintln!(
            "[phantom] labels {:?}: counted {counted:.6e}, truth {:.6e}, error {:.2e} relative \
             ({:.2} sigma, sigma {:.1e} relative); fraction {:.5} vs {:.5}",
            grid.size,
            t.total_fiber_volume,
            err / t.total_fiber_volume,
            err / sigma,
            sigma / t.total_fiber_volume,
            counted / t.envelope_volume,
            t.fiber_volume_fraction
        );
        assert!(err.abs() < 4.0 * sigma);
        for (f, c) in t.fibers.iter().zip(&per_fiber) {
            let v = *c as f64 * h * h * h;
            assert!(
                (v / f.volume - 1.0).abs() < 0.05,
                "fiber {}: {v} vs {}",
                f.label,
                f.volume
            );
        }
    }

    /// The same seed gives the same phantom; another seed another.
    #[test]
    fn phantom_is_reproducible_by_seed() {
        let spec = YarnSpec {
            fibers: 15,
            length: 0.1,
            ..yarn()
        };
        let (a, b) = (generate_yarn(&spec).unwrap(), generate_yarn(&spec).unwrap());
        assert_eq!(a.scene_toml, b.scene_toml);
        assert_eq!(a.truth, b.truth);
        let c = generate_yarn(&YarnSpec { seed: 8, ..spec }).unwrap();
        assert_ne!(a.scene_toml, c.scene_toml);
        let ply = PlySpec {
            width: 0.08,
            thickness: 0.03,
            length: 0.1,
            radius: 0.004,
            ..PlySpec::default()
        };
        assert_eq!(
            generate_ply(&ply).unwrap().scene_toml,
            generate_ply(&ply).unwrap().scene_toml
        );
    }

    /// Impossible packings and nonsense input end in errors that say what is wrong.
    #[test]
    fn phantom_rejects_impossible_and_nonsense_input() {
        let err = generate_yarn(&YarnSpec {
            fibers: 30,
            packing: 0.95,
            ..yarn()
        })
        .unwrap_err();
        eprintln!("[phantom] {err}");
        assert!(
            err.contains("not reachable") && err.contains("try a packing of"),
            "{err}"
        );
        let err = generate_ply(&PlySpec {
            width: 0.06,
            thickness: 0.03,
            length: 0.05,
            radius: 0.004,
            packing: 0.95,
            ..PlySpec::default()
        })
        .unwrap_err();
        eprintln!("[phantom] {err}");
        assert!(err.contains("not reachable"), "{err}");
        let bad: Vec<(YarnSpec, &str)> = vec![
            (
                YarnSpec {
                    fibers: 0,
                    ..yarn()
                },
                "fibers",
            ),
            (
                YarnSpec {
                    length: f64::NAN,
                    ..yarn()
                },
                "length",
            ),
            (
                YarnSpec {
                    radius: -0.01,
                    ..yarn()
                },
                "radius",
            ),
            (
                YarnSpec {
                    radius: f64::INFINITY,
                    ..yarn()
                },
                "radius",
            ),
            (
                YarnSpec {
                    packing: f64::NAN,
                    ..yarn()
                },
                "packing",
            ),
            (
                YarnSpec {
                    packing: 0.0,
                    ..yarn()
                },
                "packing",
            ),
            (
                YarnSpec {
                    twist_deg: 60.0,
                    ..yarn()
                },
                "twist_deg",
            ),
            (
                YarnSpec {
                    aspect: 0.0,
                    ..yarn()
                },
                "aspect",
            ),
            (
                YarnSpec {
                    migration: 0.5,
                    ..yarn()
                },
                "migration",
            ),
            (
                YarnSpec {
                    migration: 0.1,
                    migration_period: 0.0,
                    ..yarn()
                },
                "migration_period",
            ),
            (
                YarnSpec {
                    material: "a b".into(),
                    ..yarn()
                },
                "material",
            ),
            (
                YarnSpec {
                    segments: 1,
                    ..yarn()
                },
                "segments",
            ),
        ];
        for (spec, key) in bad {
            let err = generate_yarn(&spec).unwrap_err();
            assert!(err.contains(key), "{key}: {err}");
        }
        let plies: Vec<(PlySpec, &str)> = vec![
            (
                PlySpec {
                    fibers: 10,
                    ..PlySpec::default()
                },
                "either",
            ),
            (
                PlySpec {
                    packing: 0.0,
                    ..PlySpec::default()
                },
                "either",
            ),
            (
                PlySpec {
                    width: -1.0,
                    ..PlySpec::default()
                },
                "width",
            ),
            (
                PlySpec {
                    thickness: 0.004,
                    ..PlySpec::default()
                },
                "does not fit",
            ),
            (
                PlySpec {
                    waviness: 10.0,
                    waviness_period: 0.01,
                    ..PlySpec::default()
                },
                "slope",
            ),
        ];
        for (spec, key) in plies {
            let err = generate_ply(&spec).unwrap_err();
            assert!(err.contains(key), "{key}: {err}");
        }
    }

    /// Corner cases build and verify: one and two fibers, a left-handed 45 degree twist, a
    /// one-fiber ply, explicit segment counts.
    #[test]
    fn phantom_corner_cases_build() {
        for spec in [
            YarnSpec {
                fibers: 1,
                ..yarn()
            },
            YarnSpec {
                fibers: 2,
                packing: 0.25,
                migration: 0.1,
                migration_period: 0.3,
                ..yarn()
            },
            YarnSpec {
                twist_deg: -45.0,
                fibers: 20,
                segments: 64,
                ..yarn()
            },
        ] {
            let p = generate_yarn(&spec).unwrap_or_else(|e| panic!("{spec:?}: {e}"));
            assert_eq!(p.truth.fiber_count, spec.fibers);
            assert!((p.truth.fiber_volume_fraction / spec.packing - 1.0).abs() < 0.01);
        }
        let ply = PlySpec {
            fibers: 1,
            packing: 0.0,
            segments: 3,
            ..PlySpec::default()
        };
        let p = generate_ply(&ply).unwrap();
        assert_eq!(p.truth.segments_per_fiber, Some(3));
        let f = &p.truth.fibers[0];
        assert!((f.volume - PI * f.major_radius * f.minor_radius * 1.0).abs() < 1e-15);
    }

    /// A migrating yarn at packing 0.45: verified by sampling, disjoint by surface samples,
    /// the fraction within 1%, and the fibers' distance from the axis varies.
    #[test]
    fn phantom_migrating_yarn_is_disjoint() {
        let spec = YarnSpec {
            fibers: 40,
            packing: 0.45,
            length: 0.6,
            migration: 0.15,
            migration_period: 0.6,
            twist_deg: 20.0,
            ..yarn()
        };
        let p = generate_yarn(&spec).unwrap();
        let t = &p.truth;
        let check = t.packing_check.as_ref().unwrap();
        let scene = parse(&p);
        assert_inside(&scene.cylinders, &t.envelope);
        let (tests, near) = assert_disjoint(&scene.cylinders, &p.fiber_of_cylinder());
        eprintln!(
            "[phantom] migrating yarn: {} segments, fraction {:.6}, {tests} contains tests ({near} \
             near), check {check:?}",
            t.segments_per_fiber.unwrap(),
            t.fiber_volume_fraction
        );
        assert_eq!(check.method, "sampled");
        assert!(check.pairs_sampled > 0 && check.min_clearance >= 0.0);
        assert!(near > 500);
        assert!((t.fiber_volume_fraction / spec.packing - 1.0).abs() < 0.01);
        // Migration: along a fiber near the core, the distance from the axis swings.
        let r = yarn_radius(t);
        let c = &scene.cylinders;
        let n = t.segments_per_fiber.unwrap();
        let swing = (0..t.fiber_count)
            .map(|f| {
                let d: Vec<f64> = c[f * n..(f + 1) * n]
                    .iter()
                    .map(|c| c.axis().points[0].truncate().length())
                    .collect();
                d.iter().fold(0.0f64, |m, &x| m.max(x)) - d.iter().fold(f64::MAX, |m, &x| m.min(x))
            })
            .fold(0.0f64, f64::max);
        assert!(swing > 0.2 * r, "largest swing {swing} of R {r}");
    }

    /// Plies, straight (from the packing) and wavy (from a fiber count): disjoint, at their
    /// fractions, along x.
    #[test]
    fn phantom_plies_are_disjoint() {
        let straight = PlySpec {
            width: 0.1,
            thickness: 0.04,
            length: 0.08,
            radius: 0.004,
            packing: 0.55,
            seed: 2,
            ..PlySpec::default()
        };
        let wavy = PlySpec {
            fibers: 40,
            packing: 0.0,
            waviness: 0.5,
            waviness_period: 0.08,
            aspect: 0.9,
            ..straight.clone()
        };
        for spec in [straight, wavy] {
            let p = generate_ply(&spec).unwrap();
            let t = &p.truth;
            let scene = parse(&p);
            let (tests, near) = assert_disjoint(&scene.cylinders, &p.fiber_of_cylinder());
            let check = t.packing_check.as_ref().unwrap();
            eprintln!(
                "[phantom] ply ({} fibers, waviness {}): {} segments, fraction {:.6} (target \
                 {:.6}), {tests} tests ({near} near), check {check:?}",
                t.fiber_count,
                spec.waviness,
                t.segments_per_fiber.unwrap(),
                t.fiber_volume_fraction,
                t.target_fiber_volume_fraction.unwrap()
            );
            let target = t.target_fiber_volume_fraction.unwrap();
            assert!((t.fiber_volume_fraction / target - 1.0).abs() < 0.01);
            if spec.packing > 0.0 {
                assert!((target - spec.packing).abs() < 1e-15);
            }
            assert!(near > 200);
            for f in &t.fibers {
                assert!(f.angle_deg < 1e-6 || spec.waviness > 0.0);
            }
            assert_inside(&scene.cylinders, &t.envelope);
        }
    }

    /// `label_volume` labels exactly the voxels whose centres some cylinder contains (brute
    /// force over every cylinder), and refuses grids beyond its memory limit.
    #[test]
    fn phantom_label_volume_matches_brute_force() {
        let spec = YarnSpec {
            fibers: 8,
            length: 0.05,
            packing: 0.4,
            migration: 0.1,
            migration_period: 0.2,
            ..yarn()
        };
        let p = generate_yarn(&spec).unwrap();
        let scene = parse(&p);
        let fiber_of = p.fiber_of_cylinder();
        let grid = p.truth.grid(spec.radius / 3.0).unwrap();
        let labels = label_volume(&scene.cylinders, &fiber_of, grid).unwrap();
        let [nx, ny, nz] = grid.size;
        let brute: Vec<u32> = (0..nx * ny * nz)
            .into_par_iter()
            .map(|idx| {
                let q = grid.center(idx % nx, idx / nx % ny, idx / (nx * ny));
                scene
                    .cylinders
                    .iter()
                    .position(|c| c.contains(q))
                    .map_or(0, |c| fiber_of[c] + 1)
            })
            .collect();
        let inside = brute.iter().filter(|&&l| l != 0).count();
        assert!(inside > 1000);
        assert_eq!(labels, brute);
        let huge = VoxelGrid {
            size: [1 << 10, 1 << 10, 1 << 9],
            ..grid
        };
        assert!(
            label_volume(&scene.cylinders, &fiber_of, huge)
                .unwrap_err()
                .contains("allowed")
        );
        let nan = VoxelGrid {
            voxel: f64::NAN,
            ..grid
        };
        assert!(label_volume(&scene.cylinders, &fiber_of, nan).is_err());
        assert!(label_volume(&scene.cylinders, &fiber_of[1..], grid).is_err());
    }

    /// A label TIFF reads back page by page with the tiff crate's decoder; a failed write
    /// leaves no file behind.
    #[test]
    fn phantom_labels_tiff_round_trip() {
        use tiff::decoder::{Decoder, DecodingResult};
        let dir = std::env::temp_dir().join(format!("gencyl-phantom-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let grid = VoxelGrid {
            origin: [-1.0, 0.5, 2.0],
            voxel: 0.25,
            size: [7, 5, 3],
        };
        let labels: Vec<u32> = (0..7 * 5 * 3)
            .map(|i| {
                if i % 4 == 0 {
                    0
                } else {
                    (i as u32).wrapping_mul(2_654_435_761)
                }
            })
            .collect();
        let path = dir.join("labels.tif");
        write_labels_tiff(&path, &labels, grid).unwrap();
        let mut dec =
            Decoder::new(std::io::BufReader::new(std::fs::File::open(&path).unwrap())).unwrap();
        let mut pages = Vec::new();
        loop {
            assert_eq!(dec.dimensions().unwrap(), (7, 5));
            assert_eq!(dec.colortype().unwrap(), tiff::ColorType::Gray(32));
            match dec.read_image().unwrap() {
                DecodingResult::U32(v) => pages.extend(v),
                _ => panic!("not 32-bit unsigned"),
            }
            if !dec.more_images() {
                break;
            }
            dec.next_image().unwrap();
        }
        assert_eq!(pages, labels);
        let missing = dir.join("no-such-folder").join("labels.tif");
        assert!(write_labels_tiff(&missing, &labels, grid).is_err());
        let short = dir.join("short.tif");
        assert!(write_labels_tiff(&short, &labels[1..], grid).is_err());
        let left: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(left, vec![std::ffi::OsString::from("labels.tif")]);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Measurements for the documentation (run by hand: `cargo test --release -p gencyl-render
    /// phantom_measure -- --ignored --nocapture`): the packing the relaxation reaches, the time
    /// to generate 10,000 fibers and to label 256^3 voxels.
    #[test]
    #[ignore]
    fn phantom_measure() {
        use std::time::Instant;
        for (twist, aspect) in [(0.0, 1.0), (25.0, 1.0), (25.0, 0.7)] {
            for packing in [0.5, 0.6, 0.7, 0.75, 0.8, 0.85] {
                let spec = YarnSpec {
                    fibers: 300,
                    twist_deg: twist,
                    aspect,
                    aspect_sd: 0.0,
                    section_twist: 0.0,
                    packing,
                    length: 0.2,
                    ..yarn()
                };
                let t0 = Instant::now();
                let r = generate_yarn(&spec);
                eprintln!(
                    "[phantom] 300 fibers, twist {twist}, aspect {aspect}, packing {packing}: {} in {:.2} s",
                    r.as_ref().map_or_else(|e| e.clone(), |_| "ok".into()),
                    t0.elapsed().as_secs_f64()
                );
            }
        }
        for mig in [0.05, 0.1, 0.2] {
            for packing in [0.4, 0.45, 0.5, 0.55] {
                let spec = YarnSpec {
                    fibers: 300,
                    packing,
                    migration: mig,
                    migration_period: 1.0,
                    length: 1.0,
                    ..yarn()
                };
                let t0 = Instant::now();
                let r = generate_yarn(&spec);
                eprintln!(
                    "[phantom] 300 fibers, migration {mig}, packing {packing}: {} in {:.2} s",
                    r.as_ref().map_or_else(
                        |e| e.clone(),
                        |p| format!(
                            "ok, {} segments, {:?}",
                            p.truth.segments_per_fiber.unwrap(),
                            p.truth.packing_check
                        )
                    ),
                    t0.elapsed().as_secs_f64()
                );
            }
        }
        let spec = YarnSpec {
            fibers: 10_000,
            length: 1.0,
            packing: 0.5,
            ..yarn()
        };
        let t0 = Instant::now();
        let p = generate_yarn(&spec).unwrap();
        eprintln!(
            "[phantom] 10,000 fibers: {:.1} s, {} segments, scene {} MB, {:?}",
            t0.elapsed().as_secs_f64(),
            p.truth.segments_per_fiber.unwrap(),
            p.scene_toml.len() >> 20,
            p.truth.packing_check
        );
        let spec = YarnSpec {
            fibers: 300,
            length: 1.0,
            packing: 0.5,
            ..yarn()
        };
        let p = generate_yarn(&spec).unwrap();
        let scene = parse(&p);
        let b = p.truth.bounds;
        let voxel = (0..3).map(|k| b[1][k] - b[0][k]).fold(0.0f64, f64::max) / 256.0;
        let grid = p.truth.grid(voxel).unwrap();
        let t0 = Instant::now();
        let labels = label_volume(&scene.cylinders, &p.fiber_of_cylinder(), grid).unwrap();
        eprintln!(
            "[phantom] labels {:?} of {} cylinders: {:.1} s, {} inside",
            grid.size,
            scene.cylinders.len(),
            t0.elapsed().as_secs_f64(),
            labels.iter().filter(|&&l| l != 0).count()
        );
        // 256^3 voxels across the yarn's diameter, from z = 0.4.
        let grid = VoxelGrid {
            voxel: (b[1][0] - b[0][0]) / 256.0,
            size: [256, 256, 256],
            origin: [b[0][0], b[0][1], 0.4],
        };
        let t0 = Instant::now();
        let labels = label_volume(&scene.cylinders, &p.fiber_of_cylinder(), grid).unwrap();
        eprintln!(
            "[phantom] labels 256^3 cube in the yarn: {:.1} s, {} inside",
            t0.elapsed().as_secs_f64(),
            labels.iter().filter(|&&l| l != 0).count()
        );
        let path = std::env::temp_dir().join("gencyl-phantom-measure.tif");
        let t0 = Instant::now();
        write_labels_tiff(&path, &labels, grid).unwrap();
        eprintln!(
            "[phantom] TIFF: {:.1} s, {} MB",
            t0.elapsed().as_secs_f64(),
            std::fs::metadata(&path).unwrap().len() >> 20
        );
        std::fs::remove_file(&path).unwrap();
    }
}
