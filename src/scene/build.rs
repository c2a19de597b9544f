//! Turning parsed scene and constraint records into a [`World`]: shapes loaded once per mesh
//! file, bodies on them, and each constraint record as a lower and an upper inequality.

use super::ConstraintsChoice;
use super::files::{Disk, FileSource};
use crate::io::{
    ConstraintRecord, LoadError, SceneRecord, TetMesh, counted, parse_constraints, parse_medit,
    parse_off, parse_scene,
};
use crate::sim::body::RigidBody;
use crate::sim::constraint::DistanceConstraint;
use crate::sim::settings::Settings;
use crate::sim::shape::{Shape, ShapeError};
use crate::sim::world::World;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

pub(super) fn load_with(
    source: &dyn FileSource,
    path: &Path,
    constraints: &ConstraintsChoice,
    settings: Settings,
) -> Result<World, LoadError> {
    let text = source.read(path)?;
    let scene = parse_scene(path, &text)?;
    let records = scene.records;
    let mut warnings: Vec<String> = scene.layout_warning.iter().map(|w| w.to_string()).collect();
    let folder = path.parent().unwrap_or(Path::new(""));

    let mut shapes = Vec::new();
    let mut shape_names = Vec::new();
    let mut shape_of_path: HashMap<PathBuf, usize> = HashMap::new();
    let mut bodies = Vec::with_capacity(records.len());
    for record in &records {
        let mesh_path = mesh_path_in(source, folder, &record.mesh_path);
        let shape_index = match shape_of_path.get(&mesh_path) {
            Some(&index) => index,
            None => {
                let shape = load_shape(source, &mesh_path, path, record)?;
                warnings.extend(mesh_warning(&shape, &mesh_path));
                shapes.push(shape);
                shape_names.push(record.mesh_path.clone());
                shape_of_path.insert(mesh_path, shapes.len() - 1);
                shapes.len() - 1
            }
        };
        if record.fixed && record.density < 0.0 {
            // Not an error: a fixed body has no mass to weigh, but a sign typed by mistake
            // should not pass unseen.
            let unused = format!(
                "the fixed body's density {} is negative; a fixed body's density is not used",
                crate::io::echoed(record.density)
            );
            warnings.push(LoadError::new(path, Some(record.line), unused).to_string());
        }
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
        // A folder under the constraint file's name is read, and refused as a folder, rather
        // than passed over in silence.
        ConstraintsChoice::Auto => super::default_constraints_path(path)
            .filter(|p| source.exists(p) || source.is_folder(p)),
    };
    let mut inputs: Vec<PathBuf> = Vec::new();
    if source.on_disk() {
        inputs.push(path.to_path_buf());
        inputs.extend(shape_of_path.into_keys());
    }
    let distance_constraints = match constraint_path {
        Some(cpath) => {
            let read = (source, constraints, &mut inputs, &mut warnings);
            load_constraints(&cpath, read, (&bodies, &shapes))?
        }
        None => Vec::new(),
    };
    let mut world = World::new(shapes, shape_names, bodies, distance_constraints, settings);
    warnings.extend(starting_overlaps(&world, path, &records));
    world.warnings = warnings;
    world.inputs = inputs;
    Ok(world)
}

/// The distance constraints of the file `cpath` between `bodies`; the file joins `inputs` where
/// it is on disk, and its warnings join `warnings`.
fn load_constraints(
    cpath: &Path,
    (source, constraints, inputs, warnings): (
        &dyn FileSource,
        &ConstraintsChoice,
        &mut Vec<PathBuf>,
        &mut Vec<String>,
    ),
    (bodies, shapes): (&[RigidBody], &[Shape]),
) -> Result<Vec<DistanceConstraint>, LoadError> {
    // A user-named file is read from disk even when the scene is built in.
    let text = match constraints {
        ConstraintsChoice::File(_) => Disk.read(cpath)?,
        _ => source.read(cpath)?,
    };
    // A mesh read as constraints failed on its first word ("expected the number of
    // constraints, found 'OFF'"), as a mesh read as a scene did.
    if mesh_reader(cpath).is_some() {
        let problem = "a mesh, not a constraint file: a constraint file lists distance records \
                       between vertices of the scene's bodies";
        return Err(LoadError::new(cpath, None, problem));
    }
    if source.on_disk() || matches!(constraints, ConstraintsChoice::File(_)) {
        inputs.push(cpath.to_path_buf());
    }
    let parsed = parse_constraints(cpath, &text)?;
    warnings.extend(parsed.layout_warning.map(|w| w.to_string()));
    let built = build_constraints(cpath, &parsed.records, bodies, shapes, warnings)?;
    warnings.extend(conflicting_bounds(cpath, &parsed.records, bodies, shapes));
    Ok(built)
}

/// Depth, as a share of the smaller body's least extent, from which a body that starts inside
/// another or below the ground is called out: the pile_rest bound (`bench accuracy`), under
/// which resting contacts' own sag lies. Deeper, the solvers push the bodies apart in the first
/// steps, with speeds the scene did not ask for (200 copies of one tetrahedron at one spot
/// gained 8 times their energy under the preset).
pub const STARTING_OVERLAP: f64 = 0.01;

/// Overlaps reported one by one at most; the rest are counted.
const OVERLAPS_LISTED: usize = 5;

/// A warning for each movable body that starts inside another body or below the ground
/// (y = 0), deeper than [`STARTING_OVERLAP`] of its size, on its record's line (of two movable
/// bodies, the later's: it is placed inside the earlier), in line order; past
/// [`OVERLAPS_LISTED`], one that counts the rest. `records[i]` is body i's record. (The depths
/// are those the coursework's detection finds, [`World::current_contacts`], whichever solver is
/// set: at the patch with `--contact-patches`.)
fn starting_overlaps(world: &World, path: &Path, records: &[SceneRecord]) -> Vec<String> {
    let size = |i: usize| world.shapes[world.bodies[i].shape].least_extent();
    let mut found: Vec<Overlap> = (world.current_contacts().into_iter())
        .filter_map(|(i, j, c)| {
            let smaller = j.map_or(size(i), |j| size(i).min(size(j)));
            (c.depth > STARTING_OVERLAP * smaller)
                .then(|| Overlap::new(world, (i, j), Some(c.depth)))
        })
        .collect();
    for (i, j) in same_places(world) {
        let same = Overlap::new(world, (i, Some(j)), None);
        if !(found.iter()).any(|o| (o.inside, o.other) == (same.inside, same.other)) {
            found.push(same);
        }
    }
    found.sort_by_key(|o| (records[o.inside].line, o.other.map(|b| records[b].line)));
    let mut warnings: Vec<String> = (found.iter().take(OVERLAPS_LISTED))
        .map(|o| o.warning(world, path, records).to_string())
        .collect();
    if found.len() > OVERLAPS_LISTED {
        let more = counted(
            (found.len() - OVERLAPS_LISTED) as u64,
            "more overlap",
            "more overlaps",
        );
        let what = format!("{more} at the start (a body inside another or below the ground)");
        warnings.push(LoadError::new(path, None, what).to_string());
    }
    warnings
}

/// Pairs of bodies, one of them movable, whose centres of mass start at the same point: a
/// record copied and not moved. The detection finds no depth between two bodies that coincide
/// (GJK ends on the origin), so they passed unwarned, and the soft step never parts them (no
/// normal to push along).
fn same_places(world: &World) -> Vec<(usize, usize)> {
    let mut first: std::collections::HashMap<[u64; 3], usize> = Default::default();
    let mut pairs = Vec::new();
    for (j, body) in world.bodies.iter().enumerate() {
        let key = body.position.to_array().map(f64::to_bits);
        match first.get(&key) {
            Some(&i) if !(world.bodies[i].fixed && body.fixed) => pairs.push((i, j)),
            Some(_) => {}
            None => {
                first.insert(key, j);
            }
        }
    }
    pairs
}

/// A body that starts `depth` inside body `other`, or below the ground (None); at the same
/// place as `other`, its depth unknown (None).
struct Overlap {
    inside: usize,
    other: Option<usize>,
    depth: Option<f64>,
}

impl Overlap {
    /// The overlap of contact `(i, j)`, told from the body that moves: the later of two movable
    /// bodies, the movable one of a movable and a fixed body.
    fn new(world: &World, (i, j): (usize, Option<usize>), depth: Option<f64>) -> Self {
        let (inside, other) = match j {
            Some(j) if world.bodies[i.max(j)].fixed => (i.min(j), Some(i.max(j))),
            Some(j) => (i.max(j), Some(i.min(j))),
            None => (i, None),
        };
        Self {
            inside,
            other,
            depth,
        }
    }

    fn warning(&self, world: &World, path: &Path, records: &[SceneRecord]) -> LoadError {
        let Some(depth) = self.depth.map(three_figures) else {
            let line = self.other.map_or(0, |b| records[b].line);
            let problem = format!(
                "the body starts at the same place as the body on line {line}, inside it (a record copied and not moved?)"
            );
            return LoadError::new(path, Some(records[self.inside].line), problem);
        };
        let problem = match self.other {
            Some(b) if world.bodies[b].fixed => format!(
                "the body starts {depth} deep inside the fixed body on line {}: the solver will push it out",
                records[b].line
            ),
            Some(b) => format!(
                "the body starts {depth} deep inside the body on line {}: the solver will push them apart",
                records[b].line
            ),
            None => format!(
                "the body starts {depth} below the ground (y = 0): the solver will push it up"
            ),
        };
        LoadError::new(path, Some(records[self.inside].line), problem)
    }
}

/// `x` (positive) to three significant figures: a depth of 2e-4 is not "0.000".
fn three_figures(x: f64) -> String {
    let decimals = (2 - x.log10().floor() as i64).clamp(0, 20) as usize;
    format!("{x:.decimals$}")
}

/// Below this share of its hull's volume a mesh is called out as not convex. Not 1: a coarse
/// tetrahedral mesh of a convex solid dents its surface (the coursework's cylinder.mesh fills
/// 96.7 % of its hull), and the course simulates it as it is.
const CONVEX: f64 = 0.9;

/// Above this share of its hull's volume a mesh's solid overlaps itself: a convex solid fills
/// its hull to rounding, a dented one less.
const OVERLAPPING: f64 = 1.0 + 1e-6;

/// A warning for a mesh that is not convex: the coursework's bodies are; tumble collides the
/// hull and weighs the mesh, so such a body rests and tumbles as neither would. Or for one
/// whose solid holds more than its hull (tetrahedra that overlap, or two closed surfaces one
/// inside the other): its volume, mass and inertia count the overlap twice.
fn convexity_warning(shape: &Shape, mesh_path: &Path) -> Option<String> {
    let share = shape.convexity();
    if share > OVERLAPPING {
        return Some(format!(
            "{}: the mesh overlaps itself (its volume is {:.1} % of its convex hull's: tetrahedra or surfaces counted twice): mass and inertia count the overlap twice",
            mesh_path.display(),
            100.0 * share
        ));
    }
    (share < CONVEX).then(|| {
        format!(
            "{}: the mesh is not convex (its volume is {:.1} % of its convex hull's): collisions use the hull, mass and inertia the mesh",
            mesh_path.display(),
            100.0 * share
        )
    })
}

/// A warning for a mesh with vertices that no tetrahedron (of a `.off` surface: no face) uses,
/// or else one that is not convex ([`convexity_warning`]). Such a vertex, a stray line of the
/// file or one whose tetrahedra were deleted, still shapes the convex hull that collides (as in
/// the coursework, whose narrow phase takes every vertex), though not the mass: named, since the
/// hull may not look dented enough to be called out as not convex (a box with a vertex 3 units
/// off one face fills 96 % of its hull).
fn mesh_warning(shape: &Shape, mesh_path: &Path) -> Option<String> {
    let Some(unused) = unused_vertices(mesh_path, shape.named_vertices, &shape.tetrahedra) else {
        return convexity_warning(shape, mesh_path);
    };
    let solid = match is_surface(mesh_path) {
        true => "the faces' solid",
        false => "the tetrahedra",
    };
    Some(format!(
        "{}: {unused}: collisions use the convex hull of every vertex, mass and inertia {solid} alone ({:.1} % of the hull's volume)",
        mesh_path.display(),
        100.0 * shape.convexity()
    ))
}

/// Whether `mesh_path` names an `.off` surface (numbered from 0, its solid made of its faces).
fn is_surface(mesh_path: &Path) -> bool {
    extension(mesh_path).as_deref() == Some("off")
}

/// A file's extension in lower case: mesh formats go by it, in any case.
fn extension(path: &Path) -> Option<String> {
    Some(path.extension()?.to_str()?.to_ascii_lowercase())
}

/// The first `named` vertices that none of `tetrahedra` uses, said in the file's numbering
/// ("2 vertices are used by no tetrahedron (the first: vertex 9)"), or None.
fn unused_vertices(mesh_path: &Path, named: usize, tetrahedra: &[[u32; 4]]) -> Option<String> {
    let mut used = vec![false; named];
    for &index in tetrahedra.iter().flatten() {
        if let Some(slot) = used.get_mut(index as usize) {
            *slot = true;
        }
    }
    let first = used.iter().position(|&u| !u)?;
    let unused = used.iter().filter(|&&u| !u).count() as u64;
    let (user, number) = match is_surface(mesh_path) {
        true => ("face", format!("{first} (0-based)")),
        false => ("tetrahedron", format!("{}", first + 1)),
    };
    let unused = counted(unused, "vertex is", "vertices are");
    Some(format!(
        "{unused} used by no {user} (the first: vertex {number})"
    ))
}

/// A reader of one mesh format: the file's path (for errors) and its text.
pub type MeshReader = fn(&Path, &str) -> Result<TetMesh, LoadError>;

/// The reader of a mesh file by its extension: `.mesh` (Medit) or `.off`, in any case.
pub fn mesh_reader(path: &Path) -> Option<MeshReader> {
    match extension(path)?.as_str() {
        "mesh" => Some(parse_medit),
        "off" => Some(parse_off),
        _ => None,
    }
}

/// A mesh file on disk as a shape, and a warning when it is not convex.
pub fn load_mesh_file(path: &Path) -> Result<(Shape, Option<String>), LoadError> {
    let parse =
        mesh_reader(path).ok_or_else(|| LoadError::new(path, None, "not a .mesh or .off file"))?;
    let shape = read_shape(&Disk, path, parse)?;
    let warning = mesh_warning(&shape, path);
    Ok((shape, warning))
}

fn read_shape(
    source: &dyn FileSource,
    mesh_path: &Path,
    parse: MeshReader,
) -> Result<Shape, LoadError> {
    let text = source.read(mesh_path)?;
    let mesh = parse(mesh_path, &text)?;
    Shape::from_tet_mesh(&mesh).map_err(|e| {
        let named = mesh.vertices.len().saturating_sub(mesh.added_vertices);
        let unused = unused_vertices(mesh_path, named, &mesh.tetrahedra);
        let problem = match (e, unused) {
            // A vertex far off the solid leaves a hull too thin to build (parry's, which
            // collisions use): not a flat mesh, as the error alone says.
            (ShapeError::NoHull, Some(unused)) => format!(
                "{unused}: the convex hull of every vertex, which collisions use, could not be built (a vertex far off the solid leaves it too thin)"
            ),
            (e, _) => e.to_string(),
        };
        LoadError::new(mesh_path, None, problem)
    })
}

/// The mesh files a scene file on disk names, as its load finds them (none where the scene
/// cannot be read or parsed): the files a viewer watches for changes.
pub fn mesh_paths(scene: &Path) -> Vec<PathBuf> {
    let Ok(text) = Disk.read(scene) else {
        return Vec::new();
    };
    let folder = scene.parent().unwrap_or(Path::new(""));
    let records = parse_scene(scene, &text).map(|r| r.records);
    let path = |r: &SceneRecord| mesh_path_in(&Disk, folder, &r.mesh_path);
    records.unwrap_or_default().iter().map(path).collect()
}

/// Where a scene's mesh path leads: from the scene's folder, its backslashes read as slashes
/// where the path as written names no file (a scene written on Windows, whose
/// `..\meshes\a.mesh` was "not found" here).
fn mesh_path_in(source: &dyn FileSource, folder: &Path, written: &str) -> PathBuf {
    let path = folder.join(written);
    if source.exists(&path) || !written.contains('\\') {
        return path;
    }
    let slashed = folder.join(written.replace('\\', "/"));
    if source.exists(&slashed) {
        slashed
    } else {
        path
    }
}

/// What may have led a scene's mesh path astray: a file whose name differs only in case (a
/// scene written where names ignore case), or a Windows drive path (only its backslashes are
/// read as slashes).
fn missing_mesh_hint(source: &dyn FileSource, mesh_path: &Path, written: &str) -> String {
    if let Some(alike) = source.named_alike(mesh_path) {
        let name = alike.file_name().map(|n| n.to_string_lossy().into_owned());
        return format!(
            "; '{}' beside it differs only in case, and names are case-sensitive here",
            name.unwrap_or_default()
        );
    }
    let drive = written.as_bytes();
    if drive.len() > 2 && drive[0].is_ascii_alphabetic() && drive[1] == b':' {
        return "; a Windows drive path: give the mesh's path relative to the scene file".into();
    }
    String::new()
}

fn load_shape(
    source: &dyn FileSource,
    mesh_path: &Path,
    scene_path: &Path,
    record: &SceneRecord,
) -> Result<Shape, LoadError> {
    let Some(parse) = mesh_reader(mesh_path) else {
        return Err(LoadError::new(
            scene_path,
            Some(record.line),
            format!(
                "mesh '{}' is neither a .mesh nor an .off file",
                record.mesh_path
            ),
        ));
    };
    if !source.exists(mesh_path) {
        let problem = match source.is_folder(mesh_path) {
            true => "is a folder, not a file",
            false => "not found",
        };
        return Err(LoadError::new(
            scene_path,
            Some(record.line),
            format!(
                "mesh file '{}' {problem} (looked for {}){}",
                record.mesh_path,
                mesh_path.display(),
                missing_mesh_hint(source, mesh_path, &record.mesh_path)
            ),
        ));
    }
    read_shape(source, mesh_path, parse)
}

/// A warning for each pair of points whose records' ranges have nothing in common (`0.5 0.6` and
/// `1.4 1.5` on the same two vertices): no distance satisfies them all, so they stay violated.
/// The bounds of one pair are fractions of the same distance, so they compare as they are;
/// points that start together (all fractions of 0 are 0) and records between two fixed bodies
/// (dropped, with their own warning) conflict in nothing. The records' indices are valid.
fn conflicting_bounds(
    file: &Path,
    records: &[ConstraintRecord],
    bodies: &[RigidBody],
    shapes: &[Shape],
) -> Vec<String> {
    let pair = |r: &ConstraintRecord| {
        let (a, b) = ((r.body1, r.vertex1), (r.body2, r.vertex2));
        if a <= b { (a, b) } else { (b, a) }
    };
    let point = |(body, vertex): (usize, usize)| {
        let b = &bodies[body];
        b.world_point(shapes[b.shape].rest_vertices[vertex])
    };
    let counts = |r: &&ConstraintRecord| {
        let (a, b) = pair(r);
        !(bodies[a.0].fixed && bodies[b.0].fixed) && point(a) != point(b)
    };
    let records: Vec<&ConstraintRecord> = records.iter().filter(counts).collect();
    let mut order: Vec<usize> = (0..records.len()).collect();
    order.sort_by_key(|&k| (pair(records[k]), k));
    let mut warnings = Vec::new();
    for group in order.chunk_by(|&i, &j| pair(records[i]) == pair(records[j])) {
        // The record with the highest lower bound against the one with the lowest upper.
        let highest = group
            .iter()
            .max_by(|&&i, &&j| records[i].lower.total_cmp(&records[j].lower));
        let lowest = group
            .iter()
            .min_by(|&&i, &&j| records[i].upper.total_cmp(&records[j].upper));
        if let (Some(&h), Some(&l)) = (highest, lowest)
            && records[h].lower > records[l].upper
        {
            let (first, second) = (h.min(l), h.max(l));
            warnings.push(format!(
                "{}:{}: this record's bounds and those on line {} leave no distance between the same two points: they stay violated",
                file.display(),
                records[second].line,
                records[first].line,
            ));
        }
    }
    warnings
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
                        "body index {body} is out of range: the scene has {} (indices count from 0, in the scene file's order)",
                        crate::io::counted(bodies.len() as u64, "body", "bodies")
                    ),
                ));
            }
            // An .off surface's fan apex, which the reader adds, is not the file's to name.
            let count = shapes[bodies[body].shape].named_vertices;
            if vertex >= count {
                return Err(LoadError::new(
                    file,
                    Some(r.line),
                    format!(
                        "vertex index {vertex} is out of range: body {body}'s mesh has {} (indices count from 0)",
                        crate::io::counted(count as u64, "vertex", "vertices")
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
        if r.lower > 1.0 || r.upper < 1.0 {
            warnings.push(format!(
                "{}:{}: the bounds {} and {} leave out the distance the scene starts at (bounds are fractions of it, so 1): the first steps pull bodies {} and {} into range",
                file.display(),
                r.line,
                r.lower,
                r.upper,
                r.body1,
                r.body2
            ));
        }
        let pair = DistanceConstraint::lower_and_upper(
            bodies,
            shapes,
            (r.body1, r.vertex1),
            (r.body2, r.vertex2),
            r.lower,
            r.upper,
        );
        // Bounds are fractions of the starting distance: 1e308 of a distance of 2 is no length
        // (its bodies blew up in the first step and were frozen).
        if let Some(c) = pair.iter().find(|c| !c.reference.is_finite()) {
            let bound = if c.is_upper { r.upper } else { r.lower };
            return Err(LoadError::new(
                file,
                Some(r.line),
                format!(
                    "the bound {bound:e} times the starting distance {} is too large a length (bounds are fractions of the distance the scene starts at)",
                    c.rest_length
                ),
            ));
        }
        out.extend(pair);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::three_figures;

    #[test]
    fn depths_are_told_to_three_significant_figures() {
        let told = [1.456, 0.333, 0.15, 0.028868, 2.04e-4, 123.4].map(three_figures);
        assert_eq!(
            told,
            ["1.46", "0.333", "0.150", "0.0289", "0.000204", "123"]
        );
    }
}
