//! Every kind of bad input is an error naming the file, the line and the problem; none panics.
mod common;

use std::path::PathBuf;
use tumble::{ConstraintsChoice, LoadError, Settings};

struct Dir(PathBuf);

impl Dir {
    fn new(name: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("tumble-bad-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Dir(dir)
    }
    fn write(&self, name: &str, text: &str) -> PathBuf {
        let p = self.0.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }
}

impl Drop for Dir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

const TET: &str = "MeshVersionFormatted 1\nDimension 3\nVertices\n4\n0 0 0 0\n1 0 0 0\n0 1 0 0\n0 0 1 0\nTetrahedra\n1\n1 2 3 4 0\nEnd\n";

fn load(dir: &Dir, scene: &str, constraints: Option<&str>) -> Result<tumble::World, LoadError> {
    let path = dir.write("s-scene.txt", scene);
    if let Some(c) = constraints {
        dir.write("s-constraints.txt", c);
    }
    tumble::scene::load_file(&path, &ConstraintsChoice::Auto, Settings::default())
}

fn expect(err: Result<tumble::World, LoadError>, file: &str, line: Option<usize>, words: &str) {
    let err = match err {
        Ok(_) => panic!("expected an error mentioning '{words}'"),
        Err(e) => e,
    };
    assert!(
        err.file.ends_with(file),
        "error names {} not {file}: {err}",
        err.file.display()
    );
    assert_eq!(err.line, line, "wrong line in: {err}");
    assert!(
        err.message.contains(words),
        "message '{}' lacks '{words}'",
        err.message
    );
    // Display gives file:line: message.
    let shown = err.to_string();
    assert!(shown.contains(file) && shown.contains(&err.message));
}

#[test]
fn missing_files() {
    let dir = Dir::new("missing");
    expect(
        tumble::scene::load_file(
            &dir.0.join("nope.txt"),
            &ConstraintsChoice::Auto,
            Settings::default(),
        ),
        "nope.txt",
        None,
        "cannot open",
    );
    expect(
        load(&dir, "1\nabsent.mesh 1 0 0 0 0 1 0 0 0\n", None),
        "s-scene.txt",
        Some(2),
        "not found",
    );
    // A name that differs from the file's only in case (written where names ignore case), and
    // a Windows drive path, are said to be so.
    dir.write("Tet.MESH", TET);
    // (Only where names are case-sensitive: elsewhere tet.mesh is Tet.MESH.)
    if !dir.0.join("tet.mesh").exists() {
        expect(
            load(&dir, "1\ntet.mesh 1 0 0 0 0 1 0 0 0\n", None),
            "s-scene.txt",
            Some(2),
            "not found (looked for",
        );
        expect(
            load(&dir, "1\ntet.mesh 1 0 0 0 0 1 0 0 0\n", None),
            "s-scene.txt",
            Some(2),
            "; 'Tet.MESH' beside it differs only in case, and names are case-sensitive here",
        );
    }
    expect(
        load(&dir, "1\nC:\\meshes\\t.mesh 1 0 0 0 0 1 0 0 0\n", None),
        "s-scene.txt",
        Some(2),
        "a Windows drive path: give the mesh's path relative to the scene file",
    );
    let plain = load(&dir, "1\nabsent.mesh 1 0 0 0 0 1 0 0 0\n", None)
        .err()
        .unwrap();
    assert!(
        plain.message.ends_with(')'),
        "no hint where none applies: {plain}"
    );
    expect(
        load(&dir, "1\nabsent.obj 1 0 0 0 0 1 0 0 0\n", None),
        "s-scene.txt",
        Some(2),
        "neither a .mesh nor an .off",
    );
    dir.write("t.mesh", TET);
    let scene = dir.write("x-scene.txt", "1\nt.mesh 1 0 0 0 0 1 0 0 0\n");
    expect(
        tumble::scene::load_file(
            &scene,
            &ConstraintsChoice::File(dir.0.join("gone.txt")),
            Settings::default(),
        ),
        "gone.txt",
        None,
        "cannot open",
    );
}

/// Built-in and generated scene names that are no scene's, or a size the family cannot have,
/// are named with the problem.
#[test]
fn scene_names_that_are_no_scene() {
    expect(
        tumble::scene::load(
            "no-such-scene",
            &ConstraintsChoice::Auto,
            Settings::default(),
        )
        .map(|_| unreachable!()),
        "no-such-scene",
        None,
        "not a built-in scene",
    );
    let empty = tumble::scene::load("", &ConstraintsChoice::Auto, Settings::default());
    let shown = empty.map(|_| ()).unwrap_err().to_string();
    assert!(shown.starts_with("'': no such file"), "{shown}");
    let count = "N must be a whole number from 1 to 1000000";
    let links = "N must be a multiple of 10 (chains of 10 links)";
    let sparse = "N must be a whole number from 1 to 100000";
    for (name, words) in [
        ("stack-0", count),
        ("pile-x", count),
        ("scatter-1000001", count),
        ("rope-", count),
        ("chain-1", links),
        ("chain-15", links),
        ("sparse-100001", sparse),
        ("sparse-x", sparse),
    ] {
        expect(
            tumble::scene::load(name, &ConstraintsChoice::Auto, Settings::default())
                .map(|_| unreachable!()),
            name,
            None,
            words,
        );
    }
}

#[test]
fn scene_file_errors() {
    let dir = Dir::new("scene");
    dir.write("t.mesh", TET);
    expect(
        load(&dir, "2\nt.mesh 1 0 0 0 0 1 0 0 0\n", None),
        "s-scene.txt",
        Some(1),
        "says 2 but the file holds at most 1 such record",
    );
    expect(
        load(
            &dir,
            "1\nt.mesh 1 0 0 0 0 1 0 0 0\nt.mesh 1 0 0 0 0 1 0 0 0\n",
            None,
        ),
        "s-scene.txt",
        Some(3),
        "more records",
    );
    expect(
        load(&dir, "1\nt.mesh 1 0 0 abc 0 1 0 0 0\n", None),
        "s-scene.txt",
        Some(2),
        "found 'abc'",
    );
    expect(
        load(&dir, "1\nt.mesh 1 0 0 NaN 0 1 0 0 0\n", None),
        "s-scene.txt",
        Some(2),
        "finite",
    );
    expect(
        load(&dir, "1\nt.mesh 1 0 0 0 inf 1 0 0 0\n", None),
        "s-scene.txt",
        Some(2),
        "finite",
    );
    expect(
        load(&dir, "1\nt.mesh 0 0 0 0 0 1 0 0 0\n", None),
        "s-scene.txt",
        Some(2),
        "positive density",
    );
    expect(
        load(&dir, "1\nt.mesh -5 0 0 0 0 1 0 0 0\n", None),
        "s-scene.txt",
        Some(2),
        "positive density",
    );
    expect(
        load(&dir, "1\nt.mesh 1 0 0 0 0\n0 0 0 0\n", None),
        "s-scene.txt",
        Some(3),
        "zero",
    );
    expect(
        load(&dir, "1\nt.mesh 1 2 0 0 0 1 0 0 0\n", None),
        "s-scene.txt",
        Some(2),
        "0 or 1",
    );
    expect(
        load(&dir, "x\n", None),
        "s-scene.txt",
        Some(1),
        "number of bodies",
    );
    expect(
        load(&dir, "4000000000\nt.mesh 1 0 0 0 0 1 0 0 0\n", None),
        "s-scene.txt",
        Some(1),
        "limit",
    );
    // A fixed body may have any density, even zero.
    assert!(load(&dir, "1\nt.mesh 0 1 0 0 0 1 0 0 0\n", None).is_ok());
}

/// A constraint file given as the scene, or a scene file as the constraints, is said to be one:
/// the count and the records fail as the other kind's in ways that do not say so.
#[test]
fn swapped_scene_and_constraint_files_are_named() {
    let dir = Dir::new("swapped");
    dir.write("t.mesh", TET);
    let constraints = "2\n0 0 1 2 0.9 1.1\n1 0 2 2 0.9 1.1\n";
    expect(
        load(&dir, constraints, None),
        "s-scene.txt",
        Some(1),
        "it reads as a constraint file",
    );
    let scene = "2\nt.mesh 1 0 0 1 0 1 0 0 0\nt.mesh 1 0 0 3 0 1 0 0 0\n";
    expect(
        load(&dir, scene, Some(scene)),
        "s-constraints.txt",
        Some(2),
        "it reads as a scene file",
    );
    // A scene that is neither is not said to be the other.
    let neither = load(&dir, "2\n0 0 1 2 0.9\n", None).unwrap_err();
    assert!(!neither.message.contains("reads as"), "{neither}");
}

/// A quaternion whose length overflows (components finite, their squares not) is a rotation like
/// any other, the same as its components scaled down, not "zero"; so is one whose squares
/// underflow, down to the smallest subnormal: only the zero quaternion is refused.
#[test]
fn every_quaternion_but_zero_is_a_rotation() {
    let dir = Dir::new("quaternions");
    dir.write("t.mesh", TET);
    let orientation = |q: &str| {
        let world = load(&dir, &format!("1\nt.mesh 1 0 0 5 0 {q}\n"), None);
        world.unwrap_or_else(|e| panic!("{q}: {e}")).bodies[0].orientation
    };
    let small = orientation("1 2 0 -2");
    let half_turn_about_x = glam::DQuat::from_xyzw(1.0, 0.0, 0.0, 0.0);
    let cases = [
        ("1e200 2e200 0 -2e200", small),
        ("1e-13 2e-13 0 -2e-13", small),
        ("1e-200 2e-200 0 -2e-200", small),
        ("0 5e-324 0 0", half_turn_about_x),
    ];
    for (q, expected) in cases {
        let got = orientation(q);
        let apart = (glam::DVec4::from(got) - glam::DVec4::from(expected))
            .abs()
            .max_element();
        assert!(apart < 1e-15, "{q}: {got} against {expected}");
    }
    expect(
        load(&dir, "1\nt.mesh 1 0 0 5 0 0 0 0 0\n", None),
        "s-scene.txt",
        Some(2),
        "zero",
    );
}

/// A scene of one body on the medit mesh `text`, written as `m.mesh` in `dir`.
/// A scene of one body of `density` on the OFF surface `text`.
fn load_off(dir: &Dir, text: &str, density: f64) -> Result<tumble::World, LoadError> {
    dir.write("m.off", text);
    load(dir, &format!("1\nm.off {density} 0 0 5 0 1 0 0 0\n"), None)
}

fn load_medit(dir: &Dir, text: &str) -> Result<tumble::World, LoadError> {
    dir.write("m.mesh", text);
    load(dir, "1\nm.mesh 1 0 0 0 0 1 0 0 0\n", None)
}

#[test]
fn mesh_file_errors() {
    let dir = Dir::new("mesh");
    let mesh = |text: &str| load_medit(&dir, text);
    expect(
        mesh(&TET.replace("1 2 3 4 0", "1 2 3 9 0")),
        "m.mesh",
        Some(11),
        "only 4 vertices",
    );
    // The largest index a u32 holds after the shift to 0-based: named as written, not
    // wrapped to 0 (found by `cargo fuzz run medit`; an overflow panic with overflow checks).
    expect(
        mesh(&TET.replace("1 2 3 4 0", "1 2 3 4294967296 0")),
        "m.mesh",
        Some(11),
        "refers to vertex 4294967296 but the mesh has only 4 vertices",
    );
    expect(
        mesh(&TET.replace("1 2 3 4 0", "0 2 3 4 0")),
        "m.mesh",
        Some(11),
        "start at 1",
    );
    expect(
        mesh(&TET.replace("1 0 0 0\n0 1", "1 x 0 0\n0 1")),
        "m.mesh",
        Some(6),
        "found 'x'",
    );
    expect(
        mesh(&TET.replace("1 0 0 0\n0 1", "1 nan 0 0\n0 1")),
        "m.mesh",
        Some(6),
        "finite",
    );
    expect(
        mesh(&TET.replace("Vertices\n4", "Vertices\n40")),
        "m.mesh",
        Some(4),
        "says 40",
    );
    expect(
        mesh(&TET.replace("Vertices\n4", "Vertices\n4000000000")),
        "m.mesh",
        Some(4),
        "limit",
    );
    expect(
        mesh(&TET.replace("Tetrahedra\n1", "Tetrahedra\n3")),
        "m.mesh",
        Some(10),
        "says 3",
    );
    expect(
        mesh(&TET.replace("End", "Bogus 1")),
        "m.mesh",
        Some(12),
        "unknown section 'Bogus'",
    );
    expect(
        mesh(&TET.replace("End", "Normals 1")),
        "m.mesh",
        Some(12),
        "section 'Normals' is Medit's but tumble does not read it",
    );
}

/// Meshes that parse but are no solid (flat, too large or too small to measure, empty), and two
/// that are fine: a tetrahedron wound the other way, and CRLF line ends, blank lines and an
/// Edges section.
#[test]
fn mesh_volume_errors() {
    let dir = Dir::new("mesh-volume");
    let mesh = |text: &str| load_medit(&dir, text);
    // Degenerate: all four vertices coplanar.
    expect(
        mesh(&TET.replace("0 0 1 0", "1 1 0 0")),
        "m.mesh",
        None,
        "zero volume",
    );
    // Finite coordinates whose volume overflows: too large, not degenerate.
    expect(
        mesh(&TET.replace(
            "1 0 0 0\n0 1 0 0\n0 0 1 0",
            "1e200 0 0 0\n0 1e200 0 0\n0 0 1e200 0",
        )),
        "m.mesh",
        None,
        "too large",
    );
    // Coordinates so small that the volume underflows: too small, not degenerate.
    expect(
        mesh(&TET.replace(
            "1 0 0 0\n0 1 0 0\n0 0 1 0",
            "1e-200 0 0 0\n0 1e-200 0 0\n0 0 1e-200 0",
        )),
        "m.mesh",
        None,
        "too small",
    );
    // Far from the origin a mesh is as degenerate as it is at the origin, no more: a unit
    // tetrahedron at x = 10,000 or 1e8 loads with the volume it has there, a flat one does not.
    let tet_at = |x: f64, last: &str| {
        format!(
            "MeshVersionFormatted 1\nDimension 3\nVertices\n4\n{x} 0 0 0\n{} 0 0 0\n{x} 1 0 0\n{last} 0\nTetrahedra\n1\n1 2 3 4 0\nEnd\n",
            x + 1.0
        )
    };
    for x in [1e4, 1e8] {
        let world = mesh(&tet_at(x, &format!("{x} 0 1"))).unwrap_or_else(|e| panic!("{x}: {e}"));
        let volume = world.shapes[0].volume;
        assert!(
            (volume - 1.0 / 6.0).abs() < 1e-9,
            "at x = {x}: volume {volume}"
        );
        let flat = tet_at(x, &format!("{} 1 0", x + 1.0));
        expect(mesh(&flat), "m.mesh", None, "zero volume");
    }
    // Finite volume, but a centre of mass or inertia past double precision (the volume times
    // a coordinate, or its square): too large, not "coplanar" as it was called.
    let huge = "1e80 0 0 0\n0 1e80 0 0\n0 0 1e80 0";
    expect(
        mesh(&TET.replace("1 0 0 0\n0 1 0 0\n0 0 1 0", huge)),
        "m.mesh",
        None,
        "too large",
    );
    // A tetrahedron wound the other way is the same solid (as in the coursework's skeleton,
    // which takes each tetrahedron's absolute volume).
    assert!(mesh(&TET.replace("1 2 3 4 0", "2 1 3 4 0")).is_ok());
    expect(
        mesh("MeshVersionFormatted 1\nDimension 3\nVertices\n0\nEnd\n"),
        "m.mesh",
        None,
        "no vertices",
    );
    expect(
        mesh(&TET.replace("Tetrahedra", "Vertices\n1\n2 2 2 0\nTetrahedra")),
        "m.mesh",
        Some(9),
        "a second Vertices section",
    );
    // CRLF, blank lines and an Edges section are fine.
    assert!(
        mesh(
            &TET.replace('\n', "\r\n\r\n")
                .replace("End", "Edges\r\n1\r\n1 2 0\r\nEnd")
        )
        .is_ok()
    );
    // Lone CR line ends (classic Mac OS) end lines and comments too: a comment on the first line
    // hides nothing after it, and an error names its own line.
    let classic = format!("# a comment\n{TET}").replace('\n', "\r");
    assert!(mesh(&classic).is_ok());
    expect(
        mesh(&classic.replace("1 2 3 4 0", "1 2 3 9 0")),
        "m.mesh",
        Some(12),
        "vertex 9",
    );
}

#[test]
fn off_file_errors() {
    let dir = Dir::new("off");
    let off = |text: &str| load_off(&dir, text, 1.0);
    expect(
        off("OFF\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 7\n"),
        "m.off",
        Some(7),
        "only 4 vertices",
    );
    expect(off("PLY\n"), "m.off", Some(1), "'OFF' header");
    expect(
        off(
            "OFF\n4 4 0\n0 0 0\n1e200 0 0\n0 1e200 0\n0 0 1e200\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n",
        ),
        "m.off",
        None,
        "too large",
    );
    // Faces of 1024 corners, each a fan of 1022 triangles: refused at the face that passes the
    // mesh limit of 5,000,000 triangles (the 4,893rd, on line 7 + 4,892), not after them all.
    let face = format!("1024{}\n", " 0 1 2 3".repeat(256));
    let many = format!(
        "OFF\n4 5000 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n{}",
        face.repeat(5000)
    );
    expect(
        off(&many),
        "m.off",
        Some(4899),
        "more than 5000000 triangles",
    );
    // Closed but flat: two faces back to back.
    expect(
        off("OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 2 1\n"),
        "m.off",
        None,
        "encloses no volume",
    );
    // Every face twice: each edge pairs up with a copy's, but the volume would count twice.
    let corners = "0 0 0\n1 0 0\n0 1 0\n0 0 1\n";
    let twice: Vec<&str> = TET_FACES.iter().chain(&TET_FACES).copied().collect();
    // Faces from line 7: the fifth (line 11) repeats the first.
    let said = "the triangle of vertices 0, 2, 1 (0-based) twice (the face on line 7 has it too";
    expect(off(&tet_off(corners, &twice)), "m.off", Some(11), said);
    // The same face turned (the same vertices from another corner) is the same face.
    let turned = ["3 2 1 0", "3 1 3 0", "3 3 2 0", "3 2 3 1"];
    let twice: Vec<&str> = TET_FACES.iter().chain(&turned).copied().collect();
    expect(off(&tet_off(corners, &twice)), "m.off", Some(11), "twice");
}

/// A surface of two closed parts, one wound inside out against the other, pairs every edge
/// and encloses a positive volume; by signed volumes its far part weighs negatively and its
/// inertia is not positive: refused, not simulated (a body with a negative moment blows up).
#[test]
fn a_surface_part_wound_inside_out_is_refused() {
    let dir = Dir::new("inside-out");
    let off = |text: &str| load_off(&dir, text, 1.0);
    let big = "0 0 0\n2 0 0\n0 2 0\n0 0 2\n";
    let far = "100 0 0\n101 0 0\n100 1 0\n100 0 1\n";
    let backwards = ["3 4 5 6", "3 4 7 5", "3 4 6 7", "3 5 7 6"];
    let faces: Vec<&str> = TET_FACES.iter().chain(&backwards).copied().collect();
    let both = tet_off(&format!("{big}{far}"), &faces);
    expect(off(&both), "m.off", None, "wound inside out");
    // Wound the same way, the two parts are one body of both masses.
    let outward = ["3 4 6 5", "3 4 5 7", "3 4 7 6", "3 5 6 7"];
    let faces: Vec<&str> = TET_FACES.iter().chain(&outward).copied().collect();
    let world = off(&tet_off(&format!("{big}{far}"), &faces)).unwrap();
    let volume = world.shapes[0].volume;
    assert!((volume - 9.0 / 6.0).abs() < 1e-12, "volume {volume}");
}

/// A tetrahedron listed twice (in any order of its corners) would count its mass twice: named
/// on its line, with the line of the first.
#[test]
fn repeated_tetrahedra_are_named() {
    let dir = Dir::new("repeated-tet");
    let twice = TET.replace("1\n1 2 3 4 0\n", "2\n1 2 3 4 0\n4 3 1 2 0\n");
    expect(
        load_medit(&dir, &twice),
        "m.mesh",
        Some(12),
        "the four vertices of the one on line 11",
    );
}

/// A unit right tetrahedron as OFF faces (outward), vertices 0 1 2 3 at the origin and the axes.
const TET_FACES: [&str; 4] = ["3 0 2 1", "3 0 1 3", "3 0 3 2", "3 1 2 3"];

fn tet_off(vertices: &str, faces: &[&str]) -> String {
    let count = vertices.lines().count();
    format!(
        "OFF\n{count} {} 0\n{vertices}{}\n",
        faces.len(),
        faces.join("\n")
    )
}

/// The fan over an OFF surface is its volume only when the surface is closed and wound one way:
/// an open or inconsistently wound surface is refused (before: loaded with part of its mass, a
/// tetrahedron missing a face at 2/3 of it); one cut along a seam into patches that share
/// points but not indices is closed.
#[test]
fn off_surfaces_must_be_closed() {
    let dir = Dir::new("off-closed");
    let off = |text: &str| load_off(&dir, text, 6.0);
    let corners = "0 0 0\n1 0 0\n0 1 0\n0 0 1\n";
    let whole = off(&tet_off(corners, &TET_FACES)).unwrap();
    assert!((whole.bodies[0].mass - 1.0).abs() < 1e-12, "6 x 1/6");
    // Faces from line 7; named on the last face concerned.
    expect(
        off(&tet_off(corners, &TET_FACES[..3])),
        "m.off",
        Some(7),
        "not closed: the edge between vertices 1 and 2 (0-based) has a face on one side only",
    );
    expect(
        off(&tet_off(
            corners,
            &[TET_FACES[0], TET_FACES[1], TET_FACES[2], "3 1 3 2"],
        )),
        "m.off",
        Some(10),
        "the edge between vertices 1 and 2 (0-based), this one and the one on line 7, are wound the same way",
    );
    // The same on a seam (vertex 4 at vertex 1's point): named as the face writes it.
    expect(
        off(&tet_off(
            &format!("{corners}1 0 0\n"),
            &[TET_FACES[0], TET_FACES[1], TET_FACES[2], "3 4 3 2"],
        )),
        "m.off",
        Some(11),
        "the edge between vertices 2 and 4 (0-based), this one and the one on line 8, are wound",
    );
    // The last face on a copy of vertex 1 (index 4) at the same point: a seam, still closed.
    let seamed = off(&tet_off(
        &format!("{corners}1 0 0\n"),
        &[TET_FACES[0], TET_FACES[1], TET_FACES[2], "3 4 2 3"],
    ))
    .unwrap();
    assert!((seamed.bodies[0].mass - 1.0).abs() < 1e-12);
    // Two closed tetrahedra apart: loads (as a tetrahedral mesh of them would in the
    // coursework) with a warning that the body is not convex.
    let far = "5 5 5\n6 5 5\n5 6 5\n5 5 6\n";
    let shift = |face: &str| {
        let mut words = face.split(' ');
        let n = words.next().unwrap().to_string();
        let moved: Vec<String> = words
            .map(|i| (i.parse::<u32>().unwrap() + 4).to_string())
            .collect();
        format!("{n} {}", moved.join(" "))
    };
    let faces: Vec<String> = TET_FACES
        .iter()
        .map(|f| f.to_string())
        .chain(TET_FACES.iter().map(|f| shift(f)))
        .collect();
    let faces: Vec<&str> = faces.iter().map(String::as_str).collect();
    let pair = off(&tet_off(&format!("{corners}{far}"), &faces)).unwrap();
    assert!(
        pair.warnings.len() == 1 && pair.warnings[0].contains("m.off: the mesh is not convex"),
        "{:?}",
        pair.warnings
    );
    assert!(whole.warnings.is_empty() && seamed.warnings.is_empty());
}

/// Two tetrahedra that overlap weigh their common part twice: loaded, with a warning naming
/// the share of the hull the sum of their volumes makes.
#[test]
fn a_mesh_that_overlaps_itself_is_named() {
    let dir = Dir::new("overlap");
    // The unit corner tetrahedron, and another on its base with its apex inside the first:
    // 1/6 + 0.1/6 of a hull of 1/6.
    dir.write(
        "t.mesh",
        "MeshVersionFormatted 1\nDimension 3\nVertices\n5\n0 0 0 0\n1 0 0 0\n0 1 0 0\n0 0 1 0\n\
         0.1 0.1 0.1 0\nTetrahedra\n2\n1 2 3 4 0\n1 2 3 5 0\nEnd\n",
    );
    let world = load(&dir, "1\nt.mesh 1 0 0 5 0 1 0 0 0\n", None).unwrap();
    assert!(
        world.warnings.len() == 1
            && world.warnings[0]
                .contains("t.mesh: the mesh overlaps itself (its volume is 110.0 %"),
        "{:?}",
        world.warnings
    );
    let whole = load(
        &dir_with_tet("overlap-none"),
        "1\nt.mesh 1 0 0 5 0 1 0 0 0\n",
        None,
    );
    assert!(whole.unwrap().warnings.is_empty());
}

/// A folder holding the unit corner tetrahedron as `t.mesh`.
fn dir_with_tet(name: &str) -> Dir {
    let dir = Dir::new(name);
    dir.write("t.mesh", TET);
    dir
}

/// A fixed body's density weighs nothing, so any value loads; a negative one is named on its
/// line, as a sign typed by mistake, and zero (a coursework habit for fixed bodies) is not.
#[test]
fn a_fixed_bodys_negative_density_is_named() {
    let dir = Dir::new("fixed-density");
    dir.write("t.mesh", TET);
    let scene = "2\nt.mesh 1 0 0 5 0 1 0 0 0\nt.mesh -3 1 0 0 0 1 0 0 0\n";
    let world = load(&dir, scene, None).unwrap();
    assert!(world.bodies[1].fixed);
    assert_eq!(world.warnings.len(), 1, "{:?}", world.warnings);
    let warning = &world.warnings[0];
    assert!(
        warning.contains("s-scene.txt:3:") && warning.contains("density -3 is negative"),
        "{warning}"
    );
    let zero = load(&dir, &scene.replace("-3", "0"), None).unwrap();
    assert!(zero.warnings.is_empty(), "{:?}", zero.warnings);
}

/// A body placed inside another, or partly below the ground, loads with a warning on its line
/// that says how deep it starts (the unit corner tetrahedron's lowest vertex a quarter below its
/// centre of mass; a copy shifted by `s` along x overlaps it by `(1 - s) / sqrt(3)`, along the
/// normal of its slanted face); bodies that touch or lie apart, or sink less than 1 % of their
/// size, and fixed bodies below the ground, load without one.
#[test]
fn bodies_that_start_inside_another_or_the_ground_are_named() {
    let dir = Dir::new("start-inside");
    dir.write("t.mesh", TET);
    // Body 0 at height y, body 1 at (s, 5, 0); `fixed` the flags of the two.
    let scene = |y: f64, s: f64, fixed: [u8; 2]| {
        let [a, b] = fixed;
        format!("2\nt.mesh 1 {a} 0 {y} 0 1 0 0 0\nt.mesh 1 {b} {s} 5 0 1 0 0 0\n")
    };
    let warnings =
        |y: f64, s: f64, fixed: [u8; 2]| load(&dir, &scene(y, s, fixed), None).unwrap().warnings;
    let sunk = warnings(0.1, 3.0, [0, 0]);
    assert_eq!(sunk.len(), 1, "{sunk:?}");
    assert!(
        sunk[0].contains("s-scene.txt:2: the body starts 0.150 below the ground"),
        "{}",
        sunk[0]
    );
    // Three significant figures: 0.0289.
    let inside = warnings(5.0, 0.95, [0, 0]);
    assert_eq!(inside.len(), 1, "{inside:?}");
    let depth = 0.05 / 3f64.sqrt();
    let said = format!("s-scene.txt:3: the body starts {depth:.4} deep inside the body on line 2");
    assert!(inside[0].contains(&said), "{}", inside[0]);
    // Inside a fixed body listed after it: named on its own line, pushed out.
    let held = warnings(5.0, 0.95, [0, 1]);
    let said =
        format!("s-scene.txt:2: the body starts {depth:.4} deep inside the fixed body on line 3");
    assert!(held.len() == 1 && held[0].contains(&said), "{held:?}");
    // A fixed body below the ground, bodies touching or apart, and a body sunk 0.49 % of its size.
    for (y, s, fixed) in [
        (-3.0, 3.0, [1, 0]),
        (5.0, 1.0, [0, 0]),
        (5.0, 1.5, [0, 0]),
        (0.2451, 3.0, [0, 0]),
    ] {
        let quiet = warnings(y, s, fixed);
        assert!(quiet.is_empty(), "{y} {s} {fixed:?}: {quiet:?}");
    }
    // Copies of one body on one spot: the first five named in line order, the rest counted.
    let copies = |n: usize| format!("{n}\n{}", "t.mesh 1 0 0 5 0 1 0 0 0\n".repeat(n));
    let nine = load(&dir, &copies(9), None).unwrap().warnings;
    assert_eq!(nine.len(), 6, "{nine:?}");
    let lines = ["3: ", "4: ", "4: ", "5: ", "5: "];
    for (w, line) in nine.iter().zip(lines) {
        assert!(w.contains(&format!("s-scene.txt:{line}")), "{nine:?}");
    }
    assert!(nine[5].ends_with(
        "s-scene.txt: 31 more overlaps at the start (a body inside another or below the ground)"
    ));
    let four = load(&dir, &copies(4), None).unwrap().warnings;
    assert!(
        four[5].contains(": 1 more overlap at the start"),
        "{four:?}"
    );
    // Two boxes on one spot, between which the detection finds no depth (GJK ends on the
    // origin): named as at the same place; two fixed ones there load without a word.
    let box_mesh = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/box.mesh");
    dir.write("b.mesh", &std::fs::read_to_string(box_mesh).unwrap());
    let boxes = |f: u8| format!("2\nb.mesh 1 {f} 0 5 0 1 0 0 0\nb.mesh 1 {f} 0 5 0 1 0 0 0\n");
    let same = load(&dir, &boxes(0), None).unwrap().warnings;
    let said = "s-scene.txt:3: the body starts at the same place as the body on line 2";
    assert!(same.len() == 1 && same[0].contains(said), "{same:?}");
    assert!(load(&dir, &boxes(1), None).unwrap().warnings.is_empty());
}

/// Records on the same two points (either way round) whose ranges share no distance load with a
/// warning naming both lines; ranges that overlap load without one.
#[test]
fn bounds_that_leave_no_distance_are_named() {
    let dir = Dir::new("conflict");
    dir.write("t.mesh", TET);
    let scene = "2\nt.mesh 1 0 0 5 0 1 0 0 0\nt.mesh 1 0 0 8 0 1 0 0 0\n";
    let apart = load(&dir, scene, Some("2\n0 0 1 0 0.5 0.6\n1 0 0 0 1.4 1.5\n")).unwrap();
    let conflicts: Vec<&String> = apart
        .warnings
        .iter()
        .filter(|w| w.contains("leave no distance"))
        .collect();
    assert_eq!(conflicts.len(), 1, "{:?}", apart.warnings);
    assert!(
        conflicts[0].contains("s-constraints.txt:3:") && conflicts[0].contains("on line 2"),
        "{}",
        conflicts[0]
    );
    let overlapping = load(&dir, scene, Some("2\n0 0 1 0 0.5 1.2\n1 0 0 0 1.0 1.5\n")).unwrap();
    assert!(
        overlapping.warnings.is_empty(),
        "{:?}",
        overlapping.warnings
    );
    // Points that start together: every fraction of 0 is 0, nothing conflicts.
    let together = "2\nt.mesh 1 0 0 5 0 1 0 0 0\nt.mesh 1 0 0 5 0 1 0 0 0\n";
    let conflicting = Some("2\n0 0 1 0 0.5 0.6\n1 0 0 0 1.4 1.5\n");
    let world = load(&dir, together, conflicting).unwrap();
    assert!(
        !world
            .warnings
            .iter()
            .any(|w| w.contains("leave no distance"))
    );
    // Between two fixed bodies the records are dropped, with their own warning only.
    let fixed = "2\nt.mesh 1 1 0 5 0 1 0 0 0\nt.mesh 1 1 0 8 0 1 0 0 0\n";
    let world = load(&dir, fixed, conflicting).unwrap();
    assert!(
        world.warnings.iter().all(|w| w.contains("ignored")),
        "{:?}",
        world.warnings
    );
}

/// The readers take records as one stream of words (as the coursework's do), so a field
/// missing on one line shifts the records after it. Every coursework file holds one record a
/// line: the first line that does not is named in the error, or in a warning when the shifted
/// words still parse.
#[test]
fn records_out_of_step_name_their_line() {
    let dir = Dir::new("layout");
    dir.write("t.mesh", TET);
    expect(
        load(&dir, "1\nt.mesh 1 0 0 0 0 1 0 0\n", None),
        "s-scene.txt",
        Some(1),
        "line 2 holds 9 fields where a body record has 10",
    );
    let scene = "2\nt.mesh 1 0 0 5 0 1 0 0 0\nt.mesh 1 0 3 5 0 1 0 0 0\n";
    // An extra field on line 2 and one missing on line 3: still 12 words, read out of step as
    // body 1 vertex 0 to body 0 vertex 3.
    let shifted = load(&dir, scene, Some("2\n0 0 1 0 0.9 1.1 1\n0 0 3 0.9 1.1\n")).unwrap();
    assert_eq!(shifted.warnings.len(), 1, "{:?}", shifted.warnings);
    let warning = &shifted.warnings[0];
    assert!(
        warning.contains("s-constraints.txt:2:")
            && warning.contains("holds 7 fields where a constraint record has 6"),
        "{warning}"
    );
    // A byte-order mark before the count is not a word of the file.
    assert!(load(&dir, &format!("\u{feff}{scene}"), None).is_ok());
    // One record a line, as every coursework file: no warning.
    let aligned = load(&dir, scene, Some("1\n0 0 1 0 0.9 1.1\n")).unwrap();
    assert!(aligned.warnings.is_empty(), "{:?}", aligned.warnings);
    // Bounds that leave out the starting distance (1, as they are fractions of it) load, with
    // a warning that the bodies will be pulled into range.
    for bounds in ["1.2 1.5", "0.2 0.5"] {
        let pulled = load(&dir, scene, Some(&format!("1\n0 0 1 0 {bounds}\n"))).unwrap();
        assert!(
            pulled.warnings.len() == 1
                && pulled.warnings[0].contains("s-constraints.txt:2: the bounds")
                && pulled.warnings[0].contains("leave out the distance the scene starts at"),
            "{:?}",
            pulled.warnings
        );
    }
    // A Medit vertex with a field missing: the error where the words ran out names its line.
    dir.write("t.mesh", &TET.replace("0 1 0 0\n", "0 1 0\n"));
    let err = load(&dir, "1\nt.mesh 1 0 0 0 0 1 0 0 0\n", None).unwrap_err();
    assert!(
        err.message
            .contains("line 7 holds 3 fields where a vertex record has 4: x y z reference"),
        "{err}"
    );
}

#[test]
fn constraint_file_errors() {
    let dir = Dir::new("constraints");
    dir.write("t.mesh", TET);
    let scene = "2\nt.mesh 1 0 0 5 0 1 0 0 0\nt.mesh 1 0 3 5 0 1 0 0 0\n";
    expect(
        load(&dir, scene, Some("1\n0 0 2 0 1 1\n")),
        "s-constraints.txt",
        Some(2),
        "body index 2 is out of range: the scene has 2 bodies (indices count from 0",
    );
    expect(
        load(&dir, scene, Some("1\n0 0 1 0 1 1e308\n")),
        "s-constraints.txt",
        Some(2),
        "the bound 1e308 times the starting distance 3 is too large a length",
    );
    expect(
        load(&dir, scene, Some("1\n0 0 1 4 1 1\n")),
        "s-constraints.txt",
        Some(2),
        "vertex index 4 is out of range",
    );
    // An .off surface of four vertices: its vertex 3 may be named, not 4, the centroid its
    // reader fans the solid from (named as the surface's fifth vertex before stop 67).
    let faces = TET_FACES.join("\n");
    dir.write(
        "m.off",
        &format!("OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n{faces}\n"),
    );
    let surfaces = "2\nm.off 1 0 0 5 0 1 0 0 0\nm.off 1 0 3 5 0 1 0 0 0\n";
    assert!(load(&dir, surfaces, Some("1\n0 3 1 3 1 1\n")).is_ok());
    expect(
        load(&dir, surfaces, Some("1\n0 4 1 0 1 1\n")),
        "s-constraints.txt",
        Some(2),
        "vertex index 4 is out of range: body 0's mesh has 4 vertices",
    );
    expect(
        load(&dir, scene, Some("2\n0 0 1 0 1 1\n")),
        "s-constraints.txt",
        Some(1),
        "says 2",
    );
    expect(
        load(&dir, scene, Some("1\n0 0 1 0 1 x\n")),
        "s-constraints.txt",
        Some(2),
        "found 'x'",
    );
    expect(
        load(&dir, scene, Some("1\n0 0 1 0 1.2 1.1\n")),
        "s-constraints.txt",
        Some(2),
        "lower <= upper",
    );
    expect(
        load(&dir, scene, Some("1\n0 0 0 1 1 1\n")),
        "s-constraints.txt",
        Some(2),
        "two different bodies",
    );
    expect(
        load(&dir, scene, Some("1\n0 0 1 0 inf 1\n")),
        "s-constraints.txt",
        Some(2),
        "finite",
    );
    // Between two fixed bodies: reported at load and ignored.
    let fixed = "2\nt.mesh 1 1 0 0 0 1 0 0 0\nt.mesh 1 1 3 0 0 1 0 0 0\n";
    let world = load(&dir, fixed, Some("1\n0 0 1 0 1 1\n")).unwrap();
    assert!(world.constraints.is_empty());
    assert!(
        world
            .warnings
            .iter()
            .any(|w| w.contains("two fixed bodies"))
    );
    // A zero-length constraint (same point) gets no correction rather than NaN.
    let same = "2\nt.mesh 1 0 0 0 0 1 0 0 0\nt.mesh 1 0 0 0 0 1 0 0 0\n";
    let mut world = load(&dir, same, Some("1\n0 0 1 0 1 1\n")).unwrap();
    for _ in 0..50 {
        world.step();
    }
    assert!(world.all_finite());
}

#[cfg(feature = "cli")]
#[test]
fn cli_reports_errors_and_exits_nonzero() {
    let dir = Dir::new("cli");
    let path = dir.write("bad-scene.txt", "1\nt.mesh 1 0 0 0\n");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_tumble"))
        .args(["run"])
        .arg(&path)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("bad-scene.txt:1:") && stderr.contains("says 1"),
        "{stderr}"
    );
}

/// An output that cannot be written is refused before the run, in the user's words (it used to
/// fail after the whole run, naming the temporary `.NAME.partial` file and leaving it behind).
/// A folder where a file is expected is called a folder, also when it stands beside a scene
/// under its constraint file's name (it was passed over in silence); bytes that are not UTF-8
/// are placed on their line; a file with no length to check first (a device) is cut off at the
/// size limit instead of filling memory.
#[test]
fn folders_bytes_and_endless_files() {
    let dir = Dir::new("folders");
    std::fs::create_dir(dir.0.join("hollow.mesh")).unwrap();
    expect(
        load(&dir, "1\nhollow.mesh 1 0 0 0 0 1 0 0 0\n", None),
        "s-scene.txt",
        Some(2),
        "'hollow.mesh' is a folder, not a file",
    );
    dir.write("t.mesh", TET);
    std::fs::create_dir(dir.0.join("s-constraints.txt")).unwrap();
    expect(
        load(&dir, "1\nt.mesh 1 0 0 0 0 1 0 0 0\n", None),
        "s-constraints.txt",
        None,
        "is a folder, not a file",
    );
    let bytes = dir.0.join("b-scene.txt");
    std::fs::write(&bytes, b"1\nt.mesh 1 0 0 0 0 1 0 0 0\n\xff\n").unwrap();
    expect(
        tumble::scene::load_file(&bytes, &ConstraintsChoice::None, Settings::default()),
        "b-scene.txt",
        Some(3),
        "bytes that are not UTF-8 text",
    );
    let endless = std::path::Path::new("/dev/zero");
    if endless.exists() {
        expect(
            tumble::scene::load_file(endless, &ConstraintsChoice::None, Settings::default()),
            "/dev/zero",
            None,
            "more than the limit of 268435456 bytes",
        );
    }
}

/// What a hand edit or another system's editor leaves, named as such: a count one short of
/// its records (the record past it read as a section keyword, a face or an extra record), a
/// constraint file without its count line, UTF-16 text and Latin-1 bytes outside a comment.
/// Latin-1 bytes inside a comment, padding at the end and an empty constraint file are taken.
#[test]
fn hand_edits_and_foreign_encodings_are_named() {
    let dir = Dir::new("hand-edits");
    expect(
        load_medit(&dir, &TET.replace("Vertices\n4", "Vertices\n3")),
        "m.mesh",
        Some(8),
        "is the Vertices count on line 4 (3) smaller than the records under it?",
    );
    let off = tet_off("0 0 0\n1 0 0\n0 1 0\n0 0 1\n", &TET_FACES);
    expect(
        load_off(&dir, &off.replace("4 4 0", "4 3 0"), 1.0),
        "m.off",
        Some(10),
        "the file declares 3 faces but has more records after them",
    );
    expect(
        load_off(&dir, &off.replace("4 4 0", "3 4 0"), 1.0),
        "m.off",
        Some(6),
        "is the vertex count on line 2 (3) smaller than the vertices listed?",
    );
    dir.write("t.mesh", TET);
    let scene = "2\nt.mesh 1 0 0 5 0 1 0 0 0\nt.mesh 1 0 3 5 0 1 0 0 0\n";
    expect(
        load(&dir, scene, Some("0 0 1 0 1 1\n0 1 1 1 1 1\n")),
        "s-constraints.txt",
        Some(1),
        "line 1, read as the count, holds 6 fields, as a record does: is the count line missing?",
    );
    // A count that shares its line with a record is not taken for a missing one.
    let shared = load(&dir, scene, Some("1 0 0 1 0 1 1\n0 0 1 0 1 1\n")).unwrap_err();
    assert!(
        shared.message.contains("declares 1 constraint") && !shared.message.contains("missing")
    );
    let world = load(&dir, scene, Some("# none yet\n")).unwrap();
    assert!(world.constraints.is_empty());
    let scene_bytes = |bytes: &[u8]| {
        let path = dir.0.join("e-scene.txt");
        std::fs::write(&path, bytes).unwrap();
        tumble::scene::load_file(&path, &ConstraintsChoice::None, Settings::default())
    };
    let utf16: Vec<u8> = scene.encode_utf16().flat_map(u16::to_le_bytes).collect();
    let with_mark = [&[0xFF, 0xFE][..], &utf16].concat();
    let big_endian: Vec<u8> = scene.encode_utf16().flat_map(u16::to_be_bytes).collect();
    let big_endian = [&[0xFE, 0xFF][..], &big_endian].concat();
    for bytes in [&utf16, &with_mark, &big_endian] {
        expect(scene_bytes(bytes), "e-scene.txt", None, "UTF-16 text");
    }
    let latin = [b"# Gr\xf6\xdfe\n".as_slice(), scene.as_bytes()].concat();
    assert_eq!(scene_bytes(&latin).unwrap().bodies.len(), 2);
    let at = scene.find("0 3 5").unwrap() + 2;
    let latin = [
        &scene.as_bytes()[..at],
        b"\xb3",
        &scene.as_bytes()[at + 1..],
    ]
    .concat();
    expect(scene_bytes(&latin), "e-scene.txt", Some(3), "Latin-1");
    let nul = scene.replacen("0 3 5", "0 3\u{0} 5", 1);
    expect(
        scene_bytes(nul.as_bytes()),
        "e-scene.txt",
        Some(3),
        "a NUL byte",
    );
    // U+FFFD written as UTF-8 is text: a mesh name holding it is looked for as it is.
    let named = scene.replacen("t.mesh", "t\u{fffd}.mesh", 1);
    expect(
        scene_bytes(named.as_bytes()),
        "e-scene.txt",
        Some(2),
        "not found",
    );
    // NUL or Ctrl-Z bytes padding the end, and Latin-1 in a mesh's comment, are taken.
    let padded = [TET.as_bytes(), b"# \xe9t\xe9\n\0\0"].concat();
    std::fs::write(dir.0.join("m.mesh"), padded).unwrap();
    assert!(load(&dir, "1\nm.mesh 1 0 0 0 0 1 0 0 0\n", None).is_ok());
    assert!(load_off(&dir, &format!("{off}\u{1a}"), 1.0).is_ok());
    // No face at all: the end of the file, not a short vertex count.
    let faceless = "OFF\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n";
    let error = load_off(&dir, faceless, 1.0).unwrap_err();
    assert!(error.message.contains("end of file") && !error.message.contains("vertex count"));
}

/// A scene written on Windows (a backslash in its mesh path) loads, and a mesh vertex no
/// tetrahedron uses is named in a warning; far away, where it was refused as "zero volume"
/// before, it is named as what leaves no hull to build.
#[test]
fn windows_paths_load_and_stray_vertices_are_named() {
    let dir = Dir::new("strays");
    std::fs::create_dir_all(dir.0.join("meshes")).unwrap();
    dir.write("meshes/w.mesh", TET);
    let world = load(&dir, "1\nmeshes\\w.mesh 1 0 0 5 0 1 0 0 0\n", None).unwrap();
    assert_eq!(world.bodies.len(), 1);
    let stray = |at: &str| {
        let mesh = TET.replace("Vertices\n4", "Vertices\n5");
        load_medit(
            &dir,
            &mesh.replace("0 0 1 0\n", &format!("0 0 1 0\n{at} 0\n")),
        )
    };
    let world = stray("9 0 0").unwrap();
    let named = "1 vertex is used by no tetrahedron (the first: vertex 5)";
    assert!(
        world.warnings.iter().any(|w| w.contains(named)),
        "{:?}",
        world.warnings
    );
    // The mass is the tetrahedron's, 1/6 at density 1.
    assert!((world.bodies[0].mass - 1.0 / 6.0).abs() < 1e-15);
    // Far off, it leaves parry no hull to build (parry 0.31): the stray is named as the cause.
    match stray("1000000 0 0") {
        Ok(world) => assert!(world.warnings.iter().any(|w| w.contains(named))),
        Err(error) => assert!(error.message.contains(named), "{error}"),
    }
}

/// An output never replaces a file the run reads, nor a pipe (written through a rename, it
/// would become a plain file: `/dev/null` too, for a run as root); through a symbolic link it
/// writes the file the link leads to, and the link stays.
#[cfg(all(feature = "cli", unix))]
#[test]
fn cli_writes_no_output_over_an_input_a_pipe_or_a_link() {
    let dir = Dir::new("cli-inputs");
    let mesh = dir.write("t.mesh", TET);
    let scene = dir.write("s-scene.txt", "1\nt.mesh 1 0 0 0 3 1 0 0 0\n");
    let run = |out: &std::path::Path| -> Vec<std::ffi::OsString> {
        let args = ["run", "--steps", "2", "--trajectory"].map(std::ffi::OsString::from);
        let mut args = args.to_vec();
        args.extend([out.into(), scene.clone().into()]);
        args
    };
    let fails_saying = |out: &std::path::Path, words: &str| {
        let args = run(out);
        let args: Vec<&std::ffi::OsStr> = args.iter().map(|a| a.as_os_str()).collect();
        cli_fails_saying(&args, words);
    };
    for input in [&scene, &mesh] {
        let before = std::fs::read(input).unwrap();
        let words = format!(
            "cannot write {}: it is {}",
            input.display(),
            input.display()
        );
        fails_saying(input, &words);
        assert_eq!(
            std::fs::read(input).unwrap(),
            before,
            "{} changed",
            input.display()
        );
    }
    // A constraint file named for a built-in scene is read from disk too.
    let constraints = dir.write("c.txt", "0\n");
    let named = [
        "run",
        "cube",
        "--steps",
        "2",
        "--constraints",
        "c.txt",
        "--trajectory",
        "c.txt",
    ];
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_tumble"))
        .args(named)
        .current_dir(&dir.0)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("it is c.txt, which this run reads"),
        "{stderr}"
    );
    assert_eq!(std::fs::read_to_string(&constraints).unwrap(), "0\n");
    // A hard link to the scene is the scene under another name.
    let hard = dir.0.join("hard-link.txt");
    std::fs::hard_link(&scene, &hard).unwrap();
    fails_saying(&hard, &format!("it is {}", scene.display()));
    assert_eq!(
        std::fs::read(&hard).unwrap(),
        std::fs::read(&scene).unwrap()
    );
    let pipe = dir.0.join("pipe");
    let made = std::process::Command::new("mkfifo").arg(&pipe).status();
    if made.is_ok_and(|s| s.success()) {
        fails_saying(&pipe, "it is not a regular file");
        use std::os::unix::fs::FileTypeExt;
        let kind = std::fs::symlink_metadata(&pipe).unwrap().file_type();
        assert!(kind.is_fifo(), "the pipe was replaced");
    }
    // A link to a file there is, and one to a file not there yet (relative, beside the link).
    for (name, exists) in [("target.csv", true), ("new.csv", false)] {
        let (link, target) = (dir.0.join(format!("link-{name}")), dir.0.join(name));
        std::os::unix::fs::symlink(name, &link).unwrap();
        if exists {
            std::fs::write(&target, "").unwrap();
        }
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_tumble"))
            .args(run(&link))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{name}: {stderr}");
        let kind = std::fs::symlink_metadata(&link).unwrap().file_type();
        assert!(kind.is_symlink(), "{name}: the link was replaced");
        let rows = std::fs::read_to_string(&target).unwrap();
        assert_eq!(
            rows.lines().count(),
            1 + 3,
            "{name}: header and three steps' rows"
        );
    }
}

#[cfg(feature = "cli")]
#[test]
fn cli_refuses_an_output_it_cannot_write_before_running() {
    let dir = Dir::new("cli-out");
    let folder = dir.0.join("a-folder");
    std::fs::create_dir(&folder).unwrap();
    let missing = dir.0.join("no-such-folder").join("t.csv");
    // A name ending in a separator is a folder's, there or not.
    let slashed = std::path::PathBuf::from(format!("{}/", dir.0.join("new-folder").display()));
    for (target, words) in [
        (
            &folder,
            format!("cannot write {}: it is a folder", folder.display()),
        ),
        (
            &slashed,
            format!("cannot write {}: it names a folder", slashed.display()),
        ),
        (
            &missing,
            format!(
                "the folder {} does not exist",
                dir.0.join("no-such-folder").display()
            ),
        ),
    ] {
        let args = ["run", "cube", "--steps", "5", "--trajectory"].map(std::ffi::OsStr::new);
        let mut args = args.to_vec();
        args.push(target.as_os_str());
        cli_fails_saying(&args, &words);
    }
    let left: Vec<_> = std::fs::read_dir(&dir.0)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(
        left,
        vec![std::ffi::OsString::from("a-folder")],
        "files left behind"
    );
}

/// Runs `tumble` with `args`; it must fail and say `words` on stderr.
#[cfg(feature = "cli")]
fn cli_fails_saying(args: &[&std::ffi::OsStr], words: &str) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_tumble"))
        .args(args)
        .output()
        .unwrap();
    assert!(!out.status.success(), "{args:?}");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains(words), "{args:?}: {stderr}");
}

/// A negative number given to a setting reaches the setting's own check (not the argument
/// parser's "unexpected argument '-1'"), which names the setting, its range and the value.
#[cfg(feature = "cli")]
#[test]
fn cli_names_the_setting_a_negative_value_breaks() {
    let os = |s: &'static str| std::ffi::OsStr::new(s);
    for (flag, words) in [
        (
            "--dt",
            "--dt must be a non-negative number of seconds, got -1",
        ),
        (
            "--friction",
            "--friction must be a non-negative number, got -1",
        ),
        ("--restitution", "--restitution must lie in [0, 1], got -1"),
        ("--tolerance", "--tolerance must be non-negative, got -1"),
        (
            "--restitution-threshold",
            "--restitution-threshold must be non-negative, got -1",
        ),
        (
            "--full-substeps-from",
            "--full-substeps-from must be a non-negative number of seconds, got -1",
        ),
        (
            "--max-iterations",
            "expected a whole number, 0 or more, got '-1'",
        ),
    ] {
        let args = ["run", "pile-20", "--steps", "1", flag, "-1"].map(os);
        cli_fails_saying(&args, words);
    }
    // A count past the type's range is a whole number too: said to be too large.
    let huge = ["run", "pile-20", "--steps", "99999999999999999999999"].map(os);
    let words = "99999999999999999999999 is more than the most allowed here, 18446744073709551615";
    cli_fails_saying(&huge, words);
    // A budget that a step of rods that cannot all hold would never use up.
    let endless = [
        "run",
        "two-chain",
        "--max-iterations",
        "18446744073709551615",
    ]
    .map(os);
    let words = "--max-iterations must be at most 1000000000, got 18446744073709551615";
    cli_fails_saying(&endless, words);
    // A mesh where a scene is expected is called a mesh (it read as a scene counting "OFF").
    let mesh = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/box.mesh");
    cli_fails_saying(&["run", mesh].map(os), "a mesh, not a scene");
    let with_mesh = ["run", "two-chain", "--steps", "1", "--constraints", mesh];
    cli_fails_saying(
        &with_mesh.map(os),
        "box.mesh: a mesh, not a constraint file",
    );
    if !cfg!(feature = "viewer") {
        return;
    }
    let gif = std::env::temp_dir().join(format!("tumble-negative-{}.gif", std::process::id()));
    for (flag, words) in [
        (
            "--seconds",
            "--seconds must be a non-negative number, got -1",
        ),
        ("--fps", "--fps must lie in (0, 1000], got -1"),
    ] {
        let args = [
            os("record"),
            os("pile-20"),
            os("-o"),
            gif.as_os_str(),
            os(flag),
            os("-1"),
        ];
        cli_fails_saying(&args, words);
        assert!(!gif.exists(), "{flag}: nothing recorded");
    }
    // A camera the view cannot take is refused before a window opens (no display needed).
    let args = ["view", "pile-20", "--camera", "foo"].map(os);
    cli_fails_saying(&args, "--camera 'foo': invalid float literal");
    // A word that is neither a preset nor a flag names the presets.
    let args = ["view", "pile-20", "--compare", "bogus"].map(os);
    cli_fails_saying(
        &args,
        "expected a preset (accurate, coursework) or settings flags",
    );
}

/// `bench scale` and `bench accuracy` refuse sizes no generated scene can have, no measured
/// steps, a time cap that is not positive and time steps that are not, naming the option and
/// the value, before running anything.
#[cfg(feature = "cli")]
#[test]
fn bench_options_out_of_range_are_named() {
    let out_dir = std::env::temp_dir().join(format!("tumble-bench-args-{}", std::process::id()));
    for (args, words) in [
        (
            ["scale", "--sizes", "0"],
            "--sizes: each size must be a whole number from 1 to 1000000, got 0",
        ),
        (
            ["scale", "--scatter-sizes", "2000000"],
            "--scatter-sizes: each size must be",
        ),
        (["scale", "--steps", "0"], "--steps must be at least 1"),
        (
            ["scale", "--sizes", "15"],
            "--sizes: chain-N: N must be a multiple of 10 (chains of 10 links), not 15",
        ),
        (
            ["scale", "--sizes", "200000"],
            "--sizes: sparse-N: N must be a whole number from 1 to 100000 (it packs them",
        ),
        (
            ["scale", "--steps", "18446744073709551615"],
            "--steps must be at most 1000000, got 18446744073709551615",
        ),
        (
            ["accuracy", "--dts", "1e-300"],
            "--dts: time steps must lie in [0.00001, 1] s, got 1e-300",
        ),
        (
            ["scale", "--max-seconds", "-1"],
            "--max-seconds must be a positive number of seconds, got -1",
        ),
        (
            ["accuracy", "--dts", "-0.01"],
            "--dts: time steps must be positive numbers of seconds, got -0.01",
        ),
        // (It used to run nothing and write empty results.)
        (
            ["accuracy", "--combinations", "foo"],
            "unknown combination 'foo'; this build runs coursework, gyroscopic",
        ),
    ] {
        let mut all: Vec<&std::ffi::OsStr> = vec!["bench".as_ref()];
        all.extend(args.iter().map(std::ffi::OsStr::new));
        all.extend(["--out".as_ref(), out_dir.as_os_str()]);
        cli_fails_saying(&all, words);
    }
    #[cfg(not(feature = "compare-rapier"))]
    cli_fails_saying(
        &["bench", "scale", "--variants", "rapier", "--quick", "--out"]
            .map(std::ffi::OsStr::new)
            .into_iter()
            .chain([out_dir.as_os_str()])
            .collect::<Vec<_>>(),
        "--variants rapier: this build has no Rapier",
    );
    assert!(!out_dir.exists(), "nothing written");
    // A file where the folder should be is named before anything runs (it failed after the
    // whole run with "File exists (os error 17)").
    let file = std::env::temp_dir().join(format!("tumble-bench-file-{}", std::process::id()));
    std::fs::write(&file, "").unwrap();
    let args = "bench accuracy --scenarios free-fall --dts 0.04 --out".split(' ');
    let mut all: Vec<&std::ffi::OsStr> = args.map(std::ffi::OsStr::new).collect();
    all.push(file.as_os_str());
    cli_fails_saying(&all, &format!("--out {}: a file is there", file.display()));
    std::fs::remove_file(&file).unwrap();
    // The help lists every combination the bench knows.
    let help = std::process::Command::new(env!("CARGO_BIN_EXE_tumble"))
        .args(["bench", "accuracy", "--help"])
        .output()
        .unwrap();
    let help = String::from_utf8_lossy(&help.stdout);
    for name in tumble::bench::accuracy::combination_names() {
        assert!(help.contains(name), "--help lacks {name}");
    }
}

/// `tumble run --help` names every scene it can load by name and the defaults it runs with,
/// which are those of [`Settings::default`] (the flags are optional so that a given one
/// overrides `--accurate`; clap cannot show the default itself).
#[cfg(feature = "cli")]
#[test]
fn run_help_names_the_scenes_and_the_defaults() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_tumble"))
        .args(["run", "--help"])
        .output()
        .unwrap();
    let help = String::from_utf8_lossy(&out.stdout)
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ");
    let families = tumble::scene::generate::FAMILIES
        .iter()
        .map(|(name, _)| *name);
    for name in tumble::BUILTIN_SCENES
        .iter()
        .map(|(name, _)| *name)
        .chain(families)
    {
        assert!(help.contains(name), "--help lacks {name}");
    }
    let d = Settings::default();
    for (flag, value) in [
        ("Time step in seconds", d.time_step),
        ("1 = elastic)", d.restitution),
        ("no friction)", d.friction),
        (
            "constraint visits (coursework solver)",
            d.max_iterations as f64,
        ),
        ("Constraint tolerance (coursework solver)", d.tolerance),
        ("bounce with e = 0", d.restitution_threshold),
        ("longer than 1/80 s)", d.substeps as f64),
    ] {
        let said = format!("{flag} [default: {value}");
        assert!(help.contains(&said), "--help lacks '{said}'");
    }
}

/// A flag the chosen solver ignores is accepted with a warning saying so; with the solver it
/// acts on, no warning.
#[cfg(feature = "cli")]
#[test]
fn cli_warns_of_settings_the_solver_ignores() {
    let run = |extra: &[&str]| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_tumble"))
            .args(["run", "cube", "--steps", "2"])
            .args(extra)
            .output()
            .unwrap();
        assert!(out.status.success());
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let warned = run(&["--friction", "0.3"]);
    assert!(
        warned.contains("warning: --friction acts on the soft-step solver only"),
        "{warned}"
    );
    assert!(!run(&["--friction", "0.3", "--accurate"]).contains("warning"));
    // Each solver's own flags, given to the other.
    let coursework_only = [
        &["--max-iterations", "100000"][..],
        &["--tolerance", "0.1"],
        &["--constraint-schedule", "sparse"],
        &["--skip-separating-contacts"],
        &["--contact-patches"],
        &["--broad-phase", "all-pairs"],
    ];
    for flags in coursework_only {
        let warned = run(&[flags, &["--accurate"]].concat());
        let said = format!("warning: {} acts on the coursework's solver only", flags[0]);
        assert!(warned.contains(&said), "{warned}");
        assert!(!run(flags).contains("warning"), "{flags:?}");
    }
    let warned = run(&["--full-substeps-from", "0.05"]);
    assert!(warned.contains("--full-substeps-from acts on the soft-step solver only"));
    assert!(!run(&["--full-substeps-from", "0.05", "--accurate"]).contains("warning"));
    assert!(run(&["--dt", "0"]).contains("--dt 0: time does not advance"));
    assert!(run(&["--dt", "1e9"]).contains("--dt 1000000000: steps over 0.1 s"));
    // Not three hundred digits.
    assert!(run(&["--dt", "1e300"]).contains("--dt 1e300: steps over 0.1 s"));
    assert!(!run(&["--dt", "0.1"]).contains("warning"));
    assert!(
        run(&["--dt", "1e-300"])
            .contains("--dt 1e-300: under 1e-7 s a simulated second takes over ten million steps")
    );
    assert!(!run(&["--dt", "1e-7"]).contains("warning"));
}

/// A constraint file given with a generated scene is refused (it ran without it, in silence),
/// `none` too; a built-in scene takes either.
#[cfg(feature = "cli")]
#[test]
fn cli_refuses_a_constraint_file_for_a_generated_scene() {
    let os = std::ffi::OsStr::new;
    for (scene, choice) in [("pile-10", "none"), ("rope-5", "none"), ("rope-5", "c.txt")] {
        cli_fails_saying(
            &[os("run"), os(scene), os("--constraints"), os(choice)],
            "a generated scene makes its own distance constraints",
        );
    }
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_tumble"))
        .args(["run", "two-chain", "--constraints", "none", "--steps", "1"])
        .output()
        .unwrap();
    assert!(out.status.success());
}

/// A constraint budget that cannot visit each inequality once a step is said, with the least
/// budget that can: chain-100's 180 inequalities get ceil(10000 / 180) = 56 visits a step, and
/// 180 from 179 x 180 + 1 = 32221 on.
#[cfg(feature = "cli")]
#[test]
fn cli_warns_of_a_budget_short_of_one_pass() {
    let stderr = |args: &[&str]| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_tumble"))
            .args(args)
            .output()
            .unwrap();
        assert!(out.status.success());
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let warned = stderr(&["run", "chain-100", "--steps", "1"]);
    assert!(
        warned.contains("allows 56 constraint visits a step for 180 inequalities")
            && warned.contains("--max-iterations 32221 or more"),
        "{warned}"
    );
    let budget = |k: &'static str| ["run", "chain-100", "--steps", "1", "--max-iterations", k];
    assert!(stderr(&budget("32220")).contains("allows 179 constraint visits a step"));
    assert!(!stderr(&budget("32221")).contains("warning"));
    assert!(!stderr(&["run", "two-chain", "--steps", "1"]).contains("warning"));
    assert!(!stderr(&["run", "chain-100", "--steps", "1", "--accurate"]).contains("warning"));
}

/// A negative count is named as one (clap's own message for it was "unexpected argument '-1'").
#[cfg(feature = "cli")]
#[test]
fn cli_names_a_negative_count() {
    let os = std::ffi::OsStr::new;
    cli_fails_saying(
        &[os("run"), os("cube"), os("--steps"), os("-1")],
        "expected a whole number, 0 or more, got '-1'",
    );
}
