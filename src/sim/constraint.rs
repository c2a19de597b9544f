//! Inequality distance constraints (coursework 2): the distance between two body points stays
//! above a lower or below an upper bound. Both solvers read this type; each solves it its own way.

use super::body::RigidBody;
use super::shape::Shape;
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

    /// The violation as a share of the distance the scene placed the points at.
    pub fn relative_violation(&self, bodies: &[RigidBody]) -> f64 {
        self.share_of_rest_length(self.violation(bodies))
    }

    /// A length as a share of the rest length; 0 for points placed together, which have no
    /// length to share (their violations are lengths only).
    pub fn share_of_rest_length(&self, length: f64) -> f64 {
        if self.rest_length > 0.0 {
            length / self.rest_length
        } else {
            0.0
        }
    }

    /// Current points, unit direction from point 2 to point 1, and distance; None when the
    /// points coincide (no direction: no correction rather than NaN) or are not finite.
    pub(crate) fn direction(
        &self,
        body1: &RigidBody,
        body2: &RigidBody,
    ) -> Option<(DVec3, DVec3, DVec3, f64)> {
        let p1 = body1.world_point(self.local1);
        let p2 = body2.world_point(self.local2);
        let distance = (p1 - p2).length();
        (distance > 0.0 && distance.is_finite()).then(|| (p1, p2, (p1 - p2) / distance, distance))
    }

    pub(crate) fn position_valid(&self, c: f64, tolerance: f64) -> bool {
        if self.is_upper {
            c <= tolerance
        } else {
            c >= -tolerance
        }
    }
}

/// Two distinct bodies of one slice (rigid bodies or the soft step's solver bodies), mutably.
pub(crate) fn pair_mut<T>(bodies: &mut [T], i: usize, j: usize) -> (&mut T, &mut T) {
    assert_ne!(i, j, "a constraint or contact needs two distinct bodies");
    if i < j {
        let (a, b) = bodies.split_at_mut(j);
        (&mut a[i], &mut b[0])
    } else {
        let (a, b) = bodies.split_at_mut(i);
        (&mut b[0], &mut a[j])
    }
}
