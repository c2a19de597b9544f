//! Broad phase: the bodies' world boxes, the hash grid that holds them, and the policy that keeps
//! the grid valid while contacts move bodies mid-stage.
//!
//! The grid holds *proxies*: each body's box fattened by a margin. While a body's box stays
//! inside its proxy, every pair it can newly overlap is already a candidate; only a body that
//! escapes its proxy is re-inserted and looked up again.

use super::aabb::{Aabb, body_aabb};
use super::body::{RigidBody, collision_flags, flags_may_collide};
use super::grid::{Grid, typical_cell_size};
use super::pair_queue::PairQueue;
use super::parallel;
use super::shape::Shape;
use glam::{DQuat, DVec3};
use rayon::prelude::*;

#[derive(Debug, Clone, Default)]
pub struct BroadPhase {
    grid: Grid,
    /// Each body's box at its current pose.
    aabbs: Vec<Aabb>,
    /// The fattened boxes the grid holds (each contains its body's box).
    proxies: Vec<Aabb>,
    neighbours: Vec<u32>,
    /// Which bodies the soft step moves this step (as of its last broad phase).
    is_awake: Vec<bool>,
    /// The pose each body's box was last computed at.
    placed: Vec<Option<(DVec3, DQuat)>>,
    /// How far ahead (seconds) a proxy reaches along its body's velocity.
    lookahead: f64,
    /// Each body's box grown by how far it can travel in the step (soft step).
    speculative: Vec<Aabb>,
    /// Which bodies left their proxies this step, and which the grid holds (not quarantined):
    /// kept between steps so a step allocates neither.
    moved: Vec<bool>,
    active: Vec<bool>,
}

impl BroadPhase {
    /// A broad phase with cells sized for these bodies.
    pub fn new(bodies: &[RigidBody], shapes: &[Shape]) -> Self {
        let cell = typical_cell_size(
            bodies
                .iter()
                .map(|b| shapes[b.shape].local_box_half_extents),
        );
        Self {
            grid: Grid::new(cell),
            ..Self::default()
        }
    }

    /// Recomputes every body's box from its pose (in parallel).
    pub fn update_boxes(&mut self, bodies: &[RigidBody], shapes: &[Shape]) {
        self.aabbs.clear();
        let boxes = |b: &RigidBody| body_aabb(b, &shapes[b.shape]);
        parallel::extend_map(&mut self.aabbs, bodies.par_iter(), 256, boxes);
    }

    /// Body boxes as of the last update or move (the coursework solver's; the soft step keeps
    /// only [`BroadPhase::speculative_boxes`]).
    pub fn boxes(&self) -> &[Aabb] {
        &self.aabbs
    }

    /// Each body's box grown by how far it can travel in the step, as of the soft step's last
    /// broad phase (sleeping bodies': as of the step they last moved).
    pub fn speculative_boxes(&self) -> &[Aabb] {
        &self.speculative
    }

    /// Which bodies were awake at the soft step's last broad phase (see
    /// [`BroadPhase::speculative_pairs`]).
    pub fn awake(&self) -> &[bool] {
        &self.is_awake
    }

    pub fn overlap(&self, i: usize, j: usize) -> bool {
        self.aabbs[i].overlaps(&self.aabbs[j])
    }

    /// Asks the cache for bodies `i` and `j`'s boxes, which [`BroadPhase::overlap`] will read
    /// (a hint: nothing changes).
    #[inline(always)]
    pub fn prefetch_boxes(&self, i: usize, j: usize) {
        for k in [i, j] {
            if let Some(b) = self.aabbs.get(k) {
                super::buffer::prefetch(b);
            }
        }
    }

    /// Computes every body's box ([`BroadPhase::boxes`]) and its [`collision_flags`] (into
    /// `flags`), brings every active body's proxy into the grid, and returns the candidate pairs
    /// (i < j, sorted) whose proxies overlap and whose flags may collide, queued in order. One
    /// pass over the bodies does all three: at scatter-100000 each pass over its 27 MB of
    /// bodies waited on memory, and the three apart took 5.5 ms a step on one thread (boxes
    /// 3.5, flags 0.5, proxies 1.6; docs/scale-log.md, "Stop 68"). A proxy that still holds its
    /// body's box is kept, and costs the grid nothing: the pairs are a superset of the fresh
    /// proxies' that the loop filters by the boxes themselves, so the results are the same bit
    /// for bit (sparse-1000 re-hashed a third of its bodies every step). `tested` counts box
    /// tests. Proxies reach [`PROXY_LOOKAHEAD_STEPS`] steps of `dt` ahead along their bodies'
    /// velocities.
    pub fn candidate_pairs(
        &mut self,
        (bodies, shapes): (&[RigidBody], &[Shape]),
        dt: f64,
        flags: &mut Vec<u8>,
        tested: &mut usize,
    ) -> PairQueue {
        self.lookahead = PROXY_LOOKAHEAD_STEPS * dt;
        // The soft step computes every box again after this step has moved bodies under it.
        self.placed.clear();
        let n = bodies.len();
        // A proxy kept from an earlier step, of either solver, serves while it holds the box.
        let kept = self.proxies.len() == n;
        self.aabbs.resize(n, Aabb::EMPTY);
        self.proxies.resize(n, Aabb::EMPTY);
        flags.resize(n, 0);
        let moved = cleared(&mut self.moved, n);
        let active = cleared(&mut self.active, n);
        let lookahead = self.lookahead;
        let boxes = (&mut self.aabbs, &mut self.proxies);
        let items = (boxes, &mut flags[..], moved, active).into_par_iter();
        let items = items.zip(bodies);
        parallel::for_each(
            items,
            256,
            |(((aabb, proxy), flag, moved, active), body)| {
                *aabb = body_aabb(body, &shapes[body.shape]);
                *flag = collision_flags(body);
                *active = !body.quarantined;
                if kept && proxy.contains(aabb) {
                    return;
                }
                *proxy = proxy_of(aabb, body, shapes, lookahead);
                *moved = true;
            },
        );
        let flags = &flags[..];
        let keep = |i: usize, j: usize| flags_may_collide(flags[i], flags[j]);
        let pairs = grid_pairs(
            &mut self.grid,
            (&self.proxies, &self.active, &self.moved),
            (keep, tested),
        );
        PairQueue::new(pairs)
    }

    /// For the soft-step solver: each awake body's box grown by `margins[i]` (how far it can
    /// travel in the step: its speculative box), and the pairs (i < j, sorted) whose speculative
    /// boxes overlap, at least one body awake, and for which `keep(i, j)`. The grid holds
    /// proxies around the speculative boxes (reaching ahead as [`proxy_of`] says) and keeps its
    /// pairs from step to step, so a body whose speculative box stays inside its proxy costs it
    /// nothing, and a sleeping body, whose box is not even recomputed until its pose changes
    /// (a rewind, an edit), costs a filter test per pair. `tested` counts box tests.
    ///
    /// `again`: a second call in the step, after some sleeping bodies woke, with no pose or
    /// margin changed since the first: the boxes computed then are current, and only the
    /// woken bodies' are computed (making every awake body's box again cost scatter-100000's
    /// landing about half a millisecond a step).
    pub fn speculative_pairs(
        &mut self,
        bodies: &[RigidBody],
        shapes: &[Shape],
        (margins, dt, again): (&[f64], f64, bool),
        keep: impl Fn(usize, usize) -> bool + Sync,
        tested: &mut usize,
    ) -> Vec<(u32, u32)> {
        let n = bodies.len();
        if self.speculative.len() != n || self.proxies.len() != n || self.placed.len() != n {
            for boxes in [&mut self.speculative, &mut self.proxies] {
                boxes.clear();
                boxes.resize(n, Aabb::EMPTY);
            }
            self.placed.clear();
            self.placed.resize(n, None);
        }
        // The coursework loop's boxes are not kept meanwhile (4.8 MB at 100,000 bodies); it
        // computes them again when it runs.
        self.aabbs = Vec::new();
        self.lookahead = PROXY_LOOKAHEAD_STEPS * dt;
        let lookahead = self.lookahead;
        let moved = cleared(&mut self.moved, n);
        // The bodies' states, read once here (a pass over 100,000 bodies of 272 bytes each
        // costs a millisecond where they do not fit the cache).
        self.is_awake.resize(n, false);
        let states = (&mut self.is_awake, cleared(&mut self.active, n));
        let boxes = (&mut self.speculative, &mut self.proxies);
        let items = (boxes, &mut self.placed, moved, states).into_par_iter();
        let items = items.zip((bodies, margins));
        parallel::for_each(
            items,
            256,
            |(((speculative, proxy), placed, moved, (awake, active)), (b, &m))| {
                let was_awake = std::mem::replace(awake, b.is_awake());
                *active = !b.quarantined;
                let pose = Some((b.position, b.orientation));
                if (*awake && !(again && was_awake)) || *placed != pose {
                    *speculative = body_aabb(b, &shapes[b.shape]).fattened(m);
                    *placed = pose;
                }
                if !proxy.contains(speculative) {
                    *proxy = proxy_of(speculative, b, shapes, lookahead);
                    *moved = true;
                }
            },
        );
        let (awake, speculative) = (&self.is_awake, &self.speculative);
        let wanted = |i: usize, j: usize| {
            (awake[i] || awake[j]) && speculative[i].overlaps(&speculative[j]) && keep(i, j)
        };
        grid_pairs(
            &mut self.grid,
            (&self.proxies, &self.active, &self.moved),
            (wanted, tested),
        )
    }

    /// Body `index` was moved while the loop stood at some pair: its box is refreshed, and if it
    /// left its proxy the body is re-inserted and every pair it now forms is offered to `queue`
    /// (which keeps those the loop has not passed).
    pub fn body_moved(
        &mut self,
        index: usize,
        body: &RigidBody,
        shapes: &[Shape],
        queue: &mut PairQueue,
    ) {
        self.refresh(index, body, shapes);
        if self.proxies[index].contains(&self.aabbs[index]) {
            return;
        }
        self.proxies[index] = proxy_of(&self.aabbs[index], body, shapes, self.lookahead);
        self.grid.update(index, &self.proxies[index]);
        self.grid.query(index, &self.proxies, &mut self.neighbours);
        for &other in &self.neighbours {
            queue.push_later(index, other as usize);
        }
    }

    /// Refreshes body `index`'s box after it moved (no grid update: for loops without a grid).
    pub fn refresh(&mut self, index: usize, body: &RigidBody, shapes: &[Shape]) {
        self.aabbs[index] = body_aabb(body, &shapes[body.shape]);
    }
}

/// The grid brought to the `proxies` (the `moved` ones changed, the bodies not `active`, the
/// quarantined ones, left out), and its pairs of overlapping proxies for which `keep(i, j)`;
/// `tested` counts box tests.
fn grid_pairs(
    grid: &mut Grid,
    (proxies, active, moved): (&[Aabb], &[bool], &[bool]),
    (keep, tested): (impl Fn(usize, usize) -> bool + Sync, &mut usize),
) -> Vec<(u32, u32)> {
    grid.sync(proxies, active, moved);
    grid.overlapping_pairs(proxies, keep, tested)
}

/// `buffer` as `n` falses, its allocation kept.
fn cleared(buffer: &mut Vec<bool>, n: usize) -> &mut Vec<bool> {
    buffer.clear();
    buffer.resize(n, false);
    buffer
}

/// Steps of travel a proxy reaches ahead of its body.
pub const PROXY_LOOKAHEAD_STEPS: f64 = 8.0;

/// The body's box `aabb` fattened by a quarter of its largest half extent (room to move during
/// contact resolution before the grid must be asked again: 0.1 made pile-1000 spend a third of
/// its step re-querying the grid) and swept along its velocity for `lookahead` seconds, so a
/// falling body keeps its proxy for several steps (sparse-1000 re-inserted a third of its
/// bodies every step). Any box holding the body's gives the same contacts: only the work moves.
fn proxy_of(aabb: &Aabb, body: &RigidBody, shapes: &[Shape], lookahead: f64) -> Aabb {
    let margin = 0.25 * shapes[body.shape].local_box_half_extents.max_element();
    let fat = aabb.fattened(margin);
    let shift = body.linear_velocity * lookahead;
    if shift.is_finite() {
        fat.swept(shift)
    } else {
        fat
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::assets;

    /// The soft step's pairs, kept in the grid from step to step, are those a test of every
    /// pair gives: bodies falling, drifting, spinning and teleported, some asleep (their boxes
    /// kept), some quarantined, over steps where most or few proxies change; and again within
    /// the step after some sleepers woke (their boxes made anew, with this step's margins).
    #[test]
    fn speculative_pairs_match_every_pair_tested_over_steps() {
        let shapes = vec![
            Shape::from_tet_mesh(&assets::cuboid(DVec3::new(1.5, 0.75, 1.0))).unwrap(),
            Shape::from_tet_mesh(&assets::octahedron(DVec3::splat(1.2))).unwrap(),
        ];
        let mut rng = crate::sim::rng::Rng::new(99);
        let mut next = move || rng.unit();
        let n = 600;
        let mut bodies: Vec<RigidBody> = (0..n)
            .map(|k| {
                let p = DVec3::new(next(), next(), next()) * 40.0;
                let q = DQuat::from_scaled_axis(DVec3::new(next(), next(), next()) * 3.0);
                let mut b = RigidBody::on_shape(&shapes[k % 2], k % 2, 1.0, false, p, q);
                b.linear_velocity = DVec3::new(next() - 0.5, -20.0 * next(), next() - 0.5);
                b
            })
            .collect();
        let mut broad = BroadPhase::new(&bodies, &shapes);
        let keep = |i: usize, j: usize| !(i + j).is_multiple_of(7);
        let dt = 0.02;
        let mut kept = vec![None; n];
        for step in 0..40 {
            for (k, b) in bodies.iter_mut().enumerate() {
                b.asleep = (k + step / 10) % 4 == 0;
                b.quarantined = k % 97 == step % 97;
                if step % 13 == 12 && k % 50 == 0 {
                    b.position += DVec3::splat(30.0); // an edit: asleep or not, it moved
                } else if b.is_awake() {
                    b.position += b.linear_velocity * dt;
                    b.orientation =
                        (DQuat::from_scaled_axis(DVec3::splat(0.05)) * b.orientation).normalize();
                }
            }
            // A sleeper's margin is a resting body's; the others' change from step to step.
            let margin = |(k, b): (usize, &RigidBody)| match b.asleep {
                true => 0.1,
                false => 0.1 + 0.05 * ((k + step) % 5) as f64,
            };
            let margins: Vec<f64> = bodies.iter().enumerate().map(margin).collect();
            let mut tested = 0;
            let first = (&margins[..], dt, false);
            let pairs = broad.speculative_pairs(&bodies, &shapes, first, keep, &mut tested);
            let expected = every_pair_tested(&bodies, &shapes, (&margins, &mut kept), keep);
            assert!(
                step < 5 || expected.len() > 20,
                "step {step}: {}",
                expected.len()
            );
            assert_eq!(pairs, expected, "step {step}");
            // Some sleepers woken, asked again within the step.
            for b in bodies.iter_mut().step_by(3).filter(|b| b.asleep) {
                b.asleep = false;
            }
            let again = (&margins[..], dt, true);
            let pairs = broad.speculative_pairs(&bodies, &shapes, again, keep, &mut tested);
            let expected = every_pair_tested(&bodies, &shapes, (&margins, &mut kept), keep);
            assert_eq!(pairs, expected, "step {step}, again");
        }
    }

    /// Body pose and the speculative box made there.
    type Placed = Option<((DVec3, DQuat), Aabb)>;

    /// Every pair tested against every other, by each body's speculative box: made at its pose
    /// with its margin where it is awake or has moved since its box was made (`kept`), else
    /// the box made then.
    fn every_pair_tested(
        bodies: &[RigidBody],
        shapes: &[Shape],
        (margins, kept): (&[f64], &mut [Placed]),
        keep: impl Fn(usize, usize) -> bool,
    ) -> Vec<(u32, u32)> {
        let n = bodies.len();
        let mut grown = Vec::new();
        for (k, b) in bodies.iter().enumerate() {
            let pose = (b.position, b.orientation);
            let made = match kept[k] {
                Some((at, made)) if !b.is_awake() && at == pose => made,
                _ => body_aabb(b, &shapes[b.shape]).fattened(margins[k]),
            };
            kept[k] = Some((pose, made));
            grown.push(made);
        }
        let mut expected = Vec::new();
        for i in 0..n {
            for j in i + 1..n {
                let (a, b) = (&bodies[i], &bodies[j]);
                if !a.quarantined
                    && !b.quarantined
                    && (a.is_awake() || b.is_awake())
                    && grown[i].overlaps(&grown[j])
                    && keep(i, j)
                {
                    expected.push((i as u32, j as u32));
                }
            }
        }
        expected
    }
}
