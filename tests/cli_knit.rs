//! `skintight knit cell` and `skintight knit tile` end to end on the shared yarn data.

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
