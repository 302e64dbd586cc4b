//! The `simulate` job kind: the CLI's `skintight simulate` on the worker pool.
//!
//! Spec: the scene JSON of docs/SCENE.md, with an uploaded asset id in place of a mesh path
//! (`body.source.path` of a `surface_mesh` body). The asset is read and checked at submission, so a mesh that
//! cannot serve as a body is answered with 422 at `spec.body.source.path` instead of a failed job; assets are
//! surface meshes, so `tet_mesh` bodies are refused there too. Every Newton iteration is reported as an
//! `iteration` event (energy, residual, damping, seconds); cancellation and the time limit are observed after
//! each iteration. After every iteration the Newton state is checkpointed (`encode_checkpoint`); a job
//! interrupted by a crash or a shutdown sets up again (deterministically) and resumes the solve from that
//! state ([`crate::simulate::run_resumable`]).
//! Artifacts: `result.json`, `garment.glb`, `garment-pressure.glb`, `body.glb`, the pattern files and `report.html`
//! (docs/OUTPUTS.md).

use std::ops::ControlFlow;
use std::path::PathBuf;

use serde_json::{Value, json};

use skintight_geometry::mesh::io::{MeshFormat, read_mesh_bytes};
use skintight_geometry::{MeshCheckParams, body_surface};

use super::model::{Artifact, Asset, AssetRef, Assets, FieldError, JobError, JobOutput};
use super::runner::{JobContext, JobRunner};
use crate::json_input::parse_json_input;
use crate::scene::{BodySource, Estimate, Limits, PathResolver, Scene, SceneError, SurfaceSize};
use crate::simulate::admissibility::{Admissibility, verdict_line};
use crate::simulate::{
    ArtifactFile, SimulateError, Simulation, SimulationResult, artifacts, prepare, run_resumable,
};
use skintight_geometry::{SurfaceCoord, Vec2, Vec3};
use skintight_physics::{ClothOnBodyState, SolveProgress};

/// The `simulate` kind.
pub struct SimulateJob;

/// The spec field that holds a mesh asset id, if the body is read from a mesh.
const MESH_FIELD: &str = "body.source.path";

/// The asset id in the spec's mesh path field, if any.
fn mesh_asset(scene: &Scene) -> Option<String> {
    match &scene.body.source {
        BodySource::SurfaceMesh { path, .. } | BodySource::TetMesh { path } => Some(path.clone()),
        BodySource::Cylinder(_) | BodySource::Sphere(_) => None,
    }
}

/// The fraction done of a Newton solve, reported with each iteration: how far the relative residual has come
/// from its first value down to the tolerance, on a log scale (Newton's convergence is geometric, then
/// quadratic), or the share of the iteration limit used, whichever is more; never decreasing, and 1 only once
/// the residual is below the tolerance.
struct Progress {
    max_iterations: f64,
    tolerance: f64,
    first_residual: Option<f64>,
    fraction: f64,
}

impl Progress {
    fn new(max_iterations: usize, tolerance: f64) -> Self {
        Progress {
            max_iterations: max_iterations.max(1) as f64,
            tolerance,
            first_residual: None,
            fraction: 0.0,
        }
    }

    fn after(&mut self, iteration: usize, residual: f64) -> f64 {
        let by_count = (iteration as f64 / self.max_iterations).min(1.0);
        let first = *self.first_residual.get_or_insert(residual);
        let by_residual = if residual < self.tolerance {
            1.0
        } else if first > self.tolerance && residual.is_finite() {
            ((first / residual).ln() / (first / self.tolerance).ln()).clamp(0.0, 0.99)
        } else {
            0.0
        };
        self.fraction = self.fraction.max(by_count).max(by_residual);
        self.fraction
    }
}

/// Whether an asset can serve as a `surface_mesh` body: readable in its format, and a closed, oriented,
/// single-component 2-manifold (the check the job itself makes before filling the body with tetrahedra).
pub(super) fn check_body_surface(asset: &Asset) -> Result<(), FieldError> {
    let format = MeshFormat::from_extension(&asset.format).ok_or_else(|| {
        FieldError::new(
            MESH_FIELD,
            format!(
                "asset {} has the format {:?}, which cannot be read as a body surface",
                asset.id, asset.format
            ),
        )
    })?;
    let mesh = read_mesh_bytes(&asset.data, format).map_err(|e| {
        FieldError::new(
            MESH_FIELD,
            format!("cannot read asset {} as {}: {e}", asset.id, asset.format),
        )
    })?;
    body_surface(mesh, &MeshCheckParams::default()).map_err(|issue| {
        FieldError::new(
            MESH_FIELD,
            format!("asset {} cannot serve as a body: {issue}", asset.id),
        )
    })?;
    Ok(())
}

/// The body surface's size for admission costing: from a procedural body's parameters, or from the
/// uploaded mesh (read again here; [`check_body_surface`] has read it already).
pub(super) fn body_size(scene: &Scene, assets: &Assets) -> Result<SurfaceSize, FieldError> {
    if let Some(size) = SurfaceSize::of_procedural(&scene.body.source) {
        return Ok(size);
    }
    let asset = assets
        .get(MESH_FIELD)
        .ok_or_else(|| FieldError::new(MESH_FIELD, "the body's mesh asset was not loaded"))?;
    let format = MeshFormat::from_extension(&asset.format).ok_or_else(|| {
        FieldError::new(
            MESH_FIELD,
            format!(
                "asset {} has the unreadable format {:?}",
                asset.id, asset.format
            ),
        )
    })?;
    let mesh = read_mesh_bytes(&asset.data, format).map_err(|e| {
        FieldError::new(
            MESH_FIELD,
            format!("cannot read asset {} as {}: {e}", asset.id, asset.format),
        )
    })?;
    Ok(match &scene.body.source {
        BodySource::SurfaceMesh {
            prepare: Some(spec),
            ..
        } => SurfaceSize::of_prepared(&mesh, spec),
        _ => SurfaceSize::of_mesh(&mesh),
    })
}

/// Admission costing of a scene solved `equilibria` times (see [`crate::scene::Estimate`]).
pub(super) fn admit_scene(
    scene: &Scene,
    assets: &Assets,
    limits: &Limits,
    equilibria: f64,
) -> Result<(), FieldError> {
    let size = body_size(scene, assets)?;
    Estimate::of_scene(scene, &size, equilibria)
        .check(limits)
        .map_err(|e| FieldError::new(e.key, e.message))
}

/// The first bytes of a simulate checkpoint (format version 1).
const CHECKPOINT_MAGIC: &[u8; 8] = b"STSIM\x001\x00";

/// A simulate checkpoint: the Newton state after an iteration and the solve's progress, bit for bit
/// (little-endian): the magic, `iterations`, `diag_scale`, `alpha`, `last_factored`, the cloth and body
/// vertex counts, then per cloth vertex its face and `(s1, s2)`, per body vertex its position.
fn encode_checkpoint(state: &ClothOnBodyState, solve: &SolveProgress) -> Vec<u8> {
    let mut out = Vec::with_capacity(64 + 24 * (state.cloth.len() + state.body.len()));
    out.extend_from_slice(CHECKPOINT_MAGIC);
    out.extend_from_slice(&(solve.iterations as u64).to_le_bytes());
    for x in [solve.diag_scale, solve.alpha, solve.last_factored] {
        out.extend_from_slice(&x.to_le_bytes());
    }
    out.extend_from_slice(&(state.cloth.len() as u64).to_le_bytes());
    out.extend_from_slice(&(state.body.len() as u64).to_le_bytes());
    for c in &state.cloth {
        out.extend_from_slice(&(c.face as u64).to_le_bytes());
        out.extend_from_slice(&c.s.x.to_le_bytes());
        out.extend_from_slice(&c.s.y.to_le_bytes());
    }
    for p in &state.body {
        for x in [p.x, p.y, p.z] {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }
    out
}

/// Reads a checkpoint of [`encode_checkpoint`] for `sim`; `None` (the job starts afresh) when it is not
/// one, or does not fit this simulation's system.
fn decode_checkpoint(data: &[u8], sim: &Simulation) -> Option<(ClothOnBodyState, SolveProgress)> {
    let mut rest = data.strip_prefix(CHECKPOINT_MAGIC.as_slice())?;
    let mut word = || -> Option<[u8; 8]> {
        let (w, r) = rest.split_first_chunk::<8>()?;
        rest = r;
        Some(*w)
    };
    let iterations = u64::from_le_bytes(word()?) as usize;
    let diag_scale = f64::from_le_bytes(word()?);
    let alpha = f64::from_le_bytes(word()?);
    let last_factored = f64::from_le_bytes(word()?);
    let n_cloth = u64::from_le_bytes(word()?) as usize;
    let n_body = u64::from_le_bytes(word()?) as usize;
    if n_cloth != sim.state.cloth.len() || n_body != sim.state.body.len() {
        return None;
    }
    let faces = sim.body.surface.num_faces();
    let mut cloth = Vec::with_capacity(n_cloth);
    for _ in 0..n_cloth {
        let face = u64::from_le_bytes(word()?) as usize;
        let s = Vec2::new(f64::from_le_bytes(word()?), f64::from_le_bytes(word()?));
        if face >= faces || !(s.x.is_finite() && s.y.is_finite()) {
            return None;
        }
        cloth.push(SurfaceCoord { face, s });
    }
    let mut body = Vec::with_capacity(n_body);
    for _ in 0..n_body {
        let p = Vec3::new(
            f64::from_le_bytes(word()?),
            f64::from_le_bytes(word()?),
            f64::from_le_bytes(word()?),
        );
        if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
            return None;
        }
        body.push(p);
    }
    if !rest.is_empty() {
        return None;
    }
    let solve = SolveProgress {
        iterations,
        diag_scale,
        alpha,
        last_factored,
    };
    Some((ClothOnBodyState { cloth, body }, solve))
}

/// Resolves asset ids to the files the job wrote them to.
pub(super) struct AssetFiles {
    dir: PathBuf,
    files: Vec<(String, PathBuf)>,
}

impl PathResolver for AssetFiles {
    fn resolve(&self, key: &str, reference: &str) -> Result<PathBuf, SceneError> {
        self.files
            .iter()
            .find(|(id, _)| id == reference)
            .map(|(_, p)| p.clone())
            .ok_or_else(|| SceneError::new(key, format!("asset {reference} was not found")))
    }
}

impl Drop for AssetFiles {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// A simulation's error as a job's: input errors naming a key become 422-style invalid input, the rest
/// failures.
impl From<SimulateError> for JobError {
    fn from(e: SimulateError) -> Self {
        match (e.input, e.key) {
            (true, Some(key)) => JobError::Invalid {
                field: key,
                message: e.message,
            },
            (_, _) => JobError::Failed(e.message),
        }
    }
}

impl From<ArtifactFile> for Artifact {
    fn from(f: ArtifactFile) -> Self {
        Artifact {
            name: f.name.into(),
            content_type: f.content_type.into(),
            data: f.data,
        }
    }
}

/// Writes the referenced assets to a temporary folder of the job that the readers can open. It is named
/// after the job (which never runs twice at once), so a run killed before it could remove the folder
/// leaves nothing behind once the job runs again.
pub(super) fn asset_files(assets: &Assets, ctx: &JobContext) -> Result<AssetFiles, JobError> {
    let dir = std::env::temp_dir().join(format!("skintight-job-{}", ctx.job_id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir)
        .map_err(|e| JobError::Failed(format!("cannot create a work folder: {e}")))?;
    let mut files = AssetFiles {
        dir: dir.clone(),
        files: Vec::new(),
    };
    for (field, asset) in &assets.by_field {
        let path = dir.join(format!("{}.{}", asset.id, asset.format));
        std::fs::write(&path, &asset.data)
            .map_err(|e| JobError::Failed(format!("cannot write asset for {field}: {e}")))?;
        files.files.push((asset.id.clone(), path));
    }
    Ok(files)
}

impl JobRunner for SimulateJob {
    type Spec = Scene;

    fn kind(&self) -> &'static str {
        "simulate"
    }

    /// The scene as [`Scene::from_json`] reads it, without its validation (which [`Self::validate`] does).
    fn parse(&self, spec: &Value) -> Result<Scene, FieldError> {
        parse_json_input(spec.to_string().as_bytes()).map_err(|e| {
            let e = SceneError::from_json_input(e, "scene");
            FieldError::new(e.key, e.message)
        })
    }

    fn validate(&self, scene: &Scene) -> Result<(), FieldError> {
        scene
            .validate()
            .map_err(|e| FieldError::new(e.key, e.message))
    }

    fn assets(&self, scene: &Scene) -> Vec<AssetRef> {
        mesh_asset(scene)
            .map(|id| {
                vec![AssetRef {
                    field: MESH_FIELD.into(),
                    id,
                }]
            })
            .unwrap_or_default()
    }

    fn check_assets(&self, scene: &Scene, assets: &Assets) -> Result<(), FieldError> {
        let Some(asset) = assets.get(MESH_FIELD) else {
            return Ok(());
        };
        match scene.body.source {
            // A raw scan is prepared (and refused, naming the problem) when the job runs.
            BodySource::SurfaceMesh {
                prepare: Some(_), ..
            } => Ok(()),
            BodySource::SurfaceMesh { .. } => check_body_surface(asset),
            BodySource::TetMesh { .. } => Err(FieldError::new(
                MESH_FIELD,
                format!(
                    "asset {} is a surface mesh ({}); the service takes no tetrahedral mesh files, so use a \
                     \"surface_mesh\" body",
                    asset.id, asset.format
                ),
            )),
            BodySource::Cylinder(_) | BodySource::Sphere(_) => Ok(()),
        }
    }

    fn admit(&self, scene: &Scene, assets: &Assets, limits: &Limits) -> Result<(), FieldError> {
        admit_scene(scene, assets, limits, 1.0)
    }

    fn run(
        &self,
        scene: &Scene,
        assets: &Assets,
        ctx: &mut JobContext,
    ) -> Result<JobOutput, JobError> {
        let files = asset_files(assets, ctx)?;
        // Set-up is deterministic: the same body, garment and start state as the interrupted run.
        let mut sim = prepare(scene, &files)?;
        // Resume from the Newton state of the last finished iteration, if a run got that far.
        let resume = ctx
            .checkpoint
            .as_ref()
            .and_then(|cp| decode_checkpoint(&cp.data, &sim));
        let resume = match resume {
            Some((state, solve)) => {
                ctx.last_checkpoint();
                sim.state = state;
                Some(solve)
            }
            None => None,
        };
        let mut progress = Progress::new(scene.solver.max_iterations, scene.solver.tolerance);
        let mut stop: Option<JobError> = None;
        let report = run_resumable(&mut sim, resume, &mut |info, state, solve| {
            ctx.progress(progress.after(info.iteration, info.residual));
            // The iteration's event and its checkpoint in one transaction.
            let recorded = ctx.iteration_checkpointed(
                info.iteration as u64,
                json!({
                    "iteration": info.iteration,
                    "energy": info.energy,
                    "residual": info.residual,
                    "damping": info.damping,
                    "step_quality": info.step_quality,
                    "seconds": info.elapsed_s,
                }),
                encode_checkpoint(state, solve),
            );
            match recorded {
                Ok(()) => ControlFlow::Continue(()),
                Err(e) => {
                    stop = Some(e);
                    ControlFlow::Break(())
                }
            }
        })
        .map_err(|e| JobError::Failed(e.to_string()))?;
        if let Some(e) = stop {
            return Err(e);
        }
        let result =
            SimulationResult::new(&sim, &report).map_err(|e| JobError::Failed(e.to_string()))?;
        let files = artifacts(&sim, &result).map_err(|e| JobError::Failed(e.to_string()))?;
        let summary = result.summary();
        Ok(JobOutput {
            artifacts: files.into_iter().map(Artifact::from).collect(),
            summary,
            warnings: admissibility_warnings(&result.admissibility),
        })
    }
}

/// The `warning` events of a garment that is not admissible: one, `{code: "not_admissible", message,
/// violations}` (the message is the CLI's verdict line); none for an admissible garment.
pub(super) fn admissibility_warnings(admissibility: &Admissibility) -> Vec<Value> {
    if admissibility.admissible {
        return Vec::new();
    }
    vec![json!({
        "code": "not_admissible",
        "message": verdict_line(admissibility),
        "violations": admissibility.violations,
    })]
}

#[cfg(test)]
mod tests {
    use super::Progress;

    #[test]
    fn progress_follows_the_residual_down_to_the_tolerance() {
        let mut p = Progress::new(100, 1e-6);
        assert_eq!(p.after(1, 1e-1), 0.01);
        let half = p.after(2, 10f64.powf(-3.5));
        assert!((half - 0.5).abs() < 1e-9, "{half}");
        // A residual that goes up again does not take progress back.
        assert_eq!(p.after(3, 1e-2), half);
        assert!(p.after(4, 2e-6) < 1.0);
        assert_eq!(p.after(5, 1e-7), 1.0);
        // Slow solves move by the share of the iteration limit used.
        let mut p = Progress::new(10, 1e-6);
        assert_eq!(p.after(1, 1.0), 0.1);
        assert_eq!(p.after(5, 1.0), 0.5);
    }
}
