//! Interface pressure of the garment on the body by the generalized Young–Laplace law (thesis Eq. 174),
//! per cloth triangle:
//!
//! ```text
//! p = d tr(σ Λ)      (Pa)
//! ```
//!
//! with `d` the fabric thickness (m), `Λ` the mid-edge shape operator of the cloth triangle (1/m,
//! [`crate::mid_edge_shape_operator`], with the corrections `φ*`) and `σ` the membrane's Cauchy stress
//! (Pa) from the fabric's law at the triangle's deformation from the pattern triangle `X̄` to the cloth
//! triangle `x`: the smoothed tension-field density of `skintight_physics::tension_field_density`, or
//! (issue 46) the orthotropic curve law of `skintight_physics::orthotropic_density` read in the
//! triangle's course/wale frame ([`Fabric::response`]; the frame is held fixed as the pattern moves).
//!
//! # The stress
//!
//! With `F` (3 × 2) the deformation gradient, `C = FᵀF`, the second Piola–Kirchhoff stress
//! `S = 2 ∂ψ/∂C = 2 Σ_i ψ_i n_i n_iᵀ` (Pa, 2 × 2, `ψ_i = ∂ψ/∂μ_i` at the eigenvalues `μ_i` of `C`) and the
//! area ratio `J = A/Ā` (deformed over rest area), the membrane's Cauchy stress is `σ = F S Fᵀ / J`
//! (Pa, 3 × 3 in the tangent plane). `d σ` with the *rest* thickness `d` is then the exact surface stress
//! (N/m, force per deformed length) whatever the thickness change, since the 3D Cauchy stress times the
//! current thickness is `d F S Fᵀ / J`.
//!
//! # A simpler form
//!
//! `Fᵀ t_k = J t̄_k`, where `t̄_k` is the pattern edge normal of edge `k` (the pattern edge `ē_k` turned by
//! −90°, length `l̄_k`): `F` maps `ē_k` to `e_k` and the edge normals are determined by their products with
//! the edges (`e_j·t_k = ±2A = J (ē_j·t̄_k)`). Hence
//!
//! ```text
//! p = (d/J) Σ_k a_k/(A l_k) t_kᵀ F S Fᵀ t_k = (d/Ā) Σ_k a_k (t̄_kᵀ S t̄_k) / l_k,
//! ```
//!
//! with `a_k = θ_k/2 + s_k φ_k` (rad), `l_k` the deformed edge length and `Ā` the rest area: the normal
//! traction of `S` across each pattern edge, weighted by the mid-edge angles. The tension-field density
//! never compresses (`ψ_i ≥ 0`), so `p ≥ 0` on convex cloth and `p < 0` (the cloth would lift off) only
//! where the cloth is concave (`a_k < 0`).
//!
//! # Derivatives
//!
//! `p` of a triangle depends on its cloth corners (`F`, `l_k`, `θ_k`), the vertices across its edges
//! (`θ_k`), its pattern corners (`F`, `t̄_k`, `Ā`) and its three `φ_k`. It is evaluated with dual numbers
//! over the 24 position coordinates; `S` enters through its exact tangent: for symmetric `W`, with
//! `W̃_ij = n_iᵀ W n_j`, `ψ_ij = ∂²ψ/∂μ_i∂μ_j` and `γ = (ψ_1 − ψ_2)/(μ_1 − μ_2)` (finite at `μ_1 = μ_2`),
//!
//! ```text
//! ∂(S : W)/∂C = 2 [ Σ_j (Σ_i ψ_ij W̃_ii) n_j n_jᵀ + γ W̃_12 (n_1 n_2ᵀ + n_2 n_1ᵀ) ],
//! ```
//!
//! applied to the three components of `S`. For any law this is `2 dS_ψ[W]`, with `dS_ψ` the law's
//! tangent of `∂ψ/∂C` (`skintight_physics::membrane_law::StressTangent`, symmetric because it is a
//! Hessian): the spectral form above for the isotropic density, `R S_f(H x(Rᵀ W R)) Rᵀ` in the fabric
//! frame `R` for the orthotropic law. `∂p/∂φ_k = (d/Ā) s_k (t̄_kᵀ S t̄_k) / l_k`.

use crate::dual::{DVec3, Dual};
use crate::math::{Mat2, Real, Vec2, Vec3};
use crate::mid_edge_shape_operator::{
    MidEdgeError, MidEdgeShapeOperator, MidEdgeSolution, face_geometry, local_duals, local_values,
};
use crate::term::{Fabric, TermError, TermInput};
use crate::triangle_strain::TriangleStrain;
use skintight_physics::membrane_law::StressTangent;

/// The term name this module's errors carry: the pressures are computed for the pressure objective, whose
/// [`crate::Pressure::NAME`] is this constant (defined here, below the objective, so that this file does
/// not import `pressure.rs`, which imports it).
pub(crate) const TERM_NAME: &str = "pressure";

/// Number of dual variables: 3 corners + 3 opposite vertices (3D) + 3 pattern corners (2D).
const N: usize = 24;

/// The pressure of one triangle with its partial derivatives (φ held fixed).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrianglePressure {
    /// `p` (Pa).
    pub value: Real,
    /// `∂p/∂x` (Pa/m) for the three corners, then the vertices across edges 0, 1, 2 (zero where there
    /// is none).
    pub d_cloth: [Vec3; 6],
    /// `∂p/∂X̄` (Pa/m) for the three pattern corners.
    pub d_pattern: [Vec2; 3],
    /// `∂p/∂φ_k` (Pa/rad) for the triangle's three edges.
    pub d_phi: [Real; 3],
}

/// The Cauchy stress `σ = F S Fᵀ / J` (3 × 3, Pa) of cloth triangle `f` (whose grain an orthotropic
/// fabric reads) with corners `x` over pattern corners `rest`; `None` for a degenerate or clockwise
/// pattern triangle.
pub fn cauchy_stress(
    fabric: &Fabric,
    f: usize,
    x: &[Vec3; 3],
    rest: &[Vec2; 3],
) -> Option<crate::math::Mat3> {
    let strain = TriangleStrain::new(x, rest)?;
    let s = second_piola(fabric, f, &strain);
    let area = 0.5 * (x[1] - x[0]).cross(&(x[2] - x[0])).norm();
    let j = area / strain.area;
    Some(strain.f * s * strain.f.transpose() / j)
}

/// `S = 2 ∂ψ/∂C` (Pa, pattern coordinates) of cloth triangle `f` at `strain`.
fn second_piola(fabric: &Fabric, f: usize, strain: &TriangleStrain) -> Mat2 {
    fabric
        .response(f, &strain.c, strain.mu, &strain.n, false)
        .stress
        * 2.0
}

/// `S` of cloth triangle `f` at `strain` and the map `W ↦ ∂(S : W)/∂C` (symmetric 2 × 2) for symmetric
/// `W`; see the module documentation. The tangent of `∂ψ/∂C` is symmetric (a Hessian), so
/// `∂(S : W)/∂C = 2 dS_ψ[W]` with `dS_ψ` the law's [`StressTangent`].
fn stress_and_tangent(fabric: &Fabric, f: usize, strain: &TriangleStrain) -> (Mat2, StressTangent) {
    let r = fabric.response(f, &strain.c, strain.mu, &strain.n, true);
    let tangent = r.tangent.expect("asked for the second derivative");
    (r.stress * 2.0, tangent)
}

/// The pressure of triangle `f` of `op` with the corrections `phi` (`#E`, rad) and its derivatives.
/// `input` supplies the cloth and pattern positions, the pattern triangles and the fabric.
pub fn triangle_pressure(
    op: &MidEdgeShapeOperator,
    input: &TermInput,
    phi: &[Real],
    f: usize,
) -> Result<TrianglePressure, TermError> {
    let (corners, opposite): ([DVec3<N>; 3], [Option<DVec3<N>>; 3]) =
        local_duals::<N>(op, input.cloth, f);
    let geometry = face_geometry(&corners, &opposite);
    let (rest, strain) = rest_and_strain(input, f)?;
    let r: [[Dual<N>; 2]; 3] =
        [0, 1, 2].map(|c| [0, 1].map(|k| Dual::variable(rest[c][k], 18 + 2 * c + k)));
    // Dm and its inverse, Ā = det(Dm)/2.
    let dm = [
        [r[1][0] - r[0][0], r[2][0] - r[0][0]],
        [r[1][1] - r[0][1], r[2][1] - r[0][1]],
    ];
    let det = dm[0][0] * dm[1][1] - dm[0][1] * dm[1][0];
    let inv = [
        [dm[1][1] / det, -dm[0][1] / det],
        [-dm[1][0] / det, dm[0][0] / det],
    ];
    // Ds = [x1 − x0, x2 − x0], F = Ds Dm⁻¹, C = FᵀF.
    let ds: [[Dual<N>; 2]; 3] =
        [0, 1, 2].map(|i| [corners[1][i] - corners[0][i], corners[2][i] - corners[0][i]]);
    let fm: [[Dual<N>; 2]; 3] =
        ds.map(|row| [0, 1].map(|j| row[0] * inv[0][j] + row[1] * inv[1][j]));
    let c = |a: usize, b: usize| fm[0][a] * fm[0][b] + fm[1][a] * fm[1][b] + fm[2][a] * fm[2][b];
    let (c11, c12, c22) = (c(0, 0), c(0, 1), c(1, 1));
    // S components with their tangents.
    let (s_val, tangent) = stress_and_tangent(input.fabric, f, &strain);
    let component = |w: Mat2, value: Real| {
        let g = tangent.apply(&strain.n, &w) * 2.0;
        let mut d = [0.0; N];
        for (k, o) in d.iter_mut().enumerate() {
            *o = g[(0, 0)] * c11.d[k] + 2.0 * g[(0, 1)] * c12.d[k] + g[(1, 1)] * c22.d[k];
        }
        Dual::<N> { v: value, d }
    };
    let s11 = component(Mat2::new(1.0, 0.0, 0.0, 0.0), s_val[(0, 0)]);
    let s22 = component(Mat2::new(0.0, 0.0, 0.0, 1.0), s_val[(1, 1)]);
    let s12 = component(
        Mat2::new(0.0, 0.5, 0.5, 0.0),
        0.5 * (s_val[(0, 1)] + s_val[(1, 0)]),
    );
    let thickness = input.fabric.thickness;
    let rest_area = det * 0.5;
    let signs = op.face_signs(f);
    let edges = op.face_edges(f);
    let mut sum = Dual::<N>::constant(0.0);
    let mut d_phi = [0.0; 3];
    for k in 0..3 {
        // t̄_k = (ē_y, −ē_x).
        let (ex, ey) = (r[(k + 1) % 3][0] - r[k][0], r[(k + 1) % 3][1] - r[k][1]);
        let (tx, ty) = (ey, -ex);
        let q = s11 * tx * tx + s12 * tx * ty * 2.0 + s22 * ty * ty;
        let q_over_l = q / geometry.length[k];
        let a = geometry.theta[k] * 0.5 + signs[k] * phi[edges[k]];
        sum = sum + a * q_over_l;
        if op.has_dof(edges[k]) {
            d_phi[k] = thickness * signs[k] * q_over_l.v / rest_area.v;
        }
    }
    let p = sum / rest_area * thickness;
    let d_cloth = [0, 1, 2, 3, 4, 5].map(|v| Vec3::new(p.d[3 * v], p.d[3 * v + 1], p.d[3 * v + 2]));
    let d_pattern = [0, 1, 2].map(|c| Vec2::new(p.d[18 + 2 * c], p.d[19 + 2 * c]));
    Ok(TrianglePressure {
        value: p.v,
        d_cloth,
        d_pattern,
        d_phi,
    })
}

/// Triangle `f`'s pattern corners (m) and its strain; a collapsed triangle is the pressure term's error.
fn rest_and_strain(input: &TermInput, f: usize) -> Result<([Vec2; 3], TriangleStrain), TermError> {
    let rest = input.mesh.pattern_triangles[f].map(|v| input.pattern[v]);
    let xs = input.mesh.cloth_triangles[f].map(|v| input.cloth[v]);
    let strain = TriangleStrain::new(&xs, &rest).ok_or(TermError::Collapsed {
        term: TERM_NAME,
        triangle: f,
    })?;
    Ok((rest, strain))
}

/// [`triangle_pressure`]'s value alone: the same operations on plain numbers (the same value to the bit,
/// tested), without the 24 derivatives each carries there — what the pressure figures of a design's
/// progress and its report need.
pub fn triangle_pressure_value(
    op: &MidEdgeShapeOperator,
    input: &TermInput,
    phi: &[Real],
    f: usize,
) -> Result<Real, TermError> {
    let (corners, opposite) = local_values(op, input.cloth, f);
    let geometry = face_geometry(&corners, &opposite);
    let (rest, strain) = rest_and_strain(input, f)?;
    let det = (rest[1][0] - rest[0][0]) * (rest[2][1] - rest[0][1])
        - (rest[2][0] - rest[0][0]) * (rest[1][1] - rest[0][1]);
    let s = second_piola(input.fabric, f, &strain);
    let (s11, s22, s12) = (s[(0, 0)], s[(1, 1)], 0.5 * (s[(0, 1)] + s[(1, 0)]));
    let signs = op.face_signs(f);
    let edges = op.face_edges(f);
    let mut sum = 0.0;
    for k in 0..3 {
        let (ex, ey) = (
            rest[(k + 1) % 3][0] - rest[k][0],
            rest[(k + 1) % 3][1] - rest[k][1],
        );
        let (tx, ty) = (ey, -ex);
        let q = s11 * tx * tx + s12 * tx * ty * 2.0 + s22 * ty * ty;
        let a = geometry.theta[k].v * 0.5 + signs[k] * phi[edges[k]];
        sum += a * (q / geometry.length[k].v);
    }
    Ok(sum / (det * 0.5) * input.fabric.thickness)
}

/// The mid-edge operator of `input`'s cloth mesh solved at its cloth positions, errors as
/// [`TermError`]s of the pressure term.
pub(crate) fn solve_shape_operator(
    input: &TermInput,
    boundary: crate::mid_edge_shape_operator::BoundaryEdges,
) -> Result<(MidEdgeShapeOperator, MidEdgeSolution), TermError> {
    let name = TERM_NAME;
    let mesh = input.mesh;
    let convert = |e: MidEdgeError| match e {
        MidEdgeError::Degenerate(f) => TermError::Collapsed {
            term: name,
            triangle: f,
        },
        other => TermError::Invalid {
            term: name,
            message: other.to_string(),
        },
    };
    let op = MidEdgeShapeOperator::new(&mesh.cloth_triangles, mesh.num_cloth_vertices, boundary)
        .map_err(convert)?;
    let solution = op.solve(input.cloth).map_err(convert)?;
    Ok((op, solution))
}

/// Young–Laplace pressure (Pa) of every cloth triangle (`#Fc`) at `input`, with `φ*` solved; positive
/// where the cloth presses on the body, negative where it would lift off.
pub fn young_laplace_pressures(
    input: &TermInput,
    boundary: crate::mid_edge_shape_operator::BoundaryEdges,
) -> Result<Vec<Real>, TermError> {
    input.validate(TERM_NAME, None)?;
    check_thickness(input.fabric)?;
    let (op, solution) = solve_shape_operator(input, boundary)?;
    (0..input.mesh.num_triangles())
        .map(|f| triangle_pressure_value(&op, input, &solution.phi, f))
        .collect()
}

/// Checks a pressure term's input: sizes and finite values ([`TermInput::validate`]), the fabric's
/// thickness, and that every pattern triangle is usable (counted or not); errors name `term`.
pub(crate) fn check_pressure_input(
    term: &'static str,
    input: &TermInput,
    gradient: Option<&crate::term::TermGradient>,
) -> Result<(), TermError> {
    input.validate(term, gradient)?;
    check_thickness(input.fabric)?;
    let mesh = input.mesh;
    for f in 0..mesh.num_triangles() {
        let x = mesh.cloth_triangles[f].map(|v| input.cloth[v]);
        let rest = mesh.pattern_triangles[f].map(|v| input.pattern[v]);
        if TriangleStrain::new(&x, &rest).is_none() {
            return Err(TermError::Collapsed { term, triangle: f });
        }
    }
    Ok(())
}

/// The cloth vertices of triangle `f`'s six pressure slots ([`TrianglePressure::d_cloth`]): its corners,
/// then the vertices across edges 0, 1, 2 (`None` across a free edge).
pub(crate) fn pressure_slots(
    op: &MidEdgeShapeOperator,
    input: &TermInput,
    f: usize,
) -> [Option<usize>; 6] {
    let t = input.mesh.cloth_triangles[f];
    let o = op.face_opposite(f);
    [Some(t[0]), Some(t[1]), Some(t[2]), o[0], o[1], o[2]]
}

/// The fabric thickness, checked finite and positive.
pub(crate) fn check_thickness(fabric: &Fabric) -> Result<Real, TermError> {
    let d = fabric.thickness;
    if d.is_finite() && d > 0.0 {
        Ok(d)
    } else {
        Err(TermError::Invalid {
            term: TERM_NAME,
            message: format!("fabric thickness must be finite and positive, got {d} m"),
        })
    }
}

/// Area-weighted statistics of a per-triangle pressure field.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct PressureStatistics {
    /// Area-weighted mean `p̄ = Σ A p / Σ A` (Pa).
    pub mean_pa: Real,
    /// Area-weighted standard deviation `√(Σ A (p − p̄)² / Σ A)` (Pa).
    pub std_pa: Real,
    /// `std_pa / |mean_pa|` (dimensionless); infinite when the mean is zero.
    pub spread: Real,
    /// Smallest triangle pressure (Pa); negative means lift-off.
    pub min_pa: Real,
    /// Largest triangle pressure (Pa).
    pub max_pa: Real,
    /// Fraction of the area with negative pressure (0–1).
    pub negative_area_fraction: Real,
    /// The total area the statistics are weighted by (m²).
    pub area_m2: Real,
}

impl PressureStatistics {
    /// Statistics of `pressures` (Pa) weighted by `areas` (m², same length, ≥ 0); `None` when the
    /// lengths differ, the total area is not positive or a value is not finite.
    pub fn new(pressures: &[Real], areas: &[Real]) -> Option<Self> {
        if pressures.len() != areas.len()
            || pressures.iter().chain(areas).any(|v| !v.is_finite())
            || areas.iter().any(|&a| a < 0.0)
        {
            return None;
        }
        let total: Real = areas.iter().sum();
        if total <= 0.0 || total.is_nan() {
            return None;
        }
        let mean = pressures
            .iter()
            .zip(areas)
            .map(|(p, a)| p * a)
            .sum::<Real>()
            / total;
        let var = pressures
            .iter()
            .zip(areas)
            .map(|(p, a)| a * (p - mean) * (p - mean))
            .sum::<Real>()
            / total;
        let negative = pressures
            .iter()
            .zip(areas)
            .filter(|(p, _)| **p < 0.0)
            .fold(0.0, |sum, (_, a)| sum + a);
        let std = var.sqrt();
        Some(Self {
            mean_pa: mean,
            std_pa: std,
            spread: if mean != 0.0 {
                std / mean.abs()
            } else {
                Real::INFINITY
            },
            min_pa: pressures.iter().copied().fold(Real::INFINITY, Real::min),
            max_pa: pressures
                .iter()
                .copied()
                .fold(Real::NEG_INFINITY, Real::max),
            negative_area_fraction: negative / total,
            area_m2: total,
        })
    }
}

/// [`PressureStatistics`] of the Young–Laplace pressures at `input`, weighted by the deformed cloth
/// triangle areas; over every triangle when `include_boundary_ring`, else over the triangles without a
/// vertex on the cloth's free boundary (as the pressure objective counts them by default).
pub fn young_laplace_statistics(
    input: &TermInput,
    boundary: crate::mid_edge_shape_operator::BoundaryEdges,
    include_boundary_ring: bool,
) -> Result<PressureStatistics, TermError> {
    let p = young_laplace_pressures(input, boundary)?;
    let ring = if include_boundary_ring {
        vec![false; p.len()]
    } else {
        MidEdgeShapeOperator::new(
            &input.mesh.cloth_triangles,
            input.mesh.num_cloth_vertices,
            boundary,
        )
        .map_err(|e| TermError::Invalid {
            term: TERM_NAME,
            message: e.to_string(),
        })?
        .boundary_ring()
    };
    let (p, tris): (Vec<Real>, Vec<[usize; 3]>) = p
        .iter()
        .zip(&input.mesh.cloth_triangles)
        .zip(&ring)
        .filter(|(_, r)| !**r)
        .map(|((p, t), _)| (*p, *t))
        .unzip();
    let areas: Vec<Real> = tris
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| input.cloth[v]);
            0.5 * (b - a).cross(&(c - a)).norm()
        })
        .collect();
    PressureStatistics::new(&p, &areas).ok_or(TermError::Invalid {
        term: TERM_NAME,
        message: "the pressure statistics are undefined (no area or non-finite pressure)".into(),
    })
}

#[cfg(test)]
pub(crate) mod tests;
