//! Ray casting against the bodies' current surface triangles (f64, on the CPU).

use crate::World;
use glam::DVec3;

/// Distance along the ray to the box, if the ray meets it.
fn ray_box(origin: DVec3, dir: DVec3, min: DVec3, max: DVec3) -> Option<f64> {
    let inv = dir.recip();
    let t1 = (min - origin) * inv;
    let t2 = (max - origin) * inv;
    let near = t1.min(t2).max_element();
    let far = t1.max(t2).min_element();
    (far >= near.max(0.0)).then_some(near.max(0.0))
}

/// Möller–Trumbore; distance along the ray, either side of the triangle.
fn ray_triangle(origin: DVec3, dir: DVec3, a: DVec3, b: DVec3, c: DVec3) -> Option<f64> {
    let e1 = b - a;
    let e2 = c - a;
    let p = dir.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-14 * e1.length_squared().max(e2.length_squared()) {
        return None;
    }
    let s = origin - a;
    let u = s.dot(p) / det;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = dir.dot(q) / det;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(q) / det;
    (t > 0.0).then_some(t)
}

/// The body the ray hits first, and the distance to the hit; fixed bodies only with
/// `include_fixed` (the view hides them on demand, and a hidden wall must not take the click).
pub fn pick(
    world: &World,
    (origin, dir): (DVec3, DVec3),
    include_fixed: bool,
) -> Option<(usize, f64)> {
    let aabbs = world.body_aabbs();
    let mut best: Option<(usize, f64)> = None;
    for (index, body) in world.bodies.iter().enumerate() {
        if body.fixed && !include_fixed {
            continue;
        }
        let Some(enter) = ray_box(origin, dir, aabbs[index].min, aabbs[index].max) else {
            continue;
        };
        if best.is_some_and(|(_, t)| enter > t) {
            continue;
        }
        let shape = &world.shapes[body.shape];
        let vertices: Vec<DVec3> = shape
            .rest_vertices
            .iter()
            .map(|&v| body.world_point(v))
            .collect();
        for tri in &shape.triangles {
            let [a, b, c] = tri.map(|i| vertices[i as usize]);
            if let Some(t) = ray_triangle(origin, dir, a, b, c)
                && best.is_none_or(|(_, bt)| t < bt)
            {
                best = Some((index, t));
            }
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triangle_hit_and_miss() {
        let (a, b, c) = (
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        );
        let t = ray_triangle(DVec3::new(0.2, 0.2, 5.0), DVec3::NEG_Z, a, b, c).unwrap();
        assert!((t - 5.0).abs() < 1e-12);
        assert!(ray_triangle(DVec3::new(0.8, 0.8, 5.0), DVec3::NEG_Z, a, b, c).is_none());
        assert!(
            ray_box(
                DVec3::new(0.0, 0.0, 5.0),
                DVec3::NEG_Z,
                DVec3::splat(-1.0),
                DVec3::splat(1.0)
            )
            .is_some()
        );
        assert!(
            ray_box(
                DVec3::new(3.0, 0.0, 5.0),
                DVec3::NEG_Z,
                DVec3::splat(-1.0),
                DVec3::splat(1.0)
            )
            .is_none()
        );
    }

    #[test]
    fn picks_the_nearest_body() {
        let world = crate::scene::load(
            "mixed",
            &crate::ConstraintsChoice::Auto,
            crate::Settings::default(),
        )
        .unwrap();
        for (index, body) in world.bodies.iter().enumerate() {
            // From far above straight down onto each body's centre: the body itself or one above it.
            let origin = body.position + DVec3::new(0.0, 1000.0, 0.0);
            let (hit, _) = pick(&world, (origin, DVec3::NEG_Y), true).expect("a hit");
            assert!(hit == index || world.bodies[hit].position.y > body.position.y);
        }
    }

    /// A ray from outside a pile's bin hits a wall; with fixed bodies left out, a body inside.
    #[test]
    fn hidden_fixed_bodies_are_not_picked() {
        let world = crate::scene::generate::pile(60, crate::Settings::default());
        let inside = (world.bodies.iter().position(|b| !b.fixed)).expect("a body");
        let target = world.bodies[inside].position;
        let origin = target + DVec3::new(1000.0, 0.0, 0.0);
        let ray = (origin, DVec3::NEG_X);
        let (wall, _) = pick(&world, ray, true).expect("a hit");
        assert!(world.bodies[wall].fixed);
        let (hit, _) = pick(&world, ray, false).expect("a hit");
        assert!(!world.bodies[hit].fixed);
    }
}
