//! What every stage of one (sub)step reads: built once per step from the world's settings.

use super::coursework::contact::ContactParams;
use super::settings::Settings;

#[derive(Debug, Clone)]
pub struct StepContext {
    /// The world's settings brought into range ([`Settings::sanitized`]).
    pub settings: Settings,
    /// Seconds per substep: `time_step / substeps`.
    pub dt: f64,
    /// How the coursework solver resolves contacts.
    pub contact: ContactParams,
    /// Constraint tolerance `tau`.
    pub tolerance: f64,
    /// Most constraint visits per substep: the skeleton's loop runs while
    /// `currIteration * M < maxIterations`, M being the number of inequality constraints, so
    /// it makes at most `ceil(max_iterations / M)` visits.
    pub visit_budget: usize,
}

impl StepContext {
    /// The context of a step of a world with `constraint_count` inequality constraints.
    pub fn new(settings: &Settings, constraint_count: usize) -> Self {
        let settings = settings.sanitized();
        Self {
            dt: settings.time_step / settings.substeps as f64,
            contact: ContactParams {
                restitution: settings.restitution,
                skip_separating: settings.skip_separating_contacts,
                restitution_threshold: settings.restitution_threshold,
            },
            tolerance: settings.tolerance,
            visit_budget: settings.max_iterations.div_ceil(constraint_count.max(1)),
            settings,
        }
    }
}
