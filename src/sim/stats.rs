//! What one step did, returned by `World::step` rather than printed, and the stopwatch that
//! times its stages.

use crate::sim::settings::Solver;
use serde::Serialize;
use serde::ser::SerializeMap;
use std::time::Instant;

/// The stages of a step, in the order the coursework solver runs them (the soft step
/// integrates the bodies nothing touches after [`Stage::SolvePrepare`]). The one list of stage
/// names: statistics, `tumble run`, the benchmarks and the viewer panel all iterate over
/// [`Stage::ALL`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Stage {
    /// Gravity into velocities, velocities into poses.
    Integrate,
    /// World boxes, the grid, candidate pairs.
    BroadPhase,
    /// Exact contact queries between body hulls.
    NarrowPhase,
    /// Body-body contacts resolved by projection and impulse.
    ContactResolution,
    /// Body-ground contacts resolved by projection and impulse.
    Ground,
    /// Distance constraints (coursework solver).
    Constraints,
    /// Soft-step solver: the constraint graph's colours, solver bodies, contact and joint rows
    /// warm-started from the last step's impulses.
    SolvePrepare,
    /// Soft-step solver: contacts and constraints solved together in substeps, the solved
    /// bodies' integration between them, and the final pass.
    Solve,
    /// Soft-step solver: the restitution pass and its energy rule, velocities back into the
    /// bodies, sleeping islands, impulses kept for the next step.
    SolveFinish,
    /// Finiteness check: bodies whose state blew up are frozen at their last good pose.
    PoseCheck,
}

impl Stage {
    pub const COUNT: usize = 10;
    pub const ALL: [Stage; Stage::COUNT] = [
        Stage::Integrate,
        Stage::BroadPhase,
        Stage::NarrowPhase,
        Stage::ContactResolution,
        Stage::Ground,
        Stage::Constraints,
        Stage::SolvePrepare,
        Stage::Solve,
        Stage::SolveFinish,
        Stage::PoseCheck,
    ];

    /// snake_case name, as in JSON and CSV columns.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Integrate => "integrate",
            Stage::BroadPhase => "broad_phase",
            Stage::NarrowPhase => "narrow_phase",
            Stage::ContactResolution => "contact_resolution",
            Stage::Ground => "ground",
            Stage::Constraints => "constraints",
            Stage::SolvePrepare => "solve_prepare",
            Stage::Solve => "solve",
            Stage::SolveFinish => "solve_finish",
            Stage::PoseCheck => "pose_check",
        }
    }

    fn index(self) -> usize {
        self as usize
    }

    /// Whether `solver`'s step has this stage: summaries and the viewer panel list only those
    /// (the JSON and the bench CSV keep every stage, so their layout does not depend on it).
    pub fn runs_under(self, solver: Solver) -> bool {
        match self {
            Stage::ContactResolution | Stage::Ground | Stage::Constraints => {
                solver == Solver::Coursework
            }
            Stage::SolvePrepare | Stage::Solve | Stage::SolveFinish => solver == Solver::SoftStep,
            Stage::Integrate | Stage::BroadPhase | Stage::NarrowPhase | Stage::PoseCheck => true,
        }
    }
}

/// Seconds spent in each stage. Serialises as `{stage name: seconds}`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageTimings([f64; Stage::COUNT]);

impl StageTimings {
    pub fn get(&self, stage: Stage) -> f64 {
        self.0[stage.index()]
    }

    pub fn add_to(&mut self, stage: Stage, seconds: f64) {
        self.0[stage.index()] += seconds;
    }

    pub fn total(&self) -> f64 {
        self.0.iter().sum()
    }

    pub fn add(&mut self, other: &StageTimings) {
        for (mine, theirs) in self.0.iter_mut().zip(other.0) {
            *mine += theirs;
        }
    }

    /// Every value multiplied by `factor` (seconds to mean milliseconds per step, say).
    pub fn scaled(&self, factor: f64) -> StageTimings {
        StageTimings(self.0.map(|v| v * factor))
    }

    /// (stage, seconds) in stage order, for tables and plots.
    pub fn iter(&self) -> impl Iterator<Item = (Stage, f64)> + '_ {
        Stage::ALL.iter().map(|&s| (s, self.get(s)))
    }
}

impl Serialize for StageTimings {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut map = serializer.serialize_map(Some(Stage::COUNT))?;
        for (stage, seconds) in self.iter() {
            map.serialize_entry(stage.name(), &seconds)?;
        }
        map.end()
    }
}

/// Times the stages of a step: exactly one stage runs at a time, and [`Stopwatch::enter`] charges
/// the time since the last switch to the stage that was running (as Rapier's counters start,
/// pause and resume), so nested work is never counted twice. One that is off
/// ([`Stopwatch::off`]) reads no clock and leaves every timing zero.
#[derive(Debug)]
pub struct Stopwatch {
    timings: StageTimings,
    running: Option<(Stage, Instant)>,
    on: bool,
}

impl Stopwatch {
    pub fn new() -> Self {
        Self {
            timings: StageTimings::default(),
            running: None,
            on: true,
        }
    }

    /// A stopwatch that times nothing: a step's eight or so clock reads are 8-10 % of a
    /// two-body step (see [`crate::World::time_stages`]).
    pub fn off() -> Self {
        Self {
            on: false,
            ..Self::new()
        }
    }

    /// Starts timing `stage` and returns the stage that was running before (to resume it).
    pub fn enter(&mut self, stage: Stage) -> Option<Stage> {
        if !self.on {
            return None;
        }
        let now = Instant::now();
        let previous = self.charge(now);
        self.running = Some((stage, now));
        previous
    }

    /// Resumes the stage [`Stopwatch::enter`] returned (or stops when there was none).
    pub fn resume(&mut self, previous: Option<Stage>) {
        match previous {
            Some(stage) => {
                self.enter(stage);
            }
            None => self.stop(),
        }
    }

    /// Stops timing.
    pub fn stop(&mut self) {
        if !self.on {
            return;
        }
        self.charge(Instant::now());
        self.running = None;
    }

    /// The timings so far (the running stage counted up to now).
    pub fn finish(mut self) -> StageTimings {
        self.stop();
        self.timings
    }

    fn charge(&mut self, now: Instant) -> Option<Stage> {
        let (stage, since) = self.running?;
        self.timings
            .add_to(stage, now.duration_since(since).as_secs_f64());
        Some(stage)
    }
}

/// A stage nested in another and entered once per item (a pair's narrow phase inside the
/// coursework's contact loop), timed by sampling: one call in [`SampledStage::EVERY`] is
/// timed and the others are estimated from those. Two clock reads per pair were 9 % of
/// pile-10000's and sparse-10000's step on one thread (perf: `clock_gettime`). The step's
/// total stays exact: the estimate moves time from the enclosing stage to the nested one.
#[derive(Debug)]
pub struct SampledStage {
    stage: Stage,
    calls: usize,
    timed: usize,
    seconds: f64,
    /// The stage the unsampled calls were charged to.
    outer: Option<Stage>,
}

impl SampledStage {
    pub const EVERY: usize = 8;

    pub fn new(stage: Stage) -> Self {
        Self {
            stage,
            calls: 0,
            timed: 0,
            seconds: 0.0,
            outer: None,
        }
    }
}

impl Stopwatch {
    /// Runs `f` as a call of `sampled`'s stage (timed if it is a sampled call).
    pub fn sample<T>(&mut self, sampled: &mut SampledStage, f: impl FnOnce() -> T) -> T {
        sampled.calls += 1;
        if !self.on || sampled.calls % SampledStage::EVERY != 1 {
            return f();
        }
        let before = self.timings.get(sampled.stage);
        let outer = self.enter(sampled.stage);
        let value = f();
        self.resume(outer);
        sampled.outer = outer;
        sampled.timed += 1;
        sampled.seconds += self.timings.get(sampled.stage) - before;
        value
    }

    /// Charges `sampled`'s unsampled calls to its stage, at the mean of the sampled ones, taken
    /// from the stage they ran under.
    pub fn settle(&mut self, sampled: &SampledStage) {
        let Some(outer) = sampled.outer else {
            return;
        };
        // The running stage's time so far, charged: it holds the unsampled calls.
        if let Some((running, _)) = self.running {
            self.enter(running);
        }
        let unsampled = (sampled.calls - sampled.timed) as f64;
        let estimate = (sampled.seconds / sampled.timed as f64 * unsampled)
            .min(self.timings.get(outer))
            .max(0.0);
        self.timings.add_to(outer, -estimate);
        self.timings.add_to(sampled.stage, estimate);
    }
}

impl Default for Stopwatch {
    fn default() -> Self {
        Self::new()
    }
}

#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct StepStats {
    pub timings: StageTimings,
    /// Body pairs whose bounding boxes were compared.
    pub pairs_tested: usize,
    /// Pairs whose boxes overlapped and went to the narrow phase.
    pub narrow_phase_queries: usize,
    /// Contacts computed by the separating-axis fallback because parry's GJK/EPA failed on
    /// intersecting hulls (faces resting flush).
    pub narrow_phase_fallbacks: usize,
    /// Body-body contacts resolved (soft step: body-body manifolds).
    pub contacts: usize,
    /// Body-ground contacts resolved (soft step: ground manifolds).
    pub ground_contacts: usize,
    /// Points of all manifolds (soft step).
    pub manifold_points: usize,
    /// Deepest penetration among the contacts of this step.
    pub max_penetration: f64,
    pub constraint_visits: usize,
    pub constraint_corrections: usize,
    /// The constraint loop stopped on its budget with constraints still violated.
    pub budget_hit: bool,
    /// Soft step: position projections of a joint group (one per group in each substep that
    /// projects it) that ran out of rounds with a row still outside its bounds (by more than
    /// 1e-6 of the bound): the step could not hold them, and more substeps are the remedy.
    pub joint_projections_cut_short: usize,
    /// Soft step: joint groups handed to Gauss-Seidel because their rows depend on each other
    /// (an over-braced truss whose active sets cycled), at the end of the step: held within
    /// a few percent rather than to rounding.
    pub joint_groups_relaxed: usize,
    /// Bodies asleep at the end of the step (soft-step solver).
    pub asleep: usize,
    /// Substeps the step took: the setting's count; for the soft step fewer in a step shorter
    /// than `full_substeps_from`, and more where it begins with contacts touching and its
    /// substeps would be longer than 1/200 s, or the scene has distance constraints and they
    /// would be longer than 1/80 s (doubled after projections cut short); 0 for a step skipped
    /// at rest.
    pub substeps: u32,
    /// Bodies frozen this step because their state went non-finite or absurd.
    pub quarantined: Vec<usize>,
}

impl StepStats {
    /// Folds a substep's statistics into the step's.
    pub fn accumulate(&mut self, other: StepStats) {
        self.timings.add(&other.timings);
        self.pairs_tested += other.pairs_tested;
        self.narrow_phase_queries += other.narrow_phase_queries;
        self.narrow_phase_fallbacks += other.narrow_phase_fallbacks;
        self.contacts += other.contacts;
        self.ground_contacts += other.ground_contacts;
        self.manifold_points += other.manifold_points;
        self.max_penetration = self.max_penetration.max(other.max_penetration);
        self.constraint_visits += other.constraint_visits;
        self.constraint_corrections += other.constraint_corrections;
        self.budget_hit |= other.budget_hit;
        self.joint_projections_cut_short += other.joint_projections_cut_short;
        self.joint_groups_relaxed = other.joint_groups_relaxed;
        self.asleep = other.asleep;
        self.substeps += other.substeps;
        self.quarantined.extend(other.quarantined);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nested_stages_are_not_counted_twice() {
        let mut watch = Stopwatch::new();
        watch.enter(Stage::ContactResolution);
        std::thread::sleep(std::time::Duration::from_millis(2));
        let outer = watch.enter(Stage::NarrowPhase);
        std::thread::sleep(std::time::Duration::from_millis(2));
        watch.resume(outer);
        let t = watch.finish();
        assert!(t.get(Stage::NarrowPhase) >= 0.002);
        assert!(t.get(Stage::ContactResolution) >= 0.002);
        assert!(t.get(Stage::Integrate) == 0.0);
        let sum = t.get(Stage::NarrowPhase) + t.get(Stage::ContactResolution);
        assert_eq!(t.total(), sum);
    }

    /// Calls of at least a millisecond each: the nested stage is charged at least their whole
    /// time, taken from the enclosing stage, and the two add up to the step's time.
    #[test]
    fn sampled_calls_are_charged_to_their_stage() {
        let start = std::time::Instant::now();
        let mut watch = Stopwatch::new();
        watch.enter(Stage::ContactResolution);
        let mut narrow = SampledStage::new(Stage::NarrowPhase);
        let pause = std::time::Duration::from_millis(1);
        for _ in 0..4 * SampledStage::EVERY {
            watch.sample(&mut narrow, || std::thread::sleep(pause));
        }
        watch.settle(&narrow);
        let t = watch.finish();
        let elapsed = start.elapsed().as_secs_f64();
        let calls = (4 * SampledStage::EVERY) as f64 * 0.001;
        let (nested, outer) = (t.get(Stage::NarrowPhase), t.get(Stage::ContactResolution));
        assert!(nested >= calls, "{nested} for {calls}");
        assert!(outer >= 0.0);
        assert!(t.total() <= elapsed, "{} in {elapsed}", t.total());
        assert_eq!(t.total(), nested + outer);
    }

    #[test]
    fn stage_names_are_unique() {
        let mut names: Vec<&str> = Stage::ALL.iter().map(|s| s.name()).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), Stage::COUNT);
        for (k, stage) in Stage::ALL.iter().enumerate() {
            assert_eq!(stage.index(), k);
        }
    }
}
