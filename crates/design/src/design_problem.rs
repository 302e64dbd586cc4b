//! The design objective as a function of the pattern, `T(X̄) = Σ_terms T_i(x*(X̄), X̄)`, and its gradient by
//! the adjoint method (thesis Eq. 160–164).
//!
//! For pattern positions `X̄` (`#Vp × 2`, m) the garment is solved to equilibrium `q*(X̄)` — warm-started
//! from the last equilibrium, reusing the Hessian's pattern and symbolic analysis
//! ([`equilibrium_in`]) — and the terms are evaluated on the cloth positions `x(q*)`. At equilibrium
//! `∂U/∂q (q*, X̄) = 0`, so `dq*/dX̄ = −H⁻¹ ∂²U/∂q∂X̄` and
//!
//! ```text
//! dT/dX̄ = ∂T/∂X̄ − λᵀ ∂²U/∂q∂X̄,     H λ = ∂T/∂q = Jᵀ ∂T/∂x,
//! ```
//!
//! with `J = ∂x/∂q` (plus, for terms that depend on the state directly, their `∂T/∂q`,
//! [`Term::evaluate_with_state`]). One extra solve with the final Hessian gives `λ`
//! ([`EquilibriumWorkspace::solve_hessian`]); `λᵀ ∂²U/∂q∂X̄ = Σ_e (J λ)_eᵀ ∂²U_e/∂x∂X̄` element by element
//! ([`ClothOnBody::rest_mixed_product`]), since `J` does not depend on the pattern.

use std::ops::ControlFlow;
use std::time::Instant;

use crate::design_linearization::DesignLinearization;
use crate::design_mesh::DesignMesh;
use crate::equilibrium_predictor::equilibrium_change;
use crate::math::{Real, Vec2, Vec3};
use crate::term::{Fabric, Residuals, StateInput, Term, TermError, TermGradient, TermInput};
use skintight_optimize::{GaussNewtonError, MixedDerivative};
use skintight_physics::membrane_law::MembraneLaw;
use skintight_physics::{
    ClothOnBody, ClothOnBodyState, EquilibriumParams, EquilibriumReport, EquilibriumWorkspace,
    IterationInfo, SolveProgress, equilibrium_resumable,
};

/// Why the design objective could not be evaluated at a pattern.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum DesignError {
    /// The pattern has the wrong size, non-finite values or a triangle without positive area.
    #[error("the pattern is not usable: {0}")]
    Pattern(String),
    /// The garment found no equilibrium (iteration or time limit, no progress): its gradient would be
    /// meaningless. An optimizer treats this as a step too long.
    #[error("the garment did not reach equilibrium ({stop}, relative residual {residual:e})")]
    NotConverged {
        /// Why the solve stopped.
        stop: String,
        /// Its final relative residual.
        residual: Real,
    },
    /// The equilibrium solve or the adjoint solve failed.
    #[error("{0}")]
    Solve(String),
    /// A term could not be evaluated.
    #[error(transparent)]
    Term(#[from] TermError),
    /// The caller stopped the solve.
    #[error("cancelled")]
    Cancelled,
}

/// A Gauss-Newton direction that could not be solved for: a [`DesignError::Solve`].
impl From<GaussNewtonError> for DesignError {
    fn from(e: GaussNewtonError) -> Self {
        Self::Solve(e.to_string())
    }
}

/// One term's value at an evaluated design.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct TermReport {
    /// The term's name.
    pub name: &'static str,
    /// Its weighted value (the term's units).
    pub value: Real,
    /// Its value per element (see each term's documentation for which elements).
    pub per_element: Vec<Real>,
}

/// The design objective at one pattern.
#[derive(Clone, Debug)]
pub struct DesignEvaluation {
    /// `T`, the sum of the terms.
    pub value: Real,
    /// Each term.
    pub terms: Vec<TermReport>,
    /// `dT/dX̄` (`#Vp`, units of T per m), when asked for.
    pub gradient: Option<Vec<Vec2>>,
    /// The equilibrium solve.
    pub equilibrium: EquilibriumReport,
    /// Damping the adjoint solve needed (N/m; 0 when the final Hessian factored as it is).
    pub adjoint_damping: Real,
    /// The first-order error of `value` that the solve's unbalanced forces cause, `|λᵀ g|` (units of
    /// T): `λ = H⁻¹ ∂T/∂q` the adjoint, `g = ∂U/∂q` at the solved state, so that the exact equilibrium,
    /// `δq = −H⁻¹ g` away, has `T + δT` with `δT ≈ −λᵀ g`. Known with the gradient (else `None`); 0 when
    /// no term depends on the state.
    pub value_error: Option<Real>,
    /// `#Vc` cloth positions at equilibrium (m).
    pub cloth: Vec<Vec3>,
    /// Wall time of this evaluation (s).
    pub seconds: Real,
}

/// The fabric the terms see: the system's membrane law, its cloth thickness (m) and each triangle's
/// course direction.
fn fabric_of(system: &ClothOnBody) -> Fabric {
    Fabric {
        density: *system.density(),
        thickness: system.elements().first().map_or(0.0, |e| e.thickness()),
        orthotropic: match system.law() {
            MembraneLaw::Orthotropic(o) => Some(o.clone()),
            MembraneLaw::Isotropic(_) => None,
        },
        course: system.elements().iter().map(|e| e.course()).collect(),
    }
}

/// The design objective of one garment on one body; see the module documentation.
pub struct DesignProblem {
    system: ClothOnBody,
    mesh: DesignMesh,
    fabric: Fabric,
    terms: Vec<Box<dyn Term>>,
    params: EquilibriumParams,
    /// The last equilibrium reached (the warm start of the next solve).
    state: ClothOnBodyState,
    workspace: EquilibriumWorkspace,
    evaluations: usize,
    /// Newton iterations, factorizations and solver time of every equilibrium solve so far (failed ones
    /// included).
    totals: EquilibriumTotals,
    /// The pattern of the last successful evaluation (the one `state` is the equilibrium of).
    last_pattern: Option<Vec<Vec2>>,
    /// Whether each solve starts from the predicted equilibrium ([`Self::set_predictor`]).
    predictor: bool,
    /// The damping where the last successful solve ended (with the predictor: where the next starts).
    last_damping: Option<SolveProgress>,
    /// How the last evaluation's solve started ([`Self::replay`]).
    last_start: Option<EvaluationStart>,
    /// With the predictor: the best evaluation so far, where a line search's trials start from.
    anchor: Option<Anchor>,
    /// The objective of the last evaluation (`None` after a failed one).
    last_value: Option<Real>,
    /// Where the last evaluation's solve stopped when it did not converge (its best state) and its
    /// damping there: where [`Self::final_evaluation`] goes on from.
    unconverged: Option<(ClothOnBodyState, Option<SolveProgress>)>,
}

/// A trial whose objective exceeds the anchor's by more than this factor is taken to have left the anchor's
/// branch of equilibria: the next trial starts from the anchor ([`Anchor`]) instead of from it. Below it,
/// the next trial starts from the last one (the nearer equilibrium, usually on the same branch): on the
/// tight pants, starting every trial from the anchor took 1.7 × the time to the window (the garment's
/// slack directions make the equilibria of nearby patterns differ along them), while on the tapered
/// cylinder the failed trials sat 7–25 × above the anchor and, without the anchor, the 38 shorter trials
/// after a far one never came back (docs/BENCHMARKS.md).
const BRANCH_FACTOR: Real = 2.0;

/// The solves [`DesignProblem::final_evaluation`] adds after the first stops short, each with the
/// equilibrium settings' iteration and time limits.
pub const FINAL_ROUNDS: usize = 2;

/// The evaluation with the lowest objective so far (with the predictor on): the point a descent
/// method's line search steps from. Its trials are predicted from its equilibrium, not from the last
/// trial's: a trial that went too far may have found another equilibrium (the garment slid into another
/// configuration), and shorter trials warm-started there stay on that branch, whose objective does not
/// tend to the anchor's as the step shrinks (measured on the tapered cylinder: a line search whose 39
/// trials all failed).
#[derive(Clone, Debug)]
struct Anchor {
    /// Its objective.
    value: Real,
    /// Its pattern (`#Vp`, m).
    pattern: Vec<Vec2>,
    /// Its equilibrium.
    state: ClothOnBodyState,
    /// The damping its solve ended with.
    damping: Option<SolveProgress>,
    /// The first trial from it: its pattern change and the predicted change of the equilibrium, computed
    /// with the anchor's Hessian ([`equilibrium_change`]); a later trial along the same line is predicted
    /// by scaling it.
    ray: Option<(Vec<Vec2>, Vec<Real>)>,
}

impl Anchor {
    /// `δq` for the pattern `to` when its change from the anchor lies on the ray (`c · ray` within
    /// rounding, `c > 0`).
    fn along_ray(&self, to: &[Vec2]) -> Option<Vec<Real>> {
        let (delta, dq) = self.ray.as_ref()?;
        let mut dd = 0.0;
        let mut dr = 0.0;
        for ((t, a), d) in to.iter().zip(&self.pattern).zip(delta) {
            dd += d.norm_squared();
            dr += (t - a).dot(d);
        }
        let c = dr / dd;
        if !(c.is_finite() && c > 0.0) {
            return None;
        }
        let mut off = 0.0;
        let mut len = 0.0;
        for ((t, a), d) in to.iter().zip(&self.pattern).zip(delta) {
            off += (t - a - d * c).norm_squared();
            len += (t - a).norm_squared();
        }
        (off <= 1e-18 * len).then(|| dq.iter().map(|v| c * v).collect())
    }
}

/// How an evaluation's equilibrium solve started: what [`DesignProblem::replay`] needs to do it again bit
/// for bit. Serializable (a design checkpoint stores it).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EvaluationStart {
    /// The pattern evaluated (`#Vp`, m).
    pub pattern: Vec<Vec2>,
    /// Whether the gradient was computed.
    pub with_gradient: bool,
    /// The warm start before the evaluation (kept when it fails).
    pub warm_start: ClothOnBodyState,
    /// The damping the problem carried before it.
    pub damping_before: Option<SolveProgress>,
    /// The state its solve started from when not the warm start (the predicted equilibrium).
    pub solve_start: Option<ClothOnBodyState>,
    /// The damping its solve started with (`None`: the solver's initial damping).
    pub solve_damping: Option<SolveProgress>,
    /// The relative residual its equilibrium was solved to (`None` in checkpoints written before inexact
    /// solves: the problem's own).
    #[serde(default)]
    pub tolerance: Option<Real>,
}

/// The work of every equilibrium solve of a design added up: what its `result.json` reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EquilibriumTotals {
    /// Newton iterations.
    pub newton_iterations: usize,
    /// Numeric factorizations.
    pub factorizations: usize,
    /// Newton iterations that reused a factorization (chord steps); 0 in checkpoints written before
    /// they existed.
    #[serde(default)]
    pub chord_steps: usize,
    /// Solver time by phase (s); `newton_step_s` is the mean over all iterations, `one_factorization_s` the
    /// last solve's.
    pub timings: skintight_physics::equilibrium::EquilibriumTimings,
}

impl EquilibriumTotals {
    /// Adds one solve's report.
    pub fn add(&mut self, report: &skintight_physics::equilibrium::EquilibriumReport) {
        self.newton_iterations += report.iterations;
        self.factorizations += report.factorizations;
        self.chord_steps += report.figures.chord_steps;
        let (t, r) = (&mut self.timings, &report.figures.timings);
        t.assembly_s += r.assembly_s;
        t.factorization_s += r.factorization_s;
        t.solve_s += r.solve_s;
        t.total_s += r.total_s;
        t.newton_step_s = t.total_s / self.newton_iterations.max(1) as f64;
        if r.one_factorization_s > 0.0 {
            t.one_factorization_s = r.one_factorization_s;
        }
    }
}

impl std::fmt::Debug for DesignProblem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DesignProblem")
            .field(
                "terms",
                &self.terms.iter().map(|t| t.name()).collect::<Vec<_>>(),
            )
            .field("evaluations", &self.evaluations)
            .finish_non_exhaustive()
    }
}

impl DesignProblem {
    /// The problem of `system` (whose cloth triangles are `mesh`'s, in order) starting from `state`,
    /// with the objective `Σ terms`, each equilibrium solved with `params`.
    pub fn new(
        system: ClothOnBody,
        state: ClothOnBodyState,
        mesh: DesignMesh,
        terms: Vec<Box<dyn Term>>,
        params: EquilibriumParams,
    ) -> Result<Self, DesignError> {
        if mesh.num_triangles() != system.triangles().len()
            || mesh.cloth_triangles.as_slice() != system.triangles()
        {
            return Err(DesignError::Pattern(
                "the design mesh's cloth triangles are not the system's".into(),
            ));
        }
        if mesh.num_cloth_vertices != system.num_cloth_vertices() {
            return Err(DesignError::Pattern(format!(
                "the design mesh has {} cloth vertices, the system {}",
                mesh.num_cloth_vertices,
                system.num_cloth_vertices()
            )));
        }
        Ok(Self {
            fabric: fabric_of(&system),
            system,
            mesh,
            terms,
            params,
            state,
            workspace: EquilibriumWorkspace::default(),
            evaluations: 0,
            totals: EquilibriumTotals::default(),
            last_pattern: None,
            predictor: false,
            last_damping: None,
            last_start: None,
            anchor: None,
            last_value: None,
            unconverged: None,
        })
    }

    /// Replaces the cloth (after a remesh, [`mod@crate::design_remesh`]): the new `system` (same body) with
    /// `mesh`'s cloth triangles, and the warm start `state`. The terms, solver settings and the count of
    /// evaluations stay; the problem has no linearization until the next evaluation. Errors (leaving the
    /// problem as it was) when `mesh` and `system` do not match.
    pub fn replace_cloth(
        &mut self,
        system: ClothOnBody,
        state: ClothOnBodyState,
        mesh: DesignMesh,
    ) -> Result<(), DesignError> {
        if mesh.cloth_triangles.as_slice() != system.triangles()
            || mesh.num_cloth_vertices != system.num_cloth_vertices()
            || state.cloth.len() != system.num_cloth_vertices()
            || state.body.len() != system.num_body_vertices()
        {
            return Err(DesignError::Pattern(
                "the new design mesh, system and state do not match".into(),
            ));
        }
        self.fabric = fabric_of(&system);
        self.system = system;
        self.state = state;
        self.mesh = mesh;
        self.workspace = EquilibriumWorkspace::default();
        self.last_pattern = None;
        self.last_damping = None;
        self.last_start = None;
        self.anchor = None;
        self.last_value = None;
        self.unconverged = None;
        Ok(())
    }

    /// The connectivity.
    pub fn mesh(&self) -> &DesignMesh {
        &self.mesh
    }

    /// The coupled system at the last evaluated pattern.
    pub fn system(&self) -> &ClothOnBody {
        &self.system
    }

    /// The last equilibrium reached.
    pub fn state(&self) -> &ClothOnBodyState {
        &self.state
    }

    /// Predictor–corrector evaluations: when on, a solve that follows a successful evaluation starts from
    /// the first-order prediction of its equilibrium ([`mod@crate::equilibrium_predictor`]) instead of the
    /// last equilibrium itself; a solve from the prediction that does not converge is done again from the
    /// last equilibrium. Off by default.
    pub fn set_predictor(&mut self, on: bool) {
        self.predictor = on;
    }

    /// Chord steps in the corrector ([`EquilibriumParams::reuse_factorization`]): Newton iterations that
    /// reuse the factorization they find — the last solve's final Hessian first, which the prediction was
    /// computed with — while it contracts the residual tenfold. Off by default: on the tapered cylinder a
    /// chord step contracted 0.1–0.4 where a fresh Newton step after it contracted 10⁻²–10⁻³, and the
    /// design took 1.4 × the Newton iterations to 1/50 of its objective (155 against 107; 123 against 86
    /// with the covariant Hessian) in no less time (docs/BENCHMARKS.md).
    pub fn set_chord_steps(&mut self, on: bool) {
        self.params.reuse_factorization = on;
    }

    /// The relative residual the equilibria of the next evaluations are solved to (dimensionless, see
    /// [`skintight_physics::equilibrium`]).
    pub fn equilibrium_tolerance(&self) -> Real {
        self.params.tolerance
    }

    /// The most Newton iterations of one equilibrium solve.
    pub fn equilibrium_iteration_limit(&self) -> usize {
        self.params.max_iterations
    }

    /// Sets the most Newton iterations of each next equilibrium solve (at least 1; 0 is refused, the
    /// message names it, and nothing changes).
    pub fn set_equilibrium_iteration_limit(
        &mut self,
        iterations: usize,
    ) -> Result<(), DesignError> {
        if iterations == 0 {
            return Err(DesignError::Solve(
                "the equilibrium iteration limit must be at least 1, got 0".into(),
            ));
        }
        self.params.max_iterations = iterations;
        Ok(())
    }

    /// Sets the relative residual the next evaluations' equilibria are solved to (inexact solves,
    /// [`mod@crate::inexact_tolerance`]); a value that is not finite and positive is refused (the message
    /// names it) and nothing changes.
    pub fn set_equilibrium_tolerance(&mut self, tolerance: Real) -> Result<(), DesignError> {
        if !(tolerance.is_finite() && tolerance > 0.0) {
            return Err(DesignError::Solve(format!(
                "the equilibrium tolerance must be a positive relative residual, got {tolerance}"
            )));
        }
        self.params.tolerance = tolerance;
        Ok(())
    }

    /// Replaces the warm start (e.g. with the equilibrium of the best design so far). The problem then
    /// has no linearization until the next evaluation.
    pub fn set_state(&mut self, state: ClothOnBodyState) {
        self.state = state;
        self.last_pattern = None;
        self.anchor = None;
        self.last_value = None;
    }

    /// The pattern (`#Vp`, m) of the last successful [`Self::evaluate`], which the state is the
    /// equilibrium of; `None` before one or after [`Self::set_state`].
    pub fn last_pattern(&self) -> Option<&[Vec2]> {
        self.last_pattern.as_deref()
    }

    /// Solves `(H + αD) λ = rhs` in place with the Hessian of the last equilibrium (`rhs`: `#q`), the adjoint
    /// solve of [`Self::evaluate`]; returns the damping `α` (N/m, see
    /// [`EquilibriumWorkspace::solve_hessian`]).
    pub fn solve_hessian(&mut self, rhs: &mut [Real]) -> Result<Real, DesignError> {
        if self.last_pattern.is_none() {
            return Err(DesignError::Solve(
                "no evaluated design to solve at (evaluate the pattern first)".into(),
            ));
        }
        self.workspace
            .solve_hessian(rhs)
            .map_err(|e| DesignError::Solve(e.to_string()))
    }

    /// [`Self::solve_hessian`] for `columns` right-hand sides at once (`rhs`: `#q × columns`, column-major).
    pub fn solve_hessian_columns(
        &mut self,
        rhs: &mut [Real],
        columns: usize,
    ) -> Result<Real, DesignError> {
        if self.last_pattern.is_none() {
            return Err(DesignError::Solve(
                "no evaluated design to solve at (evaluate the pattern first)".into(),
            ));
        }
        self.workspace
            .solve_hessian_columns(rhs, columns)
            .map_err(|e| DesignError::Solve(e.to_string()))
    }

    /// The linearization of the design problem at the last successful [`Self::evaluate`] (its pattern
    /// and equilibrium), what the adjoint Gauss-Newton system is built from
    /// ([`skintight_optimize::kkt_direction`], through [`DesignLinearization::adjoint`]): the residuals of every sum-of-squares term, concatenated in term
    /// order, and the explicit sparse `J`, `H + αD` and `K`. Errors when nothing was evaluated since the
    /// last [`Self::set_state`], or when a matrix cannot be built.
    pub fn linearize(&mut self) -> Result<DesignLinearization, DesignError> {
        self.linearize_with(None)
    }

    /// [`Self::linearize`] with `K A` instead of `K`, for the design map `A` given by rows (`a_rows`:
    /// `2#Vp × columns`, row-major, row `2v + i` = coordinate `i` of pattern vertex `v`), formed
    /// matrix-free ([`ClothOnBody::rest_mixed_times`]): all the reduced Gauss-Newton direction needs, at a
    /// fraction of the cost of building `K`.
    pub fn linearize_times(
        &mut self,
        a_rows: &[Real],
        columns: usize,
    ) -> Result<DesignLinearization, DesignError> {
        self.linearize_with(Some((a_rows, columns)))
    }

    fn linearize_with(
        &mut self,
        design_map_rows: Option<(&[Real], usize)>,
    ) -> Result<DesignLinearization, DesignError> {
        let Some(pattern) = self.last_pattern.as_deref() else {
            return Err(DesignError::Solve(
                "no evaluated design to linearize at (evaluate the pattern first)".into(),
            ));
        };
        let solve = |e: &dyn std::fmt::Display| DesignError::Solve(e.to_string());
        let cloth = self
            .system
            .cloth_positions(&self.state)
            .map_err(|e| solve(&e))?;
        let input = TermInput {
            mesh: &self.mesh,
            cloth: &cloth,
            pattern,
            fabric: &self.fabric,
        };
        let state_input = StateInput {
            system: &self.system,
            state: &self.state,
        };
        let mut residuals = Residuals::default();
        let mut residual_terms = Vec::new();
        for term in &self.terms {
            let Some(r) = term.residuals_with_state(&input, &state_input) else {
                continue;
            };
            let r = r?;
            let offset = residuals.values.len();
            residuals.values.extend_from_slice(&r.values);
            residuals
                .cloth_jacobian
                .extend(r.cloth_jacobian.iter().map(|&(k, c, d)| (k + offset, c, d)));
            residuals.pattern_jacobian.extend(
                r.pattern_jacobian
                    .iter()
                    .map(|&(k, v, d)| (k + offset, v, d)),
            );
            residuals
                .state_jacobian
                .extend(r.state_jacobian.iter().map(|&(k, j, d)| (k + offset, j, d)));
            residual_terms.push(term.name());
        }
        let cloth_jacobian = self
            .system
            .cloth_jacobian_matrix(&self.state)
            .map_err(|e| solve(&e))?;
        let mixed = match design_map_rows {
            None => MixedDerivative::Matrix(
                self.system
                    .rest_mixed_matrix(
                        &self.state,
                        &self.mesh.pattern_triangles,
                        self.mesh.num_pattern_vertices(),
                    )
                    .map_err(|e| solve(&e))?,
            ),
            Some((a_rows, columns)) => MixedDerivative::TimesParameterMap(
                self.system
                    .rest_mixed_times(&self.state, &self.mesh.pattern_triangles, a_rows, columns)
                    .map_err(|e| solve(&e))?,
            ),
        };
        let (hessian, hessian_damping) = self.workspace.adjoint_hessian().map_err(|e| solve(&e))?;
        Ok(DesignLinearization {
            residuals,
            residual_terms,
            cloth_jacobian,
            hessian,
            hessian_damping,
            mixed,
        })
    }

    /// The fabric.
    pub fn fabric(&self) -> &Fabric {
        &self.fabric
    }

    /// Number of evaluations so far (each one equilibrium solve).
    pub fn evaluations(&self) -> usize {
        self.evaluations
    }

    /// Sets the count of evaluations and the work of the solves so far, as a checkpoint recorded them
    /// ([`mod@crate::design_checkpoint`]).
    pub fn restore_counts(&mut self, evaluations: usize, totals: EquilibriumTotals) {
        self.evaluations = evaluations;
        self.totals = totals;
    }

    /// The work of every equilibrium solve so far, added up.
    pub fn equilibrium_totals(&self) -> EquilibriumTotals {
        self.totals
    }

    /// The objective at pattern positions `pattern` (`#Vp`, m), and its gradient `dT/dX̄` when
    /// `with_gradient`. `on_iteration` sees the Newton iterations of the equilibrium solve and may cancel it.
    /// On an error the warm start is kept as it was. How the solve started is kept
    /// ([`Self::last_evaluation`]) so that it can be done again bit for bit ([`Self::replay`]).
    ///
    /// With the predictor ([`Self::set_predictor`]) the solve starts from the predicted equilibrium, from
    /// the last evaluation's equilibrium and with its Hessian — except after a trial that failed or whose
    /// objective is more than [`BRANCH_FACTOR`] times the best so far (the anchor): then it starts where
    /// the line search started, from the anchor's equilibrium, predicted by the anchor's first prediction
    /// scaled when the pattern lies on its line (else not predicted).
    pub fn evaluate(
        &mut self,
        pattern: &[Vec2],
        with_gradient: bool,
        on_iteration: &mut dyn FnMut(&IterationInfo) -> ControlFlow<()>,
    ) -> Result<DesignEvaluation, DesignError> {
        let clock = Instant::now();
        self.evaluations += 1;
        // The workspace's Hessian and the system's pattern change below: no linearization until success.
        let previous = self.last_pattern.take();
        let last_value = self.last_value.take();
        // Whether the last evaluation is the anchor (its state and factorization are the anchor's).
        let at_anchor = match (&self.anchor, &previous) {
            (Some(a), Some(p)) => a.pattern == *p,
            _ => false,
        };
        // A trial after one that failed, or after one whose objective left the anchor's branch.
        let left_branch = match (&self.anchor, last_value, &previous) {
            (Some(a), Some(v), Some(_)) => v > BRANCH_FACTOR * a.value,
            _ => true,
        };
        // The same pattern again (a solve to a tighter tolerance) goes on from its own equilibrium.
        let same = previous.as_deref() == Some(pattern);
        let from_anchor =
            self.predictor && self.anchor.is_some() && !at_anchor && !same && left_branch;
        let (warm_start, damping_before) = match (&self.anchor, from_anchor) {
            (Some(a), true) => (a.state.clone(), a.damping),
            _ => (self.state.clone(), self.last_damping),
        };
        let mut start = EvaluationStart {
            pattern: pattern.to_vec(),
            with_gradient,
            warm_start,
            damping_before,
            solve_start: None,
            solve_damping: None,
            tolerance: Some(self.params.tolerance),
        };
        let rest = match self.rest_shapes(pattern) {
            Ok(rest) => rest,
            Err(e) => {
                self.last_start = Some(start);
                return Err(e);
            }
        };
        // The predictor, at the old rest shapes and with the old factorization (a failure: no prediction);
        // the damping then goes on from where the anchor's (or the last) solve ended.
        if self.predictor {
            let change = if from_anchor {
                self.anchor.as_ref().and_then(|a| a.along_ray(pattern))
            } else if let Some(from) = previous.as_deref() {
                let dq = equilibrium_change(
                    &self.system,
                    &self.state,
                    &mut self.workspace,
                    &self.mesh,
                    from,
                    pattern,
                )
                .ok()
                .flatten();
                if let (Some(a), Some(dq), true) = (self.anchor.as_mut(), &dq, at_anchor) {
                    let delta = pattern.iter().zip(from).map(|(t, f)| t - f).collect();
                    a.ray = Some((delta, dq.clone()));
                }
                dq
            } else {
                None
            };
            if let Some(dq) = change
                && let Ok(state) = self.system.step(&start.warm_start, &dq, &self.params.walk)
            {
                start.solve_start = Some(state);
                start.solve_damping = damping_before.map(|p| SolveProgress { iterations: 0, ..p });
            }
        }
        let solved = self.set_rest_and_solve(&rest, &start, on_iteration);
        let solved = match solved {
            Ok((_, report, _))
                if start.solve_start.is_some()
                    && !report.converged
                    && report.stop != skintight_physics::StopReason::Cancelled =>
            {
                // The prediction led the solve astray: again from the warm start.
                self.totals.add(&report);
                start.solve_start = None;
                start.solve_damping = None;
                self.set_rest_and_solve(&rest, &start, on_iteration)
            }
            other => other,
        };
        self.last_start = Some(start);
        let (state, report, ended) = solved?;
        let evaluation = self.measure(pattern, with_gradient, state, report, ended, clock, false);
        self.record_outcome(pattern, &evaluation);
        evaluation
    }

    /// The evaluation a design ends with, which must not be lost to a slow solve: [`Self::evaluate`], and
    /// when its solve stops short of the tolerance (iteration or time limit, no progress — not a
    /// cancellation), up to [`FINAL_ROUNDS`] more solves, each going on from where the last stopped, with
    /// the damping it stopped with. If none converges, the state the last one reached is measured all the
    /// same: the evaluation's `equilibrium.converged` is false and its residual says how far it is, which
    /// the caller must report (a design's outputs then mark the garment not admissible, `not_converged`).
    ///
    /// Why: a design's evaluations may be solved loosely ([`mod@crate::inexact_tolerance`]), and the final
    /// one, at the job's own tolerance from the loose equilibrium of the best design, can take more Newton
    /// iterations than one solve allows; on the seam-traction pants the final solve stopped at the
    /// iteration limit at a relative residual of 3.5e-6 (tolerance 1e-6) after 900 s of design, and the
    /// error lost the design (docs/BENCHMARKS.md).
    pub fn final_evaluation(
        &mut self,
        pattern: &[Vec2],
        with_gradient: bool,
        on_iteration: &mut dyn FnMut(&IterationInfo) -> ControlFlow<()>,
    ) -> Result<DesignEvaluation, DesignError> {
        let clock = Instant::now();
        match self.evaluate(pattern, with_gradient, on_iteration) {
            Err(DesignError::NotConverged { .. }) => {}
            other => return other,
        }
        let rest = self.rest_shapes(pattern)?;
        for round in 1..=FINAL_ROUNDS {
            let Some((from, damping)) = self.unconverged.take() else {
                break;
            };
            let start = EvaluationStart {
                pattern: pattern.to_vec(),
                with_gradient,
                warm_start: self.state.clone(),
                damping_before: self.last_damping,
                solve_start: Some(from),
                solve_damping: damping.map(|p| SolveProgress { iterations: 0, ..p }),
                tolerance: Some(self.params.tolerance),
            };
            let solved = self.set_rest_and_solve(&rest, &start, on_iteration);
            self.last_start = Some(start);
            let (state, report, ended) = solved?;
            let evaluation = self.measure(
                pattern,
                with_gradient,
                state,
                report,
                ended,
                clock,
                round == FINAL_ROUNDS,
            );
            match evaluation {
                Err(DesignError::NotConverged { .. }) if round < FINAL_ROUNDS => continue,
                evaluation => {
                    self.record_outcome(pattern, &evaluation);
                    return evaluation;
                }
            }
        }
        Err(DesignError::Solve(
            "the final equilibrium solve stopped without a state to go on from".into(),
        ))
    }

    /// Keeps the objective of an evaluation of `pattern` (none when it failed) and, with the predictor,
    /// makes a successful one the anchor when it is the best so far.
    fn record_outcome(
        &mut self,
        pattern: &[Vec2],
        evaluation: &Result<DesignEvaluation, DesignError>,
    ) {
        self.last_value = evaluation.as_ref().ok().map(|e| e.value);
        if let Ok(e) = evaluation
            && self.predictor
            && e.equilibrium.converged
            && self.anchor.as_ref().is_none_or(|a| e.value < a.value)
        {
            self.anchor = Some(Anchor {
                value: e.value,
                pattern: pattern.to_vec(),
                state: self.state.clone(),
                damping: self.last_damping,
                ray: None,
            });
        }
    }

    /// How the last evaluation's solve started (its warm start, damping, pattern): what [`Self::replay`]
    /// needs. `None` before the first evaluation.
    pub fn last_evaluation(&self) -> Option<&EvaluationStart> {
        self.last_start.as_ref()
    }

    /// Does the evaluation `start` describes again, from the same warm start and damping, so that the
    /// state, the factorization and the last pattern afterwards are those the original left (what a resumed
    /// design needs, [`mod@crate::design_checkpoint`]). Its outcome is the original's.
    pub fn replay(
        &mut self,
        start: &EvaluationStart,
        on_iteration: &mut dyn FnMut(&IterationInfo) -> ControlFlow<()>,
    ) -> Result<DesignEvaluation, DesignError> {
        let clock = Instant::now();
        self.evaluations += 1;
        self.state = start.warm_start.clone();
        self.last_damping = start.damping_before;
        self.last_pattern = None;
        self.last_start = Some(start.clone());
        if let Some(t) = start.tolerance {
            self.set_equilibrium_tolerance(t)?;
        }
        let rest = self.rest_shapes(&start.pattern)?;
        let (state, report, ended) = self.set_rest_and_solve(&rest, start, on_iteration)?;
        let evaluation = self.measure(
            &start.pattern,
            start.with_gradient,
            state,
            report,
            ended,
            clock,
            false,
        );
        self.record_outcome(&start.pattern, &evaluation);
        evaluation
    }

    /// The rest shapes of `pattern` (`#Fc` triangles' corners), after checking its size, that it is finite
    /// and that no triangle folds over.
    fn rest_shapes(&self, pattern: &[Vec2]) -> Result<Vec<[Vec2; 3]>, DesignError> {
        let np = self.mesh.num_pattern_vertices();
        if pattern.len() != np {
            return Err(DesignError::Pattern(format!(
                "{} pattern positions for {np} pattern vertices",
                pattern.len()
            )));
        }
        if let Some(v) = pattern
            .iter()
            .position(|p| !(p.x.is_finite() && p.y.is_finite()))
        {
            return Err(DesignError::Pattern(format!(
                "pattern vertex {v} is not finite"
            )));
        }
        if let Some(f) =
            (0..self.mesh.num_triangles()).find(|&f| !(self.mesh.pattern_area(pattern, f) > 0.0))
        {
            return Err(DesignError::Pattern(format!(
                "pattern triangle {f} has folded over (no positive area)"
            )));
        }
        Ok(self
            .mesh
            .pattern_triangles
            .iter()
            .map(|t| t.map(|v| pattern[v]))
            .collect())
    }

    /// Sets the rest shapes and solves from `start`'s solve start (the warm start when it has none) with
    /// its damping: the final state, the report and the damping where the solve ended.
    fn set_rest_and_solve(
        &mut self,
        rest: &[[Vec2; 3]],
        start: &EvaluationStart,
        on_iteration: &mut dyn FnMut(&IterationInfo) -> ControlFlow<()>,
    ) -> Result<(ClothOnBodyState, EquilibriumReport, Option<SolveProgress>), DesignError> {
        self.system
            .set_rest(rest)
            .map_err(|e| DesignError::Pattern(e.to_string()))?;
        let mut state = start
            .solve_start
            .clone()
            .unwrap_or_else(|| self.state.clone());
        let mut ended = None;
        let report = equilibrium_resumable(
            &self.system,
            &mut state,
            &self.params,
            start.solve_damping,
            &mut |info, _, progress| {
                ended = Some(*progress);
                on_iteration(info)
            },
            &mut self.workspace,
        )
        .map_err(|e| DesignError::Solve(e.to_string()))?;
        Ok((state, report, ended))
    }

    /// The terms and gradient at the solved `state` of `pattern`; makes it the warm start. A solve that
    /// did not converge is an error (its state kept for [`Self::final_evaluation`]) unless
    /// `accept_unconverged` and it was not cancelled: then it is measured as it is.
    #[allow(clippy::too_many_arguments)]
    fn measure(
        &mut self,
        pattern: &[Vec2],
        with_gradient: bool,
        state: ClothOnBodyState,
        report: EquilibriumReport,
        ended: Option<SolveProgress>,
        clock: Instant,
        accept_unconverged: bool,
    ) -> Result<DesignEvaluation, DesignError> {
        self.totals.add(&report);
        self.unconverged = None;
        if !report.converged {
            match report.stop {
                skintight_physics::StopReason::Cancelled => return Err(DesignError::Cancelled),
                _ if accept_unconverged => {}
                stop => {
                    self.unconverged = Some((state, ended));
                    return Err(DesignError::NotConverged {
                        stop: format!("{stop:?}"),
                        residual: report.residual,
                    });
                }
            }
        }
        let cloth = self
            .system
            .cloth_positions(&state)
            .map_err(|e| DesignError::Solve(e.to_string()))?;

        let input = TermInput {
            mesh: &self.mesh,
            cloth: &cloth,
            pattern,
            fabric: &self.fabric,
        };
        let mut partial = with_gradient.then(|| TermGradient::zeros(&self.mesh));
        let mut state_partial = vec![
            0.0;
            if with_gradient {
                self.system.num_dofs()
            } else {
                0
            }
        ];
        let state_input = StateInput {
            system: &self.system,
            state: &state,
        };
        let mut terms = Vec::with_capacity(self.terms.len());
        let mut value = 0.0;
        for term in &self.terms {
            let eval = term.evaluate_with_state(
                &input,
                &state_input,
                partial.as_mut(),
                with_gradient.then_some(state_partial.as_mut_slice()),
            )?;
            value += eval.value;
            terms.push(TermReport {
                name: term.name(),
                value: eval.value,
                per_element: eval.per_element,
            });
        }

        let mut adjoint_damping = 0.0;
        let mut value_error = None;
        let gradient = match partial {
            None => None,
            Some(partial) => {
                let mut lambda = self
                    .system
                    .cloth_jacobian_transpose(&state, &partial.cloth)
                    .map_err(|e| DesignError::Solve(e.to_string()))?;
                for (l, d) in lambda.iter_mut().zip(&state_partial) {
                    *l += d;
                }
                let has_state_terms = lambda.iter().any(|&v| v != 0.0);
                let mut gradient = partial.pattern;
                value_error = Some(0.0);
                if has_state_terms {
                    adjoint_damping = self
                        .workspace
                        .solve_hessian(&mut lambda)
                        .map_err(|e| DesignError::Solve(e.to_string()))?;
                    value_error = self.workspace.final_gradient().map(|g| {
                        g.iter()
                            .zip(&lambda)
                            .map(|(g, l)| g * l)
                            .sum::<Real>()
                            .abs()
                    });
                    let dx = self
                        .system
                        .cloth_jacobian(&state, &lambda)
                        .map_err(|e| DesignError::Solve(e.to_string()))?;
                    let mixed = self
                        .system
                        .rest_mixed_product(&state, &dx)
                        .map_err(|e| DesignError::Solve(e.to_string()))?;
                    for (tri, m) in self.mesh.pattern_triangles.iter().zip(&mixed) {
                        for k in 0..3 {
                            gradient[tri[k]] -= m[k];
                        }
                    }
                }
                Some(gradient)
            }
        };
        self.state = state;
        self.last_pattern = Some(pattern.to_vec());
        if ended.is_some() {
            self.last_damping = ended;
        }
        Ok(DesignEvaluation {
            value,
            terms,
            gradient,
            equilibrium: report,
            adjoint_damping,
            value_error,
            cloth,
            seconds: clock.elapsed().as_secs_f64(),
        })
    }
}
