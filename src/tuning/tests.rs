use super::*;
use hexcue_core::testing::full_flight;

fn tuner() -> Tuner {
    Tuner::new(&full_flight(), &[AlgorithmId::Cwf, AlgorithmId::Smpc]).unwrap()
}

#[test]
fn every_parameter_is_listed_with_its_range_and_value_in_force() {
    let t = tuner();
    let names: Vec<&str> = t.parameters().iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names[0], MOTION_GAIN);
    assert_eq!(
        &names[1..7],
        [
            "gain.surge",
            "gain.sway",
            "gain.heave",
            "gain.roll",
            "gain.pitch",
            "gain.yaw"
        ]
    );
    for name in [
        "cwf.specific_force_scale[0]",
        "cwf.tilt_lp_wn_radps",
        "cwf.tilt_limit_deg",
        "mpc.specific_force_weight[0,1]",
        "smpc.cotc.washout_position_weight[2]",
    ] {
        assert!(names.contains(&name), "{name} in {names:?}");
    }
    // The supervisor's own keys are not live.
    assert!(!names.iter().any(|n| n.starts_with("smpc.dwell")));
    let p = full_flight();
    assert_eq!(
        t.get("cwf.specific_force_scale[1]"),
        Some(p.cwf.specific_force_scale[1])
    );
    assert_eq!(t.get("cwf.tilt_limit_deg"), Some(p.cwf.tilt_limit_deg));
    assert_eq!(t.get(MOTION_GAIN), Some(1.0));
    // The tuner's bounds.
    let i = t.index("cwf.translational_hp_wn_radps[2]").unwrap();
    assert_eq!(
        (t.parameters()[i].lower, t.parameters()[i].upper),
        (1.0, 10.0)
    );
}

#[test]
fn out_of_range_is_refused_with_the_range_and_changes_nothing() {
    let mut t = tuner();
    let before = t.profile().clone();
    let e = t.set(MOTION_GAIN, 2.0).err().unwrap();
    assert_eq!(
        e.to_string(),
        "`motion_gain`: 2 is outside its safe range [0, 1]: nothing changed"
    );
    assert!(t.set("cwf.specific_force_scale[0]", f64::NAN).is_err());
    assert!(matches!(
        t.set("cwf.nope", 0.5),
        Err(ParamError::Unknown { .. })
    ));
    assert_eq!(t.get(MOTION_GAIN), Some(1.0));
    assert_eq!(t.profile(), &before);
    assert!(t.undo().is_none());
}

/// The algorithms a change rebuilds, one [`hexcue_core::engine::Retune`] each.
fn rebuilt(retunes: &[hexcue_core::engine::Retune]) -> Vec<AlgorithmId> {
    retunes
        .iter()
        .map(|r| {
            let ids = r.algorithms();
            assert_eq!(ids.len(), 1, "one algorithm a retune: {ids:?}");
            ids[0]
        })
        .collect()
}

#[test]
fn a_key_changes_the_profile_and_undo_takes_it_back() {
    let mut t = tuner();
    let c = t.set("cwf.specific_force_scale[0]", 0.3).unwrap();
    assert_eq!(
        (c.from, c.to, c.undo),
        (full_flight().cwf.specific_force_scale[0], 0.3, false)
    );
    match &c.apply {
        Apply::Retune(r) => assert_eq!(rebuilt(r), [AlgorithmId::Cwf]),
        Apply::Gains(_) | Apply::Drive(_) => panic!("a key retunes"),
    }
    assert_eq!(t.profile().cwf.specific_force_scale[0], 0.3);
    t.record(&c, 1.5);
    // [mpc] rebuilds the S-MPC (its two MPCs run on it).
    let c2 = t.set("mpc.specific_force_weight[0,1]", 2.0).unwrap();
    match &c2.apply {
        Apply::Retune(r) => assert_eq!(rebuilt(r), [AlgorithmId::Smpc]),
        Apply::Gains(_) | Apply::Drive(_) => panic!(),
    }
    assert_eq!(t.profile().mpc.specific_force_weight[..2], [2.0, 2.0]);
    let u = t.undo().unwrap().unwrap();
    assert!(u.undo);
    assert_eq!(t.profile().mpc, full_flight().mpc);
    t.record(&u, 2.0);
    let u = t.undo().unwrap().unwrap();
    assert_eq!(t.profile().cwf, full_flight().cwf);
    assert!(t.undo().is_none());
    t.record(&u, 3.0);
    let s = t.summary();
    assert_eq!(s.changes.len(), 3);
    assert_eq!(s.changes[0].name, "cwf.specific_force_scale[0]");
    assert_eq!(s.changes[1].name, "mpc.specific_force_weight[0,1]");
    assert_eq!((s.changes[1].t_s, s.changes[1].undo), (2.0, true));
    assert_eq!(
        s.final_parameter_values["cwf.specific_force_scale[0]"],
        full_flight().cwf.specific_force_scale[0]
    );
}

#[test]
fn the_gains_multiply_and_a_console_step_stays_in_range() {
    let mut t = tuner();
    t.set(MOTION_GAIN, 0.5).unwrap();
    let c = t.set("gain.yaw", 0.4).unwrap();
    match c.apply {
        Apply::Gains(g) => assert_eq!(g, Vector6::new(0.5, 0.5, 0.5, 0.5, 0.5, 0.2)),
        Apply::Retune(_) | Apply::Drive(_) => panic!(),
    }
    let p = &t.parameters()[0];
    assert_eq!(p.step(1.0, true), 1.0);
    assert_eq!(p.step(1.0, false), 0.98);
    assert_eq!(p.step(0.0, false), 0.0);
    let i = t.index("mpc.acceleration_weight[0,1,2]").unwrap();
    let p = &t.parameters()[i];
    // Log keys step by a fiftieth of their decades: 1e-4..0.1 is 3 decades.
    let up = p.step(0.01, true);
    assert!((up / 0.01 - 10f64.powf(3.0 / 50.0)).abs() < 1e-3, "{up}");
}

/// The values in force written into a profile file's own text keep its comments, and the
/// text loads with them.
#[test]
fn writing_back_keeps_the_files_comments_and_reloads() {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/profiles/full-flight.toml"
    ))
    .unwrap();
    let mut t = tuner();
    t.set("cwf.specific_force_scale[1]", 0.25).unwrap();
    t.set("cwf.tilt_limit_deg", 12.0).unwrap();
    let mut doc: DocumentMut = text.parse().unwrap();
    t.write_into(&mut doc).unwrap();
    let out = doc.to_string();
    let changed: Vec<(&str, &str)> = text
        .lines()
        .zip(out.lines())
        .filter(|(a, b)| a != b)
        .collect();
    assert_eq!(changed.len(), 2, "{changed:?}");
    assert_eq!(text.lines().count(), out.lines().count());
    let p = hexcue_core::profile::text::parse_profile(&out, "written").unwrap();
    assert_eq!(p.cwf.specific_force_scale[1], 0.25);
    assert_eq!(p.cwf.tilt_limit_deg, 12.0);
}

/// A retune mid-manoeuvre: the step that applies it sends exactly what the old tuning would
/// (the state kept, the blend at 0), what the change adds to the command's acceleration stays
/// within the 2 m/s² and 30 °/s² through the blend (the manoeuvre's own pitch doublet
/// at 14 s takes the CWF to its 200 °/s² limit either way), and after it the new tuning acts.
#[test]
fn a_retune_mid_manoeuvre_is_bumpless_and_takes_effect() {
    use hexcue_core::engine::Engine;
    let profile = full_flight();
    let trace = std::sync::Arc::new(hexcue_core::testing::manoeuvre());
    let run = |change: bool| {
        let mut engine = Engine::new(&profile, trace.clone(), &[AlgorithmId::Cwf]).unwrap();
        let shared = Shared::handle(Tuner::new(&profile, &[AlgorithmId::Cwf]).unwrap());
        let mut drives = DriveSwitch::new(AlgorithmId::Cwf);
        let mut poses = Vec::new();
        while let Some(frame) = {
            if change && engine.position() == 1200 {
                let mut s = shared.lock().unwrap();
                s.set("cwf.specific_force_scale[1]", 0.2).unwrap();
                s.set("cwf.tilt_lp_wn_radps", 2.0).unwrap();
                let texts = apply_pending(&mut s, &mut engine, &mut drives, 12.0, 3.0, |_| {});
                assert_eq!(texts.len(), 2);
                assert!(texts[0].starts_with("parameter cwf.specific_force_scale[1] set: "));
            }
            engine.step()
        } {
            poses.push(frame.lanes[0].command.pose);
        }
        poses
    };
    let (before, after) = (run(false), run(true));
    assert_eq!(before[..=1200], after[..=1200]);
    let dt = 0.01;
    for k in 1201..1500 {
        let acc = |p: &[nalgebra::Vector6<f64>]| (p[k] - 2.0 * p[k - 1] + p[k - 2]) / (dt * dt);
        let a = acc(&after) - acc(&before);
        for i in 0..6 {
            let (unit, bound) = if i < 3 {
                (1.0, 2.0)
            } else {
                (1f64.to_degrees(), 30.0)
            };
            assert!(
                a[i].abs() * unit <= bound,
                "step {k} DoF {i}: {}",
                a[i] * unit
            );
        }
    }
    // Sway is cued at a third of the scale once the blend is over.
    let diff = (1600..2000)
        .map(|k| (before[k][1] - after[k][1]).abs())
        .fold(0.0, f64::max);
    assert!(diff > 1e-3, "{diff}");
}

/// The gains on the engine's command: the master gain 1 → 0.5 halves the pose once the path
/// is over, the algorithm's own state untouched (its limiter still sees the whole command).
#[test]
fn the_master_gain_halves_the_command_once_its_path_is_over() {
    use hexcue_core::engine::Engine;
    let profile = full_flight();
    let trace = std::sync::Arc::new(hexcue_core::testing::manoeuvre());
    let mut plain = Engine::new(&profile, trace.clone(), &[AlgorithmId::Cwf]).unwrap();
    let mut gained = Engine::new(&profile, trace, &[AlgorithmId::Cwf]).unwrap();
    let shared = Shared::handle(Tuner::new(&profile, &[AlgorithmId::Cwf]).unwrap());
    let mut drives = DriveSwitch::new(AlgorithmId::Cwf);
    let mut follow_s = 0.0;
    for k in 0..2500 {
        if k == 1000 {
            let mut s = shared.lock().unwrap();
            s.set(MOTION_GAIN, 0.5).unwrap();
            let texts = apply_pending(&mut s, &mut gained, &mut drives, 10.0, 3.0, |_| {});
            follow_s = texts[0]
                .split("within ")
                .nth(1)
                .and_then(|t| t.trim_end_matches(" s").parse::<f64>().ok())
                .unwrap();
        }
        let (a, b) = (plain.step().unwrap(), gained.step().unwrap());
        let (a, b) = (a.lanes[0].command.pose, b.lanes[0].command.pose);
        if k < 1000 {
            assert_eq!(a, b);
        }
        if k as f64 >= 1000.0 + follow_s * 100.0 + 1.0 {
            assert!((b - a * 0.5).norm() <= 1e-12, "step {k}");
        }
    }
    assert!(follow_s > 0.5 && follow_s < 5.0, "{follow_s}");
    assert_eq!(shared.lock().unwrap().tuner.summary().changes[0].t_s, 10.0);
}

/// The `drive` parameter: live only (`with_drive`), any of the session's algorithms by its
/// code, others refused with the session's list; `next_drive` cycles through the session's;
/// applied, it switches the drive through a blend and says so; undone, it switches back.
#[test]
fn the_drive_switches_between_the_sessions_algorithms_and_back() {
    let profile = full_flight();
    let algorithms = [AlgorithmId::Cwf, AlgorithmId::Smpc];
    assert_eq!(Tuner::new(&profile, &algorithms).unwrap().get(DRIVE), None);
    let tuner = Tuner::new(&profile, &algorithms)
        .unwrap()
        .with_drive(AlgorithmId::Smpc);
    assert_eq!(tuner.get(DRIVE), Some(2.0));
    assert_eq!(tuner.next_drive(), Some(0.0));
    let shared = Shared::handle(tuner);
    let mut s = shared.lock().unwrap();
    let refused = s.set(DRIVE, 1.0).unwrap_err().to_string();
    assert!(
        refused.contains("`drive`") && refused.contains("cwf, smpc"),
        "{refused}"
    );
    assert!(s.set(DRIVE, 0.5).is_err());
    assert_eq!(s.tuner.get(DRIVE), Some(2.0));
    s.set(DRIVE, 0.0).unwrap();
    let mut engine = hexcue_core::engine::Engine::new(
        &profile,
        std::sync::Arc::new(hexcue_core::testing::manoeuvre()),
        &algorithms,
    )
    .unwrap();
    let mut drives = DriveSwitch::new(AlgorithmId::Smpc);
    let texts = apply_pending(&mut s, &mut engine, &mut drives, 5.0, 3.0, |_| {});
    assert_eq!(drives.drive(), AlgorithmId::Cwf);
    assert!(drives.blending());
    assert!(
        texts[0].starts_with("parameter drive set: 2 → 0 (smpc → cwf), the command blends"),
        "{}",
        texts[0]
    );
    assert_eq!(s.tuner.next_drive(), Some(2.0));
    assert!(s.undo().unwrap());
    let texts = apply_pending(&mut s, &mut engine, &mut drives, 6.0, 3.0, |_| {});
    assert_eq!(drives.drive(), AlgorithmId::Smpc);
    assert!(
        texts[0].starts_with("parameter drive undone: 0 → 2"),
        "{}",
        texts[0]
    );
    assert_eq!(s.tuner.summary().final_parameter_values[DRIVE], 2.0);

    // An engine that does not step the new drive (a live session's stepping thread, whose
    // comparison lanes step elsewhere) hands the switch on, for the lane to be brought over;
    // the drive stays until it comes, and the change stands, to be undone as any other.
    let mut driving_only = hexcue_core::engine::Engine::new(
        &profile,
        std::sync::Arc::new(hexcue_core::testing::manoeuvre()),
        &[AlgorithmId::Smpc],
    )
    .unwrap();
    s.set(DRIVE, 0.0).unwrap();
    let mut handed = Vec::new();
    let texts = apply_pending(&mut s, &mut driving_only, &mut drives, 7.0, 3.0, |a| {
        if let Applied::Drive { to, here } = a {
            handed.push((to, here));
        }
    });
    assert_eq!(handed, [(AlgorithmId::Cwf, false)]);
    assert_eq!(drives.drive(), AlgorithmId::Smpc);
    assert!(
        texts[0].starts_with("parameter drive set: 2 → 0 (smpc → cwf), the command blends")
            && texts[0].contains("within 3.00 s of its lane's arrival"),
        "{}",
        texts[0]
    );
    assert_eq!(s.tuner.get(DRIVE), Some(0.0));
    assert!(s.undo().unwrap());
    assert_eq!(s.tuner.get(DRIVE), Some(2.0));
}
