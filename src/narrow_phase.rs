//! Narrow phase: exact contact between two convex hulls (parry3d's GJK/EPA), and against the
//! ground plane y = 0.

use crate::body::RigidBody;
use crate::contact::Contact;
use crate::shape::Shape;
use glam::DVec3;
use parry3d_f64::math::Pose;

/// Contact between the hulls of two bodies at their current poses, if they touch or overlap.
/// parry's `normal1` points from shape 1 to shape 2, `-dist` is the depth and `point2` lies on
/// shape 2: exactly the coursework's `contactNormal`, `depth` and `penPosition`.
pub fn body_contact(body1: &RigidBody, shape1: &Shape, body2: &RigidBody, shape2: &Shape) -> Option<Contact> {
    let pose1 = Pose::from_parts(body1.position, body1.orientation);
    let pose2 = Pose::from_parts(body2.position, body2.orientation);
    let contact = parry3d_f64::query::contact(&pose1, &shape1.hull, &pose2, &shape2.hull, 0.0).ok().flatten()?;
    let depth = -contact.dist;
    if !(depth >= 0.0) || !contact.normal1.is_finite() || !contact.point2.is_finite() {
        return None;
    }
    Some(Contact { depth, normal: contact.normal1, point2: contact.point2 })
}

/// Contact with the ground plane y = 0, whose body is immovable and plays body 2: depth is minus
/// the lowest vertex's height, normal `(0,-1,0)`, point the lowest vertex (first one on ties).
pub fn ground_contact(body: &RigidBody, shape: &Shape) -> Option<Contact> {
    let mut lowest = DVec3::splat(f64::INFINITY);
    for &v in &shape.rest_vertices {
        let p = body.world_point(v);
        if p.y < lowest.y {
            lowest = p;
        }
    }
    (lowest.y <= 0.0).then(|| Contact { depth: -lowest.y, normal: DVec3::NEG_Y, point2: lowest })
}
