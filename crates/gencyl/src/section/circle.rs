use std::f64::consts::{FRAC_PI_2, PI, TAU};

use glam::DVec2;

use super::{CrossSection, LineCrossings};
use crate::real::{Real, V2};

/// The unit circle `cs(v) = (cos v, sin v)`, counter-clockwise (seed section 3).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct UnitCircle;

impl CrossSection for UnitCircle {
    fn point(&self, v: f64) -> DVec2 {
        let (s, c) = crate::real::sin_cos(v);
        DVec2::new(c, s)
    }
    fn derivative(&self, v: f64) -> DVec2 {
        let (s, c) = crate::real::sin_cos(v);
        DVec2::new(-s, c)
    }
    fn point_and_derivative(&self, v: f64) -> (DVec2, DVec2) {
        let (s, c) = crate::real::sin_cos(v);
        (DVec2::new(c, s), DVec2::new(-s, c))
    }
    fn point_r<T: Real>(&self, v: T) -> V2<T> {
        let (s, c) = v.sin_cos();
        V2::new(c, s)
    }
    fn contains(&self, p: DVec2) -> bool {
        p.length_squared() <= 1.0
    }
    fn bounding_radius(&self) -> f64 {
        1.0
    }
    /// `|p + s dir|^2 = 1`: `|dir|^2 s^2 + 2 (p.dir) s + |p|^2 - 1 = 0`.
    fn intersect_line(&self, p: DVec2, dir: DVec2) -> LineCrossings {
        let mut out = LineCrossings::new();
        for s in crate::roots::quadratic_roots(
            dir.length_squared(),
            2.0 * p.dot(dir),
            p.length_squared() - 1.0,
        ) {
            let q = p + s * dir;
            out.push((s, angle(q)));
        }
        out
    }
    fn monotone_breaks(&self) -> Vec<f64> {
        vec![0.0, FRAC_PI_2, PI, 3.0 * FRAC_PI_2, TAU]
    }
    fn orientation(&self) -> f64 {
        1.0
    }
    fn is_unit_circle(&self) -> bool {
        true
    }
}

/// The angle of `p` in `[0, 2 pi)`.
pub(crate) fn angle(p: DVec2) -> f64 {
    let a = p.y.atan2(p.x);
    if a < 0.0 {
        // a + 2 pi can round up to exactly 2 pi for tiny negative a.
        let w = a + TAU;
        if w >= TAU { 0.0 } else { w }
    } else {
        a
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_crossings_lie_on_the_circle() {
        let c = UnitCircle;
        let hits = c.intersect_line(DVec2::new(-2.0, 0.5), DVec2::new(3.0, 0.1));
        assert_eq!(hits.len(), 2, "a secant line crosses twice");
        for (s, v) in hits {
            let q = DVec2::new(-2.0, 0.5) + s * DVec2::new(3.0, 0.1);
            assert!((q.length() - 1.0).abs() < 1e-14, "crossing off the circle");
            assert!(
                (c.point(v) - q).length() < 1e-14,
                "v does not name the crossing"
            );
            assert!((0.0..TAU).contains(&v), "v in [0, 2pi)");
        }
        assert!(
            c.intersect_line(DVec2::new(0.0, 2.0), DVec2::X).is_empty(),
            "a line that misses"
        );
    }
}
