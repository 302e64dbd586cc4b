//! Orthotropic, nonlinear membrane energy density from a fabric's test curves (course, wale, shear),
//! relaxed by tension-field theory where the fabric wrinkles.
//!
//! # The taut law
//!
//! In the fabric's own frame — course `e_c` (the pattern's x turned by the grain angle), wale `e_w` (course
//! turned by +90°) — write the right Cauchy–Green tensor `C = FᵀF` as `x = (C_cc, C_ww, C_cw)`
//! (dimensionless: the squared course and wale stretches and the product of the deformed course and wale
//! fibres, which is the engineering shear strain at small strain). The density (Pa) is a sum of three
//! one-dimensional convex terms, with the fabric thickness `t` (m) turning energy per rest area into energy
//! per volume as the element's `U = t A ψ` expects:
//!
//! ```text
//! ψ(x) = f_c(C_cc) + f_w(C_ww) + f_s(C_cw),
//! f(c) = W(√c − 1) / t            (c ≥ 1),      f(c) = κ (c − 1)² / 2,  κ = T'(0) / (4t)   (c < 1),
//! f_s(γ) = W_s(|γ|) / t,
//! ```
//!
//! where `W = ∫T` is the integral of the course (wale) curve of [`crate::tension_curve`] and `W_s` that of
//! the shear curve (odd extension). Derivatives by the chain rule in `s = √c`:
//! `f' = T / (2 s t)`, `f'' = (T' s − T) / (4 s³ t)`, `f_s' = sign(γ) T_s / t`, `f_s'' = T_s' / t`; at `c = 1`
//! both branches have `f = f' = 0` and `f'' = κ`, so `f` is C². The nominal tension of a strip pulled along
//! the course with the wale free is `t ∂ψ/∂s = 2 s t f_c' = T`: the curve itself, because no term couples
//! course and wale (strip curves measure no Poisson effect, and a knit's lateral contraction is taken up by
//! wrinkling in the relaxation below). `f_c` is convex in `C` when `T'(1 + ε) ≥ T` along the curve
//! (checked in [`OrthotropicDensity::new`]); `f_s` is convex because `T_s` rises. So `ψ` is strictly
//! convex in `x`.
//!
//! # Tension-field relaxation for an orthotropic law
//!
//! A wrinkled membrane's apparent metric `C` is shorter than the metric `C' = C + D` its material is
//! strained to, by a positive semi-definite `D` that the wrinkles absorb; the relaxed energy (Pipkin 1986,
//! *IMA J. Appl. Math.* 36) is the least energy over all such wrinkle strains,
//!
//! ```text
//! ψ_rel(C) = min_{D ⪰ 0} ψ(C + D).
//! ```
//!
//! This is a convex problem, so its KKT conditions characterise the minimum: with `S = ∂ψ/∂C` at `C'`,
//! `S ⪰ 0`, `D ⪰ 0`, `S : D = 0` — the stress is never compressive, and the wrinkles lie across a
//! stress-free direction. Its three regimes are the ranks of `D`:
//! - **taut** (`D = 0`): `S(C) ⪰ 0`, both principal stresses tensile; `ψ_rel = ψ`;
//! - **slack** (`D` of rank 2, so `S = 0` and `C' = I`): `I − C ⪰ 0`, no fibre longer than at rest;
//!   `ψ_rel = 0`;
//! - **wrinkled** (`D = v vᵀ` of rank 1) otherwise: `S(C')` has rank one with null vector `v`, uniaxial
//!   tension across the wrinkles. For the isotropic StVK law this is Eq. 126–127 of the thesis (there `v` is
//!   the minor principal direction of `C`); for an orthotropic law `v` is generally *not* a principal
//!   direction of `C` — wrinkles in a knit pulled on the bias turn toward its stiff direction — so it is
//!   solved for. With `d(v) = (v1², v2², v1 v2)`, `g(v) = ψ(x + d(v))` is minimised over `v ∈ ℝ²`
//!   (Newton with backtracking from `v = √β m`, `m` the eigenvector of `S(C)`'s negative eigenvalue and `β`
//!   the 1-D minimiser along it). A stationary `v` with `S(C') ⪰ 0` satisfies the KKT conditions, so it is
//!   the global minimum.
//!
//! Derivatives: by the envelope theorem `∂ψ_rel/∂x = p(x + d(v*)) = (f_c', f_w', f_s')` in every regime.
//! In the wrinkled regime, with `H = diag(f_c'', f_w'', f_s'')` at `C'`, `J = ∂d/∂v`,
//! `A = ∂²g/∂v² = JᵀHJ + [[2p1, p3], [p3, 2p2]]` and `B = ∂²g/∂x∂v = HJ`, the implicit function theorem
//! on `∂g/∂v = 0` gives
//!
//! ```text
//! ∂²ψ_rel/∂x² = H − B A⁻¹ Bᵀ,
//! ```
//!
//! the Schur complement of the positive semi-definite Hessian of `(x, v) ↦ ψ(x + d(v))` (`[I J]ᵀ H [I J]`
//! plus `diag(0, 2S)`), hence positive semi-definite: `ψ_rel` is convex in `C` in every regime (tested).
//! At the regime boundaries `ψ_rel` is C¹ — value and stress are continuous — and its Hessian jumps, as in
//! the thesis's exact Eq. 129 (the isotropic [`crate::tension_field_density`] additionally smooths these
//! jumps with C² ramps; no such smoothing is done here).
//!
//! Units: `x` dimensionless; `ψ` and its derivatives in Pa; `t` in m.

use crate::math::{Mat2, Mat3, Real, Vec2, Vec3};
use crate::tension_curve::{CurveError, TensionCurve};
use crate::tension_field_density::Regime;

/// A fabric law that cannot be built; `key` names the curve (`course`, `wale` or `shear`).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum OrthotropicError {
    /// A curve is not a monotone tension law.
    #[error("{key} curve: {source}")]
    Curve {
        /// `course`, `wale` or `shear`.
        key: &'static str,
        /// What is wrong with it.
        source: CurveError,
    },
    /// A curve softens faster than the stretch grows, so the energy would not be convex in `C`.
    #[error(
        "{key} curve: its tension {tension:.4} N/m at elongation {elongation:.4} exceeds slope × (1 + elongation); the curve softens too fast to be a convex membrane law — add points or smooth the plateau"
    )]
    NotConvex {
        /// `course` or `wale`.
        key: &'static str,
        /// Where (dimensionless).
        elongation: Real,
        /// The tension there (N/m).
        tension: Real,
    },
    /// Thickness not finite and positive.
    #[error("fabric thickness must be a finite positive number of metres, got {0}")]
    Thickness(Real),
}

/// Value, gradient and Hessian of ψ_rel with respect to `x = (C_cc, C_ww, C_cw)` in the fabric frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrthotropicDerivatives {
    /// ψ_rel (Pa).
    pub value: Real,
    /// `∂ψ_rel/∂x` (Pa).
    pub gradient: Vec3,
    /// `∂²ψ_rel/∂x²` (Pa), symmetric 3 × 3, positive semi-definite.
    pub hessian: Mat3,
    /// Taut, wrinkled or slack.
    pub regime: Regime,
}

/// The orthotropic relaxed membrane density; see the module documentation.
#[derive(Clone, Debug, PartialEq)]
pub struct OrthotropicDensity {
    course: TensionCurve,
    wale: TensionCurve,
    shear: TensionCurve,
    thickness: Real,
}

/// `(f, f', f'')` of a stretch term at `c` (Pa).
#[inline]
fn stretch_term(curve: &TensionCurve, c: Real, t: Real) -> (Real, Real, Real) {
    if c >= 1.0 {
        let s = c.sqrt();
        let (w, tension, slope) = curve.evaluate(s - 1.0);
        (
            w / t,
            tension / (2.0 * s * t),
            (slope * s - tension) / (4.0 * s * s * s * t),
        )
    } else {
        let kappa = curve.initial_slope() / (4.0 * t);
        let d = c - 1.0;
        (0.5 * kappa * d * d, kappa * d, kappa)
    }
}

/// Taut ψ, its gradient `p` and diagonal Hessian `h` at `x`.
struct Taut {
    value: Real,
    p: Vec3,
    h: Vec3,
}

impl OrthotropicDensity {
    /// From the three curves (`[elongation, N/m]` points, see [`TensionCurve::new`]; the shear curve's
    /// "elongation" is the shear strain `C_cw`) and the fabric thickness (m).
    pub fn new(
        course: &[[Real; 2]],
        wale: &[[Real; 2]],
        shear: &[[Real; 2]],
        thickness: Real,
    ) -> Result<Self, OrthotropicError> {
        if !(thickness.is_finite() && thickness > 0.0) {
            return Err(OrthotropicError::Thickness(thickness));
        }
        let curve = |key: &'static str, points: &[[Real; 2]]| {
            TensionCurve::new(points).map_err(|source| OrthotropicError::Curve { key, source })
        };
        let (course, wale, shear) = (
            curve("course", course)?,
            curve("wale", wale)?,
            curve("shear", shear)?,
        );
        for (key, c) in [("course", &course), ("wale", &wale)] {
            let (margin, elongation) = c.convexity_margin();
            if margin < 0.0 {
                return Err(OrthotropicError::NotConvex {
                    key,
                    elongation,
                    tension: c.tension(elongation),
                });
            }
        }
        Ok(Self {
            course,
            wale,
            shear,
            thickness,
        })
    }

    /// The course curve.
    pub fn course(&self) -> &TensionCurve {
        &self.course
    }

    /// The wale curve.
    pub fn wale(&self) -> &TensionCurve {
        &self.wale
    }

    /// The shear curve.
    pub fn shear(&self) -> &TensionCurve {
        &self.shear
    }

    /// Thickness `t` (m).
    pub fn thickness(&self) -> Real {
        self.thickness
    }

    fn taut_at(&self, x: &Vec3) -> Taut {
        let t = self.thickness;
        let (a, da, dda) = stretch_term(&self.course, x[0], t);
        let (b, db, ddb) = stretch_term(&self.wale, x[1], t);
        let (w, ts, dts) = self.shear.evaluate(x[2].abs());
        Taut {
            value: a + b + w / t,
            p: Vec3::new(da, db, x[2].signum() * ts / t),
            h: Vec3::new(dda, ddb, dts / t),
        }
    }

    /// The unrelaxed (taut) law ψ(x) (Pa).
    pub fn taut(&self, x: &Vec3) -> Real {
        self.taut_at(x).value
    }

    /// Regime at `x`.
    pub fn regime(&self, x: &Vec3) -> Regime {
        if slack(x) {
            Regime::Slack
        } else if stress_psd(&self.taut_at(x).p) {
            Regime::Taut
        } else {
            Regime::Wrinkled
        }
    }

    /// ψ_rel (Pa).
    pub fn value(&self, x: &Vec3) -> Real {
        self.derivatives(x).value
    }

    /// ψ_rel with its gradient and Hessian in `x` (Pa).
    pub fn derivatives(&self, x: &Vec3) -> OrthotropicDerivatives {
        if slack(x) {
            return OrthotropicDerivatives {
                value: 0.0,
                gradient: Vec3::zeros(),
                hessian: Mat3::zeros(),
                regime: Regime::Slack,
            };
        }
        let taut = self.taut_at(x);
        if stress_psd(&taut.p) {
            return OrthotropicDerivatives {
                value: taut.value,
                gradient: taut.p,
                hessian: Mat3::from_diagonal(&taut.h),
                regime: Regime::Taut,
            };
        }
        let v = self.wrinkle(x, &taut.p);
        let y = x + d(&v);
        let at = self.taut_at(&y);
        let j = jac(&v);
        let hd = Mat3::from_diagonal(&at.h);
        let a = j.transpose() * hd * j + Mat2::new(2.0 * at.p[0], at.p[2], at.p[2], 2.0 * at.p[1]);
        let b = hd * j;
        let hessian = match a.try_inverse() {
            Some(ai) => {
                let h = hd - b * ai * b.transpose();
                0.5 * (h + h.transpose())
            }
            None => hd,
        };
        OrthotropicDerivatives {
            value: at.value,
            gradient: at.p,
            hessian,
            regime: Regime::Wrinkled,
        }
    }

    /// The wrinkle vector `v` (`D = v vᵀ`) of a wrinkled state; `p` is the taut stress at `x`.
    fn wrinkle(&self, x: &Vec3, p: &Vec3) -> Vec2 {
        // Start: the eigenvector of S(C)'s smallest eigenvalue, and the 1-D minimiser along it.
        let s = Mat2::new(p[0], 0.5 * p[2], 0.5 * p[2], p[1]);
        let eig = s.symmetric_eigen();
        let i = if eig.eigenvalues[0] <= eig.eigenvalues[1] {
            0
        } else {
            1
        };
        let m: Vec2 = eig.eigenvectors.column(i).into_owned();
        let dm = d(&m);
        let slope = |beta: Real| self.taut_at(&(x + dm * beta)).p.dot(&dm);
        let (mut lo, mut hi) = (0.0, 0.01);
        let mut grown = 0;
        while slope(hi) < 0.0 && grown < 200 {
            lo = hi;
            hi *= 2.0;
            grown += 1;
        }
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if slope(mid) < 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
            if hi - lo <= 1e-6 * hi {
                break;
            }
        }
        let mut v = m * (0.5 * (lo + hi)).sqrt();
        // Newton on g(v) = ψ(x + d(v)): backtracking on g while far, and near the minimum (where g
        // changes below its rounding) full steps while they shrink the gradient.
        let g = |v: &Vec2| self.taut_at(&(x + d(v))).value;
        let grad_hess = |v: &Vec2| {
            let at = self.taut_at(&(x + d(v)));
            let j = jac(v);
            let a = j.transpose() * Mat3::from_diagonal(&at.h) * j
                + Mat2::new(2.0 * at.p[0], at.p[2], at.p[2], 2.0 * at.p[1]);
            (j.transpose() * at.p, a)
        };
        let mut gv = g(&v);
        let (mut grad, mut a) = grad_hess(&v);
        for _ in 0..100 {
            let step = match a.cholesky() {
                Some(ch) => -ch.solve(&grad),
                None => -grad / (a.norm() + Real::MIN_POSITIVE),
            };
            if !(step.norm() > 1e-16 * v.norm()) {
                break;
            }
            let mut alpha = 1.0;
            let mut next = None;
            for _ in 0..60 {
                let trial = v + step * alpha;
                let gt = g(&trial);
                let (gr, at) = grad_hess(&trial);
                if gt <= gv + 1e-4 * alpha * grad.dot(&step)
                    || (alpha == 1.0 && gt <= gv + 1e-12 * gv.abs() && gr.norm() < grad.norm())
                {
                    next = Some((trial, gt, gr, at));
                    break;
                }
                alpha *= 0.5;
            }
            match next {
                Some((trial, gt, gr, at)) => {
                    v = trial;
                    gv = gt;
                    grad = gr;
                    a = at;
                }
                None => break,
            }
        }
        v
    }
}

/// `I − C ⪰ 0`.
#[inline]
fn slack(x: &Vec3) -> bool {
    let (a, b) = (1.0 - x[0], 1.0 - x[1]);
    a >= 0.0 && b >= 0.0 && a * b >= x[2] * x[2]
}

/// `S = [[p1, p3/2], [p3/2, p2]] ⪰ 0`.
#[inline]
fn stress_psd(p: &Vec3) -> bool {
    p[0] >= 0.0 && p[1] >= 0.0 && p[0] * p[1] >= 0.25 * p[2] * p[2]
}

/// `d(v) = (v1², v2², v1 v2)`: the Voigt form of `v vᵀ`.
#[inline]
fn d(v: &Vec2) -> Vec3 {
    Vec3::new(v[0] * v[0], v[1] * v[1], v[0] * v[1])
}

/// `∂d/∂v` (3 × 2).
#[inline]
fn jac(v: &Vec2) -> nalgebra::Matrix3x2<Real> {
    nalgebra::Matrix3x2::new(2.0 * v[0], 0.0, 0.0, 2.0 * v[1], v[1], v[0])
}

/// The stress `S = ∂ψ/∂C` as a symmetric 2 × 2 matrix from the Voigt gradient `p`.
pub fn stress_matrix(p: &Vec3) -> Mat2 {
    Mat2::new(p[0], 0.5 * p[2], 0.5 * p[2], p[1])
}

#[cfg(test)]
pub(crate) mod tests;
