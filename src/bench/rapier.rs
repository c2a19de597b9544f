//! Variant (d) of `tumble bench scale`: the same generated scene stepped by Rapier, with the same
//! convex hulls, densities, time step, gravity and restitution, friction 0 and sleeping off.
//! Chain links become rope joints at the upper bound (Rapier has no lower-bound distance joint).

use rapier3d_f64::prelude::*;
use std::time::Instant;

pub struct RapierScene {
    world: PhysicsWorld,
}

impl RapierScene {
    pub fn from_world(source: &crate::sim::World) -> Self {
        let mut world = PhysicsWorld::new();
        world.gravity = source.settings.gravity;
        world.integration_parameters.dt = source.settings.time_step;
        let e = source.settings.restitution;
        let ground =
            world.insert_body(RigidBodyBuilder::fixed().translation(Vector::new(0.0, -1.0, 0.0)));
        world.insert_collider(
            ColliderBuilder::cuboid(1.0e5, 1.0, 1.0e5)
                .friction(0.0)
                .restitution(e),
            Some(ground),
        );
        let mut handles = Vec::with_capacity(source.bodies.len());
        for body in &source.bodies {
            let builder = if body.fixed {
                RigidBodyBuilder::fixed()
            } else {
                RigidBodyBuilder::dynamic()
            };
            let rb = builder
                .pose(Pose::from_parts(body.position, body.orientation))
                .linvel(body.linear_velocity)
                .angvel(body.angular_velocity)
                .can_sleep(false);
            let hull = &source.shapes[body.shape].rest_vertices;
            let collider = ColliderBuilder::convex_hull(hull)
                .expect("tumble's shapes have hulls")
                .density(if body.fixed { 1.0 } else { body.density })
                .friction(0.0)
                .restitution(e);
            let (handle, _) = world.insert(rb, collider);
            handles.push(handle);
        }
        for c in source.constraints.iter().filter(|c| c.is_upper) {
            let joint = RopeJointBuilder::new(c.reference)
                .local_anchor1(c.local1)
                .local_anchor2(c.local2);
            world.insert_impulse_joint(handles[c.body1], handles[c.body2], joint);
        }
        Self { world }
    }

    /// One step; returns its wall time in seconds.
    pub fn step(&mut self) -> f64 {
        let start = Instant::now();
        self.world.step();
        start.elapsed().as_secs_f64()
    }
}
