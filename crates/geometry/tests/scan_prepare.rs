//! Scan preparation on raw scans made from the sample bodies (subdivided, noised, holed at the soles and the
//! crown, islands, non-manifold spots, millimetres, +z up, binary PLY), and on scans that are not a body.

use std::time::Instant;

use skintight_geometry::anthropometry::measure_body;
use skintight_geometry::mesh::io::{MeshFormat, read_mesh};
use skintight_geometry::scan::raw_scan::{RawScanParams, raw_scan_ply};
use skintight_geometry::scan::surface_deviation::{
    ClosestPointGrid, deviation_of_points, vertex_areas,
};
use skintight_geometry::scan::{
    DEFAULT_MAX_FACES, PrepareError, PrepareParams, prepare_scan, read_scan_bytes,
};
use skintight_geometry::test_meshes;
use skintight_geometry::{MeshCheckParams, TriMesh, Vec3, mesh_report};

const SHAPES: [&str; 5] = ["regular", "male", "athletic", "overweight", "kid"];

/// Mean and largest distance (mm) between the prepared body and the clean one, both ways at vertices.
fn deviation_from_clean(result: &TriMesh, clean: &TriMesh) -> (f64, f64) {
    let clean_grid = ClosestPointGrid::new(&clean.positions, &clean.faces, 0.02);
    let wc = vertex_areas(&clean.positions, &clean.faces);
    let result_grid = ClosestPointGrid::new(&result.positions, &result.faces, 0.02);
    let wb = vertex_areas(&result.positions, &result.faces);
    let a = deviation_of_points(&result.positions, |v| wb[v], &clean_grid);
    let b = deviation_of_points(&clean.positions, |v| wc[v], &result_grid);
    (1e3 * 0.5 * (a.mean + b.mean), 1e3 * a.max.max(b.max))
}

fn check_prepared(
    shape: &str,
    clean_name: &str,
    scan_params: &RawScanParams,
    target: usize,
) -> (TriMesh, TriMesh) {
    let clean = read_mesh(&test_meshes::body(clean_name)).unwrap();
    let bytes = raw_scan_ply(&clean, scan_params);
    let t = Instant::now();
    let scan = read_scan_bytes(&bytes, MeshFormat::Ply, DEFAULT_MAX_FACES).unwrap();
    let params = PrepareParams {
        target_faces: target,
        ..Default::default()
    };
    let (body, report) = prepare_scan(&scan, &params).unwrap_or_else(|e| panic!("{shape}: {e}"));
    let secs = t.elapsed().as_secs_f64();
    let r = mesh_report(&body, &MeshCheckParams::default());
    assert!(
        r.closed && r.manifold && r.oriented,
        "{shape}: {:?}",
        r.problems
    );
    assert_eq!(r.genus, Some(0), "{shape}");
    assert!(body.signed_volume() > 0.0, "{shape}: outward");
    assert!(r.problems.is_empty(), "{shape}: {:?}", r.problems);
    assert_eq!(report.units, "mm");
    assert_eq!(report.up, "+z");
    assert!(report.facing_detected, "{shape}");
    assert!(report.holes_filled >= 3, "{shape}: {}", report.holes_filled);
    assert!(report.components_removed >= scan_params.islands, "{shape}");
    let (mean, max) = deviation_from_clean(&body, &clean);
    // The unbiased fit: the remeshed body straddles the scan, so it encloses the clean body's volume
    // (vertices left on the scan make chords inside it: −0.2 % to −0.5 % of the volume).
    let dv = 100.0 * (body.signed_volume() / clean.signed_volume() - 1.0);
    eprintln!(
        "{shape}: volume {dv:+.3} % of the clean body's; fit: signed mean {:.3} -> {:.3} mm, largest move {:.2} mm",
        report.fit_signed_mean_before_mm,
        report.fit_signed_mean_after_mm,
        report.fit_max_displacement_mm
    );
    // Measured on the 1k scans without the fit: −0.34 % to −0.49 %; with it −0.02 % to −0.16 %. (A Loop-
    // subdivided scan lies inside the clean polyhedron itself, so only a scan that samples the clean
    // surface — midpoint subdivision — is held to it.)
    if !scan_params.smooth {
        assert!(
            dv.abs() < 0.25,
            "{shape}: volume {dv} % of the clean body's"
        );
    }
    assert!(report.fit_signed_mean_after_mm.abs() < 0.02, "{shape}");
    eprintln!(
        "{shape}: {} scan faces -> {} faces in {secs:.2} s; vs scan mean {:.2} mm, Hausdorff {:.1} mm; vs clean mean {mean:.2} mm, max {max:.1} mm; stages {:?}",
        scan.num_faces(),
        body.num_faces(),
        report.mean_deviation_mm,
        report.hausdorff_mm,
        report.timing_s
    );
    assert!(
        mean < 2.0,
        "{shape}: mean deviation from the clean body {mean} mm"
    );
    assert!(report.mean_deviation_mm < 2.0, "{shape}");
    assert!(report.hausdorff_mm.is_finite());
    (body, clean)
}

/// `body measure` on the prepared scan agrees with the clean body: the height of every landmark named
/// `include` within `cm` centimetres and its girth within `percent` %.
fn check_measurements(
    shape: &str,
    prepared: &TriMesh,
    clean: &TriMesh,
    cm: f64,
    percent: f64,
    include: impl Fn(&str) -> bool,
) {
    let a = measure_body(prepared).unwrap_or_else(|e| panic!("{shape}: prepared: {e}"));
    let b = measure_body(clean).unwrap_or_else(|e| panic!("{shape}: clean: {e}"));
    assert_eq!(a.landmarks.len(), b.landmarks.len());
    let mut bad = Vec::new();
    let (mut dh, mut dg) = (0.0_f64, 0.0_f64);
    for (p, c) in a.landmarks.iter().zip(&b.landmarks) {
        assert_eq!((&p.name, p.side), (&c.name, c.side));
        let h = (p.height_m - c.height_m).abs();
        let g = 100.0 * (p.girth_m - c.girth_m).abs() / c.girth_m;
        dh = dh.max(h);
        dg = dg.max(g);
        if std::env::var_os("SCAN_PREPARE_VERBOSE").is_some() {
            eprintln!(
                "  {shape} {} {:?}: height {:+.1} mm, girth {:.1} vs {:.1} cm ({:+.2} %)",
                p.name,
                p.side,
                1e3 * (p.height_m - c.height_m),
                1e2 * p.girth_m,
                1e2 * c.girth_m,
                100.0 * (p.girth_m - c.girth_m) / c.girth_m
            );
        }
        if !include(&p.name) {
            continue;
        }
        if h > 0.01 * cm || g > percent {
            bad.push(format!(
                "{} {:?}: height {:.1} vs {:.1} cm, girth {:.1} vs {:.1} cm ({g:.2} %)",
                p.name,
                p.side,
                1e2 * p.height_m,
                1e2 * c.height_m,
                1e2 * p.girth_m,
                1e2 * c.girth_m
            ));
        }
    }
    eprintln!(
        "{shape}: prepared vs clean landmarks: heights within {:.1} mm, girths within {dg:.2} %",
        1e3 * dh
    );
    assert!(bad.is_empty(), "{shape}:\n{}", bad.join("\n"));
}

/// Raw scans of every 1k body (≈ 40 k triangles) come back closed, manifold, genus 0, within 2 mm, and
/// they measure as the clean body's do: landmark heights within 1 cm, girths within 2.5 %.
/// (The 1k body is a coarse polyhedron with sharp convex edges that a 24 000-face remesh rounds off;
/// measured 2026-12-02: leg and torso girths within 0.85 % (overweight) to 1.94 % (regular) with the
/// unbiased fit, 2.0 % to 3.6 % without it. The arms were left out until the arm axis was refitted to its
/// own perpendicular sections — before, on the coarse hands the axis, and with it the wrist, could land
/// 3 cm apart; since, every girth arms included within 0.82–1.44 %, heights within 5.1 mm. The acceptance
/// comparison, 1 %, is on the 12k scans below.)
#[test]
fn raw_scans_of_the_1k_bodies_are_prepared() {
    for shape in SHAPES {
        let (prepared, clean) = check_prepared(
            shape,
            &format!("{shape}_1k.obj"),
            &RawScanParams {
                smooth: false,
                ..Default::default()
            },
            skintight_geometry::scan::DEFAULT_TARGET_FACES,
        );
        check_measurements(shape, &prepared, &clean, 1.0, 2.5, |_| true);
    }
}

/// The acceptance run: raw scans of every 12k body (≈ 400 k triangles), default resolution, under 30 s in
/// release. `cargo test --release -p skintight-geometry --test scan_prepare -- --ignored --nocapture`
#[test]
#[ignore]
fn raw_scans_of_the_12k_bodies_are_prepared_in_time() {
    for shape in SHAPES {
        let t = Instant::now();
        check_prepared(
            shape,
            &format!("{shape}_12k.obj"),
            &RawScanParams::default(),
            skintight_geometry::scan::DEFAULT_TARGET_FACES,
        );
        let s = t.elapsed().as_secs_f64();
        assert!(s < 30.0, "{shape}: {s} s");
        // Loop subdivision moves the scan inside the clean polyhedron by up to a millimetre (a convex
        // control mesh's limit surface lies inside it), which alone shortens girths by 1–2 %; the
        // measurement comparison takes a scan that samples the clean surface itself (midpoint
        // subdivision), damaged the same way.
        let (prepared, clean) = check_prepared(
            shape,
            &format!("{shape}_12k.obj"),
            &RawScanParams {
                smooth: false,
                ..RawScanParams::default()
            },
            skintight_geometry::scan::DEFAULT_TARGET_FACES,
        );
        // The issue asks for girths within 1 %. Measured 2026-12-02 (docs/BENCHMARKS.md), worst girth
        // per body (regular, male, athletic, overweight, kid): uniform remesh 1.47 / 1.75 / 1.94 / 1.47 /
        // 2.06 % (every girth short: chords inside the scan); with the unbiased fit 1.26 / 1.86 / 1.40 /
        // 0.70 / 1.19 % (wrists over: a 20 mm radius at 12 mm edges); with the fit and edges graded by
        // curvature every girth but the armpits' within 0.73 %, the armpits 0.4–2.4 % short (the arm
        // axis, fitted to oblique horizontal sections, tilted with the axilla); with the arm axis refitted
        // to its own perpendicular sections every girth, the armpits' included, within 1 %.
        check_measurements(shape, &prepared, &clean, 1.0, 1.0, |_| true);
    }
}

/// A chair seen from the side (an L: seat block and back), 0.5 m wide: one closed component, 1.05 m tall.
fn chair() -> TriMesh {
    // Profile in (z, y), counter-clockwise seen from +x.
    let profile = [
        (0.0, 0.0),
        (0.5, 0.0),
        (0.5, 1.05),
        (0.45, 1.05),
        (0.45, 0.5),
        (0.0, 0.5),
    ];
    let n = profile.len();
    let mut m = TriMesh::default();
    for x in [0.0, 0.5] {
        for &(z, y) in &profile {
            m.positions.push(Vec3::new(x, y, z));
        }
    }
    // Caps: fans from the reflex corner 4.
    for k in [5, 0, 1, 2] {
        let next = (k + 1) % n;
        m.faces.push([4, next, k]);
        m.faces.push([n + 4, n + k, n + next]);
    }
    for k in 0..n {
        let next = (k + 1) % n;
        m.faces.push([k, next, n + next]);
        m.faces.push([k, n + next, n + k]);
    }
    m
}

#[test]
fn bad_scans_end_with_one_clear_line() {
    let p = PrepareParams::default();
    let chair = chair();
    let r = mesh_report(&chair, &MeshCheckParams::default());
    assert!(
        r.closed && r.manifold && r.components == 1,
        "{:?}",
        r.problems
    );
    let e = prepare_scan(&chair, &p).unwrap_err();
    assert!(matches!(e, PrepareError::NotABody(_)), "{e}");
    // A body of 40 m.
    let body = read_mesh(&test_meshes::body("regular_1k.obj")).unwrap();
    let mut giant = body.clone();
    giant.positions.iter_mut().for_each(|x| *x *= 40.0 / 1.59);
    let e = prepare_scan(&giant, &p).unwrap_err();
    assert!(e.to_string().contains("no reading"), "{e}");
    // Two people.
    let mut two = body.clone();
    let n = two.num_vertices();
    two.positions
        .extend(body.positions.iter().map(|x| x + Vec3::new(1.5, 0.0, 0.2)));
    two.faces
        .extend(body.faces.iter().map(|f| f.map(|v| v + n)));
    let e = prepare_scan(&two, &p).unwrap_err();
    assert!(e.to_string().contains("two bodies"), "{e}");
    // Empty file, and 10 M faces above the limit (told from the header).
    let e = read_scan_bytes(b"", MeshFormat::Obj, DEFAULT_MAX_FACES).unwrap_err();
    assert!(e.to_string().contains("empty"), "{e}");
    let header = b"ply\nformat binary_little_endian 1.0\nelement vertex 5000002\nproperty float x\nproperty float y\nproperty float z\nelement face 10000000\nproperty list uchar int vertex_indices\nend_header\n";
    let e = read_scan_bytes(header, MeshFormat::Ply, DEFAULT_MAX_FACES).unwrap_err();
    assert!(e.to_string().contains("above the limit of 5000000"), "{e}");
    assert!(!e.to_string().contains('\n'));
}
