//! The frame-sequence format of simulated yarn motion (what `skintight knit simulate-yarn` writes and the
//! homogenization of issue 19 part 2 reads): a directory
//!
//! ```text
//! DIR/sequence.json          metadata (below)
//! DIR/vertex_sources.npy     float64 (V, 3): per vertex the pattern vertex and the cell (cx, cy) it copies
//! DIR/frames/000000.npy      float64 (V, 4): per vertex x, y, z (m) and the angle θ (rad) of the edge
//! DIR/frames/000001.npy      starting there (0 at the last vertex of an open yarn), one file per frame
//! ```
//!
//! `sequence.json` holds `format` (`"skintight-yarn-sequence"`), `version` (1), `pattern` (the pattern
//! folder or file it was tiled from), `cells` `[nx, ny]`, `scenario`, `units` (`length: "m"`, `time: "s"`,
//! `angle: "rad"`), `yarn_radius_m`, `linear_density_kg_per_m`, `dt_s` (time step), `frame_interval_s`,
//! `vertex_count`, `frame_count`, `yarns` (per yarn `first_vertex`, `vertex_count`, `closed`: vertices
//! `first_vertex .. first_vertex + vertex_count` of every frame are that yarn's polyline, in order; a closed
//! yarn's last vertex joins its first), and `frames` (per frame its `file` relative to `DIR` and `time_s`).
//! Frame 0 is the initial state. Rows are in the order of the yarns, so vertex `i` is the same material
//! point in every frame.
//!
//! **Why NumPy `.npy` files, one per frame**: `numpy.load` reads a frame in one call with its shape and
//! dtype (part 2's fitting can be written in Python or in Rust with [`crate::npy`], which reads it too); a
//! fixed-size binary with a 64-byte-aligned header can be memory-mapped; one file per frame lets a running
//! simulation publish each frame as it is computed ([`SequenceWriter`] rewrites `sequence.json` after each),
//! so a partial sequence is always a valid, shorter one.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::npy::{read_npy, write_npy_f64};

/// The `format` value of `sequence.json`.
pub const FORMAT: &str = "skintight-yarn-sequence";
/// The `version` of this layout.
pub const VERSION: u32 = 1;

/// Units of a sequence (always SI).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Units {
    /// Length unit: `"m"`.
    pub length: String,
    /// Time unit: `"s"`.
    pub time: String,
    /// Angle unit: `"rad"`.
    pub angle: String,
}

impl Default for Units {
    fn default() -> Self {
        Self {
            length: "m".into(),
            time: "s".into(),
            angle: "rad".into(),
        }
    }
}

/// One yarn's vertex range.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct YarnRange {
    /// First vertex of the yarn.
    pub first_vertex: usize,
    /// Number of vertices.
    pub vertex_count: usize,
    /// Whether the last vertex joins the first.
    pub closed: bool,
}

/// One frame's file and time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameEntry {
    /// The `.npy` file, relative to the sequence directory.
    pub file: String,
    /// Simulated time (s).
    pub time_s: f64,
}

/// The contents of `sequence.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SequenceMeta {
    /// [`FORMAT`].
    pub format: String,
    /// [`VERSION`].
    pub version: u32,
    /// The pattern the patch was tiled from.
    pub pattern: String,
    /// Cells `[nx, ny]`.
    pub cells: [usize; 2],
    /// What was simulated (e.g. `hang`).
    pub scenario: String,
    /// Units.
    pub units: Units,
    /// Yarn radius (m).
    pub yarn_radius_m: f64,
    /// Mass per unit yarn length (kg/m).
    pub linear_density_kg_per_m: f64,
    /// Time step (s).
    pub dt_s: f64,
    /// Simulated time between frames (s).
    pub frame_interval_s: f64,
    /// Vertices per frame.
    pub vertex_count: usize,
    /// Frames written.
    pub frame_count: usize,
    /// The yarns' vertex ranges.
    pub yarns: Vec<YarnRange>,
    /// The frames.
    pub frames: Vec<FrameEntry>,
    /// What acted on the yarns besides their own elasticity and inertia: what a homogenization needs to
    /// pose each frame as a quasi-static problem. Absent in sequences written before it was recorded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub loads: Option<SequenceLoads>,
}

/// The loads of a sequence ([`SequenceMeta::loads`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SequenceLoads {
    /// Gravity's acceleration (m/s², `[x, y, z]`).
    pub gravity_m_per_s2: [f64; 3],
    /// The vertices whose positions the scene prescribed (clamped or moved by grips), ascending.
    pub held_vertices: Vec<usize>,
    /// Whether a collider (e.g. a sphere) pushed on the yarns: forces the frames do not record.
    pub collider: bool,
}

/// Errors reading or writing a sequence.
#[derive(Debug, thiserror::Error)]
pub enum SequenceError {
    /// A file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The failure.
        source: std::io::Error,
    },
    /// The contents are not a valid sequence.
    #[error("{}: {problem}", path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        problem: String,
    },
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> SequenceError + '_ {
    move |source| SequenceError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Writes a sequence frame by frame.
#[derive(Debug)]
pub struct SequenceWriter {
    dir: PathBuf,
    meta: SequenceMeta,
}

impl SequenceWriter {
    /// Creates `dir` (and `dir/frames`), writes `vertex_sources.npy` (`sources[v] = (pattern vertex, cx,
    /// cy)`) and `sequence.json` with no frames. `meta.frames` and `meta.frame_count` are reset.
    pub fn create(
        dir: &Path,
        mut meta: SequenceMeta,
        sources: &[(usize, [i32; 2])],
    ) -> Result<Self, SequenceError> {
        if sources.len() != meta.vertex_count {
            return Err(SequenceError::Invalid {
                path: dir.join("vertex_sources.npy"),
                problem: format!(
                    "{} vertex sources for {} vertices",
                    sources.len(),
                    meta.vertex_count
                ),
            });
        }
        let frames = dir.join("frames");
        std::fs::create_dir_all(&frames).map_err(io(&frames))?;
        let path = dir.join("vertex_sources.npy");
        let data: Vec<f64> = sources
            .iter()
            .flat_map(|(v, c)| [*v as f64, c[0] as f64, c[1] as f64])
            .collect();
        write_npy_f64(&path, &[sources.len(), 3], &data).map_err(io(&path))?;
        meta.frames.clear();
        meta.frame_count = 0;
        let writer = Self {
            dir: dir.to_path_buf(),
            meta,
        };
        writer.write_meta()?;
        Ok(writer)
    }

    fn write_meta(&self) -> Result<(), SequenceError> {
        let path = self.dir.join("sequence.json");
        let tmp = self.dir.join("sequence.json.tmp");
        let text =
            serde_json::to_string_pretty(&self.meta).map_err(|e| SequenceError::Invalid {
                path: path.clone(),
                problem: e.to_string(),
            })?;
        std::fs::write(&tmp, text).map_err(io(&tmp))?;
        std::fs::rename(&tmp, &path).map_err(io(&path))
    }

    /// Appends a frame at time `time_s` (s) from the unknowns `x` (4 per vertex: position in m, angle in
    /// rad) and rewrites `sequence.json`. Returns the frame's path.
    pub fn push(&mut self, time_s: f64, x: &[f64]) -> Result<PathBuf, SequenceError> {
        let file = format!("frames/{:06}.npy", self.meta.frames.len());
        let path = self.dir.join(&file);
        if x.len() != 4 * self.meta.vertex_count {
            return Err(SequenceError::Invalid {
                path,
                problem: format!(
                    "a frame of {} numbers for {} vertices (4 each)",
                    x.len(),
                    self.meta.vertex_count
                ),
            });
        }
        write_npy_f64(&path, &[self.meta.vertex_count, 4], x).map_err(io(&path))?;
        self.meta.frames.push(FrameEntry { file, time_s });
        self.meta.frame_count = self.meta.frames.len();
        self.write_meta()?;
        Ok(path)
    }

    /// Continues the sequence in `dir` after its first `frames` frames (a resumed run, the app crate's
    /// `src/knit/checkpoint.rs`): frames written after those — by a run that stopped before its next
    /// checkpoint — are deleted and `sequence.json` lists the first `frames`; the next [`Self::push`] writes
    /// frame `frames`. Fails when the sequence is not valid or has fewer frames.
    pub fn resume(dir: &Path, frames: usize) -> Result<Self, SequenceError> {
        let sequence = Sequence::open(dir)?;
        let mut meta = sequence.meta;
        if meta.frames.len() < frames {
            return Err(SequenceError::Invalid {
                path: dir.join("sequence.json"),
                problem: format!(
                    "lists {} frames; the run to resume had written {frames}",
                    meta.frames.len()
                ),
            });
        }
        for entry in meta.frames.drain(frames..) {
            let path = dir.join(&entry.file);
            match std::fs::remove_file(&path) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(io(&path)(e)),
                _ => {}
            }
        }
        meta.frame_count = meta.frames.len();
        let writer = Self {
            dir: dir.to_path_buf(),
            meta,
        };
        writer.write_meta()?;
        Ok(writer)
    }

    /// The metadata written so far.
    pub fn meta(&self) -> &SequenceMeta {
        &self.meta
    }

    /// The sequence directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }
}

/// A sequence read back.
#[derive(Clone, Debug, PartialEq)]
pub struct Sequence {
    /// The metadata.
    pub meta: SequenceMeta,
    /// Per vertex: pattern vertex and cell `[cx, cy]`.
    pub sources: Vec<(usize, [i32; 2])>,
}

impl Sequence {
    /// Reads `dir/sequence.json` and `dir/vertex_sources.npy`, checking format, version and sizes.
    pub fn open(dir: &Path) -> Result<Self, SequenceError> {
        let path = dir.join("sequence.json");
        let text = std::fs::read_to_string(&path).map_err(io(&path))?;
        let invalid = |problem: String| SequenceError::Invalid {
            path: path.clone(),
            problem,
        };
        let meta: SequenceMeta = serde_json::from_str(&text).map_err(|e| invalid(e.to_string()))?;
        if meta.format != FORMAT || meta.version != VERSION {
            return Err(invalid(format!(
                "format {} version {} is not {FORMAT} version {VERSION}",
                meta.format, meta.version
            )));
        }
        if meta.frame_count != meta.frames.len() {
            return Err(invalid(format!(
                "frame_count {} but {} frames listed",
                meta.frame_count,
                meta.frames.len()
            )));
        }
        let covered: usize = meta.yarns.iter().map(|y| y.vertex_count).sum();
        let contiguous = meta
            .yarns
            .iter()
            .scan(0, |next, y| {
                let ok = y.first_vertex == *next;
                *next += y.vertex_count;
                Some(ok)
            })
            .all(|ok| ok);
        if covered != meta.vertex_count || !contiguous {
            return Err(invalid(format!(
                "the yarn ranges do not cover the {} vertices in order",
                meta.vertex_count
            )));
        }
        let spath = dir.join("vertex_sources.npy");
        let s = read_npy(&spath).map_err(|e| SequenceError::Invalid {
            path: spath.clone(),
            problem: e.problem,
        })?;
        if s.shape != [meta.vertex_count, 3] {
            return Err(SequenceError::Invalid {
                path: spath,
                problem: format!("shape {:?}, expected [{}, 3]", s.shape, meta.vertex_count),
            });
        }
        let sources = s
            .data
            .chunks_exact(3)
            .map(|c| (c[0] as usize, [c[1] as i32, c[2] as i32]))
            .collect();
        Ok(Self { meta, sources })
    }

    /// Frame `i` as `(V, 4)` rows: x, y, z (m) and θ (rad).
    pub fn frame(&self, dir: &Path, i: usize) -> Result<Vec<[f64; 4]>, SequenceError> {
        let entry = self
            .meta
            .frames
            .get(i)
            .ok_or_else(|| SequenceError::Invalid {
                path: dir.join("sequence.json"),
                problem: format!(
                    "frame {i} does not exist ({} frames)",
                    self.meta.frame_count
                ),
            })?;
        let path = dir.join(&entry.file);
        let a = read_npy(&path).map_err(|e| SequenceError::Invalid {
            path: path.clone(),
            problem: e.problem,
        })?;
        if a.shape != [self.meta.vertex_count, 4] {
            return Err(SequenceError::Invalid {
                path,
                problem: format!(
                    "shape {:?}, expected [{}, 4]",
                    a.shape, self.meta.vertex_count
                ),
            });
        }
        Ok(a.data
            .chunks_exact(4)
            .map(|c| [c[0], c[1], c[2], c[3]])
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn meta(vertices: usize) -> SequenceMeta {
        SequenceMeta {
            format: FORMAT.into(),
            version: VERSION,
            pattern: "stock_9".into(),
            cells: [2, 1],
            scenario: "hang".into(),
            units: Units::default(),
            yarn_radius_m: 1e-3,
            linear_density_kg_per_m: 2.1e-3,
            dt_s: 1.0 / 240.0,
            frame_interval_s: 1.0 / 60.0,
            vertex_count: vertices,
            frame_count: 99,
            yarns: vec![
                YarnRange {
                    first_vertex: 0,
                    vertex_count: 2,
                    closed: false,
                },
                YarnRange {
                    first_vertex: 2,
                    vertex_count: vertices - 2,
                    closed: true,
                },
            ],
            frames: vec![],
            loads: None,
        }
    }

    #[test]
    fn frames_round_trip_and_a_partial_sequence_is_valid() {
        let dir = std::env::temp_dir().join(format!("knit_seq_{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let sources: Vec<(usize, [i32; 2])> = (0..5).map(|v| (v % 3, [v as i32 / 3, 1])).collect();
        let mut w = SequenceWriter::create(&dir, meta(5), &sources).unwrap();
        let opened = Sequence::open(&dir).unwrap();
        assert_eq!(opened.meta.frame_count, 0);
        let frames: Vec<Vec<f64>> = (0..3)
            .map(|f| (0..20).map(|k| (f * 100 + k) as f64 * 1e-4 - 0.3).collect())
            .collect();
        for (f, x) in frames.iter().enumerate() {
            w.push(f as f64 / 60.0, x).unwrap();
            let s = Sequence::open(&dir).unwrap();
            assert_eq!(s.meta.frame_count, f + 1);
        }
        let s = Sequence::open(&dir).unwrap();
        assert_eq!(s.sources, sources);
        assert_eq!(s.meta.yarns, meta(5).yarns);
        for (f, x) in frames.iter().enumerate() {
            let rows = s.frame(&dir, f).unwrap();
            let flat: Vec<f64> = rows.iter().flatten().copied().collect();
            assert_eq!(&flat, x);
            assert_eq!(s.meta.frames[f].time_s, f as f64 / 60.0);
        }
        assert!(
            s.frame(&dir, 3)
                .unwrap_err()
                .to_string()
                .contains("frame 3 does not exist")
        );
        assert!(w.push(1.0, &[0.0; 3]).is_err());
        // A broken sequence.json names the file.
        std::fs::write(dir.join("sequence.json"), "{}").unwrap();
        let e = Sequence::open(&dir).unwrap_err().to_string();
        assert!(e.contains("sequence.json"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
