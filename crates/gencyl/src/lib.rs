//! Exact ray tracing of generalized cylinders.
//!
//! A generalized cylinder is the solid swept by a closed 2D cross section `cs(v)` along a 3D
//! axis `a(u)` under an invertible sweeping rule `s(., u)` that scales and rotates the section
//! (Hsu and Chelberg 1994). Here the axis is a cubic Bezier curve, the frame is Frenet's (fixed
//! for a straight axis; strands use a projection frame that follows the fiber without
//! spinning), the section a unit circle or a closed cubic Bezier loop, and the
//! hair rule scales by linearly varying radii and rotates by a linearly varying angle: an
//! elliptical, twisted, tapering fiber.
//!
//! ```
//! use gencyl::{FiberSpec, Ray};
//! use glam::DVec3;
//!
//! // A straight round fiber of radius 0.1 along x from 0 to 3, capped.
//! let bezier = [0.0, 1.0, 2.0, 3.0].map(|x| DVec3::new(x, 0.0, 0.0));
//! let fiber = FiberSpec::round(bezier, 0.1).build().unwrap();
//! let hit = fiber.intersect(&Ray::new(DVec3::new(1.5, 0.0, 1.0), DVec3::new(0.0, 0.0, -1.0)), 0.0, f64::INFINITY).unwrap();
//! assert!((hit.t - 0.9).abs() < 1e-12);
//! assert!((hit.normal - DVec3::Z).length() < 1e-12);
//! ```
#![forbid(unsafe_code)]

pub mod bernstein;
pub mod budget;
pub mod curve;
pub mod cylinder;
pub mod frame;
pub mod intersect;
pub mod limits;
pub mod packed;
pub mod real;
pub mod roots;
pub mod section;
pub mod strand;
pub mod sweep;
#[cfg(test)]
mod test_rng;

pub use curve::CubicBezier;
pub use cylinder::{
    Aabb, FiberSpec, GeneralizedCylinder, GeometryError, Hit, Part, Ray, Unresolved,
    times_power_of_two,
};
pub use frame::{Frame, FrameAt, Framing};
pub use intersect::Method;
pub use packed::{PackedCylinders, Record, StrandControls, spline_bezier_near};
pub use section::{BezierLoop, CrossSection, Section, UnitCircle};
pub use strand::{Strand, StrandFraming, StrandSegment, Taper, along_strand, spline_segment};
pub use sweep::{HairSweep, SweepRule};
