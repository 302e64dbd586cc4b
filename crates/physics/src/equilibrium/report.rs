//! What the garment's equilibrium solve reports: the Newton toolkit's [`NewtonReport`] with the garment's
//! own figures ([`EquilibriumFigures`]: the force residual and its scale, the chord steps, rejected
//! inversions and symbolic analyses, the size and fill of the system, the timings), as
//! [`EquilibriumReport`].
//!
//! On the wire (`result.json`, the design's checkpoints and API responses, docs/API.md) the report is one
//! flat object in the order and under the names it had before the toolkit owned its core: the
//! iteration count is `newton_iterations` and the stop reason `stop_reason`, written as the variant's
//! `snake_case` name ([`StopReason`]). A private wire form holds that order; the report is converted to it
//! and back, so every file written earlier reads.

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::math::Real;
use crate::newton::{NewtonReport, StopReason};
use crate::sparse_cholesky::Ordering;

/// Outcome of [`super::equilibrium`]: the toolkit's report core and the garment's [`EquilibriumFigures`].
/// `residual` is the relative residual `‖f‖₂ / F` (dimensionless), `energy` the final `U` (J), `damping`
/// the final `α` (N/m), `iterations` the Newton iterations taken, `factorizations` the numeric
/// factorizations (failed ones included).
pub type EquilibriumReport = NewtonReport<EquilibriumFigures>;

/// The figures of a garment equilibrium solve beside the report's core.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EquilibriumFigures {
    /// Final unbalanced force norm `‖f‖₂` (N).
    pub force_residual: Real,
    /// Force scale `F` (N).
    pub force_scale: Real,
    /// Newton iterations that reused the factorization held instead of factoring (chord steps,
    /// [`super::EquilibriumParams::reuse_factorization`]); 0 in files written before they existed.
    pub chord_steps: usize,
    /// Trial steps rejected because they turned a body tetrahedron inside out.
    pub rejected_inversions: usize,
    /// Symbolic analyses (one plus one per change of the sparsity pattern).
    pub symbolic_analyses: usize,
    /// Number of unknowns.
    pub unknowns: usize,
    /// Stored entries of the Hessian's lower triangle.
    pub hessian_nonzeros: usize,
    /// Fill-reducing ordering used by the last factorization.
    pub ordering: Ordering,
    /// Nonzeros of the Cholesky factor `L`.
    pub factor_nonzeros: usize,
    /// Timings.
    pub timings: EquilibriumTimings,
}

/// Wall-clock times of a solve (s).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct EquilibriumTimings {
    /// Hessian and gradient assembly, pattern rebuilds included.
    pub assembly_s: Real,
    /// Symbolic analyses and numeric factorizations (failed attempts included).
    pub factorization_s: Real,
    /// Triangular solves.
    pub solve_s: Real,
    /// The whole solve.
    pub total_s: Real,
    /// Mean time per Newton iteration (`total_s / iterations`).
    pub newton_step_s: Real,
    /// One numeric factorization of a (damped) Hessian of the solve, timed alone: the last that succeeded
    /// among its Newton iterations (0 when it factored none).
    pub one_factorization_s: Real,
}

/// The garment's report as its files hold it (field names and order).
#[derive(Serialize, Deserialize)]
struct EquilibriumWire {
    converged: bool,
    stop_reason: StopReason,
    residual: Real,
    force_residual: Real,
    force_scale: Real,
    newton_iterations: usize,
    energy: Real,
    factorizations: usize,
    #[serde(default)]
    chord_steps: usize,
    rejected_inversions: usize,
    symbolic_analyses: usize,
    damping: Real,
    unknowns: usize,
    hessian_nonzeros: usize,
    ordering: Ordering,
    factor_nonzeros: usize,
    timings: EquilibriumTimings,
}

impl Serialize for NewtonReport<EquilibriumFigures> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let f = &self.figures;
        EquilibriumWire {
            converged: self.converged,
            stop_reason: self.stop,
            residual: self.residual,
            force_residual: f.force_residual,
            force_scale: f.force_scale,
            newton_iterations: self.iterations,
            energy: self.energy,
            factorizations: self.factorizations,
            chord_steps: f.chord_steps,
            rejected_inversions: f.rejected_inversions,
            symbolic_analyses: f.symbolic_analyses,
            damping: self.damping,
            unknowns: f.unknowns,
            hessian_nonzeros: f.hessian_nonzeros,
            ordering: f.ordering,
            factor_nonzeros: f.factor_nonzeros,
            timings: f.timings,
        }
        .serialize(s)
    }
}

impl<'de> Deserialize<'de> for NewtonReport<EquilibriumFigures> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let w = EquilibriumWire::deserialize(d)?;
        Ok(Self {
            converged: w.converged,
            stop: w.stop_reason,
            iterations: w.newton_iterations,
            factorizations: w.factorizations,
            residual: w.residual,
            energy: w.energy,
            damping: w.damping,
            figures: EquilibriumFigures {
                force_residual: w.force_residual,
                force_scale: w.force_scale,
                chord_steps: w.chord_steps,
                rejected_inversions: w.rejected_inversions,
                symbolic_analyses: w.symbolic_analyses,
                unknowns: w.unknowns,
                hessian_nonzeros: w.hessian_nonzeros,
                ordering: w.ordering,
                factor_nonzeros: w.factor_nonzeros,
                timings: w.timings,
            },
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A report as `result.json` held it before the toolkit owned its core (the field order of the
    /// files), without `chord_steps`, which came later.
    const WRITTEN: &str = "{\"converged\":false,\"stop_reason\":\"no_progress\",\"residual\":0.125,\
        \"force_residual\":0.5,\"force_scale\":4.0,\"newton_iterations\":21,\"energy\":5.814557184578273,\
        \"factorizations\":23,\"rejected_inversions\":1,\"symbolic_analyses\":2,\"damping\":0.75,\
        \"unknowns\":300,\"hessian_nonzeros\":4000,\"ordering\":\"metis\",\"factor_nonzeros\":9000,\
        \"timings\":{\"assembly_s\":0.5,\"factorization_s\":0.25,\"solve_s\":0.125,\"total_s\":1.0,\
        \"newton_step_s\":0.0625,\"one_factorization_s\":0.03125}}";

    #[test]
    fn an_earlier_file_reads_and_is_written_back_with_its_names_and_order() {
        let report: EquilibriumReport = serde_json::from_str(WRITTEN).unwrap();
        assert_eq!(report.stop, StopReason::NoProgress);
        assert_eq!(report.iterations, 21);
        assert_eq!(report.energy, 5.814557184578273);
        assert_eq!(report.figures.chord_steps, 0);
        assert_eq!(report.figures.ordering, Ordering::Metis);
        assert_eq!(report.figures.timings.one_factorization_s, 0.03125);
        let written = serde_json::to_string(&report).unwrap();
        let expected = WRITTEN.replace(
            "\"factorizations\":23,",
            "\"factorizations\":23,\"chord_steps\":0,",
        );
        assert_eq!(written, expected);
        let again: EquilibriumReport = serde_json::from_str(&written).unwrap();
        assert_eq!(again, report);
    }

    #[test]
    fn a_report_with_a_field_missing_says_which() {
        let missing = WRITTEN.replace("\"newton_iterations\":21,", "");
        let err = serde_json::from_str::<EquilibriumReport>(&missing).unwrap_err();
        assert!(err.to_string().contains("newton_iterations"), "{err}");
    }
}
