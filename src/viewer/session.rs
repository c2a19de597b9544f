//! The simulation as the viewer drives it: fixed steps following wall-clock time, capped so the
//! window stays responsive, with the statistics and history the panel shows.

use crate::World;
use crate::sim::stats::{StageTimings, StepStats};
use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// One point of the energy / constraint-violation plot.
#[derive(Debug, Clone, Copy)]
pub struct Sample {
    pub time: f64,
    pub energy: f64,
    pub violation: f64,
}

pub struct Session {
    pub world: World,
    /// Scene name or path, for display and reloading.
    pub scene: String,
    pub playing: bool,
    /// Real seconds not yet simulated.
    accumulator: f64,
    /// Statistics of the last step.
    pub last: StepStats,
    /// Summed stage timings of the steps of the last frame.
    pub frame_timings: StageTimings,
    pub frame_steps: u32,
    /// The last frame could not simulate all the real time that passed.
    pub behind: bool,
    /// (real seconds, simulated seconds) of recent frames, for the sim/real ratio.
    pace: VecDeque<(f64, f64)>,
    pub history: VecDeque<Sample>,
    /// Seconds of simulated time the plot keeps.
    pub history_span: f64,
    /// Most steps per frame, and most wall time spent stepping per frame.
    pub max_steps_per_frame: u32,
    pub step_budget: Duration,
}

impl Session {
    pub fn new(world: World, scene: String) -> Session {
        let mut session = Session {
            world,
            scene,
            playing: true,
            accumulator: 0.0,
            last: StepStats::default(),
            frame_timings: StageTimings::default(),
            frame_steps: 0,
            behind: false,
            pace: VecDeque::new(),
            history: VecDeque::new(),
            history_span: 10.0,
            max_steps_per_frame: 200,
            step_budget: Duration::from_millis(33),
        };
        session.sample();
        session
    }

    /// Swaps in another world (a newly loaded scene), keeping the play state.
    pub fn replace(&mut self, world: World, scene: String) {
        self.world = world;
        self.scene = scene;
        self.restart_bookkeeping();
    }

    pub fn reset(&mut self) {
        self.world.reset();
        self.restart_bookkeeping();
    }

    fn restart_bookkeeping(&mut self) {
        self.accumulator = 0.0;
        self.last = StepStats::default();
        self.frame_timings = StageTimings::default();
        self.frame_steps = 0;
        self.behind = false;
        self.pace.clear();
        self.history.clear();
        self.sample();
    }

    fn sample(&mut self) {
        let sample = Sample {
            time: self.world.time,
            energy: self.world.total_energy(),
            violation: self.world.max_constraint_violation(),
        };
        self.history.push_back(sample);
        while self
            .history
            .front()
            .is_some_and(|s| s.time < sample.time - self.history_span)
        {
            self.history.pop_front();
        }
    }

    /// One step, whatever the play state (S key, Step button).
    pub fn step_once(&mut self) {
        self.frame_timings = StageTimings::default();
        self.frame_steps = 0;
        self.do_step();
        self.sample();
    }

    fn do_step(&mut self) {
        let stats = self.world.step();
        self.frame_timings.add(&stats.timings);
        self.frame_steps += 1;
        self.last = stats;
    }

    /// Advances by `real_dt` seconds of wall-clock time when playing: as many steps as fit, at
    /// most `max_steps_per_frame` and `step_budget` of stepping; what does not fit is dropped
    /// (the simulation runs slower than real time and [`Self::ratio`] says by how much).
    /// `after_step` runs after every step (the viewer's recorder samples frames there).
    pub fn advance(&mut self, real_dt: f64, mut after_step: impl FnMut(&World)) {
        if !self.playing {
            return;
        }
        let dt = self.world.settings.time_step;
        self.frame_timings = StageTimings::default();
        self.frame_steps = 0;
        if !(dt.is_finite() && dt > 0.0) {
            return;
        }
        let real_dt = real_dt.clamp(0.0, 0.25);
        self.accumulator += real_dt;
        let start = Instant::now();
        let sim_before = self.world.time;
        self.behind = false;
        // A relative epsilon: 0.1 s of real time at dt = 0.02 is 5 steps, not 4 and a remainder.
        while self.accumulator >= dt * (1.0 - 1e-9) {
            if self.frame_steps >= self.max_steps_per_frame || start.elapsed() >= self.step_budget {
                self.behind = true;
                self.accumulator = 0.0;
                break;
            }
            self.do_step();
            self.accumulator -= dt;
            after_step(&self.world);
        }
        self.pace.push_back((real_dt, self.world.time - sim_before));
        let mut total = self.pace.iter().map(|p| p.0).sum::<f64>();
        while total > 1.0 && self.pace.len() > 1 {
            total -= self.pace.pop_front().map_or(0.0, |p| p.0);
        }
        if self.frame_steps > 0 {
            self.sample();
        }
    }

    /// Simulated seconds per real second over about the last second of play.
    pub fn ratio(&self) -> Option<f64> {
        let real: f64 = self.pace.iter().map(|p| p.0).sum();
        let sim: f64 = self.pace.iter().map(|p| p.1).sum();
        (real > 0.2).then(|| sim / real)
    }

    pub fn pause(&mut self) {
        self.playing = false;
        self.pace.clear();
        self.accumulator = 0.0;
    }

    pub fn toggle_play(&mut self) {
        if self.playing {
            self.pause();
        } else {
            self.playing = true;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn session() -> Session {
        let world = crate::scene::load(
            "mixed",
            &crate::ConstraintsChoice::Auto,
            crate::Settings::default(),
        )
        .unwrap();
        Session::new(world, "mixed".into())
    }

    #[test]
    fn follows_wall_clock_with_fixed_steps() {
        let mut s = session();
        let mut seen = 0;
        for _ in 0..10 {
            s.advance(0.05, |_| seen += 1);
        }
        // 0.5 s at dt = 0.02: 25 steps (the accumulator carries the remainder).
        assert_eq!(s.world.step_count, 25);
        assert_eq!(seen, 25);
        assert!((s.world.time - 0.5).abs() < 1e-9);
    }

    #[test]
    fn caps_steps_per_frame_and_reports_ratio() {
        let mut s = session();
        s.max_steps_per_frame = 2;
        for _ in 0..20 {
            s.advance(0.1, |_| {});
        }
        assert!(s.behind);
        let ratio = s.ratio().unwrap();
        assert!((ratio - 0.4).abs() < 1e-9, "{ratio}");
    }

    #[test]
    fn settings_change_applies_without_reset() {
        let mut s = session();
        s.advance(0.1, |_| {});
        let steps = s.world.step_count;
        s.world.settings.time_step = 0.01;
        s.advance(0.1, |_| {});
        assert_eq!(s.world.step_count, steps + 10);
        s.pause();
        s.advance(1.0, |_| {});
        assert_eq!(s.world.step_count, steps + 10);
        s.step_once();
        assert_eq!(s.world.step_count, steps + 11);
        s.reset();
        assert_eq!(s.world.step_count, 0);
        assert_eq!(s.world.settings.time_step, 0.01);
    }
}
