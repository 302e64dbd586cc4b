//! The volumetric knit's elastic energy over a whole mesh: `E(x) = Σ_e E_e(x)` (the knitwear paper
//! Eq. 7 summed over the `#T` tetrahedra of a [`VolumetricMesh`], J), with per-element material
//! parameters `γ` (`#T × 2`: `[γˢ_e, γᵛ_e]`, Pa). Positions `x` are `3#V` (node `v`, axis `c` at
//! `3v + c`, m). The gradient is the sum of the element gradients (N); the Hessian comes as the lower
//! triangle's triplets (N/m; repeats add up), as the Newton toolkit and the adjoint take it; and
//! `∂g/∂γ` — `E` is linear in `γ`, so this is `∂²E/∂x∂γ`, what Eq. 15–21's adjoint needs — as a sparse
//! `3#V × 2#T` matrix (column `2e` for `γˢ_e`, `2e + 1` for `γᵛ_e`; m² = N/Pa).

use faer::sparse::{SparseColMat, Triplet};

use super::density::MaterialHessian;
use super::element::{RestTet, RestTetError, knit_element};
use crate::closest_volume_preserving::{VolumePreservingError, VolumePreservingParams};
use crate::volumetric_mesh::VolumetricMesh;

/// Why the material cannot be built or evaluated.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum KnitMaterialError {
    /// A rest tetrahedron is flat or inverted.
    #[error("tets[{tet}]: {source}")]
    RestTet {
        /// Its index.
        tet: usize,
        /// What is wrong with it.
        source: RestTetError,
    },
    /// A tetrahedron names a node the mesh does not have.
    #[error("tets[{tet}] names node {node}, but the mesh has {nodes} nodes; fix the mesh")]
    NodeIndex {
        /// The tetrahedron.
        tet: usize,
        /// The node index.
        node: usize,
        /// `#V`.
        nodes: usize,
    },
    /// `gamma` has the wrong length.
    #[error(
        "gamma has {got} rows but the mesh has {expected} tetrahedra; give one [γˢ, γᵛ] per tetrahedron"
    )]
    GammaCount {
        /// Rows given.
        got: usize,
        /// `#T`.
        expected: usize,
    },
    /// A material parameter is negative or not finite.
    #[error("gamma[{tet}].{which} = {value} Pa; material parameters must be finite and ≥ 0")]
    Gamma {
        /// The tetrahedron.
        tet: usize,
        /// `gamma_s` or `gamma_v`.
        which: &'static str,
        /// The value.
        value: f64,
    },
    /// The positions have the wrong length.
    #[error("positions have {got} entries, expected 3 × #V = {expected}")]
    Positions {
        /// Entries given.
        got: usize,
        /// `3#V`.
        expected: usize,
    },
    /// A position is not finite.
    #[error("positions[{index}] = {value}: positions must be finite (m)")]
    NonFinitePosition {
        /// Its index in `x`.
        index: usize,
        /// The value.
        value: f64,
    },
    /// The projection's settings are invalid.
    #[error(transparent)]
    Params(#[from] VolumePreservingError),
}

/// The mesh's energy and derivatives at one state.
#[derive(Clone, Debug)]
pub struct MaterialEvaluation {
    /// `E` (J).
    pub energy: f64,
    /// `∂E/∂x`, `3#V` (N).
    pub gradient: Vec<f64>,
    /// The lower triangle (row ≥ column) of `∂²E/∂x²` as triplets whose repeats add up (N/m); empty
    /// for [`MaterialHessian::Skip`].
    pub hessian: Vec<Triplet<usize, usize, f64>>,
}

/// The volumetric knit's material on one mesh: the rest tetrahedra and `γ`.
#[derive(Clone, Debug)]
pub struct KnitMaterial {
    rest: Vec<RestTet>,
    tets: Vec<[usize; 4]>,
    nodes: usize,
    gamma: Vec<[f64; 2]>,
    params: VolumePreservingParams,
}

fn check_gamma(gamma: &[[f64; 2]], tets: usize) -> Result<(), KnitMaterialError> {
    if gamma.len() != tets {
        return Err(KnitMaterialError::GammaCount {
            got: gamma.len(),
            expected: tets,
        });
    }
    for (tet, g) in gamma.iter().enumerate() {
        for (which, value) in [("gamma_s", g[0]), ("gamma_v", g[1])] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(KnitMaterialError::Gamma { tet, which, value });
            }
        }
    }
    Ok(())
}

impl KnitMaterial {
    /// The material of `mesh` with `gamma` (`#T × 2`, Pa, finite and ≥ 0).
    pub fn new(
        mesh: &VolumetricMesh,
        gamma: Vec<[f64; 2]>,
        params: VolumePreservingParams,
    ) -> Result<Self, KnitMaterialError> {
        params.validate()?;
        let nodes = mesh.rest.len();
        let mut rest = Vec::with_capacity(mesh.tets.len());
        for (tet, t) in mesh.tets.iter().enumerate() {
            if let Some(&node) = t.iter().find(|&&v| v >= nodes) {
                return Err(KnitMaterialError::NodeIndex { tet, node, nodes });
            }
            let r = RestTet::new(&t.map(|v| mesh.rest[v]))
                .map_err(|source| KnitMaterialError::RestTet { tet, source })?;
            rest.push(r);
        }
        check_gamma(&gamma, mesh.tets.len())?;
        Ok(Self {
            rest,
            tets: mesh.tets.clone(),
            nodes,
            gamma,
            params,
        })
    }

    /// Replaces `γ` (`#T × 2`, Pa, finite and ≥ 0).
    pub fn set_gamma(&mut self, gamma: Vec<[f64; 2]>) -> Result<(), KnitMaterialError> {
        check_gamma(&gamma, self.tets.len())?;
        self.gamma = gamma;
        Ok(())
    }

    /// `γ`, `#T × 2` (Pa).
    pub fn gamma(&self) -> &[[f64; 2]] {
        &self.gamma
    }

    /// The rest tetrahedra, `#T`.
    pub fn rest_tets(&self) -> &[RestTet] {
        &self.rest
    }

    /// The tetrahedra's nodes, `#T × 4`.
    pub fn tets(&self) -> &[[usize; 4]] {
        &self.tets
    }

    /// `3#V`, the number of position unknowns.
    pub fn dof_count(&self) -> usize {
        3 * self.nodes
    }

    fn check_positions(&self, x: &[f64]) -> Result<(), KnitMaterialError> {
        if x.len() != 3 * self.nodes {
            return Err(KnitMaterialError::Positions {
                got: x.len(),
                expected: 3 * self.nodes,
            });
        }
        if let Some((index, &value)) = x.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(KnitMaterialError::NonFinitePosition { index, value });
        }
        Ok(())
    }

    fn corners(&self, x: &[f64], e: usize) -> [[f64; 3]; 4] {
        self.tets[e].map(|v| [x[3 * v], x[3 * v + 1], x[3 * v + 2]])
    }

    /// `E`, `∂E/∂x` and (unless [`MaterialHessian::Skip`]) the lower triangle of `∂²E/∂x²` at `x`.
    pub fn evaluate(
        &self,
        x: &[f64],
        hessian: MaterialHessian,
    ) -> Result<MaterialEvaluation, KnitMaterialError> {
        self.check_positions(x)?;
        let mut energy = 0.0;
        let mut gradient = vec![0.0; x.len()];
        let mut triplets = Vec::new();
        if hessian != MaterialHessian::Skip {
            triplets.reserve(78 * self.tets.len());
        }
        for (e, tet) in self.tets.iter().enumerate() {
            let ev = knit_element(
                &self.rest[e],
                &self.corners(x, e),
                self.gamma[e],
                hessian,
                &self.params,
            )?;
            energy += ev.energy;
            let dof = |a: usize| 3 * tet[a / 3] + a % 3;
            for a in 0..12 {
                gradient[dof(a)] += ev.gradient[a];
            }
            if let Some(h) = ev.hessian {
                for a in 0..12 {
                    for b in 0..12 {
                        let (r, c) = (dof(a), dof(b));
                        if r >= c {
                            triplets.push(Triplet::new(r, c, h[(a, b)]));
                        }
                    }
                }
            }
        }
        Ok(MaterialEvaluation {
            energy,
            gradient,
            hessian: triplets,
        })
    }

    /// `E(x)` alone (J).
    pub fn energy(&self, x: &[f64]) -> Result<f64, KnitMaterialError> {
        Ok(self.evaluate(x, MaterialHessian::Skip)?.energy)
    }

    /// `∂E/∂γ` at `x`, `2#T` (`[∂E/∂γˢ_e, ∂E/∂γᵛ_e]` per element; m³ = J/Pa).
    pub fn energy_per_gamma(&self, x: &[f64]) -> Result<Vec<f64>, KnitMaterialError> {
        self.check_positions(x)?;
        let mut out = Vec::with_capacity(2 * self.tets.len());
        for e in 0..self.tets.len() {
            let ev = knit_element(
                &self.rest[e],
                &self.corners(x, e),
                self.gamma[e],
                MaterialHessian::Skip,
                &self.params,
            )?;
            out.extend(ev.energy_per_gamma);
        }
        Ok(out)
    }

    /// `∂g/∂γ = ∂²E/∂x∂γ` at `x`: sparse `3#V × 2#T` (m² = N/Pa; see the module doc).
    pub fn gradient_per_gamma(
        &self,
        x: &[f64],
    ) -> Result<SparseColMat<usize, f64>, KnitMaterialError> {
        self.check_positions(x)?;
        let mut triplets = Vec::with_capacity(24 * self.tets.len());
        for (e, tet) in self.tets.iter().enumerate() {
            let ev = knit_element(
                &self.rest[e],
                &self.corners(x, e),
                self.gamma[e],
                MaterialHessian::Skip,
                &self.params,
            )?;
            for (k, column) in ev.gradient_per_gamma.iter().enumerate() {
                for a in 0..12 {
                    triplets.push(Triplet::new(3 * tet[a / 3] + a % 3, 2 * e + k, column[a]));
                }
            }
        }
        Ok(
            SparseColMat::try_new_from_triplets(x.len(), 2 * self.tets.len(), &triplets)
                .expect("indices within the matrix's shape"),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::knit_material::test_states::{block_mesh, rng};
    use rand::Rng;
    use skintight_geometry::finite_difference::{FdParams, check_gradient, check_jacobian};

    /// A 2 × 1 × 1 block (12 tets, 12 nodes) of 1 m cubes with random γ, randomly deformed (some
    /// elements compressed, some stretched).
    fn random_state(seed: u64) -> (KnitMaterial, Vec<f64>) {
        let mut rng = rng(seed);
        let mesh = block_mesh(2, 1, 1, 1.0);
        let gamma: Vec<[f64; 2]> = (0..mesh.tets.len())
            .map(|_| {
                [
                    rng.random_range(100.0..2000.0),
                    rng.random_range(100.0..5000.0),
                ]
            })
            .collect();
        let material = KnitMaterial::new(&mesh, gamma, VolumePreservingParams::default()).unwrap();
        let x: Vec<f64> = mesh
            .rest
            .iter()
            .flat_map(|p| p.map(|v| 1.1 * v + rng.random_range(-0.2..0.2)))
            .collect();
        (material, x)
    }

    fn dense_symmetric(n: usize, triplets: &[Triplet<usize, usize, f64>]) -> Vec<f64> {
        let mut h = vec![0.0; n * n];
        for t in triplets {
            assert!(t.row >= t.col, "lower triangle only");
            h[t.row * n + t.col] += t.val;
            if t.row != t.col {
                h[t.col * n + t.row] += t.val;
            }
        }
        h
    }

    fn fd() -> FdParams {
        FdParams {
            step: 1e-6,
            rel_tol: 2e-6,
            abs_tol: 1e-9,
        }
    }

    #[test]
    fn assembled_gradient_and_hessian_match_central_differences() {
        for seed in 0..4 {
            let (material, x) = random_state(seed);
            let n = x.len();
            let ev = material.evaluate(&x, MaterialHessian::Exact).unwrap();
            let energy = |y: &[f64]| material.energy(y).unwrap();
            let gradient = |y: &[f64]| {
                material
                    .evaluate(y, MaterialHessian::Skip)
                    .unwrap()
                    .gradient
            };
            check_gradient(energy, &x, &ev.gradient, &fd()).unwrap();
            let h = dense_symmetric(n, &ev.hessian);
            check_jacobian(gradient, &x, &h, &fd()).unwrap();
            let mut wrong = h.clone();
            wrong[5 * n + 5] *= 1.0 + 1e-3;
            assert!(check_jacobian(gradient, &x, &wrong, &fd()).is_err());
        }
    }

    #[test]
    fn gamma_derivatives_match_differences_in_gamma() {
        let (material, x) = random_state(7);
        let t = material.tets().len();
        let flat: Vec<f64> = material.gamma().iter().flatten().copied().collect();
        let with = |g: &[f64]| {
            let mut m = material.clone();
            m.set_gamma(g.chunks(2).map(|c| [c[0], c[1]]).collect())
                .unwrap();
            m
        };
        check_gradient(
            |g| with(g).energy(&x).unwrap(),
            &flat,
            &material.energy_per_gamma(&x).unwrap(),
            &fd(),
        )
        .unwrap();
        let k = material.gradient_per_gamma(&x).unwrap();
        assert_eq!((k.nrows(), k.ncols()), (x.len(), 2 * t));
        let dense = k.to_dense();
        let jac: Vec<f64> = (0..x.len())
            .flat_map(|r| (0..2 * t).map(move |c| (r, c)))
            .map(|(r, c)| dense[(r, c)])
            .collect();
        let g = |gm: &[f64]| {
            with(gm)
                .evaluate(&x, MaterialHessian::Skip)
                .unwrap()
                .gradient
        };
        check_jacobian(g, &flat, &jac, &fd()).unwrap();
        let mut wrong = jac.clone();
        let i = (0..wrong.len())
            .max_by(|&a, &b| wrong[a].abs().total_cmp(&wrong[b].abs()))
            .unwrap();
        wrong[i] *= 1.0 + 1e-4;
        assert!(check_jacobian(g, &flat, &wrong, &fd()).is_err());
    }

    #[test]
    fn bad_input_is_an_error_that_names_it() {
        let mesh = block_mesh(1, 1, 1, 0.01);
        let p = VolumePreservingParams::default();
        let e = KnitMaterial::new(&mesh, vec![[1.0, 1.0]; 5], p).unwrap_err();
        assert!(e.to_string().contains("gamma has 5 rows"), "{e}");
        let mut g = vec![[1.0, 1.0]; 6];
        g[3][1] = -2.0;
        let e = KnitMaterial::new(&mesh, g, p).unwrap_err();
        assert!(e.to_string().contains("gamma[3].gamma_v"), "{e}");
        let mut bad = mesh.clone();
        bad.tets[2].swap(0, 1);
        let e = KnitMaterial::new(&bad, vec![[1.0, 1.0]; 6], p).unwrap_err();
        assert!(e.to_string().contains("tets[2]"), "{e}");
        let mut bad = mesh.clone();
        bad.tets[4][3] = 99;
        let e = KnitMaterial::new(&bad, vec![[1.0, 1.0]; 6], p).unwrap_err();
        assert!(e.to_string().contains("node 99"), "{e}");
        let material = KnitMaterial::new(&mesh, vec![[1.0, 1.0]; 6], p).unwrap();
        let mut x: Vec<f64> = mesh.rest.iter().flatten().copied().collect();
        assert!(material.energy(&x[1..]).is_err());
        x[4] = f64::NAN;
        let e = material.energy(&x).unwrap_err();
        assert!(e.to_string().contains("positions[4]"), "{e}");
    }
}
