//! What the linearised head model leaves out, bounded over the platform's boxes (docs/bound.md,
//! "A valid relaxation"): the exact input of each channel (`model::stewart::head_motion`) is the
//! linear model's (`input_coefficients`) plus a residual ρ_c(p, v, a),
//!
//!   ρ_f = (Rᵀ − I)·a + (α_b − η̈) × r + ω_b × (ω_b × r)
//!         + g·(sin θ − θ, φ − cos θ sin φ, 1 − cos θ cos φ),
//!   ρ_ω = (E(φ, θ) − I)·η̇,
//!
//! with R the platform's rotation, E the Euler-rate matrix, ω_b = E·η̇ and α_b = E·η̈ + Ė·η̇ the
//! body rates and their derivative, r the eye point. [`residual_box`] bounds every ρ_c by
//! interval arithmetic over the excursion, rate and acceleration boxes: for every pose,
//! velocity and acceleration the limiter lets through, ρ_c lies in it. A programme that may add
//! any value of that interval to each step's input therefore contains every motion with the
//! pipeline's exact perceived signals.

use nalgebra::Vector3;

use crate::model::platform::DofLimits;
use crate::G_MPS2;

/// A closed interval [lo, hi].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interval {
    /// The lower end.
    pub lo: f64,
    /// The upper end, ≥ `lo`.
    pub hi: f64,
}

impl Interval {
    /// The interval [lo, hi].
    pub fn new(lo: f64, hi: f64) -> Self {
        Interval { lo, hi }
    }

    /// The single point x.
    pub fn point(x: f64) -> Self {
        Interval { lo: x, hi: x }
    }

    /// [−m, m].
    pub fn sym(m: f64) -> Self {
        Interval { lo: -m, hi: m }
    }

    /// Whether x lies in the interval, ends included.
    pub fn contains(&self, x: f64) -> bool {
        self.lo <= x && x <= self.hi
    }

    /// sin over an interval within [−π/2, π/2], where it is increasing.
    pub fn sin(self) -> Self {
        debug_assert!(self.lo >= -std::f64::consts::FRAC_PI_2);
        debug_assert!(self.hi <= std::f64::consts::FRAC_PI_2);
        Interval::new(self.lo.sin(), self.hi.sin())
    }

    /// cos over an interval within [−π/2, π/2]: largest at 0, smallest at the end farther
    /// from it.
    pub fn cos(self) -> Self {
        debug_assert!(self.lo >= -std::f64::consts::FRAC_PI_2);
        debug_assert!(self.hi <= std::f64::consts::FRAC_PI_2);
        let far = self.lo.abs().max(self.hi.abs());
        let near = if self.lo <= 0.0 && self.hi >= 0.0 {
            0.0
        } else {
            self.lo.abs().min(self.hi.abs())
        };
        Interval::new(far.cos(), near.cos())
    }

    /// x² (tighter than x·x, which forgets that both factors are the same).
    pub fn sq(self) -> Self {
        let (a, b) = (self.lo * self.lo, self.hi * self.hi);
        if self.lo <= 0.0 && self.hi >= 0.0 {
            Interval::new(0.0, a.max(b))
        } else {
            Interval::new(a.min(b), a.max(b))
        }
    }

    /// Widened by a relative hair so that rounding in the pipeline never falls outside.
    pub fn widened(self) -> Self {
        let m = 1e-9 * (1.0 + self.lo.abs().max(self.hi.abs()));
        Interval::new(self.lo - m, self.hi + m)
    }
}

impl std::ops::Add for Interval {
    type Output = Interval;
    fn add(self, o: Interval) -> Interval {
        Interval::new(self.lo + o.lo, self.hi + o.hi)
    }
}

impl std::ops::Sub for Interval {
    type Output = Interval;
    fn sub(self, o: Interval) -> Interval {
        Interval::new(self.lo - o.hi, self.hi - o.lo)
    }
}

impl std::ops::Neg for Interval {
    type Output = Interval;
    fn neg(self) -> Interval {
        Interval::new(-self.hi, -self.lo)
    }
}

impl std::ops::Mul for Interval {
    type Output = Interval;
    fn mul(self, o: Interval) -> Interval {
        let p = [
            self.lo * o.lo,
            self.lo * o.hi,
            self.hi * o.lo,
            self.hi * o.hi,
        ];
        Interval::new(
            p.iter().copied().fold(f64::INFINITY, f64::min),
            p.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        )
    }
}

type IVec = [Interval; 3];
type IMat = [[Interval; 3]; 3];

fn mat_vec(m: &IMat, v: &IVec) -> IVec {
    std::array::from_fn(|i| m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2])
}

fn cross(a: &IVec, b: &IVec) -> IVec {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn add(a: &IVec, b: &IVec) -> IVec {
    std::array::from_fn(|i| a[i] + b[i])
}

/// Bounds of each channel's residual ρ_c (exact input minus the linear model's) over the
/// profile's boxes: fx, fy, fz in m/s², wx, wy, wz in rad/s.
pub fn residual_box(limits: &DofLimits, eye_m: &Vector3<f64>) -> [Interval; 6] {
    let b = |what: &nalgebra::Vector6<f64>, d: usize| Interval::sym(what[d]);
    let (phi, theta, psi) = (
        b(&limits.excursion, 3),
        b(&limits.excursion, 4),
        b(&limits.excursion, 5),
    );
    let rate: IVec = std::array::from_fn(|i| b(&limits.velocity, 3 + i));
    let ang_acc: IVec = std::array::from_fn(|i| b(&limits.acceleration, 3 + i));
    let lin_acc: IVec = std::array::from_fn(|i| b(&limits.acceleration, i));
    let (sf, cf, st, ct, sp, cp) = (
        phi.sin(),
        phi.cos(),
        theta.sin(),
        theta.cos(),
        psi.sin(),
        psi.cos(),
    );
    let one = Interval::point(1.0);
    let zero = Interval::point(0.0);
    // Rᵀ − I, row i of Rᵀ being column i of `stewart::rotation`. The diagonal's products are
    // of cosines in [cos max, 1], so each is within [∏ lows, 1]: the "− 1" is taken on that.
    let rt_minus_i: IMat = [
        [cp * ct - one, sp * ct, -st],
        [
            cp * st * sf - sp * cf,
            sp * st * sf + cp * cf - one,
            ct * sf,
        ],
        [
            cp * st * cf + sp * sf,
            sp * st * cf - cp * sf,
            ct * cf - one,
        ],
    ];
    // The diagonal entries are at most 0 (products of cosines ≤ 1, and sp·st·sf + cp·cf ≤ 1 as
    // an entry of a rotation matrix); interval arithmetic's upper ends can only be looser.
    let mut rt_minus_i = rt_minus_i;
    for (i, row) in rt_minus_i.iter_mut().enumerate() {
        row[i].hi = row[i].hi.min(0.0);
    }
    // E − I and Ė = ∂E/∂φ·φ̇ + ∂E/∂θ·θ̇ (as in `head_motion`).
    let e_minus_i: IMat = [
        [zero, zero, -st],
        [zero, cf - one, ct * sf],
        [zero, -sf, ct * cf - one],
    ];
    let e: IMat = [[one, zero, -st], [zero, cf, ct * sf], [zero, -sf, ct * cf]];
    let (droll, dpitch) = (rate[0], rate[1]);
    let e_dot: IMat = [
        [zero, zero, -(ct * dpitch)],
        [zero, -(sf * droll), ct * cf * droll - st * sf * dpitch],
        [zero, -(cf * droll), -(ct * sf * droll) - st * cf * dpitch],
    ];
    let w_b = mat_vec(&e, &rate);
    let rho_w = mat_vec(&e_minus_i, &rate);
    let alpha_minus = add(&mat_vec(&e_minus_i, &ang_acc), &mat_vec(&e_dot, &rate));
    let r: IVec = std::array::from_fn(|i| Interval::point(eye_m[i]));
    // ω × (ω × r) = ω (ω·r) − r |ω|².
    let w_dot_r = w_b[0] * r[0] + w_b[1] * r[1] + w_b[2] * r[2];
    let w_sq = w_b[0].sq() + w_b[1].sq() + w_b[2].sq();
    let centripetal: IVec = std::array::from_fn(|i| w_b[i] * w_dot_r - r[i] * w_sq);
    let rotated = mat_vec(&rt_minus_i, &lin_acc);
    let lever = cross(&alpha_minus, &r);
    let g = Interval::point(G_MPS2);
    // sin θ − θ is decreasing (its derivative cos θ − 1 ≤ 0), φ − sin φ increasing.
    let t_max = limits.excursion[4];
    let f_max = limits.excursion[3];
    let sin_minus = Interval::new(t_max.sin() - t_max, t_max - t_max.sin());
    let phi_minus_sin = Interval::new(f_max.sin() - f_max, f_max - f_max.sin());
    let gravity: IVec = [
        g * sin_minus,
        g * (phi_minus_sin + sf * (one - ct)),
        g * Interval::new(0.0, 1.0 - t_max.cos() * f_max.cos()),
    ];
    let force: IVec = std::array::from_fn(|i| rotated[i] + lever[i] + centripetal[i] + gravity[i]);
    [
        force[0].widened(),
        force[1].widened(),
        force[2].widened(),
        rho_w[0].widened(),
        rho_w[1].widened(),
        rho_w[2].widened(),
    ]
}

/// The exact residual ρ_c of one step: `head_motion` minus the linear model.
pub fn residual(
    pose: &nalgebra::Vector6<f64>,
    vel: &nalgebra::Vector6<f64>,
    acc: &nalgebra::Vector6<f64>,
    eye_m: &Vector3<f64>,
) -> [f64; 6] {
    let exact = crate::model::stewart::head_motion(pose, vel, acc, eye_m).channels();
    std::array::from_fn(|c| {
        let linear: f64 = (0..6)
            .map(|d| {
                let w = super::input_coefficients(c, d, eye_m);
                w[0] * pose[d] + w[1] * vel[d] + w[2] * acc[d]
            })
            .sum();
        exact[c] - linear
    })
}
