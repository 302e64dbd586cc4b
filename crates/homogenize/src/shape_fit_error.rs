//! The errors of shape fitting (Sec. 5 of the knitwear paper: the per-segment deformation gradients, their
//! element averages, the Y2V least squares and the inertia forces). Each names the input at fault and how
//! to fix it.

use skintight_physics::CholeskyError;

/// What went wrong in shape fitting.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ShapeFitError {
    /// An input has the wrong number of entries.
    #[error("{what} has {got} entries, expected {expected}; pass one per {per}")]
    Count {
        /// Which input.
        what: &'static str,
        /// Its length.
        got: usize,
        /// The expected length.
        expected: usize,
        /// What one entry stands for.
        per: &'static str,
    },
    /// An input holds a NaN or infinite number.
    #[error("{what} {index} is not finite ({value}); every coordinate must be a finite number")]
    NotFinite {
        /// Which input (e.g. "frame row").
        what: &'static str,
        /// The entry.
        index: usize,
        /// The offending number.
        value: f64,
    },
    /// A yarn segment at rest is degenerate: its edge and material normals are not independent (zero
    /// length, or normals parallel to the edge).
    #[error(
        "yarn segment {segment} (vertices {from} → {to}) has a degenerate rest frame (edge {length_m:e} m); \
         the rest pose needs distinct consecutive vertices"
    )]
    DegenerateSegment {
        /// The segment.
        segment: usize,
        /// Its first vertex.
        from: usize,
        /// Its second vertex.
        to: usize,
        /// Its rest length (m).
        length_m: f64,
    },
    /// A deformed yarn edge has zero length, so its tangent (and material frame) is undefined.
    #[error(
        "yarn segment {segment} (vertices {from} → {to}) has zero length in the frame; the frame's \
         consecutive vertices must be distinct"
    )]
    CollapsedSegment {
        /// The segment.
        segment: usize,
        /// Its first vertex.
        from: usize,
        /// Its second vertex.
        to: usize,
    },
    /// The yarn ranges do not describe the vertices.
    #[error("yarn {yarn}: {problem}")]
    Yarns {
        /// The yarn.
        yarn: usize,
        /// What is wrong.
        problem: String,
    },
    /// The mesh is not usable for shape fitting.
    #[error("the volumetric mesh {problem}")]
    Mesh {
        /// What is wrong.
        problem: String,
    },
    /// A parameter is out of range.
    #[error("shape-fit parameter {name} = {value} {problem}")]
    Param {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What it must be.
        problem: &'static str,
    },
    /// The sparse factorization of the Y2V system failed.
    #[error(
        "the Y2V system could not be factored ({0}); every connected part of the mesh needs an embedded \
         yarn vertex"
    )]
    Solver(CholeskyError),
}
