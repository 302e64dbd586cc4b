//! Reading and writing a scene document as JSON.

use std::path::Path;

use super::error::SceneError;
use super::spec::Scene;
use crate::json_input::parse_json_input;

impl Scene {
    /// Parses a scene document and checks it with [`Scene::validate`]. Unknown keys, wrong types, missing
    /// required fields and impossible values are errors naming their key; malformed JSON is an error with an
    /// empty key and the line and column.
    pub fn from_json(text: &str) -> Result<Scene, SceneError> {
        let scene: Scene = parse_json_input(text.as_bytes())
            .map_err(|e| SceneError::from_json_input(e, "scene"))?;
        scene.validate()?;
        Ok(scene)
    }

    /// Reads and parses a scene file (see [`Scene::from_json`]); relative paths in it are meant to be
    /// resolved with [`FileResolver::for_scene_file`](crate::scene::FileResolver::for_scene_file).
    pub fn from_file(path: &Path) -> Result<Scene, SceneError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| SceneError::new("", format!("cannot read {}: {e}", path.display())))?;
        Scene::from_json(&text)
            .map_err(|e| SceneError::new(e.key, format!("{}: {}", path.display(), e.message)))
    }

    /// The scene as pretty-printed JSON (every default written out); [`Scene::from_json`] reads it back.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
    }
}
