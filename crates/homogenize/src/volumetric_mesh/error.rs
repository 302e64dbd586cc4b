//! Why a volumetric mesh cannot be built or applied: every message names the input and says how to fix it.

/// Why a volumetric mesh cannot be built from the given yarns and settings, or an operator of it applied.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum VolumetricMeshError {
    /// No yarn vertices, or no yarn segment.
    #[error(
        "the yarns are empty ({vertices} vertices, {segments} segments): give at least one yarn with two vertices"
    )]
    Empty {
        /// Yarn vertices given.
        vertices: usize,
        /// Yarn segments given.
        segments: usize,
    },
    /// The yarns' vertex ranges do not cover the vertices one after the other.
    #[error(
        "yarn {yarn} covers vertices {first}..{end} but must start at vertex {expected} (of {total}): the yarns' ranges must cover the vertices in order, each yarn starting where the previous one ends"
    )]
    YarnRange {
        /// The yarn.
        yarn: usize,
        /// Its first vertex.
        first: usize,
        /// One past its last vertex.
        end: usize,
        /// Where it should start.
        expected: usize,
        /// Vertices in all.
        total: usize,
    },
    /// Vertices after the last yarn's range.
    #[error(
        "the yarns' ranges cover vertices 0..{covered} but there are {total}: give every vertex to a yarn"
    )]
    Uncovered {
        /// Vertices covered.
        covered: usize,
        /// Vertices given.
        total: usize,
    },
    /// A yarn vertex with a NaN or infinite coordinate.
    #[error(
        "yarn vertex {vertex} (of yarn {yarn}) has a non-finite coordinate {position:?}: give finite rest positions in m"
    )]
    NonFinite {
        /// The yarn.
        yarn: usize,
        /// The vertex (index over all yarns).
        vertex: usize,
        /// Its position.
        position: [f64; 3],
    },
    /// A setting or yarn property that must be positive and finite is not.
    #[error("{name} = {value} must be positive and finite ({hint})")]
    NotPositive {
        /// The setting (`voxel_m`, `radius_m`, `linear_density_kg_per_m`).
        name: &'static str,
        /// Its value.
        value: f64,
        /// What it means and its unit.
        hint: &'static str,
    },
    /// The voxel is larger than the yarns' bounding box in every direction: the mesh would be a few cubes.
    #[error(
        "voxel_m = {voxel_m} m is larger than the patch (its bounding box is {extent_m:?} m): choose a voxel of at most {largest_m} m, e.g. the yarn diameter"
    )]
    VoxelLargerThanPatch {
        /// The voxel edge (m).
        voxel_m: f64,
        /// The bounding box's extent (m).
        extent_m: [f64; 3],
        /// Its largest extent (m).
        largest_m: f64,
    },
    /// The voxel is so small against the patch that grid coordinates would lose their precision.
    #[error(
        "voxel_m = {voxel_m} m is too small for a patch of {largest_m} m (more than 2^31 voxels across): choose a voxel of at least {smallest_m} m"
    )]
    VoxelTooSmall {
        /// The voxel edge (m).
        voxel_m: f64,
        /// The bounding box's largest extent (m).
        largest_m: f64,
        /// The smallest voxel accepted (m).
        smallest_m: f64,
    },
    /// The mesh would have more voxels than allowed.
    #[error(
        "voxel_m = {voxel_m} m would give up to {voxels} voxels, more than max_voxels = {limit}: choose a voxel of at least {suggested_m:.3e} m or raise max_voxels"
    )]
    TooManyVoxels {
        /// The voxel edge (m).
        voxel_m: f64,
        /// The estimated voxel count (an upper bound).
        voxels: f64,
        /// The limit.
        limit: usize,
        /// A voxel edge that would fit (m).
        suggested_m: f64,
    },
    /// A yarn point the mesh does not enclose (a bug of the construction, reported rather than hidden).
    #[error(
        "yarn vertex or segment point {vertex} at {position:?} m lies outside the mesh's voxels; please report this input"
    )]
    NotEnclosed {
        /// The yarn vertex (or the first vertex of the segment).
        vertex: usize,
        /// The point (m).
        position: [f64; 3],
    },
    /// A mesh whose arrays do not fit together (e.g. one read from a damaged file).
    #[error(
        "the volumetric mesh is inconsistent: {problem}; rebuild it with VolumetricMesh::build"
    )]
    Inconsistent {
        /// What does not fit.
        problem: String,
    },
    /// An array handed to an operator of the mesh has the wrong length.
    #[error("{what}: {len} given, the mesh needs {expected}")]
    Length {
        /// What the array holds.
        what: &'static str,
        /// Its length.
        len: usize,
        /// The length needed.
        expected: usize,
    },
}
