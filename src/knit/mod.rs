//! Yarn simulation scenes (`skintight knit simulate-yarn SCENE.json --out DIR`, job kind `yarn_simulate`):
//! the scene layer of the knitwear, beside the garment one (`scene/`, `simulate/`). A scene is a patch of
//! `nx × ny` cells of a shared periodic pattern in one of five scenarios (hang, stretch, biaxial stretch,
//! shear, drape over a sphere), time-stepped with backward Euler and written as a frame sequence. The
//! numerics — rods, contact, the patch energy, the periodic cell, the Newton solve, the stepper and the
//! frame-sequence format — are `skintight_knit`'s; this module reads the scene, builds its model and runs
//! it with its files and checkpoints.
//!
//! Files: `spec` (the scene's types and defaults, reading it from JSON), `validate` (the checks, each
//! message naming its field), `error` ([`YarnSceneError`]), `build` (the tiled patch, its periodic rest
//! start and its grips: [`patch_model`]), `run` ([`run`]: the start state's relaxation and the time steps),
//! `output` (`result.json`, the sequence's metadata, `yarns.obj`/`yarns.glb`) and `checkpoint`
//! ([`YarnRunCheckpoint`], a stopped run resumed); `homogenize` ([`homogenize_sequences`]: sequences of one
//! patch homogenized into a mesh with a fitted material, `knit homogenize`) and `homogenized_run`
//! ([`simulate_homogenized`]: a scene run on such a material by projective dynamics, `knit simulate`).
//! `stretch_test` ([`run_stretch_test`], `skintight knit stretch-test`) pulls a patch quasi-statically in
//! the geometry of a measured sample (Singal et al. 2024) and compares its force–extension curve with the
//! measured one; `stretch_plot` draws the two as SVG.
//!
//! Units: SI (m, s, kg, Pa, rad).

mod build;
mod checkpoint;
mod error;
mod homogenize;
mod homogenized_run;
mod output;
mod run;
mod spec;
mod stretch_plot;
mod stretch_test;
mod validate;

pub use build::patch_model;
pub use checkpoint::{
    CHECKPOINT_FILE, CHECKPOINT_FORMAT, CHECKPOINT_VERSION, YarnRunCheckpoint, YarnRunPhase,
};
pub use error::YarnSceneError;
pub use homogenize::{KnitHomogenizeError, homogenize_sequences, read_material};
pub use homogenized_run::{HomogenizedRunResult, read_scene, simulate_homogenized};
pub use output::YarnSimulationResult;
pub use run::{FrameProgress, YarnRunParams, run};
pub use spec::{Scenario, YarnScene};
pub use stretch_plot::stretch_svg;
pub use stretch_test::{
    ACRYLIC_YARN_RADIUS, MIN_COMPARED_FORCE_N, MeasuredKnit, PullDirection, STOCK_9_LOOP_RADII,
    StretchPoint, StretchTestResult, StretchTestSpec, comparison_csv, measured_file,
    run_stretch_test, simulated_csv,
};

#[cfg(test)]
mod tests;
