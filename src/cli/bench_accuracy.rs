//! `tumble bench accuracy`: error against run time for every scenario, setting combination and
//! time step, with a plot per scenario and its Pareto front.

use super::plot::{Series, log_log_plot};
use super::progress_bar;
use clap::Args;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::PathBuf;
use tumble::Settings;
use tumble::accuracy::{self, Scenario};
use tumble::settings::{ConstraintSchedule, RotationIntegrator};

#[derive(Debug, Args)]
pub struct AccuracyArgs {
    /// Scenarios to run (default: all).
    #[arg(long, value_enum, value_delimiter = ',')]
    pub scenarios: Vec<Scenario>,
    /// Time steps to sweep.
    #[arg(long, value_delimiter = ',', default_values_t = [0.04, 0.02, 0.01, 0.005, 0.0025])]
    pub dts: Vec<f64>,
    /// Reduced sweep for smoke tests (two time steps, fewer combinations).
    #[arg(long)]
    pub quick: bool,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Folder for the CSV and the plots.
    #[arg(long, default_value = "bench-out")]
    pub out: PathBuf,
}

/// The setting combinations compared: the coursework default, each opt-in alone, and all.
pub fn combinations() -> Vec<(&'static str, Settings)> {
    let d = Settings::default();
    vec![
        ("coursework", d.clone()),
        (
            "gyroscopic",
            Settings {
                rotation_integrator: RotationIntegrator::Gyroscopic,
                ..d.clone()
            },
        ),
        (
            "angular_momentum",
            Settings {
                rotation_integrator: RotationIntegrator::AngularMomentum,
                ..d.clone()
            },
        ),
        (
            "skip_separating",
            Settings {
                skip_separating_contacts: true,
                ..d.clone()
            },
        ),
        (
            "restitution_threshold",
            Settings {
                restitution_threshold: 0.5,
                ..d.clone()
            },
        ),
        (
            "contact_patches",
            Settings {
                contact_patches: true,
                ..d.clone()
            },
        ),
        (
            "substeps_4",
            Settings {
                substeps: 4,
                ..d.clone()
            },
        ),
        (
            "iterations_100",
            Settings {
                max_iterations: 100,
                ..d.clone()
            },
        ),
        (
            "sparse_schedule",
            Settings {
                constraint_schedule: ConstraintSchedule::Sparse,
                ..d.clone()
            },
        ),
        ("accurate", Settings::accurate()),
    ]
}

#[derive(Debug, Serialize)]
struct Row {
    wall_per_sim_second: f64,
    metrics: BTreeMap<String, f64>,
    finite: bool,
}

pub fn run(args: &AccuracyArgs) -> anyhow::Result<()> {
    let scenarios: Vec<Scenario> = if args.scenarios.is_empty() {
        Scenario::ALL.to_vec()
    } else {
        args.scenarios.clone()
    };
    let mut dts = args.dts.clone();
    let mut combos = combinations();
    if args.quick {
        dts = vec![0.04, 0.01];
        combos.retain(|(name, _)| {
            matches!(
                *name,
                "coursework" | "gyroscopic" | "restitution_threshold" | "accurate"
            )
        });
    }
    anyhow::ensure!(
        dts.iter().all(|dt| dt.is_finite() && *dt > 0.0),
        "time steps must be positive"
    );
    // Restitution of the bounce scenario: three runs per combination.
    let restitutions = [1.0, 0.8, 0.5];
    let total = scenarios
        .iter()
        .map(|s| {
            if *s == Scenario::Bounce {
                restitutions.len()
            } else {
                1
            }
        })
        .sum::<usize>()
        * combos.len()
        * dts.len();
    let bar = progress_bar(total as u64, "bench accuracy");
    // scenario -> combination -> dt -> row
    let mut results: BTreeMap<String, BTreeMap<String, BTreeMap<String, Row>>> = BTreeMap::new();
    let mut csv = String::from("scenario,combination,dt,wall_per_sim_second,metric,value\n");
    for &scenario in &scenarios {
        let variants: Vec<(String, Option<f64>)> = if scenario == Scenario::Bounce {
            restitutions
                .iter()
                .map(|e| (format!("bounce_e{e}"), Some(*e)))
                .collect()
        } else {
            vec![(scenario.name().to_string(), None)]
        };
        for (scenario_name, restitution) in &variants {
            for (combo, base) in &combos {
                for &dt in &dts {
                    bar.set_message(format!("{scenario_name} {combo} dt={dt}"));
                    let mut settings = Settings {
                        time_step: dt,
                        ..base.clone()
                    };
                    if let Some(e) = restitution {
                        settings.restitution = *e;
                    }
                    let outcome = accuracy::run(scenario, &settings);
                    for (name, value) in &outcome.metrics {
                        csv.push_str(&format!(
                            "{scenario_name},{combo},{dt},{:.6e},{name},{value:.6e}\n",
                            outcome.wall_per_sim_second
                        ));
                    }
                    let row = Row {
                        wall_per_sim_second: outcome.wall_per_sim_second,
                        metrics: outcome.metrics.iter().cloned().collect(),
                        finite: outcome.finite,
                    };
                    results
                        .entry(scenario_name.clone())
                        .or_default()
                        .entry(combo.to_string())
                        .or_default()
                        .insert(format!("{dt}"), row);
                    bar.inc(1);
                }
            }
        }
    }
    bar.finish_and_clear();

    std::fs::create_dir_all(&args.out)?;
    let csv_path = args.out.join("accuracy.csv");
    std::fs::write(&csv_path, csv)?;
    let mut plots = Vec::new();
    for (scenario_name, by_combo) in &results {
        let metric = primary_metric_of(scenario_name);
        let mut series = Vec::new();
        let mut all_points = Vec::new();
        for (combo, by_dt) in by_combo {
            let mut points: Vec<(f64, f64)> = by_dt
                .values()
                .filter_map(|r| Some((r.wall_per_sim_second, *r.metrics.get(metric)?)))
                .collect();
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
            all_points.extend(points.iter().copied());
            series.push(Series {
                name: combo.clone(),
                points,
                pareto: false,
            });
        }
        series.push(Series {
            name: "Pareto front".into(),
            points: pareto_front(&all_points),
            pareto: true,
        });
        let path = args.out.join(format!("accuracy-{scenario_name}.svg"));
        log_log_plot(
            &path,
            &format!("{scenario_name}: {metric} against run time"),
            "wall seconds per simulated second",
            metric,
            &series,
        )?;
        plots.push(path);
    }

    if args.json {
        println!("{}", serde_json::to_string_pretty(&results)?);
        return Ok(());
    }
    for (scenario_name, by_combo) in &results {
        let metric = primary_metric_of(scenario_name);
        println!("\n{scenario_name} ({metric}; wall ms per simulated second in brackets)");
        print!("{:<24}", "combination \\ dt");
        for dt in &dts {
            print!("{:>22}", dt);
        }
        println!();
        for (combo, by_dt) in by_combo {
            print!("{combo:<24}");
            for dt in &dts {
                match by_dt.get(&format!("{dt}")) {
                    Some(r) => print!(
                        "{:>22}",
                        format!(
                            "{:.3e} [{:.2}]",
                            r.metrics.get(metric).copied().unwrap_or(f64::NAN),
                            1000.0 * r.wall_per_sim_second
                        )
                    ),
                    None => print!("{:>22}", "-"),
                }
            }
            println!();
        }
    }
    println!(
        "\nwrote {} and {} plots in {}",
        csv_path.display(),
        plots.len(),
        args.out.display()
    );
    Ok(())
}

/// The plotted metric of a result row's scenario ("bounce_e0.8" is a bounce).
fn primary_metric_of(scenario_name: &str) -> &'static str {
    Scenario::ALL
        .iter()
        .find(|s| scenario_name.starts_with(s.name()))
        .map_or("error", |s| s.primary_metric())
}

/// Points not dominated in (time, error): nothing else is both faster and more accurate.
fn pareto_front(points: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mut sorted: Vec<(f64, f64)> = points
        .iter()
        .copied()
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .collect();
    sorted.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let mut front = Vec::new();
    let mut best = f64::INFINITY;
    for (x, y) in sorted {
        if y < best {
            front.push((x, y));
            best = y;
        }
    }
    front
}
