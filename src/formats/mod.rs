//! File formats: profiles (TOML), traces (CSV), recordings (MCAP), summaries (JSON), OMCT
//! reports (Markdown, JSON). Adapters around the core; the core never reads a file.

pub mod library;
pub mod omct;
pub mod profile;
pub mod recording;
pub mod trace;
