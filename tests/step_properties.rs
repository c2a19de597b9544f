//! Property test of the step: random small scenes from tumble's meshes, with random but legal
//! states and settings, stay finite for a few hundred steps, or the step names the body that
//! went non-finite (quarantine) and the rest stay finite.
use glam::{DQuat, DVec3};
use proptest::prelude::*;
use tumble::scene::assets;
use tumble::sim::settings::{ConstraintSchedule, RotationIntegrator};
use tumble::{RigidBody, Settings, Shape, World};

#[derive(Debug, Clone)]
struct BodySpec {
    mesh: usize,
    log_density: f64,
    fixed: bool,
    position: [f64; 3],
    axis: [f64; 3],
    angle: f64,
    velocity: [f64; 3],
    spin: [f64; 3],
}

fn body_spec() -> impl Strategy<Value = BodySpec> {
    (
        0usize..6,
        -1.0f64..4.0,
        prop::bool::weighted(0.15),
        [-30.0f64..30.0, 0.0f64..60.0, -30.0f64..30.0],
        [-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0],
        -3.2f64..3.2,
        [-100.0f64..100.0, -100.0f64..100.0, -100.0f64..100.0],
        [-20.0f64..20.0, -20.0f64..20.0, -20.0f64..20.0],
    )
        .prop_map(
            |(mesh, log_density, fixed, position, axis, angle, velocity, spin)| BodySpec {
                mesh,
                log_density,
                fixed,
                position,
                axis,
                angle,
                velocity,
                spin,
            },
        )
}

fn settings() -> impl Strategy<Value = Settings> {
    (
        1e-4f64..0.08,
        0.0f64..=1.0,
        1usize..2000,
        1e-5f64..1e-1,
        any::<bool>(),
        0.0f64..2.0,
        1u32..4,
        0usize..4,
        any::<bool>(),
        any::<bool>(),
    )
        .prop_map(
            |(
                time_step,
                restitution,
                max_iterations,
                tolerance,
                skip,
                threshold,
                substeps,
                integrator,
                sparse,
                patches,
            )| Settings {
                time_step,
                restitution,
                max_iterations,
                tolerance,
                skip_separating_contacts: skip,
                restitution_threshold: threshold,
                substeps,
                rotation_integrator: [
                    RotationIntegrator::Coursework,
                    RotationIntegrator::Gyroscopic,
                    RotationIntegrator::AngularMomentum,
                    RotationIntegrator::Coursework,
                ][integrator],
                constraint_schedule: if sparse {
                    ConstraintSchedule::Sparse
                } else {
                    ConstraintSchedule::Sweep
                },
                contact_patches: patches,
                ..Settings::default()
            },
        )
}

fn build(specs: &[BodySpec], links: &[(usize, usize, f64, f64)], settings: Settings) -> World {
    let shapes: Vec<Shape> = assets::all_meshes()
        .iter()
        .map(|(_, m)| Shape::from_tet_mesh(m).unwrap())
        .collect();
    let bodies: Vec<RigidBody> = specs
        .iter()
        .map(|s| {
            let shape = &shapes[s.mesh];
            let axis = DVec3::from(s.axis);
            let q = if axis.length() > 1e-3 {
                DQuat::from_axis_angle(axis.normalize(), s.angle)
            } else {
                DQuat::IDENTITY
            };
            let mut b = RigidBody::on_shape(
                shape,
                s.mesh,
                10f64.powf(s.log_density),
                s.fixed,
                DVec3::from(s.position),
                q,
            );
            if !b.fixed {
                b.linear_velocity = DVec3::from(s.velocity);
                b.angular_velocity = DVec3::from(s.spin);
            }
            b
        })
        .collect();
    let mut constraints = Vec::new();
    for &(i, j, lower, width) in links {
        let (i, j) = (i % bodies.len(), j % bodies.len());
        if i == j || (bodies[i].fixed && bodies[j].fixed) {
            continue;
        }
        constraints.extend(
            tumble::sim::constraint::DistanceConstraint::lower_and_upper(
                &bodies,
                &shapes,
                (i, 0),
                (j, 0),
                lower,
                lower + width,
            ),
        );
    }
    World::new(
        shapes,
        vec![String::new(); 6],
        bodies,
        constraints,
        settings,
    )
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, failure_persistence: None, .. ProptestConfig::default() })]
    #[test]
    fn random_scenes_stay_finite(
        specs in prop::collection::vec(body_spec(), 1..12),
        links in prop::collection::vec((0usize..12, 0usize..12, 0.0f64..1.0, 0.0f64..1.0), 0..6),
        settings in settings(),
    ) {
        let mut world = build(&specs, &links, settings);
        let mut quarantined = Vec::new();
        for _ in 0..300 {
            let stats = world.step();
            quarantined.extend(stats.quarantined);
        }
        // Every body is finite: either it stayed so, or it was frozen at its last finite state
        // and reported.
        prop_assert!(world.all_finite());
        for (i, b) in world.bodies.iter().enumerate() {
            prop_assert_eq!(b.quarantined, quarantined.contains(&i));
        }
    }
}
