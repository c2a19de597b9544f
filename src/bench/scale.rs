//! `tumble bench scale`: ms/step against scene size for the coursework's loop, tumble's
//! coursework solver and its soft step (the `--accurate` preset) on one core and on all cores,
//! and Rapier with `--features compare-rapier`, with peak heap, a CSV and a log-log plot per
//! scene family.

use super::Progress;
use super::alloc;
use super::plot::{Series, log_log_plot};
use crate::scene::generate;
use crate::sim::settings::{BroadPhase, ConstraintSchedule};
use crate::sim::{Settings, Stage, World};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What to measure.
#[derive(Debug, Clone)]
pub struct ScaleConfig {
    /// Scene families: sparse, pile, chain, scatter.
    pub scenes: Vec<String>,
    /// Body counts of sparse, pile and chain.
    pub sizes: Vec<usize>,
    /// Body counts of scatter (constant density: it grows further).
    pub scatter_sizes: Vec<usize>,
    /// Also run sparse-100000.
    pub huge: bool,
    /// Variants to run (default: all that are built in).
    pub variants: Vec<Variant>,
    /// Measured steps per run (after the warm-up).
    pub steps: usize,
    pub warmup: usize,
    /// Wall-clock cap per run in seconds: slow variants measure fewer steps.
    pub max_seconds: f64,
    /// Folder for the CSV and the plots.
    pub out: PathBuf,
}

impl ScaleConfig {
    /// The default run, or with `quick` the short smoke run (sizes 100 and 1000, scatter-1000,
    /// 20 steps after 3 of warm-up, 5 s a run at most): every scene family and variant.
    pub fn defaults(quick: bool) -> ScaleConfig {
        let (sizes, scatter_sizes) = if quick {
            (vec![100, 1000], vec![1000])
        } else {
            (vec![100, 1000, 10000], vec![1000, 10000, 100000])
        };
        let (steps, warmup, max_seconds) = if quick { (20, 3, 5.0) } else { (500, 20, 30.0) };
        ScaleConfig {
            scenes: SCENE_FAMILIES.iter().map(|f| f.to_string()).collect(),
            sizes,
            scatter_sizes,
            huge: false,
            variants: Variant::ALL.to_vec(),
            steps,
            warmup,
            max_seconds,
            out: PathBuf::from("bench-out"),
        }
    }
}

/// The generated scene families `bench scale` runs.
pub const SCENE_FAMILIES: [&str; 4] = ["sparse", "pile", "chain", "scatter"];

#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Variant {
    /// All pairs, cyclic sweep, every current vertex recomputed every step (the coursework's loop).
    Coursework,
    /// The coursework's solver with tumble's broad phase and sparse schedule.
    SingleThread,
    AllCores,
    /// The soft step ([`accurate_settings`]).
    AccurateSingleThread,
    AccurateAllCores,
    /// Rapier on the same scene, frictionless and never sleeping: the coursework's physics.
    Rapier,
    /// Rapier with the accurate variants' friction and restitution, sleeping on (its default).
    RapierAccurate,
}

impl Variant {
    pub const ALL: [Variant; 7] = [
        Variant::Coursework,
        Variant::SingleThread,
        Variant::AllCores,
        Variant::AccurateSingleThread,
        Variant::AccurateAllCores,
        Variant::Rapier,
        Variant::RapierAccurate,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Variant::Coursework => "coursework",
            Variant::SingleThread => "tumble_1_thread",
            Variant::AllCores => "tumble_all_cores",
            Variant::AccurateSingleThread => "accurate_1_thread",
            Variant::AccurateAllCores => "accurate_all_cores",
            Variant::Rapier => "rapier",
            Variant::RapierAccurate => "rapier_accurate",
        }
    }

    pub fn from_name(name: &str) -> Option<Variant> {
        Variant::ALL.into_iter().find(|v| v.name() == name)
    }

    pub fn is_rapier(self) -> bool {
        matches!(self, Variant::Rapier | Variant::RapierAccurate)
    }

    fn single_thread(self) -> bool {
        matches!(self, Variant::SingleThread | Variant::AccurateSingleThread)
    }

    /// Why this variant is left out of `scene-n`, if it is.
    fn left_out(self, scene: &str, n: usize) -> Option<&'static str> {
        if self.is_rapier() && !cfg!(feature = "compare-rapier") {
            return Some("built without compare-rapier");
        }
        if scene == "sparse"
            && n > 10_000
            && self != Variant::SingleThread
            && self != Variant::AllCores
        {
            // 100,000 bodies in sparse's 400 x 400 square start deep inside each other: 2.2
            // million touching pairs in the first step (24 s and 5.8 GB for the soft step);
            // Rapier, which keeps a contact pair per overlapping box, needed about 12 GB.
            return Some("sparse-100000 starts with 2.2 million overlapping pairs");
        }
        if self == Variant::Coursework && n > 10_000 {
            return Some("the coursework's all-pairs loop is quadratic: left out above 10,000");
        }
        None
    }
}

/// Restitution of the accurate variants: a pile that bounces at e = 1 never rests, and the
/// point of those variants is resting contact (friction is the preset's 0.5).
pub const ACCURATE_RESTITUTION: f64 = 0.2;

/// The `--accurate` preset (the soft step, friction 0.5, sleeping) with restitution 0.2.
pub fn accurate_settings() -> Settings {
    Settings {
        restitution: ACCURATE_RESTITUTION,
        ..Settings::accurate()
    }
}

/// The coursework's last stage, outside `World::step`: every current vertex refreshed.
pub const POSE_UPDATE: &str = "pose_update";

#[derive(Debug, Clone, Serialize)]
pub struct Measurement {
    /// Median over the first `--steps` measured steps (a pile is watched on after them).
    pub median_ms_per_step: f64,
    /// Mean over the same steps: their run time a step. Where a scene's steps are of very
    /// different lengths (free fall, then landing) the median can sit far from it (docs/scale-log.md,
    /// "Stop 71").
    pub mean_ms_per_step: f64,
    /// Median over the last fifth of the measured steps, where sleeping shows.
    pub late_median_ms_per_step: f64,
    /// Mean ms per step of each stage (by [`Stage`] name, plus [`POSE_UPDATE`]).
    pub mean_stage_ms: BTreeMap<String, f64>,
    pub constraint_visits_per_step: f64,
    pub contacts_per_step: f64,
    pub peak_mib: f64,
    pub steps_measured: usize,
    /// Bodies asleep after the last step.
    pub asleep_at_end: usize,
    /// Identical runs measured ([`repeat_short_runs`]): each step's time is its median.
    pub runs: usize,
    /// Wall seconds of each measured step, for ratios over the steps two runs share.
    #[serde(skip)]
    pub step_seconds: Vec<f64>,
    /// How many of the first `step_seconds` the median, the stage means and the ratios cover.
    #[serde(skip)]
    pub typical_steps: usize,
}

impl Measurement {
    /// A run's measurement from each step's wall seconds, the first `typical_steps` of them
    /// its typical window.
    fn from_times(step_seconds: Vec<f64>, typical_steps: usize) -> Measurement {
        let typical_steps = typical_steps.min(step_seconds.len());
        Measurement {
            median_ms_per_step: median_ms(&step_seconds[..typical_steps]),
            mean_ms_per_step: mean_ms(&step_seconds[..typical_steps]),
            late_median_ms_per_step: late_median_ms(&step_seconds),
            mean_stage_ms: BTreeMap::new(),
            constraint_visits_per_step: 0.0,
            contacts_per_step: 0.0,
            peak_mib: 0.0,
            steps_measured: step_seconds.len(),
            asleep_at_end: 0,
            runs: 1,
            step_seconds,
            typical_steps,
        }
    }

    /// Whether the run timed tumble's stages (Rapier's runs time only their whole step).
    pub fn stages_timed(&self) -> bool {
        self.mean_stage_ms.keys().any(|stage| stage != "total")
    }

    /// The steps of the typical window.
    fn typical(&self) -> &[f64] {
        &self.step_seconds[..self.typical_steps.min(self.step_seconds.len())]
    }

    /// Identical runs of one job (the engines are deterministic) as one: each step's median
    /// time over the runs, the stage means averaged, the largest peak. The median, not the
    /// fastest: a job measured once keeps its steps' typical disturbance, so the fastest of
    /// several would flatter the short jobs against the long ones.
    fn combined(runs: Vec<Measurement>) -> Measurement {
        let mut first = runs[0].clone();
        if runs.len() == 1 {
            return first;
        }
        let shared = runs.iter().map(|m| m.step_seconds.len()).min().unwrap_or(0);
        first.step_seconds = (0..shared)
            .map(|k| median(runs.iter().map(|m| m.step_seconds[k]).collect()))
            .collect();
        for (stage, mean) in first.mean_stage_ms.iter_mut() {
            let each = runs.iter().filter_map(|m| m.mean_stage_ms.get(stage));
            *mean = each.sum::<f64>() / runs.len() as f64;
        }
        first.typical_steps = first.typical_steps.min(shared);
        first.median_ms_per_step = median_ms(first.typical());
        first.mean_ms_per_step = mean_ms(first.typical());
        first.late_median_ms_per_step = late_median_ms(&first.step_seconds);
        first.steps_measured = shared;
        first.peak_mib = runs.iter().map(|m| m.peak_mib).fold(0.0, f64::max);
        first.runs = runs.len();
        first
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct ScaleReport {
    /// The machine the run measured (times compare only on one machine).
    pub machine: super::machine::Machine,
    pub cores: usize,
    pub steps: usize,
    pub rapier: &'static str,
    pub accurate_settings: String,
    /// "scene-N" -> variant name -> measurement.
    pub results: BTreeMap<String, BTreeMap<String, Measurement>>,
    /// Ratios of medians per scene and size (`a_over_b` = a's ms / b's ms), over the steps both
    /// runs measured.
    pub speedups: BTreeMap<String, BTreeMap<String, f64>>,
    /// Family -> variant -> "N1->N2" -> the larger size's median ms per step over the smaller's,
    /// over the steps both runs measured ([`growth`]).
    pub growth: BTreeMap<String, BTreeMap<String, BTreeMap<String, f64>>>,
    /// "scene-N variant: why" for each run left out.
    pub left_out: Vec<String>,
    #[serde(skip)]
    pub csv: PathBuf,
    #[serde(skip)]
    pub plots: Vec<PathBuf>,
}

fn settings_for(variant: Variant) -> Settings {
    let mut settings = Settings::default();
    match variant {
        Variant::Coursework => {
            settings.broad_phase = BroadPhase::AllPairs;
            settings.constraint_schedule = ConstraintSchedule::Sweep;
        }
        Variant::SingleThread | Variant::AllCores => {
            settings.constraint_schedule = ConstraintSchedule::Sparse;
        }
        Variant::AccurateSingleThread | Variant::AccurateAllCores | Variant::RapierAccurate => {
            settings = accurate_settings();
        }
        Variant::Rapier => settings.friction = 0.0,
    }
    settings
}

fn generated(scene: &str, n: usize, settings: Settings) -> anyhow::Result<World> {
    generate::by_name(scene, n, settings).ok_or_else(|| {
        anyhow::anyhow!("unknown generated scene '{scene}' (sparse, pile, chain, scatter)")
    })
}

/// How many times the other families' steps and time cap pile-N is watched for: a pile is
/// there to land and come to rest, where sleeping shows in the late median. Its median, stage
/// means and ratios cover the first `--steps` like every family's (the landing); its late
/// median the last fifth of the whole watch. pile-10000 lands within 10 s of its drop and its
/// soft step was all asleep at 15 s in a probe (dt 0.02; when a pile settles is chaotic).
pub const PILE_WINDOW: usize = 3;

/// Measured steps and time cap of a scene family's runs.
fn window(config: &ScaleConfig, scene: &str) -> (usize, f64) {
    let times = if scene == "pile" { PILE_WINDOW } else { 1 };
    (config.steps * times, config.max_seconds * times as f64)
}

/// Wall seconds of each step, after `warmup` steps, until `steps` or the time cap `max_seconds`.
/// `step(measured)` takes one step and returns its wall time.
fn time_steps(
    config: &ScaleConfig,
    (steps, max_seconds): (usize, f64),
    mut step: impl FnMut(bool) -> f64,
) -> Vec<f64> {
    let started = Instant::now();
    for _ in 0..config.warmup {
        step(false);
        if started.elapsed().as_secs_f64() > max_seconds / 4.0 {
            break;
        }
    }
    let mut times = Vec::with_capacity(steps);
    let started = Instant::now();
    for _ in 0..steps {
        times.push(step(true));
        if started.elapsed().as_secs_f64() > max_seconds {
            break;
        }
    }
    times
}

/// The middle value, or the mean of the middle two (two runs: their mean, not the slower).
fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    let half = values.len() / 2;
    match values.len() {
        0 => 0.0,
        n if n % 2 == 0 => 0.5 * (values[half - 1] + values[half]),
        _ => values[half],
    }
}

/// The [`median`] of `times` (seconds) in ms; 0 for none. (Until stop 76 the upper of the
/// middle two of an even count: the 251st of the default 500 steps.)
fn median_ms(times: &[f64]) -> f64 {
    1000.0 * median(times.to_vec())
}

/// The mean of `times` (seconds) in ms; 0 for none.
fn mean_ms(times: &[f64]) -> f64 {
    1000.0 * times.iter().sum::<f64>() / times.len().max(1) as f64
}

/// The median over the last fifth of `times`.
fn late_median_ms(times: &[f64]) -> f64 {
    median_ms(&times[times.len() - times.len().div_ceil(5)..])
}

fn measure(
    scene: &str,
    n: usize,
    variant: Variant,
    config: &ScaleConfig,
) -> anyhow::Result<Measurement> {
    if variant.is_rapier() {
        return measure_rapier(scene, n, variant, config);
    }
    let threads = match variant.single_thread() {
        true => 1,
        false => rayon::current_num_threads().max(1),
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;
    pool.install(|| measure_tumble(scene, n, variant, config))
}

fn measure_tumble(
    scene: &str,
    n: usize,
    variant: Variant,
    config: &ScaleConfig,
) -> anyhow::Result<Measurement> {
    let baseline = alloc::reset_peak();
    let mut world = generated(scene, n, settings_for(variant))?;
    let mut stages: BTreeMap<String, f64> = BTreeMap::new();
    let (mut visits, mut contacts, mut vertices_sink) = (0usize, 0usize, 0.0);
    let mut counted = 0;
    let times = time_steps(config, window(config, scene), |measured| {
        let start = Instant::now();
        let stats = world.step();
        let mut pose = 0.0;
        if variant == Variant::Coursework {
            // The coursework refreshes every current vertex after every step.
            let t = Instant::now();
            for i in 0..world.bodies.len() {
                vertices_sink += world.current_vertices(i)[0].x;
            }
            pose = t.elapsed().as_secs_f64();
        }
        let total = start.elapsed().as_secs_f64();
        if !measured || counted == config.steps {
            return total;
        }
        counted += 1;
        for (stage, secs) in stats.timings.iter() {
            *stages.entry(stage.name().to_string()).or_default() += secs;
        }
        *stages.entry(POSE_UPDATE.into()).or_default() += pose;
        visits += stats.constraint_visits;
        contacts += stats.contacts + stats.ground_contacts;
        total
    });
    std::hint::black_box(vertices_sink);
    let taken = counted.max(1) as f64;
    for v in stages.values_mut() {
        *v = 1000.0 * *v / taken;
    }
    Ok(Measurement {
        mean_stage_ms: stages,
        constraint_visits_per_step: visits as f64 / taken,
        contacts_per_step: contacts as f64 / taken,
        peak_mib: (alloc::peak().saturating_sub(baseline)) as f64 / (1024.0 * 1024.0),
        asleep_at_end: world.bodies.iter().filter(|b| b.asleep).count(),
        ..Measurement::from_times(times, config.steps)
    })
}

#[cfg(feature = "compare-rapier")]
fn measure_rapier(
    scene: &str,
    n: usize,
    variant: Variant,
    config: &ScaleConfig,
) -> anyhow::Result<Measurement> {
    let baseline = alloc::reset_peak();
    let world = generated(scene, n, settings_for(variant))?;
    let sleeping = variant == Variant::RapierAccurate;
    let mut rapier = super::rapier::RapierScene::from_world(&world, sleeping);
    drop(world);
    // The peak from here on, over the same baseline: Rapier's scene and what its steps take,
    // not tumble's world it was made from (counted in until stop 76).
    alloc::reset_peak();
    let times = time_steps(config, window(config, scene), |_| rapier.step());
    let mut measured = Measurement {
        peak_mib: (alloc::peak().saturating_sub(baseline)) as f64 / (1024.0 * 1024.0),
        asleep_at_end: rapier.asleep(),
        ..Measurement::from_times(times, config.steps)
    };
    let typical = measured.typical();
    let total_ms = 1000.0 * typical.iter().sum::<f64>() / typical.len().max(1) as f64;
    measured.mean_stage_ms.insert("total".to_string(), total_ms);
    Ok(measured)
}

#[cfg(not(feature = "compare-rapier"))]
fn measure_rapier(_: &str, _: usize, _: Variant, _: &ScaleConfig) -> anyhow::Result<Measurement> {
    anyhow::bail!("built without Rapier")
}

/// (scene family, N, variant) of every run, and "scene-N variant: why" for those left out.
fn jobs(config: &ScaleConfig) -> (Vec<(String, usize, Variant)>, Vec<String>) {
    let (mut jobs, mut left_out) = (Vec::new(), Vec::new());
    let variants = super::first_of_each(config.variants.clone());
    for scene in &super::first_of_each(config.scenes.clone()) {
        let mut sizes = match scene.as_str() {
            "scatter" => config.scatter_sizes.clone(),
            _ => config.sizes.clone(),
        };
        if config.huge && scene == "sparse" {
            sizes.push(100_000);
        }
        for &n in &super::first_of_each(sizes) {
            for &v in &variants {
                match v.left_out(scene, n) {
                    Some(why) => left_out.push(format!("{scene}-{n} {}: {why}", v.name())),
                    None => jobs.push((scene.clone(), n, v)),
                }
            }
        }
    }
    (jobs, left_out)
}

/// The reports a run writes into its folder (the JSON and the table beside the CSV).
const SCALE_REPORTS: [&str; 3] = ["scale.csv", "scale.json", "scale.txt"];

/// Measures every job, then writes `scale.csv` and one plot per scene family.
pub fn run(config: &ScaleConfig, progress: &dyn Progress) -> anyhow::Result<ScaleReport> {
    super::output_folder(&config.out, &SCALE_REPORTS)?;
    let (jobs, left_out) = jobs(config);
    // (An empty table, an empty plot and a zero exit, which `bench replot` then refused.)
    anyhow::ensure!(
        !jobs.is_empty(),
        "nothing to measure: {}",
        left_out.join("; ")
    );
    progress.start(jobs.len() as u64, "bench scale");
    let mut results: BTreeMap<String, BTreeMap<String, Measurement>> = BTreeMap::new();
    for (k, (scene, n, v)) in jobs.iter().enumerate() {
        progress.message(&format!("{scene}-{n} {}", v.name()));
        let m = measure(scene, *n, *v, config)?;
        results
            .entry(format!("{scene}-{n}"))
            .or_default()
            .insert(v.name().into(), m);
        progress.set_position(k as u64 + 1);
    }
    repeat_short_runs(&jobs, &mut results, config, progress)?;
    progress.finish();
    super::output_folder(&config.out, &SCALE_REPORTS)?;
    let csv = config.out.join("scale.csv");
    super::write_named(&csv, csv_text(&results))?;
    let medians = results.iter().map(|(key, by)| {
        let by_variant = by.iter().map(|(v, m)| (v.clone(), m.median_ms_per_step));
        (key.clone(), by_variant.collect())
    });
    let scenes = super::first_of_each(config.scenes.clone());
    let plots = write_plots(&medians.collect(), &scenes, &config.out)?;
    Ok(ScaleReport {
        machine: super::machine::Machine::detect(),
        cores: rayon::current_num_threads(),
        steps: config.steps,
        rapier: rapier_note(),
        accurate_settings: format!(
            "the --accurate preset (soft step, 4 substeps, friction 0.5, sleeping) with restitution {ACCURATE_RESTITUTION}"
        ),
        speedups: speedups(&results),
        growth: growth(&results),
        results,
        left_out,
        csv,
        plots,
    })
}

/// Stepping time a run is repeated for, at least (seconds), and the most runs it gets.
const MIN_MEASURED_SECONDS: f64 = 1.0;
const MAX_RUNS: usize = 5;

/// Runs again every job whose measured steps took under [`MIN_MEASURED_SECONDS`] in all, at
/// most [`MAX_RUNS`] times, in rounds over the jobs (as `bench accuracy` does), and takes each
/// step's median time ([`Measurement::combined`]). The runs are identical, their times are
/// not: scatter-1000 on one thread took 0.166 ms a step in one run and 0.212-0.222 in five
/// later ones of the same binary, and its growth to 10,000 bodies read 17x or 11x accordingly.
fn repeat_short_runs(
    jobs: &[(String, usize, Variant)],
    results: &mut BTreeMap<String, BTreeMap<String, Measurement>>,
    config: &ScaleConfig,
    progress: &dyn Progress,
) -> anyhow::Result<()> {
    let seconds = |m: &Measurement| m.step_seconds.iter().sum::<f64>();
    let mut runs: BTreeMap<(String, &str), Vec<Measurement>> = BTreeMap::new();
    for (scene, n, v) in jobs {
        let key = format!("{scene}-{n}");
        if let Some(m) = results.get_mut(&key).and_then(|r| r.remove(v.name())) {
            runs.insert((key, v.name()), vec![m]);
        }
    }
    for round in 1..MAX_RUNS {
        let mut repeated = false;
        for (scene, n, v) in jobs {
            let Some(done) = runs.get_mut(&(format!("{scene}-{n}"), v.name())) else {
                continue;
            };
            if done.iter().map(seconds).sum::<f64>() >= MIN_MEASURED_SECONDS {
                continue;
            }
            progress.message(&format!("{scene}-{n} {} (run {})", v.name(), round + 1));
            done.push(measure(scene, *n, *v, config)?);
            repeated = true;
        }
        if !repeated {
            break;
        }
    }
    for ((key, variant), measured) in runs {
        results
            .entry(key)
            .or_default()
            .insert(variant.to_string(), Measurement::combined(measured));
    }
    Ok(())
}

/// The ratios the issue's targets read, per scene and size: `a_over_b` = a's median / b's, both
/// over the first steps both runs measured. A run cut short by the time cap measured an earlier,
/// often cheaper window than one that ran on (a pile gains contacts as it builds), so medians
/// of the whole runs would compare different work.
const RATIOS: [(&str, &str); 7] = [
    ("coursework", "tumble_1_thread"),
    ("coursework", "tumble_all_cores"),
    ("coursework", "rapier"),
    ("rapier", "tumble_1_thread"),
    ("accurate_1_thread", "accurate_all_cores"),
    ("rapier", "accurate_all_cores"),
    ("rapier_accurate", "accurate_all_cores"),
];

fn speedups(
    results: &BTreeMap<String, BTreeMap<String, Measurement>>,
) -> BTreeMap<String, BTreeMap<String, f64>> {
    let mut speedups: BTreeMap<String, BTreeMap<String, f64>> = BTreeMap::new();
    for (key, by_variant) in results {
        let entry = speedups.entry(key.clone()).or_default();
        for (a, b) in RATIOS {
            if let (Some(run_a), Some(run_b)) = (by_variant.get(a), by_variant.get(b)) {
                entry.insert(format!("{a}_over_{b}"), shared_ratio(run_a, run_b));
            }
        }
    }
    speedups
}

/// `a`'s median ms per step over `b`'s, both over the first steps both runs measured.
fn shared_ratio(a: &Measurement, b: &Measurement) -> f64 {
    let (a, b) = (a.typical(), b.typical());
    let shared = a.len().min(b.len());
    median_ms(&a[..shared]) / median_ms(&b[..shared]).max(1e-9)
}

/// Each size's runs of one scene family, by variant.
type SizeRuns<'a> = Vec<(usize, &'a BTreeMap<String, Measurement>)>;

/// How each family's cost grows from one size to the next, per variant: the larger size's
/// median over the smaller's, over the steps both measured. A size cut short by the time cap
/// stops before the later, dearer part of a scene (scatter's top layer lands at 6.4 s), so
/// the whole runs' medians would compare different stretches of simulated time.
fn growth(
    results: &BTreeMap<String, BTreeMap<String, Measurement>>,
) -> BTreeMap<String, BTreeMap<String, BTreeMap<String, f64>>> {
    let mut sizes: BTreeMap<&str, SizeRuns> = BTreeMap::new();
    for (key, by_variant) in results {
        if let Some((family, n)) = key.rsplit_once('-')
            && let Ok(n) = n.parse::<usize>()
        {
            sizes.entry(family).or_default().push((n, by_variant));
        }
    }
    let mut out: BTreeMap<String, BTreeMap<String, BTreeMap<String, f64>>> = BTreeMap::new();
    for (family, mut runs) in sizes {
        runs.sort_by_key(|(n, _)| *n);
        for pair in runs.windows(2) {
            let ((small, at_small), (large, at_large)) = (pair[0], pair[1]);
            for (variant, run_large) in at_large {
                if let Some(run_small) = at_small.get(variant) {
                    out.entry(family.to_string())
                        .or_default()
                        .entry(variant.clone())
                        .or_default()
                        .insert(
                            format!("{small}->{large}"),
                            shared_ratio(run_large, run_small),
                        );
                }
            }
        }
    }
    out
}

/// The CSV columns after `variant`: the median, mean and late median, each stage's mean ms,
/// then counts.
fn csv_text(results: &BTreeMap<String, BTreeMap<String, Measurement>>) -> String {
    let stage_names: Vec<&str> = Stage::ALL
        .iter()
        .map(|s| s.name())
        .chain([POSE_UPDATE])
        .collect();
    let mut csv = format!(
        "scene,n,variant,median_ms_per_step,mean_ms_per_step,late_median_ms_per_step,{},visits_per_step,contacts_per_step,peak_mib,steps_measured,asleep_at_end,runs\n",
        stage_names
            .iter()
            .map(|s| format!("{s}_ms"))
            .collect::<Vec<_>>()
            .join(",")
    );
    for (key, by_variant) in results {
        let (scene, n) = key.rsplit_once('-').unwrap_or((key, ""));
        for (v, m) in by_variant {
            // Empty cells where the run timed no stage and counted nothing (Rapier's).
            let timed = m.stages_timed();
            let stages: Vec<String> = stage_names
                .iter()
                .map(|s| match timed {
                    true => format!("{:.5}", m.mean_stage_ms.get(*s).copied().unwrap_or(0.0)),
                    false => String::new(),
                })
                .collect();
            let counted = |count: f64| match timed {
                true => format!("{count:.1}"),
                false => String::new(),
            };
            csv.push_str(&format!(
                "{scene},{n},{v},{:.5},{:.5},{:.5},{},{},{},{:.2},{},{},{}\n",
                m.median_ms_per_step,
                m.mean_ms_per_step,
                m.late_median_ms_per_step,
                stages.join(","),
                counted(m.constraint_visits_per_step),
                counted(m.contacts_per_step),
                m.peak_mib,
                m.steps_measured,
                m.asleep_at_end,
                m.runs
            ));
        }
    }
    csv
}

/// The plots of an earlier run drawn again into `out` from its JSON report (`json`: `results
/// -> scene -> variant -> {median_ms_per_step, ...}`), for the families it holds: how the plots
/// are drawn may change without running the bench again.
pub fn replot(json: &str, out: &Path) -> anyhow::Result<Vec<PathBuf>> {
    use super::json_object as object;
    let value: serde_json::Value = serde_json::from_str(json)?;
    let mut medians: BTreeMap<String, BTreeMap<String, f64>> = BTreeMap::new();
    for (scene, by_variant) in object(&value["results"]) {
        for (variant, m) in object(&by_variant) {
            // Named as the accuracy replot names what it cannot read: such entries were left
            // out without a word, and with none left "no scale results" named none of them.
            anyhow::ensure!(
                Variant::from_name(&variant).is_some(),
                "{scene}: '{variant}' is not a variant of the bench"
            );
            let median = &m["median_ms_per_step"];
            match median.as_f64() {
                Some(median) => {
                    (medians.entry(scene.clone()).or_default()).insert(variant, median);
                }
                // Written as null: not finite, nothing to draw.
                None if median.is_null() && m.get("median_ms_per_step").is_some() => {}
                None => anyhow::bail!("{scene}/{variant}: no median_ms_per_step"),
            }
        }
    }
    let family_of = |key: &String| key.rsplit_once('-').map(|(family, _)| family.to_string());
    let held: Vec<String> = medians.keys().filter_map(family_of).collect();
    let scenes: Vec<String> = SCENE_FAMILIES
        .iter()
        .map(|f| f.to_string())
        .filter(|f| held.contains(f))
        .collect();
    anyhow::ensure!(!scenes.is_empty(), "no scale results in the JSON");
    write_plots(&medians, &scenes, out)
}

/// One log-log plot of ms per step against N per scene family, a line per variant, from each
/// run's median (`medians`: scene-N -> variant -> ms).
fn write_plots(
    medians: &BTreeMap<String, BTreeMap<String, f64>>,
    scenes: &[String],
    out: &Path,
) -> anyhow::Result<Vec<PathBuf>> {
    let mut plots = Vec::new();
    for scene in scenes {
        let series = Variant::ALL
            .iter()
            .map(|v| {
                let mut points: Vec<(f64, f64)> = medians
                    .iter()
                    .filter_map(|(key, by)| {
                        let (s, n) = key.rsplit_once('-')?;
                        let ms = by.get(v.name()).filter(|_| s == scene)?;
                        Some((n.parse::<f64>().ok()?, *ms))
                    })
                    .collect();
                points.sort_by(|a, b| a.0.total_cmp(&b.0));
                Series {
                    name: v.name().to_string(),
                    points,
                    pareto: false,
                }
            })
            .filter(|series| !series.points.is_empty())
            .collect::<Vec<_>>();
        let path = out.join(format!("scale-{scene}.svg"));
        log_log_plot(
            &path,
            &format!("{scene}-N: ms per step"),
            "bodies N",
            "ms/step (median)",
            &series,
        )?;
        plots.push(path);
    }
    super::remove_stale_plots(out, "scale-", &plots)?;
    Ok(plots)
}

fn rapier_note() -> &'static str {
    if cfg!(feature = "compare-rapier") {
        "Rapier 0.36 (rapier3d-f64, single-threaded build): same hulls, densities, dt, gravity; chain links as rope joints at the upper bound. `rapier`: restitution 1, friction 0, sleeping off (the coursework's physics); `rapier_accurate`: the accurate variants' restitution 0.2 and friction 0.5, sleeping on."
    } else {
        "Rapier comparison not built in: run `cargo run --release --features compare-rapier -- bench scale` to add it."
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An entry the replot cannot read is named, as the accuracy replot names its own: an
    /// unknown variant, or a median that is not a number; a median written as null (not
    /// finite) is left out of the plot.
    #[test]
    fn replot_names_the_entries_it_cannot_read() {
        let out = std::env::temp_dir().join(format!("tumble-scale-replot-{}", std::process::id()));
        std::fs::create_dir_all(&out).unwrap();
        let report = |entry: &str| format!(r#"{{"results": {{"pile-100": {entry}}}}}"#);
        let unknown = replot(
            &report(r#"{"nonsense": {"median_ms_per_step": 1.0}}"#),
            &out,
        );
        assert!(
            unknown
                .unwrap_err()
                .to_string()
                .contains("'nonsense' is not a variant")
        );
        let text = replot(
            &report(r#"{"coursework": {"median_ms_per_step": "fast"}}"#),
            &out,
        );
        let text = text.unwrap_err().to_string();
        assert!(
            text.contains("pile-100/coursework: no median_ms_per_step"),
            "{text}"
        );
        let fine = r#"{"coursework": {"median_ms_per_step": 1.5}, "rapier": {"median_ms_per_step": null}}"#;
        assert_eq!(replot(&report(fine), &out).unwrap().len(), 1);
        std::fs::remove_dir_all(&out).unwrap();
    }

    fn run_of(step_seconds: Vec<f64>) -> Measurement {
        let n = step_seconds.len();
        Measurement::from_times(step_seconds, n)
    }

    /// The median of an even count is the mean of the middle two, of an odd the middle one.
    #[test]
    fn medians_are_the_middle() {
        assert_eq!(median_ms(&[0.004, 0.001, 0.003, 0.002]), 2.5);
        assert_eq!(median_ms(&[0.003, 0.001, 0.002]), 2.0);
        assert_eq!(median_ms(&[]), 0.0);
        assert_eq!(
            late_median_ms(&[9.0, 9.0, 9.0, 9.0, 9.0, 9.0, 9.0, 9.0, 0.001, 0.003]),
            2.0
        );
    }

    /// A run that timed tumble's stages writes them; Rapier's, which times only its whole
    /// step, leaves their cells and its counts empty (they read 0.00000, as if free).
    #[test]
    fn untimed_stages_are_empty_cells_not_zeros() {
        let mut ours = run_of(vec![0.002; 4]);
        ours.mean_stage_ms.insert("broad_phase".into(), 0.5);
        ours.mean_stage_ms.insert("total".into(), 2.0);
        let mut theirs = run_of(vec![0.003; 4]);
        theirs.mean_stage_ms.insert("total".into(), 3.0);
        assert!(ours.stages_timed() && !theirs.stages_timed());
        let by_variant =
            BTreeMap::from([("tumble_1_thread".into(), ours), ("rapier".into(), theirs)]);
        let text = csv_text(&BTreeMap::from([("pile-100".to_string(), by_variant)]));
        let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
        let row = |variant: &str| -> Vec<String> {
            let line = text.lines().find(|l| l.contains(variant)).unwrap();
            line.split(',').map(str::to_string).collect()
        };
        let (ours, theirs) = (row("tumble_1_thread"), row("rapier"));
        assert_eq!(ours.len(), header.len());
        assert_eq!(theirs.len(), header.len());
        let column = |name: &str| header.iter().position(|h| *h == name).unwrap();
        assert_eq!(ours[column("broad_phase_ms")], "0.50000");
        assert_eq!(theirs[column("broad_phase_ms")], "");
        assert_eq!(theirs[column("visits_per_step")], "");
        assert_eq!(theirs[column("median_ms_per_step")], "3.00000");
    }

    /// Steps of two lengths (free fall, then landing): the median is one of them, the mean the
    /// run time a step over the typical window, as computed by hand. The CSV carries both.
    #[test]
    fn the_mean_is_the_run_time_a_step_where_the_median_picks_a_side() {
        let steps = [vec![0.001; 3], vec![0.009; 2], vec![0.5; 4]].concat();
        let m = Measurement::from_times(steps, 5);
        assert_eq!(m.median_ms_per_step, 1.0);
        assert!((m.mean_ms_per_step - (3.0 * 1.0 + 2.0 * 9.0) / 5.0).abs() < 1e-12);
        let text = csv_text(&BTreeMap::from([(
            "scatter-10".to_string(),
            BTreeMap::from([("tumble_1_thread".to_string(), m)]),
        )]));
        let (header, row) = (text.lines().next().unwrap(), text.lines().nth(1).unwrap());
        let at = header
            .split(',')
            .position(|h| h == "mean_ms_per_step")
            .unwrap();
        assert_eq!(row.split(',').nth(at), Some("4.20000"));
    }

    /// A pile watched on past its typical window: its median and the ratios cover the first
    /// steps only (the landing), its late median the last fifth of all (at rest).
    #[test]
    fn a_watched_run_has_its_median_from_the_typical_window_and_late_from_the_end() {
        let landing = vec![0.010; 5];
        let resting = vec![1e-6; 10];
        let pile = Measurement::from_times([landing.clone(), resting].concat(), 5);
        assert_eq!(pile.median_ms_per_step, 10.0);
        assert!((pile.mean_ms_per_step - 10.0).abs() < 1e-12);
        assert_eq!(pile.late_median_ms_per_step, 0.001);
        assert_eq!(pile.steps_measured, 15);
        let other = Measurement::from_times(vec![0.005; 15], 5);
        assert_eq!(shared_ratio(&pile, &other), 2.0);
    }

    /// Three identical runs disturbed at different steps: each step keeps its median time, the
    /// medians follow, the stage means are averaged, the peak is the largest.
    #[test]
    fn repeated_runs_keep_each_steps_median_time() {
        let run = |steps: Vec<f64>, solve: f64, peak: f64| {
            let mut m = run_of(steps);
            m.mean_stage_ms.insert("solve".into(), solve);
            m.peak_mib = peak;
            m
        };
        let combined = Measurement::combined(vec![
            run(vec![0.001, 0.003, 0.002, 0.004, 0.002], 2.4, 3.0),
            run(vec![0.002, 0.001, 0.002, 0.009, 0.001], 1.8, 2.0),
            run(vec![0.003, 0.002, 0.001, 0.005, 0.003], 2.1, 2.5),
        ]);
        assert_eq!(
            combined.step_seconds,
            vec![0.002, 0.002, 0.002, 0.005, 0.002]
        );
        assert!((combined.median_ms_per_step - 2.0).abs() < 1e-12);
        assert!((combined.mean_ms_per_step - 2.6).abs() < 1e-12);
        assert!((combined.late_median_ms_per_step - 2.0).abs() < 1e-12);
        assert!((combined.mean_stage_ms["solve"] - 2.1).abs() < 1e-12);
        assert_eq!(
            (combined.peak_mib, combined.runs, combined.steps_measured),
            (3.0, 3, 5)
        );
        let two = Measurement::combined(vec![
            run(vec![0.001, 0.004], 1.0, 1.0),
            run(vec![0.003, 0.002], 1.0, 1.0),
        ]);
        assert_eq!(two.step_seconds, vec![0.002, 0.003], "two runs: the mean");
    }

    /// One thread cut by the time cap after 3 cheap steps, all cores on into 4 dear ones: the
    /// ratio compares the 3 steps both measured (2x), not the two medians (0.5 / 2 = 0.25x).
    #[test]
    fn ratios_compare_the_steps_both_runs_measured() {
        let mut by_variant = BTreeMap::new();
        by_variant.insert("accurate_1_thread".to_string(), run_of(vec![0.5; 3]));
        let all_cores = vec![0.25, 0.25, 0.25, 2.0, 2.0, 2.0, 2.0];
        by_variant.insert("accurate_all_cores".to_string(), run_of(all_cores));
        let results = BTreeMap::from([("pile-10000".to_string(), by_variant)]);
        let ratios = speedups(&results);
        let ratio = ratios["pile-10000"]["accurate_1_thread_over_accurate_all_cores"];
        assert!((ratio - 2.0).abs() < 1e-12, "{ratio}");
    }

    /// scatter-100000 cut by the time cap after 3 steps, scatter-10000 on into dear steps: its
    /// growth compares the 3 steps both measured (10x), not the whole medians (30 / 2 = 15x);
    /// sizes in numeric order (10000 after 1000, not before 200), one entry per variant run at
    /// both sizes.
    #[test]
    fn growth_compares_consecutive_sizes_over_shared_steps() {
        let mut results = BTreeMap::new();
        let mut at = |n: usize, variant: &str, steps: Vec<f64>| {
            results
                .entry(format!("scatter-{n}"))
                .or_insert_with(BTreeMap::new)
                .insert(variant.to_string(), run_of(steps));
        };
        at(200, "tumble_1_thread", vec![0.1; 5]);
        at(1000, "tumble_1_thread", vec![0.2; 5]);
        at(
            10000,
            "tumble_1_thread",
            vec![1.0, 1.0, 1.0, 9.0, 9.0, 9.0, 9.0],
        );
        at(100000, "tumble_1_thread", vec![10.0; 3]);
        at(100000, "accurate_all_cores", vec![10.0; 3]);
        let growth = growth(&results);
        let g = &growth["scatter"]["tumble_1_thread"];
        assert_eq!(g.len(), 3);
        assert!((g["200->1000"] - 2.0).abs() < 1e-12);
        assert!((g["1000->10000"] - 5.0).abs() < 1e-12);
        assert!((g["10000->100000"] - 10.0).abs() < 1e-12);
        assert!(!growth["scatter"].contains_key("accurate_all_cores"));
    }
}
