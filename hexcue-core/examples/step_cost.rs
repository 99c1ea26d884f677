//! What a step of the MPC, COTC and the S-MPC costs, in this thread's CPU time (so that a
//! loaded machine inflates it little), and a hash of every command: two builds whose hashes
//! agree computed the same commands to the bit. It needs nothing but the core, so it builds
//! in a minute where `cargo bench` builds the whole application: docs/performance.md
//! ("The condensation, cached") compares two commits with it.
//!
//! ```text
//! cargo run --release -p hexcue-core --example step_cost            # all four
//! cargo run --release -p hexcue-core --example step_cost -- stall 3 # the stall, 3 runs
//! ```
//!
//! The loops are `benches/mpc.rs`'s: the synthetic manoeuvre closed loop on `Mpc::solve`,
//! then the engine with one lane on the shipped horizontal stall. The profile is the
//! shipped one, offline (no wall-clock limit), so that the commands do not depend on the
//! machine's load.

use std::sync::Arc;

use hexcue_core::engine::Engine;
use hexcue_core::mca::mpc::{Mpc, Terminal};
use hexcue_core::mca::{AlgorithmId, CueInput, CueSample, PlatformCommand};
use hexcue_core::profile::text::default_profile;
use hexcue_core::testing::manoeuvre_cue;
use hexcue_core::trace::{AircraftSample, Trace};
use nalgebra::Vector3;

/// This thread's CPU time (µs); 0 where the clock is not available.
#[cfg(target_os = "linux")]
fn thread_cpu_us() -> f64 {
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
    if rc == 0 {
        ts.tv_sec as f64 * 1e6 + ts.tv_nsec as f64 * 1e-3
    } else {
        0.0
    }
}

#[cfg(not(target_os = "linux"))]
fn thread_cpu_us() -> f64 {
    0.0
}

/// FNV-style hash of the commands' bits.
struct Hash(u64);

impl Hash {
    fn command(&mut self, c: &PlatformCommand) {
        for v in c.pose.iter().chain(&c.velocity).chain(&c.acceleration) {
            self.0 = (self.0 ^ v.to_bits())
                .wrapping_mul(0x100_0000_01b3)
                .rotate_left(7);
        }
    }
}

fn report(what: &str, mut cpu_us: Vec<f64>, hash: &Hash) {
    cpu_us.sort_by(f64::total_cmp);
    let at = |p: f64| cpu_us[((cpu_us.len() - 1) as f64 * p).round() as usize];
    let mean = cpu_us.iter().sum::<f64>() / cpu_us.len() as f64;
    println!(
        "{what:>16}: thread CPU per step median {:.1} µs, p90 {:.1}, mean {mean:.1}; \
         commands hash {:016x}",
        at(0.5),
        at(0.9),
        hash.0
    );
}

fn synthetic(terminal: Terminal, runs: usize) {
    let profile = default_profile().offline();
    let params = match terminal {
        Terminal::Cotc => profile.cotc_params(),
        Terminal::Free => profile.mpc.clone(),
    };
    let dt = profile.dt_s();
    let steps = 2000;
    let samples: Vec<CueSample> = (0..steps + 300)
        .map(|k| manoeuvre_cue(k as f64 * dt))
        .collect();
    let (mut cpu, mut hash) = (Vec::new(), Hash(0));
    for _ in 0..runs {
        let mut mpc = Mpc::new(&params, &profile.setting(), terminal).expect("the MPC builds");
        let mut applied = PlatformCommand::default();
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
            let t0 = thread_cpu_us();
            let out = mpc.solve(&input);
            cpu.push(thread_cpu_us() - t0);
            hash.command(&out.command);
            applied = out.command;
        }
    }
    report(&format!("{} synthetic", terminal.name()), cpu, &hash);
}

/// The shipped horizontal stall (hexcue's CSV at the profile's 100 Hz, which needs no
/// resampling), read here because the core reads no files.
fn stall() -> Arc<Trace> {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../recordings/traces/horizontal-stall.csv"
    );
    let text = std::fs::read_to_string(path).expect("the shipped stall trace");
    let rate_hz = 100.0;
    let samples = text
        .lines()
        .skip(1)
        .enumerate()
        .map(|(k, line)| {
            let v: Vec<f64> = line
                .split(',')
                .map(|s| s.trim().parse().expect("a number"))
                .collect();
            AircraftSample {
                t_s: k as f64 / rate_hz,
                specific_force_mps2: Vector3::new(v[1], v[2], v[3]),
                angular_velocity_radps: Vector3::new(v[4], v[5], v[6]),
                attitude_rad: Vector3::new(v[7], v[8], v[9]),
            }
        })
        .collect();
    Arc::new(Trace {
        name: "horizontal-stall".into(),
        rate_hz,
        samples,
        info: None,
        notices: Vec::new(),
    })
}

fn on_the_stall(id: AlgorithmId, runs: usize) {
    let profile = default_profile().offline();
    let trace = stall();
    let (mut cpu, mut hash) = (Vec::new(), Hash(0));
    for _ in 0..runs {
        let mut engine = Engine::new(&profile, trace.clone(), &[id]).expect("the engine builds");
        engine.set_parallel(false);
        loop {
            let t0 = thread_cpu_us();
            let Some(frame) = engine.step() else { break };
            cpu.push(thread_cpu_us() - t0);
            hash.command(&frame.lanes[0].command);
        }
    }
    report(&format!("{} stall", id.key()), cpu, &hash);
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let runs = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1);
    let which = args.get(1).map_or("all", String::as_str);
    if matches!(which, "all" | "synthetic") {
        synthetic(Terminal::Free, runs);
        synthetic(Terminal::Cotc, runs);
    }
    if matches!(which, "all" | "stall") {
        on_the_stall(AlgorithmId::Mpc, runs);
        on_the_stall(AlgorithmId::Smpc, runs);
    }
}
