//! Static equilibrium of the garment on the body: `q* = argmin_q U_body + U_cloth` (thesis Eq. 144) by damped
//! Newton (Eq. 145) with the damping rules of Sec. 2.1.2, sparse Cholesky factorizations whose symbolic
//! analysis is kept while the sparsity holds, and steps in `s` walked across body faces (Eq. 147–154).
//!
//! One iteration:
//! 1. evaluate the surface at the cloth vertices once ([`ClothOnBody::frames_at`]), fit the blocks' node
//!    lists to the node-pair pattern ([`ClothOnBody::structure`], [`NodeBlockAssembler::fit`]) and assemble
//!    `U`, `g = ∂U/∂q` and the matrix `H` standing for `∂²U/∂q²` on [`EquilibriumParams::assembly_threads`]
//!    threads ([`ClothOnBody::hessian_parallel`]): by default ([`EquilibriumParams::hessian`]) the covariant
//!    Hessian ([`mod@crate::cloth_on_body::hessian_form`]: Eq. 156 without the surface chart's Christoffel
//!    term, which is proportional to the unbalanced tangential forces and makes the matrix indefinite far
//!    from equilibrium; equal to `∂²U/∂q²` at every equilibrium), or Eq. 156 as written. The pattern
//!    reserves, beyond the blocks' own pairs, those a cloth vertex meets after sliding across an edge of
//!    its face ([`ClothOnBody::reserve_structure`]), so sliding rarely changes it; when a vertex goes
//!    further the pattern grows in place ([`NodeBlockAssembler::fit_or_grow`]): the triangles that slid
//!    onto other faces get the reserve around where they are now, those that left the pattern one face
//!    further, and only then is it analysed again by the Newton toolkit's pattern cache
//!    ([`crate::newton::PatternCache::fit`]) — its ordering computed on the graph of the nodes
//!    ([`SparseCholesky::analyze_grouped`]);
//! 2. solve `(H + α D) h = −g`. `D` is the damping metric ([`ClothOnBody::damping_metric`]: 1 for body
//!    coordinates, `|∂x/∂s_a|²` for surface coordinates), so `α` (N/m) means the same stiffness per metre of
//!    motion for every unknown. If the factorization fails (the matrix is not positive definite) `α` grows
//!    ×4 and the step is retried (the damping policy is the Newton toolkit's
//!    [`crate::newton::TrustRatioDamping`]);
//! 3. walk the step ([`ClothOnBody::step`]). If the energy does not decrease (or the walk fails, or a body
//!    element inverts: `U = +∞`) `α` grows ×4 and the step is retried. Otherwise the step is taken and its
//!    quality `δ = ΔU_actual / ΔU_model` (Eq. 5, model `gᵀh + ½ hᵀHh`) updates `α`: ÷3 when `δ > 0.75`
//!    (down to 0 — pure Newton — once it is negligible), ×2 when `δ < 0.25`.
//!
//! **Chord steps** ([`EquilibriumParams::reuse_factorization`], modified Newton): before step 2 factors, the
//! step `h = −M⁻¹ g` is tried with the factorization `M` already held — the last iteration's `H + αD`, or at
//! the start of a solve the previous solve's final Hessian (as the adjoint factored it, undamped where it
//! could; else with the last damping, a factorization the solve defers to the next one because a design
//! evaluation's adjoint or prediction usually makes it first: [`EquilibriumWorkspace::solve_hessian`]) —
//! walked and accepted only when the energy strictly decreases. The next iteration tries another only if this
//! one contracted the residual to at most a tenth of what it was (`CHORD_CONTRACTION`); otherwise it factors.
//! A chord step leaves `α` as it was. Cloth vertices that crossed faces since the factorization have their
//! coordinates in another face's chart: their gradient entries are rewritten into the factored matrix's
//! charts and the step's back ([`mod@crate::cloth_on_body::chart_change`]) — without that, a chord step after
//! any vertex changed face is a step in the wrong coordinates, and fails. A design evaluation starts next to
//! its equilibrium (the predictor), where the previous Hessian is close to the current one and a chord step
//! costs one assembly and two triangular solves instead of a factorization; a cold solve gains little and
//! keeps it off. A chord step contracts the residual far less than the Newton step after it, so it costs
//! Newton iterations, and designs leave it off unless asked (measurements: docs/BENCHMARKS.md, "Moved from
//! module docs (issue 42, newton)").
//!
//! Near the minimum the energy change of a step falls below the rounding of the energy sum; there a step is
//! accepted when the energy did not rise beyond that rounding band and the force residual decreased.
//!
//! **Convergence** (thesis Sec. 7.2: unbalanced forces below 1e-6, made relative here). The unbalanced
//! forces are the body-vertex entries of `g` (N) and, per cloth vertex, the tangential force represented by
//! `∂U/∂s` ([`ClothOnBody::force_residual`]). Their 2-norm is divided by the **force scale**
//! `F = max(‖∂U_cloth/∂x‖₂, F_min)`: the norm of the Cartesian cloth forces — the loads the body and the
//! sliding must balance — floored by `F_min = 10⁻³ E t ℓ √#Vc` (the force norm of a 0.1 % stretch of the
//! fabric with Young's modulus `E`, thickness `t` and mean pattern edge `ℓ`) so a slack garment has a scale.
//! The solve converges when `‖f‖₂ / F < tolerance`.
//!
//! Iteration and time limits, and a callback that may cancel, end the solve with `converged = false` and the
//! best (last accepted) state — never a hang. The solve reports in the Newton toolkit's report shape
//! ([`EquilibriumReport`] `= NewtonReport<EquilibriumFigures>`, with the names its files always had).

use std::ops::ControlFlow;
use std::time::Instant;

use faer::sparse::{SparseColMat, SparseColMatRef};

use crate::cloth_on_body::{
    ClothOnBody, ClothOnBodyError, ClothOnBodyState, CoordinateCharts, Evaluation, HessianForm,
    SurfaceFrames,
};
use crate::math::Real;
use crate::newton::{
    PatternCache, TrustRatioDamping, add_to_diagonal, indefinite, shifted_factorization,
};
use crate::node_block_assembly::{NodeBlockAssembler, NodeBlockRecorder};
use crate::sparse_cholesky::{CholeskyError, SparseCholesky, SparseCholeskyParams};
use skintight_geometry::surface::walk::WalkParams;

/// Why a solve stopped (the Newton toolkit's, [`crate::newton::StopReason`]).
pub use crate::newton::StopReason;

mod report;
pub use report::{EquilibriumFigures, EquilibriumReport, EquilibriumTimings};

/// Settings of [`equilibrium`].
#[derive(Clone, Copy, Debug)]
pub struct EquilibriumParams {
    /// Converged when the unbalanced force norm over the force scale is below this (dimensionless).
    pub tolerance: Real,
    /// Most Newton iterations.
    pub max_iterations: usize,
    /// Wall-clock limit of the solve (s).
    pub time_limit_s: Real,
    /// Initial damping relative to the median damped diagonal `median(H_ii / D_ii)` (dimensionless).
    pub initial_damping: Real,
    /// Most damping increases within one iteration before the solve stops with no progress.
    pub max_attempts: usize,
    /// Settings of the walk of surface coordinates.
    pub walk: WalkParams,
    /// Fill-reducing ordering and threads of the sparse Cholesky factorization.
    pub cholesky: SparseCholeskyParams,
    /// Threads of the Hessian assembly: `None` (default) uses the machine's available parallelism,
    /// `Some(k)` uses `k` (at least one).
    pub assembly_threads: Option<usize>,
    /// Chord (modified Newton) steps: before factoring, try the step `h = −M⁻¹ g` with the factorization
    /// `M` already held — the last iteration's, or at the start of a solve the previous solve's final
    /// Hessian — and factor only when it fails or stops contracting (see the module documentation).
    /// Default false; design evaluations turn it on with the job's `optimizer.chord_steps` (off by default
    /// there too: a chord step saves a factorization but costs Newton iterations, see the module
    /// documentation).
    pub reuse_factorization: bool,
    /// The matrix factored for `∂²U/∂q²` ([`HessianForm`]): by default `Covariant`, the Hessian without the
    /// surface chart's Christoffel term, which vanishes at every equilibrium; `Coordinate` is the Hessian in
    /// the faces' coordinates (Eq. 156 as written).
    pub hessian: HessianForm,
}

impl EquilibriumParams {
    /// The number of assembly threads these settings ask for.
    pub fn assembly_thread_count(&self) -> usize {
        self.assembly_threads
            .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
            .max(1)
    }
}

impl Default for EquilibriumParams {
    fn default() -> Self {
        Self {
            tolerance: 1e-6,
            max_iterations: 200,
            time_limit_s: 600.0,
            initial_damping: 1e-3,
            max_attempts: 40,
            walk: WalkParams::default(),
            cholesky: SparseCholeskyParams::default(),
            assembly_threads: None,
            reuse_factorization: false,
            hessian: HessianForm::Covariant,
        }
    }
}

/// What the progress callback sees after every iteration.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct IterationInfo {
    /// Iteration number (1-based).
    pub iteration: usize,
    /// Energy after the step (J).
    pub energy: Real,
    /// Relative residual after the step.
    pub residual: Real,
    /// Damping used for the step (N/m).
    pub damping: Real,
    /// Step quality `δ` (Eq. 5).
    pub step_quality: Real,
    /// Whether the step reused the factorization held (a chord step,
    /// [`EquilibriumParams::reuse_factorization`]) instead of factoring.
    pub chord: bool,
    /// Seconds since the solve started.
    pub elapsed_s: Real,
}

/// Why a solve could not run at all.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum EquilibriumError {
    /// The system could not be evaluated at the starting state.
    #[error("the starting state cannot be evaluated: {0}")]
    Start(ClothOnBodyError),
    /// Evaluation failed at an accepted state (should not happen: accepted states have finite energy).
    #[error("evaluation failed during the solve: {0}")]
    Evaluation(ClothOnBodyError),
    /// Invalid settings.
    #[error("invalid solver setting: {0}")]
    Params(String),
    /// The linear solver failed for a reason other than a matrix that is not positive definite.
    #[error("the sparse Cholesky factorization failed: {0}")]
    Linear(String),
}

/// The assembled Hessian with its pattern and its factorization (symbolic phase kept while the pattern
/// holds).
struct LinearSystem {
    assembler: NodeBlockAssembler,
    /// The symbolic analysis of the assembler's pattern, and the factorization.
    analysis: PatternCache,
    symbolic_analyses: usize,
    /// Per cloth triangle, its corners' faces when its reserve pairs were last added to the pattern.
    reserved_faces: Vec<[usize; 3]>,
    /// The charts of the cloth coordinates the assembled matrix is in (its state's).
    charts: CoordinateCharts,
    /// The charts of the matrix `analysis` holds the factorization of (a chord step rewrites the cloth
    /// vertices that crossed faces since, [`mod@crate::cloth_on_body::chart_change`]).
    factored_charts: CoordinateCharts,
    /// The undamped diagonal while `H + α D` is factored ([`NodeBlockAssembler::with_shifted_diagonal`]).
    saved_diagonal: Vec<Real>,
}

impl LinearSystem {
    /// The analysis of the assembler's pattern (a linear system is built analysed).
    fn cholesky(&self) -> &SparseCholesky {
        self.analysis
            .cholesky()
            .expect("a linear system holds the analysis of its pattern")
    }

    /// Analyses the assembler's pattern again if it is no longer the one analysed
    /// ([`PatternCache::fit`]: the ordering computed on the graph of the nodes, [`ClothOnBody::dof_groups`],
    /// of the kind the first analysis chose), counting the analysis.
    fn analyze(
        &mut self,
        system: &ClothOnBody,
        params: &SparseCholeskyParams,
    ) -> Result<(), EquilibriumError> {
        let groups = system.dof_groups();
        let analysed = self
            .analysis
            .fit(self.assembler.matrix().as_ref(), groups.as_deref(), params)
            .map_err(|e| EquilibriumError::Linear(e.to_string()))?;
        self.symbolic_analyses += usize::from(analysed);
        Ok(())
    }
}

fn params_check(p: &EquilibriumParams) -> Result<(), EquilibriumError> {
    if !(p.tolerance.is_finite() && p.tolerance > 0.0) {
        return Err(EquilibriumError::Params(format!(
            "tolerance must be a positive number, got {}",
            p.tolerance
        )));
    }
    if !(p.time_limit_s > 0.0) {
        return Err(EquilibriumError::Params(format!(
            "time limit must be positive seconds, got {}",
            p.time_limit_s
        )));
    }
    if !(p.initial_damping.is_finite() && p.initial_damping >= 0.0) {
        return Err(EquilibriumError::Params(format!(
            "initial damping must be a non-negative number, got {}",
            p.initial_damping
        )));
    }
    Ok(())
}

/// `H x` for a symmetric matrix `h` stored as its lower triangle.
fn symmetric_product(h: &SparseColMat<usize, Real>, x: &[Real]) -> Vec<Real> {
    let v = h.val();
    let n = x.len();
    let mut y = vec![0.0; n];
    let (cp, ri) = (h.symbolic().col_ptr(), h.symbolic().row_idx());
    for c in 0..n {
        for k in cp[c]..cp[c + 1] {
            let r = ri[k];
            y[r] += v[k] * x[c];
            if r != c {
                y[c] += v[k] * x[r];
            }
        }
    }
    y
}

fn dot(a: &[Real], b: &[Real]) -> Real {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// `(‖f‖, F, ‖f‖ / F)` of an evaluation, with the force-scale floor
/// ([`ClothOnBody::force_scale_floor`]).
fn residual(ev: &Evaluation, floor: Real) -> (Real, Real, Real) {
    let scale = ev.cloth_force_norm.max(floor);
    (ev.force_residual, scale, ev.force_residual / scale)
}

/// Solves for the equilibrium starting from `state`, which is replaced by the final (best) state.
/// `on_iteration` sees every accepted iteration and may stop the solve (`ControlFlow::Break`).
pub fn equilibrium(
    system: &ClothOnBody,
    state: &mut ClothOnBodyState,
    params: &EquilibriumParams,
    on_iteration: &mut dyn FnMut(&IterationInfo) -> ControlFlow<()>,
) -> Result<EquilibriumReport, EquilibriumError> {
    equilibrium_in(
        system,
        state,
        params,
        on_iteration,
        &mut EquilibriumWorkspace::default(),
    )
}

/// [`equilibrium`] keeping the Hessian's pattern, its symbolic analysis and the final Hessian in
/// `workspace`: a later solve of the same system (e.g. with a new pattern, [`ClothOnBody::set_rest`])
/// starts from them, and [`EquilibriumWorkspace::solve_hessian`] solves with the final Hessian (the
/// adjoint of a design gradient).
///
/// The damped Newton iteration of the module documentation (Eq. 145): assemble `U`, `g` and `H`; stop when
/// converged or out of iterations or time; take a damped step `(H + αD) h = −g` that decreases `U`,
/// raising `α` until one does; assemble at the new state; update `α` from the step's quality.
pub fn equilibrium_in(
    system: &ClothOnBody,
    state: &mut ClothOnBodyState,
    params: &EquilibriumParams,
    on_iteration: &mut dyn FnMut(&IterationInfo) -> ControlFlow<()>,
    workspace: &mut EquilibriumWorkspace,
) -> Result<EquilibriumReport, EquilibriumError> {
    equilibrium_resumable(
        system,
        state,
        params,
        None,
        &mut |info, _, _| on_iteration(info),
        workspace,
    )
}

/// Where a solve stands after an iteration, besides its state: what a solve resumed from that state needs
/// to go on as the interrupted one would have (the iteration count, the damping and its scale, which the
/// first Hessian of the solve fixed).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SolveProgress {
    /// Newton iterations done.
    pub iterations: usize,
    /// The median stiffness per metre of the solve's first Hessian (N/m), the damping's scale.
    pub diag_scale: Real,
    /// The damping `α` of the next step (N/m).
    pub alpha: Real,
    /// The last `α` with which `H + αD` factored (N/m).
    pub last_factored: Real,
}

/// [`equilibrium_in`] that can be resumed: `on_iteration` also sees the state after each iteration and the
/// solve's [`SolveProgress`], which a caller can store (a checkpoint); a solve started from that state with
/// `resume = Some(progress)` continues the interrupted one — same iteration count, damping and damping
/// scale — instead of starting afresh. (Its time limit counts from the resumed start.)
pub fn equilibrium_resumable(
    system: &ClothOnBody,
    state: &mut ClothOnBodyState,
    params: &EquilibriumParams,
    resume: Option<SolveProgress>,
    on_iteration: &mut dyn FnMut(
        &IterationInfo,
        &ClothOnBodyState,
        &SolveProgress,
    ) -> ControlFlow<()>,
    workspace: &mut EquilibriumWorkspace,
) -> Result<EquilibriumReport, EquilibriumError> {
    params_check(params)?;
    let start = Instant::now();
    let mut timings = EquilibriumTimings::default();
    let floor = system.force_scale_floor();
    let threads = params.assembly_thread_count();
    // The last solve's final factorization, if it was left for now (`FinalHessian::deferred_alpha`).
    timings.factorization_s += workspace.factor_deferred(system.num_dofs());
    workspace.final_hessian = None;

    let (mut linear, mut at) = start_assembly(
        system,
        state,
        params,
        workspace.linear.take(),
        threads,
        &mut timings,
    )?;
    let (mut force, mut scale, mut rel) = residual(&at.eval, floor);
    let diag_scale = match resume {
        Some(r) if r.diag_scale.is_finite() && r.diag_scale > 0.0 => r.diag_scale,
        _ => median_stiffness(&at.eval, &linear.assembler),
    };
    let mut damping = TrustRatioDamping::new(params.initial_damping, diag_scale);
    let mut iterations = 0;
    if let Some(r) = resume {
        damping.alpha = r.alpha;
        damping.last_factored = r.last_factored;
        iterations = r.iterations;
    }
    let mut counts = SolveCounts::default();
    // Whether the next iteration may try a chord step with the factorization held.
    let mut chord_allowed = params.reuse_factorization;

    let stop_reason = loop {
        if let Some(reason) = stop_test(rel, iterations, start, params) {
            break reason;
        }
        let chord = if chord_allowed && linear.cholesky().is_factorized() {
            chord_step(
                system,
                state,
                &at,
                &mut linear,
                params,
                &mut counts,
                &mut timings,
            )?
        } else {
            None
        };
        let is_chord = chord.is_some();
        let step = match chord {
            Some(step) => step,
            None => {
                let Some(step) = damped_step(
                    system,
                    state,
                    &at,
                    &mut linear,
                    &mut damping,
                    params,
                    start,
                    &mut counts,
                    &mut timings,
                )?
                else {
                    break if start.elapsed().as_secs_f64() >= params.time_limit_s {
                        StopReason::TimeLimit
                    } else {
                        StopReason::NoProgress
                    };
                };
                step
            }
        };
        let next = assemble_step(system, &step, &mut linear, params, threads, &mut timings)?;
        let (f_t, s_t, rel_t) = residual(&next.eval, floor);
        if step.rounding_only && rel_t >= rel {
            // No measurable energy change and no better balance: a stall at the rounding floor.
            break StopReason::NoProgress;
        }
        // A chord step that did not contract the residual enough: factor at the next iteration. A fresh
        // factorization may serve as the next iteration's chord.
        chord_allowed =
            params.reuse_factorization && (!is_chord || rel_t <= CHORD_CONTRACTION * rel);
        *state = step.state;
        at = next;
        (force, scale, rel) = (f_t, s_t, rel_t);
        iterations += 1;
        let used_alpha = damping.alpha;
        if is_chord {
            counts.chord_steps += 1;
        } else {
            damping.update(step.quality);
        }
        let info = IterationInfo {
            iteration: iterations,
            energy: at.eval.energy,
            residual: rel,
            damping: used_alpha,
            step_quality: step.quality,
            chord: is_chord,
            elapsed_s: start.elapsed().as_secs_f64(),
        };
        let progress = SolveProgress {
            iterations,
            diag_scale,
            alpha: damping.alpha,
            last_factored: damping.last_factored,
        };
        if on_iteration(&info, state, &progress).is_break() {
            break StopReason::Cancelled;
        }
    };

    // The final Hessian is not factored here: what follows a solve (an adjoint, a prediction) factors it
    // with the smallest damping that factors (`factor_adjoint`), and only where nothing did by the next
    // solve is it factored with the Newton steps' last damping, for that solve's chord steps.
    let final_alpha = damping.last_factored.max(damping.alpha);

    timings.total_s = start.elapsed().as_secs_f64();
    timings.newton_step_s = if iterations > 0 {
        timings.total_s / iterations as Real
    } else {
        0.0
    };
    let report = EquilibriumReport {
        converged: stop_reason == StopReason::Converged,
        stop: stop_reason,
        iterations,
        factorizations: counts.factorizations,
        residual: rel,
        energy: at.eval.energy,
        damping: damping.alpha,
        figures: EquilibriumFigures {
            force_residual: force,
            force_scale: scale,
            chord_steps: counts.chord_steps,
            rejected_inversions: counts.rejected_inversions,
            symbolic_analyses: linear.symbolic_analyses,
            unknowns: system.num_dofs(),
            hessian_nonzeros: linear.assembler.nnz(),
            ordering: linear.cholesky().ordering_used(),
            factor_nonzeros: linear.cholesky().factor_nnz(),
            timings,
        },
    };
    workspace.linear = Some(linear);
    workspace.final_hessian = Some(FinalHessian {
        gradient: at.gradient,
        threads,
        damping_metric: at.eval.damping_metric,
        diag_scale,
        factored_alpha: None,
        adjoint_factored: false,
        deferred_alpha: Some(final_alpha),
    });
    Ok(report)
}

/// `U`, `g = ∂U/∂q` and the evaluation's figures at the current state; `H` is in the assembler.
struct Assembled {
    eval: Evaluation,
    gradient: Vec<Real>,
}

/// A trial state that decreased the energy (or left it within rounding), with its surface frames.
struct AcceptedStep {
    state: ClothOnBodyState,
    frames: SurfaceFrames,
    /// Step quality `δ = ΔU_actual / ΔU_model` (Eq. 5).
    quality: Real,
    /// Accepted only because the energy change is within rounding (it did not decrease).
    rounding_only: bool,
}

/// Counters of the report.
#[derive(Default)]
struct SolveCounts {
    factorizations: usize,
    rejected_inversions: usize,
    chord_steps: usize,
}

/// The residual contraction a chord step must reach (`‖f‖` after ≤ this × before) for the next iteration
/// to try another one instead of factoring. Newton's quadratic phase contracts far more; a chord step of a
/// factorization that has gone stale contracts less, and one factorization then costs less than the
/// chord steps it would save (a chord step keeps the assembly, walk and energy of a Newton step and saves
/// its factorization). The value was chosen on the tapered-cylinder design (docs/BENCHMARKS.md, session 14).
const CHORD_CONTRACTION: Real = 0.1;

/// Why the solve stops before another step, if it does: converged, out of iterations or out of time.
fn stop_test(
    rel: Real,
    iterations: usize,
    start: Instant,
    params: &EquilibriumParams,
) -> Option<StopReason> {
    if rel < params.tolerance {
        Some(StopReason::Converged)
    } else if iterations >= params.max_iterations {
        Some(StopReason::IterationLimit)
    } else if start.elapsed().as_secs_f64() >= params.time_limit_s {
        Some(StopReason::TimeLimit)
    } else {
        None
    }
}

/// The first assembly: the pattern (kept from the workspace's `kept` when it still fits, else built with
/// its reserve and analysed), then `U`, `g` and `H` at `state`. Errors are the starting state's.
fn start_assembly(
    system: &ClothOnBody,
    state: &ClothOnBodyState,
    params: &EquilibriumParams,
    kept: Option<LinearSystem>,
    threads: usize,
    timings: &mut EquilibriumTimings,
) -> Result<(LinearSystem, Assembled), EquilibriumError> {
    let n = system.num_dofs();
    let t0 = Instant::now();
    let frames = system.frames_at(state).map_err(EquilibriumError::Start)?;
    let (mut linear, grown) = match kept {
        Some(mut linear) if linear.assembler.size() == n => {
            linear.symbolic_analyses = 0;
            let grown = refit_pattern(system, state, &frames, &mut linear);
            (linear, grown)
        }
        _ => {
            let assembler = system.hessian_assembler(state, &frames);
            let mut linear = LinearSystem {
                assembler,
                analysis: PatternCache::default(),
                reserved_faces: system.triangle_faces(state),
                symbolic_analyses: 0,
                charts: CoordinateCharts::default(),
                factored_charts: CoordinateCharts::default(),
                saved_diagonal: Vec::new(),
            };
            let t1 = Instant::now();
            linear.analyze(system, &params.cholesky)?;
            timings.factorization_s += t1.elapsed().as_secs_f64();
            (linear, false)
        }
    };
    let mut gradient = vec![0.0; n];
    let eval = assemble(
        system,
        state,
        &frames,
        &mut gradient,
        &mut linear,
        (threads, params.hessian),
    )
    .map_err(EquilibriumError::Start)?;
    if !eval.energy.is_finite() {
        return Err(EquilibriumError::Start(ClothOnBodyError::Shape(
            "the energy of the starting state is not finite".into(),
        )));
    }
    timings.assembly_s += t0.elapsed().as_secs_f64();
    if grown {
        let t0 = Instant::now();
        linear.analyze(system, &params.cholesky)?;
        timings.factorization_s += t0.elapsed().as_secs_f64();
    }
    Ok((linear, Assembled { eval, gradient }))
}

/// Assembly at an accepted step's state. The node lists of its blocks are checked against the pattern
/// first: a cloth vertex that entered a face whose stencil couples new body vertices grows the pattern
/// (the union with the old one, so it settles after a few changes), analysed again; many changed lists
/// within the pattern are re-recorded for the fast scatter path (same matrix pattern, no new analysis).
fn assemble_step(
    system: &ClothOnBody,
    step: &AcceptedStep,
    linear: &mut LinearSystem,
    params: &EquilibriumParams,
    threads: usize,
    timings: &mut EquilibriumTimings,
) -> Result<Assembled, EquilibriumError> {
    let t0 = Instant::now();
    let mut gradient = vec![0.0; system.num_dofs()];
    let grown = refit_pattern(system, &step.state, &step.frames, linear);
    let eval = assemble(
        system,
        &step.state,
        &step.frames,
        &mut gradient,
        linear,
        (threads, params.hessian),
    )
    .map_err(EquilibriumError::Evaluation)?;
    if linear.assembler.finish().is_err() {
        return Err(EquilibriumError::Linear(
            "a Hessian block fell outside the sparsity pattern fitted to it".into(),
        ));
    }
    timings.assembly_s += t0.elapsed().as_secs_f64();
    if grown {
        let t0 = Instant::now();
        linear.analyze(system, &params.cholesky)?;
        timings.factorization_s += t0.elapsed().as_secs_f64();
    }
    Ok(Assembled { eval, gradient })
}

/// `U`, `g` (into `gradient`) and `H` in `form` (into the assembler) at `state` on `threads` threads.
fn assemble(
    system: &ClothOnBody,
    state: &ClothOnBodyState,
    frames: &SurfaceFrames,
    gradient: &mut [Real],
    linear: &mut LinearSystem,
    (threads, form): (usize, HessianForm),
) -> Result<Evaluation, ClothOnBodyError> {
    linear.assembler.begin();
    linear.charts = system.charts(frames);
    system.hessian_parallel(
        state,
        frames,
        gradient,
        &mut linear.assembler,
        threads,
        form,
    )
}

/// The median stiffness per metre `median(|H_ii / D_ii|)` (N/m) of the first Hessian, the scale of the
/// damping: robust to a few extreme diagonal entries.
fn median_stiffness(eval: &Evaluation, assembler: &NodeBlockAssembler) -> Real {
    let d = &eval.damping_metric;
    let vals = assembler.matrix().val();
    let slots = assembler.diagonal_slots();
    let mut ratios: Vec<Real> = slots
        .iter()
        .zip(d.iter())
        .map(|(&s, &di)| (vals[s] / di).abs())
        .filter(|r| r.is_finite())
        .collect();
    if ratios.is_empty() {
        Real::MIN_POSITIVE
    } else {
        let mid = ratios.len() / 2;
        (*ratios.select_nth_unstable_by(mid, |a, b| a.total_cmp(b)).1).max(Real::MIN_POSITIVE)
    }
}

/// One damped Newton step (Eq. 145): solves `(H + αD) h = −g`, walks it ([`ClothOnBody::step`]) and
/// accepts it when the energy decreases (or stays within rounding), raising `α` ×4 after every failed
/// attempt (no factorization, no finite step, a failed walk, no decrease). `None` when `max_attempts`
/// attempts or the time limit ran out first.
#[allow(clippy::too_many_arguments)]
fn damped_step(
    system: &ClothOnBody,
    state: &ClothOnBodyState,
    at: &Assembled,
    linear: &mut LinearSystem,
    damping: &mut TrustRatioDamping,
    params: &EquilibriumParams,
    start: Instant,
    counts: &mut SolveCounts,
    timings: &mut EquilibriumTimings,
) -> Result<Option<AcceptedStep>, EquilibriumError> {
    let d = &at.eval.damping_metric;
    for _ in 0..params.max_attempts {
        if start.elapsed().as_secs_f64() >= params.time_limit_s {
            break;
        }
        let Some(h) = newton_direction(linear, d, &at.gradient, damping, counts, timings)? else {
            damping.increase();
            continue;
        };
        match trial_step(
            system,
            state,
            at,
            &h,
            linear.assembler.matrix(),
            params,
            counts,
        )? {
            Some(step) => return Ok(Some(step)),
            None => damping.increase(),
        }
    }
    Ok(None)
}

/// Walks the step `h` from `state` ([`ClothOnBody::step`]) and measures it: the accepted step when the
/// energy decreased or stayed within rounding ([`step_quality`], against the model `gᵀh + ½hᵀHh` of the
/// undamped Hessian `hessian`, Eq. 2, 5); `None`
/// when the walk fails, a body element inverts (`U = +∞`, counted) or the energy rose.
fn trial_step(
    system: &ClothOnBody,
    state: &ClothOnBodyState,
    at: &Assembled,
    h: &[Real],
    hessian: &SparseColMat<usize, Real>,
    params: &EquilibriumParams,
    counts: &mut SolveCounts,
) -> Result<Option<AcceptedStep>, EquilibriumError> {
    let hh = symmetric_product(hessian, h);
    let predicted = dot(&at.gradient, h) + 0.5 * dot(h, &hh);
    let Ok(trial) = system.step(state, h, &params.walk) else {
        return Ok(None);
    };
    let frames = system
        .frames_at(&trial)
        .map_err(EquilibriumError::Evaluation)?;
    let (trial_body, trial_cloth) = system
        .energies_at(&trial, &frames)
        .map_err(EquilibriumError::Evaluation)?;
    if trial_body == Real::INFINITY {
        counts.rejected_inversions += 1;
        return Ok(None);
    }
    Ok(
        step_quality(at.eval.energy, trial_body + trial_cloth, predicted).map(
            |(quality, rounding_only)| AcceptedStep {
                state: trial,
                frames,
                quality,
                rounding_only,
            },
        ),
    )
}

/// One chord step: `h = −M⁻¹ g` with the factorization `M` held (of an earlier Hessian, damped as it was
/// then), walked ([`ClothOnBody::step`]) and accepted only when the energy strictly decreases. `None`
/// (nothing changed but the time spent) when the solve fails, the walk fails, a body element inverts or
/// the energy does not decrease: the caller factors instead. The quality `δ` is measured against the
/// current Hessian's model (Eq. 2, 5), as for a Newton step.
fn chord_step(
    system: &ClothOnBody,
    state: &ClothOnBodyState,
    at: &Assembled,
    linear: &mut LinearSystem,
    params: &EquilibriumParams,
    counts: &mut SolveCounts,
    timings: &mut EquilibriumTimings,
) -> Result<Option<AcceptedStep>, EquilibriumError> {
    let t0 = Instant::now();
    // The cloth vertices that crossed faces since the factorization: their gradient in the charts the
    // factored matrix is in, the step back in the current ones.
    let changes = system.chart_changes(&linear.factored_charts, &linear.charts);
    let mut h: Vec<Real> = at.gradient.iter().map(|v| -v).collect();
    if !changes.iter().all(|c| c.gradient_to_old(&mut h)) {
        return Ok(None);
    }
    let solved = linear.cholesky().solve_in_place(&mut h);
    let rewritten = changes.iter().all(|c| c.step_to_new(&mut h));
    timings.solve_s += t0.elapsed().as_secs_f64();
    if solved.is_err() || !rewritten || !h.iter().all(|v| v.is_finite()) {
        return Ok(None);
    }
    // Only a strict decrease: a chord step within rounding is left to a fresh factorization.
    Ok(trial_step(
        system,
        state,
        at,
        &h,
        linear.assembler.matrix(),
        params,
        counts,
    )?
    .filter(|step| !step.rounding_only))
}

/// The Newton direction `h` of `(H + αD) h = −g`; `None` when `H + αD` is not positive definite or `h` is
/// not finite (then `α` must grow).
fn newton_direction(
    linear: &mut LinearSystem,
    d: &[Real],
    g: &[Real],
    damping: &mut TrustRatioDamping,
    counts: &mut SolveCounts,
    timings: &mut EquilibriumTimings,
) -> Result<Option<Vec<Real>>, EquilibriumError> {
    let t0 = Instant::now();
    let factor = factorize_damped(linear, d, damping.alpha);
    counts.factorizations += 1;
    let seconds = t0.elapsed().as_secs_f64();
    timings.factorization_s += seconds;
    match factor {
        Ok(()) => timings.one_factorization_s = seconds,
        Err(CholeskyError::NotPositiveDefinite { .. }) => return Ok(None),
        Err(e) => return Err(EquilibriumError::Linear(e.to_string())),
    }
    damping.last_factored = damping.alpha;
    let t0 = Instant::now();
    let mut h: Vec<Real> = g.iter().map(|v| -v).collect();
    linear
        .cholesky()
        .solve_in_place(&mut h)
        .map_err(|e| EquilibriumError::Linear(e.to_string()))?;
    timings.solve_s += t0.elapsed().as_secs_f64();
    Ok(h.iter().all(|v| v.is_finite()).then_some(h))
}

/// Factors `H + αD` numerically; `H` stays in the assembler as it was, to the bit.
fn factorize_damped(
    linear: &mut LinearSystem,
    d: &[Real],
    alpha: Real,
) -> Result<(), CholeskyError> {
    let LinearSystem {
        assembler,
        analysis,
        saved_diagonal,
        ..
    } = linear;
    let cholesky = analysis
        .cholesky_mut()
        .expect("a linear system holds the analysis of its pattern");
    let factor = assembler
        .with_shifted_diagonal(alpha, d, saved_diagonal, |m| cholesky.factorize(m.as_ref()));
    if factor.is_ok() {
        linear.factored_charts.clone_from(&linear.charts);
    }
    factor
}

/// Whether a trial energy is accepted against the current `energy` (J): it decreased, or it stayed within
/// the rounding band of the energy sum. Returns the step quality `δ = ΔU_actual / ΔU_model` (0 when the
/// model `predicted` does not decrease) and whether the step was accepted only within rounding.
fn step_quality(energy: Real, trial_energy: Real, predicted: Real) -> Option<(Real, bool)> {
    let band = 1e-11 * energy.abs().max(Real::MIN_POSITIVE) + 1e-14;
    let decreased = trial_energy < energy;
    let within_rounding = trial_energy.is_finite() && (trial_energy - energy).abs() <= band;
    if !(decreased || within_rounding) {
        return None;
    }
    let quality = if predicted < 0.0 {
        (trial_energy - energy) / predicted
    } else {
        0.0
    };
    Some((quality, within_rounding && !decreased))
}

/// Records the blocks' node lists at `state` and fits the assembler's pattern to them
/// ([`NodeBlockAssembler::fit_or_grow`]), reserving for the blocks outside it the pairs of
/// [`ClothOnBody::slide_reserve`] (the triangles that slid since `reserved_faces`, updated, and those that
/// moved out); returns whether the pattern grew (and must be analysed again, [`LinearSystem::analyze`]).
fn refit_pattern(
    system: &ClothOnBody,
    state: &ClothOnBodyState,
    frames: &SurfaceFrames,
    linear: &mut LinearSystem,
) -> bool {
    let mut recorder = NodeBlockRecorder::default();
    system.structure(frames, &mut recorder);
    let reserved_faces = &mut linear.reserved_faces;
    linear.assembler.fit_or_grow(&recorder, |outside| {
        system.slide_reserve(state, outside, reserved_faces)
    })
}

/// The final Hessian of the last solve, for [`EquilibriumWorkspace::solve_hessian`].
struct FinalHessian {
    /// `g = ∂U/∂q` at the final state (`#q`): what the solve left unbalanced.
    gradient: Vec<Real>,
    /// The threads the solve assembled on, which multi-column solves with this Hessian split across.
    threads: usize,
    damping_metric: Vec<Real>,
    diag_scale: Real,
    /// The damping `α` of the numeric factorization currently held, if it is one of this Hessian.
    factored_alpha: Option<Real>,
    /// Whether the factorization held is the adjoint's (the smallest damping that factors).
    adjoint_factored: bool,
    /// The Newton steps' last damping `α` (N/m) while this Hessian has not been factored: the next solve
    /// of the workspace factors `H + αD` with it before it assembles anything, so that its chord steps
    /// find the factorization they always found. An adjoint factorization ([`EquilibriumWorkspace::solve_hessian`])
    /// clears it — a design evaluation's solve is followed by the adjoint or the next prediction, which
    /// factored the final Hessian a second time when the solve ended damped and factored it at once.
    deferred_alpha: Option<Real>,
}

/// What [`equilibrium_in`] keeps between solves of one system: the Hessian's pattern and symbolic
/// analysis (reused by the next solve while they fit) and the final Hessian with its factorization.
#[derive(Default)]
pub struct EquilibriumWorkspace {
    linear: Option<LinearSystem>,
    final_hessian: Option<FinalHessian>,
}

impl std::fmt::Debug for EquilibriumWorkspace {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EquilibriumWorkspace")
            .field("has_pattern", &self.linear.is_some())
            .field("has_final_hessian", &self.final_hessian.is_some())
            .finish()
    }
}

impl EquilibriumWorkspace {
    /// The final Hessian `H = ∂²U/∂q²` of the last solve (`#q × #q`, N/m for body coordinates; the units
    /// of `U` per unit² of the unknowns in general), undamped, at the returned state. **Only the lower
    /// triangle** (row ≥ column, diagonal included) is stored, in compressed-column form with sorted row
    /// indices, as the sparse Cholesky reads it; the pattern may hold explicit zeros (reserved pairs).
    /// `None` before the first solve. The damping of the Newton steps is lent to each factorization and
    /// the assembled diagonal put back to the bit ([`NodeBlockAssembler::with_shifted_diagonal`]), so this
    /// is the assembled matrix exactly.
    pub fn hessian(&self) -> Option<SparseColMatRef<'_, usize, Real>> {
        self.final_hessian.as_ref()?;
        self.linear.as_ref().map(|l| l.assembler.matrix().as_ref())
    }

    /// The energy gradient `g = ∂U/∂q` (`#q`; N for body coordinates, the units of `U` per unit of each
    /// unknown in general) at the final state of the last solve: the forces it left unbalanced, to first
    /// order `δq = −H⁻¹ g` away from the exact equilibrium. `None` before the first solve.
    pub fn final_gradient(&self) -> Option<&[Real]> {
        self.final_hessian.as_ref().map(|f| f.gradient.as_slice())
    }

    /// The matrix [`Self::solve_hessian`] solves with, `H + α D` (`#q × #q`, lower triangle only, as
    /// [`Self::hessian`]), factoring it first if needed, and `α` (N/m, 0 when `H` factored as it is). `D`
    /// is the damping metric ([`ClothOnBody::damping_metric`]). A design Gauss-Newton system built with
    /// this matrix is consistent with the adjoint gradient.
    pub fn adjoint_hessian(
        &mut self,
    ) -> Result<(SparseColMat<usize, Real>, Real), EquilibriumError> {
        let alpha = self.factor_adjoint()?;
        let (Some(linear), Some(fin)) = (self.linear.as_ref(), self.final_hessian.as_ref()) else {
            return Err(EquilibriumError::Linear(
                "no equilibrium has been solved in this workspace yet".into(),
            ));
        };
        let mut matrix = linear.assembler.matrix().clone();
        if alpha > 0.0 {
            let slots = linear.assembler.diagonal_slots();
            add_to_diagonal(matrix.val_mut(), slots, alpha, &fin.damping_metric);
        }
        Ok((matrix, alpha))
    }

    /// Solves `H λ = rhs` in place with the Hessian `H = ∂²U/∂q²` at the final state of the last solve
    /// (`rhs`: `#q`, any units; `λ` in those units per N/m). Reuses that solve's factorization when it was
    /// undamped. `H` is positive semi-definite at a minimum; where it is singular (e.g. a cloth vertex with
    /// no stiffness along the surface) the smallest damping `α D` that factors is added, from `10⁻¹⁰` of the
    /// median diagonal stiffness up: the returned `α` (N/m, 0 when none was needed). The solution then
    /// leaves out the motions the energy does not resist, which the design gradient cannot see either.
    pub fn solve_hessian(&mut self, rhs: &mut [Real]) -> Result<Real, EquilibriumError> {
        let size = self.linear.as_ref().map(|l| l.assembler.size());
        if let Some(n) = size
            && rhs.len() != n
        {
            return Err(EquilibriumError::Linear(format!(
                "right-hand side has {} entries, the system {n} unknowns",
                rhs.len()
            )));
        }
        let alpha = self.factor_adjoint()?;
        let linear = self.linear.as_mut().expect("factored above");
        linear
            .cholesky()
            .solve_in_place(rhs)
            .map_err(|e| EquilibriumError::Linear(e.to_string()))?;
        Ok(alpha)
    }

    /// [`Self::solve_hessian`] for `columns` right-hand sides at once: `rhs` is `#q × columns`, column-major,
    /// overwritten with the solutions; returns the damping `α` (N/m). The columns are split across the
    /// solve's assembly threads ([`EquilibriumParams::assembly_threads`],
    /// [`SparseCholesky::solve_columns_in_place_on`]).
    pub fn solve_hessian_columns(
        &mut self,
        rhs: &mut [Real],
        columns: usize,
    ) -> Result<Real, EquilibriumError> {
        let size = self.linear.as_ref().map(|l| l.assembler.size());
        if let Some(n) = size
            && rhs.len() != n * columns
        {
            return Err(EquilibriumError::Linear(format!(
                "right-hand sides have {} entries, the system {n} unknowns × {columns} columns",
                rhs.len()
            )));
        }
        let alpha = self.factor_adjoint()?;
        let threads = self.final_hessian.as_ref().map_or(1, |f| f.threads);
        let linear = self.linear.as_mut().expect("factored above");
        linear
            .cholesky()
            .solve_columns_in_place_on(rhs, columns, threads)
            .map_err(|e| EquilibriumError::Linear(e.to_string()))?;
        Ok(alpha)
    }

    /// Factors the last solve's final Hessian with the Newton steps' last damping if that was deferred
    /// and nothing has factored it since (`FinalHessian::deferred_alpha`), as the solve used to before
    /// returning, so that the next solve's chord steps start from the factorization they always had; a
    /// failure leaves no factorization, as it did then. Only for a system of `unknowns` unknowns (another
    /// system rebuilds the pattern anyway). Returns the seconds it took.
    fn factor_deferred(&mut self, unknowns: usize) -> Real {
        let (Some(linear), Some(fin)) = (self.linear.as_mut(), self.final_hessian.as_mut()) else {
            return 0.0;
        };
        let Some(alpha) = fin.deferred_alpha.take() else {
            return 0.0;
        };
        if linear.assembler.size() != unknowns {
            return 0.0;
        }
        let t0 = Instant::now();
        if factorize_damped(linear, &fin.damping_metric, alpha).is_ok() {
            fin.factored_alpha = Some(alpha);
            fin.adjoint_factored = alpha == 0.0;
        }
        t0.elapsed().as_secs_f64()
    }

    /// Factors `H + α D` for [`Self::solve_hessian`] (the smallest damping that factors, see there) unless
    /// already done for this final state; returns `α` (N/m).
    fn factor_adjoint(&mut self) -> Result<Real, EquilibriumError> {
        let (Some(linear), Some(fin)) = (self.linear.as_mut(), self.final_hessian.as_mut()) else {
            return Err(EquilibriumError::Linear(
                "no equilibrium has been solved in this workspace yet".into(),
            ));
        };
        if !fin.adjoint_factored {
            fin.deferred_alpha = None;
            // From 0, then 10⁻¹⁰ of the scale up by decades while below 10⁻² of it.
            let scale = fin.diag_scale;
            let raise = |alpha: Real| {
                (alpha < 1e-2 * scale).then(|| {
                    if alpha == 0.0 {
                        1e-10 * scale
                    } else {
                        10.0 * alpha
                    }
                })
            };
            let metric = &fin.damping_metric;
            let LinearSystem {
                assembler,
                analysis,
                saved_diagonal,
                ..
            } = linear;
            let cholesky = analysis
                .cholesky_mut()
                .expect("a linear system holds the analysis of its pattern");
            let factored = shifted_factorization(
                0.0,
                raise,
                |alpha| {
                    assembler.with_shifted_diagonal(alpha, metric, saved_diagonal, |m| {
                        cholesky.factorize(m.as_ref())
                    })
                },
                indefinite,
            );
            match factored {
                Ok(alpha) => {
                    linear.factored_charts.clone_from(&linear.charts);
                    fin.factored_alpha = Some(alpha);
                    fin.adjoint_factored = true;
                }
                Err((_, e)) => {
                    fin.factored_alpha = None;
                    return Err(EquilibriumError::Linear(format!(
                        "the final Hessian cannot be factored for the adjoint: {e}"
                    )));
                }
            }
        }
        Ok(fin.factored_alpha.unwrap_or(0.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cloth_on_body::hessian_form::tests::assembled_dense;
    use crate::cloth_on_body::tests::{Kind, sphere_system, sphere_system_pinned};
    use crate::math::Vec2;

    fn solve(kind: Kind, seed: u64, scales: &[(Real, Real)]) -> (EquilibriumReport, Real, Real) {
        let (system, mut state) = sphere_system(kind, seed, scales);
        let e0 = system.energy(&state).unwrap();
        let mut count = 0;
        let report = equilibrium(
            &system,
            &mut state,
            &EquilibriumParams::default(),
            &mut |_| {
                count += 1;
                ControlFlow::Continue(())
            },
        )
        .unwrap();
        assert_eq!(count, report.iterations);
        // The reported residual is the one of the returned state.
        let mut g = vec![0.0; system.num_dofs()];
        system.gradient(&state, &mut g).unwrap();
        let f = system.force_residual(&state, &g).unwrap();
        assert!((f - report.figures.force_residual).abs() <= 1e-9 * (1.0 + f));
        (report, e0, system.energy(&state).unwrap())
    }

    #[test]
    fn a_tight_patch_reaches_equilibrium_on_both_surfaces() {
        for kind in [Kind::Loop, Kind::Linear] {
            for seed in [1, 2] {
                let (report, e0, e1) = solve(kind, seed, &[(0.9, 0.93), (0.92, 0.9)]);
                assert!(report.converged, "{kind:?} seed {seed}: {report:?}");
                assert!(report.residual < 1e-6);
                assert!(e1 < e0, "{e1} !< {e0}");
                assert!(report.figures.timings.one_factorization_s > 0.0);
            }
        }
    }

    #[test]
    fn covariant_and_coordinate_newton_reach_one_equilibrium_where_their_matrices_agree() {
        for kind in [Kind::Loop, Kind::Linear] {
            // Every other cloth vertex pinned: the free ones are held by taut triangles, so the
            // equilibrium is unique and stretched (a patch free to slide on the sphere goes slack).
            let (system, start) =
                sphere_system_pinned(kind, 1, &[(0.9, 0.93), (0.92, 0.9)], |i| i % 2 == 0);
            let mut ends = Vec::new();
            for form in [HessianForm::Coordinate, HessianForm::Covariant] {
                let mut state = start.clone();
                let params = EquilibriumParams {
                    tolerance: 1e-10,
                    hessian: form,
                    ..Default::default()
                };
                let report = equilibrium(&system, &mut state, &params, &mut |_| {
                    ControlFlow::Continue(())
                })
                .unwrap();
                assert!(report.converged, "{kind:?} {form:?}: {report:?}");
                ends.push(state);
            }
            // One minimum: the same energy, taut; on the Loop surface the same cloth and body positions too
            // (the charts may differ). On the linear surface a wrinkled direction lets the two ends lie
            // 2.5e-5 m apart at energies equal to 1e-14.
            let (a, b) = (&ends[0], &ends[1]);
            let (ea, eb) = (system.energy(a).unwrap(), system.energy(b).unwrap());
            assert!(
                eb > 0.0 && (ea - eb).abs() <= 1e-10 * eb,
                "{kind:?}: {ea} vs {eb}"
            );
            if matches!(kind, Kind::Loop) {
                let (ca, cb) = (
                    system.cloth_positions(a).unwrap(),
                    system.cloth_positions(b).unwrap(),
                );
                let gap = ca
                    .iter()
                    .zip(&cb)
                    .chain(a.body.iter().zip(&b.body))
                    .fold(0.0_f64, |m, (p, q)| m.max((p - q).norm()));
                assert!(gap <= 1e-6, "{kind:?}: positions {gap} m apart");
            }
            // There the two matrices are the Hessian, to the residual.
            let (coordinate, _) = assembled_dense(&system, b, HessianForm::Coordinate);
            let (covariant, _) = assembled_dense(&system, b, HessianForm::Covariant);
            let scale = coordinate.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            let gap = coordinate
                .iter()
                .zip(&covariant)
                .fold(0.0_f64, |m, (x, y)| m.max((x - y).abs()));
            assert!(gap <= 1e-7 * scale, "{kind:?}: {gap} of {scale}");
        }
    }

    #[test]
    fn iteration_limit_and_cancellation_end_the_solve_without_convergence() {
        let (system, mut state) = sphere_system(Kind::Loop, 3, &[(0.9, 0.93)]);
        let params = EquilibriumParams {
            max_iterations: 1,
            ..Default::default()
        };
        let report = equilibrium(&system, &mut state, &params, &mut |_| {
            ControlFlow::Continue(())
        })
        .unwrap();
        assert!(!report.converged);
        assert_eq!(report.stop, StopReason::IterationLimit);
        assert_eq!(report.iterations, 1);

        let (system, mut state) = sphere_system(Kind::Loop, 3, &[(0.9, 0.93)]);
        let report = equilibrium(
            &system,
            &mut state,
            &EquilibriumParams::default(),
            &mut |_| ControlFlow::Break(()),
        )
        .unwrap();
        assert_eq!(report.stop, StopReason::Cancelled);
        assert_eq!(report.iterations, 1);
    }

    #[test]
    fn a_solve_resumed_from_its_progress_ends_where_the_uninterrupted_one_does() {
        for kind in [Kind::Loop, Kind::Linear] {
            let (system, start) = sphere_system(kind, 1, &[(0.9, 0.93), (0.92, 0.9)]);
            let params = EquilibriumParams::default();
            // The uninterrupted solve, noting its state and progress after iteration 2.
            let mut state = start.clone();
            let mut saved = None;
            let whole = equilibrium_resumable(
                &system,
                &mut state,
                &params,
                None,
                &mut |info, s, p| {
                    if info.iteration == 2 {
                        saved = Some((s.clone(), *p));
                    }
                    ControlFlow::Continue(())
                },
                &mut EquilibriumWorkspace::default(),
            )
            .unwrap();
            assert!(whole.converged && whole.iterations > 2, "{whole:?}");
            let (mut resumed_state, progress) = saved.unwrap();
            assert_eq!(progress.iterations, 2);
            let mut seen = Vec::new();
            let resumed = equilibrium_resumable(
                &system,
                &mut resumed_state,
                &params,
                Some(progress),
                &mut |info, _, _| {
                    seen.push(info.iteration);
                    ControlFlow::Continue(())
                },
                &mut EquilibriumWorkspace::default(),
            )
            .unwrap();
            // It numbers on from 3 and takes the same steps to the same equilibrium.
            assert_eq!(seen.first(), Some(&3));
            assert_eq!(resumed.iterations, whole.iterations);
            let rel = (resumed.energy - whole.energy).abs() / whole.energy.abs();
            assert!(
                rel <= 1e-9,
                "{kind:?}: {} vs {}",
                resumed.energy,
                whole.energy
            );
        }
    }

    #[test]
    fn bad_settings_are_refused() {
        let (system, mut state) = sphere_system(Kind::Linear, 3, &[(0.9, 0.93)]);
        for params in [
            EquilibriumParams {
                tolerance: 0.0,
                ..Default::default()
            },
            EquilibriumParams {
                time_limit_s: Real::NAN,
                ..Default::default()
            },
        ] {
            assert!(matches!(
                equilibrium(
                    &system,
                    &mut state,
                    &params,
                    &mut |_| ControlFlow::Continue(())
                ),
                Err(EquilibriumError::Params(_))
            ));
        }
    }

    /// A garment on a sphere solved with `first` (to convergence), its pattern then scaled by `scale`,
    /// solved again with `second` in the same workspace, going on with the damping where the first solve
    /// ended, as a design evaluation does; `between` sees the workspace in between, `on_iteration` every
    /// iteration of the second solve. Returns both reports, the final state and the energy the second solve
    /// started from (J).
    fn solve_shrink_solve(
        (kind, seed, scale): (Kind, u64, Real),
        first: EquilibriumParams,
        second: EquilibriumParams,
        between: &mut dyn FnMut(&mut EquilibriumWorkspace, &ClothOnBody),
        on_iteration: &mut dyn FnMut(&IterationInfo),
    ) -> (EquilibriumReport, EquilibriumReport, ClothOnBodyState, Real) {
        let (mut system, mut state) = sphere_system(kind, seed, &[(0.9, 0.92), (0.88, 0.9)]);
        let mut workspace = EquilibriumWorkspace::default();
        let mut ended = None;
        let first = equilibrium_resumable(
            &system,
            &mut state,
            &first,
            None,
            &mut |_, _, progress| {
                ended = Some(SolveProgress {
                    iterations: 0,
                    ..*progress
                });
                ControlFlow::Continue(())
            },
            &mut workspace,
        )
        .unwrap();
        assert!(first.converged);
        between(&mut workspace, &system);
        let rest: Vec<[Vec2; 3]> = system
            .elements()
            .iter()
            .map(|e| e.rest().map(|p| p * scale))
            .collect();
        system.set_rest(&rest).unwrap();
        let start_energy = system.energy(&state).unwrap();
        let report = equilibrium_resumable(
            &system,
            &mut state,
            &second,
            ended,
            &mut |info, _, _| {
                on_iteration(info);
                ControlFlow::Continue(())
            },
            &mut workspace,
        )
        .unwrap();
        (first, report, state, start_energy)
    }

    #[test]
    fn chord_steps_reach_the_same_equilibrium_with_fewer_factorizations() {
        // A solved garment whose pattern then shrinks a little, solved again in the same workspace (which
        // holds the first solve's final factorization) with and without reusing it.
        let run = |kind: Kind, seed: u64, reuse: bool| {
            let mut chords = 0;
            let (first, report, _, start_energy) = solve_shrink_solve(
                (kind, seed, 0.995),
                EquilibriumParams::default(),
                EquilibriumParams {
                    reuse_factorization: reuse,
                    tolerance: 1e-9,
                    ..EquilibriumParams::default()
                },
                &mut |_, _| {},
                &mut |info| chords += usize::from(info.chord),
            );
            assert_eq!(first.figures.chord_steps, 0, "off by default");
            assert_eq!(chords, report.figures.chord_steps);
            (report, start_energy)
        };
        for (kind, seed) in [(Kind::Loop, 4), (Kind::Linear, 5)] {
            let (plain, start_energy) = run(kind, seed, false);
            let (chord, _) = run(kind, seed, true);
            assert!(plain.converged && chord.converged, "{plain:?}\n{chord:?}");
            assert_eq!(plain.figures.chord_steps, 0);
            assert!(chord.figures.chord_steps > 0, "{chord:?}");
            assert!(
                chord.factorizations < plain.factorizations,
                "{kind:?}: {} factorizations with chord steps, {} without",
                chord.factorizations,
                plain.factorizations
            );
            // The same equilibrium energy (both solved to 1e-9 of the force scale; the patch on a sphere
            // may still rotate about it at no cost, so the positions are not compared).
            assert!(plain.residual < 1e-9 && chord.residual < 1e-9);
            let diff = (plain.energy - chord.energy).abs();
            assert!(
                diff <= 1e-9 * start_energy.abs(),
                "{kind:?}: energies {} and {}",
                plain.energy,
                chord.energy
            );
            eprintln!(
                "{kind:?}: factorizations {} → {}, Newton iterations {} → {} ({} chord), energies {diff:e} J apart",
                plain.factorizations,
                chord.factorizations,
                plain.iterations,
                chord.iterations,
                chord.figures.chord_steps
            );
        }
    }

    #[test]
    fn the_deferred_final_factorization_leaves_the_next_solve_as_an_immediate_one_did() {
        // A solve leaves its final Hessian unfactored; the next solve factors it first, for its chord
        // steps. That must be the very solve it was when the first solve factored it before returning:
        // here that factorization is forced right after the first solve, then compared to the bit. The
        // pattern shrinks by 10⁻⁴ only, so that the second solve's first chord step is accepted (it is the
        // one the held factorization decides; a stale one takes another path).
        let run = |kind: Kind, seed: u64, at_once: bool| {
            let params = EquilibriumParams {
                reuse_factorization: true,
                ..EquilibriumParams::default()
            };
            let mut deferred = None;
            let (_, report, state, _) = solve_shrink_solve(
                (kind, seed, 0.9999),
                params,
                params,
                &mut |workspace, system| {
                    deferred = workspace.final_hessian.as_ref().unwrap().deferred_alpha;
                    assert!(deferred.is_some(), "the final Hessian is left unfactored");
                    if at_once {
                        assert!(workspace.factor_deferred(system.num_dofs()) > 0.0);
                        assert_eq!(workspace.factor_deferred(system.num_dofs()), 0.0, "once");
                    }
                },
                &mut |_| {},
            );
            (report, state, deferred)
        };
        for (kind, seed) in [(Kind::Loop, 4), (Kind::Linear, 5)] {
            let (later, s1, alpha) = run(kind, seed, false);
            let (at_once, s2, _) = run(kind, seed, true);
            eprintln!(
                "{kind:?}: deferred α {alpha:?}, {} Newton iterations ({} chord)",
                later.iterations, later.figures.chord_steps
            );
            assert!(later.figures.chord_steps > 0, "{later:?}");
            assert_eq!(later.energy.to_bits(), at_once.energy.to_bits());
            assert_eq!(
                (
                    later.iterations,
                    later.figures.chord_steps,
                    later.factorizations
                ),
                (
                    at_once.iterations,
                    at_once.figures.chord_steps,
                    at_once.factorizations
                )
            );
            assert_eq!(s1, s2);
        }
    }

    #[test]
    fn adjoint_solve_inverts_the_final_hessian_and_a_second_solve_reuses_the_analysis() {
        for (kind, seed) in [(Kind::Loop, 4), (Kind::Linear, 5)] {
            let (mut system, mut state) = sphere_system(kind, seed, &[(0.9, 0.92), (0.88, 0.9)]);
            let mut workspace = EquilibriumWorkspace::default();
            let mut rhs = vec![1.0; system.num_dofs()];
            assert!(
                workspace.solve_hessian(&mut rhs).is_err(),
                "nothing solved yet"
            );
            // The workspace's adjoint against the exact Hessian: the coordinate form (this garment's
            // equilibrium is nearly singular, so whether a matrix within 1e-6 of it factors undamped is
            // a matter of rounding).
            let params = EquilibriumParams {
                hessian: HessianForm::Coordinate,
                ..Default::default()
            };
            let report = equilibrium_in(
                &system,
                &mut state,
                &params,
                &mut |_| ControlFlow::Continue(()),
                &mut workspace,
            )
            .unwrap();
            assert!(report.converged);
            // H λ = b with the Hessian at the returned state.
            let n = system.num_dofs();
            let b: Vec<Real> = (0..n).map(|i| ((i * 7919) % 13) as Real - 6.0).collect();
            let mut lambda = b.clone();
            let alpha = workspace.solve_hessian(&mut lambda).unwrap();
            assert_eq!(
                alpha, 0.0,
                "{kind:?}: a taut garment's Hessian factors undamped"
            );
            let (h, _) = assembled_dense(&system, &state, params.hessian);
            let bnorm = b.iter().map(|v| v * v).sum::<Real>().sqrt();
            let res: Real = (0..n)
                .map(|r| {
                    let hl: Real = (0..n).map(|c| h[r * n + c] * lambda[c]).sum();
                    (hl - b[r]).powi(2)
                })
                .sum::<Real>()
                .sqrt();
            assert!(res <= 1e-6 * bnorm, "residual {res} vs {bnorm}");
            // A smaller pattern, solved again from the last state in the same workspace: the pattern and
            // its analysis carry over.
            let rest: Vec<[Vec2; 3]> = system
                .elements()
                .iter()
                .map(|e| e.rest().map(|p| p * 0.98))
                .collect();
            system.set_rest(&rest).unwrap();
            let again = equilibrium_in(
                &system,
                &mut state,
                &params,
                &mut |_| ControlFlow::Continue(()),
                &mut workspace,
            )
            .unwrap();
            assert!(again.converged);
            assert_eq!(again.figures.symbolic_analyses, 0);
        }
    }

    #[test]
    fn explicit_final_hessian_is_the_lower_triangle_of_the_assembled_one_and_the_adjoint_matrix() {
        for (kind, seed) in [(Kind::Loop, 6), (Kind::Linear, 7)] {
            let (system, mut state) = sphere_system(kind, seed, &[(0.9, 0.92), (0.88, 0.9)]);
            let mut workspace = EquilibriumWorkspace::default();
            assert!(workspace.hessian().is_none());
            assert!(workspace.adjoint_hessian().is_err());
            let report = equilibrium_in(
                &system,
                &mut state,
                &EquilibriumParams {
                    hessian: HessianForm::Coordinate,
                    ..Default::default()
                },
                &mut |_| ControlFlow::Continue(()),
                &mut workspace,
            )
            .unwrap();
            assert!(report.converged);
            let n = system.num_dofs();
            // The matrix the solve factored (here the coordinate form, the exact Hessian).
            let (dense, _) = assembled_dense(&system, &state, HessianForm::Coordinate);
            let h = workspace.hessian().unwrap();
            assert_eq!((h.nrows(), h.ncols()), (n, n));
            let mut stored = vec![0.0; n * n];
            let (cp, ri, v) = (h.symbolic().col_ptr(), h.symbolic().row_idx(), h.val());
            for c in 0..n {
                for k in cp[c]..cp[c + 1] {
                    assert!(ri[k] >= c, "only the lower triangle is stored");
                    stored[ri[k] * n + c] += v[k];
                }
            }
            let scale = dense.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            for r in 0..n {
                for c in 0..=r {
                    let d = (stored[r * n + c] - dense[r * n + c]).abs();
                    assert!(d <= 1e-10 * scale, "{kind:?} ({r}, {c}): {d}");
                }
            }
            // The adjoint matrix is the one solve_hessian inverts: (H + αD) λ = b.
            let (adjoint, alpha) = workspace.adjoint_hessian().unwrap();
            let b: Vec<Real> = (0..n).map(|i| ((i * 31) % 7) as Real - 3.0).collect();
            let mut lambda = b.clone();
            assert_eq!(workspace.solve_hessian(&mut lambda).unwrap(), alpha);
            let hl = symmetric_product(&adjoint, &lambda);
            let bnorm = dot(&b, &b).sqrt();
            let res = hl
                .iter()
                .zip(&b)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<Real>()
                .sqrt();
            assert!(res <= 1e-8 * bnorm, "{kind:?}: residual {res} vs {bnorm}");
        }
    }
}
