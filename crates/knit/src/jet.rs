//! Second-order forward-mode automatic differentiation: [`Jet<N>`] carries a value with its gradient and
//! Hessian with respect to `N` independent variables, and the [`Scalar`] trait lets one energy function be
//! evaluated on plain `f64` (the value) or on jets (value, exact gradient and Hessian).
//!
//! The rules are the chain rule to second order: for `c = a·b`, `∇c = a∇b + b∇a` and
//! `∇²c = a∇²b + b∇²a + ∇a∇bᵀ + ∇b∇aᵀ`; for `c = f(a)`, `∇c = f'∇a` and `∇²c = f'∇²a + f''∇a∇aᵀ`; for
//! `c = atan2(y, x)` the two-argument form with the partial derivatives of `atan2`. Results are exact up to
//! rounding (no truncation error), which the finite-difference tests of every energy check.

use std::ops::{Add, AddAssign, Div, Mul, Neg, Sub};

/// Arithmetic that both `f64` and [`Jet`] provide; energy stencils are written once over it.
pub trait Scalar:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + Add<f64, Output = Self>
    + Sub<f64, Output = Self>
    + Mul<f64, Output = Self>
{
    /// A constant (zero derivatives).
    fn cst(v: f64) -> Self;
    /// The value without derivatives.
    fn value(&self) -> f64;
    /// Square root (the argument must be positive).
    fn sqrt(self) -> Self;
    /// `atan2(self, x)`, the angle of the point `(x, self)`.
    fn atan2(self, x: Self) -> Self;
    /// `self²`.
    fn square(self) -> Self {
        self * self
    }
}

impl Scalar for f64 {
    fn cst(v: f64) -> Self {
        v
    }
    fn value(&self) -> f64 {
        *self
    }
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    fn atan2(self, x: Self) -> Self {
        f64::atan2(self, x)
    }
}

/// A value with its gradient and (symmetric) Hessian with respect to `N` variables.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Jet<const N: usize> {
    /// The value.
    pub v: f64,
    /// The gradient.
    pub g: [f64; N],
    /// The Hessian (row-major, symmetric).
    pub h: [[f64; N]; N],
}

impl<const N: usize> Jet<N> {
    /// The variable number `i` with value `v`.
    pub fn var(v: f64, i: usize) -> Self {
        let mut j = Self::cst(v);
        j.g[i] = 1.0;
        j
    }

    /// `f(self)` from `f`, `f'` and `f''` at `self.v`.
    fn unary(self, f: f64, df: f64, ddf: f64) -> Self {
        let mut r = Self {
            v: f,
            g: [0.0; N],
            h: [[0.0; N]; N],
        };
        for i in 0..N {
            r.g[i] = df * self.g[i];
            for j in 0..N {
                r.h[i][j] = df * self.h[i][j] + ddf * self.g[i] * self.g[j];
            }
        }
        r
    }

    /// `1 / self`.
    pub fn recip(self) -> Self {
        let inv = 1.0 / self.v;
        self.unary(inv, -inv * inv, 2.0 * inv * inv * inv)
    }
}

impl<const N: usize> Scalar for Jet<N> {
    fn cst(v: f64) -> Self {
        Self {
            v,
            g: [0.0; N],
            h: [[0.0; N]; N],
        }
    }
    fn value(&self) -> f64 {
        self.v
    }
    fn sqrt(self) -> Self {
        let s = self.v.sqrt();
        self.unary(s, 0.5 / s, -0.25 / (s * self.v))
    }
    fn atan2(self, x: Self) -> Self {
        // θ = atan2(y, x): θ_y = x/ρ², θ_x = −y/ρ², θ_yy = −2xy/ρ⁴, θ_xx = 2xy/ρ⁴, θ_xy = (y² − x²)/ρ⁴.
        let (y, xv) = (self.v, x.v);
        let r2 = xv * xv + y * y;
        let r4 = r2 * r2;
        let (fy, fx) = (xv / r2, -y / r2);
        let (fyy, fxx, fxy) = (
            -2.0 * xv * y / r4,
            2.0 * xv * y / r4,
            (y * y - xv * xv) / r4,
        );
        let mut r = Self::cst(y.atan2(xv));
        for i in 0..N {
            r.g[i] = fy * self.g[i] + fx * x.g[i];
            for j in 0..N {
                r.h[i][j] = fy * self.h[i][j]
                    + fx * x.h[i][j]
                    + fyy * self.g[i] * self.g[j]
                    + fxx * x.g[i] * x.g[j]
                    + fxy * (self.g[i] * x.g[j] + x.g[i] * self.g[j]);
            }
        }
        r
    }
}

impl<const N: usize> Add for Jet<N> {
    type Output = Self;
    fn add(mut self, o: Self) -> Self {
        self.v += o.v;
        for i in 0..N {
            self.g[i] += o.g[i];
            for j in 0..N {
                self.h[i][j] += o.h[i][j];
            }
        }
        self
    }
}

impl<const N: usize> AddAssign for Jet<N> {
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}

impl<const N: usize> Sub for Jet<N> {
    type Output = Self;
    fn sub(self, o: Self) -> Self {
        self + (-o)
    }
}

impl<const N: usize> Neg for Jet<N> {
    type Output = Self;
    fn neg(mut self) -> Self {
        self.v = -self.v;
        for i in 0..N {
            self.g[i] = -self.g[i];
            for j in 0..N {
                self.h[i][j] = -self.h[i][j];
            }
        }
        self
    }
}

impl<const N: usize> Mul for Jet<N> {
    type Output = Self;
    fn mul(self, o: Self) -> Self {
        let mut r = Self::cst(self.v * o.v);
        for i in 0..N {
            r.g[i] = self.v * o.g[i] + o.v * self.g[i];
            for j in 0..N {
                r.h[i][j] = self.v * o.h[i][j]
                    + o.v * self.h[i][j]
                    + self.g[i] * o.g[j]
                    + o.g[i] * self.g[j];
            }
        }
        r
    }
}

impl<const N: usize> Div for Jet<N> {
    type Output = Self;
    #[allow(clippy::suspicious_arithmetic_impl)]
    fn div(self, o: Self) -> Self {
        self * o.recip()
    }
}

impl<const N: usize> Add<f64> for Jet<N> {
    type Output = Self;
    fn add(mut self, o: f64) -> Self {
        self.v += o;
        self
    }
}

impl<const N: usize> Sub<f64> for Jet<N> {
    type Output = Self;
    fn sub(mut self, o: f64) -> Self {
        self.v -= o;
        self
    }
}

impl<const N: usize> Mul<f64> for Jet<N> {
    type Output = Self;
    fn mul(mut self, o: f64) -> Self {
        self.v *= o;
        for i in 0..N {
            self.g[i] *= o;
            for j in 0..N {
                self.h[i][j] *= o;
            }
        }
        self
    }
}

/// Evaluates `f` on jets seeded with `x` and returns (value, gradient, Hessian).
pub fn value_gradient_hessian<const N: usize>(
    x: &[f64; N],
    f: impl Fn(&[Jet<N>; N]) -> Jet<N>,
) -> (f64, [f64; N], [[f64; N]; N]) {
    let vars: [Jet<N>; N] = std::array::from_fn(|i| Jet::var(x[i], i));
    let r = f(&vars);
    (r.v, r.g, r.h)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jets_differentiate_a_composite_function_exactly() {
        // f(x, y) = atan2(y, x) · sqrt(x² + y²) / (1 + x y): compare with central differences.
        let f = |v: &[f64; 2]| -> f64 {
            v[1].atan2(v[0]) * (v[0] * v[0] + v[1] * v[1]).sqrt() / (1.0 + v[0] * v[1])
        };
        let fj = |v: &[Jet<2>; 2]| -> Jet<2> {
            v[1].atan2(v[0]) * (v[0] * v[0] + v[1] * v[1]).sqrt() / (v[0] * v[1] + 1.0)
        };
        let x = [0.7, -0.4];
        let (val, g, h) = value_gradient_hessian(&x, fj);
        assert!((val - f(&x)).abs() < 1e-14);
        let eps = 1e-5;
        for i in 0..2 {
            let mut xp = x;
            let mut xm = x;
            xp[i] += eps;
            xm[i] -= eps;
            let fd = (f(&xp) - f(&xm)) / (2.0 * eps);
            assert!((fd - g[i]).abs() < 1e-8, "g[{i}] {} vs {fd}", g[i]);
            let (_, gp, _) = value_gradient_hessian(&xp, fj);
            let (_, gm, _) = value_gradient_hessian(&xm, fj);
            for j in 0..2 {
                let fdh = (gp[j] - gm[j]) / (2.0 * eps);
                assert!(
                    (fdh - h[j][i]).abs() < 1e-7,
                    "h[{j}][{i}] {} vs {fdh}",
                    h[j][i]
                );
            }
        }
        assert_eq!(h[0][1], h[1][0]);
    }
}
