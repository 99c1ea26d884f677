//! Sources of aircraft samples (docs/design.md §11), adapters around the core's
//! [`hexcue_core::source::SampleSource`]: a trace file streamed row by row, and live simulators
//! over UDP (JSBSim, FlightGear, X-Plane), each converting its units and signs to hexcue's
//! at the edge (docs/design.md §1).

pub(crate) mod decode;
pub(crate) mod flightgear;
pub(crate) mod jsbsim;
pub mod live;
pub(crate) mod recording;
pub(crate) mod trace_file;
pub(crate) mod xplane;

use std::net::{SocketAddr, ToSocketAddrs};

use anyhow::{Context, Result};

/// `HOST:PORT` to one socket address (the first the resolver gives).
pub fn resolve(addr: &str) -> Result<SocketAddr> {
    addr.to_socket_addrs()
        .with_context(|| format!("`{addr}`: expected HOST:PORT"))?
        .next()
        .with_context(|| format!("`{addr}`: no address for this host"))
}
