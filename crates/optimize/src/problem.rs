//! What the optimizers minimize: three traits, each adding what one more optimizer needs.
//!
//! - [`Objective`]: a value `T(x)` and its gradient `∇T(x)` at a point `x` (`n` variables); all that
//!   [`crate::lbfgs()`] needs. A closure `FnMut(&[Real]) -> Result<(Real, Vec<Real>), E>` is one.
//! - [`GaussNewtonProblem`]: an objective that also gives the damped Gauss-Newton direction
//!   `d = −(2 R_totᵀ R_tot + κ I)⁻¹ g` at an accepted point; all that [`crate::gauss_newton()`] needs.
//! - [`AdjointProblem`]: a least-squares objective `T = Σ r_k² + …` whose residuals `r(q, p)` depend on
//!   the variables `c` through a state `q` at equilibrium, `∂U/∂q (q, p) = 0`, and parameters `p = A c`
//!   that follow the variables through a constant linear map `A` (see [`mod@crate::linearization`] for the
//!   symbols). It gives the linearization at the last evaluated point and solves with the equilibrium
//!   Hessian; [`crate::AdjointGaussNewton`] turns it into a [`GaussNewtonProblem`] through the KKT system
//!   ([`mod@crate::kkt_direction`]) or the reduced sensitivity ([`mod@crate::reduced_direction`]).
//!
//! The garment designer's pattern problem is one `AdjointProblem` (state: cloth and body coordinates;
//! parameters: the pattern positions; variables: boundary positions or mode coefficients); the fit of
//! per-element material parameters to simulated frames (knitwear paper Eq. 21: state: the frames'
//! positions; parameters: the material parameters; `A`: their parametrization) is another. No notion of
//! either appears here.
//!
//! **Failures.** An `Err` from [`Objective::evaluate`] (a point the equilibrium cannot be solved at) is
//! not fatal: both optimizers count it as a step too long and shrink the step; only at the starting point
//! is it an error of the run. An `Err` from a direction makes Gauss-Newton raise its damping and ask
//! again.

use crate::Real;
use crate::linearization::{Linearization, MixedForm};

/// A differentiable objective: its value and gradient at a point (units: those of the problem, `T` and
/// `T` per unit of `x`).
pub trait Objective {
    /// Why an evaluation failed.
    type Error;

    /// `(T(x), ∇T(x))`; the gradient has one entry per variable.
    fn evaluate(&mut self, x: &[Real]) -> Result<(Real, Vec<Real>), Self::Error>;
}

impl<F, E> Objective for F
where
    F: FnMut(&[Real]) -> Result<(Real, Vec<Real>), E>,
{
    type Error = E;

    fn evaluate(&mut self, x: &[Real]) -> Result<(Real, Vec<Real>), E> {
        self(x)
    }
}

/// An objective with a damped Gauss-Newton direction.
pub trait GaussNewtonProblem: Objective {
    /// `d = −(2 R_totᵀ R_tot + κ I)⁻¹ g` at the accepted point `x` with gradient `g`, damping `κ ≥ 0`
    /// (units of `T` per unit² of `x`); one entry per variable.
    fn direction(
        &mut self,
        x: &[Real],
        gradient: &[Real],
        damping: Real,
    ) -> Result<Vec<Real>, Self::Error>;

    /// Moves a trial point of the line search into the feasible set, in place (e.g. clamps variables
    /// that must not be negative, the knitwear paper's Sec. 6.3). Default: every point is feasible.
    fn project(&self, _x: &mut [Real]) {}
}

/// A least-squares objective constrained by an equilibrium (see the module documentation).
pub trait AdjointProblem: Objective {
    /// `#q`, the number of state unknowns.
    fn unknowns(&self) -> usize;

    /// The linearization at `x` (the last accepted point: its state must be the equilibrium at `x`,
    /// solved again if a later trial moved it), with the mixed derivative in the form `mixed` asks for.
    fn linearization(
        &mut self,
        x: &[Real],
        mixed: MixedForm<'_>,
    ) -> Result<Linearization, Self::Error>;

    /// Overwrites the column-major `#q × columns` block `rhs` with `H⁻¹ rhs`, `H` the Hessian of the
    /// last [`Self::linearization`].
    fn solve_hessian(&mut self, rhs: &mut [Real], columns: usize) -> Result<(), Self::Error>;

    /// [`GaussNewtonProblem::project`] of the variables `c`. Default: every point is feasible.
    fn project(&self, _c: &mut [Real]) {}

    /// The parameter map `A = dp/dc` at the variables `c` (`#p × #c`), for a problem whose map is not
    /// linear (e.g. through a projection onto a constraint set); asked for before every direction.
    /// Default `None`: the map given to [`crate::AdjointGaussNewton::new`] holds everywhere.
    fn parameter_map_at(
        &mut self,
        _c: &[Real],
    ) -> Result<Option<faer::sparse::SparseColMat<usize, Real>>, Self::Error> {
        Ok(None)
    }
}
