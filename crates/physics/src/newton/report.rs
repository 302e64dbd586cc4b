//! What a Newton solve did: one report shape, [`NewtonReport`], for both solvers of the toolkit.
//!
//! Every solve ends with the same core — whether it converged, why it stopped ([`StopReason`]), its
//! accepted iterations, factorizations, final residual, energy and damping — and figures of its own
//! solver: the minimizer's wall-clock time and [`NewtonTimings`] ([`MinimizeFigures`], from
//! [`super::minimize`]), the garment's force scale, counts and timings
//! ([`crate::equilibrium::EquilibriumFigures`], whose report is
//! [`crate::equilibrium::EquilibriumReport`] `= NewtonReport<EquilibriumFigures>`). The report is generic
//! over those figures, so code that reads the core reads it the same way from either solver.
//!
//! Each solver's reports were on the wire before they were one type, under different names, and both
//! spellings stay so that every file written earlier still reads: the minimizer's (the yarn runs' step
//! reports and checkpoints) writes `iterations` and `stop` as its phrase ([`super::stop_reason::phrase`]);
//! the garment's (`result.json`, the design's checkpoints and API) writes `newton_iterations` and
//! `stop_reason` as the variant's `snake_case` name. Each spelling is a flat serde form, the field order
//! of the files, next to its figures (here for the minimizer, in `equilibrium/report.rs` for the garment),
//! which the report is converted to and from.

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::StopReason;

/// What a Newton solve did: the core every solver reports, and `figures` of its own (the minimizer's
/// [`MinimizeFigures`] by default).
#[derive(Clone, Debug, PartialEq)]
pub struct NewtonReport<F = MinimizeFigures> {
    /// Whether the residual reached the tolerance.
    pub converged: bool,
    /// Why the solve stopped.
    pub stop: StopReason,
    /// Accepted Newton steps.
    pub iterations: usize,
    /// Numeric Cholesky factorizations, failed ones included.
    pub factorizations: usize,
    /// Final residual (dimensionless: the solver's relative residual).
    pub residual: f64,
    /// Final energy (J).
    pub energy: f64,
    /// Final damping: the minimizer's dimensionless shift `μ` ([`super::LevenbergMarquardt`]), the
    /// garment's `α` in N/m ([`super::TrustRatioDamping`]).
    pub damping: f64,
    /// The solver's own figures.
    pub figures: F,
}

/// The figures of a [`super::minimize`] solve beside the report's core.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MinimizeFigures {
    /// Wall-clock time (s).
    pub seconds: f64,
    /// Where the time went.
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

/// The minimizer's report as its files hold it (field names and order).
#[derive(Serialize, Deserialize)]
struct MinimizeWire {
    converged: bool,
    iterations: usize,
    factorizations: usize,
    residual: f64,
    energy: f64,
    damping: f64,
    seconds: f64,
    #[serde(with = "super::stop_reason::phrase")]
    stop: StopReason,
    #[serde(default)]
    timings: NewtonTimings,
}

impl Serialize for NewtonReport<MinimizeFigures> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        MinimizeWire {
            converged: self.converged,
            iterations: self.iterations,
            factorizations: self.factorizations,
            residual: self.residual,
            energy: self.energy,
            damping: self.damping,
            seconds: self.figures.seconds,
            stop: self.stop,
            timings: self.figures.timings,
        }
        .serialize(s)
    }
}

impl<'de> Deserialize<'de> for NewtonReport<MinimizeFigures> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let w = MinimizeWire::deserialize(d)?;
        Ok(Self {
            converged: w.converged,
            stop: w.stop,
            iterations: w.iterations,
            factorizations: w.factorizations,
            residual: w.residual,
            energy: w.energy,
            damping: w.damping,
            figures: MinimizeFigures {
                seconds: w.seconds,
                timings: w.timings,
            },
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_minimizer_report_keeps_its_wire_names_and_writes_the_stop_reason_as_its_phrase() {
        let report = NewtonReport {
            converged: false,
            stop: StopReason::Cancelled,
            iterations: 3,
            factorizations: 5,
            residual: 0.5,
            energy: 1.0,
            damping: 0.0,
            figures: MinimizeFigures {
                seconds: 0.25,
                timings: NewtonTimings {
                    analyses: 2,
                    ..NewtonTimings::default()
                },
            },
        };
        let json = serde_json::to_value(&report).unwrap();
        assert_eq!(json["stop"], "interrupted");
        assert_eq!(json["iterations"], 3);
        assert_eq!(json["seconds"], 0.25);
        assert_eq!(json["timings"]["analyses"], 2);
        let text = serde_json::to_string(&report).unwrap();
        assert!(
            text.starts_with(
                "{\"converged\":false,\"iterations\":3,\"factorizations\":5,\"residual\":0.5,\
                 \"energy\":1.0,\"damping\":0.0,\"seconds\":0.25,\"stop\":\"interrupted\",\"timings\":"
            ),
            "{text}"
        );
        assert_eq!(
            serde_json::from_value::<NewtonReport>(json).unwrap(),
            report
        );
    }

    #[test]
    fn a_minimizer_report_written_before_timings_existed_still_reads() {
        let old = r#"{"converged":true,"iterations":7,"factorizations":8,"residual":1e-9,
            "energy":-2.5,"damping":1e-8,"seconds":3.0,"stop":"converged"}"#;
        let report: NewtonReport = serde_json::from_str(old).unwrap();
        assert_eq!(report.stop, StopReason::Converged);
        assert_eq!(report.iterations, 7);
        assert_eq!(report.figures.timings, NewtonTimings::default());
        let bad = old.replace("\"converged\"}", "\"stalled\"}");
        let err = serde_json::from_str::<NewtonReport>(&bad).unwrap_err();
        assert!(err.to_string().contains("unknown stop reason"), "{err}");
    }
}
