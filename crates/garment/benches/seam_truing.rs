//! Seam truing (`seam_truing::true_seams`): the calf sleeve on the regular body, at two cloth edge lengths,
//! its two seams trued from the flattening's mismatch to 1e-7 m — one sparse Cholesky factorization of the
//! patterns' Laplacian, one triangular solve pair per seam edge pair and Newton step, a dense Cholesky of
//! the Schur complement.
//!
//! Run: `cargo bench -p skintight-garment --bench seam_truing`

use criterion::{Criterion, criterion_group, criterion_main};
use skintight_garment::seam_truing::{SeamTruingParams, true_seams};
use std::hint::black_box;

mod calf_sleeve;

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("seam_truing");
    group.sample_size(10);
    for edge_length in [0.02, 0.01] {
        let g = calf_sleeve::garment_at(edge_length);
        let report = true_seams(&mut g.clone(), &SeamTruingParams::default()).expect("trued");
        eprintln!("edge length {edge_length} m: {report:?}");
        group.bench_function(format!("calf_sleeve_{edge_length}"), |b| {
            b.iter(|| {
                let mut g = g.clone();
                black_box(true_seams(&mut g, &SeamTruingParams::default()).expect("trued"))
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
