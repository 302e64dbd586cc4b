//! Figures of a worn garment reported with a design (in `result.json` and at preparation): the
//! Young–Laplace pressure (thesis Eq. 174) per cloth triangle and its area-weighted statistics, and the
//! fraction of the pattern area inside the stretch window.

use skintight_design::{DesignProblem, PressureStatistics, TermInput, young_laplace_statistics};
use skintight_geometry::math::{Real, Vec2};

use super::spec::DesignJob;
use crate::simulate::Simulation;

/// Young–Laplace pressure statistics (Eq. 174; area-weighted over the deformed cloth, the boundary ring
/// counted as the pressure objective counts it) of the garment in `sim` with pattern `pattern`.
pub fn pressure_statistics(
    job: &DesignJob,
    problem: &DesignProblem,
    sim: &Simulation,
    pattern: &[Vec2],
) -> Option<PressureStatistics> {
    let cloth = sim.system.cloth_positions(&sim.state).ok()?;
    let input = TermInput {
        mesh: problem.mesh(),
        cloth: &cloth,
        pattern,
        fabric: problem.fabric(),
    };
    let ring = job
        .objectives
        .pressure
        .as_ref()
        .is_some_and(|p| p.include_boundary_ring);
    young_laplace_statistics(&input, skintight_design::BoundaryEdges::Free, ring).ok()
}

/// The fraction of the cloth's pattern area whose two principal stretches lie in `[min, max]`.
pub fn window_fraction(
    system: &skintight_physics::ClothOnBody,
    state: &skintight_physics::ClothOnBodyState,
    min: Real,
    max: Real,
) -> Option<Real> {
    let states = system.element_states(state).ok()?;
    let (mut inside, mut total) = (0.0, 0.0);
    for (s, e) in states.iter().zip(system.elements()) {
        let a = e.rest_area();
        total += a;
        if s.principal_stretches[1] >= min && s.principal_stretches[0] <= max {
            inside += a;
        }
    }
    (total > 0.0).then(|| inside / total)
}

/// Young–Laplace pressure (Pa) of every cloth triangle of the garment in `sim` with pattern `pattern`, in
/// the garment's triangle order (None when undefined).
pub fn pressure_per_triangle(
    problem: &DesignProblem,
    sim: &Simulation,
    pattern: &[Vec2],
) -> Option<Vec<Real>> {
    let cloth = sim.system.cloth_positions(&sim.state).ok()?;
    let input = TermInput {
        mesh: problem.mesh(),
        cloth: &cloth,
        pattern,
        fabric: problem.fabric(),
    };
    skintight_design::young_laplace_pressures(&input, skintight_design::BoundaryEdges::Free).ok()
}
