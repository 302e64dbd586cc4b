//! The built-in `selftest` job kind: an operator smoke test of the queue, registered only with
//! `jobs.enable_selftest = true`. It iterates a deterministic contraction
//! `x_{k+1} = x_k / 2 + u_k`, with `u_k ∈ [-1, 1)` a hash of (seed, k), checkpoints after every iteration,
//! and optionally sleeps between iterations, so restarts, cancellation and progress can be watched with a
//! real process. Spec: `{"iterations": 1..=100000, "sleep_ms": 0..=60000, "seed": u64, "fail_at": k}`.

use serde::Deserialize;
use serde_json::{Value, json};

use super::error::field_of;
use super::model::{Artifact, Assets, FieldError, JobError, JobOutput};
use super::runner::{JobContext, JobRunner};

/// The `selftest` kind.
pub struct SelfTest;

/// The spec of a `selftest` job.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Spec {
    iterations: u64,
    #[serde(default)]
    sleep_ms: u64,
    #[serde(default)]
    seed: u64,
    /// Fail (as a computation would) at this iteration.
    #[serde(default)]
    fail_at: Option<u64>,
}

#[derive(Debug)]
struct State {
    x: f64,
    sum: f64,
}

impl State {
    /// Checkpoint bytes: `x` and `sum` as little-endian f64 (exact, unlike a decimal round trip).
    fn to_bytes(&self) -> Vec<u8> {
        [self.x.to_le_bytes(), self.sum.to_le_bytes()].concat()
    }

    fn from_bytes(b: &[u8]) -> Option<State> {
        let x = f64::from_le_bytes(b.get(0..8)?.try_into().ok()?);
        let sum = f64::from_le_bytes(b.get(8..16)?.try_into().ok()?);
        Some(State { x, sum })
    }
}

/// SplitMix64: a well-mixed 64-bit hash.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The forcing term of iteration `k` (1-based), in [-1, 1).
pub fn forcing(seed: u64, k: u64) -> f64 {
    let bits = mix(seed ^ mix(k)) >> 11;
    (bits as f64) / ((1u64 << 53) as f64) * 2.0 - 1.0
}

/// The whole trajectory `x_1 … x_n` from `x_0 = 0`.
pub fn trajectory(seed: u64, n: u64) -> Vec<f64> {
    let mut x = 0.0;
    (1..=n)
        .map(|k| {
            x = 0.5 * x + forcing(seed, k);
            x
        })
        .collect()
}

fn parse(spec: &Value) -> Result<Spec, FieldError> {
    serde_path_to_error::deserialize(spec).map_err(|e| {
        let path = e.path().to_string();
        let msg = e.into_inner().to_string();
        FieldError::new(field_of(&path, &msg), msg)
    })
}

fn validate(spec: &Spec) -> Result<(), FieldError> {
    if !(1..=100_000).contains(&spec.iterations) {
        return Err(FieldError::new(
            "iterations",
            "must be between 1 and 100000",
        ));
    }
    if spec.sleep_ms > 60_000 {
        return Err(FieldError::new(
            "sleep_ms",
            "must be at most 60000 (one minute)",
        ));
    }
    if let Some(f) = spec.fail_at
        && (f == 0 || f > spec.iterations)
    {
        return Err(FieldError::new(
            "fail_at",
            "must be an iteration between 1 and `iterations`",
        ));
    }
    Ok(())
}

impl JobRunner for SelfTest {
    type Spec = Spec;

    fn kind(&self) -> &'static str {
        "selftest"
    }

    fn parse(&self, spec: &Value) -> Result<Spec, FieldError> {
        parse(spec)
    }

    fn validate(&self, spec: &Spec) -> Result<(), FieldError> {
        validate(spec)
    }

    fn run(
        &self,
        spec: &Spec,
        _assets: &Assets,
        ctx: &mut JobContext,
    ) -> Result<JobOutput, JobError> {
        let mut state = State { x: 0.0, sum: 0.0 };
        let mut start = 0;
        if let Some(cp) = ctx.last_checkpoint() {
            state = State::from_bytes(&cp.data)
                .ok_or_else(|| JobError::Failed("unreadable checkpoint".into()))?;
            start = cp.iteration;
        }
        for k in start + 1..=spec.iterations {
            if spec.sleep_ms > 0 {
                std::thread::sleep(std::time::Duration::from_millis(spec.sleep_ms));
            }
            if spec.fail_at == Some(k) {
                return Err(JobError::Failed(format!(
                    "selftest failed at iteration {k} as asked"
                )));
            }
            state.x = 0.5 * state.x + forcing(spec.seed, k);
            state.sum += state.x;
            ctx.progress(k as f64 / spec.iterations as f64);
            ctx.iteration_checkpointed(
                k,
                json!({ "x": state.x, "sum": state.sum }),
                state.to_bytes(),
            )?;
        }
        let trace: String = std::iter::once("iteration,x\n".to_string())
            .chain(
                trajectory(spec.seed, spec.iterations)
                    .iter()
                    .enumerate()
                    .map(|(i, x)| format!("{},{x:?}\n", i + 1)),
            )
            .collect();
        let summary = json!({ "iterations": spec.iterations, "x": state.x, "sum": state.sum, "seed": spec.seed });
        Ok(JobOutput {
            artifacts: vec![
                Artifact {
                    name: "result.json".into(),
                    content_type: "application/json".into(),
                    data: serde_json::to_vec_pretty(&summary).expect("summary serializes"),
                },
                Artifact {
                    name: "trace.csv".into(),
                    content_type: "text/csv".into(),
                    data: trace.into_bytes(),
                },
            ],
            summary,
            warnings: Vec::new(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn forcing_is_deterministic_and_in_range() {
        for k in 1..1000 {
            let u = forcing(7, k);
            assert!((-1.0..1.0).contains(&u));
            assert_eq!(u, forcing(7, k));
        }
        assert_ne!(forcing(7, 1), forcing(8, 1));
        // The contraction stays bounded by 2.
        assert!(trajectory(3, 500).iter().all(|x| x.abs() < 2.0));
    }

    /// The check made at submission: parse, then validate.
    fn check(spec: &Value) -> Result<(), FieldError> {
        let mut registry = crate::server::runner::JobRegistry::new();
        registry.register(std::sync::Arc::new(SelfTest));
        registry
            .accept("selftest", spec)
            .expect("a known kind")
            .map(|_| ())
    }

    #[test]
    fn spec_errors_name_the_field() {
        assert_eq!(
            check(&json!({"iterations": 0})).unwrap_err().field,
            "iterations"
        );
        assert_eq!(
            check(&json!({"iterations": "3"})).unwrap_err().field,
            "iterations"
        );
        assert_eq!(
            check(&json!({"iterations": 3, "bogus": 1}))
                .unwrap_err()
                .field,
            "bogus"
        );
        assert_eq!(check(&json!({})).unwrap_err().field, "iterations");
        assert_eq!(
            check(&json!({"iterations": 3, "fail_at": 4}))
                .unwrap_err()
                .field,
            "fail_at"
        );
        assert!(check(&json!({"iterations": 3, "sleep_ms": 5})).is_ok());
    }
}
