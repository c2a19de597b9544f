//! `tumble run`: headless simulation with a summary.

use super::{SceneArgs, SettingsArgs, progress_bar};
use clap::Args;
use serde::Serialize;
use std::path::PathBuf;
use std::time::Instant;
use tumble::io::trajectory;
use tumble::sim::stats::StageTimings;

#[derive(Debug, Args)]
pub struct RunArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Number of steps.
    #[arg(long, default_value_t = 500)]
    pub steps: u64,
    /// Write time, centre of mass and orientation of every body after every step (CSV).
    #[arg(long, value_name = "FILE.csv")]
    pub trajectory: Option<PathBuf>,
    /// Print one JSON object instead of the text summary.
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
    pub constraints: usize,
    pub contacts: usize,
    /// Pairs handed to the narrow phase (boxes overlapping).
    pub narrow_phase_queries: usize,
    pub ground_contacts: usize,
    pub constraint_visits: usize,
    pub budget_hits: u64,
    pub energy_start: f64,
    pub energy_end: f64,
    pub max_penetration: f64,
    pub max_constraint_violation: f64,
    pub finite: bool,
    pub quarantined: Vec<usize>,
    /// Mean milliseconds per step in each stage.
    pub stage_ms: StageTimings,
    pub settings: tumble::Settings,
}

pub fn run(args: &RunArgs) -> anyhow::Result<()> {
    let settings = args.settings.settings()?;
    let mut world = args.scene.load(settings.clone())?;
    let energy_start = world.total_energy();
    // Rows stream into a temporary file, renamed into place when the run ends (also on Ctrl-C).
    let mut trajectory = args
        .trajectory
        .as_deref()
        .map(tumble::io::AtomicFile::create)
        .transpose()?;
    if let Some(out) = &mut trajectory {
        trajectory::write_header(out.writer())?;
        trajectory::write_rows(out.writer(), &world)?;
    }
    let bar = progress_bar(args.steps, "simulating");
    let mut summary = RunSummary {
        scene: args.scene.scene.clone(),
        steps: args.steps,
        sim_time: 0.0,
        wall_s: 0.0,
        steps_per_s: 0.0,
        bodies: world.bodies.len(),
        constraints: world.constraints.len(),
        contacts: 0,
        narrow_phase_queries: 0,
        ground_contacts: 0,
        constraint_visits: 0,
        budget_hits: 0,
        energy_start,
        energy_end: energy_start,
        max_penetration: 0.0,
        max_constraint_violation: world.max_constraint_violation(),
        finite: world.all_finite(),
        quarantined: Vec::new(),
        stage_ms: StageTimings::default(),
        settings,
    };
    super::interrupt::install();
    let mut completed = 0;
    let start = Instant::now();
    for k in 0..args.steps {
        if super::interrupt::interrupted() {
            break;
        }
        let stats = world.step();
        summary.contacts += stats.contacts;
        summary.narrow_phase_queries += stats.narrow_phase_queries;
        summary.ground_contacts += stats.ground_contacts;
        summary.constraint_visits += stats.constraint_visits;
        summary.budget_hits += stats.budget_hit as u64;
        summary.max_penetration = summary.max_penetration.max(stats.max_penetration);
        summary.stage_ms.add(&stats.timings);
        for b in stats.quarantined {
            eprintln!(
                "warning: body {b} went non-finite at step {} and was frozen",
                world.step_count
            );
            summary.quarantined.push(b);
        }
        if !world.constraints.is_empty() {
            summary.max_constraint_violation = summary
                .max_constraint_violation
                .max(world.max_constraint_violation());
        }
        if let Some(out) = &mut trajectory {
            trajectory::write_rows(out.writer(), &world)?;
        }
        if k % 64 == 0 {
            bar.set_position(k);
        }
        completed = k + 1;
    }
    bar.finish_and_clear();
    summary.wall_s = start.elapsed().as_secs_f64();
    summary.sim_time = world.time;
    summary.steps_per_s = if summary.wall_s > 0.0 {
        completed as f64 / summary.wall_s
    } else {
        f64::INFINITY
    };
    summary.energy_end = world.total_energy();
    summary.finite = world.all_finite() && summary.quarantined.is_empty();
    summary.stage_ms = summary.stage_ms.scaled(1000.0 / completed.max(1) as f64);

    let interrupted = completed < args.steps;
    summary.steps = completed;
    if let Some(out) = trajectory {
        out.commit()?;
    }
    if interrupted {
        eprintln!(
            "interrupted after {completed} of {} steps{}",
            args.steps,
            if args.trajectory.is_some() {
                "; the trajectory holds the steps completed"
            } else {
                ""
            }
        );
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        print_summary(&summary);
    }
    if interrupted {
        // The conventional status of a run stopped by SIGINT.
        std::process::exit(130);
    }
    Ok(())
}

fn print_summary(s: &RunSummary) {
    println!(
        "scene {}: {} bodies, {} constraints",
        s.scene, s.bodies, s.constraints
    );
    println!(
        "{} steps ({:.2} s simulated) in {:.3} s wall: {:.0} steps/s",
        s.steps, s.sim_time, s.wall_s, s.steps_per_s
    );
    println!(
        "contacts {} body-body, {} ground; deepest penetration {:.4}",
        s.contacts, s.ground_contacts, s.max_penetration
    );
    if s.constraints > 0 {
        println!(
            "constraint visits {}, budget hit in {} steps, worst violation {:.4}",
            s.constraint_visits, s.budget_hits, s.max_constraint_violation
        );
    }
    println!(
        "energy {:.6e} -> {:.6e} ({:+.3}%)",
        s.energy_start,
        s.energy_end,
        100.0 * (s.energy_end - s.energy_start) / s.energy_start.abs().max(1e-300)
    );
    println!("all values finite: {}", s.finite);
    let stages: Vec<String> = s
        .stage_ms
        .iter()
        .map(|(stage, ms)| format!("{} {ms:.3}", stage.name()))
        .collect();
    println!("ms/step: {}", stages.join(", "));
}
