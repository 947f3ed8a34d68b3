//! Strands: a fiber given by a polyline of control points, turned into C2-continuous cubic
//! Bezier segments with continuous radii and twist, framed by a frame that follows the fiber
//! without spinning (or, on request, by Frenet's).

use std::f64::consts::TAU;

use glam::DVec3;

use crate::curve::CubicBezier;
use crate::cylinder::{GeneralizedCylinder, GeometryError};
use crate::frame::{Frame, FrameAt, Framing, PROJECTION_GOOD_SINE};
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
    /// Rotation of the section at the root and at the tip, radians, relative to the strand's
    /// frame.
    pub twist: [f64; 2],
    /// The cross section (default: the unit circle).
    pub section: Section,
}

/// How a strand's segments are framed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum StrandFraming {
    /// The default: a frame that follows the fiber without spinning, continuous across joints.
    ///
    /// A rotation-minimising frame (RMF) is propagated along the whole strand from the root
    /// (where it starts as the Frenet frame, or the fixed frame of a straight first segment)
    /// by the double-reflection method (Wang, Juettler, Zheng and Liu, *Computation of rotation
    /// minimizing frames*, ACM TOG 2008): from `(x_j, t_j, r_j)` to the next sample,
    /// `v1 = x_{j+1} - x_j`, `r_L = r_j - (2/v1.v1)(v1.r_j) v1`,
    /// `t_L = t_j - (2/v1.v1)(v1.t_j) v1`, `v2 = t_{j+1} - t_L`,
    /// `r_{j+1} = r_L - (2/v2.v2)(v2.r_L) v2`.
    /// Each segment gets a projection frame ([`Framing::Projected`], smooth on the segment: its
    /// reference is proven to keep at least 30 degrees from every tangent, or failing that
    /// [`Framing::projected_for_axis`]'s best, at least `asin(1e-3)`) turned about
    /// the tangent by a linear twist `phi(u) = phi0 + (phi1 - phi0) u`, where `phi0` and `phi1`
    /// are the angles of the RMF's normal in the projection frame at the segment's ends,
    /// unwrapped along the segment (`phi1 - phi0` is the projection frame's whole turn
    /// relative to the RMF, not only modulo `2 pi`). The twist is added to the sweep's
    /// rotation (`R(phi) R(theta) = R(phi + theta)`), so the intersector sees a projected frame
    /// and a hair sweep, both exact. The frame then equals the RMF at every joint (up to
    /// rounding: continuous across joints), is smooth within each segment, and turns about the
    /// tangent by the RMF's zero net rotation over each segment; within a segment it departs
    /// from the RMF only by the projection frame's non-uniform turn.
    #[default]
    RotationMinimizing,
    /// The Frenet frame of each segment (interface.md section 1; a straight segment takes its
    /// neighbour's normal as its hint). It spins through near-inflections, where the axis
    /// changes its bending direction, and an elliptical section with it.
    Frenet,
}

/// One segment of a strand: its cylinder, and how much of the cylinder's sweep rotation turns
/// the frame rather than the section.
#[derive(Clone, Debug, PartialEq)]
pub struct StrandSegment {
    /// The segment as a cylinder. Its sweep's rotation is the strand's twist plus
    /// `frame_twist`.
    pub cylinder: GeneralizedCylinder,
    /// `[phi0, phi1]`: the linear turn `phi(u)` about the tangent that takes the cylinder's
    /// frame to the strand's ([`StrandSegment::frame`]); `[0, 0]` for Frenet framing.
    pub frame_twist: [f64; 2],
}

impl StrandSegment {
    /// `phi(u)` and `phi'(u)`.
    fn twist_at(&self, u: f64) -> (f64, f64) {
        let [p0, p1] = self.frame_twist;
        (p0 + (p1 - p0) * u, p1 - p0)
    }

    /// The strand's frame at `u`: the cylinder's frame `(t, n_c, b_c)` turned about `t` by
    /// `phi(u)`, `n = cos(phi) n_c + sin(phi) b_c`, `b = -sin(phi) n_c + cos(phi) b_c`.
    pub fn frame(&self, u: f64) -> Frame {
        let f = self.cylinder.frame(u);
        let (s, c) = self.twist_at(u).0.sin_cos();
        Frame {
            t: f.t,
            n: c * f.n + s * f.b,
            b: c * f.b - s * f.n,
        }
    }

    /// The strand's frame at `u` with its derivatives in `u` ([`FrameAt::derivatives`]):
    /// `n' = phi' b + cos(phi) n_c' + sin(phi) b_c'`, `b' = -phi' n - sin(phi) n_c' + cos(phi)
    /// b_c'`, `t' = t_c'`.
    pub fn frame_at(&self, u: f64) -> FrameAt {
        let at = self.cylinder.frame_at(u);
        let [dt, dn, db] = at.derivatives();
        let (phi, dphi) = self.twist_at(u);
        let (s, c) = phi.sin_cos();
        let f = self.frame(u);
        FrameAt {
            frame: f,
            rates: Some([
                dt,
                dphi * f.b + c * dn + s * db,
                -dphi * f.n - s * dn + c * db,
            ]),
            ..at
        }
    }
}

/// Steps of the double-reflection method per segment, to start with: its error in the frame's
/// angle is of fourth order in the step (Wang et al. 2008), measured at 4e-7 rad after eleven
/// segments that turn by up to 1.2 rad each (a tight curl), 2e-11 on a gently wavy strand. A
/// segment is sampled four times more finely (up to [`RMF_MAX_STEPS`])
/// while the RMF's angle in the projection frame changes by more than [`RMF_MAX_JUMP`] between
/// samples, so the angle is unwrapped without skipping a turn.
const RMF_STEPS: usize = 16;
/// See [`RMF_STEPS`].
const RMF_MAX_STEPS: usize = 4096;
/// See [`RMF_STEPS`], radians.
const RMF_MAX_JUMP: f64 = 0.5;
/// A candidate reference whose linear twist stays this close to the RMF (radians, at the
/// samples) is taken without trying the others ([`Strand::fit_projection`]).
const FIT_ENOUGH: f64 = 5e-3;
/// Rounds of the pattern search of [`Strand::fit_projection`] (four trial references each).
const FIT_ROUNDS: usize = 3;

/// One segment's samples at `u = j / steps`, `j = 0..=steps`: points, unit tangents, the RMF's
/// normals and the RMF's angles in a projection frame. The buffers are reused from segment to
/// segment of a strand.
#[derive(Default)]
struct Samples {
    x: Vec<DVec3>,
    t: Vec<DVec3>,
    normals: Vec<DVec3>,
    psi: Vec<f64>,
}

impl Samples {
    /// Samples `axis` (points and tangents; the normals are [`Samples::propagate`]'s).
    /// Bernstein form: `a(u) = s^3 P0 + 3 s^2 u P1 + 3 s u^2 P2 + u^3 P3` and
    /// `a'(u) = s^2 H0 + 2 s u H1 + u^2 H2` with `s = 1 - u` and the hodograph's `H_i`.
    fn sample(&mut self, axis: &CubicBezier, steps: usize) {
        let p = axis.points;
        let h = axis.hodograph();
        let n = steps as f64;
        self.x.clear();
        self.t.clear();
        // Extended from a range: reserved once and written without a check per sample.
        self.x.extend((0..=steps).map(|j| {
            let u = j as f64 / n;
            let s = 1.0 - u;
            s * s * s * p[0] + 3.0 * s * u * (s * p[1] + u * p[2]) + u * u * u * p[3]
        }));
        self.t.extend((0..=steps).map(|j| {
            let u = j as f64 / n;
            let s = 1.0 - u;
            (s * s * h[0] + 2.0 * s * u * h[1] + u * u * h[2]).normalize()
        }));
    }

    fn steps(&self) -> usize {
        self.x.len() - 1
    }

    /// The unit normal of the plane through the origin nearest the tangents in the least-squares
    /// sense: the eigenvector of `M = sum_j t_j t_j^T` with the smallest eigenvalue, the
    /// largest of `tr(M) I - M` (positive semi-definite), by power iteration on its 32nd power
    /// (five squarings, each scaled to unit size), from `t_0 x t_last` (or any normal of
    /// `t_0`). Only a candidate: it need not be accurate where eigenvalues are close (the
    /// tangents then fit every such plane about as well).
    fn plane_normal(&self) -> DVec3 {
        // M and the powers of tr(M) I - M are symmetric: each is kept as its upper triangle
        // `[x00, x01, x02, x11, x12, x22]`, its entries computed as the full product would
        // compute them (the same products, summed in the same order).
        let m = self.t.iter().fold([0.0f64; 6], |m, t| {
            [
                m[0] + t.x * t.x,
                m[1] + t.x * t.y,
                m[2] + t.x * t.z,
                m[3] + t.y * t.y,
                m[4] + t.y * t.z,
                m[5] + t.z * t.z,
            ]
        });
        let trace = m[0] + m[3] + m[5];
        let mut q = [
            trace - m[0],
            0.0 - m[1],
            0.0 - m[2],
            trace - m[3],
            0.0 - m[4],
            trace - m[5],
        ];
        for _ in 0..5 {
            let [a, b, c, d, e, f] = q;
            q = [
                a * a + b * b + c * c,
                a * b + b * d + c * e,
                a * c + b * e + c * f,
                b * b + d * d + e * e,
                b * c + d * e + e * f,
                c * c + e * e + f * f,
            ];
            let size = q.iter().fold(0.0f64, |s, x| s.max(x.abs()));
            if !(size > 0.0) {
                break;
            }
            q = q.map(|x| x * (1.0 / size));
        }
        let times = |v: DVec3| {
            let [a, b, c, d, e, f] = q;
            DVec3::new(
                a * v.x + b * v.y + c * v.z,
                b * v.x + d * v.y + e * v.z,
                c * v.x + e * v.y + f * v.z,
            )
        };
        let (t0, t1) = (self.t[0], self.t[self.steps()]);
        let start = t0
            .cross(t1)
            .try_normalize()
            .unwrap_or(t0.any_orthonormal_vector());
        // Two products: a start nearly normal to the eigenvector is turned toward it.
        times(times(start) + start.any_orthonormal_vector() * 1e-3).normalize_or_zero()
    }

    /// The RMF's normals at the samples, from the unit normal `r0` at `u = 0` (normal to the
    /// tangent there), by double reflection (see [`StrandFraming::RotationMinimizing`]); each
    /// is made normal to its tangent again against rounding. (Reflections keep lengths, and
    /// that projection removes a part of the order of rounding, so the normals stay unit to
    /// rounding without being normalised.)
    fn propagate(&mut self, r0: DVec3) {
        self.normals.clear();
        self.normals.reserve(self.x.len());
        self.normals.push(r0);
        let mut r = r0;
        for (x, t) in self.x.windows(2).zip(self.t.windows(2)) {
            let v1 = x[1] - x[0];
            let c1 = v1.length_squared();
            let (mut rl, mut tl) = (r, t[0]);
            // Coincident samples (cannot happen on a cusp-free axis): no reflection.
            if c1 > 0.0 {
                rl -= (2.0 / c1) * v1.dot(r) * v1;
                tl -= (2.0 / c1) * v1.dot(t[0]) * v1;
            }
            let v2 = t[1] - tl;
            let c2 = v2.length_squared();
            // v2 = 0: the first reflection already maps t_j to t_{j+1}.
            if c2 > 0.0 {
                rl -= (2.0 / c2) * v2.dot(rl) * v2;
            }
            r = rl - rl.dot(t[1]) * t[1];
            self.normals.push(r);
        }
    }

    /// The angles `psi_j = arg z_j`, `z_j = (r_j.n_j, r_j.b_j)`, of the RMF's normals `r_j` in
    /// the projection frame of the reference `r` (`b = (t x r)/|t x r|`, `n = b x t`),
    /// unwrapped from sample to sample. `z_j` is taken times `|t x r|` (`c = t x r` for `b`,
    /// `c x t` for `n`), which leaves its argument alone.
    ///
    /// The increments `arg(z_j conj(z_{j-1}))` are taken by `atan(q)`, `q = Im/Re`, from its
    /// series `q - q^3/3 + q^5/5` where `Re > 0.9 |z_j conj(z_{j-1})|` (`|q| < 0.49`: error
    /// below `1e-3` rad, for the unwrapping, the jump and the deviation only), otherwise by
    /// `atan2`; the ends are exact: `psi_0 = atan2(z_0)`, and `psi_N` the value of `atan2(z_N)`
    /// plus the multiple of `2 pi` nearest the summed increments.
    fn fit(&mut self, r: DVec3) -> Angles {
        let z = |(t, rn): (&DVec3, &DVec3)| {
            let c = t.cross(r);
            (rn.dot(c.cross(*t)), rn.dot(c))
        };
        let steps = self.steps();
        let mut zs = self.t.iter().zip(&self.normals).map(z);
        let (x0, y0) = zs.next().unwrap_or_default();
        let first = y0.atan2(x0);
        let (mut prev, mut sum, mut jump) = ((x0, y0), 0.0, 0.0f64);
        let mut psi = std::mem::take(&mut self.psi);
        psi.clear();
        psi.reserve(steps + 1);
        psi.push(0.0);
        for (x, y) in zs {
            let (re, im) = (x * prev.0 + y * prev.1, y * prev.0 - x * prev.1);
            let d = if re > 0.0 && re * re > 0.81 * (re * re + im * im) {
                let q = im / re;
                let q2 = q * q;
                q * (1.0 - q2 * (1.0 / 3.0 - q2 / 5.0))
            } else {
                im.atan2(re)
            };
            sum += d;
            jump = jump.max(d.abs());
            psi.push(sum);
            prev = (x, y);
        }
        let last_raw = prev.1.atan2(prev.0);
        let total = last_raw - first + TAU * ((first + sum - last_raw) / TAU).round();
        let deviation = psi
            .iter()
            .enumerate()
            .map(|(j, p)| (p - sum * j as f64 / steps as f64).abs())
            .fold(0.0f64, f64::max);
        self.psi = psi;
        Angles {
            first,
            total,
            jump,
            deviation,
        }
    }
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
    /// the root and ends at the tip: segment `i` is [`spline_segment`] of
    /// `Q_{i-1}, Q_i, Q_{i+1}, Q_{i+2}` (four consecutive [`Strand::spline_controls`]).
    /// Consecutive segments share position, first and second derivatives, so the Frenet frame
    /// is continuous across joints.
    pub fn bezier_segments(&self) -> Vec<CubicBezier> {
        self.spline_controls()
            .windows(4)
            .map(|w| spline_segment([w[0], w[1], w[2], w[3]]))
            .collect()
    }

    /// The B-spline's control points with the reflected ends, `Q_{-1}, Q_0, .., Q_{n-1}, Q_n`
    /// (`n + 2` for `n >= 2` points, one segment for every window of four; none for fewer
    /// than two points).
    pub fn spline_controls(&self) -> Vec<DVec3> {
        let q = &self.points;
        let n = q.len();
        if n < 2 {
            return Vec::new();
        }
        let mut out = Vec::with_capacity(n + 2);
        out.push(2.0 * q[0] - q[1]);
        out.extend_from_slice(q);
        out.push(2.0 * q[n - 1] - q[n - 2]);
        out
    }

    /// Its radii along it ([`Strand::segments`] gives its segments these).
    pub fn taper(&self) -> Taper {
        Taper {
            radius: self.radius,
            ellipticity: self.ellipticity,
        }
    }

    /// The strand as cylinders, framed by [`StrandFraming::RotationMinimizing`] (see
    /// [`Strand::segments`]).
    pub fn cylinders(&self) -> Result<Vec<GeneralizedCylinder>, (usize, GeometryError)> {
        self.cylinders_with(StrandFraming::default())
    }

    /// The strand as cylinders with the given framing (see [`Strand::segments`]).
    pub fn cylinders_with(
        &self,
        framing: StrandFraming,
    ) -> Result<Vec<GeneralizedCylinder>, (usize, GeometryError)> {
        Ok(self
            .segments(framing)?
            .into_iter()
            .map(|s| s.cylinder)
            .collect())
    }

    /// The strand's segments: radii and twist interpolated linearly along the segments, caps
    /// only at the root and the tip, framed as `framing` says. With
    /// [`StrandFraming::Frenet`] a straight segment takes the frame of its nearest curved
    /// neighbour (as its normal hint), so the section does not jump at the joint. The error
    /// names the segment.
    pub fn segments(
        &self,
        framing: StrandFraming,
    ) -> Result<Vec<StrandSegment>, (usize, GeometryError)> {
        let segs = self.bezier_segments();
        let k = segs.len();
        let mut out: Vec<StrandSegment> = Vec::with_capacity(k);
        // The RMF's normal at the start of the next segment.
        let mut r = DVec3::ZERO;
        let mut samples = Samples::default();
        for (i, seg) in segs.iter().enumerate() {
            let (major, minor) = self.taper().radii(i, k);
            let sweep = HairSweep {
                major,
                minor,
                rotation: [i, i + 1].map(|j| along_strand(self.twist, j, k)),
            };
            let (start, end) = (i == 0, i + 1 == k);
            let segment = match framing {
                StrandFraming::Frenet => {
                    let hint = out.last().map(|prev| prev.cylinder.frame(1.0).n);
                    let cyl =
                        GeneralizedCylinder::new(*seg, self.section.clone(), sweep, true, hint)
                            .map_err(|e| (i, e))?;
                    StrandSegment {
                        cylinder: cyl.with_caps(start, end),
                        frame_twist: [0.0, 0.0],
                    }
                }
                StrandFraming::RotationMinimizing => {
                    // The cylinder works relative to its first control point: so does this.
                    let local = seg.translated(seg.points[0]);
                    if i == 0 {
                        let f = Framing::for_axis(&local, None).unwrap_or(Framing::Frenet);
                        r = FrameAt::new(&local, &f, 0.0).frame.n;
                    }
                    let fitted = Self::fit_projection(&local, r, &mut samples);
                    let built = fitted.and_then(|(framing, twist, end_normal)| {
                        r = end_normal;
                        let sweep = HairSweep {
                            rotation: [sweep.rotation[0] + twist[0], sweep.rotation[1] + twist[1]],
                            ..sweep
                        };
                        // The reference was certified when fit_projection chose it.
                        GeneralizedCylinder::with_checked_framing(
                            *seg,
                            self.section.clone(),
                            sweep,
                            true,
                            framing,
                        )
                        .ok()
                        .map(|cyl| StrandSegment {
                            cylinder: cyl.with_caps(start, end),
                            frame_twist: twist,
                        })
                    });
                    match built {
                        Some(s) => s,
                        // Why: the geometry's own error if it has one (a cusp, say, which also
                        // defeats the frame), else the frame's.
                        None => {
                            let e = GeneralizedCylinder::new(
                                *seg,
                                self.section.clone(),
                                sweep,
                                true,
                                None,
                            )
                            .err()
                            .unwrap_or_else(|| {
                                GeometryError::BadFraming(
                                    "no projection reference keeps away from the segment's tangents"
                                        .into(),
                                )
                            });
                            return Err((i, e));
                        }
                    }
                }
            };
            out.push(segment);
        }
        Ok(out)
    }

    /// The projection framing of one segment (`axis` relative to its first control point),
    /// given the RMF's unit normal `r0` at its start: the framing, the twist `[phi0, phi1]` that
    /// turns it into the RMF at both ends, and the RMF's normal at the end. `None` if the RMF or
    /// the angles are not finite, or no reference keeps away from the tangents.
    ///
    /// The reference `r` sets how far the frame departs from the RMF inside the segment. In
    /// spherical coordinates about `r` (`beta` the angle of `t` from `r`, `lambda` its azimuth),
    /// the projection frame turns against the RMF at the rate `psi' = cos(beta) lambda'`
    /// (parallel transport on the sphere of tangents), and the linear twist follows `psi`
    /// exactly when that rate is constant: so `r` is best nearly normal to all the tangents
    /// (`cos(beta)` small; for a planar arc the plane's normal makes the projection frame the
    /// RMF), or their cone's axis (a helix). The candidates: the normal of the plane through
    /// the origin that fits the tangent samples best (least squares: the eigenvector of
    /// `sum t_j t_j^T` with the smallest eigenvalue), the Darboux vector `tau t + kappa b` at
    /// `u = 1/2` (the axis the Frenet frame turns about; a helix's axis) and the RMF's normal
    /// at the middle. Of those that keep at least 30 degrees from every tangent
    /// ([`Framing::projection_sine`] `>= 1/2`) the one whose `psi` departs least from its chord
    /// at the samples is taken, and improved by a short pattern search on the sphere while
    /// that departure exceeds [`FIT_ENOUGH`]. Without a candidate,
    /// [`Framing::projected_for_axis`] chooses.
    fn fit_projection(
        axis: &CubicBezier,
        r0: DVec3,
        samples: &mut Samples,
    ) -> Option<(Framing, [f64; 2], DVec3)> {
        let t0 = axis.d1(0.0).normalize();
        // Normal to the tangent here: the previous segment's end tangent agrees to rounding.
        let r0 = (r0 - r0.dot(t0) * t0).normalize();
        let darboux = {
            let (d1, d2) = (axis.d1(0.5), axis.d2(0.5));
            let c = d1.cross(d2);
            // |a'|^3 (tau t + kappa b) = |a'|^2 (c.a''' / |c|^2) a' + c.
            let w =
                d1.length_squared() * c.dot(axis.third_derivative()) / c.length_squared() * d1 + c;
            w.normalize_or_zero()
        };
        let good = |r: DVec3| Framing::projection_sine_at_least(axis, r, PROJECTION_GOOD_SINE);
        let mut steps = RMF_STEPS;
        loop {
            samples.sample(axis, steps);
            samples.propagate(r0);
            let mid = samples.normals[steps / 2];
            let mut best: Option<(DVec3, Angles)> = None;
            for r in [samples.plane_normal(), darboux, mid] {
                if best.as_ref().is_some_and(|b| b.1.deviation <= FIT_ENOUGH) {
                    break;
                }
                if !good(r) {
                    continue;
                }
                let a = samples.fit(r);
                if best.as_ref().is_none_or(|b| a.deviation < b.1.deviation) {
                    best = Some((r, a));
                }
            }
            let (r, a) = match best {
                Some((mut r, mut a)) => {
                    // Pattern search: the best of r +- h e1, r +- h e2 (normalised; e1, e2 normal
                    // to r) replaces r while it is better; h halves when none is.
                    let (mut h, mut rounds) = (0.1, 0);
                    while a.deviation > FIT_ENOUGH && rounds < FIT_ROUNDS {
                        rounds += 1;
                        let e1 = r.any_orthonormal_vector();
                        let e2 = r.cross(e1);
                        let step = [e1, -e1, e2, -e2]
                            .into_iter()
                            .map(|e| (r + h * e).normalize())
                            .map(|q| (q, samples.fit(q)))
                            .filter(|(_, b)| b.deviation < a.deviation)
                            .min_by(|x, y| x.1.deviation.total_cmp(&y.1.deviation));
                        match step {
                            Some((q, b)) if good(q) => (r, a) = (q, b),
                            _ => h *= 0.5,
                        }
                    }
                    (r, a)
                }
                None => {
                    let ends = [mid, samples.normals[0], samples.normals[steps]];
                    let Framing::Projected(r) = Framing::projected_for_axis(axis, &ends)? else {
                        return None;
                    };
                    (r, samples.fit(r))
                }
            };
            if !(a.jump > RMF_MAX_JUMP) || steps >= RMF_MAX_STEPS {
                let twist = [a.first, a.first + a.total];
                let end = samples.normals[steps];
                return (twist.iter().all(|x| x.is_finite()) && end.is_finite()).then_some((
                    Framing::Projected(r),
                    twist,
                    end,
                ));
            }
            steps *= 4;
        }
    }
}

/// `x0 + (x1 - x0) s` at `s = j / k`: a strand's radius or twist where its segment `j` of `k`
/// starts (the one formula for both, so that a store rebuilding a segment's radii from its
/// strand's gets the bits [`Strand::segments`] made).
#[inline]
pub fn along_strand([x0, x1]: [f64; 2], j: usize, k: usize) -> f64 {
    x0 + (x1 - x0) * (j as f64 / k as f64)
}

/// A strand's radii: the major one linear from root to tip ([`along_strand`]), the minor one
/// the major times the ellipticity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Taper {
    /// The major radius at the root and at the tip.
    pub radius: [f64; 2],
    /// Minor over major radius.
    pub ellipticity: f64,
}

impl Taper {
    /// The major and minor radii at the start and end of segment `j` of `k`.
    #[inline]
    pub fn radii(&self, j: usize, k: usize) -> ([f64; 2], [f64; 2]) {
        let major = [j, j + 1].map(|j| along_strand(self.radius, j, k));
        (major, major.map(|r| r * self.ellipticity))
    }
}

/// The Bezier form of the uniform cubic B-spline segment over the control points
/// `a, b, c, d`: `(a + 4 b + c) / 6`, `(2 b + c) / 3`, `(b + 2 c) / 3`, `(b + 4 c + d) / 6`
/// (each rounded as written, so a segment can be rebuilt to the bit from its four points).
#[inline]
pub fn spline_segment([a, b, c, d]: [DVec3; 4]) -> CubicBezier {
    CubicBezier::new([
        (a + 4.0 * b + c) / 6.0,
        (2.0 * b + c) / 3.0,
        (b + 2.0 * c) / 3.0,
        (b + 4.0 * c + d) / 6.0,
    ])
}

/// The RMF's angle `psi` in a projection frame along a segment (see [`Samples::fit`]).
struct Angles {
    /// `psi(0)`, in `[-pi, pi]`.
    first: f64,
    /// `psi(1) - psi(0)`, unwrapped.
    total: f64,
    /// The largest change between samples.
    jump: f64,
    /// The largest `|psi - chord|` at the samples.
    deviation: f64,
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

    /// A curly strand through points on a helix whose axis bends: elliptical, twisted, tapering.
    fn curly() -> Strand {
        let pts: Vec<DVec3> = (0..12)
            .map(|k| {
                let a = 1.1 * k as f64;
                DVec3::new(
                    0.25 * a.cos() + 0.02 * (k * k) as f64,
                    -0.18 * k as f64,
                    0.25 * a.sin(),
                )
            })
            .collect();
        Strand {
            points: Strand::interpolating_control_points(&pts),
            radius: [0.04, 0.025],
            ellipticity: 0.45,
            twist: [0.3, 2.5],
            section: Section::default(),
        }
    }

    /// An S-shaped (wavy) strand, nearly planar: its axis changes its bending direction at every
    /// half wave, through near-inflections where the Frenet frame spins half round.
    fn wavy() -> Strand {
        let pts: Vec<DVec3> = (0..13)
            .map(|k| {
                let x = 0.3 * k as f64;
                DVec3::new(x, 0.35 * (2.1 * x).sin(), 0.04 * (0.7 * x).sin())
            })
            .collect();
        Strand {
            points: Strand::interpolating_control_points(&pts),
            radius: [0.04, 0.04],
            ellipticity: 0.5,
            twist: [0.0, 0.0],
            section: Section::default(),
        }
    }

    /// The rotation-minimising frame by another method than the library's double reflection:
    /// the ODE `r'(u) = -(r . t'(u)) t(u)` (r stays normal to t and does not turn about it),
    /// `t' = (a'' - (a''.t) t) / |a'|`, by the classical Runge-Kutta method with `steps` steps
    /// per segment, from `r0` at the root. Returns `r` at `u = j / samples` of each segment.
    fn rk4_rmf(segs: &[CubicBezier], r0: DVec3, steps: usize, samples: usize) -> Vec<Vec<DVec3>> {
        let field = |c: &CubicBezier, u: f64, r: DVec3| {
            let d1 = c.d1(u);
            let t = d1.normalize();
            let d2 = c.d2(u);
            let dt = (d2 - d2.dot(t) * t) / d1.length();
            -r.dot(dt) * t
        };
        let mut r = r0;
        let mut out = Vec::new();
        for c in segs {
            let mut at = vec![r];
            let h = 1.0 / steps as f64;
            for j in 0..steps {
                let u = j as f64 * h;
                let k1 = field(c, u, r);
                let k2 = field(c, u + 0.5 * h, r + 0.5 * h * k1);
                let k3 = field(c, u + 0.5 * h, r + 0.5 * h * k2);
                let k4 = field(c, u + h, r + h * k3);
                r += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
                if (j + 1) % (steps / samples) == 0 {
                    at.push(r);
                }
            }
            out.push(at);
        }
        out
    }

    /// The default (rotation-minimising) frame is orthonormal and continuous across joints, and
    /// so is the surface: frames agree to 1e-12 and surface points to 1e-12 of the fiber's size
    /// at every joint of a curly, twisted, elliptical strand; and the frame is smooth within a
    /// segment (its change over 1e-3 in u stays of the order of 1e-3).
    #[test]
    fn rotation_minimising_frame_is_continuous_across_joints() {
        let s = curly();
        let segs = s.segments(StrandFraming::RotationMinimizing).unwrap();
        assert_eq!(segs.len(), 11, "one segment per span");
        let (mut frame_jump, mut surface_jump) = (0.0f64, 0.0f64);
        for (i, seg) in segs.iter().enumerate() {
            assert!(
                matches!(seg.cylinder.framing(), Framing::Projected(_)),
                "segment {i} is projected"
            );
            for j in 0..=100 {
                let u = j as f64 / 100.0;
                let f = seg.frame(u);
                assert!((f.n.length() - 1.0).abs() < 1e-14, "unit n at {i}, {u}");
                assert!(f.n.dot(f.t).abs() < 1e-14, "n normal to t at {i}, {u}");
                assert!(
                    (f.n.cross(f.b) - f.t).length() < 1e-14,
                    "n x b = t at {i}, {u}"
                );
                let g = seg.frame((u + 1e-3).min(1.0));
                assert!((g.n - f.n).length() < 0.05, "smooth at {i}, {u}");
            }
        }
        for w in segs.windows(2) {
            let (a, b) = (w[0].frame(1.0), w[1].frame(0.0));
            frame_jump = frame_jump
                .max((a.t - b.t).length())
                .max((a.n - b.n).length())
                .max((a.b - b.b).length());
            for j in 0..16 {
                let v = j as f64 * std::f64::consts::TAU / 16.0;
                let gap = (w[0].cylinder.surface_point(1.0, v)
                    - w[1].cylinder.surface_point(0.0, v))
                .length();
                surface_jump = surface_jump.max(gap);
            }
        }
        eprintln!("[strand] max frame jump at joints {frame_jump:.1e}, surface {surface_jump:.1e}");
        assert!(frame_jump < 1e-12, "frame jump at a joint: {frame_jump:e}");
        assert!(
            surface_jump < 1e-12,
            "surface gap at a joint: {surface_jump:e}"
        );
    }

    /// The default frame is the rotation-minimising frame at every joint, against an RMF
    /// integrated independently (Runge-Kutta on its ODE, 4000 steps per segment, error far
    /// below 1e-12): within 2e-6 rad, the double reflection's error at 16 steps per segment
    /// (measured 4e-7 on the curly strand, whose segments turn by up to 1.2 rad, 2e-11 on the
    /// wavy one); and within 0.03 rad inside the segments, where only the projection frame's
    /// non-uniform turn against the RMF separates them (measured 1.3e-2 and 1.5e-5).
    #[test]
    fn rotation_minimising_frame_matches_an_integrated_rmf() {
        for (name, s) in [("curly", curly()), ("wavy", wavy())] {
            let segs = s.segments(StrandFraming::RotationMinimizing).unwrap();
            let beziers = s.bezier_segments();
            let samples = 20;
            let rmf = rk4_rmf(&beziers, segs[0].frame(0.0).n, 4000, samples);
            let (mut at_joints, mut inside) = (0.0f64, 0.0f64);
            for (seg, r) in segs.iter().zip(&rmf) {
                for (j, rj) in r.iter().enumerate() {
                    let u = j as f64 / samples as f64;
                    let n = seg.frame(u).n;
                    let angle = n.cross(*rj).length().asin();
                    if j == 0 || j == samples {
                        at_joints = at_joints.max(angle);
                    } else {
                        inside = inside.max(angle);
                    }
                }
            }
            eprintln!(
                "[strand] {name}: angle to the integrated RMF: {at_joints:.1e} rad at joints, {inside:.1e} inside"
            );
            assert!(at_joints < 2e-6, "{name}: at the joints {at_joints:e}");
            assert!(inside < 0.03, "{name}: inside the segments {inside:e}");
        }
    }

    /// On the S-shaped strand the Frenet frame spins: its total turn about the tangent,
    /// `int |n'.b| du` over the strand, is several half turns, all at the near-inflections,
    /// while the default frame's is more than ten times smaller. (Both from the frames' exact
    /// derivatives; the default frame's `n'.b` is the projection frame's turn plus the
    /// constant rate of the twist, zero on average over each segment. Sampled at 4000 points
    /// per segment: the Frenet frame's turns are about 0.05 wide in u here.) The Frenet option
    /// builds the old segments, Frenet-framed with no frame twist.
    #[test]
    fn frenet_frame_spins_far_more_than_the_default_on_an_s_strand() {
        let s = wavy();
        let spin = |segs: &[StrandSegment]| {
            let m = 4000;
            let mut total = 0.0;
            for seg in segs {
                for j in 0..m {
                    let at = seg.frame_at((j as f64 + 0.5) / m as f64);
                    total += at.derivatives()[1].dot(at.frame.b).abs() / m as f64;
                }
            }
            total
        };
        let frenet = s.segments(StrandFraming::Frenet).unwrap();
        let minimal = s.segments(StrandFraming::RotationMinimizing).unwrap();
        let (sf, sm) = (spin(&frenet), spin(&minimal));
        eprintln!(
            "[strand] wavy strand: total turn about t, Frenet {sf:.3} rad, default {sm:.4} rad"
        );
        assert!(
            sf > 1.6 * std::f64::consts::PI,
            "the Frenet frame spins, nearly half round at each of the two near-inflections ({sf})"
        );
        assert!(sm * 10.0 < sf, "the default frame does not ({sm} vs {sf})");
        for (i, (f, seg)) in frenet.iter().zip(s.bezier_segments()).enumerate() {
            assert_eq!(
                f.cylinder.framing(),
                &Framing::Frenet,
                "segment {i}: Frenet"
            );
            assert_eq!(f.frame_twist, [0.0, 0.0], "segment {i}: no frame twist");
            assert!(
                (f.cylinder.axis().points[3] - seg.points[3]).length() < 1e-15,
                "segment {i}: same axis"
            );
        }
        assert_eq!(
            s.cylinders_with(StrandFraming::Frenet).unwrap()[3],
            frenet[3].cylinder,
            "cylinders_with gives the segments' cylinders"
        );
        assert_eq!(
            s.cylinders().unwrap()[3],
            minimal[3].cylinder,
            "the default is rotation-minimising"
        );
    }

    /// A strand with straight segments (collinear points) and a straight root: the default
    /// frame needs no normal hint (the projection frame is defined on straight segments) and
    /// stays continuous; the segments are projected, straight ones included.
    #[test]
    fn straight_spans_get_the_default_frame_too() {
        let s = Strand {
            points: vec![
                DVec3::ZERO,
                DVec3::new(0.0, 1.0, 0.0),
                DVec3::new(0.0, 2.0, 0.0),
                DVec3::new(0.0, 3.0, 0.0),
                DVec3::new(0.5, 3.8, 0.2),
                DVec3::new(1.2, 4.0, 0.7),
            ],
            radius: [0.05, 0.03],
            ellipticity: 0.5,
            twist: [0.0, 1.0],
            section: Section::default(),
        };
        let segs = s.segments(StrandFraming::RotationMinimizing).unwrap();
        for w in segs.windows(2) {
            let (a, b) = (w[0].frame(1.0), w[1].frame(0.0));
            assert!((a.n - b.n).length() < 1e-12, "continuous: {a:?} vs {b:?}");
        }
        assert!(
            segs.iter()
                .all(|s| matches!(s.cylinder.framing(), Framing::Projected(_))),
            "all projected"
        );
    }
}
