//! Generated scenes parameterised by size, for the scale benchmark and the stress tests.

use crate::scene::assets;
use crate::sim::body::RigidBody;
use crate::sim::constraint::DistanceConstraint;
use crate::sim::settings::Settings;
use crate::sim::shape::Shape;
use crate::sim::world::World;
use glam::{DQuat, DVec3};

pub use crate::sim::rng::Rng;

fn shape_of(mesh: &crate::io::TetMesh) -> Shape {
    Shape::from_tet_mesh(mesh).expect("generated meshes are valid")
}

/// `sparse-N`: boxes and tetrahedra alternating, density 100, small tilts, in a square grid of
/// columns over x, z in [-200, 200] on 4 layers at y = 10, 73, 137, 200. No constraints. The
/// square stays the same as N grows, so the scene grows denser (the coursework comparison).
pub fn sparse(n: usize, settings: Settings) -> World {
    let shapes = vec![
        shape_of(&assets::cuboid(DVec3::new(6.0, 3.0, 4.0))),
        shape_of(&assets::tetrahedron(6.0)),
    ];
    let side = layer_side(n);
    let spacing = if side > 1 {
        400.0 / (side - 1) as f64
    } else {
        0.0
    };
    let names = vec!["box".into(), "tetrahedron".into()];
    let grid = (-200.0, spacing);
    layered(n, (shapes, names), grid, 0x5EED_0001, settings)
}

/// The spacing of `sparse-1000`'s columns (400 / 15), kept by `scatter-N` at every N.
pub const SCATTER_SPACING: f64 = 400.0 / 15.0;

/// `scatter-N`: boxes, tetrahedra and octahedra in turn, laid out as `sparse-N` is but always
/// [`SCATTER_SPACING`] apart, the square growing with N: the same density of bodies at every
/// size, so the cost per body should stay flat.
pub fn scatter(n: usize, settings: Settings) -> World {
    let shapes = vec![
        shape_of(&assets::cuboid(DVec3::new(6.0, 3.0, 4.0))),
        shape_of(&assets::tetrahedron(6.0)),
        shape_of(&assets::octahedron(DVec3::splat(5.0))),
    ];
    let names = vec!["box".into(), "tetrahedron".into(), "octahedron".into()];
    let grid = (
        -0.5 * SCATTER_SPACING * (layer_side(n) - 1) as f64,
        SCATTER_SPACING,
    );
    layered(n, (shapes, names), grid, 0x5EED_0004, settings)
}

/// Columns per side of a layer when `n` bodies fill 4 square layers.
fn layer_side(n: usize) -> usize {
    let per_layer = n.div_ceil(4).max(1);
    (per_layer as f64).sqrt().ceil().max(1.0) as usize
}

/// `n` bodies, density 100, small random tilts, the shapes in turn, in square layers of columns
/// at x, z = `origin + spacing * k` on 4 layers at y = 10, 73, 137, 200.
fn layered(
    n: usize,
    (shapes, names): (Vec<Shape>, Vec<String>),
    (origin, spacing): (f64, f64),
    seed: u64,
    settings: Settings,
) -> World {
    let layers = [10.0, 73.0, 137.0, 200.0];
    let per_layer = n.div_ceil(layers.len()).max(1);
    let side = layer_side(n);
    let mut rng = Rng::new(seed);
    let mut bodies = Vec::with_capacity(n);
    for &y in &layers {
        for cell in 0..per_layer.min(side * side) {
            if bodies.len() == n {
                break;
            }
            let (i, k) = (cell / side, cell % side);
            let shape = bodies.len() % shapes.len();
            let position = DVec3::new(origin + spacing * i as f64, y, origin + spacing * k as f64);
            bodies.push(RigidBody::on_shape(
                &shapes[shape],
                shape,
                100.0,
                false,
                position,
                rng.tilt(0.3),
            ));
        }
    }
    World::new(shapes, names, bodies, Vec::new(), settings)
}

/// `pile-N`: N mixed bodies dropped close together into a square bin of four fixed walls, so
/// contacts dominate.
pub fn pile(n: usize, settings: Settings) -> World {
    let meshes = [
        assets::cuboid(DVec3::new(3.0, 1.5, 2.0)),
        assets::tetrahedron(3.0),
        assets::octahedron(DVec3::splat(2.5)),
    ];
    let mut shapes: Vec<Shape> = meshes.iter().map(shape_of).collect();
    let per_side = ((n as f64 / 8.0).sqrt().ceil() as usize).max(2);
    // The shapes go in turn along a row (k % 3), so a side that is a multiple of three would put
    // each shape beside itself across rows, and two boxes tilted towards each other start inside
    // each other (pile-1000 had 152 such pairs): one more column keeps neighbours different.
    let per_side = per_side + usize::from(per_side.is_multiple_of(3));
    let pitch = 6.5;
    let half = pitch * per_side as f64 / 2.0 + 2.0;
    let wall_height = 40.0;
    shapes.push(shape_of(&assets::cuboid(DVec3::new(
        half + 2.0,
        wall_height / 2.0,
        1.0,
    ))));
    let wall = shapes.len() - 1;
    let mut bodies = Vec::with_capacity(n + 4);
    for (position, angle) in [
        (DVec3::new(0.0, wall_height / 2.0, half + 1.0), 0.0),
        (DVec3::new(0.0, wall_height / 2.0, -half - 1.0), 0.0),
        (
            DVec3::new(half + 1.0, wall_height / 2.0, 0.0),
            std::f64::consts::FRAC_PI_2,
        ),
        (
            DVec3::new(-half - 1.0, wall_height / 2.0, 0.0),
            std::f64::consts::FRAC_PI_2,
        ),
    ] {
        bodies.push(RigidBody::on_shape(
            &shapes[wall],
            wall,
            1000.0,
            true,
            position,
            DQuat::from_rotation_y(angle),
        ));
    }
    let mut rng = Rng::new(0x5EED_0002);
    let mut k = 0;
    'fill: for layer in 0.. {
        for i in 0..per_side {
            for j in 0..per_side {
                if k == n {
                    break 'fill;
                }
                let x = -half + 2.0 + pitch * (i as f64 + 0.5) + rng.range(-0.3, 0.3);
                let z = -half + 2.0 + pitch * (j as f64 + 0.5) + rng.range(-0.3, 0.3);
                let y = 5.0 + 6.5 * layer as f64;
                bodies.push(RigidBody::on_shape(
                    &shapes[k % 3],
                    k % 3,
                    100.0,
                    false,
                    DVec3::new(x, y, z),
                    rng.tilt(0.5),
                ));
                k += 1;
            }
        }
    }
    let names = vec![
        "box".into(),
        "tetrahedron".into(),
        "octahedron".into(),
        "wall".into(),
    ];
    World::new(shapes, names, bodies, Vec::new(), settings)
}

/// Boxes in each chain of `chain-N`.
pub const CHAIN_LINKS: usize = 10;

/// `chain-N`: N/10 chains of 10 boxes, each hanging from a fixed first box, links of bounds
/// 0.9..1.1 between a bottom corner and the next box's top corner (as the coursework's chains).
/// One chain at least (loading refuses an N that is not a multiple of ten).
pub fn chain(n: usize, settings: Settings) -> World {
    let shapes = vec![shape_of(&assets::cuboid(DVec3::new(2.0, 1.0, 1.5)))];
    let chains = (n / CHAIN_LINKS).max(1);
    let side = (chains as f64).sqrt().ceil() as usize;
    let mut bodies = Vec::with_capacity(chains * CHAIN_LINKS);
    let mut constraints = Vec::new();
    let mut rng = Rng::new(0x5EED_0003);
    for c in 0..chains {
        let (x, z) = (12.0 * (c % side) as f64, 12.0 * (c / side) as f64);
        // The chain starts tilted so that it swings; at most 0.4 per link, so that the lowest
        // link (9 links down, 4 wide) stays clear of its neighbour's 12 away whichever way both
        // lean (at most 1 per link, chain-1000 started with 27 links inside their neighbours).
        let lean = rng.range(-0.4, 0.4);
        for k in 0..CHAIN_LINKS {
            let position = DVec3::new(x + lean * k as f64, 80.0 - 4.0 * k as f64, z);
            bodies.push(RigidBody::on_shape(
                &shapes[0],
                0,
                500.0,
                k == 0,
                position,
                DQuat::IDENTITY,
            ));
            if k > 0 {
                // Bottom corner (vertex 0) of the upper box to the top corner (vertex 2) below.
                let (i, j) = (bodies.len() - 2, bodies.len() - 1);
                constraints.extend(DistanceConstraint::lower_and_upper(
                    &bodies,
                    &shapes,
                    (i, 0),
                    (j, 2),
                    0.9,
                    1.1,
                ));
            }
        }
    }
    World::new(shapes, vec!["box".into()], bodies, constraints, settings)
}

/// `rope-N`: one rope of N octahedra (half-size 1) laid out horizontally with gaps of 0.5, the
/// first fixed, each tip tied to the next one's tail with a rope's bounds (0.5 to 1 of the
/// gap), high enough to swing down without reaching the ground.
pub fn rope(n: usize, settings: Settings) -> World {
    let shape = shape_of(&assets::octahedron(DVec3::splat(1.0)));
    let extreme = |sign: f64| {
        let x = |k: usize| sign * shape.rest_vertices[k].x;
        (0..shape.rest_vertices.len())
            .max_by(|&a, &b| x(a).total_cmp(&x(b)))
            .unwrap_or(0)
    };
    let (tip, tail) = (extreme(1.0), extreme(-1.0));
    let pitch = 2.0 * shape.local_box_half_extents.x + 0.5;
    let height = pitch * n as f64 + 10.0;
    let bodies: Vec<RigidBody> = (0..n.max(1))
        .map(|k| {
            let position = DVec3::new(pitch * k as f64, height, 0.0);
            RigidBody::on_shape(&shape, 0, 100.0, k == 0, position, DQuat::IDENTITY)
        })
        .collect();
    let shapes = vec![shape];
    let constraints = (1..bodies.len())
        .flat_map(|k| {
            DistanceConstraint::lower_and_upper(&bodies, &shapes, (k - 1, tip), (k, tail), 0.5, 1.0)
        })
        .collect();
    World::new(
        shapes,
        vec!["octahedron".into()],
        bodies,
        constraints,
        settings,
    )
}

/// `stack-N`: N boxes of 2 x 1 x 1.5 (density 100) stacked from the ground up, each resting on
/// the one below: a tower that starts at rest (the soak's, and the tests' stacks).
pub fn stack(n: usize, settings: Settings) -> World {
    let shape = shape_of(&assets::cuboid(DVec3::new(1.0, 0.5, 0.75)));
    let bodies = (0..n)
        .map(|k| {
            let position = DVec3::new(0.0, 0.5 + k as f64, 0.0);
            RigidBody::on_shape(&shape, 0, 100.0, false, position, DQuat::IDENTITY)
        })
        .collect();
    World::new(
        vec![shape],
        vec!["box".into()],
        bodies,
        Vec::new(),
        settings,
    )
}

/// The generated families, as `tumble scenes` lists them.
pub const FAMILIES: [(&str, &str); 6] = [
    (
        "sparse-N",
        "N bodies in the same 400 x 400 square (the coursework's comparison)",
    ),
    (
        "scatter-N",
        "N bodies at sparse-1000's spacing, the area growing with N",
    ),
    (
        "pile-N",
        "N bodies dropped into a bin of four fixed walls (N + 4 bodies in all)",
    ),
    ("chain-N", "N/10 chains of ten links (N a multiple of 10)"),
    (
        "rope-N",
        "one rope of N links swinging down from the horizontal",
    ),
    (
        "stack-N",
        "N boxes built resting on each other (only --accurate holds it)",
    ),
];

/// Generated scene by name: `sparse`, `scatter`, `pile`, `chain`, `rope` or `stack`.
pub fn by_name(name: &str, n: usize, settings: Settings) -> Option<World> {
    match name {
        "stack" => Some(stack(n, settings)),
        "sparse" => Some(sparse(n, settings)),
        "scatter" => Some(scatter(n, settings)),
        "pile" => Some(pile(n, settings)),
        "chain" => Some(chain(n, settings)),
        "rope" => Some(rope(n, settings)),
        _ => None,
    }
}

/// A random scene of `n` bodies from tumble's meshes for stress tests: densities spanning 1:1000,
/// speeds up to `max_speed`, random orientations and spins, spread over a volume above the
/// ground so that many collide. Deterministic for a seed.
pub fn random(seed: u64, n: usize, max_speed: f64, settings: Settings) -> World {
    let shapes: Vec<Shape> = assets::all_meshes()
        .iter()
        .map(|(_, m)| shape_of(m))
        .collect();
    let names = assets::all_meshes()
        .iter()
        .map(|(name, _)| name.to_string())
        .collect();
    let mut rng = Rng::new(seed);
    let extent = 8.0 * (n as f64).cbrt() * 3.0;
    let bodies = (0..n)
        .map(|k| {
            let shape = (rng.next_u64() % shapes.len() as u64) as usize;
            let density = 10f64.powf(rng.range(0.0, 3.0));
            let position = DVec3::new(
                rng.range(-extent, extent),
                rng.range(12.0, 12.0 + 2.0 * extent),
                rng.range(-extent, extent),
            );
            let mut b = RigidBody::on_shape(
                &shapes[shape],
                shape,
                density,
                k % 17 == 16,
                position,
                rng.tilt(std::f64::consts::PI),
            );
            if !b.fixed {
                let dir = DVec3::new(
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                );
                b.linear_velocity = dir.normalize_or_zero() * rng.range(0.0, max_speed);
                b.angular_velocity = DVec3::new(
                    rng.range(-3.0, 3.0),
                    rng.range(-3.0, 3.0),
                    rng.range(-3.0, 3.0),
                );
            }
            b
        })
        .collect();
    World::new(shapes, names, bodies, Vec::new(), settings)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ConstraintsChoice;

    /// Every family `tumble scenes` lists loads by its name, and a stack is built resting: each
    /// box's bottom on the top of the one below, the first on the ground.
    #[test]
    fn every_listed_family_loads_and_a_stack_starts_at_rest() {
        for (family, _) in FAMILIES {
            let name = family.replace('N', "40");
            let world = crate::scene::load(&name, &ConstraintsChoice::Auto, Settings::default());
            assert!(world.is_ok_and(|w| !w.bodies.is_empty()), "{name}");
        }
        let world = stack(4, Settings::default());
        let half_height = world.shapes[0].local_box_half_extents.y;
        for (k, b) in world.bodies.iter().enumerate() {
            let bottom = b.position.y - half_height;
            assert!(
                (bottom - 2.0 * half_height * k as f64).abs() < 1e-12,
                "box {k}"
            );
        }
    }
}
