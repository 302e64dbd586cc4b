//! The membrane law a cloth triangle evaluates: the isotropic tension-field StVK density
//! ([`crate::tension_field_density`], a function of the eigenvalues of `C`) or the orthotropic curve law
//! ([`crate::orthotropic_density`], a function of `C` in the fabric's course/wale frame), behind one trait
//! that gives the element `ψ`, `S = ∂ψ/∂C` and the linear map `δC ↦ δS`.
//!
//! For the isotropic law everything is computed exactly as before this trait existed (the spectral
//! form of [`crate::membrane_element`]), so its results are bit for bit the same. For the orthotropic law,
//! with `R = [e_c e_w]` the course and wale unit directions in pattern coordinates (2 × 2, orthonormal),
//! `C_f = Rᵀ C R`, `x = (C_f11, C_f22, C_f12)`, and the density's Voigt gradient `p` and Hessian `H`:
//!
//! ```text
//! S = R S_f Rᵀ,  S_f = [[p1, p3/2], [p3/2, p2]],
//! dS[δC] = R S_f(H x(Rᵀ δC R)) Rᵀ,
//! ```
//!
//! which is the chain rule through the linear maps `C ↦ C_f ↦ x` (the factor ½ because `C12` and `C21`
//! both carry the single `x3`). Units: `C` dimensionless, `ψ`, `S` in Pa.

use crate::math::{Mat2, Mat3, Real, Vec2, Vec3};
use crate::orthotropic_density::{OrthotropicDensity, stress_matrix};
use crate::tension_field_density::{Regime, TensionFieldDensity};

/// How `S` changes with `C` at a state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StressTangent {
    /// Isotropic spectral form: `∂²ψ/∂λi∂λj` and the divided difference `(ψ1 − ψ2)/(λ1 − λ2)` (Pa).
    Spectral {
        /// `∂²ψ/∂λi∂λj` (Pa).
        hessian: Mat2,
        /// `(ψ1 − ψ2)/(λ1 − λ2)` (Pa).
        divided_difference: Real,
    },
    /// Orthotropic: the Voigt Hessian `H` in the fabric frame and the frame `R = [e_c e_w]`.
    Voigt {
        /// `∂²ψ/∂x²` (Pa).
        hessian: Mat3,
        /// `R` (columns course and wale, pattern coordinates).
        frame: Mat2,
    },
}

/// ψ, `S` and what the element needs for the second derivative at a state `C`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DensityResponse {
    /// ψ (Pa).
    pub value: Real,
    /// `S = ∂ψ/∂C` in pattern coordinates (Pa), symmetric 2 × 2.
    pub stress: Mat2,
    /// `niᵀ S ni` along the principal directions of `C` (Pa): `∂ψ/∂λi` for an isotropic law.
    pub principal: Vec2,
    /// For `dS`; `None` when only first derivatives were asked for.
    pub tangent: Option<StressTangent>,
}

impl StressTangent {
    /// `dS[δC]` (Pa) given the eigenvectors `n` of `C` (used by the spectral form only).
    #[inline]
    pub fn apply(&self, n: &[Vec2; 2], dc: &Mat2) -> Mat2 {
        match self {
            StressTangent::Spectral {
                hessian,
                divided_difference,
            } => {
                let [n1, n2] = *n;
                let dl1 = n1.dot(&(dc * n1));
                let dl2 = n2.dot(&(dc * n2));
                let off = n1.dot(&(dc * n2));
                let c1 = hessian[(0, 0)] * dl1 + hessian[(0, 1)] * dl2;
                let c2 = hessian[(1, 0)] * dl1 + hessian[(1, 1)] * dl2;
                let m12 = n1 * n2.transpose();
                n1 * n1.transpose() * c1
                    + n2 * n2.transpose() * c2
                    + (m12 + m12.transpose()) * (divided_difference * off)
            }
            StressTangent::Voigt { hessian, frame } => {
                let dcf = frame.transpose() * dc * frame;
                let dp = hessian * Vec3::new(dcf[(0, 0)], dcf[(1, 1)], dcf[(0, 1)]);
                frame * stress_matrix(&dp) * frame.transpose()
            }
        }
    }
}

/// A membrane energy density of `C`; see the module documentation.
pub trait MembraneDensity {
    /// ψ (Pa) at `C` whose eigenvalues are `l` (largest first), for a triangle whose course runs along
    /// the unit pattern direction `course`.
    fn energy_density(&self, c: &Mat2, l: [Real; 2], course: &Vec2) -> Real;
    /// ψ, `S` and (if `second`) the tangent; `n` are the unit eigenvectors of `C` for `l`.
    fn response(
        &self,
        c: &Mat2,
        l: [Real; 2],
        n: &[Vec2; 2],
        course: &Vec2,
        second: bool,
    ) -> DensityResponse;
    /// The regime at `C`.
    fn regime_at(&self, c: &Mat2, l: [Real; 2], course: &Vec2) -> Regime;
}

impl MembraneDensity for TensionFieldDensity {
    #[inline]
    fn energy_density(&self, _c: &Mat2, l: [Real; 2], _course: &Vec2) -> Real {
        self.value(l[0], l[1])
    }

    #[inline]
    fn response(
        &self,
        _c: &Mat2,
        l: [Real; 2],
        n: &[Vec2; 2],
        _course: &Vec2,
        second: bool,
    ) -> DensityResponse {
        let der = self.derivatives(l[0], l[1]);
        let gamma = if second {
            self.stretch_divided_difference(l[0], l[1])
        } else {
            0.0
        };
        let s =
            n[0] * n[0].transpose() * der.gradient[0] + n[1] * n[1].transpose() * der.gradient[1];
        DensityResponse {
            value: der.value,
            stress: s,
            principal: der.gradient,
            tangent: second.then_some(StressTangent::Spectral {
                hessian: der.hessian,
                divided_difference: gamma,
            }),
        }
    }

    fn regime_at(&self, _c: &Mat2, l: [Real; 2], _course: &Vec2) -> Regime {
        self.regime(l[0], l[1])
    }
}

/// The frame `R = [e_c e_w]` of a course direction (wale = course turned by +90°).
#[inline]
fn frame(course: &Vec2) -> Mat2 {
    Mat2::new(course.x, -course.y, course.y, course.x)
}

/// `x = (C_f11, C_f22, C_f12)` of `C` in the frame.
#[inline]
fn fabric_voigt(c: &Mat2, r: &Mat2) -> Vec3 {
    let cf = r.transpose() * c * r;
    Vec3::new(cf[(0, 0)], cf[(1, 1)], cf[(0, 1)])
}

impl MembraneDensity for OrthotropicDensity {
    fn energy_density(&self, c: &Mat2, _l: [Real; 2], course: &Vec2) -> Real {
        self.value(&fabric_voigt(c, &frame(course)))
    }

    fn response(
        &self,
        c: &Mat2,
        _l: [Real; 2],
        n: &[Vec2; 2],
        course: &Vec2,
        second: bool,
    ) -> DensityResponse {
        let r = frame(course);
        let der = self.derivatives(&fabric_voigt(c, &r));
        let s = r * stress_matrix(&der.gradient) * r.transpose();
        DensityResponse {
            value: der.value,
            stress: s,
            principal: Vec2::new(n[0].dot(&(s * n[0])), n[1].dot(&(s * n[1]))),
            tangent: second.then_some(StressTangent::Voigt {
                hessian: der.hessian,
                frame: r,
            }),
        }
    }

    fn regime_at(&self, c: &Mat2, _l: [Real; 2], course: &Vec2) -> Regime {
        self.regime(&fabric_voigt(c, &frame(course)))
    }
}

/// The law of a garment's fabric.
#[derive(Clone, Debug, PartialEq)]
pub enum MembraneLaw {
    /// The isotropic tension-field StVK membrane (Young's modulus, Poisson's ratio).
    Isotropic(TensionFieldDensity),
    /// The orthotropic law from course, wale and shear curves.
    Orthotropic(OrthotropicDensity),
}

impl MembraneDensity for MembraneLaw {
    #[inline]
    fn energy_density(&self, c: &Mat2, l: [Real; 2], course: &Vec2) -> Real {
        match self {
            MembraneLaw::Isotropic(d) => d.energy_density(c, l, course),
            MembraneLaw::Orthotropic(d) => d.energy_density(c, l, course),
        }
    }

    #[inline]
    fn response(
        &self,
        c: &Mat2,
        l: [Real; 2],
        n: &[Vec2; 2],
        course: &Vec2,
        second: bool,
    ) -> DensityResponse {
        match self {
            MembraneLaw::Isotropic(d) => d.response(c, l, n, course, second),
            MembraneLaw::Orthotropic(d) => d.response(c, l, n, course, second),
        }
    }

    fn regime_at(&self, c: &Mat2, l: [Real; 2], course: &Vec2) -> Regime {
        match self {
            MembraneLaw::Isotropic(d) => d.regime_at(c, l, course),
            MembraneLaw::Orthotropic(d) => d.regime_at(c, l, course),
        }
    }
}
