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
