//! The `simulate` job kind: the CLI's `skintight simulate` on the worker pool.
//!
//! Spec: the scene JSON of docs/SCENE.md, with an uploaded asset id in place of a mesh path
//! (`body.source.path` for `surface_mesh` and `tet_mesh` bodies). Every Newton iteration is reported as an
//! `iteration` event (energy, residual, damping, seconds); cancellation and the time limit are observed after
//! each iteration. The job is deterministic, so a job interrupted by a crash is simply run again from the start.
//! Artifacts: `result.json`, `garment.glb`, `body.glb`, `patterns.svg`.

use std::ops::ControlFlow;
use std::path::PathBuf;

use serde_json::{Value, json};

use super::runner::{
    Artifact, AssetRef, Assets, FieldError, JobContext, JobError, JobOutput, JobRunner,
};
use crate::scene::{PathResolver, Scene, SceneError};
use crate::simulate::{SimulationResult, artifacts, prepare, run};

/// The `simulate` kind.
pub struct SimulateJob;

/// The spec field that holds a mesh asset id, if the body is read from a mesh.
const MESH_FIELD: &str = "body.source.path";

fn parse(spec: &Value) -> Result<Scene, FieldError> {
    let scene =
        Scene::from_json(&spec.to_string()).map_err(|e| FieldError::new(e.key, e.message))?;
    scene
        .validate()
        .map_err(|e| FieldError::new(e.key, e.message))?;
    Ok(scene)
}

/// The asset id in the spec's mesh path field, if any.
fn mesh_asset(spec: &Value) -> Option<String> {
    spec.pointer("/body/source/path")
        .and_then(Value::as_str)
        .map(str::to_string)
}

/// Resolves asset ids to the files the job wrote them to.
struct AssetFiles {
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

impl JobRunner for SimulateJob {
    fn kind(&self) -> &'static str {
        "simulate"
    }

    fn validate(&self, spec: &Value) -> Result<(), FieldError> {
        parse(spec).map(|_| ())
    }

    fn assets(&self, spec: &Value) -> Vec<AssetRef> {
        mesh_asset(spec)
            .map(|id| {
                vec![AssetRef {
                    field: MESH_FIELD.into(),
                    id,
                }]
            })
            .unwrap_or_default()
    }

    fn run(
        &self,
        spec: &Value,
        assets: &Assets,
        ctx: &mut JobContext,
    ) -> Result<JobOutput, JobError> {
        let scene = parse(spec).map_err(|e| JobError::Invalid {
            field: e.field,
            message: e.message,
        })?;
        // Write the referenced assets to a private temporary folder the readers can open.
        let dir = std::env::temp_dir().join(format!("skintight-job-{}", uuid::Uuid::new_v4()));
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
        let mut sim = prepare(&scene, &files).map_err(|e| match (e.input, e.key) {
            (true, Some(key)) => JobError::Invalid {
                field: key,
                message: e.message,
            },
            (_, _) => JobError::Failed(e.message),
        })?;
        let max_iterations = scene.solver.max_iterations.max(1) as f64;
        let mut stop: Option<JobError> = None;
        let report = run(&mut sim, &mut |info| {
            ctx.progress(info.iteration as f64 / max_iterations);
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
            artifacts: files
                .into_iter()
                .map(|f| Artifact {
                    name: f.name.into(),
                    content_type: f.content_type.into(),
                    data: f.data,
                })
                .collect(),
            summary,
        })
    }
}
