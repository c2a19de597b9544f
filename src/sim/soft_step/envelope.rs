//! Symmetric positive definite matrices stored by their envelope (profile, skyline; George and
//! Liu, "Computer Solution of Large Sparse Positive Definite Systems", 1981, ch. 4): row `i`
//! keeps its entries from its first non-zero column to the diagonal, and the factors of
//! `L D L^T` fit in the same places. A chain's system in link order is tridiagonal, so storing,
//! factoring and solving take time and memory linear in its length, where a dense matrix would
//! take the square (memory) and the cube (time).

/// Fraction of its diagonal that elimination must leave of a row's pivot: below it the row
/// depends on the rows above it, or nearly (an over-braced truss), and a solve in this order
/// would magnify rounding by the inverse ([`super::pivoted_ldl`] solves such systems).
pub const WELL_CONDITIONED: f64 = 1e-6;

/// Where one row's entries lie: columns `first..=i` of row `i`, at `offset..` in the values.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Row {
    pub first: usize,
    pub offset: usize,
}

/// Lays out rows whose first columns are `firsts` (each at most its row's index) into `rows`;
/// returns the number of values.
pub fn layout(firsts: impl IntoIterator<Item = usize>, rows: &mut Vec<Row>) -> usize {
    rows.clear();
    let mut offset = 0;
    for (i, first) in firsts.into_iter().enumerate() {
        debug_assert!(first <= i);
        rows.push(Row { first, offset });
        offset += i - first + 1;
    }
    offset
}

/// Index of entry `(i, j)`, `first[i] <= j <= i`, in the values.
pub fn at(rows: &[Row], i: usize, j: usize) -> usize {
    debug_assert!(rows[i].first <= j && j <= i);
    rows[i].offset + j - rows[i].first
}

/// `(K x)_i`, summed over the row's non-zero columns in increasing order: those left of the
/// diagonal from row `i`, those right of it from the rows `reach` says may hold column `i`
/// (`reach[i]`: the last row whose envelope reaches column `i`).
pub fn row_times(rows: &[Row], values: &[f64], reach: &[usize], i: usize, x: &[f64]) -> f64 {
    let mut sum = 0.0;
    for j in rows[i].first..=i {
        sum += values[at(rows, i, j)] * x[j];
    }
    for j in (i + 1..=reach[i]).filter(|&j| rows[j].first <= i) {
        sum += values[at(rows, j, i)] * x[j];
    }
    sum
}

/// For each column, the last row whose envelope reaches it (at least the column itself).
pub fn reach(rows: &[Row], out: &mut Vec<usize>) {
    out.clear();
    out.extend(0..rows.len());
    for (i, row) in rows.iter().enumerate() {
        for last in &mut out[row.first..i] {
            *last = i;
        }
    }
}

/// The principal submatrix of the rows and columns `keep` (increasing): its layout into
/// `sub_rows`, its values into `sub_values`.
pub fn principal(
    (rows, values): (&[Row], &[f64]),
    keep: &[usize],
    (sub_rows, sub_values): (&mut Vec<Row>, &mut Vec<f64>),
) {
    // Every row kept (a hanging chain, all links taut): the matrix itself.
    if keep.len() == rows.len() {
        sub_rows.clear();
        sub_rows.extend_from_slice(rows);
        sub_values.clear();
        sub_values.extend_from_slice(values);
        return;
    }
    // Row `keep[a]` starts at the first kept row at or after its first column.
    let firsts = keep
        .iter()
        .enumerate()
        .map(|(a, &i)| keep[..a].partition_point(|&j| j < rows[i].first));
    let count = layout(firsts, sub_rows);
    sub_values.clear();
    sub_values.reserve(count);
    for (a, &i) in keep.iter().enumerate() {
        let columns = &keep[sub_rows[a].first..=a];
        sub_values.extend(columns.iter().map(|&j| values[at(rows, i, j)]));
    }
}

/// Overwrites `values` with the factors of `K = L D L^T` (Golub and Van Loan, "Matrix
/// Computations", 4.1.2) row by row: `L`'s entries left of the diagonal (its diagonal is one)
/// and `D` on the diagonal, and `inverse_diagonal` with `D`'s reciprocals; false if `K` is not
/// positive definite, or so nearly singular in this order that a pivot is under
/// [`WELL_CONDITIONED`] of its diagonal. Against Cholesky's `L L^T` a row costs one division
/// and no square root, and each row waits on the one before it (a chain's system is
/// tridiagonal).
pub fn ldl_factor(rows: &[Row], values: &mut [f64], inverse_diagonal: &mut Vec<f64>) -> bool {
    let n = rows.len();
    inverse_diagonal.clear();
    inverse_diagonal.resize(n, 0.0);
    for i in 0..n {
        let (first_i, offset_i) = (rows[i].first, rows[i].offset);
        // First `u_ij = L_ij D_j = K_ij - sum_p u_ip L_jp` over the columns both rows hold
        // (`L_jp` of the rows above is final) ...
        for j in first_i..i {
            let (first_j, offset_j) = (rows[j].first, rows[j].offset);
            let mut s = values[offset_i + j - first_i];
            for p in first_i.max(first_j)..j {
                s -= values[offset_i + p - first_i] * values[offset_j + p - first_j];
            }
            values[offset_i + j - first_i] = s;
        }
        // ... then `D_i = K_ii - sum_p u_ip L_ip` and `L_ip = u_ip / D_p`.
        let diagonal = values[offset_i + i - first_i];
        let mut d = diagonal;
        for p in first_i..i {
            let u = values[offset_i + p - first_i];
            let l = u * inverse_diagonal[p];
            d -= u * l;
            values[offset_i + p - first_i] = l;
        }
        if !(d > WELL_CONDITIONED * diagonal && d.is_finite()) {
            return false;
        }
        values[offset_i + i - first_i] = d;
        inverse_diagonal[i] = 1.0 / d;
    }
    true
}

/// Solves `K x = b` in place (`x` holds `b`) with the factors [`ldl_factor`] left: `L y = b`
/// by rows, `D z = y`, then `L^T x = z` by columns of `L^T` (rows of `L`), all within the
/// envelope.
pub fn ldl_substitute(rows: &[Row], factor: &[f64], inverse_diagonal: &[f64], x: &mut [f64]) {
    let n = rows.len();
    for i in 0..n {
        let mut s = x[i];
        for p in rows[i].first..i {
            s -= factor[at(rows, i, p)] * x[p];
        }
        x[i] = s;
    }
    for (xi, inverse) in x.iter_mut().zip(inverse_diagonal) {
        *xi *= inverse;
    }
    for i in (0..n).rev() {
        let xi = x[i];
        for p in rows[i].first..i {
            x[p] -= factor[at(rows, i, p)] * xi;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::rng::Rng;

    /// `x` with `a x = b` by Gaussian elimination with partial pivoting (an independent solve).
    fn eliminate(mut a: Vec<f64>, mut b: Vec<f64>, n: usize) -> Vec<f64> {
        for c in 0..n {
            let pivot = (c..n)
                .max_by(|&i, &j| a[i * n + c].abs().total_cmp(&a[j * n + c].abs()))
                .unwrap();
            for k in 0..n {
                a.swap(c * n + k, pivot * n + k);
            }
            b.swap(c, pivot);
            for r in c + 1..n {
                let f = a[r * n + c] / a[c * n + c];
                for k in c..n {
                    a[r * n + k] -= f * a[c * n + k];
                }
                b[r] -= f * b[c];
            }
        }
        let mut x = vec![0.0; n];
        for r in (0..n).rev() {
            let s: f64 = (r + 1..n).map(|k| a[r * n + k] * x[k]).sum();
            x[r] = (b[r] - s) / a[r * n + r];
        }
        x
    }

    /// A dense symmetric matrix's envelope: layout from each row's first non-zero.
    fn envelope_of(k: &[f64], n: usize) -> (Vec<Row>, Vec<f64>) {
        let firsts = (0..n).map(|i| (0..i).find(|&j| k[i * n + j] != 0.0).unwrap_or(i));
        let mut rows = Vec::new();
        layout(firsts, &mut rows);
        let values = (0..n)
            .flat_map(|i| (rows[i].first..=i).map(move |j| (i, j)))
            .map(|(i, j)| k[i * n + j])
            .collect();
        (rows, values)
    }

    /// Symmetric positive definite matrices with the sparsity of a chain (short and long), of a
    /// branching tree in a scrambled order (rows whose envelopes are ragged) and dense ones:
    /// the envelope factorisation solves them as elimination does; a principal submatrix and a
    /// product by rows agree with the dense matrix's.
    #[test]
    fn envelope_ldl_solves_sparse_and_dense_systems() {
        let mut rng = Rng::new(7);
        for (case, n) in [(0, 9), (1, 12), (2, 7), (1, 48), (0, 300), (2, 60)] {
            // Edges of a graph on the rows; K = D + sum over edges of a coupling (diagonally
            // dominant, hence positive definite).
            let edges: Vec<(usize, usize)> = match case {
                0 => (1..n).map(|i| (i - 1, i)).collect(),
                1 => (1..n)
                    .map(|i| ((i * 7) % n, (i * 7 + (i % 3) + 1) % n))
                    .collect(),
                _ => (0..n)
                    .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
                    .collect(),
            };
            let mut k = vec![0.0; n * n];
            for &(i, j) in edges.iter().filter(|(i, j)| i != j) {
                let v = rng.range(-1.0, 1.0);
                k[i * n + j] += v;
                k[j * n + i] += v;
            }
            for i in 0..n {
                let off: f64 = (0..n).filter(|&j| j != i).map(|j| k[i * n + j].abs()).sum();
                k[i * n + i] = off + rng.range(0.1, 2.0);
            }
            let b: Vec<f64> = (0..n).map(|_| rng.range(-5.0, 5.0)).collect();
            let (rows, values) = envelope_of(&k, n);
            let mut reaches = Vec::new();
            reach(&rows, &mut reaches);
            for i in 0..n {
                let dense: f64 = (0..n).map(|j| k[i * n + j] * b[j]).sum();
                let got = row_times(&rows, &values, &reaches, i, &b);
                assert!(
                    (got - dense).abs() < 1e-12 * (1.0 + dense.abs()),
                    "case {case}"
                );
            }
            let (mut sub_rows, mut sub) = (Vec::new(), Vec::new());
            let all: Vec<usize> = (0..n).collect();
            principal((&rows, &values), &all, (&mut sub_rows, &mut sub));
            assert_eq!((&sub_rows, &sub), (&rows, &values), "case {case}");
            let keep: Vec<usize> = (0..n).filter(|i| i % 3 != 1).collect();
            principal((&rows, &values), &keep, (&mut sub_rows, &mut sub));
            let m = keep.len();
            let dense_sub: Vec<f64> = keep
                .iter()
                .flat_map(|&i| keep.iter().map(move |&j| (i, j)))
                .map(|(i, j)| k[i * n + j])
                .collect();
            for (system, rows, mut values, size) in
                [(k.clone(), rows, values, n), (dense_sub, sub_rows, sub, m)]
            {
                let expected = eliminate(system, b[..size].to_vec(), size);
                let mut x = b[..size].to_vec();
                let mut inverse_diagonal = Vec::new();
                assert!(ldl_factor(&rows, &mut values, &mut inverse_diagonal));
                ldl_substitute(&rows, &values, &inverse_diagonal, &mut x);
                for (got, want) in x.iter().zip(&expected) {
                    assert!(
                        (got - want).abs() < 1e-10 * (1.0 + want.abs()),
                        "case {case}"
                    );
                }
            }
        }
        // Not positive definite: refused.
        let (rows, mut values) = envelope_of(&[1.0, 2.0, 2.0, 1.0], 2);
        assert!(!ldl_factor(&rows, &mut values, &mut Vec::new()));
    }
}
