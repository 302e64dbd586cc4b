//! The first-order prediction of the equilibrium of a changed pattern (the predictor of a
//! predictor–corrector evaluation, [`crate::DesignProblem::set_predictor`]).
//!
//! At an equilibrium `g(q*, X̄) = ∂U/∂q = 0` of the pattern `X̄` (`#Vp × 2`, m), a pattern change `δX̄`
//! moves the equilibrium by, to first order,
//!
//! ```text
//! H δq = −K δX̄,      H = ∂²U/∂q² (at q*),   K = ∂²U/∂q∂X̄ (#q × 2#Vp, N/m),
//! ```
//!
//! the same linearization the adjoint gradient uses (thesis Eq. 160–164), read forwards. `H` is the
//! factorization the last equilibrium solve left ([`EquilibriumWorkspace::solve_hessian`], with the
//! damping it needed where `H` is not positive definite), `K` is
//! [`ClothOnBody::rest_mixed_matrix`] at the old rest shapes; the predicted state is `q* + δq`, the
//! cloth's surface coordinates walked across faces as a Newton step is ([`ClothOnBody::step`]). Units:
//! `δq` in the unknowns' units (surface coordinates, m for body positions).
//!
//! Newton then corrects from there: for a small `δX̄` it starts one quadratic-convergence step away
//! instead of `‖δq‖` away. No derivatives of its own: it is the derivative of the equilibrium map,
//! which `tests/design_gradient.rs` checks by finite differences through the solve.

use skintight_geometry::surface::walk::WalkParams;
use skintight_physics::{ClothOnBody, ClothOnBodyState, EquilibriumWorkspace};

use crate::design_mesh::DesignMesh;
use crate::math::{Real, Vec2};

/// The predicted equilibrium for the pattern `to` (`#Vp`, m) from the equilibrium `state` of `from`,
/// whose rest shapes `system` holds and whose final Hessian `workspace` holds. Errors (a message) when the
/// sizes disagree, a solve fails or the walk leaves the surface; `Ok(None)` when the pattern did not move.
pub fn predict_equilibrium(
    system: &ClothOnBody,
    state: &ClothOnBodyState,
    workspace: &mut EquilibriumWorkspace,
    mesh: &DesignMesh,
    from: &[Vec2],
    to: &[Vec2],
    walk: &WalkParams,
) -> Result<Option<ClothOnBodyState>, String> {
    if from.len() != to.len() || to.len() != mesh.num_pattern_vertices() {
        return Err(format!(
            "{} and {} pattern positions for {} pattern vertices",
            from.len(),
            to.len(),
            mesh.num_pattern_vertices()
        ));
    }
    let dx: Vec<Real> = to
        .iter()
        .zip(from)
        .flat_map(|(a, b)| [a.x - b.x, a.y - b.y])
        .collect();
    if dx.iter().all(|&d| d == 0.0) {
        return Ok(None);
    }
    let k = system
        .rest_mixed_matrix(state, &mesh.pattern_triangles, mesh.num_pattern_vertices())
        .map_err(|e| e.to_string())?;
    // rhs = −K δX̄ (column by column: K is stored by columns).
    let mut dq = vec![0.0; k.nrows()];
    let (col_ptr, row_idx, values) = (k.symbolic().col_ptr(), k.symbolic().row_idx(), k.val());
    for (j, &d) in dx.iter().enumerate() {
        if d != 0.0 {
            for p in col_ptr[j]..col_ptr[j + 1] {
                dq[row_idx[p]] -= values[p] * d;
            }
        }
    }
    workspace
        .solve_hessian(&mut dq)
        .map_err(|e| e.to_string())?;
    if dq.iter().any(|v| !v.is_finite()) {
        return Err("the predicted step is not finite".into());
    }
    system
        .step(state, &dq, walk)
        .map(Some)
        .map_err(|e| e.to_string())
}
