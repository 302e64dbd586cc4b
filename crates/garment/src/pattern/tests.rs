//! Tests of the pattern model: named edges, cut lines, notches, grain lines, seam truing and the files
//! written from it, on a bulged tube (not developable, so its flattened seam sides differ).

use super::*;
use crate::pattern::notches::Run;
use crate::pattern::seam_allowance::{
    CornerStyle, OffsetError, cut_line, first_self_crossing, polygon_contains,
};
use crate::pattern_format::test_pattern::bulged_tube;
use crate::pattern_format::{garmentcode::garmentcode, json::patterns_json, svg::pattern_svg};
use crate::seam_truing::{SeamTruingParams, max_seam_mismatch, true_seams};
use skintight_geometry::polygon_area::polygon_area;

fn params() -> PatternParams {
    PatternParams {
        up: Vec3::z(),
        ..Default::default()
    }
}

/// Distance from `p` to the closed polyline `line`.
fn distance(line: &[Vec2], p: Vec2) -> Real {
    let n = line.len();
    (0..n)
        .map(|i| {
            let (a, b) = (line[i], line[(i + 1) % n]);
            let e = b - a;
            let t = ((p - a).dot(&e) / e.norm_squared()).clamp(0.0, 1.0);
            (a + e * t - p).norm()
        })
        .fold(Real::INFINITY, Real::min)
}

#[test]
fn seam_truing_makes_every_seam_edge_pair_equal_with_a_small_change() {
    let mut g = bulged_tube();
    let before = max_seam_mismatch(&g);
    // The flattening leaves the sides of the seams of a non-developable tube unequal.
    assert!(before > 1e-4, "mismatch before truing {before} m");
    let original: Vec<Vec<Vec2>> = g.panels.iter().map(|p| p.pattern.clone()).collect();
    let report = true_seams(&mut g, &SeamTruingParams::default()).unwrap();
    assert!(
        report.iterations >= 1 && report.iterations <= 5,
        "{report:?}"
    );
    assert!(report.max_seam_mismatch_after < 1e-6, "{report:?}");
    assert!((report.max_seam_mismatch_before - before).abs() < 1e-15);
    // Edge by edge.
    for s in &g.seams {
        let [a, b] = &s.vertices;
        let (pa, pb) = (
            &g.panels[s.panels[0]].pattern,
            &g.panels[s.panels[1]].pattern,
        );
        for k in 0..a.len() - 1 {
            let la = (pa[a[k + 1]] - pa[a[k]]).norm();
            let lb = (pb[b[k + 1]] - pb[b[k]]).norm();
            assert!((la - lb).abs() < 1e-7, "edge {k}: {la} vs {lb}");
        }
    }
    // A small, smooth correction: no vertex moves more than a few times the mismatch.
    let moved = g
        .panels
        .iter()
        .zip(&original)
        .flat_map(|(p, o)| p.pattern.iter().zip(o).map(|(a, b)| (a - b).norm()))
        .fold(0.0, Real::max);
    assert!(
        moved > 0.0 && moved < 5.0 * before,
        "moved {moved} for {before}"
    );
    assert!((moved - report.max_displacement).abs() < 1e-12);
    for p in &g.panels {
        for f in &p.faces {
            let [a, b, c] = f.map(|v| p.pattern[v]);
            assert!(crate::lscm::signed_area(a, b, c) > 0.0);
        }
    }
    // Truing again (anchors placed anew along the trued sides) changes next to nothing.
    let again = true_seams(&mut g, &SeamTruingParams::default()).unwrap();
    assert!(again.max_seam_mismatch_before < 1e-6, "{again:?}");
    assert!(
        again.max_displacement < 0.1 * report.max_displacement,
        "{again:?}"
    );
}

#[test]
fn seam_truing_refuses_sides_of_different_lengths() {
    let mut g = bulged_tube();
    g.seams[0].vertices[1].pop();
    let e = true_seams(&mut g, &SeamTruingParams::default()).unwrap_err();
    assert!(
        matches!(
            e,
            crate::seam_truing::SeamTruingError::UnequalSides { seam: 0, .. }
        ),
        "{e}"
    );
    let mut g = bulged_tube();
    let e = true_seams(
        &mut g,
        &SeamTruingParams {
            max_edge_pairs: 3,
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(
        matches!(
            e,
            crate::seam_truing::SeamTruingError::TooManyEdgePairs { limit: 3, .. }
        ),
        "{e}"
    );
}

#[test]
fn pieces_have_named_edges_cut_lines_notches_and_grain() {
    let mut g = bulged_tube();
    true_seams(&mut g, &SeamTruingParams::default()).unwrap();
    let labels = OrderLabels {
        order_id: "A-17".into(),
        customer: "C. Ustomer".into(),
        ..Default::default()
    };
    let p = pattern(&g, &params(), labels).unwrap();
    assert_eq!(p.pieces.len(), 2);
    assert_eq!(p.seams.len(), 2);
    for (i, piece) in p.pieces.iter().enumerate() {
        assert!(polygon_area(&piece.sewing_line) > 0.0, "counter-clockwise");
        // Two seam sides and two openings, top and bottom.
        let mut names: Vec<&str> = piece.edges.iter().map(|e| e.name.as_str()).collect();
        names.sort();
        assert_eq!(
            names,
            ["bottom opening", "seam 1", "seam 2", "top opening"],
            "piece {i}"
        );
        // Runs cover the sewing line once, in order.
        let n = piece.sewing_line.len();
        let mut covered = 0;
        for (k, e) in piece.edges.iter().enumerate() {
            assert_eq!(e.end, piece.edges[(k + 1) % piece.edges.len()].start);
            let run = Run {
                sewing: &piece.sewing_line,
                start: e.start,
                end: e.end,
            };
            covered += run.segments();
            assert!((run.length() - e.length).abs() < 1e-12);
        }
        assert_eq!(covered, n);
        // The top opening is higher on the body than the bottom one: its allowance is the opening's.
        for e in &piece.edges {
            let expected = match e.kind {
                EdgeKind::Seam { partner, .. } => {
                    assert_eq!(partner, 1 - i);
                    0.006
                }
                EdgeKind::Opening { .. } => 0.02,
            };
            assert_eq!(e.allowance, expected);
        }
        // The cut line: simple, counter-clockwise, around the sewing line, at least the smallest allowance
        // from it, and every sewing vertex inside a run exactly its allowance away from it.
        assert!(first_self_crossing(&piece.cut_line).is_none());
        assert!(polygon_area(&piece.cut_line) > polygon_area(&piece.sewing_line));
        for &q in &piece.sewing_line {
            assert!(polygon_contains(&piece.cut_line, q));
        }
        for &c in &piece.cut_line {
            assert!(distance(&piece.sewing_line, c) > 0.006 - 1e-9);
        }
        for e in &piece.edges {
            let run = Run {
                sewing: &piece.sewing_line,
                start: e.start,
                end: e.end,
            };
            // Away from the corners (where the other run's allowance line comes closer).
            let mut along = 0.0;
            for k in 1..run.segments() {
                let (u, v) = (
                    piece.sewing_line[(e.start + k - 1) % n],
                    piece.sewing_line[(e.start + k) % n],
                );
                along += (v - u).norm();
                if along.min(e.length - along) < 0.05 {
                    continue;
                }
                let d = distance(&piece.cut_line, v);
                assert!(
                    (d - e.allowance).abs() < 1e-3 * e.allowance,
                    "{}: {d} vs {}",
                    e.name,
                    e.allowance
                );
            }
        }
        // Notches: on the sewing line, their slits starting on the cut line, no deeper than the allowance.
        for notch in &piece.notches {
            assert!(distance(&piece.sewing_line, notch.at) < 1e-12);
            assert!(distance(&piece.cut_line, notch.on_cut_line) < 1e-9);
            assert!(notch.depth > 0.0 && notch.depth <= 0.003 + 1e-15);
        }
        // The grain runs along the tube: parallel to the seams, which run along z.
        let seam = piece.edges.iter().find(|e| e.name == "seam 1").unwrap();
        let run = Run {
            sewing: &piece.sewing_line,
            start: seam.start,
            end: seam.end,
        };
        let (a, _) = run.point_at(0.0);
        let (b, _) = run.point_at(seam.length);
        let along = (b - a).normalize();
        let grain = (piece.grain_line.to - piece.grain_line.from).normalize();
        assert!(
            along.dot(&grain).abs() > 0.97,
            "grain {grain:?} vs seam {along:?}"
        );
        assert!(polygon_contains(&piece.sewing_line, piece.grain_line.from));
        assert!(polygon_contains(&piece.sewing_line, piece.grain_line.to));
        assert!(polygon_contains(&piece.sewing_line, piece.label_anchor));
        let lines = piece.label_lines(&p.labels);
        assert_eq!(lines[0], format!("Piece: {}", piece.name));
        assert!(lines.contains(&"Order: A-17".to_string()));
        assert!(
            lines.contains(&"Cut 1".to_string()) && lines.contains(&"Face side up".to_string())
        );
    }
    // Seams sew: equal sides, notches at the same arc lengths on both, at the ends and every 10 cm.
    for (k, s) in p.seams.iter().enumerate() {
        assert!((s.lengths[0] - s.lengths[1]).abs() < 1e-6, "{s:?}");
        assert!(s.mismatch().abs() < 1e-6);
        let arcs = |piece: usize| -> Vec<Real> {
            p.pieces[piece]
                .notches
                .iter()
                .filter(|n| n.seam == Some(k))
                .map(|n| n.arc_length)
                .collect()
        };
        let (a, b) = (arcs(s.pieces[0]), arcs(s.pieces[1]));
        assert_eq!(a, b);
        let expected = 2 + ((s.lengths[0] - 0.05) / 0.1).floor() as usize;
        assert_eq!(a.len(), expected, "{a:?} on a seam {} m long", s.lengths[0]);
        assert_eq!(a[0], 0.0);
        assert_eq!(*a.last().unwrap(), s.lengths[0]);
        // Matching notches: the same arc length lands at the same fraction of the same seam edge, so the
        // two marks are at the same distance from the seam's start along each side.
        for (na, nb) in p.pieces[s.pieces[0]]
            .notches
            .iter()
            .filter(|n| n.seam == Some(k))
            .zip(
                p.pieces[s.pieces[1]]
                    .notches
                    .iter()
                    .filter(|n| n.seam == Some(k)),
            )
        {
            assert_eq!(na.arc_length, nb.arc_length);
        }
    }
}

#[test]
fn user_notches_and_their_errors() {
    let mut g = bulged_tube();
    true_seams(&mut g, &SeamTruingParams::default()).unwrap();
    let base = pattern(&g, &params(), OrderLabels::default()).unwrap();
    let with = PatternParams {
        notches: vec![UserNotch {
            seam: 1,
            arc_length: 0.123,
        }],
        ..params()
    };
    let p = pattern(&g, &with, OrderLabels::default()).unwrap();
    for piece in 0..2 {
        let users: Vec<_> = p.pieces[piece].notches.iter().filter(|n| n.user).collect();
        assert_eq!(users.len(), 1);
        assert_eq!(users[0].arc_length, 0.123);
        assert_eq!(users[0].seam, Some(1));
        assert_eq!(
            p.pieces[piece].notches.len(),
            base.pieces[piece].notches.len() + 1
        );
    }
    let off = PatternParams {
        notches: vec![UserNotch {
            seam: 0,
            arc_length: 5.0,
        }],
        ..params()
    };
    assert!(matches!(
        pattern(&g, &off, OrderLabels::default()),
        Err(PatternError::NotchOffSeam {
            index: 0,
            seam: 1,
            ..
        })
    ));
    let missing = PatternParams {
        notches: vec![UserNotch {
            seam: 7,
            arc_length: 0.1,
        }],
        ..params()
    };
    assert!(matches!(
        pattern(&g, &missing, OrderLabels::default()),
        Err(PatternError::NoSuchSeam {
            field: "notches",
            seam: 8,
            seams: 2,
            ..
        })
    ));
    for bad in [
        PatternParams {
            seam_allowance: -1.0,
            ..params()
        },
        PatternParams {
            notch_spacing: 0.0,
            ..params()
        },
        PatternParams {
            opening_allowance: Real::NAN,
            ..params()
        },
        PatternParams {
            cut_quantity: 0,
            ..params()
        },
    ] {
        assert!(matches!(
            pattern(&g, &bad, OrderLabels::default()),
            Err(PatternError::BadParameter { .. })
        ));
    }
}

#[test]
fn per_seam_allowance_and_square_corners() {
    let mut g = bulged_tube();
    true_seams(&mut g, &SeamTruingParams::default()).unwrap();
    let p = pattern(
        &g,
        &PatternParams {
            seam_allowances: vec![(1, 0.01)],
            corner: CornerStyle::Square,
            ..params()
        },
        OrderLabels::default(),
    )
    .unwrap();
    for piece in &p.pieces {
        for e in &piece.edges {
            if e.name == "seam 2" {
                assert_eq!(e.allowance, 0.01);
            } else if e.name == "seam 1" {
                assert_eq!(e.allowance, 0.006);
            }
        }
        assert!(first_self_crossing(&piece.cut_line).is_none());
    }
}

#[test]
fn cut_line_of_simple_shapes() {
    let square = [
        Vec2::new(0.0, 0.0),
        Vec2::new(1.0, 0.0),
        Vec2::new(1.0, 1.0),
        Vec2::new(0.0, 1.0),
    ];
    let corners = [true; 4];
    // Equal allowances: the square grown by 0.1, mitre and square corners alike at right angles.
    for style in [CornerStyle::Mitre, CornerStyle::Square] {
        let cut = cut_line(&square, &[0.1; 4], &corners, style).unwrap();
        assert_eq!(cut.len(), 4, "{style:?}: {cut:?}");
        assert!((polygon_area(&cut) - 1.44).abs() < 1e-12);
    }
    // A wider allowance on the bottom side (a hem): a 1.3 × 1.2 rectangle.
    let cut = cut_line(&square, &[0.2, 0.1, 0.1, 0.1], &corners, CornerStyle::Mitre).unwrap();
    assert!((polygon_area(&cut) - 1.2 * 1.3).abs() < 1e-12);
    // Acute corners (a right triangle's two 45° ones): the mitre is one point, the squared corner two.
    let triangle = [
        Vec2::new(0.0, 0.0),
        Vec2::new(1.0, 0.0),
        Vec2::new(0.0, 1.0),
    ];
    let mitre = cut_line(&triangle, &[0.1; 3], &[true; 3], CornerStyle::Mitre).unwrap();
    let squared = cut_line(&triangle, &[0.1; 3], &[true; 3], CornerStyle::Square).unwrap();
    assert_eq!(mitre.len(), 3);
    assert_eq!(squared.len(), 5);
    assert!(polygon_area(&squared) < polygon_area(&mitre));
    for c in &squared {
        assert!(distance(&triangle, *c) > 0.1 - 1e-12);
    }
    // Blunt corners (a pentagon's): squared corners are mitres.
    let house = [
        Vec2::new(0.0, 0.0),
        Vec2::new(1.0, 0.0),
        Vec2::new(1.0, 1.0),
        Vec2::new(0.5, 1.5),
        Vec2::new(0.0, 1.0),
    ];
    assert_eq!(
        cut_line(&house, &[0.1; 5], &[true; 5], CornerStyle::Mitre).unwrap(),
        cut_line(&house, &[0.1; 5], &[true; 5], CornerStyle::Square).unwrap()
    );
    // A concave L: the offset of the inner corner is the mitre inside, and the area is exact
    // (L of area 3 grown by 0.1: perimeter 8 · 0.1 + 5 convex corners' squares − 1 concave corner's).
    let l = [
        Vec2::new(0.0, 0.0),
        Vec2::new(2.0, 0.0),
        Vec2::new(2.0, 1.0),
        Vec2::new(1.0, 1.0),
        Vec2::new(1.0, 2.0),
        Vec2::new(0.0, 2.0),
    ];
    let cut = cut_line(&l, &[0.1; 6], &[false; 6], CornerStyle::Mitre).unwrap();
    assert!((polygon_area(&cut) - (3.0 + 0.8 + 5.0 * 0.01 - 0.01)).abs() < 1e-12);
    // Zero allowance: the sewing line itself.
    let cut = cut_line(&square, &[0.0; 4], &corners, CornerStyle::Mitre).unwrap();
    assert_eq!(cut, square.to_vec());
    // A slot narrower than two allowances: the allowances of its two sides overlap.
    let u = [
        Vec2::new(0.0, 0.0),
        Vec2::new(1.0, 0.0),
        Vec2::new(1.0, 1.0),
        Vec2::new(0.55, 1.0),
        Vec2::new(0.55, 0.2),
        Vec2::new(0.45, 0.2),
        Vec2::new(0.45, 1.0),
        Vec2::new(0.0, 1.0),
    ];
    assert!(cut_line(&u, &[0.01; 8], &[false; 8], CornerStyle::Mitre).is_ok());
    assert!(matches!(
        cut_line(&u, &[0.1; 8], &[false; 8], CornerStyle::Mitre),
        Err(OffsetError::SelfIntersects { .. })
    ));
    assert!(matches!(
        cut_line(&square, &[-0.1; 4], &corners, CornerStyle::Mitre),
        Err(OffsetError::BadAllowance(_))
    ));
    // A finely sampled circle of radius 0.1 grown by 0.02: radius 0.12, no loops.
    let circle: Vec<Vec2> = (0..200)
        .map(|i| {
            let a = std::f64::consts::TAU * i as Real / 200.0;
            Vec2::new(0.1 * a.cos(), 0.1 * a.sin())
        })
        .collect();
    let cut = cut_line(&circle, &[0.02; 200], &[false; 200], CornerStyle::Mitre).unwrap();
    for c in &cut {
        assert!((c.norm() - 0.12).abs() < 1e-4, "{}", c.norm());
    }
    // Its inside out (a hole's outline, clockwise) grows inwards: tight curvature, loops removed.
    let inner: Vec<Vec2> = circle.iter().rev().copied().collect();
    let cut = cut_line(&inner, &[0.02; 200], &[false; 200], CornerStyle::Mitre).unwrap();
    assert!(first_self_crossing(&cut).is_none());
}

#[test]
fn files_carry_the_model() {
    let mut g = bulged_tube();
    true_seams(&mut g, &SeamTruingParams::default()).unwrap();
    let labels = OrderLabels {
        order_id: "<A&B>".into(),
        ..Default::default()
    };
    let p = pattern(&g, &params(), labels).unwrap();
    // patterns.json: versioned, in mm, every piece and seam.
    let j = patterns_json(&p);
    assert_eq!(j["schema_version"], SCHEMA_VERSION);
    assert_eq!(j["units"], "mm");
    assert_eq!(j["pieces"].as_array().unwrap().len(), 2);
    let piece = &j["pieces"][0];
    assert_eq!(
        piece["sewing_line_mm"].as_array().unwrap().len(),
        p.pieces[0].sewing_line.len()
    );
    let x: Real = piece["cut_line_mm"][0][0].as_f64().unwrap();
    assert!((x - p.pieces[0].cut_line[0].x * 1e3).abs() < 1e-9);
    assert_eq!(piece["edges"].as_array().unwrap().len(), 4);
    let seams = j["seams"].as_array().unwrap();
    assert_eq!(seams.len(), 2);
    assert!(seams[0]["difference_mm"].as_f64().unwrap().abs() < 1e-3);
    // GarmentCode: one straight edge per sewing-line segment, one stitch per seam segment pair, and the
    // stitched edges equally long (cm).
    let gc = garmentcode(&p);
    assert_eq!(gc["properties"]["units_in_meter"], 100);
    let panels = gc["pattern"]["panels"].as_object().unwrap();
    assert_eq!(panels.len(), 2);
    let stitches = gc["pattern"]["stitches"].as_array().unwrap();
    let expected: usize = p
        .seams
        .iter()
        .map(|s| {
            let e = &p.pieces[s.pieces[0]].edges[s.edges[0]];
            Run {
                sewing: &p.pieces[s.pieces[0]].sewing_line,
                start: e.start,
                end: e.end,
            }
            .segments()
        })
        .sum();
    assert_eq!(stitches.len(), expected);
    let edge_length = |side: &serde_json::Value| {
        let panel = &panels[side["panel"].as_str().unwrap()];
        let e = side["edge"].as_u64().unwrap() as usize;
        let [a, b] = [0, 1].map(|k| panel["edges"][e]["endpoints"][k].as_u64().unwrap() as usize);
        let v = |i: usize| {
            Vec2::new(
                panel["vertices"][i][0].as_f64().unwrap(),
                panel["vertices"][i][1].as_f64().unwrap(),
            )
        };
        (v(b) - v(a)).norm()
    };
    // Stitched edges pair up along each seam: the sums of their lengths are the two (equal) sides.
    let (a, b): (Real, Real) = stitches
        .iter()
        .map(|s| (edge_length(&s[0]), edge_length(&s[1])))
        .fold((0.0, 0.0), |(x, y), (a, b)| (x + a, y + b));
    let total: Real = p.seams.iter().map(|s| s.lengths[0] * 100.0).sum();
    assert!(
        (a - total).abs() < 1e-6 && (b - total).abs() < 1e-5,
        "{a} {b} vs {total} cm"
    );
    // SVG: layers, balanced, escaped.
    let svg = pattern_svg(&p);
    for layer in [
        "cut-line",
        "sew-line",
        "seams",
        "notches",
        "grain-line",
        "drill-holes",
        "labels",
        "scale",
    ] {
        assert!(
            svg.contains(&format!(r#"<g id="{layer}" inkscape:groupmode="layer""#)),
            "{layer}"
        );
    }
    assert_eq!(svg.matches("<g ").count(), svg.matches("</g>").count());
    assert_eq!(svg.matches("<text").count(), svg.matches("</text>").count());
    let notches: usize = p.pieces.iter().map(|q| q.notches.len()).sum();
    assert_eq!(svg.matches(r#"<line class="notch""#).count(), notches);
    assert!(svg.contains("Order: &lt;A&amp;B&gt;") && !svg.contains("<A&B>"));
    assert!(!svg.contains("NaN") && !svg.contains("inf"));
    assert!(svg.contains(r#"width="100.000" height="100.000""#));
}
