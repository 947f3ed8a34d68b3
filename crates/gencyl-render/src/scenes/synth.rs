//! Synthetic scenes and rays for tests and benchmarks: random curved fibers in a cube, rays
//! aimed into it, and writers for the scene (TOML) and ray (CSV) file formats.
//!
//! Everything is seeded, so a failing case can be re-made exactly. The `random_scene` example
//! writes such files: `cargo run --release -p gencyl-render --example random_scene -- --help`.

use std::fmt::Write as _;

use gencyl::{BezierLoop, FiberSpec, Ray, Section};
use glam::{DVec2, DVec3};

use crate::sampling::SampleRng as Rng;

/// What [`random_fibers`] makes.
#[derive(Clone, Debug, PartialEq)]
pub struct FiberParams {
    /// How many fibers.
    pub count: usize,
    /// Chord length of each fiber.
    pub length: f64,
    /// Radius (the major radius of elliptical fibers).
    pub radius: f64,
    /// How far the inner control points stray from the chord, relative to `length`.
    pub bend: f64,
    /// Fraction of fibers with an elliptical, tapering, twisted section (the rest are round).
    pub elliptical_fraction: f64,
    /// Fraction of fibers with a Bezier-loop profile (a rounded, flattened square).
    pub profile_fraction: f64,
    /// Fibers' midpoints lie in the cube `[lo, hi]^3`.
    pub cube: [f64; 2],
}

impl Default for FiberParams {
    /// 1,000 round fibers of length 1 and radius 0.02 with midpoints in the unit cube.
    fn default() -> Self {
        FiberParams {
            count: 1000,
            length: 1.0,
            radius: 0.02,
            bend: 0.15,
            elliptical_fraction: 0.0,
            profile_fraction: 0.0,
            cube: [0.0, 1.0],
        }
    }
}

/// Random curved fibers: a random chord of length `length` through a random midpoint, inner
/// control points at its thirds moved by up to `bend * length` in random directions. Fibers
/// whose axis would have a cusp are drawn again, so every spec builds.
pub fn random_fibers(p: &FiberParams, seed: u64) -> Vec<FiberSpec> {
    let mut rng = Rng::from_seed(seed);
    let (lo, hi) = (DVec3::splat(p.cube[0]), DVec3::splat(p.cube[1]));
    let mut out = Vec::with_capacity(p.count);
    while out.len() < p.count {
        let mid = rng.in_box(lo, hi);
        let dir = rng.unit_vector();
        let p0 = mid - 0.5 * p.length * dir;
        let p3 = mid + 0.5 * p.length * dir;
        let p1 = p0 + p.length * (dir / 3.0 + p.bend * rng.uniform() * rng.unit_vector());
        let p2 = p0 + p.length * (2.0 * dir / 3.0 + p.bend * rng.uniform() * rng.unit_vector());
        let mut spec = FiberSpec::round([p0, p1, p2, p3], p.radius);
        let kind = rng.uniform();
        if kind < p.elliptical_fraction {
            spec.major_radius = [p.radius, p.radius * rng.range(0.6, 1.0)];
            spec.minor_radius = [
                p.radius * rng.range(0.4, 0.8),
                p.radius * rng.range(0.4, 0.6),
            ];
            spec.rotation = [rng.range(0.0, 6.3), rng.range(-6.3, 6.3)];
        } else if kind < p.elliptical_fraction + p.profile_fraction {
            spec.section = Section::Loop(squarish_profile(rng.range(0.5, 1.0)));
        }
        spec.caps = rng.uniform() < 0.8;
        if spec.build().is_ok() {
            out.push(spec);
        }
    }
    out
}

/// A rounded square flattened to height `aspect`, as a four-piece Bezier loop.
pub fn squarish_profile(aspect: f64) -> BezierLoop {
    let pts = [
        [1.0, -1.0],
        [1.2, 0.0],
        [1.0, 1.0],
        [1.0, 1.0],
        [0.0, 1.2],
        [-1.0, 1.0],
    ]
    .iter()
    .chain(&[
        [-1.0, 1.0],
        [-1.2, 0.0],
        [-1.0, -1.0],
        [-1.0, -1.0],
        [0.0, -1.2],
        [1.0, -1.0],
    ])
    .map(|&[x, y]| DVec2::new(x, y * aspect) / 1.2)
    .collect::<Vec<_>>();
    BezierLoop::new(&pts).expect("a rounded square is a valid profile")
}

/// Random rays from the sphere of radius `2 * size` about the fibers' cube's centre, aimed at
/// uniform points of the cube; directions have random lengths in `[0.5, 2)` of the distance.
pub fn random_rays(count: usize, seed: u64, p: &FiberParams) -> Vec<Ray> {
    let (lo, hi) = (DVec3::splat(p.cube[0]), DVec3::splat(p.cube[1]));
    rays_through_box(count, seed, lo, hi, (hi - lo).max_element().max(p.length))
}

/// Incoherent rays through the box `[lo, hi]`: each from a uniformly random point of the sphere
/// of radius `2 size` about the box's centre toward a uniformly random point of the box, with a
/// direction of random length (0.5 to 2 times the distance). Seeded, so reproducible.
pub fn rays_through_box(count: usize, seed: u64, lo: DVec3, hi: DVec3, size: f64) -> Vec<Ray> {
    let mut rng = Rng::from_seed(seed ^ 0x5eed);
    let centre = 0.5 * (lo + hi);
    (0..count)
        .map(|_| {
            let origin = centre + 2.0 * size * rng.unit_vector();
            let target = rng.in_box(lo, hi);
            Ray::new(origin, (target - origin) * rng.range(0.5, 2.0))
        })
        .collect()
}

/// `[x, y, z]` in TOML, every number with a decimal point or exponent.
fn toml_vec(v: &[f64]) -> String {
    let items: Vec<String> = v.iter().map(|x| format!("{x:?}")).collect();
    format!("[{}]", items.join(", "))
}

/// The scene file (`[[cylinder]]` tables) for `specs`.
pub fn scene_toml(specs: &[FiberSpec]) -> String {
    let mut s = String::new();
    for f in specs {
        let pts: Vec<String> = f.bezier.iter().map(|p| toml_vec(&p.to_array())).collect();
        let _ = writeln!(s, "[[cylinder]]\nbezier = [{}]", pts.join(", "));
        let _ = writeln!(s, "major_radius = {}", toml_vec(&f.major_radius));
        if f.minor_radius != f.major_radius {
            let _ = writeln!(s, "minor_radius = {}", toml_vec(&f.minor_radius));
        }
        if f.rotation != [0.0, 0.0] {
            let _ = writeln!(s, "rotation = {}", toml_vec(&f.rotation));
        }
        if !f.caps {
            let _ = writeln!(s, "caps = false");
        }
        if let Some(h) = f.normal_hint {
            let _ = writeln!(s, "normal_hint = {}", toml_vec(&h.to_array()));
        }
        if let Section::Loop(l) = &f.section {
            let pts: Vec<String> = l
                .pieces()
                .iter()
                .flat_map(|p| &p[..3])
                .map(|q| toml_vec(&q.to_array()))
                .collect();
            let _ = writeln!(s, "profile = [{}]", pts.join(", "));
        }
        s.push('\n');
    }
    s
}

/// The ray file for `rays`: a header line, then `ox,oy,oz,dx,dy,dz` per line.
pub fn rays_csv(rays: &[Ray]) -> String {
    let mut s = String::from("ox,oy,oz,dx,dy,dz\n");
    for r in rays {
        let (o, d) = (r.origin, r.dir);
        let _ = writeln!(s, "{},{},{},{},{},{}", o.x, o.y, o.z, d.x, d.y, d.z);
    }
    s
}

/// A generated head of hair for scale tests: `strands` strands of `segments` segments rooted
/// on the upper part of a unit-radius scalp at the origin, growing out from it, falling under
/// gravity and waving; thickness (diameter) 0.004 at the root, 0.002 at the tip. Returns the
/// points of each strand, root first, and their thickness, as [`crate::formats::hair::write_hair`]
/// takes them.
pub fn hair_model(strands: usize, segments: usize, seed: u64) -> (Vec<Vec<DVec3>>, Vec<Vec<f64>>) {
    use rayon::prelude::*;
    let points: Vec<Vec<DVec3>> = (0..strands)
        .into_par_iter()
        .map(|i| {
            let mut rng = Rng::from_seed(seed ^ (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15));
            // A root on the scalp above y = -0.1, not on the face (z > 0.5, y < 0.6).
            let n = loop {
                let n = rng.unit_vector();
                if n.y > -0.1 && !(n.z > 0.5 && n.y < 0.6) {
                    break n;
                }
            };
            let length = rng.range(1.4, 2.2);
            let step = length / segments as f64;
            let wave = DVec3::new(rng.range(-1.0, 1.0), 0.0, rng.range(-1.0, 1.0));
            let (freq, phase) = (rng.range(4.0, 9.0), rng.range(0.0, std::f64::consts::TAU));
            let mut p = n * 1.0;
            let mut dir = n;
            let mut out = Vec::with_capacity(segments + 1);
            out.push(p);
            for k in 0..segments {
                let s = (k as f64 + 0.5) / segments as f64;
                // Fall under gravity, wave sideways, and stay outside the scalp.
                dir = (dir
                    + DVec3::new(0.0, -0.35, 0.0)
                    + wave * 0.25 * (freq * s * 3.0 + phase).sin())
                .normalize();
                let next = p + dir * step;
                let lift = 1.02 + 0.1 * s - next.length();
                p = if lift > 0.0 {
                    next + next.normalize() * lift
                } else {
                    next
                };
                out.push(p);
            }
            out
        })
        .collect();
    let thickness = points
        .iter()
        .map(|s| {
            (0..s.len())
                .map(|k| 0.004 - 0.002 * k as f64 / (s.len() - 1) as f64)
                .collect()
        })
        .collect();
    (points, thickness)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene_file::SceneDescription;

    #[test]
    fn written_scene_reads_back() {
        let p = FiberParams {
            count: 30,
            elliptical_fraction: 0.3,
            profile_fraction: 0.3,
            ..FiberParams::default()
        };
        let specs = random_fibers(&p, 9);
        let text = scene_toml(&specs);
        let scene = SceneDescription::parse(&text, "synth.toml").unwrap();
        assert_eq!(scene.cylinders.len(), 30, "count");
        for (spec, cyl) in specs.iter().zip(&scene.cylinders) {
            assert_eq!(spec.build().unwrap(), *cyl, "round trip of {spec:?}");
        }
    }

    #[test]
    fn rng_is_uniformish() {
        let mut r = Rng::from_seed(1);
        let mean = (0..10_000).map(|_| r.uniform()).sum::<f64>() / 10_000.0;
        assert!((mean - 0.5).abs() < 0.01, "mean {mean}");
        let v = r.unit_vector();
        assert!((v.length() - 1.0).abs() < 1e-12, "unit vector {v}");
    }
}
