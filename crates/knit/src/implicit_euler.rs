//! Implicit (backward) Euler time stepping of a yarn patch as an incremental-potential minimisation
//! (Kane et al. 2000; the "optimization time integrator" of Gast et al. 2015):
//!
//! `x_{n+1} = argmin_x  ½ (x − x̂)ᵀ M (x − x̂) / h²  +  (c / 2h) (x − x_n)ᵀ M (x − x_n)  +  E(x)`,
//! `x̂ = x_n + h v_n`,  `v_{n+1} = (x_{n+1} − x_n) / h`
//!
//! - `x` the unknowns of [`crate::patch::PatchModel`] (positions in m, edge angles in rad), `v` their
//!   velocities (m/s, rad/s), `h` the time step (s);
//! - `M` the diagonal mass matrix: lumped vertex masses `m_i` (kg, [`crate::gravity::lumped_masses`]) for
//!   positions and the edges' moments of inertia about their axes `μ r²/2 · L̄` (kg·m²) for angles;
//! - `c` a mass-proportional (Rayleigh) damping rate (1/s): the force `−c M v`, here as its dissipation
//!   potential so that the step stays a minimisation;
//! - `E` the patch energy (J): rods, contact, gravity, sphere.
//!
//! The stationarity condition is backward Euler's `M (x − x̂)/h² + c M (x − x_n)/h + ∇E(x) = 0`, i.e.
//! `M (v_{n+1} − v_n)/h = −∇E(x_{n+1}) − c M v_{n+1}`. Its derivatives are those of `E` plus the diagonal
//! `M/h² + c M/h` (by hand: the added terms are quadratic).
//!
//! **Friction** (optional: `friction_coefficient` μ > 0): the yarn–yarn friction's dissipation potential
//! `D(x)` (J, [`crate::patch_friction`]) is one more term of the incremental potential. Its pairs, normal
//! forces and tangent planes are lagged: taken from the contact at the (sub)step's start `x_n` and frozen
//! over the step, so that the stationarity condition gains the smoothed Coulomb force `−∇D(x_{n+1})` and
//! the Newton solve minimises as before (gradient and positive semidefinite Hessian of `D` added to the
//! rest). With μ = 0 nothing is assembled and the steps are the frictionless ones to the bit.
//!
//! **Boundary conditions**: clamped vertices and vertices moving along prescribed straight paths
//! ([`Prescribed`]): at each step their positions are set to the path at `t_{n+1}` and held (their
//! gradient entries and Hessian rows are removed from the solve); so are the unused angles of open yarn
//! ends.
//!
//! **Solver**: the damped Newton of [`crate::newton`] (Levenberg–Marquardt-shifted sparse Cholesky) with
//! its per-coordinate step limit of a quarter yarn radius per Newton step — a step cannot carry a yarn
//! through another, and the contact barrier then keeps them apart — and frames re-based after every
//! accepted step. Converged when the largest unbalanced force is below `tolerance × k_s` (`k_s` the axial
//! stiffness, N) and torque below `tolerance × k_s r`. The stepper keeps one
//! [`crate::newton::NewtonWorkspace`] from step to step (the analyzed sparsity pattern and the last
//! Levenberg–Marquardt shift), and the line search evaluates the incremental potential without derivatives
//! ([`crate::patch::Order::Energy`] plus the quadratic terms above).

use std::ops::ControlFlow;

use faer::sparse::Triplet;
use serde::{Deserialize, Serialize};

use crate::newton::{
    MinimizeFigures, NewtonError, NewtonParams, NewtonProblem, NewtonReport, NewtonWorkspace,
    StopReason, minimize_with,
};
use crate::patch::{
    DOFS_PER_VERTEX, FramesSnapshot, Order, PatchEvaluation, PatchLoads, PatchModel,
};
use crate::patch_friction::PatchFriction;

/// A vertex held on a straight path: at `start` (m) at time 0, moving uniformly to `end` (m) at
/// `ramp_time` (s), then held at `end`. `start = end` clamps it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Prescribed {
    /// Global vertex index in the patch model.
    pub vertex: usize,
    /// Position at time 0 (m).
    pub start: [f64; 3],
    /// Position from `ramp_time` on (m).
    pub end: [f64; 3],
    /// Duration of the motion (s); 0 jumps to `end` at once.
    pub ramp_time: f64,
}

impl Prescribed {
    /// Position (m) at time `t` (s).
    pub fn position(&self, t: f64) -> [f64; 3] {
        let s = if self.ramp_time > 0.0 {
            (t / self.ramp_time).clamp(0.0, 1.0)
        } else {
            1.0
        };
        std::array::from_fn(|k| self.start[k] + s * (self.end[k] - self.start[k]))
    }
}

/// Settings of the time stepper.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ImplicitEulerParams {
    /// Time step `h` (s).
    pub dt: f64,
    /// Mass-proportional damping rate `c` (1/s).
    pub mass_damping: f64,
    /// The Newton solve of each step.
    pub newton: NewtonParams,
    /// How many times a step may be halved when its Newton solve does not converge (0: never; the step is
    /// then kept unconverged). See [`ImplicitEuler::step`].
    pub max_halvings: usize,
    /// Yarn–yarn Coulomb friction coefficient μ (dimensionless, ≥ 0; 0: frictionless, nothing assembled).
    pub friction_coefficient: f64,
    /// The slip `ε` (m, > 0) over which static friction is smoothed ([`crate::yarn_friction`]): a yarn held
    /// by friction creeps by at most about `ε` per (sub)step.
    pub friction_slip: f64,
}

/// The default [`ImplicitEulerParams::friction_slip`] (m): a micrometre, 10⁻³ of the 1 mm yarn radius of
/// [`crate::yarn_params::YarnParams`]'s sources; held yarns creep at most ~0.24 mm/s at `h = 1/240 s`.
pub const DEFAULT_FRICTION_SLIP: f64 = 1e-6;

impl Default for ImplicitEulerParams {
    fn default() -> Self {
        Self {
            dt: 1.0 / 240.0,
            mass_damping: 1.0,
            newton: NewtonParams {
                tolerance: 1e-9,
                max_iterations: 100,
                max_factorizations: 500,
                trace: false,
                ..NewtonParams::default()
            },
            max_halvings: 4,
            friction_coefficient: 0.0,
            friction_slip: DEFAULT_FRICTION_SLIP,
        }
    }
}

/// What one time step did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StepReport {
    /// Time at the end of the step (s).
    pub time: f64,
    /// The Newton solves of the step's substeps together: iterations, factorizations and timings summed
    /// over every attempt (abandoned ones included), `converged` when every kept substep converged, the
    /// residual, energy, damping and stop reason of the last.
    pub newton: NewtonReport,
    /// Substeps kept (1 when the whole step converged at once).
    pub substeps: usize,
    /// Substep attempts abandoned because their Newton solve did not converge (then halved).
    pub rejected_substeps: usize,
    /// Segment pairs in contact at the end of the step.
    pub contacts: usize,
    /// Candidate segment pairs at the end of the step.
    pub candidates: usize,
    /// Smallest centreline distance (m) between non-excluded candidate segments at the end of the step
    /// (infinite when none is within the contact distance).
    pub min_distance: f64,
    /// Vertices touching the sphere at the end of the step.
    pub sphere_contacts: usize,
    /// Segment pairs with friction over the step's last substep (those in contact at its start; 0 when
    /// frictionless).
    #[serde(default)]
    pub friction_pairs: usize,
}

/// The state of a patch in time.
#[derive(Clone, Debug)]
pub struct ImplicitEuler {
    model: PatchModel,
    params: ImplicitEulerParams,
    x: Vec<f64>,
    v: Vec<f64>,
    mass: Vec<f64>,
    fixed: Vec<bool>,
    prescribed: Vec<Prescribed>,
    time: f64,
    /// The Newton solver's analyzed pattern and last shift, carried from step to step.
    workspace: NewtonWorkspace,
    /// How many times the current steps are halved (`0 ..= max_halvings`), carried from step to step.
    halvings: usize,
}

/// Everything that evolves in an [`ImplicitEuler`] run, to checkpoint it and resume it later
/// ([`ImplicitEuler::save_state`], [`ImplicitEuler::restore_state`]; the model, settings and boundary
/// conditions are rebuilt from the scene). A restored stepper starts from exactly the saved state; it
/// analyzes its sparsity afresh, so its steps agree with the saved one's to rounding.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImplicitEulerState {
    /// Time (s).
    pub time: f64,
    /// How many times the current steps are halved.
    pub halvings: usize,
    /// The Levenberg–Marquardt shift the next Newton solve starts from (dimensionless).
    pub shift: f64,
    /// The unknowns, `#dofs` (4 per vertex: m, m, m, rad).
    pub x: Vec<f64>,
    /// Their velocities, `#dofs` (m/s, rad/s).
    pub v: Vec<f64>,
    /// The rod frames and reference-twist hints.
    pub frames: FramesSnapshot,
}

/// What a relaxation observer is told after every accepted Newton iteration: the model (its frames) and
/// the state. Returning `Break` ends the relaxation there (`stop = "interrupted"`).
pub type RelaxObserver<'a> = &'a mut dyn FnMut(&PatchModel, &[f64]) -> ControlFlow<()>;

/// Errors of the time stepper.
#[derive(Clone, Debug, thiserror::Error, PartialEq)]
pub enum StepError {
    /// A setting is out of range.
    #[error("{0}")]
    Params(String),
    /// The Newton solve failed.
    #[error("time step at t = {time} s: {source}")]
    Newton {
        /// Time at the start of the failed step (s).
        time: f64,
        /// The failure.
        source: NewtonError,
    },
}

impl ImplicitEuler {
    /// Starts at the model's own state, at rest, at time 0, with the prescribed vertices.
    pub fn new(
        model: PatchModel,
        params: ImplicitEulerParams,
        prescribed: Vec<Prescribed>,
    ) -> Result<Self, StepError> {
        if !(params.dt.is_finite() && params.dt > 0.0) {
            return Err(StepError::Params(format!(
                "time step dt = {} s must be > 0",
                params.dt
            )));
        }
        if !(params.mass_damping.is_finite() && params.mass_damping >= 0.0) {
            return Err(StepError::Params(format!(
                "mass_damping = {} 1/s must be ≥ 0",
                params.mass_damping
            )));
        }
        PatchFriction::validate(params.friction_coefficient, params.friction_slip)
            .map_err(StepError::Params)?;
        let nv = model.vertex_count();
        let mut fixed = vec![false; model.dof_count()];
        for p in &prescribed {
            if p.vertex >= nv {
                return Err(StepError::Params(format!(
                    "prescribed vertex {} does not exist (the patch has {nv} vertices)",
                    p.vertex
                )));
            }
            for k in 0..3 {
                fixed[DOFS_PER_VERTEX * p.vertex + k] = true;
            }
        }
        for k in model.unused_dofs() {
            fixed[k] = true;
        }
        let inertia = model.angular_inertia();
        let mut mass = Vec::with_capacity(model.dof_count());
        for (m, i) in model.masses().iter().zip(&inertia) {
            mass.extend_from_slice(&[*m, *m, *m, *i]);
        }
        let mut x = model.initial_state();
        for p in &prescribed {
            let q = p.position(0.0);
            x[DOFS_PER_VERTEX * p.vertex..DOFS_PER_VERTEX * p.vertex + 3].copy_from_slice(&q);
        }
        let v = vec![0.0; x.len()];
        Ok(Self {
            model,
            params,
            x,
            v,
            mass,
            fixed,
            prescribed,
            time: 0.0,
            workspace: NewtonWorkspace::default(),
            halvings: 0,
        })
    }

    /// The current unknowns (positions in m, angles in rad).
    pub fn state(&self) -> &[f64] {
        &self.x
    }

    /// The current velocities (m/s, rad/s).
    pub fn velocity(&self) -> &[f64] {
        &self.v
    }

    /// The current time (s).
    pub fn time(&self) -> f64 {
        self.time
    }

    /// The patch model.
    pub fn model(&self) -> &PatchModel {
        &self.model
    }

    /// The settings.
    pub fn params(&self) -> &ImplicitEulerParams {
        &self.params
    }

    /// Which unknowns are held (prescribed positions, unused angles).
    pub fn fixed(&self) -> &[bool] {
        &self.fixed
    }

    /// The kinetic energy `½ vᵀ M v` (J).
    pub fn kinetic_energy(&self) -> f64 {
        0.5 * self
            .v
            .iter()
            .zip(&self.mass)
            .map(|(v, m)| m * v * v)
            .sum::<f64>()
    }

    /// The state to checkpoint ([`ImplicitEulerState`]).
    pub fn save_state(&self) -> ImplicitEulerState {
        ImplicitEulerState {
            time: self.time,
            halvings: self.halvings,
            shift: self.workspace.shift(),
            x: self.x.clone(),
            v: self.v.clone(),
            frames: self.model.frames_snapshot(),
        }
    }

    /// Puts back a state saved by [`Self::save_state`] of a stepper built the same way (same model,
    /// settings and prescribed vertices). Checks its sizes, that it is finite and that the held unknowns
    /// are where the boundary conditions put them at its time.
    pub fn restore_state(&mut self, state: ImplicitEulerState) -> Result<(), StepError> {
        let n = self.x.len();
        let bad = |what: String| Err(StepError::Params(format!("the saved state {what}")));
        if state.x.len() != n || state.v.len() != n {
            return bad(format!(
                "has {} unknowns and {} velocities; this patch has {n}",
                state.x.len(),
                state.v.len()
            ));
        }
        if state.frames.edge_count() != self.model.edge_count()
            || state.frames.vertex_count() != self.model.vertex_count()
        {
            return bad(format!(
                "has frames of {} edges and {} vertices; this patch has {} and {}",
                state.frames.edge_count(),
                state.frames.vertex_count(),
                self.model.edge_count(),
                self.model.vertex_count()
            ));
        }
        let time_ok = state.time.is_finite() && state.time >= 0.0;
        if !time_ok
            || !state.shift.is_finite()
            || state.x.iter().chain(&state.v).any(|v| !v.is_finite())
            || !state.frames.is_valid()
        {
            return bad("has a non-finite number or a frame that is not unit".into());
        }
        if state.halvings > self.params.max_halvings {
            return bad(format!(
                "is halved {} times, more than the {} allowed",
                state.halvings, self.params.max_halvings
            ));
        }
        let scale = self.model.radius();
        for p in &self.prescribed {
            let q = p.position(state.time);
            let at = &state.x[DOFS_PER_VERTEX * p.vertex..DOFS_PER_VERTEX * p.vertex + 3];
            if (0..3).any(|k| (at[k] - q[k]).abs() > 1e-9 * scale.max(q[k].abs())) {
                return bad(format!(
                    "holds vertex {} at {at:?} m, not where its boundary condition puts it at t = {} s",
                    p.vertex, state.time
                ));
            }
        }
        self.time = state.time;
        self.halvings = state.halvings;
        self.workspace.set_shift(state.shift);
        self.x = state.x;
        self.v = state.v;
        self.model.restore_frames(&state.frames);
        Ok(())
    }

    /// Evaluates the patch energy at the current state.
    pub fn evaluate(&self) -> PatchEvaluation {
        self.model.evaluate(&self.x, false)
    }

    /// Relaxes the starting state to a static equilibrium without gravity (minimises the patch energy with
    /// gravity off, the prescribed vertices held at their start), the state a cut patch of the pattern
    /// takes at rest: the published rest geometry is not an equilibrium of this model (its yarns are cut at
    /// the border, and the pattern's rest state is balanced by HYLC's own contact law), so a simulation
    /// started from it would first spring into this state. Call before the first step; velocities are set
    /// to zero.
    pub fn relax(&mut self, newton: &NewtonParams) -> Result<NewtonReport, StepError> {
        self.relax_observed(newton, &mut |_, _| ControlFlow::Continue(()))
    }

    /// [`Self::relax`], telling `observer` every accepted Newton iteration (to checkpoint a long
    /// relaxation or report its progress); a `Break` ends it there with the state reached.
    pub fn relax_observed(
        &mut self,
        newton: &NewtonParams,
        observer: RelaxObserver<'_>,
    ) -> Result<NewtonReport, StepError> {
        let loads = *self.model.loads();
        self.model.set_loads(PatchLoads {
            gravity: [0.0; 3],
            ..loads
        });
        let zero = vec![0.0; self.x.len()];
        let x_n = self.x.clone();
        let mut x = self.x.clone();
        // A relaxation is a static equilibrium: no step, no friction.
        let friction = PatchFriction::default();
        let mut problem = StepProblem {
            model: &mut self.model,
            x_hat: &x_n,
            x_n: &x_n,
            mass: &zero,
            fixed: &self.fixed,
            h: self.params.dt,
            damping: 0.0,
            friction: &friction,
            observer: Some(observer),
            interrupted: false,
        };
        let report = minimize_with(&mut problem, &mut x, newton, &mut self.workspace);
        self.model.set_loads(loads);
        let report = report.map_err(|source| StepError::Newton {
            time: self.time,
            source,
        })?;
        self.x = x;
        self.v.iter_mut().for_each(|v| *v = 0.0);
        Ok(report)
    }

    /// Advances one time step `dt` (s), in `2^k` equal substeps of backward Euler.
    ///
    /// **Halving**: when a substep's Newton solve ends unconverged, the substep is abandoned — state,
    /// velocities and rod frames put back — and `k` grows by one (at most `max_halvings`), so the rest of
    /// the step runs in substeps of half the length; at `k = max_halvings` an unconverged substep is kept
    /// and reported (`newton.converged = false`). A whole step whose substeps all converged within a
    /// quarter of the Newton iteration limit lets the next step try `k − 1`. Why: when a frictionless knit
    /// springs from a state far from equilibrium (a cut border curling) the minimiser of one incremental
    /// potential can lie far away along a path of many contact changes, which the Newton iteration limit
    /// does not cover; the inertia term `M/h²` of a shorter step keeps it near (the 4 × 4 stockinette
    /// hang, unrelaxed, cut edges: 100 iterations a step without converging at `h = 1/240 s`, 23 at
    /// `h/16`). Frames stay at whole steps.
    pub fn step(&mut self) -> Result<StepReport, StepError> {
        let dt = self.params.dt;
        let max = self.params.max_halvings.min(30);
        let total = 1usize << max;
        let t0 = self.time;
        let mut done = 0usize;
        let mut newton = NewtonReport {
            converged: true,
            // Every step keeps at least one substep, whose reason replaces this.
            stop: StopReason::Converged,
            iterations: 0,
            factorizations: 0,
            residual: 0.0,
            energy: f64::NAN,
            damping: 0.0,
            figures: MinimizeFigures::default(),
        };
        let (mut substeps, mut rejected, mut friction_pairs) = (0, 0, 0);
        let mut easy = true;
        let easy_iterations = self.params.newton.max_iterations / 4;
        while done < total {
            let units = 1usize << (max - self.halvings.min(max));
            let h = dt * units as f64 / total as f64;
            let t1 = t0 + dt * (done + units) as f64 / total as f64;
            let saved = (self.x.clone(), self.v.clone(), self.model.frames_snapshot());
            let (report, pairs) = self.substep(h, t1)?;
            newton.iterations += report.iterations;
            newton.factorizations += report.factorizations;
            newton.figures.seconds += report.figures.seconds;
            newton.figures.timings.add(&report.figures.timings);
            if !report.converged && self.halvings < max {
                (self.x, self.v) = (saved.0, saved.1);
                self.model.restore_frames(&saved.2);
                self.time = t0 + dt * done as f64 / total as f64;
                self.halvings += 1;
                rejected += 1;
                easy = false;
                continue;
            }
            newton.converged &= report.converged;
            easy &= report.converged && report.iterations <= easy_iterations;
            (newton.residual, newton.energy, newton.damping) =
                (report.residual, report.energy, report.damping);
            newton.stop = report.stop;
            friction_pairs = pairs;
            substeps += 1;
            done += units;
        }
        self.time = t0 + dt;
        if easy && self.halvings > 0 {
            self.halvings -= 1;
        }
        // The contact figures need no derivatives.
        let ev = self.model.evaluate_order(&self.x, Order::Energy);
        Ok(StepReport {
            time: self.time,
            newton,
            substeps,
            rejected_substeps: rejected,
            contacts: ev.contacts,
            candidates: ev.candidates,
            min_distance: ev.min_distance,
            sphere_contacts: ev.sphere_contacts,
            friction_pairs,
        })
    }

    /// One backward Euler step of length `h` (s) from the current state, ending at time `t1` (s); the
    /// state, velocities and time are those at its end, converged or not. Also the segment pairs with
    /// friction (lagged at the start).
    fn substep(&mut self, h: f64, t1: f64) -> Result<(NewtonReport, usize), StepError> {
        let x_n = self.x.clone();
        let friction = PatchFriction::new(
            &self.model,
            &x_n,
            self.params.friction_coefficient,
            self.params.friction_slip,
        )
        .map_err(StepError::Params)?;
        let x_hat: Vec<f64> = x_n.iter().zip(&self.v).map(|(x, v)| x + h * v).collect();
        let mut x = x_hat.clone();
        // Held unknowns: prescribed positions at t_{n+1}; the unused angles stay where they are.
        for (k, f) in self.fixed.iter().enumerate() {
            if *f {
                x[k] = x_n[k];
            }
        }
        for p in &self.prescribed {
            let q = p.position(t1);
            x[DOFS_PER_VERTEX * p.vertex..DOFS_PER_VERTEX * p.vertex + 3].copy_from_slice(&q);
        }
        // Start the free unknowns at the predictor x̂ when the straight motion from x_n there keeps every
        // pair of yarn segments at least half a diameter apart (a freely falling piece of yarn then needs
        // one Newton step, not one per quarter radius of its fall); otherwise at x_n, from where the Newton
        // step limit walks towards the minimum.
        let safe =
            self.model.swept_clearance(&x_n, &x) >= 0.5 * self.model.stiffness().contact_distance;
        if !safe {
            for (k, f) in self.fixed.iter().enumerate() {
                if !*f {
                    x[k] = x_n[k];
                }
            }
        }
        let mut problem = StepProblem {
            model: &mut self.model,
            x_hat: &x_hat,
            x_n: &x_n,
            mass: &self.mass,
            fixed: &self.fixed,
            h,
            damping: self.params.mass_damping,
            friction: &friction,
            observer: None,
            interrupted: false,
        };
        let newton = minimize_with(
            &mut problem,
            &mut x,
            &self.params.newton,
            &mut self.workspace,
        )
        .map_err(|source| StepError::Newton {
            time: self.time,
            source,
        })?;
        for k in 0..x.len() {
            self.v[k] = (x[k] - x_n[k]) / h;
        }
        self.x = x;
        self.time = t1;
        Ok((newton, friction.len()))
    }
}

/// The incremental potential of one step as a [`NewtonProblem`].
struct StepProblem<'a> {
    model: &'a mut PatchModel,
    x_hat: &'a [f64],
    x_n: &'a [f64],
    mass: &'a [f64],
    fixed: &'a [bool],
    h: f64,
    damping: f64,
    /// The step's lagged friction (empty when frictionless).
    friction: &'a PatchFriction,
    /// Told every accepted iteration (the relaxation's checkpoints).
    observer: Option<RelaxObserver<'a>>,
    /// Whether the observer asked to stop.
    interrupted: bool,
}

impl NewtonProblem for StepProblem<'_> {
    fn dof_count(&self) -> usize {
        self.model.dof_count()
    }

    fn recycle(&self, triplets: Vec<Triplet<usize, usize, f64>>) {
        self.model.recycle(triplets);
    }

    fn evaluate(
        &self,
        x: &[f64],
        hessian: bool,
    ) -> (f64, Vec<f64>, Vec<Triplet<usize, usize, f64>>) {
        let ev = self.model.evaluate(x, hessian);
        let mut energy = ev.energy;
        let mut g = ev.gradient;
        let mut triplets = ev.hessian;
        if !self.friction.is_empty() {
            if hessian {
                // Room for the pairs' lower triangles (78 entries each) and the diagonal below: the patch
                // reserved only for its own terms and the diagonal.
                triplets.reserve(78 * self.friction.len() + x.len());
            }
            self.friction
                .add_derivatives(x, hessian, &mut energy, &mut g, &mut triplets);
        }
        let (h2, ch) = (self.h * self.h, self.damping / self.h);
        for k in 0..x.len() {
            let (a, b) = (x[k] - self.x_hat[k], x[k] - self.x_n[k]);
            let m = self.mass[k];
            energy += 0.5 * m * a * a / h2 + 0.5 * ch * m * b * b;
            g[k] += m * a / h2 + ch * m * b;
        }
        if hessian {
            triplets.retain(|t| !self.fixed[t.row] && !self.fixed[t.col]);
            triplets.reserve(x.len());
            let ks = self.model.stiffness().stretching;
            let r = self.model.radius();
            for k in 0..x.len() {
                let d = if self.fixed[k] {
                    // Any positive value: the held unknown's gradient is zero, so its step is zero.
                    if k % DOFS_PER_VERTEX == 3 {
                        ks * r
                    } else {
                        ks / r
                    }
                } else {
                    self.mass[k] * (1.0 / h2 + ch)
                };
                triplets.push(Triplet::new(k, k, d));
            }
        }
        for (k, f) in self.fixed.iter().enumerate() {
            if *f {
                g[k] = 0.0;
            }
        }
        (energy, g, triplets)
    }

    /// The patch energy without derivatives ([`Order::Energy`]) plus the quadratic terms.
    fn energy(&self, x: &[f64]) -> f64 {
        let mut energy = self.model.evaluate_order(x, Order::Energy).energy;
        if !self.friction.is_empty() {
            self.friction.add_energy(x, &mut energy);
        }
        let (h2, ch) = (self.h * self.h, self.damping / self.h);
        for k in 0..x.len() {
            let (a, b) = (x[k] - self.x_hat[k], x[k] - self.x_n[k]);
            let m = self.mass[k];
            energy += 0.5 * m * a * a / h2 + 0.5 * ch * m * b * b;
        }
        energy
    }

    /// The 4 unknowns of a vertex.
    fn group_size(&self) -> usize {
        DOFS_PER_VERTEX
    }

    /// `max(‖f‖∞ / k_s, ‖τ‖∞ / (k_s r))` over the free unknowns.
    fn residual(&self, g: &[f64]) -> f64 {
        let ks = self.model.stiffness().stretching;
        let r = self.model.radius();
        g.iter()
            .enumerate()
            .map(|(k, v)| {
                if k % DOFS_PER_VERTEX == 3 {
                    v.abs() / (ks * r)
                } else {
                    v.abs() / ks
                }
            })
            .fold(0.0, f64::max)
    }

    /// At most a quarter radius per coordinate and half a radian per angle in one Newton step.
    fn step_scale(&self, h: &[f64]) -> f64 {
        let r = self.model.radius();
        let mut scale = 1.0f64;
        for (k, v) in h.iter().enumerate() {
            let limit = if k % DOFS_PER_VERTEX == 3 {
                0.5
            } else {
                0.25 * r
            };
            if v.abs() > limit {
                scale = scale.min(limit / v.abs());
            }
        }
        scale
    }

    fn accepted(&mut self, x: &[f64]) {
        self.model.rebase_frames(x, 0.3);
        if let Some(observer) = self.observer.as_mut() {
            self.interrupted |= observer(self.model, x).is_break();
        }
    }

    fn interrupted(&self) -> bool {
        self.interrupted
    }
}

#[cfg(test)]
mod tests;
