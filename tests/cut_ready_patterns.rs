//! Issue 17's acceptance on the pants: one `skintight simulate examples/pants.json` writes every pattern file,
//! the seams sew (both sides equal to 0.5 mm, notches at the same arc lengths), and each file reads back with
//! the tool its users use.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

const EXE: &str = env!("CARGO_BIN_EXE_skintight");

/// The pants simulated once for every test of this file (about 40 s).
fn pants() -> &'static Path {
    static OUT: OnceLock<(tempfile::TempDir, PathBuf)> = OnceLock::new();
    &OUT.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("pants");
        let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/pants.json");
        let res = Command::new(EXE)
            .args(["simulate", "--quiet"])
            .arg(&scene)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        assert!(
            res.status.success(),
            "{}",
            String::from_utf8_lossy(&res.stderr)
        );
        (dir, out)
    })
    .1
}

fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

#[test]
fn pants_seams_sew_and_their_notches_match() {
    let out = pants();
    let result = read_json(&out.join("result.json"));
    let seams = result["seams"].as_array().unwrap();
    assert_eq!(seams.len(), 6, "{}", result["seams"]);
    for s in seams {
        let lengths: Vec<f64> = s["lengths_mm"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        let difference = s["difference_mm"].as_f64().unwrap();
        assert!(difference.abs() < 0.5, "{s}");
        assert!((lengths[0] - lengths[1] - difference).abs() < 1e-9);
        assert!(lengths[0] > 150.0, "{s}");
    }
    // The flattening alone left them millimetres apart: truing did the work.
    let truing = &result["seam_truing"];
    assert!(
        truing["max_seam_mismatch_before_mm"].as_f64().unwrap() > 1.0,
        "{truing}"
    );
    assert!(
        truing["max_seam_mismatch_after_mm"].as_f64().unwrap() < 1e-3,
        "{truing}"
    );

    let patterns = read_json(&out.join("patterns.json"));
    assert_eq!(patterns["schema_version"], 1);
    let pieces = patterns["pieces"].as_array().unwrap();
    assert_eq!(pieces.len(), 4);
    for (k, s) in patterns["seams"].as_array().unwrap().iter().enumerate() {
        let arcs: Vec<Vec<f64>> = (0..2)
            .map(|side| {
                let piece = &pieces[s["panels"][side].as_u64().unwrap() as usize];
                piece["notches"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .filter(|n| n["seam"].as_u64() == Some(k as u64))
                    .map(|n| n["arc_length_mm"].as_f64().unwrap())
                    .collect()
            })
            .collect();
        assert_eq!(arcs[0], arcs[1], "seam {k}");
        // Ends plus every 10 cm.
        let length = s["lengths_mm"][0].as_f64().unwrap();
        assert_eq!(
            arcs[0].len(),
            2 + ((length - 50.0) / 100.0).floor() as usize,
            "seam {k}"
        );
    }
    for piece in pieces {
        let names: Vec<&str> = piece["edges"]
            .as_array()
            .unwrap()
            .iter()
            .map(|e| e["name"].as_str().unwrap())
            .collect();
        assert!(
            names.contains(&"top opening") && names.contains(&"bottom opening"),
            "{names:?}"
        );
        let allowance: Vec<f64> = piece["edges"]
            .as_array()
            .unwrap()
            .iter()
            .map(|e| e["allowance_mm"].as_f64().unwrap())
            .collect();
        assert!(
            allowance.contains(&6.0) && allowance.contains(&20.0),
            "{allowance:?}"
        );
    }
}
