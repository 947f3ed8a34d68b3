//! Strands: a fiber given by a polyline of control points, turned into C2-continuous cubic
//! Bezier segments with continuous radii and twist.

use glam::DVec3;

use crate::curve::CubicBezier;
use crate::cylinder::{GeneralizedCylinder, GeometryError};
use crate::section::Section;
use crate::sweep::HairSweep;

/// A hair strand: control points root first, with root-to-tip shape parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct Strand {
    /// Control points of a uniform cubic B-spline, root first (at least 2).
    pub points: Vec<DVec3>,
    /// Major radius at the root and at the tip.
    pub radius: [f64; 2],
    /// Minor / major radius ratio (1 for round fibers).
    pub ellipticity: f64,
    /// Rotation of the section at the root and at the tip, radians.
    pub twist: [f64; 2],
    /// The cross section (default: the unit circle).
    pub section: Section,
}

impl Strand {
    /// The uniform cubic B-spline control points whose curve (as [`Strand::bezier_segments`]
    /// builds it) passes through every point of `points`, in order: the natural interpolating
    /// cubic spline. Segment `i` starts at `(Q_{i-1} + 4 Q_i + Q_{i+1}) / 6`, so
    /// `Q_{i-1} + 4 Q_i + Q_{i+1} = 6 P_i` inside, and the reflected end points make `Q_0 = P_0`,
    /// `Q_{n-1} = P_{n-1}` (zero second derivative at both ends). The tridiagonal system is
    /// solved by the Thomas algorithm (diagonally dominant, so stable).
    pub fn interpolating_control_points(points: &[DVec3]) -> Vec<DVec3> {
        let n = points.len();
        if n <= 2 {
            return points.to_vec();
        }
        // Unknowns Q_1 .. Q_{n-2}; row i: Q_{i-1} + 4 Q_i + Q_{i+1} = 6 P_i.
        let m = n - 2;
        let mut c = vec![0.0; m]; // modified super-diagonal
        let mut d = vec![DVec3::ZERO; m]; // modified right-hand side
        for k in 0..m {
            let mut rhs = 6.0 * points[k + 1];
            if k == 0 {
                rhs -= points[0];
            }
            if k == m - 1 {
                rhs -= points[n - 1];
            }
            let (sub, prev_c, prev_d) = if k == 0 {
                (0.0, 0.0, DVec3::ZERO)
            } else {
                (1.0, c[k - 1], d[k - 1])
            };
            let denom = 4.0 - sub * prev_c;
            c[k] = 1.0 / denom;
            d[k] = (rhs - sub * prev_d) / denom;
        }
        let mut q = vec![DVec3::ZERO; n];
        q[0] = points[0];
        q[n - 1] = points[n - 1];
        for k in (0..m).rev() {
            let next = if k + 1 < m { q[k + 2] } else { DVec3::ZERO };
            q[k + 1] = d[k] - c[k] * next;
        }
        q
    }

    /// The Bezier segments of the uniform cubic B-spline through the control points, with the
    /// end points reflected (`Q_{-1} = 2 Q_0 - Q_1`, likewise at the tip) so the curve starts at
    /// the root and ends at the tip. Segment `i` over `Q_{i-1}..Q_{i+2}` has Bezier points
    /// `(Q_{i-1} + 4 Q_i + Q_{i+1})/6`, `(2 Q_i + Q_{i+1})/3`, `(Q_i + 2 Q_{i+1})/3`,
    /// `(Q_i + 4 Q_{i+1} + Q_{i+2})/6`: consecutive segments share position, first and second
    /// derivatives, so the Frenet frame is continuous across joints.
    pub fn bezier_segments(&self) -> Vec<CubicBezier> {
        let q = &self.points;
        let n = q.len();
        if n < 2 {
            return Vec::new();
        }
        let at = |i: isize| -> DVec3 {
            if i < 0 {
                2.0 * q[0] - q[1]
            } else if i as usize >= n {
                2.0 * q[n - 1] - q[n - 2]
            } else {
                q[i as usize]
            }
        };
        (0..n as isize - 1)
            .map(|i| {
                let (a, b, c, d) = (at(i - 1), at(i), at(i + 1), at(i + 2));
                CubicBezier::new([
                    (a + 4.0 * b + c) / 6.0,
                    (2.0 * b + c) / 3.0,
                    (b + 2.0 * c) / 3.0,
                    (b + 4.0 * c + d) / 6.0,
                ])
            })
            .collect()
    }

    /// The strand as cylinders: radii and twist interpolated linearly along the segments, caps
    /// only at the root and the tip. A straight segment takes the frame of its nearest curved
    /// neighbour (as its normal hint), so the section does not jump at the joint.
    pub fn cylinders(&self) -> Result<Vec<GeneralizedCylinder>, (usize, GeometryError)> {
        let segs = self.bezier_segments();
        let k = segs.len();
        let lerp = |x: [f64; 2], s: f64| x[0] + (x[1] - x[0]) * s;
        let mut out: Vec<GeneralizedCylinder> = Vec::with_capacity(k);
        for (i, seg) in segs.iter().enumerate() {
            let (s0, s1) = (i as f64 / k as f64, (i + 1) as f64 / k as f64);
            let major = [lerp(self.radius, s0), lerp(self.radius, s1)];
            let sweep = HairSweep {
                major,
                minor: major.map(|r| r * self.ellipticity),
                rotation: [lerp(self.twist, s0), lerp(self.twist, s1)],
            };
            let hint = out.last().map(|prev| prev.frame(1.0).n);
            let cyl = GeneralizedCylinder::new(*seg, self.section.clone(), sweep, true, hint)
                .map_err(|e| (i, e))?
                .with_caps(i == 0, i + 1 == k);
            out.push(cyl);
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segments_are_c2_and_span_root_to_tip() {
        let s = Strand {
            points: vec![
                DVec3::ZERO,
                DVec3::new(1.0, 0.5, 0.0),
                DVec3::new(2.0, -0.3, 0.4),
                DVec3::new(3.0, 0.2, 1.0),
                DVec3::new(3.5, 1.0, 1.5),
            ],
            radius: [0.05, 0.02],
            ellipticity: 0.6,
            twist: [0.0, 3.0],
            section: Section::default(),
        };
        let segs = s.bezier_segments();
        assert_eq!(segs.len(), 4, "one segment per polyline span");
        assert!(
            (segs[0].point(0.0) - s.points[0]).length() < 1e-15,
            "starts at the root"
        );
        assert!(
            (segs[3].point(1.0) - s.points[4]).length() < 1e-15,
            "ends at the tip"
        );
        for w in segs.windows(2) {
            let (a, b) = (&w[0], &w[1]);
            assert!((a.point(1.0) - b.point(0.0)).length() < 1e-14, "C0");
            assert!((a.d1(1.0) - b.d1(0.0)).length() < 1e-13, "C1");
            assert!((a.d2(1.0) - b.d2(0.0)).length() < 1e-12, "C2");
        }
        let through = Strand::interpolating_control_points(&s.points);
        let interp = Strand {
            points: through,
            ..s.clone()
        };
        for (i, seg) in interp.bezier_segments().iter().enumerate() {
            let gap = (seg.point(0.0) - s.points[i]).length();
            assert!(gap < 1e-14, "the curve passes through point {i}: gap {gap}");
            let end = (seg.point(1.0) - s.points[i + 1]).length();
            assert!(end < 1e-14, "and through point {}: gap {end}", i + 1);
        }
        let segs = interp.bezier_segments();
        assert!(
            segs[0].d2(0.0).length() < 1e-12,
            "natural: no curvature at the root"
        );
        assert!(
            segs[3].d2(1.0).length() < 1e-12,
            "natural: no curvature at the tip"
        );
        let cyls = s.cylinders().unwrap();
        assert_eq!(cyls[0].caps(), [true, false], "root cap only");
        assert_eq!(cyls[3].caps(), [false, true], "tip cap only");
        assert_eq!(cyls[1].caps(), [false, false], "no inner caps");
        // Continuous frame and section across the joint: the surface points coincide.
        for w in cyls.windows(2) {
            for j in 0..8 {
                let v = j as f64 * 0.7;
                let gap = (w[0].surface_point(1.0, v) - w[1].surface_point(0.0, v)).length();
                assert!(gap < 1e-12, "surface gap {gap} at the joint, v = {v}");
            }
        }
    }

    /// A strand's root and tip have `a'' = 0` (the reflected end points), so the Frenet normal
    /// there comes from rounding noise unless the frame takes its limit: the frame must be
    /// continuous into the segment, and the capped elliptical solid closed (every ray crossing
    /// it an even number of times) near the root and the tip.
    #[test]
    fn strand_ends_have_continuous_frames_and_closed_solids() {
        let s = Strand {
            points: Strand::interpolating_control_points(&[
                DVec3::new(-1.6, 0.6, 0.0),
                DVec3::new(-0.5, 0.2, -0.3),
                DVec3::new(0.5, -0.3, 0.3),
                DVec3::new(1.6, -0.8, 0.0),
            ]),
            radius: [0.12, 0.12],
            ellipticity: 0.25,
            twist: [0.0, std::f64::consts::PI],
            section: Section::default(),
        };
        let cyls = s.cylinders().unwrap();
        let (first, last) = (&cyls[0], &cyls[cyls.len() - 1]);
        for (c, u, inward) in [(first, 0.0, 1e-4), (last, 1.0, -1e-4)] {
            let (a, b) = (c.frame(u), c.frame(u + inward));
            assert!(
                (a.n - b.n).length() < 1e-3,
                "frame continuous at the end u = {u}: {a:?} vs {b:?}"
            );
        }
        // Rays along -z over a grid around each end: hits come in pairs.
        for (c, end) in [(first, s.points[0]), (last, *s.points.last().unwrap())] {
            for i in 0..40 {
                for j in 0..40 {
                    let o = end + DVec3::new(-0.2 + 0.01 * i as f64, -0.2 + 0.01 * j as f64, 5.0);
                    let ray = crate::Ray::new(o, DVec3::NEG_Z);
                    let mut hits = Vec::new();
                    c.intersect_all(&ray, 0.0, f64::INFINITY, &mut hits);
                    let tangent = hits.iter().any(|h| h.normal.z.abs() < 1e-6);
                    assert!(
                        hits.len() % 2 == 0 || tangent,
                        "odd crossings {:?} for {ray:?}",
                        hits.iter().map(|h| (h.t, h.u, h.part)).collect::<Vec<_>>()
                    );
                }
            }
        }
    }
}
