//! A small seeded generator for unit tests (a 64-bit LCG, Knuth's constants), and
//! double-double numbers, the tests' oracle of rounding bounds.

use glam::DVec3;

/// Seeded pseudo-random numbers: `Lcg(seed)`.
pub(crate) struct Lcg(pub u64);

impl Lcg {
    /// Uniform in `[0, 1)`.
    pub fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in `[a, b)`.
    pub fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.next()
    }

    /// A unit vector (rejection from the ball, away from its centre).
    pub fn unit(&mut self) -> DVec3 {
        loop {
            let v = DVec3::new(
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
            );
            if v.length() > 0.1 && v.length() <= 1.0 {
                return v.normalize();
            }
        }
    }
}

/// A double-double number `hi + lo` (about 106 bits): the oracle of the rounding bounds.
#[derive(Clone, Copy)]
pub(crate) struct Dd(pub f64, pub f64);

impl Dd {
    pub fn of(x: f64) -> Dd {
        Dd(x, 0.0)
    }
    pub fn add(self, o: Dd) -> Dd {
        // Knuth's two-sum of the high parts, then the low parts added in.
        let s = self.0 + o.0;
        let v = s - self.0;
        let e = (self.0 - (s - v)) + (o.0 - v) + self.1 + o.1;
        let hi = s + e;
        Dd(hi, e - (hi - s))
    }
    pub fn mul(self, o: Dd) -> Dd {
        // The exact product of the high parts by a fused multiply-add, then the cross terms.
        let p = self.0 * o.0;
        let e = self.0.mul_add(o.0, -p) + (self.0 * o.1 + self.1 * o.0);
        let hi = p + e;
        Dd(hi, e - (hi - p))
    }
    pub fn value(self) -> f64 {
        self.0 + self.1
    }
}
