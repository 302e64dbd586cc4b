//! Sparse Cholesky factorization `P A Pᵀ = L Lᵀ`: the linear solver of the Newton solver.
//!
//! [`SparseCholesky`] factors a sparse symmetric positive definite `n × n` matrix `A` (e.g. a Hessian in
//! N/m; the factorization is unit-agnostic) as `P A Pᵀ = L Lᵀ`, with `P` a fill-reducing permutation and `L`
//! lower triangular. Only the **lower triangle** of `A` (row ≥ column, diagonal included) is read, stored in
//! compressed-column form — what [`crate::NodeBlockAssembler`] produces.
//!
//! As in faer, the work is split in two phases:
//!
//! 1. **Symbolic, once per sparsity pattern** ([`SparseCholesky::analyze`]): the fill-reducing ordering
//!    (approximate minimum degree, METIS nested dissection, or both with the smaller factor kept), the
//!    elimination tree, column counts and the supernodal structure of `L`, and the workspaces
//!    ([`SparseCholesky::reanalyze`]: all but the ordering, kept from an earlier analysis).
//! 2. **Numeric, per Newton step** ([`SparseCholesky::factorize`]): the values of `L` for new values of `A`
//!    on the same pattern, reusing the symbolic factorization and the workspace (no allocation); a
//!    supernodal factor reads `P A Pᵀ` through a gather built with the analysis
//!    (`symmetric_permutation.rs`) instead of faer permuting `A` again on every call. A matrix that
//!    is not numerically positive definite gives [`CholeskyError::NotPositiveDefinite`] — the damped Newton
//!    solver then increases its damping and factors again.
//!
//! [`SparseCholesky::solve_in_place`] then solves `A x = b` by two triangular solves.
//!
//! faer ships only AMD; the METIS permutation (`METIS_NodeND` from the bundled METIS 5 C library) is passed
//! to faer's low-level symbolic factorization as a custom ordering. On 3D elasticity Hessians nested
//! dissection typically gives a much smaller factor than AMD; see `docs/BENCHMARKS.md`.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{LltError, LltRegularization};
use faer::perm::PermRef;
use faer::sparse::linalg::amd;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, LltRef, SymbolicCholesky, SymbolicCholeskyRaw, SymmetricOrdering,
    factorize_symbolic_cholesky, simplicial, supernodal,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};
use serde::{Deserialize, Serialize};
use std::sync::{Mutex, TryLockError};
use thiserror::Error;

use crate::symmetric_permutation::SymmetricPermutation;

/// Fill-reducing ordering of a [`SparseCholesky`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Ordering {
    /// Approximate minimum degree (faer's AMD). Fast to compute; good on 2D-like and small problems.
    Amd,
    /// Nested dissection by METIS (`METIS_NodeND`). Slower to compute; usually a smaller factor and fewer
    /// flops on 3D meshes.
    Metis,
    /// Compute both orderings and keep the one whose factor `L` has fewer nonzeros. Falls back to AMD if
    /// METIS fails. Default.
    #[default]
    Auto,
}

/// The fewest right-hand sides a thread of [`SparseCholesky::solve_columns_in_place_on`] takes: below
/// it the sweep's fixed cost (walking the supernodes) outweighs what splitting saves.
pub const MIN_COLUMNS_PER_THREAD: usize = 16;

/// Settings of a [`SparseCholesky`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct SparseCholeskyParams {
    /// Fill-reducing ordering. Default: [`Ordering::Auto`].
    pub ordering: Ordering,
    /// Threads of the numeric factorization and the solves: `None` or `Some(1)` (default) runs
    /// single-threaded (`faer::Par::Seq`), `Some(k)` with `k ≥ 2` uses `k` rayon threads, `Some(0)` all of
    /// rayon's threads. The orderings and the symbolic phase are always single-threaded.
    pub threads: Option<usize>,
}

impl SparseCholeskyParams {
    /// The faer parallelism these settings ask for.
    fn par(&self) -> Par {
        match self.threads {
            None | Some(1) => Par::Seq,
            Some(k) => Par::rayon(k),
        }
    }
}

/// Size and cost of the factor `L` under one ordering (exact, from the elimination tree's column counts).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FillFigures {
    /// Nonzeros of `L`, diagonal included (structural; the supernodal storage may hold a few explicit zeros
    /// more, see [`SparseCholesky::factor_storage_len`]).
    pub factor_nnz: usize,
    /// Operation count `Σⱼ cⱼ²` of the numeric factorization, `cⱼ` the nonzeros of column `j` of `L`
    /// (multiply-adds, up to lower-order terms).
    pub flops: f64,
}

/// Errors of the sparse Cholesky factorization.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum CholeskyError {
    /// The matrix is not square.
    #[error("the matrix is {rows} × {cols}; a Cholesky factorization needs a square matrix")]
    NotSquare {
        /// Number of rows.
        rows: usize,
        /// Number of columns.
        cols: usize,
    },
    /// An entry lies above the diagonal.
    #[error(
        "entry ({row}, {col}) lies above the diagonal; pass only the lower triangle (row ≥ column) of the \
         symmetric matrix"
    )]
    NotLowerTriangular {
        /// Row of the offending entry.
        row: usize,
        /// Column of the offending entry.
        col: usize,
    },
    /// A matrix or vector does not have the analyzed dimension.
    #[error(
        "the {what} has dimension {got}, but the factorization was analyzed for dimension {expected}"
    )]
    DimensionMismatch {
        /// Which argument: "matrix" or "right-hand side".
        what: &'static str,
        /// Its dimension (length of a vector, size of a square matrix).
        got: usize,
        /// The analyzed dimension `n`.
        expected: usize,
    },
    /// The matrix has the right dimension but another sparsity pattern than the analyzed one.
    #[error(
        "the matrix's sparsity pattern differs from the analyzed one; call SparseCholesky::analyze again \
         for the new pattern"
    )]
    PatternMismatch,
    /// A stored entry is NaN or infinite.
    #[error("matrix entry ({row}, {col}) is not finite ({value})")]
    NonFiniteValue {
        /// Row of the entry.
        row: usize,
        /// Column of the entry.
        col: usize,
        /// Its value.
        value: f64,
    },
    /// The matrix is not (numerically) positive definite: a pivot of the factorization is ≤ 0.
    #[error(
        "the matrix is not positive definite (pivot {pivot} of the reordered matrix, unknown {unknown} of \
         the original, is not positive); add more damping/regularization to the diagonal and factor again"
    )]
    NotPositiveDefinite {
        /// Index of the failed pivot in the reordered matrix `P A Pᵀ`.
        pivot: usize,
        /// The corresponding row/column of `A`.
        unknown: usize,
    },
    /// `solve_in_place` was called without a successful `factorize` since the analysis (or after a failed
    /// one).
    #[error(
        "no valid factorization to solve with: call factorize (successfully) before solve_in_place"
    )]
    NotFactorized,
    /// METIS failed (only reported when [`Ordering::Metis`] was asked for; `Auto` falls back to AMD).
    #[error("METIS nested dissection failed: {0}")]
    Metis(String),
    /// The symbolic analysis failed (out of memory, index overflow).
    #[error("the symbolic analysis of the sparse Cholesky factorization failed: {0}")]
    Analysis(String),
}

/// A sparse Cholesky factorization `P A Pᵀ = L Lᵀ` with a reusable symbolic phase; see the module
/// documentation.
pub struct SparseCholesky {
    /// The analyzed pattern (lower triangle of `A`, compressed columns).
    col_ptr: Vec<usize>,
    col_nnz: Option<Vec<usize>>,
    row_idx: Vec<usize>,
    ordering_used: Ordering,
    amd_fill: Option<FillFigures>,
    metis_fill: Option<FillFigures>,
    metis_failure: Option<String>,
    symbolic: SymbolicCholesky<usize>,
    /// `P A Pᵀ` gathered from `A` for the supernodal factorization (built with the analysis; `None` for
    /// a simplicial one, which faer permutes itself).
    permuted: Option<SymmetricPermutation>,
    /// Values of `L` (faer's supernodal or simplicial layout).
    values: Vec<f64>,
    factorized: bool,
    par: Par,
    factor_workspace: MemBuffer,
    solve_workspace: Mutex<MemBuffer>,
}

impl std::fmt::Debug for SparseCholesky {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SparseCholesky")
            .field("dimension", &self.dimension())
            .field("ordering_used", &self.ordering_used)
            .field("amd_fill", &self.amd_fill)
            .field("metis_fill", &self.metis_fill)
            .field("metis_failure", &self.metis_failure)
            .field("supernodal", &self.is_supernodal())
            .field("factorized", &self.factorized)
            .finish_non_exhaustive()
    }
}

/// The dimension of `pattern` when it is square and holds a lower triangle (row ≥ column), else the error
/// naming the first entry that is not.
fn check_lower_triangle(
    pattern: SymbolicSparseColMatRef<'_, usize>,
) -> Result<usize, CholeskyError> {
    let (n, cols) = (pattern.nrows(), pattern.ncols());
    if n != cols {
        return Err(CholeskyError::NotSquare { rows: n, cols });
    }
    for c in 0..n {
        if let Some(&r) = pattern.row_idx_of_col_raw(c).iter().find(|&&r| r < c) {
            return Err(CholeskyError::NotLowerTriangular { row: r, col: c });
        }
    }
    Ok(n)
}

impl SparseCholesky {
    /// Symbolic analysis of the symmetric `n × n` matrix whose **lower triangle** (row ≥ column) `matrix`
    /// holds: the fill-reducing ordering (see [`Ordering`]) and the structure of `L`. Only the pattern of
    /// `matrix` is read, not its values. The result is not factorized yet: call [`Self::factorize`].
    pub fn analyze(
        matrix: SparseColMatRef<'_, usize, f64>,
        params: &SparseCholeskyParams,
    ) -> Result<Self, CholeskyError> {
        Self::analyze_grouped(matrix, None, params)
    }

    /// [`Self::analyze`] for a matrix whose unknowns come in contiguous groups that share their sparsity
    /// (the 2 or 3 coordinates of one node): `group_starts` (`#groups + 1`, increasing from 0 to `n`)
    /// delimits them. The orderings are computed on the graph of the groups (about `dim²` times fewer
    /// entries, so several times faster) and expanded, each group's unknowns kept together — which also
    /// suits the supernodes. The matrix itself need not be blocked exactly: the group graph has an edge
    /// wherever any entry couples two groups. `None`: one group per unknown, as [`Self::analyze`].
    pub fn analyze_grouped(
        matrix: SparseColMatRef<'_, usize, f64>,
        group_starts: Option<&[usize]>,
        params: &SparseCholeskyParams,
    ) -> Result<Self, CholeskyError> {
        let pattern = matrix.symbolic();
        check_lower_triangle(pattern)?;

        let groups = match group_starts {
            Some(starts) => Some(GroupGraph::new(pattern, starts)?),
            None => None,
        };
        let amd_perm = || -> Result<(Vec<usize>, Vec<usize>), CholeskyError> {
            match &groups {
                Some(g) => Ok(g.expand(amd_ordering(g.pattern())?)),
                None => amd_ordering(pattern),
            }
        };
        let metis_perm = || -> Result<(Vec<usize>, Vec<usize>), CholeskyError> {
            match &groups {
                Some(g) => Ok(g.expand(metis_ordering(g.pattern())?)),
                None => metis_ordering(pattern),
            }
        };
        let (mut amd_fill, mut metis_fill, mut metis_failure) = (None, None, None);
        let (ordering_used, fwd, inv) = match params.ordering {
            // A fixed ordering needs no fill figures to choose; `fill` computes them when asked (they cost
            // a second elimination tree and column counts, as much as faer's own in the analysis below:
            // ~4 % of a Newton iteration of the 16 × 16 yarn patch, which analyzes every iteration).
            Ordering::Amd => {
                let (fwd, inv) = amd_perm()?;
                (Ordering::Amd, fwd, inv)
            }
            Ordering::Metis => {
                let (fwd, inv) = metis_perm()?;
                (Ordering::Metis, fwd, inv)
            }
            Ordering::Auto => {
                let (a_fwd, a_inv) = amd_perm()?;
                let a_fill = fill_figures(pattern, &a_inv)?;
                amd_fill = Some(a_fill);
                match metis_perm() {
                    Ok((m_fwd, m_inv)) => {
                        let m_fill = fill_figures(pattern, &m_inv)?;
                        metis_fill = Some(m_fill);
                        if m_fill.factor_nnz < a_fill.factor_nnz {
                            (Ordering::Metis, m_fwd, m_inv)
                        } else {
                            (Ordering::Amd, a_fwd, a_inv)
                        }
                    }
                    Err(err) => {
                        metis_failure = Some(err.to_string());
                        (Ordering::Amd, a_fwd, a_inv)
                    }
                }
            }
        };

        let mut chol = Self::with_ordering(pattern, fwd, inv, ordering_used, params)?;
        (chol.amd_fill, chol.metis_fill, chol.metis_failure) =
            (amd_fill, metis_fill, metis_failure);
        Ok(chol)
    }

    /// The analysis of `matrix`'s pattern (lower triangle, the same dimension) under this analysis's
    /// ordering instead of a new one: the elimination tree, column counts and supernodes anew, the
    /// fill-reducing ordering not. Worth it only while the patterns stay close, which the caller judges
    /// ([`Self::factor_storage_len`] measures the fill). On the 16 × 16 yarn hang it is not: one time step
    /// later a kept ordering fills 1.4–1.6× (METIS, AMD) and factors 2–2.3× slower
    /// (`examples/factor_orderings.rs`, docs/BENCHMARKS.md), so the yarn solver orders afresh.
    /// Settings as `params` (its ordering is not used).
    pub fn reanalyze(
        &self,
        matrix: SparseColMatRef<'_, usize, f64>,
        params: &SparseCholeskyParams,
    ) -> Result<Self, CholeskyError> {
        let pattern = matrix.symbolic();
        if pattern.nrows() == pattern.ncols() && pattern.nrows() != self.dimension() {
            return Err(CholeskyError::DimensionMismatch {
                what: "matrix",
                got: pattern.nrows(),
                expected: self.dimension(),
            });
        }
        let n = check_lower_triangle(pattern)?;
        let (fwd, inv) = match self.symbolic.perm() {
            Some(perm) => {
                let (fwd, inv) = perm.arrays();
                (fwd.to_vec(), inv.to_vec())
            }
            None => ((0..n).collect(), (0..n).collect()),
        };
        Self::with_ordering(pattern, fwd, inv, self.ordering_used, params)
    }

    /// The symbolic factorization of the lower triangle `pattern` under the permutation `fwd`/`inv` (checked
    /// by the caller) and the workspaces.
    fn with_ordering(
        pattern: SymbolicSparseColMatRef<'_, usize>,
        fwd: Vec<usize>,
        inv: Vec<usize>,
        ordering_used: Ordering,
        params: &SparseCholeskyParams,
    ) -> Result<Self, CholeskyError> {
        let n = pattern.nrows();
        let perm = PermRef::new_checked(&fwd, &inv, n);
        let symbolic = factorize_symbolic_cholesky(
            pattern,
            Side::Lower,
            SymmetricOrdering::Custom(perm),
            CholeskySymbolicParams::default(),
        )
        .map_err(|e| CholeskyError::Analysis(format!("{e:?}")))?;

        let par = params.par();
        let factor_req = symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default());
        let solve_req = symbolic.solve_in_place_scratch::<f64>(1, par);
        let out_of_memory = |_| CholeskyError::Analysis("out of memory for the workspace".into());
        let factor_workspace = MemBuffer::try_new(factor_req).map_err(out_of_memory)?;
        let solve_workspace = MemBuffer::try_new(solve_req).map_err(out_of_memory)?;
        let mut values = Vec::new();
        values
            .try_reserve_exact(symbolic.len_val())
            .map_err(|_| CholeskyError::Analysis("out of memory for the factor".into()))?;
        values.resize(symbolic.len_val(), 0.0);
        let permuted = matches!(symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_))
            .then(|| SymmetricPermutation::new(pattern, &inv));

        Ok(Self {
            col_ptr: pattern.col_ptr().to_vec(),
            col_nnz: pattern.col_nnz().map(<[usize]>::to_vec),
            row_idx: pattern.row_idx().to_vec(),
            ordering_used,
            amd_fill: None,
            metis_fill: None,
            metis_failure: None,
            symbolic,
            permuted,
            values,
            factorized: false,
            par,
            factor_workspace,
            solve_workspace: Mutex::new(solve_workspace),
        })
    }

    /// Whether `matrix` has exactly the analyzed sparsity pattern (dimension, column pointers, row
    /// indices), i.e. whether [`Self::factorize`] accepts it. When `false`, analyze the new pattern.
    pub fn pattern_matches(&self, matrix: SparseColMatRef<'_, usize, f64>) -> bool {
        let p = matrix.symbolic();
        p.nrows() == self.dimension()
            && p.ncols() == self.dimension()
            && p.col_ptr() == self.col_ptr.as_slice()
            && p.col_nnz() == self.col_nnz.as_deref()
            && p.row_idx() == self.row_idx.as_slice()
    }

    /// Numeric factorization of `matrix` (lower triangle, the analyzed pattern, new values), reusing the
    /// symbolic analysis and the workspace. On error the previous factorization is discarded
    /// ([`Self::solve_in_place`] answers [`CholeskyError::NotFactorized`] until a factorization succeeds);
    /// [`CholeskyError::NotPositiveDefinite`] means: damp more and call again.
    pub fn factorize(
        &mut self,
        matrix: SparseColMatRef<'_, usize, f64>,
    ) -> Result<(), CholeskyError> {
        self.factorized = false;
        let n = self.dimension();
        let p = matrix.symbolic();
        if p.nrows() != p.ncols() {
            return Err(CholeskyError::NotSquare {
                rows: p.nrows(),
                cols: p.ncols(),
            });
        }
        if p.nrows() != n {
            return Err(CholeskyError::DimensionMismatch {
                what: "matrix",
                got: p.nrows(),
                expected: n,
            });
        }
        if !self.pattern_matches(matrix) {
            return Err(CholeskyError::PatternMismatch);
        }
        for c in 0..n {
            let rows = p.row_idx_of_col_raw(c);
            let vals = matrix.val_of_col(c);
            if let Some((&row, &value)) = rows.iter().zip(vals).find(|(_, v)| !v.is_finite()) {
                return Err(CholeskyError::NonFiniteValue { row, col: c, value });
            }
        }
        let stack = MemStack::new(&mut self.factor_workspace);
        let result = match (&mut self.permuted, self.symbolic.raw()) {
            // P A Pᵀ by the gather built with the analysis, then faer's supernodal factorization of it:
            // the same matrix and the same factor as faer's own permutation below gives.
            (Some(permuted), SymbolicCholeskyRaw::Supernodal(structure)) => {
                supernodal::factorize_supernodal_numeric_llt(
                    &mut self.values,
                    permuted.apply(matrix.val()),
                    LltRegularization::default(),
                    structure,
                    self.par,
                    stack,
                    Default::default(),
                )
                .map(|_| ())
            }
            _ => self
                .symbolic
                .factorize_numeric_llt::<f64>(
                    &mut self.values,
                    matrix,
                    Side::Lower,
                    LltRegularization::default(),
                    self.par,
                    stack,
                    Default::default(),
                )
                .map(|_| ()),
        };
        match result {
            Ok(()) => {
                self.factorized = true;
                Ok(())
            }
            Err(LltError::NonPositivePivot { index }) => {
                let unknown = self
                    .symbolic
                    .perm()
                    .and_then(|perm| perm.arrays().0.get(index).copied())
                    .unwrap_or(index);
                Err(CholeskyError::NotPositiveDefinite {
                    pivot: index,
                    unknown,
                })
            }
        }
    }

    /// Solves `A x = b` with the current factorization: `rhs` holds `b` (length `n`) on entry and `x` on
    /// return. Errors (and leaves `rhs` unchanged) if there is no valid factorization or the length is not
    /// `n`. The solve workspace is reused; concurrent solves on one factorization allocate their own.
    pub fn solve_in_place(&self, rhs: &mut [f64]) -> Result<(), CholeskyError> {
        if !self.factorized {
            return Err(CholeskyError::NotFactorized);
        }
        let n = self.dimension();
        if rhs.len() != n {
            return Err(CholeskyError::DimensionMismatch {
                what: "right-hand side",
                got: rhs.len(),
                expected: n,
            });
        }
        let llt = LltRef::new(&self.symbolic, &self.values);
        let solve = |buffer: &mut MemBuffer, rhs: &mut [f64]| {
            let rhs = MatMut::from_column_major_slice_mut(rhs, n, 1);
            llt.solve_in_place_with_conj(Conj::No, rhs, self.par, MemStack::new(buffer));
        };
        match self.solve_workspace.try_lock() {
            Ok(mut buffer) => solve(&mut buffer, rhs),
            Err(TryLockError::Poisoned(poisoned)) => solve(&mut poisoned.into_inner(), rhs),
            Err(TryLockError::WouldBlock) => {
                let req = self.symbolic.solve_in_place_scratch::<f64>(1, self.par);
                solve(&mut MemBuffer::new(req), rhs)
            }
        }
        Ok(())
    }

    /// Solves `A X = B` for `columns` right-hand sides at once with the current factorization (one
    /// supernodal sweep for all of them): `rhs` holds `B` column-major (`n × columns`) on entry and `X` on
    /// return. Errors (and leaves `rhs` unchanged) if there is no valid factorization or `rhs` is not
    /// `n × columns`.
    pub fn solve_columns_in_place(
        &self,
        rhs: &mut [f64],
        columns: usize,
    ) -> Result<(), CholeskyError> {
        self.solve_columns_in_place_on(rhs, columns, 1)
    }

    /// [`Self::solve_columns_in_place`] with the columns split into up to `threads` contiguous blocks,
    /// each solved in a sweep of its own on its own thread (the factor is shared, read-only): the
    /// triangular sweeps over many right-hand sides are independent per column, so `k` cores take about
    /// `1/k` of the time where one sweep runs single-threaded. Blocks hold at least
    /// [`MIN_COLUMNS_PER_THREAD`] columns; `threads` ≤ 1 or fewer columns is one sweep. Each column's result
    /// equals the one-sweep result to rounding (the blocked kernels may sum in another order).
    pub fn solve_columns_in_place_on(
        &self,
        rhs: &mut [f64],
        columns: usize,
        threads: usize,
    ) -> Result<(), CholeskyError> {
        if !self.factorized {
            return Err(CholeskyError::NotFactorized);
        }
        let n = self.dimension();
        if rhs.len() != n * columns {
            return Err(CholeskyError::DimensionMismatch {
                what: "right-hand sides",
                got: rhs.len(),
                expected: n * columns,
            });
        }
        if columns == 0 || n == 0 {
            return Ok(());
        }
        let blocks = threads.min(columns / MIN_COLUMNS_PER_THREAD).max(1);
        let llt = LltRef::new(&self.symbolic, &self.values);
        let sweep = |block: &mut [f64]| {
            let cols = block.len() / n;
            let req = self.symbolic.solve_in_place_scratch::<f64>(cols, self.par);
            let mut buffer = MemBuffer::new(req);
            let block = MatMut::from_column_major_slice_mut(block, n, cols);
            llt.solve_in_place_with_conj(Conj::No, block, self.par, MemStack::new(&mut buffer));
        };
        if blocks == 1 {
            sweep(rhs);
            return Ok(());
        }
        std::thread::scope(|scope| {
            let mut rest = rhs;
            for b in 0..blocks {
                // Columns of block b: an even share, the first blocks one more.
                let cols = columns / blocks + usize::from(b < columns % blocks);
                let (block, tail) = rest.split_at_mut(cols * n);
                rest = tail;
                if b + 1 == blocks {
                    sweep(block);
                } else {
                    scope.spawn(|| sweep(block));
                }
            }
        });
        Ok(())
    }

    /// The ordering in use: [`Ordering::Amd`] or [`Ordering::Metis`] (never `Auto`).
    pub fn ordering_used(&self) -> Ordering {
        self.ordering_used
    }

    /// Nonzeros of the factor `L` (diagonal included) under the ordering in use.
    pub fn factor_nnz(&self) -> usize {
        self.fill(self.ordering_used)
            .map_or(self.symbolic.len_val(), |f| f.factor_nnz)
    }

    /// Number of stored values of `L` in faer's layout (≥ [`Self::factor_nnz`]: supernodes may store a few
    /// explicit zeros).
    pub fn factor_storage_len(&self) -> usize {
        self.symbolic.len_val()
    }

    /// The fill figures of `ordering` if it was computed: the ordering in use (computed here, from the
    /// analyzed pattern and permutation, when the analysis asked for a fixed ordering), or both under
    /// [`Ordering::Auto`] (METIS missing if it failed). `Auto` gives the ordering in use.
    pub fn fill(&self, ordering: Ordering) -> Option<FillFigures> {
        let stored = match ordering {
            Ordering::Amd => self.amd_fill,
            Ordering::Metis => self.metis_fill,
            Ordering::Auto => return self.fill(self.ordering_used),
        };
        stored.or_else(|| {
            if ordering != self.ordering_used {
                return None;
            }
            let n = self.dimension();
            let pattern = SymbolicSparseColMatRef::new_checked(
                n,
                n,
                &self.col_ptr,
                self.col_nnz.as_deref(),
                &self.row_idx,
            );
            let inv = self.symbolic.perm()?.arrays().1;
            fill_figures(pattern, inv).ok()
        })
    }

    /// Why METIS failed when [`Ordering::Auto`] fell back to AMD; `None` otherwise.
    pub fn metis_failure(&self) -> Option<&str> {
        self.metis_failure.as_deref()
    }

    /// Matrix dimension `n`.
    pub fn dimension(&self) -> usize {
        self.col_ptr.len() - 1
    }

    /// Whether faer chose the supernodal (blocked) factorization rather than the simplicial one.
    pub fn is_supernodal(&self) -> bool {
        matches!(self.symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_))
    }

    /// Whether a successful numeric factorization is available for [`Self::solve_in_place`].
    pub fn is_factorized(&self) -> bool {
        self.factorized
    }
}

/// faer's AMD ordering of the pattern of `A + Aᵀ`: `(fwd, inv)` with `fwd[new] = old`, `inv[old] = new`.
/// The graph of groups of unknowns (see [`SparseCholesky::analyze_grouped`]): the lower triangle of the
/// quotient pattern, and the groups' ranges to expand a group ordering into one of the unknowns.
struct GroupGraph {
    starts: Vec<usize>,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
}

impl GroupGraph {
    fn new(
        pattern: SymbolicSparseColMatRef<'_, usize>,
        starts: &[usize],
    ) -> Result<Self, CholeskyError> {
        let n = pattern.nrows();
        let valid = starts.first() == Some(&0)
            && starts.last() == Some(&n)
            && starts.windows(2).all(|w| w[0] < w[1]);
        if !valid {
            return Err(CholeskyError::Analysis(format!(
                "the groups of unknowns must be increasing ranges covering 0..{n}"
            )));
        }
        let ng = starts.len() - 1;
        let mut group_of = vec![0usize; n];
        for g in 0..ng {
            group_of[starts[g]..starts[g + 1]].fill(g);
        }
        let mut col_ptr = Vec::with_capacity(ng + 1);
        let mut row_idx = Vec::new();
        col_ptr.push(0);
        let mut rows = Vec::new();
        for g in 0..ng {
            rows.clear();
            rows.push(g);
            for c in starts[g]..starts[g + 1] {
                rows.extend(
                    pattern
                        .row_idx_of_col_raw(c)
                        .iter()
                        .map(|&r| group_of[r])
                        .filter(|&rg| rg >= g),
                );
            }
            rows.sort_unstable();
            rows.dedup();
            row_idx.extend_from_slice(&rows);
            col_ptr.push(row_idx.len());
        }
        Ok(Self {
            starts: starts.to_vec(),
            col_ptr,
            row_idx,
        })
    }

    fn pattern(&self) -> SymbolicSparseColMatRef<'_, usize> {
        let ng = self.starts.len() - 1;
        SymbolicSparseColMatRef::new_checked(ng, ng, &self.col_ptr, None, &self.row_idx)
    }

    /// The ordering of the unknowns that eliminates the groups in the order `(fwd, inv)` of groups, each
    /// group's unknowns in their own order.
    fn expand(&self, (group_fwd, _): (Vec<usize>, Vec<usize>)) -> (Vec<usize>, Vec<usize>) {
        let n = *self.starts.last().expect("at least the start 0");
        let mut fwd = Vec::with_capacity(n);
        for g in group_fwd {
            fwd.extend(self.starts[g]..self.starts[g + 1]);
        }
        let mut inv = vec![0usize; n];
        for (new, &old) in fwd.iter().enumerate() {
            inv[old] = new;
        }
        (fwd, inv)
    }
}

fn amd_ordering(
    pattern: SymbolicSparseColMatRef<'_, usize>,
) -> Result<(Vec<usize>, Vec<usize>), CholeskyError> {
    let n = pattern.nrows();
    let nnz = pattern.compute_nnz();
    let mut fwd = vec![0usize; n];
    let mut inv = vec![0usize; n];
    let mut buffer = MemBuffer::try_new(amd::order_maybe_unsorted_scratch::<usize>(n, nnz))
        .map_err(|_| CholeskyError::Analysis("out of memory for the AMD ordering".into()))?;
    amd::order_maybe_unsorted(
        &mut fwd,
        &mut inv,
        pattern,
        amd::Control::default(),
        MemStack::new(&mut buffer),
    )
    .map_err(|e| CholeskyError::Analysis(format!("AMD ordering: {e:?}")))?;
    Ok((fwd, inv))
}

/// METIS nested-dissection ordering (`METIS_NodeND`) of the graph of the lower-triangle `pattern`
/// (diagonal ignored): `(fwd, inv)` with `fwd[new] = old`, `inv[old] = new`.
fn metis_ordering(
    pattern: SymbolicSparseColMatRef<'_, usize>,
) -> Result<(Vec<usize>, Vec<usize>), CholeskyError> {
    use metis_sys as m;
    let n = pattern.nrows();
    // Adjacency in CSR form (symmetric, so CSR = CSC), both directions of every off-diagonal entry.
    let mut degree = vec![0usize; n + 1];
    for c in 0..n {
        for &r in pattern.row_idx_of_col_raw(c) {
            if r != c {
                degree[r + 1] += 1;
                degree[c + 1] += 1;
            }
        }
    }
    for i in 0..n {
        degree[i + 1] += degree[i];
    }
    let num_adjacent = degree[n];
    if num_adjacent == 0 {
        // No edges (diagonal matrix, or n ≤ 1): every order is fill-free.
        let identity: Vec<usize> = (0..n).collect();
        return Ok((identity.clone(), identity));
    }
    let too_large = || {
        CholeskyError::Metis(format!(
            "the graph ({n} vertices, {num_adjacent} adjacency entries) exceeds METIS's 32-bit indices"
        ))
    };
    let to_idx = |v: usize| m::idx_t::try_from(v).map_err(|_| too_large());
    let mut xadj: Vec<m::idx_t> = degree
        .iter()
        .map(|&d| to_idx(d))
        .collect::<Result<_, _>>()?;
    let mut next = degree;
    let mut adjncy: Vec<m::idx_t> = vec![0; num_adjacent];
    for c in 0..n {
        for &r in pattern.row_idx_of_col_raw(c) {
            if r != c {
                adjncy[next[r]] = c as m::idx_t;
                next[r] += 1;
                adjncy[next[c]] = r as m::idx_t;
                next[c] += 1;
            }
        }
    }
    // METIS's random number generator (GKlib) keeps global state: serialize the calls, and fix the seed so
    // that the ordering is reproducible.
    static METIS_LOCK: Mutex<()> = Mutex::new(());
    let _guard = METIS_LOCK
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let mut nvtxs = to_idx(n)?;
    let mut options = [0 as m::idx_t; m::METIS_NOPTIONS as usize];
    let mut perm: Vec<m::idx_t> = vec![0; n];
    let mut iperm: Vec<m::idx_t> = vec![0; n];
    // SAFETY: `options` has METIS_NOPTIONS entries, as METIS_SetDefaultOptions writes.
    unsafe { m::METIS_SetDefaultOptions(options.as_mut_ptr()) };
    options[m::moptions_et_METIS_OPTION_NUMBERING as usize] = 0;
    options[m::moptions_et_METIS_OPTION_SEED as usize] = 1;
    // SAFETY: `xadj` has n + 1 entries, `adjncy` xadj[n] entries holding vertex ids < n (a valid undirected
    // graph without self-loops: every edge is stored in both directions); `perm` and `iperm` have n entries;
    // the vertex weights are NULL (optional in METIS_NodeND). METIS only reads xadj/adjncy/options and
    // writes perm/iperm; none of the buffers is kept after the call.
    let status = unsafe {
        m::METIS_NodeND(
            &mut nvtxs,
            xadj.as_mut_ptr(),
            adjncy.as_mut_ptr(),
            std::ptr::null_mut(),
            options.as_mut_ptr(),
            perm.as_mut_ptr(),
            iperm.as_mut_ptr(),
        )
    };
    if status != m::rstatus_et_METIS_OK {
        let what = match status {
            s if s == m::rstatus_et_METIS_ERROR_INPUT => "invalid input",
            s if s == m::rstatus_et_METIS_ERROR_MEMORY => "out of memory",
            _ => "error",
        };
        return Err(CholeskyError::Metis(format!(
            "METIS_NodeND returned {status} ({what})"
        )));
    }
    // METIS: row i of P A Pᵀ is row perm[i] of A, i.e. perm = fwd and iperm = inv. Check it is a valid
    // permutation pair before handing it to faer (which would panic otherwise).
    let fwd: Vec<usize> = perm.iter().map(|&p| p as usize).collect();
    let inv: Vec<usize> = iperm.iter().map(|&p| p as usize).collect();
    let valid = fwd
        .iter()
        .enumerate()
        .all(|(new, &old)| old < n && inv[old] == new);
    if !valid {
        return Err(CholeskyError::Metis(
            "METIS_NodeND returned an invalid permutation".into(),
        ));
    }
    Ok((fwd, inv))
}

/// Exact fill of `L` for the ordering `inv` (`inv[old] = new`) of the lower-triangle `pattern`: the
/// elimination tree and column counts of `P A Pᵀ` (faer's simplicial pre-factorization).
fn fill_figures(
    pattern: SymbolicSparseColMatRef<'_, usize>,
    inv: &[usize],
) -> Result<FillFigures, CholeskyError> {
    let n = pattern.nrows();
    // Upper triangle of P A Pᵀ in compressed columns (row indices unsorted).
    let mut col_ptr = vec![0usize; n + 1];
    for c in 0..n {
        for &r in pattern.row_idx_of_col_raw(c) {
            col_ptr[inv[r].max(inv[c]) + 1] += 1;
        }
    }
    for j in 0..n {
        col_ptr[j + 1] += col_ptr[j];
    }
    let mut next = col_ptr.clone();
    let mut row_idx = vec![0usize; col_ptr[n]];
    for c in 0..n {
        for &r in pattern.row_idx_of_col_raw(c) {
            let (i, j) = (inv[r].min(inv[c]), inv[r].max(inv[c]));
            row_idx[next[j]] = i;
            next[j] += 1;
        }
    }
    let upper = SymbolicSparseColMatRef::new_unsorted_checked(n, n, &col_ptr, None, &row_idx);
    let mut etree = vec![0isize; n];
    let mut col_counts = vec![0usize; n];
    let mut buffer = MemBuffer::try_new(
        simplicial::prefactorize_symbolic_cholesky_scratch::<usize>(n, row_idx.len()),
    )
    .map_err(|_| CholeskyError::Analysis("out of memory for the column counts".into()))?;
    simplicial::prefactorize_symbolic_cholesky(
        &mut etree,
        &mut col_counts,
        upper,
        MemStack::new(&mut buffer),
    );
    Ok(FillFigures {
        factor_nnz: col_counts.iter().sum(),
        flops: col_counts.iter().map(|&c| (c as f64) * (c as f64)).sum(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{Real, Vec3};
    use crate::node_block_assembly::NodeBlockAssembler;
    use crate::{NeoHookeanBody, NeoHookeanParams};
    use faer::sparse::{SparseColMat, Triplet};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use skintight_geometry::body::procedural_body::{SphereParams, solid_sphere};

    const ORDERINGS: [Ordering; 3] = [Ordering::Amd, Ordering::Metis, Ordering::Auto];

    fn params(ordering: Ordering) -> SparseCholeskyParams {
        SparseCholeskyParams {
            ordering,
            ..Default::default()
        }
    }

    /// Lower triangle (row ≥ column) of a symmetric matrix given by lower-triangle triplets.
    fn lower(n: usize, entries: &[(usize, usize, f64)]) -> SparseColMat<usize, f64> {
        let triplets: Vec<_> = entries
            .iter()
            .map(|&(r, c, v)| Triplet::new(r.max(c), r.min(c), v))
            .collect();
        SparseColMat::try_new_from_triplets(n, n, &triplets).unwrap()
    }

    /// Weighted graph Laplacian of a `dims[0] × dims[1] × dims[2]` grid (random positive edge weights in
    /// [0.5, 2]) plus `shift · I` (random per-entry shift in [shift, 2 shift]): SPD for `shift > 0`.
    fn grid_laplacian(
        dims: [usize; 3],
        shift: f64,
        rng: &mut ChaCha8Rng,
    ) -> SparseColMat<usize, f64> {
        let id = |i: usize, j: usize, k: usize| i + dims[0] * (j + dims[1] * k);
        let n = dims.iter().product();
        let mut entries = Vec::new();
        let mut diagonal = vec![0.0; n];
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let a = id(i, j, k);
                    let mut neighbours = Vec::new();
                    if i + 1 < dims[0] {
                        neighbours.push(id(i + 1, j, k));
                    }
                    if j + 1 < dims[1] {
                        neighbours.push(id(i, j + 1, k));
                    }
                    if k + 1 < dims[2] {
                        neighbours.push(id(i, j, k + 1));
                    }
                    for b in neighbours {
                        let w = rng.random_range(0.5..2.0);
                        entries.push((b, a, -w));
                        diagonal[a] += w;
                        diagonal[b] += w;
                    }
                }
            }
        }
        for (i, d) in diagonal.iter().enumerate() {
            entries.push((i, i, d + shift * rng.random_range(1.0..2.0)));
        }
        lower(n, &entries)
    }

    /// `A x` for the symmetric `A` whose lower triangle `a` holds.
    fn symmetric_mul(a: SparseColMatRef<'_, usize, f64>, x: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; x.len()];
        for c in 0..a.ncols() {
            for (&r, &v) in a.row_idx_of_col_raw(c).iter().zip(a.val_of_col(c)) {
                y[r] += v * x[c];
                if r != c {
                    y[c] += v * x[r];
                }
            }
        }
        y
    }

    fn norm(v: &[f64]) -> f64 {
        v.iter().map(|x| x * x).sum::<f64>().sqrt()
    }

    /// ‖A x − b‖ / ‖b‖ after solving with `chol`.
    fn relative_residual(
        chol: &SparseCholesky,
        a: SparseColMatRef<'_, usize, f64>,
        b: &[f64],
    ) -> f64 {
        let mut x = b.to_vec();
        chol.solve_in_place(&mut x).unwrap();
        let ax = symmetric_mul(a, &x);
        let r: Vec<f64> = ax.iter().zip(b).map(|(p, q)| p - q).collect();
        norm(&r) / norm(b)
    }

    /// Tolerance on the relative residual, scaled with the size (rounding grows with `n` and the
    /// condition number, which grows with the grid size).
    fn tolerance(n: usize) -> f64 {
        1e-10 * (n as f64 / 1000.0).max(1.0)
    }

    fn random_vector(n: usize, rng: &mut ChaCha8Rng) -> Vec<f64> {
        (0..n).map(|_| rng.random_range(-1.0..1.0)).collect()
    }

    /// Hessian (N/m, lower triangle) of a Neo-Hookean ball of radius 0.1 m with `resolution³ · 6` tets, its
    /// bottom cap fixed, at a random perturbation of the rest state, PSD projection on, plus
    /// `shift · mean(diag)` on the diagonal. Returns the assembler (to reassemble at other states), the
    /// body and the state.
    fn neo_hookean_hessian(
        resolution: usize,
        shift: f64,
        rng: &mut ChaCha8Rng,
    ) -> (NodeBlockAssembler, NeoHookeanBody, Vec<Real>) {
        let radius = 0.1;
        let mesh = solid_sphere(&SphereParams { radius, resolution }).unwrap();
        let fixed: Vec<bool> = mesh.positions.iter().map(|p| p.z < -0.8 * radius).collect();
        let params = NeoHookeanParams {
            project_psd: true,
            ..Default::default()
        };
        let body = NeoHookeanBody::new(&mesh.positions, &mesh.tets, &fixed, &params).unwrap();
        let h = 2.0 * radius / resolution as Real;
        let perturbed: Vec<Vec3> = mesh
            .positions
            .iter()
            .map(|p| {
                p + Vec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                ) * 0.1
                    * h
            })
            .collect();
        let x = body.dofs_from_positions(&perturbed);
        let mut assembler = body.hessian_assembler();
        body.assemble_hessian(&x, &mut assembler).unwrap();
        let n = body.num_dofs();
        let mean_diagonal = (0..n)
            .map(|i| assembler.matrix().val_of_col(i)[0])
            .sum::<f64>()
            / n as f64;
        assembler.add_diagonal(&vec![shift * mean_diagonal; n]);
        (assembler, body, x)
    }

    /// Orderings computed on the graph of node groups solve the same systems as the plain ones, keep each
    /// group's unknowns together, and bad groups are refused.
    #[test]
    fn grouped_orderings_solve_the_same_systems() {
        for (seed, nodes) in [(21u64, 5usize), (22, 40), (23, 150)] {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let mut starts = vec![0usize];
            for _ in 0..nodes {
                let dim = rng.random_range(1..=3);
                starts.push(starts.last().unwrap() + dim);
            }
            let n = *starts.last().unwrap();
            // SPD: node-blocked random couplings, made diagonally dominant.
            let mut dense = vec![0.0_f64; n * n];
            for _ in 0..3 * nodes {
                let (a, b) = (rng.random_range(0..nodes), rng.random_range(0..nodes));
                for i in starts[a]..starts[a + 1] {
                    for j in starts[b]..starts[b + 1] {
                        let v = rng.random_range(-1.0..1.0);
                        dense[i * n + j] += v;
                        dense[j * n + i] += v;
                    }
                }
            }
            for i in 0..n {
                let off: f64 = (0..n)
                    .filter(|&j| j != i)
                    .map(|j| dense[i * n + j].abs())
                    .sum();
                dense[i * n + i] = off + 1.0;
            }
            let entries: Vec<(usize, usize, f64)> = (0..n)
                .flat_map(|c| (c..n).map(move |r| (r, c)))
                .filter(|&(r, c)| dense[r * n + c] != 0.0)
                .map(|(r, c)| (r, c, dense[r * n + c]))
                .collect();
            let a = lower(n, &entries);
            let b: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..1.0)).collect();
            for ordering in [Ordering::Amd, Ordering::Metis, Ordering::Auto] {
                let mut plain = SparseCholesky::analyze(a.as_ref(), &params(ordering)).unwrap();
                let mut grouped =
                    SparseCholesky::analyze_grouped(a.as_ref(), Some(&starts), &params(ordering))
                        .unwrap();
                plain.factorize(a.as_ref()).unwrap();
                grouped.factorize(a.as_ref()).unwrap();
                let (mut x, mut y) = (b.clone(), b.clone());
                plain.solve_in_place(&mut x).unwrap();
                grouped.solve_in_place(&mut y).unwrap();
                let scale = x.iter().fold(0.0_f64, |m, v| m.max(v.abs())).max(1.0);
                for (u, v) in x.iter().zip(&y) {
                    assert!(
                        (u - v).abs() <= 1e-10 * scale * n as f64,
                        "{ordering:?}: {u} vs {v}"
                    );
                }
            }
            for bad in [vec![0, n + 1], vec![1, n], vec![0, 0, n]] {
                assert!(matches!(
                    SparseCholesky::analyze_grouped(a.as_ref(), Some(&bad), &params(Ordering::Amd)),
                    Err(CholeskyError::Analysis(_))
                ));
            }
        }
    }

    #[test]
    fn random_spd_grid_laplacians_are_solved_to_round_off_with_every_ordering() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for dims in [
            [1, 1, 1],
            [7, 1, 1],
            [12, 9, 1],
            [40, 40, 1],
            [6, 7, 8],
            [14, 14, 14],
        ] {
            let a = grid_laplacian(dims, 1e-2, &mut rng);
            let n = a.nrows();
            let b = random_vector(n, &mut rng);
            for ordering in ORDERINGS {
                let mut chol = SparseCholesky::analyze(a.as_ref(), &params(ordering)).unwrap();
                assert_eq!(chol.dimension(), n);
                assert_ne!(chol.ordering_used(), Ordering::Auto);
                if ordering != Ordering::Auto {
                    assert_eq!(chol.ordering_used(), ordering);
                }
                chol.factorize(a.as_ref()).unwrap();
                let residual = relative_residual(&chol, a.as_ref(), &b);
                assert!(
                    residual < tolerance(n),
                    "{dims:?} {ordering:?}: residual {residual:e}"
                );
                assert!(chol.factor_nnz() >= n);
                assert!(chol.factor_storage_len() >= chol.factor_nnz());
            }
        }
    }

    #[test]
    fn neo_hookean_sphere_hessian_is_solved_to_round_off_with_every_ordering() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for resolution in [3, 6] {
            let (assembler, _, _) = neo_hookean_hessian(resolution, 1e-3, &mut rng);
            let a = assembler.matrix();
            let n = a.nrows();
            let b = random_vector(n, &mut rng);
            for ordering in ORDERINGS {
                let mut chol = SparseCholesky::analyze(a.as_ref(), &params(ordering)).unwrap();
                chol.factorize(a.as_ref()).unwrap();
                let residual = relative_residual(&chol, a.as_ref(), &b);
                assert!(
                    residual < tolerance(n),
                    "resolution {resolution}, {ordering:?}: residual {residual:e}"
                );
            }
        }
    }

    #[test]
    fn refactorizing_new_values_on_the_same_pattern_solves_the_new_system() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let (mut assembler, body, x) = neo_hookean_hessian(4, 1e-3, &mut rng);
        let first = assembler.matrix().clone();
        let n = first.nrows();
        let b = random_vector(n, &mut rng);
        for ordering in ORDERINGS {
            let mut chol = SparseCholesky::analyze(first.as_ref(), &params(ordering)).unwrap();
            chol.factorize(first.as_ref()).unwrap();
            let mut x_first = b.clone();
            chol.solve_in_place(&mut x_first).unwrap();

            // Another state (a uniform stretch of the perturbed one) and a larger shift: new values, same
            // pattern.
            let stretched: Vec<Real> = x.iter().map(|v| 1.05 * v).collect();
            body.assemble_hessian(&stretched, &mut assembler).unwrap();
            let second = assembler.matrix().clone();
            let mut shifted = second.clone();
            for c in 0..n {
                let start = shifted.symbolic().col_ptr()[c];
                shifted.val_mut()[start] += 10.0 * (c as f64 + 1.0);
            }
            assert!(chol.pattern_matches(shifted.as_ref()));
            chol.factorize(shifted.as_ref()).unwrap();
            let residual = relative_residual(&chol, shifted.as_ref(), &b);
            assert!(
                residual < tolerance(n),
                "{ordering:?}: residual {residual:e}"
            );
            let mut x_second = b.clone();
            chol.solve_in_place(&mut x_second).unwrap();
            let change = norm(
                &x_first
                    .iter()
                    .zip(&x_second)
                    .map(|(p, q)| p - q)
                    .collect::<Vec<_>>(),
            );
            assert!(
                change > 1e-6 * norm(&x_first),
                "the solution did not change"
            );

            // And back: the first values give the first solution again.
            chol.factorize(first.as_ref()).unwrap();
            let mut x_again = b.clone();
            chol.solve_in_place(&mut x_again).unwrap();
            for (p, q) in x_again.iter().zip(&x_first) {
                assert!((p - q).abs() <= 1e-12 * norm(&x_first));
            }
        }
    }

    #[test]
    fn pattern_matches_accepts_new_values_and_rejects_other_patterns() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let a = grid_laplacian([5, 4, 3], 1.0, &mut rng);
        let mut chol = SparseCholesky::analyze(a.as_ref(), &params(Ordering::Amd)).unwrap();
        let mut same_pattern = a.clone();
        same_pattern.val_mut().iter_mut().for_each(|v| *v *= 2.0);
        assert!(chol.pattern_matches(a.as_ref()));
        assert!(chol.pattern_matches(same_pattern.as_ref()));

        let other_grid = grid_laplacian([4, 5, 3], 1.0, &mut rng); // same n, other pattern
        assert_eq!(other_grid.nrows(), a.nrows());
        assert!(!chol.pattern_matches(other_grid.as_ref()));
        let bigger = grid_laplacian([5, 4, 4], 1.0, &mut rng);
        assert!(!chol.pattern_matches(bigger.as_ref()));
        let diagonal = lower(
            a.nrows(),
            &(0..a.nrows()).map(|i| (i, i, 1.0)).collect::<Vec<_>>(),
        );
        assert!(!chol.pattern_matches(diagonal.as_ref()));

        // factorize refuses another pattern with an error, never a panic.
        assert_eq!(
            chol.factorize(other_grid.as_ref()),
            Err(CholeskyError::PatternMismatch)
        );
        assert!(matches!(
            chol.factorize(bigger.as_ref()),
            Err(CholeskyError::DimensionMismatch { what: "matrix", .. })
        ));
        chol.factorize(same_pattern.as_ref()).unwrap();
    }

    /// faer's own path for `chol`'s analysis: `factorize_numeric_llt` (which permutes `matrix` itself)
    /// into a fresh value array; the factor values or the failing pivot.
    fn faer_factor(
        chol: &SparseCholesky,
        matrix: SparseColMatRef<'_, usize, f64>,
    ) -> Result<Vec<f64>, usize> {
        let mut values = vec![0.0; chol.symbolic.len_val()];
        let req = chol
            .symbolic
            .factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default());
        let mut buffer = MemBuffer::new(req);
        match chol.symbolic.factorize_numeric_llt::<f64>(
            &mut values,
            matrix,
            Side::Lower,
            LltRegularization::default(),
            Par::Seq,
            MemStack::new(&mut buffer),
            Default::default(),
        ) {
            Ok(_) => Ok(values),
            Err(LltError::NonPositivePivot { index }) => Err(index),
        }
    }

    /// The supernodal factorization of `P A Pᵀ` gathered with the analysis ([`SymmetricPermutation`]) is
    /// faer's own factorization to the bit, and an indefinite matrix fails at the same pivot: on a Neo-Hookean
    /// Hessian (blocked, METIS and AMD) and a grid Laplacian, both supernodal.
    #[test]
    fn the_gathered_permutation_factors_as_faers_own_to_the_bit() {
        let mut rng = ChaCha8Rng::seed_from_u64(21);
        let (assembler, _, _) = neo_hookean_hessian(6, 1e-3, &mut rng);
        let grid = grid_laplacian([12, 12, 12], 1e-2, &mut rng);
        for a in [assembler.matrix().clone(), grid] {
            for ordering in [Ordering::Amd, Ordering::Metis] {
                let mut chol = SparseCholesky::analyze(a.as_ref(), &params(ordering)).unwrap();
                assert!(
                    chol.is_supernodal() && chol.permuted.is_some(),
                    "{ordering:?}"
                );
                chol.factorize(a.as_ref()).unwrap();
                let theirs = faer_factor(&chol, a.as_ref()).unwrap();
                assert!(
                    chol.values
                        .iter()
                        .zip(&theirs)
                        .all(|(x, y)| x.to_bits() == y.to_bits()),
                    "{ordering:?}: the factors differ"
                );
                // Shifted down until indefinite: the same failing pivot.
                let mut indefinite = a.clone();
                let slots: Vec<usize> = (0..a.nrows())
                    .map(|c| {
                        let range = a.symbolic().col_range(c);
                        range.start
                            + a.symbolic()
                                .row_idx_of_col_raw(c)
                                .iter()
                                .position(|&r| r == c)
                                .unwrap()
                    })
                    .collect();
                let mean = slots.iter().map(|&k| a.val()[k]).sum::<f64>() / slots.len() as f64;
                for &k in &slots {
                    indefinite.val_mut()[k] -= 0.5 * mean;
                }
                let Err(CholeskyError::NotPositiveDefinite { pivot, .. }) =
                    chol.factorize(indefinite.as_ref())
                else {
                    panic!("{ordering:?}: the shifted matrix factored");
                };
                assert_eq!(
                    Err(pivot),
                    faer_factor(&chol, indefinite.as_ref()).map(|_| ())
                );
            }
        }
    }

    /// Side by side, alternating: one numeric factorization through the gather against faer's own
    /// permutation, on the Neo-Hookean ball Hessian (METIS). Prints the medians and their ratio.
    /// `cargo test --release -p skintight-physics gathered_permutation_timing -- --ignored --nocapture`
    #[test]
    #[ignore = "timing, run by hand"]
    fn gathered_permutation_timing() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let (assembler, _, _) = neo_hookean_hessian(12, 1e-3, &mut rng);
        let a = assembler.matrix();
        let mut chol = SparseCholesky::analyze(a.as_ref(), &params(Ordering::Metis)).unwrap();
        let (mut ours, mut theirs) = (Vec::new(), Vec::new());
        for _ in 0..30 {
            let t = std::time::Instant::now();
            chol.factorize(a.as_ref()).unwrap();
            ours.push(t.elapsed().as_secs_f64());
            let t = std::time::Instant::now();
            faer_factor(&chol, a.as_ref()).unwrap();
            theirs.push(t.elapsed().as_secs_f64());
        }
        let median = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let (o, t) = (median(&mut ours), median(&mut theirs));
        println!(
            "n = {}, nnz(A) = {}, nnz(L) = {}: gather {:.2} ms, faer's permutation {:.2} ms, ratio {:.3}",
            a.nrows(),
            a.compute_nnz(),
            chol.factor_nnz(),
            1e3 * o,
            1e3 * t,
            o / t
        );
    }

    #[test]
    fn indefinite_matrix_gives_not_positive_definite_and_a_shift_recovers() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        for ordering in ORDERINGS {
            // Laplacian (eigenvalues in [0, 12)) shifted by −1 per diagonal entry: indefinite.
            let a = grid_laplacian([8, 8, 8], 1e-2, &mut rng);
            let mut indefinite = a.clone();
            let mut spd = a.clone();
            for c in 0..a.nrows() {
                let start = a.symbolic().col_ptr()[c];
                indefinite.val_mut()[start] -= 1.0;
                spd.val_mut()[start] += 1.0;
            }
            let mut chol = SparseCholesky::analyze(a.as_ref(), &params(ordering)).unwrap();
            chol.factorize(spd.as_ref()).unwrap();
            let err = chol.factorize(indefinite.as_ref()).unwrap_err();
            let CholeskyError::NotPositiveDefinite { pivot, unknown } = err else {
                panic!("{ordering:?}: expected NotPositiveDefinite, got {err:?}");
            };
            assert!(pivot < a.nrows() && unknown < a.nrows());
            assert!(err.to_string().contains("not positive definite"));
            // The failed factorization is not used for solves.
            let mut rhs = vec![1.0; a.nrows()];
            assert_eq!(
                chol.solve_in_place(&mut rhs),
                Err(CholeskyError::NotFactorized)
            );
            assert!(!chol.is_factorized());
            // Damping more (the Newton solver's retry) succeeds on the same symbolic analysis.
            chol.factorize(spd.as_ref()).unwrap();
            let b = random_vector(a.nrows(), &mut rng);
            assert!(relative_residual(&chol, spd.as_ref(), &b) < tolerance(a.nrows()));
        }
        // A 2 × 2 indefinite matrix and a zero matrix.
        let small = lower(2, &[(0, 0, 1.0), (1, 0, 2.0), (1, 1, 1.0)]);
        let zero = lower(3, &[(0, 0, 0.0), (1, 1, 0.0), (2, 2, 0.0)]);
        for m in [small, zero] {
            let mut chol = SparseCholesky::analyze(m.as_ref(), &Default::default()).unwrap();
            assert!(matches!(
                chol.factorize(m.as_ref()),
                Err(CholeskyError::NotPositiveDefinite { .. })
            ));
        }
    }

    /// `reanalyze` keeps the earlier analysis's ordering: on the same pattern it factors to the same bits,
    /// on a grown pattern (a new coupling, as a contact adds) it solves to round-off, and it checks its
    /// input.
    #[test]
    fn reanalyzing_keeps_the_ordering_and_solves_the_new_pattern() {
        let mut rng = ChaCha8Rng::seed_from_u64(14);
        for (dims, ordering) in [([12, 12, 12], Ordering::Metis), ([6, 5, 4], Ordering::Amd)] {
            let a = grid_laplacian(dims, 1e-2, &mut rng);
            let n = a.nrows();
            let chol = SparseCholesky::analyze(a.as_ref(), &params(ordering)).unwrap();
            let perm = |c: &SparseCholesky| {
                let p = c.symbolic.perm().expect("a fill-reducing permutation");
                (p.arrays().0.to_vec(), p.arrays().1.to_vec())
            };
            // The same pattern: the same permutation, the same factor.
            let mut again = chol.reanalyze(a.as_ref(), &params(Ordering::Auto)).unwrap();
            assert_eq!(perm(&again), perm(&chol));
            assert_eq!(again.ordering_used(), chol.ordering_used());
            let mut first = chol;
            first.factorize(a.as_ref()).unwrap();
            again.factorize(a.as_ref()).unwrap();
            assert!(
                first
                    .values
                    .iter()
                    .zip(&again.values)
                    .all(|(x, y)| x.to_bits() == y.to_bits())
            );
            // Couplings between far unknowns (outside the first pattern): still solved, same ordering.
            let mut entries = Vec::new();
            for c in 0..n {
                for (&r, &v) in a
                    .symbolic()
                    .row_idx_of_col_raw(c)
                    .iter()
                    .zip(a.val_of_col(c))
                {
                    entries.push((r, c, v));
                }
            }
            for k in 0..20 {
                let (i, j) = ((k * 37) % n, (k * 101 + n / 2) % n);
                if i != j {
                    entries.push((i.max(j), i.min(j), -0.1));
                    entries.push((i, i, 0.1));
                    entries.push((j, j, 0.1));
                }
            }
            let grown = lower(n, &entries);
            assert!(!first.pattern_matches(grown.as_ref()));
            let mut stale = first.reanalyze(grown.as_ref(), &params(ordering)).unwrap();
            assert_eq!(perm(&stale), perm(&first));
            assert!(stale.pattern_matches(grown.as_ref()));
            stale.factorize(grown.as_ref()).unwrap();
            let b = random_vector(n, &mut rng);
            assert!(relative_residual(&stale, grown.as_ref(), &b) < tolerance(n));
            // Another dimension, an upper triangle: errors.
            let other = grid_laplacian([3, 3, 3], 1.0, &mut rng);
            assert!(matches!(
                first.reanalyze(other.as_ref(), &params(ordering)),
                Err(CholeskyError::DimensionMismatch { .. })
            ));
            let upper = SparseColMat::<usize, f64>::try_new_from_triplets(
                n,
                n,
                &[Triplet::new(0, 1, 1.0), Triplet::new(1, 1, 1.0)],
            )
            .unwrap();
            assert!(matches!(
                first.reanalyze(upper.as_ref(), &params(ordering)),
                Err(CholeskyError::NotLowerTriangular { .. })
            ));
        }
    }

    #[test]
    fn non_finite_entries_are_rejected_before_factorizing() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let a = grid_laplacian([4, 4, 1], 1.0, &mut rng);
        let mut chol = SparseCholesky::analyze(a.as_ref(), &Default::default()).unwrap();
        for bad in [f64::NAN, f64::INFINITY] {
            let mut m = a.clone();
            m.val_mut()[3] = bad;
            assert!(matches!(
                chol.factorize(m.as_ref()),
                Err(CholeskyError::NonFiniteValue { .. })
            ));
        }
    }

    #[test]
    fn wrong_rhs_length_and_missing_factorization_are_errors() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let a = grid_laplacian([6, 5, 1], 1.0, &mut rng);
        let n = a.nrows();
        let mut chol = SparseCholesky::analyze(a.as_ref(), &Default::default()).unwrap();
        let mut rhs = vec![1.0; n];
        assert_eq!(
            chol.solve_in_place(&mut rhs),
            Err(CholeskyError::NotFactorized)
        );
        chol.factorize(a.as_ref()).unwrap();
        for len in [0, n - 1, n + 1] {
            let mut wrong = vec![1.0; len];
            let err = chol.solve_in_place(&mut wrong).unwrap_err();
            assert_eq!(
                err,
                CholeskyError::DimensionMismatch {
                    what: "right-hand side",
                    got: len,
                    expected: n
                }
            );
            assert!(wrong.iter().all(|&v| v == 1.0), "rhs must stay unchanged");
        }
        chol.solve_in_place(&mut rhs).unwrap();
    }

    #[test]
    fn solving_columns_at_once_equals_solving_them_one_by_one() {
        for (seed, dims) in [(3_u64, [5, 4, 1]), (4, [7, 6, 3]), (5, [9, 8, 4])] {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let a = grid_laplacian(dims, 1.0, &mut rng);
            let n = a.nrows();
            let mut chol = SparseCholesky::analyze(a.as_ref(), &Default::default()).unwrap();
            let columns = 5;
            let mut block = vec![0.0; n * columns];
            assert_eq!(
                chol.solve_columns_in_place(&mut block, columns),
                Err(CholeskyError::NotFactorized)
            );
            chol.factorize(a.as_ref()).unwrap();
            let b: Vec<f64> = (0..columns)
                .flat_map(|_| random_vector(n, &mut rng))
                .collect();
            block.copy_from_slice(&b);
            chol.solve_columns_in_place(&mut block, columns).unwrap();
            for c in 0..columns {
                let mut x = b[c * n..(c + 1) * n].to_vec();
                chol.solve_in_place(&mut x).unwrap();
                let scale = norm(&x).max(1.0);
                let diff: f64 = x
                    .iter()
                    .zip(&block[c * n..(c + 1) * n])
                    .map(|(p, q)| (p - q).powi(2))
                    .sum::<f64>()
                    .sqrt();
                assert!(diff <= 1e-12 * scale * n as f64, "column {c}: {diff}");
            }
            let mut wrong = vec![1.0; n * columns - 1];
            assert!(matches!(
                chol.solve_columns_in_place(&mut wrong, columns),
                Err(CholeskyError::DimensionMismatch { .. })
            ));
            assert!(wrong.iter().all(|&v| v == 1.0));
            chol.solve_columns_in_place(&mut [], 0).unwrap();
        }
    }

    #[test]
    fn solving_columns_split_across_threads_equals_one_sweep() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let a = grid_laplacian([9, 8, 4], 1.0, &mut rng);
        let n = a.nrows();
        let mut chol = SparseCholesky::analyze(a.as_ref(), &Default::default()).unwrap();
        let columns = 3 * MIN_COLUMNS_PER_THREAD + 5;
        let b: Vec<f64> = (0..columns)
            .flat_map(|_| random_vector(n, &mut rng))
            .collect();
        let mut block = b.clone();
        assert_eq!(
            chol.solve_columns_in_place_on(&mut block, columns, 2),
            Err(CholeskyError::NotFactorized)
        );
        chol.factorize(a.as_ref()).unwrap();
        let mut one = b.clone();
        chol.solve_columns_in_place(&mut one, columns).unwrap();
        // 2 and 3 threads (uneven blocks), more threads than blocks of 16 columns allow, and 1.
        for threads in [2, 3, 8, 1] {
            let mut split = b.clone();
            chol.solve_columns_in_place_on(&mut split, columns, threads)
                .unwrap();
            for c in 0..columns {
                let (x, y) = (&one[c * n..(c + 1) * n], &split[c * n..(c + 1) * n]);
                let diff: f64 = x
                    .iter()
                    .zip(y)
                    .map(|(p, q)| (p - q).powi(2))
                    .sum::<f64>()
                    .sqrt();
                assert!(
                    diff <= 1e-12 * norm(x).max(1.0),
                    "{threads} threads, column {c}: {diff}"
                );
            }
        }
        let mut wrong = vec![1.0; n * columns - 1];
        assert!(matches!(
            chol.solve_columns_in_place_on(&mut wrong, columns, 2),
            Err(CholeskyError::DimensionMismatch { .. })
        ));
        assert!(wrong.iter().all(|&v| v == 1.0));
    }

    #[test]
    fn analyze_rejects_non_square_and_upper_triangle_input() {
        let rect = SparseColMat::<usize, f64>::try_new_from_triplets(
            3,
            2,
            &[Triplet::new(0, 0, 1.0), Triplet::new(1, 1, 1.0)],
        )
        .unwrap();
        assert_eq!(
            SparseCholesky::analyze(rect.as_ref(), &Default::default()).unwrap_err(),
            CholeskyError::NotSquare { rows: 3, cols: 2 }
        );
        let upper = SparseColMat::<usize, f64>::try_new_from_triplets(
            2,
            2,
            &[
                Triplet::new(0, 0, 2.0),
                Triplet::new(0, 1, 1.0),
                Triplet::new(1, 1, 2.0),
            ],
        )
        .unwrap();
        assert_eq!(
            SparseCholesky::analyze(upper.as_ref(), &Default::default()).unwrap_err(),
            CholeskyError::NotLowerTriangular { row: 0, col: 1 }
        );
    }

    #[test]
    fn empty_and_diagonal_matrices_are_handled() {
        let empty = lower(0, &[]);
        for ordering in ORDERINGS {
            let mut chol = SparseCholesky::analyze(empty.as_ref(), &params(ordering)).unwrap();
            chol.factorize(empty.as_ref()).unwrap();
            chol.solve_in_place(&mut []).unwrap();
            let diagonal = lower(3, &[(0, 0, 2.0), (1, 1, 4.0), (2, 2, 8.0)]);
            let mut chol = SparseCholesky::analyze(diagonal.as_ref(), &params(ordering)).unwrap();
            chol.factorize(diagonal.as_ref()).unwrap();
            let mut rhs = [2.0, 2.0, 2.0];
            chol.solve_in_place(&mut rhs).unwrap();
            for (x, expected) in rhs.iter().zip([1.0, 0.5, 0.25]) {
                assert!((x - expected).abs() < 1e-15);
            }
            assert_eq!(chol.factor_nnz(), 3);
        }
    }

    #[test]
    fn auto_keeps_the_ordering_with_the_smaller_factor() {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let (sphere, _, _) = neo_hookean_hessian(6, 1e-3, &mut rng);
        let matrices = [
            grid_laplacian([30, 30, 1], 1e-2, &mut rng),
            grid_laplacian([16, 16, 16], 1e-2, &mut rng),
            sphere.matrix().clone(),
        ];
        for a in &matrices {
            let auto = SparseCholesky::analyze(a.as_ref(), &params(Ordering::Auto)).unwrap();
            let amd = auto.fill(Ordering::Amd).unwrap();
            let metis = auto.fill(Ordering::Metis).unwrap();
            assert!(auto.metis_failure().is_none());
            let expected = if metis.factor_nnz < amd.factor_nnz {
                Ordering::Metis
            } else {
                Ordering::Amd
            };
            assert_eq!(auto.ordering_used(), expected);
            assert_eq!(auto.factor_nnz(), amd.factor_nnz.min(metis.factor_nnz));
            // The single-ordering analyses report the same figures.
            for (ordering, figures) in [(Ordering::Amd, amd), (Ordering::Metis, metis)] {
                let single = SparseCholesky::analyze(a.as_ref(), &params(ordering)).unwrap();
                assert_eq!(single.fill(ordering), Some(figures));
                assert_eq!(single.factor_nnz(), figures.factor_nnz);
                assert!(single.fill(Ordering::Auto).is_some());
            }
        }
    }

    #[test]
    fn metis_permutation_reduces_fill_far_below_the_natural_order() {
        // A wrong permutation convention (perm and its inverse swapped) would scramble the nested
        // dissection and give more fill than the banded natural order of a 3D grid.
        let mut rng = ChaCha8Rng::seed_from_u64(6);
        let a = grid_laplacian([15, 15, 15], 1.0, &mut rng);
        let n = a.nrows();
        let identity: Vec<usize> = (0..n).collect();
        let natural = fill_figures(a.symbolic(), &identity).unwrap();
        let chol = SparseCholesky::analyze(a.as_ref(), &params(Ordering::Metis)).unwrap();
        let metis = chol.fill(Ordering::Metis).unwrap();
        assert!(
            (metis.factor_nnz as f64) < 0.5 * natural.factor_nnz as f64,
            "METIS {metis:?} vs natural {natural:?}"
        );
        assert!(metis.flops < 0.2 * natural.flops);
        // The natural order fills at most the band (half-bandwidth 15²) of the grid.
        let band = 15 * 15;
        let full_band: usize = (0..n).map(|j| (n - j).min(band + 1)).sum();
        assert!(natural.factor_nnz <= full_band && natural.factor_nnz > full_band * 9 / 10);
    }

    #[test]
    fn multithreaded_factorization_matches_the_sequential_one() {
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        let (assembler, _, _) = neo_hookean_hessian(5, 1e-3, &mut rng);
        let a = assembler.matrix();
        let b = random_vector(a.nrows(), &mut rng);
        let mut solutions = Vec::new();
        for threads in [None, Some(2)] {
            let p = SparseCholeskyParams {
                ordering: Ordering::Metis,
                threads,
            };
            let mut chol = SparseCholesky::analyze(a.as_ref(), &p).unwrap();
            chol.factorize(a.as_ref()).unwrap();
            let mut x = b.clone();
            chol.solve_in_place(&mut x).unwrap();
            solutions.push(x);
        }
        for (p, q) in solutions[0].iter().zip(&solutions[1]) {
            assert!((p - q).abs() <= 1e-10 * norm(&solutions[0]));
        }
    }

    #[test]
    fn ordering_and_params_serialize_in_lowercase() {
        for (ordering, name) in [
            (Ordering::Amd, "\"amd\""),
            (Ordering::Metis, "\"metis\""),
            (Ordering::Auto, "\"auto\""),
        ] {
            assert_eq!(serde_json::to_string(&ordering).unwrap(), name);
            assert_eq!(serde_json::from_str::<Ordering>(name).unwrap(), ordering);
        }
        let p: SparseCholeskyParams = serde_json::from_str(r#"{"ordering": "metis"}"#).unwrap();
        assert_eq!(p.ordering, Ordering::Metis);
        assert_eq!(p.threads, None);
        assert_eq!(SparseCholeskyParams::default().ordering, Ordering::Auto);
    }
}
