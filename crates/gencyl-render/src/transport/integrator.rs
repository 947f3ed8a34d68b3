//! Integrators: what a camera ray's value is, and the driver that renders a window of the
//! frame.
//!
//! - `normals`, `uv`, `depth`: debug views of the nearest hit.
//! - `direct`: light arriving at the first non-specular surface, by next-event estimation
//!   and BSDF sampling combined with multiple importance sampling (power heuristic).
//! - `path`: a unidirectional path tracer, the same estimators at every vertex, Russian
//!   roulette after three bounces.
//! - `xray`: the path length through the solids along the ray, `L_m` per material, written
//!   as transmittance `exp(-sum mu_m L_m)` in R, G, B and raw `L = sum L_m` in channel `L`.
//!
//! Every film has channels R, G, B and A (the fraction of samples that hit something);
//! `depth` adds `Z` (the nearest hit's distance over the samples, infinite when none hit),
//! `xray` adds `L` (mean path length). A pixel's samples come from
//! [`SampleRng::new`]`(x, y, sample, seed)` in full-frame coordinates, so its value does not
//! depend on the thread count or the crop window.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, PoisonError};

use gencyl::{Part, Ray};
use glam::DVec3;
use rayon::prelude::*;

use crate::accel::{COUNTING, QueryCounts, RegionList, SceneHit, Scratch};
use crate::formats::film::{Film, Window};
use crate::optics::camera::{Camera, CameraRays};
use crate::optics::light::Light;
use crate::optics::material::{Bsdf, Material};
use crate::sampling::{SampleRng, power_heuristic};
pub use crate::settings::{Integrator, RenderSettings};
use crate::transport::ct;
use crate::transport::world::{Crossing, Fibers, Surface, World, WorldHit};

/// Offsets a ray's origin off the surface at `p` (normal `n`) to the side `dir` goes, by
/// `1e-9 (1 + |p|_inf)`: far above the hits' error (about `1e-12` of the scene's size), far
/// below a fiber's radius.
fn spawn(p: DVec3, n: DVec3, dir: DVec3) -> Ray {
    let eps = 1e-9 * (1.0 + p.abs().max_element());
    let side = if dir.dot(n) >= 0.0 { 1.0 } else { -1.0 };
    Ray::new(p + side * eps * n, dir)
}

/// Per-thread buffers.
#[derive(Default)]
pub struct Buffers {
    pub(crate) scratch: Scratch,
    pub(crate) hits: Vec<SceneHit>,
    pub(crate) crossings: Vec<Crossing>,
    /// Path length per material.
    pub(crate) lengths: Vec<f64>,
    /// The BVH leaves a pixel's frustum may meet.
    pub(crate) region: RegionList,
}

/// One sample's contribution to a pixel, per channel of [`Integrator::channels`].
type Sample = [f64; 5];

/// The value of one camera ray.
pub fn sample_ray(
    world: &World,
    camera: &Camera,
    settings: &RenderSettings,
    ray: &Ray,
    rng: &mut SampleRng,
    buf: &mut Buffers,
) -> Sample {
    sample_ray_where(world, camera, settings, ray, Fibers::All, rng, buf)
}

/// [`sample_ray`] for a camera ray that may meet only `fibers` (its first query's, then
/// [`World::intersect_where`]; the same value).
pub fn sample_ray_where(
    world: &World,
    camera: &Camera,
    settings: &RenderSettings,
    ray: &Ray,
    fibers: Fibers,
    rng: &mut SampleRng,
    buf: &mut Buffers,
) -> Sample {
    let miss_rgb = |d: DVec3| world.environment.map_or(DVec3::ZERO, |e| e.radiance(d));
    match settings.integrator {
        Integrator::Normals | Integrator::Uv | Integrator::Depth => {
            let range = (0.0, f64::INFINITY);
            let Some(h) = world.intersect_where(ray, range, None, fibers, &mut buf.scratch) else {
                return [0.0, 0.0, 0.0, 0.0, f64::INFINITY];
            };
            let c = match (settings.integrator, h.surface) {
                (Integrator::Normals, _) => (h.normal + DVec3::ONE) * 0.5,
                (Integrator::Uv, Surface::Fiber { u, v, part, .. }) => {
                    let p = match part {
                        Part::Side => 0.0,
                        Part::StartCap => 0.5,
                        Part::EndCap => 1.0,
                        Part::Seam => 1.5,
                    };
                    DVec3::new(u, v / std::f64::consts::TAU, p)
                }
                (Integrator::Uv, _) => DVec3::ZERO,
                _ => {
                    let focus = (camera.look_at - camera.position).length();
                    DVec3::splat(1.0 / (1.0 + h.t * ray.dir.length() / focus))
                }
            };
            [c.x, c.y, c.z, 1.0, h.t * ray.dir.length()]
        }
        Integrator::Xray => {
            let (l, mu_l) = xray_length(world, ray, buf);
            let tr = (-mu_l).exp();
            [tr, tr, tr, if l > 0.0 { 1.0 } else { 0.0 }, l]
        }
        Integrator::Direct | Integrator::Path => {
            let (c, hit) = radiance(world, settings, ray, fibers, rng, buf, miss_rgb);
            [c.x, c.y, c.z, if hit { 1.0 } else { 0.0 }, 0.0]
        }
    }
}

/// Path length through the solids along the ray (`t` in units of `|d|`) in total, and the
/// absorbance `-ln(I/I0)` of the materials' attenuation along it (monochromatic: `sum mu_m
/// L_m`; under a `[ct]` spectrum, of the weighted bins): [`ct::material_lengths`] and
/// [`ct::Attenuation`].
pub fn xray_length(world: &World, ray: &Ray, buf: &mut Buffers) -> (f64, f64) {
    let mut lengths = std::mem::take(&mut buf.lengths);
    lengths.resize(world.materials.len(), 0.0);
    ct::material_lengths(world, ray, buf, &mut lengths);
    let total = lengths.iter().sum();
    let absorbance = world.attenuation.absorbance(&lengths).max(0.0);
    buf.lengths = lengths;
    (total, absorbance)
}

/// Radiance along a camera ray, and whether it hit anything. `direct` stops after the first
/// non-specular vertex (light from its next event and its BSDF sample only).
fn radiance(
    world: &World,
    settings: &RenderSettings,
    camera_ray: &Ray,
    camera_fibers: Fibers,
    rng: &mut SampleRng,
    buf: &mut Buffers,
    env: impl Fn(DVec3) -> DVec3,
) -> (DVec3, bool) {
    let direct_only = settings.integrator == Integrator::Direct;
    let n_lights = world.lights.len() + usize::from(world.environment.is_some());
    let pick = if n_lights > 0 {
        1.0 / n_lights as f64
    } else {
        0.0
    };
    let mut ray = Ray::new(camera_ray.origin, camera_ray.dir.normalize());
    let (mut l, mut beta) = (DVec3::ZERO, DVec3::ONE);
    // Density of the BSDF sample that made `ray` (inf: camera or specular), and its origin.
    let mut prev_pdf = f64::INFINITY;
    let mut prev_point = ray.origin;
    let mut emission_only = false;
    let mut first_hit = false;
    // The surface `ray` leaves (none for the camera's).
    let mut leaving = None;
    for depth in 0..=settings.max_depth {
        let fibers = if depth == 0 {
            camera_fibers
        } else {
            Fibers::All
        };
        let range = (0.0, f64::INFINITY);
        let Some(h) = world.intersect_where(&ray, range, leaving, fibers, &mut buf.scratch) else {
            if let Some(e) = world.environment {
                let w = if prev_pdf.is_infinite() {
                    1.0
                } else {
                    power_heuristic(prev_pdf, pick * e.pdf())
                };
                l += beta * env(ray.dir) * w;
            }
            break;
        };
        if depth == 0 {
            first_hit = true;
        }
        if let Surface::Light(i) = h.surface {
            if let Light::Sphere { radiance, .. } = world.lights[i as usize]
                && h.normal.dot(ray.dir) < 0.0
            {
                let w = if prev_pdf.is_infinite() {
                    1.0
                } else {
                    power_heuristic(prev_pdf, pick * world.lights[i as usize].pdf(prev_point))
                };
                l += beta * radiance * w;
            }
            break;
        }
        if emission_only || depth == settings.max_depth {
            break;
        }
        let material = &world
            .material(h.surface)
            .expect("surfaces other than lights have materials")
            .material;
        // The segment just travelled was inside this solid if the ray now leaves it.
        if let Material::Dielectric { sigma_a, .. } = *material
            && h.normal.dot(ray.dir) > 0.0
        {
            beta *= (-sigma_a * h.t).exp();
        }
        let wo = -ray.dir;
        let at = world.shading_point_for(&h, material.uses_section());
        let bsdf = Bsdf::new(material, &at, wo);
        if !bsdf.is_delta() && n_lights > 0 {
            l += beta * next_event(world, &h, &bsdf, wo, pick, rng, buf);
        }
        let Some(s) = bsdf.sample(wo, [rng.uniform(), rng.uniform(), rng.uniform()]) else {
            break;
        };
        if !s.weight.is_finite() || s.weight == DVec3::ZERO {
            break;
        }
        beta *= s.weight;
        prev_pdf = s.pdf;
        prev_point = h.point;
        ray = spawn(h.point, h.normal, s.wi);
        leaving = Some(h.surface);
        if direct_only && !bsdf.is_delta() {
            emission_only = true;
        }
        if depth >= 3 {
            let q = beta.max_element().min(0.95);
            if rng.uniform() >= q {
                break;
            }
            beta /= q;
        }
    }
    (l, first_hit)
}

/// Light from one light chosen uniformly (probability `pick`), weighted against BSDF
/// sampling by the power heuristic.
fn next_event(
    world: &World,
    h: &WorldHit,
    bsdf: &Bsdf,
    wo: DVec3,
    pick: f64,
    rng: &mut SampleRng,
    buf: &mut Buffers,
) -> DVec3 {
    let choice = ((rng.uniform() / pick) as usize).min(world.lights.len());
    let u = rng.uniform2();
    let ls = match world.lights.get(choice) {
        Some(light) => light.sample(h.point, u),
        None => world.environment.map(|e| e.sample(u)),
    };
    let Some(ls) = ls else {
        return DVec3::ZERO;
    };
    if ls.value == DVec3::ZERO {
        return DVec3::ZERO;
    }
    let shadow = spawn(h.point, h.normal, ls.wi);
    let reach = if ls.dist.is_finite() {
        (ls.dist - (shadow.origin - h.point).length()) * (1.0 - 1e-9)
    } else {
        f64::INFINITY
    };
    let mut occluded = || world.occluded(&shadow, (0.0, reach), Some(h.surface), &mut buf.scratch);
    // The same value either way; only the cost differs. A costly BSDF (hair's, where most
    // shadow rays from within the fibers are blocked) is evaluated only where the light is
    // seen; a cheap one first, so that its zero (a light behind a surface) spares the ray.
    let costly = bsdf.eval_is_costly();
    if costly && occluded() {
        return DVec3::ZERO;
    }
    let (f, bsdf_pdf) = bsdf.eval_pdf(wo, ls.wi);
    if f == DVec3::ZERO || !costly && occluded() {
        return DVec3::ZERO;
    }
    let w = if ls.pdf.is_infinite() {
        1.0
    } else {
        power_heuristic(pick * ls.pdf, bsdf_pdf)
    };
    f * ls.value * (w / pick)
}

/// A rendered window, and how many samples were dropped for not being finite.
#[derive(Clone, Debug)]
pub struct Rendered {
    /// The image.
    pub film: Film,
    /// Samples whose value was NaN or infinite (in a channel other than depth's `Z`): never
    /// written; their pixels are the mean of the finite ones.
    pub non_finite_samples: u64,
    /// What the render's ray queries did (all threads).
    pub counts: QueryCounts,
}

/// Renders `window` of the frame into a film (rows in parallel on the current rayon pool),
/// calling `progress(rows_done)` as rows finish.
pub fn render(
    world: &World,
    camera: &Camera,
    settings: &RenderSettings,
    window: Window,
    progress: &(dyn Fn(u64) + Sync),
) -> Rendered {
    let channels = settings.integrator.channels();
    let nc = channels.len();
    let mut film = Film::new((camera.width, camera.height), window, channels);
    let rays = camera.rays();
    let row_len = window.width() as usize * nc;
    let done = AtomicU64::new(0);
    let dropped = AtomicU64::new(0);
    let counts = Mutex::new(QueryCounts::default());
    film.data
        .par_chunks_mut(row_len)
        .enumerate()
        .with_max_len(1)
        .for_each_init(Buffers::default, |buf, (j, row)| {
            let y = window.y0 + j as u32;
            let mut row_dropped = 0;
            for (i, px) in row.chunks_mut(nc).enumerate() {
                let x = window.x0 + i as u32;
                let (v, d) = pixel(world, &rays, settings, x, y, buf);
                row_dropped += d as u64;
                for (dst, src) in px.iter_mut().zip(v) {
                    *dst = src as f32;
                }
            }
            if row_dropped > 0 {
                dropped.fetch_add(row_dropped, Ordering::Relaxed);
            }
            if COUNTING {
                let row_counts = buf.scratch.take_counts();
                *counts.lock().unwrap_or_else(PoisonError::into_inner) += row_counts;
            }
            progress(done.fetch_add(1, Ordering::Relaxed) + 1);
        });
    Rendered {
        film,
        non_finite_samples: dropped.into_inner(),
        counts: counts.into_inner().unwrap_or_else(PoisonError::into_inner),
    }
}

/// Pixels of at least this many samples list first the fibers' BVH leaves their frustum may
/// meet ([`World::list_fibers`]; X-ray's crossings do not); fewer samples would not repay the
/// walk. The list holds at most `spp / 2` nodes (beyond, the pixel's rays walk the tree): on
/// the path-traced ponytail a cap of 8, 16 or 32 nodes changed the instructions (callgrind,
/// one thread) of a 128x128 render at 16 samples by -1.3%, -0.5% and +0.8%, and of a band of
/// the 512x512 one at 64 samples by -7.5%, -8.1% and -9.1%; asking only whether the list is
/// empty, by -1.7% and -5.1%.
const FRUSTUM_SAMPLES: u32 = 4;

/// The value of pixel `(x, y)`: the mean of its finite samples (`Z`: their minimum), and the
/// number of samples dropped because a value other than `Z` was NaN or infinite. A pixel whose
/// every sample was dropped is 0.
pub fn pixel(
    world: &World,
    camera: &CameraRays,
    settings: &RenderSettings,
    x: u32,
    y: u32,
    buf: &mut Buffers,
) -> (Sample, u32) {
    let mut sum = [0.0; 5];
    let mut z = f64::INFINITY;
    let mut dropped = 0;
    // The fibers' BVH leaves the pixel's rays may meet, listed once for all its samples:
    // none where nothing is there, else what its camera rays walk instead of the tree.
    let (fx, fy) = (x as f64, y as f64);
    let mut region = std::mem::take(&mut buf.region);
    let fibers = if settings.spp < FRUSTUM_SAMPLES || settings.integrator == Integrator::Xray {
        Fibers::All
    } else {
        let frustum = camera.frustum([fx, fy], [fx + 1.0, fy + 1.0]);
        world.list_fibers(&frustum, (settings.spp / 2) as usize, &mut region);
        if region.is_empty() {
            Fibers::None
        } else {
            Fibers::Listed(&region)
        }
    };
    for s in 0..settings.spp {
        let mut rng = SampleRng::new(x, y, s, settings.seed);
        let ray = camera.ray(fx + rng.uniform(), fy + rng.uniform());
        let v = sample_ray_where(
            world,
            camera.camera(),
            settings,
            &ray,
            fibers,
            &mut rng,
            buf,
        );
        // The fifth value is the hit's distance (infinite where the sample saw nothing: a
        // value, not an overflow) except for X-ray, where it is a path length.
        let z_ok = if settings.integrator == Integrator::Xray {
            v[4].is_finite()
        } else {
            !v[4].is_nan()
        };
        if !(z_ok && v[..4].iter().all(|c| c.is_finite())) {
            dropped += 1;
            continue;
        }
        for k in 0..5 {
            sum[k] += v[k];
        }
        z = z.min(v[4]);
    }
    buf.region = region;
    let n = (settings.spp - dropped).max(1) as f64;
    let mut out = sum.map(|x| x / n);
    if settings.integrator == Integrator::Depth {
        out[4] = z;
    }
    (out, dropped)
}
