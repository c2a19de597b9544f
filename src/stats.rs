//! What one step did, returned by `World::step` rather than printed.

use serde::Serialize;

/// Seconds spent in each stage of a step.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct StageTimings {
    pub integrate: f64,
    pub broad_phase: f64,
    pub narrow_phase: f64,
    pub contact_resolution: f64,
    pub ground: f64,
    pub constraints: f64,
    pub finalize: f64,
}

impl StageTimings {
    pub fn total(&self) -> f64 {
        self.integrate
            + self.broad_phase
            + self.narrow_phase
            + self.contact_resolution
            + self.ground
            + self.constraints
            + self.finalize
    }

    pub fn add(&mut self, other: &StageTimings) {
        self.integrate += other.integrate;
        self.broad_phase += other.broad_phase;
        self.narrow_phase += other.narrow_phase;
        self.contact_resolution += other.contact_resolution;
        self.ground += other.ground;
        self.constraints += other.constraints;
        self.finalize += other.finalize;
    }

    /// (name, seconds) for tables and plots.
    pub fn named(&self) -> [(&'static str, f64); 7] {
        [
            ("integrate", self.integrate),
            ("broad_phase", self.broad_phase),
            ("narrow_phase", self.narrow_phase),
            ("contact_resolution", self.contact_resolution),
            ("ground", self.ground),
            ("constraints", self.constraints),
            ("finalize", self.finalize),
        ]
    }
}

#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct StepStats {
    pub timings: StageTimings,
    /// Body pairs whose bounding boxes were compared.
    pub pairs_tested: usize,
    /// Pairs whose boxes overlapped and went to the narrow phase.
    pub narrow_phase_queries: usize,
    /// Body-body contacts resolved.
    pub contacts: usize,
    /// Body-ground contacts resolved.
    pub ground_contacts: usize,
    /// Deepest penetration among the contacts of this step.
    pub max_penetration: f64,
    pub constraint_visits: usize,
    pub constraint_corrections: usize,
    /// The constraint loop stopped on its budget with constraints still violated.
    pub budget_hit: bool,
    /// Bodies frozen this step because their state went non-finite or absurd.
    pub quarantined: Vec<usize>,
}

impl StepStats {
    /// Folds a substep's statistics into the step's.
    pub fn accumulate(&mut self, other: StepStats) {
        self.timings.add(&other.timings);
        self.pairs_tested += other.pairs_tested;
        self.narrow_phase_queries += other.narrow_phase_queries;
        self.contacts += other.contacts;
        self.ground_contacts += other.ground_contacts;
        self.max_penetration = self.max_penetration.max(other.max_penetration);
        self.constraint_visits += other.constraint_visits;
        self.constraint_corrections += other.constraint_corrections;
        self.budget_hit |= other.budget_hit;
        self.quarantined.extend(other.quarantined);
    }
}
