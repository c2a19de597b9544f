//! `tumble view`: the application driving the window. Each frame runs the UI, applies its
//! actions, simulates (capturing the recording's frames), prepares and presents the scene, and
//! books the frame's timing; the parts live in the `window`, `input`, `present`,
//! `window_recording` and `frame_stats` modules.

use super::camera::OrbitCamera;
use super::frame_stats::{FrameClock, FrameStats, Phase};
use super::input::{self, Pointer, Release, Shortcut};
use super::panel::{self, Action, FrameInfo, PanelState, UiFrame};
use super::picking;
use super::present::{self, SceneView};
use super::session::Session;
use super::window::{self, Gfx, ViewRect};
use super::window_recording::Recording;
use crate::{ConstraintsChoice, World};
use anyhow::{Context, bail};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use winit::application::ApplicationHandler;
use winit::event::{ElementState, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow};
use winit::window::WindowId;

/// How `tumble view` was asked to run.
#[derive(Debug, Clone)]
pub struct ViewOptions {
    /// Scene name or path, as given.
    pub scene: String,
    /// Window size in pixels.
    pub width: u32,
    pub height: u32,
    /// Quit after this many frames (with `screenshot`, after writing it).
    pub frames: Option<u64>,
    /// PNG of the whole window written after the last frame (`--frames`) or on exit.
    pub screenshot: Option<PathBuf>,
    pub vsync: bool,
    pub paused: bool,
    /// `YAW,PITCH[,DISTANCE[,X,Y,Z]]`.
    pub camera: Option<String>,
    /// Polled every frame: true once the user asked to quit (Ctrl-C in the terminal).
    pub interrupted: fn() -> bool,
}

/// Opens the viewer on `world` and runs until the window is closed (or `--frames` are done).
pub fn run(world: World, options: ViewOptions) -> anyhow::Result<()> {
    let event_loop = window::open_event_loop()?;
    let mut app = App::new(world, options);
    event_loop
        .run_app(&mut app)
        .context("the window's event loop failed")?;
    if let Some(recording) = app.recording.take() {
        let (path, frames) = recording.finish()?;
        eprintln!("recording: wrote {frames} frames to {}", path.display());
    }
    if let Some(error) = app.error.take() {
        return Err(error);
    }
    if app.options.frames.is_some() {
        app.stats.print_summary(app.session.ratio());
    }
    Ok(())
}

struct App {
    options: ViewOptions,
    session: Session,
    panel: PanelState,
    camera: OrbitCamera,
    camera_framed: bool,
    gfx: Option<Gfx>,
    error: Option<anyhow::Error>,
    pointer: Pointer,
    view_rect: ViewRect,
    stats: FrameStats,
    screenshot_requested: Option<PathBuf>,
    screenshot_counter: u32,
    recording: Option<Recording>,
    repaint_at: Option<Instant>,
    quitting: bool,
}

impl App {
    fn new(world: World, options: ViewOptions) -> App {
        let mut session = Session::new(world, options.scene.clone());
        session.playing = !options.paused;
        App {
            options,
            session,
            panel: PanelState::default(),
            camera: OrbitCamera::default(),
            camera_framed: false,
            gfx: None,
            error: None,
            pointer: Pointer::default(),
            view_rect: ViewRect::INITIAL,
            stats: FrameStats::default(),
            screenshot_requested: None,
            screenshot_counter: 0,
            recording: None,
            repaint_at: None,
            quitting: false,
        }
    }

    fn fail(&mut self, event_loop: &ActiveEventLoop, error: anyhow::Error) {
        self.error.get_or_insert(error);
        event_loop.exit();
    }

    fn quit(&mut self, event_loop: &ActiveEventLoop) {
        self.quitting = true;
        event_loop.exit();
    }

    /// Quits when the user asked to (Ctrl-C in the terminal); returns whether they did.
    fn poll_interrupted(&mut self, event_loop: &ActiveEventLoop) -> bool {
        let interrupted = (self.options.interrupted)();
        if interrupted {
            self.quit(event_loop);
        }
        interrupted
    }

    fn request_redraw(&self) {
        if let Some(gfx) = &self.gfx {
            gfx.window.request_redraw();
        }
    }

    fn frame_camera(&mut self) {
        let (w, h) = self.view_rect.size();
        self.camera.frame(&self.session.world, w / h);
    }

    /// On the first frame, once the view's size is known: frames the scene, then applies
    /// `--camera`.
    fn frame_camera_once(&mut self) -> anyhow::Result<()> {
        if self.camera_framed {
            return Ok(());
        }
        self.frame_camera();
        if let Some(spec) = self.options.camera.clone()
            && let Err(e) = self.camera.apply_spec(&spec)
        {
            bail!(e);
        }
        self.camera_framed = true;
        Ok(())
    }

    /// Selects the body under window position `p` (or none).
    fn pick(&mut self, p: (f64, f64)) {
        let (w, h) = self.view_rect.size();
        let (x, y) = self.view_rect.local(p);
        let (origin, dir) = self.camera.ray(x, y, w, h);
        self.panel.draw.selected = picking::pick(&self.session.world, origin, dir).map(|(i, _)| i);
    }

    fn load_scene(&mut self, scene: &str) {
        let settings = self.session.world.settings.clone();
        match crate::scene::load(scene, &ConstraintsChoice::Auto, settings) {
            Ok(world) => {
                for w in &world.warnings {
                    eprintln!("warning: {w}");
                }
                self.panel.load_error = None;
                self.panel.draw.selected = None;
                self.session.replace(world, scene.to_string());
                if let Some(gfx) = &mut self.gfx {
                    gfx.renderer.set_world(&gfx.gpu.device, &self.session.world);
                    gfx.window.set_title(&format!("tumble — {scene}"));
                }
                self.frame_camera();
            }
            Err(e) => self.panel.load_error = Some(e.to_string()),
        }
    }

    fn handle_action(&mut self, action: Action) {
        match action {
            Action::TogglePlay => self.session.toggle_play(),
            Action::Step => {
                self.session.pause();
                self.session.step_once();
                self.capture_recording_frames();
            }
            Action::Reset => {
                self.session.reset();
                if let Some(recording) = &mut self.recording {
                    recording.rewind();
                }
            }
            Action::FrameScene => self.frame_camera(),
            Action::Screenshot => {
                self.screenshot_counter += 1;
                let name = format!(
                    "tumble-screenshot-{}-{}.png",
                    std::process::id(),
                    self.screenshot_counter
                );
                self.screenshot_requested = Some(PathBuf::from(name));
            }
            Action::Load(scene) => self.load_scene(&scene),
            Action::StartRecording => self.start_recording(),
            Action::StopRecording => self.stop_recording(),
        }
    }

    fn start_recording(&mut self) {
        let path = PathBuf::from(self.panel.record_path.trim());
        let time = self.session.world.time;
        match Recording::start(&path, self.view_rect, self.panel.record_fps, time) {
            Ok(recording) => {
                self.recording = Some(recording);
                self.panel.message = Some(format!("recording to {}", path.display()));
                self.capture_recording_frames();
            }
            Err(message) => self.panel.message = Some(message),
        }
    }

    fn stop_recording(&mut self) {
        if let Some(recording) = self.recording.take() {
            self.panel.message = Some(match recording.finish() {
                Ok((path, frames)) => format!("wrote {frames} frames to {}", path.display()),
                Err(e) => format!("recording failed: {e:#}"),
            });
        }
    }

    /// Captures the frames of the recording due at the current simulated time.
    fn capture_recording_frames(&mut self) {
        let (Some(gfx), Some(recording)) = (&mut self.gfx, &mut self.recording) else {
            return;
        };
        let view = SceneView {
            camera: &self.camera,
            draw: &self.panel.draw,
            rect: self.view_rect,
        };
        if let Err(e) = recording.capture_due(gfx, &self.session.world, view) {
            self.panel.message = Some(format!("recording failed: {e:#}"));
            self.recording = None;
        }
    }

    fn redraw(&mut self, event_loop: &ActiveEventLoop) -> anyhow::Result<()> {
        let mut clock = self.stats.begin_frame();
        self.poll_interrupted(event_loop);
        // UI first: slider changes apply to this frame's steps.
        let Some(ui) = self.run_ui() else {
            return Ok(());
        };
        self.place_view(ui.view, ui.output.pixels_per_point);
        self.frame_camera_once()?;
        for action in ui.actions {
            self.handle_action(action);
        }
        clock.end(Phase::Ui);
        self.simulate(clock.real_dt);
        clock.end(Phase::Simulation);
        let frame = self.prepare_frame(ui.output);
        clock.end(Phase::Upload);
        let screenshot = self.screenshot_due();
        let gfx = self.gfx.as_mut().expect("checked by run_ui");
        let surface_texture = present::acquire(gfx, screenshot.is_some());
        clock.end(Phase::Acquire);
        let repaint_delay = frame.repaint_delay;
        present::submit(
            gfx,
            frame,
            surface_texture,
            screenshot.is_some(),
            self.view_rect,
        );
        if let Some(path) = screenshot {
            self.save_screenshot(&path)?;
        }
        self.finish_frame(clock, event_loop, repaint_delay);
        Ok(())
    }

    /// Runs egui over the panel and the view overlay, with this frame's facts for the panel.
    /// None until the window exists.
    fn run_ui(&mut self) -> Option<UiFrame> {
        let gfx = self.gfx.as_mut()?;
        let raw_input = gfx.egui_state.take_egui_input(&gfx.window);
        let (frame_interval, frame_work) = self.stats.recent_means();
        let adapter = gfx.gpu.description();
        let recording = self.recording.as_ref().map(Recording::status);
        let info = FrameInfo {
            frame_interval,
            frame_work,
            adapter: &adapter,
            msaa: gfx.renderer.sample_count,
            draw_calls: gfx.renderer.body_draw_calls(),
            recording: recording
                .as_ref()
                .map(|(path, frames)| (path.as_str(), *frames)),
        };
        Some(panel::run(
            &gfx.egui_ctx,
            raw_input,
            &mut self.session,
            &mut self.panel,
            &info,
        ))
    }

    /// Takes the view's rectangle from this frame's UI layout (`rect` in points).
    fn place_view(&mut self, rect: egui::Rect, pixels_per_point: f32) {
        if let Some(gfx) = &self.gfx {
            self.view_rect = gfx.view_rect(rect, pixels_per_point);
        }
    }

    /// Steps the simulation by `real_dt` of wall-clock time. A recording samples the state
    /// after the step that reaches each frame's simulated time, so the video plays at
    /// simulated speed whatever the frame rate.
    fn simulate(&mut self, real_dt: f64) {
        let Self {
            session,
            gfx,
            recording,
            camera,
            panel,
            view_rect,
            ..
        } = self;
        let gfx = gfx.as_mut().expect("checked by run_ui");
        let view = SceneView {
            camera,
            draw: &panel.draw,
            rect: *view_rect,
        };
        let mut failure = None;
        session.advance(real_dt, |world| {
            if failure.is_none()
                && let Some(recording) = recording.as_mut()
                && let Err(e) = recording.capture_due(gfx, world, view)
            {
                failure = Some(e);
            }
        });
        if let Some(e) = failure {
            self.panel.message = Some(format!("recording failed: {e:#}"));
            self.recording = None;
        }
    }

    /// The upload phase of the presentation, for this frame's scene and UI.
    fn prepare_frame(&mut self, ui: egui::FullOutput) -> present::PreparedFrame {
        let gfx = self.gfx.as_mut().expect("checked by run_ui");
        let view = SceneView {
            camera: &self.camera,
            draw: &self.panel.draw,
            rect: self.view_rect,
        };
        present::prepare(gfx, &self.session.world, view, ui)
    }

    /// The screenshot to take this frame: one asked for (P, the button), else `--screenshot`
    /// on the last of `--frames`.
    fn screenshot_due(&mut self) -> Option<PathBuf> {
        self.screenshot_requested.take().or_else(|| {
            let last = self
                .options
                .frames
                .is_some_and(|n| self.stats.frames + 1 >= n);
            if last {
                self.options.screenshot.clone()
            } else {
                None
            }
        })
    }

    /// Reads back the window captured by this frame's submit and writes it to `path`.
    fn save_screenshot(&mut self, path: &Path) -> anyhow::Result<()> {
        let Some(gfx) = &self.gfx else { return Ok(()) };
        let Some(capture) = &gfx.capture else {
            return Ok(());
        };
        let image = capture.read(&gfx.gpu.device)?;
        image
            .save_png(path)
            .with_context(|| format!("cannot save the screenshot {}", path.display()))?;
        eprintln!(
            "screenshot: {} ({}x{})",
            path.display(),
            image.width,
            image.height
        );
        self.panel.message = Some(format!("screenshot saved to {}", path.display()));
        Ok(())
    }

    /// Books the frame's timing, quits after `--frames`, and schedules the repaint egui asked for.
    fn finish_frame(
        &mut self,
        clock: FrameClock,
        event_loop: &ActiveEventLoop,
        repaint_delay: Option<Duration>,
    ) {
        self.stats.finish_frame(clock);
        if self.options.frames.is_some_and(|n| self.stats.frames >= n) {
            self.quit(event_loop);
        }
        self.repaint_at = repaint_delay
            .and_then(|d| Instant::now().checked_add(d.min(Duration::from_secs(3600))));
    }

    /// Whether to draw frames back to back rather than wait for events.
    fn continuous(&self) -> bool {
        self.session.playing
            || self.recording.is_some()
            || self.options.frames.is_some()
            || self.pointer.dragging()
    }

    fn on_key(&mut self, key: &winit::keyboard::Key) {
        match input::shortcut(key) {
            Some(Shortcut::Action(action)) => self.handle_action(action),
            Some(Shortcut::Deselect) => self.panel.draw.selected = None,
            None => {}
        }
    }

    fn on_mouse_button(
        &mut self,
        state: ElementState,
        button: winit::event::MouseButton,
        taken_by_ui: bool,
    ) {
        match state {
            ElementState::Pressed => self.pointer.pressed(button, self.view_rect, taken_by_ui),
            ElementState::Released => {
                if let Some(release) = self.pointer.released(button) {
                    if let Release::Pick(p) = release {
                        self.pick(p);
                    }
                    self.request_redraw();
                }
            }
        }
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.gfx.is_some() {
            return;
        }
        let size = (self.options.width, self.options.height);
        let gfx = Gfx::new(
            event_loop,
            &self.options.scene,
            size,
            self.options.vsync,
            &self.session.world,
        );
        match gfx {
            Ok(gfx) => self.gfx = Some(gfx),
            Err(e) => self.fail(event_loop, e),
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let Some(gfx) = &mut self.gfx else { return };
        let response = gfx.egui_state.on_window_event(&gfx.window, &event);
        let over_egui =
            gfx.egui_ctx.is_pointer_over_egui() || gfx.egui_ctx.egui_wants_pointer_input();
        let keyboard_to_egui = gfx.egui_ctx.egui_wants_keyboard_input();
        if response.repaint {
            gfx.window.request_redraw();
        }
        match event {
            WindowEvent::CloseRequested => self.quit(event_loop),
            WindowEvent::Resized(size) if size.width > 0 && size.height > 0 => gfx.resize(size),
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.redraw(event_loop) {
                    self.fail(event_loop, e);
                }
            }
            WindowEvent::ModifiersChanged(m) => self.pointer.shift = m.state().shift_key(),
            WindowEvent::KeyboardInput { event, .. }
                if !response.consumed
                    && !keyboard_to_egui
                    && event.state == ElementState::Pressed =>
            {
                self.on_key(&event.logical_key);
            }
            WindowEvent::CursorMoved { position, .. } => {
                let view_height = self.view_rect.0[3] as f64;
                if self
                    .pointer
                    .moved((position.x, position.y), &mut self.camera, view_height)
                {
                    self.request_redraw();
                }
            }
            WindowEvent::CursorLeft { .. } => self.pointer.cursor = None,
            WindowEvent::MouseInput { state, button, .. } => {
                self.on_mouse_button(state, button, response.consumed || over_egui);
            }
            WindowEvent::MouseWheel { delta, .. }
                if !over_egui && self.pointer.over(self.view_rect) =>
            {
                self.camera.zoom(input::zoom_steps(delta));
                self.request_redraw();
            }
            _ => {}
        }
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        if self.quitting || self.poll_interrupted(event_loop) {
            return;
        }
        let Some(gfx) = &self.gfx else { return };
        if self.continuous() {
            gfx.window.request_redraw();
            event_loop.set_control_flow(ControlFlow::Poll);
        } else if let Some(at) = self.repaint_at {
            if Instant::now() >= at {
                self.repaint_at = None;
                gfx.window.request_redraw();
                event_loop.set_control_flow(ControlFlow::Poll);
            } else {
                event_loop.set_control_flow(ControlFlow::WaitUntil(at));
            }
        } else {
            event_loop.set_control_flow(ControlFlow::Wait);
        }
    }
}
