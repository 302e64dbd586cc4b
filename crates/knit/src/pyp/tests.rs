use super::*;
use crate::test_support::shared_yarns_dir;

#[test]
fn reads_all_shared_patterns_with_consistent_topology() {
    let dir = shared_yarns_dir();
    let expected_vertices = [
        ("stock_9", 100),
        ("rib_9", 356),
        ("basket_9", 80),
        ("satin_9", 130),
        ("stocktiniest_9", 13),
    ];
    for (name, n) in expected_vertices {
        let p = PeriodicPattern::read(&dir.join(name).join("pattern.pyp")).unwrap();
        assert_eq!(p.len(), n, "{name}");
        assert!(p.radius > 0.0 && p.period[0] > 0.0 && p.period[1] > 0.0);
        // Edge i starts at vertex i; every vertex ends exactly one edge.
        let mut ends = vec![0; n];
        for (i, e) in p.edges.iter().enumerate() {
            assert_eq!(e.start, i);
            ends[e.end] += 1;
            assert!(
                e.shift[0].abs() <= 1 && e.shift[1].abs() <= 1,
                "{name} edge {i} shift {:?}",
                e.shift
            );
        }
        assert!(ends.iter().all(|&c| c == 1));
        // The yarn cycles cover every vertex once.
        let total: usize = p.yarn_cycles().iter().map(|(c, _)| c.len()).sum();
        assert_eq!(total, n);
    }
}

#[test]
fn rest_lengths_match_geometry_when_edges_are_matched_by_first_vertex() {
    // README: within 0.3 % for stock, rib and satin. The basket and tiny stockinette patterns are stored
    // off their rest lengths (up to 9.4 % and 5.7 %), which this test records as a fact of the data.
    let dir = shared_yarns_dir();
    for (name, tolerance) in [
        ("stock_9", 0.003),
        ("rib_9", 0.003),
        ("satin_9", 0.003),
        ("basket_9", 0.1),
        ("stocktiniest_9", 0.06),
    ] {
        let p = PeriodicPattern::read(&dir.join(name).join("pattern.pyp")).unwrap();
        let worst = (0..p.len())
            .map(|i| (p.edge_length(i) / p.rest_length[i] - 1.0).abs())
            .fold(0.0, f64::max);
        assert!(
            worst < tolerance,
            "{name}: worst relative length error {worst}"
        );
    }
}

#[test]
fn reference_twist_matches_space_parallel_transport() {
    // RefT[i] is the angle from the parallel transport of the previous edge's director onto edge i to edge
    // i's director, about edge i's tangent: checked to float precision on the patterns whose stored
    // positions are their rest state.
    use crate::frames::{parallel_transport, signed_angle};
    let dir = shared_yarns_dir();
    for name in ["stock_9", "rib_9", "satin_9", "stocktiniest_9"] {
        let p = PeriodicPattern::read(&dir.join(name).join("pattern.pyp")).unwrap();
        let prev = p.previous_edges();
        for i in 0..p.len() {
            let t = |k: usize| {
                let a = p.positions[k];
                let b = p.edge_end_position(k);
                let l = p.edge_length(k);
                [(b[0] - a[0]) / l, (b[1] - a[1]) / l, (b[2] - a[2]) / l]
            };
            let (t0, t1) = (t(prev[i]), t(i));
            let pu = parallel_transport(p.reference_director[prev[i]], t0, t1);
            let angle = signed_angle(pu, p.reference_director[i], t1);
            assert!(
                (angle - p.reference_twist[i]).abs() < 2e-4,
                "{name} vertex {i}: {angle} vs {}",
                p.reference_twist[i]
            );
        }
    }
}

fn base_text() -> String {
    std::fs::read_to_string(shared_yarns_dir().join("stocktiniest_9/pattern.pyp")).unwrap()
}

fn parse_err(text: &str) -> PypError {
    PeriodicPattern::parse(text, Path::new("broken.pyp")).unwrap_err()
}

#[test]
fn missing_section_is_named() {
    let text = base_text();
    let start = text.find("*RT").unwrap();
    let end = text.find("*RefD1").unwrap();
    let broken = format!("{}{}", &text[..start], &text[end..]);
    let e = parse_err(&broken);
    assert!(e.to_string().contains("missing section *RT"), "{e}");
    assert!(e.to_string().starts_with("broken.pyp:0:"), "{e}");
}

#[test]
fn edge_to_missing_vertex_is_named_with_its_line() {
    let broken = base_text().replacen("11 12 0 0", "11 13 0 0", 1);
    let e = parse_err(&broken);
    let line = broken
        .lines()
        .position(|l| l.starts_with("11 13 0 0"))
        .unwrap()
        + 1;
    assert_eq!(e.line, line);
    assert!(e.problem.contains("does not exist"), "{e}");
}

#[test]
fn non_positive_radius_is_rejected() {
    for bad in ["-9.9999997e-05", "0"] {
        let broken = base_text().replacen("9.9999997e-05 13", &format!("{bad} 13"), 1);
        let e = parse_err(&broken);
        assert_eq!(e.line, 2);
        assert!(e.problem.contains("radius"), "{e}");
    }
}

#[test]
fn wrong_column_count_non_finite_and_count_mismatch_are_rejected() {
    let text = base_text();
    // Wrong column count in *Q.
    let broken = text.replacen(
        "-0.00012523646 -0.00017114044 0.00010873298 0.078571236",
        "-0.00012523646 -0.00017114044 0.00010873298",
        1,
    );
    let e = parse_err(&broken);
    assert!(e.problem.contains("needs 4 numbers per line"), "{e}");
    // Non-finite number.
    let broken = text.replacen("0.0001154272", "nan", 1);
    let e = parse_err(&broken);
    assert!(e.problem.contains("not a finite number"), "{e}");
    // Not a number.
    let broken = text.replacen("0.0001154272", "0.00011x", 1);
    assert!(parse_err(&broken).problem.contains("is not a number"));
    // Count disagreement: drop the last *RL line.
    let broken = text.replacen("0.00021525353\n", "", 1);
    let e = parse_err(&broken);
    assert!(
        e.problem.contains("the counts must agree") || e.problem.contains("counts"),
        "{e}"
    );
    // A vertex starting two edges.
    let broken = text.replacen("12 0 0 1", "11 0 0 1", 1);
    let e = parse_err(&broken);
    assert!(e.problem.contains("starts a second edge"), "{e}");
    // Unreadable file.
    let e = PeriodicPattern::read(Path::new("/nonexistent/pattern.pyp")).unwrap_err();
    assert!(e.problem.contains("cannot read"));
}
