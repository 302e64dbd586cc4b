//! Admissibility: whether a worn garment stays within what its fabric and its wearer can bear
//! (`garment.fabric.limits`, docs/SCENE.md), and, where it does not, the violations a person can act on.
//!
//! Checked on the equilibrium, triangle by triangle:
//!
//! - **stretch along the knit's two directions.** For a pattern triangle with rest corners `u₀, u₁, u₂`
//!   (m, 2D) worn at `x₀, x₁, x₂` (m, 3D), the deformation gradient is `F = [x₁−x₀ x₂−x₀] [u₁−u₀ u₂−u₀]⁻¹`
//!   (3 × 2). The stretch along a unit pattern direction `d` is `|F d|` (dimensionless): along the piece's
//!   grain line `g` (the wale direction, [`grain_direction`], the same arrow the cut-ready files carry) it is
//!   the wale stretch, along `g⊥` the course stretch. Kinds `stretch_wale`, `stretch_course`.
//! - **interface pressure** (Pa) as a 5 cm pressure probe reads it: the triangles' normal force on the body
//!   over their deformed area, averaged within 2.5 cm (`result.json`'s `elements.probe_pressure`,
//!   [`super::probe_pressure`]; one triangle's own pressure is too noisy to bound). Kind `pressure`.
//! - **pattern triangle quality** `q = 4√3·A / (a² + b² + c²)` of the rest triangle (1 equilateral, 0
//!   degenerate, negative inverted). Kind `pattern_quality` (the value is the smallest `q`, the limit the
//!   smallest allowed).
//! - **equilibrium**: a solve that stopped before converging has no trustworthy stresses at all. Kind
//!   `not_converged` (value: the relative residual; limit: the solver's tolerance).
//!
//! Violations are grouped by kind and panel: each names the panel, how many triangles and how much area
//! (m², deformed) break the limit, the worst value and where the worst triangle lies (its centroid, m).
//! A NaN counts as a violation. The garment is admissible when there is none.

use serde::{Deserialize, Serialize};
use skintight_garment::pattern::grain_line::grain_direction;
use skintight_geometry::{Vec2, Vec3};

use super::Simulation;
use crate::scene::FabricLimits;

/// The verdict: `admissible` iff `violations` is empty.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Admissibility {
    /// Whether the garment is within every limit.
    pub admissible: bool,
    /// What breaks a limit, worst first within each kind.
    pub violations: Vec<Violation>,
    /// The limits checked (the scene's `garment.fabric.limits`, defaults filled in; for a curve fabric the
    /// stretch limits are no more than where its curves end, [`crate::scene::FabricSpec::stretch_limits`]).
    pub limits: FabricLimits,
}

/// One kind of limit broken on one panel.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Violation {
    /// `stretch_wale`, `stretch_course`, `pressure`, `pattern_quality`, `not_converged`, or
    /// `prescription` (a band outside the order's prescribed window, [`super::prescription`]; value 0
    /// for a band the garment does not cover), or `grip` (an opening of a template's garment below the
    /// least pressure it needs, or with a probe below 0 mmHg, [`super::grip`]).
    pub kind: String,
    /// Where, for a person: the panel, the extent and the worst spot.
    #[serde(rename = "where")]
    pub location: String,
    /// The worst value (unit in `unit`).
    pub value: f64,
    /// The limit it breaks (same unit).
    pub limit: f64,
    /// Unit of `value` and `limit`: `1` (dimensionless), `Pa`, or `mmHg` (prescription).
    pub unit: String,
    /// The panel's name (`null` for `not_converged`).
    pub panel: Option<String>,
    /// Cloth triangles beyond the limit.
    pub triangles: usize,
    /// Their deformed area (m²).
    pub area_m2: f64,
    /// Centroid of the worst triangle at equilibrium (m), body coordinates (`null` for `not_converged`).
    pub point: Option<[f64; 3]>,
}

/// Which way a limit bounds a value.
#[derive(Clone, Copy)]
enum Bound {
    /// The value must not exceed the limit.
    Upper,
    /// The value must not fall below the limit.
    Lower,
}

impl Bound {
    fn breaks(self, value: f64, limit: f64) -> bool {
        match self {
            Bound::Upper => !(value <= limit),
            Bound::Lower => !(value >= limit),
        }
    }

    /// Whether `a` is worse than `b` (NaN worst).
    fn worse(self, a: f64, b: f64) -> bool {
        if a.is_nan() {
            return !b.is_nan();
        }
        match self {
            Bound::Upper => a > b,
            Bound::Lower => a < b,
        }
    }
}

/// Per cloth triangle, what the checks need.
pub struct TriangleMeasures {
    /// `[wale, course]` stretch (dimensionless).
    pub stretch: Vec<[f64; 2]>,
    /// Rest (pattern) shape quality (dimensionless).
    pub quality: Vec<f64>,
}

/// The wale direction (unit, pattern plane) of each panel, as the cut-ready files draw its grain line:
/// from the panel's pattern and its placement on the body.
pub fn wale_directions(sim: &Simulation) -> Vec<Vec2> {
    let up = sim.scene.patterns.params().up;
    sim.garment
        .panels
        .iter()
        .map(|panel| {
            let placed: Vec<Vec3> = panel
                .cloth_vertex
                .iter()
                .map(|&c| sim.garment.positions[c])
                .collect();
            grain_direction(&panel.pattern, &placed, &panel.faces, up)
        })
        .collect()
}

/// Wale and course stretches and pattern quality of every cloth triangle, at cloth positions `positions`
/// (`#Vc`, m).
pub fn triangle_measures(sim: &Simulation, positions: &[Vec3]) -> TriangleMeasures {
    let n = sim.system.triangles().len();
    let mut stretch = vec![[f64::NAN; 2]; n];
    let mut quality = vec![f64::NAN; n];
    for (panel, g) in sim.garment.panels.iter().zip(wale_directions(sim)) {
        let g_perp = Vec2::new(-g.y, g.x);
        for (f, &[a, b, c]) in panel.faces.iter().enumerate() {
            let t = panel.cloth_face[f];
            let [u0, u1, u2] = [a, b, c].map(|v| panel.pattern[v]);
            let [x0, x1, x2] = [a, b, c].map(|v| positions[panel.cloth_vertex[v]]);
            let (e1, e2) = (u1 - u0, u2 - u0);
            let det = e1.x * e2.y - e1.y * e2.x;
            let lengths2 = e1.norm_squared() + e2.norm_squared() + (u2 - u1).norm_squared();
            quality[t] = if lengths2 > 0.0 {
                2.0 * 3f64.sqrt() * det / lengths2
            } else {
                f64::NAN
            };
            // F d = [x1−x0 x2−x0] · Du⁻¹ d, Du = [e1 e2].
            let image = |d: Vec2| {
                let alpha = (e2.y * d.x - e2.x * d.y) / det;
                let beta = (-e1.y * d.x + e1.x * d.y) / det;
                ((x1 - x0) * alpha + (x2 - x0) * beta).norm()
            };
            stretch[t] = if det != 0.0 {
                [image(g), image(g_perp)]
            } else {
                [f64::NAN; 2]
            };
        }
    }
    TriangleMeasures { stretch, quality }
}

/// The verdict on a garment at equilibrium: `positions` (`#Vc`, m), the per-triangle `measures` of
/// [`triangle_measures`] there, probe `pressure` (Pa) and deformed `area` (m²); `converged` and `residual`
/// from the solve.
pub fn admissibility(
    sim: &Simulation,
    positions: &[Vec3],
    measures: &TriangleMeasures,
    pressure: &[f64],
    area: &[f64],
    converged: bool,
    residual: f64,
) -> Admissibility {
    let mut limits = sim.scene.garment.fabric.limits;
    limits.max_stretch = sim.scene.garment.fabric.stretch_limits();
    let centroid = |t: usize| {
        let [a, b, c] = sim.system.triangles()[t].map(|i| positions[i]);
        let m = (a + b + c) / 3.0;
        [m.x, m.y, m.z]
    };
    let mut violations = Vec::new();
    if !converged {
        violations.push(Violation {
            kind: "not_converged".into(),
            location:
                "the equilibrium solve stopped before converging: no stress or pressure of this \
                       garment can be trusted"
                    .into(),
            value: residual,
            limit: sim.scene.solver.tolerance,
            unit: "1".into(),
            panel: None,
            triangles: sim.system.triangles().len(),
            area_m2: area.iter().sum(),
            point: None,
        });
    }
    let checks: [(&str, Bound, f64, &str, &dyn Fn(usize) -> f64); 4] = [
        (
            "stretch_wale",
            Bound::Upper,
            limits.max_stretch.wale,
            "1",
            &|t| measures.stretch[t][0],
        ),
        (
            "stretch_course",
            Bound::Upper,
            limits.max_stretch.course,
            "1",
            &|t| measures.stretch[t][1],
        ),
        (
            "pressure",
            Bound::Upper,
            limits.max_pressure_pa,
            "Pa",
            &|t| pressure[t],
        ),
        (
            "pattern_quality",
            Bound::Lower,
            limits.min_pattern_quality,
            "1",
            &|t| measures.quality[t],
        ),
    ];
    for (kind, bound, limit, unit, value) in checks {
        for panel in &sim.garment.panels {
            let mut worst: Option<(usize, f64)> = None;
            let (mut triangles, mut area_m2) = (0, 0.0);
            for &t in &panel.cloth_face {
                let v = value(t);
                if !bound.breaks(v, limit) {
                    continue;
                }
                triangles += 1;
                area_m2 += area[t];
                if worst.is_none_or(|(_, w)| bound.worse(v, w)) {
                    worst = Some((t, v));
                }
            }
            let Some((t, v)) = worst else { continue };
            let point = centroid(t);
            violations.push(Violation {
                kind: kind.into(),
                location: format!(
                    "panel {:?}: {triangles} triangle{} ({:.1} cm²), worst at ({:.3}, {:.3}, {:.3}) m",
                    panel.name,
                    if triangles == 1 { "" } else { "s" },
                    area_m2 * 1e4,
                    point[0],
                    point[1],
                    point[2]
                ),
                value: v,
                limit,
                unit: unit.into(),
                panel: Some(panel.name.clone()),
                triangles,
                area_m2,
                point: Some(point),
            });
        }
    }
    Admissibility {
        admissible: violations.is_empty(),
        violations,
        limits,
    }
}

/// One line for a person: `admissible` or what is wrong, worst kinds first.
pub fn verdict_line(a: &Admissibility) -> String {
    if a.admissible {
        return "admissible: within the fabric's stretch, pressure and pattern limits".into();
    }
    let parts: Vec<String> = a
        .violations
        .iter()
        .map(|v| {
            if v.kind == "prescription" || v.kind == "grip" {
                return format!("{}: {}", v.kind, v.location);
            }
            let (value, limit) = if v.unit == "Pa" {
                (
                    format!(
                        "{:.0} Pa ({:.0} mmHg)",
                        v.value,
                        v.value / skintight_physics::PA_PER_MMHG
                    ),
                    format!("{:.0} Pa", v.limit),
                )
            } else if v.kind == "not_converged" {
                // Relative residuals are small: in scientific notation.
                (format!("{:.2e}", v.value), format!("{:.0e}", v.limit))
            } else {
                (format!("{:.3}", v.value), format!("{:.3}", v.limit))
            };
            let relation = if v.kind == "pattern_quality" {
                "below"
            } else {
                "above"
            };
            match &v.panel {
                Some(p) => format!("{} {value} {relation} {limit} on {p:?}", v.kind),
                None => format!("{} (residual {value}, tolerance {limit})", v.kind),
            }
        })
        .collect();
    format!(
        "NOT ADMISSIBLE: {} violation{}: {}",
        a.violations.len(),
        if a.violations.len() == 1 { "" } else { "s" },
        parts.join("; ")
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The verdict names a solve that stopped short with its residual and tolerance as a reader can use
    /// them (relative residuals are small: `{:.3}` would print 0.000 for both).
    #[test]
    fn verdict_line_gives_a_not_converged_residual_in_scientific_notation() {
        let a = Admissibility {
            admissible: false,
            violations: vec![Violation {
                kind: "not_converged".into(),
                location: "the equilibrium solve stopped before converging".into(),
                value: 3.5189e-6,
                limit: 1e-6,
                unit: "1".into(),
                panel: None,
                triangles: 10,
                area_m2: 0.1,
                point: None,
            }],
            limits: FabricLimits::default(),
        };
        assert_eq!(
            verdict_line(&a),
            "NOT ADMISSIBLE: 1 violation: not_converged (residual 3.52e-6, tolerance 1e-6)"
        );
    }
}
