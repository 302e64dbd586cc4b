//! The change of surface-coordinate chart of cloth vertices that crossed faces: what a Hessian assembled at
//! one state means at another (the chord steps of [`crate::equilibrium`]).
//!
//! A cloth vertex's unknowns are its coordinates `s` in the chart of the face it lies on; a step walks it
//! across faces ([`ClothOnBody::step`]), and then its `s` are coordinates of another chart. A matrix
//! assembled in the old charts does not act on gradients of the new ones. Locally the old coordinates are
//! a function of the new, `s = φ(s')`, with the Jacobian (2 × 2, dimensionless)
//!
//! ```text
//! A = ∂s/∂s' = (JᵀJ)⁻¹ Jᵀ J',      J = ∂x/∂s (old chart),  J' = ∂x/∂s' (new chart)   (3 × 2, m),
//! ```
//!
//! from `J' = J A` (the chain rule; exact where both charts' tangent planes agree, in the least-squares
//! sense elsewhere). Gradients and steps transform as covectors and vectors:
//!
//! ```text
//! g = A⁻ᵀ g',      h' = A⁻¹ h,      H' ≈ Aᵀ H A   (the term of φ's curvature times g dropped),
//! ```
//!
//! so the Newton step of the new chart, `h' = −H'⁻¹ g' = A⁻¹ (−H⁻¹ g)`, is the old chart's step for the
//! rewritten gradient, rewritten back. `J` is taken where the matrix was assembled, `J'` where the vertex is
//! now: for the small moves between a factorization and its reuse, the tangent planes nearly agree.

use super::{ClothOnBody, SurfaceFrames};
use crate::math::FaceId;
use crate::math::{Mat2, Mat3x2, Real};

/// The chart of every cloth vertex's surface coordinates at one state (`#Vc`): the face they are
/// coordinates in and `∂x/∂s` there (3 × 2, m). From [`ClothOnBody::charts`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CoordinateCharts {
    faces: Vec<FaceId>,
    tangents: Vec<Mat3x2>,
}

/// One cloth vertex whose chart changed: its first unknown and `A = ∂s_old/∂s_new` (see the module
/// documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChartChange {
    /// Index of its `s1` in `q` (`s2` follows).
    pub dof: usize,
    /// `∂s_old/∂s_new` (2 × 2, dimensionless).
    pub jacobian: Mat2,
}

impl ChartChange {
    /// `A⁻¹`, `None` when `A` is singular or not finite.
    fn inverse(&self) -> Option<Mat2> {
        self.jacobian
            .try_inverse()
            .filter(|m| m.iter().all(|v| v.is_finite()))
    }

    /// A gradient's two entries in the new chart, rewritten in the old (`g = A⁻ᵀ g'`, in place); `false`
    /// (nothing changed) when `A` is singular.
    pub fn gradient_to_old(&self, q: &mut [Real]) -> bool {
        let Some(inv) = self.inverse() else {
            return false;
        };
        let g = inv.transpose() * crate::math::Vec2::new(q[self.dof], q[self.dof + 1]);
        q[self.dof] = g.x;
        q[self.dof + 1] = g.y;
        true
    }

    /// A step's two entries in the old chart, rewritten in the new (`h' = A⁻¹ h`, in place); `false`
    /// (nothing changed) when `A` is singular.
    pub fn step_to_new(&self, q: &mut [Real]) -> bool {
        let Some(inv) = self.inverse() else {
            return false;
        };
        let h = inv * crate::math::Vec2::new(q[self.dof], q[self.dof + 1]);
        q[self.dof] = h.x;
        q[self.dof + 1] = h.y;
        true
    }
}

impl ClothOnBody {
    /// The charts of the cloth vertices' coordinates at the state `frames` was evaluated at.
    pub fn charts(&self, frames: &SurfaceFrames) -> CoordinateCharts {
        CoordinateCharts {
            faces: frames.0.faces.clone(),
            tangents: frames.0.points.iter().map(|p| p.tangents).collect(),
        }
    }

    /// The free cloth vertices whose face differs between `old` and `new` (both of this system), with
    /// `A = ∂s_old/∂s_new`. Empty when the charts are of another system's size.
    pub fn chart_changes(
        &self,
        old: &CoordinateCharts,
        new: &CoordinateCharts,
    ) -> Vec<ChartChange> {
        let n = self.cloth_dof.len();
        if old.faces.len() != n || new.faces.len() != n {
            return Vec::new();
        }
        self.cloth_dof
            .iter()
            .enumerate()
            .filter_map(|(c, dof)| {
                let dof = (*dof)?;
                (old.faces[c] != new.faces[c]).then(|| {
                    let j = &old.tangents[c];
                    let jt = j.transpose();
                    let jacobian = (jt * j)
                        .try_inverse()
                        .map_or(Mat2::from_element(Real::NAN), |m| m * jt * new.tangents[c]);
                    ChartChange { dof, jacobian }
                })
            })
            .collect()
    }
}
