//! Yarn–yarn friction over one time step: a lagged, smoothed Coulomb dissipation potential on the
//! quadrature point pairs of the contact law ([`crate::contact`]), the incremental-potential friction of
//! Li et al. 2020 ("Incremental Potential Contact", §5) on Kaldor et al.'s integrated contact:
//!
//! `D(x) = μ Σ_q λ_q f₀(|P_q Δw_q(x)|)`,  `Δw_q(x) = Σᵢ aᵢ (xᵢ − xᵢⁿ)`
//!
//! - `q = (s, t)` runs over the 3 × 3 Gauss point pairs of [`crate::contact`] that touch (`u < 1`) at the
//!   step's start `xⁿ` (the 12 unknowns: two segments' end points, m); `a = (1 − s, s, t − 1, −t)`, so
//!   `Δw_q` (m) is the step's relative displacement of the two centreline points;
//! - lagged at `xⁿ`: the contact normal `n_q = w_q/|w_q|` (`w_q = Σᵢ aᵢ xᵢⁿ`), the projector
//!   `P_q = I − n_q n_qᵀ` onto its tangent plane, and the normal force the contact law exerts there,
//!   `λ_q = |∂E_c,q/∂w| = −C ω_q φ'(u_q) 2|w_q|/D²` (N; `C = k_c ℓ_a ℓ_b`, `ω_q` the Gauss weights,
//!   `φ' < 0` below contact);
//! - `μ` the friction coefficient (dimensionless) and `ε` (m) the slip over which static friction is
//!   smoothed: `f₀(y) = −y³/(3ε²) + y²/ε + ε/3` for `y < ε`, `y` beyond (C², `f₀'(ε) = 1`,
//!   `f₀''(ε) = 0`), so the friction force `−∂D/∂Δw = −μ λ f₀'(y) v̂` is Coulomb's `μ λ` against the slip
//!   `v = P Δw` once `y = |v| ≥ ε` and falls linearly to zero as `y → 0`;
//! - `D` in J. Added to a backward Euler step's incremental potential, its minimiser satisfies the step's
//!   momentum balance with this friction force at the lagged normal forces and directions.
//!
//! Derivatives by hand: `v` is linear in the unknowns, `∂v/∂xᵢ = aᵢ P`, `P v = v`, so
//!
//! `∂D/∂xᵢ = μ λ aᵢ (f₀'(y)/y) v`,  `∂²D/∂xᵢ∂xⱼ = μ λ aᵢ aⱼ [(f₀'(y)/y) P + (f₀''(y) − f₀'(y)/y) v̂ v̂ᵀ]`
//!
//! with `f₀'(y)/y = 2/ε − y/ε²`, `f₀''(y) = 2/ε − 2y/ε²` below `ε` (both `2/ε` at `y = 0`, where the
//! Hessian is `2μλ/ε aᵢ aⱼ P` and `v̂` is not needed) and `1/y`, `0` beyond. Both coefficients are
//! non-negative, so the Hessian is positive semidefinite (eigenvalues `f₀''` along the slip, `f₀'/y`
//! across it in the tangent plane, 0 along the normal). The tests check the closed form against the jets
//! ([`crate::jet`]) and against central differences when sticking, slipping, across `y = ε` and at no
//! slip.
//!
//! The time stepper takes it up through [`crate::patch_friction`]: the pairs in contact at each step's
//! start lagged into [`FrictionPair`]s, their sum one more term of the step's incremental potential (the
//! scenes' `friction_coefficient` and `friction_slip`; default frictionless).

use crate::contact::{CONTACT_DOFS, ContactDerivatives, ContactPair, gauss_point_pairs};
use crate::jet::Scalar;
#[cfg(test)]
use crate::jet::{Jet, value_gradient_hessian};

/// One touching quadrature point pair, lagged at the step's start.
#[derive(Clone, Copy, Debug, PartialEq)]
struct FrictionPoint {
    /// `(1 − s, s, t − 1, −t)`.
    a: [f64; 4],
    /// The contact normal `n` (unit).
    normal: [f64; 3],
    /// `μ λ` (N).
    bound: f64,
}

/// The friction of one segment pair over one time step (module documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct FrictionPair {
    start: [f64; CONTACT_DOFS],
    points: Vec<FrictionPoint>,
    slip: f64,
}

impl FrictionPair {
    /// The friction of the pair `contact` over a step from `start` (the 12 unknowns at `xⁿ`, m) with
    /// coefficient `coefficient` (≥ 0) and smoothing slip `slip` (m, > 0); `Ok(None)` when no quadrature
    /// point pair touches at `start` (or `coefficient` is 0).
    pub fn new(
        contact: &ContactPair,
        start: &[f64; CONTACT_DOFS],
        coefficient: f64,
        slip: f64,
    ) -> Result<Option<Self>, String> {
        if !(coefficient.is_finite() && coefficient >= 0.0) {
            return Err(format!(
                "friction coefficient {coefficient} must be a number ≥ 0"
            ));
        }
        if !(slip.is_finite() && slip > 0.0) {
            return Err(format!("friction slip {slip} m must be > 0"));
        }
        if start.iter().any(|v| !v.is_finite()) {
            return Err("the pair's start state has a non-finite coordinate".into());
        }
        let c = contact.stiffness * contact.rest_lengths[0] * contact.rest_lengths[1];
        let inv_d2 = 1.0 / (contact.contact_distance * contact.contact_distance);
        let mut points = Vec::new();
        for (a, [ws, wt], w) in gauss_point_pairs(start) {
            let len2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
            let u = len2 * inv_d2;
            if u >= 1.0 || len2 == 0.0 {
                continue;
            }
            let len = len2.sqrt();
            let slope = contact.kernel.value_slope_curvature(u).1;
            let force = -c * ws * wt * slope * 2.0 * len * inv_d2;
            if coefficient * force > 0.0 {
                points.push(FrictionPoint {
                    a,
                    normal: w.map(|v| v / len),
                    bound: coefficient * force,
                });
            }
        }
        Ok((!points.is_empty()).then_some(Self {
            start: *start,
            points,
            slip,
        }))
    }

    /// The Coulomb bound `μ Σ_q λ_q` (N): the largest friction force the pair can exert.
    pub fn bound(&self) -> f64 {
        self.points.iter().map(|p| p.bound).sum()
    }

    /// The tangential slip `v = P Δw` (m) of point pair `p` at `x`.
    fn slip_of<S: Scalar>(&self, p: &FrictionPoint, x: &[S; CONTACT_DOFS]) -> [S; 3] {
        let dw: [S; 3] = std::array::from_fn(|k| {
            let mut sum = S::cst(0.0);
            for i in 0..4 {
                sum += (x[3 * i + k] - self.start[3 * i + k]) * p.a[i];
            }
            sum
        });
        let along = dw[0] * p.normal[0] + dw[1] * p.normal[1] + dw[2] * p.normal[2];
        std::array::from_fn(|k| dw[k] - along * p.normal[k])
    }

    fn energy_of<S: Scalar>(&self, x: &[S; CONTACT_DOFS]) -> S {
        let eps = self.slip;
        let mut sum = S::cst(0.0);
        for p in &self.points {
            let v = self.slip_of(p, x);
            let y = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            let f0 = if y.value() < eps {
                y * y * (1.0 / eps) - y * y * y * (1.0 / (3.0 * eps * eps)) + S::cst(eps / 3.0)
            } else {
                y
            };
            sum += f0 * p.bound;
        }
        sum
    }

    /// The dissipation potential `D` (J) at `x`.
    pub fn energy(&self, x: &[f64; CONTACT_DOFS]) -> f64 {
        self.energy_of(x)
    }

    /// `D` (J), its gradient (N) and, if `hessian`, its Hessian (N/m) at `x`, in closed form (module
    /// documentation); the Hessian is left zero otherwise.
    pub fn derivatives(&self, x: &[f64; CONTACT_DOFS], hessian: bool) -> ContactDerivatives {
        let eps = self.slip;
        let mut energy = 0.0;
        let mut g = [0.0; CONTACT_DOFS];
        let mut h = [[0.0; CONTACT_DOFS]; CONTACT_DOFS];
        for p in &self.points {
            let v = self.slip_of(p, x);
            let y = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            // f₀, f₀'/y and f₀''.
            let (f0, f1_over_y, f2) = if y < eps {
                (
                    // As `energy_of` writes it, so that both give the same bits.
                    y * y * (1.0 / eps) - y * y * y * (1.0 / (3.0 * eps * eps)) + eps / 3.0,
                    2.0 / eps - y / (eps * eps),
                    2.0 / eps - 2.0 * y / (eps * eps),
                )
            } else {
                (y, 1.0 / y, 0.0)
            };
            energy += p.bound * f0;
            for i in 0..4 {
                for k in 0..3 {
                    g[3 * i + k] += p.bound * p.a[i] * f1_over_y * v[k];
                }
            }
            if hessian {
                let n = p.normal;
                let vhat = if y > 0.0 { v.map(|c| c / y) } else { [0.0; 3] };
                let m: [[f64; 3]; 3] = std::array::from_fn(|k| {
                    std::array::from_fn(|l| {
                        let projector = f64::from(u8::from(k == l)) - n[k] * n[l];
                        p.bound * (f1_over_y * projector + (f2 - f1_over_y) * vhat[k] * vhat[l])
                    })
                });
                for i in 0..4 {
                    for j in 0..4 {
                        let aij = p.a[i] * p.a[j];
                        for k in 0..3 {
                            for l in 0..3 {
                                h[3 * i + k][3 * j + l] += aij * m[k][l];
                            }
                        }
                    }
                }
            }
        }
        (energy, g, h)
    }

    /// The tangential slips `|P_q Δw_q|` (m) of the point pairs at `x`.
    #[cfg(test)]
    pub(crate) fn slips(&self, x: &[f64; CONTACT_DOFS]) -> Vec<f64> {
        self.points
            .iter()
            .map(|p| {
                let v = self.slip_of(p, x);
                (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
            })
            .collect()
    }

    /// The jet (automatic differentiation) form of [`Self::derivatives`], against which the closed form is
    /// tested (away from zero slip, where the jet of `|v|` is singular).
    #[cfg(test)]
    fn derivatives_by_jets(&self, x: &[f64; CONTACT_DOFS]) -> ContactDerivatives {
        value_gradient_hessian(x, |v: &[Jet<CONTACT_DOFS>; CONTACT_DOFS]| self.energy_of(v))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::{check_derivatives_steps, flat, test_contact_pair};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    const R: f64 = 1e-3;
    const L: f64 = 1e-3;

    /// Two crossing segments 1.4 radii apart (every quadrature point pair within reach at the centre), and
    /// two parallel ones 1.6 radii apart.
    fn starts() -> [[f64; 12]; 2] {
        [
            flat([
                [-L / 2.0, 0.0, 0.0],
                [L / 2.0, 0.0, 0.0],
                [0.05 * L, -L / 2.0, 1.4 * R],
                [-0.05 * L, L / 2.0, 1.4 * R],
            ]),
            flat([
                [0.0, 0.0, 0.0],
                [L, 0.0, 0.0],
                [0.2 * L, 1.6 * R, 0.0],
                [1.2 * L, 1.6 * R, 0.0],
            ]),
        ]
    }

    /// The second segment moved by `d` (m) from `start`, plus a random jitter of size `jitter` (m).
    fn moved(start: &[f64; 12], d: [f64; 3], jitter: f64, rng: &mut ChaCha8Rng) -> [f64; 12] {
        std::array::from_fn(|i| {
            start[i] + if i >= 6 { d[i % 3] } else { 0.0 } + rng.random_range(-jitter..=jitter)
        })
    }

    fn max_abs<'a>(v: impl Iterator<Item = &'a f64>) -> f64 {
        v.fold(0.0f64, |m, x| m.max(x.abs()))
    }

    /// Closed form against the jets (to rounding) and central differences with steps of 10⁻⁵ ε: `f₀'''`
    /// is `−2/ε²` below `ε` and jumps to 0 there, so the Hessian has a kink at `y = ε` whose differences
    /// err by the step over `ε`.
    fn check(case: &str, f: &FrictionPair, x: &[f64; 12], jets: bool) {
        let (e, g, h) = f.derivatives(x, true);
        let (e1, g1, h1) = f.derivatives(x, false);
        assert_eq!((e1, g1), (e, g), "{case}");
        assert!(h1.iter().flatten().all(|v| *v == 0.0), "{case}");
        assert_eq!(f.energy(x), e, "{case}");
        if jets {
            let (ej, gj, hj) = f.derivatives_by_jets(x);
            let (gmax, hmax) = (max_abs(gj.iter()), max_abs(hj.iter().flatten()));
            assert!((e - ej).abs() <= 1e-12 * ej.abs(), "{case}: {e} vs {ej}");
            for i in 0..12 {
                assert!((g[i] - gj[i]).abs() <= 1e-10 * gmax, "{case}: g[{i}]");
                for j in 0..12 {
                    assert!(
                        (h[i][j] - hj[i][j]).abs() <= 1e-10 * hmax,
                        "{case}: h[{i}][{j}] {} vs {}",
                        h[i][j],
                        hj[i][j]
                    );
                }
            }
        }
        let r = check_derivatives_steps(x, &[1e-5 * f.slip; 12], &|x: &[f64; 12]| {
            f.derivatives(x, true)
        });
        assert!(
            r.gradient_error < 1e-6 && r.hessian_error < 1e-5,
            "{case}: {r:?}"
        );
    }

    #[test]
    fn derivatives_match_jets_and_central_differences_sticking_slipping_and_between() {
        let mut rng = ChaCha8Rng::seed_from_u64(31);
        let eps = 1e-6;
        for start in starts() {
            let f = FrictionPair::new(&test_contact_pair(), &start, 0.3, eps)
                .unwrap()
                .expect("touching at the start");
            for trial in 0..3 {
                let dir = [
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    0.2 * rng.random_range(-1.0..1.0),
                ];
                let norm = (dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]).sqrt();
                // A fixed jitter per trial, scaled with the motion: the slips scale with `size`.
                let jitter: [f64; 12] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
                let at = |size: f64| -> [f64; 12] {
                    let d = dir.map(|c| c * size / norm);
                    std::array::from_fn(|i| {
                        start[i] + if i >= 6 { d[i % 3] } else { 0.0 } + 0.02 * size * jitter[i]
                    })
                };
                // Sticking (every slip below ε), slipping (every slip beyond), and across ε: the point
                // pairs' slips differ (rotation and jitter), some below and some beyond.
                check(&format!("stick {trial}"), &f, &at(0.3 * eps), true);
                check(&format!("slip {trial}"), &f, &at(30.0 * eps), true);
                let slips_at = |x: &[f64; 12]| -> Vec<f64> {
                    f.points
                        .iter()
                        .map(|p| {
                            let v = f.slip_of(p, x);
                            (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
                        })
                        .collect()
                };
                // Scaled so that the median slip is ε: the point pairs' slips straddle it.
                let mut probe = slips_at(&at(eps));
                probe.sort_by(f64::total_cmp);
                let across = at(eps * eps / probe[probe.len() / 2]);
                let slips = slips_at(&across);
                check(&format!("across ε {trial}"), &f, &across, true);
                assert!(
                    slips.iter().any(|y| *y < eps) && slips.iter().any(|y| *y > eps),
                    "across ε: {slips:?}"
                );
            }
            // No slip: no force, the Hessian 2μλ/ε Σ aᵢaⱼ P (the central differences straddle y = 0).
            let (e, g, h) = f.derivatives(&start, true);
            assert!((e - f.bound() * eps / 3.0).abs() <= 1e-12 * e);
            assert!(g.iter().all(|v| *v == 0.0));
            // The Hessian is continuous at y = 0 but its slope there depends on the direction (a cone),
            // so the differences' error is of the step's size over ε: a step of 10⁻⁵ ε.
            let r = check_derivatives_steps(&start, &[1e-5 * eps; 12], &|x: &[f64; 12]| {
                f.derivatives(x, true)
            });
            assert!(r.hessian_error < 1e-5, "no slip: {r:?}");
            assert!(max_abs(h.iter().flatten()) > 0.0);
        }
    }

    /// Coulomb: a slip beyond ε pulls the moved segment back with `μ λ` at each point pair, against the
    /// slip's projection on its tangent plane, whatever the slip's size, and pushes the other segment
    /// forward as much; a motion along a point pair's normal meets no friction there; the Hessian is
    /// positive semidefinite.
    #[test]
    fn slipping_gives_coulombs_force_against_the_slip_and_a_semidefinite_hessian() {
        let mut rng = ChaCha8Rng::seed_from_u64(32);
        let eps = 1e-6;
        let [crossing, parallel] = starts();
        for (start, tangent) in [(crossing, [1.0, 0.0, 0.0]), (parallel, [1.0, 0.0, 0.0])] {
            let f = FrictionPair::new(&test_contact_pair(), &start, 0.4, eps)
                .unwrap()
                .unwrap();
            for size in [10.0 * eps, 1e3 * eps] {
                let x = moved(&start, tangent.map(|c| c * size), 0.0, &mut rng);
                let (_, g, h) = f.derivatives(&x, true);
                let on = |from: usize| -> [f64; 3] {
                    std::array::from_fn(|k| g[from + k] + g[from + 3 + k])
                };
                let (moved_side, other) = (on(6), on(0));
                // The gradient is the negative force: at each point pair `μ λ` along the slip's projection
                // on its tangent plane, whatever the slip's size.
                let expected: [f64; 3] = f.points.iter().fold([0.0; 3], |acc, p| {
                    let n = p.normal;
                    let along = tangent[0] * n[0] + tangent[1] * n[1] + tangent[2] * n[2];
                    let pd: [f64; 3] = std::array::from_fn(|k| tangent[k] - along * n[k]);
                    let len = (pd[0] * pd[0] + pd[1] * pd[1] + pd[2] * pd[2]).sqrt();
                    std::array::from_fn(|k| acc[k] + p.bound * pd[k] / len)
                });
                for k in 0..3 {
                    assert!(
                        (moved_side[k] - expected[k]).abs() <= 1e-9 * f.bound(),
                        "{moved_side:?} vs {expected:?}"
                    );
                }
                let magnitude = moved_side.iter().map(|v| v * v).sum::<f64>().sqrt();
                assert!(magnitude <= f.bound() * (1.0 + 1e-12) && magnitude > 0.9 * f.bound());
                assert!((0..3).all(|k| (other[k] + moved_side[k]).abs() <= 1e-9 * f.bound()));
                for _ in 0..20 {
                    let z: [f64; 12] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
                    let zhz: f64 = (0..12)
                        .map(|i| (0..12).map(|j| z[i] * h[i][j] * z[j]).sum::<f64>())
                        .sum();
                    assert!(zhz >= -1e-9 * max_abs(h.iter().flatten()), "{zhz}");
                }
            }
            // Along a point pair's normal: no slip in its tangent plane, no friction.
            let mut one = f.clone();
            one.points.truncate(1);
            let n = one.points[0].normal;
            let x = moved(&start, n.map(|c| c * 0.1 * R), 0.0, &mut rng);
            let (_, g, _) = one.derivatives(&x, false);
            assert!(max_abs(g.iter()) <= 1e-9 * one.bound(), "{g:?}");
        }
    }

    #[test]
    fn apart_or_frictionless_pairs_have_none_and_bad_parameters_are_named() {
        let [crossing, _] = starts();
        let mut apart = crossing;
        for k in [8, 11] {
            apart[k] = 2.5 * R;
        }
        assert_eq!(
            FrictionPair::new(&test_contact_pair(), &apart, 0.3, 1e-6),
            Ok(None)
        );
        assert_eq!(
            FrictionPair::new(&test_contact_pair(), &crossing, 0.0, 1e-6),
            Ok(None)
        );
        for (mu, eps, name) in [
            (-0.1, 1e-6, "coefficient"),
            (f64::NAN, 1e-6, "coefficient"),
            (0.3, 0.0, "slip"),
            (0.3, f64::INFINITY, "slip"),
        ] {
            let err = FrictionPair::new(&test_contact_pair(), &crossing, mu, eps).unwrap_err();
            assert!(err.contains(name), "{err}");
        }
        let mut bad = crossing;
        bad[4] = f64::NAN;
        assert!(FrictionPair::new(&test_contact_pair(), &bad, 0.3, 1e-6).is_err());
    }
}
