//! Garment templates (`garment.template`, `templates/garments/*.json`): each template resolves into
//! ordinary panels on the shared bodies, the worn garment converges with no slack element, the resolved
//! scene is written, and bad templates fail with one line naming the key.

mod mesh_support;
use mesh_support::sphere_obj;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const EXE: &str = env!("CARGO_BIN_EXE_skintight");

const TEMPLATES: [(&str, Option<&str>); 5] = [
    ("knee_high", Some("left")),
    ("thigh_high", Some("right")),
    ("leggings", None),
    ("calf_sleeve", Some("left")),
    ("arm_sleeve", Some("right")),
];

/// `<repo root>/../shared/data/bodies`, or the nearest ancestor's `shared/data/bodies`.
fn bodies_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .map(|a| a.join("shared/data/bodies"))
        .find(|p| p.is_dir())
        .expect("shared/data/bodies")
}

fn scene(body: &Path, template: serde_json::Value) -> serde_json::Value {
    serde_json::json!({
        "body": {"source": {"kind": "surface_mesh", "path": body, "thickness": 0.02, "layers": 2}},
        "garment": {
            "template": template,
            "edge_length": 0.02,
            "ease": -0.1,
            "pinned": {"half_spaces": []}
        },
        "solver": {"max_iterations": 100}
    })
}

fn simulate(doc: &serde_json::Value, dir: &Path, envs: &[(&str, &Path)]) -> Output {
    let file = dir.join("scene.json");
    std::fs::write(&file, serde_json::to_string_pretty(doc).unwrap()).unwrap();
    let mut cmd = Command::new(EXE);
    cmd.arg("simulate")
        .arg(&file)
        .arg("--out")
        .arg(dir.join("out"))
        .arg("--quiet");
    for (k, v) in envs {
        cmd.env(k, v);
    }
    cmd.output().unwrap()
}

/// Simulates `template` on `body` and checks convergence, no slack element, and the resolved scene. Every
/// template must be admissible as cut, except for the grip of its openings (issue 47), which a template
/// meets only once designed (the leggings' waist reads 3.7 mmHg against 5 on regular_1k; an arm sleeve as
/// cut may end above the wrist band): a verdict whose only violations are `grip` is allowed here.
fn check(body: &str, name: &str, side: Option<&str>) {
    check_on(&bodies_dir().join(body), None, name, side, true);
}

/// Whether the CLI's one-line verdict in `stderr` lists only `grip` violations.
fn only_grip_violations(stderr: &str) -> bool {
    stderr.lines().any(|l| {
        l.split_once(" violations: ")
            .or_else(|| l.split_once(" violation: "))
            .is_some_and(|(_, list)| list.split("; ").all(|v| v.starts_with("grip: ")))
    })
}

/// [`check`] on the body file `path`, prepared first as a raw scan with the settings `prepare` if given.
fn check_on(
    path: &Path,
    prepare: Option<serde_json::Value>,
    name: &str,
    side: Option<&str>,
    must_be_admissible: bool,
) {
    let body = path.display().to_string();
    let dir = tempfile::tempdir().unwrap();
    let mut t = serde_json::json!({"name": name});
    if let Some(s) = side {
        t["side"] = s.into();
    }
    let start = std::time::Instant::now();
    let mut doc = scene(path, t);
    if let Some(p) = prepare {
        doc["body"]["source"]["prepare"] = p;
    }
    let res = simulate(&doc, dir.path(), &[]);
    let stderr = String::from_utf8_lossy(&res.stderr);
    // Exit 4 is a converged garment beyond the fabric's limits: allowed only where the caller says so
    // (the sweeps over prepared scans, which report it).
    let allowed = res.status.success()
        || (res.status.code() == Some(4) && (!must_be_admissible || only_grip_violations(&stderr)));
    assert!(allowed, "{name} on {body}: {stderr}");
    if res.status.code() == Some(4) {
        eprintln!("{name} on {body}: {}", stderr.lines().last().unwrap_or(""));
    }
    let out = dir.path().join("out");
    let result: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("result.json")).unwrap()).unwrap();
    eprintln!(
        "{name} on {body}: converged {} in {} iterations, slack {}, wrinkled {}, stretch {:.3}..{:.3}, {:.1} s",
        result["converged"],
        result["newton_iterations"],
        result["slack_elements"],
        result["wrinkled_elements"],
        result["min_stretch"].as_f64().unwrap_or(f64::NAN),
        result["max_stretch"].as_f64().unwrap_or(f64::NAN),
        start.elapsed().as_secs_f64()
    );
    assert_eq!(result["converged"], true, "{name} on {body}");
    assert_eq!(result["slack_elements"], 0, "{name} on {body}");
    // The landmark bands: on the template's limb only, and the report's numbers are result.json's.
    let regions = result["regions"].as_array().unwrap();
    let bands: Vec<String> = regions
        .iter()
        .map(|r| {
            format!(
                "{}{}",
                r["name"].as_str().unwrap(),
                r["side"].as_str().map_or("", |s| &s[..1])
            )
        })
        .collect();
    eprintln!("{name} on {body}: bands {}", bands.join(" "));
    assert!(!regions.is_empty(), "{name} on {body}: no band");
    if let Some(side) = side {
        for r in regions {
            assert_eq!(
                r["side"], side,
                "{name} on {body}: a band off its limb: {r}"
            );
        }
    }
    let report = std::fs::read_to_string(out.join("report.html")).unwrap();
    skintight::simulate::report::html::read_back(&report, &result)
        .unwrap_or_else(|e| panic!("{name} on {body}: report.html: {e}"));
    // The resolved panels are written as an ordinary scene, which parses and validates on its own.
    let resolved: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("resolved_scene.json")).unwrap()).unwrap();
    assert!(resolved["garment"]["template"].is_null());
    let panels = resolved["garment"]["panels"].as_array().unwrap();
    assert_eq!(panels.len(), if side.is_none() { 4 } else { 2 }, "{name}");
    for p in panels {
        assert!(p["half_spaces"].as_array().unwrap().len() >= 5, "{p}");
    }
    skintight::scene::Scene::from_json(&serde_json::to_string(&resolved).unwrap())
        .unwrap_or_else(|e| panic!("{name}: the resolved scene: {e}"));
}

#[test]
fn every_template_converges_without_slack_on_the_regular_body() {
    for (name, side) in TEMPLATES {
        check("regular_1k.obj", name, side);
    }
}

/// Every template on every shared 1k body (`cargo test --test garment_templates -- --ignored`).
#[test]
#[ignore]
fn every_template_converges_without_slack_on_every_shared_body() {
    for shape in ["regular", "male", "athletic", "overweight", "kid"] {
        for (name, side) in TEMPLATES {
            check(&format!("{shape}_1k.obj"), name, side);
        }
    }
}

/// A customer's raw scan — the regular body subdivided, noised, open at the soles and crown, with floating
/// islands and non-manifold spots, in millimetres, +z up, binary PLY — prepared inside the job
/// (`body.source.prepare`): the knee-high and the calf sleeve fit it as they fit the clean body, admissible.
#[test]
fn templates_converge_without_slack_on_a_raw_scan_prepared_in_the_job() {
    use skintight_geometry::scan::raw_scan::{RawScanParams, raw_scan_ply};
    let clean =
        skintight_geometry::mesh::io::read_mesh(&bodies_dir().join("regular_1k.obj")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let scan = dir.path().join("scan.ply");
    std::fs::write(
        &scan,
        raw_scan_ply(
            &clean,
            &RawScanParams {
                subdivisions: 1,
                smooth: false,
                ..RawScanParams::default()
            },
        ),
    )
    .unwrap();
    for (name, side) in [("knee_high", Some("left")), ("calf_sleeve", Some("right"))] {
        check_on(
            &scan,
            Some(serde_json::json!({"target_faces": 6000})),
            name,
            side,
            true,
        );
    }
}

/// Every template on a raw scan of every shared 1k body, prepared in the job: converged, no slack element;
/// a garment beyond the default fabric limits is reported, not failed (the arm sleeve on the prepared
/// regular scan presses 60.2 mmHg at one spot) (`cargo test --test garment_templates -- --ignored`).
#[test]
#[ignore]
fn every_template_converges_without_slack_on_every_prepared_raw_scan() {
    use skintight_geometry::scan::raw_scan::{RawScanParams, raw_scan_ply};
    for shape in ["regular", "male", "athletic", "overweight", "kid"] {
        let clean =
            skintight_geometry::mesh::io::read_mesh(&bodies_dir().join(format!("{shape}_1k.obj")))
                .unwrap();
        let dir = tempfile::tempdir().unwrap();
        let scan = dir.path().join("scan.ply");
        let params = RawScanParams {
            subdivisions: 1,
            smooth: false,
            ..RawScanParams::default()
        };
        std::fs::write(&scan, raw_scan_ply(&clean, &params)).unwrap();
        for (name, side) in TEMPLATES {
            check_on(
                &scan,
                Some(serde_json::json!({"target_faces": 6000})),
                name,
                side,
                false,
            );
        }
    }
}

/// Every template on a raw scan of every shared 12k body — two Loop subdivisions (≈ 384 k triangles), noise,
/// open soles and crown, islands, millimetres, +z up, binary PLY: the acceptance scans of issue 15 —
/// prepared in the job at the default resolution (24 000 faces): converged, no slack element; a garment
/// beyond the default fabric limits is reported, not failed. Slow (one prepare and one solve on a
/// 24 000-face body per case; figures in docs/BENCHMARKS.md):
/// `cargo test --release --test garment_templates -- --ignored --nocapture prepared_12k`.
/// Measured 2026-12-02: 25 of 25 converge, the leggings on the male and kid scans with one slack element;
/// since pattern corners are taken at the cloth's scale and slivers flipped, both leggings converge with
/// none and admissible (docs/BENCHMARKS.md).
#[test]
#[ignore]
fn every_template_converges_without_slack_on_every_prepared_12k_raw_scan() {
    use skintight_geometry::scan::raw_scan::{RawScanParams, raw_scan_ply};
    let mut failures = Vec::new();
    for shape in ["regular", "male", "athletic", "overweight", "kid"] {
        let clean =
            skintight_geometry::mesh::io::read_mesh(&bodies_dir().join(format!("{shape}_12k.obj")))
                .unwrap();
        let dir = tempfile::tempdir().unwrap();
        let scan = dir.path().join(format!("{shape}_12k_scan.ply"));
        std::fs::write(&scan, raw_scan_ply(&clean, &RawScanParams::default())).unwrap();
        for (name, side) in TEMPLATES {
            // Every case runs; the failures are listed at the end.
            let run = std::panic::catch_unwind(|| {
                check_on(&scan, Some(serde_json::json!({})), name, side, false)
            });
            if let Err(e) = run {
                let msg = e
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default();
                failures.push(format!("{name} on {shape}: {msg}"));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

fn one_line_error(res: &Output) -> String {
    assert_eq!(res.status.code(), Some(2), "{res:?}");
    let stderr = String::from_utf8_lossy(&res.stderr).to_string();
    assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
    stderr
}

#[test]
fn bad_templates_fail_in_one_line_naming_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let body = bodies_dir().join("regular_1k.obj");
    let e = one_line_error(&simulate(
        &scene(
            &body,
            serde_json::json!({"name": "ball_gown", "side": "left"}),
        ),
        dir.path(),
        &[],
    ));
    assert!(
        e.contains("garment.template.name") && e.contains("ball_gown"),
        "{e}"
    );
    let e = one_line_error(&simulate(
        &scene(
            &body,
            serde_json::json!({"name": "leggings", "side": "left"}),
        ),
        dir.path(),
        &[],
    ));
    assert!(e.contains("garment.template.side"), "{e}");
    let e = one_line_error(&simulate(
        &scene(&body, serde_json::json!({"name": "knee_high"})),
        dir.path(),
        &[],
    ));
    assert!(e.contains("garment.template.side"), "{e}");
    let e = one_line_error(&simulate(
        &scene(
            &body,
            serde_json::json!({"name": "knee_high", "side": "left",
                               "options": {"top": {"landmark": "waist"}}}),
        ),
        dir.path(),
        &[],
    ));
    assert!(
        e.contains("garment.template.top") && e.contains("waist"),
        "{e}"
    );
    // A shop's template folder: a template with an unknown landmark is refused naming it.
    let shop = dir.path().join("shop");
    std::fs::create_dir_all(&shop).unwrap();
    std::fs::write(
        shop.join("ankle_band.json"),
        r#"{"name": "ankle_band", "limb": "leg", "bottom": {"landmark": "B"},
            "top": {"landmark": "Q"}, "seam": "front_back", "panels": ["front", "back"]}"#,
    )
    .unwrap();
    let e = one_line_error(&simulate(
        &scene(
            &body,
            serde_json::json!({"name": "ankle_band", "side": "left"}),
        ),
        dir.path(),
        &[("SKINTIGHT_GARMENT_TEMPLATES", &shop)],
    ));
    assert!(
        e.contains("garment.template.top") && e.contains("'Q'"),
        "{e}"
    );
    // A sphere is no body to measure: the template names what was not found.
    let sphere = dir.path().join("sphere.obj");
    std::fs::write(&sphere, sphere_obj(0.5)).unwrap();
    let e = one_line_error(&simulate(
        &scene(
            &sphere,
            serde_json::json!({"name": "knee_high", "side": "left"}),
        ),
        dir.path(),
        &[],
    ));
    assert!(e.contains("no two legs below the torso"), "{e}");
}

/// The OpenAPI document (`openapi.yaml`, components `ScanPrepare`, `GarmentTemplate`,
/// `GarmentTemplateOptions`, `TemplateAnchor`) describes `body.source.prepare` and `garment.template` as
/// the scene parser accepts them: the same fields, the same defaults, every enumerated value accepted and
/// the bounds where the parser puts them, unknown fields refused, and the landmark names those
/// `body measure` gives.
#[test]
fn openapi_describes_prepare_and_template_as_the_scene_accepts_them() {
    use serde_json::{Value, json};
    use std::collections::BTreeSet;
    let doc: Value = serde_norway::from_str(skintight::server::OPENAPI_YAML).unwrap();
    let schemas = &doc["components"]["schemas"];
    let props = |name: &str| -> BTreeSet<String> {
        assert_eq!(
            schemas[name]["additionalProperties"], false,
            "{name} is closed"
        );
        schemas[name]["properties"]
            .as_object()
            .unwrap_or_else(|| panic!("schema {name}"))
            .keys()
            .cloned()
            .collect()
    };
    let strings = |v: &Value| -> Vec<String> {
        v.as_array()
            .unwrap()
            .iter()
            .filter_map(|x| x.as_str().map(str::to_string))
            .collect()
    };
    let body = bodies_dir().join("regular_1k.obj");
    let with = |prepare: Value, template: Value| {
        let mut doc = scene(&body, template);
        doc["body"]["source"]["prepare"] = prepare;
        skintight::scene::Scene::from_json(&doc.to_string())
    };
    let knee = json!({"name": "knee_high", "side": "left"});

    // body.source.prepare: `{}` takes the documented defaults, and only those fields.
    let s = with(json!({}), knee.clone()).unwrap();
    let written = serde_json::to_value(&s).unwrap();
    let prepare = &written["body"]["source"]["prepare"];
    let fields: BTreeSet<String> = prepare.as_object().unwrap().keys().cloned().collect();
    assert_eq!(fields, props("ScanPrepare"));
    let p = &schemas["ScanPrepare"]["properties"];
    for f in &fields {
        assert_eq!(prepare[f], p[f]["default"], "default of prepare.{f}");
    }
    for field in ["units", "up"] {
        for v in strings(&p[field]["enum"]) {
            with(json!({ field: v }), knee.clone())
                .unwrap_or_else(|e| panic!("prepare.{field} = {v}: {e}"));
        }
        let e = with(json!({ field: "w" }), knee.clone()).unwrap_err();
        assert!(e.to_string().contains(&format!("prepare.{field}")), "{e}");
    }
    let (lo, hi) = (
        p["target_faces"]["minimum"].as_u64().unwrap(),
        p["target_faces"]["maximum"].as_u64().unwrap(),
    );
    for ok in [lo, hi] {
        with(json!({ "target_faces": ok }), knee.clone()).unwrap();
    }
    for bad in [lo - 1, hi + 1] {
        let e = with(json!({ "target_faces": bad }), knee.clone()).unwrap_err();
        assert!(e.to_string().contains("prepare.target_faces"), "{e}");
    }
    assert!(with(json!({"target_face": 100}), knee.clone()).is_err());

    // garment.template: every field written back is documented, and documented fields are all accepted.
    let full = json!({
        "name": "knee_high",
        "side": "left",
        "options": {
            "bottom": {"landmark": "B", "toward": "C", "fraction": 0.25, "offset_m": 0.01},
            "top": {"landmark": "D"},
            "margin_m": 0.03
        }
    });
    let s = with(json!({}), full).unwrap();
    let t = serde_json::to_value(&s).unwrap()["garment"]["template"].clone();
    let keys = |v: &Value| -> BTreeSet<String> { v.as_object().unwrap().keys().cloned().collect() };
    assert_eq!(keys(&t), props("GarmentTemplate"));
    assert_eq!(keys(&t["options"]), props("GarmentTemplateOptions"));
    assert_eq!(keys(&t["options"]["bottom"]), props("TemplateAnchor"));
    let sides = schemas["GarmentTemplate"]["properties"]["side"]["enum"]
        .as_array()
        .unwrap()
        .clone();
    assert!(sides.contains(&Value::Null));
    for side in strings(&Value::Array(sides)) {
        with(json!({}), json!({"name": "calf_sleeve", "side": side})).unwrap();
    }
    with(json!({}), json!({"name": "leggings", "side": null})).unwrap();
    let margin = &schemas["GarmentTemplateOptions"]["properties"]["margin_m"];
    let max = margin["maximum"].as_f64().unwrap();
    for (m, ok) in [
        (0.0, true),
        (max, true),
        (max + 0.01, false),
        (-0.01, false),
    ] {
        let r = with(
            json!({}),
            json!({"name": "knee_high", "side": "left", "options": {"margin_m": m}}),
        );
        assert_eq!(r.is_ok(), ok, "margin_m {m}: {r:?}");
    }
    assert!(
        with(
            json!({}),
            json!({"name": "knee_high", "side": "left", "colour": "red"})
        )
        .is_err()
    );
    // The documented built-in names are the built-in templates.
    for name in skintight::scene::template::BUILTIN_TEMPLATES
        .iter()
        .map(|(n, _)| *n)
    {
        let d = schemas["GarmentTemplate"]["properties"]["name"]["description"]
            .as_str()
            .unwrap();
        assert!(d.contains(&format!("`{name}`")), "{name} undocumented");
    }
    // Landmark names: those `body measure` gives.
    let clean = skintight_geometry::mesh::io::read_mesh(&body).unwrap();
    let measured: BTreeSet<String> = skintight_geometry::anthropometry::measure_body(&clean)
        .unwrap()
        .landmarks
        .into_iter()
        .map(|l| l.name)
        .collect();
    for field in ["landmark", "toward"] {
        let documented: BTreeSet<String> =
            strings(&schemas["TemplateAnchor"]["properties"][field]["enum"])
                .into_iter()
                .collect();
        assert_eq!(documented, measured, "TemplateAnchor.{field}");
    }
}
