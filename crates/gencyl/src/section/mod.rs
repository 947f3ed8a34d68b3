//! Closed planar cross sections `cs(v)`, `v in [0, 2 pi)`, in the `(n, b)` plane.

mod bezier_loop;
mod circle;
mod implicit;

pub use bezier_loop::{BezierLoop, ProfileError};
pub use circle::UnitCircle;
pub(crate) use circle::angle;
pub use implicit::PieceImplicit;

use arrayvec::ArrayVec;
use glam::DVec2;

use crate::real::{Real, V2};

/// Most crossings of a line with a section that [`CrossSection::intersect_line`] reports.
pub const MAX_LINE_CROSSINGS: usize = 24;

/// Crossings of a line with a section: `(s, v)` with `p + s dir = cs(v)`.
pub type LineCrossings = ArrayVec<(f64, f64), MAX_LINE_CROSSINGS>;

/// A closed planar curve `cs(v)`, `v in [0, 2 pi)`, bounding a region of the section plane.
pub trait CrossSection {
    /// `cs(v)`.
    fn point(&self, v: f64) -> DVec2;
    /// `d cs / d v`.
    fn derivative(&self, v: f64) -> DVec2;
    /// [`Self::point`] and [`Self::derivative`] at once (the circle's share one sine and
    /// cosine).
    fn point_and_derivative(&self, v: f64) -> (DVec2, DVec2) {
        (self.point(v), self.derivative(v))
    }
    /// `cs(v)` over any [`Real`], for `v` within the smooth piece of the curve that holds
    /// `v.value()`: an enclosure over a range of `v` holds the curve only if the range stays in
    /// that piece, as the ranges between [`CrossSection::monotone_breaks`] do.
    fn point_r<T: Real>(&self, v: T) -> V2<T>;
    /// Whether `p` lies inside the closed region (the boundary counts as inside).
    fn contains(&self, p: DVec2) -> bool;
    /// `max |cs(v)|`: the section lies in the disc of this radius about the origin.
    fn bounding_radius(&self) -> f64;
    /// Every crossing of the line `p + s dir` with the curve.
    fn intersect_line(&self, p: DVec2, dir: DVec2) -> LineCrossings;
    /// Parameters `0 = v_0 < v_1 < ... < v_k = 2 pi` splitting the curve into pieces that are
    /// monotone in both coordinates and free of inflections, so each piece lies in the box of
    /// its end points and in the triangle of its end points and end tangents (seed 2.3).
    fn monotone_breaks(&self) -> Vec<f64>;
    /// `+1` when the curve runs counter-clockwise, `-1` when clockwise (errata 4).
    fn orientation(&self) -> f64;
    /// Whether this is the unit circle `(cos v, sin v)`, which admits the radial fast path.
    fn is_unit_circle(&self) -> bool {
        false
    }
    /// The implicit equation of each of the section's `k` pieces, piece `i` covering
    /// `v in [2 pi i / k, 2 pi (i + 1) / k)` (`None` for a piece unfit for it); empty for a
    /// section without pieces (the circle, which has its own methods).
    fn implicit_pieces(&self) -> &[Option<PieceImplicit>] {
        &[]
    }
}

/// The cross sections a scene can name: the circle (hair) or a Bezier loop.
#[derive(Clone, Debug, PartialEq)]
pub enum Section {
    /// The unit circle.
    Circle(UnitCircle),
    /// A closed piecewise-cubic profile.
    Loop(BezierLoop),
}

impl Default for Section {
    fn default() -> Self {
        Section::Circle(UnitCircle)
    }
}

macro_rules! forward {
    ($self:ident, $s:ident => $e:expr) => {
        match $self {
            Section::Circle($s) => $e,
            Section::Loop($s) => $e,
        }
    };
}

impl CrossSection for Section {
    fn point(&self, v: f64) -> DVec2 {
        forward!(self, s => s.point(v))
    }
    fn derivative(&self, v: f64) -> DVec2 {
        forward!(self, s => s.derivative(v))
    }
    fn point_and_derivative(&self, v: f64) -> (DVec2, DVec2) {
        forward!(self, s => s.point_and_derivative(v))
    }
    fn point_r<T: Real>(&self, v: T) -> V2<T> {
        forward!(self, s => s.point_r(v))
    }
    fn contains(&self, p: DVec2) -> bool {
        forward!(self, s => s.contains(p))
    }
    fn bounding_radius(&self) -> f64 {
        forward!(self, s => s.bounding_radius())
    }
    fn intersect_line(&self, p: DVec2, dir: DVec2) -> LineCrossings {
        forward!(self, s => s.intersect_line(p, dir))
    }
    fn monotone_breaks(&self) -> Vec<f64> {
        forward!(self, s => s.monotone_breaks())
    }
    fn orientation(&self) -> f64 {
        forward!(self, s => s.orientation())
    }
    fn is_unit_circle(&self) -> bool {
        forward!(self, s => s.is_unit_circle())
    }
    fn implicit_pieces(&self) -> &[Option<PieceImplicit>] {
        forward!(self, s => s.implicit_pieces())
    }
}
