//! `skintight design JOB.json --out DIR`: optimizes the garment's patterns for the job's objectives.
//!
//! Reads the design job (docs/DESIGN_JOB.md: a scene plus `objectives`, `regularizers`, `optimizer`; file paths
//! relative to the job file), solves the initial garment, optimizes the pattern boundaries and writes the
//! simulate outputs of the best design (`result.json` with `initial_objective`, `final_objective`,
//! `iterations`, `remeshes`, `optimizer` added; `garment.glb`, `garment-pressure.glb`, `body.glb`, the pattern files, `report.html`) plus
//! `history.json`. One line per design iteration goes to standard error unless
//! `--quiet`; the last line on standard output is a one-line JSON summary.
//!
//! A graded order (`bodies: [{"name": …, <body>}, …]` in place of `body`, [`crate::design::batch_from_json`])
//! is checked whole first (a bad body is named by its index), then designed body by body into
//! `DIR/NAME/`, one summary line per body and the order's line last (also `DIR/batch.json`); a body whose
//! design fails does not stop the others (exit 1 at the end).
//!
//! Exit status: 0 done (whatever stopped the optimizer: the best design is written) and the final garment is
//! admissible; 4 done, but the final garment is beyond its fabric's limits or its final equilibrium stopped
//! short of `solver.tolerance` (`not_converged`) (`garment.fabric.limits`: the last
//! line on standard error says what and where, `result.json` lists the violations); 2 unusable job;
//! 1 failure.

use std::ops::ControlFlow;
use std::path::PathBuf;

use clap::Args;
use serde_json::json;

use super::CliError;
use super::simulate::{admit, cli_error, write_all};
use crate::design::{
    BatchBody, DesignJob, batch_from_file, batch_key, design_artifacts, design_summary,
    prepare_design, run_design,
};
use crate::scene::{FileResolver, SceneError};
use crate::simulate::ArtifactFile;
use crate::simulate::admissibility::verdict_line;

/// Arguments of `design`.
#[derive(Debug, Args)]
pub struct DesignArgs {
    /// The design job (JSON, see docs/DESIGN_JOB.md).
    pub job: PathBuf,
    /// Output folder (created if missing).
    #[arg(long)]
    pub out: PathBuf,
    /// Do not print a line per design iteration.
    #[arg(long)]
    pub quiet: bool,
}

/// How a design command ended: every garment admissible, some not (exit 4), or a body of a graded
/// order failed (exit 1, after the other bodies were designed).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DesignExit {
    /// Done; every final garment admissible.
    Admissible,
    /// Done; a final garment is not admissible (results written).
    NotAdmissible,
    /// A graded order: a body failed (its error in `batch.json`); the others were designed.
    BodyFailed,
}

/// Runs `design`: one body, or every body of a graded order (`bodies`, [`design_batch`]).
pub fn design(args: DesignArgs) -> Result<DesignExit, CliError> {
    if let Some(bodies) = batch_from_file(&args.job).map_err(|e| CliError::Input(e.to_string()))? {
        return design_batch(&args, &bodies);
    }
    let job = DesignJob::from_file(&args.job).map_err(|e| CliError::Input(e.to_string()))?;
    let resolver = FileResolver::for_scene_file(&args.job);
    admit(
        &job.scene(),
        &resolver,
        job.optimizer.max_iterations as f64 + 1.0,
    )?;
    let (summary, admissible) = design_one(&job, &resolver, &args.out, args.quiet, "design")?;
    println!("{summary}");
    Ok(if admissible {
        DesignExit::Admissible
    } else {
        DesignExit::NotAdmissible
    })
}

/// A graded order: every body admitted first (a body at fault is named by its index and name, before
/// any design runs), then designed in turn into `--out/NAME/`; a body whose design fails does not stop
/// the others. Standard output: one summary line per body (with `"body"`), then the order's line
/// `{"bodies": [...], "admissible": …, "failed": […]}`, also written to `--out/batch.json`.
fn design_batch(args: &DesignArgs, bodies: &[BatchBody]) -> Result<DesignExit, CliError> {
    let resolver = FileResolver::for_scene_file(&args.job);
    let at = |i: usize, b: &BatchBody, e: CliError| {
        let line = format!("bodies[{i}] ('{}'): {e}", b.name);
        match e {
            CliError::Input(_) => CliError::Input(line),
            CliError::Failed(_) => CliError::Failed(line),
        }
    };
    for (i, b) in bodies.iter().enumerate() {
        let scene = b.job.scene();
        scene.body_size(&resolver).map_err(|e| {
            CliError::Input(SceneError::new(batch_key(&e.key, i), e.message).to_string())
        })?;
        admit(
            &scene,
            &resolver,
            b.job.optimizer.max_iterations as f64 + 1.0,
        )
        .map_err(|e| at(i, b, e))?;
    }
    let mut summaries = Vec::with_capacity(bodies.len());
    let (mut all_admissible, mut failed) = (true, Vec::new());
    for (i, b) in bodies.iter().enumerate() {
        let out = args.out.join(&b.name);
        let label = format!("design [{}]", b.name);
        let mut summary = match design_one(&b.job, &resolver, &out, args.quiet, &label) {
            Ok((summary, admissible)) => {
                all_admissible &= admissible;
                summary
            }
            Err(e) => {
                let e = at(i, b, e);
                eprintln!("{label}: error: {e}");
                failed.push(b.name.clone());
                json!({"error": e.to_string(), "out": out.display().to_string()})
            }
        };
        summary["body"] = json!(b.name);
        println!("{summary}");
        summaries.push(summary);
    }
    let order = json!({
        "bodies": summaries,
        "admissible": all_admissible && failed.is_empty(),
        "failed": failed,
    });
    write_all(
        &args.out,
        &[ArtifactFile {
            name: "batch.json",
            content_type: "application/json",
            data: crate::simulate::json_text::json_text(&order),
        }],
    )?;
    println!("{order}");
    if !failed.is_empty() {
        eprintln!(
            "design: {} of {} bodies failed: {}",
            failed.len(),
            bodies.len(),
            failed.join(", ")
        );
        return Ok(DesignExit::BodyFailed);
    }
    Ok(if all_admissible {
        DesignExit::Admissible
    } else {
        DesignExit::NotAdmissible
    })
}

/// Designs `job` and writes its files into `out`; its summary line (not printed) and whether the final
/// garment is admissible. Progress lines go to standard error prefixed by `label` unless `quiet`.
fn design_one(
    job: &DesignJob,
    resolver: &FileResolver,
    out: &std::path::Path,
    quiet: bool,
    label: &str,
) -> Result<(serde_json::Value, bool), CliError> {
    let mut design = prepare_design(job, resolver).map_err(cli_error)?;
    // A graded order's iteration lines name their body.
    let prefix = if label == "design" {
        String::new()
    } else {
        format!("{label} ")
    };
    if !quiet {
        eprintln!(
            "{label}: {} pattern vertices, {} boundary parameters, {} cloth triangles, {} unknowns",
            design.problem.mesh().num_pattern_vertices(),
            design.map.num_parameters(),
            design.sim.system.triangles().len(),
            design.sim.system.num_dofs()
        );
    }
    let result = run_design(&mut design, &mut |it| {
        if !quiet {
            let terms: Vec<String> = it
                .terms
                .iter()
                .map(|(n, v)| format!("{n} {v:.4e}"))
                .collect();
            eprintln!(
                "{prefix}iteration {:>3}: objective {:.6e} ({}), |dT/dp| {:.3e}, stretch {:.3}–{:.3}, pattern quality {:.3}, {} remeshes, {} solves, {:.1} s",
                it.iteration,
                it.objective,
                terms.join(", "),
                it.gradient_norm,
                it.min_stretch,
                it.max_stretch,
                it.min_pattern_quality,
                it.remeshes,
                it.evaluations,
                it.seconds
            );
        }
        ControlFlow::Continue(())
    }, &|| false)
    .map_err(cli_error)?;
    let outputs = design_artifacts(&design, &result).map_err(cli_error)?;
    write_all(out, &outputs.files)?;
    let mut summary = design_summary(&result, &outputs.admissibility);
    summary["out"] = json!(out.display().to_string());
    if !outputs.admissibility.admissible {
        eprintln!("{label}: {}", verdict_line(&outputs.admissibility));
    }
    Ok((summary, outputs.admissibility.admissible))
}
