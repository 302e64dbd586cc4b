//! Smooth pattern boundaries (thesis Eq. 185): a discrete bending energy of each panel's outer boundary
//! loop.
//!
//! For every boundary vertex `i` of a panel's outer loop (counter-clockwise, cyclic), with incoming edge
//! `e_in = X̄_i − X̄_{i−1}` and outgoing edge `e_out = X̄_{i+1} − X̄_i`:
//!
//! `R_Smooth = w Σ_i κ_i² / (‖e_in‖ + ‖e_out‖)`,  `κ_i = atan2(e_in × e_out, e_in · e_out)`
//!
//! `κ_i ∈ (−π, π]` is the turning angle (rad) at the vertex: positive where the boundary turns left
//! (convex for a counter-clockwise loop). The thesis writes the integrated curvature as
//! `2 e_in × e_out / (‖e_in‖‖e_out‖ + e_in · e_out) = 2 tan(κ/2)`, which agrees with `κ` to second order
//! but diverges when the boundary folds back; the turning angle stays bounded (`κ² ≤ π²`) and is
//! well-defined for any two non-zero edges. `κ²` is continuous everywhere; its gradient flips sign where
//! the boundary folds back exactly (`κ = ±π`).
//!
//! Positions in m: the sum is in 1/m, the value in `w`'s units per m.
//!
//! **Corners are excluded.** A vertex where the boundary's border changes — the edge before it and the
//! edge after it have different [`DesignPanel::boundary_borders`](crate::DesignPanel) (free ↔ seam, or
//! one seam ↔ another) — is where a seam meets the free boundary or another seam: a pattern corner the
//! designer needs to keep sharp. Such vertices contribute nothing. A panel whose whole loop has one border
//! has no excluded vertex.
//!
//! A vertex whose incoming or outgoing edge has zero length has no turning angle: it contributes 0 with a
//! zero gradient (documented convention, so that no NaN can arise).
//!
//! `per_element`: one entry per boundary vertex, panel after panel, in loop order (0 for excluded and
//! degenerate vertices). It is a sum of squares with residuals `r_i = √w κ_i / √(‖e_in‖ + ‖e_out‖)`, one
//! per boundary vertex in the same order (0 where excluded).

use crate::math::{Real, Vec2};
use crate::regularizer_input::{check_input, num_boundary_vertices};
use crate::term::{
    Residuals, Term, TermError, TermEvaluation, TermGradient, TermInput, check_weight,
};

const NAME: &str = "boundary_smoothness";

/// The boundary smoothness regularizer `R_Smooth` (Eq. 185), corners excluded.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundarySmoothness {
    weight: Real,
}

/// The bending quantities at one boundary vertex.
struct Bend {
    /// The vertices before, at and after the bend.
    vertices: [usize; 3],
    /// Turning angle κ (rad).
    kappa: Real,
    /// `‖e_in‖ + ‖e_out‖` (m).
    length: Real,
    /// `∂κ/∂e_in`, `∂κ/∂e_out` (1/m).
    dkappa: [Vec2; 2],
    /// `∂length/∂e_in`, `∂length/∂e_out` (dimensionless).
    dlength: [Vec2; 2],
}

/// Left perpendicular `(−y, x)`.
fn perp(v: Vec2) -> Vec2 {
    Vec2::new(-v.y, v.x)
}

impl BoundarySmoothness {
    /// The regularizer with weight `weight` (≥ 0, units of the objective times m); an error for a
    /// negative or non-finite weight.
    pub fn new(weight: Real) -> Result<Self, TermError> {
        Ok(Self {
            weight: check_weight(NAME, "weight", weight)?,
        })
    }

    /// The weight (units of the objective times m).
    pub fn weight(&self) -> Real {
        self.weight
    }

    /// Calls `f(k, bend)` for every boundary vertex `k` (global per-boundary-vertex index) that is neither
    /// a corner nor degenerate.
    fn for_each_bend(input: &TermInput, mut f: impl FnMut(usize, Bend)) {
        let pattern = input.pattern;
        let mut k0 = 0;
        for panel in &input.mesh.panels {
            let n = panel.boundary.len();
            for i in 0..n {
                let prev = (i + n - 1) % n;
                let next = (i + 1) % n;
                if n < 2 || panel.boundary_borders[prev] != panel.boundary_borders[i] {
                    continue;
                }
                let vertices = [
                    panel.boundary[prev],
                    panel.boundary[i],
                    panel.boundary[next],
                ];
                let e_in = pattern[vertices[1]] - pattern[vertices[0]];
                let e_out = pattern[vertices[2]] - pattern[vertices[1]];
                let (l_in2, l_out2) = (e_in.norm_squared(), e_out.norm_squared());
                if l_in2 == 0.0 || l_out2 == 0.0 {
                    continue;
                }
                let (l_in, l_out) = (l_in2.sqrt(), l_out2.sqrt());
                let kappa = e_in.perp(&e_out).atan2(e_in.dot(&e_out));
                f(
                    k0 + i,
                    Bend {
                        vertices,
                        kappa,
                        length: l_in + l_out,
                        dkappa: [-perp(e_in) / l_in2, perp(e_out) / l_out2],
                        dlength: [e_in / l_in, e_out / l_out],
                    },
                );
            }
            k0 += n;
        }
    }
}

/// Adds `g_in` (derivative with respect to `e_in`) and `g_out` to the three vertices of a bend.
fn scatter(target: &mut [Vec2], vertices: [usize; 3], g_in: Vec2, g_out: Vec2) {
    target[vertices[0]] -= g_in;
    target[vertices[1]] += g_in - g_out;
    target[vertices[2]] += g_out;
}

impl Term for BoundarySmoothness {
    fn name(&self) -> &'static str {
        NAME
    }

    fn evaluate(
        &self,
        input: &TermInput,
        mut gradient: Option<&mut TermGradient>,
    ) -> Result<TermEvaluation, TermError> {
        check_input(NAME, input, gradient.as_deref())?;
        let w = self.weight;
        let mut per_element = vec![0.0; num_boundary_vertices(input)];
        Self::for_each_bend(input, |k, b| {
            per_element[k] = w * b.kappa * b.kappa / b.length;
            if let Some(g) = gradient.as_deref_mut() {
                let dk = 2.0 * w * b.kappa / b.length;
                let dl = -w * b.kappa * b.kappa / (b.length * b.length);
                let [g_in, g_out] = [0, 1].map(|e| dk * b.dkappa[e] + dl * b.dlength[e]);
                scatter(&mut g.pattern, b.vertices, g_in, g_out);
            }
        });
        TermEvaluation::from_per_element(NAME, per_element)
    }

    fn residuals(&self, input: &TermInput) -> Option<Result<Residuals, TermError>> {
        if let Err(e) = check_input(NAME, input, None) {
            return Some(Err(e));
        }
        let s = self.weight.sqrt();
        let mut res = Residuals {
            values: vec![0.0; num_boundary_vertices(input)],
            ..Residuals::default()
        };
        Self::for_each_bend(input, |k, b| {
            let root = b.length.sqrt();
            res.values[k] = s * b.kappa / root;
            let dl = -0.5 * s * b.kappa / (b.length * root);
            let [g_in, g_out] = [0, 1].map(|e| s / root * b.dkappa[e] + dl * b.dlength[e]);
            let [a, m, c] = b.vertices;
            res.pattern_jacobian
                .extend([(k, a, -g_in), (k, m, g_in - g_out), (k, c, g_out)]);
        });
        Some(Ok(res))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;
    use crate::test_support::*;
    use std::f64::consts::PI;

    fn evaluate(
        term: &BoundarySmoothness,
        mesh: &crate::DesignMesh,
        pattern: &[Vec2],
    ) -> TermEvaluation {
        let fabric = fabric();
        let cloth = vec![Vec3::zeros(); mesh.num_cloth_vertices];
        let input = TermInput {
            mesh,
            cloth: &cloth,
            pattern,
            fabric: &fabric,
        };
        term.evaluate(&input, None).unwrap()
    }

    #[test]
    fn rejects_bad_weights() {
        assert!(BoundarySmoothness::new(-0.5).is_err());
        assert!(BoundarySmoothness::new(Real::NAN).is_err());
        assert_eq!(BoundarySmoothness::new(2.0).unwrap().weight(), 2.0);
    }

    #[test]
    fn hand_computed_square() {
        // A square of side 0.5 m: κ = π/2 at each corner, edges 0.5 + 0.5 = 1 m.
        let corners =
            [(0.0, 0.0), (0.5, 0.0), (0.5, 0.5), (0.0, 0.5)].map(|(x, y)| Vec2::new(x, y));
        let (mesh, pattern) = polygon_panel(&corners);
        let term = BoundarySmoothness::new(3.0).unwrap();
        let eval = evaluate(&term, &mesh, &pattern);
        let expected = 3.0 * 4.0 * (PI / 2.0).powi(2) / 1.0;
        assert!(
            (eval.value - expected).abs() < 1e-12,
            "{} vs {expected}",
            eval.value
        );
        assert_eq!(eval.per_element.len(), 4);
    }

    #[test]
    fn hand_computed_reflex_vertex_and_straight_vertex() {
        // An L-like pentagon with a straight vertex (κ = 0) and a reflex one (κ = −π/2).
        let corners = [
            (0.0, 0.0),
            (1.0, 0.0),
            (2.0, 0.0),
            (2.0, 1.0),
            (1.0, 1.0),
            (1.0, 2.0),
            (0.0, 2.0),
        ]
        .map(|(x, y)| Vec2::new(x, y));
        let mesh = single_panel_mesh(7, &[], &(0..7).collect::<Vec<_>>());
        let term = BoundarySmoothness::new(1.0).unwrap();
        let eval = evaluate(&term, &mesh, &corners);
        let q = (PI / 2.0).powi(2);
        let expected = [q / 3.0, 0.0, q / 2.0, q / 2.0, q / 2.0, q / 2.0, q / 3.0];
        for (k, (a, b)) in eval.per_element.iter().zip(expected).enumerate() {
            assert!((a - b).abs() < 1e-12, "vertex {k}: {a} vs {b}");
        }
    }

    #[test]
    fn corners_where_the_border_changes_are_excluded() {
        let corners =
            [(0.0, 0.0), (0.5, 0.0), (0.5, 0.5), (0.0, 0.5)].map(|(x, y)| Vec2::new(x, y));
        let (mut mesh, pattern) = polygon_panel(&corners);
        // Edge 1 → 2 sewn: vertices 1 (free → seam) and 2 (seam → free) are corners.
        mesh.panels[0].boundary_borders[1] = Some(0);
        let term = BoundarySmoothness::new(1.0).unwrap();
        let eval = evaluate(&term, &mesh, &pattern);
        assert_eq!(eval.per_element[1], 0.0);
        assert_eq!(eval.per_element[2], 0.0);
        assert!(eval.per_element[0] > 0.0 && eval.per_element[3] > 0.0);
        // A change between two different seams is a corner too.
        mesh.panels[0].boundary_borders[2] = Some(1);
        let eval = evaluate(&term, &mesh, &pattern);
        assert_eq!(eval.per_element[2], 0.0);
        // A loop sewn all around with one panel has no corner.
        mesh.panels[0].boundary_borders = vec![Some(0); 4];
        let eval = evaluate(&term, &mesh, &pattern);
        assert!(eval.per_element.iter().all(|&v| v > 0.0));
        check_pattern_gradient(&term, &mesh, &perturbed(&pattern, 0.05, 1));
    }

    #[test]
    fn zero_length_edges_contribute_nothing() {
        let corners = [(0.0, 0.0), (0.5, 0.0), (0.5, 0.0), (0.5, 0.5), (0.0, 0.5)]
            .map(|(x, y)| Vec2::new(x, y));
        let mesh = single_panel_mesh(5, &[], &(0..5).collect::<Vec<_>>());
        let term = BoundarySmoothness::new(1.0).unwrap();
        let eval = evaluate(&term, &mesh, &corners);
        assert_eq!(eval.per_element[1], 0.0);
        assert_eq!(eval.per_element[2], 0.0);
        assert!(eval.value.is_finite());
        let res = term_residuals(&term, &mesh, &corners);
        assert!(res.values.iter().all(|r| r.is_finite()));
    }

    #[test]
    fn loops_of_fewer_than_two_vertices_contribute_nothing() {
        let mesh = single_panel_mesh(1, &[], &[0]);
        let term = BoundarySmoothness::new(1.0).unwrap();
        let eval = evaluate(&term, &mesh, &[Vec2::new(0.1, 0.2)]);
        assert_eq!(eval.per_element, vec![0.0]);
        let mesh = single_panel_mesh(1, &[], &[]);
        assert_eq!(evaluate(&term, &mesh, &[Vec2::zeros()]).value, 0.0);
    }

    #[test]
    fn fold_back_is_bounded() {
        // A degenerate "loop" going out and back: κ = ±π at both ends, value π²/(2 l) each.
        let pts = [Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0)];
        let mesh = single_panel_mesh(2, &[], &[0, 1]);
        let term = BoundarySmoothness::new(1.0).unwrap();
        let eval = evaluate(&term, &mesh, &pts);
        assert!((eval.value - PI * PI).abs() < 1e-12, "{}", eval.value);
    }

    #[test]
    fn gradient_and_residuals_match_finite_differences() {
        for seed in 0..4 {
            let (mesh, pattern) = two_panel_mesh(3, 4, seed);
            let pattern = perturbed(&pattern, 0.02, 10 + seed);
            let term = BoundarySmoothness::new(0.7).unwrap();
            check_pattern_gradient(&term, &mesh, &pattern);
            check_pattern_residuals(&term, &mesh, &pattern);
        }
    }

    #[test]
    fn rejects_mismatched_borders() {
        let corners = [(0.0, 0.0), (0.5, 0.0), (0.5, 0.5)].map(|(x, y)| Vec2::new(x, y));
        let (mut mesh, pattern) = polygon_panel(&corners);
        mesh.panels[0].boundary_borders.pop();
        let fabric = fabric();
        let cloth = vec![Vec3::zeros(); mesh.num_cloth_vertices];
        let input = TermInput {
            mesh: &mesh,
            cloth: &cloth,
            pattern: &pattern,
            fabric: &fabric,
        };
        let term = BoundarySmoothness::new(1.0).unwrap();
        assert!(term.evaluate(&input, None).is_err());
        assert!(term.residuals(&input).unwrap().is_err());
    }
}
