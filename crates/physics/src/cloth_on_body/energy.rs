//! The energy `U = U_body + U_cloth` (J) and its gradient `∂U/∂q` by the chain rule through the surface
//! (thesis Eq. 155; see the parent module for the formulas and units).

use super::{ClothOnBody, ClothOnBodyError, ClothOnBodyState, Frames, SurfaceFrames};
use crate::math::{Real, Vec3};
use crate::membrane_element::Vector9;

impl ClothOnBody {
    /// `(U_body, U_cloth)` (J). Either is `+∞` where the state is outside the energy's domain (an inverted
    /// body element, a non-finite position), never NaN.
    pub fn energies(&self, state: &ClothOnBodyState) -> Result<(Real, Real), ClothOnBodyError> {
        let frames = self.frames(state)?;
        Ok(self.energies_with(state, &frames))
    }

    /// [`Self::energies`] with the surface already evaluated at `state` (`frames` from
    /// [`Self::frames_at`], which the assembly at the same state then reuses).
    pub fn energies_at(
        &self,
        state: &ClothOnBodyState,
        frames: &SurfaceFrames,
    ) -> Result<(Real, Real), ClothOnBodyError> {
        self.check_state(state)?;
        if frames.0.points.len() != state.cloth.len() {
            return Err(ClothOnBodyError::Shape(format!(
                "surface frames of {} cloth vertices for a state of {}",
                frames.0.points.len(),
                state.cloth.len()
            )));
        }
        Ok(self.energies_with(state, &frames.0))
    }

    pub(super) fn energies_with(&self, state: &ClothOnBodyState, frames: &Frames) -> (Real, Real) {
        let mut body = 0.0;
        let material = self.body.material();
        for (t, tet) in self.tets.iter().enumerate() {
            body += self.body.elements()[t].energy(material, &tet.map(|v| state.body[v]));
        }
        let mut cloth = 0.0;
        for (t, element) in self.elements.iter().enumerate() {
            match element.energy(&self.law, &self.corners(t, &frames.points)) {
                Ok(e) => cloth += e,
                Err(_) => cloth = Real::INFINITY,
            }
        }
        if body.is_nan() {
            body = Real::INFINITY;
        }
        if cloth.is_nan() {
            cloth = Real::INFINITY;
        }
        (body, cloth)
    }

    /// `U = U_body + U_cloth` (J); `+∞` outside the domain.
    pub fn energy(&self, state: &ClothOnBodyState) -> Result<Real, ClothOnBodyError> {
        let (b, c) = self.energies(state)?;
        Ok(b + c)
    }

    /// Writes `∂U/∂q` (length `#q`) into `out` and returns `U` (J).
    pub fn gradient(
        &self,
        state: &ClothOnBodyState,
        out: &mut [Real],
    ) -> Result<Real, ClothOnBodyError> {
        self.check_dofs(out, "gradient buffer")?;
        let frames = self.frames(state)?;
        out.fill(0.0);
        let mut energy = self.body_gradient(state, out)?;
        for t in 0..self.elements.len() {
            let x = self.corners(t, &frames.points);
            let (e, g) = self.elements[t]
                .energy_gradient(&self.law, &x)
                .map_err(|source| ClothOnBodyError::Cloth {
                    triangle: t,
                    source,
                })?;
            energy += e;
            self.scatter_cloth_gradient(t, &frames, &g, out);
        }
        Ok(energy)
    }

    pub(super) fn body_gradient(
        &self,
        state: &ClothOnBodyState,
        out: &mut [Real],
    ) -> Result<Real, ClothOnBodyError> {
        let mut energy = 0.0;
        for t in 0..self.tets.len() {
            energy += self.tet_gradient(t, state, out)?;
        }
        Ok(energy)
    }

    pub(super) fn scatter_cloth_gradient(
        &self,
        t: usize,
        frames: &Frames,
        g: &Vector9,
        out: &mut [Real],
    ) {
        for (i, &c) in self.triangles[t].iter().enumerate() {
            let gi = Vec3::new(g[3 * i], g[3 * i + 1], g[3 * i + 2]);
            self.scatter_vertex_gradient(c, frames, &gi, out);
        }
    }

    /// Adds `(∂x_c/∂q)ᵀ g` — a derivative with respect to cloth vertex `c`'s position — into `out` (`#q`).
    pub(super) fn scatter_vertex_gradient(
        &self,
        c: usize,
        frames: &Frames,
        g: &Vec3,
        out: &mut [Real],
    ) {
        if let Some(d) = self.cloth_dof[c] {
            let tg = frames.points[c].tangents.transpose() * g;
            out[d] += tg.x;
            out[d + 1] += tg.y;
        }
        for &(v, w, _) in &frames.entries[frames.offsets[c]..frames.offsets[c + 1]] {
            if let Some(d) = self.body_dof[v] {
                for k in 0..3 {
                    out[d + k] += w * g[k];
                }
            }
        }
    }

    /// Body tetrahedron `t`: adds its gradient into `out`, returns its energy.
    pub(super) fn tet_gradient(
        &self,
        t: usize,
        state: &ClothOnBodyState,
        out: &mut [Real],
    ) -> Result<Real, ClothOnBodyError> {
        let tet = &self.tets[t];
        let material = self.body.material();
        let x = tet.map(|v| state.body[v]);
        let element = &self.body.elements()[t];
        let g = element
            .gradient(material, &x)
            .map_err(|det| ClothOnBodyError::InvertedBody { tet: t, det })?;
        for (a, &v) in tet.iter().enumerate() {
            if let Some(d) = self.body_dof[v] {
                for k in 0..3 {
                    out[d + k] += g[3 * a + k];
                }
            }
        }
        Ok(element.energy(material, &x))
    }
}
