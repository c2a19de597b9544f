//! tumble: a rigid-body simulator of convex tetrahedral meshes with inequality distance
//! constraints, reproducing (by default, exactly) the CGGS rigid-body coursework and improving on
//! it through opt-in settings.
//!
//! The core is headless, f64 throughout and deterministic. A [`World`] owns bodies, shapes and
//! constraints in flat arrays; [`World::step`] runs the stages in order: integrate, broad phase,
//! narrow phase and contact resolution, ground contacts, constraints, pose check.

pub mod accuracy;
pub mod assets;
pub mod body;
pub mod broad_phase;
pub mod constraint;
pub mod contact;
pub mod formats;
pub mod fuzzing;
pub mod generate;
pub mod integrate;
pub mod interrupt;
pub mod narrow_phase;
pub mod output;
pub mod scene;
pub mod settings;
pub mod shape;
pub mod stats;
#[cfg(feature = "viewer")]
pub mod viewer;
pub mod world;

pub use body::{BodyId, RigidBody};
pub use formats::LoadError;
pub use scene::{BUILTIN_SCENES, ConstraintsChoice, DEFAULT_SCENE};
pub use settings::Settings;
pub use shape::Shape;
pub use stats::StepStats;
pub use world::World;
