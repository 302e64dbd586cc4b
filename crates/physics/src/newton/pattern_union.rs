//! The union of two sparsity patterns in compressed columns: a merge of each column's sorted rows.

/// The union of the lower-triangle patterns `a` and `b` (compressed columns `(col_ptr, row_idx)` of the
/// same dimension, sorted rows): its column pointers and sorted rows.
pub fn pattern_union(a: (&[usize], &[usize]), b: (&[usize], &[usize])) -> (Vec<usize>, Vec<usize>) {
    let n = a.0.len() - 1;
    let mut col_ptr = Vec::with_capacity(n + 1);
    let mut row_idx = Vec::with_capacity(a.1.len().max(b.1.len()));
    col_ptr.push(0);
    for c in 0..n {
        let (x, y) = (&a.1[a.0[c]..a.0[c + 1]], &b.1[b.0[c]..b.0[c + 1]]);
        let (mut i, mut j) = (0, 0);
        while i < x.len() || j < y.len() {
            let next = match (x.get(i), y.get(j)) {
                (Some(&u), Some(&v)) if u == v => {
                    i += 1;
                    j += 1;
                    u
                }
                (Some(&u), Some(&v)) if u < v => {
                    i += 1;
                    u
                }
                (Some(_), Some(&v)) => {
                    j += 1;
                    v
                }
                (Some(&u), None) => {
                    i += 1;
                    u
                }
                (None, Some(&v)) => {
                    j += 1;
                    v
                }
                (None, None) => unreachable!(),
            };
            row_idx.push(next);
        }
        col_ptr.push(row_idx.len());
    }
    (col_ptr, row_idx)
}
