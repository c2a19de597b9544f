//! `tumble view`: the winit window, input, and the per-frame loop (simulate, UI, render).

use super::camera::OrbitCamera;
use super::gpu::{Gpu, Image, Offscreen};
use super::panel::{self, Action, FrameInfo, PanelState};
use super::record::FrameWriter;
use super::renderer::{DrawOptions, Renderer};
use super::session::Session;
use crate::{ConstraintsChoice, World};
use anyhow::{Context, bail};
use std::collections::VecDeque;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};
use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{Key, NamedKey};
use winit::window::{Window, WindowId};

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

const NO_DISPLAY: &str = "tumble view needs a display, and neither DISPLAY nor WAYLAND_DISPLAY is set.\n\
     Without a window you can:\n  \
     tumble record SCENE -o out.mp4   render a video offscreen (.mp4, .gif, or a directory of PNG frames)\n  \
     tumble run SCENE                 simulate headless and print a summary\n\
     or run the viewer under a virtual display: xvfb-run -a tumble view SCENE";

/// Which windowing system to use, checked before winit gets a chance to panic.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Display {
    X11,
    Wayland,
}

fn choose_display() -> anyhow::Result<Display> {
    let set = |name: &str| std::env::var_os(name).is_some_and(|v| !v.is_empty());
    if set("DISPLAY") {
        // Prefer X11 when both are set: a stale WAYLAND_DISPLAY makes winit panic.
        return Ok(Display::X11);
    }
    if set("WAYLAND_DISPLAY") {
        let name = PathBuf::from(std::env::var_os("WAYLAND_DISPLAY").unwrap_or_default());
        let socket = if name.is_absolute() {
            name.clone()
        } else {
            PathBuf::from(std::env::var_os("XDG_RUNTIME_DIR").unwrap_or_default()).join(&name)
        };
        if !socket.exists() {
            bail!(
                "WAYLAND_DISPLAY is {} but there is no compositor socket at {}.\n{NO_DISPLAY}",
                name.display(),
                socket.display()
            );
        }
        return Ok(Display::Wayland);
    }
    bail!("{NO_DISPLAY}")
}

fn build_event_loop(display: Display) -> anyhow::Result<EventLoop<()>> {
    let result = std::panic::catch_unwind(|| {
        let mut builder = EventLoop::builder();
        #[cfg(all(unix, not(target_os = "macos")))]
        match display {
            Display::X11 => {
                use winit::platform::x11::EventLoopBuilderExtX11;
                builder.with_x11();
            }
            Display::Wayland => {
                use winit::platform::wayland::EventLoopBuilderExtWayland;
                builder.with_wayland();
            }
        }
        #[cfg(not(all(unix, not(target_os = "macos"))))]
        let _ = display;
        builder.build()
    });
    match result {
        Ok(Ok(event_loop)) => Ok(event_loop),
        Ok(Err(e)) => bail!("cannot open a window ({e}).\n{NO_DISPLAY}"),
        Err(_) => bail!("cannot open a window (the windowing system panicked).\n{NO_DISPLAY}"),
    }
}

/// Opens the viewer on `world` and runs until the window is closed (or `--frames` are done).
pub fn run(world: World, options: ViewOptions) -> anyhow::Result<()> {
    let display = choose_display()?;
    let event_loop = build_event_loop(display)?;
    let mut app = App::new(world, options);
    event_loop
        .run_app(&mut app)
        .context("the window's event loop failed")?;
    if let Some(recording) = app.recording.take() {
        let path = recording.writer.path.clone();
        let (frames, _) = recording.writer.finish()?;
        eprintln!("recording: wrote {frames} frames to {}", path.display());
    }
    if let Some(error) = app.error.take() {
        return Err(error);
    }
    app.print_frame_summary();
    Ok(())
}

struct Gfx {
    window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    gpu: Gpu,
    renderer: Renderer,
    egui_ctx: egui::Context,
    egui_state: egui_winit::State,
    egui_renderer: egui_wgpu::Renderer,
    /// Window-sized copy target for screenshots.
    capture: Option<Offscreen>,
    /// The 3D view, rendered once per frame and copied into the window.
    scene: Option<Offscreen>,
    /// Whether the surface accepts copies (else the scene is drawn straight into it).
    copy_to_surface: bool,
}

struct Drag {
    button: MouseButton,
    start: (f64, f64),
    last: (f64, f64),
    moved: bool,
}

struct Recording {
    writer: FrameWriter,
    fps: f64,
    /// Simulated time of the next frame to capture.
    next: f64,
    /// Viewport captured (pixels), fixed for the whole recording.
    rect: [u32; 4],
}

struct App {
    options: ViewOptions,
    session: Session,
    panel: PanelState,
    camera: OrbitCamera,
    camera_framed: bool,
    gfx: Option<Gfx>,
    error: Option<anyhow::Error>,
    cursor: Option<(f64, f64)>,
    drag: Option<Drag>,
    shift: bool,
    /// The 3D view's rectangle in physical pixels (x, y, w, h): the window minus the panel.
    view_rect: [f32; 4],
    last_frame: Option<Instant>,
    /// (interval since previous frame, time spent on the frame), recent frames.
    recent: VecDeque<(f64, f64)>,
    /// Same, every frame of the run (for the `--frames` summary).
    all_frames: Vec<(f64, f64)>,
    frames: u64,
    screenshot_requested: Option<PathBuf>,
    screenshot_counter: u32,
    recording: Option<Recording>,
    repaint_at: Option<Instant>,
    quitting: bool,
    /// Seconds spent in each phase of a frame (UI, simulation, upload, acquiring the
    /// swapchain image, encoding/submitting/presenting), summed over frames.
    phase_totals: [f64; 5],
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
            cursor: None,
            drag: None,
            shift: false,
            view_rect: [0.0, 0.0, 1.0, 1.0],
            last_frame: None,
            recent: VecDeque::new(),
            all_frames: Vec::new(),
            frames: 0,
            screenshot_requested: None,
            screenshot_counter: 0,
            recording: None,
            repaint_at: None,
            quitting: false,
            phase_totals: [0.0; 5],
        }
    }

    fn fail(&mut self, event_loop: &ActiveEventLoop, error: anyhow::Error) {
        self.error.get_or_insert(error);
        event_loop.exit();
    }

    fn init_graphics(&mut self, event_loop: &ActiveEventLoop) -> anyhow::Result<()> {
        let attributes = Window::default_attributes()
            .with_title(format!("tumble — {}", self.options.scene))
            .with_inner_size(winit::dpi::PhysicalSize::new(
                self.options.width.max(320),
                self.options.height.max(240),
            ));
        let window = Arc::new(
            event_loop
                .create_window(attributes)
                .context("cannot create the window")?,
        );
        let descriptor = wgpu::InstanceDescriptor::new_with_display_handle_from_env(Box::new(
            DisplayHandle(event_loop.owned_display_handle()),
        ));
        let instance = wgpu::Instance::new(descriptor);
        let surface = instance
            .create_surface(window.clone())
            .context("cannot create a rendering surface for the window")?;
        let gpu = Gpu::with_instance(instance, Some(&surface))?;
        let caps = surface.get_capabilities(&gpu.adapter);
        // The window's own format is the gamma-space one egui wants (blending in sRGB space, and
        // much cheaper on software rasterisers); the scene is rendered in the sRGB variant and
        // copied in, which keeps its bytes.
        let format = caps
            .formats
            .iter()
            .copied()
            .find(|f| !f.is_srgb() && f.add_srgb_suffix() != *f)
            .or_else(|| caps.formats.first().copied())
            .context("the window surface supports no format")?;
        let scene_format = format.add_srgb_suffix();
        let size = window.inner_size();
        let present_mode = if self.options.vsync {
            wgpu::PresentMode::AutoVsync
        } else {
            wgpu::PresentMode::AutoNoVsync
        };
        let mut config = surface
            .get_default_config(&gpu.adapter, size.width.max(1), size.height.max(1))
            .context("the window surface is not supported by the adapter")?;
        config.format = format;
        config.view_formats = if scene_format != format {
            vec![scene_format]
        } else {
            Vec::new()
        };
        config.present_mode = present_mode;
        let copy_to_surface = caps.usages.contains(wgpu::TextureUsages::COPY_DST)
            && std::env::var_os("TUMBLE_NO_SURFACE_COPY").is_none();
        config.usage = wgpu::TextureUsages::RENDER_ATTACHMENT
            | if copy_to_surface {
                wgpu::TextureUsages::COPY_DST
            } else {
                wgpu::TextureUsages::empty()
            };
        surface.configure(&gpu.device, &config);

        let mut renderer = Renderer::new(&gpu, scene_format);
        renderer.set_world(&gpu.device, &self.session.world);
        renderer.resize(&gpu.device, config.width, config.height);

        let egui_ctx = egui::Context::default();
        egui_ctx.set_visuals(egui::Visuals::dark());
        let max_texture_side = gpu.device.limits().max_texture_dimension_2d as usize;
        let egui_state = egui_winit::State::new(
            egui_ctx.clone(),
            egui::ViewportId::ROOT,
            &window,
            Some(window.scale_factor() as f32),
            None,
            Some(max_texture_side),
        );
        let egui_renderer =
            egui_wgpu::Renderer::new(&gpu.device, format, egui_wgpu::RendererOptions::default());
        eprintln!(
            "tumble view: {} on {}, {}x{} {:?}, {}x MSAA",
            self.options.scene,
            gpu.description(),
            config.width,
            config.height,
            format,
            renderer.sample_count
        );
        self.gfx = Some(Gfx {
            window,
            surface,
            config,
            gpu,
            renderer,
            egui_ctx,
            egui_state,
            egui_renderer,
            capture: None,
            scene: None,
            copy_to_surface,
        });
        Ok(())
    }

    fn view_size(&self) -> (f64, f64) {
        (
            self.view_rect[2].max(1.0) as f64,
            self.view_rect[3].max(1.0) as f64,
        )
    }

    fn in_view(&self, (x, y): (f64, f64)) -> bool {
        let [vx, vy, vw, vh] = self.view_rect.map(|v| v as f64);
        x >= vx && y >= vy && x < vx + vw && y < vy + vh
    }

    fn frame_camera(&mut self) {
        let (w, h) = self.view_size();
        self.camera.frame(&self.session.world, w / h);
    }

    fn pick(&mut self, (x, y): (f64, f64)) {
        let (w, h) = self.view_size();
        let (origin, dir) = self.camera.ray(
            x - self.view_rect[0] as f64,
            y - self.view_rect[1] as f64,
            w,
            h,
        );
        self.panel.draw.selected =
            super::picking::pick(&self.session.world, origin, dir).map(|(i, _)| i);
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
                    recording.next = 0.0;
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
        let [x, y, w, h] = self.view_rect.map(|v| v.max(0.0) as u32);
        // Even sizes suit every format (H.264 needs them).
        let (w, h) = (w & !1, h & !1);
        if w < 2 || h < 2 {
            self.panel.message = Some("the view is too small to record".into());
            return;
        }
        let path = PathBuf::from(self.panel.record_path.trim());
        match FrameWriter::create(&path, w, h, self.panel.record_fps) {
            Ok(writer) => {
                let next = self.session.world.time;
                self.recording = Some(Recording {
                    writer,
                    fps: self.panel.record_fps,
                    next,
                    rect: [x, y, w, h],
                });
                self.panel.message = Some(format!("recording to {}", path.display()));
                self.capture_recording_frames();
            }
            Err(e) => self.panel.message = Some(format!("cannot record: {e:#}")),
        }
    }

    fn stop_recording(&mut self) {
        if let Some(recording) = self.recording.take() {
            let path = recording.writer.path.clone();
            self.panel.message = Some(match recording.writer.finish() {
                Ok((frames, _)) => format!("wrote {frames} frames to {}", path.display()),
                Err(e) => format!("recording failed: {e:#}"),
            });
        }
    }

    /// Captures the frames of the recording due at the current simulated time.
    fn capture_recording_frames(&mut self) {
        let Some(gfx) = &mut self.gfx else { return };
        if let Err(e) = capture_due(
            gfx,
            &mut self.recording,
            &self.session.world,
            &self.camera,
            &self.panel.draw,
            self.view_rect,
        ) {
            self.panel.message = Some(format!("recording failed: {e:#}"));
            self.recording = None;
        }
    }

    fn redraw(&mut self, event_loop: &ActiveEventLoop) -> anyhow::Result<()> {
        let frame_start = Instant::now();
        let real_dt = self
            .last_frame
            .map_or(0.0, |t| frame_start.duration_since(t).as_secs_f64());
        self.last_frame = Some(frame_start);
        if (self.options.interrupted)() {
            self.quitting = true;
            event_loop.exit();
        }

        // UI first: slider changes apply to this frame's steps.
        let mut actions = Vec::new();
        let (full_output, view_rect_points) = {
            let Some(gfx) = &mut self.gfx else {
                return Ok(());
            };
            let raw_input = gfx.egui_state.take_egui_input(&gfx.window);
            let interval = mean(self.recent.iter().map(|r| r.0));
            let work = mean(self.recent.iter().map(|r| r.1));
            let adapter = gfx.gpu.description();
            let recording_path = self
                .recording
                .as_ref()
                .map(|r| r.writer.path.display().to_string());
            let info = FrameInfo {
                frame_interval: interval,
                frame_work: work,
                adapter: &adapter,
                msaa: gfx.renderer.sample_count,
                draw_calls: gfx.renderer.body_draw_calls(),
                recording: recording_path
                    .as_deref()
                    .zip(self.recording.as_ref().map(|r| r.writer.frames)),
            };
            let session = &mut self.session;
            let panel_state = &mut self.panel;
            let mut view_rect = egui::Rect::NOTHING;
            let output = gfx.egui_ctx.run_ui(raw_input, |ui| {
                // No fill: the window is cleared to the panel colour before egui draws, which
                // spares software rasterisers a window-high quad every frame.
                let frame =
                    egui::Frame::side_top_panel(ui.style()).fill(egui::Color32::TRANSPARENT);
                egui::Panel::right("controls")
                    .frame(frame)
                    .default_size(360.0)
                    .size_range(260.0..=640.0)
                    .show(ui, |ui| {
                        actions = panel::show(ui, session, panel_state, &info);
                    });
                view_rect = ui.available_rect_before_wrap();
                panel::overlay(ui.ctx(), view_rect, session, panel_state);
            });
            (output, view_rect)
        };
        {
            let gfx = self.gfx.as_ref().expect("checked");
            let ppp = full_output.pixels_per_point;
            let (ww, wh) = (gfx.config.width as f32, gfx.config.height as f32);
            let r = view_rect_points;
            let x = (r.min.x * ppp).clamp(0.0, ww);
            let y = (r.min.y * ppp).clamp(0.0, wh);
            self.view_rect = [
                x,
                y,
                (r.width() * ppp).min(ww - x).max(1.0),
                (r.height() * ppp).min(wh - y).max(1.0),
            ];
        }
        if !self.camera_framed {
            self.frame_camera();
            if let Some(spec) = self.options.camera.clone()
                && let Err(e) = self.camera.apply_spec(&spec)
            {
                bail!(e);
            }
            self.camera_framed = true;
        }
        for action in actions {
            self.handle_action(action);
        }

        let t_ui = Instant::now();
        // Simulate; a recording samples the state after the step that reaches each frame's
        // simulated time, so the video plays at simulated speed whatever the frame rate.
        {
            let Self {
                session,
                gfx,
                recording,
                camera,
                panel,
                view_rect,
                ..
            } = self;
            let gfx = gfx.as_mut().expect("checked");
            let mut failure = None;
            session.advance(real_dt, |world| {
                if failure.is_none()
                    && let Err(e) =
                        capture_due(gfx, recording, world, camera, &panel.draw, *view_rect)
                {
                    failure = Some(e);
                }
            });
            if let Some(e) = failure {
                self.panel.message = Some(format!("recording failed: {e:#}"));
                self.recording = None;
            }
        }

        let t_sim = Instant::now();
        // Render.
        let gfx = self.gfx.as_mut().expect("checked");
        let (w, h) = (self.view_rect[2] as f64, self.view_rect[3] as f64);
        let scene = prepare_scene_target(gfx, self.view_rect);
        gfx.renderer.prepare(
            &gfx.gpu.device,
            &gfx.gpu.queue,
            &self.session.world,
            &self.camera.matrices(w / h),
            &self.panel.draw,
        );
        gfx.egui_state
            .handle_platform_output(&gfx.window, full_output.platform_output);
        let paint_jobs = gfx
            .egui_ctx
            .tessellate(full_output.shapes, full_output.pixels_per_point);
        for (id, deltas) in &full_output.textures_delta.set {
            for delta in deltas {
                gfx.egui_renderer
                    .update_texture(&gfx.gpu.device, &gfx.gpu.queue, *id, delta);
            }
        }
        let screen = egui_wgpu::ScreenDescriptor {
            size_in_pixels: [gfx.config.width, gfx.config.height],
            pixels_per_point: full_output.pixels_per_point,
        };
        let repaint_delay = full_output
            .viewport_output
            .get(&egui::ViewportId::ROOT)
            .map(|v| v.repaint_delay);

        let t_prepare = Instant::now();
        let surface_texture = match gfx.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t)
            | wgpu::CurrentSurfaceTexture::Suboptimal(t) => Some(t),
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                gfx.surface.configure(&gfx.gpu.device, &gfx.config);
                None
            }
            _ => None,
        };
        let want_screenshot = self.screenshot_requested.take().or_else(|| {
            let last = self.options.frames.is_some_and(|n| self.frames + 1 >= n);
            if last {
                self.options.screenshot.clone()
            } else {
                None
            }
        });
        if want_screenshot.is_some()
            && gfx
                .capture
                .as_ref()
                .is_none_or(|c| c.width != gfx.config.width || c.height != gfx.config.height)
        {
            gfx.capture = Some(Offscreen::new(
                &gfx.gpu.device,
                gfx.config.width,
                gfx.config.height,
                gfx.config.format,
            ));
        }
        let panel_fill = gfx.egui_ctx.global_style().visuals.panel_fill;
        let t_acquire = Instant::now();
        let mut encoder = gfx.gpu.device.create_command_encoder(&Default::default());
        let user_buffers = gfx.egui_renderer.update_buffers(
            &gfx.gpu.device,
            &gfx.gpu.queue,
            &mut encoder,
            &paint_jobs,
            &screen,
        );
        // The scene is drawn once into the view-sized scene texture and copied into each
        // target (the window, and the capture for a screenshot); without copies into the
        // surface it is drawn straight into each target.
        let surface_views = surface_texture.as_ref().map(|t| {
            let view = t.texture.create_view(&Default::default());
            let srgb_view = t.texture.create_view(&wgpu::TextureViewDescriptor {
                format: Some(gfx.renderer.color_format),
                ..Default::default()
            });
            (view, srgb_view)
        });
        // (texture, its view for egui, its sRGB view for the scene)
        let mut targets: Vec<(&wgpu::Texture, &wgpu::TextureView, &wgpu::TextureView)> = Vec::new();
        if let (Some(t), Some((view, srgb_view))) = (&surface_texture, &surface_views) {
            targets.push((&t.texture, view, srgb_view));
        }
        if want_screenshot.is_some()
            && let Some(capture) = &gfx.capture
        {
            targets.push((&capture.texture, &capture.view, &capture.srgb_view));
        }
        if let Some(scene) = scene.and(gfx.scene.as_ref())
            && !targets.is_empty()
        {
            gfx.renderer.draw(&mut encoder, &scene.view, None);
        }
        for (texture, view, srgb_view) in &targets {
            match scene.and_then(|origin| gfx.scene.as_ref().map(|s| (origin, s))) {
                Some((origin, scene)) => {
                    clear_pass(&mut encoder, view, gfx.config.format, panel_fill);
                    encoder.copy_texture_to_texture(
                        scene.texture.as_image_copy(),
                        wgpu::TexelCopyTextureInfo {
                            texture,
                            mip_level: 0,
                            origin,
                            aspect: wgpu::TextureAspect::All,
                        },
                        wgpu::Extent3d {
                            width: scene.width,
                            height: scene.height,
                            depth_or_array_layers: 1,
                        },
                    );
                }
                None => gfx
                    .renderer
                    .draw(&mut encoder, srgb_view, Some(self.view_rect)),
            }
            let mut pass = encoder
                .begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("egui"),
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Load,
                            store: wgpu::StoreOp::Store,
                        },
                    })],
                    depth_stencil_attachment: None,
                    timestamp_writes: None,
                    occlusion_query_set: None,
                    multiview_mask: None,
                })
                .forget_lifetime();
            gfx.egui_renderer.render(&mut pass, &paint_jobs, &screen);
        }
        if want_screenshot.is_some()
            && let Some(capture) = &gfx.capture
        {
            capture.copy_to_buffer(&mut encoder);
        }
        gfx.gpu
            .queue
            .submit(user_buffers.into_iter().chain([encoder.finish()]));
        if let Some(texture) = surface_texture {
            gfx.window.pre_present_notify();
            gfx.gpu.queue.present(texture);
        }
        for id in &full_output.textures_delta.free {
            gfx.egui_renderer.free_texture(id);
        }
        if let Some(path) = want_screenshot
            && let Some(capture) = &gfx.capture
        {
            let image = capture.read(&gfx.gpu.device)?;
            image
                .save_png(&path)
                .with_context(|| format!("cannot save the screenshot {}", path.display()))?;
            eprintln!(
                "screenshot: {} ({}x{})",
                path.display(),
                image.width,
                image.height
            );
            self.panel.message = Some(format!("screenshot saved to {}", path.display()));
        }

        let t_end = Instant::now();
        let work = t_end.duration_since(frame_start).as_secs_f64();
        if self.frames > 0 {
            let marks = [frame_start, t_ui, t_sim, t_prepare, t_acquire, t_end];
            for (k, total) in self.phase_totals.iter_mut().enumerate() {
                *total += marks[k + 1].duration_since(marks[k]).as_secs_f64();
            }
            self.recent.push_back((real_dt, work));
            self.all_frames.push((real_dt, work));
        }
        while self.recent.len() > 60 {
            self.recent.pop_front();
        }
        self.frames += 1;
        if self.options.frames.is_some_and(|n| self.frames >= n) {
            self.quitting = true;
            event_loop.exit();
        }
        self.repaint_at = repaint_delay
            .and_then(|d| Instant::now().checked_add(d.min(Duration::from_secs(3600))));
        Ok(())
    }

    fn continuous(&self) -> bool {
        self.session.playing
            || self.recording.is_some()
            || self.options.frames.is_some()
            || self.drag.is_some()
    }

    fn print_frame_summary(&self) {
        let Some(_) = self.options.frames else { return };
        // Skip warm-up frames (shader compilation, first uploads).
        let skip = (self.all_frames.len() / 10).min(10);
        let frames = &self.all_frames[skip..];
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
            self.session
                .ratio()
                .map_or("-".to_string(), |r| format!("{r:.2}x")),
        );
        let n = self.all_frames.len().max(1) as f64;
        let [ui, sim, prepare, acquire, submit] = self.phase_totals.map(|t| 1e3 * t / n);
        eprintln!(
            "per frame: UI {ui:.2} ms, simulation {sim:.2} ms, upload+tessellate {prepare:.2} ms, acquire image {acquire:.2} ms, render+submit+present {submit:.2} ms"
        );
    }

    fn on_key(&mut self, key: &Key) {
        match key {
            Key::Named(NamedKey::Space) => self.session.toggle_play(),
            Key::Named(NamedKey::Escape) => self.panel.draw.selected = None,
            Key::Character(c) => match c.to_lowercase().as_str() {
                "s" => self.handle_action(Action::Step),
                "r" => self.handle_action(Action::Reset),
                "f" => self.handle_action(Action::FrameScene),
                "p" => self.handle_action(Action::Screenshot),
                _ => {}
            },
            _ => {}
        }
    }
}

/// winit's display handle made `Debug` for wgpu's instance descriptor.
#[derive(Clone)]
struct DisplayHandle(winit::event_loop::OwnedDisplayHandle);

impl std::fmt::Debug for DisplayHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("DisplayHandle")
    }
}

impl wgpu::rwh::HasDisplayHandle for DisplayHandle {
    fn display_handle(&self) -> Result<wgpu::rwh::DisplayHandle<'_>, wgpu::rwh::HandleError> {
        self.0.display_handle()
    }
}

/// Sizes the renderer's targets for this frame. With copies into the surface, the scene is
/// drawn into a texture the size of the 3D view (MSAA targets that size too, not the whole
/// window) and its origin in the window is returned; otherwise the targets are window-sized
/// and the scene is drawn with a viewport.
fn prepare_scene_target(gfx: &mut Gfx, view_rect: [f32; 4]) -> Option<wgpu::Origin3d> {
    let device = &gfx.gpu.device;
    if !gfx.copy_to_surface {
        gfx.renderer
            .resize(device, gfx.config.width, gfx.config.height);
        return None;
    }
    let [x, y, w, h] = view_rect.map(|v| v.max(0.0).round() as u32);
    // Inside the window, even when the panel covers all of it.
    let (x, y) = (x.min(gfx.config.width - 1), y.min(gfx.config.height - 1));
    let (w, h) = (
        w.clamp(1, gfx.config.width - x),
        h.clamp(1, gfx.config.height - y),
    );
    if gfx
        .scene
        .as_ref()
        .is_none_or(|s| s.width != w || s.height != h)
    {
        gfx.scene = Some(Offscreen::new(device, w, h, gfx.renderer.color_format));
    }
    gfx.renderer.resize(device, w, h);
    Some(wgpu::Origin3d { x, y, z: 0 })
}

/// Clears a target to the background colour.
fn clear_pass(
    encoder: &mut wgpu::CommandEncoder,
    view: &wgpu::TextureView,
    format: wgpu::TextureFormat,
    color: egui::Color32,
) {
    let srgb = [color.r(), color.g(), color.b()].map(|v| v as f32 / 255.0);
    let c = if format.is_srgb() {
        super::palette::linear(srgb)
    } else {
        srgb
    };
    encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some("clear"),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load: wgpu::LoadOp::Clear(wgpu::Color {
                    r: c[0] as f64,
                    g: c[1] as f64,
                    b: c[2] as f64,
                    a: 1.0,
                }),
                store: wgpu::StoreOp::Store,
            },
        })],
        depth_stencil_attachment: None,
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    });
}

/// Renders the scene alone and reads back the 3D view's pixels (top left = view's top left).
fn render_capture(
    gfx: &mut Gfx,
    world: &World,
    camera: &OrbitCamera,
    draw: &DrawOptions,
    view_rect: [f32; 4],
) -> anyhow::Result<Image> {
    let scene = prepare_scene_target(gfx, view_rect);
    let (w, h) = (view_rect[2].max(1.0) as f64, view_rect[3].max(1.0) as f64);
    gfx.renderer.prepare(
        &gfx.gpu.device,
        &gfx.gpu.queue,
        world,
        &camera.matrices(w / h),
        draw,
    );
    let mut encoder = gfx.gpu.device.create_command_encoder(&Default::default());
    if scene.is_some() {
        let target = gfx.scene.as_ref().expect("sized above");
        gfx.renderer.draw(&mut encoder, &target.view, None);
        target.copy_to_buffer(&mut encoder);
        gfx.gpu.queue.submit([encoder.finish()]);
        return target.read(&gfx.gpu.device);
    }
    let (width, height) = (gfx.config.width, gfx.config.height);
    if gfx
        .capture
        .as_ref()
        .is_none_or(|c| c.width != width || c.height != height)
    {
        gfx.capture = Some(Offscreen::new(
            &gfx.gpu.device,
            width,
            height,
            gfx.config.format,
        ));
    }
    let capture = gfx.capture.as_ref().expect("created above");
    gfx.renderer
        .draw(&mut encoder, &capture.srgb_view, Some(view_rect));
    capture.copy_to_buffer(&mut encoder);
    gfx.gpu.queue.submit([encoder.finish()]);
    let [x, y, w, h] = view_rect.map(|v| v.max(0.0).round() as u32);
    Ok(capture.read(&gfx.gpu.device)?.crop(x, y, w, h))
}

/// Pushes the recording's frames due at `world.time` (one per 1/fps of simulated time).
fn capture_due(
    gfx: &mut Gfx,
    recording: &mut Option<Recording>,
    world: &World,
    camera: &OrbitCamera,
    draw: &DrawOptions,
    view_rect: [f32; 4],
) -> anyhow::Result<()> {
    let Some(rec) = recording else { return Ok(()) };
    if world.time + 1e-9 < rec.next {
        return Ok(());
    }
    let image = render_capture(gfx, world, camera, draw, view_rect)?;
    let [_, _, w, h] = rec.rect;
    let frame = image.crop(0, 0, w, h);
    anyhow::ensure!(
        frame.width == w && frame.height == h,
        "the window shrank during the recording"
    );
    while world.time + 1e-9 >= rec.next {
        rec.writer.push(frame.clone())?;
        rec.next += 1.0 / rec.fps;
    }
    Ok(())
}

fn mean(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    if n == 0 { 0.0 } else { sum / n as f64 }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.gfx.is_none()
            && let Err(e) = self.init_graphics(event_loop)
        {
            self.fail(event_loop, e);
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
            WindowEvent::CloseRequested => {
                self.quitting = true;
                event_loop.exit();
            }
            WindowEvent::Resized(size) if size.width > 0 && size.height > 0 => {
                gfx.config.width = size.width;
                gfx.config.height = size.height;
                gfx.surface.configure(&gfx.gpu.device, &gfx.config);
                gfx.renderer
                    .resize(&gfx.gpu.device, size.width, size.height);
                gfx.window.request_redraw();
            }
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.redraw(event_loop) {
                    self.fail(event_loop, e);
                }
            }
            WindowEvent::ModifiersChanged(m) => self.shift = m.state().shift_key(),
            WindowEvent::KeyboardInput { event, .. }
                if !response.consumed
                    && !keyboard_to_egui
                    && event.state == ElementState::Pressed =>
            {
                self.on_key(&event.logical_key);
            }
            WindowEvent::CursorMoved { position, .. } => {
                let p = (position.x, position.y);
                self.cursor = Some(p);
                if let Some(drag) = &mut self.drag {
                    let (dx, dy) = (p.0 - drag.last.0, p.1 - drag.last.1);
                    drag.last = p;
                    if (p.0 - drag.start.0).abs() + (p.1 - drag.start.1).abs() > 3.0 {
                        drag.moved = true;
                    }
                    let pan = drag.button != MouseButton::Left || self.shift;
                    let height = self.view_rect[3] as f64;
                    if pan {
                        self.camera.pan(dx, dy, height);
                    } else {
                        self.camera.orbit(dx, dy);
                    }
                    if let Some(gfx) = &self.gfx {
                        gfx.window.request_redraw();
                    }
                }
            }
            WindowEvent::CursorLeft { .. } => self.cursor = None,
            WindowEvent::MouseInput { state, button, .. } => match state {
                ElementState::Pressed => {
                    if let Some(p) = self.cursor
                        && !response.consumed
                        && !over_egui
                        && self.in_view(p)
                        && self.drag.is_none()
                    {
                        self.drag = Some(Drag {
                            button,
                            start: p,
                            last: p,
                            moved: false,
                        });
                    }
                }
                ElementState::Released => {
                    if let Some(drag) = self.drag.take_if(|d| d.button == button) {
                        if !drag.moved && button == MouseButton::Left {
                            self.pick(drag.start);
                        }
                        if let Some(gfx) = &self.gfx {
                            gfx.window.request_redraw();
                        }
                    }
                }
            },
            WindowEvent::MouseWheel { delta, .. }
                if !over_egui && self.cursor.is_some_and(|p| self.in_view(p)) =>
            {
                let steps = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y as f64,
                    MouseScrollDelta::PixelDelta(p) => p.y / 40.0,
                };
                self.camera.zoom(steps);
                if let Some(gfx) = &self.gfx {
                    gfx.window.request_redraw();
                }
            }
            _ => {}
        }
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        if self.quitting {
            return;
        }
        if (self.options.interrupted)() {
            self.quitting = true;
            event_loop.exit();
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
