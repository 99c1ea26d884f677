//! A frame sink that serves a session live over the Foxglove WebSocket protocol, with the
//! `foxglove` crate's server: the recording's channels (hexcue's JSON topics and the 3D
//! topics of [`super::scene`]) with the same schemas, so that a layout made for recordings
//! works on a live session too.
//!
//! Attach it to any loop that makes frames: call [`FoxgloveServer::publish`] with each frame
//! and [`FoxgloveServer::event`] for what the session wants the viewer to know (input lost,
//! e-stop, …). Publishing to no client costs the scene's construction only: the crate encodes
//! a message only for a channel that a client has subscribed.

use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::sync::Arc;

use ::foxglove::messages::{FrameTransforms, Log, SceneUpdate};
use ::foxglove::websocket::Capability;
use ::foxglove::{
    Channel, Context, FoxgloveError, PartialMetadata, RawChannel, Schema, WebSocketServer,
    WebSocketServerHandle,
};

use super::scene::{self, SceneBuilder, SESSION_SOURCE};
use crate::engine::Frame;
use crate::events::EventLevel;
use crate::formats::recording::{json_messages, json_schemas};
use crate::mca::AlgorithmId;
use crate::profile::Profile;

/// Where `--foxglove` listens when given no address: Foxglove's default.
pub const DEFAULT_ADDR: &str = "127.0.0.1:8765";

/// Messages a slow client may fall behind by before the oldest are dropped (a second of
/// three algorithms at 100 Hz).
const BACKLOG: usize = 4096;

#[derive(Debug, thiserror::Error)]
pub enum ServerError {
    #[error("--foxglove {addr}: cannot serve the Foxglove WebSocket there: {error}")]
    Start {
        addr: SocketAddr,
        error: FoxgloveError,
    },
    #[error("--foxglove: cannot create the channel `{topic}`: {error}")]
    Channel { topic: String, error: FoxgloveError },
}

/// Log times that only move forward: trace time from the server's start, carried on across
/// a rewind or a new run so that a viewer never sees time go back.
#[derive(Clone, Debug)]
struct Clock {
    origin_ns: u64,
    last_ns: Option<u64>,
    step_ns: u64,
}

impl Clock {
    fn at(&mut self, t_s: f64) -> u64 {
        let t_ns = |origin: u64| origin.saturating_add((t_s.max(0.0) * 1e9).round() as u64);
        let mut now = t_ns(self.origin_ns);
        if let Some(last) = self.last_ns.filter(|last| now <= *last) {
            // Trace time went back (a rewind, a loop): continue one step after the last.
            self.origin_ns = self.origin_ns.saturating_add(last + self.step_ns - now);
            now = t_ns(self.origin_ns);
        }
        self.last_ns = Some(now);
        now
    }
}

struct LaneChannels {
    tf: Channel<FrameTransforms>,
    scene: Channel<SceneUpdate>,
}

/// The live Foxglove server of one session.
pub struct FoxgloveServer {
    context: Arc<Context>,
    handle: Option<WebSocketServerHandle>,
    addr: SocketAddr,
    builder: SceneBuilder,
    json: BTreeMap<String, Arc<RawChannel>>,
    schemas: BTreeMap<&'static str, Vec<u8>>,
    lanes: BTreeMap<AlgorithmId, LaneChannels>,
    events: Channel<Log>,
    clock: Clock,
}

impl FoxgloveServer {
    /// Starts serving on `addr` (port 0: any free port; see [`FoxgloveServer::addr`]) the
    /// channels of a session of `algorithms` on `profile`'s rig.
    pub fn start(
        addr: SocketAddr,
        profile: &Profile,
        algorithms: &[AlgorithmId],
    ) -> Result<Self, ServerError> {
        let context = Context::new();
        let events = context.channel_builder(scene::EVENTS_TOPIC).build::<Log>();
        let start_ns = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(1, |d| d.as_nanos().min(u128::from(u64::MAX / 2)) as u64);
        let mut server = FoxgloveServer {
            handle: None,
            addr,
            builder: SceneBuilder::new(profile, algorithms),
            json: BTreeMap::new(),
            schemas: json_schemas().into_iter().collect(),
            lanes: BTreeMap::new(),
            events,
            clock: Clock {
                origin_ns: start_ns,
                last_ns: None,
                step_ns: (1e9 / profile.rate_hz.max(1e-3)).round() as u64,
            },
            context,
        };
        // Every channel exists before the first client comes, so that it sees them all.
        let topics: Vec<(String, &'static str)> = json_topics(algorithms);
        for (topic, schema) in topics {
            server.json_channel(&topic, schema)?;
        }
        for &id in algorithms {
            server.lane(id);
        }
        let info = [
            ("hexcue_version", env!("CARGO_PKG_VERSION").to_string()),
            ("profile", profile.name.clone()),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect();
        let handle = WebSocketServer::new()
            .name(format!("hexcue {}", env!("CARGO_PKG_VERSION")))
            .bind(addr.ip().to_string(), addr.port())
            .context(&server.context)
            .capabilities([Capability::Time])
            .server_info(info)
            .message_backlog_size(BACKLOG)
            .start_blocking()
            .map_err(|error| ServerError::Start { addr, error })?;
        server.addr = SocketAddr::new(addr.ip(), handle.port());
        server.handle = Some(handle);
        Ok(server)
    }

    /// Where the server listens (the port chosen when asked for port 0).
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Clients connected now.
    pub fn clients(&self) -> usize {
        self.handle.as_ref().map_or(0, |h| h.client_count())
    }

    fn json_channel(
        &mut self,
        topic: &str,
        schema: &'static str,
    ) -> Result<Arc<RawChannel>, ServerError> {
        if let Some(ch) = self.json.get(topic) {
            return Ok(ch.clone());
        }
        let data = self.schemas.get(schema).cloned().unwrap_or_default();
        let channel = self
            .context
            .channel_builder(topic)
            .message_encoding("json")
            .schema(Schema::new(schema, "jsonschema", data))
            .build_raw()
            .map_err(|error| ServerError::Channel {
                topic: topic.to_string(),
                error,
            })?;
        self.json.insert(topic.to_string(), channel.clone());
        Ok(channel)
    }

    fn lane(&mut self, id: AlgorithmId) -> &LaneChannels {
        let context = &self.context;
        self.lanes.entry(id).or_insert_with(|| LaneChannels {
            tf: context.channel_builder(scene::tf_topic(id)).build(),
            scene: context.channel_builder(scene::scene_topic(id)).build(),
        })
    }

    /// Sends one frame on every channel (to the clients subscribed to it).
    pub fn publish(&mut self, frame: &Frame) {
        let t_ns = self.clock.at(frame.t_s);
        let meta = || PartialMetadata::with_log_time(t_ns);
        if self.json.values().any(|c| c.has_sinks()) {
            // Only a serialisation error (none for these messages) would skip the step.
            if let Ok(messages) = json_messages(frame) {
                for (topic, schema, data) in messages {
                    if let Ok(channel) = self.json_channel(&topic, schema) {
                        channel.log_with_meta(&data, meta());
                    }
                }
            }
        }
        let step = self.builder.step(frame, t_ns);
        for lane in &step.lanes {
            let channels = self.lane(lane.id);
            channels.tf.log_with_time(&lane.transforms, t_ns);
            channels.scene.log_with_time(&lane.scene, t_ns);
        }
        for event in &step.events {
            self.events.log_with_time(event, t_ns);
        }
        if let Some(handle) = &self.handle {
            handle.broadcast_time(t_ns);
        }
    }

    /// Sends an event of the session on `/events`, at the time of the last frame.
    pub fn event(&mut self, level: EventLevel, text: &str) {
        let t_ns = self.clock.last_ns.unwrap_or(self.clock.origin_ns);
        self.events
            .log_with_time(&scene::event(t_ns, level, SESSION_SOURCE, text), t_ns);
    }

    /// The next frame starts a new run (the source rewound): no changes are reported
    /// between the two runs.
    pub fn restart(&mut self) {
        self.builder.reset();
    }

    /// Stops serving and waits for the connections to close.
    pub fn stop(mut self) {
        if let Some(handle) = self.handle.take() {
            handle.stop().wait_blocking();
        }
    }
}

impl Drop for FoxgloveServer {
    fn drop(&mut self) {
        // The crate's server outlives its handle; a sink that goes away must not.
        if let Some(handle) = self.handle.take() {
            handle.stop().wait_blocking();
        }
    }
}

/// The live Foxglove server as a frame sink attached for a whole session: the console's
/// playback and review, and `hexcue live` (whose events go to `/events`).
impl crate::session::FrameSink for FoxgloveServer {
    fn record(&mut self, frame: &Frame) -> anyhow::Result<()> {
        self.publish(frame);
        Ok(())
    }

    fn finish(self: Box<Self>) -> anyhow::Result<String> {
        let addr = self.addr();
        self.stop();
        Ok(format!("foxglove: stopped serving ws://{addr}"))
    }

    fn rewound(&mut self) {
        self.restart();
    }

    fn event(&mut self, event: &crate::events::Event) -> anyhow::Result<()> {
        FoxgloveServer::event(self, event.level, &event.text);
        Ok(())
    }
}

/// hexcue's own topics for `algorithms`, with their schema names, in the recorder's order.
fn json_topics(algorithms: &[AlgorithmId]) -> Vec<(String, &'static str)> {
    let mut out = vec![
        ("/aircraft".to_string(), "hexcue.Aircraft"),
        ("/aircraft/perceived".to_string(), "hexcue.Perceived"),
    ];
    for id in algorithms {
        let key = id.key();
        out.extend([
            (format!("/{key}/perceived"), "hexcue.Perceived"),
            (format!("/{key}/platform"), "hexcue.Platform"),
            (format!("/{key}/actuators"), "hexcue.Actuators"),
            (format!("/{key}/controller"), "hexcue.Controller"),
        ]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_times_never_go_back() {
        let mut c = Clock {
            origin_ns: 1_000_000_000,
            last_ns: None,
            step_ns: 10_000_000,
        };
        assert_eq!(c.at(0.0), 1_000_000_000);
        assert_eq!(c.at(0.5), 1_500_000_000);
        // A rewind to the start continues one step later.
        assert_eq!(c.at(0.0), 1_510_000_000);
        assert_eq!(c.at(0.01), 1_520_000_000);
        // A forward seek keeps the gap.
        assert_eq!(c.at(2.01), 3_520_000_000);
    }
}
