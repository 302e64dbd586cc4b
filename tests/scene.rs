//! The scene document through the public API: a scene file whose paths are relative to it, the one-line
//! errors, and the example of docs/SCENE.md.

use std::path::{Path, PathBuf};

use skintight::scene::{
    BodySource, FileResolver, PanelShapeSpec, PathResolver, Scene, SceneError, SurfaceKind,
};

fn bodies_dir() -> Option<PathBuf> {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .map(|a| a.join("shared/data/bodies"))
        .find(|d| d.is_dir())
}

/// The first ```json block of docs/SCENE.md: the complete example.
fn doc_example() -> String {
    let text =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/SCENE.md")).unwrap();
    let start = text.find("```json\n").unwrap() + "```json\n".len();
    let len = text[start..].find("```").unwrap();
    text[start..start + len].to_string()
}

#[test]
fn the_documented_example_parses() {
    let s = Scene::from_json(&doc_example()).unwrap();
    assert_eq!(s.garment.panels.len(), 2);
    assert!(matches!(
        s.garment.panels[0].shape,
        PanelShapeSpec::HalfSpaces(_)
    ));
    assert_eq!(s.solver.surface, SurfaceKind::Loop);
    assert!(matches!(
        s.body.source,
        BodySource::SurfaceMesh { layers: 2, .. }
    ));
    assert!(s.garment.pinned.is_some());
}

#[test]
fn scene_file_paths_are_relative_to_the_file() {
    let Some(bodies) = bodies_dir() else {
        eprintln!("skipped: shared/data/bodies not found");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let scenes = dir.path().join("scenes");
    std::fs::create_dir_all(&scenes).unwrap();
    std::fs::copy(bodies.join("regular_370.obj"), dir.path().join("body.obj")).unwrap();
    let file = scenes.join("scene.json");
    std::fs::write(
        &file,
        r#"{
            "body": {"source": {"kind": "surface_mesh", "path": "../body.obj"}},
            "garment": {"panels": [{"name": "patch", "faces": [0, 1, 2]}], "edge_length": 0.01}
        }"#,
    )
    .unwrap();
    let scene = Scene::from_file(&file).unwrap();
    let body = scene
        .body
        .build(&FileResolver::for_scene_file(&file))
        .unwrap();
    scene.validate_against(&body).unwrap();
    assert_eq!(body.surface_tet_vertex.len(), body.surface.num_vertices());
    assert!(body.report.fixed > 0);
    // The report serializes for the user.
    let report = serde_json::to_value(&body.report).unwrap();
    assert_eq!(report["source"], "surface_mesh");
}

#[test]
fn errors_are_one_line_naming_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("scene.json");
    std::fs::write(
        &file,
        r#"{"body": {"source": {"kind": "cylinder"}},
            "garment": {"panels": [{"name": "a", "half_spaces": []}], "edge_length": 0.01,
                        "fabric": {"poisson_ratio": 0.7}}}"#,
    )
    .unwrap();
    let e = Scene::from_file(&file).unwrap_err();
    assert_eq!(e.key, "garment.fabric.poisson_ratio");
    let line = e.to_string();
    assert!(
        line.starts_with("`garment.fabric.poisson_ratio`: "),
        "{line}"
    );
    assert!(!line.contains('\n'));
    let e = Scene::from_file(&dir.path().join("absent.json")).unwrap_err();
    assert_eq!(e.key, "");
}

#[test]
fn an_asset_resolver_can_stand_in_for_files() {
    let text = r#"{"body": {"source": {"kind": "tet_mesh", "path": "asset-42"},
                            "fixed": {"kind": "region", "half_spaces": [{"normal": [0, 1, 0], "offset": 0}]}},
                   "garment": {"panels": [{"name": "a", "half_spaces": []}], "edge_length": 0.01}}"#;
    let scene = Scene::from_json(text).unwrap();
    let seen = std::cell::RefCell::new(Vec::new());
    let assets = |key: &str, reference: &str| -> Result<PathBuf, SceneError> {
        seen.borrow_mut()
            .push((key.to_string(), reference.to_string()));
        Err(SceneError::new(key, format!("no asset {reference}")))
    };
    let e = scene.body.build(&assets).unwrap_err();
    assert_eq!(e.key, "body.source.path");
    assert_eq!(
        seen.borrow().as_slice(),
        &[("body.source.path".to_string(), "asset-42".to_string())]
    );
    let r: &dyn PathResolver = &FileResolver::new(dir_that_exists());
    assert_eq!(r.resolve("k", "").unwrap_err().key, "k");
}

fn dir_that_exists() -> PathBuf {
    std::env::temp_dir()
}
