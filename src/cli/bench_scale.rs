//! `tumble bench scale`: ms/step against scene size for the coursework's loop, tumble on one
//! core, tumble on all cores (and Rapier with `--features compare-rapier`).

use super::alloc;
use super::plot::{Series, log_log_plot};
use super::progress_bar;
use clap::Args;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;
use tumble::Settings;
use tumble::settings::{BroadPhase, ConstraintSchedule};

#[derive(Debug, Args)]
pub struct ScaleArgs {
    /// Scenes to run (sparse, pile, chain).
    #[arg(long, value_delimiter = ',', default_values_t = ["sparse".to_string(), "pile".to_string(), "chain".to_string()])]
    pub scenes: Vec<String>,
    /// Body counts.
    #[arg(long, value_delimiter = ',', default_values_t = [100usize, 1000, 10000])]
    pub sizes: Vec<usize>,
    /// Also run sparse-100000.
    #[arg(long)]
    pub huge: bool,
    /// Measured steps per run (after the warm-up).
    #[arg(long, default_value_t = 500)]
    pub steps: usize,
    /// Warm-up steps per run.
    #[arg(long, default_value_t = 20)]
    pub warmup: usize,
    /// Wall-clock cap per run in seconds: slow variants measure fewer steps.
    #[arg(long, default_value_t = 30.0)]
    pub max_seconds: f64,
    /// Short smoke run (sizes 100 and 1000, 20 steps).
    #[arg(long)]
    pub quick: bool,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Folder for the CSV and the plots.
    #[arg(long, default_value = "bench-out")]
    pub out: PathBuf,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
enum Variant {
    /// All pairs, cyclic sweep, every current vertex recomputed every step (the coursework's loop).
    Coursework,
    SingleThread,
    AllCores,
    /// Rapier on the same scene (with `--features compare-rapier`).
    Rapier,
}

impl Variant {
    fn name(self) -> &'static str {
        match self {
            Variant::Coursework => "coursework",
            Variant::SingleThread => "tumble_1_thread",
            Variant::AllCores => "tumble_all_cores",
            Variant::Rapier => "rapier",
        }
    }
}

#[derive(Debug, Clone, Serialize)]
struct Measurement {
    median_ms_per_step: f64,
    mean_stage_ms: BTreeMap<String, f64>,
    constraint_visits_per_step: f64,
    contacts_per_step: f64,
    peak_mib: f64,
    steps_measured: usize,
}

fn measure(
    scene: &str,
    n: usize,
    variant: Variant,
    args: &ScaleArgs,
) -> anyhow::Result<Measurement> {
    let mut settings = Settings::default();
    if variant == Variant::Coursework {
        settings.broad_phase = BroadPhase::AllPairs;
        settings.constraint_schedule = ConstraintSchedule::Sweep;
    } else {
        settings.constraint_schedule = ConstraintSchedule::Sparse;
    }
    let threads = match variant {
        Variant::SingleThread => 1,
        _ => rayon::current_num_threads().max(1),
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;
    if variant == Variant::Rapier {
        return measure_rapier(scene, n, settings, args);
    }
    pool.install(|| {
        let baseline = alloc::reset_peak();
        let mut world = tumble::generate::by_name(scene, n, settings).ok_or_else(|| {
            anyhow::anyhow!("unknown generated scene '{scene}' (sparse, pile, chain)")
        })?;
        let mut vertices_sink = 0.0;
        let mut step = |world: &mut tumble::World| {
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
            (start.elapsed().as_secs_f64(), stats, pose)
        };
        let started = Instant::now();
        for _ in 0..args.warmup {
            step(&mut world);
            if started.elapsed().as_secs_f64() > args.max_seconds / 4.0 {
                break;
            }
        }
        let mut times = Vec::with_capacity(args.steps);
        let mut stages: BTreeMap<String, f64> = BTreeMap::new();
        let (mut visits, mut contacts) = (0usize, 0usize);
        let started = Instant::now();
        for _ in 0..args.steps {
            let (t, stats, pose) = step(&mut world);
            times.push(t);
            for (name, secs) in stats.timings.named() {
                *stages.entry(name.to_string()).or_default() += secs;
            }
            *stages.entry("pose_update".into()).or_default() += pose;
            visits += stats.constraint_visits;
            contacts += stats.contacts + stats.ground_contacts;
            if started.elapsed().as_secs_f64() > args.max_seconds {
                break;
            }
        }
        std::hint::black_box(vertices_sink);
        let measured = times.len().max(1);
        times.sort_by(f64::total_cmp);
        let median = times.get(times.len() / 2).copied().unwrap_or(0.0);
        for v in stages.values_mut() {
            *v = 1000.0 * *v / measured as f64;
        }
        Ok(Measurement {
            median_ms_per_step: 1000.0 * median,
            mean_stage_ms: stages,
            constraint_visits_per_step: visits as f64 / measured as f64,
            contacts_per_step: contacts as f64 / measured as f64,
            peak_mib: (alloc::peak().saturating_sub(baseline)) as f64 / (1024.0 * 1024.0),
            steps_measured: times.len(),
        })
    })
}

#[cfg(feature = "compare-rapier")]
fn measure_rapier(
    scene: &str,
    n: usize,
    settings: Settings,
    args: &ScaleArgs,
) -> anyhow::Result<Measurement> {
    let baseline = alloc::reset_peak();
    let world = tumble::generate::by_name(scene, n, settings)
        .ok_or_else(|| anyhow::anyhow!("unknown generated scene '{scene}'"))?;
    let mut rapier = super::rapier::RapierScene::from_world(&world);
    drop(world);
    let started = Instant::now();
    for _ in 0..args.warmup {
        rapier.step();
        if started.elapsed().as_secs_f64() > args.max_seconds / 4.0 {
            break;
        }
    }
    let mut times = Vec::with_capacity(args.steps);
    let started = Instant::now();
    for _ in 0..args.steps {
        times.push(rapier.step());
        if started.elapsed().as_secs_f64() > args.max_seconds {
            break;
        }
    }
    let total: f64 = times.iter().sum();
    let measured = times.len().max(1);
    times.sort_by(f64::total_cmp);
    let mut stages = BTreeMap::new();
    stages.insert("total".to_string(), 1000.0 * total / measured as f64);
    Ok(Measurement {
        median_ms_per_step: 1000.0 * times[times.len() / 2],
        mean_stage_ms: stages,
        constraint_visits_per_step: 0.0,
        contacts_per_step: 0.0,
        peak_mib: (alloc::peak().saturating_sub(baseline)) as f64 / (1024.0 * 1024.0),
        steps_measured: times.len(),
    })
}

#[cfg(not(feature = "compare-rapier"))]
fn measure_rapier(_: &str, _: usize, _: Settings, _: &ScaleArgs) -> anyhow::Result<Measurement> {
    anyhow::bail!("built without Rapier")
}

#[derive(Serialize)]
struct Report {
    cores: usize,
    steps: usize,
    rapier: &'static str,
    results: BTreeMap<String, BTreeMap<String, Measurement>>,
    /// coursework / tumble_1_thread and coursework / tumble_all_cores, per scene and size.
    speedups: BTreeMap<String, BTreeMap<String, f64>>,
}

pub fn run(args: &ScaleArgs) -> anyhow::Result<()> {
    let mut args_eff = ScaleArgs { ..clone_args(args) };
    if args.quick {
        args_eff.sizes = vec![100, 1000];
        args_eff.steps = args.steps.min(20);
        args_eff.warmup = args.warmup.min(3);
        args_eff.max_seconds = args.max_seconds.min(5.0);
    }
    let args = &args_eff;
    let mut jobs = Vec::new();
    for scene in &args.scenes {
        let mut sizes = args.sizes.clone();
        if args.huge && scene == "sparse" {
            sizes.push(100_000);
        }
        for &n in &sizes {
            for v in [
                Variant::Coursework,
                Variant::SingleThread,
                Variant::AllCores,
                Variant::Rapier,
            ] {
                // Rapier needs about 12 GB at N = 100,000 (measured): left out there.
                if v != Variant::Rapier || (cfg!(feature = "compare-rapier") && n <= 10_000) {
                    jobs.push((scene.clone(), n, v));
                }
            }
        }
    }
    let bar = progress_bar(jobs.len() as u64, "bench scale");
    let mut results: BTreeMap<String, BTreeMap<String, Measurement>> = BTreeMap::new();
    for (scene, n, v) in &jobs {
        bar.set_message(format!("{scene}-{n} {}", v.name()));
        let m = measure(scene, *n, *v, args)?;
        results
            .entry(format!("{scene}-{n}"))
            .or_default()
            .insert(v.name().into(), m);
        bar.inc(1);
    }
    bar.finish_and_clear();

    let mut speedups: BTreeMap<String, BTreeMap<String, f64>> = BTreeMap::new();
    for (key, by_variant) in &results {
        let base = by_variant["coursework"].median_ms_per_step;
        let entry = speedups.entry(key.clone()).or_default();
        for v in ["tumble_1_thread", "tumble_all_cores", "rapier"] {
            if let Some(m) = by_variant.get(v) {
                entry.insert(
                    format!("coursework_over_{v}"),
                    base / m.median_ms_per_step.max(1e-9),
                );
            }
        }
        if let (Some(r), Some(t)) = (by_variant.get("rapier"), by_variant.get("tumble_1_thread")) {
            entry.insert(
                "rapier_over_tumble_1_thread".into(),
                r.median_ms_per_step / t.median_ms_per_step.max(1e-9),
            );
        }
    }

    std::fs::create_dir_all(&args.out)?;
    let mut csv = String::from(
        "scene,n,variant,median_ms_per_step,integrate_ms,broad_phase_ms,narrow_phase_ms,contact_resolution_ms,ground_ms,constraints_ms,pose_update_ms,visits_per_step,contacts_per_step,peak_mib,steps_measured\n",
    );
    for (key, by_variant) in &results {
        let (scene, n) = key.rsplit_once('-').unwrap_or((key, ""));
        for (v, m) in by_variant {
            let s = |k: &str| m.mean_stage_ms.get(k).copied().unwrap_or(0.0);
            csv.push_str(&format!(
                "{scene},{n},{v},{:.5},{:.5},{:.5},{:.5},{:.5},{:.5},{:.5},{:.5},{:.1},{:.1},{:.2},{}\n",
                m.median_ms_per_step,
                s("integrate"),
                s("broad_phase"),
                s("narrow_phase"),
                s("contact_resolution"),
                s("ground"),
                s("constraints"),
                s("pose_update"),
                m.constraint_visits_per_step,
                m.contacts_per_step,
                m.peak_mib,
                m.steps_measured
            ));
        }
    }
    let csv_path = args.out.join("scale.csv");
    std::fs::write(&csv_path, csv)?;
    let mut plots = Vec::new();
    for scene in &args.scenes {
        let mut series = Vec::new();
        for v in [
            "coursework",
            "tumble_1_thread",
            "tumble_all_cores",
            "rapier",
        ] {
            let mut points: Vec<(f64, f64)> = results
                .iter()
                .filter_map(|(key, by)| {
                    let (s, n) = key.rsplit_once('-')?;
                    (s == scene).then(|| {
                        by.get(v)
                            .map(|m| (n.parse::<f64>().ok().unwrap_or(0.0), m.median_ms_per_step))
                    })?
                })
                .collect();
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
            series.push(Series {
                name: v.to_string(),
                points,
                pareto: false,
            });
        }
        let path = args.out.join(format!("scale-{scene}.svg"));
        log_log_plot(
            &path,
            &format!("{scene}-N: ms per step"),
            "bodies N",
            "ms/step (median)",
            &series,
        )?;
        plots.push(path);
    }

    let report = Report {
        cores: rayon::current_num_threads(),
        steps: args.steps,
        rapier: rapier_note(),
        results,
        speedups,
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!(
        "{:<14} {:<18} {:>10} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9}",
        "scene",
        "variant",
        "ms/step",
        "broad",
        "narrow",
        "resolve",
        "constr",
        "integr",
        "visits",
        "peakMiB"
    );
    for (key, by_variant) in &report.results {
        for (v, m) in by_variant {
            let s = |k: &str| m.mean_stage_ms.get(k).copied().unwrap_or(0.0);
            println!(
                "{key:<14} {v:<18} {:>10.4} {:>9.4} {:>9.4} {:>9.4} {:>9.4} {:>9.4} {:>9.0} {:>9.2}",
                m.median_ms_per_step,
                s("broad_phase"),
                s("narrow_phase"),
                s("contact_resolution") + s("ground"),
                s("constraints"),
                s("integrate"),
                m.constraint_visits_per_step,
                m.peak_mib
            );
        }
        if let Some(sp) = report.speedups.get(key) {
            let parts: Vec<String> = sp.iter().map(|(k, v)| format!("{k} = {v:.1}x")).collect();
            println!("{:<14} {}", "", parts.join(", "));
        }
    }
    println!("\n{}", report.rapier);
    println!(
        "wrote {} and {}",
        csv_path.display(),
        plots
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok(())
}

fn clone_args(a: &ScaleArgs) -> ScaleArgs {
    ScaleArgs {
        scenes: a.scenes.clone(),
        sizes: a.sizes.clone(),
        huge: a.huge,
        steps: a.steps,
        warmup: a.warmup,
        max_seconds: a.max_seconds,
        quick: a.quick,
        json: a.json,
        out: a.out.clone(),
    }
}

fn rapier_note() -> &'static str {
    if cfg!(feature = "compare-rapier") {
        "Rapier 0.36 (rapier3d-f64, single-threaded build): same hulls, densities, dt, gravity and restitution; friction 0; sleeping off; chain links as rope joints at the upper bound."
    } else {
        "Rapier comparison not built in: run `cargo run --release --features compare-rapier -- bench scale` to add it."
    }
}
