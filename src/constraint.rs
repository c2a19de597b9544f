//! Inequality distance constraints (coursework 2, lecture 10): projections of positions, then of
//! velocities, one constraint at a time, scheduled as a cyclic sweep or a sparse work list.

use crate::body::RigidBody;
use crate::settings::ConstraintSchedule;
use crate::shape::Shape;
use glam::DVec3;

/// One inequality on the distance between two body-space points: `|p1 - p2| >= reference`
/// (lower) or `|p1 - p2| <= reference` (upper).
#[derive(Debug, Clone, PartialEq)]
pub struct DistanceConstraint {
    pub body1: usize,
    pub body2: usize,
    /// Vertex indices in the bodies' meshes (for display and export).
    pub vertex1: usize,
    pub vertex2: usize,
    /// The constrained points in body space (rest vertices).
    pub local1: DVec3,
    pub local2: DVec3,
    /// `bound * d0`, the threshold distance.
    pub reference: f64,
    pub is_upper: bool,
    /// Distance between the points when the scene was placed.
    pub rest_length: f64,
}

impl DistanceConstraint {
    /// The two inequalities of one constraint record: the distance between vertex `vertex1` of
    /// body `body1` and vertex `vertex2` of body `body2` stays within `[lower, upper]` times its
    /// value at the bodies' current poses.
    pub fn lower_and_upper(
        bodies: &[RigidBody],
        shapes: &[Shape],
        (body1, vertex1): (usize, usize),
        (body2, vertex2): (usize, usize),
        lower: f64,
        upper: f64,
    ) -> [DistanceConstraint; 2] {
        let local1 = shapes[bodies[body1].shape].rest_vertices[vertex1];
        let local2 = shapes[bodies[body2].shape].rest_vertices[vertex2];
        let rest_length =
            (bodies[body1].world_point(local1) - bodies[body2].world_point(local2)).length();
        [(lower, false), (upper, true)].map(|(bound, is_upper)| DistanceConstraint {
            body1,
            body2,
            vertex1,
            vertex2,
            local1,
            local2,
            reference: bound * rest_length,
            is_upper,
            rest_length,
        })
    }

    /// Current constrained points in world space.
    pub fn points(&self, bodies: &[RigidBody]) -> (DVec3, DVec3) {
        (
            bodies[self.body1].world_point(self.local1),
            bodies[self.body2].world_point(self.local2),
        )
    }

    /// `C = |p1 - p2| - reference`.
    pub fn value(&self, bodies: &[RigidBody]) -> f64 {
        let (p1, p2) = self.points(bodies);
        (p1 - p2).length() - self.reference
    }

    /// How far the distance lies outside the bound (0 when satisfied).
    pub fn violation(&self, bodies: &[RigidBody]) -> f64 {
        let c = self.value(bodies);
        if self.is_upper {
            c.max(0.0)
        } else {
            (-c).max(0.0)
        }
    }

    /// Current points, unit direction from point 2 to point 1, and distance; None when the
    /// points coincide (no direction: no correction rather than NaN) or are not finite.
    fn direction(
        &self,
        body1: &RigidBody,
        body2: &RigidBody,
    ) -> Option<(DVec3, DVec3, DVec3, f64)> {
        let p1 = body1.world_point(self.local1);
        let p2 = body2.world_point(self.local2);
        let distance = (p1 - p2).length();
        (distance > 0.0 && distance.is_finite()).then(|| (p1, p2, (p1 - p2) / distance, distance))
    }

    fn position_valid(&self, c: f64, tolerance: f64) -> bool {
        if self.is_upper {
            c <= tolerance
        } else {
            c >= -tolerance
        }
    }
}

pub(crate) fn pair_mut(
    bodies: &mut [RigidBody],
    i: usize,
    j: usize,
) -> (&mut RigidBody, &mut RigidBody) {
    assert_ne!(i, j, "a constraint or contact needs two distinct bodies");
    if i < j {
        let (a, b) = bodies.split_at_mut(j);
        (&mut a[i], &mut b[0])
    } else {
        let (a, b) = bodies.split_at_mut(i);
        (&mut b[0], &mut a[j])
    }
}

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
    if jv.abs() <= tolerance {
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

/// What a constraint pass did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ConstraintReport {
    pub visits: usize,
    pub corrections: usize,
    /// Stopped on the visit budget with constraints still violated.
    pub budget_hit: bool,
}

/// Visits one constraint: position projection, and velocity projection after a correction.
fn visit(constraint: &DistanceConstraint, bodies: &mut [RigidBody], tolerance: f64) -> bool {
    let (body1, body2) = pair_mut(bodies, constraint.body1, constraint.body2);
    if !resolve_position(constraint, body1, body2, tolerance) {
        return false;
    }
    resolve_velocity(constraint, body1, body2, tolerance);
    true
}

/// Resolves the constraints until all hold within `tolerance` or `max_visits` are spent.
/// `by_body[b]` lists the constraints on body b (used by the sparse schedule).
pub fn solve_constraints(
    constraints: &[DistanceConstraint],
    by_body: &[Vec<u32>],
    bodies: &mut [RigidBody],
    schedule: ConstraintSchedule,
    tolerance: f64,
    max_visits: usize,
) -> ConstraintReport {
    if constraints.is_empty() {
        return ConstraintReport::default();
    }
    match schedule {
        ConstraintSchedule::Sweep => sweep(constraints, bodies, tolerance, max_visits),
        ConstraintSchedule::Sparse => {
            work_list(constraints, by_body, bodies, tolerance, max_visits)
        }
    }
}

/// The coursework's loop: cycle through the list; stop after a streak of as many unchanged visits
/// as there are constraints (a full quiet pass), or when the budget is spent.
fn sweep(
    constraints: &[DistanceConstraint],
    bodies: &mut [RigidBody],
    tolerance: f64,
    max_visits: usize,
) -> ConstraintReport {
    let mut report = ConstraintReport::default();
    let mut quiet_streak = 0;
    let mut index = 0;
    while quiet_streak < constraints.len() && report.visits < max_visits {
        if visit(&constraints[index], bodies, tolerance) {
            quiet_streak = 0;
            report.corrections += 1;
        } else {
            quiet_streak += 1;
        }
        report.visits += 1;
        index = (index + 1) % constraints.len();
    }
    report.budget_hit = quiet_streak < constraints.len();
    report
}

/// Sparse scheduling (coursework 3.2): the sweep's cyclic order, but only over constraints flagged
/// as possibly violated. All start flagged; a correction flags the constraints that share a
/// movable body with it. Keeping the cyclic order keeps the sweep's Gauss-Seidel propagation along
/// chains (a FIFO work list converges more slowly and spends more visits). Ends when nothing is
/// flagged, which means every constraint was checked valid after its bodies last moved.
fn work_list(
    constraints: &[DistanceConstraint],
    by_body: &[Vec<u32>],
    bodies: &mut [RigidBody],
    tolerance: f64,
    max_visits: usize,
) -> ConstraintReport {
    let mut report = ConstraintReport::default();
    let count = constraints.len();
    let mut flagged = vec![true; count];
    let mut pending = count;
    let mut index = 0;
    while pending > 0 && report.visits < max_visits {
        // Next flagged constraint in cyclic order (a bool scan: far cheaper than a visit).
        while !flagged[index] {
            index = (index + 1) % count;
        }
        flagged[index] = false;
        pending -= 1;
        report.visits += 1;
        let constraint = &constraints[index];
        if visit(constraint, bodies, tolerance) {
            report.corrections += 1;
            for body in [constraint.body1, constraint.body2] {
                if !bodies[body].is_dynamic() {
                    continue;
                }
                for &other in &by_body[body] {
                    let other = other as usize;
                    // The corrected constraint itself now sits exactly on its bound.
                    if other != index && !flagged[other] {
                        flagged[other] = true;
                        pending += 1;
                    }
                }
            }
        }
        index = (index + 1) % count;
    }
    report.budget_hit = pending > 0;
    report
}
