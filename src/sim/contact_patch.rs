//! Where a one-point contact acts on a whole contact patch (`--contact-patches`, an opt-in of the
//! coursework's solver): the patch's point nearest below the resting body's centre of mass, on
//! the ground or on another body, so that a body resting on a face is pushed straight up
//! through its centre of mass and stays still. The patch's centroid did that only for faces
//! centred under it: a tetrahedron resting on a face rocked and gained energy there (2.2 times
//! in 10 s at dt 0.02 and restitution 1, the course's `tetrahedron.mesh`; found by review).

use glam::{DVec2, DVec3};

/// The point on the ground patch spanned by `corners` (the hull's corners at or below the
/// ground; one at least) nearest to the centre of mass `com` seen from above: `com`'s own
/// place where the patch lies under it, else the nearest point of the patch's rim. Its height
/// is the corners' mean height. ([`point_nearest_under`] in the world's axes: x and z across,
/// y up, so each coordinate is read as it is, up to the sign of a zero.)
pub fn ground_patch_point(com: DVec3, corners: &[DVec3]) -> DVec3 {
    point_nearest_under((DVec3::X, DVec3::Z, DVec3::Y), com, corners)
}

/// The point of the patch spanned by `points` (a contact's touching points, in a plane across
/// the unit `normal`; one at least) nearest to the centre of mass `com` seen along `normal`,
/// where a body rests on another: [`ground_patch_point`] for a patch in any plane.
pub fn patch_point_under(com: DVec3, points: &[DVec3], normal: DVec3) -> DVec3 {
    let (t1, t2) = normal.any_orthonormal_pair();
    point_nearest_under((t1, t2, normal), com, points)
}

/// The point of the patch spanned by `points` (in a plane across `normal`; one at least)
/// nearest to `com` seen along `normal`, in the orthonormal frame `(t1, t2, normal)`: `com`'s
/// own place across the plane where the patch lies under it, else the nearest point of the
/// patch's rim; its height along `normal` is the points' mean.
fn point_nearest_under(
    (t1, t2, normal): (DVec3, DVec3, DVec3),
    com: DVec3,
    points: &[DVec3],
) -> DVec3 {
    let height = points.iter().map(|p| p.dot(normal)).sum::<f64>() / points.len() as f64;
    let flat: Vec<DVec2> = (points.iter())
        .map(|p| DVec2::new(p.dot(t1), p.dot(t2)))
        .collect();
    let at = nearest_in_hull(&convex_hull(flat), DVec2::new(com.dot(t1), com.dot(t2)));
    at.x * t1 + at.y * t2 + height * normal
}

/// The convex hull of `points` (one at least), counter-clockwise, collinear points dropped
/// (Andrew's monotone chain: A. M. Andrew, "Another efficient algorithm for convex hulls in two
/// dimensions", 1979). One point or two where all are one or on a line.
fn convex_hull(mut points: Vec<DVec2>) -> Vec<DVec2> {
    points.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    points.dedup();
    if points.len() < 3 {
        return points;
    }
    let turns_left = |o: DVec2, a: DVec2, b: DVec2| (a - o).perp_dot(b - o) > 0.0;
    let mut hull: Vec<DVec2> = Vec::with_capacity(2 * points.len());
    for pass in [
        &points[..],
        &points.iter().rev().copied().collect::<Vec<_>>()[..],
    ] {
        let start = hull.len();
        for &p in pass {
            while hull.len() >= start + 2
                && !turns_left(hull[hull.len() - 2], hull[hull.len() - 1], p)
            {
                hull.pop();
            }
            hull.push(p);
        }
        // Each chain's last point is the other chain's first.
        hull.pop();
    }
    hull
}

/// `p` where it lies inside the convex polygon `hull` (counter-clockwise, as
/// [`convex_hull`] gives it; a point or a segment when it has one or two corners), else the
/// nearest point of its rim.
fn nearest_in_hull(hull: &[DVec2], p: DVec2) -> DVec2 {
    let n = hull.len();
    let edges = || (0..n).map(|k| (hull[k], hull[(k + 1) % n]));
    if n >= 3 && edges().all(|(a, b)| (b - a).perp_dot(p - a) >= 0.0) {
        return p;
    }
    edges()
        .map(|(a, b)| nearest_on_segment(a, b, p))
        .min_by(|x, y| x.distance_squared(p).total_cmp(&y.distance_squared(p)))
        .unwrap_or(p)
}

fn nearest_on_segment(a: DVec2, b: DVec2, p: DVec2) -> DVec2 {
    let ab = b - a;
    let length_squared = ab.length_squared();
    if length_squared == 0.0 {
        return a;
    }
    a + ab * ((p - a).dot(ab) / length_squared).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hull_of_a_square_with_inner_and_edge_points_is_its_corners() {
        let square = [(0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0)];
        let mut points: Vec<DVec2> = square.iter().map(|&(x, y)| DVec2::new(x, y)).collect();
        points.extend([
            DVec2::new(1.0, 1.0),
            DVec2::new(1.0, 0.0),
            DVec2::new(0.5, 1.7),
        ]);
        let hull = convex_hull(points);
        assert_eq!(hull.len(), 4, "{hull:?}");
        for (x, y) in square {
            assert!(hull.contains(&DVec2::new(x, y)));
        }
        // Counter-clockwise: every corner turns left.
        for k in 0..4 {
            let (a, b, c) = (hull[k], hull[(k + 1) % 4], hull[(k + 2) % 4]);
            assert!((b - a).perp_dot(c - b) > 0.0, "{hull:?}");
        }
    }

    #[test]
    fn a_point_under_the_patch_is_kept_and_one_outside_goes_to_the_rim() {
        let triangle = convex_hull(vec![
            DVec2::new(0.0, 0.0),
            DVec2::new(3.0, 0.0),
            DVec2::new(0.0, 3.0),
        ]);
        assert_eq!(
            nearest_in_hull(&triangle, DVec2::new(0.5, 1.0)),
            DVec2::new(0.5, 1.0)
        );
        assert_eq!(
            nearest_in_hull(&triangle, DVec2::new(1.0, -2.0)),
            DVec2::new(1.0, 0.0)
        );
        assert_eq!(
            nearest_in_hull(&triangle, DVec2::new(3.0, 3.0)),
            DVec2::new(1.5, 1.5)
        );
        assert_eq!(
            nearest_in_hull(&triangle, DVec2::new(-1.0, -1.0)),
            DVec2::ZERO
        );
        // An edge (two corners, or more on one line) and a corner alone.
        let edge = convex_hull(vec![
            DVec2::ZERO,
            DVec2::new(2.0, 0.0),
            DVec2::new(1.0, 0.0),
        ]);
        assert_eq!(edge.len(), 2);
        assert_eq!(
            nearest_in_hull(&edge, DVec2::new(0.5, 4.0)),
            DVec2::new(0.5, 0.0)
        );
        assert_eq!(
            nearest_in_hull(&edge, DVec2::new(5.0, 1.0)),
            DVec2::new(2.0, 0.0)
        );
        let corner = [DVec2::new(1.0, 1.0)];
        assert_eq!(
            nearest_in_hull(&corner, DVec2::new(4.0, 4.0)),
            DVec2::new(1.0, 1.0)
        );
    }

    #[test]
    fn the_patch_point_lies_under_the_centre_of_mass_at_the_corners_mean_height() {
        let corners = [
            DVec3::new(0.0, -0.1, 0.0),
            DVec3::new(4.0, -0.1, 0.0),
            DVec3::new(0.0, -0.4, 4.0),
        ];
        let point = ground_patch_point(DVec3::new(1.0, 2.0, 1.0), &corners);
        assert!(
            (point - DVec3::new(1.0, -0.2, 1.0)).length() < 1e-15,
            "{point}"
        );
    }
}
