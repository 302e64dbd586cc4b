//! The adjoint Gauss-Newton direction through the sparse KKT system against the dense Gauss-Newton
//! direction `(2 R_totᵀ R_tot + κI)⁻¹(−g)`, `R_tot = R_q S + R_X A`, `S = −H⁻¹ K A` computed column by
//! column with the adjoint solve, on a small cylinder, at several dampings; and descent.

use std::ops::ControlFlow;

use nalgebra::{DMatrix, DVector};
use skintight::scene::{FileResolver, Scene};
use skintight::simulate::{equilibrium_params, prepare};
use skintight_design::optimize::{
    GaussNewtonSystem, KktSolver, MixedDerivative, parameter_map_matrix,
};
use skintight_design::{
    BoundaryModes, DesignMesh, DesignProblem, PatternMap, SeamLength, SeamTraction,
    SeamTractionForm, ShapeImls, Term, cylinder_target,
};
use skintight_geometry::math::{Real, Vec3};

fn terms() -> Vec<Box<dyn Term>> {
    // The target is about z from z = 0; the body about y, centred: turn it (x, y, z) → (x, z − 0.1, −y).
    let mut target = cylinder_target(0.047, 0.2, 24, 8).unwrap();
    for p in &mut target.positions {
        *p = Vec3::new(p.x, p.z - 0.1, -p.y);
    }
    vec![
        Box::new(ShapeImls::from_mesh(1.0, &target, None).unwrap()),
        Box::new(SeamLength::new(100.0).unwrap()),
        // No residuals: enters the direction through the gradient only.
        Box::new(SeamTraction::new(1e-4, SeamTractionForm::Linear).unwrap()),
    ]
}

fn sparse_to_dense(
    m: faer::sparse::SparseColMatRef<'_, usize, Real>,
    symmetric_lower: bool,
) -> DMatrix<Real> {
    let mut d = DMatrix::zeros(m.nrows(), m.ncols());
    let (cp, ri, v) = (m.symbolic().col_ptr(), m.symbolic().row_idx(), m.val());
    for c in 0..m.ncols() {
        for k in cp[c]..cp[c + 1] {
            d[(ri[k], c)] += v[k];
            if symmetric_lower && ri[k] != c {
                d[(c, ri[k])] += v[k];
            }
        }
    }
    d
}

#[test]
fn kkt_direction_equals_the_dense_gauss_newton_direction_on_a_cylinder() {
    let scene = Scene::from_json(&scene_json()).unwrap();
    let mut sim = prepare(&scene, &FileResolver::new(".")).unwrap();
    let params = equilibrium_params(&scene);
    skintight::simulate::run(&mut sim, &mut |_| ControlFlow::Continue(())).unwrap();
    let (mesh, pattern) = DesignMesh::from_garment(&sim.garment);
    let map = PatternMap::new(&mesh, &pattern).unwrap();
    let modes = BoundaryModes::new(&mesh, &pattern, 5).unwrap();
    let mut problem = DesignProblem::new(sim.system, sim.state, mesh, terms(), params).unwrap();
    assert!(problem.linearize().is_err(), "nothing evaluated yet");
    let eval = problem
        .evaluate(&pattern, true, &mut |_| ControlFlow::Continue(()))
        .unwrap();
    let lin = problem.linearize().unwrap();
    assert_eq!(lin.residual_terms, vec!["shape", "seam_length"]);
    // T_res = Σ r² equals the residual terms' values.
    let t_res: Real = eval
        .terms
        .iter()
        .filter(|t| t.name != "seam_traction")
        .map(|t| t.value)
        .sum();
    let sum_sq: Real = lin.residuals.values.iter().map(|r| r * r).sum();
    assert!((t_res - sum_sq).abs() <= 1e-10 * t_res);

    // Design parameters: mode coefficients (m) at a coarse level and boundary positions (m).
    let np2 = 2 * map.num_pattern_vertices();
    let g_pattern = eval.gradient.clone().unwrap();
    let gp = map.apply_jacobian_transpose(&g_pattern).unwrap();
    for coarse in [true, false] {
        let nc = if coarse {
            modes.num_coefficients()
        } else {
            map.num_parameters()
        };
        let a = parameter_map_matrix(np2, nc, |i| {
            let mut e = vec![0.0; nc];
            e[i] = 1.0;
            let dp = if coarse {
                modes.apply_jacobian(&e).map_err(|e| e.to_string())?
            } else {
                e
            };
            Ok(map
                .apply_jacobian(&dp)
                .map_err(|e| e.to_string())?
                .iter()
                .flat_map(|v| [v.x, v.y])
                .collect())
        })
        .unwrap();
        let g = if coarse {
            modes.apply_jacobian_transpose(&gp).unwrap()
        } else {
            gp.clone()
        };

        // Dense reference: S = −H⁻¹ K A column by column with the adjoint solve.
        let a_dense = sparse_to_dense(a.as_ref(), false);
        let MixedDerivative::Matrix(k) = &lin.mixed else {
            panic!("linearize gives K itself")
        };
        let k_dense = sparse_to_dense(k.as_ref(), false);
        let ka = &k_dense * &a_dense;
        let nq = ka.nrows();
        let mut s = DMatrix::zeros(nq, nc);
        let mut workspace_alpha = None;
        for c in 0..nc {
            let mut col: Vec<Real> = ka.column(c).iter().map(|v| -v).collect();
            let alpha = problem_solve(&mut problem, &mut col);
            workspace_alpha.get_or_insert(alpha);
            s.set_column(c, &DVector::from_vec(col));
        }
        assert_eq!(workspace_alpha, Some(lin.hessian_damping));
        let nr = lin.residuals.values.len();
        let mut rx = DMatrix::zeros(nr, lin.cloth_jacobian.nrows());
        for &(k, c, d) in &lin.residuals.cloth_jacobian {
            for i in 0..3 {
                rx[(k, 3 * c + i)] += d[i];
            }
        }
        let mut rxbar = DMatrix::zeros(nr, np2);
        for &(k, v, d) in &lin.residuals.pattern_jacobian {
            rxbar[(k, 2 * v)] += d.x;
            rxbar[(k, 2 * v + 1)] += d.y;
        }
        let j = sparse_to_dense(lin.cloth_jacobian.as_ref(), false);
        let r_tot = &rx * &j * &s + &rxbar * &a_dense;
        let gtg = r_tot.transpose() * &r_tot * 2.0;
        let curvature = gtg.diagonal().max();
        assert!(curvature > 0.0);

        let mut solver = KktSolver::new();
        // The optimizers' form: R_q = R_x J, R_p from the pattern entries.
        let adjoint = lin.clone().adjoint(1.0).unwrap();
        for factor in [1e-6, 1e-3, 1.0] {
            let kappa = factor * curvature;
            let system = GaussNewtonSystem {
                linearization: &adjoint,
                parameter_map: a.as_ref(),
                gradient: &g,
            };
            let d = solver.direction(&system, kappa).unwrap();
            let m = &gtg + DMatrix::identity(nc, nc) * kappa;
            let expected = -m.lu().solve(&DVector::from_column_slice(&g)).unwrap();
            let got = DVector::from_column_slice(&d.variables);
            let err = (&got - &expected).norm() / expected.norm();
            assert!(
                err <= 1e-6,
                "coarse {coarse} κ {kappa:e}: relative difference {err:e}"
            );
            let slope = got.dot(&DVector::from_column_slice(&g));
            assert!(slope < 0.0, "a descent direction (slope {slope:e})");
        }
        assert_eq!(solver.analyses(), 1, "the symbolic analysis is reused");
    }
}

/// The adjoint solve `(H + αD)⁻¹ rhs` of the problem's last equilibrium.
fn problem_solve(problem: &mut DesignProblem, rhs: &mut [Real]) -> Real {
    problem.solve_hessian(rhs).unwrap()
}

/// The two-panel sleeve on the small cylinder, both cuffs pinned, 2 cm edges, tolerance 10⁻¹⁰.
fn scene_json() -> String {
    design_support::sleeve_scene(design_support::BOTH_CUFFS, 0.02, 1e-10)
}

mod design_support;
