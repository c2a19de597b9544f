//! The coursework's constraint projections (coursework 2, lecture 10): centres of mass back onto
//! the bound, then velocities onto `J v = 0`, one constraint at a time.

use crate::sim::body::RigidBody;
use crate::sim::constraint::{DistanceConstraint, pair_mut};

/// Projects the centres of mass back onto the bound when the constraint is violated beyond
/// `tolerance`: with `n = (p1 - p2)/|p1 - p2|`, `COM_1 -= w_1 C n`, `COM_2 += w_2 C n`.
/// Returns true when it corrected something (the coursework's `!positionWasValid`).
pub fn resolve_position(
    constraint: &DistanceConstraint,
    body1: &mut RigidBody,
    body2: &mut RigidBody,
    tolerance: f64,
) -> bool {
    let Some((_, _, n, distance)) = constraint.direction(body1, body2) else {
        return false;
    };
    let c = distance - constraint.reference;
    if constraint.position_valid(c, tolerance) {
        return false;
    }
    let inverse_mass1 = body1.effective_inverse_mass();
    let inverse_mass2 = body2.effective_inverse_mass();
    let total = inverse_mass1 + inverse_mass2;
    if total == 0.0 {
        return false;
    }
    body1.position -= (inverse_mass1 / total) * c * n;
    body2.position += (inverse_mass2 / total) * c * n;
    true
}

/// Projects the velocities onto `J v = 0` with `J = [n, r1 x n, -n, -(r2 x n)]`:
/// `v <- v - M^-1 J^T (J v) / (J M^-1 J^T)`. Returns true when it changed them.
pub fn resolve_velocity(
    constraint: &DistanceConstraint,
    body1: &mut RigidBody,
    body2: &mut RigidBody,
    tolerance: f64,
) -> bool {
    let Some((p1, p2, n, _)) = constraint.direction(body1, body2) else {
        return false;
    };
    let arm1_n = (p1 - body1.position).cross(n);
    let arm2_n = (p2 - body2.position).cross(n);
    let jv = n.dot(body1.linear_velocity) + arm1_n.dot(body1.angular_velocity)
        - n.dot(body2.linear_velocity)
        - arm2_n.dot(body2.angular_velocity);
    // A non-finite Jv (a blown-up body) must not reach the other body before the pose check
    // freezes the first.
    if !jv.is_finite() || jv.abs() <= tolerance {
        return false;
    }
    let inverse_mass1 = body1.effective_inverse_mass();
    let inverse_mass2 = body2.effective_inverse_mass();
    let inverse_inertia1 = body1.effective_world_inverse_inertia();
    let inverse_inertia2 = body2.effective_world_inverse_inertia();
    let jmj = inverse_mass1
        + inverse_mass2
        + arm1_n.dot(inverse_inertia1 * arm1_n)
        + arm2_n.dot(inverse_inertia2 * arm2_n);
    if jmj == 0.0 {
        return false;
    }
    let lambda = jv / jmj;
    body1.linear_velocity -= inverse_mass1 * lambda * n;
    body1.angular_velocity -= lambda * (inverse_inertia1 * arm1_n);
    body2.linear_velocity += inverse_mass2 * lambda * n;
    body2.angular_velocity += lambda * (inverse_inertia2 * arm2_n);
    true
}

/// Visits one constraint: position projection, and velocity projection after a correction.
pub fn visit(constraint: &DistanceConstraint, bodies: &mut [RigidBody], tolerance: f64) -> bool {
    let (body1, body2) = pair_mut(bodies, constraint.body1, constraint.body2);
    if !resolve_position(constraint, body1, body2, tolerance) {
        return false;
    }
    resolve_velocity(constraint, body1, body2, tolerance);
    true
}
