use super::*;
use crate::linearization::{Linearization, parameter_map_matrix};
use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

pub(crate) fn sparse(m: &DMatrix<Real>, lower_only: bool) -> SparseColMat<usize, Real> {
    let mut t = Vec::new();
    for c in 0..m.ncols() {
        for r in 0..m.nrows() {
            if m[(r, c)] != 0.0 && (!lower_only || r >= c) {
                t.push(faer::sparse::Triplet::new(r, c, m[(r, c)]));
            }
        }
    }
    SparseColMat::try_new_from_triplets(m.nrows(), m.ncols(), &t).unwrap()
}

/// A random system: its linearization (with `K` itself) and the dense matrices it was made from.
pub(crate) struct Random {
    pub(crate) linearization: Linearization,
    pub(crate) h: DMatrix<Real>,
    pub(crate) k: DMatrix<Real>,
    pub(crate) a: DMatrix<Real>,
    pub(crate) g: Vec<Real>,
}

/// `nr` residuals, each depending on a few state unknowns and parameters (some pairs repeated).
pub(crate) fn random(seed: u64, nr: usize) -> Random {
    let (nq, np, nc) = (9, 10, 4);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut sparse_random = |r: usize, c: usize, density: f64| {
        DMatrix::from_fn(r, c, |_, _| {
            if rng.random::<f64>() < density {
                rng.random_range(-1.0..1.0)
            } else {
                0.0
            }
        })
    };
    let b = sparse_random(nq, nq, 0.3);
    let h = &b * b.transpose() * 100.0 + DMatrix::identity(nq, nq) * 50.0;
    let k = sparse_random(nq, np, 0.4) * 30.0;
    let a = sparse_random(np, nc, 0.6) * 0.01;
    let mut residuals = Vec::new();
    let mut jacobian = Vec::new();
    for i in 0..nr {
        residuals.push(rng.random_range(-1.0..1.0));
        for _ in 0..3 {
            let q = rng.random_range(0..nq);
            jacobian.push((i, Unknown::State(q), rng.random_range(-1.0..1.0) * 10.0));
            let p = rng.random_range(0..np);
            jacobian.push((i, Unknown::Parameter(p), rng.random_range(-1.0..1.0) * 10.0));
        }
    }
    let g = (0..nc).map(|_| rng.random_range(-1.0..1.0)).collect();
    Random {
        linearization: Linearization {
            residuals,
            jacobian,
            hessian: sparse(&h, true),
            mixed: MixedDerivative::Matrix(sparse(&k, false)),
        },
        h,
        k,
        a,
        g,
    }
}

/// `(2 R_totᵀ R_tot + κI)⁻¹ (−g)` with dense matrices.
pub(crate) fn dense_direction(p: &Random, kappa: Real) -> Vec<Real> {
    let nr = p.linearization.residuals.len();
    let mut rq = DMatrix::<Real>::zeros(nr, p.h.nrows());
    let mut rp = DMatrix::<Real>::zeros(nr, p.k.ncols());
    for &(k, u, d) in &p.linearization.jacobian {
        match u {
            Unknown::State(q) => rq[(k, q)] += d,
            Unknown::Parameter(x) => rp[(k, x)] += d,
        }
    }
    let s: DMatrix<Real> = -p.h.clone().lu().solve(&(&p.k * &p.a)).unwrap();
    let r_tot: DMatrix<Real> = rq * s + rp * &p.a;
    let m = r_tot.transpose() * &r_tot * 2.0 + DMatrix::identity(p.a.ncols(), p.a.ncols()) * kappa;
    let g = nalgebra::DVector::from_column_slice(&p.g);
    (-m.lu().solve(&g).unwrap()).as_slice().to_vec()
}

pub(crate) fn solve(solver: &mut KktSolver, p: &Random, kappa: Real) -> GaussNewtonDirection {
    let a = sparse(&p.a, false);
    let system = GaussNewtonSystem {
        linearization: &p.linearization,
        parameter_map: a.as_ref(),
        gradient: &p.g,
    };
    solver.direction(&system, kappa).unwrap()
}

#[test]
fn kkt_direction_equals_the_dense_gauss_newton_direction_and_descends() {
    for seed in 0..4 {
        let p = random(seed, 7);
        let mut solver = KktSolver::new();
        for (i, kappa) in [0.0, 1e-3, 1.0, 100.0].into_iter().enumerate() {
            let d = solve(&mut solver, &p, kappa);
            assert_eq!(d.reused_analysis, i > 0, "same structure, one analysis");
            let expected = dense_direction(&p, kappa);
            let scale = expected.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            for (a, b) in d.variables.iter().zip(&expected) {
                assert!(
                    (a - b).abs() <= 1e-8 * scale,
                    "seed {seed} κ {kappa}: {a} vs {b}"
                );
            }
            let slope: Real = d.variables.iter().zip(&p.g).map(|(a, b)| a * b).sum();
            assert!(slope < 0.0, "a descent direction");
            // dp = A dc and H dq + K dp = 0.
            let dc = nalgebra::DVector::from_column_slice(&d.variables);
            let dx = &p.a * dc;
            for (a, b) in d.parameters.iter().zip(dx.iter()) {
                assert!((a - b).abs() <= 1e-9 * scale.max(1e-300));
            }
            let eq = &p.h * nalgebra::DVector::from_column_slice(&d.state) + &p.k * dx;
            assert!(eq.norm() <= 1e-8 * (p.k.norm() * scale));
        }
        assert_eq!(solver.analyses(), 1);
    }
}

#[test]
fn without_residuals_the_direction_is_the_damped_gradient_and_bad_input_is_an_error() {
    let p = random(9, 0);
    let mut solver = KktSolver::new();
    let d = solve(&mut solver, &p, 4.0);
    for (a, g) in d.variables.iter().zip(&p.g) {
        assert!((a + g / 4.0).abs() <= 1e-12);
    }
    let a = sparse(&p.a, false);
    let system = GaussNewtonSystem {
        linearization: &p.linearization,
        parameter_map: a.as_ref(),
        gradient: &p.g,
    };
    assert!(matches!(
        solver.direction(&system, 0.0),
        Err(GaussNewtonError::Invalid(_))
    ));
    assert!(solver.direction(&system, Real::NAN).is_err());
    let short = &p.g[1..];
    let short = GaussNewtonSystem {
        gradient: short,
        ..system
    };
    assert!(solver.direction(&short, 1.0).is_err());
    let upper = Linearization {
        hessian: sparse(&p.h, false),
        ..p.linearization.clone()
    };
    let upper = GaussNewtonSystem {
        linearization: &upper,
        ..system
    };
    assert!(solver.direction(&upper, 1.0).is_err());
    let mut bad = random(9, 3);
    bad.linearization.jacobian[0].1 = Unknown::State(99);
    let bad = GaussNewtonSystem {
        linearization: &bad.linearization,
        ..system
    };
    assert!(solver.direction(&bad, 1.0).is_err());
    assert!(parameter_map_matrix(2, 1, |_| Ok(vec![Real::NAN, 0.0])).is_err());
}
