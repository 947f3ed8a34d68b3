//! Invertible sweeping rules `s(p, u)`: how the cross section is transformed at each `u`.

use glam::DVec2;

use crate::real::{Dual, Real, V2};

/// An invertible sweeping rule: a map of the section plane at each `u in [0, 1]`, with its
/// inverse. Written over [`Real`] so the intersector can evaluate it with values, derivatives
/// and interval enclosures.
pub trait SweepRule {
    /// `s(p, u)`: section coordinates to `(n, b)` coordinates.
    fn apply<T: Real>(&self, u: T, p: V2<T>) -> V2<T>;
    /// `s^-1(q, u)`: `(n, b)` coordinates to section coordinates.
    fn inverse<T: Real>(&self, u: T, q: V2<T>) -> V2<T>;
    /// `s(p, u)` with its derivative in `u` (`p` held), and with its derivative along the
    /// section's tangent `dp` (`u` held): the surface's two partial derivatives' parts from
    /// the rule, for its normal.
    fn apply_with_tangent(&self, u: f64, p: DVec2, dp: DVec2) -> (V2<Dual<f64>>, V2<Dual<f64>>) {
        let along_u = self.apply(Dual::var(u), V2::cst(p));
        let along_v = self.apply(
            Dual::cst(u),
            V2::new(Dual { v: p.x, d: dp.x }, Dual { v: p.y, d: dp.y }),
        );
        (along_u, along_v)
    }
    /// A linear upper bound `[L0, L1]` of the rule's stretch: `|s(p, u)| <= (L0 + (L1 - L0) u) |p|`
    /// for `u in [0, 1]`. Bounds boxes and the frame-free prefilter of the intersector.
    fn scale_bound(&self) -> [f64; 2];
    /// `+1` if every `s(., u)` keeps orientation (positive determinant), `-1` if every one
    /// reverses it (errata 4).
    fn orientation(&self) -> f64;
    /// `Some([s0, s1])` when `s(p, u) = Rot(u) (s0 + (s1 - s0) u) p` for a rotation `Rot(u)`:
    /// the rule maps the unit circle to the circle of radius `s(u)`, so for a circular section
    /// the frame drops out of the surface and the polynomial fast path applies.
    fn uniform_scale(&self) -> Option<[f64; 2]> {
        None
    }
    /// A lower bound of the rule's least stretch over `u in [0, 1]`, `min |s(p, u)| / |p|`,
    /// if the rule knows one: the thinnest the section gets, for the resolution check of
    /// [`crate::limits`].
    fn least_scale(&self) -> Option<f64> {
        None
    }
    /// Why the rule is unusable (non-positive or non-finite radii, say), if it is.
    fn validate(&self) -> Result<(), String> {
        Ok(())
    }
}

/// The hair rule (seed section 3): `s(p, u) = R(theta(u)) diag(A(u), B(u)) p` with
/// `A(u) = A0 + (A1 - A0) u`, `B(u) = B0 + (B1 - B0) u`, `theta(u) = theta0 + (theta1 - theta0) u`;
/// inverse `s^-1(q, u) = diag(1/A, 1/B) R(-theta) q`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HairSweep {
    /// Major radius `[A0, A1]` (along the rotated first axis).
    pub major: [f64; 2],
    /// Minor radius `[B0, B1]`.
    pub minor: [f64; 2],
    /// Rotation `[theta0, theta1]` in radians, turning from `n` toward `b`.
    pub rotation: [f64; 2],
}

impl HairSweep {
    /// A round fiber of constant radius `r`.
    pub fn circular(r: f64) -> Self {
        HairSweep {
            major: [r, r],
            minor: [r, r],
            rotation: [0.0, 0.0],
        }
    }

    /// Whether the section is a circle at every `u` (`A(u) = B(u)`), so the rotation and the
    /// frame drop out of the surface.
    pub fn is_circular(&self) -> bool {
        self.major == self.minor
    }

    #[inline]
    fn lerp<T: Real>(k: [f64; 2], u: T) -> T {
        T::cst(k[0]) + u.scale(k[1] - k[0])
    }

    /// `A(u)`.
    #[inline]
    pub fn major_at<T: Real>(&self, u: T) -> T {
        Self::lerp(self.major, u)
    }

    /// `B(u)`.
    #[inline]
    pub fn minor_at<T: Real>(&self, u: T) -> T {
        Self::lerp(self.minor, u)
    }

    /// The rotation `theta(u)`; the constant where it does not turn (the same values, without
    /// carrying `u`'s enclosure through the sine and cosine).
    #[inline]
    fn angle<T: Real>(&self, u: T) -> T {
        if self.rotation[0] == self.rotation[1] {
            T::cst(self.rotation[0])
        } else {
            Self::lerp(self.rotation, u)
        }
    }

    /// `R(theta) diag(A(u), B(u)) p` with `(s, c)` the sine and cosine of `theta`: the rule's
    /// map once its rotation is known ([`SweepRule::apply`] and its tangent form share it).
    #[inline]
    fn turned_stretch<T: Real>(&self, (s, c): (T, T), u: T, p: V2<T>) -> V2<T> {
        let (x, y) = (p.x * self.major_at(u), p.y * self.minor_at(u));
        V2::new(c * x - s * y, s * x + c * y)
    }

    /// `x / k(u)` for a radius `k = [k0, k1]` linear in `u`; by the constant where `k0 = k1`.
    #[inline]
    fn over<T: Real>(k: [f64; 2], u: T, x: T) -> T {
        if k[0] == k[1] {
            x.div_cst(k[0])
        } else {
            x / Self::lerp(k, u)
        }
    }
}

impl SweepRule for HairSweep {
    #[inline]
    fn apply<T: Real>(&self, u: T, p: V2<T>) -> V2<T> {
        self.turned_stretch(self.angle(u).sin_cos(), u, p)
    }

    #[inline]
    fn inverse<T: Real>(&self, u: T, q: V2<T>) -> V2<T> {
        let (x, y) = self.angle(u).rotate_back(q.x, q.y);
        V2::new(Self::over(self.major, u, x), Self::over(self.minor, u, y))
    }

    /// The two [`SweepRule::apply`]s of the default, sharing one sine and cosine of the
    /// rotation (the second's are constants: its `u` is).
    fn apply_with_tangent(&self, u: f64, p: DVec2, dp: DVec2) -> (V2<Dual<f64>>, V2<Dual<f64>>) {
        let (s, c) = self.angle(Dual::var(u)).sin_cos();
        let along_u = self.turned_stretch((s, c), Dual::var(u), V2::cst(p));
        let along_v = self.turned_stretch(
            (Dual::cst(s.v), Dual::cst(c.v)),
            Dual::cst(u),
            V2::new(Dual { v: p.x, d: dp.x }, Dual { v: p.y, d: dp.y }),
        );
        (along_u, along_v)
    }

    /// The stretch of `R diag(A, B)` is `max(A(u), B(u))`, a convex function of `u` (the maximum
    /// of two linear ones), so the chord through its end values lies above it.
    fn scale_bound(&self) -> [f64; 2] {
        [
            self.major[0].abs().max(self.minor[0].abs()),
            self.major[1].abs().max(self.minor[1].abs()),
        ]
    }

    fn orientation(&self) -> f64 {
        1.0
    }

    /// `A` and `B` are linear in `u`, so their least values are at the ends.
    fn least_scale(&self) -> Option<f64> {
        Some(
            self.major
                .into_iter()
                .chain(self.minor)
                .fold(f64::INFINITY, f64::min),
        )
    }

    fn uniform_scale(&self) -> Option<[f64; 2]> {
        self.is_circular().then_some(self.major)
    }

    /// Each message starts with the key it is about (`major_radius`, `minor_radius`,
    /// `rotation`), so that a scene file can point at it.
    fn validate(&self) -> Result<(), String> {
        for (name, k) in [
            ("major_radius", self.major),
            ("minor_radius", self.minor),
            ("rotation", self.rotation),
        ] {
            if !k.iter().all(|x| x.is_finite()) {
                return Err(format!("{name} must be finite, got {k:?}"));
            }
        }
        for (name, k) in [("major_radius", self.major), ("minor_radius", self.minor)] {
            if !k.iter().all(|&x| x > 0.0) {
                return Err(format!("{name} must be positive at both ends, got {k:?}"));
            }
            let taper = k[0].max(k[1]) / k[0].min(k[1]);
            if !(taper <= crate::limits::MAX_TAPER) {
                return Err(format!(
                    "{name} changes by a factor of {} along the segment, more than {:.0e}: {}",
                    crate::limits::short(taper),
                    crate::limits::MAX_TAPER,
                    crate::limits::WHY_TAPER
                ));
            }
        }
        let turn = self.rotation[0].abs().max(self.rotation[1].abs());
        if !(turn <= crate::limits::MAX_TWIST) {
            return Err(format!(
                "rotation reaches {} rad, more than {:.0e}: {}",
                crate::limits::short(turn),
                crate::limits::MAX_TWIST,
                crate::limits::WHY_TWIST
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec2;

    #[test]
    fn inverse_undoes_apply() {
        let s = HairSweep {
            major: [0.05, 0.03],
            minor: [0.02, 0.025],
            rotation: [0.3, -2.0],
        };
        for i in 0..=10 {
            let u = i as f64 / 10.0;
            let p = V2::new(0.7 - u, 0.2 + u * u);
            let q = s.apply(u, p);
            let back = s.inverse(u, q);
            assert!(
                (back.value() - p.value()).length() < 1e-14,
                "round trip at {u}"
            );
            // Area scales by det = A B: the unit square's image has area A(u) B(u).
            let e1 = s.apply(u, V2::new(1.0, 0.0)).value();
            let e2 = s.apply(u, V2::new(0.0, 1.0)).value();
            let det = e1.perp_dot(e2);
            let ab = s.major_at(u) * s.minor_at(u);
            assert!((det - ab).abs() < 1e-16, "det {det} vs A B {ab}");
        }
        // theta turns from n toward b: at theta = pi/2 the major axis points along b.
        let s = HairSweep {
            major: [2.0, 2.0],
            minor: [1.0, 1.0],
            rotation: [std::f64::consts::FRAC_PI_2; 2],
        };
        let q = s.apply(0.0, V2::new(1.0, 0.0)).value();
        assert!(
            (q - DVec2::new(0.0, 2.0)).length() < 1e-15,
            "rotation sense {q:?}"
        );
    }
}
