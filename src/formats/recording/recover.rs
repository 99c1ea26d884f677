//! Recovery: a finished copy of what an unfinished or damaged recording holds.

use std::path::Path;

use super::{meta_key, shown, Recorder, Recording, RecordingError, RecordingStats};

/// What [`recover`] wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct RecoverStats {
    /// Whether the input was already finished (then the output is a plain copy).
    pub input_finished: bool,
    /// Why the input's data ended early, when it did.
    pub input_stopped: Option<String>,
    /// Stretches of the input that were damaged and skipped, with what they held.
    pub damage: Vec<super::Damage>,
    /// Steps of the input found intact (written unless a step was torn at a skip).
    pub input_steps: u64,
    pub output: RecordingStats,
}

/// Writes a finished copy of what a (possibly unfinished or damaged) recording holds:
/// metadata, attachments and every complete step, with the original log times; the steps in
/// damaged chunks are skipped and listed in [`RecoverStats::damage`].
pub fn recover(input: &Path, output: &Path) -> Result<RecoverStats, RecordingError> {
    let same = match (input.canonicalize(), output.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    };
    if same {
        return Err(RecordingError::SameFile {
            path: shown(output),
        });
    }
    let recording = Recording::open(input)?;
    let mut metadata = recording.metadata.clone();
    let keys: Vec<&str> = recording.algorithms.iter().map(|a| a.key()).collect();
    metadata.insert(meta_key::ALGORITHMS.into(), keys.join(","));
    metadata.insert(
        meta_key::RECOVERED_BY_VERSION.into(),
        env!("CARGO_PKG_VERSION").to_string(),
    );
    metadata.insert(
        meta_key::RECOVERED_FROM.into(),
        input
            .file_name()
            .map_or_else(|| shown(input), |n| n.to_string_lossy().into_owned()),
    );
    let mut recorder =
        Recorder::create_with(output, &recording.meta(), recording.start_unix_ns, metadata)?;
    for frame in recording.frames()? {
        recorder.record(&frame?)?;
    }
    Ok(RecoverStats {
        input_finished: recording.finished,
        input_stopped: recording.stopped.clone(),
        damage: recording.damage.clone(),
        input_steps: recording.steps,
        output: recorder.finish()?,
    })
}
