//! Why an optimizer run stopped, shared by [`crate::lbfgs()`] and [`crate::gauss_newton()`] (and
//! serialized in their checkpoints and results).

/// Why an optimizer stopped: [`crate::lbfgs()`] and [`crate::gauss_newton()`] share these reasons. (Not to
/// be confused with why an equilibrium solve stopped.)
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum OptimizerStop {
    /// `‖g‖ < gradient_tolerance`.
    GradientTolerance,
    /// Too little relative decrease for several iterations.
    NoProgress,
    /// L-BFGS: the line search found no strong-Wolfe step, neither along the quasi-Newton direction nor
    /// along steepest descent. Gauss-Newton: no decrease after the allowed halvings and damping retries.
    LineSearchFailed,
    /// `max_iterations` reached.
    MaxIterations,
    /// `time_limit_seconds` passed.
    TimeLimit,
    /// The per-iteration callback asked to stop.
    Callback,
}
