//! Snapshots and grabs, the core of the viewer's rewind and mouse drag: restoring a snapshot
//! repeats the following steps bit for bit (both solvers), and a grab pulls like the
//! critically damped spring it is.
mod common;

use glam::{DQuat, DVec3};
use tumble::scene::assets;
use tumble::sim::Grab;
use tumble::{ConstraintsChoice, RigidBody, Settings, World};

fn states(world: &World) -> Vec<[f64; 13]> {
    world
        .bodies
        .iter()
        .map(|b| {
            let (p, q, v, w) = (
                b.position,
                b.orientation,
                b.linear_velocity,
                b.angular_velocity,
            );
            [
                p.x, p.y, p.z, q.x, q.y, q.z, q.w, v.x, v.y, v.z, w.x, w.y, w.z,
            ]
        })
        .collect()
}

#[test]
fn restoring_a_snapshot_repeats_the_steps_bit_for_bit() {
    for settings in [Settings::default(), Settings::accurate()] {
        for scene in ["pile-120", "two-chain", "stress"] {
            let mut world =
                tumble::scene::load(scene, &ConstraintsChoice::Auto, settings.clone()).unwrap();
            let mut saved = None;
            for k in 0..200 {
                if k == 100 {
                    saved = Some(world.snapshot());
                }
                world.step();
            }
            let first = states(&world);
            let time = world.time;
            world.restore(saved.as_ref().unwrap());
            assert_eq!(world.step_count, 100);
            for _ in 0..100 {
                world.step();
            }
            let what = format!("{scene}, solver {:?}", settings.solver);
            assert!(first == states(&world), "{what}: rewound run differs");
            assert_eq!(world.time, time, "{what}");
            assert!(saved.unwrap().heap_bytes() > 0);
        }
    }
}

/// A world put back to its snapshot at load (the viewer's reset) runs like a freshly loaded one:
/// after a stretch where bodies fell asleep, one went non-finite and the soft step's caches and
/// the broad phase's pairs filled up.
#[test]
fn a_world_restored_to_its_start_runs_like_a_fresh_one() {
    for settings in [Settings::default(), Settings::accurate()] {
        for scene in ["pile-120", "two-chain"] {
            let load = || tumble::scene::load(scene, &ConstraintsChoice::Auto, settings.clone());
            let mut world = load().unwrap();
            let start = world.snapshot();
            for _ in 0..300 {
                world.step();
            }
            world.bodies[3].linear_velocity = DVec3::new(f64::NAN, 0.0, 0.0);
            world.step();
            world.restore(&start);
            let mut fresh = load().unwrap();
            assert_eq!(states(&world), states(&fresh));
            for _ in 0..150 {
                world.step();
                fresh.step();
            }
            let what = format!("{scene}, solver {:?}", settings.solver);
            assert!(
                states(&world) == states(&fresh),
                "{what}: reset run differs"
            );
            let flags = |w: &World| -> Vec<(bool, bool, f64)> {
                w.bodies
                    .iter()
                    .map(|b| (b.asleep, b.quarantined, b.sleep_time))
                    .collect()
            };
            assert_eq!(flags(&world), flags(&fresh), "{what}");
        }
    }
}

/// A box of `density` at rest 50 units up.
fn lone_box(settings: Settings, density: f64) -> World {
    let s = tumble::Shape::from_tet_mesh(&assets::cuboid(DVec3::new(1.0, 0.5, 0.75))).unwrap();
    let b = RigidBody::on_shape(
        &s,
        0,
        density,
        false,
        DVec3::new(0.0, 50.0, 0.0),
        DQuat::IDENTITY,
    );
    World::new(vec![s], vec!["box".into()], vec![b], Vec::new(), settings)
}

#[test]
fn a_grab_is_a_critically_damped_spring() {
    for base in [Settings::default(), Settings::accurate()] {
        let settings = Settings {
            gravity: DVec3::ZERO,
            ..base
        };
        // Four orders of magnitude apart in mass: the spring's force scales with it.
        let masses =
            [0.1, 1000.0].map(|density| lone_box(settings.clone(), density).bodies[0].mass);
        assert!(masses[1] > 1e3 * masses[0], "{masses:?}");
        for density in [0.1, 1000.0] {
            let mut world = lone_box(settings.clone(), density);
            let target = DVec3::new(3.0, 52.0, -1.0);
            world.grab = Some(Grab {
                body: 0,
                local_point: DVec3::ZERO,
                target,
                hertz: 2.0,
            });
            // One step of the spring from rest: at the centre of mass K = 1/m, so the velocity
            // change is -mass_scale (v + bias_rate C) with the soft-constraint factors of a
            // critically damped 2 Hz spring over the step.
            // (Measured on one substep: h = dt.)
            let h = settings.time_step;
            let omega = 2.0 * std::f64::consts::PI * 2.0;
            let (a1, a2) = (2.0 + h * omega, h * omega * (2.0 + h * omega));
            let (bias_rate, mass_scale) = (omega / a1, a2 / (1.0 + a2));
            let c = DVec3::new(0.0, 50.0, 0.0) - target;
            let expected = -mass_scale * bias_rate * c;
            let mut probe = world.clone();
            probe.settings.substeps = 1;
            probe.step();
            let what = format!("solver {:?}, density {density}", settings.solver);
            common::assert_vec_close(probe.bodies[0].linear_velocity, expected, 1e-12, &what);
            // Pulled to the target within a few periods, without overshooting it.
            let mut closest = f64::INFINITY;
            let mut overshoot: f64 = 0.0;
            let direction = (target - world.bodies[0].position).normalize();
            for _ in 0..((3.0 / settings.time_step) as usize) {
                world.step();
                let to_target = target - world.bodies[0].position;
                closest = closest.min(to_target.length());
                overshoot = overshoot.max(-to_target.dot(direction));
            }
            assert!(closest < 1e-3, "{what}: came within {closest}");
            assert!(overshoot < 1e-6, "{what}: overshot by {overshoot}");
        }
    }
}
