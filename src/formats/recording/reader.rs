//! The reader: a recording's metadata and attachments, its frames and its JSON messages,
//! streamed record by record.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use mcap::records::Record;
use mcap::McapError;
use serde::Deserialize;

use super::source::{RecordSource, SourceError};
use super::{
    sha256_hex, shown, RecordingError, RecordingMeta, METADATA_NAME, PROFILE_ATTACHMENT,
    SIDECAR_ATTACHMENT, TRACE_ATTACHMENT, TRACE_ZSTD_ATTACHMENT,
};
use crate::channels::json::{ActuatorsMsg, AircraftMsg, ControllerMsg, PerceivedMsg, PlatformMsg};
use crate::channels::{Channel, Kind, AIRCRAFT_TOPIC, REFERENCE_TOPIC};
use crate::engine::{Frame, LaneFrame, Legs};
use crate::formats::profile::{parse_profile, ProfileLoadError};
use crate::mca::{AlgorithmId, AlgorithmState, Mode, PlatformCommand, SolverReport};
use crate::profile::Profile;
use crate::trace::AircraftSample;

/// What a topic carries.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Role {
    Aircraft,
    Reference,
    Lane(AlgorithmId, usize),
}

/// `/aircraft`, `/aircraft/perceived` or `/ALG/KIND`; the algorithm is a key, which may be
/// one this build does not know.
fn parse_topic(topic: &str) -> Option<Result<(AlgorithmId, usize), &str>> {
    let (kind, alg) = Channel::parse_lane(topic)?;
    let kind = Kind::LANE_JSON.iter().position(|k| *k == kind)?;
    Some(alg.map(|id| (id, kind)))
}

fn role_of(topic: &str, algorithms: &[AlgorithmId]) -> Option<Role> {
    match topic {
        AIRCRAFT_TOPIC => Some(Role::Aircraft),
        REFERENCE_TOPIC => Some(Role::Reference),
        _ => match parse_topic(topic)? {
            Ok((id, kind)) if algorithms.contains(&id) => Some(Role::Lane(id, kind)),
            _ => None,
        },
    }
}

/// Largest trace a compressed attachment may expand to: about 15 hours of live input at
/// 100 Hz. A damaged or hostile file must not make the reader allocate without bound.
const TRACE_LIMIT: u64 = 1 << 30;

fn unzstd(data: &[u8]) -> std::io::Result<Vec<u8>> {
    use std::io::Read;
    let mut out = Vec::new();
    zstd::stream::read::Decoder::new(data)?
        .take(TRACE_LIMIT + 1)
        .read_to_end(&mut out)?;
    if out.len() as u64 > TRACE_LIMIT {
        return Err(std::io::Error::other("larger than 1 GiB"));
    }
    Ok(out)
}

/// A recording opened for review: what it says about itself and where its frames are.
#[derive(Debug)]
pub struct Recording {
    pub path: PathBuf,
    /// The `hexcue` metadata record as written (tool_version, profile_name, trace_name,
    /// trace_sha256, rate_hz, algorithms, start_unix_ns, …).
    pub metadata: BTreeMap<String, String>,
    pub tool_version: String,
    pub profile_name: String,
    /// The attached profile as it was used.
    pub profile_toml: String,
    /// The attached profile, parsed; an error when it no longer validates (the recording is
    /// still readable).
    pub profile: Result<Profile, ProfileLoadError>,
    pub trace_name: String,
    pub trace_csv: String,
    pub trace_sidecar: Option<String>,
    pub rate_hz: f64,
    /// Unix time of the recording's start (ns): log time = this + trace time.
    pub start_unix_ns: u64,
    /// Algorithms found as `/ALG/...` topics, in the order they were recorded.
    pub algorithms: Vec<AlgorithmId>,
    /// Whether the file was closed properly. An unfinished one is read up to its last
    /// complete chunk.
    pub finished: bool,
    /// Why reading stopped before a proper end, for an unfinished file.
    pub stopped: Option<String>,
    /// Steps found (`/aircraft` messages); an unfinished file's last may be incomplete and
    /// is then left out of [`Recording::frames`].
    pub steps: u64,
    pub messages: u64,
    /// Trace time of the last step (s).
    pub last_t_s: f64,
    /// Things worth telling the user: unknown topics, a trace that does not match its
    /// checksum, a profile that no longer validates.
    pub notices: Vec<String>,
}

impl Recording {
    /// Reads a recording's metadata and attachments, and checks how far it can be read.
    pub fn open(path: &Path) -> Result<Recording, RecordingError> {
        let p = shown(path);
        let mut source = RecordSource::open(path)?;
        let mut metadata = None;
        let mut attachments: BTreeMap<String, Vec<u8>> = BTreeMap::new();
        let mut topics: BTreeMap<u16, String> = BTreeMap::new();
        let mut aircraft_ids = Vec::new();
        let (mut steps, mut messages, mut last_log_time) = (0u64, 0u64, None);
        let mut stopped = None;
        loop {
            match source.next_record() {
                None => break,
                Some(Err(SourceError::Io(error))) => {
                    return Err(RecordingError::Io {
                        path: p,
                        action: "read the recording",
                        error,
                    })
                }
                Some(Err(SourceError::Mcap(error))) => {
                    if matches!(error, McapError::BadMagic)
                        || source.bytes < mcap::MAGIC.len() as u64
                    {
                        return Err(RecordingError::NotMcap { path: p });
                    }
                    stopped = Some(error);
                    break;
                }
                Some(Ok(record)) => match record {
                    Record::Metadata(m) if m.name == METADATA_NAME => metadata = Some(m.metadata),
                    Record::Attachment { header, data, .. } => {
                        // The last trace wins under either name (a live session attaches a
                        // header-only one first); files before the compressed one have
                        // `trace.csv`.
                        if header.name == TRACE_ATTACHMENT {
                            attachments.remove(TRACE_ZSTD_ATTACHMENT);
                        } else if header.name == TRACE_ZSTD_ATTACHMENT {
                            attachments.remove(TRACE_ATTACHMENT);
                        }
                        attachments.insert(header.name, data.into_owned());
                    }
                    Record::Channel(c) => {
                        if c.topic == AIRCRAFT_TOPIC {
                            aircraft_ids.push(c.id);
                        }
                        if c.message_encoding != "json"
                            && (c.topic == AIRCRAFT_TOPIC
                                || c.topic == REFERENCE_TOPIC
                                || matches!(parse_topic(&c.topic), Some(Ok(_))))
                        {
                            return Err(RecordingError::Invalid {
                                path: p,
                                what: format!(
                                    "topic `{}` has message encoding `{}`",
                                    c.topic, c.message_encoding
                                ),
                                expected: "json".into(),
                            });
                        }
                        topics.insert(c.id, c.topic);
                    }
                    Record::Message { header, .. } => {
                        messages += 1;
                        if aircraft_ids.contains(&header.channel_id) {
                            steps += 1;
                            last_log_time = Some(header.log_time);
                        }
                    }
                    _ => {}
                },
            }
        }
        let finished = stopped.is_none();
        let stopped_error = stopped;
        let stopped = stopped_error
            .as_ref()
            .map(|e| format!("after {} bytes: {e}", source.bytes));
        if !topics.values().any(|t| t == REFERENCE_TOPIC) {
            if let (Some(reason), 0) = (stopped_error, messages) {
                // A file that ends early and one with garbage where its records should be
                // are different faults for the user: say which.
                return Err(if matches!(reason, McapError::UnexpectedEof) {
                    RecordingError::Truncated {
                        path: p,
                        bytes: source.bytes,
                        reason: reason.to_string(),
                    }
                } else {
                    RecordingError::Damaged {
                        path: p,
                        bytes: source.bytes,
                        error: reason,
                    }
                });
            }
            let mut names: Vec<&str> = topics.values().map(String::as_str).collect();
            names.dedup();
            let topics = if names.is_empty() {
                "no topics".to_string()
            } else {
                names.join(", ")
            };
            return Err(RecordingError::NotHexcue { path: p, topics });
        }
        let missing = |what: &str| RecordingError::Missing {
            path: p.clone(),
            what: what.to_string(),
        };
        let metadata = metadata.ok_or_else(|| missing("the `hexcue` metadata record"))?;
        if let Some(zst) = attachments.remove(TRACE_ZSTD_ATTACHMENT) {
            let csv = unzstd(&zst).map_err(|e| RecordingError::Invalid {
                path: p.clone(),
                what: format!("attachment `{TRACE_ZSTD_ATTACHMENT}` does not decompress ({e})"),
                expected: "a zstd frame of at most 1 GiB".into(),
            })?;
            attachments.insert(TRACE_ATTACHMENT.to_string(), csv);
        }
        let text = |name: &str| -> Result<Option<String>, RecordingError> {
            attachments
                .get(name)
                .map(|bytes| {
                    String::from_utf8(bytes.clone()).map_err(|e| RecordingError::Invalid {
                        path: p.clone(),
                        what: format!("attachment `{name}` is not UTF-8 ({e})"),
                        expected: "text".into(),
                    })
                })
                .transpose()
        };
        let profile_toml =
            text(PROFILE_ATTACHMENT)?.ok_or_else(|| missing("the `profile.toml` attachment"))?;
        let trace_csv = text(TRACE_ATTACHMENT)?
            .ok_or_else(|| missing("the `trace.csv.zst` (or `trace.csv`) attachment"))?;
        let trace_sidecar = text(SIDECAR_ATTACHMENT)?;
        let field = |key: &str| metadata.get(key).cloned().unwrap_or_default();
        let number = |key: &str| -> Result<Option<f64>, RecordingError> {
            metadata
                .get(key)
                .map(|v| {
                    v.parse::<f64>().map_err(|_| RecordingError::Invalid {
                        path: p.clone(),
                        what: format!("metadata `{key}` is `{v}`"),
                        expected: "a number".into(),
                    })
                })
                .transpose()
        };
        let rate_hz = number("rate_hz")?.ok_or_else(|| missing("metadata `rate_hz`"))?;
        let start_unix_ns = match metadata.get("start_unix_ns") {
            Some(v) => v.parse::<u64>().map_err(|_| RecordingError::Invalid {
                path: p.clone(),
                what: format!("metadata `start_unix_ns` is `{v}`"),
                expected: "an integer (ns)".into(),
            })?,
            None => return Err(missing("metadata `start_unix_ns`")),
        };

        let mut notices = Vec::new();
        let mut algorithms = Vec::new();
        let mut kinds: BTreeMap<AlgorithmId, [bool; 4]> = BTreeMap::new();
        for topic in topics.values() {
            match parse_topic(topic) {
                Some(Ok((id, kind))) => {
                    if !algorithms.contains(&id) {
                        algorithms.push(id);
                    }
                    kinds.entry(id).or_default()[kind] = true;
                }
                Some(Err(alg)) => {
                    let notice = format!(
                        "algorithm `{alg}` is unknown to hexcue {}: its topics are skipped",
                        env!("CARGO_PKG_VERSION")
                    );
                    if !notices.contains(&notice) {
                        notices.push(notice);
                    }
                }
                None => {}
            }
        }
        for (id, found) in &kinds {
            if let Some(kind) = found.iter().position(|f| !f) {
                return Err(missing(&format!(
                    "topic `{}`",
                    Channel::lane(Kind::LANE_JSON[kind], *id).topic()
                )));
            }
        }
        if !topics.values().any(|t| t == AIRCRAFT_TOPIC) {
            return Err(missing(&format!("topic `{AIRCRAFT_TOPIC}`")));
        }
        if let Some(sha) = metadata.get("trace_sha256") {
            if *sha != sha256_hex(&trace_csv) {
                notices.push(
                    "the attached trace does not match the SHA-256 in the metadata".to_string(),
                );
            }
        }
        let profile = parse_profile(&profile_toml, &format!("{p}#{PROFILE_ATTACHMENT}"));
        if let Err(e) = &profile {
            notices.push(format!("the attached profile no longer loads: {e}"));
        }
        if let Some(reason) = &stopped {
            notices.push(format!(
                "the recording was not finished; read up to its last complete chunk ({reason})"
            ));
        }
        let last_t_s =
            last_log_time.map_or(0.0, |t: u64| t.saturating_sub(start_unix_ns) as f64 * 1e-9);
        Ok(Recording {
            path: path.to_path_buf(),
            tool_version: field("tool_version"),
            profile_name: field("profile_name"),
            trace_name: field("trace_name"),
            metadata,
            profile_toml,
            profile,
            trace_csv,
            trace_sidecar,
            rate_hz,
            start_unix_ns,
            algorithms,
            finished,
            stopped,
            steps,
            messages,
            last_t_s,
            notices,
        })
    }

    /// The recorded frames, in order, read from the file as they are needed. For an
    /// unfinished file the iterator ends quietly at the last complete step.
    pub fn frames(&self) -> Result<Frames, RecordingError> {
        Ok(Frames {
            path: shown(&self.path),
            source: RecordSource::open(&self.path)?,
            algorithms: self.algorithms.clone(),
            finished: self.finished,
            channels: BTreeMap::new(),
            pending: None,
            next_k: 0,
            done: false,
        })
    }

    /// Every message of a JSON channel, in file order, read as it is needed; for an
    /// unfinished file the iterator ends quietly where its data end (`hexcue export`).
    pub fn json_messages(&self) -> Result<JsonMessages, RecordingError> {
        Ok(JsonMessages {
            path: shown(&self.path),
            source: RecordSource::open(&self.path)?,
            finished: self.finished,
            channels: BTreeMap::new(),
            done: false,
        })
    }

    /// What to give a [`Recorder`] to write this session again.
    pub fn meta(&self) -> RecordingMeta {
        RecordingMeta {
            profile_name: self.profile_name.clone(),
            profile_toml: self.profile_toml.clone(),
            trace_name: self.trace_name.clone(),
            trace_csv: self.trace_csv.clone(),
            trace_sidecar: self.trace_sidecar.clone(),
            algorithms: self.algorithms.clone(),
            rate_hz: self.rate_hz,
        }
    }
}

#[derive(Default)]
struct PendingLane {
    perceived: Option<PerceivedMsg>,
    platform: Option<PlatformMsg>,
    actuators: Option<ActuatorsMsg>,
    controller: Option<ControllerMsg>,
}

struct PendingStep {
    log_time: u64,
    aircraft: Option<AircraftMsg>,
    reference: Option<PerceivedMsg>,
    lanes: Vec<(AlgorithmId, PendingLane)>,
}

impl PendingStep {
    fn new(log_time: u64) -> Self {
        PendingStep {
            log_time,
            aircraft: None,
            reference: None,
            lanes: Vec::new(),
        }
    }

    fn lane(&mut self, id: AlgorithmId) -> &mut PendingLane {
        let i = match self.lanes.iter().position(|(l, _)| *l == id) {
            Some(i) => i,
            None => {
                self.lanes.push((id, PendingLane::default()));
                self.lanes.len() - 1
            }
        };
        &mut self.lanes[i].1
    }

    fn has(&mut self, role: Role) -> bool {
        match role {
            Role::Aircraft => self.aircraft.is_some(),
            Role::Reference => self.reference.is_some(),
            Role::Lane(id, kind) => {
                let lane = self.lane(id);
                [
                    lane.perceived.is_some(),
                    lane.platform.is_some(),
                    lane.actuators.is_some(),
                    lane.controller.is_some(),
                ][kind]
            }
        }
    }
}

/// One message of a JSON channel: its topic, log time (ns) and the JSON as written.
#[derive(Clone, Debug)]
pub struct JsonMessage {
    pub topic: String,
    pub log_time_ns: u64,
    pub data: Vec<u8>,
}

/// Streams a recording's JSON messages; see [`Recording::json_messages`].
pub struct JsonMessages {
    path: String,
    source: RecordSource,
    finished: bool,
    channels: BTreeMap<u16, String>,
    done: bool,
}

impl Iterator for JsonMessages {
    type Item = Result<JsonMessage, RecordingError>;

    fn next(&mut self) -> Option<Self::Item> {
        while !self.done {
            match self.source.next_record() {
                None => self.done = true,
                // Where an unfinished file's data end, as `Recording::open` found.
                Some(Err(_)) if !self.finished => self.done = true,
                Some(Err(e)) => {
                    self.done = true;
                    return Some(Err(self.source.error(&self.path, e)));
                }
                Some(Ok(Record::Channel(c))) if c.message_encoding == "json" => {
                    self.channels.insert(c.id, c.topic);
                }
                Some(Ok(Record::Message { header, data })) => {
                    if let Some(topic) = self.channels.get(&header.channel_id) {
                        return Some(Ok(JsonMessage {
                            topic: topic.clone(),
                            log_time_ns: header.log_time,
                            data: data.into_owned(),
                        }));
                    }
                }
                Some(Ok(_)) => {}
            }
        }
        None
    }
}

/// Streams a recording's frames; see [`Recording::frames`].
pub struct Frames {
    path: String,
    source: RecordSource,
    algorithms: Vec<AlgorithmId>,
    finished: bool,
    channels: BTreeMap<u16, (Role, String)>,
    pending: Option<PendingStep>,
    next_k: usize,
    done: bool,
}

impl Frames {
    fn parse<T: for<'de> Deserialize<'de>>(
        &self,
        topic: &str,
        log_time: u64,
        data: &[u8],
        expected: &'static str,
    ) -> Result<T, RecordingError> {
        serde_json::from_slice(data).map_err(|e| RecordingError::BadMessage {
            path: self.path.clone(),
            topic: topic.to_string(),
            log_time,
            expected,
            error: e.to_string(),
        })
    }

    fn store(
        &self,
        step: &mut PendingStep,
        role: Role,
        topic: &str,
        data: &[u8],
    ) -> Result<(), RecordingError> {
        let lt = step.log_time;
        match role {
            Role::Aircraft => {
                step.aircraft = Some(self.parse(topic, lt, data, "hexcue.Aircraft")?)
            }
            Role::Reference => {
                step.reference = Some(self.parse(topic, lt, data, "hexcue.Perceived")?)
            }
            Role::Lane(id, 0) => {
                step.lane(id).perceived = Some(self.parse(topic, lt, data, "hexcue.Perceived")?)
            }
            Role::Lane(id, 1) => {
                step.lane(id).platform = Some(self.parse(topic, lt, data, "hexcue.Platform")?)
            }
            Role::Lane(id, 2) => {
                step.lane(id).actuators = Some(self.parse(topic, lt, data, "hexcue.Actuators")?)
            }
            Role::Lane(id, _) => {
                step.lane(id).controller = Some(self.parse(topic, lt, data, "hexcue.Controller")?)
            }
        }
        Ok(())
    }

    /// The frame of a step that has every message, or the topic it lacks.
    fn assemble(&mut self, step: PendingStep) -> Result<Frame, RecordingError> {
        let t_guess = step.log_time as f64 * 1e-9;
        let incomplete = |topic: String, t_s: f64| RecordingError::IncompleteStep {
            path: self.path.clone(),
            t_s,
            topic,
        };
        let aircraft = step
            .aircraft
            .ok_or_else(|| incomplete(AIRCRAFT_TOPIC.into(), t_guess))?;
        let t_s = aircraft.t;
        let reference = step
            .reference
            .ok_or_else(|| incomplete(REFERENCE_TOPIC.into(), t_s))?;
        let mut lanes = Vec::with_capacity(self.algorithms.len());
        for &id in &self.algorithms {
            let lane = step
                .lanes
                .iter()
                .position(|(l, _)| *l == id)
                .map(|i| &step.lanes[i].1);
            let topic = |kind: usize| Channel::lane(Kind::LANE_JSON[kind], id).topic();
            let lane = lane.ok_or_else(|| incomplete(topic(0), t_s))?;
            let perceived = lane
                .perceived
                .as_ref()
                .ok_or_else(|| incomplete(topic(0), t_s))?;
            let platform = lane
                .platform
                .as_ref()
                .ok_or_else(|| incomplete(topic(1), t_s))?;
            let actuators = lane
                .actuators
                .as_ref()
                .ok_or_else(|| incomplete(topic(2), t_s))?;
            let controller = lane
                .controller
                .as_ref()
                .ok_or_else(|| incomplete(topic(3), t_s))?;
            let mode =
                Mode::from_word(&controller.mode).ok_or_else(|| RecordingError::BadMessage {
                    path: self.path.clone(),
                    topic: topic(3),
                    log_time: step.log_time,
                    expected: "hexcue.Controller",
                    error: format!("unknown mode `{}`", controller.mode),
                })?;
            lanes.push((
                step.lanes
                    .iter()
                    .position(|(l, _)| *l == id)
                    .unwrap_or(usize::MAX),
                LaneFrame {
                    id,
                    command: PlatformCommand {
                        pose: platform.pose.into(),
                        velocity: platform.velocity.into(),
                        acceleration: platform.acceleration.into(),
                    },
                    perceived: perceived.perceived(),
                    legs: Legs {
                        length_m: actuators.length.into(),
                        velocity_mps: actuators.velocity.into(),
                        margin_m: actuators.margin.into(),
                    },
                    state: AlgorithmState {
                        mode,
                        blend: controller.blend,
                        time_in_mode_s: controller.time_in_mode_s,
                        switch_count: controller.switch_count,
                        last_switch_reason: controller.last_switch_reason.clone(),
                        solvers: controller
                            .solvers
                            .iter()
                            .map(|s| SolverReport {
                                name: s.name.clone(),
                                status: s.status.as_str().into(),
                                iterations: s.iterations,
                                solve_time_us: s.solve_time_us,
                            })
                            .collect(),
                    },
                    limiter_active: controller.limiter_active,
                    step_time_us: controller.step_time_us,
                },
            ));
        }
        // Lanes in the order the step wrote them, which is the engine's.
        lanes.sort_by_key(|(order, _)| *order);
        let k = aircraft.k.map_or(self.next_k, |k| k as usize);
        self.next_k = k + 1;
        Ok(Frame {
            k,
            t_s,
            aircraft: AircraftSample {
                t_s,
                specific_force_mps2: aircraft.specific_force.into(),
                angular_velocity_radps: aircraft.angular_velocity.into(),
                attitude_rad: aircraft.attitude.into(),
            },
            reference: reference.perceived(),
            lanes: lanes.into_iter().map(|(_, lane)| lane).collect(),
        })
    }

    /// The last step at the end of the data: an unfinished file's may be torn.
    fn last(&mut self) -> Option<Result<Frame, RecordingError>> {
        self.done = true;
        let step = self.pending.take()?;
        match self.assemble(step) {
            Err(RecordingError::IncompleteStep { .. }) if !self.finished => None,
            other => Some(other),
        }
    }
}

impl Iterator for Frames {
    type Item = Result<Frame, RecordingError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        loop {
            let record = match self.source.next_record() {
                None => return self.last(),
                Some(Err(e)) if self.finished => {
                    self.done = true;
                    return Some(Err(self.source.error(&self.path, e)));
                }
                // Where an unfinished file's data ends, as `Recording::open` found.
                Some(Err(_)) => return self.last(),
                Some(Ok(record)) => record,
            };
            match record {
                Record::Channel(c) => {
                    if let Some(role) = role_of(&c.topic, &self.algorithms) {
                        self.channels.insert(c.id, (role, c.topic));
                    }
                }
                Record::Message { header, data } => {
                    let Some((role, topic)) = self.channels.get(&header.channel_id).cloned() else {
                        continue;
                    };
                    // A new log time, or a topic seen twice, starts the next step.
                    let mut ready = None;
                    let starts_new = match &mut self.pending {
                        Some(step) => step.log_time != header.log_time || step.has(role),
                        None => true,
                    };
                    if starts_new {
                        ready = self.pending.replace(PendingStep::new(header.log_time));
                    }
                    let Some(mut step) = self.pending.take() else {
                        continue;
                    };
                    let stored = self.store(&mut step, role, &topic, &data);
                    self.pending = Some(step);
                    if let Err(e) = stored {
                        self.done = true;
                        return Some(Err(e));
                    }
                    if let Some(step) = ready {
                        let frame = self.assemble(step);
                        if frame.is_err() {
                            self.done = true;
                        }
                        return Some(frame);
                    }
                }
                _ => {}
            }
        }
    }
}
