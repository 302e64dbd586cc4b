//! `skintight mesh inspect` and `skintight mesh convert`, run as a user would.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn skintight(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_skintight"))
        .args(args)
        .output()
        .expect("the skintight binary runs")
}

/// `shared/data/bodies` beside the repository root, or in the nearest ancestor that has it (worktrees).
fn body(name: &str) -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let preferred = root.join("../shared/data/bodies");
    let dir = if preferred.is_dir() {
        preferred
    } else {
        root.ancestors()
            .map(|a| a.join("shared/data/bodies"))
            .find(|p| p.is_dir())
            .unwrap_or(preferred)
    };
    dir.join(name)
}

fn stderr_line(out: &Output) -> String {
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert_eq!(err.lines().count(), 1, "stderr is not one line: {err:?}");
    err.trim_end().to_string()
}

const OCTAHEDRON_VERTICES: &str = "v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n";
const OCTAHEDRON_FACES: [&str; 8] = [
    "f 1 3 5", "f 3 2 5", "f 2 4 5", "f 4 1 5", "f 3 1 6", "f 2 3 6", "f 4 2 6", "f 1 4 6",
];

fn octahedron_obj(faces: &[&str], extra: &str) -> String {
    format!("{OCTAHEDRON_VERTICES}{extra}{}\n", faces.join("\n"))
}

fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> String {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p.to_str().unwrap().to_string()
}

#[test]
fn inspect_regular_1k_is_a_usable_body() {
    let path = body("regular_1k.obj");
    let out = skintight(&["mesh", "inspect", path.to_str().unwrap()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    for key in [
        "vertices",
        "faces",
        "closed",
        "manifold",
        "genus",
        "components",
        "area",
        "volume",
        "problems",
    ] {
        assert!(json.get(key).is_some(), "missing key {key}");
    }
    assert_eq!(json["vertices"], 1229);
    assert_eq!(json["faces"], 2454);
    assert_eq!(json["closed"], true);
    assert_eq!(json["manifold"], true);
    assert_eq!(json["genus"], 0);
    assert_eq!(json["components"], 1);
    assert_eq!(json["usable_as_body"], true);
    assert_eq!(json["problems"].as_array().unwrap().len(), 0);
    let v = json["volume"].as_f64().unwrap();
    assert!((v - 0.047).abs() < 0.01 * 0.047, "volume {v}");
}

#[test]
fn open_mesh_fails_naming_the_boundary() {
    let dir = tempfile::tempdir().unwrap();
    let f = write(
        dir.path(),
        "open.obj",
        octahedron_obj(&OCTAHEDRON_FACES[..7], ""),
    );
    let out = skintight(&["mesh", "inspect", &f]);
    assert_eq!(out.status.code(), Some(1));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["closed"], false);
    assert_eq!(json["usable_as_body"], false);
    let line = stderr_line(&out);
    assert!(
        line.starts_with("error: ") && line.contains("open.obj: cannot serve as a body"),
        "{line}"
    );
    assert!(
        line.contains("the surface is open: 3 boundary edges"),
        "{line}"
    );
}

#[test]
fn non_manifold_mesh_fails_naming_the_edge() {
    let dir = tempfile::tempdir().unwrap();
    let mut faces = OCTAHEDRON_FACES.to_vec();
    faces.push("f 1 3 7");
    let f = write(
        dir.path(),
        "fin.obj",
        octahedron_obj(&faces, "v 0.5 0.5 0.5\n"),
    );
    let out = skintight(&["mesh", "inspect", &f]);
    assert_eq!(out.status.code(), Some(1));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["manifold"], false);
    let line = stderr_line(&out);
    assert!(
        line.contains("edge (0, 2) is shared by 3 faces (non-manifold edge)"),
        "{line}"
    );
}

#[test]
fn nan_coordinate_fails_naming_the_vertex() {
    let dir = tempfile::tempdir().unwrap();
    let text = octahedron_obj(&OCTAHEDRON_FACES, "").replace("v 0 0 1", "v 0 nan 1");
    let f = write(dir.path(), "nan.obj", text);
    let out = skintight(&["mesh", "inspect", &f]);
    assert_eq!(out.status.code(), Some(1));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["usable_as_body"], false);
    let line = stderr_line(&out);
    assert!(
        line.contains("vertex 4 has a non-finite coordinate"),
        "{line}"
    );
}

#[test]
fn truncated_binary_stl_is_unreadable() {
    let dir = tempfile::tempdir().unwrap();
    let mut bytes = vec![0u8; 80];
    bytes.extend(4u32.to_le_bytes());
    bytes.extend(vec![0u8; 2 * 50 + 7]); // two and a bit of the four triangles
    let f = write(dir.path(), "cut.stl", &bytes);
    let out = skintight(&["mesh", "inspect", &f]);
    assert_eq!(out.status.code(), Some(2));
    assert!(out.stdout.is_empty());
    let line = stderr_line(&out);
    assert!(
        line.ends_with(
            "binary STL truncated: header says 4 triangles (needs 284 bytes) but file has 191 bytes"
        ),
        "{line}"
    );
}

#[test]
fn bad_obj_line_is_unreadable_and_names_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let text = octahedron_obj(&OCTAHEDRON_FACES, "").replace("f 2 4 5", "f 2 4 9");
    let f = write(dir.path(), "bad.obj", text);
    let out = skintight(&["mesh", "inspect", &f]);
    assert_eq!(out.status.code(), Some(2));
    let line = stderr_line(&out);
    assert!(
        line.contains("bad.obj: OBJ line 9: face refers to vertex 9"),
        "{line}"
    );
}

#[test]
fn missing_file_and_unknown_extension_are_one_line() {
    let out = skintight(&["mesh", "inspect", "/nonexistent/body.obj"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr_line(&out).contains("cannot read /nonexistent/body.obj"));
    let out = skintight(&["mesh", "inspect", "body.xyz"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr_line(&out).contains("cannot tell the mesh format"));
}

#[test]
fn convert_to_every_format_and_inspect_back() {
    let dir = tempfile::tempdir().unwrap();
    let src = body("kid_370.obj");
    for ext in ["glb", "ply", "stl", "obj"] {
        let dst = dir.path().join(format!("kid.{ext}"));
        let out = skintight(&[
            "mesh",
            "convert",
            src.to_str().unwrap(),
            dst.to_str().unwrap(),
        ]);
        assert!(
            out.status.success(),
            "{ext}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let out = skintight(&["mesh", "inspect", dst.to_str().unwrap()]);
        assert!(
            out.status.success(),
            "{ext}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(json["vertices"], 369, "{ext}");
        assert_eq!(json["format"], ext);
    }
}
