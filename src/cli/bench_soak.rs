//! `tumble bench soak`: the resting tower and the hanging chains for a long time (100,000 steps
//! by default), reporting drift, constraint violation, energy and run time.

use super::progress_bar;
use clap::Args;
use serde::Serialize;
use std::time::Instant;
use tumble::{ConstraintsChoice, Settings};

#[derive(Debug, Args)]
pub struct SoakArgs {
    /// Steps per scene.
    #[arg(long, default_value_t = 100_000)]
    pub steps: u64,
    /// Use the `--accurate` preset instead of the coursework defaults.
    #[arg(long)]
    pub accurate: bool,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
}

#[derive(Debug, Serialize)]
struct SoakResult {
    scene: String,
    steps: u64,
    wall_s: f64,
    /// Largest distance any body's centre of mass moved from where it settled after 1 s.
    max_drift: f64,
    /// Largest speed of any body over the last 10 % of the run.
    late_max_speed: f64,
    /// Worst violation relative to the rest length over the whole run (chains).
    worst_relative_violation: f64,
    budget_hits: u64,
    energy_start: f64,
    energy_end: f64,
    finite: bool,
}

pub fn run(args: &SoakArgs) -> anyhow::Result<()> {
    let settings = if args.accurate {
        Settings::accurate()
    } else {
        Settings::default()
    };
    let mut results = Vec::new();
    for scene in ["tower", "two-chain"] {
        let mut world = tumble::scene::load(scene, &ConstraintsChoice::Auto, settings.clone())?;
        let energy_start = world.total_energy();
        let settle_steps = (1.0 / settings.time_step).ceil() as u64;
        let mut settled: Option<Vec<glam::DVec3>> = None;
        let (mut max_drift, mut late_max_speed, mut worst, mut budget_hits) =
            (0.0f64, 0.0f64, 0.0f64, 0);
        let bar = progress_bar(args.steps, &format!("soak {scene}"));
        let start = Instant::now();
        for k in 0..args.steps {
            let stats = world.step();
            budget_hits += stats.budget_hit as u64;
            if k + 1 == settle_steps {
                settled = Some(world.bodies.iter().map(|b| b.position).collect());
            }
            if let Some(reference) = &settled {
                for (b, x) in world.bodies.iter().zip(reference) {
                    max_drift = max_drift.max((b.position - *x).length());
                }
            }
            if k >= args.steps - args.steps / 10 {
                for b in &world.bodies {
                    late_max_speed = late_max_speed.max(b.linear_velocity.length());
                }
            }
            for c in &world.constraints {
                worst = worst.max(c.violation(&world.bodies) / c.rest_length);
            }
            if k % 1024 == 0 {
                bar.set_position(k);
            }
        }
        bar.finish_and_clear();
        results.push(SoakResult {
            scene: scene.to_string(),
            steps: args.steps,
            wall_s: start.elapsed().as_secs_f64(),
            max_drift,
            late_max_speed,
            worst_relative_violation: worst,
            budget_hits,
            energy_start,
            energy_end: world.total_energy(),
            finite: world.all_finite(),
        });
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&results)?);
        return Ok(());
    }
    println!(
        "{:<10} {:>8} {:>8} {:>10} {:>12} {:>12} {:>8} {:>13} {:>13} {:>6}",
        "scene",
        "steps",
        "wall s",
        "max drift",
        "late speed",
        "worst viol.",
        "budget",
        "energy start",
        "energy end",
        "finite"
    );
    for r in &results {
        println!(
            "{:<10} {:>8} {:>8.2} {:>10.3} {:>12.4} {:>12.3e} {:>8} {:>13.6e} {:>13.6e} {:>6}",
            r.scene,
            r.steps,
            r.wall_s,
            r.max_drift,
            r.late_max_speed,
            r.worst_relative_violation,
            r.budget_hits,
            r.energy_start,
            r.energy_end,
            r.finite
        );
    }
    Ok(())
}
