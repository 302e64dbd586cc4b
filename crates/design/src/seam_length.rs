//! Seam compatibility (thesis Eq. 184): the two sides of a seam must have the same length to be sewn.
//!
//! For every seam with sides `a = vertices[0]` and `b = vertices[1]` (`a[k]` sewn to `b[k]`) and every
//! pair of corresponding edges `k → k + 1` (plus the closing edge `n − 1 → 0` of a closed seam):
//!
//! `R_SeamLen = w Σ_seams Σ_k (‖a[k+1] − a[k]‖ − ‖b[k+1] − b[k]‖)²`
//!
//! with the pattern positions `X̄` in m, so the sum is in m² and the value in `w`'s units times m². The
//! term depends only on the pattern positions; the cloth gradient is left untouched. It is a sum of
//! squares with residuals `r_k = √w (‖e_a‖ − ‖e_b‖)` (m · √w).
//!
//! `per_element`: one entry per seam edge pair, seam after seam, edge `k` in seam order (the closing edge
//! of a closed seam last). A seam with fewer than two vertices has no edge pair (a closed one-vertex seam
//! has one zero-length pair).
//!
//! A zero-length edge has length 0 and, by convention, a zero length gradient (a subgradient of the norm),
//! so the value and gradient are always finite.

use crate::math::{Real, Vec2};
use crate::regularizer_input::{check_input, length_and_gradient};
use crate::term::{
    Residuals, Term, TermError, TermEvaluation, TermGradient, TermInput, check_weight,
};

const NAME: &str = "seam_length";

/// The seam compatibility regularizer `R_SeamLen` (Eq. 184).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SeamLength {
    weight: Real,
}

/// One pair of corresponding seam edges: the edge's end vertices on side 0 and on side 1.
struct EdgePair {
    a: [usize; 2],
    b: [usize; 2],
}

impl SeamLength {
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

    /// All corresponding edge pairs, in `per_element` order, after checking the seams against the mesh.
    fn edge_pairs(input: &TermInput) -> Result<Vec<EdgePair>, TermError> {
        let n = input.mesh.num_pattern_vertices();
        let mut pairs = Vec::new();
        for (s, seam) in input.mesh.seams.iter().enumerate() {
            let [a, b] = &seam.vertices;
            if a.len() != b.len() {
                return Err(TermError::Invalid {
                    term: NAME,
                    message: format!(
                        "seam {s}: the sides have {} and {} vertices",
                        a.len(),
                        b.len()
                    ),
                });
            }
            if let Some(&v) = a.iter().chain(b).find(|&&v| v >= n) {
                return Err(TermError::Invalid {
                    term: NAME,
                    message: format!("seam {s}: vertex {v} is not a pattern vertex (#Vp = {n})"),
                });
            }
            let m = a.len();
            let edges = if seam.closed { m } else { m.saturating_sub(1) };
            for k in 0..edges {
                let k1 = (k + 1) % m;
                pairs.push(EdgePair {
                    a: [a[k], a[k1]],
                    b: [b[k], b[k1]],
                });
            }
        }
        Ok(pairs)
    }

    /// `(‖e_a‖ − ‖e_b‖, ∂/∂e_a, ∂/∂e_b)` of one edge pair.
    fn difference(pattern: &[Vec2], pair: &EdgePair) -> (Real, Vec2, Vec2) {
        let (la, ga) = length_and_gradient(pattern[pair.a[1]] - pattern[pair.a[0]]);
        let (lb, gb) = length_and_gradient(pattern[pair.b[1]] - pattern[pair.b[0]]);
        (la - lb, ga, -gb)
    }
}

impl Term for SeamLength {
    fn name(&self) -> &'static str {
        NAME
    }

    fn evaluate(
        &self,
        input: &TermInput,
        mut gradient: Option<&mut TermGradient>,
    ) -> Result<TermEvaluation, TermError> {
        check_input(NAME, input, gradient.as_deref())?;
        let pairs = Self::edge_pairs(input)?;
        let mut per_element = Vec::with_capacity(pairs.len());
        for pair in &pairs {
            let (d, ga, gb) = Self::difference(input.pattern, pair);
            per_element.push(self.weight * d * d);
            if let Some(g) = gradient.as_deref_mut() {
                let c = 2.0 * self.weight * d;
                g.pattern[pair.a[1]] += c * ga;
                g.pattern[pair.a[0]] -= c * ga;
                g.pattern[pair.b[1]] += c * gb;
                g.pattern[pair.b[0]] -= c * gb;
            }
        }
        TermEvaluation::from_per_element(NAME, per_element)
    }

    fn residuals(&self, input: &TermInput) -> Option<Result<Residuals, TermError>> {
        let run = || {
            check_input(NAME, input, None)?;
            let pairs = Self::edge_pairs(input)?;
            let s = self.weight.sqrt();
            let mut res = Residuals::default();
            for (k, pair) in pairs.iter().enumerate() {
                let (d, ga, gb) = Self::difference(input.pattern, pair);
                res.values.push(s * d);
                res.pattern_jacobian.extend([
                    (k, pair.a[1], s * ga),
                    (k, pair.a[0], -s * ga),
                    (k, pair.b[1], s * gb),
                    (k, pair.b[0], -s * gb),
                ]);
            }
            Ok(res)
        };
        Some(run())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::*;

    #[test]
    fn rejects_bad_weights() {
        assert!(SeamLength::new(-1.0).is_err());
        assert!(SeamLength::new(Real::NAN).is_err());
        assert!(SeamLength::new(Real::INFINITY).is_err());
        assert_eq!(SeamLength::new(0.0).unwrap().weight(), 0.0);
    }

    #[test]
    fn hand_computed_value() {
        // One open seam of three vertices per side. Side 0: edges of length 1 and 2; side 1: 1.5 and 2.
        let (mut mesh, _) = two_panel_mesh(1, 2, 0);
        let mut pattern = vec![Vec2::zeros(); mesh.num_pattern_vertices()];
        let a = mesh.seams[0].vertices[0].clone();
        let b = mesh.seams[0].vertices[1].clone();
        pattern[a[0]] = Vec2::new(0.0, 0.0);
        pattern[a[1]] = Vec2::new(0.0, 1.0);
        pattern[a[2]] = Vec2::new(0.0, 3.0);
        pattern[b[0]] = Vec2::new(5.0, 0.0);
        pattern[b[1]] = Vec2::new(5.9, 1.2);
        pattern[b[2]] = Vec2::new(5.9, 3.2);
        let term = SeamLength::new(2.0).unwrap();
        let eval_value = term_value(&term, &mesh, &pattern);
        assert!((eval_value - 2.0 * 0.25).abs() < 1e-12, "{eval_value}");
        // Closing the seam adds the edge pair (a2 → a0: 3, b2 → b0: √(0.81 + 10.24)).
        mesh.seams[0].closed = true;
        let closing: Real = 3.0 - (0.9f64 * 0.9 + 3.2 * 3.2).sqrt();
        let expected = 2.0 * (0.25 + closing * closing);
        let value = term_value(&term, &mesh, &pattern);
        assert!((value - expected).abs() < 1e-12, "{value} vs {expected}");
    }

    #[test]
    fn per_element_is_one_entry_per_edge_pair() {
        let (mut mesh, pattern) = two_panel_mesh(2, 4, 3);
        let pattern = perturbed(&pattern, 0.02, 4);
        let term = SeamLength::new(1.0).unwrap();
        let eval = try_evaluate(&term, &mesh, &pattern, None).unwrap();
        assert_eq!(eval.per_element.len(), 4);
        mesh.seams[0].closed = true;
        let eval = try_evaluate(&term, &mesh, &pattern, None).unwrap();
        assert_eq!(eval.per_element.len(), 5);
    }

    #[test]
    fn gradient_matches_finite_differences() {
        for seed in 0..4 {
            let (mut mesh, pattern) = two_panel_mesh(2, 5, seed);
            let pattern = perturbed(&pattern, 0.03, 100 + seed);
            mesh.seams[0].closed = seed % 2 == 1;
            let term = SeamLength::new(3.5).unwrap();
            check_pattern_gradient(&term, &mesh, &pattern);
            check_pattern_residuals(&term, &mesh, &pattern);
        }
    }

    #[test]
    fn zero_length_edges_give_finite_results() {
        let (mesh, pattern) = two_panel_mesh(1, 2, 0);
        let mut pattern = pattern;
        let a = &mesh.seams[0].vertices[0];
        pattern[a[1]] = pattern[a[0]];
        let term = SeamLength::new(1.0).unwrap();
        let mut gradient = TermGradient::zeros(&mesh);
        let eval = try_evaluate(&term, &mesh, &pattern, Some(&mut gradient)).unwrap();
        assert!(eval.value.is_finite() && eval.value > 0.0);
        assert!(
            gradient
                .pattern
                .iter()
                .all(|g| g.x.is_finite() && g.y.is_finite())
        );
    }

    #[test]
    fn rejects_inconsistent_inputs() {
        let (mut mesh, pattern) = two_panel_mesh(1, 2, 0);
        let term = SeamLength::new(1.0).unwrap();
        assert!(try_evaluate(&term, &mesh, &pattern[1..], None).is_err());
        assert!(try_residuals(&term, &mesh, &pattern[1..]).unwrap().is_err());
        let mut nan = pattern.clone();
        nan[0].x = Real::NAN;
        assert!(try_evaluate(&term, &mesh, &nan, None).is_err());
        let mut small = TermGradient::zeros(&mesh);
        small.pattern.pop();
        assert!(try_evaluate(&term, &mesh, &pattern, Some(&mut small)).is_err());
        mesh.seams[0].vertices[1].pop();
        assert!(try_evaluate(&term, &mesh, &pattern, None).is_err());
        assert!(try_residuals(&term, &mesh, &pattern).unwrap().is_err());
        mesh.seams[0].vertices[1].push(10_000);
        assert!(try_evaluate(&term, &mesh, &pattern, None).is_err());
    }
}
