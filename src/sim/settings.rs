//! Every knob of the simulation in one struct. The defaults reproduce the coursework's reference;
//! each improvement that changes results is off by default.

use glam::DVec3;
use serde::{Deserialize, Serialize};

/// A setting with a fixed set of values, listed, named and explained once for the command line,
/// the viewer panel and the reports.
pub trait Choice: Copy + PartialEq + std::fmt::Debug + 'static {
    /// Every value, in the order menus show them.
    const ALL: &'static [Self];
    /// The name typed on the command line (kebab-case).
    fn name(self) -> &'static str;
    /// One sentence on what the value does.
    fn help(self) -> &'static str;
    fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|c| c.name() == name)
    }
}

/// Declares a settings enum and its [`Choice`] table from one list of
/// `Variant = "cli-name": "help"`; with the `cli` feature it is also a `clap::ValueEnum`.
macro_rules! choice_enum {
    (
        $(#[$meta:meta])*
        pub enum $name:ident (default $default:ident) {
            $($variant:ident = $text:literal : $help:literal,)+
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
        #[serde(rename_all = "snake_case")]
        pub enum $name {
            $(#[doc = $help] $variant,)+
        }

        impl Default for $name {
            fn default() -> Self {
                Self::$default
            }
        }

        impl Choice for $name {
            const ALL: &'static [Self] = &[$(Self::$variant),+];
            fn name(self) -> &'static str {
                match self { $(Self::$variant => $text,)+ }
            }
            fn help(self) -> &'static str {
                match self { $(Self::$variant => $help,)+ }
            }
        }

        #[cfg(feature = "cli")]
        impl clap::ValueEnum for $name {
            fn value_variants<'a>() -> &'a [Self] {
                <Self as Choice>::ALL
            }
            /// Also under the name `--json` prints (`soft_step` for `soft-step`).
            fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
                let value = clap::builder::PossibleValue::new(self.name()).help(self.help());
                let json = self.name().replace('-', "_");
                Some(if json == self.name() { value } else { value.alias(json) })
            }
        }
    };
}

choice_enum! {
    /// Which solver advances the world.
    pub enum Solver (default Coursework) {
        Coursework = "coursework": "The coursework's method: contacts resolved pair by pair by projection and one restitution impulse, distance constraints projected on positions then velocities.",
        SoftStep = "soft-step": "Contact manifolds with friction and distance constraints solved together, warm-started, in substeps with soft position correction and relaxation (after Catto's soft step, Box2D v3).",
    }
}

choice_enum! {
    /// How the coursework solver finds candidate body pairs (the soft step always uses the
    /// grid).
    pub enum BroadPhase (default Grid) {
        AllPairs = "all-pairs": "Test every pair's bounding boxes (the coursework's loop).",
        Grid = "grid": "Uniform hash grid over body boxes: same contacts, same order, far fewer tests.",
    }
}

choice_enum! {
    /// The order in which the coursework solver visits its distance constraints.
    pub enum ConstraintSchedule (default Sweep) {
        Sweep = "sweep": "Visit the constraints in order, again and again, until a full pass changes nothing (the coursework's loop).",
        Sparse = "sparse": "Cyclic order over flagged constraints only: a correction flags the constraints sharing a body with it (coursework 3.2).",
    }
}

choice_enum! {
    /// How orientations and angular velocities advance over a step.
    pub enum RotationIntegrator (default Coursework) {
        Coursework = "coursework": "World angular velocity held constant between impulses (the coursework's scheme).",
        Gyroscopic = "gyroscopic": "Implicit gyroscopic term solved by one Newton step in body frame (Catto, GDC 2015): torque-free bodies precess and flip.",
        AngularMomentum = "angular-momentum": "Torque-free turn by the implicit midpoint rule on Euler's equations and a Cayley rotation (Austin, Krishnaprasad and Wang 1993): keeps the energy and the world angular momentum exactly, second order; torque-free bodies precess and flip.",
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Settings {
    pub solver: Solver,
    /// Seconds per step.
    pub time_step: f64,
    /// Coefficient of restitution `e` (the coursework's CRCoeff).
    pub restitution: f64,
    /// The skeleton's `maxIterations`: the constraint loop stops once `visits * M` reaches it
    /// (M = number of inequality constraints, two per record), so a step makes at most
    /// `ceil(max_iterations / M)` constraint visits.
    pub max_iterations: usize,
    /// Constraint tolerance `tau` (length for positions, speed for velocities).
    pub tolerance: f64,
    pub gravity: DVec3,
    /// Coulomb friction coefficient `mu` (the soft-step solver; the coursework has no friction).
    pub friction: f64,
    /// Skip the impulse of contacts whose bodies already separate (`u.n <= 0`).
    pub skip_separating_contacts: bool,
    /// Contacts whose normal closing speed is below this get `e = 0` (0 = off).
    pub restitution_threshold: f64,
    /// Contacts act on the whole contact patch rather than at one deepest point, so that a body
    /// resting on a face gets no spurious torque: at the patch's point nearest under the centre
    /// of mass of the body resting there (on the ground, on a fixed body, or on top under
    /// gravity; the centroid between moving bodies side by side; see
    /// [`crate::sim::narrow_phase::body_contact_patch`]).
    pub contact_patches: bool,
    /// Substeps per step, each of `time_step / substeps` (Macklin et al. 2019). The coursework
    /// solver repeats its whole update; the soft-step solver detects contacts once per step and
    /// solves and integrates in substeps, and takes more in a step that begins with contacts
    /// touching where these are longer than 1/200 s (eight at dt 0.04), so its contacts keep
    /// their stiffness, and in a scene with distance constraints where they are longer than
    /// 1/80 s (shorter under stronger gravity), so a whipping rope holds.
    pub substeps: u32,
    /// Step length (seconds) from which the soft step takes all of its `substeps`; a shorter
    /// step takes proportionally fewer, down to half of them, so that its substeps stay about
    /// as long as at this length rather than shrinking with the step (0: always `substeps`).
    /// The preset's 0.01 takes two substeps at dt 0.005 (1/400 s each, as at dt 0.01) and two
    /// at 0.0025, at about half the time of four, with errors still below Rapier's wherever
    /// they were below it (docs/accuracy.md). The coursework solver ignores it.
    pub full_substeps_from: f64,
    pub rotation_integrator: RotationIntegrator,
    /// Islands that stay slower than the sleep threshold for half a second sleep until
    /// something touches them (soft-step solver; the coursework solver never sleeps).
    pub sleep: bool,
    /// The coursework solver's broad phase (the soft step always uses the grid).
    pub broad_phase: BroadPhase,
    pub constraint_schedule: ConstraintSchedule,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            solver: Solver::Coursework,
            time_step: 0.02,
            restitution: 1.0,
            max_iterations: 10_000,
            tolerance: 1e-3,
            gravity: DVec3::new(0.0, -9.8, 0.0),
            friction: 0.5,
            skip_separating_contacts: false,
            restitution_threshold: 0.0,
            contact_patches: false,
            substeps: 1,
            full_substeps_from: 0.0,
            rotation_integrator: RotationIntegrator::Coursework,
            sleep: true,
            broad_phase: BroadPhase::Grid,
            constraint_schedule: ConstraintSchedule::Sweep,
        }
    }
}

impl Settings {
    /// The gravity under which contact patches are taken ([`Settings::contact_patches`]), or
    /// `None` where contacts act at one point.
    pub fn patch_gravity(&self) -> Option<DVec3> {
        self.contact_patches.then_some(self.gravity)
    }

    /// The `--accurate` preset: tumble's soft-step solver, 4 substeps (more in a step with
    /// contacts at dt over 0.02, see [`Settings::substeps`]; fewer at dt under 0.01, see
    /// [`Settings::full_substeps_from`]), the angular-momentum
    /// rotation integrator, friction 0.5, bounces only for impacts faster than 0.5 units/s
    /// (chosen by `tumble bench accuracy`; see docs/accuracy.md).
    pub fn accurate() -> Self {
        Self {
            solver: Solver::SoftStep,
            substeps: 4,
            full_substeps_from: 0.01,
            rotation_integrator: RotationIntegrator::AngularMomentum,
            restitution_threshold: 0.5,
            ..Self::default()
        }
    }

    /// The best the coursework's own method reaches with the opt-ins (the angular-momentum
    /// integrator, a restitution threshold and the sparse schedule): the former `--accurate`.
    pub fn coursework_tuned() -> Self {
        Self {
            rotation_integrator: RotationIntegrator::AngularMomentum,
            restitution_threshold: 0.5,
            constraint_schedule: ConstraintSchedule::Sparse,
            ..Self::default()
        }
    }

    /// Brings values a user may have typed into a range the step can work with.
    pub fn sanitized(&self) -> Self {
        let mut s = self.clone();
        s.time_step = step_length(s.time_step);
        s.restitution = if s.restitution.is_finite() {
            s.restitution.clamp(0.0, 1.0)
        } else {
            1.0
        };
        if !s.tolerance.is_finite() || s.tolerance < 0.0 {
            s.tolerance = 0.0;
        }
        if !s.friction.is_finite() || s.friction < 0.0 {
            s.friction = 0.0;
        }
        if !s.restitution_threshold.is_finite() || s.restitution_threshold < 0.0 {
            s.restitution_threshold = 0.0;
        }
        if !s.gravity.is_finite() {
            s.gravity = Self::default().gravity;
        }
        s.substeps = s.substeps.clamp(1, 1000);
        if !s.full_substeps_from.is_finite() || s.full_substeps_from < 0.0 {
            s.full_substeps_from = 0.0;
        }
        s
    }
}

#[cfg(all(test, feature = "cli"))]
mod tests {
    use super::*;
    use clap::ValueEnum;

    /// Every choice parses from the command line under the name `--json` prints it by too.
    #[test]
    fn choices_parse_under_their_json_names() {
        fn check<T: Choice + ValueEnum + Serialize + PartialEq + std::fmt::Debug>() {
            for &choice in T::ALL {
                let json = serde_json::to_value(choice).unwrap();
                let json = json.as_str().unwrap().to_string();
                assert_eq!(T::from_str(&json, false), Ok(choice), "{json}");
                assert_eq!(T::from_str(choice.name(), false), Ok(choice));
            }
        }
        check::<Solver>();
        check::<BroadPhase>();
        check::<ConstraintSchedule>();
        check::<RotationIntegrator>();
    }
}

/// The time a step of `time_step` takes: none where it is not finite or is negative.
pub fn step_length(time_step: f64) -> f64 {
    if time_step.is_finite() && time_step >= 0.0 {
        time_step
    } else {
        0.0
    }
}
