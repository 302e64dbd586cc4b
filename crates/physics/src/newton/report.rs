//! What a solve of [`super::minimize`] did: its outcome ([`NewtonReport`]) and where its time went
//! ([`NewtonTimings`]). The garment's equilibrium solve reports in its own
//! [`crate::equilibrium::EquilibriumReport`] (the same [`StopReason`], and the figures of the garment
//! the design and `result.json` read under their names).

use serde::{Deserialize, Serialize};

use super::StopReason;

/// What [`super::minimize`] did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct NewtonReport {
    /// Whether the residual reached the tolerance.
    pub converged: bool,
    /// Accepted Newton steps.
    pub iterations: usize,
    /// Cholesky factorizations.
    pub factorizations: usize,
    /// Final residual (dimensionless).
    pub residual: f64,
    /// Final energy (J).
    pub energy: f64,
    /// Final damping `μ` (dimensionless, [`super::LevenbergMarquardt`]).
    pub damping: f64,
    /// Wall-clock time (s).
    pub seconds: f64,
    /// Why the solve stopped, written as its phrase ([`StopReason::phrase`]).
    #[serde(with = "super::stop_reason::phrase")]
    pub stop: StopReason,
    /// Where the time went.
    #[serde(default)]
    pub timings: NewtonTimings,
}

/// Where the time of a [`super::minimize`] went (s, wall clock), and how often the sparsity pattern was
/// analyzed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct NewtonTimings {
    /// Evaluations with the Hessian (the start and every accepted step).
    pub evaluation: f64,
    /// The line search's trial evaluations (energy only, or with the gradient in the rounding band).
    pub line_search: f64,
    /// Triplets to compressed columns, scattered into the analyzed pattern.
    pub assembly: f64,
    /// Symbolic analyses (ordering, elimination tree, supernodes).
    pub analysis: f64,
    /// Numeric factorizations, failed ones included.
    pub factorization: f64,
    /// Triangular solves.
    pub solve: f64,
    /// Symbolic analyses made (the others reused the pattern of an earlier iteration or solve).
    pub analyses: usize,
}

impl NewtonTimings {
    /// Adds `other` to these (sums over solves).
    pub fn add(&mut self, other: &Self) {
        self.evaluation += other.evaluation;
        self.line_search += other.line_search;
        self.assembly += other.assembly;
        self.analysis += other.analysis;
        self.factorization += other.factorization;
        self.solve += other.solve;
        self.analyses += other.analyses;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_stop_reason_is_written_as_its_phrase() {
        let report = NewtonReport {
            converged: false,
            iterations: 3,
            factorizations: 5,
            residual: 0.5,
            energy: 1.0,
            damping: 0.0,
            seconds: 0.0,
            stop: StopReason::Cancelled,
            timings: NewtonTimings::default(),
        };
        let json = serde_json::to_value(&report).unwrap();
        assert_eq!(json["stop"], "interrupted");
        assert_eq!(
            serde_json::from_value::<NewtonReport>(json).unwrap(),
            report
        );
    }
}
