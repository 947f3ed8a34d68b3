//! The `[ct]` table: an X-ray CT scan of the scene (beam, detector, a rotation series or
//! ASTRA view vectors, rays per pixel, the recorded quantity, the source's spectrum).

use std::ops::Range;

use glam::DVec3;
use serde::Deserialize;
use toml::Spanned;

use super::materials::Materials;
use super::values::*;
use crate::optics::scanner::{Beam, CtSetup, Quantity, Rotation, Scanner, Spectrum, View};

/// Most views a scan may have.
pub const MAX_VIEWS: usize = 1 << 20;
/// Most rays per pixel.
pub const MAX_SAMPLES: u32 = 1024;
/// Most energy bins.
pub const MAX_BINS: usize = 1024;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawCt {
    beam: Option<Spanned<String>>,
    detector: Spanned<Array<u32, 2>>,
    pixel: Option<Spanned<Array<f64, 2>>>,
    views: Option<Spanned<u32>>,
    arc: Option<Spanned<f64>>,
    start_angle: Option<Spanned<f64>>,
    axis: Option<Spanned<Array<f64, 3>>>,
    center: Option<Spanned<Array<f64, 3>>>,
    source_distance: Option<Spanned<f64>>,
    detector_distance: Option<Spanned<f64>>,
    vectors: Option<Spanned<Vec<Array<f64, 12>>>>,
    samples: Option<Spanned<u32>>,
    focal_spot: Option<Spanned<f64>>,
    quantity: Option<Spanned<String>>,
    material: Option<Spanned<String>>,
    spectrum: Option<Spanned<Vec<Array<f64, 2>>>>,
}

/// Builds the scan; `materials` resolves `material` and is checked against the spectrum.
pub(super) fn build_ct(
    c: &RawCt,
    table: Range<usize>,
    materials: &Materials,
) -> Result<CtSetup, Problem> {
    let beam = match c.beam.as_ref().map_or("parallel", |b| b.get_ref().as_str()) {
        "parallel" => Beam::Parallel,
        "cone" => Beam::Cone,
        other => {
            return Err((
                span_of(&c.beam).unwrap_or(table),
                format!("unknown beam `{other}`: expected `parallel` or `cone`"),
            ));
        }
    };
    let [columns, rows] = val(&c.detector);
    if !(1..=65536).contains(&columns) || !(1..=65536).contains(&rows) {
        return Err((
            c.detector.span(),
            format!("detector must be 1 to 65536 pixels each way, got [{columns}, {rows}]"),
        ));
    }
    if u64::from(columns) * u64::from(rows) > crate::limits::MAX_PIXELS {
        return Err((
            c.detector.span(),
            format!(
                "a detector of {columns} x {rows} pixels is more than the {} a projection may have",
                crate::limits::MAX_PIXELS
            ),
        ));
    }
    let views = match &c.vectors {
        Some(v) => {
            let rotation_keys = [
                ("pixel", span_of(&c.pixel)),
                ("views", span_of(&c.views)),
                ("arc", span_of(&c.arc)),
                ("start_angle", span_of(&c.start_angle)),
                ("axis", span_of(&c.axis)),
                ("center", span_of(&c.center)),
                ("source_distance", span_of(&c.source_distance)),
                ("detector_distance", span_of(&c.detector_distance)),
            ];
            only_keys(&rotation_keys, &[], "a scan given by `vectors`")?;
            if v.get_ref().is_empty() || v.get_ref().len() > MAX_VIEWS {
                return Err((
                    v.span(),
                    format!(
                        "vectors must list 1 to {MAX_VIEWS} views, got {}",
                        v.get_ref().len()
                    ),
                ));
            }
            v.get_ref().iter().map(|a| View::from_astra(a.0)).collect()
        }
        None => rotation(c, beam, &table)?.views(),
    };
    let samples = match &c.samples {
        Some(s) => {
            let n = *s.get_ref();
            let k = (f64::from(n).sqrt().round()) as u32;
            if n == 0 || n > MAX_SAMPLES || k * k != n {
                return Err((
                    s.span(),
                    format!(
                        "samples must be a square number (1, 4, 9, ...) of at most {MAX_SAMPLES}: the rays of a pixel sit on a k x k grid, got {n}"
                    ),
                ));
            }
            k
        }
        None => 1,
    };
    let focal_spot = match &c.focal_spot {
        Some(f) if beam == Beam::Parallel => {
            return Err((
                f.span(),
                "`focal_spot` does not apply to a parallel beam".into(),
            ));
        }
        Some(f) => number(f, "focal_spot", 0.0, crate::limits::MAX_LENGTH, false)?,
        None => 0.0,
    };
    let quantity = match &c.quantity {
        Some(q) => q.get_ref().parse().map_err(|e| (q.span(), e))?,
        None => Quantity::Absorbance,
    };
    let material = match &c.material {
        Some(m) if quantity != Quantity::Length => {
            return Err((
                m.span(),
                "`material` applies to quantity = \"length\" only (absorbance and transmission sum every material)".into(),
            ));
        }
        Some(_) => Some(materials.index(&c.material, "")?),
        None => None,
    };
    let spectrum = match &c.spectrum {
        Some(s) => Some(spectrum(s)?),
        None => None,
    };
    let scanner = Scanner {
        beam,
        columns,
        rows,
        views,
        samples_per_side: samples,
        focal_spot,
    };
    scanner
        .validate()
        .map_err(|e| (span_of(&c.vectors).unwrap_or(table), e))?;
    Ok(CtSetup {
        scanner,
        quantity,
        material,
        spectrum,
    })
}

/// The rotation series of a `[ct]` table without `vectors`.
fn rotation(c: &RawCt, beam: Beam, table: &Range<usize>) -> Result<Rotation, Problem> {
    let views = required(
        &c.views,
        "views",
        "a rotation series (or give `vectors`)",
        table,
    )?;
    let n = *views.get_ref() as usize;
    if n == 0 || n > MAX_VIEWS {
        return Err((
            views.span(),
            format!("views must be 1 to {MAX_VIEWS}, got {n}"),
        ));
    }
    let pixel = required(&c.pixel, "pixel", "a rotation series", table)?;
    let [du, dv] = val(pixel);
    for (x, what) in [(du, "pixel[0]"), (dv, "pixel[1]")] {
        check_number(x, what, 0.0, crate::limits::MAX_LENGTH, true)
            .map_err(|m| (pixel.span(), m))?;
    }
    let degrees = |k: &Option<Spanned<f64>>, name: &str, default: f64| match k {
        Some(x) => number(x, name, -1e6, 1e6, false).map(f64::to_radians),
        None => Ok(default.to_radians()),
    };
    let (source_distance, detector_distance) = match beam {
        Beam::Parallel => {
            not_for(&c.source_distance, "source_distance", "a parallel beam")?;
            let d = match &c.detector_distance {
                Some(d) => number(
                    d,
                    "detector_distance",
                    0.0,
                    crate::limits::MAX_LENGTH,
                    false,
                )?,
                None => 0.0,
            };
            (0.0, d)
        }
        Beam::Cone => {
            let s = required(&c.source_distance, "source_distance", "a cone beam", table)?;
            let d = required(
                &c.detector_distance,
                "detector_distance",
                "a cone beam",
                table,
            )?;
            (
                length(s, "source_distance")?,
                length(d, "detector_distance")?,
            )
        }
    };
    Ok(Rotation {
        beam,
        views: n,
        start: degrees(&c.start_angle, "start_angle", 0.0)?,
        arc: degrees(
            &c.arc,
            "arc",
            if beam == Beam::Parallel { 180.0 } else { 360.0 },
        )?,
        axis: match &c.axis {
            Some(a) => direction(a, "axis")?,
            None => DVec3::Z,
        },
        center: match &c.center {
            Some(p) => vec3(p, "center")?,
            None => DVec3::ZERO,
        },
        pixel: [du, dv],
        source_distance,
        detector_distance,
    })
}

/// `spectrum = [[energy, weight], ...]`: energies positive, weights non-negative, not all
/// zero; the weights are normalised.
fn spectrum(s: &Spanned<Vec<Array<f64, 2>>>) -> Result<Spectrum, Problem> {
    let bins = s.get_ref();
    if bins.is_empty() || bins.len() > MAX_BINS {
        return Err((
            s.span(),
            format!(
                "spectrum must have 1 to {MAX_BINS} [energy, weight] bins, got {}",
                bins.len()
            ),
        ));
    }
    let bad = bins
        .iter()
        .position(|b| !(b.0[0] > 0.0 && b.0[0].is_finite() && b.0[1] >= 0.0 && b.0[1].is_finite()));
    if let Some(i) = bad {
        return Err((
            s.span(),
            format!(
                "spectrum bin {i}: energy must be positive and weight non-negative, both finite, got [{}, {}]",
                bins[i].0[0], bins[i].0[1]
            ),
        ));
    }
    let total: f64 = bins.iter().map(|b| b.0[1]).sum();
    if !(total > 0.0 && total.is_finite()) {
        return Err((s.span(), "spectrum weights must not all be zero".into()));
    }
    Ok(Spectrum {
        energies: bins.iter().map(|b| b.0[0]).collect(),
        weights: bins.iter().map(|b| b.0[1] / total).collect(),
    })
}
