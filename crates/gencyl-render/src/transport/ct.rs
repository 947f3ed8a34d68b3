//! X-ray CT projections: path lengths through the solids along every detector ray, turned
//! into what the detector records (Beer-Lambert, mono- or polychromatic).
//!
//! For a ray with path length `L_m` through material `m`, an energy bin `b` of weight `w_b`
//! (the weights sum to 1) is attenuated by `exp(-A_b)`, `A_b = sum_m mu_mb L_m`. A pixel
//! integrates intensity, so over its `n` rays it records
//!
//! - transmission `T = (1/n) sum_rays sum_b w_b exp(-A_b)`,
//! - absorbance `-ln T`, summed in log space (`max + ln sum exp(x - max)`), so that it stays
//!   finite and exact where `T` itself underflows,
//! - length: the mean over its rays of `sum_m L_m` (or one material's `L_m`).

use std::ops::Range;

use gencyl::{Aabb, Ray};
use rayon::prelude::*;

use crate::optics::material::SceneMaterial;
use crate::optics::scanner::{Beam, CtSetup, Quantity, Spectrum, View};
use crate::transport::integrator::Buffers;
use crate::transport::world::World;

/// Linear attenuation of every material in every energy bin, and the bins' weights.
#[derive(Clone, Debug, PartialEq)]
pub struct Attenuation {
    /// `ln w_b` of the bins with weight above zero.
    ln_weights: Vec<f64>,
    /// Those bins' indices.
    bins: Vec<usize>,
    /// `mu[m * B + b]`, `B` the number of bins.
    mu: Vec<f64>,
    /// `B`.
    stride: usize,
}

impl Attenuation {
    /// The materials' `xray_mu` (one value: the same in every bin) under `spectrum` (none:
    /// one bin of weight 1).
    pub fn new(materials: &[SceneMaterial], spectrum: Option<&Spectrum>) -> Attenuation {
        let weights = spectrum.map_or_else(|| vec![1.0], |s| s.weights.clone());
        let stride = weights.len();
        let mu = materials
            .iter()
            .flat_map(|m| {
                (0..stride).map(move |b| m.xray_mu[if m.xray_mu.len() == 1 { 0 } else { b }])
            })
            .collect();
        let bins: Vec<usize> = (0..stride).filter(|&b| weights[b] > 0.0).collect();
        Attenuation {
            ln_weights: bins.iter().map(|&b| weights[b].ln()).collect(),
            bins,
            mu,
            stride,
        }
    }

    /// Adds one ray with path lengths `lengths[m]` to a pixel's transmission.
    pub fn add_ray(&self, lengths: &[f64], pixel: &mut LogSum) {
        for (&b, &ln_w) in self.bins.iter().zip(&self.ln_weights) {
            let a: f64 = lengths
                .iter()
                .enumerate()
                .filter(|&(_, &l)| l > 0.0)
                .map(|(m, &l)| self.mu[m * self.stride + b] * l)
                .sum();
            pixel.add(ln_w - a);
        }
    }

    /// One ray's absorbance `-ln sum_b w_b exp(-A_b)`.
    pub fn absorbance(&self, lengths: &[f64]) -> f64 {
        let mut s = LogSum::default();
        self.add_ray(lengths, &mut s);
        -s.ln()
    }
}

/// `ln sum_i exp(x_i)`, accumulated without overflow or underflow: the largest `x` so far
/// and `sum exp(x_i - max)`.
#[derive(Clone, Copy, Debug)]
pub struct LogSum {
    max: f64,
    sum: f64,
}

impl Default for LogSum {
    fn default() -> Self {
        LogSum {
            max: f64::NEG_INFINITY,
            sum: 0.0,
        }
    }
}

impl LogSum {
    /// Adds `exp(x)` (nothing for `x = -inf`: an opaque path).
    pub fn add(&mut self, x: f64) {
        if x == f64::NEG_INFINITY {
            return;
        }
        if x <= self.max {
            self.sum += (x - self.max).exp();
        } else {
            self.sum = self.sum * (self.max - x).exp() + 1.0;
            self.max = x;
        }
    }

    /// `ln` of the sum (`-inf` for none).
    pub fn ln(&self) -> f64 {
        self.max + self.sum.ln()
    }
}

/// Path length through each material along the ray (`t` in units of `|d|`), into
/// `lengths` (one per material of the world; overwritten). For solids that do not overlap,
/// `L_m = sum of exit t - sum of entry t` over the material's crossings: a ray that starts
/// inside has one exit more than entries, which counts from `t = 0`. Crossings with
/// `d . n = 0` exactly (tangent touches) carry no length; overlapping solids count twice.
pub fn material_lengths(world: &World, ray: &Ray, buf: &mut Buffers, lengths: &mut [f64]) {
    lengths.fill(0.0);
    buf.crossings.clear();
    world.crossings(
        ray,
        0.0,
        &mut buf.crossings,
        &mut buf.hits,
        &mut buf.scratch,
    );
    let scale = ray.dir.length();
    for c in &buf.crossings {
        lengths[c.material as usize] += if c.entering { -c.t } else { c.t } * scale;
    }
    for l in lengths {
        *l = l.max(0.0);
    }
}

/// A CT scan of a world, one view at a time.
pub struct Projector<'a> {
    world: &'a World,
    setup: &'a CtSetup,
    /// The solids' bounds, grown a little: parallel rays start on them.
    bounds: Aabb,
    /// Materials whose mean path lengths go into stacks of their own beside the quantity's.
    lengths: Vec<u32>,
}

impl<'a> Projector<'a> {
    /// The scan `setup` of `world`.
    pub fn new(world: &'a World, setup: &'a CtSetup) -> Self {
        let b = world.bounds();
        let bounds = if b.min.cmple(b.max).all() {
            let grow = 1e-6 * (b.max - b.min).max_element()
                + 1e-9 * b.max.abs().max(b.min.abs()).max_element();
            Aabb {
                min: b.min - grow,
                max: b.max + grow,
            }
        } else {
            Aabb::EMPTY
        };
        Projector {
            world,
            setup,
            bounds,
            lengths: Vec::new(),
        }
    }

    /// Also the mean path length through each of `materials` (indices into the world's), from
    /// the same rays: stacks `1..` of [`Self::project_all`] and [`Self::write_stacks`].
    pub fn with_lengths(mut self, materials: Vec<u32>) -> Self {
        self.lengths = materials;
        self
    }

    /// Projection `view` (an index into the scanner's views): `rows x columns` values, row
    /// after row, into `out`. The values do not depend on the thread count.
    pub fn project(&self, view: usize, out: &mut [f32]) {
        let mut outs = vec![Vec::new(); 1 + self.lengths.len()];
        self.project_all(view, &mut outs);
        out.copy_from_slice(&outs[0]);
    }

    /// Projection `view` into `outs[0]` and, into `outs[1 + i]`, the mean path length through
    /// material `i` of [`Self::with_lengths`] (each `rows x columns`, resized to fit).
    pub fn project_all(&self, view: usize, outs: &mut [Vec<f32>]) {
        let scanner = &self.setup.scanner;
        let (columns, rows) = (scanner.columns as usize, scanner.rows as usize);
        let stacks = 1 + self.lengths.len();
        assert_eq!(
            outs.len(),
            stacks,
            "the quantity and each material's lengths"
        );
        let view = &scanner.views[view];
        let materials = self.world.materials.len();
        // Rows in parallel, each pixel's values for every stack side by side.
        let mut all = vec![0.0f32; rows * columns * stacks];
        all.par_chunks_mut(columns * stacks)
            .enumerate()
            .with_max_len(1)
            .for_each_init(
                || {
                    (
                        Buffers::default(),
                        vec![0.0; materials],
                        vec![0.0; stacks - 1],
                    )
                },
                |(buf, lengths, means), (row, values)| {
                    for (column, px) in values.chunks_mut(stacks).enumerate() {
                        px[0] =
                            self.pixel(view, row as u32, column as u32, buf, lengths, means) as f32;
                        for (p, m) in px[1..].iter_mut().zip(means.iter()) {
                            *p = *m as f32;
                        }
                    }
                },
            );
        for (i, out) in outs.iter_mut().enumerate() {
            out.clear();
            out.extend(all.iter().skip(i).step_by(stacks));
        }
    }

    /// One pixel's value, and into `means` the mean lengths of [`Self::with_lengths`]'s
    /// materials.
    fn pixel(
        &self,
        view: &View,
        row: u32,
        column: u32,
        buf: &mut Buffers,
        lengths: &mut [f64],
        means: &mut [f64],
    ) -> f64 {
        let scanner = &self.setup.scanner;
        let n = scanner.samples();
        let mut length = 0.0;
        let mut transmission = LogSum::default();
        means.fill(0.0);
        for s in 0..n {
            match self.ray(view, row, column, s) {
                Some(ray) => material_lengths(self.world, &ray, buf, lengths),
                None => lengths.fill(0.0),
            }
            for (mean, &m) in means.iter_mut().zip(&self.lengths) {
                *mean += lengths[m as usize];
            }
            match self.setup.quantity {
                Quantity::Length => {
                    length += match self.setup.material {
                        Some(m) => lengths[m as usize],
                        None => lengths.iter().sum(),
                    }
                }
                _ => self.world.attenuation.add_ray(lengths, &mut transmission),
            }
        }
        for mean in means.iter_mut() {
            *mean /= f64::from(n);
        }
        let absorbance = f64::from(n).ln() - transmission.ln();
        match self.setup.quantity {
            Quantity::Length => length / f64::from(n),
            Quantity::Absorbance => absorbance.max(0.0),
            Quantity::Transmission => (-absorbance).exp().min(1.0),
        }
    }

    /// Sample `s`'s ray of a pixel, from where it can first meet a solid: parallel rays start
    /// where their line enters the grown bounds (`None` when it misses them), cone rays at
    /// the source.
    fn ray(&self, view: &View, row: u32, column: u32, s: u32) -> Option<Ray> {
        let ray = self.setup.scanner.ray(view, row, column, s);
        match self.setup.scanner.beam {
            _ if self.bounds == Aabb::EMPTY => None,
            Beam::Cone => Some(ray),
            Beam::Parallel => {
                let (t0, _) = self.bounds.ray_range(&ray)?;
                Some(Ray::new(ray.at(t0), ray.dir))
            }
        }
    }
}

impl Projector<'_> {
    /// Writes views `views` of the scan as `float32` TIFF stacks, computing one view at a time
    /// (page `k` is view `views.start + k`): the quantity to `outs[0]`, material `i`'s lengths
    /// of [`Self::with_lengths`] to `outs[1 + i]`; `progress(n)` after each of the `n` views.
    pub fn write_stacks<W: std::io::Write + std::io::Seek>(
        &self,
        outs: &mut [W],
        views: Range<usize>,
        progress: impl Fn(usize),
    ) -> Result<(), String> {
        let s = &self.setup.scanner;
        crate::formats::tiff::write_stacks::<f32, _>(
            outs,
            (s.columns, s.rows),
            views.len(),
            false,
            |k, pages| {
                self.project_all(views.start + k, pages);
                progress(k + 1);
                Ok(())
            },
        )
    }

    /// The JSON sidecar of views `views` of the scan: the geometry in ASTRA's vector form
    /// (`type`, `vectors`: 12 numbers per view, `rows`, `columns`), which views of the whole
    /// scan these are, the quantity, units, materials and spectrum, and the pixel convention.
    pub fn sidecar(&self, views: Range<usize>, scene: &str) -> serde_json::Value {
        let setup = self.setup;
        let s = &setup.scanner;
        let vectors: Vec<[f64; 12]> = s.views[views.clone()].iter().map(View::astra).collect();
        let materials: Vec<serde_json::Value> = self
            .world
            .materials
            .iter()
            .map(|m| serde_json::json!({ "name": m.name, "xray_mu": m.xray_mu }))
            .collect();
        serde_json::json!({
            "type": s.beam.astra_type(),
            "vectors": vectors,
            "rows": s.rows,
            "columns": s.columns,
            "views": [views.start, views.end],
            "total_views": s.views.len(),
            "quantity": setup.quantity.name(),
            "material": setup.material.map(|m| self.world.materials[m as usize].name.clone()),
            "rays_per_pixel": s.samples(),
            "focal_spot": s.focal_spot,
            "units": {
                "length": "scene units",
                "xray_mu": "per scene unit",
                "absorbance": "-ln(I/I0), dimensionless",
                "transmission": "I/I0",
            },
            "materials": materials,
            "spectrum": setup.spectrum.as_ref().map(|sp| serde_json::json!({
                "energies_keV": sp.energies,
                "weights": sp.weights,
            })),
            "layout": "page k of the TIFF stack is view views[0] + k (vectors[k]); its row r, column c is the detector pixel centred at d + (c - columns/2 + 0.5) u + (r - rows/2 + 0.5) v, the mean over a k x k grid of sub-pixel rays; float32",
            "scene": scene,
            "generator": concat!("gencyl ", env!("CARGO_PKG_VERSION")),
        })
    }

    /// The scan.
    pub fn setup(&self) -> &CtSetup {
        self.setup
    }
}
