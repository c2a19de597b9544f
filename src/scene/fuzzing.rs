//! The `world` fuzz target's entry point (fuzz/fuzz_targets/world.rs), shared with the stable
//! corpus-replay test: arbitrary bytes decoded into what a scene file, a constraint file and the
//! viewer's panel can make (tumble's meshes anywhere, in each other or far apart, at any density
//! and speed, distance constraints with any legal bounds, either solver with any settings, a
//! grab, the settings changed halfway), then stepped. A panic, a non-finite body that was not
//! reported, or a reported body that is not frozen is a bug.

use crate::scene::assets;
use crate::sim::constraint::DistanceConstraint;
use crate::sim::grab::Grab;
use crate::sim::settings::{RotationIntegrator, Settings, Solver};
use crate::sim::shape::Shape;
use crate::{RigidBody, World};
use glam::{DQuat, DVec3};

/// Reads the input a byte at a time; zeros once it runs out.
struct Bytes<'a>(std::slice::Iter<'a, u8>);

impl Bytes<'_> {
    fn byte(&mut self) -> u8 {
        self.0.next().copied().unwrap_or(0)
    }

    fn bit(&mut self) -> bool {
        self.byte() & 1 == 1
    }

    /// `lo + (hi - lo) * byte / 255`.
    fn lerp(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.byte() as f64 / 255.0
    }

    /// A value of either sign whose magnitude spans `10^lo .. 10^hi` (zero for a zero byte).
    fn signed_log(&mut self, lo: f64, hi: f64) -> f64 {
        let b = self.byte();
        if b == 0 {
            return 0.0;
        }
        let magnitude = 10f64.powf(lo + (hi - lo) * (b >> 1) as f64 / 127.0);
        if b & 1 == 1 { -magnitude } else { magnitude }
    }

    fn vector(&mut self, f: impl Fn(&mut Self) -> f64) -> DVec3 {
        DVec3::new(f(self), f(self), f(self))
    }
}

fn settings(input: &mut Bytes) -> Settings {
    let base = if input.bit() {
        Settings::accurate()
    } else {
        Settings::default()
    };
    let mut s = Settings {
        solver: [Solver::Coursework, Solver::SoftStep][input.bit() as usize],
        time_step: [
            1e-4,
            0.001,
            0.01,
            0.02,
            0.04,
            0.1,
            0.5,
            0.0,
            -0.02,
            f64::NAN,
        ][input.byte() as usize % 10],
        // As typed on the command line: the step brings it into range.
        restitution: input.lerp(-0.5, 1.5),
        friction: input.lerp(0.0, 3.0),
        substeps: 1 + input.byte() as u32 % 12,
        max_iterations: [1, 10, 1000, 10_000][input.byte() as usize % 4],
        rotation_integrator: [
            RotationIntegrator::Coursework,
            RotationIntegrator::Gyroscopic,
            RotationIntegrator::AngularMomentum,
        ][input.byte() as usize % 3],
        restitution_threshold: input.lerp(0.0, 2.0),
        contact_patches: input.bit(),
        skip_separating_contacts: input.bit(),
        sleep: input.bit(),
        ..base
    };
    s.gravity = [s.gravity, DVec3::ZERO, DVec3::new(30.0, -9.8, -40.0)][input.byte() as usize % 3];
    s
}

fn body(input: &mut Bytes, shapes: &[Shape]) -> RigidBody {
    let mesh = input.byte() as usize % shapes.len();
    let density = 10f64.powf(input.lerp(-3.0, 6.0));
    let fixed = input.byte() < 40;
    // Within a few units of each other, or (a far byte) anywhere up to 1e9 away.
    let spread = if input.byte() > 240 { 1e9 } else { 4.0 };
    let position = input.vector(|b| b.lerp(-spread, spread)) + DVec3::Y * spread;
    let axis = input.vector(|b| b.lerp(-1.0, 1.0));
    let angle = input.lerp(-std::f64::consts::PI, std::f64::consts::PI);
    let orientation = if axis.length() > 1e-3 {
        DQuat::from_axis_angle(axis.normalize(), angle)
    } else {
        DQuat::IDENTITY
    };
    let mut b = RigidBody::on_shape(&shapes[mesh], mesh, density, fixed, position, orientation);
    if !b.fixed {
        b.linear_velocity = input.vector(|b| b.signed_log(-3.0, 6.0));
        b.angular_velocity = input.vector(|b| b.signed_log(-3.0, 4.0));
    }
    b
}

/// Records as a constraint file can give them: any two different bodies not both fixed (the
/// loader refuses the one and drops the other), any vertices, `0 <= lower <= upper`.
fn constraints(
    input: &mut Bytes,
    bodies: &[RigidBody],
    shapes: &[Shape],
) -> Vec<DistanceConstraint> {
    let mut out = Vec::new();
    for _ in 0..input.byte() % 6 {
        let (i, j) = (input.byte() as usize, input.byte() as usize);
        let (i, j) = (i % bodies.len(), j % bodies.len());
        if i == j || (bodies[i].fixed && bodies[j].fixed) {
            continue;
        }
        let vertex = |input: &mut Bytes, body: usize| {
            input.byte() as usize % shapes[bodies[body].shape].rest_vertices.len()
        };
        let (vi, vj) = (vertex(input, i), vertex(input, j));
        let lower = input.lerp(0.0, 1.5);
        let upper = lower + input.signed_log(-4.0, 3.0).abs();
        out.extend(DistanceConstraint::lower_and_upper(
            bodies,
            shapes,
            (i, vi),
            (j, vj),
            lower,
            upper,
        ));
    }
    out
}

/// Cases the draws above do not reach, drawn last so that inputs that end before them (zeros:
/// no change) keep their meaning (the corpus's five that ran on past the grab were cut to the
/// bytes they used; their longer forms are kept beside them, as `-far`): a body near the end
/// of the double range (a soft-step panic at 9e307 was found by hand), and a constraint pair
/// whose points start together (a zero-length joint, which the soft step once left unsolved;
/// the body moved leaves its other constraints violated, as a grab can).
fn extremes(input: &mut Bytes, bodies: &mut [RigidBody], constraints: &mut [DistanceConstraint]) {
    if input.bit() {
        let k = input.byte() as usize % bodies.len();
        bodies[k].position = input.vector(|b| b.signed_log(2.0, 307.9));
    }
    if input.bit() && !constraints.is_empty() {
        // `constraints` holds pairs: each record's lower and upper inequality.
        let pair = 2 * (input.byte() as usize % (constraints.len() / 2));
        let c = constraints[pair].clone();
        let (p1, p2) = (
            bodies[c.body1].world_point(c.local1),
            bodies[c.body2].world_point(c.local2),
        );
        match (bodies[c.body1].fixed, bodies[c.body2].fixed) {
            (_, false) => bodies[c.body2].position += p1 - p2,
            (false, true) => bodies[c.body1].position += p2 - p1,
            (true, true) => {}
        }
        for c in &mut constraints[pair..pair + 2] {
            (c.rest_length, c.reference) = (0.0, 0.0);
        }
    }
}

/// Builds a world from `data` and steps it, changing its settings and grabbing a body halfway.
pub fn world(data: &[u8]) {
    let mut input = Bytes(data.iter());
    let shapes: Vec<Shape> = assets::all_meshes()
        .iter()
        .filter_map(|(_, mesh)| Shape::from_tet_mesh(mesh).ok())
        .collect();
    let first = settings(&mut input);
    let count = 1 + input.byte() as usize % 12;
    let mut bodies: Vec<RigidBody> = (0..count).map(|_| body(&mut input, &shapes)).collect();
    let mut constraints = constraints(&mut input, &bodies, &shapes);
    let later = settings(&mut input);
    let grab = input.bit().then(|| Grab {
        body: input.byte() as usize % count,
        local_point: input.vector(|b| b.lerp(-1.0, 1.0)),
        target: input.vector(|b| b.lerp(-20.0, 20.0)),
        hertz: input.lerp(0.0, 200.0),
    });
    extremes(&mut input, &mut bodies, &mut constraints);
    let names = vec![String::new(); shapes.len()];
    let mut world = World::new(shapes, names, bodies, constraints, first);
    let reported = run_with_change(&mut world, 60, &later, grab);
    assert!(world.all_finite(), "a body went non-finite unreported");
    for (i, b) in world.bodies.iter().enumerate() {
        assert_eq!(b.quarantined, reported.contains(&i), "body {i}");
    }
}

/// Runs `world` for `steps` steps: the first half with its settings, the second with `later`
/// and `grab` pulling, as a viewer user would change them. Returns the bodies the steps froze
/// (quarantined). Shared with the property tests of the step.
pub fn run_with_change(
    world: &mut World,
    steps: usize,
    later: &Settings,
    grab: Option<Grab>,
) -> Vec<usize> {
    let mut reported = Vec::new();
    for k in 0..steps {
        if k == steps / 2 {
            world.settings = later.clone();
            world.grab = grab;
        }
        reported.extend(world.step().quarantined);
    }
    reported
}
