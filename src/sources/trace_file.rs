//! A trace file as a sample source: checked row by row on a first pass, then streamed on the
//! profile's grid, two rows in memory (`formats::trace::GridSamples`). Rewinding reopens the
//! file; seeking (the console going back to a checkpoint) jumps to the nearest mark kept
//! every [`MARK_EVERY`] samples on the way and reads forward from there. Memory grows with
//! the flight by one small mark per [`MARK_EVERY`] samples only (about 25 KB an hour at
//! 100 Hz).

use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use crate::formats::trace::{
    open_grid, scan_trace_file_copying, GridMark, GridSamples, TraceError, TracePlan,
};
use hexcue_core::source::{SampleSource, SourceError};
use hexcue_core::trace::AircraftSample;

/// Samples between two marks: at most this many are read again to seek.
pub const MARK_EVERY: usize = 2048;

pub struct TraceFile {
    path: PathBuf,
    plan: TracePlan,
    grid: GridSamples<BufReader<File>>,
    /// The stream's position at samples 0, MARK_EVERY, 2·MARK_EVERY, ... as far as it has
    /// been read.
    marks: Vec<GridMark>,
}

impl TraceFile {
    /// Checks the whole file (every refusal names its line and column, as for a trace read
    /// into memory) and opens it at its first sample. The commands open with
    /// [`TraceFile::open_copying`]; the tests, without a copy.
    #[cfg(test)]
    pub fn open(path: &Path, rate_hz: f64) -> Result<Self, TraceError> {
        Self::open_copying(path, rate_hz, None)
    }

    /// [`TraceFile::open`], handing the file's bytes to `copy` as the checks read them (a
    /// recording's hash and compressed attachment, in the same read).
    pub fn open_copying(
        path: &Path,
        rate_hz: f64,
        copy: Option<&mut dyn std::io::Write>,
    ) -> Result<Self, TraceError> {
        let plan = scan_trace_file_copying(path, rate_hz, copy)?;
        let grid = open_grid(path, &plan)?;
        let marks = vec![grid.mark()];
        Ok(TraceFile {
            path: path.to_path_buf(),
            plan,
            grid,
            marks,
        })
    }

    /// What the first pass found: name, length, notices, sidecar.
    pub fn plan(&self) -> &TracePlan {
        &self.plan
    }
}

impl SampleSource for TraceFile {
    fn name(&self) -> &str {
        &self.plan.name
    }
    fn known_len(&self) -> Option<usize> {
        Some(self.plan.len)
    }
    fn next_sample(&mut self) -> Result<Option<AircraftSample>, SourceError> {
        let k = self.grid.position();
        if k.is_multiple_of(MARK_EVERY) && k / MARK_EVERY == self.marks.len() {
            self.marks.push(self.grid.mark());
        }
        self.grid
            .next_sample()
            .map_err(|e| SourceError(e.to_string()))
    }
    fn rewind(&mut self) -> Result<(), SourceError> {
        self.grid = open_grid(&self.path, &self.plan).map_err(|e| SourceError(e.to_string()))?;
        Ok(())
    }
    fn seek(&mut self, k: usize) -> Result<(), SourceError> {
        if k > self.plan.len {
            return Err(SourceError(format!(
                "{}: cannot seek to sample {k} of {}",
                self.plan.source_name, self.plan.len
            )));
        }
        let here = self.grid.position();
        let mark = self.marks[(k / MARK_EVERY).min(self.marks.len() - 1)].clone();
        // Forward from here when here is nearer than the mark: no jump.
        if !(mark.position() <= here && here <= k) {
            self.grid
                .restore(&mark)
                .map_err(|e| SourceError(e.to_string()))?;
        }
        while self.grid.position() < k {
            if self.next_sample()?.is_none() {
                break;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formats::trace::load_trace;

    fn shipped() -> Vec<PathBuf> {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("recordings/traces");
        let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "csv"))
            .collect();
        v.sort();
        v
    }

    fn streamed(src: &mut TraceFile) -> Vec<AircraftSample> {
        let mut out = Vec::new();
        while let Some(s) = src.next_sample().unwrap() {
            out.push(s);
        }
        out
    }

    #[test]
    fn streaming_gives_the_loaded_trace_bit_for_bit_and_rewinds() {
        for path in shipped() {
            // 100 Hz (on the grid) and 60 Hz (interpolated).
            for rate in [100.0, 60.0] {
                let loaded = load_trace(&path, rate).unwrap().trace;
                let mut src = TraceFile::open(&path, rate).unwrap();
                assert_eq!(src.known_len(), Some(loaded.len()));
                assert_eq!(src.plan().notices, loaded.notices, "{}", path.display());
                assert_eq!(src.plan().info, loaded.info);
                let first = streamed(&mut src);
                assert_eq!(first, loaded.samples, "{} at {rate} Hz", path.display());
                src.rewind().unwrap();
                assert_eq!(streamed(&mut src).len(), first.len());
            }
        }
    }

    #[test]
    fn seeking_gives_the_samples_from_there_in_both_directions() {
        let dir = tempfile::tempdir().unwrap();
        // On the grid (rows taken as they are) and off it (interpolated, two rows held).
        for (name, step) in [("grid.csv", 0.01), ("off.csv", 0.013)] {
            let path = dir.path().join(name);
            let mut text = String::from("t,fx,fy,fz,p,q,r\n");
            for k in 0..(3 * MARK_EVERY + 100) {
                let t = k as f64 * step;
                text.push_str(&format!(
                    "{t},{},0,-9.81,{},0,0\n",
                    (t * 0.7).sin(),
                    0.1 * t.cos()
                ));
            }
            std::fs::write(&path, text).unwrap();
            let loaded = load_trace(&path, 100.0).unwrap().trace;
            let mut src = TraceFile::open(&path, 100.0).unwrap();
            let all = streamed(&mut src);
            assert_eq!(all, loaded.samples, "{name}");
            let n = all.len();
            for k in [
                n - 1,
                5,
                MARK_EVERY,
                MARK_EVERY + 7,
                0,
                2 * MARK_EVERY - 1,
                n - 10,
                3,
            ] {
                src.seek(k).unwrap();
                let got: Vec<_> = (0..10).filter_map(|_| src.next_sample().unwrap()).collect();
                assert_eq!(got[..], all[k..(k + 10).min(n)], "{name} at {k}");
            }
            src.seek(n).unwrap();
            assert_eq!(src.next_sample().unwrap(), None);
            assert!(src.seek(n + 1).is_err());
        }
    }

    #[test]
    fn a_bad_row_is_refused_before_the_run_with_its_line() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.csv");
        let mut text = String::from("t,fx,fy,fz,p,q,r\n");
        for k in 0..1000 {
            let fx = if k == 700 {
                "x".to_string()
            } else {
                "0.1".to_string()
            };
            text.push_str(&format!("{},{fx},0,-9.81,0,0,0\n", k as f64 / 100.0));
        }
        std::fs::write(&path, text).unwrap();
        let e = TraceFile::open(&path, 100.0).err().unwrap();
        assert_eq!(e.line(), Some(702));
        assert_eq!(e.column_name(), Some("fx"));
    }

    /// The engine over a streamed file goes back to a snapshot, also after the end of the
    /// file, and steps exactly as the first time (the CWF: no solver warm start to differ).
    #[test]
    fn an_engine_over_a_streamed_file_restores_a_snapshot() {
        use hexcue_core::engine::Engine;
        use hexcue_core::mca::AlgorithmId;
        let profile = hexcue_core::profile::text::default_profile();
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("recordings/traces/landing.csv");
        let file = TraceFile::open(&path, profile.rate_hz).unwrap();
        let mut engine =
            Engine::with_source(&profile, Box::new(file), &[AlgorithmId::Cwf]).unwrap();
        let run = |engine: &mut Engine| -> Vec<_> {
            (0..60)
                .map(|_| {
                    let f = engine.step().unwrap();
                    (f.k, f.aircraft, f.lanes[0].command)
                })
                .collect()
        };
        for _ in 0..1450 {
            engine.step().unwrap();
        }
        let snap = engine.snapshot().unwrap();
        let first = run(&mut engine);
        assert!(engine.restore(&snap));
        assert_eq!(run(&mut engine), first);
        while engine.step().is_some() {}
        assert!(engine.restore(&snap));
        assert_eq!(run(&mut engine), first);
    }
}
