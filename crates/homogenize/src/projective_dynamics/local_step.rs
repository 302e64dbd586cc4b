//! The local step of projective dynamics (the knitwear paper Sec. 7.1, Eq. 26): with the positions `x`
//! (`#V × 3`, m) held fixed, each element's deformation gradient `F_e = D_s D_m⁻¹` is projected onto the
//! two constraint sets of the material of Eq. 7,
//!
//! ```text
//! R_e = R(F_e)   the closest rotation (polar decomposition),
//! V_e = V(F_e)   the closest matrix with det V = 1 (Eq. 26, with the paper's clamping),
//! P_e = (γˢ_e R_e + γᵛ_e V_e) / (γˢ_e + γᵛ_e)        (dimensionless; I when γˢ_e + γᵛ_e = 0),
//! ```
//!
//! and the element energy `E_e = γˢ_e V_e ‖F_e − R_e‖² + γᵛ_e V_e ‖F_e − V_e‖²` (J, Eq. 7 without a ½) is
//! summed on the way. For fixed `R`, `V` the two terms are `(γˢ + γᵛ) V_e ‖F − P‖²` plus a constant of
//! `R`, `V` alone (complete the square), which is the global step's `½ ω_e ‖F − P_e‖²` with
//! `ω_e = 2 V_e (γˢ_e + γᵛ_e)` ([`element_weights`]). No derivative is taken here; what the step hands on
//! has one property the tests check: by the envelope theorem `∂E_e/∂F = 2γˢ(F − R) + 2γᵛ(F − V) =
//! ω_e/V_e (F − P_e)`, so the global step's elastic gradient `Σ ω_e G_eᵀ (F_e − P_e)` at the `x` the
//! targets were projected from is the true `∇E` of [`crate::knit_material`].
//!
//! `R` and `V` share one rotation-variant SVD of `F_e`. The elements are independent: they are split into contiguous chunks, one per thread
//! (`std::thread::scope`), and each thread writes its own slice of the targets.

use nalgebra::Matrix3;

use crate::closest_volume_preserving::{
    VolumePreservingError, VolumePreservingParams, volume_preserving_stretches,
};
use crate::knit_material::KnitMaterial;
use crate::polar_decomposition::polar_decomposition;

/// Why a local step failed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LocalStepError {
    /// The positions or the target buffer have the wrong length.
    #[error("{what} has {given} entries where {expected} are needed")]
    Length {
        /// Which input.
        what: &'static str,
        /// Entries given.
        given: usize,
        /// Entries needed.
        expected: usize,
    },
    /// A position is NaN or ∞.
    #[error("positions[{node}] is not finite; the simulation has diverged or was given NaN")]
    NotFinite {
        /// The node.
        node: usize,
    },
    /// The projection `V(F)`'s settings are out of range.
    #[error(transparent)]
    Projection(#[from] VolumePreservingError),
}

/// `ω_e = 2 V_e (γˢ_e + γᵛ_e)` per element (J): the global step's weights for the material of Eq. 7.
pub fn element_weights(material: &KnitMaterial) -> Vec<f64> {
    material
        .rest_tets()
        .iter()
        .zip(material.gamma())
        .map(|(r, g)| 2.0 * r.volume * (g[0] + g[1]))
        .collect()
}

/// Projects every element of `material` at positions `x` (`#V × 3`, m) and writes `P_e` into `targets`
/// (`#T`), on `threads` threads (at least 1). Returns the elastic energy `E(x)` of Eq. 7 (J).
pub fn local_step(
    material: &KnitMaterial,
    x: &[[f64; 3]],
    params: &VolumePreservingParams,
    threads: usize,
    targets: &mut [Matrix3<f64>],
) -> Result<f64, LocalStepError> {
    let elements = material.tets().len();
    let nodes = material.dof_count() / 3;
    if x.len() != nodes {
        return Err(LocalStepError::Length {
            what: "the positions",
            given: x.len(),
            expected: nodes,
        });
    }
    if targets.len() != elements {
        return Err(LocalStepError::Length {
            what: "the targets",
            given: targets.len(),
            expected: elements,
        });
    }
    if let Some(node) = x.iter().position(|p| !p.iter().all(|v| v.is_finite())) {
        return Err(LocalStepError::NotFinite { node });
    }
    params.validate()?;
    let threads = threads.clamp(1, elements.max(1));
    let chunk = elements.div_ceil(threads).max(1);
    let project = |first: usize, out: &mut [Matrix3<f64>]| -> f64 {
        let mut energy = 0.0;
        for (k, p) in out.iter_mut().enumerate() {
            let e = first + k;
            let rest = &material.rest_tets()[e];
            let f = rest.deformation_gradient(&material.tets()[e].map(|v| x[v]));
            let [gs, gv] = material.gamma()[e];
            // One SVD for both: R = U Wᵀ and V = U diag(s) Wᵀ (as `closest_volume_preserving`).
            let polar = polar_decomposition(&f);
            let r = polar.rotation;
            let s = volume_preserving_stretches(&polar.sigma, params).stretches;
            let v = polar.u * Matrix3::from_diagonal(&s) * polar.w.transpose();
            energy += rest.volume * (gs * (f - r).norm_squared() + gv * (f - v).norm_squared());
            *p = if gs + gv > 0.0 {
                (gs * r + gv * v) / (gs + gv)
            } else {
                Matrix3::identity()
            };
        }
        energy
    };
    if threads == 1 {
        return Ok(project(0, targets));
    }
    let results: Vec<f64> = std::thread::scope(|scope| {
        let handles: Vec<_> = targets
            .chunks_mut(chunk)
            .enumerate()
            .map(|(i, out)| {
                let project = &project;
                scope.spawn(move || project(i * chunk, out))
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("a local-step thread panicked"))
            .collect()
    });
    Ok(results.iter().sum())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::knit_material::MaterialHessian;
    use crate::knit_material::test_states::{block_mesh, rng, rotation};
    use crate::projective_dynamics::GlobalStep;
    use rand::Rng;

    fn jittered(
        material_mesh: &crate::volumetric_mesh::VolumetricMesh,
        seed: u64,
        amount: f64,
    ) -> Vec<[f64; 3]> {
        let mut rng = rng(seed);
        let q = rotation(&mut rng);
        material_mesh
            .rest
            .iter()
            .map(|p| {
                let r = q * nalgebra::Vector3::from(*p);
                [0, 1, 2].map(|i| 1.3 * r[i] + rng.random_range(-amount..amount))
            })
            .collect()
    }

    #[test]
    fn energy_and_gradient_agree_with_the_knit_material_on_any_thread_count() {
        let mesh = block_mesh(3, 2, 2, 0.01);
        let mut rng = rng(5);
        let gamma: Vec<[f64; 2]> = (0..mesh.tets.len())
            .map(|_| [rng.random_range(0.0..2e3), rng.random_range(0.0..5e3)])
            .collect();
        let params = VolumePreservingParams::default();
        let material = KnitMaterial::new(&mesh, gamma, params).unwrap();
        // Strong jitter: compressed, stretched and some inverted elements (the clamped regime of V).
        for (seed, amount) in [(1, 0.001), (2, 0.004), (3, 0.012)] {
            let x = jittered(&mesh, seed, amount);
            let flat: Vec<f64> = x.iter().flatten().copied().collect();
            let reference = material.evaluate(&flat, MaterialHessian::Skip).unwrap();
            let mut one = vec![Matrix3::zeros(); mesh.tets.len()];
            let mut two = one.clone();
            let e1 = local_step(&material, &x, &params, 1, &mut one).unwrap();
            let e3 = local_step(&material, &x, &params, 3, &mut two).unwrap();
            assert_eq!(one, two, "the targets depend on the thread count");
            assert!((e1 - e3).abs() <= 1e-12 * e1.abs());
            assert!(
                (e1 - reference.energy).abs() <= 1e-10 * reference.energy.abs(),
                "{e1} vs {}",
                reference.energy
            );
            // The global step's elastic gradient with these targets is ∇E (the envelope theorem).
            let weights = element_weights(&material);
            let step = GlobalStep::new(&mesh, &weights, &[], 1.0).unwrap();
            let zeros = vec![[0.0; 3]; x.len()];
            let (_, g) = step.objective(&x, &zeros, &one, &[], &x);
            let scale = reference
                .gradient
                .iter()
                .fold(0.0f64, |m, v| m.max(v.abs()));
            for (v, row) in g.iter().enumerate() {
                for i in 0..3 {
                    let want = reference.gradient[3 * v + i];
                    assert!(
                        (row[i] - want).abs() <= 1e-9 * scale,
                        "seed {seed}, node {v}.{i}: {} vs {want}",
                        row[i]
                    );
                }
            }
        }
    }

    #[test]
    fn the_targets_are_the_closest_points_of_the_two_sets() {
        // For F not inverted, ‖F − R‖ ≤ ‖F − Q‖ for rotations Q and ‖F − V‖ ≤ ‖F − A‖ on det A = 1:
        // P_e minimizes the surrogate γˢ‖F − R‖² + γᵛ‖F − V‖² over the sets, the PD descent property.
        let mesh = block_mesh(1, 1, 1, 0.01);
        let params = VolumePreservingParams::default();
        let gamma = vec![[1.0, 0.0]; mesh.tets.len()];
        let shape = KnitMaterial::new(&mesh, gamma, params).unwrap();
        let volume = KnitMaterial::new(&mesh, vec![[0.0, 1.0]; mesh.tets.len()], params).unwrap();
        let x = jittered(&mesh, 9, 0.002);
        let mut r = vec![Matrix3::zeros(); mesh.tets.len()];
        let mut v = r.clone();
        local_step(&shape, &x, &params, 2, &mut r).unwrap();
        local_step(&volume, &x, &params, 2, &mut v).unwrap();
        let mut rng = rng(11);
        for e in 0..mesh.tets.len() {
            let f = shape.rest_tets()[e].deformation_gradient(&mesh.tets[e].map(|n| x[n]));
            assert!(f.determinant() > 0.0);
            assert!((r[e].determinant() - 1.0).abs() < 1e-12);
            assert!((v[e].determinant() - 1.0).abs() < 1e-10);
            for _ in 0..200 {
                let q = rotation(&mut rng);
                assert!((f - r[e]).norm() <= (f - q).norm() + 1e-12);
                let a = v[e] + Matrix3::from_fn(|_, _| rng.random_range(-0.05..0.05));
                let a = a / a.determinant().cbrt();
                assert!((f - v[e]).norm() <= (f - a).norm() + 1e-12);
            }
        }
    }

    #[test]
    fn bad_inputs_are_refused_by_name() {
        let mesh = block_mesh(1, 1, 1, 0.01);
        let params = VolumePreservingParams::default();
        let material = KnitMaterial::new(&mesh, vec![[1.0, 1.0]; 6], params).unwrap();
        let mut targets = vec![Matrix3::zeros(); 6];
        let mut x = mesh.rest.clone();
        assert!(matches!(
            local_step(&material, &x[1..], &params, 2, &mut targets),
            Err(LocalStepError::Length {
                given: 7,
                expected: 8,
                ..
            })
        ));
        assert!(matches!(
            local_step(&material, &x, &params, 2, &mut targets[1..]),
            Err(LocalStepError::Length {
                given: 5,
                expected: 6,
                ..
            })
        ));
        x[3][2] = f64::NAN;
        assert!(matches!(
            local_step(&material, &x, &params, 2, &mut targets),
            Err(LocalStepError::NotFinite { node: 3 })
        ));
        let bad = VolumePreservingParams {
            floor: 2.0,
            ..params
        };
        assert!(matches!(
            local_step(&material, &mesh.rest, &bad, 0, &mut targets),
            Err(LocalStepError::Projection(_))
        ));
        // Zero threads is one thread, and γ = 0 gives the identity target.
        let zero = KnitMaterial::new(&mesh, vec![[0.0, 0.0]; 6], params).unwrap();
        assert_eq!(
            local_step(&zero, &mesh.rest, &params, 0, &mut targets).unwrap(),
            0.0
        );
        assert!(targets.iter().all(|p| *p == Matrix3::identity()));
    }
}
