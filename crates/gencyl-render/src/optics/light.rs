//! Lights: directional, point, spherical area lights and an environment (constant or a
//! vertical gradient).
//!
//! Sampling returns radiance divided by the solid-angle density of the chosen direction;
//! delta lights (directional, point) have no density and report `pdf = inf`, which makes their
//! multiple-importance weight 1.

use std::f64::consts::{PI, TAU};

use gencyl::Ray;
use glam::DVec3;

use crate::accel::shapes::Sphere;
use crate::sampling::{basis, uniform_cone, uniform_sphere};

/// A light source other than the environment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Light {
    /// Parallel light travelling along `direction` (unit), giving `irradiance` on a surface
    /// facing it.
    Directional {
        /// Unit direction the light travels.
        direction: DVec3,
        /// Irradiance (W/m^2 per channel) on a surface perpendicular to the light.
        irradiance: DVec3,
    },
    /// Light from a point: radiant `intensity` (W/sr per channel).
    Point {
        /// Position.
        position: DVec3,
        /// Radiant intensity.
        intensity: DVec3,
    },
    /// A sphere that emits `radiance` uniformly from its surface (soft shadows); visible to
    /// camera and scattered rays.
    Sphere {
        /// The emitting sphere.
        sphere: Sphere,
        /// Emitted radiance.
        radiance: DVec3,
    },
}

/// Light from infinitely far away in every direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Environment {
    /// The same radiance from every direction (a white furnace when it is 1).
    Constant(DVec3),
    /// `bottom` below, `top` above, linear in `d.up` in between.
    Gradient {
        /// Unit up direction.
        up: DVec3,
        /// Radiance from straight up.
        top: DVec3,
        /// Radiance from straight down.
        bottom: DVec3,
    },
}

impl Environment {
    /// Radiance arriving from direction `d` (unit; the direction toward the sky).
    pub fn radiance(&self, d: DVec3) -> DVec3 {
        match *self {
            Environment::Constant(c) => c,
            Environment::Gradient { up, top, bottom } => {
                bottom.lerp(top, (0.5 * (d.dot(up) + 1.0)).clamp(0.0, 1.0))
            }
        }
    }

    /// A direction toward the sky, uniform on the sphere.
    pub fn sample(&self, u: [f64; 2]) -> LightSample {
        let wi = uniform_sphere(u);
        LightSample {
            wi,
            dist: f64::INFINITY,
            value: self.radiance(wi) * (4.0 * PI),
            pdf: 1.0 / (4.0 * PI),
        }
    }

    /// The density of [`Environment::sample`].
    pub fn pdf(&self) -> f64 {
        1.0 / (4.0 * PI)
    }
}

/// A sampled direction toward a light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    /// Unit direction from the shading point toward the light.
    pub wi: DVec3,
    /// Distance to the light along `wi` (infinite for directional and environment light).
    pub dist: f64,
    /// Arriving radiance over the density (for delta lights: the radiance-like term itself,
    /// `E` or `I / d^2`).
    pub value: DVec3,
    /// Solid-angle density of `wi`; `inf` for delta lights.
    pub pdf: f64,
}

impl Light {
    /// Whether the light emits nothing (its irradiance, intensity or radiance is zero in every
    /// channel), so it lights nothing.
    pub fn is_dark(&self) -> bool {
        let value = match self {
            Light::Directional { irradiance, .. } => irradiance,
            Light::Point { intensity, .. } => intensity,
            Light::Sphere { radiance, .. } => radiance,
        };
        *value == DVec3::ZERO
    }

    /// Checks the light's numbers; the message names the problem.
    pub fn validate(&self) -> Result<(), String> {
        let colour_ok = |c: DVec3| c.is_finite() && c.min_element() >= 0.0;
        match *self {
            Light::Directional {
                direction,
                irradiance,
            } => {
                if !(direction.is_finite() && direction.length_squared() > 0.0) {
                    return Err("direction must be a finite non-zero vector".into());
                }
                if !colour_ok(irradiance) {
                    return Err("irradiance must be finite and non-negative".into());
                }
            }
            Light::Point {
                position,
                intensity,
            } => {
                if !position.is_finite() {
                    return Err("position must be finite".into());
                }
                if !colour_ok(intensity) {
                    return Err("intensity must be finite and non-negative".into());
                }
            }
            Light::Sphere { sphere, radiance } => {
                if !sphere.center.is_finite() {
                    return Err("center must be finite".into());
                }
                if !(sphere.radius > 0.0 && sphere.radius.is_finite()) {
                    return Err("radius must be positive and finite".into());
                }
                if !colour_ok(radiance) {
                    return Err("radiance must be finite and non-negative".into());
                }
            }
        }
        Ok(())
    }

    /// A direction from `p` toward the light. Spherical lights are sampled uniformly in the
    /// cone they subtend, `pdf = 1 / (2 pi (1 - cos theta_max))`, `sin^2 theta_max = r^2/d^2`
    /// (uniform over the sphere of directions from inside).
    pub fn sample(&self, p: DVec3, u: [f64; 2]) -> Option<LightSample> {
        match *self {
            Light::Directional {
                direction,
                irradiance,
            } => Some(LightSample {
                wi: -direction,
                dist: f64::INFINITY,
                value: irradiance,
                pdf: f64::INFINITY,
            }),
            Light::Point {
                position,
                intensity,
            } => {
                let to = position - p;
                let d2 = to.length_squared();
                (d2 > 0.0).then(|| LightSample {
                    wi: to / d2.sqrt(),
                    dist: d2.sqrt(),
                    value: intensity / d2,
                    pdf: f64::INFINITY,
                })
            }
            Light::Sphere { sphere, radiance } => {
                let to = sphere.center - p;
                let d2 = to.length_squared();
                let r2 = sphere.radius * sphere.radius;
                let (wi, pdf) = if d2 <= r2 {
                    (uniform_sphere(u), 1.0 / (4.0 * PI))
                } else {
                    let w = to / d2.sqrt();
                    let sin2 = r2 / d2;
                    let cos_max = (1.0 - sin2).sqrt();
                    let (x, y) = basis(w);
                    let l = uniform_cone(u, cos_max);
                    // 1 - cos_max written without cancellation for small, far spheres.
                    let one_minus = sin2 / (1.0 + cos_max);
                    (x * l.x + y * l.y + w * l.z, 1.0 / (TAU * one_minus))
                };
                let (t0, t1) = sphere.crossings(&Ray::new(p, wi))?;
                let dist = if t0 > 0.0 { t0 } else { t1 };
                (dist > 0.0).then(|| LightSample {
                    wi,
                    dist,
                    value: radiance / pdf,
                    pdf,
                })
            }
        }
    }

    /// The density with which [`Light::sample`] from `p` picks `wi`, for a direction known to
    /// reach the light (only spherical lights can be hit).
    pub fn pdf(&self, p: DVec3) -> f64 {
        match *self {
            Light::Sphere { sphere, .. } => {
                let d2 = (sphere.center - p).length_squared();
                let r2 = sphere.radius * sphere.radius;
                if d2 <= r2 {
                    1.0 / (4.0 * PI)
                } else {
                    let sin2 = r2 / d2;
                    1.0 / (TAU * sin2 / (1.0 + (1.0 - sin2).sqrt()))
                }
            }
            _ => 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::SampleRng;

    #[test]
    fn sphere_light_irradiance_matches_the_closed_form() {
        // Irradiance at distance d on a surface facing a sphere of radiance L and radius r:
        // E = pi L r^2 / d^2 (the sphere seen as a disc of solid-angle-projected area).
        let light = Light::Sphere {
            sphere: Sphere {
                center: DVec3::new(0.0, 0.0, 3.0),
                radius: 1.0,
            },
            radiance: DVec3::ONE,
        };
        let mut rng = SampleRng::from_seed(1);
        let n = 200_000;
        let mut e = 0.0;
        for _ in 0..n {
            let s = light.sample(DVec3::ZERO, rng.uniform2()).unwrap();
            assert!(
                (s.pdf - light.pdf(DVec3::ZERO)).abs() < 1e-9 * s.pdf,
                "pdf agrees"
            );
            let hit = s.wi * s.dist - DVec3::new(0.0, 0.0, 3.0);
            assert!((hit.length() - 1.0).abs() < 1e-9, "lands on the sphere");
            e += s.value.x * s.wi.z.max(0.0);
        }
        e /= n as f64;
        let want = PI / 9.0;
        assert!((e - want).abs() < 0.01 * want, "E = {e}, want {want}");
    }

    #[test]
    fn environment_sampling_integrates_radiance() {
        // Irradiance from a constant environment on one side: pi * L.
        let env = Environment::Constant(DVec3::splat(2.0));
        let mut rng = SampleRng::from_seed(2);
        let n = 200_000;
        let e: f64 = (0..n)
            .map(|_| {
                let s = env.sample(rng.uniform2());
                s.value.x * s.wi.z.max(0.0)
            })
            .sum::<f64>()
            / n as f64;
        assert!((e - 2.0 * PI).abs() < 0.02 * 2.0 * PI, "E = {e}");
        let g = Environment::Gradient {
            up: DVec3::Y,
            top: DVec3::ONE,
            bottom: DVec3::ZERO,
        };
        assert_eq!(g.radiance(DVec3::Y), DVec3::ONE, "top");
        assert_eq!(g.radiance(-DVec3::Y), DVec3::ZERO, "bottom");
        assert_eq!(g.radiance(DVec3::X), DVec3::splat(0.5), "horizon");
    }
}
