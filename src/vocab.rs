//! The words every layer shares, at the bottom of the crate so that any module may use them
//! without reaching up: a parameter value that cannot be (the profile's sections validate
//! themselves where they are defined, next to the algorithm they tune).

/// A profile value that cannot describe a real simulator.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("`{key}`: {reason}")]
pub struct ProfileError {
    /// Dotted path of the offending key, e.g. `geometry.leg_min_m`.
    pub key: String,
    pub reason: String,
}

/// `Ok` for a finite, strictly positive value, else an error naming the key.
pub(crate) fn positive(key: &str, v: f64) -> Result<(), ProfileError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(ProfileError {
            key: key.to_string(),
            reason: format!("{v}: expected a finite value greater than 0"),
        })
    }
}
