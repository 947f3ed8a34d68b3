//! X-ray CT scanners: parallel and cone beam onto a flat detector, one [`View`] per
//! projection in ASTRA's vector conventions, and what a detector pixel records.
//!
//! A view is ASTRA's 12 numbers (`parallel3d_vec`: ray direction, `cone_vec`: source), then
//! the detector centre `d`, then `u` (from pixel (0,0) to (0,1): one column) and `v` (from
//! pixel (0,0) to (1,0): one row). Row `r`, column `c` of a projection is the pixel centred at
//!
//! `p(r, c) = d + (c - columns/2 + 0.5) u + (r - rows/2 + 0.5) v`,
//!
//! and its value is the mean over `k x k` rays through the centres of a `k x k` grid of
//! sub-pixels (sample `(i, j)` at `c + (i + 0.5)/k`, `r + (j + 0.5)/k` in place of `c + 0.5`,
//! `r + 0.5`). A rotation series is ASTRA's `parallel3d` / `cone` geometry (view `k` at angle
//! `start + k arc / views` about `z`) turned from `z` onto the rotation axis and moved to the
//! centre of rotation.

use gencyl::Ray;
use glam::{DQuat, DVec3};

use crate::sampling::{basis, concentric_disc};

/// The beam's shape.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Beam {
    /// Parallel rays, all along one direction per view (ASTRA `parallel3d_vec`).
    Parallel,
    /// Rays from a point source (ASTRA `cone_vec`).
    Cone,
}

impl Beam {
    /// ASTRA's name of the vector geometry.
    pub fn astra_type(self) -> &'static str {
        match self {
            Beam::Parallel => "parallel3d_vec",
            Beam::Cone => "cone_vec",
        }
    }
}

/// One projection's geometry: ASTRA's 12 numbers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    /// Parallel beam: the ray direction; cone beam: the source position.
    pub source: DVec3,
    /// The detector's centre.
    pub detector: DVec3,
    /// From pixel (0, 0) to pixel (0, 1): one column along the detector.
    pub u: DVec3,
    /// From pixel (0, 0) to pixel (1, 0): one row along the detector.
    pub v: DVec3,
}

impl View {
    /// ASTRA's row of 12 numbers.
    pub fn astra(&self) -> [f64; 12] {
        let [s, d, u, v] = [self.source, self.detector, self.u, self.v];
        [s.x, s.y, s.z, d.x, d.y, d.z, u.x, u.y, u.z, v.x, v.y, v.z]
    }

    /// The view from ASTRA's row of 12 numbers.
    pub fn from_astra(a: [f64; 12]) -> View {
        let at = |i: usize| DVec3::new(a[i], a[i + 1], a[i + 2]);
        View {
            source: at(0),
            detector: at(3),
            u: at(6),
            v: at(9),
        }
    }
}

/// A rotation series: `views` projections over `arc` radians about `axis` through `center`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rotation {
    /// Parallel or cone beam.
    pub beam: Beam,
    /// Number of views.
    pub views: usize,
    /// Angle of view 0, radians.
    pub start: f64,
    /// Angle covered, radians (view `k` at `start + k arc / views`).
    pub arc: f64,
    /// Unit rotation axis (the detector's row index counts along it: `v` is parallel to it).
    pub axis: DVec3,
    /// The centre of rotation.
    pub center: DVec3,
    /// Pixel pitch `[du, dv]`, world units.
    pub pixel: [f64; 2],
    /// Source to centre of rotation (cone beam).
    pub source_distance: f64,
    /// Centre of rotation to detector.
    pub detector_distance: f64,
}

impl Rotation {
    /// The views, as ASTRA's `geom_2vec` writes `parallel3d` and `cone` geometries for axis
    /// `z` at angle `a`: ray direction `(sin a, -cos a, 0)` (parallel) or source
    /// `S (sin a, -cos a, 0)` (cone), detector centre `D (-sin a, cos a, 0)`,
    /// `u = du (cos a, sin a, 0)`, `v = dv (0, 0, 1)`; then turned by the shortest rotation
    /// taking `z` to `axis` and moved by `center`.
    pub fn views(&self) -> Vec<View> {
        let turn = DQuat::from_rotation_arc(DVec3::Z, self.axis.normalize());
        (0..self.views)
            .map(|k| {
                let a = self.start + k as f64 * self.arc / self.views as f64;
                let (s, c) = a.sin_cos();
                let toward_source = DVec3::new(s, -c, 0.0);
                let source = match self.beam {
                    Beam::Parallel => turn * toward_source,
                    Beam::Cone => self.center + turn * (self.source_distance * toward_source),
                };
                View {
                    source,
                    detector: self.center - turn * (self.detector_distance * toward_source),
                    u: turn * (self.pixel[0] * DVec3::new(c, s, 0.0)),
                    v: turn * (self.pixel[1] * DVec3::Z),
                }
            })
            .collect()
    }
}

/// A scanner: its beam, its detector and its views.
#[derive(Clone, Debug, PartialEq)]
pub struct Scanner {
    /// Parallel or cone beam.
    pub beam: Beam,
    /// Detector columns (along `u`).
    pub columns: u32,
    /// Detector rows (along `v`).
    pub rows: u32,
    /// Every view.
    pub views: Vec<View>,
    /// Rays per pixel along each side: `k`, for `k^2` rays per pixel.
    pub samples_per_side: u32,
    /// Cone beam: diameter of the focal spot (a uniform disc facing the detector centre);
    /// 0 for a point source.
    pub focal_spot: f64,
}

impl Scanner {
    /// Checks the views and sizes; the message names the problem.
    pub fn validate(&self) -> Result<(), String> {
        if self.views.is_empty() {
            return Err("a scanner needs at least one view".into());
        }
        if self.columns == 0 || self.rows == 0 {
            return Err(format!(
                "detector must have at least one column and row, got {}x{}",
                self.columns, self.rows
            ));
        }
        for (k, view) in self.views.iter().enumerate() {
            let numbers = view.astra();
            if numbers.iter().any(|x| !x.is_finite()) {
                return Err(format!("view {k}: every number must be finite"));
            }
            let normal = view.u.cross(view.v);
            if !(normal.length() > 0.0) {
                return Err(format!(
                    "view {k}: the detector's u and v must be non-zero and not parallel"
                ));
            }
            // The rays must cross the detector's plane: the direction (parallel) or the
            // source's offset from the plane (cone) has a component along its normal.
            let (along, size) = match self.beam {
                Beam::Parallel => (view.source.dot(normal), view.source.length()),
                Beam::Cone => {
                    let to = view.detector - view.source;
                    (to.dot(normal), to.length())
                }
            };
            if !(along.abs() > 1e-9 * size * normal.length()) {
                return Err(format!(
                    "view {k}: the rays run parallel to the detector (or the source lies in its plane)"
                ));
            }
        }
        if self.samples_per_side == 0 || self.samples_per_side > 32 {
            return Err(format!(
                "rays per pixel: 1 to 32 per side, got {}",
                self.samples_per_side
            ));
        }
        if !(self.focal_spot >= 0.0 && self.focal_spot.is_finite()) {
            return Err(format!(
                "focal_spot must be zero or positive, got {}",
                self.focal_spot
            ));
        }
        Ok(())
    }

    /// Rays per pixel.
    pub fn samples(&self) -> u32 {
        self.samples_per_side * self.samples_per_side
    }

    /// The ray of sample `s` (`0..samples()`) of pixel (`row`, `column`) of view `view`,
    /// unit direction. Parallel beam: a point of the pixel and the view's direction (the
    /// caller places the origin before the scene); cone beam: from the source (a point of
    /// the focal spot) through the pixel.
    pub fn ray(&self, view: &View, row: u32, column: u32, s: u32) -> Ray {
        let k = self.samples_per_side;
        let (i, j) = (s % k, s / k);
        let fu =
            f64::from(column) - 0.5 * f64::from(self.columns) + (f64::from(i) + 0.5) / f64::from(k);
        let fv = f64::from(row) - 0.5 * f64::from(self.rows) + (f64::from(j) + 0.5) / f64::from(k);
        let pixel = view.detector + fu * view.u + fv * view.v;
        match self.beam {
            Beam::Parallel => Ray::new(pixel, view.source.normalize()),
            Beam::Cone => {
                let source = view.source + self.focal_offset(view, s);
                Ray::new(source, (pixel - source).normalize())
            }
        }
    }

    /// Where sample `s`'s ray leaves the focal spot, from its centre: the centres of a `k x k`
    /// grid of strata of the unit square, taken transposed and in reverse (sample `s = i + k j`
    /// takes stratum `(j', i')` of `m = k^2 - 1 - s = i' + k j'`, so that a pixel's sub-pixels
    /// do not pair with the same part of the spot), mapped onto the disc by the concentric
    /// map, in the plane facing the detector centre.
    fn focal_offset(&self, view: &View, s: u32) -> DVec3 {
        if self.focal_spot == 0.0 {
            return DVec3::ZERO;
        }
        let k = self.samples_per_side;
        let m = self.samples() - 1 - s;
        let (i, j) = (f64::from(m / k), f64::from(m % k));
        let kf = f64::from(k);
        let d = concentric_disc([(i + 0.5) / kf, (j + 0.5) / kf]);
        let (e1, e2) = basis((view.detector - view.source).normalize());
        0.5 * self.focal_spot * (d.x * e1 + d.y * e2)
    }
}

/// What each detector pixel records.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Quantity {
    /// `-ln(I / I0)`.
    Absorbance,
    /// `I / I0`.
    Transmission,
    /// Path length through the solids (of one material, or all), world units.
    Length,
}

impl Quantity {
    /// The name the `[ct]` table and the sidecar use.
    pub fn name(self) -> &'static str {
        match self {
            Quantity::Absorbance => "absorbance",
            Quantity::Transmission => "transmission",
            Quantity::Length => "length",
        }
    }
}

impl std::str::FromStr for Quantity {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "absorbance" => Ok(Quantity::Absorbance),
            "transmission" => Ok(Quantity::Transmission),
            "length" => Ok(Quantity::Length),
            _ => Err(format!(
                "unknown quantity `{s}`: expected absorbance, transmission or length"
            )),
        }
    }
}

/// A polychromatic source: energy bins and their weights (normalised to sum 1).
#[derive(Clone, Debug, PartialEq)]
pub struct Spectrum {
    /// Bin energies (keV, for the record: only the weights enter the result).
    pub energies: Vec<f64>,
    /// Weights, summing to 1.
    pub weights: Vec<f64>,
}

/// A CT scan: the scanner, what it records, the source's spectrum.
#[derive(Clone, Debug, PartialEq)]
pub struct CtSetup {
    /// Beam, detector, views.
    pub scanner: Scanner,
    /// The recorded quantity.
    pub quantity: Quantity,
    /// `Length` only: the material whose path length is recorded (`None`: all solids).
    pub material: Option<u32>,
    /// Energy bins, if polychromatic (materials then give `xray_mu` per bin).
    pub spectrum: Option<Spectrum>,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rotation(beam: Beam, axis: DVec3, center: DVec3) -> Rotation {
        Rotation {
            beam,
            views: 8,
            start: 0.3,
            arc: std::f64::consts::PI,
            axis,
            center,
            pixel: [0.5, 0.25],
            source_distance: 10.0,
            detector_distance: 4.0,
        }
    }

    /// ASTRA's `geom_2vec` for `parallel3d` and `cone` (astra/functions.py), written out from
    /// its documentation for angle `a`: direction/source, detector, u, v.
    fn astra_geom_2vec(beam: Beam, a: f64, du: f64, dv: f64, sod: f64, odd: f64) -> [f64; 12] {
        let (s, c) = a.sin_cos();
        match beam {
            Beam::Parallel => [s, -c, 0.0, 0.0, 0.0, 0.0, c * du, s * du, 0.0, 0.0, 0.0, dv],
            Beam::Cone => [
                s * sod,
                -c * sod,
                0.0,
                -s * odd,
                c * odd,
                0.0,
                c * du,
                s * du,
                0.0,
                0.0,
                0.0,
                dv,
            ],
        }
    }

    #[test]
    fn a_z_axis_series_is_astras() {
        for beam in [Beam::Parallel, Beam::Cone] {
            let mut r = rotation(beam, DVec3::Z, DVec3::ZERO);
            if beam == Beam::Parallel {
                r.detector_distance = 0.0;
            }
            for (k, view) in r.views().iter().enumerate() {
                let a = 0.3 + k as f64 * std::f64::consts::PI / 8.0;
                let want = astra_geom_2vec(beam, a, 0.5, 0.25, 10.0, 4.0);
                for (g, w) in view.astra().iter().zip(want) {
                    assert!((g - w).abs() < 1e-15, "{beam:?} view {k}: {g} vs {w}");
                }
            }
        }
    }

    #[test]
    fn a_turned_series_keeps_its_shape_about_the_axis() {
        let axis = DVec3::new(1.0, 2.0, -0.5).normalize();
        let center = DVec3::new(3.0, -1.0, 2.0);
        let r = rotation(Beam::Cone, axis, center);
        for view in r.views() {
            // v along the axis, u and the source direction perpendicular to it, distances kept.
            assert!((view.v.normalize().dot(axis) - 1.0).abs() < 1e-14);
            assert!(view.u.dot(axis).abs() < 1e-14);
            assert!(((view.source - center).length() - 10.0).abs() < 1e-13);
            assert!(((view.detector - center).length() - 4.0).abs() < 1e-13);
            assert!((view.source - center).dot(axis).abs() < 1e-13);
            assert!(
                (view.source - center)
                    .normalize()
                    .dot((view.detector - center).normalize())
                    + 1.0
                    < 1e-14
            );
        }
    }

    #[test]
    fn sub_pixel_rays_tile_the_pixel() {
        let view = View {
            source: DVec3::new(0.0, -1.0, 0.0),
            detector: DVec3::ZERO,
            u: DVec3::new(2.0, 0.0, 0.0),
            v: DVec3::new(0.0, 0.0, 3.0),
        };
        let scanner = Scanner {
            beam: Beam::Parallel,
            columns: 4,
            rows: 2,
            views: vec![view],
            samples_per_side: 2,
            focal_spot: 0.0,
        };
        // Pixel (row 1, column 3): x from 2 to 4 (centre 3), z from 0 to 3 (centre 1.5).
        let xs: Vec<(f64, f64)> = (0..4)
            .map(|s| {
                let r = scanner.ray(&view, 1, 3, s);
                (r.origin.x, r.origin.z)
            })
            .collect();
        assert_eq!(xs, vec![(2.5, 0.75), (3.5, 0.75), (2.5, 2.25), (3.5, 2.25)]);
    }

    #[test]
    fn a_focal_spot_spreads_the_source_over_its_disc() {
        let view = View {
            source: DVec3::new(0.0, -10.0, 0.0),
            detector: DVec3::new(0.0, 5.0, 0.0),
            u: DVec3::X,
            v: DVec3::Z,
        };
        let scanner = Scanner {
            beam: Beam::Cone,
            columns: 1,
            rows: 1,
            views: vec![view],
            samples_per_side: 4,
            focal_spot: 0.2,
        };
        let mut no_rays = scanner.clone();
        no_rays.samples_per_side = 0;
        assert!(no_rays.validate().unwrap_err().contains("rays per pixel"));
        let mut seen = Vec::new();
        for s in 0..16 {
            let o = scanner.ray(&view, 0, 0, s).origin - view.source;
            assert!(o.y.abs() < 1e-15 && o.length() <= 0.1 + 1e-15, "{o}");
            seen.push(o);
        }
        let mean = seen.iter().sum::<DVec3>() / 16.0;
        assert!(mean.length() < 1e-12, "strata centred: {mean}");
        seen.dedup();
        assert_eq!(seen.len(), 16, "every sample its own stratum");
    }
}
