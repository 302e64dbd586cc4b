//! The linearization of a least-squares objective constrained by an equilibrium, what the adjoint
//! Gauss-Newton directions are built from ([`mod@crate::kkt_direction`], [`mod@crate::reduced_direction`]).
//!
//! **Model.** A state `q` (`#q` unknowns) is at equilibrium, `∂U/∂q (q, p) = 0`, for parameters `p`
//! (`#p`) that follow the optimizer's variables `c` (`#c`) through a constant linear map `A = dp/dc`
//! (`#p × #c`, the *parameter map*). Residuals `r(q, p)` (`#r`, `T_res = Σ r²`) have the Jacobians
//! `R_q = ∂r/∂q` (`#r × #q`) and `R_p = ∂r/∂p` (`#r × #p`). With `H = ∂²U/∂q²` and `K = ∂²U/∂q∂p`
//! (`#q × #p`) the linearized equilibrium is `H dq + K dp = 0`, so `dq = S dc`, `S = −H⁻¹ K A`, and the
//! residuals change by `R_tot dc`, `R_tot = R_q S + R_p A`. The Gauss-Newton model of the whole objective
//! `T` is
//!
//! ```text
//! m(dc) = T + gᵀ dc + ½ dcᵀ (2 R_totᵀ R_tot + κ I) dc,     g = dT/dc (the full gradient),
//! ```
//!
//! whose minimizer solves `(2 R_totᵀ R_tot + κ I) dc = −g`. The right-hand side is the **full** gradient
//! (adjoint, all terms), so parts of the objective without residuals still enter to first order; the
//! matrix holds the Gauss-Newton curvature of the residuals only, plus the Levenberg-Marquardt damping
//! `κ I` (units of `T` per unit² of `c`).
//!
//! Pattern design: `q` the cloth and body coordinates, `p` the pattern positions, `c` boundary positions
//! or mode coefficients. Fitting per-element material parameters to simulated frames (knitwear paper
//! Eq. 21): `q` the frames' positions, `p` the material parameters, `A` their parametrization. Units are
//! the problem's; only their consistency matters.
//!
//! **Why entries, not matrices, for the residual Jacobian.** Residuals are local (a few unknowns each)
//! and come from many terms; a list of `(residual, unknown, value)` entries whose repeats add up is what
//! the terms produce, and it keeps the order in which the KKT system is assembled (and so its bits) the
//! caller's.

use faer::sparse::{SparseColMat, SparseColMatRef};

use crate::Real;

/// Which unknown a residual-Jacobian entry differentiates by.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unknown {
    /// State unknown `q_i` (an entry of `R_q`).
    State(usize),
    /// Parameter `p_i` (an entry of `R_p`).
    Parameter(usize),
}

/// `K = ∂²U/∂q∂p`, or only its product with the parameter map.
#[derive(Clone, Debug)]
pub enum MixedDerivative {
    /// `K` (`#q × #p`): what the KKT system needs.
    Matrix(SparseColMat<usize, Real>),
    /// `K A` (`#q × #c`, column-major), e.g. formed matrix-free: all the reduced direction needs,
    /// without building `K`. The KKT system cannot use it.
    TimesParameterMap(Vec<Real>),
}

/// The form of `K` a direction asks [`crate::AdjointProblem::linearization`] for.
#[derive(Clone, Copy, Debug)]
pub enum MixedForm<'a> {
    /// [`MixedDerivative::Matrix`].
    Matrix,
    /// [`MixedDerivative::TimesParameterMap`] for the parameter map `A` given by rows (`#p × columns`,
    /// row-major).
    TimesParameterMap {
        /// `A` row after row.
        rows: &'a [Real],
        /// `#c`.
        columns: usize,
    },
}

/// The problem linearized at an equilibrium (see the module documentation for the symbols).
#[derive(Clone, Debug)]
pub struct Linearization {
    /// `r` (`#r`, √T).
    pub residuals: Vec<Real>,
    /// The entries `(k, unknown, ∂r_k/∂unknown)` of `R_q` and `R_p`; repeats of one pair add up, in this
    /// order.
    pub jacobian: Vec<(usize, Unknown, Real)>,
    /// `H` (`#q × #q`), **lower triangle only** (row ≥ column), symmetric positive definite: the matrix the
    /// adjoint solves with.
    pub hessian: SparseColMat<usize, Real>,
    /// `K` or `K A`.
    pub mixed: MixedDerivative,
}

/// What a Gauss-Newton direction is solved from.
#[derive(Clone, Copy, Debug)]
pub struct GaussNewtonSystem<'a> {
    /// The linearization at the current point.
    pub linearization: &'a Linearization,
    /// `A = dp/dc` (`#p × #c`), constant over a run.
    pub parameter_map: SparseColMatRef<'a, usize, Real>,
    /// `g = dT/dc` (`#c`, T per unit of `c`): the full gradient.
    pub gradient: &'a [Real],
}

/// A Gauss-Newton direction.
#[derive(Clone, Debug, PartialEq)]
pub struct GaussNewtonDirection {
    /// `dc` (`#c`, units of `c`).
    pub variables: Vec<Real>,
    /// The predicted change of the state `dq = S dc` (`#q`).
    pub state: Vec<Real>,
    /// The predicted change of the parameters `dp = A dc` (`#p`).
    pub parameters: Vec<Real>,
    /// Relative residual of the solve (KKT: `‖b − M z‖ / ‖b‖`; reduced: of the normal equations over
    /// `‖g‖`; dimensionless).
    pub residual: Real,
    /// Whether the symbolic analysis of the previous system was reused.
    pub reused_analysis: bool,
}

/// Why a Gauss-Newton direction could not be computed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum GaussNewtonError {
    /// Inputs of inconsistent sizes or non-finite values; the message names the input.
    #[error("adjoint Gauss-Newton: {0}")]
    Invalid(String),
    /// The system could not be factored or its solution is not usable.
    #[error("adjoint Gauss-Newton: the system could not be solved: {0}")]
    Solve(String),
}

/// Entries of a column-compressed matrix as `(row, column, value)`.
pub(crate) fn entries(
    m: SparseColMatRef<'_, usize, Real>,
) -> impl Iterator<Item = (usize, usize, Real)> + '_ {
    let (cp, ri, v) = (m.symbolic().col_ptr(), m.symbolic().row_idx(), m.val());
    (0..m.ncols()).flat_map(move |c| (cp[c]..cp[c + 1]).map(move |k| (ri[k], c, v[k])))
}

/// The first residual-Jacobian entry out of range (`#r` residuals, `#q` state unknowns, `#p`
/// parameters), named for the error message.
pub(crate) fn out_of_range(
    jacobian: &[(usize, Unknown, Real)],
    residuals: usize,
    unknowns: usize,
    parameters: usize,
) -> Option<String> {
    jacobian.iter().find_map(|&(k, u, _)| {
        let fits = k < residuals
            && match u {
                Unknown::State(q) => q < unknowns,
                Unknown::Parameter(p) => p < parameters,
            };
        (!fits).then(|| format!("residual Jacobian entry ({k}, {u:?}) out of range"))
    })
}

/// The parameter map `A` (`rows × columns`) as a sparse matrix from its columns (`column(i)` = `A e_i`),
/// exact zeros left out. Errors name the column whose length or entries are wrong.
pub fn parameter_map_matrix(
    rows: usize,
    columns: usize,
    mut column: impl FnMut(usize) -> Result<Vec<Real>, String>,
) -> Result<SparseColMat<usize, Real>, GaussNewtonError> {
    let mut triplets = Vec::new();
    for c in 0..columns {
        let col = column(c).map_err(GaussNewtonError::Invalid)?;
        if col.len() != rows {
            return Err(GaussNewtonError::Invalid(format!(
                "parameter map column {c} has {} entries for {rows} rows",
                col.len()
            )));
        }
        for (r, &v) in col.iter().enumerate() {
            if !v.is_finite() {
                return Err(GaussNewtonError::Invalid(format!(
                    "parameter map entry ({r}, {c}) is not finite"
                )));
            }
            if v != 0.0 {
                triplets.push(faer::sparse::Triplet::new(r, c, v));
            }
        }
    }
    SparseColMat::try_new_from_triplets(rows, columns, &triplets)
        .map_err(|e| GaussNewtonError::Invalid(format!("parameter map: {e:?}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_parameter_map_drops_zeros_and_refuses_bad_columns() {
        assert!(parameter_map_matrix(3, 2, |_| Ok(vec![0.0; 2])).is_err());
        assert!(parameter_map_matrix(2, 1, |_| Ok(vec![Real::NAN, 0.0])).is_err());
        let a = parameter_map_matrix(2, 2, |c| {
            Ok(if c == 0 {
                vec![1.0, 0.0]
            } else {
                vec![0.0, 2.0]
            })
        })
        .unwrap();
        assert_eq!(a.compute_nnz(), 2);
        let jacobian = [(0, Unknown::State(1), 1.0), (1, Unknown::Parameter(2), 1.0)];
        assert_eq!(out_of_range(&jacobian, 2, 2, 3), None);
        assert!(
            out_of_range(&jacobian, 2, 2, 2)
                .unwrap()
                .contains("Parameter(2)")
        );
    }
}
