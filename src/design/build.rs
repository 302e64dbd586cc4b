//! Preparing a design: the initial garment solved to equilibrium, the weighted objective terms built from
//! the job (with the poses of the sliding objective read and checked), and the optimizer settings.

use std::ops::ControlFlow;

use skintight_design::{
    BoundarySmoothness, Compactness, DesignMesh, DesignProblem, EdgeLengthUniformity,
    FabricStretchLimit, GaussNewtonParams, GaussNewtonSolver, LbfgsParams, Optimizer,
    PatternDesignParams, PatternMap, PinnedTraction, Pressure, PressureStatistics, SeamLength,
    SeamTraction, SeamTractionForm, ShapeImls, Sliding, StretchWindow, Term,
};
use skintight_geometry::math::{Real, Vec3};
use skintight_geometry::mesh::TriMesh;

use super::spec::{
    DesignJob, GaussNewtonSystemSpec, OptimizerMethod, SeamTractionFormSpec, SlidingObjective,
    TargetSpec,
};
use super::statistics::{pressure_statistics, window_fraction};
use super::target::revolution_target;
use crate::scene::PathResolver;
use crate::simulate::admissibility::wale_directions;
use crate::simulate::{SimulateError, Simulation, equilibrium_params, prepare, run};
use skintight_physics::equilibrium::{EquilibriumReport, IterationInfo};

/// A prepared design: the simulation of the initial garment at equilibrium and the design problem.
pub struct Design {
    /// The job.
    pub job: DesignJob,
    /// The simulation (initial garment, then the final design after [`run_design`](super::run_design)).
    pub sim: Simulation,
    /// The design problem.
    pub problem: DesignProblem,
    /// The boundary parametrization.
    pub map: PatternMap,
    /// With a stretch objective: the fraction of the cloth's pattern area whose principal stretches both
    /// lie in its window, for the initial garment.
    pub initial_window_fraction: Option<Real>,
    /// Young–Laplace pressure statistics of the initial garment (None when undefined).
    pub initial_pressure: Option<PressureStatistics>,
    /// The solve of the initial garment's equilibrium (its Newton iterations and timings count in the
    /// design's `result.json`).
    pub initial_equilibrium: EquilibriumReport,
    /// The best design's objective (units of the objective) solved to the job's tolerance before the final
    /// seam truing moved its patterns (`result.json`'s `seam_truing.objective_before`); `None` until a run
    /// trued them (or when nothing needed truing).
    pub objective_before_truing: Option<Real>,
}

/// Builds the garment, solves its initial equilibrium and sets up the objective. `resolver` finds the
/// body and target files.
pub fn prepare_design(
    job: &DesignJob,
    resolver: &dyn PathResolver,
) -> Result<Design, SimulateError> {
    prepare_design_with(job, resolver, &mut |_| ControlFlow::Continue(()))
}

/// [`prepare_design`] with a callback at every Newton iteration of the initial equilibrium, which may stop
/// it (`Break`: the design is not prepared; the error says the initial garment did not reach equilibrium,
/// and a caller that stopped it knows why).
pub fn prepare_design_with(
    job: &DesignJob,
    resolver: &dyn PathResolver,
    on_iteration: &mut dyn FnMut(&IterationInfo) -> ControlFlow<()>,
) -> Result<Design, SimulateError> {
    job.validate()?;
    let scene = job.scene();
    let mut sim = prepare(&scene, resolver)?;
    let report = run(&mut sim, on_iteration)?;
    if !report.converged {
        return Err(SimulateError::failed(format!(
            "the initial garment did not reach equilibrium ({:?} after {} iterations); fix the scene \
             before designing",
            report.stop, report.iterations
        )));
    }
    let (mesh, pattern) = DesignMesh::from_garment(&sim.garment);
    let pattern0 = pattern.clone();
    let map = PatternMap::new(&mesh, &pattern)
        .map_err(|e| SimulateError::failed(format!("pattern parametrization: {e}")))?;
    let terms = terms(job, resolver, &sim)?;
    let mut problem = DesignProblem::new(
        sim.system.clone(),
        sim.state.clone(),
        mesh,
        terms,
        equilibrium_params(&scene),
    )
    .map_err(|e| SimulateError::failed(e.to_string()))?;
    problem.set_predictor(job.optimizer.predictor);
    problem.set_chord_steps(job.optimizer.predictor && job.optimizer.chord_steps);
    let initial_window_fraction = job
        .objectives
        .stretch
        .as_ref()
        .and_then(|w| window_fraction(&sim.system, &sim.state, w.min, w.max));
    let initial_pressure = pressure_statistics(job, &problem, &sim, &pattern0);
    Ok(Design {
        job: job.clone(),
        sim,
        problem,
        map,
        initial_window_fraction,
        initial_pressure,
        initial_equilibrium: report,
        objective_before_truing: None,
    })
}

impl Design {
    /// The report `result.json` gives for a design: the final solve's (`last`: residual, energy, the
    /// system's size) with the work of the whole design — the Newton iterations, factorizations and solver
    /// timings of the initial equilibrium and of every evaluation, added up.
    pub fn total_report(&self, last: &EquilibriumReport) -> EquilibriumReport {
        let mut totals = self.problem.equilibrium_totals();
        totals.add(&self.initial_equilibrium);
        let mut report = last.clone();
        report.iterations = totals.newton_iterations;
        report.factorizations = totals.factorizations;
        report.figures.chord_steps = totals.chord_steps;
        report.figures.timings = totals.timings;
        report
    }
}

fn term_error(key: &str, e: impl std::fmt::Display) -> SimulateError {
    SimulateError::input(key, e.to_string())
}

/// The control positions (`#Vs × 3`, m) of each pose of the sliding objective: each pose file must be the
/// body surface `surface` deformed — the same number of vertices and the same triangles.
pub(super) fn pose_controls(
    sliding: &SlidingObjective,
    surface: &TriMesh,
    num_control: usize,
    resolver: &dyn PathResolver,
) -> Result<Vec<Vec<Vec3>>, SimulateError> {
    if surface.num_vertices() != num_control {
        return Err(SimulateError::input(
            "objectives.sliding.poses",
            format!(
                "the body's smooth surface has {num_control} control vertices for {} surface vertices; \
                 poses need a body whose surface is its own control mesh",
                surface.num_vertices()
            ),
        ));
    }
    let sorted = |f: &[usize; 3]| {
        let mut f = *f;
        f.sort_unstable();
        f
    };
    let mut body_faces: Vec<[usize; 3]> = surface.faces.iter().map(sorted).collect();
    body_faces.sort_unstable();
    let mut out = Vec::with_capacity(sliding.poses.len());
    for (i, pose) in sliding.poses.iter().enumerate() {
        let key = format!("objectives.sliding.poses[{i}].path");
        let file = resolver.resolve(&key, &pose.path)?;
        let mesh = skintight_geometry::mesh::io::read_mesh(&file)
            .map_err(|e| SimulateError::input(&key, format!("cannot read {}: {e}", pose.path)))?;
        if mesh.num_vertices() != surface.num_vertices() {
            return Err(SimulateError::input(
                &key,
                format!(
                    "{} has {} vertices, the body surface {}; a pose is the body deformed",
                    pose.path,
                    mesh.num_vertices(),
                    surface.num_vertices()
                ),
            ));
        }
        let mut faces: Vec<[usize; 3]> = mesh.faces.iter().map(sorted).collect();
        faces.sort_unstable();
        if faces != body_faces {
            return Err(SimulateError::input(
                &key,
                format!(
                    "{} does not have the body surface's triangles; a pose is the body deformed",
                    pose.path
                ),
            ));
        }
        if let Some(v) = mesh
            .positions
            .iter()
            .position(|p| !p.iter().all(|c| c.is_finite()))
        {
            return Err(SimulateError::input(
                &key,
                format!("{}: vertex {v} is not finite", pose.path),
            ));
        }
        out.push(mesh.positions);
    }
    Ok(out)
}

/// The weighted terms of the job.
fn terms(
    job: &DesignJob,
    resolver: &dyn PathResolver,
    sim: &Simulation,
) -> Result<Vec<Box<dyn Term>>, SimulateError> {
    let mut out: Vec<Box<dyn Term>> = Vec::new();
    let o = &job.objectives;
    if let Some(s) = &o.sliding {
        let poses = pose_controls(
            s,
            &sim.body.surface,
            sim.system.surface().num_control_vertices(),
            resolver,
        )?;
        out.push(Box::new(
            Sliding::new(s.weight, s.friction_coefficient, poses)
                .map_err(|e| term_error("objectives.sliding", e))?,
        ));
    }
    if let Some(s) = &o.shape {
        let target = match &s.target {
            TargetSpec::Mesh { path } => {
                let key = "objectives.shape.target.path";
                let file = resolver.resolve(key, path)?;
                skintight_geometry::mesh::io::read_mesh(&file)
                    .map_err(|e| SimulateError::input(key, e.to_string()))?
            }
            TargetSpec::Revolution { profile, segments } => revolution_target(profile, *segments),
        };
        out.push(Box::new(
            ShapeImls::from_mesh(s.weight, &target, s.radius)
                .map_err(|e| term_error("objectives.shape", e))?,
        ));
    }
    if let Some(s) = &o.stretch {
        out.push(Box::new(
            StretchWindow::new(s.weight, s.min, s.max)
                .map_err(|e| term_error("objectives.stretch", e))?,
        ));
    }
    if let Some(s) = &o.seam_traction {
        let form = match s.form {
            SeamTractionFormSpec::Squared => SeamTractionForm::Squared,
            SeamTractionFormSpec::Linear => SeamTractionForm::Linear,
        };
        out.push(Box::new(
            SeamTraction::new(s.weight, form)
                .map_err(|e| term_error("objectives.seam_traction", e))?,
        ));
    }
    if let Some(p) = &o.pressure {
        let target = p.target().ok_or_else(|| {
            SimulateError::input(
                "objectives.pressure",
                "give target_pa (Pa), or min_pa and max_pa (Pa)",
            )
        })?;
        out.push(Box::new(
            Pressure::new(p.weight, target, p.negative_weight)
                .map_err(|e| term_error("objectives.pressure", e))?
                .with_boundary_ring(p.include_boundary_ring),
        ));
    }
    if let Some(p) = &o.prescription {
        for side in super::prescription_bands::prescription_sides(p, sim)? {
            out.push(Box::new(super::prescription_bands::prescription_term(
                p,
                sim,
                job.prescription_limb(),
                side,
            )?));
        }
    }
    // The openings of an order's template grip (`src/simulate/grip.rs`): each aimed 1 mmHg above the
    // least pressure the template asks for, which leaves room for the difference between the design's
    // Young–Laplace estimate and the verdict's normal force (a few tenths of a mmHg over a band).
    if let (Some(p), Some(t), Ok(m)) = (&o.prescription, &sim.template, &sim.measurements)
        && let Ok(template) = crate::scene::template::find_template(&t.name)
    {
        let limit =
            sim.scene.garment.fabric.limits.max_pressure_pa / skintight_physics::PA_PER_MMHG;
        for g in &template.grip {
            let aimed = crate::scene::template::GripBand {
                min_pressure_mmhg: g.min_pressure_mmhg + 1.0,
                ..g.clone()
            };
            for side in crate::simulate::grip::grip_sides(&template, t.side, g) {
                if let Some(term) =
                    crate::simulate::grip::grip_term(&aimed, side, m, p.weight, limit)
                {
                    out.push(Box::new(term.map_err(|e| {
                        SimulateError::input(format!("garment.template.name ({}: grip)", t.name), e)
                    })?));
                }
            }
        }
    }
    // The fabric's stretch limits, on by default: a penalty along the wales and courses of each piece.
    let c = &job.optimizer.fabric_limits;
    if c.weight > 0.0 {
        let limits = sim.scene.garment.fabric.stretch_limits();
        let bound = |limit: f64| (limit * (1.0 - c.margin)).max(1.0);
        out.push(Box::new(
            FabricStretchLimit::new(
                c.weight,
                [bound(limits.wale), bound(limits.course)],
                wale_directions(sim),
            )
            .map_err(|e| term_error("optimizer.fabric_limits", e))?,
        ));
    }
    let r = &job.regularizers;
    if let Some(w) = r.seam_length {
        out.push(Box::new(
            SeamLength::new(w.weight).map_err(|e| term_error("regularizers.seam_length", e))?,
        ));
    }
    if let Some(w) = r.smoothness {
        out.push(Box::new(
            BoundarySmoothness::new(w.weight)
                .map_err(|e| term_error("regularizers.smoothness", e))?,
        ));
    }
    if let Some(w) = r.edge_length {
        out.push(Box::new(
            EdgeLengthUniformity::new(w.weight)
                .map_err(|e| term_error("regularizers.edge_length", e))?,
        ));
    }
    if let Some(c) = r.compactness {
        out.push(Box::new(
            Compactness::new(c.weight, c.threshold)
                .map_err(|e| term_error("regularizers.compactness", e))?,
        ));
    }
    if let Some(w) = r.pinned_traction {
        out.push(Box::new(
            PinnedTraction::new(w.weight)
                .map_err(|e| term_error("regularizers.pinned_traction", e))?,
        ));
    }
    Ok(out)
}

/// The design parameters of the job's optimizer settings.
pub fn design_params(job: &DesignJob) -> PatternDesignParams {
    let o = &job.optimizer;
    PatternDesignParams {
        method: match o.method {
            OptimizerMethod::Lbfgs => Optimizer::Lbfgs,
            OptimizerMethod::GaussNewton => Optimizer::GaussNewton,
        },
        gauss_newton_solver: match o.gauss_newton_system.unwrap_or_default() {
            GaussNewtonSystemSpec::Auto => GaussNewtonSolver::Auto,
            GaussNewtonSystemSpec::Kkt => GaussNewtonSolver::Kkt,
            GaussNewtonSystemSpec::Reduced => GaussNewtonSolver::Reduced,
        },
        gauss_newton: GaussNewtonParams {
            initial_damping: o
                .damping
                .unwrap_or(GaussNewtonParams::default().initial_damping),
            gradient_tolerance: o.gradient_tolerance,
            max_iterations: o.max_iterations,
            time_limit_seconds: Some(o.time_limit_s),
            max_step_growth: if o.step_growth == 0.0 {
                Real::INFINITY
            } else {
                o.step_growth
            },
            ..GaussNewtonParams::default()
        },
        lbfgs: LbfgsParams {
            memory: o.memory,
            gradient_tolerance: o.gradient_tolerance,
            max_iterations: o.max_iterations,
            time_limit_seconds: Some(o.time_limit_s),
            ..LbfgsParams::default()
        },
        mode_levels: o.mode_levels.clone(),
        level_max_iterations: o.level_iterations,
        level_min_relative_decrease: o.level_min_decrease,
        remesh: (o.remesh.max_remeshes > 0).then(|| o.remesh.params()),
        inexact: o
            .inexact_solves
            .then_some(skintight_design::InexactTolerance {
                loosest: o.inexact_loosest,
                objective_error: o.inexact_objective_error,
            }),
        hold_seams: o.hold_seams,
    }
}
