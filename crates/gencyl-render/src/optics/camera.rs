//! Cameras: perspective (pinhole) and orthographic.

use gencyl::Ray;
use glam::DVec3;

use crate::accel::Frustum;

/// How the camera projects the scene onto the image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// A pinhole camera with this vertical field of view, in degrees (0 < fov < 180).
    Perspective {
        /// Vertical field of view, degrees.
        fov: f64,
    },
    /// Parallel rays; the image spans `height` world units vertically.
    Orthographic {
        /// Height of the viewed rectangle, world units.
        height: f64,
    },
}

/// A camera at `position` looking at `look_at`, `up` giving the image's vertical.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position (orthographic: the centre of the image rectangle).
    pub position: DVec3,
    /// The point at the image's centre.
    pub look_at: DVec3,
    /// The image's up direction (need not be perpendicular to the view).
    pub up: DVec3,
    /// Perspective or orthographic.
    pub projection: Projection,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
}

impl Camera {
    /// Checks the camera's geometry; the message names the problem.
    pub fn validate(&self) -> Result<(), String> {
        let view = self.look_at - self.position;
        if !(self.position.is_finite() && self.look_at.is_finite() && self.up.is_finite()) {
            return Err("camera position, look_at and up must be finite".into());
        }
        if view.length_squared() == 0.0 {
            return Err("camera look_at equals its position".into());
        }
        if view.normalize().cross(self.up).length_squared() < 1e-12 {
            return Err("camera up is parallel to the view direction".into());
        }
        match self.projection {
            Projection::Perspective { fov } if !(fov > 0.0 && fov < 180.0) => {
                Err(format!("camera fov must be in (0, 180) degrees, got {fov}"))
            }
            Projection::Orthographic { height } if !(height > 0.0 && height.is_finite()) => Err(
                format!("camera view_height must be positive and finite, got {height}"),
            ),
            _ if self.width == 0 || self.height == 0 => Err(format!(
                "camera resolution must be positive, got {}x{}",
                self.width, self.height
            )),
            _ => Ok(()),
        }
    }

    /// The view basis: right `u`, up `v`, forward `w`.
    fn basis(&self) -> (DVec3, DVec3, DVec3) {
        let w = (self.look_at - self.position).normalize();
        let u = w.cross(self.up).normalize();
        (u, u.cross(w), w)
    }

    /// Half the image's height on the image plane at unit distance (perspective) or in world
    /// units (orthographic).
    fn half_height(&self) -> f64 {
        match self.projection {
            Projection::Perspective { fov } => (fov.to_radians() * 0.5).tan(),
            Projection::Orthographic { height } => 0.5 * height,
        }
    }

    /// The ray through image position `(x, y)`, in pixels from the top left corner (pixel
    /// `(i, j)` covers `[i, i+1) x [j, j+1)`). Directions are unit length. (For many rays,
    /// [`Camera::rays`] once and [`CameraRays::ray`] for each.)
    pub fn ray(&self, x: f64, y: f64) -> Ray {
        self.rays().ray(x, y)
    }

    /// The camera made ready to cast rays: its basis and the image's half extents found once.
    pub fn rays(&self) -> CameraRays {
        let (u, v, w) = self.basis();
        let half_h = self.half_height();
        CameraRays {
            camera: *self,
            u,
            v,
            w,
            half_w: half_h * self.width as f64 / self.height as f64,
            half_h,
        }
    }

    /// The side of a pixel in world units, for an orthographic camera.
    pub fn pixel_size(&self) -> Option<f64> {
        match self.projection {
            Projection::Orthographic { height } => Some(height / self.height as f64),
            Projection::Perspective { .. } => None,
        }
    }
}

/// A [`Camera`] made ready to cast rays ([`Camera::rays`]): the same rays as [`Camera::ray`],
/// bit for bit, without finding the view basis (three normalisations) and the field of view's
/// tangent again for each.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraRays {
    camera: Camera,
    /// Right, up and forward.
    u: DVec3,
    v: DVec3,
    w: DVec3,
    /// Half the image's width and height on the image plane at unit distance (perspective) or
    /// in world units (orthographic).
    half_w: f64,
    half_h: f64,
}

impl CameraRays {
    /// The camera.
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    /// [`Camera::ray`]: through image position `(x, y)` in pixels from the top left corner,
    /// at `s_x u + s_y v` on the image plane, `s_x = (2x / width - 1) half_w`,
    /// `s_y = (1 - 2y / height) half_h`.
    pub fn ray(&self, x: f64, y: f64) -> Ray {
        let c = &self.camera;
        let (sx, sy) = self.image_plane(x, y);
        let (u, v, w) = (self.u, self.v, self.w);
        match c.projection {
            Projection::Perspective { .. } => {
                Ray::new(c.position, (w + sx * u + sy * v).normalize())
            }
            Projection::Orthographic { .. } => Ray::new(c.position + sx * u + sy * v, w),
        }
    }

    /// `(s_x, s_y)` of image position `(x, y)` ([`Self::ray`]).
    #[inline]
    fn image_plane(&self, x: f64, y: f64) -> (f64, f64) {
        let c = &self.camera;
        (
            (2.0 * x / c.width as f64 - 1.0) * self.half_w,
            (1.0 - 2.0 * y / c.height as f64) * self.half_h,
        )
    }

    /// The region the rays through the image square `[x0, x1] x [y0, y1]` (pixels) sweep
    /// for `t >= 0`: for a perspective camera the cone from the eye over the directions
    /// `w + s_x u + s_y v` of the square ([`Frustum::pyramid`]), for an orthographic one the
    /// half-prism of the rays from `eye + s_x u + s_y v` ([`Frustum::prism`]).
    pub fn frustum(&self, [x0, y0]: [f64; 2], [x1, y1]: [f64; 2]) -> Frustum {
        let eye = self.camera.position;
        let basis = [self.u, self.v, self.w];
        let (sx0, sy0) = self.image_plane(x0, y0);
        let (sx1, sy1) = self.image_plane(x1, y1);
        match self.camera.projection {
            Projection::Perspective { .. } => Frustum::pyramid(eye, basis, [sx0, sx1], [sy1, sy0]),
            Projection::Orthographic { .. } => Frustum::prism(eye, basis, [sx0, sx1], [sy1, sy0]),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pixel's frustum holds every ray through the pixel (corners and edges included, the
    /// sample positions `x + 1 - 2^-53` and `x + 1` too) at distances from 1e-6 to 1e6 of the
    /// view's, to within 1e-12 of the distances (rounding), and is tight: the centre ray of the
    /// pixel two to the side lies outside it. Perspective fields of view from 1e-3 to 179
    /// degrees, orthographic views, cameras 1e4 from the origin.
    #[test]
    fn frustums_hold_their_pixels_rays() {
        let mut rng = crate::sampling::SampleRng::from_seed(5);
        // The least over the planes of `(n.(p - eye) - c + point) / size`: `size` the scale of
        // the rounding of the planes and directions, `point` that of the point itself.
        let value = |f: &Frustum, p: DVec3| {
            let point = 100.0 * f64::EPSILON * p.abs().element_sum();
            f.planes()
                .iter()
                .map(|&(n, c)| {
                    let size = (p - f.eye()).abs().element_sum() + c.abs();
                    (n.dot(p - f.eye()) - c + point) / size
                })
                .fold(f64::INFINITY, f64::min)
        };
        let mut outside = 0;
        for case in 0..400 {
            let far = if case % 2 == 0 { 0.0 } else { 1e4 };
            let position = rng.in_box(DVec3::splat(-1.0), DVec3::splat(1.0)) + DVec3::splat(far);
            let view = rng.unit_vector() * 10.0f64.powf(rng.range(-3.0, 3.0));
            let projection = if case % 3 == 0 {
                Projection::Orthographic {
                    height: 10.0f64.powf(rng.range(-3.0, 2.0)),
                }
            } else {
                Projection::Perspective {
                    fov: 1e-3 * 1.79e5f64.powf(rng.uniform()),
                }
            };
            let cam = Camera {
                position,
                look_at: position + view,
                up: rng.unit_vector(),
                projection,
                width: 1 + (rng.next_u64() % 800) as u32,
                height: 1 + (rng.next_u64() % 800) as u32,
            };
            if cam.validate().is_err() {
                continue;
            }
            let rays = cam.rays();
            let x = (rng.next_u64() % cam.width as u64) as f64;
            let y = (rng.next_u64() % cam.height as u64) as f64;
            let f = rays.frustum([x, y], [x + 1.0, y + 1.0]);
            let last = 1.0 - f64::EPSILON / 2.0;
            let offsets = [0.0, 1.0, last, rng.uniform(), 0.5];
            for dx in offsets {
                for dy in offsets {
                    let ray = rays.ray(x + dx, y + dy);
                    for e in -6..=6 {
                        let p = ray.at(view.length() * 10.0f64.powi(e));
                        let v = value(&f, p);
                        assert!(
                            v >= -1e-12,
                            "{cam:?} pixel ({x}, {y}) + ({dx}, {dy}): {v:e}"
                        );
                    }
                }
            }
            // The centre ray of the pixel two to the side (when the image has one) is outside.
            let side = if x + 2.0 < cam.width as f64 {
                x + 2.5
            } else {
                x - 1.5
            };
            if side >= 0.0 {
                // Outside by at least a quarter of a pixel's width there.
                let t = view.length() * 1e3;
                let p = rays.ray(side, y + 0.5).at(t);
                let pixel = (rays.ray(x + 1.5, y).at(t) - rays.ray(x + 0.5, y).at(t)).length();
                let depth = f
                    .planes()
                    .iter()
                    .map(|&(n, c)| n.dot(p - f.eye()) - c)
                    .fold(f64::INFINITY, f64::min);
                assert!(
                    depth < -0.25 * pixel,
                    "{cam:?}: the next pixel but one is inside"
                );
                outside += 1;
            }
        }
        assert!(outside > 200, "{outside}");
    }

    fn cam(projection: Projection) -> Camera {
        Camera {
            position: DVec3::new(0.0, 0.0, 5.0),
            look_at: DVec3::ZERO,
            up: DVec3::Y,
            projection,
            width: 200,
            height: 100,
        }
    }

    #[test]
    fn perspective_corners_span_the_field_of_view() {
        let c = cam(Projection::Perspective { fov: 90.0 });
        let centre = c.ray(100.0, 50.0);
        assert!(
            (centre.dir - DVec3::NEG_Z).length() < 1e-15,
            "centre looks at look_at"
        );
        // fov 90: the top edge is 45 degrees up; the aspect 2:1 makes the right edge tan = 2.
        let top = c.ray(100.0, 0.0).dir;
        assert!(
            (top.y / -top.z - 1.0).abs() < 1e-12,
            "top edge at 45 degrees: {top}"
        );
        let right = c.ray(200.0, 50.0).dir;
        assert!(
            (right.x / -right.z - 2.0).abs() < 1e-12,
            "right edge: {right}"
        );
    }

    #[test]
    fn orthographic_rays_are_parallel_and_span_the_view_height() {
        let c = cam(Projection::Orthographic { height: 3.0 });
        let (a, b) = (c.ray(0.0, 0.0), c.ray(200.0, 100.0));
        assert_eq!(a.dir, DVec3::NEG_Z, "parallel");
        assert_eq!(b.dir, DVec3::NEG_Z, "parallel");
        assert!(
            (a.origin - DVec3::new(-3.0, 1.5, 5.0)).length() < 1e-12,
            "{}",
            a.origin
        );
        assert!(
            (b.origin - DVec3::new(3.0, -1.5, 5.0)).length() < 1e-12,
            "{}",
            b.origin
        );
        assert_eq!(c.pixel_size(), Some(0.03), "pixel size");
    }

    #[test]
    fn bad_cameras_are_named() {
        let mut c = cam(Projection::Perspective { fov: 180.0 });
        assert!(c.validate().unwrap_err().contains("fov"), "fov");
        c.projection = Projection::Perspective { fov: 40.0 };
        c.up = DVec3::Z;
        assert!(c.validate().unwrap_err().contains("parallel"), "up");
        c.up = DVec3::Y;
        c.look_at = c.position;
        assert!(c.validate().unwrap_err().contains("look_at"), "look_at");
    }
}
