//! Turning the file references of a scene (paths, or asset ids in the HTTP service) into files to read.

use std::path::{Path, PathBuf};

use super::error::SceneError;

/// Turns a file reference of the scene (a path, or an asset id in the HTTP service) into a file to read.
///
/// `key` is the key of the reference in the document (e.g. `body.source.path`), to be used in the error.
pub trait PathResolver {
    /// The file `reference` names, or an error at `key` (not found, not allowed, …).
    fn resolve(&self, key: &str, reference: &str) -> Result<PathBuf, SceneError>;
}

impl<F> PathResolver for F
where
    F: Fn(&str, &str) -> Result<PathBuf, SceneError>,
{
    fn resolve(&self, key: &str, reference: &str) -> Result<PathBuf, SceneError> {
        self(key, reference)
    }
}

/// Resolves paths against a folder (the scene file's folder for the command-line tool); absolute paths are
/// taken as they are. The file must exist.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FileResolver {
    /// Folder that relative paths start from.
    pub base_dir: PathBuf,
}

impl FileResolver {
    /// Resolves relative paths against `base_dir`.
    pub fn new(base_dir: impl Into<PathBuf>) -> Self {
        Self {
            base_dir: base_dir.into(),
        }
    }

    /// Resolves relative paths against the folder holding the scene file `scene_file`.
    pub fn for_scene_file(scene_file: &Path) -> Self {
        let dir = scene_file
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_default();
        Self::new(dir)
    }
}

impl PathResolver for FileResolver {
    fn resolve(&self, key: &str, reference: &str) -> Result<PathBuf, SceneError> {
        if reference.is_empty() {
            return Err(SceneError::new(key, "the path is empty"));
        }
        let path = Path::new(reference);
        let full = if path.is_absolute() {
            path.to_path_buf()
        } else {
            self.base_dir.join(path)
        };
        if !full.is_file() {
            return Err(SceneError::new(
                key,
                format!("file not found: {}", full.display()),
            ));
        }
        Ok(full)
    }
}
