//! One MPC step (one QP) on the full-flight profile, against docs/design.md §9 (median ≤ 200 µs,
//! goal 50 µs). A plain timing loop (`harness = false`) so that the benchmark needs no extra
//! dependency: `cargo bench --bench mpc`. The statuses say which solver solved each QP
//! (`solved`: the active set; `solved_clarabel`: the fallback).
//!
//! The input is a synthetic 20 s manoeuvre (surge pulses, a coordinated turn, heave) so that
//! constraints become active and leave again, as on a real trace. Each algorithm runs closed
//! loop: its command is fed back as the applied state, as the engine does. Then the MPC and
//! the S-MPC as the engine steps them over the shipped horizontal stall (issue 37's bars:
//! median ≤ 50 and ≤ 100 µs).

use std::time::Instant;

use hexcue_core::mca::mpc::{Mpc, Terminal};
use hexcue_core::mca::{CueInput, CueSample, PlatformCommand};
use hexcue_core::profile::text::default_profile;
use hexcue_core::testing::manoeuvre_cue;

/// CPU time this thread has run (ns): the step's own cost, whatever else the shared machine
/// is doing. `None` where the clock is unavailable.
#[cfg(target_os = "linux")]
fn thread_cpu_ns() -> Option<u64> {
    #[repr(C)]
    struct Timespec {
        tv_sec: i64,
        tv_nsec: i64,
    }
    extern "C" {
        fn clock_gettime(clock: i32, tp: *mut Timespec) -> i32;
    }
    const CLOCK_THREAD_CPUTIME_ID: i32 = 3;
    let mut ts = Timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes one timespec through a valid pointer.
    let rc = unsafe { clock_gettime(CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    (rc == 0).then(|| ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64)
}

#[cfg(not(target_os = "linux"))]
fn thread_cpu_ns() -> Option<u64> {
    None
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    let i = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[i]
}

/// `MPC_BENCH=key=value,…` overrides `[mpc]` keys, to compare formulations without editing
/// the profile: e.g. `MPC_BENCH=leg_constraint_stride=2,coarse_steps=3`.
fn profile() -> hexcue_core::profile::Profile {
    let mut profile = default_profile();
    let Ok(spec) = std::env::var("MPC_BENCH") else {
        return profile;
    };
    let m = &mut profile.mpc;
    for kv in spec.split(',').filter(|s| !s.is_empty()) {
        let Some((k, v)) = kv.split_once('=') else {
            continue;
        };
        let f: f64 = v.parse().unwrap_or(f64::NAN);
        match k {
            "fine_step_s" => m.fine_step_s = f,
            "fine_steps" => m.fine_steps = f as usize,
            "coarse_step_s" => m.coarse_step_s = f,
            "coarse_steps" => m.coarse_steps = f as usize,
            "leg_constraint_stride" => m.leg_constraint_stride = f as usize,
            "tolerance" => m.tolerance = f,
            _ => eprintln!("MPC_BENCH: unknown key {k}"),
        }
    }
    if let Err(e) = profile.validate() {
        eprintln!("MPC_BENCH: {e}");
    }
    println!("overrides: {spec}");
    profile
}

fn bench(terminal: Terminal) {
    let profile = profile();
    // COTC runs with its own tuning ([smpc.cotc]: a longer horizon), as in the S-MPC.
    let params = match terminal {
        Terminal::Cotc => profile.cotc_params(),
        Terminal::Free => profile.mpc.clone(),
    };
    let mut mpc = match Mpc::new(&params, &profile.setting(), terminal) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("cannot build the MPC: {e}");
            return;
        }
    };
    let dt = profile.dt_s();
    let steps = 2000;
    let samples: Vec<CueSample> = (0..steps + 300)
        .map(|k| manoeuvre_cue(k as f64 * dt))
        .collect();
    let mut applied = PlatformCommand::default();
    let mut times_us = Vec::with_capacity(steps);
    let mut cpu_us = Vec::with_capacity(steps);
    let mut solved = 0;
    let mut iterations = 0u64;
    let mut qp_us = Vec::with_capacity(steps);
    let mut statuses = std::collections::BTreeMap::new();
    for k in 0..steps {
        let input = CueInput {
            k,
            t_s: k as f64 * dt,
            dt_s: dt,
            sample: samples[k],
            preview: &samples[k + 1..],
            applied: &applied,
            deadline: None,
        };
        let cpu0 = thread_cpu_ns();
        let start = Instant::now();
        let out = mpc.solve(&input);
        times_us.push(start.elapsed().as_secs_f64() * 1e6);
        if let (Some(a), Some(b)) = (cpu0, thread_cpu_ns()) {
            cpu_us.push(b.saturating_sub(a) as f64 * 1e-3);
        }
        solved += usize::from(out.feasible);
        *statuses
            .entry(out.report.status.to_string())
            .or_insert(0usize) += 1;
        iterations += u64::from(out.report.iterations);
        qp_us.push(out.report.solve_time_us);
        applied = out.command;
    }
    times_us.sort_by(f64::total_cmp);
    let (nv, neq, nin) = mpc.qp_size();
    let (nnz_p, nnz_a) = mpc.qp_nonzeros();
    println!("      nonzeros: P {nnz_p}, A {nnz_a}");
    println!(
        "{:>4}: {nv} variables, {neq} equality + {nin} inequality rows; {steps} steps, \
         {solved} solved, {:.1} iterations mean; step time median {:.0} µs, p99 {:.0} µs, \
         max {:.0} µs",
        terminal.name(),
        iterations as f64 / steps as f64,
        percentile(&times_us, 0.5),
        percentile(&times_us, 0.99),
        times_us[times_us.len() - 1],
    );
    println!("      statuses: {statuses:?}");
    qp_us.sort_by(f64::total_cmp);
    println!(
        "      of which the solver's own solve: median {:.0} µs, p99 {:.0} µs",
        percentile(&qp_us, 0.5),
        percentile(&qp_us, 0.99)
    );
    if !cpu_us.is_empty() {
        cpu_us.sort_by(f64::total_cmp);
        println!(
            "      thread CPU time per step: median {:.0} µs, p99 {:.0} µs, max {:.0} µs",
            percentile(&cpu_us, 0.5),
            percentile(&cpu_us, 0.99),
            cpu_us[cpu_us.len() - 1],
        );
    }
}

/// The MPC and the S-MPC as the engine steps them over the shipped horizontal stall, one lane
/// each, on this thread (`set_parallel(false)`, as a live session runs them): the step time
/// the engine measures (wall) and this thread's CPU time per step.
fn bench_stall() {
    let profile = hexcue_core::profile::text::default_profile();
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("recordings/traces/horizontal-stall.csv");
    let stall = match hexcue::formats::trace::load_trace(&path, profile.rate_hz) {
        Ok(t) => std::sync::Arc::new(t.trace),
        Err(e) => {
            eprintln!("cannot read {}: {e}", path.display());
            return;
        }
    };
    for id in [
        hexcue_core::mca::AlgorithmId::Mpc,
        hexcue_core::mca::AlgorithmId::Smpc,
    ] {
        let mut engine = match hexcue_core::engine::Engine::new(&profile, stall.clone(), &[id]) {
            Ok(e) => e,
            Err(e) => {
                eprintln!("cannot build the engine: {e}");
                return;
            }
        };
        engine.set_parallel(false);
        let mut wall_us = Vec::new();
        let mut cpu_us = Vec::new();
        loop {
            let cpu0 = thread_cpu_ns();
            let Some(frame) = engine.step() else { break };
            if let (Some(a), Some(b)) = (cpu0, thread_cpu_ns()) {
                cpu_us.push(b.saturating_sub(a) as f64 * 1e-3);
            }
            wall_us.push(frame.lanes[0].step_time_us);
        }
        wall_us.sort_by(f64::total_cmp);
        cpu_us.sort_by(f64::total_cmp);
        print!(
            "{:>5} on the stall ({} steps): step (engine, wall) median {:.0} µs, p99 {:.0} µs",
            id.key(),
            wall_us.len(),
            percentile(&wall_us, 0.5),
            percentile(&wall_us, 0.99),
        );
        if cpu_us.is_empty() {
            println!();
        } else {
            println!(
                "; whole engine step, thread CPU median {:.0} µs, p99 {:.0} µs",
                percentile(&cpu_us, 0.5),
                percentile(&cpu_us, 0.99)
            );
        }
    }
}

fn main() {
    if let Ok(load) = std::fs::read_to_string("/proc/loadavg") {
        println!("load average: {}", load.trim());
    }
    // `cargo test --benches` runs this with `--bench` absent: keep that quick.
    if !std::env::args().any(|a| a == "--bench") {
        return;
    }
    bench(Terminal::Free);
    bench(Terminal::Cotc);
    bench_stall();
}
