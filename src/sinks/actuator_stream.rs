//! Actuator streams: the frame of the profile's `[actuators]` every step, to a serial port
//! (`serial://PATH?baud=N`, 8N1) or in one UDP datagram per frame
//! (`udp://HOST:PORT?frame=actuators`); docs/live.md, *Actuator streams*.
//!
//! The sequence, as a hobby controller expects it: nothing while the session waits for its
//! first input; the `start` frame when the platform engages, then a position frame every step
//! (neutral while hexcue holds it there: after a return to neutral the controller keeps the
//! platform where hexcue says); after the last position, once the session has parked for
//! good, the `stop` frame; nothing after it. A session that ends without parking (a fault)
//! sends the `stop` frame on close, if the port still takes it.
//!
//! A serial port that fails (write error: the device unplugged, `EIO` from a closed
//! pseudo-terminal) is a platform fault, as a silent Moog base is: latched, reported through
//! [`CommandSink::poll`], motion stops and the session exits with status 1.

use std::io::Write;
use std::net::{SocketAddr, UdpSocket};
use std::time::Duration;

use anyhow::{Context, Result};

use super::reach::{connected_socket, Reach};
use super::{CommandSink, PlatformOutput, PlatformPhase, PlatformStatus};
use hexcue_core::actuators::FrameFormat;
use hexcue_core::safety::SafetyState;

/// A write that waits longer than this for room in the port's buffer is skipped, not waited
/// for: a step never stalls on a controller that does not read.
const WRITE_TIMEOUT: Duration = Duration::from_millis(2);

/// Where a stream is in its sequence, and the buffer its frames are written into.
#[derive(Debug)]
pub struct ActuatorStream {
    frame: FrameFormat,
    buf: Vec<u8>,
    started: bool,
    stopped: bool,
}

impl ActuatorStream {
    pub fn new(frame: FrameFormat) -> Self {
        let buf = Vec::with_capacity(frame.max_len());
        ActuatorStream {
            frame,
            buf,
            started: false,
            stopped: false,
        }
    }

    /// Writes this step's frames through `write`, one call per frame, in order: the start
    /// frame on engaging, the position, and the stop frame once parked for good.
    pub fn step<E>(
        &mut self,
        out: &PlatformOutput,
        mut write: impl FnMut(&[u8]) -> Result<(), E>,
    ) -> Result<(), E> {
        let Some(positions) = out.actuators else {
            return Ok(());
        };
        if self.stopped {
            return Ok(());
        }
        if !self.started {
            if !matches!(out.state, SafetyState::Engaging | SafetyState::Running) {
                return Ok(());
            }
            self.started = true;
            if !self.frame.start().is_empty() {
                write(self.frame.start())?;
            }
        }
        self.frame.encode_into(&positions.counts, &mut self.buf);
        write(&self.buf)?;
        if out.stopped {
            self.stopped = true;
            if !self.frame.stop().is_empty() {
                write(self.frame.stop())?;
            }
        }
        Ok(())
    }

    /// The stop frame, if the stream started and has not stopped yet.
    pub fn close<E>(&mut self, write: impl FnOnce(&[u8]) -> Result<(), E>) -> Result<(), E> {
        if self.started && !self.stopped {
            self.stopped = true;
            if !self.frame.stop().is_empty() {
                return write(self.frame.stop());
            }
        }
        Ok(())
    }
}

/// The actuator frame to a serial port.
pub struct SerialActuators {
    path: String,
    baud: u32,
    port: serialport::TTYPort,
    stream: ActuatorStream,
    /// Why the port failed (latched).
    fault: Option<String>,
    /// Frames skipped because the port's buffer stayed full for [`WRITE_TIMEOUT`].
    pub skipped: u64,
}

impl SerialActuators {
    /// Opens `path` at `baud`, 8N1, no flow control.
    pub fn open(path: &str, baud: u32, frame: FrameFormat) -> Result<Self> {
        let port = serialport::new(path, baud)
            .data_bits(serialport::DataBits::Eight)
            .parity(serialport::Parity::None)
            .stop_bits(serialport::StopBits::One)
            .flow_control(serialport::FlowControl::None)
            .timeout(WRITE_TIMEOUT)
            .open_native()
            .with_context(|| format!("serial://{path}: cannot open the port at {baud} baud"))?;
        Ok(SerialActuators {
            path: path.to_string(),
            baud,
            port,
            stream: ActuatorStream::new(frame),
            fault: None,
            skipped: 0,
        })
    }

    fn failed(&mut self, e: std::io::Error) {
        self.fault = Some(format!(
            "the serial port failed: {e}; the controller is gone (unplugged or closed), no \
             more positions"
        ));
    }
}

/// A write to the port: a full buffer skips the frame, any other error is the port's end.
fn write_port(
    port: &mut serialport::TTYPort,
    bytes: &[u8],
    skipped: &mut u64,
) -> std::io::Result<()> {
    match port.write_all(bytes) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {
            *skipped += 1;
            Ok(())
        }
        Err(e) => Err(e),
    }
}

impl CommandSink for SerialActuators {
    fn poll(&mut self) -> Option<PlatformStatus> {
        self.fault.as_ref().map(|why| PlatformStatus {
            phase: PlatformPhase::Fault,
            in_phase_s: 0.0,
            detail: why.as_str().into(),
            code: Some("PORT FAILED".into()),
        })
    }

    fn send(&mut self, out: &PlatformOutput) -> std::io::Result<()> {
        if self.fault.is_some() {
            return Ok(());
        }
        let (port, skipped) = (&mut self.port, &mut self.skipped);
        if let Err(e) = self
            .stream
            .step(out, |bytes| write_port(port, bytes, skipped))
        {
            self.failed(e);
        }
        Ok(())
    }

    fn close(&mut self) -> std::io::Result<()> {
        if self.fault.is_some() {
            return Ok(());
        }
        let (port, skipped) = (&mut self.port, &mut self.skipped);
        let closed = self
            .stream
            .close(|bytes| write_port(port, bytes, skipped))
            .and_then(|()| port.flush());
        if let Err(e) = closed {
            self.failed(e);
        }
        Ok(())
    }

    fn describe(&self) -> String {
        format!("serial://{}?baud={}", self.path, self.baud)
    }
}

/// The actuator frame in one UDP datagram per frame.
pub struct UdpActuators {
    socket: UdpSocket,
    peer: SocketAddr,
    stream: ActuatorStream,
    reach: Reach,
}

impl UdpActuators {
    pub fn open(peer: SocketAddr, frame: FrameFormat) -> std::io::Result<Self> {
        Ok(UdpActuators {
            socket: connected_socket(peer)?,
            peer,
            stream: ActuatorStream::new(frame),
            reach: Reach::default(),
        })
    }
}

impl CommandSink for UdpActuators {
    fn poll(&mut self) -> Option<PlatformStatus> {
        self.reach.poll(&self.socket);
        None
    }

    fn send(&mut self, out: &PlatformOutput) -> std::io::Result<()> {
        let (socket, reach) = (&self.socket, &mut self.reach);
        self.stream
            .step(out, |bytes| reach.sent(socket.send(bytes)))
    }

    fn close(&mut self) -> std::io::Result<()> {
        let (socket, reach) = (&self.socket, &mut self.reach);
        self.stream.close(|bytes| reach.sent(socket.send(bytes)))
    }

    fn unreachable(&self) -> bool {
        self.reach.unreachable()
    }

    fn describe(&self) -> String {
        format!("udp://{}?frame=actuators", self.peer)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hexcue_core::actuators::{ActuatorPositions, Encoding};
    use hexcue_core::mca::AlgorithmId;
    use nalgebra::Vector6;

    fn output(state: SafetyState, stopped: bool, first: u32) -> PlatformOutput {
        PlatformOutput {
            t_s: 0.0,
            seq: 0,
            pose: Vector6::zeros(),
            velocity: Vector6::zeros(),
            acceleration: Vector6::zeros(),
            legs_m: Vector6::zeros(),
            state,
            stopped,
            algorithm: AlgorithmId::Cwf,
            actuators: Some(ActuatorPositions {
                counts: [first, 0, 0, 0, 0, 0],
                ..Default::default()
            }),
        }
    }

    /// Nothing before engaging, start then positions, the stop after the last position,
    /// nothing after it.
    #[test]
    fn start_positions_stop_in_that_order() {
        let frame = FrameFormat::new(
            "<Axis1a>,<Axis2a>,<Axis3a>,<Axis4a>,<Axis5a>,<Axis6a>X",
            "GO",
            "END",
            12,
            Encoding::Decimal,
        )
        .unwrap();
        let mut stream = ActuatorStream::new(frame);
        let mut sent: Vec<String> = Vec::new();
        let steps = [
            output(SafetyState::Parked, false, 1),
            output(SafetyState::Engaging, false, 2),
            output(SafetyState::Running, false, 3),
            output(SafetyState::Washout, false, 4),
            output(SafetyState::Parked, false, 5),
            output(SafetyState::Estop, false, 6),
            output(SafetyState::Parked, true, 7),
            output(SafetyState::Parked, true, 8),
        ];
        for s in &steps {
            stream
                .step(s, |b| {
                    sent.push(String::from_utf8(b.to_vec()).unwrap());
                    Ok::<(), ()>(())
                })
                .unwrap();
        }
        stream
            .close(|b| {
                sent.push(String::from_utf8(b.to_vec()).unwrap());
                Ok::<(), ()>(())
            })
            .unwrap();
        assert_eq!(
            sent,
            [
                "GO",
                "2,0,0,0,0,0X",
                "3,0,0,0,0,0X",
                "4,0,0,0,0,0X",
                "5,0,0,0,0,0X",
                "6,0,0,0,0,0X",
                "7,0,0,0,0,0X",
                "END"
            ]
        );
        // A session that ends while still moving (a fault) stops on close.
        let frame = FrameFormat::new(
            "<Axis1a><Axis2a><Axis3a><Axis4a><Axis5a><Axis6a>",
            "",
            "<0>",
            8,
            Encoding::Binary,
        )
        .unwrap();
        let mut stream = ActuatorStream::new(frame);
        let mut bytes = Vec::new();
        stream
            .step(&output(SafetyState::Running, false, 9), |b| {
                bytes.push(b.to_vec());
                Ok::<(), ()>(())
            })
            .unwrap();
        stream
            .close(|b| {
                bytes.push(b.to_vec());
                Ok::<(), ()>(())
            })
            .unwrap();
        assert_eq!(bytes, [vec![9, 0, 0, 0, 0, 0], vec![0]]);
    }
}
