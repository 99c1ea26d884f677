//! The step allocates nothing once warmed up (issue 37): each algorithm's step and state, and
//! the engine's whole step, over a shipped flight, counted by a global allocator that counts
//! only the calls made on this thread while a measurement is on.
//!
//! The algorithms run on the caller's thread (`set_parallel(false)`, as a live session runs
//! them). What this excludes, and why (docs/performance.md, "A step without allocation"):
//! - the lanes and the S-MPC's two QPs on rayon's pool (offline runs): rayon boxes each
//!   spawned job and its queues grow in blocks, inside the crate;
//! - Clarabel, the fallback of the active set: its solve allocates inside the crate. The
//!   measured stretches assert that no QP reached it (statuses `solved`, `primal_infeasible`
//!   from the active set, `standby`), so that the test cannot pass by not measuring.
//!
//! Set `HEXCUE_ALLOC_TRACE=1` to print a backtrace of each counted allocation.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::Arc;

use hexcue_core::engine::Engine;
use hexcue_core::mca::{AlgorithmId, CueInput, MotionCueing, PlatformCommand, SolveStatus};
use hexcue_core::testing::full_flight;
use hexcue_core::trace::text::parse_trace;
use hexcue_core::trace::Trace;

struct Counting;

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    static COUNT: Cell<u64> = const { Cell::new(0) };
}

fn count_one() {
    let on = COUNTING.try_with(|c| c.get()).unwrap_or(false);
    if !on {
        return;
    }
    let _ = COUNT.try_with(|n| n.set(n.get() + 1));
    // Off while reading the variable and the backtrace, which allocate themselves.
    COUNTING.with(|c| c.set(false));
    if std::env::var_os("HEXCUE_ALLOC_TRACE").is_some() {
        eprintln!("{}", std::backtrace::Backtrace::force_capture());
    }
    COUNTING.with(|c| c.set(true));
}

// SAFETY: every call is handed to the system allocator unchanged; the counting touches only
// const-initialised thread-locals, which allocate nothing.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count_one();
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count_one();
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count_one();
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Allocations made on this thread by `f`.
fn allocations_in<T>(f: impl FnOnce() -> T) -> (u64, T) {
    COUNT.with(|n| n.set(0));
    COUNTING.with(|c| c.set(true));
    let out = f();
    COUNTING.with(|c| c.set(false));
    (COUNT.with(|n| n.get()), out)
}

/// A shipped trace, read by the core's parser at 100 Hz as the application reads it.
fn shipped(name: &str) -> Trace {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../recordings/traces")
        .join(format!("{name}.csv"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    parse_trace(&text, &path.display().to_string(), name, 100.0).unwrap_or_else(|e| panic!("{e}"))
}

/// Statuses that say the QP never reached Clarabel.
fn active_set_only(status: SolveStatus) -> bool {
    matches!(
        status,
        SolveStatus::Solved | SolveStatus::PrimalInfeasible | SolveStatus::Standby
    )
}

/// What a measured stretch went through, so that a test cannot pass by measuring nothing.
#[derive(Debug, Default)]
struct Seen {
    steps: usize,
    switches: u32,
    /// Steps whose QPs added or dropped rows of the active set (constraints active).
    iterating_steps: usize,
    clarabel_steps: usize,
}

/// Steps `algorithm` closed loop over `trace`: `warm` steps, then `measured` steps counted.
fn measure_algorithm(
    algorithm: &mut dyn MotionCueing,
    trace: &Trace,
    warm: usize,
    measured: usize,
) -> (u64, Seen) {
    let profile = full_flight();
    let cues: Vec<_> = trace
        .samples
        .iter()
        .map(|s| hexcue_core::engine::cue_sample(&profile, s))
        .collect();
    let preview_len = 500;
    algorithm.set_parallel(false);
    let mut applied = PlatformCommand::default();
    let mut seen = Seen::default();
    let mut total = 0;
    let switches_before = std::cell::Cell::new(0);
    for k in 0..warm + measured {
        let end = (k + 1 + preview_len).min(cues.len());
        let input = CueInput {
            k,
            t_s: k as f64 * 0.01,
            dt_s: 0.01,
            sample: cues[k],
            preview: &cues[k + 1..end],
            applied: &applied,
            deadline: None,
        };
        let (n, (command, state)) = allocations_in(|| (algorithm.step(&input), algorithm.state()));
        applied = command;
        if k == warm {
            switches_before.set(state.switch_count);
        }
        if k >= warm {
            total += n;
            if n > 0 {
                eprintln!("{:?} step {k}: {n} allocations", algorithm.id());
            }
            seen.steps += 1;
            seen.switches = state.switch_count - switches_before.get();
            seen.iterating_steps += usize::from(state.solvers.iter().any(|s| s.iterations > 0));
            seen.clarabel_steps +=
                usize::from(state.solvers.iter().any(|s| !active_set_only(s.status)));
        }
    }
    (total, seen)
}

#[test]
fn the_washout_step_allocates_nothing() {
    let profile = full_flight();
    let mut cwf = profile.algorithm(AlgorithmId::Cwf).unwrap();
    let (n, seen) = measure_algorithm(cwf.as_mut(), &shipped("horizontal-stall"), 100, 2000);
    assert_eq!(n, 0, "{seen:?}");
    assert_eq!(seen.steps, 2000);
}

#[test]
fn the_mpc_step_allocates_nothing_with_its_constraints_active() {
    let profile = full_flight();
    let mut mpc = profile.algorithm(AlgorithmId::Mpc).unwrap();
    // The stall's pitch-up and drop (from 20 s on) after a warm-up on its first 20 s.
    let (n, seen) = measure_algorithm(mpc.as_mut(), &shipped("horizontal-stall"), 2000, 1500);
    assert!(seen.iterating_steps > 20, "constraints active: {seen:?}");
    assert_eq!(
        seen.clarabel_steps, 0,
        "Clarabel's path is not measured: {seen:?}"
    );
    assert_eq!(n, 0, "{seen:?}");
}

/// Steps of the take-off run before counting with `switching_profile`: to 18.56 s, after the
/// free MPC's first solves (from 18.50 s, they size its buffers) and before the S-MPC leaves
/// COTC (18.64 s), so that the departure, the blend and the return are all measured.
const WARM_BEFORE_THE_SWITCH: usize = 1856;

/// The shipped profile switches on none of the shipped flights; with the whole sustained
/// cue carried by tilt and the reference held over the horizon (as in the S-MPC's own
/// switching tests) both QPs fail on the takeoff's rotation from 18.50 s (the free MPC's
/// first solves): the S-MPC leaves COTC at 18.64 s and, the failure having been shared, goes
/// back at 18.84 s, during the blend, which the mixer turns around (until the supervisor
/// returned after a shared failure without the ε dwell, it stayed away until about 24 s).
fn switching_profile() -> hexcue_core::profile::Profile {
    let mut profile = full_flight();
    profile.mpc.reference = hexcue_core::mca::mpc::params::ReferenceMode::Hold;
    profile.mpc.tilt_share = 1.0;
    profile
}

#[test]
fn the_smpc_step_allocates_nothing_through_its_switches() {
    let profile = switching_profile();
    let mut smpc = profile.algorithm(AlgorithmId::Smpc).unwrap();
    // Warmed up through the free MPC's first solves (they size its buffers), measured
    // through the departure, the blend, the free MPC in charge and the return to COTC.
    let warm = WARM_BEFORE_THE_SWITCH;
    let (n, seen) = measure_algorithm(smpc.as_mut(), &shipped("takeoff"), warm, 4600 - warm);
    assert!(seen.switches > 0, "it switched: {seen:?}");
    assert!(seen.iterating_steps > 10, "constraints active: {seen:?}");
    assert_eq!(
        seen.clarabel_steps, 0,
        "Clarabel's path is not measured: {seen:?}"
    );
    assert_eq!(n, 0, "{seen:?}");
}

#[test]
fn the_engine_step_allocates_nothing_with_every_algorithm() {
    let profile = switching_profile();
    let trace = Arc::new(shipped("takeoff"));
    let mut engine = Engine::new(&profile, trace, AlgorithmId::ALL).unwrap();
    engine.set_parallel(false);
    for _ in 0..WARM_BEFORE_THE_SWITCH {
        engine.step().unwrap();
    }
    let switches_before = engine_switches(&mut engine);
    let mut total = 0;
    let mut switches = 0;
    let mut clarabel = 0;
    for k in WARM_BEFORE_THE_SWITCH + 1..4400 {
        // A live session fades the cue in and out: that path too.
        if k == 4000 {
            engine.set_cue_gain(0.5);
        }
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(3600);
        let (n, frame) = allocations_in(|| {
            if k % 2 == 0 {
                engine.step()
            } else {
                engine.step_until(deadline)
            }
        });
        let frame = frame.unwrap();
        if n > 0 {
            eprintln!("engine step {k}: {n} allocations");
        }
        total += n;
        let smpc = frame.lane(AlgorithmId::Smpc).unwrap();
        switches = smpc.state.switch_count;
        clarabel += frame
            .lanes
            .iter()
            .filter(|l| l.state.solvers.iter().any(|s| !active_set_only(s.status)))
            .count();
    }
    assert!(switches > switches_before, "the S-MPC switched");
    assert_eq!(clarabel, 0, "Clarabel's path is not measured");
    assert_eq!(total, 0);
}

/// The S-MPC's switches so far, after one more step.
fn engine_switches(engine: &mut Engine) -> u32 {
    let frame = engine.step().unwrap();
    frame.lane(AlgorithmId::Smpc).unwrap().state.switch_count
}
