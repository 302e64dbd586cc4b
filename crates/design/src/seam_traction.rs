//! The seam stress objective (thesis Eq. 181): reduce the traction that pulls the two sides of every seam
//! apart.
//!
//! # The traction
//!
//! For each seam edge, on each side `s` of the seam, take the cloth triangle of that side containing the
//! edge, its second Piola–Kirchhoff stress `S = 2 ∂ψ/∂C` (Pa, 2 × 2, in the pattern plane; `ψ` the
//! fabric's smoothed tension-field density of `skintight_physics::tension_field_density`), the rest
//! length `l0` (m) of the edge on that side and the unit normal `n` of the edge in the pattern plane.
//! The normal traction is
//!
//! ```text
//! τ = n·S n = 2 Σ_i ψ_i (n_i·n)²            (Pa, with C = Σ μ_i n_i n_iᵀ, ψ_i = ∂ψ/∂μ_i)
//! ```
//!
//! (the sign of `n` does not matter). The tension-field density never pushes (`ψ_i ≥ 0`), so `τ ≥ 0`:
//! zero for slack cloth, positive once the seam is pulled. An orthotropic curve fabric (issue 46) gives
//! `S` in the triangle's course/wale frame ([`crate::Fabric::response`]); its relaxed stress is positive
//! semi-definite too, so `τ ≥ 0` still, and `∂τ/∂C = 2 dS_ψ[n nᵀ]` with the law's symmetric tangent.
//!
//! # The objective
//!
//! Eq. 181 sums the plain traction, `T = Σ l0 d τ` (`d` the fabric thickness, m): `l0 d τ` is the force
//! (N) the seam carries across that edge measured on the rest configuration. Because `τ ≥ 0` that sum is
//! already a positive quantity to minimise, but it only lowers the *total* seam force: a design may
//! trade a slack seam elsewhere for one highly loaded edge, and seams fail at their peak load. The default
//! form is therefore the squared traction, a sum of squares,
//!
//! ```text
//! T = w Σ_seam edges Σ_sides l0 d τ²             (SeamTractionForm::Squared, m² Pa² × weight)
//! ```
//!
//! which penalises peaks more than averages, and exposes the residuals `r = √(w l0 d) τ` for
//! Gauss–Newton. The thesis's plain Eq. 181 is available as [`SeamTractionForm::Linear`],
//! `T = w Σ l0 d τ` (N × weight, no residuals).
//!
//! # Derivatives
//!
//! `τ` depends on the cloth positions through `C` and on the pattern through `C` (`F = Ds Dm⁻¹`), `n` and
//! `l0`. With `a_i = n_i·n`, `ψ_ij = ∂²ψ/∂μ_i∂μ_j` and `γ = (ψ1 − ψ2)/(μ1 − μ2)` (from
//! `TensionFieldDensity::stretch_divided_difference`, finite and equal to `ψ11 − ψ12` at `μ1 = μ2`), the
//! derivative of `τ` with respect to `C` is the symmetric
//!
//! ```text
//! ∂τ/∂C = 2 [ Σ_j (Σ_i ψ_ij a_i²) n_j n_jᵀ + γ a1 a2 (n1 n2ᵀ + n2 n1ᵀ) ],
//! ```
//!
//! which at `μ1 = μ2` equals `2 [ψ12 I + (ψ11 − ψ12) n nᵀ]` whatever eigenvectors were picked, so it is
//! exact and continuous at repeated stretches (`ψ` is C², so `S` is C¹ in `C`). It goes to the corners as
//! in `triangle_strain`. With `e = X̄_b − X̄_a`, `n = R e/|e|`: `∂τ/∂n = 2 S n`,
//! `∂τ/∂e = (I − ê êᵀ) Rᵀ (2 S n) / |e|` and `∂l0/∂e = ê`.
//!
//! # Elements
//!
//! `per_element` has two entries per seam edge: seams in order, edges along each seam in order (the
//! closing edge last for a closed seam), side 0 then side 1; entry `2m + s` is edge `m`, side `s`. A seam
//! edge must be a side of exactly one triangle of its panel, else [`TermError::Invalid`]; a degenerate or
//! clockwise pattern triangle next to a seam is [`TermError::Collapsed`].

use crate::design_mesh::DesignMesh;
use crate::math::{Mat2, Real, Vec2};
use crate::term::{
    Residuals, Term, TermError, TermEvaluation, TermGradient, TermInput, check_weight,
};
use crate::triangle_strain::TriangleStrain;
use std::collections::HashMap;

/// Which function of the seam traction is summed; see the module documentation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SeamTractionForm {
    /// `w Σ l0 d τ²` (m² Pa² × weight): penalises peak traction; a sum of squares with residuals.
    #[default]
    Squared,
    /// `w Σ l0 d τ` (N × weight): the plain Eq. 181, the total seam force; no residuals.
    Linear,
}

/// The seam traction objective of Eq. 181; see the module documentation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SeamTraction {
    weight: Real,
    form: SeamTractionForm,
}

/// One side of one seam edge.
#[derive(Clone, Copy, Debug)]
struct TractionSide {
    /// Pattern vertices at the ends of the edge.
    a: usize,
    b: usize,
    /// The triangle of that side containing the edge.
    triangle: usize,
}

/// Traction of one side and its derivatives.
struct SideTraction {
    /// Rest length `l0` (m).
    length: Real,
    /// `τ` (Pa).
    traction: Real,
    /// `∂τ/∂x` per triangle corner (Pa/m).
    d_cloth: [crate::math::Vec3; 3],
    /// `∂τ/∂X̄` per triangle corner (Pa/m), through `C` only.
    d_rest: [Vec2; 3],
    /// `∂τ/∂e` (Pa/m) through the normal.
    d_edge: Vec2,
    /// Unit edge direction `ê` (`∂l0/∂e`).
    direction: Vec2,
}

impl SeamTraction {
    /// Name of the term in reports.
    pub const NAME: &'static str = "seam_traction";

    /// The objective with weight `weight` (≥ 0, finite) summing `form` of the traction.
    pub fn new(weight: Real, form: SeamTractionForm) -> Result<Self, TermError> {
        Ok(Self {
            weight: check_weight(Self::NAME, "weight", weight)?,
            form,
        })
    }

    /// The weight `w`.
    pub fn weight(&self) -> Real {
        self.weight
    }

    /// The form summed.
    pub fn form(&self) -> SeamTractionForm {
        self.form
    }

    /// The seam edge sides in `per_element` order, with their triangles.
    fn sides(mesh: &DesignMesh) -> Result<Vec<TractionSide>, TermError> {
        let invalid = |message: String| TermError::Invalid {
            term: Self::NAME,
            message,
        };
        let np = mesh.num_pattern_vertices();
        let mut sides = Vec::new();
        for (si, seam) in mesh.seams.iter().enumerate() {
            let [v0, v1] = &seam.vertices;
            if v0.len() != v1.len() {
                return Err(invalid(format!("seam {si} has sides of different lengths")));
            }
            let n = v0.len();
            let edges = if seam.closed && n >= 3 {
                n
            } else {
                n.saturating_sub(1)
            };
            for k in 0..edges {
                for side in [v0, v1] {
                    let (a, b) = (side[k], side[(k + 1) % n]);
                    if a >= np || b >= np || a == b {
                        return Err(invalid(format!("seam {si} has an invalid edge ({a}, {b})")));
                    }
                    sides.push(TractionSide {
                        a,
                        b,
                        triangle: usize::MAX,
                    });
                }
            }
        }
        let mut lookup: HashMap<(usize, usize), Vec<usize>> = HashMap::new();
        for (i, s) in sides.iter().enumerate() {
            lookup
                .entry((s.a.min(s.b), s.a.max(s.b)))
                .or_default()
                .push(i);
        }
        let mut count = vec![0_usize; sides.len()];
        for (f, t) in mesh.pattern_triangles.iter().enumerate() {
            for c in 0..3 {
                let (u, v) = (t[c], t[(c + 1) % 3]);
                if let Some(list) = lookup.get(&(u.min(v), u.max(v))) {
                    for &i in list {
                        sides[i].triangle = f;
                        count[i] += 1;
                    }
                }
            }
        }
        if let Some(i) = count.iter().position(|&c| c != 1) {
            return Err(invalid(format!(
                "seam edge ({}, {}) is a side of {} pattern triangles, not 1",
                sides[i].a, sides[i].b, count[i]
            )));
        }
        Ok(sides)
    }

    fn traction(&self, input: &TermInput, side: &TractionSide) -> Result<SideTraction, TermError> {
        let mesh = input.mesh;
        let f = side.triangle;
        let x = mesh.cloth_triangles[f].map(|v| input.cloth[v]);
        let rest = mesh.pattern_triangles[f].map(|v| input.pattern[v]);
        let strain = TriangleStrain::new(&x, &rest).ok_or(TermError::Collapsed {
            term: Self::NAME,
            triangle: f,
        })?;
        let e = input.pattern[side.b] - input.pattern[side.a];
        let length = e.norm();
        if length.is_nan() || length <= 0.0 {
            return Err(TermError::Invalid {
                term: Self::NAME,
                message: format!("seam edge ({}, {}) has zero length", side.a, side.b),
            });
        }
        let dir = e / length;
        let normal = Vec2::new(dir.y, -dir.x);
        // τ = nᵀ S n with S = 2 ∂ψ/∂C: ∂τ/∂C = 2 dS_ψ[n nᵀ] (the law's tangent is symmetric).
        let r = input
            .fabric
            .response(f, &strain.c, strain.mu, &strain.n, true);
        let s_half = r.stress;
        let traction = 2.0 * normal.dot(&(s_half * normal));
        let g: Mat2 = r
            .tangent
            .expect("asked for the second derivative")
            .apply(&strain.n, &(normal * normal.transpose()))
            * 2.0;
        let (d_cloth, d_rest) = strain.corner_gradients_from_c(&g);
        // ∂τ/∂n = 2 S n; n = R ê, R(u, v) = (v, −u), Rᵀ(u, v) = (−v, u).
        let s_n = s_half * normal * 4.0;
        let rt = Vec2::new(-s_n.y, s_n.x);
        let d_edge = (rt - dir * dir.dot(&rt)) / length;
        Ok(SideTraction {
            length,
            traction,
            d_cloth,
            d_rest,
            d_edge,
            direction: dir,
        })
    }

    fn thickness(input: &TermInput) -> Result<Real, TermError> {
        let d = input.fabric.thickness;
        if d.is_finite() && d > 0.0 {
            Ok(d)
        } else {
            Err(TermError::Invalid {
                term: Self::NAME,
                message: format!("fabric thickness must be finite and positive, got {d} m"),
            })
        }
    }
}

impl Term for SeamTraction {
    fn name(&self) -> &'static str {
        Self::NAME
    }

    /// Value in m² Pa² × weight ([`SeamTractionForm::Squared`]) or N × weight
    /// ([`SeamTractionForm::Linear`]); `per_element` per seam edge side (see the module documentation).
    /// Adds `∂T/∂x` (`#Vc × 3`) and `∂T/∂X̄` (`#Vp × 2`), in units of T per m.
    fn evaluate(
        &self,
        input: &TermInput,
        mut gradient: Option<&mut TermGradient>,
    ) -> Result<TermEvaluation, TermError> {
        input.validate(Self::NAME, gradient.as_deref())?;
        let thickness = Self::thickness(input)?;
        let mesh = input.mesh;
        let sides = Self::sides(mesh)?;
        let mut per_element = Vec::with_capacity(sides.len());
        for side in &sides {
            let t = self.traction(input, side)?;
            let scale = self.weight * thickness;
            let (value, d_tau, d_length) = match self.form {
                SeamTractionForm::Squared => (
                    scale * t.length * t.traction * t.traction,
                    scale * 2.0 * t.length * t.traction,
                    scale * t.traction * t.traction,
                ),
                SeamTractionForm::Linear => (
                    scale * t.length * t.traction,
                    scale * t.length,
                    scale * t.traction,
                ),
            };
            per_element.push(value);
            let Some(grad) = gradient.as_deref_mut() else {
                continue;
            };
            let f = side.triangle;
            for k in 0..3 {
                grad.cloth[mesh.cloth_triangles[f][k]] += t.d_cloth[k] * d_tau;
                grad.pattern[mesh.pattern_triangles[f][k]] += t.d_rest[k] * d_tau;
            }
            let d_edge = t.d_edge * d_tau + t.direction * d_length;
            grad.pattern[side.b] += d_edge;
            grad.pattern[side.a] -= d_edge;
        }
        TermEvaluation::from_per_element(Self::NAME, per_element)
    }

    /// For [`SeamTractionForm::Squared`]: `r = √(w l0 d) τ` (m Pa × √weight) per seam edge side, in
    /// `per_element` order. `None` for [`SeamTractionForm::Linear`], which is not a sum of squares.
    fn residuals(&self, input: &TermInput) -> Option<Result<Residuals, TermError>> {
        if self.form != SeamTractionForm::Squared {
            return None;
        }
        let run = || {
            input.validate(Self::NAME, None)?;
            let thickness = Self::thickness(input)?;
            let mesh = input.mesh;
            let mut out = Residuals::default();
            for (k, side) in Self::sides(mesh)?.iter().enumerate() {
                let t = self.traction(input, side)?;
                let root_wd = (self.weight * thickness).sqrt();
                let root_l = t.length.sqrt();
                out.values.push(root_wd * root_l * t.traction);
                // ∂r = √(wd) (τ/(2√l0) ∂l0 + √l0 ∂τ).
                let d_tau = root_wd * root_l;
                let d_length = root_wd * t.traction * 0.5 / root_l;
                let f = side.triangle;
                for c in 0..3 {
                    out.cloth_jacobian
                        .push((k, mesh.cloth_triangles[f][c], t.d_cloth[c] * d_tau));
                    out.pattern_jacobian.push((
                        k,
                        mesh.pattern_triangles[f][c],
                        t.d_rest[c] * d_tau,
                    ));
                }
                let d_edge = t.d_edge * d_tau + t.direction * d_length;
                out.pattern_jacobian.push((k, side.b, d_edge));
                out.pattern_jacobian.push((k, side.a, -d_edge));
            }
            Ok(out)
        };
        Some(run())
    }
}

#[cfg(test)]
mod tests;
