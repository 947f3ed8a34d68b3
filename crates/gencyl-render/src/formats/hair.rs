//! Cem Yuksel's HAIR file format (`.hair`): strands as polylines, read into [`Strand`]s.
//!
//! Layout (little-endian): a 128-byte header
//!
//! | bytes | content |
//! |---|---|
//! | 0-3 | `HAIR` |
//! | 4-7 | number of strands (u32) |
//! | 8-11 | total number of points (u32) |
//! | 12-15 | flags: bit 0 segments array, 1 points, 2 thickness, 3 transparency, 4 colour |
//! | 16-19 | default segments per strand (u32), used without a segments array |
//! | 20-23 | default thickness (f32), used without a thickness array |
//! | 24-27 | default transparency (f32) |
//! | 28-39 | default colour (3 f32) |
//! | 40-127 | information text (NUL padded) |
//!
//! then, each present in flag order: segments per strand (u16 each), points (3 f32 each),
//! thickness (f32 per point), transparency (f32 per point), colour (3 f32 per point). A strand
//! of `s` segments has `s + 1` points. Thickness is the fiber's diameter.

use gencyl::{Section, Strand};
use glam::DVec3;

/// A HAIR file's strands and defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct HairFile {
    /// Points of each strand, root first.
    pub strands: Vec<Vec<DVec3>>,
    /// Per-point thickness (diameter), parallel to `strands`, if the file has it.
    pub thickness: Option<Vec<Vec<f64>>>,
    /// The file's default thickness.
    pub default_thickness: f64,
    /// The header's information text.
    pub info: String,
}

/// Why a HAIR file cannot be read.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum HairError {
    /// Not a HAIR file, or a header that contradicts itself or the file's size.
    #[error("{file}: {problem}")]
    Invalid {
        /// The file's name.
        file: String,
        /// What is wrong, with the byte offset where useful.
        problem: String,
    },
}

const HEADER: usize = 128;

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

fn f32_at(b: &[u8], at: usize) -> f64 {
    f32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]) as f64
}

/// Parses a HAIR file. Every count is checked against the file's size before anything is
/// allocated, so a lying or truncated file is an error, never a huge allocation or a panic.
pub fn parse_hair(bytes: &[u8], file: &str) -> Result<HairFile, HairError> {
    let bad = |problem: String| HairError::Invalid {
        file: file.to_string(),
        problem,
    };
    if bytes.len() < HEADER {
        return Err(bad(format!(
            "{} bytes: shorter than the 128-byte HAIR header",
            bytes.len()
        )));
    }
    if &bytes[0..4] != b"HAIR" {
        return Err(bad("does not start with the HAIR signature".into()));
    }
    let (strands, points, flags) = (
        u32_at(bytes, 4) as usize,
        u32_at(bytes, 8) as usize,
        u32_at(bytes, 12),
    );
    let (has_segments, has_points, has_thickness) =
        (flags & 1 != 0, flags & 2 != 0, flags & 4 != 0);
    let (has_transparency, has_color) = (flags & 8 != 0, flags & 16 != 0);
    if !has_points {
        return Err(bad("the flags say the file has no points array".into()));
    }
    let default_segments = u32_at(bytes, 16) as usize;
    let default_thickness = f32_at(bytes, 20);
    // Sizes in u64 so that no count can overflow the arithmetic.
    let (n, p) = (strands as u64, points as u64);
    let expected = HEADER as u64
        + if has_segments { 2 * n } else { 0 }
        + 12 * p
        + if has_thickness { 4 * p } else { 0 }
        + if has_transparency { 4 * p } else { 0 }
        + if has_color { 12 * p } else { 0 };
    if expected != bytes.len() as u64 {
        return Err(bad(format!(
            "the header promises {strands} strands and {points} points ({expected} bytes with flags {flags:#x}) but the file has {} bytes{}",
            bytes.len(),
            if (bytes.len() as u64) < expected {
                ": truncated"
            } else {
                ""
            }
        )));
    }
    let mut at = HEADER;
    if !has_segments && n * (default_segments as u64 + 1) != p {
        return Err(bad(format!(
            "{strands} strands of {default_segments} segments need {} points but the header says {points}",
            n * (default_segments as u64 + 1)
        )));
    }
    // Both counts are now bounded by the file's size, so these allocations are too.
    let segments: Vec<usize> = if has_segments {
        let s = (0..strands)
            .map(|i| u16::from_le_bytes([bytes[at + 2 * i], bytes[at + 2 * i + 1]]) as usize)
            .collect();
        at += 2 * strands;
        s
    } else {
        vec![default_segments; strands]
    };
    let total: u64 = segments.iter().map(|&s| s as u64 + 1).sum();
    if total != p {
        return Err(bad(format!(
            "the strands' segment counts need {total} points but the header says {points}"
        )));
    }
    let mut pts = Vec::with_capacity(points);
    for i in 0..points {
        let q = DVec3::new(
            f32_at(bytes, at),
            f32_at(bytes, at + 4),
            f32_at(bytes, at + 8),
        );
        if !q.is_finite() {
            return Err(bad(format!("point {i} (byte {at}) is not finite: {q}")));
        }
        pts.push(q);
        at += 12;
    }
    let thickness = if has_thickness {
        let mut t = Vec::with_capacity(points);
        for i in 0..points {
            let x = f32_at(bytes, at);
            if !(x.is_finite() && x > 0.0) {
                return Err(bad(format!(
                    "thickness of point {i} (byte {at}) must be positive and finite, got {x}"
                )));
            }
            t.push(x);
            at += 4;
        }
        Some(t)
    } else {
        None
    };
    // Transparency and colour are not used for shading, but a file with NaN in them is
    // damaged: refuse it rather than carry the values along.
    for (present, per_point, name, lo, hi) in [
        (has_transparency, 1, "transparency", 0.0, 1.0),
        (has_color, 3, "colour", 0.0, f64::INFINITY),
    ] {
        if !present {
            continue;
        }
        for i in 0..points * per_point {
            let x = f32_at(bytes, at);
            if !(x.is_finite() && x >= lo && x <= hi) {
                let range = if hi.is_finite() {
                    "in [0, 1]"
                } else {
                    "finite and non-negative"
                };
                return Err(bad(format!(
                    "{name} of point {} (byte {at}) must be {range}, got {x}",
                    i / per_point
                )));
            }
            at += 4;
        }
    }
    let thickness = thickness.map(|t| split(&t, &segments));
    let strand_points = split(&pts, &segments);
    let info_bytes = &bytes[40..128];
    let info = String::from_utf8_lossy(
        &info_bytes[..info_bytes.iter().position(|&c| c == 0).unwrap_or(88)],
    )
    .into_owned();
    Ok(HairFile {
        strands: strand_points,
        thickness,
        default_thickness,
        info,
    })
}

/// `flat` cut into runs of `s + 1` for each segment count `s`.
fn split<T: Clone>(flat: &[T], segments: &[usize]) -> Vec<Vec<T>> {
    let mut start = 0;
    segments
        .iter()
        .map(|&s| {
            let run = flat[start..start + s + 1].to_vec();
            start += s + 1;
            run
        })
        .collect()
}

/// Writes strands as a HAIR file with segments, points and (optionally) thickness arrays.
pub fn write_hair(strands: &[Vec<DVec3>], thickness: Option<&[Vec<f64>]>, info: &str) -> Vec<u8> {
    let points: usize = strands.iter().map(Vec::len).sum();
    let mut b = Vec::with_capacity(HEADER + 2 * strands.len() + 16 * points);
    b.extend_from_slice(b"HAIR");
    b.extend_from_slice(&(strands.len() as u32).to_le_bytes());
    b.extend_from_slice(&(points as u32).to_le_bytes());
    let flags: u32 = 1 | 2 | if thickness.is_some() { 4 } else { 0 };
    b.extend_from_slice(&flags.to_le_bytes());
    b.extend_from_slice(&0u32.to_le_bytes());
    for x in [1.0f32, 0.0, 1.0, 1.0, 1.0] {
        b.extend_from_slice(&x.to_le_bytes());
    }
    let mut text = [0u8; 88];
    let n = info.len().min(87);
    text[..n].copy_from_slice(&info.as_bytes()[..n]);
    b.extend_from_slice(&text);
    for s in strands {
        b.extend_from_slice(&((s.len() - 1) as u16).to_le_bytes());
    }
    for p in strands.iter().flatten() {
        for c in [p.x, p.y, p.z] {
            b.extend_from_slice(&(c as f32).to_le_bytes());
        }
    }
    if let Some(t) = thickness {
        for x in t.iter().flatten() {
            b.extend_from_slice(&(*x as f32).to_le_bytes());
        }
    }
    b
}

impl HairFile {
    /// The strands as [`Strand`]s: radius half the thickness at the root and the tip (or
    /// `radius` for all, if given). Points closer than `1e-6` of the strand's extent to the
    /// previous kept point are dropped (real assets repeat points; a repeated B-spline control
    /// point can make a cusp), and strands left with fewer than two points are skipped.
    pub fn to_strands(&self, radius: Option<f64>) -> Vec<Strand> {
        self.strands
            .iter()
            .enumerate()
            .filter_map(|(i, pts)| {
                let extent = pts
                    .iter()
                    .fold(0.0f64, |m, p| m.max((*p - pts[0]).length()));
                let mut kept: Vec<DVec3> = Vec::with_capacity(pts.len());
                for &p in pts {
                    if kept
                        .last()
                        .is_none_or(|&q| (p - q).length() > 1e-6 * extent)
                    {
                        kept.push(p);
                    }
                }
                if kept.len() < 2 {
                    return None;
                }
                let r = |k: usize| {
                    radius.unwrap_or_else(|| {
                        0.5 * self
                            .thickness
                            .as_ref()
                            .map_or(self.default_thickness, |t| t[i][k])
                    })
                };
                Some(Strand {
                    points: kept,
                    radius: [r(0), r(pts.len() - 1)],
                    ellipticity: 1.0,
                    twist: [0.0, 0.0],
                    section: Section::default(),
                })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> (Vec<Vec<DVec3>>, Vec<Vec<f64>>) {
        let strands: Vec<Vec<DVec3>> = (0..5)
            .map(|i| {
                (0..(3 + i))
                    .map(|k| DVec3::new(i as f64, k as f64 * 0.5, (k * i) as f64 * 0.25))
                    .collect()
            })
            .collect();
        let thick = strands
            .iter()
            .map(|s| {
                s.iter()
                    .enumerate()
                    .map(|(k, _)| 0.1 + 0.01 * k as f64)
                    .collect()
            })
            .collect();
        (strands, thick)
    }

    #[test]
    fn round_trip_keeps_points_and_thickness() {
        let (strands, thick) = sample();
        let bytes = write_hair(&strands, Some(&thick), "test strands");
        let h = parse_hair(&bytes, "t.hair").unwrap();
        assert_eq!(h.strands.len(), 5, "strand count");
        assert_eq!(h.info, "test strands", "info text");
        for (a, b) in h.strands.iter().zip(&strands) {
            assert_eq!(a.len(), b.len(), "points per strand");
            for (p, q) in a.iter().zip(b) {
                assert!((*p - *q).length() < 1e-6, "point {p} vs {q}");
            }
        }
        let t = h.thickness.as_ref().unwrap();
        assert!((t[4][6] - 0.16).abs() < 1e-6, "thickness {}", t[4][6]);
        let cyl: usize = h
            .to_strands(None)
            .iter()
            .map(|s| s.cylinders().unwrap().len())
            .sum();
        assert_eq!(cyl, (2..7).sum::<usize>(), "one cylinder per segment");
    }

    #[test]
    fn truncated_lying_and_foreign_files_are_errors() {
        let (strands, thick) = sample();
        let bytes = write_hair(&strands, Some(&thick), "x");
        for cut in [0, 3, 100, 128, 140, bytes.len() - 1] {
            let e = parse_hair(&bytes[..cut], "t.hair").unwrap_err();
            assert!(e.to_string().starts_with("t.hair: "), "names the file: {e}");
        }
        // A header claiming 4 billion points: an error, no allocation.
        let mut lying = bytes.clone();
        lying[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(
            parse_hair(&lying, "t.hair")
                .unwrap_err()
                .to_string()
                .contains("promises"),
            "lying count"
        );
        // Billions of strands of default length, no segments array: an error, no allocation.
        let mut no_seg = write_hair(&[vec![DVec3::ZERO, DVec3::X]], None, "x");
        no_seg[12..16].copy_from_slice(&2u32.to_le_bytes());
        no_seg[4..8].copy_from_slice(&u32::MAX.to_le_bytes());
        no_seg.drain(128..130);
        assert!(
            parse_hair(&no_seg, "t.hair").is_err(),
            "default segments times strands"
        );
        // Segment counts that disagree with the point count.
        let mut inconsistent = bytes.clone();
        inconsistent[128..130].copy_from_slice(&7u16.to_le_bytes());
        assert!(
            parse_hair(&inconsistent, "t.hair")
                .unwrap_err()
                .to_string()
                .contains("segment counts"),
            "segments"
        );
        let mut nan = bytes.clone();
        let at = 128 + 2 * 5;
        nan[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
        assert!(
            parse_hair(&nan, "t.hair")
                .unwrap_err()
                .to_string()
                .contains("not finite"),
            "nan point"
        );
        let mut magic = bytes;
        magic[0] = b'X';
        assert!(parse_hair(&magic, "t.hair").is_err(), "signature");
    }

    /// Transparency and colour arrays (flags 8 and 16) are checked: NaN, negative or (for
    /// transparency) above 1 is an error that names the array, the point and the byte.
    #[test]
    fn nan_in_transparency_or_colour_is_an_error() {
        let (strands, _) = sample();
        let base = write_hair(&strands, None, "x");
        let points = u32_at(&base, 8) as usize;
        let with = |flag: u32, per_point: usize, value: f32, at_point: usize| {
            let mut b = base.clone();
            let flags = u32_at(&b, 12) | flag;
            b[12..16].copy_from_slice(&flags.to_le_bytes());
            let start = b.len();
            for _ in 0..points * per_point {
                b.extend_from_slice(&0.5f32.to_le_bytes());
            }
            let at = start + 4 * per_point * at_point;
            b[at..at + 4].copy_from_slice(&value.to_le_bytes());
            b
        };
        assert!(
            parse_hair(&with(8, 1, 0.25, 1), "t.hair").is_ok(),
            "valid transparency"
        );
        assert!(
            parse_hair(&with(16, 3, 2.0, 1), "t.hair").is_ok(),
            "valid colour"
        );
        for (flag, per, value, name) in [
            (8, 1, f32::NAN, "transparency of point 2"),
            (8, 1, 1.5, "transparency of point 2"),
            (16, 3, f32::NAN, "colour of point 2"),
            (16, 3, -1.0, "colour of point 2"),
        ] {
            let e = parse_hair(&with(flag, per, value, 2), "t.hair")
                .unwrap_err()
                .to_string();
            assert!(
                e.starts_with("t.hair: ") && e.contains(name),
                "{value}: {e}"
            );
        }
    }

    #[test]
    fn repeated_points_are_merged() {
        let h = HairFile {
            strands: vec![
                vec![DVec3::ZERO, DVec3::X, DVec3::X, DVec3::new(2.0, 1.0, 0.0)],
                vec![DVec3::Y; 3],
            ],
            thickness: None,
            default_thickness: 0.1,
            info: String::new(),
        };
        let s = h.to_strands(None);
        assert_eq!(s.len(), 1, "the all-repeated strand is skipped");
        assert_eq!(s[0].points.len(), 3, "the repeated point is dropped");
        assert_eq!(s[0].radius, [0.05, 0.05], "half the default thickness");
        assert!(s[0].cylinders().is_ok(), "no cusp after merging");
    }
}
