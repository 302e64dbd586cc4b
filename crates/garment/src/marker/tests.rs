//! Tests of the marker: no two placed pieces overlap and every piece lies on the fabric (checked with `geo`'s
//! boolean operations, not with the engine that placed them), grain along the length, the length against
//! its lower bound, cut quantities and mirrored pieces, and the errors.

use super::*;
use crate::math::Vec3;
use crate::pattern::{FaceSide, Placement};
use crate::pattern_format::test_pattern::bulged_tube_pattern;
use geo::{Area, BooleanOps, Coord, LineString, Polygon};

/// A piece with cut line `outline` (m) and a grain line along `grain`.
fn piece(name: &str, outline: Vec<Vec2>, grain: Vec2) -> Piece {
    let c = outline.iter().fold(Vec2::zeros(), |a, p| a + p) / outline.len() as Real;
    Piece {
        name: name.into(),
        sewing_line: outline.clone(),
        edges: Vec::new(),
        cut_line: outline,
        notches: Vec::new(),
        grain_line: GrainLine {
            from: c - 0.05 * grain,
            to: c + 0.05 * grain,
        },
        drill_holes: vec![c],
        cut_quantity: 1,
        mirrored: false,
        face_side: FaceSide::FaceUp,
        label_anchor: c,
        placement: Placement {
            rotation_xyz: [0.0; 3],
            translation: Vec3::zeros(),
        },
    }
}

fn pattern_of(pieces: Vec<Piece>) -> Pattern {
    Pattern {
        labels: OrderLabels::default(),
        pieces,
        seams: Vec::new(),
    }
}

/// A tapered leg-like piece: `length` along x, `wide` across at x = 0 narrowing to `narrow` at the end,
/// turned by `angle` (the grain turns with it).
fn tapered(name: &str, length: Real, wide: Real, narrow: Real, angle: Real) -> Piece {
    let (s, c) = angle.sin_cos();
    let r = |x: Real, y: Real| Vec2::new(c * x - s * y, s * x + c * y);
    let outline = vec![
        r(0.0, 0.0),
        r(length, 0.5 * (wide - narrow)),
        r(length, 0.5 * (wide + narrow)),
        r(0.0, wide),
        r(-0.02, 0.5 * wide),
    ];
    piece(name, outline, r(1.0, 0.0))
}

fn geo_polygon(points: &[Vec2]) -> Polygon<f64> {
    let ring: Vec<Coord<f64>> = points.iter().map(|p| Coord { x: p.x, y: p.y }).collect();
    Polygon::new(LineString::new(ring), vec![])
}

/// The independent check: every placed cut line inside `[0, length] × [0, width]`, no two overlapping by
/// more than `1e-9` m² (geo's boolean intersection), the grain along ±x within `1e-9` rad. Returns the
/// placed pieces.
fn check(marker: &Marker, patterns: &[&Pattern]) -> Pattern {
    let placed = marker.pattern(patterns);
    assert_eq!(placed.pieces.len(), marker.placements.len());
    let polys: Vec<Polygon<f64>> = placed
        .pieces
        .iter()
        .map(|p| geo_polygon(&p.cut_line))
        .collect();
    for (i, p) in placed.pieces.iter().enumerate() {
        for q in &p.cut_line {
            assert!(
                q.x >= -1e-9 && q.x <= marker.length + 1e-9,
                "{}: x {} off [0, {}]",
                p.name,
                q.x,
                marker.length
            );
            assert!(
                q.y >= -1e-9 && q.y <= marker.width + 1e-9,
                "{}: y {} off the fabric",
                p.name,
                q.y
            );
        }
        let g = p.grain_line.to - p.grain_line.from;
        let angle = g.y.atan2(g.x).abs();
        assert!(
            angle < 1e-9 || (PI - angle) < 1e-9,
            "{}: grain at {angle} rad",
            p.name
        );
        for j in 0..i {
            let overlap = polys[i].intersection(&polys[j]).unsigned_area();
            assert!(
                overlap < 1e-9,
                "{} and {} overlap by {overlap} m²",
                p.name,
                placed.pieces[j].name
            );
        }
    }
    let area: Real = polys.iter().map(|p| p.unsigned_area()).sum();
    assert!((area - marker.pieces_area).abs() < 1e-9 * area.max(1.0));
    assert!(
        (marker.efficiency - area / (marker.width * marker.length)).abs() < 1e-12,
        "{marker:?}"
    );
    assert!(marker.length >= marker.lower_bound - 1e-9);
    placed
}

#[test]
fn strips_of_one_length_stack_across_the_fabric_at_the_bound() {
    // Four 1 m × 0.35 m rectangles on 1.5 m: side by side across, 1 m (+ the gap) long.
    let rect = |k: usize| {
        piece(
            &format!("r{k}"),
            vec![
                Vec2::new(0.0, 0.0),
                Vec2::new(1.0, 0.0),
                Vec2::new(1.0, 0.35),
                Vec2::new(0.0, 0.35),
            ],
            Vec2::new(1.0, 0.0),
        )
    };
    let p = pattern_of((0..4).map(rect).collect());
    let m = marker(&[&p], &MarkerParams::default()).unwrap();
    check(&m, &[&p]);
    assert!((m.lower_bound - 1.0).abs() < 1e-12);
    assert!(m.length <= 1.0 + 0.003, "{}", m.length);
}

#[test]
fn grain_lines_end_along_the_length_whatever_their_angle_on_the_piece() {
    let pieces: Vec<Piece> = [0.0, 0.7, 1.9, -2.5, PI / 2.0]
        .iter()
        .enumerate()
        .map(|(k, &a)| tapered(&format!("t{k}"), 0.6, 0.25, 0.1, a))
        .collect();
    let p = pattern_of(pieces);
    let m = marker(&[&p], &MarkerParams::default()).unwrap();
    check(&m, &[&p]);
    // Each piece's length (0.6 m plus the 2 cm point) runs along x.
    for pl in &m.placements {
        let placed = pl.place(&p.pieces[pl.piece]);
        let xs: Vec<Real> = placed.cut_line.iter().map(|q| q.x).collect();
        let span = xs.iter().cloned().fold(Real::NEG_INFINITY, Real::max)
            - xs.iter().cloned().fold(Real::INFINITY, Real::min);
        assert!((span - 0.62).abs() < 1e-9, "{span}");
    }
    // A one-way marker keeps every grain pointing to +x.
    let one_way = marker(
        &[&p],
        &MarkerParams {
            two_way: false,
            ..MarkerParams::default()
        },
    )
    .unwrap();
    let placed = check(&one_way, &[&p]);
    for piece in &placed.pieces {
        assert!(piece.grain_line.to.x > piece.grain_line.from.x);
    }
}

#[test]
fn cut_quantities_and_mirrored_pieces_are_all_placed() {
    let mut left = tapered("sleeve", 0.5, 0.3, 0.12, 0.3);
    left.cut_quantity = 3;
    left.mirrored = true;
    let mut other = tapered("gusset", 0.2, 0.15, 0.1, 0.0);
    other.cut_quantity = 2;
    let mut none = tapered("unused", 0.2, 0.15, 0.1, 0.0);
    none.cut_quantity = 0;
    let p = pattern_of(vec![left.clone(), other, none]);
    let m = marker(&[&p], &MarkerParams::default()).unwrap();
    check(&m, &[&p]);
    assert_eq!(m.placements.len(), 5);
    let mut copies: Vec<(usize, u32)> = m.placements.iter().map(|pl| (pl.piece, pl.copy)).collect();
    copies.sort();
    assert_eq!(copies, vec![(0, 0), (0, 1), (0, 2), (1, 0), (1, 1)]);
    for pl in &m.placements {
        assert_eq!(pl.mirrored, pl.piece == 0);
    }
    // A mirrored copy is the mirror image: its outline turns the other way (clockwise) and has the area.
    let pl = m.placements.iter().find(|pl| pl.piece == 0).unwrap();
    let placed = pl.place(&left);
    assert!(polygon_area(&placed.cut_line) < 0.0);
    assert!(
        (polygon_area(&placed.cut_line).abs() - polygon_area(&left.cut_line).abs()).abs() < 1e-12
    );
}

#[test]
fn a_real_pattern_and_a_batch_of_it_nest_without_overlap() {
    let tube = bulged_tube_pattern();
    let one = marker(&[&tube], &MarkerParams::default()).unwrap();
    check(&one, &[&tube]);
    assert!(one.length <= 1.1 * one.lower_bound, "{one:?}");
    let batch = marker(&[&tube, &tube, &tube], &MarkerParams::default()).unwrap();
    let placed = check(&batch, &[&tube, &tube, &tube]);
    assert_eq!(batch.placements.len(), 3 * tube.pieces.len());
    assert!(placed.pieces.iter().any(|p| p.name.ends_with("(3)")));
    assert!(
        batch.efficiency > one.efficiency,
        "{} vs {}",
        batch.efficiency,
        one.efficiency
    );
}

#[test]
fn bad_settings_and_pieces_are_refused_naming_what_to_fix() {
    let p = pattern_of(vec![tapered("leg", 0.9, 0.4, 0.1, 0.2)]);
    for (params, field) in [
        (
            MarkerParams {
                width: Real::NAN,
                ..Default::default()
            },
            "width",
        ),
        (
            MarkerParams {
                width: -1.0,
                ..Default::default()
            },
            "width",
        ),
        (
            MarkerParams {
                gap: -0.001,
                ..Default::default()
            },
            "gap",
        ),
        (
            MarkerParams {
                step: 0.0,
                ..Default::default()
            },
            "step",
        ),
        (
            MarkerParams {
                orders: 0,
                ..Default::default()
            },
            "orders",
        ),
    ] {
        match marker(&[&p], &params) {
            Err(MarkerError::BadParameter { field: f, .. }) => assert_eq!(f, field),
            other => panic!("{field}: {other:?}"),
        }
    }
    // Narrower than the piece across its grain (0.4 m and the gap).
    let e = marker(
        &[&p],
        &MarkerParams {
            width: 0.39,
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(
        matches!(e, MarkerError::TooWide { ref piece, .. } if piece == "leg"),
        "{e}"
    );
    assert!(e.to_string().contains("0.4020 m across"), "{e}");
    assert!(
        marker(
            &[&p],
            &MarkerParams {
                width: 0.41,
                ..Default::default()
            }
        )
        .is_ok()
    );
    assert_eq!(
        marker(&[], &MarkerParams::default()).unwrap_err(),
        MarkerError::NoPieces
    );
    let mut flat = p.clone();
    flat.pieces[0].grain_line.to = flat.pieces[0].grain_line.from;
    assert!(matches!(
        marker(&[&flat], &MarkerParams::default()),
        Err(MarkerError::BadPiece { .. })
    ));
    let mut line = p.clone();
    line.pieces[0].cut_line = vec![Vec2::zeros(), Vec2::new(1.0, 0.0), Vec2::new(2.0, 0.0)];
    assert!(matches!(
        marker(&[&line], &MarkerParams::default()),
        Err(MarkerError::BadPiece { .. })
    ));
    let mut many = p.clone();
    many.pieces[0].cut_quantity = MAX_COPIES + 1;
    assert!(matches!(
        marker(&[&many], &MarkerParams::default()),
        Err(MarkerError::BadPiece { .. })
    ));
}
