//! Membrane element throughput: energy, gradient and 9 × 9 Hessian of one cloth triangle, and the
//! 9 × 6 mixed derivative used by the adjoint.
//!
//! Run: `cargo bench -p skintight-physics --bench membrane`.

use criterion::{BatchSize, Criterion, Throughput, criterion_group, criterion_main};
use skintight_physics::math::{Real, Vec2, Vec3};
use skintight_physics::{MembraneElement, TensionFieldDensity, TensionFieldParams};
use std::hint::black_box;

/// A batch of elements in a mix of states: taut, wrinkled, slack and inside the smoothing bands.
fn batch(n: usize) -> Vec<(MembraneElement, [Vec3; 3])> {
    (0..n)
        .map(|i| {
            let s = 0.005 * (1.0 + (i % 7) as Real * 0.1);
            let rest = [
                Vec2::zeros(),
                Vec2::new(s, 0.0),
                Vec2::new(0.3 * s, 0.9 * s),
            ];
            let el = MembraneElement::new(rest, 1e-4).expect("valid element");
            // Stretch factors cycling through the regimes.
            let sx = [1.15, 1.2, 0.95, 1.004, 1.1][i % 5];
            let sy = [1.1, 0.9, 0.9, 1.0, 0.955][i % 5];
            let th = 0.1 * i as Real;
            let x = rest.map(|p| {
                let q = Vec3::new(sx * p.x, sy * p.y, 0.0);
                Vec3::new(
                    q.x * th.cos() - q.z * th.sin(),
                    q.y,
                    q.x * th.sin() + q.z * th.cos(),
                )
            });
            (el, x)
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let density =
        TensionFieldDensity::new(5.4e6, 0.33, &TensionFieldParams::default()).expect("material");
    let elements = batch(1000);
    let mut group = c.benchmark_group("membrane_element");
    group.throughput(Throughput::Elements(elements.len() as u64));
    group.bench_function("energy_gradient_hessian_x1000", |b| {
        b.iter_batched(
            || (),
            |_| {
                let mut acc = 0.0;
                for (el, x) in &elements {
                    let d = el.derivatives(&density, black_box(x)).expect("finite");
                    acc += d.energy + d.hessian[(4, 5)];
                }
                acc
            },
            BatchSize::SmallInput,
        )
    });
    group.bench_function("energy_gradient_x1000", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for (el, x) in &elements {
                let (e, g) = el.energy_gradient(&density, black_box(x)).expect("finite");
                acc += e + g[3];
            }
            acc
        })
    });
    group.bench_function("mixed_hessian_x1000", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for (el, x) in &elements {
                acc += el.mixed_hessian(&density, black_box(x)).expect("finite")[(3, 2)];
            }
            acc
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
