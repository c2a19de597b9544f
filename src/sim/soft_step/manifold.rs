//! Contact manifolds: up to four points per touching (or about to touch) pair, each with a
//! feature key that names the same point from one step to the next, so the solver can start
//! from the impulses it found last time (warm starting).
//!
//! Body-body manifolds come from parry's polyhedral feature clipping with a prediction distance
//! (speculative contacts: points up to that far apart are kept, and the solver lets the bodies
//! close the gap but no more); the features come from GJK on the hulls, or for two boxes from
//! the box-box separating-axis test (15 axes, as in Gottschalk's OBB test and Box2D's polygon
//! collider). Ground manifolds are the hull vertices within the prediction
//! distance of the plane y = 0.

use crate::sim::body::RigidBody;
use crate::sim::narrow_phase::gap_along;
use crate::sim::shape::Shape;
use glam::{DQuat, DVec3};
use parry3d_f64::math::Pose;
use parry3d_f64::query::ContactManifold;
use parry3d_f64::query::details::{contact_manifold_cuboid_cuboid, contact_manifold_pfm_pfm};
use parry3d_f64::shape::Cuboid;
use smallvec::{SmallVec, smallvec};

/// Index standing for the ground plane in a manifold's `body1`.
pub const GROUND: usize = usize::MAX;

/// Most points a manifold keeps.
pub const MAX_POINTS: usize = 4;

/// A manifold's points before the reduction, on the stack up to eight (a box face clipped
/// against another, or a box's lower face near the ground). On the heap, one or two vectors a
/// manifold, made on one thread and freed on another, they made the threads wait on each other
/// at the allocator's lock (pile-10000 `--accurate`, 250 steps on two threads: 11.6 -> 11.1 s).
type Candidates = SmallVec<[ManifoldPoint; 8]>;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ManifoldPoint {
    /// Where the two surfaces meet (midway between them), world space.
    pub point: DVec3,
    /// Signed distance along the normal between the surfaces: negative when penetrating.
    pub separation: f64,
    /// Names the pair of features (vertex, edge, face) the point comes from.
    pub key: u64,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Manifold {
    /// The first body, or [`GROUND`].
    pub body1: usize,
    pub body2: usize,
    /// Unit normal from body 1 towards body 2, world space.
    pub normal: DVec3,
    slots: [ManifoldPoint; MAX_POINTS],
    count: usize,
}

impl Manifold {
    pub(super) fn new(body1: usize, body2: usize, normal: DVec3, points: &[ManifoldPoint]) -> Self {
        let mut slots = [ManifoldPoint {
            point: DVec3::ZERO,
            separation: 0.0,
            key: 0,
        }; MAX_POINTS];
        let count = points.len().min(MAX_POINTS);
        slots[..count].copy_from_slice(&points[..count]);
        Self {
            body1,
            body2,
            normal,
            slots,
            count,
        }
    }

    pub fn points(&self) -> &[ManifoldPoint] {
        &self.slots[..self.count]
    }
}

fn pose(body: &RigidBody) -> Pose {
    Pose::from_parts(body.position, body.orientation)
}

/// What parry keeps of a pair from one step to the next: its last manifold. GJK starts from
/// its normal, and a pair whose relative pose barely changed keeps its points with updated
/// separations instead of a new query (parry's `try_update_contacts`).
pub type PairState = ContactManifold<(), ()>;

/// The manifold between bodies `i < j` with points up to `prediction` apart, or None, kept
/// for a step of `dt` (see [`reduce`]); `state` is the pair's from the last step, updated.
/// Two boxes meet through parry's box-box separating-axis test and face clipping (about 4x
/// cheaper than GJK and clipping on their hulls, measured on box pairs in contact); other pairs
/// through GJK on the hulls. A pair found apart is not queried while its gap along its last
/// normal stays beyond `prediction` (two support points instead of parry's set-up and GJK:
/// pile-200's narrow phase at dt 0.005 on one thread 0.38 -> 0.25 ms a step, where 470 of 800
/// candidate pairs a step are apart).
pub fn body_manifold(
    (i, body1): (usize, &RigidBody),
    (j, body2): (usize, &RigidBody),
    shapes: &[Shape],
    (prediction, dt): (f64, f64),
    state: &mut PairState,
) -> Option<Manifold> {
    let (shape1, shape2) = (&shapes[body1.shape], &shapes[body2.shape]);
    let pos12 = pose(body1).inv_mul(&pose(body2));
    if state.points.is_empty() && gap_along_cached_axis(state, &pos12, shape1, shape2) > prediction
    {
        return None;
    }
    if shape1.is_box && shape2.is_box {
        // parry's boxes are centred on their frames; ours on the centre of mass.
        let (c1, c2) = (shape1.local_box_center, shape2.local_box_center);
        let boxes12 = Pose::from_translation(-c1) * pos12 * Pose::from_translation(c2);
        contact_manifold_cuboid_cuboid(
            &boxes12,
            &Cuboid::new(shape1.local_box_half_extents),
            &Cuboid::new(shape2.local_box_half_extents),
            prediction,
            state,
        );
        return from_parry(state, (i, body1, c1), (j, body2, c2), (prediction, dt));
    }
    contact_manifold_pfm_pfm(
        &pos12,
        &shape1.hull,
        0.0,
        None,
        &shape2.hull,
        0.0,
        None,
        prediction,
        state,
    );
    from_parry(
        state,
        (i, body1, DVec3::ZERO),
        (j, body2, DVec3::ZERO),
        (prediction, dt),
    )
}

/// A lower bound of the distance between the two hulls: their gap along the pair's last
/// normal (GJK's separating direction when it found them apart), or along the line of their
/// centres. Any axis bounds the distance from below, so a gap beyond the prediction distance
/// proves the query would find nothing.
fn gap_along_cached_axis(state: &PairState, pos12: &Pose, shape1: &Shape, shape2: &Shape) -> f64 {
    let axis = match state.local_n1.try_normalize() {
        Some(axis) => axis,
        None => match pos12.translation.try_normalize() {
            Some(axis) => axis,
            None => return f64::NEG_INFINITY,
        },
    };
    gap_along(axis, pos12, shape1, shape2)
}

/// Each candidate pair's [`PairState`], kept in the pairs' (sorted) order.
#[derive(Debug, Clone, Default)]
pub struct PairStates {
    pairs: Vec<(u32, u32)>,
    states: Vec<PairState>,
}

impl PairStates {
    /// The states of `pairs` (sorted): last step's for the pairs it had, fresh ones for the
    /// others; the pairs that are gone are dropped.
    pub fn take_for(&mut self, pairs: &[(u32, u32)]) -> Vec<PairState> {
        let mut old = self.pairs.iter().zip(self.states.iter_mut()).peekable();
        pairs
            .iter()
            .map(|pair| {
                while old.next_if(|(p, _)| *p < pair).is_some() {}
                match old.next_if(|(p, _)| *p == pair) {
                    Some((_, state)) => std::mem::take(state),
                    None => PairState::default(),
                }
            })
            .collect()
    }

    /// Keeps this step's states of `pairs` for the next. The point buffers of pairs that are
    /// not touching are freed: parry keeps the room a clip once needed (eight points on
    /// average), 14 MiB at scatter-100000, where most candidate pairs do not touch.
    pub fn keep(&mut self, pairs: &[(u32, u32)], mut states: Vec<PairState>) {
        for state in states.iter_mut().filter(|s| s.points.is_empty()) {
            state.points = Vec::new();
        }
        self.pairs.clear();
        self.pairs.extend_from_slice(pairs);
        self.states = states;
    }

    pub fn heap_bytes(&self) -> usize {
        let points: usize = self.states.iter().map(|s| s.points.capacity()).sum();
        self.pairs.capacity() * 8
            + self.states.capacity() * std::mem::size_of::<PairState>()
            + points * std::mem::size_of::<parry3d_f64::query::TrackedContact<()>>()
    }
}

/// tumble's manifold from parry's (points beyond `prediction` dropped, at most four kept for a
/// step of `dt`); each shape's frame in parry lies at `offset` in its body's frame.
fn from_parry(
    found: &ContactManifold<(), ()>,
    (i, body1, offset1): (usize, &RigidBody, DVec3),
    (j, body2, offset2): (usize, &RigidBody, DVec3),
    (prediction, dt): (f64, f64),
) -> Option<Manifold> {
    let normal = (body1.orientation * found.local_n1).normalize_or_zero();
    if normal == DVec3::ZERO || !normal.is_finite() {
        return None;
    }
    let points: Candidates = found
        .points
        .iter()
        .filter(|p| p.dist <= prediction && p.dist.is_finite())
        .map(|p| {
            let on1 = body1.world_point(p.local_p1 + offset1);
            let on2 = body2.world_point(p.local_p2 + offset2);
            ManifoldPoint {
                point: 0.5 * (on1 + on2),
                separation: p.dist,
                key: ((p.fid1.0 as u64) << 32) | p.fid2.0 as u64,
            }
        })
        .collect();
    let mut points = without_repeated_gjk_point(points);
    // The deepest first, as the reduction below orders them: Gauss-Seidel settles a stack of
    // five boxes at dt = 0.04 to a third of the jitter it keeps in parry's clipping order.
    if !points.is_empty() {
        let deepest = argmax(&points, |p| -p.separation);
        points.swap(0, deepest);
    }
    let ahead = |p: &ManifoldPoint| {
        let (v1, v2) = (
            body1.point_velocity(p.point - body1.position),
            body2.point_velocity(p.point - body2.position),
        );
        separation_ahead(p, normal.dot(v2 - v1), dt)
    };
    (!points.is_empty()).then(|| Manifold::new(i, j, normal, &reduce(points, normal, ahead)))
}

/// parry adds GJK's closest points to the clipped ones in 3D, with no feature id (key 0); where
/// the deepest feature is a vertex it is one of them again. Kept twice, the point would be
/// warm-started twice from last step's impulse there (the nearest-point match) and push the
/// bodies apart: resting piles jittered at 0.07 units/s.
fn without_repeated_gjk_point(mut points: Candidates) -> Candidates {
    const SAME_POINT: f64 = 1e-6;
    let Some(k) = points.iter().position(|p| p.key == 0) else {
        return points;
    };
    let at = points[k].point;
    if points
        .iter()
        .any(|q| q.key != 0 && (q.point - at).length() <= SAME_POINT)
    {
        points.remove(k);
    }
    points
}

/// The manifold between the ground plane (body 1, normal +y) and body `j`: the hull vertices
/// lower than `prediction`, reduced to four for a step of `dt`.
pub fn ground_manifold(
    j: usize,
    body: &RigidBody,
    shape: &Shape,
    (prediction, dt): (f64, f64),
) -> Option<Manifold> {
    let points: Candidates = shape
        .hull
        .points()
        .iter()
        .enumerate()
        .filter_map(|(k, &local)| {
            let p = body.world_point(local);
            (p.y <= prediction).then_some(ManifoldPoint {
                point: DVec3::new(p.x, 0.5 * p.y, p.z),
                separation: p.y,
                key: k as u64,
            })
        })
        .collect();
    let ahead =
        |p: &ManifoldPoint| separation_ahead(p, body.point_velocity(p.point - body.position).y, dt);
    (!points.is_empty())
        .then(|| Manifold::new(GROUND, j, DVec3::Y, &reduce(points, DVec3::Y, ahead)))
}

/// At most [`MAX_POINTS`] of `points` that keep the patch's extent: the deepest (see
/// [`anchor_point`]), the one farthest from it, the one spanning the largest triangle with
/// those two, and the one lying farthest outside that triangle (the reduction of Box2D and
/// Rapier, in 3D). Points are weighed by `ahead`, their separation at the step's end if the
/// bodies kept their velocities (see [`separation_ahead`]): a body spinning onto a face brings
/// its far edge down while the touching one lifts. Weighed by their separation now, a box of
/// scatter-1000 turning at 9 rad/s kept four points on its lifting side and sank 1.5 units (a
/// quarter of its height) into the box below in one step.
fn reduce(
    mut points: Candidates,
    normal: DVec3,
    ahead: impl Fn(&ManifoldPoint) -> f64,
) -> Candidates {
    if points.len() <= MAX_POINTS {
        return points;
    }
    let a = points.swap_remove(anchor_point(&points));
    // Each criterion is weighed down by how much farther apart than the anchor a point is, so
    // a point about to touch is not dropped for a wider one still far off: an octahedron in
    // pile-10000 resting on two points of a neighbour lost one of them to a point 19 mm apart
    // whenever a fifth came within reach, fell onto it, was pushed back, and rocked at up to
    // 0.15 units/s for 12 s, keeping the pile awake.
    let a_ahead = ahead(&a);
    let near =
        |p: &ManifoldPoint| REDUCTION_SLOP / (REDUCTION_SLOP + (ahead(p) - a_ahead).max(0.0));
    let far = argmax(&points, |p| (p.point - a.point).length() * near(p));
    let b = points.swap_remove(far);
    let area = |p: &ManifoldPoint| (b.point - a.point).cross(p.point - a.point).dot(normal);
    let wide = argmax(&points, |p| area(p).abs() * near(p));
    let c = points.swap_remove(wide);
    // Orient the triangle along the normal, then take the point most outside one of its edges.
    let (b, c) = if area(&c) < 0.0 { (c, b) } else { (b, c) };
    let outside = |p: &ManifoldPoint| {
        [(a, b), (b, c), (c, a)]
            .iter()
            .map(|(u, v)| (v.point - u.point).cross(p.point - u.point).dot(normal))
            .fold(f64::INFINITY, f64::min)
    };
    let d = argmax(&points, |p| -outside(p) * near(p));
    let mut kept: Candidates = smallvec![a, b, c];
    if outside(&points[d]) < 0.0 {
        kept.push(points[d]);
    }
    kept
}

/// What [`reduce`] weighs point `p` by: its separation at the step's end if it kept closing at
/// `normal_velocity`, where that closing is more than [`REDUCTION_SLOP`]; its separation now
/// otherwise, so that a patch rocking by a hair keeps its points (weighed by every closing, a
/// stack of five turned boxes crept by 0.13 in 10 s).
fn separation_ahead(p: &ManifoldPoint, normal_velocity: f64, dt: f64) -> f64 {
    p.separation + (dt * normal_velocity + REDUCTION_SLOP).min(0.0)
}

/// Depth within which points count as equally deep for the reduction (units; Box2D's
/// linear slop).
const REDUCTION_SLOP: f64 = 0.005;

/// The point the reduction starts from: the deepest, or where others lie within
/// [`REDUCTION_SLOP`] of its depth, the one of them with the smallest feature key (parry's GJK
/// point or the ground's first vertex, key 0, last). On a patch nearly flat the deepest point
/// changes with every rocking by a hair, and with it the four points kept and the friction
/// anchor at their centre: a column of eight boxes left standing in pile-10000 crept across the
/// ground at 0.004 units/s and swayed at up to 0.06, keeping the pile awake for ever (Rapier,
/// solving all the points, holds it still); started by feature it stands, drift 0.019 in 20 s.
fn anchor_point(points: &[ManifoldPoint]) -> usize {
    let deepest = points[argmax(points, |p| -p.separation)].separation;
    let rank = |p: &ManifoldPoint| match p.key {
        0 => u64::MAX,
        key => key,
    };
    points
        .iter()
        .enumerate()
        .filter(|(_, p)| p.separation <= deepest + REDUCTION_SLOP)
        .min_by_key(|(_, p)| rank(p))
        .map_or(0, |(k, _)| k)
}

fn argmax(points: &[ManifoldPoint], score: impl Fn(&ManifoldPoint) -> f64) -> usize {
    let mut best = (0, f64::NEG_INFINITY);
    for (k, p) in points.iter().enumerate() {
        let s = score(p);
        if s > best.1 {
            best = (k, s);
        }
    }
    best.0
}

/// How far a body can travel in `dt`: its speed plus the rim speed of its spin over its
/// bounding radius, plus what gravity adds, times `dt` (the speculative margin).
pub fn motion_bound(body: &RigidBody, radius: f64, gravity: DVec3, dt: f64) -> f64 {
    if !body.is_dynamic() {
        return 0.0;
    }
    let speed = body.linear_velocity.length() + body.angular_velocity.length() * radius;
    (speed + gravity.length() * dt) * dt
}

/// Rotation that takes `from` to `to` (both world orientations): `to from^-1`.
pub fn delta_rotation(from: DQuat, to: DQuat) -> DQuat {
    to * from.conjugate()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(x: f64, z: f64, separation: f64) -> ManifoldPoint {
        ManifoldPoint {
            point: DVec3::new(x, 0.0, z),
            separation,
            key: 0,
        }
    }

    /// An octahedron standing on a vertex pressed into a box's top face: parry clips the vertex
    /// against the face and adds GJK's closest point, the same vertex again.
    #[test]
    fn a_vertex_on_a_face_is_one_point() {
        use crate::scene::assets;
        let cube = Shape::from_tet_mesh(&assets::cuboid(DVec3::splat(1.0))).unwrap();
        let octahedron = Shape::from_tet_mesh(&assets::octahedron(DVec3::splat(0.5))).unwrap();
        let shapes = [cube, octahedron];
        let at = |shape: usize, y: f64| {
            let tilt = DQuat::from_rotation_z(0.05);
            RigidBody::on_shape(&shapes[shape], shape, 1.0, false, DVec3::Y * y, tilt)
        };
        let (low, high) = (at(0, 0.0), at(1, 1.49));
        let mut state = PairState::default();
        let m = body_manifold((0, &low), (1, &high), &shapes, (0.1, 0.02), &mut state).unwrap();
        let points = m.points();
        assert!(!points.is_empty());
        for (k, p) in points.iter().enumerate() {
            for q in &points[k + 1..] {
                assert!((p.point - q.point).length() > 1e-6, "{points:?}");
            }
        }
    }

    /// Five candidates on a rocking body: it rests on the two points at z = 0 and the three at
    /// z = 1 are speculative, one 3 mm and two 20 mm off. Unweighed, the points 20 mm off span
    /// more, and the reduction kept them and dropped the one about to touch.
    #[test]
    fn reduction_keeps_a_point_about_to_touch_over_a_wider_one_far_off() {
        let points: Candidates = smallvec![
            point(0.0, 0.0, -0.001),
            point(2.0, 0.0, -0.0005),
            point(1.0, 1.0, 0.003),
            point(-0.2, 1.2, 0.02),
            point(2.2, 1.2, 0.02),
        ];
        let kept = reduce(points, DVec3::Y, |p| p.separation);
        assert_eq!(kept.len(), 4);
        assert!(kept.iter().any(|p| p.separation == 0.003), "{kept:?}");
        assert!(kept.iter().filter(|p| p.separation <= 0.0).count() == 2);
    }

    #[test]
    fn reduction_keeps_the_deepest_and_the_corners() {
        // A 24-gon cap seen from below with one point slightly deeper.
        let mut points: Candidates = (0..24)
            .map(|k| {
                let t = k as f64 * std::f64::consts::TAU / 24.0;
                point(t.cos(), t.sin(), -0.01)
            })
            .collect();
        points[5].separation = -0.02;
        let kept = reduce(points, DVec3::Y, |p| p.separation);
        assert_eq!(kept.len(), 4);
        assert_eq!(kept[0].separation, -0.02);
        // Spread around the rim (an inscribed square has sides of 1.41), not bunched.
        for (k, p) in kept.iter().enumerate() {
            for q in &kept[k + 1..] {
                let d = (p.point - q.point).length();
                assert!(d > 1.0, "{d}");
            }
        }
    }

    /// An irregular eight-point patch (two boxes' faces overlapping at an angle) rocking by a
    /// hair: the points' depths change from step to step by under the slop, and the four
    /// kept, started from by feature, stay the same ones; started from the deepest alone they
    /// change with it.
    #[test]
    fn reduction_keeps_its_points_while_the_patch_rocks_by_a_hair() {
        let angles = [0.1, 0.7, 1.2, 2.0, 2.9, 3.6, 4.4, 5.5];
        let patch = |(tx, tz): (f64, f64)| -> Candidates {
            angles
                .iter()
                .enumerate()
                .map(|(k, &t)| {
                    let (x, z) = (2.0 * f64::cos(t), f64::sin(t));
                    ManifoldPoint {
                        key: 10 + k as u64,
                        ..point(x, z, -0.01 + tx * x + tz * z)
                    }
                })
                .collect()
        };
        let keys = |points: Candidates| -> Vec<u64> {
            let mut keys: Vec<u64> = reduce(points, DVec3::Y, |p| p.separation)
                .iter()
                .map(|p| p.key)
                .collect();
            keys.sort();
            keys
        };
        let tilts = [
            (1e-4, 0.0),
            (-1e-4, 0.0),
            (0.0, 3e-4),
            (0.0, -3e-4),
            (1e-4, 1e-4),
        ];
        let kept: Vec<Vec<u64>> = tilts.iter().map(|&t| keys(patch(t))).collect();
        assert!(kept.iter().all(|k| k == &kept[0]), "{kept:?}");
    }

    /// A small box resting flat and slightly sunk (0.01) on a large one, off its centre: four
    /// points at the corners of the overlap rectangle, each 0.01 deep, normal straight up.
    #[test]
    fn box_on_box_is_the_overlap_rectangle() {
        use crate::scene::assets;
        let shapes = [
            Shape::from_tet_mesh(&assets::cuboid(DVec3::new(2.0, 0.5, 2.0))).unwrap(),
            Shape::from_tet_mesh(&assets::cuboid(DVec3::new(1.0, 0.5, 1.0))).unwrap(),
        ];
        assert!(shapes[0].is_box && shapes[1].is_box);
        let at = |shape: usize, p: DVec3| {
            RigidBody::on_shape(&shapes[shape], shape, 1.0, false, p, DQuat::IDENTITY)
        };
        let (low, high) = (at(0, DVec3::ZERO), at(1, DVec3::new(1.5, 0.99, 0.5)));
        let mut state = PairState::default();
        let m = body_manifold((0, &low), (1, &high), &shapes, (0.1, 0.02), &mut state).unwrap();
        assert!((m.normal - DVec3::Y).length() < 1e-12, "{:?}", m.normal);
        let mut corners: Vec<(f64, f64)> = m
            .points()
            .iter()
            .map(|p| {
                assert!((p.separation + 0.01).abs() < 1e-9, "{p:?}");
                assert!((p.point.y - 0.495).abs() < 1e-9, "{p:?}");
                (p.point.x, p.point.z)
            })
            .collect();
        corners.sort_by(|a, b| a.partial_cmp(b).unwrap());
        let expected = [(0.5, -0.5), (0.5, 1.5), (2.0, -0.5), (2.0, 1.5)];
        assert_eq!(corners.len(), 4);
        for (c, e) in corners.iter().zip(expected) {
            assert!(
                (c.0 - e.0).abs() < 1e-9 && (c.1 - e.1).abs() < 1e-9,
                "{corners:?}"
            );
        }
    }

    /// The gap along any axis is a lower bound of the hulls' distance (parry's), so a pair
    /// skipped on it has no manifold: random shapes, poses and cached axes.
    #[test]
    fn the_gap_along_an_axis_never_exceeds_the_distance() {
        use crate::scene::assets;
        let shapes: Vec<Shape> = [
            assets::cuboid(DVec3::new(1.5, 0.75, 1.0)),
            assets::tetrahedron(1.5),
            assets::octahedron(DVec3::new(1.2, 0.6, 0.9)),
        ]
        .iter()
        .map(|mesh| Shape::from_tet_mesh(mesh).unwrap())
        .collect();
        let mut rng = crate::sim::rng::Rng::new(11);
        let mut unit = move || DVec3::new(rng.unit(), rng.unit(), rng.unit()) * 2.0 - DVec3::ONE;
        let mut skipped = 0;
        for k in 0..3000 {
            let (s1, s2) = (&shapes[k % 3], &shapes[(k / 3) % 3]);
            let q = DQuat::from_scaled_axis(3.0 * unit());
            let pos12 = Pose::from_parts(4.0 * unit(), q);
            let mut state = PairState::default();
            if k % 4 != 0 {
                state.local_n1 = unit().normalize_or(DVec3::X);
            }
            let gap = gap_along_cached_axis(&state, &pos12, s1, s2);
            let distance =
                parry3d_f64::query::distance(&Pose::IDENTITY, &s1.hull, &pos12, &s2.hull)
                    .unwrap()
                    .distance;
            assert!(
                gap <= distance + 1e-12,
                "pair {k}: gap {gap} > distance {distance}"
            );
            skipped += usize::from(gap > 0.1);
        }
        assert!(skipped > 300, "{skipped}");
    }

    /// Box pairs in contact at random poses, one box with its centre of mass off its centre (a
    /// tetrahedron counted twice): the separating-axis path finds the normal and the depth that
    /// GJK and EPA find on the same hulls.
    #[test]
    fn box_pairs_agree_with_the_hull_path() {
        use crate::scene::assets;
        let mut lopsided = assets::cuboid(DVec3::new(1.0, 0.4, 0.7));
        lopsided.tetrahedra.push(lopsided.tetrahedra[0]);
        let boxes = [
            Shape::from_tet_mesh(&assets::cuboid(DVec3::new(1.5, 0.5, 1.0))).unwrap(),
            Shape::from_tet_mesh(&lopsided).unwrap(),
        ];
        assert!(boxes.iter().all(|s| s.is_box));
        assert!(boxes[1].local_box_center.length() > 0.01);
        let hulls = boxes.clone().map(|s| Shape { is_box: false, ..s });
        let mut rng = crate::sim::rng::Rng::new(99);
        let mut compared = 0;
        for _ in 0..400 {
            let axis = DVec3::new(rng.unit(), rng.unit(), rng.unit()) - 0.5;
            let turn = DQuat::from_axis_angle(axis.normalize(), 6.3 * rng.unit());
            let offset = DVec3::new(rng.unit() - 0.5, 0.0, rng.unit() - 0.5) * 2.0;
            let p = offset + DVec3::Y * (0.6 + 1.2 * rng.unit());
            let low = RigidBody::on_shape(&boxes[0], 0, 1.0, false, DVec3::ZERO, DQuat::IDENTITY);
            let high = RigidBody::on_shape(&boxes[1], 1, 1.0, false, p, turn);
            let manifold = |shapes: &[Shape]| {
                let mut state = PairState::default();
                body_manifold((0, &low), (1, &high), shapes, (0.0, 0.02), &mut state)
            };
            let (Some(sat), Some(gjk)) = (manifold(&boxes), manifold(&hulls)) else {
                continue;
            };
            let deepest =
                |m: &Manifold| m.points().iter().map(|p| p.separation).fold(0.0, f64::min);
            assert!(sat.normal.dot(gjk.normal) > 1.0 - 1e-6, "{sat:?} {gjk:?}");
            assert!(
                (deepest(&sat) - deepest(&gjk)).abs() < 1e-6,
                "{sat:?} {gjk:?}"
            );
            // Each point's ends (half the separation either way) lie on their boxes.
            let on = |body: &RigidBody, shape: &Shape, world: DVec3| {
                let local = body.orientation.inverse() * (world - body.position);
                let from_centre = (local - shape.local_box_center).abs();
                (from_centre - shape.local_box_half_extents).max_element() < 1e-6
            };
            for p in sat.points() {
                let half = 0.5 * p.separation * sat.normal;
                assert!(on(&low, &boxes[0], p.point - half), "{p:?}");
                assert!(on(&high, &boxes[1], p.point + half), "{p:?}");
            }
            compared += 1;
        }
        assert!(compared > 50, "{compared}");
    }
}
