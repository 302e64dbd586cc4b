//! A fabric's test curve — tension per width against elongation — as a monotone, C¹ tension law whose
//! integral (the strain energy per rest area) is C².
//!
//! # The law
//!
//! A curve is given as points `(εi, Ti)`: elongation `ε = λ − 1` (dimensionless, 0.5 = 50 %) and nominal
//! tension `T` (N/m: force per unit *rest* width, as a strip test reports it; a strip test's newtons per
//! 50 mm strip are `T = F / 0.05 m`, i.e. 20 N/m per N/50 mm). The point `(0, 0)` is added when the curve
//! does not start there. Between the points `T(ε)` is the monotone cubic Hermite interpolant with
//! Fritsch–Butland slopes (Fritsch & Carlson 1980, *SIAM J. Numer. Anal.* 17; Fritsch & Butland 1984, the
//! weighted harmonic mean of the neighbouring secants `δ`, zero never arising because every `δ > 0`):
//!
//! ```text
//! mk = (w1 + w2) / (w1/δ(k−1) + w2/δk),   w1 = 2h_k + h_(k−1),  w2 = h_k + 2h_(k−1),
//! m0 = δ0,  mn = δ(n−1).
//! ```
//!
//! These slopes lie in `(0, 3 min(δ(k−1), δk)]`, inside the Fritsch–Carlson monotonicity region, so `T`
//! rises wherever the data rise; it is C¹ (its slope is continuous at the points), hence its integral
//! `W(ε) = ∫₀^ε T` is C² — the smoothness a Newton solve wants, chosen over a C² interpolating spline of `T`
//! because that one overshoots and can fall between points of a J-shaped knit curve. Beyond the last
//! point `T` continues along its end tangent; below zero elongation it continues along its start tangent
//! (`T = m0 ε`; the membrane law only evaluates compression inside a relaxation search, see
//! [`crate::orthotropic_density`]). `W` is integrated exactly, piece by piece, from the Hermite basis's
//! integrals.
//!
//! Units: `ε` dimensionless, `T` in N/m, `T' = dT/dε` in N/m, `W` in J/m² (N/m).

use crate::math::Real;

/// A curve that cannot be a tension law.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CurveError {
    /// Fewer than one point beyond the origin.
    #[error("needs at least two points [elongation, N/m] besides (0, 0), got {0}")]
    TooFewPoints(usize),
    /// A point is not two finite numbers.
    #[error("point {index} is not two finite numbers [elongation, N/m]")]
    NotFinite {
        /// Index of the point as given.
        index: usize,
    },
    /// Elongation below zero.
    #[error(
        "point {index} has negative elongation {elongation}; give elongations >= 0 (0.5 = 50 %)"
    )]
    NegativeElongation {
        /// Index of the point as given.
        index: usize,
        /// Its elongation.
        elongation: Real,
    },
    /// Elongation or tension not strictly increasing.
    #[error(
        "point {index} does not rise: elongation and tension must both increase strictly from point to point (and from (0, 0))"
    )]
    NotMonotone {
        /// Index of the point as given.
        index: usize,
    },
}

/// A monotone C¹ tension law `T(ε)` and its C² integral; see the module documentation.
#[derive(Clone, Debug, PartialEq)]
pub struct TensionCurve {
    /// Elongations, starting at 0, strictly increasing (dimensionless).
    e: Vec<Real>,
    /// Tensions, starting at 0, strictly increasing (N/m).
    t: Vec<Real>,
    /// Hermite slopes dT/dε at the points (N/m).
    m: Vec<Real>,
    /// `W(εk)` (J/m²).
    w: Vec<Real>,
}

impl TensionCurve {
    /// From points `(elongation, tension)` (dimensionless, N/m), as measured; `(0, 0)` is prepended unless
    /// the first point is it. Errors name the offending point.
    pub fn new(points: &[[Real; 2]]) -> Result<Self, CurveError> {
        let mut e = vec![0.0];
        let mut t = vec![0.0];
        for (index, p) in points.iter().enumerate() {
            if !(p[0].is_finite() && p[1].is_finite()) {
                return Err(CurveError::NotFinite { index });
            }
            if p[0] < 0.0 {
                return Err(CurveError::NegativeElongation {
                    index,
                    elongation: p[0],
                });
            }
            if index == 0 && p[0] == 0.0 && p[1] == 0.0 {
                continue;
            }
            let (le, lt) = (*e.last().unwrap(), *t.last().unwrap());
            if !(p[0] > le && p[1] > lt) {
                return Err(CurveError::NotMonotone { index });
            }
            e.push(p[0]);
            t.push(p[1]);
        }
        if e.len() < 3 {
            return Err(CurveError::TooFewPoints(e.len() - 1));
        }
        let n = e.len();
        let h: Vec<Real> = (0..n - 1).map(|k| e[k + 1] - e[k]).collect();
        let d: Vec<Real> = (0..n - 1).map(|k| (t[k + 1] - t[k]) / h[k]).collect();
        let mut m = vec![0.0; n];
        m[0] = d[0];
        m[n - 1] = d[n - 2];
        for k in 1..n - 1 {
            let w1 = 2.0 * h[k] + h[k - 1];
            let w2 = h[k] + 2.0 * h[k - 1];
            m[k] = (w1 + w2) / (w1 / d[k - 1] + w2 / d[k]);
        }
        let mut curve = Self {
            e,
            t,
            m,
            w: vec![0.0; n],
        };
        for k in 1..n {
            curve.w[k] = curve.w[k - 1] + curve.piece_integral(k - 1, 1.0);
        }
        Ok(curve)
    }

    /// The points `(εk, Tk)` used, `(0, 0)` first.
    pub fn points(&self) -> impl Iterator<Item = (Real, Real)> + '_ {
        self.e.iter().copied().zip(self.t.iter().copied())
    }

    /// Largest elongation measured (dimensionless).
    pub fn max_elongation(&self) -> Real {
        *self.e.last().unwrap()
    }

    /// Initial slope `T'(0)` (N/m).
    pub fn initial_slope(&self) -> Real {
        self.m[0]
    }

    /// `∫` over the first `u` (fraction) of piece `k` of the Hermite interpolant (J/m²).
    fn piece_integral(&self, k: usize, u: Real) -> Real {
        let h = self.e[k + 1] - self.e[k];
        let (u2, u3, u4) = (u * u, u * u * u, u * u * u * u);
        let h00 = 0.5 * u4 - u3 + u;
        let h10 = 0.25 * u4 - 2.0 / 3.0 * u3 + 0.5 * u2;
        let h01 = -0.5 * u4 + u3;
        let h11 = 0.25 * u4 - u3 / 3.0;
        h * (h00 * self.t[k] + h10 * h * self.m[k] + h01 * self.t[k + 1] + h11 * h * self.m[k + 1])
    }

    /// `(W(ε), T(ε), T'(ε))`: energy per rest area (J/m²), tension (N/m) and its slope (N/m).
    pub fn evaluate(&self, eps: Real) -> (Real, Real, Real) {
        let n = self.e.len();
        if eps <= 0.0 {
            let m0 = self.m[0];
            return (0.5 * m0 * eps * eps, m0 * eps, m0);
        }
        let last = self.e[n - 1];
        if eps >= last {
            let x = eps - last;
            let (tn, mn) = (self.t[n - 1], self.m[n - 1]);
            return (self.w[n - 1] + tn * x + 0.5 * mn * x * x, tn + mn * x, mn);
        }
        // Piece k with e[k] <= eps < e[k + 1].
        let k = self.e.partition_point(|&x| x <= eps) - 1;
        let h = self.e[k + 1] - self.e[k];
        let u = (eps - self.e[k]) / h;
        let (u2, u3) = (u * u, u * u * u);
        let t = (2.0 * u3 - 3.0 * u2 + 1.0) * self.t[k]
            + (u3 - 2.0 * u2 + u) * h * self.m[k]
            + (-2.0 * u3 + 3.0 * u2) * self.t[k + 1]
            + (u3 - u2) * h * self.m[k + 1];
        let dt = ((6.0 * u2 - 6.0 * u) * self.t[k]
            + (3.0 * u2 - 4.0 * u + 1.0) * h * self.m[k]
            + (-6.0 * u2 + 6.0 * u) * self.t[k + 1]
            + (3.0 * u2 - 2.0 * u) * h * self.m[k + 1])
            / h;
        (self.w[k] + self.piece_integral(k, u), t, dt)
    }

    /// Tension `T(ε)` (N/m).
    pub fn tension(&self, eps: Real) -> Real {
        self.evaluate(eps).1
    }

    /// The smallest `T'(ε)(1 + ε) − T(ε)` (N/m) over a dense sampling of the measured range and its ends.
    /// It is the sign of `d²W/d(λ²)²`: the energy is convex in `C` (as the relaxation needs) when it is
    /// `≥ 0`.
    pub fn convexity_margin(&self) -> (Real, Real) {
        let mut worst = (Real::INFINITY, 0.0);
        for k in 0..self.e.len() - 1 {
            for i in 0..=32 {
                let eps = self.e[k] + (self.e[k + 1] - self.e[k]) * i as Real / 32.0;
                let (_, t, dt) = self.evaluate(eps);
                let margin = dt * (1.0 + eps) - t;
                if margin < worst.0 {
                    worst = (margin, eps);
                }
            }
        }
        worst
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use skintight_geometry::finite_difference::{FdParams, check_gradient};

    fn j_curve() -> TensionCurve {
        TensionCurve::new(&[[0.2, 20.0], [0.5, 60.0], [0.8, 140.0], [1.0, 260.0]]).unwrap()
    }

    #[test]
    fn interpolates_the_points_and_rises_between_them() {
        let c = j_curve();
        for (e, t) in c.points() {
            assert!((c.tension(e) - t).abs() <= 1e-12 * 260.0);
        }
        let mut prev = c.tension(-0.1);
        for i in 1..=2000 {
            let e = -0.1 + 1.3 * i as Real / 2000.0;
            let t = c.tension(e);
            assert!(t > prev, "falls at {e}");
            assert!(c.evaluate(e).2 > 0.0);
            prev = t;
        }
    }

    #[test]
    fn energy_is_the_integral_of_tension_and_tension_of_slope() {
        let c = j_curve();
        let p = FdParams {
            step: 1e-6,
            rel_tol: 1e-7,
            abs_tol: 1e-9,
        };
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut xs: Vec<Real> = (0..60).map(|_| rng.random_range(-0.2..1.4)).collect();
        // Just either side of every point: the pieces join with equal value and slope.
        for (e, _) in c.points() {
            xs.extend([e - 1e-4, e + 1e-4]);
        }
        for x in xs {
            let (_, t, dt) = c.evaluate(x);
            check_gradient(|v| c.evaluate(v[0]).0, &[x], &[t], &p)
                .unwrap_or_else(|e| panic!("W' at {x}: {e}"));
            check_gradient(|v| c.evaluate(v[0]).1, &[x], &[dt], &p)
                .unwrap_or_else(|e| panic!("T' at {x}: {e}"));
        }
        // Exact integral of a straight line.
        let line = TensionCurve::new(&[[0.5, 50.0], [1.0, 100.0]]).unwrap();
        assert!((line.evaluate(0.7).0 - 0.5 * 100.0 * 0.49).abs() < 1e-10);
    }

    #[test]
    fn slope_is_continuous_at_the_points() {
        let c = j_curve();
        for (e, _) in c.points().skip(1) {
            let (a, b) = (c.evaluate(e - 1e-9).2, c.evaluate(e + 1e-9).2);
            assert!(
                (a - b).abs() <= 1e-5 * a.abs().max(1.0),
                "at {e}: {a} vs {b}"
            );
        }
    }

    #[test]
    fn bad_curves_are_rejected_with_the_point() {
        assert_eq!(
            TensionCurve::new(&[[0.5, 10.0]]).unwrap_err(),
            CurveError::TooFewPoints(1)
        );
        assert_eq!(
            TensionCurve::new(&[[0.0, 0.0], [0.5, 10.0]]).unwrap_err(),
            CurveError::TooFewPoints(1)
        );
        assert!(matches!(
            TensionCurve::new(&[[0.5, 10.0], [-0.1, 12.0]]).unwrap_err(),
            CurveError::NegativeElongation { index: 1, .. }
        ));
        assert_eq!(
            TensionCurve::new(&[[0.5, 10.0], [0.8, 9.0]]).unwrap_err(),
            CurveError::NotMonotone { index: 1 }
        );
        assert_eq!(
            TensionCurve::new(&[[0.5, 10.0], [0.5, 12.0]]).unwrap_err(),
            CurveError::NotMonotone { index: 1 }
        );
        assert_eq!(
            TensionCurve::new(&[[0.5, Real::NAN], [0.8, 9.0]]).unwrap_err(),
            CurveError::NotFinite { index: 0 }
        );
        assert!(
            TensionCurve::new(&[[0.5, 10.0], [0.8, 9.0]])
                .unwrap_err()
                .to_string()
                .contains("increase")
        );
    }

    #[test]
    fn convexity_margin_flags_a_curve_that_softens_too_fast() {
        assert!(j_curve().convexity_margin().0 > 0.0);
        // A plateau: T nearly constant after 20 %.
        let soft = TensionCurve::new(&[[0.2, 100.0], [0.6, 101.0], [1.0, 102.0]]).unwrap();
        assert!(soft.convexity_margin().0 < 0.0);
    }
}
