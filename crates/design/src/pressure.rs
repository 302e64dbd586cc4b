//! The pressure objective (thesis Eq. 177): the garment's interface pressure on the body, by the
//! generalized Young–Laplace law per cloth triangle ([`crate::young_laplace_pressure`], Eq. 174, with the
//! mid-edge shape operator of [`crate::mid_edge_shape_operator`], Eq. 175–176), close to a target value
//! or inside a target range.
//!
//! # The objective
//!
//! For cloth triangle `f` with rest (pattern) area `Ā_f` (m²) and pressure `p_f` (Pa), the excursion is
//!
//! ```text
//! e_f = p_f − T                                   (PressureTarget::Value(T)),
//! e_f = p_f − p_min if p_f < p_min, p_f − p_max if p_f > p_max, 0 inside   (PressureTarget::Range),
//! ```
//!
//! and the lift-off `g_f = min(p_f, 0)` (negative pressure: the cloth over a concave region would leave
//! the body, which the coupled model cannot represent). The objective is
//!
//! ```text
//! T = Σ_f Ā_f (w e_f² + w_neg g_f²)               (m² Pa² × weight)
//! ```
//!
//! — Eq. 177 with weight `w`, plus a separate lift-off penalty of weight `w_neg` (0 turns it off; a
//! target below zero cannot be met where it is on). `per_element` is per cloth triangle, `Ā_f (w e_f² +
//! w_neg g_f²)`.
//!
//! # The boundary ring
//!
//! The mid-edge operator cannot know the normal across a free edge of the cloth, and the pressure of the
//! triangles with a vertex on the free boundary is off by a large fraction wherever the boundary is
//! curved (measured in `mid_edge_shape_operator`'s tests: O(1) of the curvature on the boundary triangles,
//! 10–25% on the rest of the ring, 2–4% beyond). By default those triangles are left out: their
//! `per_element` entries and residuals are zero. [`Pressure::with_boundary_ring`] counts them.
//!
//! # Derivatives (Eq. 178–180)
//!
//! `p_f` depends on the positions directly and through the corrections `φ*(x)` of the shape operator,
//! which minimise `ψ̃(φ, x)`. With `∂T/∂φ = Σ_f ∂T/∂p_f ∂p_f/∂φ` and `H̃ μ = ∂T/∂φ` (one sparse solve with
//! the factor of the `φ*` solve), `dT/dx = ∂T/∂x − μᵀ ∂²ψ̃/∂φ∂x`; `φ*` does not depend on the pattern, so
//! `dT/dX̄ = ∂T/∂X̄` (through the stress, the pattern edge normals and `Ā`).
//!
//! # Residuals (Gauss–Newton)
//!
//! `r_f = √(w Ā_f) e_f` for every triangle (0 for left-out ones), then, when `w_neg > 0`, `r_{#F+f} = √(w_neg Ā_f) g_f`; `T = Σ
//! r²` exactly. Their Jacobian includes the `φ` chain rule: row `f` of `dp/dx` is `∂p_f/∂x − μ_fᵀ
//! ∂²ψ̃/∂φ∂x` with `H̃ μ_f = ∂p_f/∂φ`, one solve per triangle (batched). Because `H̃⁻¹` is dense, so are
//! these rows; they decay geometrically away from the triangle (`H̃` is diagonally dominant on reasonable
//! meshes), and entries below `1e-12` of the row's largest are dropped, so a row holds the vertices within
//! a few dozen rings — up to `#F × #Vc` entries on small garments (1,500 triangles: about 1.2 million).

use crate::math::{Real, Vec2, Vec3};
use crate::mid_edge_shape_operator::BoundaryEdges;
use crate::term::{
    Residuals, Term, TermError, TermEvaluation, TermGradient, TermInput, check_weight,
};
use crate::triangle_strain::TriangleStrain;
use crate::young_laplace_pressure::{
    TrianglePressure, check_pressure_input, pressure_slots, solve_shape_operator, triangle_pressure,
};

/// The wanted pressure.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PressureTarget {
    /// One value (Pa).
    Value(Real),
    /// A range `[min, max]` (Pa), no penalty inside.
    Range {
        /// Lower end (Pa).
        min: Real,
        /// Upper end (Pa), > min.
        max: Real,
    },
}

impl PressureTarget {
    /// The excursion `e(p)` (Pa) and `de/dp`.
    fn excursion(&self, p: Real) -> (Real, Real) {
        match *self {
            Self::Value(t) => (p - t, 1.0),
            Self::Range { min, .. } if p < min => (p - min, 1.0),
            Self::Range { max, .. } if p > max => (p - max, 1.0),
            Self::Range { .. } => (0.0, 0.0),
        }
    }
}

/// The pressure objective of Eq. 177; see the module documentation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pressure {
    weight: Real,
    target: PressureTarget,
    negative_weight: Real,
    boundary: BoundaryEdges,
    include_boundary_ring: bool,
}

/// One triangle's pressure, excursion and lift-off.
struct TriangleTerms {
    pressure: TrianglePressure,
    rest_area: Real,
    rest_area_gradient: [Vec2; 3],
    excursion: Real,
    excursion_slope: Real,
    lift_off: Real,
    lift_off_slope: Real,
}

impl Pressure {
    /// Name of the term in reports.
    pub const NAME: &'static str = crate::young_laplace_pressure::TERM_NAME;

    /// The objective with weight `weight` (1/(m² Pa²), ≥ 0), target `target` (Pa, finite; a range needs
    /// `min < max`) and lift-off weight `negative_weight` (1/(m² Pa²), ≥ 0).
    pub fn new(
        weight: Real,
        target: PressureTarget,
        negative_weight: Real,
    ) -> Result<Self, TermError> {
        let bad = |message: String| {
            Err(TermError::Parameter {
                term: Self::NAME,
                message,
            })
        };
        check_weight(Self::NAME, "weight", weight)?;
        check_weight(Self::NAME, "negative_weight", negative_weight)?;
        match target {
            PressureTarget::Value(t) if !t.is_finite() => {
                return bad(format!("target_pa must be finite, got {t}"));
            }
            PressureTarget::Range { min, max } if !(min.is_finite() && max.is_finite()) => {
                return bad(format!(
                    "min_pa and max_pa must be finite, got {min}, {max}"
                ));
            }
            PressureTarget::Range { min, max } if min >= max => {
                return bad(format!("min_pa ({min}) must be below max_pa ({max})"));
            }
            _ => {}
        }
        Ok(Self {
            weight,
            target,
            negative_weight,
            boundary: BoundaryEdges::default(),
            include_boundary_ring: false,
        })
    }

    /// The same objective with the boundary-edge treatment `boundary` of the shape operator.
    pub fn with_boundary(mut self, boundary: BoundaryEdges) -> Self {
        self.boundary = boundary;
        self
    }

    /// The same objective counting (`true`) or leaving out (`false`, default) the triangles with a vertex
    /// on the cloth's free boundary; see the module documentation.
    pub fn with_boundary_ring(mut self, include: bool) -> Self {
        self.include_boundary_ring = include;
        self
    }

    /// Whether the triangles touching the free boundary are counted.
    pub fn includes_boundary_ring(&self) -> bool {
        self.include_boundary_ring
    }

    /// The weight `w` (1/(m² Pa²)).
    pub fn weight(&self) -> Real {
        self.weight
    }

    /// The target.
    pub fn target(&self) -> PressureTarget {
        self.target
    }

    /// The lift-off weight `w_neg` (1/(m² Pa²)).
    pub fn negative_weight(&self) -> Real {
        self.negative_weight
    }

    /// The boundary-edge treatment of the shape operator.
    pub fn boundary(&self) -> BoundaryEdges {
        self.boundary
    }

    fn triangle_terms(
        &self,
        op: &crate::mid_edge_shape_operator::MidEdgeShapeOperator,
        input: &TermInput,
        phi: &[Real],
        f: usize,
    ) -> Result<TriangleTerms, TermError> {
        let pressure = triangle_pressure(op, input, phi, f)?;
        let mesh = input.mesh;
        let x = mesh.cloth_triangles[f].map(|v| input.cloth[v]);
        let rest = mesh.pattern_triangles[f].map(|v| input.pattern[v]);
        let strain = TriangleStrain::new(&x, &rest).ok_or(TermError::Collapsed {
            term: Self::NAME,
            triangle: f,
        })?;
        let (excursion, excursion_slope) = self.target.excursion(pressure.value);
        let (lift_off, lift_off_slope) = if pressure.value < 0.0 {
            (pressure.value, 1.0)
        } else {
            (0.0, 0.0)
        };
        Ok(TriangleTerms {
            pressure,
            rest_area: strain.area,
            rest_area_gradient: strain.area_gradient(),
            excursion,
            excursion_slope,
            lift_off,
            lift_off_slope,
        })
    }

    /// `#F` flags: the triangles the objective counts.
    fn counted(&self, op: &crate::mid_edge_shape_operator::MidEdgeShapeOperator) -> Vec<bool> {
        if self.include_boundary_ring {
            vec![true; op.boundary_ring().len()]
        } else {
            op.boundary_ring().iter().map(|b| !b).collect()
        }
    }

    fn check(&self, input: &TermInput, gradient: Option<&TermGradient>) -> Result<(), TermError> {
        check_pressure_input(Self::NAME, input, gradient)
    }
}

impl Term for Pressure {
    fn name(&self) -> &'static str {
        Self::NAME
    }

    /// Value in m² Pa² × weight; `per_element` per cloth triangle. Adds `dT/dx` (`#Vc × 3`, including the
    /// corrections' chain rule) and `∂T/∂X̄` (`#Vp × 2`), in m Pa² × weight.
    #[allow(clippy::needless_range_loop)] // parallel per-triangle arrays
    fn evaluate(
        &self,
        input: &TermInput,
        mut gradient: Option<&mut TermGradient>,
    ) -> Result<TermEvaluation, TermError> {
        self.check(input, gradient.as_deref())?;
        let (op, solution) = solve_shape_operator(input, self.boundary)?;
        let mesh = input.mesh;
        let mut per_element = Vec::with_capacity(mesh.num_triangles());
        let mut d_phi = vec![0.0; op.num_edges()];
        let counted = self.counted(&op);
        for f in 0..mesh.num_triangles() {
            if !counted[f] {
                per_element.push(0.0);
                continue;
            }
            let t = self.triangle_terms(&op, input, &solution.phi, f)?;
            let (w, wn) = (self.weight, self.negative_weight);
            let per_area = w * t.excursion * t.excursion + wn * t.lift_off * t.lift_off;
            per_element.push(t.rest_area * per_area);
            let Some(grad) = gradient.as_deref_mut() else {
                continue;
            };
            let d_p = 2.0
                * t.rest_area
                * (w * t.excursion * t.excursion_slope + wn * t.lift_off * t.lift_off_slope);
            for (slot, v) in pressure_slots(&op, input, f).iter().enumerate() {
                if let Some(v) = v {
                    grad.cloth[*v] += t.pressure.d_cloth[slot] * d_p;
                }
            }
            for c in 0..3 {
                grad.pattern[mesh.pattern_triangles[f][c]] +=
                    t.pressure.d_pattern[c] * d_p + t.rest_area_gradient[c] * per_area;
            }
            for (k, e) in op.face_edges(f).iter().enumerate() {
                d_phi[*e] += t.pressure.d_phi[k] * d_p;
            }
        }
        if let Some(grad) = gradient {
            solution.adjoint_solve(&op, &mut d_phi);
            solution.add_adjoint_product(&op, input.cloth, &d_phi, &mut grad.cloth);
        }
        TermEvaluation::from_per_element(Self::NAME, per_element)
    }

    /// `r_f = √(w Ā_f) e_f` per cloth triangle, then (when `w_neg > 0`) `√(w_neg Ā_f) min(p_f, 0)` per
    /// cloth triangle (m Pa × √weight); Jacobians include the corrections' chain rule (see the module
    /// documentation).
    #[allow(clippy::needless_range_loop)] // parallel per-triangle arrays
    fn residuals(&self, input: &TermInput) -> Option<Result<Residuals, TermError>> {
        let run = || {
            self.check(input, None)?;
            let (op, solution) = solve_shape_operator(input, self.boundary)?;
            let mesh = input.mesh;
            let nf = mesh.num_triangles();
            let ne = op.num_edges();
            let terms: Vec<TriangleTerms> = (0..nf)
                .map(|f| self.triangle_terms(&op, input, &solution.phi, f))
                .collect::<Result<_, _>>()?;
            // μ_f = H̃⁻¹ ∂p_f/∂φ for every triangle, in batches.
            let mixed = solution.mixed_entries(&op, input.cloth);
            let mut by_edge: Vec<Vec<(usize, Vec3)>> = vec![Vec::new(); ne];
            for (e, v, d) in mixed {
                by_edge[e].push((v, d));
            }
            let nc = mesh.num_cloth_vertices;
            // Total dp_f/dx per triangle as sparse (vertex, gradient) lists.
            let mut rows: Vec<Vec<(usize, Vec3)>> = Vec::with_capacity(nf);
            let batch = 128;
            let mut dense = vec![Vec3::zeros(); nc];
            let mut touched = vec![false; nc];
            for start in (0..nf).step_by(batch) {
                let count = batch.min(nf - start);
                let mut rhs = vec![0.0; count * ne];
                for c in 0..count {
                    let f = start + c;
                    for (k, e) in op.face_edges(f).iter().enumerate() {
                        rhs[c * ne + e] += terms[f].pressure.d_phi[k];
                    }
                }
                solution.adjoint_solve_many(&op, &mut rhs, count);
                for c in 0..count {
                    let f = start + c;
                    let mut list = Vec::new();
                    for (slot, v) in pressure_slots(&op, input, f).iter().enumerate() {
                        if let Some(v) = v {
                            if !touched[*v] {
                                touched[*v] = true;
                                list.push(*v);
                            }
                            dense[*v] += terms[f].pressure.d_cloth[slot];
                        }
                    }
                    for (e, entries) in by_edge.iter().enumerate() {
                        let mu = rhs[c * ne + e];
                        if mu == 0.0 {
                            continue;
                        }
                        for (v, d) in entries {
                            if !touched[*v] {
                                touched[*v] = true;
                                list.push(*v);
                            }
                            dense[*v] -= d * mu;
                        }
                    }
                    let largest = list.iter().fold(0.0_f64, |m, v| m.max(dense[*v].norm()));
                    let mut row = Vec::new();
                    for v in list {
                        let d = dense[v];
                        if d.norm() > 1e-12 * largest {
                            row.push((v, d));
                        }
                        dense[v] = Vec3::zeros();
                        touched[v] = false;
                    }
                    rows.push(row);
                }
            }
            let mut out = Residuals::default();
            let counted = self.counted(&op);
            let mut push = |k: usize, f: usize, weight: Real, value: Real, slope: Real| {
                if !counted[f] {
                    out.values.push(0.0);
                    return;
                }
                let t = &terms[f];
                let root = (weight * t.rest_area).sqrt();
                out.values.push(root * value);
                // ∂r = √w (value/(2√Ā) ∂Ā + √Ā slope ∂p).
                let d_p = root * slope;
                let d_area = if t.rest_area > 0.0 {
                    weight.sqrt() * value * 0.5 / t.rest_area.sqrt()
                } else {
                    0.0
                };
                if d_p != 0.0 {
                    for (v, d) in &rows[f] {
                        out.cloth_jacobian.push((k, *v, d * d_p));
                    }
                }
                for c in 0..3 {
                    out.pattern_jacobian.push((
                        k,
                        mesh.pattern_triangles[f][c],
                        t.pressure.d_pattern[c] * d_p + t.rest_area_gradient[c] * d_area,
                    ));
                }
            };
            for f in 0..nf {
                let t = &terms[f];
                push(f, f, self.weight, t.excursion, t.excursion_slope);
            }
            if self.negative_weight > 0.0 {
                for f in 0..nf {
                    let t = &terms[f];
                    push(
                        nf + f,
                        f,
                        self.negative_weight,
                        t.lift_off,
                        t.lift_off_slope,
                    );
                }
            }
            if out.values.iter().any(|v| !v.is_finite()) {
                return Err(TermError::Invalid {
                    term: Self::NAME,
                    message: "the residuals are not finite; the state is out of range".into(),
                });
            }
            Ok(out)
        };
        Some(run())
    }
}

#[cfg(test)]
mod tests;
