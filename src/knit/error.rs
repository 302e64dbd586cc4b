//! The errors of a yarn scene and its run, in the two kinds its callers act on: bad input (exit status 2,
//! a refused job; the message names the field or file and says how to fix it) and a failure to write the
//! outputs or to step.

use skintight_knit::frame_sequence::SequenceError;
use skintight_knit::implicit_euler::StepError;

/// Errors of a yarn scene (`skintight knit simulate-yarn`, the `yarn_simulate` job).
#[derive(Debug, thiserror::Error)]
pub enum YarnSceneError {
    /// The scene (or its checkpoint) cannot be read or has a bad value (the message names the field or the
    /// file and the fix).
    #[error("{0}")]
    Input(String),
    /// Writing the outputs failed.
    #[error("{0}")]
    Output(String),
    /// A time step failed.
    #[error(transparent)]
    Step(#[from] StepError),
}

impl From<SequenceError> for YarnSceneError {
    fn from(e: SequenceError) -> Self {
        YarnSceneError::Output(e.to_string())
    }
}
