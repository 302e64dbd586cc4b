//! The symbolic analysis of a sparsity pattern kept across Newton iterations and solves, and the rule for
//! when to analyze again: one cache for both solvers of the toolkit.
//!
//! A new matrix whose entries all lie in the analyzed pattern is factored without a new analysis; when
//! an entry falls outside, the pattern grows by a union, so that entries which come and go stop costing
//! analyses, and the grown pattern is analyzed. The two solvers grow their patterns at different
//! grains, and the cache serves both:
//! - matrices assembled from triplets (the yarns, [`super::compressed_lower`]) are scattered into the
//!   analyzed pattern (explicit zeros where they have no entry, [`PatternCache::scatter`]); when an entry
//!   falls outside, [`PatternCache::analyze`] analyzes the union of the held pattern and the matrix's
//!   ([`super::pattern_union`]) — the slack of entries that may come back — until the union has more than
//!   [`UNION_SLACK`] times the matrix's entries; then the matrix's pattern alone, so entries long gone no
//!   longer add fill;
//! - a matrix that holds its own pattern and grows it in place, by node pairs, with the pairs a sliding
//!   cloth vertex may reach next as its slack (the garment, [`crate::node_block_assembly`]), is analyzed
//!   again by [`PatternCache::fit`] whenever its pattern is no longer the one analyzed.
//!
//! Every analysis orders afresh: an ordering kept from an earlier pattern fills fast as the pattern moves
//! (docs/BENCHMARKS.md). [`PatternCache::fit`] keeps the ordering's kind that the first analysis chose
//! (with [`crate::Ordering::Auto`], the one of less fill). The ordering is computed on the graph of the
//! problem's unknown groups ([`crate::SparseCholesky::analyze_grouped`]).

use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};

use super::{CompressedLower, pattern_union};
use crate::sparse_cholesky::{CholeskyError, SparseCholesky, SparseCholeskyParams};

/// A union pattern is kept while it has at most this many times the entries of the current matrix;
/// beyond, the current pattern alone is analyzed (entries long gone no longer add fill).
pub const UNION_SLACK: f64 = 1.25;

/// A lower-triangle pattern (sorted rows, every diagonal present) with its symbolic Cholesky analysis.
#[derive(Debug)]
pub struct AnalyzedPattern {
    /// Start of each column in `row_idx` (`n + 1` entries).
    pub col_ptr: Vec<usize>,
    /// Row of each entry, sorted within a column.
    pub row_idx: Vec<usize>,
    /// Position of each diagonal entry in `row_idx`.
    pub diagonal: Vec<usize>,
    /// The analysis, and the numeric factorization once one succeeded.
    pub chol: SparseCholesky,
}

impl AnalyzedPattern {
    /// Analyzes the `n × n` pattern `col_ptr, row_idx` (lower triangle, sorted rows, every diagonal
    /// present), ordering on the graph of the unknown groups that `group_starts` delimits (`None`: none,
    /// [`SparseCholesky::analyze_grouped`]).
    pub fn new(
        n: usize,
        col_ptr: Vec<usize>,
        row_idx: Vec<usize>,
        group_starts: Option<&[usize]>,
        params: &SparseCholeskyParams,
    ) -> Result<Self, CholeskyError> {
        let values = vec![0.0; row_idx.len()];
        let chol = {
            let symbolic = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
            SparseCholesky::analyze_grouped(
                SparseColMatRef::new(symbolic, &values),
                group_starts,
                params,
            )?
        };
        let diagonal = (0..n).map(|c| col_ptr[c]).collect();
        Ok(Self {
            col_ptr,
            row_idx,
            diagonal,
            chol,
        })
    }

    /// The values of `matrix` (same dimension, sorted rows) scattered into this pattern, zeros where
    /// `matrix` has no entry; `None` when `matrix` has an entry outside the pattern.
    pub fn scatter(&self, matrix: &CompressedLower) -> Option<Vec<f64>> {
        let mut values = vec![0.0; self.row_idx.len()];
        let (cp, ri, vals) = (&matrix.col_ptr, &matrix.row_idx, &matrix.values);
        for c in 0..self.col_ptr.len() - 1 {
            let mine = &self.row_idx[self.col_ptr[c]..self.col_ptr[c + 1]];
            let mut k = 0;
            for p in cp[c]..cp[c + 1] {
                // Both row lists are sorted: merge.
                while k < mine.len() && mine[k] < ri[p] {
                    k += 1;
                }
                if k == mine.len() || mine[k] != ri[p] {
                    return None;
                }
                values[self.col_ptr[c] + k] = vals[p];
            }
        }
        Some(values)
    }

    /// Factors the matrix of `values` (this pattern's) numerically.
    pub fn factorize(&mut self, values: &[f64]) -> Result<(), CholeskyError> {
        let n = self.col_ptr.len() - 1;
        let symbolic =
            SymbolicSparseColMatRef::new_checked(n, n, &self.col_ptr, None, &self.row_idx);
        self.chol.factorize(SparseColMatRef::new(symbolic, values))
    }
}

/// The pattern analyzed last, if any, kept for the matrices that follow.
#[derive(Debug, Default)]
pub struct PatternCache {
    pattern: Option<AnalyzedPattern>,
}

impl PatternCache {
    /// The pattern held, if any.
    pub fn pattern(&self) -> Option<&AnalyzedPattern> {
        self.pattern.as_ref()
    }

    /// The pattern held, if any, to factor with.
    pub fn pattern_mut(&mut self) -> Option<&mut AnalyzedPattern> {
        self.pattern.as_mut()
    }

    /// The analysis held (and its factorization, once one succeeded), if any.
    pub fn cholesky(&self) -> Option<&SparseCholesky> {
        self.pattern.as_ref().map(|p| &p.chol)
    }

    /// The analysis held, if any, to factor with.
    pub fn cholesky_mut(&mut self) -> Option<&mut SparseCholesky> {
        self.pattern.as_mut().map(|p| &mut p.chol)
    }

    /// Drops the pattern held unless it is `n × n`.
    pub fn keep_if_size(&mut self, n: usize) {
        if self
            .pattern
            .as_ref()
            .is_some_and(|p| p.col_ptr.len() != n + 1)
        {
            self.pattern = None;
        }
    }

    /// `matrix`'s values in the pattern held; `None` when there is none or `matrix` does not fit in it.
    pub fn scatter(&self, matrix: &CompressedLower) -> Option<Vec<f64>> {
        self.pattern.as_ref()?.scatter(matrix)
    }

    /// Analyzes a pattern for `matrix` (`n × n`, groups of `group` unknowns) and returns its values in
    /// it: with `union`, the union with the pattern held unless that has more than [`UNION_SLACK`] times
    /// the matrix's entries; otherwise (or with none held) the matrix's own pattern. The pattern held is
    /// dropped first, so a failed analysis leaves none. With `trace`, says on stderr how many entries fell
    /// outside the pattern held.
    pub fn analyze(
        &mut self,
        matrix: &CompressedLower,
        group: usize,
        union: bool,
        params: &SparseCholeskyParams,
        trace: bool,
    ) -> Result<Vec<f64>, CholeskyError> {
        let n = matrix.col_ptr.len() - 1;
        let (cp, ri) = (&matrix.col_ptr, &matrix.row_idx);
        if trace && let Some(p) = self.pattern.as_ref() {
            let (_, uri) = pattern_union((&p.col_ptr, &p.row_idx), (cp, ri));
            eprintln!(
                "newton: {} entries outside the analyzed pattern of {} ({} in the matrix)",
                uri.len() - p.row_idx.len(),
                p.row_idx.len(),
                ri.len()
            );
        }
        let (col_ptr, row_idx) = match self.pattern.as_ref() {
            Some(p) if union => {
                let (ucp, uri) = pattern_union((&p.col_ptr, &p.row_idx), (cp, ri));
                if uri.len() as f64 <= UNION_SLACK * ri.len() as f64 {
                    (ucp, uri)
                } else {
                    (cp.to_vec(), ri.to_vec())
                }
            }
            _ => (cp.to_vec(), ri.to_vec()),
        };
        self.pattern = None;
        let starts: Option<Vec<usize>> = (group > 1 && n.is_multiple_of(group))
            .then(|| (0..=n / group).map(|k| k * group).collect());
        let analyzed = AnalyzedPattern::new(n, col_ptr, row_idx, starts.as_deref(), params)?;
        let values = analyzed
            .scatter(matrix)
            .expect("the matrix lies in the pattern analyzed for it");
        self.pattern = Some(analyzed);
        Ok(values)
    }
    /// Keeps the analysis while `matrix` (`n × n`, lower triangle, compressed columns, sorted rows, every
    /// diagonal present; its values are not read) has the pattern analyzed, and otherwise analyzes its
    /// pattern — for a matrix that holds its own pattern and grows it in place. The ordering is computed
    /// afresh on the graph of the groups of `group_starts`, of the kind the held analysis used (with none
    /// held, `params`' kind: [`crate::Ordering::Auto`] chooses it here, once). Returns whether it
    /// analyzed. The pattern held is dropped first, so a failed analysis leaves none.
    pub fn fit(
        &mut self,
        matrix: SparseColMatRef<'_, usize, f64>,
        group_starts: Option<&[usize]>,
        params: &SparseCholeskyParams,
    ) -> Result<bool, CholeskyError> {
        let ordering = match self.pattern.take() {
            Some(held) if held.chol.pattern_matches(matrix) => {
                self.pattern = Some(held);
                return Ok(false);
            }
            Some(held) => held.chol.ordering_used(),
            None => params.ordering,
        };
        let symbolic = matrix.symbolic();
        let params = SparseCholeskyParams {
            ordering,
            ..*params
        };
        self.pattern = Some(AnalyzedPattern::new(
            symbolic.nrows(),
            symbolic.col_ptr().to_vec(),
            symbolic.row_idx().to_vec(),
            group_starts,
            &params,
        )?);
        Ok(true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::newton::compressed_lower;
    use crate::sparse_cholesky::Ordering;
    use faer::sparse::{SparseColMat, Triplet};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A diagonally dominant `n × n` lower triangle with the couplings `pairs` (row > column).
    fn matrix(n: usize, pairs: &[(usize, usize)], rng: &mut ChaCha8Rng) -> CompressedLower {
        let mut triplets: Vec<Triplet<usize, usize, f64>> = pairs
            .iter()
            .map(|&(r, c)| Triplet::new(r, c, rng.random_range(-1.0..1.0)))
            .collect();
        triplets.extend((0..n).map(|i| Triplet::new(i, i, 4.0 + pairs.len() as f64)));
        compressed_lower(n, &triplets)
    }

    fn chain(n: usize) -> Vec<(usize, usize)> {
        (1..n).map(|i| (i, i - 1)).collect()
    }

    fn as_faer(m: &CompressedLower) -> SparseColMat<usize, f64> {
        let n = m.col_ptr.len() - 1;
        let symbolic = faer::sparse::SymbolicSparseColMat::new_checked(
            n,
            n,
            m.col_ptr.clone(),
            None,
            m.row_idx.clone(),
        );
        SparseColMat::new(symbolic, m.values.clone())
    }

    #[test]
    fn a_matrix_in_the_union_is_scattered_and_the_union_is_dropped_beyond_the_slack() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let n = 12;
        let params = SparseCholeskyParams::default();
        let mut cache = PatternCache::default();
        let first = matrix(n, &chain(n), &mut rng);
        assert!(cache.scatter(&first).is_none(), "nothing is held yet");
        let values = cache.analyze(&first, 1, true, &params, false).unwrap();
        assert_eq!(values, first.values);
        // One extra coupling: the union of both is analyzed, and the first matrix scatters into it.
        let mut pairs = chain(n);
        pairs.push((7, 2));
        let second = matrix(n, &pairs, &mut rng);
        assert!(cache.scatter(&second).is_none());
        cache.analyze(&second, 1, true, &params, false).unwrap();
        let held = cache.pattern().unwrap().row_idx.len();
        assert_eq!(held, second.row_idx.len());
        let scattered = cache.scatter(&first).expect("the chain lies in the union");
        assert_eq!(scattered.len(), held);
        assert_eq!(
            scattered.iter().filter(|&&v| v != 0.0).count(),
            first.values.len()
        );
        // Many couplings that come and go: past the slack the matrix's own pattern is analyzed.
        let mut far = chain(n);
        far.extend((3..n).map(|r| (r, r - 3)));
        let third = matrix(n, &far, &mut rng);
        cache.analyze(&third, 1, true, &params, false).unwrap();
        let fourth = matrix(n, &[(9, 0), (10, 1), (11, 2), (11, 5)], &mut rng);
        cache.analyze(&fourth, 1, true, &params, false).unwrap();
        assert_eq!(cache.pattern().unwrap().row_idx, fourth.row_idx);
        // Without union, always the matrix's own pattern; a factorization solves.
        cache.analyze(&third, 1, false, &params, false).unwrap();
        assert_eq!(cache.pattern().unwrap().row_idx, third.row_idx);
        let pattern = cache.pattern_mut().unwrap();
        pattern.factorize(&third.values).unwrap();
        let mut x = vec![1.0; n];
        pattern.chol.solve_in_place(&mut x).unwrap();
        assert!(x.iter().all(|v| v.is_finite()));
    }

    #[test]
    fn fit_keeps_the_analysis_while_the_pattern_holds_and_the_ordering_kind_after() {
        let mut rng = ChaCha8Rng::seed_from_u64(12);
        let n = 30;
        let mut cache = PatternCache::default();
        let metis = SparseCholeskyParams {
            ordering: Ordering::Metis,
            ..SparseCholeskyParams::default()
        };
        let first = as_faer(&matrix(n, &chain(n), &mut rng));
        let groups: Vec<usize> = (0..=n / 3).map(|k| 3 * k).collect();
        assert!(cache.fit(first.as_ref(), Some(&groups), &metis).unwrap());
        assert_eq!(cache.cholesky().unwrap().ordering_used(), Ordering::Metis);
        // New values in the same pattern: no analysis, whatever the settings say.
        let again = as_faer(&matrix(n, &chain(n), &mut rng));
        let amd = SparseCholeskyParams {
            ordering: Ordering::Amd,
            ..metis
        };
        assert!(!cache.fit(again.as_ref(), Some(&groups), &amd).unwrap());
        // A grown pattern is analyzed, with the kind of ordering the first analysis used.
        let mut pairs = chain(n);
        pairs.extend([(20, 4), (29, 0)]);
        let grown = as_faer(&matrix(n, &pairs, &mut rng));
        assert!(cache.fit(grown.as_ref(), Some(&groups), &amd).unwrap());
        let chol = cache.cholesky_mut().unwrap();
        assert_eq!(chol.ordering_used(), Ordering::Metis);
        assert!(chol.pattern_matches(grown.as_ref()));
        chol.factorize(grown.as_ref()).unwrap();
        // A fresh cache takes the settings' kind.
        let mut fresh = PatternCache::default();
        assert!(fresh.fit(grown.as_ref(), None, &amd).unwrap());
        assert_eq!(fresh.cholesky().unwrap().ordering_used(), Ordering::Amd);
    }
}
