//! The lower triangle of `B = P A Pᵀ` as a gather from the values of `A`: the fill-reducing permutation
//! of [`crate::sparse_cholesky`] applied once per numeric factorization without rebuilding `B`'s
//! structure.
//!
//! `A` is a symmetric `n × n` matrix given by its lower triangle (compressed columns, row ≥ column),
//! `P` the permutation with `fwd[new] = old`, `inv[old] = new`. Then
//!
//! ```text
//! B[inv[i], inv[j]] = A[i, j],
//! ```
//!
//! and an entry that lands above `B`'s diagonal is stored at its mirror (`B` is symmetric and real). The
//! structure of `B` depends only on `A`'s pattern and `P`, so it is built once per symbolic analysis
//! together with `source` (`#nnz`): `B`'s `k`-th stored value is `A`'s `source[k]`-th. Each
//! factorization then costs one gather of `#nnz` values instead of faer's
//! `permute_self_adjoint_to_unsorted`, which counts the columns and places every entry again on every
//! call (4 % of the tight pants design's samples, docs/BENCHMARKS.md).
//!
//! The entries of each column of `B` are in the order faer writes them (`A`'s columns in order, each
//! column's stored entries in order), so the supernodal factorization sees the same matrix, to the bit,
//! as through faer's own permutation (tested in [`crate::sparse_cholesky`]).

use faer::sparse::{SparseColMatRef, SymbolicSparseColMat, SymbolicSparseColMatRef};

/// The pattern of `B = P A Pᵀ` (lower triangle) and the gather that fills its values from `A`'s.
#[derive(Clone, Debug)]
pub(crate) struct SymmetricPermutation {
    /// `B`'s lower triangle; the rows of a column in faer's order, not sorted.
    pattern: SymbolicSparseColMat<usize>,
    /// `B`'s `k`-th value is `A`'s value at position `source[k]` of its value array.
    source: Vec<usize>,
    values: Vec<f64>,
}

impl SymmetricPermutation {
    /// The permuted pattern of the lower triangle `a` (`n × n`) under `inv` (`inv[old] = new`, a
    /// permutation of `0..n`, checked by the caller). Entries above the diagonal of `a` are not read.
    pub(crate) fn new(a: SymbolicSparseColMatRef<'_, usize>, inv: &[usize]) -> Self {
        let n = a.ncols();
        debug_assert_eq!(inv.len(), n);
        let entries = |j: usize| {
            let range = a.col_range(j);
            let start = range.start;
            a.row_idx_of_col_raw(j)
                .iter()
                .enumerate()
                .filter(move |&(_, &i)| i >= j)
                .map(move |(offset, &i)| (start + offset, i))
        };
        // Column counts of B, then the running positions.
        let mut next = vec![0usize; n];
        for j in 0..n {
            for (_, i) in entries(j) {
                let (ni, nj) = (inv[i], inv[j]);
                next[ni.min(nj)] += 1;
            }
        }
        let mut col_ptr = Vec::with_capacity(n + 1);
        col_ptr.push(0);
        for c in next.iter_mut() {
            let start = *col_ptr.last().expect("starts with 0");
            col_ptr.push(start + *c);
            *c = start;
        }
        let nnz = col_ptr[n];
        let mut row_idx = vec![0usize; nnz];
        let mut source = vec![0usize; nnz];
        for j in 0..n {
            for (k, i) in entries(j) {
                let (ni, nj) = (inv[i], inv[j]);
                let (row, col) = (ni.max(nj), ni.min(nj));
                let slot = next[col];
                next[col] += 1;
                row_idx[slot] = row;
                source[slot] = k;
            }
        }
        Self {
            pattern: SymbolicSparseColMat::new_unsorted_checked(n, n, col_ptr, None, row_idx),
            source,
            values: vec![0.0; nnz],
        }
    }

    /// `B`'s lower triangle with the values gathered from `a_values` (`A`'s value array, in the layout of
    /// the pattern this was built from).
    pub(crate) fn apply(&mut self, a_values: &[f64]) -> SparseColMatRef<'_, usize, f64> {
        for (b, &k) in self.values.iter_mut().zip(&self.source) {
            *b = a_values[k];
        }
        SparseColMatRef::new(self.pattern.as_ref(), &self.values)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::sparse::SparseColMat;
    use faer::sparse::Triplet;

    /// `B[inv[i], inv[j]] = A[i, j]` entry by entry on a small matrix with a non-trivial permutation,
    /// mirrored entries included; a wrong mirror or source fails it.
    #[test]
    fn every_entry_lands_at_its_permuted_place() {
        let n = 5;
        let entries = [
            (0, 0, 1.0),
            (3, 0, 2.0),
            (4, 0, 3.0),
            (1, 1, 4.0),
            (2, 1, 5.0),
            (2, 2, 6.0),
            (4, 2, 7.0),
            (3, 3, 8.0),
            (4, 4, 9.0),
        ];
        let triplets: Vec<_> = entries
            .iter()
            .map(|&(r, c, v)| Triplet::new(r, c, v))
            .collect();
        let a = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &triplets).unwrap();
        let inv = [3, 0, 4, 1, 2];
        let mut p = SymmetricPermutation::new(a.symbolic(), &inv);
        let b = p.apply(a.val());
        let mut dense_b = [[0.0; 5]; 5];
        let s = b.symbolic();
        for c in 0..n {
            for (&r, &v) in s.row_idx_of_col_raw(c).iter().zip(b.val_of_col(c)) {
                assert!(r >= c, "({r}, {c}) above the diagonal");
                let row: &mut [f64; 5] = &mut dense_b[r];
                row[c] += v;
            }
        }
        for &(i, j, v) in &entries {
            let (r, c) = (inv[i].max(inv[j]), inv[i].min(inv[j]));
            assert_eq!(dense_b[r][c], v, "A[{i}, {j}]");
        }
        assert_eq!(s.col_ptr()[n], entries.len());
    }
}
