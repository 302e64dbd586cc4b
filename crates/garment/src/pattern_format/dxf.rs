//! `patterns.dxf` (DXF-AAMA) and `patterns-astm.dxf` (DXF-ASTM, ASTM D6673): the pattern for pattern-CAD
//! systems, markers and cutters.
//!
//! Both are ASCII DXF, AutoCAD 2000 (`AC1015`), in millimetres (`$INSUNITS` 4, `$MEASUREMENT` 1, metric),
//! true scale, pattern +y up, written and read back with the `dxf` crate. Text is plain ASCII, which every
//! pattern-CAD and cutter reads: letters with diacritics are folded to their base letters (`Zoë` → `Zoe`),
//! other characters outside ASCII become `?` (the crate's `\U+XXXX` escapes show up literally in many
//! readers), control characters are dropped and a `^` is written `^ ` (DXF's caret escape), so no text can
//! break the file. The crate's two handle defects in AutoCAD 2000 files are mended (`repair_handles`).
//!
//! Each piece is one BLOCK (named after the piece, made unique and safe for a block name), drawn in the
//! piece's own pattern coordinates, and INSERTed once in ENTITIES at its place on the sheet
//! ([`sheet`]: side by side, bottoms aligned). Inside a block, by the AAMA/ASTM layer numbers:
//!
//! | layer | content |
//! | --- | --- |
//! | `1` | the cut line (closed POLYLINE) and the piece text (TEXT `Piece Name: …`, `Quantity: …`, `Size: …`) |
//! | `2` | turn points: POINTs at the cut line's corners (turning more than 20°) |
//! | `3` | curve points: POINTs at the cut line's other vertices |
//! | `4` | notches: a LINE per notch, the slit from its point on the cut line towards the sewing line, `depth` long |
//! | `7` | the grain line: a LINE from tail to head (the wale direction) |
//! | `8` | internal lines (none today; the layer exists) |
//! | `13` | drill holes: POINTs |
//! | `14` | the sew line (closed POLYLINE) |
//! | `15` | annotation TEXT: the piece's label lines and the seam numbers at the seam midpoints |
//!
//! ENTITIES also holds the style system text on layer `1`, once, below the pieces: `Style Name: …`,
//! `Creation Date: …`, `Author: …`, `Sample Size: …`, `Grading Rule Table: none`, `Units: METRIC`. The ASTM
//! variant adds the ASTM layers: `84` (ASTM boundary: the cut line again, as D6673 readers look for it) and
//! `85` (ASTM internal lines: none today; the layer exists).
//!
//! `patterns-marker.dxf` ([`dxf_marker`]) is the marker ([`crate::marker`]) as DXF-AAMA: every placed copy
//! of a piece is a block drawn at its place on the fabric (INSERTed at the origin: the block's coordinates
//! are the fabric's, `x` along its length, `y` across its width, in mm), and the fabric's edges are a
//! closed POLYLINE on layer `FABRIC`, the rectangle `[0, length] × [0, width]`.

use std::collections::HashSet;
use std::fmt;

use ::dxf::entities::{Entity, EntityType, Insert, Line, ModelPoint, Polyline, Text, Vertex};
use ::dxf::enums::{AcadVersion, DrawingUnits, Units};
use ::dxf::tables::Layer;
use ::dxf::{Block, Color, Drawing, Point};

use crate::math::{Real, Vec2};
use crate::pattern::{Pattern, Piece, Sheet, sheet};
use crate::pattern_format::ascii_text;

/// File name of the DXF-AAMA pattern in an output folder.
pub const AAMA_FILE: &str = "patterns.dxf";
/// File name of the DXF-ASTM pattern in an output folder.
pub const ASTM_FILE: &str = "patterns-astm.dxf";
/// File name of the marker's DXF-AAMA in an output folder.
pub const MARKER_FILE: &str = "patterns-marker.dxf";
/// Media type of both DXF files (IANA's registered type for DXF).
pub const CONTENT_TYPE: &str = "image/vnd.dxf";

/// Margin around the sheet and gap between pieces (m), as in the other writers.
const MARGIN: Real = 0.01;
const GAP: Real = 0.02;
/// Millimetres per metre.
const MM: Real = 1000.0;
/// Height of the piece and style text (mm).
const TEXT_MM: Real = 5.0;
/// Height of the annotation text (mm).
const ANNOTATION_MM: Real = 3.5;
/// A cut-line vertex turning more than this (rad, 20°) is a turn point, the others are curve points.
const TURN_ANGLE: Real = 20.0 * std::f64::consts::PI / 180.0;

/// Which DXF pattern convention to write.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DxfVariant {
    /// DXF-AAMA (`patterns.dxf`).
    Aama,
    /// DXF-ASTM, ASTM D6673 (`patterns-astm.dxf`): AAMA plus the ASTM layers 84 and 85.
    Astm,
}

/// The `dxf` crate failed to write the drawing (it does not for a drawing made here; kept as an error so a
/// caller never panics).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DxfWriteError(pub String);

impl fmt::Display for DxfWriteError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "writing the DXF pattern file failed: {}", self.0)
    }
}

impl std::error::Error for DxfWriteError {}

/// `patterns.dxf`: the pattern as DXF-AAMA (see the module documentation).
pub fn dxf_aama(pattern: &Pattern) -> Result<Vec<u8>, DxfWriteError> {
    dxf_pattern(pattern, DxfVariant::Aama)
}

/// `patterns-astm.dxf`: the pattern as DXF-ASTM (see the module documentation).
pub fn dxf_astm(pattern: &Pattern) -> Result<Vec<u8>, DxfWriteError> {
    dxf_pattern(pattern, DxfVariant::Astm)
}

/// A point in millimetres (a non-finite coordinate, which a valid pattern never has, is written as 0).
fn point(p: Vec2) -> Point {
    let f = |x: Real| if x.is_finite() { x * MM } else { 0.0 };
    Point::new(f(p.x), f(p.y), 0.0)
}

/// Text the file can carry: [`ascii_text`], `^` escaped, at most 250 characters (DXF values
/// are limited to 255 bytes before escaping).
fn dxf_text(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in ascii_text(text).chars().take(250) {
        if c == '^' {
            out.push_str("^ ");
        } else {
            out.push(c);
        }
    }
    out
}

/// A block name from a piece name: letters, digits, `_` and `-` kept, anything else `_`, unique in `used`.
fn block_name(name: &str, index: usize, used: &mut HashSet<String>) -> String {
    let mut base: String = name
        .chars()
        .take(64)
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if base.trim_matches('_').is_empty() {
        base = format!("piece_{}", index + 1);
    }
    let mut candidate = base.clone();
    let mut k = 2;
    while !used.insert(candidate.to_ascii_uppercase()) {
        candidate = format!("{base}_{k}");
        k += 1;
    }
    candidate
}

fn on_layer(specific: EntityType, layer: &str) -> Entity {
    let mut e = Entity::new(specific);
    e.common.layer = layer.into();
    e
}

/// A closed polyline on `layer` through `points` (m), or `None` for fewer than two points.
fn polyline(drawing: &mut Drawing, points: &[Vec2], layer: &str) -> Option<Entity> {
    if points.len() < 2 {
        return None;
    }
    let mut poly = Polyline::default();
    poly.set_is_closed(true);
    for &p in points {
        poly.add_vertex(drawing, Vertex::new(point(p)));
    }
    // The crate gives a polyline's SEQEND a handle only when the polyline is added to the drawing's
    // ENTITIES, not to a block (a SEQEND with handle 0 is an invalid file for ezdxf): add it there to get
    // its handles, then take it back for the block.
    drawing.add_entity(on_layer(EntityType::Polyline(poly), layer));
    let last = drawing.entities().count() - 1;
    drawing.remove_entity(last)
}

fn text(at: Point, height: Real, value: &str, layer: &str) -> Entity {
    on_layer(
        EntityType::Text(Text {
            location: at,
            text_height: height,
            value: dxf_text(value),
            ..Default::default()
        }),
        layer,
    )
}

/// The slit of a notch: from its point on the cut line towards its point on the sewing line, `depth` long
/// (m); `None` when it has no length.
pub(crate) fn notch_slit(on_cut_line: Vec2, at: Vec2, depth: Real) -> Option<(Vec2, Vec2)> {
    let dir = at - on_cut_line;
    let len = dir.norm();
    if !(len > 0.0 && depth > 0.0 && len.is_finite() && depth.is_finite()) {
        return None;
    }
    Some((on_cut_line, on_cut_line + dir * (depth / len)))
}

/// Whether vertex `i` of the closed polygon `line` turns by more than [`TURN_ANGLE`].
fn is_turn_point(line: &[Vec2], i: usize) -> bool {
    let n = line.len();
    if n < 3 {
        return true;
    }
    let (a, b, c) = (line[(i + n - 1) % n], line[i], line[(i + 1) % n]);
    let (u, v) = (b - a, c - b);
    let (lu, lv) = (u.norm(), v.norm());
    if !(lu > 0.0 && lv > 0.0) {
        return true;
    }
    let cos = (u.dot(&v) / (lu * lv)).clamp(-1.0, 1.0);
    cos.acos() > TURN_ANGLE
}

/// The entities of one piece's block, in the piece's own coordinates.
fn piece_entities(
    drawing: &mut Drawing,
    pattern: &Pattern,
    piece: &Piece,
    variant: DxfVariant,
) -> Vec<Entity> {
    let mut out = Vec::new();
    // Layer 1: cut line and piece text.
    out.extend(polyline(drawing, &piece.cut_line, "1"));
    let anchor = point(piece.label_anchor);
    let size = pattern.labels.size.trim();
    let piece_text = [
        format!("Piece Name: {}", piece.name),
        format!(
            "Quantity: {}{}",
            piece.cut_quantity,
            if piece.mirrored { " (mirrored)" } else { "" }
        ),
        format!("Size: {}", if size.is_empty() { "one size" } else { size }),
    ];
    let line_step = 1.6 * TEXT_MM;
    for (k, line) in piece_text.iter().enumerate() {
        let at = Point::new(anchor.x, anchor.y - k as Real * line_step, 0.0);
        out.push(text(at, TEXT_MM, line, "1"));
    }
    // Layers 2 and 3: turn and curve points of the cut line.
    for (i, &p) in piece.cut_line.iter().enumerate() {
        let layer = if is_turn_point(&piece.cut_line, i) {
            "2"
        } else {
            "3"
        };
        out.push(on_layer(
            EntityType::ModelPoint(ModelPoint::new(point(p))),
            layer,
        ));
    }
    // Layer 4: notches.
    for n in &piece.notches {
        if let Some((a, b)) = notch_slit(n.on_cut_line, n.at, n.depth) {
            out.push(on_layer(
                EntityType::Line(Line::new(point(a), point(b))),
                "4",
            ));
        }
    }
    // Layer 7: grain line.
    let g = piece.grain_line;
    out.push(on_layer(
        EntityType::Line(Line::new(point(g.from), point(g.to))),
        "7",
    ));
    // Layer 13: drill holes.
    for &h in &piece.drill_holes {
        out.push(on_layer(
            EntityType::ModelPoint(ModelPoint::new(point(h))),
            "13",
        ));
    }
    // Layer 14: sew line.
    out.extend(polyline(drawing, &piece.sewing_line, "14"));
    // Layer 15: annotation (the label lines below the piece text, and the seam numbers).
    let first = piece_text.len() as Real * line_step + 0.5 * line_step;
    for (k, line) in piece.label_lines(&pattern.labels).iter().enumerate() {
        let at = Point::new(
            anchor.x,
            anchor.y - first - k as Real * 1.6 * ANNOTATION_MM,
            0.0,
        );
        out.push(text(at, ANNOTATION_MM, line, "15"));
    }
    for (at, number) in piece.seam_labels() {
        out.push(text(point(at), TEXT_MM, number, "15"));
    }
    // ASTM: the boundary again on the ASTM boundary layer.
    if variant == DxfVariant::Astm {
        out.extend(polyline(drawing, &piece.cut_line, "84"));
    }
    out
}

/// The pattern as DXF-AAMA or DXF-ASTM (see the module documentation).
pub fn dxf_pattern(pattern: &Pattern, variant: DxfVariant) -> Result<Vec<u8>, DxfWriteError> {
    dxf_laid_out(pattern, variant, &sheet(pattern, GAP, MARGIN), None)
}

/// `patterns-marker.dxf`: the marker as DXF-AAMA (see the module documentation). `placed` is the marker's
/// pieces at their places on the fabric ([`crate::marker::Marker::pattern`]), `marker` the marker.
pub fn dxf_marker(
    placed: &Pattern,
    marker: &crate::marker::Marker,
) -> Result<Vec<u8>, DxfWriteError> {
    let layout = Sheet {
        offsets: vec![Vec2::zeros(); placed.pieces.len()],
        size: Vec2::new(marker.length, marker.width),
    };
    dxf_laid_out(
        placed,
        DxfVariant::Aama,
        &layout,
        Some(Vec2::new(marker.length, marker.width)),
    )
}

/// The pattern's pieces as blocks inserted at `layout`'s offsets, with a marker's fabric `(length, width)`
/// (m) on layer `FABRIC` when given.
fn dxf_laid_out(
    pattern: &Pattern,
    variant: DxfVariant,
    layout: &Sheet,
    fabric: Option<Vec2>,
) -> Result<Vec<u8>, DxfWriteError> {
    let mut drawing = Drawing::new();
    drawing.header.version = AcadVersion::R2000;
    drawing.header.default_drawing_units = Units::Millimeters;
    drawing.header.drawing_units = DrawingUnits::Metric;
    drawing.header.maximum_drawing_extents = point(layout.size);

    let mut layers: Vec<(&str, u8)> = vec![
        ("1", 7),
        ("2", 1),
        ("3", 3),
        ("4", 1),
        ("7", 5),
        ("8", 8),
        ("13", 6),
        ("14", 2),
        ("15", 4),
    ];
    if variant == DxfVariant::Astm {
        layers.extend([("84", 7), ("85", 8)]);
    }
    if fabric.is_some() {
        layers.push(("FABRIC", 5));
    }
    for (name, color) in layers {
        drawing.add_layer(Layer {
            name: name.into(),
            color: Color::from_index(color),
            ..Default::default()
        });
    }

    let mut used = HashSet::new();
    for (i, piece) in pattern.pieces.iter().enumerate() {
        let name = block_name(&piece.name, i, &mut used);
        let entities = piece_entities(&mut drawing, pattern, piece, variant);
        drawing.add_block(Block {
            name: name.clone(),
            layer: "0".into(),
            base_point: Point::origin(),
            entities,
            ..Default::default()
        });
        let offset = layout.offsets.get(i).copied().unwrap_or_else(Vec2::zeros);
        drawing.add_entity(on_layer(
            EntityType::Insert(Insert {
                name,
                location: point(offset),
                ..Default::default()
            }),
            "0",
        ));
    }

    if let Some(f) = fabric {
        let corners = [
            Vec2::zeros(),
            Vec2::new(f.x, 0.0),
            Vec2::new(f.x, f.y),
            Vec2::new(0.0, f.y),
        ];
        if let Some(e) = polyline(&mut drawing, &corners, "FABRIC") {
            drawing.add_entity(e);
        }
    }

    // Style system text, once, below the pieces.
    let l = &pattern.labels;
    let style_name = [&l.template, &l.order_id]
        .into_iter()
        .map(|s| s.trim())
        .find(|s| !s.is_empty())
        .unwrap_or("skintight pattern");
    let style_text = [
        format!("Style Name: {style_name}"),
        format!("Creation Date: {}", l.date.trim()),
        format!("Author: {}", l.software.trim()),
        format!(
            "Sample Size: {}",
            if l.size.trim().is_empty() {
                "one size"
            } else {
                l.size.trim()
            }
        ),
        "Grading Rule Table: none".into(),
        "Units: METRIC".into(),
    ];
    for (k, line) in style_text.iter().enumerate() {
        let at = Point::new(MARGIN * MM, -(k as Real + 1.0) * 1.6 * TEXT_MM, 0.0);
        drawing.add_entity(text(at, TEXT_MM, line, "1"));
    }
    drawing.header.minimum_drawing_extents =
        Point::new(0.0, -(style_text.len() as Real + 1.0) * 1.6 * TEXT_MM, 0.0);

    let mut out = Vec::new();
    drawing
        .save(&mut out)
        .map_err(|e| DxfWriteError(e.to_string()))?;
    let text = String::from_utf8(out).map_err(|e| DxfWriteError(e.to_string()))?;
    Ok(repair_handles(&text).into_bytes())
}

/// Mends two handle defects of the `dxf` crate's AutoCAD 2000 output, which AutoCAD-strict readers reject
/// and ezdxf repairs on load: a TABLE head is written without a handle, and an ENDBLK is written with its
/// BLOCK's handle (a duplicate). Each gets a fresh handle above every handle in the file, and `$HANDSEED`
/// is raised past them. `text` is the crate's ASCII DXF (`\r\n` lines, code/value pairs).
fn repair_handles(text: &str) -> String {
    let lines: Vec<&str> = text.split("\r\n").collect();
    let pairs: Vec<(&str, &str)> = lines.chunks_exact(2).map(|p| (p[0], p[1])).collect();
    let is = |k: usize, code: &str, value: Option<&str>| {
        pairs
            .get(k)
            .is_some_and(|(c, v)| c.trim() == code && value.is_none_or(|want| v.trim() == want))
    };
    let mut next = pairs
        .iter()
        .filter(|(c, _)| matches!(c.trim(), "5" | "105"))
        .filter_map(|(_, v)| u64::from_str_radix(v.trim(), 16).ok())
        .max()
        .map_or(1, |h| h + 1);
    let mut fresh = || {
        let h = format!("{next:X}");
        next += 1;
        h
    };
    let mut out: Vec<(String, String)> = Vec::with_capacity(pairs.len() + 32);
    let mut k = 0;
    while k < pairs.len() {
        let (c, v) = pairs[k];
        out.push((c.into(), v.into()));
        if is(k, "0", Some("TABLE")) && is(k + 1, "2", None) && !is(k + 2, "5", None) {
            out.push((pairs[k + 1].0.into(), pairs[k + 1].1.into()));
            out.push(("  5".into(), fresh()));
            k += 2;
            continue;
        }
        if is(k, "0", Some("ENDBLK")) && is(k + 1, "5", None) {
            out.push(("  5".into(), fresh()));
            k += 2;
            continue;
        }
        k += 1;
    }
    for k in 0..out.len().saturating_sub(2) {
        if out[k].0.trim() == "9" && out[k].1 == "$HANDSEED" && out[k + 1].0.trim() == "5" {
            out[k + 1].1 = format!("{next:X}");
        }
    }
    let mut text = String::with_capacity(text.len() + 512);
    for (c, v) in out {
        text.push_str(&c);
        text.push_str("\r\n");
        text.push_str(&v);
        text.push_str("\r\n");
    }
    text
}

#[cfg(test)]
mod tests;
