//! The live stepping thread allocates nothing after warm-up (issue 37): a live session runs
//! in this process against a replayed JSBSim stream, under a global allocator that counts
//! the allocations of the stepping thread only (a thread-local flag, set from the session's
//! `control`, which is asked on that thread before every step), from 12 s into the session
//! (the fade-in, the first sample's events and the 10 s unit checks are over) for 3 s.
//!
//! Each counted allocation's backtrace is kept, so that a failure says where it came from.
//! The count and the backtraces are the stepping thread's own (thread-locals), so the
//! sessions run side by side as the test harness schedules them: on CI's two cores that
//! halves this file's time, and a stepping thread that shares the machine with another
//! session's is a harsher test of the deadline paths, not a weaker one.
//! Nothing at all: the input, the safety stage, the core's `Engine::step` with the driving
//! algorithm, the outputs, the statistics and the hand-off to the other threads.

mod common;

use std::backtrace::Backtrace;
use std::cell::{Cell, RefCell};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use common::*;
use hexcue::live::{run, Control, LiveSession};
use hexcue::sinks::moog::fake::{FakeBase, FakeBaseConfig};
use hexcue::sources::live::LiveInput;
use hexcue_core::mca::AlgorithmId;

#[path = "common/counting_alloc.rs"]
mod counting_alloc;
use counting_alloc::{ALLOCATIONS, COUNTING, KEEP, WHERE};

/// Steps before counting (12 s at 100 Hz) and steps counted (3 s).
const WARM_UP_STEPS: u64 = 1200;
const COUNTED_STEPS: u64 = 300;

/// Where the output goes: a JSON stream, and a Moog base beside it.
#[derive(Clone, Copy, PartialEq)]
enum Output {
    Json,
    JsonAndMoog,
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
    let mut profile = hexcue_core::testing::full_flight();
    if ground {
        profile.ground = Some(toml::from_str(GROUND).unwrap());
    }
    let in_port = free_udp_port();
    let input = LiveInput::open(&format!("jsbsim://127.0.0.1:{in_port}")).unwrap();
    let mut session = LiveSession::new(&profile, algorithms, drive, input).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let (port, listener) = json_listener(stop.clone());
    let url = format!("udp://127.0.0.1:{port}");
    session.add_output(hexcue::sinks::open_output(&url, &profile, session.period()).unwrap());
    let base = (output == Output::JsonAndMoog).then(|| {
        let base = FakeBase::start(FakeBaseConfig::default()).unwrap();
        let url = format!("moog://{}", base.addr());
        session.add_output(hexcue::sinks::open_output(&url, &profile, session.period()).unwrap());
        base
    });
    // 18 s of the steep turn, from 20 s in: longer than the session's counted part.
    let rows = trace_rows("steep-turn.csv")[2000..3800].to_vec();
    let sender = if ground {
        replay_jsbsim_with_wow(in_port, rows)
    } else {
        replay_jsbsim(in_port, rows)
    };
    let mut counted = 0;
    // The stepping thread's count and backtraces, taken on that thread when counting ends.
    let mut caught: Option<(u64, Vec<Backtrace>)> = None;
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
            // `control` is asked more than once at the same count (and again after Stop):
            // the count starts once and is taken once.
            if k == WARM_UP_STEPS && running_at_warm_up.is_none() {
                running_at_warm_up = Some(s.safety().state());
                ALLOCATIONS.with(|a| a.set(0));
                WHERE.with(|w| w.borrow_mut().clear());
                COUNTING.with(|c| c.set(true));
            }
            if k >= WARM_UP_STEPS + COUNTED_STEPS {
                COUNTING.with(|c| c.set(false));
                counted = COUNTED_STEPS;
                if caught.is_none() {
                    caught = Some((ALLOCATIONS.with(Cell::get), WHERE.with(RefCell::take)));
                }
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
    let commands = listener.join().unwrap();
    assert!(commands.len() as u64 > WARM_UP_STEPS + COUNTED_STEPS);
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
    let (allocations, kept) = caught.expect("the counted part ended");
    assert_eq!((allocations as usize).min(KEEP), kept.len());
    let traces = kept.iter().map(|b| b.to_string()).collect();
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

/// Every session at once, each on its own threads: the sessions are paced by the replayed
/// stream's clock (15 s each) and use little CPU, so side by side they take the time of one
/// instead of seven. Each scenario's failure is reported with its name.
#[test]
fn no_stepping_thread_allocates_after_warm_up() {
    let scenarios: [(&str, fn()); 7] = [
        ("phase change, CWF driving", || {
            a_change_of_phase_allocates_nothing(AlgorithmId::Cwf)
        }),
        ("phase change, MPC driving", || {
            a_change_of_phase_allocates_nothing(AlgorithmId::Mpc)
        }),
        (
            "comparison lanes",
            the_comparison_lanes_allocate_off_the_stepping_thread,
        ),
        (
            "drive switch",
            a_lane_handed_over_for_a_drive_switch_allocates_nothing,
        ),
        (
            "CWF to JSON and Moog",
            the_stepping_thread_allocates_nothing_cwf_json_and_moog,
        ),
        ("MPC", the_stepping_thread_allocates_nothing_mpc),
        ("S-MPC", the_stepping_thread_allocates_nothing_smpc),
    ];
    let failed: Vec<String> = std::thread::scope(|scope| {
        let running: Vec<_> = scenarios
            .iter()
            .map(|&(name, scenario)| (name, scope.spawn(scenario)))
            .collect();
        running
            .into_iter()
            .filter_map(|(name, handle)| handle.join().err().map(|_| name.to_string()))
            .collect()
    });
    assert!(failed.is_empty(), "failed (their panics above): {failed:?}");
}

/// The MPCs run beside the CWF as comparison lanes, on their own thread: whatever they
/// allocate, the stepping thread does not.
fn the_comparison_lanes_allocate_off_the_stepping_thread() {
    let all = [AlgorithmId::Smpc, AlgorithmId::Mpc, AlgorithmId::Cwf];
    let (traces, counted) = stepping_allocations(&all, AlgorithmId::Cwf, Output::Json);
    assert_none(&traces, counted, "driving with the CWF beside the MPCs");
}

/// The drive switched to a comparison lane (issue 36): the lanes blending on the stepping
/// thread, and the old one's return to the comparison lanes' thread, allocate nothing there.
fn a_lane_handed_over_for_a_drive_switch_allocates_nothing() {
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

fn the_stepping_thread_allocates_nothing_cwf_json_and_moog() {
    let (traces, counted) =
        stepping_allocations(&[AlgorithmId::Cwf], AlgorithmId::Cwf, Output::JsonAndMoog);
    assert_none(
        &traces,
        counted,
        "driving with the CWF to JSON and a Moog base",
    );
}

fn the_stepping_thread_allocates_nothing_mpc() {
    let (traces, counted) =
        stepping_allocations(&[AlgorithmId::Mpc], AlgorithmId::Mpc, Output::Json);
    assert_none(&traces, counted, "driving with the MPC");
}

fn the_stepping_thread_allocates_nothing_smpc() {
    let (traces, counted) =
        stepping_allocations(&[AlgorithmId::Smpc], AlgorithmId::Smpc, Output::Json);
    assert_none(&traces, counted, "driving with the S-MPC");
}

/// A profile's `[ground]` (issue 36): the simulator's weight on wheels changes twice in the
/// counted part, the second time during the first change's blend. Every algorithm of the
/// other phase was built at the start: the stepping thread builds and allocates nothing, the
/// driving lane's nor the hand-over of the phase to the comparison lanes.
fn a_change_of_phase_allocates_nothing(drive: AlgorithmId) {
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
