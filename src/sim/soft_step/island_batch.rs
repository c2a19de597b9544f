//! Small islands solved in batches of their own. The colour-by-colour passes stream every
//! contact row, point and solver body through memory some fifteen times a step (each substep's
//! warm start, soft and relax passes, and the final pass); where those do not fit the cache
//! (scatter-100000: some 60 MB), every pass waits on memory. An island of a few bodies shares
//! nothing with the others, so its whole substep program can run while its rows are in cache:
//! the step's small islands are copied, a batch of them at a time, into a workspace of their
//! own, solved there by the same program ([`Solver`]), restitution pass and energy rule
//! ([`Workspace::bounce`]: a bounce's groups lie within its island) and copied back, as the
//! island solvers of PhysX and Bullet solve one island at a time (Box2D v3 colours everything).
//!
//! The result is the colour-by-colour passes' bits: a batch keeps its constraints in the
//! colouring's order (ascending index), which within an island is the order the colours'
//! passes visit them in, and islands share no moving body, constraint or point, so no pass of
//! one reads what another wrote.

use super::constraint_graph::Shared;
use super::contact_solver::{ContactConstraint, ContactPoint};
use super::disjoint_sets::DisjointSets;
use super::joint_block::{HeldSides, JointBlocks};
use super::manifold::{GROUND, Manifold};
use super::solver_body::SolverBody;
use super::{Kicks, Solver, Substeps, Workspace};
use crate::sim::body::RigidBody;
use crate::sim::step_context::StepContext;
use glam::{DQuat, DVec3};
use rayon::prelude::*;

/// Most manifolds of an island solved in a batch: larger islands go colour by colour, where
/// the threads share them.
const ISLAND_MANIFOLDS: u32 = 64;

/// Manifolds a batch gathers (of whole islands): enough that the program's costs per call are
/// shared among many rows, few enough that its rows stay in a core's cache (a manifold with
/// its points and bodies is about a kilobyte).
const BATCH_MANIFOLDS: u32 = 128;

/// Runs of batches (one workspace each) per thread.
const RUNS_PER_THREAD: usize = 4;

/// No batch: an island too large, or a body in none.
const NONE: u32 = u32::MAX;

/// The step's small islands, in batches of whole islands: each batch's manifolds (ascending
/// indices) and moving bodies (ascending).
#[derive(Debug, Clone, Default)]
pub struct SmallIslands {
    sets: DisjointSets,
    /// Per body: whether the solver moves it.
    is_moving: Vec<bool>,
    /// Per manifold: its island (root body) or [`NONE`]; then per moving body, its batch.
    island_of: Vec<u32>,
    /// Per root body: its island's manifolds.
    count: Vec<u32>,
    /// Per root body: its island's batch, or [`NONE`].
    batch_of: Vec<u32>,
    manifolds: Vec<u32>,
    manifold_ends: Vec<usize>,
    bodies: Vec<usize>,
    body_ends: Vec<usize>,
    /// Workspaces for runs of batches, kept from step to step (made anew in every step they
    /// were grown again: reallocations took 1 % of scatter-10000's step).
    workspaces: Vec<Batch>,
}

/// The step's arrays a batch is copied from and back into.
pub struct Arrays<'a> {
    pub bodies: &'a mut [RigidBody],
    pub start: &'a [(DVec3, DQuat)],
    /// Each moving body's energy when the step began.
    pub start_energy: &'a [f64],
    pub solver_bodies: &'a mut [SolverBody],
    pub contacts: &'a mut [ContactConstraint],
    pub points: &'a mut [ContactPoint],
}

/// [`Arrays`] shared by the threads solving batches: each batch touches only its own moving
/// bodies, constraints and points, and reads the static bodies, which no batch writes.
struct SharedArrays<'a> {
    bodies: Shared<'a, RigidBody>,
    start: &'a [(DVec3, DQuat)],
    start_energy: &'a [f64],
    solver_bodies: Shared<'a, SolverBody>,
    contacts: Shared<'a, ContactConstraint>,
    points: Shared<'a, ContactPoint>,
}

impl SmallIslands {
    /// Finds the step's contact islands (moving bodies joined by manifolds) and batches the
    /// small ones; the moving bodies and constraints left to the colour-by-colour passes go to
    /// `solving` and `selected` (`None`: all of them). With `batching` off, all are left.
    pub fn find(
        &mut self,
        (manifolds, moving): (&[Manifold], &[usize]),
        n: usize,
        batching: bool,
        (solving, selected): (&mut Vec<usize>, &mut Option<Vec<u32>>),
    ) {
        self.manifold_ends.clear();
        self.body_ends.clear();
        solving.clear();
        *selected = None;
        if batching && !moving.is_empty() {
            self.join_islands((manifolds, moving), n);
            self.batch_islands();
        }
        if self.manifold_ends.is_empty() {
            solving.extend_from_slice(moving);
            return;
        }
        *selected = Some(self.sort_manifolds());
        self.sort_bodies(moving, solving);
    }

    /// Joins the moving bodies of each manifold (the colouring's: awake, not the ground; those
    /// of `moving`), then finds each manifold's island (the root of its first moving body,
    /// [`NONE`] with none) and counts each island's manifolds.
    fn join_islands(&mut self, (manifolds, moving): (&[Manifold], &[usize]), n: usize) {
        self.is_moving.clear();
        self.is_moving.resize(n, false);
        for &i in moving {
            self.is_moving[i] = true;
        }
        // One read of the manifolds (a cache line each, 6 MB at scatter-100000): each one's
        // first moving body is kept in `island_of` and turned into its root after the joins.
        let is_moving = &self.is_moving;
        let mover = |i: usize| i != GROUND && is_moving[i];
        self.sets.reset(n);
        self.island_of.clear();
        for m in manifolds {
            let (a, b) = (mover(m.body1), mover(m.body2));
            if a && b {
                self.sets.join(m.body1, m.body2);
            }
            self.island_of.push(match (a, b) {
                (true, _) => m.body1 as u32,
                (false, true) => m.body2 as u32,
                (false, false) => NONE,
            });
        }
        self.count.clear();
        self.count.resize(n, 0);
        for island in self.island_of.iter_mut().filter(|i| **i != NONE) {
            let root = self.sets.root(*island as usize);
            self.count[root] += 1;
            *island = root as u32;
        }
    }

    /// Puts each small island, in the order of its first manifold, into the open batch, or a
    /// new one where it would take the open one past [`BATCH_MANIFOLDS`]; `manifold_ends`
    /// holds each batch's count of manifolds.
    fn batch_islands(&mut self) {
        self.batch_of.clear();
        self.batch_of.resize(self.count.len(), NONE);
        let mut open = 0;
        for &island in self.island_of.iter().filter(|&&i| i != NONE) {
            let (count, batch) = (
                self.count[island as usize],
                &mut self.batch_of[island as usize],
            );
            if count > ISLAND_MANIFOLDS || *batch != NONE {
                continue;
            }
            if self.manifold_ends.is_empty() || open + count > BATCH_MANIFOLDS {
                self.manifold_ends.push(0);
                open = 0;
            }
            open += count;
            *batch = (self.manifold_ends.len() - 1) as u32;
            *self.manifold_ends.last_mut().unwrap() += count as usize;
        }
    }

    /// Each batch's manifolds in ascending order; returns the others.
    fn sort_manifolds(&mut self) -> Vec<u32> {
        let batch_of = &self.batch_of;
        let batch = |island: u32| match island {
            NONE => NONE,
            i => batch_of[i as usize],
        };
        let items = (self.island_of.iter().enumerate()).map(|(k, &i)| (batch(i), k as u32));
        let mut rest = Vec::new();
        group_by_batch(
            items,
            &mut self.manifold_ends,
            &mut self.manifolds,
            &mut rest,
        );
        rest
    }

    /// Each batch's moving bodies in ascending order; the others go to `rest`.
    fn sort_bodies(&mut self, moving: &[usize], rest: &mut Vec<usize>) {
        self.body_ends.clear();
        self.body_ends.resize(self.manifold_ends.len(), 0);
        self.island_of.clear();
        for &i in moving {
            let batch = self.batch_of[self.sets.root(i)];
            self.island_of.push(batch);
            if batch != NONE {
                self.body_ends[batch as usize] += 1;
            }
        }
        let items = self.island_of.iter().copied().zip(moving.iter().copied());
        group_by_batch(items, &mut self.body_ends, &mut self.bodies, rest);
    }

    /// Batch `k`'s manifolds and moving bodies.
    fn batch(&self, k: usize) -> (&[u32], &[usize]) {
        let start = |ends: &[usize]| if k == 0 { 0 } else { ends[k - 1] };
        (
            &self.manifolds[start(&self.manifold_ends)..self.manifold_ends[k]],
            &self.bodies[start(&self.body_ends)..self.body_ends[k]],
        )
    }

    /// Solves every batch: copied into a workspace of its own, through the substeps and the
    /// restitution pass with its energy rule, and back; on all threads (each batch on one).
    pub fn solve(&mut self, ctx: &StepContext, arrays: Arrays, substeps: &Substeps, kicks: &Kicks) {
        let batches = self.manifold_ends.len();
        if batches == 0 {
            return;
        }
        let at = SharedArrays {
            bodies: Shared::new(arrays.bodies),
            start: arrays.start,
            start_energy: arrays.start_energy,
            solver_bodies: Shared::new(arrays.solver_bodies),
            contacts: Shared::new(arrays.contacts),
            points: Shared::new(arrays.points),
        };
        // Runs of batches, a few per thread for balance (which runs there are changes no bit).
        let runs = batches.min(RUNS_PER_THREAD * rayon::current_num_threads());
        let mut workspaces = std::mem::take(&mut self.workspaces);
        workspaces.resize_with(runs, Batch::default);
        let this = &*self;
        workspaces
            .par_iter_mut()
            .enumerate()
            .for_each(|(r, batch)| {
                for k in batches * r / runs..batches * (r + 1) / runs {
                    let island = this.batch(k);
                    // SAFETY: batches share no moving body, constraint or point (see the module's
                    // documentation), and the static bodies are only read.
                    unsafe { batch.gather(island, &at) };
                    batch.solve(ctx, substeps, kicks);
                    unsafe { batch.scatter(island, &at) };
                }
            });
        self.workspaces = workspaces;
    }
}

/// A counting sort by batch: each `(batch, item)` goes into `out`, grouped by batch in the
/// items' order, or to `rest` where its batch is [`NONE`]. `ends` holds each batch's count of
/// items on entry, and where each batch's items end in `out` on return.
fn group_by_batch<T: Copy + Default>(
    items: impl Iterator<Item = (u32, T)>,
    ends: &mut [usize],
    out: &mut Vec<T>,
    rest: &mut Vec<T>,
) {
    let mut next = Vec::with_capacity(ends.len());
    let mut end = 0;
    for count in ends.iter_mut() {
        next.push(end);
        end += *count;
        *count = end;
    }
    out.clear();
    out.resize(end, T::default());
    for (batch, item) in items {
        match batch {
            NONE => rest.push(item),
            b => {
                out[next[b as usize]] = item;
                next[b as usize] += 1;
            }
        }
    }
}

/// One thread's copy of a batch: its moving bodies first (in the batch's order), then the
/// static ones its constraints reach.
#[derive(Debug, Clone, Default)]
struct Batch {
    work: Workspace,
    bodies: Vec<RigidBody>,
    start: Vec<(DVec3, DQuat)>,
    /// The step's indices of the static solver bodies, after the moving ones.
    statics: Vec<usize>,
    /// No distance constraints in a batch: empty.
    blocks: JointBlocks,
    joint_sides: HeldSides,
}

impl Batch {
    /// Copies a batch's bodies, constraints and points out of the step's arrays.
    ///
    /// # Safety
    /// No other thread touches the batch's moving bodies, constraints or points meanwhile, or
    /// writes the static bodies they reach.
    unsafe fn gather(&mut self, (manifolds, moving): (&[u32], &[usize]), at: &SharedArrays) {
        let w = &mut self.work;
        w.bodies.clear();
        w.start_energy.clear();
        self.bodies.clear();
        self.start.clear();
        self.statics.clear();
        for &i in moving {
            // SAFETY: the caller's contract.
            unsafe {
                w.bodies.push(at.solver_bodies.read(i));
                self.bodies.push(at.bodies.get(i).clone());
            }
            self.start.push(at.start[i]);
            w.start_energy.push(at.start_energy[i]);
        }
        w.contacts.clear();
        w.points.clear();
        for &k in manifolds {
            // SAFETY: the caller's contract.
            let c = unsafe { at.contacts.read(k as usize) };
            let (i, j) = c.bodies();
            let mut local = |i: usize| match moving.binary_search(&i) {
                Ok(k) => k,
                Err(_) => moving.len() + static_slot(i, &mut self.statics, &mut w.bodies, at),
            };
            let ends = (local(i), local(j));
            let first = w.points.len();
            // SAFETY: the caller's contract.
            w.points
                .extend_from_slice(unsafe { at.points.slice(c.points()) });
            w.contacts.push(c.relocated(ends, first));
        }
        w.colours.sequential(w.contacts.len());
        w.solving.clear();
        w.solving.extend(0..moving.len());
        w.selected = None;
        w.rows.clear();
        w.turns_inertia = false;
    }

    /// The substeps, then the restitution pass and its energy rule, of the batch gathered: the
    /// colour-by-colour passes' bits (see the module's documentation; an island's bouncing
    /// groups are within it), while its rows and bodies are in cache (the colours' pass over
    /// scatter-100000's bouncing constraints streamed them in again eight times, and the
    /// energy rule read bodies all over the step's arrays).
    fn solve(&mut self, ctx: &StepContext, substeps: &Substeps, kicks: &Kicks) {
        let mut solver = Solver {
            work: &mut self.work,
            blocks: &mut self.blocks,
            joint_sides: &mut self.joint_sides,
        };
        let bodies = (&mut self.bodies[..], &self.start[..]);
        solver.solve_substeps(ctx, bodies, None, substeps, kicks);
        // (`solving` is the batch's moving bodies, `selected` all its constraints: see
        // `gather`.)
        self.work
            .bounce(&self.bodies, &[], (&ctx.settings, substeps.h), |_, _| {});
    }

    /// Copies the solved bodies, constraints and points back.
    ///
    /// # Safety
    /// As [`Batch::gather`]'s.
    unsafe fn scatter(&self, (manifolds, moving): (&[u32], &[usize]), at: &SharedArrays) {
        let w = &self.work;
        for (k, &i) in moving.iter().enumerate() {
            // SAFETY: the caller's contract.
            unsafe {
                at.solver_bodies.write(i, w.bodies[k]);
                at.bodies.get_mut(i).clone_from(&self.bodies[k]);
            }
        }
        for (c, &k) in w.contacts.iter().zip(manifolds) {
            // SAFETY: the caller's contract.
            let step = unsafe { at.contacts.get_mut(k as usize) };
            let points = unsafe { at.points.slice(step.points()) };
            points.copy_from_slice(&w.points[c.points()]);
            *step = c.relocated(step.bodies(), step.points().start);
        }
    }
}

/// The place of static body `i` among a batch's `statics`, copied in at its first use.
fn static_slot(
    i: usize,
    statics: &mut Vec<usize>,
    bodies: &mut Vec<SolverBody>,
    at: &SharedArrays,
) -> usize {
    if let Some(k) = statics.iter().position(|&s| s == i) {
        return k;
    }
    statics.push(i);
    // SAFETY: static bodies are never written while batches run.
    bodies.push(unsafe { at.solver_bodies.read(i) });
    statics.len() - 1
}

#[cfg(test)]
mod tests {
    use crate::scene::generate;
    use crate::sim::Settings;

    /// Small islands solved in batches give the bits of the colour-by-colour passes: scatter
    /// (islands of one to four bodies, landing and bouncing; at e = 1 still bouncing), and a
    /// pile, whose heap is one island too large for a batch beside small ones. Positions,
    /// orientations and both velocities of every body after every step.
    #[test]
    fn batched_islands_give_the_bits_of_the_colours() {
        for (family, n, steps, restitution) in [
            ("scatter", 400, 240, 0.2),
            ("scatter", 300, 120, 1.0),
            ("pile", 200, 200, 0.2),
        ] {
            let settings = Settings {
                restitution,
                ..Settings::accurate()
            };
            let run = |by_colour: bool| {
                let mut world = generate::by_name(family, n, settings.clone()).unwrap();
                if by_colour {
                    world.soft_step_mut().solve_by_colour_only();
                }
                let (mut states, mut most) = (Vec::new(), (0, 0));
                for _ in 0..steps {
                    world.step();
                    let (batched, coloured) = world.soft_step_mut().batched_and_coloured();
                    most = (most.0.max(batched), most.1.max(coloured));
                    for b in &world.bodies {
                        let (p, q) = (b.position.to_array(), b.orientation.to_array());
                        let (v, w) = (b.linear_velocity, b.angular_velocity);
                        states.extend(p.into_iter().chain(q).chain(v.to_array()));
                        states.extend(w.to_array());
                    }
                }
                (states, most)
            };
            let (batched, most) = run(false);
            let (coloured, most_by_colour) = run(true);
            assert_eq!(most_by_colour.0, 0, "{family}: batched when told not to");
            assert!(
                most.0 >= 40,
                "{family}: batched at most {} manifolds",
                most.0
            );
            if family == "pile" {
                assert!(most.1 > 200, "{family}: coloured at most {}", most.1);
            }
            assert!(
                batched == coloured,
                "{family} at e = {restitution}: the bits differ"
            );
        }
    }
}
