//! `hexcue.read_trace`: a trace file read as `hexcue play --trace` reads it. The parsing, the
//! checks and their messages are the core's (`hexcue_core::trace::text`); this file opens the
//! file (twice: the core's first pass checks every row, the second puts the samples on the
//! grid), reads the sidecar beside it and hands the columns to NumPy.

use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use hexcue_core::profile::text::default_profile;
use hexcue_core::trace::text::{
    attach_sidecar, read_trace as read_core_trace, TraceError as CoreTraceError,
};
use hexcue_core::trace::Trace;
use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::{PyFileNotFoundError, PyOSError, PyValueError};
use pyo3::prelude::*;

use crate::PyProfile;

pyo3::create_exception!(
    hexcue,
    TraceError,
    PyValueError,
    "A trace file that hexcue refuses; the message is the command line's: the file, the line \
     and column, the column's name, what was found and what was expected."
);

/// A flight trace on the profile's grid, as `hexcue play --trace` reads it: `hexcue.run` takes
/// it whole, and its columns are NumPy arrays.
#[pyclass(name = "Trace", module = "hexcue", frozen)]
pub(crate) struct PyTrace {
    pub(crate) inner: Arc<Trace>,
}

/// One (n, 3) array of a vector of every sample.
fn columns<'py>(
    py: Python<'py>,
    trace: &Trace,
    of: impl Fn(&hexcue_core::trace::AircraftSample) -> [f64; 3],
) -> PyResult<Bound<'py, PyAny>> {
    let data: Vec<f64> = trace.samples.iter().flat_map(of).collect();
    Ok(PyArray1::from_vec(py, data)
        .reshape([trace.len(), 3])?
        .into_any())
}

#[pymethods]
impl PyTrace {
    /// The trace's name: the file's stem, as summaries and recordings name the flight.
    #[getter]
    fn name(&self) -> &str {
        &self.inner.name
    }

    /// The grid's rate (Hz): the profile's it was read for.
    #[getter]
    fn rate_hz(&self) -> f64 {
        self.inner.rate_hz
    }

    /// Each sample's time (s), k / rate_hz from 0, shape (n,).
    #[getter]
    fn t_s<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_vec(py, self.inner.samples.iter().map(|s| s.t_s).collect())
    }

    /// Specific force f = a − g at the pilot's head (m/s², head frame), shape (n, 3).
    #[getter]
    fn specific_force_mps2<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        columns(py, &self.inner, |s| s.specific_force_mps2.into())
    }

    /// Body rates p, q, r (rad/s), shape (n, 3).
    #[getter]
    fn angular_velocity_radps<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        columns(py, &self.inner, |s| s.angular_velocity_radps.into())
    }

    /// Attitude φ, θ, ψ (rad; zero when the file has none), shape (n, 3).
    #[getter]
    fn attitude_rad<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        columns(py, &self.inner, |s| s.attitude_rad.into())
    }

    /// What was done to the file on the way in (JSBSim's units converted, resampling, time
    /// shifted, a broken sidecar ignored), as the command line prints it.
    #[getter]
    fn notices(&self) -> Vec<String> {
        self.inner.notices.clone()
    }

    /// The sidecar (`name.json` beside the file) as a dict of its keys (`name`, `aircraft`,
    /// `scenario`, `source`, `sample_rate_hz`, `duration_s`, `events`), or None.
    #[getter]
    fn info<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        Ok(pythonize::pythonize(py, &self.inner.info)?)
    }

    fn __len__(&self) -> usize {
        self.inner.len()
    }

    fn __repr__(&self) -> String {
        format!(
            "hexcue.Trace({:?}, {} samples at {} Hz)",
            self.inner.name,
            self.inner.len(),
            self.inner.rate_hz
        )
    }
}

/// The core's refusal as a Python exception: a file that cannot be read is an `OSError`
/// (`FileNotFoundError` when missing), anything else `hexcue.TraceError`; the message is
/// the command line's either way.
fn trace_error(e: CoreTraceError) -> PyErr {
    match &e {
        CoreTraceError::Io { error, .. } if error.kind() == std::io::ErrorKind::NotFound => {
            PyFileNotFoundError::new_err(e.to_string())
        }
        CoreTraceError::Io { .. } => PyOSError::new_err(e.to_string()),
        _ => TraceError::new_err(e.to_string()),
    }
}

/// Reads a trace file and its sidecar on the grid of `rate_hz`, as the application's
/// `load_trace` does, streaming the file from disk rather than holding its text.
fn read_file(path: &Path, rate_hz: f64) -> Result<Trace, CoreTraceError> {
    let source_name = path.display().to_string();
    let name = path
        .file_stem()
        .map_or_else(|| "trace".to_string(), |s| s.to_string_lossy().into_owned());
    let open = || {
        File::open(path)
            .map(|f| BufReader::with_capacity(64 * 1024, f))
            .map_err(|error| CoreTraceError::Io {
                source_name: source_name.clone(),
                error,
            })
    };
    let (mut trace, measured_rate_hz) = read_core_trace(&open, &source_name, &name, rate_hz)?;
    let sidecar = path.with_extension("json");
    if sidecar != path {
        let sidecar_name = sidecar.display().to_string();
        match std::fs::read_to_string(&sidecar) {
            Ok(json) => attach_sidecar(&mut trace, &json, &sidecar_name, measured_rate_hz),
            Err(error) if error.kind() == std::io::ErrorKind::NotFound => {}
            Err(error) => {
                let e = CoreTraceError::Io {
                    source_name: sidecar_name,
                    error,
                };
                trace.notices.push(format!("sidecar ignored: {e}"));
            }
        }
    }
    Ok(trace)
}

/// A trace file (hexcue's CSV or JSBSim's, docs/formats.md) and its sidecar, read as
/// `hexcue play --trace FILE` reads them: converted to SI, checked, and put on the grid of the
/// profile's rate (the default profile's, 100 Hz, without one). Returns a `hexcue.Trace`, which
/// `hexcue.run(trace, profile=...)` takes whole. A file hexcue refuses raises
/// `hexcue.TraceError` (a `ValueError`) with the command line's message, naming the file,
/// the line and the column; one that cannot be read, an `OSError`.
#[pyfunction]
#[pyo3(signature = (path, profile = None))]
pub(crate) fn read_trace(
    py: Python<'_>,
    path: PathBuf,
    profile: Option<PyRef<'_, PyProfile>>,
) -> PyResult<PyTrace> {
    let rate_hz = profile.map_or_else(|| default_profile().rate_hz, |p| p.inner.rate_hz);
    let trace = py
        .detach(|| read_file(&path, rate_hz))
        .map_err(trace_error)?;
    Ok(PyTrace {
        inner: Arc::new(trace),
    })
}
