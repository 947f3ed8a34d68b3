//! Timing of one exact ray-fiber test, per method, on four fibers: a round curved fiber, an
//! elliptical fiber (major/minor radius 0.03/0.015) twisted by a full turn on a curly 3D
//! Bezier, the same fiber untwisted, and untwisted with the projection frame strands use
//! (`ellipse-projected`) instead of Frenet's. A fixed seeded set of rays passes within 3.2 radii of
//! the axis; a little over half of them hit.
//!
//! `cargo run --release -p gencyl --example intersect_timing [rays]` (default 2000 rays; the
//! general method gets a tenth of them). `TIMING_CASE=ellipse-twist TIMING_METHOD=Radial` limit
//! the run to one case and method, say to count instructions under
//! `valgrind --tool=callgrind`, which is repeatable where wall-clock time on a shared machine is
//! not.

use std::hint::black_box;
use std::time::Instant;

use gencyl::{CubicBezier, FiberSpec, Framing, GeneralizedCylinder, Method, Ray, Section};
use glam::DVec3;

/// A small deterministic generator (splitmix64).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.next()
    }
    fn unit(&mut self) -> DVec3 {
        loop {
            let v = DVec3::new(
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
            );
            let l = v.length();
            if l > 0.1 && l <= 1.0 {
                return v / l;
            }
        }
    }
}

const CURLY: [DVec3; 4] = [
    DVec3::new(0.0, 0.0, 0.0),
    DVec3::new(0.35, 0.45, 0.1),
    DVec3::new(0.75, 0.05, 0.55),
    DVec3::new(1.05, 0.45, 0.35),
];

fn elliptical(rotation: [f64; 2]) -> FiberSpec {
    FiberSpec {
        bezier: CURLY,
        major_radius: [0.03, 0.03],
        minor_radius: [0.015, 0.015],
        rotation,
        caps: true,
        normal_hint: None,
        section: Section::default(),
    }
}

/// Rays through a random point within `3.2 r` of a random axis point, random direction.
fn rays(cyl: &GeneralizedCylinder, r: f64, n: usize, seed: u64) -> Vec<Ray> {
    let mut rng = Rng(seed);
    let axis = cyl.axis();
    (0..n)
        .map(|_| {
            let u = rng.range(-0.02, 1.02);
            let target = axis.point(u) + rng.unit() * rng.range(0.0, 3.2 * r);
            let dir = rng.unit();
            Ray::new(target - 3.0 * dir, dir)
        })
        .collect()
}

fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(2000);
    let cases = [
        ("round", FiberSpec::round(CURLY, 0.03), 0.03),
        (
            "ellipse-twist",
            elliptical([0.0, std::f64::consts::TAU]),
            0.03,
        ),
        ("ellipse", elliptical([0.0, 0.0]), 0.03),
        ("ellipse-projected", elliptical([0.0, 0.0]), 0.03),
    ];
    let mut hits = Vec::new();
    let only_case = std::env::var("TIMING_CASE").ok();
    let only_method = std::env::var("TIMING_METHOD").ok();
    for (name, spec, r) in cases {
        if only_case.as_deref().is_some_and(|c| c != name) {
            continue;
        }
        let cyl = if name == "ellipse-projected" {
            let framing = Framing::projected_for_axis(&CubicBezier::new(CURLY), &[])
                .expect("a projection reference");
            spec.build_framed(framing)
        } else {
            spec.build()
        }
        .expect("valid fiber");
        let rays = rays(&cyl, r, n, 7);
        for method in [Method::Auto, Method::Round, Method::Radial, Method::General] {
            if method == Method::Round && name != "round" {
                continue;
            }
            if only_method
                .as_deref()
                .is_some_and(|m| m != format!("{method:?}"))
            {
                continue;
            }
            let count = if method == Method::General { n / 10 } else { n };
            let mut hit_rays = 0;
            let mut total_hits = 0;
            let start = Instant::now();
            for ray in &rays[..count] {
                hits.clear();
                cyl.intersect_all_with(black_box(ray), 0.0, f64::INFINITY, method, &mut hits);
                hit_rays += usize::from(!hits.is_empty());
                total_hits += hits.len();
            }
            let us = start.elapsed().as_secs_f64() * 1e6 / count as f64;
            println!(
                "{name:>14} {:>11} {us:10.2} us/test  ({hit_rays}/{count} rays hit, {total_hits} hits)",
                format!("{method:?}")
            );
        }
    }
}
