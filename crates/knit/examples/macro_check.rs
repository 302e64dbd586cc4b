//! The macro check of issue 45: the periodic cell's energy per reference area along `sx`, `sa` and `sy`
//! against HYLC's fitted sheet energy `ψ` (`skintight_knit::fitted_sheet_energy`), after one scale factor.
//!
//! `cargo run -p skintight-knit --profile test --example macro_check -- PATTERN_DIR MATERIAL_JSON [--kc KC]
//! [--kernel smooth|kaldor]` (materials: `tools/fetch_hylc_materials.sh`). The cell uses the constants of
//! MADYPG's generator ([`YarnParams::madypg_generator`]) with contact stiffness `KC` (J/m², default 100)
//! and the pattern's radius. For each sample `s` of the pattern's axes (`axes.txt`) with the other two
//! in-plane strains zero it solves the cell, takes `W(s) = (E(s) − E(0)) / (px py)` (J/m²; `E` the cell's
//! energy at equilibrium), and compares with `ψ(s) − ψ(0)`. The scale factor `c` is the least-squares fit
//! of `c W` to `ψ` over the tension samples of `sx` and `sy` (`s > 0`); each line reports
//! `(c W − ψ) / ψ`.

use std::path::PathBuf;

use skintight_knit::contact::ContactKernel;
use skintight_knit::fitted_sheet_energy::FittedSheetEnergy;
use skintight_knit::newton::{NewtonParams, minimize};
use skintight_knit::periodic_cell::{CellState, PeriodicCell};
use skintight_knit::published_response::PublishedResponse;
use skintight_knit::pyp::PeriodicPattern;
use skintight_knit::yarn_params::YarnParams;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let mut value = |flag: &str| -> Option<String> {
        let i = args.iter().position(|a| a == flag)?;
        let v = args.get(i + 1).cloned();
        args.drain(i..(i + 2).min(args.len()));
        v
    };
    let kc: f64 = value("--kc")
        .map(|v| v.parse())
        .transpose()?
        .unwrap_or(100.0);
    let kernel = match value("--kernel").as_deref() {
        Some("smooth") => ContactKernel::Smooth,
        _ => ContactKernel::Kaldor,
    };
    let [dir, material] = <[String; 2]>::try_from(args).map_err(|a| {
        format!("usage: macro_check PATTERN_DIR MATERIAL_JSON [--kc KC], got {a:?}")
    })?;
    let dir = PathBuf::from(dir);
    let pattern = PeriodicPattern::read(&dir.join("pattern.pyp"))?;
    let axes = PublishedResponse::read(&dir)?.axes;
    let psi = FittedSheetEnergy::read(&PathBuf::from(&material))?;
    let params = YarnParams {
        contact_kernel: kernel,
        ..YarnParams::madypg_generator(pattern.radius, kc)
    };
    let area = pattern.period[0] * pattern.period[1];
    let newton = NewtonParams::default();
    let energy = |strain: [f64; 3]| -> Result<(f64, bool), Box<dyn std::error::Error>> {
        let mut cell = PeriodicCell::new(&pattern, &params, strain)?;
        let mut x = cell.affine_state().to_vector();
        let report = minimize(&mut cell, &mut x, &newton)?;
        Ok((
            cell.evaluate(&CellState::from_vector(&x), false).energy,
            report.converged,
        ))
    };
    let (rest, _) = energy([0.0; 3])?;
    // (axis, s, W, ψ, converged)
    let mut rows = Vec::new();
    for k in 0..3 {
        for &s in &axes[k] {
            if s == 0.0 {
                continue;
            }
            let mut strain = [0.0; 3];
            strain[k] = s;
            let (e, converged) = energy(strain)?;
            rows.push((k, s, (e - rest) / area, psi.along_axis(k, s), converged));
        }
    }
    let fit: Vec<_> = rows.iter().filter(|r| r.0 != 1 && r.1 > 0.0).collect();
    let c = fit.iter().map(|r| r.2 * r.3).sum::<f64>() / fit.iter().map(|r| r.2 * r.2).sum::<f64>();
    let name = dir
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    println!(
        "{name}: kc {kc} J/m², kernel {kernel:?}, scale factor c = {c:.4e} (ψ units per J/m²)"
    );
    println!("axis | strain | W (J/m²) | psi | c W | (c W − psi)/psi | converged");
    let mut worst = [0.0f64; 3];
    for (k, s, w, p, conv) in &rows {
        let rel = (c * w - p) / p;
        if *s > 0.0 {
            worst[*k] = worst[*k].max(rel.abs());
        }
        println!(
            "{} | {s:.3} | {w:.4e} | {p:.4} | {:.4} | {rel:+.3} | {conv}",
            ["sx", "sa", "sy"][*k],
            c * w
        );
    }
    // The curves' normalized RMS over the tension samples of each axis: ‖c W − ψ‖ / ‖ψ‖.
    let curve = |k: usize| {
        let (num, den) = rows
            .iter()
            .filter(|r| r.0 == k && r.1 > 0.0)
            .fold((0.0, 0.0), |(a, b), r| {
                (a + (c * r.2 - r.3).powi(2), b + r.3 * r.3)
            });
        (num / den).sqrt()
    };
    println!(
        "SUMMARY {name}: c = {c:.4e}; largest |relative error| over s > 0: sx {:.3}, sa {:.3}, sy {:.3}; \
         curve normalized RMS over s > 0: sx {:.3}, sa {:.3}, sy {:.3}",
        worst[0],
        worst[1],
        worst[2],
        curve(0),
        curve(1),
        curve(2)
    );
    Ok(())
}
