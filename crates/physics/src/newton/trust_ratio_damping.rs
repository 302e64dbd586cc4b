//! The garment solve's damping (thesis Sec. 2.1.2): a stiffness `α` (N/m) added along the damping metric
//! `D` ([`crate::ClothOnBody::damping_metric`]), scaled by the median stiffness per metre of the solve's
//! first Hessian so that its rules hold for any garment.
//!
//! `α` grows ×4 after a rejected attempt (no factorization, no finite step, no decrease of the energy),
//! at least to `10⁻⁶` of the scale; after a taken step of quality `δ = ΔU_actual / ΔU_model` (Eq. 5) it
//! shrinks ÷3 when `δ > 0.75` (to 0 — pure Newton — below `10⁻⁹` of the scale) and doubles when
//! `δ < 0.25`: a trust-region ratio test acting on the damping instead of a radius.

use super::DampingPolicy;

/// The damping `α` (N/m) of the garment's Newton steps and its rules (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrustRatioDamping {
    /// The damping of the next step (N/m).
    pub alpha: f64,
    /// Below this, `α` drops to 0 (N/m).
    pub floor: f64,
    /// The smallest `α` an increase gives (N/m).
    pub restart: f64,
    /// The last `α` with which `H + αD` factored (N/m).
    pub last_factored: f64,
}

impl TrustRatioDamping {
    /// `α = initial · diag_scale` (`initial` dimensionless, `diag_scale` the median stiffness per metre
    /// of the first Hessian, N/m).
    pub fn new(initial: f64, diag_scale: f64) -> Self {
        let alpha = initial * diag_scale;
        Self {
            alpha,
            floor: 1e-9 * diag_scale,
            restart: 1e-6 * diag_scale,
            last_factored: alpha,
        }
    }

    /// ×4 after a rejected attempt (no factorization, no finite step, no decrease).
    pub fn increase(&mut self) {
        self.alpha = (4.0 * self.alpha).max(self.restart);
    }

    /// After an accepted step of quality `δ`: ÷3 when `δ > 0.75` (0 once negligible), ×2 when `δ < 0.25`.
    pub fn update(&mut self, quality: f64) {
        if quality > 0.75 {
            self.alpha /= 3.0;
            if self.alpha < self.floor {
                self.alpha = 0.0;
            }
        } else if quality < 0.25 {
            self.alpha = (2.0 * self.alpha).max(self.restart);
        }
    }
}

impl DampingPolicy for TrustRatioDamping {
    fn shift(&self) -> f64 {
        self.alpha
    }

    fn rejected(&mut self) {
        self.increase();
    }

    fn accepted(&mut self, quality: f64) {
        self.update(quality);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn good_steps_shrink_the_damping_to_zero_and_poor_ones_raise_it() {
        let mut d = TrustRatioDamping::new(1e-3, 100.0);
        assert_eq!(d.shift(), 0.1);
        d.accepted(0.5);
        assert_eq!(d.alpha, 0.1);
        d.accepted(0.1);
        assert_eq!(d.alpha, 0.2);
        for _ in 0..20 {
            d.accepted(0.9);
        }
        assert_eq!(d.alpha, 0.0);
        d.rejected();
        assert_eq!(d.alpha, 1e-6 * 100.0);
    }
}
