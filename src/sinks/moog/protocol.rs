//! The Moog 6DOF2000E's datagrams in DOF mode, as a third-party driver of this base defines
//! them (ericloewe/MCIS, `src/include/MOOG6DOF2000E.h`; docs/live.md cites the lines): a
//! 32-byte command and the 40-byte status the base answers every command with, both
//! big-endian, every field 4 bytes. Pure: bytes in, values out.

use nalgebra::Vector6;

/// Motion command words (MCW).
pub mod mcw {
    /// Neutral poses until the base is engaged, then new positions to move to.
    pub const NEW_POSITION: u32 = 130;
    /// Clears a recoverable fault of a parked base.
    pub const RESET: u32 = 160;
    /// Select DOF mode (poses rather than actuator lengths).
    pub const DOF_MODE: u32 = 170;
    /// Raise the base to neutral: what the third-party driver sends until ENGAGED.
    pub const START: u32 = 175;
    /// The older engage word, listed beside START (not sent by hexcue).
    pub const ENGAGE: u32 = 180;
    /// Settle the base.
    pub const PARK: u32 = 210;
}

/// Bytes of a command.
pub const COMMAND_LEN: usize = 32;
/// Bytes of a status reply.
pub const STATUS_LEN: usize = 40;

/// A datagram of the wrong size.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("a Moog {what} is {expected} bytes; this datagram has {got}")]
pub struct WrongLength {
    pub what: &'static str,
    pub expected: usize,
    pub got: usize,
}

/// The six DoF in Moog's order: roll, pitch, heave, surge, yaw, lateral (rad, m; heave down
/// positive, from the base's zero).
pub type MoogDofs = [f32; 6];

/// hexcue's pose (x, y, z, roll, pitch, yaw from neutral; z down) in Moog's order, with the
/// heave the base needs at neutral added. Moog's z points down as hexcue's does, so heave is
/// +z: no sign change (docs/live.md, *Moog*, for the evidence).
pub fn to_moog(pose: &Vector6<f64>, neutral_heave_m: f64) -> MoogDofs {
    [
        pose[3],
        pose[4],
        pose[2] + neutral_heave_m,
        pose[0],
        pose[5],
        pose[1],
    ]
    .map(|v| v as f32)
}

/// hexcue's neutral pose in Moog's order.
pub fn neutral(neutral_heave_m: f64) -> MoogDofs {
    to_moog(&Vector6::zeros(), neutral_heave_m)
}

/// One command: the word, the six DoF, a spare word of 0.
pub fn encode_command(word: u32, dofs: &MoogDofs) -> [u8; COMMAND_LEN] {
    let mut b = [0u8; COMMAND_LEN];
    b[0..4].copy_from_slice(&word.to_be_bytes());
    for (i, v) in dofs.iter().enumerate() {
        b[4 + 4 * i..8 + 4 * i].copy_from_slice(&v.to_be_bytes());
    }
    b
}

fn word_at(b: &[u8], i: usize) -> u32 {
    u32::from_be_bytes([b[4 * i], b[4 * i + 1], b[4 * i + 2], b[4 * i + 3]])
}

/// A command back into its word and DoF (what a base, or the fake one, reads).
pub fn decode_command(b: &[u8]) -> Result<(u32, MoogDofs), WrongLength> {
    if b.len() != COMMAND_LEN {
        return Err(WrongLength {
            what: "command",
            expected: COMMAND_LEN,
            got: b.len(),
        });
    }
    Ok((
        word_at(b, 0),
        std::array::from_fn(|i| f32::from_bits(word_at(b, 1 + i))),
    ))
}

/// The encoded machine state: the low nibble of the machine-state word.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BaseState {
    PowerUp,
    Idle,
    Standby,
    Engaged,
    Parking,
    /// FAULT 1, 2 or 3 (8, 9, A).
    Fault(u8),
    Disabled,
    Inhibited,
    /// A nibble the interface does not define.
    Unknown(u8),
}

impl BaseState {
    pub fn from_nibble(n: u8) -> Self {
        match n & 0x0F {
            0x0 => BaseState::PowerUp,
            0x1 => BaseState::Idle,
            0x2 => BaseState::Standby,
            0x3 => BaseState::Engaged,
            0x7 => BaseState::Parking,
            n @ 0x8..=0xA => BaseState::Fault(n - 0x7),
            0xB => BaseState::Disabled,
            0xC => BaseState::Inhibited,
            n => BaseState::Unknown(n),
        }
    }

    pub fn nibble(self) -> u8 {
        match self {
            BaseState::PowerUp => 0x0,
            BaseState::Idle => 0x1,
            BaseState::Standby => 0x2,
            BaseState::Engaged => 0x3,
            BaseState::Parking => 0x7,
            BaseState::Fault(k) => 0x7 + k.clamp(1, 3),
            BaseState::Disabled => 0xB,
            BaseState::Inhibited => 0xC,
            BaseState::Unknown(n) => n & 0x0F,
        }
    }

    /// A state in which the base takes no pose: every motion command must stop.
    pub fn is_fault(self) -> bool {
        matches!(
            self,
            BaseState::Fault(_) | BaseState::Disabled | BaseState::Inhibited
        )
    }

    pub fn word(self) -> String {
        match self {
            BaseState::PowerUp => "POWER_UP".into(),
            BaseState::Idle => "IDLE".into(),
            BaseState::Standby => "STANDBY".into(),
            BaseState::Engaged => "ENGAGED".into(),
            BaseState::Parking => "PARKING".into(),
            BaseState::Fault(k) => format!("FAULT{k}"),
            BaseState::Disabled => "DISABLED".into(),
            BaseState::Inhibited => "INHIBITED".into(),
            BaseState::Unknown(n) => format!("state {n:#x}"),
        }
    }
}

/// Command modes, bits 0x60 of the machine-state word.
pub mod mode {
    pub const MASK: u32 = 0x60;
    pub const LENGTH: u32 = 0x00;
    pub const DOF: u32 = 0x20;
    pub const MDA: u32 = 0x40;
}

/// Discrete I/O bit: the base is at its settled (home) position.
pub const IO_BASE_AT_HOME: u32 = 0x01;

/// Latched fault bits and their names (all asserted on 1).
pub const FAULT_BITS: [(u32, &str); 16] = [
    (0x8000, "e-stop"),
    (0x4000, "snubber"),
    (0x2000, "actuator runaway"),
    (0x1000, "battery"),
    (0x0800, "low idle rate"),
    (0x0400, "motor thermal"),
    (0x0200, "command range"),
    (0x0100, "invalid frame"),
    (0x0080, "watchdog"),
    (0x0040, "limit switch"),
    (0x0020, "drive bus"),
    (0x0010, "amplifier"),
    (0x0008, "comm"),
    (0x0004, "homing"),
    (0x0002, "envelope"),
    (0x0001, "torque monitor"),
];

/// One status reply.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BaseStatus {
    pub latched_faults: u32,
    pub discrete_io: u32,
    pub machine_state: u32,
    /// Roll, pitch, heave, surge, yaw, lateral as the base measures them (Moog's order).
    pub feedback: MoogDofs,
}

impl BaseStatus {
    pub fn state(&self) -> BaseState {
        BaseState::from_nibble((self.machine_state & 0x0F) as u8)
    }

    pub fn in_dof_mode(&self) -> bool {
        self.machine_state & mode::MASK == mode::DOF
    }

    pub fn at_home(&self) -> bool {
        self.discrete_io & IO_BASE_AT_HOME != 0
    }

    /// The names of the latched faults, `none` when there are none.
    pub fn fault_names(&self) -> String {
        let names: Vec<&str> = FAULT_BITS
            .iter()
            .filter(|(bit, _)| self.latched_faults & bit != 0)
            .map(|(_, name)| *name)
            .collect();
        if names.is_empty() {
            "none".into()
        } else {
            names.join(", ")
        }
    }

    /// `STANDBY (machine state 0x22, DOF mode)`, with the latched faults when there are any.
    pub fn describe(&self) -> String {
        let mode = match self.machine_state & mode::MASK {
            mode::LENGTH => "length mode",
            mode::DOF => "DOF mode",
            mode::MDA => "MDA mode",
            _ => "invalid mode",
        };
        let mut s = format!(
            "{} (machine state {:#04x}, {mode})",
            self.state().word(),
            self.machine_state
        );
        if self.latched_faults != 0 {
            s.push_str(&format!(
                ", latched faults {:#06x}: {}",
                self.latched_faults,
                self.fault_names()
            ));
        }
        s
    }
}

/// A status reply as the base sends it (what the fake base sends).
pub fn encode_status(s: &BaseStatus) -> [u8; STATUS_LEN] {
    let mut b = [0u8; STATUS_LEN];
    let words = [s.latched_faults, s.discrete_io, s.machine_state]
        .into_iter()
        .chain(s.feedback.iter().map(|v| v.to_bits()))
        .chain([0]);
    for (i, w) in words.enumerate() {
        b[4 * i..4 * i + 4].copy_from_slice(&w.to_be_bytes());
    }
    b
}

pub fn decode_status(b: &[u8]) -> Result<BaseStatus, WrongLength> {
    if b.len() != STATUS_LEN {
        return Err(WrongLength {
            what: "status reply",
            expected: STATUS_LEN,
            got: b.len(),
        });
    }
    Ok(BaseStatus {
        latched_faults: word_at(b, 0),
        discrete_io: word_at(b, 1),
        machine_state: word_at(b, 2),
        feedback: std::array::from_fn(|i| f32::from_bits(word_at(b, 3 + i))),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_command_is_32_bytes_big_endian_in_moogs_order_heave_down() {
        // hexcue: 0.1 m forward, 0.2 m left, 0.05 m up (z = −0.05), small angles.
        let pose = Vector6::new(0.1, -0.2, -0.05, 0.01, -0.02, 0.03);
        let b = encode_command(mcw::NEW_POSITION, &to_moog(&pose, -0.2286));
        assert_eq!(b.len(), 32);
        assert_eq!(&b[0..4], &[0, 0, 0, 130]);
        let f = |i: usize| f32::from_be_bytes(b[4 + 4 * i..8 + 4 * i].try_into().unwrap());
        // roll, pitch, heave (down, with Rev E11's neutral), surge, yaw, lateral
        assert_eq!(
            [f(0), f(1), f(2), f(3), f(4), f(5)],
            [0.01, -0.02, (-0.05 - 0.2286) as f32, 0.1, 0.03, -0.2]
        );
        // Up is negative heave: the upward pose is further from zero than neutral.
        assert!(f(2) < neutral(-0.2286)[2]);
        assert_eq!(&b[28..32], &[0, 0, 0, 0]);
        assert_eq!(decode_command(&b).unwrap(), (130, to_moog(&pose, -0.2286)));
        // 0x3F800000 is 1.0f32 big-endian: the byte order pinned, not just round-tripped.
        let one = encode_command(mcw::PARK, &[1.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        assert_eq!(&one[0..8], &[0, 0, 0, 210, 0x3F, 0x80, 0, 0]);
    }

    #[test]
    fn a_status_reply_decodes_field_by_field() {
        let mut b = [0u8; 40];
        b[0..4].copy_from_slice(&0x0000_0080u32.to_be_bytes());
        b[4..8].copy_from_slice(&0x0000_0001u32.to_be_bytes());
        b[8..12].copy_from_slice(&0x0000_0028u32.to_be_bytes());
        for i in 0..6 {
            b[12 + 4 * i..16 + 4 * i].copy_from_slice(&(i as f32 * 0.5).to_be_bytes());
        }
        let s = decode_status(&b).unwrap();
        assert_eq!(s.latched_faults, 0x80);
        assert!(s.at_home());
        assert_eq!(s.state(), BaseState::Fault(1));
        assert!(s.state().is_fault());
        assert!(s.in_dof_mode());
        assert_eq!(s.feedback, [0.0, 0.5, 1.0, 1.5, 2.0, 2.5]);
        assert_eq!(s.fault_names(), "watchdog");
        assert!(s.describe().contains("FAULT1"), "{}", s.describe());
        assert_eq!(encode_status(&s), b);
        assert_eq!(
            decode_status(&b[..32]),
            Err(WrongLength {
                what: "status reply",
                expected: 40,
                got: 32
            })
        );
        assert!(decode_command(&b).is_err());
    }

    #[test]
    fn every_machine_state_nibble_reads_as_the_interface_lists_it() {
        use BaseState::*;
        let want = [
            (0x0, PowerUp, false),
            (0x1, Idle, false),
            (0x2, Standby, false),
            (0x3, Engaged, false),
            (0x7, Parking, false),
            (0x8, Fault(1), true),
            (0x9, Fault(2), true),
            (0xA, Fault(3), true),
            (0xB, Disabled, true),
            (0xC, Inhibited, true),
            (0x5, Unknown(5), false),
        ];
        for (n, state, fault) in want {
            // The mode bits above the nibble do not change the state.
            assert_eq!(BaseState::from_nibble(n | 0x20), state);
            assert_eq!(state.nibble(), n);
            assert_eq!(state.is_fault(), fault, "{state:?}");
        }
    }
}
