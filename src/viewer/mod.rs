//! The real-time viewer (`tumble view`) and the offscreen recorder (`tumble record`), on wgpu,
//! winit and egui. Built with the default `viewer` feature; the core does not depend on it.
//!
//! Drawing the scene (shared by the window, the recorder and the tests):
//! - [`renderer`]: the scene renderer: per-scene meshes and ground, one `layer` per world shown
//!   (instances, lines, shadow map), one instanced draw per shape, panes for compared worlds;
//!   [`OffscreenRenderer`] with its own device.
//! - [`shadow`]: the key light's shadow map: its fitted projection, texture and depth pipeline.
//! - `pipelines`: the scene shader's uniform and vertex formats and its render pipelines.
//! - `overlay`: line geometry built on the CPU: ground plane and grid, constraint segments,
//!   selection outline, grab, contact markers.
//! - `targets`: the depth and MSAA attachments of the scene pass, and [`renderer::DEPTH_FORMAT`].
//! - `readback`: the test-only [`Renderer::gpu_body_points`], the vertex transform run on the
//!   GPU and read back.
//! - [`gpu`]: adapter and device, buffer helpers, offscreen targets read back as [`Image`]s.
//! - [`camera`], [`picking`], [`palette`]: orbit camera, ray picking, colours.
//! - [`compare`]: how compared worlds share the view (panes, ghosts) and how they are named;
//!   `labels`: their labels, in the window and painted into recordings.
//!
//! The simulation as the viewer drives it (headless, what the tests use):
//! - [`session`]: stepping that follows wall-clock time, one world or two compared in lockstep,
//!   statistics and plots, rewind, grab and reloading.
//! - [`timeline`]: the rewind history, complete world states in a ring bounded by memory.
//! - [`grab`]: the mouse's spring on a body, through the core's `Grab`, or moving the pose while
//!   paused.
//! - [`scene_source`]: where the scene comes from (name, scene file, dropped mesh) and which
//!   files it is made of; `watch`: polling those files for changes.
//!
//! The window (`tumble view`):
//! - [`app`]: the application: its state, the per-frame sequence, actions and window events.
//! - `window`: display check, event loop, the window with its surface, device, renderer and
//!   egui state, and the 3D view's rectangle in it.
//! - `present`: a frame's upload, image acquisition and submission: the scene copied into the
//!   window (or drawn straight in where the surface takes no copies), egui over it, screenshots.
//! - `input`: orbit, pan, zoom, grab and picking with the mouse; keyboard shortcuts.
//! - `view_pointer`: camera rays through the view's panes, the grab under way.
//! - `frame_stats`: frame intervals, CPU work and time per phase; the summary printed at exit.
//! - `window_recording`: recording the view from the panel at simulated-time frame rate.
//! - [`panel`]: the egui side panel and the overlay over the view.
//!
//! Recording (`tumble record`):
//! - [`mod@record`]: MP4 (ffmpeg), GIF and PNG output, and the offscreen recording loop.

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
pub use window::MIN_WINDOW_SIZE;
