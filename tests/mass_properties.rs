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
    let s = shape(&mesh);
    // The shape's triangles are in body space (centre of mass at the origin).
    let (volume, center, inertia) = surface_mass_properties(&s.rest_vertices, &s.triangles);
    assert_close(s.volume, volume, 1e-10, "volume");
    assert!(
        center.length() < 1e-9 * s.volume.cbrt(),
        "centre of mass {center}"
    );
    for k in 0..3 {
        for l in 0..3 {
            let scale = inertia.col(k)[k].abs();
            assert!(
                (s.unit_inertia.col(k)[l] - inertia.col(k)[l]).abs() < 1e-9 * scale,
                "inertia[{k}][{l}]: tets {} vs surface {}",
                s.unit_inertia.col(k)[l],
                inertia.col(k)[l]
            );
        }
    }
}

#[test]
fn shipped_meshes_match_surface_integral() {
    for (name, mesh) in assets::all_meshes() {
        let s = shape(&mesh);
        let (volume, _, inertia) = surface_mass_properties(&s.rest_vertices, &s.triangles);
        assert_close(s.volume, volume, 1e-11, name);
        for k in 0..3 {
            assert_close(s.unit_inertia.col(k)[k], inertia.col(k)[k], 1e-10, name);
        }
    }
}

/// Each tetrahedron of `mesh` with two corners swapped where `flip(k)`: the same solid, wound
/// the other way (as tet meshers that use the opposite convention write it).
fn flipped(mesh: &tumble::io::TetMesh, flip: impl Fn(usize) -> bool) -> tumble::io::TetMesh {
    let mut m = mesh.clone();
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
