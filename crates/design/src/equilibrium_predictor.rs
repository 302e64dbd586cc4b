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
//! damping it needed where `H` is not positive definite), `K δX̄` is
//! [`ClothOnBody::rest_mixed_apply`] at the old rest shapes; the predicted state is `q* + δq`, the
//! cloth's surface coordinates walked across faces as a Newton step is ([`ClothOnBody::step`], by
//! [`crate::DesignProblem::evaluate`]). Units:
//! `δq` in the unknowns' units (surface coordinates, m for body positions).
//!
//! Newton then corrects from there: for a small `δX̄` it starts one quadratic-convergence step away
//! instead of `‖δq‖` away. No derivatives of its own: it is the derivative of the equilibrium map,
//! which `tests/design_gradient.rs` checks by finite differences through the solve.

use skintight_physics::{ClothOnBody, ClothOnBodyState, EquilibriumWorkspace};

use crate::design_mesh::DesignMesh;
use crate::math::{Real, Vec2};

/// The first-order change `δq` (`#q`, the unknowns' units) of the equilibrium `state` of `from` when the
/// pattern becomes `to`: `H δq = −K (to − from)`, with the Hessian `workspace` holds and the rest shapes
/// `system` holds (both `from`'s). Linear in `to − from`, so a change along the same line is `δq` scaled
/// (what a line search's trials use, [`crate::DesignProblem::evaluate`]). Errors (a message) when the
/// sizes disagree or the solve fails; `Ok(None)` when the pattern did not move.
pub fn equilibrium_change(
    system: &ClothOnBody,
    state: &ClothOnBodyState,
    workspace: &mut EquilibriumWorkspace,
    mesh: &DesignMesh,
    from: &[Vec2],
    to: &[Vec2],
) -> Result<Option<Vec<Real>>, String> {
    if from.len() != to.len() || to.len() != mesh.num_pattern_vertices() {
        return Err(format!(
            "{} and {} pattern positions for {} pattern vertices",
            from.len(),
            to.len(),
            mesh.num_pattern_vertices()
        ));
    }
    if to.iter().zip(from).all(|(a, b)| a == b) {
        return Ok(None);
    }
    // rhs = −K δX̄, matrix-free per triangle (building K costs more than the whole corrector).
    let change: Vec<[Vec2; 3]> = mesh
        .pattern_triangles
        .iter()
        .map(|t| t.map(|v| to[v] - from[v]))
        .collect();
    let mut dq = system
        .rest_mixed_apply(state, &change)
        .map_err(|e| e.to_string())?;
    for v in &mut dq {
        *v = -*v;
    }
    workspace
        .solve_hessian(&mut dq)
        .map_err(|e| e.to_string())?;
    if dq.iter().any(|v| !v.is_finite()) {
        return Err("the predicted step is not finite".into());
    }
    Ok(Some(dq))
}
