//! hexcue's own topics as JSON (Foxglove's `json` message encoding with `jsonschema`
//! schemas): the messages a frame becomes, as written and as read back, and their schemas.

use nalgebra::{Vector3, Vector6};
use schemars::generate::SchemaSettings;
use schemars::JsonSchema;
use serde::{Deserialize, Deserializer, Serialize};

use hexcue_core::engine::{Frame, LaneFrame, Legs};
use hexcue_core::mca::{AlgorithmState, PlatformCommand, SolverReport};
use hexcue_core::model::vestibular::Perceived;
use hexcue_core::vocab::SwitchReason;

use super::{Channel, Kind};

// ---------------------------------------------------------------------------------------------
// Messages, as written and as read. Non-finite numbers become JSON `null` on the way out and
// NaN on the way back: JSON has no NaN, and a recording must never fail for a value.

fn nan_f64<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

fn nan_array<'de, D: Deserializer<'de>, const N: usize>(d: D) -> Result<[f64; N], D::Error> {
    let values = Vec::<Option<f64>>::deserialize(d)?;
    if values.len() != N {
        return Err(serde::de::Error::invalid_length(
            values.len(),
            &format!("an array of {N} numbers").as_str(),
        ));
    }
    Ok(std::array::from_fn(|i| values[i].unwrap_or(f64::NAN)))
}

/// How finely a recording keeps each quantity, and how it writes it: what a frame reads back
/// as. The digits beyond are noise that zstd cannot shrink, and they were most of the file;
/// numbers written with all their digits (`0.270900`, `-3.62862e-7`), one format a quantity,
/// compress 6 % better than the shortest form (docs/recordings.md, "Size per minute"). Files
/// written before keep their full digits and read the same way. Non-finite values are
/// written `null` and read back as NaN; −0 is written as 0.
pub mod resolution {
    use std::io::Write;

    /// `x` rounded to `10^-decimals` (decimals ≤ 22, where the power of ten is exact, so the
    /// quotient is the f64 nearest the decimal that [`write_fixed`] writes).
    fn rounded(x: f64, decimals: u32) -> f64 {
        let scale = 10f64.powi(decimals as i32);
        (x * scale).round() / scale + 0.0
    }

    /// Platform pose and leg lengths: 1 µm and 1 µrad, finer than a hexapod's actuator
    /// encoders resolve, and finer than `review` needs: its leg usage must agree with the
    /// run's within 10⁻⁵ relative, and 1 µm is 7 × 10⁻⁶ of the compact rig's half-stroke.
    pub const POSITION_DECIMALS: u32 = 6;
    /// Platform and leg velocities: 1 mm/s and 10⁻³ rad/s (0.06 °/s, 1/50 of the 3 °/s
    /// rotation threshold). Nothing `review` computes reads them. Was 0.1 mm/s (docs/
    /// recordings.md, "3D topics at 33 Hz").
    pub const VELOCITY_DECIMALS: u32 = 3;
    /// Platform accelerations: 1 mm/s² and 10⁻³ rad/s², 1/170 of the 0.17 m/s² specific-force
    /// threshold, about the noise of an accelerometer on a motion base; over a step that is
    /// 10⁻⁵ m/s, below the velocity's resolution. Nothing `review` computes reads them.
    pub const ACCELERATION_DECIMALS: u32 = 3;
    /// The aircraft's and the perceived signals: significant digits, relative (5 × 10⁻⁶ at
    /// worst), because a quiet flight's perceived rates are a few µrad/s and `review`
    /// recomputes their metrics (AAS, RAE: ratios of sums) from them, to agree with the run's
    /// within 10⁻⁵ (`tests/headless.rs`); with 5 digits the take-off's fx NAAD moved by
    /// 1.8 × 10⁻⁵.
    pub const SIGNAL_DIGITS: u32 = 6;

    pub fn position(x: f64) -> f64 {
        rounded(x, POSITION_DECIMALS)
    }

    pub fn velocity(x: f64) -> f64 {
        rounded(x, VELOCITY_DECIMALS)
    }

    pub fn acceleration(x: f64) -> f64 {
        rounded(x, ACCELERATION_DECIMALS)
    }

    /// Durations measured by the wall clock in µs (solve and step times): 1 µs, the jitter of
    /// a step, as the console shows them (`12µs`). Was 0.1 µs (docs/recordings.md, "3D
    /// topics at 33 Hz").
    pub fn duration_us(x: f64) -> f64 {
        rounded(x, 0)
    }

    /// Trace-time durations in s (time in mode): 1 ns, as log times; the digits beyond were
    /// sums of 0.01 s steps in binary.
    pub fn time_s(x: f64) -> f64 {
        rounded(x, 9)
    }

    /// Writes `x` with exactly `decimals` decimals (`-0.270900`), as [`rounded`] keeps it.
    pub fn write_fixed(out: &mut Vec<u8>, x: f64, decimals: u32) {
        let scale = 10f64.powi(decimals as i32);
        let n = (x * scale).round();
        // Beyond 2^53 the integer is no longer exact; no platform gets there.
        if !n.is_finite() || n.abs() >= 9.0e15 {
            return write_shortest(out, rounded(x, decimals));
        }
        let n = n as i64;
        let unit = 10i64.pow(decimals);
        let sign = if n < 0 { "-" } else { "" };
        let (int, frac) = (
            n.unsigned_abs() / unit as u64,
            n.unsigned_abs() % unit as u64,
        );
        let _ = write!(out, "{sign}{int}.{frac:0width$}", width = decimals as usize);
    }

    /// The significant digits of `x`: (mantissa as an integer of `digits` digits, decimal
    /// exponent of its last digit), or `None` for 0 and non-finite values.
    fn significant(x: f64, digits: u32) -> Option<(i64, i32)> {
        if x == 0.0 || !x.is_finite() {
            return None;
        }
        let top = 10i64.pow(digits);
        let mut e = x.abs().log10().floor() as i32 - (digits as i32 - 1);
        for _ in 0..3 {
            // Scaled by an exact power of ten (|e| ≤ 22), so that the integer is the decimal's.
            let m = if (-22..=0).contains(&e) {
                (x.abs() * 10f64.powi(-e)).round()
            } else if (1..=22).contains(&e) {
                (x.abs() / 10f64.powi(e)).round()
            } else {
                return None;
            };
            if m >= top as f64 {
                e += 1;
            } else if m < (top / 10) as f64 {
                e -= 1;
            } else {
                return Some((if x < 0.0 { -(m as i64) } else { m as i64 }, e));
            }
        }
        None
    }

    /// `x` at [`SIGNAL_DIGITS`] significant digits.
    pub fn signal(x: f64) -> f64 {
        match significant(x, SIGNAL_DIGITS) {
            Some((m, e)) if e <= 0 => m as f64 / 10f64.powi(-e),
            Some((m, e)) => m as f64 * 10f64.powi(e),
            None if x == 0.0 || !x.is_finite() => x + 0.0,
            // Beyond 10^±22 (never a motion), through the decimal text.
            None => format!("{x:.*e}", SIGNAL_DIGITS as usize - 1)
                .parse()
                .unwrap_or(x),
        }
    }

    /// Writes `x` at [`SIGNAL_DIGITS`] significant digits, always as `d.ddddde±x`
    /// (`-3.62862e-7`, `1.28993e1`), the value [`signal`] keeps.
    pub fn write_signal(out: &mut Vec<u8>, x: f64) {
        let Some((m, e)) = significant(x, SIGNAL_DIGITS) else {
            return write_shortest(out, signal(x));
        };
        let unit = 10u64.pow(SIGNAL_DIGITS - 1);
        let sign = if m < 0 { "-" } else { "" };
        let (int, frac) = (m.unsigned_abs() / unit, m.unsigned_abs() % unit);
        let exp = e + SIGNAL_DIGITS as i32 - 1;
        let width = SIGNAL_DIGITS as usize - 1;
        let _ = write!(out, "{sign}{int}.{frac:0width$}e{exp}");
    }

    /// serde_json's form: the shortest text that reads back to `x`, `null` if not finite.
    pub(super) fn write_shortest(out: &mut Vec<u8>, x: f64) {
        let _ = serde_json::to_writer(out, &x);
    }
}

/// A serialiser of an array written through one of [`resolution`]'s functions.
macro_rules! array_at {
    ($name:ident, $f:path) => {
        fn $name<S: serde::Serializer, const N: usize>(
            v: &[f64; N],
            s: S,
        ) -> Result<S::Ok, S::Error> {
            s.collect_seq(v.iter().map(|&x| $f(x)))
        }
    };
}
array_at!(position_array, resolution::position);
array_at!(velocity_array, resolution::velocity);
array_at!(acceleration_array, resolution::acceleration);
array_at!(signal_array, resolution::signal);

fn duration_us<S: serde::Serializer>(x: &f64, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_f64(resolution::duration_us(*x))
}

fn time_s<S: serde::Serializer>(x: &f64, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_f64(resolution::time_s(*x))
}

fn v3(v: &Vector3<f64>) -> [f64; 3] {
    [v.x, v.y, v.z]
}

fn v6(v: &Vector6<f64>) -> [f64; 6] {
    std::array::from_fn(|i| v[i])
}

#[derive(Debug, Serialize, Deserialize, JsonSchema)]
#[schemars(
    title = "hexcue.Aircraft",
    description = "Aircraft motion at the pilot's head, head frame (x forward, y right, z down)"
)]
pub struct AircraftMsg {
    #[serde(deserialize_with = "nan_f64")]
    #[schemars(with = "f64", description = "trace time (s)")]
    pub t: f64,
    /// Step index; absent from files other tools wrote, then counted.
    #[serde(default)]
    #[schemars(description = "step index")]
    pub k: Option<u64>,
    #[serde(deserialize_with = "nan_array", serialize_with = "signal_array")]
    #[schemars(
        with = "[Option<f64>; 3]",
        description = "f = a − g, x y z (m/s²); (0, 0, −9.81) at rest"
    )]
    pub specific_force: [f64; 3],
    #[serde(deserialize_with = "nan_array", serialize_with = "signal_array")]
    #[schemars(with = "[Option<f64>; 3]", description = "body rates p q r (rad/s)")]
    pub angular_velocity: [f64; 3],
    #[serde(deserialize_with = "nan_array", serialize_with = "signal_array")]
    #[schemars(with = "[Option<f64>; 3]", description = "roll pitch yaw φ θ ψ (rad)")]
    pub attitude: [f64; 3],
}

#[derive(Debug, Serialize, Deserialize, JsonSchema)]
#[schemars(
    title = "hexcue.Perceived",
    description = "Perceived motion: vestibular model output"
)]
pub struct PerceivedMsg {
    #[serde(deserialize_with = "nan_f64")]
    #[schemars(with = "f64", description = "trace time (s)")]
    pub t: f64,
    #[serde(deserialize_with = "nan_array", serialize_with = "signal_array")]
    #[schemars(
        with = "[Option<f64>; 3]",
        description = "otoliths' output for Δf, x y z head frame (m/s²)"
    )]
    pub specific_force: [f64; 3],
    #[serde(deserialize_with = "nan_array", serialize_with = "signal_array")]
    #[schemars(
        with = "[Option<f64>; 3]",
        description = "canals' output, x y z head frame (rad/s)"
    )]
    pub angular_velocity: [f64; 3],
}

impl PerceivedMsg {
    pub fn new(t: f64, p: &Perceived) -> Self {
        PerceivedMsg {
            t,
            specific_force: v3(&p.specific_force_mps2),
            angular_velocity: v3(&p.angular_velocity_radps),
        }
    }

    pub fn perceived(&self) -> Perceived {
        Perceived {
            specific_force_mps2: self.specific_force.into(),
            angular_velocity_radps: self.angular_velocity.into(),
        }
    }
}

impl AircraftMsg {
    pub fn new(frame: &Frame) -> Self {
        let a = &frame.aircraft;
        AircraftMsg {
            t: frame.t_s,
            k: Some(frame.k as u64),
            specific_force: v3(&a.specific_force_mps2),
            angular_velocity: v3(&a.angular_velocity_radps),
            attitude: v3(&a.attitude_rad),
        }
    }
}

#[derive(Debug, Serialize, Deserialize, JsonSchema)]
#[schemars(
    title = "hexcue.Platform",
    description = "Platform command after the limiter, simulator inertial frame (x y z (m), roll pitch yaw (rad), Z-Y-X Euler)"
)]
pub struct PlatformMsg {
    #[serde(deserialize_with = "nan_f64")]
    #[schemars(with = "f64", description = "trace time (s)")]
    pub t: f64,
    #[serde(deserialize_with = "nan_array", serialize_with = "position_array")]
    #[schemars(
        with = "[Option<f64>; 6]",
        description = "x y z (m), roll pitch yaw (rad) from neutral"
    )]
    pub pose: [f64; 6],
    #[serde(deserialize_with = "nan_array", serialize_with = "velocity_array")]
    #[schemars(
        with = "[Option<f64>; 6]",
        description = "first derivative of pose (m/s, rad/s)"
    )]
    pub velocity: [f64; 6],
    #[serde(deserialize_with = "nan_array", serialize_with = "acceleration_array")]
    #[schemars(
        with = "[Option<f64>; 6]",
        description = "second derivative of pose (m/s², rad/s²)"
    )]
    pub acceleration: [f64; 6],
}

impl PlatformMsg {
    pub fn new(t: f64, c: &PlatformCommand) -> Self {
        PlatformMsg {
            t,
            pose: v6(&c.pose),
            velocity: v6(&c.velocity),
            acceleration: v6(&c.acceleration),
        }
    }
}

#[derive(Debug, Serialize, Deserialize, JsonSchema)]
#[schemars(
    title = "hexcue.Actuators",
    description = "Legs 1..6 of the Stewart platform"
)]
pub struct ActuatorsMsg {
    #[serde(deserialize_with = "nan_f64")]
    #[schemars(with = "f64", description = "trace time (s)")]
    pub t: f64,
    #[serde(deserialize_with = "nan_array", serialize_with = "position_array")]
    #[schemars(with = "[Option<f64>; 6]", description = "leg lengths (m)")]
    pub length: [f64; 6],
    #[serde(deserialize_with = "nan_array", serialize_with = "velocity_array")]
    #[schemars(with = "[Option<f64>; 6]", description = "leg velocities (m/s)")]
    pub velocity: [f64; 6],
    /// Not written since format 2: each is `min(length − leg_min_m, leg_max_m − length)`,
    /// which readers compute from `length` and the attached profile (docs/recordings.md,
    /// "Leg margins"). Files written before carry it, and it is read from them; absent, it
    /// reads as NaN until the reader fills it.
    #[serde(
        default = "absent_margins",
        deserialize_with = "nan_array",
        skip_serializing
    )]
    #[schemars(
        with = "Option<[Option<f64>; 6]>",
        description = "distance to the nearer end stop (m); < 0 outside; only in files of format 1, computed from length since"
    )]
    pub margin: [f64; 6],
}

fn absent_margins() -> [f64; 6] {
    [f64::NAN; 6]
}

impl ActuatorsMsg {
    pub fn new(t: f64, l: &Legs) -> Self {
        ActuatorsMsg {
            t,
            length: v6(&l.length_m),
            velocity: v6(&l.velocity_mps),
            margin: v6(&l.margin_m),
        }
    }
}

#[derive(Debug, Serialize, Deserialize, JsonSchema)]
pub struct SolverMsg {
    pub name: String,
    pub status: String,
    pub iterations: u32,
    #[serde(deserialize_with = "nan_f64", serialize_with = "duration_us")]
    #[schemars(with = "Option<f64>", required)]
    pub solve_time_us: f64,
}

#[derive(Debug, Serialize, Deserialize, JsonSchema)]
#[schemars(
    title = "hexcue.Controller",
    description = "State of a motion cueing algorithm"
)]
pub struct ControllerMsg {
    #[serde(deserialize_with = "nan_f64")]
    #[schemars(with = "f64", description = "trace time (s)")]
    pub t: f64,
    #[schemars(extend("enum" = ["washout", "mpc", "cotc", "free", "blend", "fallback"]))]
    pub mode: String,
    #[schemars(description = "mixer weight w while blending (0 previous, 1 next)")]
    pub blend: Option<f64>,
    /// The solvers' statuses joined by `+` (`none` without a QP): one word to plot.
    #[schemars(description = "solver statuses joined by +, `none` without a QP")]
    pub status: String,
    /// Iterations and solve time of all of the step's QPs together.
    #[schemars(description = "all QPs of the step")]
    pub iterations: u64,
    #[serde(deserialize_with = "nan_f64", serialize_with = "duration_us")]
    #[schemars(
        with = "Option<f64>",
        required,
        description = "all QPs of the step (µs)"
    )]
    pub solve_time_us: f64,
    pub limiter_active: bool,
    #[serde(deserialize_with = "nan_f64", serialize_with = "duration_us")]
    #[schemars(
        with = "Option<f64>",
        required,
        description = "wall time of the step, limiter included (µs)"
    )]
    pub step_time_us: f64,
    #[serde(deserialize_with = "nan_f64", serialize_with = "time_s")]
    #[schemars(with = "Option<f64>", required)]
    pub time_in_mode_s: f64,
    pub switch_count: u32,
    pub last_switch_reason: Option<String>,
    pub solvers: Vec<SolverMsg>,
}

/// A lane's `/ALG/controller` message as a step writes it: borrowed from the frame, so that
/// building it allocates nothing (the owned [`ControllerMsg`] is what a reader gets back, and
/// its serde form is the same JSON: test `the_borrowed_controller_writes_the_owned_json`).
#[derive(Debug, Serialize)]
pub struct ControllerOut<'a> {
    t: f64,
    mode: &'static str,
    blend: Option<f64>,
    status: StatusWords<'a>,
    iterations: u64,
    #[serde(serialize_with = "duration_us")]
    solve_time_us: f64,
    limiter_active: bool,
    #[serde(serialize_with = "duration_us")]
    step_time_us: f64,
    #[serde(serialize_with = "time_s")]
    time_in_mode_s: f64,
    switch_count: u32,
    /// Serialised as its text, as [`SwitchReason`]'s `Serialize` writes it.
    last_switch_reason: Option<&'a SwitchReason>,
    solvers: SolversOut<'a>,
}

/// The words of a lane's state that the JSON carries, where the core's types become text: the
/// switch reason, and each solver's name and status. The one place to change if those
/// become enums (their JSON words must stay).
fn state_words(state: &AlgorithmState) -> Option<&SwitchReason> {
    state.last_switch_reason.as_ref()
}

/// A solver's name and status word (see [`state_words`]).
fn solver_words(report: &SolverReport) -> (&str, &'static str) {
    (report.name.word(), report.status.as_str())
}

impl<'a> ControllerOut<'a> {
    pub fn new(t: f64, lane: &'a LaneFrame) -> Self {
        let s = &lane.state;
        ControllerOut {
            t,
            mode: s.mode.word(),
            blend: s.blend,
            status: StatusWords(&s.solvers),
            iterations: s.solvers.iter().map(|r| u64::from(r.iterations)).sum(),
            solve_time_us: s.solvers.iter().map(|r| r.solve_time_us).sum(),
            limiter_active: lane.limiter_active,
            step_time_us: lane.step_time_us,
            time_in_mode_s: s.time_in_mode_s,
            switch_count: s.switch_count,
            last_switch_reason: state_words(s),
            solvers: SolversOut(&s.solvers),
        }
    }
}

/// The solvers' statuses joined by `+`, `none` without a QP: written straight into the
/// output (serde_json's `collect_str` escapes as it goes, without a `String`).
#[derive(Debug)]
struct StatusWords<'a>(&'a [SolverReport]);

impl std::fmt::Display for StatusWords<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.0.is_empty() {
            return f.write_str("none");
        }
        for (i, r) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str("+")?;
            }
            f.write_str(solver_words(r).1)?;
        }
        Ok(())
    }
}

impl Serialize for StatusWords<'_> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

#[derive(Debug)]
struct SolversOut<'a>(&'a [SolverReport]);

#[derive(Serialize)]
struct SolverOut<'a> {
    name: &'a str,
    status: &'static str,
    iterations: u32,
    #[serde(serialize_with = "duration_us")]
    solve_time_us: f64,
}

impl Serialize for SolversOut<'_> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(self.0.iter().map(|r| {
            let (name, status) = solver_words(r);
            SolverOut {
                name,
                status,
                iterations: r.iterations,
                solve_time_us: r.solve_time_us,
            }
        }))
    }
}

// ---------------------------------------------------------------------------------------------
// JSON schemas (Foxglove's `jsonschema` encoding), one a topic kind, generated from the
// message types above so that a field cannot be added without its schema.

fn generated<T: JsonSchema>() -> Vec<u8> {
    // Inlined: a schema is self-contained, with no `$ref` for a viewer to resolve.
    let generator = SchemaSettings::draft2020_12()
        .with(|s| s.inline_subschemas = true)
        .into_generator();
    serde_json::to_vec(&generator.into_root_schema_for::<T>()).unwrap_or_default()
}

/// The schema of a JSON topic kind; `None` for Foxglove's protobuf kinds.
pub fn schema_of(kind: Kind) -> Option<Vec<u8>> {
    Some(match kind {
        Kind::Aircraft => generated::<AircraftMsg>(),
        Kind::Perceived | Kind::Reference => generated::<PerceivedMsg>(),
        Kind::Platform => generated::<PlatformMsg>(),
        Kind::Actuators => generated::<ActuatorsMsg>(),
        Kind::Controller => generated::<ControllerMsg>(),
        Kind::Tf | Kind::Scene | Kind::Events => return None,
    })
}

/// One message on a JSON topic, serialised as the message itself.
#[derive(Debug, Serialize)]
#[serde(untagged)]
pub enum Message<'a> {
    Aircraft(AircraftMsg),
    Perceived(PerceivedMsg),
    Platform(PlatformMsg),
    Actuators(ActuatorsMsg),
    Controller(ControllerOut<'a>),
}

impl Message<'_> {
    /// The message's JSON as a recording (and the Foxglove server) sends it: the fields and
    /// values of its serde form, each number in its quantity's fixed format
    /// ([`resolution`]); the controller's through serde.
    pub fn write_json(&self, out: &mut Vec<u8>) -> serde_json::Result<()> {
        use resolution::{write_fixed, write_shortest, write_signal};
        let fixed = |decimals| move |out: &mut Vec<u8>, x| write_fixed(out, x, decimals);
        let position = fixed(resolution::POSITION_DECIMALS);
        let velocity = fixed(resolution::VELOCITY_DECIMALS);
        let acceleration = fixed(resolution::ACCELERATION_DECIMALS);
        let t = |out: &mut Vec<u8>, t: f64| {
            out.extend_from_slice(b"{\"t\":");
            write_shortest(out, t);
        };
        match self {
            Message::Aircraft(m) => {
                t(out, m.t);
                if let Some(k) = m.k {
                    out.extend_from_slice(b",\"k\":");
                    serde_json::to_writer(&mut *out, &k)?;
                }
                array(out, "specific_force", &m.specific_force, write_signal);
                array(out, "angular_velocity", &m.angular_velocity, write_signal);
                array(out, "attitude", &m.attitude, write_signal);
            }
            Message::Perceived(m) => {
                t(out, m.t);
                array(out, "specific_force", &m.specific_force, write_signal);
                array(out, "angular_velocity", &m.angular_velocity, write_signal);
            }
            Message::Platform(m) => {
                t(out, m.t);
                array(out, "pose", &m.pose, position);
                array(out, "velocity", &m.velocity, velocity);
                array(out, "acceleration", &m.acceleration, acceleration);
            }
            Message::Actuators(m) => {
                t(out, m.t);
                array(out, "length", &m.length, position);
                array(out, "velocity", &m.velocity, velocity);
            }
            Message::Controller(m) => return serde_json::to_writer(out, m),
        }
        out.push(b'}');
        Ok(())
    }
}

/// Writes `,"key":[a,b,…]`, each number through `number`.
fn array(out: &mut Vec<u8>, key: &str, values: &[f64], number: impl Fn(&mut Vec<u8>, f64)) {
    out.extend_from_slice(b",\"");
    out.extend_from_slice(key.as_bytes());
    out.extend_from_slice(b"\":[");
    for (i, &x) in values.iter().enumerate() {
        if i > 0 {
            out.push(b',');
        }
        number(out, x);
    }
    out.push(b']');
}

/// A frame's messages on hexcue's own topics, in the order the recorder writes them: the
/// aircraft, the reference, then each lane's four kinds in the frame's lane order.
pub fn messages(frame: &Frame) -> impl Iterator<Item = (Channel, Message<'_>)> + '_ {
    let t = frame.t_s;
    let common = [
        (
            Channel::AIRCRAFT,
            Message::Aircraft(AircraftMsg::new(frame)),
        ),
        (
            Channel::REFERENCE,
            Message::Perceived(PerceivedMsg::new(t, &frame.reference)),
        ),
    ];
    let lanes = frame.lanes.iter().flat_map(move |lane| {
        let on = |kind| Channel::lane(kind, lane.id);
        [
            (
                on(Kind::Perceived),
                Message::Perceived(PerceivedMsg::new(t, &lane.perceived)),
            ),
            (
                on(Kind::Platform),
                Message::Platform(PlatformMsg::new(t, &lane.command)),
            ),
            (
                on(Kind::Actuators),
                Message::Actuators(ActuatorsMsg::new(t, &lane.legs)),
            ),
            (
                on(Kind::Controller),
                Message::Controller(ControllerOut::new(t, lane)),
            ),
        ]
    });
    common.into_iter().chain(lanes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shortest(x: f64) -> String {
        serde_json::to_string(&x).unwrap()
    }

    fn text(write: impl Fn(&mut Vec<u8>)) -> String {
        let mut out = Vec::new();
        write(&mut out);
        String::from_utf8(out).unwrap()
    }

    #[test]
    fn signals_keep_six_significant_digits_at_any_magnitude() {
        for (x, written) in [
            (-3.6286184e-7, "-3.62862e-7"),
            (0.010555653, "1.05557e-2"),
            (-10.192777, "-1.01928e1"),
            (9.999996, "1.00000e1"),
            (1000.0, "1.00000e3"),
            (123_456_789.0, "1.23457e8"),
            (1.234_567_8e-300, "1.23457e-300"),
        ] {
            let r = resolution::signal(x);
            assert_eq!(text(|o| resolution::write_signal(o, x)), written, "{x}");
            assert_eq!(
                written.parse::<f64>().unwrap(),
                r,
                "{x}: reads back as kept"
            );
            assert_eq!(
                resolution::signal(r),
                r,
                "{x}: rounding twice changes nothing"
            );
            assert!((r - x).abs() <= 5e-6 * x.abs(), "{x}");
        }
        for (x, written) in [(0.0, "0.0"), (-0.0, "0.0"), (f64::NAN, "null")] {
            assert_eq!(text(|o| resolution::write_signal(o, x)), written, "{x}");
        }
    }

    #[test]
    fn positions_rates_and_durations_are_written_at_their_resolution() {
        let fixed = |x, d| text(|o| resolution::write_fixed(o, x, d));
        assert_eq!(fixed(3.392_921_4, 6), "3.392921");
        assert_eq!(fixed(-0.2709, 6), "-0.270900");
        assert_eq!(fixed(-4e-7, 6), "0.000000");
        assert_eq!(fixed(-0.023_773_4, 4), "-0.0238");
        assert_eq!(fixed(f64::INFINITY, 4), "null");
        for (x, d, f) in [
            (0.123_456_789, 6, resolution::position as fn(f64) -> f64),
            (-0.123_456_789, 3, resolution::velocity),
            (0.987_654_321, 3, resolution::acceleration),
        ] {
            assert_eq!(fixed(x, d).parse::<f64>().unwrap(), f(x), "{x}");
            assert_eq!(f(f(x)), f(x), "rounding twice changes nothing");
        }
        assert_eq!(resolution::duration_us(133.726_999_999_999_98), 134.0);
        assert_eq!(shortest(resolution::time_s(30.010_000_000_001_89)), "30.01");
    }

    /// The controller message as it was built before it was borrowed: owned Strings.
    fn owned_controller(t: f64, lane: &LaneFrame) -> ControllerMsg {
        let s = &lane.state;
        let status = if s.solvers.is_empty() {
            "none".to_string()
        } else {
            s.solvers
                .iter()
                .map(|r| r.status.as_str())
                .collect::<Vec<_>>()
                .join("+")
        };
        ControllerMsg {
            t,
            mode: s.mode.word().to_string(),
            blend: s.blend,
            status,
            iterations: s.solvers.iter().map(|r| u64::from(r.iterations)).sum(),
            solve_time_us: s.solvers.iter().map(|r| r.solve_time_us).sum(),
            limiter_active: lane.limiter_active,
            step_time_us: lane.step_time_us,
            time_in_mode_s: s.time_in_mode_s,
            switch_count: s.switch_count,
            last_switch_reason: s.last_switch_reason.as_ref().map(|r| r.to_string()),
            solvers: s
                .solvers
                .iter()
                .map(|r| SolverMsg {
                    name: r.name.word().to_string(),
                    status: r.status.to_string(),
                    iterations: r.iterations,
                    solve_time_us: r.solve_time_us,
                })
                .collect(),
        }
    }

    #[test]
    fn the_borrowed_controller_writes_the_owned_json() {
        use hexcue_core::mca::{AlgorithmId, Mode};
        use hexcue_core::vocab::SolveStatus;
        let profile = hexcue_core::testing::full_flight();
        let trace = std::sync::Arc::new(hexcue_core::testing::manoeuvre());
        let mut engine =
            hexcue_core::engine::Engine::new(&profile, trace, &[AlgorithmId::Cwf]).unwrap();
        let frame = engine.step().unwrap();
        let mut lane = frame.lanes[0].clone();
        use hexcue_core::vocab::QpName;
        let report = |name: QpName, status, iterations, solve_time_us| SolverReport {
            name,
            status,
            iterations,
            solve_time_us,
        };
        let cases = [
            (Mode::Washout, None, Vec::new(), None),
            (
                Mode::Blend,
                Some(0.25),
                vec![
                    report(
                        QpName::Cotc,
                        SolveStatus::PrimalInfeasible,
                        7,
                        133.726_999_999_98,
                    ),
                    report(QpName::Free, SolveStatus::Standby, 0, f64::NAN),
                ],
                Some(SwitchReason::parse("cotc infeasible: \"x\" ≥ 3")),
            ),
            (
                Mode::Mpc,
                None,
                vec![report(QpName::Mpc, SolveStatus::SolvedClarabel, 31, 1.5e3)],
                None,
            ),
        ];
        for (mode, blend, solvers, reason) in cases {
            lane.state.mode = mode;
            lane.state.blend = blend;
            lane.state.solvers = solvers.into_iter().collect();
            lane.state.last_switch_reason = reason;
            lane.state.time_in_mode_s = 30.010_000_000_001_89;
            lane.step_time_us = 12.345_6;
            let mut written = Vec::new();
            Message::Controller(ControllerOut::new(1.25, &lane))
                .write_json(&mut written)
                .unwrap();
            let owned = serde_json::to_vec(&owned_controller(1.25, &lane)).unwrap();
            assert_eq!(
                String::from_utf8(written.clone()).unwrap(),
                String::from_utf8(owned).unwrap()
            );
            let back: ControllerMsg = serde_json::from_slice(&written).unwrap();
            assert_eq!(back.mode, mode.word());
        }
    }

    #[test]
    fn written_messages_read_back_as_their_serde_form_says() {
        let xs = [0.123_456_789, -3.6e-7, f64::NAN, 2.5, -0.0, 1e-3];
        let messages = [
            Message::Aircraft(AircraftMsg {
                t: 1.25,
                k: Some(125),
                specific_force: [xs[0], xs[1], xs[2]],
                angular_velocity: [xs[3], xs[4], xs[5]],
                attitude: [xs[5], xs[0], xs[1]],
            }),
            Message::Perceived(PerceivedMsg {
                t: 1.25,
                specific_force: [xs[0], xs[1], xs[2]],
                angular_velocity: [xs[3], xs[4], xs[5]],
            }),
            Message::Platform(PlatformMsg {
                t: 1.25,
                pose: xs,
                velocity: xs,
                acceleration: xs,
            }),
            Message::Actuators(ActuatorsMsg {
                t: 1.25,
                length: xs,
                velocity: xs,
                margin: xs,
            }),
        ];
        for message in &messages {
            let mut written = Vec::new();
            message.write_json(&mut written).unwrap();
            let serde = serde_json::to_vec(message).unwrap();
            let keys = |bytes: &[u8]| {
                let text = String::from_utf8(bytes.to_vec()).unwrap();
                text.split('"')
                    .skip(1)
                    .step_by(2)
                    .map(String::from)
                    .collect::<Vec<_>>()
            };
            assert_eq!(
                keys(&written),
                keys(&serde),
                "same fields in the same order"
            );
            let a: serde_json::Value = serde_json::from_slice(&written).unwrap();
            let b: serde_json::Value = serde_json::from_slice(&serde).unwrap();
            assert_eq!(a, b, "{}", String::from_utf8_lossy(&written));
        }
    }
}
