//! An [`AdjointProblem`] made a [`GaussNewtonProblem`]: each direction linearizes the problem at the
//! accepted point and solves `(2 R_totᵀ R_tot + κ I) dc = −g` (symbols as in
//! [`mod@crate::linearization`]) through the sparse KKT system ([`mod@crate::kkt_direction`]) or the
//! reduced sensitivity ([`mod@crate::reduced_direction`]), as [`GaussNewtonSolver`] chooses.
//!
//! The parameter map `A` is constant over a run unless the problem gives one per point
//! ([`AdjointProblem::parameter_map_at`], asked before every direction), so it is held here with its rows (for a `K A` formed
//! matrix-free by the problem) and the KKT solver's symbolic analysis, reused while the structure holds.
//! If the problem has no residuals, the direction is the damped gradient `−g / κ` (a steepest-descent
//! step, see [`mod@crate::gauss_newton_loop`]) with no solve.

use faer::sparse::SparseColMat;

use crate::Real;
use crate::kkt_direction::KktSolver;
use crate::linearization::{GaussNewtonError, GaussNewtonSystem, MixedForm};
use crate::problem::{AdjointProblem, GaussNewtonProblem, Objective};
use crate::reduced_direction::reduced_direction;

/// How the Gauss-Newton direction is solved for; both give the same direction (to round-off).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GaussNewtonSolver {
    /// [`Self::Reduced`] while the dense sensitivity `#q × #c` has at most
    /// [`GaussNewtonSolver::AUTO_REDUCED_ENTRIES`] entries, else [`Self::Kkt`].
    #[default]
    Auto,
    /// The sparse KKT system ([`mod@crate::kkt_direction`], the paper's Eq. 21).
    Kkt,
    /// The sensitivity from one multi-column solve with the equilibrium factor, then the dense
    /// `#c × #c` Gauss-Newton matrix ([`mod@crate::reduced_direction`]).
    Reduced,
}

impl GaussNewtonSolver {
    /// Largest `#q · #c` (entries of the dense sensitivity, 8 bytes each: 400 MB) [`Self::Auto`] solves
    /// in reduced form.
    pub const AUTO_REDUCED_ENTRIES: usize = 50_000_000;

    /// The name used in job specs and results (`"auto"`, `"kkt"`, `"reduced"`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Auto => "auto",
            Self::Kkt => "kkt",
            Self::Reduced => "reduced",
        }
    }

    /// Whether a problem with `unknowns` state unknowns and `variables` variables is solved in reduced
    /// form.
    pub fn reduced(self, unknowns: usize, variables: usize) -> bool {
        match self {
            Self::Auto => unknowns.saturating_mul(variables) <= Self::AUTO_REDUCED_ENTRIES,
            Self::Kkt => false,
            Self::Reduced => true,
        }
    }
}

/// The adjoint Gauss-Newton directions of an [`AdjointProblem`] (see the module documentation).
pub struct AdjointGaussNewton<'p, P> {
    problem: &'p mut P,
    parameter_map: SparseColMat<usize, Real>,
    map_rows: Vec<Real>,
    solver: GaussNewtonSolver,
    kkt: KktSolver,
}

impl<'p, P> AdjointGaussNewton<'p, P> {
    /// The directions of `problem` over the variables `c`, with the parameter map `A = dp/dc`
    /// (`#p × #c`, e.g. from [`crate::parameter_map_matrix`]), solved as `solver` says.
    pub fn new(
        problem: &'p mut P,
        parameter_map: SparseColMat<usize, Real>,
        solver: GaussNewtonSolver,
    ) -> Self {
        let map_rows = rows_of(&parameter_map);
        Self {
            problem,
            parameter_map,
            map_rows,
            solver,
            kkt: KktSolver::new(),
        }
    }

    /// The problem.
    pub fn problem(&mut self) -> &mut P {
        self.problem
    }
}

/// `A` row-major (`#p × #c`, dense), for a `K A` the problem forms matrix-free.
fn rows_of(parameter_map: &SparseColMat<usize, Real>) -> Vec<Real> {
    let nc = parameter_map.ncols();
    let mut map_rows = vec![0.0; parameter_map.nrows() * nc];
    let (cp, ri) = (
        parameter_map.symbolic().col_ptr(),
        parameter_map.symbolic().row_idx(),
    );
    for c in 0..nc {
        for k in cp[c]..cp[c + 1] {
            map_rows[ri[k] * nc + c] += parameter_map.val()[k];
        }
    }
    map_rows
}

impl<P: Objective> Objective for AdjointGaussNewton<'_, P> {
    type Error = P::Error;

    fn evaluate(&mut self, x: &[Real]) -> Result<(Real, Vec<Real>), P::Error> {
        self.problem.evaluate(x)
    }
}

impl<P> GaussNewtonProblem for AdjointGaussNewton<'_, P>
where
    P: AdjointProblem,
    P::Error: From<GaussNewtonError> + std::fmt::Display,
{
    fn direction(
        &mut self,
        x: &[Real],
        gradient: &[Real],
        damping: Real,
    ) -> Result<Vec<Real>, P::Error> {
        let Self {
            problem,
            parameter_map,
            map_rows,
            solver,
            kkt,
        } = self;
        if let Some(map) = problem.parameter_map_at(x)? {
            if map.nrows() != parameter_map.nrows() || map.ncols() != parameter_map.ncols() {
                return Err(GaussNewtonError::Invalid(format!(
                    "the parameter map at the point is {} × {}, the run's {} × {}",
                    map.nrows(),
                    map.ncols(),
                    parameter_map.nrows(),
                    parameter_map.ncols()
                ))
                .into());
            }
            *map_rows = rows_of(&map);
            *parameter_map = map;
        }
        let reduced = solver.reduced(problem.unknowns(), gradient.len());
        let form = if reduced {
            MixedForm::TimesParameterMap {
                rows: map_rows,
                columns: parameter_map.ncols(),
            }
        } else {
            MixedForm::Matrix
        };
        let linearization = problem.linearization(x, form)?;
        if linearization.residuals.is_empty() {
            return Ok(gradient.iter().map(|g| -g / damping).collect());
        }
        let system = GaussNewtonSystem {
            linearization: &linearization,
            parameter_map: parameter_map.as_ref(),
            gradient,
        };
        let direction = if reduced {
            reduced_direction(&system, damping, |rhs, columns| {
                problem
                    .solve_hessian(rhs, columns)
                    .map_err(|e| e.to_string())
            })
        } else {
            kkt.direction(&system, damping)
        };
        Ok(direction?.variables)
    }

    fn project(&self, x: &mut [Real]) {
        self.problem.project(x)
    }
}
