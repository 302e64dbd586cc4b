//! A lower triangle given as triplets in compressed columns, every diagonal entry present and each
//! column's rows sorted, without a comparison sort: the transpose trick of CSparse's `cs_compress` /
//! `cs_dupl` / `cs_transpose` (Davis 2006, ch. 2).
//!
//! 1. a counting sort of the triplets (after each row's diagonal zero) on their rows;
//! 2. each row's duplicates summed in place, in triplet order, with a marker per column;
//! 3. the transpose of those rows: visiting the rows in increasing order fills every column's rows in
//!    increasing order.
//!
//! Linear in the entries: two scatters (the triplets, then the summed entries) and sequential passes.
//! Duplicates are summed in triplet order, so the sums do not depend on a sort's order of equal rows
//! (timings in docs/BENCHMARKS.md, "Moved from module docs (issue 42, newton)").

use faer::sparse::Triplet;

/// A lower triangle in compressed columns (sorted rows, duplicates summed).
#[derive(Clone, Debug, PartialEq)]
pub struct CompressedLower {
    /// Start of each column in `row_idx` (`n + 1` entries).
    pub col_ptr: Vec<usize>,
    /// Row of each entry, sorted within a column.
    pub row_idx: Vec<usize>,
    /// Value of each entry (the units of the matrix).
    pub values: Vec<f64>,
}

/// `triplets` (row ≥ column, all below `n`) of an `n × n` lower triangle in compressed columns, with
/// every diagonal entry present (zero where no triplet gives one).
pub fn compressed_lower(n: usize, triplets: &[Triplet<usize, usize, f64>]) -> CompressedLower {
    // 1. By rows, each row's diagonal first.
    let mut row_start = vec![0usize; n + 1];
    for t in triplets {
        row_start[t.row + 1] += 1;
    }
    for r in 0..n {
        row_start[r + 1] += row_start[r] + 1;
    }
    let total = row_start[n];
    let mut cols = vec![0usize; total];
    let mut vals = vec![0.0f64; total];
    let mut next = row_start[..n].to_vec();
    for (r, k) in next.iter_mut().enumerate() {
        cols[*k] = r;
        *k += 1;
    }
    for t in triplets {
        let k = &mut next[t.row];
        cols[*k] = t.col;
        vals[*k] = t.val;
        *k += 1;
    }
    drop(next);
    // 2. Duplicates summed: `at[c]` is where column `c` went in the current row (stale when below the
    // row's first slot).
    let mut at = vec![usize::MAX; n];
    let mut row_end = vec![0usize; n + 1];
    let mut w = 0;
    for r in 0..n {
        let first = w;
        for k in row_start[r]..row_start[r + 1] {
            let (c, v) = (cols[k], vals[k]);
            let slot = at[c];
            if slot >= first && slot < w {
                vals[slot] += v;
            } else {
                at[c] = w;
                cols[w] = c;
                vals[w] = v;
                w += 1;
            }
        }
        row_end[r + 1] = w;
    }
    drop(at);
    // 3. Transposed into columns.
    let mut col_ptr = vec![0usize; n + 1];
    for &c in &cols[..w] {
        col_ptr[c + 1] += 1;
    }
    for c in 0..n {
        col_ptr[c + 1] += col_ptr[c];
    }
    let mut next = col_ptr[..n].to_vec();
    let mut row_idx = vec![0usize; w];
    let mut values = vec![0.0f64; w];
    for r in 0..n {
        for k in row_end[r]..row_end[r + 1] {
            let slot = &mut next[cols[k]];
            row_idx[*slot] = r;
            values[*slot] = vals[k];
            *slot += 1;
        }
    }
    CompressedLower {
        col_ptr,
        row_idx,
        values,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::newton::pattern_union;
    use faer::sparse::SparseColMat;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn compressed_columns_and_pattern_unions_match_faer() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let n = 40;
        let random_triplets = |rng: &mut ChaCha8Rng| -> Vec<Triplet<usize, usize, f64>> {
            (0..400)
                .map(|_| {
                    let (a, b) = (rng.random_range(0..n), rng.random_range(0..n));
                    Triplet::new(a.max(b), a.min(b), rng.random_range(-1.0..1.0))
                })
                .collect()
        };
        let (ta, tb) = (random_triplets(&mut rng), random_triplets(&mut rng));
        let ours = compressed_lower(n, &ta);
        let mut with_diagonal = ta.clone();
        with_diagonal.extend((0..n).map(|i| Triplet::new(i, i, 0.0)));
        let faer = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &with_diagonal).unwrap();
        assert_eq!(ours.col_ptr, faer.symbolic().col_ptr());
        assert_eq!(ours.row_idx, faer.symbolic().row_idx());
        for (a, b) in ours.values.iter().zip(faer.val()) {
            assert!((a - b).abs() <= 1e-14, "{a} vs {b}");
        }
        // The union holds both patterns and nothing else.
        let other = compressed_lower(n, &tb);
        let mut both = ta.clone();
        both.extend(tb.iter().map(|t| Triplet::new(t.row, t.col, 0.0)));
        let joint = compressed_lower(n, &both);
        let (cp, ri) = pattern_union(
            (&ours.col_ptr, &ours.row_idx),
            (&other.col_ptr, &other.row_idx),
        );
        assert_eq!((cp, ri), (joint.col_ptr, joint.row_idx));
    }
}
