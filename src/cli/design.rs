//! `skintight design JOB.json --out DIR`: optimizes the garment's patterns for the job's objectives.
//!
//! Reads the design job (docs/DESIGN_JOB.md: a scene plus `objectives`, `regularizers`, `optimizer`; file paths
//! relative to the job file), solves the initial garment, optimizes the pattern boundaries and writes the
//! simulate outputs of the best design (`result.json` with `initial_objective`, `final_objective`,
//! `iterations`, `remeshes`, `optimizer` added; `garment.glb`, `garment-pressure.glb`, `body.glb`, the pattern files, `report.html`) plus
//! `history.json`. One line per design iteration goes to standard error unless
//! `--quiet`; the last line on standard output is a one-line JSON summary.
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
use crate::design::{DesignJob, design_artifacts, design_summary, prepare_design, run_design};
use crate::scene::FileResolver;
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

/// Runs `design`; `Ok(false)` when the final garment is not admissible.
pub fn design(args: DesignArgs) -> Result<bool, CliError> {
    let job = DesignJob::from_file(&args.job).map_err(|e| CliError::Input(e.to_string()))?;
    let resolver = FileResolver::for_scene_file(&args.job);
    admit(
        &job.scene(),
        &resolver,
        job.optimizer.max_iterations as f64 + 1.0,
    )?;
    let mut design = prepare_design(&job, &resolver).map_err(cli_error)?;
    if !args.quiet {
        eprintln!(
            "design: {} pattern vertices, {} boundary parameters, {} cloth triangles, {} unknowns",
            design.problem.mesh().num_pattern_vertices(),
            design.map.num_parameters(),
            design.sim.system.triangles().len(),
            design.sim.system.num_dofs()
        );
    }
    let quiet = args.quiet;
    let result = run_design(&mut design, &mut |it| {
        if !quiet {
            let terms: Vec<String> = it
                .terms
                .iter()
                .map(|(n, v)| format!("{n} {v:.4e}"))
                .collect();
            eprintln!(
                "iteration {:>3}: objective {:.6e} ({}), |dT/dp| {:.3e}, stretch {:.3}–{:.3}, pattern quality {:.3}, {} remeshes, {} solves, {:.1} s",
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
    write_all(&args.out, &outputs.files)?;
    let mut summary = design_summary(&result, &outputs.admissibility);
    summary["out"] = json!(args.out.display().to_string());
    println!("{summary}");
    if !outputs.admissibility.admissible {
        eprintln!("design: {}", verdict_line(&outputs.admissibility));
    }
    Ok(outputs.admissibility.admissible)
}
