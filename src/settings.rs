//! Every knob of the simulation in one struct. The defaults reproduce the coursework's reference
//! exactly; each improvement that changes results is off by default.

use glam::DVec3;
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum BroadPhase {
    /// Test every pair's bounding boxes (the coursework's loop).
    AllPairs,
    /// Uniform hash grid over body boxes. Same contacts, same order, far fewer tests.
    #[default]
    Grid,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum ConstraintSchedule {
    /// Visit the constraints in order, again and again, until a full pass changes nothing
    /// (the coursework's loop).
    #[default]
    Sweep,
    /// Work list: a correction re-queues only the constraints sharing a body with it
    /// (coursework section 3.2).
    Sparse,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum RotationIntegrator {
    /// World angular velocity held constant between impulses (the coursework's scheme).
    #[default]
    Coursework,
    /// Implicit gyroscopic term solved by one Newton step in body frame (Catto, "Numerical
    /// Methods", GDC 2015): torque-free bodies precess and flip instead of spinning rigidly.
    Gyroscopic,
    /// World angular momentum held over the step, orientation advanced by the explicit-midpoint
    /// angular velocity `I(q_half)^-1 L`: keeps L exactly and is second-order accurate.
    AngularMomentum,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Settings {
    /// Seconds per step.
    pub time_step: f64,
    /// Coefficient of restitution `e` (the coursework's CRCoeff).
    pub restitution: f64,
    /// Budget of constraint visits per step.
    pub max_iterations: usize,
    /// Constraint tolerance `tau` (length for positions, speed for velocities).
    pub tolerance: f64,
    pub gravity: DVec3,
    /// Skip the impulse of contacts whose bodies already separate (`u.n <= 0`).
    pub skip_separating_contacts: bool,
    /// Contacts whose normal closing speed is below this get `e = 0` (0 = off).
    pub restitution_threshold: f64,
    /// Contacts act at the centroid of the contact patch (all penetrating points) rather than at
    /// one deepest point: resting faces get no spurious torque.
    pub contact_patches: bool,
    /// Substeps per step, each of `time_step / substeps` (Macklin et al. 2019).
    pub substeps: u32,
    pub rotation_integrator: RotationIntegrator,
    pub broad_phase: BroadPhase,
    pub constraint_schedule: ConstraintSchedule,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            time_step: 0.02,
            restitution: 1.0,
            max_iterations: 10_000,
            tolerance: 1e-3,
            gravity: DVec3::new(0.0, -9.8, 0.0),
            skip_separating_contacts: false,
            restitution_threshold: 0.0,
            contact_patches: false,
            substeps: 1,
            rotation_integrator: RotationIntegrator::Coursework,
            broad_phase: BroadPhase::Grid,
            constraint_schedule: ConstraintSchedule::Sweep,
        }
    }
}

impl Settings {
    /// The combination `tumble bench accuracy` found best (see docs/accuracy.md).
    pub fn accurate() -> Self {
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
        if !s.time_step.is_finite() || s.time_step < 0.0 {
            s.time_step = 0.0;
        }
        s.restitution = if s.restitution.is_finite() {
            s.restitution.clamp(0.0, 1.0)
        } else {
            1.0
        };
        if !s.tolerance.is_finite() || s.tolerance < 0.0 {
            s.tolerance = 0.0;
        }
        if !s.restitution_threshold.is_finite() || s.restitution_threshold < 0.0 {
            s.restitution_threshold = 0.0;
        }
        if !s.gravity.is_finite() {
            s.gravity = Self::default().gravity;
        }
        s.substeps = s.substeps.clamp(1, 1000);
        s
    }
}
