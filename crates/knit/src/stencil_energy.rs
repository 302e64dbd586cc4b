//! The family of per-vertex rod energies on the 11-unknown stencil of a rod vertex (its two edges' end
//! points, 9 positions in m, and their 2 twist angles in rad): bending ([`crate::bending`]) and twisting
//! ([`crate::twisting`]). An implementor writes its energy (J) once, generic over the scalar type; the
//! value, the gradient and the Hessian (J per unknown, J per unknown²) then come from second-order forward
//! differentiation of that one expression ([`crate::jet`]), exact to rounding — each implementor's tests
//! check them against central finite differences.

use crate::jet::{Jet, Scalar, value_gradient_hessian};

/// Unknowns of a rod-vertex stencil: `x_{i−1}, x_i, x_{i+1}` (m) and the twists `θ_{i−1}, θ_i` (rad).
pub const STENCIL_DOFS: usize = 11;

/// A per-vertex rod energy (see the module documentation).
pub trait StencilEnergy {
    /// The energy (J) at the stencil unknowns `q`, for any scalar type (plain numbers or jets).
    fn energy_of<S: Scalar>(&self, q: &[S; STENCIL_DOFS]) -> S;

    /// The energy (J).
    fn energy(&self, q: &[f64; STENCIL_DOFS]) -> f64 {
        self.energy_of(q)
    }

    /// Energy (J), gradient and Hessian over the 11 stencil unknowns.
    #[allow(clippy::type_complexity)]
    fn derivatives(
        &self,
        q: &[f64; STENCIL_DOFS],
    ) -> (
        f64,
        [f64; STENCIL_DOFS],
        [[f64; STENCIL_DOFS]; STENCIL_DOFS],
    ) {
        value_gradient_hessian(q, |v: &[Jet<STENCIL_DOFS>; STENCIL_DOFS]| self.energy_of(v))
    }
}
