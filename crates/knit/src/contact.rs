//! Yarn–yarn contact: a smooth penalty on the distance between two rod segments closer than the yarn
//! diameter.
//!
//! `E_c = k_c ℓ_a ℓ_b (1 − d/D)³` for `d < D`, else 0
//!
//! - `d`: the segment–segment distance (m, [`crate::segment_distance`]); `D = 2r` the contact distance (m,
//!   the yarn diameter);
//! - `ℓ_a, ℓ_b`: the two segments' rest lengths (m) — the pair stands for the double integral over the two
//!   yarns' arclengths, as in the yarn-level contact of Kaldor et al. 2008 that HYLC builds on;
//! - `k_c`: the contact stiffness (J/m² = N/m);
//! - `E_c` in J. The cubic makes the energy C² at `d = D` (energy, force and stiffness all vanish there), so
//!   Newton sees no jump when a contact switches on. It is a penalty: it does not by itself prevent
//!   passing through; the stiffness is chosen so that the working penetrations stay small (see
//!   [`crate::yarn_params`]).
//!
//! Unknowns `(p₀, p₁, q₀, q₁)` (12, m). Gradient (N) and Hessian (N/m) by second-order automatic
//! differentiation ([`crate::jet`]) of `E_c(d(p₀, p₁, q₀, q₁))` with the distance in its closed form for the
//! closest-point regime — exact to rounding within the regime; the FD tests cover every regime.

use crate::frames::V3;
use crate::jet::{Jet, Scalar, value_gradient_hessian};
use crate::segment_distance::{Regime, closest_regime, segment_distance};

/// Unknowns of a contact pair: two segments' end points.
pub const CONTACT_DOFS: usize = 12;

/// One pair of segments in contact.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactPair {
    /// Rest lengths `ℓ_a, ℓ_b` of the two segments (m).
    pub rest_lengths: [f64; 2],
    /// Contact distance `D` (m): the yarn diameter.
    pub contact_distance: f64,
    /// Contact stiffness `k_c` (J/m²).
    pub stiffness: f64,
}

impl ContactPair {
    fn energy_of<S: Scalar>(&self, q: &[S; CONTACT_DOFS], regime: Regime) -> S {
        let p = |k: usize| -> V3<S> { [q[3 * k], q[3 * k + 1], q[3 * k + 2]] };
        let d = segment_distance(p(0), p(1), p(2), p(3), regime);
        let x = S::cst(1.0) - d * (1.0 / self.contact_distance);
        x * x * x * (self.stiffness * self.rest_lengths[0] * self.rest_lengths[1])
    }

    /// The distance (m) between the two segments at `q`, and its regime.
    pub fn distance(&self, q: &[f64; CONTACT_DOFS]) -> (f64, Regime) {
        let p = |k: usize| [q[3 * k], q[3 * k + 1], q[3 * k + 2]];
        let (regime, _, _) = closest_regime(p(0), p(1), p(2), p(3));
        (
            segment_distance::<f64>(p(0), p(1), p(2), p(3), regime),
            regime,
        )
    }

    /// The energy (J): 0 when the segments are at least `D` apart.
    pub fn energy(&self, q: &[f64; CONTACT_DOFS]) -> f64 {
        let (d, regime) = self.distance(q);
        if d >= self.contact_distance {
            return 0.0;
        }
        self.energy_of(q, regime)
    }

    /// Energy (J), gradient (N) and Hessian (N/m) over the 12 unknowns; `None` when the segments are at
    /// least `D` apart (all zero).
    #[allow(clippy::type_complexity)]
    pub fn derivatives(
        &self,
        q: &[f64; CONTACT_DOFS],
    ) -> Option<(
        f64,
        [f64; CONTACT_DOFS],
        [[f64; CONTACT_DOFS]; CONTACT_DOFS],
    )> {
        let (d, regime) = self.distance(q);
        if d >= self.contact_distance {
            return None;
        }
        Some(value_gradient_hessian(
            q,
            |v: &[Jet<CONTACT_DOFS>; CONTACT_DOFS]| self.energy_of(v, regime),
        ))
    }

    /// [`Self::derivatives`] with zeros when apart.
    pub fn derivatives_or_zero(
        &self,
        q: &[f64; CONTACT_DOFS],
    ) -> (
        f64,
        [f64; CONTACT_DOFS],
        [[f64; CONTACT_DOFS]; CONTACT_DOFS],
    ) {
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
    use crate::test_support::{check_derivatives, random_point};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    const R: f64 = 1e-3;

    fn pair() -> ContactPair {
        ContactPair {
            rest_lengths: [1.1e-3, 0.9e-3],
            contact_distance: 2.0 * R,
            stiffness: 3.0e4,
        }
    }

    fn flat(p: [[f64; 3]; 4]) -> [f64; 12] {
        std::array::from_fn(|i| p[i / 3][i % 3])
    }

    fn jitter(rng: &mut ChaCha8Rng, q: [f64; 12], s: f64) -> [f64; 12] {
        std::array::from_fn(|i| q[i] + rng.random_range(-s..s))
    }

    fn check(case: &str, q: [f64; 12], expect: fn(Regime) -> bool) {
        let c = pair();
        let (d, regime) = c.distance(&q);
        assert!(expect(regime), "{case}: regime {regime:?}");
        assert!(d < c.contact_distance, "{case}: d = {d}");
        let r = check_derivatives(&q, 1e-9, &|q: &[f64; 12]| c.derivatives_or_zero(q));
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
                r == Regime::Interior
            });
            // An end of the second segment over the interior of the first (T shape).
            let q = flat([
                [-l / 2.0, 0.0, 0.0],
                [l / 2.0, 0.0, 0.0],
                [0.1 * l, 0.2 * l, 1.5 * R],
                [0.1 * l, 0.5 * l, 2.0 * l],
            ]);
            check("end-interior", jitter(&mut rng, q, 0.03 * l), |r| {
                matches!(r, Regime::TEnd(_) | Regime::SEnd(_))
            });
            // End to end.
            let q = flat([
                [-l, 0.0, 0.0],
                [0.0, 0.0, 0.0],
                [0.5 * R, 0.3 * R, 0.2 * R],
                [l, 0.4 * l, 0.1 * l],
            ]);
            check("end-end", jitter(&mut rng, q, 0.02 * R), |r| {
                matches!(r, Regime::Ends(..))
            });
            // Near-parallel, overlapping segments 1.6 r apart, 1e-2 and 1e-3 rad apart in direction.
            for angle in [1e-2, 1e-3] {
                let q = flat([
                    [0.0, 0.0, 0.0],
                    [l, 0.0, 0.0],
                    [0.3 * l, 1.6 * R, 0.0],
                    [1.3 * l, 1.6 * R + angle * l, 0.0],
                ]);
                check("near-parallel", q, |r| {
                    matches!(r, Regime::SEnd(_) | Regime::TEnd(_) | Regime::Interior)
                });
            }
        }
    }

    #[test]
    fn no_contact_beyond_the_diameter_and_smooth_switch_on() {
        let c = pair();
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
}
