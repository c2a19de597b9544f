//! `tumble run`: headless simulation with a summary.

use super::{SceneArgs, SettingsArgs, progress_bar};
use clap::Args;
use serde::Serialize;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;
use tumble::io::{counted, trajectory};
use tumble::sim::quarantine::ABSURD_SPEED;
use tumble::sim::stats::StageTimings;

#[derive(Debug, Args)]
pub struct RunArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Number of steps.
    #[arg(long, default_value_t = 500, allow_negative_numbers = true, value_parser = super::whole_number::<u64>)]
    pub steps: u64,
    /// Write time, centre of mass and orientation of every body at the start (step 0) and after
    /// every step (CSV); `-` writes it to standard output, and the summary to standard error.
    #[arg(long, value_name = "FILE.csv")]
    pub trajectory: Option<PathBuf>,
    /// Print one JSON object instead of the text summary (JSON has no infinity: a number that
    /// is not finite, as the energy of a run that blew up, is null).
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub settings: SettingsArgs,
}

#[derive(Debug, Serialize)]
pub struct RunSummary {
    pub scene: String,
    pub steps: u64,
    pub sim_time: f64,
    pub wall_s: f64,
    pub steps_per_s: f64,
    pub bodies: usize,
    /// Constraint inequalities: two a distance constraint record, its lower and its upper bound
    /// (the coursework's M counts them so).
    pub constraints: usize,
    /// Distance constraint records (lines of the constraint file).
    pub constraint_records: usize,
    pub contacts: usize,
    /// Box-against-box tests the broad phase made.
    pub pairs_tested: usize,
    /// Pairs handed to the narrow phase (boxes overlapping).
    pub narrow_phase_queries: usize,
    /// Contacts the separating-axis fallback computed because parry's GJK/EPA failed.
    pub narrow_phase_fallbacks: usize,
    pub ground_contacts: usize,
    pub constraint_visits: usize,
    pub budget_hits: u64,
    /// Soft step: joint groups left out of bounds by their projections (see `StepStats`).
    pub joint_projections_cut_short: usize,
    /// Soft step: joint groups solved by Gauss-Seidel at the end (see `StepStats`).
    pub joint_groups_relaxed: usize,
    pub energy_start: f64,
    /// Energy of the bodies still moving at the end.
    pub energy_end: f64,
    /// Energy of the bodies frozen because their state blew up (at their last finite pose).
    pub energy_frozen: f64,
    pub max_penetration: f64,
    /// Largest distance, in scene units, by which a constraint lay outside its bound after a
    /// step.
    pub max_constraint_violation: f64,
    /// Largest violation as a share of its constraint's rest length (the bench's chains
    /// metric; not necessarily the same constraint's; points placed together, with no rest
    /// length, are left out).
    pub max_relative_constraint_violation: f64,
    pub finite: bool,
    pub quarantined: Vec<usize>,
    /// Bodies asleep after the last step (soft-step solver).
    pub asleep_at_end: usize,
    /// Substeps of all steps (see `StepStats::substeps`).
    pub substeps_taken: u64,
    /// Mean milliseconds per step in each stage.
    pub stage_ms: StageTimings,
    pub settings: tumble::Settings,
}

pub fn run(args: &RunArgs) -> anyhow::Result<()> {
    let settings = args.settings.settings()?;
    let mut world = args.scene.load(settings.clone())?;
    let mut summary = RunSummary::start(&args.scene.scene, args.steps, &world, settings);
    let mut trajectory = (args.trajectory.as_deref())
        .map(|path| TrajectoryOut::open(path, &world.inputs))
        .transpose()?;
    if let Some(out) = &mut trajectory {
        out.write(|w| trajectory::write_header(w))?;
        out.write(|w| trajectory::write_rows(w, &world))?;
    }
    super::interrupt::install(true);
    let start = Instant::now();
    let completed = simulate(args.steps, &mut world, &mut summary, trajectory.as_mut())?;
    summary.finish(&world, completed, start.elapsed().as_secs_f64());
    let interrupted = completed < args.steps;
    // With the trajectory on standard output, the summary goes to standard error.
    let to_stdout = matches!(trajectory, Some(TrajectoryOut::Stdout(_)));
    if let Some(out) = trajectory {
        out.finish()?;
    }
    // A file written is named (on standard error, where the summary's text would not be read
    // as CSV): it was written without a word.
    if let Some(path) = args.trajectory.as_deref().filter(|_| !to_stdout) {
        eprintln!(
            "trajectory: steps 0 to {completed} written to {}",
            path.display()
        );
    }
    if interrupted {
        eprintln!(
            "interrupted after {completed} of {}{}",
            counted(args.steps, "step", "steps"),
            if args.trajectory.is_some() {
                "; the trajectory holds the steps completed"
            } else {
                ""
            }
        );
    }
    let mut out: Box<dyn Write> = match to_stdout {
        true => Box::new(std::io::stderr().lock()),
        false => Box::new(std::io::stdout().lock()),
    };
    if args.json {
        writeln!(out, "{}", serde_json::to_string_pretty(&summary)?)?;
    } else {
        print_summary(&mut out, &summary)?;
    }
    if interrupted {
        std::process::exit(super::interrupt::exit_status());
    }
    Ok(())
}

/// Where the trajectory goes: a file, its rows streamed into a temporary file renamed into
/// place when the run ends (also on Ctrl-C), or standard output (`-`).
enum TrajectoryOut {
    File(tumble::io::AtomicFile),
    Stdout(std::io::BufWriter<std::io::Stdout>),
}

impl TrajectoryOut {
    /// The output `path` names; a file must not be one of the scene's `inputs`.
    fn open(path: &Path, inputs: &[PathBuf]) -> anyhow::Result<Self> {
        if path == Path::new("-") {
            return Ok(Self::Stdout(std::io::BufWriter::new(std::io::stdout())));
        }
        tumble::io::check_output(path, inputs)?;
        Ok(Self::File(tumble::io::AtomicFile::create(path)?))
    }

    /// Writes with `write`; an error names where the trajectory goes (a full disk, a closed
    /// pipe: the bare OS error named no file).
    fn write(
        &mut self,
        write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
    ) -> anyhow::Result<()> {
        let written = match self {
            Self::File(file) => write(file.writer()),
            Self::Stdout(out) => write(out),
        };
        // The name made only on an error: this runs every step.
        written.map_err(|e| anyhow::anyhow!("writing the trajectory to {}: {e}", self.name()))
    }

    /// Where the trajectory goes, for errors.
    fn name(&self) -> String {
        match self {
            Self::File(file) => file.path().display().to_string(),
            Self::Stdout(_) => "standard output".into(),
        }
    }

    /// The file renamed into place, or standard output flushed.
    fn finish(self) -> anyhow::Result<()> {
        match self {
            Self::File(file) => file.commit(),
            Self::Stdout(mut out) => Ok(out.flush()?),
        }
    }
}

/// Steps until `steps` are done or Ctrl-C; returns the number of steps completed.
fn simulate(
    steps: u64,
    world: &mut tumble::World,
    summary: &mut RunSummary,
    trajectory: Option<&mut TrajectoryOut>,
) -> anyhow::Result<u64> {
    let bar = progress_bar(steps, "simulating");
    // Where the world's steps run: in the thread pool, handed over once, for a large scene.
    let completed =
        world.stepping(|world| steps_until_interrupted(steps, world, summary, trajectory, &bar))?;
    bar.finish_and_clear();
    Ok(completed)
}

/// The loop of [`simulate`].
fn steps_until_interrupted(
    steps: u64,
    world: &mut tumble::World,
    summary: &mut RunSummary,
    mut trajectory: Option<&mut TrajectoryOut>,
    bar: &indicatif::ProgressBar,
) -> anyhow::Result<u64> {
    let mut completed = 0;
    for k in 0..steps {
        if super::interrupt::interrupted() {
            break;
        }
        let stats = world.step();
        warn_of_blow_ups(
            &stats.quarantined,
            summary.quarantined.len(),
            world.step_count,
        );
        summary.add_step(world, stats);
        if let Some(out) = trajectory.as_deref_mut() {
            out.write(|w| trajectory::write_rows(w, world))?;
        }
        if k % 64 == 0 {
            bar.set_position(k);
        }
        completed = k + 1;
    }
    Ok(completed)
}

/// Bodies that blew up and were frozen (at step `step`, after `earlier` others): one line each
/// for the first [`BLOW_UP_LINES`], then one saying that more follow (a step of 1e300 s froze
/// two thousand bodies of a pile, a line each); the summary lists them all.
fn warn_of_blow_ups(frozen: &[usize], earlier: usize, step: u64) {
    for (k, &b) in frozen.iter().enumerate() {
        match earlier + k {
            n if n < BLOW_UP_LINES => eprintln!(
                "warning: body {b} blew up at step {step} (a non-finite value or a speed above {:e} \
                 units/s) and was frozen at its last good pose",
                ABSURD_SPEED
            ),
            BLOW_UP_LINES => eprintln!(
                "warning: more bodies blew up from step {step} on and were frozen; the summary \
                 counts them all"
            ),
            _ => return,
        }
    }
}

/// Bodies named one by one as they blow up.
const BLOW_UP_LINES: usize = 10;

impl RunSummary {
    fn start(scene: &str, steps: u64, world: &tumble::World, settings: tumble::Settings) -> Self {
        let energy_start = world.total_energy() + 0.0;
        let worst = world.worst_constraint_violations();
        RunSummary {
            scene: scene.to_string(),
            steps,
            sim_time: 0.0,
            wall_s: 0.0,
            steps_per_s: 0.0,
            bodies: world.bodies.len(),
            constraints: world.constraints.len(),
            constraint_records: world.constraints.iter().filter(|c| !c.is_upper).count(),
            contacts: 0,
            pairs_tested: 0,
            narrow_phase_queries: 0,
            narrow_phase_fallbacks: 0,
            ground_contacts: 0,
            constraint_visits: 0,
            budget_hits: 0,
            joint_projections_cut_short: 0,
            joint_groups_relaxed: 0,
            energy_start,
            energy_end: energy_start,
            energy_frozen: 0.0,
            max_penetration: 0.0,
            max_constraint_violation: worst.0,
            max_relative_constraint_violation: worst.1,
            finite: world.all_finite(),
            quarantined: Vec::new(),
            asleep_at_end: 0,
            substeps_taken: 0,
            stage_ms: StageTimings::default(),
            settings,
        }
    }

    fn add_step(&mut self, world: &tumble::World, stats: tumble::StepStats) {
        self.contacts += stats.contacts;
        self.pairs_tested += stats.pairs_tested;
        self.narrow_phase_queries += stats.narrow_phase_queries;
        self.narrow_phase_fallbacks += stats.narrow_phase_fallbacks;
        self.ground_contacts += stats.ground_contacts;
        self.constraint_visits += stats.constraint_visits;
        self.budget_hits += stats.budget_hit as u64;
        self.joint_projections_cut_short += stats.joint_projections_cut_short;
        self.max_penetration = self.max_penetration.max(stats.max_penetration);
        self.stage_ms.add(&stats.timings);
        self.quarantined.extend(stats.quarantined);
        self.asleep_at_end = stats.asleep;
        self.joint_groups_relaxed = stats.joint_groups_relaxed;
        self.substeps_taken += stats.substeps as u64;
        if !world.constraints.is_empty() {
            let (absolute, relative) = world.worst_constraint_violations();
            self.max_constraint_violation = self.max_constraint_violation.max(absolute);
            self.max_relative_constraint_violation =
                self.max_relative_constraint_violation.max(relative);
        }
    }

    /// Totals after `completed` steps in `wall_s` seconds: rates, final energy, ms per step.
    fn finish(&mut self, world: &tumble::World, completed: u64, wall_s: f64) {
        self.steps = completed;
        self.wall_s = wall_s;
        self.sim_time = world.time;
        self.steps_per_s = if wall_s > 0.0 {
            completed as f64 / wall_s
        } else {
            f64::INFINITY
        };
        // (+ 0.0: an empty scene's energy is 0, not -0.)
        self.energy_end = world.total_energy() + 0.0;
        self.energy_frozen = world.frozen_energy();
        self.finite = world.all_finite() && self.quarantined.is_empty();
        self.stage_ms = self.stage_ms.scaled(1000.0 / completed.max(1) as f64);
    }
}

/// The text summary, into `out`.
fn print_summary(out: &mut impl Write, s: &RunSummary) -> std::io::Result<()> {
    let records = s.constraint_records;
    let inequalities = match s.constraints {
        0 => String::new(),
        n => format!(" ({n} inequalities)"),
    };
    writeln!(
        out,
        "scene {}: {}, {}{inequalities}",
        s.scene,
        counted(s.bodies as u64, "body", "bodies"),
        counted(
            records as u64,
            "distance constraint",
            "distance constraints"
        ),
    )?;
    writeln!(
        out,
        "{} ({} s simulated) in {:.3} s wall: {} steps/s",
        counted(s.steps, "step", "steps"),
        super::decimals(s.sim_time, 2),
        s.wall_s,
        steps_per_second(s.steps_per_s)
    )?;
    writeln!(
        out,
        "contacts over the run: {} body-body, {} ground; deepest penetration {}",
        s.contacts,
        s.ground_contacts,
        super::decimals(s.max_penetration, 4)
    )?;
    let per_step = |n: usize| n as f64 / s.steps.max(1) as f64;
    writeln!(
        out,
        "per step: {:.1} box tests, {:.1} narrow-phase queries, {:.2} substeps",
        per_step(s.pairs_tested),
        per_step(s.narrow_phase_queries),
        per_step(s.substeps_taken as usize)
    )?;
    if s.constraints > 0 && s.settings.solver == tumble::sim::settings::Solver::SoftStep {
        writeln!(
            out,
            "joint projections cut short {}, worst violation {}",
            s.joint_projections_cut_short,
            worst_violation(s)
        )?;
    } else if s.constraints > 0 {
        writeln!(
            out,
            "constraint visits {}, budget hit in {}, worst violation {}",
            s.constraint_visits,
            counted(s.budget_hits, "step", "steps"),
            worst_violation(s)
        )?;
    }
    print_state_at_end(out, s)
}

/// A rate of steps for the summary: whole from 100 a second up, else to three figures (a run of
/// 2 steps in 14.7 s read "0 steps/s").
fn steps_per_second(rate: f64) -> String {
    if rate >= 100.0 {
        format!("{rate:.0}")
    } else {
        tumble::io::significant(rate, 3)
    }
}

/// The worst constraint violation in scene units, and the worst share of a rest length (not
/// necessarily the same constraint's).
fn worst_violation(s: &RunSummary) -> String {
    format!(
        "{}, worst share of a rest length {}",
        super::decimals(s.max_constraint_violation, 4),
        tumble::io::significant(s.max_relative_constraint_violation, 2)
    )
}

/// The summary's lines on the state the run ended in: energy, sleep, blow-ups, stage times.
fn print_state_at_end(out: &mut impl Write, s: &RunSummary) -> std::io::Result<()> {
    // The share first: 100 times an energy of 3e306 was infinite.
    let change = 100.0 * ((s.energy_end - s.energy_start) / s.energy_start.abs().max(1e-300));
    // Past a billion percent in scientific notation (`--dt 1e9` printed twenty digits). An
    // energy past f64's range (a body at y = 1e306) has no share: it printed "NaN%".
    let sign = if change >= 0.0 { "+" } else { "" };
    let share = match change.is_finite() {
        true => format!("{sign}{}%", super::decimals(change, 3)),
        false => "no change to give: an energy lies beyond f64's range".to_string(),
    };
    let frozen = match s.quarantined.len() {
        0 => String::new(),
        n => format!(
            "; the end leaves out {}, potential energy {:.6e}",
            counted(n as u64, "frozen body", "frozen bodies"),
            s.energy_frozen
        ),
    };
    writeln!(
        out,
        "energy {:.6e} -> {:.6e} ({share}{frozen})",
        s.energy_start, s.energy_end,
    )?;
    if s.joint_groups_relaxed > 0 {
        writeln!(
            out,
            "joint groups over-braced (rods that depend on each other): {} solved by Gauss-Seidel, held within a few percent",
            s.joint_groups_relaxed
        )?;
    }
    if s.asleep_at_end > 0 {
        writeln!(
            out,
            "asleep at the end: {} of {} bodies",
            s.asleep_at_end, s.bodies
        )?;
    }
    if s.quarantined.is_empty() {
        writeln!(out, "all values finite: {}", s.finite)?;
    } else {
        let shown: Vec<String> = s
            .quarantined
            .iter()
            .take(10)
            .map(|b| b.to_string())
            .collect();
        let more = if s.quarantined.len() > 10 {
            ", ..."
        } else {
            ""
        };
        writeln!(
            out,
            "all values finite: false ({} blew up and {} frozen: {}{more})",
            counted(s.quarantined.len() as u64, "body", "bodies"),
            if s.quarantined.len() == 1 {
                "was"
            } else {
                "were"
            },
            shown.join(", ")
        )?;
    }
    let stages: Vec<String> = s
        .stage_ms
        .iter()
        .filter(|(stage, _)| stage.runs_under(s.settings.solver))
        .map(|(stage, ms)| format!("{} {ms:.3}", stage.name()))
        .collect();
    writeln!(out, "ms/step: {}", stages.join(", "))
}
