//! A frame as Foxglove's well-known messages: where each platform is (`FrameTransforms`), what
//! it looks like (`SceneUpdate`: plates, legs coloured by margin, eye point), and what happened
//! (`Log`: S-MPC mode changes, the limiter acting, events a live session reports).
//!
//! Frames (`docs/foxglove.md`):
//! - `world`: Foxglove's usual z-up frame (x forward, y left, z up), origin on the floor.
//! - `ALG/base`: docs/design.md §1's simulator inertial frame (x forward, y right, z down, origin at
//!   the platform's neutral pose), fixed to the floor. world → `ALG/base` is a half turn about
//!   x (y and z flip) and a lift by the neutral height; the rigs stand side by side along y.
//! - `ALG/platform`: the moving platform, placed by the commanded pose (after the limiter).
//! - `ALG/eye`: the pilot's head, `eye_point_m` in the platform frame.

use ::foxglove::messages::{
    line_primitive, log, ArrowPrimitive, Color, FrameTransform, FrameTransforms, LinePrimitive,
    Log, Point3, Pose, Quaternion, SceneEntity, SceneUpdate, SpherePrimitive, TextPrimitive,
    Timestamp, TriangleListPrimitive, Vector3 as FgVector3,
};
use nalgebra::{UnitQuaternion, Vector3, Vector6};

use hexcue_core::engine::{Frame, LaneFrame};
use hexcue_core::events::EventLevel;
use hexcue_core::mca::{AlgorithmId, Mode};
use hexcue_core::model::stewart::Stewart;
use hexcue_core::profile::Profile;

/// Foxglove's fixed frame: z up.
pub const WORLD_FRAME: &str = "world";
/// `Log.name` of events that belong to the session rather than to an algorithm.
pub const SESSION_SOURCE: &str = "hexcue";

/// Space left between two rigs standing side by side (m).
const RIG_GAP_M: f64 = 1.5;
const LEG_THICKNESS_M: f64 = 0.06;

pub fn base_frame(id: AlgorithmId) -> String {
    format!("{}/base", id.key())
}

pub fn platform_frame(id: AlgorithmId) -> String {
    format!("{}/platform", id.key())
}

pub fn eye_frame(id: AlgorithmId) -> String {
    format!("{}/eye", id.key())
}

fn foxglove_level(level: EventLevel) -> log::Level {
    match level {
        EventLevel::Debug => log::Level::Debug,
        EventLevel::Info => log::Level::Info,
        EventLevel::Warning => log::Level::Warning,
        EventLevel::Error => log::Level::Error,
    }
}

/// A `foxglove.Log` message at `log_time_ns`.
pub fn event(log_time_ns: u64, level: EventLevel, source: &str, text: &str) -> Log {
    Log {
        timestamp: Some(timestamp(log_time_ns)),
        level: foxglove_level(level) as i32,
        message: text.to_string(),
        name: source.to_string(),
        file: String::new(),
        line: 0,
    }
}

pub fn timestamp(log_time_ns: u64) -> Timestamp {
    Timestamp::new(
        (log_time_ns / 1_000_000_000).min(u64::from(u32::MAX)) as u32,
        (log_time_ns % 1_000_000_000) as u32,
    )
}

/// The rotation of a pose's roll, pitch and yaw (Z-Y-X Euler, R = Rz·Ry·Rx as in
/// [`hexcue_core::model::stewart::rotation`]) as Foxglove's quaternion.
pub fn pose_rotation(pose: &Vector6<f64>) -> Quaternion {
    quaternion(&UnitQuaternion::from_euler_angles(
        pose[3], pose[4], pose[5],
    ))
}

fn quaternion(q: &UnitQuaternion<f64>) -> Quaternion {
    Quaternion {
        x: q.i,
        y: q.j,
        z: q.k,
        w: q.w,
    }
}

fn vector(v: &Vector3<f64>) -> FgVector3 {
    FgVector3 {
        x: v.x,
        y: v.y,
        z: v.z,
    }
}

fn point(v: &Vector3<f64>) -> Point3 {
    Point3 {
        x: v.x,
        y: v.y,
        z: v.z,
    }
}

/// What moves in the 3D topics (the platform's transform, the legs' upper ends) is drawn at
/// 2^-12 m (0.24 mm; a leg is drawn 60 mm thick) and its rotation at 2^-16 per quaternion
/// component (about 0.002°, 45 µm at a 1.5 m platform radius): invisible in a drawing, and
/// the doubles' low bytes become zeros that zstd removes. Full doubles were most of these
/// topics' bytes; 2^-20 m and 2^-24 (a micrometre, the recorded pose's resolution) kept the
/// 3D topics at 33 Hz over the 5 MB a minute of the steep turn (docs/recordings.md, "3D
/// topics at 33 Hz"). The recorded pose on `/ALG/platform` keeps its micrometre.
fn drawn(x: f64, bits: i32) -> f64 {
    let scale = 2f64.powi(bits);
    (x * scale).round() / scale
}

fn drawn_point(v: &Vector3<f64>) -> Vector3<f64> {
    v.map(|x| drawn(x, POSITION_BITS))
}

const POSITION_BITS: i32 = 12;
const ROTATION_BITS: i32 = 16;

fn rgba(r: f64, g: f64, b: f64, a: f64) -> Color {
    Color { r, g, b, a }
}

fn transform(
    t_ns: u64,
    parent: &str,
    child: &str,
    at: FgVector3,
    rot: Quaternion,
) -> FrameTransform {
    FrameTransform {
        timestamp: Some(timestamp(t_ns)),
        parent_frame_id: parent.to_string(),
        child_frame_id: child.to_string(),
        translation: Some(at),
        rotation: Some(rot),
    }
}

fn pose_at(position: Vector3<f64>) -> Option<Pose> {
    Some(Pose {
        position: Some(vector(&position)),
        orientation: Some(quaternion(&UnitQuaternion::identity())),
    })
}

/// A filled polygon (a fan from its centroid) and its outline, through `corners` in order.
fn plate(
    corners: &[Vector3<f64>],
    fill: Color,
    edge: Color,
) -> (TriangleListPrimitive, LinePrimitive) {
    let centre = corners.iter().sum::<Vector3<f64>>() / corners.len().max(1) as f64;
    let mut points = Vec::with_capacity(3 * corners.len());
    for (i, c) in corners.iter().enumerate() {
        let next = &corners[(i + 1) % corners.len()];
        points.extend([point(&centre), point(c), point(next)]);
    }
    (
        TriangleListPrimitive {
            pose: pose_at(Vector3::zeros()),
            points,
            color: Some(fill),
            colors: Vec::new(),
            indices: Vec::new(),
        },
        LinePrimitive {
            r#type: line_primitive::Type::LineLoop as i32,
            pose: pose_at(Vector3::zeros()),
            thickness: 0.03,
            scale_invariant: false,
            points: corners.iter().map(point).collect(),
            color: Some(edge),
            colors: Vec::new(),
            indices: Vec::new(),
        },
    )
}

/// Joints sorted by their angle about the z axis, so that they outline a convex plate.
fn around(joints: &[Vector3<f64>; 6]) -> Vec<Vector3<f64>> {
    let mut v = joints.to_vec();
    v.sort_by(|a, b| a.y.atan2(a.x).total_cmp(&b.y.atan2(b.x)));
    v
}

/// Leg colours by margin, with the console's thresholds (`tui::state::LegScale`): green, amber
/// below a fifth of the smallest neutral margin, red at the limiter's margin or outside the
/// stroke.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LegColours {
    pub warn_m: f64,
    pub crit_m: f64,
}

impl LegColours {
    pub fn of(profile: &Profile, stewart: &Stewart) -> Self {
        let neutral = stewart.margins(&stewart.neutral_lengths_m);
        let least = neutral
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min)
            .max(1e-6);
        let crit_m = (1.5 * profile.limiter.leg_margin_m.max(0.0)).max(0.005);
        LegColours {
            warn_m: (0.2 * least).max(2.0 * crit_m),
            crit_m,
        }
    }

    pub fn colour(&self, margin_m: f64) -> Color {
        if !margin_m.is_finite() || margin_m < self.crit_m {
            rgba(0.90, 0.10, 0.10, 1.0)
        } else if margin_m < self.warn_m {
            rgba(0.95, 0.65, 0.0, 1.0)
        } else {
            rgba(0.15, 0.70, 0.30, 1.0)
        }
    }
}

/// What the builder remembers of a lane to report changes.
#[derive(Clone, Debug)]
struct LaneMemory {
    id: AlgorithmId,
    mode: Mode,
    limiter_active: bool,
    limiter_since_s: f64,
}

/// Every algorithm's rig at one step: one message for all the transforms and one for all
/// the entities, not one of each per algorithm. Each message costs a 16-byte index and a
/// record header that zstd cannot remove, and joining them keeps the busiest flight's
/// recording under 5 MB a minute (docs/recordings.md, "One /tf and one /scene").
#[derive(Clone, Debug, PartialEq)]
pub struct DrawnRigs {
    pub transforms: FrameTransforms,
    pub scene: SceneUpdate,
}

/// Everything a step adds in Foxglove's messages.
#[derive(Clone, Debug, PartialEq)]
pub struct StepMessages {
    /// The rigs, when drawn at this step.
    pub drawn: Option<DrawnRigs>,
    pub events: Vec<Log>,
}

/// Builds the messages of each frame for one rig geometry.
#[derive(Clone, Debug)]
pub struct SceneBuilder {
    stewart: Stewart,
    eye_m: Vector3<f64>,
    legs: LegColours,
    neutral_height_m: f64,
    /// Where each algorithm's rig stands: its base's y in the world frame (m).
    slots: Vec<(AlgorithmId, f64)>,
    spacing_m: f64,
    memory: Vec<LaneMemory>,
}

impl SceneBuilder {
    /// Rigs for `algorithms`, side by side in this order from left to right as seen from
    /// behind (the console's column order).
    pub fn new(profile: &Profile, algorithms: &[AlgorithmId]) -> Self {
        let stewart = profile.stewart();
        let reach =
            |joints: &[Vector3<f64>; 6]| joints.iter().map(|j| j.xy().norm()).fold(0.0, f64::max);
        let spacing_m =
            2.0 * reach(&stewart.base_joints_m).max(reach(&stewart.platform_joints_m)) + RIG_GAP_M;
        let n = algorithms.len() as f64;
        // World y points left: the first algorithm stands leftmost, at the largest y.
        let slots = algorithms
            .iter()
            .enumerate()
            .map(|(i, &id)| (id, ((n - 1.0) / 2.0 - i as f64) * spacing_m))
            .collect();
        SceneBuilder {
            legs: LegColours::of(profile, &stewart),
            neutral_height_m: stewart.base_joints_m[0].z,
            eye_m: profile.eye_point(),
            stewart,
            slots,
            spacing_m,
            memory: Vec::new(),
        }
    }

    /// The world y of an algorithm's rig (m); one not announced gets the next free place.
    pub fn slot_y_m(&mut self, id: AlgorithmId) -> f64 {
        if let Some((_, y)) = self.slots.iter().find(|(a, _)| *a == id) {
            return *y;
        }
        let y = self.slots.iter().map(|(_, y)| *y).fold(0.0, f64::min) - self.spacing_m;
        self.slots.push((id, y));
        y
    }

    /// Forgets what was seen: the next frame starts a new run (a rewind), with no changes to
    /// report against the previous one.
    pub fn reset(&mut self) {
        self.memory.clear();
    }

    /// The messages of one frame, stamped `log_time_ns`: the events every step (a change is
    /// never skipped), the lanes' transforms and scenes only when `draw` (a recording writes
    /// them every few steps, and building them was most of a skipped step's cost).
    pub fn step(&mut self, frame: &Frame, log_time_ns: u64, draw: bool) -> StepMessages {
        let mut events = Vec::new();
        for lane in &frame.lanes {
            self.note_changes(lane, frame.t_s, log_time_ns, &mut events);
        }
        let drawn = draw.then(|| {
            let mut rigs = DrawnRigs {
                transforms: FrameTransforms::default(),
                scene: SceneUpdate::default(),
            };
            for lane in &frame.lanes {
                rigs.transforms
                    .transforms
                    .extend(self.transforms(lane, log_time_ns).transforms);
                rigs.scene
                    .entities
                    .extend(self.scene(lane, log_time_ns).entities);
            }
            rigs
        });
        StepMessages { drawn, events }
    }

    /// world → base → platform → eye for one lane.
    pub fn transforms(&mut self, lane: &LaneFrame, t_ns: u64) -> FrameTransforms {
        let id = lane.id;
        let y = self.slot_y_m(id);
        let base = base_frame(id);
        let platform = platform_frame(id);
        let pose = &lane.command.pose;
        // A half turn about x takes the z-down base frame to the z-up world.
        let flip = Quaternion {
            x: 1.0,
            y: 0.0,
            z: 0.0,
            w: 0.0,
        };
        let mut transforms = vec![transform(
            t_ns,
            WORLD_FRAME,
            &base,
            vector(&Vector3::new(0.0, y, self.neutral_height_m)),
            flip,
        )];
        // A non-finite command (never from a healthy run) would break the viewer's transform
        // tree: the platform keeps its last place, and the plain topics still carry the value.
        if pose.iter().all(|v| v.is_finite()) {
            transforms.push(transform(
                t_ns,
                &base,
                &platform,
                vector(&drawn_point(&pose.fixed_rows::<3>(0).into_owned())),
                {
                    let q = pose_rotation(pose);
                    let d = |x| drawn(x, ROTATION_BITS);
                    Quaternion {
                        x: d(q.x),
                        y: d(q.y),
                        z: d(q.z),
                        w: d(q.w),
                    }
                },
            ));
        }
        transforms.push(transform(
            t_ns,
            &platform,
            &eye_frame(id),
            vector(&self.eye_m),
            quaternion(&UnitQuaternion::identity()),
        ));
        FrameTransforms { transforms }
    }

    /// Base plate, platform plate with its forward arrow and eye point, the six legs.
    pub fn scene(&self, lane: &LaneFrame, t_ns: u64) -> SceneUpdate {
        let id = lane.id;
        let c = super::algorithm_rgb(id);
        let (r, g, b) = (
            f64::from(c.0) / 255.0,
            f64::from(c.1) / 255.0,
            f64::from(c.2) / 255.0,
        );
        // Ids are unique within the one `/scene` topic every rig shares: `ALG/base`, ….
        let entity = |frame_id: String, name: &str, frame_locked: bool| SceneEntity {
            timestamp: Some(timestamp(t_ns)),
            frame_id,
            id: format!("{}/{name}", id.key()),
            lifetime: None,
            frame_locked,
            ..Default::default()
        };

        let mut base = entity(base_frame(id), "base", false);
        let (fill, edge) = plate(
            &around(&self.stewart.base_joints_m),
            rgba(0.55, 0.55, 0.55, 0.5),
            rgba(0.3, 0.3, 0.3, 1.0),
        );
        base.triangles.push(fill);
        base.lines.push(edge);
        base.texts.push(TextPrimitive {
            // Above the pilot's head at neutral (z is down in the base frame).
            pose: pose_at(Vector3::new(0.0, 0.0, self.eye_m.z.min(0.0) - 0.8)),
            billboard: true,
            font_size: 0.5,
            scale_invariant: false,
            color: Some(rgba(r, g, b, 1.0)),
            text: id.key().to_string(),
        });

        let mut platform = entity(platform_frame(id), "platform", true);
        let (fill, edge) = plate(
            &around(&self.stewart.platform_joints_m),
            rgba(r, g, b, 0.6),
            rgba(r, g, b, 1.0),
        );
        platform.triangles.push(fill);
        platform.lines.push(edge);
        platform.arrows.push(ArrowPrimitive {
            // The platform's forward (x) direction.
            pose: pose_at(Vector3::new(0.0, 0.0, -0.05)),
            shaft_length: 0.8,
            shaft_diameter: 0.08,
            head_length: 0.3,
            head_diameter: 0.2,
            color: Some(rgba(r, g, b, 1.0)),
        });
        platform.spheres.push(SpherePrimitive {
            pose: pose_at(self.eye_m),
            size: Some(vector(&Vector3::repeat(0.25))),
            color: Some(rgba(0.95, 0.95, 0.95, 1.0)),
        });

        let mut legs = entity(base_frame(id), "legs", false);
        let pose = &lane.command.pose;
        if pose.iter().all(|v| v.is_finite()) {
            let rot = hexcue_core::model::stewart::rotation(pose[3], pose[4], pose[5]);
            let at = pose.fixed_rows::<3>(0).into_owned();
            for i in 0..6 {
                let top = at + rot * self.stewart.platform_joints_m[i];
                legs.lines.push(LinePrimitive {
                    r#type: line_primitive::Type::LineList as i32,
                    pose: pose_at(Vector3::zeros()),
                    thickness: LEG_THICKNESS_M,
                    scale_invariant: false,
                    points: vec![
                        point(&self.stewart.base_joints_m[i]),
                        point(&drawn_point(&top)),
                    ],
                    color: Some(self.legs.colour(lane.legs.margin_m[i])),
                    colors: Vec::new(),
                    indices: Vec::new(),
                });
            }
        }
        SceneUpdate {
            deletions: Vec::new(),
            entities: vec![base, platform, legs],
        }
    }

    fn note_changes(&mut self, lane: &LaneFrame, t_s: f64, t_ns: u64, out: &mut Vec<Log>) {
        let key = lane.id.key();
        let mode = lane.state.mode;
        let Some(seen) = self.memory.iter_mut().find(|m| m.id == lane.id) else {
            self.memory.push(LaneMemory {
                id: lane.id,
                mode,
                limiter_active: lane.limiter_active,
                limiter_since_s: t_s,
            });
            return;
        };
        if seen.mode != mode {
            let level = if mode == Mode::Fallback {
                EventLevel::Warning
            } else {
                EventLevel::Info
            };
            let reason = lane
                .state
                .last_switch_reason
                .as_ref()
                .map(|r| format!(": {r}"))
                .unwrap_or_default();
            out.push(event(
                t_ns,
                level,
                key,
                &format!(
                    "{} → {} (switch {}){reason}",
                    seen.mode.word(),
                    mode.word(),
                    lane.state.switch_count
                ),
            ));
            seen.mode = mode;
        }
        if lane.limiter_active != seen.limiter_active {
            let text = if lane.limiter_active {
                "limiter acting".to_string()
            } else {
                format!("limiter released after {:.2} s", t_s - seen.limiter_since_s)
            };
            let level = if lane.limiter_active {
                EventLevel::Warning
            } else {
                EventLevel::Info
            };
            out.push(event(t_ns, level, key, &text));
            seen.limiter_active = lane.limiter_active;
            seen.limiter_since_s = t_s;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hexcue_core::model::stewart::rotation;
    use hexcue_core::testing::full_flight;

    /// The first frame of the CWF alone on the engine's test manoeuvre.
    fn first_cwf_frame(profile: &hexcue_core::profile::Profile) -> hexcue_core::engine::Frame {
        let trace = std::sync::Arc::new(hexcue_core::testing::manoeuvre());
        let mut engine =
            hexcue_core::engine::Engine::new(profile, trace, &[AlgorithmId::Cwf]).unwrap();
        engine.step().unwrap()
    }

    fn rotate(q: &Quaternion, v: &Vector3<f64>) -> Vector3<f64> {
        let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q.w, q.x, q.y, q.z));
        q * v
    }

    #[test]
    fn the_platform_rotation_is_the_kinematics_rotation() {
        for pose in [
            Vector6::new(0.0, 0.0, 0.0, 0.3, 0.0, 0.0),
            Vector6::new(0.0, 0.0, 0.0, 0.0, -0.2, 0.0),
            Vector6::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.7),
            Vector6::new(0.1, -0.2, 0.3, 0.25, -0.15, 0.4),
        ] {
            let q = pose_rotation(&pose);
            let r = rotation(pose[3], pose[4], pose[5]);
            for v in [Vector3::x(), Vector3::y(), Vector3::z()] {
                assert!((rotate(&q, &v) - r * v).norm() < 1e-12, "{pose:?}");
            }
        }
    }

    #[test]
    fn world_to_base_turns_z_down_into_z_up() {
        let profile = full_flight();
        let algorithms = [AlgorithmId::Smpc, AlgorithmId::Mpc, AlgorithmId::Cwf];
        let mut b = SceneBuilder::new(&profile, &algorithms);
        let frame = first_cwf_frame(&profile);
        let tf = b.transforms(&frame.lanes[0], 7);
        let w = &tf.transforms[0];
        assert_eq!(
            (w.parent_frame_id.as_str(), w.child_frame_id.as_str()),
            ("world", "cwf/base")
        );
        let q = w.rotation.as_ref().unwrap();
        // Base-frame down is world down; base-frame right is world right (−y).
        assert!((rotate(q, &Vector3::z()) + Vector3::z()).norm() < 1e-12);
        assert!((rotate(q, &Vector3::y()) + Vector3::y()).norm() < 1e-12);
        assert!((rotate(q, &Vector3::x()) - Vector3::x()).norm() < 1e-12);
        // The base joints, 3 m below the neutral platform, stand on the world's floor.
        let t = w.translation.as_ref().unwrap();
        let joint = profile.stewart().base_joints_m[0];
        let in_world = rotate(q, &joint) + Vector3::new(t.x, t.y, t.z);
        assert!(in_world.z.abs() < 1e-12, "{in_world:?}");
        // Side by side, the console's order from left (+y) to right.
        let ys: Vec<f64> = algorithms.iter().map(|a| b.slot_y_m(*a)).collect();
        assert!(
            ys[0] > ys[1] && ys[1] > ys[2] && ys[1].abs() < 1e-12,
            "{ys:?}"
        );
        assert!(ys[0] - ys[1] > 2.0 * 2.3, "rigs overlap: {ys:?}");
        assert_eq!(t.y, ys[2]);
    }

    #[test]
    fn legs_join_the_joints_and_take_the_margin_colour() {
        let profile = full_flight();
        let b = SceneBuilder::new(&profile, &[AlgorithmId::Cwf]);
        let mut frame = first_cwf_frame(&profile);
        let lane = &mut frame.lanes[0];
        lane.command.pose = Vector6::new(0.2, -0.1, -0.3, 0.05, 0.08, -0.1);
        let stewart = profile.stewart();
        lane.legs.length_m = stewart.leg_lengths(&lane.command.pose);
        lane.legs.margin_m = stewart.margins(&lane.legs.length_m);
        lane.legs.margin_m[2] = 0.001;
        lane.legs.margin_m[4] = b.legs.warn_m * 0.5 + b.legs.crit_m * 0.5;
        let scene = b.scene(lane, 1);
        let legs = scene.entities.iter().find(|e| e.id == "cwf/legs").unwrap();
        assert_eq!(legs.frame_id, "cwf/base");
        assert_eq!(legs.lines.len(), 6);
        for (i, line) in legs.lines.iter().enumerate() {
            let [p, q] = [&line.points[0], &line.points[1]];
            let length = Vector3::new(q.x - p.x, q.y - p.y, q.z - p.z).norm();
            // The upper end is drawn at 2^-12 m per coordinate: within √3 · 2^-13 m.
            assert!((length - lane.legs.length_m[i]).abs() < 3e-4, "leg {i}");
        }
        let red = legs.lines[2].color.as_ref().unwrap();
        let amber = legs.lines[4].color.as_ref().unwrap();
        let green = legs.lines[0].color.as_ref().unwrap();
        assert!(red.r > 0.8 && red.g < 0.2, "{red:?}");
        assert!(amber.r > 0.8 && amber.g > 0.5 && amber.b < 0.1, "{amber:?}");
        assert!(green.g > 0.6 && green.r < 0.3, "{green:?}");
    }

    #[test]
    fn mode_changes_and_the_limiter_become_events() {
        let profile = full_flight();
        let mut b = SceneBuilder::new(&profile, &[AlgorithmId::Smpc]);
        let mut frame = first_cwf_frame(&profile);
        frame.lanes[0].id = AlgorithmId::Smpc;
        frame.lanes[0].state.mode = Mode::Cotc;
        assert!(
            b.step(&frame, 1, true).events.is_empty(),
            "the first frame is no change"
        );
        frame.lanes[0].state.mode = Mode::Blend;
        frame.lanes[0].state.switch_count = 1;
        frame.lanes[0].state.last_switch_reason =
            Some(hexcue_core::mca::SwitchReason::parse("cotc infeasible"));
        frame.lanes[0].limiter_active = true;
        let events = b.step(&frame, 2, false).events;
        assert_eq!(events.len(), 2, "{events:?}");
        assert_eq!(events[0].name, "smpc");
        assert_eq!(
            events[0].message,
            "cotc → blend (switch 1): cotc infeasible"
        );
        assert_eq!(events[1].message, "limiter acting");
        assert_eq!(events[1].level, log::Level::Warning as i32);
        assert!(
            b.step(&frame, 3, true).events.is_empty(),
            "no change, no event"
        );
        frame.t_s += 0.5;
        frame.lanes[0].limiter_active = false;
        let events = b.step(&frame, 4, false).events;
        assert_eq!(events[0].message, "limiter released after 0.50 s");
        b.reset();
        frame.lanes[0].state.mode = Mode::Free;
        assert!(
            b.step(&frame, 5, true).events.is_empty(),
            "a rewind is no change"
        );
        assert!(
            b.step(&frame, 6, false).drawn.is_none(),
            "not drawn, not built"
        );
        assert!(b.step(&frame, 7, true).drawn.is_some());
    }

    /// Every rig in the one `/tf` and `/scene` message of a step, each with its own frames
    /// and entity ids, so that nothing of the three per-algorithm messages is lost.
    #[test]
    fn one_message_carries_every_rig() {
        let profile = full_flight();
        let algorithms = [AlgorithmId::Smpc, AlgorithmId::Mpc, AlgorithmId::Cwf];
        let mut b = SceneBuilder::new(&profile, &algorithms);
        let mut frame = first_cwf_frame(&profile);
        let lane = frame.lanes[0].clone();
        frame.lanes = algorithms
            .iter()
            .map(|&id| {
                let mut l = lane.clone();
                l.id = id;
                l
            })
            .collect();
        let drawn = b.step(&frame, 9, true).drawn.unwrap();
        for (k, &id) in algorithms.iter().enumerate() {
            let alone = b.transforms(&frame.lanes[k], 9).transforms;
            assert_eq!(drawn.transforms.transforms[3 * k..3 * k + 3], alone[..]);
            let entities = b.scene(&frame.lanes[k], 9).entities;
            assert_eq!(drawn.scene.entities[3 * k..3 * k + 3], entities[..]);
            let ids: Vec<&str> = entities.iter().map(|e| e.id.as_str()).collect();
            let key = id.key();
            assert_eq!(
                ids,
                [
                    format!("{key}/base"),
                    format!("{key}/platform"),
                    format!("{key}/legs")
                ]
            );
        }
        let unique: std::collections::BTreeSet<&str> =
            drawn.scene.entities.iter().map(|e| e.id.as_str()).collect();
        assert_eq!(unique.len(), 9);
    }
}
