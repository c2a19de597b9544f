//! Where `bench accuracy`'s pile_rest spends its run time, second by simulated second: the
//! accurate preset and Rapier on the same pile (pile-200 at friction 0.5 and restitution 0.2,
//! as the bench sets it), stepped in turn on one thread as the bench steps them, with
//! each engine's run time and sleeping bodies at the end of every simulated second, then the
//! bench's two metrics of each pile at the end (another BODIES draws another pile).
//!
//! ```sh
//! cargo run --release --features compare-rapier --example pile_rest_timeline -- 0.04 [BODIES]
//! ```
//!
//! pile_rest's time against Rapier's is two things: what a step costs while the pile lands and
//! settles, and when each pile falls asleep. The bench gives their product; this gives both.

use std::process::ExitCode;
use tumble::bench::rapier::RapierScene;
use tumble::bench::scenarios::{Rest, Scenario, pile_rest_world};
use tumble::sim::{Settings, World};

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (dt, bodies) = match parse(&args) {
        Ok(parsed) => parsed,
        Err(message) => {
            eprintln!("{message}\nusage: pile_rest_timeline DT [BODIES]   (e.g. 0.04 200)");
            return ExitCode::FAILURE;
        }
    };
    let settings = Settings {
        time_step: dt,
        ..Settings::accurate()
    };
    let mut world = pile_rest_world(bodies, settings);
    let mut mirror = world.clone();
    let rapier = RapierScene::from_world(&world, true);
    // One thread, as `bench accuracy` times both engines (Rapier's default build has one).
    let one_thread = match rayon::ThreadPoolBuilder::new().num_threads(1).build() {
        Ok(pool) => pool,
        Err(e) => {
            eprintln!("cannot start a thread: {e}");
            return ExitCode::FAILURE;
        }
    };
    let (rows, rapier) =
        one_thread.install(|| world.stepping(move |world| timeline(world, rapier, dt)));
    print(&rows, bodies);
    // Rapier's poses and velocities measured by the bench's measure, as the bench does.
    rapier.copy_into(&mut mirror);
    for (engine, w) in [("accurate", &world), ("rapier", &mirror)] {
        let rest = Rest::of(w);
        println!(
            "{engine:>8} at the end: max speed {:.3e}, deepest contact {:.3} % of the smallest body",
            rest.max_speed,
            100.0 * rest.max_penetration_relative
        );
    }
    ExitCode::SUCCESS
}

/// A time step in (0, 1] s and a body count of at least one.
fn parse(args: &[String]) -> Result<(f64, usize), String> {
    let dt: f64 = match args.first() {
        Some(word) => word
            .parse()
            .map_err(|_| format!("DT: not a number: {word}"))?,
        None => return Err("DT is missing".into()),
    };
    if !(dt > 0.0 && dt <= 1.0) {
        return Err(format!("DT must lie in (0, 1] s, got {dt}"));
    }
    let bodies = match args.get(1) {
        Some(word) => word
            .parse()
            .ok()
            .filter(|&n| n > 0)
            .ok_or_else(|| format!("BODIES: not a positive count: {word}"))?,
        None => 200,
    };
    Ok((dt, bodies))
}

/// One simulated second: each engine's run time (ms) and bodies asleep at its end.
#[derive(Default)]
struct Second {
    tumble_ms: f64,
    tumble_asleep: usize,
    rapier_ms: f64,
    rapier_asleep: usize,
}

/// Steps both engines in turn for pile_rest's duration, a row per simulated second; gives
/// Rapier's scene back at its end.
fn timeline(world: &mut World, mut rapier: RapierScene, dt: f64) -> (Vec<Second>, RapierScene) {
    let per_second = (1.0 / dt).round().max(1.0) as usize;
    let steps = (Scenario::PileRest.duration() / dt).round() as usize;
    let mut rows = Vec::new();
    let mut row = Second::default();
    for k in 1..=steps {
        let start = std::time::Instant::now();
        let stats = world.step();
        row.tumble_ms += 1e3 * start.elapsed().as_secs_f64();
        row.rapier_ms += 1e3 * rapier.step();
        if k % per_second == 0 || k == steps {
            row.tumble_asleep = stats.asleep;
            row.rapier_asleep = rapier.asleep();
            rows.push(std::mem::take(&mut row));
        }
    }
    (rows, rapier)
}

/// The table, the totals, and the first second at whose end each pile was all asleep.
fn print(rows: &[Second], bodies: usize) {
    println!("second  accurate ms  asleep  |  rapier ms  asleep");
    for (k, r) in rows.iter().enumerate() {
        println!(
            "{:>6}  {:>11.1}  {:>6}  |  {:>9.1}  {:>6}",
            k + 1,
            r.tumble_ms,
            r.tumble_asleep,
            r.rapier_ms,
            r.rapier_asleep
        );
    }
    let total = |f: fn(&Second) -> f64| rows.iter().map(f).sum::<f64>();
    let (tumble, rapier) = (total(|r| r.tumble_ms), total(|r| r.rapier_ms));
    println!(
        "total   {tumble:>11.1}          |  {rapier:>9.1}   accurate / rapier {:.2}",
        tumble / rapier
    );
    // pile-N holds N moving bodies beside the bin's fixed walls, which neither counts asleep.
    let all_asleep = |asleep: fn(&Second) -> usize| {
        rows.iter()
            .position(|r| asleep(r) >= bodies)
            .map_or("never".to_string(), |k| format!("by {} s", k + 1))
    };
    println!(
        "all asleep: accurate {}, rapier {}",
        all_asleep(|r| r.tumble_asleep),
        all_asleep(|r| r.rapier_asleep)
    );
}
