//! Mass properties against closed forms and an independent surface integral.
mod common;

use common::*;
use glam::{DMat3, DVec3};
use tumble::RigidBody;
use tumble::io::parse_medit;
use tumble::scene::assets;

#[test]
fn unit_cube_has_closed_form_mass_properties() {
    let s = shape(&assets::cuboid(DVec3::splat(0.5)));
    assert_close(s.volume, 1.0, 1e-14, "volume");
    // Solid cube of side a, mass m: I = m a^2 / 6 about every axis through the centre.
    for k in 0..3 {
        assert_close(
            s.unit_inertia.col(k)[k],
            1.0 / 6.0,
            1e-14,
            "principal moment",
        );
        for l in 0..3 {
            if k != l {
                assert!(s.unit_inertia.col(k)[l].abs() < 1e-15, "product of inertia");
            }
        }
    }
    let b = RigidBody::on_shape(&s, 0, 3.0, false, DVec3::ZERO, glam::DQuat::IDENTITY);
    assert_close(b.inverse_mass, 1.0 / 3.0, 1e-14, "inverse mass 1/(rho V)");
    assert_close(
        b.inverse_inertia.to_mat3().col(0)[0],
        2.0,
        1e-13,
        "inverse inertia",
    );
}

#[test]
fn regular_tetrahedron_has_closed_form_mass_properties() {
    let r = 6.0;
    let s = shape(&assets::tetrahedron(r));
    let a = r * (8.0f64 / 3.0).sqrt(); // edge of a regular tetrahedron of circumradius r
    let volume = a.powi(3) / (6.0 * 2f64.sqrt());
    assert_close(s.volume, volume, 1e-13, "volume a^3/(6 sqrt 2)");
    // Regular tetrahedron: isotropic inertia m a^2 / 20.
    let expected = volume * a * a / 20.0;
    for k in 0..3 {
        assert_close(
            s.unit_inertia.col(k)[k],
            expected,
            1e-12,
            "principal moment",
        );
    }
    // The rest vertices are re-centred on the centre of mass.
    let mean: DVec3 = s.rest_vertices.iter().copied().sum::<DVec3>() / 4.0;
    assert!(mean.length() < 1e-12);
}

/// Volume, centre of mass and inertia from the closed boundary alone, by the divergence theorem
/// (Eberly, "Polyhedral Mass Properties (Revisited)", 2002): an independent check of the
/// tetrahedral integration, which never looks at the boundary.
fn surface_mass_properties(vertices: &[DVec3], triangles: &[[u32; 3]]) -> (f64, DVec3, DMat3) {
    let mut integral = [0.0f64; 10]; // 1, x, y, z, x^2, y^2, z^2, xy, yz, zx
    let sub = |w0: f64, w1: f64, w2: f64| {
        let temp0 = w0 + w1;
        let f1 = temp0 + w2;
        let temp1 = w0 * w0;
        let temp2 = temp1 + w1 * temp0;
        let f2 = temp2 + w2 * f1;
        let f3 = w0 * temp1 + w1 * temp2 + w2 * f2;
        let g0 = f2 + w0 * (f1 + w0);
        let g1 = f2 + w1 * (f1 + w1);
        let g2 = f2 + w2 * (f1 + w2);
        (f1, f2, f3, g0, g1, g2)
    };
    for t in triangles {
        let [p0, p1, p2] = t.map(|i| vertices[i as usize]);
        let d = (p1 - p0).cross(p2 - p0);
        let (f1x, f2x, f3x, g0x, g1x, g2x) = sub(p0.x, p1.x, p2.x);
        let (_f1y, f2y, f3y, g0y, g1y, g2y) = sub(p0.y, p1.y, p2.y);
        let (_f1z, f2z, f3z, g0z, g1z, g2z) = sub(p0.z, p1.z, p2.z);
        integral[0] += d.x * f1x;
        integral[1] += d.x * f2x;
        integral[2] += d.y * f2y;
        integral[3] += d.z * f2z;
        integral[4] += d.x * f3x;
        integral[5] += d.y * f3y;
        integral[6] += d.z * f3z;
        integral[7] += d.x * (p0.y * g0x + p1.y * g1x + p2.y * g2x);
        integral[8] += d.y * (p0.z * g0y + p1.z * g1y + p2.z * g2y);
        integral[9] += d.z * (p0.x * g0z + p1.x * g1z + p2.x * g2z);
    }
    let mult = [
        1.0 / 6.0,
        1.0 / 24.0,
        1.0 / 24.0,
        1.0 / 24.0,
        1.0 / 60.0,
        1.0 / 60.0,
        1.0 / 60.0,
        1.0 / 120.0,
        1.0 / 120.0,
        1.0 / 120.0,
    ];
    for k in 0..10 {
        integral[k] *= mult[k];
    }
    let mass = integral[0];
    let c = DVec3::new(integral[1], integral[2], integral[3]) / mass;
    let ixx = integral[5] + integral[6] - mass * (c.y * c.y + c.z * c.z);
    let iyy = integral[4] + integral[6] - mass * (c.z * c.z + c.x * c.x);
    let izz = integral[4] + integral[5] - mass * (c.x * c.x + c.y * c.y);
    let ixy = -(integral[7] - mass * c.x * c.y);
    let iyz = -(integral[8] - mass * c.y * c.z);
    let ixz = -(integral[9] - mass * c.z * c.x);
    let inertia = DMat3::from_cols(
        DVec3::new(ixx, ixy, ixz),
        DVec3::new(ixy, iyy, iyz),
        DVec3::new(ixz, iyz, izz),
    );
    (mass, c, inertia)
}

#[test]
fn coursework_ellipsoid_inertia_matches_surface_integral() {
    let Some(dir) = coursework_dir() else { return };
    let path = dir.join("ellipsoid.mesh");
    let text = std::fs::read_to_string(&path).unwrap();
    let mesh = parse_medit(&path, &text).unwrap();
    assert_matches_surface_integral(&shape(&mesh), "ellipsoid.mesh");
}

/// A shape's volume, centre of mass (the origin of body space) and whole inertia tensor against
/// the integrals over its surface triangles, computed independently of the tetrahedra.
fn assert_matches_surface_integral(s: &tumble::Shape, name: &str) {
    let (volume, center, inertia) = surface_mass_properties(&s.rest_vertices, &s.triangles);
    assert_close(s.volume, volume, 1e-10, name);
    assert!(
        center.length() < 1e-9 * s.volume.cbrt(),
        "{name}: centre of mass {center}"
    );
    let scale = (0..3).map(|k| inertia.col(k)[k].abs()).fold(0.0, f64::max);
    for k in 0..3 {
        for l in 0..3 {
            assert!(
                (s.unit_inertia.col(k)[l] - inertia.col(k)[l]).abs() < 1e-9 * scale,
                "{name}: inertia[{k}][{l}]: tets {} vs surface {}",
                s.unit_inertia.col(k)[l],
                inertia.col(k)[l]
            );
        }
    }
}

#[test]
fn shipped_meshes_match_surface_integral() {
    for (name, mesh) in assets::all_meshes() {
        assert_matches_surface_integral(&shape(&mesh), name);
    }
}

/// Each tetrahedron of `mesh` with two corners swapped where `flip(k)`: the same solid, wound
/// the other way (as tet meshers that use the opposite convention write it), read as a tet
/// mesh is (absolute volumes; an `.off` surface's fan counts signed ones, and its convex
/// surfaces give the same either way).
fn flipped(mesh: &tumble::io::TetMesh, flip: impl Fn(usize) -> bool) -> tumble::io::TetMesh {
    let mut m = mesh.clone();
    m.volumes = tumble::io::TetVolumes::Absolute;
    for (k, t) in m.tetrahedra.iter_mut().enumerate() {
        if flip(k) {
            t.swap(1, 2);
        }
    }
    // Boundary triangles are rebuilt from the tetrahedra.
    m.triangles.clear();
    m
}

#[test]
fn tetrahedron_orientation_does_not_change_mass_properties() {
    let Some(dir) = coursework_dir() else { return };
    let mut meshes: Vec<(String, tumble::io::TetMesh)> = Vec::new();
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let text = || std::fs::read_to_string(&path).unwrap();
        let mesh = match path.extension().and_then(|e| e.to_str()) {
            Some("mesh") => parse_medit(&path, &text()).unwrap(),
            Some("off") => tumble::io::parse_off(&path, &text()).unwrap(),
            _ => continue,
        };
        meshes.push((path.display().to_string(), mesh));
    }
    assert!(
        meshes.len() >= 6,
        "coursework meshes not found in {}",
        dir.display()
    );
    for (name, mesh) in &meshes {
        let reference = shape(mesh);
        for (how, flip) in [
            ("all flipped", &(|_| true) as &dyn Fn(usize) -> bool),
            ("half flipped", &|k| k % 2 == 1),
        ] {
            let s = shape(&flipped(mesh, flip));
            let what = format!("{name}, {how}");
            assert_close(s.volume, reference.volume, 1e-12, &what);
            for k in 0..3 {
                for l in 0..3 {
                    assert_close(
                        s.unit_inertia.col(k)[l],
                        reference.unit_inertia.col(k)[l],
                        1e-12,
                        &what,
                    );
                }
            }
            // Same centre of mass: the re-centred vertices coincide.
            for (a, b) in s.rest_vertices.iter().zip(&reference.rest_vertices) {
                assert_vec_close(*a, *b, 1e-12, &what);
            }
            // And the rebuilt boundary still faces outward (encloses positive volume).
            let (volume, _, _) = surface_mass_properties(&s.rest_vertices, &s.triangles);
            assert_close(volume, s.volume, 1e-10, &what);
        }
    }
}

/// Bodies keep their inertia tensor and its inverse as symmetric matrices (six entries), which
/// gives them back exactly only if both are symmetric to the bit: so for every shipped mesh
/// and every coursework mesh, at several densities.
#[test]
fn inertia_and_its_inverse_are_symmetric_to_the_bit() {
    let mut meshes: Vec<(String, tumble::io::TetMesh)> = assets::all_meshes()
        .into_iter()
        .map(|(name, mesh)| (name.to_string(), mesh))
        .collect();
    if let Some(dir) = coursework_dir() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "mesh") {
                let text = std::fs::read_to_string(&path).unwrap();
                meshes.push((
                    path.display().to_string(),
                    parse_medit(&path, &text).unwrap(),
                ));
            }
        }
    }
    assert!(meshes.len() > 3, "too few meshes: {}", meshes.len());
    for (name, mesh) in &meshes {
        let s = shape(mesh);
        for density in [1.0, 0.37, 1000.0, 7.9e3] {
            let b = RigidBody::on_shape(&s, 0, density, false, DVec3::ZERO, glam::DQuat::IDENTITY);
            let inertia = s.unit_inertia * density;
            assert_eq!(inertia, inertia.transpose(), "{name}: inertia");
            assert_eq!(
                inertia.inverse(),
                inertia.inverse().transpose(),
                "{name}: inverse"
            );
            assert_eq!(b.inertia.to_mat3(), inertia, "{name}: kept inertia");
            assert_eq!(
                b.inverse_inertia.to_mat3(),
                inertia.inverse(),
                "{name}: kept inverse"
            );
        }
    }
}

/// The closed surface of a union of unit cubes (`cells`, integer corners) as OFF text: each
/// cube face not shared with another cube, wound outward.
fn voxel_surface_off(cells: &[[i32; 3]]) -> String {
    let filled = |c: [i32; 3]| cells.contains(&c);
    let (mut vertices, mut faces): (Vec<[i32; 3]>, Vec<[usize; 4]>) = (Vec::new(), Vec::new());
    let mut index = |v: [i32; 3]| match vertices.iter().position(|&w| w == v) {
        Some(k) => k,
        None => {
            vertices.push(v);
            vertices.len() - 1
        }
    };
    for &c in cells {
        for axis in 0..3 {
            for side in [0, 1] {
                let mut neighbour = c;
                neighbour[axis] += 2 * side - 1;
                if filled(neighbour) {
                    continue;
                }
                // The face's corners in the plane of the other two axes, counterclockwise seen
                // from outside (from +axis for side 1, from -axis for side 0).
                let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                let mut square = [(0, 0), (1, 0), (1, 1), (0, 1)];
                if side == 0 {
                    square.reverse();
                }
                faces.push(square.map(|(a, b)| {
                    let mut p = c;
                    p[axis] += side;
                    p[u] += a;
                    p[v] += b;
                    index(p)
                }));
            }
        }
    }
    let mut text = format!("OFF\n{} {} 0\n", vertices.len(), faces.len());
    for v in &vertices {
        text += &format!("{} {} {}\n", v[0], v[1], v[2]);
    }
    for f in &faces {
        text += &format!("4 {} {} {} {}\n", f[0], f[1], f[2], f[3]);
    }
    text
}

/// A U of seven unit cubes, read from its closed surface (`.off`): its centroid lies in the
/// U's gap, outside the solid, so the fan from there reaches some faces from behind. Volume,
/// centre of mass and inertia are the seven cubes' (each m/6 about its centre, moved by the
/// parallel-axis theorem), which the fan's absolute volumes overcount.
#[test]
fn a_surface_not_star_shaped_about_its_centroid_has_the_solids_mass_properties() {
    let cells = [
        [0, 0, 0],
        [1, 0, 0],
        [2, 0, 0],
        [0, 1, 0],
        [0, 2, 0],
        [2, 1, 0],
        [2, 2, 0],
    ];
    let text = voxel_surface_off(&cells);
    let mesh = tumble::io::parse_off(std::path::Path::new("u.off"), &text).unwrap();
    let centres: Vec<DVec3> = (cells.iter())
        .map(|c| DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64) + 0.5)
        .collect();
    let centroid = centres.iter().copied().sum::<DVec3>() / 7.0;
    let mut inertia = DMat3::ZERO;
    for c in &centres {
        let d = *c - centroid;
        let parallel_axis = DMat3::from_diagonal(DVec3::splat(d.length_squared()))
            - DMat3::from_cols(d * d.x, d * d.y, d * d.z);
        inertia += DMat3::from_diagonal(DVec3::splat(1.0 / 6.0)) + parallel_axis;
    }
    let s = shape(&mesh);
    assert_close(s.volume, 7.0, 1e-13, "volume");
    let apex = *mesh.vertices.last().unwrap();
    assert_vec_close(apex, centroid, 1e-13, "fan apex at the centroid");
    assert!(
        (1.0..2.0).contains(&apex.x) && (1.0..2.0).contains(&apex.y),
        "the centroid {apex} should lie in the gap, outside the solid"
    );
    for k in 0..3 {
        for l in 0..3 {
            let (got, want) = (s.unit_inertia.col(k)[l], inertia.col(k)[l]);
            assert!(
                (got - want).abs() < 1e-12,
                "inertia ({k}, {l}): {got} vs {want}"
            );
        }
    }
    // The same fan by absolute volumes: what a star-shaped rule gives, too much mass.
    let absolute = tumble::io::TetMesh {
        volumes: tumble::io::TetVolumes::Absolute,
        ..mesh
    };
    assert!(
        shape(&absolute).volume > 7.5,
        "the fan's absolute volumes should overcount"
    );
}

/// The coursework's `.off` surfaces are convex: every fan tetrahedron faces its apex, so
/// signed volumes give their absolute volumes' mass properties bit for bit (the coursework's
/// scenes simulate as they did).
#[test]
fn convex_surfaces_have_the_same_bits_by_either_volume_rule() {
    let Some(dir) = coursework_dir() else { return };
    let mut read = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "off") {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        let mesh = tumble::io::parse_off(&path, &text).unwrap();
        assert_eq!(mesh.volumes, tumble::io::TetVolumes::Signed);
        let absolute = tumble::io::TetMesh {
            volumes: tumble::io::TetVolumes::Absolute,
            ..mesh.clone()
        };
        let (signed, absolute) = (shape(&mesh), shape(&absolute));
        let name = path.display().to_string();
        assert_eq!(signed.volume, absolute.volume, "{name}: volume");
        assert_eq!(
            signed.unit_inertia, absolute.unit_inertia,
            "{name}: inertia"
        );
        assert_eq!(
            signed.rest_vertices, absolute.rest_vertices,
            "{name}: centre of mass"
        );
        read += 1;
    }
    assert!(read >= 10, "only {read} .off meshes in {}", dir.display());
}
