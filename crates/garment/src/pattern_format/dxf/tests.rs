//! Tests of the DXF-AAMA/ASTM writer: a round trip through the `dxf` crate, odd models, and ezdxf's audit.

use super::*;
use crate::pattern_format::test_pattern::bulged_tube_pattern;
use crate::pattern_format::verify::{EZDXF_CHECK, python_with};

fn read(bytes: &[u8]) -> Drawing {
    Drawing::load(&mut &bytes[..]).expect("the dxf crate reads the file back")
}

/// The block INSERTed for each piece, in order, with its insertion point.
fn piece_blocks(d: &Drawing) -> Vec<(&Block, Point)> {
    d.entities()
        .filter_map(|e| match &e.specific {
            EntityType::Insert(ins) => {
                let b = d.blocks().find(|b| b.name == ins.name).expect("block");
                Some((b, ins.location.clone()))
            }
            _ => None,
        })
        .collect()
}

fn on<'a>(b: &'a Block, layer: &'a str) -> impl Iterator<Item = &'a Entity> + 'a {
    b.entities.iter().filter(move |e| e.common.layer == layer)
}

fn polylines<'a>(b: &'a Block, layer: &'a str) -> Vec<Vec<Point>> {
    on(b, layer)
        .filter_map(|e| match &e.specific {
            EntityType::Polyline(p) => {
                assert!(p.is_closed());
                Some(p.vertices().map(|v| v.location.clone()).collect())
            }
            _ => None,
        })
        .collect()
}

fn lines<'a>(b: &'a Block, layer: &'a str) -> Vec<(Point, Point)> {
    on(b, layer)
        .filter_map(|e| match &e.specific {
            EntityType::Line(l) => Some((l.p1.clone(), l.p2.clone())),
            _ => None,
        })
        .collect()
}

fn assert_same_line(read: &[Point], model: &[Vec2], what: &str) {
    assert_eq!(read.len(), model.len(), "{what}: vertex count");
    for (r, m) in read.iter().zip(model) {
        let (dx, dy) = (r.x - m.x * MM, r.y - m.y * MM);
        assert!(
            dx.hypot(dy) < 0.01,
            "{what}: ({}, {}) vs {:?} mm",
            r.x,
            r.y,
            m * MM
        );
    }
}

#[test]
fn dxf_round_trip_reproduces_cut_lines_notches_grain_and_sew_lines() {
    let pattern = bulged_tube_pattern();
    let layout = sheet(&pattern, GAP, MARGIN);
    for variant in [DxfVariant::Aama, DxfVariant::Astm] {
        let bytes = dxf_pattern(&pattern, variant).unwrap();
        let d = read(&bytes);
        assert_eq!(d.header.version, AcadVersion::R2000);
        assert_eq!(d.header.default_drawing_units, Units::Millimeters);
        assert_eq!(d.header.drawing_units, DrawingUnits::Metric);
        let blocks = piece_blocks(&d);
        assert_eq!(blocks.len(), pattern.pieces.len(), "{variant:?}");
        for (i, (piece, (block, at))) in pattern.pieces.iter().zip(&blocks).enumerate() {
            let what = format!("{variant:?} piece {i}");
            assert_eq!(block.name, piece.name);
            let o = layout.offsets[i] * MM;
            assert!((at.x - o.x).abs() < 1e-6 && (at.y - o.y).abs() < 1e-6);
            // Layer 1: the cut line, once, to 0.01 mm; the piece text.
            let cut = polylines(block, "1");
            assert_eq!(cut.len(), 1, "{what}");
            assert_same_line(&cut[0], &piece.cut_line, &what);
            let texts: Vec<&str> = on(block, "1")
                .filter_map(|e| match &e.specific {
                    EntityType::Text(t) => Some(t.value.as_str()),
                    _ => None,
                })
                .collect();
            assert!(texts.contains(&format!("Piece Name: {}", piece.name).as_str()));
            assert!(texts.contains(&"Quantity: 1"), "{texts:?}");
            assert!(texts.contains(&"Size: class II"), "{texts:?}");
            // Layers 2 and 3: every cut-line vertex is a turn or a curve point.
            assert_eq!(
                on(block, "2").count() + on(block, "3").count(),
                piece.cut_line.len()
            );
            assert!(on(block, "2").count() >= 4, "{what}: the corners");
            // Layer 4: one slit per notch, from the cut line, `depth` long, towards the sewing line.
            let notches = lines(block, "4");
            assert!(!piece.notches.is_empty());
            assert_eq!(notches.len(), piece.notches.len(), "{what}");
            for ((a, b), n) in notches.iter().zip(&piece.notches) {
                assert!((a.x - n.on_cut_line.x * MM).abs() < 0.01);
                assert!((a.y - n.on_cut_line.y * MM).abs() < 0.01);
                assert!(((b.x - a.x).hypot(b.y - a.y) - n.depth * MM).abs() < 0.01);
            }
            // Layer 7: the grain line.
            let grain = lines(block, "7");
            assert_eq!(grain.len(), 1);
            assert!((grain[0].1.y - piece.grain_line.to.y * MM).abs() < 0.01);
            // Layer 14: the sew line.
            let sew = polylines(block, "14");
            assert_eq!(sew.len(), 1);
            assert_same_line(&sew[0], &piece.sewing_line, &what);
            // Layer 15: the label lines (folded to ASCII, control characters dropped).
            let notes: Vec<&str> = on(block, "15")
                .filter_map(|e| match &e.specific {
                    EntityType::Text(t) => Some(t.value.as_str()),
                    _ => None,
                })
                .collect();
            assert!(notes.contains(&"Customer: Zoe Muller"), "{notes:?}");
            // ASTM: the boundary again on 84.
            let astm = polylines(block, "84");
            match variant {
                DxfVariant::Aama => assert!(astm.is_empty()),
                DxfVariant::Astm => assert_same_line(&astm[0], &piece.cut_line, &what),
            }
        }
        let style: Vec<&str> = d
            .entities()
            .filter_map(|e| match &e.specific {
                EntityType::Text(t) if e.common.layer == "1" => Some(t.value.as_str()),
                _ => None,
            })
            .collect();
        assert!(style.contains(&"Style Name: bulged tube"), "{style:?}");
        assert!(style.contains(&"Units: METRIC"), "{style:?}");
        if variant == DxfVariant::Astm {
            assert!(d.layers().any(|l| l.name == "85"));
        }
        // The file is plain ASCII.
        assert!(bytes.is_ascii());
    }
}

#[test]
fn dxf_writes_degenerate_and_odd_models_without_panicking() {
    let mut pattern = bulged_tube_pattern();
    pattern.pieces[0].name = "a/b<c>\u{0}^ü".into();
    pattern.pieces[1].name = "a/b<c>\u{0}^ü".into();
    pattern.pieces[1].cut_line.clear();
    pattern.pieces[1].sewing_line.truncate(1);
    pattern.pieces[1].edges.clear();
    pattern.pieces[0].notches[0].depth = 0.0;
    pattern.labels.template = "x".repeat(1000);
    for variant in [DxfVariant::Aama, DxfVariant::Astm] {
        let d = read(&dxf_pattern(&pattern, variant).unwrap());
        let names: Vec<String> = piece_blocks(&d)
            .iter()
            .map(|(b, _)| b.name.clone())
            .collect();
        assert_eq!(names, ["a_b_c____", "a_b_c_____2"]);
    }
    let empty = Pattern {
        labels: Default::default(),
        pieces: vec![],
        seams: vec![],
    };
    read(&dxf_aama(&empty).unwrap());
}

/// ezdxf (the Python DXF library CAD tools are checked with) audits both files to 0 errors and finds
/// per piece one cut line on layer 1, the notches on layer 4, the grain line on layer 7 and one sew
/// line on layer 14.
#[test]
fn ezdxf_audits_both_files_without_errors() {
    let Some(python) = python_with("ezdxf", "the ezdxf audit of patterns.dxf") else {
        return;
    };
    let pattern = bulged_tube_pattern();
    let dir = crate::pattern_format::verify::scratch_dir("ezdxf");
    for (variant, file) in [
        (DxfVariant::Aama, "patterns.dxf"),
        (DxfVariant::Astm, "patterns-astm.dxf"),
    ] {
        let path = dir.join(file);
        std::fs::write(&path, dxf_pattern(&pattern, variant).unwrap()).unwrap();
        let report = python.run(EZDXF_CHECK, &[path.to_str().unwrap()]);
        eprintln!("ezdxf {file}: {report}");
        assert_eq!(report["errors"], 0, "{file}: {report}");
        assert_eq!(report["fixes"], 0, "{file}: {report}");
        assert_eq!(report["insunits"], 4, "{file}: {report}");
        let pieces = report["pieces"].as_array().unwrap();
        assert_eq!(pieces.len(), pattern.pieces.len(), "{file}: {report}");
        for (p, piece) in pieces.iter().zip(&pattern.pieces) {
            assert_eq!(p["1"], 1, "{file}: {report}");
            assert_eq!(p["4"], piece.notches.len(), "{file}: {report}");
            assert_eq!(p["7"], 1, "{file}: {report}");
            assert_eq!(p["14"], 1, "{file}: {report}");
            assert_eq!(
                p["84"],
                if variant == DxfVariant::Astm { 1 } else { 0 },
                "{file}: {report}"
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// The marker's DXF: ezdxf audits it to 0 errors and reads back every placed piece (its cut line and grain
/// line in fabric coordinates) and the fabric's edges; by `geo`'s boolean operations on what ezdxf read,
/// no two cut lines overlap and each lies on the fabric, and each grain line runs along the length.
#[test]
fn ezdxf_reads_the_marker_with_its_pieces_apart_on_the_fabric() {
    use crate::marker::{MarkerParams, marker};
    use geo::{Area, BooleanOps, Coord, LineString, Polygon};
    let pattern = bulged_tube_pattern();
    let m = marker(&[&pattern, &pattern], &MarkerParams::default()).unwrap();
    let placed = m.pattern(&[&pattern, &pattern]);
    let bytes = dxf_marker(&placed, &m).unwrap();
    // The dxf crate reads it back too: one block per placed copy, inserted at the origin.
    let d = read(&bytes);
    let blocks = piece_blocks(&d);
    assert_eq!(blocks.len(), 2 * pattern.pieces.len());
    assert!(blocks.iter().all(|(_, at)| at.x == 0.0 && at.y == 0.0));
    let Some(python) = python_with("ezdxf", "the ezdxf audit of patterns-marker.dxf") else {
        return;
    };
    let dir = crate::pattern_format::verify::scratch_dir("ezdxf-marker");
    let path = dir.join(MARKER_FILE);
    std::fs::write(&path, &bytes).unwrap();
    let report = python.run(EZDXF_CHECK, &[path.to_str().unwrap()]);
    assert_eq!(report["errors"], 0, "{report}");
    assert_eq!(report["fixes"], 0, "{report}");
    let fabric = report["fabric"].as_array().unwrap();
    assert_eq!(fabric.len(), 1, "{report}");
    let corner = |k: usize, i: usize| fabric[0][k][i].as_f64().unwrap();
    let (length, width) = (corner(2, 0), corner(2, 1));
    assert!((length - m.length * 1e3).abs() < 1e-6 && (width - m.width * 1e3).abs() < 1e-6);
    let pieces = report["pieces"].as_array().unwrap();
    assert_eq!(pieces.len(), 2 * pattern.pieces.len());
    let polys: Vec<Polygon<f64>> = pieces
        .iter()
        .map(|p| {
            let ring: Vec<Coord<f64>> = p["cut"]
                .as_array()
                .unwrap()
                .iter()
                .map(|q| Coord {
                    x: q[0].as_f64().unwrap(),
                    y: q[1].as_f64().unwrap(),
                })
                .collect();
            assert!(ring.len() >= 3);
            for c in &ring {
                assert!(
                    c.x >= -1e-6 && c.x <= length + 1e-6 && c.y >= -1e-6 && c.y <= width + 1e-6
                );
            }
            Polygon::new(LineString::new(ring), vec![])
        })
        .collect();
    for (i, p) in pieces.iter().enumerate() {
        let g = &p["grain"];
        let dx = g[1][0].as_f64().unwrap() - g[0][0].as_f64().unwrap();
        let dy = g[1][1].as_f64().unwrap() - g[0][1].as_f64().unwrap();
        assert!(dy.abs() <= dx.abs() * 1f64.to_radians().tan(), "{g}");
        for j in 0..i {
            let overlap = polys[i].intersection(&polys[j]).unsigned_area();
            assert!(
                overlap < 1e-3,
                "pieces {i} and {j} overlap by {overlap} mm²"
            );
        }
    }
    let area: f64 = polys.iter().map(|p| p.unsigned_area()).sum();
    assert!(
        (area / (length * width) - m.efficiency).abs() < 1e-6,
        "{area}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
