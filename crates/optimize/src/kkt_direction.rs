//! The adjoint Gauss-Newton direction through a sparse KKT system (Zehnder et al. 2021; Sec. 6.2, Eq. 21
//! of the volumetric homogenization paper), built from the equilibrium Hessian instead of the dense
//! Gauss-Newton matrix; symbols as in [`mod@crate::linearization`].
//!
//! **KKT system.** `2 R_totᵀ R_tot` is dense and needs `#c` solves with `H`; instead, with the scaled
//! residual change `ρ = 2 (R_q dq + R_p dp)` and the multipliers `ν` (equilibrium) and `μ` (`dp = A dc`),
//! the minimizer of `gᵀdc + ‖R_q dq + R_p dp‖² + ½κ‖dc‖²` subject to both constraints solves the symmetric
//! sparse system (unknowns `ρ, dq, dp, dc, ν, μ`; `N = #r + 2#q + 2#p + #c` rows)
//!
//! ```text
//! ⎡ −½I   R_q  R_p   0    0    0  ⎤ ⎡ ρ  ⎤   ⎡  0 ⎤
//! ⎢ R_qᵀ   0    0    0    H    0  ⎥ ⎢ dq ⎥   ⎢  0 ⎥
//! ⎢ R_pᵀ   0    0    0    Kᵀ   I  ⎥ ⎢ dp ⎥ = ⎢  0 ⎥
//! ⎢  0     0    0    κI   0   −Aᵀ ⎥ ⎢ dc ⎥   ⎢ −g ⎥
//! ⎢  0     H    K    0    0    0  ⎥ ⎢ ν  ⎥   ⎢  0 ⎥
//! ⎣  0     0    I   −A    0    0  ⎦ ⎣ μ  ⎦   ⎣  0 ⎦
//! ```
//!
//! Eliminating gives `ν = −H⁻¹R_qᵀρ`, `μ = −(R_p − R_q H⁻¹K)ᵀρ`, `Aᵀμ = −2 R_totᵀ R_tot dc`, so `dc` is the
//! Gauss-Newton direction. (Eq. 21 of the paper is the same system with the residual Jacobians folded into
//! `G`; keeping `ρ` keeps every block as sparse as the residuals.) The equilibrium rows and columns are
//! scaled by `1 / max|H_ii|` so that `H` and `K` enter with entries of order one.
//!
//! **Sparsity.** `H` (lower triangle stored, expanded here), `K`, `R_q` and `R_p` are sparse; the system
//! holds `A`'s nonzeros, so it grows with `#c` like a dense block where `A` is dense (a pattern's interior
//! follows all of its panel's boundary parameters): then [`mod@crate::reduced_direction`] is the faster
//! form ([`crate::GaussNewtonSolver`]).
//!
//! **Solver.** faer's sparse LU with partial pivoting (the matrix is indefinite) and a COLAMD column
//! ordering. The symbolic phase (ordering, structure of the factors) is kept and reused for the next
//! system while the list of entries is the same; the numeric phase runs per system. Two steps of
//! iterative refinement follow the solve; the relative residual of the final solution is reported.

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Lu, SymbolicLu};
use faer::sparse::{Pair, SparseColMat, SparseColMatRef, SymbolicSparseColMat};
use faer::{Mat, sparse::Argsort};

use crate::Real;
use crate::linearization::{
    GaussNewtonDirection, GaussNewtonError, GaussNewtonSystem, MixedDerivative, Unknown, entries,
    out_of_range,
};

/// The cached symbolic phase: the entry list it was built for, the matrix structure and the LU analysis.
struct Analysis {
    entries: Vec<Pair<usize, usize>>,
    structure: SymbolicSparseColMat<usize>,
    argsort: Argsort<usize>,
    lu: SymbolicLu<usize>,
}

/// Builds and solves the adjoint Gauss-Newton KKT system, keeping the symbolic analysis between calls.
#[derive(Default)]
pub struct KktSolver {
    analysis: Option<Analysis>,
    analyses: usize,
}

impl std::fmt::Debug for KktSolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("KktSolver")
            .field("analyses", &self.analyses)
            .finish()
    }
}

impl KktSolver {
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
    /// `κ > 0` is needed and the direction is `−g / κ`). Needs `K` itself
    /// ([`MixedDerivative::Matrix`]).
    pub fn direction(
        &mut self,
        system: &GaussNewtonSystem<'_>,
        damping: Real,
    ) -> Result<GaussNewtonDirection, GaussNewtonError> {
        let bad = |m: String| Err(GaussNewtonError::Invalid(m));
        let lin = system.linearization;
        let nr = lin.residuals.len();
        let nq = lin.hessian.ncols();
        let MixedDerivative::Matrix(mixed) = &lin.mixed else {
            return bad("the KKT system needs the mixed derivative K itself, not K A".into());
        };
        let nx = mixed.ncols();
        let nc = system.parameter_map.ncols();
        if lin.hessian.nrows() != nq {
            return bad(format!(
                "the Hessian is {} × {nq}, not square",
                lin.hessian.nrows()
            ));
        }
        if mixed.nrows() != nq {
            return bad(format!(
                "the mixed derivative is {} × {nx} for {nq} unknowns",
                mixed.nrows()
            ));
        }
        if system.parameter_map.nrows() != nx {
            return bad(format!(
                "the parameter map has {} rows for {nx} parameters",
                system.parameter_map.nrows()
            ));
        }
        if system.gradient.len() != nc {
            return bad(format!(
                "the gradient has {} entries for {nc} variables",
                system.gradient.len()
            ));
        }
        if !(damping.is_finite() && damping >= 0.0) {
            return bad(format!("the damping must be finite and ≥ 0, got {damping}"));
        }
        if nr == 0 && damping == 0.0 {
            return bad("no residuals and no damping: the Gauss-Newton matrix is zero".into());
        }
        if let Some(m) = out_of_range(&lin.jacobian, nr, nq, nx) {
            return bad(m);
        }
        let finite = lin.jacobian.iter().all(|e| e.2.is_finite())
            && lin.residuals.iter().all(|v| v.is_finite())
            && system.gradient.iter().all(|v| v.is_finite());
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
        let h_scale = entries(lin.hessian.as_ref())
            .filter(|(r, c, _)| r == c)
            .fold(0.0_f64, |m, (_, _, v)| m.max(v.abs()));
        if !(h_scale.is_finite() && h_scale > 0.0) {
            return bad(format!(
                "the Hessian has no positive diagonal (largest |H_ii| = {h_scale})"
            ));
        }
        let s = 1.0 / h_scale;

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
        // R_q and R_p, in the caller's order.
        for &(k, u, v) in &lin.jacobian {
            match u {
                Unknown::State(q) => sym(o_rho + k, o_dq + q, v),
                Unknown::Parameter(x) => sym(o_rho + k, o_dx + x, v),
            }
        }
        for (r, c, v) in entries(lin.hessian.as_ref()) {
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
        for (r, c, v) in entries(mixed.as_ref()) {
            sym(o_nu + r, o_dx + c, s * v);
        }
        for i in 0..nx {
            sym(o_mu + i, o_dx + i, 1.0);
        }
        for i in 0..nc {
            sym(o_dc + i, o_dc + i, damping);
        }
        for (r, c, v) in entries(system.parameter_map) {
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
            variables: z[o_dc..o_dc + nc].to_vec(),
            state: z[o_dq..o_dq + nq].to_vec(),
            parameters: z[o_dx..o_dx + nx].to_vec(),
            residual: kkt_residual,
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

/// Random small systems and reference directions, also used by [`crate::reduced_direction`]'s tests.
#[cfg(test)]
pub(crate) mod tests;
