//! The keys of the `hexcue` metadata record (docs/recordings.md, *Metadata record*): the
//! writer, the reader, `recover` and the live recording name them from this one table, so
//! that a key cannot be spelt two ways.

/// `hexcue`: the program that wrote the file.
pub const TOOL: &str = "tool";
/// The crate version that wrote the file.
pub const TOOL_VERSION: &str = "tool_version";
/// The topic layout's version ([`super::FORMAT_VERSION`]).
pub const FORMAT_VERSION: &str = "format_version";
/// The profile's name.
pub const PROFILE_NAME: &str = "profile_name";
/// The trace's name (a live session's: its input's address).
pub const TRACE_NAME: &str = "trace_name";
/// SHA-256 (hex) of the attached trace's text.
pub const TRACE_SHA256: &str = "trace_sha256";
/// The step rate (Hz).
pub const RATE_HZ: &str = "rate_hz";
/// The keys of the algorithms recorded, comma-separated.
pub const ALGORITHMS: &str = "algorithms";
/// The recording's start, from which log times count (ns since the Unix epoch).
pub const START_UNIX_NS: &str = "start_unix_ns";
/// The version of `hexcue recover` that wrote the file.
pub const RECOVERED_BY_VERSION: &str = "recovered_by_version";
/// The file `hexcue recover` read.
pub const RECOVERED_FROM: &str = "recovered_from";
/// A live session's input (`hexcue live --input`).
pub const INPUT: &str = "input";
/// The algorithm that drove a live session's platform at its start.
pub const DRIVE: &str = "drive";
/// What stopped all motion, when a platform fault did (a live session).
pub const PLATFORM_FAULT: &str = "platform_fault";
