//! Damped Newton minimisation of a yarn energy with the workspace's sparse Cholesky
//! ([`skintight_physics::SparseCholesky`]).
//!
//! One iteration at `x` with energy `E`, gradient `g`, Hessian `H`:
//! 1. factor `H + (μ + μ₀) D` with `D = diag(max(|H_ii|, 10⁻¹²·max|H_ii|))` (Levenberg–Marquardt scaling, so `μ`
//!    is dimensionless and means the same for positions and angles) and `μ₀ = 10⁻¹⁰` a floor that removes
//!    the exact null modes (rigid translation of a periodic cell; a global spin of the material frames when
//!    the rest curvature is zero). If the factorization fails (`H` indefinite — rods under compression,
//!    contact), `μ ← max(10 μ, 10⁻⁶)` and factor again;
//! 2. `h = −(H + (μ+μ₀)D)⁻¹ g`, scaled down to the problem's step limit ([`NewtonProblem::step_scale`]: a
//!    quarter radius per vertex for yarns, so a step cannot jump a yarn through another);
//! 3. backtracking on the energy (Armijo, `c = 10⁻⁴`, at most 8 halvings); when it fails `μ` grows ×10 and
//!    the iteration repeats; a taken step divides `μ` by 3 (to 0 below 10⁻⁸).
//!
//! **Cost per iteration** (issue 19: the 16 × 16-cell hanging patch, 102 400 unknowns, ~1.6 M entries in
//! the lower triangle; figures in docs/BENCHMARKS.md):
//! - the trial points of step 3 evaluate the energy alone ([`NewtonProblem::energy`]: no jets, ~10× cheaper
//!   than an evaluation with the Hessian); the gradient is evaluated only where Armijo fails but the trial
//!   lies in the rounding band, for the residual test there. The accepted point then gets one evaluation
//!   with the Hessian, as before;
//! - the Hessian's triplets become compressed columns once per iteration (a counting sort on the columns),
//!   with every diagonal entry present; the shifts of step 1 only change the diagonal of a copy of the
//!   values, so a failed factorization costs the numeric factorization alone;
//! - the symbolic analysis (the fill-reducing ordering on the graph of the problem's unknown groups —
//!   [`NewtonProblem::group_size`], 4 per yarn vertex — and the supernodal structure) is kept in a
//!   [`NewtonWorkspace`] with its pattern and reused while the new matrix lies in that pattern (its
//!   values scattered in, explicit zeros elsewhere); when an entry falls outside, the union of the two
//!   patterns is analyzed (the fresh pattern alone once the union has 25 % more entries), so pairs that
//!   touch, part and touch again stop costing analyses. On the 16 × 16 patch this reuse covers the shift
//!   retries only: every Newton step moves up to a quarter radius per coordinate, and some 20–70 segment
//!   pairs (~1000 entries) come into contact per iteration from beyond any margin that would not bloat
//!   the factor (candidates within 1.25 D in the pattern: 76 % more triplets, 3.5× the factorization
//!   time); on small patches whole steps run on one analysis. Each analysis orders afresh (AMD): kept
//!   for the next, an ordering fills fast as the contacts move — one time step of the 16 × 16 hang later,
//!   1.6× the fresh ordering's factor and 2.3× its factorization time (`examples/factor_orderings.rs`,
//!   [`SparseCholesky::reanalyze`]) — and METIS, with 32 % fewer flops, factors only 16 % faster while its
//!   ordering costs 0.1 s more an analysis, about even at an analysis every other iteration;
//! - `μ` starts from where the previous solve on the same workspace ended (the time steps of one run).
//!   Why: on the hanging patch the shift that factors settles at 10⁻²–4·10⁻², and the climb from 0
//!   (0, 10⁻⁶, …, 10⁻²) cost 5 failed factorizations at the start of every step. Within a solve the
//!   ÷3 / ×10 rule stays, although it falls below the working shift every other iteration there (the
//!   measured sequence 10⁻², 3.3·10⁻², 1.1·10⁻², 3.7·10⁻², …: 3 failed factorizations in 6 iterations):
//!   keeping a raised shift for the next iteration instead (tried) ratchets `μ` up whenever every
//!   iteration needs a raise — the sphere-drape scene then stalled at 400 iterations a step — and a failed
//!   factorization now costs only the numeric factorization (about a tenth of an iteration).
//!
//! [`NewtonParams`] can switch each of these off (`energy_line_search`, `reuse_analysis`, `warm_shift`)
//! to measure it; [`NewtonReport::timings`] says where the time went.
//!
//! **Why this solver**: contact and compressed rods make `H` indefinite away from equilibrium, and the
//! Levenberg–Marquardt shift keeps the sparse Cholesky of the garment solver usable (a PD matrix for
//! every accepted shift) instead of an indefinite LDLᵀ, whose faer version has no pivoting for sparse
//! matrices; near a stable equilibrium `μ → 0` and the iteration is plain Newton (quadratic convergence).
//!
//! Converged when the problem's scaled residual ([`NewtonProblem::residual`]) is at most the tolerance.
//! Iteration limits end with `converged = false` and the last accepted state — never a hang.

use std::time::Instant;

use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef, Triplet};
use serde::{Deserialize, Serialize};
use skintight_physics::{CholeskyError, Ordering, SparseCholesky, SparseCholeskyParams};

/// A problem for [`minimize`].
pub trait NewtonProblem {
    /// Number of unknowns.
    fn dof_count(&self) -> usize;
    /// Energy, gradient and (if `hessian`) the lower triangle of the Hessian at `x`.
    fn evaluate(
        &self,
        x: &[f64],
        hessian: bool,
    ) -> (f64, Vec<f64>, Vec<Triplet<usize, usize, f64>>);
    /// The energy alone at `x` (the line search's trial points): `evaluate(x, false).0`, which a problem
    /// may compute more cheaply (no derivatives).
    fn energy(&self, x: &[f64]) -> f64 {
        self.evaluate(x, false).0
    }
    /// Unknowns come in contiguous groups of this size that share their sparsity (the 4 unknowns of a yarn
    /// vertex): the fill-reducing ordering is then computed on the groups' graph
    /// ([`SparseCholesky::analyze_grouped`]). 1: no grouping.
    fn group_size(&self) -> usize {
        1
    }
    /// The dimensionless residual of gradient `g` (force over the problem's force scale).
    fn residual(&self, g: &[f64]) -> f64;
    /// The factor in `(0, 1]` that brings step `h` within the problem's step limit.
    fn step_scale(&self, h: &[f64]) -> f64;
    /// Called after every accepted step (frame updates); must leave the energy at `x` unchanged.
    fn accepted(&mut self, x: &[f64]);
    /// Whether the caller asked the solve to stop: checked before every iteration, it ends the solve with
    /// `stop = "interrupted"`, `converged = false` and the last accepted state.
    fn interrupted(&self) -> bool {
        false
    }
    /// Takes back the triplets of an evaluation once the solver is done with them, so that a later
    /// evaluation may reuse their allocation (default: dropped). Why: on a 16 × 16 patch they are ~100 MB
    /// an iteration, and fresh pages cost the kernel's page faults and zeroing.
    fn recycle(&self, triplets: Vec<Triplet<usize, usize, f64>>) {
        drop(triplets);
    }
}

/// Settings of [`minimize`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct NewtonParams {
    /// Converged when the residual is at most this (dimensionless).
    pub tolerance: f64,
    /// Most Newton iterations (each may factor several times).
    pub max_iterations: usize,
    /// Most factorizations in all.
    pub max_factorizations: usize,
    /// Print one line per iteration to stderr.
    pub trace: bool,
    /// Trial points of the line search evaluate the energy alone ([`NewtonProblem::energy`]), and the
    /// gradient only in the rounding band; `false` evaluates the gradient at every trial point (the solver
    /// before issue 19's speed-ups, kept to measure them).
    pub energy_line_search: bool,
    /// Keep the analyzed sparsity pattern while every new matrix fits in it (a union of the recent
    /// patterns); `false` analyzes at every iteration.
    pub reuse_analysis: bool,
    /// Start from the shift `μ` the previous solve on the same workspace ended with; `false` starts at 0.
    pub warm_shift: bool,
}

impl Default for NewtonParams {
    fn default() -> Self {
        Self {
            tolerance: 1e-9,
            max_iterations: 300,
            max_factorizations: 1500,
            trace: false,
            energy_line_search: true,
            reuse_analysis: true,
            warm_shift: true,
        }
    }
}

/// What [`minimize`] did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct NewtonReport {
    /// Whether the residual reached the tolerance.
    pub converged: bool,
    /// Accepted Newton steps.
    pub iterations: usize,
    /// Cholesky factorizations.
    pub factorizations: usize,
    /// Final residual (dimensionless).
    pub residual: f64,
    /// Final energy (J).
    pub energy: f64,
    /// Final damping `μ`.
    pub damping: f64,
    /// Wall-clock time (s).
    pub seconds: f64,
    /// Why the solve stopped.
    pub stop: String,
    /// Where the time went.
    #[serde(default)]
    pub timings: NewtonTimings,
}

/// Errors of [`minimize`].
#[derive(Clone, Debug, thiserror::Error, PartialEq)]
pub enum NewtonError {
    /// The linear solver failed other than by indefiniteness.
    #[error("sparse Cholesky failed: {0}")]
    Cholesky(#[from] CholeskyError),
    /// The energy or gradient is not finite at the start.
    #[error("the energy or its gradient is not finite at the starting state")]
    NonFinite,
}

/// Where the time of a [`minimize`] went (s, wall clock), and how often the sparsity pattern was analyzed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct NewtonTimings {
    /// Evaluations with the Hessian (the start and every accepted step).
    pub evaluation: f64,
    /// The line search's trial evaluations (energy only, or with the gradient in the rounding band).
    pub line_search: f64,
    /// Triplets to compressed columns, scattered into the analyzed pattern.
    pub assembly: f64,
    /// Symbolic analyses (ordering, elimination tree, supernodes).
    pub analysis: f64,
    /// Numeric factorizations, failed ones included.
    pub factorization: f64,
    /// Triangular solves.
    pub solve: f64,
    /// Symbolic analyses made (the others reused the pattern of an earlier iteration or solve).
    pub analyses: usize,
}

impl NewtonTimings {
    /// Adds `other` to these (sums over solves).
    pub fn add(&mut self, other: &Self) {
        self.evaluation += other.evaluation;
        self.line_search += other.line_search;
        self.assembly += other.assembly;
        self.analysis += other.analysis;
        self.factorization += other.factorization;
        self.solve += other.solve;
        self.analyses += other.analyses;
    }
}

/// What [`minimize_with`] keeps between solves: the analyzed sparsity pattern with its symbolic Cholesky
/// factorization, and the last Levenberg–Marquardt shift. Cloning gives an empty workspace (a cache).
#[derive(Debug, Default)]
pub struct NewtonWorkspace {
    pattern: Option<AnalyzedPattern>,
    mu: f64,
}

impl NewtonWorkspace {
    /// The Levenberg–Marquardt shift the next solve starts from (dimensionless; see the module doc).
    pub fn shift(&self) -> f64 {
        self.mu
    }

    /// Sets the starting shift (a resumed run's; negative or non-finite values count as 0).
    pub fn set_shift(&mut self, mu: f64) {
        self.mu = if mu.is_finite() { mu.max(0.0) } else { 0.0 };
    }
}

impl Clone for NewtonWorkspace {
    fn clone(&self) -> Self {
        Self::default()
    }
}

#[derive(Debug)]
struct AnalyzedPattern {
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    /// Position of each diagonal entry in `row_idx`.
    diagonal: Vec<usize>,
    chol: SparseCholesky,
}

impl AnalyzedPattern {
    /// Analyzes the pattern `col_ptr, row_idx` (lower triangle, sorted rows, every diagonal present).
    fn new(
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
    fn scatter(&self, matrix: &Csc) -> Option<Vec<f64>> {
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
}

/// A lower triangle in compressed columns (sorted rows, duplicates summed).
struct Csc {
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    values: Vec<f64>,
}

/// `triplets` (row ≥ column) in compressed columns with every diagonal entry present (zero where no
/// triplet gives one) and the rows of each column sorted, without a comparison sort (the transpose trick
/// of CSparse's `cs_compress` / `cs_dupl` / `cs_transpose`, Davis 2006, ch. 2):
/// 1. a counting sort of the triplets (after each row's diagonal zero) on their rows;
/// 2. each row's duplicates summed in place, in triplet order, with a marker per column;
/// 3. the transpose of those rows: visiting the rows in increasing order fills every column's rows in
///    increasing order.
///
/// Linear in the entries: two scatters (the triplets, then the summed entries — on the 16 × 16 hanging
/// patch 4.3 M and ~1.4 M) and sequential passes. It replaced a counting sort on the columns followed by a
/// comparison sort of each column's ~40 rows (the 8 × 8 probe's assembly time as `NewtonTimings` counts
/// it — the triplet check, this and the scatter into the analyzed pattern: 23.7 → 20.5 ms an iteration;
/// docs/BENCHMARKS.md). Duplicates are summed in triplet order, so the
/// sums no longer depend on an unstable sort's order of equal rows.
fn lower_csc(n: usize, triplets: &[Triplet<usize, usize, f64>]) -> Csc {
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
    Csc {
        col_ptr,
        row_idx,
        values,
    }
}

/// The union of the lower-triangle patterns `a` and `b` (compressed columns, sorted rows).
fn pattern_union(a: (&[usize], &[usize]), b: (&[usize], &[usize])) -> (Vec<usize>, Vec<usize>) {
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

const MU_FLOOR: f64 = 1e-10;

/// A union pattern is kept while it has at most this many times the entries of the current matrix;
/// beyond, the current pattern alone is analyzed (contacts long gone no longer add fill).
const UNION_SLACK: f64 = 1.25;

/// Minimises `problem`'s energy from `x` (updated in place) with a fresh [`NewtonWorkspace`].
pub fn minimize(
    problem: &mut impl NewtonProblem,
    x: &mut [f64],
    params: &NewtonParams,
) -> Result<NewtonReport, NewtonError> {
    minimize_with(problem, x, params, &mut NewtonWorkspace::default())
}

/// Minimises `problem`'s energy from `x` (updated in place), reusing and updating `workspace` (the
/// analyzed pattern and the starting shift; pass the same workspace to the solves of successive time
/// steps).
pub fn minimize_with(
    problem: &mut impl NewtonProblem,
    x: &mut [f64],
    params: &NewtonParams,
    workspace: &mut NewtonWorkspace,
) -> Result<NewtonReport, NewtonError> {
    let start = Instant::now();
    let mut timings = NewtonTimings::default();
    let n = problem.dof_count();
    let clock = Instant::now();
    let (mut energy, mut g, mut triplets) = problem.evaluate(x, true);
    timings.evaluation += clock.elapsed().as_secs_f64();
    if !energy.is_finite() || g.iter().any(|v| !v.is_finite()) {
        return Err(NewtonError::NonFinite);
    }
    if workspace
        .pattern
        .as_ref()
        .is_some_and(|p| p.col_ptr.len() != n + 1)
    {
        workspace.pattern = None;
    }
    let mut residual = problem.residual(&g);
    let mut mu = if params.warm_shift { workspace.mu } else { 0.0 };
    let mut iterations = 0;
    let mut factorizations = 0;
    let chol_params = SparseCholeskyParams {
        ordering: Ordering::Amd,
        threads: None,
    };
    let stop;
    'outer: loop {
        if residual <= params.tolerance {
            stop = "converged".to_string();
            break;
        }
        if iterations >= params.max_iterations {
            stop = "iteration limit".to_string();
            break;
        }
        if problem.interrupted() {
            stop = "interrupted".to_string();
            break;
        }
        // Assemble once per iteration: the lower triangle with every diagonal entry present, scattered into
        // the analyzed pattern (analyzed anew only when an entry falls outside it).
        let clock = Instant::now();
        if let Some(t) = triplets.iter().find(|t| t.row >= n || t.col > t.row) {
            return Err(CholeskyError::NotLowerTriangular {
                row: t.row,
                col: t.col,
            }
            .into());
        }
        let matrix = lower_csc(n, &triplets);
        let mut base = match workspace.pattern.as_ref() {
            Some(p) if params.reuse_analysis => p.scatter(&matrix),
            _ => None,
        };
        timings.assembly += clock.elapsed().as_secs_f64();
        if base.is_none() {
            if params.trace
                && let Some(p) = workspace.pattern.as_ref()
            {
                let (cp, ri) = (&matrix.col_ptr, &matrix.row_idx);
                let (_, uri) = pattern_union((&p.col_ptr, &p.row_idx), (cp, ri));
                eprintln!(
                    "newton: {} entries outside the analyzed pattern of {} ({} in the matrix)",
                    uri.len() - p.row_idx.len(),
                    p.row_idx.len(),
                    ri.len()
                );
            }
            let clock = Instant::now();
            let (cp, ri) = (&matrix.col_ptr, &matrix.row_idx);
            let (col_ptr, row_idx) = match workspace.pattern.as_ref() {
                Some(p) if params.reuse_analysis => {
                    let (ucp, uri) = pattern_union((&p.col_ptr, &p.row_idx), (cp, ri));
                    if uri.len() as f64 <= UNION_SLACK * ri.len() as f64 {
                        (ucp, uri)
                    } else {
                        (cp.to_vec(), ri.to_vec())
                    }
                }
                _ => (cp.to_vec(), ri.to_vec()),
            };
            workspace.pattern = None;
            let analyzed =
                AnalyzedPattern::new(n, col_ptr, row_idx, problem.group_size(), &chol_params)?;
            timings.analyses += 1;
            base = analyzed.scatter(&matrix);
            workspace.pattern = Some(analyzed);
            timings.analysis += clock.elapsed().as_secs_f64();
        }
        let base = base.expect("the matrix lies in the pattern analyzed for it");
        drop(matrix);
        let pattern = workspace.pattern.as_mut().expect("analyzed above");
        // Diagonal scaling D.
        let diag: Vec<f64> = pattern.diagonal.iter().map(|&p| base[p]).collect();
        let dmax = diag.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-300);
        let dscale: Vec<f64> = diag.iter().map(|v| v.abs().max(1e-12 * dmax)).collect();
        let mut accepted = false;
        let mut values = base.clone();
        while !accepted {
            if factorizations >= params.max_factorizations {
                stop = "factorization limit".to_string();
                break 'outer;
            }
            let clock = Instant::now();
            values.copy_from_slice(&base);
            for (&p, s) in pattern.diagonal.iter().zip(&dscale) {
                values[p] += (mu + MU_FLOOR) * s;
            }
            let symbolic = SymbolicSparseColMatRef::new_checked(
                n,
                n,
                &pattern.col_ptr,
                None,
                &pattern.row_idx,
            );
            let result = pattern
                .chol
                .factorize(SparseColMatRef::new(symbolic, &values));
            factorizations += 1;
            timings.factorization += clock.elapsed().as_secs_f64();
            match result {
                Ok(()) => {}
                Err(CholeskyError::NotPositiveDefinite { .. }) => {
                    mu = (mu * 10.0).max(1e-6);
                    continue;
                }
                Err(e) => return Err(e.into()),
            }
            let clock = Instant::now();
            let mut h: Vec<f64> = g.iter().map(|v| -v).collect();
            pattern.chol.solve_in_place(&mut h)?;
            timings.solve += clock.elapsed().as_secs_f64();
            let scale = problem.step_scale(&h);
            for v in &mut h {
                *v *= scale;
            }
            let slope: f64 = g.iter().zip(&h).map(|(a, b)| a * b).sum();
            let mut alpha = 1.0;
            let clock = Instant::now();
            for _ in 0..9 {
                let trial: Vec<f64> = x.iter().zip(&h).map(|(a, b)| a + alpha * b).collect();
                let armijo_bound = energy + 1e-4 * alpha * slope;
                let rounding_bound = energy + 1e-12 * energy.abs();
                // The energy alone decides Armijo; the gradient (for the residual) is needed only in the
                // rounding band.
                let (e_trial, r_trial) = if params.energy_line_search {
                    let e = problem.energy(&trial);
                    if e.is_finite() && e > armijo_bound && e <= rounding_bound {
                        let (e, g_trial, _) = problem.evaluate(&trial, false);
                        (e, problem.residual(&g_trial))
                    } else {
                        (e, f64::INFINITY)
                    }
                } else {
                    let (e, g_trial, _) = problem.evaluate(&trial, false);
                    (e, problem.residual(&g_trial))
                };
                let armijo = e_trial <= armijo_bound;
                // Near the minimum the energy change drowns in rounding: accept a step that keeps the
                // energy within its rounding band and lowers the residual.
                let rounding = e_trial <= rounding_bound && r_trial < residual;
                if e_trial.is_finite() && (armijo || rounding) {
                    timings.line_search += clock.elapsed().as_secs_f64();
                    x.copy_from_slice(&trial);
                    problem.accepted(x);
                    let clock = Instant::now();
                    let (e, gg, tt) = problem.evaluate(x, true);
                    timings.evaluation += clock.elapsed().as_secs_f64();
                    energy = e;
                    g = gg;
                    problem.recycle(std::mem::replace(&mut triplets, tt));
                    residual = problem.residual(&g);
                    accepted = true;
                    break;
                }
                alpha *= 0.5;
            }
            if !accepted {
                timings.line_search += clock.elapsed().as_secs_f64();
            }
            if params.trace {
                eprintln!(
                    "newton {iterations}: energy {energy:.6e} residual {residual:.3e} mu {mu:.1e} step scale {scale:.2e} alpha {alpha:.2e} accepted {accepted}"
                );
            }
            if accepted {
                iterations += 1;
                mu = if mu < 1e-8 { 0.0 } else { mu / 3.0 };
            } else {
                mu = (mu * 10.0).max(1e-6);
                if mu > 1e12 {
                    stop = "no descent step found".to_string();
                    break 'outer;
                }
            }
        }
    }
    workspace.mu = mu;
    Ok(NewtonReport {
        converged: residual <= params.tolerance,
        iterations,
        factorizations,
        residual,
        energy,
        damping: mu,
        seconds: start.elapsed().as_secs_f64(),
        stop,
        timings,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
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
        let ours = lower_csc(n, &ta);
        let mut with_diagonal = ta.clone();
        with_diagonal.extend((0..n).map(|i| Triplet::new(i, i, 0.0)));
        let faer = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &with_diagonal).unwrap();
        assert_eq!(ours.col_ptr, faer.symbolic().col_ptr());
        assert_eq!(ours.row_idx, faer.symbolic().row_idx());
        for (a, b) in ours.values.iter().zip(faer.val()) {
            assert!((a - b).abs() <= 1e-14, "{a} vs {b}");
        }
        // The union holds both patterns and nothing else.
        let other = lower_csc(n, &tb);
        let mut both = ta.clone();
        both.extend(tb.iter().map(|t| Triplet::new(t.row, t.col, 0.0)));
        let joint = lower_csc(n, &both);
        let (cp, ri) = pattern_union(
            (&ours.col_ptr, &ours.row_idx),
            (&other.col_ptr, &other.row_idx),
        );
        assert_eq!((cp, ri), (joint.col_ptr, joint.row_idx));
    }
}
