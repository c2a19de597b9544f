//! The real-time viewer (`tumble view`) and the offscreen recorder (`tumble record`), on wgpu,
//! winit and egui. Built with the default `viewer` feature; the core does not depend on it.
//!
//! - [`renderer`]: the wgpu scene renderer (instanced bodies, lines, ground grid), used by the
//!   window, the recorder and the tests alike.
//! - [`camera`], [`picking`], [`palette`]: orbit camera, ray picking, colours.
//! - [`session`]: stepping that follows wall-clock time, statistics and history.
//! - [`panel`]: the egui side panel. [`app`]: the window and its event loop.
//! - [`record`]: MP4 (ffmpeg), GIF and PNG output, and the recording loop.

pub mod app;
pub mod camera;
pub mod gpu;
mod overlay;
pub mod palette;
pub mod panel;
pub mod picking;
mod pipelines;
mod readback;
pub mod record;
pub mod renderer;
pub mod session;
mod targets;

pub use app::{ViewOptions, run as run_viewer};
pub use camera::OrbitCamera;
pub use gpu::{Gpu, Image, NoGpu, Offscreen};
pub use record::{FrameWriter, OutputKind, RecordOptions, RecordReport, record};
pub use renderer::{DrawOptions, OffscreenRenderer, Renderer};
