//! tumble: a rigid-body simulator of convex tetrahedral meshes with inequality distance
//! constraints, reproducing by default the CGGS rigid-body coursework's method and improving on
//! it through opt-in settings.
//!
//! Rooms (see docs/architecture.md), arrows pointing inward only:
//! - [`sim`]: the headless core (world, bodies, shapes, the stages of a step, settings, stats);
//! - [`io`]: file formats, writers, files that appear whole or not at all;
//! - [`scene`]: building worlds from files, built-in and generated scenes, tumble's meshes;
//! - [`mod@bench`]: accuracy scenarios and the benchmarks (drivers and plots with feature `bench`);
//! - `viewer` (feature `viewer`): the wgpu/winit/egui window and the recorder.
//!
//! The command line lives in the binary (`src/main.rs`, `src/cli/`).
//!
//! These docs are for those who work on tumble, and link to private items: build them with
//! `cargo doc --no-deps --document-private-items`.
#![allow(rustdoc::private_intra_doc_links)]

pub mod bench;
pub mod io;
pub mod scene;
pub mod sim;
#[cfg(feature = "viewer")]
pub mod viewer;

pub use io::LoadError;
pub use scene::{BUILTIN_SCENES, ConstraintsChoice, DEFAULT_SCENE};
pub use sim::{RigidBody, Settings, Shape, StepStats, World};
