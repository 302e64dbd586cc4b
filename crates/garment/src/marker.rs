//! The marker: the pieces of one or several garments packed on a fabric of given width, each piece's grain
//! along the fabric's length, so that the cutting room cuts them from the shortest length of fabric.
//!
//! **What is packed.** Every piece of every pattern, [`Piece::cut_quantity`] times, flipped when
//! [`Piece::mirrored`] (`x → −x` in the piece's coordinates, before anything else), then turned by `−θ` so
//! that its grain line (at angle `θ` after the flip) runs along the marker's `+x` axis, the fabric's length.
//! A piece may then be turned by 180° more (grain reversed, a *two-way* marker, [`MarkerParams::two_way`]),
//! never by another angle and never flipped again: a knit's wales must run along the fabric's length and its
//! face side stays up. Placed point `q` of piece point `p` (m) is `q = R(φ) M p + t`
//! ([`MarkerPlacement::apply`]), `M` the flip or the identity, `φ ∈ {−θ, π − θ}`.
//!
//! **The objective.** The fabric is the strip `0 ≤ y ≤ W` (`W` = [`MarkerParams::width`], m), unbounded in
//! `x ≥ 0`; the marker's length is `L = max x` over the placed cut lines, its efficiency
//! `E = Σ A_i / (W L)` with `A_i` the area enclosed by each placed cut line (every copy counted). Any marker
//! has `L ≥ L₀ = max(max_i ℓ_i, Σ A_i / W)`, `ℓ_i` the piece's extent along its grain: the bound the tests
//! measure the result against.
//!
//! **The engine and the heuristic.** Collisions are the `jagua-rs` crate's (J. Gardeyn's collision-detection
//! engine for 2D irregular cutting and packing, MPL-2.0, maintained, used unmodified): its strip-packing
//! problem holds the placed pieces in a quadtree and answers whether a piece at a pose overlaps any placed
//! piece or leaves the fabric, first by a fail-fast test of the piece's inscribed circles, then exactly on
//! the polygon edges. The engine works in `f32` millimetres; each piece is inflated by half of
//! [`MarkerParams::gap`] for the test (the engine's own offset), so placed cut lines keep at least `gap`
//! between them. The placement on top of it is a bottom-left heuristic (Jakobs 1996; Dowsland, Vaid & Dowsland
//! 2002 for its grid form): pieces are taken one at a time in a given order; for each allowed turn the
//! columns `x = 0, s, 2s, …` (`s` = [`MarkerParams::step`]) are scanned for the first one where some
//! `y = 0, s/2, …` fits, and that pose is compacted by sliding the piece down, then left, by halving steps
//! down to 0.1 mm until neither move fits. Of the turns, the pose whose right end is least is kept (within
//! 1 mm: the one whose area lies further left, leaving wider gaps at the right for the pieces to come; then
//! the lower). The whole is run for several orders — by decreasing area, length along the grain, width across
//! it, and [`MarkerParams::orders`] − 3 seeded shuffles of the area order — and the shortest marker is kept.
//! Nothing here is differentiated: the result is a placement, checked against an independent polygon test in
//! the tests.

use std::f64::consts::PI;
use std::time::Instant;

use jagua_rs::collision_detection::CDEConfig;
use jagua_rs::collision_detection::hazards::filter::NoFilter;
use jagua_rs::entities::Item;
use jagua_rs::geometry::fail_fast::SPSurrogateConfig;
use jagua_rs::geometry::geo_enums::RotationRange;
use jagua_rs::geometry::geo_traits::{Transformable, TransformableFrom};
use jagua_rs::geometry::primitives::{Point, SPolygon};
use jagua_rs::geometry::shape_modification::{ShapeModifyConfig, ShapeModifyMode};
use jagua_rs::geometry::{DTransformation, OriginalShape};
use jagua_rs::probs::spp::entities::{SPInstance, SPPlacement, SPProblem, Strip};
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use skintight_geometry::polygon_area::polygon_area;

use crate::math::{Real, Vec2};
use crate::pattern::{EdgeKind, GrainLine, Notch, OrderLabels, Pattern, Piece};

/// Millimetres per metre (the engine's unit).
const MM: Real = 1000.0;
/// Smallest slide of the compaction (mm).
const FINEST_SLIDE_MM: f32 = 0.1;
/// Most copies of one piece a marker takes (a bound on the work a bad cut quantity could ask for).
pub const MAX_COPIES: u32 = 1000;

/// Settings of [`marker`]. Lengths in metres.
#[derive(Clone, Debug, PartialEq)]
pub struct MarkerParams {
    /// Width of the fabric (m), across the grain: the marker's extent in `y`. Default 1.5.
    pub width: Real,
    /// Least distance between two placed cut lines, and between a cut line and the fabric's edges (half of
    /// it there) (m), ≥ 0. Default 0.002 (a knife's or a laser's kerf and a little).
    pub gap: Real,
    /// Grid step of the placement scan (m), > 0; the compaction then slides pieces to 0.1 mm. Default 0.01.
    pub step: Real,
    /// Whether a piece may lie with its grain reversed (turned 180°). Default true; false for a one-way
    /// marker (a fabric with a nap or a shading that shows the knitting direction).
    pub two_way: bool,
    /// How many piece orders are tried (≥ 1; the first three are by area, length and width, the others
    /// seeded shuffles). Default 8.
    pub orders: usize,
}

impl Default for MarkerParams {
    fn default() -> Self {
        MarkerParams {
            width: 1.5,
            gap: 0.002,
            step: 0.01,
            two_way: true,
            orders: 8,
        }
    }
}

/// Why no marker was made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MarkerError {
    /// A setting out of its range.
    #[error("marker {field} = {value} is out of range: expected {expected}")]
    BadParameter {
        /// The [`MarkerParams`] field.
        field: &'static str,
        /// The value given.
        value: Real,
        /// What is accepted.
        expected: &'static str,
    },
    /// A piece does not fit across the fabric with its grain along the length.
    #[error(
        "piece '{piece}' is {across:.4} m across its grain (with the {gap} m gap), wider than the {width} m \
         fabric: give a fabric at least that wide"
    )]
    TooWide {
        /// The piece's name.
        piece: String,
        /// Its extent across the grain plus the gap (m).
        across: Real,
        /// The gap (m).
        gap: Real,
        /// The fabric's width (m).
        width: Real,
    },
    /// A piece whose outline or grain line cannot be placed.
    #[error("piece '{piece}' cannot be placed on a marker: {reason}")]
    BadPiece {
        /// The piece's name.
        piece: String,
        /// What is wrong with it.
        reason: String,
    },
    /// Nothing to place.
    #[error(
        "the marker has no piece to place: the patterns have no pieces or every cut quantity is 0"
    )]
    NoPieces,
}

/// Where one copy of a piece lies on the marker: `q = R(rotation) M p + translation`, `M` the flip
/// `x → −x` when `mirrored`, else the identity (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct MarkerPlacement {
    /// Index of the pattern in the list given to [`marker`].
    pub pattern: usize,
    /// Index of the piece in that pattern.
    pub piece: usize,
    /// Which copy of the piece (0-based, below its cut quantity).
    pub copy: u32,
    /// Whether the piece is flipped (`x → −x`) before it is turned.
    pub mirrored: bool,
    /// The turn (rad), applied after the flip.
    pub rotation: Real,
    /// The translation (m), applied last.
    pub translation: Vec2,
}

impl MarkerPlacement {
    /// The marker point (m) of piece point `p` (m).
    pub fn apply(&self, p: Vec2) -> Vec2 {
        let m = if self.mirrored {
            Vec2::new(-p.x, p.y)
        } else {
            p
        };
        let (s, c) = self.rotation.sin_cos();
        Vec2::new(c * m.x - s * m.y, s * m.x + c * m.y) + self.translation
    }

    /// `piece` as it lies on the marker: every point moved by [`Self::apply`]. A flipped piece's outlines
    /// then run clockwise.
    pub fn place(&self, piece: &Piece) -> Piece {
        let map = |ps: &[Vec2]| ps.iter().map(|&p| self.apply(p)).collect::<Vec<_>>();
        Piece {
            sewing_line: map(&piece.sewing_line),
            cut_line: map(&piece.cut_line),
            notches: piece
                .notches
                .iter()
                .map(|n| Notch {
                    at: self.apply(n.at),
                    on_cut_line: self.apply(n.on_cut_line),
                    ..n.clone()
                })
                .collect(),
            grain_line: GrainLine {
                from: self.apply(piece.grain_line.from),
                to: self.apply(piece.grain_line.to),
            },
            drill_holes: map(&piece.drill_holes),
            label_anchor: self.apply(piece.label_anchor),
            ..piece.clone()
        }
    }
}

/// A marker: the fabric's width and the length used, and where each copy of each piece lies.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Marker {
    /// Width of the fabric (m).
    pub width: Real,
    /// Length of fabric used (m): the largest `x` of a placed cut line (the marker starts at `x = 0`).
    pub length: Real,
    /// Total area of the placed pieces' cut lines, every copy counted (m²).
    pub pieces_area: Real,
    /// `pieces_area / (width · length)`, in (0, 1].
    pub efficiency: Real,
    /// The lower bound `max(longest piece along its grain, pieces_area / width)` on any marker's length (m).
    pub lower_bound: Real,
    /// One per placed copy, in the order they were placed.
    pub placements: Vec<MarkerPlacement>,
    /// Wall time of the nesting (s).
    pub seconds: Real,
}

impl Marker {
    /// The marker as a pattern the pattern writers draw at its own coordinates: every placed copy as a piece
    /// (named `NAME` or, with several patterns, `NAME (k)` for the pattern's 1-based index), the labels of
    /// the first pattern, no seams (the seams belong to each garment's own pattern files).
    pub fn pattern(&self, patterns: &[&Pattern]) -> Pattern {
        let several = patterns.len() > 1;
        let pieces = self
            .placements
            .iter()
            .filter_map(|pl| {
                let piece = patterns.get(pl.pattern)?.pieces.get(pl.piece)?;
                let mut placed = pl.place(piece);
                if several {
                    placed.name = format!("{} ({})", piece.name, pl.pattern + 1);
                }
                // A placed piece carries no seam edges: the marker has no seams of its own.
                placed
                    .edges
                    .retain(|e| !matches!(e.kind, EdgeKind::Seam { .. }));
                Some(placed)
            })
            .collect();
        Pattern {
            labels: patterns
                .first()
                .map_or_else(OrderLabels::default, |p| p.labels.clone()),
            pieces,
            seams: Vec::new(),
        }
    }
}

/// One copy to place: where it comes from and its outline in the engine's frame before the placement turn
/// (grain along `+x`, bounding box from the origin; mm).
struct PieceCopy {
    pattern: usize,
    piece: usize,
    copy: u32,
    mirrored: bool,
    /// `−θ`: the turn that lays the grain along `+x` (rad).
    grain_turn: Real,
    /// What the turned outline was shifted by to start at the origin (m).
    shift: Vec2,
    /// Extent along and across the grain (m).
    extent: Vec2,
    area: Real,
}

/// Checks `params` (the error names the field).
fn validate(params: &MarkerParams) -> Result<(), MarkerError> {
    let bad = |field, value, expected| {
        Err(MarkerError::BadParameter {
            field,
            value,
            expected,
        })
    };
    if !(params.width.is_finite() && params.width > 0.0 && params.width <= 100.0) {
        return bad("width", params.width, "a width in (0, 100] m");
    }
    if !(params.gap.is_finite() && params.gap >= 0.0 && params.gap <= 0.1) {
        return bad("gap", params.gap, "a distance in [0, 0.1] m");
    }
    if !(params.step.is_finite() && params.step >= 1e-3 && params.step <= 0.1) {
        return bad("step", params.step, "a step in [0.001, 0.1] m");
    }
    if params.orders == 0 || params.orders > 1000 {
        return bad("orders", params.orders as Real, "between 1 and 1000");
    }
    Ok(())
}

/// `points` without consecutive repeats (closer than 1 µm), the last one against the first too.
fn distinct(points: Vec<Vec2>) -> Vec<Vec2> {
    let mut out: Vec<Vec2> = Vec::with_capacity(points.len());
    for p in points {
        if out.last().is_none_or(|q| (p - q).norm() > 1e-6) {
            out.push(p);
        }
    }
    while out.len() > 1 && (out[0] - out[out.len() - 1]).norm() <= 1e-6 {
        out.pop();
    }
    out
}

/// The copies of every piece, each with its outline in the engine's frame (mm, `f32`).
fn copies(
    patterns: &[&Pattern],
    params: &MarkerParams,
) -> Result<Vec<(PieceCopy, Vec<Point>)>, MarkerError> {
    let mut out = Vec::new();
    for (pi, pattern) in patterns.iter().enumerate() {
        for (ki, piece) in pattern.pieces.iter().enumerate() {
            if piece.cut_quantity == 0 {
                continue;
            }
            let bad = |reason: String| MarkerError::BadPiece {
                piece: piece.name.clone(),
                reason,
            };
            if piece.cut_quantity > MAX_COPIES {
                return Err(bad(format!(
                    "its cut quantity {} is above the {MAX_COPIES} a marker takes",
                    piece.cut_quantity
                )));
            }
            let flip = |p: Vec2| {
                if piece.mirrored {
                    Vec2::new(-p.x, p.y)
                } else {
                    p
                }
            };
            let g = flip(piece.grain_line.to) - flip(piece.grain_line.from);
            if !(g.norm() > 0.0 && g.norm().is_finite()) {
                return Err(bad("its grain line has no direction".into()));
            }
            let turn = -g.y.atan2(g.x);
            let (s, c) = turn.sin_cos();
            let turned: Vec<Vec2> = distinct(
                piece
                    .cut_line
                    .iter()
                    .map(|&p| {
                        let m = flip(p);
                        Vec2::new(c * m.x - s * m.y, s * m.x + c * m.y)
                    })
                    .collect(),
            );
            if turned.len() < 3 || turned.iter().any(|p| !(p.x.is_finite() && p.y.is_finite())) {
                return Err(bad(
                    "its cut line has fewer than 3 distinct finite points".into()
                ));
            }
            let area = polygon_area(&turned).abs();
            if !(area > 0.0) {
                return Err(bad("its cut line encloses no area".into()));
            }
            let lo = turned
                .iter()
                .fold(Vec2::repeat(Real::INFINITY), |a, p| a.inf(p));
            let hi = turned
                .iter()
                .fold(Vec2::repeat(Real::NEG_INFINITY), |a, p| a.sup(p));
            let extent = hi - lo;
            if extent.y + params.gap > params.width {
                return Err(MarkerError::TooWide {
                    piece: piece.name.clone(),
                    across: extent.y + params.gap,
                    gap: params.gap,
                    width: params.width,
                });
            }
            let points: Vec<Point> = turned
                .iter()
                .map(|p| Point(((p.x - lo.x) * MM) as f32, ((p.y - lo.y) * MM) as f32))
                .collect();
            for copy in 0..piece.cut_quantity {
                out.push((
                    PieceCopy {
                        pattern: pi,
                        piece: ki,
                        copy,
                        mirrored: piece.mirrored,
                        grain_turn: turn,
                        shift: -lo,
                        extent,
                        area,
                    },
                    points.clone(),
                ));
            }
        }
    }
    if out.is_empty() {
        return Err(MarkerError::NoPieces);
    }
    Ok(out)
}

/// The engine's collision settings: a shallow quadtree (a marker holds tens of pieces, not thousands) and a
/// few inscribed circles per piece for the fail-fast test.
fn cde_config() -> CDEConfig {
    CDEConfig {
        quadtree_depth: 5,
        cd_threshold: 16,
        item_surrogate_config: SPSurrogateConfig {
            n_pole_limits: [(32, 0.0), (16, 0.75), (8, 0.90)],
            n_ff_poles: 2,
            n_ff_piers: 0,
        },
    }
}

/// A pose searched for: the turn and translation (mm) and its score (right end, then bottom).
#[derive(Clone, Copy)]
struct Pose {
    rotation: f32,
    x: f32,
    y: f32,
    right: f32,
    /// `x` of the placed shape's centroid (mm): of two poses ending alike, the one whose area lies further
    /// left leaves the wider gaps at the right for the pieces still to come.
    centre: f32,
}

/// The bottom-left placement of `item` among the pieces already in `problem` (see the module
/// documentation), or `None` if it fits nowhere within the strip's length.
fn place(problem: &SPProblem, item: &Item, rotations: &[f32], step: f32) -> Option<Pose> {
    let cde = problem.layout.cde();
    let (width, length) = (problem.strip.fixed_height, problem.strip.width);
    let surrogate = item.shape_cd.surrogate();
    let mut buffer = (*item.shape_cd).clone();
    buffer.surrogate = None;
    let fits = |rotation: f32, x: f32, y: f32, buffer: &mut SPolygon| {
        let t = DTransformation::new(rotation, (x, y)).compose();
        if cde.detect_surrogate_collision(surrogate, &t, &NoFilter) {
            return false;
        }
        buffer.transform_from(&item.shape_cd, &t);
        !cde.detect_poly_collision(buffer, &NoFilter)
    };
    let mut best: Option<Pose> = None;
    for &rotation in rotations {
        // The turned shape's box, to scan its left and bottom ends over the strip.
        let turned = item
            .shape_cd
            .transform_clone(&DTransformation::new(rotation, (0.0, 0.0)).compose());
        let b = turned.bbox;
        let (w, h) = (b.x_max - b.x_min, b.y_max - b.y_min);
        if h > width {
            continue;
        }
        // The engine counts a shape touching the fabric's edge as leaving it: scans start just inside.
        let inside = 0.01_f32;
        let mut found = None;
        let mut x = inside;
        'columns: while x + w <= length {
            if best.is_some_and(|p| x + w > p.right + step) {
                break;
            }
            let mut y = inside;
            while y + h < width {
                if fits(rotation, x - b.x_min, y - b.y_min, &mut buffer) {
                    found = Some((x - b.x_min, y - b.y_min));
                    break 'columns;
                }
                y += 0.5 * step;
            }
            // The top row: flush with the far edge.
            let top = width - inside - h - b.y_min;
            if fits(rotation, x - b.x_min, top, &mut buffer) {
                found = Some((x - b.x_min, top));
                break;
            }
            x += step;
        }
        let Some((mut tx, mut ty)) = found else {
            continue;
        };
        // Compaction: down, then left, by halving slides, until neither moves.
        loop {
            let (x0, y0) = (tx, ty);
            let mut slide = step;
            while slide >= FINEST_SLIDE_MM {
                while fits(rotation, tx, ty - slide, &mut buffer) {
                    ty -= slide;
                }
                while fits(rotation, tx - slide, ty, &mut buffer) {
                    tx -= slide;
                }
                slide *= 0.5;
            }
            if tx == x0 && ty == y0 {
                break;
            }
        }
        let pose = Pose {
            rotation,
            x: tx,
            y: ty,
            right: tx + b.x_max,
            centre: tx + turned.centroid().0,
        };
        let better = best.is_none_or(|p| {
            pose.right < p.right - 1.0
                || (pose.right <= p.right + 1.0
                    && (pose.centre < p.centre - 1.0
                        || (pose.centre <= p.centre + 1.0 && pose.y < p.y)))
        });
        if better {
            best = Some(pose);
        }
    }
    best
}

/// Checks `params` and that every piece of `patterns` fits across the fabric with its grain along the
/// length, without nesting anything: the errors [`marker`] would give before its search.
pub fn fits(patterns: &[&Pattern], params: &MarkerParams) -> Result<(), MarkerError> {
    validate(params)?;
    copies(patterns, params).map(|_| ())
}

/// Packs every piece of `patterns` (cut quantities and mirrored pieces included) on one fabric of
/// `params.width` (see the module documentation); several patterns make one batch marker.
pub fn marker(patterns: &[&Pattern], params: &MarkerParams) -> Result<Marker, MarkerError> {
    let start = Instant::now();
    validate(params)?;
    let copies = copies(patterns, params)?;
    let gap_mm = (params.gap * MM) as f32;
    let modify = ShapeModifyConfig {
        offset: (gap_mm > 0.0).then_some(0.5 * gap_mm),
        simplify_tolerance: None,
        narrow_concavity_cutoff_ratio: None,
    };
    let rotations: Vec<f32> = if params.two_way {
        vec![0.0, std::f32::consts::PI]
    } else {
        vec![0.0]
    };
    let mut items = Vec::with_capacity(copies.len());
    for (id, (c, points)) in copies.iter().enumerate() {
        let bad = |e: String| MarkerError::BadPiece {
            piece: patterns[c.pattern].pieces[c.piece].name.clone(),
            reason: e,
        };
        let shape = SPolygon::new(points.clone()).map_err(|e| bad(e.to_string()))?;
        let item = Item::new(
            id,
            OriginalShape {
                shape,
                pre_transform: DTransformation::empty(),
                modify_mode: ShapeModifyMode::Inflate,
                modify_config: modify,
            },
            RotationRange::Discrete(rotations.clone()),
            None,
            cde_config().item_surrogate_config,
        )
        .map_err(|e| bad(e.to_string()))?;
        items.push((item, 1));
    }
    // A strip long enough for every piece in a row.
    let row: Real = copies.iter().map(|(c, _)| c.extent.x + params.gap).sum();
    let mut strip = Strip::new(
        (params.width * MM) as f32,
        cde_config(),
        ShapeModifyConfig {
            offset: None,
            simplify_tolerance: None,
            narrow_concavity_cutoff_ratio: None,
        },
    )
    .map_err(|_| MarkerError::BadParameter {
        field: "width",
        value: params.width,
        expected: "a positive width",
    })?;
    // Room for every piece in a row, each a grid step apart.
    strip.set_width(((row + (copies.len() + 2) as Real * params.step) * MM) as f32);
    let instance = SPInstance::new(items, strip);

    // The orders tried.
    let n = copies.len();
    let by = |key: &dyn Fn(&PieceCopy) -> Real| {
        let mut o: Vec<usize> = (0..n).collect();
        o.sort_by(|&a, &b| {
            key(&copies[b].0)
                .total_cmp(&key(&copies[a].0))
                .then(a.cmp(&b))
        });
        o
    };
    let by_area = by(&|c| c.area);
    let mut orders = vec![by_area.clone(), by(&|c| c.extent.x), by(&|c| c.extent.y)];
    let mut rng = ChaCha8Rng::seed_from_u64(47);
    while orders.len() < params.orders.max(1) {
        let mut o = by_area.clone();
        o.shuffle(&mut rng);
        orders.push(o);
    }
    orders.truncate(params.orders.max(1));

    let step = (params.step * MM) as f32;
    let mut best: Option<(Real, Vec<(usize, Pose)>)> = None;
    for order in &orders {
        let mut problem = SPProblem::new(instance.clone());
        let mut poses = Vec::with_capacity(n);
        for &id in order {
            let item = instance.items[id].0.clone();
            let Some(pose) = place(&problem, &item, &rotations, step) else {
                poses.clear();
                break;
            };
            problem.place_item(SPPlacement {
                item_id: id,
                d_transf: DTransformation::new(pose.rotation, (pose.x, pose.y)),
            });
            poses.push((id, pose));
        }
        if poses.len() != n {
            continue;
        }
        let length = poses
            .iter()
            .map(|&(id, pose)| {
                let pl = placement(&copies[id].0, pose);
                patterns[pl.pattern].pieces[pl.piece]
                    .cut_line
                    .iter()
                    .map(|&p| pl.apply(p).x)
                    .fold(Real::NEG_INFINITY, Real::max)
            })
            .fold(0.0, Real::max);
        if best.as_ref().is_none_or(|(l, _)| length < *l) {
            best = Some((length, poses));
        }
    }
    let Some((length, poses)) = best else {
        return Err(MarkerError::BadPiece {
            piece: patterns[copies[0].0.pattern].pieces[copies[0].0.piece]
                .name
                .clone(),
            reason: "no order of the pieces fits on the fabric".into(),
        });
    };
    let pieces_area: Real = copies.iter().map(|(c, _)| c.area).sum();
    let longest = copies.iter().map(|(c, _)| c.extent.x).fold(0.0, Real::max);
    Ok(Marker {
        width: params.width,
        length,
        pieces_area,
        efficiency: pieces_area / (params.width * length),
        lower_bound: longest.max(pieces_area / params.width),
        placements: poses
            .iter()
            .map(|&(id, pose)| placement(&copies[id].0, pose))
            .collect(),
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// The placement (m) of `copy` at the engine's `pose` (mm): the grain turn, the shift to the origin, the
/// engine's turn and translation, composed.
fn placement(copy: &PieceCopy, pose: Pose) -> MarkerPlacement {
    // The engine's turn is 0 or π in `f32`: taken exactly.
    let r = if pose.rotation > 1.0 { PI } else { 0.0 };
    let (s, c) = r.sin_cos();
    let shifted = Vec2::new(
        c * copy.shift.x - s * copy.shift.y,
        s * copy.shift.x + c * copy.shift.y,
    );
    // R(r) (R(g) M p + shift) + t = R(r + g) M p + R(r) shift + t.
    MarkerPlacement {
        pattern: copy.pattern,
        piece: copy.piece,
        copy: copy.copy,
        mirrored: copy.mirrored,
        rotation: (r + copy.grain_turn).rem_euclid(2.0 * PI),
        translation: shifted + Vec2::new(pose.x as Real, pose.y as Real) / MM,
    }
}

#[cfg(test)]
mod tests;
