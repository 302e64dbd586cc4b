//! Scalar and small fixed-size types used throughout skintight.
//!
//! Every length is in metres, every area in m², every volume in m³. Surface coordinates `s = (s1, s2)`
//! are dimensionless barycentric-style coordinates inside one face (the third is `s3 = 1 − s1 − s2`).

/// The scalar type of all geometry and physics.
pub type Real = f64;
/// A 3D point or vector (m).
pub type Vec3 = nalgebra::Vector3<Real>;
/// A 2D point or vector: pattern positions (m) or surface coordinates (dimensionless).
pub type Vec2 = nalgebra::Vector2<Real>;
/// 3 × 3 matrix.
pub type Mat3 = nalgebra::Matrix3<Real>;
/// 2 × 2 matrix.
pub type Mat2 = nalgebra::Matrix2<Real>;
/// 3 × 2 matrix (e.g. a surface tangent frame ∂x/∂s, or a membrane deformation gradient).
pub type Mat3x2 = nalgebra::Matrix3x2<Real>;

/// Index of a vertex in a mesh.
pub type VertexId = usize;
/// Index of a face (triangle) in a mesh.
pub type FaceId = usize;
