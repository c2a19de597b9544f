//! The world owns bodies, shapes and constraints in flat arrays addressed by index, and advances
//! them with [`World::step`].

use crate::body::RigidBody;
use crate::broad_phase::{Aabb, Grid, body_aabb, typical_cell_size};
use crate::constraint::{DistanceConstraint, pair_mut as bodies_pair_mut, solve_constraints};
use crate::contact::{Contact, ContactParams, resolve_contact};
use crate::integrate::integrate_bodies;
use crate::narrow_phase::{
    body_contact, body_contact_patch, ground_contact, oriented_boxes_overlap,
};
use crate::settings::{BroadPhase, Settings};
use crate::shape::Shape;
use crate::stats::StepStats;
use glam::{DMat3, DQuat, DVec3};
use rayon::prelude::*;
use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::time::Instant;

/// Speeds above this are treated as a blown-up state and quarantined.
pub const ABSURD_SPEED: f64 = 1e12;

#[derive(Debug, Clone)]
pub struct World {
    /// Meshes, each shared by every body that uses it.
    pub shapes: Vec<Shape>,
    /// Where each shape came from (file name), for display.
    pub shape_names: Vec<String>,
    pub bodies: Vec<RigidBody>,
    pub constraints: Vec<DistanceConstraint>,
    pub settings: Settings,
    /// Simulated seconds so far.
    pub time: f64,
    pub step_count: u64,
    /// Notes from loading (ignored constraints, ...), for the user.
    pub warnings: Vec<String>,
    constraints_by_body: Vec<Vec<u32>>,
    grid: Grid,
    aabbs: Vec<Aabb>,
    /// Fattened boxes the grid holds during the contact stage (each contains its body's box).
    proxies: Vec<Aabb>,
    /// Share of candidate pairs the last contact stage computed sequentially (because a body had
    /// moved): when high, the parallel precomputation is not worth it.
    recomputed_fraction: f64,
    /// Last state known finite, restored when a body is quarantined.
    last_good: Vec<(DVec3, DQuat)>,
    initial_bodies: Vec<RigidBody>,
}

/// The ground plane's stand-in body: immovable, at rest.
fn ground_body() -> RigidBody {
    RigidBody::new(
        usize::MAX,
        0.0,
        DMat3::ZERO,
        0.0,
        true,
        DVec3::ZERO,
        DQuat::IDENTITY,
    )
}

fn contains(outer: &Aabb, inner: &Aabb) -> bool {
    outer.min.cmple(inner.min).all() && inner.max.cmple(outer.max).all()
}

fn timed<T>(slot: &mut f64, f: impl FnOnce() -> T) -> T {
    let start = Instant::now();
    let out = f();
    *slot += start.elapsed().as_secs_f64();
    out
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
        let cell = typical_cell_size(
            bodies
                .iter()
                .map(|b| shapes[b.shape].local_box_half_extents),
        );
        let last_good = bodies.iter().map(|b| (b.position, b.orientation)).collect();
        World {
            shapes,
            shape_names,
            initial_bodies: bodies.clone(),
            bodies,
            constraints,
            settings,
            time: 0.0,
            step_count: 0,
            warnings: Vec::new(),
            constraints_by_body,
            grid: Grid::new(cell),
            aabbs: Vec::new(),
            proxies: Vec::new(),
            recomputed_fraction: 0.0,
            last_good,
        }
    }

    /// Back to the state the world was created in (settings are kept).
    pub fn reset(&mut self) {
        self.bodies = self.initial_bodies.clone();
        self.last_good = self
            .bodies
            .iter()
            .map(|b| (b.position, b.orientation))
            .collect();
        self.time = 0.0;
        self.step_count = 0;
    }

    /// One time step: integrate, broad phase, narrow phase and contact resolution, ground
    /// contacts, constraints, then a finiteness check (the pose update). With substeps, the whole
    /// sequence runs `substeps` times with `dt / substeps`.
    pub fn step(&mut self) -> StepStats {
        let settings = self.settings.sanitized();
        let dt = settings.time_step / settings.substeps as f64;
        let mut stats = StepStats::default();
        for _ in 0..settings.substeps {
            let sub = self.substep(&settings, dt);
            stats.accumulate(sub);
        }
        self.time += settings.time_step;
        self.step_count += 1;
        stats
    }

    fn substep(&mut self, settings: &Settings, dt: f64) -> StepStats {
        let mut stats = StepStats::default();
        let params = ContactParams {
            restitution: settings.restitution,
            skip_separating: settings.skip_separating_contacts,
            restitution_threshold: settings.restitution_threshold,
        };
        timed(&mut stats.timings.integrate, || {
            integrate_bodies(&mut self.bodies, settings, dt)
        });
        self.resolve_body_contacts(settings.broad_phase, &params, &mut stats);
        let mut ground_time = 0.0;
        timed(&mut ground_time, || {
            self.resolve_ground_contacts(&params, &mut stats)
        });
        stats.timings.ground = ground_time;
        if !self.constraints.is_empty() {
            let start = Instant::now();
            let report = solve_constraints(
                &self.constraints,
                &self.constraints_by_body,
                &mut self.bodies,
                settings.constraint_schedule,
                settings.tolerance,
                settings.max_iterations,
            );
            stats.timings.constraints = start.elapsed().as_secs_f64();
            stats.constraint_visits = report.visits;
            stats.constraint_corrections = report.corrections;
            stats.budget_hit = report.budget_hit;
        }
        let mut finalize = 0.0;
        timed(&mut finalize, || {
            self.quarantine_blown_up(&mut stats);
        });
        stats.timings.finalize = finalize;
        stats
    }

    fn collides(&self, i: usize, j: usize) -> bool {
        let (a, b) = (&self.bodies[i], &self.bodies[j]);
        !(a.quarantined || b.quarantined || a.fixed && b.fixed)
    }

    fn contact_between(&self, i: usize, j: usize) -> Option<Contact> {
        let (a, b) = (&self.bodies[i], &self.bodies[j]);
        let (shape_a, shape_b) = (&self.shapes[a.shape], &self.shapes[b.shape]);
        if !oriented_boxes_overlap(a, shape_a, b, shape_b) {
            return None;
        }
        let detect = if self.settings.contact_patches {
            body_contact_patch
        } else {
            body_contact
        };
        detect(a, shape_a, b, shape_b)
    }

    fn refresh_aabb(&mut self, index: usize) {
        let body = &self.bodies[index];
        self.aabbs[index] = body_aabb(body, &self.shapes[body.shape]);
    }

    fn apply_contact(
        &mut self,
        i: usize,
        j: usize,
        contact: &Contact,
        params: &ContactParams,
        stats: &mut StepStats,
    ) {
        let (a, b) = bodies_pair_mut(&mut self.bodies, i, j);
        resolve_contact(a, b, contact, params);
        stats.contacts += 1;
        stats.max_penetration = stats.max_penetration.max(contact.depth);
    }

    /// Body-body contacts, detected and resolved pair by pair in (i, j) order exactly as the
    /// coursework's all-pairs loop does: each pair is tested with the poses left by the pairs
    /// before it. The grid only skips pairs whose boxes cannot overlap, and re-queries bodies that
    /// a resolution moved, so it yields the same contacts in the same order.
    fn resolve_body_contacts(
        &mut self,
        broad_phase: BroadPhase,
        params: &ContactParams,
        stats: &mut StepStats,
    ) {
        let n = self.bodies.len();
        let start = Instant::now();
        let bodies = &self.bodies;
        let shapes = &self.shapes;
        self.aabbs.clear();
        self.aabbs.par_extend(
            bodies
                .par_iter()
                .with_min_len(256)
                .map(|b| body_aabb(b, &shapes[b.shape])),
        );
        stats.timings.broad_phase += start.elapsed().as_secs_f64();

        if broad_phase == BroadPhase::AllPairs {
            // The box tests of the loop count as broad phase: total minus the other two stages.
            let loop_start = Instant::now();
            let (narrow_before, resolution_before) =
                (stats.timings.narrow_phase, stats.timings.contact_resolution);
            for i in 0..n {
                for j in i + 1..n {
                    if !self.collides(i, j) {
                        continue;
                    }
                    stats.pairs_tested += 1;
                    if !self.aabbs[i].overlaps(&self.aabbs[j]) {
                        continue;
                    }
                    stats.narrow_phase_queries += 1;
                    let t = Instant::now();
                    let contact = self.contact_between(i, j);
                    stats.timings.narrow_phase += t.elapsed().as_secs_f64();
                    if let Some(contact) = contact {
                        let t = Instant::now();
                        self.apply_contact(i, j, &contact, params, stats);
                        self.refresh_aabb(i);
                        self.refresh_aabb(j);
                        stats.timings.contact_resolution += t.elapsed().as_secs_f64();
                    }
                }
            }
            let others = (stats.timings.narrow_phase - narrow_before)
                + (stats.timings.contact_resolution - resolution_before);
            stats.timings.broad_phase += (loop_start.elapsed().as_secs_f64() - others).max(0.0);
            return;
        }

        // Broad phase: candidate pairs of proxy boxes (body boxes fattened by a margin) from the
        // grid. While a body's box stays inside its proxy, every pair it can newly overlap is
        // already a candidate; only a body that escapes its proxy is looked up again.
        let start = Instant::now();
        let active: Vec<bool> = self.bodies.iter().map(|b| !b.quarantined).collect();
        let proxies: Vec<Aabb> = (0..n).map(|i| self.proxy_of(i)).collect();
        self.proxies = proxies;
        self.grid.rebuild(&self.proxies, &active);
        let candidates = {
            let this = &*self;
            this.grid.overlapping_pairs(
                &this.proxies,
                |i, j| this.collides(i, j),
                &mut stats.pairs_tested,
            )
        };
        stats.timings.broad_phase += start.elapsed().as_secs_f64();

        // Narrow phase, in parallel, on the candidates whose boxes overlap after integration.
        // Skipped (each pair computed when it is reached) on one thread, or when most pairs had
        // to be computed again last step anyway: results are the same either way.
        let start = Instant::now();
        let eager = rayon::current_num_threads() > 1 && self.recomputed_fraction < 0.5;
        let precomputed: Vec<Option<Contact>> = if eager {
            let this = &*self;
            candidates
                .par_iter()
                .with_min_len(16)
                .map(|&(i, j)| {
                    let (i, j) = (i as usize, j as usize);
                    let overlap = this.aabbs[i].overlaps(&this.aabbs[j]) && this.collides(i, j);
                    if overlap {
                        this.contact_between(i, j)
                    } else {
                        None
                    }
                })
                .collect()
        } else {
            Vec::new()
        };
        let queries_before = stats.narrow_phase_queries;
        stats.narrow_phase_queries += precomputed.len();
        stats.timings.narrow_phase += start.elapsed().as_secs_f64();

        // Sequential resolution in pair order; pairs touching a moved body are re-tested.
        let start = Instant::now();
        let mut narrow_again = 0.0;
        let mut moved = vec![false; n];
        let mut extra: BinaryHeap<Reverse<(u32, u32)>> = BinaryHeap::new();
        let mut neighbours = Vec::new();
        let mut next_candidate = 0;
        let mut last: Option<(u32, u32)> = None;
        loop {
            let from_list = candidates.get(next_candidate).copied();
            let from_heap = extra.peek().map(|r| r.0);
            let (pair, precomputed_index) = match (from_list, from_heap) {
                (None, None) => break,
                (Some(a), Some(b)) if b < a => {
                    extra.pop();
                    (b, None)
                }
                (Some(a), _) => {
                    next_candidate += 1;
                    (a, Some(next_candidate - 1))
                }
                (None, Some(b)) => {
                    extra.pop();
                    (b, None)
                }
            };
            if last == Some(pair) {
                continue;
            }
            last = Some(pair);
            let (i, j) = (pair.0 as usize, pair.1 as usize);
            let contact = match precomputed_index {
                Some(k) if eager && !moved[i] && !moved[j] => precomputed[k],
                _ => {
                    if !self.aabbs[i].overlaps(&self.aabbs[j]) || !self.collides(i, j) {
                        continue;
                    }
                    let t = Instant::now();
                    let c = self.contact_between(i, j);
                    narrow_again += t.elapsed().as_secs_f64();
                    stats.narrow_phase_queries += 1;
                    c
                }
            };
            let Some(contact) = contact else { continue };
            self.apply_contact(i, j, &contact, params, stats);
            for b in [i, j] {
                if !self.bodies[b].is_dynamic() {
                    continue;
                }
                moved[b] = true;
                self.refresh_aabb(b);
                if contains(&self.proxies[b], &self.aabbs[b]) {
                    continue;
                }
                self.proxies[b] = self.proxy_of(b);
                self.grid.update(b, &self.proxies[b]);
                self.grid.query(b, &self.proxies, &mut neighbours);
                for &other in &neighbours {
                    let later = if (b as u32) < other {
                        (b as u32, other)
                    } else {
                        (other, b as u32)
                    };
                    if later > pair {
                        extra.push(Reverse(later));
                    }
                }
            }
        }
        stats.timings.narrow_phase += narrow_again;
        stats.timings.contact_resolution += start.elapsed().as_secs_f64() - narrow_again;
        let recomputed = stats.narrow_phase_queries - queries_before - precomputed.len();
        self.recomputed_fraction = recomputed as f64 / candidates.len().max(1) as f64;
    }

    /// The body's box fattened by a quarter of its largest half extent: room to move during
    /// contact resolution before the grid must be asked again (0.1 made pile-1000 spend a third
    /// of its step re-querying the grid).
    fn proxy_of(&self, index: usize) -> Aabb {
        let body = &self.bodies[index];
        let margin = 0.25 * self.shapes[body.shape].local_box_half_extents.max_element();
        let aabb = self.aabbs[index];
        Aabb {
            min: aabb.min - DVec3::splat(margin),
            max: aabb.max + DVec3::splat(margin),
        }
    }

    /// Every movable body whose lowest vertex is at or below y = 0 collides with the ground.
    /// Only bodies whose box reaches y = 0 have their vertices looked at.
    fn resolve_ground_contacts(&mut self, params: &ContactParams, stats: &mut StepStats) {
        let mut ground = ground_body();
        for index in 0..self.bodies.len() {
            if !self.bodies[index].is_dynamic() || self.aabbs[index].min.y > 0.0 {
                continue;
            }
            let body = &self.bodies[index];
            let Some(contact) = ground_contact(
                body,
                &self.shapes[body.shape],
                self.settings.contact_patches,
            ) else {
                continue;
            };
            resolve_contact(&mut self.bodies[index], &mut ground, &contact, params);
            stats.ground_contacts += 1;
            stats.max_penetration = stats.max_penetration.max(contact.depth);
        }
    }

    /// Freezes bodies whose state went non-finite or absurd at their last good pose, so NaN never
    /// reaches other bodies through contacts or constraints.
    fn quarantine_blown_up(&mut self, stats: &mut StepStats) {
        for (index, body) in self.bodies.iter_mut().enumerate() {
            if body.quarantined {
                continue;
            }
            let absurd = body.linear_velocity.length() > ABSURD_SPEED
                || body.angular_velocity.length() > ABSURD_SPEED;
            if body.is_finite() && !absurd {
                self.last_good[index] = (body.position, body.orientation);
                continue;
            }
            (body.position, body.orientation) = self.last_good[index];
            body.linear_velocity = DVec3::ZERO;
            body.angular_velocity = DVec3::ZERO;
            body.quarantined = true;
            stats.quarantined.push(index);
        }
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

    /// Kinetic plus potential energy of the movable bodies.
    pub fn total_energy(&self) -> f64 {
        let g = self.settings.gravity;
        self.bodies.iter().map(|b| b.energy(g)).sum()
    }

    /// Largest distance by which any constraint lies outside its bound.
    pub fn max_constraint_violation(&self) -> f64 {
        self.constraints
            .iter()
            .map(|c| c.violation(&self.bodies))
            .fold(0.0, f64::max)
    }

    pub fn all_finite(&self) -> bool {
        self.bodies.iter().all(|b| b.is_finite())
    }

    /// Contacts at the current poses, for display: (body1, body2 or None for the ground, contact).
    /// Detection only; nothing is resolved.
    pub fn current_contacts(&self) -> Vec<(usize, Option<usize>, Contact)> {
        let aabbs = self.body_aabbs();
        let active: Vec<bool> = self.bodies.iter().map(|b| !b.quarantined).collect();
        let mut grid = Grid::new(self.grid.cell_size());
        grid.rebuild(&aabbs, &active);
        let pairs = grid.overlapping_pairs(&aabbs, |i, j| self.collides(i, j), &mut 0);
        let mut out: Vec<(usize, Option<usize>, Contact)> = pairs
            .into_iter()
            .filter_map(|(i, j)| {
                let (i, j) = (i as usize, j as usize);
                self.contact_between(i, j).map(|c| (i, Some(j), c))
            })
            .collect();
        for (i, body) in self.bodies.iter().enumerate() {
            if body.is_dynamic()
                && aabbs[i].min.y <= 0.0
                && let Some(c) = ground_contact(
                    body,
                    &self.shapes[body.shape],
                    self.settings.contact_patches,
                )
            {
                out.push((i, None, c));
            }
        }
        out
    }

    /// World boxes of all bodies (computed from poses).
    pub fn body_aabbs(&self) -> Vec<Aabb> {
        self.bodies
            .iter()
            .map(|b| body_aabb(b, &self.shapes[b.shape]))
            .collect()
    }
}
