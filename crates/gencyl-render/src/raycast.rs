//! The batch behind `gencyl raycast` (interface.md section 3): rays from a ray file, cast in
//! parallel against a [`Scene`], the hits written as CSV in ray order. The file formats are in
//! [`crate::formats::rays`] (re-exported here).
//!
//! Imports: [`crate::accel`] and [`crate::formats`].

use std::io::{self, Write};
use std::time::{Duration, Instant};

use gencyl::{Ray, times_power_of_two};
use rayon::prelude::*;

use crate::accel::{QueryCounts, Scene, SceneHit, Scratch};
pub use crate::formats::rays::{
    HEADER, Num, RayFileError, check_ray, format_row, parse_rays, part_number, rays_from_arrays,
    read_rays,
};

/// What [`raycast`] reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RaycastOptions {
    /// Every hit rather than the nearest.
    pub all: bool,
}

/// What a [`raycast`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RaycastStats {
    /// Rays cast.
    pub rays: usize,
    /// Rows written (hits).
    pub rows: usize,
    /// Time spent intersecting, not writing.
    pub intersect_time: Duration,
    /// What the ray queries did.
    pub counts: QueryCounts,
}

impl RaycastStats {
    /// Rays per second of intersection time.
    pub fn rays_per_second(&self) -> f64 {
        self.rays as f64 / self.intersect_time.as_secs_f64().max(1e-12)
    }
}

/// Rays per parallel work item.
const CHUNK: usize = 256;
/// Rows formatted as one parallel work item.
const FORMAT_CHUNK: usize = 2048;
/// Rows formatted before they are written: bounds the text held at once (about 8 MB).
const FORMAT_BATCH: usize = 32 * FORMAT_CHUNK;
/// Rays intersected before their rows are written: bounds the memory held for output.
pub const BLOCK: usize = 1 << 15;
/// [`BLOCK`] for every hit of each ray (`--all`), whose rows can be a hundred a ray.
const ALL_BLOCK: usize = 1 << 13;

/// Casts every ray against the scene on the current rayon pool and writes the CSV (header and
/// rows, in ray order) to `out`. Rows are for hits with `t > tmin`: the nearest per ray, or
/// with `opts.all` every one, sorted by `t`.
pub fn raycast(
    scene: &Scene,
    rays: &[Ray],
    tmin: f64,
    opts: RaycastOptions,
    out: &mut impl Write,
) -> io::Result<RaycastStats> {
    let mut stats = RaycastStats {
        rays: rays.len(),
        ..Default::default()
    };
    writeln!(out, "{HEADER}")?;
    let size = if opts.all { ALL_BLOCK } else { BLOCK };
    for (b, block) in rays.chunks(size).enumerate() {
        let start = Instant::now();
        let (rows, counts) = cast_rays_counted(scene, block, b * size, tmin, opts.all);
        stats.counts += counts;
        stats.intersect_time += start.elapsed();
        // The rows' text in parallel too (shortest round-trip digits cost about as much as a
        // camera ray's intersection), written in order.
        for batch in rows.chunks(FORMAT_BATCH) {
            let texts: Vec<String> = batch
                .par_chunks(FORMAT_CHUNK)
                .map(|rows| {
                    let mut text = String::with_capacity(rows.len() * 128);
                    for (ray, h) in rows {
                        format_row(&mut text, *ray as usize, h);
                    }
                    text
                })
                .collect();
            for text in &texts {
                out.write_all(text.as_bytes())?;
            }
        }
        stats.rows += rows.len();
    }
    out.flush()?;
    Ok(stats)
}

/// The rows of [`raycast`] for `rays` (in parallel on the current rayon pool): `(ray number,
/// hit)` in ray order, each ray's hits as [`cast`] gives them; ray `i` of the slice is number
/// `first + i`.
///
/// # Panics
///
/// If a ray number does not fit in a `u32`.
pub fn cast_rays(
    scene: &Scene,
    rays: &[Ray],
    first: usize,
    tmin: f64,
    all: bool,
) -> Vec<(u32, SceneHit)> {
    cast_rays_counted(scene, rays, first, tmin, all).0
}

/// [`cast_rays`], and what its queries did.
pub fn cast_rays_counted(
    scene: &Scene,
    rays: &[Ray],
    first: usize,
    tmin: f64,
    all: bool,
) -> (Vec<(u32, SceneHit)>, QueryCounts) {
    assert!(
        u32::try_from(first + rays.len()).is_ok(),
        "ray numbers fit in u32"
    );
    let rows: Vec<(Vec<(u32, SceneHit)>, QueryCounts)> = rays
        .par_chunks(CHUNK)
        .enumerate()
        // Every chunk its own task: rayon's adaptive splitting otherwise leaves a quarter of
        // the block as one sequential run, and a thread idle beside it where the rays' costs
        // are uneven (camera rays: hair in some rows, background in others).
        .with_max_len(1)
        .map(|(c, chunk)| {
            let first = first + c * CHUNK;
            let mut rows = Vec::new();
            let (mut scratch, mut hits) = (Scratch::default(), Vec::new());
            for (i, ray) in chunk.iter().enumerate() {
                hits.clear();
                cast(scene, ray, tmin, all, &mut hits, &mut scratch);
                rows.extend(hits.iter().map(|&h| ((first + i) as u32, h)));
            }
            (rows, scratch.counts())
        })
        .collect();
    let mut counts = QueryCounts::default();
    let mut all_rows = Vec::with_capacity(rows.iter().map(|(r, _)| r.len()).sum());
    for (r, c) in rows {
        counts += c;
        all_rows.extend(r);
    }
    (all_rows, counts)
}

/// The hits of one ray, appended to `out`.
pub fn cast(
    scene: &Scene,
    ray: &Ray,
    tmin: f64,
    all: bool,
    out: &mut Vec<SceneHit>,
    scratch: &mut Scratch,
) {
    // A direction far from unit size is scaled by a power of two, so that the walk's squared
    // lengths neither overflow nor underflow, and `t` scaled back (exactly: the window keeps
    // it a normal `f64`).
    let (ray, e) = ray.in_working_range().unwrap_or((*ray, 0));
    let (tmin, tmax) = if e == 0 {
        (tmin, f64::INFINITY)
    } else {
        Ray::working_window(tmin, f64::INFINITY, e)
    };
    let start = out.len();
    if all {
        scene.all_hits(&ray, tmin, tmax, out, scratch);
    } else if let Some(h) = scene.nearest_hit(&ray, tmin, tmax, scratch) {
        out.push(h);
    }
    if e != 0 {
        for h in &mut out[start..] {
            h.hit.t = times_power_of_two(h.hit.t, e);
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::scene_file::{SceneDescription, SceneError};

    #[test]
    fn extreme_rays_do_not_panic() {
        let src =
            "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\n";
        let scene = Scene::new(SceneDescription::parse(src, "s").unwrap().cylinders);
        let big = [
            1e-320,
            1e-300,
            1e-150,
            1e-20,
            1.0,
            1e20,
            1e150,
            1e300,
            f64::MAX,
        ];
        let (mut out, mut scratch) = (vec![], Scratch::default());
        let mut n = 0;
        for &a in &big {
            for &b in &big {
                for (o, d) in [
                    (DVec3::new(1.5, 0.0, a), DVec3::new(0.0, 0.0, -b)),
                    (DVec3::new(-a, 0.0, 0.0), DVec3::new(b, 0.0, 0.0)),
                    (DVec3::new(a, a, a), DVec3::new(-b, -b, -b)),
                    (DVec3::new(1.5, a, -a), DVec3::new(b, -b, b)),
                ] {
                    for all in [false, true] {
                        out.clear();
                        cast(&scene, &Ray::new(o, d), 0.0, all, &mut out, &mut scratch);
                        for h in &out {
                            assert!(h.hit.t.is_finite() && h.hit.t > 0.0, "ray {o} {d}: {h:?}");
                            assert!(h.hit.normal.is_finite(), "ray {o} {d}: {h:?}");
                        }
                        n += out.len();
                    }
                }
            }
        }
        assert!(n > 0, "some hits");
        // Tiny (even subnormal) and huge directions still find the cylinder, at a huge or tiny t.
        for (z, dz, t) in [
            (0.11, -1e-310, 1e308),
            (1.0, -1e-300, 0.9e300),
            (1.0, -1e300, 0.9e-300),
        ] {
            out.clear();
            let ray = Ray::new(DVec3::new(1.5, 0.0, z), DVec3::new(0.0, 0.0, dz));
            cast(&scene, &ray, 0.0, false, &mut out, &mut scratch);
            let got = out.first().map(|h| h.hit.t);
            // 1e-310 is subnormal, with fewer significant bits: a looser tolerance.
            assert!(
                got.is_some_and(|g| (g / t - 1.0).abs() < 1e-9),
                "{dz}: {got:?}"
            );
        }
        // A tiny direction still finds the cylinder, at a huge t.
        out.clear();
        cast(
            &scene,
            &Ray::new(DVec3::new(1.5, 0.0, 1.0), DVec3::new(0.0, 0.0, -1e-200)),
            0.0,
            false,
            &mut out,
            &mut scratch,
        );
        let t = out.first().map(|h| h.hit.t);
        assert!(
            t.is_some_and(|t| (t / 0.9e200 - 1.0).abs() < 1e-12),
            "{t:?}"
        );
    }

    #[test]
    fn rows_across_blocks_and_format_batches_keep_ray_order() {
        // Rays across a short fiber: 80,000 nearest-hit rays (three blocks, two format
        // batches), and 20,000 with every hit (three blocks of `--all`, two rows a hit ray).
        let src =
            "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\n";
        let scene = Scene::new(SceneDescription::parse(src, "s").unwrap().cylinders);
        for (n, all) in [(80_000, false), (20_000, true)] {
            let rays: Vec<Ray> = (0..n)
                .map(|i| {
                    let x = 3.2 * (i % 1000) as f64 / 1000.0 - 0.1;
                    let y = 0.25 * ((i / 1000) as f64 / (n / 1000) as f64) - 0.125;
                    Ray::new(DVec3::new(x, y, 1.0), DVec3::new(0.01, 0.0, -1.0))
                })
                .collect();
            let mut out = Vec::new();
            let stats = raycast(&scene, &rays, 0.0, RaycastOptions { all }, &mut out).unwrap();
            let mut want = format!("{HEADER}\n");
            let (mut hits, mut scratch) = (Vec::new(), Scratch::default());
            let mut rows = 0;
            for (i, ray) in rays.iter().enumerate() {
                hits.clear();
                cast(&scene, ray, 0.0, all, &mut hits, &mut scratch);
                for h in &hits {
                    format_row(&mut want, i, h);
                    rows += 1;
                }
            }
            assert!(rows > n / 2, "most rays hit: {rows}");
            assert_eq!(stats.rows, rows, "rows, all = {all}");
            assert!(
                String::from_utf8(out).unwrap() == want,
                "the CSV, all = {all}"
            );
        }
    }

    #[test]
    fn output_rows() {
        let src =
            "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\n";
        let scene = Scene::new(SceneDescription::parse(src, "s").unwrap().cylinders);
        let rays = parse_rays(
            "1.5,0,1, 0,0,-1\n1.5,0.2,1, 0,0,-1\n-1,0,0,1,0,0\n".as_bytes(),
            "r",
        )
        .unwrap();
        let mut out = Vec::new();
        let stats = raycast(&scene, &rays, 0.0, RaycastOptions::default(), &mut out).unwrap();
        let text = String::from_utf8(out).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], HEADER, "{text}");
        assert_eq!(lines.len(), 3, "{text}");
        let close = |line: &str, want: [f64; 9]| {
            let got: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
            // v is free on the axis-perpendicular ray and the cap: not compared.
            let ok = got.len() == 9 && (0..9).all(|i| i == 3 || (got[i] - want[i]).abs() < 1e-12);
            assert!(ok, "row {line} vs {want:?}");
        };
        close(lines[1], [0.0, 0.9, 0.5, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0]);
        close(lines[2], [2.0, 1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 1.0]);
        assert_eq!(stats.rows, 2, "rows");
        let mut out = Vec::new();
        let stats = raycast(&scene, &rays, 0.0, RaycastOptions { all: true }, &mut out).unwrap();
        assert_eq!(
            stats.rows,
            4,
            "entry and exit of two rays: {}",
            String::from_utf8_lossy(&out)
        );
    }

    #[test]
    fn extreme_scenes_do_not_panic() {
        // Scenes at scales from 1e-150 to 1e150, rays of any magnitude: no panic, no NaN.
        use crate::sampling::SampleRng as Rng;
        let mut rng = Rng::from_seed(77);
        let mags = [
            0.0, 1e-300, 1e-150, 1e-20, 1e-3, 1.0, 1e3, 1e20, 1e150, 1e300,
        ];
        let pick = |rng: &mut Rng| {
            mags[(rng.uniform() * mags.len() as f64) as usize] * rng.range(-1.0, 1.0)
        };
        let mut built = 0;
        for _ in 0..100 {
            let scale = [1e-150, 1e-20, 1.0, 1e20, 1e150][(rng.uniform() * 5.0) as usize];
            let mut src = String::new();
            for _ in 0..3 {
                let p: Vec<String> = (0..4)
                    .map(|_| {
                        let v = [0; 3].map(|_| scale * rng.range(-1.0, 1.0));
                        format!("[{:e}, {:e}, {:e}]", v[0], v[1], v[2])
                    })
                    .collect();
                let r = [scale * rng.range(0.01, 0.2), scale * rng.range(0.01, 0.2)];
                src.push_str(&format!(
                    "[[cylinder]]\nbezier = [{}]\nmajor_radius = [{:e}, {:e}]\n",
                    p.join(", "),
                    r[0],
                    r[1]
                ));
                if rng.uniform() < 0.1 {
                    src.push_str(&format!(
                        "minor_radius = [{:e}, {:e}]\nrotation = [{:e}, 1.0]\n",
                        r[1],
                        r[0],
                        pick(&mut rng)
                    ));
                }
            }
            let Ok(desc) = SceneDescription::parse(&src, "s") else {
                continue;
            };
            built += 1;
            let scene = Scene::new(desc.cylinders);
            let rays: Vec<Ray> = (0..12)
                .map(|i| {
                    let o = if i % 2 == 0 {
                        DVec3::new(pick(&mut rng), pick(&mut rng), pick(&mut rng))
                    } else {
                        DVec3::new(
                            rng.range(-2.0, 2.0),
                            rng.range(-2.0, 2.0),
                            rng.range(-2.0, 2.0),
                        ) * scale
                    };
                    let d = DVec3::new(pick(&mut rng), pick(&mut rng), pick(&mut rng));
                    Ray::new(o, if d == DVec3::ZERO { DVec3::X } else { d })
                })
                .collect();
            for all in [false, true] {
                let mut out = Vec::new();
                raycast(&scene, &rays, 0.0, RaycastOptions { all }, &mut out).unwrap();
                for line in String::from_utf8(out).unwrap().lines().skip(1) {
                    assert!(
                        !line.contains("NaN") && !line.contains("inf"),
                        "{line} for scene\n{src}"
                    );
                }
            }
        }
        assert!(built > 25, "some scenes should build: {built}");
    }

    #[test]
    fn garbage_never_panics_the_parsers() {
        use crate::sampling::SampleRng as Rng;
        let mut rng = Rng::from_seed(5);
        let base = "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\nprofile = [[1,0],[1,1],[0,1],[-1,0],[-1,-1],[0,-1]]\n";
        let rays = "ox,oy,oz,dx,dy,dz\n1.5,0,1, 0,0,-1\n-1,0,0,1,0,0\n";
        for i in 0..3000 {
            let src = if i % 2 == 0 { base } else { rays };
            let mut bytes = src.as_bytes().to_vec();
            for _ in 0..1 + (rng.uniform() * 4.0) as usize {
                let at = (rng.uniform() * bytes.len() as f64) as usize;
                match rng.next_u64() % 3 {
                    0 => bytes[at] = rng.next_u64() as u8,
                    1 => {
                        bytes.remove(at);
                    }
                    _ => bytes.insert(at, b"[],.=#\n\"e9-nan"[(rng.next_u64() % 14) as usize]),
                }
            }
            let _ = SceneDescription::parse_bytes(&bytes, "s").map(|d| Scene::new(d.cylinders));
            let _ = parse_rays(&bytes[..], "r");
            if let Err(SceneError::Invalid(d)) = SceneDescription::parse_bytes(&bytes, "s") {
                let _ = d.render();
            }
        }
    }
}
