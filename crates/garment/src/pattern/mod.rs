//! The cut-ready pattern: the one model every pattern file is written from (DXF, PDF, HP-GL, SVG, JSON).
//!
//! A [`Pattern`] is a list of [`Piece`]s and the [`Seam`]s between them, plus the order's [`OrderLabels`].
//! Each piece carries
//! * its **sewing line**: the closed outline of the flat pattern (the rest shape the garment was simulated
//!   with), counter-clockwise, seen from the face (right) side of the fabric;
//! * its **named edges** ([`PieceEdge`]): the sewing line split into runs, each a seam side (with its partner
//!   piece) or an opening (waist, hem, cuff…), with the seam allowance of that run;
//! * its **cut line**: the sewing line offset outwards by each edge's allowance, with mitred or squared
//!   corners where the edges meet ([`CornerStyle`]);
//! * **notches** (match marks) on the sewing line at seam ends and every `notch_spacing` along seams, at the
//!   same arc length from the seam's start on both sides, cut into the allowance from the cut line;
//! * a **grain line**: the fabric's wale direction on the piece;
//! * **drill holes**, **labels** (order, customer, fabric, piece, cut quantity, face side…).
//!
//! Units: every length and position here is in metres (m), pattern coordinates with +y up; writers convert
//! to their own units (mm for DXF, JSON and SVG, PostScript points for PDF, plotter units for HP-GL).

use serde::Serialize;

use crate::math::{Real, Vec2, Vec3};

/// Version of the pattern model as written to `patterns.json` (`schema_version`). Raise it when a field
/// changes meaning or is removed; adding a field keeps it.
pub const SCHEMA_VERSION: u32 = 1;

/// How far inside the sewing line a seam's number is printed (m).
const SEAM_LABEL_INSET: Real = 0.006;

/// A garment's cut-ready pattern: pieces, the seams joining them and the order's text.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Pattern {
    /// Text printed on every piece and in every file's header.
    pub labels: OrderLabels,
    /// The pattern pieces, in the garment's panel order.
    pub pieces: Vec<Piece>,
    /// The seams: each joins one edge of one piece to one edge of another (or the same) piece.
    pub seams: Vec<Seam>,
}

/// The order's text fields, as the shop gave them (empty when not given).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct OrderLabels {
    /// The shop's order id.
    pub order_id: String,
    /// The customer's reference (a name or an id; the shop decides).
    pub customer: String,
    /// The garment template (e.g. "knee-high stocking"), or the scene's name.
    pub template: String,
    /// Size or compression class (e.g. "class II").
    pub size: String,
    /// The fabric's name.
    pub fabric: String,
    /// Date the pattern was made, ISO 8601 (`YYYY-MM-DD`).
    pub date: String,
    /// The software and its version, e.g. `skintight 0.1.0`.
    pub software: String,
}

/// One pattern piece, true scale, in its own pattern coordinates (m, +y up).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Piece {
    /// The piece's name (the garment panel's name).
    pub name: String,
    /// `#S × 2` sewing line (m): the closed outline, counter-clockwise, not repeated at the end.
    pub sewing_line: Vec<Vec2>,
    /// The sewing line split into consecutive named runs, in order along it; together they cover it once.
    pub edges: Vec<PieceEdge>,
    /// `#C × 2` cut line (m): the sewing line offset outwards by the edges' allowances, closed,
    /// counter-clockwise, not repeated at the end; encloses the sewing line.
    pub cut_line: Vec<Vec2>,
    /// Match marks, in order along the sewing line.
    pub notches: Vec<Notch>,
    /// The grain line: the fabric's wale (lengthwise) direction on the piece.
    pub grain_line: GrainLine,
    /// Drill holes (m): points inside the piece marked by a punched hole.
    pub drill_holes: Vec<Vec2>,
    /// How many times to cut the piece.
    pub cut_quantity: u32,
    /// Whether the piece is to be cut mirrored (flipped) — false: cut as drawn.
    pub mirrored: bool,
    /// Which side of the fabric faces the viewer in the drawing.
    pub face_side: FaceSide,
    /// Where the piece's label text block starts (m): a point inside the sewing line.
    pub label_anchor: Vec2,
    /// The rigid motion that best lays the flat piece onto its place on the body (for 3D pattern formats).
    pub placement: Placement,
}

/// A rigid motion of a flat piece into 3D: pattern point `(x, y)` goes to `R (x, y, 0) + translation`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Placement {
    /// Rotation `R = R_z(γ) R_y(β) R_x(α)` as `[α, β, γ]` (rad): extrinsic x, then y, then z.
    pub rotation_xyz: [Real; 3],
    /// Translation (m).
    pub translation: Vec3,
}

/// Which side of the fabric is up as the piece is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FaceSide {
    /// The face (right, outer) side of the fabric is up: the garment as seen from outside.
    FaceUp,
}

/// A run of a piece's sewing line with one role and one seam allowance.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PieceEdge {
    /// A name for the cutting room, unique within the piece: `seam 3` or `hem`, `waist`, `top`…
    pub name: String,
    /// What the run is.
    pub kind: EdgeKind,
    /// First sewing-line vertex of the run (index into [`Piece::sewing_line`]).
    pub start: usize,
    /// Last sewing-line vertex of the run; the run goes forward (counter-clockwise) from `start` to `end`,
    /// wrapping past the end of the list. `start == end` means the run is the whole closed sewing line.
    pub end: usize,
    /// Seam allowance (m): distance from the sewing line to the cut line along this run, ≥ 0.
    pub allowance: Real,
    /// Length of the run along the sewing line (m).
    pub length: Real,
}

/// The role of a run of a piece's outline.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case", tag = "type")]
pub enum EdgeKind {
    /// One side of seam `seam` (index into [`Pattern::seams`]), sewn to `partner` (a piece index).
    Seam {
        /// Index into [`Pattern::seams`].
        seam: usize,
        /// Which side of the seam this run is (0 or 1; see [`Seam::edges`]).
        side: usize,
        /// The piece across the seam.
        partner: usize,
    },
    /// A free edge of the garment (an opening: waist, hem, cuff, neckline…), finished rather than sewn to
    /// another piece.
    Opening {
        /// Which opening, by height on the body.
        role: OpeningRole,
    },
}

/// Which opening of the garment a free edge is, by its height on the body (+y up).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum OpeningRole {
    /// The highest opening of the piece (a waist, the top of a stocking).
    Top,
    /// The lowest opening of the piece (a hem, a cuff at the ankle or wrist).
    Bottom,
    /// Any other opening.
    Side,
}

/// A match mark on a piece's sewing line.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Notch {
    /// The mark's point on the sewing line (m).
    pub at: Vec2,
    /// Where the notch starts on the cut line (m): the notch is the slit from `on_cut_line` towards `at`,
    /// `depth` long.
    pub on_cut_line: Vec2,
    /// Length of the slit cut into the allowance (m), at most the allowance.
    pub depth: Real,
    /// The seam it matches across (index into [`Pattern::seams`]), or `None` for a mark on an opening.
    pub seam: Option<usize>,
    /// Arc length (m) from the seam's start (or the edge's start) to the mark, measured the same way on both
    /// sides of a seam.
    pub arc_length: Real,
    /// Whether it was asked for by the user rather than placed automatically.
    pub user: bool,
}

/// A grain line: an arrow in the fabric's wale direction.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct GrainLine {
    /// Tail of the arrow (m).
    pub from: Vec2,
    /// Head of the arrow (m): `to − from` points along the wales.
    pub to: Vec2,
}

/// A seam: two runs of sewing line sewn together, run 0 from its start forward, run 1 from its end backward
/// (the two sides face each other), so arc length `s` on one side matches `s` on the other.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Seam {
    /// A name for the cutting room: `seam 3` (1-based like the labels on the pieces).
    pub name: String,
    /// The two pieces (indices into [`Pattern::pieces`]).
    pub pieces: [usize; 2],
    /// The edge on each piece (index into that piece's [`Piece::edges`]).
    pub edges: [usize; 2],
    /// Sewing-line length of each side (m).
    pub lengths: [Real; 2],
    /// Intended difference `lengths[0] − lengths[1]` (m): 0 for a seam sewn flat.
    pub intended_ease: Real,
    /// Whether the seam closes on itself (a tube's single seam).
    pub closed: bool,
}

impl Seam {
    /// `lengths[0] − lengths[1] − intended_ease` (m): what the sewer would have to ease in.
    pub fn mismatch(&self) -> Real {
        self.lengths[0] - self.lengths[1] - self.intended_ease
    }
}

impl Piece {
    /// The lines of text printed on the piece, in order: piece name, order, customer, template, size,
    /// fabric, cut quantity (and mirroring), face side, date and software. Empty order fields are left out.
    pub fn label_lines(&self, labels: &OrderLabels) -> Vec<String> {
        let mut lines = vec![format!("Piece: {}", self.name)];
        let mut add = |key: &str, value: &str| {
            if !value.trim().is_empty() {
                lines.push(format!("{key}: {}", value.trim()));
            }
        };
        add("Order", &labels.order_id);
        add("Customer", &labels.customer);
        add("Template", &labels.template);
        add("Size", &labels.size);
        add("Fabric", &labels.fabric);
        lines.push(format!(
            "Cut {}{}",
            self.cut_quantity,
            if self.mirrored { " mirrored" } else { "" }
        ));
        lines.push(
            match self.face_side {
                FaceSide::FaceUp => "Face side up",
            }
            .into(),
        );
        let mut add = |key: &str, value: &str| {
            if !value.trim().is_empty() {
                lines.push(format!("{key}: {}", value.trim()));
            }
        };
        add("Date", &labels.date);
        add("Made by", &labels.software);
        lines
    }

    /// Where each seam's number is printed on the piece: per seam side, the point 6 mm inside the middle of
    /// the run (m) and the number (`3` for `seam 3`), the same on both pieces of the seam.
    pub fn seam_labels(&self) -> Vec<(Vec2, &str)> {
        let n = self.sewing_line.len();
        if n < 2 {
            return Vec::new();
        }
        self.edges
            .iter()
            .filter(|e| matches!(e.kind, EdgeKind::Seam { .. }))
            .map(|e| {
                let run = notches::Run {
                    sewing: &self.sewing_line,
                    start: e.start % n,
                    end: e.end % n,
                };
                let (at, normal) = run.point_at(0.5 * e.length);
                (
                    at - normal * SEAM_LABEL_INSET,
                    e.name.trim_start_matches("seam "),
                )
            })
            .collect()
    }

    /// Axis-aligned bounds `(min, max)` of the cut line (m); the sewing line's if the cut line is empty.
    pub fn bounds(&self) -> (Vec2, Vec2) {
        let pts = if self.cut_line.is_empty() {
            &self.sewing_line
        } else {
            &self.cut_line
        };
        let mut lo = Vec2::repeat(Real::INFINITY);
        let mut hi = Vec2::repeat(Real::NEG_INFINITY);
        for p in pts {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        if lo.x > hi.x {
            (Vec2::zeros(), Vec2::zeros())
        } else {
            (lo, hi)
        }
    }
}

/// Where each piece goes on one sheet: pieces side by side from left to right in order, bottoms aligned,
/// `gap` apart (m) between their cut-line bounds, with `margin` (m) around.
#[derive(Clone, Debug, PartialEq)]
pub struct Sheet {
    /// Per piece, the translation (m) from pattern coordinates to sheet coordinates (+y up, origin at the
    /// sheet's lower-left corner).
    pub offsets: Vec<Vec2>,
    /// Width and height of the sheet (m).
    pub size: Vec2,
}

/// Lays the pieces of `pattern` out on one sheet (see [`Sheet`]).
pub fn sheet(pattern: &Pattern, gap: Real, margin: Real) -> Sheet {
    let mut offsets = Vec::with_capacity(pattern.pieces.len());
    let mut x = margin;
    let mut height: Real = 0.0;
    for (i, piece) in pattern.pieces.iter().enumerate() {
        if i > 0 {
            x += gap;
        }
        let (lo, hi) = piece.bounds();
        offsets.push(Vec2::new(x - lo.x, margin - lo.y));
        x += hi.x - lo.x;
        height = height.max(hi.y - lo.y);
    }
    Sheet {
        offsets,
        size: Vec2::new(x + margin, height + 2.0 * margin),
    }
}

pub mod build;
pub mod grain_line;
pub mod notches;
pub mod seam_allowance;

pub use build::{PatternError, PatternParams, UserNotch, pattern};
pub use seam_allowance::CornerStyle;

#[cfg(test)]
mod tests;
