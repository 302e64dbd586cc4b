//! The homogenization of yarn-level sequences end to end (the knitwear paper, Sec. 4–6): from the frames of
//! one or more sequences of one knit patch to a tetrahedral mesh with its per-element material `γ`
//! (`#T × 2`, Pa) and the error of that mesh on every frame, training and held out.
//!
//! **Poses.** The mesh is built around the first sequence's frame 0 (Sec. 4, [`crate::volumetric_mesh`]).
//! Every frame `i ≥ 2` of every sequence is a pose: its target is Y2V of the yarn frame (Eq. 5–6,
//! [`crate::shape_fit`], directors carried from frame to frame), its load is gravity on the lumped node
//! masses less the inertia force of the fitted shapes of frames `i, i − 1, i − 2` (Eq. 12–14,
//! [`crate::inertia_force`]: `f = Mⱽ g − Mⱽ aᵢ`, N), and its boundary the nodes of every tetrahedron that
//! embeds a vertex the scene held (clamped or moved by a grip), held at their fitted positions. Frames 0
//! and 1 have no inertia estimate and are no poses. Of the poses in order, every `train_every`-th
//! (the first included) is fitted; the others are held out and only evaluated.
//!
//! **Fit (Sec. 6.4–6.5).** Sample by sample: each training pose `k` is fitted alone by the adjoint
//! Gauss-Newton of [`crate::elasticity_fit`] (the shared optimizer), through the harmonic spaces of the
//! mesh (Eq. 23–24) of growing rank `r₁ < r₂ < …` ([`HomogenizationParams::ranks`], the paper's 1, 10,
//! 30), each stage started from the previous one's field projected onto the next basis, optionally
//! finished per element. The pose's `γ_k` is averaged into the running `γ` by Eq. 22,
//! `γ ← (w γ + w_k γ_k)/(w + w_k)`, with `w_k` the elastic energy (J) of the pose's equilibrium at `γ_k`
//! and `w` the largest such energy met so far (zero at the start). The first pose runs the whole
//! schedule from [`HomogenizationParams::start_gamma_pa`]; the later ones start from the running `γ` in
//! the last stage's space. Each stage's variables are `γ` per component divided by its volume-weighted
//! mean at the stage's start, so they are of order one.
//!
//! **Error.** Each pose is solved to equilibrium with the final `γ` from its fitted shape; V2Y of the
//! equilibrium (Eq. 4) against the frame's yarn vertices gives the mean and largest distance (m). The
//! shape error — V2Y of the fitted shape itself — is the floor no material can beat.
//!
//! The results and their figures are in docs/BENCHMARKS.md ("Homogenization end to end").

use std::ops::ControlFlow;
use std::path::Path;
use std::time::Instant;

use faer::sparse::SparseColMat;
use serde::Serialize;
use skintight_knit::frame_sequence::{Sequence, SequenceMeta};
use skintight_optimize::{
    AdjointGaussNewton, GaussNewtonParams, GaussNewtonSolver, OptimizerStop, gauss_newton,
    parameter_map_matrix,
};
use skintight_physics::newton::minimize;

use crate::elasticity_fit::{ElasticityFit, ElasticityFitParams, FitPose};
use crate::harmonic_basis::{HarmonicBasisParams, harmonic_basis};
use crate::inertia_force::inertia_force;
use crate::knit_material::{KnitMaterial, QuasiStaticProblem};
use crate::material_frame::DirectorTransport;
use crate::shape_fit::{ShapeFit, ShapeFitParams};
use crate::volumetric_mesh::{
    RestYarns, VolumetricMesh, VolumetricMeshParams, VolumetricMeshReport,
};

/// One sequence in memory: its metadata and every frame (`#Y` rows: x, y, z in m, θ in rad).
#[derive(Clone, Debug)]
pub struct LoadedSequence {
    /// A name for messages and reports (e.g. the directory).
    pub name: String,
    /// `sequence.json`.
    pub meta: SequenceMeta,
    /// The frames in time order.
    pub frames: Vec<Vec<[f64; 4]>>,
}

impl LoadedSequence {
    /// Reads the sequence in `dir` (`sequence.json` and its frames).
    pub fn read(dir: &Path) -> Result<Self, HomogenizationError> {
        let name = dir.display().to_string();
        let bad = |reason: String| HomogenizationError::Sequence {
            sequence: name.clone(),
            reason,
        };
        let reader = Sequence::open(dir).map_err(|e| bad(e.to_string()))?;
        let meta = reader.meta.clone();
        let frames = (0..meta.frames.len())
            .map(|i| reader.frame(dir, i).map_err(|e| bad(e.to_string())))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self { name, meta, frames })
    }
}

/// Settings of [`homogenize`].
#[derive(Clone, Debug)]
pub struct HomogenizationParams {
    /// The mesh (voxel size, dilation, the voxel budget).
    pub mesh: VolumetricMeshParams,
    /// Y2V (α of Eq. 6).
    pub shape: ShapeFitParams,
    /// The equilibrium solves of the fit.
    pub fit: ElasticityFitParams,
    /// Each stage's Gauss-Newton run (the variables are `γ` over its mean at the stage's start).
    pub gauss_newton: GaussNewtonParams,
    /// The harmonic ranks of the schedule, increasing, each ≥ 1 (clipped to `#T`). Default `[1, 10, 30]`.
    pub ranks: Vec<usize>,
    /// Whether a last stage fits every element's own `γ` (`2#T` variables). Default `false`.
    pub per_element: bool,
    /// Fit every `train_every`-th pose (≥ 1); hold out the others. Default 1.
    pub train_every: usize,
    /// `[γˢ, γᵛ]` (Pa, > 0) the schedule starts from, uniform. Default `[1000, 1000]`.
    pub start_gamma_pa: [f64; 2],
    /// The harmonic bases.
    pub harmonic: HarmonicBasisParams,
}

impl Default for HomogenizationParams {
    fn default() -> Self {
        Self {
            mesh: VolumetricMeshParams::default(),
            shape: ShapeFitParams::default(),
            fit: ElasticityFitParams::default(),
            gauss_newton: GaussNewtonParams {
                gradient_tolerance: 1e-14,
                max_iterations: 30,
                ..GaussNewtonParams::default()
            },
            ranks: vec![1, 10, 30],
            per_element: false,
            train_every: 1,
            start_gamma_pa: [1000.0, 1000.0],
            harmonic: HarmonicBasisParams::default(),
        }
    }
}

/// Why a homogenization failed; each message names the input and how to fix it.
#[derive(Debug, thiserror::Error)]
pub enum HomogenizationError {
    /// A sequence cannot be used.
    #[error("sequence {sequence}: {reason}")]
    Sequence {
        /// The sequence's name.
        sequence: String,
        /// What is wrong.
        reason: String,
    },
    /// A setting is out of range.
    #[error("homogenization setting {name}: {reason}")]
    Param {
        /// The setting.
        name: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// A stage of the method failed (the mesh, Y2V, a fit, an equilibrium); the message says which.
    #[error("homogenization: {0}")]
    Method(String),
}

fn method(what: &str, e: impl std::fmt::Display) -> HomogenizationError {
    HomogenizationError::Method(format!("{what}: {e}"))
}

/// One stage of the fit: a pose fitted in one space.
#[derive(Clone, Debug, Serialize)]
pub struct FitStage {
    /// The pose's sequence (index into the inputs).
    pub sequence: usize,
    /// The pose's frame.
    pub frame: usize,
    /// The space: a harmonic rank, or `#T` for the per-element stage.
    pub rank: usize,
    /// Whether this is the per-element stage.
    pub per_element: bool,
    /// Gauss-Newton iterations.
    pub iterations: usize,
    /// The loss (Eq. 9, m³) at the stage's start and end.
    pub loss_start_m3: f64,
    /// See [`Self::loss_start_m3`].
    pub loss_end_m3: f64,
    /// Why the stage stopped.
    pub stop: OptimizerStop,
    /// Wall-clock seconds of the stage.
    pub seconds: f64,
}

/// The mesh's error on one pose with the final material.
#[derive(Clone, Debug, Serialize)]
pub struct FrameFit {
    /// The sequence (index into the inputs).
    pub sequence: usize,
    /// The frame.
    pub frame: usize,
    /// Simulated time of the frame (s).
    pub time_s: f64,
    /// Whether the pose was fitted (else held out).
    pub training: bool,
    /// Mean distance between the yarn vertices and V2Y of the mesh's equilibrium (m).
    pub mean_error_m: f64,
    /// Largest such distance (m).
    pub max_error_m: f64,
    /// Mean distance of V2Y of the fitted shape itself (m): the floor no material can beat.
    pub shape_error_m: f64,
    /// Newton iterations of the equilibrium.
    pub newton_iterations: usize,
    /// Whether the equilibrium converged.
    pub converged: bool,
}

/// Progress of [`homogenize`], one per Gauss-Newton iteration.
#[derive(Clone, Debug, Serialize)]
pub struct HomogenizationProgress {
    /// Training pose (0-based, in fit order) and how many there are.
    pub pose: usize,
    /// Training poses in all.
    pub poses: usize,
    /// The stage's rank (see [`FitStage::rank`]).
    pub rank: usize,
    /// The iteration within the stage.
    pub iteration: usize,
    /// The stage's loss (m³).
    pub loss_m3: f64,
    /// Seconds since the homogenization started.
    pub seconds: f64,
}

/// The homogenized knit.
#[derive(Clone, Debug)]
pub struct Homogenization {
    /// The mesh (rest positions, tetrahedra, masses, the yarn embedding).
    pub mesh: VolumetricMesh,
    /// Its construction report (DOFs, elements, ratio, patch size).
    pub report: VolumetricMeshReport,
    /// `[γˢ, γᵛ]` per element (Pa).
    pub gamma: Vec<[f64; 2]>,
    /// The fit's stages in order.
    pub stages: Vec<FitStage>,
    /// Every pose's error, in sequence and frame order.
    pub frames: Vec<FrameFit>,
    /// Seconds of the fit (stages only).
    pub fit_seconds: f64,
    /// Seconds in all (mesh, Y2V, fit, evaluation).
    pub seconds: f64,
}

impl Homogenization {
    /// Gauss-Newton iterations over all stages.
    pub fn gauss_newton_iterations(&self) -> usize {
        self.stages.iter().map(|s| s.iterations).sum()
    }

    /// Mean of the poses' mean errors (m) over the training (`true`) or held-out poses; `None` if there are
    /// none.
    pub fn mean_error(&self, training: bool) -> Option<f64> {
        let e: Vec<f64> = self
            .frames
            .iter()
            .filter(|f| f.training == training)
            .map(|f| f.mean_error_m)
            .collect();
        (!e.is_empty()).then(|| e.iter().sum::<f64>() / e.len() as f64)
    }
}

/// A pose with where it came from.
struct Pose {
    sequence: usize,
    frame: usize,
    time_s: f64,
    training: bool,
    fit: FitPose,
    /// The frame's yarn positions (`#Y × 3`, m).
    yarn: Vec<[f64; 3]>,
}

/// Checks the inputs: one patch (the same pattern, yarns and vertex count) in every sequence, loads
/// recorded, no collider, a held vertex, at least three frames, finite frames.
fn check_inputs(
    sequences: &[LoadedSequence],
    params: &HomogenizationParams,
) -> Result<(), HomogenizationError> {
    if params.train_every == 0 {
        return Err(HomogenizationError::Param {
            name: "train_every",
            reason: "must be ≥ 1 (1 fits every pose)".into(),
        });
    }
    if params.ranks.windows(2).any(|w| w[0] >= w[1]) || params.ranks.first() == Some(&0) {
        return Err(HomogenizationError::Param {
            name: "ranks",
            reason: format!(
                "{:?} must increase, each ≥ 1 (e.g. [1, 10, 30])",
                params.ranks
            ),
        });
    }
    if params.ranks.is_empty() && !params.per_element {
        return Err(HomogenizationError::Param {
            name: "ranks",
            reason: "is empty and the per-element stage is off: nothing would be fitted".into(),
        });
    }
    if !params
        .start_gamma_pa
        .iter()
        .all(|g| g.is_finite() && *g > 0.0)
    {
        return Err(HomogenizationError::Param {
            name: "start_gamma_pa",
            reason: format!(
                "{:?} must be positive and finite (Pa)",
                params.start_gamma_pa
            ),
        });
    }
    let first = sequences.first().ok_or(HomogenizationError::Param {
        name: "sequences",
        reason: "none given: name at least one sequence directory".into(),
    })?;
    for s in sequences {
        let bad = |reason: String| HomogenizationError::Sequence {
            sequence: s.name.clone(),
            reason,
        };
        let m = &s.meta;
        if (m.pattern.as_str(), m.vertex_count, &m.yarns)
            != (
                first.meta.pattern.as_str(),
                first.meta.vertex_count,
                &first.meta.yarns,
            )
        {
            return Err(bad(format!(
                "is not the patch of {} (pattern {:?} with {} vertices against {:?} with {}): homogenize one patch's sequences together",
                first.name, m.pattern, m.vertex_count, first.meta.pattern, first.meta.vertex_count
            )));
        }
        if s.frames.len() < 3 {
            return Err(bad(format!(
                "has {} frames; a pose needs the two frames before it (at least 3)",
                s.frames.len()
            )));
        }
        let loads = m.loads.as_ref().ok_or_else(|| {
            bad("records no loads (gravity, held vertices): it was written before they were; run `skintight knit simulate-yarn` again".into())
        })?;
        if loads.collider {
            return Err(bad(format!(
                "scenario {:?} pushes the yarns with a collider whose forces the frames do not record; homogenize hang, stretch or shear sequences",
                m.scenario
            )));
        }
        if loads.held_vertices.is_empty() {
            return Err(bad(
                "holds no vertex: a quasi-static pose needs a support (use a hang, stretch or shear scenario)".into(),
            ));
        }
        if let Some(&v) = loads.held_vertices.iter().find(|&&v| v >= m.vertex_count) {
            return Err(bad(format!(
                "held vertex {v} is beyond its {} vertices",
                m.vertex_count
            )));
        }
        if !(m.frame_interval_s.is_finite() && m.frame_interval_s > 0.0) {
            return Err(bad(format!(
                "frame_interval_s = {} must be positive",
                m.frame_interval_s
            )));
        }
        for (i, f) in s.frames.iter().enumerate() {
            if f.len() != m.vertex_count {
                return Err(bad(format!(
                    "frame {i} has {} vertices; the sequence has {}",
                    f.len(),
                    m.vertex_count
                )));
            }
            if let Some(v) = f.iter().position(|r| r.iter().any(|x| !x.is_finite())) {
                return Err(bad(format!("frame {i}: vertex {v} is not finite")));
            }
        }
    }
    Ok(())
}

fn flatten(x: &[[f64; 3]]) -> Vec<f64> {
    x.iter().flatten().copied().collect()
}

fn positions(frame: &[[f64; 4]]) -> Vec<[f64; 3]> {
    frame.iter().map(|r| [r[0], r[1], r[2]]).collect()
}

/// The poses of every sequence (module documentation): targets, loads and held nodes.
fn poses(
    sequences: &[LoadedSequence],
    mesh: &VolumetricMesh,
    shape: &ShapeFit,
    train_every: usize,
) -> Result<Vec<Pose>, HomogenizationError> {
    let n = mesh.rest.len();
    let mut out = Vec::new();
    for (si, s) in sequences.iter().enumerate() {
        let loads = s.meta.loads.as_ref().expect("checked by check_inputs");
        let mut held = vec![false; 3 * n];
        for &v in &loads.held_vertices {
            for &node in &mesh.tets[mesh.embedding[v].tet] {
                held[3 * node..3 * node + 3].fill(true);
            }
        }
        let gravity: Vec<f64> = mesh
            .node_mass
            .iter()
            .flat_map(|m| loads.gravity_m_per_s2.map(|g| m * g))
            .collect();
        let mut transport = DirectorTransport::new(&s.meta.yarns, &s.frames[0])
            .map_err(|e| method(&format!("sequence {}: the directors", s.name), e))?;
        let mut shapes: Vec<Vec<[f64; 3]>> = Vec::with_capacity(s.frames.len());
        for (i, frame) in s.frames.iter().enumerate() {
            let context = |what: &str| format!("sequence {}, frame {i}: {what}", s.name);
            let pose = transport
                .pose(frame)
                .map_err(|e| method(&context("the material frames"), e))?;
            let target = shape
                .target(&pose)
                .map_err(|e| method(&context("the shape target"), e))?;
            let fitted = shape
                .solve(&target)
                .map_err(|e| method(&context("Y2V"), e))?;
            shapes.push(fitted);
            if i < 2 {
                continue;
            }
            let inertia = inertia_force(
                &mesh.node_mass,
                &shapes[i],
                &shapes[i - 1],
                &shapes[i - 2],
                s.meta.frame_interval_s,
            )
            .map_err(|e| method(&context("the inertia force"), e))?;
            let force = gravity.iter().zip(&inertia).map(|(g, a)| g - a).collect();
            out.push(Pose {
                sequence: si,
                frame: i,
                time_s: s.meta.frames.get(i).map_or(f64::NAN, |f| f.time_s),
                training: out.len() % train_every == 0,
                fit: FitPose {
                    force,
                    fixed: held.clone(),
                    start: flatten(&shapes[i]),
                    target,
                },
                yarn: positions(frame),
            });
        }
    }
    Ok(out)
}

/// The variables' map of one stage: `γ = diag(s) A c` with `A` the rank-`r` harmonic basis per component,
/// or the identity (`per_element`), `s` the start values (Pa).
enum Space {
    Harmonic(crate::harmonic_basis::HarmonicBasis),
    PerElement,
}

impl Space {
    fn rank(&self, tets: usize) -> usize {
        match self {
            Self::Harmonic(h) => h.rank(),
            Self::PerElement => tets,
        }
    }

    fn map(
        &self,
        tets: usize,
        scale: [f64; 2],
    ) -> Result<SparseColMat<usize, f64>, HomogenizationError> {
        let r = self.rank(tets);
        parameter_map_matrix(2 * tets, 2 * r, |c| {
            let (component, k) = (c / r, c % r);
            let mut col = vec![0.0; 2 * tets];
            for e in 0..tets {
                col[2 * e + component] = scale[component]
                    * match self {
                        Self::Harmonic(h) => h.column(k)[e],
                        Self::PerElement => f64::from(u8::from(e == k)),
                    };
            }
            Ok(col)
        })
        .map_err(|e| method("the parameter map", e))
    }

    /// The variables of the field `gamma` in this space (least squares in the volume product).
    fn project(&self, gamma: &[[f64; 2]], volumes: &[f64], scale: [f64; 2]) -> Vec<f64> {
        (0..2)
            .flat_map(|c| {
                let field: Vec<f64> = gamma.iter().map(|g| g[c] / scale[c]).collect();
                match self {
                    Self::Harmonic(h) => h.project(&field, volumes),
                    Self::PerElement => field,
                }
            })
            .collect()
    }
}

/// What one stage of the fit ends with.
struct StageOutcome {
    /// The fitted field (`#T × 2`, Pa).
    gamma: Vec<[f64; 2]>,
    loss_m3: f64,
    iterations: usize,
    stop: OptimizerStop,
    /// The (first) pose's equilibrium at `gamma` (`3#V`, m).
    state: Vec<f64>,
}

/// The fit of `poses` in `space` from the field `gamma`, reporting each iteration's loss to `progress`.
fn stage(
    (mesh, shape, volumes): (&VolumetricMesh, &ShapeFit, &[f64]),
    poses: Vec<FitPose>,
    space: &Space,
    gamma: &[[f64; 2]],
    params: &HomogenizationParams,
    progress: &mut dyn FnMut(usize, f64) -> ControlFlow<()>,
) -> Result<StageOutcome, HomogenizationError> {
    let tets = mesh.tets.len();
    // Variables of order one: each component over its volume-weighted mean at the stage's start (a
    // component far smaller than the other would otherwise leave `γ ≥ 0` at the first trial step).
    let total: f64 = volumes.iter().sum();
    let scale: [f64; 2] = std::array::from_fn(|c| {
        let mean = gamma
            .iter()
            .zip(volumes)
            .map(|(g, v)| g[c] * v)
            .sum::<f64>()
            / total;
        if mean > 0.0 {
            mean
        } else {
            params.start_gamma_pa[c]
        }
    });
    let map = space.map(tets, scale)?;
    let mut c0 = space.project(gamma, volumes, scale);
    if let Space::PerElement = space {
        c0.iter_mut().for_each(|c| *c = c.max(0.0));
    }
    let mut fit = ElasticityFit::new(mesh, shape, poses, map.clone(), params.fit)
        .map_err(|e| method("the fit", e))?;
    let mut problem = AdjointGaussNewton::new(&mut fit, map, GaussNewtonSolver::Auto);
    let out = gauss_newton(&mut problem, &c0, &params.gauss_newton, |_, it| {
        progress(it.iteration, it.value)
    })
    .map_err(|e| method("the Gauss-Newton run", e))?;
    let flat = fit.gamma(&out.x);
    Ok(StageOutcome {
        gamma: flat.chunks_exact(2).map(|g| [g[0], g[1]]).collect(),
        loss_m3: out.value,
        iterations: out.iterations,
        stop: out.stop_reason,
        state: fit.states().first().cloned().unwrap_or_default(),
    })
}

/// Homogenizes the sequences `sequences` (module documentation), calling `progress` at every Gauss-Newton
/// iteration (`ControlFlow::Break` stops the fit where it is and evaluates what it has).
pub fn homogenize(
    sequences: &[LoadedSequence],
    params: &HomogenizationParams,
    mut progress: impl FnMut(&HomogenizationProgress) -> ControlFlow<()>,
) -> Result<Homogenization, HomogenizationError> {
    let clock = Instant::now();
    check_inputs(sequences, params)?;
    let first = &sequences[0];
    let yarns = RestYarns::from_frame(&first.meta, &first.frames[0]);
    let (lo, hi) = yarns.bounding_box();
    let size = (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f64>().sqrt();
    let voxel = params.mesh.voxel_for(yarns.radius_m);
    if !(voxel > 0.0 && voxel < size) {
        return Err(HomogenizationError::Param {
            name: "voxel_m",
            reason: format!(
                "{voxel} m must be a length > 0 smaller than the patch ({size:.4} m across): choose a voxel near the yarn diameter ({} m)",
                2.0 * yarns.radius_m
            ),
        });
    }
    let mesh = VolumetricMesh::build(&yarns, &params.mesh).map_err(|e| method("the mesh", e))?;
    let report = mesh.report(&yarns, &params.mesh);
    let shape = ShapeFit::new(&mesh, &first.meta.yarns, &first.frames[0], params.shape)
        .map_err(|e| method("Y2V", e))?;
    let poses = poses(sequences, &mesh, &shape, params.train_every)?;
    let tets = mesh.tets.len();
    let volumes: Vec<f64> = (0..tets).map(|t| mesh.rest_volume(t)).collect();
    let mut spaces = Vec::new();
    for &r in &params.ranks {
        let r = r.min(tets);
        if spaces.last().is_some_and(|s: &Space| s.rank(tets) >= r) {
            continue;
        }
        let h = harmonic_basis(&mesh.rest, &mesh.tets, r, &params.harmonic)
            .map_err(|e| method(&format!("the harmonic basis of rank {r}"), e))?;
        spaces.push(Space::Harmonic(h));
    }
    if params.per_element {
        spaces.push(Space::PerElement);
    }

    let fit_clock = Instant::now();
    let training: Vec<&Pose> = poses.iter().filter(|p| p.training).collect();
    let mut gamma = vec![params.start_gamma_pa; tets];
    let mut weight = 0.0_f64;
    let mut stages = Vec::new();
    let mut stopped = false;
    let volume_preserving = params.fit.volume_preserving;
    for (k, pose) in training.iter().enumerate() {
        if stopped {
            break;
        }
        let schedule: &[Space] = if k == 0 {
            &spaces
        } else {
            &spaces[spaces.len() - 1..]
        };
        let mut gamma_k = gamma.clone();
        let mut state = pose.fit.start.clone();
        for space in schedule {
            let rank = space.rank(tets);
            let stage_clock = Instant::now();
            let mut first_loss = f64::NAN;
            let mut report = |iteration: usize, loss: f64| {
                if iteration == 0 && first_loss.is_nan() {
                    first_loss = loss;
                }
                let flow = progress(&HomogenizationProgress {
                    pose: k,
                    poses: training.len(),
                    rank,
                    iteration,
                    loss_m3: loss,
                    seconds: clock.elapsed().as_secs_f64(),
                });
                if flow.is_break() {
                    stopped = true;
                }
                flow
            };
            let outcome = stage(
                (&mesh, &shape, &volumes),
                vec![pose.fit.clone()],
                space,
                &gamma_k,
                params,
                &mut report,
            )?;
            gamma_k = outcome.gamma;
            state = outcome.state;
            stages.push(FitStage {
                sequence: pose.sequence,
                frame: pose.frame,
                rank,
                per_element: matches!(space, Space::PerElement),
                iterations: outcome.iterations,
                loss_start_m3: first_loss,
                loss_end_m3: outcome.loss_m3,
                stop: outcome.stop,
                seconds: stage_clock.elapsed().as_secs_f64(),
            });
            if stopped {
                break;
            }
        }
        // Eq. 22: the pose's weight is the elastic energy of its equilibrium at its own γ.
        let material = KnitMaterial::new(&mesh, gamma_k.clone(), volume_preserving)
            .map_err(|e| method("the fitted material", e))?;
        let w_k = material
            .energy(&state)
            .map_err(|e| method("the pose's elastic energy", e))?
            .max(f64::MIN_POSITIVE);
        for (g, gk) in gamma.iter_mut().zip(&gamma_k) {
            for c in 0..2 {
                g[c] = (weight * g[c] + w_k * gk[c]) / (weight + w_k);
            }
        }
        weight = weight.max(w_k);
    }
    let fit_seconds = fit_clock.elapsed().as_secs_f64();

    let material = KnitMaterial::new(&mesh, gamma.clone(), volume_preserving)
        .map_err(|e| method("the fitted material", e))?;
    let frames = poses
        .iter()
        .map(|p| evaluate(&mesh, &material, p, params))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Homogenization {
        mesh,
        report,
        gamma,
        stages,
        frames,
        fit_seconds,
        seconds: clock.elapsed().as_secs_f64(),
    })
}

/// Mean and largest distance (m) between V2Y of the node positions `x` (`3#V`) and the yarn positions.
fn yarn_distance(
    mesh: &VolumetricMesh,
    x: &[f64],
    yarn: &[[f64; 3]],
) -> Result<(f64, f64), HomogenizationError> {
    let nodes: Vec<[f64; 3]> = x.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect();
    let y = mesh.v2y(&nodes).map_err(|e| method("V2Y", e))?;
    let d: Vec<f64> = y
        .iter()
        .zip(yarn)
        .map(|(a, b)| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt())
        .collect();
    let mean = d.iter().sum::<f64>() / d.len().max(1) as f64;
    Ok((mean, d.iter().copied().fold(0.0, f64::max)))
}

/// The error of `material` on the pose `p` (module documentation, "Error").
fn evaluate(
    mesh: &VolumetricMesh,
    material: &KnitMaterial,
    p: &Pose,
    params: &HomogenizationParams,
) -> Result<FrameFit, HomogenizationError> {
    let context = format!(
        "the equilibrium of sequence {} frame {}",
        p.sequence, p.frame
    );
    let mut problem = QuasiStaticProblem::new(
        material,
        p.fit.force.clone(),
        p.fit.fixed.clone(),
        &params.fit.quasi_static,
    )
    .map_err(|e| method(&context, e))?;
    let mut x = p.fit.start.clone();
    let report =
        minimize(&mut problem, &mut x, &params.fit.newton).map_err(|e| method(&context, e))?;
    let (mean, max) = yarn_distance(mesh, &x, &p.yarn)?;
    let (shape_mean, _) = yarn_distance(mesh, &p.fit.start, &p.yarn)?;
    Ok(FrameFit {
        sequence: p.sequence,
        frame: p.frame,
        time_s: p.time_s,
        training: p.training,
        mean_error_m: mean,
        max_error_m: max,
        shape_error_m: shape_mean,
        newton_iterations: report.iterations,
        converged: report.converged,
    })
}
