//! The reader: a recording's metadata and attachments, its frames and its JSON messages,
//! streamed record by record.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use mcap::records::Record;
use mcap::McapError;
use nalgebra::Vector6;
use serde::Deserialize;

use super::source::{Item, RecordSource, Skip, SourceError};
use super::{
    meta_key, sha256_hex, shown, RecordingError, RecordingMeta, METADATA_NAME, PROFILE_ATTACHMENT,
    SIDECAR_ATTACHMENT, TRACE_ATTACHMENT, TRACE_ZSTD_ATTACHMENT,
};
use crate::channels::json::{ActuatorsMsg, AircraftMsg, ControllerMsg, PerceivedMsg, PlatformMsg};
use crate::channels::{Channel, Kind, AIRCRAFT_TOPIC, REFERENCE_TOPIC};
use hexcue_core::engine::{Frame, LaneFrame, Legs};
use hexcue_core::mca::{
    AlgorithmId, AlgorithmState, Mode, PlatformCommand, QpName, SolveStatus, SolverReport,
    SwitchReason,
};
use hexcue_core::profile::text::{parse_profile, ProfileLoadError};
use hexcue_core::profile::Profile;
use hexcue_core::trace::AircraftSample;

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

/// A stretch of intact data between skipped bytes.
#[derive(Default)]
struct Segment {
    channels: BTreeSet<u16>,
    /// The first and last step: its index (when the message has one) and log time (ns).
    first: Option<(Option<u64>, u64)>,
    last: Option<(Option<u64>, u64)>,
}

/// The step of an `/aircraft` message: its index, when written, and its log time.
fn step_of(aircraft: &[u8], log_time: Option<u64>) -> Option<(Option<u64>, u64)> {
    let log_time = log_time?;
    let k = serde_json::from_slice::<AircraftMsg>(aircraft)
        .ok()
        .and_then(|m| m.k);
    Some((k, log_time))
}

pub use super::damage::{Damage, LostSteps};

pub use hexcue_core::vocab::plural;

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
    /// Stretches of a damaged file that could not be read and were skipped, with what they
    /// held; empty for an intact file.
    pub damage: Vec<Damage>,
    /// JSON channels by id, from anywhere in the file (its summary repeats them), so that
    /// the chunks after a damaged first one still read.
    json_channels: BTreeMap<u16, String>,
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
        let mut json_channels: BTreeMap<u16, String> = BTreeMap::new();
        // The summary's message counts per channel, when it was read: they tell how many
        // steps a damage that runs to the end of the data took.
        let mut statistics: Option<BTreeMap<u16, u64>> = None;
        let mut skip_in_summary: Vec<bool> = Vec::new();
        // Stretches of intact data between skipped bytes: the topics each carried and its first
        // and last step, to say what a skip lost.
        let mut segments = vec![Segment::default()];
        let mut skips: Vec<Skip> = Vec::new();
        let mut data_ended = false;
        let mut last_aircraft: Vec<u8> = Vec::new();
        let mut first_after_skip = false;
        let mut segment_last_time = None;
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
                Some(Err(SourceError::Mcap(_))) => return Err(RecordingError::NotMcap { path: p }),
                Some(Ok(Item::Skipped(skip))) => {
                    if source.bytes < mcap::MAGIC.len() as u64
                        && skip.from_byte <= 8
                        && messages == 0
                    {
                        return Err(RecordingError::NotMcap { path: p });
                    }
                    if let Some(seg) = segments.last_mut() {
                        seg.last = step_of(&last_aircraft, segment_last_time.take());
                    }
                    skips.push(skip);
                    skip_in_summary.push(data_ended);
                    segments.push(Segment::default());
                    first_after_skip = true;
                }
                Some(Ok(Item::Record(record))) => match record {
                    Record::DataEnd(_) => data_ended = true,
                    Record::Statistics(s) => statistics = Some(s.channel_message_counts),
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
                        if c.topic == AIRCRAFT_TOPIC && !aircraft_ids.contains(&c.id) {
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
                        if c.message_encoding == "json" {
                            json_channels.insert(c.id, c.topic.clone());
                        }
                        topics.insert(c.id, c.topic);
                    }
                    Record::Message { header, data } => {
                        messages += 1;
                        if let Some(seg) = segments.last_mut() {
                            seg.channels.insert(header.channel_id);
                        }
                        if aircraft_ids.contains(&header.channel_id) {
                            steps += 1;
                            last_log_time = Some(header.log_time);
                            segment_last_time = last_log_time;
                            last_aircraft.clear();
                            last_aircraft.extend_from_slice(&data);
                            if first_after_skip {
                                first_after_skip = false;
                                if let Some(seg) = segments.last_mut() {
                                    seg.first = step_of(&last_aircraft, last_log_time);
                                }
                            }
                        }
                    }
                    _ => {}
                },
            }
        }
        if let Some(seg) = segments.last_mut() {
            seg.last = step_of(&last_aircraft, segment_last_time);
        }
        // A file closed properly ends with the magic: then any skip is damage done to it
        // afterwards, not a session cut short.
        let closed = source.ended || source.tail_is_magic();
        let cut = match skips.last() {
            Some(last) if !last.resumed && !closed => skips.pop(),
            _ => None,
        };
        let finished = cut.is_none();
        let stopped = cut
            .as_ref()
            .map(|c| format!("after {} bytes: {}", c.from_byte, c.error));
        if !topics.values().any(|t| t == REFERENCE_TOPIC) {
            let first_skip = cut.or_else(|| skips.into_iter().next());
            if let (Some(skip), 0) = (first_skip, messages) {
                // A file that ends early and one with garbage where its records should be
                // are different faults for the user: say which.
                return Err(if matches!(skip.error, McapError::UnexpectedEof) {
                    RecordingError::Truncated {
                        path: p,
                        bytes: source.bytes,
                        reason: skip.error.to_string(),
                    }
                } else {
                    RecordingError::Damaged {
                        path: p,
                        bytes: skip.from_byte,
                        error: skip.error,
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
        let rate_hz = number(meta_key::RATE_HZ)?
            .ok_or_else(|| missing(&format!("metadata `{}`", meta_key::RATE_HZ)))?;
        let start_unix_ns = match metadata.get(meta_key::START_UNIX_NS) {
            Some(v) => v.parse::<u64>().map_err(|_| RecordingError::Invalid {
                path: p.clone(),
                what: format!("metadata `{}` is `{v}`", meta_key::START_UNIX_NS),
                expected: "an integer (ns)".into(),
            })?,
            None => return Err(missing(&format!("metadata `{}`", meta_key::START_UNIX_NS))),
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
        if let Some(sha) = metadata.get(meta_key::TRACE_SHA256) {
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
        let time_of = |log_time: u64| log_time.saturating_sub(start_unix_ns) as f64 * 1e-9;
        let topic_names = |ids: &mut dyn Iterator<Item = &u16>| -> Vec<String> {
            let mut names: Vec<String> = ids.filter_map(|id| topics.get(id).cloned()).collect();
            names.sort();
            names.dedup();
            names
        };
        let recorded_topics = {
            let mut all: BTreeSet<u16> = BTreeSet::new();
            for seg in &segments {
                all.extend(seg.channels.iter().copied());
            }
            topic_names(&mut all.iter()).len()
        };
        let mut damage = Vec::new();
        for (i, skip) in skips.into_iter().enumerate() {
            let (before, after) = (&segments[i], segments.get(i + 1));
            let in_summary = skip_in_summary.get(i).copied().unwrap_or(false);
            let resumed_steps = after.and_then(|a| a.first).filter(|_| skip.resumed);
            let lost = if in_summary {
                None
            } else {
                // The step after the last one kept, up to the one before the first kept.
                let (first_k, from_t_s) = match before.last {
                    Some((k, t)) => (k.map(|k| k + 1), time_of(t) + 1.0 / rate_hz),
                    None => (Some(0), 0.0),
                };
                match resumed_steps {
                    Some((k_after, t_after)) => {
                        let to_t_s = time_of(t_after) - 1.0 / rate_hz;
                        let count = match (first_k, k_after) {
                            (Some(a), Some(b)) => b.saturating_sub(a),
                            _ => ((to_t_s - from_t_s) * rate_hz).round().max(-1.0) as u64 + 1,
                        };
                        (count > 0).then_some(LostSteps {
                            first_k,
                            count: Some(count),
                            from_t_s,
                            to_t_s: Some(to_t_s),
                        })
                    }
                    None => Some(LostSteps {
                        first_k,
                        count: None,
                        from_t_s,
                        to_t_s: None,
                    }),
                }
            };
            let topics_lost = match (&lost, after) {
                (None, _) => Vec::new(),
                (Some(_), Some(a)) if resumed_steps.is_some() => {
                    topic_names(&mut before.channels.intersection(&a.channels))
                }
                (Some(_), _) => topic_names(&mut before.channels.iter()),
            };
            damage.push(Damage {
                from_byte: skip.from_byte,
                to_byte: skip.to_byte,
                error: skip.error.to_string(),
                steps: lost,
                every_topic: topics_lost.len() == recorded_topics,
                topics: topics_lost,
            });
        }
        // A damage running to the end of the data took the steps the summary counts beyond
        // those found and those the other damaged parts took.
        let written_steps: Option<u64> = statistics
            .as_ref()
            .map(|counts| aircraft_ids.iter().filter_map(|id| counts.get(id)).sum());
        if let Some(written) = written_steps {
            let known: u64 = damage
                .iter()
                .filter_map(|d| d.steps.as_ref().and_then(|s| s.count))
                .sum();
            let open_ended: Vec<usize> = damage
                .iter()
                .enumerate()
                .filter(|(_, d)| d.steps.as_ref().is_some_and(|s| s.count.is_none()))
                .map(|(i, _)| i)
                .collect();
            if let [only] = open_ended[..] {
                let count = written.saturating_sub(steps + known);
                if let Some(lost) = damage[only].steps.as_mut() {
                    lost.count = Some(count);
                    lost.to_t_s = Some(lost.from_t_s + (count.max(1) - 1) as f64 / rate_hz);
                }
            }
        }
        for d in &damage {
            notices.push(d.describe());
        }
        let last_t_s =
            last_log_time.map_or(0.0, |t: u64| t.saturating_sub(start_unix_ns) as f64 * 1e-9);
        Ok(Recording {
            path: path.to_path_buf(),
            tool_version: field(meta_key::TOOL_VERSION),
            profile_name: field(meta_key::PROFILE_NAME),
            trace_name: field(meta_key::TRACE_NAME),
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
            damage,
            json_channels,
            steps,
            messages,
            last_t_s,
            notices,
        })
    }

    /// The recorded frames, in order, read from the file as they are needed. For an
    /// unfinished file the iterator ends quietly at the last complete step.
    pub fn frames(&self) -> Result<Frames, RecordingError> {
        let channels = self
            .json_channels
            .iter()
            .filter_map(|(id, topic)| {
                role_of(topic, &self.algorithms).map(|role| (*id, (role, topic.clone())))
            })
            .collect();
        Ok(Frames {
            path: shown(&self.path),
            source: RecordSource::open(&self.path)?,
            algorithms: self.algorithms.clone(),
            finished: self.finished,
            lenient: false,
            channels,
            pending: None,
            next_k: 0,
            done: false,
            stewart: self.profile.as_ref().ok().map(|p| p.stewart()),
        })
    }

    /// Every message of a JSON channel, in file order, read as it is needed; for an
    /// unfinished file the iterator ends quietly where its data end (`hexcue export`).
    pub fn json_messages(&self) -> Result<JsonMessages, RecordingError> {
        Ok(JsonMessages {
            path: shown(&self.path),
            source: RecordSource::open(&self.path)?,
            channels: self.json_channels.clone(),
            done: false,
        })
    }

    /// Steps lost to damage: `None` when none was, `Some(None)` when the damage runs to the
    /// end of the file and their number is unknown.
    pub fn lost_steps(&self) -> Option<Option<u64>> {
        let lost: Vec<&LostSteps> = self
            .damage
            .iter()
            .filter_map(|d| d.steps.as_ref())
            .collect();
        if lost.is_empty() {
            return None;
        }
        Some(lost.iter().map(|l| l.count).sum())
    }

    /// For the commands that read what is left (`review --headless`, `export`, `plot`): after
    /// their output is written, the error that makes them exit non-zero when steps were lost,
    /// so that a script does not take the output for the whole flight (as `recover` does).
    /// `output` says what holds the intact steps ("the summary", "the CSV").
    pub fn lost_error(&self, output: &str) -> Option<String> {
        let lost = self.lost_steps()?;
        let what = match lost {
            Some(n) => hexcue_core::vocab::plural(n, "step"),
            None => "the steps after the damage".to_string(),
        };
        let parts = self.damage.iter().filter(|d| d.steps.is_some()).count();
        Some(format!(
            "{}: damaged: {what} lost in {}; {output} holds every intact one",
            self.path.display(),
            hexcue_core::vocab::plural(parts as u64, "damaged part")
        ))
    }

    /// One warning per damaged part, for the commands that read what is left.
    pub fn damage_warnings(&self) -> impl Iterator<Item = String> + '_ {
        self.damage.iter().map(move |d| {
            format!(
                "warning: {}: {}; reading the rest",
                self.path.display(),
                d.describe()
            )
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
            profile: self.profile.as_ref().ok().cloned(),
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
    channels: BTreeMap<u16, String>,
    done: bool,
}

impl Iterator for JsonMessages {
    type Item = Result<JsonMessage, RecordingError>;

    fn next(&mut self) -> Option<Self::Item> {
        while !self.done {
            match self.source.next_record() {
                None => self.done = true,
                Some(Err(e)) => {
                    self.done = true;
                    return Some(Err(self.source.error(&self.path, e)));
                }
                // What was skipped is in `Recording::damage`, as `Recording::open` found.
                Some(Ok(Item::Skipped(_))) => {}
                Some(Ok(Item::Record(Record::Channel(c)))) if c.message_encoding == "json" => {
                    self.channels.insert(c.id, c.topic);
                }
                Some(Ok(Item::Record(Record::Message { header, data }))) => {
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
    /// After skipped bytes: the steps either side of them may have lost some messages, and
    /// are then left out rather than taken for a fault.
    lenient: bool,
    channels: BTreeMap<u16, (Role, String)>,
    pending: Option<PendingStep>,
    next_k: usize,
    done: bool,
    /// The rig of the attached profile, for the leg margins (not recorded since format 2).
    stewart: Option<hexcue_core::model::stewart::Stewart>,
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

    /// The legs' margins: as recorded (format 1), or, not written since, from the lengths
    /// and the attached profile's stroke, as the engine computes them (NaN when the profile
    /// no longer loads).
    fn margins(&self, actuators: &ActuatorsMsg) -> Vector6<f64> {
        let recorded: Vector6<f64> = actuators.margin.into();
        match &self.stewart {
            Some(stewart) if recorded.iter().all(|m| m.is_nan()) => {
                stewart.margins(&actuators.length.into())
            }
            _ => recorded,
        }
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
                        margin_m: self.margins(actuators),
                    },
                    state: AlgorithmState {
                        mode,
                        blend: controller.blend,
                        time_in_mode_s: controller.time_in_mode_s,
                        switch_count: controller.switch_count,
                        last_switch_reason: controller
                            .last_switch_reason
                            .as_deref()
                            .map(SwitchReason::parse),
                        solvers: controller
                            .solvers
                            .iter()
                            .map(|s| SolverReport {
                                name: QpName::from_word(&s.name),
                                status: SolveStatus::from_word(&s.status),
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
            Err(RecordingError::IncompleteStep { .. }) if !self.finished || self.lenient => None,
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
                Some(Err(e)) => {
                    self.done = true;
                    return Some(Err(self.source.error(&self.path, e)));
                }
                // Skipped bytes (damage, or where an unfinished file's data end), as
                // `Recording::open` found: the step they cut is left out.
                Some(Ok(Item::Skipped(_))) => {
                    self.lenient = true;
                    if let Some(step) = self.pending.take() {
                        match self.assemble(step) {
                            Err(RecordingError::IncompleteStep { .. }) => {}
                            Ok(frame) => return Some(Ok(frame)),
                            Err(e) => {
                                self.done = true;
                                return Some(Err(e));
                            }
                        }
                    }
                    continue;
                }
                Some(Ok(Item::Record(record))) => record,
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
                        match frame {
                            Err(RecordingError::IncompleteStep { .. }) if self.lenient => continue,
                            Err(_) => self.done = true,
                            Ok(_) => self.lenient = false,
                        }
                        return Some(frame);
                    }
                }
                _ => {}
            }
        }
    }
}
