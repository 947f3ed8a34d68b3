//! The non-fiber shapes of a scene: spheres (a scalp, a light) and infinite planes (a floor).

use gencyl::Ray;
use glam::DVec3;

/// A sphere: a closed solid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    /// Centre.
    pub center: DVec3,
    /// Radius, positive.
    pub radius: f64,
}

impl Sphere {
    /// The parameters `t0 <= t1` where the line `o + t d` crosses the sphere, if it does.
    ///
    /// `|o + t d - c|^2 = r^2`, solved with the numerically stable form: with `f = o - c`, the
    /// discriminant is `r^2 - |f - (f.d) d / |d|^2|^2` (Hearn and Baker; pbrt-v4's variant).
    pub fn crossings(&self, ray: &Ray) -> Option<(f64, f64)> {
        let f = ray.origin - self.center;
        let a = ray.dir.length_squared();
        let b = -f.dot(ray.dir);
        let l = f + (b / a) * ray.dir;
        let disc = a * (self.radius * self.radius - l.length_squared());
        if !(disc >= 0.0) {
            return None;
        }
        let q = b + disc.sqrt().copysign(b);
        let c = f.length_squared() - self.radius * self.radius;
        let (t0, t1) = if q == 0.0 { (0.0, 0.0) } else { (c / q, q / a) };
        Some((t0.min(t1), t0.max(t1)))
    }

    /// Outward unit normal at a point on the sphere.
    pub fn normal(&self, p: DVec3) -> DVec3 {
        (p - self.center).normalize()
    }
}

/// An infinite plane through `point`, facing `normal`; seen from both sides.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    /// A point of the plane.
    pub point: DVec3,
    /// Unit normal (the side called "outward").
    pub normal: DVec3,
}

impl Plane {
    /// The parameter where the ray crosses the plane, if it is not parallel to it.
    pub fn crossing(&self, ray: &Ray) -> Option<f64> {
        let t = (self.point - ray.origin).dot(self.normal) / ray.dir.dot(self.normal);
        t.is_finite().then_some(t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_crossings_are_on_the_sphere() {
        let s = Sphere {
            center: DVec3::new(1.0, 2.0, 3.0),
            radius: 0.5,
        };
        let ray = Ray::new(DVec3::new(1.0, 2.0, -10.0), DVec3::new(0.0, 0.01, 2.0));
        let (t0, t1) = s.crossings(&ray).unwrap();
        assert!(t0 < t1, "ordered");
        for t in [t0, t1] {
            let d = (ray.at(t) - s.center).length();
            assert!((d - 0.5).abs() < 1e-12, "on the sphere: {d}");
        }
        let miss = Ray::new(DVec3::new(3.0, 2.0, -10.0), DVec3::Z);
        assert_eq!(s.crossings(&miss), None, "miss");
        // Far away and tiny: the stable form still lands on the sphere.
        let far = Ray::new(DVec3::new(1.0, 2.0, -1e7), DVec3::Z);
        let (t0, _) = s.crossings(&far).unwrap();
        assert!((t0 - (1e7 + 2.5)).abs() < 1e-6, "far crossing {t0}");
    }

    #[test]
    fn plane_crossing() {
        let p = Plane {
            point: DVec3::new(0.0, -1.0, 0.0),
            normal: DVec3::Y,
        };
        let ray = Ray::new(DVec3::new(0.5, 1.0, 0.0), DVec3::new(0.0, -2.0, 0.0));
        assert_eq!(p.crossing(&ray), Some(1.0), "t in units of d");
        assert_eq!(
            p.crossing(&Ray::new(DVec3::ZERO, DVec3::X)),
            None,
            "parallel"
        );
    }
}
