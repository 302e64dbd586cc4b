use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

use skintight_knit::PeriodicPattern;
use skintight_knit::edge_finish::EdgeFinish;
use skintight_knit::frame_sequence::Sequence;
use skintight_knit::patch::PatchModel;

use super::build::bounds;
use super::*;

/// The shared yarn patterns beside the checkout.
fn shared_yarns_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data/yarns")
}

fn scene(scenario: &str, extra: &str) -> YarnScene {
    let text = format!(
        r#"{{"pattern": "stocktiniest_9", "cells": [2, 2], "scenario": "{scenario}",
            "duration_s": 0.0125, "dt_s": 0.0041666666666666666, "frame_rate_hz": 120,
            "newton": {{"max_iterations": 400, "max_factorizations": 2000}},
            "relax_max_iterations": 100 {extra}}}"#
    );
    YarnScene::parse(&text, Path::new("test.json")).unwrap()
}

fn out_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("knit_scene_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

#[test]
fn every_scenario_runs_and_writes_a_readable_sequence() {
    for name in [
        "hang",
        "stretch_uniaxial",
        "stretch_biaxial",
        "shear",
        "drape_sphere",
    ] {
        let s = scene(name, "");
        let path = s.pattern_path(Path::new("/nonexistent"), Some(&shared_yarns_dir()));
        assert!(path.ends_with("stocktiniest_9/pattern.pyp"), "{path:?}");
        let out = out_dir(name);
        let mut seen = Vec::new();
        let result = run(&s, &path, &out, &YarnRunParams::default(), |p| {
            // Frames only (a slow machine may also report the relaxation every 2 s).
            if !p.relaxing {
                seen.push(p.frame);
            }
            ControlFlow::Continue(())
        })
        .unwrap();
        // 3 steps, 2 steps per frame: frames at 0 and step 2, and the last step.
        assert_eq!(result.steps, 3, "{name}");
        assert_eq!(result.frames, 3, "{name}");
        assert_eq!(seen, vec![0, 1, 2], "{name}");
        // The relaxation here is capped short of convergence (the suite stays fast), so the first step still
        // absorbs some of it and may stop short of the tolerance, but close; the others converge. (Pieces of
        // cut yarn held only by frictionless contact, most in the free drape, slow Newton down.)
        assert!(result.unconverged_steps <= 1, "{name}: {result:?}");
        assert!(result.max_residual < 1e-4, "{name}: {result:?}");
        assert!(
            result.min_distance_over_diameter > 0.5,
            "{name}: {result:?}"
        );
        assert_eq!(
            result.prescribed_vertices == 0,
            name == "drape_sphere",
            "{name}"
        );
        let seq = Sequence::open(&out).unwrap();
        assert_eq!(seq.meta.frame_count, 3);
        assert_eq!(seq.meta.scenario, name);
        assert_eq!(seq.meta.vertex_count, result.vertices);
        let last = seq.frame(&out, 2).unwrap();
        assert!((seq.meta.frames[2].time_s - 0.0125).abs() < 1e-12);
        // yarns.obj holds the last frame.
        let obj = std::fs::read_to_string(out.join("yarns.obj")).unwrap();
        let first_v: Vec<f64> = obj
            .lines()
            .find(|l| l.starts_with("v "))
            .unwrap()
            .split_whitespace()
            .skip(1)
            .map(|t| t.parse().unwrap())
            .collect();
        for k in 0..3 {
            assert!((first_v[k] - last[0][k]).abs() < 1e-12);
        }
        let glb = std::fs::read(out.join("yarns.glb")).unwrap();
        assert_eq!(&glb[..4], b"glTF");
        let r: YarnSimulationResult =
            serde_json::from_str(&std::fs::read_to_string(out.join("result.json")).unwrap())
                .unwrap();
        assert_eq!(r.frames, 3);
        std::fs::remove_dir_all(&out).unwrap();
    }
}

#[test]
fn bonded_edges_tie_every_cut_end_and_cut_edges_none() {
    let path = shared_yarns_dir().join("stock_9/pattern.pyp");
    let pattern = PeriodicPattern::read(&path).unwrap();
    let mut s = scene("hang", "");
    s.pattern = "stock_9".into();
    assert_eq!(s.edges, EdgeFinish::Bonded, "bonded is the default");
    let (bonded, _) = patch_model(&s, &pattern).unwrap();
    let ends: std::collections::HashSet<usize> = bonded.bonds().flat_map(|b| b.vertices).collect();
    // Both ends of every open yarn are in a bond (as the cut end, or as the partner of another cut end
    // that is bonded to it already).
    let mut open = 0;
    for (r, y) in bonded.yarn_ranges().iter().zip(&bonded.patch().yarns) {
        if !y.closed {
            open += 1;
            assert!(
                ends.contains(&r.start) && ends.contains(&(r.end - 1)),
                "{r:?}"
            );
        }
    }
    assert!(open > 0 && bonded.bonds().count() > 0);
    s.edges = EdgeFinish::Cut;
    let (cut, _) = patch_model(&s, &pattern).unwrap();
    assert_eq!(cut.bonds().count(), 0);
    // The result reports the finish.
    let mut s = scene("hang", r#", "edges": "cut""#);
    s.duration_s = 1.0 / 240.0;
    s.relax_max_iterations = 0;
    let out = out_dir("cut_edges");
    let r = run(
        &s,
        &s.pattern_path(Path::new("/nonexistent"), Some(&shared_yarns_dir())),
        &out,
        &YarnRunParams::default(),
        |_| ControlFlow::Continue(()),
    )
    .unwrap();
    assert_eq!((r.edges, r.bonds), (EdgeFinish::Cut, 0));
    std::fs::remove_dir_all(&out).unwrap();
}

#[test]
fn grips_move_as_the_scenario_says() {
    let pattern =
        PeriodicPattern::read(&shared_yarns_dir().join("stocktiniest_9/pattern.pyp")).unwrap();
    for (name, check) in [
        ("stretch_uniaxial", 0usize),
        ("shear", 1),
        ("stretch_biaxial", 2),
        ("hang", 3),
    ] {
        let s = scene(name, r#", "strain": 0.3"#);
        let (model, prescribed) = patch_model(&s, &pattern).unwrap();
        let x = model.initial_state();
        let pts = PatchModel::positions(&x);
        let (lo, hi) = bounds(pts.iter());
        let (w, h) = (hi[0] - lo[0], hi[1] - lo[1]);
        assert!(!prescribed.is_empty());
        for p in &prescribed {
            let d: [f64; 3] = std::array::from_fn(|k| p.end[k] - p.start[k]);
            match check {
                0 => assert!(d[0] == 0.0 || (d[0] - 0.3 * w).abs() < 1e-12, "{d:?}"),
                1 => assert!(d[0] == 0.0 || (d[0] - 0.3 * h).abs() < 1e-12, "{d:?}"),
                2 => {
                    let c = (lo[0] + hi[0]) / 2.0;
                    assert!((d[0] - 0.3 * (p.start[0] - c)).abs() < 1e-12, "{d:?}");
                }
                _ => assert_eq!(d, [0.0; 3]),
            }
            assert_eq!(d[2], 0.0);
            assert_eq!(p.ramp_time, s.duration_s);
        }
        if check < 2 {
            assert!(prescribed.iter().any(|p| p.start != p.end), "{name}");
        }
    }
}

#[test]
fn the_patch_lands_on_the_sphere() {
    let mut s = scene("drape_sphere", "");
    s.duration_s = 0.05;
    let path = s.pattern_path(Path::new("/nonexistent"), Some(&shared_yarns_dir()));
    let out = out_dir("drape_long");
    let r = run(&s, &path, &out, &YarnRunParams::default(), |_| {
        ControlFlow::Continue(())
    })
    .unwrap();
    assert!(r.max_sphere_contacts > 0, "{r:?}");
    assert!(r.centre_of_mass_displacement_m[1] < 0.0);
    std::fs::remove_dir_all(&out).unwrap();
}

#[test]
fn bad_scenes_are_named() {
    let cases = [
        (r#""cells": [0, 2]"#, "cells"),
        (r#""cells": [2, 2], "dt_s": -1"#, "dt_s = -1"),
        (r#""cells": [2, 2], "strain": 5"#, "strain = 5"),
        (
            r#""cells": [2, 2], "clamp_band_cells": 1.5"#,
            "clamp_band_cells",
        ),
        (r#""cells": [2, 2], "colour": 1"#, "unknown field `colour`"),
        (
            r#""cells": [2, 2], "edges": "frayed""#,
            "unknown variant `frayed`",
        ),
        (
            r#""cells": [2, 2], "yarn": {"young_modulus": -1}"#,
            "young_modulus",
        ),
        (
            r#""cells": [2, 2], "friction_coefficient": -0.2"#,
            "friction_coefficient = -0.2",
        ),
        (
            r#""cells": [2, 2], "friction_slip": 0"#,
            "friction_slip = 0",
        ),
    ];
    for (fields, expect) in cases {
        let text =
            format!(r#"{{"pattern": "stock_9", "scenario": "hang", "duration_s": 0.1, {fields}}}"#);
        let e = YarnScene::parse(&text, Path::new("scene.json"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(expect) && e.contains("scene.json"),
            "{fields}: {e}"
        );
    }
    let text = r#"{"pattern": "stock_9", "cells": [2, 2], "scenario": "fly", "duration_s": 0.1}"#;
    let e = YarnScene::parse(text, Path::new("scene.json"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("unknown variant `fly`"), "{e}");
    // A missing pattern names the file.
    let s = scene("hang", "");
    let e = run(
        &s,
        Path::new("/nonexistent/pattern.pyp"),
        &out_dir("missing"),
        &YarnRunParams::default(),
        |_| ControlFlow::Continue(()),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("/nonexistent/pattern.pyp"), "{e}");
}

#[test]
fn the_friction_keys_reach_the_stepper_and_default_to_frictionless() {
    let plain = scene("hang", "").time_stepping();
    assert_eq!(plain.friction_coefficient, 0.0);
    assert_eq!(
        plain.friction_slip,
        skintight_knit::implicit_euler::DEFAULT_FRICTION_SLIP
    );
    let s = scene(
        "hang",
        r#", "friction_coefficient": 0.4, "friction_slip": 2e-6"#,
    );
    let p = s.time_stepping();
    assert_eq!((p.friction_coefficient, p.friction_slip), (0.4, 2e-6));
    // Every other setting as without the keys.
    assert_eq!(
        skintight_knit::implicit_euler::ImplicitEulerParams {
            friction_coefficient: 0.0,
            friction_slip: plain.friction_slip,
            ..p
        },
        plain
    );
}

/// Every frame file of the sequence in `dir`, in order.
fn frames_of(dir: &Path) -> Vec<Vec<[f64; 4]>> {
    let seq = Sequence::open(dir).unwrap();
    (0..seq.meta.frame_count)
        .map(|i| seq.frame(dir, i).unwrap())
        .collect()
}

#[test]
fn a_run_stopped_after_a_frame_resumes_to_the_frames_of_an_uninterrupted_run() {
    // 6 steps, 2 a frame: frames 0..=3.
    let mut s = scene("hang", "");
    s.duration_s = 0.025;
    let path = s.pattern_path(Path::new("/nonexistent"), Some(&shared_yarns_dir()));
    let whole = out_dir("resume_whole");
    let full = run(&s, &path, &whole, &YarnRunParams::default(), |_| {
        ControlFlow::Continue(())
    })
    .unwrap();
    assert_eq!(full.frames, 4);
    assert!(
        !YarnRunCheckpoint::path(&whole).exists(),
        "a completed run keeps no checkpoint"
    );

    let parts = out_dir("resume_parts");
    let first = run(&s, &path, &parts, &YarnRunParams::default(), |p| {
        if p.frame == 1 {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    })
    .unwrap();
    assert!(
        first.stopped && first.frames == 2 && first.steps == 2,
        "{first:?}"
    );
    let saved = YarnRunCheckpoint::read(&parts)
        .unwrap()
        .expect("a stopped run keeps its checkpoint");
    assert_eq!((saved.phase, saved.steps), (YarnRunPhase::Stepping, 2));
    // A frame written after the checkpoint by a run that then died is dropped on resume.
    std::fs::copy(
        parts.join("frames/000001.npy"),
        parts.join("frames/000002.npy"),
    )
    .unwrap();

    let mut reported = Vec::new();
    let resume = YarnRunParams {
        resume: true,
        ..YarnRunParams::default()
    };
    let rest = run(&s, &path, &parts, &resume, |p| {
        reported.push(p.frame);
        ControlFlow::Continue(())
    })
    .unwrap();
    assert_eq!(reported, vec![1, 2, 3], "resumed after frame 1");
    assert!(!rest.stopped && !YarnRunCheckpoint::path(&parts).exists());
    assert_eq!(
        (rest.frames, rest.steps, rest.relax_newton_iterations),
        (full.frames, full.steps, full.relax_newton_iterations)
    );
    assert_eq!(
        rest.newton_iterations, full.newton_iterations,
        "{rest:?} {full:?}"
    );
    assert!(rest.seconds >= first.seconds, "the sessions' times add up");
    // The same frames: exactly up to the checkpoint; after it, to rounding (the resumed solver analyzes
    // its sparsity afresh, so its factorization may order the sums differently).
    let (a, b) = (frames_of(&whole), frames_of(&parts));
    assert_eq!(a.len(), b.len());
    assert_eq!(a[..2], b[..2]);
    let r = full.yarn_radius_m;
    for (fa, fb) in a.iter().zip(&b).skip(2) {
        for (va, vb) in fa.iter().zip(fb) {
            for k in 0..3 {
                assert!((va[k] - vb[k]).abs() <= 1e-9 * r, "{va:?} {vb:?}");
            }
        }
    }
    std::fs::remove_dir_all(&whole).unwrap();
    std::fs::remove_dir_all(&parts).unwrap();
}

#[test]
fn a_relaxation_stopped_part_way_resumes_from_its_checkpoint() {
    let mut s = scene("hang", "");
    s.duration_s = 1.0 / 240.0;
    s.relax_max_iterations = 60;
    let path = s.pattern_path(Path::new("/nonexistent"), Some(&shared_yarns_dir()));
    let out = out_dir("resume_relax");
    let every_iteration = YarnRunParams {
        resume: false,
        checkpoint_interval_s: 3600.0,
        relax_progress_interval_s: 0.0,
    };
    let first = run(&s, &path, &out, &every_iteration, |p| {
        if p.relaxing && p.relax_newton_iterations == 10 {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    })
    .unwrap();
    assert!(first.stopped && first.steps == 0, "{first:?}");
    assert_eq!(first.relax_newton_iterations, 10);
    let saved = YarnRunCheckpoint::read(&out)
        .unwrap()
        .expect("written when stopped");
    assert_eq!(
        (saved.phase, saved.relax_newton_iterations),
        (YarnRunPhase::Relaxing, 10)
    );
    // Frame 0 of the stopped run is the state reached, and the checkpoint holds it.
    let f0 = Sequence::open(&out).unwrap().frame(&out, 0).unwrap();
    let x: Vec<f64> = f0.iter().flatten().copied().collect();
    assert_eq!(x, saved.state.x);

    let mut counts = Vec::new();
    let resume = YarnRunParams {
        resume: true,
        ..every_iteration
    };
    let rest = run(&s, &path, &out, &resume, |p| {
        if p.relaxing {
            counts.push(p.relax_newton_iterations);
        }
        ControlFlow::Continue(())
    })
    .unwrap();
    assert_eq!(
        counts.first(),
        Some(&11),
        "the count goes on from the checkpoint"
    );
    assert!(rest.relax_newton_iterations > 10 && rest.relax_newton_iterations <= 60);
    assert_eq!((rest.steps, rest.frames), (1, 2));
    assert!(!rest.stopped && !YarnRunCheckpoint::path(&out).exists());
    std::fs::remove_dir_all(&out).unwrap();
}

#[test]
fn a_checkpoint_of_another_scene_or_a_broken_one_is_refused_by_name() {
    let mut s = scene("hang", "");
    s.duration_s = 0.025;
    let path = s.pattern_path(Path::new("/nonexistent"), Some(&shared_yarns_dir()));
    let out = out_dir("resume_refused");
    run(&s, &path, &out, &YarnRunParams::default(), |p| {
        if p.frame == 1 {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    })
    .unwrap();
    let resume = YarnRunParams {
        resume: true,
        ..YarnRunParams::default()
    };
    let mut other = s.clone();
    other.gravity_m_s2 = 5.0;
    let e = run(&other, &path, &out, &resume, |_| ControlFlow::Continue(()))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("checkpoint.json") && e.contains("another scene"),
        "{e}"
    );
    // A state of the wrong size.
    let mut c = YarnRunCheckpoint::read(&out).unwrap().unwrap();
    c.state.x.pop();
    c.write(&out).unwrap();
    let e = run(&s, &path, &out, &resume, |_| ControlFlow::Continue(()))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("checkpoint.json") && e.contains("unknowns"),
        "{e}"
    );
    // Not JSON.
    std::fs::write(YarnRunCheckpoint::path(&out), "{\"format\": 1").unwrap();
    let e = run(&s, &path, &out, &resume, |_| ControlFlow::Continue(()))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("checkpoint.json") && e.contains("delete it"),
        "{e}"
    );
    // Without --resume the run starts again and the stale checkpoint goes.
    let r = run(&s, &path, &out, &YarnRunParams::default(), |_| {
        ControlFlow::Continue(())
    })
    .unwrap();
    assert_eq!(r.frames, 4);
    assert!(!YarnRunCheckpoint::path(&out).exists());
    std::fs::remove_dir_all(&out).unwrap();
}

/// A measured sample for the stretch test of `stocktiniest_9` (its own scale: yarn radius 0.1 mm).
fn tiny_sample() -> skintight_knit::measured_stretch::MeasuredStretch {
    skintight_knit::measured_stretch::MeasuredStretch {
        source: PathBuf::from("synthetic"),
        fabric_width: 2e-3,
        clamp_distance: 1.8e-3,
        extension: vec![0.1e-3, 0.15e-3, 0.2e-3],
        force: vec![0.001, 0.002, 0.003],
        force_min: vec![0.001, 0.002, 0.003],
        force_max: vec![0.001, 0.002, 0.003],
    }
}

#[test]
fn a_stretch_test_pulls_to_balanced_clamp_forces_whose_work_is_the_energy() {
    let path = shared_yarns_dir().join("stocktiniest_9/pattern.pyp");
    let sample = tiny_sample();
    for direction in [PullDirection::X, PullDirection::Y] {
        let mut spec = StretchTestSpec::new(direction);
        spec.yarn_radius = 1e-4;
        spec.cells_across = 2;
        spec.cells_along = Some(3);
        spec.steps = 5;
        let mut seen = 0;
        let r = run_stretch_test(&spec, &path, &sample, |_| seen += 1).unwrap();
        assert_eq!(seen, 6);
        assert_eq!(r.points.len(), 6);
        assert!(r.converged, "{direction:?}: {:?}", r.points);
        let a = direction.axis();
        assert_eq!(r.cells[a], 3);
        assert_eq!(r.cells[1 - a], 2);
        assert!((r.scale - 1.0).abs() < 1e-6);
        let last = r.points.last().unwrap();
        // The extension maps the clamp displacement onto the sample's clamp distance.
        assert!(
            (last.extension_m - 0.2e-3).abs() < 1e-12,
            "{}",
            last.extension_m
        );
        let fmax = r
            .points
            .iter()
            .map(|p| p.patch_force_n.abs())
            .fold(0.0, f64::max);
        for p in &r.points {
            // At equilibrium the two clamps pull equally and oppositely.
            assert!(
                p.force_imbalance_n.abs() < 1e-3 * fmax,
                "{direction:?}: imbalance {} N of {fmax} N",
                p.force_imbalance_n
            );
            assert!((p.force_n - p.patch_force_n * r.force_factor).abs() < 1e-15);
        }
        // Quasi-static and conservative: the clamp's work (trapezoids) is the energy gained, to 15 %: the
        // trapezoids see five points of a force that jumps a little where crossings change contact (a
        // wrong sign, factor or axis of the force would be off by far more). Pulled further, a crossing of
        // this tiny pattern snaps and the energy drops, which no work balance along the path sees.
        let mut work = 0.0;
        for w in r.points.windows(2) {
            work += 0.5
                * (w[0].patch_force_n + w[1].patch_force_n)
                * (w[1].patch_displacement_m - w[0].patch_displacement_m);
        }
        let gained = last.energy_j - r.points[0].energy_j;
        assert!(
            (work - gained).abs() < 0.15 * gained.abs(),
            "{direction:?}: work {work} J, energy gained {gained} J"
        );
    }
}

#[test]
fn a_stretch_test_names_bad_settings() {
    let path = shared_yarns_dir().join("stocktiniest_9/pattern.pyp");
    let sample = tiny_sample();
    let mut spec = StretchTestSpec::new(PullDirection::X);
    spec.steps = 0;
    let e = run_stretch_test(&spec, &path, &sample, |_| {}).unwrap_err();
    assert!(e.to_string().contains("steps"), "{e}");
    let mut spec = StretchTestSpec::new(PullDirection::X);
    spec.clamp_band_cells = 0.7;
    let e = run_stretch_test(&spec, &path, &sample, |_| {}).unwrap_err();
    assert!(e.to_string().contains("clamp band"), "{e}");
    let spec = StretchTestSpec::new(PullDirection::X);
    let e = run_stretch_test(&spec, Path::new("/nonexistent.pyp"), &sample, |_| {}).unwrap_err();
    assert!(e.to_string().contains("/nonexistent.pyp"), "{e}");
    assert_eq!(
        measured_file(MeasuredKnit::Rib, PullDirection::Y),
        "acrylic_rib_y.csv"
    );
}

#[test]
fn the_stock_9_loop_length_is_what_the_yarn_radius_assumes() {
    let p = PeriodicPattern::read(&shared_yarns_dir().join("stock_9/pattern.pyp")).unwrap();
    let length: f64 = (0..p.len()).map(|i| p.edge_length(i)).sum();
    // 2 yarns, each 2 loops a period (checked: each yarn's height has 2 maxima a period)
    let loop_radii = length / 4.0 / p.radius;
    assert!(
        (loop_radii - STOCK_9_LOOP_RADII).abs() < 0.01 * STOCK_9_LOOP_RADII,
        "{loop_radii}"
    );
    assert!((ACRYLIC_YARN_RADIUS - 0.4294e-3).abs() < 1e-6);
}
