//! Dumps one run step by step as CSV, for looking into a cue: the aircraft's perceived motion
//! and, per algorithm, its perceived motion, pose, limiter and mode.
//! `cargo run --release --example cue_dump -- TRACE.csv [PROFILE.toml] > run.csv`

use std::path::Path;
use std::sync::Arc;

use hexcue::formats::profile::load_profile;
use hexcue::formats::trace::load_trace;
use hexcue_core::engine::Engine;
use hexcue_core::mca::AlgorithmId;
use hexcue_core::profile::text::default_profile;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let trace_path = args
        .first()
        .ok_or("usage: cue_dump TRACE.csv [PROFILE.toml]")?;
    let mut profile = match args.get(1) {
        Some(p) => load_profile(Path::new(p))?.0,
        None => default_profile(),
    };
    profile.mpc.time_limit_ms = f64::INFINITY;
    let trace = Arc::new(load_trace(Path::new(trace_path), profile.rate_hz)?.trace);
    let algs = [AlgorithmId::Smpc, AlgorithmId::Mpc, AlgorithmId::Cwf];
    let mut engine = Engine::new(&profile, trace, &algs)?;
    let ch = ["fx", "fy", "fz", "wx", "wy", "wz"];
    let mut header = vec!["t".to_string()];
    header.extend(ch.iter().map(|c| format!("ref_{c}")));
    for a in ["smpc", "mpc", "cwf"] {
        header.extend(ch.iter().map(|c| format!("{a}_{c}")));
        header.extend(
            ["x", "y", "z", "roll", "pitch", "yaw"]
                .iter()
                .map(|c| format!("{a}_{c}")),
        );
        header.extend(["lim", "mode", "blend"].iter().map(|c| format!("{a}_{c}")));
    }
    println!("{}", header.join(","));
    while let Some(f) = engine.step() {
        let mut row = vec![format!("{:.2}", f.t_s)];
        row.extend((0..6).map(|i| format!("{:.5}", f.reference.channel(i))));
        for a in algs {
            let l = f.lane(a).ok_or("lane")?;
            row.extend((0..6).map(|i| format!("{:.5}", l.perceived.channel(i))));
            row.extend(l.command.pose.iter().map(|v| format!("{v:.5}")));
            row.push(format!("{}", u8::from(l.limiter_active)));
            row.push(format!("{:?}", l.state.mode));
            row.push(format!("{:.3}", l.state.blend.unwrap_or(f64::NAN)));
        }
        println!("{}", row.join(","));
    }
    Ok(())
}
