//! Collisions of the embedded yarns with a rigid body (the knitwear paper Sec. 7 and Fig. 15/18: the
//! energy lives on the mesh, collisions are processed at the yarn level), as projective-dynamics
//! constraints (Bouaziz et al. 2014, Sec. 5): each yarn vertex `y_j = N_j x` (V2Y, Eq. 4: the barycentric
//! row of its tetrahedron) carries
//!
//! ```text
//! E_j(x) = ½ w ‖N_j x − Π(N_j x)‖²        (J),
//! ```
//!
//! with `Π` the projection onto the **admissible set** — the points at least the clearance `c` (m, the
//! yarn radius: the centreline keeps the yarn's surface out) outside every collider — and `w` the
//! stiffness (N/m). `Π(y) = y` outside, so the term vanishes there; inside, `Π` pushes `y` along the
//! collider's outward normal to the offset surface. `E_j` is `½ w dist²(y_j, admissible)`: a penalty,
//! so a resting contact penetrates by about its load over `w`.
//!
//! **Which vertices carry the term.** The *active* vertices (those in contact, see
//! [`super::backward_euler`]): their constraints enter `K` as `w Σ_j N_jᵀ N_j`, refactored when the
//! active set changes (the pattern is `K`'s own: `N_jᵀN_j` couples the nodes of one tetrahedron), and the
//! local step only changes the targets `p_j = Π(N_j x)`. At a fixed point the converged step is that of
//! `Ψ + Σ_j E_j` exactly (the envelope argument of [`super::local_step`] applies: `∂E_j/∂y =
//! w (y − Π(y))` wherever `Π` is single-valued).
//!
//! Colliders: a **sphere** (centre, radius) and an infinite **cylinder** (a point on its axis, the axis
//! direction, radius), both in m. The projection onto the offset surface of a sphere is radial; of a
//! cylinder, radial from the axis. A point exactly on the centre (axis) has no normal; it is pushed along
//! +y (a fixed, documented choice; the derivative there does not exist).

use nalgebra::Vector3;
use thiserror::Error;

/// Why a collider or the collision settings cannot be used.
#[derive(Clone, Debug, PartialEq, Error)]
pub enum BodyCollisionError {
    /// A number of a collider is NaN, ∞ or out of range.
    #[error("collider {index}: {field} = {value} is not allowed ({expected})")]
    Collider {
        /// The collider's index in the list.
        index: usize,
        /// Which number.
        field: &'static str,
        /// Its value.
        value: f64,
        /// What is allowed.
        expected: &'static str,
    },
    /// A yarn vertex starts inside a collider: the scene would start with a collision to resolve.
    #[error(
        "collider {index} holds yarn vertex {vertex} at the start ({depth_m:.3e} m inside its clearance); \
         move the collider out of the patch"
    )]
    StartsInside {
        /// The collider.
        index: usize,
        /// The yarn vertex.
        vertex: usize,
        /// How deep (m).
        depth_m: f64,
    },
    /// The clearance or the stiffness is out of range.
    #[error("collisions: {field} = {value} is out of range ({expected})")]
    Params {
        /// Which setting.
        field: &'static str,
        /// Its value.
        value: f64,
        /// What is allowed.
        expected: &'static str,
    },
}

/// The shape of a [`BodyCollider`].
#[derive(Clone, Copy, Debug, PartialEq)]
enum Shape {
    Sphere {
        center: Vector3<f64>,
        radius: f64,
    },
    Cylinder {
        point: Vector3<f64>,
        /// Unit.
        axis: Vector3<f64>,
        radius: f64,
    },
}

/// A rigid body the yarns cannot enter (fixed in space).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyCollider {
    shape: Shape,
}

fn finite3(
    index: usize,
    field: &'static str,
    v: [f64; 3],
) -> Result<Vector3<f64>, BodyCollisionError> {
    match v.iter().find(|c| !c.is_finite()) {
        Some(&value) => Err(BodyCollisionError::Collider {
            index,
            field,
            value,
            expected: "finite (m)",
        }),
        None => Ok(Vector3::from(v)),
    }
}

fn radius(index: usize, radius: f64) -> Result<f64, BodyCollisionError> {
    if radius.is_finite() && radius > 0.0 {
        Ok(radius)
    } else {
        Err(BodyCollisionError::Collider {
            index,
            field: "radius",
            value: radius,
            expected: "finite and > 0 (m)",
        })
    }
}

impl BodyCollider {
    /// A sphere of centre `center` (m) and radius `radius` (m); `index` names it in errors.
    pub fn sphere(index: usize, center: [f64; 3], r: f64) -> Result<Self, BodyCollisionError> {
        Ok(Self {
            shape: Shape::Sphere {
                center: finite3(index, "center", center)?,
                radius: radius(index, r)?,
            },
        })
    }

    /// An infinite cylinder through `point` (m) along `axis` (any length > 0), radius `radius` (m).
    pub fn cylinder(
        index: usize,
        point: [f64; 3],
        axis: [f64; 3],
        r: f64,
    ) -> Result<Self, BodyCollisionError> {
        let axis = finite3(index, "axis", axis)?;
        let norm = axis.norm();
        if norm <= 1e-12 {
            return Err(BodyCollisionError::Collider {
                index,
                field: "axis",
                value: norm,
                expected: "a direction of length > 0",
            });
        }
        Ok(Self {
            shape: Shape::Cylinder {
                point: finite3(index, "point", point)?,
                axis: axis / norm,
                radius: radius(index, r)?,
            },
        })
    }

    /// The distance (m) of `y` outside the surface (negative inside).
    pub fn signed_distance(&self, y: [f64; 3]) -> f64 {
        let (offset, r) = self.radial(Vector3::from(y));
        offset.norm() - r
    }

    /// `Π(y)` for this collider alone: `y` when it is at least `clearance` (m) outside, else the closest
    /// point at exactly `clearance` outside.
    pub fn push_out(&self, y: [f64; 3], clearance: f64) -> [f64; 3] {
        let p = Vector3::from(y);
        let (offset, r) = self.radial(p);
        let d = offset.norm();
        if d >= r + clearance {
            return y;
        }
        let normal = if d > 0.0 {
            offset / d
        } else {
            Vector3::new(0.0, 1.0, 0.0)
        };
        (p - offset + normal * (r + clearance)).into()
    }

    /// The offset of `p` from the centre (sphere) or the axis (cylinder), and the radius.
    fn radial(&self, p: Vector3<f64>) -> (Vector3<f64>, f64) {
        match self.shape {
            Shape::Sphere { center, radius } => (p - center, radius),
            Shape::Cylinder {
                point,
                axis,
                radius,
            } => {
                let d = p - point;
                (d - axis * axis.dot(&d), radius)
            }
        }
    }
}

/// The default weight `w` over the mean diagonal of the elastic part of `K`: stiff enough that a contact
/// stays within a part of the clearance (the tests' block, dropped on a sphere: 0.11 mm at impact of a
/// 0.5 mm clearance), soft enough that PD still converges (17–125 iterations a step there; at 100 the
/// impact step did not converge in 1 000).
pub const DEFAULT_STIFFNESS_RATIO: f64 = 10.0;

/// The colliders of a simulation and how their constraints are weighted.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BodyCollision {
    /// The colliders (none: no collision terms, `K` unchanged).
    pub colliders: Vec<BodyCollider>,
    /// How far outside a collider a yarn centreline is held (m, ≥ 0): the yarn radius.
    pub clearance_m: f64,
    /// The constraint weight `w` (N/m, > 0); `None`: [`DEFAULT_STIFFNESS_RATIO`] times the mean
    /// diagonal of the elastic part of `K`.
    pub stiffness: Option<f64>,
}

impl BodyCollision {
    /// Checks the settings.
    pub fn validate(&self) -> Result<(), BodyCollisionError> {
        if !(self.clearance_m.is_finite() && self.clearance_m >= 0.0) {
            return Err(BodyCollisionError::Params {
                field: "clearance_m",
                value: self.clearance_m,
                expected: "finite and ≥ 0 (m)",
            });
        }
        if let Some(w) = self.stiffness
            && !(w.is_finite() && w > 0.0)
        {
            return Err(BodyCollisionError::Params {
                field: "stiffness",
                value: w,
                expected: "finite and > 0 (N/m)",
            });
        }
        Ok(())
    }

    /// `Π(y)`: `y` pushed out of each collider in turn (one pass; exact for one collider or disjoint
    /// ones, which is what the scenes use).
    pub fn project(&self, y: [f64; 3]) -> [f64; 3] {
        self.colliders
            .iter()
            .fold(y, |y, c| c.push_out(y, self.clearance_m))
    }

    /// Refuses yarn vertices `yarns` (`#Y × 3`, m) that start inside a collider's clearance (beyond a
    /// round-off of 10⁻⁹ of the clearance or 1 nm).
    pub fn check_start(&self, yarns: &[[f64; 3]]) -> Result<(), BodyCollisionError> {
        let slack = (1e-9 * self.clearance_m).max(1e-9);
        for (index, c) in self.colliders.iter().enumerate() {
            for (vertex, &y) in yarns.iter().enumerate() {
                let depth_m = self.clearance_m - c.signed_distance(y);
                if depth_m > slack {
                    return Err(BodyCollisionError::StartsInside {
                        index,
                        vertex,
                        depth_m,
                    });
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn pushed_points_sit_on_the_offset_surface_and_outside_points_stay() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let sphere = BodyCollider::sphere(0, [0.1, -0.2, 0.3], 0.05).unwrap();
        let cylinder = BodyCollider::cylinder(1, [0.0, 0.0, 0.0], [1.0, 1.0, 0.0], 0.03).unwrap();
        let clearance = 0.001;
        for c in [sphere, cylinder] {
            for _ in 0..200 {
                let y: [f64; 3] = [0, 1, 2].map(|_| rng.random_range(-0.3..0.3));
                let p = c.push_out(y, clearance);
                let d = c.signed_distance(y);
                if d >= clearance {
                    assert_eq!(p, y);
                } else {
                    assert!((c.signed_distance(p) - clearance).abs() < 1e-12);
                    // The push is along the normal: its length is the depth.
                    let moved = Vector3::from(p) - Vector3::from(y);
                    assert!((moved.norm() - (clearance - d)).abs() < 1e-12);
                }
            }
        }
        // A cylinder's push is perpendicular to its axis.
        let y = [0.01, 0.0, 0.005];
        let p = cylinder.push_out(y, clearance);
        let moved = Vector3::from(p) - Vector3::from(y);
        assert!(moved.dot(&Vector3::new(1.0, 1.0, 0.0)).abs() < 1e-15);
        // The centre has no normal: pushed along +y.
        let p = sphere.push_out([0.1, -0.2, 0.3], 0.0);
        assert!((Vector3::from(p) - Vector3::new(0.1, -0.15, 0.3)).norm() < 1e-15);
    }

    #[test]
    fn bad_colliders_and_starts_are_refused_by_name() {
        let err = BodyCollider::sphere(2, [0.0, f64::NAN, 0.0], 1.0).unwrap_err();
        assert!(err.to_string().contains("collider 2: center"), "{err}");
        let err = BodyCollider::sphere(0, [0.0; 3], -1.0).unwrap_err();
        assert!(err.to_string().contains("radius"), "{err}");
        let err = BodyCollider::cylinder(1, [0.0; 3], [0.0; 3], 1.0).unwrap_err();
        assert!(err.to_string().contains("axis"), "{err}");
        let collision = BodyCollision {
            colliders: vec![BodyCollider::sphere(0, [0.0; 3], 0.1).unwrap()],
            clearance_m: 0.002,
            stiffness: None,
        };
        let err = collision
            .check_start(&[[1.0, 0.0, 0.0], [0.0, 0.101, 0.0]])
            .unwrap_err();
        assert!(
            err.to_string().contains("collider 0 holds yarn vertex 1"),
            "{err}"
        );
        assert!(collision.check_start(&[[0.0, 0.103, 0.0]]).is_ok());
        for (bad, field) in [
            (
                BodyCollision {
                    clearance_m: -1.0,
                    ..collision.clone()
                },
                "clearance_m",
            ),
            (
                BodyCollision {
                    stiffness: Some(f64::NAN),
                    ..collision.clone()
                },
                "stiffness",
            ),
        ] {
            let err = bad.validate().unwrap_err();
            assert!(err.to_string().contains(field), "{err}");
        }
    }
}
