//! Yarn–yarn contact: a smooth penalty on the distances, below the yarn diameter, between the centrelines
//! of two rod segments — the double integral over both yarns' arclengths of Kaldor et al. 2008 ("Simulating
//! knitted cloth at the yarn level", §4.2), the contact model HYLC's yarn solver builds on:
//!
//! `E_c = k_c ℓ_a ℓ_b ∫₀¹∫₀¹ φ(|p(s) − q(t)|²/D²) ds dt`,  `φ(u) = (1 − u)³/u` for `u < 1`, else 0
//!
//! - `p(s) = p₀ + s(p₁ − p₀)`, `q(t) = q₀ + t(q₁ − q₀)`: the two segments (m); `ℓ_a, ℓ_b` their rest
//!   lengths (m); `D = 2r` the contact distance (m, the yarn diameter);
//! - `k_c`: the contact stiffness (J/m² = N/m); `E_c` in J;
//! - the integral by 3 × 3-point Gauss–Legendre quadrature.
//!
//! Why an integral of point distances and not the closest-point (segment–segment) distance: the latter is
//! not differentiable where two segments are parallel (the closest points jump between the two ends), and
//! woven patterns rest with exactly parallel neighbours (`basket_9`), where Newton then stalls on the kink.
//! The kernel is Kaldor et al.'s barrier `1/u + u − 2` (which is only C¹ at contact) made C²: `φ(u) =
//! (1 − u)³/u` has a triple root at `u = 1` (energy, force and stiffness vanish as a contact switches on, so
//! Newton sees no jump) and grows like `1/u` as two centreline points approach, so a working penetration
//! stays small whatever the load. The integral is C² wherever no two quadrature points coincide. The segment–segment distance ([`crate::segment_distance`]) still selects the
//! candidate pairs (no point pair is closer than it) and measures interpenetration.
//!
//! Unknowns `(p₀, p₁, q₀, q₁)` (12, m). Gradient (N) and Hessian (N/m) in closed form, by hand: at a
//! quadrature point `(s, t)` the offset `w = p(s) − q(t) = Σᵢ aᵢ xᵢ` is linear in the four points
//! `xᵢ = p₀, p₁, q₀, q₁` with `a = (1 − s, s, t − 1, −t)`, and `u = |w|²/D²`, so `∂u/∂xᵢ = aᵢ 2w/D²` and
//!
//! `∂E/∂xᵢ = C Σ ω φ'(u) aᵢ 2w/D²`,  `∂²E/∂xᵢ∂xⱼ = C Σ ω aᵢ aⱼ [φ''(u) (2w/D²)(2w/D²)ᵀ + φ'(u) 2I/D²]`
//!
//! (`C = k_c ℓ_a ℓ_b`, `ω` the product of the two Gauss weights, sums over the points with `u < 1`), with
//! `φ'(u) = −3(1 − u)²/u − (1 − u)³/u²` and `φ''(u) = 6(1 − u)/u + 6(1 − u)²/u² + 2(1 − u)³/u³` — some
//! 1.5 k flops a pair against ~50 k for second-order jets of the same expression (issue 19's speed-up). The
//! tests check the closed form against the jets ([`crate::jet`], to rounding) and against central
//! differences for crossing, end-to-interior, end-to-end, parallel and near-parallel pairs and pairs out of
//! range.
//!
//! **Kernels** ([`ContactKernel`]). The default is the C² kernel above. [`ContactKernel::Kaldor`] is Kaldor
//! et al.'s own, `φ(u) = 1/u + u − 2 = (1 − u)²/u` in `u = d²/D²` (their `f(d) = 1/d² + d² − 2` of the
//! distance over the diameter), with `φ'(u) = 1 − 1/u²` and `φ''(u) = 2/u³`: energy and force vanish at
//! contact, the stiffness jumps from 0 to `2 C ω (2w/D²)(2w/D²)ᵀ` (C¹). It is the law HYLC's yarn solver
//! builds on (Sperl et al. 2020 cite Kaldor et al. 2008 for contact); HYLC's own discretisation and
//! normalisation could not be read (its repository, git.ist.ac.at/gsperl/HYLC, is not reachable from
//! here), so the same `ℓ_a ℓ_b`-weighted Gauss quadrature of the double integral is used for both kernels.

use serde::{Deserialize, Serialize};

use crate::frames::V3;
use crate::frames::{dot, sub};
use crate::jet::Scalar;
#[cfg(test)]
use crate::jet::{Jet, value_gradient_hessian};
use crate::segment_distance::{ClosestPointCase, closest_point_case, segment_distance};

/// Gauss–Legendre nodes and weights on `[0, 1]` (3 points).
const GAUSS: [(f64, f64); 3] = [
    (0.5 - 0.387_298_334_620_741_7, 5.0 / 18.0),
    (0.5, 8.0 / 18.0),
    (0.5 + 0.387_298_334_620_741_7, 5.0 / 18.0),
];

/// The 3 × 3 Gauss point pairs `(s, t)` of the segments `q` (12 unknowns, m): `a = (1 − s, s, t − 1, −t)`,
/// the two weights, and the offset `w = p(s) − q(t) = Σᵢ aᵢ xᵢ` (m).
pub(crate) fn gauss_point_pairs(
    q: &[f64; CONTACT_DOFS],
) -> impl Iterator<Item = ([f64; 4], [f64; 2], [f64; 3])> + '_ {
    GAUSS.iter().flat_map(move |&(s, ws)| {
        GAUSS.iter().map(move |&(t, wt)| {
            let a = [1.0 - s, s, t - 1.0, -t];
            let w: [f64; 3] = std::array::from_fn(|k| {
                a[0] * q[k] + a[1] * q[3 + k] + a[2] * q[6 + k] + a[3] * q[9 + k]
            });
            (a, [ws, wt], w)
        })
    })
}

/// `φ'(u) = −3(1 − u)²/u − (1 − u)³/u²` (dimensionless), the slope of the contact kernel below contact
/// (`u < 1`; negative: repulsive).
pub(crate) fn kernel_slope(u: f64) -> f64 {
    let (m, iu) = (1.0 - u, 1.0 / u);
    -(3.0 * m * m * iu + m * m * m * iu * iu)
}

/// Unknowns of a contact pair: two segments' end points.
pub const CONTACT_DOFS: usize = 12;

/// The contact kernel `φ(u)` of `u = d²/D²` (module documentation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ContactKernel {
    /// `φ(u) = (1 − u)³/u`: C² at contact (this crate's default).
    #[default]
    Smooth,
    /// `φ(u) = 1/u + u − 2`: Kaldor et al. 2008's kernel, C¹ at contact.
    Kaldor,
}

impl ContactKernel {
    /// `φ(u)`, `φ'(u)`, `φ''(u)` (dimensionless) for `0 < u < 1`.
    pub fn value_slope_curvature(self, u: f64) -> (f64, f64, f64) {
        let (m, iu) = (1.0 - u, 1.0 / u);
        match self {
            Self::Smooth => (
                m * m * m * iu,
                kernel_slope(u),
                6.0 * m * iu + 6.0 * m * m * iu * iu + 2.0 * m * m * m * iu * iu * iu,
            ),
            Self::Kaldor => (m * m * iu, 1.0 - iu * iu, 2.0 * iu * iu * iu),
        }
    }

    fn value_of<S: Scalar>(self, u: S) -> S {
        let x = S::cst(1.0) - u;
        match self {
            Self::Smooth => x * x * x / u,
            Self::Kaldor => x * x / u,
        }
    }
}

/// A pair's energy (J), its gradient (N per unit of the 12 unknowns) and Hessian.
pub type ContactDerivatives = (
    f64,
    [f64; CONTACT_DOFS],
    [[f64; CONTACT_DOFS]; CONTACT_DOFS],
);

/// One pair of segments in contact.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactPair {
    /// Rest lengths `ℓ_a, ℓ_b` of the two segments (m).
    pub rest_lengths: [f64; 2],
    /// Contact distance `D` (m): the yarn diameter.
    pub contact_distance: f64,
    /// Contact stiffness `k_c` (J/m²).
    pub stiffness: f64,
    /// The kernel `φ`.
    pub kernel: ContactKernel,
}

impl ContactPair {
    fn energy_of<S: Scalar>(&self, q: &[S; CONTACT_DOFS]) -> S {
        let p = |k: usize| -> V3<S> { [q[3 * k], q[3 * k + 1], q[3 * k + 2]] };
        let (p0, p1, q0, q1) = (p(0), p(1), p(2), p(3));
        let da = sub(p1, p0);
        let db = sub(q1, q0);
        let mut sum = S::cst(0.0);
        for &(s, ws) in &GAUSS {
            for &(t, wt) in &GAUSS {
                let w: V3<S> = std::array::from_fn(|k| p0[k] + da[k] * s - q0[k] - db[k] * t);
                let u = dot(w, w) * (1.0 / (self.contact_distance * self.contact_distance));
                if u.value() < 1.0 {
                    sum += self.kernel.value_of(u) * (ws * wt);
                }
            }
        }
        sum * (self.stiffness * self.rest_lengths[0] * self.rest_lengths[1])
    }

    /// The distance (m) between the two segments at `q`, and its case.
    pub fn distance(&self, q: &[f64; CONTACT_DOFS]) -> (f64, ClosestPointCase) {
        let p = |k: usize| [q[3 * k], q[3 * k + 1], q[3 * k + 2]];
        let (regime, _, _) = closest_point_case(p(0), p(1), p(2), p(3));
        (
            segment_distance::<f64>(p(0), p(1), p(2), p(3), regime),
            regime,
        )
    }

    /// The energy (J): 0 when the segments are at least `D` apart.
    pub fn energy(&self, q: &[f64; CONTACT_DOFS]) -> f64 {
        let (d, _) = self.distance(q);
        if d >= self.contact_distance {
            return 0.0;
        }
        self.energy_of(q)
    }

    /// Energy (J), gradient (N) and Hessian (N/m) over the 12 unknowns; `None` when no quadrature point
    /// pair is closer than `D` (all zero).
    pub fn derivatives(&self, q: &[f64; CONTACT_DOFS]) -> Option<ContactDerivatives> {
        let (d, _) = self.distance(q);
        if d >= self.contact_distance {
            return None;
        }
        self.derivatives_within(q, true)
    }

    /// The energy (J) of a pair already known to be closer than `D` (no distance test).
    pub fn energy_within(&self, q: &[f64; CONTACT_DOFS]) -> f64 {
        self.energy_of(q)
    }

    /// [`Self::derivatives`] of a pair already known to be closer than `D` (no distance test), in closed
    /// form (module documentation); the Hessian is left zero unless `hessian`.
    pub fn derivatives_within(
        &self,
        q: &[f64; CONTACT_DOFS],
        hessian: bool,
    ) -> Option<ContactDerivatives> {
        let c = self.stiffness * self.rest_lengths[0] * self.rest_lengths[1];
        let inv_d2 = 1.0 / (self.contact_distance * self.contact_distance);
        let mut energy = 0.0;
        let mut g = [0.0; CONTACT_DOFS];
        let mut h = [[0.0; CONTACT_DOFS]; CONTACT_DOFS];
        for (a, [ws, wt], w) in gauss_point_pairs(q) {
            let u = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]) * inv_d2;
            if u >= 1.0 {
                continue;
            }
            let cw = c * ws * wt;
            let (phi, slope, curvature) = self.kernel.value_slope_curvature(u);
            energy += cw * phi;
            // φ'(u) and φ''(u), times the weight.
            let d1 = cw * slope;
            let d2 = cw * curvature;
            // ∂u/∂w = 2w/D².
            let du: [f64; 3] = std::array::from_fn(|k| 2.0 * w[k] * inv_d2);
            for i in 0..4 {
                for k in 0..3 {
                    g[3 * i + k] += d1 * a[i] * du[k];
                }
            }
            if hessian {
                // M = φ'' ∂u/∂w ∂u/∂wᵀ + φ' (2/D²) I; block (i, j) = a_i a_j M.
                let mm: [[f64; 3]; 3] = std::array::from_fn(|k| {
                    std::array::from_fn(|l| {
                        d2 * du[k] * du[l] + if k == l { 2.0 * d1 * inv_d2 } else { 0.0 }
                    })
                });
                for i in 0..4 {
                    for j in 0..4 {
                        let aij = a[i] * a[j];
                        for k in 0..3 {
                            for l in 0..3 {
                                h[3 * i + k][3 * j + l] += aij * mm[k][l];
                            }
                        }
                    }
                }
            }
        }
        (energy > 0.0).then_some((energy, g, h))
    }

    /// The jet (automatic differentiation) form of [`Self::derivatives`], against which the closed form is
    /// tested.
    #[cfg(test)]
    fn derivatives_by_jets(&self, q: &[f64; CONTACT_DOFS]) -> ContactDerivatives {
        value_gradient_hessian(q, |v: &[Jet<CONTACT_DOFS>; CONTACT_DOFS]| self.energy_of(v))
    }

    /// [`Self::derivatives`] with zeros when apart.
    pub fn derivatives_or_zero(&self, q: &[f64; CONTACT_DOFS]) -> ContactDerivatives {
        self.derivatives(q).unwrap_or((
            0.0,
            [0.0; CONTACT_DOFS],
            [[0.0; CONTACT_DOFS]; CONTACT_DOFS],
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::{check_derivatives, flat, random_point, test_contact_pair};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    const R: f64 = 1e-3;

    fn jitter(rng: &mut ChaCha8Rng, q: [f64; 12], s: f64) -> [f64; 12] {
        std::array::from_fn(|i| q[i] + rng.random_range(-s..s))
    }

    fn check(case: &str, q: [f64; 12], expect: fn(ClosestPointCase) -> bool) {
        for kernel in [ContactKernel::Smooth, ContactKernel::Kaldor] {
            check_kernel(case, q, expect, kernel);
        }
    }

    fn check_kernel(
        case: &str,
        q: [f64; 12],
        expect: fn(ClosestPointCase) -> bool,
        kernel: ContactKernel,
    ) {
        let c = ContactPair {
            kernel,
            ..test_contact_pair()
        };
        let (d, regime) = c.distance(&q);
        assert!(expect(regime), "{case}: regime {regime:?}");
        assert!(d < c.contact_distance, "{case}: d = {d}");
        // The closed form equals the jets of the same energy to rounding, and its gradient-only form
        // equals its gradient.
        let (e, g, h) = c.derivatives_or_zero(&q);
        let (ej, gj, hj) = c.derivatives_by_jets(&q);
        let gmax = gj.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let hmax = hj.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!((e - ej).abs() <= 1e-12 * ej.abs(), "{case}: {e} vs {ej}");
        for i in 0..12 {
            assert!((g[i] - gj[i]).abs() <= 1e-11 * gmax, "{case}: g[{i}]");
            for j in 0..12 {
                assert!(
                    (h[i][j] - hj[i][j]).abs() <= 1e-11 * hmax,
                    "{case}: h[{i}][{j}]"
                );
            }
        }
        let (e1, g1, h1) = c.derivatives_within(&q, false).unwrap();
        assert_eq!((e1, g1), (e, g));
        assert!(h1.iter().flatten().all(|v| *v == 0.0));
        assert_eq!(c.energy_within(&q), c.energy(&q));
        let r = check_derivatives(&q, 1e-9, &|q: &[f64; 12]| c.derivatives_or_zero(q));
        eprintln!("FD {case} {kernel:?}: {r:?}");
        assert!(
            r.gradient_error < 1e-6 && r.hessian_error < 1e-5,
            "{case}: {r:?}"
        );
    }

    #[test]
    fn derivatives_match_central_differences_in_every_regime() {
        let mut rng = ChaCha8Rng::seed_from_u64(21);
        let l = 1e-3;
        for _ in 0..4 {
            // Crossing segments: both closest points interior.
            let q = flat([
                [-l / 2.0, 0.0, 0.0],
                [l / 2.0, 0.0, 0.0],
                [0.1 * l, -l / 2.0, 1.3 * R],
                [-0.1 * l, l / 2.0, 1.4 * R],
            ]);
            check("interior-interior", jitter(&mut rng, q, 0.05 * l), |r| {
                r == ClosestPointCase::Interior
            });
            // An end of the second segment over the interior of the first (T shape).
            let q = flat([
                [-l / 2.0, 0.0, 0.0],
                [l / 2.0, 0.0, 0.0],
                [0.1 * l, 0.2 * l, 1.5 * R],
                [0.1 * l, 0.5 * l, 2.0 * l],
            ]);
            check("end-interior", jitter(&mut rng, q, 0.03 * l), |r| {
                matches!(r, ClosestPointCase::TEnd(_) | ClosestPointCase::SEnd(_))
            });
            // End to end.
            let q = flat([
                [-l, 0.0, 0.0],
                [0.0, 0.0, 0.0],
                [0.5 * R, 0.3 * R, 0.2 * R],
                [l, 0.4 * l, 0.1 * l],
            ]);
            check("end-end", jitter(&mut rng, q, 0.02 * R), |r| {
                matches!(r, ClosestPointCase::Ends(..))
            });
            // Parallel and near-parallel, overlapping segments 1.6 r apart, 0 to 1e-2 rad apart in direction.
            for angle in [1e-2, 1e-3, 0.0] {
                let q = flat([
                    [0.0, 0.0, 0.0],
                    [l, 0.0, 0.0],
                    [0.3 * l, 1.6 * R, 0.0],
                    [1.3 * l, 1.6 * R + angle * l, 0.0],
                ]);
                check("near-parallel", q, |r| {
                    matches!(
                        r,
                        ClosestPointCase::SEnd(_)
                            | ClosestPointCase::TEnd(_)
                            | ClosestPointCase::Interior
                    )
                });
            }
        }
    }

    #[test]
    fn no_contact_beyond_the_diameter_and_smooth_switch_on() {
        let c = test_contact_pair();
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        for _ in 0..20 {
            let a = random_point(&mut rng, 1e-3);
            let q = flat([
                a,
                [a[0] + 1e-3, a[1], a[2]],
                [a[0], a[1] + 2.0 * R * 1.01, a[2] - 5e-4],
                [a[0], a[1] + 2.0 * R * 1.01, a[2] + 5e-4],
            ]);
            assert!(c.derivatives(&q).is_none());
            assert_eq!(c.energy(&q), 0.0);
        }
        // Just inside the diameter: energy, force and stiffness all go to zero as d → D (C²).
        let at = |gap: f64| {
            let q = flat([
                [0.0, 0.0, 0.0],
                [1e-3, 0.0, 0.0],
                [5e-4, 2.0 * R - gap, -5e-4],
                [5e-4, 2.0 * R - gap, 5e-4],
            ]);
            c.derivatives_or_zero(&q)
        };
        let (e1, g1, h1) = at(1e-7);
        let (e2, g2, h2) = at(1e-8);
        assert!(e2 < e1 && e1 < 1e-12);
        let gmax = |g: &[f64; 12]| g.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(gmax(&g2) < gmax(&g1) * 0.02);
        assert!(h2[4][4].abs() < h1[4][4].abs() * 0.2);
    }

    #[test]
    fn kernels_match_their_closed_forms_and_differences() {
        // φ, φ', φ'' of both kernels against central differences of φ and φ' over u in (0, 1).
        for kernel in [ContactKernel::Smooth, ContactKernel::Kaldor] {
            for u in [0.05, 0.2, 0.5, 0.8, 0.97] {
                let h = 1e-6 * u;
                let (v, d1, d2) = kernel.value_slope_curvature(u);
                let (vp, d1p, _) = kernel.value_slope_curvature(u + h);
                let (vm, d1m, _) = kernel.value_slope_curvature(u - h);
                assert!(((vp - vm) / (2.0 * h) - d1).abs() <= 1e-6 * d1.abs().max(1.0));
                assert!(((d1p - d1m) / (2.0 * h) - d2).abs() <= 1e-6 * d2.abs().max(1.0));
                assert!(v > 0.0 && d1 < 0.0 && d2 > 0.0, "{kernel:?} {u}");
            }
        }
        // Kaldor's: 1/u + u − 2.
        let (v, _, _) = ContactKernel::Kaldor.value_slope_curvature(0.25);
        assert!((v - (4.0 + 0.25 - 2.0)).abs() < 1e-12);
    }

    #[test]
    fn kaldor_kernel_switches_on_with_zero_force_and_a_stiffness_step() {
        let c = ContactPair {
            kernel: ContactKernel::Kaldor,
            ..test_contact_pair()
        };
        let at = |gap: f64| {
            let q = flat([
                [0.0, 0.0, 0.0],
                [1e-3, 0.0, 0.0],
                [5e-4, 2.0 * R - gap, -5e-4],
                [5e-4, 2.0 * R - gap, 5e-4],
            ]);
            c.derivatives_or_zero(&q)
        };
        let (e1, g1, h1) = at(1e-7);
        let (e2, g2, h2) = at(1e-8);
        // Energy ~ gap², force ~ gap, stiffness → a finite, non-zero limit (C¹, not C²).
        assert!(e2 < e1 * 0.02 && e1 < 1e-9, "{e1} {e2}");
        let gmax = |g: &[f64; 12]| g.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(gmax(&g2) < gmax(&g1) * 0.2);
        assert!(h2[4][4] > 0.5 * h1[4][4] && h1[4][4] > 0.0);
    }
}
