//! Physical models: linear systems, the vestibular system and the Stewart platform.

pub mod lti;
pub mod platform;
pub mod reach;
pub mod stewart;
pub mod vestibular;
