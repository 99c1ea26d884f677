//! hexcue from Python (docs/python.md): profiles, the three motion cueing algorithms stepped one
//! sample at a time, a whole trace run through the core's engine into the summary that
//! `hexcue play --headless --summary` writes, and the vestibular model.
//!
//! Everything numerical is `hexcue_core`'s: the stepping object is the core's [`Engine`] with
//! one lane, fed by the caller instead of a trace; `run` is the engine over an in-memory trace
//! with the core's [`SummaryBuilder`]. This file only converts between NumPy arrays and the
//! core's types, and turns the core's errors into Python exceptions.

use std::path::PathBuf;
use std::sync::{Arc, Mutex, MutexGuard};

use hexcue_core::engine::{Engine, Frame, LaneFrame};
use hexcue_core::mca::AlgorithmId;
use hexcue_core::model::vestibular::{Perceived, Vestibular};
use hexcue_core::profile::text::{default_profile, parse_profile};
use hexcue_core::profile::Profile as CoreProfile;
use hexcue_core::source::{SampleSource, SourceError};
use hexcue_core::summary::{Summary, SummaryBuilder};
use hexcue_core::trace::{resample_uniform, AircraftSample, Trace};
use nalgebra::Vector3;
use numpy::ndarray::ArrayView2;
use numpy::{AllowTypeChange, PyArray1, PyArrayLike1, PyArrayLike2, PyArrayMethods};
use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

mod trace;

use trace::PyTrace;

pyo3::create_exception!(
    hexcue,
    ProfileError,
    PyValueError,
    "A profile that could not be parsed or validated; the message names the source, the line \
     and column, and the key."
);

/// The trace name summaries give when the caller names none.
const DEFAULT_RUN_NAME: &str = "python";

fn value_error(message: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(message.to_string())
}

/// The algorithm a key names (`smpc`, `mpc`, `cwf`), or an error listing the keys.
fn algorithm_id(key: &str) -> PyResult<AlgorithmId> {
    AlgorithmId::from_key(key).ok_or_else(|| {
        let keys: Vec<&str> = AlgorithmId::ALL.iter().map(|a| a.key()).collect();
        value_error(format!(
            "unknown algorithm `{key}`: expected one of {}",
            keys.join(", ")
        ))
    })
}

/// A stepping object's lock. A panic inside the core while stepping is a bug; the object is
/// then left as the panic found it, and the next call still gets it rather than a second panic.
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// A simulator profile: the platform, its limits, the step and every algorithm's tuning
/// (docs/profiles.md).
#[pyclass(name = "Profile", module = "hexcue", frozen)]
#[derive(Clone)]
struct PyProfile {
    inner: CoreProfile,
}

#[pymethods]
impl PyProfile {
    /// The shipped default profile, `profiles/full-flight.toml` (the one `hexcue play` uses
    /// without `--profile`).
    #[staticmethod]
    fn default() -> Self {
        PyProfile {
            inner: default_profile(),
        }
    }

    /// A profile from its TOML text; `name` names it in error messages (a file name, say).
    /// Raises `hexcue.ProfileError` with hexcue's message: the name, line, column and key.
    #[staticmethod]
    #[pyo3(signature = (text, name = "<python>"))]
    fn from_toml(text: &str, name: &str) -> PyResult<Self> {
        parse_profile(text, name)
            .map(|inner| PyProfile { inner })
            .map_err(|e| ProfileError::new_err(e.to_string()))
    }

    /// A profile read from a TOML file, as `hexcue --profile FILE` reads it.
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Self> {
        let text = std::fs::read_to_string(&path).map_err(|e| {
            PyOSError::new_err(format!("{}: cannot read the profile: {e}", path.display()))
        })?;
        Self::from_toml(&text, &path.display().to_string())
    }

    /// The profile's own name (its `name` key).
    #[getter]
    fn name(&self) -> &str {
        &self.inner.name
    }

    /// The rate every algorithm runs at (Hz).
    #[getter]
    fn rate_hz(&self) -> f64 {
        self.inner.rate_hz
    }

    /// The step (s).
    #[getter]
    fn dt_s(&self) -> f64 {
        self.inner.dt_s()
    }

    /// What the application warns about when it loads this profile (a valid profile whose
    /// platform reaches little, say).
    fn warnings(&self) -> Vec<String> {
        self.inner
            .warnings()
            .iter()
            .map(|w| w.to_string())
            .collect()
    }

    /// The algorithm `key` (`"smpc"`, `"mpc"` or `"cwf"`) as this profile tunes it, ready to
    /// be stepped (`hexcue.Algorithm`).
    fn algorithm(&self, key: &str) -> PyResult<PyAlgorithm> {
        PyAlgorithm::new(&self.inner, algorithm_id(key)?)
    }

    fn __repr__(&self) -> String {
        format!(
            "hexcue.Profile(name={:?}, rate_hz={})",
            self.inner.name, self.inner.rate_hz
        )
    }
}

/// The sample the Python caller gives next. Like a live simulator it has no future (the engine
/// reads no sample ahead, so the MPCs predict with the profile's causal `reference`), but unlike
/// a live stream it can go back to its start, so that `Engine::reset` starts the run over.
struct Fed {
    next: Arc<Mutex<AircraftSample>>,
    k: usize,
    rate_hz: f64,
}

impl SampleSource for Fed {
    fn name(&self) -> &str {
        DEFAULT_RUN_NAME
    }
    fn known_len(&self) -> Option<usize> {
        None
    }
    fn next_sample(&mut self) -> Result<Option<AircraftSample>, SourceError> {
        let sample = *lock(&self.next);
        // The time of a trace's grid (`trace::resample_uniform`), so that a step sees what the
        // same sample of a trace would.
        let t_s = self.k as f64 / self.rate_hz;
        self.k += 1;
        Ok(Some(AircraftSample { t_s, ..sample }))
    }
    fn rewind(&mut self) -> Result<(), SourceError> {
        self.k = 0;
        Ok(())
    }
    fn can_read_ahead(&self) -> bool {
        false
    }
    fn can_seek(&self) -> bool {
        false
    }
}

/// What a stepping object holds between calls.
struct Stepping {
    engine: Engine,
    next: Arc<Mutex<AircraftSample>>,
    summary: SummaryBuilder,
}

/// One algorithm (with the workspace limiter that ends it, and the pilot's perception of its
/// command), stepped one aircraft sample at a time: the core's engine with one lane, fed from
/// Python. Built by `Profile.algorithm(key)`.
#[pyclass(name = "Algorithm", module = "hexcue", frozen)]
struct PyAlgorithm {
    id: AlgorithmId,
    profile: CoreProfile,
    stepping: Mutex<Stepping>,
}

impl PyAlgorithm {
    fn new(profile: &CoreProfile, id: AlgorithmId) -> PyResult<Self> {
        let rest = AircraftSample {
            specific_force_mps2: Vector3::new(0.0, 0.0, -hexcue_core::G_MPS2),
            ..AircraftSample::default()
        };
        let next = Arc::new(Mutex::new(rest));
        let source = Fed {
            next: next.clone(),
            k: 0,
            rate_hz: profile.rate_hz,
        };
        let engine = Engine::with_source(profile, Box::new(source), &[id]).map_err(value_error)?;
        Ok(PyAlgorithm {
            id,
            profile: profile.clone(),
            stepping: Mutex::new(Stepping {
                engine,
                next,
                summary: SummaryBuilder::new(profile, DEFAULT_RUN_NAME),
            }),
        })
    }

    fn finished(&self) -> Summary {
        lock(&self.stepping).summary.finish()
    }
}

#[pymethods]
impl PyAlgorithm {
    /// `"smpc"`, `"mpc"` or `"cwf"`.
    #[getter]
    fn key(&self) -> &'static str {
        self.id.key()
    }

    /// Steps taken since the start (or the last `reset()`).
    #[getter]
    fn steps(&self) -> usize {
        lock(&self.stepping).engine.position()
    }

    /// One step: the aircraft's specific force f = a − g (m/s², head frame x forward, y right,
    /// z down; (0, 0, −9.80665) in level unaccelerated flight) and angular velocity p, q, r
    /// (rad/s) at the pilot's head. Returns a dict: the platform command after the limiter
    /// (`pose`, `velocity`, `acceleration`: x, y, z in m, roll, pitch, yaw in rad, and their
    /// derivatives), what the pilot perceives of it and of the aircraft, the legs, whether the
    /// limiter acted, and the controller's state (mode, switch count and reason, solvers).
    fn step<'py>(
        &self,
        py: Python<'py>,
        specific_force_mps2: [f64; 3],
        angular_velocity_radps: [f64; 3],
    ) -> PyResult<Bound<'py, PyDict>> {
        for (name, v) in [
            ("specific_force_mps2", specific_force_mps2),
            ("angular_velocity_radps", angular_velocity_radps),
        ] {
            if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                return Err(value_error(format!(
                    "{name}[{i}] is {}: expected a finite number",
                    v[i]
                )));
            }
        }
        let frame = py.detach(|| {
            let mut s = lock(&self.stepping);
            *lock(&s.next) = AircraftSample {
                t_s: 0.0,
                specific_force_mps2: Vector3::from(specific_force_mps2),
                angular_velocity_radps: Vector3::from(angular_velocity_radps),
                attitude_rad: Vector3::zeros(),
            };
            let frame = s.engine.step();
            if let Some(frame) = &frame {
                s.summary.push(frame);
            }
            frame
        });
        let frame = frame.ok_or_else(|| {
            PyRuntimeError::new_err("the engine gave no step for a sample it was given")
        })?;
        step_dict(py, &frame)
    }

    /// Back to rest at neutral, as at the start of a trace; the summary starts over too.
    fn reset(&self) {
        let mut s = lock(&self.stepping);
        s.engine.reset();
        s.summary = SummaryBuilder::new(&self.profile, DEFAULT_RUN_NAME);
    }

    /// The summary of the steps since the start (or the last `reset()`), as a dict of the
    /// shape of `hexcue play --summary`'s JSON; its `algorithms` holds this one only.
    fn summary<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        Ok(pythonize::pythonize(py, &self.finished())?)
    }

    /// The cueing score of the steps so far (lower is better; docs/score.md), as the summary
    /// gives it.
    fn score(&self) -> PyResult<f64> {
        self.finished()
            .algorithm(self.id)
            .map(|a| a.score)
            .ok_or_else(|| value_error("no step yet: the score needs at least one"))
    }

    fn __repr__(&self) -> String {
        format!(
            "hexcue.Algorithm({:?}, profile={:?}, steps={})",
            self.id.key(),
            self.profile.name,
            self.steps()
        )
    }
}

fn vec3<'py>(py: Python<'py>, v: &Vector3<f64>) -> Bound<'py, PyArray1<f64>> {
    PyArray1::from_slice(py, v.as_slice())
}

fn vec6<'py>(py: Python<'py>, v: &nalgebra::Vector6<f64>) -> Bound<'py, PyArray1<f64>> {
    PyArray1::from_slice(py, v.as_slice())
}

/// One step of one lane, for `Algorithm.step`.
fn step_dict<'py>(py: Python<'py>, frame: &Frame) -> PyResult<Bound<'py, PyDict>> {
    let lane: &LaneFrame = frame
        .lanes
        .first()
        .ok_or_else(|| PyRuntimeError::new_err("the engine stepped no algorithm"))?;
    let d = PyDict::new(py);
    d.set_item("t_s", frame.t_s)?;
    d.set_item("pose", vec6(py, &lane.command.pose))?;
    d.set_item("velocity", vec6(py, &lane.command.velocity))?;
    d.set_item("acceleration", vec6(py, &lane.command.acceleration))?;
    d.set_item(
        "perceived_specific_force_mps2",
        vec3(py, &lane.perceived.specific_force_mps2),
    )?;
    d.set_item(
        "perceived_angular_velocity_radps",
        vec3(py, &lane.perceived.angular_velocity_radps),
    )?;
    d.set_item(
        "reference_specific_force_mps2",
        vec3(py, &frame.reference.specific_force_mps2),
    )?;
    d.set_item(
        "reference_angular_velocity_radps",
        vec3(py, &frame.reference.angular_velocity_radps),
    )?;
    d.set_item("leg_length_m", vec6(py, &lane.legs.length_m))?;
    d.set_item("leg_margin_m", vec6(py, &lane.legs.margin_m))?;
    d.set_item("limiter_active", lane.limiter_active)?;
    d.set_item("step_time_us", lane.step_time_us)?;
    // Through its serde derive: the same words as a recording's controller topic, whatever
    // types the core gives the switch reason and the solver's name.
    d.set_item("state", pythonize::pythonize(py, &lane.state)?)?;
    Ok(d)
}

/// Checks an (n, 3) array of finite numbers; `name` names it in the error.
fn check_signal(name: &str, a: &ArrayView2<f64>) -> PyResult<()> {
    if a.ncols() != 3 {
        return Err(value_error(format!(
            "{name} has shape ({}, {}): expected (n, 3), one row per sample",
            a.nrows(),
            a.ncols()
        )));
    }
    if let Some(((row, col), v)) = a.indexed_iter().find(|(_, v)| !v.is_finite()) {
        return Err(value_error(format!(
            "{name}[{row}, {col}] is {v}: expected a finite number"
        )));
    }
    Ok(())
}

/// The aircraft samples of two (n, 3) signals, on the profile's grid or, with `t_s`, at those
/// times (then resampled to the profile's rate as the application resamples a trace file).
fn samples(
    f: &ArrayView2<f64>,
    w: &ArrayView2<f64>,
    t_s: Option<&[f64]>,
    rate_hz: f64,
) -> PyResult<Vec<AircraftSample>> {
    check_signal("specific_force_mps2", f)?;
    check_signal("angular_velocity_radps", w)?;
    if f.nrows() != w.nrows() {
        return Err(value_error(format!(
            "specific_force_mps2 has {} rows and angular_velocity_radps {}: expected one row \
             per sample in both",
            f.nrows(),
            w.nrows()
        )));
    }
    if f.nrows() == 0 {
        return Err(value_error("no samples: expected at least one row"));
    }
    if let Some(t) = t_s {
        if t.len() != f.nrows() {
            return Err(value_error(format!(
                "t_s has {} values for {} samples",
                t.len(),
                f.nrows()
            )));
        }
    }
    let out: Vec<AircraftSample> = f
        .rows()
        .into_iter()
        .zip(w.rows())
        .enumerate()
        .map(|(k, (f, w))| AircraftSample {
            t_s: t_s.map_or(k as f64 / rate_hz, |t| t[k]),
            specific_force_mps2: Vector3::new(f[0], f[1], f[2]),
            angular_velocity_radps: Vector3::new(w[0], w[1], w[2]),
            attitude_rad: Vector3::zeros(),
        })
        .collect();
    match t_s {
        None => Ok(out),
        Some(_) => resample_uniform(&out, rate_hz)
            .map(|r| r.samples)
            .map_err(|e| value_error(format!("t_s: {e}"))),
    }
}

/// Row-major (n, width) values as a NumPy array.
fn rows<'py>(py: Python<'py>, data: Vec<f64>, width: usize) -> PyResult<Bound<'py, PyAny>> {
    let n = data.len() / width;
    Ok(PyArray1::from_vec(py, data).reshape([n, width])?.into_any())
}

/// What `run` gathers of one algorithm, step by step.
#[derive(Default)]
struct LaneRecord {
    pose: Vec<f64>,
    velocity: Vec<f64>,
    acceleration: Vec<f64>,
    perceived_f: Vec<f64>,
    perceived_w: Vec<f64>,
    leg_length: Vec<f64>,
    leg_margin: Vec<f64>,
    limiter_active: Vec<bool>,
    mode: Vec<&'static str>,
}

impl LaneRecord {
    fn push(&mut self, lane: &LaneFrame) {
        self.pose.extend(lane.command.pose.iter());
        self.velocity.extend(lane.command.velocity.iter());
        self.acceleration.extend(lane.command.acceleration.iter());
        self.perceived_f
            .extend(lane.perceived.specific_force_mps2.iter());
        self.perceived_w
            .extend(lane.perceived.angular_velocity_radps.iter());
        self.leg_length.extend(lane.legs.length_m.iter());
        self.leg_margin.extend(lane.legs.margin_m.iter());
        self.limiter_active.push(lane.limiter_active);
        self.mode.push(lane.state.mode.word());
    }

    fn into_dict(self, py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("pose", rows(py, self.pose, 6)?)?;
        d.set_item("velocity", rows(py, self.velocity, 6)?)?;
        d.set_item("acceleration", rows(py, self.acceleration, 6)?)?;
        d.set_item(
            "perceived_specific_force_mps2",
            rows(py, self.perceived_f, 3)?,
        )?;
        d.set_item(
            "perceived_angular_velocity_radps",
            rows(py, self.perceived_w, 3)?,
        )?;
        d.set_item("leg_length_m", rows(py, self.leg_length, 6)?)?;
        d.set_item("leg_margin_m", rows(py, self.leg_margin, 6)?)?;
        d.set_item(
            "limiter_active",
            PyArray1::from_vec(py, self.limiter_active),
        )?;
        d.set_item("mode", PyList::new(py, self.mode)?)?;
        Ok(d)
    }
}

/// The result of `hexcue.run`: the summary, and every step's signals as NumPy arrays.
#[pyclass(name = "Run", module = "hexcue", frozen)]
struct PyRun {
    /// The summary as a dict of the shape of `hexcue play --summary`'s JSON (NaN where the
    /// JSON has null).
    #[pyo3(get)]
    summary: Py<PyAny>,
    /// Each step's time (s), shape (n,).
    #[pyo3(get)]
    t_s: Py<PyAny>,
    /// What the pilot would perceive in the aircraft: `specific_force_mps2` (Δf from rest) and
    /// `angular_velocity_radps`, each (n, 3).
    #[pyo3(get)]
    reference: Py<PyAny>,
    /// Per algorithm key: the commands (`pose`, `velocity`, `acceleration`, (n, 6)), the
    /// perceived signals ((n, 3)), the legs ((n, 6)), `limiter_active` (n,) and `mode`.
    #[pyo3(get)]
    algorithms: Py<PyAny>,
    scores: Vec<(String, f64)>,
}

#[pymethods]
impl PyRun {
    /// The cueing score of one algorithm (lower is better), the summary's.
    fn score(&self, algorithm: &str) -> PyResult<f64> {
        let key = algorithm_id(algorithm)?.key();
        self.scores
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, s)| *s)
            .ok_or_else(|| value_error(format!("`{key}` did not run")))
    }

    fn __repr__(&self) -> String {
        let scores: Vec<String> = self
            .scores
            .iter()
            .map(|(k, s)| format!("{k}={s:.4}"))
            .collect();
        format!("hexcue.Run(score: {})", scores.join(", "))
    }
}

/// A whole flight through the algorithms, as `hexcue play --headless` runs it: the core's
/// engine (with the trace's future offered to the MPCs, as a trace file's is) and its summary.
/// The flight is a `hexcue.Trace` (`read_trace`), alone, or `specific_force_mps2` and
/// `angular_velocity_radps`, (n, 3) arrays, one row per sample at the profile's rate from
/// t = 0, unless `t_s` gives their times (then they are resampled to the profile's rate as a
/// trace file is). `name` names the flight in the summary (a trace's own name by default). `algorithms` defaults to all three. `preview`
/// (True or False) overrides the profile's `[mpc] preview`, as `play --preview` does: the
/// MPCs then see the flight's true future over their horizon. Offline, as `play` runs by
/// default: the MPCs' wall-clock limit is lifted so that the same input gives the same result
/// on any machine; `realtime_budget = True` keeps the profile's `time_limit_ms`, as
/// `play --realtime-budget` does.
#[pyfunction]
#[pyo3(signature = (specific_force_mps2, angular_velocity_radps = None, profile = None, algorithms = None, t_s = None, name = None, preview = None, realtime_budget = false))]
#[allow(clippy::too_many_arguments)] // Python's keyword arguments, each optional
fn run(
    py: Python<'_>,
    specific_force_mps2: &Bound<'_, PyAny>,
    angular_velocity_radps: Option<PyArrayLike2<'_, f64, AllowTypeChange>>,
    profile: Option<PyRef<'_, PyProfile>>,
    algorithms: Option<Vec<String>>,
    t_s: Option<PyArrayLike1<'_, f64, AllowTypeChange>>,
    name: Option<&str>,
    preview: Option<bool>,
    realtime_budget: bool,
) -> PyResult<PyRun> {
    let mut profile = profile.map_or_else(default_profile, |p| p.inner.clone());
    // `play --preview` sets the same key (src/app/play.rs); None keeps the profile's.
    if let Some(preview) = preview {
        profile.mpc.preview = preview;
    }
    if !realtime_budget {
        profile = profile.offline();
    }
    let mut ids = match algorithms {
        None => AlgorithmId::ALL.to_vec(),
        Some(keys) => keys
            .iter()
            .map(|k| algorithm_id(k))
            .collect::<PyResult<Vec<_>>>()?,
    };
    // The console's order, as `--algorithms` takes it.
    ids.sort();
    ids.dedup();
    if ids.is_empty() {
        return Err(value_error("algorithms: expected at least one"));
    }
    let trace = match specific_force_mps2.extract::<PyRef<'_, PyTrace>>() {
        Ok(file) => {
            if angular_velocity_radps.is_some() || t_s.is_some() {
                return Err(value_error(
                    "a hexcue.Trace holds its own angular velocity and times: expected no \
                     angular_velocity_radps or t_s with it",
                ));
            }
            if file.inner.rate_hz != profile.rate_hz {
                return Err(value_error(format!(
                    "the trace `{}` was read at {} Hz and the profile `{}` runs at {} Hz: \
                     expected hexcue.read_trace(path, profile=profile)",
                    file.inner.name, file.inner.rate_hz, profile.name, profile.rate_hz
                )));
            }
            Trace {
                name: name.unwrap_or(&file.inner.name).to_string(),
                ..Trace::clone(&file.inner)
            }
        }
        Err(_) => {
            let f: PyArrayLike2<'_, f64, AllowTypeChange> = specific_force_mps2.extract()?;
            let w = angular_velocity_radps.ok_or_else(|| {
                value_error(
                    "angular_velocity_radps: expected an (n, 3) array beside \
                     specific_force_mps2, or a hexcue.Trace alone",
                )
            })?;
            let times = t_s.as_ref().map(|t| t.as_array().to_vec());
            Trace {
                name: name.unwrap_or(DEFAULT_RUN_NAME).to_string(),
                rate_hz: profile.rate_hz,
                samples: samples(
                    &f.as_array(),
                    &w.as_array(),
                    times.as_deref(),
                    profile.rate_hz,
                )?,
                info: None,
                notices: Vec::new(),
            }
        }
    };
    let trace = Arc::new(trace);
    let mut engine = Engine::new(&profile, trace.clone(), &ids).map_err(value_error)?;
    let (t, reference, lanes, summary) = py.detach(|| {
        let mut summary = SummaryBuilder::new(&profile, &trace.name);
        let n = trace.len();
        let mut t = Vec::with_capacity(n);
        let mut reference = Vec::with_capacity(6 * n);
        let mut lanes: Vec<LaneRecord> = ids.iter().map(|_| LaneRecord::default()).collect();
        while let Some(frame) = engine.step() {
            summary.push(&frame);
            t.push(frame.t_s);
            reference.extend(frame.reference.channels());
            for (record, lane) in lanes.iter_mut().zip(&frame.lanes) {
                record.push(lane);
            }
        }
        (t, reference, lanes, summary.finish())
    });
    let (ref_f, ref_w): (Vec<f64>, Vec<f64>) = {
        let mut f = Vec::with_capacity(reference.len() / 2);
        let mut w = Vec::with_capacity(reference.len() / 2);
        for row in reference.chunks(6) {
            f.extend_from_slice(&row[..3]);
            w.extend_from_slice(&row[3..]);
        }
        (f, w)
    };
    let reference_dict = PyDict::new(py);
    reference_dict.set_item("specific_force_mps2", rows(py, ref_f, 3)?)?;
    reference_dict.set_item("angular_velocity_radps", rows(py, ref_w, 3)?)?;
    let algorithms_dict = PyDict::new(py);
    for (id, record) in ids.iter().zip(lanes) {
        algorithms_dict.set_item(id.key(), record.into_dict(py)?)?;
    }
    let scores = summary
        .algorithms
        .iter()
        .map(|(k, a)| (k.key().to_string(), a.score))
        .collect();
    Ok(PyRun {
        summary: pythonize::pythonize(py, &summary)?.unbind(),
        t_s: PyArray1::from_vec(py, t).into_any().unbind(),
        reference: reference_dict.into_any().unbind(),
        algorithms: algorithms_dict.into_any().unbind(),
        scores,
    })
}

/// The vestibular model (docs/design.md §4) of a signal at the pilot's head: specific force
/// f (m/s², (0, 0, −9.80665) at rest) and angular velocity (rad/s), (n, 3) each, at the
/// profile's rate. Returns a dict of the perceived `specific_force_mps2` (as the change from
/// rest, Δf) and `angular_velocity_radps`, (n, 3) each: what `run` gives as its `reference`
/// for the same aircraft signal.
#[pyfunction]
#[pyo3(signature = (specific_force_mps2, angular_velocity_radps, profile = None))]
fn perceive<'py>(
    py: Python<'py>,
    specific_force_mps2: PyArrayLike2<'py, f64, AllowTypeChange>,
    angular_velocity_radps: PyArrayLike2<'py, f64, AllowTypeChange>,
    profile: Option<PyRef<'py, PyProfile>>,
) -> PyResult<Bound<'py, PyDict>> {
    let profile = profile.map_or_else(default_profile, |p| p.inner.clone());
    let samples = samples(
        &specific_force_mps2.as_array(),
        &angular_velocity_radps.as_array(),
        None,
        profile.rate_hz,
    )?;
    let mut model = Vestibular::new(&profile.vestibular, profile.dt_s());
    let (mut f, mut w) = (
        Vec::with_capacity(3 * samples.len()),
        Vec::with_capacity(3 * samples.len()),
    );
    for s in &samples {
        let p: Perceived = model.step(&s.delta_f_mps2(), &s.angular_velocity_radps);
        f.extend(p.specific_force_mps2.iter());
        w.extend(p.angular_velocity_radps.iter());
    }
    let d = PyDict::new(py);
    d.set_item("specific_force_mps2", rows(py, f, 3)?)?;
    d.set_item("angular_velocity_radps", rows(py, w, 3)?)?;
    Ok(d)
}

/// hexcue's motion cueing from Python: profiles, the classical washout (CWF), the MPC and the
/// switchable MPC (S-MPC) stepped one sample at a time or run over a whole flight, the
/// vestibular model and the cueing score (docs/python.md).
#[pymodule(name = "hexcue")]
mod hexcue_module {
    #[pymodule_export]
    use super::trace::{read_trace, PyTrace, TraceError};
    #[pymodule_export]
    use super::{perceive, run, ProfileError, PyAlgorithm, PyProfile, PyRun};

    use pyo3::prelude::*;

    #[pymodule_init]
    fn init(m: &Bound<'_, PyModule>) -> PyResult<()> {
        m.add("__version__", env!("CARGO_PKG_VERSION"))?;
        m.add(
            "ALGORITHMS",
            hexcue_core::mca::AlgorithmId::ALL
                .iter()
                .map(|a| a.key())
                .collect::<Vec<_>>(),
        )?;
        m.add("G_MPS2", hexcue_core::G_MPS2)?;
        Ok(())
    }
}
