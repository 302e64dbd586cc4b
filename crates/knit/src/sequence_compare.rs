//! Two frame sequences of the same patch compared in time (the knitwear paper's Fig. 10 and Table 1:
//! yarn-level against homogenized): for every frame `k` of the first sequence `A` whose time `t_k` lies
//! within the second's span, the second's positions at `t_k` are interpolated linearly between its two
//! frames around `t_k`, and the per-vertex distances are summarized,
//!
//! ```text
//! mean_error_m(k) = 1/V Σ_v |x_A,v(t_k) − x_B,v(t_k)|,      max_error_m(k) = max_v |…|      (m),
//! ```
//!
//! positions only (the edge angles `θ` are not compared: a homogenized run has none of its own). Both
//! sequences must carry the same yarn vertices in the same order (the same pattern tiled the same way,
//! the homogenized one written through V2Y). `patch_size_m` is the largest side of `A`'s first-frame
//! bounding box, the length the paper's relative errors are quoted against.
//!
//! Frames are matched by time and not by index, so runs with different time steps or frame intervals
//! compare; a frame of `A` outside `B`'s span (`B` stopped earlier) is left out and counted.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::frame_sequence::{Sequence, SequenceError};

/// Why two sequences cannot be compared.
#[derive(Debug, thiserror::Error)]
pub enum SequenceCompareError {
    /// A sequence could not be read.
    #[error(transparent)]
    Read(#[from] SequenceError),
    /// The sequences do not hold the same vertices.
    #[error(
        "{} has {a} yarn vertices and {} has {b}; compare runs of the same pattern and cells",
        first.display(),
        second.display()
    )]
    Vertices {
        /// The first sequence's directory.
        first: PathBuf,
        /// Its vertices.
        a: usize,
        /// The second sequence's directory.
        second: PathBuf,
        /// Its vertices.
        b: usize,
    },
    /// A sequence has no frames, or none of the first lies within the second's times.
    #[error("{}: {problem}", dir.display())]
    Frames {
        /// The directory.
        dir: PathBuf,
        /// What is missing.
        problem: String,
    },
    /// A frame holds NaN or ∞, or the frame times are not increasing.
    #[error("{}: {problem}", path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        problem: String,
    },
}

/// One matched frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameError {
    /// The frame's index in the first sequence.
    pub frame: usize,
    /// Its time (s).
    pub time_s: f64,
    /// Mean over vertices of the position distance (m).
    pub mean_error_m: f64,
    /// Largest position distance (m).
    pub max_error_m: f64,
}

/// What `skintight knit compare` prints.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SequenceComparison {
    /// The largest side of the first sequence's first-frame bounding box (m).
    pub patch_size_m: f64,
    /// Yarn vertices compared per frame.
    pub vertex_count: usize,
    /// The matched frames, in time order.
    pub frames: Vec<FrameError>,
    /// Frames of the first sequence outside the second's time span (not compared).
    pub unmatched_frames: usize,
    /// The largest `mean_error_m` over the frames (m).
    pub max_mean_error_m: f64,
    /// `max_mean_error_m / patch_size_m` (dimensionless).
    pub max_mean_error_over_size: f64,
}

/// Frame `i` of `seq` (in `dir`) as positions, refusing NaN and ∞.
fn positions(seq: &Sequence, dir: &Path, i: usize) -> Result<Vec<[f64; 3]>, SequenceCompareError> {
    let rows = seq.frame(dir, i)?;
    if let Some(v) = rows.iter().position(|r| !r.iter().all(|c| c.is_finite())) {
        return Err(SequenceCompareError::Invalid {
            path: dir.join(&seq.meta.frames[i].file),
            problem: format!("vertex {v} is not finite"),
        });
    }
    Ok(rows.iter().map(|r| [r[0], r[1], r[2]]).collect())
}

/// The frame times of `seq`, checked finite and increasing.
fn times(seq: &Sequence, dir: &Path) -> Result<Vec<f64>, SequenceCompareError> {
    let t: Vec<f64> = seq.meta.frames.iter().map(|f| f.time_s).collect();
    if t.is_empty() {
        return Err(SequenceCompareError::Frames {
            dir: dir.to_path_buf(),
            problem: "the sequence has no frames".into(),
        });
    }
    if t.iter().any(|v| !v.is_finite()) || t.windows(2).any(|w| w[1] <= w[0]) {
        return Err(SequenceCompareError::Invalid {
            path: dir.join("sequence.json"),
            problem: "the frames' time_s are not finite and increasing".into(),
        });
    }
    Ok(t)
}

/// Compares the sequences in `first` and `second` (see the module doc).
pub fn compare_sequences(
    first: &Path,
    second: &Path,
) -> Result<SequenceComparison, SequenceCompareError> {
    let a = Sequence::open(first)?;
    let b = Sequence::open(second)?;
    if a.meta.vertex_count != b.meta.vertex_count {
        return Err(SequenceCompareError::Vertices {
            first: first.to_path_buf(),
            a: a.meta.vertex_count,
            second: second.to_path_buf(),
            b: b.meta.vertex_count,
        });
    }
    let (ta, tb) = (times(&a, first)?, times(&b, second)?);
    let first_frame = positions(&a, first, 0)?;
    let mut size = 0.0f64;
    for i in 0..3 {
        let (lo, hi) = first_frame
            .iter()
            .fold((f64::MAX, f64::MIN), |(l, h), p| (l.min(p[i]), h.max(p[i])));
        size = size.max(hi - lo);
    }
    // Times within a part in 10⁹ of B's span count as inside (frame times are sums of steps).
    let slack = 1e-9 * (tb[tb.len() - 1] - tb[0]).abs().max(1e-12);
    let mut frames = Vec::new();
    let mut unmatched = 0;
    // B's two frames around the current time, loaded once each as the time advances.
    let mut cache: Option<(usize, Vec<[f64; 3]>, Vec<[f64; 3]>)> = None;
    for (k, &t) in ta.iter().enumerate() {
        if t < tb[0] - slack || t > tb[tb.len() - 1] + slack {
            unmatched += 1;
            continue;
        }
        let j = tb
            .partition_point(|&s| s <= t)
            .clamp(1, tb.len().max(2) - 1);
        let (lo, hi) = if tb.len() == 1 { (0, 0) } else { (j - 1, j) };
        if cache.as_ref().is_none_or(|c| c.0 != lo) {
            let p0 = positions(&b, second, lo)?;
            let p1 = if hi == lo {
                p0.clone()
            } else {
                positions(&b, second, hi)?
            };
            cache = Some((lo, p0, p1));
        }
        let (_, p0, p1) = cache.as_ref().expect("loaded above");
        let w = if hi == lo {
            0.0
        } else {
            ((t - tb[lo]) / (tb[hi] - tb[lo])).clamp(0.0, 1.0)
        };
        let xa = if k == 0 {
            first_frame.clone()
        } else {
            positions(&a, first, k)?
        };
        let (mut sum, mut worst) = (0.0, 0.0f64);
        for (v, p) in xa.iter().enumerate() {
            let d = (0..3)
                .map(|i| {
                    let q = (1.0 - w) * p0[v][i] + w * p1[v][i];
                    (p[i] - q).powi(2)
                })
                .sum::<f64>()
                .sqrt();
            sum += d;
            worst = worst.max(d);
        }
        frames.push(FrameError {
            frame: k,
            time_s: t,
            mean_error_m: sum / xa.len().max(1) as f64,
            max_error_m: worst,
        });
    }
    if frames.is_empty() {
        return Err(SequenceCompareError::Frames {
            dir: second.to_path_buf(),
            problem: format!(
                "no frame of {} lies within this sequence's times {} … {} s",
                first.display(),
                tb[0],
                tb[tb.len() - 1]
            ),
        });
    }
    let max_mean_error_m = frames.iter().fold(0.0f64, |m, f| m.max(f.mean_error_m));
    Ok(SequenceComparison {
        patch_size_m: size,
        vertex_count: a.meta.vertex_count,
        frames,
        unmatched_frames: unmatched,
        max_mean_error_m,
        max_mean_error_over_size: if size > 0.0 {
            max_mean_error_m / size
        } else {
            0.0
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame_sequence::{SequenceMeta, SequenceWriter, Units, YarnRange};

    fn meta(vertices: usize, dt: f64) -> SequenceMeta {
        SequenceMeta {
            format: crate::frame_sequence::FORMAT.into(),
            version: crate::frame_sequence::VERSION,
            pattern: "test".into(),
            cells: [1, 1],
            scenario: "test".into(),
            units: Units::default(),
            yarn_radius_m: 1e-3,
            linear_density_kg_per_m: 1e-5,
            dt_s: dt,
            frame_interval_s: dt,
            vertex_count: vertices,
            frame_count: 0,
            yarns: vec![YarnRange {
                first_vertex: 0,
                vertex_count: vertices,
                closed: false,
            }],
            frames: Vec::new(),
            loads: None,
        }
    }

    /// A straight yarn of `n` vertices 1 cm apart along x, moving along y at `speed` m/s, written at
    /// the times `times`.
    fn write(dir: &Path, n: usize, speed: f64, times: &[f64]) {
        let sources: Vec<(usize, [i32; 2])> = (0..n).map(|v| (v, [0, 0])).collect();
        let mut w = SequenceWriter::create(dir, meta(n, times[1] - times[0]), &sources).unwrap();
        for &t in times {
            let x: Vec<f64> = (0..n)
                .flat_map(|v| [0.01 * v as f64, speed * t, 0.0, 0.0])
                .collect();
            w.push(t, &x).unwrap();
        }
    }

    /// A fresh folder under the system's temporary directory, removed when dropped.
    struct Scratch(PathBuf);
    impl Scratch {
        fn new(name: &str) -> Self {
            let dir =
                std::env::temp_dir().join(format!("knit_compare_{}_{name}", std::process::id()));
            let _ = std::fs::remove_dir_all(&dir);
            std::fs::create_dir_all(&dir).unwrap();
            Self(dir)
        }
        fn path(&self) -> &Path {
            &self.0
        }
    }
    impl Drop for Scratch {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    #[test]
    fn frames_are_matched_by_time_and_interpolated() {
        let tmp = Scratch::new("matched");
        let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
        // A: 11 frames over 0.1 s, at rest. B: moving at 0.2 m/s, frames every 0.03 s to 0.09 s.
        let ta: Vec<f64> = (0..=10).map(|k| 0.01 * k as f64).collect();
        let tb: Vec<f64> = (0..=3).map(|k| 0.03 * k as f64).collect();
        write(&a, 5, 0.0, &ta);
        write(&b, 5, 0.2, &tb);
        let c = compare_sequences(&a, &b).unwrap();
        assert!((c.patch_size_m - 0.04).abs() < 1e-15);
        assert_eq!(c.vertex_count, 5);
        // The frame at 0.1 s lies beyond B's last frame.
        assert_eq!(c.unmatched_frames, 1);
        assert_eq!(c.frames.len(), 10);
        for f in &c.frames {
            // Linear motion is interpolated exactly: every vertex is 0.2 t away.
            assert!((f.mean_error_m - 0.2 * f.time_s).abs() < 1e-12, "{f:?}");
            assert!((f.max_error_m - f.mean_error_m).abs() < 1e-12);
        }
        assert!((c.max_mean_error_m - 0.2 * 0.09).abs() < 1e-12);
        assert!((c.max_mean_error_over_size - 0.018 / 0.04).abs() < 1e-9);
        // Against itself: zero.
        let same = compare_sequences(&b, &b).unwrap();
        assert_eq!(same.max_mean_error_m, 0.0);
    }

    #[test]
    fn mismatched_or_broken_sequences_are_refused_by_name() {
        let tmp = Scratch::new("broken");
        let (a, b, c) = (
            tmp.path().join("a"),
            tmp.path().join("b"),
            tmp.path().join("late"),
        );
        write(&a, 5, 0.0, &[0.0, 0.01]);
        write(&b, 6, 0.0, &[0.0, 0.01]);
        write(&c, 5, 0.0, &[1.0, 1.01]);
        let err = compare_sequences(&a, &b).unwrap_err().to_string();
        assert!(
            err.contains("5 yarn vertices") && err.contains("has 6"),
            "{err}"
        );
        let err = compare_sequences(&a, &c).unwrap_err().to_string();
        assert!(err.contains("no frame"), "{err}");
        let err = compare_sequences(&a, &tmp.path().join("missing"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("sequence.json"), "{err}");
        // A NaN in a frame is named, not propagated.
        let frame = b.join("frames/000001.npy");
        let mut bytes = std::fs::read(&frame).unwrap();
        let n = bytes.len();
        bytes[n - 8..].copy_from_slice(&f64::NAN.to_le_bytes());
        bytes[n - 40..n - 32].copy_from_slice(&f64::NAN.to_le_bytes());
        std::fs::write(&frame, bytes).unwrap();
        let err = compare_sequences(&b, &b).unwrap_err().to_string();
        assert!(
            err.contains("000001.npy") && err.contains("not finite"),
            "{err}"
        );
    }
}
