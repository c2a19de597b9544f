//! The simulation core: headless, f64 throughout, deterministic. A [`World`] owns bodies,
//! shapes and constraints in flat arrays; [`World::step`] runs the stages of one step, each in
//! its own module with its own state type, and returns [`StepStats`].
//!
//! Nothing here knows about files, screens or command lines: `io`, `scene`, `bench`, the viewer
//! and the CLI depend on this module, never the reverse.

pub mod aabb;
pub mod body;
pub mod broad_phase;
pub mod buffer;
pub mod cell_table;
pub mod clock;
pub mod constraint;
pub mod contact_patch;
pub mod coursework;
pub mod grab;
pub mod grid;
pub mod integrate;
pub mod narrow_phase;
pub mod pair_queue;
pub mod parallel;
pub mod quarantine;
pub mod rng;
pub mod settings;
pub mod shape;
pub mod soft_step;
pub mod stats;
pub mod step_context;
pub mod sym_mat3;
pub mod world;

pub use body::RigidBody;
pub use constraint::DistanceConstraint;
pub use grab::Grab;
pub use settings::{Choice, Settings};
pub use shape::{Shape, TetMesh, TetVolumes};
pub use stats::{Stage, StepStats};
pub use world::{World, WorldState};
