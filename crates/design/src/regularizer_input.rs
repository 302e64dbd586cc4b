//! Checks and small geometric helpers shared by the pattern regularizers ([`crate::seam_length`],
//! [`crate::boundary_smoothness`], [`crate::edge_length_uniformity`], [`crate::compactness`]).

use crate::math::{Real, Vec2};
use crate::term::{TermError, TermGradient, TermInput};

/// Checks that the pattern positions match the mesh and are finite, that every boundary loop index is a
/// pattern vertex and that each loop has one border per edge, and that a given gradient has the mesh's
/// size.
pub(crate) fn check_input(
    term: &'static str,
    input: &TermInput,
    gradient: Option<&TermGradient>,
) -> Result<(), TermError> {
    let invalid = |message: String| Err(TermError::Invalid { term, message });
    let mesh = input.mesh;
    let n = mesh.num_pattern_vertices();
    if input.pattern.len() != n {
        return invalid(format!(
            "{} pattern positions for {n} pattern vertices",
            input.pattern.len()
        ));
    }
    if let Some(v) = input
        .pattern
        .iter()
        .position(|p| !(p.x.is_finite() && p.y.is_finite()))
    {
        return invalid(format!("pattern vertex {v} has a non-finite position"));
    }
    for (p, panel) in mesh.panels.iter().enumerate() {
        if panel.boundary_borders.len() != panel.boundary.len() {
            return invalid(format!(
                "panel {p}: {} boundary borders for {} boundary vertices",
                panel.boundary_borders.len(),
                panel.boundary.len()
            ));
        }
        if let Some(&v) = panel.boundary.iter().find(|&&v| v >= n) {
            return invalid(format!(
                "panel {p}: boundary vertex {v} is not a pattern vertex (#Vp = {n})"
            ));
        }
    }
    if let Some(g) = gradient
        && (g.pattern.len() != n || g.cloth.len() != mesh.num_cloth_vertices)
    {
        return invalid(format!(
            "the gradient has {} pattern and {} cloth entries, the mesh {n} and {}",
            g.pattern.len(),
            g.cloth.len(),
            mesh.num_cloth_vertices
        ));
    }
    Ok(())
}

/// Length `‖e‖` (m) of `e` and its gradient `e / ‖e‖` (dimensionless); the gradient of a zero-length edge
/// is taken as zero (a subgradient of the norm), so that no NaN can arise.
pub(crate) fn length_and_gradient(e: Vec2) -> (Real, Vec2) {
    let l = e.norm();
    if l > 0.0 {
        (l, e / l)
    } else {
        (0.0, Vec2::zeros())
    }
}

/// Number of boundary vertices of all panels (the length of a per-boundary-vertex report).
pub(crate) fn num_boundary_vertices(input: &TermInput) -> usize {
    input.mesh.panels.iter().map(|p| p.boundary.len()).sum()
}
