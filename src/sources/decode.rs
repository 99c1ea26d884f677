//! What a live simulator's protocol decoder is, shared by the socket loop (`live`) and the
//! protocols (JSBSim, FlightGear, X-Plane), which therefore do not import each other.

use hexcue_core::ground::GroundSignal;
use hexcue_core::trace::AircraftSample;

/// What one datagram said.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Decoded {
    /// A sample in hexcue's units and frame (docs/design.md §1); its `t_s` is the simulator's time,
    /// when it sends one (else NaN). `paused` when the simulator says it is paused; `ground`
    /// what it says of the ground (a profile's `[ground]`, docs/live.md *Air and ground*).
    Sample {
        sample: AircraftSample,
        paused: bool,
        ground: GroundSignal,
    },
    /// Well formed but carrying no sample (JSBSim's labels line, an X-Plane reply before
    /// every subscribed value has arrived once).
    Nothing,
}

/// One simulator's protocol, pure: bytes in, a sample out.
pub trait Decoder: Send {
    /// The protocol, as the operator knows it (for "no input from …" messages).
    fn protocol(&self) -> &'static str;
    /// Decodes one datagram; an error is a malformed datagram, with the reason.
    fn decode(&mut self, datagram: &[u8]) -> Result<Decoded, String>;
    /// Datagrams to send to the simulator now (X-Plane's subscription); `receiving` says
    /// whether samples have arrived lately.
    fn requests(&mut self, _now_s: f64, _receiving: bool) -> Vec<Vec<u8>> {
        Vec::new()
    }
    /// Datagrams to send on the way out (X-Plane: unsubscribe).
    fn farewell(&mut self) -> Vec<Vec<u8>> {
        Vec::new()
    }
}
