//! The `design` job kind: the CLI's `skintight design` on the worker pool.
//!
//! Spec: the design job JSON of docs/DESIGN_JOB.md, with uploaded asset ids in place of mesh paths
//! (`body.source.path` of a `surface_mesh` body, `objectives.shape.target.path` of a mesh target). The body
//! asset is checked at submission as for `simulate`. Every design iteration is reported as an `iteration`
//! event numbered as its entry of `history.json` and carrying it (objective, terms, gradient norm,
//! stretches, pressures, …; the initial design, iteration 0, is only in `history.json`);
//! cancellation and the time limit are polled at every Newton iteration of every equilibrium solve, and a
//! stopped design is not written (the job ends cancelled or timed out). After every design iteration the
//! run is checkpointed ([`RunCheckpoint`]: optimizer memory, level, best design, remeshes), in the same
//! transaction as the iteration's event (so a resumed run re-runs no announced iteration); a job
//! interrupted by a crash or a shutdown sets up again (deterministically) and goes on from its last
//! finished iteration ([`run_design_from`]), ending with the design an uninterrupted run ends with and
//! announcing no iteration twice. Artifacts: `result.json`, `garment.glb`, `garment-pressure.glb`, `body.glb`, the pattern files,
//! `report.html` (docs/OUTPUTS.md) and `history.json`. The initial equilibrium is cancellable at every Newton iteration
//! as well.

use std::ops::ControlFlow;

use serde_json::{Value, json};

use skintight_geometry::TriMesh;
use skintight_geometry::mesh::io::{MeshFormat, read_mesh_bytes};

use super::model::{Artifact, Asset, AssetRef, Assets, FieldError, JobError, JobOutput};
use super::runner::{JobContext, JobRunner};
use super::simulate_job::{admissibility_warnings, admit_scene, asset_files, check_body_surface};
use crate::design::{
    DesignJob, RunCheckpoint, TargetSpec, design_artifacts, design_summary, prepare_design_with,
    run_design_from,
};
use crate::json_input::parse_json_input;
use crate::scene::{BodySource, Limits, SceneError};

/// The `design` kind.
pub struct DesignJobKind;

const BODY_FIELD: &str = "body.source.path";
const TARGET_FIELD: &str = "objectives.shape.target.path";

/// The spec field of the `i`-th sliding pose's asset.
fn pose_field(i: usize) -> String {
    format!("objectives.sliding.poses[{i}].path")
}

/// Reads an asset as a non-empty triangle mesh; the error names `field` and says what it should be.
fn read_triangles(asset: &Asset, field: &str, what: &str) -> Result<TriMesh, FieldError> {
    MeshFormat::from_extension(&asset.format)
        .and_then(|f| read_mesh_bytes(&asset.data, f).ok())
        .filter(|m| !m.faces.is_empty())
        .ok_or_else(|| {
            FieldError::new(
                field,
                format!("asset {} cannot be read as {what}", asset.id),
            )
        })
}

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
        if let Some(sliding) = &job.objectives.sliding {
            for (i, pose) in sliding.poses.iter().enumerate() {
                out.push(AssetRef {
                    field: pose_field(i),
                    id: pose.path.clone(),
                });
            }
        }
        out
    }

    fn admit(&self, job: &DesignJob, assets: &Assets, limits: &Limits) -> Result<(), FieldError> {
        // One equilibrium per design iteration, plus the first.
        let equilibria = job.optimizer.max_iterations as f64 + 1.0;
        admit_scene(&job.scene(), assets, limits, equilibria)
    }

    fn check_assets(&self, job: &DesignJob, assets: &Assets) -> Result<(), FieldError> {
        if let Some(asset) = assets.get(BODY_FIELD) {
            match &job.body.source {
                BodySource::SurfaceMesh {
                    prepare: Some(_), ..
                } => {}
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
            read_triangles(asset, TARGET_FIELD, "a target triangle mesh")?;
        }
        // A pose must be a readable surface with the body surface's vertex and face counts (the
        // triangles themselves are compared when the design is prepared).
        let body = match (&job.body.source, assets.get(BODY_FIELD)) {
            (BodySource::SurfaceMesh { prepare: None, .. }, Some(a)) => {
                Some(read_triangles(a, BODY_FIELD, "a body surface")?)
            }
            _ => None,
        };
        if let Some(sliding) = &job.objectives.sliding {
            for i in 0..sliding.poses.len() {
                let field = pose_field(i);
                let Some(asset) = assets.get(&field) else {
                    continue;
                };
                let pose = read_triangles(asset, &field, "a posed body surface")?;
                if let Some(body) = &body
                    && (pose.num_vertices() != body.num_vertices()
                        || pose.num_faces() != body.num_faces())
                {
                    return Err(FieldError::new(
                        field,
                        format!(
                            "asset {} has {} vertices and {} faces; a pose needs the body's {} and {}",
                            asset.id,
                            pose.num_vertices(),
                            pose.num_faces(),
                            body.num_vertices(),
                            body.num_faces()
                        ),
                    ));
                }
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
        // The initial equilibrium honours cancellation, the time limit and shutdown at every Newton
        // iteration too.
        let poll = ctx.stop_poll();
        let prepared = prepare_design_with(job, &files, &mut |_| {
            if poll() {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        });
        ctx.should_stop()?;
        let mut design = prepared?;
        // Go on from the last finished iteration, if an earlier attempt got that far.
        let resume = ctx
            .checkpoint
            .as_ref()
            .and_then(|cp| RunCheckpoint::decode(&cp.data));
        if resume.is_some() {
            ctx.last_checkpoint();
        }
        let max_iterations = job.optimizer.max_iterations.max(1) as f64;
        let poll = ctx.stop_poll();
        let mut stop: Option<JobError> = None;
        let result = run_design_from(
            &mut design,
            resume,
            &mut |it, checkpoint| {
                // The initial design (iteration 0) is in history.json and the summary's
                // `initial_objective`; the events are the design iterations 1, 2, …, each numbered as
                // its metrics are, each stored with its checkpoint (one transaction).
                let reported = if it.iteration == 0 {
                    ctx.should_stop()
                } else {
                    ctx.progress((it.iteration as f64 / max_iterations).min(1.0));
                    let metrics = serde_json::to_value(it).unwrap_or_else(|_| json!({}));
                    ctx.iteration_checkpointed(it.iteration as u64, metrics, checkpoint.encode())
                };
                match reported {
                    Ok(()) => ControlFlow::Continue(()),
                    Err(e) => {
                        stop = Some(e);
                        ControlFlow::Break(())
                    }
                }
            },
            &poll,
        );
        // A run stopped by cancellation, the time limit or a shutdown ends as that, not as a failure.
        if let Some(e) = stop {
            return Err(e);
        }
        ctx.should_stop()?;
        let result = result?;
        let outputs =
            design_artifacts(&design, &result).map_err(|e| JobError::Failed(e.to_string()))?;
        let summary = design_summary(&result, &outputs.admissibility);
        Ok(JobOutput {
            artifacts: outputs.files.into_iter().map(Artifact::from).collect(),
            summary,
            warnings: admissibility_warnings(&outputs.admissibility),
        })
    }
}
