//! Forward-mode automatic differentiation with `N` directional derivatives, for the per-triangle
//! geometry of the mid-edge shape operator and the Young–Laplace pressure (a handful of variables per
//! triangle: its corners, the opposite vertices of its neighbours, its pattern corners).
//!
//! A [`Dual`] carries a value `v` and its gradient `d` (`N` entries) with respect to the chosen local
//! variables; arithmetic applies the chain rule. Only what those modules need is implemented.

use crate::math::Real;
use std::ops::{Add, Div, Mul, Neg, Sub};

/// A value with its gradient with respect to `N` local variables.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Dual<const N: usize> {
    /// The value.
    pub v: Real,
    /// `∂v/∂u_k`, `k < N`.
    pub d: [Real; N],
}

impl<const N: usize> Dual<N> {
    /// A constant (zero gradient).
    pub fn constant(v: Real) -> Self {
        Self { v, d: [0.0; N] }
    }

    /// The local variable number `k` with value `v`.
    pub fn variable(v: Real, k: usize) -> Self {
        let mut d = [0.0; N];
        d[k] = 1.0;
        Self { v, d }
    }

    /// `√self` (the caller guarantees `v > 0`).
    pub fn sqrt(self) -> Self {
        let s = self.v.sqrt();
        self.scale_derivative(s, 0.5 / s)
    }

    /// `atan2(self, x)`, the angle of the point `(x, self)`.
    pub fn atan2(self, x: Self) -> Self {
        let r2 = self.v * self.v + x.v * x.v;
        let mut d = [0.0; N];
        for ((o, &dy), &dx) in d.iter_mut().zip(&self.d).zip(&x.d) {
            *o = (x.v * dy - self.v * dx) / r2;
        }
        Self {
            v: self.v.atan2(x.v),
            d,
        }
    }

    /// Value `v` with gradient `slope · self.d`.
    fn scale_derivative(self, v: Real, slope: Real) -> Self {
        let mut d = self.d;
        d.iter_mut().for_each(|x| *x *= slope);
        Self { v, d }
    }
}

impl<const N: usize> Add for Dual<N> {
    type Output = Self;
    fn add(mut self, o: Self) -> Self {
        self.v += o.v;
        self.d.iter_mut().zip(&o.d).for_each(|(a, b)| *a += b);
        self
    }
}

impl<const N: usize> Sub for Dual<N> {
    type Output = Self;
    fn sub(mut self, o: Self) -> Self {
        self.v -= o.v;
        self.d.iter_mut().zip(&o.d).for_each(|(a, b)| *a -= b);
        self
    }
}

impl<const N: usize> Neg for Dual<N> {
    type Output = Self;
    fn neg(self) -> Self {
        self.scale_derivative(-self.v, -1.0)
    }
}

impl<const N: usize> Mul for Dual<N> {
    type Output = Self;
    fn mul(self, o: Self) -> Self {
        let mut d = [0.0; N];
        for ((x, a), b) in d.iter_mut().zip(&self.d).zip(&o.d) {
            *x = a * o.v + self.v * b;
        }
        Self { v: self.v * o.v, d }
    }
}

impl<const N: usize> Div for Dual<N> {
    type Output = Self;
    fn div(self, o: Self) -> Self {
        let q = self.v / o.v;
        let mut d = [0.0; N];
        for ((x, a), b) in d.iter_mut().zip(&self.d).zip(&o.d) {
            *x = (a - q * b) / o.v;
        }
        Self { v: q, d }
    }
}

impl<const N: usize> Mul<Real> for Dual<N> {
    type Output = Self;
    fn mul(self, s: Real) -> Self {
        self.scale_derivative(self.v * s, s)
    }
}

impl<const N: usize> Add<Real> for Dual<N> {
    type Output = Self;
    fn add(mut self, s: Real) -> Self {
        self.v += s;
        self
    }
}

/// A 3-vector of duals.
pub(crate) type DVec3<const N: usize> = [Dual<N>; 3];

/// `a − b`.
pub(crate) fn sub3<const N: usize>(a: &DVec3<N>, b: &DVec3<N>) -> DVec3<N> {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `a · b`.
pub(crate) fn dot3<const N: usize>(a: &DVec3<N>, b: &DVec3<N>) -> Dual<N> {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `a × b`.
pub(crate) fn cross3<const N: usize>(a: &DVec3<N>, b: &DVec3<N>) -> DVec3<N> {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The point `p` as variables `first, first + 1, first + 2`.
pub(crate) fn variable3<const N: usize>(p: &crate::math::Vec3, first: usize) -> DVec3<N> {
    [0, 1, 2].map(|c| Dual::variable(p[c], first + c))
}

/// A point as three constants (no derivatives when `N` = 0: plain values through the same operations).
pub(crate) fn constant3<const N: usize>(p: &crate::math::Vec3) -> DVec3<N> {
    [0, 1, 2].map(|c| Dual::constant(p[c]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chain_rule_of_each_operation_matches_finite_differences() {
        // f(a, b) = atan2(a·b, a + b) + √(a² + 1) / (b − 3) × 2 − a at (0.7, −1.3).
        let f =
            |a: Real, b: Real| (a * b).atan2(a + b) + (a * a + 1.0).sqrt() / (b - 3.0) * 2.0 - a;
        let (a, b) = (0.7, -1.3);
        let (da, db) = (Dual::<2>::variable(a, 0), Dual::<2>::variable(b, 1));
        let g = (da * db).atan2(da + db) + (da * da + 1.0).sqrt() / (db + (-3.0)) * 2.0 - da;
        let neg = -g;
        assert_eq!(neg.v, -g.v);
        assert!((g.v - f(a, b)).abs() < 1e-14);
        let h = 1e-6;
        let fa = (f(a + h, b) - f(a - h, b)) / (2.0 * h);
        let fb = (f(a, b + h) - f(a, b - h)) / (2.0 * h);
        assert!((g.d[0] - fa).abs() < 1e-8, "{} {fa}", g.d[0]);
        assert!((g.d[1] - fb).abs() < 1e-8, "{} {fb}", g.d[1]);
        let c = Dual::<2>::constant(3.0);
        assert_eq!(c.d, [0.0; 2]);
        let u = [da, db, c];
        let w = [db, c, da];
        let x = cross3(&u, &w);
        assert!((dot3(&x, &u).v).abs() < 1e-14);
        assert_eq!(sub3(&u, &u)[0].v, 0.0);
    }
}
