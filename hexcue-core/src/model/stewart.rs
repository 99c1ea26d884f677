//! Stewart-platform kinematics in the simulator inertial frame (docs/design.md §1: origin at the
//! platform's neutral pose, x forward, y right, z down).
//!
//! Poses are `Vector6` in the order x, y, z (m), roll φ, pitch θ, yaw ψ (rad, Z-Y-X Euler).
//! The platform joints sit in the moving frame's joint plane (z = 0); the base joints lie
//! `neutral_height_m` below it (z = +h0, since z is down).

use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};
use serde::{Deserialize, Serialize};

use crate::G_MPS2;

/// Joint layout of a hexapod, in one of two forms (a profile gives exactly one):
///
/// - **symmetric**: three pairs of joints on the base and on the platform, the platform's
///   pairs rotated between the base's so that the legs cross (the 6-6 layout), from radii,
///   pair spacings, rotation and neutral height;
/// - **joint coordinates**: the six base joints and the six platform joints as measured on a
///   real hexapod, which is never perfectly symmetric. Leg i runs from `base_joints_m[i]` to
///   `platform_joints_m[i]`. Both are in the geometry frame: the simulator inertial frame at
///   the neutral pose (x forward, y right, z down, docs/design.md §1), whose origin is the platform
///   frame's; the platform joints are fixed in the platform frame, which coincides with it at
///   neutral. The base joints therefore have z > 0 (below the platform).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Geometry {
    /// Radius of the circle through the base (floor) joints (m).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base_radius_m: Option<f64>,
    /// Angle between the two joints of a base pair (deg).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base_pair_spacing_deg: Option<f64>,
    /// Radius of the circle through the platform joints (m).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub platform_radius_m: Option<f64>,
    /// Angle between the two joints of a platform pair (deg).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub platform_pair_spacing_deg: Option<f64>,
    /// Rotation of the platform's pair centres from the base's (deg).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub platform_rotation_deg: Option<f64>,
    /// Height of the platform joint plane above the base joint plane at neutral (m).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub neutral_height_m: Option<f64>,
    /// Joint-coordinate form: each leg's base joint [x, y, z], geometry frame (m). Read as
    /// lists of lists so that a wrong count is reported with the key and index.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base_joints_m: Option<Vec<Vec<f64>>>,
    /// Joint-coordinate form: each leg's platform joint [x, y, z], platform frame (m).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub platform_joints_m: Option<Vec<Vec<f64>>>,
    /// Shortest leg length, joint to joint (m).
    pub leg_min_m: f64,
    /// Longest leg length, joint to joint (m).
    pub leg_max_m: f64,
}

/// The keys of the symmetric form, in the order of [`Geometry`].
pub const SYMMETRIC_KEYS: [&str; 6] = [
    "base_radius_m",
    "base_pair_spacing_deg",
    "platform_radius_m",
    "platform_pair_spacing_deg",
    "platform_rotation_deg",
    "neutral_height_m",
];

impl Geometry {
    /// The symmetric form's values in the order of [`SYMMETRIC_KEYS`] (`None` where absent).
    pub fn symmetric_values(&self) -> [Option<f64>; 6] {
        [
            self.base_radius_m,
            self.base_pair_spacing_deg,
            self.platform_radius_m,
            self.platform_pair_spacing_deg,
            self.platform_rotation_deg,
            self.neutral_height_m,
        ]
    }

    /// Whether the joint-coordinate form is used (either of its keys is given).
    pub fn by_joints(&self) -> bool {
        self.base_joints_m.is_some() || self.platform_joints_m.is_some()
    }

    /// Height of the platform joints above the base joints at neutral (m): the symmetric
    /// form's key, or the mean z of the base joints less that of the platform joints.
    pub fn neutral_height(&self) -> f64 {
        if self.by_joints() {
            let mean_z = |p: &Option<Vec<Vec<f64>>>| {
                let pts = p.as_deref().unwrap_or(&[]);
                let zs: Vec<f64> = pts.iter().filter_map(|q| q.get(2).copied()).collect();
                zs.iter().sum::<f64>() / zs.len().max(1) as f64
            };
            mean_z(&self.base_joints_m) - mean_z(&self.platform_joints_m)
        } else {
            self.neutral_height_m.unwrap_or(f64::NAN)
        }
    }

    /// The joints of each leg: base joints in the inertial frame, platform joints in the
    /// platform frame (m). Absent or malformed values become NaN: the profile's validation
    /// refuses them, with their key, before any use.
    pub fn joints(&self) -> ([Vector3<f64>; 6], [Vector3<f64>; 6]) {
        if self.by_joints() {
            let points = |p: &Option<Vec<Vec<f64>>>| -> [Vector3<f64>; 6] {
                std::array::from_fn(|i| {
                    let q = p.as_ref().and_then(|v| v.get(i));
                    let c = |k: usize| q.and_then(|q| q.get(k)).copied().unwrap_or(f64::NAN);
                    Vector3::new(c(0), c(1), c(2))
                })
            };
            return (points(&self.base_joints_m), points(&self.platform_joints_m));
        }
        let nan = f64::NAN;
        let place = |radius: f64, centre_deg: f64, spacing_deg: f64| -> [(f64, f64); 6] {
            let mut out = [(0.0, 0.0); 6];
            for pair in 0..3 {
                let c = centre_deg + 120.0 * pair as f64;
                for (j, side) in [-0.5, 0.5].iter().enumerate() {
                    let a = (c + side * spacing_deg).to_radians();
                    out[2 * pair + j] = (radius * a.cos(), radius * a.sin());
                }
            }
            out
        };
        let base = place(
            self.base_radius_m.unwrap_or(nan),
            0.0,
            self.base_pair_spacing_deg.unwrap_or(nan),
        );
        // Legs cross: base joint i is joined to the nearer joint of the neighbouring platform
        // pair, which is platform joint i − 1 (mod 6) in the placement order.
        let plat = place(
            self.platform_radius_m.unwrap_or(nan),
            self.platform_rotation_deg.unwrap_or(nan),
            self.platform_pair_spacing_deg.unwrap_or(nan),
        );
        let h0 = self.neutral_height_m.unwrap_or(nan);
        let base_joints_m = std::array::from_fn(|i| Vector3::new(base[i].0, base[i].1, h0));
        let platform_joints_m = std::array::from_fn(|i| {
            let j = (i + 5) % 6;
            Vector3::new(plat[j].0, plat[j].1, 0.0)
        });
        (base_joints_m, platform_joints_m)
    }
}

/// Error of the forward kinematics.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum KinematicsError {
    #[error("forward kinematics did not converge (residual {residual_m:.3e} m after {iterations} iterations)")]
    /// Newton's method stopped short of the lengths asked for.
    NoConvergence {
        /// Largest leg-length error left (m).
        residual_m: f64,
        /// Newton iterations run.
        iterations: usize,
    },
}

/// A hexapod with its joints placed; every query is a pure function of a pose.
///
/// ```
/// use hexcue_core::profile::text::default_profile;
/// use nalgebra::Vector6;
///
/// let profile = default_profile();
/// let stewart = profile.stewart();
/// // Neutral: every leg at its neutral length.
/// let neutral = Vector6::zeros();
/// assert_eq!(stewart.leg_lengths(&neutral), stewart.neutral_lengths_m);
/// // 10 cm forward and 3° nose up (x, y, z in m; roll, pitch, yaw in rad).
/// let pose = Vector6::new(0.10, 0.0, 0.0, 0.0, 3f64.to_radians(), 0.0);
/// let legs_m = stewart.leg_lengths(&pose);
/// assert!(stewart.margins(&legs_m).min() > 0.0, "inside the stroke");
/// // Forward kinematics gives the pose back from the legs.
/// let back = stewart.forward(&legs_m, &neutral).unwrap();
/// assert!((back - pose).norm() < 1e-9);
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Stewart {
    /// Base joints in the inertial frame (m).
    pub base_joints_m: [Vector3<f64>; 6],
    /// Platform joints in the platform frame (m).
    pub platform_joints_m: [Vector3<f64>; 6],
    /// Shortest length a leg reaches, at its lower end stop (m).
    pub leg_min_m: f64,
    /// Longest length a leg reaches, at its upper end stop (m).
    pub leg_max_m: f64,
    /// Leg lengths at the neutral pose (m).
    pub neutral_lengths_m: Vector6<f64>,
}

/// Rotation from the platform frame to the inertial frame: R = Rz(ψ)·Ry(θ)·Rx(φ).
pub fn rotation(roll: f64, pitch: f64, yaw: f64) -> Matrix3<f64> {
    let (sf, cf) = roll.sin_cos();
    let (st, ct) = pitch.sin_cos();
    let (sp, cp) = yaw.sin_cos();
    Matrix3::new(
        cp * ct,
        cp * st * sf - sp * cf,
        cp * st * cf + sp * sf,
        sp * ct,
        sp * st * sf + cp * cf,
        sp * st * cf - cp * sf,
        -st,
        ct * sf,
        ct * cf,
    )
}

/// Partial derivatives of R with respect to roll, pitch and yaw.
fn rotation_partials(roll: f64, pitch: f64, yaw: f64) -> [Matrix3<f64>; 3] {
    let (sf, cf) = roll.sin_cos();
    let (st, ct) = pitch.sin_cos();
    let (sp, cp) = yaw.sin_cos();
    let d_roll = Matrix3::new(
        0.0,
        cp * st * cf + sp * sf,
        -cp * st * sf + sp * cf,
        0.0,
        sp * st * cf - cp * sf,
        -sp * st * sf - cp * cf,
        0.0,
        ct * cf,
        -ct * sf,
    );
    let d_pitch = Matrix3::new(
        -cp * st,
        cp * ct * sf,
        cp * ct * cf,
        -sp * st,
        sp * ct * sf,
        sp * ct * cf,
        -ct,
        -st * sf,
        -st * cf,
    );
    let d_yaw = Matrix3::new(
        -sp * ct,
        -sp * st * sf - cp * cf,
        -sp * st * cf + cp * sf,
        cp * ct,
        cp * st * sf - sp * cf,
        cp * st * cf + sp * sf,
        0.0,
        0.0,
        0.0,
    );
    [d_roll, d_pitch, d_yaw]
}

/// Maps Euler-angle rates to the body-frame angular velocity: ω_body = E(φ, θ)·(φ̇, θ̇, ψ̇).
pub fn euler_rate_matrix(roll: f64, pitch: f64) -> Matrix3<f64> {
    let (sf, cf) = roll.sin_cos();
    let (st, ct) = pitch.sin_cos();
    Matrix3::new(1.0, 0.0, -st, 0.0, cf, ct * sf, 0.0, -sf, ct * cf)
}

/// Motion felt at the pilot's head for a platform state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeadMotion {
    /// Specific force minus its value at rest, in the head frame (m/s²).
    pub delta_f_mps2: Vector3<f64>,
    /// Angular velocity in the head frame (rad/s).
    pub angular_velocity_radps: Vector3<f64>,
}

impl HeadMotion {
    /// The six channels in the order fx, fy, fz, wx, wy, wz (m/s², rad/s), as
    /// `Perceived::channels` orders what is felt of them.
    pub fn channels(&self) -> [f64; 6] {
        std::array::from_fn(|i| {
            if i < 3 {
                self.delta_f_mps2[i]
            } else {
                self.angular_velocity_radps[i - 3]
            }
        })
    }
}

/// Specific force and angular velocity at `eye_m` (a point fixed in the platform frame) for a
/// platform pose, velocity and acceleration (Euler-angle rates and their derivatives).
pub fn head_motion(
    pose: &Vector6<f64>,
    vel: &Vector6<f64>,
    acc: &Vector6<f64>,
    eye_m: &Vector3<f64>,
) -> HeadMotion {
    let (roll, pitch, yaw) = (pose[3], pose[4], pose[5]);
    let r = rotation(roll, pitch, yaw);
    let eta_dot = vel.fixed_rows::<3>(3).into_owned();
    let eta_ddot = acc.fixed_rows::<3>(3).into_owned();
    let e = euler_rate_matrix(roll, pitch);
    let w_body = e * eta_dot;
    // Ė = ∂E/∂φ·φ̇ + ∂E/∂θ·θ̇.
    let (sf, cf) = roll.sin_cos();
    let (st, ct) = pitch.sin_cos();
    let de_droll = Matrix3::new(0.0, 0.0, 0.0, 0.0, -sf, ct * cf, 0.0, -cf, -ct * sf);
    let de_dpitch = Matrix3::new(0.0, 0.0, -ct, 0.0, 0.0, -st * sf, 0.0, 0.0, -st * cf);
    let w_dot_body = e * eta_ddot + (de_droll * vel[3] + de_dpitch * vel[4]) * eta_dot;
    // Inertial-frame quantities for the lever arm from the platform centre to the head.
    let lever = r * eye_m;
    let w_i = r * w_body;
    let alpha_i = r * w_dot_body;
    let a_lin = acc.fixed_rows::<3>(0).into_owned();
    let a_head = a_lin + alpha_i.cross(&lever) + w_i.cross(&w_i.cross(&lever));
    let g = Vector3::new(0.0, 0.0, G_MPS2);
    let f_body = r.transpose() * (a_head - g);
    HeadMotion {
        delta_f_mps2: f_body - Vector3::new(0.0, 0.0, -G_MPS2),
        angular_velocity_radps: w_body,
    }
}

impl Stewart {
    /// The hexapod of a profile's `[geometry]`: its joints placed and its neutral leg lengths.
    pub fn new(g: &Geometry) -> Self {
        let (base_joints_m, platform_joints_m) = g.joints();
        let mut s = Stewart {
            base_joints_m,
            platform_joints_m,
            leg_min_m: g.leg_min_m,
            leg_max_m: g.leg_max_m,
            neutral_lengths_m: Vector6::zeros(),
        };
        s.neutral_lengths_m = s.leg_lengths(&Vector6::zeros());
        s
    }

    fn leg_vectors(&self, pose: &Vector6<f64>) -> [Vector3<f64>; 6] {
        let r = rotation(pose[3], pose[4], pose[5]);
        let t = Vector3::new(pose[0], pose[1], pose[2]);
        std::array::from_fn(|i| t + r * self.platform_joints_m[i] - self.base_joints_m[i])
    }

    /// Inverse kinematics: the six leg lengths (m) for a pose.
    pub fn leg_lengths(&self, pose: &Vector6<f64>) -> Vector6<f64> {
        let legs = self.leg_vectors(pose);
        Vector6::from_fn(|i, _| legs[i].norm())
    }

    /// J = ∂l/∂pose (6×6): leg velocities are J·ṗose for Euler-angle rates.
    pub fn jacobian(&self, pose: &Vector6<f64>) -> Matrix6<f64> {
        let legs = self.leg_vectors(pose);
        let partials = rotation_partials(pose[3], pose[4], pose[5]);
        let mut j = Matrix6::zeros();
        for i in 0..6 {
            let u = legs[i] / legs[i].norm();
            for k in 0..3 {
                j[(i, k)] = u[k];
                j[(i, 3 + k)] = u.dot(&(partials[k] * self.platform_joints_m[i]));
            }
        }
        j
    }

    /// The six leg velocities (m/s) at `pose` for the pose's velocity `vel` (m/s, and Euler-angle
    /// rates in rad/s): J·vel.
    pub fn leg_velocities(&self, pose: &Vector6<f64>, vel: &Vector6<f64>) -> Vector6<f64> {
        self.jacobian(pose) * vel
    }

    /// Distance of each leg to its nearer end stop (m); negative outside the stroke.
    pub fn margins(&self, lengths: &Vector6<f64>) -> Vector6<f64> {
        lengths.map(|l| (l - self.leg_min_m).min(self.leg_max_m - l))
    }

    /// Fraction of the stroke from neutral to the nearer end stop that each leg uses:
    /// 0 at neutral, 1 at an end stop, above 1 beyond it.
    pub fn usage(&self, lengths: &Vector6<f64>) -> Vector6<f64> {
        Vector6::from_fn(|i, _| {
            let (l, n) = (lengths[i], self.neutral_lengths_m[i]);
            if l >= n {
                (l - n) / (self.leg_max_m - n)
            } else {
                (n - l) / (n - self.leg_min_m)
            }
        })
    }

    /// [`Stewart::usage`] with the leg's direction from neutral: positive where the leg is
    /// longer than at neutral (extending), negative where it is shorter (retracting).
    pub fn signed_usage(&self, lengths: &Vector6<f64>) -> Vector6<f64> {
        let usage = self.usage(lengths);
        Vector6::from_fn(|i, _| {
            if lengths[i] >= self.neutral_lengths_m[i] {
                usage[i]
            } else {
                -usage[i]
            }
        })
    }

    /// Whether every leg at `pose` keeps at least `margin_m` (m) from both its end stops.
    pub fn fits(&self, pose: &Vector6<f64>, margin_m: f64) -> bool {
        self.margins(&self.leg_lengths(pose))
            .iter()
            .all(|&m| m >= margin_m)
    }

    /// Forward kinematics: the pose whose legs have the given lengths, by Newton's method
    /// on the inverse kinematics from `guess` (the previous pose, or neutral).
    pub fn forward(
        &self,
        lengths: &Vector6<f64>,
        guess: &Vector6<f64>,
    ) -> Result<Vector6<f64>, KinematicsError> {
        let mut pose = *guess;
        let mut residual = f64::INFINITY;
        for it in 0..50 {
            let err = self.leg_lengths(&pose) - lengths;
            residual = err.amax();
            if residual < 1e-12 {
                return Ok(pose);
            }
            let Some(step) = self.jacobian(&pose).lu().solve(&err) else {
                return Err(KinematicsError::NoConvergence {
                    residual_m: residual,
                    iterations: it,
                });
            };
            pose -= step;
        }
        if residual < 1e-9 {
            Ok(pose)
        } else {
            Err(KinematicsError::NoConvergence {
                residual_m: residual,
                iterations: 50,
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(crate) fn full_flight() -> Geometry {
        Geometry {
            base_radius_m: Some(2.3),
            base_pair_spacing_deg: Some(15.0),
            platform_radius_m: Some(1.8),
            platform_pair_spacing_deg: Some(25.0),
            platform_rotation_deg: Some(60.0),
            neutral_height_m: Some(3.0),
            base_joints_m: None,
            platform_joints_m: None,
            leg_min_m: 2.5,
            leg_max_m: 4.5,
        }
    }

    /// The same hexapod given by its joint coordinates, as a profile would write them.
    fn by_joints(g: &Geometry) -> Geometry {
        let (base, plat) = g.joints();
        let list = |p: [Vector3<f64>; 6]| Some(p.iter().map(|v| vec![v.x, v.y, v.z]).collect());
        Geometry {
            base_radius_m: None,
            base_pair_spacing_deg: None,
            platform_radius_m: None,
            platform_pair_spacing_deg: None,
            platform_rotation_deg: None,
            neutral_height_m: None,
            base_joints_m: list(base),
            platform_joints_m: list(plat),
            ..g.clone()
        }
    }

    #[test]
    fn joint_coordinates_equal_to_the_symmetric_form_give_the_same_legs_and_jacobian() {
        let sym = Stewart::new(&full_flight());
        let g = by_joints(&full_flight());
        assert!((g.neutral_height() - 3.0).abs() < 1e-12);
        let joints = Stewart::new(&g);
        assert_eq!(joints.neutral_lengths_m, sym.neutral_lengths_m);
        for p in [
            Vector6::zeros(),
            Vector6::new(0.3, -0.2, 0.1, 0.1, -0.15, 0.2),
            Vector6::new(-1.0, 0.7, -0.4, -0.3, 0.2, 0.4),
        ] {
            assert!((joints.leg_lengths(&p) - sym.leg_lengths(&p)).amax() < 1e-12);
            assert!((joints.jacobian(&p) - sym.jacobian(&p)).amax() < 1e-12);
        }
    }

    #[test]
    fn an_asymmetric_hexapod_has_its_own_legs() {
        // One platform joint 5 cm out of place: that leg alone changes at neutral, and the
        // kinematics still invert.
        let mut g = by_joints(&full_flight());
        g.platform_joints_m.as_mut().unwrap()[3][0] += 0.05;
        let s = Stewart::new(&g);
        let sym = Stewart::new(&full_flight());
        for i in 0..6 {
            let moved = (s.neutral_lengths_m[i] - sym.neutral_lengths_m[i]).abs() > 1e-6;
            assert_eq!(moved, i == 3, "leg {}", i + 1);
        }
        let p = Vector6::new(0.4, -0.3, 0.2, 0.1, -0.1, 0.2);
        let back = s.forward(&s.leg_lengths(&p), &Vector6::zeros()).unwrap();
        assert!((back - p).amax() < 1e-9);
    }

    /// Horizontal distance between a base joint and its platform joint: the pair centres are
    /// 60° apart, so the joints are 60 − 7.5 − 12.5 = 40° apart.
    fn neutral_horizontal_sq() -> f64 {
        2.3f64.powi(2) + 1.8f64.powi(2) - 2.0 * 2.3 * 1.8 * 40f64.to_radians().cos()
    }

    #[test]
    fn neutral_legs_have_the_analytic_length() {
        let s = Stewart::new(&full_flight());
        let expected = (neutral_horizontal_sq() + 9.0).sqrt();
        assert!((expected - 3.345).abs() < 1e-3);
        for l in s.neutral_lengths_m.iter() {
            assert!((l - expected).abs() < 1e-12, "{l} vs {expected}");
        }
    }

    #[test]
    fn pure_heave_changes_every_leg_alike() {
        let s = Stewart::new(&full_flight());
        for &z in &[-0.8, -0.3, 0.4, 0.8] {
            let l = s.leg_lengths(&Vector6::new(0.0, 0.0, z, 0.0, 0.0, 0.0));
            let expected = (neutral_horizontal_sq() + (3.0 - z).powi(2)).sqrt();
            for li in l.iter() {
                assert!((li - expected).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn joints_are_symmetric_and_the_combined_corner_needs_a_long_leg() {
        let s = Stewart::new(&full_flight());
        // Per-axis extremes fit, the combined x = y = 1.7 m does not (docs/design.md §3).
        for axis in 0..6 {
            let mut p = Vector6::zeros();
            p[axis] = [
                1.7,
                1.7,
                0.8,
                25f64.to_radians(),
                25f64.to_radians(),
                30f64.to_radians(),
            ][axis];
            assert!(s.fits(&p, 0.0), "axis {axis} +extreme");
            p[axis] = -p[axis];
            assert!(s.fits(&p, 0.0), "axis {axis} -extreme");
        }
        let corner = Vector6::new(1.7, 1.7, 0.0, 0.0, 0.0, 0.0);
        assert!(!s.fits(&corner, 0.0));
        assert!(s.leg_lengths(&corner).max() > 4.7);
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let s = Stewart::new(&full_flight());
        let p = Vector6::new(0.3, -0.2, 0.1, 0.1, -0.15, 0.2);
        let j = s.jacobian(&p);
        let h = 1e-6;
        for k in 0..6 {
            let mut dp = Vector6::zeros();
            dp[k] = h;
            let fd = (s.leg_lengths(&(p + dp)) - s.leg_lengths(&(p - dp))) / (2.0 * h);
            for i in 0..6 {
                assert!(
                    (j[(i, k)] - fd[i]).abs() < 1e-8,
                    "J[{i},{k}] {} vs {}",
                    j[(i, k)],
                    fd[i]
                );
            }
        }
    }

    #[test]
    fn forward_kinematics_inverts_inverse_kinematics() {
        let s = Stewart::new(&full_flight());
        let poses = [
            Vector6::zeros(),
            Vector6::new(0.5, 0.0, 0.0, 0.0, 0.0, 0.0),
            Vector6::new(-0.8, 0.6, 0.3, 0.2, -0.1, 0.3),
            Vector6::new(1.0, -1.0, -0.5, -0.3, 0.3, -0.4),
        ];
        for p in poses {
            let l = s.leg_lengths(&p);
            let back = s.forward(&l, &Vector6::zeros()).unwrap();
            assert!((back - p).amax() < 1e-9, "{p:?} -> {back:?}");
        }
    }

    #[test]
    fn rotation_is_orthonormal_and_partials_match() {
        let (f, t, p) = (0.3, -0.2, 1.1);
        let r = rotation(f, t, p);
        assert!((r.transpose() * r - Matrix3::identity()).amax() < 1e-14);
        let d = rotation_partials(f, t, p);
        let h = 1e-6;
        let fd = [
            (rotation(f + h, t, p) - rotation(f - h, t, p)) / (2.0 * h),
            (rotation(f, t + h, p) - rotation(f, t - h, p)) / (2.0 * h),
            (rotation(f, t, p + h) - rotation(f, t, p - h)) / (2.0 * h),
        ];
        for k in 0..3 {
            assert!((d[k] - fd[k]).amax() < 1e-9);
        }
    }

    #[test]
    fn tilt_coordination_signs_follow_the_design() {
        // Nose-up pitch θ: f_x = +g·sin θ. Right roll φ: f_y = −g·sin φ. At rest: Δf = 0.
        let eye = Vector3::new(0.0, 0.0, -1.0);
        let z = Vector6::zeros();
        let rest = head_motion(&z, &z, &z, &eye);
        assert!(rest.delta_f_mps2.norm() < 1e-12);
        let th = 0.2;
        let m = head_motion(&Vector6::new(0.0, 0.0, 0.0, 0.0, th, 0.0), &z, &z, &eye);
        assert!((m.delta_f_mps2.x - G_MPS2 * th.sin()).abs() < 1e-12);
        let m = head_motion(&Vector6::new(0.0, 0.0, 0.0, th, 0.0, 0.0), &z, &z, &eye);
        assert!((m.delta_f_mps2.y + G_MPS2 * th.sin()).abs() < 1e-12);
        // Surge acceleration forward at level: Δf_x = a.
        let m = head_motion(&z, &z, &Vector6::new(2.0, 0.0, 0.0, 0.0, 0.0, 0.0), &eye);
        assert!((m.delta_f_mps2 - Vector3::new(2.0, 0.0, 0.0)).norm() < 1e-12);
    }

    #[test]
    fn lever_arm_adds_tangential_and_centripetal_terms() {
        // Head 1 m above the centre (z = −1), pitch acceleration 2 rad/s² from rest: the head
        // accelerates backward, α × r = (0, 2, 0) × (0, 0, −1) = (−2, 0, 0) m/s².
        let eye = Vector3::new(0.0, 0.0, -1.0);
        let z = Vector6::zeros();
        let acc = Vector6::new(0.0, 0.0, 0.0, 0.0, 2.0, 0.0);
        let m = head_motion(&z, &z, &acc, &eye);
        assert!((m.delta_f_mps2 - Vector3::new(-2.0, 0.0, 0.0)).norm() < 1e-12);
        // Yaw at 1 rad/s with the head 1 m forward: centripetal 1 m/s² toward the axis.
        let eye = Vector3::new(1.0, 0.0, 0.0);
        let vel = Vector6::new(0.0, 0.0, 0.0, 0.0, 0.0, 1.0);
        let m = head_motion(&z, &vel, &z, &eye);
        assert!((m.delta_f_mps2 - Vector3::new(-1.0, 0.0, 0.0)).norm() < 1e-12);
        assert!((m.angular_velocity_radps - Vector3::new(0.0, 0.0, 1.0)).norm() < 1e-12);
    }
}
