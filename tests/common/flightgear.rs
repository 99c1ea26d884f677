//! FlightGear's generic protocol, output side, as FlightGear writes it: a reader of the
//! protocol files' XML, and datagrams built from a protocol file and property values in
//! FlightGear's own units the way src/Network/generic.cxx does (`read_config`,
//! `gen_message_binary`; cited in docs/live.md). The decoder's own `encode` plays no part.

use std::collections::HashMap;
use std::path::Path;

/// A protocol file of the repository (`integrations/flightgear/hexcue.xml`), read.
pub fn protocol_file(path: &Path) -> Protocol {
    let xml = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    protocol(&parse_xml(&xml))
}

// A reader of the XML FlightGear's protocol files use (elements, text, comments, the XML
// declaration; attributes are read past), small enough to check by eye.

#[derive(Debug)]
pub struct Element {
    pub name: String,
    pub text: String,
    pub children: Vec<Element>,
}

impl Element {
    pub fn child(&self, name: &str) -> Option<&Element> {
        self.children.iter().find(|c| c.name == name)
    }
    pub fn children<'a>(&'a self, name: &'a str) -> impl Iterator<Item = &'a Element> + 'a {
        self.children.iter().filter(move |c| c.name == name)
    }
    /// The text of a child, trimmed, as SGPropertyNode::getStringValue gives it.
    pub fn value(&self, name: &str) -> Option<&str> {
        self.child(name).map(|c| c.text.trim())
    }
}

pub fn parse_xml(text: &str) -> Element {
    let mut rest = text;
    let mut stack = vec![Element {
        name: String::new(),
        text: String::new(),
        children: Vec::new(),
    }];
    while !rest.is_empty() {
        if let Some(r) = rest.strip_prefix("<!--") {
            rest = &r[r.find("-->").expect("a closed comment") + 3..];
        } else if let Some(r) = rest.strip_prefix("<?") {
            rest = &r[r.find("?>").expect("a closed declaration") + 2..];
        } else if let Some(r) = rest.strip_prefix("</") {
            let end = r.find('>').expect("a closed end tag");
            let done = stack.pop().expect("an open element");
            assert_eq!(done.name, r[..end].trim(), "mismatched end tag");
            stack.last_mut().expect("a parent").children.push(done);
            rest = &r[end + 1..];
        } else if let Some(r) = rest.strip_prefix('<') {
            let end = r.find('>').expect("a closed tag");
            let tag = &r[..end];
            let empty = tag.ends_with('/');
            let name = tag
                .trim_end_matches('/')
                .split_whitespace()
                .next()
                .expect("a tag name")
                .to_string();
            let e = Element {
                name,
                text: String::new(),
                children: Vec::new(),
            };
            if empty {
                stack.last_mut().unwrap().children.push(e);
            } else {
                stack.push(e);
            }
            rest = &r[end + 1..];
        } else {
            let end = rest.find('<').unwrap_or(rest.len());
            let t = &rest[..end];
            assert!(!t.contains('&'), "entities are not used in protocol files");
            stack.last_mut().unwrap().text.push_str(t);
            rest = &rest[end..];
        }
    }
    assert_eq!(stack.len(), 1, "unclosed elements");
    stack.pop().unwrap()
}

// ---------------------------------------------------------------------------------------------
// FlightGear's generic protocol, output side, binary mode: generic.cxx `read_config` (what a
// chunk's type, factor and offset default to, the byte order) and `gen_message_binary` (how
// each type is written).

pub enum ChunkType {
    Bool,
    Int,
    Float,
    Double,
    Fixed,
    Byte,
    Word,
}

pub struct Chunk {
    pub node: String,
    pub kind: ChunkType,
    pub factor: f64,
    pub offset: f64,
}

pub struct Protocol {
    pub big_endian: bool,
    pub footer: Option<i32>,
    pub chunks: Vec<Chunk>,
}

pub fn protocol(xml: &Element) -> Protocol {
    let output = xml
        .child("PropertyList")
        .and_then(|p| p.child("generic"))
        .and_then(|g| g.child("output"))
        .expect("PropertyList/generic/output");
    // getBoolValue: "true" or a non-zero number.
    let binary = matches!(output.value("binary_mode"), Some("true" | "1"));
    assert!(binary, "hexcue's decoder reads FlightGear's binary mode");
    // Default network order; "host" is this machine's (little-endian) order.
    let big_endian = match output.value("byte_order") {
        None | Some("network") => true,
        Some("host") => cfg!(target_endian = "big"),
        Some(other) => panic!("byte_order {other}: FlightGear falls back to host order"),
    };
    let footer = match output.value("binary_footer") {
        None | Some("none") => None,
        Some(f) => panic!("binary_footer {f}: hexcue's decoder expects none"),
    };
    assert!(output.child("record_length").is_none());
    let chunks = output
        .children("chunk")
        .map(|c| {
            assert!(c.child("const").is_none(), "a const chunk");
            let kind = match c.value("type").unwrap_or("") {
                "bool" | "boolean" => ChunkType::Bool,
                "float" => ChunkType::Float,
                "double" => ChunkType::Double,
                "fixed" => ChunkType::Fixed,
                "byte" => ChunkType::Byte,
                "word" => ChunkType::Word,
                "string" => panic!("a string chunk"),
                // Anything else, and no type at all, is an int.
                _ => ChunkType::Int,
            };
            let number = |key: &str, default: f64| {
                c.value(key)
                    .map_or(default, |v| v.parse().expect("a number"))
            };
            Chunk {
                node: c.value("node").unwrap_or("/null").to_string(),
                kind,
                factor: number("factor", 1.0),
                offset: number("offset", 0.0),
            }
        })
        .collect();
    Protocol {
        big_endian,
        footer,
        chunks,
    }
}

/// One datagram, from FlightGear's property values (the property tree's own units).
pub fn datagram(p: &Protocol, props: &HashMap<&str, f64>) -> Vec<u8> {
    let mut b = Vec::new();
    let be = p.big_endian;
    for c in &p.chunks {
        let raw = *props.get(c.node.as_str()).unwrap_or_else(|| {
            panic!(
                "the protocol sends {}, which this test does not model",
                c.node
            )
        });
        // getFloatValue (a float) for every type but double.
        let val = |single: bool| {
            let v = if single { f64::from(raw as f32) } else { raw };
            c.offset + v * c.factor
        };
        match c.kind {
            ChunkType::Bool => b.push(u8::from(raw != 0.0)),
            ChunkType::Int => {
                let v = val(true) as i32;
                b.extend(if be { v.to_be_bytes() } else { v.to_le_bytes() });
            }
            ChunkType::Fixed => {
                let v = (val(true) * 65536.0) as i32;
                b.extend(if be { v.to_be_bytes() } else { v.to_le_bytes() });
            }
            ChunkType::Float => {
                let v = val(true) as f32;
                b.extend(if be { v.to_be_bytes() } else { v.to_le_bytes() });
            }
            ChunkType::Double => {
                let v = val(false);
                b.extend(if be { v.to_be_bytes() } else { v.to_le_bytes() });
            }
            // Never byte-swapped by FlightGear.
            ChunkType::Byte => b.push(val(true) as i8 as u8),
            ChunkType::Word => b.extend((val(true) as i16).to_ne_bytes()),
        }
    }
    if let Some(f) = p.footer {
        b.extend(if be { f.to_be_bytes() } else { f.to_le_bytes() });
    }
    b
}
