//! Contact constraints of the soft-step solver. Each manifold point has a normal impulse,
//! clamped non-negative, corrected softly when penetrating and speculative when apart, a
//! manifold's points solved together ([`super::normal_block`]); friction acts per manifold, as
//! Rapier's "simplified" model does: a tangential impulse in two directions at the patch's
//! centre, clamped to the disc `mu` times the points' total normal impulse, and a twist impulse
//! about the normal clamped to the same times the patch's radius (at least
//! [`MIN_TWIST_RADIUS`]).
//! One friction anchor per patch has no points to rock between (per-point friction lets a box
//! on an incline walk down it a point at a time). Impulses are warm-started from the previous
//! step: normal ones by feature key, friction by body pair.

use super::constraint_graph::{Colours, Shared, with_pair};
use super::manifold::{GROUND, MAX_POINTS, Manifold, ManifoldPoint};
use super::normal_block;
use super::softness::Softness;
use super::solver_body::SolverBody;
use crate::sim::{buffer, parallel};
use glam::{DMat3, DQuat, DVec3};
use rayon::prelude::*;
use std::mem::MaybeUninit;

/// Smallest lever of the twist friction (units): a contact at one point is a small patch of
/// the touching surfaces, not a point (as MuJoCo's torsional friction and Bullet's spinning
/// friction take it). With none, a body held at one point by each of two others swings about
/// the line through the two points as about a frictionless hinge, the points not slipping: in
/// pile-200 at dt 0.005 a tetrahedron in such a groove swung at up to 0.25 units/s for seconds
/// on end, and kept its island awake.
pub const MIN_TWIST_RADIUS: f64 = 0.01;

/// One direction `d` of a contact's Jacobian: the angular parts `r_i x d` and the angular
/// responses `I_i^-1 (r_i x d)` to a unit impulse (the arms and inertias are those of the
/// step's start), so a row costs a few dot products. The step keeps only the responses
/// ([`Responses`]) and forms the angular parts again from the arms where the row is used, the
/// same bits (two cross products against 48 bytes a row: 17 MiB of scatter-100000's peak
/// heap). Forming the responses there too would take about 28 MiB more, at 7-8 % of a
/// one-thread step of pile-1000 or scatter-10000.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Direction {
    ang1: DVec3,
    ang2: DVec3,
    inv1: DVec3,
    inv2: DVec3,
}

/// What the step keeps of a [`Direction`]: its angular responses `I_1^-1 (r_1 x d)` and
/// `I_2^-1 (r_2 x d)`.
type Responses = (DVec3, DVec3);

impl Direction {
    /// The direction `d` at arms `r1`, `r2`, and its effective mass (zero if nothing moves).
    fn new(b1: &SolverBody, r1: DVec3, b2: &SolverBody, r2: DVec3, d: DVec3) -> (Self, f64) {
        let (ang1, ang2) = (r1.cross(d), r2.cross(d));
        let (inv1, inv2) = (b1.inverse_inertia * ang1, b2.inverse_inertia * ang2);
        let k = b1.inverse_mass + b2.inverse_mass + ang1.dot(inv1) + ang2.dot(inv2);
        let mass = if k > 0.0 { 1.0 / k } else { 0.0 };
        (
            Self {
                ang1,
                ang2,
                inv1,
                inv2,
            },
            mass,
        )
    }

    /// The direction `d` at arms `(r1, r2)` whose responses were kept.
    #[inline]
    fn at((r1, r2): (DVec3, DVec3), d: DVec3, (inv1, inv2): Responses) -> Self {
        Self {
            ang1: r1.cross(d),
            ang2: r2.cross(d),
            inv1,
            inv2,
        }
    }

    fn responses(&self) -> Responses {
        (self.inv1, self.inv2)
    }

    /// Relative velocity of the points along `d` (body 2 against body 1).
    #[inline]
    pub fn velocity(&self, d: DVec3, b1: &SolverBody, b2: &SolverBody) -> f64 {
        d.dot(b2.linear_velocity - b1.linear_velocity) + self.ang2.dot(b2.angular_velocity)
            - self.ang1.dot(b1.angular_velocity)
    }

    /// Applies `impulse` along `d` to body 2 and its opposite to body 1.
    #[inline]
    pub fn apply(&self, d: DVec3, impulse: f64, b1: &mut SolverBody, b2: &mut SolverBody) {
        b1.linear_velocity -= (b1.inverse_mass * impulse) * d;
        b1.angular_velocity -= impulse * self.inv1;
        b2.linear_velocity += (b2.inverse_mass * impulse) * d;
        b2.angular_velocity += impulse * self.inv2;
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ContactPoint {
    /// Arms from the centres of mass to the point, world space, at the start of the step.
    pub r1: DVec3,
    pub r2: DVec3,
    /// The normal row's responses (see [`ContactPoint::along_normal`]) and effective mass.
    normal_responses: Responses,
    pub normal_mass: f64,
    /// Separation at the start of the step (negative: penetration).
    pub separation: f64,
    /// Accumulated normal impulse.
    pub normal_impulse: f64,
    /// What the restitution pass added to the normal impulse (not carried to the next step:
    /// warm starting it would push the bodies apart again in every substep).
    pub restitution_impulse: f64,
    /// Largest normal impulse of the step: the point really touched.
    pub max_normal_impulse: f64,
    /// Energy of the approach along the normal at the moment of impact (see
    /// [`impact_energy`]), recorded by the substep that stopped the approach; zero when none.
    pub impact_energy: f64,
}

impl ContactPoint {
    /// The Jacobian row along the manifold's normal `n`.
    #[inline]
    pub fn along_normal(&self, n: DVec3) -> Direction {
        Direction::at((self.r1, self.r2), n, self.normal_responses)
    }
}

/// Friction of one manifold, anchored at its patch's centre. The coefficient is the step's
/// ([`ContactParams`]), the second tangent `n x t1` ([`tangent_basis`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Friction {
    /// The first tangent.
    tangent: DVec3,
    /// Arms from the centres of mass to the patch centre, world space, at the step's start.
    arms: (DVec3, DVec3),
    /// The tangent rows' responses (see [`Friction::along_tangent`]) and effective masses.
    tangent_responses: [Responses; 2],
    tangent_mass: [f64; 2],
    /// Accumulated tangential impulses.
    pub tangent_impulse: [f64; 2],
    /// Angular responses `I_i^-1 n` to a unit twist, and the twist's effective mass.
    twist_inv1: DVec3,
    twist_inv2: DVec3,
    twist_mass: f64,
    /// Mean distance of the points from the patch centre: the twist's lever.
    pub twist_radius: f64,
    /// Accumulated twist impulse about the normal.
    pub twist_impulse: f64,
}

/// One manifold's constraint. What every contact of the step shares (softness, restitution,
/// friction coefficient) is in [`ContactParams`], not here: at scatter-100000 the constraints
/// and their points are a third of the peak heap.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactConstraint {
    /// Solver body indices (the ground is the last, static one).
    body1: u32,
    body2: u32,
    /// From body 1 to body 2.
    pub normal: DVec3,
    pub friction: Friction,
    /// Relative acceleration of the bodies along the normal from gravity alone.
    pub normal_acceleration: f64,
    /// This constraint's points: `points[first..first + count]`.
    first: u32,
    count: u32,
}

impl ContactConstraint {
    /// The solver bodies' indices.
    pub fn bodies(&self) -> (usize, usize) {
        (self.body1 as usize, self.body2 as usize)
    }

    /// Where this constraint's points are in the step's point list.
    pub fn points(&self) -> std::ops::Range<usize> {
        let first = self.first as usize;
        first..first + self.count as usize
    }

    /// The same constraint between solver bodies `body1` and `body2`, its points from `first`:
    /// where a batch of islands copied into a workspace of its own finds them, and back.
    pub fn relocated(&self, (body1, body2): (usize, usize), first: usize) -> Self {
        Self {
            body1: body1 as u32,
            body2: body2 as u32,
            first: first as u32,
            ..*self
        }
    }

    /// The softness of its biased pass: contacts with a static or sleeping body are stiffer.
    fn softness(&self, b1: &SolverBody, b2: &SolverBody, params: &ContactParams) -> Softness {
        if b1.inverse_mass == 0.0 || b2.inverse_mass == 0.0 {
            params.static_softness
        } else {
            params.softness
        }
    }
}

/// What one manifold point carries to the next step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct CachedPoint {
    key: u64,
    normal_impulse: f64,
    point: DVec3,
}

/// What one manifold carries to the next step; its points are `count` of the cache's point
/// list from `first` (a manifold has 2.3 points on average at scatter-100000: room for four in
/// each entry took 5.5 MiB more peak heap).
#[derive(Debug, Clone, Copy, PartialEq)]
struct CachedManifold {
    /// The friction impulse as a world vector, so a turned tangent basis does not turn it.
    friction: DVec3,
    twist: f64,
    first: u32,
    count: u32,
}

impl CachedManifold {
    /// What a solved manifold's constraint leaves for the next step, its points from `first`.
    fn new(c: &ContactConstraint, first: usize) -> Self {
        let (f, tangents) = (&c.friction, c.friction.tangents(c.normal));
        CachedManifold {
            friction: f.tangent_impulse[0] * tangents[0] + f.tangent_impulse[1] * tangents[1],
            twist: f.twist_impulse,
            first: first as u32,
            count: c.count,
        }
    }

    fn points(&self) -> std::ops::Range<usize> {
        self.first as usize..(self.first + self.count) as usize
    }
}

/// The points a solved manifold leaves for the next step: impulses and features.
fn cached_points<'a>(
    m: &'a Manifold,
    c: &ContactConstraint,
    points: &'a [ContactPoint],
) -> impl Iterator<Item = CachedPoint> + 'a {
    (points[c.points()].iter().zip(m.points())).map(|(p, mp)| CachedPoint {
        key: mp.key,
        normal_impulse: p.normal_impulse,
        point: mp.point,
    })
}

/// A cached manifold as a lookup gives it: its impulses and its points.
#[derive(Debug, Clone, Copy)]
struct Cached<'a> {
    manifold: &'a CachedManifold,
    points: &'a [CachedPoint],
}

impl Cached<'_> {
    /// Last step's impulse of the point with this feature key; failing that (faces lying flush
    /// on each other are clipped into points whose features flip from step to step, and the
    /// GJK point has none), of the nearest point within `reach`.
    fn normal_impulse(&self, key: u64, point: DVec3, reach: f64) -> f64 {
        let points = self.points;
        if key != 0
            && let Some(p) = points.iter().find(|p| p.key == key)
        {
            return p.normal_impulse;
        }
        points
            .iter()
            .map(|p| ((p.point - point).length_squared(), p.normal_impulse))
            .filter(|(d2, _)| *d2 <= reach * reach)
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map_or(0.0, |(_, impulse)| impulse)
    }
}

/// Impulses of last step's manifolds, sorted by body pair: the pairs apart from what they
/// carry, so that a lookup's binary search runs over 16-byte keys (pile-10000: 350 KiB, in the
/// L2 cache) instead of the entries (232 bytes each then: 5 MiB), where it took half of
/// preparing the contacts, 6 % of a one-thread step.
#[derive(Debug, Clone, Default)]
pub struct ContactCache {
    pairs: Vec<(usize, usize)>,
    /// What each pair carries, at the same index.
    carried: Vec<CachedManifold>,
    /// The entries' points: the kept entries' first, then this step's in manifold order.
    points: Vec<CachedPoint>,
}

impl ContactCache {
    fn lookup(&self, pair: (usize, usize)) -> Option<Cached<'_>> {
        let k = self.pairs.binary_search(&pair).ok()?;
        let manifold = &self.carried[k];
        let points = &self.points[manifold.points()];
        Some(Cached { manifold, points })
    }

    /// Scales every remembered impulse by `factor`: the substep they were applied over changed
    /// length, and an impulse per substep holds a load in proportion to it.
    pub fn scale_impulses(&mut self, factor: f64) {
        for m in &mut self.carried {
            m.friction *= factor;
            m.twist *= factor;
        }
        for p in &mut self.points {
            p.normal_impulse *= factor;
        }
    }

    /// The body pairs remembered (body 1 may be [`GROUND`]).
    pub fn pairs(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        self.pairs.iter().copied()
    }

    /// Keeps this step's impulses, and last step's of pairs with a sleeping body (not
    /// collided while they sleep, needed when they wake); forgets the rest.
    ///
    /// No entry is sorted: this step's manifolds are ordered by a sort of their pairs alone,
    /// and the kept entries and the new ones are merged in place, each written once at its
    /// place (the number of the other list's pairs below its own, plus its index). Sorting the
    /// entries (216 bytes each then) held a scratch buffer of up to all of them: 6.6 MiB more
    /// peak heap at scatter-100000 with rayon's parallel sort.
    pub fn store(
        &mut self,
        manifolds: &[Manifold],
        constraints: &[ContactConstraint],
        points: &[ContactPoint],
        bodies: &[crate::sim::body::RigidBody],
    ) {
        // Nothing collided and nothing kept: nothing to store (a chain, a body in flight).
        if manifolds.is_empty() && self.pairs.is_empty() {
            return;
        }
        let sleeping =
            |(i, j): (usize, usize)| (i != GROUND && bodies[i].asleep) || bodies[j].asleep;
        // Pairs are unique among a step's manifolds, so an unstable sort gives the one order.
        let all = manifolds.par_iter().enumerate();
        let mut order: Vec<((usize, usize), u32)> = Vec::new();
        parallel::extend_map(&mut order, all, 1024, |(k, m)| {
            ((m.body1, m.body2), k as u32)
        });
        order.par_sort_unstable_by_key(|(pair, _)| *pair);
        // A pair both collided and kept (a body fell asleep this step): the new entry wins.
        let collided = |pair: &(usize, usize)| order.binary_search_by_key(pair, |e| e.0).is_ok();
        self.retain(|pair| sleeping(pair) && !collided(&pair));
        let firsts = self.store_points(manifolds, constraints, points);
        let (kept, total) = (self.pairs.len(), self.pairs.len() + order.len());
        self.carried.reserve_exact(order.len());
        // SAFETY: the entries are `Copy`; every place below `total` is written before the
        // length is set back (the kept and the new pairs are disjoint, so their places are).
        unsafe { self.carried.set_len(0) };
        let slots = &mut self.carried.spare_capacity_mut()[..total];
        // Kept entries move up only, the last first, so none is overwritten before it moves.
        for (s, pair) in self.pairs.iter().enumerate().rev() {
            slots[s + order.partition_point(|(p, _)| p < pair)] = slots[s];
        }
        let slots = Shared::new(slots);
        let kept_pairs = &self.pairs;
        parallel::for_each(order.par_iter().enumerate(), 256, |(f, &(pair, k))| {
            let place = f + kept_pairs.partition_point(|p| *p < pair);
            let entry = CachedManifold::new(&constraints[k as usize], firsts[k as usize]);
            // SAFETY: each new entry has a place of its own, no kept entry's.
            unsafe { slots.write(place, std::mem::MaybeUninit::new(entry)) };
        });
        // SAFETY: all `total` places are written (see above).
        unsafe { self.carried.set_len(total) };
        merge_into(&mut self.pairs, kept, order.iter().map(|(pair, _)| *pair));
    }

    /// Moves the kept entries' points to the front of the point list and writes this step's
    /// after them, in manifold order; gives where each manifold's points start.
    fn store_points(
        &mut self,
        manifolds: &[Manifold],
        constraints: &[ContactConstraint],
        points: &[ContactPoint],
    ) -> Vec<usize> {
        // The kept entries are few (pairs with a sleeping body): copied aside, not in place.
        let kept: Vec<CachedPoint> = (self.carried.iter())
            .flat_map(|e| self.points[e.points()].iter().copied())
            .collect();
        let mut next = 0;
        for e in self.carried.iter_mut() {
            e.first = next;
            next += e.count;
        }
        let firsts: Vec<usize> = (constraints.iter())
            .scan(kept.len(), |next, c| {
                let first = *next;
                *next += c.count as usize;
                Some(first)
            })
            .collect();
        let fresh = constraints.iter().map(|c| c.count as usize).sum();
        buffer::clear_for(&mut self.points, kept.len() + fresh);
        self.points.extend_from_slice(&kept);
        let mut runs = buffer::runs(
            &mut self.points.spare_capacity_mut()[..fresh],
            constraints.iter().map(|c| c.count as usize),
        );
        let items = (manifolds, constraints, &mut runs[..]).into_par_iter();
        parallel::for_each(items, 256, |(m, c, run)| {
            assert_eq!(
                run.len(),
                m.points().len(),
                "a constraint of another manifold"
            );
            for (slot, p) in run.iter_mut().zip(cached_points(m, c, points)) {
                slot.write(p);
            }
        });
        // SAFETY: every run was written whole (checked: its manifold has as many points).
        unsafe { self.points.set_len(kept.len() + fresh) };
        firsts
    }

    /// Keeps the entries whose pair `keep` holds for, in order.
    fn retain(&mut self, keep: impl Fn((usize, usize)) -> bool) {
        let mut kept = 0;
        for k in 0..self.pairs.len() {
            if keep(self.pairs[k]) {
                self.pairs[kept] = self.pairs[k];
                self.carried[kept] = self.carried[k];
                kept += 1;
            }
        }
        self.pairs.truncate(kept);
        self.carried.truncate(kept);
    }

    pub fn heap_bytes(&self) -> usize {
        self.pairs.capacity() * size_of::<(usize, usize)>()
            + self.carried.capacity() * size_of::<CachedManifold>()
            + self.points.capacity() * size_of::<CachedPoint>()
    }

    /// Number of manifolds remembered.
    pub fn len(&self) -> usize {
        self.pairs.len()
    }

    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }
}

/// Merges the sorted `new` pairs into the sorted first `kept` of `pairs` (disjoint from them),
/// in place from the back.
fn merge_into(
    pairs: &mut Vec<(usize, usize)>,
    kept: usize,
    new: impl DoubleEndedIterator<Item = (usize, usize)> + ExactSizeIterator,
) {
    let total = kept + new.len();
    pairs.truncate(kept);
    pairs.resize(total, (0, 0));
    let (mut k, mut new) = (kept, new.rev().peekable());
    for place in (0..total).rev() {
        let take_new = match new.peek() {
            Some(p) => k == 0 || *p > pairs[k - 1],
            None => false,
        };
        pairs[place] = if take_new {
            new.next().expect("peeked")
        } else {
            k -= 1;
            pairs[k]
        };
    }
}

/// Which pass of the solver runs. The velocities are half-step ones during the substeps
/// (symplectic Euler between the half kicks of velocity Verlet).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pass {
    /// Soft position correction, at the poses the substep starts from.
    Soft,
    /// Rigid, at the poses the substep ends at.
    Relax,
    /// Rigid, after the step's last half kick: the velocities are the step's end.
    Final,
}

impl Pass {
    /// What to subtract from a half-step velocity to get the velocity at the poses this pass
    /// sees, for relative normal acceleration `a` over substep `h`.
    fn to_synchronised(self, a: f64, h: f64) -> f64 {
        match self {
            Pass::Soft => 0.5 * a * h,
            Pass::Relax => -0.5 * a * h,
            Pass::Final => 0.0,
        }
    }
}

/// Two unit tangents completing the normal to a right-handed basis, the same for the same
/// normal from step to step.
pub fn tangent_basis(n: DVec3) -> [DVec3; 2] {
    let helper = if n.x.abs() < 0.57735 {
        DVec3::X
    } else {
        DVec3::Y
    };
    let t1 = n.cross(helper).normalize();
    [t1, n.cross(t1)]
}

/// What every contact of the step shares: `softness` for the biased pass (`static_softness`
/// against a static or sleeping body), the friction coefficient and the gravity the bodies
/// feel.
pub struct ContactParams {
    pub softness: Softness,
    pub static_softness: Softness,
    pub friction: f64,
    pub gravity: DVec3,
}

/// The energy of the approach along the normal per unit effective mass, `E = v^2/2 - a s`
/// for separation `s` (clamped at zero), normal velocity `v` and the relative normal
/// acceleration `a` that gravity gives the bodies. The substeps integrate by velocity Verlet,
/// exact under constant acceleration: measured in the substep that stops the approach, with the
/// gap still open then, `E` is what the approach carries at the moment of impact, so a bounce
/// that leaves `e^2 E` gives apex ratios of exactly `e^2` at any step (a bounce from the
/// velocity at the start of the step loses `a s` to the gap, which grows with dt). Measured from
/// the manifold's velocities before its impulses, points that touch together bounce together.
pub fn impact_energy(separation: f64, normal_velocity: f64, normal_acceleration: f64) -> f64 {
    0.5 * normal_velocity * normal_velocity - normal_acceleration * separation.max(0.0)
}

/// The normal velocity after the bounce, `v > 0` with `v^2/2 - a s = e^2 E` at the separation
/// `s` the step ends at.
pub fn bounce_velocity(energy: f64, restitution: f64, separation: f64, a: f64) -> f64 {
    let twice = 2.0 * (restitution * restitution * energy + a * separation);
    if twice > 0.0 { twice.sqrt() } else { 0.0 }
}

/// The friction of a manifold whose points are `points`, anchored at their centre; body 1's
/// centre of mass is None for the ground.
fn friction_at(
    points: &[ManifoldPoint],
    (b1, x1): (&SolverBody, Option<DVec3>),
    (b2, x2): (&SolverBody, DVec3),
    n: DVec3,
    cached: Option<Cached>,
) -> Friction {
    let count = points.len().max(1) as f64;
    let centre = points.iter().map(|p| p.point).sum::<DVec3>() / count;
    let twist_radius = points
        .iter()
        .map(|p| (p.point - centre).length())
        .sum::<f64>()
        / count;
    let (r1, r2) = (x1.map_or(DVec3::ZERO, |x| centre - x), centre - x2);
    let tangents = tangent_basis(n);
    let (t1, m1) = Direction::new(b1, r1, b2, r2, tangents[0]);
    let (t2, m2) = Direction::new(b1, r1, b2, r2, tangents[1]);
    let (twist_inv1, twist_inv2) = (b1.inverse_inertia * n, b2.inverse_inertia * n);
    let k = n.dot(twist_inv1) + n.dot(twist_inv2);
    let warm = cached.map_or(DVec3::ZERO, |c| c.manifold.friction);
    Friction {
        tangent: tangents[0],
        arms: (r1, r2),
        tangent_responses: [t1.responses(), t2.responses()],
        tangent_mass: [m1, m2],
        tangent_impulse: [warm.dot(tangents[0]), warm.dot(tangents[1])],
        twist_inv1,
        twist_inv2,
        twist_mass: if k > 0.0 { 1.0 / k } else { 0.0 },
        twist_radius,
        twist_impulse: cached.map_or(0.0, |c| c.manifold.twist),
    }
}

/// Builds the contact constraints of this step's manifolds into `constraints` and `points`
/// (cleared first), warm-started from `cache`; `poses[i].0` is body i's centre of mass. Each
/// manifold's constraint and its points are built on their own (one cache lookup for both):
/// in parallel when there are enough of them.
pub fn prepare(
    manifolds: &[Manifold],
    poses: &[(DVec3, DQuat)],
    bodies: &[SolverBody],
    cache: &ContactCache,
    params: &ContactParams,
    (constraints, points): (&mut Vec<ContactConstraint>, &mut Vec<ContactPoint>),
) {
    if manifolds.is_empty() {
        constraints.clear();
        points.clear();
        return;
    }
    let ground = bodies.len() - 1;
    let centre = |i: usize| (i != ground).then(|| poses[i].0);
    // A manifold's constraint, and its points written into `run`.
    let build = |m: &Manifold, first: usize, run: &mut [MaybeUninit<ContactPoint>]| {
        let i = if m.body1 == GROUND { ground } else { m.body1 };
        let cached = cache.lookup((m.body1, m.body2));
        let ends = (
            (&bodies[i], centre(i)),
            (&bodies[m.body2], poses[m.body2].0),
        );
        let c = manifold_constraint(m, (i, first), ends, params, cached);
        let (i1, i2) = c.bodies();
        let (x1, x2) = (centre(i1), poses[i2].0);
        let (b1, b2) = (&bodies[i1], &bodies[i2]);
        // Points nearer than a fifth of the patch radius are taken for the same point.
        let reach = 0.2 * c.friction.twist_radius + 1e-6;
        for (slot, mp) in run.iter_mut().zip(m.points()) {
            let (r1, r2) = (x1.map_or(DVec3::ZERO, |x| mp.point - x), mp.point - x2);
            let (row, normal_mass) = Direction::new(b1, r1, b2, r2, c.normal);
            slot.write(ContactPoint {
                r1,
                r2,
                normal_responses: row.responses(),
                normal_mass,
                separation: mp.separation,
                normal_impulse: cached.map_or(0.0, |c| c.normal_impulse(mp.key, mp.point, reach)),
                ..ContactPoint::default()
            });
        }
        c
    };
    let firsts: Vec<usize> = manifolds
        .iter()
        .scan(0, |next, m| {
            let first = *next;
            *next += m.points().len();
            Some(first)
        })
        .collect();
    let total = manifolds.iter().map(|m| m.points().len()).sum();
    buffer::clear_for(constraints, manifolds.len());
    buffer::clear_for(points, total);
    // Each manifold's points written in place (collecting a flat map would hold them twice).
    let mut runs = buffer::runs(
        &mut points.spare_capacity_mut()[..total],
        manifolds.iter().map(|m| m.points().len()),
    );
    let items = (manifolds, &firsts[..], &mut runs[..]).into_par_iter();
    parallel::extend_map(constraints, items, 256, |(m, &first, run)| {
        build(m, first, run)
    });
    // SAFETY: each manifold wrote all its points, and the runs cover the first `total`.
    unsafe { points.set_len(total) };
}

/// Manifold `m`'s constraint between solver bodies `i` (the ground's index for the ground) and
/// `m.body2`, its points starting at `first`; each end is a solver body with its centre of mass
/// (none for the ground).
fn manifold_constraint(
    m: &Manifold,
    (i, first): (usize, usize),
    ((b1, x1), (b2, x2)): ((&SolverBody, Option<DVec3>), (&SolverBody, DVec3)),
    params: &ContactParams,
    cached: Option<Cached>,
) -> ContactConstraint {
    let n = m.normal;
    let gravity_on = |b: &SolverBody| {
        if b.inverse_mass > 0.0 {
            params.gravity
        } else {
            DVec3::ZERO
        }
    };
    let friction = friction_at(m.points(), (b1, x1), (b2, x2), n, cached);
    // Body indices and point counts fit in u32: the broad phase's pairs are u32 already.
    ContactConstraint {
        body1: i as u32,
        body2: m.body2 as u32,
        normal: n,
        friction,
        normal_acceleration: n.dot(gravity_on(b2) - gravity_on(b1)),
        first: first as u32,
        count: m.points().len() as u32,
    }
}

/// A share of every point's and manifold's accumulated impulse, held back from the
/// accumulators for a while. Velocity Verlet gives the first substep and the final pass half a
/// kick of gravity each: warm-started with the whole support of a full kick they would throw a
/// resting stack up and leave it falling at the step's end. The share held back from the
/// first substep is released into the second.
#[derive(Debug, Clone, Default)]
pub struct HeldImpulses {
    normal: Vec<f64>,
    friction: Vec<([f64; 2], f64)>,
}

/// Points or constraints one thread holds back or releases at a time: the passes are a few
/// operations an item, run twice a step (on one thread they were a third of the soft step's own
/// serial time at pile-10000 on two threads).
const HOLD_CHUNK: usize = 4096;

impl HeldImpulses {
    /// Moves `fraction` of every accumulated impulse out of the accumulators.
    pub fn hold_back(
        &mut self,
        constraints: &mut [ContactConstraint],
        points: &mut [ContactPoint],
        fraction: f64,
    ) {
        buffer::clear_for(&mut self.normal, points.len());
        let points = points.par_iter_mut();
        parallel::extend_map(&mut self.normal, points, HOLD_CHUNK, |p| {
            let held = fraction * p.normal_impulse;
            p.normal_impulse -= held;
            held
        });
        buffer::clear_for(&mut self.friction, constraints.len());
        let constraints = constraints.par_iter_mut();
        parallel::extend_map(&mut self.friction, constraints, HOLD_CHUNK, |c| {
            let f = &mut c.friction;
            let held = (
                f.tangent_impulse.map(|t| fraction * t),
                fraction * f.twist_impulse,
            );
            f.tangent_impulse = [0, 1].map(|k| f.tangent_impulse[k] - held.0[k]);
            f.twist_impulse -= held.1;
            held
        });
    }

    /// Adds the held impulses back to the accumulators (not applied to the bodies).
    pub fn release(&mut self, constraints: &mut [ContactConstraint], points: &mut [ContactPoint]) {
        let points = points.par_iter_mut().zip(&self.normal);
        parallel::for_each(points, HOLD_CHUNK, |(p, n)| p.normal_impulse += n);
        let constraints = constraints.par_iter_mut().zip(&self.friction);
        parallel::for_each(constraints, HOLD_CHUNK, |(c, (t, twist))| {
            let f = &mut c.friction;
            f.tangent_impulse = [0, 1].map(|k| f.tangent_impulse[k] + t[k]);
            f.twist_impulse += twist;
        });
        self.normal.clear();
        self.friction.clear();
    }
}

/// Runs `f` on every contact constraint (or the `selected` ones, increasing indices) with its
/// points and its two solver bodies, colour by colour (see [`Colours::for_each`]): the one
/// place the colouring's disjointness is relied on.
pub fn for_each_contact_in(
    colours: &Colours,
    selected: Option<&[u32]>,
    contacts: (&mut [ContactConstraint], &mut [ContactPoint]),
    bodies: &mut [SolverBody],
    f: impl Fn(&mut ContactConstraint, &mut [ContactPoint], &mut SolverBody, &mut SolverBody) + Sync,
) {
    for_each_contact_from(colours, (selected, None), contacts, bodies, f);
}

/// [`for_each_contact_in`], on all threads only from `parallel_from` selected constraints up
/// where given (see [`Colours::for_each_selected_from`]).
pub fn for_each_contact_from(
    colours: &Colours,
    (selected, parallel_from): (Option<&[u32]>, Option<usize>),
    (constraints, points): (&mut [ContactConstraint], &mut [ContactPoint]),
    bodies: &mut [SolverBody],
    f: impl Fn(&mut ContactConstraint, &mut [ContactPoint], &mut SolverBody, &mut SolverBody) + Sync,
) {
    let (bodies, points) = (Shared::new(bodies), Shared::new(points));
    // The bodies are where a pass waits at 100,000 bodies (18 MiB of them, read in colour
    // order); the constraints and points are read in order and need no hint.
    let ahead = |c: &ContactConstraint| {
        let (i, j) = c.bodies();
        bodies.prefetch(i);
        bodies.prefetch(j);
    };
    let each = |c: &mut ContactConstraint| {
        // SAFETY: within a colour a constraint's points and moving bodies are its own.
        let contact_points = unsafe { points.slice(c.points()) };
        unsafe { with_pair(&bodies, c.bodies(), |b1, b2| f(c, contact_points, b1, b2)) }
    };
    match (selected, parallel_from) {
        (Some(selected), Some(from)) => {
            colours.for_each_selected_from(constraints, (selected, from), ahead, each)
        }
        (Some(selected), None) => colours.for_each_selected(constraints, selected, ahead, each),
        (None, _) => colours.for_each(constraints, ahead, each),
    }
}

/// Applies the accumulated impulses (warm starting), once per substep, of the `selected`
/// constraints or all.
pub fn warm_start(
    colours: &Colours,
    selected: Option<&[u32]>,
    contacts: (&mut [ContactConstraint], &mut [ContactPoint]),
    bodies: &mut [SolverBody],
) {
    for_each_contact_in(colours, selected, contacts, bodies, |c, points, b1, b2| {
        for p in points.iter() {
            p.along_normal(c.normal)
                .apply(c.normal, p.normal_impulse, b1, b2);
        }
        let (f, tangents) = (&c.friction, c.friction.tangents(c.normal));
        for (k, (t, impulse)) in tangents.into_iter().zip(f.tangent_impulse).enumerate() {
            f.along_tangent(k, t).apply(t, impulse, b1, b2);
        }
        f.apply_twist(f.twist_impulse, b1, b2);
    });
}

/// One Gauss-Seidel pass over the contacts (the `selected` ones, or all). In the soft pass
/// penetration is corrected softly (at most `max_push` speed); in the others the velocities are
/// made rigid. A point still apart may close its gap within the substep but no more
/// (speculative contact).
pub fn solve(
    (colours, selected): (&Colours, Option<&[u32]>),
    contacts: (&mut [ContactConstraint], &mut [ContactPoint]),
    bodies: &mut [SolverBody],
    params: &ContactParams,
    (inv_h, pass, max_push): (f64, Pass, f64),
) {
    for_each_contact_in(colours, selected, contacts, bodies, |c, points, b1, b2| {
        on_copies(b1, b2, |b1, b2| {
            let soft = match pass {
                Pass::Soft => c.softness(b1, b2, params),
                _ => Softness::RIGID,
            };
            solve_normals(c, points, (b1, b2), (soft, inv_h, pass), max_push);
            let limit = params.friction * points.iter().map(|p| p.normal_impulse).sum::<f64>();
            c.friction.solve(c.normal, limit, b1, b2);
        });
    });
}

/// Runs `f` on copies of the two bodies, then writes their velocities back. Inlined into a
/// pass's manifold, the copies live in registers: on the bodies themselves each row's impulse
/// stored a velocity in 16-byte pieces straddling its fields and the next row loaded it whole,
/// a store-forwarding stall (6 % of the solve pass's samples in `perf` on pile-200).
#[inline(always)]
fn on_copies(
    body1: &mut SolverBody,
    body2: &mut SolverBody,
    f: impl FnOnce(&mut SolverBody, &mut SolverBody),
) {
    let (mut b1, mut b2) = (*body1, *body2);
    f(&mut b1, &mut b2);
    for (body, solved) in [(body1, b1), (body2, b2)] {
        body.linear_velocity = solved.linear_velocity;
        body.angular_velocity = solved.angular_velocity;
    }
}

/// The normal impulses of one manifold's points: solved together ([`normal_block`]) where it
/// has several, so the pass does not depend on the points' order; point after point where it
/// has one, or the block cannot be solved (a value not finite, a mass scale not positive).
///
/// Inlined into the pass, as [`Friction::solve`] is: called, it took the normal and the
/// softness through the stack, stored in 8-byte halves and loaded in 16-byte pieces, a
/// store-forwarding stall on which 7-10 % of each function's samples sat in `perf` on pile-200.
#[inline(always)]
fn solve_normals(
    c: &ContactConstraint,
    points: &mut [ContactPoint],
    (b1, b2): (&mut SolverBody, &mut SolverBody),
    (soft, inv_h, pass): (Softness, f64, Pass),
    max_push: f64,
) {
    let solve = (soft, inv_h, pass, max_push);
    let solved = match points.len() {
        2 => solve_block::<2>(c, points, (b1, b2), solve),
        3 => solve_block::<3>(c, points, (b1, b2), solve),
        4 => solve_block::<4>(c, points, (b1, b2), solve),
        _ => false,
    };
    if !solved {
        solve_point_by_point(c, points, (b1, b2), solve);
    }
}

/// The normal impulses of one manifold's points, one Gauss-Seidel pass point after point.
#[inline(always)]
fn solve_point_by_point(
    c: &ContactConstraint,
    points: &mut [ContactPoint],
    (b1, b2): (&mut SolverBody, &mut SolverBody),
    (soft, inv_h, pass, max_push): (Softness, f64, Pass, f64),
) {
    let n = c.normal;
    let use_bias = pass == Pass::Soft;
    // The normal velocities before any of this manifold's impulses: the approach speeds of
    // points that touch together. (Each point's row is formed again below rather than kept:
    // an array of four rows was zeroed by a call to memset in every manifold's pass.)
    let mut approach = [0.0; MAX_POINTS];
    for (v, p) in approach.iter_mut().zip(points.iter()) {
        *v = p.along_normal(n).velocity(n, b1, b2);
    }
    for (k, (p, &approach)) in points.iter_mut().zip(&approach).enumerate() {
        let row = p.along_normal(n);
        let s = separation_now(p, n, b1, b2);
        let (bias, mass_scale, impulse_scale) = soft.coefficients(s, inv_h, use_bias, max_push);
        // The first point sees no impulse of this manifold yet: its approach, bit for bit.
        let vn = match k {
            0 => approach,
            _ => row.velocity(n, b1, b2),
        };
        let impulse = -p.normal_mass * mass_scale * (vn + bias) - impulse_scale * p.normal_impulse;
        let total = (p.normal_impulse + impulse).max(0.0);
        settle_point(c, p, (&row, total), (s, approach, pass, inv_h), (b1, b2));
    }
}

/// Where a point of a manifold with normal `n` is now: its separation at the step's start
/// moved by the bodies since.
#[inline(always)]
pub(super) fn separation_now(p: &ContactPoint, n: DVec3, b1: &SolverBody, b2: &SolverBody) -> f64 {
    let moved = b2.point_displacement(p.r2) - b1.point_displacement(p.r1);
    p.separation + n.dot(moved)
}

/// Point `p` (its normal row `row`) takes the accumulated impulse `total`: the change is
/// applied, and an impact is recorded where the point touched after approaching at `approach`
/// (at separation `s`, in `pass` of substeps of `1 / inv_h`).
#[inline(always)]
fn settle_point(
    c: &ContactConstraint,
    p: &mut ContactPoint,
    (row, total): (&Direction, f64),
    (s, approach, pass, inv_h): (f64, f64, Pass, f64),
    (b1, b2): (&mut SolverBody, &mut SolverBody),
) {
    let delta = total - p.normal_impulse;
    p.normal_impulse = total;
    p.max_normal_impulse = p.max_normal_impulse.max(total);
    if total > 0.0 && approach < 0.0 {
        // Measured at the poses of this pass with the velocity there, where the energy is
        // exactly invariant.
        let a = c.normal_acceleration;
        let synchronised = approach - pass.to_synchronised(a, 1.0 / inv_h);
        p.impact_energy = p.impact_energy.max(impact_energy(s, synchronised, a));
    }
    row.apply(c.normal, delta, b1, b2);
}

/// The normal impulses of a manifold's `N` points solved together, if the block can be: each
/// active point where Gauss-Seidel converges, `v_i + bias_i + c_i x_i = 0` (the soft row's
/// fixed point, `c_i = impulse scale K_ii / mass scale`; for a rigid row
/// [`normal_block::COMPLIANCE`] `K_ii`), with `v` the normal velocities the impulses
/// `x - x_old` leave through the manifold's matrix `K`. Returns whether it was (nothing is
/// applied otherwise).
#[inline(always)]
fn solve_block<const N: usize>(
    c: &ContactConstraint,
    points: &mut [ContactPoint],
    (b1, b2): (&mut SolverBody, &mut SolverBody),
    (soft, inv_h, pass, max_push): (Softness, f64, Pass, f64),
) -> bool {
    let (n, use_bias) = (c.normal, pass == Pass::Soft);
    let rows: [Direction; N] = std::array::from_fn(|k| points[k].along_normal(n));
    let held: [f64; N] = std::array::from_fn(|k| points[k].normal_impulse);
    let approach: [f64; N] = std::array::from_fn(|k| rows[k].velocity(n, b1, b2));
    let separation: [f64; N] = std::array::from_fn(|k| separation_now(&points[k], n, b1, b2));
    let coefficients: [(f64, f64, f64); N] =
        std::array::from_fn(|k| soft.coefficients(separation[k], inv_h, use_bias, max_push));
    // Nothing held and nothing approaching: no impulse is the solution, without `K`.
    if (0..N).all(|i| held[i] == 0.0 && approach[i] + coefficients[i].0 >= 0.0) {
        return true;
    }
    if coefficients.iter().any(|c| c.1.is_nan() || c.1 <= 0.0) {
        return false;
    }
    let mut a = coupling(&rows, (b1, b2));
    let q: [f64; N] = std::array::from_fn(|i| {
        approach[i] + coefficients[i].0 - (0..N).map(|j| a[i][j] * held[j]).sum::<f64>()
    });
    // The soft rows' compliance; the rigid rows' least, which makes a flat face's `K` definite.
    for (i, (_, mass_scale, impulse_scale)) in coefficients.into_iter().enumerate() {
        a[i][i] += (impulse_scale / mass_scale).max(normal_block::COMPLIANCE) * a[i][i];
    }
    let Some(x) = normal_block::solve(&a, &q, &held) else {
        return false;
    };
    for (k, p) in points.iter_mut().enumerate().take(N) {
        let at = (separation[k], approach[k], pass, inv_h);
        settle_point(c, p, (&rows[k], x[k]), at, (b1, b2));
    }
    true
}

/// The matrix `K` of a manifold's normal rows `rows`: the velocity along row `i` a unit impulse
/// along row `j` gives.
#[inline(always)]
pub(super) fn coupling<const N: usize>(
    rows: &[Direction; N],
    (b1, b2): (&SolverBody, &SolverBody),
) -> [[f64; N]; N] {
    let linear = b1.inverse_mass + b2.inverse_mass;
    // A body impulses cannot turn (the ground, a sleeper) adds nothing angular: half of `K`
    // spared on a pile's ground contacts.
    let turns = |b: &SolverBody| b.inverse_inertia != DMat3::ZERO;
    let (turns1, turns2) = (turns(b1), turns(b2));
    let mut k = [[0.0; N]; N];
    for i in 0..N {
        for j in i..N {
            let mut v = linear;
            if turns1 {
                v += rows[i].ang1.dot(rows[j].inv1);
            }
            if turns2 {
                v += rows[i].ang2.dot(rows[j].inv2);
            }
            (k[i][j], k[j][i]) = (v, v);
        }
    }
    k
}

impl Friction {
    /// The two tangents, `t1` and `n x t1`, as [`tangent_basis`] made them.
    pub fn tangents(&self, n: DVec3) -> [DVec3; 2] {
        [self.tangent, n.cross(self.tangent)]
    }

    /// The Jacobian row along tangent `k`, `t`.
    #[inline]
    fn along_tangent(&self, k: usize, t: DVec3) -> Direction {
        Direction::at(self.arms, t, self.tangent_responses[k])
    }

    /// Coulomb friction at the anchor: both tangent impulses at once, clamped to the disc of
    /// radius `limit` (`mu` times the manifold's normal impulse); then the twist, clamped to
    /// the same times the patch radius. Inlined into the pass (see [`solve_normals`]).
    #[inline(always)]
    fn solve(&mut self, n: DVec3, limit: f64, b1: &mut SolverBody, b2: &mut SolverBody) {
        let tangents = self.tangents(n);
        let old = self.tangent_impulse;
        let rows = [
            self.along_tangent(0, tangents[0]),
            self.along_tangent(1, tangents[1]),
        ];
        let (mass, t) = (self.tangent_mass, tangents);
        let mut new = [
            old[0] - mass[0] * rows[0].velocity(t[0], b1, b2),
            old[1] - mass[1] * rows[1].velocity(t[1], b1, b2),
        ];
        let length = (new[0] * new[0] + new[1] * new[1]).sqrt();
        if length > limit {
            let scale = if length > 0.0 { limit / length } else { 0.0 };
            new = [new[0] * scale, new[1] * scale];
        }
        self.tangent_impulse = new;
        for k in 0..2 {
            rows[k].apply(tangents[k], new[k] - old[k], b1, b2);
        }
        let spin = n.dot(b2.angular_velocity - b1.angular_velocity);
        let twist_limit = limit * self.twist_radius.max(MIN_TWIST_RADIUS);
        let twist = self.twist_impulse - self.twist_mass * spin;
        // A load gone non-finite (a body past saving, frozen at the step's end) makes the limit
        // NaN, where `clamp` would panic: the twist is then left as it is.
        let twist = if twist_limit >= 0.0 {
            twist.clamp(-twist_limit, twist_limit)
        } else {
            twist
        };
        self.apply_twist(twist - self.twist_impulse, b1, b2);
        self.twist_impulse = twist;
    }

    /// Applies a twist impulse about the normal to body 2 and its opposite to body 1.
    fn apply_twist(&self, impulse: f64, b1: &mut SolverBody, b2: &mut SolverBody) {
        b1.angular_velocity -= impulse * self.twist_inv1;
        b2.angular_velocity += impulse * self.twist_inv2;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A box landing tilted on the ground, its four bottom corners touching (two of them
    /// penetrating: soft rows; two still apart: rigid, speculative), holding impulses from
    /// before: one block solve gives the velocities and impulses that the pass point after
    /// point converges to when repeated (an independent computation of the same fixed point).
    #[test]
    fn the_block_gives_what_repeated_point_passes_converge_to() {
        use crate::scene::assets;
        use crate::sim::body::RigidBody;
        use crate::sim::shape::Shape;
        let shape = Shape::from_tet_mesh(&assets::cuboid(DVec3::new(1.0, 0.5, 0.75))).unwrap();
        let tilt = DQuat::from_rotation_z(0.01) * DQuat::from_rotation_x(-0.02);
        let mut body = RigidBody::on_shape(&shape, 0, 1.0, false, DVec3::new(0.3, 0.5, -0.2), tilt);
        body.linear_velocity = DVec3::new(0.4, -2.0, 0.1);
        body.angular_velocity = DVec3::new(0.7, -0.3, 1.1);
        let corners = [(-1.0, -0.75), (1.0, -0.75), (1.0, 0.75), (-1.0, 0.75)];
        let points: Vec<ManifoldPoint> = corners
            .iter()
            .enumerate()
            .map(|(k, &(x, z))| {
                let at = body.position + tilt * DVec3::new(x, -0.5, z);
                ManifoldPoint {
                    point: at,
                    separation: at.y,
                    key: k as u64,
                }
            })
            .collect();
        assert_eq!(points.iter().filter(|p| p.separation < 0.0).count(), 2);
        let h = 0.005;
        let params = ContactParams {
            softness: Softness::new(30.0, 10.0, h),
            static_softness: Softness::new(37.5, 10.0, h),
            friction: 0.5,
            gravity: DVec3::new(0.0, -9.8, 0.0),
        };
        let bodies = [SolverBody::new(&body), SolverBody::STATIC];
        let manifold = Manifold::new(GROUND, 0, DVec3::Y, &points);
        let (mut constraints, mut contact_points) = (Vec::new(), Vec::new());
        let poses = [(body.position, body.orientation)];
        let cache = ContactCache::default();
        let contacts = (&mut constraints, &mut contact_points);
        prepare(&[manifold], &poses, &bodies, &cache, &params, contacts);
        for (p, held) in contact_points.iter_mut().zip([0.3, 0.0, 0.1, 0.05]) {
            p.normal_impulse = held;
        }
        let c = constraints[0];
        let solve = (params.static_softness, 1.0 / h, Pass::Soft, 3.0);
        let (mut block, mut repeated) = (contact_points.clone(), contact_points.clone());
        let (mut b1, mut b2) = (bodies[1], bodies[0]);
        assert!(solve_block::<4>(&c, &mut block, (&mut b1, &mut b2), solve));
        let (mut r1, mut r2) = (bodies[1], bodies[0]);
        for _ in 0..20_000 {
            solve_point_by_point(&c, &mut repeated, (&mut r1, &mut r2), solve);
        }
        let impulses = |p: &[ContactPoint]| p.iter().map(|p| p.normal_impulse).collect::<Vec<_>>();
        let (x, y) = (impulses(&block), impulses(&repeated));
        assert!(x.iter().any(|&v| v > 0.1), "{x:?}");
        // To the rigid rows' compliance, 1e-6 of their diagonal (3e-6 here).
        for k in 0..4 {
            assert!((x[k] - y[k]).abs() < 2e-5, "{x:?} against {y:?}");
        }
        assert!((b2.linear_velocity - r2.linear_velocity).length() < 2e-5);
        assert!((b2.angular_velocity - r2.angular_velocity).length() < 2e-5);
    }

    #[test]
    fn impact_energy_is_invariant_in_free_flight() {
        // Half kick, drift, half kick: exact under constant acceleration.
        let (a, h) = (-9.8, 0.005);
        let (mut s, mut v) = (20.0, 0.0);
        let e0 = impact_energy(s, v, a);
        while s + h * (v + 0.5 * a * h) > 0.0 {
            v += 0.5 * a * h;
            s += h * v;
            v += 0.5 * a * h;
            let e = impact_energy(s, v, a);
            assert!((e - e0).abs() < 1e-12 * e0, "{e} vs {e0}");
        }
    }

    #[test]
    fn bounce_keeps_e_squared_of_the_energy() {
        let a = -9.8;
        for e in [1.0, 0.8, 0.5, 0.0] {
            let energy = 196.0;
            let v = bounce_velocity(energy, e, 0.0, a);
            assert!(
                (impact_energy(0.0, v, a) - e * e * energy).abs() < 1e-9,
                "e {e}"
            );
        }
    }

    /// The cache after each step: the entries of this step's manifolds and those of last
    /// step's kept for pairs with a sleeping body that did not collide again, sorted by pair;
    /// against the same built by a plain sort, over steps where bodies fall asleep and wake.
    #[test]
    fn store_keeps_sleepers_and_this_steps_manifolds_in_pair_order() {
        use crate::scene::assets;
        use crate::sim::body::RigidBody;
        use crate::sim::shape::Shape;
        let shape = Shape::from_tet_mesh(&assets::cuboid(DVec3::ONE)).unwrap();
        let n = 300;
        let mut bodies: Vec<RigidBody> = (0..n)
            .map(|i| {
                let x = DVec3::new(i as f64, 0.0, 0.0);
                RigidBody::on_shape(&shape, 0, 1.0, false, x, DQuat::IDENTITY)
            })
            .collect();
        let mut rng = crate::sim::rng::Rng::new(5);
        let mut below = |k: usize| (rng.next_u64() % k as u64) as usize;
        let params = ContactParams {
            softness: Softness::RIGID,
            static_softness: Softness::RIGID,
            friction: 0.5,
            gravity: DVec3::ZERO,
        };
        let solver_bodies: Vec<SolverBody> = bodies.iter().map(SolverBody::new).collect();
        let solver_bodies = [solver_bodies, vec![SolverBody::STATIC]].concat();
        let poses: Vec<(DVec3, DQuat)> =
            bodies.iter().map(|b| (b.position, b.orientation)).collect();
        let mut cache = ContactCache::default();
        // Each pair's friction impulse, twist impulse and points.
        type Entry = (DVec3, f64, Vec<CachedPoint>);
        let mut model: Vec<((usize, usize), Entry)> = Vec::new();
        for step in 0..40 {
            let count = [0, 5, 300, 900][below(4)];
            let mut pairs: Vec<(usize, usize)> = (0..count)
                .map(|_| {
                    let (i, j) = (below(n), below(n));
                    let ground = below(5) == 0 || i == j;
                    if ground {
                        (GROUND, j)
                    } else {
                        (i.min(j), i.max(j))
                    }
                })
                .collect();
            pairs.sort_unstable();
            pairs.dedup();
            // Manifolds come in colour order, not pair order.
            pairs.reverse();
            let manifolds: Vec<Manifold> = (pairs.iter().enumerate())
                .map(|(k, &(i, j))| {
                    let point = ManifoldPoint {
                        point: DVec3::new(step as f64, k as f64, 0.0),
                        separation: -0.01,
                        key: (step * 10_000 + k) as u64,
                    };
                    Manifold::new(i, j, DVec3::Y, &[point])
                })
                .collect();
            let (mut constraints, mut points) = (Vec::new(), Vec::new());
            let contacts = (&mut constraints, &mut points);
            prepare(
                &manifolds,
                &poses,
                &solver_bodies,
                &cache,
                &params,
                contacts,
            );
            for b in bodies.iter_mut() {
                b.asleep = below(3) == 0;
            }
            cache.store(&manifolds, &constraints, &points, &bodies);
            let sleeping =
                |(i, j): (usize, usize)| (i != GROUND && bodies[i].asleep) || bodies[j].asleep;
            model.retain(|(pair, _)| sleeping(*pair) && !pairs.contains(pair));
            let fresh = manifolds.iter().zip(&constraints);
            model.extend(fresh.map(|(m, c)| {
                let e = CachedManifold::new(c, 0);
                let points = cached_points(m, c, &points).collect();
                ((m.body1, m.body2), (e.friction, e.twist, points))
            }));
            model.sort_by_key(|(pair, _)| *pair);
            let entries: Vec<_> = (cache.pairs().zip(&cache.carried))
                .map(|(pair, e)| {
                    let points = cache.points[e.points()].to_vec();
                    (pair, (e.friction, e.twist, points))
                })
                .collect();
            assert!(entries == model, "step {step}");
        }
    }
}
