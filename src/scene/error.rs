//! The error of a scene: the key of the document at fault and what is wrong with it.

use std::fmt;

use crate::json_input::JsonInputError;

/// Why a scene cannot be used: the key of the document at fault and what is wrong with it.
///
/// `key` is a path into the JSON document such as `garment.fabric.poisson_ratio` or
/// `garment.panels[2].faces[5]`; it is empty for a problem of the document as a whole (malformed JSON, a file
/// that cannot be read). Displayed as `` `key`: message `` (just the message when the key is empty).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SceneError {
    /// Path of the offending key in the document (`a.b[3].c`); empty for the document as a whole.
    pub key: String,
    /// What is wrong, for a person.
    pub message: String,
}

impl SceneError {
    /// An error at `key` with `message`.
    pub fn new(key: impl Into<String>, message: impl Into<String>) -> Self {
        Self {
            key: key.into(),
            message: message.into(),
        }
    }
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.key.is_empty() {
            write!(f, "{}", self.message)
        } else {
            write!(f, "`{}`: {}", self.key, self.message)
        }
    }
}

impl std::error::Error for SceneError {}

impl SceneError {
    /// The error of a JSON document (`what` names it in messages: "scene", "design job") that does not
    /// parse: malformed JSON has an empty key and the line and column in the message; JSON of the wrong
    /// shape names its key, without the position (the key says where).
    pub fn from_json_input(e: JsonInputError, what: &str) -> Self {
        if e.malformed {
            SceneError::new("", format!("the {what} is not valid JSON: {e}"))
        } else {
            SceneError::new(e.key, e.message)
        }
    }
}
