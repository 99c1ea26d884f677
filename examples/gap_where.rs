//! Where the yardstick's gap lies, by channel and by time window (docs/bound.md, "The gap"):
//! the relaxed joint optimum as the linear model charges it against the achieved candidates
//! through the exact head, each channel's error in windows of WINDOW seconds.
//! `cargo run --example gap_where -- TRACE.csv [SECONDS] [WINDOW]` (GAP_WHERE_RELAXED=1: the
//! relaxation only; GAP_WHERE_LIGHTENING=1: with the tilt's lightening in heave)

use std::path::Path;

use hexcue::formats::trace::load_trace;
use hexcue_core::bound::{achieved_with_legs, commands_of, model_input, relaxed, Setup};
use hexcue_core::engine::perceive_command;
use hexcue_core::mca::PlatformCommand;
use hexcue_core::model::vestibular::Vestibular;
use hexcue_core::profile::text::default_profile;
use hexcue_core::profile::Profile;
use hexcue_core::score::soft_dead_zone;

/// Per step and channel, the weighted error of a motion through the exact head (no limiter).
fn errors(profile: &Profile, setup: &Setup, cmds: &[PlatformCommand]) -> Vec<[f64; 6]> {
    let (st, eye) = (profile.stewart(), profile.eye_point());
    let mut v = Vestibular::new(&profile.vestibular, profile.dt_s());
    cmds.iter()
        .enumerate()
        .map(|(k, c)| {
            let (p, _) = perceive_command(c, &st, &eye, &mut v);
            let y = p.channels();
            std::array::from_fn(|ch| {
                setup.score_weights[ch]
                    * soft_dead_zone(
                        (y[ch] - setup.reference[ch][k]) / setup.thresholds[ch],
                        setup.below_threshold_weight,
                    )
            })
        })
        .collect()
}

/// Per step and channel, the weighted error the programmes' model gives a motion.
fn linear_steps(setup: &Setup, cmds: &[PlatformCommand]) -> Vec<[f64; 6]> {
    let mut states: Vec<nalgebra::DVector<f64>> = setup
        .filters
        .iter()
        .map(|f| nalgebra::DVector::zeros(f.a.nrows()))
        .collect();
    cmds.iter()
        .enumerate()
        .map(|(k, cmd)| {
            std::array::from_fn(|c| {
                let f = &setup.filters[c];
                let y = (&f.c * &states[c])[0];
                let e = setup.score_weights[c]
                    * soft_dead_zone(
                        (y - setup.reference[c][k]) / setup.thresholds[c],
                        setup.below_threshold_weight,
                    );
                states[c] = &f.a * &states[c] + &f.b * model_input(setup, c, cmd);
                e
            })
        })
        .collect()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let profile = default_profile();
    let mut trace = load_trace(Path::new(&args[0]), profile.rate_hz)?.trace;
    if let Some(s) = args.get(1) {
        trace
            .samples
            .truncate((s.parse::<f64>()? * profile.rate_hz) as usize);
    }
    let window: f64 = args.get(2).map_or(Ok(5.0), |s| s.parse())?;
    // GAP_WHERE_LIGHTENING: `lower` with the tilt's lightening in heave (docs/bound.md).
    let mut setup = Setup::new(&profile, &trace)?;
    if std::env::var("GAP_WHERE_LIGHTENING").is_ok() {
        setup = setup.lightened();
    }
    let n = trace.len();
    let r = relaxed(&setup, [true; 6])?;
    println!("lower per channel alone: {:?}", r.channel);
    println!(
        "joint optimum per channel: {:?} total {:.4}",
        r.joint_error, r.total
    );
    let relaxed_cmds = commands_of(&r.joint, &setup.limits);
    let lin = hexcue_core::bound::linear_error(&setup, &relaxed_cmds);
    println!("relaxed, linear model: {lin:?}");
    let mut rows = vec![(
        "relaxed exact".to_string(),
        errors(&profile, &setup, &relaxed_cmds),
    )];
    rows.push((
        "relaxed linear".to_string(),
        linear_steps(&setup, &relaxed_cmds),
    ));
    let mut best: Option<(String, f64, Vec<PlatformCommand>)> = None;
    let only_relaxed = std::env::var("GAP_WHERE_RELAXED").is_ok();
    for (label, rep, _) in if only_relaxed {
        Vec::new()
    } else {
        achieved_with_legs(&profile, &trace, &setup)
    } {
        println!(
            "{label}: {:.4} {:?}",
            rep.total,
            rep.error.map(|e| (e * 1e4).round() / 1e4)
        );
        if rep.commands.is_empty() {
            println!("  (unsolved)");
            continue;
        }
        if best.as_ref().is_none_or(|b| rep.total < b.1) {
            best = Some((label, rep.total, rep.issued.clone()));
        }
    }
    let (label, _, cmds) = best.unwrap_or(("relaxed".into(), 0.0, relaxed_cmds.clone()));
    rows.push((format!("best: {label}"), errors(&profile, &setup, &cmds)));
    // The relaxed optimum per step through its linear model.
    let w = (window * profile.rate_hz) as usize;
    for (name, e) in &rows {
        println!("\n{name}: per {window} s window, sum of weighted error / N (fx fy fz wx wy wz)");
        for (i, chunk) in e.chunks(w).enumerate() {
            let s: [f64; 6] =
                std::array::from_fn(|c| chunk.iter().map(|x| x[c]).sum::<f64>() / n as f64);
            println!(
                "  {:5.1}s {}",
                i as f64 * window,
                s.iter()
                    .map(|x| format!("{x:8.5}"))
                    .collect::<Vec<_>>()
                    .join(" ")
            );
        }
    }
    // Pitch and heave of the best motion, at the window starts.
    println!("\nbest motion: t, x, z, pitch(deg), ax");
    for k in (0..n).step_by(w) {
        let c = &cmds[k];
        println!(
            "  {:5.1} {:7.3} {:7.3} {:6.2} {:6.2}",
            k as f64 / profile.rate_hz,
            c.pose[0],
            c.pose[2],
            c.pose[4].to_degrees(),
            c.acceleration[0]
        );
    }
    Ok(())
}
