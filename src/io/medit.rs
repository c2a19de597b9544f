//! Medit `.mesh` tetrahedral meshes (the coursework's format): sections `Vertices`, `Triangles`,
//! `Tetrahedra`, 1-based indices, each row ending in a reference number that is ignored.

use super::limits::MAX_MESH_ELEMENTS;
use super::tokens::{RecordLayout, Tokens};
use super::{LoadError, TetMesh};
use glam::DVec3;
use std::fmt::Write;
use std::path::Path;

const VERTEX_RECORD: RecordLayout = RecordLayout {
    name: "a vertex record",
    fields: &["x", "y", "z", "reference"],
};
const TRIANGLE_RECORD: RecordLayout = RecordLayout {
    name: "a triangle record",
    fields: &["v1", "v2", "v3", "reference"],
};
const TETRAHEDRON_RECORD: RecordLayout = RecordLayout {
    name: "a tetrahedron record",
    fields: &["v1", "v2", "v3", "v4", "reference"],
};

/// Parses a Medit mesh. The coursework stores boundary triangles wound inward and flips them on
/// load; so does this reader (the geometry stage then checks the orientation and repairs it).
pub fn parse_medit(file: &Path, text: &str) -> Result<TetMesh, LoadError> {
    let mut tokens = Tokens::new(file, text);
    let mut mesh = TetMesh::default();
    let mut seen_vertices = false;
    // Index checks wait until all sections are read: a file may list elements before vertices.
    let mut tet_lines = Vec::new();
    let mut tri_lines = Vec::new();
    // The last section of records read: its keyword, the line of its count and the count. A
    // record past the count (one added without raising the count) reads as a keyword.
    let mut last: Option<(&str, usize, usize)> = None;

    while let Some(token) = tokens.peek() {
        let (written, line) = (token.text, token.line);
        let keyword = written.to_ascii_lowercase();
        tokens.next("a section keyword")?;
        let count_line = tokens.line();
        // Each section of records gives its count; the two header keywords none.
        let count = match keyword.as_str() {
            "meshversionformatted" | "dimension" => {
                let (value, line) = tokens.index(if keyword == "dimension" {
                    "a number after Dimension"
                } else {
                    "a number after MeshVersionFormatted"
                })?;
                if keyword == "dimension" && value != 3 {
                    return Err(tokens.error(
                        line,
                        format!("only 3-dimensional meshes are supported, found Dimension {value}"),
                    ));
                }
                None
            }
            // A second list would be numbered after the first, which no writer means.
            "vertices" if seen_vertices => {
                return Err(tokens.error(line, "a second Vertices section"));
            }
            "vertices" => {
                read_vertices(&mut tokens, &mut mesh.vertices)?;
                seen_vertices = true;
                Some(mesh.vertices.len())
            }
            "triangles" => {
                let first = mesh.triangles.len();
                read_elements(
                    &mut tokens,
                    &TRIANGLE_RECORD,
                    &mut mesh.triangles,
                    &mut tri_lines,
                )?;
                // Flipped: stored inward, wanted outward.
                mesh.triangles[first..]
                    .iter_mut()
                    .for_each(|t| t.swap(1, 2));
                Some(mesh.triangles.len() - first)
            }
            "tetrahedra" => {
                let first = mesh.tetrahedra.len();
                read_elements(
                    &mut tokens,
                    &TETRAHEDRON_RECORD,
                    &mut mesh.tetrahedra,
                    &mut tet_lines,
                )?;
                Some(mesh.tetrahedra.len() - first)
            }
            "edges" => Some(skip_records(&mut tokens, "the edge count", 3)?),
            "corners" | "ridges" | "requiredvertices" | "requirededges" | "requiredtriangles" => {
                Some(skip_records(&mut tokens, "the record count", 1)?)
            }
            "end" => break,
            _ => return Err(unknown_section(&tokens, (written, line), last)),
        };
        last = count.map(|count| (written, count_line, count));
    }

    if !seen_vertices || mesh.vertices.is_empty() {
        return Err(LoadError::new(
            file,
            None,
            "the mesh has no vertices (missing 'Vertices' section)",
        ));
    }
    if mesh.tetrahedra.is_empty() {
        return Err(LoadError::new(
            file,
            None,
            "the mesh has no tetrahedra (missing 'Tetrahedra' section)",
        ));
    }
    let n = mesh.vertices.len();
    for (tet, &line) in mesh.tetrahedra.iter().zip(&tet_lines) {
        check_indices(&tokens, tet, n, line, "tetrahedron")?;
    }
    for (tri, &line) in mesh.triangles.iter().zip(&tri_lines) {
        check_indices(&tokens, tri, n, line, "triangle")?;
    }
    refuse_repeated_tetrahedra(&tokens, &mesh.tetrahedra, &tet_lines)?;
    Ok(mesh)
}

/// A tetrahedron listed twice (its corners in any order), named on its line: its mass would
/// count twice.
fn refuse_repeated_tetrahedra(
    tokens: &Tokens,
    tetrahedra: &[[u32; 4]],
    lines: &[usize],
) -> Result<(), LoadError> {
    let corners = tetrahedra.iter().map(|t| {
        let mut sorted = *t;
        sorted.sort_unstable();
        sorted
    });
    match super::first_repeat(corners) {
        Some((first, again)) => Err(tokens.error(
            lines[again],
            format!(
                "this tetrahedron has the four vertices of the one on line {}: its mass would count twice",
                lines[first]
            ),
        )),
        None => Ok(()),
    }
}

/// A `Vertices` section after its keyword: the count, then `x y z reference` records.
fn read_vertices(tokens: &mut Tokens, vertices: &mut Vec<DVec3>) -> Result<(), LoadError> {
    let count = tokens.count_records("the vertex count", &VERTEX_RECORD, MAX_MESH_ELEMENTS)?;
    vertices.reserve(count);
    for _ in 0..count {
        let (x, _) = tokens.real("a vertex x coordinate")?;
        let (y, _) = tokens.real("a vertex y coordinate")?;
        let (z, _) = tokens.real("a vertex z coordinate")?;
        tokens.real("the vertex reference number")?;
        vertices.push(DVec3::new(x, y, z));
    }
    Ok(())
}

/// A `Triangles` or `Tetrahedra` section after its keyword: the count, then records of `N`
/// 1-based vertex indices and a reference number, kept 0-based with the line of each (their
/// indices are checked once every vertex is read).
fn read_elements<const N: usize>(
    tokens: &mut Tokens,
    layout: &'static RecordLayout,
    elements: &mut Vec<[u32; N]>,
    lines: &mut Vec<usize>,
) -> Result<(), LoadError> {
    let what = if N == 3 { "triangle" } else { "tetrahedron" };
    let count = tokens.count_records(&format!("the {what} count"), layout, MAX_MESH_ELEMENTS)?;
    elements.reserve(count);
    let (index_what, reference_what) = (
        format!("a {what} vertex index"),
        format!("the {what} reference number"),
    );
    for _ in 0..count {
        lines.push(tokens.line());
        let mut element = [0u32; N];
        for slot in &mut element {
            *slot = one_based(tokens, &index_what)?;
        }
        tokens.real(&reference_what)?;
        elements.push(element);
    }
    Ok(())
}

fn one_based(tokens: &mut Tokens, what: &str) -> Result<u32, LoadError> {
    let (value, line) = tokens.index(what)?;
    if value == 0 {
        return Err(tokens.error(line, format!("{what} is 0, but Medit indices start at 1")));
    }
    u32::try_from(value - 1).map_err(|_| tokens.error(line, format!("{what} {value} is too large")))
}

fn check_indices(
    tokens: &Tokens,
    element: &[u32],
    vertex_count: usize,
    line: usize,
    what: &str,
) -> Result<(), LoadError> {
    for &index in element {
        if index as usize >= vertex_count {
            return Err(tokens.error(
                line,
                format!(
                    "{what} refers to vertex {} but the mesh has only {vertex_count} vertices",
                    u64::from(index) + 1
                ),
            ));
        }
    }
    Ok(())
}

/// Skips a section of `count` records of `per_record` numbers; returns the count.
fn skip_records(tokens: &mut Tokens, what: &str, per_record: usize) -> Result<usize, LoadError> {
    let count = tokens.count(what, per_record, MAX_MESH_ELEMENTS)?;
    for _ in 0..count * per_record {
        tokens.real("a record field")?;
    }
    Ok(count)
}

/// Sections of the Medit format that tumble refuses rather than skip (lower case): skipping
/// them would need their record widths, and a tet mesh does not need them.
const MEDIT_SECTIONS_NOT_READ: [&str; 9] = [
    "normals",
    "normalatvertices",
    "tangents",
    "tangentatvertices",
    "quadrilaterals",
    "hexahedra",
    "prisms",
    "corners",
    "ridges",
];

/// A word where a section keyword should be, `(written, line)`. A number there is most often
/// a record past the count of the section before (`last`: its keyword, count line and count):
/// a record added by hand without raising the count.
fn unknown_section(
    tokens: &Tokens,
    (written, line): (&str, usize),
    last: Option<(&str, usize, usize)>,
) -> LoadError {
    let expected = "expected Vertices, Triangles, Tetrahedra, Edges or End";
    let message = match last {
        Some((section, count_line, count)) if written.parse::<f64>().is_ok() => format!(
            "a number, '{written}', where a section keyword should be ({expected}): is the \
             {section} count on line {count_line} ({count}) smaller than the records under it?"
        ),
        _ if MEDIT_SECTIONS_NOT_READ.contains(&written.to_ascii_lowercase().as_str()) => format!(
            "section '{written}' is Medit's but tumble does not read it ({expected}): a body is \
             its vertices and tetrahedra"
        ),
        _ => format!("unknown section '{written}' ({expected})"),
    };
    tokens.error(line, message)
}

/// Writes a mesh in the coursework's convention (triangles stored inward, as `parse_medit`
/// expects).
pub fn write_medit(mesh: &TetMesh) -> String {
    let mut out = String::from("MeshVersionFormatted 1\nDimension 3\n");
    let _ = writeln!(out, "Vertices\n{}", mesh.vertices.len());
    for v in &mesh.vertices {
        let _ = writeln!(out, "{} {} {} 0", v.x, v.y, v.z);
    }
    let _ = writeln!(out, "Triangles\n{}", mesh.triangles.len());
    for t in &mesh.triangles {
        let _ = writeln!(out, "{} {} {} 0", t[0] + 1, t[2] + 1, t[1] + 1);
    }
    let _ = writeln!(out, "Tetrahedra\n{}", mesh.tetrahedra.len());
    for t in &mesh.tetrahedra {
        let _ = writeln!(out, "{} {} {} {} 0", t[0] + 1, t[1] + 1, t[2] + 1, t[3] + 1);
    }
    out.push_str("End\n");
    out
}
