//! The live stepping thread allocates nothing after warm-up (issue 37): a live session runs
//! in this process against a replayed JSBSim stream, under a global allocator that counts
//! the allocations of the stepping thread only (a thread-local flag, set from the session's
//! `control`, which is asked on that thread before every step), from 12 s into the session
//! (the fade-in, the first sample's events and the 10 s unit checks are over) for 3 s.
//!
//! Each counted allocation's backtrace is kept, so that a failure says where it came from.
//! Nothing at all: the input, the safety stage, the core's `Engine::step` with the driving
//! algorithm, the outputs, the statistics and the hand-off to the other threads.

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::backtrace::Backtrace;
use std::cell::Cell;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use common::*;
use hexcue::live::{run, Control, LiveSession};
use hexcue::sinks::moog::fake::{FakeBase, FakeBaseConfig};
use hexcue::sources::live::LiveInput;
use hexcue_core::mca::AlgorithmId;

struct Counting;

thread_local! {
    /// Set on the stepping thread while its allocations count.
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    /// Inside the counter itself (its backtrace allocates): not counted again.
    static INSIDE: Cell<bool> = const { Cell::new(false) };
}

static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);
/// The counted allocations' backtraces (the first [`KEEP`]).
static WHERE: Mutex<Vec<Backtrace>> = Mutex::new(Vec::new());
const KEEP: usize = 2000;

fn count() {
    let counting = COUNTING.try_with(Cell::get).unwrap_or(false);
    if !counting || INSIDE.try_with(Cell::get).unwrap_or(true) {
        return;
    }
    ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
    INSIDE.with(|i| i.set(true));
    if let Ok(mut w) = WHERE.lock() {
        if w.len() < KEEP {
            w.push(Backtrace::force_capture());
        }
    }
    INSIDE.with(|i| i.set(false));
}

// SAFETY: every call is passed to the system allocator unchanged; counting touches only
// thread-locals, an atomic and, when counting, a mutex whose own allocations are not counted.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        System.alloc(layout)
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count();
        System.alloc_zeroed(layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        System.realloc(ptr, layout, new_size)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Steps before counting (12 s at 100 Hz) and steps counted (3 s).
const WARM_UP_STEPS: u64 = 1200;
const COUNTED_STEPS: u64 = 300;

/// The sessions run one at a time: the counter is the process's.
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

/// Where the output goes.
enum Output {
    Json,
    Moog,
}

/// A live session of `algorithms` driven by `drive` against the steep turn replayed in
/// JSBSim's format; returns the backtraces of the stepping thread's allocations after
/// warm-up, and how many steps were counted.
fn stepping_allocations(
    algorithms: &[AlgorithmId],
    drive: AlgorithmId,
    output: Output,
) -> (Vec<String>, u64) {
    stepping_allocations_switching(algorithms, drive, output, None)
}

/// [`stepping_allocations`], with the drive switched to `switch` (its `drive` code) 1 s
/// before the counted part: its lane comes over then (its event is made before counting),
/// the two lanes blend through the first 2 s counted, and the old lane goes back to the
/// comparison lanes' thread within them (asserted). A lane's hand-over makes no event
/// after the request's and the arrival's.
fn stepping_allocations_switching(
    algorithms: &[AlgorithmId],
    drive: AlgorithmId,
    output: Output,
    switch: Option<(AlgorithmId, f64)>,
) -> (Vec<String>, u64) {
    stepping_allocations_with(algorithms, drive, output, switch, false)
}

/// A `[ground]` table that tunes the gain, the CWF and the MPCs otherwise on the ground.
const GROUND: &str = "motion_gain = 0.5\ncwf.specific_force_scale = [0.3, 0.3, 0.8]\n\
                      mpc.specific_force_weight = [0.8, 0.8, 0.1]";

/// The simulator's weight on wheels at step k of the replay: on the ground until 0.8 s into
/// the counted part, in the air for 1 s, back on the ground (during the blend from the
/// first change: the second spare of each phase is used).
fn weight_on_wheels(k: usize) -> bool {
    let counted = k as i64 - WARM_UP_STEPS as i64;
    !(80..180).contains(&counted)
}

/// [`stepping_allocations_switching`]; with `ground`, the profile has [`GROUND`] and the
/// simulator sends weight on wheels, changing twice in the counted part (asserted from the
/// summary).
fn stepping_allocations_with(
    algorithms: &[AlgorithmId],
    drive: AlgorithmId,
    output: Output,
    switch: Option<(AlgorithmId, f64)>,
    ground: bool,
) -> (Vec<String>, u64) {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let mut profile = hexcue_core::testing::full_flight();
    if ground {
        profile.ground = Some(toml::from_str(GROUND).unwrap());
    }
    let in_port = free_udp_port();
    let input = LiveInput::open(&format!("jsbsim://127.0.0.1:{in_port}")).unwrap();
    let mut session = LiveSession::new(&profile, algorithms, drive, input).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let (listener, base) = match output {
        Output::Json => {
            let (port, listener) = json_listener(stop.clone());
            let url = format!("udp://127.0.0.1:{port}");
            let out = hexcue::sinks::open_output(&url, &profile, session.period()).unwrap();
            session.add_output(out);
            (Some(listener), None)
        }
        Output::Moog => {
            let base = FakeBase::start(FakeBaseConfig::default()).unwrap();
            let url = format!("moog://{}", base.addr());
            let out = hexcue::sinks::open_output(&url, &profile, session.period()).unwrap();
            session.add_output(out);
            (None, Some(base))
        }
    };
    // 18 s of the steep turn, from 20 s in: longer than the session's counted part.
    let rows = trace_rows("steep-turn.csv")[2000..3800].to_vec();
    let sender = if ground {
        replay_jsbsim_with_wow(in_port, rows)
    } else {
        replay_jsbsim(in_port, rows)
    };
    ALLOCATIONS.store(0, Ordering::Relaxed);
    WHERE.lock().unwrap().clear();
    let mut counted = 0;
    let mut running_at_warm_up = None;
    // Whether the stepping thread stepped both lanes mid-blend, and only the new one at the
    // end.
    let (mut blending, mut released) = (false, false);
    run(
        &mut session,
        |s| {
            let k = s.stats().commands_out;
            if let Some((to, code)) = switch {
                if k == WARM_UP_STEPS - 100 {
                    s.tuning().lock().unwrap().set("drive", code).unwrap();
                }
                if k == WARM_UP_STEPS + 50 {
                    blending = s.steps_lane(drive) && s.steps_lane(to);
                }
                if k == WARM_UP_STEPS + COUNTED_STEPS - 1 {
                    released = !s.steps_lane(drive) && s.steps_lane(to);
                }
            }
            if k == WARM_UP_STEPS {
                running_at_warm_up = Some(s.safety().state());
                COUNTING.with(|c| c.set(true));
            }
            if k >= WARM_UP_STEPS + COUNTED_STEPS {
                COUNTING.with(|c| c.set(false));
                counted = COUNTED_STEPS;
                return Control::Stop;
            }
            Control::Continue
        },
        |_| {},
    )
    .unwrap();
    COUNTING.with(|c| c.set(false));
    let (summary, _) = session.finish().unwrap();
    stop.store(true, Ordering::Relaxed);
    sender.join().unwrap();
    if let Some(listener) = listener {
        let commands = listener.join().unwrap();
        assert!(commands.len() as u64 > WARM_UP_STEPS + COUNTED_STEPS);
    }
    if let Some(base) = base {
        assert!(base.finish().len() as u64 > WARM_UP_STEPS + COUNTED_STEPS);
    }
    // Counted while the platform followed the simulator, not parked or fading in.
    assert_eq!(
        running_at_warm_up,
        Some(hexcue_core::safety::SafetyState::Running),
        "{:?}",
        summary.live
    );
    if switch.is_some() {
        assert!(
            blending && released,
            "blending {blending}, released {released}"
        );
        let tuning = summary.tuning.as_ref().unwrap();
        assert_eq!(tuning.changes.len(), 1, "{tuning:?}");
    }
    let live = summary.live.unwrap();
    assert_eq!(live.frames_dropped, 0, "{live:?}");
    if ground {
        // Onto the ground at the first sample, then the two changes counted.
        let counted_s =
            WARM_UP_STEPS as f64 / 100.0..(WARM_UP_STEPS + COUNTED_STEPS) as f64 / 100.0;
        let phases: Vec<(bool, bool)> = live
            .ground_changes
            .iter()
            .map(|c| (c.on_ground, counted_s.contains(&c.t_s)))
            .collect();
        assert_eq!(
            phases,
            [(true, false), (false, true), (true, true)],
            "{:?}",
            live.ground_changes
        );
    }
    assert!(live.first_input_s.is_some_and(|t| t < 1.0), "{live:?}");
    // Every lane stepped, on one thread or the other.
    assert_eq!(summary.algorithms.len(), algorithms.len());
    assert!(live.deadline_share.len() == algorithms.len(), "{live:?}");
    let traces = WHERE
        .lock()
        .unwrap()
        .iter()
        .map(|b| b.to_string())
        .collect();
    assert_eq!(
        (ALLOCATIONS.load(Ordering::Relaxed) as usize).min(KEEP),
        WHERE.lock().unwrap().len()
    );
    (traces, counted)
}

/// [`replay_jsbsim`] with the directive's `gear/wow` column, [`weight_on_wheels`] of each row.
fn replay_jsbsim_with_wow(port: u16, rows: Vec<Vec<f64>>) -> std::thread::JoinHandle<usize> {
    std::thread::spawn(move || {
        let sender = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let to = format!("127.0.0.1:{port}");
        sender
            .send_to(b"<LABELS> ,Time,a-pilot-x-ft sec2,a-pilot-y-ft sec2,a-pilot-z-ft sec2,p-rad sec,q-rad sec,r-rad sec,phi-rad,theta-rad,psi-rad,wow\n", &to)
            .unwrap();
        let start = std::time::Instant::now();
        for (k, row) in rows.iter().enumerate() {
            let due = start + std::time::Duration::from_secs_f64(k as f64 * 0.01);
            std::thread::sleep(due.saturating_duration_since(std::time::Instant::now()));
            let line = format!(
                "{},{}\n",
                jsbsim_line(row[0], row).trim_end(),
                u8::from(weight_on_wheels(k))
            );
            // Gone once the session has stopped.
            let _ = sender.send_to(line.as_bytes(), &to);
        }
        rows.len()
    })
}

fn assert_none(traces: &[String], counted: u64, what: &str) {
    assert_eq!(counted, COUNTED_STEPS);
    assert!(
        traces.is_empty(),
        "{} allocations on the stepping thread {what}; the first:\n{}",
        traces.len(),
        traces.first().map_or("", |s| s.as_str())
    );
}

/// The MPCs run beside the CWF as comparison lanes, on their own thread: whatever they
/// allocate, the stepping thread does not.
#[test]
fn the_comparison_lanes_allocate_off_the_stepping_thread() {
    let all = [AlgorithmId::Smpc, AlgorithmId::Mpc, AlgorithmId::Cwf];
    let (traces, counted) = stepping_allocations(&all, AlgorithmId::Cwf, Output::Json);
    assert_none(&traces, counted, "driving with the CWF beside the MPCs");
}

/// The drive switched to a comparison lane (issue 36): the lanes blending on the stepping
/// thread, and the old one's return to the comparison lanes' thread, allocate nothing there.
#[test]
fn a_lane_handed_over_for_a_drive_switch_allocates_nothing_on_the_stepping_thread() {
    let (traces, counted) = stepping_allocations_switching(
        &[AlgorithmId::Mpc, AlgorithmId::Cwf],
        AlgorithmId::Cwf,
        Output::Json,
        Some((AlgorithmId::Mpc, 1.0)),
    );
    assert_none(
        &traces,
        counted,
        "switching the drive from the CWF to the MPC",
    );
}

#[test]
fn the_stepping_thread_allocates_nothing_cwf_json_and_moog() {
    for output in [Output::Json, Output::Moog] {
        let (traces, counted) = stepping_allocations(&[AlgorithmId::Cwf], AlgorithmId::Cwf, output);
        assert_none(&traces, counted, "driving with the CWF");
    }
}

#[test]
fn the_stepping_thread_allocates_nothing_mpc() {
    let (traces, counted) =
        stepping_allocations(&[AlgorithmId::Mpc], AlgorithmId::Mpc, Output::Json);
    assert_none(&traces, counted, "driving with the MPC");
}

#[test]
fn the_stepping_thread_allocates_nothing_smpc() {
    let (traces, counted) =
        stepping_allocations(&[AlgorithmId::Smpc], AlgorithmId::Smpc, Output::Json);
    assert_none(&traces, counted, "driving with the S-MPC");
}

/// A profile's `[ground]` (issue 36): the simulator's weight on wheels changes twice in the
/// counted part, the second time during the first change's blend. Every algorithm of the
/// other phase was built at the start: the stepping thread builds and allocates nothing, the
/// driving lane's nor the hand-over of the phase to the comparison lanes.
#[test]
fn a_change_of_phase_allocates_nothing_on_the_stepping_thread() {
    for drive in [AlgorithmId::Cwf, AlgorithmId::Mpc] {
        let (traces, counted) = stepping_allocations_with(
            &[AlgorithmId::Mpc, AlgorithmId::Cwf],
            drive,
            Output::Json,
            None,
            true,
        );
        assert_none(
            &traces,
            counted,
            &format!("changing phase with the {drive} driving"),
        );
    }
}
