//! The uniaxial stretch test of a yarn-level patch in a measured sample's geometry
//! (`skintight knit stretch-test`): a patch of the knit's shared pattern (`stock_9` for stockinette,
//! `rib_9` for rib) held by two clamps across its whole width and pulled quasi-statically, its force–
//! extension curve scaled to the sample of Singal et al. 2024 (`skintight_knit::measured_stretch`) and
//! compared with the measured one.
//!
//! **Geometry.** The pattern is scaled by `s = r_yarn / r_pattern`. The default `r_yarn` makes the
//! stockinette's loop as long as the acrylic stockinette's measured stitch: `stock_9` holds 2 yarns of 2
//! loops each per cell, 105.07 mm of yarn at its 1 mm radius, so 26.27 yarn radii a loop; the experiment's
//! model settings give a stitch length of 11.28 mm (`code/fabric_simulations/stockinetteconfig.dat` in
//! github.com/sabetta/stitch-by-stitch), so `r_yarn = 11.28 / 26.27 = 0.429 mm` — between that file's
//! `core_radius` 0.325 mm and its (compressible) `yarn_radius` 0.74 mm — and the scaled wale is 3.23 mm,
//! inside the 2.8–5.3 mm range its cell sweeps. Rib is the same yarn, so the same radius. Pulling along
//! `x` (the courses; the experiment's "X") or `y` (the wales, "Y"), the patch has `n_along` cells along the
//! pull — by default the clamp distance in scaled cells, `round(L0 / (s p_along))`, at least 2 — and
//! `n_across` cells across (default 2, far fewer than the sample's 10–20: the cost). The clamps are the
//! vertices in a band of `clamp_band_cells` periods at either end of the patch along the pull, every
//! position component held (a clamp holds the fabric's whole width); the cut edges are bonded
//! ([`skintight_knit::edge_finish`]) and the two long sides free, as in the experiment.
//!
//! **Pull.** The start is the scene start of `knit simulate-yarn` ([`super::patch_model`]: the periodic
//! rest state tiled), relaxed with both clamps held (Newton, no gravity). Then `steps` equal increments
//! of the moving clamp's displacement `u` up to `u_max = e_max L_free / L0` (`e_max` the largest measured
//! extension, `L_free` the patch's clamp-to-clamp distance): each increment maps the state by the
//! piecewise-linear stretch of the pull coordinate that holds the fixed clamp, moves the other clamp by
//! `Δu` and stretches the yarn between them uniformly (distances never shrink under it, so no yarn is
//! pushed through another), then minimises the patch energy with the clamps held
//! (`skintight_knit::implicit_euler::ImplicitEuler::relax`, the load parameter carried as its time). The
//! clamp force is `F = (Σ_moving ∂E/∂x_a − Σ_fixed ∂E/∂x_a)/2` (N; `a` the pull axis): at equilibrium the
//! two clamps' reactions are equal and opposite, and their difference is reported (`force_imbalance_n`).
//!
//! **To the sample.** With every stiffness a multiple of Young's modulus `E` (`k_s = E π r²`,
//! `k_b = f E π r⁴/4`, `k_c = c E r`), the patch energy scales as `E s³` under the scaling `s` of the
//! geometry, forces as `E s²`. The sample's force is the patch's force per unit width times the sample's
//! width: `F_sample = F_patch · s · W / (n_across p_across)`, and its extension `e = u L0 / L_free`.
//! Forces are proportional to `E` at fixed geometry, so the least-squares `E` for a measured curve is
//! `E · c` with `c` of `skintight_knit::measured_stretch::least_squares_scale` — the calibration.
//!
//! Units: SI (m, N, J, Pa); the CSV and plot are in mm and N.

use std::path::Path;
use std::time::Instant;

use serde::{Deserialize, Serialize};
use serde_json::json;
use skintight_knit::PeriodicPattern;
use skintight_knit::implicit_euler::{ImplicitEuler, ImplicitEulerParams, Prescribed};
use skintight_knit::measured_stretch::{
    CurveComparison, MeasuredStretch, compare_curves, least_squares_scale,
};
use skintight_knit::newton::NewtonParams;
use skintight_knit::patch::{DOFS_PER_VERTEX, PatchModel};
use skintight_knit::yarn_params::YarnParams;

use super::build::{bounds, patch_model};
use super::error::YarnSceneError;
use super::spec::YarnScene;

/// The measured knits.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MeasuredKnit {
    /// Stockinette (pattern `stock_9`).
    Stockinette,
    /// Rib (pattern `rib_9`).
    Rib,
}

impl MeasuredKnit {
    /// The knit's name in files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            MeasuredKnit::Stockinette => "stockinette",
            MeasuredKnit::Rib => "rib",
        }
    }

    /// The shared pattern simulated.
    pub fn pattern(self) -> &'static str {
        match self {
            MeasuredKnit::Stockinette => "stock_9",
            MeasuredKnit::Rib => "rib_9",
        }
    }
}

/// The direction of the pull.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PullDirection {
    /// Along the courses (the pattern's x; the experiment's "X").
    X,
    /// Along the wales (the pattern's y; the experiment's "Y").
    Y,
}

impl PullDirection {
    /// The pattern axis of the pull (0: x, 1: y).
    pub fn axis(self) -> usize {
        match self {
            PullDirection::X => 0,
            PullDirection::Y => 1,
        }
    }

    /// `x` or `y`.
    pub fn name(self) -> &'static str {
        match self {
            PullDirection::X => "x",
            PullDirection::Y => "y",
        }
    }
}

/// The measured file of a knit and direction in the vendored folder
/// (`skintight_knit::measured_stretch::vendored_dir`).
pub fn measured_file(knit: MeasuredKnit, direction: PullDirection) -> String {
    format!("acrylic_{}_{}.csv", knit.name(), direction.name())
}

/// The settings of a stretch test.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StretchTestSpec {
    /// The pull direction.
    pub direction: PullDirection,
    /// Yarn constants (at the pattern's scale; forces scale with `young_modulus`).
    pub yarn: YarnParams,
    /// The sample's yarn radius (m): the pattern is scaled to it.
    pub yarn_radius: f64,
    /// Cells across the pull.
    pub cells_across: usize,
    /// Cells along the pull (`None`: the sample's clamp distance in scaled cells, at least 2).
    pub cells_along: Option<usize>,
    /// Increments of the clamp displacement.
    pub steps: usize,
    /// Width of each clamp band (cell periods along the pull).
    pub clamp_band_cells: f64,
    /// The Newton solve of the start's relaxation and of each increment.
    pub newton: NewtonParams,
}

/// The model's acrylic yarn radius (m): the radius at which `stock_9`'s loop (26.27 radii of yarn) is the
/// measured stockinette's stitch length, 11.28 mm (`stitch_length` in
/// `code/fabric_simulations/stockinetteconfig.dat` of github.com/sabetta/stitch-by-stitch); see the module
/// doc.
pub const ACRYLIC_YARN_RADIUS: f64 = 11.28e-3 / STOCK_9_LOOP_RADII;

/// Yarn length of one `stock_9` loop in yarn radii: 105.07 mm of yarn a cell (the sum of its rest lengths)
/// at radius 1 mm, in 4 loops (2 yarns, each 2 loops a period).
pub const STOCK_9_LOOP_RADII: f64 = 105.07 / 4.0;

impl StretchTestSpec {
    /// Defaults: the generator constants of issue 45's cell check (`YarnParams::madypg_generator` with
    /// `k_c = 200 J/m²` at the pattern's 1 mm radius), [`ACRYLIC_YARN_RADIUS`], 2 cells across, 8
    /// increments, clamp bands of 0.25 cells, Newton as the scene's relaxation (300 iterations).
    pub fn new(direction: PullDirection) -> Self {
        Self {
            direction,
            yarn: YarnParams::madypg_generator(1e-3, 200.0),
            yarn_radius: ACRYLIC_YARN_RADIUS,
            cells_across: 2,
            cells_along: None,
            steps: 8,
            clamp_band_cells: 0.25,
            newton: NewtonParams::default(),
        }
    }

    /// Checks the settings; the message names the setting.
    pub fn validate(&self) -> Result<(), String> {
        self.yarn.validate()?;
        if !(self.yarn_radius.is_finite() && self.yarn_radius > 0.0) {
            return Err(format!("yarn radius {} m must be > 0", self.yarn_radius));
        }
        if self.cells_across == 0 || self.cells_along == Some(0) {
            return Err("cells across and along must be ≥ 1".into());
        }
        if self.steps == 0 {
            return Err("steps must be ≥ 1".into());
        }
        if !(self.clamp_band_cells > 0.0 && self.clamp_band_cells < 0.5) {
            return Err(format!(
                "clamp band {} cells must be in (0, 0.5)",
                self.clamp_band_cells
            ));
        }
        Ok(())
    }
}

/// One equilibrium of the pull.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct StretchPoint {
    /// The moving clamp's displacement (m, patch scale).
    pub patch_displacement_m: f64,
    /// The clamp force on the patch (N, patch scale).
    pub patch_force_n: f64,
    /// `Σ_moving ∂E/∂x_a + Σ_fixed ∂E/∂x_a` (N, patch scale): zero at an exact equilibrium.
    pub force_imbalance_n: f64,
    /// The patch energy (J, patch scale).
    pub energy_j: f64,
    /// The sample's extension (m).
    pub extension_m: f64,
    /// The sample's force (N).
    pub force_n: f64,
    /// Newton iterations of this equilibrium.
    pub newton_iterations: usize,
    /// Whether the Newton solve converged.
    pub converged: bool,
    /// Smallest centreline distance between yarn segments (m, patch scale).
    pub min_distance_m: f64,
}

/// The outcome of a stretch test.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StretchTestResult {
    /// The pattern file.
    pub pattern: String,
    /// The pull direction.
    pub direction: PullDirection,
    /// Cells `[nx, ny]` of the patch.
    pub cells: [usize; 2],
    /// Vertices of the patch.
    pub vertices: usize,
    /// Geometric scale `s` from the pattern to the sample (dimensionless).
    pub scale: f64,
    /// Young's modulus used (Pa).
    pub young_modulus_pa: f64,
    /// The patch's clamp-to-clamp distance (m, patch scale).
    pub patch_free_length_m: f64,
    /// The sample's clamp distance (m) and width (m).
    pub sample_clamp_distance_m: f64,
    /// The sample's fabric width (m).
    pub sample_width_m: f64,
    /// `F_sample / F_patch` (dimensionless).
    pub force_factor: f64,
    /// The equilibria, the relaxed start first.
    pub points: Vec<StretchPoint>,
    /// Whether every Newton solve converged.
    pub converged: bool,
    /// The comparison with the measured curve (bins with at least 1 N).
    pub comparison: CurveComparison,
    /// The Young's modulus (Pa) whose curve fits the measured one best in least squares
    /// (`young_modulus_pa` × the least-squares scale); `None` when no bin compares.
    pub least_squares_young_modulus_pa: Option<f64>,
    /// Wall time (s).
    pub seconds: f64,
}

/// The smallest measured force compared (N): below it the gauge reads noise (the first bins).
pub const MIN_COMPARED_FORCE_N: f64 = 1.0;

/// Runs the stretch test of `spec` on the pattern at `pattern_path` in the geometry of `measured`;
/// `progress` is told each equilibrium.
pub fn run_stretch_test(
    spec: &StretchTestSpec,
    pattern_path: &Path,
    measured: &MeasuredStretch,
    mut progress: impl FnMut(&StretchPoint),
) -> Result<StretchTestResult, YarnSceneError> {
    let start = Instant::now();
    spec.validate().map_err(YarnSceneError::Input)?;
    let pattern =
        PeriodicPattern::read(pattern_path).map_err(|e| YarnSceneError::Input(e.to_string()))?;
    let a = spec.direction.axis();
    let b = 1 - a;
    let s = spec.yarn_radius / pattern.radius;
    let (p_along, p_across) = (pattern.period[a], pattern.period[b]);
    let n_along = spec
        .cells_along
        .unwrap_or_else(|| ((measured.clamp_distance / (s * p_along)).round() as usize).max(2));
    let mut cells = [0; 2];
    cells[a] = n_along;
    cells[b] = spec.cells_across;
    let scene: YarnScene = serde_json::from_value(json!({
        "pattern": pattern_path.display().to_string(),
        "cells": cells,
        "scenario": "hang",
        "duration_s": 1.0,
        "gravity_m_s2": 0.0,
        "yarn": spec.yarn,
    }))
    .map_err(|e| YarnSceneError::Input(format!("stretch test settings: {e}")))?;
    let (model, _) = patch_model(&scene, &pattern)?;
    let x0 = model.initial_state();
    let points = PatchModel::positions(&x0);
    let (lo, hi) = bounds(points.iter());
    let band = spec.clamp_band_cells * p_along;
    let (edge0, edge1) = (lo[a] + band, hi[a] - band);
    let free = edge1 - edge0;
    let u_max = measured.max_extension() * free / measured.clamp_distance;
    let mut moving = Vec::new();
    let mut fixed = Vec::new();
    let mut prescribed = Vec::new();
    for (v, p) in points.iter().enumerate() {
        let mut end = *p;
        if p[a] < edge0 {
            fixed.push(v);
        } else if p[a] > edge1 {
            moving.push(v);
            end[a] += u_max;
        } else {
            continue;
        }
        prescribed.push(Prescribed {
            vertex: v,
            start: *p,
            end,
            ramp_time: 1.0,
        });
    }
    let vertices = model.vertex_count();
    let params = ImplicitEulerParams {
        dt: 1.0,
        mass_damping: 0.0,
        newton: spec.newton,
        ..ImplicitEulerParams::default()
    };
    let mut sim = ImplicitEuler::new(model, params, prescribed.clone())?;
    let force_factor = s * measured.fabric_width / (spec.cells_across as f64 * p_across);
    let to_sample = measured.clamp_distance / free;
    let mut out = Vec::with_capacity(spec.steps + 1);
    let report = sim.relax(&spec.newton)?;
    let equilibrium = |sim: &ImplicitEuler, u: f64, iterations: usize, converged: bool| {
        let e = sim.evaluate();
        let pull = |set: &[usize]| -> f64 {
            set.iter()
                .map(|&v| e.gradient[DOFS_PER_VERTEX * v + a])
                .sum()
        };
        let (top, bottom) = (pull(&moving), pull(&fixed));
        let f = 0.5 * (top - bottom);
        StretchPoint {
            patch_displacement_m: u,
            patch_force_n: f,
            force_imbalance_n: top + bottom,
            energy_j: e.energy,
            extension_m: u * to_sample,
            force_n: f * force_factor,
            newton_iterations: iterations,
            converged,
            min_distance_m: e.min_distance,
        }
    };
    let p0 = equilibrium(&sim, 0.0, report.iterations, report.converged);
    progress(&p0);
    out.push(p0);
    for k in 1..=spec.steps {
        let t = k as f64 / spec.steps as f64;
        let (u_prev, u) = (u_max * (k - 1) as f64 / spec.steps as f64, u_max * t);
        let du = u - u_prev;
        let top_edge = edge1 + u_prev;
        let mut state = sim.save_state();
        for v in 0..vertices {
            let q = &mut state.x[DOFS_PER_VERTEX * v + a];
            if *q >= top_edge {
                *q += du;
            } else if *q > edge0 {
                *q += du * (*q - edge0) / (top_edge - edge0);
            }
        }
        for p in &prescribed {
            let q = p.position(t);
            state.x[DOFS_PER_VERTEX * p.vertex..DOFS_PER_VERTEX * p.vertex + 3].copy_from_slice(&q);
        }
        state.time = t;
        state.v.iter_mut().for_each(|v| *v = 0.0);
        sim.restore_state(state)?;
        let report = sim.relax(&spec.newton)?;
        let p = equilibrium(&sim, u, report.iterations, report.converged);
        progress(&p);
        out.push(p);
    }
    let ext: Vec<f64> = out.iter().map(|p| p.extension_m).collect();
    let force: Vec<f64> = out.iter().map(|p| p.force_n).collect();
    let comparison = compare_curves(measured, &ext, &force, MIN_COMPARED_FORCE_N);
    let e = spec.yarn.young_modulus;
    Ok(StretchTestResult {
        pattern: pattern_path.display().to_string(),
        direction: spec.direction,
        cells,
        vertices,
        scale: s,
        young_modulus_pa: e,
        patch_free_length_m: free,
        sample_clamp_distance_m: measured.clamp_distance,
        sample_width_m: measured.fabric_width,
        force_factor,
        converged: out.iter().all(|p| p.converged),
        least_squares_young_modulus_pa: least_squares_scale(&comparison).map(|c| c * e),
        comparison,
        points: out,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// The simulated curve as CSV (mm, N), one row per equilibrium.
pub fn simulated_csv(result: &StretchTestResult) -> String {
    let mut s = String::from(
        "extension_mm,force_n,patch_displacement_m,patch_force_n,force_imbalance_n,energy_j,\
         newton_iterations,converged,min_distance_m\n",
    );
    for p in &result.points {
        s.push_str(&format!(
            "{:.4},{:.5},{:.6e},{:.6e},{:.3e},{:.6e},{},{},{:.6e}\n",
            p.extension_m * 1e3,
            p.force_n,
            p.patch_displacement_m,
            p.patch_force_n,
            p.force_imbalance_n,
            p.energy_j,
            p.newton_iterations,
            p.converged,
            p.min_distance_m
        ));
    }
    s
}

/// The measured curve beside the simulated one at the measured extensions (mm, N); the simulated
/// column is empty beyond the simulated range.
pub fn comparison_csv(measured: &MeasuredStretch, result: &StretchTestResult) -> String {
    let ext: Vec<f64> = result.points.iter().map(|p| p.extension_m).collect();
    let force: Vec<f64> = result.points.iter().map(|p| p.force_n).collect();
    let mut s = String::from(
        "extension_mm,measured_force_n,measured_min_n,measured_max_n,simulated_force_n\n",
    );
    for k in 0..measured.extension.len() {
        let e = measured.extension[k];
        let sim = skintight_knit::measured_stretch::interpolate(&ext, &force, e)
            .map(|f| format!("{f:.4}"))
            .unwrap_or_default();
        s.push_str(&format!(
            "{:.4},{:.4},{:.4},{:.4},{sim}\n",
            e * 1e3,
            measured.force[k],
            measured.force_min[k],
            measured.force_max[k]
        ));
    }
    s
}
