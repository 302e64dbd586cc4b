//! Makes a raw scan from a sample body (subdivided, noised, holed, islands, non-manifold spots, mm, +z up),
//! prepares it and prints the figures: `cargo run --release -p skintight-geometry --features test-support
//! --example prepare_raw_scan -- regular_12k.obj [OUT.obj]`.

use std::time::Instant;

use skintight_geometry::mesh::io::{MeshFormat, read_mesh, write_mesh};
use skintight_geometry::scan::raw_scan::{RawScanParams, raw_scan_ply};
use skintight_geometry::scan::surface_deviation::{
    ClosestPointGrid, deviation_of_points, vertex_areas,
};
use skintight_geometry::scan::{DEFAULT_MAX_FACES, PrepareParams, prepare_scan, read_scan_bytes};
use skintight_geometry::test_meshes;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let name = args.get(1).map(String::as_str).unwrap_or("regular_12k.obj");
    let clean = read_mesh(&test_meshes::body(name)).expect("a sample body");
    let smooth = std::env::var("SMOOTH").map(|v| v != "0").unwrap_or(true);
    let bytes = raw_scan_ply(
        &clean,
        &RawScanParams {
            smooth,
            ..Default::default()
        },
    );
    let target_faces = std::env::var("TARGET")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(skintight_geometry::scan::DEFAULT_TARGET_FACES);
    let t = Instant::now();
    let scan = read_scan_bytes(&bytes, MeshFormat::Ply, DEFAULT_MAX_FACES).expect("readable");
    let read_s = t.elapsed().as_secs_f64();
    let (body, report) = match prepare_scan(
        &scan,
        &PrepareParams {
            target_faces,
            ..Default::default()
        },
    ) {
        Ok(x) => x,
        Err(e) => {
            eprintln!("{name}: {e}");
            std::process::exit(1);
        }
    };
    let total_s = t.elapsed().as_secs_f64();
    let clean_grid = ClosestPointGrid::new(&clean.positions, &clean.faces, 0.02);
    let wc = vertex_areas(&clean.positions, &clean.faces);
    let result_grid = ClosestPointGrid::new(&body.positions, &body.faces, 0.02);
    let wb = vertex_areas(&body.positions, &body.faces);
    let a = deviation_of_points(&body.positions, |v| wb[v], &clean_grid);
    let b = deviation_of_points(&clean.positions, |v| wc[v], &result_grid);
    println!(
        "{name}: scan {} faces ({} bytes PLY) -> {} faces; read {read_s:.2} s, total {total_s:.2} s; \
         vs scan: mean {:.2} mm, Hausdorff {:.1} mm; vs clean: mean {:.2} / {:.2} mm, max {:.1} mm",
        scan.num_faces(),
        bytes.len(),
        body.num_faces(),
        report.mean_deviation_mm,
        report.hausdorff_mm,
        1e3 * a.mean,
        1e3 * b.mean,
        1e3 * a.max.max(b.max)
    );
    if let Some(out) = args.get(2) {
        write_mesh(std::path::Path::new(out), &body, &Default::default()).expect("writable");
        let mut seen = Vec::new();
        let mut stamp = 0;
        let mut worst: Vec<(f64, usize)> = body
            .positions
            .iter()
            .enumerate()
            .map(|(i, p)| {
                (
                    clean_grid
                        .closest(p, &mut seen, &mut stamp)
                        .unwrap()
                        .distance,
                    i,
                )
            })
            .collect();
        worst.sort_by(|x, y| y.0.total_cmp(&x.0));
        let mut back: Vec<(f64, usize)> = clean
            .positions
            .iter()
            .enumerate()
            .map(|(i, p)| {
                (
                    result_grid
                        .closest(p, &mut seen, &mut stamp)
                        .unwrap()
                        .distance,
                    i,
                )
            })
            .collect();
        back.sort_by(|x, y| y.0.total_cmp(&x.0));
        for (d, i) in back.iter().take(5) {
            eprintln!(
                "  clean {:.1} mm at {:?}",
                d * 1e3,
                clean.positions[*i].as_slice()
            );
        }
        for (d, i) in worst.iter().take(8) {
            eprintln!("  {:.1} mm at {:?}", d * 1e3, body.positions[*i].as_slice());
        }
        eprintln!("{}", serde_json::to_string(&report).unwrap());
    }
}
