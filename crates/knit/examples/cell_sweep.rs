//! Runs the cell check over the published samples with every strain in a range and prints one JSON line
//! per sample and a summary per pattern.
//!
//! `cargo run -p skintight-knit --example cell_sweep -- [DATA_DIR] [PATTERN…] [--min -0.2] [--max 0.5]
//! [--stride k] [--only sx,sa,sy] [--contact-factor c] [--contact-distance f] [--poisson ν] [--bending-factor f] [--exclusion radii]
//! [--kernel smooth|kaldor] [--generator KC] [--all] [--tension] [--train-every k]` (defaults: the shared data beside the repository, all five patterns, [−0.2, 0.5], every
//! sample). `--stride k` keeps every k-th qualifying sample, from the `--offset o`-th (default 0). `--generator KC` uses the constants of
//! MADYPG's data generator ([`YarnParams::madypg_generator`]) with contact stiffness `KC` (J/m²) and the
//! pattern's radius (the other parameter flags, when given, override those constants). `--all` drops the `[min, max]` range,
//! `--tension` keeps only `sx, sy ≥ 0`. The summary splits tension samples (`sx, sy ≥ 0`) from the rest,
//! and with `--train-every k` every k-th kept sample (index 0, k, 2k, …) from the held-out others.

use std::path::PathBuf;

use skintight_knit::cell_check::cell_check;
use skintight_knit::contact::ContactKernel;
use skintight_knit::newton::NewtonParams;
use skintight_knit::published_response::PublishedResponse;
use skintight_knit::pyp::PeriodicPattern;
use skintight_knit::yarn_params::YarnParams;

/// One sample: normalized RMS, slide-aligned, tension, training, difference² and published² (radii²).
type Row = (f64, f64, bool, bool, f64, f64);

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
    let mut flag = |name: &str| -> bool {
        if let Some(i) = args.iter().position(|a| a == name) {
            args.remove(i);
            true
        } else {
            false
        }
    };
    let (all, tension_only) = (flag("--all"), flag("--tension"));
    let kernel = if let Some(i) = args.iter().position(|a| a == "--kernel") {
        let k = args.get(i + 1).cloned();
        args.drain(i..(i + 2).min(args.len()));
        k
    } else {
        None
    };
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
    let generator_kc = take("--generator", f64::NAN);
    let train_every = take("--train-every", 0.0) as usize;
    let (lo, hi) = (take("--min", -0.2), take("--max", 0.5));
    let stride = take("--stride", 1.0).max(1.0) as usize;
    let offset = take("--offset", 0.0).max(0.0) as usize;
    // Flags given override the defaults, or with `--generator` the generator's constants.
    let overrides = [
        take("--contact-factor", f64::NAN),
        take("--contact-distance", f64::NAN),
        take("--poisson", f64::NAN),
        take("--bending-factor", f64::NAN),
        take("--exclusion", f64::NAN),
    ];
    let smooth = kernel.as_deref() == Some("smooth");
    let kaldor = kernel.as_deref() == Some("kaldor");
    let apply = |base: YarnParams| {
        let pick = |v: f64, d: f64| if v.is_nan() { d } else { v };
        YarnParams {
            contact_factor: pick(overrides[0], base.contact_factor),
            contact_distance_factor: pick(overrides[1], base.contact_distance_factor),
            poisson_ratio: pick(overrides[2], base.poisson_ratio),
            bending_factor: pick(overrides[3], base.bending_factor),
            contact_exclusion_radii: pick(overrides[4], base.contact_exclusion_radii),
            contact_kernel: if kaldor {
                ContactKernel::Kaldor
            } else if smooth {
                ContactKernel::Smooth
            } else {
                base.contact_kernel
            },
            ..base
        }
    };
    let params = apply(YarnParams::default());
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
                    let in_range = all || s.iter().all(|v| *v >= lo - 1e-12 && *v <= hi + 1e-12);
                    let tension = s[0] >= 0.0 && s[2] >= 0.0;
                    if in_range && (tension || !tension_only) {
                        samples.push(s);
                    }
                }
            }
        }
        if let Some(s) = only {
            samples = vec![s];
        }
        let params = if generator_kc.is_finite() {
            match PeriodicPattern::read(&folder.join("pattern.pyp")) {
                Ok(p) => apply(YarnParams::madypg_generator(p.radius, generator_kc)),
                Err(e) => {
                    eprintln!("{name}: {e}");
                    continue;
                }
            }
        } else {
            params
        };
        let mut rows: Vec<Row> = Vec::new();
        let (mut unconverged, mut seconds, mut iterations) = (0, 0.0, 0);
        for (k, s) in samples.iter().skip(offset).step_by(stride).enumerate() {
            match cell_check(&folder, *s, &params, &newton) {
                Ok(r) => {
                    println!("{}", serde_json::to_string(&r).unwrap_or_default());
                    if !r.converged {
                        unconverged += 1;
                    }
                    seconds += r.seconds;
                    iterations += r.newton_iterations;
                    if let (Some(v), Some(vr), Some(d), Some(p)) = (
                        r.normalized_rms,
                        r.normalized_rms_slide_aligned,
                        r.rms_difference_radii,
                        r.published_rms_radii,
                    ) {
                        let train = train_every > 0 && k % train_every == 0;
                        rows.push((v, vr, s[0] >= 0.0 && s[2] >= 0.0, train, d * d, p * p));
                    }
                }
                Err(e) => eprintln!("{name} {s:?}: {e}"),
            }
        }
        let summary = |label: &str, keep: &dyn Fn(&Row) -> bool| {
            let chosen: Vec<_> = rows.iter().filter(|r| keep(r)).collect();
            if chosen.is_empty() {
                return;
            }
            let mut v: Vec<f64> = chosen.iter().map(|r| r.0).collect();
            v.sort_by(f64::total_cmp);
            let n = v.len() as f64;
            let mean = v.iter().sum::<f64>() / n;
            let mean_slide = chosen.iter().map(|r| r.1).sum::<f64>() / n;
            let mut vs: Vec<f64> = chosen.iter().map(|r| r.1).collect();
            vs.sort_by(f64::total_cmp);
            let pooled = (chosen.iter().map(|r| r.4).sum::<f64>()
                / chosen.iter().map(|r| r.5).sum::<f64>())
            .sqrt();
            eprintln!(
                "SUMMARY {name} {label}: samples {}, normalized_rms mean {mean:.3} median {:.3} max {:.3}, \
                 pooled {pooled:.3}; slide-aligned mean {mean_slide:.3} median {:.3}",
                v.len(),
                v[v.len() / 2],
                v[v.len() - 1],
                vs[vs.len() / 2]
            );
        };
        summary("all", &|_| true);
        summary("tension", &|r| r.2);
        summary("compression", &|r| !r.2);
        if train_every > 0 {
            summary("train", &|r| r.3);
            summary("held-out", &|r| !r.3);
            summary("held-out tension", &|r| !r.3 && r.2);
        }
        eprintln!(
            "SUMMARY {name}: {} samples of {} kept, unconverged {unconverged}, Newton steps {iterations}, \
             solve time {seconds:.1} s",
            rows.len(),
            samples.len()
        );
    }
}
