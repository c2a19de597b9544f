//! A grab: a point of a body pulled towards a target by a critically damped spring (the
//! viewer's mouse drag). It is a soft point constraint (Catto's soft step): the impulse over a
//! step of `h` is `P = -mass_scale K^-1 (v + bias_rate C)` with `C` the point's offset from the
//! target, `v` its velocity and `K = m^-1 1 + [r]^T I^-1 [r]` the point's inverse effective mass,
//! so light and heavy bodies follow alike, at the frequency asked for, without overshoot.

use super::body::RigidBody;
use super::soft_step::softness::Softness;
use glam::{DMat3, DVec3};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grab {
    pub body: usize,
    /// The grabbed point in body space.
    pub local_point: DVec3,
    /// Where the point is pulled, world space.
    pub target: DVec3,
    /// Natural frequency of the spring (Hz).
    pub hertz: f64,
}

impl Grab {
    /// The impulse on the body over a step of `h`, with the body moving at `linear` and
    /// `angular` velocity: (arm from the centre of mass, impulse), or None when the body cannot
    /// move.
    pub fn impulse(
        &self,
        body: &RigidBody,
        (linear, angular): (DVec3, DVec3),
        h: f64,
    ) -> Option<(DVec3, DVec3)> {
        if !body.is_dynamic() || h <= 0.0 {
            return None;
        }
        let r = body.orientation * self.local_point;
        let point = body.position + r;
        let error = point - self.target;
        let velocity = linear + angular.cross(r);
        // Critically damped; no faster than the step can follow.
        let soft = Softness::new(self.hertz.min(0.25 / h), 1.0, h);
        let skew = crate::sim::integrate::skew(r);
        let k = DMat3::from_diagonal(DVec3::splat(body.inverse_mass))
            + skew.transpose() * body.world_inverse_inertia() * skew;
        if k.determinant().abs() < 1e-300 {
            return None;
        }
        let impulse = -soft.mass_scale * (k.inverse() * (velocity + soft.bias_rate * error));
        impulse.is_finite().then_some((r, impulse))
    }

    /// Applies the step's impulse to the grabbed body's velocities.
    pub fn apply(&self, bodies: &mut [RigidBody], h: f64) {
        let Some(body) = bodies.get_mut(self.body) else {
            return;
        };
        let velocities = (body.linear_velocity, body.angular_velocity);
        if let Some((r, impulse)) = self.impulse(body, velocities, h) {
            body.linear_velocity += body.inverse_mass * impulse;
            body.angular_velocity += body.world_inverse_inertia() * r.cross(impulse);
        }
    }
}
