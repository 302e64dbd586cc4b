//! The report's pattern pieces: each piece's cut line (solid) and sewing line (dashed) with its grain line,
//! turned so the grain runs up the page (as the piece lies on the fabric's wales), all at one scale with a
//! 10 cm bar; under each, its size along and across the grain (sewing line, cm) and how many to cut.
//! The cut-ready, true-scale drawings are the pattern files (`patterns.svg`, `patterns.pdf`, …).

use std::fmt::Write;

use skintight_garment::pattern::Piece;
use skintight_geometry::Vec2;

use super::Report;
use super::html::escape;

/// Height the tallest piece is drawn at (px).
const PIECE_HEIGHT: f64 = 300.0;
/// Width all pieces may take together (px).
const ALL_WIDTH: f64 = 880.0;
/// Narrowest column a piece takes, for its labels (px).
const LABEL_WIDTH: f64 = 130.0;
/// Gap between pieces (px).
const GAP: f64 = 40.0;

/// A grain line's tail and head.
type Grain = [Vec2; 2];

/// `p` in the piece's grain frame: `x` across the grain, `y` along it (m).
fn grain_frame(piece: &Piece) -> impl Fn(Vec2) -> Vec2 {
    let g = piece.grain_line.to - piece.grain_line.from;
    let along = if g.norm() > 0.0 {
        g / g.norm()
    } else {
        Vec2::new(0.0, 1.0)
    };
    let across = Vec2::new(along.y, -along.x);
    move |p: Vec2| Vec2::new(across.dot(&p), along.dot(&p))
}

/// `[min x, min y, max x, max y]` of `points` (m).
fn extent(points: &[Vec2]) -> [f64; 4] {
    points.iter().fold(
        [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ],
        |b, p| [b[0].min(p.x), b[1].min(p.y), b[2].max(p.x), b[3].max(p.y)],
    )
}

/// The section.
pub fn section(r: &Report) -> String {
    let mut out = String::from("<h2>Pattern pieces</h2>\n");
    // Each piece with its cut line, sewing line and grain line in its grain frame.
    let pieces: Vec<(&Piece, Vec<Vec2>, Vec<Vec2>, Grain)> = r
        .pieces
        .iter()
        .filter(|p| p.cut_line.len() > 2 && p.sewing_line.len() > 2)
        .map(|p| {
            let f = grain_frame(p);
            (
                p,
                p.cut_line.iter().map(|&q| f(q)).collect::<Vec<_>>(),
                p.sewing_line.iter().map(|&q| f(q)).collect::<Vec<_>>(),
                [f(p.grain_line.from), f(p.grain_line.to)],
            )
        })
        .filter(|(_, cut, sew, _)| {
            cut.iter()
                .chain(sew)
                .all(|q| q.x.is_finite() && q.y.is_finite())
        })
        .collect();
    if pieces.is_empty() {
        out.push_str("<p class=\"note\">No pattern piece.</p>\n");
        return out;
    }
    out.push_str(
        "<p>Each piece with its grain line up the page: cut line solid, sewing line dashed; sizes of the \
         sewing line along and across the grain. True-scale drawings: <code>patterns.pdf</code>, \
         <code>patterns.svg</code>.</p>\n",
    );
    let extents: Vec<[f64; 4]> = pieces.iter().map(|(_, cut, _, _)| extent(cut)).collect();
    let tallest = extents.iter().map(|e| e[3] - e[1]).fold(1e-3, f64::max);
    let widths: f64 = extents.iter().map(|e| e[2] - e[0]).sum();
    let room = ALL_WIDTH - GAP * pieces.len() as f64;
    let scale = (PIECE_HEIGHT / tallest).min(room.max(100.0) / widths.max(1e-3));
    // Each piece in a column at least as wide as its labels.
    let columns: Vec<f64> = extents
        .iter()
        .map(|e| ((e[2] - e[0]) * scale).max(LABEL_WIDTH) + GAP)
        .collect();
    let width = columns.iter().sum::<f64>() + 20.0;
    let height = tallest * scale + 105.0;
    let mut svg = format!(
        "<div class=\"figure\" id=\"pieces\">\n<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{width:.0}\" \
         height=\"{height:.0}\" viewBox=\"0 0 {width:.1} {height:.1}\" role=\"img\" aria-label=\"pattern \
         pieces\">\n<defs><marker id=\"grain-head\" viewBox=\"0 0 10 10\" refX=\"9\" refY=\"5\" \
         markerWidth=\"8\" markerHeight=\"8\" orient=\"auto-start-reverse\"><path d=\"M0 0L10 5L0 10Z\" \
         fill=\"#b00020\"/></marker></defs>\n"
    );
    let mut column = 10.0;
    let top = 20.0;
    let base = top + tallest * scale;
    for (((piece, cut, sew, grain), e), w) in pieces.iter().zip(&extents).zip(&columns) {
        let x0 = column + (w - (e[2] - e[0]) * scale) / 2.0;
        let to_px = |q: Vec2| (x0 + (q.x - e[0]) * scale, top + (e[3] - q.y) * scale);
        let path = |pts: &[Vec2]| {
            let mut d = String::new();
            for (k, &q) in pts.iter().enumerate() {
                let (x, y) = to_px(q);
                let _ = write!(d, "{}{x:.1} {y:.1}", if k == 0 { "M" } else { "L" });
            }
            d.push('Z');
            d
        };
        let _ = writeln!(
            svg,
            "<path d=\"{}\" fill=\"#f7f3ea\" stroke=\"#222\" stroke-width=\"1.2\"/>\n<path d=\"{}\" \
             fill=\"none\" stroke=\"#555\" stroke-width=\"0.8\" stroke-dasharray=\"4 3\"/>",
            path(cut),
            path(sew)
        );
        let ((ax, ay), (bx, by)) = (to_px(grain[0]), to_px(grain[1]));
        let _ = writeln!(
            svg,
            "<line x1=\"{ax:.1}\" y1=\"{ay:.1}\" x2=\"{bx:.1}\" y2=\"{by:.1}\" stroke=\"#b00020\" \
             stroke-width=\"1.2\" marker-start=\"url(#grain-head)\" marker-end=\"url(#grain-head)\"/>"
        );
        let s = extent(sew);
        let (along, across) = ((s[3] - s[1]) * 100.0, (s[2] - s[0]) * 100.0);
        let cx = column + w / 2.0;
        let _ = writeln!(
            svg,
            "<text x=\"{cx:.1}\" y=\"{:.1}\" font-size=\"12\" text-anchor=\"middle\" font-weight=\"bold\">{}</text>\n\
             <text x=\"{cx:.1}\" y=\"{:.1}\" font-size=\"11\" text-anchor=\"middle\">{along:.1} cm along the grain</text>\n\
             <text x=\"{cx:.1}\" y=\"{:.1}\" font-size=\"11\" text-anchor=\"middle\">{across:.1} cm across</text>\n\
             <text x=\"{cx:.1}\" y=\"{:.1}\" font-size=\"11\" text-anchor=\"middle\">cut {}{}</text>",
            base + 18.0,
            escape(&piece.name),
            base + 33.0,
            base + 47.0,
            base + 61.0,
            piece.cut_quantity,
            if piece.mirrored { ", mirrored" } else { "" }
        );
        column += w;
    }
    // A 10 cm scale bar.
    let bar = 0.1 * scale;
    let y = height - 12.0;
    let _ = writeln!(
        svg,
        "<path d=\"M10 {:.1}V{y:.1}H{:.1}V{:.1}\" stroke=\"#222\" fill=\"none\"/><text x=\"{:.1}\" \
         y=\"{:.1}\" font-size=\"11\">10 cm</text>",
        y - 5.0,
        10.0 + bar,
        y - 5.0,
        16.0 + bar,
        y + 2.0
    );
    svg.push_str("</svg>\n</div>\n");
    out.push_str(&svg);
    out
}
