//! The design-term abstraction: every objective (shape, stretch window, pressure, seam traction, sliding)
//! and every regularizer (seam length, smoothness, edge length, compactness, pinned traction) is a
//! [`Term`] evaluated on the worn garment's cloth positions `x` (`#Vc × 3`, m) and the pattern positions
//! `X̄` (`#Vp × 2`, m) — after polyfem's one-form-per-energy.
//!
//! The design gradient `dT/dp` is assembled elsewhere from the two partial derivatives a term reports:
//! `∂T/∂x` goes through the adjoint solve (thesis Eq. 160–164), `∂T/∂X̄` directly through the design map.
//! Terms that are a weighted sum of squares `T = Σ r_k²` also expose their residuals and the residuals'
//! sparse Jacobian, for the adjoint Gauss-Newton optimizer.

use crate::design_mesh::DesignMesh;
use crate::math::{Real, Vec2, Vec3};
use skintight_physics::membrane_law::{DensityResponse, MembraneDensity};
use skintight_physics::orthotropic_density::OrthotropicDensity;
use skintight_physics::{ClothOnBody, ClothOnBodyState, TensionFieldDensity};

/// The fabric, for terms that need stresses: the isotropic tension-field membrane, or (issue 46) an
/// orthotropic curve law with the course direction of every cloth triangle in its pattern plane.
///
/// The course directions are an input of the design, held fixed while the pattern moves (the grain line
/// the cut-ready pattern draws for each piece): a term's derivative with respect to the pattern is taken
/// at fixed grain.
#[derive(Clone, Debug)]
pub struct Fabric {
    /// The smoothed tension-field density (Pa): the membrane's law when `orthotropic` is `None`.
    pub density: TensionFieldDensity,
    /// Thickness (m).
    pub thickness: Real,
    /// The orthotropic curve law the membrane follows instead of `density`, if any.
    pub orthotropic: Option<OrthotropicDensity>,
    /// `#Fc` unit course direction of each cloth triangle (pattern plane); empty for the pattern's x
    /// everywhere. Read only by an orthotropic law.
    pub course: Vec<Vec2>,
}

impl Fabric {
    /// The isotropic fabric of `density` and `thickness` (m).
    pub fn isotropic(density: TensionFieldDensity, thickness: Real) -> Self {
        Self {
            density,
            thickness,
            orthotropic: None,
            course: Vec::new(),
        }
    }

    /// The unit course direction of cloth triangle `f` (pattern plane).
    pub fn course_of(&self, f: usize) -> Vec2 {
        self.course.get(f).copied().unwrap_or(Vec2::new(1.0, 0.0))
    }

    /// The law a membrane element evaluates (the orthotropic one if given, else the isotropic density).
    pub fn law(&self) -> &dyn MembraneDensity {
        match &self.orthotropic {
            Some(o) => o,
            None => &self.density,
        }
    }

    /// `ψ`, `∂ψ/∂C` (Pa, pattern coordinates; the second Piola–Kirchhoff stress is twice it) and, if
    /// `second`, its tangent, of cloth triangle `f` at `C` with eigenvalues `mu` (largest first) and unit
    /// eigenvectors `n`.
    pub fn response(
        &self,
        f: usize,
        c: &crate::math::Mat2,
        mu: [Real; 2],
        n: &[Vec2; 2],
        second: bool,
    ) -> DensityResponse {
        self.law().response(c, mu, n, &self.course_of(f), second)
    }

    /// A membrane element of cloth triangle `f` over pattern corners `rest` with this fabric's thickness
    /// and the triangle's grain.
    pub fn element(
        &self,
        f: usize,
        rest: [Vec2; 3],
    ) -> Result<skintight_physics::MembraneElement, skintight_physics::MembraneError> {
        let c = self.course_of(f);
        skintight_physics::MembraneElement::new(rest, self.thickness).map(|e| e.with_course(c))
    }
}

/// What a term is evaluated on.
#[derive(Clone, Copy, Debug)]
pub struct TermInput<'a> {
    /// Connectivity.
    pub mesh: &'a DesignMesh,
    /// `#Vc` cloth vertex positions (m).
    pub cloth: &'a [Vec3],
    /// `#Vp` pattern (rest) positions (m).
    pub pattern: &'a [Vec2],
    /// The fabric.
    pub fabric: &'a Fabric,
}

impl TermInput<'_> {
    /// Checks that `cloth` has `#Vc` and `pattern` `#Vp` finite entries, and that `gradient`, when given,
    /// is sized the same; the error names `term`.
    pub fn validate(
        &self,
        term: &'static str,
        gradient: Option<&TermGradient>,
    ) -> Result<(), TermError> {
        let invalid = |message: String| Err(TermError::Invalid { term, message });
        let (nc, np) = (
            self.mesh.num_cloth_vertices,
            self.mesh.num_pattern_vertices(),
        );
        if self.cloth.len() != nc {
            return invalid(format!(
                "{} cloth positions for {nc} cloth vertices",
                self.cloth.len()
            ));
        }
        if self.pattern.len() != np {
            return invalid(format!(
                "{} pattern positions for {np} pattern vertices",
                self.pattern.len()
            ));
        }
        let mesh = self.mesh;
        if mesh.pattern_triangles.len() != mesh.cloth_triangles.len() {
            return invalid(format!(
                "{} pattern triangles for {} cloth triangles",
                mesh.pattern_triangles.len(),
                mesh.cloth_triangles.len()
            ));
        }
        if let Some(f) = (0..mesh.cloth_triangles.len()).find(|&f| {
            mesh.cloth_triangles[f].iter().any(|&v| v >= nc)
                || mesh.pattern_triangles[f].iter().any(|&v| v >= np)
        }) {
            return invalid(format!("triangle {f} has a vertex id out of range"));
        }
        if let Some(v) = self
            .cloth
            .iter()
            .position(|p| !p.iter().all(|c| c.is_finite()))
        {
            return invalid(format!("cloth vertex {v} is not finite"));
        }
        if let Some(v) = self
            .pattern
            .iter()
            .position(|p| !p.iter().all(|c| c.is_finite()))
        {
            return invalid(format!("pattern vertex {v} is not finite"));
        }
        if let Some(g) = gradient
            && (g.cloth.len() != nc || g.pattern.len() != np)
        {
            return invalid(format!(
                "gradient sized {} × {} for {nc} cloth and {np} pattern vertices",
                g.cloth.len(),
                g.pattern.len()
            ));
        }
        Ok(())
    }
}

/// Partial derivatives of a term; [`Term::evaluate`] *adds* into them.
#[derive(Clone, Debug, PartialEq)]
pub struct TermGradient {
    /// `#Vc`: `∂T/∂x` (units of T per m).
    pub cloth: Vec<Vec3>,
    /// `#Vp`: `∂T/∂X̄` (units of T per m).
    pub pattern: Vec<Vec2>,
}

impl TermGradient {
    /// Zero partial derivatives sized for `mesh`.
    pub fn zeros(mesh: &DesignMesh) -> Self {
        Self {
            cloth: vec![Vec3::zeros(); mesh.num_cloth_vertices],
            pattern: vec![Vec2::zeros(); mesh.num_pattern_vertices()],
        }
    }
}

/// A term's value, with its contribution per element for reports.
#[derive(Clone, Debug, PartialEq)]
pub struct TermEvaluation {
    /// The weighted value `T` (the term's documented units).
    pub value: Real,
    /// Contribution of each element (summing to `value`); which elements — cloth triangles, cloth
    /// vertices, seam vertex pairs, boundary vertices — the term documents.
    pub per_element: Vec<Real>,
}

impl TermEvaluation {
    /// The evaluation whose value is the sum of `per_element`; [`TermError::Invalid`] naming `term` when
    /// that sum overflows or is not a number (absurd inputs), so no term reports a NaN or infinite value.
    pub(crate) fn from_per_element(
        term: &'static str,
        per_element: Vec<Real>,
    ) -> Result<Self, TermError> {
        let value: Real = per_element.iter().sum();
        if !value.is_finite() {
            return Err(TermError::Invalid {
                term,
                message: format!("the value is not finite ({value}); the state is out of range"),
            });
        }
        Ok(Self { value, per_element })
    }
}

/// Residuals `r` of a sum-of-squares term `T = Σ_k r_k²`, with their sparse Jacobian.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Residuals {
    /// `r` (units of √T).
    pub values: Vec<Real>,
    /// `(k, cloth vertex, ∂r_k/∂x)` entries; several entries for one pair add up.
    pub cloth_jacobian: Vec<(usize, usize, Vec3)>,
    /// `(k, pattern vertex, ∂r_k/∂X̄)` entries; several entries for one pair add up.
    pub pattern_jacobian: Vec<(usize, usize, Vec2)>,
    /// `(k, unknown j, ∂r_k/∂q_j)` entries of the **direct** dependence on the coupled state `q` (beyond
    /// the cloth positions, which `cloth_jacobian` covers), for terms that see the state
    /// ([`Term::residuals_with_state`]); several entries for one pair add up.
    pub state_jacobian: Vec<(usize, usize, Real)>,
}

/// Why a term cannot be built or evaluated.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TermError {
    /// A term's parameters are impossible (negative weight, empty window, non-positive radius, empty
    /// target, …); returned by the terms' constructors.
    #[error("{term}: invalid parameter: {message}")]
    Parameter {
        /// Name of the term.
        term: &'static str,
        /// What is wrong.
        message: String,
    },
    /// A cloth or pattern triangle has collapsed (zero or negative area), so stretches do not exist.
    #[error("{term}: triangle {triangle} has collapsed, its stretch is undefined")]
    Collapsed {
        /// Name of the term.
        term: &'static str,
        /// Triangle index.
        triangle: usize,
    },
    /// Inputs of the wrong size or non-finite values.
    #[error("{term}: {message}")]
    Invalid {
        /// Name of the term.
        term: &'static str,
        /// What is wrong.
        message: String,
    },
}

/// `Ok(value)` when the weight `value` of the term `term` is finite and non-negative, else
/// [`TermError::Parameter`] naming the term, the parameter `parameter` (`"weight"`, or e.g.
/// `"negative_weight"` for a second weight) and the value, and saying what is allowed. Every term
/// constructor checks its weights with this.
pub fn check_weight(term: &'static str, parameter: &str, value: Real) -> Result<Real, TermError> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(TermError::Parameter {
            term,
            message: format!(
                "{parameter} must be finite and non-negative (0 switches it off), got {value}"
            ),
        })
    }
}

/// One weighted objective or regularizer.
pub trait Term: Send + Sync {
    /// Name used in reports and history (`"shape"`, `"stretch"`, …).
    fn name(&self) -> &'static str;

    /// The value at `input`; when `gradient` is given, adds `∂T/∂x` and `∂T/∂X̄` into it.
    fn evaluate(
        &self,
        input: &TermInput,
        gradient: Option<&mut TermGradient>,
    ) -> Result<TermEvaluation, TermError>;

    /// The residuals, for terms that are a weighted sum of squares (`T = Σ r_k²` exactly); `None` for the
    /// others.
    fn residuals(&self, _input: &TermInput) -> Option<Result<Residuals, TermError>> {
        None
    }

    /// The value at `input` and the coupled state `state` it is the cloth of, for terms that depend on the
    /// state directly — not only through the cloth positions (e.g. through the body surface's tangents,
    /// [`crate::PinnedTraction`]). Adds `∂T/∂x` and `∂T/∂X̄` into `gradient` as [`Term::evaluate`] does and
    /// the direct `∂T/∂q` (`#q`, units of T per unit of each unknown) into `state_gradient`; the total
    /// `dT/dq = Jᵀ ∂T/∂x + ∂T/∂q`. The default ignores the state.
    fn evaluate_with_state(
        &self,
        input: &TermInput,
        _state: &StateInput,
        gradient: Option<&mut TermGradient>,
        _state_gradient: Option<&mut [Real]>,
    ) -> Result<TermEvaluation, TermError> {
        self.evaluate(input, gradient)
    }

    /// [`Term::residuals`] for terms that see the state, with [`Residuals::state_jacobian`]. The default
    /// ignores the state.
    fn residuals_with_state(
        &self,
        input: &TermInput,
        _state: &StateInput,
    ) -> Option<Result<Residuals, TermError>> {
        self.residuals(input)
    }
}

/// The coupled system and the state a [`TermInput`]'s cloth positions come from, for terms that depend
/// on the state directly ([`Term::evaluate_with_state`]).
#[derive(Clone, Copy)]
pub struct StateInput<'a> {
    /// The garment on the body, with the pattern of the input.
    pub system: &'a ClothOnBody,
    /// The state (`s` of the unpinned cloth vertices, body positions).
    pub state: &'a ClothOnBodyState,
}

impl StateInput<'_> {
    /// Checks that the system and the state have `input`'s cloth vertices, and that a state gradient
    /// (if given) has one entry per unknown; errors name `term`.
    pub fn validate(
        &self,
        term: &'static str,
        input: &TermInput,
        state_gradient: Option<&[Real]>,
    ) -> Result<(), TermError> {
        let nc = input.mesh.num_cloth_vertices;
        if self.system.num_cloth_vertices() != nc || self.state.cloth.len() != nc {
            return Err(TermError::Invalid {
                term,
                message: format!(
                    "the system has {} cloth vertices, the input {nc}",
                    self.system.num_cloth_vertices()
                ),
            });
        }
        if let Some(sg) = state_gradient
            && sg.len() != self.system.num_dofs()
        {
            return Err(TermError::Invalid {
                term,
                message: format!(
                    "state gradient sized {} for {} unknowns",
                    sg.len(),
                    self.system.num_dofs()
                ),
            });
        }
        Ok(())
    }
}

impl std::fmt::Debug for StateInput<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StateInput")
            .field("unknowns", &self.system.num_dofs())
            .finish_non_exhaustive()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_weight_accepts_finite_non_negative_values_and_names_the_term_otherwise() {
        for w in [0.0, 1e-12, 1.0, 1e12] {
            assert_eq!(check_weight("shape", "weight", w), Ok(w));
        }
        for w in [Real::NAN, Real::INFINITY, Real::NEG_INFINITY, -1.0, -1e-300] {
            let err = check_weight("pressure", "negative_weight", w).unwrap_err();
            assert!(
                matches!(
                    err,
                    TermError::Parameter {
                        term: "pressure",
                        ..
                    }
                ),
                "{err:?}"
            );
            let text = err.to_string();
            assert!(
                text.starts_with("pressure: invalid parameter: negative_weight must be finite")
                    && text.ends_with(&format!("got {w}")),
                "{text}"
            );
        }
    }
}
