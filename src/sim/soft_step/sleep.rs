//! Sleeping: an island (bodies joined by touching contacts and distance constraints) whose
//! kinetic energy stays under that of its mass moving at [`SLEEP_SPEED`], none of its bodies
//! faster than [`SLEEP_SPEED_CAP`], for [`TIME_TO_SLEEP`] goes to sleep and costs nothing until
//! something wakes it: contact with a moving body, a constraint to one, a grab, or a change of
//! settings. A body's speed counts its spin at its rim and is weighed by
//! [`POSITION_SLEEP_FACTOR`]. A time window, not an instantaneous speed: a pendulum at its apex
//! is still for an instant only; and a body held by constraints alone rests only while its
//! velocity stays within the sleep speed of what it was when its rest began, any body in an
//! island of a few within [`REST_VELOCITY_CHANGE`] (a pendulum of 100 units swinging by 2 is
//! slower than the sleep speed for a second round each apex, and slept there, off centre, for
//! ever; a box starting to slide down a slope too steep for its friction slept at 0.5 s; see
//! [`FEW_BODIES`]). An island that touches neither the ground nor a fixed or sleeping body, and
//! hangs from no fixed body, is in free flight and never sleeps, however weak the gravity; where
//! there is none, it sleeps only while it is still ([`STILL_SPEED`]): a body at rest stays where
//! it is, and its sleep changes nothing, but one drifting keeps its momentum. The
//! island's energy, not each body's speed as in Box2D: in a pile of ten thousand one body
//! rocking at 0.1 units/s in a contact's limit cycle kept every other awake (pile-10000 at dt
//! 0.02 and restitution 0.15, 0.2 and 0.25 was asleep by 20 s, by 20 s and not within 30 s; on
//! the island's energy at 13, 16 and 13 s).
//!
//! The speed is that of the step's displacement, as Rapier measures it, not of the velocities
//! kept: those carry what the last Gauss-Seidel pass left unconverged in a deep pile, which the
//! next step's solve takes back without moving anything. Box2D v3 and Rapier weigh that
//! displacement by half (`positionSleepFactor` in Box2D's `b2FinalizeBodies`, `drift * 0.5` in
//! Rapier's `RigidBodyActivation::update_energy`), so a body rests below 0.1 units/s of it.

use super::disjoint_sets::DisjointSets;
use super::manifold::{GROUND, Manifold};
use crate::sim::body::RigidBody;
use crate::sim::constraint::DistanceConstraint;
use crate::sim::parallel;
use rayon::prelude::*;

/// Speed (units/s) at which an island's mass, moving together, has the most kinetic energy
/// a resting island may have; a body faster than it wakes the sleepers it comes near.
pub const SLEEP_SPEED: f64 = 0.05;
/// Speed (units/s) above which a body keeps its island awake whatever the island's energy: a
/// body that slides is not put to sleep with a resting pile it touches.
pub const SLEEP_SPEED_CAP: f64 = 4.0 * SLEEP_SPEED;
/// Weight of the step's displacement against [`SLEEP_SPEED`]: "position correction is not as
/// important for sleep as true velocity" (Box2D v3).
pub const POSITION_SLEEP_FACTOR: f64 = 0.5;
/// Seconds an island must rest before it sleeps.
pub const TIME_TO_SLEEP: f64 = 0.5;
/// Speed (units/s, weighed as [`SLEEP_SPEED`] is) under which an island in free flight without
/// gravity counts as still and may sleep: a millionth of a unit a second, where one drifting
/// slower than the sleep speed would otherwise be stopped, its momentum lost.
pub const STILL_SPEED: f64 = 1e-6;

/// The islands [`settle`] finds and the buffers it works in: kept from step to step, so a step
/// allocates nothing.
#[derive(Debug, Clone, Default)]
pub struct Islands {
    sets: DisjointSets,
    /// Least sleep time in each island (by root).
    least: Vec<f64>,
    /// Each island's awake bodies (by root).
    members: Vec<u32>,
    /// Each island's mass and `sum m v^2` (by root).
    mass: Vec<f64>,
    energy: Vec<f64>,
    /// Whether each body touches something (by body).
    touched: Vec<bool>,
    /// Whether each body touches the ground, a fixed body or a sleeping one, or hangs from a
    /// fixed body by a constraint (by body).
    held: Vec<bool>,
    /// Whether some body of each island is held (by root): an island that is not is in free
    /// flight and never rests.
    supported: Vec<bool>,
    /// Sleeping bodies an awake body touches, found by the last [`settle`] (see
    /// [`Islands::touched_sleepers`]).
    touched_sleepers: Vec<usize>,
    /// The awake bodies' steps ([`awake_bodies`]) and each one's island (its root).
    awake: Vec<Awake>,
    roots: Vec<usize>,
}

impl Islands {
    fn reset(&mut self, n: usize) {
        self.sets.reset(n);
        self.least.clear();
        self.least.resize(n, f64::INFINITY);
        self.members.clear();
        self.members.resize(n, 0);
        for sums in [&mut self.mass, &mut self.energy] {
            sums.clear();
            sums.resize(n, 0.0);
        }
        for flags in [&mut self.touched, &mut self.held, &mut self.supported] {
            flags.clear();
            flags.resize(n, false);
        }
        self.touched_sleepers.clear();
    }

    /// Sleeping bodies that a body still awake after the last [`settle`] touched in its step,
    /// at any speed: the next step wakes them. A touch links the two islands, as a contact that
    /// begins touching links and wakes them in Box2D v3 (`b2LinkContact`): without it a body
    /// that crept into a sleeper (slower than the sleep speed, so [`disturbed`] passes it over)
    /// met a wall, and a box set gently on the end of a sleeping plank balanced on a support
    /// rested there while the plank stayed level. Two islands that touch sleep together from
    /// then on, so the touch wakes the sleeper once.
    pub fn touched_sleepers(&self) -> &[usize] {
        &self.touched_sleepers
    }
}

/// Pairs of movable bodies that hold each other: constraints, and contacts in `pairs`.
fn links<'a>(
    bodies: &'a [RigidBody],
    constraints: &'a [DistanceConstraint],
    pairs: impl Iterator<Item = (usize, usize)> + 'a,
) -> impl Iterator<Item = (usize, usize)> + 'a {
    constraints
        .iter()
        .map(|c| (c.body1, c.body2))
        .chain(pairs)
        .filter(move |&(i, j)| i != GROUND && bodies[i].is_dynamic() && bodies[j].is_dynamic())
}

/// Updates sleep timers after a step of `dt` under `gravity` from the poses it began at
/// (`start`), then puts to sleep every island of awake bodies (joined by `touching` pairs and
/// constraints) whose bodies all rested long enough; never the island of the body a grab holds
/// (`grabbed`), which moves as the cursor does (held still on the ground, it slept at 0.5 s and
/// was woken by the next step, its velocity zeroed every half second).
pub fn settle(
    islands: &mut Islands,
    bodies: &mut [RigidBody],
    radii: &[f64],
    start: &[(glam::DVec3, glam::DQuat)],
    constraints: &[DistanceConstraint],
    touching: impl Iterator<Item = (usize, usize)>,
    (dt, gravity, grabbed): (f64, glam::DVec3, Option<usize>),
) {
    let mut awake = std::mem::take(&mut islands.awake);
    awake_bodies(bodies, radii, start, dt, &mut awake);
    islands.reset(bodies.len());
    let (touched, touched_sleepers) = (&mut islands.touched, &mut islands.touched_sleepers);
    let held = &mut islands.held;
    let view = &*bodies;
    // What does not fall: the ground, a fixed body, a sleeping one.
    let holds = |k: usize| k == GROUND || !view[k].is_dynamic() || view[k].asleep;
    let touching = touching.inspect(|&(i, j)| {
        touched[j] = true;
        held[j] |= holds(i);
        if i == GROUND {
            return;
        }
        touched[i] = true;
        held[i] |= holds(j);
        let sleeps = |k: usize| view[k].asleep && view[k].is_dynamic();
        match (view[i].is_awake(), view[j].is_awake()) {
            (true, false) if sleeps(j) => touched_sleepers.push(j),
            (false, true) if sleeps(i) => touched_sleepers.push(i),
            _ => {}
        }
    });
    for (i, j) in links(view, constraints, touching) {
        islands.sets.join(i, j);
    }
    // Each island's mass and twice its kinetic energy (of the speeds above); each body's root
    // found once.
    let mut roots = std::mem::take(&mut islands.roots);
    roots.clear();
    roots.extend((awake.iter()).map(|a| islands.sets.root(a.index)));
    for c in constraints {
        for (body, other) in [(c.body1, c.body2), (c.body2, c.body1)] {
            islands.held[body] |= !view[other].is_dynamic();
        }
    }
    for (a, &root) in awake.iter().zip(&roots) {
        islands.energy[root] += a.mass * a.speed * a.speed;
        islands.mass[root] += a.mass;
        islands.members[root] += 1;
        islands.supported[root] |= islands.held[a.index];
    }
    let weightless = gravity == glam::DVec3::ZERO;
    for (a, &root) in awake.iter().zip(&roots) {
        let i = a.index;
        let calm = islands.energy[root] < islands.mass[root] * SLEEP_SPEED * SLEEP_SPEED;
        // How much its velocity may change while it rests (see [`FEW_BODIES`]).
        let limit = match (islands.members[root] <= FEW_BODIES, islands.touched[i]) {
            (true, _) => REST_VELOCITY_CHANGE,
            (false, false) => SLEEP_SPEED,
            (false, true) => f64::INFINITY,
        };
        rest_for(&mut bodies[i], a, (calm, limit), dt);
        if grabbed == Some(i) {
            // Rests afresh once let go.
            bodies[i].sleep_time = 0.0;
        }
        // In free flight under a gravity too weak for the velocity test (a box falling at
        // 0.03 units/s^2 slept in mid-air at 0.5 s), the island rests no time at all; without
        // gravity, only while it is still.
        let still = weightless && islands.energy[root] < islands.mass[root] * STILL_SPEED.powi(2);
        let rested = match islands.supported[root] || still {
            true => bodies[i].sleep_time,
            false => 0.0,
        };
        islands.least[root] = islands.least[root].min(rested);
    }
    // An island rests when its least rested body does.
    for (&Awake { index: i, .. }, &root) in awake.iter().zip(&roots) {
        if islands.least[root] >= TIME_TO_SLEEP {
            let b = &mut bodies[i];
            b.asleep = true;
            b.linear_velocity = glam::DVec3::ZERO;
            b.angular_velocity = glam::DVec3::ZERO;
        }
    }
    // A touch joined the sleeper to its toucher's island: if that island fell asleep too, the
    // two sleep together and the touch wakes nothing.
    let (sets, least) = (&mut islands.sets, &islands.least);
    islands
        .touched_sleepers
        .retain(|&j| least[sets.root(j)] < TIME_TO_SLEEP);
    if awake.capacity().max(roots.capacity()) <= KEPT_AWAKE_AT_MOST {
        (islands.awake, islands.roots) = (awake, roots);
    }
}

/// The largest capacity (in bodies) at which [`settle`] keeps its lists for the next step. Kept,
/// they spare a small scene's step two allocations (measurably faster: the box hung by a corner,
/// docs/accuracy-log.md "Stop 74"); kept at any size, they would add 3.1 MiB to scatter-100000's
/// peak, which the narrow phase reaches while they are not needed. Past 4,096 bodies (128 KiB
/// of lists) an allocation is nothing beside the step.
const KEPT_AWAKE_AT_MOST: usize = 4096;

/// The awake bodies' steps, measured from the poses they began at (`start`), into `out`. One
/// pass over the bodies, which keeps the awake ones' indices, speeds and masses for the
/// islands: three passes over 100,000 bodies of 300 bytes took scatter-100000's sleeping from
/// 5-6.5 to 8.8-9.6 ms a step.
fn awake_bodies(
    bodies: &[RigidBody],
    radii: &[f64],
    start: &[(glam::DVec3, glam::DQuat)],
    dt: f64,
    out: &mut Vec<Awake>,
) {
    let items = bodies.par_iter().zip(start).enumerate();
    out.clear();
    parallel::extend_filter_map(out, items, 1024, |(i, (b, &(p0, q0)))| {
        if !b.is_awake() {
            return None;
        }
        let turn = (q0.conjugate() * b.orientation).normalize();
        let angle = 2.0 * turn.xyz().length().atan2(turn.w.abs());
        let moved = (b.position - p0).length() + angle * radii[b.shape];
        Some(Awake {
            index: i,
            speed: POSITION_SLEEP_FACTOR * moved / dt,
            mass: b.mass,
        })
    })
}

/// An awake body as [`settle`] measured its step.
#[derive(Debug, Clone, Copy)]
struct Awake {
    index: usize,
    /// The speed the sleep test weighs (see [`POSITION_SLEEP_FACTOR`]).
    speed: f64,
    mass: f64,
}

/// Islands of this many awake bodies or fewer have every body asked whether its velocity has
/// changed since its rest began, by [`REST_VELOCITY_CHANGE`]: a box or a few on a slope.
/// Larger ones ask only their bodies that touch nothing (held by distance constraints, whose
/// velocities are the exact solve's, or a hair from a contact), and by the sleep speed. In a
/// large island the velocities of bodies in contact carry the pile's unconverged Gauss-Seidel
/// (see the module's documentation), and its bodies slip and rock now and then, each a little
/// and briefly: the island's energy says whether it rests (asked of every body whether it
/// accelerated away from where its rest began, pile-10000 at restitution 0.2 had 75 of its
/// bodies asleep after 30 s, where it sleeps by 30 s). The price: a small island rocking in a
/// contact's limit cycle stays awake while it rocks (pile_rest at dt 0.01: a few bodies at
/// 0.11 units/s at 10 s, asleep at 12 s, where the whole pile had slept before 10 s).
pub const FEW_BODIES: u32 = 16;

/// Largest change of velocity since its rest began that an asked body may have and go on
/// resting ([`FEW_BODIES`]): from rest, an acceleration of more than 0.04 units/s^2 reaches it
/// within [`TIME_TO_SLEEP`]. A slow pendulum near its apex is under the sleep speed for longer than
/// the time to sleep (one of 100 units swinging by 2 slept there, off centre, for ever, until
/// stop 54 asked its velocity's change), and a box starting to slide down a slope too steep
/// for its friction is under it for seconds: with the sleep speed as the limit, and touching
/// bodies not asked, the box slept at 0.5 s (mu = 0.5, 27 degrees: 0.011 units moved in 10 s
/// where it slides 4.2; under sideways gravity 0.1 units/s^2 beyond friction's hold, 0.014 of
/// 1.25 in 5 s).
pub const REST_VELOCITY_CHANGE: f64 = 0.4 * SLEEP_SPEED;

/// Brings body `b`'s rest timer up to date after its step (`a`), in an island that is `calm`
/// or not: a change of its velocity since its rest began beyond `limit` ends the rest.
fn rest_for(b: &mut RigidBody, a: &Awake, (calm, limit): (bool, f64), dt: f64) {
    b.moving = a.speed >= SLEEP_SPEED;
    let changed = (b.linear_velocity - b.rest_velocity).length() > limit;
    b.sleep_time = if !(calm && a.speed < SLEEP_SPEED_CAP) {
        0.0
    } else if b.sleep_time == 0.0 || changed {
        b.rest_velocity = b.linear_velocity;
        dt
    } else {
        b.sleep_time + dt
    };
}

/// Wakes the sleeping islands of `seeds` (every sleeping body joined to one by touching
/// contacts or constraints); false if no seed was asleep.
pub fn wake(
    bodies: &mut [RigidBody],
    constraints: &[DistanceConstraint],
    touching: impl Iterator<Item = (usize, usize)>,
    seeds: impl Iterator<Item = usize>,
) -> bool {
    let mut stack: Vec<usize> = seeds.filter(|&i| bodies[i].asleep).collect();
    if stack.is_empty() {
        return false;
    }
    // Only a link between two sleepers carries the waking on (an awake body is neither woken
    // nor passed through): those links both ways, sorted, so each sleeper's are a run. (A list
    // of neighbours for every body, made at each call, took a millisecond of the steps of
    // scatter-100000's landing that woke an island.)
    let view = &*bodies;
    let mut edges: Vec<(usize, usize)> = links(view, constraints, touching)
        .filter(|&(i, j)| view[i].asleep && view[j].asleep)
        .flat_map(|(i, j)| [(i, j), (j, i)])
        .collect();
    edges.sort_unstable();
    while let Some(i) = stack.pop() {
        if !bodies[i].asleep {
            continue;
        }
        bodies[i].wake();
        let first = edges.partition_point(|&(from, _)| from < i);
        let run = edges[first..].iter().take_while(|&&(from, _)| from == i);
        stack.extend(run.map(|&(_, j)| j).filter(|&j| bodies[j].asleep));
    }
    true
}

/// Sleeping bodies that this step's candidate pairs bring next to a moving body (their boxes,
/// grown by how far the moving one can travel, overlap), and sleeping bodies constrained to an
/// awake one. An awake body at rest disturbs nothing: two resting islands whose boxes overlap
/// would otherwise wake each other in turn, each falling asleep just after the other, forever.
pub fn disturbed(
    bodies: &[RigidBody],
    constraints: &[DistanceConstraint],
    pairs: &[(u32, u32)],
) -> Vec<usize> {
    let mut out = Vec::new();
    let moving = |b: &RigidBody| b.is_awake() && b.moving;
    let mut wake = |(i, j): (usize, usize), disturbs: &dyn Fn(&RigidBody) -> bool| {
        let (a, b) = (&bodies[i], &bodies[j]);
        if a.asleep && disturbs(b) {
            out.push(i);
        } else if b.asleep && disturbs(a) {
            out.push(j);
        }
    };
    for &(i, j) in pairs {
        wake((i as usize, j as usize), &moving);
    }
    for c in constraints {
        wake((c.body1, c.body2), &RigidBody::is_awake);
    }
    out
}

/// The pairs of `manifolds` whose points hold the bodies together (touching, not merely
/// speculative).
pub fn touching_pairs(manifolds: &[Manifold]) -> impl Iterator<Item = (usize, usize)> + '_ {
    manifolds
        .iter()
        .filter(|m| m.points().iter().any(|p| p.separation <= 0.0))
        .map(|m| (m.body1, m.body2))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DMat3, DQuat, DVec3};

    fn resting_bodies(n: usize) -> Vec<RigidBody> {
        (0..n)
            .map(|_| {
                RigidBody::new(
                    0,
                    1.0,
                    DMat3::IDENTITY,
                    1.0,
                    false,
                    DVec3::ZERO,
                    DQuat::IDENTITY,
                )
            })
            .collect()
    }

    /// Moves each body along x at its speed for 1.2 [`TIME_TO_SLEEP`], the pairs `touching`
    /// held together, every body on the ground, settling after each step of 0.01 s.
    fn settle_moving(bodies: &mut [RigidBody], speeds: &[f64], touching: &[(usize, usize)]) {
        let on_ground: Vec<(usize, usize)> = (0..bodies.len()).map(|k| (GROUND, k)).collect();
        settle_moving_touching(bodies, speeds, &[touching, &on_ground].concat());
    }

    /// [`settle_moving`] with only the pairs `touching`.
    fn settle_moving_touching(
        bodies: &mut [RigidBody],
        speeds: &[f64],
        touching: &[(usize, usize)],
    ) {
        settle_moving_under(bodies, speeds, touching, DVec3::new(0.0, -9.8, 0.0));
    }

    /// [`settle_moving_touching`] under `gravity`.
    fn settle_moving_under(
        bodies: &mut [RigidBody],
        speeds: &[f64],
        touching: &[(usize, usize)],
        gravity: DVec3,
    ) {
        let (dt, mut islands) = (0.01, Islands::default());
        for _ in 0..(1.2 * TIME_TO_SLEEP / dt).ceil() as usize {
            let start: Vec<_> = bodies.iter().map(|b| (b.position, b.orientation)).collect();
            for (b, v) in bodies.iter_mut().zip(speeds) {
                if !b.asleep {
                    b.position.x += v * dt;
                }
            }
            let links = touching.iter().copied();
            settle(
                &mut islands,
                bodies,
                &[1.0],
                &start,
                &[],
                links,
                (dt, gravity, None),
            );
        }
    }

    /// Two bodies alone, one creeping at 0.09 units/s and one at 0.11: weighed by half, as Box2D
    /// v3 and Rapier weigh a step's displacement, the first rests and sleeps after
    /// [`TIME_TO_SLEEP`], the second never gathers sleep time.
    #[test]
    fn displacement_counts_half_against_the_sleep_speed() {
        let mut bodies = resting_bodies(2);
        settle_moving(&mut bodies, &[0.09, 0.11], &[]);
        assert!(bodies[0].asleep, "0.09 units/s did not sleep");
        assert!(!bodies[1].asleep && bodies[1].sleep_time == 0.0);
        assert!(!bodies[0].moving && bodies[1].moving);
    }

    /// An island of 100 resting bodies sleeps with one of them rocking at 0.3 units/s (half of
    /// it counted: 0.15, three times the sleep speed, but the island's energy is that of its mass
    /// at 0.015); the same body alone never sleeps, and one at 0.5 units/s (0.25, above
    /// [`SLEEP_SPEED_CAP`]) keeps the whole island awake.
    #[test]
    fn an_island_sleeps_on_its_energy_unless_a_body_is_fast() {
        let chain: Vec<(usize, usize)> = (1..100).map(|i| (i - 1, i)).collect();
        for (speed, sleeps) in [(0.3, true), (0.5, false)] {
            let mut bodies = resting_bodies(100);
            let mut speeds = vec![0.0; 100];
            speeds[42] = speed;
            settle_moving(&mut bodies, &speeds, &chain);
            assert!(
                bodies.iter().all(|b| b.asleep == sleeps),
                "one body at {speed} units/s"
            );
            assert!(bodies[42].moving && !bodies[41].moving);
        }
        let mut alone = resting_bodies(1);
        settle_moving(&mut alone, &[0.3], &[]);
        assert!(!alone[0].asleep);
    }

    /// Bodies at rest touching nothing that holds them are in free flight (under a gravity too
    /// weak to show within the time to sleep): two touching each other never sleep, while the
    /// same two with one of them on the ground sleep (a third, alone in the air, does not).
    /// Without gravity, where a body at rest stays at rest, all three sleep, unless they drift.
    #[test]
    fn an_island_touching_nothing_never_sleeps_unless_nothing_falls() {
        let mut bodies = resting_bodies(3);
        settle_moving_touching(&mut bodies, &[0.0; 3], &[(0, 1)]);
        assert!(bodies.iter().all(|b| !b.asleep));
        let mut bodies = resting_bodies(3);
        settle_moving_touching(&mut bodies, &[0.0; 3], &[(0, 1), (GROUND, 1)]);
        assert!(bodies[0].asleep && bodies[1].asleep && !bodies[2].asleep);
        let mut bodies = resting_bodies(3);
        let weak = DVec3::new(0.0, -1e-12, 0.0);
        settle_moving_under(&mut bodies, &[0.0; 3], &[(0, 1)], weak);
        assert!(bodies.iter().all(|b| !b.asleep));
        let mut bodies = resting_bodies(3);
        settle_moving_under(&mut bodies, &[0.0; 3], &[(0, 1)], DVec3::ZERO);
        assert!(bodies.iter().all(|b| b.asleep));
        // Drifting at 0.01 units/s (a fifth of the sleep speed), they keep their momentum.
        let mut bodies = resting_bodies(3);
        settle_moving_under(&mut bodies, &[0.01; 3], &[(0, 1)], DVec3::ZERO);
        assert!(bodies.iter().all(|b| !b.asleep));
    }
}
