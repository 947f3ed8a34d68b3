//! scratch
use gencyl::*;
use glam::DVec3;
fn main() {
    let v3 = DVec3::new;
    let mut rng = 7u64;
    let mut r = move || {
        rng = rng
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (rng >> 11) as f64 / (1u64 << 53) as f64
    };
    let straight = [0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0].map(|s| v3(s * 2.0, 0.0, 0.0));
    let curved = [
        v3(0.0, 0.0, 0.0),
        v3(0.2, 0.5, -0.2),
        v3(0.8, 0.6, 0.3),
        v3(0.9, 0.1, 0.6),
    ];
    for (name, bez, major, minor, rot) in [
        ("cone", straight, [0.3, 0.1], [0.3, 0.1], [0.0, 0.0]),
        ("ellcyl", straight, [0.2, 0.2], [0.07, 0.07], [0.0, 0.0]),
        ("round", curved, [0.06, 0.06], [0.06, 0.06], [0.0, 0.0]),
        (
            "ellipse-twist",
            curved,
            [0.06, 0.08],
            [0.03, 0.02],
            [1.0, -2.0],
        ),
    ] {
        let spec = FiberSpec {
            bezier: bez,
            major_radius: major,
            minor_radius: minor,
            rotation: rot,
            caps: false,
            normal_hint: None,
            section: Section::default(),
        };
        let c = spec.build().unwrap();
        let rays: Vec<Ray> = (0..300)
            .map(|_| {
                let tgt = c.axis().point(r()) + v3(r() - 0.5, r() - 0.5, r() - 0.5) * 0.3;
                let o = tgt + v3(r() - 0.5, r() - 0.5, r() - 0.5).normalize() * 3.0;
                Ray::new(o, tgt - o)
            })
            .collect();
        for m in [Method::Polynomial, Method::Radial, Method::General] {
            let t = std::time::Instant::now();
            let mut n = 0;
            let mut worst = 0.0f64;
            for ray in &rays {
                let t1 = std::time::Instant::now();
                let mut out = Vec::new();
                c.intersect_all_with(ray, 0.0, f64::INFINITY, m, &mut out);
                n += out.len();
                worst = worst.max(t1.elapsed().as_secs_f64());
            }
            println!(
                "{name} {m:?}: {} hits, {:.1} us/ray, worst {:.1} ms",
                n,
                t.elapsed().as_secs_f64() * 1e6 / rays.len() as f64,
                worst * 1e3
            );
        }
    }
}
