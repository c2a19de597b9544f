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
    fps: f64,
    /// Simulated time of the next frame to capture.
    next: f64,
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
                fps,
                next: time,
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

    /// After a reset of the simulation: the next frame is the one at time 0.
    pub fn rewind(&mut self) {
        self.next = 0.0;
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
        let world = &lanes[0].world;
        if world.time + 1e-9 < self.next {
            return Ok(());
        }
        let image = render_view(gfx, lanes, view, &mut self.labels)?;
        let frame = image.crop(0, 0, self.width, self.height);
        anyhow::ensure!(
            frame.width == self.width && frame.height == self.height,
            "the window shrank during the recording"
        );
        while world.time + 1e-9 >= self.next {
            self.writer.push(frame.clone())?;
            self.next += 1.0 / self.fps;
        }
        Ok(())
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
