//! What the geometry core can resolve in f64, checked when a cylinder is built: each limit
//! with its reason, which the error message quotes.
//!
//! - [`MAX_COORDINATE`]: control point coordinates up to `1e15` in magnitude.
//! - [`MAX_SECTION_TO_AXIS`]: the section's reach (its bounding radius times the largest
//!   stretch) at most `1e6` times the axis' extent.
//! - [`MIN_RESOLVED`]: the thinnest section (least stretch times the section's bounding radius)
//!   at least `1e-12` of the fiber's distance from the origin or of its extent, whichever is
//!   larger.
//! - [`MAX_TAPER`], [`MAX_TWIST`]: radii that change by at most a factor of `1e6` along one
//!   segment, rotations of at most `1e6` rad.

/// Largest coordinate magnitude of a control point.
pub const MAX_COORDINATE: f64 = 1e15;
/// Why [`MAX_COORDINATE`].
pub const WHY_COORDINATE: &str = "beyond it neighbouring f64 values are more than 0.1 apart, \
    and the intersector's products of up to eight coordinates would near the f64 range";

/// Largest ratio of the section's reach to the axis' extent.
pub const MAX_SECTION_TO_AXIS: f64 = 1e6;
/// Why [`MAX_SECTION_TO_AXIS`].
pub const WHY_SECTION_TO_AXIS: &str = "a section a million times wider than its axis is long \
    is a disc, not a fiber: the root searches along the axis lose their resolution";

/// Smallest ratio of the section's least radius to the fiber's scale (its extent, or its
/// distance from the origin if larger).
pub const MIN_RESOLVED: f64 = 1e-12;
/// Why [`MIN_RESOLVED`].
pub const WHY_RESOLVED: &str = "a thinner section spans fewer than about 4,500 steps between \
    neighbouring f64 values at its position, so its hits could not be placed on its surface";

/// Largest ratio of a radius at one end of a segment to the other.
pub const MAX_TAPER: f64 = 1e6;
/// Why [`MAX_TAPER`].
pub const WHY_TAPER: &str = "the intersector's subdivision must resolve both ends at once, and \
    its work grows with the ratio";

/// Largest rotation magnitude, in radians (about 160,000 turns).
pub const MAX_TWIST: f64 = 1e6;
/// Why [`MAX_TWIST`].
pub const WHY_TWIST: &str = "beyond it f64 angles lose their fractional digits and the \
    section's turning cannot be resolved";

/// `x` for a message: at most 12 significant digits, so a 300-digit number is not echoed whole.
pub fn short(x: f64) -> String {
    if x.is_finite() && x != 0.0 && !(1e-4..1e12).contains(&x.abs()) {
        format!("{x:.6e}")
    } else if x.is_finite() {
        let s = format!("{x}");
        if s.len() > 16 { format!("{x:.6e}") } else { s }
    } else {
        format!("{x}")
    }
}

#[cfg(test)]
mod tests {
    use super::short;

    #[test]
    fn short_numbers_stay_short() {
        assert_eq!(short(1e300), "1.000000e300");
        assert_eq!(short(0.25), "0.25");
        assert_eq!(short(3.0), "3");
        assert_eq!(short(1.0 / 3.0), "3.333333e-1");
        assert_eq!(short(f64::INFINITY), "inf");
        assert!(short(-1.234567890123e-30).len() < 16);
    }
}
