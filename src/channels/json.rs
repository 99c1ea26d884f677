//! hexcue's own topics as JSON (Foxglove's `json` message encoding with `jsonschema`
//! schemas): the messages a frame becomes, as written and as read back, and their schemas.

use nalgebra::{Vector3, Vector6};
use schemars::generate::SchemaSettings;
use schemars::JsonSchema;
use serde::{Deserialize, Deserializer, Serialize};

use crate::engine::{Frame, LaneFrame, Legs};
use crate::mca::PlatformCommand;
use crate::model::vestibular::Perceived;

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

/// Writes an array of the platform's motion or its legs rounded to 6 decimals in SI: 1 µm,
/// 1 µrad, 1 µm/s, 10⁻⁶ m/s², far below what a platform resolves. The digits beyond are noise
/// that zstd cannot shrink, and they were most of the file (docs/recordings.md, "Size per
/// minute"). Files written before keep their full digits and read the same way.
fn micro_array<S: serde::Serializer, const N: usize>(
    v: &[f64; N],
    s: S,
) -> Result<S::Ok, S::Error> {
    s.collect_seq(v.iter().map(|&x| micro(x)))
}

/// A value as the recording keeps the platform's: rounded to 6 decimals.
pub fn micro(x: f64) -> f64 {
    (x * 1e6).round() / 1e6
}

/// Writes an array of the aircraft's or a perceived signal in single precision (the shortest
/// form that reads back to the same f32, 7 significant digits): relative, not absolute,
/// because a quiet flight's perceived rates are a few µrad/s and their metrics (AAS, RAE) are
/// ratios of sums of them.
fn f32_array<S: serde::Serializer, const N: usize>(v: &[f64; N], s: S) -> Result<S::Ok, S::Error> {
    s.collect_seq(v.iter().map(|&x| x as f32))
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
    #[serde(deserialize_with = "nan_array", serialize_with = "f32_array")]
    #[schemars(
        with = "[Option<f64>; 3]",
        description = "f = a − g, x y z (m/s²); (0, 0, −9.81) at rest"
    )]
    pub specific_force: [f64; 3],
    #[serde(deserialize_with = "nan_array", serialize_with = "f32_array")]
    #[schemars(with = "[Option<f64>; 3]", description = "body rates p q r (rad/s)")]
    pub angular_velocity: [f64; 3],
    #[serde(deserialize_with = "nan_array", serialize_with = "f32_array")]
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
    #[serde(deserialize_with = "nan_array", serialize_with = "f32_array")]
    #[schemars(
        with = "[Option<f64>; 3]",
        description = "otoliths' output for Δf, x y z head frame (m/s²)"
    )]
    pub specific_force: [f64; 3],
    #[serde(deserialize_with = "nan_array", serialize_with = "f32_array")]
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
    #[serde(deserialize_with = "nan_array", serialize_with = "micro_array")]
    #[schemars(
        with = "[Option<f64>; 6]",
        description = "x y z (m), roll pitch yaw (rad) from neutral"
    )]
    pub pose: [f64; 6],
    #[serde(deserialize_with = "nan_array", serialize_with = "micro_array")]
    #[schemars(
        with = "[Option<f64>; 6]",
        description = "first derivative of pose (m/s, rad/s)"
    )]
    pub velocity: [f64; 6],
    #[serde(deserialize_with = "nan_array", serialize_with = "micro_array")]
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
    #[serde(deserialize_with = "nan_array", serialize_with = "micro_array")]
    #[schemars(with = "[Option<f64>; 6]", description = "leg lengths (m)")]
    pub length: [f64; 6],
    #[serde(deserialize_with = "nan_array", serialize_with = "micro_array")]
    #[schemars(with = "[Option<f64>; 6]", description = "leg velocities (m/s)")]
    pub velocity: [f64; 6],
    #[serde(deserialize_with = "nan_array", serialize_with = "micro_array")]
    #[schemars(
        with = "[Option<f64>; 6]",
        description = "distance to the nearer end stop (m); < 0 outside"
    )]
    pub margin: [f64; 6],
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
    #[serde(deserialize_with = "nan_f64")]
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
    #[serde(deserialize_with = "nan_f64")]
    #[schemars(
        with = "Option<f64>",
        required,
        description = "all QPs of the step (µs)"
    )]
    pub solve_time_us: f64,
    pub limiter_active: bool,
    #[serde(deserialize_with = "nan_f64")]
    #[schemars(
        with = "Option<f64>",
        required,
        description = "wall time of the step, limiter included (µs)"
    )]
    pub step_time_us: f64,
    #[serde(deserialize_with = "nan_f64")]
    #[schemars(with = "Option<f64>", required)]
    pub time_in_mode_s: f64,
    pub switch_count: u32,
    pub last_switch_reason: Option<String>,
    pub solvers: Vec<SolverMsg>,
}

impl ControllerMsg {
    pub fn new(t: f64, lane: &LaneFrame) -> Self {
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
            last_switch_reason: s.last_switch_reason.clone(),
            solvers: s
                .solvers
                .iter()
                .map(|r| SolverMsg {
                    name: r.name.clone(),
                    status: r.status.to_string(),
                    iterations: r.iterations,
                    solve_time_us: r.solve_time_us,
                })
                .collect(),
        }
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
pub enum Message {
    Aircraft(AircraftMsg),
    Perceived(PerceivedMsg),
    Platform(PlatformMsg),
    Actuators(ActuatorsMsg),
    Controller(ControllerMsg),
}

/// A frame's messages on hexcue's own topics, in the order the recorder writes them: the
/// aircraft, the reference, then each lane's four kinds in the frame's lane order.
pub fn messages(frame: &Frame) -> impl Iterator<Item = (Channel, Message)> + '_ {
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
                Message::Controller(ControllerMsg::new(t, lane)),
            ),
        ]
    });
    common.into_iter().chain(lanes)
}
