//! The recording reader (`Recording::open` and every frame) on arbitrary bytes. It reads
//! from a path, so each input is written to one scratch file in memory-backed /dev/shm.
#![no_main]

use std::path::PathBuf;
use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;

fn scratch() -> &'static PathBuf {
    static PATH: OnceLock<PathBuf> = OnceLock::new();
    PATH.get_or_init(|| {
        let dir = if std::path::Path::new("/dev/shm").is_dir() {
            PathBuf::from("/dev/shm")
        } else {
            std::env::temp_dir()
        };
        dir.join(format!("hexcue-fuzz-{}.mcap", std::process::id()))
    })
}

fuzz_target!(|data: &[u8]| {
    let path = scratch();
    if std::fs::write(path, data).is_err() {
        return;
    }
    let Ok(recording) = hexcue::formats::recording::Recording::open(path) else {
        return;
    };
    let Ok(frames) = recording.frames() else {
        return;
    };
    // Bounded: a valid prefix may hold many steps, and an error ends the read as it would
    // end a review.
    for frame in frames.take(10_000) {
        if frame.is_err() {
            break;
        }
    }
});
