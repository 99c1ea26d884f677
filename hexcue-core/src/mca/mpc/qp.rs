//! Sparse matrices assembled as triplets in a fixed order, so that the solver's structure is
//! built once and every later step only overwrites values.

use clarabel::algebra::CscMatrix;

/// Entries pushed in a fixed order; duplicates are summed.
#[derive(Clone, Debug, Default)]
pub struct Triplets {
    /// Row of each entry.
    pub rows: Vec<usize>,
    /// Column of each entry.
    pub cols: Vec<usize>,
    /// Value of each entry.
    pub vals: Vec<f64>,
}

impl Triplets {
    /// Empties the list, keeping its capacity.
    pub fn clear(&mut self) {
        self.rows.clear();
        self.cols.clear();
        self.vals.clear();
    }

    /// Keeps the first `len` entries, and their capacity.
    pub fn truncate(&mut self, len: usize) {
        self.rows.truncate(len);
        self.cols.truncate(len);
        self.vals.truncate(len);
    }

    /// Adds `val` at (`row`, `col`).
    pub fn push(&mut self, row: usize, col: usize, val: f64) {
        self.rows.push(row);
        self.cols.push(col);
        self.vals.push(val);
    }

    /// Number of entries pushed.
    pub fn len(&self) -> usize {
        self.vals.len()
    }

    /// Whether no entry was pushed.
    pub fn is_empty(&self) -> bool {
        self.vals.is_empty()
    }
}

/// The compressed-column structure of a triplet list and where each triplet lands in it.
#[derive(Clone, Debug)]
pub struct CscPattern {
    /// Number of rows of the matrix.
    pub nrows: usize,
    /// Number of columns of the matrix.
    pub ncols: usize,
    colptr: Vec<usize>,
    rowval: Vec<usize>,
    /// Position in `nzval` of each triplet, in push order.
    slot: Vec<usize>,
    /// The triplets' (row, col), to check that later lists have the same structure.
    keys: Vec<(usize, usize)>,
}

impl CscPattern {
    /// The structure of `t` in an `nrows` × `ncols` matrix (duplicates share a slot).
    pub fn new(nrows: usize, ncols: usize, t: &Triplets) -> Self {
        let mut order: Vec<usize> = (0..t.len()).collect();
        order.sort_by_key(|&i| (t.cols[i], t.rows[i]));
        let mut colptr = vec![0usize; ncols + 1];
        let mut rowval = Vec::with_capacity(t.len());
        let mut slot = vec![0usize; t.len()];
        let mut last: Option<(usize, usize)> = None;
        for &i in &order {
            let key = (t.cols[i], t.rows[i]);
            if last != Some(key) {
                rowval.push(t.rows[i]);
                colptr[t.cols[i] + 1] += 1;
                last = Some(key);
            }
            slot[i] = rowval.len() - 1;
        }
        for c in 0..ncols {
            colptr[c + 1] += colptr[c];
        }
        CscPattern {
            nrows,
            ncols,
            colptr,
            rowval,
            slot,
            keys: t.rows.iter().copied().zip(t.cols.iter().copied()).collect(),
        }
    }

    /// Number of stored nonzeros.
    pub fn nnz(&self) -> usize {
        self.rowval.len()
    }

    /// Values of `t` in this pattern's order; `false` if `t` does not have this structure.
    pub fn fill(&self, t: &Triplets, nzval: &mut Vec<f64>) -> bool {
        if t.len() != self.slot.len()
            || t.rows
                .iter()
                .zip(t.cols.iter())
                .zip(self.keys.iter())
                .any(|((r, c), k)| (*r, *c) != *k)
        {
            return false;
        }
        nzval.clear();
        nzval.resize(self.nnz(), 0.0);
        for (i, v) in t.vals.iter().enumerate() {
            nzval[self.slot[i]] += v;
        }
        true
    }

    /// The matrix with this structure and the values `nzval` (in compressed-column order).
    pub fn matrix(&self, nzval: Vec<f64>) -> CscMatrix<f64> {
        CscMatrix::new(
            self.nrows,
            self.ncols,
            self.colptr.clone(),
            self.rowval.clone(),
            nzval,
        )
    }

    /// Dense copy of the matrix with values `nzval`, for tests and diagnostics.
    #[cfg(test)]
    pub fn dense(&self, nzval: &[f64]) -> nalgebra::DMatrix<f64> {
        let mut m = nalgebra::DMatrix::zeros(self.nrows, self.ncols);
        for c in 0..self.ncols {
            for k in self.colptr[c]..self.colptr[c + 1] {
                m[(self.rowval[k], c)] += nzval[k];
            }
        }
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn duplicates_are_summed_and_structure_is_checked() {
        let mut t = Triplets::default();
        t.push(1, 0, 2.0);
        t.push(0, 1, 3.0);
        t.push(1, 0, 0.5);
        t.push(0, 0, 0.0);
        let p = CscPattern::new(2, 2, &t);
        assert_eq!(p.nnz(), 3);
        let mut nz = Vec::new();
        assert!(p.fill(&t, &mut nz));
        let d = p.dense(&nz);
        assert_eq!(d[(1, 0)], 2.5);
        assert_eq!(d[(0, 1)], 3.0);
        t.rows[0] = 0;
        assert!(!p.fill(&t, &mut nz));
    }
}
