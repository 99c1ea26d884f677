//! Whether anyone listens at a UDP output's address. A UDP sender hears nothing back, except
//! this: a host whose port is closed answers a datagram with ICMP "port unreachable", and
//! on a *connected* socket the kernel hands that to the next send (or `SO_ERROR`) as
//! `ECONNREFUSED` (Linux `udp(7)`; an unconnected socket is never told). So the outputs
//! connect their socket, and note each refusal here: nothing listening is said within a
//! step or two of the first datagram, not never. A host that is down, or a firewall that
//! drops the datagrams silently, sends no ICMP: that stays unseen.
//!
//! A remote host rate-limits its ICMP (Linux: about one a second per peer after a burst of
//! six, `icmp_ratelimit`), so one quiet second does not mean a listener: the output counts
//! as listening again only after [`QUIET_S`] without a refusal.

use std::net::UdpSocket;
use std::time::Instant;

/// Seconds without a refusal after which an output that was refused counts as listening.
pub const QUIET_S: f64 = 3.0;

#[derive(Debug, Default)]
pub struct Reach {
    last_refused: Option<Instant>,
    unreachable: bool,
}

impl Reach {
    /// Counts a send's outcome: a refusal is noted and not an error (the next step sends
    /// again, and a platform may be started later); a full buffer is not an error either.
    pub fn sent(&mut self, result: std::io::Result<usize>) -> std::io::Result<()> {
        match result {
            Ok(_) => Ok(()),
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionRefused => {
                self.refused(Instant::now());
                Ok(())
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => Ok(()),
            Err(e) => Err(e),
        }
    }

    fn refused(&mut self, at: Instant) {
        self.last_refused = Some(at);
        self.unreachable = true;
    }

    /// Reads a refusal the socket holds (`SO_ERROR`, one system call, no wait) and lets a
    /// quiet [`QUIET_S`] end the unreachable state.
    pub fn poll(&mut self, socket: &UdpSocket) {
        let now = Instant::now();
        if let Ok(Some(e)) = socket.take_error() {
            if e.kind() == std::io::ErrorKind::ConnectionRefused {
                self.refused(now);
            }
        }
        if self.unreachable
            && self
                .last_refused
                .is_none_or(|t| now.duration_since(t).as_secs_f64() >= QUIET_S)
        {
            self.unreachable = false;
        }
    }

    pub fn unreachable(&self) -> bool {
        self.unreachable
    }
}

/// A non-blocking UDP socket on an ephemeral port, connected to `peer`: sends go to it, and
/// its ICMP errors come back (see the module's text).
pub fn connected_socket(peer: std::net::SocketAddr) -> std::io::Result<UdpSocket> {
    let socket = super::sender_socket(peer)?;
    socket.connect(peer)?;
    Ok(socket)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    /// A port nobody listens on is refused within a few sends on loopback (Linux answers
    /// every datagram there: loopback is not rate-limited); one that listens never is.
    #[test]
    fn a_closed_port_is_refused_and_an_open_one_is_not() {
        let closed = {
            let s = UdpSocket::bind("127.0.0.1:0").unwrap();
            s.local_addr().unwrap()
        };
        let socket = connected_socket(closed).unwrap();
        let mut reach = Reach::default();
        let deadline = Instant::now() + Duration::from_secs(10);
        while !reach.unreachable() && Instant::now() < deadline {
            reach.sent(socket.send(b"x")).unwrap();
            reach.poll(&socket);
            std::thread::sleep(Duration::from_millis(1));
        }
        assert!(reach.unreachable(), "no refusal from a closed port in 10 s");

        let listener = UdpSocket::bind("127.0.0.1:0").unwrap();
        let socket = connected_socket(listener.local_addr().unwrap()).unwrap();
        let mut reach = Reach::default();
        for _ in 0..50 {
            reach.sent(socket.send(b"x")).unwrap();
            reach.poll(&socket);
        }
        assert!(!reach.unreachable());
        let mut buf = [0u8; 8];
        assert_eq!(listener.recv(&mut buf).unwrap(), 1);
    }

    #[test]
    fn quiet_ends_the_unreachable_state_and_only_quiet() {
        let listener = UdpSocket::bind("127.0.0.1:0").unwrap();
        let socket = connected_socket(listener.local_addr().unwrap()).unwrap();
        let mut reach = Reach::default();
        let refused = Instant::now();
        reach.refused(refused);
        reach.poll(&socket);
        assert!(reach.unreachable());
        // As if QUIET_S had passed since that refusal.
        reach.last_refused = refused.checked_sub(Duration::from_secs_f64(QUIET_S));
        reach.poll(&socket);
        assert!(!reach.unreachable());
        let e = std::io::Error::from(std::io::ErrorKind::ConnectionRefused);
        reach.sent(Err(e)).unwrap();
        assert!(reach.unreachable());
        let other = std::io::Error::from(std::io::ErrorKind::PermissionDenied);
        assert!(reach.sent(Err(other)).is_err());
    }
}
