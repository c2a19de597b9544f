//! Object File Format surface meshes (`.off`). tumble simulates volumes, so the surface is
//! tetrahedralised as a fan from its volume centroid to every triangle. The fan's tetrahedra
//! count by their signed volumes ([`TetVolumes::Signed`]), so the mass properties are those of
//! the closed surface's solid whatever its shape (a U whose centroid lies in its gap, outside
//! the solid); a convex surface's are the same bits either way, but for faces of no area, whose
//! rounding-level volumes now cancel. (The narrow phase collides the mesh's convex hull.)

use super::limits::MAX_MESH_ELEMENTS;
use super::tokens::{RecordLayout, Tokens};
use super::{LoadError, TetMesh, TetVolumes};
use glam::DVec3;
use std::collections::HashMap;
use std::path::Path;

const VERTEX_RECORD: RecordLayout = RecordLayout {
    name: "a vertex record",
    fields: &["x", "y", "z"],
};

pub fn parse_off(file: &Path, text: &str) -> Result<TetMesh, LoadError> {
    let mut tokens = Tokens::new(file, text);
    let header = tokens.next("the 'OFF' header")?;
    if !header.text.eq_ignore_ascii_case("OFF") {
        let line = header.line;
        let found = header.text.to_string();
        return Err(tokens.error(line, format!("expected the 'OFF' header, found '{found}'")));
    }
    let vertex_count_line = tokens.line();
    let vertex_count = tokens.count("the vertex count", 3, MAX_MESH_ELEMENTS)?;
    let (face_count, face_line) = tokens.index("the face count")?;
    // The edge count is optional (some exporters write only two numbers).
    if tokens.peek().is_some_and(|t| t.line == face_line) {
        tokens.index("the edge count")?;
    }
    if face_count > MAX_MESH_ELEMENTS || face_count > tokens.remaining() / 4 {
        return Err(tokens.error(
            face_line,
            format!("the face count {face_count} is more than the file can hold"),
        ));
    }
    tokens.begin_records(vertex_count, &VERTEX_RECORD);
    let mut vertices = Vec::with_capacity(vertex_count);
    for _ in 0..vertex_count {
        let (x, _) = tokens.real("a vertex x coordinate")?;
        let (y, _) = tokens.real("a vertex y coordinate")?;
        let (z, _) = tokens.real("a vertex z coordinate")?;
        vertices.push(DVec3::new(x, y, z));
    }
    let mut triangles = Vec::with_capacity(face_count);
    // The line of each triangle's face (a polygon's fan shares its face's).
    let mut lines = Vec::with_capacity(face_count);
    for face in 0..face_count {
        let line = tokens.line();
        // A vertex count too small shows at the first face: the next vertex is read as one.
        let first =
            (face == 0 && tokens.peek().is_some()).then_some((vertex_count, vertex_count_line));
        let hint = |tokens: &Tokens, error| with_vertex_hint(tokens, error, first);
        let corners = tokens
            .index("the number of corners of a face")
            .map_err(|e| hint(&tokens, e))?
            .0;
        if !(3..=1024).contains(&corners) {
            let found = format!("a face needs 3 to 1024 corners, found {corners}");
            return Err(hint(&tokens, tokens.error(line, found)));
        }
        let mut polygon = Vec::with_capacity(corners);
        for _ in 0..corners {
            let (index, line) = tokens.index("a face vertex index")?;
            if index >= vertex_count {
                return Err(tokens.error(line, format!("face refers to vertex {index} but the mesh has only {vertex_count} vertices (0-based)")));
            }
            polygon.push(index as u32);
        }
        // Skip an optional colour on the same line.
        while tokens.peek().is_some_and(|t| t.line == line) {
            tokens.next("a colour component")?;
        }
        // Each polygon is a fan of triangles, held to the mesh's limit as they come: 1024-corner
        // faces in a 246 MB file made 8 GB of triangles before any check.
        if triangles.len() + (corners - 2) > MAX_MESH_ELEMENTS {
            let found = format!(
                "the faces up to this one make more than {MAX_MESH_ELEMENTS} triangles, the most a mesh may have"
            );
            return Err(tokens.error(line, found));
        }
        for k in 1..corners - 1 {
            triangles.push([polygon[0], polygon[k], polygon[k + 1]]);
            lines.push(line);
        }
    }
    tokens.expect_end(&super::counted(face_count as u64, "face", "faces"))?;
    if triangles.is_empty() {
        return Err(LoadError::new(file, None, "the surface has no faces"));
    }
    if let Some((line, problem)) = unmatched_edge(&vertices, (&triangles, &lines)) {
        return Err(tokens.error(line, problem));
    }
    fan_tetrahedralise(file, vertices, triangles)
}

/// `error`, found where the first face should begin (`first`: the vertex count and its line),
/// with a hint where its line holds three numbers, as a vertex does: the vertex count is likely
/// smaller than the vertices listed, and the first vertex past it was read as a face.
fn with_vertex_hint(tokens: &Tokens, error: LoadError, first: Option<(usize, usize)>) -> LoadError {
    let (Some((count, line)), Some(at)) = (first, error.line) else {
        return error;
    };
    let fields: Vec<&str> = tokens.fields_on(at).collect();
    if fields.len() != 3 || fields.iter().any(|f| f.parse::<f64>().is_err()) {
        return error;
    }
    let hint = format!(
        "; line {at} holds three numbers, as a vertex does: is the vertex count on line {line} \
         ({count}) smaller than the vertices listed?"
    );
    LoadError {
        message: error.message + &hint,
        ..error
    }
}

/// Why the surface does not bound a volume once, if it does not: a face listed twice the same
/// way round, or the first edge (by vertex index) whose faces do not pair up, one on each side
/// and wound against each other. The fan below (the divergence theorem) is exact only for a
/// closed, consistently wound surface; an open one would be simulated with part of its mass, a
/// closed part listed twice (every edge paired with its copy's) with twice it. Vertices at the
/// same point are one vertex, so a surface cut into patches along seams (as exporters write
/// them for normals) is still closed. Named on the line of the last face concerned (`lines`:
/// each triangle's), with the vertex indices as that face writes them.
fn unmatched_edge(
    vertices: &[DVec3],
    (triangles, lines): (&[[u32; 3]], &[usize]),
) -> Option<(usize, String)> {
    let weld = welded(vertices);
    let corners = |t: &[u32; 3]| t.map(|i| weld[i as usize]);
    // Each face turned to start at its least vertex, so the same face wound the same way has
    // the same key; a flat one (two corners at one point, no volume) has a key of its own.
    let same_way = triangles.iter().enumerate().map(|(k, t)| {
        let [a, b, c] = corners(t);
        match (a < b && a < c, b < c) {
            _ if a == b || b == c || c == a => Err(k),
            (true, _) => Ok([a, b, c]),
            (false, true) => Ok([b, c, a]),
            (false, false) => Ok([c, a, b]),
        }
    });
    if let Some((first, again)) = super::first_repeat(same_way) {
        let [a, b, c] = triangles[again];
        let other = match lines[first] == lines[again] {
            true => "this face covers it twice".to_string(),
            false => format!("the face on line {} has it too", lines[first]),
        };
        return Some((
            lines[again],
            format!(
                "the surface has the triangle of vertices {a}, {b}, {c} (0-based) twice ({other}, at the same points and wound the same way): its volume would count twice"
            ),
        ));
    }
    // Each edge a -> b counts +1 on (a, b) for a < b and -1 otherwise: 0 when its faces pair up.
    let mut balance: HashMap<(u32, u32), i32> = HashMap::new();
    for t in triangles {
        for k in 0..3 {
            let (a, b) = (weld[t[k] as usize], weld[t[(k + 1) % 3] as usize]);
            match a.cmp(&b) {
                std::cmp::Ordering::Less => *balance.entry((a, b)).or_default() += 1,
                std::cmp::Ordering::Greater => *balance.entry((b, a)).or_default() -= 1,
                std::cmp::Ordering::Equal => {}
            }
        }
    }
    let (edge, count) = balance.into_iter().filter(|&(_, c)| c != 0).min()?;
    let (line, (a, b), others) = faces_on_edge(edge, &weld, (triangles, lines));
    let problem = if count % 2 == 0 && others.is_empty() {
        format!(
            "this face's triangles on the edge between vertices {a} and {b} (0-based) are wound the same way: a closed surface's faces are all wound one way round"
        )
    } else if count % 2 == 0 {
        format!(
            "the faces on the edge between vertices {a} and {b} (0-based), this one and {others}, are wound the same way: a closed surface's faces are all wound one way round"
        )
    } else if others.is_empty() {
        format!(
            "the surface is not closed: the edge between vertices {a} and {b} (0-based) has a face on one side only"
        )
    } else {
        format!(
            "the surface is not closed: the edge between vertices {a} and {b} (0-based) has this face and {others}, where a closed surface has one on each side"
        )
    };
    Some((line, problem))
}

/// The faces whose triangles hold the welded `edge`: the last one's line and the edge's
/// vertices as it writes them (smaller first), and the others' lines in words ("the one on line
/// 7", "those on lines 7 and 9"; empty for none).
fn faces_on_edge(
    edge: (u32, u32),
    weld: &[u32],
    (triangles, lines): (&[[u32; 3]], &[usize]),
) -> (usize, (u32, u32), String) {
    let mut found: Vec<(usize, (u32, u32))> = (triangles.iter().zip(lines))
        .filter_map(|(t, &line)| {
            (0..3).find_map(|k| {
                let (p, q) = (t[k], t[(k + 1) % 3]);
                let (a, b) = (weld[p as usize], weld[q as usize]);
                ((a, b) == edge || (b, a) == edge).then_some((line, (p.min(q), p.max(q))))
            })
        })
        .collect();
    let (line, written) = found.pop().expect("an unbalanced edge has a face");
    let mut others: Vec<usize> = found
        .iter()
        .map(|&(l, _)| l)
        .filter(|&l| l != line)
        .collect();
    others.dedup();
    let others = match others.as_slice() {
        [] => String::new(),
        [one] => format!("the one on line {one}"),
        [rest @ .., last] => {
            let rest: Vec<String> = rest.iter().map(|l| l.to_string()).collect();
            format!("those on lines {} and {last}", rest.join(", "))
        }
    };
    (line, written, others)
}

/// Each vertex's first index at its point: vertices at the same point are one vertex.
fn welded(vertices: &[DVec3]) -> Vec<u32> {
    let mut first_at: HashMap<[u64; 3], u32> = HashMap::new();
    (0..vertices.len() as u32)
        .map(|i| {
            // (+ 0.0 makes -0.0 the same point as 0.0.)
            let key = (vertices[i as usize] + DVec3::ZERO)
                .to_array()
                .map(f64::to_bits);
            *first_at.entry(key).or_insert(i)
        })
        .collect()
}

/// Builds tetrahedra (centroid, a, b, c) over a closed surface, orienting the triangles outward.
fn fan_tetrahedralise(
    file: &Path,
    mut vertices: Vec<DVec3>,
    mut triangles: Vec<[u32; 3]>,
) -> Result<TetMesh, LoadError> {
    // Signed volume and first moment by the divergence theorem, about the vertex mean for accuracy.
    let origin = vertices.iter().copied().sum::<DVec3>() / vertices.len() as f64;
    let mut volume = 0.0;
    let mut moment = DVec3::ZERO;
    for t in &triangles {
        let [a, b, c] = t.map(|i| vertices[i as usize] - origin);
        let v = a.dot(b.cross(c)) / 6.0;
        volume += v;
        moment += v * (a + b + c) / 4.0;
    }
    if !volume.is_finite() || !moment.is_finite() {
        // The coordinates are finite (checked as read), so the sums overflowed.
        return Err(LoadError::new(
            file,
            None,
            "the surface is too large: its volume overflows double precision",
        ));
    }
    if volume == 0.0 {
        return Err(LoadError::new(
            file,
            None,
            "the surface encloses no volume (degenerate or open mesh)",
        ));
    }
    if volume < 0.0 {
        for t in &mut triangles {
            t.swap(1, 2);
        }
    }
    let centroid = origin + moment / volume;
    let apex = vertices.len() as u32;
    vertices.push(centroid);
    let tetrahedra = triangles.iter().map(|t| [apex, t[0], t[1], t[2]]).collect();
    Ok(TetMesh {
        vertices,
        tetrahedra,
        triangles,
        volumes: TetVolumes::Signed,
        added_vertices: 1,
    })
}
