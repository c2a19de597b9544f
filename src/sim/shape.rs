//! Rigid shapes: a tet mesh re-centred on its centre of mass, its exact mass properties at unit
//! density, its outward boundary and the convex hull used by the narrow phase. Shapes are built
//! once and shared by every body that uses the same mesh.

use glam::{DMat3, DVec3};
use parry3d_f64::shape::ConvexPolyhedron;

/// A tetrahedral mesh as read from a file or generated: vertices, tetrahedra and (optionally)
/// boundary triangles, all 0-based.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TetMesh {
    pub vertices: Vec<DVec3>,
    pub tetrahedra: Vec<[u32; 4]>,
    pub triangles: Vec<[u32; 3]>,
    /// How the tetrahedra's volumes count in the mass properties.
    pub volumes: TetVolumes,
    /// Vertices the reader added after those the file names (an `.off` surface's fan apex):
    /// a constraint file may not name them.
    pub added_vertices: usize,
}

/// How a tetrahedron's volume counts in [`tet_mass_properties`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum TetVolumes {
    /// Each tetrahedron by its absolute volume, as in the coursework's skeleton: tet meshers
    /// differ on orientation, and a mesh that mixes both still has the same mass.
    #[default]
    Absolute,
    /// Each tetrahedron by its signed volume: a fan from one apex over a closed surface wound
    /// outward, where the tetrahedra over faces turned away from the apex count against the
    /// others (the divergence theorem), so the sum is exact for any closed surface, not only one
    /// star-shaped about the apex. Equal to [`TetVolumes::Absolute`], bit for bit, where every
    /// tetrahedron's volume is positive (a convex mesh fanned from inside, without faces of no
    /// area).
    Signed,
}

/// Why a mesh cannot be a rigid body.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ShapeError {
    #[error("the mesh has zero volume (degenerate tetrahedra)")]
    Degenerate,
    #[error("the mesh's vertices are all coplanar or coincident: no convex hull")]
    NoHull,
    #[error("the mesh has non-finite coordinates")]
    NonFinite,
    #[error(
        "the mesh is too large: its volume, centre of mass or inertia overflows double precision"
    )]
    TooLarge,
    #[error("the mesh is too small: its volume underflows double precision")]
    TooSmall,
    #[error(
        "the surface's inertia is not positive: a closed part of it is wound inside out against the rest"
    )]
    InsideOut,
}

/// Volume, centre of mass and inertia tensor (about the centre of mass, unit density) of a
/// tetrahedral mesh, integrated exactly over its tetrahedra.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MassProperties {
    pub volume: f64,
    pub center_of_mass: DVec3,
    pub unit_inertia: DMat3,
}

/// Exact mass properties of a union of tetrahedra. Each tetrahedron (a, b, c, d) relative to a
/// reference point contributes the covariance `V/20 (sum v v^T + s s^T)` with `s = a+b+c+d`
/// (the canonical-tetrahedron covariance mapped affinely, see Tonon 2004 or Blow & Binstock,
/// "How to find the inertia tensor (or other mass properties) of a 3D solid body represented by a
/// triangle mesh", 2004); the inertia tensor is `trace(C) I - C`.
///
/// `V` is each tetrahedron's absolute or signed volume, as `volumes` says.
pub fn tet_mass_properties(
    vertices: &[DVec3],
    tetrahedra: &[[u32; 4]],
    volumes: TetVolumes,
) -> MassProperties {
    let corners = |t: &[u32; 4]| t.map(|i| vertices[i as usize]);
    let signed_volume = |[a, b, c, d]: [DVec3; 4]| (b - a).dot((c - a).cross(d - a)) / 6.0;
    let volume_of = |p: [DVec3; 4]| match volumes {
        TetVolumes::Absolute => signed_volume(p).abs(),
        TetVolumes::Signed => signed_volume(p),
    };

    let mut volume = 0.0;
    let mut moment = DVec3::ZERO;
    for tet in tetrahedra {
        let p = corners(tet);
        let v = volume_of(p);
        volume += v;
        moment += v * (p[0] + p[1] + p[2] + p[3]) / 4.0;
    }
    let center_of_mass = if volume != 0.0 {
        moment / volume
    } else {
        DVec3::ZERO
    };

    // Second pass about the centre of mass: no cancellation between large moments.
    let mut covariance = DMat3::ZERO;
    for tet in tetrahedra {
        let p = corners(tet).map(|x| x - center_of_mass);
        let v = volume_of(corners(tet));
        let s = p[0] + p[1] + p[2] + p[3];
        let mut sum = outer(s, s);
        for x in p {
            sum += outer(x, x);
        }
        covariance += sum * (v / 20.0);
    }
    let trace = covariance.x_axis.x + covariance.y_axis.y + covariance.z_axis.z;
    let unit_inertia = DMat3::from_diagonal(DVec3::splat(trace)) - covariance;
    MassProperties {
        volume,
        center_of_mass,
        unit_inertia,
    }
}

pub(crate) fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// A rigid shape in body space: the centre of mass is the origin.
#[derive(Clone)]
pub struct Shape {
    /// Rest vertices relative to the centre of mass (the coursework's `origV`).
    pub rest_vertices: Vec<DVec3>,
    /// Boundary triangles, wound counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
    pub tetrahedra: Vec<[u32; 4]>,
    pub volume: f64,
    /// Inertia tensor about the centre of mass at density 1.
    pub unit_inertia: DMat3,
    /// Convex hull of the rest vertices, queried with each body's pose by the narrow phase.
    pub hull: ConvexPolyhedron,
    /// Body-space bounding box of the rest vertices (centre and half extents), from which each
    /// body's world box is bounded without touching its vertices.
    pub local_box_center: DVec3,
    pub local_box_half_extents: DVec3,
    /// Whether the hull is exactly that box (its eight corners): then two such bodies meet
    /// through the box-box separating-axis test instead of GJK on their hulls.
    pub is_box: bool,
    /// The first `named_vertices` rest vertices are the mesh file's own, those a constraint
    /// may name (see [`TetMesh::added_vertices`]).
    pub named_vertices: usize,
    /// Whether each rest vertex is a corner of the hull, one of the points parry's hull keeps:
    /// not inside it, nor (but for ties parry keeps) inside one of its faces or edges (the
    /// course's `box_tri.mesh` has a vertex inside its bottom face).
    pub on_hull: Vec<bool>,
}

impl std::fmt::Debug for Shape {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Shape")
            .field("vertices", &self.rest_vertices.len())
            .field("triangles", &self.triangles.len())
            .field("tetrahedra", &self.tetrahedra.len())
            .field("volume", &self.volume)
            .finish()
    }
}

impl Shape {
    pub fn from_tet_mesh(mesh: &TetMesh) -> Result<Shape, ShapeError> {
        if mesh.vertices.iter().any(|v| !v.is_finite()) {
            return Err(ShapeError::NonFinite);
        }
        let props = tet_mass_properties(&mesh.vertices, &mesh.tetrahedra, mesh.volumes);
        check_mass_properties(&props, (&mesh.vertices, &mesh.tetrahedra), mesh.volumes)?;
        let rest_vertices: Vec<DVec3> = mesh
            .vertices
            .iter()
            .map(|v| *v - props.center_of_mass)
            .collect();
        let mut triangles = if mesh.triangles.is_empty() {
            boundary_triangles(&mesh.vertices, &mesh.tetrahedra)
        } else {
            mesh.triangles.clone()
        };
        orient_outward(&rest_vertices, &mut triangles);
        let hull = ConvexPolyhedron::from_convex_hull(&rest_vertices).ok_or(ShapeError::NoHull)?;
        let (min, max) = rest_vertices.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), v| (lo.min(*v), hi.max(*v)),
        );
        let (center, half) = ((min + max) / 2.0, (max - min) / 2.0);
        let on_hull = corners_of(&rest_vertices, hull.points());
        Ok(Shape {
            is_box: hull_is_box(hull.points(), center, half),
            triangles,
            tetrahedra: mesh.tetrahedra.clone(),
            volume: props.volume,
            unit_inertia: props.unit_inertia,
            hull,
            local_box_center: center,
            local_box_half_extents: half,
            named_vertices: mesh.vertices.len().saturating_sub(mesh.added_vertices),
            on_hull,
            rest_vertices,
        })
    }
}

/// Refuses mass properties no body can have: overflowed, underflowed, of no volume, or (signed
/// volumes only) of an inertia that is not positive definite.
fn check_mass_properties(
    props: &MassProperties,
    (vertices, tetrahedra): (&[DVec3], &[[u32; 4]]),
    volumes: TetVolumes,
) -> Result<(), ShapeError> {
    // The solid's own size (half the longest side of its tetrahedra's box), not its distance
    // from the origin: a unit tetrahedron at x = 10,000 was refused as degenerate against
    // 1e-12 * 10,000^3. (The two are the same for a mesh centred on the origin, and the new one
    // is the smaller elsewhere, so no mesh that loaded before is refused as degenerate; one
    // under about 1e-98 across, away from the origin, may now be refused as too small.) Nor a
    // vertex no tetrahedron uses: a box with one stray vertex at 1e6 was called degenerate.
    let corners = tetrahedra
        .iter()
        .flatten()
        .filter_map(|&i| vertices.get(i as usize));
    let (low, high) = corners.fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(low, high), v| (low.min(*v), high.max(*v)),
    );
    let scale = if tetrahedra.is_empty() {
        0.0
    } else {
        (0.5 * (high - low)).max_element()
    };
    // The coordinates are finite, so a volume that is not finite overflowed on the way; so did
    // a centre of mass or inertia (the volume times a coordinate, or its square: a tetrahedron
    // of 1e80 was refused as "coplanar" after its centre of mass overflowed).
    let overflowed = !props.volume.is_finite()
        || !props.center_of_mass.is_finite()
        || !props.unit_inertia.is_finite();
    if overflowed {
        return Err(ShapeError::TooLarge);
    }
    // The degeneracy test below compares with the cube of the size, which underflows to zero
    // for sizes under about 1e-103 (and every volume with it).
    if scale > 0.0 && scale.powi(3) < 1e12 * f64::MIN_POSITIVE {
        return Err(ShapeError::TooSmall);
    }
    if props.volume <= 1e-12 * scale.powi(3) {
        return Err(ShapeError::Degenerate);
    }
    // Absolute volumes sum positive semidefinite covariances; signed ones subtract those of a
    // part wound inside out, which a surface whose parts pair their edges may have (a second
    // cube, far off and wound backwards, gave a negative moment).
    if volumes == TetVolumes::Signed && !positive_definite(props.unit_inertia) {
        return Err(ShapeError::InsideOut);
    }
    Ok(())
}

/// Sylvester's criterion for a symmetric matrix: its leading principal minors are positive.
fn positive_definite(m: DMat3) -> bool {
    let (a, b, c) = (m.x_axis.x, m.x_axis.y, m.y_axis.y);
    a > 0.0 && a * c - b * b > 0.0 && m.determinant() > 0.0
}

/// For each vertex, whether it is one of the hull's `corners` (parry's hull keeps the input
/// points it uses, bit for bit).
fn corners_of(vertices: &[DVec3], corners: &[DVec3]) -> Vec<bool> {
    let bits = |v: &DVec3| v.to_array().map(f64::to_bits);
    let corners: std::collections::HashSet<[u64; 3]> = corners.iter().map(bits).collect();
    vertices
        .iter()
        .map(|v| corners.contains(&bits(v)))
        .collect()
}

/// Whether `points` are the eight corners of the box `center +- half` (to a relative 1e-12).
fn hull_is_box(points: &[DVec3], center: DVec3, half: DVec3) -> bool {
    let tolerance = 1e-12 * (center.abs() + half).max_element();
    let mut corners_met = 0u8;
    for p in points {
        let d = *p - center;
        let signs = d.cmpgt(DVec3::ZERO).bitmask() as usize;
        let corner = DVec3::select(d.cmpgt(DVec3::ZERO), half, -half);
        if (d - corner).abs().max_element() > tolerance {
            return false;
        }
        corners_met |= 1 << signs;
    }
    points.len() == 8 && corners_met == u8::MAX && half.min_element() > 0.0
}

impl Shape {
    /// The mesh's volume over its convex hull's: 1 for a convex mesh (to rounding). Collisions
    /// see the hull and mass and inertia come from the mesh, so below 1 the two disagree.
    pub fn convexity(&self) -> f64 {
        use parry3d_f64::shape::Shape as _;
        self.volume / self.hull.mass_properties(1.0).mass()
    }

    /// The shape's size along its thinnest axis of its local box: what a depth is measured
    /// against (a body 1 % into another, or into the ground).
    pub fn least_extent(&self) -> f64 {
        2.0 * self.local_box_half_extents.min_element()
    }

    /// Largest distance of a rest vertex from the centre of mass.
    pub fn bounding_radius(&self) -> f64 {
        self.rest_vertices
            .iter()
            .map(|v| v.length())
            .fold(0.0, f64::max)
    }
}

/// Faces that belong to exactly one tetrahedron, wound so that the tetrahedron lies behind them
/// whatever its orientation.
fn boundary_triangles(vertices: &[DVec3], tetrahedra: &[[u32; 4]]) -> Vec<[u32; 3]> {
    use std::collections::HashMap;
    // For a positively oriented tet (a,b,c,d) these faces point outward.
    const FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];
    let mut count: HashMap<[u32; 3], (u32, [u32; 3])> = HashMap::new();
    let mut order = Vec::new();
    for tet in tetrahedra {
        let [a, b, c, d] = tet.map(|i| vertices[i as usize]);
        let inverted = (b - a).dot((c - a).cross(d - a)) < 0.0;
        for face in FACES {
            let mut tri = face.map(|k| tet[k]);
            if inverted {
                tri.swap(1, 2);
            }
            let mut key = tri;
            key.sort_unstable();
            let entry = count.entry(key).or_insert_with(|| {
                order.push(key);
                (0, tri)
            });
            entry.0 += 1;
        }
    }
    order
        .into_iter()
        .filter_map(|key| {
            count
                .get(&key)
                .filter(|(n, _)| *n == 1)
                .map(|(_, tri)| *tri)
        })
        .collect()
}

/// Makes the boundary face outward as a whole: if the enclosed signed volume (about the centre of
/// mass, the origin here) is negative, every triangle is flipped.
fn orient_outward(vertices: &[DVec3], triangles: &mut [[u32; 3]]) {
    let signed: f64 = triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| vertices[i as usize]);
            a.dot(b.cross(c))
        })
        .sum();
    if signed < 0.0 {
        for t in triangles.iter_mut() {
            t.swap(1, 2);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::assets;

    /// The hull's corners are the vertices it is spanned by: a box's eight, not the centre its
    /// tetrahedra fan from; a cylinder's rims, not its caps' centres (vertices inside faces).
    #[test]
    fn corners_are_the_vertices_spanning_the_hull() {
        let box_shape = Shape::from_tet_mesh(&assets::cuboid(DVec3::new(3.0, 1.5, 2.0))).unwrap();
        let flags = &box_shape.on_hull;
        assert_eq!(flags.iter().filter(|&&c| c).count(), 8);
        for (v, &corner) in box_shape.rest_vertices.iter().zip(flags) {
            let at_corner = (v.abs() - DVec3::new(3.0, 1.5, 2.0)).abs().max_element() < 1e-12;
            assert_eq!(corner, at_corner, "{v}");
        }
        let (_, cylinder) = assets::all_meshes()
            .into_iter()
            .find(|(n, _)| *n == "cylinder")
            .unwrap();
        let cylinder = Shape::from_tet_mesh(&cylinder).unwrap();
        for (v, &corner) in cylinder.rest_vertices.iter().zip(&cylinder.on_hull) {
            let on_rim = (v.x * v.x + v.z * v.z).sqrt() > 1e-6;
            assert_eq!(corner, on_rim, "{v}");
        }
        assert_eq!(
            cylinder.on_hull.iter().filter(|&&c| c).count(),
            cylinder.hull.points().len()
        );
    }

    /// A box is one; a box turned in its mesh (its body-space box is no longer its hull), a box
    /// with one corner moved, an octahedron and a tetrahedron are not.
    #[test]
    fn only_hulls_that_are_their_box_are_boxes() {
        let shape = |mesh: &TetMesh| Shape::from_tet_mesh(mesh).unwrap();
        assert!(shape(&assets::cuboid(DVec3::new(3.0, 1.5, 2.0))).is_box);
        let mut turned = assets::cuboid(DVec3::new(3.0, 1.5, 2.0));
        let turn = glam::DQuat::from_rotation_y(0.3);
        turned.vertices.iter_mut().for_each(|v| *v = turn * *v);
        assert!(!shape(&turned).is_box);
        let mut dented = assets::cuboid(DVec3::ONE);
        dented.vertices[7] *= 0.9;
        assert!(!shape(&dented).is_box);
        assert!(!shape(&assets::octahedron(DVec3::ONE)).is_box);
        assert!(!shape(&assets::tetrahedron(1.0)).is_box);
    }
}
