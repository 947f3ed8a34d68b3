//! Random streams and the warps that turn uniform numbers into directions.
//!
//! Every sample of a render draws from a [`SampleRng`] keyed by (pixel, sample index, seed), so
//! a pixel's value does not depend on which thread renders it or on the crop window.

use std::f64::consts::{PI, TAU};

use glam::{DVec2, DVec3};

/// SplitMix64 on a key: a uniform `f64` stream in `[0, 1)` per (pixel, sample, seed).
#[derive(Clone, Debug)]
pub struct SampleRng(u64);

impl SampleRng {
    /// The stream of sample `sample` of pixel `(x, y)` (full-image coordinates).
    pub fn new(x: u32, y: u32, sample: u32, seed: u64) -> Self {
        let key = (x as u64) << 40 ^ (y as u64) << 16 ^ sample as u64;
        let mut s = SampleRng(seed.wrapping_mul(0xD1B5_4A32_D192_ED03) ^ key);
        s.next_u64(); // decorrelate neighbouring keys
        s
    }

    /// A stream from a single seed (tests, scene generation).
    pub fn from_seed(seed: u64) -> Self {
        SampleRng(seed ^ 0x853c_49e6_748f_ea9b)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)`.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in `[a, b)`.
    pub fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.uniform()
    }

    /// Uniform in the box `[lo, hi)`.
    pub fn in_box(&mut self, lo: DVec3, hi: DVec3) -> DVec3 {
        DVec3::new(
            self.range(lo.x, hi.x),
            self.range(lo.y, hi.y),
            self.range(lo.z, hi.z),
        )
    }

    /// Uniform on the unit sphere.
    pub fn unit_vector(&mut self) -> DVec3 {
        let z = self.range(-1.0, 1.0);
        let phi = self.range(0.0, std::f64::consts::TAU);
        let s = (1.0 - z * z).sqrt();
        DVec3::new(s * phi.cos(), s * phi.sin(), z)
    }

    /// Two uniform numbers in `[0, 1)`.
    pub fn uniform2(&mut self) -> [f64; 2] {
        [self.uniform(), self.uniform()]
    }
}

/// An orthonormal basis `(x, y, z)` with `z = n` (Duff et al. 2017, branchless).
pub fn basis(n: DVec3) -> (DVec3, DVec3) {
    let sign = 1f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        DVec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// Uniform direction on the unit sphere; density `1 / (4 pi)`.
pub fn uniform_sphere(u: [f64; 2]) -> DVec3 {
    let z = 1.0 - 2.0 * u[0];
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = TAU * u[1];
    DVec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Uniform point of the unit disc (concentric map, Shirley and Chiu 1997).
pub fn concentric_disc(u: [f64; 2]) -> DVec2 {
    let (a, b) = (2.0 * u[0] - 1.0, 2.0 * u[1] - 1.0);
    if a == 0.0 && b == 0.0 {
        return DVec2::ZERO;
    }
    let (r, theta) = if a.abs() > b.abs() {
        (a, PI / 4.0 * (b / a))
    } else {
        (b, PI / 2.0 - PI / 4.0 * (a / b))
    };
    DVec2::new(r * theta.cos(), r * theta.sin())
}

/// Cosine-weighted direction about `+z`; density `cos(theta) / pi`.
pub fn cosine_hemisphere(u: [f64; 2]) -> DVec3 {
    let d = concentric_disc(u);
    DVec3::new(d.x, d.y, (1.0 - d.length_squared()).max(0.0).sqrt())
}

/// Uniform direction in the cone of half-angle `acos(cos_max)` about `+z`; density
/// `1 / (2 pi (1 - cos_max))`.
pub fn uniform_cone(u: [f64; 2], cos_max: f64) -> DVec3 {
    let cos_t = 1.0 - u[0] * (1.0 - cos_max);
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = TAU * u[1];
    DVec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t)
}

/// The balance heuristic's power-2 variant (Veach 1997): weight of a sample of density `a`
/// when the other strategy has density `b`, `a^2 / (a^2 + b^2)`.
pub fn power_heuristic(a: f64, b: f64) -> f64 {
    if a.is_infinite() {
        return 1.0;
    }
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 == 0.0 { 0.0 } else { a2 / (a2 + b2) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn basis_is_orthonormal() {
        let mut rng = SampleRng::from_seed(3);
        for _ in 0..1000 {
            let n = uniform_sphere(rng.uniform2());
            let (x, y) = basis(n);
            for (a, b) in [(x, y), (x, n), (y, n)] {
                assert!(a.dot(b).abs() < 1e-12, "orthogonal for n = {n}");
            }
            for v in [x, y] {
                assert!((v.length() - 1.0).abs() < 1e-12, "unit for n = {n}");
            }
            assert!(
                (x.cross(y) - n).length() < 1e-12,
                "right-handed for n = {n}"
            );
        }
    }

    #[test]
    fn warps_have_their_densities() {
        // The mean of z over each warp against its closed form: sphere 0, cosine 2/3,
        // cone (1 + c)/2. 200k samples: standard error < 0.002.
        let mut rng = SampleRng::from_seed(7);
        let n = 200_000;
        let mean = |f: &dyn Fn([f64; 2]) -> DVec3, rng: &mut SampleRng| {
            (0..n).map(|_| f(rng.uniform2()).z).sum::<f64>() / n as f64
        };
        assert!(mean(&uniform_sphere, &mut rng).abs() < 0.01, "sphere");
        assert!(
            (mean(&cosine_hemisphere, &mut rng) - 2.0 / 3.0).abs() < 0.01,
            "cosine"
        );
        let c = 0.3;
        assert!(
            (mean(&|u| uniform_cone(u, c), &mut rng) - (1.0 + c) / 2.0).abs() < 0.01,
            "cone"
        );
        for _ in 0..1000 {
            let v = cosine_hemisphere(rng.uniform2());
            assert!(
                (v.length() - 1.0).abs() < 1e-12 && v.z >= 0.0,
                "unit, upper"
            );
        }
    }

    #[test]
    fn streams_differ_per_pixel_and_sample() {
        let a = SampleRng::new(3, 4, 0, 1).next_u64();
        for b in [
            SampleRng::new(4, 4, 0, 1),
            SampleRng::new(3, 5, 0, 1),
            SampleRng::new(3, 4, 1, 1),
            SampleRng::new(3, 4, 0, 2),
        ] {
            assert_ne!(a, b.clone().next_u64(), "distinct streams");
        }
    }
}
