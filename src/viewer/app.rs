//! `tumble view`: the application driving the window. Each frame runs the UI, applies its
//! actions, simulates (capturing the recording's frames), prepares and presents the scene, and
//! books the frame's timing; between frames it polls the scene's files. The parts live in the
//! `window`, `input`, `present`, `window_recording` and `frame_stats` modules; picking and
//! grabbing through the view's panes in `view_pointer`.

use super::camera::OrbitCamera;
use super::compare::{self, Layout};
use super::frame_stats::{FrameClock, FrameStats, Phase};
use super::grab::DragPlane;
use super::input::{self, Pointer, Release, Shortcut};
use super::panel::{self, Action, FrameInfo, PanelState, UiFrame};
use super::picking;
use super::present::{self, SceneView};
use super::scene_source::SceneSource;
use super::session::Session;
use super::view_pointer::{self, GrabDrag};
use super::window::{self, Gfx, ViewRect};
use super::window_recording::Recording;
use crate::{ConstraintsChoice, Settings, World};
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
    /// The constraints the scene was loaded with (kept when it is reloaded).
    pub constraints: ConstraintsChoice,
    /// `--compare`: a preset or settings flags for a second world stepped alongside.
    pub compare: Option<String>,
    /// How compared worlds share the view.
    pub layout: Layout,
    /// Shadows on at the start.
    pub shadows: bool,
    /// Start with fixed bodies shown (a panel toggle).
    pub fixed_bodies: bool,
    /// Turns a compare spec into settings: the command line's own parser (the viewer cannot
    /// depend on it).
    pub parse_settings: fn(&str) -> Result<Settings, String>,
}

/// How often the scene's files are polled for changes.
const FILE_POLL: Duration = Duration::from_millis(500);

/// Opens the viewer on `world` and runs until the window is closed (or `--frames` are done).
pub fn run(world: World, options: ViewOptions) -> anyhow::Result<()> {
    let mut app = App::new(world, options);
    if let Some(spec) = &app.options.compare {
        let settings = (app.compared_settings(spec))
            .map_err(|e| anyhow::anyhow!("--compare '{spec}': {e}"))?;
        app.session.compare(settings);
        // The panel's field restarts the comparison with what it holds: the spec in use.
        app.panel.compare_spec = spec.clone();
    }
    let event_loop = window::open_event_loop()?;
    event_loop
        .run_app(&mut app)
        .context("the window's event loop failed")?;
    if let Some(recording) = app.recording.take() {
        let (path, frames) = recording.finish()?;
        eprintln!(
            "recording: wrote {} to {}",
            crate::io::counted(frames, "frame", "frames"),
            path.display()
        );
    }
    if let Some(error) = app.error.take() {
        return Err(error);
    }
    if app.options.frames.is_some() {
        app.stats.print_summary(app.session.ratio());
        for (k, lane) in app.session.lanes.iter().enumerate() {
            eprintln!(
                "world {} ({}): {} steps, t = {:.3} s",
                compare::lane_name(k),
                compare::settings_label(&lane.world.settings),
                lane.world.step_count,
                lane.world.time
            );
        }
    }
    Ok(())
}

/// Most steps a compared world may take for each of the first world's (`--compare --dt`).
const MAX_COMPARED_STEPS_PER_STEP: f64 = 1000.0;

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
    /// When the scene's files are next polled.
    next_poll: Instant,
    /// The grab under way (ctrl + left drag).
    grab: Option<GrabDrag>,
    quitting: bool,
}

impl App {
    fn new(world: World, options: ViewOptions) -> App {
        let source = SceneSource::Scene {
            name: options.scene.clone(),
            constraints: options.constraints.clone(),
        };
        let mut session = Session::new(world, source);
        session.playing = !options.paused;
        let mut panel = PanelState::default();
        panel.draw.layout = options.layout;
        panel.draw.shadows = options.shadows;
        panel.draw.fixed_bodies = options.fixed_bodies;
        let keep_all = options.frames.is_some();
        App {
            options,
            session,
            panel,
            camera: OrbitCamera::default(),
            camera_framed: false,
            gfx: None,
            error: None,
            pointer: Pointer::default(),
            view_rect: ViewRect::INITIAL,
            stats: FrameStats::new(keep_all),
            screenshot_requested: None,
            screenshot_counter: 0,
            recording: None,
            repaint_at: None,
            next_poll: Instant::now() + FILE_POLL,
            grab: None,
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
        let aspect = compare::pane_aspect(w, h, self.session.lanes.len(), self.panel.draw.layout);
        self.camera.frame(self.session.world(), aspect);
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
        let lanes = self.session.lanes.len();
        let ray = view_pointer::ray_at(
            &self.camera,
            self.view_rect,
            lanes,
            self.panel.draw.layout,
            p,
        );
        self.panel.draw.selected = ray.and_then(|r| {
            let world = &self.session.lanes[r.lane].world;
            picking::pick(world, (r.origin, r.dir), self.panel.draw.fixed_bodies).map(|(i, _)| i)
        });
    }

    /// Ctrl + left press at `p`: grabs the body there (in every compared world) at the picked
    /// point, and selects it.
    fn start_grab(&mut self, p: (f64, f64)) {
        let lanes = self.session.lanes.len();
        let layout = self.panel.draw.layout;
        let Some(ray) = view_pointer::ray_at(&self.camera, self.view_rect, lanes, layout, p) else {
            return;
        };
        let world = &self.session.lanes[ray.lane].world;
        let fixed = self.panel.draw.fixed_bodies;
        let Some((index, t)) = picking::pick(world, (ray.origin, ray.dir), fixed) else {
            return;
        };
        let point = ray.origin + t * ray.dir;
        let body = &world.bodies[index];
        let local = body.orientation.inverse() * (point - body.position);
        if self.session.grab(index, local, point) {
            let forward = self.camera.target - self.camera.eye();
            self.grab = Some(GrabDrag {
                plane: DragPlane::facing(point, forward),
                pane: ray.pane,
            });
            self.panel.draw.selected = Some(index);
        }
    }

    /// The cursor moved to `p` during a grab: the target follows it on the grab's plane.
    fn drag_grab(&mut self, p: (f64, f64)) {
        let Some(grab) = self.grab else { return };
        let (origin, dir) = view_pointer::ray_in(&self.camera, grab.pane, p);
        if let Some(target) = grab.plane.hit(origin, dir) {
            self.session.drag_grab(target);
        }
    }

    /// Opens `source` (a scene picked, typed or dropped), framing it; an error leaves the
    /// current scene running and shows in the panel.
    fn open_scene(&mut self, source: SceneSource) {
        match self.session.open(source) {
            Ok(()) => {
                // Framed first: a recording films the new scene's first state at once.
                self.frame_camera();
                self.scene_replaced();
            }
            Err(e) => self.panel.load_error = Some(e.to_string()),
        }
    }

    /// After the session's scene was replaced (opened or reloaded): the renderer's meshes, the
    /// window title, no selection or grab, and a recording going on from the new run's time 0
    /// (as after a reset: else it skipped the new run's frames up to the old run's time).
    fn scene_replaced(&mut self) {
        self.panel.load_error = None;
        self.panel.draw.selected = None;
        self.grab = None;
        if let Some(gfx) = &mut self.gfx {
            gfx.renderer
                .set_world(&gfx.gpu.device, self.session.world());
            gfx.window
                .set_title(&format!("tumble — {}", self.session.scene()));
        }
        self.time_jumped();
    }

    /// After the simulated time jumped (a reset, a new scene or comparison, a seek or a step
    /// back in the history): a recording goes on from the new time, with a frame of it.
    fn time_jumped(&mut self) {
        if let Some(recording) = &mut self.recording {
            recording.resume_at(self.session.world().time);
        }
        self.capture_recording_frames();
    }

    /// Reloads the scene when one of its files changed (every [`FILE_POLL`]); keeps the camera.
    fn poll_files(&mut self) {
        let now = Instant::now();
        if now < self.next_poll {
            return;
        }
        self.next_poll = now + FILE_POLL;
        match self.session.poll_files() {
            Some(Ok(())) => {
                self.scene_replaced();
                self.panel.message = Some(format!("reloaded {}", self.session.scene()));
            }
            Some(Err(e)) => self.panel.load_error = Some(e.to_string()),
            None => return,
        }
        self.request_redraw();
    }

    /// The settings of a compared world from `spec`, refused where its time step is not
    /// positive, or so much shorter than the first world's that it could not keep up: it steps
    /// to the first one's time each frame, and more than a thousand of its steps for each of
    /// the first's froze the viewer (`--dt 1e-9`).
    fn compared_settings(&self, spec: &str) -> Result<Settings, String> {
        let settings = (self.options.parse_settings)(spec)?;
        let (first, dt) = (self.session.world().settings.time_step, settings.time_step);
        if dt <= 0.0 {
            // (Not "takes more than 1000 steps": a world that stands still takes none.)
            return Err(format!(
                "a compared world's time step must be positive, got {}",
                crate::io::echoed(dt)
            ));
        }
        if first > 0.0 && dt * MAX_COMPARED_STEPS_PER_STEP < first {
            return Err(format!(
                "a time step of {} s takes more than {MAX_COMPARED_STEPS_PER_STEP} steps for each of this world's {} s",
                crate::io::echoed(dt),
                crate::io::echoed(first)
            ));
        }
        Ok(settings)
    }

    /// Starts comparing with the settings `spec` names; a spec that does not parse, or is
    /// refused ([`Self::compared_settings`]), is shown.
    fn start_comparing(&mut self, spec: &str) {
        match self.compared_settings(spec) {
            Ok(settings) => {
                self.panel.compare_error = None;
                self.grab = None;
                self.session.compare(settings);
                self.time_jumped();
            }
            Err(e) => self.panel.compare_error = Some(e),
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
                self.time_jumped();
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
            Action::Load(scene) => self.open_scene(SceneSource::named(&scene)),
            Action::StartRecording => self.start_recording(),
            Action::StopRecording => self.stop_recording(),
            Action::StepBack => self.move_in_history(Session::step_back),
            Action::StepForward => {
                // At the history's end a new step, which a recording films as `Step`'s.
                self.session.step_forward();
                self.capture_recording_frames();
            }
            Action::Seek(index) => self.move_in_history(|s| s.seek(index)),
            Action::Compare(spec) => self.start_comparing(&spec),
            Action::StopComparing => {
                self.session.stop_comparing();
                self.panel.edit_lane = 0;
            }
        }
    }

    /// Moves through the rewind history with `go`; a recording films on from the state it lands
    /// on, and films nothing again where it stays (Left at the history's start, the slider let
    /// go where it was).
    fn move_in_history(&mut self, go: impl FnOnce(&mut Session)) {
        let step = |s: &Session| s.world().step_count;
        let before = step(&self.session);
        go(&mut self.session);
        if step(&self.session) != before {
            self.time_jumped();
        }
    }

    /// Starts recording to the panel's name, or where a file or folder is there already to the
    /// first free numbered one ([`super::record::unused_name`]), said in the message.
    fn start_recording(&mut self) {
        let asked = PathBuf::from(self.panel.record_path.trim());
        let Some(path) = super::record::unused_name(&asked) else {
            self.panel.message = Some(format!(
                "cannot record: {} and its numbered names are all taken",
                asked.display()
            ));
            return;
        };
        let world = self.session.world();
        let (rate, inputs) = ((self.panel.record_fps, world.time), &world.inputs);
        match Recording::start(&path, self.view_rect, rate, inputs) {
            Ok(recording) => {
                self.recording = Some(recording);
                let kept = if path == asked {
                    String::new()
                } else {
                    format!(" ({} is there already and is kept)", asked.display())
                };
                self.panel.message = Some(format!("recording to {}{kept}", path.display()));
                self.capture_recording_frames();
            }
            Err(message) => self.panel.message = Some(message),
        }
    }

    fn stop_recording(&mut self) {
        if let Some(recording) = self.recording.take() {
            self.panel.message = Some(match recording.finish() {
                Ok((path, frames)) => {
                    format!(
                        "wrote {} to {}",
                        crate::io::counted(frames, "frame", "frames"),
                        path.display()
                    )
                }
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
        if let Err(e) = recording.capture_due(gfx, &self.session.lanes, view) {
            self.recording_failed(e);
        }
    }

    /// Ends the recording on a frame it could not take. The frames before it are a whole
    /// recording: closed and kept, as when stopped (dropped, the file would be abandoned).
    fn recording_failed(&mut self, error: anyhow::Error) {
        let kept = match self.recording.take().map(Recording::finish) {
            Some(Ok((path, frames))) => {
                format!(
                    "; {} holds its {}",
                    path.display(),
                    crate::io::counted(frames, "frame", "frames")
                )
            }
            Some(Err(e)) => format!("; and closing it: {e:#}"),
            None => String::new(),
        };
        self.panel.message = Some(format!("recording stopped: {error:#}{kept}"));
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
            // `--screenshot`'s failure ends the run it was asked of; a P key's is told in the
            // panel (a read-only folder closed the viewer, and the session with it).
            let asked_at_start = self.options.screenshot.as_ref() == Some(&path);
            match self.save_screenshot(&path) {
                Err(error) if !asked_at_start => {
                    self.panel.message = Some(format!("{error:#}"));
                }
                saved => saved?,
            }
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
        session.advance(real_dt, |lanes| {
            if failure.is_none()
                && let Some(recording) = recording.as_mut()
                && let Err(e) = recording.capture_due(gfx, lanes, view)
            {
                failure = Some(e);
            }
        });
        if let Some(e) = failure {
            self.recording_failed(e);
        }
    }

    /// The upload phase of the presentation, for this frame's scene and UI; the camera first
    /// follows the selected body when asked to.
    fn prepare_frame(&mut self, ui: egui::FullOutput) -> present::PreparedFrame {
        if self.panel.follow
            && let Some(body) = self.panel.draw.selected
            && let Some(b) = self.session.world().bodies.get(body)
            && b.position.is_finite()
        {
            self.camera.target = b.position;
        }
        let gfx = self.gfx.as_mut().expect("checked by run_ui");
        let view = SceneView {
            camera: &self.camera,
            draw: &self.panel.draw,
            rect: self.view_rect,
        };
        present::prepare(gfx, &self.session.worlds(), view, ui)
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
            Some(Shortcut::TogglePanel) => self.panel.hidden = !self.panel.hidden,
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
            ElementState::Pressed => {
                if let Some(p) = self.pointer.pressed(button, self.view_rect, taken_by_ui) {
                    self.start_grab(p);
                }
            }
            ElementState::Released => {
                match self.pointer.released(button) {
                    Some(Release::Pick(p)) => self.pick(p),
                    Some(Release::EndGrab) => {
                        self.session.release_grab();
                        self.grab = None;
                    }
                    Some(Release::EndDrag) | None => {}
                }
                self.request_redraw();
            }
        }
    }

    fn on_cursor_moved(&mut self, p: (f64, f64)) {
        let view_height = self.view_rect.0[3] as f64;
        if self.pointer.moved(p, &mut self.camera, view_height) {
            if self.pointer.grabbing() {
                self.drag_grab(p);
            }
            self.request_redraw();
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
            self.session.world(),
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
            WindowEvent::ModifiersChanged(m) => {
                self.pointer.shift = m.state().shift_key();
                self.pointer.ctrl = m.state().control_key();
            }
            WindowEvent::DroppedFile(path) => self.open_scene(SceneSource::dropped(&path)),
            WindowEvent::KeyboardInput { event, .. }
                if !response.consumed
                    && !keyboard_to_egui
                    && event.state == ElementState::Pressed =>
            {
                self.on_key(&event.logical_key);
            }
            WindowEvent::CursorMoved { position, .. } => {
                self.on_cursor_moved((position.x, position.y));
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
        self.poll_files();
        let Some(gfx) = &self.gfx else { return };
        if self.continuous() {
            gfx.window.request_redraw();
            event_loop.set_control_flow(ControlFlow::Poll);
            return;
        }
        if self.repaint_at.is_some_and(|at| Instant::now() >= at) {
            self.repaint_at = None;
            gfx.window.request_redraw();
            event_loop.set_control_flow(ControlFlow::Poll);
            return;
        }
        // Wake for egui's repaint and for the next poll of the scene's files.
        let watching = self.session.auto_reload && self.session.watched_files().next().is_some();
        let poll = watching.then_some(self.next_poll);
        match self.repaint_at.into_iter().chain(poll).min() {
            Some(at) => event_loop.set_control_flow(ControlFlow::WaitUntil(at)),
            None => event_loop.set_control_flow(ControlFlow::Wait),
        }
    }
}
