//! Frame timing of the window: the interval between frames, the CPU work of each frame and the
//! time spent in each phase of it, for the panel (means over recent frames) and for the summary
//! `tumble view --frames N` prints at exit.

use std::collections::VecDeque;
use std::time::Instant;

/// The phases of a frame, in the order they run.
#[derive(Debug, Clone, Copy)]
pub enum Phase {
    /// egui, the panel's actions and the first framing of the camera.
    Ui,
    /// Stepping, with the recording's captures.
    Simulation,
    /// The scene's uniforms, instances and lines; egui's tessellation and textures.
    Upload,
    /// Waiting for the window's next image.
    Acquire,
    /// Encoding, submitting and presenting, and writing a screenshot.
    Submit,
}

const PHASES: usize = 5;

/// Frames kept for the panel's means.
const RECENT_FRAMES: usize = 60;

/// The start of one frame and the end of each of its phases.
pub struct FrameClock {
    /// Seconds since the previous frame started (0 on the first frame).
    pub real_dt: f64,
    marks: [Instant; PHASES + 1],
}

impl FrameClock {
    pub fn end(&mut self, phase: Phase) {
        self.marks[phase as usize + 1] = Instant::now();
    }
}

#[derive(Default)]
pub struct FrameStats {
    last_start: Option<Instant>,
    /// (interval since previous frame, time spent on the frame), recent frames.
    recent: VecDeque<(f64, f64)>,
    /// Same, every frame of the run, kept only for the `--frames` summary (a window left open
    /// for a day would keep 80 MB of them).
    all: Vec<(f64, f64)>,
    keep_all: bool,
    /// Frames finished so far.
    pub frames: u64,
    /// Seconds spent in each [`Phase`], summed over frames.
    phase_totals: [f64; PHASES],
}

impl FrameStats {
    /// Frame statistics that keep every frame for [`FrameStats::print_summary`] if `keep_all`.
    pub fn new(keep_all: bool) -> FrameStats {
        FrameStats {
            keep_all,
            ..FrameStats::default()
        }
    }

    /// Starts the clock of a frame, measuring the interval since the previous one.
    pub fn begin_frame(&mut self) -> FrameClock {
        let start = Instant::now();
        let real_dt = self
            .last_start
            .map_or(0.0, |t| start.duration_since(t).as_secs_f64());
        self.last_start = Some(start);
        FrameClock {
            real_dt,
            marks: [start; PHASES + 1],
        }
    }

    /// Ends the frame's last phase and books it. The first frame has no interval and pays for
    /// the first uploads: it is counted but not measured.
    pub fn finish_frame(&mut self, mut clock: FrameClock) {
        clock.end(Phase::Submit);
        let marks = clock.marks;
        let work = marks[PHASES].duration_since(marks[0]).as_secs_f64();
        if self.frames > 0 {
            for (k, total) in self.phase_totals.iter_mut().enumerate() {
                *total += marks[k + 1].duration_since(marks[k]).as_secs_f64();
            }
            self.recent.push_back((clock.real_dt, work));
            if self.keep_all {
                self.all.push((clock.real_dt, work));
            }
        }
        while self.recent.len() > RECENT_FRAMES {
            self.recent.pop_front();
        }
        self.frames += 1;
    }

    /// Mean frame interval and mean CPU work per frame over recent frames (seconds).
    pub fn recent_means(&self) -> (f64, f64) {
        (
            mean(self.recent.iter().map(|r| r.0)),
            mean(self.recent.iter().map(|r| r.1)),
        )
    }

    /// Prints the interval distribution and the time per phase over the run, after warm-up;
    /// `sim_real` is the simulation's pace against real time.
    pub fn print_summary(&self, sim_real: Option<f64>) {
        // Skip warm-up frames (shader compilation, first uploads).
        let skip = (self.all.len() / 10).min(10);
        let frames = &self.all[skip..];
        if frames.is_empty() {
            return;
        }
        let mut intervals: Vec<f64> = frames.iter().map(|f| f.0).collect();
        intervals.sort_by(f64::total_cmp);
        let mean_interval = mean(frames.iter().map(|f| f.0));
        let mean_work = mean(frames.iter().map(|f| f.1));
        let median = intervals[intervals.len() / 2];
        let p95 = intervals[(intervals.len() * 95 / 100).min(intervals.len() - 1)];
        eprintln!(
            "frames: {} measured ({} warm-up skipped): frame interval mean {:.2} ms, median {:.2} ms, p95 {:.2} ms ({:.1} fps); CPU work per frame {:.2} ms; sim/real {}",
            frames.len(),
            skip,
            1e3 * mean_interval,
            1e3 * median,
            1e3 * p95,
            1.0 / mean_interval.max(1e-9),
            1e3 * mean_work,
            sim_real.map_or("-".to_string(), |r| format!("{r:.2}x")),
        );
        let n = self.all.len().max(1) as f64;
        let [ui, sim, prepare, acquire, submit] = self.phase_totals.map(|t| 1e3 * t / n);
        eprintln!(
            "per frame: UI {ui:.2} ms, simulation {sim:.2} ms, upload+tessellate {prepare:.2} ms, acquire image {acquire:.2} ms, render+submit+present {submit:.2} ms"
        );
    }
}

fn mean(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    if n == 0 { 0.0 } else { sum / n as f64 }
}
