//! The Moog 6DOF2000E motion base in DOF mode over UDP: the datagrams ([`protocol`]), the
//! sequence ([`driver`]), and this adapter, which sends one command per step and reads the
//! base's status replies without waiting. A stand-in base for the tests: [`fake`].
//!
//! Where the layout, the words and the sequence come from, and what is still unverified
//! without a base at hand, is in docs/live.md (*Moog 6DOF2000E*).

pub mod driver;
pub mod fake;
pub mod protocol;

use std::net::{SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

use super::{CommandSink, PlatformOutput, PlatformStatus};
use driver::{Driver, ParkOutcome};
use hexcue_core::profile::MoogParams;

/// Replies read at most per poll: a base answers one per command.
const MAX_REPLIES_PER_POLL: usize = 64;

pub struct Moog {
    socket: UdpSocket,
    peer: SocketAddr,
    driver: Driver,
    opened: Instant,
    period: Duration,
    /// Datagrams from the base that were not a 40-byte status.
    pub malformed_replies: u64,
    /// How the last way out ended, for the operator.
    parked: Option<ParkOutcome>,
}

impl Moog {
    /// A driver of the base at `peer`, sending one command every `period` while parking.
    pub fn open(peer: SocketAddr, params: &MoogParams, period: Duration) -> std::io::Result<Self> {
        let socket = super::sender_socket(peer)?;
        Ok(Moog {
            socket,
            peer,
            driver: Driver::new(params.clone()),
            opened: Instant::now(),
            period,
            malformed_replies: 0,
            parked: None,
        })
    }

    fn now_s(&self) -> f64 {
        self.opened.elapsed().as_secs_f64()
    }

    /// Every reply waiting in the socket, without blocking. The base answers to the port
    /// the commands come from, as the third-party driver expects (it reads its replies on
    /// its sending socket); datagrams from anyone else are ignored.
    fn read_replies(&mut self) -> std::io::Result<()> {
        let mut buf = [0u8; 512];
        for _ in 0..MAX_REPLIES_PER_POLL {
            match self.socket.recv_from(&mut buf) {
                Ok((n, from)) if from == self.peer => match protocol::decode_status(&buf[..n]) {
                    Ok(status) => {
                        let t = self.now_s();
                        self.driver.reply(t, status)
                    }
                    Err(_) => self.malformed_replies += 1,
                },
                Ok(_) => {}
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => break,
                // An ICMP "port unreachable" from an earlier command: no base there (yet);
                // the reply timeout says so.
                Err(e) if e.kind() == std::io::ErrorKind::ConnectionRefused => {}
                Err(e) => return Err(e),
            }
        }
        Ok(())
    }

    fn send_dofs(&self, word: u32, dofs: &protocol::MoogDofs) -> std::io::Result<()> {
        super::send_datagram(
            &self.socket,
            &protocol::encode_command(word, dofs),
            self.peer,
        )
    }

    /// The status, with the way out's outcome once there is one.
    fn status_now(&mut self) -> PlatformStatus {
        let t = self.now_s();
        let mut status = self.driver.status(t);
        // Only after the way out: no more steps then.
        let outcome = match &self.parked {
            Some(ParkOutcome::Settled { after_s }) => {
                format!("; settled {after_s:.2} s after PARK")
            }
            Some(ParkOutcome::TimedOut) => "; PARK timed out".to_string(),
            Some(ParkOutcome::NoReply) => "; no reply to PARK".to_string(),
            None => return status,
        };
        status.detail = format!("{}{outcome}", status.detail).into();
        status
    }
}

impl CommandSink for Moog {
    fn poll(&mut self) -> Option<PlatformStatus> {
        // A read error (not "nothing there") leaves the driver without replies: the reply
        // timeout turns it into a fault the operator sees, which a stalled step would not.
        let _ = self.read_replies();
        Some(self.status_now())
    }

    fn send(&mut self, out: &PlatformOutput) -> std::io::Result<()> {
        let t = self.now_s();
        if out.stopped {
            self.driver.park(t);
        }
        let (word, dofs) = self.driver.command(t, &out.pose);
        self.send_dofs(word, &dofs)
    }

    /// PARK every period until the base has settled, or the park timeout, or silence.
    fn close(&mut self) -> std::io::Result<()> {
        self.driver.park(self.now_s());
        let zero = nalgebra::Vector6::zeros();
        let mut due = Instant::now();
        loop {
            self.read_replies()?;
            let t = self.now_s();
            if let Some(outcome) = self.driver.park_outcome(t) {
                self.parked = Some(outcome);
                return Ok(());
            }
            let (word, dofs) = self.driver.command(t, &zero);
            self.send_dofs(word, &dofs)?;
            due += self.period;
            std::thread::sleep(due.saturating_duration_since(Instant::now()));
        }
    }

    fn describe(&self) -> String {
        format!("moog://{}", self.peer)
    }
}
