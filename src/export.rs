//! `hexcue export`: a recording's JSON topics as CSV for MATLAB and spreadsheets
//! (docs/recordings.md, "Export to CSV"). One CSV per topic in a folder, one topic to a file
//! or stdout, or chosen fields of several topics side by side, one row per step. Arrays are
//! expanded to named columns with their unit in the name (`pose_x_m`, `margin_leg3_m`), time
//! first.

use std::collections::{BTreeMap, HashSet};
use std::fmt;
use std::io::Write;
use std::path::Path;

use anyhow::{bail, Context, Result};
use serde::de::{self, Deserialize, Deserializer, MapAccess, SeqAccess, Visitor};

use crate::channels::json::resolution::position;
use crate::formats::recording::{JsonMessage, Recording};

/// A JSON value with its object keys in the order written, so that columns follow the
/// message's own order (`t` first, then the fields as the schema lists them).
#[derive(Clone, Debug, PartialEq)]
enum Node {
    Null,
    Bool(bool),
    /// A number as CSV text: shortest round-trip form.
    Number(String),
    Text(String),
    Array(Vec<Node>),
    Object(Vec<(String, Node)>),
}

impl<'de> Deserialize<'de> for Node {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Node, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Node;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a JSON value")
            }
            fn visit_unit<E: de::Error>(self) -> Result<Node, E> {
                Ok(Node::Null)
            }
            fn visit_none<E: de::Error>(self) -> Result<Node, E> {
                Ok(Node::Null)
            }
            fn visit_bool<E: de::Error>(self, v: bool) -> Result<Node, E> {
                Ok(Node::Bool(v))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Node, E> {
                Ok(Node::Number(v.to_string()))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Node, E> {
                Ok(Node::Number(v.to_string()))
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<Node, E> {
                // Debug is Rust's shortest round-trip form, with an exponent for tiny values.
                Ok(Node::Number(format!("{v:?}")))
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<Node, E> {
                Ok(Node::Text(v.to_string()))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Node, A::Error> {
                let mut v = Vec::new();
                while let Some(x) = seq.next_element()? {
                    v.push(x);
                }
                Ok(Node::Array(v))
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Node, A::Error> {
                let mut v = Vec::new();
                while let Some((k, x)) = map.next_entry::<String, Node>()? {
                    v.push((k, x));
                }
                Ok(Node::Object(v))
            }
        }
        d.deserialize_any(V)
    }
}

/// One CSV column of a topic: its name and the message key it comes from.
#[derive(Clone, Debug, PartialEq)]
pub struct Column {
    name: String,
    key: String,
}

/// Labels of an array's elements, with the unit, for the fields hexcue records (docs/design.md §7:
/// x, y, z or x, y, z, roll, pitch, yaw order; legs 1 to 6). `kind` is the topic's last part.
fn element_labels(kind: &str, key: &str, n: usize) -> Option<Vec<String>> {
    let xyz = |unit: &str| ["x", "y", "z"].map(|a| format!("{a}_{unit}")).to_vec();
    let six = |lin: &str, rot: &str| {
        let mut v = xyz(lin);
        v.extend(["roll", "pitch", "yaw"].map(|a| format!("{a}_{rot}")));
        v
    };
    let legs = |unit: &str| (1..=6).map(|i| format!("leg{i}_{unit}")).collect();
    let labels: Vec<String> = match (kind, key, n) {
        (_, "specific_force", 3) => xyz("mps2"),
        (_, "angular_velocity", 3) => xyz("radps"),
        (_, "attitude", 3) => ["roll", "pitch", "yaw"]
            .map(|a| format!("{a}_rad"))
            .to_vec(),
        ("platform", "pose", 6) => six("m", "rad"),
        ("platform", "velocity", 6) => six("mps", "radps"),
        ("platform", "acceleration", 6) => six("mps2", "radps2"),
        ("actuators", "length" | "margin", 6) => legs("m"),
        ("actuators", "velocity", 6) => legs("mps"),
        _ => return None,
    };
    Some(labels)
}

/// The message flattened to (column, key, text) in the message's order: arrays to one column
/// per element, objects to `key_sub`; an array of objects that have a `name` is labelled by
/// those names (the S-MPC's `solvers_cotc_status`). `null` is an empty cell, booleans 1 and 0.
fn flatten(kind: &str, message: &Node) -> Vec<(String, String, String)> {
    fn walk(name: &str, key: &str, node: &Node, out: &mut Vec<(String, String, String)>) {
        match node {
            Node::Null => out.push((name.into(), key.into(), String::new())),
            Node::Bool(b) => out.push((name.into(), key.into(), u8::from(*b).to_string())),
            Node::Number(n) => out.push((name.into(), key.into(), n.clone())),
            Node::Text(t) => out.push((name.into(), key.into(), t.clone())),
            Node::Object(fields) => {
                for (k, v) in fields {
                    walk(&format!("{name}_{k}"), key, v, out);
                }
            }
            Node::Array(items) => {
                for (i, item) in items.iter().enumerate() {
                    let label = match item {
                        Node::Object(f) => f.iter().find_map(|(k, v)| match (k.as_str(), v) {
                            ("name", Node::Text(t)) => Some(t.clone()),
                            _ => None,
                        }),
                        _ => None,
                    };
                    match (label, item) {
                        (Some(label), Node::Object(f)) => {
                            for (k, v) in f.iter().filter(|(k, _)| k != "name") {
                                walk(&format!("{name}_{label}_{k}"), key, v, out);
                            }
                        }
                        _ => walk(&format!("{name}_{}", i + 1), key, item, out),
                    }
                }
            }
        }
    }
    let mut out = Vec::new();
    let Node::Object(fields) = message else {
        walk("value", "value", message, &mut out);
        return out;
    };
    for (key, value) in fields {
        match (value, key.as_str()) {
            (Node::Number(n), "t") => out.push(("t_s".into(), key.clone(), n.clone())),
            (Node::Array(items), _) => {
                let labels = element_labels(kind, key, items.len());
                match labels {
                    Some(labels) if items.iter().all(|i| !matches!(i, Node::Object(_))) => {
                        for (label, item) in labels.iter().zip(items) {
                            walk(&format!("{key}_{label}"), key, item, &mut out);
                        }
                    }
                    _ => walk(key, key, value, &mut out),
                }
            }
            _ => walk(key, key, value, &mut out),
        }
    }
    // Time first, whatever the message's order.
    if let Some(i) = out.iter().position(|(c, _, _)| c == "t_s") {
        let t = out.remove(i);
        out.insert(0, t);
    }
    out
}

/// The last part of a topic: `platform` for `/cwf/platform`.
fn topic_kind(topic: &str) -> &str {
    topic.rsplit('/').next().unwrap_or(topic)
}

/// A topic's file name: `/cwf/platform` → `cwf-platform.csv`.
pub fn topic_file(topic: &str) -> String {
    let stem: Vec<&str> = topic.split('/').filter(|p| !p.is_empty()).collect();
    format!("{}.csv", stem.join("-"))
}

/// A column of a topic in a table of several topics: `/cwf/platform` + `pose_x_m` →
/// `cwf_platform_pose_x_m` (a valid MATLAB name).
fn qualified(topic: &str, column: &str) -> String {
    let stem: Vec<&str> = topic.split('/').filter(|p| !p.is_empty()).collect();
    format!("{}_{column}", stem.join("_"))
}

/// A message as written, with the leg margins that recordings of format 2 no longer write
/// (docs/recordings.md, "Leg margins") computed from its lengths and the attached profile's
/// stroke as `review` does, so that `/ALG/actuators` has the same columns in every recording.
fn parse(recording: &Recording, m: &JsonMessage) -> Result<Node> {
    let mut node: Node = serde_json::from_slice(&m.data).with_context(|| {
        format!(
            "{}: a message on {} at log time {} ns is not JSON",
            recording.path.display(),
            m.topic,
            m.log_time_ns
        )
    })?;
    if topic_kind(&m.topic) == "actuators" {
        if let (Node::Object(fields), Ok(profile)) = (&mut node, &recording.profile) {
            with_margins(fields, profile);
        }
    }
    Ok(node)
}

/// Adds `margin` after `velocity` when the message has lengths but no margins.
fn with_margins(fields: &mut Vec<(String, Node)>, profile: &hexcue_core::profile::Profile) {
    if fields.iter().any(|(k, _)| k == "margin") {
        return;
    }
    let Some(Node::Array(lengths)) = fields.iter().find(|(k, _)| k == "length").map(|f| &f.1)
    else {
        return;
    };
    let stewart = profile.stewart();
    let margins = lengths
        .iter()
        .map(|l| match l {
            Node::Number(text) => match text.parse::<f64>() {
                Ok(l) => {
                    let m = (l - stewart.leg_min_m).min(stewart.leg_max_m - l);
                    Node::Number(format!("{:?}", position(m)))
                }
                Err(_) => Node::Null,
            },
            _ => Node::Null,
        })
        .collect();
    let at = fields
        .iter()
        .position(|(k, _)| k == "velocity")
        .map_or(fields.len(), |i| i + 1);
    fields.insert(at, ("margin".to_string(), Node::Array(margins)));
}

/// First pass: every topic's columns, in the order they first appear.
pub fn columns(recording: &Recording) -> Result<BTreeMap<String, Vec<Column>>> {
    let mut out: BTreeMap<String, (Vec<Column>, HashSet<String>)> = BTreeMap::new();
    for m in recording.json_messages()? {
        let m = m?;
        let node = parse(recording, &m)?;
        let (cols, seen) = out.entry(m.topic.clone()).or_default();
        for (name, key, _) in flatten(topic_kind(&m.topic), &node) {
            if seen.insert(name.clone()) {
                cols.push(Column { name, key });
            }
        }
    }
    Ok(out.into_iter().map(|(t, (c, _))| (t, c)).collect())
}

/// A CSV destination: a file or stdout.
fn writer(path: Option<&Path>) -> Result<csv::Writer<Box<dyn Write>>> {
    let sink: Box<dyn Write> = match path {
        Some(p) => Box::new(std::io::BufWriter::new(
            std::fs::File::create(p).with_context(|| format!("{}: cannot create", p.display()))?,
        )),
        None => Box::new(std::io::BufWriter::new(std::io::stdout())),
    };
    Ok(csv::WriterBuilder::new().from_writer(sink))
}

/// A closed pipe (`| head`) is the reader's choice, not an error of the export.
fn finish(w: csv::Writer<Box<dyn Write>>, shown: &str) -> Result<()> {
    match w
        .into_inner()
        .map_err(|e| e.into_error())
        .and_then(|mut s| s.flush())
    {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        other => other.with_context(|| format!("{shown}: cannot write")),
    }
}

fn write_record(w: &mut csv::Writer<Box<dyn Write>>, row: &[String], shown: &str) -> Result<bool> {
    match w.write_record(row) {
        Ok(()) => Ok(true),
        Err(e) => match e.kind() {
            csv::ErrorKind::Io(io) if io.kind() == std::io::ErrorKind::BrokenPipe => Ok(false),
            _ => Err(e).with_context(|| format!("{shown}: cannot write")),
        },
    }
}

/// The chosen fields: (topic, column) pairs in the order asked, each field expanded to its
/// columns; an unknown topic or field is refused with what there is.
pub fn chosen(
    fields: &[String],
    all: &BTreeMap<String, Vec<Column>>,
    recording: &Path,
) -> Result<Vec<(String, String)>> {
    let mut out = Vec::new();
    for f in fields.iter().map(|f| f.trim()).filter(|f| !f.is_empty()) {
        let Some((topic, field)) = f.split_once('.') else {
            bail!("--fields: `{f}`: expected TOPIC.FIELD, e.g. /cwf/platform.pose");
        };
        let Some(cols) = all.get(topic) else {
            bail!(
                "--fields: `{f}`: {} has no topic `{topic}`; its topics: {}",
                recording.display(),
                all.keys().cloned().collect::<Vec<_>>().join(", ")
            );
        };
        let matched: Vec<&Column> = cols
            .iter()
            .filter(|c| c.key == field || c.name == field)
            .collect();
        if matched.is_empty() {
            let mut keys: Vec<&str> = Vec::new();
            for c in cols {
                if !keys.contains(&c.key.as_str()) {
                    keys.push(&c.key);
                }
            }
            bail!(
                "--fields: `{f}`: {topic} has no field `{field}`; its fields: {} (or one column, e.g. {})",
                keys.join(", "),
                cols.last().map_or("", |c| c.name.as_str())
            );
        }
        for c in matched {
            let pair = (topic.to_string(), c.name.clone());
            if !out.contains(&pair) {
                out.push(pair);
            }
        }
    }
    if out.is_empty() {
        bail!("--fields: expected at least one TOPIC.FIELD");
    }
    Ok(out)
}

/// What was written, for the message on stderr.
pub struct Written {
    pub path: String,
    pub rows: usize,
    pub columns: usize,
}

/// One topic, one row per message.
pub fn export_one(
    recording: &Recording,
    topic: &str,
    cols: &[Column],
    path: Option<&Path>,
) -> Result<Written> {
    let shown = path.map_or("stdout".to_string(), |p| p.display().to_string());
    let mut w = writer(path)?;
    let header: Vec<String> = cols.iter().map(|c| c.name.clone()).collect();
    let index: BTreeMap<&str, usize> = cols
        .iter()
        .enumerate()
        .map(|(i, c)| (c.name.as_str(), i))
        .collect();
    let mut rows = 0;
    if write_record(&mut w, &header, &shown)? {
        for m in recording.json_messages()? {
            let m = m?;
            if m.topic != topic {
                continue;
            }
            let mut row = vec![String::new(); cols.len()];
            for (name, _, text) in flatten(topic_kind(topic), &parse(recording, &m)?) {
                if let Some(&i) = index.get(name.as_str()) {
                    row[i] = text;
                }
            }
            if !write_record(&mut w, &row, &shown)? {
                break;
            }
            rows += 1;
        }
    }
    finish(w, &shown)?;
    Ok(Written {
        path: shown,
        rows,
        columns: cols.len(),
    })
}

/// Chosen fields of several topics, one row per step (the messages of a step share their log
/// time), time first: the step's `t` from the first of its messages that has one.
pub fn export_fields(
    recording: &Recording,
    pairs: &[(String, String)],
    path: Option<&Path>,
) -> Result<Written> {
    let shown = path.map_or("stdout".to_string(), |p| p.display().to_string());
    let mut w = writer(path)?;
    let mut header = vec!["t_s".to_string()];
    header.extend(pairs.iter().map(|(t, c)| qualified(t, c)));
    let mut index: BTreeMap<(&str, &str), usize> = BTreeMap::new();
    for (i, (t, c)) in pairs.iter().enumerate() {
        index.insert((t.as_str(), c.as_str()), i + 1);
    }
    let topics: HashSet<&str> = pairs.iter().map(|(t, _)| t.as_str()).collect();
    let mut rows = 0;
    let mut open = true;
    if write_record(&mut w, &header, &shown)? {
        let mut row: Vec<String> = vec![String::new(); header.len()];
        let mut step: Option<u64> = None;
        for m in recording.json_messages()? {
            let m = m?;
            if !topics.contains(m.topic.as_str()) {
                continue;
            }
            if step.is_some_and(|s| s != m.log_time_ns) {
                if !write_record(&mut w, &row, &shown)? {
                    open = false;
                    break;
                }
                rows += 1;
                row.iter_mut().for_each(String::clear);
            }
            step = Some(m.log_time_ns);
            for (name, _, text) in flatten(topic_kind(&m.topic), &parse(recording, &m)?) {
                if name == "t_s" && row[0].is_empty() {
                    row[0] = text.clone();
                }
                if let Some(&i) = index.get(&(m.topic.as_str(), name.as_str())) {
                    row[i] = text;
                }
            }
        }
        if open && step.is_some() && write_record(&mut w, &row, &shown)? {
            rows += 1;
        }
    }
    finish(w, &shown)?;
    Ok(Written {
        path: shown,
        rows,
        columns: header.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn node(json: &str) -> Node {
        serde_json::from_str(json).unwrap()
    }

    fn names(kind: &str, json: &str) -> Vec<String> {
        flatten(kind, &node(json))
            .into_iter()
            .map(|c| c.0)
            .collect()
    }

    #[test]
    fn arrays_become_named_columns_with_units_and_time_comes_first() {
        let platform = r#"{"pose":[1,2,3,0.1,0.2,0.3],"t":0.01,"velocity":[0,0,0,0,0,0]}"#;
        let n = names("platform", platform);
        assert_eq!(n[0], "t_s");
        assert_eq!(
            &n[1..7],
            [
                "pose_x_m",
                "pose_y_m",
                "pose_z_m",
                "pose_roll_rad",
                "pose_pitch_rad",
                "pose_yaw_rad"
            ]
        );
        assert_eq!(n[7], "velocity_x_mps");
        assert_eq!(n[12], "velocity_yaw_radps");
        let legs = names(
            "actuators",
            r#"{"t":0,"margin":[1,2,3,4,5,6],"velocity":[1,2,3,4,5,6]}"#,
        );
        assert_eq!(legs[1], "margin_leg1_m");
        assert_eq!(legs[12], "velocity_leg6_mps");
        let aircraft = names(
            "aircraft",
            r#"{"t":0,"specific_force":[0,0,-9.81],"angular_velocity":[0,0,0],"attitude":[0,0,1]}"#,
        );
        assert_eq!(aircraft[3], "specific_force_z_mps2");
        assert_eq!(aircraft[6], "angular_velocity_z_radps");
        assert_eq!(aircraft[9], "attitude_yaw_rad");
    }

    #[test]
    fn cells_are_numbers_as_written_empty_for_null_and_one_zero_for_booleans() {
        let c = flatten(
            "controller",
            &node(
                r#"{"t":1.5,"mode":"cotc","blend":null,"limiter_active":true,"iterations":7,
                "solve_time_us":1e-7,"solvers":[{"name":"cotc","status":"solved","iterations":3},
                {"name":"free","status":"standby","iterations":0}]}"#,
            ),
        );
        let cell = |n: &str| c.iter().find(|x| x.0 == n).map(|x| x.2.clone());
        assert_eq!(cell("t_s").as_deref(), Some("1.5"));
        assert_eq!(cell("mode").as_deref(), Some("cotc"));
        assert_eq!(cell("blend").as_deref(), Some(""));
        assert_eq!(cell("limiter_active").as_deref(), Some("1"));
        assert_eq!(cell("iterations").as_deref(), Some("7"));
        assert_eq!(cell("solve_time_us").as_deref(), Some("1e-7"));
        assert_eq!(cell("solvers_cotc_status").as_deref(), Some("solved"));
        assert_eq!(cell("solvers_free_iterations").as_deref(), Some("0"));
        // Full precision survives: the text parses back to the same f64.
        let x = 0.1 + 0.2;
        let c = flatten("aircraft", &node(&format!(r#"{{"t":{x}}}"#)));
        assert_eq!(c[0].2.parse::<f64>().unwrap(), x);
    }

    #[test]
    fn topics_name_files_and_qualified_columns() {
        assert_eq!(topic_file("/aircraft/perceived"), "aircraft-perceived.csv");
        assert_eq!(topic_file("/cwf/platform"), "cwf-platform.csv");
        assert_eq!(
            qualified("/cwf/platform", "pose_x_m"),
            "cwf_platform_pose_x_m"
        );
        assert_eq!(topic_kind("/smpc/actuators"), "actuators");
    }

    #[test]
    fn unknown_fields_are_refused_with_what_there_is() {
        let mut all = BTreeMap::new();
        all.insert(
            "/cwf/platform".to_string(),
            vec![
                Column {
                    name: "t_s".into(),
                    key: "t".into(),
                },
                Column {
                    name: "pose_x_m".into(),
                    key: "pose".into(),
                },
            ],
        );
        let p = Path::new("r.mcap");
        let ok = chosen(&["/cwf/platform.pose".into()], &all, p).unwrap();
        assert_eq!(ok, vec![("/cwf/platform".into(), "pose_x_m".into())]);
        let e = chosen(&["/mpc/platform.pose".into()], &all, p).unwrap_err();
        assert!(e.to_string().contains("/cwf/platform"), "{e}");
        let e = chosen(&["/cwf/platform.posture".into()], &all, p).unwrap_err();
        assert!(e.to_string().contains("t, pose"), "{e}");
        assert!(chosen(&["pose".into()], &all, p).is_err());
    }
}
