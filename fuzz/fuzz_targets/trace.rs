//! The trace parser (native and JSBSim CSV, resampling) on arbitrary text: it may refuse,
//! never panic, and what it accepts is finite and on the uniform grid.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    // The first byte picks the target rate, so resampling up and down is exercised too;
    // `load_trace` refuses non-UTF-8 before parsing, so only text goes further.
    let Some((&rate_byte, rest)) = data.split_first() else {
        return;
    };
    let rate_hz = [100.0, 50.0, 200.0, 1000.0][usize::from(rate_byte % 4)];
    let Ok(text) = std::str::from_utf8(rest) else {
        return;
    };
    if let Ok(trace) = hexcue::formats::trace::parse_trace(text, "fuzz.csv", "fuzz", rate_hz) {
        assert!(trace.samples.len() >= 2, "accepted a trace of fewer than two samples");
        assert!(trace.samples.len() <= hexcue_core::trace::MAX_TRACE_SAMPLES);
        for (k, s) in trace.samples.iter().enumerate() {
            assert!(
                s.specific_force_mps2.iter().all(|v| v.is_finite())
                    && s.angular_velocity_radps.iter().all(|v| v.is_finite())
                    && s.attitude_rad.iter().all(|v| v.is_finite()),
                "non-finite sample {k} accepted"
            );
            let expected = k as f64 / rate_hz;
            assert!(
                (s.t_s - expected).abs() <= 1e-6 * expected.max(1.0),
                "sample {k} at t = {} s, expected {expected} s",
                s.t_s
            );
        }
    }
});
