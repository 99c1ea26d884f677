//! `--foxglove`: a WebSocket client (tungstenite, loopback only) connects to a headless
//! `play`, sees the channels advertised with Foxglove's schemas and receives messages whose
//! transforms follow the platform's pose. Every wait is bounded.

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
    let wanted = [
        "/aircraft",
        "/aircraft/perceived",
        "/cwf/perceived",
        "/cwf/platform",
        "/cwf/actuators",
        "/cwf/controller",
        "/cwf/tf",
        "/cwf/scene",
        "/events",
    ];
    let channels = advertised(&mut socket, &wanted);
    for (topic, schema, encoding) in [
        ("/cwf/tf", "foxglove.FrameTransforms", "protobuf"),
        ("/cwf/scene", "foxglove.SceneUpdate", "protobuf"),
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

    let subscriptions = [(1u32, "/cwf/tf"), (2, "/cwf/platform"), (3, "/cwf/scene")];
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
    assert_eq!([at.x, at.y, at.z], poses[&matched][..3]);
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
    let out = hexcue(&["play", "--headless", "--speed", "0"]);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("speed factor > 0"),
        "{}",
        stderr(&out)
    );
    let out = hexcue(&["play", "--speed", "2"]);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("--speed goes with --headless"),
        "{}",
        stderr(&out)
    );
}
