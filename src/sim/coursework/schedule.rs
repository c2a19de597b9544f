//! Scheduling of the coursework's constraint projections: the cyclic sweep of the skeleton, or
//! the sparse work list of coursework section 3.2.

use super::projection::visit;
use crate::sim::body::RigidBody;
use crate::sim::constraint::DistanceConstraint;
use crate::sim::settings::ConstraintSchedule;
use crate::sim::step_context::StepContext;

/// What a constraint pass did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ConstraintReport {
    pub visits: usize,
    pub corrections: usize,
    /// Stopped on the visit budget with constraints still violated.
    pub budget_hit: bool,
}

/// Resolves the constraints until all hold within the step's tolerance or its visit budget is
/// spent. `by_body[b]` lists the constraints on body b (used by the sparse schedule).
pub fn solve_constraints(
    ctx: &StepContext,
    constraints: &[DistanceConstraint],
    by_body: &[Vec<u32>],
    bodies: &mut [RigidBody],
) -> ConstraintReport {
    if constraints.is_empty() {
        return ConstraintReport::default();
    }
    let (tolerance, max_visits) = (ctx.tolerance, ctx.visit_budget);
    match ctx.settings.constraint_schedule {
        ConstraintSchedule::Sweep => sweep(constraints, bodies, tolerance, max_visits),
        ConstraintSchedule::Sparse => {
            work_list(constraints, by_body, bodies, tolerance, max_visits)
        }
    }
}

/// The coursework's loop: cycle through the list; stop after a streak of as many unchanged visits
/// as there are constraints (a full quiet pass), or when the budget is spent.
fn sweep(
    constraints: &[DistanceConstraint],
    bodies: &mut [RigidBody],
    tolerance: f64,
    max_visits: usize,
) -> ConstraintReport {
    let mut report = ConstraintReport::default();
    let mut quiet_streak = 0;
    let mut index = 0;
    while quiet_streak < constraints.len() && report.visits < max_visits {
        if visit(&constraints[index], bodies, tolerance) {
            quiet_streak = 0;
            report.corrections += 1;
        } else {
            quiet_streak += 1;
        }
        report.visits += 1;
        index = (index + 1) % constraints.len();
    }
    report.budget_hit = quiet_streak < constraints.len();
    report
}

/// Sparse scheduling (coursework 3.2): the sweep's cyclic order, but only over constraints flagged
/// as possibly violated. All start flagged; a correction flags the constraints that share a
/// movable body with it. Keeping the cyclic order keeps the sweep's Gauss-Seidel propagation along
/// chains (a FIFO work list converges more slowly and spends more visits). Ends when nothing is
/// flagged, which means every constraint was checked valid after its bodies last moved.
fn work_list(
    constraints: &[DistanceConstraint],
    by_body: &[Vec<u32>],
    bodies: &mut [RigidBody],
    tolerance: f64,
    max_visits: usize,
) -> ConstraintReport {
    let mut report = ConstraintReport::default();
    let count = constraints.len();
    let mut flagged = vec![true; count];
    let mut pending = count;
    let mut index = 0;
    while pending > 0 && report.visits < max_visits {
        // Next flagged constraint in cyclic order (a bool scan: far cheaper than a visit).
        while !flagged[index] {
            index = (index + 1) % count;
        }
        flagged[index] = false;
        pending -= 1;
        report.visits += 1;
        let constraint = &constraints[index];
        if visit(constraint, bodies, tolerance) {
            report.corrections += 1;
            for body in [constraint.body1, constraint.body2] {
                if !bodies[body].is_dynamic() {
                    continue;
                }
                for &other in &by_body[body] {
                    let other = other as usize;
                    // The corrected constraint itself now sits exactly on its bound.
                    if other != index && !flagged[other] {
                        flagged[other] = true;
                        pending += 1;
                    }
                }
            }
        }
        index = (index + 1) % count;
    }
    report.budget_hit = pending > 0;
    report
}
