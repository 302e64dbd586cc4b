//! The global step of projective dynamics by Jacobi iteration instead of a factorization (the full-space
//! iteration of the knitwear paper Sec. 7.2 and Sec. 8, there on a GPU after a subspace solve; here alone,
//! to compare with [`super::GlobalStep`]'s direct solve). For `K X = B` of Eq. 27–28 (the same `K`, `B`),
//! with `D` the diagonal of `K`:
//!
//! ```text
//! plain:      X_{k+1} = X_k + D⁻¹ (B − K X_k)                                  (m)
//! Chebyshev:  X_{k+1} = ω_{k+1} (X_k + D⁻¹ (B − K X_k) − X_{k−1}) + X_{k−1},
//!             ω_1 = 1, ω_2 = 2 / (2 − ρ²), ω_{k+1} = 4 / (4 − ρ² ω_k)              (Wang 2015)
//! ```
//!
//! warm-started from the positions on entry (the previous PD iterate), for a fixed number of sweeps per
//! global step, with `ρ` the spectral radius of the Jacobi matrix `I − D⁻¹K`. `ρ` is estimated once by
//! power iteration on `D^{-1/2} K D^{-1/2}` (symmetric, so its extreme eigenvalues `μ` give
//! `ρ = max |1 − μ|`); plain Jacobi converges exactly when `ρ < 1`, which [`JacobiGlobalStep::new`]
//! checks. The three coordinates are independent systems and run on up to three threads.

use nalgebra::Matrix3;

use super::global_step::{GlobalStep, GlobalStepError};

/// Settings of [`JacobiGlobalStep`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JacobiParams {
    /// Jacobi sweeps per global step (at least 1).
    pub sweeps: usize,
    /// Chebyshev acceleration of the sweeps (with the estimated `ρ`).
    pub chebyshev: bool,
    /// Power iterations for the extreme eigenvalues of `D^{-1/2} K D^{-1/2}` (at least 10).
    pub power_iterations: usize,
    /// Threads for the three coordinate systems (1–3).
    pub threads: usize,
}

impl Default for JacobiParams {
    fn default() -> Self {
        Self {
            sweeps: 20,
            chebyshev: true,
            power_iterations: 200,
            threads: 2,
        }
    }
}

/// Why the Jacobi global step cannot be used.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum JacobiError {
    /// A setting out of range.
    #[error("Jacobi global step: {field} = {value} is out of range ({expected})")]
    Params {
        /// Which setting.
        field: &'static str,
        /// Its value.
        value: f64,
        /// What is allowed.
        expected: &'static str,
    },
    /// The Jacobi iteration does not converge on this matrix (`ρ ≥ 1`).
    #[error(
        "the Jacobi iteration does not converge on this global matrix (spectral radius {0:.6} ≥ 1); use the direct (Cholesky) global step"
    )]
    Diverges(f64),
    /// The inputs of the solve were refused.
    #[error(transparent)]
    Input(#[from] GlobalStepError),
}

/// `K` in full compressed rows (off-diagonal entries) and `D⁻¹`, with the estimated `ρ`.
#[derive(Clone, Debug)]
pub struct JacobiGlobalStep {
    row_ptr: Vec<usize>,
    col: Vec<usize>,
    val: Vec<f64>,
    inverse_diagonal: Vec<f64>,
    rho: f64,
    params: JacobiParams,
}

impl JacobiGlobalStep {
    /// The Jacobi iteration for `step`'s matrix.
    pub fn new(step: &GlobalStep, params: JacobiParams) -> Result<Self, JacobiError> {
        let bad = |field, value, expected| {
            Err(JacobiError::Params {
                field,
                value,
                expected,
            })
        };
        if params.sweeps == 0 {
            return bad("sweeps", 0.0, "at least 1");
        }
        if params.power_iterations < 10 {
            return bad(
                "power_iterations",
                params.power_iterations as f64,
                "at least 10",
            );
        }
        if !(1..=3).contains(&params.threads) {
            return bad("threads", params.threads as f64, "1 to 3");
        }
        let n = step.unknowns();
        let lower = step.lower();
        let mut diagonal = vec![0.0; n];
        let mut count = vec![0usize; n + 1];
        for c in 0..n {
            for k in lower.col_ptr[c]..lower.col_ptr[c + 1] {
                let r = lower.row_idx[k];
                if r == c {
                    diagonal[c] += lower.values[k];
                } else {
                    count[r + 1] += 1;
                    count[c + 1] += 1;
                }
            }
        }
        for i in 0..n {
            count[i + 1] += count[i];
        }
        let row_ptr = count.clone();
        let mut next = count;
        let mut col = vec![0; row_ptr[n]];
        let mut val = vec![0.0; row_ptr[n]];
        for c in 0..n {
            for k in lower.col_ptr[c]..lower.col_ptr[c + 1] {
                let r = lower.row_idx[k];
                if r != c {
                    for (a, b) in [(r, c), (c, r)] {
                        col[next[a]] = b;
                        val[next[a]] = lower.values[k];
                        next[a] += 1;
                    }
                }
            }
        }
        let inverse_diagonal: Vec<f64> = diagonal.iter().map(|d| 1.0 / d).collect();
        let mut out = Self {
            row_ptr,
            col,
            val,
            inverse_diagonal,
            rho: 0.0,
            params,
        };
        out.rho = out.spectral_radius_estimate();
        if out.rho.is_nan() || out.rho >= 1.0 {
            return Err(JacobiError::Diverges(out.rho));
        }
        Ok(out)
    }

    /// The estimated spectral radius `ρ` of `I − D⁻¹K` (dimensionless).
    pub fn spectral_radius(&self) -> f64 {
        self.rho
    }

    /// `S = D^{-1/2} K D^{-1/2}` times `z` (`S_ii = 1`).
    fn scaled_product(&self, z: &[f64], out: &mut [f64]) {
        for (i, o) in out.iter_mut().enumerate() {
            let si = self.inverse_diagonal[i].sqrt();
            let mut s = z[i];
            for k in self.row_ptr[i]..self.row_ptr[i + 1] {
                let j = self.col[k];
                s += si * self.val[k] * self.inverse_diagonal[j].sqrt() * z[j];
            }
            *o = s;
        }
    }

    /// Power iteration for the largest eigenvalue `μ_max` of `S`, then for the largest of `μ_max I − S`
    /// (giving `μ_min`); `ρ = max(|1 − μ_min|, |1 − μ_max|)`.
    fn spectral_radius_estimate(&self) -> f64 {
        let n = self.inverse_diagonal.len();
        if n == 0 {
            return 0.0;
        }
        // The largest eigenvalue of `shift I − S` (of `S` for `shift = None`), by its Rayleigh quotient.
        let power = |shift: Option<f64>| -> f64 {
            // A fixed start with no symmetry, so no eigenvector is missed.
            let mut z: Vec<f64> = (0..n)
                .map(|i| 1.0 + ((i * 7919) % 113) as f64 / 113.0)
                .collect();
            let mut w = vec![0.0; n];
            let mut lambda = 0.0;
            for _ in 0..self.params.power_iterations {
                let norm = z.iter().map(|v| v * v).sum::<f64>().sqrt();
                if norm == 0.0 || !norm.is_finite() {
                    return lambda;
                }
                z.iter_mut().for_each(|v| *v /= norm);
                self.scaled_product(&z, &mut w);
                if let Some(s) = shift {
                    for (wi, zi) in w.iter_mut().zip(&z) {
                        *wi = s * zi - *wi;
                    }
                }
                lambda = w.iter().zip(&z).map(|(a, b)| a * b).sum::<f64>();
                std::mem::swap(&mut z, &mut w);
            }
            lambda
        };
        let mu_max = power(None);
        let mu_min = mu_max - power(Some(mu_max));
        (1.0 - mu_min).abs().max((1.0 - mu_max).abs())
    }

    /// Overwrites the free nodes of `x` (`#V × 3`, m) with the result of the configured sweeps on
    /// `step`'s system for the same inputs as [`GlobalStep::solve`], starting from `x`.
    pub fn solve(
        &self,
        step: &GlobalStep,
        y: &[[f64; 3]],
        forces: &[[f64; 3]],
        targets: &[Matrix3<f64>],
        points: &[[f64; 3]],
        x: &mut [[f64; 3]],
    ) -> Result<(), JacobiError> {
        step.check(y, forces, targets, points, x)?;
        let n = step.unknowns();
        let b = step.right_hand_side(y, forces, targets, points, x);
        let mut z = step.gather(x);
        let solve_one = |b: &[f64], z: &mut [f64]| self.sweeps(b, z);
        if self.params.threads == 1 || n < 64 {
            for (bc, zc) in b.chunks(n.max(1)).zip(z.chunks_mut(n.max(1))) {
                solve_one(bc, zc);
            }
        } else {
            let per = 3usize.div_ceil(self.params.threads);
            std::thread::scope(|scope| {
                for (bs, zs) in b.chunks(per * n).zip(z.chunks_mut(per * n)) {
                    let solve_one = &solve_one;
                    scope.spawn(move || {
                        for (bc, zc) in bs.chunks(n).zip(zs.chunks_mut(n)) {
                            solve_one(bc, zc);
                        }
                    });
                }
            });
        }
        step.scatter(&z, x);
        Ok(())
    }

    /// The sweeps on one coordinate's system `K z = b`, `z` warm on entry.
    fn sweeps(&self, b: &[f64], z: &mut [f64]) {
        let n = z.len();
        let mut previous = z.to_vec();
        let mut next = vec![0.0; n];
        let rho2 = self.rho * self.rho;
        let mut omega = 1.0;
        for k in 0..self.params.sweeps {
            for i in 0..n {
                let mut r = b[i];
                for j in self.row_ptr[i]..self.row_ptr[i + 1] {
                    r -= self.val[j] * z[self.col[j]];
                }
                next[i] = r * self.inverse_diagonal[i];
            }
            if self.params.chebyshev {
                omega = match k {
                    0 => 1.0,
                    1 => 2.0 / (2.0 - rho2),
                    _ => 4.0 / (4.0 - rho2 * omega),
                };
                for i in 0..n {
                    next[i] = omega * (next[i] - previous[i]) + previous[i];
                }
            }
            // previous ← z, z ← next.
            previous.copy_from_slice(z);
            z.copy_from_slice(&next);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::knit_material::test_states::{block_mesh, rng};
    use rand::Rng;

    /// A step with its inputs: the step, `y`, the forces, the targets and a start `x`.
    type Setup = (
        GlobalStep,
        Vec<[f64; 3]>,
        Vec<[f64; 3]>,
        Vec<Matrix3<f64>>,
        Vec<[f64; 3]>,
    );

    fn setup() -> Setup {
        let mut mesh = block_mesh(4, 3, 2, 0.01);
        mesh.node_mass = vec![1e-3; mesh.rest.len()];
        let mut rng = rng(23);
        let weights: Vec<f64> = (0..mesh.tets.len())
            .map(|_| rng.random_range(0.1..1.0) * 1e-2)
            .collect();
        let step = GlobalStep::new(&mesh, &weights, &[0, 1, 2], 1.0 / 150.0).unwrap();
        let jitter = |p: &[f64; 3], rng: &mut rand_chacha::ChaCha8Rng| {
            p.map(|v| v + rng.random_range(-0.002..0.002))
        };
        let y: Vec<[f64; 3]> = mesh.rest.iter().map(|p| jitter(p, &mut rng)).collect();
        let forces = vec![[0.0, -9.81e-3, 0.0]; y.len()];
        let targets: Vec<Matrix3<f64>> = (0..mesh.tets.len())
            .map(|_| Matrix3::identity() + Matrix3::from_fn(|_, _| rng.random_range(-0.2..0.2)))
            .collect();
        let x0: Vec<[f64; 3]> = mesh.rest.iter().map(|p| jitter(p, &mut rng)).collect();
        (step, y, forces, targets, x0)
    }

    fn error(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
        a.iter()
            .flatten()
            .zip(b.iter().flatten())
            .fold(0.0, |m, (p, q)| m.max((p - q).abs()))
    }

    #[test]
    fn the_sweeps_converge_to_the_direct_solve_and_chebyshev_is_faster() {
        let (step, y, forces, targets, x0) = setup();
        let mut direct = x0.clone();
        step.solve(&y, &forces, &targets, &[], &mut direct).unwrap();
        let start = error(&x0, &direct);
        let mut errors = Vec::new();
        for chebyshev in [false, true] {
            let params = JacobiParams {
                sweeps: 40,
                chebyshev,
                ..Default::default()
            };
            let jacobi = JacobiGlobalStep::new(&step, params).unwrap();
            let rho = jacobi.spectral_radius();
            assert!(rho > 0.5 && rho < 1.0, "ρ = {rho}");
            let mut x = x0.clone();
            jacobi
                .solve(&step, &y, &forces, &targets, &[], &mut x)
                .unwrap();
            // The clamped nodes stay; the free ones approach the direct solution.
            for c in 0..3 {
                assert_eq!(x[c], x0[c]);
            }
            errors.push(error(&x, &direct));
            // Many more sweeps: the direct solution to round-off.
            let long = JacobiGlobalStep::new(
                &step,
                JacobiParams {
                    sweeps: if chebyshev { 2000 } else { 20000 },
                    threads: 1,
                    ..params
                },
            )
            .unwrap();
            let mut x = x0.clone();
            long.solve(&step, &y, &forces, &targets, &[], &mut x)
                .unwrap();
            assert!(error(&x, &direct) < 1e-10 * start, "chebyshev {chebyshev}");
        }
        assert!(
            errors[0] < start && errors[1] < 0.1 * errors[0],
            "{errors:?} from {start}"
        );
    }

    #[test]
    fn bad_settings_are_refused_by_name() {
        let (step, y, forces, targets, x0) = setup();
        let d = JacobiParams::default();
        for (p, field) in [
            (JacobiParams { sweeps: 0, ..d }, "sweeps"),
            (
                JacobiParams {
                    power_iterations: 3,
                    ..d
                },
                "power_iterations",
            ),
            (JacobiParams { threads: 0, ..d }, "threads"),
            (JacobiParams { threads: 4, ..d }, "threads"),
        ] {
            match JacobiGlobalStep::new(&step, p) {
                Err(JacobiError::Params { field: f, .. }) => assert_eq!(f, field),
                other => panic!("{field}: {other:?}"),
            }
        }
        let jacobi = JacobiGlobalStep::new(&step, d).unwrap();
        let mut x = x0.clone();
        assert!(matches!(
            jacobi.solve(&step, &y[1..], &forces, &targets, &[], &mut x),
            Err(JacobiError::Input(GlobalStepError::Length { .. }))
        ));
    }
}
