//! The `yarn_simulate` job kind: the CLI's `skintight knit simulate-yarn` on the worker pool.
//!
//! Spec: a yarn scene (`crate::knit::YarnScene`, the JSON of `examples/knit/`) whose
//! `pattern` is the name of a shared yarn pattern (`stock_9`, `rib_9`, `basket_9`, `satin_9`,
//! `stocktiniest_9`) in the server's yarn data folder (`jobs.yarns_dir`); the service reads no other
//! paths. Checked at submission: the fields' ranges, the pattern's existence, and the patch's unknowns
//! (4 per yarn vertex) against `jobs.max_unknowns`.
//!
//! Every written frame is reported as an `iteration` event numbered by the frame (1, 2, …; frame 0, the
//! start, is not an event) with `{frame, frame_count, time_s, newton_iterations,
//! min_distance_over_diameter, relaxing, relax_newton_iterations}`, and sets the progress to
//! `frame / (frame_count − 1)`; cancellation, the time limit and shutdown are observed after each frame and
//! every few seconds while the start state relaxes (that can take hours for a large patch).
//!
//! **Checkpoints**: the run keeps `checkpoint.json` in its work folder (`crate::knit::YarnRunCheckpoint`);
//! at most every [`STORE_CHECKPOINT_INTERVAL_S`] of wall-clock time (and when the job is stopped) the job
//! saves that file with the frames written so far, as one ustar archive, as the job's checkpoint in the
//! store. A job interrupted by a shutdown or a crash and claimed again — by this or another worker process —
//! unpacks it into a fresh work folder and resumes there: the relaxation from its last checkpoint, the
//! steps after their last saved frame (the same frames as an uninterrupted run, to rounding). Unlike the
//! other kinds, a frame's `iteration` event is not written in one transaction with a checkpoint: a
//! checkpoint holds megabytes (the state and every frame so far) and a frame of a small patch takes
//! milliseconds, so a resumed run re-computes the frames since the last checkpoint (without announcing
//! them again) rather than storing a checkpoint a frame.
//!
//! Artifacts: `result.json` (`crate::knit::YarnSimulationResult`), `yarns.obj` and
//! `yarns.glb` (the last frame), and `sequence.tar`: the frame-sequence directory (`sequence.json`,
//! `vertex_sources.npy`, `frames/*.npy`; docs/OUTPUTS.md) as one POSIX ustar archive, so the sequence
//! unpacks with `tar -xf` into exactly the layout the CLI writes.

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::time::Instant;

use serde_json::{Value, json};
use skintight_knit::PeriodicPattern;

use super::model::{Artifact, Assets, FieldError, JobError, JobOutput};
use super::runner::{JobContext, JobRunner};
use crate::json_input::parse_json_input;
use crate::knit::{CHECKPOINT_FILE, YarnRunParams, YarnScene, YarnSceneError, run};
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
        // An earlier attempt's checkpoint: its files, unpacked into the fresh work folder. One that does not
        // unpack or does not resume (written by another version) costs its time, not the job: the run then
        // starts over.
        let mut resume = match ctx.last_checkpoint() {
            Some(cp) => match unpack_ustar(&cp.data, &dir) {
                Ok(()) => true,
                Err(e) => {
                    tracing::warn!(job = %ctx.job_id(), error = %e, "the job's checkpoint does not unpack; starting over");
                    let _ = std::fs::remove_dir_all(&dir);
                    false
                }
            },
            None => false,
        };
        let mut saved_at = Instant::now();
        let result = loop {
            let params = YarnRunParams {
                resume,
                ..YarnRunParams::default()
            };
            let mut stop: Option<JobError> = None;
            let result = run(scene, &self.pattern_file(scene), &dir, &params, |p| {
                let mut flow = ctx.should_stop();
                if flow.is_ok() && !p.relaxing && p.frame > 0 {
                    ctx.progress(p.frame as f64 / (p.frame_count.max(2) - 1) as f64);
                    let metrics = serde_json::to_value(p).unwrap_or_else(|_| json!({}));
                    flow = ctx.iteration_number(p.frame as u64, metrics);
                }
                if flow.is_ok() && saved_at.elapsed().as_secs_f64() >= STORE_CHECKPOINT_INTERVAL_S {
                    saved_at = Instant::now();
                    flow = match pack_checkpoint(&dir) {
                        Ok(Some(bytes)) => ctx.checkpoint(bytes),
                        Ok(None) => Ok(()),
                        Err(e) => Err(JobError::Failed(e)),
                    };
                }
                match flow {
                    Ok(()) => ControlFlow::Continue(()),
                    Err(e) => {
                        stop = Some(e);
                        ControlFlow::Break(())
                    }
                }
            });
            if let Some(e) = stop {
                // A shutdown: save where the run stopped (it wrote its checkpoint on the way out), so that
                // the next attempt resumes from there. A failure to save only costs the time since the last.
                if matches!(e, JobError::Interrupted)
                    && let Ok(Some(bytes)) = pack_checkpoint(&dir)
                {
                    let _ = ctx.checkpoint(bytes);
                }
                return Err(e);
            }
            match result {
                Err(YarnSceneError::Input(m)) if resume && m.contains(CHECKPOINT_FILE) => {
                    tracing::warn!(job = %ctx.job_id(), error = %m, "the job's checkpoint does not resume; starting over");
                    let _ = std::fs::remove_dir_all(&dir);
                    resume = false;
                }
                other => break other,
            }
        };
        let result = result.map_err(|e| match e {
            YarnSceneError::Input(m) => JobError::Invalid {
                field: "pattern".into(),
                message: m,
            },
            other => JobError::Failed(other.to_string()),
        })?;
        let read = |name: &str| {
            std::fs::read(work.0.join(name))
                .map_err(|e| JobError::Failed(format!("cannot read {name}: {e}")))
        };
        let entries = sequence_files(&work.0, true).map_err(JobError::Failed)?;
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

/// Least wall-clock time between two checkpoints saved in the store (s): a checkpoint of a large patch is
/// megabytes (the state and the frames so far), and a frame of a small one takes milliseconds.
pub const STORE_CHECKPOINT_INTERVAL_S: f64 = 60.0;

/// The frame-sequence files of the run folder `dir` as `(name, bytes)` in archive order: `sequence.json`,
/// `vertex_sources.npy` and `frames/*.npy` sorted. With `complete` the first two must be there (a finished
/// run); without, whatever the run has written so far (a checkpoint, maybe before its first frame).
fn sequence_files(dir: &Path, complete: bool) -> Result<Vec<(String, Vec<u8>)>, String> {
    let read =
        |name: &str| std::fs::read(dir.join(name)).map_err(|e| format!("cannot read {name}: {e}"));
    let mut files = Vec::new();
    for name in ["sequence.json", "vertex_sources.npy"] {
        if complete || dir.join(name).is_file() {
            files.push((name.to_string(), read(name)?));
        }
    }
    let frames = match std::fs::read_dir(dir.join("frames")) {
        Ok(entries) => entries,
        Err(e) if complete => return Err(format!("cannot list the frames: {e}")),
        Err(_) => return Ok(files),
    };
    let mut names: Vec<String> = frames
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".npy"))
        .collect();
    names.sort();
    for f in names {
        let name = format!("frames/{f}");
        let data = read(&name)?;
        files.push((name, data));
    }
    Ok(files)
}

/// The run's checkpoint with the sequence written so far (`checkpoint.json` and [`sequence_files`]) as one
/// ustar archive; `None` while the run has no checkpoint.
fn pack_checkpoint(dir: &Path) -> Result<Option<Vec<u8>>, String> {
    let path = dir.join(CHECKPOINT_FILE);
    if !path.is_file() {
        return Ok(None);
    }
    let checkpoint = std::fs::read(&path)
        .map_err(|e| format!("cannot read {CHECKPOINT_FILE} for a checkpoint: {e}"))?;
    let mut files = vec![(CHECKPOINT_FILE.to_string(), checkpoint)];
    files.extend(sequence_files(dir, false)?);
    ustar(&files).map(Some)
}

/// Unpacks an archive written by [`ustar`] into `dir` (created): regular files only, names relative
/// without `..`; anything else is an error naming the entry.
pub fn unpack_ustar(bytes: &[u8], dir: &Path) -> Result<(), String> {
    let mut at = 0;
    while at + 512 <= bytes.len() {
        let h = &bytes[at..at + 512];
        if h.iter().all(|&b| b == 0) {
            return Ok(());
        }
        let name_end = h[..100].iter().position(|&b| b == 0).unwrap_or(100);
        let name = std::str::from_utf8(&h[..name_end])
            .map_err(|_| format!("the entry at byte {at} has a name that is not UTF-8"))?;
        let size_text = std::str::from_utf8(&h[124..136])
            .unwrap_or("")
            .trim_matches(|c: char| c == '\0' || c == ' ');
        let size = usize::from_str_radix(size_text, 8)
            .map_err(|_| format!("`{name}`: the size `{size_text}` is not octal"))?;
        let path = Path::new(name);
        if name.is_empty()
            || path.is_absolute()
            || path
                .components()
                .any(|c| !matches!(c, std::path::Component::Normal(_)))
        {
            return Err(format!("`{name}` is not a relative file name"));
        }
        if h[156] != b'0' && h[156] != 0 {
            return Err(format!("`{name}` is not a regular file"));
        }
        let start = at + 512;
        let end = start
            .checked_add(size)
            .filter(|&e| e <= bytes.len())
            .ok_or_else(|| format!("`{name}` runs past the end of the archive"))?;
        let target = dir.join(path);
        if let Some(parent) = target.parent() {
            std::fs::create_dir_all(parent)
                .map_err(|e| format!("cannot create {}: {e}", parent.display()))?;
        }
        std::fs::write(&target, &bytes[start..end])
            .map_err(|e| format!("cannot write {}: {e}", target.display()))?;
        at = start + size.div_ceil(512) * 512;
    }
    Err("the archive ends without its two zero blocks".into())
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
    fn ustar_archives_unpack_and_bad_entries_are_named() {
        let files = vec![
            ("checkpoint.json".to_string(), b"{}".to_vec()),
            ("frames/000000.npy".to_string(), vec![3u8; 700]),
            ("empty".to_string(), vec![]),
        ];
        let bytes = ustar(&files).unwrap();
        let dir = std::env::temp_dir().join(format!("unpack_test_{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        unpack_ustar(&bytes, &dir).unwrap();
        for (name, data) in &files {
            assert_eq!(&std::fs::read(dir.join(name)).unwrap(), data, "{name}");
        }
        // What the checkpoint of a run folder packs is what unpacks.
        std::fs::remove_file(dir.join("empty")).unwrap();
        let packed = pack_checkpoint(&dir)
            .unwrap()
            .expect("a checkpoint.json is there");
        let again = dir.join("again");
        unpack_ustar(&packed, &again).unwrap();
        assert_eq!(
            std::fs::read(again.join("frames/000000.npy")).unwrap(),
            vec![3u8; 700]
        );
        assert!(pack_checkpoint(&again.join("frames")).unwrap().is_none());
        // Truncated, escaping and non-octal entries are refused by name.
        let e = unpack_ustar(&bytes[..1024 + 512], &dir).unwrap_err();
        assert!(
            e.contains("frames/000000.npy") && e.contains("past the end"),
            "{e}"
        );
        let mut evil = ustar(&[("x".to_string(), vec![1])]).unwrap();
        evil[..5].copy_from_slice(b"../x\0");
        let e = unpack_ustar(&evil, &dir).unwrap_err();
        assert!(e.contains("../x") && e.contains("relative"), "{e}");
        let mut bad = bytes.clone();
        bad[124..136].copy_from_slice(b"zz000000000\0");
        assert!(unpack_ustar(&bad, &dir).unwrap_err().contains("not octal"));
        assert!(unpack_ustar(&bytes[..512 + 512], &dir).is_err());
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
