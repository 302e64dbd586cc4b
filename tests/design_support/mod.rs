//! Shared set-up of the design tests: the two-panel sleeve (front and back, two side seams) on a coarse
//! procedural cylinder, radius 5 cm, 16 cm long, its core fixed.

#![allow(dead_code)]

/// Both cuffs pinned (the pinned region is everything: every free-boundary vertex).
pub const BOTH_CUFFS: &str = r#", "pinned": { "half_spaces": [] }"#;

/// The sleeve scene as JSON: `pinned` is spliced into the garment (`""` or [`BOTH_CUFFS`]), at cloth
/// edge length `edge_length` (m) and equilibrium tolerance `tolerance`.
pub fn sleeve_scene(pinned: &str, edge_length: f64, tolerance: f64) -> String {
    format!(
        r#"{{
  "body": {{
    "source": {{ "kind": "cylinder", "radius": 0.05, "height": 0.16, "radial_segments": 12, "rings": 3,
                "layers": 8 }},
    "material": {{ "youngs_modulus": 24780.0, "poisson_ratio": 0.49 }},
    "fixed": {{ "kind": "core", "fraction": 0.5 }}
  }},
  "garment": {{
    "panels": [
      {{ "name": "front", "half_spaces": [ {{ "normal": [0, 0, -1], "offset": 0.0 }},
        {{ "normal": [0, 1, 0], "offset": 0.05 }}, {{ "normal": [0, -1, 0], "offset": 0.05 }} ] }},
      {{ "name": "back", "half_spaces": [ {{ "normal": [0, 0, 1], "offset": 0.0 }},
        {{ "normal": [0, 1, 0], "offset": 0.05 }}, {{ "normal": [0, -1, 0], "offset": 0.05 }} ] }}
    ],
    "edge_length": {edge_length},
    "ease": -0.1,
    "fabric": {{ "youngs_modulus": 5400000.0, "poisson_ratio": 0.33, "thickness": 0.0001 }}
    {pinned}
  }},
  "solver": {{ "surface": "loop", "tolerance": {tolerance:e}, "max_iterations": 200, "time_limit_s": 120 }}
}}"#
    )
}

/// Runs `skintight design --quiet` (the binary `exe`) on `job`, written to `dir/job.json`, with outputs in
/// `dir/out`.
pub fn design_cli(
    exe: &str,
    job: &serde_json::Value,
    dir: &std::path::Path,
) -> std::process::Output {
    let file = dir.join("job.json");
    std::fs::write(&file, serde_json::to_vec_pretty(job).unwrap()).unwrap();
    std::process::Command::new(exe)
        .args(["design", "--quiet"])
        .arg(&file)
        .arg("--out")
        .arg(dir.join("out"))
        .output()
        .unwrap()
}

/// A JSON file, parsed.
pub fn read_json(path: &std::path::Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}
