//! Foxglove's well-known messages in a recording: the recorder's channels `/tf`, `/scene`
//! (every algorithm's rig in one message each) and `/events`, protobuf-encoded with the schemas the `foxglove` crate carries
//! (the ones the Foxglove app knows).

use std::collections::BTreeMap;
use std::sync::{Arc, OnceLock};

use ::foxglove::messages::{FrameTransforms, Log, SceneUpdate};
use ::foxglove::{Decode, Encode};
use nalgebra::{UnitQuaternion, Vector3};

use crate::formats::recording::{json_messages, Recorder, RecordingMeta};
use hexcue_core::engine::{Engine, Frame};
use hexcue_core::mca::AlgorithmId;
use hexcue_core::model::stewart::rotation;
use hexcue_core::profile::text::DEFAULT_PROFILE_TOML;
use hexcue_core::testing::full_flight;
use hexcue_core::testing::manoeuvre;

/// 800 steps of the synthetic manoeuvre (the surge pulse and the turn entry), CWF and
/// MPC, recorded; the frames and the file's bytes.
fn recorded() -> &'static (Vec<Frame>, Vec<u8>) {
    static REC: OnceLock<(Vec<Frame>, Vec<u8>)> = OnceLock::new();
    REC.get_or_init(|| {
        let algorithms = vec![AlgorithmId::Cwf, AlgorithmId::Mpc];
        let trace = Arc::new(manoeuvre());
        let mut engine = Engine::new(&full_flight(), trace.clone(), &algorithms).unwrap();
        let frames: Vec<Frame> = (0..800).map_while(|_| engine.step()).collect();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("scene.mcap");
        let meta = RecordingMeta {
            profile_name: "full-flight".into(),
            profile_toml: DEFAULT_PROFILE_TOML.into(),
            trace_name: trace.name.clone(),
            trace_csv: "t,fx,fy,fz,p,q,r\n".into(),
            trace_sidecar: None,
            algorithms,
            rate_hz: 100.0,
            profile: Some(full_flight()),
        };
        let mut rec = Recorder::create(&path, &meta).unwrap();
        for f in &frames {
            rec.record(f).unwrap();
        }
        rec.finish().unwrap();
        (frames, std::fs::read(&path).unwrap())
    })
}

/// Messages by topic: (log time, data).
fn by_topic(bytes: &[u8]) -> BTreeMap<String, Vec<(u64, Vec<u8>)>> {
    let mut out: BTreeMap<String, Vec<(u64, Vec<u8>)>> = BTreeMap::new();
    for m in mcap::MessageStream::new(bytes).unwrap() {
        let m = m.unwrap();
        out.entry(m.channel.topic.clone())
            .or_default()
            .push((m.log_time, m.data.into_owned()));
    }
    out
}

fn rotate(q: &::foxglove::messages::Quaternion, v: &Vector3<f64>) -> Vector3<f64> {
    UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q.w, q.x, q.y, q.z)) * v
}

#[test]
fn the_platform_transform_follows_the_recorded_pose() {
    let (frames, bytes) = recorded();
    let topics = by_topic(bytes);
    let tfs = &topics["/tf"];
    for (k, alg) in ["cwf", "mpc"].into_iter().enumerate() {
        let platforms: BTreeMap<u64, &Vec<u8>> = topics[&format!("/{alg}/platform")]
            .iter()
            .map(|(t, p)| (*t, p))
            .collect();
        // Drawn every 3rd step at 100 Hz (33 Hz, the recorder's scene_every_steps), from the
        // first.
        assert_eq!(super::writer::scene_every_steps(100.0), 3);
        assert_eq!(tfs.len(), frames.len().div_ceil(3));
        let mut moved = 0.0f64;
        for (t_tf, tf) in tfs {
            let platform = platforms
                .get(t_tf)
                .expect("a transform at a step's log time");
            let all = FrameTransforms::decode(&tf[..]).unwrap();
            // The algorithms' frames in the session's order, three each.
            assert_eq!(all.transforms.len(), 6);
            let tf = FrameTransforms {
                transforms: all.transforms[3 * k..3 * k + 3].to_vec(),
            };
            let pose: Vec<f64> = serde_json::from_slice::<serde_json::Value>(platform).unwrap()
                ["pose"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect();
            let names: Vec<(&str, &str)> = tf
                .transforms
                .iter()
                .map(|t| (t.parent_frame_id.as_str(), t.child_frame_id.as_str()))
                .collect();
            let (base, platform_frame, eye) = (
                format!("{alg}/base"),
                format!("{alg}/platform"),
                format!("{alg}/eye"),
            );
            assert_eq!(
                names,
                [
                    ("world", base.as_str()),
                    (base.as_str(), platform_frame.as_str()),
                    (platform_frame.as_str(), eye.as_str())
                ]
            );
            let p = &tf.transforms[1];
            let stamp = p.timestamp.unwrap();
            assert_eq!(stamp.total_nanos(), *t_tf);
            // The recorded pose keeps 6 decimals; the transform is drawn from the full one
            // at 2^-12 m.
            let at = p.translation.as_ref().unwrap();
            for (a, b) in [at.x, at.y, at.z].iter().zip(&pose[..3]) {
                assert!((a - b).abs() <= 5e-7 + 2f64.powi(-13) + 1e-12, "{a} vs {b}");
            }
            let r = rotation(pose[3], pose[4], pose[5]);
            let q = p.rotation.as_ref().unwrap();
            for v in [Vector3::x(), Vector3::y(), Vector3::z()] {
                // Quaternion components at 2^-16: a direction within about 2 × 2^-16.
                assert!((rotate(q, &v) - r * v).norm() < 1e-4);
            }
            moved = moved.max(pose[0].abs());
        }
        // The surge pulse moves the platform: the comparison was not all zeros.
        assert!(moved > 0.01, "{alg}: surge at most {moved} m");
    }
}

#[test]
fn the_schemas_are_foxglove_well_known_ones() {
    let (_, bytes) = recorded();
    let summary = mcap::Summary::read(bytes).unwrap().unwrap();
    let mut seen = BTreeMap::new();
    for channel in summary.channels.values() {
        let Some(schema) = &channel.schema else {
            continue;
        };
        if schema.encoding != "protobuf" {
            assert_eq!(schema.encoding, "jsonschema", "{}", channel.topic);
            continue;
        }
        assert_eq!(channel.message_encoding, "protobuf");
        // The descriptor set names the message type and its fields as Foxglove defines them.
        let set =
            <prost_types::FileDescriptorSet as prost::Message>::decode(&schema.data[..]).unwrap();
        let (package, message) = schema.name.split_once('.').unwrap();
        let fields: Vec<String> = set
            .file
            .iter()
            .filter(|f| f.package() == package)
            .flat_map(|f| &f.message_type)
            .filter(|m| m.name() == message)
            .flat_map(|m| m.field.iter().map(|f| f.name().to_string()))
            .collect();
        seen.insert(channel.topic.clone(), (schema.name.clone(), fields));
    }
    let expect = |topic: &str, name: &str, fields: &[&str]| {
        let (n, f) = &seen[topic];
        assert_eq!(n, name, "{topic}");
        for field in fields {
            assert!(
                f.iter().any(|x| x == field),
                "{topic}: no field {field} in {f:?}"
            );
        }
    };
    expect("/tf", "foxglove.FrameTransforms", &["transforms"]);
    expect("/scene", "foxglove.SceneUpdate", &["deletions", "entities"]);
    expect(
        "/events",
        "foxglove.Log",
        &["timestamp", "level", "message", "name"],
    );
    assert_eq!(seen.len(), 3, "{seen:?}");
    // And exactly the crate's own descriptors, which the Foxglove app ships too.
    let tf = summary
        .channels
        .values()
        .find(|c| c.topic == "/tf")
        .unwrap();
    let data = &tf.schema.as_ref().unwrap().data;
    assert_eq!(data[..], FrameTransforms::get_schema().unwrap().data[..]);
    let _ = (SceneUpdate::get_schema(), Log::get_schema());
}

#[test]
fn the_scene_draws_plates_and_six_legs_for_each_algorithm() {
    let (frames, bytes) = recorded();
    let topics = by_topic(bytes);
    let scenes = &topics["/scene"];
    let all = SceneUpdate::decode(&scenes[scenes.len() - 1].1[..]).unwrap();
    let ids: Vec<&str> = all.entities.iter().map(|e| e.id.as_str()).collect();
    assert_eq!(
        ids,
        [
            "cwf/base",
            "cwf/platform",
            "cwf/legs",
            "mpc/base",
            "mpc/platform",
            "mpc/legs"
        ]
    );
    let last = SceneUpdate {
        deletions: Vec::new(),
        entities: all.entities[3..].to_vec(),
    };
    let legs = &last.entities[2];
    assert_eq!(legs.frame_id, "mpc/base");
    // Drawn every n-th step (3 at 100 Hz): the last scene is that of step n × (count − 1).
    let every = super::writer::scene_every_steps(100.0) as usize;
    let k = every * (scenes.len() - 1);
    assert!(k < frames.len() && frames.len() - k <= every);
    let lane = frames[k].lane(AlgorithmId::Mpc).unwrap();
    for (i, line) in legs.lines.iter().enumerate() {
        let [a, b] = [&line.points[0], &line.points[1]];
        let length = Vector3::new(b.x - a.x, b.y - a.y, b.z - a.z).norm();
        // The upper end is drawn at 2^-12 m per coordinate: within √3 · 2^-13 m.
        assert!((length - lane.legs.length_m[i]).abs() < 3e-4, "leg {i}");
    }
    assert_eq!(last.entities[1].frame_id, "mpc/platform");
    assert!(last.entities[1].frame_locked);
    assert_eq!(last.entities[0].triangles[0].points.len(), 18);
}

#[test]
fn live_json_is_the_recorded_json() {
    let (frames, bytes) = recorded();
    let topics = by_topic(bytes);
    for (k, frame) in frames.iter().enumerate().step_by(97) {
        for (topic, _, data) in json_messages(frame).unwrap() {
            assert_eq!(topics[&topic][k].1, data, "{topic} at step {k}");
        }
    }
}

#[test]
fn session_events_are_recorded_as_logs() {
    let (frames, _) = recorded();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("events.mcap");
    let meta = RecordingMeta {
        profile_name: "full-flight".into(),
        profile_toml: DEFAULT_PROFILE_TOML.into(),
        trace_name: "manoeuvre".into(),
        trace_csv: "t,fx,fy,fz,p,q,r\n".into(),
        trace_sidecar: None,
        algorithms: vec![AlgorithmId::Cwf, AlgorithmId::Mpc],
        rate_hz: 100.0,
        profile: Some(full_flight()),
    };
    let mut rec = Recorder::create(&path, &meta).unwrap();
    rec.record(&frames[0]).unwrap();
    rec.event(
        0.0,
        hexcue_core::events::EventLevel::Warning,
        "live",
        "input lost: washout",
    )
    .unwrap();
    rec.finish().unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let events = &by_topic(&bytes)["/events"];
    let log = Log::decode(&events[0].1[..]).unwrap();
    assert_eq!(
        (log.name.as_str(), log.message.as_str()),
        ("live", "input lost: washout")
    );
    assert_eq!(log.level, ::foxglove::messages::log::Level::Warning as i32);
}
