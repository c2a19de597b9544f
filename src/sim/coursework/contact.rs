//! Impulse-based contact resolution (coursework 1.2, lecture 9): a linear projection out of
//! penetration weighted by inverse mass, then one restitution impulse at the contact point.

use crate::sim::body::RigidBody;
use crate::sim::narrow_phase::Contact;

/// How contacts are resolved; built from the settings once per step (in the step context).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactParams {
    pub restitution: f64,
    pub skip_separating: bool,
    pub restitution_threshold: f64,
}

/// Resolves one contact in place. Positions: `COM_2 += w_2 d n`, `COM_1 -= w_1 d n` with
/// `w_i = m_i^-1 / (m_1^-1 + m_2^-1)`. Velocities: at `p = p_2 + w_2 d n`,
/// `j = -(1+e) (u.n) / (m_1^-1 + m_2^-1 + (r_1 x n).I_1(r_1 x n) + (r_2 x n).I_2(r_2 x n))`.
/// Like the coursework it applies the impulse even to separating bodies unless
/// `params.skip_separating` is set. Returns whether anything moved.
pub fn resolve_contact(
    body1: &mut RigidBody,
    body2: &mut RigidBody,
    contact: &Contact,
    params: &ContactParams,
) -> bool {
    let inverse_mass1 = body1.effective_inverse_mass();
    let inverse_mass2 = body2.effective_inverse_mass();
    let total = inverse_mass1 + inverse_mass2;
    if total == 0.0 {
        return false;
    }
    let (w1, w2) = (inverse_mass1 / total, inverse_mass2 / total);
    let (d, n) = (contact.depth, contact.normal);
    body2.position += w2 * d * n;
    body1.position -= w1 * d * n;
    let point = contact.point2 + w2 * d * n;

    let arm1 = point - body1.position;
    let arm2 = point - body2.position;
    let inverse_inertia1 = body1.effective_world_inverse_inertia();
    let inverse_inertia2 = body2.effective_world_inverse_inertia();
    let closing = body1.point_velocity(arm1) - body2.point_velocity(arm2);
    let normal_speed = closing.dot(n);
    // A non-finite velocity must not reach the other body before the pose check freezes it.
    if !normal_speed.is_finite() || params.skip_separating && normal_speed <= 0.0 {
        return true;
    }
    // The threshold stops micro-bounces of bodies that approach slowly (`u.n > 0`); a slowly
    // separating contact keeps `e`, or its impulse would glue the bodies together.
    let approaching = normal_speed > 0.0;
    let restitution = if approaching && normal_speed < params.restitution_threshold {
        0.0
    } else {
        params.restitution
    };
    let arm1_n = arm1.cross(n);
    let arm2_n = arm2.cross(n);
    let effective_inverse_mass =
        total + arm1_n.dot(inverse_inertia1 * arm1_n) + arm2_n.dot(inverse_inertia2 * arm2_n);
    let j = -(1.0 + restitution) * normal_speed / effective_inverse_mass;
    let impulse = j * n;
    body1.linear_velocity += inverse_mass1 * impulse;
    body2.linear_velocity -= inverse_mass2 * impulse;
    body1.angular_velocity += inverse_inertia1 * arm1.cross(impulse);
    body2.angular_velocity -= inverse_inertia2 * arm2.cross(impulse);
    true
}
