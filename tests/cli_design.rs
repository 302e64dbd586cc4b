//! `skintight design` end to end on a small cylinder: the objective falls, every output is written and
//! well formed; bad jobs fail with one line naming the key, exit status 2.

use std::path::Path;
use std::process::Output;

mod design_support;

use design_support::read_json;

const EXE: &str = env!("CARGO_BIN_EXE_skintight");

/// A coarse cylinder sleeve with a tapered shape target (fast enough for the default test suite).
fn job(optimizer: serde_json::Value) -> serde_json::Value {
    serde_json::json!({
        "body": {
            "source": {"kind": "cylinder", "radius": 0.05, "height": 0.16, "radial_segments": 12, "rings": 3,
                       "layers": 8},
            "fixed": {"kind": "core", "fraction": 0.5}
        },
        "garment": {
            "panels": [
                {"name": "front", "half_spaces": [{"normal": [0, 0, -1], "offset": 0.0},
                    {"normal": [0, 1, 0], "offset": 0.05}, {"normal": [0, -1, 0], "offset": 0.05}]},
                {"name": "back", "half_spaces": [{"normal": [0, 0, 1], "offset": 0.0},
                    {"normal": [0, 1, 0], "offset": 0.05}, {"normal": [0, -1, 0], "offset": 0.05}]}
            ],
            "edge_length": 0.015,
            "ease": -0.1,
            // The tapering presses the coarse sleeve's pinned cuffs to ~10 kPa (75 mmHg), beyond the default
            // 60 mmHg: these tests are about the optimizer, so the job states a limit it keeps.
            "fabric": {"youngs_modulus": 5.4e6, "poisson_ratio": 0.33, "thickness": 1e-4,
                       "limits": {"max_pressure_pa": 20000.0}},
            "pinned": {"half_spaces": []}
        },
        "objectives": {
            "shape": {"weight": 1.0, "target": {"kind": "revolution", "profile": [[-0.1, 0.049], [0.1, 0.045]]}}
        },
        "regularizers": {"seam_length": {"weight": 100.0}, "smoothness": {"weight": 1e-6}},
        "optimizer": optimizer
    })
}

fn design(job: &serde_json::Value, dir: &Path) -> Output {
    design_support::design_cli(EXE, job, dir)
}

/// Runs a design that must succeed (else the test fails with its stderr); its `result.json` and
/// `history.json`.
fn designed(job: &serde_json::Value, dir: &Path) -> (serde_json::Value, serde_json::Value) {
    let res = design(job, dir);
    assert!(
        res.status.success(),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    let out = dir.join("out");
    (
        read_json(&out.join("result.json")),
        read_json(&out.join("history.json")),
    )
}

/// `patterns.json` is the versioned pattern model, and every seam sews: its two sides are equally long to
/// 0.5 mm, both pieces name it on an edge of that length, and carry its notches at the same arc lengths.
fn check_seams(patterns: &serde_json::Value) {
    assert_eq!(patterns["schema_version"], 1);
    assert_eq!(patterns["units"], "mm");
    let pieces = patterns["pieces"].as_array().unwrap();
    for (k, seam) in patterns["seams"].as_array().unwrap().iter().enumerate() {
        let lengths: Vec<f64> = seam["lengths_mm"]
            .as_array()
            .unwrap()
            .iter()
            .map(|l| l.as_f64().unwrap())
            .collect();
        assert!(
            (lengths[0] - lengths[1]).abs() < 0.5,
            "seam {k}: {lengths:?} mm"
        );
        let mut arcs = Vec::new();
        for side in 0..2 {
            let piece = &pieces[seam["panels"][side].as_u64().unwrap() as usize];
            let edge = &piece["edges"][seam["edges"][side].as_u64().unwrap() as usize];
            assert_eq!(edge["kind"]["type"], "seam");
            assert!((edge["length_mm"].as_f64().unwrap() - lengths[side]).abs() < 1e-9);
            let mut at: Vec<f64> = piece["notches"]
                .as_array()
                .unwrap()
                .iter()
                .filter(|n| n["seam"].as_u64() == Some(k as u64))
                .map(|n| n["arc_length_mm"].as_f64().unwrap())
                .collect();
            at.sort_by(f64::total_cmp);
            assert!(at.len() >= 2, "seam {k} has notches at its ends");
            arcs.push(at);
        }
        assert_eq!(arcs[0], arcs[1], "seam {k}: notches match");
    }
}

#[test]
fn design_lowers_the_objective_and_writes_every_output() {
    let dir = tempfile::tempdir().unwrap();
    let res = design(
        &job(serde_json::json!({"max_iterations": 6, "mode_levels": [6]})),
        dir.path(),
    );
    assert!(
        res.status.success(),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    let out = dir.path().join("out");
    let result = read_json(&out.join("result.json"));
    let (t0, t1) = (
        result["initial_objective"].as_f64().unwrap(),
        result["final_objective"].as_f64().unwrap(),
    );
    assert!(t1 < 0.8 * t0, "the objective fell from {t0} to {t1}");
    assert_eq!(result["converged"], true);
    assert_eq!(result["optimizer"], "lbfgs");
    assert_eq!(result["remeshes"], 0);
    assert_eq!(result["remesh_seconds"], 0.0);
    assert!(result["iterations"].as_u64().unwrap() >= 1);
    // The final truing's cost is said: the best design's objective before it, solved as tightly, beside
    // the trued design's `final_objective`; only when truing moved the patterns.
    let truing = &result["seam_truing"];
    let before = &truing["objective_before"];
    if truing["iterations"].as_u64().unwrap() > 0 {
        let before = before.as_f64().unwrap();
        assert!(
            before.is_finite() && before > 0.0 && before < t0,
            "{truing}"
        );
    } else {
        assert!(before.is_null(), "{truing}");
    }
    // Within the default fabric limits, said in result.json and the summary.
    assert_eq!(result["admissible"], true, "{}", result["violations"]);
    let stdout = String::from_utf8_lossy(&res.stdout);
    let summary: serde_json::Value = serde_json::from_str(stdout.lines().last().unwrap()).unwrap();
    assert_eq!(summary["admissible"], true);
    let history = read_json(&out.join("history.json"));
    let history = history.as_array().unwrap();
    assert_eq!(history[0]["iteration"], 0);
    let quality = history[0]["min_pattern_quality"].as_f64().unwrap();
    assert!(quality > 0.0 && quality <= 1.0, "{quality}");
    assert!((history[0]["objective"].as_f64().unwrap() - t0).abs() <= 1e-12 * t0);
    for entry in history {
        for key in ["iteration", "objective", "gradient_norm", "seconds"] {
            assert!(entry[key].is_number(), "history entry lacks {key}: {entry}");
        }
    }
    let patterns = read_json(&out.join("patterns.json"));
    let pieces = patterns["pieces"].as_array().unwrap();
    assert_eq!(pieces.len(), 2);
    assert_eq!(pieces[0]["name"], "front");
    let n0 = pieces[0]["sewing_line_mm"].as_array().unwrap().len();
    assert!(n0 > 8);
    assert_eq!(
        patterns["seams"].as_array().unwrap().len(),
        2,
        "the two side seams"
    );
    check_seams(&patterns);
    for file in ["garment.glb", "body.glb", "patterns.svg"] {
        assert!(out.join(file).metadata().unwrap().len() > 0, "{file}");
    }
    // The fitter's report of the final design: its numbers are the design's result.json's.
    let report = std::fs::read_to_string(out.join("report.html")).unwrap();
    let fields = skintight::simulate::report::html::read_back(&report, &result)
        .unwrap_or_else(|e| panic!("report.html: {e}"));
    assert!(fields >= 5, "{fields} fields");
}

/// A design whose final garment is beyond its fabric's limits is written, but never as a success: exit
/// status 4, a last line starting `design: NOT ADMISSIBLE` that names the limit, and `admissible: false` with
/// the violations in result.json and in the summary.
#[test]
fn a_design_beyond_its_fabric_limits_ends_not_admissible_with_status_4() {
    let dir = tempfile::tempdir().unwrap();
    let mut j = job(serde_json::json!({"max_iterations": 2, "mode_levels": [6]}));
    // The sleeve presses with ~2 kPa: a 10 mmHg limit cannot hold.
    j["garment"]["fabric"]["limits"] = serde_json::json!({"max_pressure_pa": 1333.22});
    let res = design(&j, dir.path());
    let stderr = String::from_utf8_lossy(&res.stderr);
    assert_eq!(res.status.code(), Some(4), "{stderr}");
    let last = stderr.lines().last().unwrap();
    assert!(
        last.starts_with("design: NOT ADMISSIBLE") && last.contains("pressure"),
        "{last}"
    );
    let result = read_json(&dir.path().join("out").join("result.json"));
    assert_eq!(result["admissible"], false);
    let violations = result["violations"].as_array().unwrap();
    assert!(!violations.is_empty());
    assert!(
        violations
            .iter()
            .all(|v| v["kind"] == "pressure" && v["value"].as_f64().unwrap() > 1333.22)
    );
    let stdout = String::from_utf8_lossy(&res.stdout);
    let summary: serde_json::Value = serde_json::from_str(stdout.lines().last().unwrap()).unwrap();
    assert_eq!(summary["admissible"], false);
    assert_eq!(summary["violations"], result["violations"]);
}

/// The fabric's stretch limits are a constraint of every design, not only a verdict at the end: with a
/// fabric that bears 8 % around the sleeve, the tapering design that stretches it to ~1.34 when the
/// constraint is off (`optimizer.fabric_limits.weight` 0; it then ends not admissible, exit 4) keeps every
/// course stretch within the limit by default and ends admissible.
#[test]
fn the_fabric_stretch_limits_constrain_the_design_by_default() {
    let course_max = |result: &serde_json::Value| {
        result["elements"]["knit_stretches"]
            .as_array()
            .unwrap()
            .iter()
            .map(|k| k[1].as_f64().unwrap())
            .fold(0.0, f64::max)
    };
    let mut j = job(serde_json::json!({"max_iterations": 6, "mode_levels": [6]}));
    j["garment"]["fabric"]["limits"]["max_stretch"] = serde_json::json!({"course": 1.08});
    let on = tempfile::tempdir().unwrap();
    let res = design(&j, on.path());
    assert!(
        res.status.success(),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    let result = read_json(&on.path().join("out").join("result.json"));
    assert_eq!(result["admissible"], true, "{}", result["violations"]);
    let constrained = course_max(&result);
    assert!(constrained <= 1.08, "{constrained}");
    assert!(
        result["terms"]
            .as_array()
            .unwrap()
            .iter()
            .any(|t| t["name"] == "fabric_stretch_limit"),
        "{}",
        result["terms"]
    );

    j["optimizer"]["fabric_limits"] = serde_json::json!({"weight": 0.0});
    let off = tempfile::tempdir().unwrap();
    let res = design(&j, off.path());
    assert_eq!(
        res.status.code(),
        Some(4),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    let result = read_json(&off.path().join("out").join("result.json"));
    let free = course_max(&result);
    assert!(
        free > 1.2,
        "without the constraint the taper stretches to {free}"
    );
    assert!(
        result["violations"]
            .as_array()
            .unwrap()
            .iter()
            .all(|v| v["kind"] == "stretch_course")
    );
}

/// Remeshing (issue deliverable 6): with a quality bound no moving pattern keeps, every run that lowers
/// the pattern's quality stops, the patterns are remeshed and the design goes on from the re-embedded
/// garment — counted in `remeshes`, the history numbered across the remeshes, the outputs of the final
/// (remeshed) garment consistent.
#[test]
fn design_remeshes_when_the_pattern_degrades_and_goes_on() {
    let dir = tempfile::tempdir().unwrap();
    let res = design(
        &job(serde_json::json!({
            "max_iterations": 8,
            "mode_levels": [6],
            "remesh": {"min_quality": 0.99, "max_remeshes": 2}
        })),
        dir.path(),
    );
    assert!(
        res.status.success(),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    let out = dir.path().join("out");
    let result = read_json(&out.join("result.json"));
    let remeshes = result["remeshes"].as_u64().unwrap();
    assert!((1..=2).contains(&remeshes), "{remeshes} remeshes");
    assert!(result["remesh_seconds"].as_f64().unwrap() > 0.0);
    let (t0, t1) = (
        result["initial_objective"].as_f64().unwrap(),
        result["final_objective"].as_f64().unwrap(),
    );
    assert!(t1 < 0.8 * t0, "the objective fell from {t0} to {t1}");
    assert_eq!(result["converged"], true);
    let history = read_json(&out.join("history.json"));
    let history = history.as_array().unwrap();
    let iterations: Vec<u64> = history
        .iter()
        .map(|e| e["iteration"].as_u64().unwrap())
        .collect();
    assert!(
        iterations.windows(2).all(|w| w[1] == w[0] + 1),
        "{iterations:?}"
    );
    assert_eq!(
        *iterations.last().unwrap(),
        result["iterations"].as_u64().unwrap()
    );
    let counts: Vec<u64> = history
        .iter()
        .map(|e| e["remeshes"].as_u64().unwrap())
        .collect();
    assert!(counts.windows(2).all(|w| w[1] >= w[0]), "{counts:?}");
    assert_eq!(counts[0], 0);
    // The iteration after a remesh: its pattern has the fresh mesh's quality.
    let after = history
        .iter()
        .position(|e| e["remeshes"].as_u64().unwrap() >= 1)
        .expect("an iteration after the remesh (the design went on)");
    let q_before = history[after - 1]["min_pattern_quality"].as_f64().unwrap();
    let q_after = history[after]["min_pattern_quality"].as_f64().unwrap();
    println!(
        "quality {q_before:.3} → {q_after:.3}, remeshes {remeshes}, iterations {iterations:?}"
    );
    assert!(q_after > 0.4, "{q_after}");
    // The outputs describe the remeshed garment: seams one to one on its boundaries.
    let patterns = read_json(&out.join("patterns.json"));
    check_seams(&patterns);
    assert_eq!(
        result["counts"]["cloth_triangles"].as_u64().map(|n| n > 0),
        Some(true),
        "{}",
        result["counts"]
    );
}

#[test]
fn gauss_newton_design_lowers_the_objective_with_either_system_and_reports_its_method() {
    let mut first_steps = Vec::new();
    for system in ["kkt", "reduced"] {
        let dir = tempfile::tempdir().unwrap();
        let res = design(
            &job(serde_json::json!({
                "method": "gauss_newton",
                "gauss_newton_system": system,
                "max_iterations": 4,
                "mode_levels": [6]
            })),
            dir.path(),
        );
        assert!(
            res.status.success(),
            "{system}: {}",
            String::from_utf8_lossy(&res.stderr)
        );
        let out = dir.path().join("out");
        let result = read_json(&out.join("result.json"));
        let (t0, t1) = (
            result["initial_objective"].as_f64().unwrap(),
            result["final_objective"].as_f64().unwrap(),
        );
        assert!(
            t1 < 0.8 * t0,
            "{system}: the objective fell from {t0} to {t1}"
        );
        assert_eq!(result["optimizer"], "gauss_newton");
        let history = read_json(&out.join("history.json"));
        let history = history.as_array().unwrap();
        assert!(history.len() >= 2);
        // Every accepted iteration decreases the objective.
        for w in history.windows(2) {
            assert!(w[1]["objective"].as_f64().unwrap() < w[0]["objective"].as_f64().unwrap());
        }
        first_steps.push(history[1]["objective"].as_f64().unwrap());
    }
    // Both systems give the same direction, so the same first iterate.
    let (a, b) = (first_steps[0], first_steps[1]);
    assert!(
        (a - b).abs() <= 1e-6 * a.abs(),
        "first iterate: KKT {a} vs reduced {b}"
    );
}

#[test]
fn bad_design_jobs_fail_with_one_line_naming_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            {
                let mut j = job(serde_json::json!({}));
                j["objectives"] = serde_json::json!({});
                j
            },
            "`objectives`",
        ),
        (
            {
                let mut j = job(serde_json::json!({}));
                j["objectives"]["stretch"] =
                    serde_json::json!({"weight": 1.0, "min": 1.2, "max": 1.0});
                j
            },
            "`objectives.stretch.max`",
        ),
        (
            job(serde_json::json!({"mode_levels": [8, 4]})),
            "`optimizer.mode_levels[1]`",
        ),
        (job(serde_json::json!({"speed": 3})), "`optimizer.speed`"),
        (
            job(serde_json::json!({"fabric_limits": {"margin": 0.7}})),
            "`optimizer.fabric_limits.margin`",
        ),
        (
            job(serde_json::json!({"fabric_limits": {"weight": -1.0}})),
            "`optimizer.fabric_limits.weight`",
        ),
        (
            job(serde_json::json!({"remesh": {"min_quality": 1.5}})),
            "`optimizer.remesh.min_quality`",
        ),
        (
            job(serde_json::json!({"remesh": {"max_edge_ratio": 0.5}})),
            "`optimizer.remesh.max_edge_ratio`",
        ),
        (
            job(serde_json::json!({"remesh": {"every": 3}})),
            "`optimizer.remesh.every`",
        ),
        (
            job(serde_json::json!({"level_iterations": 0})),
            "`optimizer.level_iterations`",
        ),
        (
            {
                let mut j = job(serde_json::json!({}));
                j["objectives"]["pressure"] = serde_json::json!({"weight": 1e-6});
                j
            },
            "`objectives.pressure`",
        ),
        (
            {
                let mut j = job(serde_json::json!({}));
                j["objectives"]["pressure"] =
                    serde_json::json!({"weight": 1e-6, "target_pa": 900.0, "min_pa": 800.0});
                j
            },
            "`objectives.pressure.target_pa`",
        ),
        (
            {
                let mut j = job(serde_json::json!({}));
                j["objectives"]["pressure"] =
                    serde_json::json!({"weight": 1e-6, "min_pa": 800.0, "max_pa": 700.0});
                j
            },
            "`objectives.pressure.max_pa`",
        ),
        (
            {
                let mut j = job(serde_json::json!({}));
                j["objectives"]["pressure"] = serde_json::json!({"weight": 1e-6, "min_pa": 800.0});
                j
            },
            "`objectives.pressure.max_pa`",
        ),
        (
            {
                let mut j = job(serde_json::json!({}));
                j["objectives"]["pressure"] = serde_json::json!({"weight": 1e-6, "target_pa": 900.0, "negative_weight": -1.0});
                j
            },
            "`objectives.pressure.negative_weight`",
        ),
        (
            {
                let mut j = job(serde_json::json!({}));
                j["objectives"]["pressure"] = serde_json::json!({"weight": 1e-6, "target": 900.0});
                j
            },
            "`objectives.pressure.target`",
        ),
        (
            job(serde_json::json!({"method": "newton"})),
            "`optimizer.method`",
        ),
        (
            job(serde_json::json!({"damping": 1.0})),
            "`optimizer.damping`",
        ),
        (
            job(serde_json::json!({"method": "gauss_newton", "damping": -1.0})),
            "`optimizer.damping`",
        ),
        (
            {
                let mut j = job(serde_json::json!({}));
                j["regularizers"]["pinned_traction"] = serde_json::json!({"weight": -1.0});
                j
            },
            "`regularizers.pinned_traction.weight`",
        ),
        (
            {
                let mut j = job(serde_json::json!({}));
                j["objectives"]["sliding"] = serde_json::json!({"weight": 1.0, "poses": []});
                j
            },
            "`objectives.sliding.poses`",
        ),
        (
            {
                let mut j = job(serde_json::json!({}));
                j["objectives"]["sliding"] = serde_json::json!({"weight": 1.0, "friction_coefficient": -0.5,
                                       "poses": [{"path": "pose.obj"}]});
                j
            },
            "`objectives.sliding.friction_coefficient`",
        ),
        (
            {
                // A triangle is not the body deformed.
                let mut j = job(serde_json::json!({}));
                j["objectives"]["sliding"] =
                    serde_json::json!({"weight": 1.0, "poses": [{"path": "triangle.obj"}]});
                j
            },
            "`objectives.sliding.poses[0].path`",
        ),
        (
            job(serde_json::json!({"level_min_decrease": -0.1})),
            "`optimizer.level_min_decrease`",
        ),
        (
            job(serde_json::json!({"gauss_newton_system": "kkt"})),
            "`optimizer.gauss_newton_system`",
        ),
        (
            job(serde_json::json!({"method": "gauss_newton", "gauss_newton_system": "dense"})),
            "`optimizer.gauss_newton_system`",
        ),
        (
            {
                let mut j = job(serde_json::json!({}));
                j["objectives"]["shape"]["target"] =
                    serde_json::json!({"kind": "mesh", "path": "nowhere.obj"});
                j
            },
            "`objectives.shape.target.path`",
        ),
    ];
    std::fs::write(
        dir.path().join("triangle.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    for (job, key) in cases {
        let res = design(&job, dir.path());
        let stderr = String::from_utf8_lossy(&res.stderr);
        assert_eq!(res.status.code(), Some(2), "{key}: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        let bare = key.trim_matches('`');
        assert!(stderr.contains(bare), "{key} not in: {stderr}");
    }
}

/// Three wedge panels on a coarse procedural sphere (the layout of `examples/design_sphere_pressure.json`,
/// coarser), pressed at about 1.3 kPa; the pressure objective asks for a uniform 1 kPa.
fn sphere_pressure_job() -> serde_json::Value {
    let wedge = |name: &str, a: [f64; 3], b: [f64; 3]| {
        serde_json::json!({"name": name, "half_spaces": [
            {"normal": a, "offset": 0.0}, {"normal": b, "offset": 0.0},
            {"normal": [0, -1, 0], "offset": 0.05}]})
    };
    let (c, h) = (0.866025403784, 0.5);
    serde_json::json!({
        "body": {
            "source": {"kind": "sphere", "radius": 0.1, "resolution": 6},
            "material": {"youngs_modulus": 24780.0, "poisson_ratio": 0.49},
            "fixed": {"kind": "core", "fraction": 0.5}
        },
        "garment": {
            "panels": [
                wedge("wedge_a", [0.0, 0.0, -1.0], [-c, 0.0, -h]),
                wedge("wedge_b", [c, 0.0, h], [c, 0.0, -h]),
                wedge("wedge_c", [-c, 0.0, h], [0.0, 0.0, 1.0])
            ],
            "edge_length": 0.02,
            "ease": -0.07,
            "fabric": {"youngs_modulus": 5.4e6, "poisson_ratio": 0.33, "thickness": 1e-4},
            "pinned": {"half_spaces": [{"normal": [0, 1, 0], "offset": -0.045}]}
        },
        "objectives": {"pressure": {"weight": 1e-6, "target_pa": 1000.0, "negative_weight": 1e-5}},
        "regularizers": {"seam_length": {"weight": 100.0}, "smoothness": {"weight": 1e-6}},
        "optimizer": {"max_iterations": 4, "mode_levels": [6]}
    })
}

#[test]
fn sphere_pressure_design_lowers_the_pressure_objective() {
    let dir = tempfile::tempdir().unwrap();
    let res = design(&sphere_pressure_job(), dir.path());
    assert!(
        res.status.success(),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    let out = dir.path().join("out");
    let result = read_json(&out.join("result.json"));
    let (t0, t1) = (
        result["initial_objective"].as_f64().unwrap(),
        result["final_objective"].as_f64().unwrap(),
    );
    assert!(t1 < 0.8 * t0, "the objective fell from {t0} to {t1}");
    let terms = result["terms"].as_array().unwrap();
    let pressure = terms.iter().find(|t| t["name"] == "pressure").unwrap();
    let per_element = pressure["per_element"].as_array().unwrap();
    let yl = &result["young_laplace_pressure"];
    let per_triangle = yl["per_triangle_pa"].as_array().unwrap();
    assert_eq!(per_element.len(), per_triangle.len());
    let (initial, last) = (&yl["initial"], &yl["final"]);
    for s in [initial, last] {
        let (mean, spread) = (
            s["mean_pa"].as_f64().unwrap(),
            s["spread"].as_f64().unwrap(),
        );
        assert!(mean > 300.0 && mean < 3000.0, "{s}");
        assert!(spread > 0.0 && spread < 1.0, "{s}");
        assert!(s["negative_area_fraction"].as_f64().unwrap() >= 0.0);
    }
    // The initial garment presses too hard on average; the design brings the mean towards 1 kPa.
    let (m0, m1) = (
        initial["mean_pa"].as_f64().unwrap(),
        last["mean_pa"].as_f64().unwrap(),
    );
    assert!(m0 > 1100.0, "{initial}");
    assert!((m1 - 1000.0).abs() < (m0 - 1000.0).abs(), "{m0} → {m1}");
    let history = read_json(&out.join("history.json"));
    for entry in history.as_array().unwrap() {
        assert!(
            entry["young_laplace_spread"].as_f64().unwrap() > 0.0,
            "{entry}"
        );
    }
}

/// With a stretch-window objective, every history entry says how much of the pattern area is inside the
/// window, and the last one (the best design: accepted steps only lower the objective) is what result.json
/// reports for the final garment.
#[test]
fn history_reports_the_window_area_fraction_of_every_iteration() {
    let dir = tempfile::tempdir().unwrap();
    let mut doc = job(serde_json::json!({"method": "gauss_newton", "max_iterations": 3}));
    doc["objectives"] = serde_json::json!({"stretch": {"weight": 1.0, "min": 1.0, "max": 1.1}});
    let (result, history) = designed(&doc, dir.path());
    let history = history.as_array().unwrap();
    assert!(history.len() >= 2);
    let fractions: Vec<f64> = history
        .iter()
        .map(|e| e["window_area_fraction"].as_f64().expect("a fraction"))
        .collect();
    assert!(
        fractions.iter().all(|f| (0.0..=1.0).contains(f)),
        "{fractions:?}"
    );
    assert!(
        fractions.first() != fractions.last(),
        "the design moved stretch into or out of the window: {fractions:?}"
    );
    let last = *fractions.last().unwrap();
    let reported = result["window_area_fraction"]["final"].as_f64().unwrap();
    assert!(
        (last - reported).abs() <= 1e-9,
        "history {last} vs result.json {reported}"
    );
    // Without a stretch objective the fraction is null.
    let dir = tempfile::tempdir().unwrap();
    let (_, history) = designed(&job(serde_json::json!({"max_iterations": 1})), dir.path());
    assert!(history[0]["window_area_fraction"].is_null());
}

/// The coarse sleeve job as a graded order over `bodies` (each entry's keys set on the job's body, plus
/// its `name`), two design iterations.
fn graded(bodies: serde_json::Value) -> serde_json::Value {
    let mut order = job(serde_json::json!({"max_iterations": 2, "mode_levels": [6]}));
    let body = order.as_object_mut().unwrap().remove("body").unwrap();
    let list: Vec<serde_json::Value> = bodies
        .as_array()
        .unwrap()
        .iter()
        .map(|b| {
            let mut e = body.clone();
            for (k, v) in b.as_object().unwrap() {
                e[k] = v.clone();
            }
            e
        })
        .collect();
    order["bodies"] = serde_json::Value::Array(list);
    order
}

/// A graded order (issue 47): every body designed into its own folder with every file, one summary line
/// per body and the order's line last (also `batch.json`), each body's design that of the same job with
/// that body alone.
#[test]
fn a_graded_order_designs_every_body_into_its_folder() {
    let dir = tempfile::tempdir().unwrap();
    let mut order = graded(serde_json::json!([{"name": "slim"}, {"name": "wide"}]));
    order["bodies"][1]["source"]["radius"] = 0.052.into();
    let res = design(&order, dir.path());
    let stderr = String::from_utf8_lossy(&res.stderr);
    assert!(res.status.success(), "{stderr}");
    let stdout = String::from_utf8_lossy(&res.stdout);
    let lines: Vec<serde_json::Value> = stdout
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 3, "{stdout}");
    assert_eq!(lines[0]["body"], "slim");
    assert_eq!(lines[1]["body"], "wide");
    assert_eq!(lines[2]["admissible"], true);
    let out = dir.path().join("out");
    assert_eq!(read_json(&out.join("batch.json")), lines[2]);
    for name in ["slim", "wide"] {
        for file in [
            "result.json",
            "history.json",
            "body.glb",
            "garment.glb",
            "patterns.json",
            "report.html",
        ] {
            assert!(out.join(name).join(file).is_file(), "{name}/{file}");
        }
    }
    // The first body's design is the one-body job's.
    let single = dir.path().join("single");
    std::fs::create_dir_all(&single).unwrap();
    let mut one = job(serde_json::json!({"max_iterations": 2, "mode_levels": [6]}));
    one["body"] = order["bodies"][0].clone();
    one["body"].as_object_mut().unwrap().remove("name");
    let (alone, _) = designed(&one, &single);
    let slim = read_json(&out.join("slim/result.json"));
    assert_eq!(slim["final_objective"], alone["final_objective"]);
    let wide = read_json(&out.join("wide/result.json"));
    assert_ne!(slim["final_objective"], wide["final_objective"]);
}

/// Bad graded orders: one line naming the key (`bodies`, `bodies[i].name`, `bodies[i]…` of a bad body),
/// exit status 2, before any body is designed.
#[test]
fn bad_graded_orders_fail_with_one_line_naming_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let mut both = graded(serde_json::json!([{"name": "a"}]));
    both["body"] = both["bodies"][0].clone();
    let cases = [
        (graded(serde_json::json!([])), "`bodies`"),
        (both, "`bodies`"),
        (
            graded(serde_json::json!([{"name": "a"}, {"name": "a"}])),
            "`bodies[1].name`",
        ),
        (
            graded(serde_json::json!([{"name": "a"}, {"name": "../b"}])),
            "`bodies[1].name`",
        ),
        (
            graded(
                serde_json::json!([{"name": "a"}, {"name": "b", "source": {"kind": "cylinder",
                "radius": -0.05, "height": 0.16, "radial_segments": 12, "rings": 3, "layers": 8}}]),
            ),
            "`bodies[1].source",
        ),
        (
            graded(
                serde_json::json!([{"name": "a"}, {"name": "ghost", "source": {"kind": "surface_mesh",
                "path": "no_such_body.obj", "thickness": 0.02, "layers": 2}, "fixed": null}]),
            ),
            "bodies[1]",
        ),
    ];
    for (order, key) in cases {
        let res = design(&order, dir.path());
        let stderr = String::from_utf8_lossy(&res.stderr);
        assert_eq!(res.status.code(), Some(2), "{key}: {stderr}");
        assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
        assert!(stderr.contains(key), "{key}: {stderr}");
        assert!(
            !dir.path().join("out/a").exists(),
            "{key}: a body was designed"
        );
    }
}
