//! `skintight body …`: build deformable tetrahedral bodies.
//!
//! `skintight body prepare SCAN --out BODY.obj [--units mm|cm|m|auto] [--up y|z|auto] [--target-faces N]`
//! makes a raw scan a body surface (see `skintight_geometry::scan`) and prints a JSON report.
//!
//! `skintight body tetrahedralize SURFACE --thickness 0.02 --layers 2 --out BODY.vtu` fills a shell of
//! tetrahedra under a closed, outward-oriented body surface (OBJ), keeping the surface exactly as the body's
//! outer boundary and fixing the inner (core) surface, and prints a JSON report. The surface may be OBJ,
//! PLY, STL or glTF binary.
//!
//! `skintight body measure BODY --out measurements.json` finds the landmarks and girths of a standing body
//! (`skintight_geometry::anthropometry`).

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::{Args, Subcommand};
use skintight_geometry::body::shell_tetrahedralization::{ShellParams, shell_tetrahedralization};
use skintight_geometry::body::tet_io::{body_arrays, write_vtu};
use skintight_geometry::mesh::io::read_mesh;
use skintight_geometry::{MeshCheckParams, TriMesh, body_surface};

use super::CliError;

/// Body subcommands.
#[derive(Debug, Subcommand)]
pub enum BodyCommand {
    /// Fill a shell of tetrahedra under a closed body surface; print a JSON report, write a .vtu.
    ///
    /// The report's `min_quality` and `mean_quality` are the signed mean-ratio quality
    /// 12·(3V)^(2/3) / Σ ℓᵢⱼ² of the tetrahedra (V volume, ℓᵢⱼ the six edge lengths): 1 for a regular
    /// tetrahedron, near 0 for a flat one, negative for an inverted one. `surface_preserved` is true when the
    /// body's extracted outer boundary equals the input surface vertex for vertex and face for face.
    #[command(after_help = super::EXIT_DONE)]
    Tetrahedralize(TetrahedralizeArgs),
    /// Prepare a raw body scan (any units and up axis, open, noisy, islands, non-manifold spots) as a closed,
    /// 2-manifold, outward, genus-0 body surface in metres, +y up, facing +z; print a JSON report.
    ///
    /// Units and up axis are detected unless declared (a standing body is 1.0–2.1 m tall); the front is
    /// told from the feet. The result is remeshed isotropically to about `--target-faces` faces; the
    /// report gives its mean and Hausdorff deviation from the scan in millimetres. A scan that cannot be a
    /// standing human body (two people, a chair, 40 m tall, empty, over 5 M faces) ends with one line.
    #[command(after_help = super::EXIT_DONE)]
    Prepare(PrepareArgs),
    /// Bend the legs of a standing body (data/bodies frame: metres, +y up, facing +z) at hip and knee:
    /// writes the posed surface, same vertices and triangles, for `objectives.sliding.poses`.
    #[command(after_help = super::EXIT_DONE)]
    Pose(PoseArgs),
    /// Measure a standing body (A-pose, metres, +y up, facing +z): the landmarks and girths of ISO 8559-1 /
    /// RAL-GZ 387 (legs B B1 C D E F G, crotch, hip, waist, arms wrist forearm elbow upper_arm armpit).
    ///
    /// Writes `{stature_m, landmarks: [{name, side, height_m, girth_m, point, normal, axis_m, curve}],
    /// segmentation}` to --out and prints a summary (name, side, height, girth per landmark). Girths are
    /// tape-measure girths (the convex hull of the section), heights above the body's lowest point.
    #[command(after_help = super::EXIT_DONE)]
    Measure(MeasureArgs),
}

/// Arguments of `body measure`.
#[derive(Debug, Args)]
pub struct MeasureArgs {
    /// Closed body surface (OBJ, PLY, STL or .glb), metres, +y up, facing +z, standing.
    pub surface: PathBuf,
    /// Output JSON (measurements.json).
    #[arg(long)]
    pub out: PathBuf,
}

/// Arguments of `body pose`.
#[derive(Debug, Args)]
pub struct PoseArgs {
    /// Body surface (OBJ, PLY, STL or .glb), metres, +y up, facing +z.
    pub surface: PathBuf,
    /// Hip flexion in degrees (thigh forward), within ±90.
    #[arg(long, default_value_t = 30.0, allow_hyphen_values = true)]
    pub hip_deg: f64,
    /// Knee flexion in degrees (shank backward), within ±120.
    #[arg(long, default_value_t = 45.0, allow_hyphen_values = true)]
    pub knee_deg: f64,
    /// Which legs: left (x > 0), right (x < 0) or both.
    #[arg(long, default_value = "both")]
    pub leg: String,
    /// Output surface (.obj, .ply, .stl or .glb).
    #[arg(long)]
    pub out: PathBuf,
}

/// Arguments of `body prepare`.
#[derive(Debug, Args)]
pub struct PrepareArgs {
    /// Raw scan (OBJ, PLY ASCII or binary, STL or .glb).
    pub scan: PathBuf,
    /// Output body surface (.obj, .ply, .stl or .glb), metres, +y up, facing +z.
    #[arg(long)]
    pub out: PathBuf,
    /// Units of the scan: mm, cm, m or auto (from the height).
    #[arg(long, default_value = "auto")]
    pub units: String,
    /// Up axis of the scan: x, y, z (or -x, -y, -z) or auto (the longest extent).
    #[arg(long, default_value = "auto", allow_hyphen_values = true)]
    pub up: String,
    /// Faces of the prepared body (about).
    #[arg(long, default_value_t = skintight_geometry::scan::DEFAULT_TARGET_FACES)]
    pub target_faces: usize,
    /// Also write the JSON report to this file.
    #[arg(long)]
    pub report: Option<PathBuf>,
}

/// Arguments of `body tetrahedralize`.
#[derive(Debug, Args)]
pub struct TetrahedralizeArgs {
    /// Closed body surface in metres (OBJ, PLY, STL or .glb; polygons are fan-triangulated, an inward-oriented
    /// surface is flipped with a warning).
    pub surface: PathBuf,
    /// Largest shell thickness in metres (reduced locally where the body is thin or sharply curved).
    #[arg(long, default_value_t = 0.02)]
    pub thickness: f64,
    /// Number of tetrahedral layers through the thickness.
    #[arg(long, default_value_t = 2)]
    pub layers: usize,
    /// Output VTK unstructured grid (.vtu) with point data `fixed` and cell data `quality`.
    #[arg(long)]
    pub out: PathBuf,
}

/// Runs a body subcommand.
pub fn run(cmd: BodyCommand) -> Result<(), CliError> {
    match cmd {
        BodyCommand::Tetrahedralize(args) => tetrahedralize(&args),
        BodyCommand::Pose(args) => pose(&args),
        BodyCommand::Measure(args) => measure(&args),
        BodyCommand::Prepare(args) => prepare(&args),
    }
}

fn measure(args: &MeasureArgs) -> Result<(), CliError> {
    use skintight_geometry::anthropometry::measure_body;
    let (body, warnings) = read_body_surface(&args.surface)?;
    let m = measure_body(&body)
        .map_err(|e| CliError::Input(format!("{}: {e}", args.surface.display())))?;
    let text = serde_json::to_string_pretty(&m)
        .map_err(|e| CliError::Failed(format!("cannot encode the measurements: {e}")))?;
    create_parent_dir(&args.out)?;
    std::fs::write(&args.out, text)
        .map_err(|e| CliError::Failed(format!("{}: {e}", args.out.display())))?;
    let summary: Vec<serde_json::Value> = m
        .landmarks
        .iter()
        .map(|l| {
            serde_json::json!({"name": l.name, "side": l.side, "height_m": l.height_m,
                               "girth_m": l.girth_m})
        })
        .collect();
    println!(
        "{}",
        serde_json::json!({"stature_m": m.stature_m, "landmarks": summary,
                           "out": args.out.display().to_string(), "warnings": warnings})
    );
    Ok(())
}

/// Settings of scan preparation from the words of the CLI or a job (`units`, `up`: `auto` or a value).
pub fn prepare_params(
    units: &str,
    up: &str,
    target_faces: usize,
) -> Result<skintight_geometry::scan::PrepareParams, String> {
    use skintight_geometry::scan::units_and_up::{LengthUnit, SignedAxis};
    let units = match units {
        "auto" => None,
        u => Some(
            LengthUnit::parse(u)
                .ok_or_else(|| format!("units must be mm, cm, m or auto, got {u:?}"))?,
        ),
    };
    let up = match up {
        "auto" => None,
        u => Some(
            SignedAxis::parse(u)
                .ok_or_else(|| format!("up must be x, y, z, -x, -y, -z or auto, got {u:?}"))?,
        ),
    };
    if !(100..=2_000_000).contains(&target_faces) {
        return Err(format!(
            "target faces must be within 100–2000000, got {target_faces}"
        ));
    }
    Ok(skintight_geometry::scan::PrepareParams {
        units,
        up,
        target_faces,
        ..Default::default()
    })
}

fn prepare(args: &PrepareArgs) -> Result<(), CliError> {
    use skintight_geometry::scan::{PrepareError, prepare_scan, read_scan};
    let start = Instant::now();
    let params = prepare_params(&args.units, &args.up, args.target_faces)
        .map_err(|e| CliError::Input(format!("--{e}")))?;
    if skintight_geometry::mesh::io::MeshFormat::from_path(&args.out).is_none() {
        return Err(CliError::Input(format!(
            "{}: the output must be a .obj, .ply, .stl or .glb file",
            args.out.display()
        )));
    }
    let scan = read_scan(&args.scan, params.max_faces)
        .map_err(|e| CliError::Input(format!("{}: {e}", args.scan.display())))?;
    let read_s = start.elapsed().as_secs_f64();
    let (body, report) = prepare_scan(&scan, &params).map_err(|e| {
        let msg = format!("{}: {e}", args.scan.display());
        match e {
            PrepareError::Failed(_) => CliError::Failed(msg),
            _ => CliError::Input(msg),
        }
    })?;
    create_parent_dir(&args.out)?;
    skintight_geometry::mesh::io::write_mesh(&args.out, &body, &Default::default())
        .map_err(|e| CliError::Failed(format!("{}: {e}", args.out.display())))?;
    let mut value = serde_json::to_value(&report)
        .map_err(|e| CliError::Failed(format!("cannot encode the report: {e}")))?;
    if let Some(obj) = value.as_object_mut() {
        obj.insert("out".into(), args.out.display().to_string().into());
        let stages = obj.remove("timing_s").unwrap_or_default();
        obj.insert(
            "timing_s".into(),
            serde_json::json!({"read": read_s, "total": start.elapsed().as_secs_f64(), "stages": stages}),
        );
    }
    let text = serde_json::to_string_pretty(&value)
        .map_err(|e| CliError::Failed(format!("cannot encode the report: {e}")))?;
    if let Some(path) = &args.report {
        std::fs::write(path, &text)
            .map_err(|e| CliError::Failed(format!("cannot write {}: {e}", path.display())))?;
    }
    println!("{text}");
    Ok(())
}

fn pose(args: &PoseArgs) -> Result<(), CliError> {
    use skintight_geometry::body::leg_pose::{LegPoseParams, Legs, leg_pose};
    let legs = match args.leg.as_str() {
        "left" => Legs::Left,
        "right" => Legs::Right,
        "both" => Legs::Both,
        other => {
            return Err(CliError::Input(format!(
                "--leg must be left, right or both, got {other:?}"
            )));
        }
    };
    let body = read_mesh(&args.surface)
        .map_err(|e| CliError::Input(format!("{}: {e}", args.surface.display())))?;
    let params = LegPoseParams {
        hip: args.hip_deg.to_radians(),
        knee: args.knee_deg.to_radians(),
        legs,
        ..LegPoseParams::default()
    };
    let posed = leg_pose(&body, &params)
        .map_err(|e| CliError::Input(format!("{}: {e}", args.surface.display())))?;
    skintight_geometry::mesh::io::write_mesh(&args.out, &posed, &Default::default())
        .map_err(|e| CliError::Failed(format!("{}: {e}", args.out.display())))?;
    let moved = posed
        .positions
        .iter()
        .zip(&body.positions)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0_f64, f64::max);
    println!(
        "{}",
        serde_json::json!({"vertices": posed.positions.len(), "faces": posed.faces.len(),
                           "max_displacement_m": moved})
    );
    Ok(())
}

fn tetrahedralize(args: &TetrahedralizeArgs) -> Result<(), CliError> {
    let start = Instant::now();
    let (surface, warnings) = read_body_surface(&args.surface)?;
    let read_s = start.elapsed().as_secs_f64();
    let params = ShellParams {
        thickness: args.thickness,
        layers: args.layers,
        ..ShellParams::default()
    };
    let t0 = Instant::now();
    let body = shell_tetrahedralization(&surface, &params).map_err(|e| {
        use skintight_geometry::ShellError as E;
        let msg = format!("{}: {e}", args.surface.display());
        match e {
            E::BadParam { .. }
            | E::Empty
            | E::NonFinite { .. }
            | E::Topology(_)
            | E::NotClosed { .. }
            | E::NoNormal { .. } => CliError::Input(msg),
            _ => CliError::Failed(msg),
        }
    })?;
    let tet_s = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let (point_data, cell_data) = body_arrays(&body.mesh);
    create_parent_dir(&args.out)?;
    write_vtu(&args.out, &body.mesh, &point_data, &cell_data)
        .map_err(|e| CliError::Failed(e.to_string()))?;
    let write_s = t1.elapsed().as_secs_f64();
    let mut report = serde_json::to_value(&body.report)
        .map_err(|e| CliError::Failed(format!("cannot encode the report: {e}")))?;
    if let Some(obj) = report.as_object_mut() {
        obj.insert(
            "quality_measure".into(),
            "mean ratio 12(3V)^(2/3)/sum(l^2), 1 = regular".into(),
        );
        obj.insert("out".into(), args.out.display().to_string().into());
        obj.insert("warnings".into(), warnings.into());
        obj.insert(
            "timing_s".into(),
            serde_json::json!({
                "read": read_s,
                "tetrahedralize": tet_s,
                "write": write_s,
                "total": start.elapsed().as_secs_f64(),
            }),
        );
    }
    println!(
        "{}",
        serde_json::to_string_pretty(&report)
            .map_err(|e| CliError::Failed(format!("cannot encode the report: {e}")))?
    );
    Ok(())
}

/// Reads a body surface in any supported format and accepts it only when it can serve as a body (closed,
/// oriented, one component, 2-manifold, finite, no degenerate faces); an inward mesh is flipped with a warning.
fn read_body_surface(path: &Path) -> Result<(TriMesh, Vec<String>), CliError> {
    let mesh = read_mesh(path).map_err(|e| CliError::Input(format!("{}: {e}", path.display())))?;
    let body = body_surface(mesh, &MeshCheckParams::default()).map_err(|issue| {
        CliError::Input(format!(
            "{}: cannot serve as a body: {issue}",
            path.display()
        ))
    })?;
    Ok((body.mesh, body.warnings))
}

/// Creates the folder `out` is to be written into, if it has one and it is missing.
fn create_parent_dir(out: &Path) -> Result<(), CliError> {
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| {
            CliError::Failed(format!(
                "cannot create the output folder {}: {e}",
                dir.display()
            ))
        })?;
    }
    Ok(())
}
