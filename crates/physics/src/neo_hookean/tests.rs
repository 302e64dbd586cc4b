//! Tests of the Neo-Hookean body energy.

use super::*;
use crate::node_block_assembly::HessianTriplets;
use nalgebra::{Rotation3, Unit};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use skintight_geometry::finite_difference::{FdParams, check_gradient, check_jacobian};

/// The dense Hessian of `body` at `x`, row-major `n × n`: the reference of the sparse assembly.
fn dense_hessian(body: &NeoHookeanBody, x: &[Real]) -> Result<Vec<Real>, BodyStateError> {
    let mut triplets = HessianTriplets::new(body.num_dofs());
    body.hessian(x, &mut triplets)?;
    Ok(triplets.to_dense())
}

fn thesis_material() -> NeoHookeanMaterial {
    NeoHookeanParams::default().material().unwrap()
}

fn fd_params() -> FdParams {
    FdParams {
        step: 1e-6,
        rel_tol: 2e-5,
        abs_tol: 0.0,
    }
}

fn random_rotation(rng: &mut ChaCha8Rng) -> Mat3 {
    let axis = Unit::new_normalize(Vec3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    ));
    Rotation3::from_axis_angle(&axis, rng.random_range(-3.0..3.0)).into_inner()
}

/// `R · S` with `S` symmetric positive definite, principal stretches in [0.85, 1.17] (so J ∈ [0.61, 1.6]).
fn random_deformation(rng: &mut ChaCha8Rng) -> Mat3 {
    let q = random_rotation(rng);
    let stretches = Vec3::from_fn(|_, _| rng.random_range(0.85..1.17));
    random_rotation(rng) * q * Mat3::from_diagonal(&stretches) * q.transpose()
}

/// A random positively oriented tet of size about `size` (m).
fn random_rest_tet(rng: &mut ChaCha8Rng, size: Real) -> [Vec3; 4] {
    loop {
        let mut p = [Vec3::zeros(); 4];
        for (a, q) in p.iter_mut().enumerate() {
            let base = match a {
                0 => Vec3::zeros(),
                1 => Vec3::x(),
                2 => Vec3::y(),
                _ => Vec3::z(),
            };
            *q = (base + Vec3::from_fn(|_, _| rng.random_range(-0.25..0.25))) * size;
        }
        if TetElement::new(&p).is_ok() {
            return p;
        }
    }
}

fn flat(x: &[Vec3; 4]) -> Vec<Real> {
    x.iter().flat_map(|p| [p.x, p.y, p.z]).collect()
}

fn unflat(x: &[Real]) -> [Vec3; 4] {
    std::array::from_fn(|a| Vec3::new(x[3 * a], x[3 * a + 1], x[3 * a + 2]))
}

/// A structured grid of `n³` cubes of edge `h` (m), each split into 6 tets along its main diagonal
/// (Freudenthal), rest positions jittered by up to `jitter · h`; all tets positively oriented.
fn tet_grid(n: usize, h: Real, jitter: Real, rng: &mut ChaCha8Rng) -> (Vec<Vec3>, Vec<[usize; 4]>) {
    let m = n + 1;
    let id = |i: usize, j: usize, k: usize| i + m * (j + m * k);
    let mut positions = Vec::with_capacity(m * m * m);
    for k in 0..m {
        for j in 0..m {
            for i in 0..m {
                let p = Vec3::new(i as Real, j as Real, k as Real) * h;
                positions.push(p + Vec3::from_fn(|_, _| rng.random_range(-jitter..jitter) * h));
            }
        }
    }
    let mut tets = Vec::with_capacity(6 * n * n * n);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                for perm in [
                    [0, 1, 2],
                    [0, 2, 1],
                    [1, 0, 2],
                    [1, 2, 0],
                    [2, 0, 1],
                    [2, 1, 0],
                ] {
                    let mut c = [i, j, k];
                    let mut tet = [id(c[0], c[1], c[2]); 4];
                    for (s, &axis) in perm.iter().enumerate() {
                        c[axis] += 1;
                        tet[s + 1] = id(c[0], c[1], c[2]);
                    }
                    let p = tet.map(|v| positions[v]);
                    let det =
                        Mat3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]).determinant();
                    if det < 0.0 {
                        tet.swap(2, 3);
                    }
                    tets.push(tet);
                }
            }
        }
    }
    (positions, tets)
}

fn min_eigenvalue(m: &Mat12) -> Real {
    nalgebra::SymmetricEigen::new(*m).eigenvalues.min()
}

fn max_abs(values: impl IntoIterator<Item = Real>) -> Real {
    values.into_iter().fold(0.0, |m, v| m.max(v.abs()))
}

#[test]
fn element_derivatives_match_finite_differences() {
    let material = thesis_material();
    for seed in 0..6u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let size = if seed % 2 == 0 { 1.0 } else { 0.02 };
        let rest = random_rest_tet(&mut rng, size);
        let element = TetElement::new(&rest).unwrap();
        let a = random_deformation(&mut rng);
        let t = Vec3::from_fn(|_, _| rng.random_range(-1.0..1.0)) * size;
        let x0: [Vec3; 4] = rest.map(|p| a * p + t);
        let j = element.deformation_gradient(&x0).determinant();
        assert!((0.6..=1.6).contains(&j), "seed {seed}: J = {j}");
        assert!((element.deformation_gradient(&x0) - a).norm() < 1e-12 * a.norm());

        let x = flat(&x0);
        let energy = |y: &[Real]| element.energy(&material, &unflat(y));
        let g = element.gradient(&material, &x0).unwrap();
        check_gradient(energy, &x, g.as_slice(), &fd_params())
            .unwrap_or_else(|e| panic!("seed {seed}: gradient {e}"));
        let grad = |y: &[Real]| {
            element
                .gradient(&material, &unflat(y))
                .unwrap()
                .as_slice()
                .to_vec()
        };
        let h = element.hessian(&material, &x0, false).unwrap();
        check_jacobian(grad, &x, h.as_slice(), &fd_params())
            .unwrap_or_else(|e| panic!("seed {seed}: Hessian {e}"));
    }
}

#[test]
fn stress_derivative_matches_finite_differences_of_stress() {
    let material = NeoHookeanMaterial::from_young_poisson(1.0e5, 0.3).unwrap();
    for seed in 10..14u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let f = random_deformation(&mut rng);
        let fv = f.as_slice().to_vec();
        let as_mat = |y: &[Real]| Mat3::from_column_slice(y);
        let p = material.stress(&f).unwrap();
        check_gradient(
            |y| material.density(&as_mat(y)),
            &fv,
            p.as_slice(),
            &fd_params(),
        )
        .unwrap();
        let k = material.stress_derivative(&f).unwrap();
        check_jacobian(
            |y| material.stress(&as_mat(y)).unwrap().as_slice().to_vec(),
            &fv,
            k.as_slice(),
            &fd_params(),
        )
        .unwrap();
        assert!((k - k.transpose()).norm() <= 1e-12 * k.norm());
    }
}

#[test]
fn body_derivatives_match_finite_differences() {
    for (seed, n, h) in [(20u64, 1, 0.05), (21, 2, 0.02), (22, 2, 1.0)] {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (rest, tets) = tet_grid(n, h, 0.15, &mut rng);
        // Fix the bottom layer (z index 0).
        let fixed: Vec<bool> = (0..rest.len()).map(|v| v < (n + 1) * (n + 1)).collect();
        let params = NeoHookeanParams {
            youngs_modulus: 1.0e4,
            poisson_ratio: 0.45,
            ..Default::default()
        };
        let body = NeoHookeanBody::new(&rest, &tets, &fixed, &params).unwrap();
        assert_eq!(body.num_dofs(), 3 * (rest.len() - (n + 1) * (n + 1)));
        let a = Mat3::identity() + Mat3::from_fn(|_, _| rng.random_range(-0.1..0.1));
        let deformed: Vec<Vec3> = rest
            .iter()
            .map(|p| a * p + Vec3::from_fn(|_, _| rng.random_range(-0.04..0.04)) * h)
            .collect();
        let x = body.dofs_from_positions(&deformed);
        let mut g = vec![0.0; body.num_dofs()];
        body.gradient(&x, &mut g).unwrap();
        check_gradient(|y| body.value(y).unwrap(), &x, &g, &fd_params())
            .unwrap_or_else(|e| panic!("seed {seed}: gradient {e}"));
        let grad = |y: &[Real]| {
            let mut out = vec![0.0; body.num_dofs()];
            body.gradient(y, &mut out).unwrap();
            out
        };
        let hess = dense_hessian(&body, &x).unwrap();
        check_jacobian(grad, &x, &hess, &fd_params())
            .unwrap_or_else(|e| panic!("seed {seed}: Hessian {e}"));
    }
}

#[test]
fn rest_state_has_zero_energy_and_gradient() {
    for (seed, n) in [(30u64, 1), (31, 3)] {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (rest, tets) = tet_grid(n, 0.03, 0.2, &mut rng);
        let fixed = vec![false; rest.len()];
        let body = NeoHookeanBody::new(&rest, &tets, &fixed, &NeoHookeanParams::default()).unwrap();
        let x = body.dofs_from_positions(&rest);
        let e = body.value(&x).unwrap();
        let mut g = vec![1.0; body.num_dofs()];
        body.gradient(&x, &mut g).unwrap();
        // Scale: energy and force of a 1 % strain.
        let volume: Real = body.elements().iter().map(|e| e.volume).sum();
        let mu = body.material().mu;
        assert!(e.abs() <= 1e-12 * mu * volume * 1e-4, "energy at rest {e}");
        let force_scale = mu * 0.03 * 0.03 * 1e-2;
        assert!(
            max_abs(g.iter().copied()) <= 1e-10 * force_scale,
            "gradient at rest"
        );
    }
}

#[test]
fn energy_is_invariant_under_rigid_motion_and_gradient_rotates() {
    for seed in 40..44u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (rest, tets) = tet_grid(2, 0.04, 0.15, &mut rng);
        let fixed = vec![false; rest.len()];
        let body = NeoHookeanBody::new(&rest, &tets, &fixed, &NeoHookeanParams::default()).unwrap();
        let deformed: Vec<Vec3> = rest
            .iter()
            .map(|p| p + Vec3::from_fn(|_, _| rng.random_range(-0.002..0.002)))
            .collect();
        let r = random_rotation(&mut rng);
        let t = Vec3::from_fn(|_, _| rng.random_range(-1.0..1.0));
        let moved: Vec<Vec3> = deformed.iter().map(|p| r * p + t).collect();
        let (x, y) = (
            body.dofs_from_positions(&deformed),
            body.dofs_from_positions(&moved),
        );
        let (ex, ey) = (body.value(&x).unwrap(), body.value(&y).unwrap());
        assert!(ex > 0.0);
        assert!((ex - ey).abs() <= 1e-9 * ex, "seed {seed}: {ex} vs {ey}");
        let mut gx = vec![0.0; body.num_dofs()];
        let mut gy = vec![0.0; body.num_dofs()];
        body.gradient(&x, &mut gx).unwrap();
        body.gradient(&y, &mut gy).unwrap();
        let scale = max_abs(gx.iter().copied());
        for v in 0..rest.len() {
            let gxv = r * Vec3::from_column_slice(&gx[3 * v..3 * v + 3]);
            let gyv = Vec3::from_column_slice(&gy[3 * v..3 * v + 3]);
            assert!(
                (gxv - gyv).norm() <= 1e-8 * scale,
                "seed {seed}, vertex {v}"
            );
        }
    }
}

#[test]
fn projected_hessian_is_psd_and_unchanged_where_already_psd() {
    let material = thesis_material();
    let (mut already_psd, mut indefinite) = (0, 0);
    for seed in 50..80u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let rest = random_rest_tet(&mut rng, 0.05);
        let element = TetElement::new(&rest).unwrap();
        // Alternate moderate and strongly compressive / shearing states so both cases occur.
        let a = if seed % 2 == 0 {
            random_deformation(&mut rng)
        } else {
            random_rotation(&mut rng)
                * Mat3::from_diagonal(&Vec3::new(
                    rng.random_range(0.4..0.8),
                    rng.random_range(0.6..1.4),
                    rng.random_range(1.0..1.8),
                ))
        };
        let x = rest.map(|p| a * p);
        let h = element.hessian(&material, &x, false).unwrap();
        let hp = element.hessian(&material, &x, true).unwrap();
        let scale = max_abs(h.iter().copied());
        let min_projected = min_eigenvalue(&hp);
        assert!(
            min_projected >= -1e-10 * scale,
            "seed {seed}: min eigenvalue {min_projected}"
        );
        if min_eigenvalue(&h) >= -1e-10 * scale {
            already_psd += 1;
            assert!(
                (h - hp).norm() <= 1e-10 * scale,
                "seed {seed}: PSD Hessian was changed"
            );
        } else {
            indefinite += 1;
            assert!((h - hp).norm() > 1e-8 * scale);
        }
    }
    assert!(
        already_psd >= 3 && indefinite >= 3,
        "{already_psd} PSD, {indefinite} indefinite"
    );
}

#[test]
fn node_block_assembly_equals_dense_for_the_body() {
    for (seed, n, project) in [(60u64, 1, false), (61, 2, true), (62, 3, false)] {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (rest, tets) = tet_grid(n, 0.02, 0.15, &mut rng);
        let fixed: Vec<bool> = (0..rest.len()).map(|_| rng.random::<f64>() < 0.2).collect();
        let params = NeoHookeanParams {
            project_psd: project,
            ..Default::default()
        };
        let body = NeoHookeanBody::new(&rest, &tets, &fixed, &params).unwrap();
        let mut asm = body.hessian_assembler();
        for _ in 0..2 {
            let deformed: Vec<Vec3> = rest
                .iter()
                .map(|p| p * 1.05 + Vec3::from_fn(|_, _| rng.random_range(-0.002..0.002)))
                .collect();
            let x = body.dofs_from_positions(&deformed);
            body.assemble_hessian(&x, &mut asm).unwrap();
            let dense = dense_hessian(&body, &x).unwrap();
            let sparse = asm.to_dense();
            let scale = max_abs(dense.iter().copied());
            for (k, (a, b)) in sparse.iter().zip(&dense).enumerate() {
                assert!(
                    (a - b).abs() <= 1e-12 * scale,
                    "seed {seed}, entry {k}: {a} vs {b}"
                );
            }
        }
    }
}

/// Exact second-order (small-strain) energy of linear elasticity with Lamé `lambda`, `mu` (Pa) for the
/// displacement gradient `grad_u`: `μ |ε|² + λ/2 (tr ε)²` (Pa).
fn linear_density(lambda: Real, mu: Real, grad_u: &Mat3) -> Real {
    let eps = (grad_u + grad_u.transpose()) * 0.5;
    mu * eps.norm_squared() + 0.5 * lambda * eps.trace() * eps.trace()
}

#[test]
fn rest_stiffness_is_linear_elasticity() {
    let (e, nu) = (24.78e3, 0.49);
    let lambda_std = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
    let mu = e / (2.0 * (1.0 + nu));
    // (material, Lamé λ of the linear elasticity it must reduce to)
    let cases = [
        (
            NeoHookeanMaterial::matching_linear_elasticity(e, nu).unwrap(),
            lambda_std,
        ),
        (
            NeoHookeanMaterial::from_young_poisson(e, nu).unwrap(),
            lambda_std - 2.0 * mu / 3.0,
        ),
    ];
    let mut rng = ChaCha8Rng::seed_from_u64(70);
    let rest = random_rest_tet(&mut rng, 0.03);
    let element = TetElement::new(&rest).unwrap();
    for (material, lambda_lin) in cases {
        assert!((material.mu - mu).abs() <= 1e-12 * mu);
        let h = element.hessian(&material, &rest, false).unwrap();
        // Linear stiffness by polarization of the quadratic energy U(u) = V ψ_lin(Σ u_a c_aᵀ).
        let u_energy = |u: &[Real; 12]| {
            let mut grad_u = Mat3::zeros();
            for a in 0..4 {
                grad_u += Vec3::new(u[3 * a], u[3 * a + 1], u[3 * a + 2])
                    * element.shape_gradients[a].transpose();
            }
            element.volume * linear_density(lambda_lin, mu, &grad_u)
        };
        let unit = |i: usize| std::array::from_fn::<Real, 12, _>(|k| (k == i) as u8 as Real);
        let scale = max_abs(h.iter().copied());
        for i in 0..12 {
            for j in 0..12 {
                let both: [Real; 12] = std::array::from_fn(|k| unit(i)[k] + unit(j)[k]);
                let expected = if i == j {
                    2.0 * u_energy(&unit(i))
                } else {
                    u_energy(&both) - u_energy(&unit(i)) - u_energy(&unit(j))
                };
                assert!(
                    (h[(i, j)] - expected).abs() <= 1e-9 * scale,
                    "entry ({i}, {j}): {} vs {expected}",
                    h[(i, j)]
                );
            }
        }
    }
}

#[test]
fn small_uniform_stretch_energy_matches_small_strain_expectation() {
    let (e, nu) = (24.78e3, 0.49);
    let thesis = NeoHookeanMaterial::from_young_poisson(e, nu).unwrap();
    let matching = NeoHookeanMaterial::matching_linear_elasticity(e, nu).unwrap();
    let lambda_std = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
    let mu = e / (2.0 * (1.0 + nu));
    let mut rng = ChaCha8Rng::seed_from_u64(80);
    let rest = random_rest_tet(&mut rng, 0.05);
    let element = TetElement::new(&rest).unwrap();
    let eps = 1e-4;
    let stretch = Mat3::from_diagonal(&Vec3::new(1.0 + eps, 1.0, 1.0));
    let x = rest.map(|p| stretch * p);
    // Uniaxial strain ε: linear elasticity gives U = V (λ/2 + μ) ε²; the thesis convention has
    // |dev ε|² = 2ε²/3 and bulk λ: U = V (λ/2 + 2μ/3) ε².
    let expect_matching = element.volume * (lambda_std / 2.0 + mu) * eps * eps;
    let expect_thesis = element.volume * (thesis.lambda / 2.0 + 2.0 * mu / 3.0) * eps * eps;
    let got_matching = element.energy(&matching, &x);
    let got_thesis = element.energy(&thesis, &x);
    assert!(
        (got_matching / expect_matching - 1.0).abs() < 1e-3,
        "{got_matching} vs {expect_matching}"
    );
    assert!(
        (got_thesis / expect_thesis - 1.0).abs() < 1e-3,
        "{got_thesis} vs {expect_thesis}"
    );
    // Pure shear is isochoric: both conventions equal linear elasticity's μ γ²/2 ... with γ = 2ε₁₂.
    let shear = Mat3::new(1.0, eps, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
    let xs = rest.map(|p| shear * p);
    let expect_shear = element.volume * linear_density(lambda_std, mu, &(shear - Mat3::identity()));
    for m in [thesis, matching] {
        let got = element.energy(&m, &xs);
        assert!(
            (got / expect_shear - 1.0).abs() < 1e-3,
            "{got} vs {expect_shear}"
        );
    }
    // Effective small-strain moduli.
    let (e_m, nu_m) = matching.small_strain_young_poisson();
    assert!((e_m / e - 1.0).abs() < 1e-12 && (nu_m - nu).abs() < 1e-12);
    let (e_t, nu_t) = thesis.small_strain_young_poisson();
    assert!(
        (e_t / e - 1.0).abs() < 2e-4 && (nu_t - 0.4899).abs() < 1e-4,
        "{e_t} {nu_t}"
    );
}

#[test]
fn inverted_state_gives_infinite_energy_and_errors_naming_the_element() {
    let mut rng = ChaCha8Rng::seed_from_u64(90);
    let (rest, tets) = tet_grid(1, 0.05, 0.1, &mut rng);
    let fixed = vec![false; rest.len()];
    let body = NeoHookeanBody::new(&rest, &tets, &fixed, &NeoHookeanParams::default()).unwrap();
    // Push corner 3 of tet 4 through its opposite face.
    let t = 4;
    let [a, b, c, d] = tets[t];
    let mut deformed = rest.clone();
    let centroid = (rest[a] + rest[b] + rest[c]) / 3.0;
    deformed[d] = centroid - (rest[d] - centroid);
    let x = body.dofs_from_positions(&deformed);
    assert_eq!(body.value(&x).unwrap(), Real::INFINITY);
    let mut g = vec![0.0; body.num_dofs()];
    let err = body.gradient(&x, &mut g).unwrap_err();
    assert!(
        matches!(err, BodyStateError::InvertedElement { det, .. } if det < 0.0),
        "{err}"
    );
    let mut triplets = HessianTriplets::new(body.num_dofs());
    assert!(matches!(
        body.hessian(&x, &mut triplets),
        Err(BodyStateError::InvertedElement { .. })
    ));
    // Non-finite DOFs: +∞, never NaN.
    let mut y = body.dofs_from_positions(&rest);
    y[0] = Real::NAN;
    assert_eq!(body.value(&y).unwrap(), Real::INFINITY);
    assert!(body.gradient(&y, &mut g).is_err());
    // As a rest shape, the same corners are rejected as inverted.
    let err = TetElement::new(&[deformed[a], deformed[b], deformed[c], deformed[d]]).unwrap_err();
    assert_eq!(err.0, "inverted");
    // Wrong lengths are errors, not panics.
    assert!(matches!(
        body.value(&y[1..]),
        Err(BodyStateError::Length { .. })
    ));
    assert!(matches!(
        body.gradient(&x, &mut g[1..]),
        Err(BodyStateError::Length { .. })
    ));
}

#[test]
fn inverted_element_error_names_the_tet() {
    let rest = [
        Vec3::zeros(),
        Vec3::x(),
        Vec3::y(),
        Vec3::z(),
        Vec3::new(1.0, 1.0, 1.0),
    ];
    let tets = [[0, 1, 2, 3], [1, 2, 3, 4]];
    let fixed = [false; 5];
    let body = NeoHookeanBody::new(&rest, &tets, &fixed, &NeoHookeanParams::default()).unwrap();
    let mut moved = rest.to_vec();
    moved[4] = Vec3::new(0.1, 0.1, 0.1);
    let x = body.dofs_from_positions(&moved);
    let mut g = vec![0.0; 15];
    assert!(matches!(
        body.gradient(&x, &mut g),
        Err(BodyStateError::InvertedElement { element: 1, .. })
    ));
}

#[test]
fn bad_input_is_rejected_with_named_errors() {
    let rest = vec![
        Vec3::zeros(),
        Vec3::x(),
        Vec3::y(),
        Vec3::z(),
        Vec3::new(1.0, 1.0, 0.0),
    ];
    let p = NeoHookeanParams::default();
    let fixed = vec![false; 5];
    let inverted =
        NeoHookeanBody::new(&rest, &[[0, 1, 2, 3], [0, 2, 1, 3]], &fixed, &p).unwrap_err();
    assert!(
        matches!(
            inverted,
            NeoHookeanError::BadRestTet {
                tet: 1,
                kind: "inverted",
                ..
            }
        ),
        "{inverted}"
    );
    let flat = NeoHookeanBody::new(&rest, &[[0, 1, 2, 4]], &fixed, &p).unwrap_err();
    assert!(
        matches!(
            flat,
            NeoHookeanError::BadRestTet {
                tet: 0,
                kind: "degenerate (flat)",
                ..
            }
        ),
        "{flat}"
    );
    let range = NeoHookeanBody::new(&rest, &[[0, 1, 2, 7]], &fixed, &p).unwrap_err();
    assert!(
        matches!(
            range,
            NeoHookeanError::BadTetVertex {
                tet: 0,
                corner: 3,
                vertex: 7,
                ..
            }
        ),
        "{range}"
    );
    let repeat = NeoHookeanBody::new(&rest, &[[0, 1, 1, 3]], &fixed, &p).unwrap_err();
    assert!(
        matches!(repeat, NeoHookeanError::BadTetVertex { corner: 2, .. }),
        "{repeat}"
    );
    let mask = NeoHookeanBody::new(&rest, &[[0, 1, 2, 3]], &fixed[..4], &p).unwrap_err();
    assert_eq!(
        mask,
        NeoHookeanError::FixedMaskLength {
            got: 4,
            expected: 5
        }
    );
    let mut nan = rest.clone();
    nan[2].y = Real::NAN;
    assert!(matches!(
        NeoHookeanBody::new(&nan, &[[0, 1, 2, 3]], &fixed, &p),
        Err(NeoHookeanError::NonFiniteRestPosition { vertex: 2, .. })
    ));
    for (e, nu, field) in [
        (0.0, 0.3, "youngs_modulus"),
        (1e4, 0.5, "poisson_ratio"),
        (1e4, Real::NAN, "poisson_ratio"),
    ] {
        let params = NeoHookeanParams {
            youngs_modulus: e,
            poisson_ratio: nu,
            ..p
        };
        let err = NeoHookeanBody::new(&rest, &[[0, 1, 2, 3]], &fixed, &params).unwrap_err();
        assert!(
            matches!(err, NeoHookeanError::Material { field: f, .. } if f == field),
            "{err}"
        );
    }
}

#[test]
fn dof_numbering_skips_fixed_vertices() {
    let rest = vec![Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::z()];
    let body = NeoHookeanBody::new(
        &rest,
        &[[0, 1, 2, 3]],
        &[true, false, true, false],
        &NeoHookeanParams::default(),
    )
    .unwrap();
    assert_eq!(body.num_dofs(), 6);
    assert_eq!(
        (0..4).map(|v| body.vertex_dof(v)).collect::<Vec<_>>(),
        vec![None, Some(0), None, Some(3)]
    );
    let x = body.dofs_from_positions(&rest);
    assert_eq!(x, vec![1.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
    assert_eq!(body.positions_from_dofs(&x).unwrap(), rest);
}

#[test]
fn faer_cholesky_of_the_lower_triangle_solves_the_body_hessian() {
    use faer::Side;
    use faer::linalg::solvers::Solve;
    use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
    for (seed, n) in [(100u64, 1), (101, 3)] {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (rest, tets) = tet_grid(n, 0.02, 0.1, &mut rng);
        let fixed: Vec<bool> = (0..rest.len()).map(|v| v < (n + 1) * (n + 1)).collect();
        let params = NeoHookeanParams {
            project_psd: true,
            ..Default::default()
        };
        let body = NeoHookeanBody::new(&rest, &tets, &fixed, &params).unwrap();
        let deformed: Vec<Vec3> = rest
            .iter()
            .map(|p| {
                Vec3::new(p.x, p.y, 0.9 * p.z)
                    + Vec3::from_fn(|_, _| rng.random_range(-0.001..0.001))
            })
            .collect();
        let x = body.dofs_from_positions(&deformed);
        let mut asm = body.hessian_assembler();
        body.assemble_hessian(&x, &mut asm).unwrap();
        let matrix = asm.matrix();
        let symbolic = SymbolicLlt::try_new(matrix.symbolic(), Side::Lower).unwrap();
        let llt = Llt::try_new_with_symbolic(symbolic, matrix.as_ref(), Side::Lower).unwrap();
        let ndof = body.num_dofs();
        let b: Vec<Real> = (0..ndof).map(|_| rng.random_range(-1.0..1.0)).collect();
        let mut z = faer::Mat::<Real>::from_fn(ndof, 1, |i, _| b[i]);
        llt.solve_in_place(z.as_mut());
        let dense = asm.to_dense();
        let scale = max_abs(b.iter().copied());
        for r in 0..ndof {
            let hz: Real = (0..ndof).map(|c| dense[r * ndof + c] * z[(c, 0)]).sum();
            assert!(
                (hz - b[r]).abs() <= 1e-8 * scale,
                "seed {seed}, row {r}: {hz} vs {}",
                b[r]
            );
        }
    }
}
