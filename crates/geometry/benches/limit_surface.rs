//! Evaluations per second of the Loop limit surface on the regular body (`regular_1k.obj`, quads
//! fan-triangulated, one preprocessing subdivision): stencil + position + first + second derivatives,
//! separately on regular faces and on faces with an extraordinary vertex.
//!
//! Run: `cargo bench -p skintight-geometry --bench limit_surface`

use criterion::{BatchSize, Criterion, Throughput, criterion_group, criterion_main};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use skintight_geometry::{LimitSurface, LoopSurface, Real, Stencil, Vec2, Vec3};
use std::hint::black_box;

/// The regular body, read with the real reader (quads fan-triangulated).
fn read_body() -> (Vec<Vec3>, Vec<[usize; 3]>) {
    let main = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../shared/data/bodies/regular_1k.obj"
    );
    let wt = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../../shared/data/bodies/regular_1k.obj"
    );
    let path = if std::path::Path::new(main).is_file() {
        main
    } else {
        wt
    };
    let m = skintight_geometry::mesh::io::read_mesh(std::path::Path::new(path))
        .expect("regular_1k.obj");
    (m.positions, m.faces)
}

fn bench(c: &mut Criterion) {
    let (y, faces) = read_body();
    let surf = LoopSurface::with_preprocessing_subdivision(y.len(), &faces).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    const N: usize = 4096;
    for (name, irregular) in [("regular_faces", false), ("irregular_faces", true)] {
        let pool: Vec<usize> = (0..surf.num_faces())
            .filter(|&f| surf.is_irregular(f) == irregular)
            .collect();
        let queries: Vec<(usize, Vec2)> = (0..N)
            .map(|_| {
                let f = pool[rng.random_range(0..pool.len())];
                let a: Real = rng.random_range(0.0..1.0);
                let b: Real = rng.random_range(0.0..1.0 - a);
                (f, Vec2::new(a, b))
            })
            .collect();
        let mut group = c.benchmark_group("loop_limit_surface");
        group.throughput(Throughput::Elements(N as u64));
        let mut stencil = Stencil::with_capacity(64);
        group.bench_function(name, |bch| {
            bch.iter_batched_ref(
                || (),
                |_| {
                    for &(f, s) in &queries {
                        let p = surf.point_with(&y, f, s, &mut stencil).unwrap();
                        black_box(p);
                    }
                },
                BatchSize::SmallInput,
            )
        });
        group.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
