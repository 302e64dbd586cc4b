//! From a sewn [`Garment`] to its cut-ready [`Pattern`]: each panel's outer boundary loop becomes a piece's
//! sewing line, split into named runs (seam sides and openings), offset into the cut line, marked with
//! notches, a grain line and labels.
//!
//! Openings (free runs) are named by height on the body: a piece's highest opening is its `top opening`
//! (a waist, a stocking's top band), its lowest the `bottom opening` (a hem, an ankle or wrist cuff); with
//! a single opening, it is the top or the bottom one as it lies above or below the piece's mean height.
//! Seams are numbered from 1 in the garment's seam order (`seam 3` is `Garment::seams[2]`), the same on
//! both pieces.

use std::collections::HashMap;

use crate::garment::Garment;
use crate::math::{Mat3 as Matrix3, Real, Vec2, Vec3};
use crate::pattern::grain_line::{grain_direction, grain_line, inner_point};
use crate::pattern::notches::{Run, notch, notch_arc_lengths};
use crate::pattern::seam_allowance::{
    CornerStyle, OffsetError, cut_line, first_self_crossing, polygon_area, polygon_contains,
};
use crate::pattern::{
    EdgeKind, FaceSide, OpeningRole, OrderLabels, Pattern, Piece, PieceEdge, Placement, Seam,
};

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

    // Every seam edge, by panel and unordered local vertex pair.
    let mut edge_label: HashMap<(usize, usize, usize), Label> = HashMap::new();
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
                edge_label.insert(
                    (seam.panels[side], a.min(b), a.max(b)),
                    Label::Seam(k, side),
                );
            }
        }
    }

    let mut pieces = Vec::with_capacity(garment.panels.len());
    // (piece, edge) of each seam side.
    let mut seam_edges: Vec<[Option<(usize, usize)>; 2]> = vec![[None, None]; nseams];
    for (p, panel) in garment.panels.iter().enumerate() {
        let [outer] = panel.boundary.as_slice() else {
            return Err(PatternError::NotADisk {
                piece: panel.name.clone(),
                loops: panel.boundary.len(),
            });
        };
        let lv = &outer.vertices;
        let n = lv.len();
        let label = |i: usize| {
            let (a, b) = (lv[i], lv[(i + 1) % n]);
            edge_label
                .get(&(p, a.min(b), a.max(b)))
                .copied()
                .unwrap_or(Label::Free)
        };
        let labels_of: Vec<Label> = (0..n).map(label).collect();
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
        let height = |v: usize| garment.positions[panel.cloth_vertex[v]].dot(&up);

        // Runs: maximal stretches of equal labels.
        let mut runs: Vec<(usize, usize, Label)> = Vec::new();
        let mut i = 0;
        while i < n {
            let mut j = i + 1;
            while j < n && run_label[j] == run_label[i] {
                j += 1;
            }
            runs.push((i, j % n, run_label[i]));
            i = j;
        }
        // Opening roles by mean height.
        let mean_height = local.iter().map(|&v| height(v)).sum::<Real>() / n as Real;
        let run_height = |&(s, e, _): &(usize, usize, Label)| {
            let r = Run {
                sewing: &sewing,
                start: s,
                end: e,
            };
            let segs = r.segments();
            (0..=segs).map(|k| height(local[(s + k) % n])).sum::<Real>() / (segs + 1) as Real
        };
        let openings: Vec<usize> = (0..runs.len())
            .filter(|&r| runs[r].2 == Label::Free)
            .collect();
        let heights: Vec<Real> = openings.iter().map(|&r| run_height(&runs[r])).collect();
        let top = (0..openings.len()).max_by(|&a, &b| heights[a].total_cmp(&heights[b]));
        let bottom = (0..openings.len()).min_by(|&a, &b| heights[a].total_cmp(&heights[b]));
        let mut side_count = 0;
        let mut edges = Vec::with_capacity(runs.len());
        let mut allowance = vec![0.0; n];
        let mut corner = vec![false; n];
        for (r, &(s, e, lab)) in runs.iter().enumerate() {
            let run = Run {
                sewing: &sewing,
                start: s,
                end: e,
            };
            let (name, kind, a) = match lab {
                Label::Seam(k, side) => {
                    let partner = garment.seams[k].panels[1 - side];
                    seam_edges[k][side] = Some((p, r));
                    (
                        format!("seam {}", k + 1),
                        EdgeKind::Seam {
                            seam: k,
                            side,
                            partner,
                        },
                        seam_allowance[k],
                    )
                }
                Label::Free => {
                    let o = openings.iter().position(|&x| x == r).unwrap_or(0);
                    let role = if openings.len() == 1 {
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
                    };
                    let name = match role {
                        OpeningRole::Top => "top opening".to_string(),
                        OpeningRole::Bottom => "bottom opening".to_string(),
                        OpeningRole::Side => {
                            side_count += 1;
                            format!("opening {side_count}")
                        }
                    };
                    (name, EdgeKind::Opening { role }, params.opening_allowance)
                }
            };
            for k in 0..run.segments() {
                allowance[(s + k) % n] = a;
            }
            if runs.len() > 1 {
                corner[s] = true;
            }
            edges.push(PieceEdge {
                name,
                kind,
                start: s,
                end: e,
                allowance: a,
                length: run.length(),
            });
        }

        let cut = cut_line(&sewing, &allowance, &corner, params.corner).map_err(|source| {
            let at = match &source {
                OffsetError::SelfIntersects { first, .. } => *first,
                _ => 0,
            };
            let opening = run_label[at % n] == Label::Free;
            PatternError::CutLine {
                piece: panel.name.clone(),
                allowance: allowance[at % n],
                opening,
                source,
            }
        })?;
        // The cut line must be simple, counter-clockwise, and enclose the sewing line.
        let bad_cut = |first: usize, second: usize| PatternError::CutLine {
            piece: panel.name.clone(),
            allowance: allowance.iter().copied().fold(0.0, Real::max),
            opening: allowance.iter().copied().fold(0.0, Real::max) == params.opening_allowance
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
        if !(polygon_area(&cut) >= polygon_area(&sewing) - 1e-12) {
            return Err(bad_cut(0, 0));
        }
        if let Some(v) = (0..n).find(|&i| {
            allowance[i] > 1e-9
                && allowance[(i + n - 1) % n] > 1e-9
                && !polygon_contains(&cut, sewing[i])
        }) {
            return Err(bad_cut(v, v));
        }

        // Grain line and label anchor.
        let cloth: Vec<Vec3> = panel
            .cloth_vertex
            .iter()
            .map(|&c| garment.positions[c])
            .collect();
        let direction = grain_direction(&panel.pattern, &cloth, &panel.faces, up);
        let anchor = inner_point(&panel.pattern, &panel.faces, &sewing);
        let grain = grain_line(&sewing, anchor, direction);
        pieces.push(Piece {
            name: panel.name.clone(),
            sewing_line: sewing,
            edges,
            cut_line: cut,
            notches: Vec::new(),
            grain_line: grain,
            drill_holes: Vec::new(),
            cut_quantity: params.cut_quantity,
            mirrored: false,
            face_side: FaceSide::FaceUp,
            label_anchor: anchor,
            placement: placement(&panel.pattern, &cloth),
        });
    }

    // Seams and their notches.
    let mut seams = Vec::with_capacity(nseams);
    // Index into `seams` of each garment seam (a seam without an edge has none).
    let mut seam_index: Vec<Option<usize>> = vec![None; nseams];
    for (k, gs) in garment.seams.iter().enumerate() {
        let [Some((p0, e0)), Some((p1, e1))] = seam_edges[k] else {
            // A seam with no edge (a single shared vertex) has nothing to sew or mark.
            continue;
        };
        let lengths = [pieces[p0].edges[e0].length, pieces[p1].edges[e1].length];
        let mut marks: Vec<(Real, bool)> =
            notch_arc_lengths(lengths[0], params.notch_spacing, gs.closed)
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
        for (side, (p, e)) in [(p0, e0), (p1, e1)].into_iter().enumerate() {
            let piece = &pieces[p];
            let edge = &piece.edges[e];
            let run = Run {
                sewing: &piece.sewing_line,
                start: edge.start,
                end: edge.end,
            };
            let mut new: Vec<_> = marks
                .iter()
                .map(|&(s, user)| {
                    // Side 1 runs backwards from its run's end.
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
                .collect();
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
    // Seam references by pattern seam index.
    for piece in &mut pieces {
        for edge in &mut piece.edges {
            if let EdgeKind::Seam { seam, .. } = &mut edge.kind {
                *seam = seam_index[*seam].unwrap_or(usize::MAX);
            }
        }
        for n in &mut piece.notches {
            n.seam = n.seam.and_then(|k| seam_index[k]);
        }
    }
    Ok(Pattern {
        labels,
        pieces,
        seams,
    })
}
