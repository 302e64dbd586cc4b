//! Measured uniaxial force–extension curves of knitted fabrics: the reader of the small CSV files in
//! `crates/knit/data/stitch_by_stitch/` (Singal et al., "Programming mechanics in knitted materials,
//! stitch by stitch", Nature Communications 15, 2622 (2024); github.com/sabetta/stitch-by-stitch, MIT;
//! written from the published HDF5 files by `tools/stitch_by_stitch_to_csv.py`, whose docstring and the
//! folder's README say how), and the comparison of a simulated curve with a measured one.
//!
//! A file: `#` comment lines, two of which give the sample — `# fabric_width_mm W` (the fabric's width at
//! the clamp) and `# clamp_distance_mm L0` (the clamp-to-clamp distance at rest) — then the header
//! `extension_mm,force_n,force_min_n,force_max_n,videos` and one row per extension bin: the grip
//! displacement (mm), the mean force over the repeated pulls (N), the least and greatest per-pull mean (N)
//! and how many pulls had data in the bin.
//!
//! **Comparison** ([`compare_curves`]): the simulated force is interpolated linearly in the extension at
//! each measured bin; the relative error is `(F_sim − F_meas)/F_meas` at bins where `F_meas ≥ f_min` (the
//! first bins hold a few tenths of a newton of gauge noise, where a relative error means nothing).
//! [`least_squares_scale`] is the factor `c` minimising `Σ (c F_sim − F_meas)²` over the same bins:
//! `c = Σ F_sim F_meas / Σ F_sim²` — the calibration of a model whose forces are proportional to one
//! constant (the yarn-level model's are to Young's modulus when every other stiffness is a multiple of it).
//!
//! Units: SI in the API (m, N); the files are in mm and N.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

/// A measured loading curve of one sample.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MeasuredStretch {
    /// The file it was read from.
    pub source: PathBuf,
    /// Fabric width at the clamp (m).
    pub fabric_width: f64,
    /// Clamp-to-clamp distance at rest (m).
    pub clamp_distance: f64,
    /// Grip displacement of each bin's centre (m), increasing.
    pub extension: Vec<f64>,
    /// Mean force of each bin (N).
    pub force: Vec<f64>,
    /// Least per-pull mean force of each bin (N).
    pub force_min: Vec<f64>,
    /// Greatest per-pull mean force of each bin (N).
    pub force_max: Vec<f64>,
}

/// A measured curve that cannot be read: the file and what is wrong.
#[derive(Clone, Debug, thiserror::Error, PartialEq)]
#[error("{path}: {message}")]
pub struct MeasuredStretchError {
    /// The file.
    pub path: String,
    /// What is wrong and how to fix it.
    pub message: String,
}

/// The folder of the vendored curves in this crate's source tree.
pub fn vendored_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data/stitch_by_stitch")
}

impl MeasuredStretch {
    /// Reads a curve file.
    pub fn read(path: &Path) -> Result<Self, MeasuredStretchError> {
        let text = std::fs::read_to_string(path).map_err(|e| MeasuredStretchError {
            path: path.display().to_string(),
            message: format!(
                "cannot read it ({e}); the curves are in crates/knit/data/stitch_by_stitch"
            ),
        })?;
        Self::parse(&text, path)
    }

    /// Parses curve text; `path` only names the source in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Self, MeasuredStretchError> {
        let err = |message: String| MeasuredStretchError {
            path: path.display().to_string(),
            message,
        };
        let mut width = None;
        let mut clamp = None;
        let mut header = false;
        let mut out = Self {
            source: path.to_path_buf(),
            fabric_width: 0.0,
            clamp_distance: 0.0,
            extension: Vec::new(),
            force: Vec::new(),
            force_min: Vec::new(),
            force_max: Vec::new(),
        };
        for (i, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() {
                continue;
            }
            if let Some(c) = line.strip_prefix('#') {
                let mut words = c.split_whitespace();
                let key = words.next();
                let value = words.next().map(str::parse::<f64>);
                let slot = match key {
                    Some("fabric_width_mm") => &mut width,
                    Some("clamp_distance_mm") => &mut clamp,
                    _ => continue,
                };
                match value {
                    Some(Ok(v)) if v.is_finite() && v > 0.0 => *slot = Some(v * 1e-3),
                    _ => {
                        return Err(err(format!(
                            "line {}: `{line}` needs one positive number (mm)",
                            i + 1
                        )));
                    }
                }
                continue;
            }
            if !header {
                if line != "extension_mm,force_n,force_min_n,force_max_n,videos" {
                    return Err(err(format!(
                        "line {}: expected the header `extension_mm,force_n,force_min_n,force_max_n,videos`",
                        i + 1
                    )));
                }
                header = true;
                continue;
            }
            let v: Vec<f64> = line
                .split(',')
                .map(|t| t.trim().parse::<f64>())
                .collect::<Result<_, _>>()
                .map_err(|_| err(format!("line {}: `{line}` is not 5 numbers", i + 1)))?;
            if v.len() != 5 || v.iter().any(|x| !x.is_finite()) {
                return Err(err(format!(
                    "line {}: `{line}` is not 5 finite numbers",
                    i + 1
                )));
            }
            if out.extension.last().is_some_and(|&e| v[0] * 1e-3 <= e) {
                return Err(err(format!(
                    "line {}: extension {} mm does not increase",
                    i + 1,
                    v[0]
                )));
            }
            out.extension.push(v[0] * 1e-3);
            out.force.push(v[1]);
            out.force_min.push(v[2]);
            out.force_max.push(v[3]);
        }
        out.fabric_width = width.ok_or_else(|| err("no `# fabric_width_mm` line".into()))?;
        out.clamp_distance = clamp.ok_or_else(|| err("no `# clamp_distance_mm` line".into()))?;
        if out.extension.len() < 2 {
            return Err(err("fewer than 2 rows of data".into()));
        }
        Ok(out)
    }

    /// The largest extension measured (m).
    pub fn max_extension(&self) -> f64 {
        *self.extension.last().unwrap_or(&0.0)
    }
}

/// `y(x)` of the polyline `(xs, ys)` (xs increasing), linear between points; `None` outside `[xs₀, xsₙ]`.
pub fn interpolate(xs: &[f64], ys: &[f64], x: f64) -> Option<f64> {
    if xs.len() < 2 || xs.len() != ys.len() || !(x >= xs[0] && x <= xs[xs.len() - 1]) {
        return None;
    }
    let k = xs.partition_point(|&v| v < x).clamp(1, xs.len() - 1);
    let (x0, x1) = (xs[k - 1], xs[k]);
    let t = if x1 > x0 { (x - x0) / (x1 - x0) } else { 0.0 };
    Some(ys[k - 1] + t * (ys[k] - ys[k - 1]))
}

/// One measured bin against the simulation.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BinComparison {
    /// Extension (m).
    pub extension_m: f64,
    /// Measured force (N).
    pub measured_n: f64,
    /// Simulated force (N), interpolated.
    pub simulated_n: f64,
    /// `(simulated − measured)/measured` (dimensionless).
    pub relative_error: f64,
}

/// How a simulated curve agrees with a measured one ([`compare_curves`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CurveComparison {
    /// The least measured force compared (N).
    pub min_force_n: f64,
    /// The compared bins (measured force ≥ `min_force_n`, inside the simulated range).
    pub bins: Vec<BinComparison>,
    /// Mean of `|relative_error|` over the bins.
    pub mean_abs_relative_error: f64,
    /// Largest `|relative_error|`.
    pub max_abs_relative_error: f64,
    /// Fraction of the bins with `|relative_error| ≤ 0.25`.
    pub fraction_within_25_percent: f64,
    /// Measured bins at or above `min_force_n` beyond the simulated extension (not compared).
    pub bins_beyond_simulation: usize,
}

/// Compares the simulated curve `(extension_m, force_n)` (extension increasing) with `measured` at the
/// measured bins with force ≥ `min_force_n` (N).
pub fn compare_curves(
    measured: &MeasuredStretch,
    extension_m: &[f64],
    force_n: &[f64],
    min_force_n: f64,
) -> CurveComparison {
    let mut bins = Vec::new();
    let mut beyond = 0;
    for (&e, &f) in measured.extension.iter().zip(&measured.force) {
        if f < min_force_n {
            continue;
        }
        match interpolate(extension_m, force_n, e) {
            Some(s) => bins.push(BinComparison {
                extension_m: e,
                measured_n: f,
                simulated_n: s,
                relative_error: (s - f) / f,
            }),
            None => beyond += 1,
        }
    }
    let n = bins.len().max(1) as f64;
    let abs: Vec<f64> = bins.iter().map(|b| b.relative_error.abs()).collect();
    CurveComparison {
        min_force_n,
        mean_abs_relative_error: abs.iter().sum::<f64>() / n,
        max_abs_relative_error: abs.iter().cloned().fold(0.0, f64::max),
        fraction_within_25_percent: abs.iter().filter(|&&a| a <= 0.25).count() as f64 / n,
        bins,
        bins_beyond_simulation: beyond,
    }
}

/// The factor `c` minimising `Σ (c F_sim − F_meas)²` over the compared bins of [`compare_curves`]
/// (`None` when no bin is compared or the simulated forces there are all zero).
pub fn least_squares_scale(comparison: &CurveComparison) -> Option<f64> {
    let (num, den) = comparison.bins.iter().fold((0.0, 0.0), |(n, d), b| {
        (
            n + b.simulated_n * b.measured_n,
            d + b.simulated_n * b.simulated_n,
        )
    });
    (den > 0.0 && num.is_finite()).then(|| num / den)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(rows: &str) -> String {
        format!(
            "# a comment\n# fabric_width_mm 50\n# clamp_distance_mm 20\n\
             extension_mm,force_n,force_min_n,force_max_n,videos\n{rows}"
        )
    }

    #[test]
    fn the_vendored_curves_read_with_their_geometry() {
        let expect = [
            ("acrylic_stockinette_x.csv", 66.555, 32.204),
            ("acrylic_stockinette_y.csv", 95.865, 22.468),
            ("acrylic_rib_x.csv", 103.061, 28.108),
            ("acrylic_rib_y.csv", 84.381, 38.480),
        ];
        for (file, w, l0) in expect {
            let m = MeasuredStretch::read(&vendored_dir().join(file)).unwrap();
            assert!((m.fabric_width - w * 1e-3).abs() < 1e-6, "{file}");
            assert!((m.clamp_distance - l0 * 1e-3).abs() < 1e-6, "{file}");
            assert_eq!(m.extension.len(), 24, "{file}");
            // a loading curve: the force grows to the gauge's ~30 N limit
            assert!(
                m.force[23] > 20.0 && m.force[23] < 30.0,
                "{file}: {}",
                m.force[23]
            );
            assert!(m.force[0] < 1.0, "{file}");
            for k in 0..24 {
                assert!(m.force_min[k] <= m.force[k] && m.force[k] <= m.force_max[k]);
            }
        }
    }

    #[test]
    fn bad_curve_files_name_the_problem() {
        let p = Path::new("c.csv");
        let e = MeasuredStretch::parse(&sample("1,2,3\n"), p).unwrap_err();
        assert!(e.message.contains("not 5"), "{e}");
        let e = MeasuredStretch::parse(&sample("2,1,1,1,4\n1,2,2,2,4\n"), p).unwrap_err();
        assert!(e.message.contains("does not increase"), "{e}");
        let e = MeasuredStretch::parse("extension_mm,force_n,force_min_n,force_max_n,videos\n", p)
            .unwrap_err();
        assert!(e.message.contains("fabric_width_mm"), "{e}");
        let e = MeasuredStretch::parse("# fabric_width_mm -3\n", p).unwrap_err();
        assert!(e.message.contains("positive"), "{e}");
        let e = MeasuredStretch::parse(&sample("1,1,1,1,4\n"), p).unwrap_err();
        assert!(e.message.contains("fewer than 2"), "{e}");
        let e = MeasuredStretch::read(Path::new("/nonexistent/c.csv")).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/c.csv"), "{e}");
    }

    #[test]
    fn comparison_interpolates_and_the_scale_recovers_a_factor() {
        let m = MeasuredStretch::parse(
            &sample("1,0.2,0.2,0.2,4\n2,2,2,2,4\n3,4,4,4,4\n4,6,6,6,4\n5,9,9,9,4\n"),
            Path::new("c.csv"),
        )
        .unwrap();
        // simulated: half the measured force, on a grid that stops at 4.5 mm
        let ext = [0.0, 1e-3, 2e-3, 3e-3, 4e-3, 4.5e-3];
        let f = [0.0, 0.1, 1.0, 2.0, 3.0, 3.5];
        let c = compare_curves(&m, &ext, &f, 1.0);
        assert_eq!(c.bins.len(), 3);
        assert_eq!(c.bins_beyond_simulation, 1);
        assert!((c.bins[0].simulated_n - 1.0).abs() < 1e-12);
        assert!((c.bins[0].relative_error + 0.5).abs() < 1e-12);
        let scale = least_squares_scale(&c).unwrap();
        assert!((scale - 2.0).abs() < 1e-12, "{scale}");
        assert!((c.mean_abs_relative_error - 0.5).abs() < 1e-12);
        assert_eq!(c.fraction_within_25_percent, 0.0);
        assert_eq!(interpolate(&ext, &f, 5e-3), None);
        assert_eq!(interpolate(&ext, &f, 0.0), Some(0.0));
        assert_eq!(interpolate(&ext, &f, 4.5e-3), Some(3.5));
        assert!((interpolate(&ext, &f, 4.25e-3).unwrap() - 3.25).abs() < 1e-12);
    }
}
