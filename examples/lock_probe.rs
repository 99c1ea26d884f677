//! Why the limiter acts on the free MPC: runs the MPC alone with the workspace limiter in the
//! loop, as the engine does, and counts the limiter's reasons (`WorkspaceLimiter::rejection`).
//! `cargo run --release --example lock_probe -- TRACE.csv [PROFILE.toml] [SECONDS] [--preview]
//! [--smpc]`; with `--smpc` the S-MPC (both controllers, its switching) instead of the free MPC.

use std::collections::BTreeMap;
use std::path::Path;

use hexcue::formats::profile::load_profile;
use hexcue::formats::trace::load_trace;
use hexcue_core::engine::cue_sample;
use hexcue_core::mca::limiter::WorkspaceLimiter;
use hexcue_core::mca::mpc::{Mpc, Terminal};
use hexcue_core::mca::{AlgorithmId, CueInput, Mode, PlatformCommand};

/// What one step gave, from either controller.
struct Outcome {
    command: PlatformCommand,
    feasible: bool,
}
use hexcue_core::profile::text::default_profile;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let preview = args.iter().any(|a| a == "--preview");
    let smpc = args.iter().any(|a| a == "--smpc");
    let args: Vec<&String> = args.iter().filter(|a| !a.starts_with("--")).collect();
    let trace_path = args
        .first()
        .ok_or("usage: lock_probe TRACE.csv [PROFILE] [S]")?;
    let mut profile = match args.get(1) {
        Some(p) if p.as_str() != "-" => load_profile(Path::new(p.as_str()))?.0,
        _ => default_profile(),
    };
    profile.mpc.time_limit_ms = f64::INFINITY;
    let trace = load_trace(Path::new(trace_path.as_str()), profile.rate_hz)?.trace;
    let seconds: f64 = args.get(2).map_or(Ok(f64::INFINITY), |s| s.parse())?;
    let cues: Vec<_> = trace
        .samples
        .iter()
        .map(|s| cue_sample(&profile, s))
        .collect();
    let dt = profile.dt_s();
    let n = cues.len().min((seconds / dt).round() as usize);
    let mut mpc = Mpc::new(&profile.mpc, &profile.setting(), Terminal::Free)?;
    let mut smpc_lane = if smpc {
        Some(profile.algorithm(AlgorithmId::Smpc)?)
    } else {
        None
    };
    let stewart = profile.stewart();
    let mut limiter = WorkspaceLimiter::new(
        stewart.clone(),
        profile.limits.si(),
        profile.limiter.leg_margin_m,
        dt,
    );
    let mut applied = PlatformCommand::default();
    let mut reasons: BTreeMap<String, usize> = BTreeMap::new();
    let (mut acted, mut unsolved) = (0usize, 0usize);
    let mut chains: BTreeMap<usize, usize> = BTreeMap::new();
    let mut run = 0usize;
    for k in 0..n {
        let ahead = if preview {
            &cues[k + 1..(k + 501).min(cues.len())]
        } else {
            &[][..]
        };
        let input = CueInput {
            k,
            t_s: k as f64 * dt,
            dt_s: dt,
            sample: cues[k],
            preview: ahead,
            applied: &applied,
            deadline: None,
        };
        let out = match smpc_lane.as_mut() {
            Some(lane) => {
                let command = lane.step(&input);
                let state = lane.state();
                Outcome {
                    command,
                    feasible: state.mode != Mode::Fallback,
                }
            }
            None => {
                let o = mpc.solve(&input);
                Outcome {
                    command: o.command,
                    feasible: o.feasible,
                }
            }
        };
        unsolved += usize::from(!out.feasible);
        if let Some(r) = limiter.rejection(&out.command) {
            *reasons.entry(format!("{r:?}")).or_default() += 1;
            if std::env::var("PROBE_VERBOSE").is_ok() {
                let m = stewart.margins(&stewart.leg_lengths(&out.command.pose));
                eprintln!(
                    "t {:.2} {r:?} feasible {} pose {:.4?} vel {:.3?} min margin {:.5}",
                    k as f64 * dt,
                    out.feasible,
                    out.command.pose.as_slice(),
                    out.command.velocity.as_slice(),
                    m.min()
                );
            }
        }
        let limited = limiter.apply(&out.command);
        // The MPC's own braking step for the limiter counts as the limiter's action, as in
        // the engine.
        let braked = match smpc_lane.as_ref() {
            Some(lane) => lane.issued_limiter_braking(),
            None => mpc.braked_now(),
        };
        let acted_now = limited.acted || braked;
        acted += usize::from(acted_now);
        // Runs of consecutive limiter actions, by length: one refusal that becomes ten shows
        // as a run of ten.
        if acted_now {
            run += 1;
        } else if run > 0 {
            *chains.entry(run).or_default() += 1;
            run = 0;
        }
        applied = limited.command;
    }
    println!(
        "{} steps: limiter {acted} ({:.2} %), unsolved {unsolved}, reasons {reasons:?}, \
         chains {chains:?}, braked by the MPC {}",
        n,
        100.0 * acted as f64 / n as f64,
        mpc.braked_steps()
    );
    Ok(())
}
