//! Ray files and the hit CSV of `gencyl raycast` (interface.md section 3).
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
//! use gencyl_render::formats::rays::parse_rays;
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
//! `u = 0`, 2 cap at `u = 1`, 3 seam). Numbers are written in the shortest form that reads back to
//! the same `f64` (so with full precision), in exponent form below `1e-7` or from `1e16` in
//! magnitude, and `-0` as `0`.

use std::fmt;
use std::io::{self, BufRead, Read};

use crate::limits::MAX_RAY_LINE;

use gencyl::{Part, Ray};
use glam::DVec3;

use crate::accel::SceneHit;

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
        let read_err = |error| RayFileError::Read {
            path: path.to_string(),
            error,
        };
        crate::limits::check_readable(std::path::Path::new(path)).map_err(read_err)?;
        let f = std::fs::File::open(path).map_err(read_err)?;
        parse_rays(io::BufReader::with_capacity(1 << 16, f), path)
    }
}

/// Parses a ray file from `reader`; `name` is the file's name for messages. Reads line by
/// line, so only the rays are held in memory; a line longer than
/// [`crate::limits::MAX_RAY_LINE`] bytes is an error, and so are more rays than memory holds.
pub fn parse_rays(mut reader: impl BufRead, name: &str) -> Result<Vec<Ray>, RayFileError> {
    let mut rays = Vec::new();
    let mut buf = Vec::new();
    let mut line_no = 0;
    loop {
        buf.clear();
        let n = (&mut reader)
            .take(MAX_RAY_LINE as u64 + 1)
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
        if buf.len() > MAX_RAY_LINE && buf.last() != Some(&b'\n') {
            return Err(bad(format!(
                "the line is longer than {MAX_RAY_LINE} bytes (a ray is six numbers)"
            )));
        }
        if rays.len() == rays.capacity() && rays.try_reserve(rays.len().max(1024)).is_err() {
            return Err(bad(format!(
                "{} rays read: no memory for more ({} each)",
                rays.len(),
                std::mem::size_of::<Ray>()
            )));
        }
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
            Ok(x) => x,
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
    check_ray(v).map(Some)
}

/// The ray `ox, oy, oz, dx, dy, dz`, or what is wrong with it: a number that is not finite, a
/// zero direction. The one check of every ray, from a file or from an array.
#[inline]
pub fn check_ray(v: [f64; 6]) -> Result<Ray, String> {
    // Branch-free on the common path; the place of a bad number only when there is one.
    let finite = v.iter().fold(true, |ok, x| ok & x.is_finite());
    if !finite {
        let i = v.iter().position(|x| !x.is_finite()).unwrap_or(0);
        return Err(format!("{} is not finite ({})", FIELDS[i], v[i]));
    }
    let ray = Ray::new(DVec3::new(v[0], v[1], v[2]), DVec3::new(v[3], v[4], v[5]));
    if ray.dir == DVec3::ZERO {
        return Err("the direction (dx, dy, dz) is zero".to_string());
    }
    Ok(ray)
}

/// Rays from flat arrays of origins `[ox, oy, oz, ...]` and directions `[dx, dy, dz, ...]`
/// (three values a ray, as many of each), each checked as [`check_ray`] checks a line; the
/// error gives the first bad ray's index and what is wrong with it. Runs in parallel on the
/// current rayon pool.
///
/// # Panics
///
/// If the arrays differ in length or their length is not a multiple of 3.
pub fn rays_from_arrays(origins: &[f64], directions: &[f64]) -> Result<Vec<Ray>, (usize, String)> {
    use rayon::prelude::*;
    assert!(
        origins.len() == directions.len() && origins.len().is_multiple_of(3),
        "three values a ray in each array"
    );
    // What check_ray accepts, tested a block at a time without branches (so vectorised).
    const BLOCK: usize = 3 * 4096;
    let good = origins
        .par_chunks(BLOCK)
        .zip(directions.par_chunks(BLOCK))
        .all(|(o, d)| {
            let finite = |v: &[f64]| v.iter().fold(true, |ok, x| ok & x.is_finite());
            let moving = d.chunks_exact(3).fold(true, |ok, v| {
                ok & (v[0] != 0.0 || v[1] != 0.0 || v[2] != 0.0)
            });
            finite(o) & finite(d) & moving
        });
    let ray = |o: &[f64], d: &[f64]| [o[0], o[1], o[2], d[0], d[1], d[2]];
    if good {
        return Ok(origins
            .par_chunks_exact(3)
            .zip(directions.par_chunks_exact(3))
            .map(|(o, d)| Ray::new(DVec3::from_slice(o), DVec3::from_slice(d)))
            .collect());
    }
    let bad = origins
        .chunks_exact(3)
        .zip(directions.chunks_exact(3))
        .enumerate()
        .find_map(|(i, (o, d))| check_ray(ray(o, d)).err().map(|e| (i, e)));
    Err(bad.expect("a ray that check_ray refuses"))
}

/// The CSV's number of a hit's part: 0 side, 1 cap at `u = 0`, 2 cap at `u = 1`, 3 seam.
pub fn part_number(part: Part) -> u8 {
    match part {
        Part::Side => 0,
        Part::StartCap => 1,
        Part::EndCap => 2,
        Part::Seam => 3,
    }
}

fn truncate(s: &str, n: usize) -> String {
    match s.char_indices().nth(n) {
        Some((i, _)) => format!("{}...", &s[..i]),
        None => s.to_string(),
    }
}

/// The CSV header.
pub const HEADER: &str = "ray,t,u,v,nx,ny,nz,object,part";

/// One CSV row, with its newline.
pub fn format_row(s: &mut String, ray: usize, h: &SceneHit) {
    use fmt::Write as _;
    let x = &h.hit;
    let part = part_number(x.part);
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

    fn err(text: &str) -> String {
        parse_rays(text.as_bytes(), "rays.csv")
            .unwrap_err()
            .to_string()
    }

    /// The array form accepts what the line form accepts and names the first bad ray.
    #[test]
    fn arrays_are_checked_as_lines_are() {
        let mut o = vec![0.0; 3 * 10_000];
        let mut d: Vec<f64> = (0..3 * 10_000).map(|i| (i % 7) as f64 - 3.0).collect();
        d[..3].copy_from_slice(&[0.0, 0.0, -0.5]);
        let rays = rays_from_arrays(&o, &d).unwrap();
        assert_eq!(rays.len(), 10_000);
        assert_eq!(rays[0].dir, DVec3::new(0.0, 0.0, -0.5));
        assert_eq!(rays[9_999].origin, DVec3::ZERO);
        for (i, want) in [
            (9_000, "dy is not finite (NaN)"),
            (5_000, "oz is not finite (inf)"),
        ] {
            if i == 9_000 {
                d[3 * i + 1] = f64::NAN;
            } else {
                o[3 * i + 2] = f64::INFINITY;
            }
            assert_eq!(rays_from_arrays(&o, &d).unwrap_err(), (i, want.to_string()));
        }
        d[3 * 4_000..3 * 4_000 + 3].copy_from_slice(&[0.0, -0.0, 0.0]);
        let e = rays_from_arrays(&o, &d).unwrap_err();
        assert_eq!(e, (4_000, "the direction (dx, dy, dz) is zero".to_string()));
        assert!(rays_from_arrays(&[], &[]).unwrap().is_empty());
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
}
