//! `skintight simulate SCENE.json --out DIR`: the garment worn on the body at equilibrium.
//!
//! Reads the scene (docs/SCENE.md; mesh paths relative to the scene file), builds body and garment, solves
//! for the equilibrium and writes `DIR/result.json`, `DIR/garment.glb`, `DIR/garment-pressure.glb`, `DIR/body.glb`, the pattern files
//! and `DIR/report.html` (docs/OUTPUTS.md). One line per Newton iteration goes to standard error unless `--quiet`; the last line
//! on standard output is a one-line JSON summary.
//!
//! Exit status: 0 converged to an admissible garment; 4 converged, but the garment is not admissible (beyond
//! `garment.fabric.limits`: the last line on standard error says what and where, `result.json` lists the
//! violations); 3 not converged (iteration or time limit — the results are still written); 2 unusable scene;
//! 1 failure (e.g. the garment would invert the body).

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

use clap::Args;
use serde_json::json;

use super::CliError;
use crate::scene::{Estimate, FileResolver, Limits, PathResolver, Scene};
use crate::simulate::admissibility::verdict_line;
use crate::simulate::{SimulateError, SimulationResult, artifacts, prepare, run};

/// Arguments of `simulate`.
#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// The scene description (JSON, see docs/SCENE.md).
    pub scene: PathBuf,
    /// Output folder (created if missing).
    #[arg(long)]
    pub out: PathBuf,
    /// Do not print a line per Newton iteration.
    #[arg(long)]
    pub quiet: bool,
}

/// What `simulate` ended with, for the exit status.
pub enum SimulateExit {
    /// The solve converged.
    Converged,
    /// The solve stopped at a limit; results were written.
    NotConverged,
    /// The solve converged to a garment beyond its fabric's limits; results were written.
    NotAdmissible,
}

pub(crate) fn cli_error(e: SimulateError) -> CliError {
    if e.input {
        CliError::Input(e.to_string())
    } else {
        CliError::Failed(e.to_string())
    }
}

/// Writes the artifacts of a finished simulation into `dir`.
pub(crate) fn write_all(
    dir: &Path,
    files: &[crate::simulate::ArtifactFile],
) -> Result<(), CliError> {
    std::fs::create_dir_all(dir).map_err(|e| {
        CliError::Input(format!(
            "cannot create the output folder {}: {e}",
            dir.display()
        ))
    })?;
    for f in files {
        let path = dir.join(f.name);
        std::fs::write(&path, &f.data)
            .map_err(|e| CliError::Failed(format!("cannot write {}: {e}", path.display())))?;
    }
    Ok(())
}

/// Admission costing, as the service does it (with its default limits, `config/default.toml`): a scene
/// whose estimated size exceeds them is refused before anything is built, naming the field to change.
pub(crate) fn admit(
    scene: &Scene,
    resolver: &dyn PathResolver,
    equilibria: f64,
) -> Result<(), CliError> {
    let size = scene
        .body_size(resolver)
        .map_err(|e| CliError::Input(e.to_string()))?;
    Estimate::of_scene(scene, &size, equilibria)
        .check(&Limits::default())
        .map_err(|e| CliError::Input(e.to_string()))
}

/// Runs `simulate`.
pub fn simulate(args: SimulateArgs) -> Result<SimulateExit, CliError> {
    let scene = Scene::from_file(&args.scene).map_err(|e| CliError::Input(e.to_string()))?;
    let resolver = FileResolver::for_scene_file(&args.scene);
    admit(&scene, &resolver, 1.0)?;
    let mut sim = prepare(&scene, &resolver).map_err(cli_error)?;
    if !args.quiet {
        eprintln!(
            "simulate: {} cloth vertices, {} cloth triangles, {} body tetrahedra, {} unknowns",
            sim.system.num_cloth_vertices(),
            sim.system.triangles().len(),
            sim.system.tets().len(),
            sim.system.num_dofs()
        );
    }
    let quiet = args.quiet;
    let report = run(&mut sim, &mut |info| {
        if !quiet {
            eprintln!(
                "iteration {:>3}: energy {:.9e} J, residual {:.3e}, damping {:.2e} N/m, {:.2} s",
                info.iteration, info.energy, info.residual, info.damping, info.elapsed_s
            );
        }
        ControlFlow::Continue(())
    })
    .map_err(cli_error)?;
    let result = SimulationResult::new(&sim, &report).map_err(cli_error)?;
    let files = artifacts(&sim, &result).map_err(cli_error)?;
    write_all(&args.out, &files)?;
    let mut summary = result.summary();
    summary["out"] = json!(args.out.display().to_string());
    println!("{summary}");
    if result.converged {
        if result.admissibility.admissible {
            Ok(SimulateExit::Converged)
        } else {
            eprintln!("simulate: {}", verdict_line(&result.admissibility));
            Ok(SimulateExit::NotAdmissible)
        }
    } else {
        eprintln!(
            "simulate: did not converge ({:?} after {} iterations, residual {:.3e}); results written to {}",
            result.stop_reason,
            result.newton_iterations,
            result.residual,
            args.out.display()
        );
        Ok(SimulateExit::NotConverged)
    }
}
