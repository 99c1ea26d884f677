//! What a hexapod can reach from its neutral pose: the farthest excursion along each degree
//! of freedom with the others at neutral (inverse kinematics and bisection), and how well
//! conditioned its legs' Jacobian is there. A profile whose limits ask for more than this, or
//! whose legs barely act along some direction, describes a platform that cannot do what it
//! says; the profile's checks warn with these figures.

use nalgebra::Vector6;

use super::stewart::Stewart;

/// Steps of the march out from neutral before the bisection: the first pose out of the
/// stroke is found within 1/`MARCH` of the search range, so a stroke that closes and opens
/// again inside one step (not a Stewart platform's) is the only thing that can hide.
const MARCH: usize = 512;
/// Halvings of the bisection: the boundary to 2⁻⁴⁰ of a step.
const HALVINGS: usize = 40;

/// The farthest the platform reaches from neutral along `dof` (0–5: x, y, z in m, roll,
/// pitch, yaw in rad) in the positive and the negative direction, with every other DoF at
/// neutral and every leg within its stroke; each at most `up_to`.
pub fn reach(stewart: &Stewart, dof: usize, up_to: f64) -> (f64, f64) {
    let along = |sign: f64| {
        let fits = |s: f64| {
            let mut pose = Vector6::zeros();
            pose[dof] = sign * s;
            stewart.fits(&pose, 0.0)
        };
        let step = up_to / MARCH as f64;
        let mut inside = 0.0;
        for k in 1..=MARCH {
            let s = step * k as f64;
            if !fits(s) {
                let mut outside = s;
                for _ in 0..HALVINGS {
                    let mid = 0.5 * (inside + outside);
                    if fits(mid) {
                        inside = mid;
                    } else {
                        outside = mid;
                    }
                }
                return inside;
            }
            inside = s;
        }
        up_to
    };
    (along(1.0), along(-1.0))
}

/// The legs' Jacobian at neutral: its condition number (largest over smallest singular
/// value) with the rotations scaled by the platform joints' mean radius, so that every column
/// is in metres of leg per metre at the joints, and the DoFs (0–5) along which the legs act
/// least: those that make up at least a quarter of the singular vectors whose singular
/// values are within twice the smallest (a symmetric hexapod's roll and pitch come as a
/// pair).
pub fn neutral_conditioning(stewart: &Stewart) -> (f64, Vec<usize>) {
    let radius_m = stewart
        .platform_joints_m
        .iter()
        .map(|p| p.xy().norm())
        .sum::<f64>()
        / 6.0;
    let mut j = stewart.jacobian(&Vector6::zeros());
    for row in 0..6 {
        for col in 3..6 {
            j[(row, col)] /= radius_m.max(f64::MIN_POSITIVE);
        }
    }
    let svd = j.svd(false, true);
    let (max, min) = (svd.singular_values.max(), svd.singular_values.min());
    let weakest = svd.v_t.as_ref().map_or_else(Vec::new, |v_t| {
        let weak: Vec<usize> = (0..6)
            .filter(|&i| svd.singular_values[i] <= 2.0 * min)
            .collect();
        (0..6)
            .filter(|&dof| weak.iter().map(|&i| v_t[(i, dof)].powi(2)).sum::<f64>() >= 0.25)
            .collect()
    });
    let condition = if min > 0.0 { max / min } else { f64::INFINITY };
    (condition, weakest)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::text::default_profile;

    /// Heave in the symmetric form, by hand: every leg keeps its horizontal length d, so
    /// leg i is √(d² + (h0 + Δ)²) with Δ up; the reach up is where the longest leg meets
    /// leg_max, down where the shortest meets leg_min.
    #[test]
    fn heave_reach_matches_the_closed_form() {
        let p = default_profile();
        let s = Stewart::new(&p.geometry);
        let h0 = p.geometry.neutral_height();
        let d: Vec<f64> = (0..6)
            .map(|i| (s.platform_joints_m[i] - s.base_joints_m[i]).xy().norm())
            .collect();
        let d_max = d.iter().cloned().fold(0.0, f64::max);
        let d_min = d.iter().cloned().fold(f64::INFINITY, f64::min);
        let up = (p.geometry.leg_max_m.powi(2) - d_max.powi(2)).sqrt() - h0;
        let down = h0 - (p.geometry.leg_min_m.powi(2) - d_min.powi(2)).sqrt();
        // z is down: −z is up.
        let (plus_z, minus_z) = reach(&s, 2, 5.0);
        assert!((minus_z - up).abs() < 1e-9, "{minus_z} vs {up}");
        assert!((plus_z - down).abs() < 1e-9, "{plus_z} vs {down}");
    }

    #[test]
    fn a_reach_within_the_range_is_the_range() {
        let p = default_profile();
        let s = Stewart::new(&p.geometry);
        assert_eq!(reach(&s, 0, 0.01), (0.01, 0.01));
    }

    /// A flat hexapod's legs barely act out of its plane: the condition number grows as the
    /// legs lie down (2.9 for the shipped geometry, 21 at a tenth of a metre), and roll and
    /// pitch, which move the joints up and down, are the weak directions.
    #[test]
    fn a_flat_hexapod_is_ill_conditioned_out_of_its_plane() {
        let mut g = default_profile().geometry;
        let (shipped, _) = neutral_conditioning(&Stewart::new(&g));
        let mut last = shipped;
        for h in [1.0, 0.5, 0.3, 0.1] {
            g.neutral_height_m = Some(h);
            let (c, _) = neutral_conditioning(&Stewart::new(&g));
            assert!(c > last || h == 1.0, "{c} at {h} m, {last} above");
            last = c;
        }
        let (flat, weakest) = neutral_conditioning(&Stewart::new(&g));
        assert!(flat > 5.0 * shipped, "{flat} vs {shipped}");
        assert!(weakest.contains(&3) && weakest.contains(&4), "{weakest:?}");
        // An independent check of the number: the singular values of J Jᵀ's square roots.
        let j = Stewart::new(&g).jacobian(&Vector6::zeros());
        let r = Stewart::new(&g)
            .platform_joints_m
            .iter()
            .map(|p| p.xy().norm())
            .sum::<f64>()
            / 6.0;
        let mut scaled = j;
        for row in 0..6 {
            for col in 3..6 {
                scaled[(row, col)] /= r;
            }
        }
        let eig = (scaled * scaled.transpose()).symmetric_eigenvalues();
        let by_eig = (eig.max() / eig.min()).sqrt();
        assert!((by_eig - flat).abs() < 1e-6 * flat, "{by_eig} vs {flat}");
    }
}
