//! `skintight design` end to end on a small cylinder: the objective falls, every output is written and
//! well formed; bad jobs fail with one line naming the key, exit status 2.

use std::path::Path;
use std::process::{Command, Output};

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
            "fabric": {"youngs_modulus": 5.4e6, "poisson_ratio": 0.33, "thickness": 1e-4},
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
    let file = dir.join("job.json");
    std::fs::write(&file, serde_json::to_vec_pretty(job).unwrap()).unwrap();
    Command::new(EXE)
        .args(["design", "--quiet"])
        .arg(&file)
        .arg("--out")
        .arg(dir.join("out"))
        .output()
        .unwrap()
}

fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
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
    assert!(result["iterations"].as_u64().unwrap() >= 1);
    let history = read_json(&out.join("history.json"));
    let history = history.as_array().unwrap();
    assert_eq!(history[0]["iteration"], 0);
    assert!((history[0]["objective"].as_f64().unwrap() - t0).abs() <= 1e-12 * t0);
    for entry in history {
        for key in ["iteration", "objective", "gradient_norm", "seconds"] {
            assert!(entry[key].is_number(), "history entry lacks {key}: {entry}");
        }
    }
    let patterns = read_json(&out.join("patterns.json"));
    let panels = patterns["panels"].as_array().unwrap();
    assert_eq!(panels.len(), 2);
    assert_eq!(panels[0]["name"], "front");
    let n0 = panels[0]["boundary_mm"].as_array().unwrap().len();
    assert!(n0 > 8);
    let seams = patterns["seams"].as_array().unwrap();
    assert_eq!(seams.len(), 2, "the two side seams");
    for seam in seams {
        let sides = seam["boundary_indices"].as_array().unwrap();
        assert_eq!(
            sides[0].as_array().unwrap().len(),
            sides[1].as_array().unwrap().len()
        );
        for (k, side) in sides.iter().enumerate() {
            let panel = seam["panels"][k].as_u64().unwrap() as usize;
            let len = panels[panel]["boundary_mm"].as_array().unwrap().len() as u64;
            assert!(
                side.as_array()
                    .unwrap()
                    .iter()
                    .all(|i| i.as_u64().unwrap() < len)
            );
        }
    }
    for file in ["garment.glb", "body.glb", "patterns.svg"] {
        assert!(out.join(file).metadata().unwrap().len() > 0, "{file}");
    }
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
            {
                let mut j = job(serde_json::json!({}));
                j["objectives"]["shape"]["target"] =
                    serde_json::json!({"kind": "mesh", "path": "nowhere.obj"});
                j
            },
            "`objectives.shape.target.path`",
        ),
    ];
    for (job, key) in cases {
        let res = design(&job, dir.path());
        let stderr = String::from_utf8_lossy(&res.stderr);
        assert_eq!(res.status.code(), Some(2), "{key}: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        let bare = key.trim_matches('`');
        assert!(stderr.contains(bare), "{key} not in: {stderr}");
    }
}
