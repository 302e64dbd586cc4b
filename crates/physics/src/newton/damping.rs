//! The family of damping policies of a Newton solve: how the shift `σ` of the factored matrix `H + σ D`
//! answers a rejected attempt and an accepted step. Two implementors, which differ on purpose:
//! [`super::TrustRatioDamping`] (the garment's equilibrium, thesis Sec. 2.1.2) reads the step's quality,
//! [`super::LevenbergMarquardt`] (the yarn solves, with Armijo backtracking) only whether it was taken.

/// A damping policy: the shift of the next factorization and its rules.
pub trait DampingPolicy {
    /// The shift `σ` the next factorization adds times the metric `D` (the units are the policy's).
    fn shift(&self) -> f64;
    /// After a rejected attempt (no factorization, or no acceptable step): a larger shift.
    fn rejected(&mut self);
    /// After a taken step of quality `δ = ΔU_actual / ΔU_model` (Eq. 5; policies may ignore it).
    fn accepted(&mut self, quality: f64);
}
