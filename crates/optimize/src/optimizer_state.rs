//! The checkpoint of either optimizer: where an L-BFGS or Gauss-Newton run stands after an accepted
//! iteration, plain data (serde) so that a caller can store it and go on exactly as the uninterrupted run
//! would have ([`crate::lbfgs_from`], [`crate::gauss_newton_from`]). Values in the problem's units.

use crate::Real;
use crate::gauss_newton_loop::GaussNewtonState;
use crate::lbfgs::LbfgsState;

/// The optimizer's own state (see [`crate::LbfgsIteration::state`] and
/// [`crate::GaussNewtonIteration::state`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum OptimizerState {
    /// An L-BFGS run.
    Lbfgs(LbfgsState),
    /// A Gauss-Newton run.
    GaussNewton(GaussNewtonState),
}

impl OptimizerState {
    /// Accepted steps of the run.
    pub fn iteration(&self) -> usize {
        match self {
            Self::Lbfgs(s) => s.iteration,
            Self::GaussNewton(s) => s.iteration,
        }
    }

    /// `‖g‖₂` of the current point's gradient (the problem's units).
    pub fn gradient_norm(&self) -> Real {
        let g = match self {
            Self::Lbfgs(s) => &s.gradient,
            Self::GaussNewton(s) => &s.gradient,
        };
        g.iter().map(|v| v * v).sum::<Real>().sqrt()
    }
}
