//! The restitution pass, once after the substeps: every point that touched this step after an
//! approach of its own faster than the threshold leaves with the normal velocity that carries
//! `e^2` of its impact energy ([`bounce_velocity`]), iterated so that points touching together
//! bounce together, while the points that hold the struck bodies up push back as supports and
//! the distance constraints are held rigid; then a cap that keeps it from adding energy.
//!
//! Per-point targets are exact for one point and for points that touch at once, but when a
//! body lands on one corner and the turn it takes slams another corner down within the same
//! step, both corners' approaches count the same energy: bouncing both would create energy.
//! So per group of bodies joined by the manifolds the pass solved (bounces and supports) the
//! restitution impulses are scaled back, if needed, until the group ends the step with no
//! more energy than it began with; and again over each group with the bodies it pushed or
//! pulled in the step, which may hold energy the bouncing bodies handed them.

use super::constraint_graph::Colours;
use super::contact_solver::{
    ContactConstraint, ContactPoint, Direction, bounce_velocity, coupling, for_each_contact_from,
    impact_energy, separation_now,
};
use super::disjoint_sets::DisjointSets;
use super::manifold::MAX_POINTS;
use super::normal_block;
use super::solver_body::SolverBody;
use crate::sim::body::RigidBody;
use crate::sim::constraint::DistanceConstraint;
use crate::sim::parallel;
use glam::DVec3;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

/// Most Gauss-Seidel passes of the restitution targets (see [`CONVERGED`]).
pub const ITERATIONS: usize = 16;
/// A group of the restitution pass is done once no point's normal velocity changed in a pass
/// by more than the larger of this share of the group's fastest bounce and [`SETTLED`] of the
/// slowest approach that bounces.
const CONVERGED: f64 = 1e-3;
/// See [`CONVERGED`]: the share of the slowest approach that bounces (the threshold, or
/// gravity's kick over a substep) a point's normal velocity may still change by in a pass.
const SETTLED: f64 = 1e-2;
/// Passes of the restitution over fewer manifolds than this run on one thread: a manifold's
/// share of a pass is a few of its points, less than the barriers between colours cost.
const PARALLEL_RESTITUTION: usize = 2048;

/// What makes a point bounce: the coefficient of restitution, the threshold speed, and gravity's
/// kick over one substep (see [`resting_speed`]).
#[derive(Clone, Copy)]
pub struct BounceRule {
    pub restitution: f64,
    pub threshold: f64,
    pub kick: DVec3,
}

/// The points that bounce this step and the manifolds that hold them.
pub struct Bounces {
    /// Manifolds (constraint indices, ascending) with a bouncing point.
    pub manifolds: Vec<u32>,
    /// Whether each point of the step bounces (empty when none does).
    pub points: Vec<bool>,
    /// The slowest approach that bounces: the threshold, or gravity's kick over a substep.
    pub slowest: f64,
}

/// The points among the `selected` constraints (ascending) or all that bounce: each that
/// touched this step after an approach faster than the rule's threshold and than gravity's
/// kick adds to a resting contact's ([`resting_speed`]), and that was approaching that fast by
/// itself when the step began: its [`impact_energy`] at the velocities of then (`start`, each
/// moving solver body's; a static one keeps its own). A point struck through its body (a box
/// resting on the ground under one that lands on it, driven into the ground in the substeps)
/// is not a bounce but a support of the bounce above ([`apply`]).
pub fn bouncing_points(
    selected: Option<&[u32]>,
    (constraints, points): (&[ContactConstraint], &[ContactPoint]),
    (bodies, start): (&[SolverBody], &[(DVec3, DVec3)]),
    rule: BounceRule,
) -> Bounces {
    let at_start = |k: usize| {
        let b = &bodies[k];
        let now = (b.linear_velocity, b.angular_velocity);
        let (linear_velocity, angular_velocity) = match b.inverse_mass == 0.0 {
            true => now,
            false => start.get(k).copied().unwrap_or(now),
        };
        SolverBody {
            linear_velocity,
            angular_velocity,
            ..*b
        }
    };
    let bounces = |c: &ContactConstraint, p: &ContactPoint| {
        let speed = resting_speed(c, rule.threshold, rule.kick);
        let least = 0.5 * speed * speed;
        // (A point moving apart when the step began is not a bounce of its own: it could come
        // back within the step only at up to gravity's kick over the step, and is taken for
        // one held up by its support.)
        let own = || {
            let (n, (i, j)) = (c.normal, c.bodies());
            let approach = p.along_normal(n).velocity(n, &at_start(i), &at_start(j));
            approach <= 0.0 && impact_energy(p.separation, approach, c.normal_acceleration) > least
        };
        rule.restitution > 0.0 && p.impact_energy > least && p.max_normal_impulse != 0.0 && own()
    };
    // A manifold with a bouncing point, and which of its points bounce (a bit each).
    let bounced = |k: u32| {
        let c = &constraints[k as usize];
        let mask = (points[c.points()].iter().enumerate())
            .filter(|(_, p)| bounces(c, p))
            .fold(0u32, |mask, (i, _)| mask | 1 << i);
        (mask != 0).then_some((k, mask))
    };
    let found = filter_selected(selected, constraints.len(), bounced);
    let mut flags = Vec::new();
    if !found.is_empty() {
        flags.resize(points.len(), false);
        for &(k, mask) in &found {
            let range = constraints[k as usize].points();
            for (i, flag) in flags[range].iter_mut().enumerate() {
                *flag = mask & 1 << i != 0;
            }
        }
    }
    Bounces {
        manifolds: found.into_iter().map(|(k, _)| k).collect(),
        points: flags,
        slowest: rule.threshold.max(rule.kick.length()),
    }
}

/// Drives every bouncing point's normal velocity to its target (at most [`ITERATIONS`] passes
/// over the manifolds that have one: in a pile at rest, none), colour by colour like the other
/// passes, among the `selected` constraints (ascending) or all, at `restitution`. The points
/// that hold the struck bodies up take part as supports ([`with_supports`]), and after each
/// pass `hold_joints` makes the rates of the distance constraints on the struck bodies
/// (flagged by solver body) rigid again, so that what a bounce drives into a support or pulls
/// on a rod comes back as bounce. With `jointed` (distance constraints in the scene) all the
/// manifolds are passed over until all settle, as the joints join them. Returns the indices of
/// the manifolds the pass solved (the bouncing ones and their supports), ascending.
pub fn apply(
    (colours, selected): (&Colours, Option<&[u32]>),
    (constraints, points): (&mut [ContactConstraint], &mut [ContactPoint]),
    bodies: &mut [SolverBody],
    (bounces, restitution, jointed): (&Bounces, f64, bool),
    mut hold_joints: impl FnMut(&mut [SolverBody], &[bool]),
) -> Vec<u32> {
    if bounces.manifolds.is_empty() {
        return Vec::new();
    }
    let (solved, struck) =
        with_supports(&bounces.manifolds, selected, (constraints, points), bodies);
    // Each group of manifolds (joined by moving bodies) is passed over until the largest change
    // a pass makes to one of its points' normal velocities is small against its fastest bounce
    // (a stack's supports pass a bounce on one level a pass or so): alone, not until every group
    // has, so that a batch of islands and the colours' pass over all of them give the same bits.
    let group = match jointed {
        true => vec![0; solved.len()],
        false => pass_groups(&solved, constraints, bodies),
    };
    let starts: Vec<usize> = (solved.iter())
        .map(|&k| constraints[k as usize].points().start)
        .collect();
    let settled = settled_speeds(
        bounces,
        (&solved, &group),
        (constraints, points),
        restitution,
    );
    let mut active = vec![true; solved.len()];
    // Each group's largest change in the pass, taken (and zeroed) after it.
    let largest: Vec<AtomicU64> = (0..solved.len()).map(|_| AtomicU64::new(0)).collect();
    for _ in 0..ITERATIONS {
        let (selected, contacts) = (Some(&solved[..]), (&mut *constraints, &mut *points));
        let selected = (selected, Some(PARALLEL_RESTITUTION));
        for_each_contact_from(colours, selected, contacts, bodies, |c, points, b1, b2| {
            let g = group[starts.partition_point(|&s| s < c.points().start)];
            if !active[g] {
                return;
            }
            let flags = &bounces.points[c.points()];
            let change = restitute_manifold(c, (points, flags), restitution, (b1, b2));
            // Non-negative numbers order as their bits. Written only when larger, so that the
            // threads do not trade the line at every manifold.
            if change.to_bits() > largest[g].load(Ordering::Relaxed) {
                largest[g].fetch_max(change.to_bits(), Ordering::Relaxed);
            }
        });
        hold_joints(bodies, &struck);
        for (g, largest) in largest.iter().enumerate() {
            active[g] &= f64::from_bits(largest.swap(0, Ordering::Relaxed)) > settled[g];
        }
        if !active.contains(&true) {
            break;
        }
    }
    solved
}

/// One manifold's update in a pass of [`apply`]: its points that bounce or support solved
/// together ([`normal_block`]) where there are two or more, so that the pass does not depend on
/// the points' order; point after point ([`restitute`]) where there is one, or the block cannot
/// be solved. Point after point, the first of four equally deep points took more than its share
/// and a box dropped flat onto a stack of two left turning at 2 degrees a second (40 degrees
/// within 5 s of bounces at e = 1). Returns the largest change a point's impulse made to its own
/// normal velocity.
fn restitute_manifold(
    c: &ContactConstraint,
    (points, bounces): (&mut [ContactPoint], &[bool]),
    restitution: f64,
    (b1, b2): (&mut SolverBody, &mut SolverBody),
) -> f64 {
    let mut rows = [0usize; MAX_POINTS];
    let mut count = 0;
    for (k, (p, &bounce)) in points.iter().zip(bounces).enumerate() {
        if bounce || p.max_normal_impulse != 0.0 {
            rows[count] = k;
            count += 1;
        }
    }
    let rule = (bounces, restitution);
    let solved = match count {
        2 => restitute_block::<2>(c, points, (&rows, rule), (b1, b2)),
        3 => restitute_block::<3>(c, points, (&rows, rule), (b1, b2)),
        4 => restitute_block::<4>(c, points, (&rows, rule), (b1, b2)),
        _ => None,
    };
    solved.unwrap_or_else(|| {
        let mut change: f64 = 0.0;
        for (p, &bounce) in points.iter_mut().zip(bounces) {
            change = change.max(restitute(c, p, (bounce, restitution), (b1, b2)));
        }
        change
    })
}

/// The restitution impulses of a manifold's `N` points at `rows` solved together, as the linear
/// complementarity problem the point-by-point passes converge to: each point's impulse
/// `r_i >= lo_i` (a bouncing point may take back what it held but never pull, `lo_i` = minus
/// its normal impulse; a support adds, `lo_i = 0`) and its normal velocity `v_i >= t_i` (its
/// bounce velocity, or 0 for a support), one of the two at its bound. With `x = r - lo`:
/// `x >= 0`, `w = K x + q >= 0`, `x_i w_i = 0`, `q = v - t + K (lo - r_held)`; the rows given
/// [`normal_block::COMPLIANCE`] so that a flat face's `K` is definite. None where the block
/// cannot be solved (nothing applied then); else the largest change a point's impulse made to
/// its own normal velocity, as [`restitute`] measures it.
#[inline(always)]
fn restitute_block<const N: usize>(
    c: &ContactConstraint,
    points: &mut [ContactPoint],
    (rows, (bounces, restitution)): (&[usize; MAX_POINTS], (&[bool], f64)),
    (b1, b2): (&mut SolverBody, &mut SolverBody),
) -> Option<f64> {
    let n = c.normal;
    let directions: [Direction; N] = std::array::from_fn(|i| points[rows[i]].along_normal(n));
    let held: [f64; N] = std::array::from_fn(|i| points[rows[i]].restitution_impulse);
    let lower: [f64; N] = std::array::from_fn(|i| match bounces[rows[i]] {
        true => -points[rows[i]].normal_impulse,
        false => 0.0,
    });
    let target: [f64; N] = std::array::from_fn(|i| {
        let p = &points[rows[i]];
        match bounces[rows[i]] {
            true => {
                let s = separation_now(p, n, b1, b2);
                bounce_velocity(p.impact_energy, restitution, s, c.normal_acceleration)
            }
            false => 0.0,
        }
    });
    let mut a = coupling(&directions, (b1, b2));
    let q: [f64; N] = std::array::from_fn(|i| {
        let v = directions[i].velocity(n, b1, b2);
        v - target[i] + (0..N).map(|j| a[i][j] * (lower[j] - held[j])).sum::<f64>()
    });
    for (i, row) in a.iter_mut().enumerate() {
        row[i] += normal_block::COMPLIANCE * row[i];
    }
    let start: [f64; N] = std::array::from_fn(|i| held[i] - lower[i]);
    let x = normal_block::solve(&a, &q, &start)?;
    let mut change: f64 = 0.0;
    for i in 0..N {
        let p = &mut points[rows[i]];
        let taken = take_restitution(p, (&directions[i], n), x[i] + lower[i], (b1, b2));
        change = change.max(taken);
    }
    Some(change)
}

/// One point's update in a pass of [`apply`]: a bouncing point driven to its bounce at
/// `restitution`, one that touched without bouncing a support (it only pushes back what the
/// bounces drive into it). Returns the change of its normal velocity (non-negative).
#[inline(always)]
fn restitute(
    c: &ContactConstraint,
    p: &mut ContactPoint,
    (bounce, restitution): (bool, f64),
    (b1, b2): (&mut SolverBody, &mut SolverBody),
) -> f64 {
    if !bounce && p.max_normal_impulse == 0.0 {
        return 0.0;
    }
    let n = c.normal;
    let row = p.along_normal(n);
    let vn = row.velocity(n, b1, b2);
    let added = match bounce {
        true => {
            let s = separation_now(p, n, b1, b2);
            let a = c.normal_acceleration;
            let target = bounce_velocity(p.impact_energy, restitution, s, a);
            let impulse = -p.normal_mass * (vn - target);
            // May take back what it gave but never pull.
            (p.normal_impulse + p.restitution_impulse + impulse).max(0.0) - p.normal_impulse
        }
        // Adds to what it held, takes nothing back.
        false => (p.restitution_impulse - p.normal_mass * vn).max(0.0),
    };
    take_restitution(p, (&row, n), added, (b1, b2))
}

/// Point `p` (its normal row `row` along `n`) takes the restitution impulse `impulse`: the
/// change is applied, and the change it makes to the point's own normal velocity returned
/// (`|delta| K_ii`, a pass's measure of progress).
#[inline(always)]
fn take_restitution(
    p: &mut ContactPoint,
    (row, n): (&Direction, DVec3),
    impulse: f64,
    (b1, b2): (&mut SolverBody, &mut SolverBody),
) -> f64 {
    let delta = impulse - p.restitution_impulse;
    p.restitution_impulse = impulse;
    row.apply(n, delta, b1, b2);
    match p.normal_mass > 0.0 {
        true => (delta / p.normal_mass).abs(),
        false => 0.0,
    }
}

/// Each solved manifold's group (at the place among `solved` of its group's first manifold):
/// the manifolds joined through the moving bodies they share.
fn pass_groups(
    solved: &[u32],
    constraints: &[ContactConstraint],
    bodies: &[SolverBody],
) -> Vec<usize> {
    let mut ends: Vec<(usize, usize)> = (solved.iter().enumerate())
        .flat_map(|(m, &k)| {
            let (i, j) = constraints[k as usize].bodies();
            [(i, m), (j, m)]
        })
        .filter(|&(b, _)| bodies[b].inverse_mass != 0.0)
        .collect();
    ends.sort_unstable();
    let mut sets = DisjointSets::new(solved.len());
    for pair in ends.windows(2).filter(|pair| pair[0].0 == pair[1].0) {
        sets.join(pair[0].1, pair[1].1);
    }
    (0..solved.len()).map(|m| sets.root(m)).collect()
}

/// Per group (by its place, see [`pass_groups`]): the change of a point's normal velocity in a
/// pass below which the group is done, [`CONVERGED`] of its fastest bounce (the normal speed a
/// bouncing point leaves with) or [`SETTLED`] of the slowest approach that bounces.
fn settled_speeds(
    bounces: &Bounces,
    (solved, group): (&[u32], &[usize]),
    (constraints, points): (&[ContactConstraint], &[ContactPoint]),
    restitution: f64,
) -> Vec<f64> {
    let mut settled = vec![SETTLED * bounces.slowest; solved.len()];
    for (&k, &g) in solved.iter().zip(group) {
        let c = &constraints[k as usize];
        let flags = &bounces.points[c.points()];
        for (p, _) in (points[c.points()].iter().zip(flags)).filter(|(_, bounce)| **bounce) {
            let speed = restitution * (2.0 * p.impact_energy).sqrt();
            settled[g] = settled[g].max(CONVERGED * speed);
        }
    }
    settled
}

/// The `bouncing` manifolds (ascending) and their supports: every manifold with a point that
/// touched this step (held a normal impulse) and a body that a bouncing or, up to
/// [`SUPPORT_HOPS`] manifolds away, a supporting manifold moves, among the `selected`
/// (ascending) or all; and which solver bodies those manifolds move (the struck). Without them
/// a bounce drove the body it struck into what holds that body up: a box dropped 24 units at
/// e = 1 onto one resting on the ground went back up to 0.91 of its drop and threw the lower
/// box 2.1 units up (a rigid support: 1 and 0); onto a stack of two, 0.86, the middle box
/// thrown 2.9 up.
fn with_supports(
    bouncing: &[u32],
    selected: Option<&[u32]>,
    (constraints, points): (&[ContactConstraint], &[ContactPoint]),
    bodies: &[SolverBody],
) -> (Vec<u32>, Vec<bool>) {
    // The manifolds that touched, and their bodies: read once, then walked hop by hop.
    let touched = |k: u32| {
        let c = &constraints[k as usize];
        let (i, j) = c.bodies();
        let touched = points[c.points()]
            .iter()
            .any(|p| p.max_normal_impulse != 0.0);
        touched.then_some((k, i as u32, j as u32))
    };
    let touched = filter_selected(selected, constraints.len(), touched);
    let strike = |struck: &mut [bool], (i, j): (usize, usize)| {
        for b in [i, j] {
            struck[b] |= bodies[b].inverse_mass != 0.0;
        }
    };
    let mut struck = vec![false; bodies.len()];
    for &k in bouncing {
        strike(&mut struck, constraints[k as usize].bodies());
    }
    let mut solved = bouncing.to_vec();
    for _ in 0..SUPPORT_HOPS {
        // Ascending as `touched` is; a bouncing manifold touched, so it is among them.
        let reached = |&&(_, i, j): &&(u32, u32, u32)| struck[i as usize] || struck[j as usize];
        let found: Vec<&(u32, u32, u32)> = touched.iter().filter(reached).collect();
        if found.len() == solved.len() {
            break;
        }
        for &&(_, i, j) in &found {
            strike(&mut struck, (i as usize, j as usize));
        }
        solved = found.into_iter().map(|t| t.0).collect();
    }
    (solved, struck)
}

/// The values `f(k)` gives for the constraint indices `k` among the `selected` (ascending) or
/// all `count`, in order.
fn filter_selected<T: Send>(
    selected: Option<&[u32]>,
    count: usize,
    f: impl Fn(u32) -> Option<T> + Sync + Send,
) -> Vec<T> {
    match selected {
        Some(selected) => parallel::filter_map(selected.par_iter(), 1024, |&k| f(k)),
        None => parallel::filter_map((0..count as u32).into_par_iter(), 1024, f),
    }
}

/// How many manifolds away from a bounce supports are looked for: a stack of three under the
/// struck box. Further down a pass passes on little of the bounce.
const SUPPORT_HOPS: usize = 3;

/// The approach speed below which a point of `c` does not bounce: the `threshold`, or the
/// speed gravity's `kick` over one substep has along its normal where that is more. A body
/// resting on the ground, or on a body the ground holds, is driven into its support by that
/// much every substep; bounced back at e = 1 with no threshold, a box on a slope hopped in
/// place and slid as if friction barely held (at 30 degrees with mu = 0.5, 2.63 units/s^2
/// where g (sin a - mu cos a) is 0.66). Gravity's, not the pair's relative acceleration: two
/// bodies of a stack fall alike, but the lower one is held. Under the preset (a threshold of
/// 0.5, substeps of at most 1/200 s) the threshold is the larger.
fn resting_speed(c: &ContactConstraint, threshold: f64, kick: DVec3) -> f64 {
    threshold.max(kick.dot(c.normal).abs())
}

/// Kinetic plus gravitational potential energy of a body with velocities `v`, `w`.
pub fn energy(body: &RigidBody, v: DVec3, w: DVec3, gravity: DVec3) -> f64 {
    0.5 * body.mass * v.length_squared() + 0.5 * w.dot(body.world_inertia() * w)
        - body.mass * gravity.dot(body.position)
}

/// This step's contact constraints and points (the step's, or a batch's of small islands in
/// its own indices: see [`is_member`]).
#[derive(Clone, Copy)]
pub struct Contacts<'a> {
    pub constraints: &'a [ContactConstraint],
    /// The constraints to look at (ascending), or all: the others' bodies are settled
    /// elsewhere (in their batches).
    pub selected: Option<&'a [u32]>,
    pub points: &'a [ContactPoint],
    /// The constraints the restitution pass solved ([`apply`]): those with a bouncing point and
    /// their supports, the only ones with restitution impulses.
    pub solved: &'a [u32],
    /// The world's distance constraints, whichever solver holds them (a direct group or the
    /// Gauss-Seidel rows): energy passes through them as through contacts.
    pub joints: &'a [DistanceConstraint],
}

/// How much energy the restitution of one group of bodies may leave it with.
pub struct EnergyRule {
    pub restitution: f64,
    pub friction: f64,
    pub gravity: DVec3,
}

impl EnergyRule {
    pub fn of(settings: &crate::sim::Settings) -> Self {
        Self {
            restitution: settings.restitution,
            friction: settings.friction,
            gravity: settings.gravity,
        }
    }
}

/// Settles each group's restitution (velocities between `before`, each body's (linear,
/// angular) velocity before the restitution pass, and the current ones, scaled by a share
/// `alpha`) on an energy consistent with the bounce: no group of bodies touching through the
/// points the pass solved (bounces and their supports) ends the step with more energy than
/// `start` (each body's energy when the step began). Without friction, where nothing but the
/// impacts takes energy, the group keeps exactly `e^2` of what the impacts took (Poisson's
/// hypothesis is energy-consistent for frictionless contacts; targets set point by point can
/// fall short of it when a body's points disagree, as on a tilted landing): `alpha` may then
/// exceed 1, up to [`MAX_SHARE`], unless a body of the group is held by a distance constraint.
/// The rods pass on part of what an impact takes to bodies outside the group, which the
/// stretched impulses then gave back as bounce: until stop 54, random scenes of jointed boxes
/// at e = 1 without friction gained up to 154 times their energy in 10 s (tested).
///
/// Then the same cap, scaling down only, over each such group with the bodies its bouncing
/// bodies pushed or pulled this step or are joined to by a distance constraint
/// ([`joined_groups`]; until stop 54 only by those solved as Gauss-Seidel rows, not by the
/// direct groups): a body that bounces while it pushes a
/// neighbour has handed that neighbour energy in the substeps, which its own account alone
/// would let the bounce give back (a box bouncing at e = 1 while it pushed another gained the
/// mixed scene 1.9e-4 of its energy in one step at dt 0.04; 6.1e-6 with this cap). Only the
/// bodies they touch, not all they reach through others: in a resting pile that is the whole
/// pile, whose energy stays flat from step to step, so every small correction of the
/// restitution pass there read as a gain and was cut, and pile-10000 never fell asleep (64 of
/// 10,000 at 30 s). Settled on the joined groups alone, in one pass, each bounce was weighed
/// against its neighbours' friction losses and piles stayed livelier (13 draws of pile-200 at
/// dt 0.02: one still moving at 15 s).
pub fn settle_energy(
    contacts: &Contacts,
    poses: &[RigidBody],
    before: &[(DVec3, DVec3)],
    bodies: &mut [SolverBody],
    start: &[f64],
    rule: &EnergyRule,
) {
    let groups = bouncing_groups(contacts, poses);
    if groups.is_empty() {
        return;
    }
    // Which bodies a distance constraint holds (none to mark in most scenes).
    let marked = if contacts.joints.is_empty() {
        0
    } else {
        poses.len()
    };
    let mut jointed = vec![false; marked];
    for c in contacts.joints {
        (jointed[c.body1], jointed[c.body2]) = (true, true);
    }
    let bounce = |members: &[usize], terms: EnergyTerms| {
        let max = if members.iter().any(|&i| jointed.get(i) == Some(&true)) {
            1.0
        } else {
            MAX_SHARE
        };
        share_for(terms, bounce_target(&terms, rule), max)
    };
    scale_restitution(
        &groups,
        bounce,
        (poses, before, start),
        rule.gravity,
        bodies,
    );
    let joined = joined_groups(contacts, poses, &groups);
    // Against what the group had before the restitution pass too, where that was more: the
    // cap is on what the bounces add, and the soft contacts may have pushed bodies apart.
    let cap = |_: &[usize], terms: EnergyTerms| {
        let target = terms.initial.max(terms.a) + slack(&terms);
        share_for(terms, target, 1.0)
    };
    scale_restitution(&joined, cap, (poses, before, start), rule.gravity, bodies);
}

/// Scales each group's restitution (its bodies' velocities since `before`) by the share `share`
/// gives for its energy terms.
fn scale_restitution(
    groups: &[Vec<usize>],
    share: impl Fn(&[usize], EnergyTerms) -> f64 + Sync,
    (poses, before, start): (&[RigidBody], &[(DVec3, DVec3)], &[f64]),
    gravity: DVec3,
    bodies: &mut [SolverBody],
) {
    let view = &*bodies;
    // Most steps have a few small groups: on one thread then.
    let mut shares: Vec<f64> = Vec::new();
    parallel::extend_map(&mut shares, groups.par_iter(), 16, |members| {
        share(
            members,
            energy_terms(members, (poses, before, view), start, gravity),
        )
    });
    for (members, alpha) in groups.iter().zip(shares) {
        if alpha == 1.0 {
            continue;
        }
        for &i in members {
            let (v0, w0) = before[i];
            bodies[i].linear_velocity = v0 + alpha * (bodies[i].linear_velocity - v0);
            bodies[i].angular_velocity = w0 + alpha * (bodies[i].angular_velocity - w0);
        }
    }
}

/// A group's energy as a function of the share `alpha` of its restitution kept,
/// `a + b alpha + c alpha^2`, and its energy when the step began.
#[derive(Clone, Copy)]
struct EnergyTerms {
    a: f64,
    b: f64,
    c: f64,
    initial: f64,
}

fn energy_terms(
    members: &[usize],
    (poses, before, bodies): (&[RigidBody], &[(DVec3, DVec3)], &[SolverBody]),
    start: &[f64],
    gravity: DVec3,
) -> EnergyTerms {
    let mut t = EnergyTerms {
        a: 0.0,
        b: 0.0,
        c: 0.0,
        initial: 0.0,
    };
    for &i in members {
        let (body, (v0, w0)) = (&poses[i], before[i]);
        let (dv, dw) = (
            bodies[i].linear_velocity - v0,
            bodies[i].angular_velocity - w0,
        );
        let inertia = body.world_inertia();
        t.a += energy(body, v0, w0, gravity);
        t.b += body.mass * v0.dot(dv) + w0.dot(inertia * dw);
        t.c += 0.5 * body.mass * dv.length_squared() + 0.5 * dw.dot(inertia * dw);
        t.initial += start[i];
    }
    t
}

/// Rounding room above a group's starting energy.
fn slack(t: &EnergyTerms) -> f64 {
    1e-12 * t.initial.abs().max(1.0)
}

/// The energy a group of bouncing bodies ends the step with (see [`settle_energy`]). With
/// friction, which takes an unknown part of what the impacts took, the restitution pass's own
/// result, but never more than `e^2` of the step's whole loss given back (the energetic
/// coefficient, Stronge 1990, gives back `e^2` of the normal impulses' work; friction's loss
/// counts in the whole here, so this is an upper bound). Capped at the step's starting energy
/// alone, as until stop 64, a box dropped 0.6 units onto a resting box at e = 0.5 went back up
/// to 0.8 of its drop where a rigid support gives `e^2 = 0.25`: the box below, driven into the
/// ground in the substeps, bounced too, and both bounces counted the same impact.
fn bounce_target(t: &EnergyTerms, rule: &EnergyRule) -> f64 {
    let e2 = rule.restitution * rule.restitution;
    let target = if rule.friction == 0.0 {
        t.a + e2 * (t.initial - t.a)
    } else {
        // (Written so that at e = 1 the cap is the starting energy, bit for bit.)
        (t.a + t.b + t.c).min(t.initial - (1.0 - e2) * (t.initial - t.a))
    };
    target.min(t.initial) + slack(t)
}

/// Most the restitution impulses may be stretched to reach the energy of the bounce.
pub const MAX_SHARE: f64 = 2.0;

/// The share `alpha` in [0, `max`] whose energy `a + b alpha + c alpha^2` (`c >= 0`) comes
/// closest to `target` from below, preferring 1 when it is within reach; where no share gets
/// down to `target`, the one with the least energy. Until stop 57 a group already above its
/// target before the restitution pass (`a > target`) got share 0, the pass undone, even where
/// the pass had taken energy away (separating faster than the bounce, the soft contacts
/// pushing the bodies out): a stack of three struck at 18 units/s was pushed back out at up to
/// 3.5 units/s, the restitution pass slowed it to 3.3 and that was undone.
fn share_for(terms: EnergyTerms, target: f64, max: f64) -> f64 {
    let EnergyTerms { a, b, c, .. } = terms;
    let at = |x: f64| a + b * x + c * x * x;
    if (at(1.0) - target).abs() <= 1e-12 * target.abs().max(1.0) {
        return 1.0;
    }
    if c > 0.0 {
        // The shares at or below the target lie between the roots of
        // c x^2 + b x + (a - target) = 0 (the energy is convex): the largest of them within
        // [0, max], or the vertex where there is none.
        let discriminant = b * b - 4.0 * c * (a - target);
        let least = (-b / (2.0 * c)).clamp(0.0, max);
        if discriminant < 0.0 {
            return least;
        }
        let root = discriminant.sqrt();
        let (lower, upper) = ((-b - root) / (2.0 * c), (-b + root) / (2.0 * c));
        if upper < 0.0 || lower > max {
            return least;
        }
        upper.clamp(0.0, max)
    } else if b > 0.0 {
        ((target - a) / b).clamp(0.0, max)
    } else {
        1.0
    }
}

/// Which bodies take part: awake dynamic ones. A constraint's ground is the body past the last
/// (the solver bodies' static ground), as a batch's static bodies are past its moving ones.
fn is_member(i: usize, poses: &[RigidBody]) -> bool {
    poses.get(i).is_some_and(RigidBody::is_awake)
}

/// Bodies joined by manifolds with a restitution impulse this step (a bounce, or a support
/// that held a struck body up: the energy it stopped is the bounce's to give back), as lists
/// (union-find).
fn bouncing_groups(contacts: &Contacts, poses: &[RigidBody]) -> Vec<Vec<usize>> {
    let Contacts {
        constraints,
        points,
        solved,
        ..
    } = *contacts;
    let bounced: Vec<u32> = (solved.iter().copied())
        .filter(|&k| {
            let c = &constraints[k as usize];
            points[c.points()]
                .iter()
                .any(|p| p.restitution_impulse != 0.0)
        })
        .collect();
    // Most steps nothing bounces.
    if bounced.is_empty() {
        return Vec::new();
    }
    let links = (bounced.iter()).map(|&k| constraints[k as usize].bodies());
    let seeds: Vec<usize> = (links.clone())
        .flat_map(|(i, j)| [i, j])
        .filter(|&k| is_member(k, poses))
        .collect();
    groups_of(poses, links, &seeds)
}

/// The [`bouncing_groups`] joined with the bodies their bodies touched through manifolds that
/// pushed (a point with a normal impulse this step) or joint rows: those a bounce may have
/// handed energy to.
fn joined_groups(
    contacts: &Contacts,
    poses: &[RigidBody],
    groups: &[Vec<usize>],
) -> Vec<Vec<usize>> {
    let Contacts {
        constraints,
        selected,
        points,
        joints,
        ..
    } = *contacts;
    let seeds: Vec<usize> = groups.iter().flatten().copied().collect();
    let mut is_seed = vec![false; poses.len()];
    for &i in &seeds {
        is_seed[i] = true;
    }
    let touches_seed =
        |(i, j): (usize, usize)| is_seed.get(i) == Some(&true) || is_seed.get(j) == Some(&true);
    let chosen: Box<dyn Iterator<Item = &ContactConstraint>> = match selected {
        Some(selected) => Box::new(selected.iter().map(|&k| &constraints[k as usize])),
        None => Box::new(constraints.iter()),
    };
    // The seed test first: most manifolds of a landing touch no bouncing body.
    let pushed = chosen
        .filter(|c| {
            touches_seed(c.bodies())
                && points[c.points()]
                    .iter()
                    .any(|p| p.max_normal_impulse != 0.0)
        })
        .map(|c| c.bodies());
    let held = (joints.iter())
        .map(|c| (c.body1, c.body2))
        .filter(|&pair| touches_seed(pair));
    groups_of(poses, pushed.chain(held), &seeds)
}

/// The sets of member bodies joined by `links` that hold one of the `seeds` (members only),
/// each listed in ascending order, in the order of their first members. Only the seeds and the
/// linked bodies can be in one, so only those are looked at, by their places among them
/// (sorted): with a scan of every body's state the two groupings took 3.1 ms a step of
/// scatter-100000's landing, and arrays of every body (five for each grouping, 3.6 MB there)
/// another millisecond or more.
fn groups_of(
    poses: &[RigidBody],
    links: impl Iterator<Item = (usize, usize)>,
    seeds: &[usize],
) -> Vec<Vec<usize>> {
    let joins: Vec<(usize, usize)> = links
        .filter(|&(i, j)| is_member(i, poses) && is_member(j, poses))
        .collect();
    // The bodies met, ascending: each group's members in order, the groups by their first.
    let mut met: Vec<usize> = (joins.iter().flat_map(|&(i, j)| [i, j]))
        .chain(seeds.iter().copied())
        .collect();
    met.sort_unstable();
    met.dedup();
    let place = |i: usize| met.partition_point(|&m| m < i);
    let mut sets = DisjointSets::new(met.len());
    for (i, j) in joins {
        sets.join(place(i), place(j));
    }
    let mut seeded = vec![false; met.len()];
    for &i in seeds {
        seeded[sets.root(place(i))] = true;
    }
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut slot = vec![usize::MAX; met.len()];
    for (p, &i) in met.iter().enumerate() {
        let root = sets.root(p);
        if !seeded[root] {
            continue;
        }
        if slot[root] == usize::MAX {
            slot[root] = groups.len();
            groups.push(Vec::new());
        }
        groups[slot[root]].push(i);
    }
    groups
}

#[cfg(test)]
mod tests {
    use super::{EnergyTerms, MAX_SHARE, RigidBody, groups_of, share_for};
    use crate::sim::rng::Rng;
    use glam::{DMat3, DQuat, DVec3};

    /// The groups are the connected components of the links between awake bodies that hold a
    /// seed, by a search of their own: members ascending, groups by their first member.
    #[test]
    fn groups_are_the_components_of_awake_bodies_that_hold_a_seed() {
        let mut rng = Rng::new(11);
        for round in 0..50 {
            let n = 60;
            let body = |_| {
                let unit = DMat3::IDENTITY;
                RigidBody::new(0, 1.0, unit, 1.0, false, DVec3::ZERO, DQuat::IDENTITY)
            };
            let mut poses: Vec<RigidBody> = (0..n).map(body).collect();
            for b in poses.iter_mut() {
                b.asleep = rng.unit() < 0.2;
            }
            let pick = |rng: &mut Rng| (rng.unit() * n as f64) as usize % n;
            let links: Vec<(usize, usize)> =
                (0..40).map(|_| (pick(&mut rng), pick(&mut rng))).collect();
            let seeds: Vec<bool> = (0..n)
                .map(|i| !poses[i].asleep && rng.unit() < 0.1)
                .collect();
            let awake = |i: usize| !poses[i].asleep;
            let mut expected: Vec<Vec<usize>> = Vec::new();
            let mut seen = vec![false; n];
            for start in (0..n).filter(|&i| awake(i)) {
                if seen[start] {
                    continue;
                }
                let (mut component, mut stack) = (Vec::new(), vec![start]);
                seen[start] = true;
                while let Some(i) = stack.pop() {
                    component.push(i);
                    for &(a, b) in links.iter().filter(|&&(a, b)| awake(a) && awake(b)) {
                        for (x, y) in [(a, b), (b, a)] {
                            if x == i && !seen[y] {
                                seen[y] = true;
                                stack.push(y);
                            }
                        }
                    }
                }
                component.sort_unstable();
                if component.iter().any(|&i| seeds[i]) {
                    expected.push(component);
                }
            }
            let listed: Vec<usize> = (0..n).filter(|&i| seeds[i]).collect();
            let found = groups_of(&poses, links.iter().copied(), &listed);
            assert_eq!(found, expected, "round {round}");
        }
    }

    fn terms(a: f64, b: f64, c: f64) -> EnergyTerms {
        EnergyTerms {
            a,
            b,
            c,
            initial: 0.0,
        }
    }

    #[test]
    fn share_meets_the_target() {
        let at = |x: f64| 1.0 + 2.0 * x + 3.0 * x * x;
        for target in [3.0, 6.0, 10.0] {
            let x = share_for(terms(1.0, 2.0, 3.0), target, MAX_SHARE);
            assert!((at(x) - target).abs() < 1e-12, "{target}: {x}");
        }
        // Above the target at every share: the least energy (here none kept).
        assert_eq!(share_for(terms(6.0, 1.0, 1.0), 5.0, MAX_SHARE), 0.0);
        // Above the target before the pass (3), at it after (0): kept, not undone; with a
        // higher target, the largest share that reaches it (2 + sqrt 2), or the limit.
        assert_eq!(share_for(terms(3.0, -4.0, 1.0), 0.0, MAX_SHARE), 1.0);
        let x = share_for(terms(3.0, -4.0, 1.0), 1.0, 5.0);
        assert!((x - (2.0 + 2f64.sqrt())).abs() < 1e-12, "{x}");
        assert_eq!(share_for(terms(3.0, -4.0, 1.0), 1.0, MAX_SHARE), MAX_SHARE);
        // Out of reach from above: the least energy, at the vertex.
        assert_eq!(share_for(terms(3.0, -4.0, 1.0), -2.0, MAX_SHARE), 2.0);
        assert_eq!(share_for(terms(3.0, -4.0, 1.0), -2.0, 1.0), 1.0);
        // Out of reach: stretched at most to the limit.
        assert_eq!(share_for(terms(1.0, 1.0, 1.0), 1e9, MAX_SHARE), MAX_SHARE);
        assert_eq!(share_for(terms(1.0, 1.0, 1.0), 1e9, 1.0), 1.0);
    }
}
