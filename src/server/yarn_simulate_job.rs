//! The `yarn_simulate` job kind: the CLI's `skintight knit simulate-yarn` on the worker pool.
//!
//! Spec: a yarn scene (`skintight_knit::yarn_scene::YarnScene`, the JSON of `examples/knit/`) whose
//! `pattern` is the name of a shared yarn pattern (`stock_9`, `rib_9`, `basket_9`, `satin_9`,
//! `stocktiniest_9`) in the server's yarn data folder (`jobs.yarns_dir`); the service reads no other
//! paths. Checked at submission: the fields' ranges, the pattern's existence, and the patch's unknowns
//! (4 per yarn vertex) against `jobs.max_unknowns`.
//!
//! Every written frame is reported as an `iteration` event numbered by the frame (1, 2, …; frame 0, the
//! start, is not an event) with `{frame, frame_count, time_s, newton_iterations,
//! min_distance_over_diameter}`, and sets the progress to `frame / (frame_count − 1)`; cancellation, the
//! time limit and shutdown are observed after each frame. The run is not checkpointed: an interrupted job
//! runs again from its start (the scene is deterministic, so it writes the same frames).
//!
//! Artifacts: `result.json` (`skintight_knit::yarn_scene::YarnSimulationResult`), `yarns.obj` and
//! `yarns.glb` (the last frame), and `sequence.tar`: the frame-sequence directory (`sequence.json`,
//! `vertex_sources.npy`, `frames/*.npy`; docs/OUTPUTS.md) as one POSIX ustar archive, so the sequence
//! unpacks with `tar -xf` into exactly the layout the CLI writes.

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

use serde_json::{Value, json};
use skintight_knit::PeriodicPattern;
use skintight_knit::yarn_scene::{SceneError, YarnScene, run};

use super::model::{Artifact, Assets, FieldError, JobError, JobOutput};
use super::runner::{JobContext, JobRunner};
use crate::json_input::parse_json_input;
use crate::scene::Limits;

/// The `yarn_simulate` kind, reading patterns from `yarns_dir`.
pub struct YarnSimulateJob {
    yarns_dir: PathBuf,
}

impl YarnSimulateJob {
    /// The kind with the shared yarn patterns in `yarns_dir` (one folder per pattern).
    pub fn new(yarns_dir: impl Into<PathBuf>) -> Self {
        Self {
            yarns_dir: yarns_dir.into(),
        }
    }

    fn pattern_file(&self, scene: &YarnScene) -> PathBuf {
        self.yarns_dir.join(&scene.pattern).join("pattern.pyp")
    }

    fn known_patterns(&self) -> String {
        let mut names: Vec<String> = std::fs::read_dir(&self.yarns_dir)
            .map(|d| {
                d.filter_map(|e| e.ok())
                    .filter(|e| e.path().join("pattern.pyp").is_file())
                    .map(|e| e.file_name().to_string_lossy().into_owned())
                    .collect()
            })
            .unwrap_or_default();
        names.sort();
        names.join(", ")
    }
}

/// The spec field a validation message is about: its first word (`dt_s = …` → `dt_s`), and
/// `yarn.<name>` for the yarn parameters' messages.
fn field_of(message: &str) -> String {
    if let Some(rest) = message.strip_prefix("yarn parameter ") {
        let name = rest.split_whitespace().next().unwrap_or("");
        return format!("yarn.{name}");
    }
    message.split_whitespace().next().unwrap_or("").to_string()
}

impl JobRunner for YarnSimulateJob {
    type Spec = YarnScene;

    fn kind(&self) -> &'static str {
        "yarn_simulate"
    }

    fn parse(&self, spec: &Value) -> Result<YarnScene, FieldError> {
        parse_json_input(spec.to_string().as_bytes()).map_err(|e| FieldError::new(e.key, e.message))
    }

    fn validate(&self, scene: &YarnScene) -> Result<(), FieldError> {
        scene
            .validate()
            .map_err(|m| FieldError::new(field_of(&m), m))?;
        if !scene.pattern_is_name() || !self.pattern_file(scene).is_file() {
            return Err(FieldError::new(
                "pattern",
                format!(
                    "`{}` is not a shared yarn pattern; name one of: {}",
                    scene.pattern,
                    self.known_patterns()
                ),
            ));
        }
        Ok(())
    }

    fn admit(
        &self,
        scene: &YarnScene,
        _assets: &Assets,
        limits: &Limits,
    ) -> Result<(), FieldError> {
        let pattern = PeriodicPattern::read(&self.pattern_file(scene))
            .map_err(|e| FieldError::new("pattern", e.to_string()))?;
        let unknowns = 4 * pattern.len() as u64 * (scene.cells[0] * scene.cells[1]) as u64;
        if unknowns > limits.max_unknowns {
            return Err(FieldError::new(
                "cells",
                format!(
                    "{} × {} cells of {} have {unknowns} unknowns, more than this server's limit of {} \
                     (jobs.max_unknowns); use fewer cells",
                    scene.cells[0], scene.cells[1], scene.pattern, limits.max_unknowns
                ),
            ));
        }
        Ok(())
    }

    fn run(
        &self,
        scene: &YarnScene,
        _assets: &Assets,
        ctx: &mut JobContext,
    ) -> Result<JobOutput, JobError> {
        let dir = std::env::temp_dir().join(format!("skintight-yarn-{}", ctx.job_id()));
        let _ = std::fs::remove_dir_all(&dir);
        let work = WorkDir(dir.clone());
        let mut stop: Option<JobError> = None;
        let result = run(scene, &self.pattern_file(scene), &dir, |p| {
            if p.frame == 0 {
                return match ctx.should_stop() {
                    Ok(()) => ControlFlow::Continue(()),
                    Err(e) => {
                        stop = Some(e);
                        ControlFlow::Break(())
                    }
                };
            }
            ctx.progress(p.frame as f64 / (p.frame_count.max(2) - 1) as f64);
            let metrics = serde_json::to_value(p).unwrap_or_else(|_| json!({}));
            match ctx.iteration_number(p.frame as u64, metrics) {
                Ok(()) => ControlFlow::Continue(()),
                Err(e) => {
                    stop = Some(e);
                    ControlFlow::Break(())
                }
            }
        });
        if let Some(e) = stop {
            return Err(e);
        }
        let result = result.map_err(|e| match e {
            SceneError::Input(m) => JobError::Invalid {
                field: "pattern".into(),
                message: m,
            },
            other => JobError::Failed(other.to_string()),
        })?;
        let read = |name: &str| {
            std::fs::read(work.0.join(name))
                .map_err(|e| JobError::Failed(format!("cannot read {name}: {e}")))
        };
        let mut entries = vec![
            ("sequence.json".to_string(), read("sequence.json")?),
            (
                "vertex_sources.npy".to_string(),
                read("vertex_sources.npy")?,
            ),
        ];
        let mut frames: Vec<String> = std::fs::read_dir(work.0.join("frames"))
            .map_err(|e| JobError::Failed(format!("cannot list the frames: {e}")))?
            .filter_map(|e| e.ok())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect();
        frames.sort();
        for f in frames {
            let name = format!("frames/{f}");
            let data = read(&name)?;
            entries.push((name, data));
        }
        let tar = ustar(&entries).map_err(JobError::Failed)?;
        let summary = serde_json::to_value(&result).unwrap_or_else(|_| json!({}));
        Ok(JobOutput {
            artifacts: vec![
                Artifact {
                    name: "result.json".into(),
                    content_type: "application/json".into(),
                    data: read("result.json")?,
                },
                Artifact {
                    name: "yarns.obj".into(),
                    content_type: "model/obj".into(),
                    data: read("yarns.obj")?,
                },
                Artifact {
                    name: "yarns.glb".into(),
                    content_type: "model/gltf-binary".into(),
                    data: read("yarns.glb")?,
                },
                Artifact {
                    name: "sequence.tar".into(),
                    content_type: "application/x-tar".into(),
                    data: tar,
                },
            ],
            summary,
            warnings: Vec::new(),
        })
    }
}

/// Removes the job's work folder when the run ends, however it ends.
struct WorkDir(PathBuf);

impl Drop for WorkDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A POSIX ustar archive of regular files `(path, bytes)` (paths relative, `/`-separated, at most 100
/// bytes; mode 0644, owner 0, time 0 so the archive is reproducible): per file a 512-byte header (name,
/// mode, uid, gid, size and mtime as octal text, checksum = the sum of the header's bytes with the
/// checksum field read as spaces, type `0`, magic `ustar\0` version `00`) and the data padded to 512 bytes;
/// two zero blocks end it.
pub fn ustar(files: &[(String, Vec<u8>)]) -> Result<Vec<u8>, String> {
    let mut out = Vec::new();
    for (name, data) in files {
        if name.len() > 100 || name.is_empty() || Path::new(name).is_absolute() {
            return Err(format!(
                "cannot archive `{name}`: tar names are 1 to 100 bytes, relative"
            ));
        }
        let mut h = [0u8; 512];
        h[..name.len()].copy_from_slice(name.as_bytes());
        let octal = |h: &mut [u8; 512], at: usize, width: usize, v: u64| {
            let text = format!("{v:0w$o}\0", w = width - 1);
            h[at..at + width].copy_from_slice(text.as_bytes());
        };
        octal(&mut h, 100, 8, 0o644);
        octal(&mut h, 108, 8, 0);
        octal(&mut h, 116, 8, 0);
        if data.len() as u64 >= 8u64.pow(11) {
            return Err(format!("cannot archive `{name}`: larger than 8 GiB"));
        }
        octal(&mut h, 124, 12, data.len() as u64);
        octal(&mut h, 136, 12, 0);
        h[148..156].copy_from_slice(b"        ");
        h[156] = b'0';
        h[257..263].copy_from_slice(b"ustar\0");
        h[263..265].copy_from_slice(b"00");
        let sum: u64 = h.iter().map(|&b| b as u64).sum();
        let text = format!("{sum:06o}\0 ");
        h[148..156].copy_from_slice(text.as_bytes());
        out.extend_from_slice(&h);
        out.extend_from_slice(data);
        out.resize(out.len().div_ceil(512) * 512, 0);
    }
    out.resize(out.len() + 1024, 0);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ustar_archives_unpack_with_tar() {
        let files = vec![
            ("sequence.json".to_string(), b"{\"a\": 1}\n".to_vec()),
            ("frames/000000.npy".to_string(), vec![7u8; 1000]),
            ("empty".to_string(), vec![]),
        ];
        let bytes = ustar(&files).unwrap();
        assert_eq!(bytes.len() % 512, 0);
        // Headers: name, size in octal, a checksum that adds up.
        assert_eq!(&bytes[..13], b"sequence.json");
        assert_eq!(&bytes[124..136], b"00000000011\0");
        let mut h = bytes[..512].to_vec();
        let stored = u64::from_str_radix(std::str::from_utf8(&h[148..154]).unwrap(), 8).unwrap();
        h[148..156].copy_from_slice(b"        ");
        assert_eq!(stored, h.iter().map(|&b| b as u64).sum::<u64>());
        assert!(ustar(&[("/etc/x".into(), vec![])]).is_err());
        // The system's tar reads it back, when there is one.
        let dir = std::env::temp_dir().join(format!("ustar_test_{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("a.tar"), &bytes).unwrap();
        if let Ok(out) = std::process::Command::new("tar")
            .arg("-xf")
            .arg("a.tar")
            .current_dir(&dir)
            .output()
        {
            assert!(
                out.status.success(),
                "{}",
                String::from_utf8_lossy(&out.stderr)
            );
            for (name, data) in &files {
                assert_eq!(&std::fs::read(dir.join(name)).unwrap(), data, "{name}");
            }
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn validation_messages_name_their_field() {
        assert_eq!(field_of("dt_s = -1 must be a number > 0"), "dt_s");
        assert_eq!(
            field_of("yarn parameter young_modulus = -1 is out of range"),
            "yarn.young_modulus"
        );
    }
}
