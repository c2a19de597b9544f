//! Distance constraints solved exactly, a connected group (a chain, a pendulum) at a time: the
//! rows whose bound is reached or about to be form a small symmetric positive definite system
//! `K lambda = b` with `K = J M^-1 J^T`, solved directly (`L D L^T`) under the rows' sign limits by
//! an active-set loop; positions are then projected the same way (non-linear Gauss-Seidel with
//! an exact block). Gauss-Seidel would need about as many sweeps as a chain has links to pass a
//! load from its end to its anchor (the coursework needs hundreds of visits per step); a
//! direct solve passes it in one. `K` is kept by its envelope ([`envelope`]), so a chain costs
//! time linear in its length; groups whose envelope exceeds [`MAX_ENVELOPE`] entries fall back
//! to Gauss-Seidel ([`super::joint_solver`]). In the soft pass a rigid rod's target rate
//! anticipates the lengthening of the drift that follows ([`drift_lengthening`]), so that the
//! rod ends the substep at its length rather than stretched and projected back.

use super::constraint_graph::Shared;
use super::disjoint_sets::DisjointSets;
use super::envelope::{self, Row};
use super::pivoted_ldl::{self, PivotedLdl};
use super::solver_body::SolverBody;
use crate::sim::body::RigidBody;
use crate::sim::constraint::DistanceConstraint;
use glam::{DMat3, DVec3};
use rayon::prelude::*;
use std::collections::HashMap;
use std::ops::Range;

/// Largest envelope of `K` (entries on and left of the diagonal, from each row's first row
/// sharing a body with it) solved directly: a chain of 30,000 links, a group of 360 records all
/// on one body (512 KiB of `K`).
pub const MAX_ENVELOPE: usize = 1 << 16;
/// Active-set rounds per solve at most (each drops or adds the rows that broke their limits).
/// A whipping rope's taut rows take more than 8: in 20 s, rope-1000 at dt 0.02 ran out in 981
/// solves with 8 and in 43 with 32, rope-200 at dt 0.04 in 104 and 16, at the same run time
/// (counted with a probe). A solve that ends within 8 rounds is the same with 32. Block
/// principal pivoting with Murty's fallback (Judice and Pires 1994) was measured too and ran
/// out as often.
const ACTIVE_SET_ROUNDS: usize = 32;
/// Rounds of one projection of a group's positions at most (a projection runs in each substep
/// where a row is far out, and after the last): each projects the rows' linearisation
/// at the poses it starts from, so where links turn far in a step (a rope's end whipping at
/// 80 units/s) one leaves them stretched by up to a tenth of their length; the next ones start
/// from closer poses (non-linear Gauss-Seidel, with an exact block). A whip needs more than
/// 16 (rope-100 at dt 0.03: up to 28; at 0.05: 54), and a projection cut short left the rows
/// stretched, which the next step's biased passes pulled back at full speed: with 16,
/// rope-200 at dt 0.02 stretched by 3 units and gained 16 % energy in 20 s, rope-100 at
/// dt 0.05 gained 13x; with 64 both hold (1e-6 of the rest length) and run faster (fewer
/// contacts between stretched links). Rounds past the first run only while a row is out.
const PROJECTION_ROUNDS: usize = 64;
/// After the first projection, a group is projected again only while a row is outside its
/// bounds by more than this fraction of the bound.
const PROJECTION_TOLERANCE: f64 = 1e-6;

/// One constraint record: the distance between two body points kept within
/// `[lower, upper]` (equal bounds: a rigid rod).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DistanceRecord {
    /// The first of the world's inequality constraints this record stands for, and how many
    /// (one, or a lower and an upper).
    pub first_constraint: usize,
    pub constraint_count: usize,
    pub body1: usize,
    pub body2: usize,
    pub local1: DVec3,
    pub local2: DVec3,
    pub lower: f64,
    pub upper: f64,
}

impl DistanceRecord {
    /// The world's inequality constraints this record stands for.
    pub fn constraints(&self) -> Range<usize> {
        self.first_constraint..self.first_constraint + self.constraint_count
    }
}

/// Which side of its range a row is held on in one solve.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Side {
    #[default]
    Free,
    Lower,
    Upper,
    /// Equal bounds: held from both sides.
    Both,
}

/// The active sets the last solves of each group ended with, per record (velocities, and
/// positions): the next solve starts from them. From one pass to the next few rows change
/// side, so the active-set loop ends in a round or two; started from the rows violated
/// alone, a long rope whose links go slack and taut again ran out of rounds (1,000 links
/// at dt 0.02: 1.7 % of the rest length stretched, 0.16 % with four times the rounds).
/// Where the loop ends within its rounds the result is the same (the final active set's
/// system), so the start is a speed and convergence matter only.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct HeldSides {
    velocities: Vec<Side>,
    positions: Vec<Side>,
}

impl HeldSides {
    /// Sized for `records` records (all free if the count changed).
    fn fit(&mut self, records: usize) {
        for sides in [&mut self.velocities, &mut self.positions] {
            if sides.len() != records {
                sides.clear();
                sides.resize(records, Side::Free);
            }
        }
    }

    pub fn heap_bytes(&self) -> usize {
        (self.velocities.capacity() + self.positions.capacity()) * size_of::<Side>()
    }
}

/// A record's geometry at the current poses.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Geometry {
    pub r1: DVec3,
    pub r2: DVec3,
    /// Unit vector from point 1 to point 2.
    pub axis: DVec3,
    pub length: f64,
}

/// A row's Jacobian along its axis, per end (body 1, body 2): the angular part `r x axis`, the
/// angular response `I^-1 (r x axis)` to a unit impulse, and the inverse mass. Computed once
/// per solve, so each entry of `K` is a few dot products.
#[derive(Debug, Clone, Copy, Default)]
struct Jacobian {
    angular: [DVec3; 2],
    response: [DVec3; 2],
    inverse_mass: [f64; 2],
}

/// One connected group: its records, and the pairs of them that share a body (the only
/// off-diagonal entries of its `K`; a chain's are its neighbours).
#[derive(Debug, Clone, PartialEq)]
pub struct Group {
    pub records: Range<usize>,
    couplings: Range<usize>,
    /// Entries of `K`'s envelope; above [`MAX_ENVELOPE`] the group is left to Gauss-Seidel.
    envelope: usize,
    /// Left to Gauss-Seidel since its active sets cycled on rows that depend on each other
    /// ([`Scratch::active_set_rounds`]).
    relaxed: bool,
    /// Whether a record is a rigid rod (equal bounds), whose drift the soft pass anticipates.
    rods: bool,
}

impl Group {
    fn direct(&self) -> bool {
        self.envelope <= MAX_ENVELOPE && !self.relaxed
    }
}

/// The records of the world's constraints, grouped by connected bodies, and the buffers one
/// group's solve works in (kept between steps).
#[derive(Debug, Clone, Default)]
pub struct JointBlocks {
    pub records: Vec<DistanceRecord>,
    pub groups: Vec<Group>,
    /// Pairs (i < j) of records of one group that share a body, by index within the group.
    couplings: Vec<(usize, usize)>,
    /// Per record, where its row of its group's `K` lies ([`envelope`]), and the last row of
    /// the group whose envelope reaches its column (both within the group).
    rows: Vec<Row>,
    reach: Vec<usize>,
    scratch: Scratch,
    /// Groups whose projections ran out of rounds with a row still out of bounds, since the
    /// last [`JointBlocks::take_cut_short`].
    cut_short: usize,
    /// Per group, whether a solve's active sets cycled since the last
    /// [`JointBlocks::take_cycled`].
    cycled: Vec<bool>,
    /// Which of each constraint's two bodies moved (`is_dynamic`) when the groups were made:
    /// they decide the groups.
    built_for: Vec<(bool, bool)>,
}

/// One group's system: geometry, rates and their ranges, `K`, impulses, the active set.
#[derive(Debug, Clone, Default)]
struct Scratch {
    geometries: Vec<Geometry>,
    jacobians: Vec<Jacobian>,
    u: Vec<f64>,
    lo: Vec<f64>,
    hi: Vec<f64>,
    lambda: Vec<f64>,
    /// `K` by its envelope, in the group's layout.
    k: Vec<f64>,
    side: Vec<Side>,
    active: Vec<usize>,
    x: Vec<f64>,
    /// Each row's anticipated drift in the soft pass ([`drift_lengthening`]).
    ahead: Vec<f64>,
    /// Whether `factor` holds the factors of the rows `active` the last solve ended with.
    factored: bool,
    /// The `L D L^T` factors of `K`'s active rows and columns, by its envelope.
    factor: Factor,
    /// Projections cut short in this scratch (see [`JointBlocks::cut_short`]).
    cut_short: usize,
    /// Whether an active-set loop with dependent rows ran out of rounds, and relaxing did not
    /// settle, since the last look.
    cycled: bool,
}

/// The factors of `K = L D L^T` kept by its envelope ([`envelope`]): `L` left of the diagonal,
/// `D` on it, and `D`'s reciprocals.
#[derive(Debug, Clone, Default)]
struct Factor {
    rows: Vec<Row>,
    values: Vec<f64>,
    inverse_diagonal: Vec<f64>,
    /// Whether the last solve's factors are in `rows`, `values` and `inverse_diagonal` (not
    /// in `pivoted`).
    envelope_factors: bool,
    /// For systems the envelope's factorisation refuses.
    pivoted: PivotedLdl,
}

impl JointBlocks {
    /// Pairs each record's lower and upper inequality (as the loader builds them) into one
    /// record and groups records that share a movable body (union-find).
    pub fn new(constraints: &[DistanceConstraint], bodies: &[RigidBody]) -> Self {
        let records = records_of(constraints);
        let mut sets = DisjointSets::new(bodies.len());
        for r in &records {
            if bodies[r.body1].is_dynamic() && bodies[r.body2].is_dynamic() {
                sets.join(r.body1, r.body2);
            }
        }
        let mut keyed: Vec<(usize, DistanceRecord)> = records
            .into_iter()
            .filter(|r| bodies[r.body1].is_dynamic() || bodies[r.body2].is_dynamic())
            .map(|r| {
                let anchor = if bodies[r.body1].is_dynamic() {
                    r.body1
                } else {
                    r.body2
                };
                (sets.root(anchor), r)
            })
            .collect();
        keyed.sort_by_key(|(group, _)| *group);
        let records: Vec<DistanceRecord> = keyed.iter().map(|(_, r)| *r).collect();
        let mut blocks = Self {
            records,
            built_for: moving_ends(constraints, bodies).collect(),
            ..Self::default()
        };
        let mut start = 0;
        for k in 1..=keyed.len() {
            if k == keyed.len() || keyed[k].0 != keyed[start].0 {
                blocks.add_group(start..k);
                start = k;
            }
        }
        blocks
    }

    /// The group of `records`: its envelope, and if it is solved directly, its couplings.
    fn add_group(&mut self, records: Range<usize>) {
        let group_records = &self.records[records.clone()];
        let mut rows = Vec::new();
        let envelope = envelope::layout(first_sharing(group_records), &mut rows);
        let first = self.couplings.len();
        if envelope <= MAX_ENVELOPE {
            self.couplings.extend(sharing_pairs(group_records));
        }
        let mut reach = Vec::new();
        envelope::reach(&rows, &mut reach);
        self.rows.extend(rows);
        self.reach.extend(reach);
        self.groups.push(Group {
            records,
            couplings: first..self.couplings.len(),
            envelope,
            relaxed: false,
            rods: group_records.iter().any(|r| r.lower == r.upper),
        });
    }

    /// Whether the grouping still fits these constraints and bodies: as many constraints, each
    /// with the same of its two bodies moving. A body frozen by the pose check, or moving again
    /// after a snapshot from before it froze was restored, changes the groups; checking only
    /// that every record kept a moving body missed both, and a restored snapshot stepped on with
    /// groups made after it (a property test's random scene at dt 0.069).
    pub fn fits(&self, constraints: &[DistanceConstraint], bodies: &[RigidBody]) -> bool {
        self.built_for.len() == constraints.len()
            && moving_ends(constraints, bodies).eq(self.built_for.iter().copied())
    }
}

/// Whether each constraint's two bodies move.
fn moving_ends<'a>(
    constraints: &'a [DistanceConstraint],
    bodies: &'a [RigidBody],
) -> impl Iterator<Item = (bool, bool)> + 'a {
    constraints
        .iter()
        .map(|c| (bodies[c.body1].is_dynamic(), bodies[c.body2].is_dynamic()))
}

/// For each record, the first record (by index, at most its own) that shares a body with it:
/// where its row of `K` starts.
fn first_sharing(records: &[DistanceRecord]) -> Vec<usize> {
    let mut first_on: HashMap<usize, usize> = HashMap::new();
    let mut out = Vec::with_capacity(records.len());
    for (j, r) in records.iter().enumerate() {
        let mut first = j;
        for body in [r.body1, r.body2] {
            first = first.min(*first_on.entry(body).or_insert(j));
        }
        out.push(first);
    }
    out
}

/// The pairs (i < j) of `records` that share a body, in increasing order.
fn sharing_pairs(records: &[DistanceRecord]) -> Vec<(usize, usize)> {
    let mut on: HashMap<usize, Vec<usize>> = HashMap::new();
    for (j, r) in records.iter().enumerate() {
        on.entry(r.body1).or_default().push(j);
        if r.body2 != r.body1 {
            on.entry(r.body2).or_default().push(j);
        }
    }
    let mut pairs: Vec<(usize, usize)> = on
        .values()
        .flat_map(|list| {
            list.iter()
                .enumerate()
                .flat_map(move |(a, &i)| list[a + 1..].iter().map(move |&j| (i, j)))
        })
        .collect();
    pairs.sort_unstable();
    pairs.dedup();
    pairs
}

/// Consecutive lower and upper inequalities on the same points become one record.
fn records_of(constraints: &[DistanceConstraint]) -> Vec<DistanceRecord> {
    let mut out = Vec::with_capacity(constraints.len() / 2 + 1);
    let mut k = 0;
    while k < constraints.len() {
        let c = &constraints[k];
        let mut record = DistanceRecord {
            first_constraint: k,
            constraint_count: 1,
            body1: c.body1,
            body2: c.body2,
            local1: c.local1,
            local2: c.local2,
            lower: if c.is_upper { 0.0 } else { c.reference },
            upper: if c.is_upper {
                c.reference
            } else {
                f64::INFINITY
            },
        };
        if let Some(next) = constraints.get(k + 1)
            && (next.body1, next.body2, next.local1, next.local2)
                == (c.body1, c.body2, c.local1, c.local2)
            && next.is_upper != c.is_upper
        {
            if next.is_upper {
                record.upper = next.reference;
            } else {
                record.lower = next.reference;
            }
            record.constraint_count = 2;
            k += 1;
        }
        out.push(record);
        k += 1;
    }
    out
}

/// A record's [`points_geometry`], none where its points coincide (the tests' checks).
#[cfg(test)]
fn geometry(r: &DistanceRecord, a: &RigidBody, b: &RigidBody) -> Option<Geometry> {
    points_geometry((a, r.local1), (b, r.local2), |_, _| None)
}

/// Shortest distance between a record's points that gives it an axis of its own.
const MIN_AXIS_LENGTH: f64 = 1e-12;

/// The geometry of two body points (`local` to each body): their arms, the unit axis from the
/// first to the second and their distance. Where they coincide (a distance of 0: a ball joint)
/// the axis is `coincident_axis(r1, r2)`'s direction (`Y` where that is zero), or there is
/// none if it gives None. None too where the poses are not finite. A record with no axis
/// left its whole group unsolved: a body pinned at a point by a zero-length record kept
/// gravity's velocity step after step while its projection put it back (energy x8 in 4 s,
/// found by a review with hand-made scenes); its velocity rows now take the direction its
/// points separate at.
// `points_geometry` and `jacobian` are inlined into their loops: called, their results came
// back through the stack, and reading them back in wider loads than they were written in
// stalled (a third of the velocity pass's own samples in `perf` on the two chains).
#[inline(always)]
pub(super) fn points_geometry(
    (a, local1): (&RigidBody, DVec3),
    (b, local2): (&RigidBody, DVec3),
    coincident_axis: impl FnOnce(DVec3, DVec3) -> Option<DVec3>,
) -> Option<Geometry> {
    let r1 = a.orientation * local1;
    let r2 = b.orientation * local2;
    let d = (b.position + r2) - (a.position + r1);
    let length = d.length();
    if !length.is_finite() {
        return None;
    }
    let axis = if length > MIN_AXIS_LENGTH {
        d / length
    } else {
        coincident_axis(r1, r2)?.try_normalize().unwrap_or(DVec3::Y)
    };
    Some(Geometry {
        r1,
        r2,
        axis,
        length,
    })
}

/// How far a row's ends may turn in a substep (radians, the faster end's spin or the row's own
/// turn) with the drift's lengthening anticipated in full ([`drift_lengthening`]); from there
/// to twice it, less, and past that not at all. The second-order expansion overshoots as the
/// turn grows: a bar spinning on a rod in zero gravity (dt 0.04, four to sixteen substeps,
/// 10 s) gained up to 4 % of its energy anticipated in full at any turn (at 50 rad/s), 0.6 %
/// with this limit at 0.15 rad (at 30 rad/s; 21 cases of 5-150 rad/s), and 0.08 % at 0.1 (one
/// case of 21, at 20 rad/s; measured).
const ANTICIPATED_TURN: f64 = 0.1;

/// The rate at which a substep's drift (constant velocities, torque-free spin) lengthens a row
/// beyond its rate `n . u`: `h/2` times the length's second derivative,
/// `n . (a2 - a1) + |u - (n . u) n|^2 / length`, with `a` an end's acceleration in the spin
/// (centripetal, and Euler's `I^-1 (I w x w) x r`) and `u` the ends' relative velocity; scaled
/// down for fast turns ([`ANTICIPATED_TURN`]). A rod's target rate less this lands the drift
/// on the rod's length, as SHAKE's does (Ryckaert, Ciccotti and Berendsen 1977); without it the
/// rod ends each substep stretched by `h^2/2` of that derivative, and projecting it back moves
/// the body without the velocity that would move it: a box hung by a corner on a rigid rod
/// lost 48 % of its swing in 20 s at dt 0.04, 24 % at dt 0.01 (`bench accuracy`). Rigid
/// rods only: with the ranges of ropes anticipated too, rope-200 whipping at dt 0.02 gained
/// 1.2 % of its energy in 20 s (none without; measured).
#[inline(always)]
fn drift_lengthening(
    g: &Geometry,
    relative: DVec3,
    (pose1, body1): (&RigidBody, &SolverBody),
    (pose2, body2): (&RigidBody, &SolverBody),
    inv_h: f64,
) -> f64 {
    let spin = |body: &SolverBody| {
        if body.inverse_mass == 0.0 {
            DVec3::ZERO
        } else {
            body.angular_velocity
        }
    };
    let (w1, w2) = (spin(body1), spin(body2));
    let along = g.axis.dot(relative);
    let across = (relative.length_squared() - along * along).max(0.0);
    // The fastest turn as a rate, against the rate of a full anticipation's largest turn.
    let fastest = (w1.length_squared())
        .max(w2.length_squared())
        .max(across / (g.length * g.length));
    let full = ANTICIPATED_TURN * inv_h;
    let weight = if fastest <= full * full {
        1.0
    } else if fastest >= 4.0 * full * full {
        return 0.0;
    } else {
        2.0 - fastest.sqrt() / full
    };
    // Euler's equations in the body's frame: `I w' = I w x w`.
    let acceleration = |pose: &RigidBody, w: DVec3, r: DVec3| {
        if w == DVec3::ZERO {
            return DVec3::ZERO;
        }
        let mut a = w.cross(w.cross(r));
        if !pose.inertia.is_isotropic() {
            let local = pose.orientation.inverse() * w;
            let change = pose
                .inverse_inertia
                .mul_vec3(pose.inertia.mul_vec3(local).cross(local));
            a += (pose.orientation * change).cross(r);
        }
        a
    };
    let a = acceleration(pose2, w2, g.r2) - acceleration(pose1, w1, g.r1);
    weight * 0.5 / inv_h * (g.axis.dot(a) + across / g.length)
}

/// Record `r`'s rate at geometry `g` (its points' relative velocity along the axis), and, when
/// `anticipate`, for a rigid rod the rate its drift will add ([`drift_lengthening`]; else
/// zero).
///
/// # Safety
/// No other thread writes the record's bodies meanwhile.
#[inline(always)]
unsafe fn rate_and_drift(
    (r, g): (&DistanceRecord, &Geometry),
    poses: &[RigidBody],
    bodies: &Shared<SolverBody>,
    (inv_h, anticipate): (f64, bool),
) -> (f64, f64) {
    // SAFETY: the caller's contract.
    let (b1, b2) = unsafe { (bodies.get(r.body1), bodies.get(r.body2)) };
    let relative = b2.point_velocity(g.r2) - b1.point_velocity(g.r1);
    // A record without an axis of its own ([`points_geometry`]) has no lengthening to
    // anticipate.
    let ahead = if anticipate && r.lower == r.upper && g.length > MIN_AXIS_LENGTH {
        let ends = ((&poses[r.body1], b1), (&poses[r.body2], b2));
        drift_lengthening(g, relative, ends.0, ends.1, inv_h)
    } else {
        0.0
    };
    (g.axis.dot(relative), ahead)
}

/// The row's Jacobian at geometry `g`; `inverse(b)` is body b's inverse mass and world inverse
/// inertia.
#[inline(always)]
fn jacobian(
    r: &DistanceRecord,
    g: &Geometry,
    inverse: &impl Fn(usize) -> (f64, DMat3),
) -> Jacobian {
    let mut out = Jacobian::default();
    for (end, (body, arm)) in [(r.body1, g.r1), (r.body2, g.r2)].into_iter().enumerate() {
        let (inverse_mass, inverse_inertia) = inverse(body);
        out.angular[end] = arm.cross(g.axis);
        out.response[end] = inverse_inertia * out.angular[end];
        out.inverse_mass[end] = inverse_mass;
    }
    out
}

/// `K_ij`: how a unit impulse of row j changes row i's rate, through the bodies they share
/// (body 1 is pushed against the axis, body 2 along it).
fn coupling(
    (ri, gi, ji): (&DistanceRecord, &Geometry, &Jacobian),
    (rj, gj, jj): (&DistanceRecord, &Geometry, &Jacobian),
) -> f64 {
    let mut k = 0.0;
    for (ei, bi) in [ri.body1, ri.body2].into_iter().enumerate() {
        for (ej, bj) in [rj.body1, rj.body2].into_iter().enumerate() {
            if bi != bj {
                continue;
            }
            let sign = if ei == ej { 1.0 } else { -1.0 };
            k += sign
                * (ji.inverse_mass[ei] * gi.axis.dot(gj.axis)
                    + ji.angular[ei].dot(jj.response[ej]));
        }
    }
    k
}

impl Scratch {
    fn reset(&mut self, n: usize, envelope: usize) {
        for v in [&mut self.u, &mut self.lo, &mut self.hi, &mut self.lambda] {
            v.clear();
            v.resize(n, 0.0);
        }
        self.k.clear();
        self.k.resize(envelope, 0.0);
    }

    /// The rows' rates `u` must end within `[lo, hi]` (per row); finds impulses `lambda` with
    /// `u + K lambda` in range, `lambda >= 0` where held at its low end, `<= 0` at its high
    /// end. False when the block could not be solved (the caller leaves the group alone).
    fn solve_ranges(&mut self, group: GroupView) -> bool {
        let n = group.records.len();
        let Scratch {
            u,
            lo,
            hi,
            lambda,
            k,
            side,
            ..
        } = self;
        self.factored = false;
        if n == 1 {
            return solve_one_range(u[0], lo[0], hi[0], k[0], &mut lambda[0]);
        }
        side.clear();
        side.extend((0..n).map(|i| {
            // SAFETY: the group's own records (groups are disjoint).
            let held = unsafe { group.held.read(group.first + i) };
            if lo[i] == hi[i] {
                Side::Both
            } else if u[i] < lo[i] {
                Side::Lower
            } else if u[i] > hi[i] {
                Side::Upper
            } else if held == Side::Both {
                Side::Free
            } else {
                held
            }
        }));
        let solved = self.active_set_rounds(group);
        for (i, &s) in self.side.iter().enumerate() {
            // SAFETY: as above.
            unsafe { group.held.write(group.first + i, s) };
        }
        solved
    }

    /// The active-set loop of [`Scratch::solve_ranges`], from the sides set.
    fn active_set_rounds(&mut self, group: GroupView) -> bool {
        let Scratch {
            u,
            lo,
            hi,
            lambda,
            k,
            side,
            active,
            x,
            ..
        } = self;
        let n = group.records.len();
        let matrix = (group.rows, group.reach, &k[..]);
        let mut dependent = false;
        for _ in 0..ACTIVE_SET_ROUNDS {
            active.clear();
            active.extend((0..n).filter(|&i| side[i] != Side::Free));
            x.clear();
            x.extend(
                active
                    .iter()
                    .map(|&i| if side[i] == Side::Upper { hi[i] } else { lo[i] } - u[i]),
            );
            let Some(kept) = self.factor.solve(group.rows, (k, active), x) else {
                return false;
            };
            dependent |= kept < active.len();
            lambda.iter_mut().for_each(|l| *l = 0.0);
            for (a, &i) in active.iter().enumerate() {
                lambda[i] = x[a];
            }
            if !update_sides((u, lo, hi), lambda, matrix, side) {
                self.factored = self.factor.envelope_factors;
                return true;
            }
        }
        // Rows that depend on each other (an over-braced truss) with a range each: the active
        // sets can cycle, each leaving a row out of range that a twin would have held. The
        // last impulses are relaxed into ranges; if that does not settle either, the solve is
        // refused (the group left alone in this pass; its impulses, applied, tore a truss
        // apart) and the group is flagged, to be handed to Gauss-Seidel from the next step.
        if dependent && !relax_ranges((u, lo, hi), lambda, matrix, side) {
            self.cycled = true;
            return false;
        }
        true
    }
}

impl Factor {
    /// Factors `K`'s `active` rows and columns (`K` in the layout `rows`) and solves that
    /// system for `x`, which holds the right-hand side: the number of rows kept (the others
    /// depend on them and get no impulse), or None if it is not positive semi-definite.
    fn solve(
        &mut self,
        rows: &[Row],
        (k, active): (&[f64], &[usize]),
        x: &mut [f64],
    ) -> Option<usize> {
        envelope::principal((rows, k), active, (&mut self.rows, &mut self.values));
        self.envelope_factors =
            envelope::ldl_factor(&self.rows, &mut self.values, &mut self.inverse_diagonal);
        if self.envelope_factors {
            envelope::ldl_substitute(&self.rows, &self.values, &self.inverse_diagonal, x);
            return Some(active.len());
        }
        // Rows dependent, or nearly in this order (an over-braced truss): solved again with
        // pivoting.
        if active.len() > pivoted_ldl::MAX_ROWS {
            return None;
        }
        envelope::principal((rows, k), active, (&mut self.rows, &mut self.values));
        self.pivoted.solve(&self.rows, &self.values, x)
    }
}

/// Sweeps of [`relax_ranges`] at most.
const RELAX_SWEEPS: usize = 100;

/// Projected Gauss-Seidel (Cottle, Pang and Stone, "The Linear Complementarity Problem",
/// 1992, 5.2) from the impulses `lambda`: each row's impulse in turn set to bring its rate to
/// the nearer end of its range, or to zero where its rate is inside, until no impulse moves a
/// rate by more than rounding; then the sides held are those of the impulses. With `K` only
/// semi-definite it does not cycle as the active-set loop can, and no update exceeds the
/// row's own residual. True if it settled within [`RELAX_SWEEPS`].
fn relax_ranges(
    (u, lo, hi): (&[f64], &[f64], &[f64]),
    lambda: &mut [f64],
    (rows, reach, k): (&[Row], &[usize], &[f64]),
    side: &mut [Side],
) -> bool {
    let mut converged = false;
    for _ in 0..RELAX_SWEEPS {
        let mut moved: f64 = 0.0;
        for i in 0..u.len() {
            let diagonal = k[envelope::at(rows, i, i)];
            if diagonal.is_nan() || diagonal <= 0.0 {
                continue;
            }
            let rate = u[i] + envelope::row_times(rows, k, reach, i, lambda);
            let old = lambda[i];
            let (to_lo, to_hi) = (
                old + (lo[i] - rate) / diagonal,
                old + (hi[i] - rate) / diagonal,
            );
            lambda[i] = 0.0f64.max(to_lo).min(to_hi);
            let tolerance = 1e-12 * (1.0 + rate.abs());
            moved = moved.max(((lambda[i] - old) * diagonal).abs() / tolerance);
        }
        if moved <= 1.0 {
            converged = true;
            break;
        }
    }
    for (s, &l) in side.iter_mut().zip(lambda.iter()) {
        if *s != Side::Both {
            *s = match l {
                l if l > 0.0 => Side::Lower,
                l if l < 0.0 => Side::Upper,
                _ => Side::Free,
            };
        }
    }
    converged
}

/// [`Scratch::solve_ranges`] for a single row (a pendulum, a rod to a fixed body): the rate
/// `u` brought to the nearer end of `[lo, hi]` through `k`, or left alone inside it.
fn solve_one_range(u: f64, lo: f64, hi: f64, k: f64, lambda: &mut f64) -> bool {
    let target = if u < lo {
        lo
    } else if u > hi {
        hi
    } else {
        *lambda = 0.0;
        return true;
    };
    if k <= 1e-300 || !k.is_finite() {
        return false;
    }
    *lambda = (target - u) / k;
    true
}

/// Rows pushing the wrong way let go; rows now out of range are held. True if any changed.
fn update_sides(
    (u, lo, hi): (&[f64], &[f64], &[f64]),
    lambda: &[f64],
    (rows, reach, k): (&[Row], &[usize], &[f64]),
    side: &mut [Side],
) -> bool {
    let n = u.len();
    let mut changed = false;
    for i in 0..n {
        let wrong = match side[i] {
            Side::Lower => lambda[i] < 0.0,
            Side::Upper => lambda[i] > 0.0,
            _ => false,
        };
        if wrong {
            side[i] = Side::Free;
            changed = true;
        }
    }
    if changed {
        return true;
    }
    for i in 0..n {
        if side[i] != Side::Free {
            continue;
        }
        let rate = u[i] + envelope::row_times(rows, k, reach, i, lambda);
        let tolerance = 1e-12 * (1.0 + rate.abs());
        if rate < lo[i] - tolerance {
            side[i] = Side::Lower;
            changed = true;
        } else if rate > hi[i] + tolerance {
            side[i] = Side::Upper;
            changed = true;
        }
    }
    changed
}

impl JointBlocks {
    /// The world's constraints (indices) in groups too large to solve directly, or relaxed.
    pub fn large_group_constraints(&self) -> Vec<usize> {
        let mut out = Vec::new();
        for g in &self.groups {
            if !g.direct() {
                for r in &self.records[g.records.clone()] {
                    out.extend(r.constraints());
                }
            }
        }
        out.sort_unstable();
        out
    }

    /// Velocities: each group's rows end the pass with rates in range. With a `push` speed a
    /// violated bound is approached back at its full error per substep, but no faster than
    /// that (as the contacts and the rows solved one by one: where a projection left a whip
    /// stretched, the pull at full error handed it energy, rope-200 at dt 0.04 5.4 times its
    /// own in 20 s); without, it is only not crossed. A bound not yet reached may be reached
    /// but not passed (speculative).
    pub fn solve_velocities(
        &mut self,
        (poses, bodies): (&[RigidBody], &mut [SolverBody]),
        held: &mut HeldSides,
        inv_h: f64,
        push: Option<f64>,
    ) {
        self.solve_velocities_where((poses, bodies), held, (inv_h, push), |_| true);
    }

    /// [`JointBlocks::solve_velocities`] without a push, on the groups with a body flagged in
    /// `struck` only, flagging no cycle for the next step (the restitution pass holds the rods
    /// of the bodies it bounces for itself alone; the caller keeps `held` aside).
    pub fn hold_rates_of(
        &mut self,
        (poses, bodies): (&[RigidBody], &mut [SolverBody]),
        held: &mut HeldSides,
        inv_h: f64,
        struck: &[bool],
    ) {
        let flagged = |b: usize| struck.get(b) == Some(&true);
        let touches = |records: &[DistanceRecord]| {
            records.iter().any(|r| flagged(r.body1) || flagged(r.body2))
        };
        let cycled = self.cycled.clone();
        self.solve_velocities_where((poses, bodies), held, (inv_h, None), touches);
        self.cycled = cycled;
    }

    /// [`JointBlocks::solve_velocities`] on the groups whose records are `wanted`.
    fn solve_velocities_where(
        &mut self,
        (poses, bodies): (&[RigidBody], &mut [SolverBody]),
        held: &mut HeldSides,
        (inv_h, push): (f64, Option<f64>),
        wanted: impl Fn(&[DistanceRecord]) -> bool + Sync,
    ) {
        let bodies = Shared::new(bodies);
        held.fit(self.records.len());
        self.for_each_group(&mut held.velocities, |scratch, group| {
            if wanted(group.records) {
                // SAFETY: groups share no moving body; poses are only read.
                unsafe { scratch.solve_group_velocities(group, poses, &bodies, inv_h, push) };
            }
            false
        });
    }

    /// Positions: each group's violated rows are moved back onto their bounds, through the
    /// bodies' masses, as an impulse would move them in unit time (velocities untouched); a
    /// group is left alone unless a row is out by more than `first_tolerance` of its bound.
    /// Returns whether any pose moved.
    pub fn project_positions(
        &mut self,
        (poses, bodies): (&mut [RigidBody], &[SolverBody]),
        held: &mut HeldSides,
        first_tolerance: f64,
    ) -> bool {
        let poses = Shared::new(poses);
        held.fit(self.records.len());
        self.for_each_group(&mut held.positions, |scratch, group| {
            // SAFETY: groups share no moving body, and only moving bodies' poses are written.
            unsafe { scratch.project_group(group, &poses, bodies, first_tolerance) }
        })
    }

    /// Runs `f` on each group solved directly, with a scratch of its own: on the calling thread
    /// for a few groups, else on all threads (groups share no moving body, so the result is
    /// the same). True if `f` returned true for any group.
    fn for_each_group(
        &mut self,
        held: &mut [Side],
        f: impl Fn(&mut Scratch, GroupView) -> bool + Sync,
    ) -> bool {
        const PARALLEL_GROUPS: usize = 64;
        let JointBlocks {
            records,
            groups,
            couplings,
            rows,
            reach,
            scratch,
            cut_short,
            cycled,
            ..
        } = self;
        cycled.resize(groups.len(), false);
        let held = Shared::new(held);
        let cycled_in = Shared::new(cycled);
        let view = |g: &Group| GroupView {
            records: &records[g.records.clone()],
            couplings: &couplings[g.couplings.clone()],
            rows: &rows[g.records.clone()],
            reach: &reach[g.records.clone()],
            envelope: g.envelope,
            held: &held,
            first: g.records.start,
            rods: g.rods,
        };
        let direct = |(_, g): &(usize, &Group)| g.direct();
        // Whether a pose moved, and the projections cut short.
        let run = |scratch: &mut Scratch, (index, g): (usize, &Group)| {
            let before = scratch.cut_short;
            let moved = f(scratch, view(g));
            let cut = scratch.cut_short - before;
            if std::mem::take(&mut scratch.cycled) {
                // SAFETY: each group's own flag, written by the one thread that solves it.
                unsafe { cycled_in.write(index, true) };
            }
            (moved, cut)
        };
        let either = |a: (bool, usize), b: (bool, usize)| (a.0 || b.0, a.1 + b.1);
        let (moved, cut) = if groups.len() < PARALLEL_GROUPS {
            let solved = groups.iter().enumerate().filter(direct);
            solved.fold((false, 0), |sum, g| either(sum, run(scratch, g)))
        } else {
            groups
                .par_iter()
                .enumerate()
                .with_min_len(16)
                .filter(direct)
                .map_init(Scratch::default, run)
                .reduce(|| (false, 0), either)
        };
        *cut_short += cut;
        moved
    }

    /// Groups handed to Gauss-Seidel ([`JointBlocks::relax_marked`]).
    pub fn relaxed_groups(&self) -> usize {
        self.groups.iter().filter(|g| g.relaxed).count()
    }

    /// At the end of a step: marks in `relaxed` (per world constraint) the constraints of the
    /// groups whose active sets cycled in it, so that the state between steps holds them.
    pub fn take_cycled(&mut self, relaxed: &mut [bool]) {
        for (g, cycled) in self.groups.iter().zip(&mut self.cycled) {
            if std::mem::take(cycled) {
                let records = &self.records[g.records.clone()];
                for r in records {
                    if let Some(flags) = relaxed.get_mut(r.constraints()) {
                        flags.fill(true);
                    }
                }
            }
        }
    }

    /// Before a step's solve (within a step the rows of
    /// [`JointBlocks::large_group_constraints`] are fixed): hands each group with a constraint
    /// marked in `relaxed` to Gauss-Seidel; true if a group's solver changed.
    pub fn relax_marked(&mut self, relaxed: &[bool]) -> bool {
        let mut changed = false;
        for g in &mut self.groups {
            let records = &self.records[g.records.clone()];
            let now = records.iter().any(|r| {
                relaxed
                    .get(r.constraints())
                    .is_some_and(|flags| flags.contains(&true))
            });
            changed |= now != g.relaxed;
            g.relaxed = now;
        }
        changed
    }

    /// The projections cut short since the last call (see [`JointBlocks::cut_short`]).
    pub fn take_cut_short(&mut self) -> usize {
        std::mem::take(&mut self.cut_short)
    }
}

/// One group's records, the pairs of them that share a body, and the layout of its `K`.
#[derive(Clone, Copy)]
struct GroupView<'a> {
    records: &'a [DistanceRecord],
    couplings: &'a [(usize, usize)],
    rows: &'a [Row],
    reach: &'a [usize],
    envelope: usize,
    /// The active sets of the last solves, by record of the world, and the group's first.
    held: &'a Shared<'a, Side>,
    first: usize,
    rods: bool,
}

impl Scratch {
    /// [`JointBlocks::solve_velocities`] for one group.
    ///
    /// # Safety
    /// No other thread touches the group's moving bodies meanwhile.
    unsafe fn solve_group_velocities(
        &mut self,
        group: GroupView,
        poses: &[RigidBody],
        bodies: &Shared<SolverBody>,
        inv_h: f64,
        push: Option<f64>,
    ) {
        let records = group.records;
        let inverse = |i: usize| {
            // SAFETY: the group's bodies (caller's contract).
            let b = unsafe { bodies.get(i) };
            (b.inverse_mass, b.inverse_inertia)
        };
        // Points that coincide are held along the way they separate.
        let separating = |r: &DistanceRecord, r1: DVec3, r2: DVec3| {
            // SAFETY: the group's bodies (caller's contract).
            let (b1, b2) = unsafe { (bodies.get(r.body1), bodies.get(r.body2)) };
            b2.point_velocity(r2) - b1.point_velocity(r1)
        };
        if !self.set_up(group, |i| &poses[i], &inverse, separating) {
            return;
        }
        let anticipating = push.is_some() && group.rods;
        if anticipating {
            self.ahead.clear();
            self.ahead.resize(records.len(), 0.0);
        }
        for (i, (r, g)) in records.iter().zip(&self.geometries).enumerate() {
            // SAFETY: the group's bodies (caller's contract).
            let (rate, ahead) =
                unsafe { rate_and_drift((r, g), poses, bodies, (inv_h, anticipating)) };
            self.u[i] = rate;
            if anticipating {
                self.ahead[i] = ahead;
            }
            let allowed = |gap: f64| match push {
                _ if gap > 0.0 => gap * inv_h,
                Some(cap) => (gap * inv_h).max(-cap),
                None => 0.0,
            };
            (self.lo[i], self.hi[i]) = if r.lower == r.upper {
                let rate = push.map_or(0.0, |cap| ((r.lower - g.length) * inv_h).clamp(-cap, cap));
                (rate, rate)
            } else {
                (-allowed(g.length - r.lower), allowed(r.upper - g.length))
            };
            if anticipating {
                self.lo[i] -= self.ahead[i];
                self.hi[i] -= self.ahead[i];
            }
        }
        if self.solve_ranges(group) {
            // SAFETY: as above.
            unsafe { self.apply(records, bodies) };
            if anticipating && self.ahead.iter().any(|&a| a != 0.0) {
                // SAFETY: as above.
                unsafe { self.anticipate_again(group, poses, bodies, inv_h) };
            }
        }
    }

    /// The rods' drift anticipated again from the solved velocities, and the held rows'
    /// impulses corrected by the difference through the factors of their last solve (one more
    /// substitution, no new factors). Anticipated in full at any turn from the velocities
    /// before the solve alone, a box hung by a corner gained 27 % of its swing in 300 s at
    /// dt 0.04; corrected, 3.3 % (measured).
    ///
    /// # Safety
    /// As [`Scratch::solve_group_velocities`].
    unsafe fn anticipate_again(
        &mut self,
        group: GroupView,
        poses: &[RigidBody],
        bodies: &Shared<SolverBody>,
        inv_h: f64,
    ) {
        let records = group.records;
        let n = records.len();
        let single_held = n == 1 && (self.lambda[0] != 0.0 || self.lo[0] == self.hi[0]);
        if !(self.factored || single_held) {
            return;
        }
        self.x.clear();
        if single_held {
            self.active.clear();
            self.active.push(0);
        }
        for &i in &self.active {
            // SAFETY: the group's bodies (caller's contract).
            let (_, ahead) = unsafe {
                rate_and_drift(
                    (&records[i], &self.geometries[i]),
                    poses,
                    bodies,
                    (inv_h, true),
                )
            };
            self.x.push(self.ahead[i] - ahead);
        }
        if single_held {
            self.x[0] /= self.k[0];
        } else {
            let f = &self.factor;
            envelope::ldl_substitute(&f.rows, &f.values, &f.inverse_diagonal, &mut self.x);
        }
        self.lambda.iter_mut().for_each(|l| *l = 0.0);
        for (&i, &x) in self.active.iter().zip(&self.x) {
            self.lambda[i] = x;
        }
        // SAFETY: as above.
        unsafe { self.apply(records, bodies) };
    }

    /// [`JointBlocks::project_positions`] for one group; true if a pose moved.
    ///
    /// # Safety
    /// No other thread touches the group's moving bodies meanwhile.
    unsafe fn project_group(
        &mut self,
        group: GroupView,
        poses: &Shared<RigidBody>,
        bodies: &[SolverBody],
        first_tolerance: f64,
    ) -> bool {
        let mut moved = false;
        for round in 0..PROJECTION_ROUNDS {
            let tolerance = if round == 0 {
                first_tolerance
            } else {
                PROJECTION_TOLERANCE
            };
            // SAFETY: the caller's contract.
            if !unsafe { self.project_group_once(group, poses, bodies, tolerance) } {
                return moved;
            }
            moved = true;
        }
        // SAFETY: as above.
        let records = group.records;
        if !unsafe { Self::within_bounds(records, poses, PROJECTION_TOLERANCE) } {
            self.cut_short += 1;
        }
        moved
    }

    /// Whether every row of `records` lies within its bounds, widened by `tolerance` of them,
    /// at the current poses: squared lengths against squared bounds, the geometry not kept.
    /// Most checks find the group inside; with the geometry loaded, the three mid-step checks
    /// of a step cost chain-1000 7 % of its step on one thread, now 3-4 %.
    ///
    /// # Safety
    /// As [`Scratch::project_group`].
    unsafe fn within_bounds(
        records: &[DistanceRecord],
        poses: &Shared<RigidBody>,
        tolerance: f64,
    ) -> bool {
        records.iter().all(|r| {
            // SAFETY: the group's poses are written only by this call (caller's contract).
            let (a, b) = unsafe { (poses.get(r.body1), poses.get(r.body2)) };
            let d =
                (b.position + b.orientation * r.local2) - (a.position + a.orientation * r.local1);
            let squared = d.length_squared();
            let (lower, upper) = (r.lower * (1.0 - tolerance), r.upper * (1.0 + tolerance));
            squared >= lower.max(0.0).powi(2) && squared <= upper * upper
        })
    }

    /// One projection of a group whose rows are outside their bounds by more than `tolerance`
    /// of the bound; true if a pose moved.
    ///
    /// # Safety
    /// As [`Scratch::project_group`].
    unsafe fn project_group_once(
        &mut self,
        group: GroupView,
        poses: &Shared<RigidBody>,
        bodies: &[SolverBody],
        tolerance: f64,
    ) -> bool {
        let records = group.records;
        // SAFETY: the caller's contract (both).
        if unsafe { Self::within_bounds(records, poses, tolerance) }
            || !self.load_geometry(records, |i| unsafe { poses.get(i) }, |_, _, _| DVec3::Y)
        {
            return false;
        }
        self.reset(records.len(), group.envelope);
        for (i, (r, g)) in records.iter().zip(&self.geometries).enumerate() {
            (self.u[i], self.lo[i], self.hi[i]) = (g.length, r.lower, r.upper);
        }
        let inverse = |i: usize| (bodies[i].inverse_mass, bodies[i].inverse_inertia);
        self.fill_matrix(group, &inverse);
        if !self.solve_ranges(group) {
            return false;
        }
        // SAFETY: as above.
        unsafe { self.shift(records, poses) };
        true
    }

    /// The group's geometry, Jacobians and `K` at the current poses, the rates and ranges
    /// cleared. False if a record has no geometry.
    fn set_up<'p>(
        &mut self,
        group: GroupView,
        pose: impl Fn(usize) -> &'p RigidBody,
        inverse: &impl Fn(usize) -> (f64, DMat3),
        coincident_axis: impl Fn(&DistanceRecord, DVec3, DVec3) -> DVec3,
    ) -> bool {
        self.reset(group.records.len(), group.envelope);
        if !self.load_geometry(group.records, pose, coincident_axis) {
            return false;
        }
        self.fill_matrix(group, inverse);
        true
    }

    /// Each record's geometry at the current poses (`pose(i)`: body i's), along
    /// `coincident_axis(record, r1, r2)` where its points coincide ([`points_geometry`]); false
    /// if a record has none (poses not finite).
    fn load_geometry<'p>(
        &mut self,
        records: &[DistanceRecord],
        pose: impl Fn(usize) -> &'p RigidBody,
        coincident_axis: impl Fn(&DistanceRecord, DVec3, DVec3) -> DVec3,
    ) -> bool {
        self.geometries.clear();
        for r in records {
            let ends = ((pose(r.body1), r.local1), (pose(r.body2), r.local2));
            match points_geometry(ends.0, ends.1, |r1, r2| Some(coincident_axis(r, r1, r2))) {
                Some(g) => self.geometries.push(g),
                None => return false,
            }
        }
        true
    }

    /// The rows' Jacobians, then `K = J M^-1 J^T`: the diagonal and the entries of the records
    /// that share a body (the others are zero).
    fn fill_matrix(&mut self, group: GroupView, inverse: &impl Fn(usize) -> (f64, DMat3)) {
        let (records, geometries) = (group.records, &self.geometries);
        self.jacobians.clear();
        let rows = records.iter().zip(geometries);
        self.jacobians
            .extend(rows.map(|(r, g)| jacobian(r, g, inverse)));
        let row = |i: usize| (&records[i], &geometries[i], &self.jacobians[i]);
        for i in 0..records.len() {
            self.k[envelope::at(group.rows, i, i)] = coupling(row(i), row(i));
        }
        // Only the lower triangle is kept: entry (j, i) for i < j.
        for &(i, j) in group.couplings {
            self.k[envelope::at(group.rows, j, i)] = coupling(row(i), row(j));
        }
    }

    /// Calls `f` for each end of each row with an impulse: the body, the change of its linear
    /// and its angular velocity that the impulse `lambda` makes (the change of position and
    /// the rotation it would make in unit time), and the body's inverse mass.
    fn for_each_move(
        &self,
        records: &[DistanceRecord],
        mut f: impl FnMut(usize, DVec3, DVec3, f64),
    ) {
        let rows = records.iter().zip(&self.geometries).zip(&self.jacobians);
        for (((r, g), jac), &l) in rows.zip(&self.lambda) {
            if l == 0.0 {
                continue;
            }
            for (end, (index, sign)) in [(r.body1, -1.0), (r.body2, 1.0)].into_iter().enumerate() {
                let m = jac.inverse_mass[end];
                f(
                    index,
                    (sign * l * m) * g.axis,
                    (sign * l) * jac.response[end],
                    m,
                );
            }
        }
    }

    /// The impulses `lambda` along the rows, on the group's moving bodies (the others, shared
    /// with other groups, are left alone: an impulse does not move them).
    ///
    /// # Safety
    /// No other thread touches the group's moving bodies meanwhile.
    unsafe fn apply(&self, records: &[DistanceRecord], bodies: &Shared<SolverBody>) {
        self.for_each_move(records, |index, linear, angular, _| {
            // SAFETY: read, then written only if it moves: the caller's contract.
            if unsafe { bodies.get(index) }.is_static() {
                return;
            }
            let b = unsafe { bodies.get_mut(index) };
            b.linear_velocity += linear;
            b.angular_velocity += angular;
        });
    }

    /// The position change the impulses `lambda` would make in unit time, on the group's
    /// moving bodies.
    ///
    /// # Safety
    /// No other thread touches the group's moving bodies meanwhile.
    unsafe fn shift(&self, records: &[DistanceRecord], poses: &Shared<RigidBody>) {
        self.for_each_move(records, |index, shift, turn, inverse_mass| {
            if inverse_mass == 0.0 {
                return;
            }
            // SAFETY: a body with mass to move belongs to this group only.
            let pose = unsafe { poses.get_mut(index) };
            pose.position += shift;
            pose.orientation = crate::sim::integrate::turn_by(pose.orientation, turn, 1.0);
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::assets;
    use crate::sim::integrate::integrate_pose;
    use crate::sim::rng::Rng;
    use crate::sim::settings::RotationIntegrator;
    use crate::sim::shape::Shape;
    use glam::DQuat;

    /// `n` boxes in a row (the last fixed), tilted at random, and a rod (equal bounds) between
    /// a corner of each pair of `edges`.
    fn rods(
        n: usize,
        edges: &[(usize, usize)],
        rng: &mut Rng,
    ) -> (Vec<RigidBody>, Vec<DistanceConstraint>) {
        let shape = Shape::from_tet_mesh(&assets::cuboid(DVec3::new(0.5, 0.3, 0.4))).unwrap();
        let bodies: Vec<RigidBody> = (0..n)
            .map(|k| {
                let position =
                    DVec3::new(1.5 * k as f64, rng.range(5.0, 8.0), rng.range(-1.0, 1.0));
                let tilt = DQuat::from_rotation_y(rng.range(-1.0, 1.0));
                RigidBody::on_shape(&shape, 0, 100.0, k == n - 1, position, tilt)
            })
            .collect();
        let shapes = std::slice::from_ref(&shape);
        let rod = |&(a, b): &(usize, usize)| {
            DistanceConstraint::lower_and_upper(
                &bodies,
                shapes,
                (a, a % 8),
                (b, (a + b) % 8),
                1.0,
                1.0,
            )
        };
        let constraints = edges.iter().flat_map(rod).collect();
        (bodies, constraints)
    }

    /// A chain of three moving bodies and a fixed one: when the middle body freezes (the pose
    /// check), or moves again (a snapshot from before it froze restored), the groups no longer
    /// fit, though every record keeps a moving body and the count of records stays.
    #[test]
    fn groups_are_made_again_when_a_body_stops_or_starts_moving() {
        let mut rng = Rng::new(7);
        let (mut bodies, constraints) = rods(4, &[(0, 1), (1, 2), (2, 3)], &mut rng);
        let blocks = JointBlocks::new(&constraints, &bodies);
        assert!(blocks.fits(&constraints, &bodies));
        bodies[1].quarantined = true;
        assert!(!blocks.fits(&constraints, &bodies));
        let frozen = JointBlocks::new(&constraints, &bodies);
        assert!(frozen.fits(&constraints, &bodies));
        assert_ne!(frozen.groups.len(), blocks.groups.len());
        bodies[1].quarantined = false;
        assert!(!frozen.fits(&constraints, &bodies));
    }

    /// The lengthening a rod's drift is anticipated by is the drift's own to second order:
    /// between two boxes of three different moments, moving and spinning at random, the
    /// length after drifting `h` (the angular-momentum integrator in 1,000 steps) less
    /// `L + h u + h ahead` shrinks as `h^3`, and at `h = 0.01` is a small part of the
    /// drift's lengthening beyond `L + h u`.
    #[test]
    fn the_anticipated_lengthening_is_the_drifts_own_to_second_order() {
        let mut rng = Rng::new(11);
        let (mut with, mut without) = (0.0, 0.0);
        for _ in 0..20 {
            let (mut bodies, constraints) = rods(3, &[(0, 1)], &mut rng);
            for b in &mut bodies[..2] {
                b.linear_velocity = random_vector(&mut rng, 2.0);
                b.angular_velocity = random_vector(&mut rng, 2.0);
            }
            let r = &records_of(&constraints)[0];
            let (a, b) = (&bodies[r.body1], &bodies[r.body2]);
            let g = geometry(r, a, b).unwrap();
            let (sa, sb) = (SolverBody::new(a), SolverBody::new(b));
            let rate = g
                .axis
                .dot(sb.point_velocity(g.r2) - sa.point_velocity(g.r1));
            let errors = |h: f64| {
                let relative = sb.point_velocity(g.r2) - sa.point_velocity(g.r1);
                let ahead = drift_lengthening(&g, relative, (a, &sa), (b, &sb), 1.0 / h);
                let drift = |body: &RigidBody| {
                    let mut body = body.clone();
                    for _ in 0..1000 {
                        integrate_pose(&mut body, RotationIntegrator::AngularMomentum, h / 1e3);
                    }
                    body
                };
                let length = geometry(r, &drift(a), &drift(b)).unwrap().length;
                let linear = g.length + h * rate;
                ((length - linear - h * ahead).abs(), (length - linear).abs())
            };
            let ((coarse, _), (fine, fine_linear)) = (errors(0.02), errors(0.01));
            assert!(fine < coarse / 6.0, "{fine} at h 0.01, {coarse} at 0.02");
            (with, without) = (with + fine, without + fine_linear);
        }
        assert!(with < without / 20.0, "{with} against {without}");
    }

    fn random_vector(rng: &mut Rng, size: f64) -> DVec3 {
        DVec3::new(
            rng.range(-size, size),
            rng.range(-size, size),
            rng.range(-size, size),
        )
    }

    /// Rods between random bodies, in groups of every shape: a chain in link order, the same
    /// chain listed backwards and scrambled, a tree, a star on one body, a ladder of cycles;
    /// the chains are groups of 200 records (four times the old dense limit). After one rigid
    /// velocity pass from random velocities, every rod's ends move apart at zero rate: the
    /// block solve is exact whatever the group's order and shape. A second pass from new
    /// random velocities (the active sets held from the first) is exact too.
    #[test]
    fn rods_of_any_graph_end_a_pass_without_stretching() {
        let mut rng = Rng::new(11);
        let n = 201;
        let mut pick = |k: usize| (rng.next_u64() as usize) % k;
        let chain: Vec<(usize, usize)> = (1..n).map(|k| (k - 1, k)).collect();
        let mut scrambled = chain.clone();
        for k in (1..scrambled.len()).rev() {
            scrambled.swap(k, pick(k + 1));
        }
        let rung = |k: usize| {
            [
                (2 * k, 2 * k + 1),
                (2 * k, 2 * k + 2),
                (2 * k + 1, 2 * k + 3),
            ]
        };
        let graphs: Vec<Vec<(usize, usize)>> = vec![
            chain.clone(),
            chain.iter().rev().map(|&(a, b)| (b, a)).collect(),
            scrambled,
            (1..60).map(|k| (pick(k), k)).collect(),
            (1..40).map(|k| (0, k)).collect(),
            (0..30).flat_map(rung).collect(),
        ];
        for (case, edges) in graphs.iter().enumerate() {
            let mut rng = Rng::new(case as u64);
            let (bodies, constraints) = rods(n, edges, &mut rng);
            let mut blocks = JointBlocks::new(&constraints, &bodies);
            assert!(blocks.groups.iter().all(Group::direct), "case {case}");
            let mut solver: Vec<SolverBody> = bodies.iter().map(SolverBody::new).collect();
            let mut held = HeldSides::default();
            for _pass in 0..2 {
                for s in solver.iter_mut().filter(|s| !s.is_static()) {
                    s.linear_velocity = random_vector(&mut rng, 3.0);
                    s.angular_velocity = random_vector(&mut rng, 2.0);
                }
                blocks.solve_velocities((&bodies, &mut solver), &mut held, 50.0, None);
                assert_rods_hold(case, &constraints, &bodies, &solver);
            }
        }
    }

    /// Every rod's ends move apart at zero rate.
    fn assert_rods_hold(
        case: usize,
        constraints: &[DistanceConstraint],
        bodies: &[RigidBody],
        solver: &[SolverBody],
    ) {
        for c in constraints.iter().filter(|c| c.is_upper) {
            let (p1, p2) = c.points(bodies);
            let (b1, b2) = (&solver[c.body1], &solver[c.body2]);
            let rate = (p2 - p1).normalize().dot(
                b2.point_velocity(p2 - bodies[c.body2].position)
                    - b1.point_velocity(p1 - bodies[c.body1].position),
            );
            let rod = (c.body1, c.body2);
            assert!(
                rate.abs() < 1e-9,
                "case {case}: rod {rod:?} stretches at {rate}"
            );
        }
    }
}
