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
//!
//! A graded order (`bodies: [{"name": …, <body>}, …]`, [`crate::design::batch_from_json`]): each body's
//! asset at `bodies[i].source.path`, every check of a one-body job made per body with its errors at
//! `bodies[i]…`; the bodies designed in turn, their iterations numbered on from the bodies before (each
//! event's metrics name its `body`), their artifacts prefixed `NAME.` (`anna.result.json`,
//! `anna.body.glb`, …) plus `batch.json` (the job's summary: each body's summary with its name, and
//! whether all are admissible). A body whose design fails fails the job, naming the body. A restart goes
//! on in the body it stopped in, designing the bodies before it again (deterministically the same, no
//! events) for their files.

use std::ops::ControlFlow;

use serde_json::{Value, json};

use skintight_geometry::TriMesh;
use skintight_geometry::mesh::io::{MeshFormat, read_mesh_bytes};

use super::model::{Artifact, Asset, AssetRef, Assets, FieldError, JobError, JobOutput};
use super::runner::{JobContext, JobRunner};
use super::simulate_job::{
    AssetFiles, admissibility_warnings, admit_scene, asset_files, check_body_surface,
};
use crate::design::{
    BatchBody, DesignJob, DesignOutputs, RunCheckpoint, TargetSpec, batch_from_json, batch_key,
    design_artifacts, design_summary, prepare_design_with, run_design_from,
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

impl DesignJobKind {
    /// The assets of one body's job, by their fields in a one-body job.
    fn job_assets(&self, job: &DesignJob) -> Vec<AssetRef> {
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

    fn admit_job(
        &self,
        job: &DesignJob,
        assets: &Assets,
        limits: &Limits,
    ) -> Result<(), FieldError> {
        // One equilibrium per design iteration, plus the first.
        let equilibria = job.optimizer.max_iterations as f64 + 1.0;
        admit_scene(&job.scene(), assets, limits, equilibria)
    }

    fn check_job_assets(&self, job: &DesignJob, assets: &Assets) -> Result<(), FieldError> {
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

    /// Designs one body's `job`: its outputs and the iterations it took. `events`: announce its
    /// iterations (numbered from `events.base + 1`) and checkpoint after each, resuming from `resume`; or
    /// `None` to run it silently (a graded order's body designed again after a restart, whose iterations
    /// were announced before).
    fn design_job(
        &self,
        job: &DesignJob,
        files: &AssetFiles,
        ctx: &mut JobContext,
        resume: Option<RunCheckpoint>,
        events: Option<Events>,
    ) -> Result<(DesignOutputs, usize, serde_json::Value), JobError> {
        // The initial equilibrium honours cancellation, the time limit and shutdown at every Newton
        // iteration too.
        let poll = ctx.stop_poll();
        let prepared = prepare_design_with(job, files, &mut |_| {
            if poll() {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        });
        ctx.should_stop()?;
        let mut design = prepared?;
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
                let reported = match &events {
                    _ if it.iteration == 0 => ctx.should_stop(),
                    None => ctx.should_stop(),
                    Some(ev) => {
                        let done = (it.iteration as f64 / max_iterations).min(1.0);
                        ctx.progress((ev.index as f64 + done) / ev.count as f64);
                        let mut metrics = serde_json::to_value(it).unwrap_or_else(|_| json!({}));
                        if let Some(name) = &ev.name {
                            metrics["body"] = json!(name);
                        }
                        ctx.iteration_checkpointed(
                            ev.base + it.iteration as u64,
                            metrics,
                            ev.wrap(checkpoint.encode()),
                        )
                    }
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
        Ok((outputs, result.iterations, summary))
    }
}

/// Where a body's design announces its iterations.
struct Events {
    /// Iterations announced before this body (by the bodies before it in a graded order).
    base: u64,
    /// The body's index and the order's body count (for progress).
    index: usize,
    count: usize,
    /// The body's name in a graded order (added to each iteration's metrics).
    name: Option<String>,
}

/// The first bytes of a graded order's checkpoint: the magic, the body index (u32) and the iterations
/// announced before it (u64), little-endian, then the body's [`RunCheckpoint`].
const BATCH_CHECKPOINT_MAGIC: &[u8; 8] = b"STBATCH1";

impl Events {
    /// A body's checkpoint as the job saves it: as it is for a one-body order; in a graded order with the
    /// body's index and base first.
    fn wrap(&self, data: Vec<u8>) -> Vec<u8> {
        if self.name.is_none() {
            return data;
        }
        let mut out = BATCH_CHECKPOINT_MAGIC.to_vec();
        out.extend_from_slice(&(self.index as u32).to_le_bytes());
        out.extend_from_slice(&self.base.to_le_bytes());
        out.extend(data);
        out
    }
}

/// A graded order's checkpoint: the body index, the iterations announced before it and the body's
/// checkpoint.
fn unwrap_batch_checkpoint(data: &[u8]) -> Option<(usize, u64, RunCheckpoint)> {
    let rest = data.strip_prefix(BATCH_CHECKPOINT_MAGIC.as_slice())?;
    let index = u32::from_le_bytes(rest.get(..4)?.try_into().ok()?) as usize;
    let base = u64::from_le_bytes(rest.get(4..12)?.try_into().ok()?);
    Some((index, base, RunCheckpoint::decode(rest.get(12..)?)?))
}

/// The assets of `bodies[index]`'s job as a one-body job names them: `bodies[index].source.path`'s asset
/// at `body.source.path`, the order's other assets (targets, poses) as they are.
fn body_assets(assets: &Assets, index: usize) -> Assets {
    let own = batch_key(BODY_FIELD, index);
    let mut out = Assets::default();
    for (field, asset) in &assets.by_field {
        if *field == own {
            out.by_field.insert(BODY_FIELD.into(), asset.clone());
        } else if !field.starts_with("bodies[") {
            out.by_field.insert(field.clone(), asset.clone());
        }
    }
    out
}

/// A field error of `bodies[index]`'s job, at the order's key.
fn at_body(e: FieldError, index: usize) -> FieldError {
    FieldError::new(batch_key(&e.field, index), e.message)
}

impl JobRunner for DesignJobKind {
    type Spec = DesignOrder;

    fn kind(&self) -> &'static str {
        "design"
    }

    /// A one-body job as [`DesignJob::from_json`] reads it, without its validation (which
    /// [`Self::validate`] does); a graded order (`bodies`) read and checked body by body
    /// ([`batch_from_json`]).
    fn parse(&self, spec: &Value) -> Result<DesignOrder, FieldError> {
        let text = spec.to_string();
        if spec.get("bodies").is_some() {
            let bodies = batch_from_json(&text)
                .map_err(|e| FieldError::new(e.key, e.message))?
                .unwrap_or_default();
            return Ok(DesignOrder::Graded(bodies));
        }
        parse_json_input(text.as_bytes())
            .map(DesignOrder::One)
            .map_err(|e| {
                let e = SceneError::from_json_input(e, "design job");
                FieldError::new(e.key, e.message)
            })
    }

    fn validate(&self, order: &DesignOrder) -> Result<(), FieldError> {
        for (i, job) in order.jobs() {
            job.validate().map_err(|e| {
                FieldError::new(i.map_or(e.key.clone(), |i| batch_key(&e.key, i)), e.message)
            })?;
        }
        Ok(())
    }

    fn assets(&self, order: &DesignOrder) -> Vec<AssetRef> {
        let mut out: Vec<AssetRef> = Vec::new();
        for (i, job) in order.jobs() {
            for mut a in self.job_assets(job) {
                if let Some(i) = i {
                    a.field = batch_key(&a.field, i);
                }
                // The order's shared assets (targets, poses) once.
                if !out.iter().any(|b| b.field == a.field) {
                    out.push(a);
                }
            }
        }
        out
    }

    fn admit(
        &self,
        order: &DesignOrder,
        assets: &Assets,
        limits: &Limits,
    ) -> Result<(), FieldError> {
        match order {
            DesignOrder::One(job) => self.admit_job(job, assets, limits),
            DesignOrder::Graded(bodies) => bodies.iter().enumerate().try_for_each(|(i, b)| {
                self.admit_job(&b.job, &body_assets(assets, i), limits)
                    .map_err(|e| at_body(e, i))
            }),
        }
    }

    fn check_assets(&self, order: &DesignOrder, assets: &Assets) -> Result<(), FieldError> {
        match order {
            DesignOrder::One(job) => self.check_job_assets(job, assets),
            DesignOrder::Graded(bodies) => bodies.iter().enumerate().try_for_each(|(i, b)| {
                self.check_job_assets(&b.job, &body_assets(assets, i))
                    .map_err(|e| at_body(e, i))
            }),
        }
    }

    fn run(
        &self,
        order: &DesignOrder,
        assets: &Assets,
        ctx: &mut JobContext,
    ) -> Result<JobOutput, JobError> {
        let files = asset_files(assets, ctx)?;
        let bodies = match order {
            DesignOrder::One(job) => {
                // Go on from the last finished iteration, if an earlier attempt got that far.
                let resume = ctx
                    .checkpoint
                    .as_ref()
                    .and_then(|cp| RunCheckpoint::decode(&cp.data));
                if resume.is_some() {
                    ctx.last_checkpoint();
                }
                let events = Events {
                    base: 0,
                    index: 0,
                    count: 1,
                    name: None,
                };
                let (outputs, _, summary) =
                    self.design_job(job, &files, ctx, resume, Some(events))?;
                return Ok(JobOutput {
                    warnings: admissibility_warnings(&outputs.admissibility),
                    artifacts: outputs.files.into_iter().map(Artifact::from).collect(),
                    summary,
                });
            }
            DesignOrder::Graded(bodies) => bodies,
        };
        // A restart goes on in the body it stopped in; the bodies before it are designed again silently
        // (deterministically the same) for their files.
        let resume = ctx
            .checkpoint
            .as_ref()
            .and_then(|cp| unwrap_batch_checkpoint(&cp.data));
        if resume.is_some() {
            ctx.last_checkpoint();
        }
        let mut resume = resume;
        let (mut artifacts, mut summaries, mut warnings) = (Vec::new(), Vec::new(), Vec::new());
        let mut base = 0u64;
        let mut all_admissible = true;
        for (i, b) in bodies.iter().enumerate() {
            let (silent, from) = match &resume {
                Some((k, _, _)) if i < *k => (true, None),
                Some((k, kb, _)) if i == *k => {
                    base = *kb;
                    (false, resume.take().map(|(_, _, cp)| cp))
                }
                _ => (false, None),
            };
            let events = (!silent).then(|| Events {
                base,
                index: i,
                count: bodies.len(),
                name: Some(b.name.clone()),
            });
            let (outputs, iterations, mut summary) = self
                .design_job(&b.job, &files, ctx, from, events)
                .map_err(|e| match e {
                    JobError::Failed(m) => {
                        JobError::Failed(format!("bodies[{i}] ('{}'): {m}", b.name))
                    }
                    JobError::Invalid { field, message } => JobError::Invalid {
                        field: batch_key(&field, i),
                        message: format!("bodies[{i}] ('{}'): {message}", b.name),
                    },
                    other => other,
                })?;
            base += iterations as u64;
            all_admissible &= outputs.admissibility.admissible;
            for mut w in admissibility_warnings(&outputs.admissibility) {
                w["body"] = json!(b.name);
                warnings.push(w);
            }
            summary["body"] = json!(b.name);
            summaries.push(summary);
            artifacts.extend(outputs.files.into_iter().map(|f| {
                let mut a = Artifact::from(f);
                a.name = format!("{}.{}", b.name, a.name);
                a
            }));
        }
        let summary = json!({"bodies": summaries, "admissible": all_admissible});
        artifacts.push(Artifact {
            name: "batch.json".into(),
            content_type: "application/json".into(),
            data: crate::simulate::json_text::json_text(&summary),
        });
        Ok(JobOutput {
            artifacts,
            summary,
            warnings,
        })
    }
}

/// A `design` job's spec: one body (`body`), or a graded order (`bodies`, [`BatchBody`]).
#[derive(Clone, Debug, PartialEq)]
pub enum DesignOrder {
    /// A one-body design job.
    One(DesignJob),
    /// A graded order: one job per named body.
    Graded(Vec<BatchBody>),
}

impl DesignOrder {
    /// Each body's job with its index in `bodies` (`None` for a one-body job).
    fn jobs(&self) -> Vec<(Option<usize>, &DesignJob)> {
        match self {
            DesignOrder::One(job) => vec![(None, job)],
            DesignOrder::Graded(bodies) => bodies
                .iter()
                .enumerate()
                .map(|(i, b)| (Some(i), &b.job))
                .collect(),
        }
    }
}
