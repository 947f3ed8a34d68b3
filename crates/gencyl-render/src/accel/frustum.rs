//! Regions that bundles of rays sweep, for [`super::Bvh::list_region`]: a pixel's camera
//! rays.

use glam::DVec3;

/// The region a bundle of rays sweeps (a pixel's camera rays: `CameraRays::frustum`): the
/// points `p` with `n.(p - eye) >= c` for each plane `(n, c)` (`n` unit), what
/// [`super::Bvh::list_region`] lists the leaves of.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frustum {
    eye: DVec3,
    /// The view direction `w` (unit).
    axis: DVec3,
    planes: [(DVec3, f64); 5],
}

impl Frustum {
    /// The cone from `eye` over the directions `w + x u + y v`, `x` in `[x0, x1]`, `y` in
    /// `[y0, y1]` (`u`, `v`, `w` orthonormal): bounded by the planes through the eye and two
    /// adjacent corners `e_i`, normals `e_i x u` or `e_i x v` along the rectangle's edge
    /// (without the cancellation of `e_i x e_j` for a small rectangle), turned toward its
    /// centre, and by `w.(p - eye) >= 0`.
    pub fn pyramid(
        eye: DVec3,
        [u, v, w]: [DVec3; 3],
        [x0, x1]: [f64; 2],
        [y0, y1]: [f64; 2],
    ) -> Self {
        let e = |x: f64, y: f64| w + x * u + y * v;
        let corners = [e(x0, y0), e(x1, y0), e(x1, y1), e(x0, y1)];
        let centre = e(0.5 * (x0 + x1), 0.5 * (y0 + y1));
        let edges = [u, v, u, v];
        let side = |i: usize| {
            let n = corners[i].cross(edges[i]).normalize_or_zero();
            (if n.dot(centre) < 0.0 { -n } else { n }, 0.0)
        };
        Frustum {
            eye,
            axis: w,
            planes: [side(0), side(1), side(2), side(3), (w, 0.0)],
        }
    }

    /// The half-prism of parallel rays `w` from the rectangle `eye + x u + y v`, `x` in
    /// `[x0, x1]`, `y` in `[y0, y1]` (`u`, `v`, `w` orthonormal): `x0 <= u.(p - eye) <= x1`,
    /// `y0 <= v.(p - eye) <= y1`, `w.(p - eye) >= 0` (an orthographic camera's rays).
    pub fn prism(
        eye: DVec3,
        [u, v, w]: [DVec3; 3],
        [x0, x1]: [f64; 2],
        [y0, y1]: [f64; 2],
    ) -> Self {
        Frustum {
            eye,
            axis: w,
            planes: [(u, x0), (-u, -x1), (v, y0), (-v, -y1), (w, 0.0)],
        }
    }

    /// The point the planes are taken relative to: the camera's position.
    pub fn eye(&self) -> DVec3 {
        self.eye
    }

    /// The direction `w` (unit) along which every ray of the region runs at most at its speed.
    pub fn axis(&self) -> DVec3 {
        self.axis
    }

    /// The planes `(n, c)`: the region is `n.(p - eye) >= c` for each.
    pub fn planes(&self) -> &[(DVec3, f64)] {
        &self.planes
    }
}
