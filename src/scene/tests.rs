use std::path::PathBuf;

use skintight_geometry::body::procedural_body::{CylinderParams, SphereParams};
use skintight_geometry::math::Real;
use skintight_geometry::region::HalfSpace;

use super::*;
use skintight_physics::HessianForm;

pub(super) fn minimal() -> serde_json::Value {
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

pub(super) fn with(
    mut doc: serde_json::Value,
    pointer: &str,
    value: serde_json::Value,
) -> serde_json::Value {
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
    assert_eq!(s.garment.fabric.youngs_modulus(), 5.4e6);
    assert_eq!(s.garment.fabric.poisson_ratio(), 0.33);
    assert_eq!(s.garment.fabric.thickness(), 1e-4);
    assert_eq!(s.garment.pinned, None);
    assert_eq!(s.solver, SolverSpec::default());
    assert_eq!(s.solver.surface, SurfaceKind::Loop);
    assert_eq!(s.solver.tolerance, 1e-6);
    assert_eq!(s.solver.max_iterations, 200);
    assert_eq!(s.solver.time_limit_s, 600.0);
    assert_eq!(s.solver.hessian, HessianForm::Covariant);
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
            layers: 2,
            prepare: None,
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
        "solver": {"surface": "linear", "tolerance": 1e-8, "max_iterations": 50, "time_limit_s": 30.0,
                   "hessian": "coordinate"}
    });
    let s = Scene::from_json(&doc.to_string()).unwrap();
    assert_eq!(s.solver.surface, SurfaceKind::Linear);
    assert_eq!(s.solver.hessian, HessianForm::Coordinate);
    assert_eq!(
        crate::simulate::equilibrium_params(&s).hessian,
        HessianForm::Coordinate
    );
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
        "/solver",
        serde_json::json!({"hessian": "exact"}),
    ));
    assert_eq!(e.key, "solver.hessian");
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

pub(super) fn no_files(key: &str, reference: &str) -> Result<PathBuf, SceneError> {
    Err(SceneError::new(key, format!("no file for {reference}")))
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
        ScenePanel {
            name: "a".into(),
            shape: PanelShapeSpec::Faces(vec![0, 1]),
        },
        ScenePanel {
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

/// Issue 46: a fabric from its test curves or from the library, and bad fabrics named by key.
#[test]
fn curve_and_named_fabrics_parse_and_bad_ones_are_named() {
    let curves = serde_json::json!({
        "course": [[0.2, 20.0], [0.5, 60.0]],
        "wale": [[0.2, 80.0], [0.5, 240.0]],
        "shear": [[0.1, 2.0], [0.3, 8.0]]
    });
    let doc = with(
        minimal(),
        "/garment/fabric",
        serde_json::json!({"curves": curves.clone(), "thickness": 5e-4}),
    );
    let s = Scene::from_json(&doc.to_string()).unwrap();
    let (c, t) = s.garment.fabric.resolved_curves().unwrap();
    assert_eq!((c.course[1], t), ([0.5, 60.0], 5e-4));
    // The isotropic equivalent is the course curve's first secant over the thickness; no Poisson effect.
    assert_eq!(s.garment.fabric.youngs_modulus(), 100.0 / 5e-4);
    assert_eq!(s.garment.fabric.poisson_ratio(), 0.0);
    // Round trip.
    let again = Scene::from_json(&serde_json::to_string(&s).unwrap()).unwrap();
    assert_eq!(again.garment.fabric, s.garment.fabric);
    // A library fabric brings its curves and thickness.
    let doc = with(
        minimal(),
        "/garment/fabric",
        serde_json::json!({"name": "power_net_class2"}),
    );
    let s = Scene::from_json(&doc.to_string()).unwrap();
    assert_eq!(s.garment.fabric.thickness(), 6e-4);
    assert!(s.garment.fabric.resolved_curves().is_some());
    // The isotropic scene is unchanged.
    let s = Scene::from_json(&minimal().to_string()).unwrap();
    assert!(s.garment.fabric.resolved_curves().is_none());

    let bad = |fabric: serde_json::Value, key: &str| {
        let e = err(&with(minimal(), "/garment/fabric", fabric.clone()));
        assert_eq!(e.key, key, "{fabric}: {e}");
        assert!(!e.to_string().contains('\n'));
    };
    let mut c = curves.clone();
    c["course"] = serde_json::json!([[0.2, 20.0], [0.5, 15.0]]);
    bad(
        serde_json::json!({"curves": c}),
        "garment.fabric.curves.course[1]",
    );
    let mut c = curves.clone();
    c["wale"] = serde_json::json!([[-0.1, 20.0], [0.5, 60.0]]);
    bad(
        serde_json::json!({"curves": c}),
        "garment.fabric.curves.wale[0]",
    );
    let mut c = curves.clone();
    c["shear"] = serde_json::json!([[0.2, 3.0]]);
    bad(
        serde_json::json!({"curves": c}),
        "garment.fabric.curves.shear",
    );
    let mut c = curves.clone();
    c.as_object_mut().unwrap().remove("shear");
    bad(
        serde_json::json!({"curves": c}),
        "garment.fabric.curves.shear",
    );
    bad(serde_json::json!({"name": "denim"}), "garment.fabric.name");
    bad(
        serde_json::json!({"curves": curves.clone(), "youngs_modulus": 1e6}),
        "garment.fabric.youngs_modulus",
    );
    bad(
        serde_json::json!({"name": "power_net_class2", "poisson_ratio": 0.3}),
        "garment.fabric.poisson_ratio",
    );
    bad(
        serde_json::json!({"name": "power_net_class2", "thickness": 1e-3}),
        "garment.fabric.thickness",
    );
    bad(
        serde_json::json!({"name": "power_net_class2", "curves": curves}),
        "garment.fabric.name",
    );
}
