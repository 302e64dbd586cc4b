//! From a sewn [`Garment`] to its cut-ready [`Pattern`]: each panel's outer boundary loop becomes a piece's
//! sewing line, split into named runs (seam sides and openings), offset into the cut line, marked with
//! notches, a grain line and labels.
//!
//! Openings (free runs) are named by height on the body: a piece's highest opening is its `top opening`
//! (a waist, a stocking's top band), its lowest the `bottom opening` (a hem, an ankle or wrist cuff); with
//! a single opening, it is the top or the bottom one as it lies above or below the piece's mean height.
//! Seams are numbered from 1 in the garment's seam order (`seam 3` is `Garment::seams[2]`), the same on
//! both pieces.
//!
//! The work is in three steps, each with its own state: the settings are checked once (`Settings`); each
//! panel's boundary becomes an `Outline` — its sewing line and labelled runs — which draws the piece's
//! edges, cut line and grain line; and the `SeamSides` the outlines recorded are sewn into the
//! pattern's seams, whose notches are cut into both pieces.

use std::collections::HashMap;

use crate::garment::Garment;
use crate::math::{Mat3 as Matrix3, Real, Vec2, Vec3};
use crate::pattern::grain_line::{grain_direction, grain_line, inner_point};
use crate::pattern::notches::{Run, notch, notch_arc_lengths};
use crate::pattern::seam_allowance::{
    CornerStyle, OffsetError, cut_line, first_self_crossing, polygon_contains,
};
use crate::pattern::{
    EdgeKind, FaceSide, Notch, OpeningRole, OrderLabels, Pattern, Piece, PieceEdge, Placement, Seam,
};
use skintight_geometry::polygon_area::polygon_area;

/// A notch the user asks for on a seam, besides the automatic ones.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UserNotch {
    /// The seam (index into [`Garment::seams`]; `seam k` on the pieces is index `k − 1`).
    pub seam: usize,
    /// Arc length from the seam's start (m), in `[0, length]`.
    pub arc_length: Real,
}

/// Settings of [`pattern`]. Lengths in metres.
#[derive(Clone, Debug, PartialEq)]
pub struct PatternParams {
    /// Seam allowance of every seam side (m, ≥ 0). 6 mm is the usual overlock allowance on knits
    /// (ISO 4915 stitch class 500, 1/4 in).
    pub seam_allowance: Real,
    /// Allowance of the openings (m, ≥ 0): 20 mm for a turned and coverstitched hem or band.
    pub opening_allowance: Real,
    /// Per-seam allowances overriding `seam_allowance`: `(seam index, allowance m)`.
    pub seam_allowances: Vec<(usize, Real)>,
    /// How convex corners between runs are drawn.
    pub corner: CornerStyle,
    /// Distance between automatic notches along a seam (m, > 0).
    pub notch_spacing: Real,
    /// Depth of a notch slit (m, ≥ 0; at most the allowance where it is cut).
    pub notch_depth: Real,
    /// Extra notches.
    pub notches: Vec<UserNotch>,
    /// How many times each piece is cut (≥ 1).
    pub cut_quantity: u32,
    /// The body's up axis (unit), for the grain line and the names of the openings.
    pub up: Vec3,
}

impl Default for PatternParams {
    fn default() -> Self {
        Self {
            seam_allowance: 0.006,
            opening_allowance: 0.02,
            seam_allowances: Vec::new(),
            corner: CornerStyle::Mitre,
            notch_spacing: 0.10,
            notch_depth: 0.003,
            notches: Vec::new(),
            cut_quantity: 1,
            up: Vec3::new(0.0, 1.0, 0.0),
        }
    }
}

/// Why a garment's pattern could not be drawn. Fields are named as [`PatternParams`] names them.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PatternError {
    /// A setting is out of its range.
    #[error("{field} = {value} is invalid: it must be {expected}")]
    BadParameter {
        field: &'static str,
        value: Real,
        expected: &'static str,
    },
    /// A per-seam allowance or a user notch names a seam the garment does not have.
    #[error(
        "{field} names seam {seam} (index {index}), but the garment has {seams} seam(s), numbered from 1"
    )]
    NoSuchSeam {
        field: &'static str,
        index: usize,
        seam: usize,
        seams: usize,
    },
    /// A user notch lies off its seam.
    #[error(
        "notch {index} at {arc_length} m along seam {seam} is off the seam, which is {length:.4} m long; give a position between 0 and the seam's length"
    )]
    NotchOffSeam {
        index: usize,
        seam: usize,
        arc_length: Real,
        length: Real,
    },
    /// A panel's pattern has not exactly one boundary loop.
    #[error("panel '{piece}' has {loops} boundary loops; a pattern piece has exactly one")]
    NotADisk { piece: String, loops: usize },
    /// The cut line could not be drawn: the allowances overlap themselves (too wide for the piece).
    #[error("piece '{piece}': {source}; reduce its seam allowance (it is {allowance} m there)")]
    CutLine {
        piece: String,
        allowance: Real,
        /// Whether the offending allowance is an opening's (else a seam's).
        opening: bool,
        source: OffsetError,
    },
}

fn check(
    field: &'static str,
    value: Real,
    ok: bool,
    expected: &'static str,
) -> Result<(), PatternError> {
    if ok && value.is_finite() {
        Ok(())
    } else {
        Err(PatternError::BadParameter {
            field,
            value,
            expected,
        })
    }
}

/// The least-squares rigid motion (Kabsch) taking the pattern points `(x, y, 0)` to their cloth points.
fn placement(pattern: &[Vec2], cloth: &[Vec3]) -> Placement {
    let n = pattern.len().min(cloth.len()).max(1) as Real;
    let flat = |p: &Vec2| Vec3::new(p.x, p.y, 0.0);
    let c2 = pattern.iter().map(flat).sum::<Vec3>() / n;
    let c3 = cloth.iter().sum::<Vec3>() / n;
    let mut h = Matrix3::zeros();
    for (p, x) in pattern.iter().zip(cloth) {
        h += (flat(p) - c2) * (x - c3).transpose();
    }
    let svd = h.svd(true, true);
    let rotation = match (svd.u, svd.v_t) {
        (Some(u), Some(v_t)) => {
            let v = v_t.transpose();
            let d = (v * u.transpose()).determinant().signum();
            let fix =
                Matrix3::from_diagonal(&Vec3::new(1.0, 1.0, if d < 0.0 { -1.0 } else { 1.0 }));
            v * fix * u.transpose()
        }
        _ => Matrix3::identity(),
    };
    let r = rotation;
    // R = R_z(γ) R_y(β) R_x(α): R₂₀ = −sin β, R₂₁ / R₂₂ = tan α, R₁₀ / R₀₀ = tan γ.
    let beta = (-r[(2, 0)]).clamp(-1.0, 1.0).asin();
    let alpha = r[(2, 1)].atan2(r[(2, 2)]);
    let gamma = r[(1, 0)].atan2(r[(0, 0)]);
    let rotation_xyz = [alpha, beta, gamma];
    if rotation_xyz.iter().all(|a| a.is_finite()) {
        Placement {
            rotation_xyz,
            translation: c3 - r * c2,
        }
    } else {
        Placement {
            rotation_xyz: [0.0; 3],
            translation: c3 - c2,
        }
    }
}

/// What lies across one edge of a panel's boundary loop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Label {
    Free,
    /// Seam index and side.
    Seam(usize, usize),
}

/// The cut-ready pattern of `garment` (see the module documentation), labelled with `labels`.
pub fn pattern(
    garment: &Garment,
    params: &PatternParams,
    labels: OrderLabels,
) -> Result<Pattern, PatternError> {
    let settings = Settings::checked(garment, params)?;
    let edge_labels = EdgeLabels::of(garment);
    let mut sides = SeamSides::new(garment.seams.len());
    let mut pieces = Vec::with_capacity(garment.panels.len());
    for p in 0..garment.panels.len() {
        let outline = Outline::of(garment, p, &edge_labels)?;
        pieces.push(outline.piece(&settings, &mut sides)?);
    }
    let seams = sides.sew(garment, &settings, &mut pieces)?;
    Ok(Pattern {
        labels,
        pieces,
        seams,
    })
}

/// [`PatternParams`] checked, with each garment seam's allowance and the unit up axis.
struct Settings<'a> {
    params: &'a PatternParams,
    /// Allowance of each garment seam (m).
    seam_allowance: Vec<Real>,
    /// The body's up axis, unit.
    up: Vec3,
}

impl<'a> Settings<'a> {
    /// The settings, or the first one out of its range.
    fn checked(garment: &Garment, params: &'a PatternParams) -> Result<Self, PatternError> {
        check(
            "seam_allowance",
            params.seam_allowance,
            params.seam_allowance >= 0.0,
            "a length ≥ 0 m",
        )?;
        check(
            "opening_allowance",
            params.opening_allowance,
            params.opening_allowance >= 0.0,
            "a length ≥ 0 m",
        )?;
        check(
            "notch_spacing",
            params.notch_spacing,
            params.notch_spacing > 0.0,
            "a length > 0 m",
        )?;
        check(
            "notch_depth",
            params.notch_depth,
            params.notch_depth >= 0.0,
            "a length ≥ 0 m",
        )?;
        check(
            "cut_quantity",
            params.cut_quantity as Real,
            params.cut_quantity >= 1,
            "at least 1",
        )?;
        let nseams = garment.seams.len();
        let mut seam_allowance = vec![params.seam_allowance; nseams];
        for (index, &(seam, a)) in params.seam_allowances.iter().enumerate() {
            if seam >= nseams {
                return Err(PatternError::NoSuchSeam {
                    field: "seam_allowances",
                    index,
                    seam: seam + 1,
                    seams: nseams,
                });
            }
            check("seam_allowances", a, a >= 0.0, "a length ≥ 0 m")?;
            seam_allowance[seam] = a;
        }
        let up = if params.up.norm() > 0.0 {
            params.up.normalize()
        } else {
            Vec3::y()
        };
        Ok(Self {
            params,
            seam_allowance,
            up,
        })
    }
}

/// What lies across every seam edge of the garment, by panel and unordered local vertex pair.
struct EdgeLabels(HashMap<(usize, usize, usize), Label>);

impl EdgeLabels {
    fn of(garment: &Garment) -> Self {
        let mut labels = HashMap::new();
        for (k, seam) in garment.seams.iter().enumerate() {
            for side in 0..2 {
                let v = &seam.vertices[side];
                let m = v.len();
                let edges = if seam.closed && m > 1 {
                    m
                } else {
                    m.saturating_sub(1)
                };
                for j in 0..edges {
                    let (a, b) = (v[j], v[(j + 1) % m]);
                    labels.insert(
                        (seam.panels[side], a.min(b), a.max(b)),
                        Label::Seam(k, side),
                    );
                }
            }
        }
        Self(labels)
    }

    /// What lies across the edge `ab` of panel `p`.
    fn across(&self, p: usize, a: usize, b: usize) -> Label {
        self.0
            .get(&(p, a.min(b), a.max(b)))
            .copied()
            .unwrap_or(Label::Free)
    }
}

/// A maximal stretch of equally labelled edges of a sewing line, from vertex `start` to vertex `end`
/// (`end` taken modulo the loop's length).
#[derive(Clone, Copy, Debug)]
struct LabelledRun {
    start: usize,
    end: usize,
    label: Label,
}

/// One panel's outer boundary as a sewing line, started where a run starts, and its runs.
struct Outline<'g> {
    garment: &'g Garment,
    /// The panel's index.
    p: usize,
    /// Its local pattern vertex at each sewing-line vertex.
    local: Vec<usize>,
    /// What lies across each sewing-line edge (from vertex `i` to `i + 1`).
    run_label: Vec<Label>,
    /// The sewing line (m).
    sewing: Vec<Vec2>,
    runs: Vec<LabelledRun>,
}

impl<'g> Outline<'g> {
    /// The outline of panel `p`, or [`PatternError::NotADisk`].
    fn of(garment: &'g Garment, p: usize, edge_labels: &EdgeLabels) -> Result<Self, PatternError> {
        let panel = &garment.panels[p];
        let [outer] = panel.boundary.as_slice() else {
            return Err(PatternError::NotADisk {
                piece: panel.name.clone(),
                loops: panel.boundary.len(),
            });
        };
        let lv = &outer.vertices;
        let n = lv.len();
        let labels_of: Vec<Label> = (0..n)
            .map(|i| edge_labels.across(p, lv[i], lv[(i + 1) % n]))
            .collect();
        // Start the sewing line where a run starts; a single run covering the loop starts where its seam
        // does.
        let shift = match (0..n).find(|&i| labels_of[(i + n - 1) % n] != labels_of[i]) {
            Some(i) => i,
            None => match labels_of[0] {
                Label::Seam(k, side) => {
                    let first = garment.seams[k].vertices[side][0];
                    lv.iter().position(|&v| v == first).unwrap_or(0)
                }
                Label::Free => 0,
            },
        };
        let local: Vec<usize> = (0..n).map(|i| lv[(i + shift) % n]).collect();
        let run_label: Vec<Label> = (0..n).map(|i| labels_of[(i + shift) % n]).collect();
        let sewing: Vec<Vec2> = local.iter().map(|&v| panel.pattern[v]).collect();
        let mut runs = Vec::new();
        let mut i = 0;
        while i < n {
            let mut j = i + 1;
            while j < n && run_label[j] == run_label[i] {
                j += 1;
            }
            runs.push(LabelledRun {
                start: i,
                end: j % n,
                label: run_label[i],
            });
            i = j;
        }
        Ok(Self {
            garment,
            p,
            local,
            run_label,
            sewing,
            runs,
        })
    }

    fn len(&self) -> usize {
        self.sewing.len()
    }

    fn run(&self, r: &LabelledRun) -> Run<'_> {
        Run {
            sewing: &self.sewing,
            start: r.start,
            end: r.end,
        }
    }

    /// Height (m) along `up` of the panel's local vertex `v` on the body.
    fn height(&self, v: usize, up: Vec3) -> Real {
        let panel = &self.garment.panels[self.p];
        self.garment.positions[panel.cloth_vertex[v]].dot(&up)
    }

    /// The role of each opening (free run), in the order of the runs: the highest is the top, the lowest
    /// the bottom, a single one top or bottom as its mean height lies above or below the piece's.
    fn opening_roles(&self, up: Vec3) -> Vec<OpeningRole> {
        let n = self.len();
        let mean_height = self.local.iter().map(|&v| self.height(v, up)).sum::<Real>() / n as Real;
        let heights: Vec<Real> = self
            .runs
            .iter()
            .filter(|r| r.label == Label::Free)
            .map(|r| {
                let segs = self.run(r).segments();
                (0..=segs)
                    .map(|k| self.height(self.local[(r.start + k) % n], up))
                    .sum::<Real>()
                    / (segs + 1) as Real
            })
            .collect();
        let top = (0..heights.len()).max_by(|&a, &b| heights[a].total_cmp(&heights[b]));
        let bottom = (0..heights.len()).min_by(|&a, &b| heights[a].total_cmp(&heights[b]));
        (0..heights.len())
            .map(|o| {
                if heights.len() == 1 {
                    if heights[0] >= mean_height {
                        OpeningRole::Top
                    } else {
                        OpeningRole::Bottom
                    }
                } else if Some(o) == top {
                    OpeningRole::Top
                } else if Some(o) == bottom {
                    OpeningRole::Bottom
                } else {
                    OpeningRole::Side
                }
            })
            .collect()
    }

    /// The piece's named edges, one per run, and each sewing-line edge's allowance (m); records on
    /// `sides` which edge each seam side is.
    fn edges(&self, settings: &Settings, sides: &mut SeamSides) -> (Vec<PieceEdge>, Vec<Real>) {
        let n = self.len();
        let roles = self.opening_roles(settings.up);
        let mut openings = roles.into_iter();
        let mut side_count = 0;
        let mut edges = Vec::with_capacity(self.runs.len());
        let mut allowance = vec![0.0; n];
        for (r, run) in self.runs.iter().enumerate() {
            let (name, kind, a) = match run.label {
                Label::Seam(k, side) => {
                    let partner = self.garment.seams[k].panels[1 - side];
                    sides.edge[k][side] = Some((self.p, r));
                    (
                        format!("seam {}", k + 1),
                        EdgeKind::Seam {
                            seam: k,
                            side,
                            partner,
                        },
                        settings.seam_allowance[k],
                    )
                }
                Label::Free => {
                    let role = openings.next().unwrap_or(OpeningRole::Side);
                    let name = match role {
                        OpeningRole::Top => "top opening".to_string(),
                        OpeningRole::Bottom => "bottom opening".to_string(),
                        OpeningRole::Side => {
                            side_count += 1;
                            format!("opening {side_count}")
                        }
                    };
                    (
                        name,
                        EdgeKind::Opening { role },
                        settings.params.opening_allowance,
                    )
                }
            };
            let segments = self.run(run);
            for k in 0..segments.segments() {
                allowance[(run.start + k) % n] = a;
            }
            edges.push(PieceEdge {
                name,
                kind,
                start: run.start,
                end: run.end,
                allowance: a,
                length: segments.length(),
            });
        }
        (edges, allowance)
    }

    /// The cut line for the sewing-line edges' `allowance` (m), checked to be simple, counter-clockwise
    /// and around the sewing line.
    fn cut(&self, allowance: &[Real], params: &PatternParams) -> Result<Vec<Vec2>, PatternError> {
        let n = self.len();
        let name = &self.garment.panels[self.p].name;
        // Every run's first vertex is a corner where runs meet (none on a single run).
        let mut corner = vec![false; n];
        if self.runs.len() > 1 {
            for run in &self.runs {
                corner[run.start] = true;
            }
        }
        let sewing = &self.sewing;
        let cut = cut_line(sewing, allowance, &corner, params.corner).map_err(|source| {
            let at = match &source {
                OffsetError::SelfIntersects { first, .. } => *first,
                _ => 0,
            };
            PatternError::CutLine {
                piece: name.clone(),
                allowance: allowance[at % n],
                opening: self.run_label[at % n] == Label::Free,
                source,
            }
        })?;
        let widest = allowance.iter().copied().fold(0.0, Real::max);
        let bad_cut = |first: usize, second: usize| PatternError::CutLine {
            piece: name.clone(),
            allowance: widest,
            opening: widest == params.opening_allowance
                && params.opening_allowance > params.seam_allowance,
            source: OffsetError::SelfIntersects { first, second },
        };
        // The sewing-line vertex nearest a cut-line point, to name where a crossing is.
        let nearest = |q: Vec2| {
            (0..n)
                .min_by(|&a, &b| (sewing[a] - q).norm().total_cmp(&(sewing[b] - q).norm()))
                .unwrap_or(0)
        };
        if let Some((i, j)) = first_self_crossing(&cut) {
            return Err(bad_cut(nearest(cut[i]), nearest(cut[j])));
        }
        if !(polygon_area(&cut) >= polygon_area(sewing) - 1e-12) {
            return Err(bad_cut(0, 0));
        }
        if let Some(v) = (0..n).find(|&i| {
            allowance[i] > 1e-9
                && allowance[(i + n - 1) % n] > 1e-9
                && !polygon_contains(&cut, sewing[i])
        }) {
            return Err(bad_cut(v, v));
        }
        Ok(cut)
    }

    /// The piece: its edges, cut line, grain line, label anchor and placement (notches come with the
    /// seams).
    fn piece(self, settings: &Settings, sides: &mut SeamSides) -> Result<Piece, PatternError> {
        let (edges, allowance) = self.edges(settings, sides);
        let cut = self.cut(&allowance, settings.params)?;
        let panel = &self.garment.panels[self.p];
        let cloth: Vec<Vec3> = panel
            .cloth_vertex
            .iter()
            .map(|&c| self.garment.positions[c])
            .collect();
        let direction = grain_direction(&panel.pattern, &cloth, &panel.faces, settings.up);
        let anchor = inner_point(&panel.pattern, &panel.faces, &self.sewing);
        let grain = grain_line(&self.sewing, anchor, direction);
        Ok(Piece {
            name: panel.name.clone(),
            sewing_line: self.sewing,
            edges,
            cut_line: cut,
            notches: Vec::new(),
            grain_line: grain,
            drill_holes: Vec::new(),
            cut_quantity: settings.params.cut_quantity,
            mirrored: false,
            face_side: FaceSide::FaceUp,
            label_anchor: anchor,
            placement: placement(&panel.pattern, &cloth),
        })
    }
}

/// Which (piece, edge) each side of each garment seam became.
struct SeamSides {
    edge: Vec<[Option<(usize, usize)>; 2]>,
}

impl SeamSides {
    fn new(nseams: usize) -> Self {
        Self {
            edge: vec![[None, None]; nseams],
        }
    }

    /// The pattern's seams, with their notches cut into `pieces`; a garment seam with no edge (a single
    /// shared vertex) has nothing to sew or mark and is left out, and the pieces' seam references are
    /// renumbered to the pattern's seams.
    fn sew(
        &self,
        garment: &Garment,
        settings: &Settings,
        pieces: &mut [Piece],
    ) -> Result<Vec<Seam>, PatternError> {
        let mut seams = Vec::with_capacity(garment.seams.len());
        // Index into `seams` of each garment seam.
        let mut seam_index: Vec<Option<usize>> = vec![None; garment.seams.len()];
        for (k, gs) in garment.seams.iter().enumerate() {
            let [Some((p0, e0)), Some((p1, e1))] = self.edge[k] else {
                continue;
            };
            let lengths = [pieces[p0].edges[e0].length, pieces[p1].edges[e1].length];
            let marks = marks(k, lengths, gs.closed, garment.seams.len(), settings.params)?;
            for (side, (p, e)) in [(p0, e0), (p1, e1)].into_iter().enumerate() {
                let mut new = notches(&pieces[p], e, side, k, &marks, settings.params);
                pieces[p].notches.append(&mut new);
            }
            seam_index[k] = Some(seams.len());
            seams.push(Seam {
                name: format!("seam {}", k + 1),
                pieces: [p0, p1],
                edges: [e0, e1],
                lengths,
                intended_ease: 0.0,
                closed: gs.closed,
            });
        }
        for piece in pieces.iter_mut() {
            for edge in &mut piece.edges {
                if let EdgeKind::Seam { seam, .. } = &mut edge.kind {
                    *seam = seam_index[*seam].unwrap_or(usize::MAX);
                }
            }
            for n in &mut piece.notches {
                n.seam = n.seam.and_then(|k| seam_index[k]);
            }
        }
        Ok(seams)
    }
}

/// The notch positions of garment seam `k` whose sides are `lengths` (m) long: arc lengths from the seam's
/// start (m), each with whether the user asked for it — the automatic ones every
/// [`PatternParams::notch_spacing`], then the user's on this seam, checked.
fn marks(
    k: usize,
    lengths: [Real; 2],
    closed: bool,
    nseams: usize,
    params: &PatternParams,
) -> Result<Vec<(Real, bool)>, PatternError> {
    let mut marks: Vec<(Real, bool)> = notch_arc_lengths(lengths[0], params.notch_spacing, closed)
        .into_iter()
        .map(|s| (s, false))
        .collect();
    for (index, un) in params.notches.iter().enumerate() {
        if un.seam >= nseams {
            return Err(PatternError::NoSuchSeam {
                field: "notches",
                index,
                seam: un.seam + 1,
                seams: nseams,
            });
        }
        if un.seam != k {
            continue;
        }
        let len = lengths[0].min(lengths[1]);
        if !(un.arc_length.is_finite() && un.arc_length >= 0.0 && un.arc_length <= len) {
            return Err(PatternError::NotchOffSeam {
                index,
                seam: k + 1,
                arc_length: un.arc_length,
                length: len,
            });
        }
        marks.push((un.arc_length, true));
    }
    Ok(marks)
}

/// The notches of garment seam `k` at `marks` on edge `e` of `piece`, its side `side` (side 1 runs
/// backwards from its run's end).
fn notches(
    piece: &Piece,
    e: usize,
    side: usize,
    k: usize,
    marks: &[(Real, bool)],
    params: &PatternParams,
) -> Vec<Notch> {
    let edge = &piece.edges[e];
    let run = Run {
        sewing: &piece.sewing_line,
        start: edge.start,
        end: edge.end,
    };
    marks
        .iter()
        .map(|&(s, user)| {
            let along = if side == 0 { s } else { edge.length - s };
            let (at, normal) = run.point_at(along);
            notch(
                at,
                normal,
                edge.allowance,
                params.notch_depth,
                &piece.cut_line,
                Some(k),
                s,
                user,
            )
        })
        .collect()
}
