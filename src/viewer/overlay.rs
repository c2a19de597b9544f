//! Line and plane geometry drawn with the bodies, built on the CPU in world space: the ground
//! plane and grid (once per scene), and each frame the constraint segments coloured by violation,
//! the outline of the selected body, the grab and the contact markers.

use super::palette;
use super::pipelines::LineVertex;
use crate::World;
use glam::DVec3;
use std::ops::Range;

pub fn with_alpha(c: [f32; 3], a: f32) -> [f32; 4] {
    [c[0], c[1], c[2], a]
}

fn push_line(lines: &mut Vec<LineVertex>, a: DVec3, b: DVec3, color: [f32; 4]) {
    lines.push(LineVertex {
        position: a.as_vec3().to_array(),
        color,
    });
    lines.push(LineVertex {
        position: b.as_vec3().to_array(),
        color,
    });
}

/// Constraint indices drawn as one segment: consecutive constraints between the same two
/// vertices (a file record's lower and upper bound) share a segment, coloured by the worse one.
pub fn constraint_groups(world: &World) -> Vec<Vec<usize>> {
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for (index, c) in world.constraints.iter().enumerate() {
        let same = groups.last().map(|g| {
            let p = &world.constraints[g[0]];
            (p.body1, p.body2, p.vertex1, p.vertex2) == (c.body1, c.body2, c.vertex1, c.vertex2)
        });
        match same {
            Some(true) => groups.last_mut().expect("nonempty").push(index),
            _ => groups.push(vec![index]),
        }
    }
    groups
}

/// One segment per constraint group, green within the bounds through yellow to red.
pub fn constraint_segments(lines: &mut Vec<LineVertex>, world: &World, groups: &[Vec<usize>]) {
    for group in groups {
        let first = &world.constraints[group[0]];
        let (p1, p2) = first.points(&world.bodies);
        let violation = group
            .iter()
            .map(|&k| world.constraints[k].violation(&world.bodies))
            .fold(0.0, f64::max);
        // Red at 10% of the rest length outside the bounds.
        let t = violation / (0.1 * first.rest_length).max(1e-9);
        let color = with_alpha(palette::linear(palette::violation_srgb(t)), 1.0);
        push_line(lines, p1, p2, color);
    }
}

/// The edges of body `index`'s triangles, pulled slightly towards `eye` so they win the depth
/// test against the body's own faces.
pub fn selection_outline(lines: &mut Vec<LineVertex>, world: &World, index: usize, eye: DVec3) {
    let color = with_alpha(palette::linear([1.0, 0.85, 0.25]), 1.0);
    let vertices: Vec<DVec3> = world
        .current_vertices(index)
        .into_iter()
        .map(|p| p + (eye - p) * 0.003)
        .collect();
    let shape = &world.shapes[world.bodies[index].shape];
    for tri in &shape.triangles {
        for k in 0..3 {
            let (a, b) = (tri[k] as usize, tri[(k + 1) % 3] as usize);
            push_line(lines, vertices[a], vertices[b], color);
        }
    }
}

/// The grab: a line from the grabbed point to its target, with a small cross at the target.
pub fn grab_line(lines: &mut Vec<LineVertex>, world: &World, scene_scale: f64) {
    let Some((point, target)) = super::grab::line(world) else {
        return;
    };
    let color = with_alpha(palette::linear([0.55, 0.95, 1.0]), 1.0);
    push_line(lines, point, target, color);
    let s = 0.01 * scene_scale;
    for axis in [DVec3::X, DVec3::Y, DVec3::Z] {
        push_line(lines, target - s * axis, target + s * axis, color);
    }
}

/// A small cross at each contact point and its normal, sized by `scene_scale`.
pub fn contact_markers(lines: &mut Vec<LineVertex>, world: &World, scene_scale: f64) {
    let point_color = with_alpha(palette::linear([1.0, 0.95, 0.2]), 1.0);
    let normal_color = with_alpha(palette::linear([1.0, 0.45, 0.1]), 1.0);
    let s = 0.015 * scene_scale;
    for (p, normal) in world.display_contacts() {
        for axis in [DVec3::X, DVec3::Y, DVec3::Z] {
            push_line(lines, p - s * axis, p + s * axis, point_color);
        }
        push_line(lines, p, p + normal * (5.0 * s), normal_color);
    }
}

/// The ground at y = 0: two triangles of plane, then grid lines.
pub struct Ground {
    pub vertices: Vec<LineVertex>,
    pub plane: Range<u32>,
    pub grid: Range<u32>,
    /// Half the side of the square.
    pub extent: f64,
}

/// The ground under a scene spanning `lo`..`hi`: around the origin, past the bodies, and at least
/// as wide as the scene is tall (a tower stands on a floor, not on a tile), with about a dozen
/// grid lines each side of the axes at a round spacing.
pub fn ground(lo: DVec3, hi: DVec3) -> Ground {
    let half = [lo.x, hi.x, lo.z, hi.z]
        .iter()
        .map(|v| v.abs())
        .fold(0.5 * (hi.y - lo.y), f64::max)
        .max(1.0)
        * 1.15;
    let step = nice_step(half / 12.0);
    let n = (half / step).ceil() as i64;
    let extent = n as f64 * step;
    let ground = with_alpha(palette::linear(palette::GROUND_SRGB), 1.0);
    let grid = with_alpha(palette::linear(palette::GRID_SRGB), 1.0);
    let x_axis = with_alpha(palette::linear(palette::GRID_X_AXIS_SRGB), 1.0);
    let z_axis = with_alpha(palette::linear(palette::GRID_Z_AXIS_SRGB), 1.0);
    let v = |x: f64, z: f64, color: [f32; 4]| LineVertex {
        position: [x as f32, 0.0, z as f32],
        color,
    };
    let e = extent;
    let mut vertices = vec![
        v(-e, -e, ground),
        v(e, -e, ground),
        v(e, e, ground),
        v(-e, -e, ground),
        v(e, e, ground),
        v(-e, e, ground),
    ];
    for k in -n..=n {
        let t = k as f64 * step;
        // Lines along x (constant z) and along z (constant x); the axes themselves in colour.
        let (cx, cz) = if k == 0 {
            (x_axis, z_axis)
        } else {
            (grid, grid)
        };
        vertices.extend([v(-e, t, cx), v(e, t, cx), v(t, -e, cz), v(t, e, cz)]);
    }
    let grid = 6..vertices.len() as u32;
    Ground {
        vertices,
        plane: 0..6,
        grid,
        extent,
    }
}

/// 1, 2 or 5 times a power of ten, at least `x`.
fn nice_step(x: f64) -> f64 {
    let p = 10f64.powf(x.max(1e-9).log10().floor());
    for m in [1.0, 2.0, 5.0, 10.0] {
        if m * p >= x {
            return m * p;
        }
    }
    10.0 * p
}
