//! `--foxglove`: a WebSocket client (tungstenite, loopback only) connects to a headless
//! `play`, sees the channels advertised with Foxglove's schemas and receives messages whose
//! transforms follow the platform's pose; to a headless `live` session, it also receives the
//! session's events. Every wait is bounded.

mod common;

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::net::TcpListener;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use ::foxglove::messages::{FrameTransforms, SceneUpdate};
use ::foxglove::Decode;
use common::*;
use tungstenite::client::IntoClientRequest;
use tungstenite::stream::MaybeTlsStream;
use tungstenite::Message;

/// Longest any single wait of these tests may take.
const PATIENCE: Duration = Duration::from_secs(30);

/// What a session of the CWF alone serves: its topics, and `/events`, advertised from the
/// start.
fn cwf_channels() -> Vec<&'static str> {
    CWF_TOPICS.iter().copied().chain(["/events"]).collect()
}

/// A hexcue process this test started; killed (by its own pid) if the test ends early.
struct Hexcue {
    child: Child,
    stderr: mpsc::Receiver<String>,
}

impl Hexcue {
    fn spawn(args: &[&str]) -> Hexcue {
        let mut child = Command::new(env!("CARGO_BIN_EXE_hexcue"))
            .args(args)
            .current_dir(repo())
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("the hexcue binary runs");
        let (tx, rx) = mpsc::channel();
        let err = child.stderr.take().unwrap();
        std::thread::spawn(move || {
            for line in BufReader::new(err).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        Hexcue { child, stderr: rx }
    }

    /// The address from "foxglove: serving ws://ADDR …".
    fn serving(&self) -> String {
        let until = Instant::now() + PATIENCE;
        let mut seen = Vec::new();
        while let Some(left) = until.checked_duration_since(Instant::now()) {
            let Ok(line) = self.stderr.recv_timeout(left) else {
                break;
            };
            if let Some(rest) = line.strip_prefix("foxglove: serving ws://") {
                return rest.split_whitespace().next().unwrap().to_string();
            }
            seen.push(line);
        }
        panic!(
            "hexcue never said where it serves; stderr:\n{}",
            seen.join("\n")
        );
    }

    /// SIGINT, as Ctrl-C would, then the exit status (bounded).
    fn interrupt(mut self) -> std::process::ExitStatus {
        // SAFETY: kill(2) on the pid of the child this test spawned and has not reaped.
        unsafe { libc::kill(self.child.id() as libc::pid_t, libc::SIGINT) };
        let until = Instant::now() + PATIENCE;
        while Instant::now() < until {
            if let Some(status) = self.child.try_wait().unwrap() {
                return status;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        panic!("hexcue did not stop on SIGINT within {PATIENCE:?}");
    }
}

impl Drop for Hexcue {
    fn drop(&mut self) {
        if self.child.try_wait().ok().flatten().is_none() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

type Socket = tungstenite::WebSocket<MaybeTlsStream<std::net::TcpStream>>;

fn connect(addr: &str) -> Socket {
    let mut request = format!("ws://{addr}").into_client_request().unwrap();
    request
        .headers_mut()
        .insert("Sec-WebSocket-Protocol", "foxglove.sdk.v1".parse().unwrap());
    let (socket, response) = tungstenite::connect(request).expect("the server accepts a client");
    assert_eq!(
        response.headers()["sec-websocket-protocol"],
        "foxglove.sdk.v1"
    );
    if let MaybeTlsStream::Plain(tcp) = socket.get_ref() {
        tcp.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    }
    socket
}

struct Advertised {
    id: u64,
    encoding: String,
    schema_name: String,
    schema_encoding: String,
    /// The schema as advertised: JSON Schema text, or a base64 FileDescriptorSet.
    schema: String,
}

/// Reads text messages until the advertised topics include `wanted`.
fn advertised(socket: &mut Socket, wanted: &[&str]) -> BTreeMap<String, Advertised> {
    let mut channels = BTreeMap::new();
    let mut ops = Vec::new();
    let until = Instant::now() + PATIENCE;
    while !wanted.iter().all(|t| channels.contains_key(*t)) {
        assert!(Instant::now() < until, "advertised {:?}", channels.keys());
        let Message::Text(text) = socket.read().expect("the server talks") else {
            continue;
        };
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        ops.push(v["op"].as_str().unwrap_or_default().to_string());
        if v["op"] == "advertise" {
            for c in v["channels"].as_array().unwrap() {
                let s = |k: &str| c[k].as_str().unwrap_or_default().to_string();
                channels.insert(
                    s("topic"),
                    Advertised {
                        id: c["id"].as_u64().unwrap(),
                        encoding: s("encoding"),
                        schema_name: s("schemaName"),
                        schema_encoding: s("schemaEncoding"),
                        schema: s("schema"),
                    },
                );
            }
        }
    }
    assert_eq!(
        ops.first().map(String::as_str),
        Some("serverInfo"),
        "{ops:?}"
    );
    channels
}

#[test]
fn a_websocket_client_sees_the_channels_and_receives_messages() {
    let hexcue = Hexcue::spawn(&[
        "play",
        "--headless",
        "--algorithms",
        "cwf",
        "--foxglove",
        "127.0.0.1:0",
        "--speed",
        "2",
    ]);
    let addr = hexcue.serving();
    assert!(addr.starts_with("127.0.0.1:"), "{addr}");
    let mut socket = connect(&addr);
    let channels = advertised(&mut socket, &cwf_channels());
    for (topic, schema, encoding) in [
        ("/tf", "foxglove.FrameTransforms", "protobuf"),
        ("/scene", "foxglove.SceneUpdate", "protobuf"),
        ("/events", "foxglove.Log", "protobuf"),
        ("/cwf/platform", "hexcue.Platform", "json"),
        ("/aircraft", "hexcue.Aircraft", "json"),
    ] {
        let c = &channels[topic];
        assert_eq!(
            (c.schema_name.as_str(), c.encoding.as_str()),
            (schema, encoding)
        );
        let schema_encoding = if encoding == "json" {
            "jsonschema"
        } else {
            "protobuf"
        };
        assert_eq!(c.schema_encoding, schema_encoding, "{topic}");
    }

    let subscriptions = [(1u32, "/tf"), (2, "/cwf/platform"), (3, "/scene")];
    let subscribe = serde_json::json!({
        "op": "subscribe",
        "subscriptions": subscriptions
            .iter()
            .map(|(id, topic)| serde_json::json!({"id": id, "channelId": channels[*topic].id}))
            .collect::<Vec<_>>(),
    });
    socket
        .send(Message::Text(subscribe.to_string().into()))
        .unwrap();

    // Messages by subscription, keyed by log time, until a transform and a pose share one.
    let mut tfs: BTreeMap<u64, FrameTransforms> = BTreeMap::new();
    let mut poses: BTreeMap<u64, Vec<f64>> = BTreeMap::new();
    let mut scenes = 0;
    let mut last_time = 0;
    let until = Instant::now() + PATIENCE;
    let matched = loop {
        assert!(
            Instant::now() < until,
            "no transform and pose of the same step"
        );
        let Message::Binary(data) = socket.read().expect("messages arrive") else {
            continue;
        };
        // Opcode 1: message data (u32 subscription, u64 log time, payload).
        if data[0] != 1 {
            continue;
        }
        let sub = u32::from_le_bytes(data[1..5].try_into().unwrap());
        let t = u64::from_le_bytes(data[5..13].try_into().unwrap());
        let payload = &data[13..];
        match sub {
            1 => {
                assert!(t >= last_time, "log time went back");
                last_time = t;
                tfs.insert(t, FrameTransforms::decode(payload).unwrap());
            }
            2 => {
                let v: serde_json::Value = serde_json::from_slice(payload).unwrap();
                let pose = v["pose"].as_array().unwrap();
                poses.insert(t, pose.iter().map(|x| x.as_f64().unwrap()).collect());
            }
            3 => {
                let scene = SceneUpdate::decode(payload).unwrap();
                assert_eq!(scene.entities.len(), 3);
                assert_eq!(scene.entities[2].lines.len(), 6, "six legs");
                scenes += 1;
            }
            other => panic!("a message for subscription {other}"),
        }
        if let Some(t) = tfs.keys().rev().find(|t| poses.contains_key(t)) {
            if scenes > 0 {
                break *t;
            }
        }
    };
    let platform = &tfs[&matched].transforms[1];
    assert_eq!(platform.parent_frame_id, "cwf/base");
    assert_eq!(platform.child_frame_id, "cwf/platform");
    let at = platform.translation.as_ref().unwrap();
    // The JSON keeps 6 decimals (docs/recordings.md, "Size per minute"); the transform is
    // drawn from the full pose at 2^-12 m (src/channels/scene.rs): within half of that.
    for (a, b) in [at.x, at.y, at.z].iter().zip(&poses[&matched][..3]) {
        assert!((a - b).abs() <= 5e-7 + 2f64.powi(-13) + 1e-12, "{a} vs {b}");
    }
    socket.close(None).ok();

    let status = hexcue.interrupt();
    assert!(status.success(), "hexcue ended with {status}");
}

#[test]
fn an_address_in_use_is_refused_by_name() {
    let taken = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = taken.local_addr().unwrap().to_string();
    let out = hexcue(&[
        "play",
        "--headless",
        "--algorithms",
        "cwf",
        "--foxglove",
        &addr,
    ]);
    assert!(!out.status.success());
    let err = stderr(&out);
    assert!(err.contains(&format!("--foxglove {addr}")), "{err}");
    assert!(stdout(&out).is_empty());
}

#[test]
fn a_bad_address_or_speed_is_refused() {
    let out = hexcue(&["play", "--headless", "--foxglove", "localhost"]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("--foxglove"), "{}", stderr(&out));
    // --speed takes the console's speeds, which also pace a headless run with --foxglove.
    for bad in ["0", "3"] {
        let out = hexcue(&[
            "play",
            "--headless",
            "--foxglove",
            "127.0.0.1:0",
            "--speed",
            bad,
        ]);
        assert!(!out.status.success());
        assert!(
            stderr(&out).contains("0.25, 0.5, 1, 2, 4, 8, 16, max"),
            "{}",
            stderr(&out)
        );
    }
    let out = hexcue(&[
        "live",
        "--headless",
        "--input",
        "jsbsim://127.0.0.1:0",
        "--foxglove",
        "nowhere",
    ]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("--foxglove"), "{}", stderr(&out));
}

/// The topics of a recording with their schema names.
fn channels_of(path: &std::path::Path) -> BTreeMap<String, String> {
    let bytes = std::fs::read(path).unwrap();
    let summary = mcap::Summary::read(&bytes)
        .unwrap()
        .expect("a finished recording");
    summary
        .channels
        .values()
        .map(|c| {
            let schema = c.schema.as_ref().map_or(String::new(), |s| s.name.clone());
            (c.topic.clone(), schema)
        })
        .collect()
}

/// `hexcue live --headless --foxglove` against a simulator that sends level flight, pauses
/// long enough for the input to be lost, resumes, and is still sending when --duration ends
/// the session with a stop: a WebSocket client sees the recording's channels advertised,
/// transforms, and the session's events (input lost, to neutral, stopping) on `/events`; the
/// session's recording has the same channels as a playback's, and the same events. The
/// server is fed from the recorder (`LiveRecording::serve`): every message on the wire is the
/// recording's, byte for byte and at the same log time.
#[test]
fn a_live_session_serves_its_channels_and_events_to_foxglove() {
    let dir = tempfile::tempdir().unwrap();
    let in_port = std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let mcap = dir.path().join("live.mcap");
    let session = Hexcue::spawn(&[
        "live",
        "--headless",
        "--input",
        &format!("jsbsim://127.0.0.1:{in_port}"),
        "--algorithms",
        "cwf",
        "--drive",
        "cwf",
        // The return after the loss takes up to the profile's 4.5 s and the session then
        // engages again: 12 s leaves the stop to find it moving (at 8 s it raced the return).
        "--duration",
        "12",
        "--record",
        mcap.to_str().unwrap(),
        "--foxglove",
        "127.0.0.1:0",
    ]);
    let addr = session.serving();
    let mut socket = connect(&addr);
    let channels = advertised(&mut socket, &cwf_channels());
    assert_eq!(channels["/events"].schema_name, "foxglove.Log");
    let subscribe = serde_json::json!({
        "op": "subscribe",
        "subscriptions": [
            {"id": 1, "channelId": channels["/events"].id},
            {"id": 2, "channelId": channels["/tf"].id},
            {"id": 3, "channelId": channels["/cwf/platform"].id},
        ],
    });
    socket
        .send(Message::Text(subscribe.to_string().into()))
        .unwrap();

    // The simulator: 100 Hz, silent from 4 s to 4.6 s, then on until the session ends.
    let sending = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(true));
    let sender = {
        let sending = sending.clone();
        std::thread::spawn(move || {
            let tx = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
            let to = format!("127.0.0.1:{in_port}");
            let start = Instant::now();
            let mut k = 0u64;
            while sending.load(std::sync::atomic::Ordering::Relaxed) && start.elapsed() < PATIENCE {
                let t = k as f64 * 0.01;
                if !(4.0..4.6).contains(&t) {
                    // Level flight with a gentle surge (ft/s², as JSBSim sends).
                    let line = format!("{t},{},0,-32.17,0,0,0,0,0,0\n", 2.0 * (t * 0.5).sin());
                    let _ = tx.send_to(line.as_bytes(), &to);
                }
                k += 1;
                let due = start + Duration::from_secs_f64(k as f64 * 0.01);
                std::thread::sleep(due.saturating_duration_since(Instant::now()));
            }
        })
    };

    let mut events: Vec<String> = Vec::new();
    let mut transforms = 0;
    // What came over the wire: (topic, log time) → bytes.
    let mut served: BTreeMap<(&str, u64), Vec<u8>> = BTreeMap::new();
    let until = Instant::now() + PATIENCE;
    while Instant::now() < until
        && !events
            .iter()
            .any(|e| e.starts_with("parked at neutral after"))
    {
        // The server stops when the session ends: the socket then fails.
        let Ok(message) = socket.read() else { break };
        let Message::Binary(data) = message else {
            continue;
        };
        if data[0] != 1 {
            continue;
        }
        let sub = u32::from_le_bytes(data[1..5].try_into().unwrap());
        let t = u64::from_le_bytes(data[5..13].try_into().unwrap());
        let topic = match sub {
            1 => {
                events.push(
                    ::foxglove::messages::Log::decode(&data[13..])
                        .unwrap()
                        .message,
                );
                "/events"
            }
            2 => {
                transforms += 1;
                "/tf"
            }
            3 => "/cwf/platform",
            other => panic!("a message for subscription {other}"),
        };
        served.insert((topic, t), data[13..].to_vec());
    }
    sending.store(false, std::sync::atomic::Ordering::Relaxed);
    sender.join().unwrap();
    let status = {
        let mut h = session;
        let until = Instant::now() + PATIENCE;
        loop {
            if let Some(status) = h.child.try_wait().unwrap() {
                break status;
            }
            assert!(Instant::now() < until, "the session did not end");
            std::thread::sleep(Duration::from_millis(20));
        }
    };
    assert!(status.success(), "hexcue live ended with {status}");
    assert!(transforms > 100, "{transforms} transforms");
    for start in [
        "engaging",
        "running",
        "input lost",
        "to neutral: input lost",
        "input back",
        "stopping: return to neutral, then park",
        "parked at neutral after the stop",
    ] {
        assert!(
            events.iter().any(|e| e.starts_with(start)),
            "no `{start}…` on /events: {events:#?}"
        );
    }

    // The recording: the channels of a playback's, and the same events as served.
    let played = dir.path().join("played.mcap");
    let out = hexcue(&[
        "play",
        "--headless",
        "--algorithms",
        "cwf",
        "--record",
        played.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(channels_of(&mcap), channels_of(&played));
    let recorded = recorded_events(&mcap);
    for e in &events {
        assert!(
            recorded.contains(e),
            "`{e}` served but not recorded: {recorded:#?}"
        );
    }

    // One encoding for both: each served message whose step the recording also holds is the
    // recording's message at that log time, byte for byte (the transforms are served at every
    // step but recorded at 30 Hz; events and the platform are recorded at every one).
    let bytes = std::fs::read(&mcap).unwrap();
    let in_file: BTreeMap<(String, u64), Vec<u8>> = mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(Result::unwrap)
        .map(|m| ((m.channel.topic.clone(), m.log_time), m.data.into_owned()))
        .collect();
    let mut same = BTreeMap::<&str, usize>::new();
    for ((topic, t), data) in &served {
        match in_file.get(&(topic.to_string(), *t)) {
            Some(recorded) => {
                assert!(
                    recorded == data,
                    "{topic} at {t}: the bytes served differ from the recording's"
                );
                *same.entry(topic).or_default() += 1;
            }
            None => assert_eq!(
                *topic, "/tf",
                "{topic} served at {t}, a log time the recording does not have"
            ),
        }
    }
    for topic in ["/events", "/tf", "/cwf/platform"] {
        assert!(
            same.get(topic).is_some_and(|n| *n > 0),
            "no {topic} message both served and recorded: {same:?}"
        );
    }
}

/// The topics a table of `doc` lists, with their schemas: rows `` | `TOPIC` | `SCHEMA` | … ``,
/// `ALG` standing for each algorithm.
fn documented_topics(doc: &str) -> BTreeMap<String, String> {
    let text = std::fs::read_to_string(repo().join(doc)).unwrap();
    let mut topics = BTreeMap::new();
    for line in text.lines() {
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        let [_, topic, schema, ..] = cells[..] else {
            continue;
        };
        let (Some(topic), Some(schema)) = (
            topic.strip_prefix("`/").and_then(|t| t.strip_suffix('`')),
            schema.strip_prefix('`').and_then(|s| s.strip_suffix('`')),
        ) else {
            continue;
        };
        if topic.contains('`')
            || !(schema.starts_with("hexcue.") || schema.starts_with("foxglove."))
        {
            continue;
        }
        for alg in ["smpc", "mpc", "cwf"] {
            topics.insert(
                format!("/{}", topic.replace("ALG", alg)),
                schema.to_string(),
            );
        }
    }
    topics
}

/// `value` against the top level of a JSON schema: an object with every `required` property,
/// none that the schema does not list, each of the type the schema gives it (and of its
/// length, for arrays of a fixed one). Returns what is wrong.
fn schema_faults(schema: &serde_json::Value, value: &serde_json::Value) -> Vec<String> {
    let mut faults = Vec::new();
    let Some(object) = value.as_object() else {
        return vec![format!("not an object: {value}")];
    };
    let properties = schema["properties"]
        .as_object()
        .expect("a schema with properties");
    for key in schema["required"].as_array().into_iter().flatten() {
        let key = key.as_str().unwrap();
        if !object.contains_key(key) {
            faults.push(format!("`{key}` missing"));
        }
    }
    for (key, v) in object {
        let Some(property) = properties.get(key) else {
            faults.push(format!("`{key}` not in the schema"));
            continue;
        };
        let types: Vec<&str> = match &property["type"] {
            serde_json::Value::String(t) => vec![t.as_str()],
            serde_json::Value::Array(ts) => ts.iter().filter_map(|t| t.as_str()).collect(),
            _ => continue, // a `$ref` or `anyOf`: not checked here
        };
        let fits = |t: &str| match t {
            "number" => v.is_number(),
            "integer" => v.is_u64() || v.is_i64(),
            "string" => v.is_string(),
            "boolean" => v.is_boolean(),
            "array" => v.is_array(),
            "object" => v.is_object(),
            "null" => v.is_null(),
            _ => true,
        };
        if !types.iter().any(|t| fits(t)) {
            faults.push(format!("`{key}` = {v} is not {types:?}"));
        }
        if let (Some(items), Some(n)) = (v.as_array(), property["minItems"].as_u64()) {
            if property["maxItems"].as_u64() == Some(n) && items.len() as u64 != n {
                faults.push(format!("`{key}` has {} items, not {n}", items.len()));
            }
        }
    }
    faults
}

/// Issue 38: a client that subscribes to everything a headless `play` of the three algorithms
/// serves finds the channels docs/recordings.md and docs/foxglove.md list, with their schemas
/// and nothing else, and on each a message its advertised schema decodes: JSON that fits the
/// advertised JSON schema, protobuf that the `foxglove` crate's types decode. `/events`
/// included, with the surge limit cut so that the limiters act.
#[test]
fn a_client_subscribed_to_everything_decodes_every_documented_channel() {
    let mut documented = documented_topics("docs/recordings.md");
    documented.extend(documented_topics("docs/foxglove.md"));
    documented.insert("/events".into(), "foxglove.Log".into());
    // The aircraft, its perception, the events, each algorithm's four JSON topics, and
    // every rig's one `/tf` and `/scene`.
    assert!(documented.len() >= 17, "{documented:#?}");

    // The default profile with 5 cm of surge, so that every algorithm's limiter acts within
    // the first seconds of the stall and `/events` has its `limiter acting` warnings.
    let dir = tempfile::tempdir().unwrap();
    let profile = dir.path().join("short-surge.toml");
    let text = std::fs::read_to_string(repo().join("profiles/full-flight.toml")).unwrap();
    let line = "[limits.surge]\nexcursion_m = 1.7";
    assert!(text.contains(line), "the surge limit moved");
    std::fs::write(
        &profile,
        text.replacen(line, "[limits.surge]\nexcursion_m = 0.05", 1),
    )
    .unwrap();
    let hexcue = Hexcue::spawn(&[
        "play",
        "--headless",
        "--profile",
        profile.to_str().unwrap(),
        "--foxglove",
        "127.0.0.1:0",
        "--speed",
        "4",
    ]);
    let addr = hexcue.serving();
    let mut socket = connect(&addr);
    let wanted: Vec<&str> = documented.keys().map(String::as_str).collect();
    let channels = advertised(&mut socket, &wanted);
    let served: BTreeMap<String, String> = channels
        .iter()
        .map(|(t, c)| (t.clone(), c.schema_name.clone()))
        .collect();
    assert_eq!(
        served, documented,
        "served channels against the docs' tables"
    );

    let mut json_schemas: BTreeMap<u64, serde_json::Value> = BTreeMap::new();
    let mut topic_of: BTreeMap<u32, &str> = BTreeMap::new();
    let mut subscriptions = Vec::new();
    for (k, (topic, c)) in channels.iter().enumerate() {
        let sub = k as u32 + 1;
        topic_of.insert(sub, topic);
        subscriptions.push(serde_json::json!({"id": sub, "channelId": c.id}));
        let expected = if c.encoding == "json" {
            "jsonschema"
        } else {
            "protobuf"
        };
        assert_eq!(c.schema_encoding, expected, "{topic}");
        if c.encoding == "json" {
            let schema = serde_json::from_str(&c.schema)
                .unwrap_or_else(|e| panic!("{topic}: the advertised JSON schema is not JSON: {e}"));
            json_schemas.insert(c.id, schema);
        }
    }
    socket
        .send(Message::Text(
            serde_json::json!({"op": "subscribe", "subscriptions": subscriptions})
                .to_string()
                .into(),
        ))
        .unwrap();

    let mut received: BTreeMap<&str, usize> = BTreeMap::new();
    let mut events = Vec::new();
    let until = Instant::now() + PATIENCE * 4;
    while received.len() < channels.len() {
        assert!(
            Instant::now() < until,
            "nothing on {:?} (received {received:?})",
            topic_of
                .values()
                .filter(|t| !received.contains_key(*t))
                .collect::<Vec<_>>()
        );
        let message = socket.read().unwrap_or_else(|e| {
            panic!("the server stopped ({e}) before every channel sent: {received:?}")
        });
        let Message::Binary(data) = message else {
            continue;
        };
        if data[0] != 1 {
            continue;
        }
        let sub = u32::from_le_bytes(data[1..5].try_into().unwrap());
        let payload = &data[13..];
        let topic = topic_of[&sub];
        let c = &channels[topic];
        if c.encoding == "json" {
            let value: serde_json::Value = serde_json::from_slice(payload)
                .unwrap_or_else(|e| panic!("{topic}: not JSON: {e}"));
            let faults = schema_faults(&json_schemas[&c.id], &value);
            assert!(faults.is_empty(), "{topic}: {faults:?} in {value}");
        } else {
            match c.schema_name.as_str() {
                "foxglove.FrameTransforms" => {
                    let tf = FrameTransforms::decode(payload).unwrap();
                    assert_eq!(
                        tf.transforms.len(),
                        9,
                        "{topic}: world → base → platform → eye of each of the three"
                    );
                }
                "foxglove.SceneUpdate" => {
                    let scene = SceneUpdate::decode(payload).unwrap();
                    assert_eq!(
                        scene.entities.len(),
                        9,
                        "{topic}: base, platform, legs of each of the three"
                    );
                }
                "foxglove.Log" => {
                    events.push(::foxglove::messages::Log::decode(payload).unwrap().message)
                }
                other => panic!("{topic}: an undocumented schema {other}"),
            }
        }
        *received.entry(topic).or_default() += 1;
    }
    socket.close(None).ok();
    eprintln!("received {received:?}; events {events:?}");
    assert!(
        events.iter().any(|e| e.contains("limiter acting")),
        "{events:?}"
    );
    let status = hexcue.interrupt();
    assert!(status.success(), "hexcue ended with {status}");
}
