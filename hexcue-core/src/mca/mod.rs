//! Motion cueing algorithms (docs/design.md §5): a common trait, the classical washout filter and the
//! workspace limiter that ends every algorithm.

pub mod limiter;
pub mod mpc;
pub mod smpc;
pub mod switching;
pub mod washout;

use nalgebra::{Vector3, Vector6};
use serde::Serialize;

use crate::model::platform::Platform;
use crate::model::vestibular::VestibularParams;
pub use crate::vocab::{AlgorithmId, QpName, SolveStatus, SwitchReason};

/// What every algorithm is built for besides its own tuning: the platform it drives, where
/// the pilot's head sits on it, the pilot's vestibular system and the step. The profile
/// composes it from its sections; the algorithms never see the profile itself.
#[derive(Clone, Debug, PartialEq)]
pub struct Setting {
    /// The step every algorithm runs at (s).
    pub dt_s: f64,
    /// The platform driven: its hexapod, limits and leg margin.
    pub platform: Platform,
    /// Pilot's head relative to the centre of the platform joint plane, platform frame
    /// (x forward, y right, z down) (m).
    pub eye_point_m: Vector3<f64>,
    /// The pilot's vestibular model, which the MPCs predict perception with.
    pub vestibular: VestibularParams,
}

/// The aircraft motion an algorithm cues, after input limiting: Δf = f − (0, 0, −g) and ω at
/// the pilot's head (head frame).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CueSample {
    /// Δf: the specific force less its value at rest, head frame (m/s²).
    pub delta_f_mps2: Vector3<f64>,
    /// ω: the angular velocity, head frame (rad/s).
    pub angular_velocity_radps: Vector3<f64>,
}

/// Everything an algorithm is given at step k.
#[derive(Clone, Copy, Debug)]
pub struct CueInput<'a> {
    /// Index of the step, from 0.
    pub k: usize,
    /// Time of the step, k · dt (s).
    pub t_s: f64,
    /// The step (s).
    pub dt_s: f64,
    /// The aircraft motion to cue at this step.
    pub sample: CueSample,
    /// The samples after this one (k+1, k+2, …), for algorithms that may look ahead; shorter
    /// near the end of the trace. A live simulator has none.
    pub preview: &'a [CueSample],
    /// What the platform was commanded at the previous step, after the limiter.
    pub applied: &'a PlatformCommand,
    /// When the whole step must be done: every QP of the step (the active set, then
    /// Clarabel; both of the S-MPC's) shares it. `None`: no caller's deadline, and the MPCs
    /// give the step their profile's `time_limit_ms` from its start (offline runs: `play`,
    /// `compare`, `tune`).
    pub deadline: Option<std::time::Instant>,
}

/// Platform command in the simulator inertial frame: x, y, z (m), roll, pitch, yaw (rad) and
/// their first and second derivatives (Euler-angle rates).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PlatformCommand {
    /// x, y, z (m) and roll, pitch, yaw (rad) from neutral, inertial frame.
    pub pose: Vector6<f64>,
    /// The pose's rate: m/s and Euler-angle rates (rad/s).
    pub velocity: Vector6<f64>,
    /// The pose's second derivative: m/s² and Euler-angle accelerations (rad/s²).
    pub acceleration: Vector6<f64>,
}

impl PlatformCommand {
    /// Whether every component is finite (a command that is not never reaches the platform).
    pub fn is_finite(&self) -> bool {
        self.pose
            .iter()
            .chain(self.velocity.iter())
            .chain(self.acceleration.iter())
            .all(|v| v.is_finite())
    }
}

/// Which controller produced a command.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    /// The classical washout filter.
    Washout,
    /// An MPC without terminal conditions.
    Mpc,
    /// An MPC with terminal conditions (COTC).
    Cotc,
    /// The S-MPC running its MPC without terminal conditions.
    Free,
    /// The S-MPC blending from one controller to the other.
    Blend,
    /// Every solver failed: a smooth washout to neutral.
    Fallback,
}

impl Mode {
    /// The word recordings and the JSON output store (`washout`, `mpc`, `cotc`, …).
    pub fn word(self) -> &'static str {
        match self {
            Mode::Washout => "washout",
            Mode::Mpc => "mpc",
            Mode::Cotc => "cotc",
            Mode::Free => "free",
            Mode::Blend => "blend",
            Mode::Fallback => "fallback",
        }
    }

    /// The mode a [`Mode::word`] names, as recordings store it.
    pub fn from_word(word: &str) -> Option<Self> {
        [
            Mode::Washout,
            Mode::Mpc,
            Mode::Cotc,
            Mode::Free,
            Mode::Blend,
            Mode::Fallback,
        ]
        .into_iter()
        .find(|m| m.word() == word)
    }
}

/// Outcome of one QP solve, as information for the operator. `Copy`: the step hands it on
/// without allocating.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct SolverReport {
    /// Which QP; recordings store its word (`mpc`, `cotc`, `free`).
    pub name: QpName,
    /// How the solve ended; recordings store its word, e.g. `solved`, `primal_infeasible`.
    pub status: SolveStatus,
    /// Solver iterations of the solve.
    pub iterations: u32,
    /// Wall time of the solve (µs).
    pub solve_time_us: f64,
}

/// The state an algorithm exposes to the console and the recording (docs/design.md §5).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AlgorithmState {
    /// The controller in charge.
    pub mode: Mode,
    /// Blend weight w of the S-MPC's mixer while blending (0 = previous controller, 1 = next).
    pub blend: Option<f64>,
    /// Time since the mode last changed (s).
    pub time_in_mode_s: f64,
    /// Controller switches since the start.
    pub switch_count: u32,
    /// The supervisor's last reason to switch; recordings store its text.
    pub last_switch_reason: Option<SwitchReason>,
    /// The QPs of the step, in the algorithm's order (the S-MPC: COTC, then the free MPC).
    pub solvers: Solvers,
}

/// The most solver reports a step carries: the S-MPC's two QPs, with room to spare.
pub const MAX_SOLVERS: usize = 4;

/// The solver reports of one step, held inline so that an algorithm's state is built without
/// allocating; a slice of [`SolverReport`] to read. Beyond [`MAX_SOLVERS`] reports (none of
/// hexcue's algorithms has more than two) the rest are left out.
#[derive(Clone, Copy, Default)]
pub struct Solvers {
    reports: [SolverReport; MAX_SOLVERS],
    len: usize,
}

impl Solvers {
    /// No report: an algorithm without a QP.
    pub const fn new() -> Self {
        Solvers {
            reports: [SolverReport {
                name: QpName::Mpc,
                status: SolveStatus::NotYet,
                iterations: 0,
                solve_time_us: 0.0,
            }; MAX_SOLVERS],
            len: 0,
        }
    }

    /// Appends a report; false (and nothing changed) when [`MAX_SOLVERS`] are already held.
    pub fn push(&mut self, report: SolverReport) -> bool {
        if self.len == MAX_SOLVERS {
            return false;
        }
        self.reports[self.len] = report;
        self.len += 1;
        true
    }
}

impl std::ops::Deref for Solvers {
    type Target = [SolverReport];
    fn deref(&self) -> &[SolverReport] {
        &self.reports[..self.len]
    }
}

impl std::ops::DerefMut for Solvers {
    fn deref_mut(&mut self) -> &mut [SolverReport] {
        &mut self.reports[..self.len]
    }
}

impl PartialEq for Solvers {
    fn eq(&self, other: &Self) -> bool {
        **self == **other
    }
}

impl std::fmt::Debug for Solvers {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

impl Serialize for Solvers {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(self.iter())
    }
}

impl FromIterator<SolverReport> for Solvers {
    fn from_iter<I: IntoIterator<Item = SolverReport>>(iter: I) -> Self {
        let mut out = Solvers::new();
        for r in iter {
            if !out.push(r) {
                break;
            }
        }
        out
    }
}

impl<const N: usize> From<[SolverReport; N]> for Solvers {
    fn from(reports: [SolverReport; N]) -> Self {
        reports.into_iter().collect()
    }
}

impl<'a> IntoIterator for &'a Solvers {
    type Item = &'a SolverReport;
    type IntoIter = std::slice::Iter<'a, SolverReport>;
    fn into_iter(self) -> Self::IntoIter {
        self.iter()
    }
}

impl<'a> IntoIterator for &'a mut Solvers {
    type Item = &'a mut SolverReport;
    type IntoIter = std::slice::IterMut<'a, SolverReport>;
    fn into_iter(self) -> Self::IntoIter {
        self.iter_mut()
    }
}

impl AlgorithmState {
    /// The state of an algorithm with no switch and no QP, in `mode`.
    pub fn simple(mode: Mode) -> Self {
        AlgorithmState {
            mode,
            blend: None,
            time_in_mode_s: 0.0,
            switch_count: 0,
            last_switch_reason: None,
            solvers: Solvers::new(),
        }
    }
}

/// A motion cueing algorithm: aircraft motion in, platform command out, one sample at a time.
pub trait MotionCueing: Send {
    /// Which algorithm this is.
    fn id(&self) -> AlgorithmId;
    /// The raw command for step k; the engine's limiter follows.
    fn step(&mut self, input: &CueInput) -> PlatformCommand;
    /// Its state after the last step, for the console and the recording.
    fn state(&self) -> AlgorithmState;
    /// Back to rest at neutral, as at the start of a trace.
    fn reset(&mut self);
    /// The running state, so that [`MotionCueing::restore`] can return to this step: the
    /// console keeps some to seek back without replaying from the start. `None` when the
    /// algorithm cannot (the console then replays).
    fn snapshot(&self) -> Option<AlgorithmSnapshot> {
        None
    }
    /// Returns to a state [`MotionCueing::snapshot`] took of this algorithm; false (and
    /// nothing changed) if the snapshot is another algorithm's.
    fn restore(&mut self, _snapshot: &AlgorithmSnapshot) -> bool {
        false
    }
    /// Takes over the running state of a snapshot of the same algorithm tuned otherwise (a
    /// live change, issue 36), keeping this one's own tuning; false if it cannot. The MPCs'
    /// running state holds no tuning, so restoring it is enough.
    fn inherit(&mut self, snapshot: &AlgorithmSnapshot) -> bool {
        self.restore(snapshot)
    }
    /// [`MotionCueing::inherit`] straight from `other`, the same algorithm tuned otherwise,
    /// without a snapshot in between: the CWF and the MPCs copy into the buffers they hold
    /// and allocate nothing, so that a live session's change of phase (air ↔ ground, issue
    /// 36) is made on its stepping thread, which must not allocate. Others go through a
    /// snapshot.
    fn inherit_from(&mut self, other: &dyn MotionCueing) -> bool {
        match other.snapshot() {
            Some(s) => self.inherit(&s),
            None => false,
        }
    }
    /// The algorithm as [`std::any::Any`], for [`MotionCueing::inherit_from`]'s downcast;
    /// `None` where it has no use for it.
    fn as_any(&self) -> Option<&dyn std::any::Any> {
        None
    }
    /// Whether the algorithm may hand part of a step to rayon's pool (true by default). A
    /// live session says no: its stepping thread runs at real-time priority and the pool's
    /// threads do not, so the step would wait behind whatever else the machine runs.
    fn set_parallel(&mut self, _parallel: bool) {}
    /// Whether the last step's command is the workspace limiter's own braking step, which the
    /// algorithm issued itself because the limiter would have refused the pose it had decided
    /// a step ahead (the MPCs: docs/mpc.md, "The chain after one refusal, cured"). The engine
    /// counts such a step as the limiter's: it is its action, taken one step earlier.
    fn issued_limiter_braking(&self) -> bool {
        false
    }
}

/// An algorithm's running state, opaque to everyone but the algorithm that took it.
pub struct AlgorithmSnapshot(Box<dyn std::any::Any + Send + Sync>);

impl AlgorithmSnapshot {
    /// A snapshot holding `state`.
    pub fn new<T: std::any::Any + Send + Sync>(state: T) -> Self {
        AlgorithmSnapshot(Box::new(state))
    }

    /// The state, if it is a `T`.
    pub fn get<T: std::any::Any>(&self) -> Option<&T> {
        self.0.downcast_ref()
    }
}

impl std::fmt::Debug for AlgorithmSnapshot {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("AlgorithmSnapshot(..)")
    }
}

/// Error building an algorithm.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    /// The profile lacks a section the algorithm is built from.
    #[error("profile `{profile}` has no [{section}] section, which {algorithm} needs")]
    MissingSection {
        /// The profile's name.
        profile: String,
        /// The section missing, e.g. `smpc`.
        section: &'static str,
        /// The algorithm that needs it.
        algorithm: AlgorithmId,
    },
    /// The algorithm could not be set up from its parameters.
    #[error("{algorithm}: {reason}")]
    Setup {
        /// The algorithm.
        algorithm: AlgorithmId,
        /// Why, in a sentence.
        reason: String,
    },
}
