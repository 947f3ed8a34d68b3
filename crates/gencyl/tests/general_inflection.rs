//! The general method on the trilobal fiber of `examples/xray.toml`, whose axis is a planar
//! S-curve with an inflection at `u = 1/2`, and on the same fiber with the axis bent slightly out
//! of its plane.
//!
//! * Bent by `dx` (`1e-5` down to `1e-8`): the axis has no inflection, the swept surface is
//!   closed and smooth, so every ray from outside crosses it an even number of times. But the
//!   Frenet frame turns half round within about `dx` of `u = 1/2`, and `phi(u)` with it, at up
//!   to `1e7` per unit of `u`: it passes several tangent directions within a cell of the
//!   general path's former 64-cell feature sampling (so pieces it took for monotone were not,
//!   and their end-point boxes pruned pairs holding roots), and pieces narrower than `1e-6` in
//!   `u` passed the seed's linearity test however much they bent. Before the fix 0, 36, 104
//!   and 122 of the 3602 rays here (for `dx = 1e-5 ... 1e-8`) got an odd number of hits.
//! * Planar: the frame jumps by half a turn at the inflection (interface.md 1: the limit from
//!   either side), so the trilobal surface has a seam: the normal plane at `u = 1/2` bounds the
//!   solid where one limiting section covers it and the other does not. A ray through that part
//!   of the plane meets only one side-surface sheet there: the reported rays' "missing" hits.
//!   The library reports those seam crossings as `Part::Seam` hits (checked here against the two
//!   limiting frames), so every ray crosses an even number of times. (Before the fix three rays still had an odd count: side
//!   hits next to the seam were missed.)

use gencyl::{
    BezierLoop, CrossSection, FiberSpec, GeneralizedCylinder, Hit, Method, Part, Ray, Section,
};
use glam::{DVec2, DVec3};

/// `examples/xray.toml`'s trilobal fiber, the axis' second control point moved by `dx` along x.
fn xray_fiber(dx: f64) -> GeneralizedCylinder {
    let profile: Vec<DVec2> = [
        [1.0, 0.0],
        [1.0, 0.35],
        [0.55, 0.55],
        [-0.5, 0.87],
        [-0.45, 0.45],
        [-0.5, 0.0],
        [-0.5, -0.87],
        [0.1, -0.75],
        [0.55, -0.55],
    ]
    .map(DVec2::from_array)
    .to_vec();
    FiberSpec {
        bezier: [
            DVec3::new(-0.3, -1.1, 0.5),
            DVec3::new(-0.1 + dx, -0.4, 0.6),
            DVec3::new(0.1, 0.4, 0.4),
            DVec3::new(0.3, 1.1, 0.5),
        ],
        major_radius: [0.13, 0.13],
        minor_radius: [0.13, 0.13],
        rotation: [0.0, 2.0],
        caps: true,
        normal_hint: None,
        section: Section::Loop(BezierLoop::new(&profile).unwrap()),
    }
    .build()
    .unwrap()
}

/// The two rays of the report, then an `nx` x `ny` grid of rays along -z over
/// `x in [-0.16, 0.04]`, `y in [-0.05, 0.05]`: the middle of the fiber, `u` near 1/2.
fn rays(nx: usize, ny: usize) -> Vec<Ray> {
    let d = DVec3::new(0.0, 0.0, -1.0);
    let mut origins = vec![
        DVec3::new(-0.10333333333333333, 0.023333333333333383, 10.0),
        DVec3::new(-0.09666666666666668, 0.030000000000000027, 10.0),
    ];
    for i in 0..nx {
        for j in 0..ny {
            let x = -0.16 + 0.2 * i as f64 / (nx - 1) as f64;
            let y = -0.05 + 0.1 * j as f64 / (ny - 1) as f64;
            origins.push(DVec3::new(x, y, 10.0));
        }
    }
    origins.into_iter().map(|o| Ray::new(o, d)).collect()
}

fn general_hits(cyl: &GeneralizedCylinder, ray: &Ray) -> Vec<Hit> {
    let mut hits = Vec::new();
    cyl.intersect_all_with(ray, 0.0, f64::INFINITY, Method::General, &mut hits);
    hits
}

/// The hit lies on the surface at its `(u, v)` (to `1e-9`, or to what `Gamma` moves over a few
/// ulps of `u` and `v`: `|dGamma/du|` reaches `1e7` where the frame turns fast), and its normal
/// is the outward normal `orientation * (dGamma/dv x dGamma/du)` by central differences with
/// steps small enough to follow the frame's half turn.
fn check_hit(cyl: &GeneralizedCylinder, ray: &Ray, h: &Hit, what: &str) {
    let (hu, hv) = (1e-11, 1e-7);
    let gu = (cyl.surface_point(h.u + hu, h.v) - cyl.surface_point(h.u - hu, h.v)) / (2.0 * hu);
    let gv = (cyl.surface_point(h.u, h.v + hv) - cyl.surface_point(h.u, h.v - hv)) / (2.0 * hv);
    let ulps = 4.0 * f64::EPSILON * (gu.length() * h.u + gv.length() * h.v);
    let p = cyl.surface_point(h.u, h.v);
    assert!(
        (p - h.point).length() <= 1e-9 + ulps,
        "{what}: hit {h:?} is {:e} off Gamma(u, v), ray {ray:?}",
        (p - h.point).length()
    );
    let fd = (cyl.section().orientation() * gv.cross(gu)).normalize();
    assert!(
        (fd - h.normal).length() <= 1e-3,
        "{what}: normal {:?} vs finite differences {fd:?}, hit {h:?}, ray {ray:?}",
        h.normal
    );
}

/// Bent axes: an even number of hits on every ray (none starts inside; tangencies would need
/// a ray through a fold of the surface, and there is none on this grid), each hit on the
/// surface with the right normal.
#[test]
fn nearly_planar_inflection_gives_even_crossings() {
    let rays = rays(60, 60);
    let mut report = Vec::new();
    for dx in [1e-5, 1e-6, 1e-7, 1e-8] {
        let cyl = xray_fiber(dx);
        let mut odd = Vec::new();
        let mut twist_hits = 0;
        for ray in &rays {
            let hits = general_hits(&cyl, ray);
            for h in &hits {
                check_hit(&cyl, ray, h, &format!("dx {dx:e}"));
                twist_hits += usize::from((h.u - 0.5).abs() <= 1e3 * dx);
            }
            if hits.len() % 2 == 1 {
                odd.push(format!(
                    "  ray {:?}: (t, u) {:?}",
                    ray.origin,
                    hits.iter().map(|h| (h.t, h.u)).collect::<Vec<_>>()
                ));
            }
        }
        // The grid does cross the stretch where the frame turns.
        if twist_hits < 100 {
            report.push(format!("dx {dx:e}: only {twist_hits} hits near u = 1/2"));
        }
        if !odd.is_empty() {
            report.push(format!(
                "dx {dx:e}: {} of {} rays with an odd number of hits:\n{}",
                odd.len(),
                rays.len(),
                odd[..odd.len().min(5)].join("\n")
            ));
        }
    }
    assert!(report.is_empty(), "{}", report.join("\n"));
}

/// Whether the ray crosses the seam of the planar fiber: it meets the normal plane at the
/// inflection in a point inside exactly one of the two limiting sections (the hair rule's
/// inverse and the loop's inside test, with the frames just either side of `u = 1/2`).
fn crosses_seam(cyl: &GeneralizedCylinder, ray: &Ray) -> bool {
    let (u, h) = (0.5, 1e-6);
    let a = cyl.axis().point(u);
    let t = cyl.frame(u).t;
    let w = t.dot(a - ray.origin) / t.dot(ray.dir);
    let e = ray.at(w) - a;
    let inside = |us: f64| {
        let f = cyl.frame(us);
        let (rho, theta) = (DVec2::new(f.n.dot(e), f.b.dot(e)), 2.0 * u);
        let (s, c) = theta.sin_cos();
        let q = DVec2::new(c * rho.x + s * rho.y, -s * rho.x + c * rho.y) / 0.13;
        cyl.section().contains(q)
    };
    inside(u - h) != inside(u + h)
}

/// The reported fiber: its frame flips at the inflection (the two limiting binormals are
/// opposite), the general method reports the seam crossings itself ([`Part::Seam`], normal
/// `+-t`, in the normal plane at the inflection) exactly where the independent test above finds
/// them, every ray has an even number of hits, and the two reported rays each have one side hit
/// and one seam hit.
#[test]
fn planar_inflection_parity_counts_the_seam() {
    let cyl = xray_fiber(0.0);
    let (b0, b1) = (cyl.frame(0.5 - 1e-6).b, cyl.frame(0.5 + 1e-6).b);
    assert!(b0.dot(b1) < -0.999, "the binormal flips: {b0:?} {b1:?}");
    let rays = rays(60, 60);
    let mut odd = Vec::new();
    let mut seams = 0;
    for (k, ray) in rays.iter().enumerate() {
        let hits = general_hits(&cyl, ray);
        let mut seam_hits = 0;
        for h in &hits {
            if h.part == Part::Seam {
                seam_hits += 1;
                // At the switch of the frame, within the stretch (1e-9 wide) around the
                // inflection where the Frenet frame is taken from its limit.
                assert!((h.u - 0.5).abs() < 1e-9, "seam at the inflection: {h:?}");
                let (a, t) = (cyl.axis().point(h.u), cyl.frame(h.u).t);
                assert!(
                    (h.point - a).dot(t).abs() < 1e-12,
                    "in the normal plane: {h:?}"
                );
                assert!(h.normal.cross(t).length() < 1e-12, "normal +-t: {h:?}");
            } else {
                check_hit(&cyl, ray, h, "planar");
            }
        }
        let seam = crosses_seam(&cyl, ray);
        seams += usize::from(seam);
        assert_eq!(
            seam_hits,
            usize::from(seam),
            "ray {ray:?}: seam hits vs the seam test: {hits:?}"
        );
        if k < 2 {
            assert!(
                hits.len() == 2 && seam,
                "reported ray {k}: one side hit and the seam: {hits:?}, seam {seam}"
            );
        }
        if hits.len() % 2 == 1 {
            odd.push(format!(
                "  ray {:?}: seam {seam}, (t, u) {:?}",
                ray.origin,
                hits.iter().map(|h| (h.t, h.u)).collect::<Vec<_>>()
            ));
        }
    }
    assert!(seams > 50, "{seams} rays cross the seam");
    assert!(
        odd.is_empty(),
        "{} of {} rays with an odd count:\n{}",
        odd.len(),
        rays.len(),
        odd[..odd.len().min(5)].join("\n")
    );
}
