//! Both optimizers on a problem with no garment in it: the stiffnesses of a chain of springs fitted to
//! the displacements it shows under a few loads (the shape of the knitwear paper's Eq. 21 fit: per-element
//! material parameters `p`, the frames' positions `q` at equilibrium, residuals `q − q_target`).
//!
//! A chain of `n` springs hangs from a wall: node `i` (1..n, positions `u_i`, m) is joined to node `i − 1`
//! (node 0 the wall) by a spring of stiffness `k_i` (N/m). Under a load `f` (N per node) its energy is
//! `U = ½ Σ k_i (u_i − u_{i−1})² − fᵀu`, so `H = ∂²U/∂u²` is tridiagonal and
//! `K_{j,i} = ∂²U/∂u_j∂k_i = (u_i − u_{i−1}) (δ_ij − δ_{i−1,j})`. Each load is a frame; the state is all
//! frames' positions, `H` block diagonal. The variables are the stiffnesses in units of 100 N/m
//! (`p = A c`, `A = 100 I`), or a linear profile `k_i = c₀ + c₁ i` (two variables).

use std::ops::ControlFlow;

use faer::sparse::{SparseColMat, Triplet};
use nalgebra::{DMatrix, DVector};
use skintight_optimize::{
    AdjointGaussNewton, AdjointProblem, GaussNewtonError, GaussNewtonParams, GaussNewtonSolver,
    LbfgsParams, Linearization, MixedDerivative, MixedForm, Objective, OptimizerStop, Unknown,
    gauss_newton, lbfgs, parameter_map_matrix,
};

/// The problem's floating-point type (the crate's `Real` is `f64`).
type Real = f64;

#[derive(Debug)]
struct FitError(String);

impl std::fmt::Display for FitError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl From<GaussNewtonError> for FitError {
    fn from(e: GaussNewtonError) -> Self {
        Self(e.to_string())
    }
}

/// The fit: loads (N), target positions (m), and the parameter map (N/m per unit of the variables).
struct SpringFit {
    n: usize,
    loads: Vec<Vec<Real>>,
    targets: Vec<Vec<Real>>,
    map: DMatrix<Real>,
    evaluations: usize,
    /// The stiffnesses of the last linearization, whose Hessian `solve_hessian` solves with.
    last: Option<Vec<Real>>,
}

impl SpringFit {
    fn new(n: usize, map: DMatrix<Real>, truth: &[Real]) -> Self {
        let loads: Vec<Vec<Real>> = vec![
            (0..n).map(|i| if i + 1 == n { 1.0 } else { 0.0 }).collect(),
            vec![0.5; n],
            (0..n).map(|i| 0.3 * (i as Real + 1.0)).collect(),
        ];
        let mut fit = Self {
            n,
            loads,
            targets: Vec::new(),
            map,
            evaluations: 0,
            last: None,
        };
        let k = fit.stiffness(truth).unwrap();
        fit.targets = fit.loads.iter().map(|f| fit.frame(&k, f)).collect();
        fit
    }

    /// `k = A c` (N/m); an error where a spring would not be stiff.
    fn stiffness(&self, c: &[Real]) -> Result<Vec<Real>, FitError> {
        let k = &self.map * DVector::from_column_slice(c);
        if k.iter().any(|k| k.is_nan() || *k <= 0.0) {
            return Err(FitError(format!("a spring stiffness is not positive: {k}")));
        }
        Ok(k.as_slice().to_vec())
    }

    /// `H` of one frame (N/m).
    fn hessian(&self, k: &[Real]) -> DMatrix<Real> {
        let n = self.n;
        DMatrix::from_fn(n, n, |r, c| {
            let mut v = 0.0;
            if r == c {
                v += k[r] + if r + 1 < n { k[r + 1] } else { 0.0 };
            }
            if r + 1 == c {
                v -= k[c];
            }
            if c + 1 == r {
                v -= k[r];
            }
            v
        })
    }

    /// The equilibrium positions under `f` (m).
    fn frame(&self, k: &[Real], f: &[Real]) -> Vec<Real> {
        let u = self.hessian(k).lu().solve(&DVector::from_column_slice(f));
        u.expect("a stiff chain").as_slice().to_vec()
    }

    /// `K` of one frame at positions `u`: column `i` (spring i) holds `±(u_i − u_{i−1})`.
    fn mixed(&self, u: &[Real]) -> DMatrix<Real> {
        DMatrix::from_fn(self.n, self.n, |j, i| {
            let stretch = u[i] - if i > 0 { u[i - 1] } else { 0.0 };
            if j == i {
                stretch
            } else if i > 0 && j == i - 1 {
                -stretch
            } else {
                0.0
            }
        })
    }

    /// The stiffnesses at `c` (N/m) and every frame's positions (m).
    fn solve(&self, c: &[Real]) -> Result<(Vec<Real>, Vec<Vec<Real>>), FitError> {
        let k = self.stiffness(c)?;
        let frames = self.loads.iter().map(|f| self.frame(&k, f)).collect();
        Ok((k, frames))
    }

    /// One `n × n` block per frame on the diagonal.
    fn block_diagonal(&self, block: &DMatrix<Real>) -> DMatrix<Real> {
        let m = self.n * self.loads.len();
        DMatrix::from_fn(m, m, |r, c| {
            if r / self.n == c / self.n {
                block[(r % self.n, c % self.n)]
            } else {
                0.0
            }
        })
    }
}

impl Objective for SpringFit {
    type Error = FitError;

    /// `T = Σ r²` and `dT/dc = −Aᵀ Σ_frames Kᵀ λ`, `H λ = 2 r` (the adjoint).
    fn evaluate(&mut self, c: &[Real]) -> Result<(Real, Vec<Real>), FitError> {
        self.evaluations += 1;
        let (k, frames) = self.solve(c)?;
        let h = self.hessian(&k).lu();
        let mut value = 0.0;
        let mut dk = DVector::zeros(self.n);
        for (u, target) in frames.iter().zip(&self.targets) {
            let r = DVector::from_iterator(self.n, u.iter().zip(target).map(|(u, t)| u - t));
            value += r.norm_squared();
            let lambda = h.solve(&(2.0 * &r)).unwrap();
            dk -= self.mixed(u).transpose() * lambda;
        }
        Ok((value, (self.map.transpose() * dk).as_slice().to_vec()))
    }
}

fn sparse(m: &DMatrix<Real>, lower_only: bool) -> SparseColMat<usize, Real> {
    let mut t = Vec::new();
    for c in 0..m.ncols() {
        for r in 0..m.nrows() {
            if m[(r, c)] != 0.0 && (!lower_only || r >= c) {
                t.push(Triplet::new(r, c, m[(r, c)]));
            }
        }
    }
    SparseColMat::try_new_from_triplets(m.nrows(), m.ncols(), &t).unwrap()
}

impl AdjointProblem for SpringFit {
    fn unknowns(&self) -> usize {
        self.n * self.loads.len()
    }

    fn linearization(
        &mut self,
        c: &[Real],
        mixed: MixedForm<'_>,
    ) -> Result<Linearization, FitError> {
        let (k, frames) = self.solve(c)?;
        let n = self.n;
        let mut residuals = Vec::new();
        let mut jacobian = Vec::new();
        let mut kq = DMatrix::zeros(self.unknowns(), n);
        for (f, (u, target)) in frames.iter().zip(&self.targets).enumerate() {
            for i in 0..n {
                jacobian.push((residuals.len(), Unknown::State(f * n + i), 1.0));
                residuals.push(u[i] - target[i]);
            }
            kq.view_mut((f * n, 0), (n, n)).copy_from(&self.mixed(u));
        }
        let hessian = sparse(&self.block_diagonal(&self.hessian(&k)), true);
        self.last = Some(k);
        let mixed = match mixed {
            MixedForm::Matrix => MixedDerivative::Matrix(sparse(&kq, false)),
            MixedForm::TimesParameterMap { rows, columns } => {
                let a = DMatrix::from_row_slice(n, columns, rows);
                MixedDerivative::TimesParameterMap((kq * a).as_slice().to_vec())
            }
        };
        Ok(Linearization {
            residuals,
            jacobian,
            hessian,
            mixed,
        })
    }

    fn solve_hessian(&mut self, rhs: &mut [Real], columns: usize) -> Result<(), FitError> {
        let k = self
            .last
            .as_ref()
            .ok_or(FitError("nothing linearized".into()))?;
        let h = self.block_diagonal(&self.hessian(k));
        let b = DMatrix::from_column_slice(h.nrows(), columns, rhs);
        let x = h.lu().solve(&b).ok_or(FitError("singular".into()))?;
        rhs.copy_from_slice(x.as_slice());
        Ok(())
    }
}

const N: usize = 4;

fn truth() -> Vec<Real> {
    vec![1.0, 2.0, 3.0, 4.0]
}

/// Gauss-Newton from 2 (200 N/m) on every spring, with `solver`: the stiffnesses found and the run.
fn fit_by_gauss_newton(solver: GaussNewtonSolver) -> (Vec<Real>, usize, OptimizerStop) {
    let a = DMatrix::identity(N, N) * 100.0;
    let mut fit = SpringFit::new(N, a.clone(), &truth());
    let map = parameter_map_matrix(N, N, |c| Ok(a.column(c).as_slice().to_vec())).unwrap();
    let mut problem = AdjointGaussNewton::new(&mut fit, map, solver);
    let mut values = Vec::new();
    let params = GaussNewtonParams {
        gradient_tolerance: 1e-14,
        max_iterations: 50,
        ..Default::default()
    };
    let out = gauss_newton(&mut problem, &[2.0; N], &params, |problem, it| {
        assert!(problem.problem().evaluations >= it.evaluations);
        values.push(it.value);
        ControlFlow::Continue(())
    })
    .unwrap();
    assert!(values.windows(2).all(|w| w[1] < w[0]), "{values:?}");
    (out.x, out.iterations, out.stop_reason)
}

#[test]
fn gauss_newton_fits_the_stiffnesses_through_either_direction() {
    let (kkt, iterations, stop) = fit_by_gauss_newton(GaussNewtonSolver::Kkt);
    for (k, t) in kkt.iter().zip(truth()) {
        assert!((k - t).abs() < 1e-6, "{kkt:?} ({stop:?})");
    }
    assert!(iterations < 30, "{iterations} iterations");
    let (reduced, _, _) = fit_by_gauss_newton(GaussNewtonSolver::Reduced);
    for (a, b) in kkt.iter().zip(&reduced) {
        assert!((a - b).abs() < 1e-9, "{kkt:?} vs {reduced:?}");
    }
}

#[test]
fn gauss_newton_fits_a_linear_profile_through_a_parameter_map() {
    // k_i = 100 (c₀ + c₁ i): the truth 1, 2, 3, 4 is c = (1, 1).
    let a = DMatrix::from_fn(N, 2, |i, j| 100.0 * if j == 0 { 1.0 } else { i as Real });
    let mut fit = SpringFit::new(N, a.clone(), &[1.0, 1.0]);
    let map = parameter_map_matrix(N, 2, |c| Ok(a.column(c).as_slice().to_vec())).unwrap();
    for solver in [GaussNewtonSolver::Kkt, GaussNewtonSolver::Reduced] {
        let mut problem = AdjointGaussNewton::new(&mut fit, map.clone(), solver);
        let params = GaussNewtonParams {
            gradient_tolerance: 1e-14,
            ..Default::default()
        };
        let out = gauss_newton(&mut problem, &[2.0, 0.5], &params, |_, _| {
            ControlFlow::Continue(())
        })
        .unwrap();
        assert!(
            (out.x[0] - 1.0).abs() < 1e-6 && (out.x[1] - 1.0).abs() < 1e-6,
            "{solver:?}: {:?}",
            out.x
        );
    }
}

#[test]
fn lbfgs_fits_the_stiffnesses() {
    let mut fit = SpringFit::new(N, DMatrix::identity(N, N) * 100.0, &truth());
    let params = LbfgsParams {
        gradient_tolerance: 1e-12,
        min_relative_decrease: 0.0,
        initial_step_length: 0.1,
        ..Default::default()
    };
    let mut seen = 0;
    let out = lbfgs(&mut fit, &[2.0; N], &params, |fit, it| {
        seen += 1;
        assert_eq!(fit.evaluations, it.evaluations);
        ControlFlow::Continue(())
    })
    .unwrap();
    assert!(out.value < 1e-16, "{out:?}");
    for (k, t) in out.x.iter().zip(truth()) {
        assert!((k - t).abs() < 1e-4, "{:?}", out.x);
    }
    assert_eq!(seen, out.iterations + 1);
}
