use std::path::PathBuf;

use super::*;

/// The folder `shared/data/bodies` found by walking up from this crate.
pub(crate) fn bodies_dir() -> Option<PathBuf> {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .map(|a| a.join("shared/data/bodies"))
        .find(|d| d.is_dir())
}

fn minimal() -> serde_json::Value {
    serde_json::json!({
        "body": {"source": {"kind": "cylinder"}},
        "garment": {
            "panels": [{"name": "front", "half_spaces": [{"normal": [0, 0, -1], "offset": 0.0}]}],
            "edge_length": 0.01
        }
    })
}

fn err(doc: &serde_json::Value) -> SceneError {
    Scene::from_json(&doc.to_string()).expect_err("the scene must be refused")
}

fn with(mut doc: serde_json::Value, pointer: &str, value: serde_json::Value) -> serde_json::Value {
    let (parent, last) = pointer.rsplit_once('/').unwrap();
    let target = doc.pointer_mut(parent).unwrap();
    match target {
        serde_json::Value::Object(m) => {
            m.insert(last.to_string(), value);
        }
        serde_json::Value::Array(a) => {
            a[last.parse::<usize>().unwrap()] = value;
        }
        _ => panic!("not a container"),
    }
    doc
}

#[test]
fn minimal_scene_gets_the_defaults() {
    let s = Scene::from_json(&minimal().to_string()).unwrap();
    assert_eq!(s.body.material, BodyMaterial::default());
    assert_eq!(s.body.material.youngs_modulus, 24.78e3);
    assert_eq!(s.body.material.poisson_ratio, 0.49);
    assert_eq!(
        s.body.source,
        BodySource::Cylinder(CylinderParams::default())
    );
    assert_eq!(s.body.fixed, None);
    assert_eq!(s.garment.ease, -0.1);
    assert_eq!(s.garment.fabric.youngs_modulus, 5.4e6);
    assert_eq!(s.garment.fabric.poisson_ratio, 0.33);
    assert_eq!(s.garment.fabric.thickness, 1e-4);
    assert_eq!(s.garment.pinned, None);
    assert_eq!(s.solver, SolverSpec::default());
    assert_eq!(s.solver.surface, SurfaceKind::Loop);
    assert_eq!(s.solver.tolerance, 1e-6);
    assert_eq!(s.solver.max_iterations, 200);
    assert_eq!(s.solver.time_limit_s, 600.0);
    let doc = serde_json::json!({
        "body": {"source": {"kind": "surface_mesh", "path": "a.obj"}},
        "garment": {"panels": [{"name": "a", "faces": [1, 2]}], "edge_length": 0.01}
    });
    let s = Scene::from_json(&doc.to_string()).unwrap();
    assert_eq!(
        s.body.source,
        BodySource::SurfaceMesh {
            path: "a.obj".into(),
            thickness: 0.02,
            layers: 2
        }
    );
    assert_eq!(s.garment.panels[0].shape, PanelShapeSpec::Faces(vec![1, 2]));
}

#[test]
fn full_scene_round_trips_through_json() {
    let doc = serde_json::json!({
        "body": {
            "source": {"kind": "sphere", "radius": 0.12, "resolution": 6},
            "material": {"youngs_modulus": 3.0e4, "poisson_ratio": 0.45},
            "fixed": {"kind": "region", "half_spaces": [{"normal": [0, 1, 0], "offset": -0.05}]}
        },
        "garment": {
            "panels": [
                {"name": "front", "half_spaces": [{"normal": [0, 0, -1], "offset": 0.0}]},
                {"name": "back", "faces": [12, 13, 14]}
            ],
            "edge_length": 0.005,
            "ease": -0.05,
            "fabric": {"youngs_modulus": 3.0e7, "poisson_ratio": 0.3, "thickness": 2e-4},
            "pinned": {"half_spaces": [{"normal": [0, -1, 0], "offset": -0.1}]}
        },
        "solver": {"surface": "linear", "tolerance": 1e-8, "max_iterations": 50, "time_limit_s": 30.0}
    });
    let s = Scene::from_json(&doc.to_string()).unwrap();
    assert_eq!(s.solver.surface, SurfaceKind::Linear);
    assert_eq!(
        s.body.fixed,
        Some(FixedSpec::Region {
            half_spaces: vec![HalfSpace::new([0.0, 1.0, 0.0], -0.05)]
        })
    );
    let back = Scene::from_json(&s.to_json()).unwrap();
    assert_eq!(back, s);
    // Every kind of every tagged type survives the trip.
    for (source, fixed) in [
        (
            r#"{"kind": "surface_mesh", "path": "b.obj", "thickness": 0.01, "layers": 3}"#,
            r#"{"kind": "core"}"#,
        ),
        (
            r#"{"kind": "surface_mesh", "path": "b.obj"}"#,
            r#"{"kind": "none"}"#,
        ),
        (
            r#"{"kind": "tet_mesh", "path": "b.msh"}"#,
            r#"{"kind": "region", "half_spaces": [{"normal": [1, 0, 0], "offset": 0}]}"#,
        ),
        (
            r#"{"kind": "cylinder", "radius": 0.04, "height": 0.3, "radial_segments": 12, "rings": 2, "layers": 10}"#,
            r#"{"kind": "core", "fraction": 0.25}"#,
        ),
    ] {
        let text = format!(
            r#"{{"body": {{"source": {source}, "fixed": {fixed}}}, "garment": {{"panels": [{{"name": "a", "half_spaces": []}}], "edge_length": 0.01}}}}"#
        );
        let s = Scene::from_json(&text).unwrap();
        assert_eq!(Scene::from_json(&s.to_json()).unwrap(), s, "{text}");
    }
}

#[test]
fn unknown_keys_are_named() {
    let e = err(&with(minimal(), "/extra", 1.into()));
    assert_eq!(e.key, "extra");
    assert!(e.message.contains("unknown field"), "{e}");
    let e = err(&with(minimal(), "/garment/colour", "red".into()));
    assert_eq!(e.key, "garment.colour");
    let e = err(&with(minimal(), "/garment/panels/0/color", "red".into()));
    assert_eq!(e.key, "garment.panels[0].color");
    let e = err(&with(
        minimal(),
        "/garment/panels/0/half_spaces/0/offst",
        1.into(),
    ));
    assert_eq!(e.key, "garment.panels[0].half_spaces[0].offst");
    let e = err(&with(minimal(), "/body/source/colour", 1.into()));
    assert_eq!(e.key, "body.source.colour");
    // A field of another kind.
    let e = err(&with(minimal(), "/body/source/path", "x.obj".into()));
    assert_eq!(e.key, "body.source.path");
    assert!(e.message.contains("cylinder"), "{e}");
    let e = err(&with(
        minimal(),
        "/body/fixed",
        serde_json::json!({"kind": "region", "fraction": 0.5, "half_spaces": []}),
    ));
    assert_eq!(e.key, "body.fixed.fraction");
    let e = err(&with(
        minimal(),
        "/solver",
        serde_json::json!({"tolerance": 1e-6, "iterations": 3}),
    ));
    assert_eq!(e.key, "solver.iterations");
    assert!(e.to_string().starts_with("`solver.iterations`: "), "{e}");
}

#[test]
fn wrong_types_are_named() {
    let e = err(&with(minimal(), "/garment/edge_length", "small".into()));
    assert_eq!(e.key, "garment.edge_length");
    let e = err(&with(minimal(), "/body/source/radius", "wide".into()));
    assert_eq!(e.key, "body.source.radius");
    let e = err(&with(minimal(), "/body/source/layers", (-3).into()));
    assert_eq!(e.key, "body.source.layers");
    let e = err(&with(minimal(), "/body/source/kind", "cube".into()));
    assert_eq!(e.key, "body.source.kind");
    assert!(e.message.contains("cube"), "{e}");
    let e = err(&with(
        minimal(),
        "/garment/panels/0/half_spaces/0/normal",
        serde_json::json!([0, 1]),
    ));
    assert_eq!(e.key, "garment.panels[0].half_spaces[0].normal");
    let e = err(&with(
        minimal(),
        "/solver",
        serde_json::json!({"surface": "cubic"}),
    ));
    assert_eq!(e.key, "solver.surface");
    let e = err(&with(
        minimal(),
        "/garment/fabric",
        serde_json::json!({"poisson_ratio": "a third"}),
    ));
    assert_eq!(e.key, "garment.fabric.poisson_ratio");
}

#[test]
fn missing_fields_are_named() {
    let mut doc = minimal();
    doc["garment"]
        .as_object_mut()
        .unwrap()
        .remove("edge_length");
    assert_eq!(err(&doc).key, "garment.edge_length");
    let mut doc = minimal();
    doc.as_object_mut().unwrap().remove("body");
    assert_eq!(err(&doc).key, "body");
    let doc = with(
        minimal(),
        "/body/source",
        serde_json::json!({"kind": "tet_mesh"}),
    );
    assert_eq!(err(&doc).key, "body.source.path");
    let doc = with(
        minimal(),
        "/body/source",
        serde_json::json!({"radius": 0.1}),
    );
    assert_eq!(err(&doc).key, "body.source.kind");
    let doc = with(
        minimal(),
        "/body/fixed",
        serde_json::json!({"kind": "region"}),
    );
    assert_eq!(err(&doc).key, "body.fixed.half_spaces");
    let doc = with(
        minimal(),
        "/garment/panels/0",
        serde_json::json!({"name": "front"}),
    );
    let e = err(&doc);
    assert_eq!(e.key, "garment.panels[0].half_spaces");
    assert!(e.message.contains("either"), "{e}");
    let doc = with(
        minimal(),
        "/garment/panels/0",
        serde_json::json!({"name": "front", "faces": [1], "half_spaces": []}),
    );
    let e = err(&doc);
    assert_eq!(e.key, "garment.panels[0].faces");
    assert!(e.message.contains("exactly one"), "{e}");
}

#[test]
fn malformed_json_has_an_empty_key() {
    let e = Scene::from_json("{\"body\": ").unwrap_err();
    assert_eq!(e.key, "");
    assert!(e.message.contains("not valid JSON"), "{e}");
    assert!(!e.to_string().starts_with('`'));
}

#[test]
fn impossible_values_are_named() {
    let cases: Vec<(&str, serde_json::Value, &str)> = vec![
        (
            "/body/material/youngs_modulus",
            (-1.0).into(),
            "body.material.youngs_modulus",
        ),
        (
            "/body/material/youngs_modulus",
            0.0.into(),
            "body.material.youngs_modulus",
        ),
        (
            "/body/material/poisson_ratio",
            0.5.into(),
            "body.material.poisson_ratio",
        ),
        (
            "/body/material/poisson_ratio",
            (-1.0).into(),
            "body.material.poisson_ratio",
        ),
        (
            "/garment/fabric/poisson_ratio",
            0.5.into(),
            "garment.fabric.poisson_ratio",
        ),
        (
            "/garment/fabric/poisson_ratio",
            (-0.1).into(),
            "garment.fabric.poisson_ratio",
        ),
        (
            "/garment/fabric/youngs_modulus",
            0.0.into(),
            "garment.fabric.youngs_modulus",
        ),
        (
            "/garment/fabric/thickness",
            (-1e-4).into(),
            "garment.fabric.thickness",
        ),
        ("/garment/edge_length", 0.0.into(), "garment.edge_length"),
        ("/garment/ease", (-1.0).into(), "garment.ease"),
        ("/garment/panels", serde_json::json!([]), "garment.panels"),
        ("/solver/tolerance", 0.0.into(), "solver.tolerance"),
        ("/solver/max_iterations", 0.into(), "solver.max_iterations"),
        ("/solver/time_limit_s", (-5.0).into(), "solver.time_limit_s"),
        ("/body/source/layers", 0.into(), "body.source.layers"),
        ("/body/source/radius", 0.0.into(), "body.source.radius"),
        (
            "/body/source/radial_segments",
            2.into(),
            "body.source.radial_segments",
        ),
        (
            "/body/fixed",
            serde_json::json!({"kind": "core", "fraction": 1.5}),
            "body.fixed.fraction",
        ),
        (
            "/body/fixed",
            serde_json::json!({"kind": "none"}),
            "body.fixed",
        ),
        (
            "/body/fixed",
            serde_json::json!({"kind": "region", "half_spaces": []}),
            "body.fixed.half_spaces",
        ),
        (
            "/garment/panels/0/half_spaces/0/normal",
            serde_json::json!([0, 0, 0]),
            "garment.panels[0].half_spaces[0].normal",
        ),
        (
            "/garment/pinned",
            serde_json::json!({"half_spaces": [{"normal": [0, 0, 0], "offset": 1}]}),
            "garment.pinned.half_spaces[0].normal",
        ),
        (
            "/garment/panels/0",
            serde_json::json!({"name": "", "faces": [1]}),
            "garment.panels[0].name",
        ),
        (
            "/garment/panels/0",
            serde_json::json!({"name": "a", "faces": []}),
            "garment.panels[0].faces",
        ),
        (
            "/garment/panels/0",
            serde_json::json!({"name": "a", "faces": [3, 4, 3]}),
            "garment.panels[0].faces[2]",
        ),
    ];
    for (pointer, value, key) in cases {
        let mut doc = minimal();
        if pointer.starts_with("/body/material") {
            doc["body"]["material"] = serde_json::json!({});
        }
        if pointer.starts_with("/garment/fabric") {
            doc["garment"]["fabric"] = serde_json::json!({});
        }
        if pointer.starts_with("/solver") {
            doc["solver"] = serde_json::json!({});
        }
        let e = err(&with(doc, pointer, value.clone()));
        assert_eq!(e.key, key, "{pointer} = {value}: {e}");
    }
    // Duplicate names.
    let mut doc = minimal();
    doc["garment"]["panels"] = serde_json::json!([
        {"name": "a", "faces": [1]},
        {"name": "a", "faces": [2]}
    ]);
    let e = err(&doc);
    assert_eq!(e.key, "garment.panels[1].name");
    // Values JSON cannot hold are still caught for scenes built in code.
    let mut s = Scene::from_json(&minimal().to_string()).unwrap();
    s.garment.ease = Real::NAN;
    assert_eq!(s.validate().unwrap_err().key, "garment.ease");
    s.garment.ease = 0.0;
    s.body.material.youngs_modulus = Real::INFINITY;
    assert_eq!(
        s.validate().unwrap_err().key,
        "body.material.youngs_modulus"
    );
}

#[test]
fn fixed_rules_that_cannot_apply_are_refused() {
    let surface = serde_json::json!({"kind": "surface_mesh", "path": "a.obj"});
    let doc = with(
        with(minimal(), "/body/source", surface),
        "/body/fixed",
        serde_json::json!({"kind": "core", "fraction": 0.3}),
    );
    assert_eq!(err(&doc).key, "body.fixed.fraction");
    let tet = serde_json::json!({"kind": "tet_mesh", "path": "a.msh"});
    let doc = with(minimal(), "/body/source", tet.clone());
    assert_eq!(err(&doc).key, "body.fixed");
    let doc = with(
        with(minimal(), "/body/source", tet),
        "/body/fixed",
        serde_json::json!({"kind": "core"}),
    );
    assert_eq!(err(&doc).key, "body.fixed");
}

fn no_files(key: &str, reference: &str) -> Result<PathBuf, SceneError> {
    Err(SceneError::new(key, format!("no file for {reference}")))
}

#[test]
fn procedural_bodies_build_with_their_core_fixed() {
    let mut s = Scene::from_json(&minimal().to_string()).unwrap();
    s.body.source = BodySource::Cylinder(CylinderParams {
        radius: 0.05,
        height: 0.1,
        radial_segments: 12,
        rings: 2,
        layers: 4,
    });
    let body = s.body.build(&no_files).unwrap();
    assert!(body.report.fixed > 0 && body.report.fixed < body.report.vertices);
    assert_eq!(body.report.source, "cylinder");
    assert_eq!(body.surface_tet_vertex.len(), body.surface.num_vertices());
    for (s, &t) in body.surface_tet_vertex.iter().enumerate() {
        assert_eq!(body.surface.positions[s], body.tets.positions[t]);
    }
    // The core (within half the radius of the axis) is fixed; the rest, the lateral skin included, is free.
    for (p, &f) in body.tets.positions.iter().zip(&body.tets.fixed) {
        assert_eq!(f, p.x.hypot(p.z) <= 0.025 + 1e-9, "{p:?}");
    }
    assert_eq!(body.material.youngs_modulus, 24.78e3);
    assert!(body.surface.signed_volume() > 0.0);

    s.body.source = BodySource::Sphere(SphereParams {
        radius: 0.1,
        resolution: 4,
    });
    s.body.fixed = Some(FixedSpec::Core {
        fraction: Some(0.3),
    });
    let body = s.body.build(&no_files).unwrap();
    assert_eq!(body.report.source, "sphere");
    assert!(body.report.fixed > 0);
    assert!((body.surface.signed_volume() - body.tets.volume()).abs() < 1e-12);

    // A region that holds no vertex leaves nothing fixed.
    s.body.fixed = Some(FixedSpec::Region {
        half_spaces: vec![HalfSpace::new([0.0, 1.0, 0.0], -1.0)],
    });
    assert_eq!(s.body.build(&no_files).unwrap_err().key, "body.fixed");
    s.body.fixed = Some(FixedSpec::Region {
        half_spaces: vec![HalfSpace::new([0.0, 1.0, 0.0], -0.05)],
    });
    let body = s.body.build(&no_files).unwrap();
    assert!(
        body.tets
            .positions
            .iter()
            .zip(&body.tets.fixed)
            .all(|(p, &f)| f == (p.y <= -0.05 + 1e-12))
    );
}

#[test]
fn faces_are_checked_against_the_body() {
    let mut s = Scene::from_json(&minimal().to_string()).unwrap();
    s.body.source = BodySource::Sphere(SphereParams {
        radius: 0.1,
        resolution: 2,
    });
    let body = s.body.build(&no_files).unwrap();
    let nf = body.surface.num_faces();
    s.garment.panels = vec![
        PanelSpec {
            name: "a".into(),
            shape: PanelShapeSpec::Faces(vec![0, 1]),
        },
        PanelSpec {
            name: "b".into(),
            shape: PanelShapeSpec::Faces(vec![2, 3, nf - 1]),
        },
    ];
    s.validate().unwrap();
    s.validate_against(&body).unwrap();
    s.garment.panels[1].shape = PanelShapeSpec::Faces(vec![2, 3, nf]);
    assert_eq!(
        s.validate_against(&body).unwrap_err().key,
        "garment.panels[1].faces[2]"
    );
    s.garment.panels[1].shape = PanelShapeSpec::Faces(vec![2, 1]);
    let e = s.validate_against(&body).unwrap_err();
    assert_eq!(e.key, "garment.panels[1].faces[1]");
    assert!(e.message.contains("'a'"), "{e}");
}

#[test]
fn missing_files_name_the_path_key() {
    let dir = std::env::temp_dir();
    let resolver = FileResolver::new(&dir);
    let mut s = Scene::from_json(&minimal().to_string()).unwrap();
    s.body.source = BodySource::SurfaceMesh {
        path: "surely-not-here-4711.obj".into(),
        thickness: 0.02,
        layers: 2,
    };
    s.body.fixed = None;
    let e = s.body.build(&resolver).unwrap_err();
    assert_eq!(e.key, "body.source.path");
    assert!(e.message.contains("not found"), "{e}");
    s.body.source = BodySource::TetMesh {
        path: "surely-not-here-4711.msh".into(),
    };
    s.body.fixed = Some(FixedSpec::Region {
        half_spaces: vec![HalfSpace::new([1.0, 0.0, 0.0], 0.0)],
    });
    assert_eq!(s.body.build(&resolver).unwrap_err().key, "body.source.path");
}

/// A Gmsh ASCII 2.2 file of a tetrahedral mesh (1-based node tags).
pub(crate) fn msh_text(mesh: &TetMesh) -> String {
    let mut s = String::from("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n");
    s += &format!("{}\n", mesh.num_vertices());
    for (i, p) in mesh.positions.iter().enumerate() {
        s += &format!("{} {:e} {:e} {:e}\n", i + 1, p.x, p.y, p.z);
    }
    s += &format!("$EndNodes\n$Elements\n{}\n", mesh.num_tets());
    for (t, tet) in mesh.tets.iter().enumerate() {
        s += &format!(
            "{} 4 2 0 1 {} {} {} {}\n",
            t + 1,
            tet[0] + 1,
            tet[1] + 1,
            tet[2] + 1,
            tet[3] + 1
        );
    }
    s += "$EndElements\n";
    s
}

use skintight_geometry::TetMesh;

#[test]
fn tet_mesh_bodies_are_read_and_fixed_by_region() {
    let sphere = skintight_geometry::body::procedural_body::solid_sphere(&SphereParams {
        radius: 0.1,
        resolution: 3,
    })
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("ball.msh"), msh_text(&sphere)).unwrap();
    let doc = with(
        with(
            minimal(),
            "/body/source",
            serde_json::json!({"kind": "tet_mesh", "path": "ball.msh"}),
        ),
        "/body/fixed",
        serde_json::json!({"kind": "region", "half_spaces": [{"normal": [0, 1, 0], "offset": 0.0}]}),
    );
    let s = Scene::from_json(&doc.to_string()).unwrap();
    let body = s
        .body
        .build(&FileResolver::for_scene_file(
            &dir.path().join("scene.json"),
        ))
        .unwrap();
    assert_eq!(body.report.source, "tet_mesh");
    assert_eq!(body.tets.num_tets(), sphere.num_tets());
    assert!(body.report.fixed > 0);
    for (sv, &t) in body.surface_tet_vertex.iter().enumerate() {
        assert_eq!(body.surface.positions[sv], body.tets.positions[t]);
    }
    // A broken file names the path key.
    std::fs::write(dir.path().join("bad.msh"), "$MeshFormat\n2.2 0 8\n").unwrap();
    let mut s = s;
    s.body.source = BodySource::TetMesh {
        path: "bad.msh".into(),
    };
    let e = s.body.build(&FileResolver::new(dir.path())).unwrap_err();
    assert_eq!(e.key, "body.source.path");
}

#[test]
fn surface_mesh_bodies_keep_the_input_faces() {
    let Some(dir) = bodies_dir() else {
        eprintln!("skipped: shared/data/bodies not found");
        return;
    };
    let input = skintight_geometry::mesh::io::read_mesh(&dir.join("regular_370.obj")).unwrap();
    let doc = with(
        minimal(),
        "/body/source",
        serde_json::json!({"kind": "surface_mesh", "path": "regular_370.obj"}),
    );
    let s = Scene::from_json(&doc.to_string()).unwrap();
    let body = s.body.build(&FileResolver::new(&dir)).unwrap();
    assert_eq!(body.report.source, "surface_mesh");
    assert_eq!(body.surface.faces, input.faces);
    assert_eq!(body.surface.positions, input.positions);
    assert_eq!(
        body.surface_tet_vertex,
        (0..input.num_vertices()).collect::<Vec<_>>()
    );
    assert!(body.report.fixed > 0);
    assert_eq!(body.report.fixed, body.tets.num_fixed());
    assert!(body.report.shell.as_ref().unwrap().surface_preserved);

    // The same mesh turned inward: faces flipped in place, in the same order.
    let mut inward = input.clone();
    inward.flip_orientation();
    let tmp = tempfile::tempdir().unwrap();
    let bytes = skintight_geometry::mesh::io::write_obj(&inward, &Default::default());
    std::fs::write(tmp.path().join("inward.obj"), bytes).unwrap();
    let doc = with(
        minimal(),
        "/body/source",
        serde_json::json!({"kind": "surface_mesh", "path": "inward.obj"}),
    );
    let s = Scene::from_json(&doc.to_string()).unwrap();
    let body = s.body.build(&FileResolver::new(tmp.path())).unwrap();
    assert!(body.report.flipped);
    assert!(!body.report.warnings.is_empty());
    assert_eq!(body.surface.num_faces(), input.num_faces());
    for (f, (a, b)) in body.surface.faces.iter().zip(&input.faces).enumerate() {
        let mut a = *a;
        let mut b = *b;
        a.sort_unstable();
        b.sort_unstable();
        assert_eq!(a, b, "face {f} changed");
    }
    assert_eq!(body.surface.faces, input.faces);
}

#[test]
fn unusable_surface_meshes_name_the_path_key() {
    let tmp = tempfile::tempdir().unwrap();
    // An open mesh: one triangle.
    std::fs::write(
        tmp.path().join("open.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    std::fs::write(tmp.path().join("junk.obj"), "v 0 0\nf 1 2 9\n").unwrap();
    for name in ["open.obj", "junk.obj"] {
        let doc = with(
            minimal(),
            "/body/source",
            serde_json::json!({"kind": "surface_mesh", "path": name}),
        );
        let s = Scene::from_json(&doc.to_string()).unwrap();
        let e = s.body.build(&FileResolver::new(tmp.path())).unwrap_err();
        assert_eq!(e.key, "body.source.path", "{name}");
        assert!(e.message.contains(name), "{e}");
    }
}
