use super::*;
use crate::PeriodicPattern;
use crate::test_support::shared_yarns_dir;
use crate::tile::tile;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn small_patch(name: &str, nx: usize, ny: usize) -> Patch {
    let p = PeriodicPattern::read(&shared_yarns_dir().join(name).join("pattern.pyp")).unwrap();
    tile(&p, nx, ny).unwrap()
}

/// `x` with positions jittered by up to `s` (m) and angles by up to `a` (rad).
fn jitter(rng: &mut ChaCha8Rng, x: &[f64], s: f64, a: f64) -> Vec<f64> {
    x.iter()
        .enumerate()
        .map(|(k, v)| {
            let w = if k % 4 == 3 { a } else { s };
            v + rng.random_range(-w..w)
        })
        .collect()
}

fn dense_times(h: &[Triplet<usize, usize, f64>], d: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; d.len()];
    for t in h {
        out[t.row] += t.val * d[t.col];
        if t.row != t.col {
            out[t.col] += t.val * d[t.row];
        }
    }
    out
}

/// Central differences of the assembled energy and gradient along random directions: returns the largest
/// relative errors of `g·d` and of `H d`.
fn directional_errors(model: &PatchModel, x: &[f64], rng: &mut ChaCha8Rng) -> (f64, f64) {
    let ev = model.evaluate(x, true);
    let r = model.radius();
    let (mut ge, mut he) = (0.0f64, 0.0f64);
    for _ in 0..4 {
        let d: Vec<f64> = (0..x.len())
            .map(|k| {
                let w = if k % 4 == 3 { 1.0 } else { r };
                rng.random_range(-w..w)
            })
            .collect();
        let t = 1e-6;
        let xp: Vec<f64> = x.iter().zip(&d).map(|(a, b)| a + t * b).collect();
        let xm: Vec<f64> = x.iter().zip(&d).map(|(a, b)| a - t * b).collect();
        let (ep, em) = (model.evaluate(&xp, false), model.evaluate(&xm, false));
        let fd = (ep.energy - em.energy) / (2.0 * t);
        let gd: f64 = ev.gradient.iter().zip(&d).map(|(a, b)| a * b).sum();
        let gscale: f64 = ev
            .gradient
            .iter()
            .zip(&d)
            .map(|(a, b)| (a * b).abs())
            .sum::<f64>()
            .max(1e-300);
        ge = ge.max((fd - gd).abs() / gscale);
        let hd = dense_times(&ev.hessian, &d);
        let hmax = hd.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-300);
        for k in 0..x.len() {
            let fdh = (ep.gradient[k] - em.gradient[k]) / (2.0 * t);
            he = he.max((fdh - hd[k]).abs() / hmax);
        }
    }
    (ge, he)
}

#[test]
fn bonds_of_a_fused_edge_hold_every_cut_end_and_their_derivatives_match_central_differences() {
    let mut rng = ChaCha8Rng::seed_from_u64(23);
    let patch = small_patch("stock_9", 2, 2);
    let params = YarnParams::default();
    let free = PatchModel::new(&patch, &params, PatchLoads::default()).unwrap();
    let mut model = free.clone();
    let count = model.bond_cut_ends();
    let open = model.patch().yarns.iter().filter(|y| !y.closed).count();
    // Every cut end is bonded once, except where the partner's own end already bonded the pair.
    assert!(
        count > 0 && count <= 2 * open,
        "{count} bonds for {open} open yarns"
    );
    let ranges = model.yarn_ranges();
    for b in model.bonds() {
        let [a, p] = b.vertices;
        let yarn_of = |v: usize| ranges.iter().position(|r| r.contains(&v)).unwrap();
        assert_ne!(yarn_of(a), yarn_of(p), "a bond within one yarn: {b:?}");
        assert!(ranges[yarn_of(a)].start == a || ranges[yarn_of(a)].end == a + 1);
    }
    // At the start the bonds cost nothing: same energy and gradient as the free patch.
    let x0 = model.initial_state();
    let (eb, ef) = (model.evaluate(&x0, false), free.evaluate(&x0, false));
    assert!((eb.energy - ef.energy).abs() <= 1e-12 * ef.energy.abs());
    // Moved, the bonds pull: the energy rises by exactly the links' stretching energy.
    let x = jitter(&mut rng, &x0, 0.05 * patch.radius, 0.05);
    let (eb, ef) = (model.evaluate(&x, false), free.evaluate(&x, false));
    let links: f64 = model
        .bonds()
        .map(|b| {
            let [a, p] = b.vertices;
            StretchingEdge {
                rest_length: b.rest_length,
                stiffness: model.stiffness().stretching,
            }
            .energy(PatchModel::pos(&x, a), PatchModel::pos(&x, p))
        })
        .sum();
    assert!(links > 0.0);
    assert!(
        ((eb.energy - ef.energy) - links).abs() <= 1e-9 * links,
        "{} {links}",
        eb.energy - ef.energy
    );
    assert!(((eb.parts[0] - ef.parts[0]) - links).abs() <= 1e-9 * links);
    let energy_only = model.evaluate_order(&x, Order::Energy);
    assert!((energy_only.energy - eb.energy).abs() <= 1e-12 * eb.energy.abs());
    for _ in 0..3 {
        let x = jitter(&mut rng, &x0, 0.05 * patch.radius, 0.05);
        let (ge, he) = directional_errors(&model, &x, &mut rng);
        eprintln!("FD bonded patch: gradient {ge:.2e} hessian {he:.2e}");
        assert!(ge < 1e-6 && he < 1e-4, "{ge} {he}");
        // The bonds are in the Hessian: 21 lower-triangle entries a bond (none of them zero at a
        // jittered state) beyond the free patch's.
        let (hb, hf) = (
            model.evaluate(&x, true).hessian,
            free.evaluate(&x, true).hessian,
        );
        assert_eq!(hb.len() - hf.len(), 21 * count);
    }
}

#[test]
fn assembled_derivatives_match_central_differences_with_contact_gravity_and_sphere() {
    let mut rng = ChaCha8Rng::seed_from_u64(19);
    let patch = small_patch("stocktiniest_9", 2, 2);
    let params = YarnParams::default();
    // Sphere regimes: apart, and touching the lowest vertices of the patch (its centre below the patch in z).
    let x0 = PatchModel::new(&patch, &params, PatchLoads::default())
        .unwrap()
        .initial_state();
    let zmin = x0.chunks(4).map(|c| c[2]).fold(f64::INFINITY, f64::min);
    let centre = [x0[0], x0[1], zmin - 0.02];
    for (case, sphere) in [
        ("no sphere", None),
        (
            "sphere touching",
            Some(SphereObstacle {
                center: centre,
                radius: 0.02 + 0.4 * patch.radius,
                stiffness: 1.0e7,
            }),
        ),
    ] {
        let loads = PatchLoads {
            gravity: [0.3, -9.81, 1.2],
            sphere,
        };
        let model = PatchModel::new(&patch, &params, loads).unwrap();
        for _ in 0..3 {
            let x = jitter(&mut rng, &x0, 0.03 * patch.radius, 0.05);
            let ev = model.evaluate(&x, true);
            assert!(ev.contacts > 0, "{case}: no yarn contact exercised");
            if sphere.is_some() {
                assert!(ev.sphere_contacts > 0, "{case}: sphere not touched");
            } else {
                assert_eq!(ev.parts[5], 0.0);
            }
            let (ge, he) = directional_errors(&model, &x, &mut rng);
            eprintln!("FD patch {case}: gradient {ge:.2e} hessian {he:.2e}");
            assert!(ge < 1e-6 && he < 1e-4, "{case}: {ge} {he}");
        }
    }
}

#[test]
fn gravity_energy_is_the_weight_times_the_height_of_the_centre_of_mass() {
    let patch = small_patch("stock_9", 2, 1);
    let params = YarnParams::default();
    let model = PatchModel::new(&patch, &params, PatchLoads::default()).unwrap();
    let x = model.initial_state();
    let ev = model.evaluate(&x, false);
    let total_length: f64 = model
        .patch()
        .yarns
        .iter()
        .flat_map(|y| y.rest_length.iter())
        .sum();
    let mass = params.linear_density(patch.radius) * total_length;
    let m: f64 = model.masses().iter().sum();
    assert!((m - mass).abs() < 1e-12 * mass);
    let ycm: f64 = model
        .masses()
        .iter()
        .zip(x.chunks(4))
        .map(|(mi, c)| mi * c[1])
        .sum::<f64>()
        / m;
    let expect = m * crate::gravity::STANDARD_GRAVITY * ycm;
    assert!((ev.parts[4] - expect).abs() <= 1e-12 * expect.abs().max(1e-12));
    assert!(model.masses().iter().all(|m| *m > 0.0));
    let unused = model.unused_dofs();
    let open = model.patch().yarns.iter().filter(|y| !y.closed).count();
    assert_eq!(unused.len(), open);
    for k in unused {
        assert_eq!(ev.gradient[k], 0.0);
    }
}

#[test]
fn exclusion_follows_the_arclength_along_one_yarn_only() {
    let patch = small_patch("stock_9", 2, 2);
    let model = PatchModel::new(&patch, &YarnParams::default(), PatchLoads::default()).unwrap();
    let cutoff = model.stiffness().contact_exclusion;
    let y0 = &model.patch().yarns[0];
    assert!(y0.edge_count() > 10);
    assert!(model.excluded(0, 0) && model.excluded(0, 1) && model.excluded(1, 0));
    // The first edge k whose gap from edge 0 reaches the cutoff is the first one not excluded.
    let mut gap = 0.0;
    let mut k = 1;
    while gap < cutoff {
        assert!(model.excluded(0, k), "edge {k} at gap {gap}");
        gap += y0.rest_length[k];
        k += 1;
    }
    assert!(!model.excluded(0, k), "edge {k} at gap {gap}");
    // Edges of different yarns always may touch.
    let other = y0.edge_count();
    assert!(!model.excluded(0, other));
}

#[test]
fn a_rigid_motion_leaves_the_energy_without_gravity_unchanged() {
    let patch = small_patch("stocktiniest_9", 2, 2);
    let params = YarnParams::default();
    let loads = PatchLoads {
        gravity: [0.0; 3],
        sphere: None,
    };
    let (c, s) = (0.6f64, 0.8f64);
    let rotation = [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]];
    let moved = transform_patch(&patch, rotation, [0.1, -0.2, 0.3]);
    let a = PatchModel::new(&patch, &params, loads).unwrap();
    let b = PatchModel::new(&moved, &params, loads).unwrap();
    let (ea, eb) = (
        a.evaluate(&a.initial_state(), false),
        b.evaluate(&b.initial_state(), false),
    );
    for k in 0..4 {
        assert!(
            (ea.parts[k] - eb.parts[k]).abs() <= 1e-9 * ea.energy.abs().max(1e-12),
            "part {k}: {} vs {}",
            ea.parts[k],
            eb.parts[k]
        );
    }
    assert!(
        ea.energy > 0.0,
        "the published rest state is not stress-free"
    );
    assert_eq!(ea.contacts, eb.contacts);
}

#[test]
fn the_energy_alone_equals_the_energy_of_the_full_evaluation() {
    // The line search's energy-only path (plain numbers, bending and twisting from one strain evaluation,
    // contact without derivatives) against the evaluation with gradient and Hessian, term by term.
    let mut rng = ChaCha8Rng::seed_from_u64(23);
    let patch = small_patch("stocktiniest_9", 2, 2);
    let x0 = PatchModel::new(&patch, &YarnParams::default(), PatchLoads::default())
        .unwrap()
        .initial_state();
    let zmin = x0.chunks(4).map(|c| c[2]).fold(f64::INFINITY, f64::min);
    let loads = PatchLoads {
        gravity: [0.3, -9.81, 1.2],
        sphere: Some(SphereObstacle {
            center: [x0[0], x0[1], zmin - 0.02],
            radius: 0.02 + 0.4 * patch.radius,
            stiffness: 1.0e7,
        }),
    };
    let model = PatchModel::new(&patch, &YarnParams::default(), loads).unwrap();
    for _ in 0..3 {
        let x = jitter(&mut rng, &x0, 0.05 * patch.radius, 0.1);
        let full = model.evaluate_order(&x, Order::Hessian);
        let gradient = model.evaluate_order(&x, Order::Gradient);
        let energy = model.evaluate_order(&x, Order::Energy);
        assert!(full.contacts > 0 && full.sphere_contacts > 0);
        assert!(energy.gradient.is_empty() && energy.hessian.is_empty());
        assert!(gradient.hessian.is_empty());
        assert_eq!(gradient.gradient, full.gradient);
        for (a, b) in [(&energy, &full), (&gradient, &full)] {
            assert!(
                (a.energy - b.energy).abs() <= 1e-12 * b.energy.abs(),
                "{} vs {}",
                a.energy,
                b.energy
            );
            for k in 0..6 {
                assert!(
                    (a.parts[k] - b.parts[k]).abs() <= 1e-12 * b.parts[k].abs(),
                    "part {k}: {} vs {}",
                    a.parts[k],
                    b.parts[k]
                );
            }
            assert_eq!(
                (a.contacts, a.candidates, a.sphere_contacts),
                (b.contacts, b.candidates, b.sphere_contacts)
            );
            assert_eq!(a.min_distance, b.min_distance);
        }
    }
}
