//! `skintight knit …`: yarn-level knitwear (crates/knit).
//!
//! - `skintight knit cell PATTERN_DIR --strain sx,sa,sy` solves one periodic cell of the pattern in
//!   `PATTERN_DIR/pattern.pyp` at the in-plane strain (`sx`, `sy`: stretches minus one, `sa`: cosine of the
//!   angle between the material axes) and, when the folder has the published `data.npy`/`axes.txt`,
//!   compares with the published displacement; prints the JSON report (`normalized_rms`,
//!   `newton_iterations`, `residual`, `seconds`, …; see `skintight_knit::cell_check::CellReport`).
//!   `--bending-factor`, `--contact-factor`, `--contact-distance` override the yarn parameters
//!   (`skintight_knit::yarn_params`).
//!   Exit status: 0 converged, 3 not converged (report still printed), 2 bad input (pattern, strain outside
//!   the sampled range), 1 failure.
//! - `skintight knit tile PATTERN --cells nx,ny --out PATCH.obj` tiles a pattern (`pattern.pyp` or its
//!   folder) into `nx × ny` cells of continuous yarns and writes them as OBJ polylines; prints a JSON summary.
//! - `skintight knit simulate-yarn SCENE.json --out DIR` runs a yarn-level simulation scene
//!   (`crate::knit`: a tiled patch hanging, stretched, sheared or draped over a sphere,
//!   backward Euler) and writes the frame sequence (`skintight_knit::frame_sequence`), `yarns.obj` and
//!   `yarns.glb` of the last frame and `result.json` into `DIR`; prints `result.json` on one line. The scene's
//!   `pattern` is relative to the scene file, or a shared pattern name looked up in `--yarns-dir` (default:
//!   `../shared/data/yarns` beside the working directory). One line per frame goes to stderr with `--progress`.
//!   The run keeps `DIR/checkpoint.json` while it goes (`crate::knit::YarnRunCheckpoint`); `--resume`
//!   continues an interrupted run from it.
//!   Exit status: 0 done, 3 done with time steps whose Newton solve stopped early, 2 bad input, 1 failure.
//! - `skintight knit stretch-test --knit stockinette|rib --direction x|y --out DIR` pulls a yarn-level patch
//!   of the knit's shared pattern (`stock_9`, `rib_9`, looked up in `--yarns-dir`) in the geometry of the
//!   measured acrylic sample of Singal et al. 2024 (`--data-dir`, default the vendored
//!   `crates/knit/data/stitch_by_stitch`) and writes `simulated.csv` (the equilibria, mm and N),
//!   `comparison.csv` (measured and simulated force at the measured extensions), `stretch_test.svg` and
//!   `result.json` (`crate::knit::StretchTestResult`: the comparison and the least-squares Young's modulus,
//!   the calibration); prints `result.json` on one line. `--young-modulus`, `--bending-factor`,
//!   `--contact-stiffness`, `--yarn-radius`, `--cells-across`, `--cells-along`, `--steps` set the model.
//!   Exit status: 0 done, 3 done with equilibria whose Newton solve stopped early, 2 bad input, 1 failure.
//! - `skintight knit compare FIRST_DIR SECOND_DIR` compares two frame sequences of the same patch (e.g. the
//!   yarn-level run and the homogenized one of one scene) frame by frame, matched by time: prints JSON with
//!   `patch_size_m` and `frames: [{frame, time_s, mean_error_m, max_error_m}]`
//!   (`skintight_knit::sequence_compare`). Exit status: 0 compared, 2 bad input (unreadable or mismatched
//!   sequences, no overlapping times).
//! - `skintight knit homogenize SEQUENCE_DIR… --out DIR` homogenizes one patch's sequences
//!   (`skintight_homogenize::homogenization`: the mesh around frame 0, Y2V of every frame, the sample-by-
//!   sample fit through the harmonic ranks, the error on every pose) and writes `DIR/material.json`
//!   (`pattern`, `yarn_dofs`, `mesh_dofs`, `elements`, `voxel_m`, `patch_size_m`, `fit_seconds`,
//!   `gauss_newton_iterations`, `frames: [{sequence, frame, time_s, training, mean_error_m, …}]`, the
//!   fit's `stages`) and `DIR/mesh.vtu` (`gamma_s`, `gamma_v` in Pa as cell data); prints a JSON summary.
//!   `--train-every K` fits every K-th pose and holds the others out; `--voxel M`, `--ranks 1,10,30`,
//!   `--per-element`, `--progress` (one JSON line per Gauss-Newton iteration to stderr).
//!   Exit status: 0 done, 2 bad input (unreadable or mismatched sequences, bad settings), 1 failure.

use std::path::{Path, PathBuf};

use clap::{Args, Subcommand};
use serde_json::json;
use skintight_knit::PeriodicPattern;
use skintight_knit::cell_check::{CellCheckError, cell_check};
use skintight_knit::newton::NewtonParams;
use skintight_knit::tile::tile;
use skintight_knit::yarn_params::YarnParams;

use super::CliError;

/// Knit subcommands.
#[derive(Debug, Subcommand)]
pub enum KnitCommand {
    /// Solve one periodic cell at a strain and compare with the published displacement (JSON report).
    #[command(after_help = super::EXIT_KNIT)]
    Cell(CellArgs),
    /// Tile a periodic pattern into a patch of continuous yarns (OBJ polylines).
    #[command(after_help = super::EXIT_DONE)]
    Tile(TileArgs),
    /// Simulate a patch of yarns in time (hang, stretch, shear, drape) and write the frame sequence.
    #[command(after_help = super::EXIT_KNIT)]
    SimulateYarn(SimulateYarnArgs),
    /// Pull a yarn-level patch in a measured sample's geometry and compare its force–extension curve with
    /// the measured one (CSV, SVG, result.json).
    #[command(after_help = super::EXIT_KNIT)]
    StretchTest(StretchTestArgs),
    /// Compare two frame sequences of one patch frame by frame (matched by time); prints JSON.
    ///
    /// Exit status: 0 compared, 2 bad input.
    Compare(CompareArgs),
    /// Homogenize yarn-level sequences of one patch into a tetrahedral mesh with a fitted material
    /// (material.json, mesh.vtu).
    #[command(after_help = super::EXIT_DONE)]
    Homogenize(HomogenizeArgs),
    /// Run a yarn scene on a homogenized material (`material` in the scene) by projective dynamics and
    /// write the yarns' frame sequence through V2Y.
    #[command(after_help = super::EXIT_DONE)]
    Simulate(SimulateYarnArgs),
}

/// Arguments of `knit homogenize`.
#[derive(Debug, Args)]
pub struct HomogenizeArgs {
    /// The sequences' folders (`knit simulate-yarn` outputs of one patch).
    #[arg(required = true)]
    pub sequences: Vec<PathBuf>,
    /// Output folder (created).
    #[arg(long)]
    pub out: PathBuf,
    /// Fit every K-th pose (frames 2, 3, … of each sequence in order); the others are held out.
    #[arg(long, default_value_t = 1)]
    pub train_every: usize,
    /// Voxel edge (m); default the yarn diameter.
    #[arg(long)]
    pub voxel: Option<f64>,
    /// The harmonic ranks of the fit's schedule, increasing (e.g. `1,10,30`).
    #[arg(long, default_value = "1,10,30")]
    pub ranks: String,
    /// Finish with every element's own material (2 parameters per element).
    #[arg(long)]
    pub per_element: bool,
    /// Print one JSON line per Gauss-Newton iteration to stderr.
    #[arg(long)]
    pub progress: bool,
}

/// Arguments of `knit stretch-test`.
#[derive(Debug, Args)]
pub struct StretchTestArgs {
    /// The knit: `stockinette` or `rib`.
    #[arg(long)]
    pub knit: String,
    /// The pull: `x` (along the courses) or `y` (along the wales).
    #[arg(long)]
    pub direction: String,
    /// Output folder (created).
    #[arg(long)]
    pub out: PathBuf,
    /// Folder of the measured curves (default: the vendored `crates/knit/data/stitch_by_stitch`).
    #[arg(long)]
    pub data_dir: Option<PathBuf>,
    /// Folder of the shared yarn patterns (default `../shared/data/yarns`).
    #[arg(long)]
    pub yarns_dir: Option<PathBuf>,
    /// Young's modulus of the yarn (Pa; default 1e6, the generator's). Every stiffness scales with it.
    #[arg(long)]
    pub young_modulus: Option<f64>,
    /// Bending and twisting stiffness relative to a solid rod (default 1).
    #[arg(long)]
    pub bending_factor: Option<f64>,
    /// Contact stiffness k_c (J/m²) at the pattern's scale and the default modulus (default 200); it scales
    /// with `--young-modulus`.
    #[arg(long)]
    pub contact_stiffness: Option<f64>,
    /// The model yarn radius (m; default 0.429e-3, the stockinette's measured stitch length): the pattern is
    /// scaled to it.
    #[arg(long)]
    pub yarn_radius: Option<f64>,
    /// Cells across the pull (default 2).
    #[arg(long)]
    pub cells_across: Option<usize>,
    /// Cells along the pull (default: the sample's clamp distance in scaled cells).
    #[arg(long)]
    pub cells_along: Option<usize>,
    /// Increments of the clamp displacement (default 8).
    #[arg(long)]
    pub steps: Option<usize>,
    /// Most Newton iterations of each equilibrium (default 300).
    #[arg(long)]
    pub max_iterations: Option<usize>,
    /// Print one JSON line per equilibrium to stderr.
    #[arg(long)]
    pub progress: bool,
}

/// Arguments of `knit compare`.
#[derive(Debug, Args)]
pub struct CompareArgs {
    /// The first sequence's folder (its frames are the ones reported; e.g. the yarn-level run).
    pub first: PathBuf,
    /// The second sequence's folder (interpolated in time to the first's frames).
    pub second: PathBuf,
}

/// Arguments of `knit simulate-yarn`.
#[derive(Debug, Args)]
pub struct SimulateYarnArgs {
    /// The scene JSON (`crate::knit::YarnScene`).
    pub scene: PathBuf,
    /// Output folder (created).
    #[arg(long)]
    pub out: PathBuf,
    /// Folder of the shared yarn patterns, for scenes that name a pattern (`stock_9`, …).
    #[arg(long)]
    pub yarns_dir: Option<PathBuf>,
    /// Print one JSON line per written frame (and every few seconds of the start's relaxation) to stderr.
    #[arg(long)]
    pub progress: bool,
    /// Continue the run from `OUT/checkpoint.json` (written during the run; kept when it is interrupted)
    /// instead of starting again; without a checkpoint the run starts from the beginning.
    #[arg(long)]
    pub resume: bool,
}

/// Arguments of `knit cell`.
#[derive(Debug, Args)]
pub struct CellArgs {
    /// Folder with `pattern.pyp` (and optionally the published `axes.txt` and `data.npy`).
    pub pattern_dir: PathBuf,
    /// The strain `sx,sa,sy`.
    #[arg(long, allow_hyphen_values = true)]
    pub strain: String,
    /// Yarn bending and twisting stiffness relative to a solid rod (default: `YarnParams::default()`).
    #[arg(long)]
    pub bending_factor: Option<f64>,
    /// Contact stiffness factor `c` in `k_c = c E r` (default: `YarnParams::default()`).
    #[arg(long)]
    pub contact_factor: Option<f64>,
    /// Contact distance in yarn diameters (default: `YarnParams::default()`).
    #[arg(long)]
    pub contact_distance: Option<f64>,
}

/// Arguments of `knit tile`.
#[derive(Debug, Args)]
pub struct TileArgs {
    /// A `.pyp` file or a folder holding `pattern.pyp`.
    pub pattern: PathBuf,
    /// Cells `nx,ny`.
    #[arg(long, default_value = "4,4")]
    pub cells: String,
    /// Output OBJ file.
    #[arg(long)]
    pub out: PathBuf,
}

/// Runs a knit subcommand; `Ok(false)` when a cell solve did not converge.
pub fn run(cmd: KnitCommand) -> Result<bool, CliError> {
    match cmd {
        KnitCommand::Cell(args) => cell(&args),
        KnitCommand::Tile(args) => tile_patch(&args).map(|()| true),
        KnitCommand::SimulateYarn(args) => simulate_yarn(&args),
        KnitCommand::StretchTest(args) => stretch_test(&args),
        KnitCommand::Compare(args) => compare(&args).map(|()| true),
        KnitCommand::Homogenize(args) => homogenize(&args).map(|()| true),
        KnitCommand::Simulate(args) => simulate_homogenized(&args).map(|()| true),
    }
}

fn homogenize(args: &HomogenizeArgs) -> Result<(), CliError> {
    use skintight_homogenize::homogenization::HomogenizationParams;
    let ranks = args
        .ranks
        .split(',')
        .map(|r| r.trim().parse::<usize>())
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| CliError::Input(format!("--ranks {:?}: {e} (e.g. 1,10,30)", args.ranks)))?;
    let mut params = HomogenizationParams {
        ranks,
        per_element: args.per_element,
        train_every: args.train_every,
        ..HomogenizationParams::default()
    };
    params.mesh.voxel_m = args.voxel;
    let progress = args.progress;
    let summary = crate::knit::homogenize_sequences(&args.sequences, &args.out, &params, |p| {
        if progress {
            eprintln!("{}", serde_json::to_string(p).unwrap_or_default());
        }
        std::ops::ControlFlow::Continue(())
    })
    .map_err(homogenize_error)?;
    println!("{summary}");
    Ok(())
}

fn simulate_homogenized(args: &SimulateYarnArgs) -> Result<(), CliError> {
    if args.resume {
        return Err(CliError::Input(
            "--resume: `knit simulate` has no checkpoints yet; run it again".into(),
        ));
    }
    let (scene, _) = crate::knit::read_scene(&args.scene).map_err(homogenize_error)?;
    let pattern = scene_pattern(&scene, &args.scene, args.yarns_dir.as_deref())?;
    let trace = args.progress;
    let result = crate::knit::simulate_homogenized(&args.scene, &pattern, &args.out, |frame, t| {
        if trace {
            eprintln!("{}", json!({"frame": frame, "time_s": t}));
        }
    })
    .map_err(homogenize_error)?;
    println!(
        "{}",
        serde_json::to_string(&result).map_err(|e| CliError::Failed(e.to_string()))?
    );
    Ok(())
}

fn homogenize_error(e: crate::knit::KnitHomogenizeError) -> CliError {
    match e {
        crate::knit::KnitHomogenizeError::Input(m) => CliError::Input(m),
        other => CliError::Failed(other.to_string()),
    }
}

fn compare(args: &CompareArgs) -> Result<(), CliError> {
    let report = skintight_knit::sequence_compare::compare_sequences(&args.first, &args.second)
        .map_err(|e| CliError::Input(e.to_string()))?;
    println!(
        "{}",
        serde_json::to_string(&report).map_err(|e| CliError::Failed(e.to_string()))?
    );
    Ok(())
}

fn parse_numbers<const N: usize>(text: &str, what: &str) -> Result<[f64; N], CliError> {
    let values: Vec<f64> = text
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| {
            CliError::Input(format!(
                "--{what} `{text}` is not {N} comma-separated numbers"
            ))
        })?;
    let array: [f64; N] = values.try_into().map_err(|_| {
        CliError::Input(format!(
            "--{what} `{text}` needs exactly {N} comma-separated numbers"
        ))
    })?;
    if array.iter().any(|v| !v.is_finite()) {
        return Err(CliError::Input(format!(
            "--{what} `{text}` has a non-finite number"
        )));
    }
    Ok(array)
}

fn cell(args: &CellArgs) -> Result<bool, CliError> {
    let strain: [f64; 3] = parse_numbers(&args.strain, "strain")?;
    let report = cell_check(
        &args.pattern_dir,
        strain,
        &YarnParams::default(),
        &NewtonParams::default(),
    )
    .map_err(|e| match e {
        CellCheckError::Newton(_) => CliError::Failed(e.to_string()),
        other => CliError::Input(other.to_string()),
    })?;
    let line = serde_json::to_string(&report).map_err(|e| CliError::Failed(e.to_string()))?;
    println!("{line}");
    Ok(report.converged)
}

fn tile_patch(args: &TileArgs) -> Result<(), CliError> {
    let [nx, ny]: [f64; 2] = parse_numbers(&args.cells, "cells")?;
    if nx < 1.0 || ny < 1.0 || nx.fract() != 0.0 || ny.fract() != 0.0 {
        return Err(CliError::Input(format!(
            "--cells `{}` must be two whole numbers ≥ 1",
            args.cells
        )));
    }
    let path = if args.pattern.is_dir() {
        args.pattern.join("pattern.pyp")
    } else {
        args.pattern.clone()
    };
    let pattern = PeriodicPattern::read(&path).map_err(|e| CliError::Input(e.to_string()))?;
    let patch =
        tile(&pattern, nx as usize, ny as usize).map_err(|e| CliError::Input(e.to_string()))?;
    if let Some(dir) = args.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .map_err(|e| CliError::Failed(format!("cannot create {}: {e}", dir.display())))?;
    }
    patch
        .write_obj(&args.out)
        .map_err(|e| CliError::Failed(format!("cannot write {}: {e}", out_name(&args.out))))?;
    println!(
        "{}",
        json!({
            "pattern": path.display().to_string(),
            "cells": [nx as usize, ny as usize],
            "yarns": patch.yarns.len(),
            "vertices": patch.vertex_count(),
            "radius_m": patch.radius,
            "out": args.out.display().to_string(),
        })
    );
    Ok(())
}

fn simulate_yarn(args: &SimulateYarnArgs) -> Result<bool, CliError> {
    use crate::knit::{YarnRunParams, YarnScene, YarnSceneError, run};
    let scene = YarnScene::from_file(&args.scene).map_err(|e| CliError::Input(e.to_string()))?;
    let pattern = scene_pattern(&scene, &args.scene, args.yarns_dir.as_deref())?;
    let trace = args.progress;
    let params = YarnRunParams {
        resume: args.resume,
        ..YarnRunParams::default()
    };
    let result = run(&scene, &pattern, &args.out, &params, |p| {
        if trace {
            eprintln!("{}", serde_json::to_string(p).unwrap_or_default());
        }
        std::ops::ControlFlow::Continue(())
    })
    .map_err(|e| match e {
        YarnSceneError::Input(m) => CliError::Input(m),
        other => CliError::Failed(other.to_string()),
    })?;
    let line = serde_json::to_string(&result).map_err(|e| CliError::Failed(e.to_string()))?;
    println!("{line}");
    Ok(result.unconverged_steps == 0)
}

fn stretch_test(args: &StretchTestArgs) -> Result<bool, CliError> {
    use crate::knit::{
        MeasuredKnit, PullDirection, StretchTestSpec, YarnSceneError, comparison_csv,
        measured_file, run_stretch_test, simulated_csv, stretch_svg,
    };
    use skintight_knit::measured_stretch::{MeasuredStretch, vendored_dir};
    let knit = match args.knit.as_str() {
        "stockinette" => MeasuredKnit::Stockinette,
        "rib" => MeasuredKnit::Rib,
        other => {
            return Err(CliError::Input(format!(
                "--knit `{other}` is not `stockinette` or `rib`"
            )));
        }
    };
    let direction = match args.direction.as_str() {
        "x" => PullDirection::X,
        "y" => PullDirection::Y,
        other => {
            return Err(CliError::Input(format!(
                "--direction `{other}` is not `x` or `y`"
            )));
        }
    };
    let mut spec = StretchTestSpec::new(direction);
    if let Some(kc) = args.contact_stiffness {
        if !(kc.is_finite() && kc > 0.0) {
            return Err(CliError::Input(format!(
                "--contact-stiffness {kc} J/m² must be > 0"
            )));
        }
        // k_c = c E r at the patterns' 1 mm radius and the default modulus; c then scales k_c with E.
        spec.yarn.contact_factor = kc / (spec.yarn.young_modulus * 1e-3);
    }
    if let Some(e) = args.young_modulus {
        if !(e.is_finite() && e > 0.0) {
            return Err(CliError::Input(format!(
                "--young-modulus {e} Pa must be > 0"
            )));
        }
        spec.yarn.young_modulus = e;
    }
    if let Some(f) = args.bending_factor {
        spec.yarn.bending_factor = f;
    }
    if let Some(r) = args.yarn_radius {
        spec.yarn_radius = r;
    }
    if let Some(n) = args.cells_across {
        spec.cells_across = n;
    }
    spec.cells_along = args.cells_along.or(spec.cells_along);
    if let Some(n) = args.steps {
        spec.steps = n;
    }
    if let Some(n) = args.max_iterations {
        if n == 0 {
            return Err(CliError::Input("--max-iterations must be ≥ 1".into()));
        }
        spec.newton.max_iterations = n;
        spec.newton.max_factorizations = 5 * n;
    }
    spec.validate()
        .map_err(|e| CliError::Input(format!("stretch-test: {e}")))?;
    let data_dir = args.data_dir.clone().unwrap_or_else(vendored_dir);
    let measured = MeasuredStretch::read(&data_dir.join(measured_file(knit, direction)))
        .map_err(|e| CliError::Input(e.to_string()))?;
    let yarns_dir = args
        .yarns_dir
        .clone()
        .unwrap_or_else(|| PathBuf::from("../shared/data/yarns"));
    let pattern = yarns_dir.join(knit.pattern()).join("pattern.pyp");
    if !pattern.is_file() {
        return Err(CliError::Input(format!(
            "pattern `{}` not found (looked for {}); give the folder of the shared yarn patterns with \
             --yarns-dir",
            knit.pattern(),
            pattern.display()
        )));
    }
    std::fs::create_dir_all(&args.out)
        .map_err(|e| CliError::Failed(format!("cannot create {}: {e}", args.out.display())))?;
    let trace = args.progress;
    let result = run_stretch_test(&spec, &pattern, &measured, |p| {
        if trace {
            eprintln!("{}", serde_json::to_string(p).unwrap_or_default());
        }
    })
    .map_err(|e| match e {
        YarnSceneError::Input(m) => CliError::Input(m),
        other => CliError::Failed(other.to_string()),
    })?;
    let sim: Vec<(f64, f64)> = result
        .points
        .iter()
        .map(|p| (p.extension_m * 1e3, p.force_n))
        .collect();
    let title = format!(
        "acrylic {} {}: measured and yarn-level (E = {:.3e} Pa)",
        knit.name(),
        direction.name(),
        result.young_modulus_pa
    );
    let line = serde_json::to_string(&result).map_err(|e| CliError::Failed(e.to_string()))?;
    for (name, text) in [
        ("simulated.csv", simulated_csv(&result)),
        ("comparison.csv", comparison_csv(&measured, &result)),
        ("stretch_test.svg", stretch_svg(&measured, &sim, &title)),
        ("result.json", format!("{line}\n")),
    ] {
        let path = args.out.join(name);
        std::fs::write(&path, text)
            .map_err(|e| CliError::Failed(format!("cannot write {}: {e}", path.display())))?;
    }
    println!("{line}");
    Ok(result.converged)
}

/// The scene's `.pyp`: relative to the scene file, or a shared pattern name in `yarns_dir` (default
/// `../shared/data/yarns`); the error says where it looked.
fn scene_pattern(
    scene: &crate::knit::YarnScene,
    scene_path: &Path,
    yarns_dir: Option<&Path>,
) -> Result<PathBuf, CliError> {
    let base = scene_path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let yarns_dir =
        yarns_dir.map_or_else(|| PathBuf::from("../shared/data/yarns"), Path::to_path_buf);
    let pattern = scene.pattern_path(base, Some(&yarns_dir));
    if !pattern.is_file() {
        return Err(CliError::Input(format!(
            "{}: pattern `{}` not found (looked for {}); give a folder with pattern.pyp or a .pyp file \
             relative to the scene, or a shared pattern name with --yarns-dir",
            scene_path.display(),
            scene.pattern,
            pattern.display()
        )));
    }
    Ok(pattern)
}

fn out_name(p: &Path) -> String {
    p.display().to_string()
}
