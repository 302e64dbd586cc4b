//! Central finite-difference checks of derivatives, shared by every energy, objective and map.
//!
//! Each check compares an analytic derivative with a central difference `(f(x + h d) − f(x − h d)) / 2h`
//! and passes when `|analytic − numeric| ≤ abs_tol + rel_tol · scale`, where `scale` is the larger of the
//! two magnitudes (the largest entry magnitude for vectors). Tolerances are relative so that one setting
//! serves quantities of any unit and size.

use crate::math::Real;

/// Settings of a finite-difference check.
#[derive(Clone, Copy, Debug)]
pub struct FdParams {
    /// Step size `h`, relative to `max(1, |x|∞)`.
    pub step: Real,
    /// Relative tolerance.
    pub rel_tol: Real,
    /// Absolute tolerance (in the units of the derivative).
    pub abs_tol: Real,
}

impl Default for FdParams {
    fn default() -> Self {
        Self {
            step: 1e-6,
            rel_tol: 1e-5,
            abs_tol: 1e-9,
        }
    }
}

/// A failed comparison: where, the analytic and numeric values.
#[derive(Clone, Debug, PartialEq)]
pub struct FdMismatch {
    /// Which derivative: the coordinate (gradient), `(row, column)` flattened as `row * n + col` (Jacobian),
    /// or the direction index (directional checks).
    pub index: usize,
    /// Analytic value.
    pub analytic: Real,
    /// Central-difference value.
    pub numeric: Real,
}

impl std::fmt::Display for FdMismatch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "derivative {}: analytic {:.9e} vs central difference {:.9e} (difference {:.3e})",
            self.index,
            self.analytic,
            self.numeric,
            self.analytic - self.numeric
        )
    }
}

fn step_size(x: &[Real], params: &FdParams) -> Real {
    let scale = x.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
    params.step * scale
}

fn within(analytic: Real, numeric: Real, scale: Real, params: &FdParams) -> bool {
    let diff = (analytic - numeric).abs();
    diff.is_finite() && diff <= params.abs_tol + params.rel_tol * scale
}

/// Checks `grad` (the analytic gradient of `f` at `x`) coordinate by coordinate.
/// Tolerances scale with the largest gradient entry.
pub fn check_gradient(
    f: impl Fn(&[Real]) -> Real,
    x: &[Real],
    grad: &[Real],
    params: &FdParams,
) -> Result<(), FdMismatch> {
    assert_eq!(x.len(), grad.len(), "gradient length must match the point");
    let h = step_size(x, params);
    let numeric: Vec<Real> = (0..x.len())
        .map(|i| {
            let mut xp = x.to_vec();
            let mut xm = x.to_vec();
            xp[i] += h;
            xm[i] -= h;
            (f(&xp) - f(&xm)) / (2.0 * h)
        })
        .collect();
    let scale = grad
        .iter()
        .chain(&numeric)
        .fold(0.0_f64, |m, v| m.max(v.abs()));
    for i in 0..x.len() {
        if !within(grad[i], numeric[i], scale, params) {
            return Err(FdMismatch {
                index: i,
                analytic: grad[i],
                numeric: numeric[i],
            });
        }
    }
    Ok(())
}

/// Checks the `m × n` Jacobian `jac` (row-major, `jac[r * n + c] = ∂g_r/∂x_c`) of `g: ℝⁿ → ℝᵐ` at `x`,
/// column by column. A Hessian is the Jacobian of a gradient. Tolerances scale with the largest entry.
pub fn check_jacobian(
    g: impl Fn(&[Real]) -> Vec<Real>,
    x: &[Real],
    jac: &[Real],
    params: &FdParams,
) -> Result<(), FdMismatch> {
    let n = x.len();
    assert!(
        n > 0 && jac.len() % n == 0,
        "Jacobian size must be a multiple of the point size"
    );
    let m = jac.len() / n;
    let h = step_size(x, params);
    let mut numeric = vec![0.0; m * n];
    for c in 0..n {
        let mut xp = x.to_vec();
        let mut xm = x.to_vec();
        xp[c] += h;
        xm[c] -= h;
        let (gp, gm) = (g(&xp), g(&xm));
        assert_eq!(
            gp.len(),
            m,
            "function output length must match the Jacobian's rows"
        );
        for r in 0..m {
            numeric[r * n + c] = (gp[r] - gm[r]) / (2.0 * h);
        }
    }
    let scale = jac
        .iter()
        .chain(&numeric)
        .fold(0.0_f64, |s, v| s.max(v.abs()));
    for k in 0..m * n {
        if !within(jac[k], numeric[k], scale, params) {
            return Err(FdMismatch {
                index: k,
                analytic: jac[k],
                numeric: numeric[k],
            });
        }
    }
    Ok(())
}

/// Checks one directional derivative: `analytic` should equal `d/dε f(x + ε d)` at `ε = 0`.
/// For large systems (a whole simulation) where coordinate-wise checks are too expensive. Here `h` is
/// absolute (along the direction `d`) and the tolerance scales with the larger of the two values.
pub fn check_directional(
    f: impl Fn(&[Real]) -> Real,
    x: &[Real],
    d: &[Real],
    analytic: Real,
    params: &FdParams,
) -> Result<(), FdMismatch> {
    assert_eq!(x.len(), d.len(), "direction length must match the point");
    let h = params.step;
    let at = |t: Real| -> Real {
        let xs: Vec<Real> = x.iter().zip(d).map(|(a, b)| a + t * b).collect();
        f(&xs)
    };
    let numeric = (at(h) - at(-h)) / (2.0 * h);
    let scale = analytic.abs().max(numeric.abs());
    if within(analytic, numeric, scale, params) {
        Ok(())
    } else {
        Err(FdMismatch {
            index: 0,
            analytic,
            numeric,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn f(x: &[Real]) -> Real {
        x[0] * x[0] * x[1] + x[1].sin() * x[2] + x[2].powi(3)
    }

    fn grad(x: &[Real]) -> Vec<Real> {
        vec![
            2.0 * x[0] * x[1],
            x[0] * x[0] + x[1].cos() * x[2],
            x[1].sin() + 3.0 * x[2] * x[2],
        ]
    }

    fn hess(x: &[Real]) -> Vec<Real> {
        vec![
            2.0 * x[1],
            2.0 * x[0],
            0.0,
            2.0 * x[0],
            -x[1].sin() * x[2],
            x[1].cos(),
            0.0,
            x[1].cos(),
            6.0 * x[2],
        ]
    }

    #[test]
    fn correct_derivatives_pass() {
        let x = [0.3, -1.2, 0.7];
        let p = FdParams::default();
        check_gradient(f, &x, &grad(&x), &p).unwrap();
        check_jacobian(grad, &x, &hess(&x), &p).unwrap();
        let d = [0.1, 0.2, -0.3];
        let dd: Real = grad(&x).iter().zip(&d).map(|(a, b)| a * b).sum();
        check_directional(f, &x, &d, dd, &p).unwrap();
    }

    #[test]
    fn wrong_derivatives_fail() {
        let x = [0.3, -1.2, 0.7];
        let p = FdParams::default();
        let mut g = grad(&x);
        g[1] *= 1.001;
        assert_eq!(check_gradient(f, &x, &g, &p).unwrap_err().index, 1);
        let mut h = hess(&x);
        h[5] += 1e-3;
        assert!(check_jacobian(grad, &x, &h, &p).is_err());
        assert!(check_directional(f, &x, &[1.0, 0.0, 0.0], 0.0, &p).is_err());
    }
}
