//! A first renderer: a perspective camera, hair shading on the exact geometry, a floor, a
//! spherical light with soft shadows and a sky gradient, to PNG.
//!
//! Shading: fibers mix Lambert on the exact surface normal (which shows the elliptical,
//! twisted sections) with a Kajiya-Kay highlight around the fiber tangent `t(u)`; the floor is
//! Lambertian. Each sample takes one shadow ray to a uniformly chosen point of the light's
//! sphere, so shadows are soft. Sample positions come from a hash of (pixel, sample, seed): a
//! render does not depend on the thread count.

use std::path::Path;

use gencyl::{GeneralizedCylinder, Ray, Section, Strand};
use glam::DVec3;
use rayon::prelude::*;

use crate::scene::{Scene, Scratch};

/// A pinhole camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position.
    pub eye: DVec3,
    /// The point looked at.
    pub look_at: DVec3,
    /// Up direction.
    pub up: DVec3,
    /// Vertical field of view, degrees.
    pub vfov: f64,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
}

impl Camera {
    /// The ray through image position `(x, y)` (pixels, from the top left).
    pub fn ray(&self, x: f64, y: f64) -> Ray {
        let w = (self.look_at - self.eye).normalize();
        let u = w.cross(self.up).normalize();
        let v = u.cross(w);
        let half_h = (self.vfov.to_radians() * 0.5).tan();
        let half_w = half_h * self.width as f64 / self.height as f64;
        let sx = (2.0 * x / self.width as f64 - 1.0) * half_w;
        let sy = (1.0 - 2.0 * y / self.height as f64) * half_h;
        Ray::new(self.eye, (w + sx * u + sy * v).normalize())
    }
}

/// A spherical light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SphereLight {
    /// Centre.
    pub center: DVec3,
    /// Radius (soft shadows grow with it).
    pub radius: f64,
    /// Irradiance scale at unit distance... in practice: brightness.
    pub intensity: f64,
}

/// What is rendered besides the fibers.
#[derive(Clone, Debug, PartialEq)]
pub struct Stage {
    /// The camera.
    pub camera: Camera,
    /// The light.
    pub light: SphereLight,
    /// Height of the floor plane `y = floor_y`, if any.
    pub floor_y: Option<f64>,
    /// Fiber base colour (linear RGB).
    pub fiber_color: DVec3,
    /// Samples per pixel.
    pub spp: u32,
    /// Seed of the per-pixel sample streams.
    pub seed: u64,
}

/// A linear RGB image, row-major from the top left.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// Pixels.
    pub pixels: Vec<DVec3>,
}

/// SplitMix64 on a key: uniform `f64` in `[0, 1)` streams per (pixel, sample, seed).
struct SampleRng(u64);

impl SampleRng {
    fn new(x: u32, y: u32, sample: u32, seed: u64) -> Self {
        SampleRng(
            seed ^ ((x as u64) << 40 | (y as u64) << 16 | sample as u64)
                .wrapping_mul(0x9E3779B97F4A7C15),
        )
    }
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E3779B97F4A7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Renders `scene` on `stage`, rows in parallel on the current rayon pool.
pub fn render(scene: &Scene, stage: &Stage) -> Image {
    let cam = stage.camera;
    let rows: Vec<Vec<DVec3>> = (0..cam.height)
        .into_par_iter()
        .map_init(Scratch::default, |scratch, y| {
            (0..cam.width)
                .map(|x| {
                    let mut sum = DVec3::ZERO;
                    for s in 0..stage.spp {
                        let mut rng = SampleRng::new(x, y, s, stage.seed);
                        let ray = cam.ray(x as f64 + rng.next(), y as f64 + rng.next());
                        sum += radiance(scene, stage, &ray, &mut rng, scratch);
                    }
                    sum / stage.spp as f64
                })
                .collect()
        })
        .collect();
    Image {
        width: cam.width,
        height: cam.height,
        pixels: rows.into_iter().flatten().collect(),
    }
}

fn sky(d: DVec3) -> DVec3 {
    let k = 0.5 * (d.y + 1.0);
    DVec3::new(0.55, 0.6, 0.68).lerp(DVec3::new(0.18, 0.28, 0.45), k)
}

/// Visibility of a random point of the light from `p`, and the direction and distance to it.
fn light_sample(
    scene: &Scene,
    light: &SphereLight,
    p: DVec3,
    rng: &mut SampleRng,
    scratch: &mut Scratch,
) -> (DVec3, f64) {
    // Uniform point in the sphere (rejection), good enough for soft shadows.
    let offset = loop {
        let q = DVec3::new(rng.next(), rng.next(), rng.next()) * 2.0 - DVec3::ONE;
        if q.length_squared() <= 1.0 {
            break q * light.radius;
        }
    };
    let to = light.center + offset - p;
    let dist = to.length();
    let dir = to / dist;
    let blocked = scene.any_hit(&Ray::new(p, dir), 1e-9, dist, scratch);
    (
        dir,
        if blocked {
            0.0
        } else {
            light.intensity / (dist * dist)
        },
    )
}

fn radiance(
    scene: &Scene,
    stage: &Stage,
    ray: &Ray,
    rng: &mut SampleRng,
    scratch: &mut Scratch,
) -> DVec3 {
    let floor_t = stage.floor_y.and_then(|fy| {
        let t = (fy - ray.origin.y) / ray.dir.y;
        (t > 0.0 && t.is_finite()).then_some(t)
    });
    let limit = floor_t.unwrap_or(f64::INFINITY);
    let ambient = 0.12;
    if let Some(h) = scene.nearest_hit(ray, 0.0, limit, scratch) {
        let cyl = &scene.cylinders()[h.object as usize];
        let n = h.hit.normal;
        let p = h.hit.point + n * 1e-7;
        let (l, e) = light_sample(scene, &stage.light, p, rng, scratch);
        let t = cyl.frame(h.hit.u).t;
        let v = -ray.dir;
        // Lambert on the exact normal, plus Kajiya-Kay: diffuse ~ sin(t, l), specular
        // ~ (cos(t,l) cos(t,v) + sin(t,l) sin(t,v))^p.
        let (tl, tv) = (t.dot(l), t.dot(v));
        let (sl, sv) = (
            (1.0 - tl * tl).max(0.0).sqrt(),
            (1.0 - tv * tv).max(0.0).sqrt(),
        );
        let lambert = n.dot(l).max(0.0);
        let kk_spec = (-tl * tv + sl * sv).max(0.0).powf(40.0);
        let color = stage.fiber_color;
        return color * (ambient + e * (0.75 * lambert + 0.25 * sl))
            + DVec3::splat(0.35 * e * kk_spec * lambert.sqrt());
    }
    if let Some(t) = floor_t {
        let p = ray.at(t);
        let (l, e) = light_sample(scene, &stage.light, p + DVec3::Y * 1e-9, rng, scratch);
        // A soft checker to show depth.
        let check = ((p.x * 2.0).floor() + (p.z * 2.0).floor()).rem_euclid(2.0);
        let albedo = DVec3::splat(0.55 + 0.1 * check);
        let fade = (-0.02 * t * t).exp();
        return (albedo * (ambient + e * l.y.max(0.0))) * fade + sky(ray.dir) * (1.0 - fade);
    }
    sky(ray.dir)
}

/// Writes `image` as an 8-bit sRGB PNG (values clamped to `[0, 1]`).
pub fn write_png(image: &Image, path: &Path) -> std::io::Result<()> {
    let encode = |c: f64| {
        let c = c.clamp(0.0, 1.0);
        let s = if c <= 0.0031308 {
            12.92 * c
        } else {
            1.055 * c.powf(1.0 / 2.4) - 0.055
        };
        (s * 255.0 + 0.5) as u8
    };
    let data: Vec<u8> = image
        .pixels
        .iter()
        .flat_map(|p| [encode(p.x), encode(p.y), encode(p.z)])
        .collect();
    // Write to a temporary file first, so a failure leaves nothing half-written.
    let tmp = path.with_extension("png.partial");
    {
        let file = std::fs::File::create(&tmp)?;
        let mut enc = png::Encoder::new(std::io::BufWriter::new(file), image.width, image.height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.write_header()
            .and_then(|mut w| w.write_image_data(&data))
            .map_err(std::io::Error::other)?;
    }
    std::fs::rename(&tmp, path)
}

/// The built-in scene: a tuft of curly fibers rising from the floor, elliptical and twisted to
/// different degrees, under a large spherical light.
pub fn default_scene() -> (Vec<GeneralizedCylinder>, Stage) {
    let mut rng = SampleRng(0x5eed);
    let mut cylinders = Vec::new();
    let strands = 48;
    for i in 0..strands {
        // Roots on a disc (sunflower pattern), leaning outward.
        let a = i as f64 * 2.399963;
        let rr = 0.28 * ((i as f64 + 0.5) / strands as f64).sqrt();
        let root = DVec3::new(rr * a.cos(), 0.0, rr * a.sin());
        let lean = DVec3::new(a.cos(), 0.0, a.sin()) * (0.15 + 0.5 * rr);
        let height = 1.0 + 0.5 * rng.next();
        let curl_r = 0.05 + 0.07 * rng.next();
        let turns = 2.0 + 2.0 * rng.next();
        let phase = rng.next() * std::f64::consts::TAU;
        let n = 14;
        let points = (0..n)
            .map(|k| {
                let s = k as f64 / (n - 1) as f64;
                let ang = phase + s * turns * std::f64::consts::TAU;
                let grow = s.min(0.25) * 4.0; // curls open up above the root
                root + DVec3::Y * (height * s)
                    + lean * s * s
                    + DVec3::new(ang.cos(), 0.0, ang.sin()) * curl_r * grow
            })
            .collect();
        let ellipticity = [1.0, 0.75, 0.5, 0.35][i % 4];
        let strand = Strand {
            points,
            radius: [0.012, 0.005],
            ellipticity,
            twist: [0.0, (i % 3) as f64 * 2.0 * std::f64::consts::TAU],
            section: Section::default(),
        };
        cylinders.extend(strand.cylinders().expect("the default strands are valid"));
    }
    let stage = Stage {
        camera: Camera {
            eye: DVec3::new(0.4, 1.1, 3.0),
            look_at: DVec3::new(0.0, 0.7, 0.0),
            up: DVec3::Y,
            vfov: 32.0,
            width: 320,
            height: 240,
        },
        light: SphereLight {
            center: DVec3::new(2.5, 4.0, 2.0),
            radius: 0.8,
            intensity: 28.0,
        },
        floor_y: Some(0.0),
        fiber_color: DVec3::new(0.42, 0.2, 0.08),
        spp: 2,
        seed: 1,
    };
    (cylinders, stage)
}

/// A stage that frames `cylinders`: the camera looks at the centre of their bounds from the
/// front and above, far enough to see all of it; the floor just below; the light above.
pub fn framed_stage(cylinders: &[GeneralizedCylinder]) -> Stage {
    let (_, mut stage) = default_scene();
    let b = cylinders
        .iter()
        .fold(gencyl::Aabb::EMPTY, |b, c| b.union(c.bounds()));
    if !(b.min.is_finite() && b.max.is_finite()) {
        return stage; // no cylinders: the empty stage
    }
    let center = b.center();
    let radius = (0.5 * (b.max - b.min).length()).max(1e-9);
    let dist = radius / (0.5 * stage.camera.vfov.to_radians()).sin() * 1.05;
    let dir = DVec3::new(0.25, 0.35, 1.0).normalize();
    stage.camera.eye = center + dir * dist;
    stage.camera.look_at = center;
    stage.light = SphereLight {
        center: center + DVec3::new(1.5, 3.0, 1.2) * radius * 1.5,
        radius: 0.4 * radius,
        intensity: stage.light.intensity / 36.0 * (radius * 1.5).powi(2) * 14.0,
    };
    stage.floor_y = Some(b.min.y - 0.02 * radius);
    stage
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small_default() -> (Scene, Stage) {
        let (cyl, mut stage) = default_scene();
        stage.camera.width = 40;
        stage.camera.height = 30;
        stage.spp = 1;
        (Scene::new(cyl), stage)
    }

    #[test]
    fn the_default_scene_shows_fibers_floor_and_sky_without_nan() {
        let (scene, stage) = small_default();
        let img = render(&scene, &stage);
        assert_eq!(img.pixels.len(), 40 * 30, "one value per pixel");
        assert!(
            img.pixels
                .iter()
                .all(|p| p.is_finite() && p.min_element() >= 0.0),
            "finite, non-negative"
        );
        // Fiber pixels are reddish-brown (r > 1.5 b); the sky is bluish (b > r).
        let fiber = img.pixels.iter().filter(|p| p.x > 1.5 * p.z).count();
        let sky = img.pixels.iter().filter(|p| p.z > p.x).count();
        assert!(
            fiber > 20 && sky > 20,
            "fiber pixels {fiber}, sky pixels {sky}"
        );
    }

    #[test]
    fn renders_do_not_depend_on_the_thread_count() {
        let (scene, stage) = small_default();
        let run = |n| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .unwrap()
                .install(|| render(&scene, &stage))
        };
        assert_eq!(run(1), run(2), "1 thread vs 2 threads");
    }

    #[test]
    fn png_output_is_complete_or_absent() {
        let (scene, stage) = small_default();
        let img = render(&scene, &stage);
        let dir = std::env::temp_dir().join(format!("gencyl-png-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("x.png");
        write_png(&img, &path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(&bytes[1..4], b"PNG", "PNG signature");
        assert!(
            !path.with_extension("png.partial").exists(),
            "no partial file left"
        );
        // A directory that does not exist: an error, and nothing written.
        let bad = dir.join("missing").join("y.png");
        assert!(
            write_png(&img, &bad).is_err(),
            "unwritable path is an error"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
