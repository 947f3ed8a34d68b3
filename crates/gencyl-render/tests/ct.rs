//! The CT projector against closed forms: chords of a straight elliptical fiber (a conic
//! section in the plane across it) and of a sphere, through every sub-pixel ray written out
//! here from ASTRA's pixel convention, for parallel and cone beams at several angles; and
//! Beer-Lambert, mono- and polychromatic, on those chords.

use gencyl_render::optics::scanner::{CtSetup, Quantity, View};
use gencyl_render::scene_file::SceneDescription;
use gencyl_render::transport::World;
use gencyl_render::transport::ct::Projector;
use glam::{DVec2, DVec3};

/// The fiber: along z from -H to H, major radius A along the direction `PSI` from x toward y
/// (the straight axis' normal is `normal_hint = x`), minor radius B.
const A: f64 = 0.3;
const B: f64 = 0.17;
const PSI: f64 = 0.7;
const H: f64 = 50.0;

fn fiber_scene(ct: &str, extra: &str) -> (World, CtSetup) {
    let src = format!(
        "[material.glass]\ntype = \"dielectric\"\nxray_mu = 2.0\n\
         [[cylinder]]\nbezier = [[0, 0, {lo}], [0, 0, {a}], [0, 0, {b}], [0, 0, {hi}]]\n\
         major_radius = [{A}, {A}]\nminor_radius = [{B}, {B}]\nrotation = [{PSI}, {PSI}]\n\
         normal_hint = [1, 0, 0]\nmaterial = \"glass\"\n{extra}\n[ct]\n{ct}",
        lo = -H,
        a = -H / 3.0,
        b = H / 3.0,
        hi = H,
    );
    let desc = SceneDescription::parse(&src, "ct.toml").unwrap();
    let setup = desc.ct.clone().unwrap();
    (World::new(desc), setup)
}

/// The chord of the ellipse `x^2/A^2 + y^2/B^2 = 1` (turned by `PSI`) cut by the line
/// `p + t d` across z, in 3D length: the roots of `alpha t^2 + beta t + gamma = 0` are where
/// the line's xy shadow crosses the ellipse, `|t1 - t0| = sqrt(disc) / alpha` times `|d|`.
fn ellipse_chord(p: DVec3, d: DVec3) -> f64 {
    // From the line's point nearest the axis (in xy), so that the quadratic's terms are of
    // the ellipse's size and its discriminant does not cancel.
    let p = p - p.truncate().dot(d.truncate()) / d.truncate().length_squared() * d;
    let turn = DVec2::from_angle(-PSI);
    let q = turn.rotate(p.truncate());
    let e = turn.rotate(d.truncate());
    let alpha = e.x * e.x / (A * A) + e.y * e.y / (B * B);
    let beta = 2.0 * (q.x * e.x / (A * A) + q.y * e.y / (B * B));
    let gamma = q.x * q.x / (A * A) + q.y * q.y / (B * B) - 1.0;
    let disc = beta * beta - 4.0 * alpha * gamma;
    if disc <= 0.0 {
        0.0
    } else {
        disc.sqrt() / alpha * d.length()
    }
}

/// The sub-pixel sample points and ray directions of a pixel, from the view's 12 numbers:
/// `d + (c - C/2 + (i + 1/2)/k) u + (r - R/2 + (j + 1/2)/k) v`.
fn pixel_rays(
    view: &View,
    cone: bool,
    size: (u32, u32),
    pixel: (u32, u32),
    k: u32,
) -> Vec<(DVec3, DVec3)> {
    let (columns, rows) = size;
    let (r, c) = pixel;
    let mut rays = Vec::new();
    for j in 0..k {
        for i in 0..k {
            let fu = c as f64 - columns as f64 / 2.0 + (i as f64 + 0.5) / k as f64;
            let fv = r as f64 - rows as f64 / 2.0 + (j as f64 + 0.5) / k as f64;
            let point = view.detector + fu * view.u + fv * view.v;
            let dir = if cone {
                (point - view.source).normalize()
            } else {
                view.source.normalize()
            };
            rays.push((point, dir));
        }
    }
    rays
}

fn project(world: &World, setup: &CtSetup, view: usize) -> Vec<f32> {
    let s = &setup.scanner;
    let mut out = vec![0.0; (s.columns * s.rows) as usize];
    Projector::new(world, setup).project(view, &mut out);
    out
}

/// Every pixel of every view against the mean of its rays' closed-form chords.
fn check_chords(ct: &str, cone: bool, chord: impl Fn(DVec3, DVec3) -> f64) -> usize {
    let (world, setup) = fiber_scene(ct, "");
    let s = &setup.scanner;
    let mut hit = 0;
    for (k, view) in s.views.iter().enumerate() {
        let got = project(&world, &setup, k);
        for r in 0..s.rows {
            for c in 0..s.columns {
                let rays = pixel_rays(view, cone, (s.columns, s.rows), (r, c), s.samples_per_side);
                let want: f64 =
                    rays.iter().map(|&(p, d)| chord(p, d)).sum::<f64>() / rays.len() as f64;
                let g = got[(r * s.columns + c) as usize] as f64;
                // f32 output: half an ulp of f32 relative, on the fiber's scale.
                assert!(
                    (g - want).abs() <= 1e-7 * want + 1e-12 * A,
                    "view {k} pixel ({r}, {c}): {g} vs {want}"
                );
                hit += usize::from(want > 0.0);
            }
        }
    }
    hit
}

#[test]
fn parallel_projections_are_the_ellipse_chords() {
    // 13 views over 180 degrees, a detector wider than the fiber, 3 x 3 rays per pixel.
    let ct = "beam = \"parallel\"\ndetector = [17, 3]\npixel = [0.05, 0.4]\nviews = 13\n\
              arc = 180\nstart_angle = 7\nsamples = 9\nquantity = \"length\"\n";
    let hits = check_chords(ct, false, ellipse_chord);
    assert!(hits > 13 * 3 * 8, "most pixels see the fiber: {hits}");
}

#[test]
fn cone_projections_are_the_ellipse_chords() {
    // Source 4 from the axis, detector 2 beyond it: rays tilt by up to atan(0.6 / 6) along z,
    // far from the caps at z = +-50.
    let ct = "beam = \"cone\"\ndetector = [21, 5]\npixel = [0.06, 0.3]\nviews = 11\n\
              arc = 360\nsource_distance = 4\ndetector_distance = 2\nsamples = 4\n\
              quantity = \"length\"\n";
    let hits = check_chords(ct, true, ellipse_chord);
    assert!(hits > 11 * 5 * 8, "most pixels see the fiber: {hits}");
}

/// The chords are exact in f64 before the f32 output: one ray per pixel, compared in f64
/// through `material_lengths`, to 1e-12 relative.
#[test]
fn ray_lengths_are_the_chords_to_1e_12() {
    use gencyl_render::transport::ct::material_lengths;
    let ct = "beam = \"cone\"\ndetector = [41, 7]\npixel = [0.03, 0.2]\nviews = 7\narc = 180\n\
              source_distance = 5\ndetector_distance = 3\n";
    let (world, setup) = fiber_scene(ct, "");
    let s = &setup.scanner;
    let mut buf = Default::default();
    let mut lengths = vec![0.0; world.materials.len()];
    let mut worst: f64 = 0.0;
    for view in &s.views {
        for r in 0..s.rows {
            for c in 0..s.columns {
                let ray = s.ray(view, r, c, 0);
                let (p, d) = pixel_rays(view, true, (s.columns, s.rows), (r, c), 1)[0];
                assert!((ray.dir - d).length() < 1e-15 && ray.origin == view.source);
                let want = ellipse_chord(p, d);
                material_lengths(&world, &ray, &mut buf, &mut lengths);
                let got: f64 = lengths.iter().sum();
                // A chord's error from the line's own rounding (`e ~ 1e-16 |o|` across it)
                // is `e |dc/ds| ~ e 4 A / c` for a chord `c` at offset `s`: relative
                // `4 A e / c^2`, above 1e-12 for the grazing chords shorter than
                // `sqrt(4 A e / 1e-12)`, about 0.08 A here. Those are held to that bound.
                let e = 1e-16 * 5.0;
                let conditioned = 4.0 * A * e / (want * want);
                if want == 0.0 {
                    // A miss, or a touch: a tangent line's chord is at most `sqrt(8 A e)`.
                    assert!(got <= (80.0 * A * e).sqrt(), "{got} for a miss");
                } else if conditioned < 1e-13 {
                    worst = worst.max((got - want).abs() / want);
                } else {
                    assert!(
                        (got - want).abs() <= 10.0 * conditioned * want + 1e-12,
                        "{got} vs {want}"
                    );
                }
            }
        }
    }
    assert!(worst < 1e-12, "worst relative error {worst:e}");
}

#[test]
fn sphere_projections_are_its_chords() {
    let sphere = "[material.bone]\ntype = \"diffuse\"\n\
                  [[sphere]]\ncenter = [0.1, -0.2, 3]\nradius = 0.8\nmaterial = \"bone\"\n";
    for (beam, extra) in [
        ("parallel", ""),
        ("cone", "source_distance = 6\ndetector_distance = 2\n"),
    ] {
        let ct = format!(
            "beam = \"{beam}\"\ndetector = [15, 15]\npixel = [0.15, 0.15]\nviews = 5\n\
             center = [0, 0, 3]\nsamples = 4\nquantity = \"length\"\nmaterial = \"bone\"\n{extra}"
        );
        // The fiber crosses the sphere's rays too: `material` keeps the sphere's lengths.
        let (world, setup) = fiber_scene(&ct, sphere);
        let s = &setup.scanner;
        let chord = |p: DVec3, d: DVec3| {
            let c = DVec3::new(0.1, -0.2, 3.0);
            let off = (p - c) - (p - c).dot(d) * d;
            let h2 = 0.64 - off.length_squared();
            if h2 > 0.0 { 2.0 * h2.sqrt() } else { 0.0 }
        };
        for (k, view) in s.views.iter().enumerate() {
            let got = project(&world, &setup, k);
            for r in 0..s.rows {
                for c in 0..s.columns {
                    let rays = pixel_rays(view, beam == "cone", (s.columns, s.rows), (r, c), 2);
                    let want = rays.iter().map(|&(p, d)| chord(p, d)).sum::<f64>() / 4.0;
                    let g = got[(r * s.columns + c) as usize] as f64;
                    assert!(
                        (g - want).abs() <= 1e-7 * want + 1e-12,
                        "{beam} view {k} ({r}, {c}): {g} vs {want}"
                    );
                }
            }
        }
    }
}

#[test]
fn beer_lambert_mono_and_polychromatic() {
    let geometry = "beam = \"parallel\"\ndetector = [9, 1]\npixel = [0.08, 0.1]\nviews = 3\n";
    let (world, length) = fiber_scene(&format!("{geometry}quantity = \"length\"\n"), "");
    let (_, absorbance) = fiber_scene(geometry, "");
    let (_, transmission) = fiber_scene(&format!("{geometry}quantity = \"transmission\"\n"), "");
    for k in 0..3 {
        let l = project(&world, &length, k);
        let a = project(&world, &absorbance, k);
        let t = project(&world, &transmission, k);
        for i in 0..9 {
            let want = 2.0 * l[i] as f64;
            assert!(
                (a[i] as f64 - want).abs() <= 1e-6 * want,
                "{} vs {want}",
                a[i]
            );
            let tw = (-want).exp();
            assert!((t[i] as f64 - tw).abs() <= 1e-6 * tw, "{} vs {tw}", t[i]);
        }
    }
    // Three bins; the material's mu per bin. I/I0 = sum_b w_b exp(-mu_b L): beam hardening
    // makes the absorbance less than the mean mu times L.
    let poly = format!("{geometry}spectrum = [[30, 1], [50, 2], [80, 1]]\n");
    let src_mu = "xray_mu = [4.0, 2.0, 0.5]";
    let (world_p, setup_p) = {
        let (_, _) = fiber_scene(&poly, "");
        let src = format!(
            "[material.glass]\ntype = \"dielectric\"\n{src_mu}\n\
             [[cylinder]]\nbezier = [[0, 0, -50], [0, 0, -10], [0, 0, 10], [0, 0, 50]]\n\
             major_radius = [{A}, {A}]\nminor_radius = [{B}, {B}]\nrotation = [{PSI}, {PSI}]\n\
             normal_hint = [1, 0, 0]\nmaterial = \"glass\"\n[ct]\n{poly}"
        );
        let desc = SceneDescription::parse(&src, "poly.toml").unwrap();
        let setup = desc.ct.clone().unwrap();
        (World::new(desc), setup)
    };
    for k in 0..3 {
        let l = project(&world, &length, k);
        let a = project(&world_p, &setup_p, k);
        for i in 0..9 {
            let li = l[i] as f64;
            let want =
                -(0.25 * (-4.0 * li).exp() + 0.5 * (-2.0 * li).exp() + 0.25 * (-0.5 * li).exp())
                    .ln();
            assert!(
                (a[i] as f64 - want).abs() <= 1e-6 * want + 1e-30,
                "{} vs {want}",
                a[i]
            );
            if li > 0.01 {
                assert!(want < 2.125 * li, "beam hardening: {want} < {}", 2.125 * li);
            }
        }
    }
}

#[test]
fn absorbance_stays_finite_where_transmission_underflows() {
    let src = format!(
        "[material.lead]\ntype = \"diffuse\"\nxray_mu = 1e6\n\
         [[cylinder]]\nbezier = [[0, 0, -50], [0, 0, -10], [0, 0, 10], [0, 0, 50]]\n\
         major_radius = [{A}, {A}]\nmaterial = \"lead\"\n\
         [ct]\ndetector = [1, 1]\npixel = [0.01, 0.01]\nviews = 1\nsamples = 4\n"
    );
    let desc = SceneDescription::parse(&src, "lead.toml").unwrap();
    let setup = desc.ct.clone().unwrap();
    let world = World::new(desc);
    let a = project(&world, &setup, 0)[0] as f64;
    // Four rays through the centre of a round fiber of radius A, 0.005 apart: the least
    // attenuated (longest-offset) ray dominates the mean, -ln mean exp(-mu L) ~ mu L_min + ln 4.
    assert!(a.is_finite() && a > 1e5 && a < 1e6 * 2.0 * A, "{a}");
}

#[test]
fn an_opaque_path_reads_opaque() {
    // mu L overflows to infinity: no light, never NaN (nor read as clear).
    let src = format!(
        "[material.lead]\ntype = \"diffuse\"\nxray_mu = 1e308\n\
         [[cylinder]]\nbezier = [[0, 0, -50], [0, 0, -10], [0, 0, 10], [0, 0, 50]]\n\
         major_radius = [{A}, {A}]\nmaterial = \"lead\"\n\
         [ct]\ndetector = [1, 1]\npixel = [0.01, 0.01]\nviews = 1\nquantity = \"transmission\"\n"
    );
    let desc = SceneDescription::parse(&src, "lead.toml").unwrap();
    let setup = desc.ct.clone().unwrap();
    let world = World::new(desc);
    let t = project(&world, &setup, 0)[0];
    assert_eq!(t, 0.0);
    let mut absorbance = setup.clone();
    absorbance.quantity = Quantity::Absorbance;
    let a = project(&world, &absorbance, 0)[0];
    assert!(!a.is_nan() && a > 1e30, "{a}");
}

#[test]
fn ct_table_errors_are_located() {
    let base =
        "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\n";
    let cases = [
        (
            "[ct]\ndetector = [4, 4]\npixel = [1, 1]\n",
            "a rotation series (or give `vectors`) needs `views`",
        ),
        (
            "[ct]\ndetector = [0, 4]\npixel = [1, 1]\nviews = 3\n",
            "detector must be 1 to 65536",
        ),
        (
            "[ct]\ndetector = [4, 4]\npixel = [1, 1]\nviews = 3\nsamples = 5\n",
            "samples must be a square number",
        ),
        (
            "[ct]\ndetector = [4, 4]\npixel = [1, 1]\nviews = 3\nbeam = \"fan\"\n",
            "unknown beam `fan`",
        ),
        (
            "[ct]\ndetector = [4, 4]\npixel = [1, 1]\nviews = 3\nbeam = \"cone\"\n",
            "a cone beam needs `source_distance`",
        ),
        (
            "[ct]\ndetector = [4, 4]\npixel = [1, nan]\nviews = 3\n",
            "pixel[1] must be",
        ),
        (
            "[ct]\ndetector = [4, 4]\npixel = [1, 1]\nviews = 3\nfocal_spot = 0.1\n",
            "`focal_spot` does not apply to a parallel beam",
        ),
        (
            "[ct]\ndetector = [4, 4]\nvectors = [[0,1,0, 0,0,0, 1,0,0, 0,0,1]]\nviews = 3\n",
            "`views` does not apply to a scan given by `vectors`",
        ),
        (
            "[ct]\ndetector = [4, 4]\nvectors = [[0,1,0, 0,0,0, 1,0,0, 2,0,0]]\n",
            "view 0: the detector's u and v must be non-zero and not parallel",
        ),
        (
            "[ct]\ndetector = [4, 4]\nvectors = [[1,0,0, 0,0,0, 1,0,0, 0,0,1]]\n",
            "view 0: the rays run parallel to the detector",
        ),
        (
            "[ct]\ndetector = [4, 4]\npixel = [1, 1]\nviews = 3\nquantity = \"dose\"\n",
            "unknown quantity `dose`",
        ),
        (
            "[ct]\ndetector = [4, 4]\npixel = [1, 1]\nviews = 3\nmaterial = \"fiber\"\n",
            "`material` applies to quantity = \"length\" only",
        ),
        (
            "[ct]\ndetector = [4, 4]\npixel = [1, 1]\nviews = 3\nquantity = \"length\"\nmaterial = \"wool\"\n",
            "unknown material `wool`",
        ),
        (
            "[ct]\ndetector = [4, 4]\npixel = [1, 1]\nviews = 3\nspectrum = [[30, 1], [-1, 2]]\n",
            "spectrum bin 1",
        ),
        (
            "[ct]\ndetector = [4, 4]\npixel = [1, 1]\nviews = 3\nspectrum = [[30, 0]]\n",
            "spectrum weights must not all be zero",
        ),
        (
            "[material.m]\ntype = \"diffuse\"\nxray_mu = [1, 2]\n[ct]\ndetector = [4, 4]\npixel = [1, 1]\nviews = 3\n",
            "xray_mu has 2 values but the scene has no [ct] spectrum",
        ),
        (
            "[material.m]\ntype = \"diffuse\"\nxray_mu = [1, 2]\n[ct]\ndetector = [4, 4]\npixel = [1, 1]\nviews = 3\nspectrum = [[1, 1], [2, 1], [3, 1]]\n",
            "the [ct] spectrum has 3 bins",
        ),
        (
            "[material.m]\ntype = \"diffuse\"\nxray_mu = [1, nan]\n",
            "xray_mu must be",
        ),
    ];
    for (ct, want) in cases {
        let src = format!("{base}{ct}");
        let err = SceneDescription::parse(&src, "s.toml")
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("s.toml:") && err.contains(want),
            "{ct}: {err}"
        );
    }
}

#[test]
fn quantity_defaults_and_names() {
    let (_, setup) = fiber_scene("detector = [2, 2]\npixel = [1, 1]\nviews = 4\n", "");
    assert_eq!(setup.quantity, Quantity::Absorbance);
    assert_eq!(setup.scanner.views.len(), 4);
    // 180 degrees by default for a parallel beam: view 2 is at 90 degrees.
    let d = setup.scanner.views[2].source;
    assert!((d - DVec3::new(1.0, 0.0, 0.0)).length() < 1e-15, "{d}");
}
