//! `patterns.pdf` and `patterns-a4.pdf`: the pattern to print at 1:1.
//!
//! Both are written with `pdf-writer` (the typst project's low-level PDF writer: small, no C dependencies,
//! and all this needs — vector paths and base-14 text; printpdf and krilla bring font and layout machinery
//! that a drawing of lines does not use). Text is Helvetica, a base-14 font every reader has, so nothing is
//! embedded; it is WinAnsi-encoded, and a character outside WinAnsi is written `?`.
//!
//! Units: the drawing is made in millimetres (one user unit = 1 mm after a `72 / 25.4` scale; 72 pt =
//! 25.4 mm), pattern +y up (PDF's own orientation). The drawing is the sheet of [`sheet`] (pieces side by
//! side, bottoms aligned) with a strip of [`SCALE_SPACE_MM`] above it holding, at its top left, a 100 mm
//! test square to check the print scale. It shows the cut lines (filled outline), the sew lines (dashed),
//! notch slits, grain-line arrows, drill holes, the piece text and the seam numbers (red, at the middle of
//! each seam side, the same on both pieces).
//!
//! - [`pattern_pdf`] (`patterns.pdf`): one page the size of the drawing, at 1:1, for a wide-format
//!   printer or plotter. A drawing over 14 400 pt (≈ 5 m, the classic page-size limit) gets a `/UserUnit`
//!   so the page still measures true.
//! - [`tiled_pdf`] (`patterns-a4.pdf`): the same drawing at 1:1 cut into portrait [`Paper`] tiles. Page 1
//!   is the key: the tile grid over a small overview of the sheet, with each tile's page number. Each tile
//!   page prints [`PAGE_MARGIN_MM`] inside the paper edge; neighbouring tiles share [`OVERLAP_MM`] of the
//!   drawing (a dashed line on a page marks where the page to its left or above ends); it carries its key
//!   (`row 2 / col 3 — page 7 of 12`), crop marks at the corners of the printable area and registration
//!   marks (circle and cross) at the corners of its own part of the drawing, which fall on the same points
//!   of the drawing as the neighbours' marks. The test square is on the first tile page (row 1, col 1).
//!   At most [`MAX_TILES_PER_SIDE`] tiles a side (the key page says when a sheet needs more). A tile whose
//!   printed area meets no piece's cut line (by a positive area, the polygon clipped to the tile's
//!   rectangle) and not the test square is left out: the key page draws only the printed tiles, numbered in
//!   order, and says how many were left out.
//! - [`marker_pdf`] (`patterns-marker.pdf`): the marker ([`crate::marker`]) on one page at 1:1 — the
//!   fabric's edges as a rectangle, every placed piece drawn as in `patterns.pdf`, and a line of text with
//!   the fabric's width, the marker's length and its efficiency — for a plotter to draw on the fabric or on
//!   marker paper.

use std::fmt;
use std::str::FromStr;

use pdf_writer::{Content, Finish, Name, Pdf, Rect, Ref, Str};

use crate::math::{Real, Vec2};
use crate::pattern::{Pattern, Sheet, sheet};
use crate::pattern_format::dxf::notch_slit;

/// File name of the one-page 1:1 PDF in an output folder.
pub const WIDE_FILE: &str = "patterns.pdf";
/// File name of the tiled PDF in an output folder.
pub const TILED_FILE: &str = "patterns-a4.pdf";
/// File name of the marker's 1:1 PDF in an output folder.
pub const MARKER_FILE: &str = "patterns-marker.pdf";
/// Media type of both PDF files.
pub const CONTENT_TYPE: &str = "application/pdf";

/// Margin around the sheet and gap between pieces (m), as in the other writers.
const MARGIN: Real = 0.01;
const GAP: Real = 0.02;
/// Millimetres per metre.
const MM: Real = 1000.0;
/// Height of the strip above the pieces that holds the test square (mm).
pub const SCALE_SPACE_MM: Real = 120.0;
/// Side of the test square (mm).
pub const TEST_SQUARE_MM: Real = 100.0;
/// Distance from the paper's edge to the printed area of a tile (mm).
pub const PAGE_MARGIN_MM: Real = 12.0;
/// Width of the strip of drawing that neighbouring tiles share (mm).
pub const OVERLAP_MM: Real = 10.0;
/// Most tiles a side of the tiled PDF (a drawing of about 5 × 7.5 m on A4; garments are far smaller):
/// past that only the drawing's top-left part is tiled, and the key page says so.
pub const MAX_TILES_PER_SIDE: usize = 30;
/// PostScript points per millimetre.
const PT_PER_MM: Real = 72.0 / 25.4;
/// Largest page side in user units that every reader takes (pt).
const MAX_PAGE_PT: Real = 14_400.0;
/// The font resource name (Helvetica).
const FONT: Name = Name(b"F1");

/// Where the tiled PDF's 100 mm test square is, to measure it in a render: its page (1-based; the first tile
/// page, after the key page) and its top-left corner in mm from the page's top-left corner.
pub fn tiled_test_square(pattern: &Pattern, paper: Paper) -> (usize, Real, Real) {
    let d = Drawing::new(pattern);
    let t = Tiles::new(d.size, paper);
    let (x0, y0) = t.origin(0, 0);
    let (_, ph) = paper.size_mm();
    (
        2,
        PAGE_MARGIN_MM + d.square.0 - x0,
        ph - (PAGE_MARGIN_MM + d.square.1 - y0 + TEST_SQUARE_MM),
    )
}

/// A paper size for the tiled print, portrait.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Paper {
    /// ISO A4, 210 × 297 mm.
    A4,
    /// US Letter, 8.5 × 11 in (215.9 × 279.4 mm).
    Letter,
    /// ISO A3, 297 × 420 mm.
    A3,
}

impl Paper {
    /// Width and height (mm), portrait.
    pub fn size_mm(self) -> (Real, Real) {
        match self {
            Paper::A4 => (210.0, 297.0),
            Paper::Letter => (215.9, 279.4),
            Paper::A3 => (297.0, 420.0),
        }
    }

    /// The paper's name as printed and parsed: `A4`, `Letter`, `A3`.
    pub fn name(self) -> &'static str {
        match self {
            Paper::A4 => "A4",
            Paper::Letter => "Letter",
            Paper::A3 => "A3",
        }
    }
}

/// An unknown paper name (see [`Paper::from_str`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UnknownPaper(pub String);

impl fmt::Display for UnknownPaper {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "paper: unknown paper size {:?} (expected \"A4\", \"Letter\" or \"A3\")",
            self.0
        )
    }
}

impl std::error::Error for UnknownPaper {}

impl FromStr for Paper {
    type Err = UnknownPaper;

    /// `A4`, `Letter` or `A3`, in any case.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "a4" => Ok(Paper::A4),
            "letter" => Ok(Paper::Letter),
            "a3" => Ok(Paper::A3),
            _ => Err(UnknownPaper(s.into())),
        }
    }
}

/// How a tiled PDF is cut: a grid of `rows × cols` tiles, of which `tiles` are printed (the others meet no
/// piece), `pages = 1 + tiles` in all.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TileGrid {
    /// Rows of tiles, top to bottom.
    pub rows: usize,
    /// Columns of tiles, left to right.
    pub cols: usize,
    /// Tile pages printed: the tiles that meet a piece or the test square.
    pub tiles: usize,
    /// Pages in the file: the key page and the printed tiles.
    pub pages: usize,
}

/// The drawing both files print: its size and where things are on it (mm, origin lower left, +y up).
struct Drawing {
    /// Per piece, the translation from pattern coordinates (m) to the drawing (m).
    offsets: Vec<Vec2>,
    /// Width and height (mm).
    size: (Real, Real),
    /// Lower-left corner of the test square (mm).
    square: (Real, Real),
    /// The fabric of a marker: lower-left corner and size (mm), drawn as a rectangle.
    fabric: Option<[Real; 4]>,
}

impl Drawing {
    fn new(pattern: &Pattern) -> Self {
        Self::with_sheet(sheet(pattern, GAP, MARGIN), None)
    }

    /// The drawing of pieces laid out by `layout`, with the fabric `(length, width)` (m) of a marker at
    /// the margin when given.
    fn with_sheet(layout: Sheet, fabric: Option<(Real, Real)>) -> Self {
        let width = finite(layout.size.x * MM).max(2.0 * MARGIN * MM + TEST_SQUARE_MM);
        let height = finite(layout.size.y * MM).max(0.0) + SCALE_SPACE_MM;
        Drawing {
            offsets: layout.offsets,
            size: (width, height),
            square: (MARGIN * MM, height - MARGIN * MM - TEST_SQUARE_MM),
            fabric: fabric.map(|(l, w)| [MARGIN * MM, MARGIN * MM, finite(l * MM), finite(w * MM)]),
        }
    }

    /// Whether the rectangle `[x0, x0 + w] × [y0, y0 + h]` (mm) meets a piece's cut line by a positive area
    /// or the test square.
    fn meets(&self, pattern: &Pattern, [x0, y0, w, h]: [Real; 4]) -> bool {
        let (sx, sy) = self.square;
        let s = TEST_SQUARE_MM;
        if sx < x0 + w && sx + s > x0 && sy < y0 + h && sy + s > y0 {
            return true;
        }
        pattern.pieces.iter().enumerate().any(|(p, piece)| {
            let poly: Vec<(Real, Real)> = piece
                .cut_line
                .iter()
                .map(|&q| {
                    let (x, y) = self.at(p, q);
                    (x as Real, y as Real)
                })
                .collect();
            clipped_area(&poly, [x0, y0, x0 + w, y0 + h]) > 1e-6
        })
    }

    /// Drawing point (mm, as `f32` for the content stream) of pattern point `q` (m) of piece `p`.
    fn at(&self, p: usize, q: Vec2) -> (f32, f32) {
        let o = self.offsets.get(p).copied().unwrap_or_else(Vec2::zeros);
        let s = (q + o) * MM;
        (finite(s.x) as f32, finite(s.y) as f32)
    }
}

/// Area (mm²) of polygon `poly` (mm, either orientation, concave allowed) inside the rectangle
/// `[x0, y0, x1, y1]`: the polygon clipped against the rectangle's four edges in turn (Sutherland–Hodgman,
/// exact for a convex clip window), then the shoelace formula.
fn clipped_area(poly: &[(Real, Real)], [x0, y0, x1, y1]: [Real; 4]) -> Real {
    let mut ring: Vec<(Real, Real)> = poly.to_vec();
    // Each edge as (inside test, intersection of segment a–b with the edge line).
    type Inside = fn((Real, Real), Real) -> bool;
    let edges: [(Inside, bool, Real); 4] = [
        (|p, v| p.0 >= v, true, x0),
        (|p, v| p.0 <= v, true, x1),
        (|p, v| p.1 >= v, false, y0),
        (|p, v| p.1 <= v, false, y1),
    ];
    for (inside, vertical, v) in edges {
        if ring.is_empty() {
            return 0.0;
        }
        let cross = |a: (Real, Real), b: (Real, Real)| {
            if vertical {
                let t = (v - a.0) / (b.0 - a.0);
                (v, a.1 + t * (b.1 - a.1))
            } else {
                let t = (v - a.1) / (b.1 - a.1);
                (a.0 + t * (b.0 - a.0), v)
            }
        };
        let mut out = Vec::with_capacity(ring.len() + 4);
        for i in 0..ring.len() {
            let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
            match (inside(a, v), inside(b, v)) {
                (true, true) => out.push(b),
                (true, false) => out.push(cross(a, b)),
                (false, true) => {
                    out.push(cross(a, b));
                    out.push(b);
                }
                (false, false) => {}
            }
        }
        ring = out;
    }
    let n = ring.len();
    (0..n)
        .map(|i| {
            let (a, b) = (ring[i], ring[(i + 1) % n]);
            a.0 * b.1 - b.0 * a.1
        })
        .sum::<Real>()
        .abs()
        * 0.5
}

/// `x`, or 0 for a non-finite number (which a valid pattern never has).
fn finite(x: Real) -> Real {
    if x.is_finite() { x } else { 0.0 }
}

/// `text` in WinAnsiEncoding (Windows-1252): Latin-1 as is, a few typographic characters mapped, other
/// characters `?`, control characters dropped.
fn win_ansi(text: &str) -> Vec<u8> {
    text.chars()
        .filter(|c| !c.is_control())
        .map(|c| match c {
            ' '..='~' | '\u{a0}'..='\u{ff}' => c as u32 as u8,
            '€' => 0x80,
            '–' => 0x96,
            '—' => 0x97,
            '‘' => 0x91,
            '’' => 0x92,
            '“' => 0x93,
            '”' => 0x94,
            '•' => 0x95,
            _ => b'?',
        })
        .collect()
}

/// Rough width of `text` in Helvetica at `size` (an average glyph width: for centring, not for fitting).
fn text_width(text: &str, size: f32) -> f32 {
    0.52 * size * text.chars().count() as f32
}

fn text(c: &mut Content, x: f32, y: f32, size: f32, s: &str) {
    c.begin_text();
    c.set_font(FONT, size);
    c.next_line(x, y);
    c.show(Str(&win_ansi(s)));
    c.end_text();
}

/// A polyline path (not stroked yet).
fn path(c: &mut Content, points: &[(f32, f32)], closed: bool) {
    for (i, &(x, y)) in points.iter().enumerate() {
        if i == 0 {
            c.move_to(x, y);
        } else {
            c.line_to(x, y);
        }
    }
    if closed {
        c.close_path();
    }
}

/// A circle path (four Bézier quarters).
fn circle(c: &mut Content, (x, y): (f32, f32), r: f32) {
    let k = 0.552_284_8 * r;
    c.move_to(x + r, y);
    c.cubic_to(x + r, y + k, x + k, y + r, x, y + r);
    c.cubic_to(x - k, y + r, x - r, y + k, x - r, y);
    c.cubic_to(x - r, y - k, x - k, y - r, x, y - r);
    c.cubic_to(x + k, y - r, x + r, y - k, x + r, y);
    c.close_path();
}

/// Draws the whole drawing in the current coordinates (mm, drawing origin).
fn draw(c: &mut Content, pattern: &Pattern, d: &Drawing) {
    let pieces = &pattern.pieces;
    c.set_line_join(pdf_writer::types::LineJoinStyle::RoundJoin);
    // A marker's fabric: its edges.
    if let Some([x, y, w, h]) = d.fabric {
        c.set_stroke_rgb(0.12, 0.31, 0.61);
        c.set_line_width(0.5);
        c.rect(x as f32, y as f32, w as f32, h as f32);
        c.stroke();
    }
    // Cut lines: filled, outlined.
    c.set_fill_rgb(0.965, 0.945, 0.906);
    c.set_stroke_gray(0.0);
    c.set_line_width(0.4);
    for (p, piece) in pieces.iter().enumerate() {
        if piece.cut_line.len() >= 2 {
            let pts: Vec<_> = piece.cut_line.iter().map(|&q| d.at(p, q)).collect();
            path(c, &pts, true);
            c.fill_nonzero_and_stroke();
        }
    }
    // Sew lines: dashed.
    c.set_stroke_gray(0.33);
    c.set_line_width(0.25);
    c.set_dash_pattern([2.0, 1.0], 0.0);
    for (p, piece) in pieces.iter().enumerate() {
        if piece.sewing_line.len() >= 2 {
            let pts: Vec<_> = piece.sewing_line.iter().map(|&q| d.at(p, q)).collect();
            path(c, &pts, true);
            c.stroke();
        }
    }
    c.set_dash_pattern([], 0.0);
    // Notches.
    c.set_stroke_gray(0.0);
    c.set_line_width(0.4);
    for (p, piece) in pieces.iter().enumerate() {
        for n in &piece.notches {
            if let Some((a, b)) = notch_slit(n.on_cut_line, n.at, n.depth) {
                path(c, &[d.at(p, a), d.at(p, b)], false);
                c.stroke();
            }
        }
    }
    // Drill holes: a circle and a cross.
    c.set_line_width(0.25);
    for (p, piece) in pieces.iter().enumerate() {
        for &h in &piece.drill_holes {
            let (x, y) = d.at(p, h);
            circle(c, (x, y), 1.5);
            c.stroke();
            path(c, &[(x - 2.0, y), (x + 2.0, y)], false);
            path(c, &[(x, y - 2.0), (x, y + 2.0)], false);
            c.stroke();
        }
    }
    // Grain lines: arrows along the wales.
    c.set_stroke_rgb(0.12, 0.31, 0.61);
    c.set_line_width(0.4);
    for (p, piece) in pieces.iter().enumerate() {
        let g = piece.grain_line;
        let dir = g.to - g.from;
        let len = dir.norm();
        if !(len > 0.0 && len.is_finite()) {
            continue;
        }
        let (u, n) = (dir / len, Vec2::new(-dir.y, dir.x) / len);
        let head = 0.008_f64.min(0.3 * len);
        path(c, &[d.at(p, g.from), d.at(p, g.to)], false);
        path(
            c,
            &[
                d.at(p, g.to - u * head + n * 0.4 * head),
                d.at(p, g.to),
                d.at(p, g.to - u * head - n * 0.4 * head),
            ],
            false,
        );
        c.stroke();
    }
    // Piece text.
    c.set_fill_gray(0.0);
    for (p, piece) in pieces.iter().enumerate() {
        let (x, y) = d.at(p, piece.label_anchor);
        for (k, line) in piece.label_lines(&pattern.labels).iter().enumerate() {
            text(c, x, y - 5.0 * k as f32, 3.5, line);
        }
    }
    // Seam numbers.
    c.set_fill_rgb(0.75, 0.22, 0.17);
    for (p, piece) in pieces.iter().enumerate() {
        for (at, number) in piece.seam_labels() {
            let (x, y) = d.at(p, at);
            text(c, x - 0.5 * text_width(number, 5.0), y - 1.8, 5.0, number);
        }
    }
    // The test square.
    let (sx, sy) = (d.square.0 as f32, d.square.1 as f32);
    let side = TEST_SQUARE_MM as f32;
    c.set_stroke_gray(0.0);
    c.set_line_width(0.3);
    c.rect(sx, sy, side, side);
    c.stroke();
    c.set_fill_gray(0.0);
    text(c, sx + 3.0, sy + 8.0, 3.5, "test square 100 mm × 100 mm");
    text(
        c,
        sx + 3.0,
        sy + 3.0,
        2.5,
        "print at 100 % (actual size): measure it",
    );
}

/// Page size in `/UserUnit`s and the unit (pt) for a page of `w × h` mm.
fn page_units(w: Real, h: Real) -> (f32, f32, f32) {
    let unit = ((w.max(h) * PT_PER_MM) / MAX_PAGE_PT).ceil().max(1.0);
    (
        (w * PT_PER_MM / unit) as f32,
        (h * PT_PER_MM / unit) as f32,
        unit as f32,
    )
}

/// A PDF being built: pages in order, each with its content, sharing one Helvetica font.
struct Doc {
    pdf: Pdf,
    next: i32,
    pages: Vec<Ref>,
    font: Ref,
    tree: Ref,
}

impl Doc {
    fn new() -> Self {
        let mut pdf = Pdf::new();
        let (catalog, tree, font) = (Ref::new(1), Ref::new(2), Ref::new(3));
        pdf.catalog(catalog).pages(tree);
        pdf.type1_font(font)
            .base_font(Name(b"Helvetica"))
            .encoding_predefined(Name(b"WinAnsiEncoding"));
        Doc {
            pdf,
            next: 4,
            pages: Vec::new(),
            font,
            tree,
        }
    }

    /// Adds a page of `w × h` mm whose content `draw` makes in millimetres (origin lower left).
    fn page(&mut self, w: Real, h: Real, draw: impl FnOnce(&mut Content)) {
        let (pw, ph, unit) = page_units(w, h);
        let (id, content_id) = (Ref::new(self.next), Ref::new(self.next + 1));
        self.next += 2;
        let mut content = Content::new();
        let k = PT_PER_MM as f32 / unit;
        content.transform([k, 0.0, 0.0, k, 0.0, 0.0]);
        draw(&mut content);
        let mut page = self.pdf.page(id);
        page.media_box(Rect::new(0.0, 0.0, pw, ph));
        if unit > 1.0 {
            page.user_unit(unit);
        }
        page.parent(self.tree);
        page.contents(content_id);
        page.resources().fonts().pair(FONT, self.font);
        page.finish();
        self.pdf.stream(content_id, &content.finish());
        self.pages.push(id);
    }

    fn finish(mut self, title: &str) -> Vec<u8> {
        let count = self.pages.len() as i32;
        self.pdf.pages(self.tree).kids(self.pages).count(count);
        self.pdf
            .document_info(Ref::new(self.next))
            .title(pdf_writer::TextStr(title))
            .creator(pdf_writer::TextStr("skintight"));
        self.pdf.finish()
    }
}

/// `patterns.pdf`: the whole drawing on one page at 1:1 (see the module documentation).
pub fn pattern_pdf(pattern: &Pattern) -> Vec<u8> {
    let d = Drawing::new(pattern);
    let mut doc = Doc::new();
    doc.page(d.size.0, d.size.1, |c| draw(c, pattern, &d));
    doc.finish("Pattern, 1:1")
}

/// The tiling of a drawing of `size` (mm) onto `paper`.
struct Tiles {
    paper: (Real, Real),
    /// Printable area of a page (mm).
    area: (Real, Real),
    /// Drawing advance from one tile to the next (mm): the area less the overlap.
    step: (Real, Real),
    rows: usize,
    cols: usize,
    /// Drawing height (mm).
    height: Real,
    /// Whether the drawing needs more than [`MAX_TILES_PER_SIDE`] tiles a side, so only its top-left part
    /// is tiled.
    truncated: bool,
    /// Per tile (row-major), its page number if it is printed (it meets a piece or the test square).
    printed: Vec<Option<usize>>,
}

impl Tiles {
    fn new(size: (Real, Real), paper: Paper) -> Self {
        let (pw, ph) = paper.size_mm();
        let area = (pw - 2.0 * PAGE_MARGIN_MM, ph - 2.0 * PAGE_MARGIN_MM);
        let step = (area.0 - OVERLAP_MM, area.1 - OVERLAP_MM);
        let count = |len: Real, step: Real| ((len - OVERLAP_MM) / step).ceil().max(1.0);
        let (rows, cols) = (count(size.1, step.1), count(size.0, step.0));
        let max = MAX_TILES_PER_SIDE as Real;
        let (rows, cols, truncated) = (
            rows.min(max) as usize,
            cols.min(max) as usize,
            rows > max || cols > max,
        );
        Tiles {
            paper: (pw, ph),
            area,
            step,
            rows,
            cols,
            height: size.1,
            truncated,
            printed: (0..rows * cols).map(|k| Some(k + 2)).collect(),
        }
    }

    /// The tiling of drawing `d` of `pattern` with the tiles that meet nothing left out.
    fn of(d: &Drawing, pattern: &Pattern, paper: Paper) -> Self {
        let mut t = Tiles::new(d.size, paper);
        let mut page = 2;
        for row in 0..t.rows {
            for col in 0..t.cols {
                let (x, y) = t.origin(row, col);
                let meets = d.meets(pattern, [x, y, t.area.0, t.area.1]);
                t.printed[row * t.cols + col] = meets.then_some(page);
                if meets {
                    page += 1;
                }
            }
        }
        t
    }

    /// Lower-left corner (mm, drawing coordinates) of the part of the drawing on tile `(row, col)`.
    fn origin(&self, row: usize, col: usize) -> (Real, Real) {
        (
            col as Real * self.step.0,
            self.height - row as Real * self.step.1 - self.area.1,
        )
    }

    /// The page of tile `(row, col)`, `None` if it is left out.
    fn page_number(&self, row: usize, col: usize) -> Option<usize> {
        self.printed.get(row * self.cols + col).copied().flatten()
    }

    /// Tile pages printed.
    fn tiles(&self) -> usize {
        self.printed.iter().flatten().count()
    }

    fn pages(&self) -> usize {
        1 + self.tiles()
    }
}

/// The key page: what the file is, how to assemble it, and the tile grid over an overview of the sheet.
fn key_page(c: &mut Content, pattern: &Pattern, d: &Drawing, t: &Tiles, paper: Paper) {
    let (pw, ph) = t.paper;
    let m = PAGE_MARGIN_MM as f32;
    let top = ph as f32 - m;
    c.set_fill_gray(0.0);
    text(
        c,
        m,
        top - 6.0,
        6.0,
        &format!("Pattern, 1:1, tiled on {} portrait", paper.name()),
    );
    let l = &pattern.labels;
    let mut lines = vec![
        format!(
            "{} rows × {} columns: {} tile pages after this key, {} pages in all. Key: page 1 of {}.",
            t.rows,
            t.cols,
            t.tiles(),
            t.pages(),
            t.pages()
        ),
        "Print at 100 % (actual size, no fit to page). Check the 100 mm test square on page 2."
            .into(),
        format!(
            "Neighbouring pages share {OVERLAP_MM:.0} mm: lay each page over the one to its left and above, \
             on the dashed line,"
        ),
        "with the registration marks (circle and cross) on top of each other; tape, then cut."
            .into(),
    ];
    if t.tiles() < t.rows * t.cols {
        lines.push(format!(
            "The {} tiles that meet no piece are left out: their places in the grid are blank.",
            t.rows * t.cols - t.tiles()
        ));
    }
    if t.truncated {
        lines.push(format!(
            "The sheet needs more than {MAX_TILES_PER_SIDE} pages a side: only its top-left part is tiled here; \
             print patterns.pdf on a wide-format printer."
        ));
    }
    for (key, value) in [
        ("Order", &l.order_id),
        ("Customer", &l.customer),
        ("Template", &l.template),
        ("Size", &l.size),
        ("Fabric", &l.fabric),
        ("Date", &l.date),
    ] {
        if !value.trim().is_empty() {
            lines.push(format!("{key}: {}", value.trim()));
        }
    }
    for (k, line) in lines.iter().enumerate() {
        text(c, m, top - 14.0 - 5.0 * k as f32, 3.2, line);
    }
    // The overview: the drawing scaled into the rest of the page, the tiles over it.
    let box_top = top - 14.0 - 5.0 * lines.len() as f32 - 6.0;
    let (bw, bh) = (pw as f32 - 2.0 * m, box_top - m);
    if bw <= 0.0 || bh <= 0.0 {
        return;
    }
    let (dw, dh) = (d.size.0 as f32, d.size.1 as f32);
    // The tiles reach past the drawing to the right and below it: fit the grid's extent.
    let (_, gy0) = t.origin(t.rows - 1, 0);
    let (gx1, _) = t.origin(0, t.cols - 1);
    let gy0 = gy0.min(0.0) as f32;
    let (gw, gh) = (((gx1 + t.area.0) as f32).max(dw), dh - gy0);
    let s = (bw / gw).min(bh / gh);
    let (ox, oy) = (m, box_top - s * dh);
    c.save_state();
    c.transform([s, 0.0, 0.0, s, ox, oy]);
    c.set_line_width(0.2 / s);
    c.set_stroke_gray(0.6);
    c.rect(0.0, 0.0, dw, dh);
    c.stroke();
    c.set_stroke_gray(0.0);
    for (p, piece) in pattern.pieces.iter().enumerate() {
        if piece.cut_line.len() >= 2 {
            let pts: Vec<_> = piece.cut_line.iter().map(|&q| d.at(p, q)).collect();
            path(c, &pts, true);
            c.stroke();
        }
    }
    c.rect(
        d.square.0 as f32,
        d.square.1 as f32,
        TEST_SQUARE_MM as f32,
        TEST_SQUARE_MM as f32,
    );
    c.stroke();
    c.set_stroke_rgb(0.12, 0.31, 0.61);
    c.set_line_width(0.3 / s);
    for row in 0..t.rows {
        for col in 0..t.cols {
            if t.page_number(row, col).is_none() {
                continue;
            }
            let (x, y) = t.origin(row, col);
            c.rect(x as f32, y as f32, t.area.0 as f32, t.area.1 as f32);
            c.stroke();
        }
    }
    c.restore_state();
    // Page numbers in the tiles' own parts, in page coordinates (text stays readable at any scale).
    c.set_fill_rgb(0.12, 0.31, 0.61);
    let size = (0.25 * s * t.step.0.min(t.step.1) as f32).clamp(1.5, 8.0);
    for row in 0..t.rows {
        for col in 0..t.cols {
            let Some(page) = t.page_number(row, col) else {
                continue;
            };
            let (x, y) = t.origin(row, col);
            let (cx, cy) = (
                ox + s * (x + 0.5 * t.area.0) as f32,
                oy + s * (y + 0.5 * t.area.1) as f32,
            );
            let label = format!("{page}");
            text(
                c,
                cx - 0.5 * text_width(&label, size),
                cy - 0.35 * size,
                size,
                &label,
            );
        }
    }
}

/// Page furniture of tile `(row, col)`: frame, overlap lines, crop and registration marks, key.
fn tile_marks(c: &mut Content, t: &Tiles, row: usize, col: usize, paper: Paper) {
    let m = PAGE_MARGIN_MM as f32;
    let (aw, ah) = (t.area.0 as f32, t.area.1 as f32);
    let (pw, ph) = (t.paper.0 as f32, t.paper.1 as f32);
    let ov = OVERLAP_MM as f32;
    // Frame of the printed area.
    c.set_stroke_gray(0.6);
    c.set_line_width(0.15);
    c.rect(m, m, aw, ah);
    c.stroke();
    // Where the page to the left and the page above end.
    c.set_dash_pattern([3.0, 2.0], 0.0);
    if col > 0 {
        path(c, &[(m + ov, m), (m + ov, m + ah)], false);
        c.stroke();
    }
    if row > 0 {
        path(c, &[(m, m + ah - ov), (m + aw, m + ah - ov)], false);
        c.stroke();
    }
    c.set_dash_pattern([], 0.0);
    // Crop marks in the margin at the printed area's corners.
    c.set_stroke_gray(0.0);
    c.set_line_width(0.2);
    for (x, sx) in [(m, -1.0), (m + aw, 1.0)] {
        for (y, sy) in [(m, -1.0), (m + ah, 1.0)] {
            path(c, &[(x + sx * 2.0, y), (x + sx * 8.0, y)], false);
            path(c, &[(x, y + sy * 2.0), (x, y + sy * 8.0)], false);
            c.stroke();
        }
    }
    // Registration marks at the corners of this tile's own part of the drawing.
    let left = if col > 0 { m + ov } else { m };
    let top = if row > 0 { m + ah - ov } else { m + ah };
    for x in [left, m + aw] {
        for y in [m, top] {
            circle(c, (x, y), 2.5);
            path(c, &[(x - 4.0, y), (x + 4.0, y)], false);
            path(c, &[(x, y - 4.0), (x, y + 4.0)], false);
            c.stroke();
        }
    }
    // The key.
    c.set_fill_gray(0.0);
    let page = t.page_number(row, col).unwrap_or(0);
    text(
        c,
        m + 10.0,
        ph - m + 4.0,
        3.5,
        &format!(
            "row {} / col {} — page {} of {}",
            row + 1,
            col + 1,
            page,
            t.pages()
        ),
    );
    let scale = format!(
        "{} portrait, 1:1 — overlap {OVERLAP_MM:.0} mm",
        paper.name()
    );
    text(
        c,
        pw - m - 10.0 - text_width(&scale, 3.0),
        ph - m + 4.0,
        3.0,
        &scale,
    );
    let footer = format!("page {page} of {}", t.pages());
    text(
        c,
        0.5 * pw - 0.5 * text_width(&footer, 3.0),
        m - 7.0,
        3.0,
        &footer,
    );
}

/// `patterns-a4.pdf`: the drawing at 1:1 tiled onto `paper`, after a key page (see the module
/// documentation); also returns the grid.
pub fn tiled_pdf(pattern: &Pattern, paper: Paper) -> (Vec<u8>, TileGrid) {
    let d = Drawing::new(pattern);
    let t = Tiles::of(&d, pattern, paper);
    let mut doc = Doc::new();
    doc.page(t.paper.0, t.paper.1, |c| {
        key_page(c, pattern, &d, &t, paper)
    });
    let m = PAGE_MARGIN_MM as f32;
    for row in 0..t.rows {
        for col in 0..t.cols {
            if t.page_number(row, col).is_none() {
                continue;
            }
            doc.page(t.paper.0, t.paper.1, |c| {
                let (x0, y0) = t.origin(row, col);
                c.save_state();
                c.rect(m, m, t.area.0 as f32, t.area.1 as f32);
                c.clip_nonzero();
                c.end_path();
                c.transform([1.0, 0.0, 0.0, 1.0, m - x0 as f32, m - y0 as f32]);
                draw(c, pattern, &d);
                c.restore_state();
                tile_marks(c, &t, row, col, paper);
            });
        }
    }
    let grid = TileGrid {
        rows: t.rows,
        cols: t.cols,
        tiles: t.tiles(),
        pages: t.pages(),
    };
    (
        doc.finish(&format!("Pattern, 1:1, tiled on {}", paper.name())),
        grid,
    )
}

/// `patterns-marker.pdf`: the marker on one page at 1:1 (see the module documentation). `placed` is the
/// marker's pieces at their places on the fabric ([`crate::marker::Marker::pattern`]), `marker` the marker.
pub fn marker_pdf(placed: &Pattern, marker: &crate::marker::Marker) -> Vec<u8> {
    let layout = Sheet {
        offsets: vec![Vec2::new(MARGIN, MARGIN); placed.pieces.len()],
        size: Vec2::new(marker.length + 2.0 * MARGIN, marker.width + 2.0 * MARGIN),
    };
    let d = Drawing::with_sheet(layout, Some((marker.length, marker.width)));
    let mut doc = Doc::new();
    let caption = format!(
        "Marker, 1:1: fabric {:.3} m wide, {:.3} m long, efficiency {:.1} % ({} pieces, grain along the \
         length)",
        marker.width,
        marker.length,
        100.0 * marker.efficiency,
        marker.placements.len()
    );
    doc.page(d.size.0, d.size.1, |c| {
        draw(c, placed, &d);
        c.set_fill_gray(0.0);
        let (sx, sy) = (
            d.square.0 + TEST_SQUARE_MM + 10.0,
            d.square.1 + TEST_SQUARE_MM - 8.0,
        );
        text(c, sx as f32, sy as f32, 6.0, &caption);
    });
    doc.finish("Marker, 1:1")
}

#[cfg(test)]
mod tests;
