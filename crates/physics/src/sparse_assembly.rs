//! Sparse Hessian assembly with a fixed sparsity pattern.
//!
//! A Newton solver factors the Hessian once per step, always with the same sparsity pattern. The
//! [`FixedPatternAssembler`] therefore splits assembly in two:
//!
//! 1. **Symbolic, once** ([`FixedPatternAssembler::new`]): the form's element blocks are recorded, the
//!    pattern of the **lower triangle** (row ≥ column, diagonal included and always complete) is built in
//!    compressed-column form with sorted row indices, and every stored element entry gets the index of the
//!    value slot it lands in.
//! 2. **Numeric, per step** ([`FixedPatternAssembler::assemble`]): the values are zeroed and each element
//!    entry is added to its precomputed slot — no hashing, sorting or allocation.
//!
//! The matrix is a faer `SparseColMat<usize, f64>` holding only the lower triangle; factor it with
//! `faer::Side::Lower`, e.g. `SymbolicLlt::try_new(m.symbolic(), Side::Lower)` then
//! `Llt::try_new_with_symbolic(symbolic, m.as_ref(), Side::Lower)`.

use crate::form::{Form, FormError, HessianSink};
use crate::math::Real;
use faer::sparse::{SparseColMat, SymbolicSparseColMat};

/// One recorded element block.
#[derive(Clone, Copy, Debug)]
struct BlockRecord {
    /// Start of the block's DOF list in `block_dofs`.
    dofs_start: usize,
    /// Number of local DOFs `m` of the block.
    size: usize,
    /// Start of the block's stored entries in `entry_local` / `entry_slot`.
    entries_start: usize,
}

/// Records the blocks a form emits (first phase of [`FixedPatternAssembler::new`]).
#[derive(Default)]
struct BlockRecorder {
    blocks: Vec<BlockRecord>,
    block_dofs: Vec<Option<usize>>,
}

impl HessianSink for BlockRecorder {
    fn add_block(&mut self, dofs: &[Option<usize>], _block: &[Real]) {
        self.blocks.push(BlockRecord {
            dofs_start: self.block_dofs.len(),
            size: dofs.len(),
            entries_start: 0,
        });
        self.block_dofs.extend_from_slice(dofs);
    }
}

/// A Hessian assembler with a sparsity pattern fixed at construction; see the module documentation.
/// Stores the lower triangle (row ≥ column) of the symmetric `n × n` Hessian.
#[derive(Clone, Debug)]
pub struct FixedPatternAssembler {
    matrix: SparseColMat<usize, Real>,
    blocks: Vec<BlockRecord>,
    block_dofs: Vec<Option<usize>>,
    /// For every stored element entry: its local index `a * m + b` in the block.
    entry_local: Vec<u32>,
    /// For every stored element entry: the index of its value slot in the matrix.
    entry_slot: Vec<usize>,
    /// Value slot of each diagonal entry `(i, i)`.
    diagonal_slots: Vec<usize>,
}

impl FixedPatternAssembler {
    /// Records the pattern of `form`'s Hessian by evaluating it once at `x` (any state where the Hessian
    /// exists, e.g. the rest state). The diagonal is always stored in full, even for DOFs no block touches,
    /// so a diagonal regularization can always be added.
    pub fn new(form: &dyn Form, x: &[Real]) -> Result<Self, FormError> {
        let n = form.num_dofs();
        let mut recorder = BlockRecorder::default();
        form.hessian(x, &mut recorder)?;
        let BlockRecorder {
            mut blocks,
            block_dofs,
        } = recorder;

        // All lower-triangle positions (column, row), plus the diagonal.
        let mut positions: Vec<(usize, usize)> = (0..n).map(|i| (i, i)).collect();
        for (k, block) in blocks.iter().enumerate() {
            let dofs = &block_dofs[block.dofs_start..block.dofs_start + block.size];
            for da in dofs.iter().flatten() {
                for db in dofs.iter().flatten() {
                    if *da >= n || *db >= n {
                        return Err(FormError::PatternMismatch {
                            block: k,
                            detail: format!(
                                "DOF {} is out of range for a form with {n} DOFs",
                                (*da).max(*db)
                            ),
                        });
                    }
                    if da >= db {
                        positions.push((*db, *da));
                    }
                }
            }
        }
        positions.sort_unstable();
        positions.dedup();

        let mut col_ptr = vec![0usize; n + 1];
        for &(c, _) in &positions {
            col_ptr[c + 1] += 1;
        }
        for c in 0..n {
            col_ptr[c + 1] += col_ptr[c];
        }
        let row_idx: Vec<usize> = positions.iter().map(|&(_, r)| r).collect();
        let slot_of = |row: usize, col: usize| -> usize {
            let range = col_ptr[col]..col_ptr[col + 1];
            let within = row_idx[range.clone()]
                .binary_search(&row)
                .expect("every recorded position is in the pattern");
            range.start + within
        };

        let diagonal_slots: Vec<usize> = (0..n).map(|i| slot_of(i, i)).collect();
        let mut entry_local = Vec::new();
        let mut entry_slot = Vec::new();
        for block in &mut blocks {
            block.entries_start = entry_local.len();
            let m = block.size;
            let dofs = &block_dofs[block.dofs_start..block.dofs_start + m];
            for (a, da) in dofs.iter().enumerate() {
                let Some(ga) = *da else { continue };
                for (b, db) in dofs.iter().enumerate() {
                    let Some(gb) = *db else { continue };
                    // Each full-matrix entry (ga, gb) with ga > gb equals its mirror (gb, ga); keep the lower
                    // one only. When ga == gb (diagonal, possibly from two local DOFs) every pair counts.
                    if ga >= gb {
                        entry_local.push((a * m + b) as u32);
                        entry_slot.push(slot_of(ga, gb));
                    }
                }
            }
        }

        // SAFETY-free construction: `new_checked` validates the column pointers and sorted row indices.
        let symbolic = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
        let nnz = positions.len();
        Ok(Self {
            matrix: SparseColMat::new(symbolic, vec![0.0; nnz]),
            blocks,
            block_dofs,
            entry_local,
            entry_slot,
            diagonal_slots,
        })
    }

    /// Matrix size `n`.
    pub fn size(&self) -> usize {
        self.diagonal_slots.len()
    }

    /// Number of stored (lower-triangle) entries.
    pub fn nnz(&self) -> usize {
        self.matrix.val().len()
    }

    /// Re-evaluates `form`'s Hessian at `x` into the fixed pattern (values only) and returns the matrix
    /// (lower triangle). `form` must emit the same blocks as when the pattern was recorded.
    pub fn assemble(
        &mut self,
        form: &dyn Form,
        x: &[Real],
    ) -> Result<&SparseColMat<usize, Real>, FormError> {
        self.matrix.val_mut().fill(0.0);
        let mut scatter = Scatter {
            assembler: self,
            cursor: 0,
            mismatch: None,
        };
        form.hessian(x, &mut scatter)?;
        let (cursor, mismatch) = (scatter.cursor, scatter.mismatch);
        if let Some(err) = mismatch {
            return Err(err);
        }
        if cursor != self.blocks.len() {
            return Err(FormError::PatternMismatch {
                block: cursor,
                detail: format!(
                    "the form emitted {cursor} blocks, the pattern was recorded from {}",
                    self.blocks.len()
                ),
            });
        }
        Ok(&self.matrix)
    }

    /// The assembled matrix (lower triangle, row ≥ column, sorted row indices per column).
    pub fn matrix(&self) -> &SparseColMat<usize, Real> {
        &self.matrix
    }

    /// Adds `shift` to every diagonal entry (e.g. a regularization `H + δ I`).
    pub fn add_to_diagonal(&mut self, shift: Real) {
        let values = self.matrix.val_mut();
        for &s in &self.diagonal_slots {
            values[s] += shift;
        }
    }

    /// Value slot of each diagonal entry `(i, i)` in `matrix().val()`.
    pub fn diagonal_slots(&self) -> &[usize] {
        &self.diagonal_slots
    }

    /// The full symmetric matrix as dense row-major `n × n` (for tests and small problems).
    pub fn to_dense(&self) -> Vec<Real> {
        let n = self.size();
        let mut dense = vec![0.0; n * n];
        let m = &self.matrix;
        for c in 0..n {
            let rows = m.row_idx_of_col_raw(c);
            let vals = m.val_of_col(c);
            for (&r, &v) in rows.iter().zip(vals) {
                dense[r * n + c] = v;
                dense[c * n + r] = v;
            }
        }
        dense
    }
}

/// Numeric phase: scatters blocks into the fixed pattern, following the recorded sequence.
struct Scatter<'a> {
    assembler: &'a mut FixedPatternAssembler,
    cursor: usize,
    mismatch: Option<FormError>,
}

impl HessianSink for Scatter<'_> {
    fn add_block(&mut self, dofs: &[Option<usize>], block: &[Real]) {
        if self.mismatch.is_some() {
            return;
        }
        let k = self.cursor;
        self.cursor += 1;
        let asm = &mut *self.assembler;
        let Some(record) = asm.blocks.get(k).copied() else {
            self.mismatch = Some(FormError::PatternMismatch {
                block: k,
                detail: format!("only {} blocks were recorded", asm.blocks.len()),
            });
            return;
        };
        let recorded = &asm.block_dofs[record.dofs_start..record.dofs_start + record.size];
        if recorded != dofs || block.len() != record.size * record.size {
            self.mismatch = Some(FormError::PatternMismatch {
                block: k,
                detail: format!("DOFs {dofs:?} were recorded as {recorded:?}"),
            });
            return;
        }
        let end = asm
            .blocks
            .get(k + 1)
            .map_or(asm.entry_local.len(), |b| b.entries_start);
        let values = asm.matrix.val_mut();
        for (&local, &slot) in asm.entry_local[record.entries_start..end]
            .iter()
            .zip(&asm.entry_slot[record.entries_start..end])
        {
            values[slot] += block[local as usize];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::form::{check_dof_length, check_gradient_length, dense_hessian};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// E(x) = Σ_k ½ scale · x_kᵀ A_k x_k over random blocks (random DOF lists, some `None`, some repeated).
    struct RandomBlocks {
        n: usize,
        blocks: Vec<(Vec<Option<usize>>, Vec<Real>)>,
        scale: Real,
    }

    impl RandomBlocks {
        fn new(n: usize, count: usize, seed: u64) -> Self {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let blocks = (0..count)
                .map(|_| {
                    let m = rng.random_range(1..=6);
                    let dofs: Vec<Option<usize>> = (0..m)
                        .map(|_| (rng.random::<f64>() > 0.15).then(|| rng.random_range(0..n)))
                        .collect();
                    let mut a = vec![0.0; m * m];
                    for i in 0..m {
                        for j in 0..=i {
                            let v = rng.random_range(-1.0..1.0);
                            a[i * m + j] = v;
                            a[j * m + i] = v;
                        }
                    }
                    (dofs, a)
                })
                .collect();
            Self {
                n,
                blocks,
                scale: 1.0,
            }
        }

        fn local(dofs: &[Option<usize>], x: &[Real]) -> Vec<Real> {
            dofs.iter().map(|d| d.map_or(0.0, |g| x[g])).collect()
        }
    }

    impl Form for RandomBlocks {
        fn num_dofs(&self) -> usize {
            self.n
        }
        fn value(&self, x: &[Real]) -> Result<Real, FormError> {
            check_dof_length(x, self.n)?;
            let mut e = 0.0;
            for (dofs, a) in &self.blocks {
                let xl = Self::local(dofs, x);
                let m = dofs.len();
                for i in 0..m {
                    for j in 0..m {
                        e += 0.5 * self.scale * xl[i] * a[i * m + j] * xl[j];
                    }
                }
            }
            Ok(e)
        }
        fn gradient(&self, x: &[Real], out: &mut [Real]) -> Result<(), FormError> {
            check_dof_length(x, self.n)?;
            check_gradient_length(out, self.n)?;
            out.fill(0.0);
            for (dofs, a) in &self.blocks {
                let xl = Self::local(dofs, x);
                let m = dofs.len();
                for i in 0..m {
                    if let Some(g) = dofs[i] {
                        for j in 0..m {
                            out[g] += self.scale * a[i * m + j] * xl[j];
                        }
                    }
                }
            }
            Ok(())
        }
        fn hessian(&self, x: &[Real], sink: &mut dyn HessianSink) -> Result<(), FormError> {
            check_dof_length(x, self.n)?;
            let mut scaled = Vec::new();
            for (dofs, a) in &self.blocks {
                scaled.clear();
                scaled.extend(a.iter().map(|v| v * self.scale));
                sink.add_block(dofs, &scaled);
            }
            Ok(())
        }
    }

    fn assert_dense_eq(a: &[Real], b: &[Real], tol: Real) {
        assert_eq!(a.len(), b.len());
        for (k, (x, y)) in a.iter().zip(b).enumerate() {
            assert!((x - y).abs() <= tol, "entry {k}: {x} vs {y}");
        }
    }

    #[test]
    fn fixed_pattern_equals_dense_assembly() {
        for (seed, n, count) in [(1, 5, 4), (2, 20, 30), (3, 60, 200)] {
            let mut form = RandomBlocks::new(n, count, seed);
            let x = vec![0.0; n];
            let mut asm = FixedPatternAssembler::new(&form, &x).unwrap();
            asm.assemble(&form, &x).unwrap();
            let dense = dense_hessian(&form, &x).unwrap();
            assert_dense_eq(&asm.to_dense(), &dense, 1e-12);
            // Only the lower triangle is stored, rows sorted within each column.
            let m = asm.matrix();
            for c in 0..n {
                let rows = m.row_idx_of_col_raw(c);
                assert!(rows.windows(2).all(|w| w[0] < w[1]));
                assert!(rows.iter().all(|&r| r >= c));
            }
            // Numeric-only reassembly after the values changed.
            form.scale = -2.5;
            asm.assemble(&form, &x).unwrap();
            assert_dense_eq(&asm.to_dense(), &dense_hessian(&form, &x).unwrap(), 1e-12);
        }
    }

    #[test]
    fn random_blocks_hessian_matches_finite_differences() {
        // Guards the test form itself: its Hessian is the Jacobian of its gradient.
        use skintight_geometry::finite_difference::{FdParams, check_gradient, check_jacobian};
        let form = RandomBlocks::new(8, 6, 7);
        let mut rng = ChaCha8Rng::seed_from_u64(70);
        let x: Vec<Real> = (0..8).map(|_| rng.random_range(-1.0..1.0)).collect();
        let mut g = vec![0.0; 8];
        form.gradient(&x, &mut g).unwrap();
        let p = FdParams::default();
        check_gradient(|y| form.value(y).unwrap(), &x, &g, &p).unwrap();
        let grad = |y: &[Real]| {
            let mut out = vec![0.0; 8];
            form.gradient(y, &mut out).unwrap();
            out
        };
        check_jacobian(grad, &x, &dense_hessian(&form, &x).unwrap(), &p).unwrap();
    }

    #[test]
    fn diagonal_is_complete_and_regularizable() {
        let form = RandomBlocks {
            n: 4,
            blocks: vec![(vec![Some(2), None], vec![1.0, 5.0, 5.0, 7.0])],
            scale: 1.0,
        };
        let x = vec![0.0; 4];
        let mut asm = FixedPatternAssembler::new(&form, &x).unwrap();
        asm.assemble(&form, &x).unwrap();
        asm.add_to_diagonal(0.5);
        let d = asm.to_dense();
        assert_eq!(asm.nnz(), 4);
        assert_eq!([d[0], d[5], d[10], d[15]], [0.5, 0.5, 1.5, 0.5]);
    }

    #[test]
    fn changed_blocks_are_reported_as_pattern_mismatch() {
        let mut form = RandomBlocks::new(10, 5, 11);
        let x = vec![0.0; 10];
        let mut asm = FixedPatternAssembler::new(&form, &x).unwrap();
        form.blocks[3].0.reverse();
        form.blocks[3].0.push(Some(0));
        let m = form.blocks[3].0.len();
        form.blocks[3].1 = vec![0.0; m * m];
        let err = asm.assemble(&form, &x).unwrap_err();
        assert!(
            matches!(err, FormError::PatternMismatch { block: 3, .. }),
            "{err}"
        );
        form.blocks.pop();
        form.blocks.truncate(2);
        let err = asm.assemble(&form, &x).unwrap_err();
        assert!(
            matches!(err, FormError::PatternMismatch { block: 2, .. }),
            "{err}"
        );
    }
}
