//! Entry points shared by the `cargo fuzz` targets (fuzz/) and the stable corpus-replay test:
//! each feeds arbitrary bytes to one reader and, when it loads, builds what the simulation would
//! build from it. Any panic is a bug; errors are the expected outcome for garbage.

use crate::io::{parse_constraints, parse_medit, parse_off, parse_scene};
use crate::sim::settings::Settings;
use crate::sim::shape::Shape;
use std::path::Path;

/// The bytes as a file on disk is read: decoded as the readers take text.
fn text(data: &[u8]) -> Option<String> {
    crate::io::decode_text(Path::new("fuzz"), data.to_vec()).ok()
}

/// A mesh that loads becomes a shape, a body and a few simulated steps.
fn exercise_mesh(mesh: &crate::io::TetMesh) {
    if let Ok(shape) = Shape::from_tet_mesh(mesh) {
        let body = crate::RigidBody::on_shape(
            &shape,
            0,
            1.0,
            false,
            glam::DVec3::new(0.0, 5.0, 0.0),
            glam::DQuat::IDENTITY,
        );
        if body.inverse_mass.is_finite() && body.inverse_inertia.is_finite() {
            let mut world = crate::World::new(
                vec![shape],
                vec!["fuzz".into()],
                vec![body],
                Vec::new(),
                Settings::default(),
            );
            for _ in 0..3 {
                world.step();
            }
        }
    }
}

pub fn medit(data: &[u8]) {
    if let Some(t) = text(data)
        && let Ok(mesh) = parse_medit(Path::new("fuzz.mesh"), &t)
    {
        exercise_mesh(&mesh);
    }
}

pub fn off(data: &[u8]) {
    if let Some(t) = text(data)
        && let Ok(mesh) = parse_off(Path::new("fuzz.off"), &t)
    {
        exercise_mesh(&mesh);
    }
}

pub fn scene(data: &[u8]) {
    if let Some(t) = text(data) {
        let _ = parse_scene(Path::new("fuzz-scene.txt"), &t);
    }
}

pub fn constraints(data: &[u8]) {
    if let Some(t) = text(data) {
        let _ = parse_constraints(Path::new("fuzz-constraints.txt"), &t);
    }
}

/// Target by name, for the replay test.
pub fn by_name(name: &str) -> Option<fn(&[u8])> {
    match name {
        "medit" => Some(medit),
        "off" => Some(off),
        "scene" => Some(scene),
        "constraints" => Some(constraints),
        _ => None,
    }
}
