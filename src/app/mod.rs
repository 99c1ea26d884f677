//! The commands, one room each (issue 22): `cli` parses the arguments, and what a command
//! does lives here. Set-ups every command shares are in `common`.

pub mod common;
pub mod live;
pub mod play;
pub mod review;
