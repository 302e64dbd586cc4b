//! The form abstraction (after polyfem's `Form`): an energy `E(x)` over a flat vector of degrees of freedom
//! (DOFs) `x ∈ ℝⁿ`, with its value, gradient and sparse Hessian.
//!
//! The Hessian is not returned as a matrix: a form hands its dense symmetric element blocks, together with
//! the global DOF of each block row, to a [`HessianSink`]. Sinks decide what to do with them:
//! [`HessianTriplets`] keeps every entry (simple, for tests and one-off assembly), while
//! [`crate::sparse_assembly::FixedPatternAssembler`] records the sparsity pattern once and afterwards only
//! scatters numbers into a fixed faer matrix — what a Newton solver that refactors every step wants.
//!
//! Contract of [`Form::hessian`]: the sequence of [`HessianSink::add_block`] calls — their number and the
//! DOF list of each — depends only on the form's structure (mesh, fixed vertices), never on `x`. The
//! pattern-fixed assembler relies on this and reports [`FormError::PatternMismatch`] when it is broken.

use crate::math::Real;
use thiserror::Error;

/// Errors of evaluating a form.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum FormError {
    /// The DOF vector or the gradient output has the wrong length.
    #[error("{what} has {got} entries but the form has {expected} degrees of freedom")]
    Length {
        /// Which argument: "DOF vector x" or "gradient output".
        what: &'static str,
        /// Its length.
        got: usize,
        /// The form's number of DOFs.
        expected: usize,
    },
    /// An element is inverted, flat or has non-finite positions at this state (`J = det F ≤ 0` or NaN).
    /// Its energy is +∞ there ([`Form::value`] returns `Ok(+∞)`), so a line search must reject the step;
    /// gradient and Hessian do not exist and return this error instead.
    #[error(
        "element {element} is inverted, flat or non-finite at this state (J = det F = {det:e}); the energy \
         is +∞ there — reject this step"
    )]
    InvertedElement {
        /// Index of the element (tetrahedron) in the form's element list.
        element: usize,
        /// `det F` (dimensionless volume ratio), or NaN.
        det: Real,
    },
    /// A form's Hessian blocks did not match the pattern recorded for a fixed-pattern assembler.
    #[error("Hessian block {block} does not match the recorded sparsity pattern: {detail}")]
    PatternMismatch {
        /// Index of the offending block in the form's sequence of blocks.
        block: usize,
        /// What differs.
        detail: String,
    },
}

/// Receives the dense symmetric element blocks of a Hessian.
pub trait HessianSink {
    /// Adds the symmetric `m × m` block `block` (entry `(a, b)` at `block[a * m + b]`; being symmetric, row-
    /// and column-major storage coincide) at the global DOFs `dofs` (`m = dofs.len()`): the global Hessian
    /// entry `(dofs[a], dofs[b])` receives `block[a * m + b]`. A `None` DOF (e.g. a coordinate of a fixed
    /// vertex) drops that row and column. Repeated DOFs are allowed; their contributions add up.
    fn add_block(&mut self, dofs: &[Option<usize>], block: &[Real]);
}

/// An energy over a flat DOF vector. Units are the implementor's to document (the body energy takes
/// positions in m and returns J).
pub trait Form {
    /// Number of degrees of freedom `n`: the length of `x` and of the gradient.
    fn num_dofs(&self) -> usize;

    /// The energy at `x`. States outside the energy's domain (inverted elements, non-finite DOFs) give
    /// `Ok(Real::INFINITY)` — never NaN — so that a line search rejects them; `Err` only for malformed input.
    fn value(&self, x: &[Real]) -> Result<Real, FormError>;

    /// Writes (overwrites) the gradient `∂E/∂x` (length `n`) into `out`.
    fn gradient(&self, x: &[Real], out: &mut [Real]) -> Result<(), FormError>;

    /// Hands the Hessian `∂²E/∂x²` (`n × n`, symmetric) to `sink` as element blocks. The sequence of blocks
    /// and their DOF lists must not depend on `x` (see the module documentation).
    fn hessian(&self, x: &[Real], sink: &mut dyn HessianSink) -> Result<(), FormError>;
}

/// Checks that a DOF vector has the form's length.
pub fn check_dof_length(x: &[Real], expected: usize) -> Result<(), FormError> {
    if x.len() == expected {
        Ok(())
    } else {
        Err(FormError::Length {
            what: "DOF vector x",
            got: x.len(),
            expected,
        })
    }
}

/// Checks that a gradient output buffer has the form's length.
pub fn check_gradient_length(out: &[Real], expected: usize) -> Result<(), FormError> {
    if out.len() == expected {
        Ok(())
    } else {
        Err(FormError::Length {
            what: "gradient output",
            got: out.len(),
            expected,
        })
    }
}

/// A Hessian as an unsorted list of `(row, column, value)` triplets covering both triangles; duplicates add
/// up. Simple and allocation-heavy: for tests, reference assembly and small problems.
#[derive(Clone, Debug, Default)]
pub struct HessianTriplets {
    /// Matrix size `n` (rows = columns).
    pub size: usize,
    /// Entries `(row, column, value)`, both triangles, duplicates allowed.
    pub entries: Vec<(usize, usize, Real)>,
}

impl HessianTriplets {
    /// An empty `n × n` Hessian.
    pub fn new(size: usize) -> Self {
        Self {
            size,
            entries: Vec::new(),
        }
    }

    /// The dense `n × n` matrix, row-major (`dense[r * n + c]`), duplicates summed.
    pub fn to_dense(&self) -> Vec<Real> {
        let n = self.size;
        let mut dense = vec![0.0; n * n];
        for &(r, c, v) in &self.entries {
            dense[r * n + c] += v;
        }
        dense
    }
}

impl HessianSink for HessianTriplets {
    fn add_block(&mut self, dofs: &[Option<usize>], block: &[Real]) {
        let m = dofs.len();
        debug_assert_eq!(block.len(), m * m, "block must be m × m");
        for (a, da) in dofs.iter().enumerate() {
            let Some(ga) = *da else { continue };
            for (b, db) in dofs.iter().enumerate() {
                let Some(gb) = *db else { continue };
                self.entries.push((ga, gb, block[a * m + b]));
            }
        }
    }
}

/// The dense Hessian of `form` at `x`, row-major `n × n` — a reference for tests and tiny problems.
pub fn dense_hessian(form: &dyn Form, x: &[Real]) -> Result<Vec<Real>, FormError> {
    let mut triplets = HessianTriplets::new(form.num_dofs());
    form.hessian(x, &mut triplets)?;
    Ok(triplets.to_dense())
}
