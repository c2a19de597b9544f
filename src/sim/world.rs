//! The world owns bodies, shapes and constraints in flat arrays addressed by index, and advances
//! them with [`World::step`], which reads as the list of its stages.

use super::aabb::{Aabb, body_aabb};
use super::body::{RigidBody, any_awake};
use super::broad_phase::BroadPhase;
use super::clock::SimClock;
use super::constraint::DistanceConstraint;
use super::coursework::contact_stage::{
    Bodies, ContactStage, contact_between, resolve_ground_contacts,
};
use super::coursework::schedule::solve_constraints;
use super::grab::Grab;
use super::integrate::integrate_bodies;
use super::narrow_phase::{Contact, ground_contact};
use super::quarantine::Quarantine;
use super::settings::{Settings, Solver};
use super::shape::Shape;
use super::soft_step::{Scene, SoftStep};
use super::stats::{Stage, StepStats, Stopwatch};
use super::step_context::StepContext;
use glam::DVec3;

/// Scenes with this many bodies step inside the thread pool (see [`World::step`]).
const IN_POOL_BODIES: usize = 64;

#[derive(Debug, Clone)]
pub struct World {
    /// Meshes, each shared by every body that uses it.
    pub shapes: Vec<Shape>,
    /// Where each shape came from (file name), for display.
    pub shape_names: Vec<String>,
    pub bodies: Vec<RigidBody>,
    pub constraints: Vec<DistanceConstraint>,
    pub settings: Settings,
    /// Simulated seconds so far (counted in steps, see [`SimClock`]).
    pub time: f64,
    pub step_count: u64,
    /// Notes from loading (ignored constraints, ...), for the user.
    pub warnings: Vec<String>,
    /// The files on disk the world was read from (scene, meshes, constraints; none for a
    /// built-in or generated scene): what no output of a run may replace.
    pub inputs: Vec<std::path::PathBuf>,
    /// A point of a body pulled towards a target (the viewer's mouse drag), by both solvers.
    pub grab: Option<Grab>,
    /// Whether [`World::step`] times its stages ([`StepStats::timings`]; on by default, for the
    /// viewer's and `tumble run`'s stage figures). Off, a step reads no clock: its eight or so
    /// reads are 8-10 % of a two-body step (the box hung by a corner, `bench accuracy`, which
    /// turns them off as Rapier's counters are compiled out by default).
    pub time_stages: bool,
    /// `constraints_by_body[b]`: the constraints on body b.
    constraints_by_body: Vec<Vec<u32>>,
    broad_phase: BroadPhase,
    contact_stage: ContactStage,
    soft_step: SoftStep,
    quarantine: Quarantine,
    /// Whether bodies may be flagged asleep for the coursework's step to wake: a soft step
    /// ran, or a state was restored, since its last step.
    may_sleep: bool,
    clock: SimClock,
}

impl World {
    pub fn new(
        shapes: Vec<Shape>,
        shape_names: Vec<String>,
        bodies: Vec<RigidBody>,
        constraints: Vec<DistanceConstraint>,
        settings: Settings,
    ) -> World {
        let mut constraints_by_body = vec![Vec::new(); bodies.len()];
        for (index, c) in constraints.iter().enumerate() {
            constraints_by_body[c.body1].push(index as u32);
            constraints_by_body[c.body2].push(index as u32);
        }
        World {
            broad_phase: BroadPhase::new(&bodies, &shapes),
            quarantine: Quarantine::new(&bodies),
            contact_stage: ContactStage::default(),
            soft_step: SoftStep::default(),
            may_sleep: false,
            shapes,
            shape_names,
            bodies,
            constraints,
            settings,
            time: 0.0,
            step_count: 0,
            clock: SimClock::default(),
            warnings: Vec::new(),
            inputs: Vec::new(),
            grab: None,
            time_stages: true,
            constraints_by_body,
        }
    }

    /// Runs `steps`, a loop of this world's steps, where [`World::step`] runs each step: in the
    /// thread pool for a scene of [`IN_POOL_BODIES`] bodies or more, so the loop hands its work
    /// over once instead of once a step (each hand-over wakes an idle core: 40-105 us on a 2-core
    /// virtual machine, see [`super::parallel::in_pool`]); a smaller scene's steps never hand
    /// over, so its loop stays on this thread.
    pub fn stepping<R: Send>(&mut self, steps: impl FnOnce(&mut World) -> R + Send) -> R {
        if self.bodies.len() >= IN_POOL_BODIES {
            super::parallel::in_pool(|| steps(self))
        } else {
            steps(self)
        }
    }

    /// One time step by the world's solver.
    pub fn step(&mut self) -> StepStats {
        if self.bodies.len() >= IN_POOL_BODIES
            && rayon::current_thread_index().is_none()
            && any_awake(&self.bodies)
        {
            // From outside the thread pool every parallel loop that splits would hand its work
            // over cold (wake a worker, wait on it); inside it they split hot. One hand-over per
            // step instead of one per loop (pile-200 under the soft step: three passes of every
            // colour per substep, four where the substep clamps the contacts; sparse-1000 under
            // the coursework solver: 40 % of a one-thread step was spent switching threads). A
            // scene with nothing awake stays here: its step has no loop to split. A loop of many
            // steps is better run in the pool as a whole ([`World::stepping`]): each hand-over
            // here wakes an idle core.
            return rayon::scope(|_| self.step());
        }
        let ctx = StepContext::new(&self.settings, self.constraints.len());
        let stats = match ctx.settings.solver {
            Solver::Coursework => self.coursework_step(&ctx),
            Solver::SoftStep => self.soft_step(&ctx),
        };
        self.count_step(ctx.settings.time_step);
        stats
    }

    /// Counts one step of `dt` in [`World::time`] and [`World::step_count`] (also for a loop
    /// that moves the bodies by other means, as the bench's Rapier runs do). A `dt` that is not
    /// finite or is negative counts as none, as the step itself takes it ([`Settings`]'s
    /// sanitizing): the time holds, and goes on from there once the step is valid again.
    pub fn count_step(&mut self, dt: f64) {
        let dt = super::settings::step_length(dt);
        self.time = self.clock.advance(self.time, dt);
        self.step_count += 1;
    }

    /// The step's stage timer: on or off as [`World::time_stages`] says.
    fn stopwatch(&self) -> Stopwatch {
        if self.time_stages {
            Stopwatch::new()
        } else {
            Stopwatch::off()
        }
    }

    /// The coursework solver: with substeps, its whole update runs `substeps` times with
    /// `dt / substeps`.
    fn coursework_step(&mut self, ctx: &StepContext) -> StepStats {
        // The coursework's method never sleeps: bodies the soft step put to sleep before a
        // switch of solver are awake again (still flagged, they moved under this step but the
        // pose check passed them over: a NaN went unreported; found by the world fuzz target).
        // Looked for only after a soft step: the pass reads every body.
        if std::mem::take(&mut self.may_sleep) {
            for body in self.bodies.iter_mut().filter(|b| b.asleep) {
                body.wake();
            }
        }
        let mut stats = StepStats::default();
        for _ in 0..ctx.settings.substeps {
            let sub = self.substep(ctx);
            stats.accumulate(sub);
        }
        stats
    }

    /// The soft-step solver's state (for tests of its parts).
    #[cfg(test)]
    pub(crate) fn soft_step_mut(&mut self) -> &mut SoftStep {
        &mut self.soft_step
    }

    /// The soft-step solver: collide once, solve and integrate in substeps, then the pose check.
    fn soft_step(&mut self, ctx: &StepContext) -> StepStats {
        self.may_sleep = true;
        let mut stats = StepStats::default();
        let mut watch = self.stopwatch();
        // A grab of a body that is not there pulls nothing (as in the coursework's step).
        let count = self.bodies.len();
        let scene = Scene {
            start: self.quarantine.step_start(&self.bodies),
            bodies: &mut self.bodies,
            shapes: &self.shapes,
            constraints: &self.constraints,
            grab: self.grab.as_ref().filter(|g| g.body < count),
        };
        self.soft_step
            .step(ctx, scene, &mut self.broad_phase, &mut watch, &mut stats);
        watch.enter(Stage::PoseCheck);
        self.quarantine
            .check(&mut self.bodies, &mut stats.quarantined);
        stats.timings = watch.finish();
        stats
    }

    /// The coursework's update: integrate, body contacts (broad phase, narrow phase, resolution),
    /// ground contacts, constraints, then the pose check.
    fn substep(&mut self, ctx: &StepContext) -> StepStats {
        let mut stats = StepStats {
            substeps: 1,
            ..StepStats::default()
        };
        let mut watch = self.stopwatch();
        watch.enter(Stage::Integrate);
        integrate_bodies(&mut self.bodies, &ctx.settings, ctx.dt);
        if let Some(grab) = &self.grab {
            grab.apply(&mut self.bodies, ctx.dt);
        }
        let bodies = Bodies {
            bodies: &mut self.bodies,
            shapes: &self.shapes,
        };
        let broad_phase = &mut self.broad_phase;
        self.contact_stage
            .resolve_body_contacts(ctx, bodies, broad_phase, &mut watch, &mut stats);
        watch.enter(Stage::Ground);
        let bodies = Bodies {
            bodies: &mut self.bodies,
            shapes: &self.shapes,
        };
        resolve_ground_contacts(ctx, bodies, self.broad_phase.boxes(), &mut stats);
        if !self.constraints.is_empty() {
            watch.enter(Stage::Constraints);
            let report = solve_constraints(
                ctx,
                &self.constraints,
                &self.constraints_by_body,
                &mut self.bodies,
            );
            stats.constraint_visits = report.visits;
            stats.constraint_corrections = report.corrections;
            stats.budget_hit = report.budget_hit;
        }
        watch.enter(Stage::PoseCheck);
        self.quarantine
            .check(&mut self.bodies, &mut stats.quarantined);
        stats.timings = watch.finish();
        stats
    }

    /// Wakes body `index` and the island it fell asleep in (soft step; a body awake, or out of
    /// range, changes nothing): for a body the viewer grabs or moves while paused, which the
    /// step would not see moved.
    pub fn wake_island(&mut self, index: usize) {
        if index < self.bodies.len() {
            self.soft_step
                .wake_island(&mut self.bodies, &self.constraints, index);
        }
    }

    /// Everything a later step depends on, to come back to it exactly ([`World::restore`]).
    pub fn snapshot(&self) -> WorldState {
        WorldState {
            bodies: self.bodies.clone(),
            time: self.time,
            step_count: self.step_count,
            clock: self.clock,
            soft_step: self.soft_step.carried(),
            quarantine: self.quarantine.clone(),
        }
    }

    /// Back to a snapshot of this world: the steps after it repeat bit for bit.
    pub fn restore(&mut self, state: &WorldState) {
        self.bodies.clone_from(&state.bodies);
        self.time = state.time;
        self.step_count = state.step_count;
        self.clock = state.clock;
        self.soft_step.restore(&state.soft_step);
        self.quarantine.clone_from(&state.quarantine);
        self.may_sleep = true;
    }

    /// Current world-space vertices of one body (the coursework's `currV`), computed on demand.
    pub fn current_vertices(&self, index: usize) -> Vec<DVec3> {
        let body = &self.bodies[index];
        self.shapes[body.shape]
            .rest_vertices
            .iter()
            .map(|&v| body.world_point(v))
            .collect()
    }

    /// Kinetic plus potential energy of the movable bodies (frozen ones apart: see
    /// [`World::frozen_energy`]).
    pub fn total_energy(&self) -> f64 {
        let g = self.settings.gravity;
        self.bodies
            .iter()
            .filter(|b| !b.quarantined)
            .map(|b| b.energy(g))
            .sum()
    }

    /// Potential energy of the bodies frozen by the pose check, at their last finite pose.
    pub fn frozen_energy(&self) -> f64 {
        let g = self.settings.gravity;
        let frozen = self.bodies.iter().filter(|b| b.quarantined);
        // An empty sum of floats is -0.0, which summaries printed as "-0.0" with nothing frozen.
        frozen.map(|b| b.energy(g)).sum::<f64>() + 0.0
    }

    /// Largest distance by which any constraint lies outside its bound.
    pub fn max_constraint_violation(&self) -> f64 {
        self.worst_constraint_violations().0
    }

    /// The largest distance by which any constraint lies outside its bound, and the largest
    /// violation as a share of its constraint's rest length (not necessarily the same
    /// constraint's; points placed together have no share), in one pass.
    pub fn worst_constraint_violations(&self) -> (f64, f64) {
        self.constraints
            .iter()
            .fold((0.0f64, 0.0f64), |(absolute, relative), c| {
                let violation = c.violation(&self.bodies);
                let share = c.share_of_rest_length(violation);
                (absolute.max(violation), relative.max(share))
            })
    }

    pub fn all_finite(&self) -> bool {
        self.bodies.iter().all(|b| b.is_finite())
    }

    /// Contacts at the current poses: (body1, body2 or None for the ground, contact), for the
    /// contact display, the bench's depths and the scene loader's check of bodies that start
    /// inside another. Detection only, through a broad phase of its own; nothing is resolved.
    pub fn current_contacts(&self) -> Vec<(usize, Option<usize>, Contact)> {
        let (bodies, shapes) = (&self.bodies, &self.shapes);
        let mut broad = self.broad_phase.clone();
        let mut queue = broad.candidate_pairs((bodies, shapes), 0.0, &mut Vec::new(), &mut 0);
        let patches = self.settings.patch_gravity();
        let mut out = Vec::new();
        while let Some(((i, j), _)) = queue.pop() {
            if broad.overlap(i, j)
                && let Some(c) = contact_between(bodies, shapes, i, j, patches).contact
            {
                out.push((i, Some(j), c));
            }
        }
        for (i, body) in bodies.iter().enumerate() {
            if body.is_dynamic()
                && broad.boxes()[i].min.y <= 0.0
                && let Some(c) = ground_contact(body, &shapes[body.shape], patches.is_some())
            {
                out.push((i, None, c));
            }
        }
        out
    }

    /// Contact points to draw, as (point, unit normal): for the coursework solver the contacts
    /// at the current poses; for the soft step the points of the last step's manifolds that
    /// touch or are about to (within 0.01 units).
    pub fn display_contacts(&self) -> Vec<(DVec3, DVec3)> {
        match self.settings.solver {
            Solver::Coursework => self
                .current_contacts()
                .into_iter()
                .map(|(_, _, c)| (c.point2, c.normal))
                .collect(),
            Solver::SoftStep => self
                .soft_step
                .manifolds()
                .iter()
                .flat_map(|m| {
                    m.points()
                        .iter()
                        .filter(|p| p.separation <= 0.01)
                        .map(move |p| (p.point, m.normal))
                })
                .collect(),
        }
    }

    /// World boxes of all bodies (computed from poses).
    pub fn body_aabbs(&self) -> Vec<Aabb> {
        self.bodies
            .iter()
            .map(|b| body_aabb(b, &self.shapes[b.shape]))
            .collect()
    }
}

/// A world's state at one step: poses, velocities, time, and what the solvers carry from one
/// step to the next (warm-start impulses, last finite poses).
#[derive(Debug, Clone)]
pub struct WorldState {
    bodies: Vec<RigidBody>,
    time: f64,
    step_count: u64,
    clock: SimClock,
    soft_step: super::soft_step::Carried,
    quarantine: Quarantine,
}

impl WorldState {
    /// Simulated seconds at this state.
    pub fn time(&self) -> f64 {
        self.time
    }

    pub fn step_count(&self) -> u64 {
        self.step_count
    }

    /// Approximate heap bytes the snapshot holds (for bounding a history by memory).
    pub fn heap_bytes(&self) -> usize {
        self.bodies.capacity() * std::mem::size_of::<RigidBody>()
            + self.soft_step.heap_bytes()
            + self.quarantine.heap_bytes()
    }
}
