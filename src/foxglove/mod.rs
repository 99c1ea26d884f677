//! Foxglove: the platforms in 3D, in recordings and live (issue 15, `docs/foxglove.md`).
//!
//! - [`scene`]: what a frame looks like in Foxglove's well-known messages (transforms, plates
//!   and legs, events). Pure: no file, no socket.
//! - [`record`]: writes those messages into a recording beside hexcue's own topics.
//! - [`server`]: a frame sink that serves the same channels over the Foxglove WebSocket
//!   protocol, so that the Foxglove app follows a running session.

pub mod record;
pub mod scene;
pub mod server;

pub use scene::SceneBuilder;
pub use server::{FoxgloveServer, ServerError, DEFAULT_ADDR};
