//! The crank angle of a rotary actuator (a servo arm of radius `a` and a rod of length `s`
//! from the arm's end to the platform joint), from the same inverse kinematics as the legs:
//! the standard rotary Stewart solution, as knaufinator/6DOF-Rotary-Stewart-Motion-Simulator
//! computes it (`Controller/helpers.cpp` lines 66–70; docs/live.md cites it).
//!
//! The crank turns in the vertical plane through its pivot `B` along the arm direction
//! `u = (cos β, sin β, 0)` (β measured in the base plane from x forward toward y right), its
//! angle α from the horizontal, positive up. Its end is `A = B + a (cos α u − sin α z)` in
//! hexcue's frame (z down). The rod closes the chain when |P − A| = s, P the platform joint:
//!
//! ```text
//! |P − B|² − 2a (cos α (u · (P − B)) + sin α (−(P − B)_z)) + a² = s²
//! ⇔  M sin α + N cos α = L,  L = |P − B|² − (s² − a²),  M = 2a (B_z − P_z),  N = 2a u · (P − B)
//! ⇔  α = asin(L / √(M² + N²)) − atan2(N, M)
//! ```
//!
//! (the branch with the arm's end on the joint's side; the other, π − α − 2 atan2(N, M),
//! folds the arm under the rod). No solution when |L| > √(M² + N²): the joint is out of the
//! arm's reach.

use nalgebra::Vector3;

/// A crank's angle for one pose, or the nearest the crank can give.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CrankAngle {
    /// The angle that puts the rod's end on the joint, inside the limits (rad).
    Exact(f64),
    /// None inside the limits does: the nearest angle within them (rad), which is not the
    /// pose asked for.
    Limited(f64),
}

impl CrankAngle {
    /// The angle, exact or limited (rad).
    pub fn rad(self) -> f64 {
        match self {
            CrankAngle::Exact(a) | CrankAngle::Limited(a) => a,
        }
    }
}

/// One rotary actuator's geometry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Crank {
    /// Length of the crank arm, from its axis to the rod's joint (m).
    pub radius_m: f64,
    /// Length of the rod from the arm's end to the platform joint (m).
    pub rod_m: f64,
    /// cos β and sin β of the arm's direction in the base plane.
    pub arm: (f64, f64),
    /// Lower travel limit of the crank, from the horizontal, positive up (rad).
    pub min_rad: f64,
    /// Upper travel limit of the crank, from the horizontal, positive up (rad).
    pub max_rad: f64,
}

impl Crank {
    /// The crank angle that brings the rod's end from the pivot `pivot_m` to the platform
    /// joint `joint_m` (both in the inertial frame, m), limited to [min, max].
    pub fn angle(&self, pivot_m: &Vector3<f64>, joint_m: &Vector3<f64>) -> CrankAngle {
        let (a, s) = (self.radius_m, self.rod_m);
        let d = joint_m - pivot_m;
        let l = d.norm_squared() - (s * s - a * a);
        let m = 2.0 * a * (-d.z);
        let n = 2.0 * a * (self.arm.0 * d.x + self.arm.1 * d.y);
        let r = m.hypot(n);
        let phase = n.atan2(m);
        let ratio = l / r;
        // Out of reach: the arm pointed straight at (or away from) the joint is the nearest.
        let (alpha, reached) = if ratio.abs() <= 1.0 {
            (ratio.asin() - phase, true)
        } else {
            (ratio.clamp(-1.0, 1.0).asin() - phase, false)
        };
        if reached && (self.min_rad..=self.max_rad).contains(&alpha) {
            CrankAngle::Exact(alpha)
        } else if alpha.is_finite() {
            CrankAngle::Limited(alpha.clamp(self.min_rad, self.max_rad))
        } else {
            // A joint on the pivot (r = 0) has no direction to point the arm at.
            CrankAngle::Limited(0.0f64.clamp(self.min_rad, self.max_rad))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const A: f64 = 0.2;
    const S: f64 = 0.7;
    const H: f64 = 0.6;

    fn crank(beta_deg: f64) -> Crank {
        let b = beta_deg.to_radians();
        Crank {
            radius_m: A,
            rod_m: S,
            arm: (b.cos(), b.sin()),
            min_rad: (-60f64).to_radians(),
            max_rad: 60f64.to_radians(),
        }
    }

    /// The arm's end at angle α, computed from the definition (not the solution).
    fn arm_end(pivot: Vector3<f64>, beta_deg: f64, alpha: f64) -> Vector3<f64> {
        let b = beta_deg.to_radians();
        pivot + A * Vector3::new(alpha.cos() * b.cos(), alpha.cos() * b.sin(), -alpha.sin())
    }

    /// A platform joint straight above the arm's end at α = 0, the rod vertical: neutral.
    #[test]
    fn neutral_is_the_horizontal_arm() {
        let pivot = Vector3::new(0.3, -0.1, H);
        for beta in [0.0, 90.0, -150.0, 33.0] {
            let end = arm_end(pivot, beta, 0.0);
            let joint = end - Vector3::new(0.0, 0.0, S);
            let got = crank(beta).angle(&pivot, &joint);
            assert!(
                matches!(got, CrankAngle::Exact(a) if a.abs() < 1e-12),
                "{beta}: {got:?}"
            );
        }
    }

    /// Pure heave by hand: the joint straight above the pivot's arm end at α = 0, raised by
    /// dz, stays at horizontal distance a from the pivot, so the arm must satisfy
    /// (a − a cos α)² + (s + dz − a sin α)² = s². For α = 30°: a − a cos α = 0.0267949…,
    /// s + dz − a sin α = √(s² − 0.0267949²) = 0.6994870…, so dz = 0.6994870 + 0.1 − 0.7.
    #[test]
    fn pure_heave_to_a_known_angle() {
        let pivot = Vector3::new(0.0, 0.0, H);
        let horizontal = A - A * 30f64.to_radians().cos();
        assert!((horizontal - 0.026_794_919).abs() < 1e-9);
        let dz = (S * S - horizontal * horizontal).sqrt() + A * 0.5 - S;
        assert!((dz - 0.099_487_0).abs() < 1e-6, "{dz}");
        let joint = Vector3::new(A, 0.0, H - S - dz);
        let got = crank(0.0).angle(&pivot, &joint);
        match got {
            CrankAngle::Exact(a) => assert!((a - 30f64.to_radians()).abs() < 1e-12, "{a}"),
            other => panic!("{other:?}"),
        }
        // Down by the same construction at −20°.
        let horizontal = A - A * 20f64.to_radians().cos();
        let dz = (S * S - horizontal * horizontal).sqrt() - A * 20f64.to_radians().sin() - S;
        let joint = Vector3::new(A, 0.0, H - S - dz);
        let a = crank(0.0).angle(&pivot, &joint).rad();
        assert!((a + 20f64.to_radians()).abs() < 1e-12, "{a}");
    }

    /// Any angle within the limits: the solution puts the rod's end on the joint.
    #[test]
    fn the_solution_closes_the_chain() {
        let pivot = Vector3::new(0.2, 0.35, H);
        for beta in [-170.0, -60.0, 0.0, 45.0, 120.0] {
            for alpha_deg in [-55.0, -10.0, 0.0, 25.0, 59.0] {
                let alpha = f64::to_radians(alpha_deg);
                let end = arm_end(pivot, beta, alpha);
                // The rod leaning a little toward the centre, as on a rig.
                let lean = Vector3::new(-0.1, 0.05, -1.0).normalize();
                let joint = end + S * lean;
                let got = crank(beta).angle(&pivot, &joint);
                let CrankAngle::Exact(a) = got else {
                    panic!("{beta} {alpha_deg}: {got:?}")
                };
                let rod = (joint - arm_end(pivot, beta, a)).norm();
                assert!((rod - S).abs() < 1e-9, "{beta} {alpha_deg}: rod {rod}");
                assert!((a - alpha).abs() < 1e-9, "{beta} {alpha_deg}: {a}");
            }
        }
    }

    #[test]
    fn beyond_the_limits_or_the_reach_is_limited_never_wrong() {
        let pivot = Vector3::new(0.0, 0.0, H);
        // 70° needs an arm past its 60° limit: the limit, flagged.
        let joint = arm_end(pivot, 0.0, 70f64.to_radians()) - Vector3::new(0.0, 0.0, S);
        assert_eq!(
            crank(0.0).angle(&pivot, &joint),
            CrankAngle::Limited(60f64.to_radians())
        );
        // Farther than arm and rod together: out of reach, the arm up as far as it goes.
        let far = pivot - Vector3::new(0.0, 0.0, A + S + 0.05);
        assert_eq!(
            crank(0.0).angle(&pivot, &far),
            CrankAngle::Limited(60f64.to_radians())
        );
        // Nearer than rod less arm: out of reach the other way.
        let near = pivot - Vector3::new(0.0, 0.0, S - A - 0.05);
        assert_eq!(
            crank(0.0).angle(&pivot, &near),
            CrankAngle::Limited((-60f64).to_radians())
        );
        // The joint on the pivot: no direction at all, still a number within the limits.
        let got = crank(0.0).angle(&pivot, &pivot);
        assert!(
            matches!(got, CrankAngle::Limited(a) if a.is_finite()),
            "{got:?}"
        );
    }
}
