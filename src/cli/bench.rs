//! `tumble bench scale|accuracy|soak`: arguments, and the reports printed as tables or JSON.
//! The measuring is done by `tumble::bench`.

use super::ProgressBar;
use clap::Args;
use serde::Serialize;
use std::fmt::Write as _;
use std::io::Write;
use std::path::{Path, PathBuf};
use tumble::Settings;
use tumble::bench::accuracy::{AccuracyConfig, AccuracyReport, primary_metric_of};
use tumble::bench::scale::{SCENE_FAMILIES, ScaleConfig, ScaleReport, Variant};
use tumble::bench::scenarios::Scenario;
use tumble::bench::soak::SoakResult;

/// Where `bench scale` and `bench accuracy` put their report.
#[derive(Debug, Args)]
pub struct ReportArgs {
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Folder for the table (.txt), the CSV, the JSON (which `bench replot` reads) and the
    /// plots.
    #[arg(long, default_value = "bench-out")]
    pub out: PathBuf,
}

#[derive(Debug, Args)]
pub struct ScaleArgs {
    /// Scene families to run: sparse (the coursework's comparison: more bodies in the same
    /// square), pile, chain, scatter (constant density: the area grows with N) [default: all].
    #[arg(long, num_args = 1.., value_delimiter = ',')]
    pub scenes: Vec<String>,
    /// Body counts of sparse (at most 100000), pile and chain [default: 100 1000 10000; 100
    /// 1000 with --quick].
    #[arg(long, num_args = 1.., value_delimiter = ',', allow_negative_numbers = true, value_parser = super::whole_number::<usize>)]
    pub sizes: Vec<usize>,
    /// Body counts of scatter [default: 1000 10000 100000; 1000 with --quick].
    #[arg(long, num_args = 1.., value_delimiter = ',', allow_negative_numbers = true, value_parser = super::whole_number::<usize>)]
    pub scatter_sizes: Vec<usize>,
    /// Variants to run (default: all): coursework, tumble_1_thread, tumble_all_cores,
    /// accurate_1_thread, accurate_all_cores, rapier, rapier_accurate (the last two need
    /// `--features compare-rapier`).
    #[arg(long, num_args = 1.., value_delimiter = ',', value_parser = parse_variant)]
    pub variants: Vec<Variant>,
    /// Also run sparse-100000.
    #[arg(long)]
    pub huge: bool,
    /// Measured steps per run (after the warm-up); pile-N is watched on for three times as
    /// many, for its pile to come to rest (its median still covers the first ones) [default:
    /// 500; 20 with --quick].
    #[arg(long, allow_negative_numbers = true, value_parser = super::whole_number::<usize>)]
    pub steps: Option<usize>,
    /// Warm-up steps per run [default: 20; 3 with --quick].
    #[arg(long, allow_negative_numbers = true, value_parser = super::whole_number::<usize>)]
    pub warmup: Option<usize>,
    /// Wall-clock cap per run in seconds (pile-N: three times it): slow variants measure fewer
    /// steps [default: 30; 5 with --quick].
    #[arg(long, allow_negative_numbers = true)]
    pub max_seconds: Option<f64>,
    /// Short smoke run: the sizes, steps and time cap in brackets above, where not given.
    #[arg(long)]
    pub quick: bool,
    #[command(flatten)]
    pub report: ReportArgs,
}

#[derive(Debug, Args)]
pub struct AccuracyArgs {
    /// Scenarios to run (default: all).
    #[arg(long, value_enum, num_args = 1.., value_delimiter = ',')]
    pub scenarios: Vec<Scenario>,
    /// Time steps to sweep [default: 0.04 0.02 0.01 0.005 0.0025; 0.04 0.01 with --quick].
    #[arg(long, num_args = 1.., value_delimiter = ',', allow_negative_numbers = true)]
    pub dts: Vec<f64>,
    /// Setting combinations to run (default: all): coursework, gyroscopic, angular_momentum,
    /// skip_separating, restitution_threshold, contact_patches, substeps_4, iterations_100,
    /// sparse_schedule, coursework_tuned, accurate, and rapier (built with compare-rapier);
    /// `angular-momentum` and the like are taken too.
    #[arg(long, num_args = 1.., value_delimiter = ',')]
    pub combinations: Vec<String>,
    /// Reduced sweep for smoke tests: two time steps and the coursework, coursework_tuned,
    /// accurate and rapier combinations, where --dts or --combinations do not name others.
    #[arg(long)]
    pub quick: bool,
    #[command(flatten)]
    pub report: ReportArgs,
}

#[derive(Debug, Args)]
pub struct SoakArgs {
    /// Steps per scene.
    #[arg(long, default_value_t = 100_000, allow_negative_numbers = true, value_parser = super::whole_number::<u64>)]
    pub steps: u64,
    /// Use the `--accurate` preset instead of the coursework defaults.
    #[arg(long)]
    pub accurate: bool,
    /// Print a JSON array instead of the table: one object per scene.
    #[arg(long)]
    pub json: bool,
}

fn parse_variant(name: &str) -> Result<Variant, String> {
    Variant::from_name(name).ok_or_else(|| {
        let names: Vec<&str> = Variant::ALL.iter().map(|v| v.name()).collect();
        format!("unknown variant '{name}' (one of {})", names.join(", "))
    })
}

/// Most measured steps `bench scale` takes per run.
const MAX_SCALE_STEPS: usize = 1_000_000;

/// Sizes a generated scene can have, at least one measured step, and a positive time cap.
fn check_scale_config(config: &ScaleConfig) -> anyhow::Result<()> {
    use tumble::scene::MAX_GENERATED;
    if let Some(scene) = config
        .scenes
        .iter()
        .find(|s| !SCENE_FAMILIES.contains(&s.as_str()))
    {
        anyhow::bail!(
            "unknown scene family '{scene}' ({})",
            SCENE_FAMILIES.join(", ")
        );
    }
    for (flag, sizes) in [
        ("--sizes", &config.sizes),
        ("--scatter-sizes", &config.scatter_sizes),
    ] {
        if let Some(n) = sizes.iter().find(|n| !(1..=MAX_GENERATED).contains(*n)) {
            anyhow::bail!(
                "{flag}: each size must be a whole number from 1 to {MAX_GENERATED}, got {n}"
            );
        }
    }
    // Each family's own limits (sparse's smaller most, chain-N's multiples of ten).
    for family in &config.scenes {
        let (flag, sizes) = match family.as_str() {
            "scatter" => ("--scatter-sizes", &config.scatter_sizes),
            _ => ("--sizes", &config.sizes),
        };
        for &n in sizes {
            if let Some(problem) = tumble::scene::generated_size_problem(family, n) {
                anyhow::bail!("{flag}: {problem}");
            }
        }
    }
    if config.steps == 0 {
        anyhow::bail!("--steps must be at least 1");
    }
    // Each measured step's time is kept: 2^64 steps asked for that many at once and panicked.
    if config.steps > MAX_SCALE_STEPS {
        anyhow::bail!(
            "--steps must be at most {MAX_SCALE_STEPS}, got {}",
            config.steps
        );
    }
    if !(config.max_seconds > 0.0 && config.max_seconds.is_finite()) {
        anyhow::bail!(
            "--max-seconds must be a positive number of seconds, got {}",
            config.max_seconds
        );
    }
    Ok(())
}

/// The run asked for: what is given, and for the rest the defaults (or `--quick`'s).
fn scale_config(args: &ScaleArgs) -> ScaleConfig {
    fn given<T: Clone>(list: &[T], default: &mut Vec<T>) {
        if !list.is_empty() {
            *default = list.to_vec();
        }
    }
    let mut config = ScaleConfig::defaults(args.quick);
    given(&args.sizes, &mut config.sizes);
    given(&args.scatter_sizes, &mut config.scatter_sizes);
    given(&args.scenes, &mut config.scenes);
    given(&args.variants, &mut config.variants);
    config.steps = args.steps.unwrap_or(config.steps);
    config.warmup = args.warmup.unwrap_or(config.warmup);
    config.max_seconds = args.max_seconds.unwrap_or(config.max_seconds);
    config.huge = args.huge;
    config.out = args.report.out.clone();
    config
}

pub fn scale(args: &ScaleArgs) -> anyhow::Result<()> {
    let config = scale_config(args);
    check_scale_config(&config)?;
    // Asked for by name, as `bench accuracy --combinations rapier` is refused: not an empty
    // table and a zero exit.
    if let Some(v) = args.variants.iter().find(|v| v.is_rapier())
        && !cfg!(feature = "compare-rapier")
    {
        anyhow::bail!(
            "--variants {}: this build has no Rapier; build with --features compare-rapier",
            v.name()
        );
    }
    let report = tumble::bench::scale::run(&config, &ProgressBar::default())?;
    print_or_table(
        args.report.json,
        &report,
        &report.csv,
        &report.plots,
        |out| {
            writeln!(out, "machine: {}", report.machine.describe())?;
            print_scale(out, &report)
        },
    )
}

/// With `--json` prints `value` as JSON, else the `table` and then the files written (one
/// `wrote` line for the CSV, JSON and table, then one a plot, as `bench replot` says them);
/// either way the JSON and the table are written beside the `csv` (its name with `.json` and
/// `.txt`), so a folder's JSON, CSV, table and `plots` are always from the same run. The table
/// file holds the table only.
fn print_or_table<T: Serialize>(
    json: bool,
    value: &T,
    csv: &Path,
    plots: &[PathBuf],
    table: impl FnOnce(&mut String) -> std::fmt::Result,
) -> anyhow::Result<()> {
    let text = serde_json::to_string_pretty(value)?;
    let json_path = csv.with_extension("json");
    tumble::io::write_file_atomically(&json_path, |w| w.write_all(text.as_bytes()))?;
    let mut lines = String::new();
    table(&mut lines)?;
    let txt = csv.with_extension("txt");
    tumble::io::write_file_atomically(&txt, |w| w.write_all(lines.as_bytes()))?;
    if json {
        println!("{text}");
    } else {
        print!("{lines}");
        let (csv, json_path, txt) = (csv.display(), json_path.display(), txt.display());
        println!("\nwrote {csv}, {json_path} and {txt}");
        print_written(plots);
    }
    Ok(())
}

/// One `wrote` line a file: the benches' plots and `bench replot`'s.
fn print_written(files: &[PathBuf]) {
    for file in files {
        println!("wrote {}", file.display());
    }
}

/// One scene's variant as a row of the scale table.
fn scale_row(key: &str, v: &str, m: &tumble::bench::scale::Measurement) -> String {
    let s = |k: &str| m.mean_stage_ms.get(k).copied().unwrap_or(0.0);
    let solve = [
        "contact_resolution",
        "ground",
        "solve_prepare",
        "solve",
        "solve_finish",
    ]
    .map(s)
    .iter()
    .sum::<f64>();
    let figures = [
        s("broad_phase"),
        s("narrow_phase"),
        solve,
        s("constraints"),
        s("integrate"),
    ];
    // Rapier's runs time no stage of tumble's and count no visits: a dash, not 0.000.
    let timed = m.stages_timed();
    let stages: Vec<String> = figures
        .iter()
        .map(|ms| match timed {
            true => format!("{ms:>8.3}"),
            false => format!("{:>8}", "-"),
        })
        .collect();
    let visits = match timed {
        true => format!("{:>7.0}", m.constraint_visits_per_step),
        false => format!("{:>7}", "-"),
    };
    format!(
        "{key:<14} {v:<18} {:>9.3} {:>9.3} {} {visits} {:>8.1} {:>7}",
        m.median_ms_per_step,
        m.late_median_ms_per_step,
        stages.join(" "),
        m.peak_mib,
        m.asleep_at_end
    )
}

fn print_scale(out: &mut String, report: &ScaleReport) -> std::fmt::Result {
    writeln!(
        out,
        "{:<14} {:<18} {:>9} {:>9} {:>8} {:>8} {:>8} {:>8} {:>8} {:>7} {:>8} {:>7}",
        "scene",
        "variant",
        "ms/step",
        "late",
        "broad",
        "narrow",
        "solve",
        "constr",
        "integr",
        "visits",
        "peakMiB",
        "asleep"
    )?;
    for (key, by_variant) in &report.results {
        for (variant, m) in by_variant {
            writeln!(out, "{}", scale_row(key, variant, m))?;
        }
        if let Some(sp) = report.speedups.get(key) {
            let parts: Vec<String> = sp.iter().map(|(k, v)| format!("{k} = {v:.2}x")).collect();
            if !parts.is_empty() {
                writeln!(out, "{:<14} {}", "", parts.join(", "))?;
            }
        }
    }
    writeln!(
        out,
        "\nms/step: median over the measured steps; a run whose steps took under a second in all \
         was run again, up to five times in all, each step taking its median time over the runs \
         (`runs` in the CSV and JSON). pile-N is watched on for {}x the steps and the time cap, \
         for its pile to land and come to rest: its median, stages and ratios cover the first \
         steps as every scene's do; late: the median over the last fifth of all its steps.",
        tumble::bench::scale::PILE_WINDOW
    )?;
    if !report.growth.is_empty() {
        writeln!(
            out,
            "\ngrowth from one size to the next (larger median / smaller, over the steps both measured):"
        )?;
        for (family, by_variant) in &report.growth {
            for (variant, steps) in by_variant {
                let mut steps: Vec<_> = steps.iter().collect();
                // Keys are "N1->N2": in order of N1, not of the text.
                steps.sort_by_key(|(k, _)| {
                    k.split('-').next().and_then(|n| n.parse::<usize>().ok())
                });
                let parts: Vec<String> =
                    steps.iter().map(|(k, v)| format!("{k}: {v:.1}x")).collect();
                writeln!(out, "  {family:<8} {variant:<18} {}", parts.join(", "))?;
            }
        }
    }
    if !report.left_out.is_empty() {
        writeln!(out, "\nleft out:")?;
        for why in &report.left_out {
            writeln!(out, "  {why}")?;
        }
    }
    writeln!(
        out,
        "\nratios a_over_b: a's median ms / b's, over the steps both runs measured (a run cut by the time cap measured fewer)"
    )?;
    writeln!(out, "accurate variants: {}", report.accurate_settings)?;
    writeln!(out, "{}", report.rapier)?;
    Ok(())
}

pub fn accuracy(args: &AccuracyArgs) -> anyhow::Result<()> {
    let config = AccuracyConfig {
        scenarios: args.scenarios.clone(),
        dts: args.dts.clone(),
        // `angular-momentum` as the settings flags spell it, `angular_momentum` as the results do.
        combinations: (args.combinations.iter())
            .map(|name| name.replace('-', "_"))
            .collect(),
        quick: args.quick,
        out: args.report.out.clone(),
    };
    let report = tumble::bench::accuracy::run(&config, &ProgressBar::default())?;
    print_or_table(
        args.report.json,
        &report.results,
        &report.csv,
        &report.plots,
        |out| {
            writeln!(out, "machine: {}", report.machine.describe())?;
            print_accuracy(out, &report)
        },
    )
}

fn print_accuracy(out: &mut String, report: &AccuracyReport) -> std::fmt::Result {
    for (scenario_name, by_combo) in &report.results {
        let metric = primary_metric_of(scenario_name);
        writeln!(
            out,
            "\n{scenario_name} ({metric}; wall ms per simulated second in brackets, fastest of \
             repeated runs)"
        )?;
        write!(out, "{:<24}", "combination \\ dt")?;
        for dt in &report.dts {
            write!(out, "{:>22}", dt)?;
        }
        writeln!(out)?;
        for (combo, by_dt) in by_combo {
            write!(out, "{combo:<24}")?;
            for dt in &report.dts {
                match by_dt.get(&format!("{dt}")) {
                    Some(r) => write!(
                        out,
                        "{:>22}",
                        format!(
                            "{:.3e} [{:.2}]",
                            r.metrics.get(metric).copied().unwrap_or(f64::NAN),
                            1000.0 * r.wall_per_sim_second
                        )
                    )?,
                    None => write!(out, "{:>22}", "-")?,
                }
            }
            writeln!(out)?;
        }
    }
    Ok(())
}

#[derive(Debug, Args)]
pub struct ReplotArgs {
    /// Folder of an earlier run's accuracy.json and scale.json (either); the plots are written
    /// beside them.
    #[arg(default_value = "bench-out")]
    pub folder: PathBuf,
}

/// A report's reader of its plots: its JSON text and the folder to draw into.
type Replot = fn(&str, &Path) -> anyhow::Result<Vec<PathBuf>>;

pub fn replot(args: &ReplotArgs) -> anyhow::Result<()> {
    use anyhow::Context;
    let folder = &args.folder;
    let what = if folder.exists() {
        "a file, not a folder"
    } else {
        "no such folder"
    };
    anyhow::ensure!(folder.is_dir(), "{}: {what}", folder.display());
    let reports: [(&str, Replot); 2] = [
        ("accuracy.json", tumble::bench::accuracy::replot),
        ("scale.json", tumble::bench::scale::replot),
    ];
    // Each report drawn on its own: a malformed accuracy.json left scale.json undrawn.
    let (mut plots, mut failures, mut found) = (Vec::new(), Vec::new(), 0);
    for (name, replot) in reports {
        let json = args.folder.join(name);
        if !json.is_file() {
            continue;
        }
        found += 1;
        let drawn = std::fs::read_to_string(&json)
            .with_context(|| format!("cannot read {}", json.display()))
            .and_then(|text| {
                replot(&text, &args.folder).with_context(|| json.display().to_string())
            });
        match drawn {
            Ok(drawn) => plots.extend(drawn),
            Err(e) => failures.push(format!("{e:#}")),
        }
    }
    anyhow::ensure!(
        found > 0,
        "{}: no accuracy.json or scale.json to plot",
        args.folder.display()
    );
    print_written(&plots);
    anyhow::ensure!(failures.is_empty(), "{}", failures.join("\n"));
    Ok(())
}

pub fn soak(args: &SoakArgs) -> anyhow::Result<()> {
    // Zero steps read as bodies that never moved (speed 0), as `bench scale` refuses them.
    anyhow::ensure!(args.steps >= 1, "--steps must be at least 1");
    let settings = if args.accurate {
        Settings::accurate()
    } else {
        Settings::default()
    };
    let results = tumble::bench::soak::run(&settings, args.steps, &ProgressBar::default())?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&results)?);
    } else {
        print_soak(&results);
    }
    Ok(())
}

fn print_soak(results: &[SoakResult]) {
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
    for r in results {
        println!(
            "{:<10} {:>8} {:>8.2} {:>10} {:>12.4} {:>12.3e} {:>8} {:>13.6e} {:>13.6e} {:>6}",
            r.scene,
            r.steps,
            r.wall_s,
            // None for a run shorter than the second it settles in.
            r.max_drift.map_or("-".to_string(), |d| format!("{d:.3}")),
            r.late_max_speed,
            r.worst_relative_violation,
            r.budget_hits,
            r.energy_start,
            r.energy_end,
            r.finite
        );
    }
}
