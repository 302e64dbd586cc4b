//! Why a Newton solve stopped: one enum for the garment's equilibrium solve
//! ([`mod@crate::equilibrium`]) and the line-search minimizer ([`super::minimize`]).
//!
//! Two spellings are on the wire and both stay: the garment's reports (`result.json`, the design's
//! checkpoints and API) write the `snake_case` names of the variants (`"no_progress"`), the minimizer's
//! reports (the yarn runs' step reports and checkpoints) the phrases of [`StopReason::phrase`]
//! (`"no descent step found"`), through the [`phrase`] serde adapter.

use serde::{Deserialize, Serialize};

/// Why a solve stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    /// The residual fell below the tolerance.
    Converged,
    /// `max_iterations` were used up.
    IterationLimit,
    /// The time limit was reached.
    TimeLimit,
    /// The caller asked to stop (the progress callback, or [`super::NewtonProblem::interrupted`]).
    Cancelled,
    /// No step decreased the energy even with the largest damping tried.
    NoProgress,
    /// The most factorizations allowed were used up ([`super::NewtonParams::max_factorizations`]).
    FactorizationLimit,
}

impl StopReason {
    /// The phrase the minimizer's reports write for this reason.
    pub fn phrase(self) -> &'static str {
        match self {
            Self::Converged => "converged",
            Self::IterationLimit => "iteration limit",
            Self::TimeLimit => "time limit",
            Self::Cancelled => "interrupted",
            Self::NoProgress => "no descent step found",
            Self::FactorizationLimit => "factorization limit",
        }
    }

    /// The reason [`Self::phrase`] writes as `text`, if any.
    pub fn from_phrase(text: &str) -> Option<Self> {
        [
            Self::Converged,
            Self::IterationLimit,
            Self::TimeLimit,
            Self::Cancelled,
            Self::NoProgress,
            Self::FactorizationLimit,
        ]
        .into_iter()
        .find(|r| r.phrase() == text)
    }
}

/// Serde adapter writing a [`StopReason`] as its [`StopReason::phrase`]
/// (`#[serde(with = "skintight_physics::newton::stop_reason::phrase")]`).
pub mod phrase {
    use super::StopReason;
    use serde::{Deserialize, Deserializer, Serializer};

    /// Writes `reason` as its phrase.
    pub fn serialize<S: Serializer>(reason: &StopReason, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(reason.phrase())
    }

    /// Reads a phrase back; an unknown one is an error that lists the known phrases.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<StopReason, D::Error> {
        let text = String::deserialize(d)?;
        StopReason::from_phrase(&text).ok_or_else(|| {
            serde::de::Error::custom(format!(
                "unknown stop reason {text:?}: expected one of \"converged\", \"iteration limit\", \
                 \"time limit\", \"interrupted\", \"no descent step found\", \"factorization limit\""
            ))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_spellings_read_back() {
        for r in [
            StopReason::Converged,
            StopReason::IterationLimit,
            StopReason::TimeLimit,
            StopReason::Cancelled,
            StopReason::NoProgress,
            StopReason::FactorizationLimit,
        ] {
            assert_eq!(StopReason::from_phrase(r.phrase()), Some(r));
            let name = serde_json::to_string(&r).unwrap();
            assert_eq!(serde_json::from_str::<StopReason>(&name).unwrap(), r);
        }
        assert_eq!(
            serde_json::to_string(&StopReason::NoProgress).unwrap(),
            "\"no_progress\""
        );
        assert_eq!(StopReason::from_phrase("stalled"), None);
    }
}
