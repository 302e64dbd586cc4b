//! Tests of the PDF writers: page sizes and counts, paper names, odd models, and the test square measured
//! in pdftoppm renders.

use super::*;
use crate::pattern_format::test_pattern::bulged_tube_pattern;
use crate::pattern_format::verify::{measure_square, missing, on_path, page_count};

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
        assert_eq!(grid.pages, 1 + grid.rows * grid.cols, "{paper:?}");
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
        let last = format!("row {} / col {} ", grid.rows, grid.cols);
        assert!(contains_text(&pdf, &last), "{paper:?}: {last}");
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
