//! Uniform boundary sampling (thesis text after Eq. 185: "penalize differences in length between two
//! consecutive edges", with the energy of Eq. 184): keeps neighbouring boundary vertices from approaching
//! each other.
//!
//! For every boundary vertex `i` of a panel's outer loop (cyclic), with incoming edge
//! `e_in = X̄_i − X̄_{i−1}` and outgoing edge `e_out = X̄_{i+1} − X̄_i`:
//!
//! `R_EdgeLen = w Σ_i (‖e_in‖ − ‖e_out‖)²`
//!
//! Positions in m: the sum is in m², the value in `w`'s units times m². Every boundary vertex counts,
//! corners included (unlike [`crate::boundary_smoothness`]): an edge next to a corner should not collapse
//! either. It is a sum of squares with residuals `r_i = √w (‖e_in‖ − ‖e_out‖)` (m · √w).
//!
//! `per_element` and the residuals: one entry per boundary vertex, panel after panel, in loop order. A
//! zero-length edge has length 0 and, by convention, a zero length gradient (a subgradient of the norm).

use crate::math::{Real, Vec2};
use crate::regularizer_input::{check_input, length_and_gradient, num_boundary_vertices};
use crate::term::{
    Residuals, Term, TermError, TermEvaluation, TermGradient, TermInput, check_weight,
};

const NAME: &str = "edge_length_uniformity";

/// The consecutive boundary edge length regularizer `R_EdgeLen`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeLengthUniformity {
    weight: Real,
}

impl EdgeLengthUniformity {
    /// The regularizer with weight `weight` (≥ 0, units of the objective per m²); an error for a negative
    /// or non-finite weight.
    pub fn new(weight: Real) -> Result<Self, TermError> {
        Ok(Self {
            weight: check_weight(NAME, "weight", weight)?,
        })
    }

    /// The weight (units of the objective per m²).
    pub fn weight(&self) -> Real {
        self.weight
    }

    /// Calls `f(k, [previous, vertex, next], ‖e_in‖ − ‖e_out‖, ∂/∂e_in, ∂/∂e_out)` for every boundary
    /// vertex `k` (global per-boundary-vertex index).
    fn for_each_vertex(input: &TermInput, mut f: impl FnMut(usize, [usize; 3], Real, Vec2, Vec2)) {
        let mut k0 = 0;
        for panel in &input.mesh.panels {
            let n = panel.boundary.len();
            for i in 0..n {
                let v = [
                    panel.boundary[(i + n - 1) % n],
                    panel.boundary[i],
                    panel.boundary[(i + 1) % n],
                ];
                let (l_in, g_in) = length_and_gradient(input.pattern[v[1]] - input.pattern[v[0]]);
                let (l_out, g_out) = length_and_gradient(input.pattern[v[2]] - input.pattern[v[1]]);
                f(k0 + i, v, l_in - l_out, g_in, -g_out);
            }
            k0 += n;
        }
    }
}

impl Term for EdgeLengthUniformity {
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
        Self::for_each_vertex(input, |k, v, d, g_in, g_out| {
            per_element[k] = w * d * d;
            if let Some(g) = gradient.as_deref_mut() {
                let c = 2.0 * w * d;
                g.pattern[v[0]] -= c * g_in;
                g.pattern[v[1]] += c * (g_in - g_out);
                g.pattern[v[2]] += c * g_out;
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
        Self::for_each_vertex(input, |k, v, d, g_in, g_out| {
            res.values[k] = s * d;
            res.pattern_jacobian.extend([
                (k, v[0], -s * g_in),
                (k, v[1], s * (g_in - g_out)),
                (k, v[2], s * g_out),
            ]);
        });
        Some(Ok(res))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;
    use crate::test_support::*;

    #[test]
    fn rejects_bad_weights() {
        assert!(EdgeLengthUniformity::new(-1e-3).is_err());
        assert!(EdgeLengthUniformity::new(Real::INFINITY).is_err());
        assert_eq!(EdgeLengthUniformity::new(1.5).unwrap().weight(), 1.5);
    }

    #[test]
    fn hand_computed_rectangle() {
        // A 2 × 1 rectangle: every corner sees one edge of 2 and one of 1 → 4 (2 − 1)² w.
        let corners =
            [(0.0, 0.0), (2.0, 0.0), (2.0, 1.0), (0.0, 1.0)].map(|(x, y)| Vec2::new(x, y));
        let (mesh, pattern) = polygon_panel(&corners);
        let term = EdgeLengthUniformity::new(0.5).unwrap();
        assert!((term_value(&term, &mesh, &pattern) - 2.0).abs() < 1e-12);
        // A square is uniform.
        let square = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)].map(|(x, y)| Vec2::new(x, y));
        let (mesh, pattern) = polygon_panel(&square);
        assert_eq!(term_value(&term, &mesh, &pattern), 0.0);
    }

    #[test]
    fn gradient_and_residuals_match_finite_differences() {
        for seed in 0..4 {
            let (mesh, pattern) = two_panel_mesh(3, 2, seed);
            let pattern = perturbed(&pattern, 0.03, 20 + seed);
            let term = EdgeLengthUniformity::new(4.0).unwrap();
            check_pattern_gradient(&term, &mesh, &pattern);
            check_pattern_residuals(&term, &mesh, &pattern);
        }
    }

    #[test]
    fn zero_length_edges_give_finite_results() {
        let corners =
            [(0.0, 0.0), (1.0, 0.0), (1.0, 0.0), (0.0, 1.0)].map(|(x, y)| Vec2::new(x, y));
        let mesh = single_panel_mesh(4, &[], &[0, 1, 2, 3]);
        let term = EdgeLengthUniformity::new(1.0).unwrap();
        let fabric = fabric();
        let cloth = vec![Vec3::zeros(); mesh.num_cloth_vertices];
        let input = TermInput {
            mesh: &mesh,
            cloth: &cloth,
            pattern: &corners,
            fabric: &fabric,
        };
        let mut gradient = TermGradient::zeros(&mesh);
        let eval = term.evaluate(&input, Some(&mut gradient)).unwrap();
        // Vertex 1: (1 − 0)², vertex 2: (0 − √2)², vertex 3: (√2 − 1)², vertex 0: (1 − 1)².
        let expected = 1.0 + 2.0 + (2f64.sqrt() - 1.0).powi(2);
        assert!((eval.value - expected).abs() < 1e-12);
        assert!(
            gradient
                .pattern
                .iter()
                .all(|g| g.x.is_finite() && g.y.is_finite())
        );
    }

    #[test]
    fn rejects_out_of_range_boundary() {
        let mesh = single_panel_mesh(3, &[], &[0, 1, 5]);
        let pattern = vec![Vec2::zeros(); 3];
        let fabric = fabric();
        let cloth = vec![Vec3::zeros(); 3];
        let input = TermInput {
            mesh: &mesh,
            cloth: &cloth,
            pattern: &pattern,
            fabric: &fabric,
        };
        let term = EdgeLengthUniformity::new(1.0).unwrap();
        assert!(term.evaluate(&input, None).is_err());
        assert!(term.residuals(&input).unwrap().is_err());
    }
}
