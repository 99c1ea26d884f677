//! Handing a frame to the recorder's thread allocates nothing on the stepping thread after
//! warm-up (issue 37), also when the channel is full and the stepping thread waits for the
//! recorder: `play --headless --record` and the console hand every step's frame to a
//! [`RecorderThread`], which encodes and compresses it on a thread of its own.
//!
//! A global allocator counts this thread's allocations (a thread-local flag) while it calls
//! `RecorderThread::record`, not the recorder's own on its worker. The frames are stepped
//! first and then handed over as fast as the calls go, so that the recorder, which encodes
//! and compresses each one, falls behind and the channel fills: the test goes on until the
//! stepping thread has waited on a full channel many times, before and while counting.

use std::cell::Cell;
use std::sync::Arc;

use hexcue::formats::recording::{Recorder, RecorderThread, RecordingMeta, CAPACITY_FRAMES};
use hexcue_core::engine::{Engine, Frame};
use hexcue_core::mca::AlgorithmId;
use hexcue_core::testing::{full_flight, manoeuvre};

#[path = "common/counting_alloc.rs"]
mod counting_alloc;
use counting_alloc::{ALLOCATIONS, COUNTING, WHERE};

/// Waits on a full channel before counting, and while counting.
const WARM_UP_WAITS: u64 = 5;
const COUNTED_WAITS: u64 = 50;
/// The most frames handed over in either part: the recorder would have to keep up with
/// bare copies of frames for this long for the test to fail for want of waits.
const MOST_FRAMES: usize = 200 * CAPACITY_FRAMES;

#[test]
fn handing_frames_to_the_recorders_thread_allocates_nothing_even_when_it_waits() {
    let profile = full_flight();
    let algorithms = [AlgorithmId::Smpc, AlgorithmId::Mpc, AlgorithmId::Cwf];
    let mut engine = Engine::new(&profile, Arc::new(manoeuvre()), &algorithms).unwrap();
    let frames: Vec<Frame> = std::iter::from_fn(|| engine.step()).collect();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("handoff.mcap");
    let meta = RecordingMeta::session(
        &profile,
        hexcue_core::profile::text::DEFAULT_PROFILE_TOML,
        "manoeuvre",
        "",
        None,
        &algorithms,
    );
    let mut rec = RecorderThread::spawn(Recorder::create(&path, &meta).unwrap()).unwrap();
    // Trace time goes on across the passes over the frames, as a long run's does.
    let duration_s = frames.last().unwrap().t_s + 0.01;
    let mut pass = 0;
    let mut feed = |rec: &mut RecorderThread, until_waits: u64, counted: bool| -> usize {
        let mut handed = 0;
        let mut frame = frames[0].clone();
        while rec.waits() < until_waits {
            assert!(
                handed < MOST_FRAMES,
                "{handed} frames handed over and the recorder never fell behind"
            );
            frame.clone_from(&frames[handed % frames.len()]);
            if handed % frames.len() == 0 {
                pass += 1;
            }
            frame.t_s += (pass - 1) as f64 * duration_s;
            COUNTING.with(|c| c.set(counted));
            let fed = rec.record(&frame);
            COUNTING.with(|c| c.set(false));
            fed.unwrap();
            handed += 1;
        }
        handed
    };
    feed(&mut rec, WARM_UP_WAITS, false);
    let counted = feed(&mut rec, WARM_UP_WAITS + COUNTED_WAITS, true);
    let stats = rec.finish().unwrap();
    assert!(stats.steps as usize > counted);
    let allocations = ALLOCATIONS.with(Cell::get);
    let traces: Vec<String> = WHERE.with(|w| w.borrow().iter().map(|b| b.to_string()).collect());
    assert_eq!(
        allocations,
        0,
        "{allocations} allocations in {counted} hand-overs; the first at:\n{}",
        traces.first().map_or("", |t| t.as_str())
    );
}
