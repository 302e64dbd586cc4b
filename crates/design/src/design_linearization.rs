//! The design problem linearized at an equilibrium ([`crate::DesignProblem::linearize`]), and that
//! linearization in the optimizers' form ([`skintight_optimize::Linearization`], whose module documents
//! the adjoint Gauss-Newton model).
//!
//! The terms give their residuals' Jacobians per cloth vertex (`∂r/∂x`, √T per m), per pattern vertex
//! (`∂r/∂X̄`) and, for terms that see the state, per state unknown (`∂r/∂q`). The optimizers need them with
//! respect to the state `q` and the parameters `p = X̄` (`2#Vp` pattern coordinates, row `2v + i` =
//! coordinate `i` of vertex `v`): `R_q = R_x J + ∂r/∂q` with the sparse `J = ∂x/∂q` (`3#Vc × #q`), and
//! `R_p` the pattern entries by coordinate. [`DesignLinearization::adjoint`] composes them, entry by entry
//! in a fixed order (the cloth entries through `J`, the pattern entries, the direct state entries), so the
//! KKT system is assembled in the same order every time.

use faer::sparse::SparseColMat;
use skintight_optimize::{GaussNewtonError, Linearization, MixedDerivative, Unknown};

use crate::math::Real;
use crate::term::Residuals;

/// The design problem linearized at an equilibrium ([`crate::DesignProblem::linearize`]).
#[derive(Clone, Debug)]
pub struct DesignLinearization {
    /// Residuals of the sum-of-squares terms (`#r`, √T) with their Jacobians, term after term.
    pub residuals: Residuals,
    /// The names of the terms with residuals, in order.
    pub residual_terms: Vec<&'static str>,
    /// `J = ∂x/∂q` (`3#Vc × #q`, dimensionless).
    pub cloth_jacobian: SparseColMat<usize, Real>,
    /// `H + αD` (`#q × #q`, N/m, lower triangle only), the matrix the adjoint solves with.
    pub hessian: SparseColMat<usize, Real>,
    /// `α` (N/m, 0 when the Hessian factored undamped).
    pub hessian_damping: Real,
    /// `K = ∂²U/∂q∂X̄` (`#q × 2#Vp`, N/m), or `K A` for a design map `A`
    /// ([`crate::DesignProblem::linearize_times`]).
    pub mixed: MixedDerivative,
}

impl DesignLinearization {
    /// The optimizers' form, residuals and their derivatives multiplied by `residual_scale` (the design
    /// loop's `1 / √T₀`). Errors when `J` has not 3 rows per cloth vertex or a non-finite entry, or a
    /// residual names a cloth vertex beyond it.
    pub fn adjoint(self, residual_scale: Real) -> Result<Linearization, GaussNewtonError> {
        let bad = |m: String| Err(GaussNewtonError::Invalid(m));
        let r = &self.residuals;
        if r.values.is_empty() {
            return Ok(Linearization {
                residuals: Vec::new(),
                jacobian: Vec::new(),
                hessian: self.hessian,
                mixed: self.mixed,
            });
        }
        let j = self.cloth_jacobian.as_ref();
        if j.nrows() % 3 != 0 {
            return bad(format!(
                "the cloth Jacobian has {} rows, not 3 per vertex",
                j.nrows()
            ));
        }
        if j.val().iter().any(|v| !v.is_finite()) {
            return bad("the cloth Jacobian has a non-finite entry".into());
        }
        let nvc = j.nrows() / 3;
        if let Some(&(k, c, _)) = r.cloth_jacobian.iter().find(|(_, c, _)| *c >= nvc) {
            return bad(format!(
                "residual Jacobian entry ({k}, cloth vertex {c}) out of range"
            ));
        }
        // J row by row: cloth vertex c → (unknown, ∂x_c/∂q_j).
        let mut j_rows: Vec<Vec<(usize, [Real; 3])>> = vec![Vec::new(); nvc];
        let (cp, ri, v) = (j.symbolic().col_ptr(), j.symbolic().row_idx(), j.val());
        for c in 0..j.ncols() {
            for k in cp[c]..cp[c + 1] {
                let (r, v) = (ri[k], v[k]);
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
        }
        let s = residual_scale;
        let mut jacobian = Vec::new();
        // R_q = R_x J.
        for &(k, c, d) in &r.cloth_jacobian {
            let d = d * s;
            for &(q, e) in &j_rows[c] {
                jacobian.push((k, Unknown::State(q), d.x * e[0] + d.y * e[1] + d.z * e[2]));
            }
        }
        for &(k, v, d) in &r.pattern_jacobian {
            let d = d * s;
            jacobian.push((k, Unknown::Parameter(2 * v), d.x));
            jacobian.push((k, Unknown::Parameter(2 * v + 1), d.y));
        }
        // The direct part of R_q.
        for &(k, q, d) in &r.state_jacobian {
            jacobian.push((k, Unknown::State(q), d * s));
        }
        Ok(Linearization {
            residuals: r.values.iter().map(|v| v * s).collect(),
            jacobian,
            hessian: self.hessian,
            mixed: self.mixed,
        })
    }
}
