//! Accuracy scenarios: small worlds with an independent reference (closed form, conservation law,
//! or a fine-step / RK4 solution), each returning its error metrics. Used by
//! `tumble bench accuracy` and by the tests of the opt-in settings.

use crate::scene::assets;
use crate::sim::body::RigidBody;
use crate::sim::constraint::DistanceConstraint;
use crate::sim::settings::Settings;
use crate::sim::shape::Shape;
use crate::sim::world::World;
use glam::{DMat3, DQuat, DVec3};
use serde::Serialize;
use std::time::Instant;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "snake_case")]
pub enum Scenario {
    /// A box thrown upwards: position error against the closed form.
    #[cfg_attr(feature = "cli", value(alias = "free_fall"))]
    FreeFall,
    /// Torque-free spin of an ellipsoid near its intermediate axis: when it flips.
    #[cfg_attr(feature = "cli", value(alias = "spin_ellipsoid"))]
    SpinEllipsoid,
    /// The same for a long octahedron.
    #[cfg_attr(feature = "cli", value(alias = "spin_long_octahedron"))]
    SpinLongOctahedron,
    /// An octahedron bouncing at e = 1, 0.8 and 0.5: apex heights against e^2 a bounce. (The
    /// results' three names run it whole.)
    #[cfg_attr(
        feature = "cli",
        value(aliases = ["bounce_e1", "bounce_e0.8", "bounce_e0.5"])
    )]
    Bounce,
    /// A box on a rigid rod at its centre of mass: period and amplitude against the closed form.
    Pendulum,
    /// A box hung by a corner on a rigid rod: it turns as it swings, its energy kept.
    #[cfg_attr(feature = "cli", value(alias = "corner_pendulum"))]
    CornerPendulum,
    /// Boxes of very different densities stacked at rest: how far they drift.
    Tower,
    /// The built-in two-chain scene: its constraints' worst violation.
    Chains,
    /// The built-in mixed scene at e = 1, without friction: its energy kept.
    #[cfg_attr(feature = "cli", value(alias = "mixed_energy"))]
    MixedEnergy,
    /// A box on a 20 degree incline with mu = 0.5: static friction holds it.
    #[cfg_attr(feature = "cli", value(alias = "slope_20"))]
    Slope20,
    /// The same at 30 degrees: it slides with acceleration g (sin a - mu cos a).
    #[cfg_attr(feature = "cli", value(alias = "slope_30"))]
    Slope30,
    /// pile-200 with friction, dropped: it should come to rest without sinking in.
    #[cfg_attr(feature = "cli", value(alias = "pile_rest"))]
    PileRest,
}

impl Scenario {
    pub const ALL: [Scenario; 12] = [
        Scenario::FreeFall,
        Scenario::SpinEllipsoid,
        Scenario::SpinLongOctahedron,
        Scenario::Bounce,
        Scenario::Pendulum,
        Scenario::CornerPendulum,
        Scenario::Tower,
        Scenario::Chains,
        Scenario::MixedEnergy,
        Scenario::Slope20,
        Scenario::Slope30,
        Scenario::PileRest,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Scenario::FreeFall => "free_fall",
            Scenario::SpinEllipsoid => "spin_ellipsoid",
            Scenario::SpinLongOctahedron => "spin_long_octahedron",
            Scenario::Bounce => "bounce",
            Scenario::Pendulum => "pendulum",
            Scenario::CornerPendulum => "corner_pendulum",
            Scenario::Tower => "tower",
            Scenario::Chains => "chains",
            Scenario::MixedEnergy => "mixed_energy",
            Scenario::Slope20 => "slope_20",
            Scenario::Slope30 => "slope_30",
            Scenario::PileRest => "pile_rest",
        }
    }

    /// Name of the metric the plots use (the others are reported alongside).
    pub fn primary_metric(self) -> &'static str {
        match self {
            Scenario::FreeFall => "position_error",
            Scenario::SpinEllipsoid | Scenario::SpinLongOctahedron => "flip_time_error",
            Scenario::Bounce => "apex_ratio_error",
            Scenario::Pendulum => "period_error",
            Scenario::CornerPendulum => "energy_drift",
            Scenario::Tower => "drift",
            Scenario::Chains => "worst_relative_violation",
            Scenario::MixedEnergy => "energy_drift",
            Scenario::Slope20 => "displacement",
            Scenario::Slope30 => "acceleration_error",
            Scenario::PileRest => "max_speed",
        }
    }

    /// Simulated seconds.
    pub fn duration(self) -> f64 {
        match self {
            Scenario::FreeFall => 5.0,
            Scenario::SpinEllipsoid | Scenario::SpinLongOctahedron => 20.0,
            Scenario::Bounce => 12.0,
            Scenario::Pendulum | Scenario::CornerPendulum => 20.0,
            Scenario::Tower | Scenario::Chains | Scenario::MixedEnergy => 10.0,
            Scenario::Slope20 | Scenario::Slope30 => 5.0,
            Scenario::PileRest => 10.0,
        }
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct Outcome {
    /// Wall-clock seconds per simulated second.
    pub wall_per_sim_second: f64,
    /// (metric name, value); the scenario's primary metric comes first.
    pub metrics: Vec<(String, f64)>,
    pub finite: bool,
}

impl Outcome {
    pub fn primary(&self) -> f64 {
        self.metrics[0].1
    }
    pub fn metric(&self, name: &str) -> Option<f64> {
        self.metrics
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| *v)
    }
}

fn shape(mesh: &crate::io::TetMesh) -> Shape {
    Shape::from_tet_mesh(mesh).expect("tumble's meshes are valid")
}

fn single(shape: Shape, body: RigidBody, settings: Settings) -> World {
    World::new(
        vec![shape],
        vec!["body".into()],
        vec![body],
        Vec::new(),
        settings,
    )
}

/// What steps a scenario's world.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Engine {
    Tumble,
    /// Rapier on the same bodies, settings and constraints (feature `compare-rapier`): the
    /// scenario's world mirrors Rapier's state after every step.
    Rapier,
}

/// One scenario run: the settings and the engine.
pub struct Run {
    pub settings: Settings,
    pub engine: Engine,
}

/// Runs `world` for `duration` simulated seconds calling `observe` after every step; returns
/// the wall seconds of stepping (observation excluded) per simulated second. The loop runs
/// where the world's steps run ([`World::stepping`]): in the pool it is called in (`bench
/// accuracy`'s has one thread), for pile_rest, or else on the calling thread. Handed over once
/// a step from outside the pool, pile_rest under the soft step took 1.4-1.7x the time of an
/// earlier run of the same bits on another machine, where every other scenario (small enough
/// to step on the calling thread) and Rapier took the same or less. The world's stage timers
/// are off ([`World::time_stages`]), as Rapier's are by default: nothing here reads them.
fn simulate(
    engine: Engine,
    world: &mut World,
    duration: f64,
    mut observe: impl FnMut(&World, &crate::StepStats) + Send,
) -> f64 {
    let steps = if world.settings.time_step > 0.0 {
        (duration / world.settings.time_step).round() as usize
    } else {
        0
    };
    world.time_stages = false;
    let mut step = stepper(engine, world);
    let stepping = world.stepping(|world| {
        let mut stepping = 0.0;
        for _ in 0..steps {
            let start = Instant::now();
            let stats = step(world);
            stepping += start.elapsed().as_secs_f64();
            observe(world, &stats);
        }
        stepping
    });
    stepping / duration
}

/// A function that advances a world by one step with `engine`.
type Stepper = Box<dyn FnMut(&mut World) -> crate::StepStats + Send>;

/// A function that advances `world` by one step with `engine`.
fn stepper(engine: Engine, world: &World) -> Stepper {
    match engine {
        Engine::Tumble => Box::new(|w: &mut World| w.step()),
        #[cfg(feature = "compare-rapier")]
        Engine::Rapier => {
            let mut mirror = super::rapier::RapierScene::from_world(world, true);
            Box::new(move |w: &mut World| {
                mirror.step();
                mirror.copy_into(w);
                crate::StepStats::default()
            })
        }
        #[cfg(not(feature = "compare-rapier"))]
        Engine::Rapier => {
            let _ = world;
            panic!("Rapier is compared only in builds with the compare-rapier feature")
        }
    }
}

pub fn run(scenario: Scenario, settings: &Settings) -> Outcome {
    run_with(scenario, settings, Engine::Tumble)
}

/// A scenario stepped by `engine`.
pub fn run_with(scenario: Scenario, settings: &Settings, engine: Engine) -> Outcome {
    let run = &Run {
        settings: settings.clone(),
        engine,
    };
    let (wall, metrics, finite) = match scenario {
        Scenario::FreeFall => free_fall(run),
        Scenario::SpinEllipsoid => spin(
            shape(&assets::ellipsoid(DVec3::new(6.0, 4.0, 2.5), 10, 20)),
            DVec3::Y,
            run,
        ),
        Scenario::SpinLongOctahedron => spin(
            shape(&assets::octahedron(DVec3::new(3.0, 10.0, 4.0))),
            DVec3::Z,
            run,
        ),
        Scenario::Bounce => bounce(run),
        Scenario::Pendulum => pendulum(run),
        Scenario::CornerPendulum => corner_pendulum(run),
        Scenario::Tower => tower(run),
        Scenario::Chains => chains(run),
        Scenario::MixedEnergy => mixed_energy(run),
        Scenario::Slope20 => slope(run, 20.0),
        Scenario::Slope30 => slope(run, 30.0),
        Scenario::PileRest => pile_rest(run),
    };
    Outcome {
        wall_per_sim_second: wall,
        metrics,
        finite,
    }
}

type Measured = (f64, Vec<(String, f64)>, bool);

fn m(name: &str, value: f64) -> (String, f64) {
    (name.to_string(), value)
}

/// A box thrown upwards high above the ground: position error against `x0 + v0 t + g t^2 / 2`.
fn free_fall(run: &Run) -> Measured {
    let settings = run.settings.clone();
    let s = shape(&assets::cuboid(DVec3::new(1.0, 1.0, 1.0)));
    let mut b = RigidBody::on_shape(
        &s,
        0,
        100.0,
        false,
        DVec3::new(0.0, 1000.0, 0.0),
        DQuat::IDENTITY,
    );
    let v0 = DVec3::new(3.0, 20.0, 1.0);
    b.linear_velocity = v0;
    let (x0, g) = (b.position, settings.gravity);
    let mut world = single(s, b, settings);
    let duration = Scenario::FreeFall.duration();
    let mut worst: f64 = 0.0;
    let wall = simulate(run.engine, &mut world, duration, |w, _| {
        let t = w.time;
        worst = worst.max((w.bodies[0].position - (x0 + v0 * t + 0.5 * g * t * t)).length());
    });
    let finite = world.all_finite();
    (wall, vec![m("position_error", worst)], finite)
}

/// Body-frame reference of torque-free motion: Euler's equations and the quaternion kinematics
/// integrated with classical RK4 at a tiny step.
pub fn torque_free_reference(
    inertia: DMat3,
    w_body0: DVec3,
    q0: DQuat,
    duration: f64,
    h: f64,
) -> Vec<(f64, DVec3, DQuat)> {
    let inverse = inertia.inverse();
    let f = |w: DVec3, q: DQuat| -> (DVec3, DQuat) {
        let dw = inverse * (-w.cross(inertia * w));
        let dq = q * DQuat::from_xyzw(w.x, w.y, w.z, 0.0) * 0.5;
        (dw, dq)
    };
    let steps = (duration / h).round() as usize;
    let mut out = Vec::with_capacity(steps + 1);
    let (mut w, mut q) = (w_body0, q0);
    out.push((0.0, w, q));
    for k in 0..steps {
        let (k1w, k1q) = f(w, q);
        let (k2w, k2q) = f(w + k1w * (h / 2.0), q + k1q * (h / 2.0));
        let (k3w, k3q) = f(w + k2w * (h / 2.0), q + k2q * (h / 2.0));
        let (k4w, k4q) = f(w + k3w * h, q + k3q * h);
        w += (k1w + k2w * 2.0 + k3w * 2.0 + k4w) * (h / 6.0);
        q = (q + (k1q + k2q * 2.0 + k3q * 2.0 + k4q) * (h / 6.0)).normalize();
        out.push(((k + 1) as f64 * h, w, q));
    }
    out
}

/// First time the body-frame spin component along `axis` changes sign (the tennis-racket flip),
/// interpolated linearly between the two samples around the change: the step at which it is
/// seen would quantise every engine's error to the step (at dt 0.005, 0.001 s or 0.004 s).
fn first_flip(series: impl Iterator<Item = (f64, f64)>) -> f64 {
    let mut previous: Option<(f64, f64)> = None;
    for (t, v) in series {
        if let Some((tp, p)) = previous
            && p.signum() != v.signum()
        {
            let fraction = if p == v { 1.0 } else { p / (p - v) };
            return tp + (t - tp) * fraction;
        }
        previous = Some((t, v));
    }
    f64::NAN
}

/// Torque-free spin near the intermediate principal axis, no gravity, no ground.
fn spin(s: Shape, axis: DVec3, run: &Run) -> Measured {
    let settings = run.settings.clone();
    let settings = Settings {
        gravity: DVec3::ZERO,
        ..settings
    };
    let q0 = DQuat::IDENTITY;
    let mut b = RigidBody::on_shape(&s, 0, 10.0, false, DVec3::new(0.0, 1000.0, 0.0), q0);
    let w0 = 2.0 * axis + DVec3::new(0.02, 0.02, 0.02);
    b.angular_velocity = w0;
    let inertia = b.inertia.to_mat3();
    let l0 = b.world_inertia() * w0;
    let e0 = 0.5 * w0.dot(l0);
    let duration = Scenario::SpinEllipsoid.duration();
    let mut world = single(s, b, settings);
    let (mut l_err, mut e_err): (f64, f64) = (0.0, 0.0);
    let mut spin_axis = Vec::new();
    let wall = simulate(run.engine, &mut world, duration, |w, _| {
        let b = &w.bodies[0];
        let l = b.world_inertia() * b.angular_velocity;
        l_err = l_err.max((l - l0).length() / l0.length());
        e_err = e_err.max((0.5 * b.angular_velocity.dot(l) - e0).abs() / e0);
        spin_axis.push((
            w.time,
            (b.orientation.inverse() * b.angular_velocity).dot(axis),
        ));
    });
    let reference = torque_free_reference(inertia, w0, q0, duration, 1e-4);
    let reference_flip = first_flip(reference.iter().map(|(t, w, _)| (*t, w.dot(axis))));
    let flip = first_flip(spin_axis.into_iter());
    let (_, w_ref, q_ref) = reference.last().copied().unwrap();
    let b = &world.bodies[0];
    let w_world_ref = q_ref * w_ref;
    let w_error = (b.angular_velocity - w_world_ref).length() / w0.length();
    let flip_error = if reference_flip.is_nan() {
        f64::NAN
    } else if flip.is_nan() {
        duration
    } else {
        (flip - reference_flip).abs()
    };
    let finite = world.all_finite();
    (
        wall,
        vec![
            m("angular_momentum_error", l_err),
            m("energy_error", e_err),
            m("final_angular_velocity_error", w_error),
            m("flip_time_error", flip_error),
            m("reference_flip_time", reference_flip),
        ],
        finite,
    )
}

/// An octahedron dropped tip-down (the lowest vertex straight below the centre of mass, so no
/// torque): successive apex heights should fall by e^2 per bounce. Each apex is the vertex of
/// the parabola through the highest sample and its two neighbours ([`parabola_vertex`]), not
/// the highest sample, which fell short of it by up to g dt^2 / 8 (2e-3 units at dt 0.04: the
/// preset's apex ratio error there read 9.5e-5 at e = 1, where the vertex gives 1e-12).
fn bounce(run: &Run) -> Measured {
    let settings = run.settings.clone();
    let h = 2.0;
    let s = shape(&assets::octahedron(DVec3::splat(h)));
    let b = RigidBody::on_shape(
        &s,
        0,
        100.0,
        false,
        DVec3::new(0.0, 20.0 + h, 0.0),
        DQuat::IDENTITY,
    );
    let e = settings.restitution;
    let mut world = single(s, b, settings);
    let mut heights = vec![20.0];
    let mut previous_vy = 0.0;
    // The last three heights of the tip, oldest first.
    let mut last = [20.0; 3];
    let wall = simulate(
        run.engine,
        &mut world,
        Scenario::Bounce.duration(),
        |w, _| {
            let b = &w.bodies[0];
            last = [last[1], last[2], b.position.y - h];
            // An apex: upward velocity turned downward, so the middle sample is the highest
            // (each step's displacement has its new velocity's sign).
            if previous_vy > 0.0 && b.linear_velocity.y <= 0.0 {
                heights.push(parabola_vertex(last));
            }
            previous_vy = b.linear_velocity.y;
        },
    );
    let bounces = heights.len().min(4);
    let mut error: f64 = 0.0;
    for k in 1..bounces {
        if heights[k - 1] > 0.05 {
            error = error.max((heights[k] / heights[k - 1] - e * e).abs());
        }
    }
    if bounces < 2 {
        error = 1.0;
    }
    let finite = world.all_finite();
    (
        wall,
        vec![
            m("apex_ratio_error", error),
            m("apexes_seen", heights.len() as f64 - 1.0),
        ],
        finite,
    )
}

/// The highest value of the parabola through three samples a step apart (`[before, top,
/// after]`, the middle one the highest sampled): exact for a body in free flight, whose
/// heights step by step lie on a parabola under (semi-implicit) Euler as in time. The middle
/// sample where the three do not bend down.
pub fn parabola_vertex([a, b, c]: [f64; 3]) -> f64 {
    let bend = a - 2.0 * b + c;
    if bend < 0.0 {
        b - (a - c) * (a - c) / (8.0 * bend)
    } else {
        b
    }
}

/// Period of a simple pendulum of `length` swinging `theta0` (rad) each way under `g`:
/// 4 sqrt(L/g) K(sin(theta0/2)), the complete elliptic integral K by the arithmetic-geometric
/// mean (K(k) = pi / (2 AGM(1, sqrt(1 - k^2)))). The series to theta0^4 it replaces was off by
/// 1.5e-8 at 0.2 rad, most of the preset's period error at small dt.
pub fn pendulum_period(length: f64, g: f64, theta0: f64) -> f64 {
    let k = (0.5 * theta0).sin();
    let (mut a, mut b) = (1.0f64, (1.0 - k * k).sqrt());
    while (a - b).abs() > 1e-15 * a {
        (a, b) = (0.5 * (a + b), (a * b).sqrt());
    }
    let elliptic_k = std::f64::consts::PI / (a + b);
    4.0 * (length / g).sqrt() * elliptic_k
}

/// The pendulum's pivot, rod length and initial angle (rad).
pub const PENDULUM: (DVec3, f64, f64) = (DVec3::new(0.0, 60.0, 0.0), 20.0, 0.2);

/// A box hanging from a fixed box at `pivot` by a rigid distance constraint of `length`
/// (lower = upper = 1) attached at its centre of mass, let go at `theta0` (rad) from the
/// vertical; the bench's is [`PENDULUM`].
pub fn pendulum_world(settings: Settings, (pivot, length, theta0): (DVec3, f64, f64)) -> World {
    let s = shape(&assets::cuboid(DVec3::new(2.0, 1.0, 1.5)));
    let centre = s.rest_vertices.len() - 1; // the fan's apex: the box's centre of mass
    assert!(s.rest_vertices[centre].length() < 1e-12);
    let anchor = RigidBody::on_shape(&s, 0, 100.0, true, pivot, DQuat::IDENTITY);
    let bob = RigidBody::on_shape(
        &s,
        0,
        100.0,
        false,
        pivot + length * DVec3::new(theta0.sin(), -theta0.cos(), 0.0),
        DQuat::IDENTITY,
    );
    let bodies = [anchor, bob];
    let constraints = DistanceConstraint::lower_and_upper(
        &bodies,
        std::slice::from_ref(&s),
        (0, centre),
        (1, centre),
        1.0,
        1.0,
    )
    .to_vec();
    World::new(
        vec![s],
        vec!["box".into()],
        bodies.to_vec(),
        constraints,
        settings,
    )
}

/// [`pendulum_world`]: a simple pendulum of length L (the rod holds the bob at its centre of
/// mass, so its turning is its own). Period against the exact one ([`pendulum_period`]); the
/// amplitude at the end from the bob's energy, `cos a = cos theta - v^2 / (2 g L)` with the rod
/// as long as it is then, against its initial value. (The largest angle over the last 3 s, as
/// before, held an apex only for periods near this one's 9 s, and fell short of it by the
/// sampling: 2.3e-6 of the amplitude at every dt from 0.04 to 0.01.)
fn pendulum(run: &Run) -> Measured {
    let settings = run.settings.clone();
    let (pivot, length, theta0) = PENDULUM;
    let g = settings.gravity.length();
    let mut world = pendulum_world(settings, PENDULUM);
    let mut crossings = Vec::new();
    let mut previous: Option<(f64, f64)> = None;
    let duration = Scenario::Pendulum.duration();
    let wall = simulate(run.engine, &mut world, duration, |w, _| {
        let d = w.bodies[1].position - pivot;
        let theta = d.x.atan2(-d.y);
        if let Some((t0, th0)) = previous
            && th0.signum() != theta.signum()
            && th0 != 0.0
        {
            crossings.push(t0 + (w.time - t0) * th0 / (th0 - theta));
        }
        previous = Some((w.time, theta));
    });
    let bob = &world.bodies[1];
    let d = bob.position - pivot;
    let speed = bob.linear_velocity.length();
    let cos_amplitude = d.x.atan2(-d.y).cos() - speed * speed / (2.0 * g * d.length());
    let amplitude_late = cos_amplitude.clamp(-1.0, 1.0).acos();
    let closed = pendulum_period(length, g, theta0);
    let period = if crossings.len() >= 3 {
        2.0 * (crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as f64
    } else {
        f64::INFINITY
    };
    let finite = world.all_finite();
    (
        wall,
        vec![
            m("period_error", ((period - closed) / closed).abs()),
            m(
                "amplitude_error",
                ((amplitude_late - theta0) / theta0).abs(),
            ),
            m("period", period),
            m("closed_form_period", closed),
        ],
        finite,
    )
}

/// A box of 2 x 1 x 1.5 hung by a corner on a rigid rod (lower = upper = 1) of 3 units from a
/// small fixed box, let go with the rod at 1 rad from the vertical: a compound pendulum that
/// turns as it swings (the coursework's chains hang their links by vertices), which the bench's
/// pendulum, held at its centre of mass, never does. Its energy is invariant: the largest
/// change over 20 s, and the change at the end, relative to the energy it can swing with (down
/// to hanging at rest, its centre of mass below the pivot).
fn corner_pendulum(run: &Run) -> Measured {
    let bob_shape = shape(&assets::cuboid(DVec3::new(1.0, 0.5, 0.75)));
    let anchor_shape = shape(&assets::cuboid(DVec3::splat(0.05)));
    let (pivot, length, theta0) = (DVec3::new(0.0, 60.0, 0.0), 3.0, 1.0);
    let corner = bob_shape.rest_vertices[0];
    let turn = DQuat::from_rotation_z(0.5 * theta0);
    let hook = pivot + length * DVec3::new(theta0.sin(), -theta0.cos(), 0.0);
    let bodies = [
        RigidBody::on_shape(&anchor_shape, 1, 100.0, true, pivot, DQuat::IDENTITY),
        RigidBody::on_shape(&bob_shape, 0, 100.0, false, hook - turn * corner, turn),
    ];
    let centre = anchor_shape.rest_vertices.len() - 1; // the fan's apex: its centre
    let shapes = vec![bob_shape, anchor_shape];
    let rod = DistanceConstraint::lower_and_upper(&bodies, &shapes, (0, centre), (1, 0), 1.0, 1.0);
    let names = vec!["box".into(), "anchor".into()];
    let settings = run.settings.clone();
    let mut world = World::new(shapes, names, bodies.to_vec(), rod.to_vec(), settings);
    let g = world.settings.gravity.length();
    let e0 = world.total_energy();
    let lowest = pivot.y - length - corner.length();
    let swing = e0 - world.bodies[1].mass * g * lowest;
    let (mut worst, mut shortest): (f64, f64) = (0.0, f64::INFINITY);
    let duration = Scenario::CornerPendulum.duration();
    let wall = simulate(run.engine, &mut world, duration, |w, _| {
        worst = worst.max((w.total_energy() - e0).abs());
        let rod = &w.constraints[0];
        shortest = shortest.min((rod.value(&w.bodies) + rod.reference) / rod.rest_length);
    });
    let finite = world.all_finite();
    (
        wall,
        vec![
            m("energy_drift", worst / swing),
            m("energy_change_at_end", (world.total_energy() - e0) / swing),
            // Below 1: the rod was pushed shorter (Rapier's rope joint goes slack there).
            m("shortest_rod", shortest),
        ],
        finite,
    )
}

/// Boxes of very different densities stacked exactly touching, at rest: they should stay put.
fn tower(run: &Run) -> Measured {
    let settings = run.settings.clone();
    let s = shape(&assets::cuboid(DVec3::new(6.0, 3.0, 4.0)));
    let densities = [3000.0, 1000.0, 200.0, 50.0];
    let bodies: Vec<RigidBody> = densities
        .iter()
        .enumerate()
        .map(|(k, &rho)| {
            RigidBody::on_shape(
                &s,
                0,
                rho,
                false,
                DVec3::new(0.0, 3.0 + 6.0 * k as f64, 0.0),
                DQuat::IDENTITY,
            )
        })
        .collect();
    let start: Vec<DVec3> = bodies.iter().map(|b| b.position).collect();
    let mut world = World::new(vec![s], vec!["box".into()], bodies, Vec::new(), settings);
    let duration = Scenario::Tower.duration();
    let (mut drift, mut jitter, mut tilt): (f64, f64, f64) = (0.0, 0.0, 0.0);
    let wall = simulate(run.engine, &mut world, duration, |w, _| {
        for (b, x0) in w.bodies.iter().zip(&start) {
            drift = drift.max((b.position - *x0).length());
            tilt = tilt.max(b.orientation.angle_between(DQuat::IDENTITY));
            if w.time > duration / 2.0 {
                jitter = jitter.max(b.linear_velocity.length() + 6.0 * b.angular_velocity.length());
            }
        }
    });
    let finite = world.all_finite();
    (
        wall,
        vec![
            m("drift", drift),
            m("jitter_speed", jitter),
            m("max_tilt_rad", tilt),
        ],
        finite,
    )
}

/// The built-in two-chain scene: worst constraint violation relative to the rest length.
fn chains(run: &Run) -> Measured {
    let settings = run.settings.clone();
    let mut world = crate::scene::load("two-chain", &crate::ConstraintsChoice::Auto, settings)
        .expect("built-in scene");
    let (mut worst, mut visits, mut steps, mut budget_hits) = (0.0f64, 0usize, 0usize, 0usize);
    // The upper bounds alone too: Rapier is given those only (rope joints), so its worst
    // violation may be a lower bound it never had.
    let mut worst_upper = 0.0f64;
    let wall = simulate(
        run.engine,
        &mut world,
        Scenario::Chains.duration(),
        |w, stats| {
            for c in &w.constraints {
                let violation = c.relative_violation(&w.bodies);
                worst = worst.max(violation);
                if c.is_upper {
                    worst_upper = worst_upper.max(violation);
                }
            }
            visits += stats.constraint_visits;
            steps += 1;
            budget_hits += stats.budget_hit as usize;
        },
    );
    let finite = world.all_finite();
    (
        wall,
        vec![
            m("worst_relative_violation", worst),
            m("worst_upper_violation", worst_upper),
            m("visits_per_step", visits as f64 / steps.max(1) as f64),
            m("budget_hits", budget_hits as f64),
        ],
        finite,
    )
}

/// The built-in mixed scene with e = 1 and no friction: total energy should stay what it was
/// (friction takes energy away by design; the coursework has none).
fn mixed_energy(run: &Run) -> Measured {
    let settings = run.settings.clone();
    let settings = Settings {
        restitution: 1.0,
        friction: 0.0,
        ..settings
    };
    let mut world = crate::scene::load("mixed", &crate::ConstraintsChoice::None, settings)
        .expect("built-in scene");
    let e0 = world.total_energy();
    let mut worst: f64 = 0.0;
    let wall = simulate(
        run.engine,
        &mut world,
        Scenario::MixedEnergy.duration(),
        |w, _| {
            worst = worst.max((w.total_energy() - e0).abs() / e0.abs());
        },
    );
    let finite = world.all_finite();
    (
        wall,
        vec![
            m("energy_drift", worst),
            m("final_energy_ratio", world.total_energy() / e0),
        ],
        finite,
    )
}

/// Friction of the slope scenarios.
const SLOPE_FRICTION: f64 = 0.5;

/// A 2 x 1 x 1.5 box resting on a fixed incline of `degrees` (friction 0.5, no bounce), high
/// above the ground. Held by static friction below atan(0.5) = 26.6 degrees: displacement
/// after 5 s; above it slides with `g (sin a - mu cos a)`: relative error of the acceleration
/// measured between 1 s and 5 s.
fn slope(run: &Run, degrees: f64) -> Measured {
    let settings = Settings {
        friction: SLOPE_FRICTION,
        restitution: 0.0,
        ..run.settings.clone()
    };
    let angle = degrees.to_radians();
    let tilt = DQuat::from_rotation_z(angle);
    let (down_slope, up) = (tilt * DVec3::NEG_X, tilt * DVec3::Y);
    let incline = shape(&assets::cuboid(DVec3::new(40.0, 1.0, 4.0)));
    let block = shape(&assets::cuboid(DVec3::new(1.0, 0.5, 0.75)));
    let base = DVec3::new(0.0, 60.0, 0.0);
    let bodies = vec![
        RigidBody::on_shape(&incline, 0, 100.0, true, base, tilt),
        RigidBody::on_shape(&block, 1, 100.0, false, base + 1.5 * up, tilt),
    ];
    let start = bodies[1].position;
    let g = settings.gravity.length();
    let mut world = World::new(
        vec![incline, block],
        vec!["incline".into(), "box".into()],
        bodies,
        Vec::new(),
        settings,
    );
    let duration = Scenario::Slope20.duration();
    let (mut early_speed, mut early_time) = (0.0, 0.0);
    let wall = simulate(run.engine, &mut world, duration, |w, _| {
        if early_time == 0.0 && w.time >= 1.0 - 1e-9 {
            (early_speed, early_time) = (w.bodies[1].linear_velocity.dot(down_slope), w.time);
        }
    });
    let b = &world.bodies[1];
    let displacement = (b.position - start).length();
    // Along the incline: the slip, without the contact's sag into it (most of the preset's
    // displacement at 20 degrees).
    let slip = (b.position - start).dot(down_slope).abs();
    let expected = g * (angle.sin() - SLOPE_FRICTION * angle.cos());
    let measured = (b.linear_velocity.dot(down_slope) - early_speed) / (world.time - early_time);
    let finite = world.all_finite();
    let metrics = if expected > 0.0 {
        vec![
            m(
                "acceleration_error",
                ((measured - expected) / expected).abs(),
            ),
            m("acceleration", measured),
            m("expected_acceleration", expected),
            m("displacement", displacement),
            m("slip", slip),
        ]
    } else {
        vec![
            m("displacement", displacement),
            m("slip", slip),
            m("acceleration", measured),
        ]
    };
    (wall, metrics, finite)
}

/// pile-200 (boxes, tetrahedra, octahedra dropped into a walled bin) with friction 0.5 and
/// restitution 0.2, 10 s: the largest speed of any body at the end, and the deepest penetration
/// then relative to the smallest body's size; and the deepest over the whole run, landing
/// included (a reading of the "max penetration" the end alone does not give), found by
/// the same detection for both engines at the poses of every step, after the timed run.
fn pile_rest(run: &Run) -> Measured {
    let mut world = pile_rest_world(200, run.settings.clone());
    // The poses after each step, kept for the deepest contact over the run: searched between
    // the timed steps (stop 77's run), the detection left each engine's data out of cache,
    // Rapier's more than the preset's (pile_rest 1.38x Rapier's time at dt 0.04 then, 1.54x
    // without the search in stop 76's run). A pile at rest keeps one entry.
    let mut poses: Vec<Vec<(DVec3, DQuat)>> = Vec::new();
    let wall = simulate(
        run.engine,
        &mut world,
        Scenario::PileRest.duration(),
        |w, _| {
            let now = w.bodies.iter().map(|b| (b.position, b.orientation));
            if poses
                .last()
                .is_none_or(|last| !now.clone().eq(last.iter().copied()))
            {
                poses.push(now.collect());
            }
        },
    );
    let rest = Rest::of(&world);
    let finite = world.all_finite();
    let deepest = deepest_contact_at(&world, &poses);
    (
        wall,
        vec![
            m("max_speed", rest.max_speed),
            m("max_penetration_relative", rest.max_penetration_relative),
            m("max_penetration_relative_over_run", deepest / rest.size),
        ],
        finite,
    )
}

/// The deepest contact of `world`'s bodies at any of the `poses` ([`Rest::deepest_contact`]).
fn deepest_contact_at(world: &World, poses: &[Vec<(DVec3, DQuat)>]) -> f64 {
    let mut probe = world.clone();
    let mut deepest: f64 = 0.0;
    for step in poses {
        for (body, &(position, orientation)) in probe.bodies.iter_mut().zip(step) {
            (body.position, body.orientation) = (position, orientation);
        }
        deepest = deepest.max(Rest::deepest_contact(&probe));
    }
    deepest
}

/// pile_rest's pile of `bodies` bodies (the bench's is 200) under `settings` with its friction
/// and restitution.
pub fn pile_rest_world(bodies: usize, settings: Settings) -> World {
    let settings = Settings {
        friction: SLOPE_FRICTION,
        restitution: 0.2,
        ..settings
    };
    crate::scene::generate::pile(bodies, settings)
}

/// How far a pile is from rest: pile_rest's two metrics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rest {
    /// The largest speed of a moving body.
    pub max_speed: f64,
    /// The deepest contact, relative to [`Rest::size`].
    pub max_penetration_relative: f64,
    /// The least extent of the smallest moving body.
    pub size: f64,
}

impl Rest {
    /// The world's bodies as they are now.
    pub fn of(world: &World) -> Self {
        let moving = || world.bodies.iter().filter(|b| !b.fixed);
        let size = moving()
            .map(|b| world.shapes[b.shape].least_extent())
            .fold(f64::INFINITY, f64::min);
        let max_speed = moving()
            .map(|b| b.linear_velocity.length())
            .fold(0.0, f64::max);
        Self {
            max_speed,
            max_penetration_relative: Self::deepest_contact(world) / size,
            size,
        }
    }

    /// The depth of the world's deepest contact now.
    pub fn deepest_contact(world: &World) -> f64 {
        (world.current_contacts().iter())
            .map(|(_, _, c)| c.depth)
            .fold(0.0, f64::max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `--scenarios` takes the names the results print (`corner_pendulum`) as well as its own
    /// (`corner-pendulum`).
    #[cfg(feature = "cli")]
    #[test]
    fn scenarios_parse_under_their_printed_names() {
        use clap::ValueEnum;
        for scenario in Scenario::ALL {
            assert_eq!(Scenario::from_str(scenario.name(), false), Ok(scenario));
        }
        assert_eq!(Scenario::from_str("slope20", false), Ok(Scenario::Slope20));
        assert_eq!(
            Scenario::from_str("bounce_e0.8", false),
            Ok(Scenario::Bounce)
        );
    }

    /// pile_rest's measure of a box whose lowest face is 0.03 below the ground (its thinnest
    /// side 0.5 long: 6 %) and which moves at 5 units/s, beside a fixed box deeper still and
    /// faster, which neither counts.
    #[test]
    fn rest_measures_the_moving_bodies_speed_and_deepest_contact() {
        let box_shape = shape(&assets::cuboid(DVec3::new(1.0, 0.25, 0.75)));
        let mut moving = RigidBody::on_shape(
            &box_shape,
            0,
            1.0,
            false,
            DVec3::new(0.0, 0.25 - 0.03, 0.0),
            DQuat::IDENTITY,
        );
        moving.linear_velocity = DVec3::new(3.0, 4.0, 0.0);
        let mut wall = RigidBody::on_shape(
            &box_shape,
            0,
            1.0,
            true,
            DVec3::new(10.0, 0.0, 0.0),
            DQuat::IDENTITY,
        );
        wall.linear_velocity = DVec3::new(0.0, 0.0, 100.0);
        let world = World::new(
            vec![box_shape],
            vec!["box".into()],
            vec![moving, wall],
            Vec::new(),
            Settings::accurate(),
        );
        let rest = Rest::of(&world);
        assert!((rest.max_speed - 5.0).abs() < 1e-12, "{rest:?}");
        let expected = 0.03 / 0.5;
        assert!(
            (rest.max_penetration_relative - expected).abs() < 1e-6,
            "{rest:?}"
        );
    }

    #[test]
    fn flip_time_is_where_the_samples_cross_zero() {
        // cos(t) sampled every 0.1 s crosses zero at pi/2; a chord's root is off by
        // O(h^2) of the curvature, far under the 0.1 s of the sample the change is seen at.
        let series = (0..40).map(|k| (0.1 * k as f64, (0.1 * k as f64).cos()));
        let flip = first_flip(series);
        assert!((flip - std::f64::consts::FRAC_PI_2).abs() < 1e-3, "{flip}");
        let linear = [(0.0, 3.0), (1.0, 1.0), (2.0, -1.0)];
        assert_eq!(first_flip(linear.into_iter()), 1.5);
        assert!(first_flip([(0.0, 1.0), (1.0, 2.0)].into_iter()).is_nan());
    }

    /// The vertex of a parabola sampled a step apart on both sides of its top, wherever the
    /// top lies between them; the middle sample where the three do not bend down.
    #[test]
    fn a_parabola_s_top_is_found_between_its_samples() {
        for top in [-0.5, -0.2, 0.0, 0.37, 0.5] {
            let y = |t: f64| 7.0 - 3.0 * (t - top) * (t - top);
            let found = parabola_vertex([y(-1.0), y(0.0), y(1.0)]);
            assert!((found - 7.0).abs() < 1e-12, "top at {top}: {found}");
        }
        assert_eq!(parabola_vertex([1.0, 2.0, 3.0]), 2.0);
    }

    /// The exact period: 2 pi sqrt(L/g) for small swings, and the tabulated ratio to it at
    /// larger ones (2 K(sin(a/2)) / pi: 1.0663 at 1 rad, 1.1803 at pi/2, from Abramowitz and
    /// Stegun's K).
    #[test]
    fn the_pendulum_period_is_the_elliptic_integral_s() {
        let small = 2.0 * std::f64::consts::PI * (20.0f64 / 9.8).sqrt();
        assert!((pendulum_period(20.0, 9.8, 1e-6) / small - 1.0).abs() < 1e-12);
        let ratio = |a: f64| pendulum_period(20.0, 9.8, a) / small;
        assert!((ratio(1.0) - 1.066_335).abs() < 1e-6, "{}", ratio(1.0));
        let half_pi = std::f64::consts::FRAC_PI_2;
        assert!(
            (ratio(half_pi) - 1.180_341).abs() < 1e-6,
            "{}",
            ratio(half_pi)
        );
        // The series to theta^4 is within its next term, theta^6 / 1000 or so, at 0.2 rad.
        let series = 1.0 + 0.04 / 16.0 + 11.0 * 0.0016 / 3072.0;
        assert!((ratio(0.2) - series).abs() < 1e-7);
    }
}
