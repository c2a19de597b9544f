//! Distance constraints in the soft-step solver: each inequality (the distance between two body
//! points above a lower or below an upper bound) is a one-sided row along the current axis,
//! solved with the contacts in the same substeps; speculative while satisfied (the bodies may
//! move up to the bound within a substep but not past it), softly corrected when violated,
//! rigid in the relax pass. Unlike the coursework's projection of the centres of mass, nothing
//! moves a body without the impulse that would move it, so no energy leaves with corrections.

use super::softness::Softness;
use super::solver_body::{SolverBody, inverse_effective_mass};
use crate::sim::body::RigidBody;
use crate::sim::constraint::{DistanceConstraint, pair_mut};
use glam::DVec3;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointRow {
    /// Index in the world's constraints.
    pub constraint: usize,
    pub body1: usize,
    pub body2: usize,
    pub local1: DVec3,
    pub local2: DVec3,
    pub bound: f64,
    pub is_upper: bool,
    /// Accumulated impulse along the axis (>= 0; pushes apart for a lower bound, pulls
    /// together for an upper one).
    pub impulse: f64,
}

/// The rows of the constraints `which` (indices into `constraints`), warm-started with last
/// step's impulses (indexed like `constraints`).
pub fn prepare(
    constraints: &[DistanceConstraint],
    which: &[usize],
    previous: &[f64],
) -> Vec<JointRow> {
    which
        .iter()
        .map(|&k| (k, &constraints[k]))
        .map(|(k, c)| JointRow {
            constraint: k,
            body1: c.body1,
            body2: c.body2,
            local1: c.local1,
            local2: c.local2,
            bound: c.reference,
            is_upper: c.is_upper,
            impulse: previous.get(k).copied().unwrap_or(0.0),
        })
        .collect()
}

/// Current arms, unit axis from point 1 to point 2, and distance; None when the points coincide.
fn geometry(row: &JointRow, poses: &[RigidBody]) -> Option<(DVec3, DVec3, DVec3, f64)> {
    let (a, b) = (&poses[row.body1], &poses[row.body2]);
    let r1 = a.orientation * row.local1;
    let r2 = b.orientation * row.local2;
    let d = (b.position + r2) - (a.position + r1);
    let length = d.length();
    (length > 1e-12 && length.is_finite()).then(|| (r1, r2, d / length, length))
}

/// The direction an impulse of this row pushes body 2 (body 1 the opposite way).
fn sign(row: &JointRow) -> f64 {
    if row.is_upper { -1.0 } else { 1.0 }
}

pub fn warm_start(rows: &[JointRow], poses: &[RigidBody], bodies: &mut [SolverBody]) {
    for row in rows {
        let Some((r1, r2, axis, _)) = geometry(row, poses) else {
            continue;
        };
        let (b1, b2) = pair_mut(bodies, row.body1, row.body2);
        let p = sign(row) * row.impulse * axis;
        b1.apply(r1, -p);
        b2.apply(r2, p);
    }
}

/// One pass over the rows at the bodies' current poses.
pub fn solve(
    rows: &mut [JointRow],
    poses: &[RigidBody],
    bodies: &mut [SolverBody],
    softness: Softness,
    inv_h: f64,
    use_bias: bool,
    max_push: f64,
) {
    for row in rows.iter_mut() {
        let Some((r1, r2, axis, length)) = geometry(row, poses) else {
            continue;
        };
        let (b1, b2) = pair_mut(bodies, row.body1, row.body2);
        let k = inverse_effective_mass(b1, r1, b2, r2, axis);
        if k <= 0.0 {
            continue;
        }
        let sign = sign(row);
        // C >= 0 when satisfied; Cdot its rate along the row's direction.
        let c = sign * (length - row.bound);
        let c_dot = sign * axis.dot(b2.point_velocity(r2) - b1.point_velocity(r1));
        let (bias, mass_scale, impulse_scale) = softness.coefficients(c, inv_h, use_bias, max_push);
        let impulse = -mass_scale * (c_dot + bias) / k - impulse_scale * row.impulse;
        let total = (row.impulse + impulse).max(0.0);
        let p = sign * (total - row.impulse) * axis;
        row.impulse = total;
        b1.apply(r1, -p);
        b2.apply(r2, p);
    }
}
