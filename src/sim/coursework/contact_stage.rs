//! The coursework solver's contact stages: body pairs detected and resolved one at a time in
//! (i, j) order exactly as the coursework's all-pairs loop does (each pair is tested with the
//! poses left by the pairs before it), then every body against the ground plane.

use super::contact::{ContactParams, resolve_contact};
use crate::sim::body::{RigidBody, flags_may_collide, may_collide, prefetch_pose};
use crate::sim::broad_phase::BroadPhase;
use crate::sim::constraint::pair_mut;
use crate::sim::narrow_phase::{
    Contact, Detection, body_contact, body_contact_patch, ground_contact, oriented_boxes_overlap,
};
use crate::sim::pair_queue::{PairQueue, PairSource};
use crate::sim::parallel;
use crate::sim::settings::BroadPhase as BroadPhaseKind;
use crate::sim::shape::Shape;
use crate::sim::stats::{SampledStage, Stage, StepStats, Stopwatch};
use crate::sim::step_context::StepContext;
use glam::DVec3;
use rayon::prelude::*;

/// What the body-contact stage keeps from one step to the next.
#[derive(Debug, Clone, Default)]
pub struct ContactStage {
    /// Share of the candidate pairs the last stage tested whose contact an earlier contact of
    /// the step had made stale (a body moved): when high, the parallel precomputation is
    /// mostly thrown away and the pairs computed again one by one.
    stale_share: f64,
    /// The precomputed narrow phase of the step's candidate pairs (`None`: boxes apart), kept
    /// for its room: a fresh buffer each step was mapped anew by the allocator on two threads
    /// and faulted in page by page (pile-10000: 140,000 page faults in 120 steps, 21,000 on one
    /// thread).
    precomputed: Vec<Option<Detection>>,
    /// The bodies' [`collision_flags`](crate::sim::body::collision_flags) as of the step's
    /// broad phase, kept for its room.
    flags: Vec<u8>,
}

/// Candidate pairs the sequential resolution tested, and how many of them had a body that an
/// earlier contact of the step moved.
#[derive(Debug, Clone, Copy, Default)]
struct Reached {
    tested: usize,
    stale: usize,
}

/// Above this share of stale candidate contacts, the stage computes each pair when it reaches
/// it instead of all in parallel first (see [`ContactStage::stale_share`]). A stale pair is
/// computed twice, so on two cores the parallel pass pays once a third or so of the pairs stay
/// fresh; in piles a third to three quarters go stale. Measured on two threads, 150 steps,
/// four alternating runs each: pile-10000 7.12 s at 0.5, 7.02 at 0.25; sparse-10000 5.28,
/// 5.07; pile-1000 0.560, 0.542. (The old rule, stale pairs over all candidates below 0.5,
/// counted the many whose boxes are apart and nearly always precomputed: pile-10000 on two
/// threads was slower than on one.)
const MAX_STALE_SHARE: f64 = 0.25;

/// The bodies and shapes a stage works on.
pub struct Bodies<'a> {
    pub bodies: &'a mut [RigidBody],
    pub shapes: &'a [Shape],
}

/// Exact contact between bodies `i` and `j` at their current poses: disjoint oriented boxes
/// first (cheap and exact), then the hulls; with `patches` (the gravity they are taken under,
/// [`crate::Settings::patch_gravity`]) acting at the contact patch.
pub fn contact_between(
    bodies: &[RigidBody],
    shapes: &[Shape],
    i: usize,
    j: usize,
    patches: Option<DVec3>,
) -> Detection {
    let (a, b) = (&bodies[i], &bodies[j]);
    let (shape_a, shape_b) = (&shapes[a.shape], &shapes[b.shape]);
    if !oriented_boxes_overlap(a, shape_a, b, shape_b) {
        return Detection::apart();
    }
    match patches {
        Some(gravity) => body_contact_patch((a, shape_a), (b, shape_b), gravity),
        None => body_contact(a, shape_a, b, shape_b),
    }
}

fn apply_contact(
    bodies: &mut [RigidBody],
    (i, j): (usize, usize),
    contact: &Contact,
    params: &ContactParams,
    stats: &mut StepStats,
) {
    let (a, b) = pair_mut(bodies, i, j);
    resolve_contact(a, b, contact, params);
    stats.contacts += 1;
    stats.max_penetration = stats.max_penetration.max(contact.depth);
}

impl ContactStage {
    /// Body-body contacts of one substep. The grid only skips pairs whose boxes cannot overlap
    /// and re-queries bodies that a resolution moved, so it yields the all-pairs loop's contacts
    /// in the same order.
    pub fn resolve_body_contacts(
        &mut self,
        ctx: &StepContext,
        world: Bodies,
        broad: &mut BroadPhase,
        watch: &mut Stopwatch,
        stats: &mut StepStats,
    ) {
        watch.enter(Stage::BroadPhase);
        match ctx.settings.broad_phase {
            BroadPhaseKind::AllPairs => {
                broad.update_boxes(world.bodies, world.shapes);
                all_pairs(ctx, world, broad, watch, stats)
            }
            BroadPhaseKind::Grid => self.grid_pairs(ctx, world, broad, watch, stats),
        }
    }

    fn grid_pairs(
        &mut self,
        ctx: &StepContext,
        world: Bodies,
        broad: &mut BroadPhase,
        watch: &mut Stopwatch,
        stats: &mut StepStats,
    ) {
        let Bodies { bodies, shapes } = world;
        // Read from a byte per body instead of the bodies (272 bytes each): no contact changes
        // them, and at scatter-100000 the resolution loop missed the cache on every body it read.
        let mut flags = std::mem::take(&mut self.flags);
        let tested = &mut stats.pairs_tested;
        let mut queue = broad.candidate_pairs((bodies, shapes), ctx.dt, &mut flags, tested);
        watch.enter(Stage::NarrowPhase);
        // Skipped (each pair computed when it is reached) on one thread, or when too many of
        // last step's precomputed contacts went stale: results are the same either way.
        let eager = rayon::current_num_threads() > 1 && self.stale_share < MAX_STALE_SHARE;
        let mut precomputed = std::mem::take(&mut self.precomputed);
        precomputed.clear();
        if eager {
            precompute(
                ctx,
                (bodies, shapes),
                (broad, &flags),
                queue.candidates(),
                &mut precomputed,
            );
            stats.narrow_phase_queries += precomputed.iter().flatten().count();
        }
        watch.enter(Stage::ContactResolution);
        let reached = resolve_in_order(
            ctx,
            Bodies { bodies, shapes },
            broad,
            (&mut queue, &flags),
            &precomputed,
            watch,
            stats,
        );
        self.stale_share = reached.stale as f64 / reached.tested.max(1) as f64;
        self.precomputed = precomputed;
        self.flags = flags;
    }
}

/// The coursework's literal loop over every pair (i < j); box tests count as broad phase.
fn all_pairs(
    ctx: &StepContext,
    world: Bodies,
    broad: &mut BroadPhase,
    watch: &mut Stopwatch,
    stats: &mut StepStats,
) {
    let Bodies { bodies, shapes } = world;
    let n = bodies.len();
    let patches = ctx.settings.patch_gravity();
    let mut narrow = SampledStage::new(Stage::NarrowPhase);
    let mut resolution = SampledStage::new(Stage::ContactResolution);
    for i in 0..n {
        for j in i + 1..n {
            if !may_collide(&bodies[i], &bodies[j]) {
                continue;
            }
            stats.pairs_tested += 1;
            if !broad.overlap(i, j) {
                continue;
            }
            stats.narrow_phase_queries += 1;
            let detection = watch.sample(&mut narrow, || {
                contact_between(bodies, shapes, i, j, patches)
            });
            stats.narrow_phase_fallbacks += detection.fallback as usize;
            if let Some(contact) = detection.contact {
                watch.sample(&mut resolution, || {
                    apply_contact(bodies, (i, j), &contact, &ctx.contact, stats);
                    broad.refresh(i, &bodies[i], shapes);
                    broad.refresh(j, &bodies[j], shapes);
                });
            }
        }
    }
    watch.settle(&narrow);
    watch.settle(&resolution);
}

/// The narrow phase of every candidate whose boxes overlap after integration, in parallel,
/// into `out` (`None` where the boxes are apart).
fn precompute(
    ctx: &StepContext,
    (bodies, shapes): (&[RigidBody], &[Shape]),
    (broad, flags): (&BroadPhase, &[u8]),
    candidates: &[(u32, u32)],
    out: &mut Vec<Option<Detection>>,
) {
    let detect = |&(i, j): &(u32, u32)| {
        let (i, j) = (i as usize, j as usize);
        (broad.overlap(i, j) && flags_may_collide(flags[i], flags[j]))
            .then(|| contact_between(bodies, shapes, i, j, ctx.settings.patch_gravity()))
    };
    parallel::extend_map(out, candidates.par_iter(), 16, detect);
}

/// Candidates past the loop's next whose boxes [`resolve_in_order`] asks the cache for.
const BOX_PREFETCH_DISTANCE: usize = 8;
/// Candidates past the loop's next whose bodies it asks the cache for (boxes asked for before).
const BODY_PREFETCH_DISTANCE: usize = 4;
/// Bytes of bodies up to which the loop does not ask for them ahead, chosen between two
/// measurements on this project's 2-core machine (32 MiB of L3; docs/scale-log.md, "Stop 67"):
/// asked for, scatter-30000's step (8 MB of bodies) and scatter-100000's (27 MB) took less
/// time, scatter-10000's (3 MB) and sparse-1000's more: where the bodies stay in the caches, the
/// extra box test and hints cost more than the waits they save.
const BODIES_IN_CACHE: usize = 6 << 20;

/// Sequential resolution in pair order. A pair whose bodies a resolution moved is tested again
/// at the new poses; a body that left its proxy box brings its new pairs into the queue.
fn resolve_in_order(
    ctx: &StepContext,
    world: Bodies,
    broad: &mut BroadPhase,
    (queue, flags): (&mut PairQueue, &[u8]),
    precomputed: &[Option<Detection>],
    watch: &mut Stopwatch,
    stats: &mut StepStats,
) -> Reached {
    let Bodies { bodies, shapes } = world;
    let mut moved = vec![false; bodies.len()];
    let mut reached = Reached::default();
    let mut narrow = SampledStage::new(Stage::NarrowPhase);
    // The hints below only where the loop runs the narrow phase itself (on one thread, or where
    // the last step's precomputation went mostly stale): where it was precomputed on other
    // threads, they cost scatter-100000's loop 0.4 ms a step on two threads for the boxes and
    // 1.5 ms for the bodies (docs/scale-log.md, "Stop 67").
    let detects = precomputed.is_empty();
    let ask_for_bodies = detects && std::mem::size_of_val(bodies) > BODIES_IN_CACHE;
    while let Some(((i, j), source)) = queue.pop() {
        // The boxes of a pair a few places on, which the loop's box test reads: at 100,000
        // bodies (4.8 MB of boxes, beside 27 MB of bodies) that test waited on memory.
        if detects && let Some((a, b)) = queue.candidate_ahead(BOX_PREFETCH_DISTANCE) {
            broad.prefetch_boxes(a, b);
        }
        // Nearer, with its boxes in the cache: the bodies of a pair whose boxes overlap, which
        // its contact test reads (at scatter-100000 on one thread, a third of the narrow phase
        // waited on loading them).
        if ask_for_bodies
            && let Some((a, b)) = queue.candidate_ahead(BODY_PREFETCH_DISTANCE)
            && broad.overlap(a, b)
        {
            prefetch_pose(bodies, a);
            prefetch_pose(bodies, b);
        }
        let stale = moved[i] || moved[j];
        let kept = match source {
            PairSource::Candidate(k) if !stale => precomputed.get(k),
            _ => None,
        };
        let detection = match kept {
            Some(Some(d)) => *d,
            Some(None) => continue,
            None => {
                if !broad.overlap(i, j) || !flags_may_collide(flags[i], flags[j]) {
                    continue;
                }
                let patches = ctx.settings.patch_gravity();
                let d = watch.sample(&mut narrow, || {
                    contact_between(bodies, shapes, i, j, patches)
                });
                stats.narrow_phase_queries += 1;
                d
            }
        };
        if let PairSource::Candidate(_) = source {
            reached.tested += 1;
            reached.stale += stale as usize;
        }
        stats.narrow_phase_fallbacks += detection.fallback as usize;
        let Some(contact) = detection.contact else {
            continue;
        };
        apply_contact(bodies, (i, j), &contact, &ctx.contact, stats);
        for b in [i, j] {
            if bodies[b].is_dynamic() {
                moved[b] = true;
                broad.body_moved(b, &bodies[b], shapes, queue);
            }
        }
    }
    watch.settle(&narrow);
    reached
}

/// Every movable body whose lowest vertex is at or below y = 0 collides with the ground, an
/// immovable body at rest. Only bodies whose box (`boxes`) reaches y = 0 are looked at.
pub fn resolve_ground_contacts(
    ctx: &StepContext,
    world: Bodies,
    boxes: &[crate::sim::aabb::Aabb],
    stats: &mut StepStats,
) {
    let Bodies { bodies, shapes } = world;
    let mut ground = RigidBody::ground();
    for (index, body) in bodies.iter_mut().enumerate() {
        // The box first: 48 bytes a body, where the flag brings in the body's 272-byte line;
        // a body whose box is off the ground is then not read at all (scatter-100000's ground
        // stage about a sixth faster, docs/scale-log.md, "Stop 68").
        if boxes[index].min.y > 0.0 || !body.is_dynamic() {
            continue;
        }
        let patches = ctx.settings.contact_patches;
        let Some(contact) = ground_contact(body, &shapes[body.shape], patches) else {
            continue;
        };
        resolve_contact(body, &mut ground, &contact, &ctx.contact);
        stats.ground_contacts += 1;
        stats.max_penetration = stats.max_penetration.max(contact.depth);
    }
}
