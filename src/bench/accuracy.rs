//! `tumble bench accuracy`: error against run time for every scenario, setting combination and
//! time step, a CSV of every metric and a log-log plot per scenario with its Pareto front.

use super::Progress;
use super::plot::{Series, log_log_plot};
use super::scenarios::{self, Engine, Scenario};
use crate::sim::Settings;
use crate::sim::settings::{ConstraintSchedule, RotationIntegrator};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// What to sweep.
#[derive(Debug, Clone)]
pub struct AccuracyConfig {
    /// Scenarios to run (empty: all).
    pub scenarios: Vec<Scenario>,
    /// Time steps to sweep (empty: [`DTS`], or [`QUICK_DTS`] with `quick`).
    pub dts: Vec<f64>,
    /// Setting combinations to run (empty: all, or the reduced set with `quick`).
    pub combinations: Vec<String>,
    /// Reduced sweep for smoke tests: two time steps and fewer combinations, where the time
    /// steps or the combinations are not named.
    pub quick: bool,
    /// Folder for the CSV and the plots.
    pub out: PathBuf,
}

/// The setting combinations compared: the coursework default, each of its opt-ins alone, the
/// best of them together (`coursework_tuned`), and the soft-step solver (`accurate`).
pub fn combinations() -> Vec<(&'static str, Settings)> {
    let d = Settings::default();
    let with = |f: &dyn Fn(&mut Settings)| {
        let mut s = d.clone();
        f(&mut s);
        s
    };
    vec![
        ("coursework", d.clone()),
        (
            "gyroscopic",
            with(&|s| s.rotation_integrator = RotationIntegrator::Gyroscopic),
        ),
        (
            "angular_momentum",
            with(&|s| s.rotation_integrator = RotationIntegrator::AngularMomentum),
        ),
        (
            "skip_separating",
            with(&|s| s.skip_separating_contacts = true),
        ),
        (
            "restitution_threshold",
            with(&|s| s.restitution_threshold = 0.5),
        ),
        ("contact_patches", with(&|s| s.contact_patches = true)),
        ("substeps_4", with(&|s| s.substeps = 4)),
        ("iterations_100", with(&|s| s.max_iterations = 100)),
        (
            "sparse_schedule",
            with(&|s| s.constraint_schedule = ConstraintSchedule::Sparse),
        ),
        ("coursework_tuned", Settings::coursework_tuned()),
        ("accurate", Settings::accurate()),
    ]
}

/// The time steps swept by default, and by the reduced (`--quick`) sweep.
pub const DTS: [f64; 5] = [0.04, 0.02, 0.01, 0.005, 0.0025];
pub const QUICK_DTS: [f64; 2] = [0.04, 0.01];

/// The combinations of the reduced (`--quick`) sweep.
const QUICK_COMBINATIONS: [&str; 4] = ["coursework", "coursework_tuned", "accurate", "rapier"];

/// Restitutions of the bounce scenario: one run per value and combination.
const BOUNCE_RESTITUTIONS: [f64; 3] = [1.0, 0.8, 0.5];

#[derive(Debug, Clone, Serialize)]
pub struct Row {
    pub wall_per_sim_second: f64,
    pub metrics: BTreeMap<String, f64>,
    pub finite: bool,
}

/// scenario (bounce split by restitution) -> combination -> dt -> row.
pub type AccuracyResults = BTreeMap<String, BTreeMap<String, BTreeMap<String, Row>>>;

#[derive(Debug, Clone)]
pub struct AccuracyReport {
    /// The machine the run measured: printed with the table, not in the JSON, whose layout is
    /// the results alone.
    pub machine: super::machine::Machine,
    pub results: AccuracyResults,
    pub dts: Vec<f64>,
    pub csv: PathBuf,
    pub plots: Vec<PathBuf>,
}

/// One run: a scenario (named as in the results) with its settings.
struct Job {
    scenario: Scenario,
    name: String,
    combination: &'static str,
    settings: Settings,
    engine: Engine,
    dt: f64,
}

/// The combinations with the engine that steps them: tumble for every setting combination,
/// and Rapier (with the preset's friction and restitution) when it is built in.
fn engines() -> Vec<(&'static str, Settings, Engine)> {
    let mut all: Vec<(&'static str, Settings, Engine)> = combinations()
        .into_iter()
        .map(|(name, settings)| (name, settings, Engine::Tumble))
        .collect();
    if cfg!(feature = "compare-rapier") {
        all.push(("rapier", Settings::accurate(), Engine::Rapier));
    }
    all
}

/// Every combination name this build can run, in the results' order.
pub fn combination_names() -> Vec<&'static str> {
    engines().into_iter().map(|(name, ..)| name).collect()
}

/// Refuses a combination name this build cannot run, listing those it can.
fn check_combinations(names: &[String]) -> anyhow::Result<()> {
    let known = combination_names();
    for name in names {
        if known.contains(&name.as_str()) {
            continue;
        }
        if name == "rapier" {
            anyhow::bail!(
                "--combinations: 'rapier' needs a build with Rapier: cargo run --release --features compare-rapier -- bench accuracy ..."
            );
        }
        anyhow::bail!(
            "--combinations: unknown combination '{name}'; this build runs {}",
            known.join(", ")
        );
    }
    Ok(())
}

fn jobs(config: &AccuracyConfig) -> (Vec<Job>, Vec<f64>) {
    let scenarios = if config.scenarios.is_empty() {
        Scenario::ALL.to_vec()
    } else {
        config.scenarios.clone()
    };
    // What is named is run as named, `quick` or not (`--quick --dts 0.04` ran dt 0.01 too).
    let dts = match (config.dts.is_empty(), config.quick) {
        (false, _) => config.dts.clone(),
        (true, false) => DTS.to_vec(),
        (true, true) => QUICK_DTS.to_vec(),
    };
    // Named twice, a scenario or dt runs once (`bounce_e1,bounce_e0.5` both name the bounce:
    // it ran twice, the second results replacing the first).
    let (scenarios, dts) = (super::first_of_each(scenarios), super::first_of_each(dts));
    let mut combos = engines();
    if !config.combinations.is_empty() {
        combos.retain(|(name, ..)| config.combinations.iter().any(|c| c == name));
    } else if config.quick {
        combos.retain(|(name, ..)| QUICK_COMBINATIONS.contains(name));
    }
    let mut jobs = Vec::new();
    for &scenario in &scenarios {
        let variants: Vec<(String, Option<f64>)> = if scenario == Scenario::Bounce {
            BOUNCE_RESTITUTIONS
                .iter()
                .map(|e| (format!("bounce_e{e}"), Some(*e)))
                .collect()
        } else {
            vec![(scenario.name().to_string(), None)]
        };
        // A scenario's combinations at one dt run one after another (their runs interleaved,
        // see [`measure_together`]): the times compared with each other are taken close in time.
        for (name, restitution) in &variants {
            for &dt in &dts {
                for &(combination, ref base, engine) in &combos {
                    let mut settings = Settings {
                        time_step: dt,
                        ..base.clone()
                    };
                    if let Some(e) = restitution {
                        settings.restitution = *e;
                    }
                    jobs.push(Job {
                        scenario,
                        name: name.clone(),
                        combination,
                        settings,
                        engine,
                        dt,
                    });
                }
            }
        }
    }
    (jobs, dts)
}

/// Stepping time a job is repeated for, at least (seconds), the fewest runs and the most runs
/// it gets.
const MIN_MEASURED_SECONDS: f64 = 0.1;
const MIN_RUNS: usize = 3;
const MAX_RUNS: usize = 15;

/// The jobs' outcomes (one scenario at one dt), each with its fastest run's time: every job is
/// run [`MIN_RUNS`] times, and one whose steps take a few milliseconds in all (the pendulum at
/// dt 0.04: 1.5 ms) again until its steps have taken [`MIN_MEASURED_SECONDS`], at most
/// [`MAX_RUNS`] times, in rounds over the jobs, so every engine's runs meet the machine in the
/// same state. The runs are identical (the engines are deterministic) but their times are not:
/// a single short run moved by 30 % between sweeps, more than the differences between the
/// engines it is meant to show, and pile_rest's single run of each engine (a fifth of a second
/// to three seconds) by 10-20 % (the soft step at dt 0.04: 18.7 ms per simulated second in one
/// sweep, 14.8-16.6 in five runs after it). The fastest is the one least disturbed by the rest
/// of the machine.
fn measure_together(jobs: &[Job], one_thread: &rayon::ThreadPool) -> Vec<scenarios::Outcome> {
    let run = |job: &Job| {
        one_thread.install(|| scenarios::run_with(job.scenario, &job.settings, job.engine))
    };
    let seconds =
        |job: &Job, o: &scenarios::Outcome| o.wall_per_sim_second * job.scenario.duration();
    let mut outcomes: Vec<scenarios::Outcome> = jobs.iter().map(run).collect();
    let mut measured: Vec<f64> = jobs
        .iter()
        .zip(&outcomes)
        .map(|(j, o)| seconds(j, o))
        .collect();
    for runs in 1..MAX_RUNS {
        let short: Vec<usize> = (0..jobs.len())
            .filter(|&k| runs < MIN_RUNS || measured[k] < MIN_MEASURED_SECONDS)
            .collect();
        if short.is_empty() {
            break;
        }
        for k in short {
            let again = run(&jobs[k]);
            measured[k] += seconds(&jobs[k], &again);
            let fastest = outcomes[k]
                .wall_per_sim_second
                .min(again.wall_per_sim_second);
            outcomes[k].wall_per_sim_second = fastest;
        }
    }
    outcomes
}

/// One job's outcome into the results and the CSV.
fn record(
    job: &Job,
    outcome: &scenarios::Outcome,
    results: &mut AccuracyResults,
    csv: &mut String,
) {
    for (metric, value) in &outcome.metrics {
        csv.push_str(&format!(
            "{},{},{},{:.6e},{metric},{value:.6e}\n",
            job.name, job.combination, job.dt, outcome.wall_per_sim_second
        ));
    }
    let row = Row {
        wall_per_sim_second: outcome.wall_per_sim_second,
        metrics: outcome.metrics.iter().cloned().collect(),
        finite: outcome.finite,
    };
    results
        .entry(job.name.clone())
        .or_default()
        .entry(job.combination.to_string())
        .or_default()
        .insert(format!("{}", job.dt), row);
}

/// Shortest and longest time step `--dts` takes (s).
const DT_RANGE: (f64, f64) = (1e-5, 1.0);

/// The reports a run writes into its folder (the JSON and the table beside the CSV).
const ACCURACY_REPORTS: [&str; 3] = ["accuracy.csv", "accuracy.json", "accuracy.txt"];

/// Runs the sweep, writes `accuracy.csv` and one plot per scenario into `config.out`.
pub fn run(config: &AccuracyConfig, progress: &dyn Progress) -> anyhow::Result<AccuracyReport> {
    if let Some(dt) = config.dts.iter().find(|dt| !(dt.is_finite() && **dt > 0.0)) {
        anyhow::bail!("--dts: time steps must be positive numbers of seconds, got {dt}");
    }
    // Short enough to take steps within the shortest scenario (5 s), long enough to finish:
    // --dts 1e9 took no step and reported an error of zero, 1e-300 ran for ever.
    if let Some(dt) = config
        .dts
        .iter()
        .find(|dt| !(DT_RANGE.0..=DT_RANGE.1).contains(*dt))
    {
        let got = match dt.abs() {
            x if x != 0.0 && !(1e-4..1e4).contains(&x) => format!("{dt:e}"),
            _ => dt.to_string(),
        };
        anyhow::bail!(
            "--dts: time steps must lie in [{}, {}] s, got {got}",
            DT_RANGE.0,
            DT_RANGE.1
        );
    }
    check_combinations(&config.combinations)?;
    super::output_folder(&config.out, &ACCURACY_REPORTS)?;
    let (jobs, dts) = jobs(config);
    progress.start(jobs.len() as u64, "bench accuracy");
    let mut results = AccuracyResults::new();
    let mut csv =
        String::from("scenario,combination,dt,wall_seconds_per_simulated_second,metric,value\n");
    // Every engine on one thread: Rapier's default build (the one compared) is single-threaded,
    // and pile_rest, the one scenario large enough to split its step, ran on every core against
    // it until stop 76 (1.4-1.5x Rapier's time on one core, 1.3x on two). `bench scale` measures
    // what more cores give.
    let one_thread = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    // The first job of a process pays one-off costs (the thread pool starting, first page
    // faults): run once unmeasured, free fall with the coursework at dt 0.04 took 0.058 ms per
    // simulated second against 0.037 at dt 0.02.
    if let Some(first) = jobs.first() {
        one_thread.install(|| scenarios::run_with(first.scenario, &first.settings, first.engine));
    }
    let mut done = 0;
    for together in jobs.chunk_by(|a, b| (&a.name, a.dt) == (&b.name, b.dt)) {
        let first = &together[0];
        progress.message(&format!("{} dt={}", first.name, first.dt));
        for (job, outcome) in together.iter().zip(measure_together(together, &one_thread)) {
            record(job, &outcome, &mut results, &mut csv);
        }
        done += together.len();
        progress.set_position(done as u64);
    }
    progress.finish();
    super::output_folder(&config.out, &ACCURACY_REPORTS)?;
    let csv_path = config.out.join("accuracy.csv");
    super::write_named(&csv_path, csv)?;
    let plots = write_plots(&results, &config.out)?;
    Ok(AccuracyReport {
        machine: super::machine::Machine::detect(),
        results,
        dts,
        csv: csv_path,
        plots,
    })
}

/// The plots of an earlier run drawn again into `out` from its JSON report (`json`, the
/// results' layout: scenario -> combination -> dt -> row): how the plots are drawn may change
/// without running the bench again. A metric written as `null` (not finite) is left out.
pub fn replot(json: &str, out: &Path) -> anyhow::Result<Vec<PathBuf>> {
    use super::json_object as object;
    let value: serde_json::Value = serde_json::from_str(json)?;
    let mut results = AccuracyResults::new();
    for (scenario, by_combo) in object(&value) {
        // A scenario names a plot's file: one of the bench's, not a path.
        let known = Scenario::ALL.iter().any(|s| scenario.starts_with(s.name()));
        let plain = scenario
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "._".contains(c));
        anyhow::ensure!(
            known && plain,
            "'{scenario}' is not a scenario of the bench"
        );
        for (combo, by_dt) in object(&by_combo) {
            for (dt, row) in object(&by_dt) {
                let metrics = object(&row["metrics"]).into_iter();
                let row = Row {
                    wall_per_sim_second: row["wall_per_sim_second"]
                        .as_f64()
                        .ok_or_else(|| anyhow::anyhow!("{scenario}/{combo}/{dt}: no run time"))?,
                    metrics: metrics
                        .filter_map(|(k, v)| Some((k, v.as_f64()?)))
                        .collect(),
                    finite: row["finite"].as_bool().unwrap_or(false),
                };
                let combos = results.entry(scenario.clone()).or_default();
                combos.entry(combo.clone()).or_default().insert(dt, row);
            }
        }
    }
    anyhow::ensure!(!results.is_empty(), "no accuracy results in the JSON");
    write_plots(&results, out)
}

/// One log-log plot of error against run time per scenario, with the Pareto front.
fn write_plots(results: &AccuracyResults, out: &Path) -> anyhow::Result<Vec<PathBuf>> {
    let mut plots = Vec::new();
    for (scenario_name, by_combo) in results {
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
        let path = out.join(format!("accuracy-{scenario_name}.svg"));
        log_log_plot(
            &path,
            &format!("{scenario_name}: {metric} against run time"),
            "wall seconds per simulated second (a point per dt, the smaller further right)",
            metric,
            &series,
        )?;
        plots.push(path);
    }
    super::remove_stale_plots(out, "accuracy-", &plots)?;
    Ok(plots)
}

/// The plotted metric of a result row's scenario ("bounce_e0.8" is a bounce).
pub fn primary_metric_of(scenario_name: &str) -> &'static str {
    Scenario::ALL
        .iter()
        .find(|s| scenario_name.starts_with(s.name()))
        .map_or("error", |s| s.primary_metric())
}

/// Points not dominated in (time, error): nothing else is both faster and more accurate.
pub fn pareto_front(points: &[(f64, f64)]) -> Vec<(f64, f64)> {
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A scenario or dt named twice is one job each: the bounce's three result names, and a dt
    /// repeated, give the jobs of the bounce at that dt once.
    #[test]
    fn a_scenario_or_dt_named_twice_runs_once() {
        let config = |scenarios: Vec<Scenario>, dts: Vec<f64>| AccuracyConfig {
            scenarios,
            dts,
            combinations: vec!["coursework".into(), "accurate".into()],
            quick: false,
            out: PathBuf::new(),
        };
        let once = jobs(&config(vec![Scenario::Bounce], vec![0.04])).0;
        let twice = jobs(&config(vec![Scenario::Bounce; 3], vec![0.04, 0.04])).0;
        let names = |jobs: &[Job]| -> Vec<(String, &str, u64)> {
            (jobs.iter())
                .map(|j| (j.name.clone(), j.combination, j.dt.to_bits()))
                .collect()
        };
        assert_eq!(once.len(), 3 * 2);
        assert_eq!(names(&twice), names(&once));
    }
}
