//! The pipeline against docs/design.md §9: the CWF step (≤ 20 µs), the MPC and S-MPC steps as the
//! engine times them, a single-algorithm CWF run (≥ 1,000× real time) and a headless run of
//! every algorithm with recording on a 60 s trace (≥ 25× real time). A plain timing loop (`harness = false`): `cargo bench --bench pipeline`.

use std::sync::Arc;
use std::time::Instant;

use hexcue::formats::recording::{Recorder, RecordingMeta};
use hexcue::formats::trace::load_trace;
use hexcue_core::engine::Engine;
use hexcue_core::mca::{AlgorithmId, CueInput, PlatformCommand};
use hexcue_core::metrics::TimeHistogram;
use hexcue_core::profile::text::default_profile;
use hexcue_core::summary::SummaryBuilder;

fn repo(path: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

fn main() {
    let profile = default_profile();
    let stall = load_trace(
        &repo("recordings/traces/horizontal-stall.csv"),
        profile.rate_hz,
    )
    .expect("shipped trace");
    let landing =
        load_trace(&repo("recordings/traces/landing.csv"), profile.rate_hz).expect("shipped trace");

    // 1. The CWF step alone, over the stall's inputs, 20 passes.
    let mut cwf = profile.algorithm(AlgorithmId::Cwf).expect("cwf builds");
    let inputs: Vec<_> = stall
        .trace
        .samples
        .iter()
        .map(|s| hexcue_core::engine::cue_sample(&profile, s))
        .collect();
    let applied = PlatformCommand::default();
    let mut hist = TimeHistogram::default();
    for _ in 0..20 {
        cwf.reset();
        for (k, sample) in inputs.iter().enumerate() {
            let input = CueInput {
                k,
                t_s: k as f64 * profile.dt_s(),
                dt_s: profile.dt_s(),
                sample: *sample,
                preview: &[],
                applied: &applied,
                deadline: None,
            };
            let t = Instant::now();
            std::hint::black_box(cwf.step(&input));
            hist.push(t.elapsed().as_secs_f64() * 1e6);
        }
    }
    let s = hist.summary();
    println!("cwf step                      median {:7.2} µs  p99 {:7.2} µs  max {:8.1} µs   (target ≤ 20 µs)", s.median, s.p99, s.max);

    // 2. A whole CWF-only run: engine, reference model, perception, kinematics, summary.
    let run = |algorithms: &[AlgorithmId],
               trace: &hexcue::formats::trace::LoadedTrace,
               record: bool|
     -> f64 {
        let tr = Arc::new(trace.trace.clone());
        let started = Instant::now();
        let mut engine = Engine::new(&profile, tr.clone(), algorithms).expect("engine");
        let mut summary = SummaryBuilder::new(&profile, &tr.name);
        let dir = std::env::temp_dir().join(format!("hexcue-bench-{}", std::process::id()));
        let _ = std::fs::create_dir_all(&dir);
        let path = dir.join("bench.mcap");
        let mut recorder = record.then(|| {
            let meta = RecordingMeta {
                profile_name: profile.name.clone(),
                profile_toml: hexcue_core::profile::text::DEFAULT_PROFILE_TOML.to_string(),
                trace_name: tr.name.clone(),
                trace_csv: trace.text.clone(),
                trace_sidecar: None,
                algorithms: algorithms.to_vec(),
                rate_hz: profile.rate_hz,
                profile: Some(profile.clone()),
            };
            Recorder::create(&path, &meta).expect("recorder")
        });
        while let Some(frame) = engine.step() {
            summary.push(&frame);
            if let Some(r) = recorder.as_mut() {
                r.record(&frame).expect("record");
            }
        }
        if let Some(r) = recorder {
            r.finish().expect("finish");
        }
        std::hint::black_box(summary.finish());
        let _ = std::fs::remove_dir_all(&dir);
        tr.duration_s() / started.elapsed().as_secs_f64()
    };
    // 3. Engine-level step times of the MPC and the S-MPC (COTC, the free MPC beside it when it
    // is needed, the supervisor and the mixer), wall clock, over the stall.
    for (id, target) in [
        (AlgorithmId::Mpc, "median ≤ 200 µs, goal 50 µs"),
        (AlgorithmId::Smpc, "median ≤ 300 µs, goal 100 µs"),
    ] {
        let mut engine =
            Engine::new(&profile, Arc::new(stall.trace.clone()), &[id]).expect("engine");
        let mut hist = TimeHistogram::default();
        while let Some(frame) = engine.step() {
            hist.push(frame.lanes[0].step_time_us);
        }
        let s = hist.summary();
        println!(
            "{:<6} step (engine, wall)     median {:7.0} µs  p99 {:7.0} µs  max {:8.0} µs   (target {target})",
            id.key(),
            s.median,
            s.p99,
            s.max
        );
    }

    let best = |f: &dyn Fn() -> f64, n: usize| (0..n).map(|_| f()).fold(0.0, f64::max);
    let x = best(&|| run(&[AlgorithmId::Cwf], &stall, false), 5);
    println!("cwf run, horizontal-stall     {x:8.0}× real time                           (target ≥ 1000×)");
    let x = best(&|| run(&[AlgorithmId::Cwf], &stall, true), 5);
    println!("cwf run with --record         {x:8.0}× real time");
    let x = best(&|| run(AlgorithmId::ALL, &landing, true), 1);
    let names: Vec<&str> = AlgorithmId::ALL.iter().map(|a| a.key()).collect();
    println!(
        "{:<29} {x:8.1}× real time  (60 s landing, --record)   (target ≥ 25×)",
        names.join("+")
    );
}
