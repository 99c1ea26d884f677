//! A Foxglove WebSocket client (protocol `foxglove.sdk.v1`, tungstenite over loopback) for the
//! tests that read and set parameters the way Foxglove's Parameters panel does.

use std::time::{Duration, Instant};

use serde_json::{json, Value};
use tungstenite::client::IntoClientRequest;
use tungstenite::stream::MaybeTlsStream;
use tungstenite::Message;

pub type Socket = tungstenite::WebSocket<MaybeTlsStream<std::net::TcpStream>>;

/// How long any answer may take, at most.
const PATIENCE: Duration = Duration::from_secs(60);

pub fn connect(addr: &str) -> Socket {
    let mut request = format!("ws://{addr}").into_client_request().unwrap();
    request
        .headers_mut()
        .insert("Sec-WebSocket-Protocol", "foxglove.sdk.v1".parse().unwrap());
    let (socket, _) = tungstenite::connect(request).expect("the server accepts a client");
    if let MaybeTlsStream::Plain(tcp) = socket.get_ref() {
        tcp.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    }
    socket
}

/// Reads the server's text messages until one satisfies `wanted`; returns it and every text
/// message read before it.
pub fn read_until(socket: &mut Socket, wanted: impl Fn(&Value) -> bool) -> (Value, Vec<Value>) {
    let until = Instant::now() + PATIENCE;
    let mut before = Vec::new();
    loop {
        assert!(Instant::now() < until, "not answered: {before:?}");
        let Message::Text(text) = socket.read().expect("the server talks") else {
            continue;
        };
        let v: Value = serde_json::from_str(&text).unwrap();
        if wanted(&v) {
            return (v, before);
        }
        before.push(v);
    }
}

pub fn send(socket: &mut Socket, v: Value) {
    socket.send(Message::Text(v.to_string().into())).unwrap();
}

/// The value of `name` in a `parameterValues` message.
pub fn parameter(msg: &Value, name: &str) -> Option<f64> {
    msg["parameters"]
        .as_array()?
        .iter()
        .find(|p| p["name"] == name)
        .and_then(|p| p["value"].as_f64())
}

/// `name` as the server says it now (`getParameters`).
pub fn get(socket: &mut Socket, name: &str) -> Option<f64> {
    send(
        socket,
        json!({"op": "getParameters", "parameterNames": [name], "id": "get"}),
    );
    let (answer, _) = read_until(socket, |v| v["op"] == "parameterValues" && v["id"] == "get");
    parameter(&answer, name)
}

/// Sets `name` to `value` (`setParameters`); returns the value the server answers with.
pub fn set(socket: &mut Socket, name: &str, value: f64) -> Option<f64> {
    send(
        socket,
        json!({"op": "setParameters", "id": "set",
               "parameters": [{"name": name, "value": value, "type": "float64"}]}),
    );
    let (answer, _) = read_until(socket, |v| v["op"] == "parameterValues" && v["id"] == "set");
    parameter(&answer, name)
}
