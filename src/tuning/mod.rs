//! The parameters an engineer may change while a pilot flies (issue 36, docs/parameters.md):
//! the master motion gain, a gain per DoF, and each algorithm's main keys by the profile's
//! key path, each with its safe range. No I/O: the console and the Foxglove server call
//! [`Tuner::set`]; what it returns is applied by the engine, bumplessly
//! ([`hexcue_core::bumpless`]).
//!
//! The ranges of the algorithms' keys are `hexcue tune`'s search bounds (`crate::tune::keys`):
//! values inside them were scored by the tuner and load; the gains run from 0 to 1, so that a
//! change only ever brings the command nearer neutral than the algorithm asks.

use nalgebra::Vector6;
use toml_edit::DocumentMut;

use crate::tune::keys::{tunable_keys, TunableKey};
use hexcue_core::bumpless::DriveSwitch;
use hexcue_core::engine::Retune;
use hexcue_core::mca::AlgorithmId;
use hexcue_core::profile::Profile;
use hexcue_core::safety::DOF_NAMES;
use hexcue_core::summary::{ParameterChange, TuningSummary};

/// The master gain's name, as the issue and Foxglove's panel call it.
pub const MOTION_GAIN: &str = "motion_gain";

/// The driving algorithm's parameter (live only): 0 the CWF, 1 the MPC, 2 the S-MPC.
pub const DRIVE: &str = "drive";

/// The algorithms by their `drive` value.
pub const DRIVE_CODES: [AlgorithmId; 3] = [AlgorithmId::Cwf, AlgorithmId::Mpc, AlgorithmId::Smpc];

/// The `drive` value of `id`.
pub fn drive_code(id: AlgorithmId) -> f64 {
    DRIVE_CODES.iter().position(|a| *a == id).unwrap_or(0) as f64
}

/// The CWF's tilt limits, which `hexcue tune` keeps fixed (a matter of perception, not of
/// taste) but an engineer may lower, or raise to the largest a shipped profile uses: 20° of
/// tilt, and the canals' 3 °/s threshold for its rate (docs/design.md §5).
const TILT_KEYS: &[TunableKey] = &[
    TunableKey {
        path: "cwf.tilt_limit_deg",
        elements: &[],
        lower: 1.0,
        upper: 20.0,
        log: false,
    },
    TunableKey {
        path: "cwf.tilt_rate_limit_dps",
        elements: &[],
        lower: 0.5,
        upper: 3.0,
        log: false,
    },
];

/// What a parameter acts on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Target {
    /// Every DoF's gain, times its own.
    MotionGain,
    /// One DoF's gain (0 surge … 5 yaw).
    DofGain(usize),
    /// The driving algorithm, by its code in [`DRIVE_CODES`].
    Drive,
    /// A key of the profile (one element, or several tuned as one).
    Key(TunableKey),
}

/// One tunable parameter.
#[derive(Clone, Debug, PartialEq)]
pub struct Parameter {
    /// `motion_gain`, `gain.surge`, `cwf.specific_force_scale[0]`, `mpc.specific_force_weight[0,1]`.
    pub name: String,
    pub lower: f64,
    pub upper: f64,
    pub target: Target,
}

impl Parameter {
    /// Which algorithm it tunes; `None` for the gains.
    pub fn algorithm(&self) -> Option<AlgorithmId> {
        match self.target {
            Target::Key(k) if k.path.starts_with("cwf.") => Some(AlgorithmId::Cwf),
            Target::Key(k) if k.path.starts_with("mpc.") => Some(AlgorithmId::Mpc),
            Target::Key(_) => Some(AlgorithmId::Smpc),
            _ => None,
        }
    }

    /// A step of the console's keys: a fiftieth of the range (on a log scale for the keys the
    /// tuner searches so), `up` or down from `value`, within the range.
    pub fn step(&self, value: f64, up: bool) -> f64 {
        if self.target == Target::Drive {
            // The next algorithm either way (the tuner refuses one the session lacks).
            let next = if up { value + 1.0 } else { value - 1.0 };
            return next.rem_euclid(DRIVE_CODES.len() as f64);
        }
        let log = matches!(self.target, Target::Key(k) if k.log);
        let v = if log {
            let f = (self.upper / self.lower).powf(1.0 / 50.0);
            if up {
                value * f
            } else {
                value / f
            }
        } else {
            let d = (self.upper - self.lower) / 50.0;
            if up {
                value + d
            } else {
                value - d
            }
        };
        crate::tune::keys::round_significant(v, 4).clamp(self.lower, self.upper)
    }
}

/// A refused change: the name and what was expected, for the operator.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ParamError {
    #[error("`{name}`: no such parameter (the panel and getParameters list them)")]
    Unknown { name: String },
    #[error("`{name}`: {value} is outside its safe range [{lower}, {upper}]: nothing changed")]
    OutOfRange {
        name: String,
        value: f64,
        lower: f64,
        upper: f64,
    },
    #[error("`{name}`: the profile refuses {value}: {reason}: nothing changed")]
    Refused {
        name: String,
        value: f64,
        reason: String,
    },
}

/// What the engine is to do for a change.
pub enum Apply {
    /// Send the gains (per DoF) toward these.
    Gains(Vector6<f64>),
    /// Hand the rebuilt algorithms over: one [`Retune`] per algorithm, so that a live
    /// session hands each to the engine that steps it (the driving lane's on the stepping
    /// thread, the comparison lanes' on theirs).
    Retune(Vec<Retune>),
    /// Blend the command from the driving algorithm's to this one's
    /// ([`hexcue_core::bumpless::DriveSwitch`]).
    Drive(AlgorithmId),
}

/// A change made, before the engine has applied it.
pub struct Change {
    /// The parameter's index in [`Tuner::parameters`].
    pub index: usize,
    pub from: f64,
    pub to: f64,
    /// Made by [`Tuner::undo`].
    pub undo: bool,
    pub apply: Apply,
}

/// The registry: every parameter, the values in force, the undo stack and the log.
pub struct Tuner {
    parameters: Vec<Parameter>,
    values: Vec<f64>,
    /// The profile with the values in force, as TOML (every key stated: serialised).
    doc: DocumentMut,
    profile: Profile,
    algorithms: Vec<AlgorithmId>,
    /// (parameter, value before) of each change not undone.
    undo: Vec<(usize, f64)>,
    log: Vec<ParameterChange>,
}

impl Tuner {
    /// The parameters of a session of `algorithms` on `profile`: the gains, then each
    /// algorithm's keys.
    pub fn new(profile: &Profile, algorithms: &[AlgorithmId]) -> Result<Self, ParamError> {
        let text = toml::to_string(profile).map_err(|e| ParamError::Refused {
            name: profile.name.clone(),
            value: f64::NAN,
            reason: format!("the profile cannot be written as TOML: {e}"),
        })?;
        let doc: DocumentMut = text.parse().map_err(|e| ParamError::Refused {
            name: profile.name.clone(),
            value: f64::NAN,
            reason: format!("the profile's TOML does not read back: {e}"),
        })?;
        let mut parameters = vec![Parameter {
            name: MOTION_GAIN.to_string(),
            lower: 0.0,
            upper: 1.0,
            target: Target::MotionGain,
        }];
        parameters.extend(DOF_NAMES.iter().enumerate().map(|(i, dof)| Parameter {
            name: format!("gain.{dof}"),
            lower: 0.0,
            upper: 1.0,
            target: Target::DofGain(i),
        }));
        let mut keys: Vec<TunableKey> = Vec::new();
        for id in [AlgorithmId::Cwf, AlgorithmId::Mpc, AlgorithmId::Smpc] {
            let wanted = match id {
                // The S-MPC runs on `[mpc]`: its keys come with either MPC.
                AlgorithmId::Mpc => {
                    algorithms.contains(&AlgorithmId::Mpc)
                        || algorithms.contains(&AlgorithmId::Smpc)
                }
                _ => algorithms.contains(&id),
            };
            if !wanted {
                continue;
            }
            keys.extend(tunable_keys(id).iter().filter(|k| match id {
                // The supervisor's keys live in its running state (dwell, ε, the blend): a
                // change mid-switch has no bumpless meaning. COTC's weights do.
                AlgorithmId::Smpc => k.path.starts_with("smpc.cotc."),
                _ => true,
            }));
            if id == AlgorithmId::Cwf {
                keys.extend(TILT_KEYS);
            }
        }
        let mut values = vec![profile.motion_gain];
        values.extend(profile.gain.as_array());
        for k in keys {
            // A key the serialised profile lacks (none: every field is written) is skipped.
            let Ok(v) = k.get(&doc) else {
                continue;
            };
            parameters.push(Parameter {
                name: k.name(),
                lower: k.lower,
                upper: k.upper,
                target: Target::Key(k),
            });
            values.push(v);
        }
        Ok(Tuner {
            parameters,
            values,
            doc,
            profile: profile.clone(),
            algorithms: algorithms.to_vec(),
            undo: Vec::new(),
            log: Vec::new(),
        })
    }

    /// With the `drive` parameter, `drive` in force: the algorithm driving a live session,
    /// switched through a blend (any of the session's algorithms).
    pub fn with_drive(mut self, drive: AlgorithmId) -> Self {
        self.parameters.insert(
            1 + DOF_NAMES.len(),
            Parameter {
                name: DRIVE.to_string(),
                lower: 0.0,
                upper: (DRIVE_CODES.len() - 1) as f64,
                target: Target::Drive,
            },
        );
        self.values.insert(1 + DOF_NAMES.len(), drive_code(drive));
        self
    }

    /// The `drive` value that switches to the session's next algorithm after the one driving
    /// (in the order cwf, mpc, smpc, round); `None` without the parameter or a second one.
    pub fn next_drive(&self) -> Option<f64> {
        let now = self.get(DRIVE)? as usize;
        (1..DRIVE_CODES.len())
            .map(|k| (now + k) % DRIVE_CODES.len())
            .find(|c| self.algorithms.contains(&DRIVE_CODES[*c]))
            .map(|c| c as f64)
    }

    pub fn parameters(&self) -> &[Parameter] {
        &self.parameters
    }

    /// The value in force of parameter `index`.
    pub fn value(&self, index: usize) -> f64 {
        self.values[index]
    }

    pub fn index(&self, name: &str) -> Option<usize> {
        self.parameters.iter().position(|p| p.name == name)
    }

    /// The value in force of the parameter called `name`.
    pub fn get(&self, name: &str) -> Option<f64> {
        self.index(name).map(|i| self.values[i])
    }

    /// The profile with the values in force.
    pub fn profile(&self) -> &Profile {
        &self.profile
    }

    /// The gain per DoF in force: the master gain times each DoF's.
    pub fn gains(&self) -> Vector6<f64> {
        Vector6::from_fn(|i, _| self.values[0] * self.values[1 + i])
    }

    /// Changes `name` to `value` if it is inside its range (and the profile loads with it):
    /// what the engine is to do, or why nothing changed.
    pub fn set(&mut self, name: &str, value: f64) -> Result<Change, ParamError> {
        let index = self.index(name).ok_or_else(|| ParamError::Unknown {
            name: name.to_string(),
        })?;
        let change = self.change(index, value, false)?;
        self.undo.push((index, change.from));
        Ok(change)
    }

    /// Takes back the last change not yet undone; `None` when there is none.
    pub fn undo(&mut self) -> Option<Result<Change, ParamError>> {
        let (index, before) = self.undo.pop()?;
        let out = self.change(index, before, true);
        if out.is_err() {
            self.undo.push((index, before));
        }
        Some(out)
    }

    /// Changes a parameter in force, with no record.
    fn change(&mut self, index: usize, value: f64, undo: bool) -> Result<Change, ParamError> {
        let p = &self.parameters[index];
        if !(value.is_finite() && value >= p.lower && value <= p.upper) {
            return Err(ParamError::OutOfRange {
                name: p.name.clone(),
                value,
                lower: p.lower,
                upper: p.upper,
            });
        }
        let from = self.values[index];
        let apply = match p.target {
            Target::MotionGain | Target::DofGain(_) => {
                self.values[index] = value;
                // The profile in force carries them, so that `w` writes them and a later
                // retune (or the ground tuning) starts from them.
                set_gain(&mut self.profile, &mut self.doc, p.target, value);
                Apply::Gains(self.gains())
            }
            Target::Drive => {
                let id = DRIVE_CODES
                    .get(value as usize)
                    .filter(|_| value.fract() == 0.0)
                    .copied();
                let Some(id) = id.filter(|id| self.algorithms.contains(id)) else {
                    let session: Vec<&str> = self.algorithms.iter().map(|a| a.key()).collect();
                    return Err(ParamError::Refused {
                        name: p.name.clone(),
                        value,
                        reason: format!(
                            "expected the code of one of this session's algorithms ({}; 0 cwf, \
                             1 mpc, 2 smpc)",
                            session.join(", ")
                        ),
                    });
                };
                self.values[index] = value;
                Apply::Drive(id)
            }
            Target::Key(key) => {
                let refused = |reason: String| ParamError::Refused {
                    name: p.name.clone(),
                    value,
                    reason,
                };
                let mut doc = self.doc.clone();
                key.set(&mut doc, value)
                    .map_err(|e| refused(e.to_string()))?;
                let profile: Profile =
                    toml::from_str(&doc.to_string()).map_err(|e| refused(e.to_string()))?;
                profile
                    .validate_offline()
                    .map_err(|e| refused(e.to_string()))?;
                let retunes = self
                    .algorithms
                    .iter()
                    .map(|id| Retune::build(&self.profile, &profile, &[*id]))
                    .filter(|r| r.as_ref().map_or(true, |r| !r.algorithms().is_empty()))
                    .collect::<Result<Vec<_>, _>>()
                    .map_err(|e| refused(e.to_string()))?;
                self.doc = doc;
                self.profile = profile;
                self.values[index] = value;
                Apply::Retune(retunes)
            }
        };
        Ok(Change {
            index,
            from,
            to: value,
            undo,
            apply,
        })
    }

    /// Notes a change as applied at session time `t_s`, for the summary.
    pub fn record(&mut self, change: &Change, t_s: f64) {
        self.log.push(ParameterChange {
            t_s,
            name: self.parameters[change.index].name.clone(),
            from: change.from,
            to: change.to,
            undo: change.undo,
        });
    }

    /// The changes applied so far.
    pub fn changes(&self) -> &[ParameterChange] {
        &self.log
    }

    /// What a session without a JSON summary (the `play` console) says at its end: each
    /// parameter changed, from its first value to the one in force, and how many changes;
    /// nothing when none was made.
    pub fn final_lines(&self) -> Vec<String> {
        if self.log.is_empty() {
            return Vec::new();
        }
        let mut lines = vec![format!(
            "tuning: {} change(s) during the session; the values in force at its end:",
            self.log.len()
        )];
        for (p, v) in self.parameters.iter().zip(&self.values) {
            let first = self.log.iter().find(|c| c.name == p.name).map(|c| c.from);
            if let Some(first) = first.filter(|f| f != v) {
                lines.push(format!("tuning: {} = {v} (was {first})", p.name));
            }
        }
        lines
    }

    /// For the summary: every parameter's value in force, and the changes.
    pub fn summary(&self) -> TuningSummary {
        TuningSummary {
            final_parameter_values: self
                .parameters
                .iter()
                .zip(&self.values)
                .map(|(p, v)| (p.name.clone(), *v))
                .collect(),
            changes: self.log.clone(),
        }
    }

    /// Writes the profile keys in force into `doc` (a profile file's own TOML), keeping its
    /// comments and layout: the algorithms' keys, and the gains (`motion_gain`, `[gain]`,
    /// added where the file does not state them and they are not 1). The drive is the
    /// session's, not the profile's. A tuned key the file does not state is an error naming
    /// it.
    pub fn write_into(&self, doc: &mut DocumentMut) -> anyhow::Result<()> {
        for (p, v) in self.parameters.iter().zip(&self.values) {
            match p.target {
                Target::Key(key) => {
                    if key.get(doc).ok() != Some(*v) {
                        key.set(doc, *v)?;
                    }
                }
                Target::MotionGain | Target::DofGain(_) => {
                    let stated = gain_item(doc, p.target)
                        .and_then(|i| i.as_float().or(i.as_integer().map(|n| n as f64)));
                    if stated.unwrap_or(1.0) != *v {
                        let mut profile = self.profile.clone();
                        set_gain(&mut profile, doc, p.target, *v);
                    }
                }
                Target::Drive => {}
            }
        }
        Ok(())
    }
}

/// The gain `target` set to `value` in `profile` and in its TOML `doc` (`motion_gain` at
/// the top, `gain.surge` … in `[gain]`, made where missing).
fn set_gain(profile: &mut Profile, doc: &mut DocumentMut, target: Target, value: f64) {
    match target {
        Target::MotionGain => {
            profile.motion_gain = value;
            doc[MOTION_GAIN] = toml_edit::value(value);
        }
        Target::DofGain(i) => {
            if let Some(g) = profile.gain.get_mut(i) {
                *g = value;
            }
            if !doc.contains_key("gain") {
                doc["gain"] = toml_edit::table();
            }
            doc["gain"][DOF_NAMES[i]] = toml_edit::value(value);
        }
        Target::Drive | Target::Key(_) => {}
    }
}

/// The gain `target`'s item in `doc`, if stated.
fn gain_item(doc: &DocumentMut, target: Target) -> Option<&toml_edit::Item> {
    match target {
        Target::MotionGain => doc.get(MOTION_GAIN),
        Target::DofGain(i) => doc.get("gain")?.get(DOF_NAMES[i]),
        Target::Drive | Target::Key(_) => None,
    }
}

/// A tuner shared between the stepping loop and whoever changes parameters (the console, the
/// Foxglove server): changes are checked at once, queued, and applied by the loop at its next
/// step, which alone knows the session time.
pub struct Shared {
    pub tuner: Tuner,
    pending: Vec<Change>,
}

/// The handle every side holds.
pub type TuningHandle = std::sync::Arc<Tuning>;

/// The shared tuner behind its lock, with a flag saying whether changes are queued: the
/// stepping loop reads the flag each step and takes the lock only when there is something
/// to apply, so that no step takes a lock while nobody tunes.
pub struct Tuning {
    shared: std::sync::Mutex<Shared>,
    pending: std::sync::atomic::AtomicBool,
}

/// The tuner could not be had: a side panicked while holding it.
#[derive(Debug)]
pub struct Poisoned;

/// The locked tuner; on release it raises or clears [`Tuning`]'s flag by its queue.
pub struct TuningGuard<'a> {
    guard: std::sync::MutexGuard<'a, Shared>,
    pending: &'a std::sync::atomic::AtomicBool,
}

impl std::ops::Deref for TuningGuard<'_> {
    type Target = Shared;
    fn deref(&self) -> &Shared {
        &self.guard
    }
}

impl std::ops::DerefMut for TuningGuard<'_> {
    fn deref_mut(&mut self) -> &mut Shared {
        &mut self.guard
    }
}

impl Drop for TuningGuard<'_> {
    fn drop(&mut self) {
        self.pending.store(
            !self.guard.pending.is_empty(),
            std::sync::atomic::Ordering::Release,
        );
    }
}

impl Tuning {
    /// Waits for the tuner (the console and the Foxglove server).
    pub fn lock(&self) -> Result<TuningGuard<'_>, Poisoned> {
        let guard = self.shared.lock().map_err(|_| Poisoned)?;
        Ok(TuningGuard {
            guard,
            pending: &self.pending,
        })
    }

    /// The tuner when changes are queued and nobody else holds it; `None` otherwise, at the
    /// cost of one atomic load when nothing is queued (the stepping loop, each step).
    pub fn try_lock_pending(&self) -> Option<TuningGuard<'_>> {
        if !self.pending.load(std::sync::atomic::Ordering::Acquire) {
            return None;
        }
        let guard = self.shared.try_lock().ok()?;
        Some(TuningGuard {
            guard,
            pending: &self.pending,
        })
    }
}

impl Shared {
    pub fn handle(tuner: Tuner) -> TuningHandle {
        std::sync::Arc::new(Tuning {
            shared: std::sync::Mutex::new(Shared {
                tuner,
                pending: Vec::new(),
            }),
            pending: std::sync::atomic::AtomicBool::new(false),
        })
    }

    /// [`Tuner::set`], queued for the next step.
    pub fn set(&mut self, name: &str, value: f64) -> Result<(), ParamError> {
        let change = self.tuner.set(name, value)?;
        self.pending.push(change);
        Ok(())
    }

    /// [`Tuner::undo`], queued for the next step; false when there is nothing to undo.
    pub fn undo(&mut self) -> Result<bool, ParamError> {
        match self.tuner.undo() {
            None => Ok(false),
            Some(change) => {
                self.pending.push(change?);
                Ok(true)
            }
        }
    }

    /// The changes not yet applied, for the stepping loop (no allocation when none).
    pub fn take_pending(&mut self) -> Vec<Change> {
        std::mem::take(&mut self.pending)
    }
}

/// Applies queued changes to `engine` at session time `t_s`: the gains along their paths,
/// a retune or a drive switch through a blend of `blend_s`. Returns each change's event
/// text; the changes are recorded in the tuner for the summary. What is also for lanes
/// `engine` does not step goes to `elsewhere`: every new gain target, each rebuilt algorithm
/// not among `engine`'s, and every drive switch (to an algorithm `engine` may not step).
pub fn apply_pending(
    shared: &mut Shared,
    engine: &mut hexcue_core::engine::Engine,
    drives: &mut DriveSwitch,
    t_s: f64,
    blend_s: f64,
    mut elsewhere: impl FnMut(Applied),
) -> Vec<String> {
    let mut texts = Vec::new();
    for change in shared.take_pending() {
        let name = shared.tuner.parameters()[change.index].name.clone();
        shared.tuner.record(&change, t_s);
        let follow_s = match &change.apply {
            Apply::Gains(g) => engine.set_gains(*g),
            Apply::Retune(_) | Apply::Drive(_) => blend_s,
        };
        let mut text = change_text(&name, &change, follow_s);
        match change.apply {
            Apply::Gains(g) => elsewhere(Applied::Gains(g)),
            Apply::Retune(retunes) => {
                let here = engine.algorithms();
                for r in retunes {
                    if r.algorithms().iter().all(|id| here.contains(id)) {
                        engine.retune(r, blend_s);
                    } else {
                        elsewhere(Applied::Retune(Box::new(r)));
                    }
                }
            }
            // A lane `engine` does not step (a live session's comparison lane, on its own
            // thread) is handed on: the session brings it over, and the blend starts when it
            // arrives (docs/live.md, *Switching the drive*).
            Apply::Drive(to) => {
                let from = drives.drive();
                let here = engine.has_lane(to);
                let cut = here && drives.switch(to, blend_s);
                elsewhere(Applied::Drive { to, here });
                text = format!(
                    "parameter {name} {}: {} → {} ({} → {}), the command blends from {}'s to {}'s \
                     within {blend_s:.2} s{}{}",
                    if change.undo { "undone" } else { "set" },
                    change.from,
                    change.to,
                    from.key(),
                    to.key(),
                    from.key(),
                    to.key(),
                    if here {
                        ""
                    } else {
                        " of its lane's arrival from the comparison lanes' thread"
                    },
                    if cut {
                        "; the oldest blend still under way was cut short"
                    } else {
                        ""
                    }
                );
            }
        }
        texts.push(text);
    }
    texts
}

/// What [`apply_pending`] hands on for the lanes of another engine (a live session's
/// comparison lanes): the new gains, which every lane's command takes, the rebuilt
/// algorithms that engine steps, and each drive switch.
pub enum Applied {
    Gains(Vector6<f64>),
    Retune(Box<Retune>),
    /// The drive switched to `to`: already blending in when `here` (the engine steps it),
    /// else to be brought over, the blend to start on its arrival.
    Drive {
        to: AlgorithmId,
        here: bool,
    },
}

/// The text of a change's event: what changed, and how long the command takes to follow.
pub fn change_text(name: &str, change: &Change, follow_s: f64) -> String {
    let what = if change.undo { "undone" } else { "set" };
    format!(
        "parameter {name} {what}: {} → {}, the command follows bumplessly within {follow_s:.2} s",
        change.from, change.to
    )
}

pub mod played;

#[cfg(test)]
mod tests;
