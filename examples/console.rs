//! The live console on a synthetic trace, with a stand-in recorder that writes one line of text
//! per frame, until the CLI wires in the trace parser and the MCAP recorder.
//!
//!     cargo run --release --example console [-- --record FILE] [--paused]

use std::io::Write;
use std::sync::Arc;

use hexcue::tui::{self, FrameSink, LiveConfig, RecordingRequest};
use hexcue_core::engine::Frame;
use hexcue_core::mca::AlgorithmId;
use hexcue_core::profile::text::default_profile;
use hexcue_core::trace::{AircraftSample, Trace};
use nalgebra::Vector3;

/// Writes `t fx_ref fx_perceived...` per frame: enough to see what was recorded and when.
struct TextSink {
    out: std::io::BufWriter<std::fs::File>,
    path: String,
    frames: u64,
}

impl FrameSink for TextSink {
    fn record(&mut self, frame: &Frame) -> anyhow::Result<()> {
        write!(
            self.out,
            "{:.2} {:.4}",
            frame.t_s, frame.reference.specific_force_mps2.x
        )?;
        for lane in &frame.lanes {
            write!(self.out, " {:.4}", lane.perceived.specific_force_mps2.x)?;
        }
        writeln!(self.out)?;
        self.frames += 1;
        Ok(())
    }
    fn finish(mut self: Box<Self>) -> anyhow::Result<String> {
        self.out.flush()?;
        Ok(format!("recorded {} frames to {}", self.frames, self.path))
    }
}

fn synthetic_trace() -> Trace {
    let samples = (0..6000)
        .map(|k| {
            let t = k as f64 * 0.01;
            let s = (t * 0.4).sin();
            AircraftSample {
                t_s: t,
                specific_force_mps2: Vector3::new(
                    2.0 * s * (t * 0.13).cos(),
                    1.5 * (t * 0.25).sin(),
                    -hexcue_core::G_MPS2 - 1.0 * (t * 0.9).sin() * s,
                ),
                angular_velocity_radps: Vector3::new(
                    0.1 * (t * 0.7).sin(),
                    0.05 * (t * 0.5).cos(),
                    0.03 * s,
                ),
                attitude_rad: Vector3::zeros(),
            }
        })
        .collect();
    Trace {
        name: "synthetic".into(),
        rate_hz: 100.0,
        samples,
        info: None,
        notices: vec![],
    }
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let mut cfg = LiveConfig::new(
        default_profile(),
        Arc::new(synthetic_trace()),
        AlgorithmId::ALL.to_vec(),
    );
    cfg.record = args
        .iter()
        .position(|a| a == "--record")
        .and_then(|i| args.get(i + 1))
        .map(Into::into);
    cfg.start_paused = args.iter().any(|a| a == "--paused");
    let outcome = tui::run_live(
        cfg,
        Box::new(|req: &RecordingRequest| {
            let file = std::fs::File::create(&req.path)?;
            Ok(Box::new(TextSink {
                out: std::io::BufWriter::new(file),
                path: req.path.display().to_string(),
                frames: 0,
            }) as Box<dyn FrameSink>)
        }),
    )?;
    if let Some(sig) = outcome.signal {
        eprintln!("ended by {sig}");
    }
    Ok(())
}
