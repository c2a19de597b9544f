//! The scalable step gives bit-identical results: grid broad phase vs all pairs, any thread
//! count; the sparse constraint schedule reaches the sweep's tolerance with fewer visits.
mod common;

use tumble::sim::settings::{BroadPhase, ConstraintSchedule};
use tumble::{ConstraintsChoice, Settings, World};

fn trajectory(world: &mut World, steps: usize) -> Vec<u64> {
    let mut bits = Vec::new();
    for _ in 0..steps {
        world.step();
        for b in &world.bodies {
            let q = b.orientation;
            for v in [
                b.position.x,
                b.position.y,
                b.position.z,
                q.x,
                q.y,
                q.z,
                q.w,
                b.linear_velocity.x,
                b.linear_velocity.y,
                b.linear_velocity.z,
                b.angular_velocity.x,
                b.angular_velocity.y,
                b.angular_velocity.z,
            ] {
                bits.push(v.to_bits());
            }
        }
    }
    bits
}

fn scenes(settings: &Settings) -> Vec<(String, World)> {
    let mut out: Vec<(String, World)> = Vec::new();
    for name in ["mixed", "tower", "stress", "cube", "two-chain"] {
        out.push((
            name.into(),
            tumble::scene::load(name, &ConstraintsChoice::Auto, settings.clone()).unwrap(),
        ));
    }
    out.push((
        "pile-120".into(),
        tumble::scene::generate::pile(120, settings.clone()),
    ));
    out.push((
        "sparse-200".into(),
        tumble::scene::generate::sparse(200, settings.clone()),
    ));
    if let Some(dir) = common::coursework_dir() {
        for name in [
            "mixed-scene.txt",
            "stress-scene.txt",
            "tet-scene.txt",
            "two_chain-scene.txt",
        ] {
            out.push((
                name.into(),
                tumble::scene::load_file(
                    &dir.join(name),
                    &ConstraintsChoice::Auto,
                    settings.clone(),
                )
                .unwrap(),
            ));
        }
    }
    out
}

#[test]
fn grid_broad_phase_reproduces_all_pairs_bit_for_bit() {
    let grid = Settings {
        broad_phase: BroadPhase::Grid,
        ..Settings::default()
    };
    let all = Settings {
        broad_phase: BroadPhase::AllPairs,
        ..Settings::default()
    };
    let mut contacts = 0;
    for ((name, a), (_, b)) in scenes(&grid).into_iter().zip(scenes(&all)) {
        let mut probe = a.clone();
        for _ in 0..300 {
            contacts += probe.step().contacts;
        }
        assert!(
            trajectory(&mut { a }, 300) == trajectory(&mut { b }, 300),
            "{name}: grid and all-pairs trajectories differ"
        );
    }
    assert!(
        contacts > 100,
        "the scenes must actually collide ({contacts} contacts)"
    );
}

#[test]
fn results_do_not_depend_on_thread_count() {
    let run = |threads: usize| {
        common::with_threads(threads, || {
            scenes(&Settings::default())
                .into_iter()
                .map(|(_, mut w)| trajectory(&mut w, 200))
                .collect::<Vec<_>>()
        })
    };
    assert!(
        run(1) == run(2),
        "1 and 2 threads give different trajectories"
    );
    assert!(run(2) == run(2), "two runs give different trajectories");
}

/// `World::stepping` runs a loop of steps where the world's steps run, in the thread pool for a
/// scene of 64 bodies or more and on the calling thread below: the same bits as the steps called
/// one by one from outside the pool, under either solver.
#[test]
fn a_loop_of_steps_run_where_its_steps_run_gives_their_bits() {
    for settings in [Settings::default(), Settings::accurate()] {
        for (name, world) in scenes(&settings).into_iter().take(7) {
            let expected = trajectory(&mut world.clone(), 120);
            let (on_pool, looped) = world.clone().stepping(|w| {
                let on_pool = rayon::current_thread_index().is_some();
                (on_pool, trajectory(w, 120))
            });
            assert_eq!(on_pool, world.bodies.len() >= 64, "{name}: where it ran");
            assert!(looped == expected, "{name}: other bits");
        }
    }
}

#[test]
fn sparse_schedule_reaches_tolerance_with_fewer_visits() {
    // A budget no step reaches (the skeleton's rule allows max_iterations / M visits).
    let base = Settings {
        max_iterations: 1_000_000_000,
        ..Settings::default()
    };
    for (name, make) in [("chain-100", 0), ("two-chain", 1)] {
        let build = |schedule| {
            let s = Settings {
                constraint_schedule: schedule,
                ..base.clone()
            };
            if make == 0 {
                tumble::scene::generate::chain(100, s)
            } else {
                tumble::scene::load("two-chain", &ConstraintsChoice::Auto, s).unwrap()
            }
        };
        let (mut sweep, mut sparse) = (
            build(ConstraintSchedule::Sweep),
            build(ConstraintSchedule::Sparse),
        );
        let (mut sweep_visits, mut sparse_visits) = (0, 0);
        for step in 0..300 {
            let a = sweep.step();
            let b = sparse.step();
            sweep_visits += a.constraint_visits;
            sparse_visits += b.constraint_visits;
            // Whenever the sweep gets every constraint within tolerance, so does the work list.
            assert!(
                !b.budget_hit,
                "{name}: sparse ran out of budget at step {step}"
            );
            if !a.budget_hit {
                let worst = sparse
                    .constraints
                    .iter()
                    .map(|c| c.violation(&sparse.bodies))
                    .fold(0.0, f64::max);
                assert!(
                    worst <= base.tolerance * (1.0 + 1e-9),
                    "{name}: step {step}: sparse left a violation of {worst}"
                );
            }
        }
        assert!(
            sparse_visits < sweep_visits,
            "{name}: sparse {sparse_visits} visits, sweep {sweep_visits}"
        );
    }
}

#[test]
fn sparse_schedule_keeps_going_until_nothing_is_violated() {
    // A chain stretched far beyond its bounds needs many rounds of corrections: a work list that
    // stopped after one pass would leave violations behind.
    let settings = Settings {
        constraint_schedule: ConstraintSchedule::Sparse,
        max_iterations: 1_000_000,
        gravity: glam::DVec3::ZERO,
        ..Settings::default()
    };
    let mut world = tumble::scene::generate::chain(10, settings);
    for (k, b) in world.bodies.iter_mut().enumerate().skip(1) {
        b.position.y -= 3.0 * k as f64;
    }
    let stats = world.step();
    let worst = world
        .constraints
        .iter()
        .map(|c| c.violation(&world.bodies))
        .fold(0.0, f64::max);
    assert!(!stats.budget_hit);
    assert!(
        stats.constraint_visits > world.constraints.len(),
        "only {} visits",
        stats.constraint_visits
    );
    assert!(worst <= 1e-3 + 1e-12, "violation {worst} left");
    // And a tiny budget is reported honestly: max_iterations = 3 M allows 3 visits.
    let m = world.constraints.len();
    let mut world = tumble::scene::generate::chain(
        10,
        Settings {
            max_iterations: 3 * m,
            ..world.settings.clone()
        },
    );
    for (k, b) in world.bodies.iter_mut().enumerate().skip(1) {
        b.position.y -= 3.0 * k as f64;
    }
    let stats = world.step();
    assert!(stats.budget_hit && stats.constraint_visits == 3);
}
