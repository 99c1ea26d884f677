//! The table of channels: every topic a session publishes, with its schema and how a frame
//! becomes its messages. The recorder (`formats::recording`), the live Foxglove server and
//! the recording's readers (review, export, recover) all take their topics from here, so a
//! layout made for a recording works on a live session and a reader never meets a topic the
//! writer spells differently.
//!
//! It sits below both the file formats and the Foxglove server and imports neither, so that
//! they share it without reaching each other.
//!
//! - [`json`]: hexcue's own topics, JSON with `jsonschema` schemas.
//! - [`scene`]: the platforms in Foxglove's well-known messages (protobuf).

pub mod json;
pub mod scene;

use ::foxglove::messages::{FrameTransforms, Log, SceneUpdate};
use ::foxglove::Encode;

use hexcue_core::mca::AlgorithmId;

/// What a topic carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Kind {
    /// `/aircraft`: the aircraft's motion at the pilot's head.
    Aircraft,
    /// `/aircraft/perceived`: what the pilot feels in the aircraft.
    Reference,
    /// `/ALG/perceived`: what the pilot feels on the platform.
    Perceived,
    /// `/ALG/platform`: the platform command after the limiter.
    Platform,
    /// `/ALG/actuators`: the six legs.
    Actuators,
    /// `/ALG/controller`: the algorithm's state and solvers.
    Controller,
    /// `/tf`: where each rig stands and how its platform is placed (every algorithm's
    /// frames in one message: docs/recordings.md, "One /tf and one /scene").
    Tf,
    /// `/scene`: what the rigs look like (every algorithm's entities in one message).
    Scene,
    /// `/events`: what happened, from every algorithm and the session.
    Events,
}

impl Kind {
    /// The JSON kinds, one for each JSON schema, in the order a recording adds the schemas.
    pub const JSON_SCHEMAS: [Kind; 5] = [
        Kind::Aircraft,
        Kind::Perceived,
        Kind::Platform,
        Kind::Actuators,
        Kind::Controller,
    ];
    /// Foxglove's kinds, in the order a recording adds their schemas.
    pub const SCENE_SCHEMAS: [Kind; 3] = [Kind::Tf, Kind::Scene, Kind::Events];
    /// Each algorithm's JSON topics, in the order a step writes them.
    pub const LANE_JSON: [Kind; 4] = [
        Kind::Perceived,
        Kind::Platform,
        Kind::Actuators,
        Kind::Controller,
    ];

    pub fn is_json(self) -> bool {
        !matches!(self, Kind::Tf | Kind::Scene | Kind::Events)
    }

    /// The last part of an algorithm's topic: `/ALG/SUFFIX`.
    pub fn lane_suffix(self) -> Option<&'static str> {
        Some(match self {
            Kind::Perceived => "perceived",
            Kind::Platform => "platform",
            Kind::Actuators => "actuators",
            Kind::Controller => "controller",
            Kind::Aircraft | Kind::Reference | Kind::Events | Kind::Tf | Kind::Scene => {
                return None
            }
        })
    }

    pub fn schema_name(self) -> &'static str {
        match self {
            Kind::Aircraft => "hexcue.Aircraft",
            Kind::Reference | Kind::Perceived => "hexcue.Perceived",
            Kind::Platform => "hexcue.Platform",
            Kind::Actuators => "hexcue.Actuators",
            Kind::Controller => "hexcue.Controller",
            Kind::Tf => "foxglove.FrameTransforms",
            Kind::Scene => "foxglove.SceneUpdate",
            Kind::Events => "foxglove.Log",
        }
    }

    /// The messages' encoding: `json` or `protobuf`.
    pub fn message_encoding(self) -> &'static str {
        if self.is_json() {
            "json"
        } else {
            "protobuf"
        }
    }

    /// The schema as a recording stores it and the server advertises it.
    pub fn schema(self) -> Schema {
        let well_known = |s: Option<::foxglove::Schema>| {
            // Every message of the crate has its schema; `None` would be a custom type.
            let s = s.unwrap_or_else(|| unreachable!("a well-known message"));
            (s.encoding, s.data.into_owned())
        };
        let (encoding, data) = match self {
            Kind::Tf => well_known(FrameTransforms::get_schema()),
            Kind::Scene => well_known(SceneUpdate::get_schema()),
            Kind::Events => well_known(Log::get_schema()),
            _ => (
                "jsonschema".to_string(),
                json::schema_of(self).unwrap_or_default(),
            ),
        };
        Schema {
            name: self.schema_name(),
            encoding,
            data,
        }
    }
}

/// A schema: its name, its encoding (`jsonschema`, `protobuf`) and its text.
#[derive(Clone, Debug, PartialEq)]
pub struct Schema {
    pub name: &'static str,
    pub encoding: String,
    pub data: Vec<u8>,
}

/// One channel: a kind, and the algorithm for the kinds each algorithm has.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Channel {
    pub kind: Kind,
    pub lane: Option<AlgorithmId>,
}

impl Channel {
    pub const AIRCRAFT: Channel = Channel {
        kind: Kind::Aircraft,
        lane: None,
    };
    pub const REFERENCE: Channel = Channel {
        kind: Kind::Reference,
        lane: None,
    };
    pub const EVENTS: Channel = Channel {
        kind: Kind::Events,
        lane: None,
    };
    pub const TF: Channel = Channel {
        kind: Kind::Tf,
        lane: None,
    };
    pub const SCENE: Channel = Channel {
        kind: Kind::Scene,
        lane: None,
    };

    /// An algorithm's channel of `kind`.
    pub fn lane(kind: Kind, id: AlgorithmId) -> Channel {
        Channel {
            kind,
            lane: Some(id),
        }
    }

    pub fn topic(&self) -> String {
        match (self.kind, self.lane) {
            (Kind::Aircraft, _) => AIRCRAFT_TOPIC.to_string(),
            (Kind::Reference, _) => REFERENCE_TOPIC.to_string(),
            (Kind::Events, _) => EVENTS_TOPIC.to_string(),
            (Kind::Tf, _) => TF_TOPIC.to_string(),
            (Kind::Scene, _) => SCENE_TOPIC.to_string(),
            (kind, lane) => format!(
                "/{}/{}",
                lane.map_or("?", |id| id.key()),
                kind.lane_suffix().unwrap_or("?")
            ),
        }
    }

    /// An algorithm's topic `/ALG/SUFFIX`: its kind and the algorithm's key, which may be one
    /// this build does not know. `None` for any other topic.
    pub fn parse_lane(topic: &str) -> Option<(Kind, Result<AlgorithmId, &str>)> {
        let rest = topic.strip_prefix('/')?;
        let (alg, suffix) = rest.split_once('/')?;
        if alg == "aircraft" {
            return None;
        }
        let kind = Kind::LANE_JSON
            .into_iter()
            .find(|k| k.lane_suffix() == Some(suffix))?;
        Some((kind, AlgorithmId::from_key(alg).ok_or(alg)))
    }
}

pub const AIRCRAFT_TOPIC: &str = "/aircraft";
pub const REFERENCE_TOPIC: &str = "/aircraft/perceived";
/// Where events go, from every algorithm and from the session.
pub const EVENTS_TOPIC: &str = "/events";
/// Every rig's transforms: recordings of format 2 and before had one `/ALG/tf` each.
pub const TF_TOPIC: &str = "/tf";
/// Every rig's scene entities: recordings of format 2 and before had one `/ALG/scene` each.
pub const SCENE_TOPIC: &str = "/scene";

/// Every channel of a session of `algorithms`, in the order a recording adds them: hexcue's
/// JSON topics (the aircraft, the reference, each algorithm's four), then Foxglove's (the
/// events, every algorithm's transforms and every algorithm's scene).
pub fn session(algorithms: &[AlgorithmId]) -> Vec<Channel> {
    let mut out = vec![Channel::AIRCRAFT, Channel::REFERENCE];
    for &id in algorithms {
        out.extend(Kind::LANE_JSON.map(|k| Channel::lane(k, id)));
    }
    out.push(Channel::EVENTS);
    if !algorithms.is_empty() {
        out.extend([Channel::TF, Channel::SCENE]);
    }
    out
}

/// An algorithm's colour, from its place in [`AlgorithmId::ALL`] so that it is the same in
/// every figure and in Foxglove whatever subset was recorded (Okabe–Ito colours:
/// distinguishable with the common colour-vision deficiencies).
pub fn algorithm_rgb(id: AlgorithmId) -> (u8, u8, u8) {
    const PALETTE: [(u8, u8, u8); 6] = [
        (0, 114, 178),
        (213, 94, 0),
        (0, 158, 115),
        (204, 121, 167),
        (230, 159, 0),
        (86, 180, 233),
    ];
    let i = AlgorithmId::ALL.iter().position(|a| *a == id).unwrap_or(0);
    PALETTE[i % PALETTE.len()]
}

/// Where a recorder hands each message it has encoded, so that a live viewer fed the same
/// frames gets the same bytes at the same log times without encoding them again
/// (`play --headless --record --foxglove`: `sinks::recorder::RecordedAndServed`).
pub trait MessageTap {
    /// Whether anyone listens on `channel`; a message nobody wants is not handed over.
    fn wants(&mut self, channel: Channel) -> bool;
    /// Whether the 3D topics should be drawn at this step though the recording skips it (a
    /// live viewer shows every step).
    fn wants_every_scene(&mut self) -> bool;
    /// One encoded message on `channel`.
    fn message(&mut self, channel: Channel, bytes: &[u8], log_time_ns: u64);
    /// Every message of the step at `log_time_ns` has been handed over.
    fn step_done(&mut self, log_time_ns: u64);
}

/// One of Foxglove's well-known messages of a step, to encode for its channel.
#[derive(Clone, Copy, Debug)]
pub enum SceneMessage<'a> {
    Tf(&'a FrameTransforms),
    Scene(&'a SceneUpdate),
    Log(&'a Log),
}

#[derive(Debug, thiserror::Error)]
#[error("cannot encode a {schema} message: {error}")]
pub struct EncodeError {
    pub schema: &'static str,
    pub error: String,
}

impl SceneMessage<'_> {
    /// Encodes the message (protobuf) into `buf`, which is cleared first.
    pub fn encode(&self, buf: &mut Vec<u8>) -> Result<(), EncodeError> {
        buf.clear();
        let failed = |schema, e: &dyn std::fmt::Display| EncodeError {
            schema,
            error: e.to_string(),
        };
        match self {
            SceneMessage::Tf(m) => m
                .encode(buf)
                .map_err(|e| failed(Kind::Tf.schema_name(), &e)),
            SceneMessage::Scene(m) => m
                .encode(buf)
                .map_err(|e| failed(Kind::Scene.schema_name(), &e)),
            SceneMessage::Log(m) => m
                .encode(buf)
                .map_err(|e| failed(Kind::Events.schema_name(), &e)),
        }
    }
}

impl scene::StepMessages {
    /// The step's messages by channel: every lane's transforms and scene when they were
    /// drawn, then the events.
    pub fn by_channel(&self) -> impl Iterator<Item = (Channel, SceneMessage<'_>)> {
        let drawn = self.drawn.iter().flat_map(|d| {
            [
                (Channel::TF, SceneMessage::Tf(&d.transforms)),
                (Channel::SCENE, SceneMessage::Scene(&d.scene)),
            ]
        });
        let events = self
            .events
            .iter()
            .map(|e| (Channel::EVENTS, SceneMessage::Log(e)));
        drawn.chain(events)
    }
}
