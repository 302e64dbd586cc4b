//! Remeshing a designed garment (`garment_remesh`): the calf sleeve of `examples/calf_sleeve.json` on the
//! regular body (two panels, two seams, free hems), its patterns distorted the way a design distorts them
//! (stretched along the leg by up to 30 % and sheared), at two cloth edge lengths. Resampling, constrained
//! Delaunay refinement, point location and sewing; the design's re-embedding and new biharmonic
//! coordinates come on top (`remesh_seconds` of a design's `result.json`).
//!
//! Run: `cargo bench -p skintight-garment --bench garment_remesh`

use criterion::{Criterion, criterion_group, criterion_main};
use skintight_garment::garment_remesh::garment_remesh;
use skintight_garment::pattern_remesh::RemeshParams;
use skintight_geometry::{Vec2, Vec3};
use std::hint::black_box;

mod calf_sleeve;

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("garment_remesh");
    group.sample_size(10);
    for edge_length in [0.02, 0.01] {
        let g = calf_sleeve::garment_at(edge_length);
        let patterns: Vec<Vec<Vec2>> = g
            .panels
            .iter()
            .map(|p| {
                let lo = p.pattern.iter().map(|q| q.y).fold(f64::INFINITY, f64::min);
                let hi = p
                    .pattern
                    .iter()
                    .map(|q| q.y)
                    .fold(f64::NEG_INFINITY, f64::max);
                p.pattern
                    .iter()
                    .map(|q| {
                        let t = (q.y - lo) / (hi - lo).max(1e-12);
                        Vec2::new(q.x + 0.2 * (q.y - lo), q.y * (1.0 + 0.3 * t))
                    })
                    .collect()
            })
            .collect();
        let positions: Vec<Vec3> = g.positions.clone();
        let params = RemeshParams {
            target_edge_length: 0.9 * edge_length,
            ..Default::default()
        };
        let faces = g.num_faces();
        group.bench_function(format!("calf_sleeve_{faces}_triangles"), |b| {
            b.iter(|| {
                black_box(garment_remesh(&g, &positions, &patterns, &params).expect("remesh"))
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
