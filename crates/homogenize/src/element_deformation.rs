//! The target deformation gradient of each tetrahedron from the yarn segments inside it (the knitwear
//! paper, Sec. 5, Eq. 5):
//!
//! ```text
//! Fₑʸ²ⱽ = exp( Σⱼ Lⱼ Ωⱼ / Σⱼ Lⱼ ) · ( Σⱼ Lⱼ Sⱼ / Σⱼ Lⱼ ),     Fⱼʸ = Rⱼ Sⱼ = exp(Ωⱼ) Sⱼ
//! ```
//!
//! over the segments `j` passing through element `e`, `Lⱼ` the length of segment `j` inside `e` at rest
//! (m, [`crate::segment_clipping`]), `Fⱼʸ` its deformation gradient ([`crate::segment_deformation`]) and
//! `Rⱼ Sⱼ` its polar decomposition ([`crate::polar_decomposition`]). The symmetric stretches are averaged
//! linearly; the rotations through their logarithms ([`crate::rotation_average`], refined to the Karcher
//! mean unless `iterations = 0`). Dimensionless.
//!
//! A voxel crossed by a thread is split into six tetrahedra, and the thread need not cross all six, so
//! some elements hold no segment. Such an element takes the average (same rule, equal weights) of its
//! already-assigned neighbours across its faces, ring by ring outward from the elements that hold
//! segments (then, for elements that touch those only along an edge or at a node, of its neighbours
//! sharing a node): the fill order and the neighbours depend only on the mesh and are computed once.
//! A connected part of the mesh with no segment at all has no target and is refused.

use std::collections::HashMap;

use nalgebra::Matrix3;

use crate::polar_decomposition::polar_decomposition;
use crate::rotation_average::rotation_average;
use crate::shape_fit_error::ShapeFitError;
use crate::volumetric_mesh::tet_split::sorted_faces;

/// Which segments make up each element's average, and in which order the empty elements are filled.
#[derive(Clone, Debug)]
pub struct ElementAverage {
    /// Per element, `(segment, length inside in m)`.
    contributions: Vec<Vec<(usize, f64)>>,
    /// Elements without segments, in fill order, each with the earlier-assigned neighbours it averages.
    fill: Vec<(usize, Vec<usize>)>,
}

impl ElementAverage {
    /// The averaging plan for `tets` (`#T × 4` node indices < `node_count`) with per element the segments
    /// inside it and their lengths (m), as [`crate::segment_clipping::segment_lengths_in_tets`] gives.
    pub fn new(
        tets: &[[usize; 4]],
        node_count: usize,
        contributions: Vec<Vec<(usize, f64)>>,
    ) -> Result<Self, ShapeFitError> {
        if contributions.len() != tets.len() {
            return Err(ShapeFitError::Count {
                what: "the segment lengths per element",
                got: contributions.len(),
                expected: tets.len(),
                per: "tetrahedron",
            });
        }
        let mut node_tets = vec![Vec::new(); node_count];
        let mut face_tets: HashMap<[usize; 3], Vec<usize>> = HashMap::new();
        for (e, t) in tets.iter().enumerate() {
            for &v in t {
                node_tets[v].push(e);
            }
            for f in sorted_faces(t) {
                face_tets.entry(f).or_default().push(e);
            }
        }
        let face_neighbours = |e: usize| -> Vec<usize> {
            let mut out = Vec::with_capacity(4);
            for f in sorted_faces(&tets[e]) {
                out.extend(face_tets[&f].iter().copied().filter(|&n| n != e));
            }
            out
        };
        let node_neighbours = |e: usize| -> Vec<usize> {
            tets[e]
                .iter()
                .flat_map(|&v| node_tets[v].iter().copied())
                .collect()
        };
        let mut assigned: Vec<bool> = contributions
            .iter()
            .map(|c| c.iter().map(|(_, l)| l).sum::<f64>() > 0.0)
            .collect();
        if !assigned.iter().any(|&a| a) {
            return Err(ShapeFitError::Mesh {
                problem: "holds no yarn segment; build it around the rest pose of the yarns".into(),
            });
        }
        let mut fill = Vec::new();
        // Rings across faces first (at most 4 sources an element); elements that touch the assigned ones
        // only along an edge or at a node follow by node-sharing rings.
        for neighbours in [
            &face_neighbours as &dyn Fn(usize) -> Vec<usize>,
            &node_neighbours,
        ] {
            loop {
                let mut ring = Vec::new();
                for e in 0..tets.len() {
                    if assigned[e] {
                        continue;
                    }
                    let mut sources: Vec<usize> =
                        neighbours(e).into_iter().filter(|&n| assigned[n]).collect();
                    sources.sort_unstable();
                    sources.dedup();
                    if !sources.is_empty() {
                        ring.push((e, sources));
                    }
                }
                if ring.is_empty() {
                    break;
                }
                for (e, _) in &ring {
                    assigned[*e] = true;
                }
                fill.extend(ring);
            }
        }
        if let Some(e) = assigned.iter().position(|&a| !a) {
            return Err(ShapeFitError::Mesh {
                problem: format!(
                    "has a connected part without yarn (tetrahedron {e}); every part must hold a yarn \
                     segment"
                ),
            });
        }
        Ok(Self {
            contributions,
            fill,
        })
    }

    /// The elements' target deformation gradients (Eq. 5), `#T`, from the segments' deformation
    /// gradients `segment_f` (`#S`, dimensionless), with `iterations` Karcher steps of the rotation mean.
    pub fn targets(&self, segment_f: &[Matrix3<f64>], iterations: usize) -> Vec<Matrix3<f64>> {
        let polars: Vec<(Matrix3<f64>, Matrix3<f64>)> = segment_f
            .iter()
            .map(|f| {
                let p = polar_decomposition(f);
                (p.rotation, p.stretch)
            })
            .collect();
        let mut rotation = vec![Matrix3::identity(); self.contributions.len()];
        let mut stretch = vec![Matrix3::identity(); self.contributions.len()];
        let mut weights = Vec::new();
        let mut rotations = Vec::new();
        let average = |weights: &[f64],
                       rotations: &[Matrix3<f64>],
                       stretches: &mut dyn Iterator<Item = Matrix3<f64>>| {
            let total: f64 = weights.iter().sum();
            let s: Matrix3<f64> = weights
                .iter()
                .zip(stretches)
                .map(|(w, s)| s * *w)
                .sum::<Matrix3<f64>>()
                / total;
            let r =
                rotation_average(weights, rotations, iterations).unwrap_or_else(Matrix3::identity);
            (r, s)
        };
        for (e, list) in self.contributions.iter().enumerate() {
            let list: Vec<&(usize, f64)> = list.iter().filter(|(_, l)| *l > 0.0).collect();
            if list.is_empty() {
                continue;
            }
            weights.clear();
            rotations.clear();
            weights.extend(list.iter().map(|(_, l)| *l));
            rotations.extend(list.iter().map(|(j, _)| polars[*j].0));
            let (r, s) = average(
                &weights,
                &rotations,
                &mut list.iter().map(|(j, _)| polars[*j].1),
            );
            rotation[e] = r;
            stretch[e] = s;
        }
        for (e, sources) in &self.fill {
            weights.clear();
            rotations.clear();
            weights.resize(sources.len(), 1.0);
            rotations.extend(sources.iter().map(|&n| rotation[n]));
            let stretches: Vec<Matrix3<f64>> = sources.iter().map(|&n| stretch[n]).collect();
            let (r, s) = average(&weights, &rotations, &mut stretches.into_iter());
            rotation[*e] = r;
            stretch[*e] = s;
        }
        rotation.iter().zip(&stretch).map(|(r, s)| r * s).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rotation_average::rotation_exp;
    use nalgebra::Vector3;

    #[test]
    fn the_average_of_eq_5_and_the_fill_of_empty_elements() {
        // Three elements in a chain (0–1 share nodes, 1–2 share nodes), a fourth apart from all.
        let tets = [[0, 1, 2, 3], [3, 4, 5, 6], [6, 7, 8, 9]];
        let r1 = rotation_exp(&Vector3::new(0.0, 0.0, 0.4));
        let r2 = rotation_exp(&Vector3::new(0.0, 0.0, 0.1));
        let s1 = Matrix3::from_diagonal(&Vector3::new(1.2, 1.0, 1.0));
        let s2 = Matrix3::from_diagonal(&Vector3::new(1.0, 0.8, 1.0));
        let plan =
            ElementAverage::new(&tets, 10, vec![vec![(0, 1.0), (1, 3.0)], vec![], vec![]]).unwrap();
        let f = plan.targets(&[r1 * s1, r2 * s2], 0);
        // Same axis: the rotation vectors average to 0.25·0.4 + 0.75·0.1 = 0.175 rad.
        let expected = rotation_exp(&Vector3::new(0.0, 0.0, 0.175)) * (s1 * 0.25 + s2 * 0.75);
        assert!((f[0] - expected).norm() < 1e-12);
        // Elements 1 and 2 are filled from 0 then 1: the same target.
        assert!((f[1] - expected).norm() < 1e-12);
        assert!((f[2] - expected).norm() < 1e-12);

        // A part without yarn is refused, naming it.
        let tets = [[0, 1, 2, 3], [4, 5, 6, 7]];
        let e = ElementAverage::new(&tets, 8, vec![vec![(0, 1.0)], vec![]]).unwrap_err();
        assert!(e.to_string().contains("tetrahedron 1"), "{e}");
        let e = ElementAverage::new(&tets, 8, vec![vec![], vec![]]).unwrap_err();
        assert!(e.to_string().contains("no yarn segment"), "{e}");
    }
}
