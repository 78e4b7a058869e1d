//! The sparse linear algebra of the backend: a symmetric block-sparse matrix
//! with square blocks of size `D` (3 for SE(2) poses, 2 for the initialisation
//! problems) and its sparse Cholesky factorisation on faer.
//!
//! This is the only module that touches faer (pinned to 0.24.4; its sparse
//! API changes between minor versions), and no faer type leaves it.
//!
//! The sparsity pattern is fixed when a [`BlockSystem`] is built. The
//! fill-reducing ordering (AMD on the block graph, [`fill_reducing_ordering`])
//! is applied once, to the pattern itself: the matrix is stored as its lower
//! triangle, in compressed columns, already in the permuted order faer's
//! supernodal factorisation works in, so the numeric factorisation neither
//! permutes nor transposes anything. The symbolic (supernodal) analysis is
//! also done once. Each iteration then only refills the values, adds the
//! damping on the diagonal (the pattern already holds the diagonal, so it
//! never changes) and factorises into a reused buffer; right-hand sides are
//! permuted on the way in and out.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::{LltError, LltRegularization};
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, LltRef, SymbolicCholesky, SymmetricOrdering,
    factorize_symbolic_cholesky,
};
use faer::sparse::linalg::{SupernodalThreshold, amd};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMat, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};
use nalgebra::SMatrix;
use thiserror::Error;

/// Failures of the linear algebra.
#[derive(Debug, Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum LinearError {
    /// The (damped) matrix is not numerically positive definite; `block` is
    /// the block (variable) whose pivot failed.
    #[error("matrix not positive definite at block {block}")]
    NotPositiveDefinite { block: usize },
    /// faer could not allocate or index the factorisation.
    #[error("sparse factorisation failed: {0}")]
    Factorisation(String),
}

/// Where block `(a, b)` of the full matrix lives in the stored lower
/// triangle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BlockSlot {
    /// Permuted block column (`col <= row`).
    col: usize,
    /// Rank of the permuted block row among the stored block rows of `col`
    /// (0 is the diagonal block).
    rank: usize,
    /// Whether the stored block is the transpose of block `(a, b)`.
    transposed: bool,
}

/// A symmetric positive (semi)definite block-sparse matrix with a cached
/// symbolic Cholesky factorisation.
pub struct BlockSystem<const D: usize> {
    blocks: usize,
    /// Permuted position of each block: `position[original]`.
    position: Vec<usize>,
    /// Original block at each permuted position.
    original: Vec<usize>,
    /// The stored lower triangle (checked once, at construction).
    pattern: SymbolicSparseColMat<usize>,
    /// Stored (permuted) block rows of each permuted block column, sorted;
    /// the first is the diagonal block.
    block_rows: Vec<Vec<usize>>,
    values: Vec<f64>,
    damped: Vec<f64>,
    symbolic: SymbolicCholesky<usize>,
    factor: Vec<f64>,
    factorised: bool,
    work: Vec<f64>,
    memory: MemBuffer,
    par: Par,
}

impl<const D: usize> BlockSystem<D> {
    /// Builds the pattern of a `blocks x blocks` block matrix that holds
    /// every diagonal block and the off-diagonal blocks `pairs` (in either
    /// order; duplicates allowed), permuted by `ordering` (from
    /// [`fill_reducing_ordering`] on the same pattern), and analyses it
    /// symbolically. `threads == 1` runs sequentially, more uses faer's
    /// rayon backend.
    pub fn new(
        blocks: usize,
        pairs: &[(usize, usize)],
        ordering: &BlockOrdering,
        threads: usize,
    ) -> Result<Self, LinearError> {
        assert_eq!(ordering.fwd.len(), blocks, "one ordering entry per block");
        let original = ordering.fwd.clone();
        let mut position = vec![0; blocks];
        for (p, &b) in original.iter().enumerate() {
            position[b] = p;
        }
        let permuted: Vec<(usize, usize)> = pairs
            .iter()
            .map(|&(a, b)| (position[a], position[b]))
            .collect();
        let block_rows = lower_block_pattern(blocks, &permuted);
        let (col_ptr, row_idx) = lower_scalar_pattern::<D>(&block_rows);
        let nnz = row_idx.len();
        let n = blocks * D;
        let pattern = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
        let symbolic = analyse::<D>(&block_rows)?;
        let par = if threads <= 1 {
            Par::Seq
        } else {
            Par::rayon(threads)
        };
        let scratch = StackReq::any_of(&[
            symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default()),
            symbolic.solve_in_place_scratch::<f64>(1, par),
        ]);
        let memory = MemBuffer::try_new(scratch)
            .map_err(|_| LinearError::Factorisation("out of memory".into()))?;
        Ok(Self {
            blocks,
            position,
            original,
            factor: vec![0.0; symbolic.len_val()],
            symbolic,
            pattern,
            block_rows,
            values: vec![0.0; nnz],
            damped: vec![0.0; nnz],
            factorised: false,
            work: vec![0.0; blocks * D],
            memory,
            par,
        })
    }

    /// Number of scalar unknowns.
    pub fn dim(&self) -> usize {
        self.blocks * D
    }

    /// The slot of block `(a, b)` of the full matrix (rows of block `a`,
    /// columns of block `b`); `None` if the pattern does not hold it.
    pub fn slot(&self, a: usize, b: usize) -> Option<BlockSlot> {
        let (pa, pb) = (*self.position.get(a)?, *self.position.get(b)?);
        let (row, col) = if pa >= pb { (pa, pb) } else { (pb, pa) };
        let rank = self.block_rows[col].binary_search(&row).ok()?;
        Some(BlockSlot {
            col,
            rank,
            transposed: pa < pb,
        })
    }

    /// Sets every stored value to zero.
    pub fn clear(&mut self) {
        self.values.fill(0.0);
        self.factorised = false;
    }

    /// Adds `m` to block `(a, b)` of the full matrix (and `mᵀ` to `(b, a)`),
    /// `slot = self.slot(a, b)`. For a diagonal block only one triangle of
    /// `m` is read: pass a symmetric matrix.
    pub fn add(&mut self, slot: BlockSlot, m: &SMatrix<f64, D, D>) {
        let col_ptr = self.pattern.col_ptr();
        for cj in 0..D {
            let column = col_ptr[slot.col * D + cj];
            if slot.rank == 0 {
                // Diagonal block: rows cj..D of column cj come first.
                for ri in cj..D {
                    self.values[column + ri - cj] += m[(ri, cj)];
                }
            } else {
                let base = column + (D - cj) + (slot.rank - 1) * D;
                for ri in 0..D {
                    let v = if slot.transposed {
                        m[(cj, ri)]
                    } else {
                        m[(ri, cj)]
                    };
                    self.values[base + ri] += v;
                }
            }
        }
        self.factorised = false;
    }

    /// The diagonal of the matrix (undamped), in the original order.
    pub fn diagonal(&self) -> Vec<f64> {
        let col_ptr = self.pattern.col_ptr();
        let mut diagonal = vec![0.0; self.dim()];
        for (p, &b) in self.original.iter().enumerate() {
            for k in 0..D {
                // The diagonal entry is the first stored row of its column.
                diagonal[b * D + k] = self.values[col_ptr[p * D + k]];
            }
        }
        diagonal
    }

    /// `y = A x` with the stored (undamped) symmetric matrix, original order.
    #[cfg(test)]
    pub fn multiply(&self, x: &[f64]) -> Vec<f64> {
        let scalar = |p: usize| self.original[p / D] * D + p % D;
        let (col_ptr, row_idx) = (self.pattern.col_ptr(), self.pattern.row_idx());
        let mut y = vec![0.0; self.dim()];
        for c in 0..self.dim() {
            let range = col_ptr[c]..col_ptr[c + 1];
            for (&r, &v) in row_idx[range.clone()].iter().zip(&self.values[range]) {
                y[scalar(r)] += v * x[scalar(c)];
                if r != c {
                    y[scalar(c)] += v * x[scalar(r)];
                }
            }
        }
        y
    }

    /// Factorises `A + diag(damping)` (`damping` in the original order,
    /// `damping.len() == dim()`, entries `>= 0`).
    pub fn factorise(&mut self, damping: &[f64]) -> Result<(), LinearError> {
        assert_eq!(damping.len(), self.dim(), "one damping value per unknown");
        self.damped.copy_from_slice(&self.values);
        let col_ptr = self.pattern.col_ptr();
        for (p, &b) in self.original.iter().enumerate() {
            for k in 0..D {
                self.damped[col_ptr[p * D + k]] += damping[b * D + k];
            }
        }
        self.factorised = false;
        let n = self.dim();
        let matrix = SparseColMatRef::new(self.pattern.as_ref(), &self.damped);
        let result = self.symbolic.factorize_numeric_llt::<f64>(
            &mut self.factor,
            matrix,
            Side::Lower,
            LltRegularization::default(),
            self.par,
            MemStack::new(&mut self.memory),
            Default::default(),
        );
        match result {
            Ok(_) => {
                self.factorised = true;
                Ok(())
            }
            Err(LltError::NonPositivePivot { index }) => {
                let block = self.original[index.min(n - 1) / D];
                Err(LinearError::NotPositiveDefinite { block })
            }
        }
    }

    /// Solves `(A + diag(damping)) x = rhs` in place (original order) with
    /// the last factorisation.
    ///
    /// # Panics
    /// If [`factorise`](Self::factorise) has not succeeded since the last
    /// change of the values (a programming error).
    pub fn solve(&mut self, rhs: &mut [f64]) {
        assert!(self.factorised, "solve needs a successful factorise");
        assert_eq!(rhs.len(), self.dim());
        let n = self.dim();
        for (p, &b) in self.original.iter().enumerate() {
            self.work[p * D..(p + 1) * D].copy_from_slice(&rhs[b * D..(b + 1) * D]);
        }
        let llt = LltRef::new(&self.symbolic, &self.factor);
        let work = MatMut::from_column_major_slice_mut(&mut self.work, n, 1);
        llt.solve_in_place_with_conj(Conj::No, work, self.par, MemStack::new(&mut self.memory));
        for (p, &b) in self.original.iter().enumerate() {
            rhs[b * D..(b + 1) * D].copy_from_slice(&self.work[p * D..(p + 1) * D]);
        }
    }
}

/// Sorted, deduplicated block rows `>= col` of every block column, diagonal
/// first.
fn lower_block_pattern(blocks: usize, pairs: &[(usize, usize)]) -> Vec<Vec<usize>> {
    let mut rows: Vec<Vec<usize>> = (0..blocks).map(|c| vec![c]).collect();
    for &(a, b) in pairs {
        let (row, col) = if a >= b { (a, b) } else { (b, a) };
        if row != col {
            rows[col].push(row);
        }
    }
    for r in &mut rows {
        r.sort_unstable();
        r.dedup();
    }
    rows
}

/// Compressed-column lower triangle of the scalar matrix.
fn lower_scalar_pattern<const D: usize>(block_rows: &[Vec<usize>]) -> (Vec<usize>, Vec<usize>) {
    let mut col_ptr = Vec::with_capacity(block_rows.len() * D + 1);
    let mut row_idx = Vec::new();
    col_ptr.push(0);
    for (col_block, rows) in block_rows.iter().enumerate() {
        for cj in 0..D {
            for &row_block in rows {
                let first = if row_block == col_block { cj } else { 0 };
                row_idx.extend((first..D).map(|ri| row_block * D + ri));
            }
            col_ptr.push(row_idx.len());
        }
    }
    (col_ptr, row_idx)
}

/// Supernodal symbolic analysis of the (already permuted) pattern. faer's
/// analysis without reordering reads the upper triangle, so it gets the
/// transposed pattern.
fn analyse<const D: usize>(
    block_rows: &[Vec<usize>],
) -> Result<SymbolicCholesky<usize>, LinearError> {
    let blocks = block_rows.len();
    let mut upper_rows: Vec<Vec<usize>> = vec![Vec::new(); blocks];
    for (col, rows) in block_rows.iter().enumerate() {
        for &row in rows {
            upper_rows[row].push(col);
        }
    }
    // Rows of each upper column come out sorted: columns are visited in order.
    let mut col_ptr = Vec::with_capacity(blocks * D + 1);
    let mut row_idx = Vec::new();
    col_ptr.push(0);
    for (col_block, rows) in upper_rows.iter().enumerate() {
        for cj in 0..D {
            for &row_block in rows {
                let count = if row_block == col_block { cj + 1 } else { D };
                row_idx.extend((0..count).map(|ri| row_block * D + ri));
            }
            col_ptr.push(row_idx.len());
        }
    }
    let n = blocks * D;
    let pattern = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
    let params = CholeskySymbolicParams {
        supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
        ..Default::default()
    };
    factorize_symbolic_cholesky(pattern, Side::Upper, SymmetricOrdering::Identity, params)
        .map_err(|e| LinearError::Factorisation(format!("{e:?}")))
}

/// A fill-reducing ordering of the blocks: AMD on the block graph. Cheaper
/// to compute than AMD on the scalar matrix, it keeps the scalars of one
/// block together, which gives the supernodal factorisation dense columns;
/// one ordering serves systems of any block size on the same graph.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BlockOrdering {
    /// `fwd[new] = old`.
    fwd: Vec<usize>,
}

/// AMD ordering of the block graph with the given off-diagonal pairs.
pub fn fill_reducing_ordering(
    blocks: usize,
    pairs: &[(usize, usize)],
) -> Result<BlockOrdering, LinearError> {
    // AMD reads one triangle; the lower one of the unpermuted pattern.
    let block_rows = lower_block_pattern(blocks, pairs);
    let mut col_ptr = Vec::with_capacity(blocks + 1);
    let mut row_idx = Vec::new();
    col_ptr.push(0);
    for rows in &block_rows {
        row_idx.extend_from_slice(rows);
        col_ptr.push(row_idx.len());
    }
    let pattern = SymbolicSparseColMatRef::new_checked(blocks, blocks, &col_ptr, None, &row_idx);
    let mut fwd = vec![0usize; blocks];
    let mut inv = vec![0usize; blocks];
    let mut memory = MemBuffer::try_new(amd::order_scratch::<usize>(blocks, row_idx.len()))
        .map_err(|_| LinearError::Factorisation("out of memory".into()))?;
    amd::order(
        &mut fwd,
        &mut inv,
        pattern,
        amd::Control::default(),
        MemStack::new(&mut memory),
    )
    .map_err(|e| LinearError::Factorisation(format!("{e:?}")))?;
    Ok(BlockOrdering { fwd })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector, Matrix2};

    /// A small SPD block tridiagonal-plus-corner matrix solved against a
    /// dense reference.
    #[test]
    fn solves_against_dense_reference() {
        let pairs = [(0, 1), (1, 2), (2, 3), (3, 0), (1, 0)];
        let ordering = fill_reducing_ordering(4, &pairs).unwrap();
        let mut sys = BlockSystem::<2>::new(4, &pairs, &ordering, 1).unwrap();
        let mut dense = DMatrix::<f64>::zeros(8, 8);
        let off = Matrix2::new(0.3, -0.2, 0.1, 0.4);
        for i in 0..4 {
            let d = Matrix2::new(4.0 + i as f64, 0.5, 0.5, 3.0);
            sys.add(sys.slot(i, i).unwrap(), &d);
            dense.view_mut((2 * i, 2 * i), (2, 2)).copy_from(&d);
        }
        for &(a, b) in &pairs[..4] {
            // Block (a, b) of the full matrix is `off`.
            sys.add(sys.slot(a, b).unwrap(), &off);
            let mut upper_view = dense.view_mut((2 * a, 2 * b), (2, 2));
            upper_view += off;
            let mut lower_view = dense.view_mut((2 * b, 2 * a), (2, 2));
            lower_view += off.transpose();
        }
        let rhs: Vec<f64> = (0..8).map(|i| (i as f64).sin()).collect();
        let damping = vec![0.25; 8];
        sys.factorise(&damping).unwrap();
        let mut x = rhs.clone();
        sys.solve(&mut x);
        let damped = &dense + DMatrix::identity(8, 8) * 0.25;
        let expected = damped
            .cholesky()
            .unwrap()
            .solve(&DVector::from_vec(rhs.clone()));
        for i in 0..8 {
            assert!(
                (x[i] - expected[i]).abs() < 1e-12,
                "{i}: {} vs {}",
                x[i],
                expected[i]
            );
        }
        let y = sys.multiply(&x);
        let y_dense = &dense * DVector::from_vec(x.clone());
        for i in 0..8 {
            assert!((y[i] - y_dense[i]).abs() < 1e-12);
        }
        assert_eq!(sys.diagonal()[0], 4.0);
    }

    #[test]
    fn reports_the_singular_block() {
        let pairs = [(0, 1), (1, 2)];
        let ordering = fill_reducing_ordering(3, &pairs).unwrap();
        let mut sys = BlockSystem::<2>::new(3, &pairs, &ordering, 1).unwrap();
        for i in [0, 2] {
            sys.add(sys.slot(i, i).unwrap(), &Matrix2::identity());
        }
        // Block 1 is all zero: singular.
        let err = sys.factorise(&[0.0; 6]).unwrap_err();
        assert_eq!(err, LinearError::NotPositiveDefinite { block: 1 });
        // Damping makes it definite without changing the pattern.
        sys.factorise(&[1.0; 6]).unwrap();
    }
}
