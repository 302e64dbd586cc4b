//! What a yarn run writes into its output folder: the frame sequence (`sequence.json`,
//! `vertex_sources.npy`, `frames/*.npy`; the format is `skintight_knit::frame_sequence`, which the
//! homogenization reads), `yarns.obj` and `yarns.glb` of the last frame, and `result.json`
//! ([`YarnSimulationResult`]: the run's counters, extremes and timings). Formats in docs/OUTPUTS.md.
//!
//! Units: SI (m, s, kg, J); wall-clock times in s.

use std::path::Path;

use serde::{Deserialize, Serialize};
use skintight_knit::edge_finish::EdgeFinish;
use skintight_knit::frame_sequence::{
    FORMAT, SequenceLoads, SequenceMeta, Units, VERSION, YarnRange,
};
use skintight_knit::newton::NewtonTimings;
use skintight_knit::patch::PatchModel;
use skintight_knit::tubes::tubes;

use super::error::YarnSceneError;
use super::spec::YarnScene;

/// The outcome of a run (`result.json`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct YarnSimulationResult {
    /// The scenario's name.
    pub scenario: String,
    /// The `.pyp` read.
    pub pattern: String,
    /// Cells `[nx, ny]`.
    pub cells: [usize; 2],
    /// Yarns (with at least one edge).
    pub yarns: usize,
    /// Yarn vertices.
    pub vertices: usize,
    /// Unknowns (4 per vertex).
    pub dofs: usize,
    /// Held vertices (clamped or moving).
    pub prescribed_vertices: usize,
    /// The border's finish (`bonded` or `cut`).
    pub edges: EdgeFinish,
    /// Bonds of a fused edge (cut yarn ends tied to the fabric; 0 for `cut`).
    pub bonds: usize,
    /// Yarn radius (m).
    pub yarn_radius_m: f64,
    /// Total yarn mass (kg).
    pub mass_kg: f64,
    /// Frames written (including frame 0).
    pub frames: usize,
    /// Time steps taken.
    pub steps: usize,
    /// Time step (s).
    pub dt_s: f64,
    /// Simulated time reached (s).
    pub simulated_time_s: f64,
    /// Newton iterations of the relaxation of the start state.
    pub relax_newton_iterations: usize,
    /// Whether that relaxation reached the tolerance.
    pub relax_converged: bool,
    /// Wall-clock time of the start state: the periodic rest solve and the relaxation (s).
    pub relax_seconds: f64,
    /// Newton iterations over all steps.
    pub newton_iterations: usize,
    /// Most Newton iterations in one step.
    pub newton_iterations_max_step: usize,
    /// Cholesky factorizations over all steps.
    pub factorizations: usize,
    /// Steps with a substep whose Newton solve stopped before the tolerance at the finest substep allowed.
    pub unconverged_steps: usize,
    /// Substeps kept over all steps (equal to `steps` when no step was halved).
    pub substeps: usize,
    /// Substep attempts abandoned unconverged and halved.
    pub rejected_substeps: usize,
    /// Largest final residual of a step (dimensionless, force over `k_s`).
    pub max_residual: f64,
    /// Smallest centreline distance between non-excluded yarn segments over all steps (m; `null` in JSON
    /// when no pair came within the contact distance).
    #[serde(with = "infinite_as_null")]
    pub min_distance_m: f64,
    /// The same over the yarn diameter (≥ 0.5 means the yarn surfaces overlap by less than a radius; a
    /// yarn passing through another would reach 0).
    #[serde(with = "infinite_as_null")]
    pub min_distance_over_diameter: f64,
    /// Most segment pairs in contact in one step.
    pub max_contacts: usize,
    /// Most candidate pairs in one step.
    pub max_candidates: usize,
    /// Most vertices on the sphere in one step.
    pub max_sphere_contacts: usize,
    /// Kinetic energy at the end (J).
    pub kinetic_energy_j: f64,
    /// Displacement of the centre of mass from start to end (m).
    pub centre_of_mass_displacement_m: [f64; 3],
    /// Wall-clock time of the run (s).
    pub seconds: f64,
    /// Wall-clock time per step, without the start state (s).
    pub seconds_per_step: f64,
    /// Wall-clock time per Newton iteration of the steps, without the start state (s).
    pub seconds_per_newton_iteration: f64,
    /// Whether the run was stopped early by the caller.
    pub stopped: bool,
    /// Where the Newton solves of the steps spent their time (s), summed over the steps.
    #[serde(default)]
    pub newton_timings: NewtonTimings,
}

impl YarnSimulationResult {
    /// The result at frame 0 (the relaxed start state `x`, nothing stepped yet): the patch's figures and
    /// the relaxation's; the step counters at zero.
    pub fn at_start(
        scene: &YarnScene,
        pattern_path: &Path,
        model: &PatchModel,
        x: &[f64],
        prescribed_vertices: usize,
        relaxation: (usize, bool, f64),
    ) -> Self {
        let (relax_newton_iterations, relax_converged, relax_seconds) = relaxation;
        let min_distance_m = model.min_distance(x);
        YarnSimulationResult {
            scenario: scene.scenario.name().into(),
            pattern: pattern_path.display().to_string(),
            cells: scene.cells,
            yarns: model.patch().yarns.len(),
            vertices: model.vertex_count(),
            dofs: model.dof_count(),
            prescribed_vertices,
            edges: scene.edges,
            bonds: model.bonds().count(),
            yarn_radius_m: model.radius(),
            mass_kg: model.masses().iter().sum(),
            frames: 1,
            steps: 0,
            dt_s: scene.dt_s,
            simulated_time_s: 0.0,
            relax_newton_iterations,
            relax_converged,
            relax_seconds,
            newton_iterations: 0,
            newton_iterations_max_step: 0,
            factorizations: 0,
            unconverged_steps: 0,
            substeps: 0,
            rejected_substeps: 0,
            max_residual: 0.0,
            min_distance_m,
            min_distance_over_diameter: min_distance_m / (2.0 * model.radius()),
            max_contacts: 0,
            max_candidates: 0,
            max_sphere_contacts: 0,
            kinetic_energy_j: 0.0,
            centre_of_mass_displacement_m: [0.0; 3],
            seconds: 0.0,
            seconds_per_step: 0.0,
            seconds_per_newton_iteration: 0.0,
            stopped: false,
            newton_timings: Default::default(),
        }
    }

    /// Writes `out/result.json` (pretty JSON).
    pub fn write(&self, out: &Path) -> Result<(), YarnSceneError> {
        let path = out.join("result.json");
        let text = serde_json::to_string_pretty(self)
            .map_err(|e| YarnSceneError::Output(e.to_string()))?;
        std::fs::write(&path, text)
            .map_err(|e| YarnSceneError::Output(format!("cannot write {}: {e}", path.display())))
    }
}

/// Serde for a distance that is infinite when nothing was near: `null` in JSON.
mod infinite_as_null {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        if v.is_finite() {
            s.serialize_f64(*v)
        } else {
            s.serialize_none()
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::INFINITY))
    }
}

/// The metadata of the scene's frame sequence (`sequence.json`, no frames yet), frames every `per_frame`
/// steps.
pub fn sequence_meta(
    scene: &YarnScene,
    pattern_path: &Path,
    model: &PatchModel,
    per_frame: usize,
    held_vertices: &[usize],
) -> SequenceMeta {
    SequenceMeta {
        format: FORMAT.into(),
        version: VERSION,
        pattern: pattern_path.display().to_string(),
        cells: scene.cells,
        scenario: scene.scenario.name().into(),
        units: Units::default(),
        yarn_radius_m: model.radius(),
        linear_density_kg_per_m: model.linear_density(),
        dt_s: scene.dt_s,
        frame_interval_s: scene.dt_s * per_frame as f64,
        vertex_count: model.vertex_count(),
        frame_count: 0,
        yarns: model
            .yarn_ranges()
            .iter()
            .zip(&model.patch().yarns)
            .map(|(r, y)| YarnRange {
                first_vertex: r.start,
                vertex_count: r.len(),
                closed: y.closed,
            })
            .collect(),
        frames: vec![],
        loads: Some(SequenceLoads {
            gravity_m_per_s2: [0.0, -scene.gravity_m_s2, 0.0],
            held_vertices: held_vertices.to_vec(),
            collider: model.loads().sphere.is_some(),
        }),
    }
}

/// Per vertex of the patch, the pattern vertex and the cell it copies (`vertex_sources.npy`).
pub fn vertex_sources(model: &PatchModel) -> Vec<(usize, [i32; 2])> {
    model
        .patch()
        .yarns
        .iter()
        .flat_map(|y| y.source.iter().copied())
        .collect()
}

/// The centre of mass of the state `x` (m).
pub fn centre_of_mass(model: &PatchModel, x: &[f64]) -> [f64; 3] {
    let m: f64 = model.masses().iter().sum();
    std::array::from_fn(|k| {
        model
            .masses()
            .iter()
            .zip(x.chunks(4))
            .map(|(mi, c)| mi * c[k])
            .sum::<f64>()
            / m
    })
}

/// Writes `yarns.obj` (polylines) and `yarns.glb` (tubes) of the state `x` into `out`.
pub fn write_shapes(model: &PatchModel, x: &[f64], out: &Path) -> Result<(), YarnSceneError> {
    let points = PatchModel::positions(x);
    let mut patch = model.patch().clone();
    for (y, range) in patch.yarns.iter_mut().zip(model.yarn_ranges()) {
        y.positions = points[range].to_vec();
    }
    let obj = out.join("yarns.obj");
    patch
        .write_obj(&obj)
        .map_err(|e| YarnSceneError::Output(format!("cannot write {}: {e}", obj.display())))?;
    let lines: Vec<(&[[f64; 3]], bool)> = patch
        .yarns
        .iter()
        .map(|y| (y.positions.as_slice(), y.closed))
        .collect();
    let glb = out.join("yarns.glb");
    let bytes = tubes(&lines, patch.radius, 8)
        .to_glb("yarns")
        .map_err(|e| YarnSceneError::Output(format!("cannot encode {}: {e}", glb.display())))?;
    std::fs::write(&glb, bytes)
        .map_err(|e| YarnSceneError::Output(format!("cannot write {}: {e}", glb.display())))
}
