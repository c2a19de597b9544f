//! The restitution pass, once after the substeps: every point that touched this step after an
//! approach faster than the threshold leaves with the normal velocity that carries `e^2` of its
//! impact energy ([`bounce_velocity`]), iterated so that points touching together bounce
//! together; then a cap that keeps it from adding energy.
//!
//! Per-point targets are exact for one point and for points that touch at once, but when a
//! body lands on one corner and the turn it takes slams another corner down within the same
//! step, both corners' approaches count the same energy: bouncing both would create energy.
//! So per group of touching bodies the restitution impulses are scaled back, if needed, until
//! the group ends the step with no more energy than it began with.

use super::constraint_graph::Colours;
use super::contact_solver::{
    ContactConstraint, ContactPoint, bounce_velocity, for_each_contact_in,
};
use super::manifold::{GROUND, Manifold};
use super::solver_body::SolverBody;
use crate::sim::body::RigidBody;
use glam::DVec3;
use rayon::prelude::*;

/// Gauss-Seidel passes of the restitution targets.
pub const ITERATIONS: usize = 8;

/// Drives every bouncing point's normal velocity to its target ([`ITERATIONS`] passes over the
/// manifolds that have one: in a pile at rest, none), colour by colour like the other passes;
/// `restitution` applies to impacts faster than `threshold`. Returns the indices of those
/// manifolds' constraints.
pub fn apply(
    colours: &Colours,
    (constraints, points): (&mut [ContactConstraint], &mut [ContactPoint]),
    bodies: &mut [SolverBody],
    (restitution, threshold): (f64, f64),
) -> Vec<u32> {
    let bounces = |p: &ContactPoint| {
        restitution > 0.0
            && p.impact_energy > 0.5 * threshold * threshold
            && p.max_normal_impulse != 0.0
    };
    let view = (&*constraints, &*points);
    let bouncing: Vec<u32> = (0..constraints.len())
        .into_par_iter()
        .with_min_len(1024)
        .filter(|&k| {
            let c = &view.0[k];
            view.1[c.points()].iter().any(bounces)
        })
        .map(|k| k as u32)
        .collect();
    if bouncing.is_empty() {
        return bouncing;
    }
    for _ in 0..ITERATIONS {
        let (selected, contacts) = (Some(&bouncing[..]), (&mut *constraints, &mut *points));
        for_each_contact_in(colours, selected, contacts, bodies, |c, points, b1, b2| {
            let n = c.normal;
            for p in points.iter_mut().filter(|p| bounces(p)) {
                let moved = b2.point_displacement(p.r2) - b1.point_displacement(p.r1);
                let s = p.separation + n.dot(moved);
                let target =
                    bounce_velocity(p.impact_energy, restitution, s, c.normal_acceleration);
                let row = p.along_normal(n);
                let vn = row.velocity(n, b1, b2);
                let impulse = -p.normal_mass * (vn - target);
                // The restitution impulse may take back what it gave but never pull.
                let added = (p.normal_impulse + p.restitution_impulse + impulse).max(0.0)
                    - p.normal_impulse;
                let delta = added - p.restitution_impulse;
                p.restitution_impulse = added;
                row.apply(n, delta, b1, b2);
            }
        });
    }
    bouncing
}

/// Kinetic plus gravitational potential energy of a body with velocities `v`, `w`.
pub fn energy(body: &RigidBody, v: DVec3, w: DVec3, gravity: DVec3) -> f64 {
    0.5 * body.mass * v.length_squared() + 0.5 * w.dot(body.world_inertia() * w)
        - body.mass * gravity.dot(body.position)
}

/// This step's manifolds with their constraints and points.
#[derive(Clone, Copy)]
pub struct Contacts<'a> {
    pub manifolds: &'a [Manifold],
    pub constraints: &'a [ContactConstraint],
    pub points: &'a [ContactPoint],
    /// The constraints with a bouncing point ([`apply`]): the only ones with restitution
    /// impulses.
    pub bouncing: &'a [u32],
}

/// How much energy the restitution of one group of bodies may leave it with.
pub struct EnergyRule {
    pub restitution: f64,
    pub friction: f64,
    pub gravity: DVec3,
}

/// Settles each group's restitution (velocities between `before`, each body's (linear,
/// angular) velocity before the restitution pass, and the current ones, scaled by a share
/// `alpha`) on an energy consistent with the bounce: no group of bodies touching
/// through bouncing points ends the step with more energy than `start` (each body's energy
/// when the step began). Without friction, where nothing but the impacts takes energy, the
/// group keeps exactly `e^2` of what the impacts took (Poisson's hypothesis is
/// energy-consistent for frictionless contacts; targets set point by point can fall short of
/// it when a body's points disagree, as on a tilted landing): `alpha` may then exceed 1, up to
/// [`MAX_SHARE`].
pub fn settle_energy(
    contacts: &Contacts,
    poses: &[RigidBody],
    before: &[(DVec3, DVec3)],
    bodies: &mut [SolverBody],
    start: &[f64],
    rule: &EnergyRule,
) {
    let groups = bouncing_groups(contacts, poses);
    let view = &*bodies;
    // Most steps have a few small groups: on one thread then.
    let shares: Vec<f64> = groups
        .par_iter()
        .with_min_len(16)
        .map(|members| group_share(members, (poses, before, view), start, rule))
        .collect();
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

/// The share of restitution one group of bodies keeps (see [`settle_energy`]).
fn group_share(
    members: &[usize],
    (poses, before, bodies): (&[RigidBody], &[(DVec3, DVec3)], &[SolverBody]),
    start: &[f64],
    rule: &EnergyRule,
) -> f64 {
    // Energy as a function of the share alpha of restitution kept: a + b alpha + c alpha^2.
    let (mut a, mut b, mut c, mut initial) = (0.0, 0.0, 0.0, 0.0);
    for &i in members {
        let (body, (v0, w0)) = (&poses[i], before[i]);
        let (dv, dw) = (
            bodies[i].linear_velocity - v0,
            bodies[i].angular_velocity - w0,
        );
        let inertia = body.world_inertia();
        a += energy(body, v0, w0, rule.gravity);
        b += body.mass * v0.dot(dv) + w0.dot(inertia * dw);
        c += 0.5 * body.mass * dv.length_squared() + 0.5 * dw.dot(inertia * dw);
        initial += start[i];
    }
    let slack = 1e-12 * initial.abs().max(1.0);
    let target = if rule.friction == 0.0 {
        a + rule.restitution * rule.restitution * (initial - a)
    } else {
        (a + b + c).min(initial)
    };
    share_for(a, b, c, target.min(initial) + slack)
}

/// Most the restitution impulses may be stretched to reach the energy of the bounce.
pub const MAX_SHARE: f64 = 2.0;

/// The share `alpha` in [0, MAX_SHARE] whose energy `a + b alpha + c alpha^2` (`c >= 0`)
/// comes closest to `target` from below, preferring 1 when it is within reach.
fn share_for(a: f64, b: f64, c: f64, target: f64) -> f64 {
    let at = |x: f64| a + b * x + c * x * x;
    if a > target {
        return 0.0;
    }
    // The upper root of c x^2 + b x + (a - target) = 0 (a <= target, so it is >= 0).
    let root = if c > 0.0 {
        let discriminant = (b * b - 4.0 * c * (a - target)).max(0.0);
        (-b + discriminant.sqrt()) / (2.0 * c)
    } else if b > 0.0 {
        (target - a) / b
    } else {
        return 1.0;
    };
    if (at(1.0) - target).abs() <= 1e-12 * target.abs().max(1.0) {
        return 1.0;
    }
    root.clamp(0.0, MAX_SHARE)
}

/// Dynamic bodies joined by manifolds with a bounce this step (union-find), as lists.
fn bouncing_groups(contacts: &Contacts, poses: &[RigidBody]) -> Vec<Vec<usize>> {
    let Contacts {
        manifolds,
        constraints,
        points,
        bouncing,
    } = *contacts;
    let bounced: Vec<u32> = (bouncing.iter().copied())
        .filter(|&k| {
            let c = &constraints[k as usize];
            points[c.points()]
                .iter()
                .any(|p| p.restitution_impulse != 0.0)
        })
        .collect();
    // Most steps nothing bounces: no O(n) scratch then.
    if bounced.is_empty() {
        return Vec::new();
    }
    let n = poses.len();
    let dynamic = |i: usize| i != GROUND && poses[i].is_awake();
    let mut parent: Vec<usize> = (0..n).collect();
    let mut bouncing_body = vec![false; n];
    let find = |parent: &mut Vec<usize>, mut x: usize| {
        while parent[x] != x {
            parent[x] = parent[parent[x]];
            x = parent[x];
        }
        x
    };
    for &k in &bounced {
        let m = &manifolds[k as usize];
        let (i, j) = (m.body1, m.body2);
        for k in [i, j] {
            if dynamic(k) {
                bouncing_body[k] = true;
            }
        }
        if dynamic(i) && dynamic(j) {
            let (a, b) = (find(&mut parent, i), find(&mut parent, j));
            parent[a.max(b)] = a.min(b);
        }
    }
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut slot = vec![usize::MAX; n];
    for i in (0..n).filter(|&i| bouncing_body[i]) {
        let root = find(&mut parent, i);
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
    use super::share_for;

    #[test]
    fn share_meets_the_target() {
        let at = |x: f64| 1.0 + 2.0 * x + 3.0 * x * x;
        for target in [3.0, 6.0, 10.0] {
            let x = share_for(1.0, 2.0, 3.0, target);
            assert!((at(x) - target).abs() < 1e-12, "{target}: {x}");
        }
        assert_eq!(share_for(6.0, 1.0, 1.0, 5.0), 0.0);
        // Out of reach: stretched at most to MAX_SHARE.
        assert_eq!(share_for(1.0, 1.0, 1.0, 1e9), super::MAX_SHARE);
    }
}
