//! Flight traces from files (docs/formats.md): the core parses the text
//! (`hexcue_core::trace::text`: hexcue's CSV, JSBSim's, sidecars, every check and message);
//! this module opens the files, limits what is read into memory, reads the sidecar beside a
//! trace, hands a recording the bytes it attaches in the same read as the checks, and keeps
//! the shipped traces embedded in the binary.

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom, Write};
use std::path::Path;

use hexcue_core::trace::Trace;

pub use hexcue_core::trace::text::*;
pub use hexcue_core::trace::units::{UnitJudgement, UnitNames, UnitStats};

mod embedded;

pub use embedded::*;

/// Largest trace file read into memory by default (`compare`, `tune`, `bound`, `play
/// --bound`), in MB (10^6 bytes): 256 MB is about 7.5 h at 100 Hz. `play` streams its trace
/// and has no such limit. Each of those commands takes [`MAX_TRACE_OPTION`] to set another.
pub const DEFAULT_MAX_TRACE_MB: f64 = 256.0;
/// The command-line option that sets another limit than [`DEFAULT_MAX_TRACE_MB`].
pub const MAX_TRACE_OPTION: &str = "--max-trace-mb";

/// The largest trace file read into memory (bytes): `max_trace_mb` MB, or
/// [`DEFAULT_MAX_TRACE_MB`] when `None`.
pub fn max_trace_bytes(max_trace_mb: Option<f64>) -> u64 {
    (max_trace_mb.unwrap_or(DEFAULT_MAX_TRACE_MB) * 1e6).round() as u64
}
/// Largest sidecar read.
const MAX_SIDECAR_BYTES: u64 = 1024 * 1024;

/// A trace with the text it was read from (recordings attach it).
#[derive(Clone, Debug, PartialEq)]
pub struct LoadedTrace {
    pub trace: Trace,
    /// The raw CSV.
    pub text: String,
}

fn open_file(path: &Path, source_name: &str) -> Result<BufReader<File>, TraceError> {
    File::open(path)
        .map(|f| BufReader::with_capacity(64 * 1024, f))
        .map_err(|error| TraceError::Io {
            source_name: source_name.to_string(),
            error,
        })
}

/// Reads at most `limit` bytes of a file as UTF-8 text.
fn read_text(
    path: &Path,
    source_name: &str,
    limit: u64,
    beyond: &str,
) -> Result<String, TraceError> {
    let io = |error| TraceError::Io {
        source_name: source_name.to_string(),
        error,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let mut bytes = Vec::new();
    file.take(limit + 1).read_to_end(&mut bytes).map_err(io)?;
    if bytes.len() as u64 > limit {
        return Err(TraceError::File {
            source_name: source_name.to_string(),
            kind: TraceErrorKind::TooLarge,
            message: format!("larger than {limit} bytes{beyond}"),
        });
    }
    String::from_utf8(bytes).map_err(|e| {
        let valid = e.utf8_error().valid_up_to();
        let bytes = e.as_bytes();
        let line = bytes[..valid].iter().filter(|&&b| b == b'\n').count() + 1;
        let line_start = bytes[..valid]
            .iter()
            .rposition(|&b| b == b'\n')
            .map_or(0, |p| p + 1);
        let column = String::from_utf8_lossy(&bytes[line_start..valid])
            .chars()
            .count()
            + 1;
        TraceError::At {
            source_name: source_name.to_string(),
            line,
            column,
            column_name: None,
            kind: TraceErrorKind::NotUtf8,
            message: "not UTF-8 text; expected a CSV file".to_string(),
        }
    })
}

/// Reads a trace and, if there is one, its sidecar `stem.json` beside it, within the
/// default size ([`DEFAULT_MAX_TRACE_MB`]). A broken sidecar is a notice, not an error: the
/// data are what matter.
pub fn load_trace(path: &Path, target_rate_hz: f64) -> Result<LoadedTrace, TraceError> {
    load_trace_within(path, target_rate_hz, None)
}

/// [`load_trace`] with the size limit the user gave ([`MAX_TRACE_OPTION`], in MB).
pub fn load_trace_within(
    path: &Path,
    target_rate_hz: f64,
    max_trace_mb: Option<f64>,
) -> Result<LoadedTrace, TraceError> {
    let source_name = path.display().to_string();
    let limit = max_trace_bytes(max_trace_mb);
    let beyond = format!(
        ", the most read into memory (`compare`, `tune` and `bound` hold their traces; `play` \
         streams a trace of any size); give {MAX_TRACE_OPTION} a larger number of MB \
         (10^6 bytes) to allow it"
    );
    let text = read_text(path, &source_name, limit, &beyond)?;
    let name = path
        .file_stem()
        .map_or_else(|| "trace".to_string(), |s| s.to_string_lossy().into_owned());
    let (mut trace, measured_rate_hz) = parse_measured(&text, &source_name, &name, target_rate_hz)?;
    read_sidecar(path, &mut trace, measured_rate_hz);
    Ok(LoadedTrace { trace, text })
}

/// Checks a trace file row by row without holding it, and reads its sidecar: the plan to
/// stream it with [`open_grid`]. Memory does not grow with the file's length.
pub fn scan_trace_file(path: &Path, target_rate_hz: f64) -> Result<TracePlan, TraceError> {
    scan_trace_file_copying(path, target_rate_hz, None)
}

/// [`scan_trace_file`], handing every byte of the file, as this pass reads it, to `copy`: a
/// recording's hash and compressed attachment made in the same read as the checks
/// (`formats::recording::TraceCopy`). On success `copy` has had the whole file.
pub fn scan_trace_file_copying(
    path: &Path,
    target_rate_hz: f64,
    copy: Option<&mut dyn Write>,
) -> Result<TracePlan, TraceError> {
    let source_name = path.display().to_string();
    let name = path
        .file_stem()
        .map_or_else(|| "trace".to_string(), |s| s.to_string_lossy().into_owned());
    let io = |error| TraceError::Io {
        source_name: source_name.clone(),
        error,
    };
    let copied = std::cell::Cell::new(0u64);
    // Only the first opening (the scan) copies; a second is for a refusal's line numbers.
    let copy = std::cell::RefCell::new(copy);
    // No cap on the file's size or length: nothing here grows with it (docs/design.md §9).
    // A file that is not a trace is refused by its first lines.
    let open = || {
        let file = File::open(path).map_err(io)?;
        Ok(BufReader::with_capacity(
            64 * 1024,
            Copying {
                file,
                copy: copy.borrow_mut().take(),
                copied: &copied,
            },
        ))
    };
    let mut plan = scan(&open, &source_name, &name, target_rate_hz, usize::MAX)?;
    if let Some(copy) = copy.into_inner() {
        // The scan reads to the end of the file; had it stopped short, the copy completes it.
        let mut rest = File::open(path).map_err(io)?;
        rest.seek(SeekFrom::Start(copied.get())).map_err(io)?;
        std::io::copy(&mut rest, copy).map_err(io)?;
    }
    let mut trace = Trace {
        name: name.clone(),
        rate_hz: target_rate_hz,
        samples: Vec::new(),
        info: None,
        notices: std::mem::take(&mut plan.notices),
    };
    read_sidecar(path, &mut trace, plan.measured_rate_hz);
    plan.notices = trace.notices;
    plan.info = trace.info;
    Ok(plan)
}

/// Streams the samples of a scanned trace file from its start.
pub fn open_grid(
    path: &Path,
    plan: &TracePlan,
) -> Result<GridSamples<BufReader<File>>, TraceError> {
    GridSamples::new(open_file(path, &plan.source_name)?, plan)
}

/// A file read that hands what it reads to `copy` (when there is one) and counts it.
struct Copying<'c, 'w> {
    file: File,
    copy: Option<&'w mut dyn Write>,
    copied: &'c std::cell::Cell<u64>,
}

impl Read for Copying<'_, '_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.file.read(buf)?;
        if let Some(copy) = self.copy.as_deref_mut() {
            copy.write_all(&buf[..n])?;
            self.copied.set(self.copied.get() + n as u64);
        }
        Ok(n)
    }
}

/// Attaches the sidecar `stem.json` beside `path`, if there is one. A broken sidecar is a
/// notice, not an error: the data are what matter.
fn read_sidecar(path: &Path, trace: &mut Trace, measured_rate_hz: f64) {
    let sidecar = path.with_extension("json");
    if sidecar != path {
        let sidecar_name = sidecar.display().to_string();
        match read_text(
            &sidecar,
            &sidecar_name,
            MAX_SIDECAR_BYTES,
            "; expected a JSON sidecar",
        ) {
            Err(TraceError::Io { error, .. }) if error.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => trace.notices.push(format!("sidecar ignored: {e}")),
            Ok(json) => attach_sidecar(trace, &json, &sidecar_name, measured_rate_hz),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use hexcue_core::testing::native_trace_text as native;

    fn shipped(name: &str) -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("recordings/traces")
            .join(format!("{name}.csv"))
    }

    #[test]
    fn the_shipped_traces_load_with_their_sidecars() {
        for (name, rows) in [
            ("horizontal-stall", 5500),
            ("landing", 6000),
            ("steep-turn", 7500),
            ("takeoff", 5000),
            ("turbulence-cruise", 9000),
        ] {
            let loaded = load_trace(&shipped(name), 100.0).unwrap();
            let t = &loaded.trace;
            assert_eq!(t.name, name);
            assert_eq!(t.len(), rows, "{name}");
            assert!(t.notices.is_empty(), "{name}: {:?}", t.notices);
            assert_eq!(t.samples[rows - 1].t_s, (rows - 1) as f64 / 100.0);
            let info = t.info.as_ref().unwrap();
            assert_eq!(info.name.as_deref(), Some(name));
            assert!(!info.events.is_empty(), "{name}");
            // Near 1 g at the start and on average; rates and attitude of a light aircraft.
            let f0 = t.samples[0].specific_force_mps2;
            assert!(f0.z < -6.0 && f0.z > -14.0, "{name}: {f0}");
            assert!(f0.x.abs() < 2.0 && f0.y.abs() < 2.0, "{name}: {f0}");
            let mean_fz = t
                .samples
                .iter()
                .map(|s| s.specific_force_mps2.z)
                .sum::<f64>()
                / rows as f64;
            // The steep turn holds 2 g for most of its length.
            assert!(mean_fz < -9.0 && mean_fz > -20.0, "{name}: {mean_fz}");
            for s in &t.samples {
                assert!(s.angular_velocity_radps.amax() < 3.0, "{name}: {s:?}");
                assert!(
                    s.attitude_rad.x.abs() < 1.6 && s.attitude_rad.y.abs() < 1.0,
                    "{name}: {s:?}"
                );
            }
            assert!(loaded.text.starts_with(NATIVE_HEADER));
        }
        let stall = load_trace(&shipped("horizontal-stall"), 100.0)
            .unwrap()
            .trace;
        assert!((stall.samples[0].specific_force_mps2.z + 9.795856).abs() < 1e-12);
    }

    #[test]
    fn the_embedded_shipped_traces_are_the_files() {
        let embedded = shipped_traces(100.0).unwrap();
        assert_eq!(embedded.len(), 5);
        for t in &embedded {
            let file = load_trace(&shipped(&t.name), 100.0).unwrap().trace;
            assert_eq!(t.samples, file.samples, "{}", t.name);
            assert_eq!(t.info, file.info, "{}", t.name);
        }
    }

    #[test]
    fn the_default_trace_is_the_shipped_horizontal_stall() {
        let d = default_trace(100.0);
        assert_eq!(d.trace.name, "horizontal-stall");
        assert_eq!(d.trace.len(), 5500);
        assert!(d.trace.notices.is_empty(), "{:?}", d.trace.notices);
        assert_eq!(
            d.trace.info.as_ref().unwrap().aircraft.as_deref(),
            Some("c172p")
        );
        let from_file = load_trace(&shipped("horizontal-stall"), 100.0).unwrap();
        assert_eq!(d.trace.samples, from_file.trace.samples);
        assert_eq!(d.text, from_file.text);
        // Another rate resamples; an impossible one keeps 100 Hz and says so.
        let d50 = default_trace(50.0);
        assert_eq!(d50.trace.len(), 2750);
        assert_eq!(
            d50.trace.samples[10].specific_force_mps2,
            d.trace.samples[20].specific_force_mps2
        );
        let bad = default_trace(f64::NAN);
        assert_eq!(bad.trace.rate_hz, 100.0);
        assert!(bad
            .trace
            .notices
            .iter()
            .any(|n| n.contains("kept its own 100 Hz")));
    }

    #[test]
    fn load_trace_names_the_file_and_treats_a_broken_sidecar_as_a_notice() {
        let dir = tempfile::tempdir().unwrap();
        let csv = dir.path().join("my-flight.csv");
        std::fs::write(&csv, native(4)).unwrap();
        let t = load_trace(&csv, 100.0).unwrap().trace;
        assert_eq!(t.name, "my-flight");
        assert!(t.info.is_none());
        assert!(
            t.notices.iter().all(|n| n.contains("could not be checked")),
            "{:?}",
            t.notices
        );

        std::fs::write(dir.path().join("my-flight.json"), "{ \"name\": ").unwrap();
        let t = load_trace(&csv, 100.0).unwrap().trace;
        assert!(t.info.is_none());
        assert!(
            t.notices
                .iter()
                .any(|n| n.starts_with("sidecar ignored: ") && n.contains("my-flight.json:1:")),
            "{:?}",
            t.notices
        );

        std::fs::write(
            dir.path().join("my-flight.json"),
            "{\"aircraft\": \"a320\", \"sample_rate_hz\": 50}",
        )
        .unwrap();
        let t = load_trace(&csv, 100.0).unwrap().trace;
        assert_eq!(t.info.unwrap().aircraft.as_deref(), Some("a320"));
        assert!(
            t.notices.iter().any(|n| n.contains("sidecar says 50 Hz")),
            "{:?}",
            t.notices
        );

        let missing = dir.path().join("nope.csv");
        let e = load_trace(&missing, 100.0).unwrap_err();
        assert!(matches!(e, TraceError::Io { .. }), "{e}");
        assert!(e.to_string().contains("nope.csv"), "{e}");

        let bin = dir.path().join("bin.csv");
        std::fs::write(&bin, b"t,fx\n0,\xff\xfe\n").unwrap();
        let e = load_trace(&bin, 100.0).unwrap_err();
        assert_eq!(e.kind(), Some(TraceErrorKind::NotUtf8));
        assert!(e.to_string().contains("bin.csv:2:3:"), "{e}");
    }
}
