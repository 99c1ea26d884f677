//! Dense strictly convex QP by a dual active-set method (Goldfarb–Idnani), warm-started from
//! a working set. The algorithm, its warm start and its degeneracy handling: `docs/qp.md`.
//!
//! ```text
//! minimise   ½ uᵀ H u + gᵀ u
//! subject to a_kᵀ u = b_k            k < n_eq          (equality rows)
//!            lo_k ≤ a_kᵀ u ≤ hi_k    n_eq ≤ k < m      (inequality rows; ±∞ for one side)
//! ```
//!
//! H (symmetric positive definite) is factored once by [`ActiveSetQp::set_hessian`] and kept
//! until it is set again; the rows, bounds and gradient are overwritten before every solve.
//! Every buffer is allocated when the solver is made (or when the row count first grows),
//! so a solve allocates nothing. A solve never panics: bad data gives
//! [`QpStatus::NumericalError`].
//!
//! Hand-written because no crate offers this under a permissive licence: `quadprog` is
//! GPL-2.0, there is no DAQP crate, and `osqp-sys` fetches its sources at build time.

use std::time::Instant;

#[cfg(test)]
mod tests;

/// How a solve ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum QpStatus {
    /// Optimal to the primal tolerance; the solution, objective and active set are valid.
    Solved,
    /// No point satisfies the rows (the dual is unbounded).
    Infeasible,
    /// The iteration cap of [`QpSettings`] was reached.
    MaxIterations,
    /// The wall-time limit of [`QpSettings`] was reached.
    MaxTime,
    /// Non-finite data, no factored Hessian, or a breakdown in the factor updates.
    NumericalError,
}

impl From<QpStatus> for crate::vocab::SolveStatus {
    fn from(s: QpStatus) -> Self {
        use crate::vocab::SolveStatus;
        match s {
            QpStatus::Solved => SolveStatus::Solved,
            QpStatus::Infeasible => SolveStatus::PrimalInfeasible,
            QpStatus::MaxIterations => SolveStatus::MaxIterations,
            QpStatus::MaxTime => SolveStatus::MaxTime,
            QpStatus::NumericalError => SolveStatus::NumericalError,
        }
    }
}

/// Which side of a row is held.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// a_kᵀu = lo_k.
    Lower,
    /// a_kᵀu = hi_k.
    Upper,
    /// An equality row.
    Equal,
}

/// One row of a working set.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ActiveRow {
    /// Index of the row.
    pub row: usize,
    /// Which of its bounds is held.
    pub side: Side,
}

/// Limits of one solve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QpSettings {
    /// Cap on the add/drop steps of the main loop.
    pub max_iterations: u32,
    /// When the solve must have ended (the step's deadline, which the solves of a step
    /// share); `None` for never.
    pub deadline: Option<Instant>,
    /// A row counts as satisfied when it is violated by at most this times (|a_k| + |bound|):
    /// relative to the bound, absolute for bounds near zero, and the same for a row scaled by
    /// any factor.
    pub primal_tolerance: f64,
}

impl Default for QpSettings {
    fn default() -> Self {
        QpSettings {
            max_iterations: 500,
            deadline: None,
            primal_tolerance: 1e-9,
        }
    }
}

/// The Hessian given to [`ActiveSetQp::set_hessian`] was rejected.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum QpError {
    /// The Hessian's values are not n × n.
    #[error("Hessian: expected {expected} values (n × n, column-major), got {got}")]
    Dimension {
        /// n², the values expected.
        expected: usize,
        /// The values given.
        got: usize,
    },
    /// The Cholesky factorisation met a pivot that is not positive.
    #[error("Hessian is not positive definite (pivot {column})")]
    NotPositiveDefinite {
        /// The column of that pivot.
        column: usize,
    },
    /// A value of the Hessian is NaN or infinite.
    #[error("Hessian holds a non-finite value")]
    NonFinite,
}

/// A constraint is taken as linearly dependent on the active ones when the part of its
/// normal outside their span (in H's metric) is below this fraction of the whole.
const DEPENDENT: f64 = 1e-10;

/// aᵀb over the shorter length, with four partial sums: a plain `zip().map().sum()` is one
/// chain of dependent additions (the compiler may not reorder floating-point sums), which
/// the dot products of the row scan, the factors and the multipliers spend most of a solve
/// waiting on. Four chains run in parallel and vectorise.
#[inline]
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    let len = a.len().min(b.len());
    let (a, b) = (&a[..len], &b[..len]);
    let mut acc = [0.0f64; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        acc[0] += x[0] * y[0];
        acc[1] += x[1] * y[1];
        acc[2] += x[2] * y[2];
        acc[3] += x[3] * y[3];
    }
    let mut tail = 0.0;
    for (x, y) in ra.iter().zip(rb) {
        tail += x * y;
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// Where a vector's nonzeros lie, widened to [`dot`]'s groups of four: `(lo, hi)` with `lo`
/// a multiple of 4 at or before the first nonzero, and `hi` a multiple of 4 (or `len`) at or
/// after the last one; `(0, 0)` for a vector of zeros. A NaN counts as a nonzero.
///
/// `dot(&a[lo..hi], &b[lo..hi])` is then `dot(a, b)` to the bit for any finite `b`: the
/// groups left out add only zeros to `dot`'s four partial sums (each starts at +0, and a sum
/// of +0 and ±0 is +0), and the groups kept are summed in the same lanes and order.
#[inline]
pub(crate) fn nonzero_span(a: &[f64]) -> (usize, usize) {
    let Some(first) = a.iter().position(|&v| v != 0.0) else {
        return (0, 0);
    };
    let last = a.iter().rposition(|&v| v != 0.0).unwrap_or(first);
    (first / 4 * 4, (last / 4 * 4 + 4).min(a.len()))
}

/// The solver: problem data, factors and working storage, all of fixed size after `new`.
#[derive(Clone, Debug)]
pub struct ActiveSetQp {
    n: usize,
    /// H, column-major, for the objective.
    h: Vec<f64>,
    /// L⁻ᵀ of the Cholesky factor H = L Lᵀ, column-major (upper triangular).
    j0: Vec<f64>,
    /// Per row of H, the column of its first nonzero (its diagonal when none is before).
    first_nonzero: Vec<usize>,
    factored: bool,
    g: Vec<f64>,
    /// Rows stored one after the other (row k at k·n).
    rows: Vec<f64>,
    /// Whether row k was handed out by `row_mut` since its norm and span were computed.
    row_dirty: Vec<bool>,
    /// [`nonzero_span`] of each row: the dot products with a row read only that part.
    span: Vec<(usize, usize)>,
    lo: Vec<f64>,
    hi: Vec<f64>,
    n_eq: usize,
    m: usize,
    // Working storage.
    /// J = L⁻ᵀ Q (column-major): its first q columns span the active normals.
    jm: Vec<f64>,
    /// R, upper triangular (column-major, n × n), L⁻¹ N_active = Q₁ R.
    r: Vec<f64>,
    active: Vec<ActiveRow>,
    /// Multipliers of the active rows, in `active`'s order.
    mult: Vec<f64>,
    /// Whether each row is in the active set.
    is_active: Vec<bool>,
    row_norm: Vec<f64>,
    x: Vec<f64>,
    x0: Vec<f64>,
    d: Vec<f64>,
    z: Vec<f64>,
    dir: Vec<f64>,
    work: Vec<f64>,
    warm: Vec<ActiveRow>,
    /// Whether J, R and `active` are the last solve's (solved), with `snapshot` holding its
    /// active rows' coefficients, so the next solve can start from them.
    factor_reusable: bool,
    snapshot: Vec<f64>,
    solves_since_rebuild: u32,
    objective: f64,
    iterations: u32,
}

/// Solves that keep the factors before they are rebuilt from H's factor, so that rounding
/// in the Givens updates cannot accumulate.
const REBUILD_EVERY: u32 = 50;

impl ActiveSetQp {
    /// A solver for `n` variables; `rows_hint` rows are preallocated.
    pub fn new(n: usize, rows_hint: usize) -> Self {
        ActiveSetQp {
            n,
            h: vec![0.0; n * n],
            j0: vec![0.0; n * n],
            first_nonzero: vec![0; n],
            factored: false,
            g: vec![0.0; n],
            rows: Vec::with_capacity(rows_hint * n),
            row_dirty: Vec::with_capacity(rows_hint),
            span: Vec::with_capacity(rows_hint),
            lo: Vec::with_capacity(rows_hint),
            hi: Vec::with_capacity(rows_hint),
            n_eq: 0,
            m: 0,
            jm: vec![0.0; n * n],
            r: vec![0.0; n * n],
            active: Vec::with_capacity(n),
            mult: Vec::with_capacity(n),
            is_active: Vec::with_capacity(rows_hint),
            row_norm: Vec::with_capacity(rows_hint),
            x: vec![0.0; n],
            x0: vec![0.0; n],
            d: vec![0.0; n],
            z: vec![0.0; n],
            dir: vec![0.0; n],
            work: vec![0.0; n],
            warm: Vec::with_capacity(n),
            factor_reusable: false,
            snapshot: vec![0.0; n * n],
            solves_since_rebuild: 0,
            objective: f64::NAN,
            iterations: 0,
        }
    }

    /// Number of variables n.
    pub fn n_vars(&self) -> usize {
        self.n
    }

    /// Number of equality and inequality rows.
    pub fn n_rows(&self) -> (usize, usize) {
        (self.n_eq, self.m - self.n_eq)
    }

    /// Factors H (n × n, column-major; only the lower triangle is read) and keeps the factor
    /// until the next call. On error the solver has no Hessian and solves report
    /// `NumericalError`.
    pub fn set_hessian(&mut self, h: &[f64]) -> Result<(), QpError> {
        let n = self.n;
        self.factored = false;
        self.factor_reusable = false;
        if h.len() != n * n {
            return Err(QpError::Dimension {
                expected: n * n,
                got: h.len(),
            });
        }
        if h.iter().any(|v| !v.is_finite()) {
            return Err(QpError::NonFinite);
        }
        // Symmetric copy from the lower triangle.
        for c in 0..n {
            for r in c..n {
                self.h[c * n + r] = h[c * n + r];
                self.h[r * n + c] = h[c * n + r];
            }
        }
        // The envelope: row i of L is zero before the first nonzero of H's row i (the
        // factorisation fills nothing to its left). The MPC's slacks are such rows: their H
        // rows hold the diagonal alone, and they were most of the factorisation's work.
        let first = &mut self.first_nonzero;
        for (i, f) in first.iter_mut().enumerate() {
            *f = (0..i).find(|&j| self.h[j * n + i] != 0.0).unwrap_or(i);
        }
        // Cholesky H = L Lᵀ, L's rows stored one after the other in `r` (free until the
        // next solve, which rebuilds the active set's factors after a new Hessian), so that
        // each entry's sum is a dot product of two contiguous rows. The products outside the
        // envelope are products with zero, left out in whole groups of four (`nonzero_span`):
        // L and J₀ are the same to the bit as with every product summed.
        let lt = &mut self.r;
        lt.fill(0.0);
        for j in 0..n {
            let row_j = j * n;
            let f = first[j] / 4 * 4;
            let s = self.h[j * n + j] - dot(&lt[row_j + f..row_j + j], &lt[row_j + f..row_j + j]);
            if !s.is_finite() || s <= 0.0 {
                return Err(QpError::NotPositiveDefinite { column: j });
            }
            let ljj = s.sqrt();
            lt[row_j + j] = ljj;
            for i in j + 1..n {
                if first[i] > j {
                    // H[i][j] and row i of L left of j are zero: so is L[i][j].
                    continue;
                }
                let row_i = i * n;
                let f = first[i].max(first[j]) / 4 * 4;
                let s =
                    self.h[j * n + i] - dot(&lt[row_i + f..row_i + j], &lt[row_j + f..row_j + j]);
                lt[row_i + j] = s / ljj;
            }
        }
        // L column-major into `jm`: column i of L is row i of Lᵀ, which the back
        // substitution reads.
        let l = &mut self.jm;
        for c in 0..n {
            for r in 0..n {
                l[c * n + r] = lt[r * n + c];
            }
        }
        // Lᵀ J0 = I, column by column (back substitution; column c is zero below c).
        let j0 = &mut self.j0;
        j0.fill(0.0);
        for c in 0..n {
            if self.first_nonzero[c] == c {
                // Row c of L is its diagonal alone: above the diagonal, every sum of column c
                // is a sum of zeros, and the column is e_c / L[c][c].
                j0[c * n + c] = 1.0 / l[c * n + c];
                continue;
            }
            for i in (0..=c).rev() {
                let unit = if i == c { 1.0 } else { 0.0 };
                // (Lᵀ)[i, k] = L[k, i] for k > i: column i of L, contiguous.
                let s = unit
                    - dot(
                        &l[i * n + i + 1..i * n + c + 1],
                        &j0[c * n + i + 1..c * n + c + 1],
                    );
                j0[c * n + i] = s / l[i * n + i];
            }
        }
        self.factored = true;
        Ok(())
    }

    /// Whether a Hessian is factored.
    pub fn is_factored(&self) -> bool {
        self.factored
    }

    /// The linear term g, to overwrite before a solve.
    pub fn gradient_mut(&mut self) -> &mut [f64] {
        &mut self.g
    }

    /// The linear term g.
    pub fn gradient(&self) -> &[f64] {
        &self.g
    }

    /// Sets the number of rows (equalities first); their values are then written with
    /// [`row_mut`](Self::row_mut) and [`set_bounds`](Self::set_bounds). Grows storage only
    /// when the count exceeds any before. A row keeps its coefficients (and their norm) until
    /// it is written again, so a caller whose rows rarely change writes only those that do.
    pub fn set_rows(&mut self, n_eq: usize, n_ineq: usize) {
        let m = n_eq + n_ineq;
        if (n_eq, m) != (self.n_eq, self.m) {
            self.factor_reusable = false;
        }
        self.n_eq = n_eq;
        self.m = m;
        self.rows.resize(m * self.n, 0.0);
        self.row_dirty.clear();
        self.row_dirty.resize(m, true);
        self.span.resize(m, (0, 0));
        self.lo.resize(m, 0.0);
        self.hi.resize(m, 0.0);
        self.is_active.resize(m, false);
        self.row_norm.resize(m, 0.0);
    }

    /// Coefficients a_k of row k (length n), to write. The row's norm and nonzero span are
    /// computed again at the next solve; a row not handed out here keeps its last ones.
    pub fn row_mut(&mut self, k: usize) -> &mut [f64] {
        let n = self.n;
        self.row_dirty[k] = true;
        &mut self.rows[k * n..(k + 1) * n]
    }

    /// Coefficients a_k of row k (length n).
    pub fn row(&self, k: usize) -> &[f64] {
        &self.rows[k * self.n..(k + 1) * self.n]
    }

    /// Bounds of row k: lo ≤ a_kᵀu ≤ hi (±∞ for a one-sided row); for an equality row
    /// lo = hi = b.
    pub fn set_bounds(&mut self, k: usize, lo: f64, hi: f64) {
        self.lo[k] = lo;
        self.hi[k] = hi;
    }

    /// Bounds (lo, hi) of row k.
    pub fn bounds(&self, k: usize) -> (f64, f64) {
        (self.lo[k], self.hi[k])
    }

    /// The working set the next solve starts from. After a solve that ends `Solved` it is
    /// that solve's active set (inequality rows), so consecutive solves warm-start by default.
    /// Any set is accepted: rows out of range, on an infinite bound, repeated, linearly
    /// dependent or with a negative multiplier are left out by the solve.
    pub fn set_warm_start(&mut self, rows: &[ActiveRow]) {
        self.factor_reusable = false;
        self.warm.clear();
        self.warm.extend_from_slice(rows);
    }

    /// The working set the next solve starts from ([`ActiveSetQp::set_warm_start`]).
    pub fn warm_start(&self) -> &[ActiveRow] {
        &self.warm
    }

    /// The next solve starts from an empty working set.
    pub fn clear_warm_start(&mut self) {
        self.factor_reusable = false;
        self.warm.clear();
    }

    /// The solution u of the last solve (valid after `Solved`).
    pub fn solution(&self) -> &[f64] {
        &self.x
    }

    /// ½ uᵀHu + gᵀu at the solution.
    pub fn objective(&self) -> f64 {
        self.objective
    }

    /// Add/drop steps of the last solve's main loop.
    pub fn iterations(&self) -> u32 {
        self.iterations
    }

    /// Rows active at the end of the last solve (equalities included).
    pub fn active_set(&self) -> &[ActiveRow] {
        &self.active
    }

    /// Multipliers of [`active_set`](Self::active_set) (≥ 0 for inequalities, the force
    /// pushing u into the feasible side; any sign for equalities).
    pub fn multipliers(&self) -> &[f64] {
        &self.mult
    }

    /// Solves with the current data, starting from the warm-start working set.
    pub fn solve(&mut self, settings: &QpSettings) -> QpStatus {
        self.iterations = 0;
        self.objective = f64::NAN;
        let status = self.run(settings);
        if status != QpStatus::Solved {
            return status;
        }
        self.objective = self.objective_at_x();
        if !self.objective.is_finite() || self.x.iter().any(|v| !v.is_finite()) {
            return QpStatus::NumericalError;
        }
        // The factors stay for the next solve (`keep_unchanged_rows`).
        let n = self.n;
        for (j, a) in self.active.iter().enumerate() {
            self.snapshot[j * n..(j + 1) * n]
                .copy_from_slice(&self.rows[a.row * n..(a.row + 1) * n]);
        }
        self.factor_reusable = true;
        self.warm.clear();
        for a in &self.active {
            if a.side != Side::Equal {
                self.warm.push(*a);
            }
        }
        status
    }

    fn objective_at_x(&self) -> f64 {
        let n = self.n;
        let mut f = 0.0;
        for c in 0..n {
            let col = &self.h[c * n..(c + 1) * n];
            let hx = dot(col, &self.x);
            f += self.x[c] * (0.5 * hx + self.g[c]);
        }
        f
    }

    /// The normal and right-hand side of a row held on a side, as n⁺ᵀu ≥ b⁺ (equalities:
    /// n⁺ᵀu = b⁺).
    fn sign_rhs(&self, a: ActiveRow) -> (f64, f64) {
        match a.side {
            Side::Lower | Side::Equal => (1.0, self.lo[a.row]),
            Side::Upper => (-1.0, -self.hi[a.row]),
        }
    }

    fn run(&mut self, s: &QpSettings) -> QpStatus {
        let n = self.n;
        if !self.factored {
            return QpStatus::NumericalError;
        }
        let tol = if s.primal_tolerance > 0.0 {
            s.primal_tolerance
        } else {
            1e-9
        };
        if self.g.iter().any(|v| !v.is_finite()) {
            return QpStatus::NumericalError;
        }
        for k in 0..self.m {
            let a = &self.rows[k * n..(k + 1) * n];
            // The norm and span of a row written since the last solve; the others keep theirs
            // (the row scan, its square roots and the rows' condensation were a third of a step).
            if self.row_dirty[k] {
                let (lo, hi) = nonzero_span(a);
                self.span[k] = (lo, hi);
                self.row_norm[k] = dot(&a[lo..hi], &a[lo..hi]).sqrt();
                self.row_dirty[k] = false;
            }
            let norm = self.row_norm[k];
            // A NaN or infinite coefficient makes the norm NaN or infinite (so does a
            // finite row whose squares overflow, which the scan then lets through as before).
            if (!norm.is_finite() && a.iter().any(|v| !v.is_finite()))
                || self.lo[k].is_nan()
                || self.hi[k].is_nan()
            {
                return QpStatus::NumericalError;
            }
            self.is_active[k] = false;
            let (lo, hi) = (self.lo[k], self.hi[k]);
            if k < self.n_eq && !lo.is_finite() {
                return QpStatus::NumericalError;
            }
            if lo > hi + tol * (norm + lo.abs().min(hi.abs())) {
                return QpStatus::Infeasible;
            }
            // An empty row is a statement about its bounds alone.
            if norm == 0.0 && (lo > tol || hi < -tol) {
                return QpStatus::Infeasible;
            }
        }
        // Unconstrained minimum: x0 = −H⁻¹g = −J0 J0ᵀ g. J0's column i is zero below row i
        // (upper triangular), so both products read its first i + 1 entries, widened to the
        // dot product's groups of four (`nonzero_span`: the same sums to the bit).
        for i in 0..n {
            let len = (i / 4 * 4 + 4).min(n);
            let col = &self.j0[i * n..i * n + len];
            self.work[i] = dot(col, &self.g[..len]);
        }
        self.x0.fill(0.0);
        for i in 0..n {
            let w = self.work[i];
            if w != 0.0 {
                let col = &self.j0[i * n..i * n + i + 1];
                for (x, c) in self.x0.iter_mut().zip(col) {
                    *x -= w * c;
                }
            }
        }
        let reuse = self.factor_reusable && self.solves_since_rebuild < REBUILD_EVERY;
        if reuse && self.keep_unchanged_rows() {
            self.solves_since_rebuild += 1;
        } else {
            for a in &self.active {
                if a.row < self.m {
                    self.is_active[a.row] = false;
                }
            }
            self.solves_since_rebuild = 0;
            self.active.clear();
            self.mult.clear();
            self.jm.copy_from_slice(&self.j0);
        }
        self.factor_reusable = false;

        // Equalities first: they stay in the set. One that depends on those before is only
        // checked for consistency once x is known.
        let mut skipped_eq = false;
        for k in 0..self.n_eq {
            if self.row_norm[k] == 0.0 || self.is_active[k] {
                continue;
            }
            let act = ActiveRow {
                row: k,
                side: Side::Equal,
            };
            if !self.try_add(act) {
                skipped_eq = true;
            }
        }
        // The warm start: each row added to the factors if it is new and independent, then
        // the equality-constrained optimum on that set, dropping the most negative
        // multiplier until all are ≥ 0. What remains is a dual-feasible start. (When the
        // factors were kept, the warm rows still in them are skipped here as active.)
        for w in 0..self.warm.len() {
            let a = self.warm[w];
            let ok = a.row >= self.n_eq
                && a.row < self.m
                && !self.is_active[a.row]
                && self.row_norm[a.row] > 0.0
                && match a.side {
                    Side::Lower => self.lo[a.row].is_finite(),
                    Side::Upper => self.hi[a.row].is_finite(),
                    Side::Equal => false,
                };
            if ok {
                self.try_add(a);
            }
        }
        loop {
            if !self.equality_optimum() {
                return QpStatus::NumericalError;
            }
            let mut worst: Option<(usize, f64)> = None;
            for (j, a) in self.active.iter().enumerate() {
                if a.side != Side::Equal
                    && self.mult[j] < 0.0
                    && worst.is_none_or(|(_, m)| self.mult[j] < m)
                {
                    worst = Some((j, self.mult[j]));
                }
            }
            match worst {
                Some((j, _)) => self.drop_active(j),
                None => break,
            }
            if s.deadline.is_some_and(|d| Instant::now() > d) {
                return QpStatus::MaxTime;
            }
        }
        if skipped_eq {
            for k in 0..self.n_eq {
                if !self.is_active[k] {
                    let v = self.dot_row(k, &self.x);
                    if (v - self.lo[k]).abs() > tol * (self.row_norm[k] + self.lo[k].abs()) {
                        return QpStatus::Infeasible;
                    }
                }
            }
        }

        // Main loop: add the most violated row; partial steps drop rows whose multiplier
        // reaches zero on the way.
        loop {
            if s.deadline.is_some_and(|d| Instant::now() > d) {
                return QpStatus::MaxTime;
            }
            let Some(p) = self.most_violated(tol) else {
                return QpStatus::Solved;
            };
            let (sign, rhs) = self.sign_rhs(p);
            let mut u_plus = 0.0;
            loop {
                if self.iterations >= s.max_iterations {
                    return QpStatus::MaxIterations;
                }
                if s.deadline.is_some_and(|d| Instant::now() > d) {
                    return QpStatus::MaxTime;
                }
                self.iterations += 1;
                let q = self.active.len();
                self.compute_d(p.row, sign);
                let d_norm2: f64 = self.d.iter().map(|v| v * v).sum();
                let d2_norm2: f64 = self.d[q..].iter().map(|v| v * v).sum();
                // Primal direction z = J₂ d₂, dual direction R⁻¹ d₁.
                self.z.fill(0.0);
                let dependent = d2_norm2 <= DEPENDENT * DEPENDENT * d_norm2;
                if !dependent {
                    for c in q..n {
                        let w = self.d[c];
                        let col = &self.jm[c * n..(c + 1) * n];
                        for (z, j) in self.z.iter_mut().zip(col) {
                            *z += w * j;
                        }
                    }
                }
                if !self.back_solve_r(q) {
                    return QpStatus::NumericalError;
                }
                // Partial step: the first active inequality whose multiplier reaches zero.
                let mut t1 = f64::INFINITY;
                let mut drop = usize::MAX;
                for j in 0..q {
                    if self.active[j].side != Side::Equal && self.dir[j] > 0.0 {
                        let t = self.mult[j] / self.dir[j];
                        if t < t1 {
                            t1 = t;
                            drop = j;
                        }
                    }
                }
                // Full step: p satisfied with equality.
                let t2 = if dependent {
                    f64::INFINITY
                } else {
                    let slack = sign * self.dot_row(p.row, &self.x) - rhs;
                    -slack / d2_norm2
                };
                if !t1.is_finite() && !t2.is_finite() {
                    return QpStatus::Infeasible;
                }
                let t = t1.min(t2).max(0.0);
                if !t.is_finite() {
                    return QpStatus::NumericalError;
                }
                if !dependent {
                    for (x, z) in self.x.iter_mut().zip(&self.z) {
                        *x += t * z;
                    }
                }
                for j in 0..q {
                    self.mult[j] -= t * self.dir[j];
                }
                u_plus += t;
                if t2 <= t1 {
                    // Full step: p joins the set with its accumulated multiplier.
                    self.add_with_d(p);
                    self.mult.push(u_plus);
                    break;
                }
                // The dropped row's multiplier is zero by construction.
                self.drop_active(drop);
            }
        }
    }

    /// The factors of the last solve, kept: its active rows whose coefficients have not
    /// changed stay (their bounds may have), the others are dropped and come back through
    /// the warm start like any other row. The active set is then the warm set in the factors
    /// without the O(q·n²) of adding every row again. False (nothing kept) if a row is out
    /// of range.
    fn keep_unchanged_rows(&mut self) -> bool {
        let n = self.n;
        if self.active.iter().any(|a| a.row >= self.m) {
            return false;
        }
        for a in &self.active {
            self.is_active[a.row] = true;
        }
        for j in (0..self.active.len()).rev() {
            let a = self.active[j];
            let valid = (a.row < self.n_eq) == (a.side == Side::Equal)
                && self.row_norm[a.row] > 0.0
                && match a.side {
                    Side::Lower | Side::Equal => self.lo[a.row].is_finite(),
                    Side::Upper => self.hi[a.row].is_finite(),
                }
                && self.rows[a.row * n..(a.row + 1) * n] == self.snapshot[j * n..(j + 1) * n];
            if !valid {
                self.drop_active(j);
            }
        }
        true
    }

    /// a_kᵀ v, over the row's nonzero span (the same sum as over the whole row).
    fn dot_row(&self, k: usize, v: &[f64]) -> f64 {
        let (lo, hi) = self.span[k];
        let row = &self.rows[k * self.n..(k + 1) * self.n];
        dot(&row[lo..hi], &v[lo..hi])
    }

    /// The inactive side with the largest violation per unit norm beyond `tol`.
    fn most_violated(&self, tol: f64) -> Option<ActiveRow> {
        let mut best: Option<(ActiveRow, f64)> = None;
        for k in self.n_eq..self.m {
            if self.is_active[k] || self.row_norm[k] == 0.0 {
                continue;
            }
            let v = self.dot_row(k, &self.x);
            let norm = self.row_norm[k];
            let (below, above) = (self.lo[k] - v, v - self.hi[k]);
            let (excess, bound, side) = if below > above {
                (below, self.lo[k], Side::Lower)
            } else {
                (above, self.hi[k], Side::Upper)
            };
            if excess > tol * (norm + bound.abs()) {
                let viol = excess / norm;
                if best.is_none_or(|(_, b)| viol > b) {
                    best = Some((ActiveRow { row: k, side }, viol));
                }
            }
        }
        best.map(|(a, _)| a)
    }

    /// d = Jᵀ n⁺ for row k with sign σ.
    fn compute_d(&mut self, k: usize, sign: f64) {
        let n = self.n;
        let (lo, hi) = self.span[k];
        let a = &self.rows[k * n + lo..k * n + hi];
        for i in 0..n {
            let col = &self.jm[i * n + lo..i * n + hi];
            self.d[i] = sign * dot(col, a);
        }
    }

    /// `dir` = R⁻¹ d₁ over the first q entries; false on a zero pivot.
    fn back_solve_r(&mut self, q: usize) -> bool {
        let n = self.n;
        for i in (0..q).rev() {
            let mut s = self.d[i];
            for j in i + 1..q {
                s -= self.r[j * n + i] * self.dir[j];
            }
            let piv = self.r[i * n + i];
            if piv == 0.0 || !piv.is_finite() {
                return false;
            }
            self.dir[i] = s / piv;
        }
        true
    }

    /// Adds row `a` to the factors if it is independent of the active rows; its multiplier
    /// is left for the caller (`equality_optimum` computes all of them).
    fn try_add(&mut self, a: ActiveRow) -> bool {
        let (sign, _) = self.sign_rhs(a);
        self.compute_d(a.row, sign);
        let q = self.active.len();
        let d_norm2: f64 = self.d.iter().map(|v| v * v).sum();
        let d2_norm2: f64 = self.d[q..].iter().map(|v| v * v).sum();
        if q >= self.n || d2_norm2 <= DEPENDENT * DEPENDENT * d_norm2 || d_norm2 == 0.0 {
            return false;
        }
        self.add_with_d(a);
        self.mult.push(0.0);
        true
    }

    /// Appends `a` to the active set using d = Jᵀn⁺ already computed: Givens rotations fold
    /// d's tail into one entry (rotating J's columns alike) and R gains a column.
    fn add_with_d(&mut self, a: ActiveRow) {
        let n = self.n;
        let q = self.active.len();
        for j in (q + 1..n).rev() {
            let (x, y) = (self.d[j - 1], self.d[j]);
            if y == 0.0 {
                continue;
            }
            let h = (x * x + y * y).sqrt();
            let (c, s) = (x / h, y / h);
            self.d[j - 1] = h;
            self.d[j] = 0.0;
            let (left, right) = self.jm.split_at_mut(j * n);
            let cj1 = &mut left[(j - 1) * n..];
            let cj = &mut right[..n];
            for (p, r) in cj1.iter_mut().zip(cj.iter_mut()) {
                let (u, v) = (*p, *r);
                *p = c * u + s * v;
                *r = -s * u + c * v;
            }
        }
        for i in 0..=q {
            self.r[q * n + i] = self.d[i];
        }
        self.active.push(a);
        self.is_active[a.row] = true;
    }

    /// Removes the active row at position `j`: R loses a column and is made triangular again
    /// by Givens rotations of its rows, which rotate J's columns alike.
    fn drop_active(&mut self, j: usize) {
        let n = self.n;
        let q = self.active.len();
        self.is_active[self.active[j].row] = false;
        self.active.remove(j);
        self.mult.remove(j);
        for c in j..q - 1 {
            for i in 0..=c + 1 {
                self.r[c * n + i] = self.r[(c + 1) * n + i];
            }
        }
        let qn = q - 1;
        for i in j..qn {
            let (x, y) = (self.r[i * n + i], self.r[i * n + i + 1]);
            if y == 0.0 {
                continue;
            }
            let h = (x * x + y * y).sqrt();
            let (c, s) = (x / h, y / h);
            for col in i..qn {
                let (u, v) = (self.r[col * n + i], self.r[col * n + i + 1]);
                self.r[col * n + i] = c * u + s * v;
                self.r[col * n + i + 1] = -s * u + c * v;
            }
            self.r[i * n + i + 1] = 0.0;
            let (left, right) = self.jm.split_at_mut((i + 1) * n);
            let ci = &mut left[i * n..];
            let ci1 = &mut right[..n];
            for (p, r) in ci.iter_mut().zip(ci1.iter_mut()) {
                let (u, v) = (*p, *r);
                *p = c * u + s * v;
                *r = -s * u + c * v;
            }
        }
    }

    /// x and the multipliers of the equality-constrained QP on the active set:
    /// w = b_A − N_Aᵀx0, Rᵀy = w, x = x0 + J₁y, λ = R⁻¹y. False on a zero pivot.
    fn equality_optimum(&mut self) -> bool {
        let n = self.n;
        let q = self.active.len();
        for i in 0..q {
            let a = self.active[i];
            let (sign, rhs) = self.sign_rhs(a);
            let w = rhs - sign * self.dot_row(a.row, &self.x0);
            let mut s = w;
            for k in 0..i {
                s -= self.r[i * n + k] * self.work[k];
            }
            let piv = self.r[i * n + i];
            if piv == 0.0 || !piv.is_finite() {
                return false;
            }
            self.work[i] = s / piv;
        }
        self.x.copy_from_slice(&self.x0);
        for i in 0..q {
            let y = self.work[i];
            let col = &self.jm[i * n..(i + 1) * n];
            for (x, c) in self.x.iter_mut().zip(col) {
                *x += y * c;
            }
        }
        self.d[..q].copy_from_slice(&self.work[..q]);
        if !self.back_solve_r(q) {
            return false;
        }
        self.mult.clear();
        self.mult.extend_from_slice(&self.dir[..q]);
        true
    }
}
