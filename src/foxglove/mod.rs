//! Foxglove: the platforms in 3D, in recordings and live (issue 15, `docs/foxglove.md`).
//!
//! - [`scene`]: what a frame looks like in Foxglove's well-known messages (transforms, plates
//!   and legs, events). Pure: no file, no socket. It lives in [`crate::channels`], the table
//!   of channels that the recorder and the server share.
//! - [`server`]: a frame sink that serves the channels of that table over the Foxglove
//!   WebSocket protocol, so that the Foxglove app follows a running session.

pub mod parameters;
pub mod server;

pub use crate::channels::scene;
pub use server::{FoxgloveServer, DEFAULT_ADDR};
