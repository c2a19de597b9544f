//! Helpers shared by the integration tests.
#![allow(dead_code)]

use glam::DVec3;
use std::path::PathBuf;
use tumble::Shape;
use tumble::io::TetMesh;

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
