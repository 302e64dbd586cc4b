//! One linear cloth triangle: `U_e = t A ψ(C)` (thesis Eq. 120–123, 130–132) with the smoothed
//! tension-field density of [`crate::tension_field_density`], its gradient and Hessian with respect to the
//! deformed positions, and its derivatives with respect to the rest (pattern) positions needed by the
//! adjoint (Eq. 164).
//!
//! Conventions and shapes:
//! - deformed corners `x = (x0, x1, x2)`, each in ℝ³ (m), flattened as `x[3i + k]` (9 entries);
//! - rest (pattern) corners `X̄ = (X̄0, X̄1, X̄2)`, each in ℝ² (m), flattened as `X̄[2i + k]` (6 entries);
//! - `Dm = [X̄1 − X̄0, X̄2 − X̄0]` (2 × 2, m), `Ds = [x1 − x0, x2 − x0]` (3 × 2, m),
//!   `F = Ds Dm⁻¹` (3 × 2, Eq. 121), `C = FᵀF` (2 × 2), `A = |det Dm| / 2` (m²), thickness `t` (m).
//!
//! Derivatives go through `C` and its eigenvalues (Eq. 131–132), written as a spectral function so that
//! they stay exact at repeated eigenvalues: with `C = Σ λi ni niᵀ` and `ψi = ∂ψ/∂λi`,
//!
//! ```text
//! S = ∂ψ/∂C = ψ1 n1n1ᵀ + ψ2 n2n2ᵀ,                         P = ∂ψ/∂F = 2 F S,
//! dS[δC] = Σij ψij (njᵀδC nj) ni niᵀ + γ (n1ᵀδC n2)(n1n2ᵀ + n2n1ᵀ),   γ = (ψ1 − ψ2)/(λ1 − λ2).
//! ```
//!
//! `γ` comes from [`crate::tension_field_density::TensionFieldDensity::stretch_divided_difference`], which evaluates it without
//! cancellation and returns its limit `ψ11 − ψ12` at `λ1 = λ2`; there `S = ψ1 I` and
//! `dS = (ψ11 − ψ12) δC + ψ12 tr(δC) I` whatever eigenvectors are picked, so no eigenvector derivative
//! (which blows up like `1/(λ1 − λ2)`) is ever formed. The eigenvalues are
//! `tr C / 2 ± hypot((C11 − C22)/2, C12)`, which avoids the cancellation in `tr(C)²/4 − det C`.

use crate::math::{Mat2, Mat3, Mat3x2, Real, Vec2, Vec3};
use crate::membrane_law::{MembraneDensity, StressTangent};
use crate::tension_field_density::Regime;
use nalgebra::{SMatrix, SVector};

/// 9-vector over the deformed corners, `[3i + k]` (N for forces, m for positions).
pub type Vector9 = SVector<Real, 9>;
/// 6-vector over the rest corners, `[2i + k]`.
pub type Vector6 = SVector<Real, 6>;
/// 9 × 9 matrix over the deformed corners (N/m for a stiffness).
pub type Matrix9 = SMatrix<Real, 9, 9>;
/// 9 × 6 matrix: rows deformed corners `[3i + k]`, columns rest corners `[2j + l]` (N/m).
pub type Matrix9x6 = SMatrix<Real, 9, 6>;

/// A membrane element that cannot be built or evaluated.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MembraneError {
    /// Thickness not finite and positive.
    #[error("cloth thickness must be a finite positive number of metres, got {0}")]
    Thickness(Real),
    /// A rest (pattern) corner is NaN or infinite.
    #[error("pattern corner {corner} of the membrane triangle is not finite: ({x}, {y})")]
    NonFiniteRest {
        /// Corner 0, 1 or 2.
        corner: usize,
        /// Its coordinates (m).
        x: Real,
        /// Its coordinates (m).
        y: Real,
    },
    /// The rest triangle has (nearly) zero area.
    #[error(
        "pattern triangle is degenerate: its area {area:e} m² is below {min_area:e} m² (corners collinear or coincident)"
    )]
    DegeneratePattern {
        /// Rest area (m²).
        area: Real,
        /// Smallest area accepted, relative to the squared longest edge (m²).
        min_area: Real,
    },
    /// A deformed corner is NaN or infinite.
    #[error("deformed corner {corner} of the membrane triangle is not finite: {position:?}")]
    NonFinitePosition {
        /// Corner 0, 1 or 2.
        corner: usize,
        /// Its position (m).
        position: [Real; 3],
    },
    /// The deformed triangle has zero area, so the Cauchy stress (per deformed area) is undefined.
    #[error(
        "deformed membrane triangle has collapsed to zero area; its Cauchy stress is undefined"
    )]
    Collapsed,
}

/// Energy, gradient and Hessian with respect to the deformed corners.
#[derive(Clone, Debug, PartialEq)]
pub struct MembraneDerivatives {
    /// `U_e = t A ψ` (J).
    pub energy: Real,
    /// `∂U_e/∂x` (N), `[3i + k]`; the force on the corners is its negative (Eq. 130).
    pub gradient: Vector9,
    /// `∂²U_e/∂x²` (N/m), symmetric 9 × 9.
    pub hessian: Matrix9,
}

/// Strain and stress of a deformed element, for results.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MembraneState {
    /// Principal stretches `(√λ1, √λ2)` of `F`, largest first (dimensionless).
    pub principal_stretches: [Real; 2],
    /// Regime of `(λ1, λ2)`.
    pub regime: Regime,
    /// Deformed-to-rest area ratio `J = √det C`.
    pub area_ratio: Real,
    /// Unit deformed principal directions `F ni / |F ni|` (3D, tangent to the deformed triangle).
    pub principal_directions: [Vec3; 2],
    /// Principal Cauchy stresses `σi = 2 ψi λi / J` (Pa) along `principal_directions`; never negative.
    /// Multiply by the thickness for a membrane force per length (N/m).
    pub principal_stresses: [Real; 2],
    /// Cauchy stress `σ = F (2S) Fᵀ / J` (Pa), 3 × 3, symmetric, in the plane of the deformed triangle.
    pub cauchy_stress: Mat3,
}

/// Rest shape of one cloth triangle; see the module documentation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MembraneElement {
    rest: [Vec2; 3],
    thickness: Real,
    /// Rest area A (m²).
    area: Real,
    /// Dm⁻¹ (1/m).
    dm_inv: Mat2,
    /// Unit course direction of the fabric in pattern coordinates (the pattern's x turned by the grain
    /// angle); read only by orthotropic laws.
    course: Vec2,
}

/// Everything about `C` and the density that the derivatives share.
struct Spectral {
    f: Mat3x2,
    c: Mat2,
    l: [Real; 2],
    n: [Vec2; 2],
    psi: Real,
    /// `niᵀ S ni` (`∂ψ/∂λi` for an isotropic law).
    d1: Vec2,
    tangent: Option<StressTangent>,
    /// S = ∂ψ/∂C.
    s: Mat2,
}

impl Spectral {
    /// `dS[δC]` (see the module documentation); zero when only first derivatives were evaluated.
    #[inline]
    fn ds(&self, dc: &Mat2) -> Mat2 {
        self.tangent
            .as_ref()
            .map_or_else(Mat2::zeros, |t| t.apply(&self.n, dc))
    }

    /// `dP[δF] = 2 δF S + 2 F dS[δFᵀF + FᵀδF]`.
    #[inline]
    fn dp(&self, df: &Mat3x2) -> Mat3x2 {
        let ftdf = self.f.transpose() * df;
        let dc = ftdf + ftdf.transpose();
        (df * self.s + self.f * self.ds(&dc)) * 2.0
    }
}

/// Gathers a 3 × 2 `∂/∂Ds` into the 9 corner coordinates (`x0` gets minus the sum).
#[inline]
fn scatter_x(g: &Mat3x2) -> Vector9 {
    let mut out = Vector9::zeros();
    for k in 0..3 {
        out[3 + k] = g[(k, 0)];
        out[6 + k] = g[(k, 1)];
        out[k] = -g[(k, 0)] - g[(k, 1)];
    }
    out
}

/// Gathers a 2 × 2 `∂/∂Dm` into the 6 rest corner coordinates.
#[inline]
fn scatter_rest(g: &Mat2) -> Vector6 {
    let mut out = Vector6::zeros();
    for k in 0..2 {
        out[2 + k] = g[(k, 0)];
        out[4 + k] = g[(k, 1)];
        out[k] = -g[(k, 0)] - g[(k, 1)];
    }
    out
}

impl MembraneElement {
    /// A triangle with rest (pattern) corners `rest` (m) and thickness `thickness` (m). The corners may
    /// run either way round; the area must exceed `1e-12` times the squared longest edge.
    pub fn new(rest: [Vec2; 3], thickness: Real) -> Result<Self, MembraneError> {
        if !(thickness.is_finite() && thickness > 0.0) {
            return Err(MembraneError::Thickness(thickness));
        }
        for (corner, p) in rest.iter().enumerate() {
            if !(p.x.is_finite() && p.y.is_finite()) {
                return Err(MembraneError::NonFiniteRest {
                    corner,
                    x: p.x,
                    y: p.y,
                });
            }
        }
        let dm = Mat2::from_columns(&[rest[1] - rest[0], rest[2] - rest[0]]);
        let det = dm.determinant();
        let area = 0.5 * det.abs();
        let longest = (rest[1] - rest[0])
            .norm_squared()
            .max((rest[2] - rest[1]).norm_squared())
            .max((rest[0] - rest[2]).norm_squared());
        let min_area = 1e-12 * longest;
        if !(area > min_area) {
            return Err(MembraneError::DegeneratePattern { area, min_area });
        }
        let dm_inv = Mat2::new(dm[(1, 1)], -dm[(0, 1)], -dm[(1, 0)], dm[(0, 0)]) / det;
        Ok(Self {
            rest,
            thickness,
            area,
            dm_inv,
            course: Vec2::new(1.0, 0.0),
        })
    }

    /// The same triangle with the fabric's course along the pattern direction at `angle` (rad,
    /// counter-clockwise from the pattern's x); the wale runs at `angle + π/2`. Only orthotropic laws read
    /// it. A non-finite angle keeps the course along x.
    pub fn with_grain(mut self, angle: Real) -> Self {
        if angle.is_finite() {
            let (sin, cos) = angle.sin_cos();
            self.course = Vec2::new(cos, sin);
        }
        self
    }

    /// The same triangle with the course along `course` (a unit pattern direction, as [`Self::course`]
    /// returns it).
    pub fn with_course(mut self, course: Vec2) -> Self {
        self.course = course;
        self
    }

    /// Unit course direction in pattern coordinates.
    pub fn course(&self) -> Vec2 {
        self.course
    }

    /// Rest corners (m).
    pub fn rest(&self) -> &[Vec2; 3] {
        &self.rest
    }

    /// Rest area `A` (m²).
    pub fn rest_area(&self) -> Real {
        self.area
    }

    /// Thickness `t` (m).
    pub fn thickness(&self) -> Real {
        self.thickness
    }

    /// Deformation gradient `F = Ds Dm⁻¹` (3 × 2, Eq. 121).
    pub fn deformation_gradient(&self, x: &[Vec3; 3]) -> Result<Mat3x2, MembraneError> {
        for (corner, p) in x.iter().enumerate() {
            if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
                return Err(MembraneError::NonFinitePosition {
                    corner,
                    position: [p.x, p.y, p.z],
                });
            }
        }
        let ds = Mat3x2::from_columns(&[x[1] - x[0], x[2] - x[0]]);
        Ok(ds * self.dm_inv)
    }

    /// `t A` (m³).
    #[inline]
    fn volume(&self) -> Real {
        self.thickness * self.area
    }

    fn spectral<D: MembraneDensity + ?Sized>(
        &self,
        density: &D,
        x: &[Vec3; 3],
        second: bool,
    ) -> Result<Spectral, MembraneError> {
        let f = self.deformation_gradient(x)?;
        let c = f.transpose() * f;
        let (p, q, r) = (c[(0, 0)], c[(0, 1)], c[(1, 1)]);
        let mean = 0.5 * (p + r);
        let half_gap = (0.5 * (p - r)).hypot(q);
        let l = [mean + half_gap, mean - half_gap];
        // Eigenvector of the larger eigenvalue at angle θ = ½ atan2(2C12, C11 − C22) (θ = 0 when C = sI).
        let theta = 0.5 * (2.0 * q).atan2(p - r);
        let (sin, cos) = theta.sin_cos();
        let n = [Vec2::new(cos, sin), Vec2::new(-sin, cos)];
        let r = density.response(&c, l, &n, &self.course, second);
        Ok(Spectral {
            f,
            c,
            l,
            n,
            psi: r.value,
            d1: r.principal,
            tangent: r.tangent,
            s: r.stress,
        })
    }

    /// `U_e = t A ψ` (J, Eq. 123).
    pub fn energy<D: MembraneDensity + ?Sized>(
        &self,
        density: &D,
        x: &[Vec3; 3],
    ) -> Result<Real, MembraneError> {
        let f = self.deformation_gradient(x)?;
        let c = f.transpose() * f;
        let mean = 0.5 * (c[(0, 0)] + c[(1, 1)]);
        let half_gap = (0.5 * (c[(0, 0)] - c[(1, 1)])).hypot(c[(0, 1)]);
        Ok(self.volume()
            * density.energy_density(&c, [mean + half_gap, mean - half_gap], &self.course))
    }

    /// `U_e` (J) and `∂U_e/∂x` (N, 9).
    pub fn energy_gradient<D: MembraneDensity + ?Sized>(
        &self,
        density: &D,
        x: &[Vec3; 3],
    ) -> Result<(Real, Vector9), MembraneError> {
        let sp = self.spectral(density, x, false)?;
        let g = sp.f * sp.s * (2.0 * self.volume()) * self.dm_inv.transpose();
        Ok((self.volume() * sp.psi, scatter_x(&g)))
    }

    /// `U_e` (J), `∂U_e/∂x` (N, 9) and `∂²U_e/∂x²` (N/m, 9 × 9).
    pub fn derivatives<D: MembraneDensity + ?Sized>(
        &self,
        density: &D,
        x: &[Vec3; 3],
    ) -> Result<MembraneDerivatives, MembraneError> {
        let sp = self.spectral(density, x, true)?;
        let vol = self.volume();
        let dm_inv_t = self.dm_inv.transpose();
        let g = sp.f * sp.s * (2.0 * vol) * dm_inv_t;
        // Columns of ∂(∂U/∂Ds)/∂Ds for each unit δDs (edge j, coordinate k), then gathered to corners.
        let mut cols = [Vector9::zeros(); 6];
        for j in 0..2 {
            for k in 0..3 {
                let mut df = Mat3x2::zeros();
                df[(k, 0)] = self.dm_inv[(j, 0)];
                df[(k, 1)] = self.dm_inv[(j, 1)];
                cols[3 * j + k] = scatter_x(&(sp.dp(&df) * vol * dm_inv_t));
            }
        }
        let mut hessian = Matrix9::zeros();
        for k in 0..3 {
            let (c1, c2) = (cols[k], cols[3 + k]);
            hessian.set_column(3 + k, &c1);
            hessian.set_column(6 + k, &c2);
            hessian.set_column(k, &(-c1 - c2));
        }
        Ok(MembraneDerivatives {
            energy: vol * sp.psi,
            gradient: scatter_x(&g),
            hessian,
        })
    }

    /// `∂U_e/∂X̄` (N, 6): the energy's derivative with respect to the rest (pattern) corners at fixed `x`.
    pub fn rest_gradient<D: MembraneDensity + ?Sized>(
        &self,
        density: &D,
        x: &[Vec3; 3],
    ) -> Result<Vector6, MembraneError> {
        let sp = self.spectral(density, x, false)?;
        // δU = tA [ψ tr(Dm⁻¹δDm) − P : (F δDm Dm⁻¹)] = tA (ψ I − FᵀP) Dm⁻ᵀ : δDm.
        let ftp = sp.f.transpose() * sp.f * sp.s * 2.0;
        let g = (Mat2::identity() * sp.psi - ftp) * self.volume() * self.dm_inv.transpose();
        Ok(scatter_rest(&g))
    }

    /// `∂²U_e/∂x∂X̄` (N/m, 9 × 6): how the corner forces change with the rest (pattern) corners, for the
    /// adjoint `∂f/∂p` (Eq. 164).
    pub fn mixed_hessian<D: MembraneDensity + ?Sized>(
        &self,
        density: &D,
        x: &[Vec3; 3],
    ) -> Result<Matrix9x6, MembraneError> {
        let sp = self.spectral(density, x, true)?;
        let (t, a) = (self.thickness, self.area);
        let dm_inv_t = self.dm_inv.transpose();
        let p = sp.f * sp.s * 2.0;
        // G = t A P Dm⁻ᵀ; for each unit δDm (edge j, coordinate k):
        // δA = A tr(Dm⁻¹δDm), δ(Dm⁻¹) = −Dm⁻¹ δDm Dm⁻¹, δF = Ds δ(Dm⁻¹) = −F δDm Dm⁻¹, and
        // δG = t δA P Dm⁻ᵀ + t A dP[δF] Dm⁻ᵀ + t A P δ(Dm⁻¹)ᵀ.
        let mut cols = [Vector9::zeros(); 4];
        for j in 0..2 {
            for k in 0..2 {
                let mut ddm = Mat2::zeros();
                ddm[(k, j)] = 1.0;
                let d_area = a * self.dm_inv[(j, k)];
                let d_inv = -self.dm_inv * ddm * self.dm_inv;
                let df = sp.f * ddm * (-self.dm_inv);
                let dg = p * dm_inv_t * (t * d_area)
                    + sp.dp(&df) * dm_inv_t * (t * a)
                    + p * d_inv.transpose() * (t * a);
                cols[2 * j + k] = scatter_x(&dg);
            }
        }
        let mut out = Matrix9x6::zeros();
        for k in 0..2 {
            let (c1, c2) = (cols[k], cols[2 + k]);
            out.set_column(2 + k, &c1);
            out.set_column(4 + k, &c2);
            out.set_column(k, &(-c1 - c2));
        }
        Ok(out)
    }

    /// Principal stretches, regime and Cauchy stress of the deformed element.
    pub fn state<D: MembraneDensity + ?Sized>(
        &self,
        density: &D,
        x: &[Vec3; 3],
    ) -> Result<MembraneState, MembraneError> {
        let sp = self.spectral(density, x, false)?;
        let j = sp.f.column(0).cross(&sp.f.column(1)).norm();
        if !(j > 0.0) {
            return Err(MembraneError::Collapsed);
        }
        let mut dirs = [Vec3::zeros(); 2];
        let mut stresses = [0.0; 2];
        for i in 0..2 {
            let v = sp.f * sp.n[i];
            let len = v.norm();
            dirs[i] = if len > 0.0 { v / len } else { v };
            stresses[i] = 2.0 * sp.d1[i] * sp.l[i].max(0.0) / j;
        }
        let cauchy = sp.f * (sp.s * 2.0) * sp.f.transpose() / j;
        Ok(MembraneState {
            principal_stretches: [sp.l[0].max(0.0).sqrt(), sp.l[1].max(0.0).sqrt()],
            regime: density.regime_at(&sp.c, sp.l, &self.course),
            area_ratio: j,
            principal_directions: dirs,
            principal_stresses: stresses,
            cauchy_stress: cauchy,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tension_field_density::{TensionFieldDensity, TensionFieldParams};
    use nalgebra::{Rotation2, Rotation3};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use skintight_geometry::finite_difference::{FdParams, check_gradient, check_jacobian};

    const E: Real = 5.4e6;
    const NU: Real = 0.33;
    const T: Real = 1e-4;
    const SIZES: [Real; 2] = [1e-3, 1.0];

    fn cloth() -> TensionFieldDensity {
        TensionFieldDensity::new(E, NU, &TensionFieldParams::default()).unwrap()
    }

    fn random_pattern(rng: &mut ChaCha8Rng, size: Real) -> [Vec2; 3] {
        loop {
            let o = Vec2::new(rng.random_range(-size..size), rng.random_range(-size..size));
            let p = [
                o,
                o + Vec2::new(rng.random_range(-size..size), rng.random_range(-size..size)),
                o + Vec2::new(rng.random_range(-size..size), rng.random_range(-size..size)),
            ];
            let area = 0.5 * (p[1] - p[0]).perp(&(p[2] - p[0])).abs();
            if area > 0.2 * size * size {
                return p;
            }
        }
    }

    fn random_rotation(rng: &mut ChaCha8Rng) -> Rotation3<Real> {
        Rotation3::new(Vec3::new(
            rng.random_range(-3.0..3.0),
            rng.random_range(-3.0..3.0),
            rng.random_range(-3.0..3.0),
        ))
    }

    /// Deformed corners with `C` having eigenvalues `(l1, l2)`: `F = Q diag(√l1, √l2) Vᵀ`, plus a
    /// random rigid motion.
    fn deformed(
        rng: &mut ChaCha8Rng,
        rest: &[Vec2; 3],
        l1: Real,
        l2: Real,
        size: Real,
    ) -> [Vec3; 3] {
        let q = random_rotation(rng)
            .matrix()
            .fixed_view::<3, 2>(0, 0)
            .into_owned();
        let v = Rotation2::new(rng.random_range(-3.0..3.0)).into_inner();
        let f = q * Mat2::new(l1.sqrt(), 0.0, 0.0, l2.sqrt()) * v.transpose();
        let shift = Vec3::new(
            rng.random_range(-size..size),
            rng.random_range(-size..size),
            0.3 * size,
        );
        rest.map(|p| f * p + shift)
    }

    fn flat_x(x: &[Vec3; 3]) -> Vec<Real> {
        x.iter().flat_map(|p| [p.x, p.y, p.z]).collect()
    }

    fn unflat_x(v: &[Real]) -> [Vec3; 3] {
        [0, 1, 2].map(|i| Vec3::new(v[3 * i], v[3 * i + 1], v[3 * i + 2]))
    }

    fn flat_rest(r: &[Vec2; 3]) -> Vec<Real> {
        r.iter().flat_map(|p| [p.x, p.y]).collect()
    }

    fn unflat_rest(v: &[Real]) -> [Vec2; 3] {
        [0, 1, 2].map(|i| Vec2::new(v[2 * i], v[2 * i + 1]))
    }

    fn row_major<const R: usize, const C: usize>(m: &SMatrix<Real, R, C>) -> Vec<Real> {
        (0..R)
            .flat_map(|r| (0..C).map(move |c| m[(r, c)]))
            .collect()
    }

    /// FD settings with a step of `rel_step` times the element size and tolerances scaled by it.
    fn fd(size: Real, x: &[Real], rel_step: Real, rel_tol: Real) -> FdParams {
        let scale = x.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
        FdParams {
            step: rel_step * size / scale,
            rel_tol,
            abs_tol: 1e-12 * T * E * size,
        }
    }

    /// Central-difference checks of the gradient, Hessian, rest gradient and mixed derivative.
    fn check_all(
        d: &TensionFieldDensity,
        rest: &[Vec2; 3],
        x: &[Vec3; 3],
        size: Real,
        rel_step: Real,
        rel_tol: Real,
    ) {
        check_all_grain(d, rest, x, size, rel_step, rel_tol, 0.0)
    }

    /// [`check_all`] for any law, with the course at `grain` (rad) in the pattern.
    fn check_all_grain<D: MembraneDensity>(
        d: &D,
        rest: &[Vec2; 3],
        x: &[Vec3; 3],
        size: Real,
        rel_step: Real,
        rel_tol: Real,
        grain: Real,
    ) {
        let el = MembraneElement::new(*rest, T).unwrap().with_grain(grain);
        let der = el.derivatives(d, x).unwrap();
        let (e, g) = el.energy_gradient(d, x).unwrap();
        assert_eq!(e, der.energy);
        assert!(
            (e - el.energy(d, x).unwrap()).abs() <= 1e-13 * e.abs().max(T * E * size * size * 1e-6)
        );
        assert!((g - der.gradient).abs().max() <= 1e-12 * g.abs().max() + 1e-30);
        let xf = flat_x(x);
        let p = fd(size, &xf, rel_step, rel_tol);
        let ctx = |what: &str, err: skintight_geometry::finite_difference::FdMismatch| {
            panic!(
                "{what} (size {size}, state {:?}): {err}",
                el.state(d, x).map(|s| s.principal_stretches)
            )
        };
        check_gradient(
            |v| el.energy(d, &unflat_x(v)).unwrap(),
            &xf,
            der.gradient.as_slice(),
            &p,
        )
        .unwrap_or_else(|err| ctx("gradient", err));
        let ph = FdParams {
            abs_tol: p.abs_tol / size,
            ..p
        };
        check_jacobian(
            |v| {
                el.energy_gradient(d, &unflat_x(v))
                    .unwrap()
                    .1
                    .as_slice()
                    .to_vec()
            },
            &xf,
            &row_major(&der.hessian),
            &ph,
        )
        .unwrap_or_else(|err| ctx("hessian", err));
        assert!(
            (der.hessian - der.hessian.transpose()).abs().max()
                <= 1e-10 * der.hessian.abs().max() + 1e-30
        );
        // Rest (pattern) derivatives.
        let rf = flat_rest(rest);
        let pr = fd(size, &rf, rel_step, rel_tol);
        let rg = el.rest_gradient(d, x).unwrap();
        check_gradient(
            |v| {
                MembraneElement::new(unflat_rest(v), T)
                    .unwrap()
                    .with_grain(grain)
                    .energy(d, x)
                    .unwrap()
            },
            &rf,
            rg.as_slice(),
            &pr,
        )
        .unwrap_or_else(|err| ctx("rest gradient", err));
        let mixed = el.mixed_hessian(d, x).unwrap();
        check_jacobian(
            |v| {
                MembraneElement::new(unflat_rest(v), T)
                    .unwrap()
                    .with_grain(grain)
                    .energy_gradient(d, x)
                    .unwrap()
                    .1
                    .as_slice()
                    .to_vec()
            },
            &rf,
            &row_major(&mixed),
            &FdParams {
                abs_tol: pr.abs_tol / size,
                ..pr
            },
        )
        .unwrap_or_else(|err| ctx("mixed derivative", err));
    }

    /// `(λ1, λ2)` from `a = λ1 − 1` and `g = λ2 − λ̄2(λ1)`.
    fn at(d: &TensionFieldDensity, a: Real, g: Real) -> (Real, Real) {
        (1.0 + a, d.wrinkling_threshold(1.0 + a) + g)
    }

    #[test]
    fn orthotropic_derivatives_match_finite_differences_in_every_regime_and_grain() {
        // Course soft, wale ten times stiffer (and the reverse), each triangle's grain random: every
        // regime of the relaxed orthotropic law appears and each derivative matches central differences.
        let mut rng = ChaCha8Rng::seed_from_u64(4601);
        for ratio in [10.0, 0.1] {
            let d = crate::orthotropic_density::tests::knit(ratio);
            let mut seen = std::collections::HashSet::new();
            for size in SIZES {
                for _ in 0..30 {
                    let rest = random_pattern(&mut rng, size);
                    let grain = rng.random_range(-3.0..3.0);
                    let (l1, l2) = (rng.random_range(0.7..1.8), rng.random_range(0.7..1.8));
                    let x = deformed(&mut rng, &rest, l1, l2, size);
                    let el = MembraneElement::new(rest, T).unwrap().with_grain(grain);
                    seen.insert(el.state(&d, &x).unwrap().regime);
                    check_all_grain(&d, &rest, &x, size, 1e-7, 1e-5, grain);
                }
            }
            assert_eq!(seen.len(), 3, "{seen:?}");
        }
    }

    #[test]
    fn orthotropic_stress_follows_the_grain() {
        // A strip stretched along the course, whatever the grain angle in the pattern: the Cauchy stress
        // along the course is the course curve's tension over the thickness and the stretch across.
        let d = crate::orthotropic_density::tests::knit(10.0);
        let mut rng = ChaCha8Rng::seed_from_u64(4602);
        for _ in 0..20 {
            let grain: Real = rng.random_range(-3.0..3.0);
            let rest = random_pattern(&mut rng, 0.01);
            let el = MembraneElement::new(rest, T).unwrap().with_grain(grain);
            let s: Real = rng.random_range(1.05..1.8);
            let sw: Real = rng.random_range(0.8..1.0);
            // F maps course to s e_x and wale to sw e_y.
            let (c, w) = (el.course(), Vec2::new(-el.course().y, el.course().x));
            let f = Mat3x2::new(s * c.x, s * c.y, sw * w.x, sw * w.y, 0.0, 0.0);
            let x = rest.map(|p| f * p);
            let st = el.state(&d, &x).unwrap();
            let want = d.course().tension(s - 1.0) / (d.thickness() * sw);
            let along = st.cauchy_stress[(0, 0)];
            assert!((along - want).abs() <= 1e-9 * want, "{along} vs {want}");
            assert!(st.cauchy_stress[(1, 1)].abs() <= 1e-9 * want);
        }
    }

    #[test]
    fn derivatives_match_finite_differences_in_every_regime_and_across_every_band() {
        let d = cloth();
        let w = d.transition_width();
        let wg = (1.0 + NU) * w;
        let mut rng = ChaCha8Rng::seed_from_u64(20);
        for size in SIZES {
            for _ in 0..4 {
                let states = [
                    (
                        Regime::Taut,
                        at(
                            &d,
                            rng.random_range(1.5 * w..0.5),
                            rng.random_range(1.5 * wg..0.3),
                        ),
                    ),
                    (
                        Regime::Wrinkled,
                        at(
                            &d,
                            rng.random_range(1.5 * w..0.5),
                            rng.random_range(-0.4..-0.1 * w),
                        ),
                    ),
                    (Regime::Slack, {
                        let l1 = rng.random_range(0.3..0.99);
                        (l1, rng.random_range(0.2..l1))
                    }),
                    // Slack→wrinkled band, wrinkled→taut band, and both near the triple point.
                    (
                        Regime::Transition,
                        at(
                            &d,
                            rng.random_range(0.05 * w..0.95 * w),
                            rng.random_range(-0.4..-0.05),
                        ),
                    ),
                    (
                        Regime::Transition,
                        at(
                            &d,
                            rng.random_range(2.0 * w..0.5),
                            rng.random_range(0.05 * wg..0.95 * wg),
                        ),
                    ),
                    (
                        Regime::Transition,
                        at(
                            &d,
                            rng.random_range(0.05 * w..0.95 * w),
                            rng.random_range(0.05 * wg..0.5 * wg),
                        ),
                    ),
                ];
                for (regime, (l1, l2)) in states {
                    let rest = random_pattern(&mut rng, size);
                    let x = deformed(&mut rng, &rest, l1, l2, size);
                    let el = MembraneElement::new(rest, T).unwrap();
                    assert_eq!(el.state(&d, &x).unwrap().regime, regime, "({l1}, {l2})");
                    check_all(&d, &rest, &x, size, 1e-6, 1e-5);
                }
            }
        }
    }

    #[test]
    fn derivatives_are_exact_and_continuous_at_repeated_eigenvalues() {
        let d = cloth();
        let w = d.transition_width();
        let mut rng = ChaCha8Rng::seed_from_u64(21);
        for size in SIZES {
            // Taut, both bands at once (near the triple point), and slack, on and near λ1 = λ2.
            for s in [1.2, 1.0 + 0.5 * w, 1.0 + 0.9 * w, 0.995] {
                let rest = random_pattern(&mut rng, size);
                let seed: u64 = rng.random();
                let at_gap = |gap: Real| {
                    let mut r = ChaCha8Rng::seed_from_u64(seed);
                    deformed(&mut r, &rest, s, s - gap, size)
                };
                let el = MembraneElement::new(rest, T).unwrap();
                let h0 = el.derivatives(&d, &at_gap(0.0)).unwrap().hessian;
                let scale = h0.abs().max();
                for gap in [0.0, 1e-12, 1e-8, 1e-5] {
                    let x = at_gap(gap);
                    let der = el.derivatives(&d, &x).unwrap();
                    assert!(der.hessian.iter().all(|v| v.is_finite()));
                    assert!(
                        el.mixed_hessian(&d, &x)
                            .unwrap()
                            .iter()
                            .all(|v| v.is_finite())
                    );
                    // The third derivative of ψ(C) jumps across λ1 = λ2 inside the bands, so use a
                    // small step there; the Hessian itself is continuous.
                    check_all(&d, &rest, &x, size, 1e-8, 1e-4);
                    assert!(
                        (der.hessian - h0).abs().max() <= 1e-3 * scale + 1e-20,
                        "Hessian jumps at gap {gap} (s = {s})"
                    );
                }
            }
        }
    }

    /// Largest relative change of the 9 × 9 Hessian per unit path length in λ along a straight path.
    fn hessian_lipschitz(
        d: &TensionFieldDensity,
        from: (Real, Real),
        to: (Real, Real),
        n: usize,
        seed: u64,
    ) -> Real {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let rest = random_pattern(&mut rng, 0.01);
        let el = MembraneElement::new(rest, T).unwrap();
        let hess = |t: Real| {
            let mut r = ChaCha8Rng::seed_from_u64(seed + 1);
            let x = deformed(
                &mut r,
                &rest,
                from.0 + t * (to.0 - from.0),
                from.1 + t * (to.1 - from.1),
                0.01,
            );
            el.derivatives(d, &x).unwrap().hessian
        };
        let len = ((to.0 - from.0).powi(2) + (to.1 - from.1).powi(2)).sqrt();
        let mut prev = hess(0.0);
        let (mut worst, mut scale): (Real, Real) = (0.0, 0.0);
        for i in 1..=n {
            let h = hess(i as Real / n as Real);
            worst = worst.max((h - prev).abs().max());
            scale = scale.max(h.abs().max());
            prev = h;
        }
        worst / scale / (len / n as Real)
    }

    #[test]
    fn hessian_is_continuous_across_every_transition() {
        let d = cloth();
        let w = d.transition_width();
        let paths = [
            ((0.99, 0.7), (1.03, 0.7)),   // slack → wrinkled
            ((1.3, 0.85), (1.3, 0.95)),   // wrinkled → taut
            ((0.98, 0.98), (1.04, 1.04)), // slack → taut through the triple point, λ1 = λ2
            ((0.98, 0.97), (1.04, 1.03)), // just beside it
            (
                (1.0 + 0.8 * w, 1.0 + 0.2 * w),
                (1.0 + 0.2 * w, 1.0 + 0.8 * w),
            ), // across λ1 = λ2 in the bands
        ];
        for (i, (from, to)) in paths.into_iter().enumerate() {
            let lip = hessian_lipschitz(&d, from, to, 4000, 30 + i as u64);
            // Measured ≤ 7 (relative change per unit λ, times w); the unsmoothed model gives 340–920.
            assert!(
                lip * w < 30.0,
                "Hessian jumps along {from:?} → {to:?}: {lip}"
            );
        }
        // The same walk sees the jumps of the unsmoothed Eq. 129.
        let exact = TensionFieldDensity::new(
            E,
            NU,
            &TensionFieldParams {
                transition_width: 0.0,
            },
        )
        .unwrap();
        assert!(hessian_lipschitz(&exact, paths[0].0, paths[0].1, 4000, 30) * w > 150.0);
        assert!(hessian_lipschitz(&exact, paths[1].0, paths[1].1, 4000, 31) * w > 150.0);
    }

    #[test]
    fn taut_element_equals_plain_stvk() {
        let d = cloth();
        let w = d.transition_width();
        let mut rng = ChaCha8Rng::seed_from_u64(22);
        for size in SIZES {
            for _ in 0..10 {
                let (l1, l2) = at(
                    &d,
                    rng.random_range(1.5 * w..0.6),
                    rng.random_range(1.5 * w..0.4),
                );
                let rest = random_pattern(&mut rng, size);
                let x = deformed(&mut rng, &rest, l1, l2, size);
                let el = MembraneElement::new(rest, T).unwrap();
                let f = el.deformation_gradient(&x).unwrap();
                // Eq. 122 in matrix form, E = (C − I)/2, and its first Piola–Kirchhoff stress.
                let e = (f.transpose() * f - Mat2::identity()) * 0.5;
                let psi = 0.5 * d.lambda() * e.trace().powi(2) + d.mu() * (e * e).trace();
                let u = T * el.rest_area() * psi;
                let pk1 = f * (Mat2::identity() * (d.lambda() * e.trace()) + e * (2.0 * d.mu()));
                let g = scatter_x(&(pk1 * (T * el.rest_area()) * el.dm_inv.transpose()));
                let (ue, ge) = el.energy_gradient(&d, &x).unwrap();
                assert!((ue - u).abs() <= 1e-12 * u);
                assert!((ge - g).abs().max() <= 1e-11 * g.abs().max());
            }
        }
    }

    #[test]
    fn rest_state_and_rigid_placements_have_zero_energy_and_force() {
        let d = cloth();
        let mut rng = ChaCha8Rng::seed_from_u64(23);
        for size in SIZES {
            for _ in 0..10 {
                let rest = random_pattern(&mut rng, size);
                let x = deformed(&mut rng, &rest, 1.0, 1.0, size);
                let el = MembraneElement::new(rest, T).unwrap();
                let der = el.derivatives(&d, &x).unwrap();
                assert!(der.energy.abs() <= 1e-30 * T * E * size * size);
                assert!(der.gradient.abs().max() <= 1e-20 * T * E * size);
                assert!(der.hessian.abs().max() <= 1e-10 * T * E);
                assert!(el.rest_gradient(&d, &x).unwrap().abs().max() <= 1e-20 * T * E * size);
            }
        }
    }

    #[test]
    fn slack_element_has_exactly_zero_energy_force_and_stiffness() {
        let d = cloth();
        let mut rng = ChaCha8Rng::seed_from_u64(24);
        for size in SIZES {
            for _ in 0..10 {
                let l1 = rng.random_range(0.2..0.999);
                let rest = random_pattern(&mut rng, size);
                let l2 = rng.random_range(0.01..l1);
                let x = deformed(&mut rng, &rest, l1, l2, size);
                let el = MembraneElement::new(rest, T).unwrap();
                let der = el.derivatives(&d, &x).unwrap();
                assert_eq!(der.energy, 0.0);
                assert_eq!(der.gradient, Vector9::zeros());
                assert_eq!(der.hessian, Matrix9::zeros());
                assert_eq!(el.mixed_hessian(&d, &x).unwrap(), Matrix9x6::zeros());
                assert_eq!(el.state(&d, &x).unwrap().regime, Regime::Slack);
            }
        }
        // Fully collapsed onto a point.
        let el = MembraneElement::new([Vec2::zeros(), Vec2::x(), Vec2::y()], T).unwrap();
        let der = el.derivatives(&d, &[Vec3::zeros(); 3]).unwrap();
        assert_eq!(der.energy, 0.0);
        assert_eq!(
            el.state(&d, &[Vec3::zeros(); 3]).unwrap_err(),
            MembraneError::Collapsed
        );
    }

    #[test]
    fn energy_is_invariant_under_rigid_motions_of_either_configuration() {
        let d = cloth();
        let w = d.transition_width();
        let mut rng = ChaCha8Rng::seed_from_u64(25);
        for size in SIZES {
            for _ in 0..10 {
                let (l1, l2) = at(
                    &d,
                    rng.random_range(0.2 * w..0.4),
                    rng.random_range(-0.1..0.1),
                );
                let rest = random_pattern(&mut rng, size);
                let x = deformed(&mut rng, &rest, l1, l2, size);
                let el = MembraneElement::new(rest, T).unwrap();
                let der = el.derivatives(&d, &x).unwrap();
                let rot = random_rotation(&mut rng);
                let shift = Vec3::new(rng.random(), rng.random(), rng.random()) * size;
                let moved = x.map(|p| rot * p + shift);
                let dm = el.derivatives(&d, &moved).unwrap();
                assert!((dm.energy - der.energy).abs() <= 1e-12 * der.energy);
                let mut block = Matrix9::zeros();
                for i in 0..3 {
                    block
                        .fixed_view_mut::<3, 3>(3 * i, 3 * i)
                        .copy_from(rot.matrix());
                }
                assert!(
                    (dm.gradient - block * der.gradient).abs().max()
                        <= 1e-10 * der.gradient.abs().max()
                );
                let hr = block * der.hessian * block.transpose();
                assert!((dm.hessian - hr).abs().max() <= 1e-9 * der.hessian.abs().max());
                // Forces balance: no net force from internal stress.
                let net: Vec3 = (0..3)
                    .map(|i| der.gradient.fixed_rows::<3>(3 * i).into_owned())
                    .sum();
                assert!(net.norm() <= 1e-12 * der.gradient.abs().max());
                // Moving the pattern rigidly (even mirroring it) changes nothing.
                let r2 = Rotation2::new(rng.random_range(-3.0..3.0));
                let mirrored = rest.map(|p| {
                    let q = r2 * p;
                    Vec2::new(-q.x, q.y) + Vec2::new(size, -size)
                });
                let em = MembraneElement::new(mirrored, T)
                    .unwrap()
                    .energy(&d, &x)
                    .unwrap();
                assert!((em - der.energy).abs() <= 1e-11 * der.energy);
            }
        }
    }

    #[test]
    fn state_reports_stretches_regime_and_tangent_cauchy_stress() {
        let d = cloth();
        let mut rng = ChaCha8Rng::seed_from_u64(26);
        for (l1, l2, regime) in [
            (1.3, 1.1, Regime::Taut),
            (1.3, 0.8, Regime::Wrinkled),
            (0.9, 0.8, Regime::Slack),
        ] {
            let rest = random_pattern(&mut rng, 0.02);
            let x = deformed(&mut rng, &rest, l1, l2, 0.02);
            let el = MembraneElement::new(rest, T).unwrap();
            let s = el.state(&d, &x).unwrap();
            assert_eq!(s.regime, regime);
            assert!((s.principal_stretches[0] - l1.sqrt()).abs() < 1e-12);
            assert!((s.principal_stretches[1] - l2.sqrt()).abs() < 1e-12);
            assert!((s.area_ratio - (l1 * l2).sqrt()).abs() < 1e-12);
            let g = d.derivatives(l1, l2).gradient;
            let j = (l1 * l2).sqrt();
            let normal = (x[1] - x[0]).cross(&(x[2] - x[0])).normalize();
            assert!((s.cauchy_stress * normal).norm() <= 1e-9 * E);
            for i in 0..2 {
                let expect = 2.0 * g[i] * [l1, l2][i] / j;
                assert!((s.principal_stresses[i] - expect).abs() <= 1e-9 * E);
                let m = s.principal_directions[i];
                assert!((s.cauchy_stress * m - m * s.principal_stresses[i]).norm() <= 1e-9 * E);
                assert!(s.principal_stresses[i] >= 0.0);
            }
            if regime == Regime::Wrinkled {
                assert_eq!(s.principal_stresses[1], 0.0);
                // Uniaxial: σ1 = E ε λ1 / J with the Green strain ε = (λ1 − 1)/2.
                assert!(
                    (s.principal_stresses[0] - E * 0.5 * (l1 - 1.0) * l1 / j).abs() <= 1e-9 * E
                );
            }
        }
    }

    #[test]
    fn bad_input_is_rejected_without_panicking() {
        let d = cloth();
        let tri = [Vec2::zeros(), Vec2::new(0.01, 0.0), Vec2::new(0.0, 0.01)];
        assert!(matches!(
            MembraneElement::new(tri, 0.0),
            Err(MembraneError::Thickness(_))
        ));
        assert!(MembraneElement::new(tri, Real::NAN).is_err());
        let line = [Vec2::zeros(), Vec2::new(0.01, 0.0), Vec2::new(0.02, 0.0)];
        let err = MembraneElement::new(line, T).unwrap_err();
        assert!(err.to_string().contains("degenerate"), "{err}");
        let mut bad = tri;
        bad[2].y = Real::INFINITY;
        let err = MembraneElement::new(bad, T).unwrap_err();
        assert!(err.to_string().contains("corner 2"), "{err}");
        let el = MembraneElement::new(tri, T).unwrap();
        let mut x = [Vec3::zeros(), Vec3::x() * 0.01, Vec3::y() * 0.01];
        x[1].z = Real::NAN;
        let err = el.derivatives(&d, &x).unwrap_err();
        assert!(err.to_string().contains("deformed corner 1"), "{err}");
        assert!(el.energy(&d, &x).is_err());
        assert!(el.mixed_hessian(&d, &x).is_err());
        assert!(el.rest_gradient(&d, &x).is_err());
        assert!(el.state(&d, &x).is_err());
    }
}
