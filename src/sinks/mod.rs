//! Where frames and platform commands go (DESIGN §11): adapters around the core, each named
//! for what it is. [`FrameSink`]s take whole frames (the MCAP recorder; Foxglove next);
//! [`CommandSink`]s take the one command a live session sends to the platform each step
//! (hexcue's JSON over UDP, Moog's 6DOF2000E DOF mode), and a platform that answers says
//! where it is in its own sequence ([`PlatformStatus`]): the safety stage waits for it.

pub mod actuator_stream;
pub mod live_recording;
pub mod moog;
pub mod reach;
pub mod recorder;
pub mod udp_json;

use anyhow::{bail, Context, Result};
use nalgebra::Vector6;

use hexcue_core::mca::AlgorithmId;
use hexcue_core::safety::SafetyState;

/// Where a platform that reports its state is in its own sequence.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlatformPhase {
    /// No answer yet, or not yet in the mode poses need (Moog: DOF mode).
    Connecting,
    /// Rising to neutral: poses are held at neutral until it is engaged.
    Engaging,
    /// Follows poses.
    Engaged,
    /// Settling on the way out.
    Parking,
    /// Settled after parking.
    Parked,
    /// Stopped by a fault (reported, or silence): no more poses, latched.
    Fault,
}

impl PlatformPhase {
    pub fn word(self) -> &'static str {
        match self {
            PlatformPhase::Connecting => "CONNECTING",
            PlatformPhase::Engaging => "ENGAGING",
            PlatformPhase::Engaged => "ENGAGED",
            PlatformPhase::Parking => "PARKING",
            PlatformPhase::Parked => "PARKED",
            PlatformPhase::Fault => "FAULT",
        }
    }
}

/// What a platform says of itself, for the safety stage and the operator.
#[derive(Clone, Debug, PartialEq)]
pub struct PlatformStatus {
    pub phase: PlatformPhase,
    /// Time in this phase (s).
    pub in_phase_s: f64,
    /// What the platform last said, in words (its state, the fault and why). Shared, not
    /// copied: the status goes with every step's report.
    pub detail: std::sync::Arc<str>,
    /// A few characters for the console's header: the fault word, or `NO REPLY`.
    pub code: Option<std::sync::Arc<str>>,
}

impl PlatformStatus {
    /// The console header's words: `BASE ENGAGING 1.3s`, `BASE FAULT 0x0080`.
    pub fn header(&self) -> String {
        match (&self.code, self.phase) {
            (Some(code), _) => format!("BASE {} {code}", self.phase.word()),
            (None, PlatformPhase::Engaged | PlatformPhase::Parked) => {
                format!("BASE {}", self.phase.word())
            }
            (None, phase) => format!("BASE {} {:.1}s", phase.word(), self.in_phase_s),
        }
    }
}

/// The command a live session sends at one step, after the safety stage and the limiter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlatformOutput {
    /// Session time of the step (s).
    pub t_s: f64,
    /// Step number, from 0, one per command.
    pub seq: u64,
    /// x, y, z (m), roll, pitch, yaw (rad) from neutral, simulator inertial frame (DESIGN §1).
    pub pose: Vector6<f64>,
    /// The command's own rate and acceleration of the pose (m/s, rad/s; m/s², rad/s²): the
    /// driving algorithm's, or the way back to neutral's.
    pub velocity: Vector6<f64>,
    pub acceleration: Vector6<f64>,
    /// Leg lengths 1..6 (m).
    pub legs_m: Vector6<f64>,
    pub state: SafetyState,
    /// Parked for good after an e-stop.
    pub stopped: bool,
    /// The algorithm driving the platform.
    pub algorithm: AlgorithmId,
    /// The actuator positions of this pose, when the profile has `[actuators]`.
    pub actuators: Option<hexcue_core::actuators::ActuatorPositions>,
}

/// A platform, or anything listening like one, fed one command per step.
pub trait CommandSink: Send {
    /// Reads what the platform has said since the last call, without waiting: `None` for an
    /// output that does not answer (hexcue's JSON), which counts as ready. Called at the start
    /// of every step, and once after [`CommandSink::close`].
    fn poll(&mut self) -> Option<PlatformStatus> {
        None
    }
    /// Sends one command. A full socket buffer or a peer that is not listening is not an
    /// error here: the next step sends again, and a platform must not stall the clock.
    fn send(&mut self, out: &PlatformOutput) -> std::io::Result<()>;
    /// The last words before the session ends (Moog: park until settled, or a timeout, whose
    /// outcome the next [`CommandSink::poll`] tells).
    fn close(&mut self) -> std::io::Result<()> {
        Ok(())
    }
    /// What it is, for the user (`udp://…`).
    fn describe(&self) -> String;
    /// Nothing listens at its address: an ICMP port unreachable came back lately
    /// ([`reach`]). Asked every step after [`CommandSink::poll`]; an output that cannot
    /// know says `false`.
    fn unreachable(&self) -> bool {
        false
    }
}

/// What `--output` accepts, for messages.
const OUTPUT_FORMS: &str = "udp://HOST:PORT (JSON), udp://HOST:PORT?frame=actuators, \
     serial://PATH?baud=N or moog://HOST:PORT";

/// Opens a command sink from its URL: `udp://HOST:PORT` (hexcue's JSON; `?frame=json` says
/// so explicitly), `udp://HOST:PORT?frame=actuators` and `serial://PATH?baud=N` (the
/// profile's `[actuators]` frame) or `moog://HOST:PORT` (the profile's `[moog]`, one command
/// every `period`).
pub fn open_output(
    url: &str,
    profile: &hexcue_core::profile::Profile,
    period: std::time::Duration,
) -> Result<Box<dyn CommandSink>> {
    let (scheme, rest) = url
        .split_once("://")
        .with_context(|| format!("--output {url}: expected {OUTPUT_FORMS}"))?;
    let (place, query) = rest.split_once('?').unwrap_or((rest, ""));
    let mut params: Vec<(&str, &str)> = Vec::new();
    for pair in query.split('&').filter(|p| !p.is_empty()) {
        let (k, v) = pair
            .split_once('=')
            .with_context(|| format!("--output {url}: `{pair}`: expected KEY=VALUE after `?`"))?;
        params.push((k, v));
    }
    let allowed: &[&str] = match scheme {
        "udp" => &["frame"],
        "serial" => &["baud"],
        _ => &[],
    };
    if let Some((k, _)) = params.iter().find(|(k, _)| !allowed.contains(k)) {
        let expected = if allowed.is_empty() {
            "no options".to_string()
        } else {
            allowed.join(", ")
        };
        bail!("--output {url}: unknown option `{k}`; {scheme}:// takes {expected}");
    }
    let param = |key: &str| params.iter().find(|(k, _)| *k == key).map(|(_, v)| *v);
    let frame = || -> Result<hexcue_core::actuators::FrameFormat> {
        let actuators = profile
            .actuators()
            .with_context(|| format!("--output {url}: the profile's [actuators]"))?;
        match actuators {
            Some(a) => Ok(a.frame().clone()),
            None => bail!(
                "--output {url}: the profile `{}` has no [actuators] section; an actuator \
                 stream needs one (its kind and frame: docs/live.md, *Actuator streams*)",
                profile.name
            ),
        }
    };
    Ok(match scheme {
        "udp" => {
            let addr = crate::sources::resolve(place).with_context(|| format!("--output {url}"))?;
            match param("frame").unwrap_or("json") {
                "json" => {
                    let rotary = profile
                        .actuators()
                        .ok()
                        .flatten()
                        .is_some_and(|a| a.is_rotary());
                    Box::new(udp_json::UdpJson::open(addr, rotary)?)
                }
                "actuators" => Box::new(actuator_stream::UdpActuators::open(addr, frame()?)?),
                other => bail!(
                    "--output {url}: frame={other}: expected frame=json (hexcue's JSON, the \
                     default) or frame=actuators (the profile's [actuators] frame)"
                ),
            }
        }
        "serial" => {
            if place.is_empty() {
                bail!("--output {url}: expected serial://PATH?baud=N, e.g. serial:///dev/ttyUSB0?baud=115200");
            }
            let baud = match param("baud") {
                None => 115_200,
                Some(b) => b.parse::<u32>().ok().filter(|b| *b > 0).with_context(|| {
                    format!("--output {url}: baud={b}: expected a positive whole number of bits per second")
                })?,
            };
            Box::new(actuator_stream::SerialActuators::open(
                place,
                baud,
                frame()?,
            )?)
        }
        "moog" => {
            let addr = crate::sources::resolve(place).with_context(|| format!("--output {url}"))?;
            Box::new(moog::Moog::open(addr, &profile.moog, period)?)
        }
        other => bail!("--output {url}: unknown scheme `{other}`; expected {OUTPUT_FORMS}"),
    })
}

/// A non-blocking UDP socket on an ephemeral port of the peer's address family, for the
/// command outputs: a step must never wait on the network.
/// Sends one datagram from a [`sender_socket`]. Nobody listening yet (ICMP port unreachable)
/// or a full buffer is not an error: the next step sends again.
pub(crate) fn send_datagram(
    socket: &std::net::UdpSocket,
    bytes: &[u8],
    peer: std::net::SocketAddr,
) -> std::io::Result<()> {
    match socket.send_to(bytes, peer) {
        Ok(_) => Ok(()),
        Err(e)
            if matches!(
                e.kind(),
                std::io::ErrorKind::ConnectionRefused | std::io::ErrorKind::WouldBlock
            ) =>
        {
            Ok(())
        }
        Err(e) => Err(e),
    }
}

pub(crate) fn sender_socket(peer: std::net::SocketAddr) -> std::io::Result<std::net::UdpSocket> {
    let any: std::net::SocketAddr = if peer.is_ipv4() {
        (std::net::Ipv4Addr::UNSPECIFIED, 0).into()
    } else {
        (std::net::Ipv6Addr::UNSPECIFIED, 0).into()
    };
    let socket = std::net::UdpSocket::bind(any)?;
    socket.set_nonblocking(true)?;
    Ok(socket)
}
