//! The symbolic analysis of a sparsity pattern kept across Newton iterations and solves, for matrices
//! assembled from triplets ([`super::compressed_lower`]).
//!
//! A new matrix whose entries all lie in the analyzed pattern is scattered into it (explicit zeros where
//! it has no entry) and factored without a new analysis. When an entry falls outside, the union of the
//! held pattern and the matrix's is analyzed ([`super::pattern_union`]), so that entries which come and
//! go (yarn contacts that touch, part and touch again) stop costing analyses; once the union has more
//! than [`UNION_SLACK`] times the matrix's entries, the matrix's pattern alone is analyzed, so entries
//! long gone no longer add fill. Every analysis orders afresh: an ordering kept from an earlier pattern
//! fills fast as the pattern moves (docs/BENCHMARKS.md). The ordering is computed on the graph of the
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
    /// present), ordering on the graph of contiguous groups of `group` unknowns (1: none).
    pub fn new(
        n: usize,
        col_ptr: Vec<usize>,
        row_idx: Vec<usize>,
        group: usize,
        params: &SparseCholeskyParams,
    ) -> Result<Self, CholeskyError> {
        let values = vec![0.0; row_idx.len()];
        let starts: Option<Vec<usize>> = (group > 1 && n.is_multiple_of(group))
            .then(|| (0..=n / group).map(|k| k * group).collect());
        let chol = {
            let symbolic = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
            SparseCholesky::analyze_grouped(
                SparseColMatRef::new(symbolic, &values),
                starts.as_deref(),
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
        let analyzed = AnalyzedPattern::new(n, col_ptr, row_idx, group, params)?;
        let values = analyzed
            .scatter(matrix)
            .expect("the matrix lies in the pattern analyzed for it");
        self.pattern = Some(analyzed);
        Ok(values)
    }
}
