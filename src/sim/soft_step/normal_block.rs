//! A manifold's normal impulses solved together rather than point after point: the linear
//! complementarity problem of its (at most four) rows, solved by trying active sets (Murty,
//! "Linear Complementarity, Linear and Nonlinear Programming", 1988, ch. 1; Box2D v2's block
//! solver does this for two points). Point after point, the result of a pass depends on which
//! point goes first: a box sliding down an incline, its two front corners equally deep to
//! 1e-7, swapped its first point with the noise of its roll, and its velocity carried a
//! three-step cycle of 3e-6 units/s around the closed form. Solved together, a pass gives
//! every point what converged Gauss-Seidel would (to [`COMPLIANCE`]), in any order.
//!
//! The problem: impulses `x >= 0` with `w = A x + q >= 0` and `x_i w_i = 0`, for `A`
//! symmetric and positive definite. Rigid rows of four points in one plane are dependent
//! (`K` has rank three), their impulses not unique, only the velocities they leave: the caller
//! gives every row at least a compliance of [`COMPLIANCE`] of its diagonal, which makes `A`
//! definite and the solution unique (for consistent rows, near the least-norm one weighted by
//! `A`'s diagonal) and moves the velocities by that fraction of an impulse's effect; soft rows
//! have their own, of a few per cent. The checks' slack on `w` is far below what a wrong
//! active set leaves there (about the compliance times an impulse's share), so the set found
//! is the one solution's whatever the order the rows come in or the impulses the points hold.

/// The least compliance of a row, relative to its diagonal.
pub const COMPLIANCE: f64 = 1e-6;

/// Slack of the check `w >= 0` on rows left out, relative to the problem's scale: rounding
/// leaves 1e-16 to 1e-14 of it; a wrong set, about [`COMPLIANCE`] times an impulse's share.
const W_SLACK: f64 = 1e-13;

/// Slack of the check `x >= 0` on the set's rows, relative to the largest impulse: the
/// compliance's conditioning (1e6) leaves 1e-10 of it.
const X_SLACK: f64 = 1e-9;

/// Solves the problem of `N` rows (at most 5: a manifold has 4); `held`: the impulses the
/// points hold now. The active sets are tried in a fixed order, those most often right first:
/// the points holding an impulse, none, all, then the rest from the largest down. A system of
/// fixed size, whose loops the compiler unrolls. None if no set passes (a value not finite,
/// or `A` not definite): the caller then solves point after point.
pub fn solve<const N: usize>(a: &[[f64; N]; N], q: &[f64; N], held: &[f64; N]) -> Option<[f64; N]> {
    const { assert!(N <= 5) };
    let all = ((1u16 << N) - 1) as u8;
    if !a.iter().flatten().chain(q).all(|v| v.is_finite()) {
        return None;
    }
    // What the checks' slack is relative to: the largest velocity and diagonal.
    let scale = q.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let diagonal = (0..N).fold(0.0f64, |m, i| m.max(a[i][i]));
    let holding = (0..N).fold(0u8, |set, i| set | (((held[i] > 0.0) as u8) << i));
    let by_size = (1..N as u32)
        .rev()
        .flat_map(move |size| (1..all).filter(move |s| s.count_ones() == size));
    // A bit per active set tried (16 for four rows).
    let mut tried = 0u32;
    for set in [holding, 0, all].into_iter().chain(by_size) {
        let first = tried & (1 << set) == 0;
        tried |= 1 << set;
        if first && let Some(x) = try_set(a, q, set, (scale, diagonal)) {
            return Some(x);
        }
    }
    None
}

/// The solution with exactly the rows of `set` active (`A_SS x_S = -q_S`, the others zero), if
/// it is one: `x >= 0` on the set and `w >= 0` off it, within rounding.
fn try_set<const N: usize>(
    a: &[[f64; N]; N],
    q: &[f64; N],
    set: u8,
    (scale, diagonal): (f64, f64),
) -> Option<[f64; N]> {
    let active = |i: usize| set & (1 << i) != 0;
    // The set's rows, the others made identity rows with zero impulse: one system of `N`.
    let m: [[f64; N]; N] = std::array::from_fn(|i| {
        std::array::from_fn(|j| match (active(i), active(j)) {
            (true, true) => a[i][j],
            _ => (i == j) as u8 as f64,
        })
    });
    let b: [f64; N] = std::array::from_fn(|i| if active(i) { -q[i] } else { 0.0 });
    let x = solve_definite(&m, &b)?;
    let largest = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let slack = W_SLACK * (scale + diagonal * largest);
    for i in 0..N {
        let fits = if active(i) {
            x[i] >= -X_SLACK * largest
        } else {
            q[i] + (0..N).map(|j| a[i][j] * x[j]).sum::<f64>() >= -slack
        };
        if !fits {
            return None;
        }
    }
    Some(x.map(|v| v.max(0.0)))
}

/// `M x = b` for `M` symmetric positive definite, by `L D L^T`; None if a pivot is not
/// positive or the result not finite. The joint groups' `L D L^T` ([`super::envelope`]) works
/// on slices and a growable inverse diagonal; this one, of fixed size on the stack, runs for
/// every manifold in every pass.
fn solve_definite<const N: usize>(m: &[[f64; N]; N], b: &[f64; N]) -> Option<[f64; N]> {
    let mut l = [[0.0; N]; N];
    let mut d = [0.0; N];
    for j in 0..N {
        let mut dj = m[j][j];
        for k in 0..j {
            dj -= l[j][k] * l[j][k] * d[k];
        }
        if dj.is_nan() || dj <= 0.0 {
            return None;
        }
        d[j] = dj;
        for i in j + 1..N {
            let mut v = m[i][j];
            for k in 0..j {
                v -= l[i][k] * l[j][k] * d[k];
            }
            l[i][j] = v / dj;
        }
    }
    let mut y = *b;
    for i in 0..N {
        for k in 0..i {
            y[i] -= l[i][k] * y[k];
        }
    }
    for i in 0..N {
        y[i] /= d[i];
    }
    for i in (0..N).rev() {
        for k in i + 1..N {
            y[i] -= l[k][i] * y[k];
        }
    }
    y.iter().all(|v| v.is_finite()).then_some(y)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::rng::Rng;
    use glam::DVec3;

    const MAX_POINTS: usize = 4;
    type Block = [[f64; MAX_POINTS]; MAX_POINTS];
    type Column = [f64; MAX_POINTS];

    /// [`solve`] on the first `n` rows of a system of four.
    fn solve_n(a: &Block, q: &Column, n: usize, held: &Column) -> Option<Column> {
        fn first<const N: usize>(a: &Block, q: &Column, held: &Column) -> Option<Column> {
            let a: [[f64; N]; N] = std::array::from_fn(|i| std::array::from_fn(|j| a[i][j]));
            let (q, held): ([f64; N], [f64; N]) = (
                std::array::from_fn(|i| q[i]),
                std::array::from_fn(|i| held[i]),
            );
            let x = solve(&a, &q, &held)?;
            Some(std::array::from_fn(|i| x.get(i).copied().unwrap_or(0.0)))
        }
        match n {
            2 => first::<2>(a, q, held),
            3 => first::<3>(a, q, held),
            _ => first::<4>(a, q, held),
        }
    }

    /// `J M^-1 J^T` of the normal rows at `points` (normal +y) on a body of unit mass and
    /// inverse inertia `inertia` (diagonal) against the ground, plus `compliance` of each
    /// diagonal: the matrix the soft step forms for a ground manifold.
    fn ground_block(points: &[DVec3], inertia: DVec3, compliance: f64) -> Block {
        let n = DVec3::Y;
        let mut a = [[0.0; MAX_POINTS]; MAX_POINTS];
        for (i, p) in points.iter().enumerate() {
            for (j, r) in points.iter().enumerate() {
                a[i][j] = 1.0 + p.cross(n).dot(inertia * r.cross(n));
            }
            a[i][i] *= 1.0 + compliance;
        }
        a
    }

    /// Projected Gauss-Seidel on the same problem, run until it no longer changes: an
    /// independent computation of the converged result.
    fn converged_gauss_seidel(a: &Block, q: &Column, n: usize) -> Column {
        let mut x = [0.0; MAX_POINTS];
        for _ in 0..200_000 {
            for i in 0..n {
                let w = q[i] + (0..n).map(|j| a[i][j] * x[j]).sum::<f64>();
                x[i] = (x[i] - w / a[i][i]).max(0.0);
            }
        }
        x
    }

    /// `w = A x + q`: the velocities the impulses `x` leave, first `n` rows.
    fn velocities(a: &Block, q: &Column, x: &Column, n: usize) -> Column {
        std::array::from_fn(|i| match i < n {
            true => q[i] + (0..n).map(|j| a[i][j] * x[j]).sum::<f64>(),
            false => 0.0,
        })
    }

    /// The four bottom corners of a 2 x 1 x 2 box, from its centre.
    fn bottom_corners() -> [DVec3; 4] {
        [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)].map(|(x, z)| DVec3::new(x, -0.5, z))
    }

    /// The impulses `x` of four rigid rows hold their load: every point still (to `tolerance`),
    /// none pulling.
    fn assert_holds(a: &Block, q: &Column, x: &Column, tolerance: f64) {
        let w = velocities(a, q, x, 4);
        let holds = (0..4).all(|i| x[i] >= 0.0 && w[i].abs() < tolerance);
        assert!(holds, "{x:?}, w {w:?}");
    }

    fn random_problem(rng: &mut Rng, n: usize, compliance: f64) -> (Block, Column) {
        let points: Vec<DVec3> = (0..n)
            .map(|_| DVec3::new(rng.range(-1.0, 1.0), -0.5, rng.range(-1.0, 1.0)))
            .collect();
        let inertia = DVec3::new(
            rng.range(0.2, 2.0),
            rng.range(0.2, 2.0),
            rng.range(0.2, 2.0),
        );
        let a = ground_block(&points, inertia, compliance);
        let q = std::array::from_fn(|i| if i < n { rng.range(-2.0, 1.0) } else { 0.0 });
        (a, q)
    }

    /// Soft rows (a compliance of 5 % of the diagonal; the preset's contacts have 3-4 %): the
    /// solution is what Gauss-Seidel converges to, and it satisfies the complementarity
    /// conditions.
    #[test]
    fn soft_rows_give_what_gauss_seidel_converges_to() {
        let mut rng = Rng::new(7);
        for case in 0..300 {
            let n = 2 + case % 3;
            let (a, q) = random_problem(&mut rng, n, 0.05);
            let x = solve_n(&a, &q, n, &[0.0; MAX_POINTS]).expect("solved");
            let expected = converged_gauss_seidel(&a, &q, n);
            for i in 0..n {
                assert!(
                    (x[i] - expected[i]).abs() < 1e-7 * (1.0 + expected[i].abs()),
                    "case {case}: {x:?} against {expected:?}"
                );
                let w = velocities(&a, &q, &x, n)[i];
                let slack = 1e-9 * (1.0 + x[i]);
                assert!(
                    x[i] >= 0.0 && w >= -slack && (x[i] * w).abs() < slack,
                    "case {case}: {x:?} w {w}"
                );
            }
        }
    }

    /// The rows' order does not change the solution: solved in reverse, every impulse is the
    /// same to rounding (point after point, the first point of a tie took the load).
    #[test]
    fn the_solution_does_not_depend_on_the_rows_order() {
        let mut rng = Rng::new(11);
        for case in 0..300 {
            let n = 2 + case % 3;
            let compliance = if case % 2 == 0 { 0.05 } else { COMPLIANCE };
            let (a, q) = random_problem(&mut rng, n, compliance);
            let rev = |i: usize| n - 1 - i;
            let mut b = [[0.0; MAX_POINTS]; MAX_POINTS];
            let mut p = [0.0; MAX_POINTS];
            for i in 0..n {
                p[i] = q[rev(i)];
                for j in 0..n {
                    b[i][j] = a[rev(i)][rev(j)];
                }
            }
            let x = solve_n(&a, &q, n, &[0.0; MAX_POINTS]).expect("solved");
            let y = solve_n(&b, &p, n, &[0.0; MAX_POINTS]).expect("solved");
            let largest = x.iter().fold(1.0f64, |m, v| m.max(v.abs()));
            for i in 0..n {
                assert!(
                    (x[i] - y[rev(i)]).abs() < 1e-6 * largest,
                    "case {case}: {x:?} {y:?}"
                );
            }
        }
    }

    /// Rigid rows of a box's four bottom corners (dependent: rank three) with the load of a
    /// resting box off centre: the impulses hold it (no point approaches), none pulls, and
    /// they carry the load's force and moment as converged Gauss-Seidel's do.
    #[test]
    fn dependent_rigid_rows_hold_an_off_centre_load() {
        let corners = bottom_corners();
        let a = ground_block(&corners, DVec3::new(0.6, 0.3, 0.8), COMPLIANCE);
        // The velocities of a body sinking at 1 unit/s and turning about x and z.
        let q = corners.map(|r| -1.0 + DVec3::new(0.3, 0.0, -0.2).cross(r).y);
        let x = solve_n(&a, &q, 4, &[0.0; MAX_POINTS]).expect("solved");
        let expected = converged_gauss_seidel(&a, &q, 4);
        let moment = |x: &Column| -> (f64, DVec3) {
            let force: f64 = x.iter().sum();
            let torque = (0..4).map(|i| corners[i].cross(DVec3::Y) * x[i]).sum();
            (force, torque)
        };
        let ((f, t), (g, u)) = (moment(&x), moment(&expected));
        assert!(
            (f - g).abs() < 1e-6 * g && (t - u).length() < 1e-6 * g,
            "{x:?} {expected:?}"
        );
        assert_holds(&a, &q, &x, 1e-6);
    }

    /// Rigid rows of four corners (dependent) under a load they can hold in many ways: the
    /// impulses found are the same whatever the rows' order and whatever impulses the points
    /// held before (tried first). With a slack on `w` as large as the compliance, a wrong set
    /// passed: (1.1, 0.1, 0.1, 0) in one order, (1.0, 0.2, 0, 0.1) in the other, and others
    /// again after other held impulses.
    #[test]
    fn dependent_rigid_rows_give_one_answer_in_any_order_and_from_any_start() {
        let corners = bottom_corners();
        let inertia = DVec3::new(0.6, 0.3, 0.8);
        let (k, a) = (
            ground_block(&corners, inertia, 0.0),
            ground_block(&corners, inertia, COMPLIANCE),
        );
        let load = [1.0, 0.2, 0.0, 0.1];
        let q: Column = std::array::from_fn(|i| -(0..4).map(|j| k[i][j] * load[j]).sum::<f64>());
        let starts = [[0.0; 4], [0.4, 0.9, 0.0, 0.2], [0.6, 0.5, 0.3, 0.0]];
        let reference = solve_n(&a, &q, 4, &starts[0]).expect("solved");
        for held in starts {
            let x = solve_n(&a, &q, 4, &held).expect("solved");
            let rev = |i: usize| 3 - i;
            let b: Block = std::array::from_fn(|i| std::array::from_fn(|j| a[rev(i)][rev(j)]));
            let p: Column = std::array::from_fn(|i| q[rev(i)]);
            let h: Column = std::array::from_fn(|i| held[rev(i)]);
            let y = solve_n(&b, &p, 4, &h).expect("solved");
            for i in 0..4 {
                assert!(
                    (x[i] - reference[i]).abs() < 1e-6,
                    "{x:?} {reference:?} held {held:?}"
                );
                assert!(
                    (y[rev(i)] - reference[i]).abs() < 1e-6,
                    "{y:?} reversed, held {held:?}"
                );
            }
        }
        assert_holds(&a, &q, &reference, 1e-5);
    }

    #[test]
    fn values_not_finite_are_refused() {
        let a = ground_block(&[DVec3::X, DVec3::Z], DVec3::ONE, 0.05);
        assert!(solve_n(&a, &[f64::NAN, -1.0, 0.0, 0.0], 2, &[0.0; MAX_POINTS]).is_none());
        let mut bad = a;
        (bad[0][1], bad[1][0]) = (f64::INFINITY, f64::INFINITY);
        assert!(solve_n(&bad, &[-1.0, -1.0, 0.0, 0.0], 2, &[0.0; MAX_POINTS]).is_none());
    }
}
