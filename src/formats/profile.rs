//! Profiles as TOML files (docs/design.md §3): the file is read here, parsed by
//! [`hexcue_core::profile::text`].

use std::path::Path;

use hexcue_core::profile::text::{parse_profile, ProfileLoadError};
use hexcue_core::profile::Profile;

/// A profile from a file, with its text (recordings attach it).
pub fn load_profile(path: &Path) -> Result<(Profile, String), ProfileLoadError> {
    let source_name = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|error| ProfileLoadError::Io {
        source_name: source_name.clone(),
        error,
    })?;
    let profile = parse_profile(&text, &source_name)?;
    Ok((profile, text))
}
