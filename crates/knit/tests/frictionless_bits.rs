//! A measurement, not a check: the bits of a few frictionless steps (2 × 2 `stocktiniest_9` relaxed and
//! `stock_9` unrelaxed, hanging from their top rows, 4 steps each, default settings) as one hash per patch,
//! to compare two commits (issue 45: friction wired into the stepper leaves frictionless runs unchanged to
//! the bit). Run at each commit and compare the printed lines (docs/BENCHMARKS.md, issue 45, friction):
//! `cargo test -p skintight-knit --test frictionless_bits -- --ignored --nocapture`.

use skintight_knit::PeriodicPattern;
use skintight_knit::implicit_euler::{ImplicitEuler, ImplicitEulerParams, Prescribed};
use skintight_knit::patch::{PatchLoads, PatchModel};
use skintight_knit::tile::tile;
use skintight_knit::yarn_params::YarnParams;
use std::hash::{Hash, Hasher};

#[test]
#[ignore]
fn fingerprint() {
    let dir =
        std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/yarns");
    for name in ["stocktiniest_9", "stock_9"] {
        let p = PeriodicPattern::read(&dir.join(name).join("pattern.pyp")).unwrap();
        let patch = tile(&p, 2, 2).unwrap();
        let m = PatchModel::new(&patch, &YarnParams::default(), PatchLoads::default()).unwrap();
        let x = m.initial_state();
        let ymax = x.chunks(4).map(|c| c[1]).fold(f64::NEG_INFINITY, f64::max);
        let held: Vec<Prescribed> = x
            .chunks(4)
            .enumerate()
            .filter(|(_, c)| c[1] > ymax - 0.5 * m.radius())
            .map(|(v, c)| Prescribed {
                vertex: v,
                start: [c[0], c[1], c[2]],
                end: [c[0], c[1], c[2]],
                ramp_time: 0.0,
            })
            .collect();
        let params = ImplicitEulerParams::default();
        let mut sim = ImplicitEuler::new(m, params, held).unwrap();
        if name == "stocktiniest_9" {
            sim.relax(&params.newton).unwrap();
        }
        let mut its = 0;
        for _ in 0..4 {
            its += sim.step().unwrap().newton.iterations;
        }
        let mut h = std::collections::hash_map::DefaultHasher::new();
        for v in sim.state().iter().chain(sim.velocity()) {
            v.to_bits().hash(&mut h);
        }
        println!(
            "FINGERPRINT {name}: {:016x} after {its} Newton iterations; x[0] = {:e}",
            h.finish(),
            sim.state()[0]
        );
    }
}
