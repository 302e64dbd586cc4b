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

    /// `1 / self`.
    pub fn recip(self) -> Self {
        let inv = 1.0 / self.v;
        unary(&self, inv, -inv * inv, 2.0 * inv * inv * inv)
    }
}

/// Defines a jet kernel three times — compiled for the baseline target, for AVX2 and for AVX-512F — and
/// `$name`, which runs the widest the CPU has (detected at run time; the detection is cached by `std`).
///
/// Why: the second-order jets of the rod vertices are a sixth of a yarn patch's Newton iteration
/// (docs/BENCHMARKS.md), their loops over the `N × N` Hessian are element-wise, and the default
/// `x86_64` target only vectorizes them two doubles wide. The three versions compute the same IEEE
/// operations in the same order (element-wise, no reductions, no fused multiply–add: Rust never contracts
/// `a * b + c`), so their results are identical bit for bit — `tests::every_kernel_gives_the_scalar_bits`
/// checks it on the machine that runs the tests.
macro_rules! jet_kernel {
    ($(#[$meta:meta])* fn $name:ident<const N: usize>($($arg:ident: $ty:ty),*) -> $ret:ty $body:block) => {
        $(#[$meta])*
        fn $name<const N: usize>($($arg: $ty),*) -> $ret {
            #[inline(always)]
            fn kernel<const N: usize>($($arg: $ty),*) -> $ret $body
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx512f")]
                fn avx512<const N: usize>($($arg: $ty),*) -> $ret {
                    kernel($($arg),*)
                }
                #[target_feature(enable = "avx2")]
                fn avx2<const N: usize>($($arg: $ty),*) -> $ret {
                    kernel($($arg),*)
                }
                if std::arch::is_x86_feature_detected!("avx512f") {
                    // SAFETY: the CPU has AVX-512F (detected just above), the only requirement of `avx512`.
                    return unsafe { avx512($($arg),*) };
                }
                if std::arch::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU has AVX2 (detected just above), the only requirement of `avx2`.
                    return unsafe { avx2($($arg),*) };
                }
            }
            kernel($($arg),*)
        }
    };
}

jet_kernel! {
    /// `f(a)` from `f = f(a.v)`, `df = f'(a.v)` and `ddf = f''(a.v)`: `∇f = f'∇a`, `∇²f = f'∇²a + f''∇a∇aᵀ`.
    fn unary<const N: usize>(a: &Jet<N>, f: f64, df: f64, ddf: f64) -> Jet<N> {
        let mut r = Jet::cst(f);
        for i in 0..N {
            r.g[i] = df * a.g[i];
            for j in 0..N {
                r.h[i][j] = df * a.h[i][j] + ddf * a.g[i] * a.g[j];
            }
        }
        r
    }
}

jet_kernel! {
    /// `atan2(y, x)` from the partial derivatives of `atan2` at `(y.v, x.v)`.
    fn atan2<const N: usize>(y: &Jet<N>, x: &Jet<N>) -> Jet<N> {
        // θ = atan2(y, x): θ_y = x/ρ², θ_x = −y/ρ², θ_yy = −2xy/ρ⁴, θ_xx = 2xy/ρ⁴, θ_xy = (y² − x²)/ρ⁴.
        let (yv, xv) = (y.v, x.v);
        let r2 = xv * xv + yv * yv;
        let r4 = r2 * r2;
        let (fy, fx) = (xv / r2, -yv / r2);
        let (fyy, fxx, fxy) = (
            -2.0 * xv * yv / r4,
            2.0 * xv * yv / r4,
            (yv * yv - xv * xv) / r4,
        );
        let mut r = Jet::cst(yv.atan2(xv));
        for i in 0..N {
            r.g[i] = fy * y.g[i] + fx * x.g[i];
            for j in 0..N {
                r.h[i][j] = fy * y.h[i][j]
                    + fx * x.h[i][j]
                    + fyy * y.g[i] * y.g[j]
                    + fxx * x.g[i] * x.g[j]
                    + fxy * (y.g[i] * x.g[j] + x.g[i] * y.g[j]);
            }
        }
        r
    }
}

jet_kernel! {
    /// `a + b`.
    fn add<const N: usize>(a: &Jet<N>, b: &Jet<N>) -> Jet<N> {
        let mut r = *a;
        r.v += b.v;
        for i in 0..N {
            r.g[i] += b.g[i];
            for j in 0..N {
                r.h[i][j] += b.h[i][j];
            }
        }
        r
    }
}

jet_kernel! {
    /// `a − b` (the same bits as `a + (−b)`: IEEE subtraction is the addition of the negation).
    fn sub<const N: usize>(a: &Jet<N>, b: &Jet<N>) -> Jet<N> {
        let mut r = *a;
        r.v -= b.v;
        for i in 0..N {
            r.g[i] -= b.g[i];
            for j in 0..N {
                r.h[i][j] -= b.h[i][j];
            }
        }
        r
    }
}

jet_kernel! {
    /// `a · b`: `∇(ab) = a∇b + b∇a`, `∇²(ab) = a∇²b + b∇²a + ∇a∇bᵀ + ∇b∇aᵀ`.
    fn mul<const N: usize>(a: &Jet<N>, b: &Jet<N>) -> Jet<N> {
        let mut r = Jet::cst(a.v * b.v);
        for i in 0..N {
            r.g[i] = a.v * b.g[i] + b.v * a.g[i];
            for j in 0..N {
                r.h[i][j] = a.v * b.h[i][j] + b.v * a.h[i][j] + a.g[i] * b.g[j] + b.g[i] * a.g[j];
            }
        }
        r
    }
}

jet_kernel! {
    /// `a · s` for a constant `s`.
    fn scale<const N: usize>(a: &Jet<N>, s: f64) -> Jet<N> {
        let mut r = *a;
        r.v *= s;
        for i in 0..N {
            r.g[i] *= s;
            for j in 0..N {
                r.h[i][j] *= s;
            }
        }
        r
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
        unary(&self, s, 0.5 / s, -0.25 / (s * self.v))
    }
    fn atan2(self, x: Self) -> Self {
        atan2(&self, &x)
    }
}

impl<const N: usize> Add for Jet<N> {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        add(&self, &o)
    }
}

impl<const N: usize> AddAssign for Jet<N> {
    fn add_assign(&mut self, o: Self) {
        *self = add(self, &o);
    }
}

impl<const N: usize> Sub for Jet<N> {
    type Output = Self;
    fn sub(self, o: Self) -> Self {
        sub(&self, &o)
    }
}

impl<const N: usize> Neg for Jet<N> {
    type Output = Self;
    fn neg(self) -> Self {
        scale(&self, -1.0)
    }
}

impl<const N: usize> Mul for Jet<N> {
    type Output = Self;
    fn mul(self, o: Self) -> Self {
        mul(&self, &o)
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
    fn mul(self, o: f64) -> Self {
        scale(&self, o)
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

    /// The kernels run at the widest instruction set the CPU has ([`jet_kernel`]); each must give exactly
    /// the bits of the same formula evaluated as scalar code (compiled for the baseline target here), on
    /// random jets of the rod vertices' size. A kernel that summed in another order, or fused a multiply
    /// and an add, would differ in the last bits of some of the 2 × 73 × 200 numbers compared.
    #[test]
    fn every_kernel_gives_the_scalar_bits() {
        use rand::{Rng, SeedableRng};
        const N: usize = 8;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(19);
        let jet = |rng: &mut rand_chacha::ChaCha8Rng| Jet::<N> {
            v: rng.random_range(0.1..2.0),
            g: std::array::from_fn(|_| rng.random_range(-1.0..1.0)),
            h: std::array::from_fn(|_| std::array::from_fn(|_| rng.random_range(-1.0..1.0))),
        };
        let same = |what: &str,
                    r: Jet<N>,
                    v: f64,
                    g: &dyn Fn(usize) -> f64,
                    h: &dyn Fn(usize, usize) -> f64| {
            assert_eq!(r.v.to_bits(), v.to_bits(), "{what}: value");
            for i in 0..N {
                assert_eq!(r.g[i].to_bits(), g(i).to_bits(), "{what}: g[{i}]");
                for j in 0..N {
                    assert_eq!(
                        r.h[i][j].to_bits(),
                        h(i, j).to_bits(),
                        "{what}: h[{i}][{j}]"
                    );
                }
            }
        };
        for _ in 0..100 {
            let (a, b) = (jet(&mut rng), jet(&mut rng));
            let s: f64 = rng.random_range(-3.0..3.0);
            same(
                "a·b",
                a * b,
                a.v * b.v,
                &|i| a.v * b.g[i] + b.v * a.g[i],
                &|i, j| a.v * b.h[i][j] + b.v * a.h[i][j] + a.g[i] * b.g[j] + b.g[i] * a.g[j],
            );
            same("a+b", a + b, a.v + b.v, &|i| a.g[i] + b.g[i], &|i, j| {
                a.h[i][j] + b.h[i][j]
            });
            same("a−b", a - b, a.v - b.v, &|i| a.g[i] - b.g[i], &|i, j| {
                a.h[i][j] - b.h[i][j]
            });
            same("−a", -a, -a.v, &|i| -a.g[i], &|i, j| -a.h[i][j]);
            same("a·s", a * s, a.v * s, &|i| a.g[i] * s, &|i, j| {
                a.h[i][j] * s
            });
            let r = a.v.sqrt();
            let (df, ddf) = (0.5 / r, -0.25 / (r * a.v));
            same("√a", a.sqrt(), r, &|i| df * a.g[i], &|i, j| {
                df * a.h[i][j] + ddf * a.g[i] * a.g[j]
            });
            let (y, x) = (a.v, b.v - 1.0);
            let xj = b - 1.0;
            let (r2, xy) = (x * x + y * y, x * y);
            let r4 = r2 * r2;
            let (fy, fx, fyy, fxx, fxy) = (
                x / r2,
                -y / r2,
                -2.0 * xy / r4,
                2.0 * xy / r4,
                (y * y - x * x) / r4,
            );
            same(
                "atan2",
                a.atan2(xj),
                y.atan2(x),
                &|i| fy * a.g[i] + fx * xj.g[i],
                &|i, j| {
                    fy * a.h[i][j]
                        + fx * xj.h[i][j]
                        + fyy * a.g[i] * a.g[j]
                        + fxx * xj.g[i] * xj.g[j]
                        + fxy * (a.g[i] * xj.g[j] + xj.g[i] * a.g[j])
                },
            );
        }
    }
}
