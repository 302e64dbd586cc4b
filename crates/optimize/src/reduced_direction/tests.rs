use super::*;
use crate::kkt_direction::KktSolver;
use crate::kkt_direction::tests::{dense_direction, random, solve, sparse};
use crate::linearization::Linearization;
use nalgebra::DMatrix;

#[test]
fn reduced_direction_equals_the_dense_and_kkt_directions() {
    for (seed, nr) in [(0_u64, 7), (1, 3), (2, 12), (3, 0)] {
        let p = random(seed, nr);
        let a = sparse(&p.a, false);
        let system = GaussNewtonSystem {
            linearization: &p.linearization,
            parameter_map: a.as_ref(),
            gradient: &p.g,
        };
        let lu = p.h.clone().lu();
        let nq = p.h.nrows();
        let solve_h = |rhs: &mut [Real], columns: usize| {
            let b = DMatrix::from_column_slice(nq, columns, rhs);
            let x = lu.solve(&b).ok_or("singular")?;
            rhs.copy_from_slice(x.as_slice());
            Ok::<(), String>(())
        };
        // K A formed beforehand (matrix-free, as the pattern design does) gives the same direction.
        let ka = &p.k * &p.a;
        let times = Linearization {
            mixed: MixedDerivative::TimesParameterMap(ka.as_slice().to_vec()),
            ..p.linearization.clone()
        };
        let times = GaussNewtonSystem {
            linearization: &times,
            ..system
        };
        for kappa in [1e-3, 1.0, 100.0] {
            let d = reduced_direction(&system, kappa, solve_h).unwrap();
            let e = reduced_direction(&times, kappa, solve_h).unwrap();
            for (a, b) in d.variables.iter().zip(&e.variables) {
                assert!(
                    (a - b).abs() <= 1e-12 * (1.0 + a.abs()),
                    "K A given: {b} vs {a}"
                );
            }
            let expected = dense_direction(&p, kappa);
            let kkt = solve(&mut KktSolver::new(), &p, kappa);
            let scale = expected.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            for ((a, b), c) in d.variables.iter().zip(&expected).zip(&kkt.variables) {
                assert!(
                    (a - b).abs() <= 1e-8 * scale && (a - c).abs() <= 1e-8 * scale,
                    "seed {seed} κ {kappa}: {a} vs dense {b}, KKT {c}"
                );
            }
            for (a, b) in d.state.iter().zip(&kkt.state) {
                assert!((a - b).abs() <= 1e-8 * scale.max(1e-300) * 1e3);
            }
            for (a, b) in d.parameters.iter().zip(&kkt.parameters) {
                assert!((a - b).abs() <= 1e-8 * scale.max(1e-300));
            }
        }
        let short = Linearization {
            mixed: MixedDerivative::TimesParameterMap(ka.as_slice()[1..].to_vec()),
            ..p.linearization.clone()
        };
        let short = GaussNewtonSystem {
            linearization: &short,
            ..system
        };
        assert!(matches!(
            reduced_direction(&short, 1.0, solve_h),
            Err(GaussNewtonError::Invalid(_))
        ));
        assert!(matches!(
            reduced_direction(&system, -1.0, solve_h),
            Err(GaussNewtonError::Invalid(_))
        ));
        assert!(matches!(
            reduced_direction(&system, 1.0, |_, _| Err("no factor".into())),
            Err(GaussNewtonError::Solve(_))
        ));
    }
}
