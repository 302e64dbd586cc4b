//! The `simulate` job kind: the CLI's `skintight simulate` on the worker pool.
//!
//! Spec: the scene JSON of docs/SCENE.md, with an uploaded asset id in place of a mesh path
//! (`body.source.path` of a `surface_mesh` body). The asset is read and checked at submission, so a mesh that
//! cannot serve as a body is answered with 422 at `spec.body.source.path` instead of a failed job; assets are
//! surface meshes, so `tet_mesh` bodies are refused there too. Every Newton iteration is reported as an
//! `iteration` event (energy, residual, damping, seconds); cancellation and the time limit are observed after
//! each iteration. The job is deterministic, so a job interrupted by a crash is simply run again from the start.
//! Artifacts: `result.json`, `garment.glb`, `body.glb`, `patterns.svg`.

use std::ops::ControlFlow;
use std::path::PathBuf;

use serde_json::{Value, json};

use skintight_geometry::mesh::io::{MeshFormat, read_mesh_bytes};
use skintight_geometry::{MeshCheckParams, body_surface};

use super::model::{Artifact, Asset, AssetRef, Assets, FieldError, JobError, JobOutput};
use super::runner::{JobContext, JobRunner};
use crate::json_input::parse_json_input;
use crate::scene::{BodySource, Estimate, Limits, PathResolver, Scene, SceneError, SurfaceSize};
use crate::simulate::{ArtifactFile, SimulateError, SimulationResult, artifacts, prepare, run};

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
    Ok(SurfaceSize::of_mesh(&mesh))
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
        let mut sim = prepare(scene, &files)?;
        let mut progress = Progress::new(scene.solver.max_iterations, scene.solver.tolerance);
        let mut stop: Option<JobError> = None;
        let report = run(&mut sim, &mut |info| {
            ctx.progress(progress.after(info.iteration, info.residual));
            match ctx.iteration(json!({
                "iteration": info.iteration,
                "energy": info.energy,
                "residual": info.residual,
                "damping": info.damping,
                "step_quality": info.step_quality,
                "seconds": info.elapsed_s,
            })) {
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
        })
    }
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
