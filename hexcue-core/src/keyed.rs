//! Maps keyed by a word of the vocabulary ([`AlgorithmId`], [`Channel`], [`Dof`],
//! [`InputAxis`]) inside, written as
//! JSON objects keyed by the word's text at the edge.
//!
//! The summary's JSON was written from maps keyed by `String`, so its objects list their
//! keys in the text's order (`cwf`, `mpc`, `smpc`). The enums order themselves otherwise
//! (the console's order: S-MPC, MPC, CWF), so [`by_word`] sorts by the text when it writes:
//! a summary reads the same, byte for byte, as before the maps were typed.
//!
//! ```
//! use std::collections::BTreeMap;
//! use hexcue_core::vocab::AlgorithmId;
//!
//! #[derive(serde::Serialize, serde::Deserialize)]
//! struct Scores {
//!     #[serde(with = "hexcue_core::keyed::by_word")]
//!     score: BTreeMap<AlgorithmId, f64>,
//! }
//!
//! let scores = Scores {
//!     score: [(AlgorithmId::Smpc, 1.0), (AlgorithmId::Cwf, 2.0)].into(),
//! };
//! let json = serde_json::to_string(&scores).unwrap();
//! assert_eq!(json, r#"{"score":{"cwf":2.0,"smpc":1.0}}"#);
//! let back: Scores = serde_json::from_str(&json).unwrap();
//! assert_eq!(back.score, scores.score);
//! ```

use crate::vocab::{AlgorithmId, Channel, Dof, InputAxis};

/// A word of the vocabulary that keys a map in the JSON.
pub trait Word: Copy + Ord + 'static {
    /// What the word names, for a message about a key that is none ("algorithm").
    const WHAT: &'static str;
    /// Every word, for the message.
    fn all() -> &'static [Self];
    /// Its text in the JSON.
    fn word(self) -> &'static str;
    /// The word whose text is exactly `text`.
    fn from_word(text: &str) -> Option<Self> {
        Self::all().iter().copied().find(|w| w.word() == text)
    }
}

impl Word for AlgorithmId {
    const WHAT: &'static str = "algorithm";
    fn all() -> &'static [Self] {
        AlgorithmId::ALL
    }
    fn word(self) -> &'static str {
        self.key()
    }
}

impl Word for Channel {
    const WHAT: &'static str = "channel";
    fn all() -> &'static [Self] {
        &Channel::ALL
    }
    fn word(self) -> &'static str {
        self.key()
    }
}

impl Word for Dof {
    const WHAT: &'static str = "degree of freedom";
    fn all() -> &'static [Self] {
        &Dof::ALL
    }
    fn word(self) -> &'static str {
        self.key()
    }
}

impl Word for InputAxis {
    const WHAT: &'static str = "input axis";
    fn all() -> &'static [Self] {
        &InputAxis::ALL
    }
    fn word(self) -> &'static str {
        self.key()
    }
}

/// `#[serde(with = "hexcue_core::keyed::by_word")]` on a `BTreeMap<K: Word, V>`: an object
/// keyed by the words' text, in the text's order; reading it back refuses a key that is no
/// word, naming it and the words expected.
pub mod by_word {
    use std::collections::BTreeMap;

    use serde::de::Error as _;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    use super::Word;

    /// Writes `map` as an object keyed by the words' text, sorted by that text.
    pub fn serialize<K: Word, V: Serialize, S: Serializer>(
        map: &BTreeMap<K, V>,
        serializer: S,
    ) -> Result<S::Ok, S::Error> {
        let mut entries: Vec<(&'static str, &V)> = map.iter().map(|(k, v)| (k.word(), v)).collect();
        entries.sort_unstable_by_key(|(word, _)| *word);
        serializer.collect_map(entries)
    }

    /// Reads an object keyed by the words' text.
    pub fn deserialize<'de, K: Word, V: Deserialize<'de>, D: Deserializer<'de>>(
        deserializer: D,
    ) -> Result<BTreeMap<K, V>, D::Error> {
        BTreeMap::<String, V>::deserialize(deserializer)?
            .into_iter()
            .map(|(text, v)| match K::from_word(&text) {
                Some(k) => Ok((k, v)),
                None => {
                    let expected: Vec<&str> = K::all().iter().map(|w| w.word()).collect();
                    Err(D::Error::custom(format!(
                        "unknown {} `{text}`: expected one of {}",
                        K::WHAT,
                        expected.join(", ")
                    )))
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use super::*;

    #[derive(Debug, PartialEq, serde::Serialize, serde::Deserialize)]
    struct Keyed {
        #[serde(with = "by_word")]
        algorithms: BTreeMap<AlgorithmId, u32>,
        #[serde(with = "by_word")]
        channels: BTreeMap<Channel, u32>,
    }

    #[test]
    fn written_in_the_order_of_the_text_and_read_back() {
        let keyed = Keyed {
            algorithms: AlgorithmId::ALL.iter().map(|&a| (a, a as u32)).collect(),
            channels: Channel::ALL
                .iter()
                .map(|&c| (c, c.index() as u32))
                .collect(),
        };
        let json = serde_json::to_string(&keyed).unwrap();
        // The text's order, as the `String`-keyed maps wrote it, not the enums' own.
        assert_eq!(
            json,
            r#"{"algorithms":{"cwf":2,"mpc":1,"smpc":0},"channels":{"fx":0,"fy":1,"fz":2,"wx":3,"wy":4,"wz":5}}"#
        );
        assert_eq!(serde_json::from_str::<Keyed>(&json).unwrap(), keyed);
    }

    #[derive(Debug, PartialEq, serde::Serialize, serde::Deserialize)]
    struct Usage {
        #[serde(with = "by_word")]
        dofs: BTreeMap<Dof, u32>,
        #[serde(with = "by_word")]
        axes: BTreeMap<InputAxis, u32>,
        binding: Vec<Channel>,
    }

    #[test]
    fn dofs_and_input_axes_keyed_as_the_string_maps_were() {
        let usage = Usage {
            dofs: Dof::ALL.iter().map(|&d| (d, d.index() as u32)).collect(),
            axes: InputAxis::ALL
                .iter()
                .map(|&a| (a, a.index() as u32))
                .collect(),
            binding: vec![Channel::Wz, Channel::Fx],
        };
        let json = serde_json::to_string(&usage).unwrap();
        // The DoFs in the text's order (pitch before x), as `max_dof_usage` always listed
        // them; a list of channels keeps its own order.
        assert_eq!(
            json,
            r#"{"dofs":{"pitch":4,"roll":3,"x":0,"y":1,"yaw":5,"z":2},"axes":{"fx":0,"fy":1,"fz":2,"p":3,"q":4,"r":5},"binding":["wz","fx"]}"#
        );
        assert_eq!(serde_json::from_str::<Usage>(&json).unwrap(), usage);
    }

    #[test]
    fn an_unknown_key_is_named() {
        let err = serde_json::from_str::<Keyed>(r#"{"algorithms":{"S-MPC":1},"channels":{}}"#)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("unknown algorithm `S-MPC`: expected one of smpc, mpc, cwf"),
            "{err}"
        );
    }
}
