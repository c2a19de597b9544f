//! Narrow phase: exact contact between two convex hulls (parry3d's GJK/EPA), and against the
//! ground plane y = 0.

use super::body::RigidBody;
use super::shape::Shape;
use glam::DVec3;
use parry3d_f64::math::Pose;

/// A penetrating contact between body 1 and body 2.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    /// Penetration depth along `normal`, >= 0.
    pub depth: f64,
    /// Unit normal pointing from body 1 towards body 2.
    pub normal: DVec3,
    /// Point on body 2 deepest inside body 1 (the coursework's `penPosition`).
    pub point2: DVec3,
}

fn pose(body: &RigidBody) -> Pose {
    Pose::from_parts(body.position, body.orientation)
}

/// Whether the bodies' oriented bounding boxes (body-space box at the current pose, padded by a
/// relative 1e-9 against rounding) overlap, by the separating axis theorem on the 15 axes of two
/// boxes (Gottschalk, Lin & Manocha, "OBBTree", 1996). The boxes contain the hulls, so disjoint
/// boxes mean disjoint hulls: a cheap and exact early "no contact" before GJK.
pub fn oriented_boxes_overlap(
    body1: &RigidBody,
    shape1: &Shape,
    body2: &RigidBody,
    shape2: &Shape,
) -> bool {
    let pad = |s: &Shape, b: &RigidBody| {
        let h = s.local_box_half_extents;
        h + DVec3::splat(1e-9 * (h.max_element() + b.position.abs().max_element()) + 1e-12)
    };
    let (h1, h2) = (pad(shape1, body1), pad(shape2, body2));
    let (r1, r2) = (body1.rotation(), body2.rotation());
    let a = [r1.x_axis, r1.y_axis, r1.z_axis];
    let b = [r2.x_axis, r2.y_axis, r2.z_axis];
    let t = body2.world_point(shape2.local_box_center) - body1.world_point(shape1.local_box_center);
    let separated_along = |axis: DVec3| {
        let length = axis.length_squared();
        if length < 1e-24 {
            return false; // parallel edges: the face axes decide
        }
        let r1 =
            h1.x * a[0].dot(axis).abs() + h1.y * a[1].dot(axis).abs() + h1.z * a[2].dot(axis).abs();
        let r2 =
            h2.x * b[0].dot(axis).abs() + h2.y * b[1].dot(axis).abs() + h2.z * b[2].dot(axis).abs();
        t.dot(axis).abs() > (r1 + r2) * (1.0 + 1e-12)
    };
    if a.iter().chain(b.iter()).any(|&axis| separated_along(axis)) {
        return false;
    }
    !a.iter()
        .any(|&u| b.iter().any(|&v| separated_along(u.cross(v))))
}

/// Contact between the hulls of two bodies at their current poses, if they touch or overlap.
/// parry's `normal1` points from shape 1 to shape 2, `-dist` is the depth and `point2` lies on
/// shape 2: exactly the coursework's `contactNormal`, `depth` and `penPosition`.
pub fn body_contact(
    body1: &RigidBody,
    shape1: &Shape,
    body2: &RigidBody,
    shape2: &Shape,
) -> Option<Contact> {
    let (pose1, pose2) = (pose(body1), pose(body2));
    let contact = parry3d_f64::query::contact(&pose1, &shape1.hull, &pose2, &shape2.hull, 0.0)
        .ok()
        .flatten()?;
    let depth = -contact.dist;
    if depth.is_nan() || depth < 0.0 || !contact.normal1.is_finite() || !contact.point2.is_finite()
    {
        return None;
    }
    Some(Contact {
        depth,
        normal: contact.normal1,
        point2: contact.point2,
    })
}

/// Like [`body_contact`], but acting at the centroid of the whole contact patch: parry's contact
/// manifold (feature clipping) gives up to several penetrating points; the depth is the deepest,
/// the point the centroid of their points on body 2. A box resting on a face is then pushed
/// through its centre instead of one corner, which is what makes stacks topple.
pub fn body_contact_patch(
    body1: &RigidBody,
    shape1: &Shape,
    body2: &RigidBody,
    shape2: &Shape,
) -> Option<Contact> {
    use parry3d_f64::query::{ContactManifold, DefaultQueryDispatcher, PersistentQueryDispatcher};
    let pose12 = pose(body1).inv_mul(&pose(body2));
    let mut manifolds: Vec<ContactManifold<(), ()>> = Vec::new();
    DefaultQueryDispatcher
        .contact_manifolds(
            &pose12,
            &shape1.hull,
            &shape2.hull,
            0.0,
            &mut manifolds,
            &mut None,
        )
        .ok()?;
    let manifold = manifolds.first()?;
    let (mut depth, mut sum, mut count) = (0.0f64, DVec3::ZERO, 0);
    for point in manifold.points.iter().filter(|p| p.dist <= 0.0) {
        depth = depth.max(-point.dist);
        sum += body2.world_point(point.local_p2);
        count += 1;
    }
    let normal = body1.orientation * manifold.local_n1;
    if count == 0 || !normal.is_finite() || !sum.is_finite() {
        return None;
    }
    Some(Contact {
        depth,
        normal: normal.normalize(),
        point2: sum / count as f64,
    })
}

/// Contact with the ground plane y = 0, whose body is immovable and plays body 2: depth is minus
/// the lowest vertex's height, normal `(0,-1,0)`, point the lowest vertex (first one on ties).
/// With `patch`, the point is instead the centroid of all vertices at or below the ground.
pub fn ground_contact(body: &RigidBody, shape: &Shape, patch: bool) -> Option<Contact> {
    let mut lowest = DVec3::splat(f64::INFINITY);
    let (mut below_sum, mut below_count) = (DVec3::ZERO, 0);
    for &v in &shape.rest_vertices {
        let p = body.world_point(v);
        if p.y < lowest.y {
            lowest = p;
        }
        if patch && p.y <= 0.0 {
            below_sum += p;
            below_count += 1;
        }
    }
    if lowest.y.is_nan() || lowest.y > 0.0 {
        return None;
    }
    let point2 = if patch {
        below_sum / below_count as f64
    } else {
        lowest
    };
    Some(Contact {
        depth: -lowest.y,
        normal: DVec3::NEG_Y,
        point2,
    })
}
