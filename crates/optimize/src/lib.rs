//! Optimizers for skintight, generic over the problem: the garment's pattern design
//! (`skintight_design`) and the fit of material parameters to simulated frames use the same code. No
//! garment, body or web notion lives here.
//!
//! **Problems** ([`mod@problem`]): an [`Objective`] (value and gradient), a [`GaussNewtonProblem`] (plus a
//! damped Gauss-Newton direction) and an [`AdjointProblem`] (a least-squares objective whose residuals
//! depend on the variables through an equilibrium: its linearization, [`mod@linearization`], and solves
//! with the equilibrium Hessian).
//!
//! **Optimizers.**
//! - [`mod@lbfgs`]: L-BFGS with a strong-Wolfe line search, tolerant of failing evaluations, always
//!   returning the best point seen.
//! - [`mod@gauss_newton_loop`]: Levenberg-Marquardt-damped Gauss-Newton with a backtracking line search
//!   by quadratic interpolation ([`gauss_newton()`]).
//! - Its adjoint directions (Zehnder et al. 2021; the volumetric homogenization paper Sec. 6.2–6.3):
//!   [`mod@kkt_direction`], the sparse KKT system of the paper's Eq. 21 ([`KktSolver`]), or
//!   [`mod@reduced_direction`], through the sensitivity `Z = H⁻¹ K A` and the dense `#c × #c`
//!   Gauss-Newton matrix; [`AdjointGaussNewton`] makes an [`AdjointProblem`] a [`GaussNewtonProblem`]
//!   with either ([`GaussNewtonSolver`]).
//!
//! [`OptimizerStop`] says why a run stopped; [`OptimizerState`] is either run's checkpoint, from which
//! [`lbfgs_from`] and [`gauss_newton_from`] go on exactly as the uninterrupted run would have.
//!
//! Units: the problem's own; the optimizers only need them consistent (a gradient in units of the value
//! per unit of `x`, a damping in units of the value per unit² of `x`). Times in s.

/// Floating-point type of every quantity: `f64`, as the workspace's `skintight_geometry::math::Real`, which
/// this crate does not depend on (crate-private, so the public name keeps one meaning).
pub(crate) type Real = f64;

pub mod adjoint_gauss_newton;
pub mod gauss_newton_loop;
pub mod kkt_direction;
pub mod lbfgs;
pub mod linearization;
pub mod optimizer_state;
pub mod optimizer_stop;
pub mod problem;
pub mod reduced_direction;

pub use adjoint_gauss_newton::{AdjointGaussNewton, GaussNewtonSolver};
pub use gauss_newton_loop::{
    GaussNewtonIteration, GaussNewtonOutcome, GaussNewtonParams, GaussNewtonRunError,
    GaussNewtonStart, GaussNewtonState, gauss_newton, gauss_newton_from,
};
pub use kkt_direction::KktSolver;
pub use lbfgs::{
    LbfgsError, LbfgsIteration, LbfgsParams, LbfgsResult, LbfgsStart, LbfgsState, lbfgs, lbfgs_from,
};
pub use linearization::{
    GaussNewtonDirection, GaussNewtonError, GaussNewtonSystem, Linearization, MixedDerivative,
    MixedForm, Unknown, parameter_map_matrix,
};
pub use optimizer_state::OptimizerState;
pub use optimizer_stop::OptimizerStop;
pub use problem::{AdjointProblem, GaussNewtonProblem, Objective};
pub use reduced_direction::reduced_direction;
