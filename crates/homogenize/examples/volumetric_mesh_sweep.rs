//! The volumetric mesh of the shared stockinette and rib patterns tiled 8 × 8, for several voxel sizes: the
//! paper's counts (yarn DOFs, mesh DOFs, elements, their ratio; its Table 1) and the build time, as a
//! Markdown table for docs/BENCHMARKS.md ("Volumetric mesh (issue 43)").
//!
//! `cargo run -p skintight-homogenize --example volumetric_mesh_sweep [CELLS]`

use std::path::PathBuf;
use std::time::Instant;

use skintight_homogenize::volumetric_mesh::{RestYarns, VolumetricMesh, VolumetricMeshParams};
use skintight_knit::PeriodicPattern;
use skintight_knit::tile::tile;
use skintight_knit::yarn_params::YarnParams;

fn main() {
    let cells: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(8);
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/yarns");
    println!(
        "| pattern | voxel h (mm) | h / r | dilation | yarn DOFs n^Y | mesh DOFs n^V | elements | voxels | n^V / n^Y | components | estimate voxels ≤ | build (ms, best of 3) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|");
    for name in ["stock_9", "rib_9"] {
        let pattern = match PeriodicPattern::read(&dir.join(name).join("pattern.pyp")) {
            Ok(p) => p,
            Err(e) => {
                eprintln!("{e}");
                std::process::exit(1);
            }
        };
        let patch = tile(&pattern, cells, cells).expect("a positive cell count");
        let yarns =
            RestYarns::from_patch(&patch, YarnParams::default().linear_density(patch.radius));
        let r = patch.radius;
        for (factor, dilation) in [
            (1.0, 0),
            (1.5, 0),
            (2.0, 0),
            (2.5, 0),
            (3.0, 0),
            (4.0, 0),
            (2.0, 1),
        ] {
            let params = VolumetricMeshParams {
                voxel_m: Some(factor * r),
                dilation_layers: dilation,
                ..VolumetricMeshParams::default()
            };
            let estimate = VolumetricMesh::estimate(&yarns, &params).expect("a valid patch");
            let mut best = f64::INFINITY;
            let mut mesh = None;
            for _ in 0..3 {
                let start = Instant::now();
                mesh = Some(VolumetricMesh::build(&yarns, &params).expect("a valid patch"));
                best = best.min(start.elapsed().as_secs_f64());
            }
            let report = mesh.expect("built").report(&yarns, &params);
            println!(
                "| {name} {cells}×{cells} | {:.2} | {factor} | {dilation} | {} | {} | {} | {} | {:.3} | {} | {} | {:.0} |",
                1e3 * report.voxel_m,
                report.yarn_dofs,
                report.mesh_dofs,
                report.elements,
                report.voxels,
                report.ratio,
                report.components,
                estimate.voxels,
                1e3 * best,
            );
        }
    }
}
