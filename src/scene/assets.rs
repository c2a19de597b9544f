//! tumble's own meshes and generated scenes. `tumble gen-assets` writes them into `assets/` and
//! `scenes/`; the built-in scenes embed those files.

use crate::io::{TetMesh, TetVolumes, write_medit};
use glam::DVec3;
use std::f64::consts::PI;
use std::fmt::Write;

/// Name and mesh of every shipped asset.
pub fn all_meshes() -> Vec<(&'static str, TetMesh)> {
    vec![
        ("tetrahedron", tetrahedron(6.0)),
        ("box", cuboid(DVec3::new(6.0, 3.0, 4.0))),
        ("octahedron", octahedron(DVec3::new(5.0, 5.0, 5.0))),
        ("long-octahedron", octahedron(DVec3::new(3.0, 10.0, 4.0))),
        ("cylinder", cylinder(3.0, 10.0, 24)),
        ("ellipsoid", ellipsoid(DVec3::new(6.0, 4.0, 2.5), 10, 20)),
    ]
}

/// Closes a convex point set's surface into tetrahedra: a fan from the vertex mean (appended as
/// the last vertex) to each triangle, with triangles wound outward.
fn convex_fan(mut vertices: Vec<DVec3>, mut triangles: Vec<[u32; 3]>) -> TetMesh {
    let center = vertices.iter().copied().sum::<DVec3>() / vertices.len() as f64;
    for t in &mut triangles {
        let [a, b, c] = t.map(|i| vertices[i as usize]);
        if (b - a).cross(c - a).dot((a + b + c) / 3.0 - center) < 0.0 {
            t.swap(1, 2);
        }
    }
    let apex = vertices.len() as u32;
    vertices.push(center);
    let tetrahedra = triangles.iter().map(|t| [apex, t[0], t[1], t[2]]).collect();
    // The centre is written into the asset files, a vertex like the others.
    TetMesh {
        vertices,
        tetrahedra,
        triangles,
        volumes: TetVolumes::Absolute,
        added_vertices: 0,
    }
}

/// Regular tetrahedron with circumradius `r`, centred on the origin.
pub fn tetrahedron(r: f64) -> TetMesh {
    let s = r / 3f64.sqrt();
    let vertices = vec![
        DVec3::new(s, s, s),
        DVec3::new(s, -s, -s),
        DVec3::new(-s, s, -s),
        DVec3::new(-s, -s, s),
    ];
    // A single tetrahedron needs no interior vertex.
    let mut mesh = convex_fan(vertices, vec![[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]]);
    mesh.vertices.pop();
    mesh.tetrahedra = vec![[0, 1, 2, 3]];
    let [a, b, c, d] = [0, 1, 2, 3].map(|i| mesh.vertices[i]);
    if (b - a).dot((c - a).cross(d - a)) < 0.0 {
        mesh.tetrahedra = vec![[0, 2, 1, 3]];
    }
    mesh
}

/// Box with half extents `h`.
pub fn cuboid(h: DVec3) -> TetMesh {
    let vertices: Vec<DVec3> = (0..8)
        .map(|i| {
            DVec3::new(
                if i & 1 == 0 { -h.x } else { h.x },
                if i & 2 == 0 { -h.y } else { h.y },
                if i & 4 == 0 { -h.z } else { h.z },
            )
        })
        .collect();
    let quads = [
        [0, 1, 3, 2],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 3, 7, 6],
        [0, 2, 6, 4],
        [1, 3, 7, 5],
    ];
    let triangles = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    convex_fan(vertices, triangles)
}

/// Octahedron with semi-axes `h`.
pub fn octahedron(h: DVec3) -> TetMesh {
    let vertices = vec![
        DVec3::X * h.x,
        -DVec3::X * h.x,
        DVec3::Y * h.y,
        -DVec3::Y * h.y,
        DVec3::Z * h.z,
        -DVec3::Z * h.z,
    ];
    let mut triangles = Vec::new();
    for &x in &[0u32, 1] {
        for &y in &[2u32, 3] {
            for &z in &[4u32, 5] {
                triangles.push([x, y, z]);
            }
        }
    }
    convex_fan(vertices, triangles)
}

/// Cylinder of `radius` and `height` along y with `segments` sides.
pub fn cylinder(radius: f64, height: f64, segments: u32) -> TetMesh {
    let mut vertices = Vec::new();
    for k in 0..segments {
        let a = 2.0 * PI * k as f64 / segments as f64;
        vertices.push(DVec3::new(
            radius * a.cos(),
            -height / 2.0,
            radius * a.sin(),
        ));
        vertices.push(DVec3::new(radius * a.cos(), height / 2.0, radius * a.sin()));
    }
    let bottom = vertices.len() as u32;
    vertices.push(DVec3::new(0.0, -height / 2.0, 0.0));
    vertices.push(DVec3::new(0.0, height / 2.0, 0.0));
    let mut triangles = Vec::new();
    for k in 0..segments {
        let (a, b) = (2 * k, 2 * ((k + 1) % segments));
        triangles.push([a, b, a + 1]);
        triangles.push([b, b + 1, a + 1]);
        triangles.push([bottom, a, b]);
        triangles.push([bottom + 1, a + 1, b + 1]);
    }
    convex_fan(vertices, triangles)
}

/// Ellipsoid with semi-axes `h`, `rings` latitude bands and `segments` longitudes.
pub fn ellipsoid(h: DVec3, rings: u32, segments: u32) -> TetMesh {
    let mut vertices = vec![DVec3::new(0.0, h.y, 0.0), DVec3::new(0.0, -h.y, 0.0)];
    for i in 1..rings {
        let theta = PI * i as f64 / rings as f64;
        for k in 0..segments {
            let phi = 2.0 * PI * k as f64 / segments as f64;
            vertices.push(DVec3::new(
                h.x * theta.sin() * phi.cos(),
                h.y * theta.cos(),
                h.z * theta.sin() * phi.sin(),
            ));
        }
    }
    let ring = |i: u32, k: u32| 2 + (i - 1) * segments + (k % segments);
    let mut triangles = Vec::new();
    for k in 0..segments {
        triangles.push([0, ring(1, k), ring(1, k + 1)]);
        triangles.push([1, ring(rings - 1, k), ring(rings - 1, k + 1)]);
        for i in 1..rings - 1 {
            triangles.push([ring(i, k), ring(i + 1, k), ring(i + 1, k + 1)]);
            triangles.push([ring(i, k), ring(i + 1, k + 1), ring(i, k + 1)]);
        }
    }
    convex_fan(vertices, triangles)
}

/// The built-in stress scene: dozens of mixed bodies falling between fixed cylinder posts.
pub fn stress_scene() -> String {
    let meshes = [
        "tetrahedron",
        "box",
        "octahedron",
        "long-octahedron",
        "cylinder",
        "ellipsoid",
    ];
    let mut records = Vec::new();
    for (x, z) in [
        (-60.0, -60.0),
        (-60.0, 0.0),
        (-60.0, 60.0),
        (0.0, -60.0),
        (0.0, 60.0),
        (60.0, -60.0),
        (60.0, 0.0),
        (60.0, 60.0),
    ] {
        // Upright (the cylinder's axis is y), standing on the ground: 10 high.
        records.push(format!(
            "../assets/cylinder.mesh\t5000\t1\t{x} 5 {z}\t1 0 0 0"
        ));
    }
    let mut k = 0;
    for layer in 0..3 {
        for i in 0..4 {
            for j in 0..4 {
                let mesh = meshes[k % meshes.len()];
                let density = [50.0, 200.0, 800.0][k % 3];
                let (x, y, z) = (
                    -45.0 + 30.0 * i as f64 + 3.0 * layer as f64,
                    30.0 + 25.0 * layer as f64,
                    -45.0 + 30.0 * j as f64,
                );
                // A deterministic spread of tilts.
                let a = 0.3 * (k as f64 * 0.7).sin();
                let (s, c) = (0.5 * a).sin_cos();
                records.push(format!(
                    "../assets/{mesh}.mesh\t{density}\t0\t{x} {y} {z}\t{c} {s} {} 0",
                    s * 0.5
                ));
                k += 1;
            }
        }
    }
    let mut out = format!(
        "# Dozens of mixed bodies falling between fixed cylinder posts (tumble gen-assets).\n{}\n",
        records.len()
    );
    for r in records {
        let _ = writeln!(out, "{r}");
    }
    out
}

/// Files written by `tumble gen-assets`, relative to the repository root.
pub fn generated_files() -> Vec<(String, String)> {
    let mut files: Vec<(String, String)> = all_meshes()
        .into_iter()
        .map(|(name, mesh)| (format!("assets/{name}.mesh"), write_medit(&mesh)))
        .collect();
    files.push(("scenes/stress-scene.txt".into(), stress_scene()));
    files
}
