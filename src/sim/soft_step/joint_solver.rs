//! Distance constraints in the soft-step solver: each inequality (the distance between two body
//! points above a lower or below an upper bound) is a one-sided row along the current axis,
//! solved with the contacts in the same substeps; speculative while satisfied (the bodies may
//! move up to the bound within a substep but not past it), softly corrected when violated,
//! rigid in the relax pass. Unlike the coursework's projection of the centres of mass, nothing
//! moves a body without the impulse that would move it, so no energy leaves with corrections.

use super::joint_block::{Geometry, points_geometry};
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

/// Current arms, unit axis from point 1 to point 2, and distance; where the points coincide the
/// axis `coincident_axis` gives, or none.
fn geometry(
    row: &JointRow,
    poses: &[RigidBody],
    coincident_axis: impl FnOnce(DVec3, DVec3) -> Option<DVec3>,
) -> Option<Geometry> {
    let ends = (&poses[row.body1], &poses[row.body2]);
    points_geometry((ends.0, row.local1), (ends.1, row.local2), coincident_axis)
}

/// The direction an impulse of this row pushes body 2 (body 1 the opposite way).
fn sign(row: &JointRow) -> f64 {
    if row.is_upper { -1.0 } else { 1.0 }
}

pub fn warm_start(rows: &[JointRow], poses: &[RigidBody], bodies: &mut [SolverBody]) {
    for row in rows {
        // A row whose points coincide has no axis its impulse was along: not warm-started.
        let Some(Geometry { r1, r2, axis, .. }) = geometry(row, poses, |_, _| None) else {
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
        // Points that coincide are held along the way they separate.
        let separating = |r1: DVec3, r2: DVec3| {
            let (b1, b2) = (&bodies[row.body1], &bodies[row.body2]);
            Some(b2.point_velocity(r2) - b1.point_velocity(r1))
        };
        let Some(Geometry {
            r1,
            r2,
            axis,
            length,
        }) = geometry(row, poses, separating)
        else {
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
