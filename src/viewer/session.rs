//! The simulation as the viewer drives it, and the API the tests drive it through: fixed steps
//! following wall-clock time, capped so the window stays responsive; one world, or two of the
//! same scene with different settings stepped in lockstep ([`Lane`]s); the rewind history; the
//! mouse grab; and the scene's source, reloaded when its files change.

use super::grab;
use super::scene_source::SceneSource;
use super::timeline::{self, Timeline};
use super::watch::FileWatch;
use crate::sim::WorldState;
use crate::sim::stats::{StageTimings, StepStats};
use crate::{LoadError, Settings, World};
use glam::DVec3;
use std::collections::VecDeque;
use std::path::Path;
use std::time::{Duration, Instant};

/// One point of the energy / constraint-violation plot.
#[derive(Debug, Clone, Copy)]
pub struct Sample {
    pub time: f64,
    pub energy: f64,
    pub violation: f64,
}

/// One world of the session with its statistics and plot.
pub struct Lane {
    pub world: World,
    /// Statistics of the last step.
    pub last: StepStats,
    /// Summed stage timings of the steps of the last frame, and their number.
    pub frame_timings: StageTimings,
    pub frame_steps: u32,
    /// Energy and violation over the last `plot_span` simulated seconds.
    pub plot: VecDeque<Sample>,
    /// Where this world's grabbed point was, less where the grab began in the world it was
    /// made in ([`Session::grab`]): its target is the cursor's plus this.
    grab_offset: DVec3,
}

/// Most steps a compared world takes in one tick to catch up with the first: 10,000 steps of
/// a small scene are some milliseconds.
const MAX_CATCH_UP_STEPS: usize = 10_000;

impl Lane {
    fn new(world: World) -> Lane {
        Lane {
            world,
            last: StepStats::default(),
            frame_timings: StageTimings::default(),
            frame_steps: 0,
            plot: VecDeque::new(),
            grab_offset: DVec3::ZERO,
        }
    }

    fn step(&mut self) {
        let stats = self.world.step();
        self.frame_timings.add(&stats.timings);
        self.frame_steps += 1;
        self.last = stats;
    }

    /// Steps until the world's time is within half a step of `time` (lockstep with the first
    /// world, whatever this one's time step), at most [`MAX_CATCH_UP_STEPS`] a call and never
    /// past a step that leaves the time where it was: a compared world at `--dt 1e-300` stepped
    /// for ever in one tick, past Ctrl-C. One left behind catches up on later ticks.
    fn catch_up(&mut self, time: f64) {
        let dt = self.world.settings.time_step;
        if !(dt.is_finite() && dt > 0.0) {
            return;
        }
        for _ in 0..MAX_CATCH_UP_STEPS {
            let before = self.world.time;
            if before >= time - 0.5 * dt {
                break;
            }
            self.step();
            if self.world.time <= before {
                break;
            }
        }
    }

    fn begin_frame(&mut self) {
        self.frame_timings = StageTimings::default();
        self.frame_steps = 0;
    }

    /// Adds the current state to the plot, dropping samples older than `span` seconds and any
    /// after the current time (left from before a rewind).
    fn sample(&mut self, span: f64) {
        let sample = Sample {
            time: self.world.time,
            energy: self.world.total_energy(),
            violation: self.world.max_constraint_violation(),
        };
        while self.plot.back().is_some_and(|s| s.time >= sample.time) {
            self.plot.pop_back();
        }
        self.plot.push_back(sample);
        while self
            .plot
            .front()
            .is_some_and(|s| s.time < sample.time - span)
        {
            self.plot.pop_front();
        }
    }
}

pub struct Session {
    /// The first world, then the compared one (if any).
    pub lanes: Vec<Lane>,
    /// Where the scene comes from, for reloading.
    pub source: SceneSource,
    pub playing: bool,
    /// Real seconds not yet simulated.
    accumulator: f64,
    /// The last frame could not simulate all the real time that passed.
    pub behind: bool,
    /// (real seconds, simulated seconds) of recent frames, for the sim/real ratio.
    pace: VecDeque<(f64, f64)>,
    /// Seconds of simulated time the plots keep.
    pub plot_span: f64,
    /// Most steps per frame, and most wall time spent stepping per frame.
    pub max_steps_per_frame: u32,
    pub step_budget: Duration,
    /// Every state since the start, as far as the memory budget allows.
    pub timeline: Timeline,
    /// Natural frequency of the grab spring (Hz).
    pub grab_hertz: f64,
    /// Reload the scene when one of its files changes.
    pub auto_reload: bool,
    watch: FileWatch,
    /// The scene as loaded, for reset and compare: the viewer keeps it, not the world, so a
    /// headless run does not carry a copy of its start.
    start: WorldState,
}

impl Session {
    pub fn new(world: World, source: SceneSource) -> Session {
        let mut session = Session {
            start: world.snapshot(),
            lanes: vec![Lane::new(world)],
            watch: FileWatch::new(source.files()),
            source,
            playing: true,
            accumulator: 0.0,
            behind: false,
            pace: VecDeque::new(),
            plot_span: 10.0,
            max_steps_per_frame: 200,
            step_budget: Duration::from_millis(33),
            timeline: Timeline::new(timeline::DEFAULT_BUDGET),
            grab_hertz: grab::DEFAULT_HERTZ,
            auto_reload: true,
        };
        session.restart_bookkeeping();
        session
    }

    /// The first world (the one the panel's settings and the selection refer to).
    pub fn world(&self) -> &World {
        &self.lanes[0].world
    }

    pub fn world_mut(&mut self) -> &mut World {
        &mut self.lanes[0].world
    }

    /// Every world, first to last.
    pub fn worlds(&self) -> Vec<&World> {
        self.lanes.iter().map(|l| &l.world).collect()
    }

    pub fn comparing(&self) -> bool {
        self.lanes.len() > 1
    }

    /// Scene name or path, for display.
    pub fn scene(&self) -> String {
        self.source.name()
    }

    /// Compares the scene with `settings`: both worlds start again from the scene's start and
    /// step in lockstep.
    pub fn compare(&mut self, settings: Settings) {
        self.lanes.truncate(1);
        let first = &mut self.lanes[0].world;
        first.restore(&self.start);
        first.grab = None;
        let mut second = first.clone();
        second.settings = settings;
        self.lanes.push(Lane::new(second));
        self.restart_bookkeeping();
    }

    /// Back to the first world alone; the history keeps its states.
    pub fn stop_comparing(&mut self) {
        self.lanes.truncate(1);
        self.timeline.keep_lanes(1);
    }

    /// Swaps in a newly loaded scene, keeping each world's settings and the play state.
    fn replace(&mut self, world: World, source: SceneSource, watch: FileWatch) {
        self.start = world.snapshot();
        let settings: Vec<Settings> = self
            .lanes
            .iter()
            .map(|l| l.world.settings.clone())
            .collect();
        self.lanes = settings
            .into_iter()
            .map(|settings| {
                let mut w = world.clone();
                w.settings = settings;
                Lane::new(w)
            })
            .collect();
        self.watch = watch;
        self.source = source;
        self.restart_bookkeeping();
    }

    /// Loads `source` with the current settings; on an error the current scene stays.
    pub fn open(&mut self, source: SceneSource) -> Result<(), LoadError> {
        // Its files are stamped before they are read: one saved while the scene loads is seen
        // by the next poll (stamped after, that save was taken as read and never loaded).
        let watch = FileWatch::new(source.files());
        self.open_watched(source, watch)
    }

    /// [`Session::open`] with the watch of the files stamped before the load.
    fn open_watched(&mut self, source: SceneSource, watch: FileWatch) -> Result<(), LoadError> {
        let world = source.load(self.world().settings.clone())?;
        for w in &world.warnings {
            eprintln!("warning: {w}");
        }
        self.replace(world, source, watch);
        Ok(())
    }

    /// When reloading is on and one of the scene's files changed since the last poll: loads the
    /// scene again (None when nothing changed). On an error the current scene keeps running;
    /// the files stay watched either way, stamped before they were read.
    pub fn poll_files(&mut self) -> Option<Result<(), LoadError>> {
        if !self.auto_reload {
            return None;
        }
        self.watch.poll()?;
        // The scene may now name other meshes: watch those. A scene file gone (deleted, or a
        // folder now) names none: the old ones stay watched, so that its return is seen (the
        // watch was left empty, and reloading stopped for good).
        let mut files = self.source.files();
        if files.is_empty() {
            files = self.watch.files().map(Path::to_path_buf).collect();
        }
        let watch = FileWatch::new(files);
        let result = self.open_watched(self.source.clone(), watch.clone());
        if result.is_err() {
            self.watch = watch;
        }
        Some(result)
    }

    /// The files being watched.
    pub fn watched_files(&self) -> impl Iterator<Item = &std::path::Path> {
        self.watch.files()
    }

    pub fn reset(&mut self) {
        for lane in &mut self.lanes {
            lane.world.restore(&self.start);
        }
        self.restart_bookkeeping();
    }

    fn restart_bookkeeping(&mut self) {
        self.accumulator = 0.0;
        self.behind = false;
        self.pace.clear();
        for lane in &mut self.lanes {
            lane.last = StepStats::default();
            lane.begin_frame();
            lane.plot.clear();
            lane.sample(self.plot_span);
        }
        self.timeline.clear();
        self.timeline.record(self.lanes.iter().map(|l| &l.world));
    }

    /// One tick: the first world steps once, the others catch up with it; the states go into
    /// the history (dropping those after the current one when resuming from the past).
    fn tick(&mut self) {
        let (first, others) = self.lanes.split_first_mut().expect("one lane at least");
        first.step();
        for lane in others {
            lane.catch_up(first.world.time);
        }
        self.timeline.record(self.lanes.iter().map(|l| &l.world));
    }

    fn begin_frame(&mut self) {
        for lane in &mut self.lanes {
            lane.begin_frame();
        }
    }

    fn sample(&mut self) {
        for lane in &mut self.lanes {
            lane.sample(self.plot_span);
        }
    }

    /// Steps taken in the last frame by the first world.
    pub fn frame_steps(&self) -> u32 {
        self.lanes[0].frame_steps
    }

    /// One tick, whatever the play state (S key, Step button, Right at the end of the history).
    pub fn step_once(&mut self) {
        self.begin_frame();
        self.tick();
        self.sample();
    }

    /// Advances by `real_dt` seconds of wall-clock time when playing: as many ticks of the first
    /// world's `dt` as fit, at most `max_steps_per_frame` and `step_budget` of stepping; what
    /// does not fit is dropped (the simulation runs slower than real time and [`Self::ratio`]
    /// says by how much). `after_tick` runs after every tick (the recorder samples frames there).
    pub fn advance(&mut self, real_dt: f64, mut after_tick: impl FnMut(&[Lane])) {
        if !self.playing {
            return;
        }
        let dt = self.world().settings.time_step;
        self.begin_frame();
        if !(dt.is_finite() && dt > 0.0) {
            return;
        }
        let real_dt = real_dt.clamp(0.0, 0.25);
        self.accumulator += real_dt;
        let start = Instant::now();
        let sim_before = self.world().time;
        self.behind = false;
        let mut ticks = 0;
        // A relative epsilon: 0.1 s of real time at dt = 0.02 is 5 steps, not 4 and a remainder.
        while self.accumulator >= dt * (1.0 - 1e-9) {
            if ticks >= self.max_steps_per_frame || start.elapsed() >= self.step_budget {
                self.behind = true;
                self.accumulator = 0.0;
                break;
            }
            self.tick();
            ticks += 1;
            self.accumulator -= dt;
            after_tick(&self.lanes);
        }
        self.pace
            .push_back((real_dt, self.world().time - sim_before));
        let mut total = self.pace.iter().map(|p| p.0).sum::<f64>();
        while total > 1.0 && self.pace.len() > 1 {
            total -= self.pace.pop_front().map_or(0.0, |p| p.0);
        }
        if ticks > 0 {
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

    /// Pauses and puts every world back to entry `index` of the history (clamped). Resuming
    /// from there drops the later entries.
    pub fn seek(&mut self, index: usize) {
        self.pause();
        let Some(states) = self.timeline.seek(index) else {
            return;
        };
        for (lane, state) in self.lanes.iter_mut().zip(states) {
            lane.world.restore(state);
            lane.last = StepStats::default();
        }
    }

    /// Pauses at the state after step `step` of the first world; false when the history no
    /// longer holds it.
    pub fn seek_step(&mut self, step: u64) -> bool {
        match self.timeline.index_of_step(step) {
            Some(index) => {
                self.seek(index);
                true
            }
            None => false,
        }
    }

    /// Left arrow: one state back (pauses).
    pub fn step_back(&mut self) {
        self.seek(self.timeline.cursor().saturating_sub(1));
    }

    /// Right arrow: one state forward in the history, or a new step at its end (pauses).
    pub fn step_forward(&mut self) {
        if self.timeline.at_end() {
            self.pause();
            self.step_once();
        } else {
            self.seek(self.timeline.cursor() + 1);
        }
    }

    /// Starts pulling `local_point` (body space) of `body` in every world, from where that
    /// point is in each (`target`: where it is in the world it was picked in); false when the
    /// body cannot move. Compared worlds drift apart, so each world's body keeps its own
    /// offset from the cursor and every drag moves them alike: one target for all pulled the
    /// other world's body onto this one's, and a paused click moved it there at once. A click
    /// alone changes no pose, and keeps a rewound history's future.
    pub fn grab(&mut self, body: usize, local_point: DVec3, target: DVec3) -> bool {
        let hertz = self.grab_hertz;
        let mut any = false;
        for lane in &mut self.lanes {
            let point =
                (lane.world.bodies.get(body)).map_or(target, |b| b.world_point(local_point));
            lane.grab_offset = point - target;
            any |= grab::attach(&mut lane.world, body, local_point, point, hertz);
        }
        any
    }

    /// Moves the grab's target to `target` (each world's offset by where its body was
    /// grabbed). While paused, the grabbed bodies are moved there directly and the history's
    /// current state becomes the edited one.
    pub fn drag_grab(&mut self, target: DVec3) {
        let hertz = self.grab_hertz;
        for lane in &mut self.lanes {
            grab::retarget(&mut lane.world, target + lane.grab_offset, hertz);
            if !self.playing {
                grab::place(&mut lane.world);
            }
        }
        if !self.playing && self.grabbing() {
            self.timeline
                .replace_current(self.lanes.iter().map(|l| &l.world));
        }
    }

    pub fn release_grab(&mut self) {
        for lane in &mut self.lanes {
            lane.world.grab = None;
        }
    }

    pub fn grabbing(&self) -> bool {
        self.lanes.iter().any(|l| l.world.grab.is_some())
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
        Session::new(world, SceneSource::named("mixed"))
    }

    #[test]
    fn follows_wall_clock_with_fixed_steps() {
        let mut s = session();
        let mut seen = 0;
        for _ in 0..10 {
            s.advance(0.05, |_| seen += 1);
        }
        // 0.5 s at dt = 0.02: 25 steps (the accumulator carries the remainder).
        assert_eq!(s.world().step_count, 25);
        assert_eq!(seen, 25);
        assert!((s.world().time - 0.5).abs() < 1e-9);
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
        let steps = s.world().step_count;
        s.world_mut().settings.time_step = 0.01;
        s.advance(0.1, |_| {});
        assert_eq!(s.world().step_count, steps + 10);
        s.pause();
        s.advance(1.0, |_| {});
        assert_eq!(s.world().step_count, steps + 10);
        s.step_once();
        assert_eq!(s.world().step_count, steps + 11);
        s.reset();
        assert_eq!(s.world().step_count, 0);
        assert_eq!(s.world().settings.time_step, 0.01);
    }

    #[test]
    fn arrows_walk_the_history_and_resuming_drops_the_future() {
        let mut s = session();
        for _ in 0..10 {
            s.step_once();
        }
        assert_eq!(s.timeline.len(), 11);
        s.step_back();
        s.step_back();
        assert_eq!(s.world().step_count, 8);
        s.step_forward();
        assert_eq!(s.world().step_count, 9);
        s.step_once();
        assert_eq!(s.world().step_count, 10);
        assert_eq!(s.timeline.len(), 11, "step 10 replaced, nothing after it");
        assert!(s.timeline.at_end());
        s.step_forward();
        assert_eq!(s.world().step_count, 11);
    }
}
