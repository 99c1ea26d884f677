//! Air and ground tunings (issue 36, docs/parameters.md *Air and ground*), end to end:
//! `hexcue play --headless` of the CWF on the shipped take-off and landing with a profile
//! whose `[ground]` table lowers the master gain (and, in the second profile, a CWF scale).
//! The ground tuning is in force on the ground and the air tuning in the air, exactly where
//! the flight's phase is pure (the recorded command against runs with each tuning alone),
//! the change is said at lift-off and touchdown, and across each the command's acceleration
//! exceeds the larger of the two tunings' own by no more than the transition limits
//! (2 m/s², 30 °/s²).

mod common;

use std::path::{Path, PathBuf};

use common::*;

const AXIS_MPS2: f64 = 2.0;
/// The recording's pose resolution (1 µm, 1 µrad: docs/recordings.md), twice: a recorded
/// value and the recorded value it is compared with are each rounded.
const RESOLUTION: f64 = 1e-6 + 1e-12;
const ANGLE_DPS2: f64 = 30.0;
const DT_S: f64 = 0.01;

type Poses = Vec<(f64, [f64; 6])>;

fn poses(path: &Path) -> Poses {
    recorded_poses(path)
}

/// `play --headless` of the CWF on a shipped trace with `profile`: the recorded poses and
/// stderr.
fn play(dir: &Path, trace: &str, profile: &Path, name: &str) -> (Poses, String) {
    let mcap = dir.join(format!("{name}.mcap"));
    let out = hexcue(&[
        "play".as_ref(),
        "--headless".as_ref(),
        "--algorithms".as_ref(),
        "cwf".as_ref(),
        "--trace".as_ref(),
        repo()
            .join(format!("recordings/traces/{trace}.csv"))
            .as_os_str(),
        "--profile".as_ref(),
        profile.as_os_str(),
        "--record".as_ref(),
        mcap.as_os_str(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    (poses(&mcap), stderr(&out))
}

/// The shipped full-flight profile with `edit` applied to its TOML, written as `name`.
fn profile(dir: &Path, name: &str, edit: impl FnOnce(&mut toml_edit::DocumentMut)) -> PathBuf {
    let text = std::fs::read_to_string(repo().join("profiles/full-flight.toml")).unwrap();
    let mut doc: toml_edit::DocumentMut = text.parse().unwrap();
    edit(&mut doc);
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, doc.to_string()).unwrap();
    path
}

const GROUND_SCALE: f64 = 0.3;

/// `[ground]`: the master gain at 0.4 and, with `scale`, the CWF's surge and sway scales at
/// 0.3; the same keys at the top for a profile that is on the ground throughout.
fn ground_keys(doc: &mut toml_edit::DocumentMut, table: &str, scale: bool) {
    let t = if table.is_empty() {
        doc.as_table_mut()
    } else {
        doc[table] = toml_edit::table();
        doc[table].as_table_mut().unwrap()
    };
    t["motion_gain"] = toml_edit::value(0.4);
    if scale {
        let mut s = toml_edit::Array::new();
        for v in [GROUND_SCALE, GROUND_SCALE, 0.8] {
            s.push(v);
        }
        if table.is_empty() {
            t["cwf"]["specific_force_scale"] = toml_edit::value(s);
        } else {
            let mut cwf = toml_edit::Table::new();
            cwf.set_implicit(true);
            cwf["specific_force_scale"] = toml_edit::value(s);
            t["cwf"] = toml_edit::Item::Table(cwf);
        }
    }
}

/// The worst acceleration (second difference of the poses) per DoF within [from, to].
fn worst_acceleration(p: &Poses, from: f64, to: f64) -> [f64; 6] {
    let mut worst = [0.0f64; 6];
    for k in 2..p.len() {
        if p[k].0 < from || p[k].0 > to {
            continue;
        }
        for (i, w) in worst.iter_mut().enumerate() {
            let a = (p[k].1[i] - 2.0 * p[k - 1].1[i] + p[k - 2].1[i]) / (DT_S * DT_S);
            *w = w.max(a.abs());
        }
    }
    worst
}

/// Across the change at `t_c`: the command's acceleration within the larger of the two
/// tunings' own plus the transition limits.
fn no_step(name: &str, mixed: &Poses, air: &Poses, ground: &Poses, t_c: f64) {
    let (from, to) = (t_c - 1.0, t_c + 6.0);
    let m = worst_acceleration(mixed, from, to);
    let a = worst_acceleration(air, from, to);
    let g = worst_acceleration(ground, from, to);
    eprintln!(
        "{name}: worst acceleration from {from:.2} s to {to:.2} s (surge sway heave m/s², roll \
         pitch yaw °/s²): switched {:?}, air alone {:?}, ground alone {:?}",
        shown(&m),
        shown(&a),
        shown(&g)
    );
    for i in 0..6 {
        let limit = if i < 3 {
            AXIS_MPS2
        } else {
            ANGLE_DPS2.to_radians()
        };
        assert!(
            m[i] <= a[i].max(g[i]) + limit,
            "{name} DoF {i}: {} against {} and {}",
            m[i],
            a[i],
            g[i]
        );
    }
}

fn shown(a: &[f64; 6]) -> [String; 6] {
    std::array::from_fn(|i| {
        let v = if i < 3 { a[i] } else { a[i].to_degrees() };
        format!("{v:.3}")
    })
}

/// The change's time from its stderr event (`play: t 18.52 s: in the air: …`).
fn change_time(err: &str, words: &str) -> f64 {
    let line = err
        .lines()
        .find(|l| l.starts_with("play: t ") && l.contains(words))
        .unwrap_or_else(|| panic!("no `{words}` event in\n{err}"));
    line["play: t ".len()..]
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap()
}

fn assert_scaled(name: &str, p: &Poses, by: &Poses, gain: f64, from: f64, to: f64) {
    let mut n = 0;
    for ((t, x), (_, r)) in p.iter().zip(by) {
        if *t < from || *t > to {
            continue;
        }
        n += 1;
        for i in 0..6 {
            assert!(
                (x[i] - gain * r[i]).abs() <= RESOLUTION,
                "{name}: t {t} DoF {i}: {} against {gain} × {}",
                x[i],
                r[i]
            );
        }
    }
    assert!(n > 100, "{name}: {n} steps checked in [{from}, {to}]");
}

#[test]
fn the_ground_tuning_is_in_force_on_the_runway_and_the_air_tuning_in_flight() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let air_profile = profile(d, "air", |_| {});
    let gains = profile(d, "ground-gain", |doc| ground_keys(doc, "ground", false));
    let keyed = profile(d, "ground-keys", |doc| ground_keys(doc, "ground", true));
    let throughout = profile(d, "ground-throughout", |doc| ground_keys(doc, "", true));
    for trace in ["takeoff", "landing"] {
        let (air, _) = play(d, trace, &air_profile, &format!("{trace}-air"));
        let (ground, _) = play(d, trace, &throughout, &format!("{trace}-ground"));
        let (by_gain, err) = play(d, trace, &gains, &format!("{trace}-gain"));
        let (by_keys, err_keys) = play(d, trace, &keyed, &format!("{trace}-keys"));
        let end = air.last().unwrap().0;
        let (words, on_ground_before) = match trace {
            // The sidecars: lift-off at 18.52 s, main gear touchdown at 32.43 s.
            "takeoff" => (
                "in the air: the air tuning blends back in within 3.00 s",
                true,
            ),
            _ => (
                "on the ground: the profile's [ground] tuning blends in within 3.00 s",
                false,
            ),
        };
        let t_c = change_time(&err, words);
        assert_eq!(t_c, change_time(&err_keys, words));
        assert_eq!(t_c, if on_ground_before { 18.52 } else { 32.43 });
        // The gains alone: exactly 0.4 × the air's command on the ground, exactly the air's
        // in the air once the gain's path (under 5 s) is over.
        let (g_before, g_after) = if on_ground_before {
            (0.4, 1.0)
        } else {
            (1.0, 0.4)
        };
        assert_scaled(trace, &by_gain, &air, g_before, 0.0, t_c - DT_S);
        assert_scaled(trace, &by_gain, &air, g_after, t_c + 5.0, end);
        no_step(&format!("{trace}, gain"), &by_gain, &air, &ground, t_c);
        // With a CWF key too: the phase the flight starts in runs exactly its own tuning;
        // the change blends without a step.
        let first = if on_ground_before { &ground } else { &air };
        assert_scaled(trace, &by_keys, first, 1.0, 0.0, t_c - DT_S);
        no_step(
            &format!("{trace}, gain and scale"),
            &by_keys,
            &air,
            &ground,
            t_c,
        );
    }
}

#[test]
fn a_ground_key_that_is_not_a_tuning_is_refused_with_its_name() {
    let dir = tempfile::tempdir().unwrap();
    let bad = profile(dir.path(), "bad", |doc| {
        doc["ground"] = toml_edit::table();
        doc["ground"]["limits"] = toml_edit::value(1.0);
    });
    let out = hexcue(&[
        "play".as_ref(),
        "--headless".as_ref(),
        "--profile".as_ref(),
        bad.as_os_str(),
    ]);
    assert!(!out.status.success());
    let err = stderr(&out);
    assert!(
        err.contains("`ground.limits`")
            && err.contains("expected motion_gain, or keys of [gain], [cwf], [mpc] or [smpc]"),
        "{err}"
    );
}
