//! Building a [`World`] from scene and constraint files, on disk or built into the binary.

use crate::body::RigidBody;
use crate::constraint::DistanceConstraint;
use crate::formats::{
    ConstraintRecord, LoadError, SceneRecord, TetMesh, limits, parse_constraints, parse_medit,
    parse_off, parse_scene,
};
use crate::settings::Settings;
use crate::shape::Shape;
use crate::world::World;
use std::collections::HashMap;
use std::path::{Component, Path, PathBuf};

/// Which constraints to load with a scene.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum ConstraintsChoice {
    /// `X-constraints.txt` beside `X-scene.txt` when it exists.
    #[default]
    Auto,
    None,
    File(PathBuf),
}

impl ConstraintsChoice {
    /// Parses the CLI's `--constraints FILE|none`.
    pub fn from_arg(arg: Option<&str>) -> Self {
        match arg {
            None => Self::Auto,
            Some(s) if s.eq_ignore_ascii_case("none") => Self::None,
            Some(s) => Self::File(PathBuf::from(s)),
        }
    }
}

/// The scenes built into the binary: (name, scene file under `scenes/`).
pub const BUILTIN_SCENES: &[(&str, &str)] = &[
    ("mixed", "mixed-scene.txt"),
    ("tower", "tower-scene.txt"),
    ("two-chain", "two-chain-scene.txt"),
    ("cube", "cube-scene.txt"),
    ("stress", "stress-scene.txt"),
    ("two-cylinders", "two-cylinders-scene.txt"),
];

pub const DEFAULT_SCENE: &str = "mixed";

/// Files compiled into the binary, addressed by their path in the repository.
const EMBEDDED: &[(&str, &str)] = &[
    (
        "scenes/mixed-scene.txt",
        include_str!("../scenes/mixed-scene.txt"),
    ),
    (
        "scenes/tower-scene.txt",
        include_str!("../scenes/tower-scene.txt"),
    ),
    (
        "scenes/two-chain-scene.txt",
        include_str!("../scenes/two-chain-scene.txt"),
    ),
    (
        "scenes/two-chain-constraints.txt",
        include_str!("../scenes/two-chain-constraints.txt"),
    ),
    (
        "scenes/cube-scene.txt",
        include_str!("../scenes/cube-scene.txt"),
    ),
    (
        "scenes/cube-constraints.txt",
        include_str!("../scenes/cube-constraints.txt"),
    ),
    (
        "scenes/stress-scene.txt",
        include_str!("../scenes/stress-scene.txt"),
    ),
    (
        "scenes/two-cylinders-scene.txt",
        include_str!("../scenes/two-cylinders-scene.txt"),
    ),
    (
        "scenes/two-cylinders-constraints.txt",
        include_str!("../scenes/two-cylinders-constraints.txt"),
    ),
    (
        "assets/tetrahedron.mesh",
        include_str!("../assets/tetrahedron.mesh"),
    ),
    ("assets/box.mesh", include_str!("../assets/box.mesh")),
    (
        "assets/octahedron.mesh",
        include_str!("../assets/octahedron.mesh"),
    ),
    (
        "assets/long-octahedron.mesh",
        include_str!("../assets/long-octahedron.mesh"),
    ),
    (
        "assets/cylinder.mesh",
        include_str!("../assets/cylinder.mesh"),
    ),
    (
        "assets/ellipsoid.mesh",
        include_str!("../assets/ellipsoid.mesh"),
    ),
];

/// Where scene, mesh and constraint files are read from.
trait FileSource {
    fn read(&self, path: &Path) -> Result<String, LoadError>;
    fn exists(&self, path: &Path) -> bool;
}

struct Disk;

impl FileSource for Disk {
    fn read(&self, path: &Path) -> Result<String, LoadError> {
        let meta = std::fs::metadata(path)
            .map_err(|e| LoadError::new(path, None, format!("cannot open: {e}")))?;
        if meta.is_dir() {
            return Err(LoadError::new(path, None, "is a directory, not a file"));
        }
        if meta.len() > limits::MAX_FILE_BYTES {
            return Err(LoadError::new(
                path,
                None,
                format!(
                    "file is {} bytes, more than the limit of {}",
                    meta.len(),
                    limits::MAX_FILE_BYTES
                ),
            ));
        }
        let bytes = std::fs::read(path)
            .map_err(|e| LoadError::new(path, None, format!("cannot read: {e}")))?;
        String::from_utf8(bytes).map_err(|e| {
            LoadError::new(
                path,
                None,
                format!(
                    "not a text file (invalid UTF-8 at byte {})",
                    e.utf8_error().valid_up_to()
                ),
            )
        })
    }
    fn exists(&self, path: &Path) -> bool {
        path.is_file()
    }
}

struct Embedded;

impl Embedded {
    fn key(path: &Path) -> String {
        let mut parts: Vec<String> = Vec::new();
        for component in path.components() {
            match component {
                Component::ParentDir => {
                    parts.pop();
                }
                Component::Normal(s) => parts.push(s.to_string_lossy().into_owned()),
                _ => {}
            }
        }
        parts.join("/")
    }
}

impl FileSource for Embedded {
    fn read(&self, path: &Path) -> Result<String, LoadError> {
        let key = Self::key(path);
        EMBEDDED
            .iter()
            .find(|(name, _)| *name == key)
            .map(|(_, text)| text.to_string())
            .ok_or_else(|| LoadError::new(path, None, "no such file among the built-in scenes"))
    }
    fn exists(&self, path: &Path) -> bool {
        let key = Self::key(path);
        EMBEDDED.iter().any(|(name, _)| *name == key)
    }
}

/// Text of a built-in file (used by the asset tests and `tumble scenes`).
pub fn embedded_file(path: &str) -> Option<&'static str> {
    EMBEDDED
        .iter()
        .find(|(name, _)| *name == path)
        .map(|(_, text)| *text)
}

/// Loads a scene by path, or by built-in name when no such file exists.
pub fn load(
    scene: &str,
    constraints: &ConstraintsChoice,
    settings: Settings,
) -> Result<World, LoadError> {
    let path = Path::new(scene);
    if path.exists() {
        return load_file(path, constraints, settings);
    }
    if let Some(world) = generated(scene, &settings) {
        return Ok(world);
    }
    match BUILTIN_SCENES.iter().find(|(name, _)| *name == scene) {
        Some((_, file)) => load_with(
            &Embedded,
            &Path::new("scenes").join(file),
            constraints,
            settings,
        ),
        None => {
            let names: Vec<&str> = BUILTIN_SCENES.iter().map(|(n, _)| *n).collect();
            Err(LoadError::new(
                path,
                None,
                format!(
                    "no such file, and not a built-in scene (built-in: {}; generated: sparse-N, pile-N, chain-N)",
                    names.join(", ")
                ),
            ))
        }
    }
}

/// `sparse-N`, `pile-N` or `chain-N` (N at most 1,000,000): a generated scene.
fn generated(name: &str, settings: &Settings) -> Option<World> {
    let (kind, n) = name.rsplit_once('-')?;
    let n: usize = n.parse().ok().filter(|n| (1..=1_000_000).contains(n))?;
    crate::generate::by_name(kind, n, settings.clone())
}

/// Loads a scene file from disk; mesh paths are relative to its folder.
pub fn load_file(
    path: &Path,
    constraints: &ConstraintsChoice,
    settings: Settings,
) -> Result<World, LoadError> {
    load_with(&Disk, path, constraints, settings)
}

/// `X-constraints.txt` for `X-scene.txt`.
pub fn default_constraints_path(scene: &Path) -> Option<PathBuf> {
    let name = scene.file_name()?.to_str()?;
    let stem = name.strip_suffix("-scene.txt")?;
    Some(scene.with_file_name(format!("{stem}-constraints.txt")))
}

fn load_with(
    source: &dyn FileSource,
    path: &Path,
    constraints: &ConstraintsChoice,
    settings: Settings,
) -> Result<World, LoadError> {
    let text = source.read(path)?;
    let records = parse_scene(path, &text)?;
    let folder = path.parent().unwrap_or(Path::new(""));

    let mut shapes = Vec::new();
    let mut shape_names = Vec::new();
    let mut shape_of_path: HashMap<PathBuf, usize> = HashMap::new();
    let mut bodies = Vec::with_capacity(records.len());
    for record in &records {
        let mesh_path = folder.join(&record.mesh_path);
        let shape_index = match shape_of_path.get(&mesh_path) {
            Some(&index) => index,
            None => {
                let shape = load_shape(source, &mesh_path, path, record)?;
                shapes.push(shape);
                shape_names.push(record.mesh_path.clone());
                shape_of_path.insert(mesh_path, shapes.len() - 1);
                shapes.len() - 1
            }
        };
        let shape = &shapes[shape_index];
        let body = RigidBody::on_shape(
            shape,
            shape_index,
            record.density,
            record.fixed,
            record.position,
            record.orientation,
        );
        let invertible = body.inverse_mass.is_finite()
            && body.inverse_inertia.is_finite()
            && body.inverse_mass > 0.0;
        if !body.fixed && !invertible {
            return Err(LoadError::new(
                path,
                Some(record.line),
                "the body's mass or inertia is not invertible (density or mesh too small or too large)",
            ));
        }
        bodies.push(body);
    }

    let constraint_path = match constraints {
        ConstraintsChoice::None => None,
        ConstraintsChoice::File(p) => Some(p.clone()),
        ConstraintsChoice::Auto => default_constraints_path(path).filter(|p| source.exists(p)),
    };
    let mut warnings = Vec::new();
    let mut distance_constraints = Vec::new();
    if let Some(cpath) = constraint_path {
        // A user-named file is read from disk even when the scene is built in.
        let text = match constraints {
            ConstraintsChoice::File(_) => Disk.read(&cpath)?,
            _ => source.read(&cpath)?,
        };
        let records = parse_constraints(&cpath, &text)?;
        distance_constraints =
            build_constraints(&cpath, &records, &bodies, &shapes, &mut warnings)?;
    }
    let mut world = World::new(shapes, shape_names, bodies, distance_constraints, settings);
    world.warnings = warnings;
    Ok(world)
}

fn load_shape(
    source: &dyn FileSource,
    mesh_path: &Path,
    scene_path: &Path,
    record: &SceneRecord,
) -> Result<Shape, LoadError> {
    let extension = mesh_path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    let parse: fn(&Path, &str) -> Result<TetMesh, LoadError> = match extension.as_deref() {
        Some("mesh") => parse_medit,
        Some("off") => parse_off,
        _ => {
            return Err(LoadError::new(
                scene_path,
                Some(record.line),
                format!(
                    "mesh '{}' is neither a .mesh nor an .off file",
                    record.mesh_path
                ),
            ));
        }
    };
    if !source.exists(mesh_path) {
        return Err(LoadError::new(
            scene_path,
            Some(record.line),
            format!(
                "mesh file '{}' not found (looked for {})",
                record.mesh_path,
                mesh_path.display()
            ),
        ));
    }
    let text = source.read(mesh_path)?;
    let mesh = parse(mesh_path, &text)?;
    Shape::from_tet_mesh(&mesh).map_err(|e| LoadError::new(mesh_path, None, e.to_string()))
}

/// Each record becomes a lower and an upper inequality on the distance between the two vertices,
/// relative to their distance `d0` once the scene is placed.
fn build_constraints(
    file: &Path,
    records: &[ConstraintRecord],
    bodies: &[RigidBody],
    shapes: &[Shape],
    warnings: &mut Vec<String>,
) -> Result<Vec<DistanceConstraint>, LoadError> {
    let mut out = Vec::with_capacity(2 * records.len());
    for r in records {
        for (body, vertex) in [(r.body1, r.vertex1), (r.body2, r.vertex2)] {
            if body >= bodies.len() {
                return Err(LoadError::new(
                    file,
                    Some(r.line),
                    format!(
                        "body index {body} is out of range: the scene has {} bodies",
                        bodies.len()
                    ),
                ));
            }
            let count = shapes[bodies[body].shape].rest_vertices.len();
            if vertex >= count {
                return Err(LoadError::new(
                    file,
                    Some(r.line),
                    format!(
                        "vertex index {vertex} is out of range: body {body}'s mesh has {count} vertices"
                    ),
                ));
            }
        }
        if r.body1 == r.body2 {
            return Err(LoadError::new(
                file,
                Some(r.line),
                format!(
                    "a constraint needs two different bodies, both are {}",
                    r.body1
                ),
            ));
        }
        let (b1, b2) = (&bodies[r.body1], &bodies[r.body2]);
        if b1.fixed && b2.fixed {
            warnings.push(format!(
                "{}:{}: constraint between two fixed bodies ({} and {}) ignored",
                file.display(),
                r.line,
                r.body1,
                r.body2
            ));
            continue;
        }
        out.extend(DistanceConstraint::lower_and_upper(
            bodies,
            shapes,
            (r.body1, r.vertex1),
            (r.body2, r.vertex2),
            r.lower,
            r.upper,
        ));
    }
    Ok(out)
}
