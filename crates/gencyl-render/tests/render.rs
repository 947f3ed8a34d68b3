//! Renders checked against closed forms: silhouettes, X-ray chords, furnaces, Beer-Lambert,
//! light falloff; and the run-level guarantees (thread count, crop windows).

use gencyl::Ray;
use gencyl_render::accel::RegionList;
use gencyl_render::formats::{Film, Window};
use gencyl_render::optics::Camera;
use gencyl_render::sampling::SampleRng;
use gencyl_render::scene_file::SceneDescription;
use gencyl_render::settings::{Integrator, RenderSettings};
use gencyl_render::transport::World;
use gencyl_render::transport::integrator::{self, Buffers};
use glam::DVec3;

/// A world and its camera from scene text.
fn world(src: &str) -> (World, Camera) {
    let d = SceneDescription::parse(src, "test.toml").unwrap_or_else(|e| panic!("{e}"));
    let cam = d.camera.expect("test scenes have a camera");
    (World::new(d), cam)
}

fn settings(integrator: Integrator, spp: u32) -> RenderSettings {
    RenderSettings {
        integrator,
        spp,
        max_depth: 64,
        seed: 7,
    }
}

fn full(world: &World, cam: &Camera, s: &RenderSettings) -> Film {
    let r = integrator::render(world, cam, s, Window::full(cam.width, cam.height), &|_| {});
    assert_eq!(r.non_finite_samples, 0, "every sample finite");
    r.film
}

/// A straight fiber along x from -2 to 2, radii (A, B), seen by an orthographic camera.
fn straight_fiber(a: f64, b: f64, camera: &str) -> String {
    format!(
        "[[cylinder]]\nbezier = [[-2, 0, 0], [-1, 0, 0], [1, 0, 0], [2, 0, 0]]\n\
         major_radius = [{a}, {a}]\nminor_radius = [{b}, {b}]\nnormal_hint = [0, 1, 0]\n\
         [camera]\n{camera}\n"
    )
}

/// Orthographic debug renders: the coverage (alpha) summed down a column is the fiber's width
/// in pixels, `2r / pixel`, to within one pixel. The elliptical fiber's major axis lies along
/// its frame's `n` = +y (the hint): seen from +z it is `2A` wide, from +y `2B`.
#[test]
fn silhouette_width_is_the_diameter() {
    let front = "type = \"orthographic\"\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\nview_height = 1.0\nresolution = [16, 64]";
    let above = "type = \"orthographic\"\nposition = [0, 5, 0]\nlook_at = [0, 0, 0]\nup = [0, 0, -1]\nview_height = 1.0\nresolution = [16, 64]";
    for (a, b, cam, want_r) in [
        (0.1, 0.1, front, 0.1),
        (0.2, 0.07, front, 0.2),
        (0.2, 0.07, above, 0.07),
    ] {
        let (w, c) = world(&straight_fiber(a, b, cam));
        let film = full(&w, &c, &settings(Integrator::Normals, 16));
        let px = c.pixel_size().unwrap();
        let alpha = film.channel_index("A").unwrap();
        for x in [3, 8, 12] {
            let width: f64 = (0..c.height).map(|y| film.pixel(x, y)[alpha] as f64).sum();
            let want = 2.0 * want_r / px;
            assert!(
                (width - want).abs() <= 1.0,
                "A={a} B={b}: column {x} covers {width} px, want {want}"
            );
        }
    }
}

/// X-ray path lengths against chords: across a straight round fiber at offset `s` from the
/// axis `2 sqrt(r^2 - s^2)`; in through the cap and out through the side; from inside; through
/// a sphere; and the transmittance channel `exp(-mu L)`.
#[test]
fn xray_lengths_match_chords() {
    let r = 0.25;
    let src = format!(
        "[[cylinder]]\nbezier = [[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]]\nmajor_radius = [{r}, {r}]\nmaterial = \"bone\"\n\
         [[sphere]]\ncenter = [10, 5, 0]\nradius = 2\n\
         [material.bone]\ntype = \"diffuse\"\nxray_mu = 3\n\
         [camera]\nposition = [1.5, 0, 5]\nlook_at = [1.5, 0, 0]\n"
    );
    let (w, _) = world(&src);
    let mut buf = Buffers::default();
    let len = |ray: Ray, buf: &mut Buffers| integrator::xray_length(&w, &ray, buf);
    for s in [0.0, 0.1, 0.2, 0.249] {
        let (l, mu_l) = len(
            Ray::new(DVec3::new(1.5, s, 4.0), DVec3::new(0.0, 0.0, -2.0)),
            &mut buf,
        );
        let want = 2.0 * (r * r - s * s).sqrt();
        assert!((l - want).abs() < 1e-12, "offset {s}: L = {l}, want {want}");
        assert!((mu_l - 3.0 * want).abs() < 1e-11, "mu L = {mu_l}");
    }
    // In through the cap at x = 0, out through the side z = r: origin (-1, 0, z0), d = (1, 0, k).
    let (z0, k) = (-0.1, 0.1);
    let x_exit = (r - z0) / k - 1.0;
    let want = (1.0 + k * k).sqrt() * x_exit;
    let (l, _) = len(
        Ray::new(DVec3::new(-1.0, 0.0, z0), DVec3::new(1.0, 0.0, k)),
        &mut buf,
    );
    assert!(
        (l - want).abs() < 1e-12,
        "cap to side: L = {l}, want {want}"
    );
    // Along the axis through both caps: the axis length, 3. A non-unit direction: lengths
    // are in world units.
    let (l, _) = len(
        Ray::new(DVec3::new(-1.0, 0.01, 0.02), DVec3::X * 0.5),
        &mut buf,
    );
    assert!((l - 3.0).abs() < 1e-12, "through both caps: L = {l}");
    // From inside the fiber (origin on the axis) straight out: r.
    let (l, _) = len(Ray::new(DVec3::new(1.5, 0.0, 0.0), DVec3::Z), &mut buf);
    assert!((l - r).abs() < 1e-12, "from inside: L = {l}");
    // Through the sphere's centre: its diameter.
    let (l, mu_l) = len(Ray::new(DVec3::new(10.0, 5.0, 9.0), -DVec3::Z), &mut buf);
    assert!(
        (l - 4.0).abs() < 1e-12 && (mu_l - 4.0).abs() < 1e-12,
        "sphere: L = {l}"
    );
    // The pixel: transmittance exp(-mu L) in R, raw L in channel L.
    let cam = Camera {
        position: DVec3::new(1.5, 0.0, 5.0),
        look_at: DVec3::new(1.5, 0.0, 0.0),
        up: DVec3::Y,
        projection: gencyl_render::optics::Projection::Orthographic { height: 0.001 },
        width: 1,
        height: 1,
    };
    let (v, dropped) = integrator::pixel(
        &w,
        &cam.rays(),
        &settings(Integrator::Xray, 4),
        0,
        0,
        &mut buf,
    );
    assert_eq!(dropped, 0);
    assert!((v[4] - 2.0 * r).abs() < 1e-5, "pixel L = {}", v[4]);
    assert!(
        (v[0] - (-3.0 * v[4]).exp()).abs() < 1e-12,
        "pixel transmittance {}",
        v[0]
    );
}

/// Listing once a pixel the BVH leaves its frustum may meet (its camera rays then walk the
/// list, or nothing where it is empty) changes no pixel: every pixel of
/// curly strands seen by perspective and orthographic cameras, near and far, under `path`
/// and `normals`, equals the mean of its samples each traced in full; some pixels see only
/// the background (the rays are then not traced among the fibers) and some see fibers.
#[test]
fn pixel_frustums_change_no_pixel() {
    let strands = "[[strand]]\npoints = [[-2, 0, 0], [-0.5, 0.4, 0.1], [0.5, -0.3, 0], [2, 0.1, 0.2]]\n\
                   radius = [0.05, 0.02]\nmaterial = \"m\"\n\
                   [[strand]]\npoints = [[-1, -1, 0.3], [0, -0.6, -0.2], [1, -1.2, 0.1]]\n\
                   radius = [0.03, 0.03]\nmaterial = \"m\"\n\
                   [material.m]\ntype = \"hair\"\nmelanin = 1\n\
                   [environment]\ncolor = 0.5\n\
                   [[light]]\ntype = \"directional\"\ndirection = [0, -1, -1]\nirradiance = 2\n";
    // And a fringe of thin strands below them, so that some pixels meet many BVH nodes.
    let fringe: String = (0..60)
        .map(|i| {
            let (x, z) = (-1.5 + 0.05 * i as f64, 0.02 * (i % 7) as f64);
            format!(
                "[[strand]]\npoints = [[{x}, -1.2, {z}], [{}, -1.6, {}], [{x}, -2, {z}]]\n\
                 radius = [0.01, 0.005]\nmaterial = \"m\"\n",
                x + 0.1,
                z - 0.1
            )
        })
        .collect();
    let strands = format!("{strands}{fringe}");
    let cameras = [
        "position = [0, 0, 5]\nlook_at = [0, -0.3, 0]\nfov = 40\nresolution = [24, 18]",
        "position = [0.3, 1, 40]\nlook_at = [0, 0, 0]\nfov = 5\nresolution = [20, 20]",
        "type = \"orthographic\"\nposition = [0, 0, 5]\nlook_at = [0, -0.3, 0]\n\
         view_height = 3\nresolution = [16, 16]",
    ];
    let (mut empty, mut listed, mut whole) = (0, 0, 0);
    for camera in cameras {
        let (w, cam) = world(&format!("{strands}[camera]\n{camera}\n"));
        let rays = cam.rays();
        // Lists of up to 4 and 16 nodes (spp / 2).
        for (integ, spp) in [(Integrator::Path, 8), (Integrator::Normals, 32)] {
            let s = settings(integ, spp);
            let mut buf = Buffers::default();
            for y in 0..cam.height {
                for x in 0..cam.width {
                    let (fx, fy) = (x as f64, y as f64);
                    // As the pixel lists them: empty, walked as listed, or walked as the tree.
                    let mut list = RegionList::default();
                    let frustum = rays.frustum([fx, fy], [fx + 1.0, fy + 1.0]);
                    w.list_fibers(&frustum, spp as usize / 2, &mut list);
                    empty += usize::from(list.is_empty());
                    listed += usize::from(list.nodes() > 0);
                    whole += usize::from(!list.is_empty() && list.nodes() == 0);
                    let (v, dropped) = integrator::pixel(&w, &rays, &s, x, y, &mut buf);
                    assert_eq!(dropped, 0);
                    let mut sum = [0.0; 5];
                    for i in 0..s.spp {
                        let mut rng = SampleRng::new(x, y, i, s.seed);
                        let ray = rays.ray(fx + rng.uniform(), fy + rng.uniform());
                        let one = integrator::sample_ray(&w, &cam, &s, &ray, &mut rng, &mut buf);
                        for k in 0..5 {
                            sum[k] += one[k];
                        }
                    }
                    let mut want = sum.map(|x| x / s.spp as f64);
                    if integ == Integrator::Normals {
                        want[4] = v[4];
                    }
                    assert_eq!(
                        v.map(f64::to_bits),
                        want.map(f64::to_bits),
                        "{camera} ({x}, {y})"
                    );
                }
            }
        }
    }
    assert!(
        empty > 200 && listed > 50 && whole > 20,
        "{empty} empty, {listed} listed, {whole} walked whole"
    );
}

/// One camera ray's mean radiance over `n` samples, and the standard error.
fn mean_radiance(w: &World, cam: &Camera, s: &RenderSettings, ray: Ray, n: u32) -> (f64, f64) {
    let mut buf = Buffers::default();
    let (mut sum, mut sum2) = (0.0, 0.0);
    for i in 0..n {
        let mut rng = SampleRng::new(0, 0, i, s.seed);
        let v = integrator::sample_ray(w, cam, s, &ray, &mut rng, &mut buf);
        assert!(
            v.iter().take(4).all(|x| x.is_finite()),
            "finite sample {v:?}"
        );
        sum += v[1];
        sum2 += v[1] * v[1];
    }
    let mean = sum / n as f64;
    let var = (sum2 / n as f64 - mean * mean).max(0.0);
    (mean, (var / n as f64).sqrt())
}

/// White furnaces: in a constant environment of radiance 1, a non-absorbing scatterer that
/// conserves energy looks exactly 1: a hair fiber (Chiang, sigma_a = 0), a dielectric fiber
/// without absorption (refraction, internal reflection, caps), a diffuse sphere of albedo 1.
/// These pass only if next-event estimation, BSDF sampling and their MIS weights agree.
#[test]
fn white_furnaces_are_white() {
    let materials = [
        "type = \"hair\"\nsigma_a = 0\nbeta_m = 0.3\nbeta_n = 0.3",
        "type = \"hair\"\nsigma_a = 0\nbeta_m = 0.1\nbeta_n = 0.8\nalpha = 3",
        "type = \"dielectric\"\neta = 1.55",
        "type = \"diffuse\"\nalbedo = 1",
    ];
    for m in materials {
        // Hair shades fibers only: no sphere in its furnace.
        let sphere = if m.contains("hair") {
            ""
        } else {
            "[[sphere]]\ncenter = [0, 3, 0]\nradius = 1\nmaterial = \"m\"\n"
        };
        let src = format!(
            "[[strand]]\npoints = [[-2, 0, 0], [-0.5, 0.2, 0.1], [0.5, -0.1, 0], [2, 0, 0.2]]\nradius = [0.3, 0.2]\nellipticity = 0.7\nmaterial = \"m\"\n\
             {sphere}\
             [material.m]\n{m}\n[environment]\ncolor = 1\n\
             [camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n"
        );
        let (w, cam) = world(&src);
        for integ in [Integrator::Path, Integrator::Direct] {
            let s = settings(integ, 1);
            // Direct lighting counts one non-specular bounce: exactly 1 for the far-field hair
            // and the convex sphere, not for a diffuse strand that shadows itself at its bends.
            let fiber = DVec3::new(0.05, 0.0, 0.0);
            let ball = DVec3::new(0.0, 3.2, 0.0);
            let targets: &[DVec3] = match (integ, sphere.is_empty(), m.contains("diffuse")) {
                (_, true, _) => &[fiber],
                (Integrator::Direct, false, true) => &[ball],
                _ => &[fiber, ball],
            };
            for &target in targets {
                let ray = Ray::new(
                    DVec3::new(0.1, 0.1, 5.0),
                    target - DVec3::new(0.1, 0.1, 5.0),
                );
                let (mean, se) = mean_radiance(&w, &cam, &s, ray, 4_000);
                let want = 1.0;
                assert!(
                    (mean - want).abs() < 4.0 * se + 2e-3,
                    "{integ:?} {m:?} toward {target}: {mean} +- {se}"
                );
            }
        }
    }
}

/// A fiber under a directional light is dark exactly where a black plane blocks the light and
/// lit where nothing does, for a BSDF evaluated after the shadow ray (hair's) and one
/// evaluated before it (diffuse), by both integrators.
#[test]
fn blocked_light_leaves_fibers_dark() {
    for m in [
        "type = \"hair\"\nsigma_a = 0.2",
        "type = \"diffuse\"\nalbedo = 0.8",
    ] {
        for blocked in [false, true] {
            let plane = if blocked {
                "[[plane]]\npoint = [0, 1, 0]\nnormal = [0, 1, 0]\nmaterial = \"black\"\n"
            } else {
                ""
            };
            let src = format!(
                "[[cylinder]]\nbezier = [[-2, 0, 0], [-1, 0, 0], [1, 0, 0], [2, 0, 0]]\nmajor_radius = [0.2, 0.2]\nmaterial = \"m\"\n\
                 {plane}\
                 [material.m]\n{m}\n[material.black]\ntype = \"diffuse\"\nalbedo = 0\n\
                 [[light]]\ntype = \"directional\"\ndirection = [0.3, -1, -0.2]\nirradiance = 2\n\
                 [camera]\nposition = [0, 0.5, 5]\nlook_at = [0, 0, 0]\n"
            );
            let (w, cam) = world(&src);
            let ray = Ray::new(DVec3::new(0.0, 0.5, 5.0), DVec3::new(0.0, -0.4, -5.0));
            for integ in [Integrator::Direct, Integrator::Path] {
                let (mean, _) = mean_radiance(&w, &cam, &settings(integ, 1), ray, 500);
                if blocked {
                    assert_eq!(mean, 0.0, "{m:?} {integ:?}: light through the plane");
                } else {
                    assert!(mean > 1e-2, "{m:?} {integ:?}: unlit, {mean}");
                }
            }
        }
    }
}

/// Beer-Lambert through a dielectric fiber, along the ray through its axis at normal
/// incidence (the path stays on that line): with Fresnel reflectance `F` and `a = sigma_a 2r`,
/// the radiance from a furnace of 1 is `F + (1 - F)^2 e^-a / (1 - F e^-a)`; index-matched
/// (`eta = 1`, `F = 0`) it is `e^-a` exactly.
#[test]
fn beer_lambert_through_a_fiber() {
    let r = 0.2;
    for (eta, sigma) in [(1.0, 1.5), (1.55, 1.5), (1.55, 0.0), (1.33, 4.0)] {
        let src = format!(
            "[[cylinder]]\nbezier = [[-2, 0, 0], [-1, 0, 0], [1, 0, 0], [2, 0, 0]]\nmajor_radius = [{r}, {r}]\nmaterial = \"glass\"\n\
             [material.glass]\ntype = \"dielectric\"\neta = {eta}\nsigma_a = {sigma}\n\
             [environment]\ncolor = 1\n[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n"
        );
        let (w, cam) = world(&src);
        let f = gencyl_render::optics::material::fresnel_dielectric(1.0, eta);
        let a: f64 = sigma * 2.0 * r;
        let want = f + (1.0 - f).powi(2) * (-a).exp() / (1.0 - f * (-a).exp());
        let ray = Ray::new(DVec3::new(0.3, 0.0, 5.0), -DVec3::Z);
        let (mean, se) = mean_radiance(&w, &cam, &settings(Integrator::Path, 1), ray, 20_000);
        assert!(
            (mean - want).abs() < 4.0 * se + 1e-9,
            "eta {eta}, sigma {sigma}: {mean} +- {se}, want {want}"
        );
    }
}

/// A diffuse plane under a spherical light: the radiance toward the camera is
/// `albedo / pi * E` with `E = pi L r^2 / d^2` right below the light, by both integrators.
#[test]
fn sphere_light_falloff() {
    let src = "[[plane]]\npoint = [0, 0, 0]\nnormal = [0, 1, 0]\nmaterial = \"white\"\n\
               [material.white]\ntype = \"diffuse\"\nalbedo = 0.8\n\
               [[light]]\ntype = \"sphere\"\ncenter = [0, 4, 0]\nradius = 0.5\nradiance = 10\n\
               [camera]\nposition = [0, 1, 3]\nlook_at = [0, 0, 0]\n";
    let (w, cam) = world(src);
    let want = 0.8 / std::f64::consts::PI * std::f64::consts::PI * 10.0 * 0.25 / 16.0;
    for integ in [Integrator::Direct, Integrator::Path] {
        let ray = Ray::new(DVec3::new(0.0, 1.0, 3.0), DVec3::new(0.0, -1.0, -3.0));
        let (mean, se) = mean_radiance(&w, &cam, &settings(integ, 1), ray, 20_000);
        assert!(
            (mean - want).abs() < 4.0 * se + 1e-3 * want,
            "{integ:?}: {mean} +- {se}, want {want}"
        );
    }
}

/// A small copy of the built-in scene.
fn small_default() -> (World, Camera, RenderSettings) {
    let d = gencyl_render::scenes::builtin::default_scene();
    let mut cam = d.camera.unwrap();
    cam.width = 32;
    cam.height = 24;
    let s = RenderSettings {
        integrator: Integrator::Path,
        spp: 1,
        max_depth: 4,
        seed: 3,
    };
    (World::new(d), cam, s)
}

/// The same image whatever the thread count, and windows merged back equal the whole frame,
/// bit for bit (through EXR files, as a render farm would pass them).
#[test]
fn threads_and_crop_windows_give_identical_pixels() {
    let (w, cam, s) = small_default();
    let run = |n: usize, win: Window| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .unwrap()
            .install(|| integrator::render(&w, &cam, &s, win, &|_| {}).film)
    };
    let whole = Window::full(cam.width, cam.height);
    let one = run(1, whole);
    let two = run(2, whole);
    let bits = |f: &Film| f.data.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&one), bits(&two), "1 thread vs 2 threads");
    assert!(
        one.data.iter().all(|x| x.is_finite()),
        "no NaN or infinity in a path-traced film"
    );
    let lit = one.data.chunks(4).filter(|p| p[3] > 0.0).count();
    assert!(lit > 20, "the fibers and floor are in view: {lit} pixels");

    let dir = std::env::temp_dir().join(format!("gencyl-crop-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let windows = [
        Window::new(0, 0, 32, 7),
        Window::new(0, 7, 13, 24),
        Window::new(13, 7, 32, 24),
    ];
    let parts: Vec<Film> = windows
        .iter()
        .enumerate()
        .map(|(i, &win)| {
            let path = dir.join(format!("part{i}.exr"));
            run(2, win).write(&path).unwrap();
            Film::read_exr(&path).unwrap()
        })
        .collect();
    let merged = Film::merge(&parts).unwrap();
    let path = dir.join("whole.exr");
    one.write(&path).unwrap();
    let whole_read = Film::read_exr(&path).unwrap();
    assert_eq!(
        bits(&merged),
        bits(&whole_read),
        "merged windows vs whole frame"
    );
    assert_eq!(merged.channels, whole_read.channels, "channels");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Every example scene under `examples/` loads (the ponytail's hair file included).
#[test]
fn example_scenes_load() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let p = entry.unwrap().path();
        if p.extension().is_some_and(|e| e == "toml") {
            let d = SceneDescription::load(&p).unwrap_or_else(|e| panic!("{e}"));
            assert!(!d.cylinders.is_empty(), "{} has fibers", p.display());
            n += 1;
        }
    }
    assert!(n >= 4, "the example scenes: {n}");
}

/// A sample that is not finite is never written: an environment of NaN makes every sample
/// NaN; each is counted, and the pixels are 0 (no finite samples), not NaN.
#[test]
fn non_finite_samples_are_dropped_and_counted() {
    let cam = "type = \"orthographic\"\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\nview_height = 1.0\nresolution = [8, 6]";
    let (mut w, cam) = world(&straight_fiber(0.1, 0.1, cam));
    w.environment = Some(gencyl_render::optics::Environment::Constant(DVec3::NAN));
    w.lights.clear();
    let s = settings(Integrator::Path, 3);
    let r = integrator::render(&w, &cam, &s, Window::full(cam.width, cam.height), &|_| {});
    assert!(r.film.data.iter().all(|x| x.is_finite()), "no NaN written");
    // Rays that miss see the NaN sky; rays that hit the fiber gather it too (path tracing).
    assert!(
        r.non_finite_samples > 0 && r.non_finite_samples <= 8 * 6 * 3,
        "{}",
        r.non_finite_samples
    );
    let (_, dropped) = integrator::pixel(&w, &cam.rays(), &s, 0, 0, &mut Buffers::default());
    assert_eq!(dropped, 3, "a corner pixel sees only sky");
}
