//! `skintight knit cell`, `knit tile`, `knit simulate-yarn`, `knit stretch-test` (its bad input), `knit compare`, `knit homogenize` and `knit simulate` end to end on the shared yarn data.

use std::path::PathBuf;
use std::process::Command;

const EXE: &str = env!("CARGO_BIN_EXE_skintight");

/// `<repo root>/../shared/data/yarns`, or the nearest ancestor's `shared/data/yarns`.
fn yarns_dir() -> PathBuf {
    let conventional = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/yarns"));
    if conventional.is_dir() {
        return conventional;
    }
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .map(|a| a.join("shared/data/yarns"))
        .find(|p| p.is_dir())
        .unwrap_or(conventional)
}

#[test]
fn knit_cell_prints_a_json_report_with_the_comparison() {
    let out = Command::new(EXE)
        .args(["knit", "cell"])
        .arg(yarns_dir().join("stocktiniest_9"))
        .args(["--strain", "0.1666666667,0,0"])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_str(stdout.trim()).unwrap();
    for key in ["normalized_rms", "newton_iterations", "residual", "seconds"] {
        assert!(
            report.get(key).is_some_and(|v| !v.is_null()),
            "{key} missing: {stdout}"
        );
    }
    assert!(report["residual"].as_f64().unwrap() <= 1e-9);
}

#[test]
fn knit_cell_names_a_strain_outside_the_samples_and_a_broken_pattern() {
    let out = Command::new(EXE)
        .args(["knit", "cell"])
        .arg(yarns_dir().join("stocktiniest_9"))
        .args(["--strain", "0,0,1.5"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("strain sy = 1.5 is outside the sampled range [-0.2, 1]"),
        "{stderr}"
    );

    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(yarns_dir().join("stocktiniest_9/pattern.pyp")).unwrap();
    std::fs::write(
        dir.path().join("pattern.pyp"),
        text.replacen("11 12 0 0", "11 40 0 0", 1),
    )
    .unwrap();
    let out = Command::new(EXE)
        .args(["knit", "cell"])
        .arg(dir.path())
        .args(["--strain", "0,0,0"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("pattern.pyp:31:") && stderr.contains("does not exist"),
        "{stderr}"
    );
}

#[test]
fn knit_tile_writes_obj_polylines() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("patch.obj");
    let out = Command::new(EXE)
        .args(["knit", "tile"])
        .arg(yarns_dir().join("stock_9"))
        .args(["--cells", "3,2", "--out"])
        .arg(&obj)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: serde_json::Value =
        serde_json::from_str(String::from_utf8_lossy(&out.stdout).trim()).unwrap();
    assert_eq!(summary["vertices"], 600);
    let text = std::fs::read_to_string(&obj).unwrap();
    assert_eq!(text.lines().filter(|l| l.starts_with("v ")).count(), 600);
    assert_eq!(
        text.lines().filter(|l| l.starts_with("l ")).count() as u64,
        summary["yarns"].as_u64().unwrap()
    );
}

/// `knit simulate-yarn` on a tiny scene: the frame sequence, the last frame as OBJ and glTF (checked with the
/// Khronos validator when `SKINTIGHT_GLTF_VALIDATOR` is set), and `result.json` on stdout.
#[test]
fn knit_simulate_yarn_writes_the_sequence_obj_glb_and_result() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.json");
    std::fs::write(
        &scene,
        r#"{"pattern": "stocktiniest_9", "cells": [2, 2], "scenario": "shear", "strain": 0.1,
            "duration_s": 0.0125, "dt_s": 0.004166666666666667, "frame_rate_hz": 120}"#,
    )
    .unwrap();
    let out = dir.path().join("out");
    let run = Command::new(EXE)
        .args(["knit", "simulate-yarn"])
        .arg(&scene)
        .arg("--out")
        .arg(&out)
        .arg("--yarns-dir")
        .arg(yarns_dir())
        .arg("--progress")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    let result: serde_json::Value =
        serde_json::from_str(String::from_utf8_lossy(&run.stdout).trim()).unwrap();
    assert_eq!(result["frames"], 3, "{result}");
    assert_eq!(result["scenario"], "shear");
    // One line per written frame (and, on a slow machine, relaxation reports every 2 s before them).
    assert_eq!(
        stderr
            .lines()
            .filter(|l| l.contains("\"frame\"") && l.contains("\"relaxing\":false"))
            .count(),
        3,
        "{stderr}"
    );
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("sequence.json")).unwrap()).unwrap();
    assert_eq!(meta["frame_count"], 3);
    for f in meta["frames"].as_array().unwrap() {
        assert!(out.join(f["file"].as_str().unwrap()).is_file(), "{f}");
    }
    assert!(out.join("yarns.obj").is_file() && out.join("result.json").is_file());
    // `knit compare`: the sequence against itself (every frame matched, no error), and against a
    // folder that holds none (exit 2, one line naming it).
    let compare = Command::new(EXE)
        .args(["knit", "compare"])
        .arg(&out)
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        compare.status.success(),
        "{}",
        String::from_utf8_lossy(&compare.stderr)
    );
    let report: serde_json::Value =
        serde_json::from_str(String::from_utf8_lossy(&compare.stdout).trim()).unwrap();
    assert_eq!(report["frames"].as_array().unwrap().len(), 3, "{report}");
    assert_eq!(report["max_mean_error_m"], 0.0, "{report}");
    assert!(report["patch_size_m"].as_f64().unwrap() > 0.0, "{report}");
    let missing = dir.path().join("no-sequence");
    let compare = Command::new(EXE)
        .args(["knit", "compare"])
        .arg(&out)
        .arg(&missing)
        .output()
        .unwrap();
    assert_eq!(compare.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&compare.stderr);
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    assert!(stderr.contains("no-sequence"), "{stderr}");
    // `knit homogenize`: the sequence's one pose (frame 2) fitted in the rank-1 space; the mesh with its
    // material and the summary; bad input named in one line with exit status 2.
    let material = dir.path().join("material");
    let summary = json_of(
        Command::new(EXE)
            .args(["knit", "homogenize"])
            .arg(&out)
            .args(["--ranks", "1", "--out"])
            .arg(&material),
    );
    let written: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(material.join("material.json")).unwrap())
            .unwrap();
    for key in [
        "yarn_dofs",
        "mesh_dofs",
        "elements",
        "voxel_m",
        "patch_size_m",
        "fit_seconds",
    ] {
        assert!(written[key].as_f64().unwrap() > 0.0, "{key}: {written}");
        assert_eq!(written[key], summary[key], "{key}");
    }
    let frames = written["frames"].as_array().unwrap();
    assert_eq!(frames.len(), 1, "{written}");
    let error = frames[0]["mean_error_m"].as_f64().unwrap();
    assert!(
        error.is_finite() && error < 0.05 * written["patch_size_m"].as_f64().unwrap(),
        "{written}"
    );
    assert!(
        written["gauss_newton_iterations"].as_u64().unwrap() > 0,
        "{written}"
    );
    let vtu = std::fs::read_to_string(material.join("mesh.vtu")).unwrap();
    assert!(vtu.contains("gamma_s") && vtu.contains("gamma_v"));
    let plot = std::fs::read_to_string(material.join("fit_error.svg")).unwrap();
    assert!(plot.starts_with("<svg") && plot.contains("<circle") && plot.contains("held out"));
    for name in ["gamma_s.glb", "gamma_v.glb"] {
        let glb = std::fs::read(material.join(name)).unwrap();
        assert_eq!(&glb[..4], b"glTF", "{name}");
        validate_glb(&material.join(name));
    }
    for (args, named) in [
        (vec![missing.to_str().unwrap(), "--out"], "no-sequence"),
        (
            vec![out.to_str().unwrap(), "--train-every", "0", "--out"],
            "train_every",
        ),
        (
            vec![out.to_str().unwrap(), "--ranks", "3,1", "--out"],
            "ranks",
        ),
    ] {
        let run = Command::new(EXE)
            .args(["knit", "homogenize"])
            .args(&args)
            .arg(dir.path().join("bad"))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{args:?}: {stderr}");
        assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
        assert!(stderr.contains(named), "{named}: {stderr}");
    }
    // `knit simulate`: the same scene on the fitted material by projective dynamics, its yarns through
    // V2Y, compared with the yarn-level run frame by frame.
    let homogenized_scene = dir.path().join("homogenized.json");
    let mut scene_json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&scene).unwrap()).unwrap();
    scene_json["material"] = serde_json::json!(material);
    std::fs::write(&homogenized_scene, scene_json.to_string()).unwrap();
    let homogenized = dir.path().join("homogenized");
    let result = json_of(
        Command::new(EXE)
            .args(["knit", "simulate"])
            .arg(&homogenized_scene)
            .arg("--out")
            .arg(&homogenized)
            .arg("--yarns-dir")
            .arg(yarns_dir()),
    );
    assert_eq!(result["frames"], 3, "{result}");
    assert_eq!(result["steps"], 3, "{result}");
    for key in ["dt_s", "seconds", "seconds_per_step"] {
        assert!(result[key].as_f64().unwrap() > 0.0, "{key}: {result}");
    }
    let report = json_of(
        Command::new(EXE)
            .args(["knit", "compare"])
            .arg(&out)
            .arg(&homogenized),
    );
    assert_eq!(report["frames"].as_array().unwrap().len(), 3, "{report}");
    let worst = report["max_mean_error_over_size"].as_f64().unwrap();
    assert!(worst.is_finite() && worst < 0.05, "{report}");
    scene_json.as_object_mut().unwrap().remove("material");
    std::fs::write(&homogenized_scene, scene_json.to_string()).unwrap();
    let run = Command::new(EXE)
        .args(["knit", "simulate"])
        .arg(&homogenized_scene)
        .arg("--out")
        .arg(dir.path().join("bad"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("material"), "{stderr}");
    let glb = std::fs::read(out.join("yarns.glb")).unwrap();
    assert_eq!(&glb[..4], b"glTF");
    validate_glb(&out.join("yarns.glb"));
}

/// Runs `command`, which must succeed, and parses the JSON line it prints.
fn json_of(command: &mut Command) -> serde_json::Value {
    let run = command.output().unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    serde_json::from_str(String::from_utf8_lossy(&run.stdout).trim()).unwrap()
}

/// Checks a `.glb` with the Khronos glTF validator when `SKINTIGHT_GLTF_VALIDATOR` is set (required in CI):
/// no errors, warnings or infos.
fn validate_glb(path: &std::path::Path) {
    match std::env::var_os("SKINTIGHT_GLTF_VALIDATOR").filter(|p| !p.is_empty()) {
        None => {
            assert!(
                std::env::var("CI").as_deref() != Ok("true"),
                "CI=true but SKINTIGHT_GLTF_VALIDATOR is not set (.ci/run installs the glTF validator)"
            );
            eprintln!("note: skipping the glTF validator: SKINTIGHT_GLTF_VALIDATOR is not set");
        }
        Some(validator) => {
            let script =
                std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/gltf_validate.js");
            let check = Command::new("node")
                .arg(script)
                .arg(path)
                .env(
                    "NODE_PATH",
                    std::path::Path::new(&validator).join("node_modules"),
                )
                .output()
                .expect("node runs");
            assert!(
                check.status.success(),
                "{}",
                String::from_utf8_lossy(&check.stderr)
            );
            let report: serde_json::Value =
                serde_json::from_str(String::from_utf8_lossy(&check.stdout).trim()).unwrap();
            for count in ["errors", "warnings", "infos"] {
                assert_eq!(report[count], 0, "{report}");
            }
        }
    }
}

/// `knit simulate-yarn --resume` after the process was killed mid-run: a checkpoint of another scene is
/// refused in one line naming it; the same scene continues after the last checkpointed frame and completes
/// the sequence.
#[test]
fn knit_simulate_yarn_resumes_a_killed_run() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.json");
    let text = r#"{"pattern": "stocktiniest_9", "cells": [2, 2], "scenario": "hang",
            "duration_s": 5, "dt_s": 0.004166666666666667, "frame_rate_hz": 60}"#;
    std::fs::write(&scene, text).unwrap();
    let out = dir.path().join("out");
    let command = |scene: &std::path::Path| {
        let mut c = Command::new(EXE);
        c.args(["knit", "simulate-yarn"])
            .arg(scene)
            .arg("--out")
            .arg(&out)
            .arg("--yarns-dir")
            .arg(yarns_dir());
        c
    };
    let mut child = command(&scene)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let started = std::time::Instant::now();
    while !out.join("frames/000003.npy").is_file() {
        assert!(
            started.elapsed().as_secs() < 300,
            "no third frame after 300 s"
        );
        assert!(child.try_wait().unwrap().is_none(), "the run ended early");
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(out.join("checkpoint.json").is_file());
    assert!(!out.join("result.json").exists(), "killed before the end");

    let other = dir.path().join("other.json");
    std::fs::write(
        &other,
        text.replace(r#""hang""#, r#""hang", "gravity_m_s2": 1"#),
    )
    .unwrap();
    let refused = command(&other).arg("--resume").output().unwrap();
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("checkpoint.json") && stderr.contains("another scene"),
        "{stderr}"
    );
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");

    let resumed = command(&scene)
        .arg("--resume")
        .arg("--progress")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&resumed.stderr);
    assert!(resumed.status.success(), "{stderr}");
    let first: serde_json::Value =
        serde_json::from_str(stderr.lines().next().expect("a progress line")).unwrap();
    assert!(
        first["frame"].as_u64().unwrap() >= 2,
        "resumed after the frames already written: {first}"
    );
    let result: serde_json::Value =
        serde_json::from_str(String::from_utf8_lossy(&resumed.stdout).trim()).unwrap();
    assert_eq!(
        (result["frames"].as_u64(), result["steps"].as_u64()),
        (Some(301), Some(1200))
    );
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("sequence.json")).unwrap()).unwrap();
    assert_eq!(meta["frame_count"], 301);
    assert!(
        !out.join("checkpoint.json").exists(),
        "a completed run keeps none"
    );
}

/// Bad input to `knit simulate-yarn` and `knit tile`: one line naming the problem, exit status 2.
#[test]
fn knit_simulate_yarn_and_tile_name_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.json");
    let cases = [
        (
            r#"{"pattern": "stocktiniest_9", "cells": [2, 2], "scenario": "hang", "duration_s": -1}"#,
            "duration_s = -1",
        ),
        (
            r#"{"pattern": "stocktiniest_9", "cells": [2, 2], "scenario": "twirl", "duration_s": 1}"#,
            "unknown variant `twirl`",
        ),
        (
            r#"{"pattern": "no_such_pattern", "cells": [2, 2], "scenario": "hang", "duration_s": 1}"#,
            "pattern `no_such_pattern` not found",
        ),
    ];
    for (text, expect) in cases {
        std::fs::write(&scene, text).unwrap();
        let run = Command::new(EXE)
            .args(["knit", "simulate-yarn"])
            .arg(&scene)
            .arg("--out")
            .arg(dir.path().join("out"))
            .arg("--yarns-dir")
            .arg(yarns_dir())
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{text}: {stderr}");
        assert!(stderr.contains(expect), "{text}: {stderr}");
        assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    }
    // A pattern with a negative radius is named with its file and line.
    let text = std::fs::read_to_string(yarns_dir().join("stocktiniest_9/pattern.pyp")).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let header = lines
        .iter()
        .position(|l| l.starts_with("*pattern"))
        .unwrap()
        + 1;
    let mut fields: Vec<String> = lines[header].split_whitespace().map(String::from).collect();
    fields[2] = format!("-{}", fields[2]);
    lines[header] = fields.join(" ");
    std::fs::write(dir.path().join("pattern.pyp"), lines.join("\n")).unwrap();
    let run = Command::new(EXE)
        .args(["knit", "tile"])
        .arg(dir.path())
        .args(["--cells", "2,2", "--out"])
        .arg(dir.path().join("p.obj"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("pattern.pyp:") && stderr.contains("radius"),
        "{stderr}"
    );
    // A pattern file without its `*RT` section.
    let without: String = {
        let mut out = Vec::new();
        let mut skip = false;
        for l in text.lines() {
            if l.starts_with('*') {
                skip = l.starts_with("*RT");
            }
            if !skip {
                out.push(l);
            }
        }
        out.join("\n")
    };
    std::fs::write(dir.path().join("pattern.pyp"), without).unwrap();
    let run = Command::new(EXE)
        .args(["knit", "tile"])
        .arg(dir.path())
        .args(["--cells", "2,2", "--out"])
        .arg(dir.path().join("p.obj"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("missing section *RT"), "{stderr}");
}

/// Bad input to `knit stretch-test`: one line naming the flag or file, exit status 2, before any solve.
#[test]
fn knit_stretch_test_names_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let cases: [(&[&str], &str); 5] = [
        (&["--knit", "garter", "--direction", "x"], "--knit `garter`"),
        (&["--knit", "rib", "--direction", "z"], "--direction `z`"),
        (
            &["--knit", "rib", "--direction", "x", "--young-modulus=-1"],
            "--young-modulus -1",
        ),
        (
            &["--knit", "rib", "--direction", "x", "--steps", "0"],
            "steps must be",
        ),
        (
            &[
                "--knit",
                "rib",
                "--direction",
                "x",
                "--data-dir",
                "/nonexistent",
            ],
            "/nonexistent/acrylic_rib_x.csv",
        ),
    ];
    for (args, expect) in cases {
        let run = Command::new(EXE)
            .args(["knit", "stretch-test"])
            .args(args)
            .arg("--out")
            .arg(&out)
            .arg("--yarns-dir")
            .arg(yarns_dir())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(expect), "{args:?}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
    }
}
