//! Building bodies: procedural, tetrahedral-mesh and surface-mesh sources, their fixed vertices, and errors
//! naming the path key.

use std::path::{Path, PathBuf};

use skintight_geometry::TetMesh;
use skintight_geometry::body::procedural_body::{CylinderParams, SphereParams};
use skintight_geometry::region::HalfSpace;

use crate::scene::tests::{minimal, no_files, with};
use crate::scene::{BodySource, FileResolver, FixedSpec, Scene};

/// The folder `shared/data/bodies` found by walking up from this crate.
pub(crate) fn bodies_dir() -> Option<PathBuf> {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .map(|a| a.join("shared/data/bodies"))
        .find(|d| d.is_dir())
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
fn missing_files_name_the_path_key() {
    let dir = std::env::temp_dir();
    let resolver = FileResolver::new(&dir);
    let mut s = Scene::from_json(&minimal().to_string()).unwrap();
    s.body.source = BodySource::SurfaceMesh {
        path: "surely-not-here-4711.obj".into(),
        thickness: 0.02,
        layers: 2,
        prepare: None,
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

/// A `surface_mesh` body with `prepare` reads a raw scan (mm, +z up, open, islands) and builds a body on
/// the prepared surface; a bad `prepare` field is named.
#[test]
fn surface_mesh_with_prepare_builds_on_the_prepared_scan() {
    use skintight_geometry::scan::raw_scan::{RawScanParams, raw_scan_ply};
    let dir = tempfile::tempdir().unwrap();
    let clean = skintight_geometry::mesh::io::read_mesh(&skintight_geometry::test_meshes::body(
        "regular_1k.obj",
    ))
    .unwrap();
    let params = RawScanParams {
        smooth: false,
        ..Default::default()
    };
    std::fs::write(dir.path().join("scan.ply"), raw_scan_ply(&clean, &params)).unwrap();
    let resolver = FileResolver::new(dir.path());
    let mut s = Scene::from_json(&minimal().to_string()).unwrap();
    s.body.source = BodySource::SurfaceMesh {
        path: "scan.ply".into(),
        thickness: 0.01,
        layers: 1,
        prepare: Some(crate::scene::spec::PrepareSpec {
            units: "auto".into(),
            up: "z".into(),
            target_faces: 4000,
        }),
    };
    s.body.fixed = None;
    let model = s.body.build(&resolver).unwrap();
    assert!(
        model
            .report
            .warnings
            .iter()
            .any(|w| w.contains("prepared from a raw scan"))
    );
    assert!(model.report.surface_faces > 3000 && model.report.surface_faces < 6000);
    let BodySource::SurfaceMesh { prepare, .. } = &mut s.body.source else {
        unreachable!()
    };
    prepare.as_mut().unwrap().units = "inch".into();
    let e = s.body.validate().unwrap_err();
    assert_eq!(e.key, "body.source.prepare.units");
}
