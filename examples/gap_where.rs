//! Where the yardstick's gap lies, by channel and by time window (docs/bound.md, "The gap"):
//! the relaxed joint optimum as the linear model charges it against the achieved candidates
//! through the exact head, each channel's error in windows of WINDOW seconds.
//! `cargo run --example gap_where -- TRACE.csv [SECONDS] [WINDOW]` (GAP_WHERE_RELAXED=1: the
//! relaxation only; GAP_WHERE_LIGHTENING=1: with the tilt's lightening in heave, and the achieved motion's
//! sequence from the lightened relaxation, `LIGHTENED_SEQUENCE`)

use std::path::Path;

use hexcue::formats::trace::load_trace;
use hexcue_core::bound::{
    achieved_with_sequences, commands_of, model_input, relaxed, Setup, ACHIEVED_SEQUENCES,
    LIGHTENED_SEQUENCE,
};
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
    // With the lightening: where the relaxation takes lightness no tilt of its own gives (L
    // above the true g(1 − cos θ cos φ) of its tilts), per window: what a branch and bound
    // over the tilt would have to remove (docs/bound.md).
    let window_steps = (window * profile.rate_hz) as usize;
    for sol in r.joint.iter().filter(|s| !s.lightening_mps2.is_empty()) {
        println!("free lightness of the relaxed optimum (L − g(1 − cos θ cos φ), m/s²):");
        let free: Vec<f64> = (0..sol.pose.len())
            .map(|k| {
                let (phi, theta) = (sol.pose[k][3], sol.pose[k][4]);
                let l = sol.lightening_mps2[k];
                l[0] + l[1] - hexcue_core::G_MPS2 * (1.0 - theta.cos() * phi.cos())
            })
            .collect();
        for (i, chunk) in free.chunks(window_steps).enumerate() {
            let mean = chunk.iter().sum::<f64>() / chunk.len() as f64;
            let over = chunk.iter().filter(|f| **f > 0.05).count();
            let tilt = sol.pose[(i * window_steps).min(sol.pose.len() - 1)][4].to_degrees();
            println!(
                "  {:5.1}s mean {mean:.3}, max {:.3}, steps above 0.05: {over}, pitch at start {tilt:.1}°",
                i as f64 * window,
                chunk.iter().cloned().fold(f64::MIN, f64::max)
            );
        }
    }
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
        // With the lightening, also the sequence from the lightened relaxation.
        let mut sequences = ACHIEVED_SEQUENCES.to_vec();
        if setup.lightening {
            sequences.push(LIGHTENED_SEQUENCE);
        }
        achieved_with_sequences(&profile, &trace, &setup, &sequences)
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
    // The best motion as the programmes' model charges it (with the lightening: M_L's error
    // of a motion the platform makes, an upper end of M_L's optimum).
    let model: f64 = hexcue_core::bound::linear_error(&setup, &cmds).iter().sum();
    println!("best ({label}) under the programmes' model: {model:.4}");
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
