use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettings, DefaultSolver, IPSolver, SolverStatus, SupportedConeT};

use super::*;

/// A dense QP in the solver's form, for building tests and the reference.
#[derive(Clone, Debug)]
struct Problem {
    n: usize,
    /// Column-major.
    h: Vec<f64>,
    g: Vec<f64>,
    rows: Vec<Vec<f64>>,
    lo: Vec<f64>,
    hi: Vec<f64>,
    n_eq: usize,
}

impl Problem {
    fn load(&self, qp: &mut ActiveSetQp) {
        qp.set_hessian(&self.h).expect("positive definite");
        qp.gradient_mut().copy_from_slice(&self.g);
        qp.set_rows(self.n_eq, self.rows.len() - self.n_eq);
        for (k, r) in self.rows.iter().enumerate() {
            qp.row_mut(k).copy_from_slice(r);
            qp.set_bounds(k, self.lo[k], self.hi[k]);
        }
    }

    fn solve(&self, warm: &[ActiveRow]) -> (QpStatus, Vec<f64>, f64, u32) {
        let mut qp = ActiveSetQp::new(self.n, self.rows.len());
        self.load(&mut qp);
        qp.set_warm_start(warm);
        let st = qp.solve(&QpSettings::default());
        (st, qp.solution().to_vec(), qp.objective(), qp.iterations())
    }

    fn objective(&self, x: &[f64]) -> f64 {
        let n = self.n;
        let mut f = 0.0;
        for c in 0..n {
            for r in 0..n {
                f += 0.5 * x[r] * self.h[c * n + r] * x[c];
            }
            f += self.g[c] * x[c];
        }
        f
    }

    /// Largest violation of any row at x.
    fn violation(&self, x: &[f64]) -> f64 {
        let mut worst: f64 = 0.0;
        for (k, r) in self.rows.iter().enumerate() {
            let v: f64 = r.iter().zip(x).map(|(a, b)| a * b).sum();
            worst = worst.max(self.lo[k] - v).max(v - self.hi[k]);
        }
        worst
    }

    /// Clarabel's answer, to tight tolerances.
    fn clarabel(&self) -> (SolverStatus, Vec<f64>, f64) {
        let n = self.n;
        let upper: Vec<Vec<f64>> = (0..n)
            .map(|r| {
                (0..n)
                    .map(|c| if r <= c { self.h[c * n + r] } else { 0.0 })
                    .collect()
            })
            .collect();
        let p = dense_csc(&upper, n);
        let mut a_rows = Vec::new();
        let mut b = Vec::new();
        for k in 0..self.n_eq {
            a_rows.push(self.rows[k].clone());
            b.push(self.lo[k]);
        }
        for k in self.n_eq..self.rows.len() {
            if self.hi[k].is_finite() {
                a_rows.push(self.rows[k].clone());
                b.push(self.hi[k]);
            }
            if self.lo[k].is_finite() {
                a_rows.push(self.rows[k].iter().map(|v| -v).collect());
                b.push(-self.lo[k]);
            }
        }
        let a = dense_csc(&a_rows, n);
        let cones = [
            SupportedConeT::ZeroConeT(self.n_eq),
            SupportedConeT::NonnegativeConeT(a_rows.len() - self.n_eq),
        ];
        let settings = DefaultSettings {
            verbose: false,
            tol_gap_abs: 1e-12,
            tol_gap_rel: 1e-12,
            tol_feas: 1e-12,
            tol_ktratio: 1e-10,
            max_iter: 200,
            ..DefaultSettings::default()
        };
        let mut solver = DefaultSolver::new(&p, &self.g, &a, &b, &cones, settings).unwrap();
        solver.solve();
        let s = &solver.solution;
        (s.status, s.x.clone(), s.obj_val)
    }
}

fn dense_csc(rows: &[Vec<f64>], ncols: usize) -> CscMatrix<f64> {
    let mut colptr = vec![0];
    let mut rowval = Vec::new();
    let mut nzval = Vec::new();
    for c in 0..ncols {
        for (r, row) in rows.iter().enumerate() {
            if row[c] != 0.0 {
                rowval.push(r);
                nzval.push(row[c]);
            }
        }
        colptr.push(rowval.len());
    }
    CscMatrix::new(rows.len(), ncols, colptr, rowval, nzval)
}

/// SplitMix64: reproducible random numbers without a dependency.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
}

/// A strictly convex QP whose rows hold at a known point, with a mix of two-sided,
/// one-sided, equality, duplicated and parallel rows.
fn random_feasible(rng: &mut Rng) -> Problem {
    let n = 1 + rng.below(40);
    let n_eq = rng.below(n.min(6) + 1).min(n - 1);
    let n_in = rng.below(3 * n + 10);
    let k = n + rng.below(4);
    let m: Vec<Vec<f64>> = (0..k)
        .map(|_| (0..n).map(|_| rng.range(-1.0, 1.0)).collect())
        .collect();
    let delta = rng.range(1e-2, 1.0);
    let mut h = vec![0.0; n * n];
    for c in 0..n {
        for r in 0..n {
            h[c * n + r] = m.iter().map(|row| row[r] * row[c]).sum::<f64>();
        }
        h[c * n + c] += delta;
    }
    let scale = rng.range(0.1, 10.0);
    let g: Vec<f64> = (0..n).map(|_| scale * rng.range(-3.0, 3.0)).collect();
    let x_feas: Vec<f64> = (0..n).map(|_| rng.range(-1.0, 1.0)).collect();
    let mut rows: Vec<Vec<f64>> = Vec::new();
    let (mut lo, mut hi) = (Vec::new(), Vec::new());
    let dot = |r: &[f64]| r.iter().zip(&x_feas).map(|(a, b)| a * b).sum::<f64>();
    for i in 0..n_eq + n_in {
        let row: Vec<f64> = if i > 0 && rng.unit() < 0.08 {
            // Parallel (or duplicate) to an earlier row.
            let j = rng.below(i);
            let f = if rng.unit() < 0.5 {
                1.0
            } else {
                rng.range(0.2, 5.0)
            };
            rows[j].iter().map(|v| f * v).collect()
        } else if rng.unit() < 0.3 {
            // A simple bound, as most of the MPC's rows are.
            let mut r = vec![0.0; n];
            r[rng.below(n)] = 1.0;
            r
        } else {
            (0..n).map(|_| rng.range(-1.0, 1.0)).collect()
        };
        let v = dot(&row);
        if i < n_eq {
            lo.push(v);
            hi.push(v);
        } else {
            match rng.below(4) {
                0 => {
                    lo.push(f64::NEG_INFINITY);
                    hi.push(v + rng.range(0.0, 0.5));
                }
                1 => {
                    lo.push(v - rng.range(0.0, 0.5));
                    hi.push(f64::INFINITY);
                }
                _ => {
                    lo.push(v - rng.range(0.0, 1.0));
                    hi.push(v + rng.range(0.0, 1.0));
                }
            }
        }
        rows.push(row);
    }
    Problem {
        n,
        h,
        g,
        rows,
        lo,
        hi,
        n_eq,
    }
}

fn assert_matches_clarabel(p: &Problem, x: &[f64], f: f64, what: &str) {
    let (status, xr, fr) = p.clarabel();
    assert_eq!(
        status,
        SolverStatus::Solved,
        "{what}: Clarabel did not solve"
    );
    assert!(
        (f - fr).abs() <= 1e-8 * fr.abs().max(1.0),
        "{what}: objective {f} vs Clarabel {fr}"
    );
    let dx = x
        .iter()
        .zip(&xr)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(dx <= 1e-6, "{what}: solution differs by {dx}");
    assert!((p.objective(x) - f).abs() <= 1e-9 * f.abs().max(1.0));
}

#[test]
fn a_thousand_random_strictly_convex_qps_match_clarabel() {
    let mut rng = Rng(12);
    let mut with_active = 0;
    for case in 0..1000 {
        let p = random_feasible(&mut rng);
        let mut qp = ActiveSetQp::new(p.n, p.rows.len());
        p.load(&mut qp);
        let st = qp.solve(&QpSettings::default());
        assert_eq!(st, QpStatus::Solved, "case {case}: {p:?}");
        assert!(p.violation(qp.solution()) < 1e-8, "case {case}");
        assert_matches_clarabel(&p, qp.solution(), qp.objective(), &format!("case {case}"));
        if qp.active_set().len() > p.n_eq {
            with_active += 1;
        }
        // The multipliers of active inequalities are ≥ 0 (dual feasibility).
        for (a, m) in qp.active_set().iter().zip(qp.multipliers()) {
            if a.side != Side::Equal {
                assert!(*m >= -1e-9, "case {case}: multiplier {m}");
            }
        }
    }
    // The generator must exercise the active set, not only interior optima.
    assert!(
        with_active > 700,
        "{with_active} of 1000 with an active row"
    );
}

#[test]
fn wrong_warm_starts_give_the_cold_answer() {
    let mut rng = Rng(7);
    for case in 0..300 {
        let p = random_feasible(&mut rng);
        let (st, x_cold, f_cold, _) = p.solve(&[]);
        assert_eq!(st, QpStatus::Solved);
        let m = p.rows.len();
        // Random rows on random sides, rows out of range, equality rows claimed as
        // inequalities, repeats: anything a stale or corrupted working set could hold.
        let mut warm = Vec::new();
        for _ in 0..rng.below(2 * p.n + 3) {
            let side = match rng.below(3) {
                0 => Side::Lower,
                1 => Side::Upper,
                _ => Side::Equal,
            };
            warm.push(ActiveRow {
                row: rng.below(m + 3),
                side,
            });
        }
        // And every row on both sides.
        let all: Vec<ActiveRow> = (0..m)
            .flat_map(|row| {
                [Side::Lower, Side::Upper]
                    .into_iter()
                    .map(move |side| ActiveRow { row, side })
            })
            .collect();
        for w in [&warm, &all] {
            let (st, x, f, _) = p.solve(w);
            assert_eq!(st, QpStatus::Solved, "case {case}");
            assert!(
                (f - f_cold).abs() <= 1e-9 * f_cold.abs().max(1.0),
                "case {case}"
            );
            let dx = x
                .iter()
                .zip(&x_cold)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(dx < 1e-7, "case {case}: {dx}");
        }
    }
}

#[test]
fn the_previous_active_set_is_the_next_warm_start_and_saves_iterations() {
    let mut rng = Rng(99);
    let (mut cold_total, mut warm_total) = (0, 0);
    for _ in 0..100 {
        let mut p = random_feasible(&mut rng);
        let mut qp = ActiveSetQp::new(p.n, p.rows.len());
        p.load(&mut qp);
        assert_eq!(qp.solve(&QpSettings::default()), QpStatus::Solved);
        let warm: Vec<ActiveRow> = qp.warm_start().to_vec();
        let active_ineq = qp.active_set().iter().filter(|a| a.side != Side::Equal);
        assert!(warm.iter().copied().eq(active_ineq.copied()));
        // The next problem differs a little, as consecutive MPC steps do.
        for v in p.g.iter_mut() {
            *v += 0.01 * rng.range(-1.0, 1.0);
        }
        qp.gradient_mut().copy_from_slice(&p.g);
        assert_eq!(qp.solve(&QpSettings::default()), QpStatus::Solved);
        warm_total += qp.iterations();
        let (st, x_cold, f_cold, it_cold) = p.solve(&[]);
        assert_eq!(st, QpStatus::Solved);
        cold_total += it_cold;
        assert!((qp.objective() - f_cold).abs() <= 1e-9 * f_cold.abs().max(1.0));
        assert!(qp
            .solution()
            .iter()
            .zip(&x_cold)
            .all(|(a, b)| (a - b).abs() < 1e-7));
    }
    assert!(
        warm_total * 2 < cold_total,
        "warm {warm_total} vs cold {cold_total} iterations"
    );
}

fn identity(n: usize, w: f64) -> Vec<f64> {
    let mut h = vec![0.0; n * n];
    for i in 0..n {
        h[i * n + i] = w;
    }
    h
}

fn problem(n: usize, g: &[f64], rows: &[(&[f64], f64, f64)], n_eq: usize) -> Problem {
    Problem {
        n,
        h: identity(n, 1.0),
        g: g.to_vec(),
        rows: rows.iter().map(|r| r.0.to_vec()).collect(),
        lo: rows.iter().map(|r| r.1).collect(),
        hi: rows.iter().map(|r| r.2).collect(),
        n_eq,
    }
}

const INF: f64 = f64::INFINITY;

#[test]
fn degenerate_rows_duplicate_parallel_and_redundant() {
    // min ½|u|² − u₁ − u₂ (optimum (1, 1) unconstrained) pushed to u ≤ 0.5 by duplicated,
    // parallel and redundant rows: three rows through the same optimum in two dimensions.
    let cases: Vec<Problem> = vec![
        problem(
            2,
            &[-1.0, -1.0],
            &[
                (&[1.0, 0.0], -INF, 0.5),
                (&[1.0, 0.0], -INF, 0.5),
                (&[2.0, 0.0], -INF, 1.0),
                (&[0.0, 1.0], -INF, 0.5),
                (&[1.0, 1.0], -INF, 1.0),
                (&[-1.0, -1.0], -1.0, INF),
            ],
            0,
        ),
        // Degenerate vertex: u₁ + u₂ ≥ 2, u₁ ≥ 1, u₂ ≥ 1 from the origin's optimum.
        problem(
            2,
            &[0.0, 0.0],
            &[
                (&[1.0, 1.0], 2.0, INF),
                (&[1.0, 0.0], 1.0, INF),
                (&[0.0, 1.0], 1.0, INF),
            ],
            0,
        ),
        // An equality row repeated and scaled, and an inequality parallel to it.
        problem(
            3,
            &[1.0, -2.0, 0.5],
            &[
                (&[1.0, 1.0, 1.0], 1.0, 1.0),
                (&[2.0, 2.0, 2.0], 2.0, 2.0),
                (&[1.0, 1.0, 1.0], 1.0, 1.0),
                (&[1.0, 1.0, 1.0], -INF, 1.0),
                (&[0.0, 1.0, 0.0], -INF, 0.2),
            ],
            3,
        ),
    ];
    for (i, p) in cases.iter().enumerate() {
        let (st, x, f, _) = p.solve(&[]);
        assert_eq!(st, QpStatus::Solved, "case {i}");
        assert_matches_clarabel(p, &x, f, &format!("case {i}"));
    }
    let (_, x, _, _) = cases[0].solve(&[]);
    assert!((x[0] - 0.5).abs() < 1e-12 && (x[1] - 0.5).abs() < 1e-12);
    let (_, x, _, _) = cases[1].solve(&[]);
    assert!((x[0] - 1.0).abs() < 1e-12 && (x[1] - 1.0).abs() < 1e-12);
}

#[test]
fn infeasible_rows_are_reported_not_solved() {
    let cases: Vec<(&str, Problem)> = vec![
        (
            "opposite bounds",
            problem(
                2,
                &[0.0, 0.0],
                &[(&[1.0, 0.0], 1.0, INF), (&[1.0, 0.0], -INF, 0.0)],
                0,
            ),
        ),
        ("lo above hi", problem(1, &[0.0], &[(&[1.0], 1.0, 0.5)], 0)),
        (
            "inconsistent equalities",
            problem(
                2,
                &[0.0, 0.0],
                &[(&[1.0, 1.0], 1.0, 1.0), (&[2.0, 2.0], 3.0, 3.0)],
                2,
            ),
        ),
        (
            "equality against an inequality",
            problem(
                2,
                &[1.0, 0.0],
                &[
                    (&[1.0, 1.0], 1.0, 1.0),
                    (&[1.0, 0.0], -INF, -1.0),
                    (&[0.0, 1.0], -INF, 1.0),
                ],
                1,
            ),
        ),
        (
            "an empty row that cannot hold",
            problem(2, &[0.0, 0.0], &[(&[0.0, 0.0], 1.0, INF)], 0),
        ),
        (
            "a triangle with no inside",
            problem(
                2,
                &[0.3, -0.2],
                &[
                    (&[1.0, 0.0], 0.0, INF),
                    (&[0.0, 1.0], 0.0, INF),
                    (&[1.0, 1.0], -INF, -0.1),
                ],
                0,
            ),
        ),
    ];
    for (what, p) in &cases {
        let (st, ..) = p.solve(&[]);
        assert_eq!(st, QpStatus::Infeasible, "{what}");
        // With a warm start of every row, too.
        let all: Vec<ActiveRow> = (0..p.rows.len())
            .map(|row| ActiveRow {
                row,
                side: Side::Lower,
            })
            .collect();
        assert_eq!(p.solve(&all).0, QpStatus::Infeasible, "{what}, warm");
    }
    // Random infeasible problems agree with Clarabel's verdict: a feasible problem with one
    // row's bounds moved beyond what the other rows allow.
    let mut rng = Rng(3);
    let mut found = 0;
    for _ in 0..200 {
        let mut p = random_feasible(&mut rng);
        if p.rows.len() < 2 || p.rows.len() == p.n_eq {
            continue;
        }
        let k = p.n_eq + rng.below(p.rows.len() - p.n_eq);
        let bound = p.rows[k].iter().map(|v| v.abs()).sum::<f64>() * 5.0 + 5.0;
        p.lo[k] = bound;
        p.hi[k] = INF;
        // A box keeps every variable within ±1, so the row cannot reach its bound.
        for i in 0..p.n {
            let mut r = vec![0.0; p.n];
            r[i] = 1.0;
            p.rows.push(r);
            p.lo.push(-1.0);
            p.hi.push(1.0);
        }
        let (st, ..) = p.solve(&[]);
        let (cst, ..) = p.clarabel();
        assert_eq!(cst, SolverStatus::PrimalInfeasible);
        assert_eq!(st, QpStatus::Infeasible);
        found += 1;
    }
    assert!(found > 100);
}

#[test]
fn terminal_equalities_like_cotc() {
    // A chain x_{i+1} = x_i + u_i with x_0 = 0 condensed to the inputs: the terminal state
    // fixed (x_N = 1) and zero input in the last interval, as COTC's terminal rows do, with
    // the inputs bounded.
    let n = 8;
    let mut p = problem(n, &vec![0.0; n], &[], 0);
    for i in 0..n {
        p.g[i] = if i % 2 == 0 { 0.3 } else { -0.1 };
    }
    p.rows.push(vec![1.0; n]);
    p.lo.push(1.0);
    p.hi.push(1.0);
    let mut last = vec![0.0; n];
    last[n - 1] = 1.0;
    p.rows.push(last);
    p.lo.push(0.0);
    p.hi.push(0.0);
    p.n_eq = 2;
    for i in 0..n {
        let mut r = vec![0.0; n];
        r[i] = 1.0;
        p.rows.push(r);
        p.lo.push(-0.1);
        p.hi.push(0.2);
    }
    let (st, x, f, _) = p.solve(&[]);
    assert_eq!(st, QpStatus::Solved);
    assert!((x.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    assert!(x[n - 1].abs() < 1e-12);
    assert_matches_clarabel(&p, &x, f, "terminal");
    // Beyond what the bounds allow in the remaining intervals: infeasible.
    p.lo[0] = 1.5;
    p.hi[0] = 1.5;
    assert_eq!(p.solve(&[]).0, QpStatus::Infeasible);
}

#[test]
fn limits_and_bad_data_give_a_status() {
    let mut rng = Rng(5);
    let p = loop {
        let p = random_feasible(&mut rng);
        let (_, _, _, it) = p.solve(&[]);
        if it >= 3 {
            break p;
        }
    };
    let mut qp = ActiveSetQp::new(p.n, p.rows.len());
    p.load(&mut qp);
    let capped = QpSettings {
        max_iterations: 1,
        ..QpSettings::default()
    };
    assert_eq!(qp.solve(&capped), QpStatus::MaxIterations);
    let timed = QpSettings {
        // A deadline already past.
        deadline: Some(std::time::Instant::now()),
        ..QpSettings::default()
    };
    qp.clear_warm_start();
    assert_eq!(qp.solve(&timed), QpStatus::MaxTime);
    // Non-finite data.
    qp.gradient_mut()[0] = f64::NAN;
    assert_eq!(qp.solve(&QpSettings::default()), QpStatus::NumericalError);
    qp.gradient_mut()[0] = 0.0;
    qp.row_mut(0)[0] = f64::INFINITY;
    assert_eq!(qp.solve(&QpSettings::default()), QpStatus::NumericalError);
    // A Hessian that is not positive definite is refused, and no solve follows it.
    let mut h = identity(p.n, 1.0);
    h[0] = -1.0;
    assert!(matches!(
        qp.set_hessian(&h),
        Err(QpError::NotPositiveDefinite { column: 0 })
    ));
    assert_eq!(qp.solve(&QpSettings::default()), QpStatus::NumericalError);
    assert!(qp.set_hessian(&[1.0]).is_err() || p.n == 1);
    // No Hessian at all.
    let mut fresh = ActiveSetQp::new(2, 0);
    assert_eq!(
        fresh.solve(&QpSettings::default()),
        QpStatus::NumericalError
    );
}

#[test]
fn a_new_hessian_replaces_the_factor() {
    // min ½ w u² − u: u = 1/w, for several w on one solver.
    let mut qp = ActiveSetQp::new(1, 1);
    qp.gradient_mut()[0] = -1.0;
    qp.set_rows(0, 1);
    qp.row_mut(0)[0] = 1.0;
    qp.set_bounds(0, -INF, 0.3);
    for w in [1.0, 2.0, 4.0, 10.0] {
        qp.set_hessian(&[w]).unwrap();
        assert_eq!(qp.solve(&QpSettings::default()), QpStatus::Solved);
        assert!(
            (qp.solution()[0] - (1.0 / w).min(0.3)).abs() < 1e-14,
            "w {w}"
        );
    }
}

#[test]
fn a_sequence_of_changing_qps_on_one_solver_matches_cold_solves() {
    // As in the MPC: one solver, many solves in a row, the gradient, the bounds and some
    // rows' coefficients changing each time; the kept factors must never change the answer.
    // Longer than the factors are kept, so their rebuild is crossed as well.
    let mut rng = Rng(2024);
    for _ in 0..12 {
        let mut p = random_feasible(&mut rng);
        let mut qp = ActiveSetQp::new(p.n, p.rows.len());
        p.load(&mut qp);
        let m = p.rows.len();
        for step in 0..2 * REBUILD_EVERY + 7 {
            for v in p.g.iter_mut() {
                *v += 0.05 * rng.range(-1.0, 1.0);
            }
            if m > p.n_eq {
                for _ in 0..2 {
                    let k = p.n_eq + rng.below(m - p.n_eq);
                    if rng.unit() < 0.5 {
                        // New coefficients, bounds kept feasible around zero's neighbourhood.
                        for v in p.rows[k].iter_mut() {
                            *v += 0.1 * rng.range(-1.0, 1.0);
                        }
                    }
                    let w = rng.range(0.05, 1.0);
                    if p.lo[k].is_finite() {
                        p.lo[k] = -w;
                    }
                    if p.hi[k].is_finite() {
                        p.hi[k] = w;
                    }
                }
            }
            // Equalities hold at 0 (rhs 0) so that zero stays feasible whatever changes.
            for k in 0..p.n_eq {
                p.lo[k] = 0.0;
                p.hi[k] = 0.0;
            }
            for k in p.n_eq..m {
                p.lo[k] = p.lo[k].min(0.0);
                p.hi[k] = p.hi[k].max(0.0);
            }
            qp.gradient_mut().copy_from_slice(&p.g);
            for k in 0..m {
                qp.row_mut(k).copy_from_slice(&p.rows[k]);
                qp.set_bounds(k, p.lo[k], p.hi[k]);
            }
            let st = qp.solve(&QpSettings::default());
            let (cold_st, x_cold, f_cold, _) = p.solve(&[]);
            assert_eq!(st, cold_st, "step {step}");
            assert_eq!(st, QpStatus::Solved, "step {step}");
            assert!(
                (qp.objective() - f_cold).abs() <= 1e-9 * f_cold.abs().max(1.0),
                "step {step}: {} vs {f_cold}",
                qp.objective()
            );
            let dx = qp
                .solution()
                .iter()
                .zip(&x_cold)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(dx < 1e-7, "step {step}: {dx}");
        }
    }
}

#[test]
fn the_nonzero_span_by_hand() {
    assert_eq!(nonzero_span(&[]), (0, 0));
    assert_eq!(nonzero_span(&[0.0; 9]), (0, 0));
    assert_eq!(nonzero_span(&[1.0]), (0, 1));
    // First nonzero at 5, last at 5: the group of four [4, 8), cut at the length 7.
    assert_eq!(nonzero_span(&[0.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0]), (4, 7));
    // 3 and 8: from the group starting at 0 to the one ending at 12.
    let mut a = [0.0; 12];
    a[3] = -1.0;
    a[8] = 1.0;
    assert_eq!(nonzero_span(&a), (0, 12));
    // −0.0 is a zero; NaN is not.
    assert_eq!(nonzero_span(&[-0.0, 0.0, 0.0, 0.0, f64::NAN]), (4, 5));
}

#[test]
fn a_dot_over_the_nonzero_span_is_the_whole_dot_to_the_bit() {
    // Rows with zeros before, after and between their nonzeros (some −0.0), of every length
    // against every group-of-four phase, times finite vectors: the same f64, bit for bit.
    let mut rng = Rng(37);
    for _ in 0..5000 {
        let n = 1 + rng.below(90);
        let first = rng.below(n);
        let last = first + rng.below(n - first);
        let a: Vec<f64> = (0..n)
            .map(|i| {
                if i < first || i > last || rng.unit() < 0.3 {
                    if rng.unit() < 0.5 {
                        0.0
                    } else {
                        -0.0
                    }
                } else {
                    rng.range(-1e3, 1e3) * 10f64.powi(rng.below(9) as i32 - 4)
                }
            })
            .collect();
        let b: Vec<f64> = (0..n).map(|_| rng.range(-50.0, 50.0)).collect();
        let (lo, hi) = nonzero_span(&a);
        assert!(lo % 4 == 0 && (hi % 4 == 0 || hi == n) && lo <= hi && hi <= n);
        assert!(a[..lo].iter().chain(&a[hi..]).all(|&v| v == 0.0));
        assert_eq!(
            dot(&a[lo..hi], &b[lo..hi]).to_bits(),
            dot(&a, &b).to_bits(),
            "n {n}, span {lo}..{hi}"
        );
    }
}

#[test]
fn rows_not_written_again_keep_their_norms_and_give_the_same_solves() {
    // One solver is given every row at every solve, the other only the rows that changed:
    // the second's kept norms and spans must make it solve exactly as the first, bit for bit.
    // The rows have blocks of zeros (as the condensed MPC's do), so the spans are partial.
    let mut rng = Rng(4242);
    for _ in 0..20 {
        let mut p = random_feasible(&mut rng);
        for r in p.rows.iter_mut() {
            let n = r.len();
            let keep = rng.below(n) + 1;
            let start = rng.below(n - keep + 1);
            for (i, v) in r.iter_mut().enumerate() {
                if i < start || i >= start + keep {
                    *v = 0.0;
                }
            }
        }
        // Zero rows are the problem's statement about bounds only: keep them feasible.
        for k in 0..p.rows.len() {
            if p.rows[k].iter().all(|&v| v == 0.0) {
                p.lo[k] = p.lo[k].min(0.0);
                p.hi[k] = p.hi[k].max(0.0);
            }
        }
        let mut all = ActiveSetQp::new(p.n, p.rows.len());
        let mut some = ActiveSetQp::new(p.n, p.rows.len());
        p.load(&mut all);
        p.load(&mut some);
        let m = p.rows.len();
        for step in 0..30 {
            let changed = if m > p.n_eq && step > 0 {
                let k = p.n_eq + rng.below(m - p.n_eq);
                for v in p.rows[k].iter_mut().filter(|v| **v != 0.0) {
                    *v += 0.1 * rng.range(-1.0, 1.0);
                }
                Some(k)
            } else {
                None
            };
            for v in p.g.iter_mut() {
                *v += 0.05 * rng.range(-1.0, 1.0);
            }
            for qp in [&mut all, &mut some] {
                qp.gradient_mut().copy_from_slice(&p.g);
                for k in 0..m {
                    qp.set_bounds(k, p.lo[k], p.hi[k]);
                }
            }
            for k in 0..m {
                all.row_mut(k).copy_from_slice(&p.rows[k]);
            }
            if let Some(k) = changed {
                some.row_mut(k).copy_from_slice(&p.rows[k]);
            }
            let (sa, ss) = (
                all.solve(&QpSettings::default()),
                some.solve(&QpSettings::default()),
            );
            assert_eq!(sa, ss, "step {step}");
            let bits = |x: &[f64]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(all.solution()), bits(some.solution()), "step {step}");
            assert_eq!(all.objective().to_bits(), some.objective().to_bits());
            assert_eq!(all.iterations(), some.iterations());
        }
    }
}
