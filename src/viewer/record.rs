//! Video output: MP4 through `ffmpeg`, GIF with the `gif` crate, or a directory of numbered PNGs,
//! encoded on a background thread; and the offscreen recording loop of `tumble record`.

use super::camera::OrbitCamera;
use super::compare;
use super::gpu::Image;
use super::labels::Label;
use super::renderer::{DrawOptions, OffscreenRenderer};
use crate::io::atomic_file::Unfinished;
pub use crate::io::{partial_path, write_file_atomically};
use crate::{Settings, StepStats, World};
use anyhow::{Context, bail};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::thread::JoinHandle;
use std::time::Instant;

/// What an output path means.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutputKind {
    Mp4,
    Gif,
    /// A directory of `frame_000000.png`, ...
    PngDir,
}

impl OutputKind {
    pub fn of(path: &Path) -> anyhow::Result<OutputKind> {
        let text = path.to_string_lossy();
        if path.is_dir() || text.ends_with('/') || text.ends_with(std::path::MAIN_SEPARATOR) {
            return Ok(OutputKind::PngDir);
        }
        match path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
        {
            Some(e) if e == "mp4" => Ok(OutputKind::Mp4),
            Some(e) if e == "gif" => Ok(OutputKind::Gif),
            None => Ok(OutputKind::PngDir),
            Some(e) => bail!(
                "cannot record to '{}': unknown extension .{e}; use .mp4, .gif, or a directory for PNG frames",
                path.display()
            ),
        }
    }
}

/// Whether an `ffmpeg` executable is on PATH.
pub fn ffmpeg_on_path() -> bool {
    std::env::var_os("PATH")
        .is_some_and(|paths| std::env::split_paths(&paths).any(|dir| dir.join("ffmpeg").is_file()))
}

trait Encoder: Send {
    fn frame(&mut self, image: &mut Image) -> anyhow::Result<()>;
    fn finish(self: Box<Self>) -> anyhow::Result<()>;
}

struct GifEncoder {
    encoder: gif::Encoder<std::io::BufWriter<std::fs::File>>,
    path: PathBuf,
    tmp: Unfinished,
    fps: f64,
    frames: u64,
    centiseconds: u64,
}

impl GifEncoder {
    /// Writes into `path`'s partial file, renamed into place by [`Encoder::finish`].
    fn create(path: &Path, width: u32, height: u32, fps: f64) -> anyhow::Result<GifEncoder> {
        // Listed before it exists, so that no exit finds it there unlisted.
        let tmp = Unfinished::new(&partial_path(path));
        let file = std::fs::File::create(tmp.path()).with_context(|| {
            format!(
                "cannot write {} (as {} first)",
                path.display(),
                tmp.path().display()
            )
        })?;
        let mut encoder = gif::Encoder::new(
            std::io::BufWriter::new(file),
            width as u16,
            height as u16,
            &[],
        )
        .with_context(|| format!("cannot write {}", path.display()))?;
        encoder
            .set_repeat(gif::Repeat::Infinite)
            .with_context(|| format!("cannot write {}", path.display()))?;
        Ok(GifEncoder {
            encoder,
            path: path.to_path_buf(),
            tmp,
            fps,
            frames: 0,
            centiseconds: 0,
        })
    }
}

impl Encoder for GifEncoder {
    fn frame(&mut self, image: &mut Image) -> anyhow::Result<()> {
        let mut frame = gif::Frame::from_rgba_speed(
            image.width as u16,
            image.height as u16,
            &mut image.rgba,
            10,
        );
        // GIF delays are whole centiseconds: round the frame's end time, so 30 fps alternates 3
        // and 4 cs and stays in step.
        self.frames += 1;
        let end = (self.frames as f64 * 100.0 / self.fps).round() as u64;
        frame.delay = (end - self.centiseconds).clamp(1, u16::MAX as u64) as u16;
        self.centiseconds = end;
        self.encoder
            .write_frame(&frame)
            .with_context(|| format!("cannot write {}", self.path.display()))
    }

    fn finish(self: Box<Self>) -> anyhow::Result<()> {
        let GifEncoder {
            encoder, path, tmp, ..
        } = *self;
        let written = || format!("cannot write {}", path.display());
        let mut writer = encoder.into_inner().with_context(written)?;
        writer.flush().with_context(written)?;
        drop(writer);
        move_into_place(tmp, &path)
    }
}

struct PngDirEncoder {
    dir: PathBuf,
    frames: u64,
}

impl PngDirEncoder {
    /// Creates the directory. The frames of an earlier recording, which would mix with this
    /// one's, go when the first frame comes: a recording that ends before it (an error, an
    /// interrupt, a window recording stopped at once) leaves the earlier one whole.
    fn create(path: &Path) -> anyhow::Result<PngDirEncoder> {
        std::fs::create_dir_all(path)
            .with_context(|| format!("cannot create directory {}", path.display()))?;
        Ok(PngDirEncoder {
            dir: path.to_path_buf(),
            frames: 0,
        })
    }
}

/// Frame k of a folder recording is `frame_` and k in six digits or more, `.png`.
const FRAME_PREFIX: &str = "frame_";
const FRAME_DIGITS: usize = 6;

/// The name of frame `k` of a folder recording.
fn frame_name(k: u64) -> String {
    format!("{FRAME_PREFIX}{k:0FRAME_DIGITS$}.png")
}

/// Whether `name` is one that [`frame_name`] gives, and no other (a user's `frame_intro.png` or
/// `frame_1.png` is not).
fn is_frame_name(name: &str) -> bool {
    let digits = (name.strip_prefix(FRAME_PREFIX)).and_then(|n| n.strip_suffix(".png"));
    digits.is_some_and(|d| d.len() >= FRAME_DIGITS && d.bytes().all(|b| b.is_ascii_digit()))
}

/// The frames an earlier recording left in `folder` ([`is_frame_name`]), which a new one
/// replaces.
fn earlier_frames(folder: &Path) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(folder) else {
        return Vec::new(); // Not there yet.
    };
    entries
        .flatten()
        .filter(|entry| entry.file_name().to_str().is_some_and(is_frame_name))
        .map(|entry| entry.path())
        .collect()
}

/// The file or folder a recording to `path` writes, never over one of `inputs` (the files the
/// run reads): a video where a link leads ([`crate::io::check_output`]), a folder of frames as
/// it is ([`check_frames_folder`]).
pub fn check_recording_output(path: &Path, inputs: &[PathBuf]) -> anyhow::Result<PathBuf> {
    match OutputKind::of(path)? {
        OutputKind::PngDir => check_frames_folder(path, inputs).map(|()| path.to_path_buf()),
        _ => crate::io::check_output(path, inputs),
    }
}

/// `path`, or where something is there already the first of `name-2.ext`, `name-3.ext`, ...
/// that is free (`name-2` for a folder of frames, whatever dots its name has): the panel's
/// Record button keeps earlier recordings (a second recording to the panel's name replaced the
/// first without a word). None when every name up to [`MAX_NUMBERED_NAMES`] is taken.
pub fn unused_name(path: &Path) -> Option<PathBuf> {
    let taken = |p: &Path| std::fs::symlink_metadata(p).is_ok();
    if !taken(path) {
        return Some(path.to_path_buf());
    }
    let name = path.file_name()?.to_string_lossy();
    let folder = matches!(OutputKind::of(path), Ok(OutputKind::PngDir));
    let (stem, extension) = match name.rfind('.') {
        Some(dot) if dot > 0 && !folder => name.split_at(dot),
        _ => (name.as_ref(), ""),
    };
    let numbered = |k: u32| {
        let mut numbered = path.with_file_name(format!("{stem}-{k}{extension}"));
        if folder {
            // Still a folder to `OutputKind::of` (`shots.v1-2` would be a .v1-2 file).
            numbered
                .as_mut_os_string()
                .push(std::path::MAIN_SEPARATOR_STR);
        }
        numbered
    };
    (2..=MAX_NUMBERED_NAMES).map(numbered).find(|p| !taken(p))
}

/// Most numbered names [`unused_name`] tries.
const MAX_NUMBERED_NAMES: u32 = 10_000;

/// Refuses to record frames into `folder` where one of the frames it would replace is one of
/// `inputs`, the files the run reads. Only a frame that is the input's own file counts: the
/// frames are unlinked, which leaves a file that a link named like a frame leads to, or that
/// has another name too, as it was.
fn check_frames_folder(folder: &Path, inputs: &[PathBuf]) -> anyhow::Result<()> {
    let read: Vec<PathBuf> = inputs
        .iter()
        .filter_map(|p| std::fs::canonicalize(p).ok())
        .collect();
    for frame in earlier_frames(folder) {
        let own_file = std::fs::symlink_metadata(&frame).is_ok_and(|m| m.is_file());
        if let Some(real) = own_file
            .then(|| std::fs::canonicalize(&frame).ok())
            .flatten()
            && read.contains(&real)
        {
            bail!(
                "cannot record into {}: it would replace {}, which this run reads",
                folder.display(),
                frame.display()
            );
        }
    }
    Ok(())
}

impl Encoder for PngDirEncoder {
    fn frame(&mut self, image: &mut Image) -> anyhow::Result<()> {
        if self.frames == 0 {
            for frame in earlier_frames(&self.dir) {
                let _ = std::fs::remove_file(frame);
            }
        }
        let path = self.dir.join(frame_name(self.frames));
        self.frames += 1;
        image.save_png(&path)
    }

    fn finish(self: Box<Self>) -> anyhow::Result<()> {
        Ok(())
    }
}

struct Mp4Encoder {
    child: std::process::Child,
    stdin: Option<std::process::ChildStdin>,
    path: PathBuf,
    /// Removed, when dropped unfinished, after ffmpeg has stopped writing it.
    tmp: Option<Unfinished>,
}

impl Mp4Encoder {
    /// Starts `ffmpeg` reading raw RGBA frames on its standard input and writing H.264 into
    /// `path`'s partial file, renamed into place by [`Encoder::finish`].
    fn spawn(path: &Path, width: u32, height: u32, fps: f64) -> anyhow::Result<Mp4Encoder> {
        let tmp = partial_path(path);
        let mut command = std::process::Command::new("ffmpeg");
        command
            .args([
                "-hide_banner",
                "-loglevel",
                "error",
                "-y",
                "-f",
                "rawvideo",
                "-pixel_format",
                "rgba",
                "-video_size",
            ])
            .arg(format!("{width}x{height}"))
            .arg("-framerate")
            .arg(format!("{fps}"))
            .args([
                "-i",
                "-",
                "-c:v",
                "libx264",
                "-preset",
                "veryfast",
                "-pix_fmt",
                "yuv420p",
                "-movflags",
                "+faststart",
                "-f",
                "mp4",
            ])
            .arg(&tmp)
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::null());
        // Its own process group: Ctrl-C in the terminal reaches tumble only, which then closes
        // ffmpeg's input so the file is finished properly.
        #[cfg(unix)]
        std::os::unix::process::CommandExt::process_group(&mut command, 0);
        let mut child = command.spawn().context("cannot start ffmpeg")?;
        let stdin = child.stdin.take();
        Ok(Mp4Encoder {
            child,
            stdin,
            path: path.to_path_buf(),
            tmp: Some(Unfinished::new(&tmp)),
        })
    }
}

impl Encoder for Mp4Encoder {
    fn frame(&mut self, image: &mut Image) -> anyhow::Result<()> {
        let stdin = self.stdin.as_mut().expect("open until finish");
        stdin.write_all(&image.rgba).with_context(|| {
            format!(
                "ffmpeg stopped accepting the frames of {} (see its messages above)",
                self.path.display()
            )
        })
    }

    fn finish(mut self: Box<Self>) -> anyhow::Result<()> {
        drop(self.stdin.take());
        let status = self.child.wait().context("cannot wait for ffmpeg")?;
        if !status.success() {
            bail!("ffmpeg failed ({status}) writing {}", self.path.display());
        }
        match self.tmp.take() {
            Some(tmp) => move_into_place(tmp, &self.path),
            None => Ok(()),
        }
    }
}

/// Renames a finished partial file to `path`.
fn move_into_place(tmp: Unfinished, path: &Path) -> anyhow::Result<()> {
    std::fs::rename(tmp.path(), path)
        .with_context(|| format!("cannot move {} to {}", tmp.path().display(), path.display()))?;
    tmp.keep();
    Ok(())
}

impl Drop for Mp4Encoder {
    fn drop(&mut self) {
        if self.stdin.is_some() {
            drop(self.stdin.take());
            let _ = self.child.wait();
        }
    }
}

/// Frames go to an encoder thread through a short queue, so rendering and encoding overlap.
pub struct FrameWriter {
    pub path: PathBuf,
    pub kind: OutputKind,
    pub width: u32,
    pub height: u32,
    sender: Option<SyncSender<Queued>>,
    thread: Option<JoinHandle<anyhow::Result<f64>>>,
    /// Seconds the encoder thread spent encoding, known after [`Self::finish`].
    pub encode_s: f64,
    pub frames: u64,
}

impl FrameWriter {
    /// Checks that `path` can take `width` x `height` frames at `fps` (format known, ffmpeg
    /// present for MP4, sizes allowed, parent directory present) without creating anything.
    pub fn check(path: &Path, width: u32, height: u32, fps: f64) -> anyhow::Result<OutputKind> {
        let kind = OutputKind::of(path)?;
        anyhow::ensure!(width > 0 && height > 0, "the frame size must not be empty");
        anyhow::ensure!(
            fps.is_finite() && fps > 0.0,
            "the frame rate must be positive, got {fps}"
        );
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty())
            && kind != OutputKind::PngDir
        {
            anyhow::ensure!(
                parent.is_dir(),
                "cannot write {}: directory {} does not exist",
                path.display(),
                parent.display()
            );
        }
        match kind {
            OutputKind::Gif => {
                anyhow::ensure!(
                    width <= u16::MAX as u32 && height <= u16::MAX as u32,
                    "GIF frames are at most 65535 pixels wide and tall"
                );
                // A GIF's frame lasts at most 65535 centiseconds: slower rates were cut to that
                // in silence, while the closing line gave the length asked for.
                anyhow::ensure!(
                    fps >= MIN_GIF_FPS,
                    "--fps {}: a GIF shows a frame for at most 655.35 s, so it takes at least \
                     {} frames a second",
                    crate::io::echoed(fps),
                    crate::io::significant(MIN_GIF_FPS, 3)
                );
            }
            OutputKind::Mp4 => {
                // ffmpeg reads the rate as a decimal: 1e-300 came out as three hundred digits it
                // would not parse.
                anyhow::ensure!(
                    fps >= MIN_MP4_FPS,
                    "--fps {fps:e}: an MP4 takes at least {MIN_MP4_FPS} frames a second"
                );
                if !ffmpeg_on_path() {
                    bail!(
                        "cannot write {}: ffmpeg is not on PATH. Install it (e.g. `apt-get install ffmpeg`), or record to a .gif or to a directory of PNG frames",
                        path.display()
                    );
                }
                anyhow::ensure!(
                    width.is_multiple_of(2) && height.is_multiple_of(2),
                    "MP4 (H.264, yuv420p) needs an even width and height, got {width}x{height}"
                );
            }
            OutputKind::PngDir => anyhow::ensure!(
                !path.exists() || path.is_dir(),
                "cannot record frames into {}: it is a file (a path without an extension is a \
                 folder of PNG frames; end it in .mp4 or .gif for a video)",
                path.display()
            ),
        }
        Ok(kind)
    }

    /// Opens `path` for `width` x `height` frames shown `fps` times per second.
    pub fn create(path: &Path, width: u32, height: u32, fps: f64) -> anyhow::Result<FrameWriter> {
        let kind = Self::check(path, width, height, fps)?;
        let encoder: Box<dyn Encoder> = match kind {
            OutputKind::Gif => Box::new(GifEncoder::create(path, width, height, fps)?),
            OutputKind::PngDir => Box::new(PngDirEncoder::create(path)?),
            OutputKind::Mp4 => Box::new(Mp4Encoder::spawn(path, width, height, fps)?),
        };
        let (sender, receiver) = sync_channel::<Queued>(4);
        let thread = std::thread::Builder::new()
            .name("tumble-encoder".into())
            .spawn(move || encode(encoder, receiver))?;
        Ok(FrameWriter {
            path: path.to_path_buf(),
            kind,
            width,
            height,
            sender: Some(sender),
            thread: Some(thread),
            encode_s: 0.0,
            frames: 0,
        })
    }

    /// Queues one frame; blocks while the encoder is behind.
    pub fn push(&mut self, image: Image) -> anyhow::Result<()> {
        anyhow::ensure!(
            image.width == self.width && image.height == self.height,
            "frame size changed during the recording"
        );
        let sent = self
            .sender
            .as_ref()
            .is_some_and(|s| s.send(Queued::Frame(image)).is_ok());
        if !sent {
            // The encoder thread stopped: report why.
            return Err(self
                .join()
                .err()
                .unwrap_or_else(|| anyhow::anyhow!("the encoder stopped")));
        }
        self.frames += 1;
        Ok(())
    }

    /// Waits for the encoder thread; an error once it had already stopped on one (the
    /// recording was abandoned and its file removed, see [`FrameWriter::push`]).
    fn join(&mut self) -> anyhow::Result<()> {
        drop(self.sender.take());
        let Some(thread) = self.thread.take() else {
            bail!("the recording had already stopped on an error; its file was removed");
        };
        self.encode_s = thread
            .join()
            .map_err(|_| anyhow::anyhow!("the encoder thread panicked"))??;
        Ok(())
    }

    /// Encodes the queued frames and closes the file. Returns the number of frames written and
    /// the seconds the encoder thread spent encoding them.
    pub fn finish(mut self) -> anyhow::Result<(u64, f64)> {
        if let Some(sender) = &self.sender {
            // A send fails only where the encoder stopped on an error, which the join reports.
            let _ = sender.send(Queued::Finish);
        }
        self.join()?;
        Ok((self.frames, self.encode_s))
    }
}

/// Dropped without [`FrameWriter::finish`] (an error on the way), the recording is abandoned: a
/// video's partial file is removed rather than moved into place as if complete.
impl Drop for FrameWriter {
    fn drop(&mut self) {
        let _ = self.join();
    }
}

/// What the encoder thread is sent: a frame, or the word to close the file.
enum Queued {
    Frame(Image),
    Finish,
}

fn encode(mut encoder: Box<dyn Encoder>, queue: Receiver<Queued>) -> anyhow::Result<f64> {
    let mut busy = 0.0;
    for queued in queue {
        let start = Instant::now();
        match queued {
            Queued::Frame(mut image) => encoder.frame(&mut image)?,
            Queued::Finish => {
                encoder.finish()?;
                return Ok(busy + start.elapsed().as_secs_f64());
            }
        }
        busy += start.elapsed().as_secs_f64();
    }
    Ok(busy) // Abandoned: the encoder's partial file goes with it.
}

/// Settings of an offscreen recording.
#[derive(Debug, Clone)]
pub struct RecordOptions {
    pub output: PathBuf,
    /// Simulated seconds to record.
    pub seconds: f64,
    pub fps: f64,
    pub width: u32,
    pub height: u32,
    /// `YAW,PITCH[,DISTANCE[,X,Y,Z]]` over the framed scene, or `orbit`.
    pub camera: Option<String>,
    pub draw: DrawOptions,
    /// Settings of a second world of the scene stepped alongside and drawn with it (panes side
    /// by side or a ghost, as `draw.layout` says), each labelled.
    pub compare: Option<Settings>,
}

/// Fewest frames a second an MP4 is recorded at.
const MIN_MP4_FPS: f64 = 0.01;

/// Lowest frame rate of a GIF: a frame lasts at most 65535 centiseconds.
const MIN_GIF_FPS: f64 = 100.0 / 65535.0;

/// Most steps a recording takes (of each world).
const MAX_RECORD_STEPS: f64 = 1e8;

/// Most frames a recording makes: 93 hours at 30 fps. `--seconds 2e6` at the defaults asked
/// for 6e7 frames (a folder of PNGs to fill a disk), with no word before it began.
const MAX_RECORD_FRAMES: f64 = 1e7;

/// Rejects a length, frame rate and time steps (the world's, and the compared world's where
/// there is one) that cannot make a recording.
pub fn check_rates(
    seconds: f64,
    fps: f64,
    (dt, compared): (f64, Option<f64>),
) -> anyhow::Result<()> {
    anyhow::ensure!(
        seconds.is_finite() && seconds >= 0.0,
        "--seconds must be a non-negative number, got {seconds}"
    );
    let named = std::iter::once(("", dt)).chain(compared.map(|dt| ("--compare: ", dt)));
    for (world, dt) in named {
        anyhow::ensure!(
            dt.is_finite() && dt > 0.0,
            "{world}the time step must be positive to record, got {}",
            crate::io::echoed(dt)
        );
        // --dt 5e-324 stepped for ever (time plus the step is the time again), past Ctrl-C,
        // which is asked between frames.
        let steps = seconds / dt;
        // (Not three hundred digits for --seconds 1e300 or --dt 5e-324, nor a flag the user
        // did not give.)
        let short = |x: f64| crate::io::significant(x, 6);
        anyhow::ensure!(
            steps <= MAX_RECORD_STEPS,
            "{world}recording {} s takes {steps:.1e} steps of {} s, more than \
             {MAX_RECORD_STEPS:.0e}: record fewer --seconds or take a longer --dt",
            short(seconds),
            short(dt)
        );
    }
    anyhow::ensure!(
        fps.is_finite() && fps > 0.0 && fps <= 1000.0,
        "--fps must lie in (0, 1000], got {}",
        crate::io::echoed(fps)
    );
    let frames = seconds * fps;
    anyhow::ensure!(
        frames <= MAX_RECORD_FRAMES,
        "recording {} s at {} fps makes {frames:.1e} frames, more than {MAX_RECORD_FRAMES:.0e}: \
         record fewer --seconds or at a lower --fps",
        crate::io::significant(seconds, 6),
        crate::io::significant(fps, 6)
    );
    Ok(())
}

/// The share of a recording's frames that show the same step as the frame before: frame k
/// shows the step nearest k / fps, and at more frames than steps a second some share one.
pub fn repeated_frame_share(fps: f64, dt: f64) -> f64 {
    (1.0 - 1.0 / (fps * dt)).max(0.0)
}

impl RecordOptions {
    /// Rejects settings that cannot make a recording, with simulation time step `dt`.
    fn check(&self, dt: f64) -> anyhow::Result<()> {
        let compared = self.compare.as_ref().map(|s| s.time_step);
        check_rates(self.seconds, self.fps, (dt, compared))
    }

    /// The camera over `world`: framed for one pane, then as `camera` says.
    fn camera(&self, world: &World, panes_of: usize) -> anyhow::Result<(OrbitCamera, bool)> {
        let mut camera = OrbitCamera::default();
        let aspect = compare::pane_aspect(
            self.width as f64,
            self.height as f64,
            panes_of,
            self.draw.layout,
        );
        camera.frame(world, aspect);
        match self.camera.as_deref().map(str::trim) {
            Some("orbit") => Ok((camera, true)),
            Some(spec) => {
                camera.apply_spec(spec).map_err(anyhow::Error::msg)?;
                Ok((camera, false))
            }
            None => Ok((camera, false)),
        }
    }
}

#[derive(Debug, Clone)]
pub struct RecordReport {
    pub frames: u64,
    /// Steps of the first world.
    pub steps: u64,
    pub sim_time: f64,
    pub wall_s: f64,
    /// Seconds stepping the simulation (every world).
    pub simulate_s: f64,
    /// Seconds rendering and reading frames back.
    pub render_s: f64,
    /// Seconds waiting for the encoder (queue full) and finishing the file.
    pub encode_wait_s: f64,
    /// Seconds the encoder thread worked (in parallel with rendering).
    pub encode_s: f64,
    /// Stopped early by Ctrl-C; the frames so far were written.
    pub interrupted: bool,
    pub adapter: String,
    /// Bodies of each world (the first, then the compared one) that blew up and were frozen.
    pub frozen: Vec<usize>,
}

/// The worlds being recorded, each with its last step's statistics.
struct Recorded {
    worlds: Vec<(World, StepStats)>,
    layout: compare::Layout,
}

impl Recorded {
    /// Steps every world up to simulated time `time` (within half its step); returns the first
    /// world's steps.
    fn step_to(&mut self, time: f64) -> u64 {
        let mut first_steps = 0;
        for (k, (world, last)) in self.worlds.iter_mut().enumerate() {
            let dt = world.settings.time_step;
            while world.time < time - 0.5 * dt {
                *last = world.step();
                first_steps += (k == 0) as u64;
            }
        }
        first_steps
    }

    fn worlds(&self) -> Vec<&World> {
        self.worlds.iter().map(|(w, _)| w).collect()
    }

    /// Labels naming the worlds, when there is more than one.
    fn labels(&self, width: u32, height: u32) -> Vec<Label> {
        if self.worlds.len() < 2 {
            return Vec::new();
        }
        let worlds: Vec<(&World, &StepStats)> = self.worlds.iter().map(|(w, s)| (w, s)).collect();
        Label::for_panes(
            [0.0, 0.0, width as f32, height as f32],
            &worlds,
            self.layout,
        )
    }
}

/// Renders `options.seconds` of simulation at a fixed rate (frame k shows time k / fps,
/// whatever the rendering speed) into `options.output`; with `options.compare`, a second world
/// of the scene beside (or over) it. `progress(done, total)` is called after each frame; when
/// `interrupted()` turns true the frames so far are finished into a valid file.
pub fn record(
    world: World,
    options: &RecordOptions,
    progress: &mut dyn FnMut(u64, u64),
    interrupted: &dyn Fn() -> bool,
) -> anyhow::Result<RecordReport> {
    let start = Instant::now();
    options.check(world.settings.time_step)?;
    let frames = ((options.seconds * options.fps).round() as u64).max(1);
    let panes = 1 + options.compare.is_some() as usize;
    let (mut camera, orbit) = options.camera(&world, panes)?;
    FrameWriter::check(&options.output, options.width, options.height, options.fps)?;
    let mut offscreen = OffscreenRenderer::new(&world, options.width, options.height)?;
    let mut writer =
        FrameWriter::create(&options.output, options.width, options.height, options.fps)?;
    let mut report = RecordReport {
        frames: 0,
        steps: 0,
        sim_time: 0.0,
        wall_s: 0.0,
        simulate_s: 0.0,
        render_s: 0.0,
        encode_wait_s: 0.0,
        encode_s: 0.0,
        interrupted: false,
        adapter: offscreen.gpu.description(),
        frozen: Vec::new(),
    };
    let start_time = world.time;
    let yaw = camera.yaw;
    let mut recorded = Recorded {
        worlds: compared_worlds(world, options.compare.as_ref()),
        layout: options.draw.layout,
    };
    for k in 0..frames {
        if interrupted() {
            report.interrupted = true;
            break;
        }
        let t = Instant::now();
        report.steps += recorded.step_to(start_time + k as f64 / options.fps);
        report.simulate_s += t.elapsed().as_secs_f64();
        if orbit {
            // One turn over the recording: the loop of a GIF closes.
            camera.yaw = yaw + std::f64::consts::TAU * k as f64 / frames as f64;
        }
        let t = Instant::now();
        let labels = recorded.labels(options.width, options.height);
        let image = offscreen.render_worlds(&recorded.worlds(), &camera, &options.draw, &labels)?;
        report.render_s += t.elapsed().as_secs_f64();
        let t = Instant::now();
        writer.push(image)?;
        report.encode_wait_s += t.elapsed().as_secs_f64();
        report.frames += 1;
        progress(k + 1, frames);
    }
    let t = Instant::now();
    // Interrupted before its first frame, a video would be a file with no picture: none is left.
    if report.frames > 0 || !report.interrupted {
        report.encode_s = writer.finish()?.1;
    }
    report.encode_wait_s += t.elapsed().as_secs_f64();
    report.sim_time = recorded.worlds[0].0.time - start_time;
    report.frozen = (recorded.worlds.iter())
        .map(|(w, _)| w.bodies.iter().filter(|b| b.quarantined).count())
        .collect();
    report.wall_s = start.elapsed().as_secs_f64();
    Ok(report)
}

/// `world`, and a copy of it with the `compare` settings when given.
fn compared_worlds(world: World, compare: Option<&Settings>) -> Vec<(World, StepStats)> {
    let second = compare.map(|settings| {
        let mut w = world.clone();
        w.settings = settings.clone();
        (w, StepStats::default())
    });
    std::iter::once((world, StepStats::default()))
        .chain(second)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An empty folder of the temporary directory for one test (`name`).
    fn fresh_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("tumble-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn unused_name_numbers_a_taken_file_or_folder() {
        let dir = fresh_dir("unused");
        let video = dir.join("run.mp4");
        assert_eq!(unused_name(&video), Some(video.clone()));
        std::fs::write(&video, "first").unwrap();
        assert_eq!(unused_name(&video), Some(dir.join("run-2.mp4")));
        std::fs::write(dir.join("run-2.mp4"), "second").unwrap();
        assert_eq!(unused_name(&video), Some(dir.join("run-3.mp4")));
        for folder in ["frames", "shots.v1"] {
            std::fs::create_dir_all(dir.join(folder)).unwrap();
            let numbered = unused_name(&dir.join(format!("{folder}/"))).unwrap();
            assert_eq!(numbered, dir.join(format!("{folder}-2")));
            assert!(matches!(OutputKind::of(&numbered), Ok(OutputKind::PngDir)));
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A new recording replaces the frames an earlier one wrote, past a million too, and no
    /// other file (checked without a GPU; `tests/record_cli.rs` records into a folder).
    #[test]
    fn only_the_frames_a_recording_names_are_replaced() {
        for k in [0, 7, 999_999, 1_000_000] {
            assert!(is_frame_name(&frame_name(k)), "{}", frame_name(k));
        }
        assert_eq!(frame_name(12), "frame_000012.png");
        let theirs = [
            "frame_intro.png",
            "frame_1.png",
            "frame_00001.png",
            "frame_000001.PNG",
        ];
        for name in theirs
            .into_iter()
            .chain(["frame_0000x1.png", "frame_.png", "x_000001.png"])
        {
            assert!(!is_frame_name(name), "{name}");
        }
    }

    #[test]
    fn output_kinds() {
        assert_eq!(OutputKind::of(Path::new("a.mp4")).unwrap(), OutputKind::Mp4);
        assert_eq!(OutputKind::of(Path::new("a.GIF")).unwrap(), OutputKind::Gif);
        assert_eq!(
            OutputKind::of(Path::new("frames/")).unwrap(),
            OutputKind::PngDir
        );
        assert_eq!(
            OutputKind::of(Path::new("frames")).unwrap(),
            OutputKind::PngDir
        );
        assert!(OutputKind::of(Path::new("a.avi")).is_err());
    }

    /// What a recording cannot be is refused before it starts, saying why: a GIF slower than
    /// its longest frame (65535 cs; cut to it in silence before), a folder of frames where a
    /// file is, a compared world's time step named as the compared one's.
    #[test]
    fn what_cannot_be_recorded_is_refused_saying_why() {
        let dir = fresh_dir("refused");
        let gif = dir.join("slow.gif");
        let slow = FrameWriter::check(&gif, 32, 32, 0.0015).unwrap_err();
        assert!(slow.to_string().contains("at most 655.35 s"), "{slow}");
        assert!(FrameWriter::check(&gif, 32, 32, 0.0016).is_ok());
        let file = dir.join("plainfile");
        std::fs::write(&file, "not a folder").unwrap();
        let into_file = FrameWriter::check(&file, 32, 32, 30.0).unwrap_err();
        assert!(
            into_file.to_string().contains("it is a file"),
            "{into_file}"
        );
        let compared = check_rates(1.0, 30.0, (0.02, Some(0.0))).unwrap_err();
        assert!(
            compared.to_string().starts_with("--compare: "),
            "{compared}"
        );
        assert!(check_rates(1.0, 30.0, (0.02, Some(0.01))).is_ok());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A folder recording replaces an earlier one's frames when its first frame comes, not
    /// before: one that ends without a frame leaves them (it removed them as it began).
    #[test]
    fn a_folder_recording_without_a_frame_keeps_the_earlier_frames() {
        let dir = fresh_dir("folder");
        let earlier: Vec<String> = (0..3).map(frame_name).collect();
        for name in earlier.iter().chain(["notes.txt".to_string()].iter()) {
            std::fs::write(dir.join(name), b"earlier").unwrap();
        }
        let listed = || {
            let mut names: Vec<(String, u64)> = (std::fs::read_dir(&dir).unwrap().flatten())
                .map(|e| {
                    (
                        e.file_name().to_string_lossy().into_owned(),
                        e.metadata().unwrap().len(),
                    )
                })
                .collect();
            names.sort();
            names
        };
        drop(FrameWriter::create(&dir, 4, 2, 10.0).unwrap());
        let kept = listed();
        let mut writer = FrameWriter::create(&dir, 4, 2, 10.0).unwrap();
        let image = Image {
            width: 4,
            height: 2,
            rgba: vec![200; 32],
        };
        writer.push(image).unwrap();
        writer.finish().unwrap();
        let replaced = listed();
        let _ = std::fs::remove_dir_all(&dir);
        let names =
            |list: &[(String, u64)]| list.iter().map(|(n, _)| n.clone()).collect::<Vec<_>>();
        assert_eq!(
            names(&kept),
            [&earlier[..], &["notes.txt".to_string()]].concat()
        );
        assert!(kept.iter().all(|(_, len)| *len == 7), "{kept:?}");
        assert_eq!(names(&replaced), [frame_name(0), "notes.txt".to_string()]);
        assert_ne!(replaced[0].1, 7, "frame 0 is the new recording's");
    }

    /// A recording finished is in place and nothing else; one dropped unfinished (an error on
    /// the way) leaves neither the video nor its partial file, where it used to be moved into
    /// place as if complete.
    #[test]
    fn an_abandoned_recording_leaves_no_file() {
        let dir = fresh_dir("frames");
        let frame = || Image {
            width: 4,
            height: 2,
            rgba: vec![200; 32],
        };
        let (finished, abandoned) = (dir.join("finished.gif"), dir.join("abandoned.gif"));
        let mut writer = FrameWriter::create(&finished, 4, 2, 10.0).unwrap();
        writer.push(frame()).unwrap();
        assert_eq!(writer.finish().unwrap().0, 1);
        let mut writer = FrameWriter::create(&abandoned, 4, 2, 10.0).unwrap();
        writer.push(frame()).unwrap();
        writer.push(frame()).unwrap();
        drop(writer);
        let mut names: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        let _ = std::fs::remove_dir_all(&dir);
        assert_eq!(names, ["finished.gif"]);
    }
}
