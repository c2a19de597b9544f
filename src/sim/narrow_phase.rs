//! Narrow phase: exact contact between two convex hulls (parry3d's GJK/EPA), and against the
//! ground plane y = 0.

use super::body::RigidBody;
use super::contact_patch::{ground_patch_point, patch_point_under};
use super::shape::Shape;
use glam::DVec3;
use parry3d_f64::math::Pose;
use parry3d_f64::shape::SupportMap;
use smallvec::SmallVec;

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
/// boxes in the first box's frame (Gottschalk, Lin & Manocha, "OBBTree", 1996: `R = A^T B`,
/// its magnitudes raised by a small epsilon so that near-parallel edges, whose cross product
/// vanishes, never separate). The boxes contain the hulls, so disjoint boxes mean disjoint
/// hulls: a cheap and exact early "no contact" before GJK. Every test errs towards "overlap".
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
    let (h1, h2) = (pad(shape1, body1).to_array(), pad(shape2, body2).to_array());
    let (r1, r2) = (body1.rotation(), body2.rotation());
    let a = [r1.x_axis, r1.y_axis, r1.z_axis];
    let b = [r2.x_axis, r2.y_axis, r2.z_axis];
    let t = body2.world_point(shape2.local_box_center) - body1.world_point(shape1.local_box_center);
    let t = [a[0].dot(t), a[1].dot(t), a[2].dot(t)];
    let r = a.map(|ai| b.map(|bj| ai.dot(bj)));
    let abs_r = r.map(|row| row.map(|x| x.abs() + 1e-12));
    let apart = |distance: f64, radii: f64| distance.abs() > radii * (1.0 + 1e-12);
    for i in 0..3 {
        let radius2 = h2[0] * abs_r[i][0] + h2[1] * abs_r[i][1] + h2[2] * abs_r[i][2];
        if apart(t[i], h1[i] + radius2) {
            return false;
        }
    }
    for j in 0..3 {
        let radius1 = h1[0] * abs_r[0][j] + h1[1] * abs_r[1][j] + h1[2] * abs_r[2][j];
        let distance = t[0] * r[0][j] + t[1] * r[1][j] + t[2] * r[2][j];
        if apart(distance, radius1 + h2[j]) {
            return false;
        }
    }
    for i in 0..3 {
        let (i1, i2) = ((i + 1) % 3, (i + 2) % 3);
        for j in 0..3 {
            let (j1, j2) = ((j + 1) % 3, (j + 2) % 3);
            let radius1 = h1[i1] * abs_r[i2][j] + h1[i2] * abs_r[i1][j];
            let radius2 = h2[j1] * abs_r[i][j2] + h2[j2] * abs_r[i][j1];
            if apart(t[i2] * r[i1][j] - t[i1] * r[i2][j], radius1 + radius2) {
                return false;
            }
        }
    }
    true
}

/// What the narrow phase found for one pair of bodies.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detection {
    pub contact: Option<Contact>,
    /// parry's GJK/EPA failed on intersecting hulls and the separating-axis fallback
    /// ([`sat_contact`]) computed the contact instead.
    pub fallback: bool,
}

impl Detection {
    pub fn apart() -> Self {
        Self {
            contact: None,
            fallback: false,
        }
    }
}

/// parry's support-map contact (GJK, then EPA inside the Minkowski difference) at prediction 0,
/// step for step as `parry3d::query::contact` computes it, but telling EPA's failure apart from
/// "no intersection" (parry reports both as no contact).
enum HullContact {
    Touching(parry3d_f64::query::Contact),
    Apart,
    EpaFailed,
}

fn hull_contact(pose1: &Pose, shape1: &Shape, pose2: &Pose, shape2: &Shape) -> HullContact {
    use parry3d_f64::query::epa::EPA;
    use parry3d_f64::query::gjk::GJKResult;
    let (g1, g2) = (&shape1.hull, &shape2.hull);
    let pos12 = pose1.inv_mul(pose2);
    let Some((result, simplex)) = gjk(&pos12, shape1, shape2) else {
        return HullContact::Apart;
    };
    let (point1, point2_1, normal1) = match result {
        GJKResult::ClosestPoints(p1, p2, n) => (p1, p2, n),
        GJKResult::Intersection => match EPA::new().closest_points(&pos12, g1, g2, &simplex) {
            Some(found) => found,
            None => return HullContact::EpaFailed,
        },
        GJKResult::NoIntersection(_) | GJKResult::Proximity(_) => return HullContact::Apart,
    };
    let dist = (point2_1 - point1).dot(normal1);
    let point2 = pos12.inverse_transform_point(point2_1);
    let normal2 = pos12.rotation.inverse() * -normal1;
    let mut contact = parry3d_f64::query::Contact::new(point1, point2, normal1, normal2, dist);
    contact.transform_by_mut(pose1, pose2);
    HullContact::Touching(contact)
}

/// parry's GJK on the two hulls at prediction 0 (`pos12` takes body 2's frame to body 1's),
/// from the line of their centres, and the simplex it ends with (EPA's start); None where the
/// gap along that line already settles them apart.
fn gjk(
    pos12: &Pose,
    shape1: &Shape,
    shape2: &Shape,
) -> Option<(
    parry3d_f64::query::gjk::GJKResult,
    parry3d_f64::query::gjk::VoronoiSimplex,
)> {
    use parry3d_f64::math::Vector;
    use parry3d_f64::query::gjk::{self, CsoPoint, VoronoiSimplex};
    let (g1, g2) = (&shape1.hull, &shape2.hull);
    let dir = pos12.translation.try_normalize().unwrap_or(Vector::X);
    // GJK's first direction settles most pairs apart with one support point of each: at
    // scatter-10000, 71 % of the pairs whose boxes overlap and hulls do not.
    if apart_for_sure(dir, pos12, shape1, shape2) {
        return None;
    }
    let mut simplex = VoronoiSimplex::new();
    simplex.reset(CsoPoint::from_shapes(pos12, g1, g2, dir));
    let result = gjk::closest_points(pos12, g1, g2, 0.0, true, &mut simplex);
    Some((result, simplex))
}

/// Whether GJK finds the hulls touching or overlapping (without EPA: no depth asked).
fn hulls_meet(pos12: &Pose, shape1: &Shape, shape2: &Shape) -> bool {
    use parry3d_f64::query::gjk::GJKResult;
    match gjk(pos12, shape1, shape2) {
        Some((GJKResult::Intersection, _)) => true,
        Some((GJKResult::ClosestPoints(p1, p2, n), _)) => (p2 - p1).dot(n) <= 0.0,
        _ => false,
    }
}

/// The gap between two hulls along the unit `axis` (in body 1's frame; `pos12` takes body 2's
/// frame to body 1's): how far body 2's nearest point along the axis lies beyond body 1's
/// farthest, from one support point of each. Any axis bounds the distance from below, so a
/// positive gap proves the hulls apart by at least that much.
pub fn gap_along(axis: DVec3, pos12: &Pose, shape1: &Shape, shape2: &Shape) -> f64 {
    let reach1 = shape1.hull.local_support_point(axis).dot(axis);
    let toward1 = pos12.rotation.inverse() * -axis;
    let near2 = pos12.transform_point(shape2.hull.local_support_point(toward1));
    near2.dot(axis) - reach1
}

/// Whether the gap along the unit `axis` proves the hulls apart where GJK would find them apart
/// too, so that the answer is the same either way: GJK (at prediction 0) may call hulls
/// touching within `sqrt(10 eps)`, about 5e-8, of the pair's extent (parry's
/// `gjk::closest_points`; its support points, measured from the centres of mass, reach at most
/// about twice the extent taken here), and a millionth of it is far beyond that.
fn apart_for_sure(axis: DVec3, pos12: &Pose, shape1: &Shape, shape2: &Shape) -> bool {
    let gap = gap_along(axis, pos12, shape1, shape2);
    // The extent's three square roots only for a gap that may pass (the touching pairs' is not).
    gap > 0.0 && {
        let (h1, h2) = (shape1.local_box_half_extents, shape2.local_box_half_extents);
        let extent = 1.0 + pos12.translation.length() + h1.length() + h2.length();
        gap > SEPARATION_BEYOND_GJK * extent
    }
}

/// Share of a pair's extent by which [`apart_for_sure`] asks hulls to be apart.
const SEPARATION_BEYOND_GJK: f64 = 1e-6;

/// Contact between the hulls of two bodies at their current poses, if they touch or overlap.
/// parry's `normal1` points from shape 1 to shape 2, `-dist` is the depth and `point2` lies on
/// shape 2: exactly the coursework's `contactNormal`, `depth` and `penPosition`. When EPA fails
/// (it does on faces resting flush, the tower's case) the contact comes from [`sat_contact`].
pub fn body_contact(
    body1: &RigidBody,
    shape1: &Shape,
    body2: &RigidBody,
    shape2: &Shape,
) -> Detection {
    let (pose1, pose2) = (pose(body1), pose(body2));
    let contact = match hull_contact(&pose1, shape1, &pose2, shape2) {
        HullContact::Touching(c) => c,
        HullContact::Apart => return Detection::apart(),
        HullContact::EpaFailed => return sat_fallback(body1, shape1, body2, shape2),
    };
    let depth = -contact.dist;
    if depth.is_nan() || !contact.normal1.is_finite() || !contact.point2.is_finite() {
        return sat_fallback(body1, shape1, body2, shape2);
    }
    if depth < 0.0 {
        return Detection::apart();
    }
    Detection {
        contact: Some(Contact {
            depth,
            normal: contact.normal1,
            point2: contact.point2,
        }),
        fallback: false,
    }
}

fn sat_fallback(body1: &RigidBody, shape1: &Shape, body2: &RigidBody, shape2: &Shape) -> Detection {
    Detection {
        contact: sat_contact(body1, shape1, body2, shape2),
        fallback: true,
    }
}

/// Exact contact of two convex hulls by the separating axis theorem: the candidate axes are the
/// face normals of both hulls and the cross products of their edge directions (Gottschalk et al.
/// 1996, Ericson 2005 ch. 5.2.1); the axis of least overlap gives the depth and the normal (from
/// body 1 to body 2). The point on body 2 is its vertex deepest in body 1 when one vertex is;
/// when body 1 pokes a vertex into a face of body 2, that vertex moved back by the depth; on
/// faces or edges meeting flat, the middle of the two deepest features. None when an axis
/// separates the hulls.
pub fn sat_contact(
    body1: &RigidBody,
    shape1: &Shape,
    body2: &RigidBody,
    shape2: &Shape,
) -> Option<Contact> {
    let world = |body: &RigidBody, shape: &Shape| -> Vec<DVec3> {
        shape
            .hull
            .points()
            .iter()
            .map(|&p| body.world_point(p))
            .collect()
    };
    let (points1, points2) = (world(body1, shape1), world(body2, shape2));
    let mut best: Option<(f64, DVec3)> = None;
    for axis in sat_axes(body1, shape1, body2, shape2) {
        let (min1, max1) = extent(&points1, axis);
        let (min2, max2) = extent(&points2, axis);
        // Overlap if body 2 is pushed along +axis, or along -axis.
        let (depth, normal) = if max1 - min2 <= max2 - min1 {
            (max1 - min2, axis)
        } else {
            (max2 - min1, -axis)
        };
        // Separated along this axis (or not comparable: a non-finite pose).
        if depth.is_nan() || depth < 0.0 {
            return None;
        }
        if best.is_none_or(|(d, _)| depth < d) {
            best = Some((depth, normal));
        }
    }
    let (depth, normal) = best?;
    let (deepest2, count2) = extreme_feature(&points2, -normal);
    let (deepest1, count1) = extreme_feature(&points1, normal);
    let point2 = match (count2, count1) {
        (1, _) => deepest2,
        (_, 1) => deepest1 - depth * normal,
        _ => 0.5 * (deepest1 - depth * normal + deepest2),
    };
    Some(Contact {
        depth,
        normal,
        point2,
    })
}

/// Unit candidate axes: face normals of both hulls, then the normalised cross products of each
/// pair of distinct edge directions (parallel pairs skipped: the face axes cover them).
fn sat_axes(body1: &RigidBody, shape1: &Shape, body2: &RigidBody, shape2: &Shape) -> Vec<DVec3> {
    let normals = |body: &RigidBody, shape: &Shape| -> Vec<DVec3> {
        shape
            .hull
            .faces()
            .iter()
            .map(|f| body.orientation * f.normal)
            .collect()
    };
    let directions = |body: &RigidBody, shape: &Shape| -> Vec<DVec3> {
        let mut dirs: Vec<DVec3> = Vec::new();
        for e in shape.hull.edges() {
            let d = body.orientation * e.dir;
            if !dirs.iter().any(|u| u.cross(d).length_squared() < 1e-18) {
                dirs.push(d);
            }
        }
        dirs
    };
    let mut axes = normals(body1, shape1);
    axes.extend(normals(body2, shape2));
    let edges2 = directions(body2, shape2);
    for u in directions(body1, shape1) {
        for &v in &edges2 {
            let c = u.cross(v);
            if c.length_squared() > 1e-18 {
                axes.push(c.normalize());
            }
        }
    }
    axes
}

fn extent(points: &[DVec3], axis: DVec3) -> (f64, f64) {
    points
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
            let t = p.dot(axis);
            (lo.min(t), hi.max(t))
        })
}

/// The points furthest along `direction` (within a relative 1e-9): their mean and how many.
fn extreme_feature(points: &[DVec3], direction: DVec3) -> (DVec3, usize) {
    let (_, top) = extent(points, direction);
    let scale = points
        .iter()
        .map(|p| p.abs().max_element())
        .fold(1.0, f64::max);
    let tied: Vec<DVec3> = points
        .iter()
        .copied()
        .filter(|p| p.dot(direction) >= top - 1e-9 * scale)
        .collect();
    let mean = tied.iter().copied().sum::<DVec3>() / tied.len().max(1) as f64;
    (mean, tied.len())
}

/// Like [`body_contact`], but acting in the contact patch, the points where parry's contact
/// manifold (feature clipping) finds the hulls' faces overlapping: at its point nearest under the
/// centre of mass of the body resting there ([`patch_point`]), as on the ground. Between hulls
/// of few corners ([`sat_pays`]: boxes, tetrahedra, octahedra) the depth and normal are the
/// separating-axis test's, exact, where GJK finds the hulls meeting (so no fallback is counted):
/// on faces built exactly flush EPA's normal leans sideways (two plates rocked, their energy 2.7
/// times what it was after 5 s) and parry's manifold normal can be wrong outright (a box set
/// flush on another was pushed sideways by a contact 8 units deep, its size along z, and fell
/// through it; so did two plates). Between larger hulls, [`body_contact`]'s. Not taken from the
/// manifold:
/// - GJK's own point, which parry adds to the clipped ones, where there are others: one more
///   corner pulled the centroid off the patch's middle, and a box resting on another rocked
///   and gained 15 % of its energy in 10 s at dt 0.02 (found by review);
/// - any point, where the manifold's normal is not the contact's: the contact's own point
///   serves.
pub fn body_contact_patch(
    (body1, shape1): (&RigidBody, &Shape),
    (body2, shape2): (&RigidBody, &Shape),
    gravity: DVec3,
) -> Detection {
    use parry3d_f64::query::{ContactManifold, DefaultQueryDispatcher, PersistentQueryDispatcher};
    let pose12 = pose(body1).inv_mul(&pose(body2));
    let (contact, fallback) = if sat_pays(shape1, shape2) {
        let exact = hulls_meet(&pose12, shape1, shape2)
            .then(|| sat_contact(body1, shape1, body2, shape2))
            .flatten();
        (exact, false)
    } else {
        let single = body_contact(body1, shape1, body2, shape2);
        (single.contact, single.fallback)
    };
    let Some(contact) = contact else {
        return Detection {
            contact: None,
            fallback,
        };
    };
    let mut manifolds: Vec<ContactManifold<(), ()>> = Vec::new();
    let found = DefaultQueryDispatcher.contact_manifolds(
        &pose12,
        &shape1.hull,
        &shape2.hull,
        0.0,
        &mut manifolds,
        &mut None,
    );
    let point = match (found, manifolds.first()) {
        (Ok(()), Some(manifold)) => patch_point(manifold, (body1, body2), contact.normal, gravity),
        _ => None,
    };
    Detection {
        contact: Some(Contact {
            point2: point.unwrap_or(contact.point2),
            ..contact
        }),
        fallback,
    }
}

/// Whether the separating-axis test is cheap enough for every touching pair of these hulls: it
/// tries every pair of their edge directions against all their corners, which grows as the
/// product of their edges times their corners (one fuzzed world of tumble's meshes took 101 s
/// for its steps, 0.5 s with this limit). Boxes, tetrahedra and octahedra pass; cylinders and
/// ellipsoids do not.
fn sat_pays(shape1: &Shape, shape2: &Shape) -> bool {
    shape1.hull.points().len() + shape2.hull.points().len() <= SAT_MOST_CORNERS
}

/// Most corners of two hulls between which a patch takes the separating-axis test's contact.
const SAT_MOST_CORNERS: usize = 24;

/// The point a contact of `normal` (from body 1 to body 2) acts at in the patch of `manifold`'s
/// touching points on body 2, its clipped ones where it has any (GJK's point, with no feature on
/// either side, left out), where the manifold's normal is `normal`: the patch's point nearest
/// under the centre of mass of the body that rests there ([`patch_point_under`]): the body that
/// moves where the other is fixed, else the one on top under `gravity`. Where neither rests
/// (both move and the normal lies further than [`RESTING_NORMAL_COSINE`] from gravity, or there
/// is none), the patch's centroid. Its
/// centroid served for every pair until stop 73: a body resting on a face whose centroid is not
/// under its centre of mass rocked (the course's tetrahedron on a fixed `box_tri` gained 15 % of
/// its energy in 10 s at dt 0.02; found by review).
fn patch_point(
    manifold: &parry3d_f64::query::ContactManifold<(), ()>,
    (body1, body2): (&RigidBody, &RigidBody),
    normal: DVec3,
    gravity: DVec3,
) -> Option<DVec3> {
    let along = (body1.orientation * manifold.local_n1).try_normalize()?;
    if along.dot(normal) < 1.0 - 1e-6 {
        return None;
    }
    let touching = || manifold.points.iter().filter(|p| p.dist <= 0.0);
    let clipped = || touching().filter(|p| p.fid1.0 != 0 || p.fid2.0 != 0);
    let chosen: SmallVec<[DVec3; 16]> = match clipped().next() {
        Some(_) => clipped().map(|p| body2.world_point(p.local_p2)).collect(),
        None => touching().map(|p| body2.world_point(p.local_p2)).collect(),
    };
    let mean = chosen.iter().sum::<DVec3>() / chosen.len() as f64;
    if chosen.is_empty() || !mean.is_finite() {
        return None;
    }
    // How far the normal points down (from body 1 to body 2 below it), or up.
    let down = normal.dot(gravity.normalize_or_zero());
    let resting = match (body1.is_dynamic(), body2.is_dynamic()) {
        (true, false) => Some(body1),
        (false, true) => Some(body2),
        _ if down > RESTING_NORMAL_COSINE => Some(body1),
        _ if down < -RESTING_NORMAL_COSINE => Some(body2),
        _ => None,
    };
    let point = resting.map_or(mean, |b| patch_point_under(b.position, &chosen, normal));
    point.is_finite().then_some(point)
}

/// Between two bodies that move, one rests on the other where the contact's normal lies within
/// 60 degrees of gravity (the cosine of their angle above this): closer to across gravity, a
/// rounding of the normal's sign would pick one body in one step and the other in the next.
const RESTING_NORMAL_COSINE: f64 = 0.5;

/// Contact with the ground plane y = 0, whose body is immovable and plays body 2: depth is minus
/// the lowest vertex's height, normal `(0,-1,0)`, point the lowest vertex (first one on ties).
/// With `patch`, the point is instead the point of the patch of the hull's corners at or below
/// the ground nearest under the centre of mass ([`ground_patch_point`]). Corners only: a vertex
/// inside the hull spans no patch (a box's centre, below the ground only when it is half sunk).
pub fn ground_contact(body: &RigidBody, shape: &Shape, patch: bool) -> Option<Contact> {
    let mut lowest = DVec3::splat(f64::INFINITY);
    let mut below: SmallVec<[DVec3; 16]> = SmallVec::new();
    for (k, &v) in shape.rest_vertices.iter().enumerate() {
        let p = body.world_point(v);
        if p.y < lowest.y {
            lowest = p;
        }
        // The flags read only for a patch: the default's ground stage reads every vertex of
        // every body each step.
        if patch && p.y <= 0.0 && shape.on_hull.get(k) == Some(&true) {
            below.push(p);
        }
    }
    if lowest.y.is_nan() || lowest.y > 0.0 {
        return None;
    }
    // The lowest vertex is a corner of the hull, so a patch has one at least (but for rounding,
    // where the lowest point serves).
    let point2 = if patch && !below.is_empty() {
        ground_patch_point(body.position, &below)
    } else {
        lowest
    };
    Some(Contact {
        depth: -lowest.y,
        normal: DVec3::NEG_Y,
        point2,
    })
}
