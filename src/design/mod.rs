//! Pattern design jobs: a scene plus `objectives`, `regularizers` and `optimizer` (docs/DESIGN_JOB.md), run
//! by the CLI (`skintight design`) and by the service (`design` job kind).
//!
//! The job is parsed and checked like a scene (every error names its key), the garment is built and
//! solved to equilibrium as in `simulate`, then the pattern boundary is optimized
//! ([`mod@skintight_design::pattern_design`]) and the best design is written with the simulate outputs plus
//! `patterns.json` and `history.json`.
//!
//! Files: `batch` (an order graded over several bodies: `bodies`, one job per body), `spec` (the job's types and their defaults, reading it from JSON), `validate` (the checks, one
//! per section, every error naming its key), `target` (the revolution target surface), `build` (the
//! initial equilibrium and the objective terms: [`prepare_design`]), `run` ([`run_design`], with
//! remeshing), `statistics` (pressure and stretch-window figures of a worn garment) and `output`
//! ([`design_summary`], [`design_artifacts`]).

mod batch;
mod build;
mod checkpoint;
mod output;
mod prescription_bands;
mod run;
mod spec;
mod statistics;
mod target;
mod validate;

pub use batch::{
    BatchBody, MAX_BATCH_BODIES, batch_from_file, batch_from_json, batch_key, valid_body_name,
};
pub use build::{Design, design_params, prepare_design, prepare_design_with};
pub use checkpoint::RunCheckpoint;
pub use output::{DesignOutputs, design_artifacts, design_summary};
pub use run::{run_design, run_design_from};
pub use spec::{
    CompactnessSpec, DesignJob, GaussNewtonSystemSpec, ObjectivesSpec, OptimizerMethod,
    OptimizerSpec, PoseSpec, PressureObjective, RegularizersSpec, RemeshSpec, SeamTractionFormSpec,
    SeamTractionObjective, ShapeObjective, SlidingObjective, StretchObjective, TargetSpec,
    WeightSpec,
};
pub use statistics::{pressure_per_triangle, pressure_statistics, window_fraction};
pub use target::revolution_target;

#[cfg(test)]
mod tests;
