//! Where the viewer's scene comes from, so it can be loaded again when its files change: a scene
//! by name or path with its constraints, or one mesh file dropped on the window, which becomes a
//! one-body scene above the ground.

use crate::io::LoadError;
use crate::scene::default_constraints_path;
use crate::{ConstraintsChoice, RigidBody, Settings, World};
use glam::{DQuat, DVec3};
use std::path::{Path, PathBuf};

/// Density of a dropped mesh's body (that of tumble's own scenes).
const MESH_DENSITY: f64 = 1000.0;

#[derive(Debug, Clone, PartialEq)]
pub enum SceneSource {
    /// A built-in or generated scene name, or the path of an `X-scene.txt`.
    Scene {
        name: String,
        constraints: ConstraintsChoice,
    },
    /// A `.mesh` or `.off` file as the only body.
    Mesh(PathBuf),
}

impl SceneSource {
    /// A scene name or path with its constraints found beside it.
    pub fn named(name: &str) -> SceneSource {
        SceneSource::Scene {
            name: name.to_string(),
            constraints: ConstraintsChoice::Auto,
        }
    }

    /// What a file dropped on the window means: a mesh by its extension, else a scene file.
    pub fn dropped(path: &Path) -> SceneSource {
        if crate::scene::mesh_reader(path).is_some() {
            SceneSource::Mesh(path.to_path_buf())
        } else {
            SceneSource::named(&path.to_string_lossy())
        }
    }

    /// For display: the name or path given.
    pub fn name(&self) -> String {
        match self {
            SceneSource::Scene { name, .. } => name.clone(),
            SceneSource::Mesh(path) => path.display().to_string(),
        }
    }

    pub fn load(&self, settings: Settings) -> Result<World, LoadError> {
        match self {
            SceneSource::Scene { name, constraints } => {
                crate::scene::load(name, constraints, settings)
            }
            SceneSource::Mesh(path) => mesh_scene(path, settings),
        }
    }

    /// The files on disk the scene is built from (none for built-in and generated scenes): the
    /// scene file, its constraints (also when they do not exist yet) and its meshes.
    pub fn files(&self) -> Vec<PathBuf> {
        let (name, constraints) = match self {
            SceneSource::Mesh(path) => return vec![path.clone()],
            SceneSource::Scene { name, constraints } => (name, constraints),
        };
        let scene = PathBuf::from(name);
        if !scene.is_file() {
            return Vec::new();
        }
        let mut files = vec![scene.clone()];
        match constraints {
            ConstraintsChoice::Auto => files.extend(default_constraints_path(&scene)),
            ConstraintsChoice::File(path) => files.push(path.clone()),
            ConstraintsChoice::None => {}
        }
        for mesh in crate::scene::mesh_paths(&scene) {
            if !files.contains(&mesh) {
                files.push(mesh);
            }
        }
        files
    }
}

/// One body of the mesh at `path`, its lowest point half its height above the ground.
fn mesh_scene(path: &Path, settings: Settings) -> Result<World, LoadError> {
    let (shape, warning) = crate::scene::load_mesh_file(path)?;
    let (low, high) = shape
        .rest_vertices
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v.y), hi.max(v.y))
        });
    let position = DVec3::new(0.0, -low + 0.5 * (high - low), 0.0);
    let body = RigidBody::on_shape(&shape, 0, MESH_DENSITY, false, position, DQuat::IDENTITY);
    let name = path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into(),
    );
    let mut world = World::new(vec![shape], vec![name], vec![body], Vec::new(), settings);
    world.warnings.extend(warning);
    Ok(world)
}
