//! The Newton toolkit both equilibrium solvers of the workspace are built from: the garment on the body
//! ([`mod@crate::equilibrium`]) and the yarn solves of `skintight-knit` (through [`minimize`]).
//!
//! A Newton solve of an energy `U(q)` factors `H + σ D` — the Hessian (or a stand-in) plus a shift `σ`
//! along a diagonal metric `D` — solves `(H + σ D) h = −g`, and takes or rejects the step. What the two
//! solvers share lives here, one file each:
//! - the matrix from the problem's triplets into a fixed pattern: [`compressed_lower`] (triplets to
//!   compressed columns), [`pattern_union`], and the [`PatternCache`] that keeps a pattern's symbolic
//!   analysis and decides when to analyze again — for the yarns' triplet matrices and for the garment's
//!   node-block pattern, which grows in place ([`PatternCache::fit`]);
//! - the factorization of `H + σ D` retried with larger shifts while it is not positive definite
//!   ([`shifted_factorization`], [`add_to_diagonal`]);
//! - the damping policies, one family ([`DampingPolicy`]) with two strategies that differ on purpose:
//!   [`TrustRatioDamping`] (the garment's `α` in N/m with the metric `D` of the surface coordinates and
//!   the trust-ratio rules of thesis Sec. 2.1.2) and [`LevenbergMarquardt`] (the yarns' dimensionless
//!   shift `μ` on the scaled diagonal, for a line search);
//! - one [`StopReason`] and one report, [`NewtonReport`]: the core every solve reports and the solver's
//!   own figures ([`MinimizeFigures`] with its [`NewtonTimings`]; the garment's
//!   [`crate::equilibrium::EquilibriumFigures`]);
//! - [`minimize`]: Newton with the Levenberg–Marquardt shift and Armijo backtracking for a
//!   [`NewtonProblem`] (the yarn solves' problems implement it in `skintight-knit`).
//!
//! The garment's solve keeps its own assembly into a pattern that survives sliding
//! ([`crate::node_block_assembly`]) and its own step (a walk across body faces), and uses from here the
//! pattern cache, the stop reasons, the report, its damping policy and the shifted factorization of its
//! adjoint.

mod compressed_lower;
mod damping;
mod levenberg_marquardt;
mod minimize;
mod pattern_cache;
mod pattern_union;
mod problem;
mod report;
mod shifted_factorization;
pub mod stop_reason;
mod trust_ratio_damping;

pub use compressed_lower::{CompressedLower, compressed_lower};
pub use damping::DampingPolicy;
pub use levenberg_marquardt::{LevenbergMarquardt, MU_FLOOR, MU_LIMIT};
pub use minimize::{NewtonError, NewtonParams, NewtonWorkspace, minimize, minimize_with};
pub use pattern_cache::{AnalyzedPattern, PatternCache, UNION_SLACK};
pub use pattern_union::pattern_union;
pub use problem::NewtonProblem;
pub use report::{MinimizeFigures, NewtonReport, NewtonTimings};
pub use shifted_factorization::{add_to_diagonal, indefinite, shifted_factorization};
pub use stop_reason::StopReason;
pub use trust_ratio_damping::TrustRatioDamping;
