//! Linear time-invariant systems: continuous state space, exact zero-order-hold
//! discretisation and frequency responses.

use nalgebra::{Complex, DMatrix, DVector};

/// Continuous-time system ẋ = A x + B u, y = C x + D u.
#[derive(Clone, Debug, PartialEq)]
pub struct StateSpace {
    /// State matrix A (n × n).
    pub a: DMatrix<f64>,
    /// Input matrix B (n × m).
    pub b: DMatrix<f64>,
    /// Output matrix C (p × n).
    pub c: DMatrix<f64>,
    /// Feedthrough matrix D (p × m).
    pub d: DMatrix<f64>,
}

/// Discrete-time system x\[k+1\] = A x\[k\] + B u\[k\], y\[k\] = C x\[k\] + D u\[k\].
#[derive(Clone, Debug, PartialEq)]
pub struct DiscreteStateSpace {
    /// State matrix A (n × n).
    pub a: DMatrix<f64>,
    /// Input matrix B (n × m).
    pub b: DMatrix<f64>,
    /// Output matrix C (p × n).
    pub c: DMatrix<f64>,
    /// Feedthrough matrix D (p × m).
    pub d: DMatrix<f64>,
    /// Sample period T (s).
    pub dt_s: f64,
}

impl StateSpace {
    /// Number of states n.
    pub fn n_states(&self) -> usize {
        self.a.nrows()
    }
    /// Number of inputs m.
    pub fn n_inputs(&self) -> usize {
        self.b.ncols()
    }
    /// Number of outputs p.
    pub fn n_outputs(&self) -> usize {
        self.c.nrows()
    }

    /// Controllable canonical realisation of a proper SISO transfer function.
    /// Coefficients are given highest power of s first; `den[0]` must be non-zero
    /// and `num` may not be longer than `den`.
    pub fn from_transfer_function(num: &[f64], den: &[f64]) -> Self {
        assert!(
            !den.is_empty() && den[0] != 0.0,
            "denominator must have a leading coefficient"
        );
        assert!(num.len() <= den.len(), "transfer function must be proper");
        let n = den.len() - 1;
        let lead = den[0];
        // a[i] is the coefficient of s^i of the monic denominator.
        let a: Vec<f64> = (0..n).map(|i| den[n - i] / lead).collect();
        let mut b = vec![0.0; n + 1];
        for (j, &c) in num.iter().rev().enumerate() {
            b[j] = c / lead;
        }
        let d_term = b[n];
        let mut sys = StateSpace {
            a: DMatrix::zeros(n, n),
            b: DMatrix::zeros(n, 1),
            c: DMatrix::zeros(1, n),
            d: DMatrix::from_element(1, 1, d_term),
        };
        if n == 0 {
            return sys;
        }
        for i in 0..n - 1 {
            sys.a[(i, i + 1)] = 1.0;
        }
        for i in 0..n {
            sys.a[(n - 1, i)] = -a[i];
            sys.c[(0, i)] = b[i] - d_term * a[i];
        }
        sys.b[(n - 1, 0)] = 1.0;
        sys
    }

    /// Parallel, independent systems: states, inputs and outputs stacked in order.
    pub fn block_diagonal(systems: &[StateSpace]) -> Self {
        let (n, m, p) = systems.iter().fold((0, 0, 0), |(n, m, p), s| {
            (n + s.n_states(), m + s.n_inputs(), p + s.n_outputs())
        });
        let mut out = StateSpace {
            a: DMatrix::zeros(n, n),
            b: DMatrix::zeros(n, m),
            c: DMatrix::zeros(p, n),
            d: DMatrix::zeros(p, m),
        };
        let (mut i, mut j, mut k) = (0, 0, 0);
        for s in systems {
            let (ns, ms, ps) = (s.n_states(), s.n_inputs(), s.n_outputs());
            out.a.view_mut((i, i), (ns, ns)).copy_from(&s.a);
            out.b.view_mut((i, j), (ns, ms)).copy_from(&s.b);
            out.c.view_mut((k, i), (ps, ns)).copy_from(&s.c);
            out.d.view_mut((k, j), (ps, ms)).copy_from(&s.d);
            i += ns;
            j += ms;
            k += ps;
        }
        out
    }

    /// Exact discretisation for inputs held constant over each sample:
    /// exp([[A, B], [0, 0]]·dt) = [[Ad, Bd], [0, I]].
    pub fn discretise_zoh(&self, dt_s: f64) -> DiscreteStateSpace {
        let (n, m) = (self.n_states(), self.n_inputs());
        let mut aug = DMatrix::zeros(n + m, n + m);
        aug.view_mut((0, 0), (n, n)).copy_from(&(&self.a * dt_s));
        aug.view_mut((0, n), (n, m)).copy_from(&(&self.b * dt_s));
        let e = aug.exp();
        DiscreteStateSpace {
            a: e.view((0, 0), (n, n)).into_owned(),
            b: e.view((0, n), (n, m)).into_owned(),
            c: self.c.clone(),
            d: self.d.clone(),
            dt_s,
        }
    }

    /// G(jω) = C (jωI − A)⁻¹ B + D.
    pub fn frequency_response(&self, w_radps: f64) -> DMatrix<Complex<f64>> {
        let n = self.n_states();
        let mut m = self.a.map(|v| Complex::new(-v, 0.0));
        for i in 0..n {
            m[(i, i)] += Complex::new(0.0, w_radps);
        }
        let b = self.b.map(|v| Complex::new(v, 0.0));
        let x = m.lu().solve(&b).unwrap_or_else(|| {
            DMatrix::from_element(n, self.n_inputs(), Complex::new(f64::NAN, f64::NAN))
        });
        self.c.map(|v| Complex::new(v, 0.0)) * x + self.d.map(|v| Complex::new(v, 0.0))
    }

    /// Steady-state gain −C A⁻¹ B + D; `None` when A is singular (an integrator).
    pub fn dc_gain(&self) -> Option<DMatrix<f64>> {
        let x = self.a.clone().lu().solve(&self.b)?;
        Some(&self.d - &self.c * x)
    }
}

impl DiscreteStateSpace {
    /// Number of states n.
    pub fn n_states(&self) -> usize {
        self.a.nrows()
    }

    /// Frequency response of the sampled system at ω (rad/s): C (e^{jωT} I − A)⁻¹ B + D.
    pub fn frequency_response(&self, w_radps: f64) -> DMatrix<Complex<f64>> {
        let n = self.n_states();
        let z = Complex::from_polar(1.0, w_radps * self.dt_s);
        let mut m = self.a.map(|v| Complex::new(-v, 0.0));
        for i in 0..n {
            m[(i, i)] += z;
        }
        let b = self.b.map(|v| Complex::new(v, 0.0));
        let x = m.lu().solve(&b).unwrap_or_else(|| {
            DMatrix::from_element(n, self.b.ncols(), Complex::new(f64::NAN, f64::NAN))
        });
        self.c.map(|v| Complex::new(v, 0.0)) * x + self.d.map(|v| Complex::new(v, 0.0))
    }
}

/// A discrete system with its state, stepped sample by sample without allocating.
#[derive(Clone, Debug)]
pub struct LtiFilter {
    sys: DiscreteStateSpace,
    x: DVector<f64>,
    next: DVector<f64>,
    u: DVector<f64>,
    y: DVector<f64>,
}

impl LtiFilter {
    /// A filter over `sys`, starting from the zero state.
    pub fn new(sys: DiscreteStateSpace) -> Self {
        let (n, m, p) = (sys.a.nrows(), sys.b.ncols(), sys.c.nrows());
        LtiFilter {
            sys,
            x: DVector::zeros(n),
            next: DVector::zeros(n),
            u: DVector::zeros(m),
            y: DVector::zeros(p),
        }
    }

    /// The system it steps.
    pub fn system(&self) -> &DiscreteStateSpace {
        &self.sys
    }

    /// Its state x\[k\].
    pub fn state(&self) -> &DVector<f64> {
        &self.x
    }

    /// Back to the zero state.
    pub fn reset(&mut self) {
        self.x.fill(0.0);
    }

    /// Takes over another filter's state (the same structure tuned otherwise: a live
    /// change); false, and nothing changed, if the state sizes differ.
    pub fn inherit_state(&mut self, from: &LtiFilter) -> bool {
        if from.x.len() != self.x.len() {
            return false;
        }
        self.x.copy_from(&from.x);
        true
    }

    /// Output for the input `u` at this sample, then advance the state by one sample.
    pub fn step(&mut self, u: &[f64]) -> &[f64] {
        self.u.copy_from_slice(u);
        self.y.gemv(1.0, &self.sys.c, &self.x, 0.0);
        self.y.gemv(1.0, &self.sys.d, &self.u, 1.0);
        self.next.gemv(1.0, &self.sys.a, &self.x, 0.0);
        self.next.gemv(1.0, &self.sys.b, &self.u, 1.0);
        std::mem::swap(&mut self.x, &mut self.next);
        self.y.as_slice()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_order_lag_matches_analytic_zoh() {
        // 1/(τs+1): Ad = e^{-T/τ}, Bd = 1 − e^{-T/τ} (in the canonical realisation C = 1/τ, B = 1).
        let tau = 0.5;
        let sys = StateSpace::from_transfer_function(&[1.0], &[tau, 1.0]);
        let d = sys.discretise_zoh(0.01);
        let ad = (-0.01f64 / tau).exp();
        assert!((d.a[(0, 0)] - ad).abs() < 1e-14);
        let step_gain = d.c[(0, 0)] * d.b[(0, 0)] / (1.0 - d.a[(0, 0)]);
        assert!((step_gain - 1.0).abs() < 1e-12);
        assert!((sys.dc_gain().unwrap()[(0, 0)] - 1.0).abs() < 1e-12);
    }

    #[test]
    fn realisation_reproduces_transfer_function() {
        // (2s² + 3s + 1)/(s³ + 4s² + 5s + 6) at ω = 0.7 rad/s.
        let num = [2.0, 3.0, 1.0];
        let den = [1.0, 4.0, 5.0, 6.0];
        let sys = StateSpace::from_transfer_function(&num, &den);
        let s = Complex::new(0.0, 0.7);
        let eval = |c: &[f64]| c.iter().fold(Complex::new(0.0, 0.0), |acc, &v| acc * s + v);
        let expected = eval(&num) / eval(&den);
        let got = sys.frequency_response(0.7)[(0, 0)];
        assert!((got - expected).norm() < 1e-12);
    }

    #[test]
    fn biproper_transfer_function_has_feedthrough() {
        let sys = StateSpace::from_transfer_function(&[3.0, 1.0], &[1.0, 2.0]);
        assert_eq!(sys.d[(0, 0)], 3.0);
        let g = sys.frequency_response(1e6)[(0, 0)];
        assert!((g.re - 3.0).abs() < 1e-5);
    }

    #[test]
    fn filter_steps_like_the_matrices() {
        let sys = StateSpace::from_transfer_function(&[1.0], &[1.0, 1.0]).discretise_zoh(0.1);
        let mut f = LtiFilter::new(sys.clone());
        let mut y = 0.0;
        for _ in 0..200 {
            y = f.step(&[1.0])[0];
        }
        assert!((y - 1.0).abs() < 1e-8);
    }
}
