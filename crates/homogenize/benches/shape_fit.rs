//! Shape fitting (issue 43, the knitwear paper Sec. 5) on a synthetic block of 14 × 12 × 10 voxels
//! (10,080 tetrahedra) threaded by straight yarns: the once-per-mesh setup (segment clipping, the Eq. 5
//! plan, assembly, analysis and factorization of the Y2V matrix) and the per-frame work (the Eq. 5
//! targets, the Eq. 6 solve, and both). Run: `cargo bench -p skintight-homogenize --bench shape_fit`.

use criterion::{Criterion, criterion_group, criterion_main};
use skintight_homogenize::shape_fit::{ShapeFit, ShapeFitParams};
use skintight_homogenize::straight_yarn_block::straight_yarn_block;

fn bench(c: &mut Criterion) {
    let block = straight_yarn_block([14, 12, 10], 2e-3, 1e-3);
    let params = ShapeFitParams::default();
    let fit = ShapeFit::new(&block.mesh, &block.yarns, &block.rest, params).expect("a valid block");
    eprintln!(
        "shape_fit bench: {} nodes, {} tetrahedra, {} yarn vertices",
        block.mesh.rest.len(),
        block.mesh.tets.len(),
        block.rest.len()
    );
    // A bent, stretched and twisted frame.
    let rows: Vec<[f64; 4]> = block
        .rest
        .iter()
        .map(|r| {
            let s = r[0] / 2e-3;
            [
                1.1 * r[0],
                r[1] + 2e-4 * s.sin(),
                r[2] + 1e-5 * s * s,
                r[3] + 0.05 * s,
            ]
        })
        .collect();
    let pose = fit.transport().pose(&rows).expect("a valid frame");
    let target = fit.target(&pose).expect("a valid pose");

    let mut group = c.benchmark_group("shape_fit");
    group.sample_size(10);
    group.bench_function("new (clip, plan, assemble, analyze, factorize)", |b| {
        b.iter(|| ShapeFit::new(&block.mesh, &block.yarns, &block.rest, params).unwrap())
    });
    group.bench_function("target (Eq. 5)", |b| b.iter(|| fit.target(&pose).unwrap()));
    let paper = ShapeFitParams {
        karcher_iterations: 0,
        ..params
    };
    let fit0 = ShapeFit::new(&block.mesh, &block.yarns, &block.rest, paper).unwrap();
    group.bench_function(
        "target (Eq. 5, the paper's one-step rotation average)",
        |b| b.iter(|| fit0.target(&pose).unwrap()),
    );
    group.bench_function("solve (Eq. 6, factored)", |b| {
        b.iter(|| fit.solve(&target).unwrap())
    });
    group.bench_function("fit (Eq. 5 + Eq. 6)", |b| {
        b.iter(|| fit.fit(&pose).unwrap())
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
