//! The yarn solves' damping: a Levenberg–Marquardt shift `μ` (dimensionless) on the scaled diagonal
//! `D = diag(max(|H_ii|, 10⁻¹²·max|H_ii|))`, so that `μ` means the same for positions and angles, plus a
//! floor `μ₀ = 10⁻¹⁰` that removes exact null modes (a periodic cell's rigid translation; a global spin
//! of the material frames at zero rest curvature). The matrix factored is `H + (μ + μ₀) D`.
//!
//! A rejected attempt (no factorization, or no Armijo step) raises `μ ← max(10 μ, 10⁻⁶)`; a taken step
//! divides it by 3 (to 0 below 10⁻⁸). Near a stable equilibrium `μ → 0` and the iteration is plain
//! Newton. Why not the garment's [`super::TrustRatioDamping`]: the yarn step is cut to the problem's step
//! limit and backtracked, so the model's quality ratio says little about the shift.

use super::DampingPolicy;

/// The floor `μ₀` added to every shift (dimensionless).
pub const MU_FLOOR: f64 = 1e-10;

/// Beyond this shift the minimizer stops: no descent step found.
pub const MU_LIMIT: f64 = 1e12;

/// The shift `μ` (dimensionless) and its rules (see the module doc).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LevenbergMarquardt {
    /// The shift of the next factorization, without the floor [`MU_FLOOR`].
    pub mu: f64,
}

impl LevenbergMarquardt {
    /// The scaling `D` of the diagonal `diagonal` of `H`: `max(|H_ii|, 10⁻¹²·max|H_ii|)`.
    pub fn scaling(diagonal: &[f64]) -> Vec<f64> {
        let dmax = diagonal
            .iter()
            .fold(0.0f64, |m, v| m.max(v.abs()))
            .max(1e-300);
        diagonal.iter().map(|v| v.abs().max(1e-12 * dmax)).collect()
    }

    /// The shift after a rejected attempt at `mu`: `max(10 μ, 10⁻⁶)`.
    pub fn raised(mu: f64) -> f64 {
        (mu * 10.0).max(1e-6)
    }

    /// The shift the factored matrix adds times `D`: `μ + μ₀`.
    pub fn factored_shift(&self) -> f64 {
        self.mu + MU_FLOOR
    }

    /// Whether the shift has grown past [`MU_LIMIT`] (no descent direction worth trying is left).
    pub fn exhausted(&self) -> bool {
        self.mu > MU_LIMIT
    }
}

impl DampingPolicy for LevenbergMarquardt {
    fn shift(&self) -> f64 {
        self.mu
    }

    fn rejected(&mut self) {
        self.mu = Self::raised(self.mu);
    }

    fn accepted(&mut self, _quality: f64) {
        self.mu = if self.mu < 1e-8 { 0.0 } else { self.mu / 3.0 };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shift_rises_by_decades_and_falls_by_thirds_to_zero() {
        let mut lm = LevenbergMarquardt::default();
        lm.rejected();
        assert_eq!(lm.mu, 1e-6);
        lm.rejected();
        assert_eq!(lm.mu, 1e-6 * 10.0);
        lm.accepted(0.0);
        assert_eq!(lm.mu, 1e-6 * 10.0 / 3.0);
        lm.mu = 5e-9;
        lm.accepted(0.0);
        assert_eq!(lm.mu, 0.0);
        assert_eq!(LevenbergMarquardt::scaling(&[-2.0, 0.0]), [2.0, 2e-12]);
    }
}
