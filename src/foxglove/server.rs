//! A frame sink that serves a session live over the Foxglove WebSocket protocol, with the
//! `foxglove` crate's server: the recording's channels (hexcue's JSON topics and the 3D
//! topics of [`super::scene`]) from the same table, [`crate::channels`], with the same schemas, so that a layout made for recordings
//! works on a live session too.
//!
//! Attach it to any loop that makes frames: call [`FoxgloveServer::publish`] with each frame
//! and [`FoxgloveServer::event`] for what the session wants the viewer to know (input lost,
//! e-stop, …). Publishing to no client costs the scene's construction only: the crate encodes
//! a message only for a channel that a client has subscribed.

use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::sync::Arc;

use ::foxglove::websocket::Capability;
use ::foxglove::{
    Context, FoxgloveError, PartialMetadata, RawChannel, Schema, WebSocketServer,
    WebSocketServerHandle,
};

use crate::channels::scene::{self, SceneBuilder, SESSION_SOURCE};
use crate::channels::{self, json, Channel, Kind, MessageTap, SceneMessage};
use hexcue_core::engine::Frame;
use hexcue_core::events::EventLevel;
use hexcue_core::mca::AlgorithmId;
use hexcue_core::profile::Profile;

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

/// The live Foxglove server of one session.
pub struct FoxgloveServer {
    context: Arc<Context>,
    handle: Option<WebSocketServerHandle>,
    addr: SocketAddr,
    builder: SceneBuilder,
    channels: BTreeMap<Channel, Arc<RawChannel>>,
    buf: Vec<u8>,
    clock: Clock,
}

impl FoxgloveServer {
    /// Starts serving on `addr` (port 0: any free port; see [`FoxgloveServer::addr`]) the
    /// channels of a session of `algorithms` on `profile`'s rig, offering the Parameters
    /// capability on `tuning` when given (a live session's parameters: [`super::parameters`]).
    pub fn start(
        addr: SocketAddr,
        profile: &Profile,
        algorithms: &[AlgorithmId],
        tuning: Option<crate::tuning::TuningHandle>,
    ) -> Result<Self, ServerError> {
        let context = Context::new();
        let start_ns = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(1, |d| d.as_nanos().min(u128::from(u64::MAX / 2)) as u64);
        let mut server = FoxgloveServer {
            handle: None,
            addr,
            builder: SceneBuilder::new(profile, algorithms),
            channels: BTreeMap::new(),
            buf: Vec::with_capacity(4096),
            clock: Clock {
                origin_ns: start_ns,
                last_ns: None,
                step_ns: (1e9 / profile.rate_hz.max(1e-3)).round() as u64,
            },
            context,
        };
        // Every channel exists before the first client comes, so that it sees them all.
        for channel in channels::session(algorithms) {
            server.channel(channel)?;
        }
        let info = [
            ("hexcue_version", env!("CARGO_PKG_VERSION").to_string()),
            ("profile", profile.name.clone()),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect();
        let mut capabilities = vec![Capability::Time];
        let mut ws = WebSocketServer::new();
        if let Some(tuning) = tuning {
            capabilities.push(Capability::Parameters);
            ws = ws.parameter_handler(Arc::new(super::parameters::LiveParameters(tuning)));
        }
        let handle = ws
            .name(format!("hexcue {}", env!("CARGO_PKG_VERSION")))
            .bind(addr.ip().to_string(), addr.port())
            .context(&server.context)
            .capabilities(capabilities)
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

    fn channel(&mut self, channel: Channel) -> Result<Arc<RawChannel>, ServerError> {
        if let Some(ch) = self.channels.get(&channel) {
            return Ok(ch.clone());
        }
        let topic = channel.topic();
        let schema = channel.kind.schema();
        let raw = self
            .context
            .channel_builder(&topic)
            .message_encoding(channel.kind.message_encoding())
            .schema(Schema::new(schema.name, schema.encoding, schema.data))
            .build_raw()
            .map_err(|error| ServerError::Channel { topic, error })?;
        self.channels.insert(channel, raw.clone());
        Ok(raw)
    }

    /// Encodes a Foxglove message for the clients subscribed to its channel, if any.
    fn send_scene(&mut self, channel: Channel, message: SceneMessage<'_>, t_ns: u64) {
        // A lane that was not announced gets its channels now; only the crate's refusal
        // of a channel (none for these topics) would skip it.
        let Ok(raw) = self.channel(channel) else {
            return;
        };
        if raw.has_sinks() && message.encode(&mut self.buf).is_ok() {
            raw.log_with_meta(&self.buf, PartialMetadata::with_log_time(t_ns));
        }
    }

    /// Sends one frame on every channel (to the clients subscribed to it).
    pub fn publish(&mut self, frame: &Frame) {
        let t_ns = self.clock.at(frame.t_s);
        let meta = || PartialMetadata::with_log_time(t_ns);
        for (channel, message) in json::messages(frame) {
            let Ok(raw) = self.channel(channel) else {
                continue;
            };
            // Only a serialisation error (none for these messages) would skip a message.
            if raw.has_sinks() {
                self.buf.clear();
                if message.write_json(&mut self.buf).is_ok() {
                    raw.log_with_meta(&self.buf, meta());
                }
            }
        }
        let step = self.builder.step(frame, t_ns, true);
        for (channel, message) in step.by_channel() {
            self.send_scene(channel, message, t_ns);
        }
        if let Some(handle) = &self.handle {
            handle.broadcast_time(t_ns);
        }
    }

    /// Sends an event of the session on `/events`, at the time of the last frame.
    pub fn event(&mut self, level: EventLevel, text: &str) {
        let t_ns = self.clock.last_ns.unwrap_or(self.clock.origin_ns);
        let log = scene::event(t_ns, level, SESSION_SOURCE, text);
        self.send_scene(Channel::EVENTS, SceneMessage::Log(&log), t_ns);
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

/// Fed by a recorder (`Recorder::record_with`): the recording's bytes and log times, sent
/// to the clients subscribed, instead of [`FoxgloveServer::publish`] encoding the frame again.
impl MessageTap for FoxgloveServer {
    fn wants(&mut self, channel: Channel) -> bool {
        self.channel(channel).is_ok_and(|raw| raw.has_sinks())
    }

    fn wants_every_scene(&mut self) -> bool {
        self.channels
            .iter()
            .any(|(c, raw)| matches!(c.kind, Kind::Tf | Kind::Scene) && raw.has_sinks())
    }

    fn message(&mut self, channel: Channel, bytes: &[u8], log_time_ns: u64) {
        if let Some(raw) = self.channels.get(&channel) {
            raw.log_with_meta(bytes, PartialMetadata::with_log_time(log_time_ns));
        }
    }

    fn step_done(&mut self, log_time_ns: u64) {
        // Session events go out at the last frame's time, as with `publish`.
        self.clock.last_ns = Some(log_time_ns);
        if let Some(handle) = &self.handle {
            handle.broadcast_time(log_time_ns);
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

    fn event(&mut self, event: &hexcue_core::events::Event) -> anyhow::Result<()> {
        FoxgloveServer::event(self, event.level, &event.text);
        Ok(())
    }
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
