//! Patch compactness (thesis Eq. 186–187): keeps patterns from becoming arbitrarily thin by penalizing
//! boundary vertex pairs that are close in the plane but far apart along the boundary.
//!
//! For a pair `(i, j)` of boundary vertices of one panel's outer loop and the boundary path `i → j`,
//!
//! `ρ_ij = ‖X̄_i − X̄_j‖ / Σ_{k ∈ path} ‖X̄_{k+1} − X̄_k‖`   (dimensionless, `0 ≤ ρ ≤ 1`)
//!
//! `R_Comp = w Σ_(i,j) (ρ_ij − r_D)⁴` over the pairs with `ρ_ij ≤ r_D` (zero otherwise).
//!
//! The penalty is C³ at the threshold (value and three derivatives vanish at `ρ = r_D`). The value is in
//! `w`'s units (the ratio is dimensionless).
//!
//! **Pair set.** For a loop of `n` vertices (indices cyclic) the pairs are `(i, i + d)` for every start
//! `i` and every index distance `2 ≤ d ≤ min(D, ⌊n/2⌋)`, each unordered pair once (for even `n` and
//! `d = n/2`, only the starts `i < n/2`), with the path the `d` boundary edges `i → i+1 → … → i+d`. The
//! path is thus the one with fewer edges — the thesis keeps "the initially shortest" path, which for an
//! evenly sampled boundary is the same, and this choice needs no stored initial state. Pairs at index
//! distance 1 are left out (`ρ = 1` always). `D` is [`Compactness::max_index_distance`]; the default
//! (`None`) is all pairs, `O(n²)` per panel in value and gradient (the path lengths come from prefix sums
//! and the path-length gradients are accumulated per edge by a difference array).
//!
//! Degenerate pairs: a pair whose path has zero total length (all its vertices coincide) has no ratio and
//! contributes 0; a pair of coincident endpoints on a path of positive length has `ρ = 0`, with the
//! chord's gradient taken as zero (a subgradient of the norm).
//!
//! `per_element`: one entry per boundary vertex, panel after panel, in loop order; each pair's penalty is
//! split half and half between its two end vertices. There are no residuals: each active pair's residual
//! `√w (ρ − r_D)²` depends on every vertex of its path, so the residual Jacobian would have `O(n³)` entries.

use crate::math::{Real, Vec2};
use crate::regularizer_input::{check_input, length_and_gradient, num_boundary_vertices};
use crate::term::{Term, TermError, TermEvaluation, TermGradient, TermInput, check_weight};

const NAME: &str = "compactness";

/// The compactness regularizer `R_Comp` (Eq. 186–187).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Compactness {
    weight: Real,
    threshold: Real,
    max_index_distance: Option<usize>,
}

impl Compactness {
    /// Default threshold `r_D = 0.1`: the thesis gives no value. A long rectangle's narrowest ratio
    /// (across its middle) is `width / (length + width)`, so `0.1` leaves panels up to about 9:1 free, and
    /// it penalizes corners sharper than about 11.5° (`ρ = sin(θ/2)` for two vertices at equal distances
    /// from a corner of angle `θ`).
    pub const DEFAULT_THRESHOLD: Real = 0.1;

    /// The regularizer with weight `weight` (≥ 0, units of the objective), the threshold `r_D`
    /// `threshold` (dimensionless, in `(0, 1]`), over all pairs; an error for other values.
    pub fn new(weight: Real, threshold: Real) -> Result<Self, TermError> {
        let weight = check_weight(NAME, "weight", weight)?;
        if !(threshold.is_finite() && threshold > 0.0 && threshold <= 1.0) {
            return Err(TermError::Invalid {
                term: NAME,
                message: format!("the threshold r_D must be in (0, 1], got {threshold}"),
            });
        }
        Ok(Self {
            weight,
            threshold,
            max_index_distance: None,
        })
    }

    /// The same regularizer restricted to pairs at most `distance` boundary indices apart (≥ 2); `None`
    /// for all pairs. An error for `Some(0)` or `Some(1)` (no pair at all).
    pub fn with_max_index_distance(self, distance: Option<usize>) -> Result<Self, TermError> {
        if let Some(d) = distance.filter(|&d| d < 2) {
            return Err(TermError::Invalid {
                term: NAME,
                message: format!("the largest index distance must be at least 2, got {d}"),
            });
        }
        Ok(Self {
            max_index_distance: distance,
            ..self
        })
    }

    /// The weight (units of the objective).
    pub fn weight(&self) -> Real {
        self.weight
    }

    /// The threshold `r_D` (dimensionless).
    pub fn threshold(&self) -> Real {
        self.threshold
    }

    /// The largest index distance `D` of a pair; `None` for all pairs.
    pub fn max_index_distance(&self) -> Option<usize> {
        self.max_index_distance
    }

    /// Value, per-vertex report and gradient of one panel's loop; `per_element` and `gradient` are
    /// indexed by position in the loop and by pattern vertex respectively.
    fn panel(
        &self,
        loop_vertices: &[usize],
        pattern: &[Vec2],
        per_element: &mut [Real],
        mut gradient: Option<&mut [Vec2]>,
    ) {
        let n = loop_vertices.len();
        let max_d = self.max_index_distance.unwrap_or(usize::MAX).min(n / 2);
        if max_d < 2 {
            return;
        }
        let p = |i: usize| pattern[loop_vertices[i % n]];
        let edges: Vec<(Real, Vec2)> = (0..n)
            .map(|k| length_and_gradient(p(k + 1) - p(k)))
            .collect();
        // prefix[k] = length of edges 0..k over the loop walked twice.
        let mut prefix = vec![0.0; 2 * n + 1];
        for k in 0..2 * n {
            prefix[k + 1] = prefix[k] + edges[k % n].0;
        }
        // Coefficient of each edge's length in the gradient, as a difference array over 2n edges.
        let mut edge_coefficient = vec![0.0; 2 * n + 1];
        let r = self.threshold;
        for d in 2..=max_d {
            let starts = if 2 * d == n { n / 2 } else { n };
            for i in 0..starts {
                let j = i + d;
                let path = prefix[j] - prefix[i];
                if path <= 0.0 {
                    continue;
                }
                let (chord, dchord) = length_and_gradient(p(j) - p(i));
                let rho = chord / path;
                if rho > r {
                    continue;
                }
                let t = rho - r;
                let value = self.weight * t * t * t * t;
                per_element[i] += 0.5 * value;
                per_element[j % n] += 0.5 * value;
                if let Some(g) = gradient.as_deref_mut() {
                    let drho = 4.0 * self.weight * t * t * t;
                    let gj = drho / path * dchord;
                    g[loop_vertices[j % n]] += gj;
                    g[loop_vertices[i]] -= gj;
                    let dpath = -drho * rho / path;
                    edge_coefficient[i] += dpath;
                    edge_coefficient[j] -= dpath;
                }
            }
        }
        if let Some(g) = gradient {
            let mut running = 0.0;
            let mut coefficient = vec![0.0; n];
            for (k, c) in edge_coefficient.iter().take(2 * n).enumerate() {
                running += c;
                coefficient[k % n] += running;
            }
            for (k, (c, (_, u))) in coefficient.iter().zip(&edges).enumerate() {
                let ge = *c * *u;
                g[loop_vertices[(k + 1) % n]] += ge;
                g[loop_vertices[k]] -= ge;
            }
        }
    }
}

impl Term for Compactness {
    fn name(&self) -> &'static str {
        NAME
    }

    fn evaluate(
        &self,
        input: &TermInput,
        mut gradient: Option<&mut TermGradient>,
    ) -> Result<TermEvaluation, TermError> {
        check_input(NAME, input, gradient.as_deref())?;
        let mut per_element = vec![0.0; num_boundary_vertices(input)];
        let mut k0 = 0;
        for panel in &input.mesh.panels {
            let n = panel.boundary.len();
            self.panel(
                &panel.boundary,
                input.pattern,
                &mut per_element[k0..k0 + n],
                gradient.as_deref_mut().map(|g| g.pattern.as_mut_slice()),
            );
            k0 += n;
        }
        TermEvaluation::from_per_element(NAME, per_element)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::*;

    /// A right angle: 0 = (0, 0), 1 = (1, 0), 2 = (1, 1), then back along a far-away arc so that only the
    /// pair (0, 2) (ρ = √2 / 2) can be active for a small threshold.
    fn right_angle() -> (crate::DesignMesh, Vec<Vec2>) {
        let pts = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (-3.0, 5.0)].map(|(x, y)| Vec2::new(x, y));
        (single_panel_mesh(4, &[], &[0, 1, 2, 3]), pts.to_vec())
    }

    #[test]
    fn rejects_bad_parameters() {
        assert!(Compactness::new(-1.0, 0.1).is_err());
        assert!(Compactness::new(1.0, 0.0).is_err());
        assert!(Compactness::new(1.0, 1.5).is_err());
        assert!(Compactness::new(1.0, Real::NAN).is_err());
        let c = Compactness::new(1.0, Compactness::DEFAULT_THRESHOLD).unwrap();
        assert_eq!(c.threshold(), 0.1);
        assert_eq!(c.max_index_distance(), None);
        assert!(c.with_max_index_distance(Some(1)).is_err());
        assert_eq!(
            c.with_max_index_distance(Some(3))
                .unwrap()
                .max_index_distance(),
            Some(3)
        );
    }

    #[test]
    fn hand_computed_active_pair() {
        // n = 4: pairs (0, 2) and (1, 3). (0, 2): chord √2, path 2 → ρ = 0.7071.
        // (1, 3): chord √(16 + 25) = 6.403, path |1→2| + |2→3| = 1 + √32 = 6.657 → ρ = 0.962.
        let (mesh, pts) = right_angle();
        let term = Compactness::new(2.0, 0.8).unwrap();
        let rho: Real = 2f64.sqrt() / 2.0;
        let expected = 2.0 * (rho - 0.8).powi(4);
        let value = term_value(&term, &mesh, &pts);
        assert!((value - expected).abs() < 1e-15, "{value} vs {expected}");
        // Raising the threshold above 0.962 activates (1, 3) too.
        let term = Compactness::new(2.0, 0.99).unwrap();
        let rho13 = 41f64.sqrt() / (1.0 + 32f64.sqrt());
        let expected = 2.0 * ((rho - 0.99).powi(4) + (rho13 - 0.99).powi(4));
        let value = term_value(&term, &mesh, &pts);
        assert!((value - expected).abs() < 1e-14, "{value} vs {expected}");
    }

    #[test]
    fn short_loops_have_no_pairs() {
        // n = 3: every pair is adjacent (index distance 1), so there is nothing to penalize.
        let pts = [(0.0, 0.0), (1.0, 0.0), (0.0, 0.01)].map(|(x, y)| Vec2::new(x, y));
        let mesh = single_panel_mesh(3, &[], &[0, 1, 2]);
        let term = Compactness::new(1.0, 1.0).unwrap();
        assert_eq!(term_value(&term, &mesh, &pts), 0.0);
    }

    #[test]
    fn inactive_below_the_ratio() {
        let (mesh, pts) = right_angle();
        let term = Compactness::new(2.0, 0.5).unwrap();
        assert_eq!(term_value(&term, &mesh, &pts), 0.0);
        check_pattern_gradient(&term, &mesh, &pts);
    }

    #[test]
    fn at_the_threshold_value_and_gradient_vanish() {
        let (mesh, pts) = right_angle();
        let rho: Real = 2f64.sqrt() / 2.0;
        let term = Compactness::new(1.0, rho).unwrap();
        let fabric = fabric();
        let cloth = vec![crate::math::Vec3::zeros(); mesh.num_cloth_vertices];
        let input = TermInput {
            mesh: &mesh,
            cloth: &cloth,
            pattern: &pts,
            fabric: &fabric,
        };
        let mut g = TermGradient::zeros(&mesh);
        let eval = term.evaluate(&input, Some(&mut g)).unwrap();
        assert!(eval.value <= 1e-60, "{}", eval.value);
        assert!(g.pattern.iter().all(|g| g.norm() <= 1e-40));
        // Just above and below the threshold the gradient is continuous (C³): both tiny.
        for r in [rho * (1.0 + 1e-6), rho * (1.0 - 1e-6)] {
            let term = Compactness::new(1.0, r).unwrap();
            let mut g = TermGradient::zeros(&mesh);
            term.evaluate(&input, Some(&mut g)).unwrap();
            assert!(g.pattern.iter().all(|g| g.norm() <= 1e-15));
        }
    }

    #[test]
    fn pair_set_counts() {
        // Threshold 1 activates every pair with ρ < 1; on a regular polygon all pairs with d ≥ 2 have ρ < 1,
        // and each contributes to its two end vertices: count the pairs through the per-vertex report.
        for (n, max_d, pairs) in [
            (4, None, 2),
            (5, None, 5),
            (6, None, 9),
            (8, Some(2), 8),
            (8, None, 20),
        ] {
            let corners: Vec<Vec2> = (0..n)
                .map(|k| {
                    let a = 2.0 * std::f64::consts::PI * k as Real / n as Real;
                    Vec2::new(a.cos(), a.sin())
                })
                .collect();
            let (mesh, pts) = polygon_panel(&corners);
            let term = Compactness::new(1.0, 1.0)
                .unwrap()
                .with_max_index_distance(max_d)
                .unwrap();
            // Value of one pair at index distance d on a regular n-gon: (sin(πd/n) / (d sin(π/n)) − 1)⁴.
            let ratio = |d: usize| {
                let pi = std::f64::consts::PI;
                (pi * d as Real / n as Real).sin() / (d as Real * (pi / n as Real).sin())
            };
            let max = max_d.unwrap_or(n).min(n / 2);
            let mut expected = 0.0;
            let mut count = 0;
            for d in 2..=max {
                let k = if 2 * d == n { n / 2 } else { n };
                count += k;
                expected += k as Real * (ratio(d) - 1.0).powi(4);
            }
            assert_eq!(count, pairs);
            let value = term_value(&term, &mesh, &pts);
            assert!(
                (value - expected).abs() < 1e-13,
                "n = {n}: {value} vs {expected}"
            );
        }
    }

    #[test]
    fn gradient_matches_finite_differences() {
        for seed in 0..4 {
            let (mesh, pattern) = two_panel_mesh(3, 4, seed);
            let pattern = perturbed(&pattern, 0.03, 30 + seed);
            let term = Compactness::new(5.0, 0.6).unwrap();
            let value = term_value(&term, &mesh, &pattern);
            assert!(value > 0.0);
            check_pattern_gradient(&term, &mesh, &pattern);
            let limited = term.with_max_index_distance(Some(3)).unwrap();
            check_pattern_gradient(&limited, &mesh, &pattern);
        }
    }

    #[test]
    fn degenerate_pairs_are_finite() {
        // Vertices 0 and 2 coincide (ρ = 0), vertices 4, 5, 6 coincide (zero path for the pair (4, 6)).
        let pts = [
            (0.0, 0.0),
            (1.0, 0.0),
            (0.0, 0.0),
            (0.0, 1.0),
            (0.5, 2.0),
            (0.5, 2.0),
            (0.5, 2.0),
        ]
        .map(|(x, y)| Vec2::new(x, y));
        let mesh = single_panel_mesh(7, &[], &(0..7).collect::<Vec<_>>());
        let term = Compactness::new(1.0, 0.3).unwrap();
        let fabric = fabric();
        let cloth = vec![crate::math::Vec3::zeros(); 7];
        let input = TermInput {
            mesh: &mesh,
            cloth: &cloth,
            pattern: &pts,
            fabric: &fabric,
        };
        let mut g = TermGradient::zeros(&mesh);
        let eval = term.evaluate(&input, Some(&mut g)).unwrap();
        assert!(eval.value >= 0.3f64.powi(4));
        assert!(eval.value.is_finite());
        assert!(g.pattern.iter().all(|g| g.x.is_finite() && g.y.is_finite()));
    }
}
