//! Compressible Neo-Hookean energy of the body's linear tetrahedra (thesis Eq. 134–136).
//!
//! Per element, with deformation gradient `F` (3 × 3, dimensionless), `J = det F`, `I₁ = tr(FᵀF)`:
//!
//! ```text
//!   ψ(F) = μ/2 (Ī₁ − 3) + λ/2 (J − 1)²,   Ī₁ = J^(−2/3) I₁          (Eq. 134, J/m³ = Pa)
//!   U_e  = V ψ(F)                                                   (Eq. 135, J; V = rest volume, m³)
//!   U    = Σ_e U_e                                                  (Eq. 136)
//! ```
//!
//! **Inverted elements.** `J^(−2/3)` is undefined for `J ≤ 0`. The energy of such a state is reported as
//! `+∞` (never NaN), so a Newton line search rejects the step by its value; the gradient and Hessian do not
//! exist there and return [`BodyStateError::InvertedElement`] naming the element.
//!
//! **Derivatives** (closed form). With `G = ∂J/∂F = cof F = J F⁻ᵀ`, `f = vec F`, `g = vec G` (column-major):
//!
//! ```text
//!   P = ∂ψ/∂F = μ J^(−2/3) F − (μ/3) I₁ J^(−5/3) G + λ (J − 1) G
//!   ∂²ψ/∂f² = μ J^(−2/3) 𝟙₉ − (2μ/3) J^(−5/3) (f gᵀ + g fᵀ) + ((5μ/9) I₁ J^(−8/3) + λ) g gᵀ
//!             + (λ (J − 1) − (μ/3) I₁ J^(−5/3)) ∂²J/∂f²
//! ```
//!
//! where `∂²J/∂f²` is made of the cross-product matrices of F's columns. The deformation gradient of a
//! linear tet is `F = Σ_a x_a c_aᵀ` with constant `c_a` (rows of `Dm⁻¹`, `c₀ = −c₁ − c₂ − c₃`), so
//! `∂U_e/∂x_a = V P c_a` and `∂²U_e/∂x_a∂x_b = V Σ_{j,n} c_{a,j} c_{b,n} ∂²ψ/∂F_{·j}∂F_{·n}`.
//!
//! **PSD projection.** With `B = ∂f/∂x` (9 × 12, rank 9) the element Hessian is `V Bᵀ (∂²ψ/∂f²) B`; since
//! `B` is onto, it is positive semi-definite exactly when the 9 × 9 `∂²ψ/∂f²` is. The projection clamps the
//! negative eigenvalues of that 9 × 9 matrix to zero, so an element Hessian that already was PSD is left
//! unchanged (up to rounding) and every projected one is PSD.
//!
//! **Small strains.** For `F = I + ∇u`, `ε = sym ∇u`, the density tends to
//! `μ |dev ε|² + λ/2 (tr ε)²` — linear elasticity with shear modulus μ but bulk modulus λ (not
//! `λ + 2μ/3`). See [`NeoHookeanMaterial`] for the two ways to set λ from Young's modulus and Poisson's
//! ratio.

use crate::math::{Mat3, Real, Vec3};
use crate::node_block_assembly::{Node, NodeBlockAssembler, NodeBlockRecorder, NodeHessianSink};
use nalgebra::{SMatrix, SVector};
use thiserror::Error;

/// 9 × 9 matrix: a derivative with respect to `vec F` (column-major).
pub type Mat9 = SMatrix<Real, 9, 9>;
/// 12 × 12 matrix: an element Hessian over the four corner positions (`3a + i` = coordinate i of corner a).
pub type Mat12 = SMatrix<Real, 12, 12>;
/// 12-vector: an element gradient over the four corner positions.
pub type Vec12 = SVector<Real, 12>;

/// Errors of building a Neo-Hookean body.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum NeoHookeanError {
    /// A material parameter is out of its physical range.
    #[error("material parameter {field} = {value} is invalid: {reason}")]
    Material {
        /// The parameter's name.
        field: &'static str,
        /// Its value.
        value: Real,
        /// What is required.
        reason: &'static str,
    },
    /// The fixed-vertex mask does not have one entry per vertex.
    #[error("the fixed-vertex mask has {got} entries but the mesh has {expected} vertices")]
    FixedMaskLength {
        /// Length of the mask.
        got: usize,
        /// Number of rest positions.
        expected: usize,
    },
    /// A rest position is NaN or infinite.
    #[error("rest position of vertex {vertex} is not finite: {position:?}")]
    NonFiniteRestPosition {
        /// The vertex.
        vertex: usize,
        /// Its position (m).
        position: [Real; 3],
    },
    /// A tetrahedron names a vertex that does not exist, or one vertex twice.
    #[error(
        "tetrahedron {tet} has corner {corner} = vertex {vertex}, {problem} (the mesh has {num_vertices} vertices)"
    )]
    BadTetVertex {
        /// The tetrahedron.
        tet: usize,
        /// Its corner (0–3).
        corner: usize,
        /// The vertex index given.
        vertex: usize,
        /// "which is out of range" or "which repeats an earlier corner".
        problem: &'static str,
        /// Number of vertices.
        num_vertices: usize,
    },
    /// A rest tetrahedron is flat or inverted. Corners must be ordered so that
    /// `det[x₁ − x₀, x₂ − x₀, x₃ − x₀] > 0`; swap two corners to flip one.
    #[error(
        "rest tetrahedron {tet} is {kind}: signed volume {volume:e} m³ (relative {relative:e}); corners must \
         satisfy det[x1−x0, x2−x0, x3−x0] > 0"
    )]
    BadRestTet {
        /// The tetrahedron.
        tet: usize,
        /// "inverted" or "degenerate (flat)".
        kind: &'static str,
        /// Signed rest volume (m³).
        volume: Real,
        /// Volume divided by the cube of the longest edge over 6 (dimensionless).
        relative: Real,
    },
}

/// Lamé parameters of the Neo-Hookean density (Eq. 134), in Pa.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NeoHookeanMaterial {
    /// Shear modulus μ (Pa).
    pub mu: Real,
    /// Volumetric parameter λ of the `(J − 1)²` term (Pa).
    pub lambda: Real,
}

fn check_young_poisson(youngs_modulus: Real, poisson_ratio: Real) -> Result<(), NeoHookeanError> {
    if !(youngs_modulus.is_finite() && youngs_modulus > 0.0) {
        return Err(NeoHookeanError::Material {
            field: "youngs_modulus",
            value: youngs_modulus,
            reason: "Young's modulus must be a positive finite number of pascals",
        });
    }
    if !(poisson_ratio.is_finite() && poisson_ratio > -1.0 && poisson_ratio < 0.5) {
        return Err(NeoHookeanError::Material {
            field: "poisson_ratio",
            value: poisson_ratio,
            reason: "Poisson's ratio must lie in (−1, 0.5)",
        });
    }
    Ok(())
}

impl NeoHookeanMaterial {
    /// The thesis' convention: the standard Lamé parameters of Young's modulus `E` (Pa) and Poisson's ratio
    /// `ν`, `μ = E / (2 (1 + ν))`, `λ = E ν / ((1 + ν)(1 − 2ν))`. The small-strain limit then has shear
    /// modulus μ (as linear elasticity) but bulk modulus λ instead of `λ + 2μ/3`; for the body's
    /// `ν = 0.49` this changes the effective Young's modulus by 0.01 % and ν to 0.4899 (see
    /// [`Self::small_strain_young_poisson`]).
    pub fn from_young_poisson(
        youngs_modulus: Real,
        poisson_ratio: Real,
    ) -> Result<Self, NeoHookeanError> {
        check_young_poisson(youngs_modulus, poisson_ratio)?;
        let (e, nu) = (youngs_modulus, poisson_ratio);
        Ok(Self {
            mu: e / (2.0 * (1.0 + nu)),
            lambda: e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)),
        })
    }

    /// λ chosen as the bulk modulus `K = E / (3 (1 − 2ν))`, so that the small-strain limit is exactly linear
    /// elasticity with Young's modulus `E` (Pa) and Poisson's ratio `ν`.
    pub fn matching_linear_elasticity(
        youngs_modulus: Real,
        poisson_ratio: Real,
    ) -> Result<Self, NeoHookeanError> {
        check_young_poisson(youngs_modulus, poisson_ratio)?;
        let (e, nu) = (youngs_modulus, poisson_ratio);
        Ok(Self {
            mu: e / (2.0 * (1.0 + nu)),
            lambda: e / (3.0 * (1.0 - 2.0 * nu)),
        })
    }

    /// Young's modulus (Pa) and Poisson's ratio of the linear elasticity this material tends to at small
    /// strains (shear modulus μ, bulk modulus λ).
    pub fn small_strain_young_poisson(&self) -> (Real, Real) {
        let (k, mu) = (self.lambda, self.mu);
        (
            9.0 * k * mu / (3.0 * k + mu),
            (3.0 * k - 2.0 * mu) / (2.0 * (3.0 * k + mu)),
        )
    }

    /// Energy density ψ(F) (Pa = J/m³), Eq. 134; `+∞` when `J ≤ 0` or `F` is not finite.
    pub fn density(&self, f: &Mat3) -> Real {
        let j = f.determinant();
        if !(j > 0.0 && j.is_finite()) {
            return Real::INFINITY;
        }
        let i1 = f.norm_squared();
        let psi = 0.5 * self.mu * (j.powf(-2.0 / 3.0) * i1 - 3.0)
            + 0.5 * self.lambda * (j - 1.0) * (j - 1.0);
        if psi.is_finite() { psi } else { Real::INFINITY }
    }

    /// First Piola–Kirchhoff stress `P = ∂ψ/∂F` (3 × 3, Pa); `None` when `J ≤ 0` or not finite.
    pub fn stress(&self, f: &Mat3) -> Option<Mat3> {
        let j = f.determinant();
        if !(j > 0.0 && j.is_finite()) {
            return None;
        }
        let g = cofactor(f);
        let i1 = f.norm_squared();
        let j23 = j.powf(-2.0 / 3.0);
        let j53 = j23 / j;
        let p = f * (self.mu * j23) + g * (self.lambda * (j - 1.0) - self.mu / 3.0 * i1 * j53);
        p.iter().all(|v| v.is_finite()).then_some(p)
    }

    /// `∂²ψ/∂f²` with `f = vec F` column-major (9 × 9, Pa); `None` when `J ≤ 0` or not finite.
    pub fn stress_derivative(&self, f: &Mat3) -> Option<Mat9> {
        let j = f.determinant();
        if !(j > 0.0 && j.is_finite()) {
            return None;
        }
        let (mu, lambda) = (self.mu, self.lambda);
        let gm = cofactor(f);
        let fv = SVector::<Real, 9>::from_column_slice(f.as_slice());
        let gv = SVector::<Real, 9>::from_column_slice(gm.as_slice());
        let i1 = f.norm_squared();
        let j23 = j.powf(-2.0 / 3.0);
        let j53 = j23 / j;
        let j83 = j53 / j;

        let mut k = Mat9::identity() * (mu * j23);
        let fg = fv * gv.transpose();
        k -= (fg + fg.transpose()) * (2.0 * mu / 3.0 * j53);
        k += gv * gv.transpose() * (5.0 * mu / 9.0 * i1 * j83 + lambda);
        // ∂²J/∂f²: block (i, j) = ∂(cofactor column i)/∂(F column j).
        let c = lambda * (j - 1.0) - mu / 3.0 * i1 * j53;
        let cols = [f.column(0), f.column(1), f.column(2)];
        for (bi, bj, col, sign) in [
            (0, 1, 2, -1.0),
            (0, 2, 1, 1.0),
            (1, 0, 2, 1.0),
            (1, 2, 0, -1.0),
            (2, 0, 1, -1.0),
            (2, 1, 0, 1.0),
        ] {
            let v = cols[col];
            let s = sign * c;
            // s · [v]×
            k[(3 * bi + 1, 3 * bj)] += s * v[2];
            k[(3 * bi + 2, 3 * bj)] -= s * v[1];
            k[(3 * bi, 3 * bj + 1)] -= s * v[2];
            k[(3 * bi + 2, 3 * bj + 1)] += s * v[0];
            k[(3 * bi, 3 * bj + 2)] += s * v[1];
            k[(3 * bi + 1, 3 * bj + 2)] -= s * v[0];
        }
        k.iter().all(|v| v.is_finite()).then_some(k)
    }
}

/// Cofactor matrix `cof F = J F⁻ᵀ`, columns `(f₁×f₂, f₂×f₀, f₀×f₁)` for `F = [f₀ f₁ f₂]`.
pub fn cofactor(f: &Mat3) -> Mat3 {
    let (c0, c1, c2) = (f.column(0), f.column(1), f.column(2));
    Mat3::from_columns(&[c1.cross(&c2), c2.cross(&c0), c0.cross(&c1)])
}

/// Projects a symmetric 9 × 9 matrix onto the positive semi-definite cone by clamping negative eigenvalues
/// to 0; a matrix that already is PSD is returned unchanged.
pub fn project_psd(m: &Mat9) -> Mat9 {
    let eig = nalgebra::SymmetricEigen::new(*m);
    if eig.eigenvalues.iter().all(|&l| l >= 0.0) {
        return *m;
    }
    let clamped = eig.eigenvalues.map(|l| l.max(0.0));
    eig.eigenvectors * Mat9::from_diagonal(&clamped) * eig.eigenvectors.transpose()
}

/// Precomputed rest data of one linear tetrahedron.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TetElement {
    /// Rest volume V (m³).
    pub volume: Real,
    /// `c_a` (1/m) for the four corners: `F = Σ_a x_a c_aᵀ`; `c₁..c₃` are the rows of `Dm⁻¹`,
    /// `c₀ = −c₁ − c₂ − c₃`.
    pub shape_gradients: [Vec3; 4],
}

impl TetElement {
    /// Rest data from the four rest corners (m). `Err` carries `(kind, signed volume, relative volume)` when
    /// the tet is inverted or flat (relative volume `6V / ℓ_max³ < 1e-10`).
    pub fn new(rest: &[Vec3; 4]) -> Result<Self, (&'static str, Real, Real)> {
        let dm = Mat3::from_columns(&[rest[1] - rest[0], rest[2] - rest[0], rest[3] - rest[0]]);
        let volume = dm.determinant() / 6.0;
        let mut longest: Real = 0.0;
        for a in 0..4 {
            for b in a + 1..4 {
                longest = longest.max((rest[a] - rest[b]).norm());
            }
        }
        let relative = 6.0 * volume / longest.powi(3);
        if !(relative.abs() >= 1e-10) {
            return Err(("degenerate (flat)", volume, relative));
        }
        if volume < 0.0 {
            return Err(("inverted", volume, relative));
        }
        let inv = dm
            .try_inverse()
            .ok_or(("degenerate (flat)", volume, relative))?;
        let c1 = inv.row(0).transpose();
        let c2 = inv.row(1).transpose();
        let c3 = inv.row(2).transpose();
        Ok(Self {
            volume,
            shape_gradients: [-(c1 + c2 + c3), c1, c2, c3],
        })
    }

    /// Deformation gradient `F` (3 × 3) for deformed corners `x` (m).
    pub fn deformation_gradient(&self, x: &[Vec3; 4]) -> Mat3 {
        let mut f = Mat3::zeros();
        for (xa, ca) in x.iter().zip(&self.shape_gradients) {
            f += xa * ca.transpose();
        }
        f
    }

    /// Element energy `U_e = V ψ(F)` (J), Eq. 135; `+∞` when inverted.
    pub fn energy(&self, material: &NeoHookeanMaterial, x: &[Vec3; 4]) -> Real {
        self.volume * material.density(&self.deformation_gradient(x))
    }

    /// Element gradient `∂U_e/∂x` (12, N; entry `3a + i`) or the inverted `J` as error.
    pub fn gradient(&self, material: &NeoHookeanMaterial, x: &[Vec3; 4]) -> Result<Vec12, Real> {
        let f = self.deformation_gradient(x);
        let p = material.stress(&f).ok_or_else(|| f.determinant())?;
        let mut g = Vec12::zeros();
        for (a, ca) in self.shape_gradients.iter().enumerate() {
            g.fixed_rows_mut::<3>(3 * a)
                .copy_from(&(p * ca * self.volume));
        }
        Ok(g)
    }

    /// Element Hessian `∂²U_e/∂x²` (12 × 12, N/m), optionally projected to PSD, or the inverted `J`.
    pub fn hessian(
        &self,
        material: &NeoHookeanMaterial,
        x: &[Vec3; 4],
        project: bool,
    ) -> Result<Mat12, Real> {
        let f = self.deformation_gradient(x);
        let mut k = material
            .stress_derivative(&f)
            .ok_or_else(|| f.determinant())?;
        if project {
            k = project_psd(&k);
        }
        // M = K B (9 × 12) with B[(l + 3j), (3a + l)] = c_{a,j}: column 3a + m of M is
        // Σ_n c_{a,n} K[:, m + 3n].
        let c = &self.shape_gradients;
        let mut kb = SMatrix::<Real, 9, 12>::zeros();
        for a in 0..4 {
            for m in 0..3 {
                let mut col = SVector::<Real, 9>::zeros();
                for n in 0..3 {
                    col += k.column(m + 3 * n) * c[a][n];
                }
                kb.set_column(3 * a + m, &col);
            }
        }
        // H = V Bᵀ M: row 3a + l is Σ_j c_{a,j} M[l + 3j, :].
        let mut h = Mat12::zeros();
        for a in 0..4 {
            for l in 0..3 {
                let mut row = SMatrix::<Real, 1, 12>::zeros();
                for j in 0..3 {
                    row += kb.row(l + 3 * j) * c[a][j];
                }
                h.set_row(3 * a + l, &(row * self.volume));
            }
        }
        Ok(h)
    }
}

/// Settings of the body energy.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NeoHookeanParams {
    /// Young's modulus E (Pa). Default: the thesis body, 24.78 kPa.
    pub youngs_modulus: Real,
    /// Poisson's ratio ν (dimensionless, in (−1, 0.5)). Default: 0.49.
    pub poisson_ratio: Real,
    /// Lamé convention: `false` (default, the thesis) takes the standard Lamé λ
    /// ([`NeoHookeanMaterial::from_young_poisson`]); `true` takes λ = bulk modulus so the small-strain limit is
    /// linear elasticity with the same E and ν ([`NeoHookeanMaterial::matching_linear_elasticity`]).
    pub match_linear_bulk_modulus: bool,
    /// Project every element Hessian to positive semi-definite (see the module documentation).
    pub project_psd: bool,
}

impl Default for NeoHookeanParams {
    fn default() -> Self {
        Self {
            youngs_modulus: 24.78e3,
            poisson_ratio: 0.49,
            match_linear_bulk_modulus: false,
            project_psd: false,
        }
    }
}

impl NeoHookeanParams {
    /// The material these settings describe.
    pub fn material(&self) -> Result<NeoHookeanMaterial, NeoHookeanError> {
        if self.match_linear_bulk_modulus {
            NeoHookeanMaterial::matching_linear_elasticity(self.youngs_modulus, self.poisson_ratio)
        } else {
            NeoHookeanMaterial::from_young_poisson(self.youngs_modulus, self.poisson_ratio)
        }
    }
}

/// Why the body energy cannot be evaluated at a DOF vector.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum BodyStateError {
    /// The DOF vector or the gradient output has the wrong length.
    #[error("{what} has {got} entries but the body has {expected} degrees of freedom")]
    Length {
        /// Which argument: "DOF vector x" or "gradient output".
        what: &'static str,
        /// Its length.
        got: usize,
        /// The body's number of DOFs.
        expected: usize,
    },
    /// An element is inverted, flat or has non-finite positions at this state (`J = det F ≤ 0` or NaN).
    /// Its energy is +∞ there ([`NeoHookeanBody::value`] returns `Ok(+∞)`), so a line search must reject
    /// the step; gradient and Hessian do not exist and return this error instead.
    #[error(
        "element {element} is inverted, flat or non-finite at this state (J = det F = {det:e}); the energy \
         is +∞ there — reject this step"
    )]
    InvertedElement {
        /// Index of the element (tetrahedron).
        element: usize,
        /// `det F` (dimensionless volume ratio), or NaN.
        det: Real,
    },
}

/// Checks that a DOF vector (or gradient buffer, `what`) has `expected` entries.
fn check_length(x: &[Real], expected: usize, what: &'static str) -> Result<(), BodyStateError> {
    if x.len() == expected {
        Ok(())
    } else {
        Err(BodyStateError::Length {
            what,
            got: x.len(),
            expected,
        })
    }
}

/// The body energy `U_body` (Eq. 136) of a tetrahedral mesh over a flat DOF vector, with its gradient and
/// its Hessian as node blocks (the coupled solve uses its elements directly, see
/// [`crate::ClothOnBody`]).
///
/// **DOF numbering**: only free vertices carry DOFs, 3 per vertex. Free vertices are numbered in increasing
/// vertex order (`k`-th free vertex = k-th vertex with `fixed[v] == false`), and `x[3k + i]` is coordinate
/// `i` (m) of free vertex `k`; `x.len() = 3 · #free`. Fixed vertices stay at their positions in
/// [`Self::fixed_positions`] (the rest positions unless changed with [`Self::set_fixed_positions`]).
/// Value in J, gradient in N, Hessian in N/m.
#[derive(Clone, Debug)]
pub struct NeoHookeanBody {
    material: NeoHookeanMaterial,
    project_psd: bool,
    tets: Vec<[usize; 4]>,
    elements: Vec<TetElement>,
    /// First DOF (3k) of each vertex, `None` for fixed vertices.
    vertex_dof: Vec<Option<usize>>,
    fixed_positions: Vec<Vec3>,
    num_free: usize,
}

impl NeoHookeanBody {
    /// Builds the body from rest positions (`#V`, m), tetrahedra (`#T × 4` vertex indices, positively
    /// oriented: `det[x₁ − x₀, x₂ − x₀, x₃ − x₀] > 0`) and a fixed-vertex mask (`#V`).
    pub fn new(
        rest_positions: &[Vec3],
        tets: &[[usize; 4]],
        fixed: &[bool],
        params: &NeoHookeanParams,
    ) -> Result<Self, NeoHookeanError> {
        let material = params.material()?;
        let nv = rest_positions.len();
        if fixed.len() != nv {
            return Err(NeoHookeanError::FixedMaskLength {
                got: fixed.len(),
                expected: nv,
            });
        }
        if let Some((vertex, p)) = rest_positions
            .iter()
            .enumerate()
            .find(|(_, p)| !p.iter().all(|c| c.is_finite()))
        {
            return Err(NeoHookeanError::NonFiniteRestPosition {
                vertex,
                position: [p.x, p.y, p.z],
            });
        }
        let mut elements = Vec::with_capacity(tets.len());
        for (t, tet) in tets.iter().enumerate() {
            for (corner, &v) in tet.iter().enumerate() {
                let problem = if v >= nv {
                    Some("which is out of range")
                } else if tet[..corner].contains(&v) {
                    Some("which repeats an earlier corner")
                } else {
                    None
                };
                if let Some(problem) = problem {
                    return Err(NeoHookeanError::BadTetVertex {
                        tet: t,
                        corner,
                        vertex: v,
                        problem,
                        num_vertices: nv,
                    });
                }
            }
            let rest = tet.map(|v| rest_positions[v]);
            let element = TetElement::new(&rest).map_err(|(kind, volume, relative)| {
                NeoHookeanError::BadRestTet {
                    tet: t,
                    kind,
                    volume,
                    relative,
                }
            })?;
            elements.push(element);
        }
        let mut num_free = 0;
        let vertex_dof = fixed
            .iter()
            .map(|&is_fixed| {
                (!is_fixed).then(|| {
                    num_free += 1;
                    3 * (num_free - 1)
                })
            })
            .collect();
        Ok(Self {
            material,
            project_psd: params.project_psd,
            tets: tets.to_vec(),
            elements,
            vertex_dof,
            fixed_positions: rest_positions.to_vec(),
            num_free,
        })
    }

    /// The material (Lamé parameters, Pa).
    pub fn material(&self) -> &NeoHookeanMaterial {
        &self.material
    }

    /// Precomputed rest data per tetrahedron.
    pub fn elements(&self) -> &[TetElement] {
        &self.elements
    }

    /// Whether element Hessians are projected to PSD.
    pub fn projects_psd(&self) -> bool {
        self.project_psd
    }

    /// Turns the PSD projection of element Hessians on or off (the Hessian pattern does not change).
    pub fn set_project_psd(&mut self, project: bool) {
        self.project_psd = project;
    }

    /// Number of free vertices (`num_dofs() / 3`).
    pub fn num_free_vertices(&self) -> usize {
        self.num_free
    }

    /// First DOF index (`3k`) of vertex `v`, or `None` if it is fixed or out of range.
    pub fn vertex_dof(&self, v: usize) -> Option<usize> {
        self.vertex_dof.get(v).copied().flatten()
    }

    /// Positions (m, `#V`) used for the fixed vertices (entries of free vertices are ignored).
    pub fn fixed_positions(&self) -> &[Vec3] {
        &self.fixed_positions
    }

    /// Moves the fixed vertices (e.g. a new skeleton pose): takes `#V` positions (m) and keeps those of fixed
    /// vertices. Returns `false` (and changes nothing) if the length is not `#V`.
    pub fn set_fixed_positions(&mut self, positions: &[Vec3]) -> bool {
        if positions.len() != self.fixed_positions.len() {
            return false;
        }
        self.fixed_positions.copy_from_slice(positions);
        true
    }

    /// The DOF vector (m, `3 · #free`) of all-vertex positions `positions` (`#V`).
    pub fn dofs_from_positions(&self, positions: &[Vec3]) -> Vec<Real> {
        let mut x = vec![0.0; 3 * self.num_free];
        for (p, d) in positions.iter().zip(&self.vertex_dof) {
            if let Some(d) = *d {
                x[d..d + 3].copy_from_slice(p.as_slice());
            }
        }
        x
    }

    /// All vertex positions (m, `#V`): free ones from `x`, fixed ones from [`Self::fixed_positions`].
    pub fn positions_from_dofs(&self, x: &[Real]) -> Result<Vec<Vec3>, BodyStateError> {
        check_length(x, self.num_dofs(), "DOF vector x")?;
        Ok((0..self.vertex_dof.len())
            .map(|v| self.position(v, x))
            .collect())
    }

    #[inline]
    fn position(&self, v: usize, x: &[Real]) -> Vec3 {
        match self.vertex_dof[v] {
            Some(d) => Vec3::new(x[d], x[d + 1], x[d + 2]),
            None => self.fixed_positions[v],
        }
    }

    #[inline]
    fn corners(&self, t: usize, x: &[Real]) -> [Vec3; 4] {
        self.tets[t].map(|v| self.position(v, x))
    }
}

impl NeoHookeanBody {
    /// Number of degrees of freedom `n = 3 · #free`: the length of `x` and of the gradient.
    pub fn num_dofs(&self) -> usize {
        3 * self.num_free
    }

    /// `U_body` (J); `+∞` if any element is inverted or any position is not finite (never NaN), so that a
    /// line search rejects the state; `Err` only for a DOF vector of the wrong length.
    pub fn value(&self, x: &[Real]) -> Result<Real, BodyStateError> {
        check_length(x, self.num_dofs(), "DOF vector x")?;
        let mut total = 0.0;
        for (t, element) in self.elements.iter().enumerate() {
            let e = element.energy(&self.material, &self.corners(t, x));
            if e == Real::INFINITY {
                return Ok(Real::INFINITY);
            }
            total += e;
        }
        Ok(total)
    }

    /// Writes (overwrites) the gradient `∂U_body/∂x` (N, length `n`) into `out`.
    pub fn gradient(&self, x: &[Real], out: &mut [Real]) -> Result<(), BodyStateError> {
        check_length(x, self.num_dofs(), "DOF vector x")?;
        check_length(out, self.num_dofs(), "gradient output")?;
        out.fill(0.0);
        for (t, element) in self.elements.iter().enumerate() {
            let g = element
                .gradient(&self.material, &self.corners(t, x))
                .map_err(|det| BodyStateError::InvertedElement { element: t, det })?;
            for (a, &v) in self.tets[t].iter().enumerate() {
                if let Some(d) = self.vertex_dof[v] {
                    for i in 0..3 {
                        out[d + i] += g[3 * a + i];
                    }
                }
            }
        }
        Ok(())
    }

    /// The DOF nodes: one per free vertex (dimension 3, first DOF `3k`), in vertex order.
    pub fn nodes(&self) -> Vec<Node> {
        (0..self.num_free)
            .map(|k| Node {
                first_dof: 3 * k,
                dim: 3,
            })
            .collect()
    }

    /// The node list of every block [`Self::hessian`] hands out (the free corners of each tetrahedron
    /// with at least one), without values: to fit a [`NodeBlockAssembler`]'s pattern first.
    pub fn structure(&self, recorder: &mut NodeBlockRecorder) {
        let mut nodes = Vec::with_capacity(4);
        for tet in &self.tets {
            nodes.clear();
            nodes.extend(
                tet.iter()
                    .filter_map(|&v| self.vertex_dof[v])
                    .map(|d| Node {
                        first_dof: d,
                        dim: 3,
                    }),
            );
            if !nodes.is_empty() {
                recorder.record(&nodes);
            }
        }
    }

    /// Hands the Hessian `∂²U_body/∂x²` (N/m, `n × n`, symmetric) to `sink` as one node block per
    /// tetrahedron over its free corners (in corner order; tetrahedra with four fixed corners give none).
    /// Row-major `3m × 3m` blocks for `m` free corners.
    pub fn hessian(
        &self,
        x: &[Real],
        sink: &mut dyn NodeHessianSink,
    ) -> Result<(), BodyStateError> {
        check_length(x, self.num_dofs(), "DOF vector x")?;
        let mut nodes = Vec::with_capacity(4);
        let mut local = Vec::with_capacity(4);
        let mut block = Vec::with_capacity(144);
        for (t, element) in self.elements.iter().enumerate() {
            let h = element
                .hessian(&self.material, &self.corners(t, x), self.project_psd)
                .map_err(|det| BodyStateError::InvertedElement { element: t, det })?;
            nodes.clear();
            local.clear();
            for (a, &v) in self.tets[t].iter().enumerate() {
                if let Some(d) = self.vertex_dof[v] {
                    nodes.push(Node {
                        first_dof: d,
                        dim: 3,
                    });
                    local.push(a);
                }
            }
            if nodes.is_empty() {
                continue;
            }
            let m = 3 * nodes.len();
            block.clear();
            block.resize(m * m, 0.0);
            for (i, &a) in local.iter().enumerate() {
                for (j, &b) in local.iter().enumerate() {
                    for r in 0..3 {
                        for c in 0..3 {
                            block[(3 * i + r) * m + 3 * j + c] = h[(3 * a + r, 3 * b + c)];
                        }
                    }
                }
            }
            sink.add_node_block(&nodes, &block);
        }
        Ok(())
    }

    /// A [`NodeBlockAssembler`] over the body's nodes with the pattern of [`Self::structure`] (lower
    /// triangle, as the sparse Cholesky reads it); fill it with [`Self::assemble_hessian`].
    pub fn hessian_assembler(&self) -> NodeBlockAssembler {
        let mut recorder = NodeBlockRecorder::default();
        self.structure(&mut recorder);
        NodeBlockAssembler::new(self.num_dofs(), &self.nodes(), &recorder)
    }

    /// Assembles the Hessian at `x` into `assembler` (from [`Self::hessian_assembler`]), overwriting its
    /// values.
    pub fn assemble_hessian(
        &self,
        x: &[Real],
        assembler: &mut NodeBlockAssembler,
    ) -> Result<(), BodyStateError> {
        assembler.begin();
        self.hessian(x, assembler)?;
        assembler
            .finish()
            .expect("the body's blocks are those of its structure");
        Ok(())
    }
}

#[cfg(test)]
mod tests;
