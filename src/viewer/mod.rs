//! The real-time viewer (`tumble view`) and the offscreen recorder (`tumble record`), on wgpu,
//! winit and egui. Built with the default `viewer` feature; the core does not depend on it.
//!
//! Drawing the scene (shared by the window, the recorder and the tests):
//! - [`renderer`]: the scene renderer: per-scene meshes and ground, per-frame instances and
//!   lines, one instanced draw per shape; [`OffscreenRenderer`] with its own device.
//! - `pipelines`: the scene shader's uniform and vertex formats and its render pipelines.
//! - `overlay`: line geometry built on the CPU: ground plane and grid, constraint segments,
//!   selection outline, contact markers.
//! - `targets`: the depth and MSAA attachments of the scene pass, and [`renderer::DEPTH_FORMAT`].
//! - `readback`: the test-only [`Renderer::gpu_body_points`], the vertex transform run on the
//!   GPU and read back.
//! - [`gpu`]: adapter and device, buffer helpers, offscreen targets read back as [`Image`]s.
//! - [`camera`], [`picking`], [`palette`]: orbit camera, ray picking, colours.
//!
//! The window (`tumble view`):
//! - [`app`]: the application: its state, the per-frame sequence, actions and window events.
//! - `window`: display check, event loop, the window with its surface, device, renderer and
//!   egui state, and the 3D view's rectangle in it.
//! - `present`: a frame's upload, image acquisition and submission: the scene copied into the
//!   window (or drawn straight in where the surface takes no copies), egui over it, screenshots.
//! - `input`: orbit, pan, zoom and picking with the mouse; keyboard shortcuts.
//! - `frame_stats`: frame intervals, CPU work and time per phase; the summary printed at exit.
//! - `window_recording`: recording the view from the panel at simulated-time frame rate.
//! - [`panel`]: the egui side panel and the overlay over the view.
//! - [`session`]: stepping that follows wall-clock time, statistics and history.
//!
//! Recording (`tumble record`):
//! - [`record`]: MP4 (ffmpeg), GIF and PNG output, and the offscreen recording loop.

pub mod app;
pub mod camera;
pub mod compare;
mod frame_stats;
pub mod gpu;
pub mod grab;
mod input;
mod labels;
mod layer;
mod overlay;
pub mod palette;
pub mod panel;
pub mod picking;
mod pipelines;
mod present;
mod readback;
pub mod record;
pub mod renderer;
pub mod scene_source;
pub mod session;
pub mod shadow;
mod targets;
pub mod timeline;
mod view_pointer;
mod watch;
mod window;
mod window_recording;

pub use app::{ViewOptions, run as run_viewer};
pub use camera::OrbitCamera;
pub use compare::Layout;
pub use gpu::{Gpu, Image, NoGpu, Offscreen};
pub use record::{FrameWriter, OutputKind, RecordOptions, RecordReport, record};
pub use renderer::{DrawOptions, OffscreenRenderer, Renderer};
pub use scene_source::SceneSource;
pub use session::Session;
