//! Acceptance of issue 46: a tube of fabric worn on a rigid cylinder presses it with the hoop law
//! `p = τ / R`, `τ = T(λc − 1) / λz` the course tension per deformed width (N/m) — the course curve read at
//! the hoop stretch for an orthotropic fabric, whatever its wale stiffness and grain angle in the pattern,
//! and `τ = t · 2 λc ∂ψ/∂λ1 / λz` for the isotropic one.
//!
//! The tube is `around × rows` quads of a cylinder of radius `R`, each split in two triangles whose pattern
//! is the unrolled cylinder shrunk by the hoop stretch `λc` and the axial stretch `λz` (then turned by the
//! grain angle). The pressure at a vertex is the inward radial component of the membrane force
//! `−∂U/∂x` over a third of the deformed area of its triangles. Chords shorten the hoop stretch by
//! `sin(π/N)/(π/N)`, so the measured pressure equals `τ(λ_chord)/R` to rounding and `τ(λc)/R` to
//! `O(1/N²)` (within 1 % from `N = 96`).

use skintight_physics::math::{Mat2, Real, Vec2, Vec3};
use skintight_physics::membrane_law::MembraneDensity;
use skintight_physics::orthotropic_density::OrthotropicDensity;
use skintight_physics::{MembraneElement, TensionFieldDensity, TensionFieldParams};
use std::f64::consts::PI;

const R: Real = 0.05;
const T: Real = 5e-4;

/// Course curve of a soft compression knit (N/m); the wale is `ratio` times it.
fn knit(ratio: Real) -> OrthotropicDensity {
    let course = [[0.2, 12.0], [0.5, 40.0], [0.8, 95.0], [1.2, 210.0]];
    let wale: Vec<[Real; 2]> = course.iter().map(|p| [p[0], ratio * p[1]]).collect();
    OrthotropicDensity::new(&course, &wale, &[[0.1, 1.5], [0.3, 6.0]], T).unwrap()
}

/// Pressure (Pa) at the vertex of ring `rows / 2`, angle 0, and the smallest and largest over that ring.
fn tube_pressure<D: MembraneDensity>(
    law: &D,
    around: usize,
    rows: usize,
    lc: Real,
    lz: Real,
    grain: Real,
) -> (Real, Real) {
    let h = 2.0 * PI * R / around as Real;
    let vid = |i: usize, j: usize| (i % around) + around * j;
    let pos: Vec<Vec3> = (0..=rows)
        .flat_map(|j| {
            (0..around).map(move |i| {
                let a = 2.0 * PI * i as Real / around as Real;
                Vec3::new(R * a.cos(), R * a.sin(), h * j as Real)
            })
        })
        .collect();
    // Pattern of (i, j) (unwrapped per triangle), turned by the grain angle.
    let rot = Mat2::new(grain.cos(), -grain.sin(), grain.sin(), grain.cos());
    let pat = |i: usize, j: usize| rot * Vec2::new(h * i as Real / lc, h * j as Real / lz);
    let mut tris = Vec::new();
    for j in 0..rows {
        for i in 0..around {
            tris.push([(i, j), (i + 1, j), (i + 1, j + 1)]);
            tris.push([(i, j), (i + 1, j + 1), (i, j + 1)]);
        }
    }
    let mut force = vec![Vec3::zeros(); pos.len()];
    let mut area = vec![0.0; pos.len()];
    for t in &tris {
        let rest = t.map(|(i, j)| pat(i, j));
        let el = MembraneElement::new(rest, T).unwrap().with_grain(grain);
        let ids = t.map(|(i, j)| vid(i, j));
        let x = ids.map(|v| pos[v]);
        let (_, g) = el.energy_gradient(law, &x).unwrap();
        let a = 0.5 * (x[1] - x[0]).cross(&(x[2] - x[0])).norm();
        for (k, &v) in ids.iter().enumerate() {
            force[v] -= Vec3::new(g[3 * k], g[3 * k + 1], g[3 * k + 2]);
            area[v] += a / 3.0;
        }
    }
    let ring = rows / 2;
    let (mut lo, mut hi) = (Real::INFINITY, Real::NEG_INFINITY);
    for i in 0..around {
        let v = vid(i, ring);
        let inward = -Vec3::new(pos[v].x, pos[v].y, 0.0) / R;
        let p = force[v].dot(&inward) / area[v];
        lo = lo.min(p);
        hi = hi.max(p);
    }
    (lo, hi)
}

fn chord(lc: Real, around: usize) -> Real {
    let x = PI / around as Real;
    lc * x.sin() / x
}

#[test]
fn orthotropic_tube_pressure_is_course_tension_over_radius() {
    let around = 96;
    for ratio in [10.0, 0.1] {
        let law = knit(ratio);
        for (lc, lz) in [(1.3, 1.0), (1.6, 1.0), (1.3, 1.08), (1.45, 0.92)] {
            for grain in [0.0, 0.6, -2.0] {
                let (lo, hi) = tube_pressure(&law, around, 8, lc, lz, grain);
                let want = law.course().tension(lc - 1.0) / (lz * R);
                for p in [lo, hi] {
                    assert!(
                        (p - want).abs() <= 1e-2 * want,
                        "wale ×{ratio}, λc {lc}, λz {lz}, grain {grain}: {p} Pa vs {want} Pa"
                    );
                }
                // Exactly the hoop law at the chords' stretch.
                let exact = law.course().tension(chord(lc, around) - 1.0) / (lz * R);
                assert!((lo - exact).abs() <= 1e-6 * exact && (hi - exact).abs() <= 1e-6 * exact);
            }
        }
    }
}

#[test]
fn isotropic_tube_pressure_is_hoop_tension_over_radius() {
    let law = TensionFieldDensity::new(5.4e6, 0.33, &TensionFieldParams::default()).unwrap();
    let around = 96;
    for (lc, lz) in [(1.2, 1.0), (1.1, 1.02)] {
        let tau = |l: Real| T * l * 2.0 * law.derivatives(l * l, lz * lz).gradient[0] / lz;
        let (lo, hi) = tube_pressure(&law, around, 8, lc, lz, 0.0);
        let want = tau(lc) / R;
        let exact = tau(chord(lc, around)) / R;
        for p in [lo, hi] {
            assert!((p - want).abs() <= 1e-2 * want, "{p} vs {want}");
            assert!((p - exact).abs() <= 1e-6 * exact, "{p} vs {exact}");
        }
    }
}

#[test]
fn coarse_tubes_converge_to_the_hoop_law() {
    // The error falls as 1/N² with the number of segments around.
    let law = knit(10.0);
    let want = law.course().tension(0.4) / R;
    let errs: Vec<Real> = [12, 24, 48]
        .iter()
        .map(|&n| (tube_pressure(&law, n, 4, 1.4, 1.0, 0.3).0 - want).abs() / want)
        .collect();
    for w in errs.windows(2) {
        assert!(w[1] < w[0] / 3.0, "{errs:?}");
    }
}
