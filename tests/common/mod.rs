//! Helpers shared by the integration tests.
#![allow(dead_code)]

use glam::{DQuat, DVec3};
use std::path::PathBuf;
use tumble::io::TetMesh;
use tumble::scene::assets;
use tumble::{RigidBody, Settings, Shape, World};

/// `../shared/coursework-data` beside the checkout, or None (tests then skip with a reason).
pub fn coursework_dir() -> Option<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/coursework-data");
    if dir.is_dir() {
        Some(dir)
    } else {
        eprintln!(
            "skipped: {} not found (the coursework data lives beside the checkout)",
            dir.display()
        );
        None
    }
}

pub fn shape(mesh: &TetMesh) -> Shape {
    Shape::from_tet_mesh(mesh).expect("valid mesh")
}

/// Relative closeness with an absolute floor.
pub fn assert_close(a: f64, b: f64, rel: f64, what: &str) {
    let scale = a.abs().max(b.abs()).max(1.0);
    assert!(
        (a - b).abs() <= rel * scale,
        "{what}: {a} vs {b} (diff {})",
        (a - b).abs()
    );
}

pub fn assert_vec_close(a: DVec3, b: DVec3, rel: f64, what: &str) {
    let scale = a.length().max(b.length()).max(1.0);
    assert!((a - b).length() <= rel * scale, "{what}: {a} vs {b}");
}

/// A 1-unit box thrown at 200 units/s along x at a fixed wall 1 unit thick (x = -0.5..0.5),
/// without gravity: the tunnelling case.
pub fn box_thrown_at_wall(settings: Settings) -> World {
    let ball = shape(&assets::cuboid(DVec3::splat(0.5)));
    let wall = shape(&assets::cuboid(DVec3::new(0.5, 20.0, 20.0)));
    let at = |x: f64| DVec3::new(x, 30.0, 0.0);
    let mut thrown = RigidBody::on_shape(&ball, 0, 100.0, false, at(-10.0), DQuat::IDENTITY);
    thrown.linear_velocity = DVec3::new(200.0, 0.0, 0.0);
    let fixed = RigidBody::on_shape(&wall, 1, 100.0, true, at(0.0), DQuat::IDENTITY);
    World::new(
        vec![ball, wall],
        vec!["ball".into(), "wall".into()],
        vec![thrown, fixed],
        Vec::new(),
        Settings {
            gravity: DVec3::ZERO,
            ..settings
        },
    )
}

/// `f` run on a pool of `threads` threads.
pub fn with_threads<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("thread pool")
        .install(f)
}
