//! Why the workspace limiter cuts the yardstick's achieved motion (docs/bound.md, "The gap"):
//! solves the achieved programme's sequences, takes each candidate's commands and replays them
//! through the lanes' limiter, counting `WorkspaceLimiter::rejection` at the step where each
//! stretch of limiting starts (the cause) and at the steps after it (the cascade), and checks
//! every command against its own predecessor with the limiter's checks written out (the
//! "shadow": what the plan itself breaks, with no earlier cut).
//! `cargo run --example gap_probe -- TRACE.csv [SECONDS]`; `GAP_PROBE_ONLY=text` details only
//! the candidates whose label contains it, `GAP_PROBE_VERBOSE=1` prints every stretch's start.

use std::collections::BTreeMap;
use std::path::Path;

use hexcue::formats::trace::load_trace;
use hexcue_core::bound::{achieved_with_legs, replay_with, Setup};
use hexcue_core::mca::limiter::{Rejection, WorkspaceLimiter};
use hexcue_core::mca::PlatformCommand;
use hexcue_core::model::platform::DofLimits;
use hexcue_core::model::stewart::Stewart;
use hexcue_core::profile::text::default_profile;
use nalgebra::Vector6;

const DOF: [&str; 6] = ["x", "y", "z", "roll", "pitch", "yaw"];

fn reason(r: &Rejection) -> String {
    match r {
        Rejection::NonFinite => "non-finite".into(),
        Rejection::Excursion(d) => format!("excursion {}", DOF[*d]),
        Rejection::Legs => "legs".into(),
        Rejection::Velocity(d) => format!("velocity {}", DOF[*d]),
        Rejection::Acceleration(d) => format!("acceleration {}", DOF[*d]),
        Rejection::Braking => "braking".into(),
    }
}

/// The limiter's braking look-ahead written out: where the simulated stop first fails
/// (excursion of a DoF, or legs with the worst margin), `None` if it stops inside.
fn braking_failure(
    s: &Stewart,
    lim: &DofLimits,
    margin: f64,
    dt: f64,
    pose: &Vector6<f64>,
    rate: &Vector6<f64>,
) -> Option<(usize, String)> {
    let (mut p, mut v) = (*pose, *rate);
    for step in 1..=1000 {
        if v.iter().all(|x| *x == 0.0) {
            return None;
        }
        for i in 0..6 {
            let a = lim.acceleration[i];
            v[i] += (-v[i] / dt).clamp(-a, a) * dt;
            if v[i].abs() < 1e-12 {
                v[i] = 0.0;
            }
            p[i] += v[i] * dt;
        }
        if let Some(d) = (0..6).find(|&i| p[i].abs() > lim.excursion[i]) {
            return Some((step, format!("excursion {}", DOF[d])));
        }
        let m = s.margins(&s.leg_lengths(&p));
        if m.min() < margin {
            // Which DoFs were still moving (the braking path differs from the plan's).
            let moving: Vec<&str> = (0..6).filter(|&i| v[i] != 0.0).map(|i| DOF[i]).collect();
            return Some((
                step,
                format!(
                    "legs (leg {} margin {:.1} mm; moving {})",
                    m.imin(),
                    m.min() * 1e3,
                    moving.join(",")
                ),
            ));
        }
    }
    None
}

fn shadow(
    s: &Stewart,
    lim: &DofLimits,
    margin: f64,
    dt: f64,
    cmds: &[PlatformCommand],
) -> BTreeMap<String, usize> {
    let mut out = BTreeMap::new();
    let (mut last, mut last_rate) = (Vector6::zeros(), Vector6::<f64>::zeros());
    let slack = 1.0 + 1e-6;
    for c in cmds {
        let rate = (c.pose - last) / dt;
        let mut why: Option<String> = None;
        if let Some(d) = (0..6).find(|&i| c.pose[i].abs() > lim.excursion[i]) {
            why = Some(format!("excursion {}", DOF[d]));
        } else if !s.fits(&c.pose, margin) {
            why = Some("legs".into());
        } else {
            for i in 0..6 {
                let rc = (rate[i] - last_rate[i]) / dt;
                if c.velocity[i].abs() > lim.velocity[i] * slack
                    || rate[i].abs() > lim.velocity[i] * slack + 1e-9
                {
                    why = Some(format!("velocity {}", DOF[i]));
                    break;
                }
                if c.acceleration[i].abs() > lim.acceleration[i] * slack
                    || rc.abs() > lim.acceleration[i] * slack + 1e-9
                {
                    why = Some(format!("acceleration {}", DOF[i]));
                    break;
                }
            }
            if why.is_none() {
                if let Some((_, w)) = braking_failure(s, lim, margin, dt, &c.pose, &rate) {
                    let key: String = w.split(" (").next().unwrap_or("").to_string();
                    why = Some(format!("braking: {key}"));
                }
            }
        }
        if let Some(w) = why {
            *out.entry(w).or_insert(0) += 1;
        }
        last_rate = rate;
        last = c.pose;
    }
    out
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let trace_path = args.first().ok_or("usage: gap_probe TRACE.csv [SECONDS]")?;
    let profile = default_profile();
    let mut trace = load_trace(Path::new(trace_path), profile.rate_hz)?.trace;
    if let Some(s) = args.get(1) {
        let keep = (s.parse::<f64>()? * profile.rate_hz).round() as usize;
        trace.samples.truncate(keep.max(2));
    }
    let setup = Setup::new(&profile, &trace)?;
    let (s, lim, dt) = (profile.stewart(), profile.limits.si(), profile.dt_s());
    let margin = profile.limiter.leg_margin_m;
    let verbose = std::env::var("GAP_PROBE_VERBOSE").is_ok();
    for (label, r, _) in achieved_with_legs(&profile, &trace, &setup) {
        let unlimited = replay_with(&profile, &trace, &r.commands, false).total;
        println!(
            "\n{label}: total {:.4}, limiter {:.2} %, without the limiter {unlimited:.4}",
            r.total,
            100.0 * r.limiter_fraction
        );
        if std::env::var("GAP_PROBE_ONLY").is_ok_and(|w| !label.contains(w.as_str())) {
            continue;
        }
        let mut limiter = WorkspaceLimiter::new(s.clone(), lim, margin, dt);
        let (mut first, mut cascade) = (BTreeMap::new(), BTreeMap::new());
        let mut braking_detail: BTreeMap<String, usize> = BTreeMap::new();
        let (mut runs, mut acted_prev, mut run_len, mut longest) = (0, false, 0, 0);
        for (k, c) in r.commands.iter().enumerate() {
            let why = limiter.rejection(c);
            let before = *limiter.last();
            let out = limiter.apply(c);
            if out.acted {
                let w = why.as_ref().map_or("none?".to_string(), reason);
                if acted_prev {
                    *cascade.entry(w).or_insert(0) += 1;
                    run_len += 1;
                } else {
                    runs += 1;
                    run_len = 1;
                    if why == Some(Rejection::Braking) {
                        let rate = (c.pose - before.pose) / dt;
                        if let Some((step, d)) =
                            braking_failure(&s, &lim, margin, dt, &c.pose, &rate)
                        {
                            let key = d.split(" margin").next().unwrap_or("").to_string();
                            *braking_detail.entry(key).or_insert(0) += 1;
                            if verbose {
                                println!(
                                    "  k={k} t={:.2}: braking fails after {step} steps: {d}; \
                                     pose {:?} rate {:?}",
                                    k as f64 * dt,
                                    c.pose.as_slice(),
                                    rate.as_slice()
                                );
                            }
                        }
                    } else if verbose {
                        println!("  k={k} t={:.2}: {w}", k as f64 * dt);
                    }
                    *first.entry(w).or_insert(0) += 1;
                }
                longest = longest.max(run_len);
            }
            acted_prev = out.acted;
        }
        println!("  stretches of limiting: {runs}, longest {longest} steps");
        println!("  the cause (first step of a stretch): {first:?}");
        println!("  braking failures at a stretch's start: {braking_detail:?}");
        println!("  the cascade (the steps after): {cascade:?}");
        println!(
            "  shadow (each command against its own predecessor): {:?}",
            shadow(&s, &lim, margin, dt, &r.commands)
        );
    }
    Ok(())
}
