use std::f64::consts::TAU;
use std::sync::Arc;

use glam::DVec2;
use polycool::Cubic;

use super::implicit::PieceImplicit;
use super::{CrossSection, LineCrossings};
use crate::real::{Real, V2};

/// A closed piecewise-cubic Bezier profile: `k` cubic pieces, piece `i` running from anchor
/// `P_i` through controls `C_i`, `D_i` to the next anchor `P_{(i+1) mod k}`.
///
/// The parameter `v in [0, 2 pi)` runs uniformly over the pieces: piece `i` covers
/// `[2 pi i / k, 2 pi (i+1) / k)`.
///
/// In a scene, `profile = [[x, y], ...]` lists `3k` points `P_0, C_0, D_0, P_1, C_1, D_1, ...`.
///
/// Shared, not copied, between the fibers that use it (a clone is a reference count): a
/// cylinder holds one pointer for its section.
#[derive(Clone, Debug, PartialEq)]
pub struct BezierLoop(Arc<LoopData>);

/// A [`BezierLoop`]'s pieces, their implicit equations, orientation (the sign of its area) and
/// bounding radius.
#[derive(Debug, PartialEq)]
struct LoopData {
    pieces: Vec<[DVec2; 4]>,
    implicit: Vec<Option<PieceImplicit>>,
    orientation: f64,
    radius: f64,
}

/// Why a list of points is not a usable profile.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ProfileError {
    /// The point count is not a positive multiple of 3.
    #[error("a profile needs 3k points (anchor, control, control per piece), got {0}")]
    Count(usize),
    /// A coordinate is NaN or infinite.
    #[error("profile point {0} is not finite")]
    NotFinite(usize),
    /// The loop encloses no area.
    #[error("the profile encloses no area")]
    NoArea,
}

impl BezierLoop {
    /// The loop through `3k` points `P_0, C_0, D_0, P_1, ...` (see the type's docs).
    pub fn new(points: &[DVec2]) -> Result<Self, ProfileError> {
        if points.is_empty() || !points.len().is_multiple_of(3) {
            return Err(ProfileError::Count(points.len()));
        }
        if let Some(i) = points.iter().position(|p| !p.is_finite()) {
            return Err(ProfileError::NotFinite(i));
        }
        let k = points.len() / 3;
        let pieces: Vec<[DVec2; 4]> = (0..k)
            .map(|i| {
                [
                    points[3 * i],
                    points[3 * i + 1],
                    points[3 * i + 2],
                    points[(3 * i + 3) % points.len()],
                ]
            })
            .collect();
        // Signed area by Green's theorem, exact for cubic pieces:
        // A = sum over pieces of (1/2) integral (x y' - y x') ds (here by 16-point Gauss rule,
        // exact for the degree-5 integrand).
        let area: f64 = pieces
            .iter()
            .map(|p| 0.5 * gauss16(|s| cross(eval(p, s), deriv(p, s))))
            .sum();
        let radius = pieces
            .iter()
            .flatten()
            .map(|p| p.length())
            .fold(0.0, f64::max);
        if !(area.abs() > 1e-12 * radius * radius) {
            return Err(ProfileError::NoArea);
        }
        let implicit = pieces.iter().map(PieceImplicit::new).collect();
        Ok(BezierLoop(Arc::new(LoopData {
            pieces,
            implicit,
            orientation: area.signum(),
            radius,
        })))
    }

    /// An identity of the shared data, equal for clones of one loop (to count its memory once).
    pub fn storage_id(&self) -> usize {
        Arc::as_ptr(&self.0) as usize
    }

    /// Bytes of the shared data (counted once for all clones).
    pub fn storage_bytes(&self) -> usize {
        size_of::<LoopData>()
            + size_of_val(self.0.pieces.as_slice())
            + size_of_val(self.0.implicit.as_slice())
    }

    /// The four-piece cubic approximation of the unit circle (control distance
    /// `4/3 (sqrt 2 - 1)`), radial error below 2.8e-4.
    pub fn circle_approximation() -> Self {
        let k = 4.0 / 3.0 * (2f64.sqrt() - 1.0);
        let pts: Vec<DVec2> = (0..4)
            .flat_map(|i| {
                let r = |p: DVec2| rot90(p, i);
                [
                    r(DVec2::new(1.0, 0.0)),
                    r(DVec2::new(1.0, k)),
                    r(DVec2::new(k, 1.0)),
                ]
            })
            .collect();
        BezierLoop::new(&pts).expect("the circle approximation is a valid loop")
    }

    /// The same loop with no piece's implicit equation: the General method then searches every
    /// piece by the curve-curve subdivision (the tests' second method).
    #[cfg(test)]
    pub(crate) fn subdivided_only(&self) -> Self {
        BezierLoop(Arc::new(LoopData {
            pieces: self.0.pieces.clone(),
            implicit: vec![None; self.0.pieces.len()],
            orientation: self.0.orientation,
            radius: self.0.radius,
        }))
    }

    /// The cubic pieces.
    pub fn pieces(&self) -> &[[DVec2; 4]] {
        &self.0.pieces
    }

    fn locate(&self, v: f64) -> (usize, f64) {
        let k = self.0.pieces.len();
        let x = (v / TAU).rem_euclid(1.0) * k as f64;
        let i = (x.floor() as usize).min(k - 1);
        (i, x - i as f64)
    }

    fn v_of(&self, i: usize, s: f64) -> f64 {
        let v = (i as f64 + s) / self.0.pieces.len() as f64 * TAU;
        if v >= TAU { 0.0 } else { v }
    }

    /// `sum_i (cross(dir, B_i(s) - p))` as a cubic in `s`, for each piece.
    fn cross_cubic(piece: &[DVec2; 4], p: DVec2, dir: DVec2) -> Cubic {
        let [c0, c1, c2, c3] = power(piece);
        Cubic::new([
            cross(dir, c0 - p),
            cross(dir, c1),
            cross(dir, c2),
            cross(dir, c3),
        ])
    }
}

fn rot90(p: DVec2, times: usize) -> DVec2 {
    (0..times).fold(p, |q, _| DVec2::new(-q.y, q.x))
}

fn cross(a: DVec2, b: DVec2) -> f64 {
    a.x * b.y - a.y * b.x
}

/// Power-basis coefficients `c0 + c1 s + c2 s^2 + c3 s^3` of a cubic Bezier.
pub(super) fn power(p: &[DVec2; 4]) -> [DVec2; 4] {
    [
        p[0],
        3.0 * (p[1] - p[0]),
        3.0 * (p[2] - 2.0 * p[1] + p[0]),
        p[3] - 3.0 * p[2] + 3.0 * p[1] - p[0],
    ]
}

fn eval(p: &[DVec2; 4], s: f64) -> DVec2 {
    let t = 1.0 - s;
    t * t * t * p[0] + 3.0 * s * t * t * p[1] + 3.0 * s * s * t * p[2] + s * s * s * p[3]
}

fn deriv(p: &[DVec2; 4], s: f64) -> DVec2 {
    let t = 1.0 - s;
    3.0 * (t * t * (p[1] - p[0]) + 2.0 * s * t * (p[2] - p[1]) + s * s * (p[3] - p[2]))
}

fn gauss16(f: impl Fn(f64) -> f64) -> f64 {
    // 8-point Gauss-Legendre on [0, 1], applied on two halves.
    const X: [f64; 4] = [
        0.1834346424956498,
        0.525_532_409_916_329,
        0.7966664774136267,
        0.9602898564975363,
    ];
    const W: [f64; 4] = [
        0.362_683_783_378_362,
        0.313_706_645_877_887_3,
        0.2223810344533745,
        0.1012285362903763,
    ];
    let mut sum = 0.0;
    for (a, b) in [(0.0, 0.5), (0.5, 1.0)] {
        let (m, h) = (0.5 * (a + b), 0.5 * (b - a));
        for k in 0..4 {
            sum += W[k] * h * (f(m + h * X[k]) + f(m - h * X[k]));
        }
    }
    sum
}

/// Root tolerance in the piece parameter `s` before Newton polishing.
const S_TOL: f64 = 1e-13;

impl CrossSection for BezierLoop {
    fn point(&self, v: f64) -> DVec2 {
        let (i, s) = self.locate(v);
        eval(&self.0.pieces[i], s)
    }

    /// The cubic of the piece holding `v.value()` at `s = (v - v_i) k / (2 pi)`, in Bernstein form.
    fn point_r<T: Real>(&self, v: T) -> V2<T> {
        let (i, _) = self.locate(v.value());
        let k = self.0.pieces.len() as f64;
        let s = (v - T::cst(i as f64 / k * TAU)).scale(k / TAU);
        let t = T::cst(1.0) - s;
        let p = &self.0.pieces[i];
        let w = [
            t * t * t,
            (s * t * t).scale(3.0),
            (s * s * t).scale(3.0),
            s * s * s,
        ];
        let c = |f: fn(DVec2) -> f64| {
            w[0].scale(f(p[0])) + w[1].scale(f(p[1])) + w[2].scale(f(p[2])) + w[3].scale(f(p[3]))
        };
        V2::new(c(|q| q.x), c(|q| q.y))
    }

    /// `d cs / d v = B_i'(s) * k / (2 pi)`.
    fn derivative(&self, v: f64) -> DVec2 {
        let (i, s) = self.locate(v);
        deriv(&self.0.pieces[i], s) * (self.0.pieces.len() as f64 / TAU)
    }

    /// Winding number of the loop about `p`, counted along the ray `p + (x, 0)`, `x > 0`.
    fn contains(&self, p: DVec2) -> bool {
        let mut winding = 0i32;
        for piece in &self.0.pieces {
            let [c0, c1, c2, c3] = power(piece);
            let y = Cubic::new([c0.y - p.y, c1.y, c2.y, c3.y]);
            for s in y.roots_between(0.0, 1.0, S_TOL) {
                // Half-open [0, 1): a crossing at a shared anchor counts once.
                if s >= 1.0 || eval(piece, s).x <= p.x {
                    continue;
                }
                let dy = deriv(piece, s).y;
                winding += if dy > 0.0 {
                    1
                } else if dy < 0.0 {
                    -1
                } else {
                    0
                };
            }
        }
        winding != 0 || self.on_boundary(p)
    }

    fn bounding_radius(&self) -> f64 {
        self.0.radius
    }

    fn intersect_line(&self, p: DVec2, dir: DVec2) -> LineCrossings {
        let mut out = LineCrossings::new();
        let d2 = dir.length_squared();
        for (i, piece) in self.0.pieces.iter().enumerate() {
            for s in Self::cross_cubic(piece, p, dir).roots_between(0.0, 1.0, S_TOL) {
                if s >= 1.0 || out.is_full() {
                    continue;
                }
                let q = eval(piece, s);
                out.push(((q - p).dot(dir) / d2, self.v_of(i, s)));
            }
        }
        out
    }

    fn monotone_breaks(&self) -> Vec<f64> {
        let mut breaks = Vec::new();
        for (i, piece) in self.0.pieces.iter().enumerate() {
            let [_, c1, c2, c3] = power(piece);
            let mut ss = vec![0.0];
            // x'(s), y'(s): quadratics; inflections: x' y'' - y' x'', a polynomial of degree <= 2
            // (the cubic terms cancel) written here as a cubic for uniformity.
            let qx = Cubic::new([c1.x, 2.0 * c2.x, 3.0 * c3.x, 0.0]);
            let qy = Cubic::new([c1.y, 2.0 * c2.y, 3.0 * c3.y, 0.0]);
            let cross_poly = inflection_poly(c1, c2, c3);
            for poly in [qx, qy, cross_poly] {
                ss.extend(
                    poly.roots_between(0.0, 1.0, S_TOL)
                        .into_iter()
                        .filter(|&s| s > 1e-12 && s < 1.0 - 1e-12),
                );
            }
            ss.sort_by(f64::total_cmp);
            ss.dedup_by(|a, b| (*a - *b).abs() < 1e-12);
            breaks.extend(
                ss.into_iter()
                    .map(|s| (i as f64 + s) / self.0.pieces.len() as f64 * TAU),
            );
        }
        breaks.push(TAU);
        breaks
    }

    fn orientation(&self) -> f64 {
        self.0.orientation
    }

    fn implicit_pieces(&self) -> &[Option<PieceImplicit>] {
        &self.0.implicit
    }
}

/// `B'(s) x B''(s)` for `B = c0 + c1 s + c2 s^2 + c3 s^3`:
/// `B' = c1 + 2 c2 s + 3 c3 s^2`, `B'' = 2 c2 + 6 c3 s`, so
/// `B' x B'' = 2 (c1 x c2) + 6 (c1 x c3) s + 6 (c2 x c3) s^2` (the `s^3` terms cancel).
fn inflection_poly(c1: DVec2, c2: DVec2, c3: DVec2) -> Cubic {
    Cubic::new([
        2.0 * cross(c1, c2),
        6.0 * cross(c1, c3),
        6.0 * cross(c2, c3),
        0.0,
    ])
}

impl BezierLoop {
    fn on_boundary(&self, p: DVec2) -> bool {
        // Cheap exact-boundary check for points on an anchor.
        self.0.pieces.iter().any(|piece| piece[0] == p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn circle_approximation_is_close_to_the_circle() {
        let c = BezierLoop::circle_approximation();
        assert_eq!(c.orientation(), 1.0, "counter-clockwise");
        for i in 0..400 {
            let v = i as f64 / 400.0 * TAU;
            let r = c.point(v).length();
            assert!(
                (r - 1.0).abs() < 2.8e-4,
                "radial error {} at v={v}",
                r - 1.0
            );
            // Derivative against a central difference.
            let h = 1e-6;
            let fd = (c.point(v + h) - c.point(v - h)) / (2.0 * h);
            if (v * 4.0 / TAU).fract() > 1e-3 && (v * 4.0 / TAU).fract() < 1.0 - 1e-3 {
                assert!((fd - c.derivative(v)).length() < 1e-6, "derivative at {v}");
            }
        }
        assert!(
            c.contains(DVec2::new(0.5, 0.5)) && !c.contains(DVec2::new(0.8, 0.8)),
            "inside test"
        );
        assert!(
            c.contains(DVec2::ZERO) && !c.contains(DVec2::new(1.1, 0.0)),
            "inside test"
        );
        assert_eq!(
            c.monotone_breaks().len(),
            5,
            "quarter arcs are monotone and convex"
        );
    }

    #[test]
    fn clockwise_loops_report_their_orientation_and_bad_input_is_rejected() {
        let ccw = BezierLoop::circle_approximation();
        let mut pts: Vec<DVec2> = ccw
            .pieces()
            .iter()
            .flat_map(|p| [p[0], p[1], p[2]])
            .collect();
        // Reverse: anchors in reverse order, each piece's controls swapped.
        let k = pts.len() / 3;
        let rev: Vec<DVec2> = (0..k)
            .flat_map(|i| {
                let j = (k - i) % k; // anchor P_j, then the controls of the piece ending at P_j
                let prev = (j + k - 1) % k;
                [pts[3 * j], pts[3 * prev + 2], pts[3 * prev + 1]]
            })
            .collect();
        let cw = BezierLoop::new(&rev).expect("valid");
        assert_eq!(cw.orientation(), -1.0, "clockwise");
        assert!(
            cw.contains(DVec2::new(0.3, -0.2)),
            "inside is inside either way"
        );
        pts.pop();
        assert_eq!(BezierLoop::new(&pts), Err(ProfileError::Count(11)), "count");
        let flat = [DVec2::ZERO, DVec2::X, DVec2::new(2.0, 0.0)];
        assert_eq!(BezierLoop::new(&flat), Err(ProfileError::NoArea), "no area");
        let nan = [DVec2::ZERO, DVec2::new(f64::NAN, 0.0), DVec2::Y];
        assert_eq!(
            BezierLoop::new(&nan),
            Err(ProfileError::NotFinite(1)),
            "nan"
        );
    }

    #[test]
    fn line_crossings_lie_on_the_loop() {
        let c = BezierLoop::circle_approximation();
        let (p, d) = (DVec2::new(-3.0, 0.2), DVec2::new(2.0, 0.3));
        let hits = c.intersect_line(p, d);
        assert_eq!(hits.len(), 2, "secant: {hits:?}");
        for (s, v) in hits {
            assert!(
                (c.point(v) - (p + s * d)).length() < 1e-12,
                "crossing {s} {v}"
            );
        }
    }
}
