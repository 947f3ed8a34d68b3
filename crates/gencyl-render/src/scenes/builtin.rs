//! The built-in scene, and what the renderer supplies when a scene leaves it out: a camera
//! framed on the geometry and default lighting.

use gencyl::Aabb;
use glam::DVec3;

use crate::accel::shapes::Sphere;
use crate::optics::camera::{Camera, Projection};
use crate::optics::light::{Environment, Light};
use crate::scene_file::SceneDescription;

/// The built-in scene's file (`examples/default.toml`), embedded in the binary.
pub const DEFAULT_SCENE: &str = include_str!("../../../../examples/default.toml");

/// The built-in scene: a tuft of 48 curly fibers, round, elliptical and flat, some twisted,
/// on a floor under a spherical light and a sky gradient.
pub fn default_scene() -> SceneDescription {
    SceneDescription::parse(DEFAULT_SCENE, "examples/default.toml")
        .expect("the built-in scene is valid (tested)")
}

/// A perspective camera (40 degree field of view) that looks at the centre of `bounds` from
/// the front and above, far enough to see all of it.
pub fn framed_camera(bounds: Aabb, width: u32, height: u32) -> Camera {
    let fov: f64 = 40.0;
    let (center, radius) = extent(bounds);
    let aspect = (width as f64 / height as f64).min(1.0);
    let half = (0.5 * fov.to_radians()).tan() * aspect;
    let dist = radius / half.atan().sin() * 1.05;
    let dir = DVec3::new(0.25, 0.35, 1.0).normalize();
    Camera {
        position: center + dir * dist,
        look_at: center,
        up: DVec3::Y,
        projection: Projection::Perspective { fov },
        width,
        height,
    }
}

/// Light for a scene that has none: a sky gradient and a spherical key light above and in
/// front of the geometry, bright enough to give an irradiance of about 3 at its centre.
pub fn default_lighting(bounds: Aabb) -> (Light, Environment) {
    let (center, radius) = extent(bounds);
    let offset = DVec3::new(1.5, 3.0, 1.2) * radius;
    let r = 0.4 * radius;
    // E = pi L r^2 / d^2 for a sphere seen from distance d.
    let radiance = 3.0 * offset.length_squared() / (std::f64::consts::PI * r * r);
    (
        Light::Sphere {
            sphere: Sphere {
                center: center + offset,
                radius: r,
            },
            radiance: DVec3::splat(radiance),
        },
        Environment::Gradient {
            up: DVec3::Y,
            top: DVec3::new(0.18, 0.28, 0.45),
            bottom: DVec3::new(0.55, 0.6, 0.68),
        },
    )
}

/// Centre and radius of the bounds' sphere (the unit sphere at the origin for empty bounds).
fn extent(b: Aabb) -> (DVec3, f64) {
    if !(b.min.is_finite() && b.max.is_finite()) {
        return (DVec3::ZERO, 1.0);
    }
    (b.center(), (0.5 * (b.max - b.min).length()).max(1e-9))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_scene_parses_with_its_camera_and_lights() {
        let d = default_scene();
        assert_eq!(d.cylinders.len(), 48 * 13, "48 strands of 13 segments");
        assert!(d.camera.is_some(), "camera");
        assert_eq!(d.lights.len(), 2, "a key light and a rim light");
        assert!(d.environment.is_some(), "sky");
        assert_eq!(d.planes.len(), 1, "floor");
    }

    #[test]
    fn framing_sees_the_whole_bounds() {
        let b = Aabb {
            min: DVec3::new(-1.0, 0.0, -2.0),
            max: DVec3::new(3.0, 5.0, 1.0),
        };
        let cam = framed_camera(b, 400, 300);
        // Every corner of the box projects inside the image.
        let (w, v) = ((cam.look_at - cam.position).normalize(), DVec3::Y);
        let right = w.cross(v).normalize();
        let up = right.cross(w);
        let half = (20f64).to_radians().tan();
        for i in 0..8 {
            let c = DVec3::new(
                if i & 1 == 0 { b.min.x } else { b.max.x },
                if i & 2 == 0 { b.min.y } else { b.max.y },
                if i & 4 == 0 { b.min.z } else { b.max.z },
            );
            let d = c - cam.position;
            let z = d.dot(w);
            assert!(z > 0.0, "in front");
            assert!(
                (d.dot(up) / z).abs() < half,
                "vertically inside: corner {c}"
            );
            assert!(
                (d.dot(right) / z).abs() < half * 400.0 / 300.0,
                "horizontally inside"
            );
        }
    }
}
