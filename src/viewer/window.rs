//! The window and what draws into it: the display check and the event loop, the wgpu surface with
//! its device, the scene renderer and egui's state ([`Gfx`]), and the 3D view's place in the
//! window ([`ViewRect`]).

use super::gpu::{Gpu, Offscreen};
use super::renderer::Renderer;
use crate::World;
use anyhow::{Context, bail};
use std::path::PathBuf;
use std::sync::Arc;
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::window::Window;

/// What to do without a window, said after each reason there is none.
const WITHOUT_A_WINDOW: &str = "Without a window you can:\n  \
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
                "WAYLAND_DISPLAY is {} but there is no compositor socket at {}.\n{WITHOUT_A_WINDOW}",
                name.display(),
                socket.display()
            );
        }
        return Ok(Display::Wayland);
    }
    bail!(
        "tumble view needs a display, and neither DISPLAY nor WAYLAND_DISPLAY is set.\n{WITHOUT_A_WINDOW}"
    )
}

/// The event loop on the display the environment names, or an error saying what to do
/// without one.
pub fn open_event_loop() -> anyhow::Result<EventLoop<()>> {
    let display = choose_display()?;
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
        Ok(Err(e)) => bail!("cannot open a window ({e}).\n{WITHOUT_A_WINDOW}"),
        Err(_) => {
            bail!("cannot open a window (the windowing system panicked).\n{WITHOUT_A_WINDOW}")
        }
    }
}

/// The 3D view's rectangle in the window in physical pixels (x, y, width, height): the window
/// minus the panel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewRect(pub [f32; 4]);

impl ViewRect {
    /// Until the first frame's UI has placed the panel.
    pub const INITIAL: ViewRect = ViewRect([0.0, 0.0, 1.0, 1.0]);

    /// Width and height, at least a pixel each.
    pub fn size(self) -> (f64, f64) {
        (self.0[2].max(1.0) as f64, self.0[3].max(1.0) as f64)
    }

    pub fn contains(self, (x, y): (f64, f64)) -> bool {
        let [vx, vy, vw, vh] = self.0.map(|v| v as f64);
        x >= vx && y >= vy && x < vx + vw && y < vy + vh
    }

    /// Rounded to whole pixels (x, y, width, height).
    pub fn pixels(self) -> [u32; 4] {
        self.0.map(|v| v.max(0.0).round() as u32)
    }
}

/// The window with everything that draws into it.
pub struct Gfx {
    pub window: Arc<Window>,
    pub surface: wgpu::Surface<'static>,
    pub config: wgpu::SurfaceConfiguration,
    pub gpu: Gpu,
    pub renderer: Renderer,
    pub egui_ctx: egui::Context,
    pub egui_state: egui_winit::State,
    pub egui_renderer: egui_wgpu::Renderer,
    /// Window-sized copy target for screenshots.
    pub capture: Option<Offscreen>,
    /// The 3D view, rendered once per frame and copied into the window.
    pub scene: Option<Offscreen>,
    /// Whether the surface accepts copies (else the scene is drawn straight into it).
    pub copy_to_surface: bool,
}

/// How the window's surface is configured, and what follows for the scene.
struct SurfaceSetup {
    config: wgpu::SurfaceConfiguration,
    /// The sRGB variant of the surface format, which the scene is rendered in.
    scene_format: wgpu::TextureFormat,
    copy_to_surface: bool,
}

/// Smallest window asked of the window system, in pixels (`view --size` below it is raised).
pub const MIN_WINDOW_SIZE: (u32, u32) = (320, 240);

impl Gfx {
    /// Opens a `width` x `height` window titled after `scene` on a device that can present to
    /// it, with the renderer holding `world`'s static data.
    pub fn new(
        event_loop: &ActiveEventLoop,
        scene: &str,
        (width, height): (u32, u32),
        vsync: bool,
        world: &World,
    ) -> anyhow::Result<Gfx> {
        let attributes = Window::default_attributes()
            .with_title(format!("tumble — {scene}"))
            .with_inner_size(winit::dpi::PhysicalSize::new(
                width.max(MIN_WINDOW_SIZE.0),
                height.max(MIN_WINDOW_SIZE.1),
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
        let SurfaceSetup {
            config,
            scene_format,
            copy_to_surface,
        } = configure_surface(&surface, &gpu, window.inner_size(), vsync)?;

        let mut renderer = Renderer::new(&gpu, scene_format);
        renderer.set_world(&gpu.device, world);
        renderer.resize(&gpu.device, config.width, config.height);
        let (egui_ctx, egui_state, egui_renderer) = egui_setup(&window, &gpu, config.format);
        eprintln!(
            "tumble view: {} on {}, {}x{} {:?}, {}x MSAA",
            scene,
            gpu.description(),
            config.width,
            config.height,
            config.format,
            renderer.sample_count
        );
        Ok(Gfx {
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
        })
    }

    /// Follows a change of the window's size (not to zero).
    pub fn resize(&mut self, size: winit::dpi::PhysicalSize<u32>) {
        let (width, height) = surface_size(&self.gpu, size);
        self.config.width = width;
        self.config.height = height;
        self.surface.configure(&self.gpu.device, &self.config);
        self.renderer.resize(&self.gpu.device, width, height);
        self.window.request_redraw();
    }

    /// egui's rectangle for the view (points) in window pixels, inside the window and at least
    /// a pixel wide and high.
    pub fn view_rect(&self, rect: egui::Rect, pixels_per_point: f32) -> ViewRect {
        let (ww, wh) = (self.config.width as f32, self.config.height as f32);
        let x = (rect.min.x * pixels_per_point).clamp(0.0, ww);
        let y = (rect.min.y * pixels_per_point).clamp(0.0, wh);
        ViewRect([
            x,
            y,
            (rect.width() * pixels_per_point).min(ww - x).max(1.0),
            (rect.height() * pixels_per_point).min(wh - y).max(1.0),
        ])
    }

    /// (Re)creates the window-sized target screenshots are drawn into, when missing or of
    /// another size than the window.
    pub fn ensure_window_capture(&mut self) {
        let (width, height) = (self.config.width, self.config.height);
        if self
            .capture
            .as_ref()
            .is_none_or(|c| c.width != width || c.height != height)
        {
            self.capture = Some(Offscreen::new(
                &self.gpu.device,
                width,
                height,
                self.config.format,
            ));
        }
    }
}

/// The surface's size for a window of `size`: at least a pixel, and at most the device's
/// largest texture side (a window stretched past it, over several screens, ended in wgpu's
/// validation error; the view is then drawn at that size and scaled to the window).
fn surface_size(gpu: &Gpu, size: winit::dpi::PhysicalSize<u32>) -> (u32, u32) {
    let most = gpu.device.limits().max_texture_dimension_2d.max(1);
    (size.width.clamp(1, most), size.height.clamp(1, most))
}

/// Configures `surface` for a window of `size`.
///
/// The window's own format is the gamma-space one egui wants (blending in sRGB space, and much
/// cheaper on software rasterisers); the scene is rendered in the sRGB variant and copied in,
/// which keeps its bytes. Copies into the surface are used where it allows them, unless
/// `TUMBLE_NO_SURFACE_COPY` is set (to exercise the fallback that draws the scene straight in).
fn configure_surface(
    surface: &wgpu::Surface<'_>,
    gpu: &Gpu,
    size: winit::dpi::PhysicalSize<u32>,
    vsync: bool,
) -> anyhow::Result<SurfaceSetup> {
    let caps = surface.get_capabilities(&gpu.adapter);
    let format = caps
        .formats
        .iter()
        .copied()
        .find(|f| !f.is_srgb() && f.add_srgb_suffix() != *f)
        .or_else(|| caps.formats.first().copied())
        .context("the window surface supports no format")?;
    let scene_format = format.add_srgb_suffix();
    let (width, height) = surface_size(gpu, size);
    let mut config = surface
        .get_default_config(&gpu.adapter, width, height)
        .context("the window surface is not supported by the adapter")?;
    config.format = format;
    config.view_formats = if scene_format != format {
        vec![scene_format]
    } else {
        Vec::new()
    };
    config.present_mode = if vsync {
        wgpu::PresentMode::AutoVsync
    } else {
        wgpu::PresentMode::AutoNoVsync
    };
    let copy_to_surface = caps.usages.contains(wgpu::TextureUsages::COPY_DST)
        && std::env::var_os("TUMBLE_NO_SURFACE_COPY").is_none();
    config.usage = wgpu::TextureUsages::RENDER_ATTACHMENT
        | if copy_to_surface {
            wgpu::TextureUsages::COPY_DST
        } else {
            wgpu::TextureUsages::empty()
        };
    surface.configure(&gpu.device, &config);
    Ok(SurfaceSetup {
        config,
        scene_format,
        copy_to_surface,
    })
}

/// egui's context (dark theme), its winit input state and its wgpu renderer for `format`.
fn egui_setup(
    window: &Window,
    gpu: &Gpu,
    format: wgpu::TextureFormat,
) -> (egui::Context, egui_winit::State, egui_wgpu::Renderer) {
    let egui_ctx = egui::Context::default();
    egui_ctx.set_visuals(egui::Visuals::dark());
    let max_texture_side = gpu.device.limits().max_texture_dimension_2d as usize;
    let egui_state = egui_winit::State::new(
        egui_ctx.clone(),
        egui::ViewportId::ROOT,
        window,
        Some(window.scale_factor() as f32),
        None,
        Some(max_texture_side),
    );
    let egui_renderer =
        egui_wgpu::Renderer::new(&gpu.device, format, egui_wgpu::RendererOptions::default());
    (egui_ctx, egui_state, egui_renderer)
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
