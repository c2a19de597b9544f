//! `tumble bench scale`: ms/step against scene size for the coursework's loop, tumble on one
//! core, tumble on all cores (and Rapier with `--features compare-rapier`), with peak heap,
//! a CSV and a log-log plot per scene family.

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
    /// Scene families: sparse, pile, chain.
    pub scenes: Vec<String>,
    pub sizes: Vec<usize>,
    /// Also run sparse-100000.
    pub huge: bool,
    /// Measured steps per run (after the warm-up).
    pub steps: usize,
    pub warmup: usize,
    /// Wall-clock cap per run in seconds: slow variants measure fewer steps.
    pub max_seconds: f64,
    /// Short smoke run (sizes 100 and 1000, 20 steps).
    pub quick: bool,
    /// Folder for the CSV and the plots.
    pub out: PathBuf,
}

impl ScaleConfig {
    /// The configuration actually run: `quick` shrinks sizes, steps and time caps.
    fn effective(&self) -> ScaleConfig {
        let mut c = self.clone();
        if c.quick {
            c.sizes = vec![100, 1000];
            c.steps = c.steps.min(20);
            c.warmup = c.warmup.min(3);
            c.max_seconds = c.max_seconds.min(5.0);
        }
        c
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Variant {
    /// All pairs, cyclic sweep, every current vertex recomputed every step (the coursework's loop).
    Coursework,
    SingleThread,
    AllCores,
    /// Rapier on the same scene (with `--features compare-rapier`).
    Rapier,
}

impl Variant {
    pub const ALL: [Variant; 4] = [
        Variant::Coursework,
        Variant::SingleThread,
        Variant::AllCores,
        Variant::Rapier,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Variant::Coursework => "coursework",
            Variant::SingleThread => "tumble_1_thread",
            Variant::AllCores => "tumble_all_cores",
            Variant::Rapier => "rapier",
        }
    }
}

/// The coursework's last stage, outside `World::step`: every current vertex refreshed.
pub const POSE_UPDATE: &str = "pose_update";

#[derive(Debug, Clone, Serialize)]
pub struct Measurement {
    pub median_ms_per_step: f64,
    /// Mean ms per step of each stage (by [`Stage`] name, plus [`POSE_UPDATE`]).
    pub mean_stage_ms: BTreeMap<String, f64>,
    pub constraint_visits_per_step: f64,
    pub contacts_per_step: f64,
    pub peak_mib: f64,
    pub steps_measured: usize,
}

#[derive(Debug, Clone, Serialize)]
pub struct ScaleReport {
    pub cores: usize,
    pub steps: usize,
    pub rapier: &'static str,
    /// "scene-N" -> variant name -> measurement.
    pub results: BTreeMap<String, BTreeMap<String, Measurement>>,
    /// coursework / tumble_1_thread and coursework / tumble_all_cores, per scene and size.
    pub speedups: BTreeMap<String, BTreeMap<String, f64>>,
    #[serde(skip)]
    pub csv: PathBuf,
    #[serde(skip)]
    pub plots: Vec<PathBuf>,
}

fn settings_for(variant: Variant) -> Settings {
    let mut settings = Settings::default();
    if variant == Variant::Coursework {
        settings.broad_phase = BroadPhase::AllPairs;
        settings.constraint_schedule = ConstraintSchedule::Sweep;
    } else {
        settings.constraint_schedule = ConstraintSchedule::Sparse;
    }
    settings
}

fn generated(scene: &str, n: usize, settings: Settings) -> anyhow::Result<World> {
    generate::by_name(scene, n, settings)
        .ok_or_else(|| anyhow::anyhow!("unknown generated scene '{scene}' (sparse, pile, chain)"))
}

/// Wall seconds of each step, after `warmup` steps, until `steps` or the time cap. `step(measured)`
/// takes one step and returns its wall time.
fn time_steps(config: &ScaleConfig, mut step: impl FnMut(bool) -> f64) -> Vec<f64> {
    let started = Instant::now();
    for _ in 0..config.warmup {
        step(false);
        if started.elapsed().as_secs_f64() > config.max_seconds / 4.0 {
            break;
        }
    }
    let mut times = Vec::with_capacity(config.steps);
    let started = Instant::now();
    for _ in 0..config.steps {
        times.push(step(true));
        if started.elapsed().as_secs_f64() > config.max_seconds {
            break;
        }
    }
    times
}

fn median_ms(times: &[f64]) -> f64 {
    let mut sorted = times.to_vec();
    sorted.sort_by(f64::total_cmp);
    1000.0 * sorted.get(sorted.len() / 2).copied().unwrap_or(0.0)
}

fn measure(
    scene: &str,
    n: usize,
    variant: Variant,
    config: &ScaleConfig,
) -> anyhow::Result<Measurement> {
    if variant == Variant::Rapier {
        return measure_rapier(scene, n, config);
    }
    let threads = match variant {
        Variant::SingleThread => 1,
        _ => rayon::current_num_threads().max(1),
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
    let times = time_steps(config, |measured| {
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
        if !measured {
            return total;
        }
        for (stage, secs) in stats.timings.iter() {
            *stages.entry(stage.name().to_string()).or_default() += secs;
        }
        *stages.entry(POSE_UPDATE.into()).or_default() += pose;
        visits += stats.constraint_visits;
        contacts += stats.contacts + stats.ground_contacts;
        total
    });
    std::hint::black_box(vertices_sink);
    let taken = times.len().max(1) as f64;
    for v in stages.values_mut() {
        *v = 1000.0 * *v / taken;
    }
    Ok(Measurement {
        median_ms_per_step: median_ms(&times),
        mean_stage_ms: stages,
        constraint_visits_per_step: visits as f64 / taken,
        contacts_per_step: contacts as f64 / taken,
        peak_mib: (alloc::peak().saturating_sub(baseline)) as f64 / (1024.0 * 1024.0),
        steps_measured: times.len(),
    })
}

#[cfg(feature = "compare-rapier")]
fn measure_rapier(scene: &str, n: usize, config: &ScaleConfig) -> anyhow::Result<Measurement> {
    let baseline = alloc::reset_peak();
    let settings = Settings {
        friction: 0.0,
        ..settings_for(Variant::Rapier)
    };
    let world = generated(scene, n, settings)?;
    let mut rapier = super::rapier::RapierScene::from_world(&world, false);
    drop(world);
    let times = time_steps(config, |_| rapier.step());
    let total: f64 = times.iter().sum();
    let mut stages = BTreeMap::new();
    stages.insert(
        "total".to_string(),
        1000.0 * total / times.len().max(1) as f64,
    );
    Ok(Measurement {
        median_ms_per_step: median_ms(&times),
        mean_stage_ms: stages,
        constraint_visits_per_step: 0.0,
        contacts_per_step: 0.0,
        peak_mib: (alloc::peak().saturating_sub(baseline)) as f64 / (1024.0 * 1024.0),
        steps_measured: times.len(),
    })
}

#[cfg(not(feature = "compare-rapier"))]
fn measure_rapier(_: &str, _: usize, _: &ScaleConfig) -> anyhow::Result<Measurement> {
    anyhow::bail!("built without Rapier")
}

/// (scene family, N, variant) of every run.
fn jobs(config: &ScaleConfig) -> Vec<(String, usize, Variant)> {
    let mut jobs = Vec::new();
    for scene in &config.scenes {
        let mut sizes = config.sizes.clone();
        if config.huge && scene == "sparse" {
            sizes.push(100_000);
        }
        for &n in &sizes {
            for v in Variant::ALL {
                // Rapier needs about 12 GB at N = 100,000 (measured): left out there.
                if v != Variant::Rapier || (cfg!(feature = "compare-rapier") && n <= 10_000) {
                    jobs.push((scene.clone(), n, v));
                }
            }
        }
    }
    jobs
}

/// Measures every job, then writes `scale.csv` and one plot per scene family.
pub fn run(config: &ScaleConfig, progress: &dyn Progress) -> anyhow::Result<ScaleReport> {
    let config = &config.effective();
    let jobs = jobs(config);
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
    progress.finish();
    std::fs::create_dir_all(&config.out)?;
    let csv = config.out.join("scale.csv");
    std::fs::write(&csv, csv_text(&results))?;
    let plots = write_plots(&results, &config.scenes, &config.out)?;
    Ok(ScaleReport {
        cores: rayon::current_num_threads(),
        steps: config.steps,
        rapier: rapier_note(),
        speedups: speedups(&results),
        results,
        csv,
        plots,
    })
}

fn speedups(
    results: &BTreeMap<String, BTreeMap<String, Measurement>>,
) -> BTreeMap<String, BTreeMap<String, f64>> {
    let mut speedups: BTreeMap<String, BTreeMap<String, f64>> = BTreeMap::new();
    for (key, by_variant) in results {
        let entry = speedups.entry(key.clone()).or_default();
        let ratio = |a: &str, b: &str| {
            let (a, b) = (by_variant.get(a)?, by_variant.get(b)?);
            Some(a.median_ms_per_step / b.median_ms_per_step.max(1e-9))
        };
        for v in ["tumble_1_thread", "tumble_all_cores", "rapier"] {
            if let Some(r) = ratio("coursework", v) {
                entry.insert(format!("coursework_over_{v}"), r);
            }
        }
        if let Some(r) = ratio("rapier", "tumble_1_thread") {
            entry.insert("rapier_over_tumble_1_thread".into(), r);
        }
    }
    speedups
}

/// The CSV columns after `variant`: the median, each stage's mean ms, then counts.
fn csv_text(results: &BTreeMap<String, BTreeMap<String, Measurement>>) -> String {
    let stage_names: Vec<&str> = Stage::ALL
        .iter()
        .map(|s| s.name())
        .chain([POSE_UPDATE])
        .collect();
    let mut csv = format!(
        "scene,n,variant,median_ms_per_step,{},visits_per_step,contacts_per_step,peak_mib,steps_measured\n",
        stage_names
            .iter()
            .map(|s| format!("{s}_ms"))
            .collect::<Vec<_>>()
            .join(",")
    );
    for (key, by_variant) in results {
        let (scene, n) = key.rsplit_once('-').unwrap_or((key, ""));
        for (v, m) in by_variant {
            let stages: Vec<String> = stage_names
                .iter()
                .map(|s| format!("{:.5}", m.mean_stage_ms.get(*s).copied().unwrap_or(0.0)))
                .collect();
            csv.push_str(&format!(
                "{scene},{n},{v},{:.5},{},{:.1},{:.1},{:.2},{}\n",
                m.median_ms_per_step,
                stages.join(","),
                m.constraint_visits_per_step,
                m.contacts_per_step,
                m.peak_mib,
                m.steps_measured
            ));
        }
    }
    csv
}

fn write_plots(
    results: &BTreeMap<String, BTreeMap<String, Measurement>>,
    scenes: &[String],
    out: &Path,
) -> anyhow::Result<Vec<PathBuf>> {
    let mut plots = Vec::new();
    for scene in scenes {
        let series = Variant::ALL
            .iter()
            .map(|v| {
                let mut points: Vec<(f64, f64)> = results
                    .iter()
                    .filter_map(|(key, by)| {
                        let (s, n) = key.rsplit_once('-')?;
                        let m = by.get(v.name()).filter(|_| s == scene)?;
                        Some((n.parse::<f64>().ok()?, m.median_ms_per_step))
                    })
                    .collect();
                points.sort_by(|a, b| a.0.total_cmp(&b.0));
                Series {
                    name: v.name().to_string(),
                    points,
                    pareto: false,
                }
            })
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
    Ok(plots)
}

fn rapier_note() -> &'static str {
    if cfg!(feature = "compare-rapier") {
        "Rapier 0.36 (rapier3d-f64, single-threaded build): same hulls, densities, dt, gravity and restitution; friction 0; sleeping off; chain links as rope joints at the upper bound."
    } else {
        "Rapier comparison not built in: run `cargo run --release --features compare-rapier -- bench scale` to add it."
    }
}
