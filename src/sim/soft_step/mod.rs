//! tumble's own solver, after Catto's soft step (Solver2D 2024, Box2D v3) in 3D:
//!
//! - contacts are detected once per step as manifolds of up to four points, speculatively (points
//!   up to the distance the bodies can travel in the step), warm-started by feature key
//!   ([`manifold`], [`contact_solver`]);
//! - contacts with Coulomb friction and the distance constraints are solved together in
//!   substeps: integrate velocities, warm start, a soft (biased) pass, integrate positions, a
//!   rigid relax pass, two where the substep clamps the contacts' stiffness
//!   ([`contact_solver`], [`joint_solver`], [`softness`]);
//! - then one restitution pass that gives each bouncing point `e^2` of the energy it arrived
//!   with, measured in the invariant of the integrator (exact apex ratios at any step).
//!
//! Large islands are solved colour by colour on all threads ([`constraint_graph`]); small ones
//! (up to 64 manifolds), in a scene without distance constraints or a grab, in batches, each
//! through all its substeps while its rows are in cache ([`island_batch`]), with the same bits.

pub mod constraint_graph;
pub mod contact_solver;
pub mod disjoint_sets;
pub mod envelope;
mod island_batch;
pub mod joint_block;
pub mod joint_solver;
pub mod manifold;
pub mod normal_block;
pub mod pivoted_ldl;
pub mod restitution;
pub mod sleep;
pub mod softness;
pub mod solver_body;

use super::body::{RigidBody, any_awake, may_collide};
use super::broad_phase::BroadPhase;
use super::buffer;
use super::constraint::DistanceConstraint;
use super::grab::Grab;
use super::integrate::integrate_pose;
use super::parallel;
use super::shape::Shape;
use super::stats::{Stage, StepStats, Stopwatch};
use super::step_context::StepContext;
use constraint_graph::{Colours, for_each_indexed, for_each_indexed2};
use contact_solver::{
    ContactCache, ContactConstraint, ContactParams, ContactPoint, HeldImpulses, Pass,
};
use glam::{DQuat, DVec3};
use joint_block::{HeldSides, JointBlocks};
use joint_solver::JointRow;
use manifold::{Manifold, PairStates, body_manifold, ground_manifold, motion_bound};
use rayon::prelude::*;
use softness::Softness;
use solver_body::SolverBody;

/// Natural frequency of the soft contacts, where the substep allows it: the stiffest the clamp
/// of [`Substeps::new`] allows at the preset's four substeps of dt 0.02. Box2D's 30 Hz sagged a
/// third more under load: pile-200's deepest contact at rest 0.0166-0.0176 units against
/// 0.0103-0.0118 (medians of 130 draws at each of dt 0.04, 0.02, 0.01), the tower's drift
/// 0.00145 against 0.00102 at dt 0.02; piles settle as soon (asleep by 10 s: 110, 107, 107 of
/// 130, against 97, 111, 111 at 30 Hz), at no cost at dt 0.02 and below and an eighth substep at
/// dt 0.04.
const CONTACT_HERTZ: f64 = 37.5;
/// Stiffest contacts between bodies, as a fraction of the substep rate (see [`Substeps::new`]).
const CONTACT_RATE_FRACTION: f64 = 0.1875;
/// Stiffest contacts with a static body, as a fraction of the substep rate.
const STATIC_RATE_FRACTION: f64 = 0.25;
const CONTACT_DAMPING_RATIO: f64 = 10.0;
const JOINT_HERTZ: f64 = 60.0;
const JOINT_DAMPING_RATIO: f64 = 2.0;
/// Fastest a soft correction pushes bodies apart (units/s).
const MAX_PUSH_SPEED: f64 = 3.0;
/// A joint group is projected onto its bounds in a substep before the last only where a row
/// is out by more than this fraction of its bound. A whipping rope's links turn far in a step,
/// and four substeps of soft rows left it stretched by up to 5 % at the step's end, too far
/// for the projection's linearisation (Gauss-Newton overshot, the links lying nearly in line):
/// it ran through its 64 rounds, and rope-200 at dt 0.03 and 0.04 and rope-1000 at dt 0.04
/// came apart. Caught at 0.1 %, ropes of 200 and 1,000 links at dt 0.02 ... 0.05 hold within
/// 1e-6 of a link's rest length for 20 s (rope-1000 at dt 0.04 in 8.6 ms a step). At 1 %,
/// rope-1000 still came apart; at 0.01 %, the chains' worst stretch moved at every dt, where
/// at 0.1 % only at dt 0.02 and 0.04, the pendulum (one row) at none (measured). The checks
/// cost chain-1000 (100 groups) 3 % of its step on one thread and 11-13 % on two, where each
/// is a fork into the thread pool; a check on one thread first cost more.
const MIDSTEP_PROJECTION_TOLERANCE: f64 = 1e-3;
/// Points this far apart still count as contacts, whatever the speeds (units).
const SPECULATIVE_DISTANCE: f64 = 0.02;
/// Bodies or pairs whose manifolds are collected at once (see [`buffer::blocks`]).
const MANIFOLD_BLOCK: usize = 16_384;

/// What the soft-step solver carries from one step to the next: the impulses of the contact
/// points and of the distance constraints (warm starting), and the buffers a step works in.
#[derive(Debug, Clone, Default)]
pub struct SoftStep {
    contacts: ContactCache,
    joint_impulses: Vec<f64>,
    /// Where each joint group's active-set loop starts.
    joint_sides: HeldSides,
    /// parry's last manifold of each candidate pair.
    pair_states: PairStates,
    /// Bounding radius of each shape (for the speculative margin of spinning bodies).
    radii: Vec<f64>,
    blocks: JointBlocks,
    /// Per constraint, whether its group was handed to Gauss-Seidel (its active sets
    /// cycled; see [`JointBlocks::take_cycled`]). Kept by constraint, not by group, so that
    /// groups made again, or a restored snapshot, see the same.
    relaxed_joints: Vec<bool>,
    islands: sleep::Islands,
    /// The step's small islands, solved in batches of their own.
    small_islands: island_batch::SmallIslands,
    /// Sleeping bodies an awake body touched in the last step: the next step wakes them.
    touched_sleepers: Vec<usize>,
    /// The settings of the last step: a change wakes every sleeping body.
    last_settings: Option<crate::sim::Settings>,
    /// Length of the last solved step's substeps (the carried impulses are per substep).
    last_substep: f64,
    /// Doublings of a jointed scene's substeps since its joint projections were cut short
    /// (see [`joint_substeps`]).
    joint_boost: u32,
    /// Every island solved colour by colour, none in batches (for tests: the same bits).
    by_colour_only: bool,
    work: Workspace,
}

/// Buffers of one step, kept so that a step allocates nothing once the scene is warm.
#[derive(Debug, Clone, Default)]
struct Workspace {
    margins: Vec<f64>,
    manifolds: Vec<Manifold>,
    bodies: Vec<SolverBody>,
    /// Linear and angular velocity of each solved body before the restitution pass.
    before_restitution: Vec<(DVec3, DVec3)>,
    /// Energy of every body when the step began.
    start_energy: Vec<f64>,
    contacts: Vec<ContactConstraint>,
    points: Vec<ContactPoint>,
    rows: Vec<JointRow>,
    large_groups: Vec<usize>,
    held: HeldImpulses,
    held_rows: Vec<f64>,
    /// The manifolds' colours (they are kept in colour order).
    colours: Colours,
    /// The bodies the solver sees this step: every body in a manifold or a constraint, and
    /// the grabbed one (ascending; fixed ones included, as static solver bodies).
    solved: Vec<usize>,
    /// The awake ones among `solved`: those the substeps integrate.
    moving: Vec<usize>,
    /// Those of `moving` the substep program integrates: all but the small islands' (see
    /// [`island_batch`]).
    solving: Vec<usize>,
    /// The contact constraints the substep program solves (ascending): all where `None`, else
    /// those not in a small island.
    selected: Option<Vec<u32>>,
    /// Marks of `solved` by body index.
    in_solver: Vec<bool>,
    /// Awake bodies that nothing touches or holds: integrated on their own, in parallel.
    free: Vec<bool>,
    /// Whether the solver bodies' world inverse inertia turns with them in the substeps:
    /// where distance constraints or a grab read it after [`SoftStep::prepare`] (see
    /// [`Workspace::integrate_positions`]).
    turns_inertia: bool,
}

impl Workspace {
    /// Holds back `fraction` of the contacts' and joint rows' accumulated impulses (see
    /// [`HeldImpulses`]).
    fn hold_back(&mut self, fraction: f64) {
        self.held
            .hold_back(&mut self.contacts, &mut self.points, fraction);
        self.held_rows.clear();
        self.held_rows.extend(self.rows.iter_mut().map(|r| {
            let held = fraction * r.impulse;
            r.impulse -= held;
            held
        }));
    }

    fn release(&mut self) {
        self.held.release(&mut self.contacts, &mut self.points);
        for (r, held) in self.rows.iter_mut().zip(self.held_rows.drain(..)) {
            r.impulse += held;
        }
    }

    /// Each solving body's velocities now into `before_restitution`: as the step begins, before
    /// any kick (what [`restitution::bouncing_points`] reads), and again just before the
    /// restitution pass (what its energy rule reads). Nothing without contact points: neither
    /// reads them then.
    fn record_velocities(&mut self) {
        if self.points.is_empty() {
            return;
        }
        let before = &mut self.before_restitution;
        before.resize(self.bodies.len(), (DVec3::ZERO, DVec3::ZERO));
        for &i in &self.solving {
            before[i] = (
                self.bodies[i].linear_velocity,
                self.bodies[i].angular_velocity,
            );
        }
    }

    /// The restitution pass over the program's constraints (`selected`), then its energy rule
    /// over the bodies the program moves (`solving`, whose velocities before the pass it reads;
    /// `poses` their poses, `joints` the distance constraints, held rigid by `hold_joints`).
    /// The step's program and each batch of small islands run it on their own constraints.
    fn bounce(
        &mut self,
        poses: &[RigidBody],
        joints: &[DistanceConstraint],
        (settings, h): (&crate::sim::Settings, f64),
        hold_joints: impl FnMut(&mut [SolverBody], &[bool]),
    ) {
        // No contact point, no bounce: the pass and its energy rule would find nothing (a
        // chain, a pendulum, a body in flight).
        if self.points.is_empty() {
            return;
        }
        let rule = restitution::BounceRule {
            restitution: settings.restitution,
            threshold: settings.restitution_threshold,
            kick: settings.gravity * h,
        };
        let bounces = restitution::bouncing_points(
            self.selected.as_deref(),
            (&self.contacts, &self.points),
            (&self.bodies, &self.before_restitution),
            rule,
        );
        self.record_velocities();
        let solved = restitution::apply(
            (&self.colours, self.selected.as_deref()),
            (&mut self.contacts, &mut self.points),
            &mut self.bodies,
            (&bounces, settings.restitution, !joints.is_empty()),
            hold_joints,
        );
        let contacts = restitution::Contacts {
            constraints: &self.contacts,
            selected: self.selected.as_deref(),
            points: &self.points,
            solved: &solved,
            joints,
        };
        restitution::settle_energy(
            &contacts,
            poses,
            &self.before_restitution,
            &mut self.bodies,
            &self.start_energy,
            &restitution::EnergyRule::of(settings),
        );
    }
}

/// The bodies, shapes and constraints the solver works on.
pub struct Scene<'a> {
    pub bodies: &'a mut [RigidBody],
    pub shapes: &'a [Shape],
    pub constraints: &'a [DistanceConstraint],
    pub grab: Option<&'a Grab>,
    /// Each body's pose when the step began, one per body: the step records those of the
    /// bodies it moves before it moves them and measures their motion from there. The pose
    /// check's last finite poses are these same poses ([`crate::sim::quarantine`]); one buffer
    /// serves both (5.3 MiB at 100,000 bodies).
    pub start: &'a mut [(DVec3, DQuat)],
}

/// What [`SoftStep::finish`] works on: the bodies, the constraints, each body's pose when the
/// step began, and the body a grab holds.
type FinishedParts<'a> = (
    &'a mut [RigidBody],
    &'a [DistanceConstraint],
    &'a [(DVec3, DQuat)],
    Option<usize>,
);

/// What a step leaves for the next one (warm-start impulses): a snapshot's share.
#[derive(Debug, Clone, Default)]
pub struct Carried {
    contacts: ContactCache,
    joint_impulses: Vec<f64>,
    joint_sides: HeldSides,
    pair_states: PairStates,
    /// The settings the state was stepped with: a step with others wakes every sleeper, so
    /// a restored state continued with its own settings repeats its steps bit for bit.
    last_settings: Option<crate::sim::Settings>,
    last_substep: f64,
    joint_boost: u32,
    relaxed_joints: Vec<bool>,
    touched_sleepers: Vec<usize>,
}

impl Carried {
    pub fn heap_bytes(&self) -> usize {
        self.contacts.heap_bytes()
            + self.joint_impulses.capacity() * 8
            + self.joint_sides.heap_bytes()
            + self.pair_states.heap_bytes()
            + self.relaxed_joints.capacity()
            + self.touched_sleepers.capacity() * std::mem::size_of::<usize>()
    }
}

/// The step's constants: substep length, softness, contact parameters.
struct Substeps {
    count: u32,
    h: f64,
    inv_h: f64,
    /// Rigid passes after each substep's soft pass and at the step's end: two where the
    /// contacts' stiffness is clamped by the substep ([`Substeps::new`]).
    relax_passes: u32,
    joint_softness: Softness,
    contact: ContactParams,
}

impl Substeps {
    /// The step's substeps: the setting's count (fewer in a step shorter than the setting's
    /// full-count length, see [`short_step_substeps`]), raised in a step that begins with contacts
    /// touching ([`touches`]) until each substep is short enough for the contacts' full
    /// stiffness (see [`contact_substeps`]), and in a scene with distance constraints
    /// (`joints`: its boost) until each is short enough for a whipping rope (see
    /// [`joint_substeps`]).
    fn new(ctx: &StepContext, touching: bool, joints: Option<u32>) -> Option<Self> {
        let mut count = short_step_substeps(&ctx.settings);
        if touching {
            count = count.max(contact_substeps(ctx.settings.time_step));
        }
        if let Some(boost) = joints {
            let (dt, gravity) = (ctx.settings.time_step, ctx.settings.gravity.length());
            count = count.max(joint_substeps(dt, gravity, boost));
        }
        let h = ctx.settings.time_step / count as f64;
        if h <= 0.0 || !h.is_finite() {
            return None;
        }
        // Soft contacts are clamped to 3/16 of the substep rate, those with a static body (twice
        // as stiff) to a quarter: at half the rate these ring (a stack of five at dt = 0.04
        // jitters at 0.4 units/s). The clamp binds (substeps over 1/200 s) only in a step with
        // no contacts touching or one past [`MAX_CONTACT_SUBSTEPS`] (dt over 0.08); there a
        // second relax pass holds a stack of five still (measured at dt 0.04 with four
        // substeps: drift 5e-4 in 10 s awake, 2e-3 with one pass). Box2D v3.1 clamps at an
        // eighth with one relax pass:
        // twice the sag under load (the top of a stack of ten sank by 0.18 at dt = 0.04 that
        // way, 0.08 with the clamp at 3/16 and four substeps, 0.033 with seven at 30 Hz).
        let clamp = CONTACT_RATE_FRACTION / h;
        let contact_hertz = CONTACT_HERTZ.min(clamp);
        let static_hertz = (2.0 * contact_hertz).min(STATIC_RATE_FRACTION / h);
        Some(Self {
            count,
            h,
            inv_h: 1.0 / h,
            // (A clamp short of the contacts' stiffness by a rounding is not a clamp.)
            relax_passes: if clamp < CONTACT_HERTZ * (1.0 - 1e-9) {
                2
            } else {
                1
            },
            joint_softness: Softness::new(JOINT_HERTZ.min(0.25 / h), JOINT_DAMPING_RATIO, h),
            contact: ContactParams {
                softness: Softness::new(contact_hertz, CONTACT_DAMPING_RATIO, h),
                static_softness: Softness::new(static_hertz, CONTACT_DAMPING_RATIO, h),
                friction: ctx.settings.friction,
                gravity: ctx.settings.gravity,
            },
        })
    }
}

/// The setting's substeps for a step of `time_step`: all of them from a step of
/// `full_substeps_from` up, proportionally fewer below it, down to half of them (a count that
/// comes out whole is not raised by its rounding): the substeps of a step shorter than that
/// length are no longer than its substeps, and no more than twice as long as the setting's
/// count would make them. Measured (`bench accuracy`, the preset against Rapier in the same
/// run, dt 0.005 and 0.0025): four substeps spent their length on errors thousands of times
/// below Rapier's (the box hung by a corner kept its energy to 1.3e-4 and 3.4e-5 against
/// Rapier's 0.32 and 0.28) at up to 1.1x Rapier's time, pile_rest at 1.36x and 1.06x; with two
/// the hung box keeps it to 6.4e-4 and 1.5e-4 at 0.78x, pile_rest takes 0.85x and 0.68x. Down to
/// one substep at dt 0.0025 the pendulum's period error stayed at dt 0.01's 1.2e-7, above
/// Rapier's 9.6e-8 there; with two it is 1.9e-8.
fn short_step_substeps(settings: &crate::sim::Settings) -> u32 {
    let (count, full) = (settings.substeps.max(1), settings.full_substeps_from);
    if full <= 0.0 || settings.time_step >= full {
        return count;
    }
    whole_substeps(count as f64 * settings.time_step / full, count).max(count.div_ceil(2))
}

/// Most substeps a step with touching contacts is raised to by [`contact_substeps`].
const MAX_CONTACT_SUBSTEPS: u32 = 16;

/// Substeps a step of `dt` with contacts needs for its contacts to reach [`CONTACT_HERTZ`]
/// under the clamp of [`Substeps::new`] (substeps of at most 1/200 s), up to
/// [`MAX_CONTACT_SUBSTEPS`]. At dt 0.04 the preset's four substeps clamped them to 18.75 Hz, and
/// a resting pile sank like a soft spring under the load of the bodies above: its deepest
/// contact 0.9-1.9 % of the smallest body over 13 draws of pile-200 (the bench's draw 1.4 %).
/// With seven substeps where there are contacts (the 30 Hz of then), 0.33-0.74 % (0.50 %), all
/// 13 asleep by 10 s (9 before), the tower's drift 0.0017 (0.0034), for 7 % more time on the
/// pile (18.9 -> 20.3 ms per simulated second); a step without contacts (free flight, a hanging
/// chain) keeps the setting's count. dt 0.02 and below are unchanged (four are enough there;
/// a count that comes out whole is not raised by its rounding). Only contacts touching when
/// the step begins raise it ([`touches`]): until a later stop a speculative manifold of an
/// approach did too, in 169 of the 221 steps with manifolds of the two chains' first 500 at dt
/// 0.04 and all through a pile's fall, for no load held.
fn contact_substeps(dt: f64) -> u32 {
    whole_substeps(
        dt * CONTACT_HERTZ / CONTACT_RATE_FRACTION,
        MAX_CONTACT_SUBSTEPS,
    )
}

/// `wanted` substeps rounded up to a whole count, at most `most` (a count that comes out whole
/// is not raised by its rounding).
fn whole_substeps(wanted: f64, most: u32) -> u32 {
    (wanted - 1e-9).ceil().min(most as f64) as u32
}

/// Longest substep of a scene with distance constraints (s), under [`JOINT_SUBSTEP_GRAVITY`].
const JOINT_SUBSTEP: f64 = 1.0 / 80.0;
/// Earth's gravity (units/s^2), the default.
const JOINT_SUBSTEP_GRAVITY: f64 = 9.8;
/// Most substeps a scene with distance constraints is raised to by [`joint_substeps`], before
/// its boost.
const MAX_JOINT_SUBSTEPS: u32 = 16;
/// Most doublings of a jointed scene's substeps (see [`joint_substeps`]).
const MAX_JOINT_BOOST: u32 = 2;

/// Substeps a step of `dt` takes where the scene has distance constraints: enough for substeps
/// of at most 1/80 s, up to [`MAX_JOINT_SUBSTEPS`]. Within a longer substep a whipping rope's
/// links turn too far for the projections' linearisation, however early they run (see
/// [`MIDSTEP_PROJECTION_TOLERANCE`]): with the preset's four, rope-500 came apart at dt 0.075
/// (substeps of 0.019 s) and 0.1, rope-1000 at 0.1, and held at 0.06 (0.015 s); with substeps of
/// 1/80 s both hold at dt 0.075 and 0.1 for 20 s, and rope-1000 at dt 0.1 runs in half the time
/// (6.0 against 12.2 s). The preset's four substeps are 1/80 s or shorter up to dt 0.05, so
/// nothing changes there (the bench's dts, the viewer slider's range).
///
/// Under stronger gravity `g` a rope whips faster (a swing's time scales as sqrt(length / g)),
/// so the longest substep is 1/80 s times sqrt(9.8 / g): rope-200 at dt 0.05 came apart under
/// 5, 6 and 8 g with substeps of 1/80 s and gained 3.7 %, 27 % and 2.3 times its energy in
/// 20 s; eight substeps hold each (measured). A rope that still whips too fast (a step past the
/// cap) has its joint projections cut short ([`StepStats::joint_projections_cut_short`]): from
/// the next step on the substeps are doubled, up to [`MAX_JOINT_BOOST`] times (`boost`), until
/// the settings change. That holds a rope caught early (rope-1000 at dt 0.2, cut short in 5
/// groups), not one already apart (rope-500 at dt 0.4).
fn joint_substeps(dt: f64, gravity: f64, boost: u32) -> u32 {
    // A swing's time scales as sqrt(length / g): under stronger gravity, shorter substeps.
    let longest = JOINT_SUBSTEP * (JOINT_SUBSTEP_GRAVITY / gravity).sqrt().min(1.0);
    whole_substeps(dt / longest, MAX_JOINT_SUBSTEPS) << boost
}

impl SoftStep {
    /// Brings the carried impulses to substeps of length `h`: they are impulses per substep,
    /// and a load is held by an impulse in proportion to the substep's length (a step with
    /// contacts may take more substeps than one without, see [`Substeps::new`]).
    fn rescale_warm_start(&mut self, h: f64) {
        let last = std::mem::replace(&mut self.last_substep, h);
        if last > 0.0 && last != h {
            let factor = h / last;
            self.contacts.scale_impulses(factor);
            self.joint_impulses.iter_mut().for_each(|j| *j *= factor);
        }
    }

    pub fn carried(&self) -> Carried {
        Carried {
            contacts: self.contacts.clone(),
            joint_impulses: self.joint_impulses.clone(),
            joint_sides: self.joint_sides.clone(),
            pair_states: self.pair_states.clone(),
            last_settings: self.last_settings.clone(),
            last_substep: self.last_substep,
            joint_boost: self.joint_boost,
            relaxed_joints: self.relaxed_joints.clone(),
            touched_sleepers: self.touched_sleepers.clone(),
        }
    }

    /// Wakes sleeping body `index` and the island it fell asleep in (the bodies it touched or
    /// was joined to then): a body the user moves or grabs takes the bodies it held with it.
    pub fn wake_island(
        &self,
        bodies: &mut [RigidBody],
        constraints: &[DistanceConstraint],
        index: usize,
    ) {
        let touching = self.contacts.pairs();
        sleep::wake(bodies, constraints, touching, std::iter::once(index));
    }

    pub fn restore(&mut self, carried: &Carried) {
        self.contacts.clone_from(&carried.contacts);
        self.joint_impulses.clone_from(&carried.joint_impulses);
        self.joint_sides.clone_from(&carried.joint_sides);
        self.pair_states.clone_from(&carried.pair_states);
        self.last_settings.clone_from(&carried.last_settings);
        self.last_substep = carried.last_substep;
        self.joint_boost = carried.joint_boost;
        self.relaxed_joints.clone_from(&carried.relaxed_joints);
        self.touched_sleepers.clone_from(&carried.touched_sleepers);
    }

    /// One step: collide, then solve in substeps.
    pub fn step(
        &mut self,
        ctx: &StepContext,
        scene: Scene,
        broad: &mut BroadPhase,
        watch: &mut Stopwatch,
        stats: &mut StepStats,
    ) {
        let mut scene = scene;
        self.wake_on_demand(ctx, &mut scene);
        if at_rest(&scene) {
            self.rest(scene.bodies, stats);
            return;
        }
        let pairs = self.broad_phase(ctx, &mut scene, broad, watch, stats);
        let dt = ctx.settings.time_step;
        self.narrow_phase(
            (scene.bodies, scene.shapes, dt),
            broad,
            &pairs,
            watch,
            stats,
        );
        watch.enter(Stage::SolvePrepare);
        // The bodies' awake flags as the broad phase left them (nothing has woken or slept
        // since): 100 KB at 100,000 bodies where the bodies are 25 MB.
        let awake = broad.awake();
        let w = &mut self.work;
        w.colours
            .colour(&mut w.manifolds, awake.len(), |i| awake[i]);
        let touching = self.work.manifolds.iter().any(touches);
        let joints = (!scene.constraints.is_empty()).then_some(self.joint_boost);
        let Some(substeps) = Substeps::new(ctx, touching, joints) else {
            return;
        };
        self.rescale_warm_start(substeps.h);
        stats.substeps = substeps.count;
        self.prepare(ctx, (&mut scene, awake), &substeps);
        // Velocity Verlet: half a kick of gravity, then full kicks between the substeps' drifts
        // (symplectic Euler on the half-step velocities), and the last half kick at the end, so
        // free flight under gravity is exact and the velocities kept are those of the step's end.
        let kicks = Kicks::new(ctx.settings.gravity, substeps.h);
        watch.enter(Stage::Integrate);
        let w = &mut self.work;
        integrate_free(ctx, (scene.bodies, scene.start), &w.free, &substeps, &kicks);
        // The solved bodies' kicks and drifts between the substeps' passes count as Solve: a
        // clock read per switch costs more than a small scene's integration (bounce: a quarter
        // of the step).
        watch.enter(Stage::Solve);
        // With no manifold, constraint or grab every body is free: the passes would find none.
        if !self.work.solved.is_empty() {
            self.solve(ctx, &mut scene, &substeps, &kicks);
        }
        watch.enter(Stage::SolveFinish);
        stats.joint_projections_cut_short = self.blocks.take_cut_short();
        stats.joint_groups_relaxed = self.blocks.relaxed_groups();
        if stats.joint_projections_cut_short > 0 {
            self.joint_boost = (self.joint_boost + 1).min(MAX_JOINT_BOOST);
        }
        let grabbed = scene.grab.map(|g| g.body);
        let parts = (
            &mut *scene.bodies,
            scene.constraints,
            &*scene.start,
            grabbed,
        );
        self.finish(ctx, parts, substeps.h, stats);
        self.blocks.take_cycled(&mut self.relaxed_joints);
    }

    /// The solved bodies' substeps: the large islands' colour by colour, then the small ones'
    /// in batches (see [`island_batch`]). The two share no moving body, contact or point, so
    /// the order between them changes no bit. (The colours' holding back of half of every
    /// impulse, and its release, pass over the batches' points too and leave them as they were:
    /// `x - x/2` is exactly `x/2`, and `x/2 + x/2` exactly `x`.)
    fn solve(&mut self, ctx: &StepContext, scene: &mut Scene, substeps: &Substeps, kicks: &Kicks) {
        let w = &mut self.work;
        if !w.solving.is_empty() || w.selected.as_ref().is_none_or(|s| !s.is_empty()) {
            let mut solver = Solver {
                work: &mut *w,
                blocks: &mut self.blocks,
                joint_sides: &mut self.joint_sides,
            };
            let bodies = (&mut *scene.bodies, &*scene.start);
            solver.solve_substeps(ctx, bodies, scene.grab, substeps, kicks);
        }
        let arrays = island_batch::Arrays {
            bodies: &mut *scene.bodies,
            start: &*scene.start,
            start_energy: &w.start_energy,
            solver_bodies: &mut w.bodies,
            contacts: &mut w.contacts,
            points: &mut w.points,
        };
        self.small_islands.solve(ctx, arrays, substeps, kicks);
    }

    /// Wakes everything when sleeping is off or the settings changed, and the grabbed body's
    /// island.
    fn wake_on_demand(&mut self, ctx: &StepContext, scene: &mut Scene) {
        let changed = self.last_settings.as_ref() != Some(&ctx.settings);
        if changed {
            self.last_settings = Some(ctx.settings.clone());
            self.joint_boost = 0;
        }
        let bodies = &mut *scene.bodies;
        if changed || !ctx.settings.sleep {
            for b in bodies.iter_mut().filter(|b| b.asleep) {
                b.wake();
            }
        } else if let Some(grab) = scene.grab {
            let touching = self.contacts.pairs();
            sleep::wake(
                bodies,
                scene.constraints,
                touching,
                std::iter::once(grab.body),
            );
        }
    }

    /// The step of a scene at rest: what a full step would leave with no body awake (no
    /// manifolds, no pair states; sleeping bodies keep their cached impulses), without the
    /// stages that would find nothing.
    fn rest(&mut self, bodies: &[RigidBody], stats: &mut StepStats) {
        let w = &mut self.work;
        w.manifolds.clear();
        w.contacts.clear();
        w.points.clear();
        self.pair_states.keep(&[], Vec::new());
        self.touched_sleepers.clear();
        stats.asleep = bodies.iter().filter(|b| b.asleep).count();
    }

    /// Candidate pairs (see [`candidate_pairs`]), after waking the sleeping islands a moving
    /// body comes near or an awake body touched.
    fn broad_phase(
        &mut self,
        ctx: &StepContext,
        scene: &mut Scene,
        broad: &mut BroadPhase,
        watch: &mut Stopwatch,
        stats: &mut StepStats,
    ) -> Vec<(u32, u32)> {
        watch.enter(Stage::BroadPhase);
        let (bodies, shapes) = (&mut *scene.bodies, scene.shapes);
        if self.radii.len() != shapes.len() {
            self.radii = shapes.iter().map(|s| s.bounding_radius()).collect();
        }
        let (dt, gravity) = (ctx.settings.time_step, ctx.settings.gravity);
        let (margins, radii) = (&mut self.work.margins, &self.radii);
        margins.clear();
        parallel::extend_map(margins, bodies.par_iter(), 1024, |b| {
            motion_bound(b, radii[b.shape], gravity, dt) + SPECULATIVE_DISTANCE
        });
        let pairs = candidate_pairs(broad, (bodies, shapes), (radii, margins, dt, false), stats);
        let mut seeds = sleep::disturbed(bodies, scene.constraints, &pairs);
        seeds.append(&mut self.touched_sleepers);
        let touching = self.contacts.pairs();
        if !sleep::wake(bodies, scene.constraints, touching, seeds.into_iter()) {
            return pairs;
        }
        // The woken islands' pairs with their neighbours. They have not moved, so they disturb
        // no other sleeper in this step (their neighbours stay static to them for it, and wake
        // in the next step if they moved): waking them in a loop until nothing more woke ran
        // the broad phase once per ring of a resting carpet, five times a step at
        // scatter-100000, and kept all of it awake.
        candidate_pairs(broad, (bodies, shapes), (radii, margins, dt, true), stats)
    }

    /// Manifolds of the candidate pairs and of the awake bodies near the ground, ground first,
    /// then pairs in (body 1, body 2) order.
    fn narrow_phase(
        &mut self,
        (bodies, shapes, dt): (&[RigidBody], &[Shape], f64),
        broad: &BroadPhase,
        pairs: &[(u32, u32)],
        watch: &mut Stopwatch,
        stats: &mut StepStats,
    ) {
        watch.enter(Stage::NarrowPhase);
        stats.narrow_phase_queries += pairs.len();
        let margins = &self.work.margins;
        let manifolds = &mut self.work.manifolds;
        manifolds.clear();
        // A body's box grown by its margin reaches the ground plane. (Told from the broad
        // phase's arrays, so a body the ground is far from is not read.)
        let (grown, awake) = (broad.speculative_boxes(), broad.awake());
        for range in buffer::blocks(bodies.len(), MANIFOLD_BLOCK) {
            buffer::reserve_exact(manifolds, range.len());
            parallel::extend_filter_map(manifolds, range.into_par_iter(), 256, |j| {
                let reaches = awake[j] && grown[j].min.y <= 0.0;
                let b = &bodies[j];
                reaches.then(|| ground_manifold(j, b, &shapes[b.shape], (margins[j], dt)))?
            });
        }
        stats.ground_contacts = manifolds.len();
        let mut states = self.pair_states.take_for(pairs);
        for range in buffer::blocks(pairs.len(), MANIFOLD_BLOCK) {
            buffer::reserve_exact(manifolds, range.len());
            let (pairs, states) = (&pairs[range.clone()], &mut states[range]);
            let items = pairs.par_iter().zip(states);
            parallel::extend_filter_map(manifolds, items, 32, |(&(i, j), state)| {
                let (i, j) = (i as usize, j as usize);
                let prediction = margins[i] + margins[j];
                let (a, b) = ((i, &bodies[i]), (j, &bodies[j]));
                body_manifold(a, b, shapes, (prediction, dt), state)
            });
        }
        self.pair_states.keep(pairs, states);
        stats.contacts = manifolds.len() - stats.ground_contacts;
        for m in manifolds.iter() {
            for p in m.points() {
                stats.max_penetration = stats.max_penetration.max(-p.separation);
            }
        }
    }

    /// The bodies the solver must see (see [`Workspace::solved`]), and the free ones. The
    /// bodies are marked one manifold and constraint at a time, then listed in order and
    /// told apart, on all threads in a large scene (listed as met and sorted, on one thread,
    /// it took 1.4 ms of scatter-100000's step).
    fn select_bodies(&mut self, scene: &Scene, awake: &[bool]) {
        let (n, constraints) = (awake.len(), scene.constraints);
        let w = &mut self.work;
        w.in_solver.clear();
        w.in_solver.resize(n, false);
        let touched = w.manifolds.iter().flat_map(|m| [m.body1, m.body2]);
        let held = constraints.iter().flat_map(|c| [c.body1, c.body2]);
        let grabbed = scene.grab.map(|g| g.body);
        for i in touched.chain(held).chain(grabbed).filter(|&i| i < n) {
            w.in_solver[i] = true;
        }
        let in_solver = &w.in_solver;
        buffer::indices_where(n, |i| in_solver[i], &mut w.solved);
        let moving = |i: usize| in_solver[i] && awake[i];
        buffer::indices_where(n, moving, &mut w.moving);
        let free = |i: usize| !in_solver[i] && awake[i];
        buffer::map_indices(n, free, &mut w.free);
    }

    /// Solver bodies, start poses and energies, contact constraints and joint groups. Only the
    /// entries of the bodies the solver sees are written (the free ones' start poses, which
    /// sleeping reads, are written by [`integrate_free`]): the others are never read.
    fn prepare(
        &mut self,
        ctx: &StepContext,
        (scene, awake): (&mut Scene, &[bool]),
        substeps: &Substeps,
    ) {
        self.select_bodies(scene, awake);
        let (bodies, constraints, start) = (&*scene.bodies, scene.constraints, &mut *scene.start);
        let work = &mut self.work;
        // New solver bodies (their world inverse inertia at this step's poses).
        let n = bodies.len();
        work.bodies.resize(n + 1, SolverBody::STATIC);
        work.bodies[n] = SolverBody::STATIC; // the ground
        work.start_energy.resize(n, 0.0);
        let g = ctx.settings.gravity;
        for_each_indexed2(&work.solved, &mut work.bodies, start, |i, sb, start| {
            let b = &bodies[i];
            *sb = SolverBody::new(b);
            record_start(start, b);
        });
        let energy = |i: usize, e: &mut f64| {
            let b = &bodies[i];
            *e = match b.is_awake() {
                true => restitution::energy(b, b.linear_velocity, b.angular_velocity, g),
                false => 0.0,
            };
        };
        for_each_indexed(&work.solved, &mut work.start_energy, energy);
        contact_solver::prepare(
            &work.manifolds,
            start,
            &work.bodies,
            &self.contacts,
            &substeps.contact,
            (&mut work.contacts, &mut work.points),
        );
        let made = !self.blocks.fits(constraints, bodies);
        if made {
            self.blocks = JointBlocks::new(constraints, bodies);
        }
        self.relaxed_joints.resize(constraints.len(), false);
        if self.blocks.relax_marked(&self.relaxed_joints) || made {
            work.large_groups = self.blocks.large_group_constraints();
        }
        work.turns_inertia = !constraints.is_empty() || scene.grab.is_some();
        work.rows.clear();
        work.rows.extend(joint_solver::prepare(
            constraints,
            &work.large_groups,
            &self.joint_impulses,
        ));
        // Small islands are batched where the program's bodies are the contacts' alone.
        let batching = constraints.is_empty() && scene.grab.is_none() && !self.by_colour_only;
        self.small_islands.find(
            (&work.manifolds, &work.moving),
            bodies.len(),
            batching,
            (&mut work.solving, &mut work.selected),
        );
    }

    /// Restitution with its energy rule (the small islands' ran in their batches), velocities
    /// back into the bodies, sleep (the `grabbed` body's island kept awake), impulses kept.
    fn finish(
        &mut self,
        ctx: &StepContext,
        (bodies, constraints, start, grabbed): FinishedParts,
        h: f64,
        stats: &mut StepStats,
    ) {
        let w = &mut self.work;
        let rows = std::mem::take(&mut w.rows);
        let (blocks, sides) = (&mut self.blocks, &mut self.joint_sides);
        // A bound not yet reached may be closed within the next step, not a substep: the
        // velocities the pass leaves last that long (a rope slack by 0.008 at the end of the
        // step let a struck box sink at 2.4 units/s within substeps of dt / 4).
        let (poses, inv_h) = (&*bodies, 1.0 / ctx.settings.time_step);
        // The struck bodies' joints are held in the restitution pass for it alone: rows
        // copied, the groups' held sides put back, so the next step starts from what they
        // held before it.
        let (mut held_rows, mut kept_sides) = (None, None);
        let hold_joints = |solved: &mut [SolverBody], struck: &[bool]| {
            if constraints.is_empty() {
                return;
            }
            kept_sides.get_or_insert_with(|| sides.clone());
            blocks.hold_rates_of((poses, solved), sides, inv_h, struck);
            // (Rows on a struck body only: a chain solved row by row is held at its first
            // link; its groups, solved exactly, are held whole.)
            let on_struck = |r: &&JointRow| struck[r.body1] || struck[r.body2];
            let held = held_rows
                .get_or_insert_with(|| rows.iter().filter(on_struck).copied().collect::<Vec<_>>());
            joint_solver::solve(held, poses, solved, Softness::RIGID, inv_h, false, 0.0);
        };
        w.bounce(poses, constraints, (&ctx.settings, h), hold_joints);
        if let Some(kept) = kept_sides {
            *sides = kept;
        }
        w.rows = rows;
        for_each_indexed2(&w.moving, bodies, &mut w.bodies, |_, body, sb| {
            body.linear_velocity = sb.linear_velocity;
            body.angular_velocity = sb.angular_velocity;
        });
        if ctx.settings.sleep {
            let touching = sleep::touching_pairs(&w.manifolds);
            sleep::settle(
                &mut self.islands,
                bodies,
                &self.radii,
                start,
                constraints,
                touching,
                (ctx.settings.time_step, ctx.settings.gravity, grabbed),
            );
        }
        self.touched_sleepers.clear();
        if ctx.settings.sleep {
            let touched = self.islands.touched_sleepers();
            self.touched_sleepers.extend_from_slice(touched);
        }
        stats.asleep = bodies.iter().filter(|b| b.asleep).count();
        self.contacts
            .store(&w.manifolds, &w.contacts, &w.points, bodies);
        let count = w.rows.iter().map(|r| r.constraint + 1).max().unwrap_or(0);
        self.joint_impulses.clear();
        self.joint_impulses.resize(count, 0.0);
        for r in &w.rows {
            self.joint_impulses[r.constraint] = r.impulse;
        }
        stats.manifold_points = w.points.len();
    }

    /// From now on every island is solved colour by colour, none in batches.
    #[cfg(test)]
    pub(crate) fn solve_by_colour_only(&mut self) {
        self.by_colour_only = true;
    }

    /// The last step's manifolds solved in batches of small islands, and colour by colour.
    #[cfg(test)]
    pub(crate) fn batched_and_coloured(&self) -> (usize, usize) {
        let w = &self.work;
        let coloured = w.selected.as_ref().map_or(w.contacts.len(), Vec::len);
        (w.contacts.len() - coloured, coloured)
    }

    /// The manifolds of the last step (for display).
    pub fn manifolds(&self) -> &[Manifold] {
        &self.work.manifolds
    }
}

/// The substep program (kicks, warm starts, passes, drifts, the final pass) over one
/// workspace: the step's, colour by colour, or a batch of small islands copied into one of
/// its own ([`island_batch`]).
struct Solver<'a> {
    work: &'a mut Workspace,
    blocks: &'a mut JointBlocks,
    joint_sides: &'a mut HeldSides,
}

impl Solver<'_> {
    /// The solved bodies' substeps between the half kicks, then the final pass.
    fn solve_substeps(
        &mut self,
        ctx: &StepContext,
        (bodies, start): (&mut [RigidBody], &[(DVec3, DQuat)]),
        grab: Option<&Grab>,
        substeps: &Substeps,
        kicks: &Kicks,
    ) {
        self.work.record_velocities();
        self.work.kick(kicks.half);
        for k in 0..substeps.count {
            if k > 0 {
                self.work.kick(kicks.full);
            }
            if let Some(grab) = grab {
                pull(grab, bodies, &mut self.work.bodies, substeps.h);
            }
            if k == 0 {
                self.work.hold_back(0.5);
            }
            let last = k + 1 == substeps.count;
            self.substep(ctx, (bodies, start), substeps, last);
            if k == 0 {
                self.work.release();
            }
        }
        self.work.kick(kicks.half);
        self.final_pass(bodies, substeps);
    }

    /// Warm start, the soft pass, new poses, joints projected (in the `last` substep), the relax
    /// pass.
    ///
    /// The joint groups' positions are projected onto their bounds once per step, after the
    /// last drift, and in earlier substeps only where a row is far out (see
    /// [`MIDSTEP_PROJECTION_TOLERANCE`]): a projection moves poses without the velocity that
    /// would move them, and so takes energy with every correction; between projections the
    /// soft joint rows hold the bounds. Measured (`bench accuracy`, dt 0.04 ... 0.0025):
    /// projecting in every substep, the pendulum lost 6.6e-4 ... 4.1e-5 of its amplitude in
    /// 20 s (Rapier's rope: 6.7e-4 ... 4.1e-5); once per step, 1.7e-4 ... 1.0e-5, with the
    /// chains' worst stretch 1.2e-4 of the rest length at dt 0.04 (3.5e-5 before) and a
    /// quarter fewer group solves; never, at most 2.4e-6, but the chains stretched by 1e-2.
    fn substep(
        &mut self,
        ctx: &StepContext,
        (bodies, start): (&mut [RigidBody], &[(DVec3, DQuat)]),
        substeps: &Substeps,
        last: bool,
    ) {
        let w = &mut self.work;
        joint_solver::warm_start(&w.rows, bodies, &mut w.bodies);
        let (contacts, selected) = (
            (&mut w.contacts[..], &mut w.points[..]),
            w.selected.as_deref(),
        );
        contact_solver::warm_start(&w.colours, selected, contacts, &mut w.bodies);
        self.solve_pass(bodies, substeps, Pass::Soft);
        let w = &mut self.work;
        w.integrate_positions(ctx, (bodies, start), substeps.h);
        let tolerance = if last {
            0.0
        } else {
            MIDSTEP_PROJECTION_TOLERANCE
        };
        if self
            .blocks
            .project_positions((bodies, &w.bodies), self.joint_sides, tolerance)
        {
            w.update_deltas(bodies, start);
        }
        self.relax(bodies, substeps, Pass::Relax);
    }

    /// One pass over joints then contacts.
    ///
    /// The relax pass leaves the joint groups solved directly alone. Their solve is exact: it
    /// projects the velocities onto the held rows' targets (`v - M^-1 J^T K^-1 (J v - b)`),
    /// and the next pass at the same poses (the next substep's soft pass, or the final pass)
    /// projects again, so a projection between them changes nothing while the same rows are
    /// held (`P_b(P_0(v) + dv) = P_b(v + dv)` for the kick `dv` between them). Measured
    /// (`bench accuracy`): the pendulum's period and amplitude errors the same to 9 digits at
    /// every dt, the chains' worst stretch the same or lower (1.49e-6 -> 1.31e-6 at dt 0.04,
    /// 1.0e-8 -> 5.6e-9 at 0.0025), a chain step a tenth cheaper.
    fn solve_pass(&mut self, bodies: &[RigidBody], substeps: &Substeps, pass: Pass) {
        let (w, inv_h, soft) = (&mut self.work, substeps.inv_h, substeps.joint_softness);
        let biased = pass == Pass::Soft;
        if pass != Pass::Relax {
            self.blocks.solve_velocities(
                (bodies, &mut w.bodies),
                self.joint_sides,
                inv_h,
                biased.then_some(MAX_PUSH_SPEED),
            );
        }
        joint_solver::solve(
            &mut w.rows,
            bodies,
            &mut w.bodies,
            soft,
            inv_h,
            biased,
            MAX_PUSH_SPEED,
        );
        contact_solver::solve(
            (&w.colours, w.selected.as_deref()),
            (&mut w.contacts, &mut w.points),
            &mut w.bodies,
            &substeps.contact,
            (inv_h, pass, MAX_PUSH_SPEED),
        );
    }

    /// Passes without position correction: the velocities made rigid (see
    /// [`Substeps::relax_passes`]).
    fn relax(&mut self, bodies: &[RigidBody], substeps: &Substeps, pass: Pass) {
        for _ in 0..substeps.relax_passes {
            self.solve_pass(bodies, substeps, pass);
        }
    }

    /// A rigid pass after the last half kick, warm-started with half of every accumulated
    /// impulse (the support that half kick needs), so a resting stack ends the step at rest.
    fn final_pass(&mut self, bodies: &[RigidBody], substeps: &Substeps) {
        let w = &mut self.work;
        w.hold_back(0.5);
        joint_solver::warm_start(&w.rows, bodies, &mut w.bodies);
        let (contacts, selected) = (
            (&mut w.contacts[..], &mut w.points[..]),
            w.selected.as_deref(),
        );
        contact_solver::warm_start(&w.colours, selected, contacts, &mut w.bodies);
        self.relax(bodies, substeps, Pass::Final);
        self.work.release();
    }
}

/// Whether a manifold has a point touching or about to (within [`SPECULATIVE_DISTANCE`]): a
/// contact that may hold a load in this step. Points further apart are an approach, which the
/// speculative rows stop where the surfaces meet, rigidly, whatever the substeps.
fn touches(m: &Manifold) -> bool {
    m.points()
        .iter()
        .any(|p| p.separation <= SPECULATIVE_DISTANCE)
}

/// Whether nothing in the scene can move this step: no body awake, none grabbed, and no
/// constraints (their rows are prepared even between sleeping bodies).
fn at_rest(scene: &Scene) -> bool {
    scene.grab.is_none() && scene.constraints.is_empty() && !any_awake(scene.bodies)
}

/// Candidate pairs: bodies whose boxes, grown by their `margins` (how far they can travel this
/// step), overlap and whose bounding spheres so grown reach each other; pairs of sleeping
/// bodies left out. `again`: the step's second call, after waking (see
/// [`BroadPhase::speculative_pairs`]).
fn candidate_pairs(
    broad: &mut BroadPhase,
    (bodies, shapes): (&[RigidBody], &[Shape]),
    (radii, margins, dt, again): (&[f64], &[f64], f64, bool),
    stats: &mut StepStats,
) -> Vec<(u32, u32)> {
    let keep = |i: usize, j: usize| {
        let (a, b) = (&bodies[i], &bodies[j]);
        may_collide(a, b)
            && !(a.asleep && b.asleep)
            && spheres_reach(
                (a, radii[a.shape] + margins[i]),
                (b, radii[b.shape] + margins[j]),
            )
    };
    let (speculative, tested) = ((margins, dt, again), &mut stats.pairs_tested);
    broad.speculative_pairs(bodies, shapes, speculative, keep, tested)
}

/// Whether the bounding spheres of two bodies, each grown by its reach, overlap. The boxes of
/// tumbling bodies overlap at corners the spheres do not reach: in pile-10000 the spheres drop
/// half of the candidate pairs, and a pair they drop is further apart than the narrow phase
/// looks, so no manifold is lost.
fn spheres_reach((a, ra): (&RigidBody, f64), (b, rb): (&RigidBody, f64)) -> bool {
    let reach = ra + rb;
    (a.position - b.position).length_squared() <= reach * reach
}

/// The grab's impulse over a substep, on the solver's velocities.
fn pull(grab: &Grab, bodies: &[RigidBody], solver_bodies: &mut [SolverBody], h: f64) {
    let (Some(body), Some(sb)) = (bodies.get(grab.body), solver_bodies.get_mut(grab.body)) else {
        return;
    };
    let velocities = (sb.linear_velocity, sb.angular_velocity);
    if let Some((r, impulse)) = grab.impulse(body, velocities, h) {
        sb.apply(r, impulse);
    }
}

/// Gravity's velocity kicks of velocity Verlet: half a substep's at the ends of the step, a
/// whole one's between substeps.
struct Kicks {
    half: DVec3,
    full: DVec3,
}

impl Kicks {
    fn new(gravity: DVec3, h: f64) -> Self {
        Self {
            half: (0.5 * h) * gravity,
            full: h * gravity,
        }
    }
}

/// Records the pose body `b` begins the step at. A pose made non-finite by an edit between
/// steps is left out: the entry keeps the last finite pose, which the pose check restores.
#[inline]
fn record_start(start: &mut (DVec3, DQuat), b: &RigidBody) {
    if b.position.is_finite() && b.orientation.is_finite() {
        *start = (b.position, b.orientation);
    }
}

/// The substeps of the bodies nothing touches or holds, each on its own (in parallel): the
/// same kicks and drifts, in the same order, as the solver gives the others, so a body's
/// flight does not depend on whether it is solved. Each one's pose before them goes to
/// `start` (for sleeping) in the same pass: a pass of its own over 100,000 bodies took 1.7 ms
/// of scatter-100000's step, on one thread.
fn integrate_free(
    ctx: &StepContext,
    (bodies, start): (&mut [RigidBody], &mut [(DVec3, DQuat)]),
    free: &[bool],
    substeps: &Substeps,
    kicks: &Kicks,
) {
    let integrator = ctx.settings.rotation_integrator;
    let h = substeps.h;
    let items = (bodies, start, free).into_par_iter();
    parallel::for_each(items, 512, |(body, start, &free)| {
        if !free {
            return;
        }
        record_start(start, body);
        body.linear_velocity += kicks.half;
        for k in 0..substeps.count {
            if k > 0 {
                body.linear_velocity += kicks.full;
            }
            integrate_pose(body, integrator, h);
        }
        body.linear_velocity += kicks.half;
    });
}

impl Workspace {
    /// Adds `dv` to the velocity of every body the substeps integrate.
    fn kick(&mut self, dv: DVec3) {
        for_each_indexed(&self.solving, &mut self.bodies, |_, sb| {
            sb.linear_velocity += dv;
        });
    }

    /// Poses from the solved velocities (by the world's rotation integrator), and each body's
    /// displacement since the step began for the contacts' separations (only where the step has
    /// contact points: nothing reads it otherwise).
    ///
    /// Where the joints or a grab will read it ([`Workspace::turns_inertia`]), each body's world
    /// inverse inertia is turned with it. An impulse applied through the inertia of the step's
    /// start to a body that has since turned is not the one the turned body would feel, and
    /// the rotation integrators measure its energy and angular momentum with the turned
    /// inertia: a jointed body that spins gained energy from every substep. A bar of
    /// 2 x 0.4 x 0.4 spun at 10 rad/s and tethered by a rigid rod to a box in free flight,
    /// dt 0.04: 1.8 times its energy in 10 s with four substeps and 114 times with sixteen, its
    /// angular momentum off by 113 % and 1,000 %; turned, its energy never above the start and
    /// its angular momentum within 3.9 % and 0.12 % (tested). The contact rows keep what they
    /// were prepared with (their anchors and responses are those of the step's start, and
    /// the restitution's energy cap holds their bounces).
    fn integrate_positions(
        &mut self,
        ctx: &StepContext,
        (bodies, start): (&mut [RigidBody], &[(DVec3, DQuat)]),
        h: f64,
    ) {
        let (integrator, turns_inertia) = (ctx.settings.rotation_integrator, self.turns_inertia);
        let contacts = !self.points.is_empty();
        for_each_indexed2(&self.solving, bodies, &mut self.bodies, |i, body, sb| {
            let (p0, q0) = start[i];
            body.linear_velocity = sb.linear_velocity;
            body.angular_velocity = sb.angular_velocity;
            integrate_pose(body, integrator, h);
            // The angular-momentum integrator turns the angular velocity with the body.
            sb.angular_velocity = body.angular_velocity;
            // (Equal principal moments look the same from every orientation.)
            if turns_inertia && !body.inertia.is_isotropic() {
                sb.inverse_inertia = body.world_inverse_inertia();
            }
            if contacts {
                record_displacement(sb, body, (p0, q0));
            }
        });
    }

    /// Each solving body's displacement since the step began, for the contacts' separations
    /// (none to read without contact points).
    fn update_deltas(&mut self, bodies: &mut [RigidBody], start: &[(DVec3, DQuat)]) {
        if self.points.is_empty() {
            return;
        }
        for_each_indexed2(&self.solving, bodies, &mut self.bodies, |i, body, sb| {
            record_displacement(sb, body, start[i]);
        });
    }
}

/// The body's displacement from the pose its step began at, which the contact rows add to
/// their separations (the rows keep the step's start).
fn record_displacement(sb: &mut SolverBody, body: &RigidBody, (p0, q0): (DVec3, DQuat)) {
    sb.delta_position = body.position - p0;
    sb.delta_rotation = manifold::delta_rotation(q0, body.orientation);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::assets;

    /// The preset takes all four substeps from dt 0.01 up and proportionally fewer below, each
    /// at most 1/400 s long, down to two; more substeps asked for stay proportionally more; a
    /// length of 0 keeps the count at every step.
    #[test]
    fn short_steps_take_proportionally_fewer_substeps() {
        let with = |dt: f64, substeps: u32, full: f64| {
            let settings = crate::sim::Settings {
                time_step: dt,
                substeps,
                full_substeps_from: full,
                ..crate::sim::Settings::accurate()
            };
            short_step_substeps(&settings)
        };
        let preset = crate::sim::Settings::accurate().full_substeps_from;
        for (dt, count) in [
            (0.04, 4),
            (0.01, 4),
            (0.0099, 4),
            (0.0075, 3),
            (0.005, 2),
            (0.004, 2),
            (0.0025, 2),
            (1e-9, 2),
        ] {
            assert_eq!(with(dt, 4, preset), count, "dt {dt}");
        }
        assert_eq!((with(0.005, 8, preset), with(0.0025, 8, preset)), (4, 4));
        assert_eq!((with(0.001, 1, preset), with(0.001, 3, preset)), (1, 2));
        assert_eq!((with(0.0025, 4, 0.0), with(0.001, 3, 0.0)), (4, 3));
        // A length typed as nonsense means all of them.
        for typed in [f64::NAN, f64::INFINITY, -0.01] {
            let settings = crate::sim::Settings {
                full_substeps_from: typed,
                ..crate::sim::Settings::accurate()
            };
            assert_eq!(settings.sanitized().full_substeps_from, 0.0, "{typed}");
        }
    }

    /// The bounding-sphere filter drops only pairs the narrow phase finds nothing for: bodies of
    /// the three generated shapes at random orientations and distances around touching.
    #[test]
    fn sphere_filter_keeps_every_pair_with_a_manifold() {
        let shapes: Vec<Shape> = [
            assets::cuboid(DVec3::new(1.5, 0.75, 1.0)),
            assets::tetrahedron(1.5),
            assets::octahedron(DVec3::splat(1.2)),
        ]
        .iter()
        .map(|mesh| Shape::from_tet_mesh(mesh).unwrap())
        .collect();
        let radii: Vec<f64> = shapes.iter().map(|s| s.bounding_radius()).collect();
        let mut rng = crate::sim::rng::Rng::new(7);
        let mut next = move || rng.unit();
        let (mut found, mut filtered) = (0, 0);
        for k in 0..4000 {
            let (s1, s2) = (k % 3, (k / 3) % 3);
            let turn = |v: DVec3| DQuat::from_scaled_axis(3.0 * v);
            let mut unit = || DVec3::new(next(), next(), next()) * 2.0 - DVec3::ONE;
            let direction = unit().normalize_or(DVec3::X);
            let (q1, q2) = (turn(unit()), turn(unit()));
            let distance = (radii[s1] + radii[s2]) * (0.3 + next());
            let a = RigidBody::on_shape(&shapes[s1], s1, 1.0, false, DVec3::ZERO, q1);
            let b = RigidBody::on_shape(&shapes[s2], s2, 1.0, false, direction * distance, q2);
            let prediction = 0.2 * next();
            let mut state = manifold::PairState::default();
            let touches = body_manifold((0, &a), (1, &b), &shapes, (prediction, 0.02), &mut state);
            let half = 0.5 * prediction;
            let kept = spheres_reach((&a, radii[s1] + half), (&b, radii[s2] + half));
            found += usize::from(touches.is_some());
            filtered += usize::from(!kept);
            assert!(
                kept || touches.is_none(),
                "pair {k} dropped with a manifold"
            );
        }
        assert!(found > 500 && filtered > 300, "{found} {filtered}");
    }
}
