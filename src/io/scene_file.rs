//! Scene files: a count N, then N records `mesh_path density is_fixed x y z qw qx qy qz`
//! separated by any white space. Mesh paths are relative to the scene file's folder.

use super::limits::MAX_BODIES;
use super::tokens::{RecordLayout, Tokens};
use super::{LoadError, Records};
use glam::{DQuat, DVec3};
use std::path::Path;

#[derive(Debug, Clone, PartialEq)]
pub struct SceneRecord {
    pub mesh_path: String,
    pub density: f64,
    pub fixed: bool,
    pub position: DVec3,
    /// Normalised on load.
    pub orientation: DQuat,
    /// Line of the record in the scene file, for errors found later (mesh loading, mass).
    pub line: usize,
}

const BODY_RECORD: RecordLayout = RecordLayout {
    name: "a body record",
    fields: &[
        "mesh", "density", "is_fixed", "x", "y", "z", "qw", "qx", "qy", "qz",
    ],
};

/// The records of scene file `file` holding `text`. A constraint file given as a scene is said
/// to be one (its count and records fail as bodies in ways that do not say so).
pub fn parse_scene(file: &Path, text: &str) -> Result<Records<SceneRecord>, LoadError> {
    read_scene(file, text).map_err(|error| {
        match super::constraint_file::read_constraints(file, text) {
            Ok(read) if !read.records.is_empty() => error.noting(
                "it reads as a constraint file (m1 v1 m2 v2 lower upper): give it with --constraints beside its scene",
            ),
            _ => error,
        }
    })
}

pub(super) fn read_scene(file: &Path, text: &str) -> Result<Records<SceneRecord>, LoadError> {
    let mut tokens = Tokens::new(file, text);
    let count = tokens.count_records("the number of bodies", &BODY_RECORD, MAX_BODIES)?;
    let mut records = Vec::with_capacity(count);
    for _ in 0..count {
        let name = tokens.next("a mesh file name")?;
        let (mesh_path, line) = (name.text.to_string(), name.line);
        let (density, density_line) = tokens.real("the density")?;
        let (fixed, fixed_line) = tokens.index("the is_fixed flag (0 or 1)")?;
        if fixed > 1 {
            return Err(tokens.error(
                fixed_line,
                format!("the is_fixed flag must be 0 or 1, found {fixed}"),
            ));
        }
        let fixed = fixed == 1;
        if !fixed && density <= 0.0 {
            return Err(tokens.error(
                density_line,
                format!(
                    "a movable body needs a positive density, found {}",
                    super::echoed(density)
                ),
            ));
        }
        let (x, _) = tokens.real("the x position")?;
        let (y, _) = tokens.real("the y position")?;
        let (z, _) = tokens.real("the z position")?;
        let (qw, q_line) = tokens.real("the quaternion w")?;
        let (qx, _) = tokens.real("the quaternion x")?;
        let (qy, _) = tokens.real("the quaternion y")?;
        let (qz, _) = tokens.real("the quaternion z")?;
        let Some(orientation) = normalised(DQuat::from_xyzw(qx, qy, qz, qw)) else {
            return Err(tokens.error(
                q_line,
                "the orientation quaternion is zero and cannot be normalised",
            ));
        };
        records.push(SceneRecord {
            mesh_path,
            density,
            fixed,
            position: DVec3::new(x, y, z),
            orientation,
            line,
        });
    }
    tokens.expect_end(&super::counted(count as u64, "body", "bodies"))?;
    Ok(Records {
        records,
        layout_warning: tokens.layout_warning(),
    })
}

/// The unit quaternion along `q` (finite components), or None for the zero quaternion. Any
/// other is a rotation, however large or small its components: scaled by the largest first,
/// so that their squares neither overflow nor underflow (before stop 67 a length of 1e-12 or
/// less was called zero, while one whose squares overflowed was scaled).
fn normalised(q: DQuat) -> Option<DQuat> {
    let largest = glam::DVec4::from(q).abs().max_element();
    (largest > 0.0).then(|| {
        let scaled = q / largest;
        scaled / scaled.length()
    })
}
