//! The fabric's stretch limits as a design constraint: a penalty that keeps the stretch along the knit's
//! two directions — the wales (the grain line) and the courses (across it) — below the fabric's limits.
//!
//! For cloth triangle `e` with rest (pattern) area `A^e` (m²), right Cauchy–Green tensor `C = FᵀF`
//! (dimensionless, in pattern coordinates; `F = Ds Dm⁻¹` as in [`crate::triangle_strain`]) and unit
//! pattern directions `g_w` (wale) and `g_c = g_w⊥` (course) of its piece, the directional stretches are
//! `s_d = √(g_dᵀ C g_d) = |F g_d|` (dimensionless), and
//!
//! ```text
//! T = w Σ_e A^e Σ_{d ∈ {w, c}} max(0, s_d^e − b_d)²        (m² × weight)
//! ```
//!
//! with the activation bounds `b_d` (dimensionless) — the fabric's limits, usually lowered by a margin so
//! that the penalty acts before the limit is reached: an exterior penalty leaves its constraint violated by
//! `O(1/w)` at the optimum, and the margin absorbs that. The same directional stretches are what the
//! admissibility verdict checks after the design (`skintight::simulate::admissibility`).
//!
//! The wale direction of each piece is a parameter, fixed for the run: the grain line of the piece at
//! the start of the design (the area-weighted image of the body's up axis in the pattern,
//! `skintight_garment::pattern::grain_line`). The design moves the pieces' outlines, not their
//! orientation in the pattern plane, so the grain barely turns; the verdict at the end measures along the
//! final grain line.
//!
//! # Derivatives
//!
//! `Φ(C) = Σ_d max(0, s_d − b_d)²` with `s_d = √(g_dᵀ C g_d)`: `∂s_d/∂C = g_d g_dᵀ / (2 s_d)`, so
//! `G = ∂Φ/∂C = Σ_d (s_d − b_d)/s_d · g_d g_dᵀ` over the active directions — C¹ in `C` (the hinge is
//! squared). Then, as in [`crate::stretch_window`], `∂T/∂x` and `∂T/∂X̄` follow from
//! `TriangleStrain::corner_gradients_from_c` and `∂A/∂X̄`.
//!
//! # Residuals
//!
//! One residual `r = √(wA)(s_d − b_d)` per active direction (`Σ r² = T` exactly), with
//! `∂r = √w ((s_d − b_d)/(2√A) ∂A + √A ∂s_d)`.
//!
//! # Failure cases
//!
//! A pattern triangle that is degenerate or clockwise gives [`TermError::Collapsed`]. An active direction
//! has `s_d > b_d ≥ 1`, so no derivative is formed at `s_d = 0`.

use crate::math::{Mat2, Real, Vec2};
use crate::term::{
    Residuals, Term, TermError, TermEvaluation, TermGradient, TermInput, check_weight,
};
use crate::triangle_strain::TriangleStrain;

/// The fabric-stretch-limit penalty; see the module documentation. `per_element` of its evaluation has one
/// entry per cloth triangle (`#Fc`, m² × weight).
#[derive(Clone, Debug, PartialEq)]
pub struct FabricStretchLimit {
    weight: Real,
    /// Activation bounds `[b_wale, b_course]` (dimensionless, ≥ 1).
    bounds: [Real; 2],
    /// Unit wale direction of each panel, in the pattern plane.
    wale: Vec<Vec2>,
}

/// Per-triangle quantities shared by the value, gradient and residuals.
struct LimitElement {
    strain: TriangleStrain,
    /// Unit `[wale, course]` directions in the pattern plane.
    dirs: [Vec2; 2],
    /// Directional stretches `[s_w, s_c]`.
    stretch: [Real; 2],
    /// `max(0, s_d − b_d)`.
    excess: [Real; 2],
}

impl FabricStretchLimit {
    /// Name of the term in reports.
    pub const NAME: &'static str = "fabric_stretch_limit";

    /// The penalty of weight `weight` (≥ 0, finite) above the bounds `[wale, course]` (finite, ≥ 1), with
    /// the wale direction `wale[p]` (any non-zero length; normalized here) of each panel `p` (the
    /// [`crate::design_mesh::DesignMesh`] panel order, which survives remeshing).
    pub fn new(weight: Real, bounds: [Real; 2], wale: Vec<Vec2>) -> Result<Self, TermError> {
        check_weight(Self::NAME, "weight", weight)?;
        let bad = |message: String| TermError::Parameter {
            term: Self::NAME,
            message,
        };
        for (name, b) in ["wale", "course"].iter().zip(bounds) {
            if !(b.is_finite() && b >= 1.0) {
                return Err(bad(format!(
                    "the {name} bound must be a finite stretch ≥ 1, got {b}"
                )));
            }
        }
        let wale = wale
            .into_iter()
            .enumerate()
            .map(|(f, g)| {
                let n = g.norm();
                if n > 0.0 && n.is_finite() {
                    Ok(g / n)
                } else {
                    Err(bad(format!(
                        "the wale direction of panel {f} is not a direction: {g:?}"
                    )))
                }
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self {
            weight,
            bounds,
            wale,
        })
    }

    /// The activation bounds `[wale, course]` (dimensionless).
    pub fn bounds(&self) -> [Real; 2] {
        self.bounds
    }

    /// Strain, the two directions and their stretches and excesses over the bounds.
    fn element(&self, input: &TermInput, f: usize) -> Result<LimitElement, TermError> {
        let mesh = input.mesh;
        let x = mesh.cloth_triangles[f].map(|v| input.cloth[v]);
        let rest = mesh.pattern_triangles[f].map(|v| input.pattern[v]);
        let strain = TriangleStrain::new(&x, &rest).ok_or(TermError::Collapsed {
            term: Self::NAME,
            triangle: f,
        })?;
        let g = self.wale[mesh.pattern_panel[mesh.pattern_triangles[f][0]]];
        let dirs = [g, Vec2::new(-g.y, g.x)];
        let stretch = dirs.map(|d| (d.dot(&(strain.c * d))).max(0.0).sqrt());
        let excess = [0, 1].map(|i| (stretch[i] - self.bounds[i]).max(0.0));
        Ok(LimitElement {
            strain,
            dirs,
            stretch,
            excess,
        })
    }

    fn check_size(&self, input: &TermInput) -> Result<(), TermError> {
        let n = input.mesh.panels.len();
        if self.wale.len() != n {
            return Err(TermError::Invalid {
                term: Self::NAME,
                message: format!("{} wale directions for {n} panels", self.wale.len()),
            });
        }
        Ok(())
    }
}

impl Term for FabricStretchLimit {
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
        self.check_size(input)?;
        let mesh = input.mesh;
        let mut per_element = vec![0.0; mesh.num_triangles()];
        for (f, out) in per_element.iter_mut().enumerate() {
            let LimitElement {
                strain: s,
                dirs,
                stretch,
                excess,
            } = self.element(input, f)?;
            let phi: Real = excess.iter().map(|e| e * e).sum();
            if phi == 0.0 {
                continue;
            }
            *out = self.weight * s.area * phi;
            let Some(grad) = gradient.as_deref_mut() else {
                continue;
            };
            let mut g = Mat2::zeros();
            for i in 0..2 {
                if excess[i] > 0.0 {
                    g += dirs[i] * dirs[i].transpose() * (excess[i] / stretch[i]);
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

    /// `r = √(wA)(s_d − b_d)` (m × √weight) for each active direction, triangle by triangle, wale first.
    fn residuals(&self, input: &TermInput) -> Option<Result<Residuals, TermError>> {
        Some(self.limit_residuals(input))
    }
}

impl FabricStretchLimit {
    fn limit_residuals(&self, input: &TermInput) -> Result<Residuals, TermError> {
        input.validate(Self::NAME, None)?;
        self.check_size(input)?;
        let mesh = input.mesh;
        let mut out = Residuals::default();
        for f in 0..mesh.num_triangles() {
            let LimitElement {
                strain: s,
                dirs,
                stretch,
                excess,
            } = self.element(input, f)?;
            for i in 0..2 {
                let e = excess[i];
                if e == 0.0 {
                    continue;
                }
                // ∂s_d/∂C = g_d g_dᵀ / (2 s_d).
                let g = dirs[i] * dirs[i].transpose() * (0.5 / stretch[i]);
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
    use crate::math::Vec3;
    use crate::term::Fabric;
    use crate::test_support::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use skintight_geometry::finite_difference::FdParams;

    const WALE: Real = 1.2;
    const COURSE: Real = 1.4;

    fn fd() -> FdParams {
        FdParams {
            step: 1e-7,
            rel_tol: 2e-5,
            abs_tol: 1e-11,
        }
    }

    fn term(mesh: &DesignMesh, wale: Vec2) -> FabricStretchLimit {
        FabricStretchLimit::new(3.0, [WALE, COURSE], vec![wale; mesh.panels.len()]).unwrap()
    }

    fn input<'a>(
        mesh: &'a DesignMesh,
        fabric: &'a Fabric,
        cloth: &'a [Vec3],
        pattern: &'a [Vec2],
    ) -> TermInput<'a> {
        TermInput {
            mesh,
            cloth,
            pattern,
            fabric,
        }
    }

    /// Stretching the strip by 1.5 along pattern x and 1.1 along y: with the wale along y, only the course
    /// (x) exceeds its bound, by 0.1; with the wale along x, the wale exceeds by 0.3 and the course (y)
    /// stays below.
    #[test]
    fn value_matches_a_hand_computed_case() {
        let s = strip(2, 2, 0.5);
        let fabric = fabric();
        let cloth: Vec<Vec3> = s
            .cloth_layout
            .iter()
            .map(|p| Vec3::new(1.5 * p.x, 1.1 * p.y, 0.0))
            .collect();
        // The strip's rest area is 2 m².
        let along_y = term(&s.mesh, Vec2::new(0.0, 2.0));
        let e = along_y
            .evaluate(&input(&s.mesh, &fabric, &cloth, &s.pattern_layout), None)
            .unwrap();
        let expected = 3.0 * 2.0 * (1.5_f64 - COURSE).powi(2);
        assert!(
            (e.value - expected).abs() <= 1e-12,
            "{} vs {expected}",
            e.value
        );
        let along_x = term(&s.mesh, Vec2::new(-1.0, 0.0));
        let e = along_x
            .evaluate(&input(&s.mesh, &fabric, &cloth, &s.pattern_layout), None)
            .unwrap();
        let expected = 3.0 * 2.0 * (1.5_f64 - WALE).powi(2);
        assert!(
            (e.value - expected).abs() <= 1e-12,
            "{} vs {expected}",
            e.value
        );
        let r = along_x
            .residuals(&input(&s.mesh, &fabric, &cloth, &s.pattern_layout))
            .unwrap()
            .unwrap();
        assert_eq!(r.values.len(), s.mesh.num_triangles());
    }

    /// Both directions below, one above, both above, near the bounds, along and across the principal
    /// directions, for random grain directions: the gradient and the residuals' Jacobian match central
    /// differences, and the value is zero exactly when nothing exceeds.
    #[test]
    fn gradient_and_residuals_match_finite_differences_in_every_regime() {
        let s = strip(2, 1, 0.1);
        let fabric = fabric();
        for seed in [1, 2, 3] {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            // `Some(active)` where every direction agrees (all stretches below both bounds, or all above
            // both), `None` where it depends on the grain.
            for (name, l1, l2, active) in [
                ("both below", 1.1, 1.0, Some(false)),
                ("compressed", 0.8, 0.7, Some(false)),
                ("one above", 1.6, 1.0, None),
                ("both above", 1.7, 1.5, Some(true)),
                ("just above", COURSE + 2e-3, 1.0, None),
                ("equal above", 1.6, 1.6, Some(true)),
            ] {
                let f = deformation(&mut rng, l1, l2);
                let angle = rng.random_range(-3.0..3.0);
                let (cloth, pattern) = place(&mut rng, &s, &f, angle, 2e-4);
                let theta: Real = rng.random_range(-3.0..3.0);
                let t = term(&s.mesh, Vec2::new(theta.cos(), theta.sin()));
                let v = check_term_gradient(&t, &s.mesh, &fabric, &cloth, &pattern, &fd());
                match active {
                    Some(true) => assert!(v > 0.0, "{name}"),
                    Some(false) => assert_eq!(v, 0.0, "{name}"),
                    None => {}
                }
                check_term_residuals(&t, &s.mesh, &fabric, &cloth, &pattern, &fd());
            }
        }
    }

    /// A strip wrapped round a cylinder with a stretch that grows along it: triangles below and above the
    /// course bound in one garment.
    #[test]
    fn bent_garment_with_mixed_regimes() {
        let s = strip(4, 2, 0.05);
        let fabric = fabric();
        let t = term(&s.mesh, Vec2::new(0.0, 1.0));
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let cloth: Vec<Vec3> = s
            .cloth_layout
            .iter()
            .map(|p| {
                let sx = 1.0 + 4.0 * p.x;
                let a = p.x * sx / 0.3;
                let j = Vec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                ) * 1e-4;
                Vec3::new(0.3 * a.cos(), 0.3 * a.sin(), 1.05 * p.y) + j
            })
            .collect();
        let e = t
            .evaluate(&input(&s.mesh, &fabric, &cloth, &s.pattern_layout), None)
            .unwrap();
        assert!(e.per_element.contains(&0.0));
        assert!(e.per_element.iter().any(|&v| v > 0.0));
        check_term_gradient(&t, &s.mesh, &fabric, &cloth, &s.pattern_layout, &fd());
        check_term_residuals(&t, &s.mesh, &fabric, &cloth, &s.pattern_layout, &fd());
    }

    #[test]
    fn invalid_parameters_and_inputs_are_errors_not_nan() {
        let s = strip(1, 1, 0.1);
        let n = s.mesh.panels.len();
        for (w, b) in [
            (-1.0, [1.2, 1.2]),
            (Real::NAN, [1.2, 1.2]),
            (1.0, [0.9, 1.2]),
            (1.0, [1.2, Real::INFINITY]),
            (1.0, [Real::NAN, 1.2]),
        ] {
            let err = FabricStretchLimit::new(w, b, vec![Vec2::y(); n]).unwrap_err();
            assert!(matches!(err, TermError::Parameter { .. }), "{err}");
        }
        assert!(FabricStretchLimit::new(1.0, [1.2, 1.2], vec![Vec2::zeros(); n]).is_err());
        let fabric = fabric();
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        let (cloth, mut pattern) = place(&mut rng, &s, &crate::math::Mat3x2::identity(), 0.3, 0.0);
        // A wale direction for a panel the mesh does not have.
        let short = FabricStretchLimit::new(1.0, [1.2, 1.2], vec![Vec2::y(); n + 1]).unwrap();
        assert!(matches!(
            short.evaluate(&input(&s.mesh, &fabric, &cloth, &pattern), None),
            Err(TermError::Invalid { .. })
        ));
        let t = term(&s.mesh, Vec2::y());
        // A cloth collapsed onto a line stretches nothing above the bounds: zero, not NaN.
        let line: Vec<Vec3> = cloth.iter().map(|p| Vec3::new(p.x, 0.0, 0.0)).collect();
        let v = t
            .evaluate(&input(&s.mesh, &fabric, &line, &pattern), None)
            .unwrap()
            .value;
        assert!(v.is_finite());
        let [a, b, _] = s.mesh.pattern_triangles[0];
        pattern.swap(a, b);
        assert!(matches!(
            t.evaluate(&input(&s.mesh, &fabric, &cloth, &pattern), None),
            Err(TermError::Collapsed { triangle: 0, .. })
        ));
    }
}
