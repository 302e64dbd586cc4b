//! The published yarn-level response of a periodic pattern (MADYPG data, Sperl et al. 2021, computed with
//! the HYLC yarn solver, Sperl et al. 2020): `axes.txt` (the sampled values of the in-plane strains
//! `sx`, `sa`, `sy`) and `data.npy` (shape `(vertices × samples, 4)`, float32; row
//! `isx + nx·isa + nx·na·isy + nx·na·ny·v` holds vertex `v`'s displacement `(dx, dy, dz, dt)` — m, m, m,
//! rad — in the reference cell at sample `(sx[isx], sa[isa], sy[isy])`, see `shared/data/yarns/README.md`).
//!
//! [`PublishedResponse::at_sample`] returns the table at a grid sample, [`PublishedResponse::interpolate`]
//! interpolates trilinearly between samples (the rule of MADYPG's `TexND::sample`, but an error instead of
//! clamping outside the sampled range).

use std::path::{Path, PathBuf};

use thiserror::Error;

use crate::npy::{NpyError, read_npy};

/// Names of the three strain axes, in the order of `axes.txt`.
pub const AXIS_NAMES: [&str; 3] = ["sx", "sa", "sy"];

/// Errors reading or querying a published response.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum ResponseError {
    /// `axes.txt` is missing or malformed.
    #[error("{}:{line}: {problem}", path.display())]
    Axes {
        /// The file.
        path: PathBuf,
        /// 1-based line (0: the whole file).
        line: usize,
        /// What is wrong.
        problem: String,
    },
    /// `data.npy` is unreadable.
    #[error(transparent)]
    Npy(#[from] NpyError),
    /// `data.npy` does not fit the axes and the pattern.
    #[error("{}: {problem}", path.display())]
    Shape {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        problem: String,
    },
    /// A strain outside the sampled range.
    #[error(
        "strain {axis} = {value} is outside the sampled range [{min}, {max}]; the published data cannot be \
         interpolated there — choose {axis} within the range"
    )]
    OutOfRange {
        /// The axis name (`sx`, `sa` or `sy`).
        axis: &'static str,
        /// The requested value.
        value: f64,
        /// Smallest sample.
        min: f64,
        /// Largest sample.
        max: f64,
    },
    /// A sample index or vertex beyond the table.
    #[error("{what} {index} is out of range (there are {count})")]
    Index {
        /// What was indexed.
        what: &'static str,
        /// The index.
        index: usize,
        /// How many there are.
        count: usize,
    },
}

/// The displacement table of one pattern.
#[derive(Clone, Debug, PartialEq)]
pub struct PublishedResponse {
    /// Sampled values of `sx`, `sa`, `sy` (dimensionless), each increasing.
    pub axes: [Vec<f64>; 3],
    /// Number of yarn vertices.
    pub vertex_count: usize,
    /// Rows of `(dx, dy, dz, dt)` in the file's order.
    data: Vec<[f64; 4]>,
}

impl PublishedResponse {
    /// Reads `axes.txt` and `data.npy` from a pattern folder.
    pub fn read(dir: &Path) -> Result<Self, ResponseError> {
        let axes_path = dir.join("axes.txt");
        let text = std::fs::read_to_string(&axes_path).map_err(|e| ResponseError::Axes {
            path: axes_path.clone(),
            line: 0,
            problem: format!("cannot read the file ({e})"),
        })?;
        let axes = parse_axes(&text).map_err(|(line, problem)| ResponseError::Axes {
            path: axes_path.clone(),
            line,
            problem,
        })?;
        let data_path = dir.join("data.npy");
        let array = read_npy(&data_path)?;
        Self::from_table(axes, &array.shape, array.data).map_err(|problem| ResponseError::Shape {
            path: data_path,
            problem,
        })
    }

    /// Builds the response from axes and a `(vertices × samples, 4)` table.
    pub fn from_table(
        axes: [Vec<f64>; 3],
        shape: &[usize],
        values: Vec<f64>,
    ) -> Result<Self, String> {
        let samples = axes.iter().map(Vec::len).product::<usize>();
        if shape.len() != 2 || shape[1] != 4 {
            return Err(format!(
                "the table has shape {shape:?}; it must be (rows, 4)"
            ));
        }
        if samples == 0 || !shape[0].is_multiple_of(samples) {
            return Err(format!(
                "{} rows are not a whole number of vertices × {samples} samples",
                shape[0]
            ));
        }
        let data = values
            .chunks_exact(4)
            .map(|c| [c[0], c[1], c[2], c[3]])
            .collect();
        Ok(Self {
            vertex_count: shape[0] / samples,
            axes,
            data,
        })
    }

    /// Number of strain samples.
    pub fn sample_count(&self) -> usize {
        self.axes.iter().map(Vec::len).product()
    }

    /// The strain `[sx, sa, sy]` of sample `[isx, isa, isy]`.
    pub fn strain_of(&self, index: [usize; 3]) -> [f64; 3] {
        [
            self.axes[0][index[0]],
            self.axes[1][index[1]],
            self.axes[2][index[2]],
        ]
    }

    /// Displacements `(dx, dy, dz, dt)` (m, m, m, rad) of every vertex at grid sample `[isx, isa, isy]`.
    pub fn at_sample(&self, index: [usize; 3]) -> Result<Vec<[f64; 4]>, ResponseError> {
        for k in 0..3 {
            if index[k] >= self.axes[k].len() {
                return Err(ResponseError::Index {
                    what: "sample index",
                    index: index[k],
                    count: self.axes[k].len(),
                });
            }
        }
        let (nx, na) = (self.axes[0].len(), self.axes[1].len());
        let s = self.sample_count();
        let row = index[0] + nx * index[1] + nx * na * index[2];
        Ok((0..self.vertex_count)
            .map(|v| self.data[row + s * v])
            .collect())
    }

    /// Displacements at strain `[sx, sa, sy]`, trilinear between the neighbouring samples; an error names
    /// the axis and range of a strain outside the samples.
    pub fn interpolate(&self, strain: [f64; 3]) -> Result<Vec<[f64; 4]>, ResponseError> {
        let mut cells = [(0usize, 0.0f64); 3];
        for k in 0..3 {
            let ax = &self.axes[k];
            let (min, max) = (ax[0], ax[ax.len() - 1]);
            let tol = 1e-9 * (max - min).abs().max(1.0);
            let value = strain[k];
            if !(value >= min - tol && value <= max + tol) {
                return Err(ResponseError::OutOfRange {
                    axis: AXIS_NAMES[k],
                    value,
                    min,
                    max,
                });
            }
            if ax.len() == 1 {
                cells[k] = (0, 0.0);
                continue;
            }
            let c = ax[1..ax.len() - 1]
                .iter()
                .take_while(|&&a| a <= value)
                .count();
            let w = ((value - ax[c]) / (ax[c + 1] - ax[c])).clamp(0.0, 1.0);
            cells[k] = (c, w);
        }
        let mut out = vec![[0.0; 4]; self.vertex_count];
        for corner in 0..8 {
            let mut index = [0; 3];
            let mut weight = 1.0;
            for k in 0..3 {
                let bit = (corner >> k) & 1;
                let (c, w) = cells[k];
                if self.axes[k].len() == 1 {
                    if bit == 1 {
                        weight = 0.0;
                    }
                    index[k] = 0;
                    continue;
                }
                index[k] = c + bit;
                weight *= if bit == 1 { w } else { 1.0 - w };
            }
            if weight == 0.0 {
                continue;
            }
            for (o, d) in out.iter_mut().zip(self.at_sample(index)?) {
                for j in 0..4 {
                    o[j] += weight * d[j];
                }
            }
        }
        Ok(out)
    }
}

/// Parses `axes.txt`: three lines of increasing numbers. Errors carry (line, problem).
fn parse_axes(text: &str) -> Result<[Vec<f64>; 3], (usize, String)> {
    let mut axes: Vec<Vec<f64>> = Vec::new();
    for (k, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let mut values = Vec::new();
        for token in line.split_whitespace() {
            let v: f64 = token
                .parse()
                .map_err(|_| (k + 1, format!("`{token}` is not a number")))?;
            if !v.is_finite() {
                return Err((k + 1, format!("`{token}` is not finite")));
            }
            values.push(v);
        }
        if values.windows(2).any(|w| w[1] <= w[0]) {
            return Err((k + 1, "the sampled values must increase".into()));
        }
        axes.push(values);
    }
    if axes.len() != 3 {
        return Err((
            0,
            format!(
                "found {} lines of samples; axes.txt needs three (sx, sa, sy)",
                axes.len()
            ),
        ));
    }
    let sy = axes.pop().unwrap_or_default();
    let sa = axes.pop().unwrap_or_default();
    let sx = axes.pop().unwrap_or_default();
    Ok([sx, sa, sy])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::{PATTERNS, shared_yarns_dir};

    #[test]
    fn reads_every_shared_response_and_rest_sample_is_zero() {
        for name in PATTERNS {
            let r = PublishedResponse::read(&shared_yarns_dir().join(name)).unwrap();
            let p =
                crate::PeriodicPattern::read(&shared_yarns_dir().join(name).join("pattern.pyp"))
                    .unwrap();
            assert_eq!(r.vertex_count, p.len(), "{name}");
            assert_eq!(r.sample_count(), 729);
            // sx = sa = sy = 0 is sample (2, 4, 2): zero displacement there (README).
            assert_eq!(r.strain_of([2, 4, 2]), [0.0, 0.0, 0.0]);
            // Positions only: the twist column is not zero at rest (up to ~0.01 rad on stock_9).
            let d = r.at_sample([2, 4, 2]).unwrap();
            let max = d
                .iter()
                .flat_map(|v| &v[..3])
                .fold(0.0f64, |m, v| m.max(v.abs()));
            if name == "basket_9" {
                // The basket table is not zero at rest: its yarn moves by up to 0.14 r (its `*Q` is also
                // 9 % off its rest lengths) — a fact of the published data.
                assert!(
                    max > 0.1 * p.radius && max < 0.2 * p.radius,
                    "{name}: {max}"
                );
            } else {
                assert!(max < 1e-6 * p.radius, "{name}: {max}");
            }
            // A stretched sample does move the yarn.
            let d = r.at_sample([8, 4, 2]).unwrap();
            let max = d.iter().map(|v| v[0].abs()).fold(0.0f64, f64::max);
            assert!(max > 0.01 * p.radius, "{name}: {max}");
        }
    }

    #[test]
    fn interpolation_reproduces_samples_and_is_linear_between() {
        let r = PublishedResponse::read(&shared_yarns_dir().join("stocktiniest_9")).unwrap();
        let at = r.interpolate(r.strain_of([3, 5, 1])).unwrap();
        assert_eq!(at, r.at_sample([3, 5, 1]).unwrap());
        // Halfway between two sx samples with the others on the grid: the mean of the two.
        let a = r.at_sample([3, 5, 1]).unwrap();
        let b = r.at_sample([4, 5, 1]).unwrap();
        let mid = r
            .interpolate([
                (r.axes[0][3] + r.axes[0][4]) / 2.0,
                r.axes[1][5],
                r.axes[2][1],
            ])
            .unwrap();
        for v in 0..r.vertex_count {
            for j in 0..4 {
                assert!((mid[v][j] - 0.5 * (a[v][j] + b[v][j])).abs() < 1e-12);
            }
        }
        // A point inside a cell: trilinear weights sum to one (a constant table stays constant).
        let constant =
            PublishedResponse::from_table(r.axes.clone(), &[729 * 2, 4], vec![0.25; 729 * 2 * 4])
                .unwrap();
        let v = constant.interpolate([0.05, -0.3, 0.7]).unwrap();
        assert!(v.iter().flatten().all(|x| (x - 0.25).abs() < 1e-14));
    }

    #[test]
    fn strain_outside_the_samples_names_axis_and_range() {
        let r = PublishedResponse::read(&shared_yarns_dir().join("stocktiniest_9")).unwrap();
        let e = r.interpolate([0.1, 0.0, 1.5]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "strain sy = 1.5 is outside the sampled range [-0.2, 1]; the published data cannot be interpolated \
             there — choose sy within the range"
        );
        assert!(matches!(
            r.interpolate([0.0, -0.9, 0.0]),
            Err(ResponseError::OutOfRange { axis: "sa", .. })
        ));
        assert!(r.interpolate([f64::NAN, 0.0, 0.0]).is_err());
    }

    #[test]
    fn malformed_axes_are_rejected() {
        assert_eq!(parse_axes("1 2\n3 4\n").unwrap_err().0, 0);
        assert_eq!(parse_axes("1 2\n3 x\n5 6\n").unwrap_err().0, 2);
        assert!(
            parse_axes("1 2\n4 3\n5 6\n")
                .unwrap_err()
                .1
                .contains("increase")
        );
    }
}
