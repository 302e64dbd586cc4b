//! The problem [`super::minimize`] solves: an energy of `n` unknowns with its gradient and the lower
//! triangle of its Hessian as triplets, a residual and a step limit of the problem's own.

use faer::sparse::Triplet;

/// A problem for [`super::minimize`].
pub trait NewtonProblem {
    /// Number of unknowns.
    fn dof_count(&self) -> usize;
    /// Energy, gradient and (if `hessian`) the lower triangle of the Hessian at `x`.
    fn evaluate(
        &self,
        x: &[f64],
        hessian: bool,
    ) -> (f64, Vec<f64>, Vec<Triplet<usize, usize, f64>>);
    /// The energy alone at `x` (the line search's trial points): `evaluate(x, false).0`, which a problem
    /// may compute more cheaply (no derivatives).
    fn energy(&self, x: &[f64]) -> f64 {
        self.evaluate(x, false).0
    }
    /// Unknowns come in contiguous groups of this size that share their sparsity (the 4 unknowns of a yarn
    /// vertex): the fill-reducing ordering is then computed on the groups' graph
    /// ([`crate::SparseCholesky::analyze_grouped`]). 1: no grouping.
    fn group_size(&self) -> usize {
        1
    }
    /// The dimensionless residual of gradient `g` (force over the problem's force scale).
    fn residual(&self, g: &[f64]) -> f64;
    /// The factor in `(0, 1]` that brings step `h` within the problem's step limit.
    fn step_scale(&self, h: &[f64]) -> f64;
    /// Called after every accepted step (frame updates); must leave the energy at `x` unchanged.
    fn accepted(&mut self, x: &[f64]);
    /// Whether the caller asked the solve to stop: checked before every iteration, it ends the solve with
    /// [`super::StopReason::Cancelled`], `converged = false` and the last accepted state.
    fn interrupted(&self) -> bool {
        false
    }
    /// Takes back the triplets of an evaluation once the solver is done with them, so that a later
    /// evaluation may reuse their allocation (default: dropped). Why: on a 16 × 16 yarn patch they are
    /// ~100 MB an iteration, and fresh pages cost the kernel's page faults and zeroing.
    fn recycle(&self, triplets: Vec<Triplet<usize, usize, f64>>) {
        drop(triplets);
    }
}
