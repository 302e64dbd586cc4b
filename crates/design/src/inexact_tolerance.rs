//! Inexact equilibria where they are safe: the equilibrium tolerance of each design evaluation tied to the
//! optimizer's progress, loose far from the optimum and as tight as the job asks near it.
//!
//! **Error of the gradient.** An equilibrium solved to the relative residual `τ` ([`skintight_physics::equilibrium`]:
//! unbalanced forces `f` with `‖f‖ < τ F`, `F` the force scale) is off the exact one by `δq ≈ −H⁻¹ f`, and
//! the adjoint gradient computed there is off by `δg ≈ (dg/dq) δq`: to first order linear in the residual,
//!
//! ```text
//! ‖δg‖ ≤ L τ,
//! ```
//!
//! with `L` a constant of the problem at the design (the design gradient's sensitivity to unbalanced
//! forces, per unit of relative residual; in the optimizer's normalized units, dimensionless).
//!
//! **Schedule.** With `‖g̃_k‖` the normalized gradient at the accepted design `k` ([`mod@crate::pattern_design`]:
//! dimensionless), `ε_g` the optimizer's gradient tolerance and `τ` the job's equilibrium tolerance, every
//! evaluation from design `k` (line-search trials included) is solved to
//!
//! ```text
//! τ_k = clamp(τ ‖g̃_k‖ / ε_g,  τ,  τ_max),
//! ```
//!
//! which keeps the **relative** gradient error `‖δg‖ / ‖g̃_k‖ ≤ L τ / ε_g` — the relative error the tight
//! solve has where the optimizer stops. Where the gradient is still large the solves stop early; once it
//! falls to the stopping tolerance they are as tight as the job asks, and the stopping test itself is on a
//! tight gradient. A relative error below 1 keeps the direction a descent direction, the condition under
//! which gradient and trust-region methods converge with inexact gradients (R. G. Carter, "On the global
//! convergence of trust region algorithms using inexact gradient information", SIAM J. Numer. Anal. 28,
//! 1991). `τ_max` bounds the tolerance where `‖g̃_k‖` is large (and before the first accepted design, where it
//! is not known yet) — and throughout a job whose `ε_g` is so small that even the tight solve's gradient
//! error exceeds it (such a job cannot meet its stopping test by the gradient and runs to its limits); `tests/design_inexact.rs` measures the directional derivative at `τ_max` against
//! central differences of tightly solved objectives.
//!
//! **Error of the objective.** The same residual moves the objective: the exact equilibrium is
//! `δq = −H⁻¹ g` away (`g = ∂U/∂q` at the solved state), so to first order
//!
//! ```text
//! T_exact − T ≈ −λᵀ g,     λ = H⁻¹ ∂T/∂q       (units of T),
//! ```
//!
//! with `λ` the adjoint the gradient already solves for ([`crate::DesignEvaluation::value_error`] is
//! `|λᵀ g|`). Terms that measure displacements barely see a small residual; terms that measure forces
//! (sliding's friction excess, seam traction, band pressures) see it at the size of the unbalanced forces
//! themselves: on the sliding pants the estimate is about 0.6 % of `T` at a residual of 3·10⁻⁴ (from the
//! re-solves' targets, docs/BENCHMARKS.md), against 10⁻⁵ of `T` for a shape objective at a similar
//! residual (`tests/design_inexact.rs`). So an
//! evaluation whose estimated error exceeds `ε_T |T|` ([`InexactTolerance::objective_error`]) is solved
//! again, on from its state, to the residual that brings the estimate within half the bound — the error is
//! linear in the residual `r` reached: `τ' = max(τ, ½ r ε_T |T| / |λᵀ g|)`, at most `r / 2` — until it is
//! within the bound or solved to `τ` ([`InexactTolerance::tighter`]).

use crate::math::Real;

/// Settings of the inexact-equilibrium schedule (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InexactTolerance {
    /// The loosest relative residual an evaluation is solved to, `τ_max` (dimensionless, > 0). Default
    /// `10⁻³`.
    pub loosest: Real,
    /// The largest first-order error of an evaluation's objective its residual may cause, relative to
    /// the objective, `ε_T` (`|λᵀ g| / |T|`, dimensionless, > 0). Default `10⁻³`: below the relative
    /// decrease of an accepted step on the benchmark designs until their last iterations, where the
    /// gradient schedule has tightened the solves anyway.
    pub objective_error: Real,
}

impl Default for InexactTolerance {
    fn default() -> Self {
        Self {
            loosest: 1e-3,
            objective_error: 1e-3,
        }
    }
}

impl InexactTolerance {
    /// Checks the settings; the message names the field.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.loosest.is_finite() && self.loosest > 0.0 && self.loosest < 1.0) {
            return Err(format!(
                "loosest must be a relative residual in (0, 1), got {}",
                self.loosest
            ));
        }
        if !(self.objective_error.is_finite() && self.objective_error > 0.0) {
            return Err(format!(
                "objective_error must be a positive fraction of the objective, got {}",
                self.objective_error
            ));
        }
        Ok(())
    }

    /// The tolerance to solve an evaluation again to, on from its state, when its objective `value` (units
    /// of T) carries the estimated error `value_error` (`|λᵀ g|`, same units) at the relative residual
    /// `residual` it reached: `None` when the error is within `objective_error · |value|` or the solve is
    /// already at the job's tolerance `tight`; otherwise `max(tight, ½ residual · bound / value_error)`,
    /// at most half the residual (see the module documentation).
    pub fn tighter(
        &self,
        tight: Real,
        residual: Real,
        value: Real,
        value_error: Real,
    ) -> Option<Real> {
        let bound = self.objective_error * value.abs();
        if !(residual > tight) || !(value_error > bound) {
            return None;
        }
        Some((0.5 * residual * (bound / value_error).min(1.0)).max(tight))
    }

    /// The tolerance `τ_k` for the evaluations from a design whose normalized gradient norm is
    /// `gradient_norm` (`+∞` or NaN: not known yet, the loosest), with the job's tolerance `tight` and the
    /// optimizer's gradient tolerance `gradient_tolerance` (0: always `tight`). Never below `tight`.
    pub fn tolerance(&self, tight: Real, gradient_norm: Real, gradient_tolerance: Real) -> Real {
        let loosest = self.loosest.max(tight);
        if !(gradient_tolerance > 0.0) {
            return tight;
        }
        if !(gradient_norm < Real::INFINITY) {
            return loosest;
        }
        (tight * gradient_norm / gradient_tolerance).clamp(tight, loosest)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tolerance_follows_the_gradient_between_the_tight_and_the_loosest() {
        let s = InexactTolerance {
            loosest: 1e-3,
            ..Default::default()
        };
        // At the stopping tolerance and below: as tight as the job asks.
        assert_eq!(s.tolerance(1e-6, 1e-3, 1e-3), 1e-6);
        assert_eq!(s.tolerance(1e-6, 1e-5, 1e-3), 1e-6);
        // In proportion in between.
        assert!((s.tolerance(1e-6, 5e-2, 1e-3) - 5e-5).abs() < 1e-18);
        // Bounded by the loosest, which an unknown gradient gets.
        assert_eq!(s.tolerance(1e-6, 10.0, 1e-3), 1e-3);
        assert_eq!(s.tolerance(1e-6, Real::INFINITY, 1e-3), 1e-3);
        assert_eq!(s.tolerance(1e-6, Real::NAN, 1e-3), 1e-3);
        // A job tighter than nothing: never looser than the loosest, never tighter than the job.
        assert_eq!(s.tolerance(1e-2, 1e-3, 1e-3), 1e-2);
        // No gradient tolerance: no schedule.
        assert_eq!(s.tolerance(1e-6, 1.0, 0.0), 1e-6);
        assert!(s.validate().is_ok());
        for bad in [0.0, -1e-3, 1.0, Real::NAN, Real::INFINITY] {
            let e = InexactTolerance {
                loosest: bad,
                ..Default::default()
            }
            .validate()
            .unwrap_err();
            assert!(e.contains("loosest"), "{e}");
        }
    }

    #[test]
    fn an_objective_misread_beyond_its_bound_is_solved_again_tighter() {
        let s = InexactTolerance {
            loosest: 1e-3,
            objective_error: 1e-3,
        };
        // Within the bound (1e-3 of T = 100: 0.1): as it is.
        assert_eq!(s.tighter(1e-6, 5e-4, 100.0, 0.1), None);
        assert_eq!(s.tighter(1e-6, 5e-4, -100.0, 0.05), None);
        // 10 × the bound: the residual that brings it to half the bound, linear in the residual.
        let t = s.tighter(1e-6, 5e-4, 100.0, 1.0).unwrap();
        assert!((t - 5e-4 * 0.5 * 0.1).abs() < 1e-15, "{t}");
        // Just above the bound: at least halved.
        let t = s.tighter(1e-6, 5e-4, 100.0, 0.1000001).unwrap();
        assert!((t - 2.5e-4).abs() < 1e-9, "{t}");
        // Never below the job's tolerance; nothing to do once there.
        assert_eq!(s.tighter(1e-6, 5e-4, 100.0, 1e6).unwrap(), 1e-6);
        assert_eq!(s.tighter(1e-6, 9e-7, 100.0, 1e6), None);
        // An objective of 0 with any error, and a NaN error: solved tight / left (NaN is not "above").
        assert_eq!(s.tighter(1e-6, 5e-4, 0.0, 1e-12).unwrap(), 1e-6);
        assert_eq!(s.tighter(1e-6, 5e-4, 100.0, Real::NAN), None);
        for bad in [0.0, -1e-3, Real::NAN, Real::INFINITY] {
            let e = InexactTolerance {
                objective_error: bad,
                ..Default::default()
            }
            .validate()
            .unwrap_err();
            assert!(e.contains("objective_error"), "{e}");
        }
    }
}
