//! The byte frame an actuator controller takes, laid out by a template in the language of
//! SimTools, FlyPT Mover and SimHub's generic outputs (docs/live.md, *Actuator streams*):
//! `<AxisNa>` is actuator N's position (N = 1..6), `<n>` one byte of value n (0..255), and
//! anything else literal text. A template is compiled once, when the profile is loaded;
//! [`FrameFormat::encode_into`] then writes a frame into a buffer the caller keeps, with no
//! allocation once the buffer has grown to [`FrameFormat::max_len`].

use crate::vocab::ProfileError;

/// How a position is written into the frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoding {
    /// Big-endian, in ceil(bits / 8) bytes.
    Binary,
    /// ASCII decimal digits, no padding (`127`).
    Decimal,
    /// ASCII upper-case hexadecimal, zero-padded to ceil(bits / 4) digits (`07F` at 12 bits).
    Hex,
}

impl Encoding {
    /// The encoding a profile's `encoding` key names (`binary`, `decimal`, `hex`).
    pub fn from_key(key: &str) -> Option<Self> {
        match key {
            "binary" => Some(Encoding::Binary),
            "decimal" => Some(Encoding::Decimal),
            "hex" => Some(Encoding::Hex),
            _ => None,
        }
    }
}

/// One piece of a compiled template.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Piece {
    /// Bytes `start..end` of the template's literal bytes.
    Literal { start: usize, end: usize },
    /// The position of frame actuator `0..6`.
    Axis(usize),
}

/// A template compiled: its pieces in order and their literal bytes.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Template {
    pieces: Vec<Piece>,
    literals: Vec<u8>,
}

/// Where a template went wrong (the caller adds the key).
fn compile(text: &str, axes_allowed: bool) -> Result<Template, String> {
    let mut pieces = Vec::new();
    let mut literals = Vec::new();
    let mut literal_start = 0;
    let mut rest = text;
    let mut column = 1;
    let close_literal = |pieces: &mut Vec<Piece>, literals: &Vec<u8>, start: usize| {
        if literals.len() > start {
            pieces.push(Piece::Literal {
                start,
                end: literals.len(),
            });
        }
    };
    while let Some(open) = rest.find('<') {
        literals.extend_from_slice(&rest.as_bytes()[..open]);
        column += rest[..open].chars().count();
        let after = &rest[open + 1..];
        let Some(close) = after.find('>') else {
            return Err(format!(
                "`<` at character {column} is never closed; expected <AxisNa>, <n> (a byte, \
                 0-255) or literal text (write a literal `<` as <60>)"
            ));
        };
        let inner = &after[..close];
        if let Some(n) = inner
            .strip_prefix("Axis")
            .and_then(|s| s.strip_suffix('a'))
            .and_then(|n| n.parse::<usize>().ok())
            .filter(|n| (1..=6).contains(n) && inner.len() == 6)
        {
            if !axes_allowed {
                return Err(format!(
                    "<{inner}> at character {column}: a start or stop frame carries no \
                     position; expected <n> (a byte, 0-255) and literal text"
                ));
            }
            close_literal(&mut pieces, &literals, literal_start);
            pieces.push(Piece::Axis(n - 1));
            literal_start = literals.len();
        } else if let Some(byte) = (!inner.is_empty() && inner.bytes().all(|b| b.is_ascii_digit()))
            .then(|| inner.parse::<u8>().ok())
        {
            let Some(byte) = byte else {
                return Err(format!("<{inner}> at character {column}: a byte is 0-255"));
            };
            literals.push(byte);
        } else {
            return Err(format!(
                "<{inner}> at character {column}: expected <Axis1a> … <Axis6a> (actuator \
                 positions) or <0> … <255> (a byte)"
            ));
        }
        column += inner.chars().count() + 2;
        rest = &after[close + 1..];
    }
    literals.extend_from_slice(rest.as_bytes());
    close_literal(&mut pieces, &literals, literal_start);
    Ok(Template { pieces, literals })
}

/// Why bytes are not a frame of a template.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FrameParseError {
    /// The bytes end before the template does.
    #[error("the frame ends early (byte {at})")]
    Short {
        /// Index of the byte where the frame ended.
        at: usize,
    },
    /// A byte differs from the template's literal there.
    #[error("byte {at}: {found:#04x} where the template has {expected:#04x}")]
    Literal {
        /// Index of the byte.
        at: usize,
        /// The template's byte.
        expected: u8,
        /// The frame's byte.
        found: u8,
    },
    /// A position's byte is not a digit of the encoding.
    #[error("byte {at}: expected a digit of actuator {axis}'s position")]
    NotADigit {
        /// Index of the byte.
        at: usize,
        /// The actuator, from 0.
        axis: usize,
    },
    /// A position does not fit the resolution.
    #[error("actuator {axis}: {value} is beyond the {bits}-bit range")]
    OutOfRange {
        /// The actuator, from 0.
        axis: usize,
        /// The position read.
        value: u64,
        /// The resolution (bits).
        bits: u8,
    },
}

/// A compiled frame: the position template, the start and stop frames, the resolution and
/// the encoding.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FrameFormat {
    bits: u8,
    encoding: Encoding,
    template: Template,
    start: Vec<u8>,
    stop: Vec<u8>,
    max_len: usize,
}

impl FrameFormat {
    /// Compiles `template`, `start` and `stop` at `bits` (8–24) in `encoding`; errors name
    /// the key (`actuators.template`, …) and what was expected.
    pub fn new(
        template: &str,
        start: &str,
        stop: &str,
        bits: u32,
        encoding: Encoding,
    ) -> Result<Self, ProfileError> {
        let err = |key: &str, reason: String| ProfileError {
            key: format!("actuators.{key}"),
            reason,
        };
        if !(8..=24).contains(&bits) {
            return Err(err("bits", format!("{bits}: expected 8 to 24")));
        }
        let bits = bits as u8;
        let compiled = compile(template, true).map_err(|r| err("template", r))?;
        let mut seen = [0usize; 6];
        for p in &compiled.pieces {
            if let Piece::Axis(i) = p {
                seen[*i] += 1;
            }
        }
        for (i, n) in seen.iter().enumerate() {
            if *n != 1 {
                return Err(err(
                    "template",
                    format!(
                        "<Axis{}a> appears {n} times; expected each of <Axis1a> … <Axis6a> \
                         exactly once",
                        i + 1
                    ),
                ));
            }
        }
        if encoding == Encoding::Decimal {
            // Decimal digits have no fixed width: a controller finds the end of a number
            // at the first byte that is not a digit.
            for (k, p) in compiled.pieces.iter().enumerate() {
                let Piece::Axis(i) = p else { continue };
                let next = compiled.pieces.get(k + 1).map(|n| match n {
                    Piece::Literal { start, .. } => Some(compiled.literals[*start]),
                    Piece::Axis(_) => None,
                });
                match next {
                    Some(Some(b)) if !b.is_ascii_digit() => {}
                    _ => {
                        return Err(err(
                            "template",
                            format!(
                                "<Axis{}a> is not followed by a separator that is not a digit; \
                                 with encoding = \"decimal\" a controller cannot tell where the \
                                 number ends (e.g. <Axis1a>,<Axis2a>…X)",
                                i + 1
                            ),
                        ))
                    }
                }
            }
        }
        let start = compile(start, false).map_err(|r| err("start", r))?.literals;
        let stop = compile(stop, false).map_err(|r| err("stop", r))?.literals;
        let mut format = FrameFormat {
            bits,
            encoding,
            template: compiled,
            start,
            stop,
            max_len: 0,
        };
        format.max_len = format.template.literals.len() + 6 * format.width();
        Ok(format)
    }

    /// Resolution of a position (bits).
    pub fn bits(&self) -> u8 {
        self.bits
    }

    /// How positions are written.
    pub fn encoding(&self) -> Encoding {
        self.encoding
    }

    /// The largest position: 2^bits − 1.
    pub fn full_scale(&self) -> u32 {
        (1u32 << self.bits) - 1
    }

    /// Characters (or bytes) of one position at most.
    fn width(&self) -> usize {
        let bits = self.bits as usize;
        match self.encoding {
            Encoding::Binary => bits.div_ceil(8),
            Encoding::Hex => bits.div_ceil(4),
            // 2^24 − 1 = 16777215: 8 digits.
            Encoding::Decimal => decimal_digits(self.full_scale()),
        }
    }

    /// The longest position frame.
    pub fn max_len(&self) -> usize {
        self.max_len
    }

    /// Sent once when the platform engages (may be empty).
    pub fn start(&self) -> &[u8] {
        &self.start
    }

    /// Sent once after the platform has parked for good (may be empty).
    pub fn stop(&self) -> &[u8] {
        &self.stop
    }

    /// Writes the frame of `positions` (frame actuators 1..6, each at most
    /// [`FrameFormat::full_scale`]) into `out`, replacing what it held. No allocation once
    /// `out` has [`FrameFormat::max_len`] of capacity.
    pub fn encode_into(&self, positions: &[u32; 6], out: &mut Vec<u8>) {
        out.clear();
        let width = self.width();
        for p in &self.template.pieces {
            match *p {
                Piece::Literal { start, end } => {
                    out.extend_from_slice(&self.template.literals[start..end])
                }
                Piece::Axis(i) => {
                    let v = positions[i].min(self.full_scale());
                    match self.encoding {
                        Encoding::Binary => {
                            let be = v.to_be_bytes();
                            out.extend_from_slice(&be[4 - width..]);
                        }
                        Encoding::Hex => {
                            for k in (0..width).rev() {
                                out.push(b"0123456789ABCDEF"[((v >> (4 * k)) & 0xF) as usize]);
                            }
                        }
                        Encoding::Decimal => {
                            let digits = decimal_digits(v);
                            for k in (0..digits).rev() {
                                out.push(b'0' + ((v / 10u32.pow(k as u32)) % 10) as u8);
                            }
                        }
                    }
                }
            }
        }
    }

    /// Reads one frame from the start of `bytes`: the six positions and the bytes it took.
    /// The inverse of [`FrameFormat::encode_into`], for tests and fake controllers.
    pub fn parse(&self, bytes: &[u8]) -> Result<([u32; 6], usize), FrameParseError> {
        let mut at = 0;
        let mut positions = [0u32; 6];
        let width = self.width();
        let byte = |at: usize| bytes.get(at).copied().ok_or(FrameParseError::Short { at });
        for p in &self.template.pieces {
            match *p {
                Piece::Literal { start, end } => {
                    for &expected in &self.template.literals[start..end] {
                        let found = byte(at)?;
                        if found != expected {
                            return Err(FrameParseError::Literal {
                                at,
                                expected,
                                found,
                            });
                        }
                        at += 1;
                    }
                }
                Piece::Axis(i) => {
                    let mut v: u64 = 0;
                    match self.encoding {
                        Encoding::Binary => {
                            for _ in 0..width {
                                v = (v << 8) | byte(at)? as u64;
                                at += 1;
                            }
                        }
                        Encoding::Hex => {
                            for _ in 0..width {
                                let b = byte(at)?;
                                let d = (b as char)
                                    .to_digit(16)
                                    .ok_or(FrameParseError::NotADigit { at, axis: i + 1 })?;
                                v = (v << 4) | d as u64;
                                at += 1;
                            }
                        }
                        Encoding::Decimal => {
                            let first = at;
                            while let Some(b) = bytes.get(at).filter(|b| b.is_ascii_digit()) {
                                v = (v * 10 + (b - b'0') as u64).min(u64::MAX / 20);
                                at += 1;
                            }
                            if at == first {
                                byte(at)?;
                                return Err(FrameParseError::NotADigit { at, axis: i + 1 });
                            }
                        }
                    }
                    if v > self.full_scale() as u64 {
                        return Err(FrameParseError::OutOfRange {
                            axis: i + 1,
                            value: v,
                            bits: self.bits,
                        });
                    }
                    positions[i] = v as u32;
                }
            }
        }
        Ok((positions, at))
    }
}

fn decimal_digits(v: u32) -> usize {
    let mut digits = 1;
    let mut rest = v / 10;
    while rest > 0 {
        digits += 1;
        rest /= 10;
    }
    digits
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn frame(template: &str, bits: u32, encoding: Encoding, positions: [u32; 6]) -> Vec<u8> {
        let f = FrameFormat::new(template, "", "", bits, encoding).unwrap();
        let mut out = Vec::new();
        f.encode_into(&positions, &mut out);
        assert!(out.len() <= f.max_len());
        let (back, used) = f.parse(&out).unwrap();
        assert_eq!((back, used), (positions, out.len()));
        out
    }

    /// Motion4Sim's direct mode at 24 bits (docs.motion4sim.com, *Flypt Mover*): 28 bytes.
    #[test]
    fn motion4sim_24_bit_binary() {
        let out = frame(
            "<255><255><Axis1a><Axis2a><Axis3a><Axis4a><Axis5a><Axis6a>000000<10><13>",
            24,
            Encoding::Binary,
            [0, 0xFFFFFF, 0x7FFFFF, 0x123456, 1, 0xABCDEF],
        );
        let mut want = vec![0xFF, 0xFF];
        want.extend([
            0, 0, 0, 0xFF, 0xFF, 0xFF, 0x7F, 0xFF, 0xFF, 0x12, 0x34, 0x56,
        ]);
        want.extend([0, 0, 1, 0xAB, 0xCD, 0xEF]);
        want.extend(b"000000");
        want.extend([10, 13]);
        assert_eq!(out, want);
        assert_eq!(out.len(), 28);
    }

    /// FlyPT Mover to ODrive, 16 bits: a letter and the axis number between the positions.
    #[test]
    fn flypt_odrive_16_bit_binary() {
        let out = frame(
            "<255><255>F1<Axis1a>2<Axis2a>3<Axis3a>4<Axis4a>5<Axis5a>6<Axis6a>!",
            16,
            Encoding::Binary,
            [0, 65535, 32768, 0x0102, 0x00FF, 0xFF00],
        );
        let want: Vec<u8> = [
            &[0xFF, 0xFF][..],
            b"F1",
            &[0, 0],
            b"2",
            &[0xFF, 0xFF],
            b"3",
            &[0x80, 0x00],
            b"4",
            &[0x01, 0x02],
            b"5",
            &[0x00, 0xFF],
            b"6",
            &[0xFF, 0x00],
            b"!",
        ]
        .concat();
        assert_eq!(out, want);
    }

    /// SimTools to the knaufinator ESP32: 12-bit decimal, comma-separated, ended by X.
    #[test]
    fn simtools_esp32_12_bit_decimal() {
        let out = frame(
            "<Axis1a>,<Axis2a>,<Axis3a>,<Axis4a>,<Axis5a>,<Axis6a>X",
            12,
            Encoding::Decimal,
            [0, 4095, 2048, 7, 10, 999],
        );
        assert_eq!(out, b"0,4095,2048,7,10,999X");
    }

    /// SMC3-style: a letter before each position, 10-bit hex here (three digits each).
    #[test]
    fn smc3_style_hex() {
        let out = frame(
            "P<Axis1a><Axis2a><Axis3a><Axis4a><Axis5a><Axis6a><13>",
            10,
            Encoding::Hex,
            [0, 1023, 512, 0x0AB, 1, 0x3FE],
        );
        assert_eq!(out, b"P0003FF2000AB0013FE\r");
        let out = frame(
            "P<Axis1a><Axis2a><Axis3a><Axis4a><Axis5a><Axis6a>",
            8,
            Encoding::Binary,
            [0, 255, 128, 1, 2, 3],
        );
        assert_eq!(out, [b'P', 0, 255, 128, 1, 2, 3]);
    }

    #[test]
    fn start_and_stop_frames_are_bytes_and_text() {
        let f = FrameFormat::new(
            "<Axis1a>,<Axis2a>,<Axis3a>,<Axis4a>,<Axis5a>,<Axis6a>X",
            "<249><249><0><6><0><1><10><13>",
            "S<13><10>",
            12,
            Encoding::Decimal,
        )
        .unwrap();
        assert_eq!(f.start(), [249, 249, 0, 6, 0, 1, 10, 13]);
        assert_eq!(f.stop(), b"S\r\n");
    }

    fn reason(template: &str, start: &str, bits: u32, encoding: Encoding) -> ProfileError {
        FrameFormat::new(template, start, "", bits, encoding).unwrap_err()
    }

    #[test]
    fn a_bad_template_is_refused_with_its_key_and_what_was_expected() {
        let all = "<Axis1a><Axis2a><Axis3a><Axis4a><Axis5a><Axis6a>";
        let e = reason(all, "", 300, Encoding::Binary);
        assert_eq!(e.key, "actuators.bits");
        assert!(e.reason.contains("8 to 24"), "{e}");
        let e = reason(&format!("{all}<Axis7a>"), "", 16, Encoding::Binary);
        assert_eq!(e.key, "actuators.template");
        assert!(
            e.reason.contains("<Axis7a>") && e.reason.contains("character 49"),
            "{e}"
        );
        let e = reason(&format!("{all}<256>"), "", 16, Encoding::Binary);
        assert!(e.reason.contains("0-255"), "{e}");
        let e = reason(&format!("{all}<13"), "", 16, Encoding::Binary);
        assert!(e.reason.contains("never closed"), "{e}");
        let e = reason(
            "<Axis1a><Axis2a><Axis3a><Axis4a><Axis5a>",
            "",
            16,
            Encoding::Binary,
        );
        assert!(e.reason.contains("<Axis6a> appears 0 times"), "{e}");
        let e = reason(&format!("{all}<Axis1a>"), "", 16, Encoding::Binary);
        assert!(e.reason.contains("<Axis1a> appears 2 times"), "{e}");
        // Decimal numbers need a separator that is not a digit.
        let e = reason(
            "<Axis1a>,<Axis2a>,<Axis3a>,<Axis4a>,<Axis5a>,<Axis6a>",
            "",
            12,
            Encoding::Decimal,
        );
        assert!(
            e.reason.contains("<Axis6a>") && e.reason.contains("separator"),
            "{e}"
        );
        let e = reason(
            "<Axis1a>0<Axis2a>,<Axis3a>,<Axis4a>,<Axis5a>,<Axis6a>X",
            "",
            12,
            Encoding::Decimal,
        );
        assert!(e.reason.contains("<Axis1a>"), "{e}");
        // The same template in hex is fine: fixed width.
        FrameFormat::new(all, "", "", 12, Encoding::Hex).unwrap();
        let e = reason(all, "<Axis1a>", 12, Encoding::Hex);
        assert_eq!(e.key, "actuators.start");
        assert!(e.reason.contains("no position"), "{e}");
    }

    #[test]
    fn parsing_tells_a_frame_from_noise() {
        let f = FrameFormat::new(
            "<255><255><Axis1a><Axis2a><Axis3a><Axis4a><Axis5a><Axis6a><10><13>",
            "",
            "",
            16,
            Encoding::Binary,
        )
        .unwrap();
        assert_eq!(
            f.parse(&[0xFF, 0x00]),
            Err(FrameParseError::Literal {
                at: 1,
                expected: 0xFF,
                found: 0
            })
        );
        assert_eq!(
            f.parse(&[0xFF, 0xFF, 1]),
            Err(FrameParseError::Short { at: 3 })
        );
        let d = FrameFormat::new(
            "<Axis1a>,<Axis2a>,<Axis3a>,<Axis4a>,<Axis5a>,<Axis6a>X",
            "",
            "",
            12,
            Encoding::Decimal,
        )
        .unwrap();
        assert_eq!(
            d.parse(b"1,2,3,4,5,4096X"),
            Err(FrameParseError::OutOfRange {
                axis: 6,
                value: 4096,
                bits: 12
            })
        );
        assert_eq!(
            d.parse(b"1,,3,4,5,6X"),
            Err(FrameParseError::NotADigit { at: 2, axis: 2 })
        );
    }

    fn encoding() -> impl Strategy<Value = Encoding> {
        prop_oneof![
            Just(Encoding::Binary),
            Just(Encoding::Decimal),
            Just(Encoding::Hex)
        ]
    }

    proptest! {
        /// Any positions in range, any resolution and encoding, separators of any bytes
        /// that keep decimal numbers apart: what is encoded parses back to itself, and
        /// takes the whole frame.
        #[test]
        fn encode_then_parse_is_the_identity(
            bits in 8u32..=24,
            enc in encoding(),
            raw in prop::array::uniform6(any::<u32>()),
            header in prop::collection::vec(any::<u8>(), 0..4),
            seps in prop::array::uniform6(prop::collection::vec(0u8..=255, 1..3)),
        ) {
            let mut template = String::new();
            for b in &header {
                template.push_str(&format!("<{b}>"));
            }
            for (i, sep) in seps.iter().enumerate() {
                template.push_str(&format!("<Axis{}a>", i + 1));
                for (k, b) in sep.iter().enumerate() {
                    // The first separator byte of a decimal number must not be a digit.
                    let b = if k == 0 && b.is_ascii_digit() { b'|' } else { *b };
                    template.push_str(&format!("<{b}>"));
                }
            }
            let f = FrameFormat::new(&template, "", "", bits, enc).unwrap();
            let positions = raw.map(|v| v % (f.full_scale() + 1));
            let mut out = Vec::with_capacity(f.max_len());
            let capacity = out.capacity();
            f.encode_into(&positions, &mut out);
            prop_assert_eq!(out.capacity(), capacity, "no allocation");
            let (back, used) = f.parse(&out).unwrap();
            prop_assert_eq!(back, positions);
            prop_assert_eq!(used, out.len());
        }
    }
}
