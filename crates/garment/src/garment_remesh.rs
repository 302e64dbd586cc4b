//! Remeshing of a garment whose patterns have changed: pattern design moves each panel's boundary and drags
//! the interior along ([`biharmonic coordinates`](https://doi.org/10.1145/2601097.2601209) in the design
//! crate), so its triangles degrade; [`garment_remesh`] resamples and triangulates the designed patterns
//! afresh at a target edge length and locates every new cloth vertex on the previous cloth, so that the
//! caller can carry the worn garment over (re-embedding).
//!
//! It is the garment pipeline's remeshing ([`remesh_panels`]) and sewing ([`sew`]) with the previous
//! garment in the role of the cut body:
//! - each panel's "cut surface" is its designed pattern (in the plane z = 0), so the boundary is resampled
//!   by pattern arc length, vertices are kept at pattern corners (turns sharper than
//!   [`RemeshParams::corner_angle`]) and wherever the border changes (seam ends), and the triangulation is
//!   refined to [`RemeshParams::min_angle`] at the target edge length;
//! - the "cut mesh" the samples refer to is the previous cloth: the cut vertex of a pattern vertex is its
//!   cloth vertex. A seam piece is resampled once, as parameters along the previous cloth's boundary edges
//!   that both panels share, so both sides get the very same samples and stay sewn one to one (the
//!   previous seams' pattern lengths differ a little; the samples are uniform along the first panel's side);
//! - a new cloth vertex's [`Garment::vertex_body`] is the previous cloth triangle it lies in and its
//!   barycentric coordinates there (found in the pattern plane), and its [`Garment::positions`] the same
//!   combination of the previous cloth positions given — the worn, deformed ones for a re-embedding.
//!
//! The patterns keep their shapes: boundary vertices lie on the previous boundary polylines (a chord may cut
//! a corner flatter than `corner_angle`) and no ease is applied.

use crate::garment::{Garment, GarmentError, PanelStats, sew};
use crate::math::{Vec2, Vec3};
use crate::pattern_remesh::{RemeshParams, remesh_panels};
use crate::plane_cut::{BoundaryLoop, CutMesh, FaceOrigin, MeshPoint, Panel, PanelSet};
use skintight_geometry::mesh::TriMesh;

/// Remeshes `garment` with the panel patterns `patterns` (`patterns[p]`: one 2D position per vertex of
/// panel `p`'s pattern, m, counter-clockwise triangles of positive area) at `params.target_edge_length`
/// (pattern length, m). `positions` (`#Vc`, m) are the previous cloth vertices' positions carried over to
/// the new vertices (see the module documentation).
///
/// Errors: a pattern or position list of the wrong size or not finite, a pattern boundary that crosses
/// itself (the triangulation cannot follow it), or the remeshing's own errors (refinement cap).
pub fn garment_remesh(
    garment: &Garment,
    positions: &[Vec3],
    patterns: &[Vec<Vec2>],
    params: &RemeshParams,
) -> Result<Garment, GarmentError> {
    let bad = |panel: &str, problem: String| {
        GarmentError::Remesh(crate::pattern_remesh::RemeshError::BadSamples {
            panel: panel.to_string(),
            problem,
        })
    };
    if positions.len() != garment.num_vertices() {
        return Err(bad(
            "",
            format!(
                "{} cloth positions given for {} cloth vertices",
                positions.len(),
                garment.num_vertices()
            ),
        ));
    }
    if let Some(v) = positions
        .iter()
        .position(|p| !p.iter().all(|c| c.is_finite()))
    {
        return Err(bad("", format!("cloth position {v} is not finite")));
    }
    if patterns.len() != garment.panels.len() {
        return Err(bad(
            "",
            format!(
                "{} patterns given for {} panels",
                patterns.len(),
                garment.panels.len()
            ),
        ));
    }
    let mut panels = Vec::with_capacity(garment.panels.len());
    for (gp, pattern) in garment.panels.iter().zip(patterns) {
        if pattern.len() != gp.pattern.len() {
            return Err(bad(
                &gp.name,
                format!(
                    "{} pattern positions given for {} vertices",
                    pattern.len(),
                    gp.pattern.len()
                ),
            ));
        }
        let nv = pattern.len();
        let mut vertex_origin = vec![None; nv];
        let face_origin: Vec<FaceOrigin> = gp
            .faces
            .iter()
            .zip(&gp.cloth_face)
            .map(|(tri, &cf)| {
                for (k, &v) in tri.iter().enumerate() {
                    let mut bary = [0.0; 3];
                    bary[k] = 1.0;
                    vertex_origin[v].get_or_insert(MeshPoint { face: cf, bary });
                }
                FaceOrigin {
                    face: cf,
                    corner_bary: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
                }
            })
            .collect();
        let vertex_origin = vertex_origin
            .into_iter()
            .enumerate()
            .map(|(v, o)| {
                o.ok_or_else(|| bad(&gp.name, format!("pattern vertex {v} is in no triangle")))
            })
            .collect::<Result<Vec<_>, _>>()?;
        panels.push(Panel {
            name: gp.name.clone(),
            mesh: TriMesh::new(
                pattern.iter().map(|p| Vec3::new(p.x, p.y, 0.0)).collect(),
                gp.faces.clone(),
            ),
            vertex_origin,
            face_origin,
            cut_vertex: gp.cloth_vertex.clone(),
            boundary: gp
                .boundary
                .iter()
                .map(|lp| BoundaryLoop {
                    vertices: lp.vertices.clone(),
                    borders: lp.borders.clone(),
                })
                .collect(),
        });
    }
    let set = PanelSet {
        cut: CutMesh {
            mesh: TriMesh::default(),
            face_origin: Vec::new(),
        },
        panels,
        seams: Vec::new(),
    };
    let mut meshes = remesh_panels(&set, patterns, params)?;
    // The new vertices' positions: their previous cloth triangle's positions, interpolated.
    for m in &mut meshes {
        for (p3, sp) in m.positions3.iter_mut().zip(&m.body) {
            let tri = garment.faces[sp.face];
            *p3 = (0..3).map(|k| positions[tri[k]] * sp.bary[k]).sum();
        }
    }
    let stats: Vec<PanelStats> = garment
        .panels
        .iter()
        .zip(&meshes)
        .map(|(gp, m)| PanelStats {
            min_angle: m.min_angle,
            ..gp.stats
        })
        .collect();
    sew(&set, &meshes, &stats, 0.0, params.max_added_vertices)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::garment::{GarmentParams, PanelShape, PanelSpec, garment};
    use crate::lscm::signed_area;
    use crate::math::Real;
    use crate::plane_cut::{Border, HalfSpace};
    use skintight_geometry::mesh::topology::Topology;
    use skintight_geometry::test_meshes::capped_cylinder;

    /// Two panels around a band of a tube: two open seams, free hems above and below.
    fn tube(edge_length: Real) -> Garment {
        let body = capped_cylinder(0.1, 0.4, 24, 8);
        let region = |name: &str, hs: Vec<HalfSpace>| PanelSpec {
            name: name.into(),
            shape: PanelShape::Region(hs),
        };
        // Front (y ≤ 0) and back (y ≥ 0) of the band 0.05 ≤ z ≤ 0.25: two open seams, free hems.
        let band = |side: Real| {
            vec![
                HalfSpace::new([0.0, side, 0.0], 0.0),
                HalfSpace::new([0.0, 0.0, -1.0], -0.05),
                HalfSpace::new([0.0, 0.0, 1.0], 0.25),
            ]
        };
        let specs = vec![region("front", band(1.0)), region("back", band(-1.0))];
        garment(
            &body,
            &specs,
            &GarmentParams {
                edge_length,
                ease: -0.1,
                ..Default::default()
            },
        )
        .unwrap()
    }

    fn min_angle(g: &Garment) -> Real {
        (0..g.num_faces())
            .map(|f| {
                let t = g.rest_triangle(f);
                (0..3)
                    .map(|k| {
                        let (a, b) = (t[(k + 1) % 3] - t[k], t[(k + 2) % 3] - t[k]);
                        a.angle(&b)
                    })
                    .fold(Real::INFINITY, Real::min)
            })
            .fold(Real::INFINITY, Real::min)
    }

    /// Checks of every remeshed garment: sewn one to one, positive rest areas, a manifold cloth, boundary
    /// vertices on the previous pattern outline, and positions interpolated from the previous cloth.
    fn check(old: &Garment, positions: &[Vec3], patterns: &[Vec<Vec2>], new: &Garment) {
        Topology::new(new.num_vertices(), &new.faces).unwrap();
        for (p, gp) in new.panels.iter().enumerate() {
            for (lf, &cf) in gp.cloth_face.iter().enumerate() {
                assert_eq!(new.faces[cf], gp.faces[lf].map(|v| gp.cloth_vertex[v]));
                let [a, b, c] = new.rest_triangle(cf);
                assert!(signed_area(a, b, c) > 0.0, "panel {p} face {lf}");
            }
        }
        assert_eq!(new.seams.len(), old.seams.len());
        for s in &new.seams {
            let [pa, pb] = s.panels;
            assert_eq!(s.vertices[0].len(), s.vertices[1].len());
            for (&va, &vb) in s.vertices[0].iter().zip(&s.vertices[1]) {
                assert_eq!(
                    new.panels[pa].cloth_vertex[va],
                    new.panels[pb].cloth_vertex[vb]
                );
            }
        }
        // Each new vertex sits where its previous triangle puts it, in 3D and in the pattern.
        for (p, gp) in new.panels.iter().enumerate() {
            let old_p = &old.panels[p];
            for (v, &c) in gp.cloth_vertex.iter().enumerate() {
                let sp = new.vertex_body[c];
                assert!((sp.bary.iter().sum::<Real>() - 1.0).abs() < 1e-12);
                let tri = old.faces[sp.face];
                let x: Vec3 = (0..3).map(|k| positions[tri[k]] * sp.bary[k]).sum();
                assert!((x - new.positions[c]).norm() < 1e-12);
                // A vertex of panel p: in a triangle of panel p (a seam vertex: of either panel).
                let f_panel = old.face_panel[sp.face];
                if f_panel == p {
                    let lt = old_p.faces[old.face_pattern[sp.face]];
                    let y: Vec2 = (0..3).map(|k| patterns[p][lt[k]] * sp.bary[k]).sum();
                    assert!(
                        (y - gp.pattern[v]).norm() < 1e-9,
                        "panel {p} vertex {v}: pattern point off its previous triangle by {:.2e} m",
                        (y - gp.pattern[v]).norm()
                    );
                }
            }
        }
        // Free boundary flags follow the borders.
        let free_edges = new
            .panels
            .iter()
            .flat_map(|gp| gp.boundary.iter().flat_map(|lp| lp.borders.iter()))
            .filter(|b| **b == Border::Free)
            .count();
        assert_eq!(free_edges > 0, new.free_boundary.iter().any(|&f| f));
    }

    #[test]
    fn unchanged_patterns_remesh_to_an_equivalent_garment() {
        let g = tube(0.03);
        let patterns: Vec<Vec<Vec2>> = g.panels.iter().map(|p| p.pattern.clone()).collect();
        let target = 0.03 * 0.9;
        let new = garment_remesh(
            &g,
            &g.positions,
            &patterns,
            &RemeshParams {
                target_edge_length: target,
                ..Default::default()
            },
        )
        .unwrap();
        check(&g, &g.positions, &patterns, &new);
        // Same pattern areas (the outline is kept: every sample lies on the previous polyline, whose
        // vertices at corners are kept), about as many triangles.
        for (a, b) in g.panels.iter().zip(&new.panels) {
            let rel = (a.stats.pattern_area - b.stats.pattern_area).abs() / a.stats.pattern_area;
            assert!(
                rel < 0.01,
                "{}: area changed by {:.3} %",
                a.name,
                rel * 100.0
            );
        }
        let ratio = new.num_faces() as Real / g.num_faces() as Real;
        assert!(
            (0.6..1.6).contains(&ratio),
            "{} → {} faces",
            g.num_faces(),
            new.num_faces()
        );
        assert!(
            min_angle(&new) > 20f64.to_radians(),
            "{}",
            min_angle(&new).to_degrees()
        );
    }

    /// The design use: the patterns are sheared and stretched (their triangles degrade) and the cloth is
    /// deformed; the remesh restores the angle bound on the new outlines, carries the positions, and the
    /// seams still match one to one.
    #[test]
    fn distorted_patterns_get_well_shaped_triangles_back() {
        let g = tube(0.03);
        // A smooth, non-affine distortion per panel: stretch along x growing with y, plus a shear.
        let patterns: Vec<Vec<Vec2>> = g
            .panels
            .iter()
            .map(|p| {
                p.pattern
                    .iter()
                    .map(|q| {
                        let s = 1.0 + 4.0 * q.y.abs();
                        Vec2::new(s * q.x + 0.8 * q.y, q.y + 0.5 * q.x * q.x)
                    })
                    .collect()
            })
            .collect();
        let positions: Vec<Vec3> = g
            .positions
            .iter()
            .map(|x| Vec3::new(1.1 * x.x, x.y + 0.02 * x.x, 1.1 * x.z))
            .collect();
        let distorted = Garment {
            panels: g
                .panels
                .iter()
                .zip(&patterns)
                .map(|(p, q)| crate::garment::GarmentPanel {
                    pattern: q.clone(),
                    ..p.clone()
                })
                .collect(),
            ..g.clone()
        };
        let before = min_angle(&distorted);
        let new = garment_remesh(
            &g,
            &positions,
            &patterns,
            &RemeshParams {
                target_edge_length: 0.027,
                ..Default::default()
            },
        )
        .unwrap();
        check(&g, &positions, &patterns, &new);
        let after = min_angle(&new);
        println!(
            "min angle {:.1}° → {:.1}°, {} → {} faces",
            before.to_degrees(),
            after.to_degrees(),
            g.num_faces(),
            new.num_faces()
        );
        assert!(
            before < 15f64.to_radians(),
            "the test distortion is too mild"
        );
        assert!(after > 20f64.to_radians());
        for (a, b) in distorted.panels.iter().zip(&new.panels) {
            let area_a: Real = a
                .faces
                .iter()
                .map(|t| signed_area(a.pattern[t[0]], a.pattern[t[1]], a.pattern[t[2]]))
                .sum();
            let rel = (area_a - b.stats.pattern_area).abs() / area_a;
            assert!(
                rel < 0.01,
                "{}: area changed by {:.3} %",
                a.name,
                rel * 100.0
            );
        }
    }

    #[test]
    fn wrong_sizes_are_errors_not_panics() {
        let g = tube(0.04);
        let patterns: Vec<Vec<Vec2>> = g.panels.iter().map(|p| p.pattern.clone()).collect();
        let params = RemeshParams {
            target_edge_length: 0.036,
            ..Default::default()
        };
        assert!(garment_remesh(&g, &g.positions[1..], &patterns, &params).is_err());
        assert!(garment_remesh(&g, &g.positions, &patterns[1..], &params).is_err());
        let mut short = patterns.clone();
        short[0].pop();
        assert!(garment_remesh(&g, &g.positions, &short, &params).is_err());
        let mut nan = g.positions.clone();
        nan[3].x = Real::NAN;
        assert!(garment_remesh(&g, &nan, &patterns, &params).is_err());
        // A boundary folded over itself: mirror one panel's pattern (clockwise triangles).
        let mut folded = patterns.clone();
        let n = folded[0].len();
        for q in &mut folded[0][..n / 2] {
            q.x = -q.x;
        }
        let _ = garment_remesh(&g, &g.positions, &folded, &params); // must not panic
    }
}
