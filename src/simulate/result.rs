//! What a simulation reports: `result.json` (summary, timings and per-element / per-vertex fields) and the
//! coloured meshes `garment.glb` (by stretch), `garment-pressure.glb` (by probe pressure, mmHg) and
//! `body.glb` (the body's limit surface, by displacement).

use serde::{Deserialize, Serialize};
use skintight_geometry::mesh::io::{WriteParams, write_glb};
use skintight_geometry::surface::limit_mesh::limit_mesh;
use skintight_geometry::{TriMesh, Vec3};
use skintight_physics::equilibrium::{EquilibriumReport, EquilibriumTimings, StopReason};
use skintight_physics::tension_field_density::Regime;

use super::admissibility::{Admissibility, admissibility, triangle_measures};
use super::colormap::color;
use super::probe_pressure::{PROBE_RADIUS, probe_pressure};
use super::regions::{LandmarkBand, LandmarkGirth, landmark_girths, regions};
use super::{SetupTimings, SimulateError, Simulation};

pub use skintight_physics::PA_PER_MMHG;

/// Summary statistics of a field over the cloth, weighted by deformed area.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FieldStats {
    /// Smallest value.
    pub min: f64,
    /// Largest value.
    pub max: f64,
    /// Area-weighted mean.
    pub mean: f64,
    /// Area-weighted standard deviation.
    pub std_dev: f64,
}

impl FieldStats {
    /// Statistics of `values` weighted by `weights` (all zero if empty).
    pub fn weighted(values: &[f64], weights: &[f64]) -> Self {
        let total: f64 = weights.iter().sum();
        if values.is_empty() || !(total > 0.0) {
            return Self::default();
        }
        let mean = values.iter().zip(weights).map(|(v, w)| v * w).sum::<f64>() / total;
        let var = values
            .iter()
            .zip(weights)
            .map(|(v, w)| w * (v - mean) * (v - mean))
            .sum::<f64>()
            / total;
        Self {
            min: values.iter().copied().fold(f64::INFINITY, f64::min),
            max: values.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            mean,
            std_dev: var.sqrt(),
        }
    }
}

/// Per cloth triangle (`#Fc` entries each).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ElementFields {
    /// Principal stretches `[largest, smallest]` (dimensionless, 1 = unstretched).
    pub principal_stretches: Vec<[f64; 2]>,
    /// Stretches along the knit's directions `[wale, course]` (dimensionless): along the piece's grain line
    /// and across it ([`super::admissibility`]).
    pub knit_stretches: Vec<[f64; 2]>,
    /// Tension-field regime (`taut`, `wrinkled`, `slack`, `transition`).
    pub regime: Vec<String>,
    /// Interface pressure (Pa): normal force of the triangle over its deformed area; negative would lift off.
    pub pressure: Vec<f64>,
    /// Interface pressure as a 5 cm pressure probe reads it (Pa): `pressure` averaged over the triangles
    /// within 2.5 cm ([`super::probe_pressure`]); the pressure limit is checked on this.
    pub probe_pressure: Vec<f64>,
    /// Deformed area (m²).
    pub area: Vec<f64>,
    /// Panel of the triangle.
    pub panel: Vec<usize>,
}

/// Everything `result.json` holds. Units: SI (m, Pa, N, J, s).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SimulationResult {
    /// Whether the equilibrium solve converged.
    pub converged: bool,
    /// Why it stopped.
    pub stop_reason: StopReason,
    /// Final relative force residual (dimensionless; see the solver's force scale).
    pub residual: f64,
    /// Final unbalanced force norm (N).
    pub force_residual: f64,
    /// Force scale the residual is relative to (N).
    pub force_scale: f64,
    /// Newton iterations.
    pub newton_iterations: usize,
    /// Total energy at the end (J).
    pub energy: f64,
    /// Body strain energy (J).
    pub body_energy: f64,
    /// Cloth strain energy (J).
    pub cloth_energy: f64,
    /// Cloth triangles in the slack regime.
    pub slack_elements: usize,
    /// Cloth triangles in the wrinkled regime.
    pub wrinkled_elements: usize,
    /// Cloth triangles in the taut regime.
    pub taut_elements: usize,
    /// Largest principal stretch over the cloth.
    pub max_stretch: f64,
    /// Smallest principal stretch over the cloth.
    pub min_stretch: f64,
    /// Interface pressure statistics over the cloth (Pa).
    pub pressure: FieldStats,
    /// Mean interface pressure (mmHg).
    pub mean_pressure_mmhg: f64,
    /// Area of cloth with negative pressure (m²).
    pub negative_pressure_area: f64,
    /// Largest body displacement (m).
    pub max_body_displacement: f64,
    /// Smallest volume ratio `det F` over the body tetrahedra (1 at rest; near 0 is crushed).
    pub min_body_volume_ratio: f64,
    /// Solver timings (s).
    pub timings: EquilibriumTimings,
    /// Set-up timings (s).
    pub setup: SetupTimings,
    /// Sizes of the problem.
    pub counts: Counts,
    /// The verdict against the fabric's limits: `admissible`, `violations`, `limits` (flattened into
    /// `result.json`'s top level).
    #[serde(flatten)]
    pub admissibility: Admissibility,
    /// The body's landmarks at rest — the customer's measurements (`name`, `side`, `height_m`, `girth_m`;
    /// [`super::regions::LandmarkGirth`]); empty when the body cannot be measured.
    #[serde(default)]
    pub landmarks: Vec<LandmarkGirth>,
    /// The garment's pressure per landmark band it covers ([`super::regions`]); empty when the body
    /// cannot be measured.
    #[serde(default)]
    pub regions: Vec<LandmarkBand>,
    /// The verdict against the order's compression prescription (`objectives.prescription` of a design
    /// job, [`super::prescription`]); absent without one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prescription: Option<super::prescription::PrescriptionVerdict>,
    /// Per cloth triangle.
    pub elements: ElementFields,
    /// Cloth triangles (`#Fc × 3` cloth vertex ids), for the per-element and per-vertex fields.
    pub cloth_triangles: Vec<[usize; 3]>,
    /// Per cloth vertex: normal force pressing onto the body (N).
    pub cloth_vertex_normal_force: Vec<f64>,
    /// Per cloth vertex: position at equilibrium (m).
    pub cloth_vertex_position: Vec<[f64; 3]>,
    /// Per body vertex: displacement from rest (m).
    pub body_vertex_displacement: Vec<[f64; 3]>,
}

/// Problem sizes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Counts {
    /// Cloth vertices.
    pub cloth_vertices: usize,
    /// Cloth triangles.
    pub cloth_triangles: usize,
    /// Pinned cloth vertices.
    pub pinned_vertices: usize,
    /// Panels.
    pub panels: usize,
    /// Seams.
    pub seams: usize,
    /// Body vertices.
    pub body_vertices: usize,
    /// Body tetrahedra.
    pub body_tets: usize,
    /// Fixed body vertices.
    pub fixed_body_vertices: usize,
    /// Unknowns of the Newton system.
    pub unknowns: usize,
    /// Stored entries of the Hessian's lower triangle.
    pub hessian_nonzeros: usize,
    /// Numeric factorizations.
    pub factorizations: usize,
    /// Symbolic analyses.
    pub symbolic_analyses: usize,
}

fn regime_name(r: Regime) -> &'static str {
    match r {
        Regime::Taut => "taut",
        Regime::Wrinkled => "wrinkled",
        Regime::Slack => "slack",
        _ => "transition",
    }
}

impl SimulationResult {
    /// The one-object summary the CLI prints and the service shows with the job: the headline figures
    /// without the per-element and per-vertex fields.
    pub fn summary(&self) -> serde_json::Value {
        serde_json::json!({
            "converged": self.converged,
            "stop_reason": self.stop_reason,
            "residual": self.residual,
            "newton_iterations": self.newton_iterations,
            "energy": self.energy,
            "slack_elements": self.slack_elements,
            "max_stretch": self.max_stretch,
            "min_stretch": self.min_stretch,
            "mean_pressure_pa": self.pressure.mean,
            "min_body_volume_ratio": self.min_body_volume_ratio,
            "timings": self.timings,
            "admissible": self.admissibility.admissible,
            "violations": self.admissibility.violations,
        })
    }

    /// Gathers the result of `sim` after a solve that produced `report`.
    pub fn new(sim: &Simulation, report: &EquilibriumReport) -> Result<Self, SimulateError> {
        let fail = |e: skintight_physics::ClothOnBodyError| SimulateError {
            key: None,
            message: format!("evaluating the results failed: {e}"),
            input: false,
        };
        let system = &sim.system;
        let state = &sim.state;
        let states = system.element_states(state).map_err(fail)?;
        let pressure = system.element_pressures(state).map_err(fail)?;
        let positions = system.cloth_positions(state).map_err(fail)?;
        let normal_force = system.cloth_normal_forces(state).map_err(fail)?;
        let (body_energy, cloth_energy) = system.energies(state).map_err(fail)?;
        let area: Vec<f64> = system
            .triangles()
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| positions[i]);
                0.5 * (b - a).cross(&(c - a)).norm()
            })
            .collect();
        let count = |r: Regime| states.iter().filter(|s| s.regime == r).count();
        let displacement: Vec<[f64; 3]> = state
            .body
            .iter()
            .zip(system.rest_positions())
            .map(|(y, r)| {
                let d = y - r;
                [d.x, d.y, d.z]
            })
            .collect();
        let pressure_stats = FieldStats::weighted(&pressure, &area);
        let centroids: Vec<Vec3> = system
            .triangles()
            .iter()
            .map(|t| (positions[t[0]] + positions[t[1]] + positions[t[2]]) / 3.0)
            .collect();
        let probe = probe_pressure(&centroids, &pressure, &area, PROBE_RADIUS);
        let measures = triangle_measures(sim, &positions);
        let admissibility = admissibility(
            sim,
            &positions,
            &measures,
            &probe,
            &area,
            report.converged,
            report.residual,
        );
        let cloth_vertex_position: Vec<[f64; 3]> =
            positions.iter().map(|p| [p.x, p.y, p.z]).collect();
        let (landmarks, regions) = match &sim.measurements {
            Ok(m) => (
                landmark_girths(m),
                regions(
                    m,
                    &cloth_vertex_position,
                    system.triangles(),
                    &pressure,
                    &probe,
                    &area,
                ),
            ),
            Err(_) => (Vec::new(), Vec::new()),
        };
        Ok(Self {
            converged: report.converged,
            stop_reason: report.stop,
            residual: report.residual,
            force_residual: report.figures.force_residual,
            force_scale: report.figures.force_scale,
            newton_iterations: report.iterations,
            energy: report.energy,
            body_energy,
            cloth_energy,
            slack_elements: count(Regime::Slack),
            wrinkled_elements: count(Regime::Wrinkled),
            taut_elements: count(Regime::Taut),
            max_stretch: states
                .iter()
                .map(|s| s.principal_stretches[0])
                .fold(f64::NEG_INFINITY, f64::max),
            min_stretch: states
                .iter()
                .map(|s| s.principal_stretches[1])
                .fold(f64::INFINITY, f64::min),
            pressure: pressure_stats,
            mean_pressure_mmhg: pressure_stats.mean / PA_PER_MMHG,
            negative_pressure_area: pressure
                .iter()
                .zip(&area)
                .filter(|(p, _)| **p < 0.0)
                .map(|(_, a)| a)
                .sum(),
            max_body_displacement: displacement
                .iter()
                .map(|d| Vec3::new(d[0], d[1], d[2]).norm())
                .fold(0.0, f64::max),
            min_body_volume_ratio: system.min_volume_ratio(state).0,
            timings: report.figures.timings,
            setup: sim.setup_s,
            counts: Counts {
                cloth_vertices: system.num_cloth_vertices(),
                cloth_triangles: system.triangles().len(),
                pinned_vertices: sim.pinned.iter().filter(|&&p| p).count(),
                panels: sim.garment.panels.len(),
                seams: sim.garment.seams.len(),
                body_vertices: system.num_body_vertices(),
                body_tets: system.tets().len(),
                fixed_body_vertices: sim.body.tets.fixed.iter().filter(|&&f| f).count(),
                unknowns: report.figures.unknowns,
                hessian_nonzeros: report.figures.hessian_nonzeros,
                factorizations: report.factorizations,
                symbolic_analyses: report.figures.symbolic_analyses,
            },
            admissibility,
            landmarks,
            regions,
            prescription: None,
            elements: ElementFields {
                principal_stretches: states.iter().map(|s| s.principal_stretches).collect(),
                knit_stretches: measures.stretch,
                regime: states
                    .iter()
                    .map(|s| regime_name(s.regime).to_string())
                    .collect(),
                pressure,
                probe_pressure: probe,
                area,
                panel: sim.garment.face_panel.clone(),
            },
            cloth_triangles: system.triangles().to_vec(),
            cloth_vertex_normal_force: normal_force,
            cloth_vertex_position,
            body_vertex_displacement: displacement,
        })
    }
}

/// A colour legend for a result mesh's `extras`: the quantity, its unit, the range the ramp spans and the
/// ramp's anchors as `[value, [r, g, b]]` (linear RGB), so a viewer or a report can draw the scale.
pub(crate) fn legend(quantity: &str, unit: &str, lo: f64, hi: f64) -> serde_json::Value {
    let stops: Vec<serde_json::Value> = (0..=7)
        .map(|k| {
            let v = lo + (hi - lo) * k as f64 / 7.0;
            serde_json::json!([v, color(v, lo, hi)])
        })
        .collect();
    serde_json::json!({
        "skintight_legend": {"quantity": quantity, "unit": unit, "range": [lo, hi], "stops": stops,
                             "clamped": "values outside the range take the nearest end's colour"},
        "units": "positions in metres, +y up"
    })
}

fn glb(
    mesh: &TriMesh,
    colors: &[[f32; 3]],
    name: &str,
    extras: &serde_json::Value,
    double_sided: bool,
) -> Result<Vec<u8>, SimulateError> {
    write_glb(
        mesh,
        &WriteParams {
            colors: Some(colors),
            name: Some(name),
            extras: Some(extras),
            double_sided,
            ..Default::default()
        },
    )
    .map_err(|e| SimulateError {
        key: None,
        message: format!("writing a result mesh failed: {e}"),
        input: false,
    })
}

/// The worn garment as flat-coloured triangles (no shared vertices, so colours stay per triangle), each
/// coloured by `value(t)` on a ramp from `lo` to `hi`.
fn flat_garment(
    sim: &Simulation,
    result: &SimulationResult,
    value: impl Fn(usize) -> f64,
    lo: f64,
    hi: f64,
) -> (TriMesh, Vec<[f32; 3]>) {
    let mut positions = Vec::with_capacity(3 * sim.system.triangles().len());
    let mut faces = Vec::with_capacity(sim.system.triangles().len());
    let mut colors = Vec::with_capacity(positions.capacity());
    for (t, tri) in sim.system.triangles().iter().enumerate() {
        let c = color(value(t), lo, hi);
        let base = positions.len();
        for &i in tri {
            let p = result.cloth_vertex_position[i];
            positions.push(Vec3::new(p[0], p[1], p[2]));
            colors.push(c);
        }
        faces.push([base, base + 1, base + 2]);
    }
    (TriMesh::new(positions, faces), colors)
}

/// The worn garment, each triangle flat-coloured by its largest principal stretch (ramp from 1.0 to the
/// garment's maximum; slack triangles at the low end); the legend in the mesh's `extras`.
pub fn garment_glb(sim: &Simulation, result: &SimulationResult) -> Result<Vec<u8>, SimulateError> {
    let hi = result.max_stretch.max(1.0 + 1e-6);
    let (mesh, colors) = flat_garment(
        sim,
        result,
        |t| result.elements.principal_stretches[t][0],
        1.0,
        hi,
    );
    let extras = legend("largest principal stretch", "1", 1.0, hi);
    glb(&mesh, &colors, "garment (stretch)", &extras, true)
}

/// The worn garment, each triangle flat-coloured by its interface pressure as a 5 cm probe reads it, in
/// mmHg, from 0 to the fabric's pressure limit (a triangle at the top colour is at or over the limit).
pub fn garment_pressure_glb(
    sim: &Simulation,
    result: &SimulationResult,
) -> Result<Vec<u8>, SimulateError> {
    let hi = result.admissibility.limits.max_pressure_pa / PA_PER_MMHG;
    let (mesh, colors) = flat_garment(
        sim,
        result,
        |t| result.elements.probe_pressure[t] / PA_PER_MMHG,
        0.0,
        hi,
    );
    let extras = legend(
        "interface pressure (5 cm probe); the top is the fabric's pressure limit",
        "mmHg",
        0.0,
        hi,
    );
    glb(&mesh, &colors, "garment (pressure)", &extras, true)
}

/// Refinement of the body's limit surface in `body.glb`: each surface face in `n²` triangles.
const BODY_LIMIT_SAMPLES: usize = 3;

/// The deformed body as its smooth limit surface — the surface the garment lies on — tessellated finely
/// enough ([`skintight_geometry::surface::limit_mesh`], 9 triangles per surface face) that the garment
/// does not sink into coarse body triangles in a viewer; coloured by displacement magnitude (ramp from 0
/// to the largest), legend in `extras`.
pub fn body_glb(sim: &Simulation) -> Result<Vec<u8>, SimulateError> {
    let fail = |e: skintight_geometry::surface::SurfaceError| SimulateError {
        key: None,
        message: format!("tessellating the body's limit surface failed: {e}"),
        input: false,
    };
    let surface = sim.system.surface();
    let deformed = limit_mesh(
        surface.as_ref(),
        &sim.system.control_positions(&sim.state.body),
        BODY_LIMIT_SAMPLES,
    )
    .map_err(fail)?;
    let rest = limit_mesh(
        surface.as_ref(),
        &sim.system.control_positions(sim.system.rest_positions()),
        BODY_LIMIT_SAMPLES,
    )
    .map_err(fail)?;
    let displacement: Vec<f64> = deformed
        .positions
        .iter()
        .zip(&rest.positions)
        .map(|(a, b)| (a - b).norm())
        .collect();
    let hi = displacement.iter().copied().fold(0.0, f64::max);
    let colors: Vec<[f32; 3]> = displacement.iter().map(|&d| color(d, 0.0, hi)).collect();
    let extras = legend("body displacement", "m", 0.0, hi);
    glb(&deformed, &colors, "body", &extras, false)
}
