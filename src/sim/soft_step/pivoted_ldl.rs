//! Symmetric positive semi-definite systems with dependent rows, solved by `L D L^T` with
//! complete (diagonal) pivoting, dense (Higham, "Accuracy and Stability of Numerical
//! Algorithms", 2nd ed., 2002, 10.3). Each step eliminates the row with the largest diagonal
//! left, so the rows kept are the best conditioned the system has, and it stops when what is
//! left of every diagonal is rounding: those rows depend on the ones kept and get no share of
//! the solution. A truss braced more than it needs is such a system: the coursework's cube
//! scene joins the same point of eight bodies by 28 rods, of which 18 fix it. The envelope's
//! factorisation in row order ([`super::envelope`]) keeps the rows' order for a chain's
//! sparsity; on the cube it met pivots of 1e-16 of their diagonal, and as the truss turned,
//! rows nearly dependent in that order (1e-9) whose impulses tore it apart. Rows that depend
//! on each other with a range each can make the active sets cycle; see
//! [`super::joint_block`].

use super::envelope::{self, Row};

/// Rows at most solved this way (a dense matrix of 2 MiB).
pub const MAX_ROWS: usize = 512;
/// What is left of a row's diagonal, relative to it, under which the row counts as dependent.
/// Rounding leaves 1e-16 to 1e-14 of it on the cube, whose rows kept leave 1e-2 and more; a
/// truss nearly flat leaves anything between, and a row held on 1e-9 of its diagonal takes
/// an impulse 1e9 times its error (dropped only under 1e-10, such a truss of nine bodies
/// landing at dt 0.02 gained 290 times its energy; under 1e-6, 0.2 %: a probe).
const DEPENDENT: f64 = 1e-6;

/// The dense matrix (scaled to a unit diagonal), the row order and the buffers of one solve.
#[derive(Debug, Clone, Default)]
pub struct PivotedLdl {
    a: Vec<f64>,
    /// `1 / sqrt(K_ii)` per row: the scaling that gives a unit diagonal.
    scale: Vec<f64>,
    /// The row eliminated `k`-th.
    order: Vec<usize>,
    y: Vec<f64>,
}

impl PivotedLdl {
    /// Solves `K x = b` for `K` given by its envelope (`x` holds `b`), the rows found dependent
    /// given no share (`x_i = 0`); returns how many rows were kept, or None if `K` is not
    /// positive semi-definite (a diagonal not positive, or a value not finite).
    pub fn solve(&mut self, rows: &[Row], values: &[f64], x: &mut [f64]) -> Option<usize> {
        let n = rows.len();
        self.load(rows, values)?;
        let rank = self.factor(n)?;
        let (a, y) = (&self.a, &mut self.y);
        y.clear();
        y.extend(self.order.iter().map(|&i| x[i] * self.scale[i]));
        // `L y = b`, `D z = y`, `L^T x = z` over the kept rows; the dependent rows' unknowns
        // are zero.
        for i in 0..rank {
            let s: f64 = (0..i).map(|p| a[i * n + p] * y[p]).sum();
            y[i] -= s;
        }
        for i in 0..rank {
            y[i] /= a[i * n + i];
        }
        for i in (0..rank).rev() {
            let s: f64 = (i + 1..rank).map(|k| a[k * n + i] * y[k]).sum();
            y[i] -= s;
        }
        x.iter_mut().for_each(|v| *v = 0.0);
        for (k, &i) in self.order[..rank].iter().enumerate() {
            x[i] = y[k] * self.scale[i];
        }
        Some(rank)
    }

    /// `K` dense and scaled to a unit diagonal; None if a diagonal is not positive.
    fn load(&mut self, rows: &[Row], values: &[f64]) -> Option<()> {
        let n = rows.len();
        self.scale.clear();
        for i in 0..n {
            let d = values[envelope::at(rows, i, i)];
            if !(d > 0.0 && d.is_finite()) {
                return None;
            }
            self.scale.push(1.0 / d.sqrt());
        }
        self.a.clear();
        self.a.resize(n * n, 0.0);
        for (i, row) in rows.iter().enumerate() {
            for j in row.first..=i {
                let v = values[envelope::at(rows, i, j)] * self.scale[i] * self.scale[j];
                (self.a[i * n + j], self.a[j * n + i]) = (v, v);
            }
        }
        self.order.clear();
        self.order.extend(0..n);
        Some(())
    }

    /// Factors the loaded matrix in place (`L` below the diagonal, `D` on it, rows and columns
    /// swapped into the order eliminated): the number of rows kept, None if a pivot is not
    /// finite.
    fn factor(&mut self, n: usize) -> Option<usize> {
        let a = &mut self.a;
        for k in 0..n {
            let p = (k..n).max_by(|&i, &j| a[i * n + i].total_cmp(&a[j * n + j]))?;
            let d = a[p * n + p];
            if !d.is_finite() {
                return None;
            }
            if d <= DEPENDENT {
                return Some(k);
            }
            if p != k {
                self.order.swap(k, p);
                for c in 0..n {
                    a.swap(k * n + c, p * n + c);
                }
                for r in 0..n {
                    a.swap(r * n + k, r * n + p);
                }
            }
            // The trailing block less the outer product of row k (both triangles, so the next
            // swaps move whole rows), then column k divided into `L`.
            for i in k + 1..n {
                let f = a[i * n + k] / d;
                if f != 0.0 {
                    for j in k + 1..n {
                        a[i * n + j] -= f * a[k * n + j];
                    }
                }
            }
            for i in k + 1..n {
                a[i * n + k] /= d;
            }
        }
        Some(n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::rng::Rng;

    /// `K = J J^T` of `m` random rows over `n < m` unknowns: `n` independent rows and `m - n`
    /// that depend on them, as in an over-braced truss. For a right-hand side `K l` (one
    /// the rows agree on), the solve keeps `n` rows and its `x` gives `K x = b` to rounding;
    /// full rank (`m <= n`) it agrees with the envelope's factorisation.
    #[test]
    fn dependent_rows_get_no_share_and_the_others_solve_the_system() {
        let mut rng = Rng::new(3);
        for (m, n) in [(28, 18), (12, 12), (40, 7), (5, 9)] {
            let j: Vec<f64> = (0..m * n).map(|_| rng.range(-1.0, 1.0)).collect();
            let k = |r: usize, c: usize| (0..n).map(|p| j[r * n + p] * j[c * n + p]).sum::<f64>();
            let mut rows = Vec::new();
            envelope::layout((0..m).map(|_| 0), &mut rows);
            let values: Vec<f64> = (0..m)
                .flat_map(|r| (0..=r).map(move |c| (r, c)))
                .map(|(r, c)| k(r, c))
                .collect();
            let l: Vec<f64> = (0..m).map(|_| rng.range(-2.0, 2.0)).collect();
            let b: Vec<f64> = (0..m)
                .map(|r| (0..m).map(|c| k(r, c) * l[c]).sum())
                .collect();
            let mut x = b.clone();
            let rank = PivotedLdl::default().solve(&rows, &values, &mut x).unwrap();
            assert_eq!(rank, m.min(n), "{m} rows over {n}");
            for (r, want) in b.iter().enumerate() {
                let got: f64 = (0..m).map(|c| k(r, c) * x[c]).sum();
                assert!(
                    (got - want).abs() < 1e-9 * (1.0 + want.abs()),
                    "{m} over {n}: row {r}: {got} vs {want}"
                );
            }
            assert_eq!(x.iter().filter(|&&v| v == 0.0).count(), m - rank);
            if m <= n {
                let (mut factored, mut inverse, mut direct) =
                    (values.clone(), Vec::new(), b.clone());
                assert!(envelope::ldl_factor(&rows, &mut factored, &mut inverse));
                envelope::ldl_substitute(&rows, &factored, &inverse, &mut direct);
                for (a, b) in x.iter().zip(&direct) {
                    assert!((a - b).abs() < 1e-9 * (1.0 + b.abs()));
                }
            }
        }
        // A diagonal that is not positive: refused.
        let mut rows = Vec::new();
        envelope::layout([0, 0], &mut rows);
        assert!(
            PivotedLdl::default()
                .solve(&rows, &[1.0, 2.0, -1.0], &mut [1.0, 1.0])
                .is_none()
        );
    }
}
