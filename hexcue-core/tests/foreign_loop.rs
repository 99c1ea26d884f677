//! The example `foreign_loop` (the S-MPC in a lab's own loop) runs, and its platform does
//! what the made-up take-off roll asks: pitched nose up for the sustained thrust, swayed
//! by the gust, every leg inside its stroke. Run through the example's own code (`#[path]`),
//! with the shipped profile less its wall-clock limit so that the result does not depend on
//! this machine's load.

#[path = "../examples/foreign_loop.rs"]
#[allow(dead_code)]
mod foreign_loop;

use foreign_loop::{pose_line, run, take_off_roll, Step, TAKE_OFF_S};

fn at(steps: &[Step], t_s: f64) -> &Step {
    steps
        .iter()
        .find(|s| (s.t_s - t_s).abs() < 1e-9)
        .expect("a step at that time")
}

#[test]
fn the_s_mpc_steps_a_take_off_roll_in_a_foreign_loop() {
    let profile = hexcue_core::testing::full_flight();
    let steps = run(&profile).unwrap();
    assert_eq!(steps.len(), (TAKE_OFF_S * profile.rate_hz).round() as usize);
    assert!(steps.iter().all(|s| s.command.is_finite()));
    // The limiter's promise: every leg keeps the profile's margin from its end stops.
    let closest = steps
        .iter()
        .map(|s| s.leg_margin_m)
        .fold(f64::INFINITY, f64::min);
    assert!(
        closest >= profile.limiter.leg_margin_m - 1e-9,
        "closest leg {closest} m"
    );
    // Sustained thrust before the gust: the cabin is pitched nose up so that gravity gives
    // the forward push (+g·θ on f_x), and it is not rolled.
    let thrust = at(&steps, 4.0).command.pose;
    assert!(thrust[4] > 0.5f64.to_radians(), "pitch {} rad", thrust[4]);
    assert!(
        thrust[3].abs() < 0.1f64.to_radians(),
        "roll {} rad",
        thrust[3]
    );
    // The gust pushes the aircraft left (f_y < 0) for half a second: the platform sways left
    // (y < 0) after having held its lateral position through the thrust.
    assert!(thrust[1].abs() < 1e-3, "y {} m", thrust[1]);
    let gust_sway_m = steps
        .iter()
        .filter(|s| s.t_s >= 5.0 && s.t_s < 7.0)
        .map(|s| s.command.pose[1])
        .fold(f64::INFINITY, f64::min);
    assert!(gust_sway_m < -0.1, "y {gust_sway_m} m");
    // The printed line carries the pose in mm and degrees.
    let line = pose_line(at(&steps, 4.0));
    assert!(line.starts_with(" 4.00 s  x "), "{line}");
    assert!(
        line.contains(&format!("pitch {:6.2}", thrust[4].to_degrees())),
        "{line}"
    );
}

#[test]
fn the_made_up_take_off_is_at_rest_before_the_thrust_and_lifts_at_rotation() {
    let start = take_off_roll(0.0);
    assert_eq!(start.delta_f_mps2(), nalgebra::Vector3::zeros());
    let rotating = take_off_roll(9.0);
    assert!(rotating.angular_velocity_radps.y > 0.0);
    assert!(
        rotating.delta_f_mps2().z < 0.0,
        "more lift: f_z further below −g"
    );
}
