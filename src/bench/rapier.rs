//! Rapier on a tumble scene, for the benchmarks: the same convex hulls, densities, poses and
//! velocities, time step, gravity, friction and restitution, the ground as a fixed slab whose
//! top is y = 0, and each distance constraint's upper bound as a rope joint (Rapier has no
//! lower-bound distance joint). Everything else is left at Rapier's defaults, as a Rapier user
//! would set the scene up.

use crate::sim::World;
use rapier3d_f64::prelude::*;

pub struct RapierScene {
    world: PhysicsWorld,
    handles: Vec<RigidBodyHandle>,
}

impl RapierScene {
    /// The scene of `source` (with its settings); `sleeping` lets Rapier put resting bodies to
    /// sleep (its default).
    pub fn from_world(source: &World, sleeping: bool) -> Self {
        let settings = &source.settings;
        let mut world = PhysicsWorld::new();
        world.gravity = settings.gravity;
        world.integration_parameters.dt = settings.time_step;
        let (mu, e) = (settings.friction, settings.restitution);
        let ground =
            world.insert_body(RigidBodyBuilder::fixed().translation(Vector::new(0.0, -1.0, 0.0)));
        world.insert_collider(
            ColliderBuilder::cuboid(1.0e5, 1.0, 1.0e5)
                .friction(mu)
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
                .can_sleep(sleeping);
            let hull = &source.shapes[body.shape].rest_vertices;
            let collider = ColliderBuilder::convex_hull(hull)
                .expect("tumble's shapes have hulls")
                .density(if body.fixed { 1.0 } else { body.density })
                .friction(mu)
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
        Self { world, handles }
    }

    /// One step; returns its wall time in seconds.
    pub fn step(&mut self) -> f64 {
        let start = std::time::Instant::now();
        self.world.step();
        start.elapsed().as_secs_f64()
    }

    /// Bodies Rapier has put to sleep.
    pub fn asleep(&self) -> usize {
        self.world
            .bodies
            .iter()
            .filter(|(_, b)| b.is_sleeping())
            .count()
    }

    /// Copies poses and velocities into `world` (its mirror) and advances its clock by a step.
    pub fn copy_into(&self, world: &mut World) {
        for (body, &handle) in world.bodies.iter_mut().zip(&self.handles) {
            let Some(rb) = self.world.bodies.get(handle) else {
                continue;
            };
            let pose = rb.position();
            body.position = pose.translation;
            body.orientation = pose.rotation;
            body.linear_velocity = rb.linvel();
            body.angular_velocity = rb.angvel();
        }
        world.count_step(world.settings.time_step);
    }
}
