//! `tumble bench soak`: towers and hanging chains for a long time (100,000 steps by default),
//! reporting drift, constraint violation, energy and run time.

use super::Progress;
use crate::scene::{ConstraintsChoice, load};
use crate::sim::{Settings, World};
use glam::DVec3;
use serde::Serialize;
use std::time::Instant;

/// The scenes a soak runs: the built-in tower (its bodies dropped onto each other from up to 160
/// units), a stack of ten boxes built at rest, and the two chains.
pub const SOAK_SCENES: [&str; 3] = ["tower", "stack-10", "two-chain"];

#[derive(Debug, Clone, Serialize)]
pub struct SoakResult {
    pub scene: String,
    pub steps: u64,
    pub wall_s: f64,
    /// Largest distance any body's centre of mass moved from where it settled after 1 s; none
    /// for a run shorter than that (it read 0, as if nothing drifted).
    pub max_drift: Option<f64>,
    /// Largest speed of any body over the last 10 % of the run (its last step at least: under
    /// 10 steps it read 0).
    pub late_max_speed: f64,
    /// Worst violation relative to the rest length over the whole run (chains).
    pub worst_relative_violation: f64,
    pub budget_hits: u64,
    pub energy_start: f64,
    pub energy_end: f64,
    pub finite: bool,
}

/// Running maxima of one soak.
#[derive(Default)]
struct Watch {
    settled: Option<Vec<DVec3>>,
    max_drift: f64,
    late_max_speed: f64,
    worst: f64,
    budget_hits: u64,
}

impl Watch {
    fn observe(&mut self, world: &World, budget_hit: bool, settled_now: bool, late: bool) {
        self.budget_hits += budget_hit as u64;
        if settled_now {
            self.settled = Some(world.bodies.iter().map(|b| b.position).collect());
        }
        if let Some(reference) = &self.settled {
            for (b, x) in world.bodies.iter().zip(reference) {
                self.max_drift = self.max_drift.max((b.position - *x).length());
            }
        }
        if late {
            for b in &world.bodies {
                self.late_max_speed = self.late_max_speed.max(b.linear_velocity.length());
            }
        }
        for c in &world.constraints {
            self.worst = self.worst.max(c.relative_violation(&world.bodies));
        }
    }
}

/// Runs every soak scene for `steps` steps with `settings`.
pub fn run(
    settings: &Settings,
    steps: u64,
    progress: &dyn Progress,
) -> anyhow::Result<Vec<SoakResult>> {
    let mut results = Vec::new();
    for scene in SOAK_SCENES {
        let mut world = load(scene, &ConstraintsChoice::Auto, settings.clone())?;
        let energy_start = world.total_energy();
        let settle_steps = (1.0 / settings.time_step).ceil() as u64;
        let mut watch = Watch::default();
        progress.start(steps, &format!("soak {scene}"));
        let start = Instant::now();
        world.stepping(|world| {
            for k in 0..steps {
                let stats = world.step();
                let late = k >= steps - (steps / 10).max(1);
                watch.observe(world, stats.budget_hit, k + 1 == settle_steps, late);
                if k % 1024 == 0 {
                    progress.set_position(k);
                }
            }
        });
        progress.finish();
        results.push(SoakResult {
            scene: scene.to_string(),
            steps,
            wall_s: start.elapsed().as_secs_f64(),
            max_drift: watch.settled.is_some().then_some(watch.max_drift),
            late_max_speed: watch.late_max_speed,
            worst_relative_violation: watch.worst,
            budget_hits: watch.budget_hits,
            energy_start,
            energy_end: world.total_energy(),
            finite: world.all_finite(),
        });
    }
    Ok(results)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A run of a few steps still measures its last step's speeds, and says it has no drift
    /// (it ends before the second its bodies settle in) rather than a drift of 0.
    #[test]
    fn a_short_soak_measures_what_it_can() {
        let results = run(&Settings::default(), 5, &super::super::Silent).unwrap();
        let chains = results.iter().find(|r| r.scene == "two-chain").unwrap();
        // Five steps of free fall from rest: the links hang slack, about g * 5 dt fast.
        assert!(chains.late_max_speed > 0.5, "{}", chains.late_max_speed);
        assert!(results.iter().all(|r| r.max_drift.is_none()));
        let settled = run(&Settings::default(), 60, &super::super::Silent).unwrap();
        assert!(settled.iter().all(|r| r.max_drift.is_some()));
    }
}
