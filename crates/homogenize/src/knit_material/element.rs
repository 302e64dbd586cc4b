//! One linear tetrahedron of the volumetric knit: `E_e = V_e ψ(F_e)` (the knitwear paper Eq. 7; `V_e`
//! the rest volume in m³, `ψ` the density of [`super::density`] in Pa, `E_e` in J) with
//! `F = D_s D_m⁻¹`, `D_s = [x₁ − x₀, x₂ − x₀, x₃ − x₀]` (deformed edges, m) and `D_m` the rest edges.
//!
//! `F` is linear in the 12 nodal coordinates (node `k`, axis `c` at `3k + c`): `vec(dF) = B dx` with
//! `∂F_ab/∂x_kc = δ_ac (D_m⁻¹)_{k−1,b}` for `k ≥ 1` and `−δ_ac Σ_j (D_m⁻¹)_jb` for `k = 0`. So
//! `∂E/∂x = V_e Bᵀ vec(P)` (N), `∂²E/∂x² = V_e Bᵀ (∂²ψ/∂F²) B` (N/m), and — `E` being linear in `γ` —
//! `∂E/∂γˢ = V_e ‖F − R‖²` (m³), `∂E/∂γᵛ = V_e ‖F − V‖²`, and the mixed derivatives
//! `∂²E/∂x∂γˢ = V_e Bᵀ vec(2(F − R))`, `∂²E/∂x∂γᵛ = V_e Bᵀ vec(2(F − V))` (m², N per Pa), what the
//! adjoint fit of Eq. 15–21 needs. `B` has rank 9 for a non-degenerate rest tet (its null space is the
//! translations), so `Bᵀ H B` is PSD exactly when `H` is: the projected element Hessian equals the
//! exact one wherever that is PSD.

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

use super::density::{DensityEvaluation, MaterialHessian, knit_density};
use crate::closest_volume_preserving::{VolumePreservingError, VolumePreservingParams};

/// The rest shape of one tetrahedron: `D_m⁻¹` and the rest volume.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RestTet {
    /// `D_m⁻¹` (1/m).
    pub dm_inverse: Matrix3<f64>,
    /// The rest volume `V_e = det D_m / 6` (m³), positive.
    pub volume: f64,
}

/// Why a rest tetrahedron cannot be used.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error(
    "rest tetrahedron with signed volume {volume} m³ (relative {relative}): it must be positively oriented and not flat; fix the mesh's node order or positions"
)]
pub struct RestTetError {
    /// Its signed volume (m³).
    pub volume: f64,
    /// `6 V / (mean edge length)³`, dimensionless.
    pub relative: f64,
}

impl RestTet {
    /// From the four rest positions (m); positively oriented, with volume above `10⁻¹²` of its edge
    /// length cubed.
    pub fn new(rest: &[[f64; 3]; 4]) -> Result<Self, RestTetError> {
        let p = rest.map(|r| Vector3::new(r[0], r[1], r[2]));
        let dm = Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]);
        let det = dm.determinant();
        let mut edges = 0.0;
        for i in 0..4 {
            for j in i + 1..4 {
                edges += (p[i] - p[j]).norm() / 6.0;
            }
        }
        let relative = det / edges.powi(3);
        let volume = det / 6.0;
        if relative.is_nan() || relative <= 1e-12 || !det.is_finite() {
            return Err(RestTetError { volume, relative });
        }
        let dm_inverse = dm.try_inverse().ok_or(RestTetError { volume, relative })?;
        Ok(Self { dm_inverse, volume })
    }

    /// `F = D_s D_m⁻¹` at deformed positions `x` (m).
    pub fn deformation_gradient(&self, x: &[[f64; 3]; 4]) -> Matrix3<f64> {
        let p = x.map(|r| Vector3::new(r[0], r[1], r[2]));
        Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]) * self.dm_inverse
    }

    /// The corner gradients `g_a` (1/m) of the barycentric functions: `g_{1,2,3}` are the rows of `D_m⁻¹`
    /// and `g₀ = −(g₁ + g₂ + g₃)`, so that `F = Σ_a x_a ⊗ g_a`.
    pub fn corner_gradients(&self) -> [Vector3<f64>; 4] {
        let g: [Vector3<f64>; 3] = std::array::from_fn(|k| self.dm_inverse.row(k).transpose());
        [-(g[0] + g[1] + g[2]), g[0], g[1], g[2]]
    }

    /// `B = ∂vec(F)/∂x`, 9 × 12 (1/m).
    pub fn gradient_map(&self) -> SMatrix<f64, 9, 12> {
        let d = &self.dm_inverse;
        let mut b = SMatrix::<f64, 9, 12>::zeros();
        for col in 0..3 {
            let first = -(d[(0, col)] + d[(1, col)] + d[(2, col)]);
            for a in 0..3 {
                let row = a + 3 * col;
                b[(row, a)] = first;
                for k in 1..4 {
                    b[(row, 3 * k + a)] = d[(k - 1, col)];
                }
            }
        }
        b
    }
}

/// `E_e` and its derivatives at one state.
#[derive(Clone, Debug, PartialEq)]
pub struct ElementEvaluation {
    /// `E_e = V_e ψ(F)` (J).
    pub energy: f64,
    /// `∂E_e/∂x`, 12 (N).
    pub gradient: SVector<f64, 12>,
    /// `∂²E_e/∂x²`, 12 × 12 (N/m), exact or projected as asked.
    pub hessian: Option<SMatrix<f64, 12, 12>>,
    /// `[∂E_e/∂γˢ, ∂E_e/∂γᵛ]` (m³ = J/Pa).
    pub energy_per_gamma: [f64; 2],
    /// `[∂²E_e/∂x∂γˢ, ∂²E_e/∂x∂γᵛ]`, 12 each (m² = N/Pa).
    pub gradient_per_gamma: [SVector<f64, 12>; 2],
    /// The density evaluation behind it (at `F`).
    pub density: DensityEvaluation,
}

/// `E_e` at deformed positions `x` (m) for `gamma = [γˢ, γᵛ]` (Pa).
pub fn knit_element(
    rest: &RestTet,
    x: &[[f64; 3]; 4],
    gamma: [f64; 2],
    hessian: MaterialHessian,
    params: &VolumePreservingParams,
) -> Result<ElementEvaluation, VolumePreservingError> {
    let f = rest.deformation_gradient(x);
    let density = knit_density(&f, gamma, hessian, params)?;
    let b = rest.gradient_map();
    let vol = rest.volume;
    let vec = |m: &Matrix3<f64>| SVector::<f64, 9>::from_column_slice(m.as_slice());
    let bt = b.transpose();
    let gradient = bt * vec(&density.stress) * vol;
    let gradient_per_gamma = [
        bt * vec(&density.shape_stress) * vol,
        bt * vec(&density.volume_stress) * vol,
    ];
    let hessian = density.hessian.map(|h| {
        let m = bt * h * b * vol;
        0.5 * (m + m.transpose())
    });
    Ok(ElementEvaluation {
        energy: vol * density.value,
        gradient,
        hessian,
        energy_per_gamma: [vol * density.shape, vol * density.volume],
        gradient_per_gamma,
        density,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::knit_material::test_states::{regimes, rest_tet, rng};
    use nalgebra::{DMatrix, SymmetricEigen};
    use rand::Rng;
    use skintight_geometry::finite_difference::{FdParams, check_gradient, check_jacobian};

    const GAMMA: [f64; 2] = [1.3e3, 4.1e3];

    fn corners(x: &[f64]) -> [[f64; 3]; 4] {
        [0, 1, 2, 3].map(|k| [x[3 * k], x[3 * k + 1], x[3 * k + 2]])
    }

    /// The 12 coordinates of `F X + c` for a rest tet `X`.
    fn deformed(
        rest: &[[f64; 3]; 4],
        f: &Matrix3<f64>,
        rng: &mut rand_chacha::ChaCha8Rng,
    ) -> Vec<f64> {
        let c = Vector3::from_fn(|_, _| rng.random_range(-0.5..0.5));
        rest.iter()
            .flat_map(|p| {
                let y = f * Vector3::from(*p) + c;
                [y[0], y[1], y[2]]
            })
            .collect()
    }

    fn eval(rest: &RestTet, x: &[f64], form: MaterialHessian) -> ElementEvaluation {
        knit_element(
            rest,
            &corners(x),
            GAMMA,
            form,
            &VolumePreservingParams::default(),
        )
        .unwrap()
    }

    fn row_major(h: &SMatrix<f64, 12, 12>) -> Vec<f64> {
        (0..12)
            .flat_map(|r| (0..12).map(move |c| h[(r, c)]))
            .collect()
    }

    fn fd() -> FdParams {
        FdParams {
            step: 1e-6,
            rel_tol: 2e-6,
            abs_tol: 1e-9,
        }
    }

    #[test]
    fn gradient_and_hessian_match_central_differences_in_every_regime() {
        let mut rng = rng(21);
        let fd = fd();
        for trial in 0..12 {
            for (name, f) in regimes(&mut rng) {
                let rest_x = rest_tet(&mut rng);
                let rest = RestTet::new(&rest_x).unwrap();
                let x = deformed(&rest_x, &f, &mut rng);
                let ev = eval(&rest, &x, MaterialHessian::Exact);
                let energy = |y: &[f64]| eval(&rest, y, MaterialHessian::Skip).energy;
                let gradient = |y: &[f64]| {
                    eval(&rest, y, MaterialHessian::Skip)
                        .gradient
                        .as_slice()
                        .to_vec()
                };
                if let Err(e) = check_gradient(energy, &x, ev.gradient.as_slice(), &fd) {
                    panic!("trial {trial}, {name}: gradient {e}");
                }
                let h = row_major(&ev.hessian.unwrap());
                if let Err(e) = check_jacobian(gradient, &x, &h, &fd) {
                    panic!("trial {trial}, {name}: Hessian {e}");
                }
                // Each check can fail: a slightly wrong gradient or Hessian is caught.
                if trial == 0 {
                    let mut g = ev.gradient;
                    let k = g.iamax();
                    g[k] *= 1.0 + 1e-4;
                    assert!(
                        check_gradient(energy, &x, g.as_slice(), &fd).is_err(),
                        "{name}"
                    );
                    let mut wrong = h.clone();
                    let k = (0..wrong.len())
                        .max_by(|&a, &b| wrong[a].abs().total_cmp(&wrong[b].abs()))
                        .unwrap();
                    wrong[k] *= 1.0 + 1e-4;
                    assert!(check_jacobian(gradient, &x, &wrong, &fd).is_err(), "{name}");
                }
            }
        }
    }

    #[test]
    fn clamping_transitions_are_smooth_to_first_order() {
        // σ = (c·90, c·40, 1): the floor of Eq. 26 holds s₃ for c above a threshold c*. Locate c* by
        // bisection; just off it on either side the Hessian matches central differences (the active
        // set is constant within the step), and straddling it the gradient does (E is C¹ there).
        let params = VolumePreservingParams::default();
        let clamped = |c: f64| {
            crate::closest_volume_preserving::volume_preserving_stretches(
                &Vector3::new(90.0 * c, 40.0 * c, 1.0),
                &params,
            )
            .clamped[2]
        };
        let (mut lo, mut hi) = (0.01, 2.0);
        assert!(
            !clamped(lo) && clamped(hi),
            "the transition lies in the bracket"
        );
        for _ in 0..80 {
            let mid = 0.5 * (lo + hi);
            if clamped(mid) { hi = mid } else { lo = mid }
        }
        let c_star = 0.5 * (lo + hi);
        let mut rng = rng(22);
        let fd = fd();
        for (offset, hessian_too) in [(-1e-3, true), (1e-3, true), (-1e-9, false), (1e-9, false)] {
            let c = c_star * (1.0 + offset);
            let f = crate::knit_material::test_states::with_singular_values(
                Vector3::new(90.0 * c, 40.0 * c, 1.0),
                &mut rng,
            );
            let rest_x = rest_tet(&mut rng);
            let rest = RestTet::new(&rest_x).unwrap();
            let x = deformed(&rest_x, &f, &mut rng);
            let ev = eval(&rest, &x, MaterialHessian::Exact);
            let energy = |y: &[f64]| eval(&rest, y, MaterialHessian::Skip).energy;
            check_gradient(energy, &x, ev.gradient.as_slice(), &fd)
                .unwrap_or_else(|e| panic!("offset {offset}: gradient {e}"));
            if hessian_too {
                let gradient = |y: &[f64]| {
                    eval(&rest, y, MaterialHessian::Skip)
                        .gradient
                        .as_slice()
                        .to_vec()
                };
                check_jacobian(gradient, &x, &row_major(&ev.hessian.unwrap()), &fd)
                    .unwrap_or_else(|e| panic!("offset {offset}: Hessian {e}"));
            }
        }
    }

    #[test]
    fn gamma_derivatives_match_differences_in_gamma() {
        let mut rng = rng(23);
        let p = VolumePreservingParams::default();
        let fd = fd();
        for (name, f) in regimes(&mut rng) {
            let rest_x = rest_tet(&mut rng);
            let rest = RestTet::new(&rest_x).unwrap();
            let x = corners(&deformed(&rest_x, &f, &mut rng));
            let at = |g: &[f64]| {
                knit_element(&rest, &x, [g[0], g[1]], MaterialHessian::Skip, &p).unwrap()
            };
            let ev = at(&GAMMA);
            check_gradient(|g| at(g).energy, &GAMMA, &ev.energy_per_gamma, &fd)
                .unwrap_or_else(|e| panic!("{name}: ∂E/∂γ {e}"));
            // ∂g/∂γ, 12 × 2 row-major.
            let jac: Vec<f64> = (0..12)
                .flat_map(|a| [ev.gradient_per_gamma[0][a], ev.gradient_per_gamma[1][a]])
                .collect();
            let g = |gm: &[f64]| at(gm).gradient.as_slice().to_vec();
            check_jacobian(g, &GAMMA, &jac, &fd).unwrap_or_else(|e| panic!("{name}: ∂g/∂γ {e}"));
            let mut wrong = jac.clone();
            let k = (0..24)
                .max_by(|&a, &b| wrong[a].abs().total_cmp(&wrong[b].abs()))
                .unwrap();
            wrong[k] *= 1.0 + 1e-4;
            assert!(check_jacobian(g, &GAMMA, &wrong, &fd).is_err());
        }
    }

    fn smallest_eigenvalue(h: &SMatrix<f64, 12, 12>) -> f64 {
        SymmetricEigen::new(DMatrix::from_column_slice(12, 12, h.as_slice()))
            .eigenvalues
            .min()
    }

    #[test]
    fn projected_hessian_is_psd_and_exact_where_the_exact_one_is() {
        let mut rng = rng(24);
        let (mut psd, mut indefinite) = (0, 0);
        for _ in 0..20 {
            for (name, f) in regimes(&mut rng) {
                if name == "det crossing 0" {
                    continue; // σ₂ + σ₃ ≈ σ₂ is fine, but σ₃ ≈ 0 gives no new information here.
                }
                let rest_x = rest_tet(&mut rng);
                let rest = RestTet::new(&rest_x).unwrap();
                let x = deformed(&rest_x, &f, &mut rng);
                let exact = eval(&rest, &x, MaterialHessian::Exact).hessian.unwrap();
                let projected = eval(&rest, &x, MaterialHessian::Projected).hessian.unwrap();
                let scale = exact.amax();
                let tol = 1e-10 * scale;
                assert!(
                    smallest_eigenvalue(&projected) >= -tol,
                    "{name}: projected not PSD"
                );
                if smallest_eigenvalue(&exact) >= -tol {
                    psd += 1;
                    assert!(
                        (exact - projected).amax() <= 1e-9 * scale,
                        "{name}: PSD but changed"
                    );
                } else {
                    indefinite += 1;
                    assert!((exact - projected).amax() > 1e-9 * scale, "{name}");
                }
            }
        }
        assert!(
            psd > 10 && indefinite > 10,
            "both cases seen: {psd} PSD, {indefinite} indefinite"
        );
    }

    #[test]
    fn rest_state_has_zero_energy_and_force() {
        let mut rng = rng(25);
        let rest_x = rest_tet(&mut rng);
        let rest = RestTet::new(&rest_x).unwrap();
        let q = crate::knit_material::test_states::rotation(&mut rng);
        let x = deformed(&rest_x, &q, &mut rng);
        let ev = eval(&rest, &x, MaterialHessian::Exact);
        assert!(ev.energy.abs() < 1e-20);
        assert!(ev.gradient.amax() < 1e-9);
        // A uniform scaling by c: ‖F − R‖² = 3 (c − 1)², ‖F − V‖² = 3 (c − 1)² with V = R.
        let c = 1.2;
        let x = deformed(&rest_x, &(q * c), &mut rng);
        let ev = eval(&rest, &x, MaterialHessian::Skip);
        let expected = rest.volume * (GAMMA[0] + GAMMA[1]) * 3.0 * (c - 1.0) * (c - 1.0);
        assert!(
            (ev.energy - expected).abs() < 1e-12 * expected,
            "{} vs {expected}",
            ev.energy
        );
    }

    #[test]
    fn degenerate_states_stay_finite() {
        let mut rng = rng(26);
        let rest_x = rest_tet(&mut rng);
        let rest = RestTet::new(&rest_x).unwrap();
        for f in [
            Matrix3::zeros(),
            Matrix3::from_diagonal(&Vector3::new(1.0, 0.0, 0.0)),
            Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0)),
            Matrix3::from_diagonal(&Vector3::new(1.0, 1e-9, -1e-9)),
        ] {
            let x = deformed(&rest_x, &f, &mut rng);
            for form in [MaterialHessian::Exact, MaterialHessian::Projected] {
                let ev = eval(&rest, &x, form);
                assert!(
                    ev.energy.is_finite() && ev.gradient.iter().all(|v| v.is_finite()),
                    "{f}"
                );
                assert!(ev.hessian.unwrap().iter().all(|v| v.is_finite()), "{f}");
            }
        }
        // Flat or inverted rest tets are an error that names the fix.
        let flat = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]];
        assert!(
            RestTet::new(&flat)
                .unwrap_err()
                .to_string()
                .contains("positively oriented")
        );
        let mut inverted = rest_x;
        inverted.swap(1, 2);
        assert!(RestTet::new(&inverted).is_err());
    }
}
