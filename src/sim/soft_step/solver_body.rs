//! The state the soft-step solver works on for each body: velocities, the masses seen by
//! impulses, and how far the body moved since the step began (contacts measure their current
//! separation from that, without a new collision query).

use crate::sim::body::RigidBody;
use glam::{DMat3, DQuat, DVec3};

/// Laid out in this order (`repr(C)`): the contact passes read the first 112 bytes of each body
/// they touch and never the inverse inertia (a contact keeps its angular responses), so at
/// 100,000 bodies, out of cache, a body costs them two cache lines or three, where the compiler's
/// order (the rotation first, the inertia between the velocities and the position change) split
/// what they read in two runs.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C)]
pub struct SolverBody {
    pub linear_velocity: DVec3,
    pub angular_velocity: DVec3,
    /// Zero for fixed and frozen bodies and the ground: impulses do not move them.
    pub inverse_mass: f64,
    /// Position change since the start of the step.
    pub delta_position: DVec3,
    /// Rotation since the start of the step.
    pub delta_rotation: DQuat,
    /// World inverse inertia at the start of the step; in a step with distance constraints
    /// or a grab, at the body's current orientation, turned with it after each substep's
    /// drift (see `Workspace::integrate_positions`). The contact rows keep the responses
    /// they were prepared with.
    pub inverse_inertia: DMat3,
}

impl SolverBody {
    /// The ground and every body impulses cannot move.
    pub const STATIC: SolverBody = SolverBody {
        linear_velocity: DVec3::ZERO,
        angular_velocity: DVec3::ZERO,
        inverse_mass: 0.0,
        inverse_inertia: DMat3::ZERO,
        delta_position: DVec3::ZERO,
        delta_rotation: DQuat::IDENTITY,
    };

    pub fn new(body: &RigidBody) -> Self {
        if !body.is_awake() {
            return Self::STATIC;
        }
        Self {
            linear_velocity: body.linear_velocity,
            angular_velocity: body.angular_velocity,
            inverse_mass: body.inverse_mass,
            inverse_inertia: body.world_inverse_inertia(),
            ..Self::STATIC
        }
    }

    /// Whether impulses leave it where it is (the ground, fixed and sleeping bodies).
    pub fn is_static(&self) -> bool {
        self.inverse_mass == 0.0 && self.inverse_inertia == DMat3::ZERO
    }

    /// Velocity of the material point at world arm `r`.
    #[inline]
    pub fn point_velocity(&self, r: DVec3) -> DVec3 {
        self.linear_velocity + self.angular_velocity.cross(r)
    }

    /// Applies impulse `p` at arm `r`.
    #[inline]
    pub fn apply(&mut self, r: DVec3, p: DVec3) {
        self.linear_velocity += self.inverse_mass * p;
        self.angular_velocity += self.inverse_inertia * r.cross(p);
    }

    /// How far the point at step-start arm `r` moved since the step began.
    #[inline]
    pub fn point_displacement(&self, r: DVec3) -> DVec3 {
        self.delta_position + self.delta_rotation * r - r
    }

    /// `(r x n) . I^-1 (r x n)`: the angular part of the inverse effective mass along `n`.
    #[inline]
    pub fn angular_mass(&self, r: DVec3, n: DVec3) -> f64 {
        let rn = r.cross(n);
        rn.dot(self.inverse_inertia * rn)
    }
}

/// Inverse effective mass `m1^-1 + m2^-1 + (r1 x n).I1^-1(r1 x n) + (r2 x n).I2^-1(r2 x n)`.
#[inline]
pub fn inverse_effective_mass(
    b1: &SolverBody,
    r1: DVec3,
    b2: &SolverBody,
    r2: DVec3,
    n: DVec3,
) -> f64 {
    b1.inverse_mass + b2.inverse_mass + b1.angular_mass(r1, n) + b2.angular_mass(r2, n)
}
