//! A small deterministic random generator for generated scenes and randomised tests: the same
//! sequence on every machine, no dependency.

use glam::{DQuat, DVec3};

/// A small deterministic generator (SplitMix64), so generated scenes are the same everywhere.
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
    /// A rotation by a random axis (a point drawn uniformly in the cube [-1, 1]^3, normalised:
    /// not uniform on the sphere, which the generated scenes do not need) and an angle up to
    /// `max_angle`.
    pub fn tilt(&mut self, max_angle: f64) -> DQuat {
        let axis = DVec3::new(
            self.range(-1.0, 1.0),
            self.range(-1.0, 1.0),
            self.range(-1.0, 1.0),
        );
        let axis = if axis.length() > 1e-6 {
            axis.normalize()
        } else {
            DVec3::X
        };
        DQuat::from_axis_angle(axis, self.range(-max_angle, max_angle))
    }
}
