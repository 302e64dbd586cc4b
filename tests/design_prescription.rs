//! Orders designed to a compression prescription (`objectives.prescription`, docs/DESIGN_JOB.md): the
//! knee-high class II order of `examples/order_knee_high_class2.json` on a shared body ends admissible with
//! every band inside its window, its verdict in `result.json` and in `report.html`; an order no fabric
//! could meet ends with exit status 4 and says which band misses by how much. The acceptance runs
//! (every shared 1k body at class II, regular_12k at class I) are behind `--ignored`; they print the
//! pressure-by-height tables of docs/BENCHMARKS.md.

use std::path::{Path, PathBuf};
use std::process::Output;

mod design_support;

use design_support::read_json;

const EXE: &str = env!("CARGO_BIN_EXE_skintight");

fn bodies() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/bodies")
}

/// The example order on `body` (a shared body's stem) at class `class`.
fn order(example: &str, body: &str, class: u8) -> serde_json::Value {
    let file = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("examples")
        .join(example);
    let mut job: serde_json::Value = serde_json::from_slice(&std::fs::read(file).unwrap()).unwrap();
    job["body"]["source"]["path"] = bodies()
        .join(format!("{body}.obj"))
        .to_string_lossy()
        .into_owned()
        .into();
    job["objectives"]["prescription"]["class"] = class.into();
    job
}

fn design(job: &serde_json::Value, dir: &Path) -> Output {
    design_support::design_cli(EXE, job, dir)
}

/// Checks the verdict against the regions it was made from and the standard's table; returns
/// `result.json`.
fn check_verdict(out: &Path, window: [f64; 2]) -> serde_json::Value {
    let r = read_json(&out.join("result.json"));
    let p = &r["prescription"];
    assert_eq!(p["standard"], "RAL-GZ 387");
    assert_eq!(p["window_mmhg"], serde_json::json!(window));
    let b = p["measured_b_mmhg"].as_f64().unwrap();
    let regions = r["regions"].as_array().unwrap();
    for band in p["bands"].as_array().unwrap() {
        let region = regions
            .iter()
            .find(|g| g["name"] == band["name"] && g["side"] == band["side"])
            .unwrap_or_else(|| panic!("no region for {band}"));
        let measured = band["measured_mmhg"].as_f64().unwrap();
        assert_eq!(measured, region["pressure_mmhg"]["mean"].as_f64().unwrap());
        let w = band["window_mmhg"].as_array().unwrap();
        let (lo, hi) = (w[0].as_f64().unwrap(), w[1].as_f64().unwrap());
        if band["name"] != "B" {
            // The graduated profile: percent windows of the measured B.
            assert!(lo < b && hi <= b + 1e-9, "{band}");
        }
        assert_eq!(
            band["pass"].as_bool().unwrap(),
            measured >= lo && measured <= hi,
            "{band}"
        );
    }
    r
}

/// One line per band: name, height, girth, measured, window (mmHg), pass.
fn table(r: &serde_json::Value) -> String {
    let mut out = String::new();
    for band in r["prescription"]["bands"].as_array().unwrap() {
        let region = r["regions"]
            .as_array()
            .unwrap()
            .iter()
            .find(|g| g["name"] == band["name"] && g["side"] == band["side"])
            .unwrap();
        let w = &band["window_mmhg"];
        out += &format!(
            "| {} | {:.1} | {:.1} | {:.1} ({:.1}–{:.1}) | {:.1}–{:.1} | {} |\n",
            band["name"].as_str().unwrap(),
            region["height_m"].as_f64().unwrap() * 100.0,
            region["girth_m"].as_f64().unwrap() * 100.0,
            band["measured_mmhg"].as_f64().unwrap(),
            region["pressure_mmhg"]["min"].as_f64().unwrap(),
            region["pressure_mmhg"]["max"].as_f64().unwrap(),
            w[0].as_f64().unwrap(),
            w[1].as_f64().unwrap(),
            if band["pass"].as_bool().unwrap() {
                "pass"
            } else {
                "FAIL"
            },
        );
    }
    out
}

#[test]
fn a_knee_high_class_ii_order_designs_to_its_prescription_and_its_report_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let out = design(
        &order("order_knee_high_class2.json", "regular_1k", 2),
        dir.path(),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let r = check_verdict(&dir.path().join("out"), [23.0, 32.0]);
    println!("{}", table(&r));
    assert_eq!(r["admissible"], true, "{}", r["violations"]);
    assert_eq!(r["prescription"]["pass"], true);
    let names: Vec<&str> = r["prescription"]["bands"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| b["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["B", "B1", "C", "D"]);
    // The design got there: the band objective fell by orders of magnitude.
    let (first, last) = (
        r["initial_objective"].as_f64().unwrap(),
        r["final_objective"].as_f64().unwrap(),
    );
    assert!(last < 1e-3 * first, "{first} → {last}");
    assert!(
        r["terms"]
            .as_array()
            .unwrap()
            .iter()
            .any(|t| t["name"] == "band_pressure")
    );
    // The fitter's report carries the verdict with result.json's numbers.
    let html = std::fs::read_to_string(dir.path().join("out/report.html")).unwrap();
    let b = r["prescription"]["measured_b_mmhg"].as_f64().unwrap();
    assert!(html.contains("RAL-GZ 387"));
    assert!(
        html.contains(&format!("{b:.1}")),
        "the report lacks B = {b:.1}"
    );
    assert!(html.contains("data-field=\"prescription.measured_b_mmhg\""));
}

#[test]
fn an_order_no_fabric_within_its_limits_can_meet_ends_not_admissible_and_says_why() {
    // Class III (34–46 mmHg at the ankle) from a fabric that may stretch only 3 % across: no garment
    // meets both. The stretch limit is a penalty (`optimizer.fabric_limits`), so the design may end beyond
    // the fabric or short of the class — either way it ends with status 4 and says what, never as a
    // success. (Measured: the class wins, course stretch 1.46 > 1.03.)
    let dir = tempfile::tempdir().unwrap();
    let mut job = order("order_knee_high_class2.json", "regular_1k", 3);
    job["garment"]["fabric"] =
        serde_json::json!({"limits": {"max_stretch": {"wale": 2.0, "course": 1.03}}});
    job["optimizer"]["max_iterations"] = 8.into();
    let out = design(&job, dir.path());
    assert_eq!(
        out.status.code(),
        Some(4),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    let last = stderr.lines().last().unwrap();
    println!("{last}");
    assert!(last.starts_with("design: NOT ADMISSIBLE:"), "{last}");
    let r = check_verdict(&dir.path().join("out"), [34.0, 46.0]);
    assert_eq!(r["admissible"], false);
    let v = r["violations"].as_array().unwrap();
    let stretch = v.iter().any(|v| v["kind"] == "stretch_course");
    let missed = v.iter().any(|v| v["kind"] == "prescription");
    assert!(stretch || missed, "{v:?}");
    assert_eq!(missed, r["prescription"]["pass"] == false);
    if stretch {
        assert!(last.contains("stretch_course"), "{last}");
    }
    if missed {
        assert!(last.contains("(RAL-GZ 387 class 3)"), "{last}");
    }
}

#[test]
fn a_prescription_needs_a_leg_and_a_known_class() {
    let dir = tempfile::tempdir().unwrap();
    for (edit, key) in [
        (
            serde_json::json!({"class": 5}),
            "objectives.prescription.class",
        ),
        (
            serde_json::json!({"standard": "DIN 58133"}),
            "objectives.prescription.standard",
        ),
        (
            serde_json::json!({"profile": {"Z": [50, 80]}}),
            "objectives.prescription.profile.Z",
        ),
        (
            serde_json::json!({"profile": "steep"}),
            "objectives.prescription.profile",
        ),
        (
            serde_json::json!({"margin": 0.6}),
            "objectives.prescription.margin",
        ),
        (
            serde_json::json!({"weight": -1}),
            "objectives.prescription.weight",
        ),
    ] {
        let mut job = order("order_knee_high_class2.json", "regular_1k", 2);
        for (k, v) in edit.as_object().unwrap() {
            job["objectives"]["prescription"][k] = v.clone();
        }
        let out = design(&job, dir.path());
        assert_eq!(out.status.code(), Some(2), "{edit}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(stderr.contains(key), "{edit}: {stderr}");
    }
    // A prescription on a body without legs: one line, naming the objective.
    let mut job = order("order_knee_high_class2.json", "regular_1k", 2);
    job["body"] = serde_json::json!({"source": {"kind": "cylinder", "radius": 0.05, "height": 0.16,
        "radial_segments": 12, "rings": 3, "layers": 8}, "fixed": {"kind": "core", "fraction": 0.5}});
    job["garment"] = serde_json::json!({
        "panels": [
            {"name": "front", "half_spaces": [{"normal": [0, 0, -1], "offset": 0.0},
                {"normal": [0, 1, 0], "offset": 0.05}, {"normal": [0, -1, 0], "offset": 0.05}]},
            {"name": "back", "half_spaces": [{"normal": [0, 0, 1], "offset": 0.0},
                {"normal": [0, 1, 0], "offset": 0.05}, {"normal": [0, -1, 0], "offset": 0.05}]}
        ],
        "edge_length": 0.02, "ease": -0.1, "pinned": {"half_spaces": []}});
    job["objectives"]["prescription"]["side"] = "left".into();
    let out = design(&job, dir.path());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_ne!(out.status.code(), Some(0));
    assert!(stderr.contains("objectives.prescription"), "{stderr}");
    assert!(stderr.trim_end().lines().count() <= 2, "{stderr}");
}

#[test]
#[ignore = "the issue's acceptance: every shared 1k body at class II and regular_12k at class I (~3 min release)"]
fn knee_high_orders_on_every_shared_body_meet_their_prescription() {
    let runs = [
        ("regular_1k", 2, [23.0, 32.0]),
        ("athletic_1k", 2, [23.0, 32.0]),
        ("kid_1k", 2, [23.0, 32.0]),
        ("male_1k", 2, [23.0, 32.0]),
        ("overweight_1k", 2, [23.0, 32.0]),
        ("regular_12k", 1, [18.0, 21.0]),
    ];
    let mut failures = Vec::new();
    for (body, class, window) in runs {
        let dir = tempfile::tempdir().unwrap();
        let t = std::time::Instant::now();
        let out = design(
            &order("order_knee_high_class2.json", body, class),
            dir.path(),
        );
        let r = check_verdict(&dir.path().join("out"), window);
        println!(
            "{body}, class {class}: exit {:?}, {:.0} s, {} iterations\n| band | height (cm) | girth (cm) | \
             measured mmHg (probe min–max) | window mmHg | |\n|---|---|---|---|---|---|\n{}",
            out.status.code(),
            t.elapsed().as_secs_f64(),
            r["iterations"],
            table(&r)
        );
        if !(out.status.success() && r["admissible"] == true && r["prescription"]["pass"] == true) {
            failures.push(body);
        }
    }
    assert!(failures.is_empty(), "{failures:?}");
}

/// Bad orders end with one line naming the key or the body (issue 47): a template on the wrong limb side
/// (a side for the two-leg leggings, none for a one-leg stocking, a prescription on the other leg than
/// the template's), a prescription class the order cannot have (beyond the standard's classes, or starting
/// above the fabric's pressure limit), a graduated profile on an arm, and leggings on a body without legs.
#[test]
fn bad_orders_end_with_one_line_naming_the_key_or_the_body() {
    let dir = tempfile::tempdir().unwrap();
    let knee = || order("order_knee_high_class2.json", "regular_1k", 2);
    let leggings = || order("order_leggings_class1.json", "regular_1k", 1);
    let mut cases: Vec<(serde_json::Value, &str, &str)> = Vec::new();
    let mut j = leggings();
    j["garment"]["template"]["side"] = "left".into();
    cases.push((j, "garment.template.side", "give no side"));
    let mut j = knee();
    j["garment"]["template"]
        .as_object_mut()
        .unwrap()
        .remove("side");
    cases.push((j, "garment.template.side", "needs a side"));
    let mut j = knee();
    j["objectives"]["prescription"]["side"] = "right".into();
    cases.push((j, "objectives.prescription.side", "cut on the left"));
    let mut j = knee();
    j["objectives"]["prescription"]["class"] = 5.into();
    cases.push((j, "objectives.prescription.class", "classes 1 to 4"));
    let mut j = knee();
    j["objectives"]["prescription"]["class"] = 4.into();
    j["garment"]["fabric"] = serde_json::json!({"limits": {"max_pressure_pa": 40.0 * 133.322}});
    cases.push((
        j,
        "objectives.prescription.class",
        "above the order's pressure limit",
    ));
    let mut j = order("order_arm_sleeve_class1.json", "regular_1k", 1);
    j["objectives"]["prescription"]["profile"] = "graduated".into();
    cases.push((
        j,
        "objectives.prescription.profile",
        "no graduated arm profile",
    ));
    for (job, key, words) in cases {
        let out = design(&job, dir.path());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{key}: {stderr}");
        assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
        assert!(stderr.contains(&format!("`{key}`")), "{key}: {stderr}");
        assert!(stderr.contains(words), "{key}: {stderr}");
    }
    // Leggings on a body without legs (a cylinder): one line about the body, never a panic.
    let mut j = leggings();
    j["body"] = serde_json::json!({"source": {"kind": "cylinder", "radius": 0.05, "height": 0.16,
        "radial_segments": 12, "rings": 3, "layers": 8}, "fixed": {"kind": "core", "fraction": 0.5}});
    let out = design(&j, dir.path());
    let stderr = String::from_utf8_lossy(&out.stderr);
    println!(
        "leggings on a cylinder: exit {:?}: {stderr}",
        out.status.code()
    );
    assert!(matches!(out.status.code(), Some(1 | 2)), "{stderr}");
    assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("body") && stderr.contains("leg"),
        "{stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
}

/// Distance from `p` to the triangle `(a, b, c)` (m): Ericson's closest point on a triangle.
fn triangle_distance(p: skintight_geometry::Vec3, [a, b, c]: [skintight_geometry::Vec3; 3]) -> f64 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    let (vc, vb, va) = (d1 * d4 - d3 * d2, d5 * d2 - d1 * d6, d3 * d6 - d5 * d4);
    let q = if d1 <= 0.0 && d2 <= 0.0 {
        a
    } else if d3 >= 0.0 && d4 <= d3 {
        b
    } else if d6 >= 0.0 && d5 <= d6 {
        c
    } else if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        a + ab * (d1 / (d1 - d3))
    } else if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        a + ac * (d2 / (d2 - d6))
    } else if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)))
    } else {
        let denom = 1.0 / (va + vb + vc);
        a + ab * (vb * denom) + ac * (vc * denom)
    };
    (p - q).norm()
}

/// The knee-high order's files are sized for a shop and the garment still sits on the displayed body
/// (issue 47): the viewable files (the `.glb` files, `report.html`, the pattern files) together at most
/// 5 MB, and at least 99 % of the worn cloth vertices outside `body.glb` or within 0.5 mm of its surface
/// (inside-ness by the generalized winding number, Van Oosterom & Strackee 1983, for the vertices farther
/// than 0.5 mm from it). The design runs one iteration: the files' sizes and the display do not depend on
/// how far the design went. The glTF validator checks the three meshes when `SKINTIGHT_GLTF_VALIDATOR` is
/// set (as in tests/cli_simulate.rs).
#[test]
fn a_knee_high_orders_files_fit_five_megabytes_and_the_garment_sits_on_the_displayed_body() {
    shop_files_and_display("regular_1k");
}

/// The same on regular_12k (a body.glb of 1.6 MB; minutes in a debug build).
#[test]
#[ignore = "minutes in a debug build: the knee-high order on regular_12k"]
fn a_knee_high_order_on_a_12k_body_fits_five_megabytes_and_sits_on_the_displayed_body() {
    shop_files_and_display("regular_12k");
}

/// The checks of the two tests above on the knee-high class II order on `body`, one design iteration.
fn shop_files_and_display(body: &str) {
    use skintight_geometry::Vec3 as Vector3;
    let dir = tempfile::tempdir().unwrap();
    let mut job = order("order_knee_high_class2.json", body, 2);
    job["optimizer"]["max_iterations"] = 1.into();
    let out = design(&job, dir.path());
    assert!(
        matches!(out.status.code(), Some(0 | 4)),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = dir.path().join("out");
    let mut viewable = 0u64;
    let mut sizes = Vec::new();
    for entry in std::fs::read_dir(&out).unwrap() {
        let entry = entry.unwrap();
        let name = entry.file_name().to_string_lossy().into_owned();
        let size = entry.metadata().unwrap().len();
        sizes.push(format!("{name} {size}"));
        if name.ends_with(".glb") || name == "report.html" || name.starts_with("patterns") {
            viewable += size;
        }
    }
    sizes.sort();
    println!("knee-high on {body}, files (bytes): {}", sizes.join(", "));
    println!("viewable total: {viewable} bytes");
    assert!(viewable <= 5_000_000, "{viewable} bytes: {sizes:?}");

    let result = read_json(&out.join("result.json"));
    let body =
        skintight_geometry::mesh::io::read_glb(&std::fs::read(out.join("body.glb")).unwrap())
            .unwrap();
    let cloth: Vec<Vector3> = result["cloth_vertex_position"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            Vector3::new(
                p[0].as_f64().unwrap(),
                p[1].as_f64().unwrap(),
                p[2].as_f64().unwrap(),
            )
        })
        .collect();
    let tris: Vec<[Vector3; 3]> = body
        .faces
        .iter()
        .map(|f| f.map(|v| body.positions[v]))
        .collect();
    // Triangles by the grid cells their bounding boxes meet (cell 1 cm).
    let cell = 0.01;
    let key = |p: Vector3| [p.x, p.y, p.z].map(|x| (x / cell).floor() as i64);
    let mut grid: std::collections::HashMap<[i64; 3], Vec<usize>> = Default::default();
    for (t, tri) in tris.iter().enumerate() {
        let lo = key(tri[0].inf(&tri[1]).inf(&tri[2]));
        let hi = key(tri[0].sup(&tri[1]).sup(&tri[2]));
        for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                for z in lo[2]..=hi[2] {
                    grid.entry([x, y, z]).or_default().push(t);
                }
            }
        }
    }
    let winding = |p: Vector3| {
        let mut total = 0.0;
        for [a, b, c] in &tris {
            let [a, b, c] = [a - p, b - p, c - p];
            let (la, lb, lc) = (a.norm(), b.norm(), c.norm());
            let det = a.dot(&b.cross(&c));
            let den = la * lb * lc + a.dot(&b) * lc + b.dot(&c) * la + c.dot(&a) * lb;
            total += 2.0 * det.atan2(den);
        }
        total / (4.0 * std::f64::consts::PI)
    };
    let (mut near, mut outside, mut sunk, mut deepest) = (0usize, 0usize, 0usize, 0.0f64);
    for &p in &cloth {
        let k = key(p);
        let mut d = f64::INFINITY;
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    if let Some(ids) = grid.get(&[k[0] + dx, k[1] + dy, k[2] + dz]) {
                        for &t in ids {
                            d = d.min(triangle_distance(p, tris[t]));
                        }
                    }
                }
            }
        }
        if d <= 5e-4 {
            near += 1;
        } else if winding(p) < 0.5 {
            outside += 1;
        } else {
            sunk += 1;
            deepest = deepest.max(d);
        }
    }
    let fraction = (near + outside) as f64 / cloth.len() as f64;
    println!(
        "knee-high on body.glb ({} triangles): {near} cloth vertices within 0.5 mm, {outside} outside \
         farther, {sunk} inside deeper than 0.5 mm (deepest {:.2} mm) of {}: {:.2} % on or outside",
        tris.len(),
        1e3 * deepest,
        cloth.len(),
        100.0 * fraction
    );
    assert!(fraction >= 0.99, "{:.2} %", 100.0 * fraction);
    // The Khronos glTF validator: no errors, no warnings, no infos.
    if let Some(dir) = std::env::var_os("SKINTIGHT_GLTF_VALIDATOR").filter(|p| !p.is_empty()) {
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/gltf_validate.js");
        let run = std::process::Command::new("node")
            .arg(script)
            .args(["garment.glb", "garment-pressure.glb", "body.glb"].map(|f| out.join(f)))
            .env("NODE_PATH", Path::new(&dir).join("node_modules"))
            .output()
            .expect("node runs");
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        for line in String::from_utf8_lossy(&run.stdout).lines() {
            let report: serde_json::Value = serde_json::from_str(line).unwrap();
            for count in ["errors", "warnings", "infos"] {
                assert_eq!(report[count], 0, "{report}");
            }
        }
    }
}

/// The hem width (mm) of the knee-high's piece: its `bottom opening` edge in `patterns.json`, which the
/// knee-high cuts at B — the pattern's width at B.
fn hem_width_mm(out: &Path) -> f64 {
    let p = read_json(&out.join("patterns.json"));
    p["pieces"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|piece| piece["edges"].as_array().unwrap().iter())
        .filter(|e| e["name"] == "bottom opening")
        .map(|e| e["length_mm"].as_f64().unwrap())
        .sum()
}

/// Where a fitter starts a curve fabric: the ease `1/λ − 1` at which the course curve (linear between its
/// points) gives the bottom of the class II window, 23 mmHg, by the hoop law on an 18.2 cm ankle
/// (regular_1k's B girth): `T = p R`. (Started from the window's middle, 27.5 mmHg, the soft fabric ended
/// 0.6 mmHg above C's window; docs/BENCHMARKS.md.)
fn starting_ease(fabric: &str) -> f64 {
    let file = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("fabrics/{fabric}.json"));
    let f = read_json(&file);
    let tension = 23.0 * 133.322 * 0.182 / (2.0 * std::f64::consts::PI);
    let mut prev = [0.0, 0.0];
    for p in f["curves"]["course"].as_array().unwrap() {
        let p = [p[0].as_f64().unwrap(), p[1].as_f64().unwrap()];
        if p[1] >= tension {
            let e = prev[0] + (tension - prev[1]) / (p[1] - prev[1]) * (p[0] - prev[0]);
            return 1.0 / (1.0 + e) - 1.0;
        }
        prev = p;
    }
    panic!("{fabric}'s course curve never reaches {tension} N/m")
}

/// Issue 46's acceptance: the knee-high class II order on regular_1k with two library fabrics whose
/// course curves differ by a factor of two (`power_net_class2`, `power_net_soft`), each started from the
/// ease its course curve suggests ([`starting_ease`]; a curve fabric is worn at 30–50 % course elongation,
/// not the isotropic default's 11 %): both pass, and the stiffer fabric's pattern is wider at B. Prints the tables and widths of docs/BENCHMARKS.md.
#[test]
#[ignore = "two designs, minutes in the test profile: cargo test --test design_prescription curve_fabrics -- --ignored --nocapture"]
fn curve_fabrics_a_factor_two_apart_both_pass_and_the_stiffer_is_wider() {
    let body = std::env::var("SKINTIGHT_BODY").unwrap_or_else(|_| "regular_1k".into());
    let mut widths = Vec::new();
    let mut failures = Vec::new();
    for fabric in ["power_net_class2", "power_net_soft"] {
        let mut job = order("order_knee_high_class2.json", &body, 2);
        job["garment"]["fabric"] = serde_json::json!({"name": fabric});
        job["garment"]["ease"] = starting_ease(fabric).into();
        let dir = tempfile::tempdir().unwrap();
        let t = std::time::Instant::now();
        let out = design(&job, dir.path());
        let secs = t.elapsed().as_secs_f64();
        let stderr = String::from_utf8_lossy(&out.stderr);
        let r = read_json(&dir.path().join("out/result.json"));
        let width = hem_width_mm(&dir.path().join("out"));
        println!(
            "{body}, {fabric} (starting ease {:.3}): exit {:?}, {secs:.0} s, {} iterations, width at B {width:.1} mm, admissible {}\n\
             | band | height (cm) | girth (cm) | measured mmHg (probe min–max) | window mmHg | |\n\
             |---|---|---|---|---|---|\n{}",
            job["garment"]["ease"],
            out.status.code(),
            r["iterations"],
            r["admissible"],
            table(&r)
        );
        if !(out.status.success() && r["admissible"] == true && r["prescription"]["pass"] == true) {
            failures.push(format!("{fabric}: {stderr}"));
        }
        widths.push(width);
    }
    assert!(failures.is_empty(), "{failures:?}");
    assert!(
        widths[0] > widths[1],
        "stiffer fabric narrower at B: {widths:?} mm"
    );
}

/// An orthotropic curve fabric close to the isotropic default (E t = 540 N/m, ν = 0.33): linear course
/// and wale curves of slope E t, a shear curve of slope E t / (2 (1 + ν)) — the speed comparison's
/// fabric, so that both laws reach a like equilibrium and the times compare the laws.
fn linear_curve_fabric() -> serde_json::Value {
    let et = 5.4e6 * 1e-4;
    let g = et / (2.0 * 1.33);
    let line =
        |s: f64, ends: &[f64]| -> Vec<[f64; 2]> { ends.iter().map(|&e| [e, s * e]).collect() };
    serde_json::json!({
        "curves": {
            "course": line(et, &[0.1, 0.5, 1.0]),
            "wale": line(et, &[0.1, 0.5, 1.0]),
            "shear": line(g, &[0.1, 0.5, 1.0])
        },
        "thickness": 1e-4
    })
}

/// Issue 46's speed item: the pants (simulate) and the knee-high class II order (design) with the
/// orthotropic curve fabric of [`linear_curve_fabric`] against the isotropic default, side by side in
/// one run; prints the times of docs/BENCHMARKS.md and checks the ratio ≤ 1.5.
#[test]
#[ignore = "four runs, minutes: cargo test --test design_prescription curve_fabric_speed -- --ignored --nocapture"]
fn curve_fabric_speed_is_within_one_and_a_half_of_the_isotropic() {
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    let mut ratios = Vec::new();
    // The pants, simulate.
    let pants: serde_json::Value =
        serde_json::from_slice(&std::fs::read(examples.join("pants.json")).unwrap()).unwrap();
    let mut times = Vec::new();
    for curve in [false, true] {
        let mut scene = pants.clone();
        if curve {
            let limits = scene["garment"]["fabric"]["limits"].clone();
            scene["garment"]["fabric"] = linear_curve_fabric();
            scene["garment"]["fabric"]["limits"] = limits;
        }
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("scene.json");
        // The pants' body path is relative to the examples folder.
        let text = serde_json::to_string(&scene)
            .unwrap()
            .replace("\"../", &format!("\"{}/../", examples.display()));
        std::fs::write(&path, text).unwrap();
        let t = std::time::Instant::now();
        let out = std::process::Command::new(EXE)
            .args(["simulate", "--quiet"])
            .arg(&path)
            .arg("--out")
            .arg(dir.path().join("out"))
            .output()
            .unwrap();
        let secs = t.elapsed().as_secs_f64();
        let r = read_json(&dir.path().join("out/result.json"));
        println!(
            "pants simulate, {}: exit {:?}, {secs:.1} s, {} Newton iterations, converged {}, mean {:.2} mmHg",
            if curve { "curve fabric" } else { "isotropic" },
            out.status.code(),
            r["newton_iterations"],
            r["converged"],
            r["mean_pressure_mmhg"].as_f64().unwrap_or(f64::NAN)
        );
        assert_eq!(r["converged"], true);
        times.push(secs);
    }
    ratios.push(("pants", times[1] / times[0]));
    // The knee-high order, design.
    let mut times = Vec::new();
    for curve in [false, true] {
        let mut job = order("order_knee_high_class2.json", "regular_1k", 2);
        if curve {
            job["garment"]["fabric"] = linear_curve_fabric();
        }
        let dir = tempfile::tempdir().unwrap();
        let t = std::time::Instant::now();
        let out = design(&job, dir.path());
        let secs = t.elapsed().as_secs_f64();
        let r = read_json(&dir.path().join("out/result.json"));
        println!(
            "knee-high class II design, {}: exit {:?}, {secs:.1} s, {} iterations, B {:.1} mmHg, pass {}",
            if curve { "curve fabric" } else { "isotropic" },
            out.status.code(),
            r["iterations"],
            r["prescription"]["measured_b_mmhg"]
                .as_f64()
                .unwrap_or(f64::NAN),
            r["prescription"]["pass"]
        );
        times.push(secs);
    }
    ratios.push(("knee-high", times[1] / times[0]));
    println!("ratios curve / isotropic: {ratios:?}");
    for (what, r) in ratios {
        assert!(r <= 1.5, "{what}: {r}");
    }
}
