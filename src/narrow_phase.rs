//! Narrow phase: exact contact between two convex hulls (parry3d's GJK/EPA), and against the
//! ground plane y = 0.

use crate::body::RigidBody;
use crate::contact::Contact;
use crate::shape::Shape;
use glam::DVec3;
use parry3d_f64::math::Pose;

fn pose(body: &RigidBody) -> Pose {
    Pose::from_parts(body.position, body.orientation)
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
