//! Batch ray casting: the ray file format, parallel intersection, the hit CSV
//! (interface.md section 3).
//!
//! # Ray file
//!
//! One ray per line, `ox,oy,oz,dx,dy,dz`: six numbers separated by commas, spaces or tabs
//! around them allowed. `d` need not be unit length. Blank lines and lines starting with `#`
//! are skipped, and so are lines starting with a letter (a header such as
//! `ox,oy,oz,dx,dy,dz`), unless the line is six numbers (`nan,0,0,1,0,0`: a data line, and a bad
//! one). Rays are numbered 0, 1, 2, ... among the data lines. Every number must be finite and
//! the direction non-zero.
//!
//! ```
//! use gencyl_render::raycast::parse_rays;
//!
//! let text = "ox,oy,oz,dx,dy,dz\n# a comment\n\n1.5,0,1, 0,0,-1\n-1, 0, 0, 1e0, 0, 0\n";
//! let rays = parse_rays(text.as_bytes(), "rays.csv").unwrap();
//! assert_eq!(rays.len(), 2);
//! assert_eq!(rays[1].dir.x, 1.0);
//!
//! let err = parse_rays("1,2,3\n0,0,0,0,0,nan\n".as_bytes(), "rays.csv").unwrap_err();
//! assert_eq!(err.to_string(), "rays.csv:1: expected 6 numbers, found 3");
//! ```
//!
//! # Output
//!
//! CSV, the header `ray,t,u,v,nx,ny,nz,object,part`, then one row per hit: the ray's number,
//! the hit's `t`, `u`, `v`, unit outward normal, cylinder number and part (0 side, 1 cap at
//! `u = 0`, 2 cap at `u = 1`). Numbers are written in the shortest form that reads back to
//! the same `f64` (so with full precision), in exponent form below `1e-7` or from `1e16` in
//! magnitude, and `-0` as `0`.

use std::fmt;
use std::io::{self, BufRead, Write};
use std::time::{Duration, Instant};

use gencyl::{Part, Ray};
use glam::DVec3;
use rayon::prelude::*;

use crate::scene::{Scene, SceneHit, Scratch};

/// Why a ray file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum RayFileError {
    /// The file could not be read.
    #[error("{path}: cannot read: {error}")]
    Read {
        /// The file's name as given.
        path: String,
        /// Why.
        error: io::Error,
    },
    /// A line is not a valid ray.
    #[error("{path}:{line}: {message}")]
    Invalid {
        /// The file's name as given.
        path: String,
        /// 1-based line number in the file (counting every line).
        line: usize,
        /// What is wrong.
        message: String,
    },
}

/// The names of a ray's six numbers, for messages.
const FIELDS: [&str; 6] = ["ox", "oy", "oz", "dx", "dy", "dz"];

/// Reads the ray file at `path` (`-` for standard input): every ray, validated. Nothing is
/// returned unless every line is valid.
pub fn read_rays(path: &str) -> Result<Vec<Ray>, RayFileError> {
    if path == "-" {
        parse_rays(io::stdin().lock(), "<stdin>")
    } else {
        let f = std::fs::File::open(path).map_err(|error| RayFileError::Read {
            path: path.to_string(),
            error,
        })?;
        parse_rays(io::BufReader::with_capacity(1 << 16, f), path)
    }
}

/// Parses a ray file from `reader`; `name` is the file's name for messages. Reads line by
/// line, so only the rays are held in memory.
pub fn parse_rays(mut reader: impl BufRead, name: &str) -> Result<Vec<Ray>, RayFileError> {
    let mut rays = Vec::new();
    let mut buf = Vec::new();
    let mut line_no = 0;
    loop {
        buf.clear();
        let n = reader
            .read_until(b'\n', &mut buf)
            .map_err(|error| RayFileError::Read {
                path: name.to_string(),
                error,
            })?;
        if n == 0 {
            break;
        }
        line_no += 1;
        let bad = |message: String| RayFileError::Invalid {
            path: name.to_string(),
            line: line_no,
            message,
        };
        let Ok(text) = std::str::from_utf8(&buf) else {
            return Err(bad("the line is not valid UTF-8 text".to_string()));
        };
        let text = if line_no == 1 {
            text.trim_start_matches('\u{feff}')
        } else {
            text
        };
        if let Some(ray) = parse_line(text).map_err(bad)? {
            rays.push(ray);
        }
    }
    Ok(rays)
}

/// One line: `Ok(None)` for a line to skip, the ray, or what is wrong.
fn parse_line(text: &str) -> Result<Option<Ray>, String> {
    let text = text.trim();
    let header = text.starts_with(|c: char| c.is_alphabetic());
    if text.is_empty() || text.starts_with('#') {
        return Ok(None);
    }
    let fields: Vec<&str> = text.split(',').map(str::trim).collect();
    let numbers: Vec<Result<f64, _>> = fields.iter().map(|f| f.parse::<f64>()).collect();
    if header && (fields.len() != 6 || numbers.iter().any(Result::is_err)) {
        return Ok(None);
    }
    if fields.len() != 6 {
        return Err(format!("expected 6 numbers, found {}", fields.len()));
    }
    let mut v = [0.0; 6];
    for (i, (f, x)) in fields.iter().zip(numbers).enumerate() {
        v[i] = match x {
            Ok(x) if x.is_finite() => x,
            Ok(x) => return Err(format!("{} is not finite ({x})", FIELDS[i])),
            Err(_) if f.is_empty() => return Err(format!("{} is missing", FIELDS[i])),
            Err(_) => {
                return Err(format!(
                    "{} is not a number: {:?}",
                    FIELDS[i],
                    truncate(f, 40)
                ));
            }
        };
    }
    let ray = Ray::new(DVec3::new(v[0], v[1], v[2]), DVec3::new(v[3], v[4], v[5]));
    if ray.dir == DVec3::ZERO {
        return Err("the direction (dx, dy, dz) is zero".to_string());
    }
    Ok(Some(ray))
}

fn truncate(s: &str, n: usize) -> String {
    match s.char_indices().nth(n) {
        Some((i, _)) => format!("{}...", &s[..i]),
        None => s.to_string(),
    }
}

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
}

impl RaycastStats {
    /// Rays per second of intersection time.
    pub fn rays_per_second(&self) -> f64 {
        self.rays as f64 / self.intersect_time.as_secs_f64().max(1e-12)
    }
}

/// Rays per parallel work item.
const CHUNK: usize = 256;
/// Rays intersected before their rows are written: bounds the memory held for output.
const BLOCK: usize = 1 << 13;

/// The CSV header.
pub const HEADER: &str = "ray,t,u,v,nx,ny,nz,object,part";

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
    let mut line = String::with_capacity(256);
    for (b, block) in rays.chunks(BLOCK).enumerate() {
        let start = Instant::now();
        let rows: Vec<Vec<(u32, SceneHit)>> = block
            .par_chunks(CHUNK)
            .enumerate()
            .map(|(c, chunk)| {
                let first = b * BLOCK + c * CHUNK;
                let mut rows = Vec::new();
                let (mut scratch, mut hits) = (Scratch::default(), Vec::new());
                for (i, ray) in chunk.iter().enumerate() {
                    hits.clear();
                    cast(scene, ray, tmin, opts.all, &mut hits, &mut scratch);
                    rows.extend(hits.iter().map(|&h| ((first + i) as u32, h)));
                }
                rows
            })
            .collect();
        stats.intersect_time += start.elapsed();
        for (ray, h) in rows.iter().flatten() {
            line.clear();
            format_row(&mut line, *ray as usize, h);
            out.write_all(line.as_bytes())?;
            stats.rows += 1;
        }
    }
    out.flush()?;
    Ok(stats)
}

/// A ray whose direction is far from unit size is cast with the direction scaled by a power
/// of two (exact), so squared lengths neither overflow nor underflow; `t` is scaled back.
const SCALE_LIMIT: f64 = 1e100;

/// The hits of one ray, appended to `out`.
pub fn cast(
    scene: &Scene,
    ray: &Ray,
    tmin: f64,
    all: bool,
    out: &mut Vec<SceneHit>,
    scratch: &mut Scratch,
) {
    let m = ray.dir.abs().max_element();
    // 2^e with d 2^e having its largest component in [1, 2); e in [-1024, 1074].
    let e = if (1.0 / SCALE_LIMIT..SCALE_LIMIT).contains(&m) {
        0
    } else {
        -(m.log2().floor() as i32)
    };
    // x 2^k, exact (barring overflow and underflow) for |k| up to 2046, in two steps since
    // 2^k alone may be out of range.
    let scale = |x: f64, k: i32| x * 2f64.powi(k / 2) * 2f64.powi(k - k / 2);
    let ray = Ray::new(
        ray.origin,
        ray.dir * 2f64.powi(e / 2) * 2f64.powi(e - e / 2),
    );
    // The scaled ray's t': o + t' (d 2^e) = o + t d, so t = t' 2^e.
    let start = out.len();
    let tmin = scale(tmin, -e);
    if all {
        scene.all_hits(&ray, tmin, f64::INFINITY, out, scratch);
    } else if let Some(h) = scene.nearest_hit(&ray, tmin, f64::INFINITY, scratch) {
        out.push(h);
    }
    if e != 0 {
        for h in &mut out[start..] {
            h.hit.t = scale(h.hit.t, e);
        }
        // A t beyond f64 range after scaling back is not a usable hit.
        let mut k = start;
        for j in start..out.len() {
            if out[j].hit.t.is_finite() {
                out[k] = out[j];
                k += 1;
            }
        }
        out.truncate(k);
    }
}

/// One CSV row, with its newline.
pub fn format_row(s: &mut String, ray: usize, h: &SceneHit) {
    use fmt::Write as _;
    let x = &h.hit;
    let part = match x.part {
        Part::Side => 0,
        Part::StartCap => 1,
        Part::EndCap => 2,
    };
    let n = x.normal;
    let _ = writeln!(
        s,
        "{ray},{},{},{},{},{},{},{},{part}",
        Num(x.t),
        Num(x.u),
        Num(x.v),
        Num(n.x),
        Num(n.y),
        Num(n.z),
        h.object
    );
}

/// An `f64` for the CSV: shortest round-trip digits, `-0` as `0`, exponent form for very large
/// or small magnitudes (where plain notation would print hundreds of zeros).
#[derive(Clone, Copy, Debug)]
pub struct Num(pub f64);

impl fmt::Display for Num {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let x = if self.0 == 0.0 { 0.0 } else { self.0 };
        let a = x.abs();
        if x == 0.0 || (1e-7..1e16).contains(&a) || !a.is_finite() {
            write!(f, "{x}")
        } else {
            write!(f, "{x:e}")
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::SceneDescription;

    fn err(text: &str) -> String {
        parse_rays(text.as_bytes(), "rays.csv")
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn skips_headers_comments_blanks() {
        let t = "\u{feff}ox, oy, oz, dx, dy, dz\r\n\r\n  # c\n\t1, 2, 3, 4, 5, 6 \r\nX\n+1,-2,.5,5.,1e-3,-0\n";
        let rays = parse_rays(t.as_bytes(), "r").unwrap();
        assert_eq!(rays.len(), 2, "{rays:?}");
        assert_eq!(
            rays[1].origin,
            DVec3::new(1.0, -2.0, 0.5),
            "signs and forms"
        );
        assert_eq!(rays[1].dir, DVec3::new(5.0, 1e-3, 0.0), "signs and forms");
        assert!(
            parse_rays("".as_bytes(), "r").unwrap().is_empty(),
            "empty file"
        );
        assert!(
            parse_rays("\n\n".as_bytes(), "r").unwrap().is_empty(),
            "blank file"
        );
        // No final newline.
        assert_eq!(
            parse_rays("1,2,3,4,5,6".as_bytes(), "r").unwrap().len(),
            1,
            "no final newline"
        );
    }

    #[test]
    fn bad_lines_name_the_line() {
        assert_eq!(
            err("#\n1,2,3,4,5\n"),
            "rays.csv:2: expected 6 numbers, found 5"
        );
        assert_eq!(
            err("1,2,3,4,5,6,\n"),
            "rays.csv:1: expected 6 numbers, found 7"
        );
        assert_eq!(err("1,2,3,4,5,NaN\n"), "rays.csv:1: dz is not finite (NaN)");
        assert_eq!(
            err("1,2,3,4,5,1e400\n"),
            "rays.csv:1: dz is not finite (inf)"
        );
        assert_eq!(err("nan,2,3,4,5,6\n"), "rays.csv:1: ox is not finite (NaN)");
        assert_eq!(
            err("1,2,3,0,0,-0\n"),
            "rays.csv:1: the direction (dx, dy, dz) is zero"
        );
        assert_eq!(err("1,2,,4,5,6\n"), "rays.csv:1: oz is missing");
        assert_eq!(
            err("1,2,3,4,5,6x\n"),
            "rays.csv:1: dz is not a number: \"6x\""
        );
        assert_eq!(
            err("1 2 3 4 5 6\n"),
            "rays.csv:1: expected 6 numbers, found 1"
        );
        assert_eq!(
            err("1,2,3,4,5,6\n\u{2603}\n"),
            "rays.csv:2: expected 6 numbers, found 1"
        );
        let e = parse_rays(&b"1,2,3,4,5,6\n\xff\xfe\n"[..], "rays.csv")
            .unwrap_err()
            .to_string();
        assert_eq!(e, "rays.csv:2: the line is not valid UTF-8 text");
    }

    #[test]
    fn numbers_are_shortest_round_trip() {
        let f = |x: f64| Num(x).to_string();
        assert_eq!(f(-0.0), "0");
        assert_eq!(f(0.9), "0.9");
        assert_eq!(f(1.0), "1");
        assert_eq!(f(-1.5), "-1.5");
        assert_eq!(f(1e-17), "1e-17");
        assert_eq!(f(1e300), "1e300");
        for x in [
            0.1 + 0.2,
            std::f64::consts::PI,
            1.0 / 3.0,
            1e-7,
            123456789.12345679,
            2.5e-8,
            1e16,
            9.99e15,
        ] {
            assert_eq!(
                f(x).parse::<f64>().unwrap(),
                x,
                "{x} round trips via {}",
                f(x)
            );
        }
    }

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
            if let Err(crate::scene::SceneError::Invalid(d)) =
                SceneDescription::parse_bytes(&bytes, "s")
            {
                let _ = d.render();
            }
        }
    }
}
