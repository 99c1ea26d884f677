//! Physical models: linear systems, the vestibular system and the Stewart platform.

pub mod lti;
pub mod stewart;
pub mod vestibular;
