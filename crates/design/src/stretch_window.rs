//! The stretch objective (thesis Eq. 173): keep every principal stretch of the worn garment inside a
//! window `[λmin, λmax]`.
//!
//! For cloth triangle `e` with rest (pattern) area `A^e` (m²) and principal stretches
//! `λ_i^e = √μ_i` (dimensionless; `μ_i` the eigenvalues of `C = FᵀF`, `F = Ds Dm⁻¹` as in
//! `skintight_physics::membrane_element`),
//!
//! ```text
//! T = w Σ_e A^e Σ_{i=1,2} f(λ_i^e),   f(λ) = (λ − λmin)²  if λ < λmin,
//!                                          (λ − λmax)²  if λ > λmax,
//!                                          0            otherwise,
//! ```
//!
//! in m² times the weight `w`. Eq. 173 writes "eigenvalues of `C`" but means the principal stretches
//! (the window is a range of admissible *stretch*), so the square roots of those eigenvalues are used.
//!
//! # Derivatives
//!
//! `Φ(C) = Σ_i f(√μ_i)` is a symmetric function of the eigenvalues of `C`; with `g(μ) = f(√μ)` (C¹ because
//! `f` is), its derivative is the spectral matrix
//!
//! ```text
//! G = ∂Φ/∂C = Σ_i g'(μ_i) n_i n_iᵀ,   g'(μ) = f'(λ)/(2λ) = (λ − bound)/λ,
//! ```
//!
//! which equals `g'(μ) I` when `μ1 = μ2` whatever eigenvectors are picked, so it is exact and continuous
//! at repeated stretches (no eigenvector derivative is formed). Then (see `triangle_strain`)
//! `∂T/∂Ds = 2wA F G Dm⁻ᵀ` and, since the rest area and `Dm⁻¹` depend on the pattern,
//! `∂T/∂Dm = w (Φ A Dm⁻ᵀ − 2A C G Dm⁻ᵀ)`.
//!
//! # Residuals
//!
//! One residual `r = √(wA)(λ_i − bound)` per violated principal stretch (`Σ r² = T` exactly), with
//! `∂λ_i/∂C = n_i n_iᵀ / (2λ_i)`. Individual principal stretches are not differentiable where they
//! coincide (their sum is), so at `λ1 = λ2` the Jacobian rows are one valid choice among many; `Jᵀr`
//! is still exactly `∇T / 2` there.
//!
//! # Failure cases
//!
//! A pattern triangle that is degenerate or clockwise, and a cloth triangle whose smaller stretch is below
//! `1e-8` while the lower bound is active (√ is not differentiable at 0), give
//! [`TermError::Collapsed`].

use crate::math::{Mat2, Real};
use crate::term::{
    Residuals, Term, TermError, TermEvaluation, TermGradient, TermInput, check_weight,
};
use crate::triangle_strain::TriangleStrain;

/// Smallest principal stretch whose derivative is formed while the lower bound is active.
const MIN_STRETCH_DERIVATIVE: Real = 1e-8;

/// The stretch-window objective of Eq. 173; see the module documentation. `per_element` of its
/// evaluation has one entry per cloth triangle (`#Fc`, m² × weight).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StretchWindow {
    weight: Real,
    min_stretch: Real,
    max_stretch: Real,
}

/// Per-triangle quantities shared by the value, gradient and residuals.
struct WindowElement {
    strain: TriangleStrain,
    /// Principal stretches `λ1 ≥ λ2`.
    stretch: [Real; 2],
    /// `λ_i − bound` when violated, else 0.
    excess: [Real; 2],
}

impl WindowElement {
    /// `Φ = Σ f(λ_i)` (dimensionless).
    fn penalty(&self) -> Real {
        self.excess.iter().map(|e| e * e).sum()
    }
}

impl StretchWindow {
    /// Name of the term in reports.
    pub const NAME: &'static str = "stretch";

    /// The objective with weight `weight` (≥ 0, finite; multiplies m²) and admissible principal stretches
    /// `[min_stretch, max_stretch]` (dimensionless, `0 ≤ min_stretch < max_stretch`). `max_stretch` may be
    /// `+∞` for a lower bound only (the thesis's use in all its examples); `min_stretch = 0` gives an upper
    /// bound only.
    pub fn new(weight: Real, min_stretch: Real, max_stretch: Real) -> Result<Self, TermError> {
        let bad = |message: String| {
            Err(TermError::Parameter {
                term: Self::NAME,
                message,
            })
        };
        check_weight(Self::NAME, "weight", weight)?;
        if !(min_stretch.is_finite() && min_stretch >= 0.0) {
            return bad(format!(
                "min_stretch must be finite and non-negative, got {min_stretch}"
            ));
        }
        if max_stretch.is_nan() || max_stretch <= min_stretch {
            return bad(format!(
                "max_stretch ({max_stretch}) must exceed min_stretch ({min_stretch})"
            ));
        }
        Ok(Self {
            weight,
            min_stretch,
            max_stretch,
        })
    }

    /// The weight `w` (multiplies m²).
    pub fn weight(&self) -> Real {
        self.weight
    }

    /// Lower bound `λmin` of the principal stretches (dimensionless).
    pub fn min_stretch(&self) -> Real {
        self.min_stretch
    }

    /// Upper bound `λmax` of the principal stretches (dimensionless, possibly `+∞`).
    pub fn max_stretch(&self) -> Real {
        self.max_stretch
    }

    /// `f(λ)` of Eq. 173 for one principal stretch (dimensionless; multiply by the rest area and weight).
    pub fn penalty(&self, stretch: Real) -> Real {
        let e = self.excess(stretch);
        e * e
    }

    /// `λ − bound` for a violated bound, else 0.
    fn excess(&self, stretch: Real) -> Real {
        if stretch < self.min_stretch {
            stretch - self.min_stretch
        } else if stretch > self.max_stretch {
            stretch - self.max_stretch
        } else {
            0.0
        }
    }

    fn element(&self, input: &TermInput, f: usize) -> Result<WindowElement, TermError> {
        let mesh = input.mesh;
        let x = mesh.cloth_triangles[f].map(|v| input.cloth[v]);
        let rest = mesh.pattern_triangles[f].map(|v| input.pattern[v]);
        let collapsed = TermError::Collapsed {
            term: Self::NAME,
            triangle: f,
        };
        let strain = TriangleStrain::new(&x, &rest).ok_or(collapsed.clone())?;
        let stretch = strain.mu.map(Real::sqrt);
        let excess = stretch.map(|s| self.excess(s));
        if excess[1] != 0.0 && stretch[1] < MIN_STRETCH_DERIVATIVE {
            return Err(collapsed);
        }
        Ok(WindowElement {
            strain,
            stretch,
            excess,
        })
    }
}

impl Term for StretchWindow {
    fn name(&self) -> &'static str {
        Self::NAME
    }

    /// Value in m² × weight; `per_element[f]` for cloth triangle `f`. Adds `∂T/∂x` (`#Vc × 3`) and
    /// `∂T/∂X̄` (`#Vp × 2`), both in m × weight.
    fn evaluate(
        &self,
        input: &TermInput,
        mut gradient: Option<&mut TermGradient>,
    ) -> Result<TermEvaluation, TermError> {
        input.validate(Self::NAME, gradient.as_deref())?;
        let mesh = input.mesh;
        let mut per_element = vec![0.0; mesh.num_triangles()];
        for (f, out) in per_element.iter_mut().enumerate() {
            let el = self.element(input, f)?;
            let phi = el.penalty();
            if phi == 0.0 {
                continue;
            }
            let s = &el.strain;
            *out = self.weight * s.area * phi;
            let Some(grad) = gradient.as_deref_mut() else {
                continue;
            };
            // G = Σ (λ_i − bound)/λ_i n_i n_iᵀ (terms with no excess vanish; λ_i > 0 otherwise).
            let mut g = Mat2::zeros();
            for i in 0..2 {
                if el.excess[i] != 0.0 {
                    g += s.n[i] * s.n[i].transpose() * (el.excess[i] / el.stretch[i]);
                }
            }
            s.add_area_weighted_gradient(
                self.weight,
                phi,
                &g,
                mesh.cloth_triangles[f],
                mesh.pattern_triangles[f],
                grad,
            );
        }
        TermEvaluation::from_per_element(Self::NAME, per_element)
    }

    /// `r = √(wA)(λ_i − bound)` (m × √weight) for each violated principal stretch, triangle by triangle,
    /// larger stretch first.
    fn residuals(&self, input: &TermInput) -> Option<Result<Residuals, TermError>> {
        Some(self.stretch_residuals(input))
    }
}

impl StretchWindow {
    fn stretch_residuals(&self, input: &TermInput) -> Result<Residuals, TermError> {
        input.validate(Self::NAME, None)?;
        let mesh = input.mesh;
        let mut out = Residuals::default();
        for f in 0..mesh.num_triangles() {
            let el = self.element(input, f)?;
            let s = &el.strain;
            for i in 0..2 {
                let e = el.excess[i];
                if e == 0.0 {
                    continue;
                }
                // ∂λ_i/∂C = n_i n_iᵀ / (2λ_i).
                let g = s.n[i] * s.n[i].transpose() * (0.5 / el.stretch[i]);
                s.push_area_weighted_residual(
                    self.weight,
                    e,
                    &g,
                    mesh.cloth_triangles[f],
                    mesh.pattern_triangles[f],
                    &mut out,
                );
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::design_mesh::DesignMesh;
    use crate::math::Mat3x2;
    use crate::math::{Vec2, Vec3};
    use crate::term::Fabric;
    use crate::test_support::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use skintight_geometry::finite_difference::FdParams;

    const MIN: Real = 0.95;
    const MAX: Real = 1.25;

    fn fd() -> FdParams {
        FdParams {
            step: 1e-7,
            rel_tol: 2e-5,
            abs_tol: 1e-11,
        }
    }

    fn term() -> StretchWindow {
        StretchWindow::new(3.0, MIN, MAX).unwrap()
    }

    fn eval(
        t: &StretchWindow,
        mesh: &DesignMesh,
        fabric: &Fabric,
        cloth: &[Vec3],
        pattern: &[Vec2],
    ) -> Result<TermEvaluation, TermError> {
        t.evaluate(
            &TermInput {
                mesh,
                cloth,
                pattern,
                fabric,
            },
            None,
        )
    }

    #[test]
    fn value_matches_a_hand_computed_case() {
        // Dyadic coordinates and an axis-aligned stretch: every triangle has stretches exactly 1.5 and
        // 0.75, and the two panels have rest area 2 · (2 · 0.5)² = 2 m².
        let s = strip(2, 2, 0.5);
        let fabric = fabric();
        let cloth: Vec<Vec3> = s
            .cloth_layout
            .iter()
            .map(|p| Vec3::new(1.5 * p.x, 0.75 * p.y, 0.0))
            .collect();
        let t = StretchWindow::new(2.0, 0.875, 1.25).unwrap();
        let e = eval(&t, &s.mesh, &fabric, &cloth, &s.pattern_layout).unwrap();
        let expected = 2.0 * 2.0 * ((1.5_f64 - 1.25).powi(2) + (0.75_f64 - 0.875).powi(2));
        assert!(
            (e.value - expected).abs() <= 1e-13,
            "{} vs {expected}",
            e.value
        );
        for (f, v) in e.per_element.iter().enumerate() {
            let area = s.mesh.pattern_area(&s.pattern_layout, f);
            assert!((v - 2.0 * area * 0.078125).abs() <= 1e-14);
        }
        let r = t
            .residuals(&TermInput {
                mesh: &s.mesh,
                cloth: &cloth,
                pattern: &s.pattern_layout,
                fabric: &fabric,
            })
            .unwrap()
            .unwrap();
        assert_eq!(r.values.len(), 2 * s.mesh.num_triangles());
        // Per triangle: √(2 · 0.125) (1.5 − 1.25) and √(2 · 0.125) (0.75 − 0.875).
        assert!((r.values[0] - 0.125).abs() <= 1e-14);
        assert!((r.values[1] + 0.0625).abs() <= 1e-14);
        assert_eq!(t.penalty(1.0), 0.0);
        assert_eq!(t.penalty(1.5), 0.0625);
    }

    /// The states of one regime: stretch pairs `(λ1, λ2)`.
    fn regimes() -> Vec<(&'static str, Real, Real)> {
        vec![
            ("below", 0.8, 0.7),
            ("inside", 1.1, 1.0),
            ("above", 1.5, 1.35),
            ("across", 1.4, 0.85),
            ("equal below", 0.85, 0.85),
            ("equal inside", 1.1, 1.1),
            ("equal above", 1.4, 1.4),
            ("just below the window", MIN - 1e-3, 1.0),
            ("just inside the lower edge", 1.1, MIN + 1e-3),
            ("just inside the upper edge", MAX - 1e-3, 1.0),
            ("just above the window", MAX + 1e-3, MIN - 2e-3),
        ]
    }

    #[test]
    fn gradient_matches_finite_differences_in_every_regime() {
        let s = strip(2, 1, 0.1);
        let fabric = fabric();
        let t = term();
        for seed in [1, 2, 3] {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            for (name, l1, l2) in regimes() {
                let f = deformation(&mut rng, l1, l2);
                let angle = rng.random_range(-3.0..3.0);
                // Equal and near-edge states are taken exactly; the others get a little noise.
                let noise = if name.contains("equal") || name.contains("just") {
                    0.0
                } else {
                    2e-4
                };
                let (cloth, pattern) = place(&mut rng, &s, &f, angle, noise);
                let v = check_term_gradient(&t, &s.mesh, &fabric, &cloth, &pattern, &fd());
                if name.contains("inside") {
                    assert_eq!(v, 0.0, "{name}");
                } else {
                    assert!(v > 0.0, "{name}");
                }
            }
        }
    }

    #[test]
    fn gradient_is_exact_at_exactly_equal_stretches() {
        // Dyadic layout, uniform scaling: C = s² I exactly in every triangle.
        let s = strip(2, 2, 0.25);
        let fabric = fabric();
        let t = term();
        for scale in [0.75, 1.0, 1.5] {
            let cloth: Vec<Vec3> = s
                .cloth_layout
                .iter()
                .map(|p| Vec3::new(scale * p.x, 0.0, scale * p.y))
                .collect();
            let v = check_term_gradient(&t, &s.mesh, &fabric, &cloth, &s.pattern_layout, &fd());
            let area = 2.0 * 0.25;
            let expect = 3.0 * area * 2.0 * t.penalty(scale);
            assert!((v - expect).abs() <= 1e-13, "{v} vs {expect}");
            // Jᵀr = ∇T/2 even where single stretches are not differentiable.
            let input = TermInput {
                mesh: &s.mesh,
                cloth: &cloth,
                pattern: &s.pattern_layout,
                fabric: &fabric,
            };
            let mut grad = TermGradient::zeros(&s.mesh);
            t.evaluate(&input, Some(&mut grad)).unwrap();
            let r = t.residuals(&input).unwrap().unwrap();
            let mut jtr = TermGradient::zeros(&s.mesh);
            for &(k, v, d) in &r.cloth_jacobian {
                jtr.cloth[v] += d * r.values[k];
            }
            for &(k, v, d) in &r.pattern_jacobian {
                jtr.pattern[v] += d * r.values[k];
            }
            let (a, b) = (gradient_flat(&jtr), gradient_flat(&grad));
            let big = b.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            for (a, b) in a.iter().zip(&b) {
                assert!((2.0 * a - b).abs() <= 1e-12 * big + 1e-300);
            }
        }
    }

    #[test]
    fn residuals_square_to_the_value_and_match_finite_differences() {
        let s = strip(2, 1, 0.1);
        let fabric = fabric();
        let t = term();
        for seed in [4, 5, 6] {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            for (name, l1, l2, count) in [
                ("below", 0.8, 0.7, 2),
                ("above", 1.5, 1.35, 2),
                ("across", 1.4, 0.85, 2),
                ("one above", 1.4, 1.1, 1),
                ("inside", 1.1, 1.0, 0),
            ] {
                let f = deformation(&mut rng, l1, l2);
                let angle = rng.random_range(-3.0..3.0);
                let (cloth, pattern) = place(&mut rng, &s, &f, angle, 2e-4);
                let m = check_term_residuals(&t, &s.mesh, &fabric, &cloth, &pattern, &fd());
                assert_eq!(m, count * s.mesh.num_triangles(), "{name}");
            }
        }
    }

    #[test]
    fn bent_garment_with_mixed_regimes() {
        // A strip wrapped round a cylinder with a varying stretch: triangles below, inside and above.
        let s = strip(4, 2, 0.05);
        let fabric = fabric();
        let t = term();
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let cloth: Vec<Vec3> = s
            .cloth_layout
            .iter()
            .map(|p| {
                let sx = 0.8 + 3.0 * p.x;
                let a = p.x * sx / 0.3;
                let j = Vec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                ) * 1e-4;
                Vec3::new(0.3 * a.cos(), 0.3 * a.sin(), 1.1 * p.y) + j
            })
            .collect();
        let e = eval(&t, &s.mesh, &fabric, &cloth, &s.pattern_layout).unwrap();
        assert!(e.per_element.contains(&0.0));
        assert!(e.per_element.iter().any(|&v| v > 0.0));
        check_term_gradient(&t, &s.mesh, &fabric, &cloth, &s.pattern_layout, &fd());
        check_term_residuals(&t, &s.mesh, &fabric, &cloth, &s.pattern_layout, &fd());
    }

    #[test]
    fn invalid_parameters_are_rejected() {
        for (w, lo, hi) in [
            (-1.0, 0.9, 1.1),
            (Real::NAN, 0.9, 1.1),
            (Real::INFINITY, 0.9, 1.1),
            (1.0, 1.1, 1.1),
            (1.0, 1.2, 1.1),
            (1.0, -0.1, 1.1),
            (1.0, Real::NAN, 1.1),
            (1.0, 0.9, Real::NAN),
        ] {
            let err = StretchWindow::new(w, lo, hi).unwrap_err();
            assert!(matches!(err, TermError::Parameter { .. }), "{err}");
        }
        let lower_only = StretchWindow::new(1.0, 0.9, Real::INFINITY).unwrap();
        assert_eq!(lower_only.penalty(1e6), 0.0);
        assert!(StretchWindow::new(0.0, 0.0, 1.0).is_ok());
    }

    #[test]
    fn collapsed_triangles_and_bad_inputs_are_errors_not_nan() {
        let s = strip(1, 1, 0.1);
        let fabric = fabric();
        let t = term();
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        let (cloth, mut pattern) = place(&mut rng, &s, &Mat3x2::identity(), 0.3, 0.0);
        // All cloth vertices on a line: stretch 0 below the window.
        let line: Vec<Vec3> = cloth.iter().map(|p| Vec3::new(p.x, 0.0, 0.0)).collect();
        assert!(matches!(
            eval(&t, &s.mesh, &fabric, &line, &pattern),
            Err(TermError::Collapsed { .. })
        ));
        // Without a lower bound the same state is fine.
        let upper = StretchWindow::new(1.0, 0.0, 1.2).unwrap();
        assert_eq!(
            eval(&upper, &s.mesh, &fabric, &line, &pattern)
                .unwrap()
                .value,
            0.0
        );
        assert!(eval(&t, &s.mesh, &fabric, &cloth[1..], &pattern).is_err());
        let mut nan = cloth.clone();
        nan[2].y = Real::NAN;
        assert!(matches!(
            eval(&t, &s.mesh, &fabric, &nan, &pattern),
            Err(TermError::Invalid { .. })
        ));
        // An inverted pattern triangle.
        let [a, b, _] = s.mesh.pattern_triangles[0];
        pattern.swap(a, b);
        assert!(matches!(
            eval(&t, &s.mesh, &fabric, &cloth, &pattern),
            Err(TermError::Collapsed { triangle: 0, .. })
        ));
    }
}
