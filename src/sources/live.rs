//! A live simulator over UDP: a socket, the decoder of its protocol, and the latest sample
//! with the moment it arrived. Reads never block and are bounded per step, so a flood of
//! datagrams cannot stall the clock; malformed datagrams are counted and ignored.

use std::net::{SocketAddr, UdpSocket};
use std::time::Instant;

use anyhow::{bail, Context, Result};

use hexcue_core::ground::GroundSignal;
use hexcue_core::trace::AircraftSample;

use super::decode::{Decoded, Decoder};

/// Largest believable magnitudes (SI) in a live sample; past them a datagram is malformed,
/// the same bounds as a trace file's.
const MAX_SPECIFIC_FORCE_MPS2: f64 = 1000.0;
const MAX_RATE_RADPS: f64 = 100.0;

/// Where the socket binds and where requests go, from the URL.
pub enum Endpoint {
    /// The simulator sends to HOST:PORT: hexcue listens there (JSBSim, FlightGear).
    Listen(SocketAddr),
    /// HOST:PORT is the simulator: hexcue sends requests there from a port of its own, and
    /// the replies come back to it (X-Plane).
    Ask(SocketAddr),
}

/// The latest sample of a live input, with its age.
pub struct LiveInput {
    url: String,
    socket: UdpSocket,
    peer: Option<SocketAddr>,
    decoder: Box<dyn Decoder>,
    opened: Instant,
    latest: Option<(AircraftSample, Instant)>,
    paused: bool,
    /// What the latest sample said of the ground.
    ground: GroundSignal,
    /// Datagrams that carried a sample.
    pub samples_in: u64,
    /// Datagrams refused (and ignored).
    pub malformed: u64,
    /// The last refusal's reason, for the operator.
    pub last_malformed: Option<String>,
    buf: Vec<u8>,
}

impl LiveInput {
    /// Opens `jsbsim://HOST:PORT`, `flightgear://HOST:PORT` or `xplane://HOST:PORT`.
    pub fn open(url: &str) -> Result<Self> {
        let (scheme, addr) = url.split_once("://").with_context(|| {
            format!("--input {url}: expected jsbsim://HOST:PORT, flightgear://HOST:PORT or xplane://HOST:PORT")
        })?;
        let addr = super::resolve(addr).with_context(|| format!("--input {url}"))?;
        let (decoder, endpoint): (Box<dyn Decoder>, Endpoint) = match scheme {
            "jsbsim" => (Box::new(super::jsbsim::Jsbsim::default()), Endpoint::Listen(addr)),
            "flightgear" => (
                Box::new(super::flightgear::FlightGear),
                Endpoint::Listen(addr),
            ),
            "xplane" => (Box::new(super::xplane::XPlane::new()), Endpoint::Ask(addr)),
            other => bail!(
                "--input {url}: unknown simulator `{other}`; expected jsbsim://, flightgear:// or xplane://"
            ),
        };
        Self::with_decoder(url, decoder, endpoint)
    }

    pub fn with_decoder(url: &str, decoder: Box<dyn Decoder>, endpoint: Endpoint) -> Result<Self> {
        let (bind, peer) = match endpoint {
            Endpoint::Listen(a) => (a, None),
            Endpoint::Ask(a) => {
                let any: SocketAddr = if a.is_ipv4() {
                    "0.0.0.0:0".parse()?
                } else {
                    "[::]:0".parse()?
                };
                (any, Some(a))
            }
        };
        let socket =
            UdpSocket::bind(bind).with_context(|| format!("--input {url}: cannot bind {bind}"))?;
        socket.set_nonblocking(true)?;
        Ok(LiveInput {
            url: url.to_string(),
            socket,
            peer,
            decoder,
            opened: Instant::now(),
            latest: None,
            paused: false,
            ground: GroundSignal::default(),
            samples_in: 0,
            malformed: 0,
            last_malformed: None,
            buf: vec![0; 65536],
        })
    }

    pub fn url(&self) -> &str {
        &self.url
    }

    /// Where input is expected and by which protocol, for the operator: "JSBSim socket
    /// output, UDP listening on 127.0.0.1:5138", or for X-Plane the address asked and the
    /// port the replies come back to.
    pub fn source_text(&self) -> String {
        let local = self
            .socket
            .local_addr()
            .map_or_else(|_| "?".to_string(), |a| a.to_string());
        let protocol = self.decoder.protocol();
        match self.peer {
            Some(peer) => format!("{protocol}, asking {peer} over UDP, replies to {local}"),
            None => format!("{protocol}, UDP listening on {local}"),
        }
    }

    /// The address the socket is bound to (tests bind port 0).
    pub fn local_addr(&self) -> std::io::Result<SocketAddr> {
        self.socket.local_addr()
    }

    /// Reads what has arrived, at most `max_datagrams`, and sends the decoder's requests.
    /// Never blocks.
    pub fn poll(&mut self, now: Instant, max_datagrams: usize) -> std::io::Result<()> {
        if let Some(peer) = self.peer {
            let now_s = now.saturating_duration_since(self.opened).as_secs_f64();
            let receiving = self.age_s(now).is_some_and(|a| a < 1.0);
            for req in self.decoder.requests(now_s, receiving) {
                match self.socket.send_to(&req, peer) {
                    Ok(_) => {}
                    // Nothing listening yet: the decoder asks again later.
                    Err(e)
                        if matches!(
                            e.kind(),
                            std::io::ErrorKind::ConnectionRefused | std::io::ErrorKind::WouldBlock
                        ) => {}
                    Err(e) => return Err(e),
                }
            }
        }
        for _ in 0..max_datagrams {
            let n = match self.socket.recv_from(&mut self.buf) {
                Ok((n, _)) => n,
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => break,
                // ICMP errors from an earlier send surface here on some systems.
                Err(e) if e.kind() == std::io::ErrorKind::ConnectionRefused => continue,
                Err(e) => return Err(e),
            };
            match self.decoder.decode(&self.buf[..n]).and_then(check) {
                Ok(Decoded::Sample {
                    sample,
                    paused,
                    ground,
                }) => {
                    self.latest = Some((sample, Instant::now()));
                    self.paused = paused;
                    self.ground = ground;
                    self.samples_in += 1;
                }
                Ok(Decoded::Nothing) => {}
                Err(why) => {
                    self.malformed += 1;
                    self.last_malformed = Some(why);
                }
            }
        }
        Ok(())
    }

    /// Blocks until a datagram waits in the socket or `until` passes, whichever comes first,
    /// without reading it; returns whether one waits. The live loop sleeps here between
    /// steps, so that it wakes when the simulator's sample arrives rather than on a timer
    /// (docs/live.md, *The clock*). `ppoll(2)` on Linux (a nanosecond timeout), `poll(2)`
    /// elsewhere (rounded up to the next millisecond, never early).
    pub fn wait(&self, until: Instant) -> std::io::Result<bool> {
        use std::os::fd::AsRawFd;
        let left = until.saturating_duration_since(Instant::now());
        let mut fd = libc::pollfd {
            fd: self.socket.as_raw_fd(),
            events: libc::POLLIN,
            revents: 0,
        };
        #[cfg(target_os = "linux")]
        let rc = {
            let timeout = libc::timespec {
                tv_sec: left.as_secs() as libc::time_t,
                tv_nsec: left.subsec_nanos() as libc::c_long,
            };
            // SAFETY: one valid pollfd, a valid timespec, no signal mask change.
            unsafe { libc::ppoll(&mut fd, 1, &timeout, std::ptr::null()) }
        };
        #[cfg(not(target_os = "linux"))]
        let rc = {
            let ms = left.as_nanos().div_ceil(1_000_000).min(i32::MAX as u128) as i32;
            // SAFETY: one valid pollfd.
            unsafe { libc::poll(&mut fd, 1, ms) }
        };
        if rc >= 0 {
            return Ok(rc > 0);
        }
        let e = std::io::Error::last_os_error();
        if e.kind() == std::io::ErrorKind::Interrupted {
            // A signal (SIGINT, SIGWINCH) woke it: the caller's loop looks again.
            return Ok(false);
        }
        Err(e)
    }

    /// The latest sample and when it arrived.
    pub fn latest(&self) -> Option<(AircraftSample, Instant)> {
        self.latest
    }

    /// Seconds since the latest sample arrived.
    pub fn age_s(&self, now: Instant) -> Option<f64> {
        self.latest
            .map(|(_, at)| now.saturating_duration_since(at).as_secs_f64())
    }

    pub fn paused(&self) -> bool {
        self.paused
    }

    /// What the latest sample said of the ground (nothing, for a protocol that does not say).
    pub fn ground(&self) -> &GroundSignal {
        &self.ground
    }

    /// Says goodbye to the simulator (X-Plane: stop sending).
    pub fn close(&mut self) {
        if let Some(peer) = self.peer {
            for req in self.decoder.farewell() {
                let _ = self.socket.send_to(&req, peer);
            }
        }
    }
}

/// Refuses samples no aircraft flies: non-finite or beyond the trace files' bounds. A height
/// or ground speed that is not a finite number is dropped (the phase is then kept).
fn check(mut d: Decoded) -> Result<Decoded, String> {
    if let Decoded::Sample { ground, .. } = &mut d {
        ground.height_agl_m = ground.height_agl_m.filter(|h| h.is_finite());
        ground.ground_speed_mps = ground.ground_speed_mps.filter(|v| v.is_finite());
    }
    if let Decoded::Sample { sample, .. } = &d {
        let f = &sample.specific_force_mps2;
        let w = &sample.angular_velocity_radps;
        let a = &sample.attitude_rad;
        if !(f
            .iter()
            .chain(w.iter())
            .chain(a.iter())
            .all(|v| v.is_finite()))
        {
            return Err("a value is not a finite number".into());
        }
        if f.amax() > MAX_SPECIFIC_FORCE_MPS2 || w.amax() > MAX_RATE_RADPS {
            return Err(format!(
                "specific force {f:?} m/s² or rates {w:?} rad/s beyond ±{MAX_SPECIFIC_FORCE_MPS2} m/s², ±{MAX_RATE_RADPS} rad/s"
            ));
        }
    }
    Ok(d)
}
