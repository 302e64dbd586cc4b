//! Traction-free pinned boundaries (thesis Eq. 188): a regularizer that asks the cloth vertices pinned to
//! the body (waistbands, cuffs) to carry no tangential force.
//!
//! A pinned cloth vertex `i` keeps its surface coordinates `s_i`, so the equilibrium leaves the energy's
//! derivative with respect to them, the tangential traction
//!
//! ```text
//! b_i = dU/ds_i = T_iᵀ f_i,     T_i = ∂x_i/∂s_i  (3 × 2, m),   f_i = Σ_{e ∋ i} ∂U_e/∂x_i  (N),
//! R = w Σ_{i pinned} ‖b_i‖²     (J² × w),
//! ```
//!
//! unbalanced (`U` the cloth energy: the body energy does not depend on `s`). `T_i` are the tangents of the
//! **deformed** body surface under the pinned vertex: they move with the body positions `y`, so the term
//! depends on the state directly, not only through the cloth positions ([`Term::evaluate_with_state`]).
//! `b_i` is in J per unit of surface coordinate (the coordinates are barycentric, so `b_i` is about the
//! tangential force times the size of the body face).
//!
//! # Derivatives
//!
//! With `u_i = 2w T_i b_i` (3-vector):
//! - `∂R/∂x` = `Σ_i Σ_{e ∋ i} H_e[i, :]ᵀ u_i` with the element Hessians `H_e = ∂²U_e/∂x²`;
//! - `∂R/∂X̄` = `Σ_i Σ_{e ∋ i} M_e[i, :]ᵀ u_i` with the mixed `M_e = ∂²U_e/∂x∂X̄`;
//! - `∂R/∂y_v` (direct, through the tangents `δT_i = Σ_v δy_v (∂w_v/∂s)ᵀ`,
//!   [`skintight_physics::ClothOnBody::tangent_body_derivatives`]) = `2w (b_i · ∂w_v/∂s) f_i`.
//!
//! It is a sum of squares: two residuals `√w b_i` per pinned vertex, with Jacobians from the same blocks.
//!
//! Without the state ([`Term::evaluate`]) the term cannot be evaluated and says so.

use crate::math::{Mat3x2, Real, Vec2, Vec3};
use crate::term::{
    Residuals, StateInput, Term, TermError, TermEvaluation, TermGradient, TermInput, check_weight,
};
use skintight_physics::MembraneElement;

const NAME: &str = "pinned_traction";

/// The traction-free pinned-boundary regularizer of Eq. 188; see the module documentation. `per_element`
/// of its evaluation has one entry per cloth vertex (`#Vc`; zero for unpinned vertices).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PinnedTraction {
    weight: Real,
}

/// What one pinned vertex needs: its tangents, force and traction.
struct Pinned {
    vertex: usize,
    tangents: Mat3x2,
    force: Vec3,
    traction: Vec2,
}

impl PinnedTraction {
    /// The term with weight `w` (≥ 0, finite; per J²).
    pub fn new(weight: Real) -> Result<Self, TermError> {
        Ok(Self {
            weight: check_weight(NAME, "weight", weight)?,
        })
    }

    fn element(input: &TermInput, t: usize) -> Result<(MembraneElement, [Vec3; 3]), TermError> {
        let rest = input.mesh.pattern_triangles[t].map(|v| input.pattern[v]);
        let x = input.mesh.cloth_triangles[t].map(|v| input.cloth[v]);
        let element = input
            .fabric
            .element(t, rest)
            .map_err(|_| TermError::Collapsed {
                term: NAME,
                triangle: t,
            })?;
        Ok((element, x))
    }

    /// The pinned vertices with their tangents, forces and tractions; the flags of which cloth vertices
    /// are pinned.
    fn pinned(
        &self,
        input: &TermInput,
        state: &StateInput,
    ) -> Result<(Vec<Pinned>, Vec<Option<usize>>), TermError> {
        state.validate(NAME, input, None)?;
        let system = state.system;
        let nc = input.mesh.num_cloth_vertices;
        let mut slot = vec![None; nc];
        let mut pinned = Vec::new();
        let invalid = |e: &dyn std::fmt::Display| TermError::Invalid {
            term: NAME,
            message: e.to_string(),
        };
        if (0..nc).all(|c| system.cloth_dof(c).is_some()) {
            return Ok((pinned, slot));
        }
        let points = system
            .cloth_surface_points(state.state)
            .map_err(|e| invalid(&e))?;
        for (c, s) in slot.iter_mut().enumerate() {
            if system.cloth_dof(c).is_none() {
                *s = Some(pinned.len());
                pinned.push(Pinned {
                    vertex: c,
                    tangents: points[c].tangents,
                    force: Vec3::zeros(),
                    traction: Vec2::zeros(),
                });
            }
        }
        let density = input.fabric.law();
        for (t, tri) in input.mesh.cloth_triangles.iter().enumerate() {
            if tri.iter().all(|&c| slot[c].is_none()) {
                continue;
            }
            let (element, x) = Self::element(input, t)?;
            let (_, g) =
                element
                    .energy_gradient(density, &x)
                    .map_err(|_| TermError::Collapsed {
                        term: NAME,
                        triangle: t,
                    })?;
            for (k, &c) in tri.iter().enumerate() {
                if let Some(i) = slot[c] {
                    pinned[i].force += Vec3::new(g[3 * k], g[3 * k + 1], g[3 * k + 2]);
                }
            }
        }
        for p in &mut pinned {
            p.traction = p.tangents.transpose() * p.force;
        }
        Ok((pinned, slot))
    }

    /// Calls `visit(t, k, pinned index, H_e, M_e)` for every pinned corner `k` of every cloth triangle `t`.
    fn for_each_pinned_corner(
        input: &TermInput,
        slot: &[Option<usize>],
        mut visit: impl FnMut(
            usize,
            usize,
            usize,
            &skintight_physics::membrane_element::Matrix9,
            &skintight_physics::membrane_element::Matrix9x6,
        ),
    ) -> Result<(), TermError> {
        let density = input.fabric.law();
        for (t, tri) in input.mesh.cloth_triangles.iter().enumerate() {
            if tri.iter().all(|&c| slot[c].is_none()) {
                continue;
            }
            let (element, x) = Self::element(input, t)?;
            let collapsed = |_| TermError::Collapsed {
                term: NAME,
                triangle: t,
            };
            let d = element.derivatives(density, &x).map_err(collapsed)?;
            let m = element.mixed_hessian(density, &x).map_err(collapsed)?;
            for (k, &c) in tri.iter().enumerate() {
                if let Some(i) = slot[c] {
                    visit(t, k, i, &d.hessian, &m);
                }
            }
        }
        Ok(())
    }
}

impl Term for PinnedTraction {
    fn name(&self) -> &'static str {
        NAME
    }

    fn evaluate(
        &self,
        _input: &TermInput,
        _gradient: Option<&mut TermGradient>,
    ) -> Result<TermEvaluation, TermError> {
        Err(TermError::Invalid {
            term: NAME,
            message: "the pinned traction needs the coupled state (the body surface's tangents)"
                .into(),
        })
    }

    fn evaluate_with_state(
        &self,
        input: &TermInput,
        state: &StateInput,
        gradient: Option<&mut TermGradient>,
        state_gradient: Option<&mut [Real]>,
    ) -> Result<TermEvaluation, TermError> {
        input.validate(NAME, gradient.as_deref())?;
        state.validate(NAME, input, state_gradient.as_deref())?;
        let (pinned, slot) = self.pinned(input, state)?;
        let mut per_element = vec![0.0; input.mesh.num_cloth_vertices];
        for p in &pinned {
            per_element[p.vertex] = self.weight * p.traction.norm_squared();
        }
        let eval = TermEvaluation::from_per_element(NAME, per_element)?;
        if let Some(g) = gradient {
            let u: Vec<Vec3> = pinned
                .iter()
                .map(|p| p.tangents * p.traction * (2.0 * self.weight))
                .collect();
            Self::for_each_pinned_corner(input, &slot, |t, k, i, h, m| {
                let tri = input.mesh.cloth_triangles[t];
                let ptri = input.mesh.pattern_triangles[t];
                for (j, &c) in tri.iter().enumerate() {
                    g.cloth[c] += h.fixed_view::<3, 3>(3 * k, 3 * j).transpose() * u[i];
                }
                for (j, &v) in ptri.iter().enumerate() {
                    g.pattern[v] += m.fixed_view::<3, 2>(3 * k, 2 * j).transpose() * u[i];
                }
            })?;
        }
        if let Some(sg) = state_gradient
            && !pinned.is_empty()
        {
            let stencils = state
                .system
                .tangent_body_derivatives(state.state)
                .map_err(|e| TermError::Invalid {
                    term: NAME,
                    message: e.to_string(),
                })?;
            for p in &pinned {
                for &(d, dw) in &stencils[p.vertex] {
                    let a = 2.0 * self.weight * p.traction.dot(&dw);
                    for j in 0..3 {
                        sg[d + j] += a * p.force[j];
                    }
                }
            }
        }
        Ok(eval)
    }

    fn residuals_with_state(
        &self,
        input: &TermInput,
        state: &StateInput,
    ) -> Option<Result<Residuals, TermError>> {
        Some((|| {
            input.validate(NAME, None)?;
            let (pinned, slot) = self.pinned(input, state)?;
            let root = self.weight.sqrt();
            let mut res = Residuals {
                values: pinned
                    .iter()
                    .flat_map(|p| [root * p.traction.x, root * p.traction.y])
                    .collect(),
                ..Residuals::default()
            };
            Self::for_each_pinned_corner(input, &slot, |t, k, i, h, m| {
                let tri = input.mesh.cloth_triangles[t];
                let ptri = input.mesh.pattern_triangles[t];
                for a in 0..2 {
                    let ta = pinned[i].tangents.column(a) * root;
                    for (j, &c) in tri.iter().enumerate() {
                        let d = h.fixed_view::<3, 3>(3 * k, 3 * j).transpose() * ta;
                        res.cloth_jacobian.push((2 * i + a, c, d));
                    }
                    for (j, &v) in ptri.iter().enumerate() {
                        let d = m.fixed_view::<3, 2>(3 * k, 2 * j).transpose() * ta;
                        res.pattern_jacobian.push((2 * i + a, v, d));
                    }
                }
            })?;
            if !pinned.is_empty() {
                let stencils = state
                    .system
                    .tangent_body_derivatives(state.state)
                    .map_err(|e| TermError::Invalid {
                        term: NAME,
                        message: e.to_string(),
                    })?;
                for (i, p) in pinned.iter().enumerate() {
                    for &(d, dw) in &stencils[p.vertex] {
                        for a in 0..2 {
                            for j in 0..3 {
                                res.state_jacobian.push((
                                    2 * i + a,
                                    d + j,
                                    root * dw[a] * p.force[j],
                                ));
                            }
                        }
                    }
                }
            }
            Ok(res)
        })())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_weights_are_refused() {
        for w in [-1.0, Real::NAN, Real::INFINITY] {
            assert!(matches!(
                PinnedTraction::new(w),
                Err(TermError::Parameter { .. })
            ));
        }
        assert!(PinnedTraction::new(0.0).is_ok());
    }
}
