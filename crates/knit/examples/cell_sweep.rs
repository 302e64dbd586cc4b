//! Runs the cell check over the published samples with every strain in a range and prints one JSON line
//! per sample and a summary per pattern.
//!
//! `cargo run -p skintight-knit --example cell_sweep -- [DATA_DIR] [PATTERN…] [--min -0.2] [--max 0.5]
//! [--stride k] [--only sx,sa,sy] [--contact-factor c] [--contact-distance f] [--poisson ν] [--bending-factor f] [--exclusion radii]` (defaults: the shared data beside the repository, all five patterns, [−0.2, 0.5], every
//! sample). `--stride k` keeps every k-th qualifying sample.

use std::path::PathBuf;

use skintight_knit::cell_check::cell_check;
use skintight_knit::newton::NewtonParams;
use skintight_knit::published_response::PublishedResponse;
use skintight_knit::yarn_params::YarnParams;

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    // `--only sx,sa,sy`: a single strain instead of the samples.
    let only: Option<[f64; 3]> = args.iter().position(|a| a == "--only").and_then(|i| {
        let v: Vec<f64> = args
            .get(i + 1)?
            .split(',')
            .filter_map(|t| t.parse().ok())
            .collect();
        args.drain(i..i + 2);
        v.try_into().ok()
    });
    let mut take = |flag: &str, default: f64| -> f64 {
        if let Some(i) = args.iter().position(|a| a == flag) {
            let v = args
                .get(i + 1)
                .and_then(|s| s.parse().ok())
                .unwrap_or(default);
            args.drain(i..(i + 2).min(args.len()));
            v
        } else {
            default
        }
    };
    let (lo, hi) = (take("--min", -0.2), take("--max", 0.5));
    let stride = take("--stride", 1.0).max(1.0) as usize;
    let defaults = YarnParams::default();
    let params = YarnParams {
        contact_factor: take("--contact-factor", defaults.contact_factor),
        contact_distance_factor: take("--contact-distance", defaults.contact_distance_factor),
        poisson_ratio: take("--poisson", defaults.poisson_ratio),
        bending_factor: take("--bending-factor", defaults.bending_factor),
        contact_exclusion_radii: take("--exclusion", defaults.contact_exclusion_radii),
        ..defaults
    };
    let mut dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/yarns");
    if let Some(first) = args.first()
        && PathBuf::from(first).is_dir()
    {
        dir = PathBuf::from(args.remove(0));
    }
    let patterns: Vec<String> = if args.is_empty() {
        ["stock_9", "rib_9", "basket_9", "satin_9", "stocktiniest_9"]
            .iter()
            .map(|s| s.to_string())
            .collect()
    } else {
        args
    };
    let newton = NewtonParams::default();
    for name in patterns {
        let folder = dir.join(&name);
        let response = match PublishedResponse::read(&folder) {
            Ok(r) => r,
            Err(e) => {
                eprintln!("{name}: {e}");
                continue;
            }
        };
        let mut samples = Vec::new();
        for isy in 0..response.axes[2].len() {
            for isa in 0..response.axes[1].len() {
                for isx in 0..response.axes[0].len() {
                    let s = response.strain_of([isx, isa, isy]);
                    if s.iter().all(|v| *v >= lo - 1e-12 && *v <= hi + 1e-12) {
                        samples.push(s);
                    }
                }
            }
        }
        if let Some(s) = only {
            samples = vec![s];
        }
        let mut values = Vec::new();
        let mut values_rest = Vec::new();
        let (mut unconverged, mut seconds, mut iterations) = (0, 0.0, 0);
        for s in samples.iter().step_by(stride) {
            match cell_check(&folder, *s, &params, &newton) {
                Ok(r) => {
                    println!("{}", serde_json::to_string(&r).unwrap_or_default());
                    if !r.converged {
                        unconverged += 1;
                    }
                    seconds += r.seconds;
                    iterations += r.newton_iterations;
                    if let Some(v) = r.normalized_rms {
                        values.push(v);
                    }
                    if let Some(v) = r.normalized_rms_from_own_rest {
                        values_rest.push(v);
                    }
                }
                Err(e) => eprintln!("{name} {s:?}: {e}"),
            }
        }
        values.sort_by(f64::total_cmp);
        let mean = values.iter().sum::<f64>() / values.len().max(1) as f64;
        let median = values.get(values.len() / 2).copied().unwrap_or(f64::NAN);
        let max = values.last().copied().unwrap_or(f64::NAN);
        values_rest.sort_by(f64::total_cmp);
        let mean_rest = values_rest.iter().sum::<f64>() / values_rest.len().max(1) as f64;
        let median_rest = values_rest
            .get(values_rest.len() / 2)
            .copied()
            .unwrap_or(f64::NAN);
        eprintln!(
            "SUMMARY-REST {name}: normalized_rms_from_own_rest mean {mean_rest:.3} median {median_rest:.3}"
        );
        eprintln!(
            "SUMMARY {name}: samples {} (of {} in range), normalized_rms mean {mean:.3} median {median:.3} max {max:.3}, \
             unconverged {unconverged}, Newton steps {iterations}, solve time {seconds:.1} s",
            values.len(),
            samples.len()
        );
    }
}
