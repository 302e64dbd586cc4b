//! The adjoint Gauss-Newton direction (Zehnder et al. 2021; Sec. 6.2, Eq. 21 of the volumetric
//! homogenization paper) for the pattern design problem: a sparse KKT system built from the equilibrium
//! Hessian instead of the dense Gauss-Newton matrix.
//!
//! **Model.** The state `q` (`#q`: surface coordinates of the cloth, body positions) is at equilibrium,
//! `∂U/∂q (q, X̄) = 0`; the pattern `X̄` (`2#Vp`, m) follows the design parameters `c` (`#c`) through a
//! constant map `A = dX̄/dc` (`2#Vp × #c`). The sum-of-squares terms give residuals `r` (`#r`, `T_res = Σ r²`)
//! with Jacobians `R_x = ∂r/∂x` (`#r × 3#Vc`) and `R_X = ∂r/∂X̄` (`#r × 2#Vp`); `J = ∂x/∂q` (`3#Vc × #q`) and
//! `R_q = R_x J` (plus the direct `∂r/∂q` of terms that see the state, [`Residuals::state_jacobian`]). With `H = ∂²U/∂q²` and `K = ∂²U/∂q∂X̄` (`#q × 2#Vp`) the linearized equilibrium is
//! `H dq + K dX̄ = 0`, so `dq = S dc`, `S = −H⁻¹ K A`, and the residuals change by `R_tot dc`,
//! `R_tot = R_q S + R_X A`. The Gauss-Newton model of the whole objective `T` is
//!
//! ```text
//! m(dc) = T + gᵀ dc + ½ dcᵀ (2 R_totᵀ R_tot + κ I) dc,     g = dT/dc (the full design gradient),
//! ```
//!
//! whose minimizer solves `(2 R_totᵀ R_tot + κ I) dc = −g`. The right-hand side is the **full** gradient
//! (adjoint, all terms), so terms without residuals (e.g. a linear seam traction) still enter to first
//! order; the matrix holds the Gauss-Newton curvature of the residual terms only, plus the
//! Levenberg-Marquardt damping `κ I` (units of `T` per unit² of `c`).
//!
//! **KKT system.** `2 R_totᵀ R_tot` is dense and needs `#c` solves with `H`; instead, with the scaled
//! residual change `ρ = 2 (R_q dq + R_X dX̄)` and the multipliers `ν` (equilibrium) and `μ` (`dX̄ = A dc`),
//! the minimizer of `gᵀdc + ‖R_q dq + R_X dX̄‖² + ½κ‖dc‖²` subject to both constraints solves the symmetric
//! sparse system (unknowns `ρ, dq, dX̄, dc, ν, μ`; `N = #r + 2#q + 4#Vp + #c` rows)
//!
//! ```text
//! ⎡ −½I   R_q  R_X   0    0    0  ⎤ ⎡ ρ  ⎤   ⎡  0 ⎤
//! ⎢ R_qᵀ   0    0    0    H    0  ⎥ ⎢ dq ⎥   ⎢  0 ⎥
//! ⎢ R_Xᵀ   0    0    0    Kᵀ   I  ⎥ ⎢ dX̄ ⎥ = ⎢  0 ⎥
//! ⎢  0     0    0    κI   0   −Aᵀ ⎥ ⎢ dc ⎥   ⎢ −g ⎥
//! ⎢  0     H    K    0    0    0  ⎥ ⎢ ν  ⎥   ⎢  0 ⎥
//! ⎣  0     0    I   −A    0    0  ⎦ ⎣ μ  ⎦   ⎣  0 ⎦
//! ```
//!
//! Eliminating gives `ν = −H⁻¹R_qᵀρ`, `μ = −(R_X − R_q H⁻¹K)ᵀρ`, `Aᵀμ = −2 R_totᵀ R_tot dc`, so `dc` is the
//! Gauss-Newton direction above. (Eq. 21 of the paper is the same system with the residual Jacobians
//! folded into `G`; keeping `ρ` keeps every block as sparse as the residuals.) The equilibrium rows and
//! columns are scaled by `1 / max|H_ii|` so that `H` and `K` enter with entries of order one.
//!
//! **Sparsity.** `H` (lower triangle stored, expanded here), `J`, `K`, `R_x`, `R_X` are sparse. `A` is
//! **dense per panel** (the interior of a panel follows all its boundary parameters through the
//! bi-harmonic coordinates, [`crate::PatternMap`]): its exact zeros are dropped, leaving about
//! `2 Σ_panels #interior · #boundary` entries — acceptable for `#c` up to a few hundred, and the reason
//! the system grows with `#c` like a dense block.
//!
//! **Solver.** faer's sparse LU with partial pivoting (the matrix is indefinite) and a COLAMD column
//! ordering. The symbolic phase (ordering, structure of the factors) is kept and reused for the next
//! system while the list of entries is the same (same residual structure, same cloth stencils, same
//! Hessian pattern); the numeric phase runs per system. Two steps of iterative refinement follow the
//! solve; the relative residual of the final solution is reported.

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Lu, SymbolicLu};
use faer::sparse::{Pair, SparseColMat, SparseColMatRef, SymbolicSparseColMat};
use faer::{Mat, sparse::Argsort};

use crate::math::Real;
use crate::term::Residuals;

/// Why a Gauss-Newton direction could not be computed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum GaussNewtonError {
    /// Inputs of inconsistent sizes or non-finite values; the message names the input.
    #[error("adjoint Gauss-Newton: {0}")]
    Invalid(String),
    /// The KKT system could not be factored or its solution is not usable.
    #[error("adjoint Gauss-Newton: the KKT system could not be solved: {0}")]
    Solve(String),
}

/// What the Gauss-Newton system is built from (see the module documentation for the symbols). The
/// units are any consistent ones: the design loop passes the normalized objective `T / T₀` and design
/// parameters in cloth edge lengths.
#[derive(Clone, Copy, Debug)]
pub struct GaussNewtonSystem<'a> {
    /// `r` (`#r`, √T) with `R_x` (cloth vertex entries, √T per m) and `R_X` (pattern vertex entries).
    pub residuals: &'a Residuals,
    /// `J = ∂x/∂q` (`3#Vc × #q`, row `3c + i` = coordinate `i` of cloth vertex `c`).
    pub cloth_jacobian: SparseColMatRef<'a, usize, Real>,
    /// `H` (`#q × #q`, N/m), **lower triangle only** (row ≥ column), symmetric positive definite (the
    /// Hessian the adjoint solves with, [`skintight_physics::EquilibriumWorkspace::adjoint_hessian`]).
    pub hessian: SparseColMatRef<'a, usize, Real>,
    /// `K = ∂²U/∂q∂X̄`, explicit or already multiplied by the design map (see [`MixedDerivative`]).
    pub mixed: MixedDerivative<'a>,
    /// `A = dX̄/dc` (`2#Vp × #c`, m per unit of `c`), constant over a level.
    pub design_map: SparseColMatRef<'a, usize, Real>,
    /// `g = dT/dc` (`#c`, T per unit of `c`): the full design gradient.
    pub gradient: &'a [Real],
}

/// How a [`GaussNewtonSystem`] holds `K = ∂²U/∂q∂X̄`.
#[derive(Clone, Copy, Debug)]
pub enum MixedDerivative<'a> {
    /// `K` itself (`#q × 2#Vp`, N/m, column `2v + i` = coordinate `i` of pattern vertex `v`): what the KKT
    /// system needs.
    Matrix(SparseColMatRef<'a, usize, Real>),
    /// `K A` already formed (`#q × #c`, column-major, N/m per unit of `c`), e.g. matrix-free by
    /// [`skintight_physics::ClothOnBody::rest_mixed_times`]: all the reduced direction
    /// ([`crate::reduced_direction`]) needs, without building `K`. The KKT system cannot use it.
    TimesDesignMap(&'a [Real]),
}

/// A Gauss-Newton direction.
#[derive(Clone, Debug, PartialEq)]
pub struct GaussNewtonDirection {
    /// `dc` (`#c`, units of `c`).
    pub design: Vec<Real>,
    /// The predicted change of the state `dq = S dc` (`#q`).
    pub state: Vec<Real>,
    /// The predicted change of the pattern `dX̄ = A dc` (`2#Vp`, m).
    pub pattern: Vec<Real>,
    /// Relative residual `‖b − M z‖ / ‖b‖` of the KKT solve (dimensionless).
    pub kkt_residual: Real,
    /// Whether the symbolic analysis of the previous system was reused.
    pub reused_analysis: bool,
}

/// The cached symbolic phase: the entry list it was built for, the matrix structure and the LU analysis.
struct Analysis {
    entries: Vec<Pair<usize, usize>>,
    structure: SymbolicSparseColMat<usize>,
    argsort: Argsort<usize>,
    lu: SymbolicLu<usize>,
}

/// Builds and solves the adjoint Gauss-Newton KKT system, keeping the symbolic analysis between calls.
#[derive(Default)]
pub struct AdjointGaussNewton {
    analysis: Option<Analysis>,
    analyses: usize,
}

impl std::fmt::Debug for AdjointGaussNewton {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AdjointGaussNewton")
            .field("analyses", &self.analyses)
            .finish()
    }
}

/// Entries of a column-compressed matrix as `(row, column, value)`.
fn entries(m: SparseColMatRef<'_, usize, Real>) -> impl Iterator<Item = (usize, usize, Real)> + '_ {
    let (cp, ri, v) = (m.symbolic().col_ptr(), m.symbolic().row_idx(), m.val());
    (0..m.ncols()).flat_map(move |c| (cp[c]..cp[c + 1]).map(move |k| (ri[k], c, v[k])))
}

impl AdjointGaussNewton {
    /// A solver with no analysis yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Symbolic analyses done so far (one per change of the KKT structure).
    pub fn analyses(&self) -> usize {
        self.analyses
    }

    /// The Gauss-Newton direction `dc` solving `(2 R_totᵀ R_tot + κ I) dc = −g` through the KKT system
    /// (module documentation), with damping `κ ≥ 0` (units of `T` per unit² of `c`; with no residuals,
    /// `κ > 0` is needed and the direction is `−g / κ`).
    pub fn direction(
        &mut self,
        system: &GaussNewtonSystem<'_>,
        damping: Real,
    ) -> Result<GaussNewtonDirection, GaussNewtonError> {
        let bad = |m: String| Err(GaussNewtonError::Invalid(m));
        let res = system.residuals;
        let nr = res.values.len();
        let j = system.cloth_jacobian;
        let nq = j.ncols();
        let MixedDerivative::Matrix(mixed) = system.mixed else {
            return bad("the KKT system needs the mixed derivative K itself, not K A".into());
        };
        let nx = mixed.ncols();
        let nc = system.design_map.ncols();
        if j.nrows() % 3 != 0 {
            return bad(format!(
                "the cloth Jacobian has {} rows, not 3 per vertex",
                j.nrows()
            ));
        }
        let nvc = j.nrows() / 3;
        if system.hessian.nrows() != nq || system.hessian.ncols() != nq {
            return bad(format!(
                "the Hessian is {} × {} for {nq} unknowns",
                system.hessian.nrows(),
                system.hessian.ncols()
            ));
        }
        if mixed.nrows() != nq || nx % 2 != 0 {
            return bad(format!(
                "the mixed derivative is {} × {nx} for {nq} unknowns and 2 per pattern vertex",
                mixed.nrows()
            ));
        }
        if system.design_map.nrows() != nx {
            return bad(format!(
                "the design map has {} rows for {nx} pattern coordinates",
                system.design_map.nrows()
            ));
        }
        if system.gradient.len() != nc {
            return bad(format!(
                "the gradient has {} entries for {nc} design parameters",
                system.gradient.len()
            ));
        }
        if !(damping.is_finite() && damping >= 0.0) {
            return bad(format!("the damping must be finite and ≥ 0, got {damping}"));
        }
        if nr == 0 && damping == 0.0 {
            return bad("no residuals and no damping: the Gauss-Newton matrix is zero".into());
        }
        if let Some(&(k, c, _)) = res
            .cloth_jacobian
            .iter()
            .find(|(k, c, _)| *k >= nr || *c >= nvc)
        {
            return bad(format!(
                "residual Jacobian entry ({k}, cloth vertex {c}) out of range"
            ));
        }
        if let Some(&(k, v, _)) = res
            .pattern_jacobian
            .iter()
            .find(|(k, v, _)| *k >= nr || 2 * v >= nx)
        {
            return bad(format!(
                "residual Jacobian entry ({k}, pattern vertex {v}) out of range"
            ));
        }
        if let Some(&(k, q, _)) = res
            .state_jacobian
            .iter()
            .find(|(k, q, _)| *k >= nr || *q >= nq)
        {
            return bad(format!(
                "residual Jacobian entry ({k}, unknown {q}) out of range"
            ));
        }
        let finite = res.state_jacobian.iter().all(|e| e.2.is_finite())
            && res.values.iter().all(|v| v.is_finite())
            && system.gradient.iter().all(|v| v.is_finite())
            && res
                .cloth_jacobian
                .iter()
                .all(|e| e.2.iter().all(|v| v.is_finite()))
            && res
                .pattern_jacobian
                .iter()
                .all(|e| e.2.iter().all(|v| v.is_finite()));
        if !finite {
            return bad("a residual, residual derivative or gradient entry is not finite".into());
        }

        // Offsets of the blocks.
        let o_rho = 0;
        let o_dq = nr;
        let o_dx = o_dq + nq;
        let o_dc = o_dx + nx;
        let o_nu = o_dc + nc;
        let o_mu = o_nu + nq;
        let n = o_mu + nx;

        // Scale of the equilibrium rows and columns.
        let h_scale = entries(system.hessian)
            .filter(|(r, c, _)| r == c)
            .fold(0.0_f64, |m, (_, _, v)| m.max(v.abs()));
        if !(h_scale.is_finite() && h_scale > 0.0) {
            return bad(format!(
                "the Hessian has no positive diagonal (largest |H_ii| = {h_scale})"
            ));
        }
        let s = 1.0 / h_scale;

        // J row by row: cloth vertex c → (unknown, ∂x_c/∂q_j).
        let mut j_rows: Vec<Vec<(usize, [Real; 3])>> = vec![Vec::new(); nvc];
        for (r, c, v) in entries(j) {
            let row = &mut j_rows[r / 3];
            match row.iter_mut().find(|(d, _)| *d == c) {
                Some((_, e)) => e[r % 3] += v,
                None => {
                    let mut e = [0.0; 3];
                    e[r % 3] = v;
                    row.push((c, e));
                }
            }
        }

        let mut idx: Vec<Pair<usize, usize>> = Vec::new();
        let mut val: Vec<Real> = Vec::new();
        let mut sym = |r: usize, c: usize, v: Real| {
            idx.push(Pair { row: r, col: c });
            val.push(v);
            if r != c {
                idx.push(Pair { row: c, col: r });
                val.push(v);
            }
        };
        for k in 0..nr {
            sym(o_rho + k, o_rho + k, -0.5);
        }
        // R_q = R_x J.
        for &(k, c, d) in &res.cloth_jacobian {
            for &(q, e) in &j_rows[c] {
                sym(o_rho + k, o_dq + q, d.x * e[0] + d.y * e[1] + d.z * e[2]);
            }
        }
        for &(k, v, d) in &res.pattern_jacobian {
            sym(o_rho + k, o_dx + 2 * v, d.x);
            sym(o_rho + k, o_dx + 2 * v + 1, d.y);
        }
        // The direct part of R_q.
        for &(k, q, d) in &res.state_jacobian {
            sym(o_rho + k, o_dq + q, d);
        }
        for (r, c, v) in entries(system.hessian) {
            if r < c {
                return bad(format!(
                    "the Hessian has an entry above the diagonal ({r}, {c})"
                ));
            }
            sym(o_nu + r, o_dq + c, s * v);
            if r != c {
                sym(o_nu + c, o_dq + r, s * v);
            }
        }
        for (r, c, v) in entries(mixed) {
            sym(o_nu + r, o_dx + c, s * v);
        }
        for i in 0..nx {
            sym(o_mu + i, o_dx + i, 1.0);
        }
        for i in 0..nc {
            sym(o_dc + i, o_dc + i, damping);
        }
        for (r, c, v) in entries(system.design_map) {
            sym(o_mu + r, o_dc + c, -v);
        }
        if let Some(i) = val.iter().position(|v| !v.is_finite()) {
            return bad(format!(
                "KKT entry {i} is not finite (a non-finite H, K, J or A)"
            ));
        }

        // Symbolic phase, reused while the entry list is the same.
        let reused = self.analysis.as_ref().is_some_and(|a| a.entries == idx);
        if !reused {
            let (structure, argsort) = SymbolicSparseColMat::try_new_from_indices(n, n, &idx)
                .map_err(|e| GaussNewtonError::Solve(format!("structure: {e:?}")))?;
            let lu = SymbolicLu::try_new(structure.as_ref())
                .map_err(|e| GaussNewtonError::Solve(format!("symbolic LU: {e:?}")))?;
            self.analyses += 1;
            self.analysis = Some(Analysis {
                entries: idx,
                structure,
                argsort,
                lu,
            });
        }
        let analysis = self.analysis.as_ref().expect("analysed above");
        let matrix =
            SparseColMat::new_from_argsort(analysis.structure.clone(), &analysis.argsort, &val)
                .map_err(|e| GaussNewtonError::Solve(format!("values: {e:?}")))?;
        let lu = Lu::try_new_with_symbolic(analysis.lu.clone(), matrix.as_ref())
            .map_err(|e| GaussNewtonError::Solve(format!("numeric LU: {e:?}")))?;

        let mut b = vec![0.0; n];
        for (i, g) in system.gradient.iter().enumerate() {
            b[o_dc + i] = -g;
        }
        let b_norm = b.iter().map(|v| v * v).sum::<Real>().sqrt();
        let mut z = vec![0.0; n];
        let mut kkt_residual = Real::INFINITY;
        if b_norm == 0.0 {
            kkt_residual = 0.0;
        } else {
            // Solve, then refine twice: z += M⁻¹ (b − M z).
            let mut r = b.clone();
            for _ in 0..3 {
                let mut rhs = Mat::<Real>::from_fn(n, 1, |i, _| r[i]);
                lu.solve_in_place(rhs.as_mut());
                for (i, zi) in z.iter_mut().enumerate() {
                    *zi += rhs[(i, 0)];
                }
                let mz = product(matrix.as_ref(), &z);
                r = b.iter().zip(&mz).map(|(b, m)| b - m).collect();
                let rel = r.iter().map(|v| v * v).sum::<Real>().sqrt() / b_norm;
                if !rel.is_finite() {
                    break;
                }
                kkt_residual = rel;
                if rel < 1e-14 {
                    break;
                }
            }
        }
        if !(kkt_residual.is_finite() && kkt_residual < 1e-6) || z.iter().any(|v| !v.is_finite()) {
            return Err(GaussNewtonError::Solve(format!(
                "the solution is not accurate (relative residual {kkt_residual:e}): the system is \
                 singular or nearly so"
            )));
        }
        Ok(GaussNewtonDirection {
            design: z[o_dc..o_dc + nc].to_vec(),
            state: z[o_dq..o_dq + nq].to_vec(),
            pattern: z[o_dx..o_dx + nx].to_vec(),
            kkt_residual,
            reused_analysis: reused,
        })
    }
}

/// `M z` for a column-compressed matrix holding all its entries.
fn product(m: SparseColMatRef<'_, usize, Real>, z: &[Real]) -> Vec<Real> {
    let mut y = vec![0.0; m.nrows()];
    for (r, c, v) in entries(m) {
        y[r] += v * z[c];
    }
    y
}

/// The design map `A` (`rows × columns`) as a sparse matrix from its columns (`column(i)` = `A e_i`),
/// exact zeros left out.
pub fn design_map_matrix(
    rows: usize,
    columns: usize,
    mut column: impl FnMut(usize) -> Result<Vec<Real>, String>,
) -> Result<SparseColMat<usize, Real>, GaussNewtonError> {
    let mut triplets = Vec::new();
    for c in 0..columns {
        let col = column(c).map_err(GaussNewtonError::Invalid)?;
        if col.len() != rows {
            return Err(GaussNewtonError::Invalid(format!(
                "design map column {c} has {} entries for {rows} rows",
                col.len()
            )));
        }
        for (r, &v) in col.iter().enumerate() {
            if !v.is_finite() {
                return Err(GaussNewtonError::Invalid(format!(
                    "design map entry ({r}, {c}) is not finite"
                )));
            }
            if v != 0.0 {
                triplets.push(faer::sparse::Triplet::new(r, c, v));
            }
        }
    }
    SparseColMat::try_new_from_triplets(rows, columns, &triplets)
        .map_err(|e| GaussNewtonError::Invalid(format!("design map: {e:?}")))
}

/// Random small systems and reference directions, also used by [`crate::reduced_direction`]'s tests.
#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::math::{Vec2, Vec3};
    use nalgebra::DMatrix;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    pub(crate) fn sparse(m: &DMatrix<Real>, lower_only: bool) -> SparseColMat<usize, Real> {
        let mut t = Vec::new();
        for c in 0..m.ncols() {
            for r in 0..m.nrows() {
                if m[(r, c)] != 0.0 && (!lower_only || r >= c) {
                    t.push(faer::sparse::Triplet::new(r, c, m[(r, c)]));
                }
            }
        }
        SparseColMat::try_new_from_triplets(m.nrows(), m.ncols(), &t).unwrap()
    }

    pub(crate) struct Random {
        pub(crate) residuals: Residuals,
        pub(crate) j: DMatrix<Real>,
        pub(crate) h: DMatrix<Real>,
        pub(crate) k: DMatrix<Real>,
        pub(crate) a: DMatrix<Real>,
        pub(crate) g: Vec<Real>,
    }

    pub(crate) fn random(seed: u64, nr: usize) -> Random {
        let (nvc, nq, nvp, nc) = (4, 9, 5, 4);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut sparse_random = |r: usize, c: usize, density: f64| {
            DMatrix::from_fn(r, c, |_, _| {
                if rng.random::<f64>() < density {
                    rng.random_range(-1.0..1.0)
                } else {
                    0.0
                }
            })
        };
        let j = sparse_random(3 * nvc, nq, 0.4);
        let b = sparse_random(nq, nq, 0.3);
        let h = &b * b.transpose() * 100.0 + DMatrix::identity(nq, nq) * 50.0;
        let k = sparse_random(nq, 2 * nvp, 0.4) * 30.0;
        let a = sparse_random(2 * nvp, nc, 0.6) * 0.01;
        let mut residuals = Residuals::default();
        for i in 0..nr {
            residuals.values.push(rng.random_range(-1.0..1.0));
            for _ in 0..2 {
                let c = rng.random_range(0..nvc);
                let d = Vec3::new(rng.random(), rng.random(), rng.random()) * 10.0;
                residuals.cloth_jacobian.push((i, c, d));
                let v = rng.random_range(0..nvp);
                let d = Vec2::new(rng.random(), rng.random()) * 10.0;
                residuals.pattern_jacobian.push((i, v, d));
            }
            let q = rng.random_range(0..nq);
            residuals
                .state_jacobian
                .push((i, q, rng.random_range(-1.0..1.0) * 10.0));
        }
        let g = (0..nc).map(|_| rng.random_range(-1.0..1.0)).collect();
        Random {
            residuals,
            j,
            h,
            k,
            a,
            g,
        }
    }

    /// `(2 R_totᵀ R_tot + κI)⁻¹ (−g)` with dense matrices.
    pub(crate) fn dense_direction(p: &Random, kappa: Real) -> Vec<Real> {
        let nr = p.residuals.values.len();
        let mut rx = DMatrix::zeros(nr, p.j.nrows());
        for &(k, c, d) in &p.residuals.cloth_jacobian {
            for i in 0..3 {
                rx[(k, 3 * c + i)] += d[i];
            }
        }
        let mut rxbar = DMatrix::zeros(nr, p.k.ncols());
        for &(k, v, d) in &p.residuals.pattern_jacobian {
            rxbar[(k, 2 * v)] += d.x;
            rxbar[(k, 2 * v + 1)] += d.y;
        }
        let mut rq = DMatrix::zeros(nr, p.h.nrows());
        for &(k, q, d) in &p.residuals.state_jacobian {
            rq[(k, q)] += d;
        }
        let s = -p.h.clone().lu().solve(&(&p.k * &p.a)).unwrap();
        let r_tot = (&rx * &p.j + rq) * s + rxbar * &p.a;
        let m =
            r_tot.transpose() * &r_tot * 2.0 + DMatrix::identity(p.a.ncols(), p.a.ncols()) * kappa;
        let g = nalgebra::DVector::from_column_slice(&p.g);
        (-m.lu().solve(&g).unwrap()).as_slice().to_vec()
    }

    pub(crate) fn solve(
        solver: &mut AdjointGaussNewton,
        p: &Random,
        kappa: Real,
    ) -> GaussNewtonDirection {
        let (j, h, k, a) = (
            sparse(&p.j, false),
            sparse(&p.h, true),
            sparse(&p.k, false),
            sparse(&p.a, false),
        );
        let system = GaussNewtonSystem {
            residuals: &p.residuals,
            cloth_jacobian: j.as_ref(),
            hessian: h.as_ref(),
            mixed: MixedDerivative::Matrix(k.as_ref()),
            design_map: a.as_ref(),
            gradient: &p.g,
        };
        solver.direction(&system, kappa).unwrap()
    }

    #[test]
    fn kkt_direction_equals_the_dense_gauss_newton_direction_and_descends() {
        for seed in 0..4 {
            let p = random(seed, 7);
            let mut solver = AdjointGaussNewton::new();
            for (i, kappa) in [0.0, 1e-3, 1.0, 100.0].into_iter().enumerate() {
                let d = solve(&mut solver, &p, kappa);
                assert_eq!(d.reused_analysis, i > 0, "same structure, one analysis");
                let expected = dense_direction(&p, kappa);
                let scale = expected.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
                for (a, b) in d.design.iter().zip(&expected) {
                    assert!(
                        (a - b).abs() <= 1e-8 * scale,
                        "seed {seed} κ {kappa}: {a} vs {b}"
                    );
                }
                let slope: Real = d.design.iter().zip(&p.g).map(|(a, b)| a * b).sum();
                assert!(slope < 0.0, "a descent direction");
                // dX̄ = A dc and H dq + K dX̄ = 0.
                let dc = nalgebra::DVector::from_column_slice(&d.design);
                let dx = &p.a * dc;
                for (a, b) in d.pattern.iter().zip(dx.iter()) {
                    assert!((a - b).abs() <= 1e-9 * scale.max(1e-300));
                }
                let eq = &p.h * nalgebra::DVector::from_column_slice(&d.state) + &p.k * dx;
                assert!(eq.norm() <= 1e-8 * (p.k.norm() * scale));
            }
            assert_eq!(solver.analyses(), 1);
        }
    }

    #[test]
    fn without_residuals_the_direction_is_the_damped_gradient_and_bad_input_is_an_error() {
        let p = random(9, 0);
        let mut solver = AdjointGaussNewton::new();
        let d = solve(&mut solver, &p, 4.0);
        for (a, g) in d.design.iter().zip(&p.g) {
            assert!((a + g / 4.0).abs() <= 1e-12);
        }
        let (j, h, k, a) = (
            sparse(&p.j, false),
            sparse(&p.h, true),
            sparse(&p.k, false),
            sparse(&p.a, false),
        );
        let system = GaussNewtonSystem {
            residuals: &p.residuals,
            cloth_jacobian: j.as_ref(),
            hessian: h.as_ref(),
            mixed: MixedDerivative::Matrix(k.as_ref()),
            design_map: a.as_ref(),
            gradient: &p.g,
        };
        assert!(matches!(
            solver.direction(&system, 0.0),
            Err(GaussNewtonError::Invalid(_))
        ));
        assert!(solver.direction(&system, Real::NAN).is_err());
        let short = &p.g[1..];
        assert!(
            solver
                .direction(
                    &GaussNewtonSystem {
                        gradient: short,
                        ..system
                    },
                    1.0
                )
                .is_err()
        );
        let upper = sparse(&p.h, false);
        assert!(
            solver
                .direction(
                    &GaussNewtonSystem {
                        hessian: upper.as_ref(),
                        ..system
                    },
                    1.0
                )
                .is_err()
        );
        let mut bad = random(9, 3);
        bad.residuals.cloth_jacobian[0].1 = 99;
        let system = GaussNewtonSystem {
            residuals: &bad.residuals,
            ..system
        };
        assert!(solver.direction(&system, 1.0).is_err());
        assert!(design_map_matrix(3, 2, |_| Ok(vec![0.0; 2])).is_err());
        assert!(design_map_matrix(2, 1, |_| Ok(vec![Real::NAN, 0.0])).is_err());
        let a = design_map_matrix(2, 2, |c| {
            Ok(if c == 0 {
                vec![1.0, 0.0]
            } else {
                vec![0.0, 2.0]
            })
        })
        .unwrap();
        assert_eq!(a.compute_nnz(), 2);
    }
}
