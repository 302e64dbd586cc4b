//! The `design` job kind: the CLI's `skintight design` on the worker pool.
//!
//! Spec: the design job JSON of docs/DESIGN_JOB.md, with uploaded asset ids in place of mesh paths
//! (`body.source.path` of a `surface_mesh` body, `objectives.shape.target.path` of a mesh target). The body
//! asset is checked at submission as for `simulate`. Every design iteration is reported as an `iteration`
//! event with the entry `history.json` gets (objective, terms, gradient norm, stretches, pressures, …);
//! cancellation and the time limit are polled at every Newton iteration of every equilibrium solve, and a
//! stopped design is not written (the job ends cancelled or timed out). The job is deterministic, so one
//! interrupted by a crash runs again from the start. Artifacts: `result.json`, `garment.glb`, `body.glb`, the
//! pattern files (docs/OUTPUTS.md) and `history.json`.

use std::ops::ControlFlow;

use serde_json::{Value, json};

use super::model::{Artifact, AssetRef, Assets, FieldError, JobError, JobOutput};
use super::runner::{JobContext, JobRunner};
use super::simulate_job::{asset_files, check_body_surface};
use crate::design::{
    DesignJob, TargetSpec, design_artifacts, design_summary, prepare_design, run_design,
};
use crate::json_input::parse_json_input;
use crate::scene::{BodySource, SceneError};

/// The `design` kind.
pub struct DesignJobKind;

const BODY_FIELD: &str = "body.source.path";
const TARGET_FIELD: &str = "objectives.shape.target.path";

impl JobRunner for DesignJobKind {
    type Spec = DesignJob;

    fn kind(&self) -> &'static str {
        "design"
    }

    /// The job as [`DesignJob::from_json`] reads it, without its validation (which [`Self::validate`]
    /// does).
    fn parse(&self, spec: &Value) -> Result<DesignJob, FieldError> {
        parse_json_input(spec.to_string().as_bytes()).map_err(|e| {
            let e = SceneError::from_json_input(e, "design job");
            FieldError::new(e.key, e.message)
        })
    }

    fn validate(&self, job: &DesignJob) -> Result<(), FieldError> {
        job.validate()
            .map_err(|e| FieldError::new(e.key, e.message))
    }

    fn assets(&self, job: &DesignJob) -> Vec<AssetRef> {
        let mut out = Vec::new();
        if let BodySource::SurfaceMesh { path, .. } | BodySource::TetMesh { path, .. } =
            &job.body.source
        {
            out.push(AssetRef {
                field: BODY_FIELD.into(),
                id: path.clone(),
            });
        }
        if let Some(shape) = &job.objectives.shape
            && let TargetSpec::Mesh { path } = &shape.target
        {
            out.push(AssetRef {
                field: TARGET_FIELD.into(),
                id: path.clone(),
            });
        }
        out
    }

    fn check_assets(&self, job: &DesignJob, assets: &Assets) -> Result<(), FieldError> {
        if let Some(asset) = assets.get(BODY_FIELD) {
            match &job.body.source {
                BodySource::SurfaceMesh { .. } => check_body_surface(asset)?,
                _ => {
                    return Err(FieldError::new(
                        BODY_FIELD,
                        "the service takes no tetrahedral mesh files: use a \"surface_mesh\" body",
                    ));
                }
            }
        }
        if let Some(asset) = assets.get(TARGET_FIELD) {
            let format = skintight_geometry::mesh::io::MeshFormat::from_extension(&asset.format);
            let readable = format
                .and_then(|f| skintight_geometry::mesh::io::read_mesh_bytes(&asset.data, f).ok())
                .is_some_and(|m| !m.faces.is_empty());
            if !readable {
                return Err(FieldError::new(
                    TARGET_FIELD,
                    format!(
                        "asset {} cannot be read as a target triangle mesh",
                        asset.id
                    ),
                ));
            }
        }
        Ok(())
    }

    fn run(
        &self,
        job: &DesignJob,
        assets: &Assets,
        ctx: &mut JobContext,
    ) -> Result<JobOutput, JobError> {
        let files = asset_files(assets, ctx)?;
        let mut design = prepare_design(job, &files)?;
        ctx.should_stop()?;
        let max_iterations = job.optimizer.max_iterations.max(1) as f64;
        let poll = ctx.stop_poll();
        let mut stop: Option<JobError> = None;
        let result = run_design(
            &mut design,
            &mut |it| {
                ctx.progress((it.iteration as f64 / max_iterations).min(1.0));
                let metrics = serde_json::to_value(it).unwrap_or_else(|_| json!({}));
                match ctx.iteration(metrics) {
                    Ok(()) => ControlFlow::Continue(()),
                    Err(e) => {
                        stop = Some(e);
                        ControlFlow::Break(())
                    }
                }
            },
            &poll,
        )?;
        if let Some(e) = stop {
            return Err(e);
        }
        ctx.should_stop()?;
        let files =
            design_artifacts(&design, &result).map_err(|e| JobError::Failed(e.to_string()))?;
        let summary = design_summary(&result);
        Ok(JobOutput {
            artifacts: files.into_iter().map(Artifact::from).collect(),
            summary,
        })
    }
}
