//! Tests of the PDF writers: page sizes and counts, paper names, odd models, and the test square measured
//! in pdftoppm renders.

use super::*;
use crate::marker::{MarkerParams, marker};
use crate::pattern_format::test_pattern::bulged_tube_pattern;
use crate::pattern_format::verify::{
    fill_pixels_per_page, measure_square, missing, on_path, page_count,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Whether a text string of the PDF starts with or is `s` (ASCII): pdf-writer writes ASCII strings as
/// literals, others (a WinAnsi dash, say) as hex.
fn contains_text(pdf: &[u8], s: &str) -> bool {
    let text = String::from_utf8_lossy(pdf).to_ascii_lowercase();
    let hex: String = s.bytes().map(|b| format!("{b:02x}")).collect();
    text.contains(&format!("({}", s.to_ascii_lowercase())) || text.contains(&format!("<{hex}"))
}

/// The `/MediaBox` numbers of the pages, in order.
fn media_boxes(pdf: &[u8]) -> Vec<[f32; 4]> {
    let text = String::from_utf8_lossy(pdf);
    text.split("/MediaBox [")
        .skip(1)
        .map(|s| {
            let v: Vec<f32> = s[..s.find(']').unwrap()]
                .split_whitespace()
                .map(|x| x.parse().unwrap())
                .collect();
            [v[0], v[1], v[2], v[3]]
        })
        .collect()
}

#[test]
fn wide_pdf_is_one_page_the_size_of_the_sheet() {
    let pattern = bulged_tube_pattern();
    let pdf = pattern_pdf(&pattern);
    assert!(pdf.starts_with(b"%PDF-"));
    assert_eq!(page_count(&pdf), 1);
    let d = Drawing::new(&pattern);
    let [x0, y0, w, h] = media_boxes(&pdf)[0];
    assert_eq!((x0, y0), (0.0, 0.0));
    assert!((w as Real - d.size.0 * 72.0 / 25.4).abs() < 0.01, "{w}");
    assert!((h as Real - d.size.1 * 72.0 / 25.4).abs() < 0.01, "{h}");
    assert!(String::from_utf8_lossy(&pdf).contains("/BaseFont /Helvetica"));
}

#[test]
fn tiled_pdf_has_the_pages_its_key_says() {
    let pattern = bulged_tube_pattern();
    for paper in [Paper::A4, Paper::Letter, Paper::A3] {
        let (pdf, grid) = tiled_pdf(&pattern, paper);
        assert_eq!(grid.pages, 1 + grid.tiles, "{paper:?}");
        assert!(grid.tiles <= grid.rows * grid.cols, "{paper:?}");
        assert_eq!(page_count(&pdf), grid.pages, "{paper:?}");
        let (pw, ph) = paper.size_mm();
        for [_, _, w, h] in media_boxes(&pdf) {
            assert!((w as Real - pw * 72.0 / 25.4).abs() < 0.01);
            assert!((h as Real - ph * 72.0 / 25.4).abs() < 0.01);
        }
        // The tiles cover the drawing with the overlap, and no more tiles than that.
        let d = Drawing::new(&pattern);
        let t = Tiles::new(d.size, paper);
        assert!(grid.cols as Real * t.step.0 + OVERLAP_MM >= d.size.0);
        assert!(grid.rows as Real * t.step.1 + OVERLAP_MM >= d.size.1);
        assert!((grid.cols - 1) as Real * t.step.0 + OVERLAP_MM < d.size.0);
        assert!((grid.rows - 1) as Real * t.step.1 + OVERLAP_MM < d.size.1);
        // The first tile (the test square's) is printed.
        assert!(contains_text(&pdf, "row 1 / col 1 "), "{paper:?}");
        assert!(contains_text(&pdf, &format!("page {0} of {0}", grid.pages)));
    }
    // The bulged tube is wider than an A4 page: more than one column.
    let (_, grid) = tiled_pdf(&pattern, Paper::A4);
    assert!(grid.cols >= 2 && grid.rows >= 2, "{grid:?}");
}

#[test]
fn paper_names_parse_and_unknown_ones_name_the_field() {
    assert_eq!("a4".parse::<Paper>(), Ok(Paper::A4));
    assert_eq!(" Letter ".parse::<Paper>(), Ok(Paper::Letter));
    assert_eq!("A3".parse::<Paper>(), Ok(Paper::A3));
    let e = "B5".parse::<Paper>().unwrap_err();
    assert!(e.to_string().starts_with("paper: "), "{e}");
}

#[test]
fn pdfs_survive_degenerate_models() {
    let mut pattern = bulged_tube_pattern();
    pattern.pieces[0].cut_line.clear();
    pattern.pieces[1].sewing_line.truncate(1);
    pattern.pieces[1].label_anchor.x = Real::INFINITY;
    pattern.pieces[1].name = "(unbalanced \\ ) ✂ é".into();
    assert_eq!(page_count(&pattern_pdf(&pattern)), 1);
    let empty = Pattern {
        labels: Default::default(),
        pieces: vec![],
        seams: vec![],
    };
    assert_eq!(page_count(&pattern_pdf(&empty)), 1);
    let (pdf, grid) = tiled_pdf(&empty, Paper::A4);
    assert_eq!(page_count(&pdf), grid.pages);
    // A huge sheet is tiled only so far, and its wide page gets a user unit.
    let mut huge = bulged_tube_pattern();
    huge.pieces[0].cut_line[0].x = 1.0e7;
    let (pdf, grid) = tiled_pdf(&huge, Paper::A3);
    assert_eq!(grid.cols, MAX_TILES_PER_SIDE);
    assert!(grid.rows <= 2, "{grid:?}");
    assert_eq!(page_count(&pdf), grid.pages);
    assert!(contains_text(&pdf, "The sheet needs more than"));
    assert_eq!(page_count(&pattern_pdf(&huge)), 1);
    // A very long sheet gets a user unit and stays true to scale.
    assert_eq!(page_units(6000.0, 300.0).2, 2.0);
}

/// pdftoppm renders the first tile page of the A4 file and the wide page, and the test square measures
/// 100 mm ± 0.5 mm both ways on each.
#[test]
fn test_square_measures_100_mm_in_the_rendered_pages() {
    if !on_path("pdftoppm") {
        missing(
            "the pdftoppm render of patterns-a4.pdf",
            "pdftoppm is not on PATH (Debian: poppler-utils)",
        );
        return;
    }
    let pattern = bulged_tube_pattern();
    let d = Drawing::new(&pattern);
    // The first tile page (page 2), at 200 dpi.
    let (pdf, _) = tiled_pdf(&pattern, Paper::A4);
    let (page, left, top) = tiled_test_square(&pattern, Paper::A4);
    assert_eq!(page, 2);
    let (w, h) = measure_square(&pdf, 2, 200.0, left, top);
    eprintln!("A4 tile page 2 at 200 dpi: test square {w:.3} mm × {h:.3} mm");
    assert!(
        (w - 100.0).abs() <= 0.5 && (h - 100.0).abs() <= 0.5,
        "{w} × {h} mm"
    );
    // The wide page, at 100 dpi.
    let pdf = pattern_pdf(&pattern);
    let top = d.size.1 - (d.square.1 + TEST_SQUARE_MM);
    let (w, h) = measure_square(&pdf, 1, 100.0, d.square.0, top);
    eprintln!("wide page at 100 dpi: test square {w:.3} mm × {h:.3} mm");
    assert!(
        (w - 100.0).abs() <= 0.5 && (h - 100.0).abs() <= 0.5,
        "{w} × {h} mm"
    );
}

/// The clipped area of a polygon in a rectangle is `geo`'s boolean intersection's, for seeded random
/// star-shaped (concave) polygons against rectangles inside, across and outside them.
#[test]
fn clipped_area_is_the_area_of_the_intersection() {
    use geo::{Area, BooleanOps, Coord, LineString, Polygon, Rect};
    let mut rng = ChaCha8Rng::seed_from_u64(47);
    for _ in 0..200 {
        let (cx, cy) = (rng.random_range(-50.0..50.0), rng.random_range(-50.0..50.0));
        let n = rng.random_range(3..24);
        let poly: Vec<(Real, Real)> = (0..n)
            .map(|k| {
                let a =
                    std::f64::consts::TAU * (k as Real + rng.random_range(0.0..0.8)) / n as Real;
                let r = rng.random_range(5.0..60.0);
                (cx + r * a.cos(), cy + r * a.sin())
            })
            .collect();
        let (x0, y0) = (rng.random_range(-80.0..60.0), rng.random_range(-80.0..60.0));
        let (w, h) = (rng.random_range(1.0..90.0), rng.random_range(1.0..90.0));
        let ring: Vec<Coord<f64>> = poly.iter().map(|&(x, y)| Coord { x, y }).collect();
        let g = Polygon::new(LineString::new(ring), vec![]);
        let r = Rect::new(
            Coord { x: x0, y: y0 },
            Coord {
                x: x0 + w,
                y: y0 + h,
            },
        )
        .to_polygon();
        let want = g.intersection(&r).unsigned_area();
        let got = clipped_area(&poly, [x0, y0, x0 + w, y0 + h]);
        assert!(
            (got - want).abs() <= 1e-9 * want.max(1.0),
            "{got} vs {want}"
        );
    }
}

/// A sheet with a tall piece beside a short one: the tiles above the short piece meet nothing and are
/// left out; every tile page printed shows a piece's fill in a pdftoppm render (or is the test square's).
#[test]
fn tiled_pdf_leaves_out_the_tiles_that_meet_no_piece() {
    let mut pattern = bulged_tube_pattern();
    // Stretch the first piece to 1.2 m tall: the second stays about 0.3 m tall beside it.
    let tall = &mut pattern.pieces[0];
    for q in tall.cut_line.iter_mut().chain(tall.sewing_line.iter_mut()) {
        q.y *= 4.0;
    }
    let (pdf, grid) = tiled_pdf(&pattern, Paper::A4);
    assert!(grid.tiles < grid.rows * grid.cols, "{grid:?}");
    assert_eq!(page_count(&pdf), grid.pages);
    assert!(contains_text(&pdf, &format!("page {0} of {0}", grid.pages)));
    assert!(
        contains_text(&pdf, "The "),
        "the key says tiles are left out"
    );
    if !on_path("pdftoppm") {
        missing(
            "the pdftoppm render of the tiled PDF",
            "pdftoppm is not on PATH",
        );
        return;
    }
    let fill = fill_pixels_per_page(&pdf, 30.0);
    assert_eq!(fill.len(), grid.pages);
    // The control: the key page draws the pieces' outlines only, no fill.
    assert_eq!(fill[0], 0, "{fill:?}");
    for (k, &n) in fill.iter().enumerate().skip(1) {
        assert!(n > 0 || k == 1, "page {} shows no piece: {fill:?}", k + 1);
    }
    // The untrimmed tiling would have had empty pages.
    assert!(grid.rows * grid.cols > grid.tiles);
}

/// The marker's PDF: one page the size of the fabric (plus the margins and the test-square strip), with
/// its caption, and every placed piece's fill in a pdftoppm render.
#[test]
fn marker_pdf_is_one_page_the_size_of_the_fabric() {
    let pattern = bulged_tube_pattern();
    let m = marker(&[&pattern], &MarkerParams::default()).unwrap();
    let placed = m.pattern(&[&pattern]);
    let pdf = marker_pdf(&placed, &m);
    assert_eq!(page_count(&pdf), 1);
    let [_, _, w, h] = media_boxes(&pdf)[0];
    let want_w = ((m.length + 2.0 * MARGIN) * MM).max(2.0 * MARGIN * MM + TEST_SQUARE_MM);
    let want_h = (m.width + 2.0 * MARGIN) * MM + SCALE_SPACE_MM;
    assert!(
        (w as Real - want_w * PT_PER_MM).abs() < 0.01,
        "{w} vs {want_w} mm"
    );
    assert!(
        (h as Real - want_h * PT_PER_MM).abs() < 0.01,
        "{h} vs {want_h} mm"
    );
    assert!(contains_text(&pdf, "Marker, 1:1: fabric 1.500 m wide"));
}
