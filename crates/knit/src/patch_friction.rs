//! The yarn–yarn friction of a whole patch over one time step: the lagged dissipation potential of
//! [`crate::yarn_friction`] summed over the segment pairs in contact at the step's start,
//!
//! `D(x) = Σ_pairs D_pair(x_pair)`,  `D_pair = μ Σ_q λ_q f₀(|P_q Δw_q|)` (J)
//!
//! - the pairs are the contact candidates ([`crate::patch::PatchModel::contact_candidates`]: spatial hash,
//!   exclusions removed) at the step's start `xⁿ` (m) with at least one quadrature point pair closer than
//!   the contact distance; each keeps its 12 global unknowns (the positions of its two segments' end
//!   points; the material angles meet no friction);
//! - everything a pair needs is frozen at `xⁿ` — the normal forces `λ_q` (N) the contact law exerts
//!   there, the normals, the tangent projectors and `xⁿ` itself — so over the step `D` is a function of
//!   the positions alone, convex per quadrature point pair, and the backward Euler step stays one
//!   minimisation ([`crate::implicit_euler`] adds `D` to the incremental potential);
//! - `μ` (dimensionless) the friction coefficient, `ε` (m) the slip below which static friction is
//!   smoothed ([`crate::yarn_friction`]): a yarn held by friction creeps at most about `ε` per step.
//!
//! Derivatives: each pair's gradient (N) and Hessian (N/m, positive semidefinite) in closed form
//! ([`crate::yarn_friction`], derived and tested there) scattered onto the global unknowns, the Hessian's
//! lower triangle as sparse triplets like [`crate::patch::PatchModel::evaluate`]'s; the sum of positive
//! semidefinite blocks stays positive semidefinite, so Newton's shifted Cholesky sees no new indefinite
//! direction. The tests check the assembled sum against central differences on a patch whose pairs stick,
//! slide and straddle `ε`.
//!
//! With `μ = 0` there are no pairs (no candidate search), and a step adds nothing: frictionless runs are
//! unchanged to the bit.

use faer::sparse::Triplet;

use crate::contact::{CONTACT_DOFS, ContactPair};
use crate::patch::PatchModel;
use crate::yarn_friction::FrictionPair;

/// The friction of a patch over one time step (module documentation); empty when frictionless.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PatchFriction {
    /// Each pair's 12 global unknowns (positions of `p₀, p₁, q₀, q₁`) and its lagged friction.
    pairs: Vec<([usize; CONTACT_DOFS], FrictionPair)>,
}

impl PatchFriction {
    /// The friction over a step from `start` (the patch unknowns at `xⁿ`: m and rad, 4 per vertex) with
    /// coefficient `coefficient` (dimensionless, ≥ 0) and smoothing slip `slip` (m, > 0); empty when
    /// `coefficient` is 0. The error names the bad value.
    pub fn new(
        model: &PatchModel,
        start: &[f64],
        coefficient: f64,
        slip: f64,
    ) -> Result<Self, String> {
        Self::validate(coefficient, slip)?;
        if start.len() != model.dof_count() {
            return Err(format!(
                "the friction's start state has {} unknowns; the patch has {}",
                start.len(),
                model.dof_count()
            ));
        }
        if coefficient == 0.0 {
            return Ok(Self::default());
        }
        let stiffness = model.stiffness();
        let mut pairs = Vec::new();
        for (e1, e2) in model.contact_candidates(start) {
            let (dofs, rest_lengths) = model.contact_dofs(e1, e2);
            let contact = ContactPair {
                rest_lengths,
                contact_distance: stiffness.contact_distance,
                stiffness: stiffness.contact,
                kernel: stiffness.contact_kernel,
            };
            let q: [f64; CONTACT_DOFS] = std::array::from_fn(|k| start[dofs[k]]);
            if let Some(pair) = FrictionPair::new(&contact, &q, coefficient, slip)? {
                pairs.push((dofs, pair));
            }
        }
        Ok(Self { pairs })
    }

    /// Checks the settings: `coefficient` (dimensionless) a number ≥ 0, `slip` (m) a number > 0; the
    /// message names the setting.
    pub fn validate(coefficient: f64, slip: f64) -> Result<(), String> {
        if !(coefficient.is_finite() && coefficient >= 0.0) {
            return Err(format!(
                "friction_coefficient = {coefficient} must be a number ≥ 0 (0: frictionless)"
            ));
        }
        if !(slip.is_finite() && slip > 0.0) {
            return Err(format!(
                "friction_slip = {slip} m must be a number > 0 (e.g. 1e-6 m)"
            ));
        }
        Ok(())
    }

    /// Segment pairs with friction.
    pub fn len(&self) -> usize {
        self.pairs.len()
    }

    /// Whether no pair has friction (frictionless, or nothing in contact at the start).
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// The Coulomb bound `μ Σ λ` summed over the pairs (N).
    pub fn bound(&self) -> f64 {
        self.pairs.iter().map(|(_, p)| p.bound()).sum()
    }

    /// The dissipation potential `D` (J) at the patch unknowns `x`.
    pub fn energy(&self, x: &[f64]) -> f64 {
        let mut energy = 0.0;
        self.add_energy(x, &mut energy);
        energy
    }

    /// Adds `D` (J) at `x` to `energy`, pair after pair: the same bits as [`Self::add_derivatives`]'s.
    pub fn add_energy(&self, x: &[f64], energy: &mut f64) {
        for (dofs, p) in &self.pairs {
            *energy += p.energy(&std::array::from_fn(|k| x[dofs[k]]));
        }
    }

    /// The tangential slips (m) of every touching point pair at the patch unknowns `x`.
    #[cfg(test)]
    pub(crate) fn slips(&self, x: &[f64]) -> Vec<f64> {
        self.pairs
            .iter()
            .flat_map(|(dofs, p)| p.slips(&std::array::from_fn(|k| x[dofs[k]])))
            .collect()
    }

    /// Adds `D` (J) at `x` to `energy`, its gradient (N) to `gradient` (`#dofs`) and, if `hessian`, its
    /// Hessian's lower-triangle entries (N/m; row ≥ column) to `triplets`.
    pub fn add_derivatives(
        &self,
        x: &[f64],
        hessian: bool,
        energy: &mut f64,
        gradient: &mut [f64],
        triplets: &mut Vec<Triplet<usize, usize, f64>>,
    ) {
        for (dofs, p) in &self.pairs {
            let q: [f64; CONTACT_DOFS] = std::array::from_fn(|k| x[dofs[k]]);
            let (e, g, h) = p.derivatives(&q, hessian);
            *energy += e;
            for k in 0..CONTACT_DOFS {
                gradient[dofs[k]] += g[k];
            }
            if hessian {
                for a in 0..CONTACT_DOFS {
                    for b in 0..CONTACT_DOFS {
                        let (r, c) = (dofs[a], dofs[b]);
                        if r >= c && h[a][b] != 0.0 {
                            triplets.push(Triplet::new(r, c, h[a][b]));
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
pub(crate) mod tests;
