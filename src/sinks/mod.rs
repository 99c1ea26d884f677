//! Where frames and platform commands go (DESIGN §11): adapters around the core, each named
//! for what it is. [`FrameSink`]s take whole frames (the MCAP recorder; Foxglove next);
//! [`CommandSink`]s take the one command a live session sends to the platform each step
//! (hexcue's JSON over UDP, Moog's 6DOF2000E DOF mode), and a platform that answers says
//! where it is in its own sequence ([`PlatformStatus`]): the safety stage waits for it.

pub mod live_recording;
pub mod moog;
pub mod recorder;
pub mod udp_json;

/// The trait lives with the session runner, which feeds it; kept here for the merge.
pub use crate::session::FrameSink;

use anyhow::{bail, Context, Result};
use nalgebra::Vector6;

use crate::mca::AlgorithmId;
use crate::safety::SafetyState;

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
    /// What the platform last said, in words (its state, the fault and why).
    pub detail: String,
    /// A few characters for the console's header: the fault word, or `NO REPLY`.
    pub code: Option<String>,
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
}

/// Opens a command sink from `udp://HOST:PORT` or `moog://HOST:PORT`; a Moog base is driven
/// with `moog` (the profile's `[moog]`) at one command every `period`.
pub fn open_output(
    url: &str,
    moog: &crate::profile::MoogParams,
    period: std::time::Duration,
) -> Result<Box<dyn CommandSink>> {
    let (scheme, addr) = url
        .split_once("://")
        .with_context(|| format!("--output {url}: expected udp://HOST:PORT or moog://HOST:PORT"))?;
    let addr = crate::sources::resolve(addr).with_context(|| format!("--output {url}"))?;
    Ok(match scheme {
        "udp" => Box::new(udp_json::UdpJson::open(addr)?),
        "moog" => Box::new(moog::Moog::open(addr, moog, period)?),
        other => bail!("--output {url}: unknown scheme `{other}`; expected udp:// or moog://"),
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
