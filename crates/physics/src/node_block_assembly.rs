//! Sparse Hessian assembly by node blocks, for element blocks too large to scatter entry by entry.
//!
//! A coupled cloth-on-body element touches the 2 surface coordinates of each of its three cloth corners and
//! the 3 coordinates of every body vertex in the corners' surface stencils — up to about 100 DOFs. Storing a
//! matrix slot for every entry of every element block would take hundreds of megabytes, so this assembler
//! works with **nodes**: groups of consecutive DOFs that always appear together (a cloth vertex's
//! `(s1, s2)`, a body vertex's `(x, y, z)`).
//!
//! 1. **Symbolic** ([`NodeBlockAssembler::new`]): from the node list of every element block, the pattern of
//!    the **lower triangle** (row ≥ column) is built in compressed-column form with sorted row indices; every
//!    pair of nodes that share an element gets, per column of the pair's column node, the value slot of its
//!    first row. Each element block stores one pair id per pair of its nodes (`m(m + 1)/2` integers for `m`
//!    nodes), never one slot per scalar entry.
//! 2. **Numeric** ([`NodeBlockAssembler::begin`], then the blocks through [`NodeHessianSink`], then [`NodeBlockAssembler::finish`]): each dense element block is added through its pair ids.
//!
//! The pattern holds as long as every element keeps its node list; [`NodeBlockAssembler::fit`] checks
//! this and reports a mismatch, after which the caller rebuilds the assembler (the coupled system does so
//! when a cloth vertex walks into a face with a different stencil).
//!
//! The matrix is a faer `SparseColMat<usize, f64>` holding the lower triangle, as the sparse Cholesky
//! expects.

use crate::math::Real;
use faer::sparse::{SparseColMat, SymbolicSparseColMat};

/// Pair id by `(column node id, row node id)`.
type PairIndex =
    std::collections::HashMap<(u32, u32), u32, std::hash::BuildHasherDefault<PairHasher>>;

/// A multiplicative hash for the small integer keys of [`PairIndex`] (the standard SipHash is several
/// times slower and its flooding resistance is not needed for node ids).
#[derive(Default)]
struct PairHasher(u64);

impl std::hash::Hasher for PairHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(b as u64);
        }
    }

    fn write_u32(&mut self, v: u32) {
        self.write_u64(v as u64);
    }

    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(29) ^ v).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    }
}

/// A group of `dim` consecutive DOFs `first_dof .. first_dof + dim` that enter element blocks together.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Node {
    /// Global index of the node's first DOF.
    pub first_dof: usize,
    /// Number of DOFs (1 to 3).
    pub dim: usize,
}

/// Receives dense symmetric element blocks over lists of nodes.
pub trait NodeHessianSink {
    /// Adds the symmetric `m × m` block `block` (row-major, `m = Σ dim`) whose rows and columns are the
    /// DOFs of `nodes` in order. Nodes within one block must be distinct.
    fn add_node_block(&mut self, nodes: &[Node], block: &[Real]);
}

/// Collects the node lists of element blocks (the symbolic pass).
#[derive(Clone, Debug, Default)]
pub struct NodeBlockRecorder {
    starts: Vec<usize>,
    nodes: Vec<Node>,
}

impl NodeBlockRecorder {
    /// Records one element block's node list.
    pub fn record(&mut self, nodes: &[Node]) {
        self.starts.push(self.nodes.len());
        self.nodes.extend_from_slice(nodes);
    }

    /// Number of recorded blocks.
    pub fn len(&self) -> usize {
        self.starts.len()
    }

    /// Whether no block was recorded.
    pub fn is_empty(&self) -> bool {
        self.starts.is_empty()
    }

    /// The recorded node lists, in order.
    pub fn lists(&self) -> impl Iterator<Item = &[Node]> {
        let ends = self
            .starts
            .iter()
            .skip(1)
            .copied()
            .chain(std::iter::once(self.nodes.len()));
        self.starts
            .iter()
            .zip(ends)
            .map(|(&start, end)| &self.nodes[start..end])
    }
}

impl NodeHessianSink for NodeBlockRecorder {
    fn add_node_block(&mut self, nodes: &[Node], _block: &[Real]) {
        self.record(nodes);
    }
}

/// Where a node pair `(row node A, column node B)`, `A.first_dof ≥ B.first_dof`, lives in the matrix.
#[derive(Clone, Copy, Debug)]
struct PairSlots {
    row: Node,
    col: Node,
    /// For column `j` of `B`: slot of the first stored row of `A` (row `A.first_dof`, or `A.first_dof + j`
    /// on a diagonal pair).
    first: [usize; 3],
}

/// A lower-triangle Hessian with a node-pair pattern; see the module documentation.
#[derive(Clone, Debug)]
pub struct NodeBlockAssembler {
    matrix: SparseColMat<usize, Real>,
    pairs: Vec<PairSlots>,
    /// Per element block: start of its node list in `block_nodes` and of its pair ids in `block_pairs`.
    block_starts: Vec<(usize, usize)>,
    block_nodes: Vec<Node>,
    /// Pair ids of each block's node pairs `(a, b)`, `a ≤ b`, row-major over the upper triangle.
    block_pairs: Vec<u32>,
    diagonal_slots: Vec<usize>,
    /// Pair id by `(column node id, row node id)`, for blocks whose node list changed.
    pair_index: PairIndex,
    /// Node id (index into the declared nodes) by first DOF; `u32::MAX` elsewhere.
    node_of_dof: Vec<u32>,
    /// Blocks of the current pass scattered through `pair_index` (their node list had changed).
    slow_blocks: usize,
    cursor: usize,
    mismatch: Option<usize>,
    /// Zeroed value buffers of merged shares (`#nnz` each), lent to the next pass's shares
    /// ([`Self::lend_buffers`]) so that a parallel assembly allocates, faults in and frees no
    /// `#nnz`-sized copy of the values per thread and pass.
    spare_values: Vec<Vec<Real>>,
}

impl NodeBlockAssembler {
    /// Builds the pattern for an `n × n` matrix from the recorded element blocks. `nodes` lists every node
    /// (a partition of `0..n`); their diagonal blocks are always stored, so `H + αD` can always be formed.
    ///
    /// # Panics
    /// If a node reaches past `n` or a block names a node that is not in `nodes` (a programming error of
    /// the caller).
    pub fn new(n: usize, nodes: &[Node], recorded: &NodeBlockRecorder) -> Self {
        Self::with_union(n, nodes, recorded, None)
    }

    /// Like [`Self::new`], but the pattern also keeps every node pair of `previous` (built over the same
    /// `nodes`): patterns rebuilt this way only grow, so after a few changes of the element node lists the
    /// matrix pattern — and with it the symbolic factorization — stops changing.
    pub fn with_union(
        n: usize,
        nodes: &[Node],
        recorded: &NodeBlockRecorder,
        previous: Option<&NodeBlockAssembler>,
    ) -> Self {
        Self::with_reserve(n, nodes, recorded, None, previous)
    }

    /// Like [`Self::with_union`], and the pattern also holds every node pair of the blocks in `reserve`
    /// (which are not scattered: only `recorded` says what the numeric passes will add). A caller that
    /// knows where its blocks' node lists may go next — a cloth vertex sliding into a neighbouring face —
    /// reserves those pairs now, so the pattern and its symbolic factorization survive the move.
    pub fn with_reserve(
        n: usize,
        nodes: &[Node],
        recorded: &NodeBlockRecorder,
        reserve: Option<&NodeBlockRecorder>,
        previous: Option<&NodeBlockAssembler>,
    ) -> Self {
        // Node id by first DOF.
        let mut node_of_dof = vec![u32::MAX; n];
        for (k, node) in nodes.iter().enumerate() {
            assert!(
                node.first_dof + node.dim <= n && (1..=3).contains(&node.dim),
                "node {node:?} out of range for {n} DOFs"
            );
            node_of_dof[node.first_dof] = k as u32;
        }
        let id = |node: &Node| -> u32 {
            let k = node_of_dof[node.first_dof];
            assert!(k != u32::MAX, "block node {node:?} is not a declared node");
            k
        };
        // All node pairs (row id, col id) with row.first ≥ col.first.
        let mut keys: Vec<(u32, u32)> = (0..nodes.len() as u32).map(|k| (k, k)).collect();
        if let Some(prev) = previous {
            keys.extend(prev.pair_index.keys().copied());
        }
        for list in recorded
            .lists()
            .chain(reserve.into_iter().flat_map(|r| r.lists()))
        {
            for (i, u) in list.iter().enumerate() {
                for v in &list[i + 1..] {
                    let (r, c) = if u.first_dof >= v.first_dof {
                        (u, v)
                    } else {
                        (v, u)
                    };
                    keys.push((id(c), id(r)));
                }
            }
        }
        // Sort by (column node's first DOF, row node's first DOF): by the ids themselves when the nodes are
        // declared in DOF order (the usual case, and much faster as one 64-bit key).
        if nodes.windows(2).all(|w| w[0].first_dof < w[1].first_dof) {
            let mut packed: Vec<u64> = keys
                .iter()
                .map(|&(c, r)| ((c as u64) << 32) | r as u64)
                .collect();
            packed.sort_unstable();
            packed.dedup();
            keys = packed
                .into_iter()
                .map(|k| ((k >> 32) as u32, k as u32))
                .collect();
        } else {
            keys.sort_unstable_by_key(|&(c, r)| {
                (nodes[c as usize].first_dof, nodes[r as usize].first_dof)
            });
            keys.dedup();
        }

        let mut assembler = Self::from_sorted_keys(n, nodes, node_of_dof, &keys);
        let fitted = assembler.refit(recorded);
        debug_assert!(fitted, "the pattern holds every recorded pair");
        assembler
    }

    /// The pattern of the node pairs `keys` (`(column node id, row node id)`, sorted by the nodes' first
    /// DOFs, no duplicates, every diagonal pair included), with no element block recorded yet.
    fn from_sorted_keys(
        n: usize,
        nodes: &[Node],
        node_of_dof: Vec<u32>,
        keys: &[(u32, u32)],
    ) -> Self {
        // Column counts, then pointers.
        let mut col_ptr = vec![0usize; n + 1];
        for &(c, r) in keys {
            let (cn, rn) = (nodes[c as usize], nodes[r as usize]);
            for j in 0..cn.dim {
                col_ptr[cn.first_dof + j + 1] += if c == r { cn.dim - j } else { rn.dim };
            }
        }
        for c in 0..n {
            col_ptr[c + 1] += col_ptr[c];
        }
        let nnz = col_ptr[n];
        let mut row_idx = vec![0usize; nnz];
        let mut fill = col_ptr.clone();
        let mut pair_of_key: PairIndex =
            PairIndex::with_capacity_and_hasher(keys.len(), Default::default());
        let mut pairs = Vec::with_capacity(keys.len());
        for &(c, r) in keys {
            let (cn, rn) = (nodes[c as usize], nodes[r as usize]);
            let mut first = [0usize; 3];
            for j in 0..cn.dim {
                let col = cn.first_dof + j;
                first[j] = fill[col];
                let rows = if c == r {
                    (cn.first_dof + j)..(cn.first_dof + cn.dim)
                } else {
                    rn.first_dof..(rn.first_dof + rn.dim)
                };
                for row in rows {
                    row_idx[fill[col]] = row;
                    fill[col] += 1;
                }
            }
            pair_of_key.insert((c, r), pairs.len() as u32);
            pairs.push(PairSlots {
                row: rn,
                col: cn,
                first,
            });
        }
        let mut diagonal_slots = vec![usize::MAX; n];
        for p in &pairs {
            if p.row == p.col {
                for j in 0..p.col.dim {
                    diagonal_slots[p.col.first_dof + j] = p.first[j];
                }
            }
        }
        let symbolic = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
        Self {
            matrix: SparseColMat::new(symbolic, vec![0.0; nnz]),
            pair_index: pair_of_key,
            node_of_dof,
            slow_blocks: 0,
            pairs,
            block_starts: Vec::new(),
            block_nodes: Vec::new(),
            block_pairs: Vec::new(),
            diagonal_slots,
            cursor: 0,
            mismatch: None,
            spare_values: Vec::new(),
        }
    }

    /// Grows the pattern in place to hold the node pairs of `recorded` that it lacks and every pair of
    /// `reserve` (see [`Self::with_reserve`]), keeping all of its pairs, and takes `recorded` as the
    /// blocks' node lists (as [`Self::refit`]). Cheaper than a rebuild with [`Self::with_reserve`] when
    /// few blocks moved out: only their pairs are looked up and sorted, the others' pair ids are renumbered.
    /// Returns whether the pattern changed.
    ///
    /// # Panics
    /// If a block names a node that is not declared (a programming error of the caller).
    pub fn grow(
        &mut self,
        recorded: &NodeBlockRecorder,
        reserve: Option<&NodeBlockRecorder>,
    ) -> bool {
        let id = |node: &Node| -> u32 {
            let k = self
                .node_of_dof
                .get(node.first_dof)
                .copied()
                .unwrap_or(u32::MAX);
            assert!(k != u32::MAX, "block node {node:?} is not a declared node");
            k
        };
        let mut missing: Vec<(u32, u32)> = Vec::new();
        let mut ids = Vec::new();
        let lists = recorded
            .lists()
            .enumerate()
            .filter(|&(b, list)| !self.holds(b, list, &mut ids))
            .map(|(_, list)| list)
            .chain(reserve.into_iter().flat_map(|r| r.lists()));
        for list in lists {
            for (i, u) in list.iter().enumerate() {
                for v in &list[i + 1..] {
                    let (r, c) = if u.first_dof >= v.first_dof {
                        (u, v)
                    } else {
                        (v, u)
                    };
                    let key = (id(c), id(r));
                    if !self.pair_index.contains_key(&key) {
                        missing.push(key);
                    }
                }
            }
        }
        if missing.is_empty() {
            let fitted = self.refit(recorded);
            debug_assert!(fitted, "no pair is missing");
            return false;
        }
        let nodes: Vec<Node> = {
            let mut by_id = vec![
                Node {
                    first_dof: 0,
                    dim: 0
                };
                self.node_count()
            ];
            for p in &self.pairs {
                by_id[id(&p.col) as usize] = p.col;
                by_id[id(&p.row) as usize] = p.row;
            }
            by_id
        };
        let order =
            |&(c, r): &(u32, u32)| (nodes[c as usize].first_dof, nodes[r as usize].first_dof);
        missing.sort_unstable_by_key(order);
        missing.dedup();
        // Merge with the current pairs (already in order), remembering where each old pair goes.
        let old: Vec<(u32, u32)> = self
            .pairs
            .iter()
            .map(|p| (id(&p.col), id(&p.row)))
            .collect();
        let mut keys = Vec::with_capacity(old.len() + missing.len());
        let mut renumber = Vec::with_capacity(old.len());
        let (mut i, mut j) = (0, 0);
        while i < old.len() || j < missing.len() {
            let take_old =
                j == missing.len() || (i < old.len() && order(&old[i]) < order(&missing[j]));
            if take_old {
                renumber.push(keys.len() as u32);
                keys.push(old[i]);
                i += 1;
            } else {
                keys.push(missing[j]);
                j += 1;
            }
        }
        let n = self.size();
        let node_of_dof = std::mem::take(&mut self.node_of_dof);
        let mut grown = Self::from_sorted_keys(n, &nodes, node_of_dof, &keys);
        // Blocks whose node list is unchanged keep their pairs, renumbered; the others are looked up.
        let mut block_starts = Vec::with_capacity(recorded.len());
        let mut block_pairs = Vec::with_capacity(self.block_pairs.len());
        for (b, (&start, list)) in recorded.starts.iter().zip(recorded.lists()).enumerate() {
            block_starts.push((start, block_pairs.len()));
            match self.recorded_block(b) {
                Some((same, old_ids)) if same == list => {
                    block_pairs.extend(old_ids.iter().map(|&p| renumber[p as usize]));
                }
                _ => {
                    let fitted = grown.pair_ids(list, &mut ids);
                    debug_assert!(fitted, "the grown pattern holds every recorded pair");
                    block_pairs.extend_from_slice(&ids);
                }
            }
        }
        grown.block_starts = block_starts;
        grown.block_pairs = block_pairs;
        grown.block_nodes = recorded.nodes.clone();
        *self = grown;
        true
    }

    /// Takes `recorded` as the blocks' node lists, in the pattern as it is while it holds them and grown
    /// when it does not: when every pair lies in the pattern, the fast scatter path is refitted if more
    /// than a tenth of the lists changed (fewer are looked up pair by pair as they are scattered); when
    /// some pair is outside, the pattern grows ([`Self::grow`]) by those pairs and by every pair of
    /// `reserve(outside)`, the slack the caller reserves for the blocks outside (their indices), so that
    /// it settles after a few growths. Returns whether the pattern grew (and must be analysed again,
    /// [`crate::newton::PatternCache::fit`]).
    pub fn fit_or_grow(
        &mut self,
        recorded: &NodeBlockRecorder,
        reserve: impl FnOnce(&[usize]) -> NodeBlockRecorder,
    ) -> bool {
        let grow = match self.fit(recorded) {
            Some(changed) if changed * 10 <= self.num_blocks() => false,
            Some(_) => !self.refit(recorded),
            None => true,
        };
        if !grow {
            return false;
        }
        let outside = self.outside_blocks(recorded);
        let reserve = reserve(&outside);
        self.grow(recorded, Some(&reserve))
    }

    /// Whether the pattern holds every node pair of `list`, the node list of block `b`: at once when it is
    /// the list recorded for `b`, else by looking its pairs up (`ids` is scratch).
    fn holds(&self, b: usize, list: &[Node], ids: &mut Vec<u32>) -> bool {
        matches!(self.recorded_block(b), Some((same, _)) if same == list)
            || self.pair_ids(list, ids)
    }

    /// Number of declared nodes.
    fn node_count(&self) -> usize {
        self.node_of_dof.iter().filter(|&&k| k != u32::MAX).count()
    }

    /// Takes `recorded` as the element blocks' node lists of the next numeric passes (their fast scatter
    /// path), keeping the matrix pattern: `false`, and nothing changed, if some node pair of `recorded` is
    /// outside the pattern (rebuild with [`Self::with_reserve`] then). Cheaper than a rebuild when many
    /// lists changed within the pattern.
    pub fn refit(&mut self, recorded: &NodeBlockRecorder) -> bool {
        let mut block_starts = Vec::with_capacity(recorded.len());
        let mut block_pairs = Vec::with_capacity(self.block_pairs.len());
        let mut ids = Vec::new();
        for (&start, list) in recorded.starts.iter().zip(recorded.lists()) {
            block_starts.push((start, block_pairs.len()));
            if !self.pair_ids(list, &mut ids) {
                return false;
            }
            block_pairs.extend_from_slice(&ids);
        }
        self.block_starts = block_starts;
        self.block_pairs = block_pairs;
        self.block_nodes = recorded.nodes.clone();
        true
    }

    /// Matrix size `n`.
    pub fn size(&self) -> usize {
        self.diagonal_slots.len()
    }

    /// Number of stored (lower-triangle) entries.
    pub fn nnz(&self) -> usize {
        self.matrix.val().len()
    }

    /// Zeroes the values and starts a new numeric pass; call before the element blocks are scattered.
    pub fn begin(&mut self) {
        self.matrix.val_mut().fill(0.0);
        self.cursor = 0;
        self.mismatch = None;
        self.slow_blocks = 0;
    }

    /// Blocks of the current pass whose node list differed from the recorded one but whose node pairs are
    /// all in the pattern: they were scattered correctly, through a hash lookup per pair. Rebuild (with
    /// [`Self::with_union`]) when there are many, to get the fast path back.
    pub fn slow_blocks(&self) -> usize {
        self.slow_blocks
    }

    /// How the blocks of `recorded` fit this pattern: `None` if some node pair is outside it (rebuild with
    /// [`Self::with_union`] and analyse the new pattern), else the number of blocks whose node list differs
    /// from the one recorded here (they are scattered by lookup; rebuild when there are many).
    pub fn fit(&self, recorded: &NodeBlockRecorder) -> Option<usize> {
        let mut changed = 0;
        let mut ids = Vec::new();
        for (b, &start) in recorded.starts.iter().enumerate() {
            let end = recorded
                .starts
                .get(b + 1)
                .copied()
                .unwrap_or(recorded.nodes.len());
            let list = &recorded.nodes[start..end];
            let same = self.block_starts.get(b).is_some_and(|&(node_start, _)| {
                let node_end = self
                    .block_starts
                    .get(b + 1)
                    .map_or(self.block_nodes.len(), |s| s.0);
                self.block_nodes[node_start..node_end] == *list
            });
            if same {
                continue;
            }
            changed += 1;
            if !self.pair_ids(list, &mut ids) {
                return None;
            }
        }
        Some(changed)
    }

    /// The blocks of `recorded` (by index) with a node pair outside the pattern.
    pub fn outside_blocks(&self, recorded: &NodeBlockRecorder) -> Vec<usize> {
        let mut ids = Vec::new();
        recorded
            .lists()
            .enumerate()
            .filter(|&(b, list)| !self.holds(b, list, &mut ids))
            .map(|(b, _)| b)
            .collect()
    }

    /// Number of element blocks recorded.
    pub fn num_blocks(&self) -> usize {
        self.block_starts.len()
    }

    /// Scatters a block whose node list is not the recorded one, looking each node pair up; `false` if a
    /// pair is not in the pattern (nothing is added then).
    fn scatter_by_lookup(&mut self, nodes: &[Node], block: &[Real]) -> bool {
        let mut ids = Vec::with_capacity(nodes.len() * (nodes.len() + 1) / 2);
        if !self.pair_ids(nodes, &mut ids) {
            return false;
        }
        self.scatter_with(nodes, block, &ids);
        true
    }

    /// The pair ids of the node pairs `(a, b)`, `a ≤ b`, of `nodes` into `out` (cleared first), in the
    /// order [`Self::scatter_with`] reads them; `false` if a pair is not in the pattern.
    fn pair_ids(&self, nodes: &[Node], out: &mut Vec<u32>) -> bool {
        out.clear();
        let id = |n: &Node| {
            self.node_of_dof
                .get(n.first_dof)
                .copied()
                .unwrap_or(u32::MAX)
        };
        for (i, u) in nodes.iter().enumerate() {
            for v in &nodes[i..] {
                let (r, c) = if u.first_dof >= v.first_dof {
                    (u, v)
                } else {
                    (v, u)
                };
                match self.pair_index.get(&(id(c), id(r))) {
                    Some(&p) => out.push(p),
                    None => return false,
                }
            }
        }
        true
    }

    fn scatter_with(&mut self, nodes: &[Node], block: &[Real], pair_ids: &[u32]) {
        let values = self.matrix.val_mut();
        scatter_values(&self.pairs, values, nodes, block, pair_ids);
    }

    /// The recorded node list and pair ids of block `b`, if it was recorded.
    fn recorded_block(&self, b: usize) -> Option<(&[Node], &[u32])> {
        let &(node_start, pair_start) = self.block_starts.get(b)?;
        let node_end = self
            .block_starts
            .get(b + 1)
            .map_or(self.block_nodes.len(), |s| s.0);
        let list = &self.block_nodes[node_start..node_end];
        let count = list.len() * (list.len() + 1) / 2;
        Some((list, &self.block_pairs[pair_start..pair_start + count]))
    }

    /// `count` zeroed value buffers (`#nnz` each) for [`Self::share_in`]: the ones the last
    /// [`Self::merge`] gave back, allocated only where there are too few or the pattern grew.
    pub fn lend_buffers(&mut self, count: usize) -> Vec<Vec<Real>> {
        let nnz = self.nnz();
        (0..count)
            .map(|_| match self.spare_values.pop() {
                Some(values) if values.len() == nnz => values,
                _ => vec![0.0; nnz],
            })
            .collect()
    }

    /// A share of the next numeric pass for one thread (see [`AssemblyShare`]), scattering into `values`,
    /// a buffer lent by [`Self::lend_buffers`] (zeroed, `#nnz` long).
    ///
    /// # Panics
    /// If `values` is not `#nnz` long (a programming error of the caller).
    pub fn share_in(&self, values: Vec<Real>) -> AssemblyShare<'_> {
        assert_eq!(
            values.len(),
            self.nnz(),
            "a share's buffer holds every value"
        );
        AssemblyShare {
            assembler: self,
            part: AssemblyPart {
                values,
                blocks: 0,
                slow_blocks: 0,
                mismatch: None,
            },
            ids: Vec::new(),
        }
    }

    /// Adds the shares' blocks to the current pass (after [`Self::begin`]): their values, their count
    /// (as if they had been added one by one through [`NodeHessianSink`]) and their slow or mismatched
    /// blocks.
    pub fn merge(&mut self, parts: Vec<AssemblyPart>) {
        let values = self.matrix.val_mut();
        for mut part in parts {
            // Each buffer is zeroed as it is read, and kept for the next pass's shares.
            for (v, p) in values.iter_mut().zip(&mut part.values) {
                *v += *p;
                *p = 0.0;
            }
            if part.values.len() == values.len() {
                self.spare_values.push(part.values);
            }
            self.cursor += part.blocks;
            self.slow_blocks += part.slow_blocks;
            self.mismatch = match (self.mismatch, part.mismatch) {
                (Some(a), Some(b)) => Some(a.min(b)),
                (a, b) => a.or(b),
            };
        }
    }
}

/// One thread's share of a numeric pass: element blocks are added by their index in the pass (the order
/// in which a sequential pass would add them) into a private copy of the values, then
/// [`NodeBlockAssembler::merge`]d. Blocks may come in any order and from any number of shares, as long as
/// every index of the pass is added exactly once.
pub struct AssemblyShare<'a> {
    assembler: &'a NodeBlockAssembler,
    part: AssemblyPart,
    ids: Vec<u32>,
}

/// What an [`AssemblyShare`] assembled, to [`NodeBlockAssembler::merge`].
#[derive(Debug)]
pub struct AssemblyPart {
    values: Vec<Real>,
    blocks: usize,
    slow_blocks: usize,
    mismatch: Option<usize>,
}

impl AssemblyShare<'_> {
    /// Adds block number `b` of the pass (nodes and values as for
    /// [`NodeHessianSink::add_node_block`]).
    pub fn add(&mut self, b: usize, nodes: &[Node], block: &[Real]) {
        let a = self.assembler;
        self.part.blocks += 1;
        if let Some((list, ids)) = a.recorded_block(b)
            && list == nodes
        {
            scatter_values(&a.pairs, &mut self.part.values, nodes, block, ids);
        } else if a.pair_ids(nodes, &mut self.ids) {
            scatter_values(&a.pairs, &mut self.part.values, nodes, block, &self.ids);
            self.part.slow_blocks += 1;
        } else {
            self.part.mismatch = Some(self.part.mismatch.map_or(b, |m| m.min(b)));
        }
    }

    /// Adds block number `b` of the pass by writing its node-pair blocks straight into the values
    /// (`write` gets a [`BlockSlots`] over `nodes`), without forming the dense block — when `nodes` is the
    /// list recorded for `b`. Otherwise nothing is added and `false` is returned: add the dense block with
    /// [`Self::add`] then.
    pub fn add_direct(
        &mut self,
        b: usize,
        nodes: &[Node],
        write: impl FnOnce(&mut BlockSlots<'_>),
    ) -> bool {
        let a = self.assembler;
        match a.recorded_block(b) {
            Some((list, ids)) if list == nodes => {
                self.part.blocks += 1;
                write(&mut BlockSlots {
                    pairs: &a.pairs,
                    ids,
                    nodes,
                    values: &mut self.part.values,
                });
                true
            }
            _ => false,
        }
    }

    /// The assembled share.
    pub fn into_part(self) -> AssemblyPart {
        self.part
    }
}

/// The value slots of one recorded element block, to add its node-pair blocks directly (see
/// [`AssemblyShare::add_direct`]).
pub struct BlockSlots<'a> {
    pairs: &'a [PairSlots],
    ids: &'a [u32],
    nodes: &'a [Node],
    values: &'a mut [Real],
}

impl BlockSlots<'_> {
    /// Adds the block `h` (row-major, `nodes[i].dim × nodes[j].dim`) of the node pair `(i, j)`, `i ≤ j`
    /// positions in the block's node list. For `i = j` only its lower triangle is read (the block is
    /// symmetric).
    #[inline]
    pub fn add(&mut self, i: usize, j: usize, h: &[Real]) {
        debug_assert!(i <= j && j < self.nodes.len());
        let len = self.nodes.len();
        // Pair ids run row-major over the upper triangle of the node list.
        let k = i * len - i * i.saturating_sub(1) / 2 + (j - i);
        let p = &self.pairs[self.ids[k] as usize];
        let (u, v) = (self.nodes[i], self.nodes[j]);
        if i == j {
            for c in 0..u.dim {
                for r in c..u.dim {
                    self.values[p.first[c] + r - c] += h[r * u.dim + c];
                }
            }
        } else if u.first_dof >= v.first_dof {
            // Rows of node i, columns of node j.
            for c in 0..v.dim {
                for r in 0..u.dim {
                    self.values[p.first[c] + r] += h[r * v.dim + c];
                }
            }
        } else {
            // Rows of node j, columns of node i: the transpose.
            for c in 0..u.dim {
                for r in 0..v.dim {
                    self.values[p.first[c] + r] += h[c * v.dim + r];
                }
            }
        }
    }
}

/// Adds the upper node pairs of the dense block `block` over `nodes` into `values` at the slots of
/// `pair_ids` (in the order of [`NodeBlockAssembler::pair_ids`]).
fn scatter_values(
    pairs: &[PairSlots],
    values: &mut [Real],
    nodes: &[Node],
    block: &[Real],
    pair_ids: &[u32],
) {
    {
        let m: usize = nodes.iter().map(|n| n.dim).sum();
        debug_assert_eq!(block.len(), m * m);
        let mut k = 0;
        let mut off_u = 0;
        for (i, u) in nodes.iter().enumerate() {
            let mut off_v = off_u;
            for (j_node, v) in nodes.iter().enumerate().skip(i) {
                let p = &pairs[pair_ids[k] as usize];
                k += 1;
                if j_node == i {
                    // Diagonal node block: lower triangle only.
                    for j in 0..u.dim {
                        for r in j..u.dim {
                            values[p.first[j] + r - j] += block[(off_u + r) * m + off_u + j];
                        }
                    }
                } else {
                    // Rows of the pair's row node, columns of its column node.
                    let (off_r, off_c) = if u.first_dof >= v.first_dof {
                        (off_u, off_v)
                    } else {
                        (off_v, off_u)
                    };
                    for j in 0..p.col.dim {
                        for r in 0..p.row.dim {
                            values[p.first[j] + r] += block[(off_r + r) * m + off_c + j];
                        }
                    }
                }
                off_v += v.dim;
            }
            off_u += u.dim;
        }
    }
}

impl NodeBlockAssembler {
    /// Ends the numeric pass: `Err(block)` with the first element block that has a node pair outside the
    /// pattern; the matrix is then incomplete and the assembler must be rebuilt (see [`Self::with_union`]).
    /// Blocks whose node list changed but whose pairs are all in the pattern are fine (see
    /// [`Self::slow_blocks`]).
    pub fn finish(&self) -> Result<&SparseColMat<usize, Real>, usize> {
        if let Some(b) = self.mismatch {
            return Err(b);
        }
        Ok(&self.matrix)
    }

    /// The matrix (lower triangle, sorted row indices per column).
    pub fn matrix(&self) -> &SparseColMat<usize, Real> {
        &self.matrix
    }

    /// Adds `d[i]` to each diagonal entry `(i, i)` (`d.len() = n`), e.g. the damping `α D`.
    pub fn add_diagonal(&mut self, d: &[Real]) {
        let values = self.matrix.val_mut();
        for (&s, &di) in self.diagonal_slots.iter().zip(d) {
            values[s] += di;
        }
    }

    /// Lends `f` the matrix with `α d[i]` added to each diagonal entry `(i, i)` (`d.len() = n`; e.g. the
    /// damped Newton matrix `H + α D`), then puts the diagonal back as it was, to the bit — an add and a
    /// subtract would leave `H` changed by rounding after every damped factorization. `saved` holds the
    /// diagonal meanwhile (no allocation once it has had `n` entries).
    pub fn with_shifted_diagonal<R>(
        &mut self,
        alpha: Real,
        d: &[Real],
        saved: &mut Vec<Real>,
        f: impl FnOnce(&SparseColMat<usize, Real>) -> R,
    ) -> R {
        let values = self.matrix.val_mut();
        saved.clear();
        saved.extend(self.diagonal_slots.iter().map(|&s| values[s]));
        for (&s, &di) in self.diagonal_slots.iter().zip(d) {
            values[s] += alpha * di;
        }
        let result = f(&self.matrix);
        let values = self.matrix.val_mut();
        for (&s, &v) in self.diagonal_slots.iter().zip(saved.iter()) {
            values[s] = v;
        }
        result
    }

    /// Value slot of each diagonal entry `(i, i)` in `matrix().val()`.
    pub fn diagonal_slots(&self) -> &[usize] {
        &self.diagonal_slots
    }

    /// The full symmetric matrix as dense row-major `n × n` (tests, small problems).
    pub fn to_dense(&self) -> Vec<Real> {
        let n = self.size();
        let mut dense = vec![0.0; n * n];
        let m = &self.matrix;
        let (col_ptr, row_idx, val) = (m.symbolic().col_ptr(), m.symbolic().row_idx(), m.val());
        for c in 0..n {
            for k in col_ptr[c]..col_ptr[c + 1] {
                let r = row_idx[k];
                dense[r * n + c] = val[k];
                dense[c * n + r] = val[k];
            }
        }
        dense
    }
}

impl NodeHessianSink for NodeBlockAssembler {
    fn add_node_block(&mut self, nodes: &[Node], block: &[Real]) {
        let b = self.cursor;
        self.cursor += 1;
        if self.mismatch.is_some() {
            return;
        }
        let recorded = self.block_starts.get(b).map(|&(node_start, pair_start)| {
            let node_end = self
                .block_starts
                .get(b + 1)
                .map_or(self.block_nodes.len(), |s| s.0);
            (node_start, node_end, pair_start)
        });
        if let Some((node_start, node_end, pair_start)) = recorded
            && self.block_nodes[node_start..node_end] == *nodes
        {
            let count = nodes.len() * (nodes.len() + 1) / 2;
            let ids = std::mem::take(&mut self.block_pairs);
            self.scatter_with(nodes, block, &ids[pair_start..pair_start + count]);
            self.block_pairs = ids;
            return;
        }
        if self.scatter_by_lookup(nodes, block) {
            self.slow_blocks += 1;
        } else {
            self.mismatch = Some(b);
        }
    }
}

/// A Hessian as an unsorted list of `(row, column, value)` triplets covering both triangles, from node
/// blocks; duplicates add up. The dense reference of the tests.
#[cfg(test)]
#[derive(Clone, Debug, Default)]
pub(crate) struct HessianTriplets {
    /// Matrix size `n` (rows = columns).
    pub size: usize,
    /// Entries `(row, column, value)`, both triangles, duplicates allowed.
    pub entries: Vec<(usize, usize, Real)>,
}

#[cfg(test)]
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

#[cfg(test)]
impl NodeHessianSink for HessianTriplets {
    fn add_node_block(&mut self, nodes: &[Node], block: &[Real]) {
        let dofs: Vec<usize> = nodes
            .iter()
            .flat_map(|n| (0..n.dim).map(move |j| n.first_dof + j))
            .collect();
        let m = dofs.len();
        debug_assert_eq!(block.len(), m * m, "block must be m × m");
        for (a, &ga) in dofs.iter().enumerate() {
            for (b, &gb) in dofs.iter().enumerate() {
                self.entries.push((ga, gb, block[a * m + b]));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The block of `list` reversed node by node.
    fn reversed(list: &[Node], block: &[Real]) -> (Vec<Node>, Vec<Real>) {
        let m: usize = list.iter().map(|n| n.dim).sum();
        let mut offsets = Vec::new();
        let mut o = 0;
        for n in list {
            offsets.push(o);
            o += n.dim;
        }
        // Local DOF order after reversal.
        let order: Vec<usize> = (0..list.len())
            .rev()
            .flat_map(|k| (0..list[k].dim).map(move |j| (k, j)))
            .map(|(k, j)| offsets[k] + j)
            .collect();
        let mut out = vec![0.0; m * m];
        for (a, &oa) in order.iter().enumerate() {
            for (b, &ob) in order.iter().enumerate() {
                out[a * m + b] = block[oa * m + ob];
            }
        }
        (list.iter().rev().copied().collect(), out)
    }

    /// Random node lists over `nodes` with random symmetric blocks.
    fn random_blocks(
        rng: &mut ChaCha8Rng,
        nodes: &[Node],
        count: usize,
    ) -> Vec<(Vec<Node>, Vec<Real>)> {
        let num_nodes = nodes.len();
        (0..count)
            .map(|_| {
                let k = rng.random_range(1..=num_nodes.min(6));
                let mut ids: Vec<usize> = (0..num_nodes).collect();
                for i in 0..k {
                    let j = rng.random_range(i..num_nodes);
                    ids.swap(i, j);
                }
                let list: Vec<Node> = ids[..k].iter().map(|&i| nodes[i]).collect();
                let m: usize = list.iter().map(|n| n.dim).sum();
                let mut block = vec![0.0; m * m];
                for a in 0..m {
                    for b in 0..=a {
                        let v = rng.random_range(-1.0..1.0);
                        block[a * m + b] = v;
                        block[b * m + a] = v;
                    }
                }
                (list, block)
            })
            .collect()
    }

    /// Growing the pattern in place (the equilibrium solver's path when cloth vertices slide out of it)
    /// gives exactly the pattern of a rebuild with the old one as `previous`, scatters every recorded
    /// block on the fast path, and assembles the same matrix; nothing changes when nothing is missing.
    #[test]
    fn growing_in_place_matches_a_rebuild() {
        for (seed, num_nodes) in [(11u64, 6usize), (12, 20), (13, 60)] {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let mut nodes = Vec::new();
            let mut n = 0;
            for _ in 0..num_nodes {
                let dim = rng.random_range(1..=3);
                nodes.push(Node { first_dof: n, dim });
                n += dim;
            }
            let first = random_blocks(&mut rng, &nodes, num_nodes);
            let mut recorder = NodeBlockRecorder::default();
            for (list, _) in &first {
                recorder.record(list);
            }
            let asm = NodeBlockAssembler::new(n, &nodes, &recorder);

            // Half the blocks move to new node lists; some extra lists are reserved.
            let mut moved = first.clone();
            let fresh = random_blocks(&mut rng, &nodes, num_nodes);
            for (k, b) in fresh.into_iter().enumerate() {
                if k % 2 == 0 {
                    moved[k] = b;
                }
            }
            let mut moved_recorder = NodeBlockRecorder::default();
            for (list, _) in &moved {
                moved_recorder.record(list);
            }
            let mut reserve = NodeBlockRecorder::default();
            for (list, _) in random_blocks(&mut rng, &nodes, 3) {
                reserve.record(&list);
            }

            let mut grown = asm.clone();
            let changed = grown.grow(&moved_recorder, Some(&reserve));
            let rebuilt = NodeBlockAssembler::with_reserve(
                n,
                &nodes,
                &moved_recorder,
                Some(&reserve),
                Some(&asm),
            );
            assert_eq!(changed, rebuilt.nnz() != asm.nnz());
            let (a, b) = (grown.matrix().symbolic(), rebuilt.matrix().symbolic());
            assert_eq!(a.col_ptr(), b.col_ptr());
            assert_eq!(a.row_idx(), b.row_idx());
            assert_eq!(grown.diagonal_slots(), rebuilt.diagonal_slots());

            let mut assembled = Vec::new();
            for mut target in [grown.clone(), rebuilt] {
                target.begin();
                for (list, block) in &moved {
                    target.add_node_block(list, block);
                }
                assert!(target.finish().is_ok());
                assert_eq!(
                    target.slow_blocks(),
                    0,
                    "every recorded block takes the fast path"
                );
                assembled.push(target.to_dense());
            }
            assert_eq!(assembled[0], assembled[1]);

            // Growing again with the same lists adds nothing.
            let before = grown.nnz();
            assert!(!grown.grow(&moved_recorder, Some(&reserve)));
            assert_eq!(grown.nnz(), before);
        }
    }

    /// Shares split a pass's blocks across buffers and merge to the sequential pass's matrix; the merged
    /// buffers are lent to the next pass zeroed (the same allocations: no `#nnz` copy is allocated per
    /// pass), so consecutive passes give the same matrix to the bit.
    #[test]
    fn merged_share_buffers_are_lent_again_zeroed() {
        let mut rng = ChaCha8Rng::seed_from_u64(21);
        let nodes: Vec<Node> = (0..12)
            .map(|i| Node {
                first_dof: 2 * i,
                dim: 2,
            })
            .collect();
        let blocks = random_blocks(&mut rng, &nodes, 30);
        let mut recorder = NodeBlockRecorder::default();
        for (list, _) in &blocks {
            recorder.record(list);
        }
        let mut asm = NodeBlockAssembler::new(24, &nodes, &recorder);
        asm.begin();
        for (list, block) in &blocks {
            asm.add_node_block(list, block);
        }
        let sequential = asm.matrix().val().to_vec();
        let mut lent_before: Option<Vec<*const Real>> = None;
        let mut first_pass: Option<Vec<Real>> = None;
        for _ in 0..3 {
            let buffers = asm.lend_buffers(2);
            assert!(
                buffers
                    .iter()
                    .all(|b| b.len() == asm.nnz() && b.iter().all(|&v| v == 0.0))
            );
            let pointers: Vec<*const Real> = buffers.iter().map(|b| b.as_ptr()).collect();
            if let Some(before) = &lent_before {
                let mut sorted = pointers.clone();
                sorted.sort();
                assert_eq!(&sorted, before, "the merged buffers, not new ones");
            }
            asm.begin();
            let mut parts = Vec::new();
            for (k, values) in buffers.into_iter().enumerate() {
                let mut share = asm.share_in(values);
                for (b, (list, block)) in blocks.iter().enumerate().filter(|(b, _)| b % 2 == k) {
                    share.add(b, list, block);
                }
                parts.push(share.into_part());
            }
            asm.merge(parts);
            assert!(asm.finish().is_ok());
            for (a, b) in asm.matrix().val().iter().zip(&sequential) {
                assert!((a - b).abs() <= 1e-12 * (1.0 + b.abs()), "{a} vs {b}");
            }
            match &first_pass {
                None => first_pass = Some(asm.matrix().val().to_vec()),
                Some(v) => assert_eq!(v.as_slice(), asm.matrix().val()),
            }
            let mut sorted = pointers;
            sorted.sort();
            lent_before = Some(sorted);
        }
    }

    /// Random symmetric blocks over random node subsets assemble to the same matrix as plain triplets, and
    /// a changed node list is reported as a mismatch.
    #[test]
    fn node_blocks_match_triplet_assembly_at_several_sizes() {
        for (seed, num_nodes) in [(1u64, 3usize), (2, 10), (3, 40)] {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let mut nodes = Vec::new();
            let mut n = 0;
            for _ in 0..num_nodes {
                let dim = rng.random_range(1..=3);
                nodes.push(Node { first_dof: n, dim });
                n += dim;
            }
            let mut blocks = Vec::new();
            for _ in 0..3 * num_nodes {
                let k = rng.random_range(1..=num_nodes.min(6));
                let mut ids: Vec<usize> = (0..num_nodes).collect();
                for i in 0..k {
                    let j = rng.random_range(i..num_nodes);
                    ids.swap(i, j);
                }
                let list: Vec<Node> = ids[..k].iter().map(|&i| nodes[i]).collect();
                let m: usize = list.iter().map(|n| n.dim).sum();
                let mut block = vec![0.0; m * m];
                for a in 0..m {
                    for b in 0..=a {
                        let v = rng.random_range(-1.0..1.0);
                        block[a * m + b] = v;
                        block[b * m + a] = v;
                    }
                }
                blocks.push((list, block));
            }
            let mut recorder = NodeBlockRecorder::default();
            for (list, _) in &blocks {
                recorder.record(list);
            }
            let mut asm = NodeBlockAssembler::new(n, &nodes, &recorder);
            asm.begin();
            let mut triplets = HessianTriplets::new(n);
            for (list, block) in &blocks {
                asm.add_node_block(list, block);
                triplets.add_node_block(list, block);
            }
            assert!(asm.finish().is_ok());
            let dense = asm.to_dense();
            let reference = triplets.to_dense();
            for (a, b) in dense.iter().zip(&reference) {
                assert!((a - b).abs() <= 1e-12 * (1.0 + b.abs()), "{a} vs {b}");
            }
            // Every diagonal is stored.
            assert!(asm.diagonal_slots().iter().all(|&s| s < asm.nnz()));
            // A shifted diagonal is lent and put back to the bit: a shift by 0.1 of irrational-looking
            // numbers would change the last bits under an add and a subtract.
            let before = asm.matrix().val().to_vec();
            let d: Vec<Real> = (0..n).map(|i| 1.0 + (i as Real).sqrt()).collect();
            let mut expected = before.clone();
            let alpha = 0.1;
            for (&slot, &di) in asm.diagonal_slots().iter().zip(&d) {
                expected[slot] += alpha * di;
            }
            let mut saved = Vec::new();
            asm.with_shifted_diagonal(alpha, &d, &mut saved, |m| {
                assert_eq!(m.val(), expected.as_slice());
            });
            assert!(
                asm.matrix()
                    .val()
                    .iter()
                    .zip(&before)
                    .all(|(a, b)| a.to_bits() == b.to_bits())
            );

            // The same blocks with their node lists reversed: every pair is in the pattern, so they are
            // scattered by lookup and give the same matrix.
            asm.begin();
            for (list, block) in &blocks {
                let (rev, rblock) = reversed(list, block);
                asm.add_node_block(&rev, &rblock);
            }
            assert!(asm.finish().is_ok());
            let multi = blocks.iter().filter(|(l, _)| l.len() > 1).count();
            assert_eq!(asm.slow_blocks(), multi);
            for (a, b) in asm.to_dense().iter().zip(&reference) {
                assert!((a - b).abs() <= 1e-12 * (1.0 + b.abs()), "{a} vs {b}");
            }

            // A block joining two nodes that never shared one is outside the pattern: a mismatch, until the
            // pattern is rebuilt as the union of the old one and the new blocks.
            let lonely = (0..num_nodes)
                .flat_map(|a| (a + 1..num_nodes).map(move |b| (a, b)))
                .find(|&(a, b)| {
                    !blocks
                        .iter()
                        .any(|(l, _)| l.contains(&nodes[a]) && l.contains(&nodes[b]))
                });
            if let Some((a, b)) = lonely {
                let list = vec![nodes[a], nodes[b]];
                let m = nodes[a].dim + nodes[b].dim;
                let block = vec![1.0; m * m];
                asm.begin();
                asm.add_node_block(&list, &block);
                assert_eq!(asm.finish().err(), Some(0));
                let mut rec = NodeBlockRecorder::default();
                rec.record(&list);
                let grown = NodeBlockAssembler::with_union(n, &nodes, &rec, Some(&asm));
                assert!(grown.nnz() > asm.nnz());
                let mut grown = grown;
                grown.begin();
                for (list, block) in &blocks {
                    grown.add_node_block(list, block);
                }
                grown.add_node_block(&list, &block);
                assert!(grown.finish().is_ok());
            }
        }
    }
}
