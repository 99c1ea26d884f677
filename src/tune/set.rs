//! `--set KEY=VALUE` of `hexcue eval`: one profile value replaced in the profile's TOML by its
//! key path (`cwf.tilt_lp_zeta=0.8`, `mpc.specific_force_weight=[1, 1, 0.5]`), or some elements
//! of an array (`mpc.specific_force_weight[0,1]=3`, the form in which `hexcue eval --space`
//! names the tuned keys). The document is edited with `toml_edit`, so that comments and layout
//! stay; the edited text then goes through the profile loader like any profile, which holds
//! the bounds and the checks, so there is no second list of them here.

use std::str::FromStr;

use thiserror::Error;
use toml_edit::{DocumentMut, Item, Table, Value};

/// One parsed `--set`.
#[derive(Clone, Debug)]
pub struct Setting {
    /// As given, for messages and the profile's header.
    pub text: String,
    /// Dotted key path, e.g. `cwf.tilt_lp_zeta`.
    pub path: String,
    /// The array elements to set (`[0,1]`); empty: the whole value.
    pub elements: Vec<usize>,
    pub value: Value,
}

#[derive(Debug, Error, PartialEq)]
pub enum SetError {
    #[error("--set `{0}`: expected KEY=VALUE, e.g. cwf.tilt_lp_zeta=0.8 or mpc.specific_force_weight[0,1]=3")]
    NoEquals(String),
    #[error(
        "--set `{text}`: the key `{key}` is not a dotted path of names (letters, digits, `_`)"
    )]
    BadKey { text: String, key: String },
    #[error("--set `{text}`: `{elements}`: expected array elements as [i] or [i,j,…]")]
    BadElements { text: String, elements: String },
    #[error("--set `{text}`: `{value}` is not a TOML value (a number, true/false, \"text\" or [a, b, …])")]
    BadValue { text: String, value: String },
    #[error("--set `{text}`: setting array elements takes a number, not `{value}`")]
    NotANumber { text: String, value: String },
    #[error("--set `{text}`: `{table}` is a value in the profile, not a table")]
    NotATable { text: String, table: String },
    #[error("--set `{text}`: `{path}` is a table in the profile; set its keys one by one")]
    IsATable { text: String, path: String },
    #[error("--set `{text}`: `{path}` is not in the profile, so it has no elements to set")]
    Missing { text: String, path: String },
    #[error("--set `{text}`: `{path}` has no element {index} (it is {found})")]
    NoElement {
        text: String,
        path: String,
        index: usize,
        found: String,
    },
}

impl FromStr for Setting {
    type Err = SetError;

    fn from_str(text: &str) -> Result<Self, SetError> {
        let (key, value) = text
            .split_once('=')
            .ok_or_else(|| SetError::NoEquals(text.to_string()))?;
        let key = key.trim();
        let (path, elements) = match key.split_once('[') {
            None => (key, Vec::new()),
            Some((path, rest)) => {
                let bad = || SetError::BadElements {
                    text: text.to_string(),
                    elements: format!("[{rest}"),
                };
                let inner = rest.strip_suffix(']').ok_or_else(bad)?;
                let elements: Vec<usize> = inner
                    .split(',')
                    .map(|i| i.trim().parse::<usize>())
                    .collect::<Result<_, _>>()
                    .map_err(|_| bad())?;
                (path.trim(), elements)
            }
        };
        let names_ok = !path.is_empty()
            && path.split('.').all(|part| {
                !part.is_empty()
                    && part
                        .chars()
                        .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
            });
        if !names_ok {
            return Err(SetError::BadKey {
                text: text.to_string(),
                key: key.to_string(),
            });
        }
        let value_text = value.trim();
        let value = Value::from_str(value_text).map_err(|_| SetError::BadValue {
            text: text.to_string(),
            value: value_text.to_string(),
        })?;
        let numeric = value.is_float() || value.is_integer();
        if !elements.is_empty() && !numeric {
            return Err(SetError::NotANumber {
                text: text.to_string(),
                value: value_text.to_string(),
            });
        }
        Ok(Setting {
            text: text.to_string(),
            path: path.to_string(),
            elements,
            value,
        })
    }
}

impl Setting {
    /// Writes the value into `doc`: a key the profile states keeps its comments and spacing; one
    /// it does not state is added to its table (made if absent), for the loader to accept or
    /// refuse as it would in a file.
    pub fn apply(&self, doc: &mut DocumentMut) -> Result<(), SetError> {
        let parts: Vec<&str> = self.path.split('.').collect();
        let (last, tables) = parts.split_last().expect("a checked, non-empty path");
        let mut table: &mut Table = doc.as_table_mut();
        for (depth, part) in tables.iter().enumerate() {
            let item = table
                .entry(part)
                .or_insert_with(|| Item::Table(Table::new()));
            if let Some(inline) = item.as_inline_table().cloned() {
                *item = Item::Table(inline.into_table());
            }
            table = item.as_table_mut().ok_or_else(|| SetError::NotATable {
                text: self.text.clone(),
                table: parts[..=depth].join("."),
            })?;
        }
        if table.get(last).is_some_and(|i| i.is_table_like()) {
            return Err(SetError::IsATable {
                text: self.text.clone(),
                path: self.path.clone(),
            });
        }
        if self.elements.is_empty() {
            match table.get_mut(last).and_then(Item::as_value_mut) {
                Some(old) => replace(old, self.value.clone()),
                None => {
                    table.insert(last, Item::Value(self.value.clone()));
                }
            }
            return Ok(());
        }
        let missing = || SetError::Missing {
            text: self.text.clone(),
            path: self.path.clone(),
        };
        let value = table
            .get_mut(last)
            .and_then(Item::as_value_mut)
            .ok_or_else(missing)?;
        let found = match value.as_array() {
            Some(a) => format!("an array of {}", a.len()),
            None => format!("a {}", value.type_name()),
        };
        let no_element = |index: usize| SetError::NoElement {
            text: self.text.clone(),
            path: self.path.clone(),
            index,
            found: found.clone(),
        };
        let Some(array) = value.as_array_mut() else {
            return Err(no_element(self.elements[0]));
        };
        if let Some(&i) = self.elements.iter().find(|&&i| i >= array.len()) {
            return Err(no_element(i));
        }
        for &i in &self.elements {
            if let Some(element) = array.get_mut(i) {
                replace(element, self.value.clone());
            }
        }
        Ok(())
    }
}

/// Replaces a value, keeping the comment and spacing around it.
fn replace(old: &mut Value, new: Value) {
    let decor = old.decor().clone();
    *old = new;
    *old.decor_mut() = decor;
}

/// Applies every setting in order (a later one wins where two set the same value).
pub fn apply_all(doc: &mut DocumentMut, settings: &[Setting]) -> Result<(), SetError> {
    settings.iter().try_for_each(|s| s.apply(doc))
}

#[cfg(test)]
mod tests {
    use super::*;
    use hexcue_core::profile::text::{parse_profile, DEFAULT_PROFILE_TOML};

    fn set(doc: &mut DocumentMut, text: &str) -> Result<(), SetError> {
        text.parse::<Setting>()?.apply(doc)
    }

    fn base() -> DocumentMut {
        DEFAULT_PROFILE_TOML.parse().unwrap()
    }

    #[test]
    fn a_scalar_an_array_and_elements_are_set_with_the_comments_kept() {
        let mut doc = base();
        set(&mut doc, "cwf.tilt_lp_zeta=0.9").unwrap();
        set(&mut doc, "cwf.angular_velocity_scale = [0.5, 0.6, 0.7]").unwrap();
        set(&mut doc, "mpc.specific_force_weight[0,1]=3").unwrap();
        set(&mut doc, "smpc.cotc.washout_position_weight[2]=2.5").unwrap();
        let text = doc.to_string();
        let p = parse_profile(&text, "set").unwrap();
        let b = parse_profile(DEFAULT_PROFILE_TOML, "base").unwrap();
        assert_eq!(p.cwf.tilt_lp_zeta, 0.9);
        assert_eq!(p.cwf.angular_velocity_scale, [0.5, 0.6, 0.7]);
        assert_eq!(
            p.mpc.specific_force_weight,
            [3.0, 3.0, b.mpc.specific_force_weight[2]]
        );
        assert_eq!(p.smpc.cotc.washout_position_weight, Some([0.0, 0.0, 2.5]));
        // Only the four lines changed: comments and layout kept.
        let changed = DEFAULT_PROFILE_TOML
            .lines()
            .zip(text.lines())
            .filter(|(a, b)| a != b)
            .count();
        assert_eq!(changed, 4);
        assert_eq!(DEFAULT_PROFILE_TOML.lines().count(), text.lines().count());
    }

    #[test]
    fn a_key_the_profile_does_not_state_is_added_and_the_loader_judges_it() {
        let mut doc: DocumentMut = include_str!("../../profiles/compact.toml").parse().unwrap();
        set(&mut doc, "mpc.false_cue_margin=0.5").unwrap();
        assert!(doc.to_string().contains("false_cue_margin = 0.5"));
        // Unknown to the loader: refused there, with the key named.
        let mut doc = base();
        set(&mut doc, "cwf.no_such_gain=1").unwrap();
        let err = parse_profile(&doc.to_string(), "set")
            .unwrap_err()
            .to_string();
        assert!(err.contains("no_such_gain"), "{err}");
        // Out of the loader's bounds: refused with the key.
        let mut doc = base();
        set(&mut doc, "score.leg_usage_start=1.5").unwrap();
        let err = parse_profile(&doc.to_string(), "set")
            .unwrap_err()
            .to_string();
        assert!(err.contains("score.leg_usage_start"), "{err}");
    }

    #[test]
    fn malformed_settings_are_refused_with_what_was_expected() {
        let bad = |t: &str| t.parse::<Setting>().unwrap_err().to_string();
        assert!(bad("cwf.tilt_lp_zeta").contains("expected KEY=VALUE"));
        assert!(bad("cwf..x=1").contains("dotted path"));
        assert!(bad("a.b[x]=1").contains("[i]"));
        assert!(bad("a.b[0=1").contains("[i]"));
        assert!(bad("cwf.tilt_lp_zeta=zero").contains("not a TOML value"));
        assert!(bad("a.b[0]=\"x\"").contains("takes a number"));
        let mut doc = base();
        let e = set(&mut doc, "cwf.tilt_lp_zeta.x=1")
            .unwrap_err()
            .to_string();
        assert!(e.contains("`cwf.tilt_lp_zeta` is a value"), "{e}");
        let e = set(&mut doc, "cwf=1").unwrap_err().to_string();
        assert!(e.contains("is a table"), "{e}");
        let e = set(&mut doc, "cwf.specific_force_scale[3]=1")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("no element 3") && e.contains("array of 3"),
            "{e}"
        );
        let e = set(&mut doc, "cwf.tilt_lp_zeta[0]=1")
            .unwrap_err()
            .to_string();
        assert!(e.contains("no element 0"), "{e}");
        let e = set(&mut doc, "cwf.nothing[0]=1").unwrap_err().to_string();
        assert!(e.contains("not in the profile"), "{e}");
    }
}
