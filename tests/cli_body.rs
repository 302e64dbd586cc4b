//! `skintight body tetrahedralize`, `pose`, `measure` and `prepare` end to end.

mod mesh_support;
use mesh_support::sphere_obj;
use std::path::PathBuf;
use std::process::Command;

const EXE: &str = env!("CARGO_BIN_EXE_skintight");

/// `<repo root>/../shared/data/bodies`, or the nearest ancestor's `shared/data/bodies` (worktrees sit deeper).
fn bodies_dir() -> PathBuf {
    let conventional = PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../shared/data/bodies"
    ));
    if conventional.is_dir() {
        return conventional;
    }
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .map(|a| a.join("shared/data/bodies"))
        .find(|p| p.is_dir())
        .unwrap_or(conventional)
}

fn tetrahedralize(surface: &std::path::Path, out: &std::path::Path) -> std::process::Output {
    Command::new(EXE)
        .args(["body", "tetrahedralize"])
        .arg(surface)
        .args(["--thickness", "0.02", "--layers", "2", "--out"])
        .arg(out)
        .output()
        .unwrap()
}

fn check_shape(shape: &str) {
    let dir = tempfile::tempdir().unwrap();
    // The output folder does not exist yet: the command creates it.
    let out = dir.path().join("out").join(format!("{shape}.vtu"));
    let res = tetrahedralize(&bodies_dir().join(format!("{shape}_1k.obj")), &out);
    let stderr = String::from_utf8_lossy(&res.stderr);
    assert!(res.status.success(), "{shape}: {stderr}");
    let report: serde_json::Value = serde_json::from_slice(&res.stdout).unwrap();
    eprintln!("{shape}: {report}");
    assert_eq!(report["inverted"], 0, "{shape}");
    assert_eq!(report["surface_preserved"], true, "{shape}");
    assert_eq!(report["self_intersections"], 0, "{shape}");
    assert!(report["min_quality"].as_f64().unwrap() > 0.0);
    let tets = report["tets"].as_u64().unwrap();
    // Three layers of 1229 points, less the two layer points of each vertex where the shell is pinched.
    let pinched = report["pinched_vertices"].as_u64().unwrap();
    assert!(pinched <= 20, "{shape}: {pinched} pinched vertices");
    assert_eq!(report["vertices"].as_u64().unwrap() + 2 * pinched, 3 * 1229);
    assert_eq!(report["fixed_vertices"].as_u64().unwrap(), 1229);
    assert!(report["timing_s"]["total"].as_f64().unwrap() >= 0.0);
    let vtu = std::fs::read_to_string(&out).unwrap();
    assert!(vtu.contains(&format!("NumberOfCells=\"{tets}\"")));
}

#[test]
fn regular_1k_gives_a_valid_body() {
    check_shape("regular");
}

#[test]
fn all_five_1k_shapes_give_valid_bodies() {
    for shape in ["male", "athletic", "overweight", "kid"] {
        check_shape(shape);
    }
}

#[test]
fn missing_file_gives_one_error_line_and_status_2() {
    let dir = tempfile::tempdir().unwrap();
    let res = tetrahedralize(&dir.path().join("nope.obj"), &dir.path().join("x.vtu"));
    assert_eq!(res.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&res.stderr);
    assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
    assert!(
        stderr.starts_with("error: ") && stderr.contains("nope.obj"),
        "{stderr}"
    );
}

#[test]
fn open_mesh_gives_one_error_line_and_status_2() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("open.obj");
    // A tetrahedron's surface with one face missing.
    std::fs::write(
        &obj,
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\n",
    )
    .unwrap();
    let res = tetrahedralize(&obj, &dir.path().join("x.vtu"));
    assert_eq!(res.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&res.stderr);
    assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("open") && stderr.contains("boundary edges"),
        "{stderr}"
    );
}

#[test]
fn pose_bends_the_legs_keeping_the_mesh_and_bad_settings_fail_in_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let body = bodies_dir().join("regular_1k.obj");
    let out = dir.path().join("pose.obj");
    let res = Command::new(EXE)
        .args(["body", "pose"])
        .arg(&body)
        .args([
            "--hip-deg",
            "30",
            "--knee-deg",
            "45",
            "--leg",
            "left",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        res.status.success(),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&res.stdout).unwrap();
    assert!(report["max_displacement_m"].as_f64().unwrap() > 0.1);
    let a = skintight_geometry::mesh::io::read_mesh(&body).unwrap();
    let b = skintight_geometry::mesh::io::read_mesh(&out).unwrap();
    assert_eq!(a.positions.len(), b.positions.len());
    assert_eq!(a.faces, b.faces);
    for args in [vec!["--leg", "middle"], vec!["--hip-deg", "120"]] {
        let res = Command::new(EXE)
            .args(["body", "pose"])
            .arg(&body)
            .args(&args)
            .arg("--out")
            .arg(dir.path().join("bad.obj"))
            .output()
            .unwrap();
        assert_eq!(res.status.code(), Some(2), "{args:?}");
        let stderr = String::from_utf8_lossy(&res.stderr);
        assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
    }
}

#[test]
fn measure_writes_the_landmarks_and_refuses_a_sphere_in_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("m").join("measurements.json");
    let res = Command::new(EXE)
        .args(["body", "measure"])
        .arg(bodies_dir().join("regular_1k.obj"))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        res.status.success(),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&res.stdout).unwrap();
    assert_eq!(summary["landmarks"].as_array().unwrap().len(), 27);
    let file: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    let landmarks = file["landmarks"].as_array().unwrap();
    let find = |name: &str, side: serde_json::Value| {
        landmarks
            .iter()
            .find(|l| l["name"] == name && l["side"] == side)
            .unwrap_or_else(|| panic!("{name} {side}"))
    };
    for l in landmarks {
        for key in ["name", "side", "height_m", "girth_m", "point", "curve"] {
            assert!(l.get(key).is_some(), "{l}: {key}");
        }
        assert!(l["curve"].as_array().unwrap().len() >= 3);
    }
    let girth = |n: &str, s: serde_json::Value| find(n, s)["girth_m"].as_f64().unwrap();
    assert!(girth("B", "left".into()) < girth("C", "left".into()));
    assert!(
        find("waist", serde_json::Value::Null)["height_m"]
            .as_f64()
            .unwrap()
            > 0.8
    );
    // A sphere is no standing body: one line naming what was not found, status 2.
    let sphere = dir.path().join("sphere.obj");
    std::fs::write(&sphere, sphere_obj(0.5)).unwrap();
    let res = Command::new(EXE)
        .args(["body", "measure"])
        .arg(&sphere)
        .arg("--out")
        .arg(dir.path().join("x.json"))
        .output()
        .unwrap();
    assert_eq!(res.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&res.stderr);
    assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
    assert!(stderr.contains("no two legs below the torso"), "{stderr}");
}

fn prepare(scan: &std::path::Path, out: &std::path::Path, extra: &[&str]) -> std::process::Output {
    Command::new(EXE)
        .args(["body", "prepare"])
        .arg(scan)
        .arg("--out")
        .arg(out)
        .args(extra)
        .output()
        .unwrap()
}

/// A raw scan made from the regular 1k body (midpoint-subdivided, noised, holed at soles and crown,
/// islands, non-manifold spots, mm, +z up, binary PLY) comes back as a closed genus-0 body in metres.
#[test]
fn prepare_makes_a_raw_scan_a_body() {
    use skintight_geometry::scan::raw_scan::{RawScanParams, raw_scan_ply};
    let dir = tempfile::tempdir().unwrap();
    let clean =
        skintight_geometry::mesh::io::read_mesh(&bodies_dir().join("regular_1k.obj")).unwrap();
    let scan = dir.path().join("scan.ply");
    let params = RawScanParams {
        smooth: false,
        ..Default::default()
    };
    std::fs::write(&scan, raw_scan_ply(&clean, &params)).unwrap();
    let out = dir.path().join("out").join("body.obj");
    let report_path = dir.path().join("report.json");
    let res = prepare(
        &scan,
        &out,
        &[
            "--target-faces",
            "6000",
            "--report",
            report_path.to_str().unwrap(),
        ],
    );
    let stderr = String::from_utf8_lossy(&res.stderr);
    assert!(res.status.success(), "{stderr}");
    let report: serde_json::Value = serde_json::from_slice(&res.stdout).unwrap();
    for key in [
        "closed",
        "manifold",
        "genus",
        "faces",
        "components_removed",
        "holes_filled",
        "mean_deviation_mm",
        "hausdorff_mm",
        "units",
        "up",
    ] {
        assert!(report.get(key).is_some(), "{key} missing: {report}");
    }
    assert_eq!(report["closed"], true);
    assert_eq!(report["manifold"], true);
    assert_eq!(report["genus"], 0);
    assert_eq!(report["units"], "mm");
    assert_eq!(report["up"], "+z");
    assert!(report["mean_deviation_mm"].as_f64().unwrap() < 2.0);
    assert!(report["timing_s"]["stages"]["remesh"].as_f64().unwrap() >= 0.0);
    let saved: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report_path).unwrap()).unwrap();
    assert_eq!(saved["faces"], report["faces"]);
    // The result serves as a body.
    let tet = tetrahedralize(&out, &dir.path().join("body.vtu"));
    assert!(
        tet.status.success(),
        "{}",
        String::from_utf8_lossy(&tet.stderr)
    );
}

#[test]
fn prepare_refuses_bad_scans_in_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let empty = dir.path().join("empty.obj");
    std::fs::write(&empty, "").unwrap();
    let huge = dir.path().join("huge.ply");
    std::fs::write(
        &huge,
        "ply\nformat binary_little_endian 1.0\nelement vertex 5000002\nproperty float x\nproperty float y\nproperty float z\nelement face 10000000\nproperty list uchar int vertex_indices\nend_header\n",
    )
    .unwrap();
    let giant = dir.path().join("giant.obj");
    let body = std::fs::read_to_string(bodies_dir().join("regular_370.obj")).unwrap();
    let scaled: String = body
        .lines()
        .map(|l| {
            if let Some(rest) = l.strip_prefix("v ") {
                let v: Vec<f64> = rest
                    .split_whitespace()
                    .map(|x| x.parse().unwrap())
                    .collect();
                format!("v {} {} {}\n", 25.0 * v[0], 25.0 * v[1], 25.0 * v[2])
            } else {
                format!("{l}\n")
            }
        })
        .collect();
    std::fs::write(&giant, scaled).unwrap();
    let out = dir.path().join("body.obj");
    for (scan, extra, expect) in [
        (&empty, &[][..], "empty"),
        (&huge, &[][..], "above the limit"),
        (&giant, &[][..], "no reading"),
        (&dir.path().join("missing.ply"), &[][..], "missing.ply"),
        (&empty, &["--units", "inch"][..], "units must be"),
    ] {
        let res = prepare(scan, &out, extra);
        let stderr = String::from_utf8_lossy(&res.stderr);
        assert_eq!(res.status.code(), Some(2), "{expect}: {stderr}");
        assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
        assert!(stderr.contains(expect), "{expect}: {stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
}
