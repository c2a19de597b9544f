//! Recording started from the window's panel. A frame of the 3D view is taken after the step that
//! reaches each frame's simulated time (one per 1/fps of simulated time), so the video plays at
//! simulated speed whatever the window's frame rate. The encoding is [`mod@super::record`]'s.

use super::gpu::Image;
use super::labels::{Label, LabelPainter};
use super::present::{SceneView, prepare_scene};
use super::record::{FrameWriter, check_recording_output};
use super::session::Lane;
use super::window::{Gfx, ViewRect};
use crate::{StepStats, World};
use std::path::{Path, PathBuf};

pub struct Recording {
    writer: FrameWriter,
    times: FrameTimes,
    /// Frame size (pixels), fixed for the whole recording.
    width: u32,
    height: u32,
    /// Paints the compared worlds' labels into the frames.
    labels: Option<LabelPainter>,
}

impl Recording {
    /// Starts recording the view into `path` from simulated time `time`, never over one of
    /// `inputs` (the files the scene was read from); the error is the message for the panel.
    pub fn start(
        path: &Path,
        view: ViewRect,
        (fps, time): (f64, f64),
        inputs: &[PathBuf],
    ) -> Result<Recording, String> {
        let path =
            &check_recording_output(path, inputs).map_err(|e| format!("cannot record: {e:#}"))?;
        let [_, _, w, h] = view.0.map(|v| v.max(0.0) as u32);
        // Even sizes suit every format (H.264 needs them).
        let (width, height) = (w & !1, h & !1);
        if width < 2 || height < 2 {
            return Err("the view is too small to record".into());
        }
        match FrameWriter::create(path, width, height, fps) {
            Ok(writer) => Ok(Recording {
                writer,
                times: FrameTimes::new(fps, time),
                width,
                height,
                labels: None,
            }),
            Err(e) => Err(format!("cannot record: {e:#}")),
        }
    }

    /// Output path (for display) and frames so far.
    pub fn status(&self) -> (String, u64) {
        (self.writer.path.display().to_string(), self.writer.frames)
    }

    /// After the simulated time jumped to `time` (see [`FrameTimes::resume_at`]).
    pub fn resume_at(&mut self, time: f64) {
        self.times.resume_at(time);
    }

    /// Encodes the queued frames and closes the file; returns its path and the frames written.
    pub fn finish(self) -> anyhow::Result<(PathBuf, u64)> {
        let path = self.writer.path.clone();
        let (frames, _) = self.writer.finish()?;
        Ok((path, frames))
    }

    /// Pushes the frames due at the first world's time: one render serves every frame time the
    /// last step passed. `lanes`: the world and those compared with it, labelled in the frames.
    pub fn capture_due(
        &mut self,
        gfx: &mut Gfx,
        lanes: &[Lane],
        view: SceneView<'_>,
    ) -> anyhow::Result<()> {
        let time = lanes[0].world.time;
        let due = self.times.due(time);
        if due == 0 {
            return Ok(());
        }
        let image = render_view(gfx, lanes, view, &mut self.labels)?;
        let frame = image.crop(0, 0, self.width, self.height);
        anyhow::ensure!(
            frame.width == self.width && frame.height == self.height,
            "the window shrank during the recording"
        );
        for _ in 0..self.times.taken(due, time) {
            self.writer.push(frame.clone())?;
        }
        Ok(())
    }
}

/// When a recording's frames are due, in simulated time: one every `1 / fps`, from the
/// recording's start or from where the time last jumped.
#[derive(Debug, Clone, Copy)]
struct FrameTimes {
    fps: f64,
    /// Where the frames are timed from. Frame `k` is due at `origin + k / fps`: counted, not
    /// summed, so that the frame times neither drift nor stall where a time is so large that
    /// adding `1 / fps` leaves it unchanged (`--dt 1e15` looped for ever).
    origin: f64,
    /// Index of the next frame, from `origin`.
    next_frame: u64,
}

/// Most frames of one image a capture writes: 2 s of video at 30 fps. A step longer than that
/// (`--dt 1e15`; the panel's slider ends at 0.05 s) is filmed as this long, and the frames go
/// on from its end: 600 frames a step kept the window waiting on their encoding step after step.
const MAX_FRAMES_PER_CAPTURE: u64 = 60;

impl FrameTimes {
    fn new(fps: f64, time: f64) -> FrameTimes {
        FrameTimes {
            fps,
            origin: time,
            next_frame: 0,
        }
    }

    /// After the simulated time jumped to `time` (a reset, a new scene, a seek or a step back in
    /// the history): the next frame is the one at `time`, and the frames go on from there. The
    /// video shows what the view showed: a run replayed after a step back is filmed again, and
    /// the time a seek skips is not filmed as a still (it was, one frame per skipped frame time).
    fn resume_at(&mut self, time: f64) {
        self.origin = time;
        self.next_frame = 0;
    }

    /// Frames due at simulated time `time`: those from the next one up to `time`. A step longer
    /// than a frame's time is filmed as that many frames of one image, so that the video keeps
    /// to simulated speed.
    fn due(&self, time: f64) -> u64 {
        let last = ((time + 1e-9 - self.origin) * self.fps).floor();
        let next = self.next_frame as f64;
        if last >= next {
            (last - next + 1.0).min(u64::MAX as f64) as u64
        } else {
            // Also a NaN time: nothing due.
            0
        }
    }

    /// Books the `due` frames at `time` as captured; returns how many to write (at most
    /// [`MAX_FRAMES_PER_CAPTURE`]: the rest of so long a step is not filmed).
    fn taken(&mut self, due: u64, time: f64) -> u64 {
        if due > MAX_FRAMES_PER_CAPTURE {
            self.resume_at(time);
            self.next_frame = 1;
            MAX_FRAMES_PER_CAPTURE
        } else {
            self.next_frame += due;
            due
        }
    }
}

/// Renders the scene alone, with the compared worlds' labels (painted by `painter`, made on
/// first use), and reads back the 3D view's pixels (top left = view's top left): from the scene
/// texture, or from the window-sized capture drawn with a viewport.
fn render_view(
    gfx: &mut Gfx,
    lanes: &[Lane],
    view: SceneView<'_>,
    painter: &mut Option<LabelPainter>,
) -> anyhow::Result<Image> {
    let worlds: Vec<&World> = lanes.iter().map(|l| &l.world).collect();
    let scene = prepare_scene(gfx, &worlds, view);
    let mut encoder = gfx.gpu.device.create_command_encoder(&Default::default());
    let target = if scene.is_some() {
        gfx.scene.as_ref().expect("sized by prepare_scene")
    } else {
        gfx.ensure_window_capture();
        gfx.capture.as_ref().expect("created above")
    };
    // Drawn into the scene texture whole, or into the capture within the view.
    let rect = match scene {
        Some(_) => [0.0, 0.0, target.width as f32, target.height as f32],
        None => view.rect.0,
    };
    gfx.renderer.draw(
        &mut encoder,
        &target.srgb_view,
        scene.is_none().then_some(rect),
    );
    if lanes.len() > 1 {
        let stats: Vec<(&World, &StepStats)> = lanes.iter().map(|l| (&l.world, &l.last)).collect();
        let labels = Label::for_panes(rect, &stats, view.draw.layout);
        painter
            .get_or_insert_with(|| LabelPainter::new(&gfx.gpu.device, target.format))
            .paint(
                &gfx.gpu,
                &mut encoder,
                &target.view,
                (target.width, target.height),
                &labels,
            );
    }
    target.copy_to_buffer(&mut encoder);
    gfx.gpu.queue.submit([encoder.finish()]);
    let image = target.read(&gfx.gpu.device)?;
    Ok(match scene {
        Some(_) => image,
        None => {
            let [x, y, w, h] = view.rect.pixels();
            image.crop(x, y, w, h)
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Captures at each of `times` in turn; the frames written at each.
    fn film(times: &mut FrameTimes, at: &[f64]) -> Vec<u64> {
        at.iter()
            .map(|&t| {
                let due = times.due(t);
                times.taken(due, t)
            })
            .collect()
    }

    #[test]
    fn a_frame_every_frame_time_of_simulated_time() {
        // 30 fps, steps of 0.02 s from t = 0: frames at 0, 1/30, 2/30, ... Over 1.5 s of
        // steps (the capture after each step) that is 46 frames, t = 0 to 1.5 included.
        let mut times = FrameTimes::new(30.0, 0.0);
        let steps: Vec<f64> = (0..=75).map(|k| k as f64 * 0.02).collect();
        let written = film(&mut times, &steps);
        assert_eq!(written.iter().sum::<u64>(), 46);
        assert!(written.iter().all(|&n| n <= 1), "{written:?}");
        // A step of 0.1 s spans three frame times: three frames of its one image.
        assert_eq!(film(&mut times, &[1.6]), vec![3]);
    }

    #[test]
    fn a_jump_in_time_is_one_frame_and_the_frames_go_on_from_it() {
        let mut times = FrameTimes::new(10.0, 0.0);
        assert_eq!(film(&mut times, &[0.0, 0.5]), vec![1, 5]);
        // A seek forward to t = 3: one frame there, not one per skipped frame time.
        times.resume_at(3.0);
        assert_eq!(film(&mut times, &[3.0, 3.05, 3.1]), vec![1, 0, 1]);
        // A step back to t = 2.9: filmed again from there.
        times.resume_at(2.9);
        assert_eq!(film(&mut times, &[2.9, 3.0, 3.1]), vec![1, 1, 1]);
    }

    #[test]
    fn a_huge_step_writes_at_most_the_cap_and_never_stalls() {
        // At t = 1e15 adding 1/30 leaves the time as it was: summed frame times never passed
        // it and the capture looped for ever.
        let mut times = FrameTimes::new(30.0, 0.0);
        assert_eq!(film(&mut times, &[0.0]), vec![1]);
        let written = film(&mut times, &[1e15, 2e15, 2e15]);
        assert_eq!(
            written,
            vec![MAX_FRAMES_PER_CAPTURE, MAX_FRAMES_PER_CAPTURE, 0]
        );
        assert_eq!(film(&mut times, &[f64::NAN]), vec![0]);
    }
}
