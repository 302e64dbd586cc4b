//! `skintight knit simulate SCENE.json --out DIR`: a homogenized knit in time. The scene reads like a
//! `knit simulate-yarn` scene (pattern, cells, scenario, grips, duration, step, frame rate, damping) plus
//! `material`, a folder written by `knit homogenize` for that patch (relative to the scene file). The same
//! scenario runs on the material's mesh by projective dynamics
//! (`skintight_homogenize::projective_dynamics`, the knitwear paper's Sec. 7.1): the scene's held yarn
//! vertices hold the nodes of the tetrahedra that embed them, each node moved by the mean displacement of
//! those vertices' grips (`Prescribed::position`, the same ramp); gravity and mass damping as the scene
//! says; a `drape_sphere` scene's sphere keeps the embedded yarns out by the PD collision constraints.
//! The yarns are written per frame through V2Y (Eq. 4) in part 1's sequence format (θ = 0: the mesh has no
//! twist), so `knit compare` sets the yarn-level and the homogenized run of one scene side by side.
//! `DIR/result.json`: [`HomogenizedRunResult`].

use std::path::Path;
use std::time::Instant;

use serde::Serialize;
use skintight_homogenize::projective_dynamics::{
    BodyCollider, BodyCollision, ProjectiveDynamics, ProjectiveDynamicsParams,
};
use skintight_knit::PeriodicPattern;
use skintight_knit::frame_sequence::SequenceWriter;

use super::homogenize::{KnitHomogenizeError, read_material};
use super::output::{sequence_meta, vertex_sources};
use super::{YarnScene, patch_model};

/// `result.json` of `knit simulate`.
#[derive(Clone, Debug, Serialize)]
pub struct HomogenizedRunResult {
    /// The scenario's name.
    pub scenario: String,
    /// The `.pyp` read.
    pub pattern: String,
    /// The material folder.
    pub material: String,
    /// Cells `[nx, ny]`.
    pub cells: [usize; 2],
    /// Tetrahedra of the mesh.
    pub elements: usize,
    /// Nodes of the mesh.
    pub nodes: usize,
    /// Yarn vertices written per frame.
    pub yarn_vertices: usize,
    /// Nodes held by the grips.
    pub held_nodes: usize,
    /// Time steps taken.
    pub steps: usize,
    /// Time step (s).
    pub dt_s: f64,
    /// Frames written (frame 0 included).
    pub frames: usize,
    /// Simulated time reached (s).
    pub simulated_time_s: f64,
    /// PD iterations (global steps) over all steps, and the most in one step.
    pub pd_iterations: usize,
    /// See [`Self::pd_iterations`].
    pub max_pd_iterations: usize,
    /// Steps that stopped at the iteration limit above the tolerance.
    pub unconverged_steps: usize,
    /// The largest final residual of a step (dimensionless, `‖∇Ψ‖_∞ / F`).
    pub max_residual: f64,
    /// Wall-clock seconds of the steps, and per step.
    pub seconds: f64,
    /// See [`Self::seconds`].
    pub seconds_per_step: f64,
}

fn input(e: impl std::fmt::Display) -> KnitHomogenizeError {
    KnitHomogenizeError::Input(e.to_string())
}

/// Runs the scene in `scene_path` (module documentation) into `out`; `pattern_path` is the scene's
/// `.pyp` (resolved by the caller as for `simulate-yarn`). Calls `progress(frame, time_s)` after each
/// written frame.
pub fn simulate_homogenized(
    scene_path: &Path,
    pattern_path: &Path,
    out: &Path,
    mut progress: impl FnMut(usize, f64),
) -> Result<HomogenizedRunResult, KnitHomogenizeError> {
    let (scene, material_dir) = read_scene(scene_path)?;
    let pattern = PeriodicPattern::read(pattern_path).map_err(input)?;
    let (model, prescribed) = patch_model(&scene, &pattern).map_err(input)?;
    let (mesh, gamma) = read_material(&material_dir)?;
    if mesh.embedding.len() != model.vertex_count() {
        return Err(input(format!(
            "{}: the material's mesh embeds {} yarn vertices but the scene's patch ({} × {} cells of {}) has {}: homogenize this patch's sequences",
            material_dir.display(),
            mesh.embedding.len(),
            scene.cells[0],
            scene.cells[1],
            scene.pattern,
            model.vertex_count()
        )));
    }
    // Held nodes and their grips: each node of a tetrahedron embedding a held vertex follows the mean
    // displacement of those vertices.
    let mut moves: Vec<Option<(usize, Vec<usize>)>> = vec![None; mesh.rest.len()];
    for (k, p) in prescribed.iter().enumerate() {
        for &node in &mesh.tets[mesh.embedding[p.vertex].tet] {
            moves[node]
                .get_or_insert_with(|| (node, Vec::new()))
                .1
                .push(k);
        }
    }
    let held: Vec<(usize, Vec<usize>)> = moves.into_iter().flatten().collect();
    let clamped: Vec<usize> = held.iter().map(|(n, _)| *n).collect();
    let at = |t: f64| -> Vec<[f64; 3]> {
        held.iter()
            .map(|(node, grips)| {
                let mut d = [0.0; 3];
                for &k in grips {
                    let (p, s) = (prescribed[k].position(t), prescribed[k].start);
                    for c in 0..3 {
                        d[c] += (p[c] - s[c]) / grips.len() as f64;
                    }
                }
                std::array::from_fn(|c| mesh.rest[*node][c] + d[c])
            })
            .collect()
    };
    let params = ProjectiveDynamicsParams {
        dt: scene.dt_s,
        gravity: [0.0, -scene.gravity_m_s2, 0.0],
        mass_damping: scene.mass_damping_per_s,
        ..ProjectiveDynamicsParams::default()
    };
    let collision = match &model.loads().sphere {
        Some(s) => BodyCollision {
            colliders: vec![BodyCollider::sphere(0, s.center, s.radius).map_err(input)?],
            clearance_m: model.radius(),
            stiffness: None,
        },
        None => BodyCollision::default(),
    };
    let mut pd = ProjectiveDynamics::with_collision(&mesh, gamma, &clamped, params, collision)
        .map_err(|e| input(format!("{}: {e}", scene_path.display())))?;
    let (steps, per_frame) = scene.steps();
    let held_vertices: Vec<usize> = prescribed.iter().map(|p| p.vertex).collect();
    let meta = sequence_meta(&scene, pattern_path, &model, per_frame, &held_vertices);
    let mut writer = SequenceWriter::create(out, meta, &vertex_sources(&model))
        .map_err(|e| KnitHomogenizeError::Output(e.to_string()))?;
    let write = |writer: &mut SequenceWriter, pd: &ProjectiveDynamics| {
        let yarn = mesh
            .v2y(pd.positions())
            .map_err(|e| KnitHomogenizeError::Failed(e.to_string()))?;
        let rows: Vec<f64> = yarn.iter().flat_map(|p| [p[0], p[1], p[2], 0.0]).collect();
        writer
            .push(pd.time(), &rows)
            .map_err(|e| KnitHomogenizeError::Output(e.to_string()))
    };
    write(&mut writer, &pd)?;
    let mut result = HomogenizedRunResult {
        scenario: scene.scenario.name().into(),
        pattern: pattern_path.display().to_string(),
        material: material_dir.display().to_string(),
        cells: scene.cells,
        elements: mesh.tets.len(),
        nodes: mesh.rest.len(),
        yarn_vertices: mesh.embedding.len(),
        held_nodes: clamped.len(),
        steps: 0,
        dt_s: scene.dt_s,
        frames: 1,
        simulated_time_s: 0.0,
        pd_iterations: 0,
        max_pd_iterations: 0,
        unconverged_steps: 0,
        max_residual: 0.0,
        seconds: 0.0,
        seconds_per_step: 0.0,
    };
    progress(0, 0.0);
    let clock = Instant::now();
    for step in 1..=steps {
        let targets = at(step as f64 * scene.dt_s);
        let report = pd
            .step(Some(&targets))
            .map_err(|e| KnitHomogenizeError::Failed(format!("step {step}: {e}")))?;
        result.steps = step;
        result.pd_iterations += report.iterations;
        result.max_pd_iterations = result.max_pd_iterations.max(report.iterations);
        result.unconverged_steps += usize::from(!report.converged);
        result.max_residual = result.max_residual.max(report.residual);
        if step % per_frame == 0 || step == steps {
            write(&mut writer, &pd)?;
            result.frames += 1;
            progress(result.frames - 1, pd.time());
        }
    }
    result.simulated_time_s = pd.time();
    result.seconds = clock.elapsed().as_secs_f64();
    result.seconds_per_step = result.seconds / result.steps.max(1) as f64;
    let path = out.join("result.json");
    let text = serde_json::to_string_pretty(&result)
        .map_err(|e| KnitHomogenizeError::Output(e.to_string()))?;
    std::fs::write(&path, text)
        .map_err(|e| KnitHomogenizeError::Output(format!("{}: {e}", path.display())))?;
    Ok(result)
}

/// The scene without its `material` key (read as a yarn scene, validated as one) and the material folder
/// (relative to the scene file).
pub fn read_scene(path: &Path) -> Result<(YarnScene, std::path::PathBuf), KnitHomogenizeError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| input(format!("cannot read {}: {e}", path.display())))?;
    let mut value: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| input(format!("{}: {e}", path.display())))?;
    let material = value
        .as_object_mut()
        .and_then(|o| o.remove("material"))
        .ok_or_else(|| {
            input(format!(
                "{}: material: missing — name the folder `skintight knit homogenize` wrote for this patch",
                path.display()
            ))
        })?;
    let material = material.as_str().filter(|m| !m.is_empty()).ok_or_else(|| {
        input(format!(
            "{}: material: must be a folder name (a string)",
            path.display()
        ))
    })?;
    let scene = YarnScene::parse(&value.to_string(), path).map_err(input)?;
    let base = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    Ok((scene, base.join(material)))
}
