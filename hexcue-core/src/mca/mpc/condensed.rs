//! The MPC's sparse QP condensed to its inputs and solved by the dual active-set solver
//! (`crate::qp`). Nothing here knows the MPC's cost or rows: it reads the sparse QP the MPC
//! assembles (P, q, A, b; the dynamics rows first) and eliminates the states, so whatever the
//! MPC optimises, both solvers solve the same QP. The derivation: `docs/mpc.md`.
//!
//! With z = (u, x) split by column and the dynamics rows A_u u + A_x x = b_dyn (A_x square
//! and constant), x = Γu + x̄ with Γ = −A_x⁻¹A_u (once) and x̄ = A_x⁻¹ b_dyn (each step).
//! Writing z = T u + z̄ (T = [I; Γ], z̄ = [0; x̄]):
//!
//! ```text
//! H = Tᵀ P T                     when P changes (see below)
//! g = Tᵀ (q + P z̄)               each step
//! a_uᵀu + a_xᵀx ≤ b  →  (a_u + Γᵀa_x)ᵀ u ≤ b − a_xᵀx̄      each row, each step
//! ```
//!
//! P changes only with the washout gain, and it is affine in it. H(gain) = H₀ + gain·H_w is
//! condensed once from P at gains 0 and 1 and checked at gain 2; a change of gain then costs
//! an n_u × n_u sum, and one Cholesky factorisation of that size at the next solve (not at
//! every change: the S-MPC moves the gain of its free MPC at every step while it follows
//! COTC without solving). If the check fails (a cost that is not affine in the gain), every
//! change of P is condensed in full instead.
//!
//! What a step does not repeat (docs/performance.md, "The condensation, cached"): a row
//! whose sparse entries are those of the last step keeps its condensed coefficients (only
//! its bounds move with x̄), and the active set keeps its norm; and every product with Γ
//! reads only the part of Γ's row that can be nonzero (a state depends on the inputs up to
//! its interval, none on the slacks). The sums left out are sums of zeros, so the condensed
//! QP is the same to the bit.

use nalgebra::DMatrix;

use super::qp::Triplets;
use crate::qp::{ActiveSetQp, QpSettings, QpStatus};

/// What a column of the sparse QP holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Var {
    /// An input: index among the inputs.
    Input(usize),
    /// A state: index among the states (and among the dynamics rows it is solved from).
    State(usize),
}

/// The sparse QP's layout.
#[derive(Clone, Debug)]
pub struct Layout {
    /// What each column holds.
    pub vars: Vec<Var>,
    /// The first `n_dyn` rows are the dynamics: equalities that give the states.
    pub n_dyn: usize,
    /// Rows in all.
    pub m: usize,
    /// Equality rows (the dynamics included), before the inequalities.
    pub n_eq: usize,
}

/// A row of the condensed QP: one sparse row, or two whose coefficients are negatives of
/// each other (a ≤ hi and −a ≤ −lo), merged into lo ≤ a ≤ hi.
#[derive(Clone, Copy, Debug)]
struct RowMap {
    row: usize,
    paired: bool,
    /// Triplets of `row` in `row_trips[start..end]` (and of `row + 1` right after when paired).
    start: usize,
    end: usize,
}

/// Why the sparse QP cannot be condensed.
#[derive(Debug, thiserror::Error)]
pub enum CondenseError {
    /// The dynamics rows do not have one row per state.
    #[error("{states} state columns but {rows} dynamics rows")]
    Shape {
        /// Number of state columns.
        states: usize,
        /// Number of dynamics rows.
        rows: usize,
    },
    /// A_x, the dynamics rows' state columns, cannot be inverted: the states are not determined
    /// by the inputs.
    #[error("the dynamics rows are singular in the states")]
    Singular,
    /// A constraint's triplet names a row past the QP's last.
    #[error("a constraint entry lies beyond the {0} rows")]
    Layout(usize),
    /// The condensed Hessian TᵀPT could not be factorised.
    #[error("the condensed Hessian is not positive definite: {0}")]
    Hessian(#[from] crate::qp::QpError),
}

/// The MPC's QP with its states eliminated (x = Γu + x̄), posed over the inputs alone and
/// solved by the dual active set (`crate::qp`); built once per grid, updated each step.
pub struct CondensedQp {
    vars: Vec<Var>,
    n_u: usize,
    n_x: usize,
    /// Sparse column of each input and state.
    u_cols: Vec<usize>,
    x_cols: Vec<usize>,
    /// Triplets of the dynamics rows and their values when Γ was computed.
    dyn_trips: Vec<usize>,
    dyn_vals: Vec<f64>,
    /// A_x⁻¹ (n_x × n_x).
    a_x_inv: DMatrix<f64>,
    /// Γ, row-major (state i's row at i·n_u).
    gamma: Vec<f64>,
    /// `crate::qp::nonzero_span` of each of Γ's rows.
    gamma_span: Vec<(usize, usize)>,
    x_bar: Vec<f64>,
    /// H₀ and H_w (column-major) when P is affine in the gain.
    h_affine: Option<(Vec<f64>, Vec<f64>)>,
    h: Vec<f64>,
    /// `h` changed since the solver last factored it.
    h_unfactored: bool,
    /// Rows of the sparse QP, the first `n_eq` equalities.
    m: usize,
    n_eq: usize,
    rows: Vec<RowMap>,
    n_eq_rows: usize,
    row_trips: Vec<usize>,
    /// The column and value of each of `row_trips`' triplets when its row's coefficients
    /// were last condensed; valid while `rows_condensed` (same layout, same Γ).
    condensed_entries: Vec<(usize, u64)>,
    rows_condensed: bool,
    /// Rows the last solve condensed (the others kept theirs).
    rows_condensed_last: usize,
    v: Vec<f64>,
    z: Vec<f64>,
    qp: ActiveSetQp,
}

impl CondensedQp {
    /// Sets up the condensation of the sparse QP laid out as `layout`; `a` gives the
    /// structure (and the dynamics' values). `p_at_0_1_2` is P's upper triangle at washout
    /// gains 0, 1 and 2, `p_now` at the current `gain`.
    pub fn new(
        layout: Layout,
        a: &Triplets,
        p_at_0_1_2: [&Triplets; 3],
        gain: f64,
        p_now: &Triplets,
    ) -> Result<Self, CondenseError> {
        let Layout {
            vars,
            n_dyn,
            m,
            n_eq,
        } = layout;
        let n_u = vars.iter().filter(|v| matches!(v, Var::Input(_))).count();
        let n_x = vars.len() - n_u;
        if n_x != n_dyn {
            return Err(CondenseError::Shape {
                states: n_x,
                rows: n_dyn,
            });
        }
        let mut u_cols = vec![0; n_u];
        let mut x_cols = vec![0; n_x];
        for (c, v) in vars.iter().enumerate() {
            match *v {
                Var::Input(i) if i < n_u => u_cols[i] = c,
                Var::State(i) if i < n_x => x_cols[i] = c,
                _ => return Err(CondenseError::Singular),
            }
        }
        let mut cq = CondensedQp {
            vars,
            n_u,
            n_x,
            u_cols,
            x_cols,
            dyn_trips: (0..a.len()).filter(|&t| a.rows[t] < n_dyn).collect(),
            dyn_vals: Vec::new(),
            a_x_inv: DMatrix::zeros(0, 0),
            gamma: vec![0.0; n_x * n_u],
            gamma_span: vec![(0, 0); n_x],
            x_bar: vec![0.0; n_x],
            h_affine: None,
            h: vec![0.0; n_u * n_u],
            h_unfactored: true,
            m,
            n_eq,
            rows: Vec::new(),
            n_eq_rows: 0,
            row_trips: Vec::new(),
            condensed_entries: Vec::new(),
            rows_condensed: false,
            rows_condensed_last: 0,
            v: Vec::new(),
            z: Vec::new(),
            qp: ActiveSetQp::new(n_u, 0),
        };
        cq.z = vec![0.0; cq.vars.len()];
        cq.v = vec![0.0; cq.vars.len()];
        cq.set_dynamics(a)?;
        if !cq.layout_rows(a, n_dyn) {
            return Err(CondenseError::Layout(m));
        }
        // H affine in the gain: condensed at 0 and 1, checked at 2.
        let h0 = cq.condense_p(p_at_0_1_2[0]);
        let h1 = cq.condense_p(p_at_0_1_2[1]);
        let h2 = cq.condense_p(p_at_0_1_2[2]);
        let hw: Vec<f64> = h1.iter().zip(&h0).map(|(a, b)| a - b).collect();
        let scale = h2.iter().fold(1e-300_f64, |m, v| m.max(v.abs()));
        let affine = h2
            .iter()
            .zip(h0.iter().zip(&hw))
            .all(|(h, (a, w))| (h - (a + 2.0 * w)).abs() <= 1e-10 * scale);
        if affine {
            cq.h_affine = Some((h0, hw));
        }
        cq.set_gain(gain, p_now);
        cq.factor_hessian()?;
        Ok(cq)
    }

    /// Number of inputs u the condensed QP is posed over.
    pub fn n_inputs(&self) -> usize {
        self.n_u
    }

    /// Rows of the condensed QP: equalities, inequalities (a pair of opposite sparse rows is
    /// one two-sided row).
    pub fn n_rows(&self) -> (usize, usize) {
        (self.n_eq_rows, self.rows.len() - self.n_eq_rows)
    }

    /// Whether a change of gain is an update of H₀ + gain·H_w (else a full condensation).
    pub fn is_affine_in_gain(&self) -> bool {
        self.h_affine.is_some()
    }

    /// Γ and A_x⁻¹ from the dynamics rows' current values.
    fn set_dynamics(&mut self, a: &Triplets) -> Result<(), CondenseError> {
        let (n_u, n_x) = (self.n_u, self.n_x);
        let mut a_x: DMatrix<f64> = DMatrix::zeros(n_x, n_x);
        let mut a_u = DMatrix::zeros(n_x, n_u);
        self.dyn_vals.clear();
        for &t in &self.dyn_trips {
            let (r, c, v) = (a.rows[t], a.cols[t], a.vals[t]);
            self.dyn_vals.push(v);
            match self.vars[c] {
                Var::Input(i) => a_u[(r, i)] += v,
                Var::State(i) => a_x[(r, i)] += v,
            }
        }
        let inv = a_x.try_inverse().ok_or(CondenseError::Singular)?;
        if inv.iter().any(|v| !v.is_finite()) {
            return Err(CondenseError::Singular);
        }
        let gamma = -(&inv * a_u);
        for i in 0..n_x {
            for j in 0..n_u {
                self.gamma[i * n_u + j] = gamma[(i, j)];
            }
            self.gamma_span[i] = crate::qp::nonzero_span(&self.gamma[i * n_u..(i + 1) * n_u]);
        }
        self.a_x_inv = inv;
        self.rows_condensed = false;
        Ok(())
    }

    /// Groups the non-dynamics rows' triplets by row and pairs opposite rows.
    /// False if a triplet lies beyond the rows.
    fn layout_rows(&mut self, a: &Triplets, n_dyn: usize) -> bool {
        let n_rows = self.m.max(n_dyn);
        let mut count = vec![0usize; n_rows + 1];
        if a.rows.iter().any(|&r| r >= n_rows) {
            return false;
        }
        for &r in &a.rows {
            count[r + 1] += 1;
        }
        for r in 0..n_rows {
            count[r + 1] += count[r];
        }
        let mut next = count.clone();
        self.row_trips = vec![0; a.len()];
        self.condensed_entries = vec![(usize::MAX, 0); a.len()];
        self.rows_condensed = false;
        for (t, &r) in a.rows.iter().enumerate() {
            self.row_trips[next[r]] = t;
            next[r] += 1;
        }
        self.rows.clear();
        let mut r = n_dyn;
        while r < n_rows {
            let (start, end) = (count[r], count[r + 1]);
            let paired = r >= self.n_eq && r + 1 < n_rows && self.opposite(a, &count, r);
            self.rows.push(RowMap {
                row: r,
                paired,
                start,
                end,
            });
            r += if paired { 2 } else { 1 };
        }
        self.n_eq_rows = self.rows.iter().filter(|m| m.row < self.n_eq).count();
        let (n_eq, n_in) = self.n_rows();
        self.qp.set_rows(n_eq, n_in);
        true
    }

    /// Whether rows r and r + 1 have the same columns in the same order and opposite values.
    fn opposite(&self, a: &Triplets, count: &[usize], r: usize) -> bool {
        let (s0, e0, s1, e1) = (count[r], count[r + 1], count[r + 1], count[r + 2]);
        e0 - s0 == e1 - s1
            && (0..e0 - s0).all(|k| {
                let (t0, t1) = (self.row_trips[s0 + k], self.row_trips[s1 + k]);
                a.cols[t0] == a.cols[t1] && a.vals[t0] == -a.vals[t1]
            })
    }

    /// Tᵀ P T for P's upper triangle `p` (column-major n_u × n_u).
    fn condense_p(&self, p: &Triplets) -> Vec<f64> {
        let (n_u, nz) = (self.n_u, self.vars.len());
        let mut t = DMatrix::zeros(nz, n_u);
        for (c, v) in self.vars.iter().enumerate() {
            match *v {
                Var::Input(i) => t[(c, i)] = 1.0,
                Var::State(i) => {
                    for j in 0..n_u {
                        t[(c, j)] = self.gamma[i * n_u + j];
                    }
                }
            }
        }
        let mut pt = DMatrix::zeros(nz, n_u);
        for k in 0..p.len() {
            let (r, c, v) = (p.rows[k], p.cols[k], p.vals[k]);
            for j in 0..n_u {
                pt[(r, j)] += v * t[(c, j)];
                if r != c {
                    pt[(c, j)] += v * t[(r, j)];
                }
            }
        }
        let h = t.transpose() * pt;
        // Exactly symmetric, as the factorisation reads one triangle.
        let mut out = vec![0.0; n_u * n_u];
        for c in 0..n_u {
            for r in 0..n_u {
                out[c * n_u + r] = 0.5 * (h[(r, c)] + h[(c, r)]);
            }
        }
        out
    }

    /// The Hessian for washout gain `gain`, with `p` P's upper triangle at that gain. It is
    /// factored by [`CondensedQp::factor_hessian`], or else by the next solve.
    pub fn set_gain(&mut self, gain: f64, p: &Triplets) {
        match &self.h_affine {
            Some((h0, hw)) => {
                for ((h, a), w) in self.h.iter_mut().zip(h0).zip(hw) {
                    *h = a + gain * w;
                }
            }
            None => self.h = self.condense_p(p),
        }
        self.h_unfactored = true;
    }

    /// Factors the Hessian last set, if it has not been: an error says it is not positive
    /// definite (then every solve reports a numerical error until another is set).
    pub fn factor_hessian(&mut self) -> Result<(), CondenseError> {
        if self.h_unfactored {
            self.h_unfactored = false;
            self.qp.set_hessian(&self.h)?;
        }
        Ok(())
    }

    /// Condenses this step's QP and solves it. `p` is P's upper triangle (as last given to
    /// `set_gain`), `q`, `a` and `b` the sparse QP's current values.
    pub fn solve(
        &mut self,
        p: &Triplets,
        q: &[f64],
        a: &Triplets,
        b: &[f64],
        settings: &QpSettings,
    ) -> QpStatus {
        if q.len() != self.vars.len() || a.len() != self.row_trips.len() || b.len() != self.m {
            return QpStatus::NumericalError;
        }
        // The dynamics are constant; should they ever change, Γ and H follow.
        let changed = self
            .dyn_trips
            .iter()
            .zip(&self.dyn_vals)
            .any(|(&t, &v)| a.vals[t] != v);
        if changed {
            if self.set_dynamics(a).is_err() {
                return QpStatus::NumericalError;
            }
            self.h_affine = None;
            self.h = self.condense_p(p);
            self.h_unfactored = true;
        }
        if self.factor_hessian().is_err() {
            return QpStatus::NumericalError;
        }
        // x̄ = A_x⁻¹ b_dyn, over b_dyn's nonzeros (A_x⁻¹ column-major: column r contiguous).
        let (n_u, n_x) = (self.n_u, self.n_x);
        self.x_bar.fill(0.0);
        let inv = self.a_x_inv.as_slice();
        for (r, &br) in b.iter().enumerate().take(n_x) {
            if br != 0.0 {
                let col = &inv[r * n_x..(r + 1) * n_x];
                for (x, c) in self.x_bar.iter_mut().zip(col) {
                    *x += br * c;
                }
            }
        }
        // v = q + P z̄, then g = Tᵀ v.
        self.z.fill(0.0);
        for (i, &c) in self.x_cols.iter().enumerate() {
            self.z[c] = self.x_bar[i];
        }
        self.v.copy_from_slice(q);
        for k in 0..p.len() {
            let (r, c, val) = (p.rows[k], p.cols[k], p.vals[k]);
            self.v[r] += val * self.z[c];
            if r != c {
                self.v[c] += val * self.z[r];
            }
        }
        {
            let g = self.qp.gradient_mut();
            for (j, gj) in g.iter_mut().enumerate() {
                *gj = self.v[self.u_cols[j]];
            }
            for i in 0..n_x {
                let vx = self.v[self.x_cols[i]];
                if vx != 0.0 {
                    let (lo, hi) = gamma_span(&self.gamma_span, i, vx, n_u);
                    let row = &self.gamma[i * n_u + lo..i * n_u + hi];
                    for (gj, gam) in g[lo..hi].iter_mut().zip(row) {
                        *gj += vx * gam;
                    }
                }
            }
        }
        // Rows: a pair whose values stopped being opposite means a new structure.
        if !self.fill_rows(a, b) {
            let n_dyn = self.n_x;
            self.qp.clear_warm_start();
            if !self.layout_rows(a, n_dyn) || !self.fill_rows(a, b) {
                return QpStatus::NumericalError;
            }
        }
        let status = self.qp.solve(settings);
        if status == QpStatus::Solved {
            let u = self.qp.solution();
            for (j, &c) in self.u_cols.iter().enumerate() {
                self.z[c] = u[j];
            }
            for i in 0..n_x {
                // The solution is finite (the solver checks): the span's dot is the whole's.
                let (lo, hi) = self.gamma_span[i];
                let row = &self.gamma[i * n_u + lo..i * n_u + hi];
                self.z[self.x_cols[i]] = self.x_bar[i] + crate::qp::dot(row, &u[lo..hi]);
            }
        }
        status
    }

    /// Writes every condensed row whose sparse entries changed, and every row's bounds; false
    /// if a pair is no longer opposite.
    fn fill_rows(&mut self, a: &Triplets, b: &[f64]) -> bool {
        let n_u = self.n_u;
        self.rows_condensed_last = 0;
        for k in 0..self.rows.len() {
            let m = self.rows[k];
            let len = m.end - m.start;
            // A pair's second row (right after the first in `row_trips`) is compared too.
            let entries = m.start..if m.paired { m.end + len } else { m.end };
            // Compared bit for bit, so that a kept row is exactly the one condensing would
            // write (the solver keeps its coefficients, norm and span).
            let unchanged = self.rows_condensed
                && entries.clone().all(|j| {
                    let t = self.row_trips[j];
                    self.condensed_entries[j] == (a.cols[t], a.vals[t].to_bits())
                });
            // A pair kept is still opposite: it was when it was condensed.
            if m.paired && !unchanged {
                for j in 0..len {
                    let (t0, t1) = (self.row_trips[m.start + j], self.row_trips[m.end + j]);
                    if a.vals[t0] != -a.vals[t1] {
                        return false;
                    }
                }
            }
            let mut shift = 0.0;
            if unchanged {
                for &t in &self.row_trips[m.start..m.end] {
                    if let Var::State(i) = self.vars[a.cols[t]] {
                        shift += a.vals[t] * self.x_bar[i];
                    }
                }
            } else {
                self.rows_condensed_last += 1;
                for j in entries {
                    let t = self.row_trips[j];
                    self.condensed_entries[j] = (a.cols[t], a.vals[t].to_bits());
                }
                let out = self.qp.row_mut(k);
                out.fill(0.0);
                for j in m.start..m.end {
                    let t = self.row_trips[j];
                    let val = a.vals[t];
                    match self.vars[a.cols[t]] {
                        Var::Input(i) => out[i] += val,
                        Var::State(i) => {
                            shift += val * self.x_bar[i];
                            let (lo, hi) = gamma_span(&self.gamma_span, i, val, n_u);
                            let row = &self.gamma[i * n_u + lo..i * n_u + hi];
                            for (o, g) in out[lo..hi].iter_mut().zip(row) {
                                *o += val * g;
                            }
                        }
                    }
                }
            }
            let hi = b[m.row] - shift;
            if m.row < self.n_eq {
                self.qp.set_bounds(k, hi, hi);
            } else if m.paired {
                // −a u ≤ b₂ − (−a_x x̄)  ⇔  a u ≥ −b₂ − a_x x̄.
                self.qp.set_bounds(k, -b[m.row + 1] - shift, hi);
            } else {
                self.qp.set_bounds(k, f64::NEG_INFINITY, hi);
            }
        }
        self.rows_condensed = true;
        true
    }

    /// The full sparse vector z = (u, x) of the last solve (valid after `Solved`).
    pub fn z(&self) -> &[f64] {
        &self.z
    }

    /// Active-set iterations of the last solve.
    pub fn iterations(&self) -> u32 {
        self.qp.iterations()
    }

    /// The condensed QP's objective, without the constant ½z̄ᵀPz̄ + qᵀz̄.
    pub fn objective(&self) -> f64 {
        self.qp.objective()
    }

    /// Forgets the warm start (after a reset or a jump of the state).
    pub fn clear_warm_start(&mut self) {
        self.qp.clear_warm_start();
    }

    /// The Hessian in use (column-major n_u × n_u).
    pub fn hessian(&self) -> &[f64] {
        &self.h
    }

    /// Tᵀ P T condensed in full, for checking the affine update.
    #[cfg(test)]
    pub fn condense_full(&self, p: &Triplets) -> Vec<f64> {
        self.condense_p(p)
    }
}

/// The part of Γ's row `i` that a product with the factor `f` must read: its nonzero span, or
/// the whole row when `f` is not finite (∞ · 0 is NaN, which the whole row then carries, as
/// before the spans).
#[inline]
fn gamma_span(spans: &[(usize, usize)], i: usize, f: f64, n_u: usize) -> (usize, usize) {
    if f.is_finite() {
        spans[i]
    } else {
        (0, n_u)
    }
}

/// ½zᵀPz + qᵀz for P's upper triangle `p`: the sparse QP's objective.
pub fn sparse_objective(p: &Triplets, q: &[f64], z: &[f64]) -> f64 {
    let mut f: f64 = q.iter().zip(z).map(|(a, b)| a * b).sum();
    for k in 0..p.len() {
        let (r, c, v) = (p.rows[k], p.cols[k], p.vals[k]);
        f += if r == c {
            0.5 * v * z[r] * z[r]
        } else {
            v * z[r] * z[c]
        };
    }
    f
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::super::{Mpc, Terminal};
    use crate::mca::{CueInput, CueSample, PlatformCommand};
    use crate::qp::{QpSettings, QpStatus};
    use crate::testing::full_flight;

    /// The condensed QP a step leaves in the MPC's solver, against the same step's sparse QP
    /// condensed afresh by a new `CondensedQp`: every row's coefficients and bounds and the
    /// gradient the same to the bit, though the kept solver wrote only the rows whose sparse
    /// entries changed and reads Γ over its rows' nonzero spans; and the same solution (the
    /// kept solver warm-started, with a Hessian factored lazily after gain changes, the new
    /// one cold), to the solver's tolerance.
    #[test]
    fn kept_rows_are_the_rows_condensed_afresh() {
        let p = full_flight().offline();
        for terminal in [Terminal::Free, Terminal::Cotc] {
            let params = match terminal {
                Terminal::Cotc => p.cotc_params(),
                Terminal::Free => p.mpc.clone(),
            };
            let mut mpc = Mpc::new(&params, &p.setting(), terminal).unwrap();
            let mut applied = PlatformCommand::default();
            let (mut kept_rows, mut changed_rows) = (0usize, 0usize);
            for k in 0..60 {
                let t = k as f64 * 0.01;
                // A surge that reverses (the false-cue rows' signs flip), a roll rate, and
                // every few steps a new washout gain (factored only when the MPC solves).
                if k % 7 == 3 {
                    mpc.set_washout_gain(1.0 + 0.5 * (k % 3) as f64);
                    mpc.set_washout_gain(1.0 + 0.25 * (k % 5) as f64);
                }
                let sample = CueSample {
                    delta_f_mps2: Vector3::new(2.0 * (6.0 * t).sin(), 0.3, -0.5 * t),
                    angular_velocity_radps: Vector3::new(0.1 * (4.0 * t).cos(), 0.0, 0.05),
                };
                let input = CueInput {
                    k,
                    t_s: t,
                    dt_s: 0.01,
                    sample,
                    preview: &[],
                    applied: &applied,
                    deadline: None,
                };
                let out = mpc.solve(&input);
                applied = out.command;
                let mut fresh = mpc.condense().expect("condenses");
                let kept = mpc.condensed.as_ref().expect("condensed");
                let settings = QpSettings::default();
                let status = fresh.solve(&mpc.p_trip, &mpc.q, &mpc.a_trip, &mpc.b, &settings);
                let (a, b) = (&kept.qp, &fresh.qp);
                assert_eq!(a.n_rows(), b.n_rows());
                let (eq, ineq) = a.n_rows();
                for r in 0..eq + ineq {
                    let same = |x: &[f64], y: &[f64]| {
                        x.iter().zip(y).all(|(u, v)| u.to_bits() == v.to_bits())
                    };
                    assert!(same(a.row(r), b.row(r)), "{terminal:?} step {k} row {r}");
                    let (lo_a, hi_a) = a.bounds(r);
                    let (lo_b, hi_b) = b.bounds(r);
                    assert_eq!(lo_a.to_bits(), lo_b.to_bits(), "step {k} row {r} lo");
                    assert_eq!(hi_a.to_bits(), hi_b.to_bits(), "step {k} row {r} hi");
                }
                let same_g = (a.gradient().iter())
                    .zip(b.gradient())
                    .all(|(u, v)| u.to_bits() == v.to_bits());
                assert!(same_g, "{terminal:?} step {k}: gradient");
                if out.report.status == crate::mca::SolveStatus::Solved {
                    assert_eq!(status, QpStatus::Solved, "{terminal:?} step {k}");
                    let dz = kept
                        .z()
                        .iter()
                        .zip(fresh.z())
                        .map(|(u, v)| (u - v).abs())
                        .fold(0.0, f64::max);
                    assert!(dz < 1e-7, "{terminal:?} step {k}: solutions differ by {dz}");
                }
                // The fresh one condensed every row; the kept one, after its first step, only
                // some (the legs' linearisation moves every step, the excursions' rows never).
                assert_eq!(fresh.rows_condensed_last, eq + ineq);
                if k > 0 {
                    changed_rows += kept.rows_condensed_last;
                    kept_rows += eq + ineq - kept.rows_condensed_last;
                }
            }
            assert!(kept_rows > 0, "{terminal:?}: no row kept");
            assert!(changed_rows > 0, "{terminal:?}: no row condensed again");
        }
    }
}
