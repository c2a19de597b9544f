//! Stress suite: random scenes, extreme but legal inputs, long chains. Seeded and deterministic.
mod common;

use glam::{DQuat, DVec3};
use tumble::scene::{assets, generate};
use tumble::sim::settings::{ConstraintSchedule, Solver};
use tumble::{Settings, World};

/// Lowest point of a body below the ground, by its vertices.
fn depth_below_ground(world: &World) -> f64 {
    (0..world.bodies.len())
        .filter(|&i| !world.bodies[i].fixed)
        .map(|i| {
            world
                .current_vertices(i)
                .iter()
                .map(|v| -v.y)
                .fold(f64::MIN, f64::max)
        })
        .fold(0.0, f64::max)
}

#[test]
fn random_scenes_stay_finite_and_above_ground() {
    let cases = [
        (1u64, 50usize, 0.001),
        (2, 120, 0.01),
        (3, 200, 0.02),
        (4, 80, 0.05),
    ];
    for (seed, n, dt) in cases {
        for settings in [
            Settings {
                time_step: dt,
                ..Settings::default()
            },
            Settings {
                time_step: dt,
                ..Settings::accurate()
            },
        ] {
            let mut world = generate::random(seed, n, 200.0, settings);
            for step in 0..2000 {
                let stats = world.step();
                assert!(
                    stats.quarantined.is_empty(),
                    "seed {seed}: bodies {:?} blew up at step {step}",
                    stats.quarantined
                );
            }
            assert!(world.all_finite(), "seed {seed}: non-finite state");
            // Whatever tunnels through a body is pushed back out at the ground: nothing ends
            // deeper below y = 0 than one step of its fastest fall.
            let depth = depth_below_ground(&world);
            assert!(
                depth < 1.0,
                "seed {seed} dt {dt}: a body ends {depth} below the ground"
            );
        }
    }
}

#[test]
fn energy_does_not_grow_in_accurate_mode_without_constraints() {
    // e <= 1, no constraints: collisions may only lose energy, up to the position projection's
    // small gain (it lifts penetrating bodies). Bound: 2% of the initial energy measured from the
    // lowest possible state, over 2000 steps.
    for (seed, e) in [(11u64, 1.0), (12, 0.8), (13, 0.3)] {
        let settings = Settings {
            restitution: e,
            time_step: 0.005,
            ..Settings::accurate()
        };
        let mut world = generate::random(seed, 60, 50.0, settings);
        let start = world.total_energy();
        let mut worst = f64::MIN;
        for _ in 0..2000 {
            world.step();
            worst = worst.max(world.total_energy());
        }
        assert!(
            worst <= start + 0.02 * start.abs(),
            "seed {seed} e {e}: energy rose from {start:.6e} to {worst:.6e}"
        );
    }
}

#[test]
fn hundred_chains_of_ten_stay_bounded_and_report_their_budget() {
    let settings = Settings {
        constraint_schedule: ConstraintSchedule::Sparse,
        ..Settings::default()
    };
    let mut world = generate::chain(1000, settings); // 100 chains of 10
    // 20,000 visits per step under the skeleton's rule (max_iterations / M visits).
    world.settings.max_iterations = 20_000 * world.constraints.len();
    let mut hits = 0;
    let mut worst: f64 = 0.0;
    for _ in 0..500 {
        let stats = world.step();
        assert!(
            stats.constraint_visits <= 20_000,
            "visits {} over the budget",
            stats.constraint_visits
        );
        hits += stats.budget_hit as usize;
        worst = worst.max(worst_relative_violation(&world));
        if stats.budget_hit {
            // Honest report: some constraint really is still violated.
            assert!(world.max_constraint_violation() > 0.0);
        }
    }
    assert!(world.all_finite());
    eprintln!("chain-1000: worst relative violation {worst}, budget hit in {hits} of 500 steps");
    assert!(worst < 0.5, "worst relative violation {worst}");
}

/// Largest violation of any constraint's bounds, relative to its rest length.
fn worst_relative_violation(world: &World) -> f64 {
    world
        .constraints
        .iter()
        .map(|c| c.violation(&world.bodies) / c.rest_length)
        .fold(0.0, f64::max)
}

/// One chain of 100 links with bounds 0.99..1.01 under a tight and a generous visit budget.
#[test]
fn hundred_link_chain_with_tight_bounds_stays_bounded_under_a_budget() {
    let s = tumble::Shape::from_tet_mesh(&assets::cuboid(DVec3::new(1.0, 0.5, 0.5))).unwrap();
    let mut bodies = Vec::new();
    let mut constraints = Vec::new();
    for k in 0..100 {
        bodies.push(tumble::RigidBody::on_shape(
            &s,
            0,
            100.0,
            k == 0,
            DVec3::new(0.3 * k as f64, 400.0 - 1.5 * k as f64, 0.0),
            DQuat::IDENTITY,
        ));
        if k > 0 {
            constraints.extend(
                tumble::sim::constraint::DistanceConstraint::lower_and_upper(
                    &bodies,
                    std::slice::from_ref(&s),
                    (k - 1, 0),
                    (k, 2),
                    0.99,
                    1.01,
                ),
            );
        }
    }
    for (budget, bound) in [(10_000, 20.0), (50_000, 1.0)] {
        let mut world = World::new(
            vec![s.clone()],
            vec!["box".into()],
            bodies.clone(),
            constraints.clone(),
            Settings {
                max_iterations: budget * constraints.len(),
                ..Settings::default()
            },
        );
        let (mut budget_hits, mut worst_first_half, mut worst) = (0, 0.0f64, 0.0f64);
        for step in 0..600 {
            let stats = world.step();
            budget_hits += stats.budget_hit as usize;
            assert!(stats.constraint_visits <= budget);
            worst = worst.max(worst_relative_violation(&world));
            if step < 300 {
                worst_first_half = worst;
            }
        }
        assert!(world.all_finite());
        eprintln!(
            "100-link chain, budget {budget}: worst relative violation {worst_first_half} after 300 steps, {worst} after 600, budget hit in {budget_hits} of 600 steps"
        );
        // Bounded: the stretch settles rather than growing without end, and a generous budget
        // holds the chain close to its bounds.
        assert!(
            worst < bound,
            "budget {budget}: worst relative violation {worst}"
        );
        if budget >= 50_000 {
            assert!(
                worst <= 1.5 * worst_first_half + 1e-3,
                "budget {budget}: violation still growing ({worst_first_half} -> {worst})"
            );
        }
    }
}

fn two_bodies(a: (f64, DVec3), b: (f64, DVec3), settings: Settings) -> World {
    let s = tumble::Shape::from_tet_mesh(&assets::cuboid(DVec3::new(2.0, 1.0, 1.5))).unwrap();
    let bodies = [a, b]
        .iter()
        .map(|&(density, p)| tumble::RigidBody::on_shape(&s, 0, density, false, p, DQuat::IDENTITY))
        .collect();
    World::new(vec![s], vec!["box".into()], bodies, Vec::new(), settings)
}

#[test]
fn degenerate_but_legal_inputs() {
    // Interpenetrating at the start, half inside each other.
    let mut w = two_bodies(
        (100.0, DVec3::new(0.0, 5.0, 0.0)),
        (100.0, DVec3::new(1.0, 5.5, 0.3)),
        Settings::default(),
    );
    for _ in 0..500 {
        w.step();
    }
    assert!(w.all_finite());
    assert!(
        w.current_contacts().iter().all(|(_, _, c)| c.depth < 0.5),
        "still deeply interpenetrated"
    );
    // Exactly touching the ground.
    let mut w = two_bodies(
        (100.0, DVec3::new(0.0, 1.0, 0.0)),
        (100.0, DVec3::new(10.0, 1.0, 0.0)),
        Settings::default(),
    );
    for _ in 0..500 {
        w.step();
    }
    assert!(w.all_finite() && depth_below_ground(&w) < 0.2);
    // Zero time step: nothing moves.
    let mut w = two_bodies(
        (100.0, DVec3::new(0.0, 5.0, 0.0)),
        (100.0, DVec3::new(10.0, 5.0, 0.0)),
        Settings {
            time_step: 0.0,
            ..Settings::default()
        },
    );
    let before = w.bodies.clone();
    for _ in 0..10 {
        w.step();
    }
    assert_eq!(w.bodies, before);
    // Huge time step: a body falls far through the ground in one step and is put back on it.
    let mut w = two_bodies(
        (100.0, DVec3::new(0.0, 5.0, 0.0)),
        (100.0, DVec3::new(10.0, 5.0, 0.0)),
        Settings {
            time_step: 10.0,
            ..Settings::default()
        },
    );
    for _ in 0..20 {
        w.step();
    }
    assert!(w.all_finite() && depth_below_ground(&w) < 1e-9);
    // A body of tiny mass on one of huge mass (ratio 1e9).
    let mut w = two_bodies(
        (1e6, DVec3::new(0.0, 1.0, 0.0)),
        (1e-3, DVec3::new(0.0, 3.0, 0.0)),
        Settings {
            restitution: 0.0,
            ..Settings::default()
        },
    );
    for _ in 0..1000 {
        w.step();
    }
    assert!(w.all_finite());
    assert!(
        w.bodies[1].position.y > w.bodies[0].position.y,
        "the light body fell through the heavy one"
    );
}

#[test]
fn injected_nan_is_quarantined_and_does_not_spread() {
    let mut world = tumble::scene::load(
        "stress",
        &tumble::ConstraintsChoice::Auto,
        Settings::default(),
    )
    .unwrap();
    for _ in 0..50 {
        world.step();
    }
    let victim = world.bodies.iter().position(|b| !b.fixed).unwrap();
    world.bodies[victim].linear_velocity = DVec3::new(f64::NAN, 0.0, 0.0);
    let stats = world.step();
    assert_eq!(stats.quarantined, vec![victim]);
    assert!(world.bodies[victim].quarantined && world.bodies[victim].is_finite());
    for _ in 0..300 {
        let stats = world.step();
        assert!(stats.quarantined.is_empty());
    }
    assert!(world.all_finite(), "NaN reached other bodies");
    // A blown-up speed is quarantined too.
    let other = world
        .bodies
        .iter()
        .rposition(|b| !b.fixed && !b.quarantined)
        .unwrap();
    world.bodies[other].angular_velocity = DVec3::splat(1e300);
    assert_eq!(world.step().quarantined, vec![other]);
}

/// A pose made non-finite between steps (an edit, not the solver) is frozen at the last finite
/// pose the pose check saw, under both solvers (the soft step measures motion from those same
/// poses and must not overwrite them with the bad one), and the NaN reaches no other body.
#[test]
fn a_pose_edited_to_nan_is_frozen_at_its_last_finite_pose() {
    for settings in [Settings::default(), Settings::accurate()] {
        let mut world =
            tumble::scene::load("mixed", &tumble::ConstraintsChoice::Auto, settings).unwrap();
        for _ in 0..30 {
            world.step();
        }
        let victim = world.bodies.iter().position(|b| !b.fixed).unwrap();
        let last = (
            world.bodies[victim].position,
            world.bodies[victim].orientation,
        );
        world.bodies[victim].position.y = f64::NAN;
        assert_eq!(world.step().quarantined, vec![victim]);
        let b = &world.bodies[victim];
        assert!(b.quarantined && b.is_finite());
        assert_eq!((b.position, b.orientation), last);
        for _ in 0..100 {
            assert!(world.step().quarantined.is_empty());
        }
        assert!(world.all_finite(), "NaN reached other bodies");
    }
}

/// Tunnelling: a fast box thrown at a thin fixed wall. At dt = 0.04 it moves 8 units a step and
/// skips the 1-unit wall; 8 substeps (1 unit each) catch it.
fn thrown_at_wall(settings: Settings) -> f64 {
    let mut world = common::box_thrown_at_wall(settings);
    for _ in 0..10 {
        world.step();
    }
    world.bodies[0].position.x
}

#[test]
fn large_steps_tunnel_and_substeps_catch_it() {
    let coarse = thrown_at_wall(Settings {
        time_step: 0.04,
        ..Settings::default()
    });
    assert!(
        coarse > 0.0,
        "expected the coursework step to tunnel through the wall (x = {coarse})"
    );
    let substepped = thrown_at_wall(Settings {
        time_step: 0.04,
        substeps: 8,
        ..Settings::default()
    });
    assert!(
        substepped < 0.0,
        "8 substeps should stop the box at the wall (x = {substepped})"
    );
}

#[test]
fn far_away_bodies_neither_hang_nor_panic() {
    // Grid cells far beyond the i64 range once overflowed `hi - lo` (an almost endless loop over
    // cells in release). Bodies at 1e15 and 1e300, a box 2e20 wide (more cells than i64 holds),
    // and others near the origin, for both broad phases.
    for broad_phase in [
        tumble::sim::settings::BroadPhase::Grid,
        tumble::sim::settings::BroadPhase::AllPairs,
    ] {
        let settings = Settings {
            broad_phase,
            ..Settings::default()
        };
        let s = tumble::Shape::from_tet_mesh(&assets::cuboid(DVec3::ONE)).unwrap();
        let wide = tumble::Shape::from_tet_mesh(&assets::cuboid(DVec3::splat(1e20))).unwrap();
        let at = |shape: &tumble::Shape, index, p| {
            tumble::RigidBody::on_shape(shape, index, 1.0, false, p, DQuat::IDENTITY)
        };
        let bodies = vec![
            at(&s, 0, DVec3::new(1e15, 5.0, -1e15)),
            at(&s, 0, DVec3::new(1e15 + 0.5, 5.5, -1e15)),
            at(&s, 0, DVec3::splat(1e300)),
            at(&s, 0, DVec3::new(-1e300, 1e300, 0.0)),
            at(&wide, 1, DVec3::new(0.0, 2e20, 0.0)),
            at(&s, 0, DVec3::new(0.0, 3.0, 0.0)),
            at(&s, 0, DVec3::new(0.5, 5.5, 0.0)),
        ];
        let mut world = World::new(
            vec![s, wide],
            vec!["box".into(), "wide".into()],
            bodies,
            Vec::new(),
            settings,
        );
        let start = std::time::Instant::now();
        for _ in 0..50 {
            world.step();
        }
        // Generous: 50 steps of 7 bodies take microseconds; the old grid looped for ages.
        assert!(
            start.elapsed().as_secs_f64() < 5.0,
            "{broad_phase:?} took too long"
        );
        for b in &world.bodies {
            assert!(b.is_finite(), "{broad_phase:?}: {b:?}");
        }
    }
}

/// Bodies near the end of the double range (a coordinate of 9e307 or 1e308, where a box's
/// size or a speed times a step overflows) under the soft step: frozen and reported, not a
/// panic. Until stop 62 the twist friction's clamp panicked on the NaN limit such a body's
/// contact gave (a tetrahedron at y = 9e307, found by a review with hand-made scenes).
#[test]
fn bodies_at_the_end_of_the_double_range_are_frozen_not_a_panic() {
    let s = tumble::Shape::from_tet_mesh(&assets::tetrahedron(1.0)).unwrap();
    for p in [
        DVec3::new(0.0, 9e307, 10.0),
        DVec3::new(0.0, 1e308, 10.0),
        DVec3::new(0.0, 0.0, -9e307),
        DVec3::new(1e308, 3.0, 0.0),
    ] {
        let spin = DQuat::from_xyzw(1.0, 0.0, 0.0, 0.0);
        let far = tumble::RigidBody::on_shape(&s, 0, 100.0, false, p, spin);
        let near = tumble::RigidBody::on_shape(&s, 0, 100.0, false, DVec3::Y, spin);
        let mut world = World::new(
            vec![s.clone()],
            vec!["tet".into()],
            vec![far, near],
            Vec::new(),
            Settings::accurate(),
        );
        let mut quarantined = 0;
        for _ in 0..200 {
            quarantined += world.step().quarantined.len();
        }
        let b = &world.bodies[0];
        assert!(
            b.is_finite() || quarantined > 0,
            "{p}: non-finite and not reported"
        );
        assert!(world.bodies[1].is_finite(), "{p}: the body near the origin");
    }
}

#[test]
fn nan_does_not_reach_a_constrained_partner() {
    // Two boxes tied by a distance constraint; one gets an infinite velocity. The constraint's
    // velocity projection must not hand it to the other before the pose check freezes the first.
    let s = tumble::Shape::from_tet_mesh(&assets::cuboid(DVec3::ONE)).unwrap();
    let bodies = vec![
        tumble::RigidBody::on_shape(
            &s,
            0,
            1.0,
            false,
            DVec3::new(0.0, 10.0, 0.0),
            DQuat::IDENTITY,
        ),
        tumble::RigidBody::on_shape(
            &s,
            0,
            1.0,
            false,
            DVec3::new(3.0, 10.0, 0.0),
            DQuat::IDENTITY,
        ),
    ];
    let constraints = tumble::sim::constraint::DistanceConstraint::lower_and_upper(
        &bodies,
        std::slice::from_ref(&s),
        (0, 0),
        (1, 0),
        1.0,
        1.0,
    )
    .to_vec();
    for bad in [f64::INFINITY, f64::NAN] {
        let mut world = World::new(
            vec![s.clone()],
            vec!["box".into()],
            bodies.clone(),
            constraints.clone(),
            Settings::default(),
        );
        world.bodies[0].linear_velocity = DVec3::new(bad, 0.0, 0.0);
        let stats = world.step();
        assert_eq!(stats.quarantined, vec![0], "{bad}");
        assert!(world.bodies[1].is_finite(), "{bad} reached the partner");
        // From then on the frozen body is a fixed anchor: the partner hangs from it.
        let anchor = world.bodies[0].position;
        for _ in 0..200 {
            world.step();
        }
        assert_eq!(world.bodies[0].position, anchor);
        assert!(world.all_finite());
        let c = &world.constraints[0];
        let (p1, p2) = c.points(&world.bodies);
        assert!(((p1 - p2).length() - c.rest_length).abs() < 0.01);
        // Its energy is reported apart from the moving bodies'.
        let g = world.settings.gravity;
        assert_eq!(world.frozen_energy(), world.bodies[0].energy(g));
        assert_eq!(world.total_energy(), world.bodies[1].energy(g));
    }
}

/// Simulated time under time steps that are not valid (not finite, negative): each such step
/// counts as none, as the step itself takes it, and the time goes on from where it stood once
/// the step is valid again (counted from there: 0.2 + 10 x 0.02).
#[test]
fn the_time_holds_through_steps_that_are_not_valid() {
    for solver in [Solver::Coursework, Solver::SoftStep] {
        let settings = Settings {
            solver,
            time_step: 0.02,
            ..Settings::default()
        };
        let mut world = two_bodies(
            (1.0, DVec3::new(0.0, 5.0, 0.0)),
            (1.0, DVec3::new(5.0, 5.0, 0.0)),
            settings,
        );
        for _ in 0..10 {
            world.step();
        }
        assert_eq!(world.time, 0.2, "{solver:?}");
        for bad in [f64::NAN, f64::INFINITY, -0.02] {
            world.settings.time_step = bad;
            world.step();
            assert_eq!(world.time, 0.2, "{solver:?}, dt {bad}");
        }
        world.settings.time_step = 0.02;
        for _ in 0..10 {
            world.step();
        }
        assert_eq!(world.time, 0.2 + 10.0 * 0.02, "{solver:?}");
        assert_eq!(world.step_count, 23);
    }
}
