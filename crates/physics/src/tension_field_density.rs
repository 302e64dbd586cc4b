//! Tension-field relaxed Saint-Venant–Kirchhoff membrane strain energy density in the eigenvalues of
//! `C = FᵀF`, smoothed to C² (thesis Sec. 5.2, Eq. 122–129, and Sec. 6.1, Eq. 165–170).
//!
//! # The density
//!
//! Let `λ1 ≥ λ2` be the eigenvalues of the right Cauchy–Green tensor `C = FᵀF` (dimensionless; the squared
//! principal stretches) and write `a = λ1 − 1`, `b = λ2 − 1`. With the Green–Lagrange strain
//! `E = (C − I)/2` we have `tr E = (a + b)/2` and `tr E² = (a² + b²)/4`, so StVK (Eq. 122)
//!
//! ```text
//! ψ_StVK = ½ λ tr(E)² + μ tr(E²) = λ/8 (λ1 + λ2 − 2)² + μ/4 ((λ1 − 1)² + (λ2 − 1)²).
//! ```
//!
//! This is the taut branch of Eq. 129 and is what is implemented. Eq. 125 as printed (`λ/2`, `μ`) is four
//! times larger: it corresponds to `E = C − I`, not the `E = (C − I)/2` of Eq. 122.
//!
//! Tension-field theory (Eq. 126–129): for fixed `λ1`, StVK is minimal over `λ2` at
//! `λ̄2(λ1) = 1 − ν'(λ1 − 1)` with `ν' = λ/(λ + 2μ)` (this is Eq. 126 rearranged; the factor 4 cancels
//! there). Completing the square in `b` gives the exact identity
//!
//! ```text
//! ψ_StVK(λ1, λ2) = c a² + (k/2) g²,   g = (λ2 − 1) + ν'(λ1 − 1) = λ2 − λ̄2(λ1),
//! k = (λ + 2μ)/4 = ∂²ψ_StVK/∂λ2²,      c = μ(λ + μ) / (2(λ + 2μ)),
//! ```
//!
//! so the wrinkled energy `min_λ2 ψ_StVK = c (λ1 − 1)²` is exactly Eq. 127 (derived here with the `λ/8`,
//! `μ/4` factors of Eq. 129; with Eq. 125's factors it would be four times Eq. 127). In the slack case
//! `λ2 ≤ λ1 ≤ 1`, `ν' ≥ 0` gives `g ≤ 0`. Hence the whole piecewise Eq. 129 is
//!
//! ```text
//! ψ_relaxed = 2c · r(a) + k · r(g),   r(x) = max(x, 0)² / 2,
//! ```
//!
//! taut where `a ≥ 0, g ≥ 0`, wrinkled where `a ≥ 0, g ≤ 0`, slack where `a ≤ 0`. The two ramps `r` are
//! the only places where the energy is merely C¹.
//!
//! # C² smoothing (our design, in the spirit of Sec. 6.1)
//!
//! The thesis fits quadratic force transitions over a band of half-width `ε` centred on each boundary and
//! shifts the regimes' energies (Eq. 165–170); its bands must shrink towards `(1, 1)`, which stays
//! discontinuous, and centred bands put a non-zero force at the rest state. We instead replace each ramp
//! `r` by a C² ramp `R_w` whose transition lies entirely on the tensile side, `0 ≤ x ≤ w`:
//!
//! ```text
//! R_w(x) = 0                         x ≤ 0
//!        = w² (3/2 u³ − 3/2 u⁴ + 1/2 u⁵),  u = x/w,   0 ≤ x ≤ w
//!        = x²/2                      x ≥ w
//! R_w''(x) = 9u − 18u² + 10u³ on the band (0 at u = 0, 1 at u = 1, ≥ 0 throughout).
//! ```
//!
//! `R_w` is C², convex, and equal to `r` outside the band (its second derivative was chosen so that the
//! first and zeroth moments match, so no shift terms are needed). The smoothed density is
//!
//! ```text
//! ψ = 2c · R_w(λ1 − 1) + k · R_{(1+ν')w}(g).
//! ```
//!
//! Properties (all tested): exactly Eq. 129 outside the bands — exactly StVK (Eq. 122) when
//! `λ1 − 1 ≥ w` and `g ≥ (1 + ν')w`, exactly Eq. 127 when `λ1 − 1 ≥ w` and `g ≤ 0`, exactly zero when
//! `λ1 ≤ 1`; zero energy, force and stiffness at rest; convex in `(λ1, λ2)`; `∂ψ/∂λi ≥ 0`, so the stress
//! is never compressive. The band width of the second ramp is `(1 + ν')w` so that on the line
//! `λ1 = λ2` both ramps sit at the same relative position `u`, which makes `∂ψ/∂λ1 = ∂ψ/∂λ2` there
//! (because `2c = k(1 − ν'²)`). The symmetric extension `ψ(λ1, λ2) = ψ(λ2, λ1)` is therefore C² on the
//! whole plane, and `C ↦ ψ(eig C)` is C² everywhere, including at `λ1 = λ2` and at the triple point
//! `(1, 1)` (unlike Sec. 6.1, which leaves `(1, 1)` discontinuous). Every function here accepts `λ1, λ2`
//! in either order and evaluates that symmetric extension.
//!
//! # Lamé parameters
//!
//! [`TensionFieldDensity::new`] takes Young's modulus `E` (Pa) and Poisson's ratio `ν` and uses the
//! plane-stress (membrane) Lamé parameters `λ = Eν/(1 − ν²)`, `μ = E/(2(1 + ν))`. With them uniaxial
//! tension of the membrane (the wrinkled regime) has modulus exactly `E` (`4(2c) = E`, i.e.
//! `ψ = ½ E ε²` in the Green strain `ε = (λ1 − 1)/2`) and `ν' = ν`, so the wrinkling threshold is
//! `λ̄2 = 1 − ν(λ1 − 1)`; for `ν = 0` it is the line `λ2 = 1` as Sec. 6.1 states. The thesis writes plain
//! (3D) `λ, μ`, which would make the membrane stiffer in-plane and shift the threshold for a given `ν`;
//! [`TensionFieldDensity::from_lame`] accepts explicit Lamé parameters for anyone who wants those.
//!
//! Units: `λ1, λ2` dimensionless; `ψ` and its derivatives in Pa (J/m³).

use crate::math::{Mat2, Real, Vec2};

/// Settings of the C² smoothing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TensionFieldParams {
    /// Width `w` of the smoothed transitions, in units of `λ` (squared stretch, dimensionless). The
    /// slack→wrinkled band is `1 ≤ λ1 ≤ 1 + w`, the wrinkled→taut band is `0 ≤ λ2 − λ̄2(λ1) ≤ (1 + ν)w`.
    /// Zero gives the exact, only C¹, Eq. 129.
    pub transition_width: Real,
}

impl Default for TensionFieldParams {
    fn default() -> Self {
        Self {
            transition_width: 1e-2,
        }
    }
}

/// Invalid material or smoothing settings.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MaterialError {
    /// Young's modulus not finite and positive.
    #[error("cloth Young's modulus must be a finite positive number of pascals, got {0}")]
    YoungsModulus(Real),
    /// Poisson's ratio outside `[0, 1)`.
    #[error(
        "cloth Poisson's ratio must lie in [0, 1) for a tension-field membrane (plane stress), got {0}"
    )]
    PoissonRatio(Real),
    /// Lamé parameters not finite, or `μ ≤ 0`, or `λ < 0`.
    #[error(
        "cloth Lamé parameters must be finite with lambda >= 0 and mu > 0 (Pa), got lambda = {lambda}, mu = {mu}"
    )]
    Lame {
        /// First Lamé parameter (Pa).
        lambda: Real,
        /// Shear modulus (Pa).
        mu: Real,
    },
    /// Transition width not finite or outside `[0, 0.5]`.
    #[error("tension-field transition_width must be finite and within [0, 0.5], got {0}")]
    TransitionWidth(Real),
}

/// Which branch of Eq. 129 a state is in. `Transition` is inside a smoothing band.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum Regime {
    /// Both directions in tension: plain StVK.
    Taut,
    /// Tension along the first principal direction only: Eq. 127.
    Wrinkled,
    /// No tension: zero energy.
    Slack,
    /// Inside one of the smoothed bands of width `w`.
    Transition,
}

/// Value, gradient and Hessian of the density with respect to `(λ1, λ2)` (Pa).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DensityDerivatives {
    /// ψ (Pa).
    pub value: Real,
    /// `(∂ψ/∂λ1, ∂ψ/∂λ2)` (Pa).
    pub gradient: Vec2,
    /// `∂²ψ/∂λi∂λj` (Pa), symmetric 2 × 2.
    pub hessian: Mat2,
}

/// The smoothed tension-field StVK density; see the module documentation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TensionFieldDensity {
    lambda: Real,
    mu: Real,
    /// Effective Poisson ratio ν' = λ/(λ + 2μ): slope of the wrinkling threshold.
    nu: Real,
    /// Wrinkled coefficient c = μ(λ + μ)/(2(λ + 2μ)) (Eq. 127).
    c: Real,
    /// Taut λ2 stiffness k = (λ + 2μ)/4.
    k: Real,
    /// Band width of the slack→wrinkled ramp.
    w: Real,
    /// Band width of the wrinkled→taut ramp, (1 + ν')w.
    wg: Real,
}

/// Value of the C² ramp `R_w(x)` (→ `max(x, 0)²/2`), its first and second derivative.
#[inline]
fn ramp(x: Real, w: Real) -> (Real, Real, Real) {
    if x <= 0.0 {
        (0.0, 0.0, 0.0)
    } else if x >= w {
        (0.5 * x * x, x, 1.0)
    } else {
        let u = x / w;
        let u2 = u * u;
        let v = w * w * u2 * u * (1.5 - 1.5 * u + 0.5 * u2);
        let d1 = w * u2 * (4.5 - 6.0 * u + 2.5 * u2);
        let d2 = u * (9.0 - 18.0 * u + 10.0 * u2);
        (v, d1, d2)
    }
}

/// Divided difference `(R_w'(x) − R_w'(y)) / (x − y)` for `x ≥ y`, without cancellation: the interval is
/// split at the breakpoints 0 and `w` and the exact mean slope of each polynomial piece is weighted by its
/// share of the interval. Equals `R_w''(x)` when `x = y`.
fn ramp_slope_divided_difference(x: Real, y: Real, w: Real) -> Real {
    let len = x - y;
    if len <= 0.0 {
        return ramp(x, w).2;
    }
    // Piece x ≥ w: R' = x, mean slope 1.
    let mut sum = (x - y.max(w)).max(0.0);
    // Band 0 ≤ x ≤ w: R' = w q(x/w), q(u) = 9/2 u² − 6u³ + 5/2 u⁴.
    let lo = y.max(0.0);
    let hi = x.min(w);
    if hi > lo && w > 0.0 {
        let (s, t) = (hi / w, lo / w);
        let q_dd = 4.5 * (s + t) - 6.0 * (s * s + s * t + t * t) + 2.5 * (s + t) * (s * s + t * t);
        sum += (hi - lo) * q_dd;
    }
    // Piece x ≤ 0 contributes slope 0.
    sum / len
}

impl TensionFieldDensity {
    /// From Young's modulus `youngs_modulus` (Pa) and Poisson's ratio `poisson_ratio` (in `[0, 1)`),
    /// with plane-stress Lamé parameters `λ = Eν/(1 − ν²)`, `μ = E/(2(1 + ν))`.
    pub fn new(
        youngs_modulus: Real,
        poisson_ratio: Real,
        params: &TensionFieldParams,
    ) -> Result<Self, MaterialError> {
        if !(youngs_modulus.is_finite() && youngs_modulus > 0.0) {
            return Err(MaterialError::YoungsModulus(youngs_modulus));
        }
        if !(poisson_ratio.is_finite() && (0.0..1.0).contains(&poisson_ratio)) {
            return Err(MaterialError::PoissonRatio(poisson_ratio));
        }
        let lambda = youngs_modulus * poisson_ratio / (1.0 - poisson_ratio * poisson_ratio);
        let mu = youngs_modulus / (2.0 * (1.0 + poisson_ratio));
        Self::from_lame(lambda, mu, params)
    }

    /// From explicit Lamé parameters `lambda ≥ 0` and `mu > 0` (Pa), used as given in Eq. 129.
    pub fn from_lame(
        lambda: Real,
        mu: Real,
        params: &TensionFieldParams,
    ) -> Result<Self, MaterialError> {
        if !(lambda.is_finite() && mu.is_finite() && lambda >= 0.0 && mu > 0.0) {
            return Err(MaterialError::Lame { lambda, mu });
        }
        let w = params.transition_width;
        if !(w.is_finite() && (0.0..=0.5).contains(&w)) {
            return Err(MaterialError::TransitionWidth(w));
        }
        let nu = lambda / (lambda + 2.0 * mu);
        Ok(Self {
            lambda,
            mu,
            nu,
            c: mu * (lambda + mu) / (2.0 * (lambda + 2.0 * mu)),
            k: 0.25 * (lambda + 2.0 * mu),
            w,
            wg: (1.0 + nu) * w,
        })
    }

    /// First Lamé parameter λ (Pa).
    pub fn lambda(&self) -> Real {
        self.lambda
    }

    /// Shear modulus μ (Pa).
    pub fn mu(&self) -> Real {
        self.mu
    }

    /// Smoothing band width `w` (dimensionless, in units of λ).
    pub fn transition_width(&self) -> Real {
        self.w
    }

    /// Plain StVK (Eq. 122 = taut branch of Eq. 129) in the eigenvalues of `C`, without relaxation (Pa).
    pub fn stvk(&self, l1: Real, l2: Real) -> Real {
        let (a, b) = (l1 - 1.0, l2 - 1.0);
        0.125 * self.lambda * (a + b) * (a + b) + 0.25 * self.mu * (a * a + b * b)
    }

    /// The wrinkling threshold `λ̄2(λ1) = argmin_λ2 ψ_StVK` (Eq. 126), dimensionless.
    pub fn wrinkling_threshold(&self, l1: Real) -> Real {
        1.0 - self.nu * (l1 - 1.0)
    }

    /// The wrinkled energy `c (λ1 − 1)²` of Eq. 127 (Pa), without the `λ1 ≥ 1` condition.
    pub fn wrinkled(&self, l1: Real) -> Real {
        self.c * (l1 - 1.0) * (l1 - 1.0)
    }

    /// Orders the pair and returns `(max, min, swapped)` plus the regime variables `a = λ1 − 1` and
    /// `g = λ2 − λ̄2(λ1)`.
    #[inline]
    fn ordered(&self, l1: Real, l2: Real) -> (Real, Real, bool) {
        let swapped = l2 > l1;
        let (hi, lo) = if swapped { (l2, l1) } else { (l1, l2) };
        let a = hi - 1.0;
        let g = (lo - 1.0) + self.nu * a;
        (a, g, swapped)
    }

    /// Regime of the state `(λ1, λ2)` (either order).
    pub fn regime(&self, l1: Real, l2: Real) -> Regime {
        let (a, g, _) = self.ordered(l1, l2);
        if a <= 0.0 {
            Regime::Slack
        } else if a < self.w || (g > 0.0 && g < self.wg) {
            Regime::Transition
        } else if g <= 0.0 {
            Regime::Wrinkled
        } else {
            Regime::Taut
        }
    }

    /// ψ(λ1, λ2) (Pa).
    pub fn value(&self, l1: Real, l2: Real) -> Real {
        let (a, g, _) = self.ordered(l1, l2);
        2.0 * self.c * ramp(a, self.w).0 + self.k * ramp(g, self.wg).0
    }

    /// ψ with its gradient and Hessian with respect to `(λ1, λ2)` in the order given (Pa).
    pub fn derivatives(&self, l1: Real, l2: Real) -> DensityDerivatives {
        let (a, g, swapped) = self.ordered(l1, l2);
        let (ra, da, dda) = ramp(a, self.w);
        let (rg, dg, ddg) = ramp(g, self.wg);
        let (c2, k, nu) = (2.0 * self.c, self.k, self.nu);
        let value = c2 * ra + k * rg;
        // Ordered: ∂/∂λmax = 2c R'(a) + kν' R'(g), ∂/∂λmin = k R'(g).
        let g_hi = c2 * da + k * nu * dg;
        let g_lo = k * dg;
        let h_hh = c2 * dda + k * nu * nu * ddg;
        let h_hl = k * nu * ddg;
        let h_ll = k * ddg;
        if swapped {
            DensityDerivatives {
                value,
                gradient: Vec2::new(g_lo, g_hi),
                hessian: Mat2::new(h_ll, h_hl, h_hl, h_hh),
            }
        } else {
            DensityDerivatives {
                value,
                gradient: Vec2::new(g_hi, g_lo),
                hessian: Mat2::new(h_hh, h_hl, h_hl, h_ll),
            }
        }
    }

    /// `(∂ψ/∂λ1 − ∂ψ/∂λ2) / (λ1 − λ2)` (Pa), computed without cancellation and equal to its limit
    /// `∂²ψ/∂λ1² − ∂²ψ/∂λ1∂λ2` at `λ1 = λ2`. This is the coefficient of the eigenvector-rotation term of
    /// the Hessian with respect to `C`. Symmetric in its arguments.
    pub fn stretch_divided_difference(&self, l1: Real, l2: Real) -> Real {
        let (a, g, _) = self.ordered(l1, l2);
        // ψ1 − ψ2 = 2c (R'_w(a) − R'_w(y)) with y = g/(1 + ν'), and a − y = (λ1 − λ2)/(1 + ν').
        let y = g / (1.0 + self.nu);
        2.0 * self.c / (1.0 + self.nu) * ramp_slope_divided_difference(a, y, self.w)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use skintight_geometry::finite_difference::{FdParams, check_gradient, check_jacobian};

    fn cloth() -> TensionFieldDensity {
        TensionFieldDensity::new(5.4e6, 0.33, &TensionFieldParams::default()).unwrap()
    }

    /// A point with `λ1 − 1 = a` and `g = λ2 − λ̄2(λ1)`.
    fn at(d: &TensionFieldDensity, a: Real, g: Real) -> (Real, Real) {
        let l1 = 1.0 + a;
        (l1, d.wrinkling_threshold(l1) + g)
    }

    fn fd_check(d: &TensionFieldDensity, l1: Real, l2: Real) {
        let p = FdParams {
            step: 1e-7,
            rel_tol: 1e-6,
            abs_tol: 1e-9 * d.mu(),
        };
        let x = [l1, l2];
        let der = d.derivatives(l1, l2);
        assert!((der.value - d.value(l1, l2)).abs() <= 1e-12 * d.mu());
        check_gradient(|v| d.value(v[0], v[1]), &x, der.gradient.as_slice(), &p)
            .unwrap_or_else(|e| panic!("gradient at ({l1}, {l2}): {e}"));
        let h = der.hessian;
        check_jacobian(
            |v| {
                let g = d.derivatives(v[0], v[1]).gradient;
                vec![g[0], g[1]]
            },
            &x,
            &[h[(0, 0)], h[(0, 1)], h[(1, 0)], h[(1, 1)]],
            &p,
        )
        .unwrap_or_else(|e| panic!("hessian at ({l1}, {l2}): {e}"));
    }

    #[test]
    fn eq129_factors_give_stvk_of_green_strain() {
        // Eq. 122 with E = (C − I)/2 on a diagonal C equals the λ/8, μ/4 form of Eq. 129.
        let d = cloth();
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for _ in 0..20 {
            let (l1, l2): (Real, Real) = (rng.random_range(0.5..2.0), rng.random_range(0.5..2.0));
            let (e1, e2) = ((l1 - 1.0) / 2.0, (l2 - 1.0) / 2.0);
            let eq122 = 0.5 * d.lambda() * (e1 + e2).powi(2) + d.mu() * (e1 * e1 + e2 * e2);
            assert!((d.stvk(l1, l2) - eq122).abs() <= 1e-12 * d.mu());
        }
    }

    #[test]
    fn plane_stress_lame_recover_youngs_modulus_and_poisson_ratio() {
        let (e, nu) = (5.4e6, 0.33);
        let d = TensionFieldDensity::new(e, nu, &TensionFieldParams::default()).unwrap();
        // Uniaxial (wrinkled) response: ψ = ½ E ε² in the Green strain ε = (λ1 − 1)/2.
        let eps: Real = 0.1;
        assert!((d.wrinkled(1.0 + 2.0 * eps) - 0.5 * e * eps * eps).abs() < 1e-9 * e);
        // Lateral contraction of the Green strain is −ν times the axial one.
        assert!((d.wrinkling_threshold(1.2) - (1.0 - nu * 0.2)).abs() < 1e-14);
    }

    #[test]
    fn wrinkling_threshold_matches_eq126_and_minimizes_stvk() {
        let d = cloth();
        let (lam, mu) = (d.lambda(), d.mu());
        for l1 in [1.0, 1.05, 1.3, 1.9] {
            let eq126 = -(lam * l1 - 2.0 * lam - 2.0 * mu) / (lam + 2.0 * mu);
            let t = d.wrinkling_threshold(l1);
            assert!((t - eq126).abs() < 1e-14);
            // Dense search for the minimum of StVK over λ2.
            let best = (0..=20000)
                .map(|i| t - 0.1 + 0.2 * i as Real / 20000.0)
                .min_by(|x, y| d.stvk(l1, *x).total_cmp(&d.stvk(l1, *y)))
                .unwrap();
            assert!((best - t).abs() <= 1e-5, "argmin {best} vs threshold {t}");
            // Eq. 127 is the value at the minimum.
            let eq127 = mu * (lam + mu) / (2.0 * lam + 4.0 * mu) * (l1 - 1.0).powi(2);
            assert!((d.stvk(l1, t) - eq127).abs() <= 1e-12 * mu);
            assert!((d.wrinkled(l1) - eq127).abs() <= 1e-12 * mu);
        }
    }

    #[test]
    fn regimes_equal_eq129_outside_bands() {
        let d = cloth();
        let w = d.transition_width();
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        for _ in 0..200 {
            // Taut.
            let (l1, l2) = at(&d, rng.random_range(w..1.0), rng.random_range(1.4 * w..0.5));
            if l2 <= l1 {
                assert_eq!(d.regime(l1, l2), Regime::Taut);
                assert!((d.value(l1, l2) - d.stvk(l1, l2)).abs() <= 1e-12 * d.mu());
            }
            // Wrinkled.
            let (l1, l2) = at(&d, rng.random_range(w..1.0), rng.random_range(-0.9..0.0));
            assert_eq!(d.regime(l1, l2), Regime::Wrinkled);
            assert!((d.value(l1, l2) - d.wrinkled(l1)).abs() <= 1e-12 * d.mu());
            // Slack: λ2 ≤ λ1 ≤ 1.
            let l1 = rng.random_range(0.0..1.0);
            let l2 = rng.random_range(0.0..l1);
            assert_eq!(d.regime(l1, l2), Regime::Slack);
            let der = d.derivatives(l1, l2);
            assert_eq!(der.value, 0.0);
            assert_eq!(der.gradient, Vec2::zeros());
            assert_eq!(der.hessian, Mat2::zeros());
        }
        // Inside the bands.
        assert_eq!(d.regime(1.0 + 0.5 * w, 0.9), Regime::Transition);
        let (l1, l2) = at(&d, 0.3, 0.5 * w);
        assert_eq!(d.regime(l1, l2), Regime::Transition);
    }

    #[test]
    fn zero_width_is_exact_eq129_everywhere() {
        let d = TensionFieldDensity::new(
            5.4e6,
            0.33,
            &TensionFieldParams {
                transition_width: 0.0,
            },
        )
        .unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..500 {
            let l1: Real = rng.random_range(0.3..2.0);
            let l2: Real = rng.random_range(0.3..l1);
            let eq129 = if l1 <= 1.0 {
                0.0
            } else if l2 <= d.wrinkling_threshold(l1) {
                d.wrinkled(l1)
            } else {
                d.stvk(l1, l2)
            };
            assert!((d.value(l1, l2) - eq129).abs() <= 1e-12 * d.mu());
        }
    }

    #[test]
    fn rest_state_has_zero_energy_force_and_stiffness() {
        let der = cloth().derivatives(1.0, 1.0);
        assert_eq!(der.value, 0.0);
        assert_eq!(der.gradient, Vec2::zeros());
        assert_eq!(der.hessian, Mat2::zeros());
    }

    #[test]
    fn derivatives_match_finite_differences_in_every_regime_and_band() {
        for (seed, nu) in [(10_u64, 0.33), (11, 0.0), (12, 0.49)] {
            let d = TensionFieldDensity::new(30e6, nu, &TensionFieldParams::default()).unwrap();
            let w = d.transition_width();
            let wg = (1.0 + nu) * w;
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            for _ in 0..20 {
                // Taut, wrinkled, slack.
                let (l1, l2) = at(
                    &d,
                    rng.random_range(1.5 * w..0.8),
                    rng.random_range(1.5 * wg..0.3),
                );
                fd_check(&d, l1, l2);
                let (l1, l2) = at(
                    &d,
                    rng.random_range(1.5 * w..0.8),
                    rng.random_range(-0.5..-0.1 * w),
                );
                fd_check(&d, l1, l2);
                let l1 = rng.random_range(0.2..0.999);
                fd_check(&d, l1, rng.random_range(0.1..l1));
                // Slack→wrinkled band, wrinkled→taut band, and both together near (1, 1).
                let (l1, l2) = at(
                    &d,
                    rng.random_range(0.05 * w..0.95 * w),
                    rng.random_range(-0.5..-w),
                );
                fd_check(&d, l1, l2);
                let (l1, l2) = at(
                    &d,
                    rng.random_range(2.0 * w..0.8),
                    rng.random_range(0.05 * wg..0.95 * wg),
                );
                fd_check(&d, l1, l2);
                let (l1, l2) = at(
                    &d,
                    rng.random_range(0.05 * w..0.95 * w),
                    rng.random_range(0.05 * wg..0.95 * wg),
                );
                fd_check(&d, l1, l2);
                // Either order of the arguments.
                fd_check(&d, l2, l1);
            }
        }
    }

    /// Walks a straight path in the (λ1, λ2) plane with a small step and asserts the Hessian changes by
    /// O(step) each step (`bound` is the allowed Lipschitz constant relative to the largest Hessian entry).
    fn hessian_jumps(
        d: &TensionFieldDensity,
        from: (Real, Real),
        to: (Real, Real),
        n: usize,
    ) -> Real {
        let mut worst: Real = 0.0;
        let mut prev = d.derivatives(from.0, from.1).hessian;
        let step_len = ((to.0 - from.0).powi(2) + (to.1 - from.1).powi(2)).sqrt() / n as Real;
        for i in 1..=n {
            let t = i as Real / n as Real;
            let h = d
                .derivatives(from.0 + t * (to.0 - from.0), from.1 + t * (to.1 - from.1))
                .hessian;
            worst = worst.max((h - prev).abs().max() / step_len);
            prev = h;
        }
        worst / d.k
    }

    #[test]
    fn hessian_is_continuous_across_every_transition() {
        let d = cloth();
        let w = d.transition_width();
        let n = 20_000;
        // Slack → wrinkled (λ1 through 1 with λ2 = 0.7), wrinkled → taut (λ2 up through λ̄2 at λ1 = 1.3),
        // slack → taut through the triple point along the diagonal and just off it, and across the
        // diagonal λ1 = λ2 inside the bands.
        let paths = [
            ((0.99, 0.7), (1.03, 0.7)),
            ((1.3, 0.85), (1.3, 0.95)),
            ((0.98, 0.98), (1.04, 1.04)),
            ((0.98, 0.975), (1.04, 1.035)),
            (
                (1.0 + 0.3 * w, 1.0 + 0.7 * w),
                (1.0 + 0.7 * w, 1.0 + 0.3 * w),
            ),
            ((1.5, 1.4), (1.4, 1.5)),
        ];
        for (from, to) in paths {
            // A Lipschitz constant of order 1/w (relative) means continuity; a jump would give ~n.
            let lip = hessian_jumps(&d, from, to, n);
            assert!(
                lip * w < 60.0,
                "Hessian jumps along {from:?} → {to:?}: {lip}"
            );
        }
        // The same walk detects the jumps of the unsmoothed Eq. 129.
        let exact = TensionFieldDensity::new(
            5.4e6,
            0.33,
            &TensionFieldParams {
                transition_width: 0.0,
            },
        )
        .unwrap();
        assert!(hessian_jumps(&exact, (0.99, 0.7), (1.03, 0.7), n) * w > 1000.0);
        assert!(hessian_jumps(&exact, (1.3, 0.85), (1.3, 0.95), n) * w > 1000.0);
    }

    #[test]
    fn gradient_is_continuous_and_energy_c1_along_paths() {
        // Value and gradient steps are O(step) along a path through all bands and the triple point.
        let d = cloth();
        let n = 10_000;
        let (from, to): ((Real, Real), (Real, Real)) = ((0.95, 0.9), (1.2, 1.05));
        let len: Real =
            ((to.0 - from.0) * (to.0 - from.0) + (to.1 - from.1) * (to.1 - from.1)).sqrt();
        let step = len / n as Real;
        let w = d.transition_width();
        let mut prev = d.derivatives(from.0, from.1);
        for i in 1..=n {
            let t = i as Real / n as Real;
            let cur = d.derivatives(from.0 + t * (to.0 - from.0), from.1 + t * (to.1 - from.1));
            let dir = Vec2::new(to.0 - from.0, to.1 - from.1) / n as Real;
            // Trapezoid rule on the directional derivative reproduces the energy change to O(step³)
            // (the third derivative is at most ~9k/w); a jump of the gradient would give O(step).
            let predicted = 0.5 * (prev.gradient + cur.gradient).dot(&dir);
            assert!(
                (cur.value - prev.value - predicted).abs()
                    <= 10.0 * d.k / w * step.powi(3) + 1e-13 * d.k,
                "energy increment at step {i}"
            );
            let dg = (cur.gradient - prev.gradient).abs().max();
            assert!(dg <= 2.0 * d.k * step, "gradient jump at step {i}");
            prev = cur;
        }
    }

    #[test]
    fn symmetric_and_never_compressive() {
        let d = cloth();
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        for _ in 0..500 {
            let (l1, l2) = (rng.random_range(0.5..1.5), rng.random_range(0.5..1.5));
            let (p, q) = (d.derivatives(l1, l2), d.derivatives(l2, l1));
            assert_eq!(p.value, q.value);
            assert_eq!(p.gradient[0], q.gradient[1]);
            assert_eq!(p.hessian[(0, 0)], q.hessian[(1, 1)]);
            assert!(p.gradient.min() >= 0.0);
            // Convex in (λ1, λ2).
            let eig = p.hessian.symmetric_eigenvalues();
            assert!(eig.min() >= -1e-9 * d.k);
        }
    }

    #[test]
    fn gradient_components_agree_on_the_diagonal() {
        // ∂ψ/∂λ1 = ∂ψ/∂λ2 at λ1 = λ2 in every band: the spectral function of C is differentiable there.
        let d = cloth();
        for i in 0..=300 {
            let s = 0.99 + 0.06 * i as Real / 300.0;
            let g = d.derivatives(s, s).gradient;
            assert!((g[0] - g[1]).abs() <= 1e-12 * d.k, "at λ = {s}: {g:?}");
        }
    }

    #[test]
    fn divided_difference_matches_gradient_difference_and_its_limit() {
        let d = cloth();
        let w = d.transition_width();
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for _ in 0..300 {
            let l1: Real = rng.random_range(0.98..1.0 + 4.0 * w);
            let l2: Real = l1 - rng.random_range(1e-3..0.05);
            let g = d.derivatives(l1, l2).gradient;
            let naive = (g[0] - g[1]) / (l1 - l2);
            let dd = d.stretch_divided_difference(l1, l2);
            assert!(
                (dd - naive).abs() <= 1e-8 * d.k,
                "({l1}, {l2}): {dd} vs {naive}"
            );
            assert_eq!(dd, d.stretch_divided_difference(l2, l1));
        }
        // Limit at λ1 = λ2: ψ11 − ψ12, and continuity as the gap closes.
        for s in [0.99, 1.0 + 0.2 * w, 1.0 + 0.7 * w, 1.0 + 1.2 * w, 1.3] {
            let h = d.derivatives(s, s).hessian;
            let lim = h[(0, 0)] - h[(0, 1)];
            assert!((d.stretch_divided_difference(s, s) - lim).abs() <= 1e-10 * d.k);
            for gap in [1e-12, 1e-9, 1e-6] {
                let dd = d.stretch_divided_difference(s + gap, s);
                assert!((dd - lim).abs() <= 1e3 * gap / w * d.k, "gap {gap} at {s}");
            }
        }
    }

    #[test]
    fn bad_material_is_rejected_with_named_field() {
        let p = TensionFieldParams::default();
        let e = TensionFieldDensity::new(-1.0, 0.3, &p).unwrap_err();
        assert!(e.to_string().contains("Young's modulus"));
        assert!(TensionFieldDensity::new(Real::NAN, 0.3, &p).is_err());
        let e = TensionFieldDensity::new(1e6, 1.0, &p).unwrap_err();
        assert!(e.to_string().contains("Poisson"));
        assert!(TensionFieldDensity::new(1e6, -0.1, &p).is_err());
        let e = TensionFieldDensity::new(
            1e6,
            0.3,
            &TensionFieldParams {
                transition_width: -1.0,
            },
        )
        .unwrap_err();
        assert!(e.to_string().contains("transition_width"));
        assert!(TensionFieldDensity::from_lame(1.0, 0.0, &p).is_err());
    }
}
