//! The energy density of the volumetric knit's material (the knitwear paper Eq. 7 per unit rest volume)
//! and its first and second derivatives with respect to the deformation gradient:
//!
//! ```text
//! ψ(F) = γˢ ‖F − R(F)‖²_F + γᵛ ‖F − V(F)‖²_F        (Pa = J/m³; γˢ, γᵛ in Pa, F dimensionless)
//! ```
//!
//! with `R` the closest rotation ([`crate::polar_decomposition`]) and `V` the closest volume-preserving
//! matrix ([`crate::closest_volume_preserving`]); the paper's Eq. 7 has no factor ½ and neither has
//! this. With the rotation-variant SVD `F = U diag(σ) Wᵀ` both terms are functions of the signed
//! singular values alone — `‖F − R‖² = Σ (σ_i − 1)²` and `‖F − V‖² = Σ (σ_i − s_i(σ))²` — so `ψ` is
//! isotropic and its derivatives follow from those of `ψ̂(σ)`.
//!
//! **Gradient (envelope theorem).** For the squared distance `d(F) = ‖F − P(F)‖²` to a set `M`, where
//! the projection `P` is unique and differentiable, `∂d/∂F = 2 (F − P) : (I − DP) = 2 (F − P)`, because
//! `DP` maps into the tangent space of `M` at `P` and `F − P` is normal to it (the first-order condition
//! of the projection). In `σ`: `∂ψ̂/∂σ_i = 2γˢ(σ_i − 1) + 2γᵛ(σ_i − s_i)`, the `∂s/∂σ` term vanishing
//! because `σ − s = −μ ∇(Π s)` is normal to the constraint and `ds` is tangent to it (a clamped `s_i`
//! has `ds_i = 0`, so the clamping keeps this). Hence `P = ∂ψ/∂F = 2γˢ(F − R) + 2γᵛ(F − V)`. It fails
//! on the cut locus, where the projection is not unique: for `R` when `σ_i + σ_j = 0` (an element
//! flattened or inverted so that two signed singular values cancel, e.g. `F = diag(1, 1, −1)` has a
//! circle of closest rotations), for `V` there and where two KKT points of Eq. 26 tie (`σ₁ = σ₂` with
//! the minimizer breaking the symmetry, e.g. `σ = (100, 100, 1)`); `ψ` is continuous but has a kink
//! there.
//!
//! **Hessian.** For an isotropic `ψ` the Hessian in the rotated frame `dF̂ = Uᵀ dF W` is block diagonal
//! (differentiate `P = U diag(ψ̂') Wᵀ` with `dU = U Ω_U`, `dW = W Ω_W`): the diagonal entries `dF̂_ii`
//! couple through `∂²ψ̂/∂σ_i∂σ_j = 2γˢ δ_ij + 2γᵛ (δ_ij − ∂s_i/∂σ_j)` (with `∂s/∂σ` from the implicit
//! differentiation of the KKT system, [`crate::closest_volume_preserving`]), and each pair `i < j`
//! has two modes, the symmetric `(E_ij + E_ji)/√2` with eigenvalue
//! `(ψ̂_i − ψ̂_j)/(σ_i − σ_j) = 2γˢ + 2γᵛ (1 − (s_i − s_j)/(σ_i − σ_j))` (its limit
//! `2γˢ + 2γᵛ (1 − ∂s_i/∂σ_i + ∂s_i/∂σ_j)` when `σ_i ≈ σ_j`) and the antisymmetric `(E_ij − E_ji)/√2`
//! with eigenvalue `(ψ̂_i + ψ̂_j)/(σ_i + σ_j) = 2γˢ (1 − 2/(σ_i + σ_j)) + 2γᵛ (1 − (s_i + s_j)/(σ_i + σ_j))`.
//! This is the derivative of `R` through the SVD (`DR` is `2/(σ_i + σ_j)` on the antisymmetric modes and
//! zero elsewhere, so `∂²‖F − R‖² = 2 (I − DR)`) and of `V` through the KKT system, in one formula. It
//! is exact wherever the projections are differentiable; at the cut locus the `σ_i + σ_j` denominator
//! is floored at [`CUT_LOCUS_FLOOR`] (huge but finite entries, never NaN). The positive semi-definite
//! form for Newton is the analytic filtered one: the same blocks with negative eigenvalues set to zero
//! (the 3 × 3 block by its eigendecomposition) — it equals the exact Hessian exactly when that is PSD,
//! since the blocks are orthogonal.

use nalgebra::{Matrix3, SMatrix, SymmetricEigen, Vector3};

use crate::closest_volume_preserving::{
    VolumePreservingError, VolumePreservingParams, volume_preserving_stretches,
};
use crate::polar_decomposition::polar_decomposition;

/// The smallest `σ_i + σ_j` divided by in the antisymmetric eigenvalue (dimensionless): the cut locus
/// of the projections (see the module doc).
pub const CUT_LOCUS_FLOOR: f64 = 1e-12;

/// Below this `|σ_i − σ_j|` (relative to `max(1, |σ|∞)`) the symmetric eigenvalue is evaluated by its
/// limit instead of the difference quotient.
const EQUAL_SINGULAR_VALUES: f64 = 1e-6;

/// Which second derivative to compute.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MaterialHessian {
    /// None: value and gradient only.
    Skip,
    /// The exact Hessian (where it exists; see the module doc).
    Exact,
    /// The positive semi-definite filtered Hessian, for Newton.
    Projected,
}

/// `ψ` and its derivatives at one deformation gradient. Matrices over `F` act on `vec(F)`, column-major
/// (`F_ab` at `a + 3b`).
#[derive(Clone, Debug, PartialEq)]
pub struct DensityEvaluation {
    /// `ψ = γˢ a + γᵛ b` (Pa = J/m³).
    pub value: f64,
    /// `a = ‖F − R(F)‖²_F` (dimensionless): `∂ψ/∂γˢ`.
    pub shape: f64,
    /// `b = ‖F − V(F)‖²_F` (dimensionless): `∂ψ/∂γᵛ`.
    pub volume: f64,
    /// `∂a/∂F = 2 (F − R)` (dimensionless).
    pub shape_stress: Matrix3<f64>,
    /// `∂b/∂F = 2 (F − V)` (dimensionless).
    pub volume_stress: Matrix3<f64>,
    /// The first Piola–Kirchhoff stress `∂ψ/∂F = γˢ ∂a/∂F + γᵛ ∂b/∂F` (Pa).
    pub stress: Matrix3<f64>,
    /// `∂²ψ/∂F²`, 9 × 9 (Pa), exact or projected as asked; `None` for [`MaterialHessian::Skip`].
    pub hessian: Option<SMatrix<f64, 9, 9>>,
}

/// `ψ(F)` for `gamma = [γˢ, γᵛ]` (Pa) and its derivatives (see the module doc).
pub fn knit_density(
    f: &Matrix3<f64>,
    gamma: [f64; 2],
    hessian: MaterialHessian,
    params: &VolumePreservingParams,
) -> Result<DensityEvaluation, VolumePreservingError> {
    params.validate()?;
    if let Some(&value) = f.iter().find(|v| !v.is_finite()) {
        return Err(VolumePreservingError::NonFinite { value });
    }
    let polar = polar_decomposition(f);
    let sigma = polar.sigma;
    let sol = volume_preserving_stretches(&sigma, params);
    let s = sol.stretches;
    let (u, w) = (polar.u, polar.w);
    let v = u * Matrix3::from_diagonal(&s) * w.transpose();
    let [gs, gv] = gamma;
    let shape = (sigma - Vector3::repeat(1.0)).norm_squared();
    let volume = (sigma - s).norm_squared();
    let shape_stress = 2.0 * (f - polar.rotation);
    let volume_stress = 2.0 * (f - v);
    let stress = gs * shape_stress + gv * volume_stress;
    let hessian = match hessian {
        MaterialHessian::Skip => None,
        form => {
            let jac = sol.jacobian();
            let blocks = rotated_blocks(&sigma, &s, &jac, gamma);
            let blocks = if form == MaterialHessian::Projected {
                blocks.projected()
            } else {
                blocks
            };
            Some(blocks.in_world(&u, &w))
        }
    };
    Ok(DensityEvaluation {
        value: gs * shape + gv * volume,
        shape,
        volume,
        shape_stress,
        volume_stress,
        stress,
        hessian,
    })
}

/// The Hessian of `ψ` in the frame `dF̂ = Uᵀ dF W`: the 3 × 3 block of the diagonal entries and the
/// symmetric and antisymmetric eigenvalues of the pairs (0,1), (0,2), (1,2).
#[derive(Clone, Copy, Debug)]
struct RotatedBlocks {
    diagonal: Matrix3<f64>,
    symmetric: [f64; 3],
    antisymmetric: [f64; 3],
}

const PAIRS: [(usize, usize); 3] = [(0, 1), (0, 2), (1, 2)];

fn rotated_blocks(
    sigma: &Vector3<f64>,
    s: &Vector3<f64>,
    jac: &Matrix3<f64>,
    [gs, gv]: [f64; 2],
) -> RotatedBlocks {
    let diagonal = Matrix3::identity() * (2.0 * gs + 2.0 * gv) - jac * (2.0 * gv);
    // Symmetrize (∂s/∂σ is symmetric up to round-off).
    let diagonal = 0.5 * (diagonal + diagonal.transpose());
    let scale = sigma.amax().max(1.0);
    let mut symmetric = [0.0; 3];
    let mut antisymmetric = [0.0; 3];
    for (k, &(i, j)) in PAIRS.iter().enumerate() {
        let gap = sigma[i] - sigma[j];
        let quotient = if gap.abs() > EQUAL_SINGULAR_VALUES * scale {
            (s[i] - s[j]) / gap
        } else {
            0.5 * (jac[(i, i)] - jac[(i, j)] + jac[(j, j)] - jac[(j, i)])
        };
        symmetric[k] = 2.0 * gs + 2.0 * gv * (1.0 - quotient);
        let sum = (sigma[i] + sigma[j]).max(CUT_LOCUS_FLOOR);
        antisymmetric[k] = 2.0 * gs * (1.0 - 2.0 / sum) + 2.0 * gv * (1.0 - (s[i] + s[j]) / sum);
    }
    RotatedBlocks {
        diagonal,
        symmetric,
        antisymmetric,
    }
}

impl RotatedBlocks {
    /// Negative eigenvalues set to zero.
    fn projected(&self) -> Self {
        let eig = SymmetricEigen::new(self.diagonal);
        let clamped = eig.eigenvalues.map(|l| l.max(0.0));
        let diagonal =
            eig.eigenvectors * Matrix3::from_diagonal(&clamped) * eig.eigenvectors.transpose();
        Self {
            diagonal,
            symmetric: self.symmetric.map(|l| l.max(0.0)),
            antisymmetric: self.antisymmetric.map(|l| l.max(0.0)),
        }
    }

    /// The 9 × 9 Hessian over `vec(F)` (column-major): `Tᵀ Ĥ T` with `T = Wᵀ ⊗ Uᵀ`.
    fn in_world(&self, u: &Matrix3<f64>, w: &Matrix3<f64>) -> SMatrix<f64, 9, 9> {
        let idx = |a: usize, b: usize| a + 3 * b;
        let mut hat = SMatrix::<f64, 9, 9>::zeros();
        for i in 0..3 {
            for j in 0..3 {
                hat[(idx(i, i), idx(j, j))] = self.diagonal[(i, j)];
            }
        }
        for (k, &(i, j)) in PAIRS.iter().enumerate() {
            // On (F̂_ij, F̂_ji): ½ [[λs + λa, λs − λa], [λs − λa, λs + λa]].
            let (ls, la) = (self.symmetric[k], self.antisymmetric[k]);
            let (d, o) = (0.5 * (ls + la), 0.5 * (ls - la));
            let (p, q) = (idx(i, j), idx(j, i));
            hat[(p, p)] = d;
            hat[(q, q)] = d;
            hat[(p, q)] = o;
            hat[(q, p)] = o;
        }
        // T[(a,b), (c,d)] = W[d,b] U[c,a].
        let t = SMatrix::<f64, 9, 9>::from_fn(|r, c| {
            let (a, b) = (r % 3, r / 3);
            let (cc, d) = (c % 3, c / 3);
            w[(d, b)] * u[(cc, a)]
        });
        let h = t.transpose() * hat * t;
        0.5 * (h + h.transpose())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::knit_material::test_states::{regimes, rng};
    use skintight_geometry::finite_difference::{FdParams, check_gradient, check_jacobian};

    #[test]
    fn stress_and_hessian_over_f_match_central_differences() {
        let gamma = [700.0, 2500.0];
        let p = VolumePreservingParams::default();
        let fd = FdParams {
            step: 1e-6,
            rel_tol: 2e-6,
            abs_tol: 1e-9,
        };
        let at = |v: &[f64], form| {
            knit_density(&Matrix3::from_column_slice(v), gamma, form, &p).unwrap()
        };
        let mut rng = rng(31);
        for _ in 0..10 {
            for (name, f) in regimes(&mut rng) {
                let v = f.as_slice().to_vec();
                let ev = at(&v, MaterialHessian::Exact);
                check_gradient(
                    |y| at(y, MaterialHessian::Skip).value,
                    &v,
                    ev.stress.as_slice(),
                    &fd,
                )
                .unwrap_or_else(|e| panic!("{name}: P {e}"));
                // The parts: ∂a/∂F = 2(F − R), ∂b/∂F = 2(F − V) (the envelope theorem).
                check_gradient(
                    |y| at(y, MaterialHessian::Skip).shape,
                    &v,
                    ev.shape_stress.as_slice(),
                    &fd,
                )
                .unwrap_or_else(|e| panic!("{name}: 2(F − R) {e}"));
                check_gradient(
                    |y| at(y, MaterialHessian::Skip).volume,
                    &v,
                    ev.volume_stress.as_slice(),
                    &fd,
                )
                .unwrap_or_else(|e| panic!("{name}: 2(F − V) {e}"));
                let h = ev.hessian.unwrap();
                let flat: Vec<f64> = (0..9)
                    .flat_map(|r| (0..9).map(move |c| (r, c)))
                    .map(|(r, c)| h[(r, c)])
                    .collect();
                let stress = |y: &[f64]| at(y, MaterialHessian::Skip).stress.as_slice().to_vec();
                check_jacobian(stress, &v, &flat, &fd)
                    .unwrap_or_else(|e| panic!("{name}: ∂P/∂F {e}"));
            }
        }
    }
}
